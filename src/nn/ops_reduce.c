/* ops_reduce.c: sum and mean over all elements or over one axis.
 *
 * Sums are accumulated in double in a fixed blocked order by the kernels, so
 * a loss does not change with the thread count. The backward spreads the
 * output gradient back over the reduced axis (times 1/len for a mean).
 * Leaves out: max/min reductions, reductions over several axes at once
 * (chain them or reshape first).
 */
#include "nn/tape.h"

static cr_tensor *reduce_all(cr_nn_ctx *ctx, cr_op op, cr_tensor *x) {
    const char *name = cr_op_name(op);
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    if (op == CR_OP_MEAN && x->numel == 0) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "mean: tensor is empty");
        return NULL;
    }
    cr_tensor *y = cr_nn_tensor(ctx, name, 0, NULL);
    if (!y) return NULL;
    float scale = op == CR_OP_MEAN ? 1.0f / (float)x->numel : 1.0f;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node n = {.op = op,
                 .nsrc = 1,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.reduce = {.axis = -1, .scale = scale}};
    return cr_nn_run(ctx, &n);
}

static cr_tensor *reduce_axis(cr_nn_ctx *ctx, cr_op op, cr_tensor *x, int axis, int keepdim) {
    const char *name = cr_op_name(op);
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    int a;
    if (!cr_nn_axis(ctx, name, x, axis, &a)) return NULL;
    if (op == CR_OP_MEAN_AXIS && x->shape[a] == 0) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "mean_axis: axis %d is empty", axis);
        return NULL;
    }
    int64_t shape[CR_NN_MAX_DIMS];
    int ndim = 0;
    for (int i = 0; i < x->ndim; i++) {
        if (i != a)
            shape[ndim++] = x->shape[i];
        else if (keepdim)
            shape[ndim++] = 1;
    }
    cr_tensor *y = cr_nn_tensor(ctx, name, ndim, shape);
    if (!y) return NULL;
    float scale = op == CR_OP_MEAN_AXIS ? 1.0f / (float)x->shape[a] : 1.0f;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node n = {.op = op,
                 .nsrc = 1,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.reduce = {.axis = a, .scale = scale}};
    return cr_nn_run(ctx, &n);
}

/* x viewed as (outer, len, inner) around the reduced axis (all: (1, n, 1)). */
static void reduce_view(const nn_node *n, int64_t *outer, int64_t *len, int64_t *inner) {
    const cr_tensor *x = n->src[0];
    if (n->p.reduce.axis < 0) {
        *outer = 1;
        *len = x->numel;
        *inner = 1;
    } else {
        cr_nn_split_axis(x, n->p.reduce.axis, outer, len, inner);
    }
}

void cr_nn_reduce_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    if (n->p.reduce.axis < 0) {
        float v = (float)(ctx->be->sum_all(x->data, x->numel) * n->p.reduce.scale);
        ctx->be->fill(y->data, 1, v);
        return;
    }
    int64_t outer, len, inner;
    reduce_view(n, &outer, &len, &inner);
    ctx->be->sum_axis(x->data, outer, len, inner, n->p.reduce.scale, y->data, 0);
}

void cr_nn_reduce_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    if (!gx) return;
    int64_t outer, len, inner;
    reduce_view(n, &outer, &len, &inner);
    ctx->be->expand_axis_acc(y->grad, outer, len, inner, n->p.reduce.scale, gx);
}

cr_tensor *cr_nn_sum(cr_nn_ctx *ctx, cr_tensor *x) {
    return reduce_all(ctx, CR_OP_SUM, x);
}

cr_tensor *cr_nn_mean(cr_nn_ctx *ctx, cr_tensor *x) {
    return reduce_all(ctx, CR_OP_MEAN, x);
}

cr_tensor *cr_nn_sum_axis(cr_nn_ctx *ctx, cr_tensor *x, int axis, int keepdim) {
    return reduce_axis(ctx, CR_OP_SUM_AXIS, x, axis, keepdim);
}

cr_tensor *cr_nn_mean_axis(cr_nn_ctx *ctx, cr_tensor *x, int axis, int keepdim) {
    return reduce_axis(ctx, CR_OP_MEAN_AXIS, x, axis, keepdim);
}
