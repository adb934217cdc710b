/* test_nn_mlp_fused.c: the whole MLP by blocks of rows (src/nn/mlp_fused.c)
 * against the layer-by-layer path it replaces, its gradient against central
 * differences, and its sums on one thread and on all.
 *
 * Shapes cross the op's block and chunk boundaries: batches below one block,
 * of many blocks, and of more blocks than chunks (64-wide layers run in
 * blocks of 512 rows, 16 chunks at most), widths that change the block
 * height (256 wide: blocks of 128 rows), a model wide enough to take fewer
 * chunks, every fused activation, on every SIMD level the CPU runs.
 */
#include "crease/nn_layers.h"
#include "nn/cpu/cpu.h"
#include "nn/mlp_fused.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { ARENA = 256 << 20 };

/* One step's output and every gradient (parameters, then x) of
 * L = sum(y * wts), on the path `fused` selects and `threads` threads. */
typedef struct step_out {
    float *y, *grads, *gx;
    int64_t ny, np, nx;
} step_out;

static step_out run_step(const cr_mlp *m, cr_nn_params *P, const float *x, int64_t rows,
                         const float *wts, int fused, int threads) {
    cr_error err = {0};
    int prev_fused = cr_nn_mlp_fused_set(fused), prev_threads = cr_thread_count();
    cr_set_thread_count(threads);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(ARENA);
    CR_CHECK(ctx != NULL);
    const int in = m->def.widths[0], out = m->def.widths[m->def.nlayers];
    cr_nn_params_zero_grad(P);
    cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){rows, in}, x);
    xt->requires_grad = 1;
    cr_tensor *y = cr_mlp_forward(ctx, m, xt);
    cr_tensor *L =
        cr_nn_sum(ctx, cr_nn_mul(ctx, y, cr_nn_from(ctx, 2, (int64_t[]){rows, out}, wts)));
    CR_CHECK_OK(cr_nn_backward(ctx, L, &err), &err);
    step_out s = {.ny = rows * out, .nx = rows * in};
    const float *g = cr_nn_params_grad(P, &s.np);
    s.y = malloc((size_t)s.ny * sizeof(float));
    s.grads = malloc((size_t)s.np * sizeof(float));
    s.gx = malloc((size_t)s.nx * sizeof(float));
    memcpy(s.y, y->data, (size_t)s.ny * sizeof(float));
    memcpy(s.grads, g, (size_t)s.np * sizeof(float));
    memcpy(s.gx, xt->grad, (size_t)s.nx * sizeof(float));
    cr_nn_ctx_destroy(ctx);
    cr_set_thread_count(prev_threads);
    cr_nn_mlp_fused_set(prev_fused);
    return s;
}

static void step_free(step_out *s) {
    free(s->y), free(s->grads), free(s->gx);
}

/* Largest |a - b| / (scale + |b|) over n values. */
static double max_rel(const float *a, const float *b, int64_t n, double scale) {
    double m = 0.0;
    for (int64_t i = 0; i < n; i++)
        m = fmax(m, fabs((double)a[i] - b[i]) / (scale + fabs((double)b[i])));
    return m;
}

static double max_abs(const float *a, int64_t n) {
    double m = 0.0;
    for (int64_t i = 0; i < n; i++)
        m = fmax(m, fabs((double)a[i]));
    return m;
}

CR_TEST(nn_mlp_fused, matches_the_layer_path_and_the_thread_count) {
    typedef struct shape_case {
        int nl, widths[5];
        cr_act act, out_act;
        float param; /* leaky_relu's slope or softplus's beta */
        int64_t rows;
    } shape_case;
    const shape_case cases[] = {
        /* crease fit: 8 blocks */
        {4, {6, 64, 64, 64, 3}, CR_ACT_RELU, CR_ACT_NONE, 0.0f, 4096},
        /* the drape: more blocks than chunks */
        {4, {6, 64, 64, 64, 3}, CR_ACT_SOFTPLUS, CR_ACT_NONE, 10.0f, 9000},
        /* under one block, an activation on the output */
        {3, {2, 64, 64, 3}, CR_ACT_TANH, CR_ACT_SIGMOID, 0.0f, 300},
        /* 128-row blocks, a partial one */
        {3, {5, 256, 256, 4}, CR_ACT_SIGMOID, CR_ACT_NONE, 0.0f, 1100},
        /* odd widths */
        {2, {7, 33, 5}, CR_ACT_LEAKY_RELU, CR_ACT_TANH, 0.1f, 2049},
        /* 363,603 parameters: 11 chunks, not 13 (13 blocks of 48 rows), keep the partials
         * within 16 MB */
        {3, {4, 600, 600, 3}, CR_ACT_TANH, CR_ACT_NONE, 0.0f, 600},
    };
    /* every SIMD level this CPU runs, the kernels the op calls dispatching on
     * it; the layer path on the own GEMM, as the op is (OpenBLAS, which the
     * layer path may pick, rounds differently) */
    const int prev_level = cr_nn_cpu_simd(), prev_gemm = cr_nn_cpu_set_gemm_own(1);
    const size_t ncases = sizeof cases / sizeof *cases;
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (size_t k = 0; k < ncases; k++) {
            const shape_case *c = &cases[k];
            cr_error err = {0};
            cr_rng rng = cr_rng_make(40 + k, 0);
            cr_nn_params *P = NULL;
            CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
            cr_mlp_def d = cr_mlp_default_def();
            d.nlayers = c->nl;
            memcpy(d.widths, c->widths, (size_t)(c->nl + 1) * sizeof(int));
            d.act = c->act;
            d.out_act = c->out_act;
            d.leaky_slope = d.softplus_beta = c->param;
            cr_mlp *m = NULL;
            CR_CHECK_OK(cr_mlp_create(&d, P, "mlp", &rng, &m, &err), &err);
            for (int l = 0; l < c->nl; l++)
                nn_gradcheck_fill(m->layer[l].bias->data, c->widths[l + 1], -0.5f, 0.5f, 0.0f,
                                  100 * k + l);
            const int64_t nx = c->rows * c->widths[0], ny = c->rows * c->widths[c->nl];
            float *x = malloc((size_t)nx * sizeof(float)), *w = malloc((size_t)ny * sizeof(float));
            nn_gradcheck_fill(x, nx, -1, 1, 0.0f, 100 * k + 50);
            nn_gradcheck_fill(w, ny, -1, 1, 0.0f, 100 * k + 51);
            const int all = cr_thread_count();
            step_out layers = run_step(m, P, x, c->rows, w, 0, all);
            step_out fused = run_step(m, P, x, c->rows, w, 1, all);
            step_out one = run_step(m, P, x, c->rows, w, 1, 1);
            /* The same products in another grouping: the values to float
             * rounding; the gradients (the weights': sums over the rows) to 1e-4
             * of themselves or 1e-6 of the largest, about 8 ulps of it (the
             * 600-wide case differs by 1.5e-6 of its largest). */
            CR_CHECK(max_rel(fused.y, layers.y, ny, 1e-3) < 1e-5);
            CR_CHECK(max_rel(fused.gx, layers.gx, nx, 1e-2 * max_abs(layers.gx, nx)) < 1e-4);
            CR_CHECK(max_rel(fused.grads, layers.grads, fused.np,
                             1e-2 * max_abs(layers.grads, layers.np)) < 1e-4);
            /* The gradient is not zero, so the comparison can fail. */
            CR_CHECK(max_abs(fused.grads, fused.np) > 1e-3);
            CR_CHECK(memcmp(fused.y, one.y, (size_t)ny * sizeof(float)) == 0);
            CR_CHECK(memcmp(fused.grads, one.grads, (size_t)fused.np * sizeof(float)) == 0);
            CR_CHECK(memcmp(fused.gx, one.gx, (size_t)nx * sizeof(float)) == 0);
            step_free(&layers), step_free(&fused), step_free(&one);
            free(x), free(w);
            cr_mlp_destroy(m);
            cr_nn_params_destroy(P);
        }
    }
    cr_nn_cpu_set_simd(prev_level);
    cr_nn_cpu_set_gemm_own(prev_gemm);
}

static cr_tensor *build_mlp(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_mlp_forward(ctx, user, in[0]);
}

CR_TEST(nn_mlp_fused, gradcheck_across_blocks) {
    /* 700 rows of a 6-64-64-3 softplus MLP: two blocks of 512 rows, so the
     * weights' gradient adds two chunks' partials; a subset of every tensor
     * is checked against central differences. */
    cr_error err = {0};
    cr_rng rng = cr_rng_make(51, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_mlp_def d = cr_mlp_default_def();
    d.nlayers = 3;
    memcpy(d.widths, (int[]){6, 64, 64, 3}, 4 * sizeof(int));
    d.act = CR_ACT_SOFTPLUS;
    d.softplus_beta = 4.0f;
    cr_mlp *m = NULL;
    CR_CHECK_OK(cr_mlp_create(&d, P, "mlp", &rng, &m, &err), &err);
    enum { R = 700 };
    float *x = malloc(R * 6 * sizeof(float));
    nn_gradcheck_fill(x, R * 6, -1, 1, 0.0f, 52);
    const int prev = cr_nn_mlp_fused_set(1);
    nn_gradcheck_input in[1] = {{2, {R, 6}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "mlp fused";
    gd.max_elems = 40;
    gd.arena_bytes = (size_t)64 << 20;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_mlp, m, &res) == 0);
    CR_CHECK(res.checked >= 4 * 40);
    cr_nn_mlp_fused_set(prev);
    free(x);
    cr_mlp_destroy(m);
    cr_nn_params_destroy(P);
}

CR_TEST(nn_mlp_fused, refuses_a_weight_of_the_wrong_width) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx(ARENA);
    CR_REQUIRE(ctx);
    cr_tensor *x = cr_nn_zeros(ctx, 2, (int64_t[]){10, 4});
    cr_tensor *w = cr_nn_zeros(ctx, 2, (int64_t[]){8, 5}), *b = cr_nn_zeros(ctx, 1, (int64_t[]){8});
    cr_op act = CR_OP_RELU;
    float p = 0.0f;
    CR_CHECK(!cr_nn_mlp_fused(ctx, x, 1, &w, &b, &act, &p));
    cr_error err = {0};
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "layer 0") != NULL);
    cr_nn_ctx_destroy(ctx);
}
