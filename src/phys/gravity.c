/* gravity.c: gravitational potential with lumped vertex masses.
 *
 *     E = -sum_i m_i g . x_i,   m_i = density * (sum of rest areas of the faces at i) / 3
 *
 * The lumped (diagonal) mass matrix of linear triangles (Baraff & Witkin
 * 1998; every cloth simulator in docs/physics.md uses it). Gradient -m_i g,
 * Hessian zero. Masses come from the 3-D rest triangles even when the
 * membrane's rest shape comes from UVs: mass is what the garment weighs now.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_gravity {
    int32_t nv;   /* V */
    double *mass; /* (V) kg */
    double g[3];  /* m/s^2 */
};

cr_status cr_gravity_create(const cr_mesh *rest, const cr_material *mat, const double g[3],
                            cr_gravity **out, cr_error *err) {
    CR_ASSERT(rest && mat && g && out);
    CR_ASSERT(mat->cookie == CR_MATERIAL_COOKIE);
    *out = NULL;
    if (!isfinite(g[0]) || !isfinite(g[1]) || !isfinite(g[2]))
        return CR_FAIL(err, CR_ERR_NAN, "gravity: g = (%g, %g, %g) must be finite", g[0], g[1],
                       g[2]);
    cr_gravity *gr = cr_calloc(1, sizeof *gr, err);
    if (!gr) return err ? err->status : CR_ERR_MEMORY;
    gr->nv = rest->nv;
    memcpy(gr->g, g, sizeof gr->g);
    gr->mass = cr_calloc((size_t)(rest->nv > 0 ? rest->nv : 1), sizeof(double), err);
    if (!gr->mass) {
        cr_gravity_destroy(gr);
        return err ? err->status : CR_ERR_MEMORY;
    }
    for (int32_t f = 0; f < rest->nf; f++) {
        const int32_t *t = rest->tri + 3 * (int64_t)f;
        const float *p0 = rest->pos + 3 * (int64_t)t[0];
        const float *p1 = rest->pos + 3 * (int64_t)t[1];
        const float *p2 = rest->pos + 3 * (int64_t)t[2];
        double a[3], b[3];
        for (int d = 0; d < 3; d++)
            a[d] = (double)p1[d] - p0[d], b[d] = (double)p2[d] - p0[d];
        const double n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                             a[0] * b[1] - a[1] * b[0]};
        const double m3 = mat->density * 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) / 3.0;
        for (int k = 0; k < 3; k++)
            gr->mass[t[k]] += m3;
    }
    *out = gr;
    return CR_OK;
}

void cr_gravity_destroy(cr_gravity *g) {
    if (!g) return;
    free(g->mass);
    free(g);
}

const double *cr_gravity_masses(const cr_gravity *g) {
    return g->mass;
}

static double gravity_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_gravity *gr = data;
    const double m = gr->mass[e];
    if (g)
        for (int d = 0; d < 3; d++)
            g[d] = -m * gr->g[d];
    if (H) memset(H, 0, 9 * sizeof(double));
    return -m * (gr->g[0] * xe[0] + gr->g[1] * xe[1] + gr->g[2] * xe[2]);
}

void cr_gravity_term(const cr_gravity *g, cr_energy_term *out) {
    CR_ASSERT(g && out);
    memset(out, 0, sizeof *out);
    out->name = "gravity";
    out->nelem = g->nv;
    out->nvert = 1;
    out->kernel = gravity_kernel;
    out->data = g;
    out->weight = 1.0;
}
