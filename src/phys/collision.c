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
 * The thickness is held over the cloth's faces, not only at its vertices.
 * Over a curved collider a flat triangle's interior sags toward the surface:
 * with cr_collision_set_edges, cr_collision_update_margins sets vertex i's
 * threshold to eps plus the largest chord sag (cr_collision_chord_sag) of its
 * edges, so a face whose corners sit at their thresholds has its centroid at
 * eps. The sag is taken from the collider's smooth normal (its vertex normals
 * interpolated at the closest point), not from the pseudo-normal the
 * penalty is linearised with: on a polyhedral body the pseudo-normal turns
 * by a facet's angle within a fraction of a millimetre, and a 0.1 mm move
 * then changed a neighbour's threshold by a millimetre (a twin started
 * 0.1 mm away parted from its reference four times faster on a coarse cloth
 * over a sphere). The simulator sets the thresholds once per substep, at the
 * step's start, and holds them through the solve (as friction holds its
 * contacts): the objective stays one function of x while Newton's iterates
 * and VBD's sweeps relinearise. On a
 * 630-vertex t-shirt (3.5 cm edges over a 5 cm shoulder) the sag is about
 * 4 mm, twice the 2 mm thickness, and the skin showed through every face
 * over the shoulders while every vertex stayed outside.
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
    double *margin; /* (V) eps + the largest chord sag of the vertex's edges, m */
    int32_t *edge;  /* (E,2) the cloth's edges (NULL: the margin is eps) */
    int32_t ne;
    double max_margin; /* m */
    double max_pen;    /* m */
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
    c->margin = cr_malloc(sizeof(double) * n, err);
    if (!c->x || !c->dist || !c->normal || !c->margin) {
        cr_collision_destroy(c);
        return err ? err->status : CR_ERR_MEMORY;
    }
    /* Until the first update every vertex is far away. */
    for (int32_t i = 0; i < nv; i++)
        c->dist[i] = INFINITY, c->margin[i] = c->eps;
    c->max_margin = c->eps;
    *out = c;
    return CR_OK;
}

void cr_collision_destroy(cr_collision *c) {
    if (!c) return;
    free(c->x);
    free(c->dist);
    free(c->normal);
    free(c->margin);
    free(c->edge);
    free(c);
}

cr_status cr_collision_set_edges(cr_collision *c, const int32_t *edge, int32_t ne, cr_error *err) {
    CR_ASSERT(c && (edge || ne == 0) && ne >= 0);
    for (int64_t k = 0; k < 2 * (int64_t)ne; k++)
        if (edge[k] < 0 || edge[k] >= c->nv)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "collision: edge %lld names vertex %d of a %d-vertex cloth",
                           (long long)(k / 2), edge[k], c->nv);
    int32_t *copy = cr_malloc(2 * (size_t)(ne > 0 ? ne : 1) * sizeof(int32_t), err);
    if (!copy) return err ? err->status : CR_ERR_MEMORY;
    memcpy(copy, edge, 2 * (size_t)ne * sizeof(int32_t));
    free(c->edge);
    c->edge = copy;
    c->ne = ne;
    return CR_OK;
}

double cr_collision_chord_sag(const double xa[3], const double na[3], const double xb[3],
                              const double nb[3]) {
    const double cos_ab = na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2];
    const double apart = fmin(1.0, (cos_ab - 0.5) / 0.2); /* 1 within 46 degrees, 0 past 60 */
    if (!(apart > 0.0)) return 0.0;
    const double c = (nb[0] - na[0]) * (xb[0] - xa[0]) + (nb[1] - na[1]) * (xb[1] - xa[1]) +
                     (nb[2] - na[2]) * (xb[2] - xa[2]);
    return c > 0.0 ? apart * c / 6.0 : 0.0;
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

/* The sag fades out over the last millimetre before the query's reach (an
 * edge's far end then has no normal) and as the normals part from about 46
 * to 60 degrees (cr_collision_chord_sag), so the thresholds are continuous
 * in the positions. */
#define SAG_FADE_M 1e-3

void cr_collision_update_margins(cr_collision *c, const float *normal, double reach) {
    CR_ASSERT(c && (normal || c->ne == 0));
    for (int32_t i = 0; i < c->nv; i++)
        c->margin[i] = c->eps;
    double top = c->eps;
    for (int32_t e = 0; e < c->ne; e++) {
        const int32_t a = c->edge[2 * e], b = c->edge[2 * e + 1];
        const double far = fmax(c->dist[a], c->dist[b]);
        const double fade = fmin(1.0, (reach - far) / SAG_FADE_M);
        if (!(fade > 0.0)) continue;
        double na[3], nb[3];
        for (int k = 0; k < 3; k++)
            na[k] = normal[3 * (int64_t)a + k], nb[k] = normal[3 * (int64_t)b + k];
        const double sag =
            fade * cr_collision_chord_sag(c->x + 3 * (int64_t)a, na, c->x + 3 * (int64_t)b, nb);
        if (!(sag > 0.0)) continue;
        const double m = c->eps + sag;
        if (m > c->margin[a]) c->margin[a] = m;
        if (m > c->margin[b]) c->margin[b] = m;
        if (m > top) top = m;
    }
    c->max_margin = top;
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

double cr_collision_margin(const cr_collision *c, int32_t i) {
    CR_ASSERT(c && i >= 0 && i < c->nv);
    return c->margin[i];
}

double cr_collision_max_margin(const cr_collision *c) {
    return c->max_margin;
}

int cr_collision_contact(const cr_collision *c, int32_t i, double normal[3], double *force) {
    CR_ASSERT(c && i >= 0 && i < c->nv);
    const double s = c->margin[i] - c->dist[i];
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
    return cr_collision_penalty(c->k, c->margin[e], d, n, g, H);
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
