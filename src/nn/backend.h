/* backend.h (private): the table of kernels the tape calls.
 *
 * The tape (tape.c, ops_*.c) decides shapes, allocates from the arena and
 * records nodes; it never loops over tensor elements. All element work goes
 * through one of these function pointers, which take raw pointers and sizes,
 * so a CUDA backend is a second table (src/nn/cuda/) with the same entries.
 *
 * Conventions for every entry:
 *   - pointers are device pointers of the backend's device;
 *   - `acc` (accumulate) means dst += result, otherwise dst = result;
 *   - backward kernels always accumulate into input grads (the tape zeroes
 *     grad buffers when it allocates them);
 *   - padded shapes are 4 entries, right-aligned with leading 1s (numpy
 *     broadcasting order).
 * Index arrays (int32) live in host memory on every backend.
 */
#ifndef CREASE_NN_BACKEND_H
#define CREASE_NN_BACKEND_H

#include "crease/nn.h"

/* Which result a broadcast binary loop writes (see binary below). */
typedef enum nn_binary_mode {
    NN_BINARY_VALUE,  /* out = f(a, b) */
    NN_BINARY_GRAD_A, /* out = dy * df/da */
    NN_BINARY_GRAD_B  /* out = dy * df/db */
} nn_binary_mode;

/* GAT-LN's attention for inference (cpu_gat.c): what layer_gat.c's tape
 * ops compute from the projection p to the activated output. Several heads
 * may go aggregate-first (p NULL): per head the weighted sums of the inputs
 * x (IN wide, where p's head is F wide), then one GEMM over the heads side
 * by side (averaged) or one per head (concatenated); the same products,
 * fewer bytes per edge. Edges come grouped by receiver:
 * those of receiver i are snd[perm[k]] for k in [off[i], off[i+1]), self loops included. */
enum { NN_GAT_MAX_HEADS = 64 };
enum { NN_GAT_NORM_NONE = 0, NN_GAT_NORM_GLOBAL = 1, NN_GAT_NORM_RECEIVER = 2 }; /* cr_gat_norm */
typedef struct nn_gat_attend_args {
    int64_t N, IN, H, F; /* nodes, input features, heads (<= NN_GAT_MAX_HEADS), per-head out */
    int concat;          /* 1: out (N,H*F) heads side by side; 0: (N,F) their mean */
    int norm;            /* NN_GAT_NORM_* */
    float alpha, slope;  /* eq. 4's alpha; LeakyReLU's negative slope */
    const float *x;      /* (N,IN) the layer's input (|x| of eq. 4) */
    const float *w;      /* (H*F,IN) the projection's weight (Lip(g) of eq. 4) */
    const float *p;      /* (N,H*F) x w^T; NULL: aggregate first */
    const float *att_src, *att_dst; /* (H,F) */
    const int64_t *off;             /* (N+1) */
    const int32_t *perm, *snd;      /* (E) */
    const float *bias;              /* (concat ? H*F : F) added to out, or NULL */
    cr_op act;                      /* then out = act(out): NONE, RELU, LEAKY_RELU, TANH, */
    float act_p;                    /* SIGMOID or SOFTPLUS, with its slope or beta */
    float *scratch;                 /* gat_attend_scratch(N, E, H) floats */
    float *out;                     /* (N,concat ? H*F : F) */
} nn_gat_attend_args;

/* An LSTM cell's gates for inference (cpu_rnn.c): z = zx + zh (+ peepholes
 * on c), [i, f, g, o] along 4H, c_out = f c + i g, h = o tanh(c_out). */
typedef struct nn_lstm_gates_args {
    int64_t B, H;
    const float *zx;    /* (B,4H) */
    const float *zh;    /* (B,4H) or NULL (zero) */
    const float *c;     /* (B,H) or NULL (zero state) */
    const float *pw[3]; /* (H) peephole weights of i, f, o on c, or all NULL */
    float *z;           /* (B,4H) scratch */
    float *h, *c_out;   /* (B,H) */
} nn_lstm_gates_args;

/* One MLP block of a message-passing net over rows (edges or nodes) for
 * inference (cpu_mpnn.c): per row r, with x_r = x[x_rows ? x_rows[r] : r]
 * (rows ldx apart, 0: width[0]),
 *   z = x_r W0^T + b0 (+ gath[0][gath_idx[0][r]] + gath[1][gath_idx[1][r]]),
 *   z = act_l(z Wl^T + bl) layer by layer (act_0 on the first),
 *   z = LayerNorm(z) with ln_w, ln_b (when ln_w),  out_r = res_r + z (res
 *   NULL: z),
 * and, when agg, agg[n] = sum of out_r over the rows of node n, rows
 * [off[n], off[n+1]) (rows sorted by node; every node's sum written, rows
 * ld_agg apart, 0: width[nl]). Layer l's weight is (width[l+1], ldw[l])
 * row-major, its first width[l] columns used (a column block of a wider
 * layer: w[l] may point into a row). */
enum { NN_MPNN_MAX_LAYERS = 8, NN_MPNN_MAX_WIDTH = 256 };
typedef struct nn_mpnn_block_args {
    int64_t R, N;                          /* rows; nodes of gath and agg */
    int nl;                                /* layers, 1..NN_MPNN_MAX_LAYERS */
    int64_t width[NN_MPNN_MAX_LAYERS + 1]; /* width[0]: x's; the others <= NN_MPNN_MAX_WIDTH */
    const float *w[NN_MPNN_MAX_LAYERS];
    int64_t ldw[NN_MPNN_MAX_LAYERS];
    const float *b[NN_MPNN_MAX_LAYERS]; /* or NULL */
    cr_op act[NN_MPNN_MAX_LAYERS];      /* NONE, RELU, LEAKY_RELU, TANH, SIGMOID, SOFTPLUS */
    float act_p[NN_MPNN_MAX_LAYERS];
    const float *x;             /* rows of width[0], ldx apart */
    int64_t ldx;                /* 0: width[0] */
    const int32_t *x_rows;      /* (R) or NULL */
    const float *gath[2];       /* (N,width[1]) rows added to the first layer, or NULL */
    const int32_t *gath_idx[2]; /* (R) */
    const float *ln_w, *ln_b;   /* (width[nl]) or NULL */
    float ln_eps;
    const float *res;   /* (R,width[nl]) added to the output, or NULL; may be out */
    float *out;         /* (R,width[nl]); may be x */
    float *agg;         /* (N,width[nl]) rows ld_agg apart, or NULL */
    int64_t ld_agg;     /* 0: width[nl] */
    const int64_t *off; /* (N+1) with agg */
    float *scratch;     /* mpnn_block_scratch(a) floats */
} nn_mpnn_block_args;

/* WIRE networks from a hyper-network's rows, one per point
 * (cr_wire_hyper_infer, nn_layers.h). */
typedef struct nn_wire_points_args {
    const float *theta; /* (G,P) */
    int64_t P;
    const int32_t *group; /* (M) rows of theta, in [0,G) */
    int64_t G;
    const int64_t *off;  /* (G+1) and perm (M): the points by group (csr_build), so that */
    const int32_t *perm; /* a row's points run one after another while it is in cache */
    const float *x;      /* point m's inputs at x[m ldx] and x[m ldx + 1] */
    int64_t ldx, M;
    int width, layers, out;
    float omega0, s2; /* s2 = s0^2 */
    float *y;         /* (M,out) */
} nn_wire_points_args;

typedef struct cr_nn_backend {
    const char *name;

    /* ---- memory */
    void (*fill)(float *x, int64_t n, float value);
    void (*copy)(float *dst, const float *src, int64_t n);

    /* ---- elementwise (op is one of the unary cr_op values; p its parameter:
     * constant, exponent, slope or beta) */
    void (*unary_forward)(cr_op op, float p, const float *x, float *y, int64_t n);
    /* dx += dy * f'(x); y is the forward output (tanh, sigmoid use it). */
    void (*unary_backward)(cr_op op, float p, const float *x, const float *y, const float *dy,
                           float *dx, int64_t n);
    /* op in ADD..DIV. out has shape ys; a, b broadcast to it. dy is read in
     * the GRAD modes (shape ys). */
    void (*binary)(cr_op op, nn_binary_mode mode, const float *a, const int64_t as[4],
                   const float *b, const int64_t bs[4], const float *dy, const int64_t ys[4],
                   float *out, int acc);

    /* ---- reductions (double accumulation, fixed order) */
    double (*sum_all)(const float *x, int64_t n);
    /* x viewed as (outer, len, inner): y[o,i] (+)= scale * sum_l x[o,l,i]. */
    void (*sum_axis)(const float *x, int64_t outer, int64_t len, int64_t inner, float scale,
                     float *y, int acc);
    /* dx[o,l,i] += scale * dy[o,i] (the backward of sum_axis). */
    void (*expand_axis_acc)(const float *dy, int64_t outer, int64_t len, int64_t inner, float scale,
                            float *dx);
    /* dst (shape ds) += src (shape ys) summed over the axes where ds is 1. */
    void (*reduce_to_shape_acc)(const float *src, const int64_t ys[4], float *dst,
                                const int64_t ds[4]);

    /* ---- matrix products, row-major, cblas semantics:
     * C (M,N) = alpha op(A) op(B) + beta C, op(A) (M,K), op(B) (K,N). */
    void (*gemm)(int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha, const float *A,
                 int64_t lda, const float *B, int64_t ldb, float beta, float *C, int64_t ldc);
    /* The same for `batch` products at fixed strides (floats) between them. */
    void (*gemm_batched)(int ta, int tb, int64_t M, int64_t N, int64_t K, const float *A,
                         int64_t lda, int64_t stride_a, const float *B, int64_t ldb,
                         int64_t stride_b, float beta, float *C, int64_t ldc, int64_t stride_c,
                         int64_t batch);
    /* Grouped products on rows sorted by group (off: (G+1) row offsets):
     * ys[off[g]:off[g+1]] = xs[off[g]:off[g+1]] op(w[g]); w (G,K,N) or
     * (G,N,K) when trans_w. */
    void (*grouped_forward)(const float *xs, int64_t K, const float *w, int trans_w, int64_t N,
                            const int64_t *off, int64_t G, float *ys);
    /* dxs = dys op(w[g])^T (assigned, may be NULL), dw[g] += xs^T dys (may be NULL). */
    void (*grouped_backward)(const float *xs, const float *dys, int64_t K, const float *w,
                             int trans_w, int64_t N, const int64_t *off, int64_t G, float *dxs,
                             float *dw);

    /* ---- the passes of a fused linear + activation (act: CR_OP_NONE, RELU,
     * LEAKY_RELU with p >= 0, TANH, SIGMOID or SOFTPLUS with beta p > 0; y and
     * dy (R,C) row-major) */
    /* y = act(y + b) in place; b (C) may be NULL. */
    void (*bias_act_forward)(cr_op act, float p, const float *b, float *y, int64_t R, int64_t C);
    /* dz = dy act'(.) from the output y (assigned; may be NULL), db += its
     * column sums (may be NULL). */
    void (*act_bias_backward)(cr_op act, float p, const float *y, const float *dy, int64_t R,
                              int64_t C, float *dz, float *db);

    /* ---- indexing */
    /* rows x cols block copy between row strides (src_stride 0 repeats one row). */
    void (*copy2d)(const float *src, int64_t src_stride, float *dst, int64_t dst_stride,
                   int64_t rows, int64_t cols, int acc);
    /* y[i] (+)= x[idx[i]], rows of C floats, i in [0,n). */
    void (*gather_rows)(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                        int acc);
    /* y[idx[i]] (+)= x[i]; idx must be a permutation (no repeats). */
    void (*scatter_rows)(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                         int acc);
    /* Position of the first idx outside [0,limit), or -1. */
    int64_t (*index_check)(const int32_t *idx, int64_t n, int64_t limit);
    /* Counting sort of positions by bucket (stable): off (nb+1), perm (n);
     * positions with idx == b are perm[off[b]..off[b+1]). idx checked first. */
    void (*csr_build)(const int32_t *idx, int64_t n, int64_t nb, int64_t *off, int32_t *perm);
    /* y[s] (+)= sum of x[perm[j]] for j in [off[s],off[s+1]), rows of C floats. */
    void (*segment_sum_rows)(const float *x, int64_t C, const int64_t *off, const int32_t *perm,
                             int64_t nseg, float *y, int acc);
    void (*segment_softmax_forward)(const float *x, int64_t H, const int64_t *off,
                                    const int32_t *perm, int64_t nseg, float *y);
    void (*segment_softmax_backward)(const float *y, const float *dy, int64_t H, const int64_t *off,
                                     const int32_t *perm, int64_t nseg, float *dx);

    /* ---- fused forward-only kernels (inference: no tape, nothing kept) */
    size_t (*gat_attend_scratch)(const nn_gat_attend_args *a); /* floats; a without scratch */
    void (*gat_attend_forward)(const nn_gat_attend_args *a);
    void (*lstm_gates_forward)(const nn_lstm_gates_args *a);
    size_t (*mpnn_block_scratch)(const nn_mpnn_block_args *a); /* floats; a without scratch */
    void (*mpnn_block_forward)(const nn_mpnn_block_args *a);
    void (*wire_points_forward)(const nn_wire_points_args *a);

    /* ---- row-wise vector ops over rows of C floats */
    /* mean, rstd: (R) saved for backward; w, b may be NULL. */
    void (*layer_norm_forward)(const float *x, int64_t R, int64_t C, const float *w, const float *b,
                               float eps, float *y, float *mean, float *rstd);
    void (*layer_norm_backward)(const float *x, const float *dy, int64_t R, int64_t C,
                                const float *w, const float *mean, const float *rstd, float *dx,
                                float *dw, float *db);
    void (*cross_forward)(const float *a, const float *b, int64_t R, float *y);
    void (*cross_backward)(const float *a, const float *b, const float *dy, int64_t R, float *da,
                           float *db);
    void (*dot_forward)(const float *a, const float *b, int64_t R, int64_t C, float *y);
    void (*dot_backward)(const float *a, const float *b, const float *dy, int64_t R, int64_t C,
                         float *da, float *db);
    void (*norm_forward)(const float *x, int64_t R, int64_t C, float *y);
    void (*norm_backward)(const float *x, const float *y, const float *dy, int64_t R, int64_t C,
                          float eps, float *dx);
    void (*normalize_forward)(const float *x, int64_t R, int64_t C, float eps, float *y);
    void (*normalize_backward)(const float *x, const float *y, const float *dy, int64_t R,
                               int64_t C, float eps, float *dx);
} cr_nn_backend;

/* The CPU table (src/nn/cpu/cpu_backend.c). */
const cr_nn_backend *cr_nn_backend_cpu(void);

#endif
