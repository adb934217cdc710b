/* friction.c: lagged, smoothed Coulomb friction against the collider.
 *
 * IPC's friction potential (Li et al. 2020, "Incremental Potential Contact",
 * sec. 5), specialised to vertex-vs-collider contact. Once per time step the
 * simulator freezes, for every vertex i within the collision thickness, the
 * normal force lambda_i = 3 k (eps - d_i)^2 of the penalty (collision.c), an
 * orthonormal tangent basis T_i (3x2) of the contact normal, and the anchor
 * a_i = x_i^start + db_i (db_i: the collider surface's displacement under the
 * vertex over the step). Over the step's Newton iterations
 *     u_i = T_i^T (x_i - a_i)             tangential slip, m
 *     D_i = mu lambda_i f0(|u_i|)
 *     f0(y) = -y^3/(3 eps_v^2) + y^2/eps_v + eps_v/3   (y < eps_v),   y   (y >= eps_v)
 * f0' = f1 with f1(y) = 2y/eps_v - y^2/eps_v^2 below eps_v and 1 above, so
 * the force -mu lambda_i f1(|u|) T u/|u| is Coulomb's mu lambda opposing the
 * slip once it exceeds eps_v and a stiff spring below (static friction).
 * In u, the Hessian is mu lambda [(f1/y) I + (f1' - f1/y) ^u ^u^T]:
 *     y < eps_v:  mu lambda [(2/eps_v - y/eps_v^2) I - (y/eps_v^2) ^u ^u^T]
 *     y >= eps_v: mu lambda / y (I - ^u ^u^T)
 * both PSD (eigenvalues >= 0 for y <= eps_v), so no eigensolve is needed;
 * the 3x3 Hessian is T H_u T^T.
 *
 * Lagging lambda and T makes friction a potential within the step (IPC's
 * lagged iteration with one outer pass). Left out: cloth-cloth friction,
 * re-lagging within a step.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cr_friction {
    int32_t nv;       /* V */
    double mu;        /* Coulomb coefficient */
    double eps_v;     /* m */
    int32_t ncontact; /* C: contacts frozen at the last update */
    int32_t *vert;    /* (C) vertex of each contact (room for V) */
    double *lambda;   /* (C) normal force, N */
    double *basis;    /* (C,6) tangents t1, t2 */
    double *anchor;   /* (C,3) m */
};

cr_status cr_friction_create(int32_t nv, const cr_material *mat, double eps_v, cr_friction **out,
                             cr_error *err) {
    CR_ASSERT(mat && out && nv >= 0);
    CR_ASSERT(mat->cookie == CR_MATERIAL_COOKIE);
    *out = NULL;
    if (!(eps_v > 0.0) || !isfinite(eps_v))
        return CR_FAIL(err, CR_ERR_INVALID, "friction: eps_v = %g must be a positive slip in m",
                       eps_v);
    cr_friction *f = cr_calloc(1, sizeof *f, err);
    if (!f) return err ? err->status : CR_ERR_MEMORY;
    const size_t n = (size_t)(nv > 0 ? nv : 1);
    f->nv = nv;
    f->mu = mat->friction;
    f->eps_v = eps_v;
    f->vert = cr_malloc(sizeof(int32_t) * n, err);
    f->lambda = cr_malloc(sizeof(double) * n, err);
    f->basis = cr_malloc(sizeof(double) * 6 * n, err);
    f->anchor = cr_malloc(sizeof(double) * 3 * n, err);
    if (!f->vert || !f->lambda || !f->basis || !f->anchor) {
        cr_friction_destroy(f);
        return err ? err->status : CR_ERR_MEMORY;
    }
    *out = f;
    return CR_OK;
}

void cr_friction_destroy(cr_friction *f) {
    if (!f) return;
    free(f->vert);
    free(f->lambda);
    free(f->basis);
    free(f->anchor);
    free(f);
}

/* Orthonormal t1, t2 with (t1, t2, n) right-handed; n unit. */
static void tangent_basis(const double *n, double *t) {
    /* Cross with the axis least aligned with n, so the product is not tiny. */
    const double ax[3] = {fabs(n[0]) < 0.9 ? 1.0 : 0.0, fabs(n[0]) < 0.9 ? 0.0 : 1.0, 0.0};
    double t1[3] = {ax[1] * n[2] - ax[2] * n[1], ax[2] * n[0] - ax[0] * n[2],
                    ax[0] * n[1] - ax[1] * n[0]};
    const double l = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    for (int d = 0; d < 3; d++)
        t[d] = t1[d] / l;
    t[3] = n[1] * t[2] - n[2] * t[1];
    t[4] = n[2] * t[0] - n[0] * t[2];
    t[5] = n[0] * t[1] - n[1] * t[0];
}

void cr_friction_update(cr_friction *f, const cr_collision *c, const double *x_start,
                        const double *collider_disp) {
    CR_ASSERT(f && c && x_start);
    int32_t nc = 0;
    for (int32_t i = 0; i < f->nv; i++) {
        double n[3], force = 0.0;
        if (!cr_collision_contact(c, i, n, &force)) continue;
        const double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(nn > 0.5) || !(force > 0.0) || f->mu == 0.0) continue;
        for (int d = 0; d < 3; d++)
            n[d] /= nn;
        f->vert[nc] = i;
        f->lambda[nc] = force;
        tangent_basis(n, f->basis + 6 * (int64_t)nc);
        for (int d = 0; d < 3; d++)
            f->anchor[3 * (int64_t)nc + d] =
                x_start[3 * (int64_t)i + d] +
                (collider_disp ? collider_disp[3 * (int64_t)i + d] : 0.0);
        nc++;
    }
    f->ncontact = nc;
}

int32_t cr_friction_contact_count(const cr_friction *f) {
    return f->ncontact;
}

static double friction_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_friction *f = data;
    const double *t = f->basis + 6 * (int64_t)e, *a = f->anchor + 3 * (int64_t)e;
    const double r[3] = {xe[0] - a[0], xe[1] - a[1], xe[2] - a[2]};
    const double u[2] = {t[0] * r[0] + t[1] * r[1] + t[2] * r[2],
                         t[3] * r[0] + t[4] * r[1] + t[5] * r[2]};
    const double y = sqrt(u[0] * u[0] + u[1] * u[1]);
    const double ev = f->eps_v, s = f->mu * f->lambda[e];
    const int smooth = y < ev;
    const double f0 = smooth ? -y * y * y / (3.0 * ev * ev) + y * y / ev + ev / 3.0 : y;
    if (g) {
        /* f1(y)/y, finite at y = 0. */
        const double w = s * (smooth ? 2.0 / ev - y / (ev * ev) : 1.0 / y);
        for (int d = 0; d < 3; d++)
            g[d] = w * (u[0] * t[d] + u[1] * t[3 + d]);
    }
    if (H) {
        double Hu[4];
        if (smooth) {
            const double diag = 2.0 / ev - y / (ev * ev);
            const double k = y > 0.0 ? 1.0 / (ev * ev * y) : 0.0; /* (y/eps^2) ^u ^u^T = k u u^T */
            Hu[0] = s * (diag - k * u[0] * u[0]);
            Hu[1] = Hu[2] = -s * k * u[0] * u[1];
            Hu[3] = s * (diag - k * u[1] * u[1]);
        } else {
            const double k = 1.0 / (y * y * y);
            Hu[0] = s * (1.0 / y - k * u[0] * u[0]);
            Hu[1] = Hu[2] = -s * k * u[0] * u[1];
            Hu[3] = s * (1.0 / y - k * u[1] * u[1]);
        }
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++)
                H[3 * p + q] = Hu[0] * t[p] * t[q] + Hu[1] * (t[p] * t[3 + q] + t[3 + p] * t[q]) +
                               Hu[3] * t[3 + p] * t[3 + q];
    }
    return s * f0;
}

void cr_friction_term(const cr_friction *f, cr_energy_term *out) {
    CR_ASSERT(f && out);
    memset(out, 0, sizeof *out);
    out->name = "friction";
    out->nelem = f->ncontact;
    out->nvert = 1;
    out->elem = f->vert;
    out->kernel = friction_kernel;
    out->data = f;
    out->weight = 1.0;
}
