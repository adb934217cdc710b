/* drape_strain.c: the drape method's strain loss over an edge list.
 *
 * Per edge e = (i, j) with rest length L (Shu et al., ../shared/papers/000,
 * eq. 19, the scaled form the paper uses):
 *     E_e = r^2,   r = (l - L) / L,   l = |x_i - x_j|
 * Gradient 2 r / (L l) (x_i - x_j) on x_i, the negative on x_j; zero when the
 * ends coincide (no direction to push along).
 *
 * Hessian: with u = (x_i - x_j)/l, the exact one is
 *     [A -A; -A A],   A = 2/L^2 u u^T + 2 r/(L l) (I - u u^T),
 * whose eigenvalues are 0 (translations) and twice those of A: 2 (2/L^2)
 * along u, twice 2 r/(L l) across it. It is PSD exactly when the edge is
 * stretched; the projection clamps the transverse eigenvalue of a compressed
 * edge to 0, in closed form (no eigensolve).
 *
 * Elements change every training step (sampled local structures): _set
 * copies them into storage that only grows.
 * Left out: the paper's eq. 18 (unscaled (l - L)^2), which it does not use.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* E edges. */
struct cr_drape_strain {
    int32_t ne, cap; /* E, edges allocated */
    int32_t *edge;   /* (E,2) */
    double *rest;    /* (E) L, m */
};

static cr_status reserve(cr_drape_strain *s, int32_t n, cr_error *err) {
    if (n <= s->cap && s->edge) return CR_OK;
    int32_t cap = n > 2 * s->cap ? n : 2 * s->cap;
    if (cap < 1) cap = 1;
    int32_t *edge = cr_malloc(sizeof(int32_t) * 2 * (size_t)cap, err);
    double *rest = cr_malloc(sizeof(double) * (size_t)cap, err);
    if (!edge || !rest) {
        free(edge), free(rest);
        return err ? err->status : CR_ERR_MEMORY;
    }
    free(s->edge), free(s->rest);
    s->edge = edge, s->rest = rest, s->cap = cap;
    return CR_OK;
}

cr_status cr_drape_strain_create(int32_t cap, cr_drape_strain **out, cr_error *err) {
    CR_ASSERT(out && cap >= 0);
    *out = NULL;
    cr_drape_strain *s = cr_calloc(1, sizeof *s, err);
    if (!s) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = reserve(s, cap, err);
    if (st != CR_OK) {
        cr_drape_strain_destroy(s);
        return st;
    }
    *out = s;
    return CR_OK;
}

void cr_drape_strain_destroy(cr_drape_strain *s) {
    if (!s) return;
    free(s->edge);
    free(s->rest);
    free(s);
}

cr_status cr_drape_strain_set(cr_drape_strain *s, const int32_t *edges, const float *rest,
                              int32_t ne, int32_t nv, cr_error *err) {
    CR_ASSERT(s && ne >= 0 && (ne == 0 || (edges && rest)));
    s->ne = 0;
    CR_TRY(reserve(s, ne, err));
    for (int32_t e = 0; e < ne; e++) {
        const int32_t i = edges[2 * (int64_t)e], j = edges[2 * (int64_t)e + 1];
        if (i < 0 || i >= nv || j < 0 || j >= nv)
            return CR_FAIL(err, CR_ERR_RANGE, "drape strain: edge %d (%d, %d) outside [0, %d)", e,
                           i, j, nv);
        if (!(rest[e] > 0.0f) || !isfinite(rest[e]))
            return CR_FAIL(err, CR_ERR_INVALID, "drape strain: rest length of edge %d is %g", e,
                           (double)rest[e]);
        s->edge[2 * (int64_t)e] = i, s->edge[2 * (int64_t)e + 1] = j;
        s->rest[e] = rest[e];
    }
    s->ne = ne;
    return CR_OK;
}

static double strain_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_drape_strain *s = data;
    const double d[3] = {xe[0] - xe[3], xe[1] - xe[4], xe[2] - xe[5]};
    const double L = s->rest[e], l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double r = (l - L) / L;
    if (g) {
        const double k = l > 0.0 ? 2.0 * r / (L * l) : 0.0;
        for (int c = 0; c < 3; c++)
            g[c] = k * d[c], g[3 + c] = -k * d[c];
    }
    if (H) {
        double A[9] = {0};
        if (l > 0.0) {
            const double along = 2.0 / (L * L), across = r > 0.0 ? 2.0 * r / (L * l) : 0.0;
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) {
                    const double uu = d[a] * d[b] / (l * l);
                    A[3 * a + b] = along * uu + across * ((a == b) - uu);
                }
        }
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                H[6 * a + b] = H[6 * (a + 3) + b + 3] = A[3 * a + b];
                H[6 * a + b + 3] = H[6 * (a + 3) + b] = -A[3 * a + b];
            }
    }
    return r * r;
}

void cr_drape_strain_term(const cr_drape_strain *s, cr_energy_term *out) {
    CR_ASSERT(s && out);
    memset(out, 0, sizeof *out);
    out->name = "drape_strain";
    out->nelem = s->ne;
    out->nvert = 2;
    out->elem = s->edge;
    out->kernel = strain_kernel;
    out->data = s;
    out->weight = 1.0;
}
