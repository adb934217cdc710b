/* bench_stats.h: the median every benchmark reports (sorts t in place), and
 * the mean and sample standard deviation for figures over seeds. */
#ifndef CREASE_BENCH_STATS_H
#define CREASE_BENCH_STATS_H

#include <math.h>
#include <stdlib.h>

static int bench_cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static inline double bench_median(double *t, int n) {
    qsort(t, (size_t)n, sizeof *t, bench_cmp_double);
    return t[n / 2];
}

static inline void bench_mean_sd(const double *x, int n, double *mean, double *sd) {
    double s = 0.0, q = 0.0;
    for (int i = 0; i < n; i++)
        s += x[i];
    *mean = n > 0 ? s / n : 0.0;
    for (int i = 0; i < n; i++)
        q += (x[i] - *mean) * (x[i] - *mean);
    *sd = n > 1 ? sqrt(q / (n - 1)) : 0.0;
}

#endif
