/* test.h: the project's tiny test framework.
 *
 *   CR_TEST(module, name) { ... }    defines and registers test "module.name"
 *   CR_CHECK(cond)                   fails the test (and goes on) printing the expression
 *   CR_CHECK_NEAR(a, b, tol)         |a - b| <= tol, printing both values
 *   CR_REQUIRE(cond)                 like CR_CHECK but returns from the test
 *
 * One runner (runner.c) runs every test whose name starts with the filter
 * given on its command line and ends with "N passed, N failed".
 */
#ifndef CREASE_TEST_H
#define CREASE_TEST_H

#include <math.h>
#include <stdio.h>

typedef void (*cr_test_fn)(void);
void cr_test_register(const char *name, cr_test_fn fn);
void cr_test_fail_here(const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Scratch directory for files a test writes (created by the runner). */
const char *cr_test_tmpdir(void);
/* 1 where the environment sets CREASE_TEST_QUICK. ctest does in the builds
 * configured with -DCREASE_TEST_QUICK=ON: `make check`'s second compiler
 * (clang) and its sanitizer build, which runs code 3-5x slower. There the
 * heaviest tests train and simulate less and keep every code path; the checks
 * of a physical outcome that need the full size are made once, by the release
 * stage (`make test`). */
int cr_test_quick(void);
/* full in a full run, small in a quick one */
#define CR_TEST_SIZE(full, small) (cr_test_quick() ? (small) : (full))

#define CR_TEST(module, name)                                                                      \
    static void test_##module##_##name(void);                                                      \
    __attribute__((constructor)) static void register_##module##_##name(void) {                    \
        cr_test_register(#module "." #name, test_##module##_##name);                               \
    }                                                                                              \
    static void test_##module##_##name(void)

#define CR_CHECK(cond)                                                                             \
    do {                                                                                           \
        if (!(cond)) cr_test_fail_here(__FILE__, __LINE__, "CHECK(%s)", #cond);                    \
    } while (0)

#define CR_REQUIRE(cond)                                                                           \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            cr_test_fail_here(__FILE__, __LINE__, "REQUIRE(%s)", #cond);                           \
            return;                                                                                \
        }                                                                                          \
    } while (0)

#define CR_CHECK_NEAR(a, b, tol)                                                                   \
    do {                                                                                           \
        double cr_a_ = (double)(a), cr_b_ = (double)(b), cr_t_ = (double)(tol);                    \
        if (!(fabs(cr_a_ - cr_b_) <= cr_t_))                                                       \
            cr_test_fail_here(__FILE__, __LINE__, "CHECK_NEAR(%s, %s): %.9g vs %.9g, tol %.3g",    \
                              #a, #b, cr_a_, cr_b_, cr_t_);                                        \
    } while (0)

/* Status must be CR_OK; prints the error message otherwise. */
#define CR_CHECK_OK(expr, errp)                                                                    \
    do {                                                                                           \
        cr_status cr_s_ = (expr);                                                                  \
        if (cr_s_ != CR_OK)                                                                        \
            cr_test_fail_here(__FILE__, __LINE__, "%s returned %s: %s", #expr,                     \
                              cr_status_str(cr_s_), (errp)->msg);                                  \
    } while (0)

#endif
