/* tape.c: the op name table, recording, the forward and backward dispatch
 * switches, cr_nn_backward, and the fused-op hook.
 *
 * The tape is a singly linked list of nodes in the step arena, newest first;
 * backward walks it from the newest node, which is a reverse topological
 * order because an op can only consume tensors that already exist. A node is
 * skipped when none of its outputs received a gradient.
 * Leaves out: double backward (backward records nothing), graph replay.
 * Reference: the tape design follows llm.c's paired forward/backward
 * functions and ggml's op enum + dispatch switch (see STYLE.md).
 */
#include "nn/tape.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *const op_names[CR_OP_COUNT] = {
    [CR_OP_NONE] = "leaf",
    [CR_OP_MATMUL] = "matmul",
    [CR_OP_MATMUL_BATCHED] = "matmul_batched",
    [CR_OP_MATMUL_GROUPED] = "matmul_grouped",
    [CR_OP_LINEAR] = "linear",
    [CR_OP_ADD] = "add",
    [CR_OP_SUB] = "sub",
    [CR_OP_MUL] = "mul",
    [CR_OP_DIV] = "div",
    [CR_OP_ADD_SCALAR] = "add_scalar",
    [CR_OP_MUL_SCALAR] = "mul_scalar",
    [CR_OP_POW] = "pow",
    [CR_OP_RELU] = "relu",
    [CR_OP_LEAKY_RELU] = "leaky_relu",
    [CR_OP_LEAKY_RELU_DERIV] = "leaky_relu_deriv",
    [CR_OP_TANH] = "tanh",
    [CR_OP_SIGMOID] = "sigmoid",
    [CR_OP_SOFTPLUS] = "softplus",
    [CR_OP_SIN] = "sin",
    [CR_OP_COS] = "cos",
    [CR_OP_EXP] = "exp",
    [CR_OP_LOG] = "log",
    [CR_OP_SQRT] = "sqrt",
    [CR_OP_ABS] = "abs",
    [CR_OP_SQUARE] = "square",
    [CR_OP_SUM] = "sum",
    [CR_OP_MEAN] = "mean",
    [CR_OP_SUM_AXIS] = "sum_axis",
    [CR_OP_MEAN_AXIS] = "mean_axis",
    [CR_OP_CONCAT] = "concat",
    [CR_OP_SLICE] = "slice",
    [CR_OP_GATHER_ROWS] = "gather_rows",
    [CR_OP_SCATTER_ADD_ROWS] = "scatter_add_rows",
    [CR_OP_SEGMENT_SOFTMAX] = "segment_softmax",
    [CR_OP_LAYER_NORM] = "layer_norm",
    [CR_OP_CROSS] = "cross",
    [CR_OP_DOT] = "dot",
    [CR_OP_NORM] = "norm",
    [CR_OP_NORMALIZE] = "normalize",
    [CR_OP_FUSED] = "fused",
};

const char *cr_op_name(cr_op op) {
    if ((unsigned)op >= (unsigned)CR_OP_COUNT || !op_names[op]) return "unknown op";
    return op_names[op];
}

/* The name to use in messages: a fused op goes by its own name. */
static const char *node_name(const nn_node *n) {
    return n->op == CR_OP_FUSED ? n->p.fused.def->name : cr_op_name(n->op);
}

static void forward(cr_nn_ctx *ctx, nn_node *n) {
    switch (n->op) {
    case CR_OP_MATMUL:
    case CR_OP_MATMUL_BATCHED:
        cr_nn_matmul_forward(ctx, n);
        break;
    case CR_OP_MATMUL_GROUPED:
        cr_nn_grouped_forward(ctx, n);
        break;
    case CR_OP_LINEAR:
        cr_nn_linear_forward(ctx, n);
        break;
    case CR_OP_ADD:
    case CR_OP_SUB:
    case CR_OP_MUL:
    case CR_OP_DIV:
        cr_nn_binary_forward(ctx, n);
        break;
    case CR_OP_ADD_SCALAR:
    case CR_OP_MUL_SCALAR:
    case CR_OP_POW:
    case CR_OP_RELU:
    case CR_OP_LEAKY_RELU:
    case CR_OP_LEAKY_RELU_DERIV:
    case CR_OP_TANH:
    case CR_OP_SIGMOID:
    case CR_OP_SOFTPLUS:
    case CR_OP_SIN:
    case CR_OP_COS:
    case CR_OP_EXP:
    case CR_OP_LOG:
    case CR_OP_SQRT:
    case CR_OP_ABS:
    case CR_OP_SQUARE:
        cr_nn_unary_forward(ctx, n);
        break;
    case CR_OP_SUM:
    case CR_OP_MEAN:
    case CR_OP_SUM_AXIS:
    case CR_OP_MEAN_AXIS:
        cr_nn_reduce_forward(ctx, n);
        break;
    case CR_OP_CONCAT:
        cr_nn_concat_forward(ctx, n);
        break;
    case CR_OP_SLICE:
        cr_nn_slice_forward(ctx, n);
        break;
    case CR_OP_GATHER_ROWS:
        cr_nn_gather_forward(ctx, n);
        break;
    case CR_OP_SCATTER_ADD_ROWS:
        cr_nn_scatter_add_forward(ctx, n);
        break;
    case CR_OP_SEGMENT_SOFTMAX:
        cr_nn_segment_softmax_forward(ctx, n);
        break;
    case CR_OP_LAYER_NORM:
        cr_nn_layer_norm_forward(ctx, n);
        break;
    case CR_OP_CROSS:
    case CR_OP_DOT:
    case CR_OP_NORM:
    case CR_OP_NORMALIZE:
        cr_nn_rowwise_forward(ctx, n);
        break;
    case CR_OP_FUSED:
        cr_nn_fused_forward(ctx, n);
        break;
    default:
        NN_FAIL(ctx, CR_ERR_UNSUPPORTED, "forward: op %s (%d) has no forward", cr_op_name(n->op),
                (int)n->op);
    }
}

static void backward(cr_nn_ctx *ctx, nn_node *n) {
    switch (n->op) {
    case CR_OP_MATMUL:
    case CR_OP_MATMUL_BATCHED:
        cr_nn_matmul_backward(ctx, n);
        break;
    case CR_OP_MATMUL_GROUPED:
        cr_nn_grouped_backward(ctx, n);
        break;
    case CR_OP_LINEAR:
        cr_nn_linear_backward(ctx, n);
        break;
    case CR_OP_ADD:
    case CR_OP_SUB:
    case CR_OP_MUL:
    case CR_OP_DIV:
        cr_nn_binary_backward(ctx, n);
        break;
    case CR_OP_ADD_SCALAR:
    case CR_OP_MUL_SCALAR:
    case CR_OP_POW:
    case CR_OP_RELU:
    case CR_OP_LEAKY_RELU:
    case CR_OP_LEAKY_RELU_DERIV:
    case CR_OP_TANH:
    case CR_OP_SIGMOID:
    case CR_OP_SOFTPLUS:
    case CR_OP_SIN:
    case CR_OP_COS:
    case CR_OP_EXP:
    case CR_OP_LOG:
    case CR_OP_SQRT:
    case CR_OP_ABS:
    case CR_OP_SQUARE:
        cr_nn_unary_backward(ctx, n);
        break;
    case CR_OP_SUM:
    case CR_OP_MEAN:
    case CR_OP_SUM_AXIS:
    case CR_OP_MEAN_AXIS:
        cr_nn_reduce_backward(ctx, n);
        break;
    case CR_OP_CONCAT:
        cr_nn_concat_backward(ctx, n);
        break;
    case CR_OP_SLICE:
        cr_nn_slice_backward(ctx, n);
        break;
    case CR_OP_GATHER_ROWS:
        cr_nn_gather_backward(ctx, n);
        break;
    case CR_OP_SCATTER_ADD_ROWS:
        cr_nn_scatter_add_backward(ctx, n);
        break;
    case CR_OP_SEGMENT_SOFTMAX:
        cr_nn_segment_softmax_backward(ctx, n);
        break;
    case CR_OP_LAYER_NORM:
        cr_nn_layer_norm_backward(ctx, n);
        break;
    case CR_OP_CROSS:
    case CR_OP_DOT:
    case CR_OP_NORM:
    case CR_OP_NORMALIZE:
        cr_nn_rowwise_backward(ctx, n);
        break;
    case CR_OP_FUSED:
        cr_nn_fused_backward(ctx, n);
        break;
    default:
        NN_FAIL(ctx, CR_ERR_UNSUPPORTED, "backward: op %s (%d) has no backward", cr_op_name(n->op),
                (int)n->op);
    }
}

cr_tensor *cr_nn_run(cr_nn_ctx *ctx, nn_node *n) {
    forward(ctx, n);
    if (ctx->err.status != CR_OK) return NULL;
    int wants_grad = 0;
    if (ctx->grad_enabled)
        for (int i = 0; i < n->nsrc; i++)
            wants_grad |= n->src[i] && n->src[i]->requires_grad;
    for (int k = 0; k < n->nout; k++) {
        n->out[k]->requires_grad = (uint8_t)wants_grad;
        n->out[k]->op = n->op;
    }
    if (!wants_grad) return n->out[0];
    if (n->op == CR_OP_FUSED && !n->p.fused.def->backward) {
        NN_FAIL(ctx, CR_ERR_INVALID, "%s: an input requires grad but the fused op has no backward",
                node_name(n));
        return NULL;
    }
    /* The node and its two pointer arrays in one allocation. */
    size_t ptrs = (size_t)(n->nsrc + n->nout) * sizeof(cr_tensor *);
    nn_node *rec = cr_nn_alloc(ctx, node_name(n), sizeof(nn_node) + ptrs);
    if (!rec) return NULL;
    *rec = *n;
    rec->src = (cr_tensor **)(rec + 1);
    rec->out = rec->src + n->nsrc;
    if (n->nsrc > 0) memcpy(rec->src, n->src, (size_t)n->nsrc * sizeof(cr_tensor *));
    memcpy(rec->out, n->out, (size_t)n->nout * sizeof(cr_tensor *));
    rec->prev = ctx->tail;
    ctx->tail = rec;
    ctx->tape_len++;
    return n->out[0];
}

/* Make sure a node's buffers exist before its backward: inputs that require
 * grad get a (zeroed) grad; a fused op's outputs all get one. A linear's
 * input x that has no grad yet gets an uninitialised one that its backward
 * assigns with beta = 0 (x the weight or bias too would be added into, so
 * that case is zeroed as usual). */
static void prepare_grads(cr_nn_ctx *ctx, nn_node *n) {
    const char *who = node_name(n);
    ctx->fresh_grad = NULL;
    cr_tensor *x = n->nsrc > 0 ? n->src[0] : NULL;
    if (n->op == CR_OP_LINEAR && x && x->requires_grad && !x->grad && x != n->src[1] &&
        x != n->src[2] && cr_nn_grad_uninit(ctx, x, who))
        ctx->fresh_grad = x;
    for (int i = 0; i < n->nsrc; i++)
        if (n->src[i] && n->src[i]->requires_grad) cr_nn_grad(ctx, n->src[i], who);
    if (n->op == CR_OP_FUSED)
        for (int k = 0; k < n->nout; k++)
            cr_nn_grad(ctx, n->out[k], who);
}

cr_status cr_nn_backward(cr_nn_ctx *ctx, cr_tensor *loss, cr_error *err) {
    if (ctx->err.status != CR_OK) return cr_nn_ctx_error(ctx, err);
    if (!loss) return CR_FAIL(err, CR_ERR_INVALID, "backward: loss is NULL");
    if (loss->numel != 1) {
        char s[64];
        return CR_FAIL(err, CR_ERR_SHAPE, "backward: loss must be a scalar, got shape %s",
                       cr_nn_shape_str(loss, s, sizeof s));
    }
    float value = loss->data[0];
    if (isnan(value)) return CR_FAIL(err, CR_ERR_NAN, "backward: loss is NaN");
    if (isinf(value)) return CR_FAIL(err, CR_ERR_NAN, "backward: loss is infinite (%g)", value);
    if (!loss->requires_grad)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "backward: the loss depends on no tensor that requires grad");
    if (ctx->backward_done)
        return CR_FAIL(err, CR_ERR_INVALID, "backward: already ran since the last reset");
    ctx->backward_done = 1;
    float *seed = cr_nn_grad(ctx, loss, "backward");
    if (!seed) return cr_nn_ctx_error(ctx, err);
    seed[0] += 1.0f;
    for (nn_node *n = ctx->tail; n; n = n->prev) {
        int reached = 0;
        for (int k = 0; k < n->nout; k++)
            reached |= n->out[k]->grad != NULL;
        if (!reached) continue;
        prepare_grads(ctx, n);
        if (ctx->err.status == CR_OK) backward(ctx, n);
        ctx->fresh_grad = NULL;
        if (ctx->err.status != CR_OK) break;
    }
    return cr_nn_ctx_error(ctx, err);
}

/* ------------------------------------------------------------ fused ops -- */

/* Keep a callback's error (with its file and line) as the step's error. */
static void fail_from(cr_nn_ctx *ctx, const cr_error *e, const char *name) {
    if (ctx->err.status != CR_OK) return;
    if (e->status == CR_OK) {
        NN_FAIL(ctx, CR_ERR_INVALID, "%s: callback failed without a message", name);
        return;
    }
    ctx->err = *e;
}

void cr_nn_fused_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_fused_op *def = n->p.fused.def;
    cr_error e = {0};
    cr_status st = def->forward(def, ctx, n->src, n->nsrc, n->out, n->nout, &n->p.fused.stash, &e);
    if (st != CR_OK) fail_from(ctx, &e, def->name);
}

void cr_nn_fused_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_fused_op *def = n->p.fused.def;
    cr_error e = {0};
    cr_status st = def->backward(def, ctx, n->src, n->nsrc, n->out, n->nout, n->p.fused.stash, &e);
    if (st != CR_OK) fail_from(ctx, &e, def->name);
}

cr_tensor *cr_nn_fused(cr_nn_ctx *ctx, const cr_fused_op *def, int nin, cr_tensor *const *in,
                       int nout, const cr_nn_shape *out_shapes, cr_tensor **out) {
    CR_ASSERT(def && def->name && def->forward);
    CR_ASSERT(nin >= 0 && nout >= 1 && out_shapes && (out || nout == 1) && (in || nin == 0));
    for (int k = 0; out && k < nout; k++)
        out[k] = NULL;
    if (ctx->err.status != CR_OK) return NULL;
    cr_tensor **outs = cr_nn_alloc(ctx, def->name, (size_t)nout * sizeof(cr_tensor *));
    if (!outs) return NULL;
    for (int k = 0; k < nout; k++) {
        outs[k] = cr_nn_tensor(ctx, def->name, out_shapes[k].ndim, out_shapes[k].d);
        if (!outs[k]) return NULL;
    }
    /* The node only reads its input array; cr_nn_run copies it when recording. */
    nn_node n = {.op = CR_OP_FUSED,
                 .nsrc = nin,
                 .src = (cr_tensor **)in,
                 .nout = nout,
                 .out = outs,
                 .p.fused = {.def = def, .stash = NULL}};
    cr_tensor *first = cr_nn_run(ctx, &n);
    if (first && out)
        for (int k = 0; k < nout; k++)
            out[k] = outs[k];
    return first;
}
