/* inertia.c: the inertia term of implicit Euler as an incremental potential.
 *
 *     E = 1/(2 h^2) sum_i m_i |x_i - xpred_i|^2,   xpred = x_t + h v_t (+ h^2 f_ext/m when lagged)
 *
 * Minimising E plus the potential energies over x is one backward Euler step
 * (Martin et al. 2011, "Example-based elastic materials"; Gast et al. 2015,
 * "Optimization integrator for large time steps"; IPC, Li et al. 2020).
 * Gradient m_i/h^2 (x_i - xpred_i), Hessian m_i/h^2 I: PSD, diagonal.
 * Left out: higher-order integrators (BDF2); the simulator forms xpred.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_inertia {
    int32_t nv;    /* V */
    double *mass;  /* (V) kg */
    double *xpred; /* (V,3) m */
    double inv_h2; /* 1/h^2, 1/s^2 */
};

cr_status cr_inertia_create(const double *masses, int32_t nv, cr_inertia **out, cr_error *err) {
    CR_ASSERT(masses && out && nv >= 0);
    *out = NULL;
    for (int32_t i = 0; i < nv; i++)
        if (!(masses[i] >= 0.0) || !isfinite(masses[i]))
            return CR_FAIL(err, CR_ERR_INVALID, "inertia: mass of vertex %d = %g must be >= 0", i,
                           masses[i]);
    cr_inertia *in = cr_calloc(1, sizeof *in, err);
    if (!in) return err ? err->status : CR_ERR_MEMORY;
    const size_t n = (size_t)(nv > 0 ? nv : 1);
    in->nv = nv;
    in->mass = cr_malloc(sizeof(double) * n, err);
    in->xpred = cr_calloc(3 * n, sizeof(double), err);
    if (!in->mass || !in->xpred) {
        cr_inertia_destroy(in);
        return err ? err->status : CR_ERR_MEMORY;
    }
    memcpy(in->mass, masses, sizeof(double) * (size_t)nv);
    in->inv_h2 = 0.0;
    *out = in;
    return CR_OK;
}

void cr_inertia_destroy(cr_inertia *in) {
    if (!in) return;
    free(in->mass);
    free(in->xpred);
    free(in);
}

void cr_inertia_set(cr_inertia *in, const double *x_pred, double h) {
    CR_ASSERT(in && x_pred && h > 0.0 && isfinite(h));
    memcpy(in->xpred, x_pred, sizeof(double) * 3 * (size_t)in->nv);
    in->inv_h2 = 1.0 / (h * h);
}

static double inertia_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_inertia *in = data;
    const double k = in->mass[e] * in->inv_h2;
    const double *p = in->xpred + 3 * (int64_t)e;
    const double d[3] = {xe[0] - p[0], xe[1] - p[1], xe[2] - p[2]};
    if (g)
        for (int c = 0; c < 3; c++)
            g[c] = k * d[c];
    if (H) {
        memset(H, 0, 9 * sizeof(double));
        H[0] = H[4] = H[8] = k;
    }
    return 0.5 * k * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

void cr_inertia_term(const cr_inertia *in, cr_energy_term *out) {
    CR_ASSERT(in && out);
    memset(out, 0, sizeof *out);
    out->name = "inertia";
    out->nelem = in->nv;
    out->nvert = 1;
    out->kernel = inertia_kernel;
    out->data = in;
    out->weight = 1.0;
}
