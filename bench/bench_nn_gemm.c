/* bench_nn_gemm.c: the tape's linear layer against raw cblas_sgemm at the
 * shapes of an MLP training step (batch 4096, widths 64 and 256).
 *
 * One step of one layer is y = x W^T + b forward and dx, dW, db backward:
 * three GEMMs of 2 B W^2 flops each. "raw" times exactly those three
 * cblas_sgemm calls; "tape" times cr_nn_linear + cr_nn_sum + cr_nn_backward
 * on a reset context (bias broadcast, column sums, grad zeroing and the
 * tape's bookkeeping included). Reports the median of `iters` steps.
 *
 *   bench_nn_gemm [iters]      (default 20)
 */
#include "crease/nn.h"

#include <cblas.h>
#include <stdio.h>
#include <stdlib.h>

enum { BATCH = 4096, MAX_ITERS = 1000 };

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *t, int n) {
    qsort(t, (size_t)n, sizeof *t, cmp_double);
    return t[n / 2];
}

static int run(int width, int iters) {
    int64_t W = width;
    size_t xbytes = (size_t)BATCH * (size_t)W * sizeof(float);
    float *x = malloc(xbytes), *y = malloc(xbytes), *dy = malloc(xbytes), *dx = malloc(xbytes);
    float *w = malloc((size_t)(W * W) * sizeof(float)),
          *dw = malloc((size_t)(W * W) * sizeof(float));
    double *t_raw = malloc((size_t)iters * sizeof(double)),
           *t_tape = malloc((size_t)iters * sizeof(double));
    if (!x || !y || !dy || !dx || !w || !dw || !t_raw || !t_tape) return 1;
    cr_rng rng = cr_rng_make(1, 0);
    for (int64_t i = 0; i < BATCH * W; i++)
        x[i] = cr_rng_uniformf(&rng) - 0.5f, dy[i] = 1.0f;
    for (int64_t i = 0; i < W * W; i++)
        w[i] = cr_rng_uniformf(&rng) - 0.5f;

    for (int it = 0; it < iters; it++) {
        double t0 = cr_time_now();
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, BATCH, width, width, 1.0f, x, width, w,
                    width, 0.0f, y, width);
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, BATCH, width, width, 1.0f, dy, width,
                    w, width, 0.0f, dx, width);
        cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, width, width, BATCH, 1.0f, dy, width,
                    x, width, 0.0f, dw, width);
        t_raw[it] = cr_time_now() - t0;
    }

    cr_error err = {0};
    cr_nn_params *P = NULL;
    cr_tensor *pw, *pb;
    cr_nn_ctx *ctx = NULL;
    cr_nn_ctx_def def = cr_nn_ctx_default_def();
    def.arena_bytes = 8 * xbytes;
    if (cr_nn_params_create(&P, &err) != CR_OK ||
        cr_nn_params_add(P, "w", 2, (int64_t[]){W, W}, &pw, &err) != CR_OK ||
        cr_nn_params_add(P, "b", 1, (int64_t[]){W}, &pb, &err) != CR_OK ||
        cr_nn_ctx_create(&def, &ctx, &err) != CR_OK) {
        fprintf(stderr, "bench_nn_gemm: %s\n", err.msg);
        return 1;
    }
    for (int64_t i = 0; i < W * W; i++)
        pw->data[i] = w[i];
    for (int it = 0; it < iters; it++) {
        double t0 = cr_time_now();
        cr_nn_ctx_reset(ctx);
        cr_tensor *tx = cr_nn_wrap(ctx, 2, (int64_t[]){BATCH, W}, x);
        tx->requires_grad = 1; /* so dx is computed, as in a hidden layer */
        cr_tensor *loss = cr_nn_sum(ctx, cr_nn_linear(ctx, tx, pw, pb));
        if (cr_nn_backward(ctx, loss, &err) != CR_OK) {
            fprintf(stderr, "bench_nn_gemm: %s\n", err.msg);
            return 1;
        }
        t_tape[it] = cr_time_now() - t0;
    }
    double flops = 3.0 * 2.0 * BATCH * (double)W * (double)W;
    double raw = median(t_raw, iters), tape = median(t_tape, iters);
    printf("%6d %6d %12.3f %10.1f %12.3f %10.1f %8.2f\n", BATCH, width, raw * 1e3,
           flops / raw * 1e-9, tape * 1e3, flops / tape * 1e-9, tape / raw);
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
    free(x), free(y), free(dy), free(dx), free(w), free(dw), free(t_raw), free(t_tape);
    return 0;
}

int main(int argc, char **argv) {
    int iters = argc > 1 ? atoi(argv[1]) : 20;
    if (iters < 1 || iters > MAX_ITERS) {
        fprintf(stderr, "usage: bench_nn_gemm [iters 1..%d]\n", MAX_ITERS);
        return 2;
    }
    printf("linear layer fwd+bwd (3 GEMMs), median of %d, %d threads\n", iters, cr_thread_count());
    printf("%6s %6s %12s %10s %12s %10s %8s\n", "batch", "width", "raw_ms", "raw_GF/s", "tape_ms",
           "tape_GF/s", "ratio");
    return run(64, iters) || run(256, iters);
}
