/* crease/losses.h: physics energies as losses on the neural engine's tape.
 *
 * Any cr_energy_term (phys_energy.h) becomes a differentiable loss through
 * one generic fused op: the input is a float32 tensor of positions, either
 * one state (V,3) or a batch of states (B,V,3); forward runs the term's
 * element kernel over every element of every batch item, backward scatters
 * the kernels' analytic gradients (no Hessian). Parallel over elements and
 * deterministic: the same bits whatever the thread count.
 *
 * The op borrows the term's element array and data: keep them alive until
 * the context is reset (after backward).
 *
 *   cr_energy_term t;
 *   cr_bending_term(bending, &t);
 *   cr_tensor *e = cr_loss_energy(ctx, &t, x);        // (B) energies, J
 *   cr_tensor *terms[2] = {e, cr_loss_energy(ctx, &g, x)};
 *   cr_tensor *loss = cr_loss_weighted_sum(ctx, terms, (float[]){1, 1}, 2, NULL);
 *
 * Implemented in src/methods/common/losses.c (work in progress: issue 14).
 */
#ifndef CREASE_LOSSES_H
#define CREASE_LOSSES_H

#include "crease/nn.h"
#include "crease/phys_energy.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Energy of `term` (times its weight) for each batch item: x (B,V,3) gives
 * (B); x (V,3) gives (1). NULL on error (the context records it). */
cr_tensor *cr_loss_energy(cr_nn_ctx *ctx, const cr_energy_term *term, cr_tensor *x);

/* The same, per element: x (B,V,3) gives (B, nelem); x (V,3) gives (nelem). */
cr_tensor *cr_loss_energy_per_element(cr_nn_ctx *ctx, const cr_energy_term *term, cr_tensor *x);

/* sum_k w[k] * sum(terms[k]) as a scalar. weighted (n, may be NULL) receives
 * each weighted scalar w[k] * sum(terms[k]) for reports. */
cr_tensor *cr_loss_weighted_sum(cr_nn_ctx *ctx, cr_tensor *const *terms, const float *w, int n,
                                cr_tensor **weighted);

#ifdef __cplusplus
}
#endif
#endif
