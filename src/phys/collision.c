/* collision.c: penalty against a collider's signed distance.
 *
 * Per cloth vertex i, with the collider's signed distance d (negative inside)
 * and thickness eps,
 *     E_i = k max(eps - d_i(x), 0)^3
 * (the cubic penalty of Santesteban et al. 2022 (SNUG) and Grigorev et al.
 * 2023 (HOOD): C^2 at the contact threshold, so Newton sees no kink). The
 * signed distance is not differentiated through the BVH: per Newton iterate
 * the simulator queries d_i and the outward normal n_i at the current x_i, and
 * the kernel uses the linearised distance d_i(x) = d_i + n_i . (x - x_i), the
 * usual way a signed-distance penalty enters Newton (its Hessian omits the
 * collider's curvature, which keeps it PSD):
 *     grad = -3 k (eps - d)^2 n_i,   Hess = 6 k (eps - d) n_i n_i^T.
 * Left out: cloth self-collision, continuous collision detection.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_collision {
    int32_t nv;     /* V */
    double eps;     /* m */
    double k;       /* J/m^3 */
    double *x;      /* (V,3) linearisation points, m */
    double *dist;   /* (V) signed distance there, m */
    double *normal; /* (V,3) unit outward normals (zero when not reached) */
    double max_pen; /* m */
};

cr_status cr_collision_create(int32_t nv, const cr_material *mat, cr_collision **out,
                              cr_error *err) {
    CR_ASSERT(mat && out && nv >= 0);
    CR_ASSERT(mat->cookie == CR_MATERIAL_COOKIE);
    *out = NULL;
    cr_collision *c = cr_calloc(1, sizeof *c, err);
    if (!c) return err ? err->status : CR_ERR_MEMORY;
    const size_t n = (size_t)(nv > 0 ? nv : 1);
    c->nv = nv;
    c->eps = mat->collision_thickness;
    c->k = mat->collision_stiffness;
    c->x = cr_calloc(3 * n, sizeof(double), err);
    c->dist = cr_malloc(sizeof(double) * n, err);
    c->normal = cr_calloc(3 * n, sizeof(double), err);
    if (!c->x || !c->dist || !c->normal) {
        cr_collision_destroy(c);
        return err ? err->status : CR_ERR_MEMORY;
    }
    /* Until the first update every vertex is far away. */
    for (int32_t i = 0; i < nv; i++)
        c->dist[i] = INFINITY;
    *out = c;
    return CR_OK;
}

void cr_collision_destroy(cr_collision *c) {
    if (!c) return;
    free(c->x);
    free(c->dist);
    free(c->normal);
    free(c);
}

/* Vertex i's linearisation at x_i (a non-finite distance is a query that
 * reached nothing). */
static void update_vertex(cr_collision *c, int32_t i, const double *x, const float *dist,
                          const float *normal) {
    const int far = !isfinite(dist[i]);
    c->dist[i] = far ? INFINITY : (double)dist[i];
    for (int d = 0; d < 3; d++) {
        c->x[3 * (int64_t)i + d] = x[3 * (int64_t)i + d];
        c->normal[3 * (int64_t)i + d] = far ? 0.0 : (double)normal[3 * (int64_t)i + d];
    }
}

static void update_max_pen(cr_collision *c) {
    double min_d = INFINITY;
    for (int32_t i = 0; i < c->nv; i++)
        min_d = fmin(min_d, c->dist[i]);
    c->max_pen = min_d < 0.0 ? -min_d : 0.0;
}

void cr_collision_update(cr_collision *c, const double *x, const float *dist, const float *normal) {
    CR_ASSERT(c && x && dist && normal);
    for (int32_t i = 0; i < c->nv; i++)
        update_vertex(c, i, x, dist, normal);
    update_max_pen(c);
}

void cr_collision_update_vertices(cr_collision *c, const double *x, const float *dist,
                                  const float *normal, const int32_t *idx, int32_t n) {
    CR_ASSERT(c && x && dist && normal && (idx || n == 0));
    for (int32_t k = 0; k < n; k++)
        update_vertex(c, idx[k], x, dist, normal);
    update_max_pen(c);
}

void cr_collision_set_stiffness(cr_collision *c, double k) {
    CR_ASSERT(c && k > 0.0);
    c->k = k;
}

double cr_collision_max_penetration(const cr_collision *c) {
    return c->max_pen;
}

int cr_collision_contact(const cr_collision *c, int32_t i, double normal[3], double *force) {
    CR_ASSERT(c && i >= 0 && i < c->nv);
    const double s = c->eps - c->dist[i];
    if (!(s > 0.0)) return 0;
    if (normal) memcpy(normal, c->normal + 3 * (int64_t)i, 3 * sizeof(double));
    if (force) *force = 3.0 * c->k * s * s;
    return 1;
}

double cr_collision_penalty(double k, double eps, double d, const double n[3], double *g,
                            double *H) {
    const double s = eps - d;
    if (!(s > 0.0)) {
        if (g) memset(g, 0, 3 * sizeof(double));
        if (H) memset(H, 0, 9 * sizeof(double));
        return 0.0;
    }
    if (g)
        for (int i = 0; i < 3; i++)
            g[i] = -3.0 * k * s * s * n[i];
    if (H)
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++)
                H[3 * p + q] = 6.0 * k * s * n[p] * n[q];
    return k * s * s * s;
}

static double collision_kernel(const void *data, int32_t e, const double *xe, double *g,
                               double *H) {
    const cr_collision *c = data;
    const double *n = c->normal + 3 * (int64_t)e, *x0 = c->x + 3 * (int64_t)e;
    const double dist = c->dist[e];
    const double d = isfinite(dist) ? dist + n[0] * (xe[0] - x0[0]) + n[1] * (xe[1] - x0[1]) +
                                          n[2] * (xe[2] - x0[2])
                                    : INFINITY;
    return cr_collision_penalty(c->k, c->eps, d, n, g, H);
}

void cr_collision_term(const cr_collision *c, cr_energy_term *out) {
    CR_ASSERT(c && out);
    memset(out, 0, sizeof *out);
    out->name = "collision";
    out->nelem = c->nv;
    out->nvert = 1;
    out->kernel = collision_kernel;
    out->data = c;
    out->weight = 1.0;
}
