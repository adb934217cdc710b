/* test_nn_linear_act.c: the fused linear + activation (cr_nn_linear_act)
 * and the MLP built on it, on every SIMD path this CPU runs: values against
 * the unfused ops (linear, then the activation op), gradients against
 * central differences, the bias sum and the uninitialised input grad
 * (assigned with beta = 0) when the input also feeds other ops.
 * Sizes: 19 outputs = two 8-wide AVX2 chunks or one 16-wide AVX-512 one, and a scalar tail.
 */
#include "crease/nn.h"
#include "crease/nn_layers.h"
#include "nn/cpu/cpu.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <string.h>

enum { ROWS = 7, IN = 5, OUT = 19 };

typedef struct act_case {
    const char *name;
    cr_op op;
    float p;
    int shared; /* 1: x also feeds a second linear and a sum (grad accumulates) */
} act_case;

static const act_case cases[] = {
    {"none", CR_OP_NONE, 0.0f, 0},
    {"relu", CR_OP_RELU, 0.0f, 0},
    {"leaky", CR_OP_LEAKY_RELU, 0.1f, 0},
    {"tanh", CR_OP_TANH, 0.0f, 0},
    {"sigmoid", CR_OP_SIGMOID, 0.0f, 0},
    {"softplus", CR_OP_SOFTPLUS, 10.0f, 0},
    {"softplus soft", CR_OP_SOFTPLUS, 1.0f, 0},
    {"relu shared", CR_OP_RELU, 0.0f, 1},
};

static cr_tensor *unfused(cr_nn_ctx *ctx, const act_case *c, cr_tensor *z) {
    switch (c->op) {
    case CR_OP_RELU:
        return cr_nn_relu(ctx, z);
    case CR_OP_LEAKY_RELU:
        return cr_nn_leaky_relu(ctx, z, c->p);
    case CR_OP_TANH:
        return cr_nn_tanh(ctx, z);
    case CR_OP_SIGMOID:
        return cr_nn_sigmoid(ctx, z);
    case CR_OP_SOFTPLUS:
        return cr_nn_softplus(ctx, z, c->p);
    default:
        return z;
    }
}

/* in: x (ROWS,IN), W (OUT,IN), b (OUT). */
static cr_tensor *build(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const act_case *c = user;
    cr_tensor *y = cr_nn_linear_act(ctx, in[0], in[1], in[2], c->op, c->p);
    if (!c->shared) return y;
    /* x's grad: first from sum(x) (zeroed), then both linears add into it */
    cr_tensor *y2 = cr_nn_linear_act(ctx, in[0], in[1], NULL, c->op, c->p);
    cr_tensor *s = cr_nn_sum(ctx, cr_nn_square(ctx, in[0]));
    return cr_nn_add(ctx, cr_nn_add(ctx, y, cr_nn_mul_scalar(ctx, y2, 0.5f)), s);
}

CR_TEST(nn_linear_act, matches_unfused_ops_and_finite_differences_on_every_path) {
    float x[ROWS * IN], w[OUT * IN], b[OUT];
    nn_gradcheck_fill(w, OUT * IN, -1, 1, 0, 72);
    nn_gradcheck_fill(b, OUT, -0.5f, 0.5f, 0, 73);
    /* x from the first seed that keeps every pre-activation 0.02 clear of
     * relu's kink (the FD step moves it by about 1e-3) */
    int clear = 0;
    for (uint64_t seed = 71; seed < 171 && !clear; seed++) {
        nn_gradcheck_fill(x, ROWS * IN, -1, 1, 0, seed);
        clear = 1;
        for (int r = 0; r < ROWS; r++)
            for (int o = 0; o < OUT; o++) {
                double z = b[o];
                for (int k = 0; k < IN; k++)
                    z += x[r * IN + k] * w[o * IN + k];
                clear &= fabs(z) > 0.02;
            }
    }
    CR_REQUIRE(clear);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    int prev = cr_nn_cpu_simd();
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        CR_CHECK(cr_nn_cpu_simd() == level);
        for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
            const act_case *c = &cases[k];
            cr_nn_ctx_reset(ctx);
            cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){ROWS, IN}, x);
            cr_tensor *wt = cr_nn_from(ctx, 2, (int64_t[]){OUT, IN}, w);
            cr_tensor *bt = cr_nn_from(ctx, 1, (int64_t[]){OUT}, b);
            cr_tensor *fused = cr_nn_linear_act(ctx, xt, wt, bt, c->op, c->p);
            cr_tensor *ref = unfused(ctx, c, cr_nn_linear(ctx, xt, wt, bt));
            CR_REQUIRE(fused && ref && fused->numel == ROWS * OUT);
            for (int i = 0; i < ROWS * OUT; i++)
                CR_CHECK_NEAR(fused->data[i], ref->data[i], 1e-6);
            nn_gradcheck_input in[3] = {nn_gradcheck_in(2, (int64_t[]){ROWS, IN}, x),
                                        nn_gradcheck_in(2, (int64_t[]){OUT, IN}, w),
                                        nn_gradcheck_in(1, (int64_t[]){OUT}, b)};
            if (nn_gradcheck_quick(c->name, 3, in, NULL, build, (void *)c) != 0)
                cr_test_fail_here(__FILE__, __LINE__, "linear_act %s on SIMD level %d", c->name,
                                  level);
        }
    }
    cr_nn_cpu_set_simd(prev);
    cr_nn_ctx_destroy(ctx);
}

CR_TEST(nn_linear_act, gradients_equal_the_unfused_ops) {
    /* Tape gradients of the fused op against linear + relu, 64 rows so the
     * bias column sums run over a real batch. */
    enum { R = 64 };
    float x[R * IN], w[OUT * IN], b[OUT];
    nn_gradcheck_fill(x, R * IN, -1, 1, 0, 81);
    nn_gradcheck_fill(w, OUT * IN, -1, 1, 0, 82);
    nn_gradcheck_fill(b, OUT, -0.5f, 0.5f, 0, 83);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    int prev = cr_nn_cpu_simd();
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        float g[2][3][OUT * IN > R * IN ? OUT * IN : R * IN];
        for (int fused = 0; fused < 2; fused++) {
            cr_nn_ctx_reset(ctx);
            cr_tensor *t[3] = {cr_nn_from(ctx, 2, (int64_t[]){R, IN}, x),
                               cr_nn_from(ctx, 2, (int64_t[]){OUT, IN}, w),
                               cr_nn_from(ctx, 1, (int64_t[]){OUT}, b)};
            for (int i = 0; i < 3; i++)
                t[i]->requires_grad = 1;
            cr_tensor *y = fused ? cr_nn_linear_act(ctx, t[0], t[1], t[2], CR_OP_RELU, 0)
                                 : cr_nn_relu(ctx, cr_nn_linear(ctx, t[0], t[1], t[2]));
            cr_tensor *loss = cr_nn_sum(ctx, cr_nn_square(ctx, y));
            cr_error err = {0};
            CR_REQUIRE(cr_nn_backward(ctx, loss, &err) == CR_OK);
            for (int i = 0; i < 3; i++)
                for (int64_t e = 0; e < t[i]->numel; e++)
                    g[fused][i][e] = t[i]->grad[e];
        }
        int64_t n[3] = {R * IN, OUT * IN, OUT};
        for (int i = 0; i < 3; i++)
            for (int64_t e = 0; e < n[i]; e++)
                CR_CHECK_NEAR(g[1][i][e], g[0][i][e], 1e-4 * (1 + fabsf(g[0][i][e])));
    }
    cr_nn_cpu_set_simd(prev);
    cr_nn_ctx_destroy(ctx);
}

CR_TEST(nn_linear_act, refuses_activations_it_cannot_fuse) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 16);
    CR_REQUIRE(ctx);
    float x[IN] = {0}, w[OUT * IN] = {0};
    cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){1, IN}, x);
    cr_tensor *wt = cr_nn_from(ctx, 2, (int64_t[]){OUT, IN}, w);
    CR_CHECK(cr_nn_linear_act(ctx, xt, wt, NULL, CR_OP_SIN, 0) == NULL);
    cr_error err = {0};
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "cannot be fused") != NULL);
    cr_nn_ctx_reset(ctx);
    xt = cr_nn_from(ctx, 2, (int64_t[]){1, IN}, x);
    wt = cr_nn_from(ctx, 2, (int64_t[]){OUT, IN}, w);
    CR_CHECK(cr_nn_linear_act(ctx, xt, wt, NULL, CR_OP_LEAKY_RELU, -0.5f) == NULL);
    cr_nn_ctx_destroy(ctx);
}

static cr_tensor *mlp_build(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_mlp_forward(ctx, user, in[0]);
}

/* The same ReLU MLP from the unfused ops: linear, then relu. */
static cr_tensor *mlp_unfused(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *h) {
    for (int i = 0; i < mlp->def.nlayers; i++) {
        h = cr_nn_linear(ctx, h, mlp->layer[i].weight, mlp->layer[i].bias);
        if (i < mlp->def.nlayers - 1) h = cr_nn_relu(ctx, h);
    }
    return h;
}

/* The 6-W-W-W-3 shape the methods use (W = 19: two AVX2 chunks and a tail)
 * through cr_mlp_forward, which fuses each layer, on every SIMD path: with
 * tanh and softplus (beta 10, the drape's) against central differences; with ReLU (where some
 * hidden unit sits within the FD step of its kink for most seeds) against the tape gradients of the
 * unfused ops, for the parameters and the input. */
CR_TEST(nn_linear_act, mlp_gradients_on_every_path) {
    enum { B = 5, P = 8192 };
    int widths[5] = {6, 19, 19, 19, 3};
    float x[B * 6];
    nn_gradcheck_fill(x, B * 6, -1, 1, 0, 91);
    int prev = cr_nn_cpu_simd();
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    for (int kind = 0; kind < 3; kind++) {
        int relu = kind == 2;
        cr_mlp_def def = cr_mlp_default_def();
        def.nlayers = 4;
        for (int i = 0; i < 5; i++)
            def.widths[i] = widths[i];
        def.act = kind == 0 ? CR_ACT_TANH : kind == 1 ? CR_ACT_SOFTPLUS : CR_ACT_RELU;
        def.softplus_beta = 10.0f;
        def.init = CR_INIT_TORCH;
        cr_rng rng = cr_rng_make(9, 0);
        cr_nn_params *params = NULL;
        cr_mlp *mlp = NULL;
        cr_error err = {0};
        CR_REQUIRE(cr_nn_params_create(&params, &err) == CR_OK);
        CR_REQUIRE(cr_mlp_create(&def, params, "mlp", &rng, &mlp, &err) == CR_OK);
        int64_t np = 0;
        float *grad = cr_nn_params_grad(params, &np);
        CR_REQUIRE(np <= P);
        for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
            cr_nn_cpu_set_simd(level);
            if (!relu) {
                nn_gradcheck_input in[1] = {nn_gradcheck_in(2, (int64_t[]){B, 6}, x)};
                nn_gradcheck_def gd = nn_gradcheck_default_def();
                gd.name = kind ? "mlp fused softplus" : "mlp fused tanh";
                if (nn_gradcheck(&gd, 1, in, params, mlp_build, mlp, NULL) != 0)
                    cr_test_fail_here(__FILE__, __LINE__, "%s mlp on SIMD level %d", gd.name,
                                      level);
                continue;
            }
            static float g[2][P], gx[2][B * 6];
            for (int fused = 0; fused < 2; fused++) {
                cr_nn_ctx_reset(ctx);
                cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){B, 6}, x);
                xt->requires_grad = 1;
                cr_tensor *y = fused ? cr_mlp_forward(ctx, mlp, xt) : mlp_unfused(ctx, mlp, xt);
                cr_tensor *loss = cr_nn_sum(ctx, cr_nn_square(ctx, y));
                cr_nn_params_zero_grad(params);
                CR_REQUIRE(cr_nn_backward(ctx, loss, &err) == CR_OK);
                for (int64_t e = 0; e < np; e++)
                    g[fused][e] = grad[e];
                for (int e = 0; e < B * 6; e++)
                    gx[fused][e] = xt->grad[e];
            }
            for (int64_t e = 0; e < np; e++)
                CR_CHECK_NEAR(g[1][e], g[0][e], 1e-5 * (1 + fabsf(g[0][e])));
            for (int e = 0; e < B * 6; e++)
                CR_CHECK_NEAR(gx[1][e], gx[0][e], 1e-5 * (1 + fabsf(gx[0][e])));
        }
        cr_mlp_destroy(mlp);
        cr_nn_params_destroy(params);
    }
    cr_nn_cpu_set_simd(prev);
    cr_nn_ctx_destroy(ctx);
}
