/* test_nn_ops.c: every tensor op, forward against closed forms and plain
 * loops, backward against central differences (nn_gradcheck: step 1e-3,
 * pass when |g_tape - g_fd| <= 1e-2 max(1, |g_fd|), the loss sum_i w_i y_i
 * accumulated in double with random weights w). Covers broadcasting
 * ((N,3)+(3), (N,1)*(N,3), (2,1,3)-(1,4,1), scalars), every transpose of
 * matmul, grouped weights, and the BLAS GEMM against its naive reference.
 */
#include "crease/nn.h"
#include "nn/cpu/cpu.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------- unary -- */

typedef struct unary_case {
    const char *name;
    cr_tensor *(*f)(cr_nn_ctx *, cr_tensor *);
    cr_tensor *(*fp)(cr_nn_ctx *, cr_tensor *, float);
    float p, lo, hi, gap;
    double (*ref)(double x, double p);
} unary_case;

static double r_add(double x, double p) {
    return x + p;
}
static double r_mul(double x, double p) {
    return x * p;
}
static double r_pow(double x, double p) {
    return pow(x, p);
}
static double r_relu(double x, double p) {
    (void)p;
    return x > 0 ? x : 0;
}
static double r_leaky(double x, double p) {
    return x > 0 ? x : p * x;
}
static double r_leaky_d(double x, double p) {
    return x > 0 ? 1 : p;
}
static double r_tanh(double x, double p) {
    (void)p;
    return tanh(x);
}
static double r_sigmoid(double x, double p) {
    (void)p;
    return 1 / (1 + exp(-x));
}
static double r_softplus(double x, double p) {
    return log1p(exp(p * x)) / p;
}
static double r_sin(double x, double p) {
    (void)p;
    return sin(x);
}
static double r_cos(double x, double p) {
    (void)p;
    return cos(x);
}
static double r_exp(double x, double p) {
    (void)p;
    return exp(x);
}
static double r_log(double x, double p) {
    (void)p;
    return log(x);
}
static double r_sqrt(double x, double p) {
    (void)p;
    return sqrt(x);
}
static double r_abs(double x, double p) {
    (void)p;
    return fabs(x);
}
static double r_square(double x, double p) {
    (void)p;
    return x * x;
}
static double r_dtanh(double x, double p) {
    (void)p;
    return 1 - tanh(x) * tanh(x);
}
static double r_dsigmoid(double x, double p) {
    double s = r_sigmoid(x, p);
    return s * (1 - s);
}
static double r_dsoftplus(double x, double p) {
    return r_sigmoid(p * x, 0);
}

static const unary_case unary_cases[] = {
    {"add_scalar", NULL, cr_nn_add_scalar, 0.7f, -2, 2, 0, r_add},
    {"mul_scalar", NULL, cr_nn_mul_scalar, -1.3f, -2, 2, 0, r_mul},
    {"pow", NULL, cr_nn_pow, 1.7f, 0.3f, 2, 0, r_pow},
    {"relu", cr_nn_relu, NULL, 0, -2, 2, 0.05f, r_relu},
    {"leaky_relu", NULL, cr_nn_leaky_relu, 0.1f, -2, 2, 0.05f, r_leaky},
    {"leaky_relu_deriv", NULL, cr_nn_leaky_relu_deriv, 0.2f, -2, 2, 0.05f, r_leaky_d},
    {"tanh", cr_nn_tanh, NULL, 0, -2, 2, 0, r_tanh},
    {"sigmoid", cr_nn_sigmoid, NULL, 0, -3, 3, 0, r_sigmoid},
    {"softplus", NULL, cr_nn_softplus, 2.0f, -2, 2, 0, r_softplus},
    {"sin", cr_nn_sin, NULL, 0, -3, 3, 0, r_sin},
    {"cos", cr_nn_cos, NULL, 0, -3, 3, 0, r_cos},
    {"exp", cr_nn_exp, NULL, 0, -2, 1.5f, 0, r_exp},
    {"log", cr_nn_log, NULL, 0, 0.2f, 3, 0, r_log},
    {"sqrt", cr_nn_sqrt, NULL, 0, 0.2f, 3, 0, r_sqrt},
    {"abs", cr_nn_abs, NULL, 0, -2, 2, 0.05f, r_abs},
    {"square", cr_nn_square, NULL, 0, -2, 2, 0, r_square},
    {"tanh_deriv", cr_nn_tanh_deriv, NULL, 0, -2, 2, 0, r_dtanh},
    {"sigmoid_deriv", cr_nn_sigmoid_deriv, NULL, 0, -3, 3, 0, r_dsigmoid},
    {"softplus_deriv", NULL, cr_nn_softplus_deriv, 1.5f, -2, 2, 0, r_dsoftplus},
};

static cr_tensor *build_unary(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const unary_case *u = user;
    return u->f ? u->f(ctx, in[0]) : u->fp(ctx, in[0], u->p);
}

/* On every SIMD level (the vector kernels of exp, log, tanh, sigmoid and
 * softplus); 3 x 13 elements: whole 8- and 16-wide vectors and a scalar tail. */
CR_TEST(nn_ops, unary_values_and_gradients) {
    enum { R = 3, C = 13 };
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    int ncases = (int)(sizeof unary_cases / sizeof unary_cases[0]);
    int prev = cr_nn_cpu_simd();
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (int c = 0; c < ncases; c++) {
            const unary_case *u = &unary_cases[c];
            float x[R * C];
            nn_gradcheck_fill(x, R * C, u->lo, u->hi, u->gap, 10 + (uint64_t)c);
            cr_nn_ctx_reset(ctx);
            cr_tensor *t = cr_nn_from(ctx, 2, (int64_t[]){R, C}, x);
            cr_tensor *y = build_unary(ctx, &t, (void *)u);
            CR_REQUIRE(y && y->ndim == 2 && y->shape[1] == C);
            for (int i = 0; i < R * C; i++) {
                double want = u->ref(x[i], u->p);
                if (fabs(y->data[i] - want) > 1e-5 * fmax(1, fabs(want)))
                    cr_test_fail_here(__FILE__, __LINE__, "%s(%g) on SIMD level %d: %g, want %g",
                                      u->name, x[i], level, y->data[i], want);
            }
            nn_gradcheck_input in = nn_gradcheck_in(2, (int64_t[]){R, C}, x);
            if (nn_gradcheck_quick(u->name, 1, &in, NULL, build_unary, (void *)u) != 0)
                cr_test_fail_here(__FILE__, __LINE__, "gradient of %s on SIMD level %d", u->name,
                                  level);
        }
    }
    cr_nn_cpu_set_simd(prev);
    /* Stable at extreme inputs. */
    cr_nn_ctx_reset(ctx);
    float big[4] = {-200, -30, 30, 200};
    cr_tensor *t = cr_nn_from(ctx, 1, (int64_t[]){4}, big);
    cr_tensor *sp = cr_nn_softplus(ctx, t, 1.0f), *sg = cr_nn_sigmoid(ctx, t);
    CR_REQUIRE(sp && sg);
    CR_CHECK(sp->data[0] >= 0 && sp->data[0] < 1e-30 && fabsf(sp->data[3] - 200) < 1e-4f);
    CR_CHECK(sg->data[0] == 0.0f && sg->data[3] == 1.0f && isfinite(sp->data[1]));
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------------------------ binary -- */

static cr_tensor *build_binary(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    switch (*(const int *)user) {
    case 0:
        return cr_nn_add(ctx, in[0], in[1]);
    case 1:
        return cr_nn_sub(ctx, in[0], in[1]);
    case 2:
        return cr_nn_mul(ctx, in[0], in[1]);
    default:
        return cr_nn_div(ctx, in[0], in[1]);
    }
}

/* Reference broadcasting by explicit index arithmetic on padded shapes. */
static float ref_binary(int op, const float *a, const int64_t as[4], const float *b,
                        const int64_t bs[4], const int64_t idx[4]) {
    int64_t ia = 0, ib = 0;
    for (int k = 0; k < 4; k++) {
        ia = ia * as[k] + (as[k] == 1 ? 0 : idx[k]);
        ib = ib * bs[k] + (bs[k] == 1 ? 0 : idx[k]);
    }
    float x = a[ia], y = b[ib];
    return op == 0 ? x + y : op == 1 ? x - y : op == 2 ? x * y : x / y;
}

CR_TEST(nn_ops, binary_broadcasting_values_and_gradients) {
    /* shapes: (a, b) pairs */
    static const struct {
        int na, nb;
        int64_t a[4], b[4];
    } cases[] = {
        {2, 2, {4, 3}, {4, 3}},       {2, 1, {5, 3}, {3}}, {2, 2, {5, 1}, {5, 3}},
        {3, 3, {2, 1, 3}, {1, 4, 1}}, {1, 0, {3}, {0}},    {4, 2, {2, 3, 1, 2}, {3, 2}},
    };
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        for (int op = 0; op < 4; op++) {
            float a[32], b[32];
            int64_t na = 1, nb = 1;
            for (int i = 0; i < cases[c].na; i++)
                na *= cases[c].a[i];
            for (int i = 0; i < cases[c].nb; i++)
                nb *= cases[c].b[i];
            nn_gradcheck_fill(a, na, -2, 2, 0, 100 + c);
            nn_gradcheck_fill(b, nb, op == 3 ? 0.5f : -2, 2, 0, 200 + c);
            cr_nn_ctx_reset(ctx);
            cr_tensor *ts[2] = {cr_nn_from(ctx, cases[c].na, cases[c].a, a),
                                cr_nn_from(ctx, cases[c].nb, cases[c].b, b)};
            cr_tensor *y = build_binary(ctx, ts, &op);
            CR_REQUIRE(y);
            int64_t as[4], bs[4], ys[4];
            for (int k = 0; k < 4; k++) {
                as[k] = k < 4 - ts[0]->ndim ? 1 : ts[0]->shape[k - (4 - ts[0]->ndim)];
                bs[k] = k < 4 - ts[1]->ndim ? 1 : ts[1]->shape[k - (4 - ts[1]->ndim)];
                ys[k] = as[k] > bs[k] ? as[k] : bs[k];
            }
            int64_t n = 0;
            for (int64_t i0 = 0; i0 < ys[0]; i0++)
                for (int64_t i1 = 0; i1 < ys[1]; i1++)
                    for (int64_t i2 = 0; i2 < ys[2]; i2++)
                        for (int64_t i3 = 0; i3 < ys[3]; i3++, n++) {
                            int64_t idx[4] = {i0, i1, i2, i3};
                            CR_CHECK_NEAR(y->data[n], ref_binary(op, a, as, b, bs, idx), 1e-6);
                        }
            CR_CHECK(n == y->numel);
            nn_gradcheck_input in[2] = {nn_gradcheck_in(cases[c].na, cases[c].a, a),
                                        nn_gradcheck_in(cases[c].nb, cases[c].b, b)};
            if (nn_gradcheck_quick("binary", 2, in, NULL, build_binary, &op) != 0)
                cr_test_fail_here(__FILE__, __LINE__, "binary op %d, case %zu", op, c);
        }
    }
    cr_nn_ctx_destroy(ctx);
}

/* ---------------------------------------------------------- reduction -- */

typedef struct reduce_case {
    int kind; /* 0 sum, 1 mean, 2 sum_axis, 3 mean_axis */
    int axis, keepdim;
} reduce_case;

static cr_tensor *build_reduce(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const reduce_case *r = user;
    switch (r->kind) {
    case 0:
        return cr_nn_sum(ctx, in[0]);
    case 1:
        return cr_nn_mean(ctx, in[0]);
    case 2:
        return cr_nn_sum_axis(ctx, in[0], r->axis, r->keepdim);
    default:
        return cr_nn_mean_axis(ctx, in[0], r->axis, r->keepdim);
    }
}

CR_TEST(nn_ops, reductions) {
    float x[24];
    nn_gradcheck_fill(x, 24, -2, 2, 0, 7);
    int64_t shape[3] = {2, 3, 4};
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *t = cr_nn_from(ctx, 3, shape, x);
    /* sum over axis 1 by hand */
    cr_tensor *s1 = cr_nn_sum_axis(ctx, t, 1, 0), *m1 = cr_nn_mean_axis(ctx, t, -2, 1);
    CR_REQUIRE(s1 && m1 && s1->ndim == 2 && m1->ndim == 3 && m1->shape[1] == 1);
    for (int i = 0; i < 2; i++)
        for (int k = 0; k < 4; k++) {
            double s = 0;
            for (int j = 0; j < 3; j++)
                s += x[(i * 3 + j) * 4 + k];
            CR_CHECK_NEAR(s1->data[i * 4 + k], s, 1e-6);
            CR_CHECK_NEAR(m1->data[i * 4 + k], s / 3, 1e-6);
        }
    double total = 0;
    for (int i = 0; i < 24; i++)
        total += x[i];
    CR_CHECK_NEAR(cr_nn_sum(ctx, t)->data[0], total, 1e-5);
    CR_CHECK_NEAR(cr_nn_mean(ctx, t)->data[0], total / 24, 1e-6);
    cr_nn_ctx_destroy(ctx);
    reduce_case cases[] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 1},
                           {2, 2, 0}, {3, 0, 1}, {3, 1, 0}, {3, -1, 1}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        nn_gradcheck_input in = nn_gradcheck_in(3, shape, x);
        if (nn_gradcheck_quick("reduce", 1, &in, NULL, build_reduce, &cases[c]) != 0)
            cr_test_fail_here(__FILE__, __LINE__, "reduce case %zu", c);
    }
}

/* ------------------------------------------------------------- matmul -- */

typedef struct mm_case {
    int ta, tb, batched, grouped, bias;
    const int32_t *group;
} mm_case;

/* Two inputs: A and B, or x and the grouped weights. */
static cr_tensor *build_mm(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const mm_case *m = user;
    if (m->grouped) return cr_nn_matmul_grouped(ctx, in[0], in[1], m->group, m->tb);
    return cr_nn_matmul(ctx, in[0], in[1], m->ta, m->tb);
}

/* x and W, and the bias as a third input when m->bias. */
static cr_tensor *build_linear(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const mm_case *m = user;
    return cr_nn_linear(ctx, in[0], in[1], m->bias ? in[2] : NULL);
}

CR_TEST(nn_ops, gemm_matches_naive_reference) {
    cr_rng r = cr_rng_make(5, 0);
    for (int t = 0; t < 4; t++) {
        int ta = t & 1, tb = t >> 1;
        int64_t M = 7, N = 5, K = 9;
        float A[63], B[45], C1[35], C2[35];
        for (int i = 0; i < 63; i++)
            A[i] = cr_rng_uniformf(&r) - 0.5f;
        for (int i = 0; i < 45; i++)
            B[i] = cr_rng_uniformf(&r) - 0.5f;
        for (int i = 0; i < 35; i++)
            C1[i] = C2[i] = cr_rng_uniformf(&r);
        cr_nn_cpu_gemm(ta, tb, M, N, K, 0.5f, A, ta ? M : K, B, tb ? K : N, 0.25f, C1, N);
        cr_nn_cpu_gemm_naive(ta, tb, M, N, K, 0.5f, A, ta ? M : K, B, tb ? K : N, 0.25f, C2, N);
        for (int i = 0; i < 35; i++)
            CR_CHECK_NEAR(C1[i], C2[i], 1e-5);
    }
}

CR_TEST(nn_ops, matmul_gradients) {
    float a[2 * 4 * 3], b[2 * 3 * 5];
    nn_gradcheck_fill(a, 24, -1, 1, 0, 31);
    nn_gradcheck_fill(b, 30, -1, 1, 0, 32);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    for (int t = 0; t < 8; t++) {
        mm_case m = {.ta = t & 1, .tb = (t >> 1) & 1, .batched = t >> 2};
        int64_t M = 4, K = 3, N = 5;
        int64_t as[3] = {2, m.ta ? K : M, m.ta ? M : K}, bs[3] = {2, m.tb ? N : K, m.tb ? K : N};
        int nd = m.batched ? 3 : 2;
        const int64_t *ash = m.batched ? as : as + 1, *bsh = m.batched ? bs : bs + 1;
        /* forward against the naive product, batch entry 0 */
        cr_nn_ctx_reset(ctx);
        cr_tensor *ts[2] = {cr_nn_from(ctx, nd, ash, a), cr_nn_from(ctx, nd, bsh, b)};
        cr_tensor *y = build_mm(ctx, ts, &m);
        CR_REQUIRE(y && y->shape[nd - 2] == M && y->shape[nd - 1] == N);
        float ref[20];
        cr_nn_cpu_gemm_naive(m.ta, m.tb, M, N, K, 1, a, m.ta ? M : K, b, m.tb ? K : N, 0, ref, N);
        for (int i = 0; i < 20; i++)
            CR_CHECK_NEAR(y->data[i], ref[i], 1e-5);
        nn_gradcheck_input in[2] = {nn_gradcheck_in(nd, ash, a), nn_gradcheck_in(nd, bsh, b)};
        if (nn_gradcheck_quick("matmul", 2, in, NULL, build_mm, &m) != 0)
            cr_test_fail_here(__FILE__, __LINE__, "matmul ta=%d tb=%d batched=%d", m.ta, m.tb,
                              m.batched);
    }
    cr_nn_ctx_destroy(ctx);
}

CR_TEST(nn_ops, matmul_grouped_and_linear) {
    /* 7 rows in 3 groups, unsorted; group 1 has one row. */
    static const int32_t group[7] = {2, 0, 2, 1, 0, 2, 0};
    float x[7 * 4], w[3 * 4 * 5];
    nn_gradcheck_fill(x, 28, -1, 1, 0, 41);
    nn_gradcheck_fill(w, 60, -1, 1, 0, 42);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    for (int tw = 0; tw < 2; tw++) {
        mm_case m = {.grouped = 1, .tb = tw, .group = group};
        int64_t ws[3] = {3, tw ? 5 : 4, tw ? 4 : 5};
        cr_nn_ctx_reset(ctx);
        cr_tensor *ts[2] = {cr_nn_from(ctx, 2, (int64_t[]){7, 4}, x), cr_nn_from(ctx, 3, ws, w)};
        cr_tensor *y = build_mm(ctx, ts, &m);
        CR_REQUIRE(y && y->shape[0] == 7 && y->shape[1] == 5);
        for (int i = 0; i < 7; i++)
            for (int j = 0; j < 5; j++) {
                double s = 0;
                const float *wg = w + group[i] * 20;
                for (int k = 0; k < 4; k++)
                    s += x[i * 4 + k] * (tw ? wg[j * 4 + k] : wg[k * 5 + j]);
                CR_CHECK_NEAR(y->data[i * 5 + j], s, 1e-5);
            }
        nn_gradcheck_input in[2] = {nn_gradcheck_in(2, (int64_t[]){7, 4}, x),
                                    nn_gradcheck_in(3, ws, w)};
        CR_CHECK(nn_gradcheck_quick("matmul_grouped", 2, in, NULL, build_mm, &m) == 0);
    }
    /* linear: x (2,3,4), W (5,4), b (5); with and without bias */
    float bias[5];
    nn_gradcheck_fill(bias, 5, -1, 1, 0, 43);
    for (int with_bias = 0; with_bias < 2; with_bias++) {
        mm_case m = {.bias = with_bias};
        cr_nn_ctx_reset(ctx);
        cr_tensor *ts[3] = {cr_nn_from(ctx, 3, (int64_t[]){2, 3, 4}, x),
                            cr_nn_from(ctx, 2, (int64_t[]){5, 4}, w),
                            cr_nn_from(ctx, 1, (int64_t[]){5}, bias)};
        cr_tensor *y = build_linear(ctx, ts, &m);
        CR_REQUIRE(y && y->ndim == 3 && y->shape[2] == 5);
        for (int r = 0; r < 6; r++)
            for (int o = 0; o < 5; o++) {
                double s = with_bias ? bias[o] : 0;
                for (int k = 0; k < 4; k++)
                    s += x[r * 4 + k] * w[o * 4 + k];
                CR_CHECK_NEAR(y->data[r * 5 + o], s, 1e-5);
            }
        nn_gradcheck_input in[3] = {nn_gradcheck_in(3, (int64_t[]){2, 3, 4}, x),
                                    nn_gradcheck_in(2, (int64_t[]){5, 4}, w),
                                    nn_gradcheck_in(1, (int64_t[]){5}, bias)};
        CR_CHECK(nn_gradcheck_quick("linear", with_bias ? 3 : 2, in, NULL, build_linear, &m) == 0);
    }
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------------------------ indexing -- */

typedef struct index_case {
    int kind; /* 0 concat axis, 1 slice, 2 gather, 3 scatter-add, 4 segment softmax */
    int axis;
    int64_t start, len, n;
    const int32_t *idx;
} index_case;

static cr_tensor *build_index(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const index_case *c = user;
    switch (c->kind) {
    case 0:
        return cr_nn_concat(ctx, 3, in, c->axis);
    case 1:
        return cr_nn_slice(ctx, in[0], c->axis, c->start, c->len);
    case 2:
        return cr_nn_gather_rows(ctx, in[0], c->idx, c->n);
    case 3:
        return cr_nn_scatter_add_rows(ctx, in[0], c->idx, c->n);
    default:
        return cr_nn_segment_softmax(ctx, in[0], c->idx, c->n);
    }
}

CR_TEST(nn_ops, concat_and_slice) {
    float a[12], b[12], c[12];
    nn_gradcheck_fill(a, 12, -1, 1, 0, 51);
    nn_gradcheck_fill(b, 12, -1, 1, 0, 52);
    nn_gradcheck_fill(c, 12, -1, 1, 0, 53);
    /* axis 0: (2,3)+(1,3)+(3,3); axis 1: (2,2)+(2,1)+(2,3) */
    int64_t s0[3][2] = {{2, 3}, {1, 3}, {3, 3}}, s1[3][2] = {{2, 2}, {2, 1}, {2, 3}};
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *ts[3] = {cr_nn_from(ctx, 2, s1[0], a), cr_nn_from(ctx, 2, s1[1], b),
                        cr_nn_from(ctx, 2, s1[2], c)};
    cr_tensor *y = cr_nn_concat(ctx, 3, ts, 1);
    CR_REQUIRE(y && y->shape[0] == 2 && y->shape[1] == 6);
    const float want_row1[6] = {a[2], a[3], b[1], c[3], c[4], c[5]};
    for (int j = 0; j < 6; j++)
        CR_CHECK(y->data[6 + j] == want_row1[j]);
    cr_nn_ctx_destroy(ctx);
    for (int axis = 0; axis < 2; axis++) {
        index_case ic = {.kind = 0, .axis = axis};
        int64_t(*s)[2] = axis ? s1 : s0;
        nn_gradcheck_input in[3] = {nn_gradcheck_in(2, s[0], a), nn_gradcheck_in(2, s[1], b),
                                    nn_gradcheck_in(2, s[2], c)};
        CR_CHECK(nn_gradcheck_quick("concat", 3, in, NULL, build_index, &ic) == 0);
    }
    index_case sl[3] = {{.kind = 1, .axis = 1, .start = 1, .len = 1},
                        {.kind = 1, .axis = 0, .start = 1, .len = 2},
                        {.kind = 1, .axis = -1, .start = 0, .len = 1}};
    for (int i = 0; i < 3; i++) {
        nn_gradcheck_input in = nn_gradcheck_in(3, (int64_t[]){3, 2, 2}, a);
        CR_CHECK(nn_gradcheck_quick("slice", 1, &in, NULL, build_index, &sl[i]) == 0);
    }
}

CR_TEST(nn_ops, gather_scatter_segment_softmax) {
    static const int32_t gidx[6] = {3, 0, 3, 1, 3, 2};   /* repeats: backward accumulates */
    static const int32_t sidx[5] = {1, 4, 1, 0, 4};      /* rows 2, 3 receive nothing */
    static const int32_t seg[7] = {2, 0, 2, 2, 0, 3, 0}; /* segment 1 empty, 3 single */
    float x[4 * 3], e[5 * 2], logits[7 * 2];
    nn_gradcheck_fill(x, 12, -1, 1, 0, 61);
    nn_gradcheck_fill(e, 10, -1, 1, 0, 62);
    nn_gradcheck_fill(logits, 14, -2, 2, 0, 63);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *g = cr_nn_gather_rows(ctx, cr_nn_from(ctx, 2, (int64_t[]){4, 3}, x), gidx, 6);
    CR_REQUIRE(g && g->shape[0] == 6);
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 3; j++)
            CR_CHECK(g->data[i * 3 + j] == x[gidx[i] * 3 + j]);
    cr_tensor *s = cr_nn_scatter_add_rows(ctx, cr_nn_from(ctx, 2, (int64_t[]){5, 2}, e), sidx, 5);
    CR_REQUIRE(s && s->shape[0] == 5);
    CR_CHECK_NEAR(s->data[2], e[0] + e[4], 1e-6);
    CR_CHECK_NEAR(s->data[9], e[3] + e[9], 1e-6);
    CR_CHECK(s->data[4] == 0 && s->data[7] == 0);
    /* softmax: large shifts do not overflow; each segment's column sums to 1 */
    float shifted[14];
    for (int i = 0; i < 14; i++)
        shifted[i] = logits[i] + 1000.0f;
    cr_tensor *sm =
        cr_nn_segment_softmax(ctx, cr_nn_from(ctx, 2, (int64_t[]){7, 2}, shifted), seg, 4);
    CR_REQUIRE(sm);
    for (int sgm = 0; sgm < 4; sgm++)
        for (int h = 0; h < 2; h++) {
            double tot = 0, mx = -1e30, z = 0;
            for (int i = 0; i < 7; i++)
                if (seg[i] == sgm) mx = fmax(mx, shifted[i * 2 + h]);
            for (int i = 0; i < 7; i++)
                if (seg[i] == sgm) z += exp(shifted[i * 2 + h] - mx);
            for (int i = 0; i < 7; i++)
                if (seg[i] == sgm) {
                    tot += sm->data[i * 2 + h];
                    CR_CHECK_NEAR(sm->data[i * 2 + h], exp(shifted[i * 2 + h] - mx) / z, 1e-6);
                }
            if (sgm != 1) CR_CHECK_NEAR(tot, 1.0, 1e-6);
        }
    cr_nn_ctx_destroy(ctx);
    index_case cg = {.kind = 2, .idx = gidx, .n = 6}, cs = {.kind = 3, .idx = sidx, .n = 5},
               cm = {.kind = 4, .idx = seg, .n = 4};
    nn_gradcheck_input in_g = nn_gradcheck_in(2, (int64_t[]){4, 3}, x);
    nn_gradcheck_input in_s = nn_gradcheck_in(2, (int64_t[]){5, 2}, e);
    nn_gradcheck_input in_m = nn_gradcheck_in(2, (int64_t[]){7, 2}, logits);
    CR_CHECK(nn_gradcheck_quick("gather_rows", 1, &in_g, NULL, build_index, &cg) == 0);
    CR_CHECK(nn_gradcheck_quick("scatter_add_rows", 1, &in_s, NULL, build_index, &cs) == 0);
    CR_CHECK(nn_gradcheck_quick("segment_softmax", 1, &in_m, NULL, build_index, &cm) == 0);
    in_m.ndim = 1; /* (E) form */
    in_m.shape[0] = 7;
    CR_CHECK(nn_gradcheck_quick("segment_softmax 1-D", 1, &in_m, NULL, build_index, &cm) == 0);
}

/* -------------------------------------------------------- vector ops -- */

static cr_tensor *build_vector(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    switch (*(const int *)user) {
    case 0:
        return cr_nn_layer_norm(ctx, in[0], in[1], in[2], 1e-5f);
    case 1:
        return cr_nn_layer_norm(ctx, in[0], NULL, NULL, 1e-5f);
    case 2:
        return cr_nn_cross(ctx, in[0], in[1]);
    case 3:
        return cr_nn_dot(ctx, in[0], in[1]);
    case 4:
        return cr_nn_norm(ctx, in[0], 1e-12f);
    default:
        return cr_nn_normalize(ctx, in[0], 1e-12f);
    }
}

CR_TEST(nn_ops, layer_norm_cross_dot_norm_normalize) {
    float x[4 * 3], y[4 * 3], w[3], b[3];
    nn_gradcheck_fill(x, 12, -2, 2, 0, 71);
    nn_gradcheck_fill(y, 12, -2, 2, 0, 72);
    nn_gradcheck_fill(w, 3, 0.5f, 1.5f, 0, 73);
    nn_gradcheck_fill(b, 3, -1, 1, 0, 74);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *tx = cr_nn_from(ctx, 2, (int64_t[]){4, 3}, x);
    cr_tensor *ty = cr_nn_from(ctx, 2, (int64_t[]){4, 3}, y);
    cr_tensor *tw = cr_nn_from(ctx, 1, (int64_t[]){3}, w),
              *tb = cr_nn_from(ctx, 1, (int64_t[]){3}, b);
    cr_tensor *ln = cr_nn_layer_norm(ctx, tx, tw, tb, 1e-5f);
    cr_tensor *cx = cr_nn_cross(ctx, tx, ty), *dt = cr_nn_dot(ctx, tx, ty);
    cr_tensor *nm = cr_nn_norm(ctx, tx, 1e-12f), *nz = cr_nn_normalize(ctx, tx, 1e-12f);
    CR_REQUIRE(ln && cx && dt && nm && nz && dt->shape[1] == 1 && nm->shape[1] == 1);
    for (int r = 0; r < 4; r++) {
        const float *a = x + 3 * r, *c = y + 3 * r;
        double m = (a[0] + a[1] + a[2]) / 3.0, v = 0;
        for (int k = 0; k < 3; k++)
            v += (a[k] - m) * (a[k] - m) / 3.0;
        for (int k = 0; k < 3; k++)
            CR_CHECK_NEAR(ln->data[3 * r + k], (a[k] - m) / sqrt(v + 1e-5) * w[k] + b[k], 1e-5);
        CR_CHECK_NEAR(cx->data[3 * r + 0], a[1] * c[2] - a[2] * c[1], 1e-6);
        CR_CHECK_NEAR(cx->data[3 * r + 2], a[0] * c[1] - a[1] * c[0], 1e-6);
        CR_CHECK_NEAR(dt->data[r], a[0] * c[0] + a[1] * c[1] + a[2] * c[2], 1e-5);
        double n = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        CR_CHECK_NEAR(nm->data[r], n, 1e-6);
        CR_CHECK_NEAR(nz->data[3 * r + 1], a[1] / n, 1e-6);
    }
    /* A zero row: norm 0 with a zero (finite) gradient. */
    cr_nn_ctx_reset(ctx);
    float zero[3] = {0, 0, 0};
    cr_tensor *z = cr_nn_from(ctx, 2, (int64_t[]){1, 3}, zero);
    z->requires_grad = 1;
    cr_error err = {0};
    CR_CHECK_OK(cr_nn_backward(ctx, cr_nn_sum(ctx, cr_nn_norm(ctx, z, 1e-12f)), &err), &err);
    CR_CHECK(z->grad && z->grad[0] == 0 && z->grad[2] == 0);
    cr_nn_ctx_destroy(ctx);
    for (int k = 0; k < 6; k++) {
        nn_gradcheck_input in[3] = {nn_gradcheck_in(2, (int64_t[]){4, 3}, x),
                                    nn_gradcheck_in(2, (int64_t[]){4, 3}, y),
                                    nn_gradcheck_in(1, (int64_t[]){3}, b)};
        if (k == 0) in[1] = nn_gradcheck_in(1, (int64_t[]){3}, w);
        int nin = k == 0 ? 3 : (k == 2 || k == 3) ? 2 : 1;
        if (nn_gradcheck_quick("vector op", nin, in, NULL, build_vector, &k) != 0)
            cr_test_fail_here(__FILE__, __LINE__, "vector op %d", k);
    }
}
