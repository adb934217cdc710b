/* runner.c: runs registered tests whose name starts with argv[1] (all when absent). */
#define _POSIX_C_SOURCE 200809L
#include "test.h"

#include "crease/base.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum { MAX_TESTS = 1024 };

typedef struct {
    const char *name;
    cr_test_fn fn;
} test_entry;

/* Registration happens in constructors before main, so these are filled once. */
static test_entry tests[MAX_TESTS];
static int test_count;
static int current_failures;
static char tmpdir[256];

void cr_test_register(const char *name, cr_test_fn fn) {
    if (test_count >= MAX_TESTS) {
        fprintf(stderr, "too many tests\n");
        abort();
    }
    tests[test_count].name = name;
    tests[test_count].fn = fn;
    test_count++;
}

void cr_test_fail_here(const char *file, int line, const char *fmt, ...) {
    current_failures++;
    fprintf(stderr, "    %s:%d: ", file, line);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

const char *cr_test_tmpdir(void) {
    return tmpdir;
}

int cr_test_quick(void) {
    const char *v = getenv("CREASE_TEST_QUICK");
    return v && *v && strcmp(v, "0") != 0;
}

static int by_name(const void *a, const void *b) {
    return strcmp(((const test_entry *)a)->name, ((const test_entry *)b)->name);
}

int main(int argc, char **argv) {
    /* as the tool does: ctest runs two test processes on two cores, and
     * libgomp's default spinning after every parallel region made each take
     * the other's core (epnet: 143 s under ctest -j 2 against 41 alone) */
    cr_parallel_prefer_passive_wait(argv);
    const char *filter = argc > 1 ? argv[1] : "";
    snprintf(tmpdir, sizeof tmpdir, "%s/crease-test-%ld",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", (long)getpid());
    mkdir(tmpdir, 0777);
    qsort(tests, (size_t)test_count, sizeof tests[0], by_name);
    int passed = 0, failed = 0;
    for (int i = 0; i < test_count; i++) {
        if (strncmp(tests[i].name, filter, strlen(filter)) != 0) continue;
        current_failures = 0;
        fprintf(stderr, "[ RUN  ] %s\n", tests[i].name);
        double started = cr_time_now();
        tests[i].fn();
        double took = cr_time_now() - started;
        if (current_failures == 0) {
            passed++;
            fprintf(stderr, "[  OK  ] %s (%.2f s)\n", tests[i].name, took);
        } else {
            failed++;
            fprintf(stderr, "[ FAIL ] %s (%d checks failed, %.2f s)\n", tests[i].name,
                    current_failures, took);
        }
    }
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "warning: could not remove %s\n", tmpdir);
    printf("%d passed, %d failed\n", passed, failed);
    if (passed + failed == 0) {
        fprintf(stderr, "no test matches '%s'\n", filter);
        return 1;
    }
    return failed ? 1 : 0;
}
