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
 * Energies with per-item data (rest angles, three states for inertia, a
 * body per frame) have their own calls below. Design: docs/losses.md.
 * Implemented in src/methods/common/losses.c and losses_items.c.
 */
#ifndef CREASE_LOSSES_H
#define CREASE_LOSSES_H

#include "crease/nn.h"
#include "crease/phys_energies.h"
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

/* ------------------------------------------------ per-batch-item data --
 *
 * Energies whose element data change per batch item take that data as
 * tensors. Each returns the weighted energy per item (B) (x (V,3): (1)),
 * or NULL with the context error naming the loss. */

/* Discrete-shell bending (phys_energies.h) with rest angles rest (B,H) per
 * item, or (H) shared by all items, rad; NULL: b's own. Gradients flow to x
 * and, when rest requires grad, to the rest angles:
 * dE/dtheta_rest = -k_e (theta - theta_rest) (epnet's plastic rest bending). */
cr_tensor *cr_loss_bending(cr_nn_ctx *ctx, const cr_bending *b, double weight, cr_tensor *x,
                           cr_tensor *rest);

/* Hinge angle residuals, not an energy: weight wrap(theta_h(x) - rest_h) per
 * hinge of b, rad, wrapped into (-pi, pi] as the bending energy is.
 * x (B,V,3) gives (B,H), x (V,3) gives (H); rest (B,H) or (H), rad; NULL:
 * b's own. Gradients flow to x (weight d theta/dx) and, when rest
 * requires grad, to rest (-weight). For losses on the angles themselves,
 * built from the tape's ops (epnet's RB response). */
cr_tensor *cr_loss_hinge_residual(cr_nn_ctx *ctx, const cr_bending *b, double weight, cr_tensor *x,
                                  cr_tensor *rest);

/* Implicit Euler's inertia over three consecutive states, each (B,V,3):
 *     E = sum_i m_i / (2 h^2) |x_t - 2 x_{t-1} + x_{t-2}|^2,
 * cr_inertia's energy with x_pred = 2 x_{t-1} - x_{t-2}; gradients flow to
 * all three. masses (V) kg (e.g. cr_gravity_masses), copied; h > 0 s. */
cr_tensor *cr_loss_inertia(cr_nn_ctx *ctx, const double *masses, int32_t nv, double h,
                           double weight, cr_tensor *x_t, cr_tensor *x_prev, cr_tensor *x_prev2);

/* A collider with a fixed triangle list whose vertices move per batch item
 * (a body per frame): owns one BVH, refitted to each item's body positions
 * in forward (so one collider serves one op call at a time). */
typedef struct cr_loss_collider cr_loss_collider;
/* Triangles tri (F,3) over nv body vertices at positions pos (V_b,3), m. */
cr_status cr_loss_collider_create(const float *pos, int32_t nv, const int32_t *tri, int32_t nf,
                                  cr_loss_collider **out, cr_error *err);
void cr_loss_collider_destroy(cr_loss_collider *c); /* NULL is a no-op */
/* The garment's edges (E,2) over its cloth_nv vertices, copied: from then on
 * the penalty of cr_loss_collision starts at each vertex's threshold
 * eps + the largest chord sag of its edges over the body, as the simulator's
 * (cr_collision_update_margins, with the body's smooth normals at the
 * closest points), so that the thickness holds at the faces' centroids. A
 * garment of another vertex count is then refused. */
cr_status cr_loss_collider_set_edges(cr_loss_collider *c, const int32_t *edge, int32_t ne,
                                     int32_t cloth_nv, cr_error *err);

/* Collision penalty of each garment vertex against the body of its item:
 * E_i = k max(eps - d_i, 0)^3 (eps + sag_i with the collider's edges) with
 * k = mat->collision_stiffness and eps = mat->collision_thickness as the
 * simulator's (collision.c), d_i the signed distance to the body (negative
 * inside, bvh.h). body (B,V_b,3) or (V_b,3) for every item, m (wrap a host
 * array with cr_nn_wrap); NULL: the collider's current positions. Its data
 * is read in forward; no gradient flows to it. The gradient to x is
 * -3 k (eps - d)^2 grad d, with grad d the unit direction from the closest
 * point (the pseudo-normal where the vertex lies on the surface). */
cr_tensor *cr_loss_collision(cr_nn_ctx *ctx, cr_loss_collider *c, const cr_material *mat,
                             double weight, cr_tensor *x, cr_tensor *body);

#ifdef __cplusplus
}
#endif
#endif
