/* drape_collision.c: the drape method's collision loss per point against a
 * static object.
 *
 *     E_i = min(s_i - eps, 0)^2
 * (Shu et al., ../shared/papers/000, eq. 26), s_i by mode:
 *   CR_DRAPE_COLLIDE_VERTEX  s = (x - v) . n_v, v the object vertex nearest
 *                            to x and n_v its angle-weighted normal (the
 *                            paper's form); v held fixed, so grad s = n_v;
 *   CR_DRAPE_COLLIDE_SDF     s the signed distance to the surface (BVH,
 *                            angle-weighted pseudo-normals): |x - p| times
 *                            its sign, p the closest point; grad s =
 *                            sign (x - p)/|x - p|, the pseudo-normal where x
 *                            lies on the surface.
 * Gradient 2 min(s - eps, 0) grad s. Hessian: Gauss-Newton
 * 2 grad s grad s^T inside the band, 0 outside (exact for the vertex mode
 * with v fixed; the signed distance's curvature is left out). PSD.
 *
 * Points outside the object's bounding box grown by |eps| skip the search
 * (value 0: they cannot be within eps of the object). The BVH queries run in
 * float on the float-rounded point, as the positions on the tape are float;
 * s is then evaluated in double at the point given.
 * Left out: a moving object (the BVH is not refitted here).
 */
#include "crease/phys_energies.h"

#include "crease/bvh.h"
#include "crease/vertex_grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_drape_collision {
    int32_t n; /* points */
    const cr_bvh *bvh;
    cr_bvh *vertices; /* vertex mode: a tree over the object's vertices alone (owned) */
    cr_vertex_grid *grid; /* vertex mode: the tree's answers by candidate lists (owned) */
    cr_drape_collision_mode mode;
    double eps;         /* m */
    float lo[3], hi[3]; /* the object's box grown by |eps|, m */
};

cr_status cr_drape_collision_create(const cr_bvh *object, cr_drape_collision_mode mode, double eps,
                                    cr_drape_collision **out, cr_error *err) {
    CR_ASSERT(object && out);
    *out = NULL;
    if (mode != CR_DRAPE_COLLIDE_VERTEX && mode != CR_DRAPE_COLLIDE_SDF)
        return CR_FAIL(err, CR_ERR_INVALID, "drape collision: unknown mode %d", (int)mode);
    if (!isfinite(eps))
        return CR_FAIL(err, CR_ERR_NAN, "drape collision: eps %g m must be finite", eps);
    cr_drape_collision *c = cr_calloc(1, sizeof *c, err);
    if (!c) return err ? err->status : CR_ERR_MEMORY;
    c->bvh = object, c->mode = mode, c->eps = eps;
    const float *pos = cr_bvh_positions(object);
    const int32_t nv = cr_bvh_vertex_count(object);
    for (int d = 0; d < 3; d++)
        c->lo[d] = INFINITY, c->hi[d] = -INFINITY;
    for (int32_t v = 0; v < nv; v++)
        for (int d = 0; d < 3; d++) {
            c->lo[d] = fminf(c->lo[d], pos[3 * (int64_t)v + d]);
            c->hi[d] = fmaxf(c->hi[d], pos[3 * (int64_t)v + d]);
        }
    const float grow = fabsf((float)eps);
    for (int d = 0; d < 3; d++)
        c->lo[d] -= grow, c->hi[d] += grow;
    if (mode == CR_DRAPE_COLLIDE_VERTEX) {
        /* The nearest-vertex search on the face tree tests every vertex once
         * per face around it, in boxes as large as the faces; a tree of
         * one-vertex faces (v, v, v) has point-sized boxes and prunes sooner
         * (the face tree's query was a third of a drape epoch). */
        int32_t *tri = cr_malloc(3 * (size_t)nv * sizeof(int32_t), err);
        cr_status st = tri ? CR_OK : CR_ERR_MEMORY;
        for (int32_t v = 0; tri && v < nv; v++)
            tri[3 * (size_t)v] = tri[3 * (size_t)v + 1] = tri[3 * (size_t)v + 2] = v;
        if (st == CR_OK) st = cr_bvh_build(pos, nv, tri, nv, &c->vertices, err);
        free(tri);
        /* the same answers as the tree's, about 6 times sooner for points a
         * few centimetres off a dense object (crease/vertex_grid.h) */
        if (st == CR_OK) st = cr_vertex_grid_build(c->vertices, c->lo, c->hi, NULL, &c->grid, err);
        if (st != CR_OK) {
            cr_drape_collision_destroy(c);
            return st;
        }
    }
    *out = c;
    return CR_OK;
}

void cr_drape_collision_destroy(cr_drape_collision *c) {
    if (c) {
        cr_vertex_grid_destroy(c->grid);
        cr_bvh_destroy(c->vertices);
    }
    free(c);
}

void cr_drape_collision_set_count(cr_drape_collision *c, int32_t n) {
    CR_ASSERT(c && n >= 0);
    c->n = n;
}

/* s at xe and its gradient ds (3); 0 when the point is out of reach (then s
 * is left unset). */
static int distance(const cr_drape_collision *c, const double *xe, double *s, double ds[3]) {
    const float p[3] = {(float)xe[0], (float)xe[1], (float)xe[2]};
    for (int d = 0; d < 3; d++)
        if (p[d] < c->lo[d] || p[d] > c->hi[d]) return 0;
    if (c->mode == CR_DRAPE_COLLIDE_VERTEX) {
        const int32_t v = cr_vertex_grid_nearest(c->grid, p, NULL);
        if (v < 0) return 0;
        const float *q = cr_bvh_positions(c->bvh) + 3 * (int64_t)v;
        const float *n = cr_bvh_vertex_normals(c->bvh) + 3 * (int64_t)v;
        *s = 0.0;
        for (int d = 0; d < 3; d++) {
            *s += (xe[d] - q[d]) * n[d];
            ds[d] = n[d];
        }
        return 1;
    }
    float dist, nrm[3];
    cr_bvh_hit hit;
    if (!cr_bvh_signed_distance(c->bvh, p, INFINITY, &dist, nrm, &hit)) return 0;
    const double d[3] = {xe[0] - hit.point[0], xe[1] - hit.point[1], xe[2] - hit.point[2]};
    const double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), sg = dist < 0 ? -1.0 : 1.0;
    if (l > 1e-9) {
        *s = sg * l;
        for (int k = 0; k < 3; k++)
            ds[k] = sg * d[k] / l;
    } else { /* on the surface: the pseudo-normal */
        *s = dist;
        for (int k = 0; k < 3; k++)
            ds[k] = nrm[k];
    }
    return 1;
}

static double collision_kernel(const void *data, int32_t e, const double *xe, double *g,
                               double *H) {
    (void)e;
    const cr_drape_collision *c = data;
    if (g) memset(g, 0, 3 * sizeof(double));
    if (H) memset(H, 0, 9 * sizeof(double));
    double s, ds[3];
    if (!distance(c, xe, &s, ds)) return 0.0;
    const double m = s - c->eps < 0.0 ? s - c->eps : 0.0;
    if (m == 0.0) return 0.0;
    if (g)
        for (int d = 0; d < 3; d++)
            g[d] = 2.0 * m * ds[d];
    if (H)
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                H[3 * a + b] = 2.0 * ds[a] * ds[b];
    return m * m;
}

void cr_drape_collision_term(const cr_drape_collision *c, cr_energy_term *out) {
    CR_ASSERT(c && out);
    memset(out, 0, sizeof *out);
    out->name = "drape_collision";
    out->nelem = c->n;
    out->nvert = 1;
    out->elem = NULL;
    out->kernel = collision_kernel;
    out->data = c;
    out->weight = 1.0;
}
