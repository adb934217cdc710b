/* bench_stats.h: the median every benchmark reports (sorts t in place). */
#ifndef CREASE_BENCH_STATS_H
#define CREASE_BENCH_STATS_H

#include <stdlib.h>

static int bench_cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static inline double bench_median(double *t, int n) {
    qsort(t, (size_t)n, sizeof *t, bench_cmp_double);
    return t[n / 2];
}

#endif
