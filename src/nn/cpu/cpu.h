/* cpu.h (private): the CPU kernels behind cr_nn_backend_cpu(), one prototype per
 * backend-table entry (see nn/backend.h for what each computes), plus the
 * naive GEMM kept as the reference the tests compare against.
 *
 * Kernels split work with cr_parallel_for once a call touches about
 * NN_CPU_GRAIN elements; below that, thread start-up costs more than it
 * saves. Reductions always use the same block boundaries, so results do not
 * depend on the thread count.
 */
#ifndef CREASE_NN_CPU_H
#define CREASE_NN_CPU_H

#include "nn/backend.h"

#include <math.h>
#include <string.h>

/* NN_CPU_X86: the AVX2 and AVX-512 paths are built (x86 intrinsics, compiled
 * per function with target attributes); elsewhere the portable ones only. */
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define NN_CPU_X86 1
#else
#define NN_CPU_X86 0
#endif

enum { NN_CPU_GRAIN = 16384 }; /* elements per parallel chunk, at least */

/* Rows per chunk so that a chunk holds about NN_CPU_GRAIN elements. */
static inline int64_t nn_cpu_row_grain(int64_t cols) {
    return cols >= NN_CPU_GRAIN ? 1 : NN_CPU_GRAIN / (cols > 0 ? cols : 1);
}

/* key > 0 ? a : b without a branch on the data (a branch on the sign of
 * activations mispredicts half the time); NaN keys select b. */
static inline float nn_cpu_select_pos(float key, float a, float b) {
    uint32_t ua, ub, m = -(uint32_t)(key > 0.0f);
    memcpy(&ua, &a, sizeof ua);
    memcpy(&ub, &b, sizeof ub);
    ua = (ua & m) | (ub & ~m);
    memcpy(&a, &ua, sizeof a);
    return a;
}

/* The logistic function without overflow in exp. */
static inline float nn_cpu_sigmoidf(float x) {
    if (x >= 0.0f) return 1.0f / (1.0f + expf(-x));
    float e = expf(x);
    return e / (1.0f + e);
}

/* log(1 + e) for e in [0, 1] from logf (Goldberg's correction, within 2 ulp):
 * glibc's log1pf costs twice as much and was a quarter of a drape epoch. */
static inline float nn_cpu_log1pf(float e) {
    float u = 1.0f + e;
    return u == 1.0f ? e : logf(u) * (e / (u - 1.0f));
}

/* log(1 + exp(beta x)) / beta without overflow. */
static inline float nn_cpu_softplusf(float x, float beta) {
    float bx = beta * x;
    return (nn_cpu_select_pos(bx, bx, 0.0f) + nn_cpu_log1pf(expf(-fabsf(bx)))) / beta;
}

/* The fused ops' activations, one element (CR_OP_NONE and any other: z). */
static inline float nn_cpu_act(cr_op act, float p, float z) {
    switch (act) {
    case CR_OP_RELU:
        return nn_cpu_select_pos(z, z, 0.0f);
    case CR_OP_LEAKY_RELU:
        return nn_cpu_select_pos(z, z, p * z);
    case CR_OP_TANH:
        return tanhf(z);
    case CR_OP_SIGMOID:
        return nn_cpu_sigmoidf(z);
    case CR_OP_SOFTPLUS:
        return nn_cpu_softplusf(z, p);
    default:
        return z;
    }
}

/* sigmoid(beta x) from y = softplus_beta(x): 1 - exp(-beta y), by its Taylor
 * series below 0.1 where the difference would cancel (glibc's expm1f costs
 * twice expf); relative error below 1e-6. */
static inline float nn_cpu_softplus_deriv_from_y(float y, float beta) {
    float t = beta * y;
    float series =
        t * (1.0f - t * (0.5f - t * (1.0f / 6.0f - t * (1.0f / 24.0f - t * (1.0f / 120.0f)))));
    float direct = 1.0f - expf(-t);
    return t < 0.1f ? series : direct;
}

/* A kernel was handed an op it has no case for: a bug in the tape, so abort
 * naming the kernel and the op. */
void cr_nn_cpu_bad_op(const char *kernel, cr_op op, const char *file, int line)
    __attribute__((noreturn));

/* cpu_elementwise.c */
void cr_nn_cpu_fill(float *x, int64_t n, float value);
void cr_nn_cpu_copy(float *dst, const float *src, int64_t n);
void cr_nn_cpu_unary_forward(cr_op op, float p, const float *x, float *y, int64_t n);
void cr_nn_cpu_unary_backward(cr_op op, float p, const float *x, const float *y, const float *dy,
                              float *dx, int64_t n);
void cr_nn_cpu_binary(cr_op op, nn_binary_mode mode, const float *a, const int64_t as[4],
                      const float *b, const int64_t bs[4], const float *dy, const int64_t ys[4],
                      float *out, int acc);

/* cpu_fused.c: the passes around a fused linear + activation's GEMMs.
 * SIMD paths: the highest the CPU has is chosen at first use
 * (CREASE_NN_SIMD=scalar forces the portable one, =avx2 caps it at AVX2);
 * the elementwise kernels and cpu_vmath.c follow the same level. */
enum { NN_SIMD_SCALAR = 0, NN_SIMD_AVX2 = 1, NN_SIMD_AVX512 = 2 };
int cr_nn_cpu_simd(void);     /* the path in use */
int cr_nn_cpu_simd_max(void); /* the highest this CPU runs */
/* Use `level` (clamped to what the CPU runs); returns the previous level.
 * For tests and benchmarks: not safe while kernels run on other threads. */
int cr_nn_cpu_set_simd(int level);
void cr_nn_cpu_bias_act_forward(cr_op act, float p, const float *b, float *y, int64_t R, int64_t C);
void cr_nn_cpu_act_bias_backward(cr_op act, float p, const float *y, const float *dy, int64_t R,
                                 int64_t C, float *dz, float *db);

/* cpu_vmath.c: the functions the vector transcendental kernels compute;
 * "from y" ones take the activation's output (as the fused backward does). */
typedef enum nn_vec_fn {
    NN_VEC_EXP,
    NN_VEC_LOG,
    NN_VEC_TANH,
    NN_VEC_SIGMOID,
    NN_VEC_SOFTPLUS,              /* softplus with beta p */
    NN_VEC_SIGMOID_SCALED,        /* sigmoid(p x): softplus's derivative */
    NN_VEC_TANH_DERIV_FROM_Y,     /* 1 - y^2 */
    NN_VEC_SIGMOID_DERIV_FROM_Y,  /* y (1 - y) */
    NN_VEC_SOFTPLUS_DERIV_FROM_Y, /* nn_cpu_softplus_deriv_from_y(y, p) */
} nn_vec_fn;
/* out[i] = (acc ? out[i] : 0) + (mul ? mul[i] : 1) fn(p, x[i] + (b ? b[i] : 0))
 * on SIMD `level` for the leading whole vectors of the n elements; returns
 * how many it wrote (0 on the scalar level), the caller does the rest.
 * out may be x. */
int64_t cr_nn_cpu_vec_span(int level, nn_vec_fn fn, float p, const float *x, const float *b,
                           const float *mul, float *out, int acc, int64_t n);
/* out[i] = act(x[i]) over n floats (CR_OP_NONE, RELU, LEAKY_RELU, TANH,
 * SIGMOID, SOFTPLUS with p, or EXP): the vector span where cpu_vmath.c has
 * the function, then nn_cpu_act (expf) for the rest. out may be x. */
void cr_nn_cpu_act_span(int level, cr_op act, float p, const float *x, float *out, int64_t n);

/* cpu_reduce.c */
double cr_nn_cpu_sum_all(const float *x, int64_t n);
void cr_nn_cpu_sum_axis(const float *x, int64_t outer, int64_t len, int64_t inner, float scale,
                        float *y, int acc);
void cr_nn_cpu_expand_axis_acc(const float *dy, int64_t outer, int64_t len, int64_t inner,
                               float scale, float *dx);
void cr_nn_cpu_reduce_to_shape_acc(const float *src, const int64_t ys[4], float *dst,
                                   const int64_t ds[4]);

/* cpu_matmul.c */
void cr_nn_cpu_gemm(int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha, const float *A,
                    int64_t lda, const float *B, int64_t ldb, float beta, float *C, int64_t ldc);
/* Triple loop with double accumulation: the reference for cr_nn_cpu_gemm. */
void cr_nn_cpu_gemm_naive(int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                          const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                          float *C, int64_t ldc);
void cr_nn_cpu_gemm_batched(int ta, int tb, int64_t M, int64_t N, int64_t K, const float *A,
                            int64_t lda, int64_t stride_a, const float *B, int64_t ldb,
                            int64_t stride_b, float beta, float *C, int64_t ldc, int64_t stride_c,
                            int64_t batch);
void cr_nn_cpu_grouped_forward(const float *xs, int64_t K, const float *w, int trans_w, int64_t N,
                               const int64_t *off, int64_t G, float *ys);
void cr_nn_cpu_grouped_backward(const float *xs, const float *dys, int64_t K, const float *w,
                                int trans_w, int64_t N, const int64_t *off, int64_t G, float *dxs,
                                float *dw);

/* cpu_gemm.c: the engine's GEMM (what cr_nn_cpu_gemm computes, for M, N,
 * K > 0 and alpha != 0) on SIMD `level`; -1 without running when those do
 * not hold or memory for the packed B runs out (the caller uses OpenBLAS). */
int cr_nn_cpu_gemm_own(int level, int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                       const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                       float *C, int64_t ldc);
/* cpu_matmul.c: whether cr_nn_cpu_gemm uses it: CREASE_NN_GEMM=own|blas
 * (1, 0); unset, own on the AVX2 and AVX-512 levels (1) unless OpenBLAS
 * runs a kernel measured faster there: on AVX-512 (SkylakeX family) own for
 * products with a side below 128 and OpenBLAS for the others (2), on AVX2
 * (Haswell, Zen) OpenBLAS (0); OpenBLAS on the portable level (0).
 * The setter (for tests and benchmarks) takes 0, 1 or 2 and returns the
 * previous choice; not safe while kernels run on other threads. */
int cr_nn_cpu_gemm_uses_own(void);
int cr_nn_cpu_set_gemm_own(int own);

/* cpu_index.c */
void cr_nn_cpu_copy2d(const float *src, int64_t src_stride, float *dst, int64_t dst_stride,
                      int64_t rows, int64_t cols, int acc);
void cr_nn_cpu_gather_rows(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                           int acc);
void cr_nn_cpu_scatter_rows(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                            int acc);
int64_t cr_nn_cpu_index_check(const int32_t *idx, int64_t n, int64_t limit);
void cr_nn_cpu_csr_build(const int32_t *idx, int64_t n, int64_t nb, int64_t *off, int32_t *perm);
void cr_nn_cpu_segment_sum_rows(const float *x, int64_t C, const int64_t *off, const int32_t *perm,
                                int64_t nseg, float *y, int acc);
void cr_nn_cpu_segment_softmax_forward(const float *x, int64_t H, const int64_t *off,
                                       const int32_t *perm, int64_t nseg, float *y);
void cr_nn_cpu_segment_softmax_backward(const float *y, const float *dy, int64_t H,
                                        const int64_t *off, const int32_t *perm, int64_t nseg,
                                        float *dx);

/* cpu_gat.c */
size_t cr_nn_cpu_gat_attend_scratch(const nn_gat_attend_args *a);
void cr_nn_cpu_gat_attend_forward(const nn_gat_attend_args *a);

/* cpu_rnn.c */
void cr_nn_cpu_lstm_gates_forward(const nn_lstm_gates_args *a);

/* cpu_mpnn.c */
size_t cr_nn_cpu_mpnn_block_scratch(const nn_mpnn_block_args *a);
void cr_nn_cpu_mpnn_block_forward(const nn_mpnn_block_args *a);
/* cpu_wire.c */
void cr_nn_cpu_wire_points_forward(const nn_wire_points_args *a);

/* cpu_vector.c */
void cr_nn_cpu_layer_norm_forward(const float *x, int64_t R, int64_t C, const float *w,
                                  const float *b, float eps, float *y, float *mean, float *rstd);
void cr_nn_cpu_layer_norm_backward(const float *x, const float *dy, int64_t R, int64_t C,
                                   const float *w, const float *mean, const float *rstd, float *dx,
                                   float *dw, float *db);
void cr_nn_cpu_cross_forward(const float *a, const float *b, int64_t R, float *y);
void cr_nn_cpu_cross_backward(const float *a, const float *b, const float *dy, int64_t R, float *da,
                              float *db);
void cr_nn_cpu_dot_forward(const float *a, const float *b, int64_t R, int64_t C, float *y);
void cr_nn_cpu_dot_backward(const float *a, const float *b, const float *dy, int64_t R, int64_t C,
                            float *da, float *db);
void cr_nn_cpu_norm_forward(const float *x, int64_t R, int64_t C, float *y);
void cr_nn_cpu_norm_backward(const float *x, const float *y, const float *dy, int64_t R, int64_t C,
                             float eps, float *dx);
void cr_nn_cpu_normalize_forward(const float *x, int64_t R, int64_t C, float eps, float *y);
void cr_nn_cpu_normalize_backward(const float *x, const float *y, const float *dy, int64_t R,
                                  int64_t C, float eps, float *dx);

#endif
