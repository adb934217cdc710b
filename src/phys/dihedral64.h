/* dihedral64.h: the signed dihedral angle of a hinge in double precision,
 * with its gradient and exact Hessian, for the bending energy.
 *
 * Same hinge and sign convention as diffgeo.h's float cr_dihedral_angle: edge
 * x0-x1, face A = (x0, x1, x2), face B = (x1, x0, x3), unit normals nA, nB,
 * e = (x1 - x0)/|x1 - x0|, theta = atan2((nB x nA) . e, nA . nB) in (-pi, pi],
 * 0 flat, positive when the wings fold toward the normals' side.
 *
 * Derivatives are taken in the edge-relative variables y = (e, u, v) =
 * (x1 - x0, x2 - x0, x3 - x0), where theta's gradient is compact:
 *     d theta/du = a/|a|^2,  a = ^e x u        (= nA/hA)
 *     d theta/dv = b/|b|^2,  b = v x ^e        (= nB/hB)
 *     d theta/de = -alpha d/du - beta d/dv,   alpha = u.e/|e|^2, beta = v.e/|e|^2
 * (Bridson et al. 2003; Tamstorf & Grinspun 2013), and its Hessian follows
 * from D(a/|a|^2) = (I - 2 ^a ^a^T)/|a|^2 and d^e/de = (I - ^e ^e^T)/|e|.
 * Positions are recovered by x0 = -(e + u + v) in the chain rule (the map
 * x -> y is linear with full row rank 9), so a 9x9 matrix in y is PSD
 * exactly when its 12x12 image in x is.
 */
#ifndef CREASE_PHYS_DIHEDRAL64_H
#define CREASE_PHYS_DIHEDRAL64_H

#include <math.h>

#include "base/atan2d.h"
#include "base/vec3.h"

/* fmax without the call (the same result, NaN included: the other operand). */
static inline double cr_dihedral64_maxd(double a, double b) {
    return a > b || b != b ? a : b;
}

/* x: (4,3) hinge positions x0..x3, m. Returns theta, rad. */
double cr_dihedral64_angle(const double *x);

/* theta (returned) and, in y = (e, u, v) coordinates, its gradient gy (9) and,
 * when Hy is not NULL, its exact Hessian Hy (9x9 row-major, symmetric).
 * Returns 0 gradient and Hessian (and still theta) when a face or the edge is
 * degenerate (area or length below 1e-12 of the hinge's scale). Sets *ok to 0
 * then, 1 otherwise. */
double cr_dihedral64_derivs_y(const double *x, double *gy, double *Hy, int *ok);

/* Gradient in x (12) from gy (9): g_x0 = -(g_e + g_u + g_v). */
void cr_dihedral64_grad_x(const double *gy, double *gx);

/* Hessian in x (12x12) from Hy (9x9): Hx = J^T Hy J. */
void cr_dihedral64_hess_x(const double *Hy, double *Hx);

/* The hinge's edges from x0: e = x1 - x0, u = x2 - x0, v = x3 - x0; returns |e|^2
 * and sets *scale, the largest squared edge (the degeneracy tests' yardstick). */
static inline double cr_dihedral64_edges(const double *x, double *e, double *u, double *v,
                                         double *scale) {
    sub3d(x + 3, x, e);
    sub3d(x + 6, x, u);
    sub3d(x + 9, x, v);
    const double L2 = dot3d(e, e);
    *scale = cr_dihedral64_maxd(L2, cr_dihedral64_maxd(dot3d(u, u), dot3d(v, v)));
    return L2;
}

/* Vertex k's share (k = 0..3): theta (returned, the same bits as
 * cr_dihedral64_angle) and d theta/dx_k (3), equal to the row of
 * cr_dihedral64_derivs_y + cr_dihedral64_grad_x up to roundoff, from the two
 * face normals alone. Degenerate hinges as there (gk 0, *ok 0). */
double cr_dihedral64_vertex_grad(const double *x, int k, double *gk, int *ok);

/* The same, inline (bending's vertex block, the hot loop of a VBD sweep). */
static inline double cr_dihedral64_vertex_grad_inline(const double *x, int k, double *gk, int *ok) {
    double e[3], u[3], v[3], NA[3], NB[3], scale;
    const double L2 = cr_dihedral64_edges(x, e, u, v, &scale);
    const double L = sqrt(L2);
    /* angle_from's operations, in its order: the same bits. */
    cross3d(e, u, NA);
    cross3d(v, e, NB);
    double theta = 0.0;
    if (L > 0.0) {
        double c[3];
        cross3d(NB, NA, c);
        theta = cr_atan2d(dot3d(c, e), L * dot3d(NA, NB));
    }
    /* a = ^e x u = NA/L and b = v x ^e = NB/L, so a/|a|^2 = NA L/|NA|^2. */
    const double A2 = dot3d(NA, NA), B2 = dot3d(NB, NB);
    *ok = L2 > 1e-24 * scale && A2 > 1e-24 * scale * L2 && B2 > 1e-24 * scale * L2;
    if (!*ok) {
        gk[0] = gk[1] = gk[2] = 0.0;
        return theta;
    }
    const double su = L / A2, sv = L / B2;
    double cu, cv; /* gk = cu NA + cv NB */
    if (k == 2) {
        cu = su, cv = 0.0;
    } else if (k == 3) {
        cu = 0.0, cv = sv;
    } else {
        const double alpha = dot3d(u, e) / L2, beta = dot3d(v, e) / L2;
        /* g_e = -alpha g_u - beta g_v; g_x0 = -(g_e + g_u + g_v). */
        cu = k == 1 ? -alpha * su : (alpha - 1.0) * su;
        cv = k == 1 ? -beta * sv : (beta - 1.0) * sv;
    }
    for (int i = 0; i < 3; i++)
        gk[i] = cu * NA[i] + cv * NB[i];
    return theta;
}

/* The (k,k) 3x3 block of cr_dihedral64_hess_x's Hx, from Hy (9x9). */
void cr_dihedral64_hess_x_block(const double *Hy, int k, double *Hk);

#endif
