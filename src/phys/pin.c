/* pin.c: soft pins, a spring from each chosen vertex to its target.
 *
 *     E = k/2 sum_j |x_{v_j} - t_j|^2,   grad k (x - t),   Hess k I
 *
 * The usual way to hold a garment's waistband or a sheet's corners in an
 * incremental-potential solver (a stiff quadratic instead of a hard
 * constraint), and the pinning loss of the self-supervised garment methods.
 * One element per pinned vertex. Left out: hard constraints (the simulator's
 * fixed vertices), pins to moving body points (set new targets per step).
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_pin {
    int32_t n;      /* pinned vertices */
    int32_t *vert;  /* (n) vertex indices */
    double *target; /* (n,3) m */
    double k;       /* N/m */
};

cr_status cr_pin_create(int32_t nv, const int32_t *vertices, int32_t n, double stiffness,
                        cr_pin **out, cr_error *err) {
    CR_ASSERT(out && n >= 0 && (vertices || n == 0));
    *out = NULL;
    if (!(stiffness >= 0.0) || !isfinite(stiffness))
        return CR_FAIL(err, CR_ERR_INVALID, "pin: stiffness %g N/m must be finite and >= 0",
                       stiffness);
    for (int32_t j = 0; j < n; j++)
        if (vertices[j] < 0 || vertices[j] >= nv)
            return CR_FAIL(err, CR_ERR_RANGE, "pin: pin %d names vertex %d, outside [0,%d)", j,
                           vertices[j], nv);
    cr_pin *p = cr_calloc(1, sizeof *p, err);
    if (!p) return err ? err->status : CR_ERR_MEMORY;
    const size_t m = (size_t)(n > 0 ? n : 1);
    p->n = n;
    p->k = stiffness;
    p->vert = cr_malloc(sizeof(int32_t) * m, err);
    p->target = cr_calloc(3 * m, sizeof(double), err);
    if (!p->vert || !p->target) {
        cr_pin_destroy(p);
        return err ? err->status : CR_ERR_MEMORY;
    }
    if (n > 0) memcpy(p->vert, vertices, sizeof(int32_t) * (size_t)n);
    *out = p;
    return CR_OK;
}

void cr_pin_destroy(cr_pin *p) {
    if (!p) return;
    free(p->vert);
    free(p->target);
    free(p);
}

void cr_pin_set_targets(cr_pin *p, const double *targets) {
    CR_ASSERT(p && (targets || p->n == 0));
    if (p->n > 0) memcpy(p->target, targets, sizeof(double) * 3 * (size_t)p->n);
}

int32_t cr_pin_count(const cr_pin *p) {
    return p->n;
}

static double pin_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_pin *p = data;
    const double *t = p->target + 3 * (int64_t)e;
    const double d[3] = {xe[0] - t[0], xe[1] - t[1], xe[2] - t[2]};
    if (g)
        for (int c = 0; c < 3; c++)
            g[c] = p->k * d[c];
    if (H) {
        memset(H, 0, 9 * sizeof(double));
        H[0] = H[4] = H[8] = p->k;
    }
    return 0.5 * p->k * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

void cr_pin_term(const cr_pin *p, cr_energy_term *out) {
    CR_ASSERT(p && out);
    memset(out, 0, sizeof *out);
    out->name = "pin";
    out->nelem = p->n;
    out->nvert = 1;
    out->elem = p->vert;
    out->kernel = pin_kernel;
    out->data = p;
    out->weight = 1.0;
}
