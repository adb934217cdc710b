/* loss.c: SwinGar's training losses (paper 002, eq. 11-14): vertex MSE,
 * edge and normal-Laplacian consistency, gravity and collision, on a window
 * of predicted frames. The edge and normal terms are built from engine ops
 * (their gradients are the ops' own); gravity and collision reuse the
 * energies of losses.h. */
#include "swingar_internal.h"

#include "crease/losses.h"
#include "crease/phys_energies.h"

#include <math.h>
#include <string.h>

cr_swingar_loss_def cr_swingar_loss_default_def(void) {
    cr_swingar_loss_def d;
    memset(&d, 0, sizeof d);
    d.k_v = 50.0f, d.k_e = 10.0f, d.k_b = 3.0f, d.k_g = 0.2f, d.k_c = 1.5f;
    d.collision_eps = 0.004f;
    return d;
}

static float item(const cr_tensor *t) {
    return t ? t->data[0] : 0.0f;
}

/* Laplacian of the face normals over faces sharing an edge (PBNS's bending
 * term, which eq. 12 cites): N_f - mean of the neighbours' normals. x (K,V,3). */
static cr_tensor *normal_laplacian(cr_nn_ctx *ctx, const cr_swingar_garment *g, cr_tensor *x) {
    const int64_t K = x->shape[0], V = x->shape[1], F = g->rest->nf, A = g->nadj;
    int32_t *c[3], *self, *other;
    float *inv = cr_nn_scratch(ctx, "swingar bend", sizeof(float) * (size_t)(K * F));
    for (int k = 0; k < 3; k++)
        c[k] = cr_nn_scratch(ctx, "swingar bend", sizeof(int32_t) * (size_t)(K * F));
    self = cr_nn_scratch(ctx, "swingar bend", sizeof(int32_t) * (size_t)(2 * K * A));
    other = cr_nn_scratch(ctx, "swingar bend", sizeof(int32_t) * (size_t)(2 * K * A));
    if (!inv || !c[0] || !c[1] || !c[2] || !self || !other) return NULL;
    for (int64_t k = 0; k < K; k++)
        for (int64_t f = 0; f < F; f++)
            for (int i = 0; i < 3; i++)
                c[i][k * F + f] = (int32_t)(k * V + g->rest->tri[3 * f + i]);
    memset(inv, 0, sizeof(float) * (size_t)(K * F));
    for (int64_t k = 0; k < K; k++)
        for (int64_t a = 0; a < A; a++) {
            int32_t f0 = (int32_t)(k * F + g->adj[2 * a]),
                    f1 = (int32_t)(k * F + g->adj[2 * a + 1]);
            self[2 * (k * A + a)] = f0, other[2 * (k * A + a)] = f1;
            self[2 * (k * A + a) + 1] = f1, other[2 * (k * A + a) + 1] = f0;
            inv[f0] += 1.0f, inv[f1] += 1.0f;
        }
    for (int64_t i = 0; i < K * F; i++)
        inv[i] = inv[i] > 0 ? 1.0f / inv[i] : 0.0f;
    cr_tensor *flat = cr_nn_reshape(ctx, x, 2, (int64_t[]){K * V, 3});
    cr_tensor *p0 = cr_nn_gather_rows(ctx, flat, c[0], K * F);
    cr_tensor *p1 = cr_nn_gather_rows(ctx, flat, c[1], K * F);
    cr_tensor *p2 = cr_nn_gather_rows(ctx, flat, c[2], K * F);
    cr_tensor *n = cr_nn_normalize(
        ctx, cr_nn_cross(ctx, cr_nn_sub(ctx, p1, p0), cr_nn_sub(ctx, p2, p0)), 1e-12f);
    cr_tensor *nsum =
        cr_nn_scatter_add_rows(ctx, cr_nn_gather_rows(ctx, n, other, 2 * K * A), self, K * F);
    cr_tensor *w = cr_nn_wrap(ctx, 2, (int64_t[]){K * F, 1}, inv);
    cr_tensor *lap = cr_nn_sub(ctx, n, cr_nn_mul(ctx, nsum, w));
    return cr_nn_mean(ctx, cr_nn_sum_axis(ctx, cr_nn_square(ctx, lap), -1, 0));
}

static cr_tensor *edge_term(cr_nn_ctx *ctx, const cr_swingar_garment *g, cr_tensor *x,
                            const float *gt) {
    const int64_t K = x->shape[0], V = x->shape[1], E = g->nedges;
    int32_t *a = cr_nn_scratch(ctx, "swingar edge", sizeof(int32_t) * (size_t)(K * E));
    int32_t *b = cr_nn_scratch(ctx, "swingar edge", sizeof(int32_t) * (size_t)(K * E));
    cr_tensor *len_gt = cr_nn_new(ctx, 2, (int64_t[]){K * E, 1});
    if (!a || !b || !len_gt) return NULL;
    for (int64_t k = 0; k < K; k++)
        for (int64_t e = 0; e < E; e++) {
            int32_t i = g->edges[2 * e], j = g->edges[2 * e + 1];
            a[k * E + e] = (int32_t)(k * V + i), b[k * E + e] = (int32_t)(k * V + j);
            const float *pi = gt + (size_t)(k * V + i) * 3, *pj = gt + (size_t)(k * V + j) * 3;
            float dx = pi[0] - pj[0], dy = pi[1] - pj[1], dz = pi[2] - pj[2];
            len_gt->data[k * E + e] = sqrtf(dx * dx + dy * dy + dz * dz);
        }
    cr_tensor *flat = cr_nn_reshape(ctx, x, 2, (int64_t[]){K * V, 3});
    cr_tensor *len = cr_nn_norm(ctx,
                                cr_nn_sub(ctx, cr_nn_gather_rows(ctx, flat, a, K * E),
                                          cr_nn_gather_rows(ctx, flat, b, K * E)),
                                1e-12f);
    return cr_nn_mean(ctx, cr_nn_square(ctx, cr_nn_sub(ctx, len, len_gt)));
}

cr_tensor *cr_swingar_loss(cr_nn_ctx *ctx, const cr_swingar_loss_def *def,
                           const cr_swingar_garment *g, cr_tensor *pred, const float *gt,
                           struct cr_loss_collider *collider, const float *body, int32_t body_nv,
                           cr_swingar_loss_terms *terms) {
    if (!pred || pred->ndim != 3 || pred->shape[2] != 3 || pred->shape[1] != g->rest->nv)
        return NULL;
    const int64_t K = pred->shape[0], V = pred->shape[1];
    cr_tensor *gtt = cr_nn_wrap(ctx, 3, (int64_t[]){K, V, 3}, (float *)gt);
    cr_tensor *sq = cr_nn_sum_axis(ctx, cr_nn_square(ctx, cr_nn_sub(ctx, pred, gtt)), -1, 0);
    cr_tensor *vert = cr_nn_mul_scalar(ctx, cr_nn_mean(ctx, sq), def->k_v);
    cr_tensor *t[5] = {vert, NULL, NULL, NULL, NULL};
    int n = 1;
    if (!def->supervised_only) {
        if (def->k_e > 0) t[n++] = cr_nn_mul_scalar(ctx, edge_term(ctx, g, pred, gt), def->k_e);
        if (def->k_b > 0 && g->nadj > 0)
            t[n++] = cr_nn_mul_scalar(ctx, normal_laplacian(ctx, g, pred), def->k_b);
        if (def->k_g > 0) {
            /* eq. 13, -k_g M X g, per frame: the gravity energy sum m_i g h_i
             * (phys_energies.h), averaged over the window */
            cr_energy_term gt_term;
            cr_gravity_term(g->gravity, &gt_term);
            t[n++] = cr_nn_mul_scalar(ctx, cr_nn_mean(ctx, cr_loss_energy(ctx, &gt_term, pred)),
                                      def->k_g);
        }
        if (def->k_c > 0 && collider && body) {
            /* eq. 14 through losses.h's collision penalty: per vertex
             * ((eps - d) / eps)^3 where d < eps, averaged over vertices and
             * frames (the simulator's cubic penalty in place of the square) */
            cr_material mat;
            memset(&mat, 0, sizeof mat);
            mat.collision_thickness = def->collision_eps;
            mat.collision_stiffness = 1.0 / pow(def->collision_eps, 3);
            cr_tensor *bt = cr_nn_wrap(ctx, 3, (int64_t[]){K, body_nv, 3}, (float *)body);
            t[n++] = cr_nn_mean(ctx, cr_loss_collision(ctx, collider, &mat,
                                                       (double)def->k_c / (double)V, pred, bt));
        }
    }
    cr_tensor *loss = t[0];
    for (int i = 1; i < n; i++)
        loss = cr_nn_add(ctx, loss, t[i]);
    if (terms) {
        memset(terms, 0, sizeof *terms);
        terms->vert = item(vert);
        int i = 1;
        if (!def->supervised_only) {
            if (def->k_e > 0) terms->edge = item(t[i++]);
            if (def->k_b > 0 && g->nadj > 0) terms->bend = item(t[i++]);
            if (def->k_g > 0) terms->gravity = item(t[i++]);
            if (def->k_c > 0 && collider && body) terms->collision = item(t[i++]);
        }
        double s = 0;
        if (sq)
            for (int64_t k = 0; k < K * V; k++)
                s += sqrt(sq->data[k]);
        terms->vert_err_m = (float)(s / (double)(K * V));
    }
    return loss;
}
