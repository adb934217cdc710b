/* ops_elementwise.c: unary ops (activations, scalar arithmetic, powers) and
 * binary ops with numpy broadcasting, forward and backward.
 *
 * Broadcasting aligns shapes at the right; each axis must be equal or 1 in
 * one of them. The backward of a broadcast input sums the output-shaped
 * contribution over the axes it was repeated along (reduce_to_shape_acc).
 * Activation derivatives for input Jacobians are compositions of these ops
 * (tanh' = 1 - tanh^2, ...), so they are differentiable like any other.
 * Leaves out: in-place variants, integer powers by repeated multiplication.
 */
#include "nn/tape.h"

#include <string.h>

/* ------------------------------------------------------------- unary -- */

static cr_tensor *unary(cr_nn_ctx *ctx, cr_op op, cr_tensor *x, float p) {
    const char *name = cr_op_name(op);
    if (!cr_nn_begin(ctx, name, 1, &x)) return NULL;
    cr_tensor *y = cr_nn_tensor(ctx, name, x->ndim, x->shape);
    if (!y) return NULL;
    cr_tensor *src[1] = {x}, *out[1] = {y};
    nn_node n = {.op = op, .nsrc = 1, .src = src, .nout = 1, .out = out, .p.unary = {p}};
    return cr_nn_run(ctx, &n);
}

void cr_nn_unary_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    ctx->be->unary_forward(n->op, n->p.unary.p, x->data, y->data, y->numel);
}

void cr_nn_unary_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *x = n->src[0], *y = n->out[0];
    float *gx = nn_gout(x);
    if (gx) ctx->be->unary_backward(n->op, n->p.unary.p, x->data, y->data, y->grad, gx, y->numel);
}

cr_tensor *cr_nn_add_scalar(cr_nn_ctx *ctx, cr_tensor *x, float c) {
    return unary(ctx, CR_OP_ADD_SCALAR, x, c);
}

cr_tensor *cr_nn_mul_scalar(cr_nn_ctx *ctx, cr_tensor *x, float c) {
    return unary(ctx, CR_OP_MUL_SCALAR, x, c);
}

cr_tensor *cr_nn_pow(cr_nn_ctx *ctx, cr_tensor *x, float p) {
    return unary(ctx, CR_OP_POW, x, p);
}

cr_tensor *cr_nn_relu(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_RELU, x, 0.0f);
}

cr_tensor *cr_nn_leaky_relu(cr_nn_ctx *ctx, cr_tensor *x, float slope) {
    return unary(ctx, CR_OP_LEAKY_RELU, x, slope);
}

cr_tensor *cr_nn_leaky_relu_deriv(cr_nn_ctx *ctx, cr_tensor *x, float slope) {
    return unary(ctx, CR_OP_LEAKY_RELU_DERIV, x, slope);
}

cr_tensor *cr_nn_tanh(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_TANH, x, 0.0f);
}

cr_tensor *cr_nn_sigmoid(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_SIGMOID, x, 0.0f);
}

cr_tensor *cr_nn_softplus(cr_nn_ctx *ctx, cr_tensor *x, float beta) {
    if (ctx->err.status == CR_OK && !(beta > 0.0f)) {
        NN_FAIL(ctx, CR_ERR_INVALID, "softplus: beta must be positive, got %g", beta);
        return NULL;
    }
    return unary(ctx, CR_OP_SOFTPLUS, x, beta);
}

cr_tensor *cr_nn_sin(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_SIN, x, 0.0f);
}

cr_tensor *cr_nn_cos(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_COS, x, 0.0f);
}

cr_tensor *cr_nn_exp(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_EXP, x, 0.0f);
}

cr_tensor *cr_nn_log(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_LOG, x, 0.0f);
}

cr_tensor *cr_nn_sqrt(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_SQRT, x, 0.0f);
}

cr_tensor *cr_nn_abs(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_ABS, x, 0.0f);
}

cr_tensor *cr_nn_square(cr_nn_ctx *ctx, cr_tensor *x) {
    return unary(ctx, CR_OP_SQUARE, x, 0.0f);
}

/* 1 - tanh(x)^2 */
cr_tensor *cr_nn_tanh_deriv(cr_nn_ctx *ctx, cr_tensor *x) {
    cr_tensor *t2 = cr_nn_square(ctx, cr_nn_tanh(ctx, x));
    return cr_nn_add_scalar(ctx, cr_nn_mul_scalar(ctx, t2, -1.0f), 1.0f);
}

/* s (1 - s), s = sigmoid(x) */
cr_tensor *cr_nn_sigmoid_deriv(cr_nn_ctx *ctx, cr_tensor *x) {
    cr_tensor *s = cr_nn_sigmoid(ctx, x);
    return cr_nn_mul(ctx, s, cr_nn_add_scalar(ctx, cr_nn_mul_scalar(ctx, s, -1.0f), 1.0f));
}

/* d/dx log(1 + exp(beta x)) / beta = sigmoid(beta x) */
cr_tensor *cr_nn_softplus_deriv(cr_nn_ctx *ctx, cr_tensor *x, float beta) {
    return cr_nn_sigmoid(ctx, cr_nn_mul_scalar(ctx, x, beta));
}

/* ------------------------------------------------------------ binary -- */

static cr_tensor *binary(cr_nn_ctx *ctx, cr_op op, cr_tensor *a, cr_tensor *b) {
    const char *name = cr_op_name(op);
    cr_tensor *src[2] = {a, b};
    if (!cr_nn_begin(ctx, name, 2, src)) return NULL;
    int64_t as[4], bs[4], ys[4];
    cr_nn_pad_shape(a, as);
    cr_nn_pad_shape(b, bs);
    for (int i = 0; i < 4; i++) {
        if (as[i] != bs[i] && as[i] != 1 && bs[i] != 1) {
            char sa[64], sb[64];
            NN_FAIL(ctx, CR_ERR_SHAPE, "%s: shapes do not broadcast: %s and %s", name,
                    cr_nn_shape_str(a, sa, sizeof sa), cr_nn_shape_str(b, sb, sizeof sb));
            return NULL;
        }
        /* A 0-sized axis against 1 broadcasts to 0. */
        ys[i] = as[i] == 1 ? bs[i] : as[i];
    }
    int ndim = a->ndim > b->ndim ? a->ndim : b->ndim;
    cr_tensor *y = cr_nn_tensor(ctx, name, ndim, ys + (4 - ndim));
    if (!y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node n = {.op = op, .nsrc = 2, .src = src, .nout = 1, .out = out};
    return cr_nn_run(ctx, &n);
}

void cr_nn_binary_forward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *a = n->src[0], *b = n->src[1], *y = n->out[0];
    int64_t as[4], bs[4], ys[4];
    cr_nn_pad_shape(a, as);
    cr_nn_pad_shape(b, bs);
    cr_nn_pad_shape(y, ys);
    ctx->be->binary(n->op, NN_BINARY_VALUE, a->data, as, b->data, bs, NULL, ys, y->data, 0);
}

/* Add one operand's gradient: straight in when it has the output's shape,
 * else through an output-shaped temporary summed down to its shape. */
static void binary_grad(cr_nn_ctx *ctx, nn_node *n, nn_binary_mode mode, float *g,
                        const int64_t target[4]) {
    cr_tensor *a = n->src[0], *b = n->src[1], *y = n->out[0];
    int64_t as[4], bs[4], ys[4];
    cr_nn_pad_shape(a, as);
    cr_nn_pad_shape(b, bs);
    cr_nn_pad_shape(y, ys);
    if (memcmp(target, ys, sizeof ys) == 0) {
        ctx->be->binary(n->op, mode, a->data, as, b->data, bs, y->grad, ys, g, 1);
        return;
    }
    size_t mark = cr_arena_mark(&ctx->arena);
    float *tmp = cr_nn_alloc(ctx, cr_op_name(n->op), (size_t)y->numel * sizeof(float));
    if (!tmp) return;
    ctx->be->binary(n->op, mode, a->data, as, b->data, bs, y->grad, ys, tmp, 0);
    ctx->be->reduce_to_shape_acc(tmp, ys, g, target);
    cr_arena_rewind(&ctx->arena, mark);
}

void cr_nn_binary_backward(cr_nn_ctx *ctx, nn_node *n) {
    cr_tensor *a = n->src[0], *b = n->src[1];
    float *ga = nn_gout(a), *gb = nn_gout(b);
    int64_t s[4];
    if (ga) {
        cr_nn_pad_shape(a, s);
        binary_grad(ctx, n, NN_BINARY_GRAD_A, ga, s);
    }
    if (gb) {
        cr_nn_pad_shape(b, s);
        binary_grad(ctx, n, NN_BINARY_GRAD_B, gb, s);
    }
}

cr_tensor *cr_nn_add(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    return binary(ctx, CR_OP_ADD, a, b);
}

cr_tensor *cr_nn_sub(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    return binary(ctx, CR_OP_SUB, a, b);
}

cr_tensor *cr_nn_mul(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    return binary(ctx, CR_OP_MUL, a, b);
}

cr_tensor *cr_nn_div(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    return binary(ctx, CR_OP_DIV, a, b);
}
