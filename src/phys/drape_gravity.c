/* drape_gravity.c: the drape method's gravity loss per point.
 *
 *     E_i = m g y_i
 * one mass m for every point (the paper's m(p), Shu et al.,
 * ../shared/papers/000, eq. 24), g the acceleration's magnitude, height y
 * along +Y. Gradient (0, m g, 0), Hessian zero. The same potential as
 * gravity.c's -m_i g . x_i with g = (0, -g, 0), for points that carry no
 * mesh: the local structures' vertices, whose count changes every step.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_drape_gravity {
    int32_t n;   /* points */
    double mass; /* kg per point */
    double g;    /* m/s^2 */
};

cr_status cr_drape_gravity_create(double mass, double g, cr_drape_gravity **out, cr_error *err) {
    CR_ASSERT(out);
    *out = NULL;
    if (!isfinite(mass) || !isfinite(g))
        return CR_FAIL(err, CR_ERR_NAN, "drape gravity: mass %g kg and g %g m/s^2 must be finite",
                       mass, g);
    cr_drape_gravity *gr = cr_calloc(1, sizeof *gr, err);
    if (!gr) return err ? err->status : CR_ERR_MEMORY;
    gr->mass = mass, gr->g = g;
    *out = gr;
    return CR_OK;
}

void cr_drape_gravity_destroy(cr_drape_gravity *g) {
    free(g);
}

void cr_drape_gravity_set_count(cr_drape_gravity *g, int32_t n) {
    CR_ASSERT(g && n >= 0);
    g->n = n;
}

static double gravity_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    (void)e;
    const cr_drape_gravity *gr = data;
    const double mg = gr->mass * gr->g;
    if (g) g[0] = 0.0, g[1] = mg, g[2] = 0.0;
    if (H) memset(H, 0, 9 * sizeof(double));
    return mg * xe[1];
}

void cr_drape_gravity_term(const cr_drape_gravity *g, cr_energy_term *out) {
    CR_ASSERT(g && out);
    memset(out, 0, sizeof *out);
    out->name = "drape_gravity";
    out->nelem = g->n;
    out->nvert = 1;
    out->elem = NULL;
    out->kernel = gravity_kernel;
    out->data = g;
    out->weight = 1.0;
}
