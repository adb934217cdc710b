/* losses_items.c: the losses whose element data change per batch item, on
 * the generic op of losses.c: bending with rest angles per item (and their
 * gradient), hinge angle residuals, inertia over three consecutive states,
 * and collision against a body given per frame.
 *
 * B batch items, V garment vertices, H hinges, V_b body vertices, F_b body
 * triangles. The math is phys/'s: cr_bending_kernel_rest (bending.c),
 * inertia.c's energy with x_pred = 2 x_{t-1} - x_{t-2}, cr_collision_penalty
 * (collision.c) at distances from cr_bvh_signed_distance_batch.
 * Left out: friction (it needs the contact state of the previous step),
 * gradients into the body.
 */
#include "methods/common/losses_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "crease/bvh.h"

/* ------------------------------------------------------------ bending -- */

static double bending_rest_kernel(const loss_spec *s, int64_t b, int32_t e, const double *xe,
                                  double aux, double *g, double *g_aux) {
    (void)b;
    return cr_bending_kernel_rest(s->data, e, aux, xe, g, NULL, g_aux);
}

cr_tensor *cr_loss_bending(cr_nn_ctx *ctx, const cr_bending *b, double weight, cr_tensor *x,
                           cr_tensor *rest) {
    if (!ctx || !b || !x) return NULL;
    if (!rest) {
        cr_energy_term t;
        cr_bending_term(b, &t);
        t.weight = weight;
        return cr_loss_energy(ctx, &t, x);
    }
    loss_spec *s = cr_loss_spec_new(ctx);
    if (!s) return NULL;
    s->term = "bending";
    s->nelem = cr_bending_count(b);
    s->nvert = 4;
    s->elem = cr_bending_hinges(b);
    s->has_aux = 1;
    s->weight = weight;
    s->kernel = bending_rest_kernel;
    s->data = b;
    cr_tensor *in[2] = {x, rest};
    return cr_loss_spec_run(ctx, s, in);
}

static double residual_kernel(const loss_spec *s, int64_t b, int32_t e, const double *xe,
                              double aux, double *g, double *g_aux) {
    (void)b;
    if (g_aux) *g_aux = -1.0; /* the wrap is locally the identity */
    return cr_bending_residual(s->data, e, aux, xe, g);
}

cr_tensor *cr_loss_hinge_residual(cr_nn_ctx *ctx, const cr_bending *b, double weight, cr_tensor *x,
                                  cr_tensor *rest) {
    if (!ctx || !b || !x) return NULL;
    if (!rest) { /* b's own rest angles, read only */
        const int32_t H = cr_bending_count(b);
        const double *r = cr_bending_rest_angles((cr_bending *)b);
        if (!(rest = cr_nn_new(ctx, 1, (int64_t[]){H}))) return NULL;
        for (int32_t h = 0; h < H; h++)
            rest->data[h] = (float)r[h];
    }
    loss_spec *s = cr_loss_spec_new(ctx);
    if (!s) return NULL;
    s->term = "hinge residual";
    s->nelem = cr_bending_count(b);
    s->nvert = 4;
    s->elem = cr_bending_hinges(b);
    s->has_aux = 1;
    s->per_element = 1;
    s->weight = weight;
    s->kernel = residual_kernel;
    s->data = b;
    cr_tensor *in[2] = {x, rest};
    return cr_loss_spec_run(ctx, s, in);
}

/* ------------------------------------------------------------ inertia -- */

typedef struct inertia3 {
    double *mass; /* (V) kg, a copy */
    int32_t nv;
    double h;      /* s */
    double inv_h2; /* 1/s^2 */
} inertia3;

/* Slots (x_t[i], x_{t-1}[i], x_{t-2}[i]) = (i, V + i, 2V + i). */
static double inertia3_kernel(const loss_spec *s, int64_t b, int32_t e, const double *xe,
                              double aux, double *g, double *g_aux) {
    (void)b, (void)aux, (void)g_aux;
    const inertia3 *in = s->data;
    const double k = in->mass[e] * in->inv_h2;
    double r[3];
    for (int c = 0; c < 3; c++) {
        const double xpred = 2.0 * xe[3 + c] - xe[6 + c];
        r[c] = xe[c] - xpred;
    }
    if (g)
        for (int c = 0; c < 3; c++)
            g[c] = k * r[c], g[3 + c] = -2.0 * k * r[c], g[6 + c] = k * r[c];
    return 0.5 * k * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
}

static cr_status inertia3_prepare(loss_spec *s, int64_t b, const float *x_b, cr_error *err) {
    (void)x_b;
    const inertia3 *in = s->data;
    if (b > 0) return CR_OK;
    if (in->nv != s->V)
        return CR_FAIL(err, CR_ERR_SHAPE, "loss_energy(inertia): %d masses, x has %lld vertices",
                       in->nv, (long long)s->V);
    if (!(in->h > 0.0) || !isfinite(in->h))
        return CR_FAIL(err, CR_ERR_INVALID, "loss_energy(inertia): step h = %g s must be > 0",
                       in->h);
    for (int32_t i = 0; i < in->nv; i++)
        if (!(in->mass[i] >= 0.0) || !isfinite(in->mass[i]))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "loss_energy(inertia): mass of vertex %d = %g must be >= 0", i,
                           in->mass[i]);
    return CR_OK;
}

cr_tensor *cr_loss_inertia(cr_nn_ctx *ctx, const double *masses, int32_t nv, double h,
                           double weight, cr_tensor *x_t, cr_tensor *x_prev, cr_tensor *x_prev2) {
    if (!ctx || !masses || !x_t || !x_prev || !x_prev2 || nv < 0) return NULL;
    loss_spec *s = cr_loss_spec_new(ctx);
    inertia3 *in = cr_nn_scratch(ctx, "loss_energy(inertia)", sizeof *in);
    int32_t *elem =
        cr_nn_scratch(ctx, "loss_energy(inertia)", sizeof(int32_t) * 3 * (size_t)nv + 1);
    double *m = cr_nn_scratch(ctx, "loss_energy(inertia)", sizeof(double) * (size_t)nv + 1);
    if (!s || !in || !elem || !m) return NULL;
    if (nv) memcpy(m, masses, sizeof(double) * (size_t)nv);
    for (int32_t i = 0; i < nv; i++)
        elem[3 * i] = i, elem[3 * i + 1] = nv + i, elem[3 * i + 2] = 2 * nv + i;
    *in = (inertia3){.mass = m, .nv = nv, .h = h, .inv_h2 = 1.0 / (h * h)};
    s->term = "inertia";
    s->nelem = nv;
    s->nvert = 3;
    s->elem = elem;
    s->npos = 3;
    s->weight = weight;
    s->kernel = inertia3_kernel;
    s->prepare = inertia3_prepare;
    s->data = in;
    cr_tensor *inputs[3] = {x_t, x_prev, x_prev2};
    return cr_loss_spec_run(ctx, s, inputs);
}

/* ---------------------------------------------------------- collision -- */

struct cr_loss_collider {
    cr_bvh *bvh;
    int32_t nv, nf;
    /* With the cloth's edges: its chord sags, by the simulator's own code
     * (cr_collision_update_margins) with a thickness of 0, so that each
     * vertex's threshold is its sag alone. */
    cr_collision *cloth;
    int32_t cloth_nv;
};

cr_status cr_loss_collider_create(const float *pos, int32_t nv, const int32_t *tri, int32_t nf,
                                  cr_loss_collider **out, cr_error *err) {
    CR_ASSERT(pos && tri && out);
    *out = NULL;
    cr_loss_collider *c = cr_calloc(1, sizeof *c, err);
    if (!c) return err ? err->status : CR_ERR_MEMORY;
    c->nv = nv, c->nf = nf;
    const cr_status st = cr_bvh_build(pos, nv, tri, nf, &c->bvh, err);
    if (st != CR_OK) {
        free(c);
        return st;
    }
    *out = c;
    return CR_OK;
}

void cr_loss_collider_destroy(cr_loss_collider *c) {
    if (!c) return;
    cr_bvh_destroy(c->bvh);
    cr_collision_destroy(c->cloth);
    free(c);
}

cr_status cr_loss_collider_set_edges(cr_loss_collider *c, const int32_t *edge, int32_t ne,
                                     int32_t cloth_nv, cr_error *err) {
    CR_ASSERT(c && (edge || ne == 0) && cloth_nv >= 0);
    cr_material mat;
    CR_TRY(cr_material_preset("cotton", &mat, err));
    mat.collision_thickness = 0.0;
    cr_collision *cloth = NULL;
    CR_TRY(cr_collision_create(cloth_nv, &mat, &cloth, err));
    const cr_status st = cr_collision_set_edges(cloth, edge, ne, err);
    if (st != CR_OK) {
        cr_collision_destroy(cloth);
        return st;
    }
    cr_collision_destroy(c->cloth);
    c->cloth = cloth, c->cloth_nv = cloth_nv;
    return CR_OK;
}

typedef struct collision_data {
    cr_loss_collider *c;
    const cr_tensor *body; /* (B,V_b,3), (V_b,3) or NULL */
    double k, eps;         /* J/m^3, m */
    float *dist;           /* (V) scratch of one item's query, m */
    float *normal;         /* (V,3) */
    float *point;          /* (V,3) closest points, m */
    float *smooth;         /* (V,3) the body's smooth normals there (with the cloth's edges) */
    double *xd;            /* (V,3) the item's positions in double (with the cloth's edges) */
} collision_data;

/* Lengths below this (m) have no direction: the vertex is on the surface and
 * the pseudo-normal stands in for the distance gradient. */
#define ON_SURFACE_M 1e-9

static cr_status collision_prepare(loss_spec *s, int64_t b, const float *x_b, cr_error *err) {
    collision_data *d = (collision_data *)s->data;
    const cr_tensor *body = d->body;
    const int64_t V = s->V;
    if (b == 0) {
        if (!(d->k >= 0.0) || !isfinite(d->k) || !(d->eps >= 0.0) || !isfinite(d->eps))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "loss_energy(collision): stiffness %g J/m^3 and thickness %g m must "
                           "be finite and >= 0",
                           d->k, d->eps);
        if (body) {
            char a[64];
            const int ok = (body->ndim == 2 || body->ndim == 3) &&
                           body->shape[body->ndim - 1] == 3 &&
                           body->shape[body->ndim - 2] == d->c->nv &&
                           (body->ndim == 2 || body->shape[0] == s->item_count);
            if (!ok)
                return CR_FAIL(err, CR_ERR_SHAPE,
                               "loss_energy(collision): body must be (%lld,%d,3) or (%d,3), got %s",
                               (long long)s->item_count, d->c->nv, d->c->nv,
                               cr_nn_shape_str(body, a, sizeof a));
        }
    }
    if (body && (b == 0 || body->ndim == 3)) {
        const float *pb = body->data + (body->ndim == 3 ? 3 * (int64_t)d->c->nv * b : 0);
        cr_error e2;
        const cr_status st = cr_bvh_refit(d->c->bvh, pb, &e2);
        if (st != CR_OK)
            return CR_FAIL(err, st, "loss_energy(collision): body of item %lld: %s", (long long)b,
                           e2.msg);
    }
    for (int64_t i = 0; i < 3 * V; i++)
        if (!isfinite(x_b[i]))
            return CR_FAIL(err, CR_ERR_NAN,
                           "loss_energy(collision): vertex %lld of item %lld is not finite",
                           (long long)(i / 3), (long long)b);
    cr_collision *cloth = d->c->cloth;
    if (cloth && V != d->c->cloth_nv)
        return CR_FAIL(err, CR_ERR_SHAPE,
                       "loss_energy(collision): %lld garment vertices, the collider's edges are "
                       "over %d",
                       (long long)V, d->c->cloth_nv);
    cr_bvh_signed_distance_smooth_batch(d->c->bvh, x_b, V, INFINITY, d->dist, d->normal, d->point,
                                        cloth ? d->smooth : NULL);
    /* The cloth's thresholds (docs/physics.md, "Collision"): below, a
     * vertex's distance is taken as its chord sag nearer (its direction from
     * the true one's sign), so that the penalty starts at eps + sag. */
    if (cloth) {
        for (int64_t k = 0; k < 3 * V; k++)
            d->xd[k] = x_b[k];
        cr_collision_update(cloth, d->xd, d->dist, d->normal);
        cr_collision_update_margins(cloth, d->smooth, INFINITY);
    }
    float *item = s->item + 4 * V * b;
    for (int64_t i = 0; i < V; i++) {
        const double q[3] = {(double)x_b[3 * i] - d->point[3 * i],
                             (double)x_b[3 * i + 1] - d->point[3 * i + 1],
                             (double)x_b[3 * i + 2] - d->point[3 * i + 2]};
        const double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        const double sgn = d->dist[i] < 0.0f ? -1.0 : 1.0;
        const double sag = cloth ? cr_collision_margin(cloth, (int32_t)i) : 0.0;
        item[4 * i] = (float)(d->dist[i] - sag);
        for (int c = 0; c < 3; c++)
            item[4 * i + 1 + c] =
                len > ON_SURFACE_M ? (float)(sgn * q[c] / len) : d->normal[3 * i + c];
    }
    return CR_OK;
}

static double collision_kernel(const loss_spec *s, int64_t b, int32_t e, const double *xe,
                               double aux, double *g, double *g_aux) {
    (void)xe, (void)aux, (void)g_aux;
    const collision_data *d = s->data;
    const float *it = s->item + 4 * (s->V * b + e);
    const double n[3] = {it[1], it[2], it[3]};
    return cr_collision_penalty(d->k, d->eps, it[0], n, g, NULL);
}

cr_tensor *cr_loss_collision(cr_nn_ctx *ctx, cr_loss_collider *c, const cr_material *mat,
                             double weight, cr_tensor *x, cr_tensor *body) {
    if (!ctx || !c || !mat || !x) return NULL;
    const int shaped = (x->ndim == 2 || x->ndim == 3) && x->shape[x->ndim - 1] == 3;
    const int64_t V = shaped ? x->shape[x->ndim - 2] : 0, B = x->ndim == 3 ? x->shape[0] : 1;
    loss_spec *s = cr_loss_spec_new(ctx);
    collision_data *d = cr_nn_scratch(ctx, "loss_energy(collision)", sizeof *d);
    float *f = cr_nn_scratch(ctx, "loss_energy(collision)",
                             sizeof(float) * (size_t)(10 * V + 4 * V * B) + 1);
    double *xd = c->cloth ? cr_nn_scratch(ctx, "loss_energy(collision)",
                                          sizeof(double) * (size_t)(3 * V) + 1)
                          : NULL;
    if (!s || !d || !f || (c->cloth && !xd)) return NULL;
    *d = (collision_data){.c = c,
                          .body = body,
                          .k = mat->collision_stiffness,
                          .eps = mat->collision_thickness,
                          .dist = f,
                          .normal = f + V,
                          .point = f + 4 * V,
                          .smooth = f + 7 * V,
                          .xd = xd};
    s->term = "collision";
    s->nelem = (int32_t)V;
    s->nvert = 1;
    s->weight = weight;
    s->kernel = collision_kernel;
    s->prepare = collision_prepare;
    s->data = d;
    s->item = f + 10 * V;
    s->item_count = B;
    return cr_loss_spec_run(ctx, s, &x);
}
