/* membrane.h: what the two membrane kernels share (private to phys/).
 *
 * A triangle's deformation gradient F = Ds Dm^-1 (3x2), Ds = [x1 - x0, x2 - x0],
 * is linear in its vertices: column j is f_j = sum_i c_ij x_i with
 * c_1j = Dm^-1[0][j], c_2j = Dm^-1[1][j], c_0j = -(c_1j + c_2j). A kernel
 * works on psi(f0, f1): its gradient gF (6) and Hessian HF (6x6, index 3j+d)
 * are mapped to the vertices by the chain rule,
 *     g_i = A0 sum_j c_ij gF_j,   H_ik = A0 sum_jl c_ij c_kl HF_jl,
 * and because that map has full row rank 6, H is PSD exactly when HF is: so
 * the kernels project the 6x6 HF, not the 9x9 H (cr_membrane_project_hf).
 */
#ifndef CREASE_PHYS_MEMBRANE_H
#define CREASE_PHYS_MEMBRANE_H

#include "crease/phys_energies.h"

struct cr_membrane {
    int32_t nf;    /* F */
    int32_t *tri;  /* (F,3) vertex indices */
    double *dminv; /* (F,4) Dm^-1, row-major 2x2, 1/m */
    double *area;  /* (F) rest area A0, m^2 */
    cr_membrane_model model;
    double mu, lambda;         /* StVK, J/m^2 */
    double k_stretch, k_shear; /* Baraff-Witkin, J/m^2 */
    cr_hessian_mode mode;
};

/* f (6) = (f0, f1) and c (3x2, c[2i+j]) of element e at xe (9). */
static inline void cr_membrane_deform(const struct cr_membrane *m, int32_t e, const double *xe,
                                      double *f, double *c) {
    const double *D = m->dminv + 4 * (int64_t)e;
    c[2] = D[0], c[3] = D[1], c[4] = D[2], c[5] = D[3];
    c[0] = -(c[2] + c[4]), c[1] = -(c[3] + c[5]);
    for (int j = 0; j < 2; j++)
        for (int d = 0; d < 3; d++)
            f[3 * j + d] = c[j] * xe[d] + c[2 + j] * xe[3 + d] + c[4 + j] * xe[6 + d];
}

/* g (9) and H (9x9), when not NULL, from gF (6), HF (6x6) and the rest area. */
static inline void cr_membrane_to_x(const double *c, double area, const double *gF,
                                    const double *HF, double *g, double *H) {
    if (g)
        for (int i = 0; i < 3; i++)
            for (int d = 0; d < 3; d++)
                g[3 * i + d] = area * (c[2 * i] * gF[d] + c[2 * i + 1] * gF[3 + d]);
    if (H)
        for (int i = 0; i < 3; i++)
            for (int k = i; k < 3; k++)
                for (int p = 0; p < 3; p++)
                    for (int q = 0; q < 3; q++) {
                        double s = 0.0;
                        for (int j = 0; j < 2; j++)
                            for (int l = 0; l < 2; l++)
                                s += c[2 * i + j] * c[2 * k + l] * HF[6 * (3 * j + p) + 3 * l + q];
                        H[9 * (3 * i + p) + 3 * k + q] = area * s;
                        H[9 * (3 * k + q) + 3 * i + p] = area * s;
                    }
}

/* Vertex k's rows of cr_membrane_to_x: g (3) and, when not NULL, the (k,k)
 * block H (9), the same expressions as the whole map's. */
static inline void cr_membrane_to_vertex(const double *c, double area, int k, const double *gF,
                                         const double *HF, double *g, double *H) {
    if (g)
        for (int d = 0; d < 3; d++)
            g[d] = area * (c[2 * k] * gF[d] + c[2 * k + 1] * gF[3 + d]);
    if (H)
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++) {
                double s = 0.0;
                for (int j = 0; j < 2; j++)
                    for (int l = 0; l < 2; l++)
                        s += c[2 * k + j] * c[2 * k + l] * HF[6 * (3 * j + p) + 3 * l + q];
                H[3 * p + q] = area * s;
            }
}

/* Project HF (6x6, index 3j+d) onto the PSD cone. Both membrane energies
 * depend on F only through f0, f1, so their HF splits exactly into an
 * in-plane 4x4 block (perturbations within span(f0, f1)) and a normal 2x2
 * block (perturbations along the normal n); the two are projected apart,
 * the 2x2 in closed form, the 4x4 by an eigensolve (the whole StVK density
 * does its own in closed form instead, membrane_stvk.c). Falls back to the
 * whole 6x6 when f0, f1 do not span a plane. */
void cr_membrane_project_hf(const double *f, double *HF);

/* The kernels, whole and by part (cr_membrane_part). */
double cr_membrane_stvk_kernel(const void *data, int32_t e, const double *xe, double *g, double *H);
double cr_membrane_stvk_stretch_kernel(const void *data, int32_t e, const double *xe, double *g,
                                       double *H);
double cr_membrane_stvk_shear_kernel(const void *data, int32_t e, const double *xe, double *g,
                                     double *H);
double cr_membrane_bw_kernel(const void *data, int32_t e, const double *xe, double *g, double *H);
double cr_membrane_bw_stretch_kernel(const void *data, int32_t e, const double *xe, double *g,
                                     double *H);
double cr_membrane_bw_shear_kernel(const void *data, int32_t e, const double *xe, double *g,
                                   double *H);
/* Their vertex blocks (cr_energy_vertex_kernel), same order. */
double cr_membrane_stvk_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                               double *H);
double cr_membrane_stvk_stretch_vertex(const void *data, int32_t e, int k, const double *xe,
                                       double *g, double *H);
double cr_membrane_stvk_shear_vertex(const void *data, int32_t e, int k, const double *xe,
                                     double *g, double *H);
double cr_membrane_bw_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                             double *H);
double cr_membrane_bw_stretch_vertex(const void *data, int32_t e, int k, const double *xe,
                                     double *g, double *H);
double cr_membrane_bw_shear_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                                   double *H);

#endif
