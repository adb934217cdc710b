/* test_nn_gemm.c: the engine's own GEMM (cr_nn_cpu_gemm_own, cpu_gemm.c) on
 * every SIMD level this CPU runs against the double-precision triple loop
 * (cr_nn_cpu_gemm_naive): odd shapes around the tile and block sizes
 * (1, 3, 7, 17, 65, 511 and past KC = 256 and MC = 240), the three
 * transposition cases the layers use (y = x W^T, dx = dy W, dW = dy^T x) and
 * plain NN, leading dimensions wider than the rows, alpha and beta
 * (overwrite with NaN in C, accumulate), the narrow forward's dot-product
 * path, a long k split into chunks (weights gradients), more B blocks than one parallel region
 * packs, the same bits whatever the thread count, and the dispatch through cr_nn_cpu_gemm with
 * CREASE_NN_GEMM's choice forced either way.
 */
#include "crease/nn.h"
#include "nn/cpu/cpu.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void fill(float *x, int64_t n, cr_rng *rng) {
    for (int64_t i = 0; i < n; i++)
        x[i] = 2.0f * cr_rng_uniformf(rng) - 1.0f;
}

/* Largest |own - ref| / (sum_k |a b| + |beta c| + 1e-30) over C, in units of
 * float epsilon: the error bound a float GEMM's rounding allows. */
static double gemm_error(int level, int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                         float beta, cr_rng *rng) {
    int64_t pad = 3, lda = (ta ? M : K) + pad, ldb = (tb ? K : N) + pad, ldc = N + pad;
    int64_t na = (ta ? K : M) * lda, nb = (tb ? N : K) * ldb, nc = M * ldc;
    float *A = malloc((size_t)na * 4), *B = malloc((size_t)nb * 4);
    float *C = malloc((size_t)nc * 4), *R = malloc((size_t)nc * 4);
    float *absA = malloc((size_t)na * 4), *absB = malloc((size_t)nb * 4);
    float *S = malloc((size_t)nc * 4);
    if (!A || !B || !C || !R || !absA || !absB || !S) return INFINITY;
    fill(A, na, rng), fill(B, nb, rng), fill(C, nc, rng);
    if (beta == 0.0f)
        for (int64_t i = 0; i < nc; i++)
            C[i] = NAN; /* must not be read */
    memcpy(R, C, (size_t)nc * 4);
    for (int64_t i = 0; i < na; i++)
        absA[i] = fabsf(A[i]);
    for (int64_t i = 0; i < nb; i++)
        absB[i] = fabsf(B[i]);
    cr_nn_cpu_gemm_naive(ta, tb, M, N, K, 1.0f, absA, lda, absB, ldb, 0.0f, S, ldc);
    double worst = 0.0;
    if (cr_nn_cpu_gemm_own(level, ta, tb, M, N, K, alpha, A, lda, B, ldb, beta, C, ldc) != 0)
        worst = INFINITY;
    cr_nn_cpu_gemm_naive(ta, tb, M, N, K, alpha, A, lda, B, ldb, beta, R, ldc);
    for (int64_t i = 0; i < M && worst < INFINITY; i++)
        for (int64_t j = 0; j < N; j++) {
            int64_t at = i * ldc + j;
            double scale = fabs(alpha) * S[at] + (beta != 0.0f ? fabs(beta * R[at]) : 0.0) + 1e-30;
            double e = fabs((double)C[at] - R[at]) / scale / 1.1920929e-7;
            if (!(e <= worst)) worst = isnan(e) ? INFINITY : e;
        }
    /* the padding between rows is left alone */
    for (int64_t i = 0; i < M && worst < INFINITY; i++)
        for (int64_t j = N; j < ldc; j++)
            if (!(C[i * ldc + j] == R[i * ldc + j] || (isnan(C[i * ldc + j]) && beta == 0.0f)))
                worst = INFINITY;
    free(A), free(B), free(C), free(R), free(absA), free(absB), free(S);
    return worst;
}

CR_TEST(nn_gemm, odd_shapes_all_transpositions_every_level) {
    static const int64_t dims[] = {1, 3, 7, 17, 65, 511};
    cr_rng rng = cr_rng_make(15, 0);
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++)
        for (int t = 0; t < 4; t++)
            for (int a = 0; a < 6; a++)
                for (int b = 0; b < 6; b++) {
                    /* M over all, N and K over pairs, kept small enough to be fast */
                    int64_t M = dims[a], N = dims[b], K = dims[(a + b + t) % 6];
                    if (M * N * K > 20000000) K = 65;
                    double e = gemm_error(level, t >> 1, t & 1, M, N, K, 1.0f, 0.0f, &rng);
                    if (!(e < 8.0))
                        fprintf(stderr, "level %d ta %d tb %d %lldx%lldx%lld: %g eps\n", level,
                                t >> 1, t & 1, (long long)M, (long long)N, (long long)K, e);
                    CR_CHECK(e < 8.0);
                }
}

CR_TEST(nn_gemm, layer_shapes_past_the_blocks_with_alpha_and_beta) {
    cr_rng rng = cr_rng_make(16, 0);
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        /* forward y (M,N) = x (M,K) W^T; beta 0 */
        CR_CHECK(gemm_error(level, 0, 1, 1000, 64, 6, 1.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 1, 257, 300, 257, 1.0f, 0.0f, &rng) < 8.0);
        /* dx (M,K) = dy (M,N) W; accumulate into an existing gradient */
        CR_CHECK(gemm_error(level, 0, 0, 241, 65, 3, 1.0f, 1.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 0, 130, 40, 600, 1.0f, 1.0f, &rng) < 8.0);
        /* dW (N,K) += dy^T (N,M) x (M,K): M the reduction, past KC */
        CR_CHECK(gemm_error(level, 1, 0, 64, 6, 1029, 1.0f, 1.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 1, 0, 3, 64, 777, 1.0f, 1.0f, &rng) < 8.0);
        /* the narrow forward (N <= 8: a dot product per element), K with and
         * without a tail past the vector width, past KC */
        CR_CHECK(gemm_error(level, 0, 1, 4100, 3, 64, 1.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 1, 300, 8, 300, 0.5f, 1.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 1, 97, 1, 13, 1.0f, 0.0f, &rng) < 8.0);
        /* a few rows against a wide weight (M <= 8, B = W transposed: one or
         * two frames through epnet's decoder): C^T = W x^T by dot products
         * over W's rows, K with and without a tail, alpha and beta */
        CR_CHECK(gemm_error(level, 0, 1, 2, 6171, 256, 1.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 1, 1, 500, 131, 0.5f, 1.0f, &rng) < 8.0);
        /* the same path with B not transposed (dx of a 6-wide input layer,
         * W copied to N x K first), with beta 0 and accumulating */
        CR_CHECK(gemm_error(level, 0, 0, 6144, 6, 64, 1.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 0, 300, 3, 67, 0.5f, 1.0f, &rng) < 8.0);
        /* more B blocks than one parallel region's packing budget (2 x 5 of
         * KC x NC, 8 to a region at AVX-512's panel width) */
        CR_CHECK(gemm_error(level, 0, 1, 13, 2100, 1100, 1.0f, 0.0f, &rng) < 8.0);
        /* k split into chunks summed after (K >= 2048 and 8 x the output's
         * sides): a drape batch's dW at widths 6, 64 and 3, k not a multiple
         * of the chunks, every transposition, alpha and beta */
        CR_CHECK(gemm_error(level, 1, 0, 64, 6, 6144, 1.0f, 1.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 1, 0, 3, 64, 4099, 1.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 1, 0, 64, 64, 2053, 1.0f, 1.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 1, 17, 5, 3001, -0.5f, 0.25f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 1, 1, 9, 33, 2300, 2.0f, 0.0f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 0, 2, 7, 9000, 1.0f, -1.0f, &rng) < 8.0);
        /* general alpha and beta, the last case */
        CR_CHECK(gemm_error(level, 1, 1, 33, 47, 300, -0.5f, 0.25f, &rng) < 8.0);
        CR_CHECK(gemm_error(level, 0, 0, 121, 33, 17, 2.0f, -1.0f, &rng) < 8.0);
    }
}

CR_TEST(nn_gemm, dispatch_either_way_agrees_with_the_reference) {
    cr_rng rng = cr_rng_make(17, 0);
    int64_t M = 150, N = 20, K = 30;
    float A[150 * 30], B[30 * 20], C[150 * 20], R[150 * 20];
    fill(A, M * K, &rng), fill(B, K * N, &rng);
    cr_nn_cpu_gemm_naive(0, 0, M, N, K, 1.0f, A, K, B, N, 0.0f, R, N);
    for (int own = 0; own < 3; own++) { /* OpenBLAS, own, by shape */
        int prev = cr_nn_cpu_set_gemm_own(own);
        CR_CHECK(cr_nn_cpu_gemm_uses_own() == own);
        cr_nn_cpu_gemm(0, 0, M, N, K, 1.0f, A, K, B, N, 0.0f, C, N);
        double worst = 0.0;
        for (int64_t i = 0; i < M * N; i++)
            worst = fmax(worst, fabs((double)C[i] - R[i]));
        CR_CHECK(worst < 1e-4);
        cr_nn_cpu_set_gemm_own(prev);
    }
    /* the cases left to OpenBLAS or the scale-only path */
    CR_CHECK(cr_nn_cpu_gemm_own(cr_nn_cpu_simd(), 0, 0, M, N, 0, 1.0f, A, K, B, N, 0.0f, C, N) ==
             -1);
    CR_CHECK(cr_nn_cpu_gemm_own(cr_nn_cpu_simd(), 0, 0, M, N, K, 0.0f, A, K, B, N, 0.0f, C, N) ==
             -1);
}

CR_TEST(nn_gemm, same_bits_on_one_thread_and_on_three) {
    cr_rng rng = cr_rng_make(18, 0);
    enum { M = 700, N = 40, K = 300, KS = 6000 /* a k that splits; 8 KS floats fit in A */ };
    float *A = malloc(M * K * 4), *B = malloc(K * N * 4), *C1 = malloc(M * N * 4);
    float *C3 = malloc(M * N * 4);
    CR_REQUIRE(A && B && C1 && C3);
    fill(A, M * K, &rng), fill(B, K * N, &rng);
    int prev = cr_thread_count();
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_set_thread_count(1);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 0, 1, M, N, K, 1.0f, A, K, B, K, 0.0f, C1, N) == 0);
        cr_set_thread_count(3);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 0, 1, M, N, K, 1.0f, A, K, B, K, 0.0f, C3, N) == 0);
        CR_CHECK(memcmp(C1, C3, (size_t)M * N * 4) == 0);
        /* the narrow forward, 3 outputs */
        cr_set_thread_count(1);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 0, 1, M, 3, K, 1.0f, A, K, B, K, 0.0f, C1, 3) == 0);
        cr_set_thread_count(3);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 0, 1, M, 3, K, 1.0f, A, K, B, K, 0.0f, C3, 3) == 0);
        CR_CHECK(memcmp(C1, C3, (size_t)M * 3 * 4) == 0);
        /* k split into chunks: C (3 x 5) = X^T (3 x KS) Y (KS x 5), X and Y
         * read from A */
        const float *X = A, *Y = A + 3 * KS;
        cr_set_thread_count(1);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 1, 0, 3, 5, KS, 1.0f, X, 3, Y, 5, 0.0f, C1, 5) == 0);
        cr_set_thread_count(3);
        CR_CHECK(cr_nn_cpu_gemm_own(level, 1, 0, 3, 5, KS, 1.0f, X, 3, Y, 5, 0.0f, C3, 5) == 0);
        CR_CHECK(memcmp(C1, C3, (size_t)3 * 5 * 4) == 0);
    }
    cr_set_thread_count(prev);
    free(A), free(B), free(C1), free(C3);
}
