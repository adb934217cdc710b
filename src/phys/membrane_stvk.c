/* membrane_stvk.c: the membrane energy's rest shape, its term, and the
 * St. Venant-Kirchhoff kernel.
 *
 * Per triangle, with F = Ds Dm^-1 (3x2) and the Green strain
 * E = (F^T F - I)/2 (2x2),
 *     E_tri = A0 psi(F),   psi = mu |E|_F^2 + lambda/2 tr(E)^2,
 * mu and lambda per rest area with the thickness folded in (Santesteban et al.
 * 2022 (SNUG), Grigorev et al. 2023 (HOOD); the constitutive model of
 * Volino et al. 2009, "A simple approach to nonlinear tensile stiffness for
 * accurate cloth simulation"). Writing a = f0.f0, b = f1.f1, c = f0.f1,
 *     psi = mu ((a-1)^2/4 + (b-1)^2/4 + c^2/2) + lambda/8 (a + b - 2)^2,
 * its gradient is P = F S with the second Piola-Kirchhoff stress
 * S = 2 mu E + lambda tr(E) I, and its Hessian in F is a Gauss-Newton part
 * (PSD: psi is a PSD quadratic of (a, b, c)) plus S (x) I3, so it is PSD
 * whenever S is; only then is the eigensolve skipped.
 *
 * The rest shape is the 3-D rest triangle laid flat in its own plane (first
 * edge along the local u axis) or the triangle's UVs times a scale.
 * Left out: anisotropy, strain limiting, damping.
 */
#include "phys/membrane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

cr_status cr_membrane_create(const cr_mesh *rest, int use_uv_rest, float uv_scale,
                             const cr_material *mat, cr_membrane **out, cr_error *err) {
    CR_ASSERT(rest && mat && out);
    CR_ASSERT(mat->cookie == CR_MATERIAL_COOKIE);
    *out = NULL;
    if (use_uv_rest && !cr_mesh_has_uv(rest))
        return CR_FAIL(err, CR_ERR_INVALID, "membrane: rest shape from UVs, but the mesh has none");
    if (use_uv_rest && !(uv_scale > 0.0f && isfinite(uv_scale)))
        return CR_FAIL(err, CR_ERR_INVALID, "membrane: uv_scale = %g must be positive",
                       (double)uv_scale);
    cr_membrane *m = cr_calloc(1, sizeof *m, err);
    if (!m) return err ? err->status : CR_ERR_MEMORY;
    const int32_t F = rest->nf;
    const size_t nalloc = (size_t)(F > 0 ? F : 1);
    m->nf = F;
    m->model = mat->membrane;
    m->mu = mat->lame_mu;
    m->lambda = mat->lame_lambda;
    m->k_stretch = mat->bw_stretch;
    m->k_shear = mat->bw_shear;
    m->mode = CR_HESSIAN_PROJECTED;
    m->tri = cr_malloc(sizeof(int32_t) * 3 * nalloc, err);
    m->dminv = cr_malloc(sizeof(double) * 4 * nalloc, err);
    m->area = cr_malloc(sizeof(double) * nalloc, err);
    if (!m->tri || !m->dminv || !m->area) {
        cr_membrane_destroy(m);
        return err ? err->status : CR_ERR_MEMORY;
    }
    if (F > 0) memcpy(m->tri, rest->tri, sizeof(int32_t) * 3 * (size_t)F);
    for (int32_t f = 0; f < F; f++) {
        double D[4]; /* Dm, row-major 2x2: columns are the two rest edges in 2-D */
        if (use_uv_rest) {
            const float *u0 = rest->uv + 2 * (int64_t)rest->tri_uv[3 * f];
            const float *u1 = rest->uv + 2 * (int64_t)rest->tri_uv[3 * f + 1];
            const float *u2 = rest->uv + 2 * (int64_t)rest->tri_uv[3 * f + 2];
            D[0] = ((double)u1[0] - u0[0]) * uv_scale, D[1] = ((double)u2[0] - u0[0]) * uv_scale;
            D[2] = ((double)u1[1] - u0[1]) * uv_scale, D[3] = ((double)u2[1] - u0[1]) * uv_scale;
        } else {
            const float *p0 = rest->pos + 3 * (int64_t)rest->tri[3 * f];
            const float *p1 = rest->pos + 3 * (int64_t)rest->tri[3 * f + 1];
            const float *p2 = rest->pos + 3 * (int64_t)rest->tri[3 * f + 2];
            double t1[3], t2[3];
            for (int d = 0; d < 3; d++)
                t1[d] = (double)p1[d] - p0[d], t2[d] = (double)p2[d] - p0[d];
            const double l1 = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
            const double along =
                l1 > 0.0 ? (t1[0] * t2[0] + t1[1] * t2[1] + t1[2] * t2[2]) / l1 : 0.0;
            const double t22 = t2[0] * t2[0] + t2[1] * t2[1] + t2[2] * t2[2];
            const double across = sqrt(fmax(t22 - along * along, 0.0));
            D[0] = l1, D[1] = along, D[2] = 0.0, D[3] = across;
        }
        const double det = D[0] * D[3] - D[1] * D[2];
        const double scale = fmax(fabs(D[0]) + fabs(D[2]), fabs(D[1]) + fabs(D[3]));
        if (!(fabs(det) > 1e-12 * scale * scale)) {
            cr_membrane_destroy(m);
            return CR_FAIL(err, CR_ERR_TOPOLOGY,
                           "membrane: triangle %d has a degenerate rest shape (%s area %g m^2)", f,
                           use_uv_rest ? "UV" : "3-D", 0.5 * fabs(det));
        }
        double *Di = m->dminv + 4 * (int64_t)f;
        Di[0] = D[3] / det, Di[1] = -D[1] / det, Di[2] = -D[2] / det, Di[3] = D[0] / det;
        m->area[f] = 0.5 * fabs(det);
    }
    *out = m;
    return CR_OK;
}

void cr_membrane_destroy(cr_membrane *m) {
    if (!m) return;
    free(m->tri);
    free(m->dminv);
    free(m->area);
    free(m);
}

void cr_membrane_set_hessian(cr_membrane *m, cr_hessian_mode mode) {
    CR_ASSERT(m && (mode == CR_HESSIAN_PROJECTED || mode == CR_HESSIAN_GAUSS_NEWTON));
    m->mode = mode;
}

const double *cr_membrane_rest_areas(const cr_membrane *m) {
    return m->area;
}

const double *cr_membrane_rest_dminv(const cr_membrane *m) {
    return m->dminv;
}

void cr_membrane_term(const cr_membrane *m, cr_energy_term *out) {
    cr_membrane_term_part(m, CR_MEMBRANE_ALL, out);
}

void cr_membrane_term_part(const cr_membrane *m, cr_membrane_part part, cr_energy_term *out) {
    CR_ASSERT(m && out);
    CR_ASSERT(part == CR_MEMBRANE_ALL || part == CR_MEMBRANE_STRETCH || part == CR_MEMBRANE_SHEAR);
    static const cr_energy_kernel kernels[2][3] = {
        {cr_membrane_stvk_kernel, cr_membrane_stvk_stretch_kernel, cr_membrane_stvk_shear_kernel},
        {cr_membrane_bw_kernel, cr_membrane_bw_stretch_kernel, cr_membrane_bw_shear_kernel}};
    static const cr_energy_vertex_kernel blocks[2][3] = {
        {cr_membrane_stvk_vertex, cr_membrane_stvk_stretch_vertex, cr_membrane_stvk_shear_vertex},
        {cr_membrane_bw_vertex, cr_membrane_bw_stretch_vertex, cr_membrane_bw_shear_vertex}};
    static const char *const names[3] = {"membrane", "membrane_stretch", "membrane_shear"};
    memset(out, 0, sizeof *out);
    out->name = names[part];
    out->nelem = m->nf;
    out->nvert = 3;
    out->elem = m->tri;
    out->kernel = kernels[m->model == CR_MEMBRANE_STVK ? 0 : 1][part];
    out->vertex_block = blocks[m->model == CR_MEMBRANE_STVK ? 0 : 1][part];
    out->data = m;
    out->weight = 1.0;
}

/* Clamp the symmetric 2x2 [[a, b], [b, c]] (m[0], m[1], m[2]) to PSD. */
static void project2(double *m) {
    const double a = m[0], b = m[1], c = m[2];
    if (a >= 0.0 && c >= 0.0 && a * c >= b * b) return; /* PSD: no square root */
    const double mean = 0.5 * (a + c), r = sqrt(0.25 * (a - c) * (a - c) + b * b);
    const double l1 = mean + r, l2 = mean - r;
    if (l2 >= 0.0) return;
    if (l1 <= 0.0) {
        m[0] = m[1] = m[2] = 0.0;
        return;
    }
    /* Keep l1 v v^T; of the two expressions for v take the longer. */
    double v0 = b, v1 = l1 - a;
    if ((l1 - c) * (l1 - c) + b * b > v0 * v0 + v1 * v1) v0 = l1 - c, v1 = b;
    const double s = l1 / (v0 * v0 + v1 * v1);
    m[0] = s * v0 * v0, m[1] = s * v0 * v1, m[2] = s * v1 * v1;
}

/* The in-plane 4x4 of StVK's Hessian in F, eigen-clamped in closed form.
 * In the frame (p1, p2) of cr_membrane_project_hf, F's in-plane part is
 * M = [[a, b], [0, d]] (a = |f0|, d > 0: never inverted). StVK is
 * isotropic, so with M = U diag(s1, s2) V^T its Hessian's eigenvectors are
 * known (Smith, De Goes & Kim 2019, "Analytic eigensystems for isotropic
 * distortion energies", 2-D case): twist (u2 v1^T - u1 v2^T)/sqrt2 with
 * eigenvalue (psi_1 + psi_2)/(s1 + s2), flip (u1 v2^T + u2 v1^T)/sqrt2 with
 * (psi_1 - psi_2)/(s1 - s2), and the scaling modes u_p v_p^T mixed by the
 * 2x2 Hessian of psi(s1, s2). For
 *     psi = mu/4 ((s1^2 - 1)^2 + (s2^2 - 1)^2) + lambda/8 (s1^2 + s2^2 - 2)^2
 * these are mu (s1^2 -+ s1 s2 + s2^2 - 1) + lambda/2 (s1^2 + s2^2 - 2), both
 * without a division, and psi_pp = mu (3 s_p^2 - 1) + lambda/2 (s1^2 + s2^2 - 2)
 * + lambda s_p^2, psi_12 = lambda s1 s2. The same matrix as cr_psd_project
 * of the rotated block, to roundoff (tested), at a fraction of a Jacobi
 * eigensolve. A: (4x4, index 2j + component) as in cr_membrane_project_hf. */
typedef struct stvk_modes {
    double s1, s2;         /* singular values of M, s1 >= s2 >= 0 */
    double vc, vs;         /* v1 = (vc, vs), v2 = (-vs, vc) */
    double lt, lf, hs[3];  /* twist and flip eigenvalues, scaling 2x2; all clamped */
} stvk_modes;

/* The eigensystem of StVK's in-plane Hessian, clamped, from M's Gram matrix
 * M^T M = [[g00, g01], [g01, g11]] (= F^T F) and det M = jac > 0: what the
 * whole kernel and the vertex block share. */
static void stvk_modes_from_gram(double mu, double lambda, double g00, double g01, double g11,
                                 double jac, stvk_modes *o) {
    /* V from the eigenvectors of M^T M. */
    const double x = g00 - g11, y = 2.0 * g01, r = sqrt(x * x + y * y);
    const double s1 = sqrt(0.5 * (g00 + g11 + r)), s2 = jac / s1;
    double c = 1.0, sn = 0.0; /* v1 = (c, sn) at angle atan2(y, x)/2 */
    if (r > 0.0) {
        if (x >= 0.0) {
            c = sqrt(0.5 * (1.0 + x / r));
            sn = y / (2.0 * r * c);
        } else {
            sn = copysign(sqrt(0.5 * (1.0 - x / r)), y);
            c = y / (2.0 * r * sn);
        }
    }
    const double i2 = s1 * s1 + s2 * s2 - 2.0;
    const double lt = mu * (s1 * s1 - s1 * s2 + s2 * s2 - 1.0) + 0.5 * lambda * i2;
    const double lf = mu * (s1 * s1 + s1 * s2 + s2 * s2 - 1.0) + 0.5 * lambda * i2;
    o->hs[0] = mu * (3.0 * s1 * s1 - 1.0) + 0.5 * lambda * i2 + lambda * s1 * s1;
    o->hs[1] = lambda * s1 * s2;
    o->hs[2] = mu * (3.0 * s2 * s2 - 1.0) + 0.5 * lambda * i2 + lambda * s2 * s2;
    o->lt = lt > 0.0 ? lt : 0.0, o->lf = lf > 0.0 ? lf : 0.0; /* fmax(., 0) without the call */
    project2(o->hs);
    o->s1 = s1, o->s2 = s2, o->vc = c, o->vs = sn;
}

static void stvk_inplane_projected(double mu, double lambda, double a, double b, double d,
                                   double *A) {
    stvk_modes md;
    stvk_modes_from_gram(mu, lambda, a * a, a * b, b * b + d * d, a * d, &md);
    const double s1 = md.s1, c = md.vc, sn = md.vs, lt = md.lt, lf = md.lf;
    const double *hs = md.hs;
    const double v1[2] = {c, sn}, v2[2] = {-sn, c};
    /* u1 = M v1 / s1; u2 = its perpendicular (det U = det M / det V > 0). */
    double u1[2] = {(a * c + b * sn) / s1, d * sn / s1};
    const double un = sqrt(u1[0] * u1[0] + u1[1] * u1[1]);
    u1[0] /= un, u1[1] /= un;
    const double u2[2] = {-u1[1], u1[0]};
    /* Modes as vec(D), D[comp][col] at index 2 col + comp. */
    double w1[4], w2[4], wt[4], wf[4];
    for (int j = 0; j < 2; j++)
        for (int q = 0; q < 2; q++) {
            const int i = 2 * j + q;
            w1[i] = u1[q] * v1[j];
            w2[i] = u2[q] * v2[j];
            wt[i] = M_SQRT1_2 * (u2[q] * v1[j] - u1[q] * v2[j]);
            wf[i] = M_SQRT1_2 * (u1[q] * v2[j] + u2[q] * v1[j]);
        }
    for (int i = 0; i < 4; i++)
        for (int k = i; k < 4; k++) {
            const double v = hs[0] * w1[i] * w1[k] + hs[1] * (w1[i] * w2[k] + w2[i] * w1[k]) +
                             hs[2] * w2[i] * w2[k] + lt * wt[i] * wt[k] + lf * wf[i] * wf[k];
            A[4 * i + k] = A[4 * k + i] = v;
        }
}

/* Vertex k's (k,k) block of the projected StVK Hessian (the whole density,
 * stress not PSD), straight from f0, f1 without the in-plane 4x4: with
 * (c0, c1) = vertex k's coefficients, alpha = (c0, c1).v1, beta = (c0, c1).v2,
 * the modes contract to alpha u1, beta u2, (alpha u2 - beta u1)/sqrt2 and
 * (beta u1 + alpha u2)/sqrt2, so the
 * in-plane part is Y00 r1 r1^T + Y01 (r1 r2^T + r2 r1^T) + Y11 r2 r2^T with
 * r1 = F v1/|F v1|, r2 = n x r1 (the 3-D images of u1, u2), plus the normal
 * part (c0, c1) N (c0, c1)^T n n^T. The same matrix as the (k,k) block of
 * the whole kernel's (stvk_inplane_projected, hf_from_frame), to roundoff (tested: phys_energy.vertex_blocks).
 * 0 when f0, f1 do not span a plane (plane_frame's test). */
static int stvk_block_projected(double mu, double lambda, const double *f, double g00, double g01,
                                double g11, const double *N, double c0, double c1, double area,
                                double *H) {
    const double *f0 = f, *f1 = f + 3;
    double n[3] = {f0[1] * f1[2] - f0[2] * f1[1], f0[2] * f1[0] - f0[0] * f1[2],
                   f0[0] * f1[1] - f0[1] * f1[0]};
    const double n2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (!(g00 > 0.0) || !(n2 > 1e-16 * g00 * g11)) return 0;
    const double jac = sqrt(n2);
    for (int p = 0; p < 3; p++)
        n[p] /= jac;
    stvk_modes md;
    stvk_modes_from_gram(mu, lambda, g00, g01, g11, jac, &md);
    double r1[3];
    for (int p = 0; p < 3; p++)
        r1[p] = md.vc * f0[p] + md.vs * f1[p];
    const double rl = 1.0 / sqrt(r1[0] * r1[0] + r1[1] * r1[1] + r1[2] * r1[2]);
    for (int p = 0; p < 3; p++)
        r1[p] *= rl;
    const double r2[3] = {n[1] * r1[2] - n[2] * r1[1], n[2] * r1[0] - n[0] * r1[2],
                          n[0] * r1[1] - n[1] * r1[0]};
    const double al = c0 * md.vc + c1 * md.vs, be = c1 * md.vc - c0 * md.vs;
    const double ltf = 0.5 * (md.lt + md.lf);
    const double y00 = md.hs[0] * al * al + ltf * be * be;
    const double y01 = al * be * (md.hs[1] + 0.5 * (md.lf - md.lt));
    const double y11 = md.hs[2] * be * be + ltf * al * al;
    const double xn = c0 * c0 * N[0] + 2.0 * c0 * c1 * N[1] + c1 * c1 * N[2];
    for (int p = 0; p < 3; p++)
        for (int q = p; q < 3; q++) {
            const double v = y00 * r1[p] * r1[q] + y01 * (r1[p] * r2[q] + r2[p] * r1[q]) +
                             y11 * r2[p] * r2[q] + xn * n[p] * n[q];
            H[3 * p + q] = H[3 * q + p] = area * v;
        }
    return 1;
}

/* n^T M n for the 3x3 block M of HF at block (j, l). */
static double normal_form(const double *n, const double *HF, int j, int l) {
    double s = 0.0;
    for (int p = 0; p < 3; p++) {
        const double *m = HF + 6 * (3 * j + p) + 3 * l;
        s += n[p] * (m[0] * n[0] + m[1] * n[1] + m[2] * n[2]);
    }
    return s;
}

/* B = R^T M R for the 3x3 block M of HF at block (j, l) (row stride 6). */
static void rotate_in(const double *R, const double *HF, int j, int l, double *B) {
    double T[9];
    for (int p = 0; p < 3; p++)
        for (int b = 0; b < 3; b++) {
            const double *m = HF + 6 * (3 * j + p) + 3 * l;
            T[3 * p + b] = m[0] * R[b] + m[1] * R[3 + b] + m[2] * R[6 + b];
        }
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            B[3 * a + b] = R[a] * T[b] + R[3 + a] * T[3 + b] + R[6 + a] * T[6 + b];
}

/* The frame of f = (f0, f1): R[3d + k] is component d of basis vector
 * k = p1 = f0/|f0|, p2 (f1 orthogonalised), n = p1 x p2, and F's in-plane
 * part is [[a, b], [0, d]]. 0 when f0, f1 do not span a plane. */
static int plane_frame(const double *f, double *R, double *a, double *b, double *d) {
    const double *f0 = f, *f1 = f + 3;
    const double n0 = sqrt(f0[0] * f0[0] + f0[1] * f0[1] + f0[2] * f0[2]);
    const double n1 = sqrt(f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2]);
    double r[3], nr = 0.0, along = 0.0;
    if (n0 > 0.0) {
        along = (f1[0] * f0[0] + f1[1] * f0[1] + f1[2] * f0[2]) / (n0 * n0);
        for (int k = 0; k < 3; k++)
            r[k] = f1[k] - along * f0[k];
        nr = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    }
    if (!(nr > 1e-8 * n1) || !(n0 > 0.0)) return 0;
    for (int k = 0; k < 3; k++)
        R[3 * k] = f0[k] / n0, R[3 * k + 1] = r[k] / nr;
    R[2] = R[3] * R[7] - R[6] * R[4];
    R[5] = R[6] * R[1] - R[0] * R[7];
    R[8] = R[0] * R[4] - R[3] * R[1];
    *a = n0, *b = along * n0, *d = nr;
    return 1;
}

/* HF from the rotated frame: HF_jl = R B_jl R^T with B_jl = [[A_jl, 0],
 * [0, N_jl]] (A the in-plane 4x4, index 2j + a; N the normal 2x2 as
 * (N00, N01, N11)): the in-plane/normal coupling is zero in exact arithmetic. */
static void hf_from_frame(const double *R, const double *A, const double *N, double *HF) {
    for (int j = 0; j < 2; j++)
        for (int l = j; l < 2; l++) {
            const double nn = N[j + l];
            const double *a0 = A + 4 * (2 * j) + 2 * l, *a1 = A + 4 * (2 * j + 1) + 2 * l;
            double T[9]; /* B_jl R^T */
            for (int q = 0; q < 3; q++) {
                T[q] = a0[0] * R[3 * q] + a0[1] * R[3 * q + 1];
                T[3 + q] = a1[0] * R[3 * q] + a1[1] * R[3 * q + 1];
                T[6 + q] = nn * R[3 * q + 2];
            }
            for (int p = 0; p < 3; p++)
                for (int q = 0; q < 3; q++) {
                    const double v =
                        R[3 * p] * T[q] + R[3 * p + 1] * T[3 + q] + R[3 * p + 2] * T[6 + q];
                    HF[6 * (3 * j + p) + 3 * l + q] = v;
                    if (j != l) HF[6 * (3 * l + q) + 3 * j + p] = v;
                }
            if (j == l) /* symmetric in exact arithmetic: keep it so in floats */
                for (int p = 0; p < 3; p++)
                    for (int q = p + 1; q < 3; q++) {
                        double *hpq = HF + 6 * (3 * j + p) + 3 * l + q;
                        double *hqp = HF + 6 * (3 * j + q) + 3 * l + p;
                        *hpq = *hqp = 0.5 * (*hpq + *hqp);
                    }
        }
}

void cr_membrane_project_hf(const double *f, double *HF) {
    double R[9], a, b, d;
    if (!plane_frame(f, R, &a, &b, &d)) {
        cr_psd_project(HF, 6);
        return;
    }
    const double nrm[3] = {R[2], R[5], R[8]};
    /* The blocks in the rotated frame B_jl = R^T HF_jl R (HF symmetric:
     * B_10 = B_01^T): A their in-plane 4x4, N their normal 2x2. */
    double A[16], N[3] = {normal_form(nrm, HF, 0, 0), normal_form(nrm, HF, 0, 1),
                          normal_form(nrm, HF, 1, 1)};
    double B00[9], B01[9], B11[9];
    rotate_in(R, HF, 0, 0, B00);
    rotate_in(R, HF, 0, 1, B01);
    rotate_in(R, HF, 1, 1, B11);
    const double *Bj[2][2] = {{B00, B01}, {NULL, B11}};
    for (int j = 0; j < 2; j++)
        for (int l = j; l < 2; l++)
            for (int p = 0; p < 2; p++)
                for (int q = 0; q < 2; q++) {
                    const double v = Bj[j][l][3 * p + q];
                    A[4 * (2 * j + p) + 2 * l + q] = v;
                    A[4 * (2 * l + q) + 2 * j + p] = v;
                }
    cr_psd_project(A, 4);
    project2(N);
    hf_from_frame(R, A, N, HF);
}

/* Vertex k's block where no projection is needed (the Gauss-Newton part, or
 * the whole Hessian with a PSD stress S = (S00, S01, S11), NULL for the
 * Gauss-Newton part alone), in closed form: sum_jl c_kj c_kl HF_jl of
 * stvk_eval's HF is lambda w w^T + 2 mu (c0^2 f0 f0^T + c1^2 f1 f1^T)
 * + mu_sh s s^T (+ (c S c) I), w = c0 f0 + c1 f1, s = c0 f1 + c1 f0. */
static void stvk_block_direct(double mu_s, double mu_sh, double lambda, const double *f,
                              const double *S, double c0, double c1, double area, double *H) {
    const double *f0 = f, *f1 = f + 3;
    const double cs2 = S ? c0 * c0 * S[0] + 2.0 * c0 * c1 * S[1] + c1 * c1 * S[2] : 0.0;
    double w[3], sv[3];
    for (int d = 0; d < 3; d++)
        w[d] = c0 * f0[d] + c1 * f1[d], sv[d] = c0 * f1[d] + c1 * f0[d];
    for (int p = 0; p < 3; p++)
        for (int q = p; q < 3; q++) {
            const double v = lambda * w[p] * w[q] +
                             2.0 * mu_s * (c0 * c0 * f0[p] * f0[q] + c1 * c1 * f1[p] * f1[q]) +
                             mu_sh * sv[p] * sv[q] + (p == q ? cs2 : 0.0);
            H[3 * p + q] = H[3 * q + p] = area * v;
        }
}

/* The density psi(a, b, cc) and its stress S = 2 mu E + lambda tr(E) I
 * (S00, S11, S01), a = f0.f0, b = f1.f1, cc = f0.f1, with the stretch terms'
 * mu_s and lambda and the shear term's mu_sh. */
static inline double stvk_psi(double mu_s, double mu_sh, double lambda, double a, double b,
                              double cc, double *S) {
    const double tr = a + b - 2.0;
    if (S) {
        S[0] = mu_s * (a - 1.0) + 0.5 * lambda * tr;
        S[1] = mu_sh * cc;
        S[2] = mu_s * (b - 1.0) + 0.5 * lambda * tr;
    }
    return mu_s * (0.25 * (a - 1.0) * (a - 1.0) + 0.25 * (b - 1.0) * (b - 1.0)) +
           mu_sh * 0.5 * cc * cc + 0.125 * lambda * tr * tr;
}

/* The StVK density with the stretch terms (mu (E11^2 + E22^2) + lambda/2
 * tr(E)^2) scaled by cs and the shear term (2 mu E12^2) by csh, each 0 or 1:
 * (1, 1) is the full density, bit for bit. k < 0: the whole element's g (9)
 * and H (81); k = 0..2: vertex k's g (3) and block H (9) alone. */
static double stvk_eval(const cr_membrane *m, double cs, double csh, int32_t e, int k,
                        const double *xe, double *g, double *H) {
    double f[6], c[6];
    cr_membrane_deform(m, e, xe, f, c);
    const double *f0 = f, *f1 = f + 3;
    const double a = f0[0] * f0[0] + f0[1] * f0[1] + f0[2] * f0[2];
    const double b = f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2];
    const double cc = f0[0] * f1[0] + f0[1] * f1[1] + f0[2] * f1[2];
    const double mu_s = cs * m->mu, lambda = cs * m->lambda, mu_sh = csh * m->mu;
    double St[3];
    const double psi = stvk_psi(mu_s, mu_sh, lambda, a, b, cc, St);
    if (!g && !H) return m->area[e] * psi;
    /* S = 2 mu E + lambda tr(E) I, so P = F S: gF_0 = S00 f0 + S01 f1, ... */
    const double S00 = St[0], S11 = St[2], S01 = St[1];
    double gF[6], HF[36];
    for (int d = 0; d < 3; d++) {
        gF[d] = S00 * f0[d] + S01 * f1[d];
        gF[3 + d] = S01 * f0[d] + S11 * f1[d];
    }
    const int projected = H && m->mode == CR_HESSIAN_PROJECTED;
    const int stress_psd = S00 >= 0.0 && S11 >= 0.0 && S00 * S11 >= S01 * S01;
    double R[9], fa, fb, fd;
    /* The whole density is isotropic (its parts are not): its projection
     * has a closed form in the plane, and its normal block is S. */
    if (projected && !stress_psd && cs == 1.0 && csh == 1.0 && k >= 0) {
        double N[3] = {S00, S01, S11};
        project2(N);
        if (stvk_block_projected(m->mu, m->lambda, f, a, cc, b, N, c[2 * k], c[2 * k + 1],
                                 m->area[e], H)) {
            cr_membrane_to_vertex(c, m->area[e], k, gF, NULL, g, NULL);
            return m->area[e] * psi;
        }
    }
    if (projected && !stress_psd && cs == 1.0 && csh == 1.0 && k < 0 &&
        plane_frame(f, R, &fa, &fb, &fd)) {
        double A[16], N[3] = {S00, S01, S11};
        stvk_inplane_projected(m->mu, m->lambda, fa, fb, fd, A);
        project2(N);
        hf_from_frame(R, A, N, HF);
    } else if (H && k >= 0 && !(projected && !stress_psd)) {
        const double S[3] = {S00, S01, S11};
        stvk_block_direct(mu_s, mu_sh, lambda, f, projected ? S : NULL, c[2 * k], c[2 * k + 1],
                          m->area[e], H);
        cr_membrane_to_vertex(c, m->area[e], k, gF, NULL, g, NULL);
        return m->area[e] * psi;
    } else if (H) {
        /* Gauss-Newton part: d(a,b,c)/dF^T W d(a,b,c)/dF with
         * W = [[mu/2 + lambda/4, lambda/4, 0], [lambda/4, mu/2 + lambda/4, 0], [0, 0, mu]]
         * and da/df0 = 2 f0, db/df1 = 2 f1, dc/df0 = f1, dc/df1 = f0. */
        const double kk = 2.0 * mu_s + lambda;
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++) {
                HF[6 * p + q] = kk * f0[p] * f0[q] + mu_sh * f1[p] * f1[q];
                HF[6 * (3 + p) + 3 + q] = kk * f1[p] * f1[q] + mu_sh * f0[p] * f0[q];
                HF[6 * p + 3 + q] = lambda * f0[p] * f1[q] + mu_sh * f1[p] * f0[q];
                HF[6 * (3 + q) + p] = HF[6 * p + 3 + q];
            }
        if (projected) {
            /* The stress part S (x) I3. */
            for (int p = 0; p < 3; p++) {
                HF[6 * p + p] += S00;
                HF[6 * (3 + p) + 3 + p] += S11;
                HF[6 * p + 3 + p] += S01;
                HF[6 * (3 + p) + p] += S01;
            }
            if (!stress_psd) cr_membrane_project_hf(f, HF);
        }
    }
    if (k < 0)
        cr_membrane_to_x(c, m->area[e], gF, H ? HF : NULL, g, H);
    else
        cr_membrane_to_vertex(c, m->area[e], k, gF, H ? HF : NULL, g, H);
    return m->area[e] * psi;
}

double cr_membrane_stvk_kernel(const void *data, int32_t e, const double *xe, double *g,
                               double *H) {
    return stvk_eval(data, 1.0, 1.0, e, -1, xe, g, H);
}

double cr_membrane_stvk_stretch_kernel(const void *data, int32_t e, const double *xe, double *g,
                                       double *H) {
    return stvk_eval(data, 1.0, 0.0, e, -1, xe, g, H);
}

double cr_membrane_stvk_shear_kernel(const void *data, int32_t e, const double *xe, double *g,
                                     double *H) {
    return stvk_eval(data, 0.0, 1.0, e, -1, xe, g, H);
}

/* The whole density's block, the common case of a VBD sweep, without
 * stvk_eval's element-sized paths (the same expressions: stvk_psi,
 * stvk_block_direct, stvk_block_projected); the Gauss-Newton mode and a
 * triangle that spans no plane go to stvk_eval. */
double cr_membrane_stvk_vertex(const void *data, int32_t e, int k, const double *xe, double *g,
                               double *H) {
    const cr_membrane *m = data;
    if (H && m->mode != CR_HESSIAN_PROJECTED) return stvk_eval(m, 1.0, 1.0, e, k, xe, g, H);
    double f[6], c[6], S[3];
    cr_membrane_deform(m, e, xe, f, c);
    const double *f0 = f, *f1 = f + 3;
    const double a = f0[0] * f0[0] + f0[1] * f0[1] + f0[2] * f0[2];
    const double b = f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2];
    const double cc = f0[0] * f1[0] + f0[1] * f1[1] + f0[2] * f1[2];
    const double mu = m->mu, lambda = m->lambda, area = m->area[e];
    const double psi = stvk_psi(mu, mu, lambda, a, b, cc, S);
    if (!g && !H) return area * psi;
    if (H) {
        const int stress_psd = S[0] >= 0.0 && S[2] >= 0.0 && S[0] * S[2] >= S[1] * S[1];
        if (stress_psd) {
            stvk_block_direct(mu, mu, lambda, f, S, c[2 * k], c[2 * k + 1], area, H);
        } else {
            double N[3] = {S[0], S[1], S[2]};
            project2(N);
            if (!stvk_block_projected(mu, lambda, f, a, cc, b, N, c[2 * k], c[2 * k + 1], area,
                                      H))
                return stvk_eval(m, 1.0, 1.0, e, k, xe, g, H);
        }
    }
    if (g) {
        const double c0 = c[2 * k], c1 = c[2 * k + 1];
        for (int d = 0; d < 3; d++) {
            const double gF0 = S[0] * f0[d] + S[1] * f1[d], gF1 = S[1] * f0[d] + S[2] * f1[d];
            g[d] = area * (c0 * gF0 + c1 * gF1);
        }
    }
    return area * psi;
}

double cr_membrane_stvk_stretch_vertex(const void *data, int32_t e, int k, const double *xe,
                                       double *g, double *H) {
    return stvk_eval(data, 1.0, 0.0, e, k, xe, g, H);
}

double cr_membrane_stvk_shear_vertex(const void *data, int32_t e, int k, const double *xe,
                                     double *g, double *H) {
    return stvk_eval(data, 0.0, 1.0, e, k, xe, g, H);
}
