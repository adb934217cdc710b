/* test_nn_vmath.c: the vector transcendental kernels (cr_nn_cpu_vec_span)
 * on every SIMD level this CPU runs, against double-precision libm applied
 * to the same float inputs: the largest error in units of the float result's
 * last place (ulp; 2^-149 for subnormal results) over dense sweeps of each
 * function's whole range, overflow and underflow included, and the special
 * values (NaN, +-inf, +-0, subnormals, negative logs) classified as the
 * scalar path classifies them. Then the span's bias, multiplier and
 * accumulate options, and the elementwise ops on every level against the
 * scalar level.
 */
#include "crease/nn.h"
#include "nn/cpu/cpu.h"
#include "test.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct vm_case {
    const char *name;
    nn_vec_fn fn;
    float p;
    double lo, hi; /* sweep, linear; or geometric over positive lo..hi when geo */
    int geo;
    double max_ulp; /* allowed; < 0: in ulp of 1 (absolute, 2^-23 units) */
} vm_case;

static const vm_case cases[] = {
    {"exp", NN_VEC_EXP, 0, -110, 95, 0, 1.5},
    {"exp small", NN_VEC_EXP, 0, -1e-3, 1e-3, 0, 1.5},
    {"log", NN_VEC_LOG, 0, 1e-45, 3e38, 1, 1.5},
    {"log near 1", NN_VEC_LOG, 0, 0.5, 2, 0, 1.5},
    {"tanh", NN_VEC_TANH, 0, -12, 12, 0, 2},
    {"tanh tiny", NN_VEC_TANH, 0, 1e-38, 0.7, 1, 2},
    {"sigmoid", NN_VEC_SIGMOID, 0, -110, 95, 0, 2.5},
    {"softplus beta 10", NN_VEC_SOFTPLUS, 10, -12, 12, 0, 4},
    {"softplus beta 1", NN_VEC_SOFTPLUS, 1, -110, 95, 0, 4},
    {"sigmoid scaled", NN_VEC_SIGMOID_SCALED, 10, -11, 9.5, 0, 2.5},
    /* 1 - y^2 cancels near |y| = 1 on both paths: the error is y^2's rounding, so
     * tanh' is measured in ulp of 1 (the `max_ulp < 0` rows) */
    {"tanh' from y", NN_VEC_TANH_DERIV_FROM_Y, 0, -1, 1, 0, -0.5},
    {"sigmoid' from y", NN_VEC_SIGMOID_DERIV_FROM_Y, 0, 0, 1, 0, 2},
    /* 1 - exp(-t) by a series below t = 0.1 on both paths (4.6 ulp measured) */
    {"softplus' from y", NN_VEC_SOFTPLUS_DERIV_FROM_Y, 10, 1e-9, 10, 1, 6},
};

/* The function in double on the float input, as the kernels define it
 * (products with p rounded to float first, as both paths compute them). */
static double ref(const vm_case *c, float x) {
    double d = x;
    float bx = c->p * x;
    switch (c->fn) {
    case NN_VEC_EXP:
        return exp(d);
    case NN_VEC_LOG:
        return log(d);
    case NN_VEC_TANH:
        return tanh(d);
    case NN_VEC_SIGMOID:
        return 1.0 / (1.0 + exp(-d));
    case NN_VEC_SOFTPLUS:
        return ((bx > 0 ? bx : 0.0) + log1p(exp(-fabs((double)bx)))) / c->p;
    case NN_VEC_SIGMOID_SCALED:
        return 1.0 / (1.0 + exp(-(double)bx));
    case NN_VEC_TANH_DERIV_FROM_Y:
        return 1.0 - d * d;
    case NN_VEC_SIGMOID_DERIV_FROM_Y:
        return d * (1.0 - d);
    case NN_VEC_SOFTPLUS_DERIV_FROM_Y:
        return -expm1(-(double)bx);
    }
    return NAN;
}

/* The scalar path's value of the same function. */
static float scalar(const vm_case *c, float x) {
    switch (c->fn) {
    case NN_VEC_EXP:
        return expf(x);
    case NN_VEC_LOG:
        return logf(x);
    case NN_VEC_TANH:
        return tanhf(x);
    case NN_VEC_SIGMOID:
        return nn_cpu_sigmoidf(x);
    case NN_VEC_SOFTPLUS:
        return nn_cpu_softplusf(x, c->p);
    case NN_VEC_SIGMOID_SCALED:
        return nn_cpu_sigmoidf(c->p * x);
    case NN_VEC_TANH_DERIV_FROM_Y:
        return 1.0f - x * x;
    case NN_VEC_SIGMOID_DERIV_FROM_Y:
        return x * (1.0f - x);
    case NN_VEC_SOFTPLUS_DERIV_FROM_Y:
        return nn_cpu_softplus_deriv_from_y(x, c->p);
    }
    return NAN;
}

/* |got - want| in ulp of want rounded to float. */
static double ulp_err(float got, double want) {
    if (isnan(want) || isnan(got)) return isnan(want) && isnan(got) ? 0 : INFINITY;
    if (fabs(want) > FLT_MAX) return got == (float)want ? 0 : INFINITY;
    if (isinf(got)) return INFINITY;
    int e;
    frexp(want, &e); /* |want| in [2^(e-1), 2^e) */
    double ulp = ldexp(1.0, (e - 1 > -126 ? e - 1 : -126) - 23);
    return fabs(got - want) / ulp;
}

enum { SWEEP = 200003 }; /* odd: the last vector is followed by a scalar tail */

CR_TEST(nn_vmath, within_a_few_ulp_of_libm_on_every_level) {
    float *x = malloc(SWEEP * sizeof *x), *y = malloc(SWEEP * sizeof *y);
    CR_REQUIRE(x && y);
    for (int level = NN_SIMD_AVX2; level <= cr_nn_cpu_simd_max(); level++) {
        int width = level == NN_SIMD_AVX512 ? 16 : 8;
        for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
            const vm_case *c = &cases[k];
            for (int i = 0; i < SWEEP; i++) {
                double t = (double)i / (SWEEP - 1);
                x[i] =
                    (float)(c->geo ? c->lo * pow(c->hi / c->lo, t) : c->lo + (c->hi - c->lo) * t);
            }
            int64_t done = cr_nn_cpu_vec_span(level, c->fn, c->p, x, NULL, NULL, y, 0, SWEEP);
            CR_CHECK(done == SWEEP / width * width);
            double worst = 0;
            float at = 0;
            for (int64_t i = 0; i < done; i++) {
                double want = ref(c, x[i]);
                double e = c->max_ulp < 0 ? fabs(y[i] - want) / 0x1p-23 : ulp_err(y[i], want);
                if (e > worst) worst = e, at = x[i];
            }
            if (!(worst <= fabs(c->max_ulp)))
                cr_test_fail_here(__FILE__, __LINE__, "%s on level %d: %.2f ulp at x = %.9g",
                                  c->name, level, worst, (double)at);
        }
    }
    free(x);
    free(y);
}

CR_TEST(nn_vmath, special_values_as_the_scalar_path) {
    const float specials[] = {NAN,     -NAN,    INFINITY, -INFINITY, 0.0f,   -0.0f,   1e-45f,
                              -1e-45f, 1e-40f,  FLT_MIN,  -FLT_MIN,  88.72f, 88.73f,  -87.33f,
                              -103.9f, -104.5f, 200.0f,   -200.0f,   1.0f,   -1.0f,   0.625f,
                              -0.625f, 0.6249f, FLT_MAX,  -FLT_MAX,  1e-20f, -1e-20f, 44.0f,
                              -44.5f,  9.0f,    0.01f,    0.1f};
    enum { N = sizeof specials / sizeof specials[0], PAD = 48 };
    float x[PAD], y[PAD];
    for (int level = NN_SIMD_AVX2; level <= cr_nn_cpu_simd_max(); level++)
        for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
            const vm_case *c = &cases[k];
            for (int i = 0; i < PAD; i++)
                x[i] = specials[i % N];
            int64_t done = cr_nn_cpu_vec_span(level, c->fn, c->p, x, NULL, NULL, y, 0, PAD);
            CR_REQUIRE(done == PAD);
            for (int i = 0; i < PAD; i++) {
                float s = scalar(c, x[i]);
                int same = (isnan(s) && isnan(y[i])) || (isinf(s) && s == y[i]) ||
                           (isfinite(s) && isfinite(y[i]) && signbit(s) == signbit(y[i]) &&
                            ulp_err(y[i], s) <= fabs(c->max_ulp) + 2);
                if (!same)
                    cr_test_fail_here(__FILE__, __LINE__, "%s(%g) on level %d: %g, scalar %g",
                                      c->name, (double)x[i], level, (double)y[i], (double)s);
            }
        }
}

CR_TEST(nn_vmath, bias_multiplier_and_accumulate) {
    enum { N = 37 };
    float x[N] = {0}, b[N], m[N], out[N], want[N];
    CR_CHECK(cr_nn_cpu_vec_span(NN_SIMD_SCALAR, NN_VEC_EXP, 0, x, NULL, NULL, out, 0, N) == 0);
    for (int level = NN_SIMD_AVX2; level <= cr_nn_cpu_simd_max(); level++) {
        for (int i = 0; i < N; i++) {
            x[i] = 0.37f * (float)(i - 18) / 3.0f;
            b[i] = 0.05f * (float)(i % 5) - 0.1f;
            m[i] = 1.5f - 0.07f * (float)i;
            out[i] = 0.25f * (float)i;
            want[i] = out[i] + m[i] * nn_cpu_softplusf(x[i] + b[i], 10.0f);
        }
        int64_t done = cr_nn_cpu_vec_span(level, NN_VEC_SOFTPLUS, 10.0f, x, b, m, out, 1, N);
        CR_CHECK(done == 32); /* 4 vectors of 8 or 2 of 16 */
        for (int64_t i = 0; i < done; i++)
            CR_CHECK_NEAR(out[i], want[i], 1e-6 * (1 + fabsf(want[i])));
        for (int64_t i = done; i < N; i++) /* the tail is the caller's */
            CR_CHECK(out[i] == 0.25f * (float)i);
    }
}

/* Every elementwise op with a vector kernel, on every level, against the
 * scalar level: values and the gradients the backward kernel adds. */
CR_TEST(nn_vmath, elementwise_ops_on_every_level_match_the_scalar_level) {
    enum { N = 1000 };
    static float x[N], pos[N], dy[N], y[3][N], dx[3][N];
    const cr_op ops[] = {CR_OP_EXP, CR_OP_LOG, CR_OP_TANH, CR_OP_SIGMOID, CR_OP_SOFTPLUS};
    for (int i = 0; i < N; i++) {
        x[i] = -30.0f + 60.0f * (float)i / (N - 1);
        pos[i] = 1e-3f + 50.0f * (float)i / (N - 1);
        dy[i] = 1.0f - 0.002f * (float)i;
    }
    int prev = cr_nn_cpu_simd();
    for (size_t k = 0; k < sizeof ops / sizeof ops[0]; k++) {
        cr_op op = ops[k];
        float p = op == CR_OP_SOFTPLUS ? 10.0f : 0.0f;
        const float *in = op == CR_OP_LOG ? pos : x;
        for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
            cr_nn_cpu_set_simd(level);
            cr_nn_cpu_unary_forward(op, p, in, y[level], N);
            for (int i = 0; i < N; i++)
                dx[level][i] = 0.5f;
            cr_nn_cpu_unary_backward(op, p, in, y[level], dy, dx[level], N);
            for (int i = 0; i < N && level > NN_SIMD_SCALAR; i++) {
                if (ulp_err(y[level][i], y[0][i]) > 4)
                    cr_test_fail_here(__FILE__, __LINE__, "%s(%g) level %d: %.9g, scalar %.9g",
                                      cr_op_name(op), (double)in[i], level, (double)y[level][i],
                                      (double)y[0][i]);
                CR_CHECK_NEAR(dx[level][i], dx[0][i], 1e-6 * (1 + fabsf(dx[0][i])));
            }
        }
    }
    cr_nn_cpu_set_simd(prev);
}
