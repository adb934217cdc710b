/* layer_jacobian.c: the input Jacobian of a cr_mlp as an ordinary tape
 * tensor, by forward-mode propagation through the layers:
 *
 *   J_0 = I,   J_{l+1} = diag(act'(z_l)) N_l W_l J_l  (+ J_l on residual layers)
 *
 * with N_l the layer norm's Jacobian when the MLP has one. Every factor is
 * made by differentiable ops (linear, mul, the activation-derivative ops), so
 * a loss on J backpropagates through the tape to the weights and to x (the
 * "double backward" that eikonal and metric losses need, without the engine
 * having to differentiate its own backward).
 *
 * Layout: the tangents are carried transposed, T_l = J_l^T of shape
 * (N,IN,C): one row per input axis. Then W_l J_l is a linear op on the rows
 * of T_l (y = T W^T), and diag(act') a broadcast multiply by (N,1,C). The
 * first layer's W_0^T comes from linear(I, W_0) so that it stays on the tape.
 * The cost is IN times a forward pass (IN = 2 for UV maps).
 *
 * Leaves out: Jacobians with respect to anything but the MLP's own input
 * (chaining through an encoding is the caller's multiply), second
 * derivatives (Hessians).
 * Reference: forward-mode AD as in Griewank & Walther, Evaluating
 * Derivatives, 2008, ch. 3; layer-norm derivative from Ba et al. 2016.
 */
#include "crease/nn_layers.h"

/* Layer norm on z (N,C) with its tangents tz (B,IN,C), B = N or 1, built
 * from ops so the Jacobian stays differentiable:
 *   xhat = (z - mean) rstd,  rstd = (var + eps)^(-1/2),
 *   d xhat = rstd (t - mean(t) - xhat mean(xhat t))   (means over C),
 *   y = xhat w + b,  d y = w d xhat. */
static void layer_norm_jvp(cr_nn_ctx *ctx, cr_tensor *z, cr_tensor *tz, cr_tensor *w, cr_tensor *b,
                           float eps, cr_tensor **y, cr_tensor **ty) {
    *y = *ty = NULL;
    if (!z) return;
    int64_t n = z->shape[0], c = z->shape[1];
    cr_tensor *mean = cr_nn_mean_axis(ctx, z, -1, 1);                         /* (N,1) */
    cr_tensor *d = cr_nn_sub(ctx, z, mean);                                   /* (N,C) */
    cr_tensor *var = cr_nn_mean_axis(ctx, cr_nn_square(ctx, d), -1, 1);       /* (N,1) */
    cr_tensor *rstd = cr_nn_pow(ctx, cr_nn_add_scalar(ctx, var, eps), -0.5f); /* (N,1) */
    cr_tensor *xhat = cr_nn_mul(ctx, d, rstd);                                /* (N,C) */
    *y = cr_nn_add(ctx, cr_nn_mul(ctx, xhat, w), b);
    cr_tensor *x3 = cr_nn_reshape(ctx, xhat, 3, (int64_t[]){n, 1, c});
    cr_tensor *r3 = cr_nn_reshape(ctx, rstd, 3, (int64_t[]){n, 1, 1});
    cr_tensor *tc = cr_nn_sub(ctx, tz, cr_nn_mean_axis(ctx, tz, -1, 1));   /* (B,IN,C) */
    cr_tensor *proj = cr_nn_mean_axis(ctx, cr_nn_mul(ctx, x3, tz), -1, 1); /* (N,IN,1) */
    cr_tensor *tx = cr_nn_mul(ctx, cr_nn_sub(ctx, tc, cr_nn_mul(ctx, x3, proj)), r3);
    *ty = cr_nn_mul(ctx, tx, w);
}

cr_tensor *cr_mlp_input_jacobian(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *x,
                                 cr_tensor **y_out) {
    const cr_mlp_def *def = &mlp->def;
    if (y_out) *y_out = NULL;
    /* The first linear checks x's last axis against the layer and reports a
     * mismatch on the context like any op. */
    cr_tensor *z0 = cr_linear_forward(ctx, &mlp->layer[0], x);
    if (!z0) return NULL;
    int64_t in = def->widths[0], n = x->numel / in;
    cr_tensor *h = cr_nn_reshape(ctx, x, 2, (int64_t[]){n, in});
    z0 = cr_nn_reshape(ctx, z0, 2, (int64_t[]){n, def->widths[1]});
    cr_tensor *eye = cr_nn_zeros(ctx, 2, (int64_t[]){in, in});
    if (!eye) return NULL;
    for (int64_t i = 0; i < in; i++)
        eye->data[i * in + i] = 1.0f;
    /* T_0 W_0^T = W_0^T, broadcast over the points: (1,IN,C1). */
    cr_tensor *t = cr_nn_reshape(ctx, cr_nn_linear(ctx, eye, mlp->layer[0].weight, NULL), 3,
                                 (int64_t[]){1, in, def->widths[1]});
    for (int i = 0; i < def->nlayers; i++) {
        int64_t c = def->widths[i + 1];
        cr_tensor *z = z0, *tz = t;
        if (i > 0) {
            z = cr_linear_forward(ctx, &mlp->layer[i], h);
            tz = cr_nn_linear(ctx, t, mlp->layer[i].weight, NULL);
        }
        if (mlp->ln_weight[i])
            layer_norm_jvp(ctx, z, tz, mlp->ln_weight[i], mlp->ln_bias[i], def->ln_eps, &z, &tz);
        float param;
        cr_act act = cr_mlp_layer_act(def, i, &param);
        if (act != CR_ACT_NONE) {
            cr_tensor *d = cr_act_deriv(ctx, act, param, z);
            tz = cr_nn_mul(ctx, tz, cr_nn_reshape(ctx, d, 3, (int64_t[]){n, 1, c}));
        }
        cr_tensor *a = cr_act_forward(ctx, act, param, z);
        if (cr_mlp_layer_residual(def, i)) {
            a = cr_nn_add(ctx, h, a);
            tz = cr_nn_add(ctx, t, tz);
        }
        h = a;
        t = tz;
    }
    if (!t || !h) return NULL;
    /* A network that is affine all the way (no activation anywhere) leaves
     * one shared Jacobian; give every point its copy. */
    if (t->shape[0] != n) t = cr_nn_add(ctx, t, cr_nn_zeros(ctx, 3, (int64_t[]){n, 1, 1}));
    if (y_out) *y_out = h;
    return t;
}
