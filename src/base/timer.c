/* timer.c: monotonic wall clock in seconds. */
#define _POSIX_C_SOURCE 199309L
#include "crease/base.h"

#include <time.h>

double cr_time_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
