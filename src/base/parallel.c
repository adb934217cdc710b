/* parallel.c: chunked parallel-for over an index range, on OpenMP when built with it. */
#define _GNU_SOURCE /* sched_getaffinity, CPU_COUNT */
#include "crease/base.h"

#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#ifdef _OPENMP
/* The CPUs this process may run on. */
static int usable_cpus(void) {
#ifdef CPU_COUNT
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) return CPU_COUNT(&set);
#endif
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

/* Other processes' runnable threads now: the fewest of five looks 2 ms
 * apart at /proc/loadavg's running count, less this reader (a job that
 * competes for the CPUs shows in every look, a short-lived process in one);
 * negative when it cannot be read. An instant, not the 1-minute average,
 * which still holds a finished job's load (the previous run's two threads,
 * a build) for minutes. */
static double runnable_others(void) {
    double fewest = -1.0;
    for (int look = 0; look < 5; look++) {
        FILE *f = fopen("/proc/loadavg", "r");
        if (!f) return -1.0;
        double a1, a5, a15;
        int running = 0, total = 0;
        if (fscanf(f, "%lf %lf %lf %d/%d", &a1, &a5, &a15, &running, &total) == 5 &&
            (fewest < 0.0 || running - 1 < fewest))
            fewest = running - 1;
        fclose(f);
        if (look < 4) usleep(2000);
    }
    return fewest;
}
#endif

const char *cr_parallel_wait_policy_for(double others, int threads, int cpus) {
    return others >= 0.0 && others + threads <= cpus ? "spin" : "passive";
}

/* Set name=value and re-execute; returns when that could not be done. */
static void reexec_with(const char *name, const char *value, char **argv) {
#ifdef _OPENMP
    if (setenv(name, value, 1) != 0) return;
    execv("/proc/self/exe", argv);
    /* no /proc or exec refused: go on with the runtime's default policy */
    unsetenv(name);
#else
    (void)name, (void)value, (void)argv;
#endif
}

static int wait_policy_set(char **argv) {
    return !argv || getenv("OMP_WAIT_POLICY") || getenv("GOMP_SPINCOUNT");
}

void cr_parallel_choose_wait_policy(char **argv) {
#ifdef _OPENMP
    if (wait_policy_set(argv)) return;
    int cpus = usable_cpus(), threads = cpus;
    const char *env = getenv("OMP_NUM_THREADS");
    int asked = env ? atoi(env) : 0;
    if (asked > 0) threads = asked;
    if (strcmp(cr_parallel_wait_policy_for(runnable_others(), threads, cpus), "spin") == 0)
        reexec_with("GOMP_SPINCOUNT", CR_PARALLEL_SPIN_COUNT, argv);
    else
        reexec_with("OMP_WAIT_POLICY", "passive", argv);
#else
    (void)argv;
#endif
}

void cr_parallel_prefer_passive_wait(char **argv) {
    if (!wait_policy_set(argv)) reexec_with("OMP_WAIT_POLICY", "passive", argv);
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

static int in_parallel(void) {
#ifdef _OPENMP
    return omp_in_parallel();
#else
    return 0;
#endif
}

void cr_parallel_for(int64_t n, int64_t grain, cr_range_fn fn, void *ctx) {
    if (n <= 0) return;
    int threads = cr_thread_count();
    if (grain <= 0) grain = 256;
    int64_t chunks = (n + grain - 1) / grain;
    /* At most a few chunks per thread, each thread taking a contiguous run
     * of them (static): the same share of every range goes to the same
     * thread, so rows one op wrote are in that core's cache when the next
     * op reads them. With dynamic scheduling the rows wandered between cores
     * and a width-64 MLP step ran no faster on two threads than on one
     * (docs/nn.md, "Static chunks"). */
    if (chunks > 4 * (int64_t)threads) chunks = 4 * (int64_t)threads;
    /* Inside a parallel region (a fused op's block worker calling a kernel)
     * the range runs on the calling thread: regions do not nest. */
    if (threads <= 1 || chunks <= 1 || in_parallel()) {
        fn(ctx, 0, n);
        return;
    }
#ifdef _OPENMP
#pragma omp parallel for schedule(static)
#endif
    for (int64_t c = 0; c < chunks; c++) {
        int64_t begin = n * c / chunks, end = n * (c + 1) / chunks;
        if (begin < end) fn(ctx, begin, end);
    }
}
