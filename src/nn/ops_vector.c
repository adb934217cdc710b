/* ops_vector.c: row-wise ops over the last axis: layer norm, cross product,
 * dot product, Euclidean norm and normalisation.
 *
 * Layer norm (Ba, Kiros, Hinton, "Layer Normalization", 2016, eq. 4) uses the
 * biased variance and keeps mean and 1/sqrt(var + eps) per row for the
 * backward:
 *   dx = rstd (g - mean(g) - xhat mean(g xhat)),  g = dy w.
 * norm returns |x| exactly; only its gradient x / max(|x|, eps) is guarded,
 * so a zero row gets a zero gradient instead of NaN. normalize divides by
 * max(|x|, eps), whose backward is (dy - y (y.dy)) / |x| above eps and
 * dy / eps below.
 * Leaves out: RMS norm, norms over other axes (move the axis last first).
 */
#include "nn/tape.h"

/* ---------------------------------------------------------- layer norm -- */

cr_tensor *cr_nn_layer_norm(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b, float eps) {
    const char *name = "layer_norm";
    cr_tensor *src[3] = {x, w, b};
    if (!cr_nn_begin(ctx, name, 1, src)) return NULL;
    char sx[64], sp[64];
    if (x->ndim < 1 || x->shape[x->ndim - 1] < 1) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: expects (...,C) with C >= 1, got %s", name,
                cr_nn_shape_str(x, sx, sizeof sx));
        return NULL;
    }
    int64_t R, C;
    cr_nn_rows_cols(x, &R, &C);
    for (int i = 1; i < 3; i++) {
        if (src[i] && (src[i]->ndim != 1 || src[i]->shape[0] != C)) {
            NN_FAIL(ctx, CR_ERR_SHAPE, "%s: %s %s does not match x %s: expected (%lld)", name,
                    i == 1 ? "weight" : "bias", cr_nn_shape_str(src[i], sp, sizeof sp),
                    cr_nn_shape_str(x, sx, sizeof sx), (long long)C);
            return NULL;
        }
    }
    if (!(eps > 0.0f)) {
        NN_FAIL(ctx, CR_ERR_INVALID, "%s: eps must be positive, got %g", name, eps);
        return NULL;
    }
    float *mean = cr_nn_alloc(ctx, name, (size_t)R * sizeof(float));
    float *rstd = cr_nn_alloc(ctx, name, (size_t)R * sizeof(float));
    cr_tensor *y = cr_nn_tensor(ctx, name, x->ndim, x->shape);
    if (!mean || !rstd || !y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node n = {.op = CR_OP_LAYER_NORM,
                 .nsrc = 3,
                 .src = src,
                 .nout = 1,
                 .out = out,
                 .p.layer_norm = {.eps = eps, .mean = mean, .rstd = rstd}};
    return cr_nn_run(ctx, &n);
}

void cr_nn_layer_norm_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1], *b = n->src[2];
    cr_tensor *y = n->out[0];
    const nn_layer_norm_params *p = &n->p.layer_norm;
    int64_t R, C;
    cr_nn_rows_cols(x, &R, &C);
    ctx->be->layer_norm_forward(x->data, R, C, w ? w->data : NULL, b ? b->data : NULL, p->eps,
                                y->data, p->mean, p->rstd);
}

void cr_nn_layer_norm_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *x = n->src[0], *w = n->src[1], *b = n->src[2], *y = n->out[0];
    const nn_layer_norm_params *p = &n->p.layer_norm;
    int64_t R, C;
    cr_nn_rows_cols(x, &R, &C);
    ctx->be->layer_norm_backward(x->data, y->grad, R, C, w ? w->data : NULL, p->mean, p->rstd,
                                 nn_gout(x), nn_gout(w), nn_gout(b));
}

/* ----------------------------------------------- cross, dot, norm, ... -- */

static cr_tensor *rowwise(cr_nn_ctx *ctx, cr_op op, cr_tensor *a, cr_tensor *b, float eps) {
    const char *name = cr_op_name(op);
    int nsrc = b ? 2 : 1;
    cr_tensor *src[2] = {a, b};
    if (!cr_nn_begin(ctx, name, nsrc, src)) return NULL;
    char sa[64], sb[64];
    if (a->ndim < 1) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: expects (...,C), got a scalar", name);
        return NULL;
    }
    if (b && !cr_nn_same_shape(a, b)) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: shapes differ: %s and %s", name,
                cr_nn_shape_str(a, sa, sizeof sa), cr_nn_shape_str(b, sb, sizeof sb));
        return NULL;
    }
    if (op == CR_OP_CROSS && a->shape[a->ndim - 1] != 3) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "cross: expects (...,3), got %s",
                cr_nn_shape_str(a, sa, sizeof sa));
        return NULL;
    }
    if ((op == CR_OP_NORM || op == CR_OP_NORMALIZE) && !(eps > 0.0f)) {
        NN_FAIL(ctx, CR_ERR_INVALID, "%s: eps must be positive, got %g", name, eps);
        return NULL;
    }
    int64_t shape[CR_NN_MAX_DIMS];
    for (int d = 0; d < a->ndim; d++)
        shape[d] = a->shape[d];
    if (op == CR_OP_DOT || op == CR_OP_NORM) shape[a->ndim - 1] = 1;
    cr_tensor *y = cr_nn_tensor(ctx, name, a->ndim, shape);
    if (!y) return NULL;
    cr_tensor *out[1] = {y};
    nn_node n = {.op = op, .nsrc = nsrc, .src = src, .nout = 1, .out = out, .p.eps = {eps}};
    return cr_nn_run(ctx, &n);
}

void cr_nn_rowwise_forward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *a = n->src[0], *b = n->nsrc > 1 ? n->src[1] : NULL;
    cr_tensor *y = n->out[0];
    int64_t R, C;
    cr_nn_rows_cols(a, &R, &C);
    const cr_nn_backend *be = ctx->be;
    switch (n->op) {
    case CR_OP_CROSS:
        be->cross_forward(a->data, b->data, R, y->data);
        break;
    case CR_OP_DOT:
        be->dot_forward(a->data, b->data, R, C, y->data);
        break;
    case CR_OP_NORM:
        be->norm_forward(a->data, R, C, y->data);
        break;
    case CR_OP_NORMALIZE:
        be->normalize_forward(a->data, R, C, n->p.eps.eps, y->data);
        break;
    default:
        NN_FAIL(ctx, CR_ERR_UNSUPPORTED, "rowwise forward: op %s is not row-wise",
                cr_op_name(n->op));
    }
}

void cr_nn_rowwise_backward(cr_nn_ctx *ctx, nn_node *n) {
    const cr_tensor *a = n->src[0], *b = n->nsrc > 1 ? n->src[1] : NULL, *y = n->out[0];
    float *ga = nn_gout(a), *gb = nn_gout(b);
    int64_t R, C;
    cr_nn_rows_cols(a, &R, &C);
    const cr_nn_backend *be = ctx->be;
    float eps = n->p.eps.eps;
    switch (n->op) {
    case CR_OP_CROSS:
        be->cross_backward(a->data, b->data, y->grad, R, ga, gb);
        break;
    case CR_OP_DOT:
        be->dot_backward(a->data, b->data, y->grad, R, C, ga, gb);
        break;
    case CR_OP_NORM:
        if (ga) be->norm_backward(a->data, y->data, y->grad, R, C, eps, ga);
        break;
    case CR_OP_NORMALIZE:
        if (ga) be->normalize_backward(a->data, y->data, y->grad, R, C, eps, ga);
        break;
    default:
        NN_FAIL(ctx, CR_ERR_UNSUPPORTED, "rowwise backward: op %s is not row-wise",
                cr_op_name(n->op));
    }
}

cr_tensor *cr_nn_cross(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    if (ctx->err.status == CR_OK && !b) {
        NN_FAIL(ctx, CR_ERR_INVALID, "cross: input 1 is NULL");
        return NULL;
    }
    return rowwise(ctx, CR_OP_CROSS, a, b, 0.0f);
}

cr_tensor *cr_nn_dot(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    if (ctx->err.status == CR_OK && !b) {
        NN_FAIL(ctx, CR_ERR_INVALID, "dot: input 1 is NULL");
        return NULL;
    }
    return rowwise(ctx, CR_OP_DOT, a, b, 0.0f);
}

cr_tensor *cr_nn_norm(cr_nn_ctx *ctx, cr_tensor *x, float eps) {
    return rowwise(ctx, CR_OP_NORM, x, NULL, eps);
}

cr_tensor *cr_nn_normalize(cr_nn_ctx *ctx, cr_tensor *x, float eps) {
    return rowwise(ctx, CR_OP_NORMALIZE, x, NULL, eps);
}
