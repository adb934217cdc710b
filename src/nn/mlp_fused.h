/* mlp_fused.h (private): a whole MLP as one op over blocks of rows
 * (mlp_fused.c), the path cr_mlp_forward takes where it can. */
#ifndef CREASE_NN_MLP_FUSED_H
#define CREASE_NN_MLP_FUSED_H

#include "crease/nn.h"
#include "crease/nn_layers.h"

/* Whether cr_mlp_forward takes the fused path where it can: off unless the
 * environment has CREASE_NN_MLP=fused (mlp_fused.c says why);
 * cr_nn_mlp_fused_set overrides it (returns the previous setting; tests and
 * benchmarks run both paths). */
int cr_nn_mlp_fused_enabled(void);
int cr_nn_mlp_fused_set(int on);

/* 1 when the context's backend runs the fused MLP (the CPU's). */
int cr_nn_mlp_fused_usable(const cr_nn_ctx *ctx);

/* y = layer nl-1(... layer 0(x)), layer l: act[l](x W[l]^T + b[l]) with the
 * activation's parameter p[l]; b[l] may be NULL. Every act[l] must be one the
 * fused linear takes (none, relu, leaky_relu with slope >= 0, tanh, sigmoid,
 * softplus with beta > 0). The same values as the layer-by-layer path; the
 * weights' gradients are summed in another order. */
cr_tensor *cr_nn_mlp_fused(cr_nn_ctx *ctx, cr_tensor *x, int nl, cr_tensor *const *w,
                           cr_tensor *const *b, const cr_op *act, const float *p);

#endif
