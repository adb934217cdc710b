/* drape_bend.c: the drape method's bending loss over a hinge list.
 *
 * Per hinge (edge x0-x1 shared by face A = (x0,x1,x2) and face B =
 * (x1,x0,x3), topology.h's layout), with m_A = (x1 - x0) x (x2 - x0),
 * m_B = (x0 - x1) x (x3 - x1) and n = m/|m| (Shu et al.,
 * ../shared/papers/000, eq. 22, the unweighted form the paper uses):
 *     E_h = |n_A - n_B|^2
 * 0 for a flat hinge, 4 for one folded shut. A degenerate face (|m| = 0)
 * gives 0 and no gradient.
 *
 * Gradient: dE/dn_A = 2 (n_A - n_B) = -dE/dn_B; through n = m/|m|,
 * dE/dm = (I - n n^T) dE/dn / |m|; through m = a x b, dE/da = b x dE/dm and
 * dE/db = dE/dm x a.
 * Hessian: Gauss-Newton, 2 J^T J with J (3x12) the Jacobian of the residual
 * n_A - n_B; PSD by construction. It leaves out the residual times the
 * normals' second derivatives, small where the loss is (n_A near n_B).
 *
 * Elements change every training step (sampled local structures): _set
 * copies them into storage that only grows.
 * Left out: the paper's eq. 21 (area-weighted), which it does not use.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* H hinges. */
struct cr_drape_bend {
    int32_t nh, cap; /* H, hinges allocated */
    int32_t *hinge;  /* (H,4) x0, x1, x2, x3 */
};

static cr_status reserve(cr_drape_bend *b, int32_t n, cr_error *err) {
    if (n <= b->cap && b->hinge) return CR_OK;
    int32_t cap = n > 2 * b->cap ? n : 2 * b->cap;
    if (cap < 1) cap = 1;
    int32_t *hinge = cr_malloc(sizeof(int32_t) * 4 * (size_t)cap, err);
    if (!hinge) return err ? err->status : CR_ERR_MEMORY;
    free(b->hinge);
    b->hinge = hinge, b->cap = cap;
    return CR_OK;
}

cr_status cr_drape_bend_create(int32_t cap, cr_drape_bend **out, cr_error *err) {
    CR_ASSERT(out && cap >= 0);
    *out = NULL;
    cr_drape_bend *b = cr_calloc(1, sizeof *b, err);
    if (!b) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = reserve(b, cap, err);
    if (st != CR_OK) {
        cr_drape_bend_destroy(b);
        return st;
    }
    *out = b;
    return CR_OK;
}

void cr_drape_bend_destroy(cr_drape_bend *b) {
    if (!b) return;
    free(b->hinge);
    free(b);
}

cr_status cr_drape_bend_set(cr_drape_bend *b, const int32_t *hinges, int32_t nh, int32_t nv,
                            cr_error *err) {
    CR_ASSERT(b && nh >= 0 && (nh == 0 || hinges));
    b->nh = 0;
    CR_TRY(reserve(b, nh, err));
    for (int64_t k = 0; k < 4 * (int64_t)nh; k++)
        if (hinges[k] < 0 || hinges[k] >= nv)
            return CR_FAIL(err, CR_ERR_RANGE, "drape bend: vertex %d of hinge %lld outside [0, %d)",
                           hinges[k], (long long)(k / 4), nv);
    if (nh) memcpy(b->hinge, hinges, sizeof(int32_t) * 4 * (size_t)nh);
    b->nh = nh;
    return CR_OK;
}

static inline void cross(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* dE/dm = (I - n n^T) gn / |m| for n = m/|m|; for m = a x b, dE/da = b x dE/dm
 * and dE/db = dE/dm x a. */
static void cross_backward(const double m[3], double len, const double gn[3], const double a[3],
                           const double b[3], double ga[3], double gb[3]) {
    const double n[3] = {m[0] / len, m[1] / len, m[2] / len};
    const double nd = n[0] * gn[0] + n[1] * gn[1] + n[2] * gn[2];
    double gm[3];
    for (int c = 0; c < 3; c++)
        gm[c] = (gn[c] - n[c] * nd) / len;
    cross(b, gm, ga);
    cross(gm, a, gb);
}

/* out (3x3) = P S(v) / len with P = I - n n^T, S(v) w = v x w. */
static void proj_skew(const double n[3], double len, const double v[3], double s, double *out) {
    const double S[9] = {0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double acc = 0.0;
            for (int k = 0; k < 3; k++)
                acc += ((i == k) - n[i] * n[k]) * S[3 * k + j];
            out[3 * i + j] = s * acc / len;
        }
}

static double bend_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    (void)data, (void)e;
    const double *x0 = xe, *x1 = xe + 3, *x2 = xe + 6, *x3 = xe + 9;
    double a[3], b[3], c[3], f[3], mA[3], mB[3];
    for (int d = 0; d < 3; d++)
        a[d] = x1[d] - x0[d], b[d] = x2[d] - x0[d], c[d] = x0[d] - x1[d], f[d] = x3[d] - x1[d];
    cross(a, b, mA), cross(c, f, mB);
    const double lA = sqrt(mA[0] * mA[0] + mA[1] * mA[1] + mA[2] * mA[2]);
    const double lB = sqrt(mB[0] * mB[0] + mB[1] * mB[1] + mB[2] * mB[2]);
    if (g) memset(g, 0, 12 * sizeof(double));
    if (H) memset(H, 0, 144 * sizeof(double));
    if (!(lA > 0.0 && lB > 0.0)) return 0.0;
    double r[3], s = 0.0;
    for (int d = 0; d < 3; d++) {
        r[d] = mA[d] / lA - mB[d] / lB;
        s += r[d] * r[d];
    }
    if (g) {
        double gnA[3], gnB[3], ga[3], gb[3], gc[3], gf[3];
        for (int d = 0; d < 3; d++)
            gnA[d] = 2.0 * r[d], gnB[d] = -gnA[d];
        cross_backward(mA, lA, gnA, a, b, ga, gb); /* a = x1 - x0, b = x2 - x0 */
        cross_backward(mB, lB, gnB, c, f, gc, gf); /* c = x0 - x1, f = x3 - x1 */
        for (int d = 0; d < 3; d++) {
            g[d] = -ga[d] - gb[d] + gc[d];
            g[3 + d] = ga[d] - gc[d] - gf[d];
            g[6 + d] = gb[d];
            g[9 + d] = gf[d];
        }
    }
    if (H) {
        /* J_k = P_A/|m_A| dm_A/dx_k - P_B/|m_B| dm_B/dx_k, with dm = -S(b) da + S(a) db:
         * dm_A/dx1 = -S(b), dm_A/dx2 = S(a), dm_A/dx0 = -(the two); likewise
         * dm_B/dx0 = -S(f), dm_B/dx3 = S(c), dm_B/dx1 = -(the two). */
        const double nA[3] = {mA[0] / lA, mA[1] / lA, mA[2] / lA};
        const double nB[3] = {mB[0] / lB, mB[1] / lB, mB[2] / lB};
        double J[4][9] = {{0}};
        proj_skew(nA, lA, b, -1.0, J[1]);
        proj_skew(nA, lA, a, 1.0, J[2]);
        double JB0[9], JB3[9];
        proj_skew(nB, lB, f, -1.0, JB0);
        proj_skew(nB, lB, c, 1.0, JB3);
        for (int q = 0; q < 9; q++) {
            J[0][q] = -(J[1][q] + J[2][q]) - JB0[q];
            J[1][q] += JB0[q] + JB3[q];
            J[3][q] = -JB3[q];
        }
        for (int k = 0; k < 4; k++)
            for (int l = 0; l < 4; l++)
                for (int i = 0; i < 3; i++)
                    for (int j = 0; j < 3; j++) {
                        double acc = 0.0;
                        for (int q = 0; q < 3; q++)
                            acc += J[k][3 * q + i] * J[l][3 * q + j];
                        H[12 * (3 * k + i) + 3 * l + j] = 2.0 * acc;
                    }
    }
    return s;
}

void cr_drape_bend_term(const cr_drape_bend *b, cr_energy_term *out) {
    CR_ASSERT(b && out);
    memset(out, 0, sizeof *out);
    out->name = "drape_bend";
    out->nelem = b->nh;
    out->nvert = 4;
    out->elem = b->hinge;
    out->kernel = bend_kernel;
    out->data = b;
    out->weight = 1.0;
}
