/* dihedral64.c: double-precision dihedral angle, gradient and exact Hessian
 * of a hinge (derivation in dihedral64.h). Leaves out any projection: the
 * bending energy decides how to make its Hessian PSD.
 *
 * References: Bridson, Marino & Fedkiw 2003, "Simulation of clothing with
 * folds and wrinkles" (gradient); Tamstorf & Grinspun 2013, "Discrete bending
 * forces and their Jacobians" (Hessian; derived here afresh in edge-relative
 * variables, which keeps it to a few 3x3 products).
 */
#include "phys/dihedral64.h"
#include "base/vec3.h"

#include <math.h>
#include <string.h>

/* C = A B for 3x3 row-major. */
static void mul33(const double *A, const double *B, double *C) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}
/* [w]x: the matrix of w x (.). */
static void skew(const double *w, double *W) {
    W[0] = 0.0, W[1] = -w[2], W[2] = w[1];
    W[3] = w[2], W[4] = 0.0, W[5] = -w[0];
    W[6] = -w[1], W[7] = w[0], W[8] = 0.0;
}
/* D(a/|a|^2) = (I - 2 ^a ^a^T)/|a|^2 = (|a|^2 I - 2 a a^T)/|a|^4. */
static void dinv(const double *a, double a2, double *D) {
    const double s = 1.0 / (a2 * a2);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            D[3 * i + j] = s * ((i == j ? a2 : 0.0) - 2.0 * a[i] * a[j]);
}

static double angle_from(const double *e, const double *u, const double *v, double L) {
    double NA[3], NB[3], c[3];
    cross3d(e, u, NA);
    cross3d(v, e, NB);
    cross3d(NB, NA, c);
    /* atan2 ignores the positive scales |NA|, |NB| and L (sin = c.e/L,
     * cos = NA.NB over the same |NA||NB|): no normalisation needed. */
    return cr_atan2d(dot3d(c, e), L * dot3d(NA, NB));
}

double cr_dihedral64_angle(const double *x) {
    double e[3], u[3], v[3];
    sub3d(x + 3, x, e);
    sub3d(x + 6, x, u);
    sub3d(x + 9, x, v);
    const double L = sqrt(dot3d(e, e));
    if (!(L > 0.0)) return 0.0;
    return angle_from(e, u, v, L);
}

double cr_dihedral64_derivs_y(const double *x, double *gy, double *Hy, int *ok) {
    double e[3], u[3], v[3], scale;
    const double L2 = cr_dihedral64_edges(x, e, u, v, &scale);
    const double L = sqrt(L2);
    const double theta = L > 0.0 ? angle_from(e, u, v, L) : 0.0;
    double eh[3] = {e[0] / L, e[1] / L, e[2] / L}, a[3], b[3];
    int good = L2 > 1e-24 * scale;
    if (good) {
        cross3d(eh, u, a);
        cross3d(v, eh, b);
    }
    const double a2 = good ? dot3d(a, a) : 0.0, b2 = good ? dot3d(b, b) : 0.0;
    good = good && a2 > 1e-24 * scale && b2 > 1e-24 * scale;
    *ok = good;
    if (!good) {
        memset(gy, 0, 9 * sizeof(double));
        if (Hy) memset(Hy, 0, 81 * sizeof(double));
        return theta;
    }
    const double alpha = dot3d(u, e) / L2, beta = dot3d(v, e) / L2;
    double gu[3], gv[3];
    for (int i = 0; i < 3; i++) {
        gu[i] = a[i] / a2;
        gv[i] = b[i] / b2;
        gy[i] = -alpha * gu[i] - beta * gv[i];
        gy[3 + i] = gu[i];
        gy[6 + i] = gv[i];
    }
    if (!Hy) return theta;

    double Da[9], Db[9], Ex[9], Ux[9], Vx[9], P[9], T[9];
    double Huu[9], Hvv[9], Hue[9], Hve[9], Hee[9];
    dinv(a, a2, Da);
    dinv(b, b2, Db);
    skew(eh, Ex);
    skew(u, Ux);
    skew(v, Vx);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            P[3 * i + j] = ((i == j) - eh[i] * eh[j]) / L;
    /* d gu/du = Da [^e]x, d gv/dv = -Db [^e]x (a = [^e]x u, b = -[^e]x v). */
    mul33(Da, Ex, Huu);
    mul33(Db, Ex, Hvv);
    for (int k = 0; k < 9; k++)
        Hvv[k] = -Hvv[k];
    /* d gu/de = Da (-[u]x) P/L, d gv/de = Db [v]x P/L (a = -[u]x ^e, b = [v]x ^e). */
    mul33(Ux, P, T);
    mul33(Da, T, Hue);
    for (int k = 0; k < 9; k++)
        Hue[k] = -Hue[k];
    mul33(Vx, P, T);
    mul33(Db, T, Hve);
    /* d ge/de with ge = -alpha gu - beta gv and grad alpha = (u - 2 alpha e)/L^2. */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            const double da = (u[j] - 2.0 * alpha * e[j]) / L2;
            const double db = (v[j] - 2.0 * beta * e[j]) / L2;
            Hee[3 * i + j] =
                -gu[i] * da - alpha * Hue[3 * i + j] - gv[i] * db - beta * Hve[3 * i + j];
        }
    /* Assemble symmetric 9x9 in blocks (e, u, v); symmetrising the diagonal
     * blocks removes only roundoff, they are symmetric in exact arithmetic. */
    memset(Hy, 0, 81 * sizeof(double));
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            Hy[9 * i + j] = 0.5 * (Hee[3 * i + j] + Hee[3 * j + i]);
            Hy[9 * (3 + i) + 3 + j] = 0.5 * (Huu[3 * i + j] + Huu[3 * j + i]);
            Hy[9 * (6 + i) + 6 + j] = 0.5 * (Hvv[3 * i + j] + Hvv[3 * j + i]);
            Hy[9 * (3 + i) + j] = Hue[3 * i + j];
            Hy[9 * j + 3 + i] = Hue[3 * i + j];
            Hy[9 * (6 + i) + j] = Hve[3 * i + j];
            Hy[9 * j + 6 + i] = Hve[3 * i + j];
        }
    return theta;
}

void cr_dihedral64_grad_x(const double *gy, double *gx) {
    for (int d = 0; d < 3; d++) {
        gx[d] = -(gy[d] + gy[3 + d] + gy[6 + d]);
        gx[3 + d] = gy[d];
        gx[6 + d] = gy[3 + d];
        gx[9 + d] = gy[6 + d];
    }
}

void cr_dihedral64_hess_x(const double *Hy, double *Hx) {
    /* Row-block sums r[j] = sum_i Y_ij, c[i] = sum_j Y_ij (3x3 each). */
    double r[3][9] = {{0}}, c[3][9] = {{0}}, t[9] = {0};
    for (int I = 0; I < 3; I++)
        for (int J = 0; J < 3; J++)
            for (int p = 0; p < 3; p++)
                for (int q = 0; q < 3; q++) {
                    const double y = Hy[9 * (3 * I + p) + 3 * J + q];
                    r[J][3 * p + q] += y;
                    c[I][3 * p + q] += y;
                    t[3 * p + q] += y;
                }
    for (int p = 0; p < 3; p++)
        for (int q = 0; q < 3; q++) {
            Hx[12 * p + q] = t[3 * p + q];
            for (int J = 0; J < 3; J++) {
                Hx[12 * p + 3 * (J + 1) + q] = -r[J][3 * p + q];
                Hx[12 * (3 * (J + 1) + p) + q] = -c[J][3 * p + q];
            }
            for (int I = 0; I < 3; I++)
                for (int J = 0; J < 3; J++)
                    Hx[12 * (3 * (I + 1) + p) + 3 * (J + 1) + q] = Hy[9 * (3 * I + p) + 3 * J + q];
        }
}

double cr_dihedral64_vertex_grad(const double *x, int k, double *gk, int *ok) {
    return cr_dihedral64_vertex_grad_inline(x, k, gk, ok);
}

void cr_dihedral64_hess_x_block(const double *Hy, int k, double *Hk) {
    for (int p = 0; p < 3; p++)
        for (int q = 0; q < 3; q++) {
            if (k > 0) {
                Hk[3 * p + q] = Hy[9 * (3 * (k - 1) + p) + 3 * (k - 1) + q];
                continue;
            }
            double t = 0.0; /* as hess_x's t: the sum of all nine blocks */
            for (int I = 0; I < 3; I++)
                for (int J = 0; J < 3; J++)
                    t += Hy[9 * (3 * I + p) + 3 * J + q];
            Hk[3 * p + q] = t;
        }
}
