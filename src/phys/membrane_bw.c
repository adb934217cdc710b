/* membrane_bw.c: the Baraff-Witkin stretch/shear membrane kernel.
 *
 * With w_u = F[:,0], w_v = F[:,1] (F = Ds Dm^-1, Dm from the rest shape in
 * UV-aligned coordinates), per triangle
 *     E_tri = A0 ( k_s/2 ((|w_u| - 1)^2 + (|w_v| - 1)^2) + k_sh/2 (w_u . w_v)^2 )
 * Baraff & Witkin 1998, "Large steps in cloth simulation" (their condition
 * functions C_stretch = A0 (|w| - 1), C_shear = A0 w_u . w_v, here taken per
 * rest area so E does not scale with A0^2): the form the NCS code and the
 * GDSR and EPNet papers use. The warp/weft directions are the rest shape's
 * axes: the UV axes with a UV rest shape, else each triangle's first edge, so
 * use a UV rest shape for a meaningful stretch/shear split.
 *
 * Hessian in F (6x6): stretch gives k_s (^w ^w^T + (1 - 1/|w|)(I - ^w ^w^T))
 * per column, shear k_sh ((w_v; w_u)(w_v; w_u)^T + (w_u . w_v) [[0, I], [I, 0]]);
 * CR_HESSIAN_PROJECTED eigen-clamps the sum (which is indefinite under
 * compression or shear), CR_HESSIAN_GAUSS_NEWTON keeps k_s ^w ^w^T and the
 * shear's outer product. Left out: damping, anisotropic stiffness.
 */
#include "phys/membrane.h"

#include <math.h>

/* The density with the stretch condition scaled by cs and the shear by csh
 * (each 0 or 1; (1, 1) is the whole membrane). k < 0: the whole element's g
 * and H; k = 0..2: vertex k's g (3) and block H (9) alone. */
static double bw_eval(const cr_membrane *m, double cs, double csh, int32_t e, int k,
                      const double *xe, double *g, double *H) {
    double f[6], c[6];
    cr_membrane_deform(m, e, xe, f, c);
    const double *fu = f, *fv = f + 3;
    const double nu = sqrt(fu[0] * fu[0] + fu[1] * fu[1] + fu[2] * fu[2]);
    const double nv = sqrt(fv[0] * fv[0] + fv[1] * fv[1] + fv[2] * fv[2]);
    const double s = fu[0] * fv[0] + fu[1] * fv[1] + fu[2] * fv[2];
    const double ks = cs * m->k_stretch, ksh = csh * m->k_shear;
    const double psi =
        0.5 * ks * ((nu - 1.0) * (nu - 1.0) + (nv - 1.0) * (nv - 1.0)) + 0.5 * ksh * s * s;
    if (!g && !H) return m->area[e] * psi;
    /* Unit directions; a collapsed column (|w| = 0) has no direction and
     * contributes its stretch only through the value. */
    double hu[3] = {0}, hv[3] = {0};
    for (int d = 0; d < 3; d++) {
        if (nu > 0.0) hu[d] = fu[d] / nu;
        if (nv > 0.0) hv[d] = fv[d] / nv;
    }
    double gF[6], HF[36];
    for (int d = 0; d < 3; d++) {
        gF[d] = ks * (nu - 1.0) * hu[d] + ksh * s * fv[d];
        gF[3 + d] = ks * (nv - 1.0) * hv[d] + ksh * s * fu[d];
    }
    if (H) {
        const int exact = m->mode == CR_HESSIAN_PROJECTED;
        const double tu = exact && nu > 0.0 ? 1.0 - 1.0 / nu : 0.0;
        const double tv = exact && nv > 0.0 ? 1.0 - 1.0 / nv : 0.0;
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++) {
                const double I = p == q ? 1.0 : 0.0;
                HF[6 * p + q] =
                    ks * (hu[p] * hu[q] + tu * (I - hu[p] * hu[q])) + ksh * fv[p] * fv[q];
                HF[6 * (3 + p) + 3 + q] =
                    ks * (hv[p] * hv[q] + tv * (I - hv[p] * hv[q])) + ksh * fu[p] * fu[q];
                HF[6 * p + 3 + q] = ksh * (fv[p] * fu[q] + (exact ? s * I : 0.0));
                HF[6 * (3 + q) + p] = HF[6 * p + 3 + q];
            }
        if (exact) cr_membrane_project_hf(f, HF);
    }
    if (k < 0)
        cr_membrane_to_x(c, m->area[e], gF, H ? HF : NULL, g, H);
    else
        cr_membrane_to_vertex(c, m->area[e], k, gF, H ? HF : NULL, g, H);
    return m->area[e] * psi;
}

double cr_membrane_bw_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    return bw_eval(data, 1.0, 1.0, e, -1, xe, g, H);
}

double cr_membrane_bw_stretch_kernel(const void *data, int32_t e, const double *xe, double *g,
                                     double *H) {
    return bw_eval(data, 1.0, 0.0, e, -1, xe, g, H);
}

double cr_membrane_bw_shear_kernel(const void *data, int32_t e, const double *xe, double *g,
                                   double *H) {
    return bw_eval(data, 0.0, 1.0, e, -1, xe, g, H);
}

double cr_membrane_bw_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                             double *H) {
    return bw_eval(data, 1.0, 1.0, e, k, xe, g, H);
}

double cr_membrane_bw_stretch_vertex(const void *data, int32_t e, int k, const double *xe,
                                     double *g, double *H) {
    return bw_eval(data, 1.0, 0.0, e, k, xe, g, H);
}

double cr_membrane_bw_shear_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                                   double *H) {
    return bw_eval(data, 0.0, 1.0, e, k, xe, g, H);
}
