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

/* Vertex k's share (k = 0..3): theta (returned, the same bits as
 * cr_dihedral64_angle) and d theta/dx_k (3), equal to the row of
 * cr_dihedral64_derivs_y + cr_dihedral64_grad_x up to roundoff, from the two
 * face normals alone. Degenerate hinges as there (gk 0, *ok 0). */
double cr_dihedral64_vertex_grad(const double *x, int k, double *gk, int *ok);

/* The (k,k) 3x3 block of cr_dihedral64_hess_x's Hx, from Hy (9x9). */
void cr_dihedral64_hess_x_block(const double *Hy, int k, double *Hk);

#endif
