/* bench_nn_mlp.c: throughput of one MLP training step (forward, backward,
 * Adam) at batch 4096 for hidden widths 64 and 256, and the share of that
 * step the GEMMs would take on their own: the same GEMM shapes timed as raw
 * cblas_sgemm calls in the same run.
 *
 * The MLP is the drape paper's head shape, 6-W-W-W-3 with ReLU: per layer one
 * forward GEMM x W^T and two backward GEMMs (dX = dY W, dW = dY^T X; the
 * first layer's dX is not needed). "gemm share" = raw GEMM time / step time;
 * the rest is activations, bias sums, the loss, the tape and Adam. Then the
 * step alone (no raw GEMMs between) on one thread and on all.
 *
 *   bench_nn_mlp [iters] [width]   (default 30 iterations of widths 64 and
 *                                  256; prints medians, and the fastest step
 *                                  and GEMM set)
 */
#include "crease/nn.h"
#include "crease/nn_layers.h"
#include "crease/nn_optim.h"

#include "bench_stats.h"

#include <cblas.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { BATCH = 4096, IN = 6, OUT = 3, HIDDEN_LAYERS = 3, MAX_ITERS = 1000 };

/* The GEMMs of one training step of a width[0]-...-width[nl] MLP, raw. */
static double raw_gemms(const int *width, int nl, float *a, float *b, float *c) {
    double t0 = cr_time_now();
    for (int l = 0; l < nl; l++) { /* forward: (B,in) x (out,in)^T */
        int in = width[l], out = width[l + 1];
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, BATCH, out, in, 1.0f, a, in, b, in,
                    0.0f, c, out);
    }
    for (int l = nl - 1; l >= 0; l--) {
        int in = width[l], out = width[l + 1];
        /* dW (out,in) = dY^T (out,B) x X (B,in) */
        cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, out, in, BATCH, 1.0f, a, out, b, in,
                    0.0f, c, in);
        if (l > 0) /* dX (B,in) = dY (B,out) x W (out,in) */
            cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, BATCH, in, out, 1.0f, a, out, b,
                        in, 0.0f, c, in);
    }
    return cr_time_now() - t0;
}

typedef struct step_ctx {
    cr_nn_ctx *ctx;
    cr_mlp *mlp;
    cr_nn_params *params;
    cr_optim *opt;
    float *x, *y;
} step_ctx;

/* One training step (forward, backward, Adam): its seconds, -1 on error. */
static double one_step(const step_ctx *s, cr_error *err) {
    double t0 = cr_time_now();
    cr_nn_ctx_reset(s->ctx);
    cr_tensor *xt = cr_nn_wrap(s->ctx, 2, (int64_t[]){BATCH, IN}, s->x);
    cr_tensor *yt = cr_nn_wrap(s->ctx, 2, (int64_t[]){BATCH, OUT}, s->y);
    cr_tensor *loss = cr_nn_mean(
        s->ctx, cr_nn_square(s->ctx, cr_nn_sub(s->ctx, cr_mlp_forward(s->ctx, s->mlp, xt), yt)));
    cr_nn_params_zero_grad(s->params);
    if (cr_nn_backward(s->ctx, loss, err) || cr_optim_step(s->opt, err)) {
        fprintf(stderr, "bench_nn_mlp: %s\n", err->msg);
        return -1.0;
    }
    return cr_time_now() - t0;
}

static int run(int hidden, int iters) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(1, 0);
    cr_nn_params *params = NULL;
    cr_mlp *mlp = NULL;
    cr_optim *opt = NULL;
    cr_nn_ctx *ctx = NULL;
    cr_mlp_def def = cr_mlp_default_def();
    def.nlayers = HIDDEN_LAYERS + 1;
    int width[HIDDEN_LAYERS + 2] = {IN, hidden, hidden, hidden, OUT};
    memcpy(def.widths, width, sizeof width);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)256 << 20;
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    if (cr_nn_params_create(&params, &err) ||
        cr_mlp_create(&def, params, "mlp", &rng, &mlp, &err) ||
        cr_optim_create(&od, params, &opt, &err) || cr_nn_ctx_create(&cd, &ctx, &err)) {
        fprintf(stderr, "bench_nn_mlp: %s\n", err.msg);
        return 1;
    }
    size_t big = (size_t)BATCH * (size_t)hidden;
    float *x = malloc((size_t)BATCH * IN * sizeof(float)), *y = malloc((size_t)BATCH * OUT * 4);
    float *a = calloc(big, sizeof(float)), *b = calloc(big, sizeof(float));
    float *c = calloc(big, sizeof(float));
    double t_step[MAX_ITERS], t_gemm[MAX_ITERS];
    if (!x || !y || !a || !b || !c) return 1;
    for (int i = 0; i < BATCH * IN; i++)
        x[i] = cr_rng_uniformf(&rng);
    for (int i = 0; i < BATCH * OUT; i++)
        y[i] = cr_rng_uniformf(&rng);
    step_ctx sc = {ctx, mlp, params, opt, x, y};
    for (int it = -3; it < iters; it++) { /* three warm-up steps */
        double step = one_step(&sc, &err);
        if (step < 0.0) return 1;
        double gemm = raw_gemms(width, HIDDEN_LAYERS + 1, a, b, c);
        if (it >= 0) t_step[it] = step, t_gemm[it] = gemm;
    }
    /* the engine's step alone, on one thread and on all: how far the
     * second thread helps (a step whose ops hand rows from core to core
     * gains nothing; docs/nn.md, "Static chunks") */
    double alone[2];
    const int threads = cr_thread_count();
    for (int k = 0; k < 2; k++) {
        cr_set_thread_count(k == 0 ? 1 : threads);
        double t[MAX_ITERS];
        for (int it = -3; it < iters; it++) {
            double step = one_step(&sc, &err);
            if (step < 0.0) return 1;
            if (it >= 0) t[it] = step;
        }
        alone[k] = bench_median(t, iters);
    }
    cr_set_thread_count(threads);
    /* fastest of each, the figure least disturbed by other processes on a
     * shared machine (medians sort the arrays, so take these first) */
    double best_step = t_step[0], best_gemm = t_gemm[0];
    for (int i = 1; i < iters; i++) {
        if (t_step[i] < best_step) best_step = t_step[i];
        if (t_gemm[i] < best_gemm) best_gemm = t_gemm[i];
    }
    double step = bench_median(t_step, iters), gemm = bench_median(t_gemm, iters);
    printf("mlp 6-%d-%d-%d-3 batch %d: step %.2f ms, %.3g points/s; raw GEMMs %.2f ms; "
           "gemm share %.2f (step/gemm %.2f); fastest: %.2f ms per step, raw GEMMs %.2f ms\n",
           hidden, hidden, hidden, BATCH, 1e3 * step, BATCH / step, 1e3 * gemm, gemm / step,
           step / gemm, 1e3 * best_step, 1e3 * best_gemm);
    printf("  the step alone: %.2f ms on 1 thread, %.2f ms on %d (%.2fx)\n", 1e3 * alone[0],
           1e3 * alone[1], threads, alone[0] / alone[1]);
    free(x), free(y), free(a), free(b), free(c);
    cr_nn_ctx_destroy(ctx);
    cr_optim_destroy(opt);
    cr_mlp_destroy(mlp);
    cr_nn_params_destroy(params);
    return 0;
}

int main(int argc, char **argv) {
    int iters = argc > 1 ? atoi(argv[1]) : 30, width = argc > 2 ? atoi(argv[2]) : 0;
    if (iters < 1 || iters > MAX_ITERS || argc > 3 || (argc > 2 && (width < 1 || width > 4096))) {
        fprintf(stderr, "usage: bench_nn_mlp [iters 1..%d] [width 1..4096]\n", MAX_ITERS);
        return 2;
    }
    const char *core = getenv("OPENBLAS_CORETYPE");
    printf("threads %d, OpenBLAS %s, core type %s\n", cr_thread_count(), openblas_get_config(),
           openblas_get_corename());
    if (core) printf("OPENBLAS_CORETYPE=%s (set by the environment)\n", core);
    if (width) return run(width, iters);
    return run(64, iters) || run(256, iters);
}
