/* bending.c: discrete-shell bending energy on the hinges of a mesh.
 *
 * Per interior hinge h (edge x0-x1 shared by faces A and B; topology.h):
 *     E_h = k_e/2 (theta - theta_rest)^2,   k_e = k_b l^2 / (4 (A1 + A2))
 * with l the rest edge length and A1, A2 the rest face areas: the HOOD/SNUG
 * form (Grigorev et al. 2023; Santesteban et al. 2022), which equals ARCSim's
 * k_b l^2/(8 (A1 + A2)) (theta - theta_rest)^2 (Narain et al. 2012) and is
 * Grinspun et al. 2003's discrete shell up to the constant in front.
 * theta - theta_rest is wrapped into (-pi, pi] so a hinge whose angle passes
 * through +-pi sees a continuous energy.
 *
 * Hessian: k_e (grad theta grad theta^T + (theta - theta_rest) Hess theta),
 * the exact Hessian of theta from dihedral64.c. CR_HESSIAN_PROJECTED clamps
 * its negative eigenvalues in the 9-dimensional edge-relative coordinates
 * (PSD there exactly when PSD in the 12 positions; Tamstorf & Grinspun 2013
 * project the same matrix). CR_HESSIAN_GAUSS_NEWTON, the default, keeps only
 * the first, rank-one term, PSD by construction and without an eigensolve:
 * ARCSim's choice (Narain et al. 2012), and about 20x cheaper than the 9x9
 * eigensolve per hinge (docs/physics.md has the timings).
 *
 * Left out: curvature-dependent stiffness (ARCSim's tables), anisotropy, and
 * plasticity, which the simulator applies by writing the rest angles.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "phys/dihedral64.h"

struct cr_bending {
    int32_t nh;     /* H */
    int32_t *hinge; /* (H,4) x0, x1, x2, x3 */
    double *ke;     /* (H) k_b l^2 / (4 (A1 + A2)), J/rad^2 */
    double *rest;   /* (H) theta_rest, rad */
    cr_hessian_mode mode;
};

static double tri_area(const double *p, const double *q, const double *r) {
    const double a[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    const double b[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    const double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]};
    return 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

static void gather(const float *pos, const int32_t *idx, int n, double *x) {
    for (int k = 0; k < n; k++)
        for (int d = 0; d < 3; d++)
            x[3 * k + d] = pos[3 * (int64_t)idx[k] + d];
}

cr_status cr_bending_create(const cr_mesh *rest, const cr_topology *t, const cr_material *mat,
                            int rest_angles_from_mesh, cr_bending **out, cr_error *err) {
    CR_ASSERT(rest && t && mat && out);
    CR_ASSERT(mat->cookie == CR_MATERIAL_COOKIE);
    *out = NULL;
    if (t->nv != rest->nv || t->nf != rest->nf)
        return CR_FAIL(err, CR_ERR_SHAPE,
                       "bending: topology built for %d vertices, %d faces; mesh has %d, %d", t->nv,
                       t->nf, rest->nv, rest->nf);
    cr_bending *b = cr_calloc(1, sizeof *b, err);
    if (!b) return err ? err->status : CR_ERR_MEMORY;
    const int32_t H = t->nh;
    b->nh = H;
    b->mode = CR_HESSIAN_GAUSS_NEWTON;
    b->hinge = cr_malloc(sizeof(int32_t) * 4 * (size_t)(H > 0 ? H : 1), err);
    b->ke = cr_malloc(sizeof(double) * (size_t)(H > 0 ? H : 1), err);
    b->rest = cr_malloc(sizeof(double) * (size_t)(H > 0 ? H : 1), err);
    if (!b->hinge || !b->ke || !b->rest) {
        cr_bending_destroy(b);
        return err ? err->status : CR_ERR_MEMORY;
    }
    if (H > 0) memcpy(b->hinge, t->hinge, sizeof(int32_t) * 4 * (size_t)H);
    for (int32_t h = 0; h < H; h++) {
        double x[12];
        gather(rest->pos, b->hinge + 4 * (int64_t)h, 4, x);
        const double e[3] = {x[3] - x[0], x[4] - x[1], x[5] - x[2]};
        const double l2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
        const double area = tri_area(x, x + 3, x + 6) + tri_area(x + 3, x, x + 9);
        /* A hinge with zero rest area has no defined stiffness: it is given
         * none rather than an infinite one. */
        b->ke[h] = area > 0.0 ? mat->bending * l2 / (4.0 * area) : 0.0;
        b->rest[h] = rest_angles_from_mesh ? cr_dihedral64_angle(x) : 0.0;
    }
    *out = b;
    return CR_OK;
}

void cr_bending_destroy(cr_bending *b) {
    if (!b) return;
    free(b->hinge);
    free(b->ke);
    free(b->rest);
    free(b);
}

void cr_bending_set_hessian(cr_bending *b, cr_hessian_mode mode) {
    CR_ASSERT(b && (mode == CR_HESSIAN_PROJECTED || mode == CR_HESSIAN_GAUSS_NEWTON));
    b->mode = mode;
}

int32_t cr_bending_count(const cr_bending *b) {
    return b->nh;
}
const int32_t *cr_bending_hinges(const cr_bending *b) {
    return b->hinge;
}
const double *cr_bending_stiffness(const cr_bending *b) {
    return b->ke;
}
double *cr_bending_rest_angles(cr_bending *b) {
    return b->rest;
}

void cr_bending_angles(const cr_bending *b, const double *x, double *theta) {
    for (int32_t h = 0; h < b->nh; h++) {
        double xe[12];
        const int32_t *idx = b->hinge + 4 * (int64_t)h;
        for (int k = 0; k < 4; k++)
            for (int d = 0; d < 3; d++)
                xe[3 * k + d] = x[3 * (int64_t)idx[k] + d];
        theta[h] = cr_dihedral64_angle(xe);
    }
}

/* theta - theta_rest wrapped into (-pi, pi]. */
static double wrap_angle(double d) {
    if (d > -M_PI && d <= M_PI) return d; /* what remainder() returns, at a tenth of its cost */
    d = remainder(d, 2.0 * M_PI);         /* [-pi, pi] */
    return d <= -M_PI ? d + 2.0 * M_PI : d;
}

double cr_bending_kernel_rest(const cr_bending *b, int32_t h, double theta_rest, const double *xe,
                              double *g, double *H, double *g_rest) {
    const double ke = b->ke[h];
    if (!g && !H) {
        const double d = wrap_angle(cr_dihedral64_angle(xe) - theta_rest);
        if (g_rest) *g_rest = -ke * d;
        return 0.5 * ke * d * d;
    }
    double gy[9], Hy[81];
    int ok = 0;
    const int exact = H && b->mode == CR_HESSIAN_PROJECTED;
    const double theta = cr_dihedral64_derivs_y(xe, gy, exact ? Hy : NULL, &ok);
    const double d = wrap_angle(theta - theta_rest);
    if (g_rest) *g_rest = -ke * d; /* the wrap is locally the identity */
    if (g) {
        double gx[12];
        cr_dihedral64_grad_x(gy, gx);
        for (int k = 0; k < 12; k++)
            g[k] = ke * d * gx[k];
    }
    if (H) {
        /* In y: k_e (gy gy^T + d Hy), or its Gauss-Newton part alone. */
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                Hy[9 * i + j] = ke * (gy[i] * gy[j] + (exact ? d * Hy[9 * i + j] : 0.0));
        if (exact && ok) cr_psd_project(Hy, 9);
        cr_dihedral64_hess_x(Hy, H);
    }
    return 0.5 * ke * d * d;
}

double cr_bending_residual(const cr_bending *b, int32_t h, double theta_rest, const double *xe,
                           double *g) {
    (void)b, (void)h;
    if (!g) return wrap_angle(cr_dihedral64_angle(xe) - theta_rest);
    double gy[9];
    int ok = 0;
    const double theta = cr_dihedral64_derivs_y(xe, gy, NULL, &ok);
    cr_dihedral64_grad_x(gy, g); /* zero on a degenerate hinge */
    return wrap_angle(theta - theta_rest);
}

static double bending_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_bending *b = data;
    return cr_bending_kernel_rest(b, e, b->rest[e], xe, g, H, NULL);
}

/* Vertex k's block: with the Gauss-Newton Hessian k_e gx gx^T its (k,k)
 * block is k_e gx_k gx_k^T, so neither the 9x9 in y nor the 12x12 in x is
 * formed; the projected Hessian still needs the 9x9 and its eigensolve. */
static double bending_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                             double *H) {
    const cr_bending *b = data;
    const double ke = b->ke[e];
    if (!g && !H) return cr_bending_kernel_rest(b, e, b->rest[e], xe, NULL, NULL, NULL);
    if (H && b->mode == CR_HESSIAN_PROJECTED) {
        double gy[9], Hy[81], gx[12];
        int ok = 0;
        const double d = wrap_angle(cr_dihedral64_derivs_y(xe, gy, Hy, &ok) - b->rest[e]);
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++)
                Hy[9 * i + j] = ke * (gy[i] * gy[j] + d * Hy[9 * i + j]);
        if (ok) cr_psd_project(Hy, 9);
        cr_dihedral64_hess_x_block(Hy, k, H);
        if (g) {
            cr_dihedral64_grad_x(gy, gx);
            for (int r = 0; r < 3; r++)
                g[r] = ke * d * gx[3 * k + r];
        }
        return 0.5 * ke * d * d;
    }
    double gk[3];
    int ok = 0;
    const double d = wrap_angle(cr_dihedral64_vertex_grad_inline(xe, k, gk, &ok) - b->rest[e]);
    if (g)
        for (int r = 0; r < 3; r++)
            g[r] = ke * d * gk[r];
    if (H)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                H[3 * r + c] = ke * gk[r] * gk[c];
    return 0.5 * ke * d * d;
}

void cr_bending_term(const cr_bending *b, cr_energy_term *out) {
    CR_ASSERT(b && out);
    memset(out, 0, sizeof *out);
    out->name = "bending";
    out->nelem = b->nh;
    out->nvert = 4;
    out->elem = b->hinge;
    out->kernel = bending_kernel;
    out->vertex_block = bending_vertex;
    out->data = b;
    out->weight = 1.0;
}
