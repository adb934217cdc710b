/* test_phys_energy.c: every cloth energy kernel against central differences
 * (gradient from the value: step 1e-6 m, relative tolerance 1e-5; Hessian
 * from the gradient, same step) where its Hessian is exact; where it is
 * eigen-clamped, that the result is symmetric PSD, dominates the exact
 * Hessian (H_proj - H_exact PSD) and equals it when the exact one is PSD.
 * Plus closed forms: zero membrane energy and gradient at rest, rigid-motion
 * invariance, bending minimal at a non-zero rest angle, the dihedral sign
 * convention of diffgeo.h, zero collision outside the thickness, gravity's
 * gradient -m g, friction's Coulomb limit, cr_psd_project on a matrix with
 * known eigen-decomposition; the terms assembled over a small cloth agree with
 * differences of the total; and kernel costs (ns per element) printed. */
#include "crease/diffgeo.h"
#include "crease/phys_energies.h"
#include "crease/primitives.h"
#include "crease/topology.h"
#include "energy_fd.h"
#include "phys/dihedral64.h"
#include "phys/lapack.h"
#include "phys/membrane.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FD_STEP 1e-6 /* m */
#define FD_RTOL 1e-5

/* ------------------------------------------------------------ helpers -- */

static double grad_rel_error(const cr_energy_term *t, int32_t e, const double *x0) {
    return fd_grad_rel_error(t, e, x0, FD_STEP);
}

/* Hessian by central differences of a gradient function. */
typedef void (*grad_fn)(const void *ctx, const double *x, double *g);
static void fd_hessian_h(grad_fn f, const void *ctx, const double *x0, int n, double h, double *H) {
    double x[12], gp[12], gm[12];
    memcpy(x, x0, sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        x[j] = x0[j] + h;
        f(ctx, x, gp);
        x[j] = x0[j] - h;
        f(ctx, x, gm);
        x[j] = x0[j];
        for (int i = 0; i < n; i++)
            H[i * n + j] = (gp[i] - gm[i]) / (2.0 * h);
    }
    for (int i = 0; i < n; i++) /* symmetrise: the FD noise is not */
        for (int j = 0; j < i; j++)
            H[i * n + j] = H[j * n + i] = 0.5 * (H[i * n + j] + H[j * n + i]);
}

static void fd_hessian(grad_fn f, const void *ctx, const double *x0, int n, double *H) {
    fd_hessian_h(f, ctx, x0, n, FD_STEP, H);
}

typedef struct term_elem {
    const cr_energy_term *t;
    int32_t e;
} term_elem;
static void term_grad(const void *ctx, const double *x, double *g) {
    const term_elem *te = ctx;
    te->t->kernel(te->t->data, te->e, x, g, NULL);
}

static double rel_diff(const double *a, const double *b, int n) {
    double d = 0.0;
    for (int i = 0; i < n; i++)
        d = fmax(d, fabs(a[i] - b[i]));
    return d / fmax(fmax(fd_max_abs(a, n), fd_max_abs(b, n)), 1e-300);
}

/* Kernel Hessian against FD of the kernel gradient (relative error). */
static double hess_rel_error_h(const cr_energy_term *t, int32_t e, const double *x0, double h) {
    const int n = 3 * t->nvert;
    double H[144], Hfd[144], g[12];
    t->kernel(t->data, e, x0, g, H);
    term_elem te = {t, e};
    fd_hessian_h(term_grad, &te, x0, n, h, Hfd);
    return rel_diff(H, Hfd, n * n);
}
static double hess_rel_error(const cr_energy_term *t, int32_t e, const double *x0) {
    return hess_rel_error_h(t, e, x0, FD_STEP);
}

/* Smallest eigenvalue of a symmetric n x n matrix, relative to its largest |.|. */
static double min_eig_rel(const double *H, int n) {
    double a[144], w[12], work[12 * 34];
    memcpy(a, H, sizeof(double) * (size_t)(n * n));
    int lwork = 12 * 34, info = 0;
    dsyev_("N", "U", &n, a, &n, w, work, &lwork, &info);
    CR_CHECK(info == 0);
    const double big = fmax(fabs(w[0]), fabs(w[n - 1]));
    return big > 0.0 ? w[0] / big : 0.0;
}

static int is_symmetric(const double *H, int n) {
    const double s = fd_max_abs(H, n * n);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            if (fabs(H[i * n + j] - H[j * n + i]) > 1e-12 * s) return 0;
    return 1;
}

static cr_material material(const char *name, cr_membrane_model model) {
    cr_material m;
    cr_error err;
    CR_CHECK_OK(cr_material_preset(name, &m, &err), &err);
    m.membrane = model;
    return m;
}

/* One triangle in the z = 0 plane with UVs equal to its positions / 2. */
static cr_mesh *one_triangle(void) {
    cr_mesh *m = NULL;
    cr_error err;
    CR_CHECK_OK(cr_mesh_create(3, 1, 3, &m, &err), &err);
    const float p[9] = {0.01f, 0.02f, 0, 0.11f, 0.03f, 0, 0.04f, 0.10f, 0};
    memcpy(m->pos, p, sizeof p);
    for (int k = 0; k < 3; k++) {
        m->tri[k] = m->tri_uv[k] = k;
        m->uv[2 * k] = p[3 * k] / 2.0f, m->uv[2 * k + 1] = p[3 * k + 1] / 2.0f;
    }
    return m;
}

static void rest_x(const cr_mesh *m, double *x) {
    for (int64_t i = 0; i < 3 * (int64_t)m->nv; i++)
        x[i] = m->pos[i];
}

/* x_out = R x_in + t for n points, R a random rotation. */
static void rigid(cr_rng *r, const double *in, int n, double *out) {
    double q[4], s = 0;
    for (int i = 0; i < 4; i++)
        q[i] = cr_rng_normal(r), s += q[i] * q[i];
    s = sqrt(s);
    const double w = q[0] / s, a = q[1] / s, b = q[2] / s, c = q[3] / s;
    const double R[9] = {1 - 2 * (b * b + c * c), 2 * (a * b - w * c),     2 * (a * c + w * b),
                         2 * (a * b + w * c),     1 - 2 * (a * a + c * c), 2 * (b * c - w * a),
                         2 * (a * c - w * b),     2 * (b * c + w * a),     1 - 2 * (a * a + b * b)};
    const double t[3] = {cr_rng_normal(r), cr_rng_normal(r), cr_rng_normal(r)};
    for (int k = 0; k < n; k++)
        for (int i = 0; i < 3; i++)
            out[3 * k + i] = R[3 * i] * in[3 * k] + R[3 * i + 1] * in[3 * k + 1] +
                             R[3 * i + 2] * in[3 * k + 2] + t[i];
}

/* ---------------------------------------------------------- psd project -- */

CR_TEST(phys_energy, psd_project_clamps_known_matrix) {
    /* H = Q diag(2, -1, 3) Q^T with Q a rotation: projection is Q diag(2, 0, 3) Q^T. */
    const double c = cos(0.7), s = sin(0.7);
    const double Q[9] = {c, -s, 0, s * 0.6, c * 0.6, -0.8, s * 0.8, c * 0.8, 0.6};
    const double lam[3] = {2, -1, 3}, lam_p[3] = {2, 0, 3};
    double H[9] = {0}, want[9] = {0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) {
                H[3 * i + j] += Q[3 * i + k] * lam[k] * Q[3 * j + k];
                want[3 * i + j] += Q[3 * i + k] * lam_p[k] * Q[3 * j + k];
            }
    cr_psd_project(H, 3);
    for (int i = 0; i < 9; i++)
        CR_CHECK_NEAR(H[i], want[i], 1e-12);
    /* A PSD (singular) matrix comes back bit for bit; so does a PD one. */
    double P[144], P0[144];
    cr_rng r = cr_rng_make(3, 0);
    double v[12];
    for (int i = 0; i < 12; i++)
        v[i] = cr_rng_normal(&r);
    for (int i = 0; i < 12; i++)
        for (int j = 0; j < 12; j++)
            P[12 * i + j] = v[i] * v[j] + (i == j && i < 6 ? 1.0 : 0.0);
    memcpy(P0, P, sizeof P);
    cr_psd_project(P, 12);
    CR_CHECK(memcmp(P, P0, sizeof P) == 0);
    /* A random symmetric 12x12: the result is PSD and H_proj - H is PSD. */
    for (int i = 0; i < 12; i++)
        for (int j = 0; j <= i; j++)
            P[12 * i + j] = P[12 * j + i] = cr_rng_normal(&r);
    memcpy(P0, P, sizeof P);
    cr_psd_project(P, 12);
    CR_CHECK(is_symmetric(P, 12));
    CR_CHECK(min_eig_rel(P, 12) > -1e-12);
    double D[144];
    for (int i = 0; i < 144; i++)
        D[i] = P[i] - P0[i];
    CR_CHECK(min_eig_rel(D, 12) > -1e-12);
}

/* ------------------------------------------------------------ membrane -- */

/* Deformations of the rest triangle: s scales it in its plane, plus noise. */
static void deform(cr_rng *r, const double *x0, double s, double noise, double *x) {
    for (int i = 0; i < 9; i++)
        x[i] = s * x0[i] + noise * cr_rng_normal(r);
}

static void membrane_checks(cr_membrane_model model) {
    cr_error err;
    cr_material mat = material("cotton", model);
    cr_mesh *m = one_triangle();
    cr_membrane *mem = NULL;
    CR_CHECK_OK(cr_membrane_create(m, 0, 1.0f, &mat, &mem, &err), &err);
    CR_REQUIRE(mem);
    cr_energy_term t;
    cr_membrane_term(mem, &t);
    CR_CHECK(t.nvert == 3 && t.nelem == 1 && strcmp(t.name, "membrane") == 0);
    double x0[9], x[9], y[9], g[9], H[81];
    rest_x(m, x0);
    CR_CHECK_NEAR(cr_membrane_rest_areas(mem)[0], 0.5 * fabs(0.1 * 0.08 - 0.03 * 0.01), 1e-9);
    /* Rest: zero energy and zero gradient, also after a rigid motion. */
    cr_rng r = cr_rng_make(7, (uint64_t)model);
    CR_CHECK_NEAR(t.kernel(t.data, 0, x0, g, H), 0.0, 1e-15);
    CR_CHECK(fd_max_abs(g, 9) < 1e-9);
    rigid(&r, x0, 3, y);
    CR_CHECK_NEAR(t.kernel(t.data, 0, y, g, NULL), 0.0, 1e-12);
    CR_CHECK(fd_max_abs(g, 9) < 1e-7);
    for (int trial = 0; trial < 20; trial++) {
        const double s = trial < 10 ? 1.1 : 0.9; /* tension, then compression */
        deform(&r, x0, s, 2e-3, x);
        const double e = fd_kval(&t, 0, x);
        CR_CHECK(e > 0.0);
        CR_CHECK(grad_rel_error(&t, 0, x) < FD_RTOL);
        rigid(&r, x, 3, y);
        CR_CHECK_NEAR(fd_kval(&t, 0, y), e, 1e-9 * e);
        t.kernel(t.data, 0, x, g, H);
        CR_CHECK(is_symmetric(H, 9));
        CR_CHECK(min_eig_rel(H, 9) > -1e-10);
        /* Dominates the exact Hessian (FD of the gradient). */
        term_elem te = {&t, 0};
        double Hfd[81], D[81];
        fd_hessian(term_grad, &te, x, 9, Hfd);
        for (int i = 0; i < 81; i++)
            D[i] = H[i] - Hfd[i];
        CR_CHECK(min_eig_rel(D, 9) * fd_max_abs(D, 81) > -1e-5 * fd_max_abs(H, 81));
        /* Under uniform stretch without shear the exact Hessian is PSD: equal. */
        if (trial < 10 && model == CR_MEMBRANE_STVK) CR_CHECK(hess_rel_error(&t, 0, x) < FD_RTOL);
    }
    if (model == CR_MEMBRANE_BARAFF_WITKIN) {
        /* Pure stretch along the rest axes (w_u . w_v = 0, |w| > 1): PSD, exact. */
        for (int i = 0; i < 9; i++)
            x[i] = 1.2 * x0[i];
        CR_CHECK(hess_rel_error(&t, 0, x) < FD_RTOL);
    }
    /* Gauss-Newton: PSD by construction. */
    cr_membrane_set_hessian(mem, CR_HESSIAN_GAUSS_NEWTON);
    deform(&r, x0, 0.9, 5e-3, x);
    t.kernel(t.data, 0, x, g, H);
    CR_CHECK(is_symmetric(H, 9) && min_eig_rel(H, 9) > -1e-10);
    cr_membrane_destroy(mem);
    cr_mesh_destroy(m);
}

CR_TEST(phys_energy, membrane_stvk) {
    membrane_checks(CR_MEMBRANE_STVK);
}

CR_TEST(phys_energy, membrane_baraff_witkin) {
    membrane_checks(CR_MEMBRANE_BARAFF_WITKIN);
}

CR_TEST(phys_energy, membrane_uv_rest) {
    cr_error err;
    cr_mesh *m = one_triangle();
    cr_membrane *a = NULL, *b = NULL;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    CR_CHECK_OK(cr_membrane_create(m, 0, 1.0f, &mat, &a, &err), &err);
    CR_CHECK_OK(cr_membrane_create(m, 1, 2.0f, &mat, &b, &err), &err);
    CR_REQUIRE(a && b);
    CR_CHECK_NEAR(cr_membrane_rest_areas(a)[0], cr_membrane_rest_areas(b)[0], 1e-9);
    cr_energy_term ta, tb;
    cr_membrane_term(a, &ta);
    cr_membrane_term(b, &tb);
    double x0[9], x[9];
    rest_x(m, x0);
    CR_CHECK_NEAR(fd_kval(&tb, 0, x0), 0.0, 1e-12);
    cr_rng r = cr_rng_make(5, 0);
    for (int trial = 0; trial < 5; trial++) {
        deform(&r, x0, 1.05, 3e-3, x);
        /* StVK is isotropic: the UV rest (same shape, other frame) agrees. */
        CR_CHECK_NEAR(fd_kval(&tb, 0, x), fd_kval(&ta, 0, x), 1e-6 * fd_kval(&ta, 0, x));
        CR_CHECK(grad_rel_error(&tb, 0, x) < FD_RTOL);
    }
    /* A UV scale of 1 shrinks the rest shape by half: the rest mesh is stretched. */
    cr_membrane *c = NULL;
    CR_CHECK_OK(cr_membrane_create(m, 1, 1.0f, &mat, &c, &err), &err);
    cr_energy_term tc;
    cr_membrane_term(c, &tc);
    CR_CHECK(fd_kval(&tc, 0, x0) > 0.0);
    /* Errors: no UVs; degenerate rest triangle named. */
    cr_mesh *flat = NULL;
    CR_CHECK_OK(cr_mesh_clone(m, &flat, &err), &err);
    flat->pos[6] = flat->pos[3] * 2 - flat->pos[0], flat->pos[7] = flat->pos[4] * 2 - flat->pos[1];
    cr_membrane *bad = NULL;
    CR_CHECK(cr_membrane_create(flat, 0, 1.0f, &mat, &bad, &err) == CR_ERR_TOPOLOGY);
    CR_CHECK(bad == NULL && strstr(err.msg, "triangle 0") != NULL);
    cr_membrane_destroy(a);
    cr_membrane_destroy(b);
    cr_membrane_destroy(c);
    cr_mesh_destroy(flat);
    cr_mesh_destroy(m);
}

/* ------------------------------------------------------------- bending -- */

/* The folded strip of test_diffgeo.c in double: theta = phi. */
static void folded_hinge(double phi, double *x) {
    const double h[12] = {0, 0, 0, 1, 0, 0, 0.3, 0, -0.8, 0.6, 0.7 * sin(phi), 0.7 * cos(phi)};
    memcpy(x, h, sizeof h);
}

typedef struct {
    int unused;
} no_ctx;
static void theta_grad(const void *ctx, const double *x, double *g) {
    (void)ctx;
    double gy[9];
    int ok;
    cr_dihedral64_derivs_y(x, gy, NULL, &ok);
    cr_dihedral64_grad_x(gy, g);
}

CR_TEST(phys_energy, dihedral64_derivatives) {
    const double phis[] = {0.0, 0.3, -0.3, 1.5, -2.5, 3.0};
    cr_rng r = cr_rng_make(9, 0);
    for (size_t k = 0; k < sizeof phis / sizeof phis[0]; k++) {
        double x[12], y[12];
        folded_hinge(phis[k], x);
        CR_CHECK_NEAR(cr_dihedral64_angle(x), phis[k], 1e-12);
        /* Same sign convention as diffgeo.h's float version. */
        float xf[12];
        for (int i = 0; i < 12; i++)
            xf[i] = (float)x[i];
        CR_CHECK_NEAR(cr_dihedral_angle(xf, xf + 3, xf + 6, xf + 9), phis[k], 1e-5);
        /* Perturb off the symmetric setup, then check gradient and Hessian by FD. */
        for (int i = 0; i < 12; i++)
            y[i] = x[i] + 0.05 * cr_rng_normal(&r);
        double gy[9], Hy[81], g[12], H[144], Hfd[144];
        int ok = 0;
        const double th = cr_dihedral64_derivs_y(y, gy, Hy, &ok);
        CR_CHECK(ok);
        CR_CHECK_NEAR(th, cr_dihedral64_angle(y), 1e-14);
        cr_dihedral64_grad_x(gy, g);
        double gerr = 0.0, yy[12];
        memcpy(yy, y, sizeof yy);
        for (int i = 0; i < 12; i++) {
            yy[i] = y[i] + FD_STEP;
            const double tp = cr_dihedral64_angle(yy);
            yy[i] = y[i] - FD_STEP;
            const double tm = cr_dihedral64_angle(yy);
            yy[i] = y[i];
            gerr = fmax(gerr, fabs(g[i] - (tp - tm) / (2 * FD_STEP)));
        }
        CR_CHECK(gerr < FD_RTOL * fd_max_abs(g, 12));
        cr_dihedral64_hess_x(Hy, H);
        CR_CHECK(is_symmetric(H, 12));
        no_ctx c;
        fd_hessian(theta_grad, &c, y, 12, Hfd);
        CR_CHECK(rel_diff(H, Hfd, 144) < FD_RTOL);
    }
}

/* Two triangles on one hinge: A = (0, 1, 2), B = (1, 0, 3). */
static cr_mesh *hinge_mesh(double phi) {
    cr_mesh *m = NULL;
    cr_error err;
    CR_CHECK_OK(cr_mesh_create(4, 2, 0, &m, &err), &err);
    double x[12];
    folded_hinge(phi, x);
    for (int i = 0; i < 12; i++)
        m->pos[i] = (float)x[i];
    const int32_t tri[6] = {0, 1, 2, 1, 0, 3};
    memcpy(m->tri, tri, sizeof tri);
    return m;
}

/* k_e (grad grad^T + d Hess theta): the unprojected bending Hessian (12x12). */
static void bending_exact_hessian(double ke, double d, const double *x, double *H) {
    double gy[9], Hy[81];
    int ok;
    cr_dihedral64_derivs_y(x, gy, Hy, &ok);
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 9; j++)
            Hy[9 * i + j] = ke * (gy[i] * gy[j] + d * Hy[9 * i + j]);
    cr_dihedral64_hess_x(Hy, H);
}

/* The hinge's atan2 (dihedral64.h) against libm's: within 2 ulp of the
 * result (bound 3) on random directions at every scale, both quadrant signs, near the
 * reduction's fold (|y/x| about tan(pi/8)) and the swap (|y| = |x|), and
 * libm's own answers for zeros, infinities and NaN. */
CR_TEST(phys_energy, bending) {
    cr_error err;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    const double phi0 = 0.4;
    cr_mesh *m = hinge_mesh(phi0);
    cr_topology *topo = NULL;
    CR_CHECK_OK(cr_topology_build(m, &topo, &err), &err);
    CR_REQUIRE(topo && topo->nh == 1);
    cr_bending *bf = NULL, *br = NULL;
    CR_CHECK_OK(cr_bending_create(m, topo, &mat, 0, &bf, &err), &err);
    CR_CHECK_OK(cr_bending_create(m, topo, &mat, 1, &br, &err), &err);
    CR_REQUIRE(bf && br);
    CR_CHECK(cr_bending_count(br) == 1);
    /* k_e = k_b l^2 / (4 (A1 + A2)), l = 1, A1 = 0.4, A2 = 0.35. */
    /* (from float rest positions: 1e-6 relative) */
    CR_CHECK_NEAR(cr_bending_stiffness(br)[0], mat.bending / (4.0 * 0.75), 1e-6 * mat.bending);
    const double ke = cr_bending_stiffness(br)[0];
    CR_CHECK_NEAR(cr_bending_rest_angles(bf)[0], 0.0, 0.0);
    CR_CHECK_NEAR(cr_bending_rest_angles(br)[0], phi0, 1e-6);
    cr_bending_rest_angles(br)[0] = phi0; /* exactly, for the closed forms below */
    cr_bending_set_hessian(br, CR_HESSIAN_PROJECTED);
    cr_energy_term t;
    cr_bending_term(br, &t);
    CR_CHECK(t.nvert == 4 && t.nelem == 1 && strcmp(t.name, "bending") == 0);
    double x[12], y[12], g[12], H[144], Hx[144], D[144];
    /* Minimal, with zero gradient, at theta = theta_rest != 0. */
    folded_hinge(phi0, x);
    CR_CHECK_NEAR(t.kernel(t.data, 0, x, g, H), 0.0, 1e-20);
    CR_CHECK(fd_max_abs(g, 12) < 1e-15);
    CR_CHECK(hess_rel_error(&t, 0, x) < FD_RTOL); /* k_e g g^T: PSD, so exact */
    double prev = INFINITY;
    for (int k = -10; k <= 10; k++) {
        folded_hinge(phi0 + 0.05 * k, y);
        const double e = fd_kval(&t, 0, y);
        CR_CHECK_NEAR(e, 0.5 * ke * (0.05 * k) * (0.05 * k), 1e-9 * ke);
        if (k <= 0) CR_CHECK(e < prev || k == -10);
        prev = e;
    }
    double theta = 0.0;
    cr_bending_angles(br, x, &theta);
    CR_CHECK_NEAR(theta, phi0, 1e-12);
    /* Wrapping: rest 3.0, angle -3.0 is 2 pi - 6 away, not 6. */
    cr_bending_rest_angles(br)[0] = 3.0;
    folded_hinge(-3.0, y);
    CR_CHECK_NEAR(fd_kval(&t, 0, y), 0.5 * ke * (2 * M_PI - 6) * (2 * M_PI - 6), 1e-9 * ke);
    cr_bending_rest_angles(br)[0] = phi0;
    /* Random configurations: gradient by FD; the projected Hessian is PSD,
     * symmetric and dominates the exact one; rigid motions change nothing. */
    cr_rng r = cr_rng_make(13, 0);
    for (int trial = 0; trial < 20; trial++) {
        folded_hinge(-2.0 + 0.2 * trial, x);
        for (int i = 0; i < 12; i++)
            x[i] += 0.05 * cr_rng_normal(&r);
        const double e = fd_kval(&t, 0, x);
        CR_CHECK(grad_rel_error(&t, 0, x) < FD_RTOL);
        rigid(&r, x, 4, y);
        CR_CHECK_NEAR(fd_kval(&t, 0, y), e, 1e-9 * e + 1e-20);
        t.kernel(t.data, 0, x, g, H);
        CR_CHECK(is_symmetric(H, 12));
        CR_CHECK(min_eig_rel(H, 12) > -1e-10);
        const double d = remainder(cr_dihedral64_angle(x) - phi0, 2 * M_PI);
        bending_exact_hessian(ke, d, x, Hx);
        for (int i = 0; i < 144; i++)
            D[i] = H[i] - Hx[i];
        CR_CHECK(min_eig_rel(D, 12) * fd_max_abs(D, 144) > -1e-10 * fd_max_abs(H, 144));
        /* The exact Hessian against FD of the kernel gradient. */
        term_elem te = {&t, 0};
        double Hfd[144];
        fd_hessian(term_grad, &te, x, 12, Hfd);
        CR_CHECK(rel_diff(Hx, Hfd, 144) < FD_RTOL);
    }
    /* Gauss-Newton: exactly k_e g g^T. */
    cr_bending_set_hessian(br, CR_HESSIAN_GAUSS_NEWTON);
    t.kernel(t.data, 0, x, g, H);
    const double d = remainder(cr_dihedral64_angle(x) - phi0, 2 * M_PI);
    for (int i = 0; i < 12; i++)
        for (int j = 0; j < 12; j++)
            CR_CHECK_NEAR(H[12 * i + j], g[i] * g[j] / (ke * d * d), 1e-9 * fd_max_abs(H, 144));
    /* A flat rest: energy k_e/2 phi^2 at the fold phi (here the mesh's float
     * rest angle is 0 exactly). */
    cr_bending_term(bf, &t);
    folded_hinge(1.0, x);
    CR_CHECK_NEAR(fd_kval(&t, 0, x), 0.5 * cr_bending_stiffness(bf)[0], 1e-12 * ke);
    cr_bending_destroy(bf);
    cr_bending_destroy(br);
    cr_topology_destroy(topo);
    cr_mesh_destroy(m);
}

/* -------------------------------------------------- vertex blocks -- */

/* Every vertex block (cr_energy_term.vertex_block) of one element against
 * its kernel; fd_hess only where the kernel's Hessian is exact; exact == 2:
 * at a minimum (zero gradient, so no relative gradient check). */
static void check_blocks(const cr_energy_term *t, const double *x, int exact) {
    CR_REQUIRE(t->vertex_block);
    fd_block_errors b = fd_vertex_block_errors(t, 0, x, FD_STEP);
    CR_CHECK(b.value_same);
    CR_CHECK(b.grad < 1e-12);
    CR_CHECK(b.hess < 1e-12);
    if (exact != 2) CR_CHECK(b.fd_grad < FD_RTOL);
    if (exact) CR_CHECK(b.fd_hess < FD_RTOL);
}

/* The membrane's blocks, whole and by part, both models and both Hessians,
 * in tension and in compression (where the projection works), and the
 * bending's on random hinges: the block is the kernel's row of vertex k, its
 * gradient the central difference of its value in x_k, and its Hessian that
 * of its gradient where the kernel's is exact (StVK in uniform tension, the
 * Gauss-Newton bending at its rest angle). */
CR_TEST(phys_energy, vertex_blocks) {
    cr_error err;
    cr_mesh *m = one_triangle();
    double x0[9], x[9];
    rest_x(m, x0);
    cr_rng r = cr_rng_make(31, 0);
    for (int model = 0; model < 2; model++) {
        cr_material mat = material("cotton", model ? CR_MEMBRANE_BARAFF_WITKIN : CR_MEMBRANE_STVK);
        cr_membrane *mem = NULL;
        CR_CHECK_OK(cr_membrane_create(m, 0, 1.0f, &mat, &mem, &err), &err);
        CR_REQUIRE(mem);
        for (int mode = 0; mode < 2; mode++) {
            cr_membrane_set_hessian(mem, mode ? CR_HESSIAN_GAUSS_NEWTON : CR_HESSIAN_PROJECTED);
            for (int part = 0; part < 3; part++) {
                cr_energy_term t;
                cr_membrane_term_part(mem, (cr_membrane_part)part, &t);
                for (int trial = 0; trial < 12; trial++) {
                    const double sc = trial < 4 ? 1.1 : trial < 8 ? 0.9 : 1.0;
                    deform(&r, x0, sc, trial < 8 ? 2e-3 : 8e-3, x);
                    check_blocks(&t, x, 0);
                }
            }
        }
        if (model == 0) { /* uniform stretch: StVK's Hessian is PSD, exact */
            cr_membrane_set_hessian(mem, CR_HESSIAN_PROJECTED);
            cr_energy_term t;
            cr_membrane_term(mem, &t);
            for (int i = 0; i < 9; i++)
                x[i] = 1.1 * x0[i];
            check_blocks(&t, x, 1);
        }
        cr_membrane_destroy(mem);
    }
    cr_mesh_destroy(m);
    /* Bending. */
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    cr_mesh *hm = hinge_mesh(0.4);
    cr_topology *topo = NULL;
    CR_CHECK_OK(cr_topology_build(hm, &topo, &err), &err);
    cr_bending *b = NULL;
    CR_CHECK_OK(cr_bending_create(hm, topo, &mat, 1, &b, &err), &err);
    CR_REQUIRE(b);
    cr_energy_term t;
    cr_bending_term(b, &t);
    double y[12];
    for (int mode = 0; mode < 2; mode++) {
        cr_bending_set_hessian(b, mode ? CR_HESSIAN_GAUSS_NEWTON : CR_HESSIAN_PROJECTED);
        for (int trial = 0; trial < 20; trial++) {
            folded_hinge(-2.0 + 0.2 * trial, y);
            for (int i = 0; i < 12; i++)
                y[i] += 0.05 * cr_rng_normal(&r);
            check_blocks(&t, y, 0);
        }
    }
    /* At the rest angle the Gauss-Newton Hessian k_e g g^T is the exact one. */
    folded_hinge(0.7, y);
    cr_bending_rest_angles(b)[0] = cr_dihedral64_angle(y);
    check_blocks(&t, y, 2);
    cr_bending_destroy(b);
    cr_topology_destroy(topo);
    cr_mesh_destroy(hm);
}

/* StVK's closed-form projection (membrane_stvk.c) against the eigensolve of
 * the same rotated Hessian: on a rest triangle with Dm = I and area 1/2 the
 * kernel's Hessian rows of vertices 1 and 2 are HF/2, HF the Hessian in
 * F = (x1 - x0, x2 - x0); HF exact by central differences of the gradient,
 * projected by cr_membrane_project_hf without the closed form, must equal
 * twice the kernel's projected rows. Compressed, sheared and mixed. */
CR_TEST(phys_energy, stvk_projection_closed_form) {
    cr_error err;
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_mesh_create(3, 1, 0, &m, &err), &err);
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    memcpy(m->pos, p, sizeof p);
    m->tri[0] = 0, m->tri[1] = 1, m->tri[2] = 2;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    cr_membrane *mem = NULL;
    CR_CHECK_OK(cr_membrane_create(m, 0, 1.0f, &mat, &mem, &err), &err);
    CR_REQUIRE(mem);
    cr_energy_term t;
    cr_membrane_term(mem, &t);
    cr_rng r = cr_rng_make(37, 0);
    const double stretch[6][2] = {{0.9, 0.9},  {0.95, 1.05}, {1.1, 0.8},
                                  {0.7, 0.99}, {1.0, 1.0},   {0.98, 0.97}};
    double worst = 0.0;
    int projected = 0;
    for (int trial = 0; trial < 60; trial++) {
        const double *st = stretch[trial % 6];
        double x[9] = {0.0};
        for (int d = 0; d < 3; d++)
            x[d] = 0.01 * cr_rng_normal(&r);
        /* f0, f1 stretched, sheared by 0.1 at most, rotated out of plane */
        double f[6] = {
            st[0], 0.1 * cr_rng_uniform(&r), 0.05 * cr_rng_normal(&r), 0.1 * cr_rng_uniform(&r),
            st[1], 0.05 * cr_rng_normal(&r)};
        for (int j = 0; j < 2; j++)
            for (int d = 0; d < 3; d++)
                x[3 * (j + 1) + d] = x[d] + f[3 * j + d];
        double g[9], H[81], HF[36], Hfd[81];
        t.kernel(t.data, 0, x, g, H);
        term_elem te = {&t, 0};
        fd_hessian(term_grad, &te, x, 9, Hfd);
        int indefinite = 0;
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 6; b++)
                HF[6 * a + b] = 2.0 * Hfd[9 * (3 + a) + 3 + b];
        double Hex[36];
        memcpy(Hex, HF, sizeof Hex);
        indefinite = min_eig_rel(Hex, 6) < -1e-6;
        projected += indefinite;
        cr_membrane_project_hf(f, HF);
        double K[36];
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 6; b++)
                K[6 * a + b] = 2.0 * H[9 * (3 + a) + 3 + b];
        worst = fmax(worst, rel_diff(K, HF, 36));
    }
    printf("    closed form vs eigensolve: largest relative difference %.2e over 60 "
           "deformations (%d indefinite)\n",
           worst, projected);
    CR_CHECK(projected >= 20);
    CR_CHECK(worst < 1e-5);
    cr_membrane_destroy(mem);
    cr_mesh_destroy(m);
}

/* ------------------------------------------------- vertex energies -- */

CR_TEST(phys_energy, gravity_and_inertia) {
    cr_error err;
    cr_material mat = material("denim", CR_MEMBRANE_STVK);
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(5, 4, 1.0f, 0.6f, &m, &err), &err);
    CR_REQUIRE(m);
    const double gv[3] = {0.0, -9.81, 0.0};
    cr_gravity *gr = NULL;
    CR_CHECK_OK(cr_gravity_create(m, &mat, gv, &gr, &err), &err);
    CR_REQUIRE(gr);
    const double *mass = cr_gravity_masses(gr);
    double total = 0.0;
    for (int i = 0; i < m->nv; i++)
        total += mass[i];
    CR_CHECK_NEAR(total, mat.density * 0.6, 1e-6 * total);
    /* Interior vertex of a regular grid: six triangles of area A/6... i.e. 2 quads. */
    CR_CHECK(mass[6] > mass[0]);
    cr_energy_term t;
    cr_gravity_term(gr, &t);
    cr_rng r = cr_rng_make(17, 0);
    for (int e = 0; e < m->nv; e++) {
        double x[3] = {cr_rng_normal(&r), cr_rng_normal(&r), cr_rng_normal(&r)}, g[3], H[9];
        const double v = t.kernel(t.data, e, x, g, H);
        CR_CHECK_NEAR(v, mass[e] * 9.81 * x[1], 1e-12);
        CR_CHECK_NEAR(g[0], 0.0, 0.0);
        CR_CHECK_NEAR(g[1], 9.81 * mass[e], 1e-15);
        CR_CHECK(fd_max_abs(H, 9) == 0.0);
    }
    cr_inertia *in = NULL;
    CR_CHECK_OK(cr_inertia_create(mass, m->nv, &in, &err), &err);
    CR_REQUIRE(in);
    double *xp = calloc(3 * (size_t)m->nv, sizeof(double));
    for (int i = 0; i < 3 * m->nv; i++)
        xp[i] = cr_rng_normal(&r);
    const double h = 1.0 / 30.0;
    cr_inertia_set(in, xp, h);
    cr_inertia_term(in, &t);
    for (int e = 0; e < m->nv; e++) {
        double x[3] = {xp[3 * e] + 0.1, xp[3 * e + 1] - 0.2, xp[3 * e + 2] + 0.05};
        CR_CHECK_NEAR(fd_kval(&t, e, x), mass[e] / (2 * h * h) * (0.01 + 0.04 + 0.0025), 1e-12);
        CR_CHECK(grad_rel_error(&t, e, x) < FD_RTOL);
        CR_CHECK(hess_rel_error(&t, e, x) < FD_RTOL);
    }
    double neg = -1.0;
    cr_inertia *bad = NULL;
    CR_CHECK(cr_inertia_create(&neg, 1, &bad, &err) == CR_ERR_INVALID && bad == NULL);
    free(xp);
    cr_inertia_destroy(in);
    cr_gravity_destroy(gr);
    cr_mesh_destroy(m);
}

CR_TEST(phys_energy, collision) {
    cr_error err;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    const double eps = mat.collision_thickness, k = mat.collision_stiffness;
    cr_collision *c = NULL;
    CR_CHECK_OK(cr_collision_create(4, &mat, &c, &err), &err);
    CR_REQUIRE(c);
    /* Vertex 0 outside the thickness, 1 inside it, 2 penetrating, 3 unreached. */
    const double x[12] = {0, 1, 0, 0, 0.001, 0, 0.2, -0.003, 0.1, 5, 5, 5};
    const float dist[4] = {0.01f, 0.001f, -0.003f, INFINITY};
    const float n3 = 0.6f, n4 = 0.8f;
    const float normal[12] = {0, 1, 0, 0, 1, 0, n3, n4, 0, 0, 0, 0};
    cr_collision_update(c, x, dist, normal);
    CR_CHECK_NEAR(cr_collision_max_penetration(c), 0.003, 1e-9);
    double nrm[3], force;
    CR_CHECK(!cr_collision_contact(c, 0, nrm, &force));
    CR_CHECK(cr_collision_contact(c, 1, nrm, &force));
    /* dist is float: 1e-6 relative. */
    CR_CHECK_NEAR(force, 3 * k * (eps - 0.001) * (eps - 0.001), 1e-6 * force);
    CR_CHECK(!cr_collision_contact(c, 3, nrm, &force));
    cr_energy_term t;
    cr_collision_term(c, &t);
    double g[3], H[9];
    CR_CHECK(t.kernel(t.data, 0, x, g, H) == 0.0 && fd_max_abs(g, 3) == 0.0 &&
             fd_max_abs(H, 9) == 0.0);
    CR_CHECK(t.kernel(t.data, 3, x + 9, g, H) == 0.0 && fd_max_abs(g, 3) == 0.0);
    CR_CHECK_NEAR(fd_kval(&t, 1, x + 3), k * pow(eps - 0.001, 3), 1e-6 * k * pow(eps, 3));
    CR_CHECK_NEAR(fd_kval(&t, 2, x + 6), k * pow(eps + 0.003, 3), 1e-6 * k * pow(eps, 3));
    /* The linearised distance: moving 0.5 mm along the normal. */
    const double x2[3] = {0.2 + 0.0005 * n3, -0.003 + 0.0005 * n4, 0.1};
    CR_CHECK_NEAR(fd_kval(&t, 2, x2), k * pow(eps + 0.0025, 3), 1e-6 * k * pow(eps, 3));
    /* Moving out past the thickness: zero. */
    const double x1[3] = {0, 0.001 + 1.5 * eps, 0};
    CR_CHECK(fd_kval(&t, 1, x1) == 0.0);
    for (int e = 1; e <= 2; e++) {
        CR_CHECK(grad_rel_error(&t, e, x + 3 * e) < FD_RTOL);
        CR_CHECK(hess_rel_error(&t, e, x + 3 * e) < FD_RTOL);
    }
    cr_collision_destroy(c);
}

/* The chord sag over a sphere of radius R: the centroid of an equilateral
 * triangle of side L whose corners lie on it sits L^2 / (6 R) below the
 * surface to leading order; a concave pair and a pair more than 60 degrees
 * apart sag by nothing. Each vertex's threshold is eps plus its largest. */
CR_TEST(phys_energy, collision_chord_sag) {
    const double R = 0.3, L = 0.03;
    /* Corners of the triangle, on the sphere about the point (0, R, 0). */
    double x[9], n[9];
    const double r_c = L / sqrt(3.0);
    for (int k = 0; k < 3; k++) {
        const double a = 2.0 * 3.14159265358979323846 * k / 3.0;
        const double p[3] = {r_c * cos(a), sqrt(R * R - r_c * r_c), r_c * sin(a)};
        for (int d = 0; d < 3; d++)
            x[3 * k + d] = p[d], n[3 * k + d] = p[d] / R;
    }
    const double exact = R - sqrt(R * R - r_c * r_c); /* the centroid's depth */
    for (int k = 0; k < 3; k++) {
        const int j = (k + 1) % 3;
        const double sag = cr_collision_chord_sag(x + 3 * k, n + 3 * k, x + 3 * j, n + 3 * j);
        CR_CHECK_NEAR(sag, L * L / (6.0 * R), 1e-9);
        CR_CHECK_NEAR(sag, exact, 0.01 * exact);
    }
    /* Inside a sphere's shell (concave): the normals point inward. */
    const double ni[3] = {-n[0], -n[1], -n[2]}, nj[3] = {-n[3], -n[4], -n[5]};
    CR_CHECK(cr_collision_chord_sag(x, ni, x + 3, nj) == 0.0);
    /* A flat surface. */
    const double up[3] = {0, 1, 0};
    CR_CHECK(cr_collision_chord_sag(x, up, x + 3, up) == 0.0);
    /* Normals 90 degrees apart: two parts of a body, not one curve. */
    const double xa[3] = {0.1, 0, 0}, na[3] = {1, 0, 0}, xb[3] = {0, 0.1, 0}, nb[3] = {0, 1, 0};
    CR_CHECK(cr_collision_chord_sag(xa, na, xb, nb) == 0.0);
    /* 53 degrees (cos 0.6): half the sag, fading from 46 to 60 degrees. */
    const double nh[3] = {0.6, 0.8, 0}, xh[3] = {0.06, 0.08, 0};
    CR_CHECK_NEAR(cr_collision_chord_sag(xa, na, xh, nh), 0.5 * (0.4 * 0.04 + 0.8 * 0.08) / 6.0,
                  1e-12);

    cr_error err;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    const double eps = mat.collision_thickness;
    cr_collision *c = NULL;
    CR_CHECK_OK(cr_collision_create(4, &mat, &c, &err), &err);
    CR_REQUIRE(c);
    const int32_t edge[8] = {0, 1, 1, 2, 0, 2, 2, 3};
    const int32_t bad[2] = {0, 4};
    CR_CHECK(cr_collision_set_edges(c, bad, 1, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "vertex 4") != NULL);
    CR_CHECK_OK(cr_collision_set_edges(c, edge, 4, &err), &err);
    /* Vertex 3 unreached by the query: its edge sags by nothing. */
    double x4[12], dist_d[4] = {0.001, 0.001, 0.001, INFINITY};
    float dist[4], normal[12];
    memcpy(x4, x, sizeof x);
    for (int d = 0; d < 3; d++)
        x4[9 + d] = 1.0, normal[9 + d] = 0.0f;
    for (int k = 0; k < 9; k++)
        normal[k] = (float)n[k];
    for (int k = 0; k < 4; k++)
        dist[k] = (float)dist_d[k];
    cr_collision_update(c, x4, dist, normal);
    CR_CHECK(cr_collision_margin(c, 0) == eps); /* before the margins are set */
    /* The sag fades out near the query's reach: gone at 1 mm, half at 1.5 mm. */
    cr_collision_update_margins(c, normal, 0.001);
    CR_CHECK(cr_collision_max_margin(c) == eps);
    cr_collision_update_margins(c, normal, 0.0015);
    CR_CHECK_NEAR(cr_collision_margin(c, 0), eps + 0.5 * L * L / (6.0 * R), 1e-6);
    cr_collision_update_margins(c, normal, 0.05);
    for (int k = 0; k < 3; k++)
        CR_CHECK_NEAR(cr_collision_margin(c, k), eps + L * L / (6.0 * R), 1e-6);
    CR_CHECK(cr_collision_margin(c, 3) == eps);
    CR_CHECK_NEAR(cr_collision_max_margin(c), eps + L * L / (6.0 * R), 1e-6);
    /* The penalty starts at the threshold: vertex 0, 1 mm out, is inside it. */
    double nrm[3], force;
    CR_CHECK(cr_collision_contact(c, 0, nrm, &force));
    CR_CHECK_NEAR(force, 3 * mat.collision_stiffness * pow(cr_collision_margin(c, 0) - 0.001, 2),
                  1e-5 * force);
    cr_collision_destroy(c);
}

CR_TEST(phys_energy, friction) {
    cr_error err;
    cr_material mat = material("cotton", CR_MEMBRANE_STVK);
    cr_collision *c = NULL;
    cr_friction *f = NULL;
    const double eps_v = 1e-4;
    CR_CHECK_OK(cr_collision_create(3, &mat, &c, &err), &err);
    CR_CHECK_OK(cr_friction_create(3, &mat, eps_v, &f, &err), &err);
    CR_REQUIRE(c && f);
    const double x0[9] = {0, 0, 0, 1, 0, 0, 2, 0.001, 0};
    const float dist[3] = {0.001f, 0.05f, -0.001f};
    const float nn = (float)(1.0 / sqrt(3.0));
    const float normal[9] = {0, 1, 0, 0, 1, 0, nn, nn, nn};
    cr_collision_update(c, x0, dist, normal);
    const double disp[9] = {0.01, 0, 0, 0, 0, 0, 0, 0, 0}; /* collider slides under vertex 0 */
    cr_friction_update(f, c, x0, disp);
    CR_REQUIRE(cr_friction_contact_count(f) == 2);
    cr_energy_term t;
    cr_friction_term(f, &t);
    int32_t idx[1];
    cr_energy_term_vertices(&t, 0, idx);
    CR_CHECK(idx[0] == 0);
    cr_energy_term_vertices(&t, 1, idx);
    CR_CHECK(idx[0] == 2);
    double lambda0;
    CR_CHECK(cr_collision_contact(c, 0, NULL, &lambda0));
    double g[3], H[9];
    /* At the anchor: zero force. Far past eps_v: Coulomb mu lambda, tangential. */
    const double at[3] = {0.01, 0, 0};
    t.kernel(t.data, 0, at, g, H);
    CR_CHECK(fd_max_abs(g, 3) < 1e-18);
    const double slid[3] = {0.0, 0.3, 0.0}; /* 1 cm behind the collider, 30 cm off the plane */
    t.kernel(t.data, 0, slid, g, H);
    CR_CHECK_NEAR(sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]), mat.friction * lambda0,
                  1e-9 * lambda0);
    CR_CHECK_NEAR(g[1], 0.0, 1e-15); /* no normal component */
    CR_CHECK(g[0] < 0.0);            /* opposes x - anchor = -1 cm */
    /* FD in both regimes, for both contacts (the second has a skew normal). */
    cr_rng r = cr_rng_make(19, 0);
    for (int trial = 0; trial < 10; trial++) {
        const double s = trial < 5 ? 0.3 * eps_v : 20.0 * eps_v;
        for (int e = 0; e < 2; e++) {
            const double *a = e == 0 ? at : x0 + 6;
            double x[3];
            for (int d = 0; d < 3; d++)
                x[d] = a[d] + s * cr_rng_normal(&r) / sqrt(3.0);
            /* Friction's length scale is eps_v: step eps_v/1000. */
            CR_CHECK(fd_grad_rel_error(&t, e, x, 1e-3 * eps_v) < FD_RTOL);
            CR_CHECK(hess_rel_error_h(&t, e, x, 1e-3 * eps_v) < FD_RTOL);
            t.kernel(t.data, e, x, g, H);
            CR_CHECK(min_eig_rel(H, 3) > -1e-12);
        }
    }
    cr_friction *bad = NULL;
    CR_CHECK(cr_friction_create(3, &mat, 0.0, &bad, &err) == CR_ERR_INVALID && bad == NULL);
    cr_friction_destroy(f);
    cr_collision_destroy(c);
}

/* ---------------------------------------------------- assembled terms -- */

typedef struct scene {
    cr_mesh *m;
    cr_topology *topo;
    cr_membrane *mem;
    cr_bending *bend;
    cr_gravity *grav;
    cr_inertia *in;
    cr_collision *col;
    cr_energy_term t[5];
} scene;

/* A cloth of n x n vertices, 1 m square, with UV rest, bending with flat rest,
 * gravity, inertia and a collision plane at y = 0 (the cloth is at y ~ 1 mm). */
static int scene_make(scene *s, int n, cr_membrane_model model) {
    cr_error err;
    memset(s, 0, sizeof *s);
    cr_material mat = material("cotton", model);
    const double gv[3] = {0, -9.81, 0};
    CR_CHECK_OK(cr_prim_plane(n, n, 1.0f, 1.0f, &s->m, &err), &err);
    if (!s->m) return 0;
    CR_CHECK_OK(cr_topology_build(s->m, &s->topo, &err), &err);
    CR_CHECK_OK(cr_membrane_create(s->m, 1, 1.0f, &mat, &s->mem, &err), &err);
    CR_CHECK_OK(cr_bending_create(s->m, s->topo, &mat, 0, &s->bend, &err), &err);
    CR_CHECK_OK(cr_gravity_create(s->m, &mat, gv, &s->grav, &err), &err);
    if (!s->topo || !s->mem || !s->bend || !s->grav) return 0;
    CR_CHECK_OK(cr_inertia_create(cr_gravity_masses(s->grav), s->m->nv, &s->in, &err), &err);
    CR_CHECK_OK(cr_collision_create(s->m->nv, &mat, &s->col, &err), &err);
    if (!s->in || !s->col) return 0;
    cr_membrane_term(s->mem, &s->t[0]);
    cr_bending_term(s->bend, &s->t[1]);
    cr_gravity_term(s->grav, &s->t[2]);
    cr_inertia_term(s->in, &s->t[3]);
    cr_collision_term(s->col, &s->t[4]);
    return 1;
}

static void scene_destroy(scene *s) {
    cr_collision_destroy(s->col);
    cr_inertia_destroy(s->in);
    cr_gravity_destroy(s->grav);
    cr_bending_destroy(s->bend);
    cr_membrane_destroy(s->mem);
    cr_topology_destroy(s->topo);
    cr_mesh_destroy(s->m);
}

/* Total energy and (when grad != NULL) the assembled gradient (V,3). */
static double scene_energy(const scene *s, const double *x, double *grad) {
    double e = 0.0;
    if (grad) memset(grad, 0, sizeof(double) * 3 * (size_t)s->m->nv);
    for (int k = 0; k < 5; k++) {
        const cr_energy_term *t = &s->t[k];
        for (int32_t el = 0; el < t->nelem; el++) {
            int32_t idx[CR_ENERGY_MAX_VERTS];
            double xe[12], ge[12];
            cr_energy_term_vertices(t, el, idx);
            for (int v = 0; v < t->nvert; v++)
                for (int d = 0; d < 3; d++)
                    xe[3 * v + d] = x[3 * (int64_t)idx[v] + d];
            e += t->weight * t->kernel(t->data, el, xe, grad ? ge : NULL, NULL);
            if (grad)
                for (int v = 0; v < t->nvert; v++)
                    for (int d = 0; d < 3; d++)
                        grad[3 * (int64_t)idx[v] + d] += t->weight * ge[3 * v + d];
        }
    }
    return e;
}

CR_TEST(phys_energy, assembled_gradient) {
    scene s;
    CR_REQUIRE(scene_make(&s, 6, CR_MEMBRANE_STVK));
    const int V = s.m->nv;
    double *x = malloc(sizeof(double) * 3 * (size_t)V), *g = malloc(sizeof(double) * 3 * (size_t)V);
    float *dist = malloc(sizeof(float) * (size_t)V), *nrm = malloc(sizeof(float) * 3 * (size_t)V);
    cr_rng r = cr_rng_make(23, 0);
    for (int i = 0; i < 3 * V; i++)
        x[i] = s.m->pos[i] + 0.01 * cr_rng_normal(&r);
    for (int i = 0; i < V; i++) {
        x[3 * i + 1] = 0.001 + 0.002 * cr_rng_uniform(&r);
        dist[i] = (float)x[3 * i + 1];
        nrm[3 * i] = nrm[3 * i + 2] = 0.0f, nrm[3 * i + 1] = 1.0f;
    }
    cr_collision_update(s.col, x, dist, nrm);
    cr_inertia_set(s.in, x, 1.0 / 30.0);
    for (int i = 0; i < 3 * V; i++)
        x[i] += 0.003 * cr_rng_normal(&r);
    scene_energy(&s, x, g);
    double err = 0.0;
    for (int i = 0; i < 3 * V; i++) {
        const double x0 = x[i];
        x[i] = x0 + FD_STEP;
        const double ep = scene_energy(&s, x, NULL);
        x[i] = x0 - FD_STEP;
        const double em = scene_energy(&s, x, NULL);
        x[i] = x0;
        err = fmax(err, fabs(g[i] - (ep - em) / (2 * FD_STEP)));
    }
    CR_CHECK(err < FD_RTOL * fd_max_abs(g, 3 * V));
    free(x), free(g), free(dist), free(nrm);
    scene_destroy(&s);
}

/* ------------------------------------------------------- kernel costs -- */

static double time_term(const cr_energy_term *t, const double *x, int with_hessian) {
    double sink = 0.0, elapsed = 0.0;
    int64_t calls = 0;
    const double t0 = cr_time_now();
    do {
        for (int32_t el = 0; el < t->nelem; el++) {
            int32_t idx[CR_ENERGY_MAX_VERTS];
            double xe[12], ge[12], He[144];
            cr_energy_term_vertices(t, el, idx);
            for (int v = 0; v < t->nvert; v++)
                for (int d = 0; d < 3; d++)
                    xe[3 * v + d] = x[3 * (int64_t)idx[v] + d];
            sink += t->kernel(t->data, el, xe, ge, with_hessian ? He : NULL);
        }
        calls += t->nelem;
        elapsed = cr_time_now() - t0;
    } while (elapsed < 0.05);
    CR_CHECK(isfinite(sink));
    return 1e9 * elapsed / (double)calls;
}

CR_TEST(phys_energy, kernel_cost) {
    scene s, b;
    CR_REQUIRE(scene_make(&s, 101, CR_MEMBRANE_STVK));
    CR_REQUIRE(scene_make(&b, 101, CR_MEMBRANE_BARAFF_WITKIN));
    const int V = s.m->nv;
    double *x = malloc(sizeof(double) * 3 * (size_t)V);
    cr_rng r = cr_rng_make(29, 0);
    /* Compressed 5 % in the plane and wrinkled: most elements need projection. */
    for (int i = 0; i < V; i++) {
        x[3 * i] = 0.95 * s.m->pos[3 * i] + 1e-3 * cr_rng_normal(&r);
        x[3 * i + 1] = 5e-3 * cr_rng_normal(&r);
        x[3 * i + 2] = 0.95 * s.m->pos[3 * i + 2] + 1e-3 * cr_rng_normal(&r);
    }
    const double stvk = time_term(&s.t[0], x, 1), stvk_g = time_term(&s.t[0], x, 0);
    const double bw = time_term(&b.t[0], x, 1);
    cr_bending_set_hessian(s.bend, CR_HESSIAN_PROJECTED);
    const double bend = time_term(&s.t[1], x, 1), bend_g = time_term(&s.t[1], x, 0);
    cr_bending_set_hessian(s.bend, CR_HESSIAN_GAUSS_NEWTON);
    const double bend_gn = time_term(&s.t[1], x, 1);
    cr_membrane_set_hessian(s.mem, CR_HESSIAN_GAUSS_NEWTON);
    const double stvk_gn = time_term(&s.t[0], x, 1);
    double P[144];
    int64_t n = 0;
    const double t0 = cr_time_now();
    for (; cr_time_now() - t0 < 0.05; n++) {
        for (int i = 0; i < 144; i++)
            P[i] = 0.0;
        for (int i = 0; i < 12; i++)
            P[13 * i] = i == 5 ? -1.0 : 1.0 + i;
        P[1] = P[12] = 0.3;
        cr_psd_project(P, 12);
    }
    const double psd12 = 1e9 * (cr_time_now() - t0) / (double)n;
    printf("  kernel cost, ns/element (%d vertices, %d triangles, %d hinges):\n"
           "    membrane StVK: %.0f (H projected), %.0f (H Gauss-Newton), %.0f (gradient only)\n"
           "    membrane Baraff-Witkin: %.0f (H projected)\n"
           "    bending: %.0f (H projected), %.0f (H Gauss-Newton), %.0f (gradient only)\n"
           "    cr_psd_project 12x12 (indefinite): %.0f ns/call\n",
           V, s.t[0].nelem, s.t[1].nelem, stvk, stvk_gn, stvk_g, bw, bend, bend_gn, bend_g, psd12);
    free(x);
    scene_destroy(&s);
    scene_destroy(&b);
}
