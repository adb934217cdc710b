/* ops_index.c: concat, slice, gather rows, scatter-add rows and segment
 * softmax, forward and backward.
 *
 * Rows are the first axis. Gather's backward and scatter-add's forward are
 * the same reduction (many source rows into one target row); both group the
 * source positions by target with a counting sort and then sum each target's
 * rows in a fixed order, which is race-free in parallel and deterministic.
 * Segment softmax (eq. 2 of Velickovic et al., "Graph Attention Networks",
 * ICLR 2018, per destination node) subtracts each segment's maximum before
 * exponentiating and has backward dx = y (dy - sum_seg(y dy)).
 * Leaves out: strided slices, gathers along other axes (reshape/concat).
 */
#include "nn/tape.h"

/* ------------------------------------------------------------- concat -- */

cr_tensor *cr_nn_concat(cr_nn_ctx *ctx, int n, cr_tensor *const *ts, int axis) {
    CR_ASSERT(n >= 1 && ts);
    if (!cr_nn_begin(ctx, "concat", n, ts)) return NULL;
    int a;
    if (!cr_nn_axis(ctx, "concat", ts[0], axis, &a)) return NULL;
    int64_t shape[CR_NN_MAX_DIMS];
    for (int d = 0; d < ts[0]->ndim; d++)
        shape[d] = ts[0]->shape[d];
    for (int i = 1; i < n; i++) {
        int same = ts[i]->ndim == ts[0]->ndim;
        for (int d = 0; same && d < ts[0]->ndim; d++)
            same = d == a || ts[i]->shape[d] == ts[0]->shape[d];
        if (!same) {
            char s0[64], si[64];
            NN_FAIL(ctx, CR_ERR_SHAPE,
                    "concat: shapes differ outside axis %d: %s and %s (input %d)", axis,
                    cr_nn_shape_str(ts[0], s0, sizeof s0), cr_nn_shape_str(ts[i], si, sizeof si),
                    i);
            return NULL;
        }
        shape[a] += ts[i]->shape[a];
    }
    cr_tensor *y = cr_nn_tensor(ctx, "concat", ts[0]->ndim, shape);
    if (!y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node node = {.op = CR_OP_CONCAT,
                    .nsrc = n,
                    .src = (cr_tensor **)ts,
                    .nout = 1,
                    .out = out,
                    .p.slice = {.axis = a}};
    return cr_nn_run(ctx, &node);
}

void cr_nn_concat_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *y = n->out[0];
    int64_t outer, total, inner, off = 0;
    cr_nn_split_axis(y, n->p.slice.axis, &outer, &total, &inner);
    for (int i = 0; i < n->nsrc; i++) {
        int64_t len = n->src[i]->shape[n->p.slice.axis];
        ctx->be->copy2d(n->src[i]->data, len * inner, y->data + off * inner, total * inner, outer,
                        len * inner, 0);
        off += len;
    }
}

void cr_nn_concat_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *y = n->out[0];
    int64_t outer, total, inner, off = 0;
    cr_nn_split_axis(y, n->p.slice.axis, &outer, &total, &inner);
    for (int i = 0; i < n->nsrc; i++) {
        int64_t len = n->src[i]->shape[n->p.slice.axis];
        float *g = nn_gout(n->src[i]);
        if (g)
            ctx->be->copy2d(y->grad + off * inner, total * inner, g, len * inner, outer,
                            len * inner, 1);
        off += len;
    }
}

/* -------------------------------------------------------------- slice -- */

cr_tensor *cr_nn_slice(cr_nn_ctx *ctx, cr_tensor *x, int axis, int64_t start, int64_t len) {
    if (!cr_nn_begin(ctx, "slice", 1, &x)) return NULL;
    int a;
    if (!cr_nn_axis(ctx, "slice", x, axis, &a)) return NULL;
    if (start < 0 || len < 0 || start > x->shape[a] - len) {
        NN_FAIL(ctx, CR_ERR_RANGE, "slice: [%lld,%lld) is outside axis %d of size %lld",
                (long long)start, (long long)(start + len), axis, (long long)x->shape[a]);
        return NULL;
    }
    if (a == 0) return cr_nn_slice_view(ctx, x, start, len);
    int64_t shape[CR_NN_MAX_DIMS];
    for (int d = 0; d < x->ndim; d++)
        shape[d] = x->shape[d];
    shape[a] = len;
    cr_tensor *y = cr_nn_tensor(ctx, "slice", x->ndim, shape);
    if (!y) return NULL;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node n = {.op = CR_OP_SLICE,
                 .nsrc = 1,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.slice = {.axis = a, .start = start}};
    return cr_nn_run(ctx, &n);
}

void cr_nn_slice_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    int64_t outer, full, inner, len = y->shape[n->p.slice.axis];
    cr_nn_split_axis(x, n->p.slice.axis, &outer, &full, &inner);
    ctx->be->copy2d(x->data + n->p.slice.start * inner, full * inner, y->data, len * inner, outer,
                    len * inner, 0);
}

void cr_nn_slice_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    if (!gx) return;
    int64_t outer, full, inner, len = y->shape[n->p.slice.axis];
    cr_nn_split_axis(x, n->p.slice.axis, &outer, &full, &inner);
    ctx->be->copy2d(y->grad, len * inner, gx + n->p.slice.start * inner, full * inner, outer,
                    len * inner, 1);
}

/* ------------------------------------------------------ row index ops -- */

/* Rows and row length (C) of x; x must have at least one axis. */
static int rows_of(cr_nn_ctx *ctx, const char *op, const cr_tensor *x, int64_t *rows, int64_t *C) {
    if (x->ndim < 1) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: expects a tensor with rows, got a scalar", op);
        return 0;
    }
    *rows = x->shape[0];
    *C = 1;
    for (int d = 1; d < x->ndim; d++)
        *C *= x->shape[d];
    return 1;
}

/* Range-check an index array, copy it into the arena. */
static int32_t *checked_index(cr_nn_ctx *ctx, const char *op, const char *what, const int32_t *idx,
                              int64_t n, int64_t limit) {
    CR_ASSERT(idx || n == 0);
    int64_t bad = ctx->be->index_check(idx, n, limit);
    if (bad >= 0) {
        NN_FAIL(ctx, CR_ERR_RANGE, "%s: %s %d at position %lld is out of range [0,%lld)", op, what,
                idx[bad], (long long)bad, (long long)limit);
        return NULL;
    }
    return cr_nn_index_copy(ctx, op, idx, n);
}

/* Positions grouped by target: off (nb+1), perm (n), from the arena. */
static int group_by(cr_nn_ctx *ctx, const char *op, const int32_t *idx, int64_t n, int64_t nb,
                    int64_t **off, int32_t **perm) {
    *off = cr_nn_alloc(ctx, op, (size_t)(nb + 1) * sizeof(int64_t));
    *perm = cr_nn_alloc(ctx, op, (size_t)n * sizeof(int32_t));
    if (!*off || !*perm) return 0;
    ctx->be->csr_build(idx, n, nb, *off, *perm);
    return 1;
}

cr_tensor *cr_nn_gather_rows(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *index, int64_t n) {
    const char *name = "gather_rows";
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    int64_t rows, C;
    if (!rows_of(ctx, name, x, &rows, &C)) return NULL;
    if (n < 0) {
        NN_FAIL(ctx, CR_ERR_RANGE, "%s: negative count %lld", name, (long long)n);
        return NULL;
    }
    int32_t *idx = checked_index(ctx, name, "index", index, n, rows);
    if (!idx) return NULL;
    int64_t shape[CR_NN_MAX_DIMS];
    for (int d = 0; d < x->ndim; d++)
        shape[d] = x->shape[d];
    shape[0] = n;
    cr_tensor *y = cr_nn_tensor(ctx, name, x->ndim, shape);
    if (!y) return NULL;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node node = {.op = CR_OP_GATHER_ROWS,
                    .nsrc = 1,
                    .src = src,
                    .nout = 1,
                    .out = out,
                    .p.index = {.index = idx, .n = n, .rows = rows}};
    return cr_nn_run(ctx, &node);
}

void cr_nn_gather_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    int64_t C = n->p.index.rows > 0 ? x->numel / n->p.index.rows : 0;
    ctx->be->gather_rows(x->data, C, n->p.index.index, n->p.index.n, y->data, 0);
}

void cr_nn_gather_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    if (!gx) return;
    const nn_index_params *p = &n->p.index;
    int64_t C = p->rows > 0 ? x->numel / p->rows : 0;
    size_t mark = cr_arena_mark(&ctx->arena);
    int64_t *off;
    int32_t *perm;
    if (!group_by(ctx, "gather_rows", p->index, p->n, p->rows, &off, &perm)) return;
    ctx->be->segment_sum_rows(y->grad, C, off, perm, p->rows, gx, 1);
    cr_arena_rewind(&ctx->arena, mark);
}

cr_tensor *cr_nn_scatter_add_rows(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *index,
                                  int64_t rows) {
    const char *name = "scatter_add_rows";
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    int64_t E, C;
    if (!rows_of(ctx, name, x, &E, &C)) return NULL;
    if (rows < 0) {
        NN_FAIL(ctx, CR_ERR_RANGE, "%s: negative row count %lld", name, (long long)rows);
        return NULL;
    }
    int32_t *idx = checked_index(ctx, name, "index", index, E, rows);
    int64_t *off;
    int32_t *perm;
    if (!idx || !group_by(ctx, name, idx, E, rows, &off, &perm)) return NULL;
    int64_t shape[CR_NN_MAX_DIMS];
    for (int d = 0; d < x->ndim; d++)
        shape[d] = x->shape[d];
    shape[0] = rows;
    cr_tensor *y = cr_nn_tensor(ctx, name, x->ndim, shape);
    if (!y) return NULL;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node node = {.op = CR_OP_SCATTER_ADD_ROWS,
                    .nsrc = 1,
                    .src = src,
                    .nout = 1,
                    .out = out,
                    .p.index = {.index = idx, .n = E, .off = off, .perm = perm, .rows = rows}};
    return cr_nn_run(ctx, &node);
}

void cr_nn_scatter_add_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    const nn_index_params *p = &n->p.index;
    int64_t C = p->n > 0 ? x->numel / p->n : 0;
    if (p->n == 0) {
        ctx->be->fill(y->data, y->numel, 0.0f);
        return;
    }
    ctx->be->segment_sum_rows(x->data, C, p->off, p->perm, p->rows, y->data, 0);
}

void cr_nn_scatter_add_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    const nn_index_params *p = &n->p.index;
    if (!gx || p->n == 0) return;
    ctx->be->gather_rows(y->grad, x->numel / p->n, p->index, p->n, gx, 1);
}

cr_tensor *cr_nn_segment_softmax(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *segment,
                                 int64_t nseg) {
    const char *name = "segment_softmax";
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    int64_t E, H;
    if (!rows_of(ctx, name, x, &E, &H)) return NULL;
    if (nseg < 0) {
        NN_FAIL(ctx, CR_ERR_RANGE, "%s: negative segment count %lld", name, (long long)nseg);
        return NULL;
    }
    int32_t *seg = checked_index(ctx, name, "segment id", segment, E, nseg);
    int64_t *off;
    int32_t *perm;
    if (!seg || !group_by(ctx, name, seg, E, nseg, &off, &perm)) return NULL;
    cr_tensor *y = cr_nn_tensor(ctx, name, x->ndim, x->shape);
    if (!y) return NULL;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node node = {.op = CR_OP_SEGMENT_SOFTMAX,
                    .nsrc = 1,
                    .src = src,
                    .nout = 1,
                    .out = out,
                    .p.index = {.index = seg, .n = E, .off = off, .perm = perm, .rows = nseg}};
    return cr_nn_run(ctx, &node);
}

void cr_nn_segment_softmax_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    const nn_index_params *p = &n->p.index;
    if (p->n == 0) return;
    ctx->be->segment_softmax_forward(x->data, x->numel / p->n, p->off, p->perm, p->rows, y->data);
}

void cr_nn_segment_softmax_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    const nn_index_params *p = &n->p.index;
    if (!gx || p->n == 0) return;
    ctx->be->segment_softmax_backward(y->data, y->grad, x->numel / p->n, p->off, p->perm, p->rows,
                                      gx);
}
