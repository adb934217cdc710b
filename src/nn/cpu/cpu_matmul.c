/* cpu_matmul.c: GEMM through the engine's own kernel (cpu_gemm.c) or
 * cblas_sgemm (OpenBLAS), a naive reference beside it, and the batched and
 * grouped products built from it.
 *
 * OpenBLAS threads each product itself, so batched and grouped products call
 * it in a plain loop rather than from OpenMP threads (which would nest two
 * thread pools). Empty products are handled here because BLAS rejects
 * leading dimensions of 0.
 * Leaves out: packing many tiny products into one call.
 */
#include "nn/cpu/cpu.h"

#include <cblas.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static void scale_block(float *C, int64_t M, int64_t N, int64_t ldc, float beta) {
    for (int64_t i = 0; i < M; i++)
        for (int64_t j = 0; j < N; j++)
            C[i * ldc + j] = beta == 0.0f ? 0.0f : beta * C[i * ldc + j];
}

/* OpenBLAS kernels that beat the own GEMM on a level (docs/nn.md, "The
 * engine's own GEMM"): on AVX-512 its SkylakeX family, on AVX2 also its
 * Haswell and Zen; below them (Prescott, Sandybridge ...) the own one wins. */
static int blas_core_wins(int level) {
    static const char *const avx512[] = {"SkylakeX", "Cooperlake", "SapphireRapids"};
    static const char *const avx2[] = {"Haswell", "Zen"};
    const char *core = openblas_get_corename();
    if (!core) return 0;
    for (size_t i = 0; i < sizeof avx512 / sizeof *avx512; i++)
        if (strcmp(core, avx512[i]) == 0) return 1;
    for (size_t i = 0; level < NN_SIMD_AVX512 && i < sizeof avx2 / sizeof *avx2; i++)
        if (strcmp(core, avx2[i]) == 0) return 1;
    return 0;
}

/* -1: not read yet; 0: OpenBLAS; 1: own; 2: by shape (gemm_narrow) */
static int gemm_choice = -1;

int cr_nn_cpu_gemm_uses_own(void) {
    if (gemm_choice < 0) {
        const char *env = getenv("CREASE_NN_GEMM");
        int level = cr_nn_cpu_simd();
        if (env && strcmp(env, "blas") == 0)
            gemm_choice = 0;
        else if (env && strcmp(env, "own") == 0)
            gemm_choice = 1;
        else if (level < NN_SIMD_AVX2)
            gemm_choice = 0;
        else if (blas_core_wins(level)) /* by shape measured on AVX-512 only */
            gemm_choice = level >= NN_SIMD_AVX512 ? 2 : 0;
        else
            gemm_choice = 1;
    }
    return gemm_choice;
}

/* Where OpenBLAS runs its SkylakeX-family kernel on AVX-512 it keeps the
 * square products, and the own GEMM takes those with a side below 128: a 3-
 * or 6-wide layer, a 64-wide MLP (the drape's), where OpenBLAS's beta pass,
 * packing and thread start cost more than the multiply-adds (docs/nn.md,
 * "The narrow layers on both threads, both GEMMs by shape"). */
static int gemm_narrow(int64_t M, int64_t N, int64_t K) {
    enum { GEMM_OWN_BELOW = 128 };
    return M < GEMM_OWN_BELOW || N < GEMM_OWN_BELOW || K < GEMM_OWN_BELOW;
}

int cr_nn_cpu_set_gemm_own(int own) {
    int prev = cr_nn_cpu_gemm_uses_own();
    gemm_choice = own == 2 ? 2 : own != 0;
    return prev;
}

/* 2MNK of every product since the process started (cr_nn_gemm_flops). */
static _Atomic uint64_t gemm_flops;

uint64_t cr_nn_gemm_flops(void) {
    return atomic_load_explicit(&gemm_flops, memory_order_relaxed);
}

const char *cr_nn_kernel_level(void) {
    int l = cr_nn_cpu_simd();
    return l == NN_SIMD_AVX512 ? "avx512" : l == NN_SIMD_AVX2 ? "avx2" : "scalar";
}

static int ld(int64_t x) {
    return x > 0 ? (int)x : 1;
}

void cr_nn_cpu_gemm(int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha, const float *A,
                    int64_t lda, const float *B, int64_t ldb, float beta, float *C, int64_t ldc) {
    if (M == 0 || N == 0) return;
    if (K == 0) {
        scale_block(C, M, N, ldc, beta);
        return;
    }
    atomic_fetch_add_explicit(&gemm_flops, (uint64_t)(2 * M * N * K), memory_order_relaxed);
    int own = cr_nn_cpu_gemm_uses_own();
    if (alpha != 0.0f && (own == 1 || (own == 2 && gemm_narrow(M, N, K))) &&
        cr_nn_cpu_gemm_own(cr_nn_cpu_simd(), ta, tb, M, N, K, alpha, A, lda, B, ldb, beta, C,
                           ldc) == 0)
        return;
    cblas_sgemm(CblasRowMajor, ta ? CblasTrans : CblasNoTrans, tb ? CblasTrans : CblasNoTrans,
                (int)M, (int)N, (int)K, alpha, A, ld(lda), B, ld(ldb), beta, C, ld(ldc));
}

void cr_nn_cpu_gemm_naive(int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                          const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                          float *C, int64_t ldc) {
    for (int64_t i = 0; i < M; i++) {
        for (int64_t j = 0; j < N; j++) {
            double s = 0.0;
            for (int64_t k = 0; k < K; k++) {
                float a = ta ? A[k * lda + i] : A[i * lda + k];
                float b = tb ? B[j * ldb + k] : B[k * ldb + j];
                s += (double)a * b;
            }
            float prev = beta == 0.0f ? 0.0f : beta * C[i * ldc + j];
            C[i * ldc + j] = (float)(alpha * s) + prev;
        }
    }
}

void cr_nn_cpu_gemm_batched(int ta, int tb, int64_t M, int64_t N, int64_t K, const float *A,
                            int64_t lda, int64_t stride_a, const float *B, int64_t ldb,
                            int64_t stride_b, float beta, float *C, int64_t ldc, int64_t stride_c,
                            int64_t batch) {
    for (int64_t b = 0; b < batch; b++)
        cr_nn_cpu_gemm(ta, tb, M, N, K, 1.0f, A + b * stride_a, lda, B + b * stride_b, ldb, beta,
                       C + b * stride_c, ldc);
}

void cr_nn_cpu_grouped_forward(const float *xs, int64_t K, const float *w, int trans_w, int64_t N,
                               const int64_t *off, int64_t G, float *ys) {
    for (int64_t g = 0; g < G; g++) {
        int64_t r0 = off[g], m = off[g + 1] - r0;
        /* ys_g (m,N) = xs_g (m,K) op(w_g) (K,N) */
        cr_nn_cpu_gemm(0, trans_w, m, N, K, 1.0f, xs + r0 * K, K, w + g * K * N, trans_w ? K : N,
                       0.0f, ys + r0 * N, N);
    }
}

void cr_nn_cpu_grouped_backward(const float *xs, const float *dys, int64_t K, const float *w,
                                int trans_w, int64_t N, const int64_t *off, int64_t G, float *dxs,
                                float *dw) {
    for (int64_t g = 0; g < G; g++) {
        int64_t r0 = off[g], m = off[g + 1] - r0;
        const float *wg = w + g * K * N;
        if (dxs) /* dxs_g (m,K) = dys_g (m,N) op(w_g)^T (N,K) */
            cr_nn_cpu_gemm(0, !trans_w, m, K, N, 1.0f, dys + r0 * N, N, wg, trans_w ? K : N, 0.0f,
                           dxs + r0 * K, K);
        if (dw && !trans_w) /* dw_g (K,N) += xs_g^T dys_g */
            cr_nn_cpu_gemm(1, 0, K, N, m, 1.0f, xs + r0 * K, K, dys + r0 * N, N, 1.0f,
                           dw + g * K * N, N);
        if (dw && trans_w) /* dw_g stored (N,K) += dys_g^T xs_g */
            cr_nn_cpu_gemm(1, 0, N, K, m, 1.0f, dys + r0 * N, N, xs + r0 * K, K, 1.0f,
                           dw + g * K * N, K);
    }
}
