/* parallel.c: chunked parallel-for over an index range, on OpenMP when built with it. */
#include "crease/base.h"

#include <stdlib.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

void cr_parallel_prefer_passive_wait(char **argv) {
#ifdef _OPENMP
    if (!argv || getenv("OMP_WAIT_POLICY") || getenv("GOMP_SPINCOUNT")) return;
    if (setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
    execv("/proc/self/exe", argv);
    /* no /proc or exec refused: go on with the runtime's default policy */
    unsetenv("OMP_WAIT_POLICY");
#else
    (void)argv;
#endif
}

int cr_thread_count(void) {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

void cr_set_thread_count(int n) {
#ifdef _OPENMP
    if (n > 0) omp_set_num_threads(n);
#else
    (void)n;
#endif
}

void cr_parallel_for(int64_t n, int64_t grain, cr_range_fn fn, void *ctx) {
    if (n <= 0) return;
    int threads = cr_thread_count();
    if (grain <= 0) grain = 256;
    int64_t chunks = (n + grain - 1) / grain;
    /* A few chunks per thread balance uneven work without much overhead. */
    if (chunks > 4 * (int64_t)threads) chunks = 4 * (int64_t)threads;
    if (threads <= 1 || chunks <= 1) {
        fn(ctx, 0, n);
        return;
    }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
    for (int64_t c = 0; c < chunks; c++) {
        int64_t begin = n * c / chunks, end = n * (c + 1) / chunks;
        if (begin < end) fn(ctx, begin, end);
    }
}
