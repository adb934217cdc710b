/* ops_matmul.c: matrix products: plain and batched matmul with transpose
 * flags, per-group weights (hyper-networks), and the linear layer.
 *
 * With C = op(A) op(B), the backward is the usual pair (written for the
 * stored layouts so no transpose is ever materialised):
 *   dA = dC op(B)^T   (stored transposed: dA^T = op(B) dC^T)
 *   dB = op(A)^T dC   (stored transposed: dB^T = dC^T op(A))
 * Grouped rows are sorted by group once (counting sort), each group is one
 * GEMM against its own weight, and the results are scattered back.
 * Leaves out: broadcasting a 2-D weight over a 3-D batch (reshape to 2-D).
 */
#include "nn/tape.h"

#include <limits.h>
#include <stdio.h>

/* "(64,3)" or "(3,64)^T" for messages. */
static const char *shape_t(const cr_tensor *t, int trans, char *buf, size_t cap) {
    char s[64];
    snprintf(buf, cap, "%s%s", cr_nn_shape_str(t, s, sizeof s), trans ? "^T" : "");
    return buf;
}

/* BLAS takes int sizes. */
static int blas_sizes_ok(cr_nn_ctx *ctx, const char *op, int64_t m, int64_t n, int64_t k) {
    if (m <= INT_MAX && n <= INT_MAX && k <= INT_MAX) return 1;
    NN_FAIL(ctx, CR_ERR_RANGE, "%s: a dimension exceeds the BLAS limit of %d", op, INT_MAX);
    return 0;
}

/* ------------------------------------------------------------- matmul -- */

cr_tensor *cr_nn_matmul(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b, int trans_a, int trans_b) {
    cr_tensor *src[2] = {a, b};
    if (!cr_nn_begin(ctx, "matmul", 2, src)) return NULL;
    char sa[80], sb[80];
    int batched = a->ndim == 3;
    if (!((a->ndim == 2 && b->ndim == 2) || (a->ndim == 3 && b->ndim == 3))) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "matmul: expects 2-D x 2-D or 3-D x 3-D, got %s x %s",
                shape_t(a, trans_a, sa, sizeof sa), shape_t(b, trans_b, sb, sizeof sb));
        return NULL;
    }
    int r = batched; /* index of the row axis */
    int64_t M = trans_a ? a->shape[r + 1] : a->shape[r];
    int64_t Ka = trans_a ? a->shape[r] : a->shape[r + 1];
    int64_t Kb = trans_b ? b->shape[r + 1] : b->shape[r];
    int64_t N = trans_b ? b->shape[r] : b->shape[r + 1];
    if (batched && a->shape[0] != b->shape[0]) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "matmul: batch sizes differ: %s x %s",
                shape_t(a, trans_a, sa, sizeof sa), shape_t(b, trans_b, sb, sizeof sb));
        return NULL;
    }
    if (Ka != Kb) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "matmul: inner dimensions differ: %s x %s",
                shape_t(a, trans_a, sa, sizeof sa), shape_t(b, trans_b, sb, sizeof sb));
        return NULL;
    }
    if (!blas_sizes_ok(ctx, "matmul", M, N, Ka)) return NULL;
    int64_t shape[3] = {a->shape[0], M, N};
    cr_tensor *y =
        batched ? cr_nn_tensor(ctx, "matmul", 3, shape) : cr_nn_tensor(ctx, "matmul", 2, shape + 1);
    if (!y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node n = {.op = batched ? CR_OP_MATMUL_BATCHED : CR_OP_MATMUL,
                 .nsrc = 2,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.matmul = {.trans_a = trans_a != 0, .trans_b = trans_b != 0}};
    return cr_nn_run(ctx, &n);
}

/* Sizes of a (batched) product as recorded: batch, M, N, K, stored row
 * lengths of a and b. */
typedef struct mm_dims {
    int64_t batch, M, N, K, lda, ldb;
} mm_dims;

static mm_dims matmul_dims(const nn_node *n) {
    const cr_tensor *a = n->src[0], *b = n->src[1], *y = n->out[0];
    int r = n->op == CR_OP_MATMUL_BATCHED;
    mm_dims d;
    d.batch = r ? a->shape[0] : 1;
    d.M = y->shape[r];
    d.N = y->shape[r + 1];
    d.K = n->p.matmul.trans_a ? a->shape[r] : a->shape[r + 1];
    d.lda = a->shape[r + 1];
    d.ldb = b->shape[r + 1];
    return d;
}

void cr_nn_matmul_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *a = n->src[0], *b = n->src[1];
    cr_tensor *y = n->out[0];
    mm_dims d = matmul_dims(n);
    ctx->be->gemm_batched(n->p.matmul.trans_a, n->p.matmul.trans_b, d.M, d.N, d.K, a->data, d.lda,
                          d.M * d.K, b->data, d.ldb, d.K * d.N, 0.0f, y->data, d.N, d.M * d.N,
                          d.batch);
}

void cr_nn_matmul_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *a = n->src[0], *b = n->src[1], *y = n->out[0];
    float *ga = nn_gout(a), *gb = nn_gout(b);
    int ta = n->p.matmul.trans_a, tb = n->p.matmul.trans_b;
    mm_dims d = matmul_dims(n);
    int64_t sa = d.M * d.K, sb = d.K * d.N, sy = d.M * d.N;
    const cr_nn_backend *be = ctx->be;
    if (ga && !ta) /* dA (M,K) += dC op(B)^T */
        be->gemm_batched(0, !tb, d.M, d.K, d.N, y->grad, d.N, sy, b->data, d.ldb, sb, 1.0f, ga, d.K,
                         sa, d.batch);
    if (ga && ta) /* dA^T (K,M) += op(B) dC^T */
        be->gemm_batched(tb, 1, d.K, d.M, d.N, b->data, d.ldb, sb, y->grad, d.N, sy, 1.0f, ga, d.M,
                         sa, d.batch);
    if (gb && !tb) /* dB (K,N) += op(A)^T dC */
        be->gemm_batched(!ta, 0, d.K, d.N, d.M, a->data, d.lda, sa, y->grad, d.N, sy, 1.0f, gb, d.N,
                         sb, d.batch);
    if (gb && tb) /* dB^T (N,K) += dC^T op(A) */
        be->gemm_batched(1, ta, d.N, d.K, d.M, y->grad, d.N, sy, a->data, d.lda, sa, 1.0f, gb, d.K,
                         sb, d.batch);
}

/* ------------------------------------------------------------ grouped -- */

cr_tensor *cr_nn_matmul_grouped(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, const int32_t *group,
                                int trans_w) {
    const char *name = "matmul_grouped";
    cr_tensor *src[2] = {x, w};
    if (!cr_nn_begin(ctx, name, 2, src)) return NULL;
    char sx[80], sw[80];
    if (x->ndim != 2 || w->ndim != 3) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: expects x (M,K) and w (G,K,N), got %s and %s", name,
                cr_nn_shape_str(x, sx, sizeof sx), cr_nn_shape_str(w, sw, sizeof sw));
        return NULL;
    }
    int64_t M = x->shape[0], K = x->shape[1], G = w->shape[0];
    int64_t Kw = trans_w ? w->shape[2] : w->shape[1], N = trans_w ? w->shape[1] : w->shape[2];
    if (K != Kw) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: inner dimensions differ: %s x %s", name,
                cr_nn_shape_str(x, sx, sizeof sx), shape_t(w, trans_w, sw, sizeof sw));
        return NULL;
    }
    if (!blas_sizes_ok(ctx, name, M, N, K)) return NULL;
    CR_ASSERT(group || M == 0);
    int64_t bad = ctx->be->index_check(group, M, G);
    if (bad >= 0) {
        NN_FAIL(ctx, CR_ERR_RANGE, "%s: group id %d of row %lld is out of range [0,%lld)", name,
                group[bad], (long long)bad, (long long)G);
        return NULL;
    }
    int64_t *off = cr_nn_alloc(ctx, name, (size_t)(G + 1) * sizeof(int64_t));
    int32_t *perm = cr_nn_alloc(ctx, name, (size_t)M * sizeof(int32_t));
    float *xs = cr_nn_alloc(ctx, name, (size_t)(M * K) * sizeof(float));
    cr_tensor *y = cr_nn_tensor(ctx, name, 2, (int64_t[]){M, N});
    if (!off || !perm || !xs || !y) return NULL;
    ctx->be->csr_build(group, M, G, off, perm);
    cr_tensor *out[1] = {y};
    nn_node n = {
        .op = CR_OP_MATMUL_GROUPED,
        .nsrc = 2,
        .src = src,
        .nout = 1,
        .out = out,
        .p.grouped = {.trans_w = trans_w != 0, .groups = G, .off = off, .perm = perm, .xs = xs}};
    return cr_nn_run(ctx, &n);
}

void cr_nn_grouped_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1];
    cr_tensor *y = n->out[0];
    const nn_grouped_params *p = &n->p.grouped;
    int64_t M = x->shape[0], K = x->shape[1], N = y->shape[1];
    const cr_nn_backend *be = ctx->be;
    be->gather_rows(x->data, K, p->perm, M, p->xs, 0);
    size_t mark = cr_arena_mark(&ctx->arena);
    float *ys = cr_nn_alloc(ctx, "matmul_grouped", (size_t)(M * N) * sizeof(float));
    if (!ys) return;
    be->grouped_forward(p->xs, K, w->data, p->trans_w, N, p->off, p->groups, ys);
    be->scatter_rows(ys, N, p->perm, M, y->data, 0);
    cr_arena_rewind(&ctx->arena, mark);
}

void cr_nn_grouped_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1], *y = n->out[0];
    const nn_grouped_params *p = &n->p.grouped;
    float *gx = nn_gout(x), *gw = nn_gout(w);
    if (!gx && !gw) return;
    int64_t M = x->shape[0], K = x->shape[1], N = y->shape[1];
    const cr_nn_backend *be = ctx->be;
    size_t mark = cr_arena_mark(&ctx->arena);
    float *dys = cr_nn_alloc(ctx, "matmul_grouped", (size_t)(M * N) * sizeof(float));
    float *dxs = gx ? cr_nn_alloc(ctx, "matmul_grouped", (size_t)(M * K) * sizeof(float)) : NULL;
    if (!dys || (gx && !dxs)) return;
    be->gather_rows(y->grad, N, p->perm, M, dys, 0);
    be->grouped_backward(p->xs, dys, K, w->data, p->trans_w, N, p->off, p->groups, dxs, gw);
    if (gx) be->scatter_rows(dxs, K, p->perm, M, gx, 1);
    cr_arena_rewind(&ctx->arena, mark);
}

/* ------------------------------------------------------------- linear -- */

/* The activations whose derivative the fused backward reads off the output. */
static int fusable_act(cr_op act, float p) {
    return act == CR_OP_NONE || act == CR_OP_RELU || (act == CR_OP_LEAKY_RELU && p >= 0.0f) ||
           act == CR_OP_TANH || act == CR_OP_SIGMOID || (act == CR_OP_SOFTPLUS && p > 0.0f);
}

cr_tensor *cr_nn_linear_act(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b, cr_op act,
                            float p) {
    cr_tensor *src[3] = {x, w, b};
    if (!cr_nn_begin(ctx, "linear", 2, src)) return NULL;
    char sx[64], sw[64], sb[64];
    if (!fusable_act(act, p)) {
        NN_FAIL(ctx, CR_ERR_INVALID,
                "linear: activation %s (p = %g) cannot be fused (none, relu, leaky_relu with "
                "slope >= 0, tanh, sigmoid, softplus with beta > 0)",
                cr_op_name(act), (double)p);
        return NULL;
    }
    if (x->ndim < 1 || w->ndim != 2 || x->shape[x->ndim - 1] != w->shape[1]) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "linear: x %s does not match weight %s (OUT,IN)",
                cr_nn_shape_str(x, sx, sizeof sx), cr_nn_shape_str(w, sw, sizeof sw));
        return NULL;
    }
    if (b && (b->ndim != 1 || b->shape[0] != w->shape[0])) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "linear: bias %s does not match weight %s (OUT,IN)",
                cr_nn_shape_str(b, sb, sizeof sb), cr_nn_shape_str(w, sw, sizeof sw));
        return NULL;
    }
    int64_t rows, in;
    cr_nn_rows_cols(x, &rows, &in);
    if (!blas_sizes_ok(ctx, "linear", rows, w->shape[0], in)) return NULL;
    int64_t shape[CR_NN_MAX_DIMS];
    for (int i = 0; i < x->ndim; i++)
        shape[i] = x->shape[i];
    shape[x->ndim - 1] = w->shape[0];
    cr_tensor *y = cr_nn_tensor(ctx, "linear", x->ndim, shape);
    if (!y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node n = {.op = CR_OP_LINEAR,
                 .nsrc = 3,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.linear = {.act = act, .p = p}};
    return cr_nn_run(ctx, &n);
}

cr_tensor *cr_nn_linear(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b) {
    return cr_nn_linear_act(ctx, x, w, b, CR_OP_NONE, 0.0f);
}

void cr_nn_linear_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1], *b = n->src[2];
    cr_tensor *y = n->out[0];
    int64_t R, in, out = w->shape[0];
    cr_nn_rows_cols(x, &R, &in);
    /* y (R,OUT) = x (R,IN) W^T (IN,OUT), then bias and activation in one pass */
    ctx->be->gemm(0, 1, R, out, in, 1.0f, x->data, in, w->data, in, 0.0f, y->data, out);
    ctx->be->bias_act_forward(n->p.linear.act, n->p.linear.p, b ? b->data : NULL, y->data, R, out);
}

void cr_nn_linear_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1], *b = n->src[2], *y = n->out[0];
    float *gx = nn_gout(x), *gw = nn_gout(w), *gb = nn_gout(b);
    int64_t R, in, out = w->shape[0];
    cr_nn_rows_cols(x, &R, &in);
    const cr_nn_backend *be = ctx->be;
    cr_op act = n->p.linear.act;
    size_t mark = cr_arena_mark(&ctx->arena);
    /* dz = dy act'(z), with db's column sums in the same pass; without an
     * activation dz is dy itself. */
    const float *dz = y->grad;
    if (act != CR_OP_NONE && (gx || gw)) {
        float *tmp = cr_nn_alloc(ctx, "linear", (size_t)y->numel * sizeof(float));
        if (!tmp) return;
        be->act_bias_backward(act, n->p.linear.p, y->data, y->grad, R, out, tmp, gb);
        dz = tmp;
    } else if (gb) {
        be->act_bias_backward(act, n->p.linear.p, y->data, y->grad, R, out, NULL, gb);
    }
    if (gw) /* dW (OUT,IN) += dz^T (OUT,R) x (R,IN) */
        be->gemm(1, 0, out, in, R, 1.0f, dz, out, x->data, in, 1.0f, gw, in);
    if (gx) /* dx (R,IN) (+)= dz (R,OUT) W (OUT,IN); assigned into a fresh grad */
        be->gemm(0, 0, R, in, out, 1.0f, dz, out, w->data, in, ctx->fresh_grad == x ? 0.0f : 1.0f,
                 gx, in);
    cr_arena_rewind(&ctx->arena, mark);
}
