/* test_phys_drape_energy.c: the drape method's four loss kernels (phys/
 * drape_*.c) against central differences and closed forms.
 *
 * Gradients from the value (step 1e-6 m, relative tolerance 1e-5; the
 * signed distance, whose closest point comes back in float, 1e-5 m and
 * 1e-4 on a box's axis-aligned faces, 1e-4 m and 1e-3 on a faceted ball). Hessians: exact ones
 * (strain under tension, collision with its nearest vertex held fixed)
 * against differences of the gradient; clamped or Gauss-Newton ones are
 * symmetric PSD, equal the exact Hessian where it is PSD (strain) or where
 * the residual vanishes (bend on a flat hinge), and dominate it (strain
 * under compression). Closed forms: ((l - L)/L)^2 of a known stretch,
 * 2 - 2 cos(phi) for a hinge folded by phi, m g y, (s - eps)^2 below a
 * sphere's vertex and a box's face, 0 outside the band and the box; bad
 * elements refused naming the element; storage reused once warm. */
#include "crease/bvh.h"
#include "crease/phys_energies.h"
#include "crease/primitives.h"
#include "energy_fd.h"
#include "phys/lapack.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FD_STEP 1e-6 /* m */
#define FD_RTOL 1e-5

/* ------------------------------------------------------------ helpers -- */

/* The kernel's gradient with and without H asked for: the same numbers. */
static int grad_same_with_hessian(const cr_energy_term *t, int32_t e, const double *x) {
    double g1[12], g2[12], H[144];
    const int n = 3 * t->nvert;
    const double v1 = t->kernel(t->data, e, x, g1, NULL), v2 = t->kernel(t->data, e, x, g2, H);
    if (v1 != v2 || v1 != fd_kval(t, e, x)) return 0;
    for (int i = 0; i < n; i++)
        if (fabs(g1[i] - g2[i]) > 1e-12 * fmax(fd_max_abs(g1, n), 1e-300)) return 0;
    return 1;
}

/* Hessian by central differences of the kernel's gradient, symmetrised. */
static void fd_hessian(const cr_energy_term *t, int32_t e, const double *x0, double h, double *H) {
    const int n = 3 * t->nvert;
    double x[12], gp[12], gm[12];
    memcpy(x, x0, sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        x[j] = x0[j] + h;
        t->kernel(t->data, e, x, gp, NULL);
        x[j] = x0[j] - h;
        t->kernel(t->data, e, x, gm, NULL);
        x[j] = x0[j];
        for (int i = 0; i < n; i++)
            H[i * n + j] = (gp[i] - gm[i]) / (2.0 * h);
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            H[i * n + j] = H[j * n + i] = 0.5 * (H[i * n + j] + H[j * n + i]);
}

static double rel_diff(const double *a, const double *b, int n) {
    double d = 0.0;
    for (int i = 0; i < n; i++)
        d = fmax(d, fabs(a[i] - b[i]));
    return d / fmax(fmax(fd_max_abs(a, n), fd_max_abs(b, n)), 1e-300);
}

/* Kernel Hessian against FD of the kernel gradient (relative error). */
static double hess_rel_error(const cr_energy_term *t, int32_t e, const double *x0, double h) {
    const int n = 3 * t->nvert;
    double H[144], Hfd[144], g[12];
    t->kernel(t->data, e, x0, g, H);
    fd_hessian(t, e, x0, h, Hfd);
    return rel_diff(H, Hfd, n * n);
}

/* Eigenvalues (ascending) of a symmetric n x n matrix. */
static void eigenvalues(const double *H, int n, double *w) {
    double a[144], work[12 * 34];
    memcpy(a, H, sizeof(double) * (size_t)(n * n));
    int lwork = 12 * 34, info = 0;
    dsyev_("N", "U", &n, a, &n, w, work, &lwork, &info);
    CR_CHECK(info == 0);
}

/* Smallest eigenvalue relative to the largest |eigenvalue|. */
static double min_eig_rel(const double *H, int n) {
    double w[12];
    eigenvalues(H, n, w);
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

/* The kernel's Hessian at x0 is symmetric and PSD (to rounding). */
static int kernel_hessian_psd(const cr_energy_term *t, int32_t e, const double *x0) {
    double g[12], H[144];
    const int n = 3 * t->nvert;
    t->kernel(t->data, e, x0, g, H);
    return is_symmetric(H, n) && min_eig_rel(H, n) > -1e-10;
}

/* ------------------------------------------------------------- strain -- */

CR_TEST(phys_drape_energy, strain) {
    cr_error err = {0};
    cr_drape_strain *s = NULL;
    CR_CHECK_OK(cr_drape_strain_create(0, &s, &err), &err);
    CR_REQUIRE(s);
    /* three points, two edges: 0-1 rest 0.1 m, 1-2 rest 0.05 m */
    const int32_t edges[4] = {0, 1, 1, 2};
    const float rest[2] = {0.1f, 0.05f};
    CR_CHECK_OK(cr_drape_strain_set(s, edges, rest, 2, 3, &err), &err);
    cr_energy_term t;
    cr_drape_strain_term(s, &t);
    CR_CHECK(t.nelem == 2 && t.nvert == 2 && t.elem && t.elem[2] == 1 && t.elem[3] == 2);
    CR_CHECK(strcmp(t.name, "drape_strain") == 0 && t.weight == 1.0);

    /* closed form: stretched by 10 % along a diagonal gives 0.01; at rest 0 */
    const double L = (double)0.1f, dir[3] = {2.0 / 3, -1.0 / 3, 2.0 / 3};
    double x[6] = {0.3, 0.2, -0.1};
    for (int c = 0; c < 3; c++)
        x[3 + c] = x[c] + 1.1 * L * dir[c];
    CR_CHECK_NEAR(fd_kval(&t, 0, x), 0.01, 1e-12);
    for (int c = 0; c < 3; c++)
        x[3 + c] = x[c] + L * dir[c];
    CR_CHECK_NEAR(fd_kval(&t, 0, x), 0.0, 1e-24);

    cr_rng r = cr_rng_make(7, 0);
    for (int trial = 0; trial < 20; trial++) {
        /* lengths from 0.6 L (compressed) to 1.4 L (stretched), random direction */
        const double len = L * (0.6 + 0.8 * trial / 19.0);
        double u[3], n = 0.0;
        for (int c = 0; c < 3; c++)
            u[c] = cr_rng_normal(&r), n += u[c] * u[c];
        for (int c = 0; c < 3; c++) {
            x[c] = 0.2 * cr_rng_normal(&r);
            x[3 + c] = x[c] + len * u[c] / sqrt(n);
        }
        CR_CHECK(fd_grad_rel_error(&t, 0, x, FD_STEP) < FD_RTOL);
        CR_CHECK(grad_same_with_hessian(&t, 0, x));
        CR_CHECK(kernel_hessian_psd(&t, 0, x));
        double H[36], Hfd[36], g[6];
        t.kernel(t.data, 0, x, g, H);
        fd_hessian(&t, 0, x, FD_STEP, Hfd);
        if (len > L * 1.001) { /* stretched: the exact Hessian, PSD */
            CR_CHECK(rel_diff(H, Hfd, 36) < 1e-5);
        } else if (len < L * 0.999) { /* compressed: the clamped one dominates the exact one */
            double D[36], w[6];
            for (int i = 0; i < 36; i++)
                D[i] = H[i] - Hfd[i];
            eigenvalues(D, 6, w);
            CR_CHECK(w[0] > -1e-5 * fd_max_abs(H, 36));
            CR_CHECK(w[5] > 1e-3 * fd_max_abs(H, 36)); /* and differs: the clamp acted */
        }
    }

    /* coincident ends: no gradient, energy 1 */
    double xc[6] = {0.1, 0.1, 0.1, 0.1, 0.1, 0.1}, gc[6], Hc[36];
    CR_CHECK_NEAR(t.kernel(t.data, 1, xc, gc, Hc), 1.0, 1e-12);
    CR_CHECK(fd_max_abs(gc, 6) == 0.0 && fd_max_abs(Hc, 36) == 0.0);

    /* storage reused once warm; bad elements refused naming the edge */
    const int32_t *elem = t.elem;
    CR_CHECK_OK(cr_drape_strain_set(s, edges, rest, 1, 3, &err), &err);
    cr_drape_strain_term(s, &t);
    CR_CHECK(t.elem == elem && t.nelem == 1);
    const float bad_rest[2] = {0.1f, 0.0f};
    CR_CHECK(cr_drape_strain_set(s, edges, bad_rest, 2, 3, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "edge 1") != NULL);
    const float nan_rest[2] = {NAN, 0.1f};
    CR_CHECK(cr_drape_strain_set(s, edges, nan_rest, 2, 3, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_drape_strain_set(s, edges, rest, 2, 2, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "edge 1") != NULL);
    cr_drape_strain_term(s, &t);
    CR_CHECK(t.nelem == 0); /* a refused set leaves an empty term */
    cr_drape_strain_destroy(s);
    cr_drape_strain_destroy(NULL);
}

/* --------------------------------------------------------------- bend -- */

/* A hinge over the edge x0 = (0,0,0), x1 = (1,0,0) (scaled by s): face A's
 * apex x2 in the plane y > 0, face B's apex x3 turned by phi out of it. The
 * faces' normals then make the angle phi. */
static void hinge(double phi, double s, double *x) {
    const double p[12] = {0, 0, 0, 1, 0, 0, 0.4, 0.9, 0, 0.6, -0.8 * cos(phi), 0.8 * sin(phi)};
    for (int i = 0; i < 12; i++)
        x[i] = s * p[i];
}

CR_TEST(phys_drape_energy, bend) {
    cr_error err = {0};
    cr_drape_bend *b = NULL;
    CR_CHECK_OK(cr_drape_bend_create(4, &b, &err), &err);
    CR_REQUIRE(b);
    const int32_t hinges[8] = {0, 1, 2, 3, 1, 2, 3, 0};
    CR_CHECK_OK(cr_drape_bend_set(b, hinges, 2, 4, &err), &err);
    cr_energy_term t;
    cr_drape_bend_term(b, &t);
    CR_CHECK(t.nelem == 2 && t.nvert == 4 && t.elem && t.elem[5] == 2);
    CR_CHECK(strcmp(t.name, "drape_bend") == 0);

    /* closed form: |n_A - n_B|^2 = 2 - 2 cos(phi); 0 flat, whatever the scale */
    double x[12];
    for (int k = 0; k <= 8; k++) {
        const double phi = k * 0.35;
        hinge(phi, 0.01, x);
        CR_CHECK_NEAR(fd_kval(&t, 0, x), 2.0 - 2.0 * cos(phi), 1e-12);
    }

    /* gradient against differences on random hinges near a fold */
    cr_rng r = cr_rng_make(11, 0);
    for (int trial = 0; trial < 20; trial++) {
        hinge(0.1 + 0.12 * trial, 0.02, x);
        for (int i = 0; i < 12; i++)
            x[i] += 0.002 * cr_rng_normal(&r);
        CR_CHECK(fd_grad_rel_error(&t, 0, x, FD_STEP * 0.01) < FD_RTOL);
        CR_CHECK(grad_same_with_hessian(&t, 0, x));
        CR_CHECK(kernel_hessian_psd(&t, 0, x));
    }

    /* Gauss-Newton equals the exact Hessian where the residual vanishes (flat,
     * randomly placed), and the gap grows with the fold */
    for (int trial = 0; trial < 5; trial++) {
        hinge(0.0, 0.02, x);
        const double shift[3] = {cr_rng_normal(&r), cr_rng_normal(&r), cr_rng_normal(&r)};
        for (int i = 0; i < 12; i++)
            x[i] += 0.1 * shift[i % 3];
        CR_CHECK(hess_rel_error(&t, 0, x, FD_STEP * 0.01) < 1e-5);
    }
    hinge(0.05, 0.02, x);
    const double gap_small = hess_rel_error(&t, 0, x, FD_STEP * 0.01);
    hinge(0.5, 0.02, x);
    const double gap_large = hess_rel_error(&t, 0, x, FD_STEP * 0.01);
    CR_CHECK(gap_small < gap_large && gap_small < 0.2);

    /* a degenerate face: 0, no gradient */
    double xd[12] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0.5, -1, 0.3}, gd[12], Hd[144];
    CR_CHECK(t.kernel(t.data, 0, xd, gd, Hd) == 0.0);
    CR_CHECK(fd_max_abs(gd, 12) == 0.0 && fd_max_abs(Hd, 144) == 0.0);

    const int32_t *elem = t.elem;
    CR_CHECK_OK(cr_drape_bend_set(b, hinges, 1, 4, &err), &err);
    cr_drape_bend_term(b, &t);
    CR_CHECK(t.elem == elem && t.nelem == 1);
    CR_CHECK(cr_drape_bend_set(b, hinges, 2, 3, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "hinge 0") != NULL);
    cr_drape_bend_destroy(b);
    cr_drape_bend_destroy(NULL);
}

/* ------------------------------------------------------------ gravity -- */

CR_TEST(phys_drape_energy, gravity) {
    cr_error err = {0};
    cr_drape_gravity *g = NULL;
    CR_CHECK_OK(cr_drape_gravity_create(1e-4, 9.81, &g, &err), &err);
    CR_REQUIRE(g);
    cr_drape_gravity_set_count(g, 7);
    cr_energy_term t;
    cr_drape_gravity_term(g, &t);
    CR_CHECK(t.nelem == 7 && t.nvert == 1 && t.elem == NULL);
    const double x[3] = {0.3, -0.25, 1.7};
    double gr[3], H[9];
    CR_CHECK_NEAR(t.kernel(t.data, 3, x, gr, H), 1e-4 * 9.81 * -0.25, 1e-18);
    CR_CHECK(gr[0] == 0.0 && gr[2] == 0.0);
    CR_CHECK_NEAR(gr[1], 1e-4 * 9.81, 1e-18);
    CR_CHECK(fd_max_abs(H, 9) == 0.0);
    CR_CHECK(fd_grad_rel_error(&t, 0, x, FD_STEP) < FD_RTOL);
    cr_drape_gravity_destroy(g);
    CR_CHECK(cr_drape_gravity_create(NAN, 9.81, &g, &err) == CR_ERR_NAN && g == NULL);
    cr_drape_gravity_destroy(NULL);
}

/* ---------------------------------------------------------- collision -- */

CR_TEST(phys_drape_energy, collision_vertex) {
    cr_error err = {0};
    cr_mesh *ball = NULL;
    cr_bvh *bvh = NULL;
    CR_CHECK_OK(cr_prim_icosphere(0.3f, 3, &ball, &err), &err);
    CR_REQUIRE(ball);
    CR_CHECK_OK(cr_bvh_build(ball->pos, ball->nv, ball->tri, ball->nf, &bvh, &err), &err);
    CR_REQUIRE(bvh);
    const double eps = 0.002;
    cr_drape_collision *c = NULL;
    CR_CHECK_OK(cr_drape_collision_create(bvh, CR_DRAPE_COLLIDE_VERTEX, eps, &c, &err), &err);
    CR_REQUIRE(c);
    cr_drape_collision_set_count(c, 5);
    cr_energy_term t;
    cr_drape_collision_term(c, &t);
    CR_CHECK(t.nelem == 5 && t.nvert == 1 && t.elem == NULL);

    const float *vn = cr_bvh_vertex_normals(bvh), *vp = cr_bvh_positions(bvh);
    const int32_t verts[4] = {0, 17, 101, 300};
    const double depth[4] = {-0.005, -0.001, 0.0015, 0.01}; /* along the vertex normal */
    for (int k = 0; k < 4; k++) {
        const int32_t v = verts[k];
        double x[3];
        for (int d = 0; d < 3; d++)
            x[d] = vp[3 * v + d] + depth[k] * vn[3 * v + d];
        const double m = fmin(depth[k] - eps, 0.0);
        CR_CHECK_NEAR(fd_kval(&t, 0, x), m * m, 1e-12);
        if (m == 0.0) continue;
        /* a small tangential offset keeps the vertex nearest: the FD sees one plane */
        for (int d = 0; d < 3; d++)
            x[d] += 1e-4 * (d == 0 ? 1.0 : -0.5);
        CR_CHECK(fd_grad_rel_error(&t, 0, x, FD_STEP) < FD_RTOL);
        CR_CHECK(hess_rel_error(&t, 0, x, FD_STEP) < 1e-5); /* exact: s linear in x */
        CR_CHECK(kernel_hessian_psd(&t, 0, x));
        CR_CHECK(grad_same_with_hessian(&t, 0, x));
    }
    /* outside the band, and outside the box grown by eps: 0 and no gradient */
    double far[3], g[3], H[9];
    for (int d = 0; d < 3; d++)
        far[d] = vp[d] + 0.0025 * vn[d];
    const double away[3] = {1.0, 0.0, 0.0};
    CR_CHECK(t.kernel(t.data, 0, far, g, H) == 0.0 && fd_max_abs(g, 3) == 0.0);
    CR_CHECK(t.kernel(t.data, 0, away, g, H) == 0.0 && fd_max_abs(g, 3) == 0.0);
    CR_CHECK(fd_max_abs(H, 9) == 0.0);
    cr_drape_collision_destroy(c);
    CR_CHECK(cr_drape_collision_create(bvh, (cr_drape_collision_mode)7, eps, &c, &err) ==
             CR_ERR_INVALID);
    cr_drape_collision_destroy(NULL);
    cr_bvh_destroy(bvh);
    cr_mesh_destroy(ball);
}

/* The vertex mode searches a tree of the object's vertices alone: at random
 * points in and around the ball its value is the brute-force nearest vertex's. */
CR_TEST(phys_drape_energy, collision_vertex_matches_brute_force) {
    cr_error err = {0};
    cr_mesh *ball = NULL;
    cr_bvh *bvh = NULL;
    CR_CHECK_OK(cr_prim_icosphere(0.3f, 3, &ball, &err), &err);
    CR_REQUIRE(ball);
    CR_CHECK_OK(cr_bvh_build(ball->pos, ball->nv, ball->tri, ball->nf, &bvh, &err), &err);
    CR_REQUIRE(bvh);
    const double eps = 0.05; /* a wide band, so most points have a value */
    cr_drape_collision *c = NULL;
    CR_CHECK_OK(cr_drape_collision_create(bvh, CR_DRAPE_COLLIDE_VERTEX, eps, &c, &err), &err);
    CR_REQUIRE(c);
    cr_drape_collision_set_count(c, 1);
    cr_energy_term t;
    cr_drape_collision_term(c, &t);
    const float *vn = cr_bvh_vertex_normals(bvh), *vp = cr_bvh_positions(bvh);
    cr_rng rng = cr_rng_make(5, 0);
    int nonzero = 0;
    for (int i = 0; i < 2000; i++) {
        double x[3];
        float xf[3];
        for (int d = 0; d < 3; d++) {
            xf[d] = 0.34f * (2.0f * cr_rng_uniformf(&rng) - 1.0f);
            x[d] = xf[d];
        }
        int32_t best = -1;
        double bd = INFINITY;
        for (int32_t v = 0; v < ball->nv; v++) {
            double d2 = 0;
            for (int d = 0; d < 3; d++) {
                double e = (double)xf[d] - vp[3 * v + d];
                d2 += e * e;
            }
            if (d2 < bd) bd = d2, best = v;
        }
        double s = 0;
        for (int d = 0; d < 3; d++)
            s += (x[d] - vp[3 * best + d]) * vn[3 * best + d];
        const double m = fmin(s - eps, 0.0);
        nonzero += m != 0.0;
        CR_CHECK_NEAR(fd_kval(&t, 0, x), m * m, 1e-15);
    }
    CR_CHECK(nonzero > 500);
    cr_drape_collision_destroy(c);
    cr_bvh_destroy(bvh);
    cr_mesh_destroy(ball);
}

CR_TEST(phys_drape_energy, collision_sdf) {
    cr_error err = {0};
    cr_mesh *box = NULL, *ball = NULL;
    cr_bvh *bvh = NULL;
    const double eps = 0.002;
    cr_drape_collision *c = NULL;
    cr_energy_term t;

    /* a box: inside near the face centres, s = -(depth below the face) */
    CR_CHECK_OK(cr_prim_box(0.4f, 0.4f, 0.4f, 2, &box, &err), &err);
    CR_REQUIRE(box);
    CR_CHECK_OK(cr_bvh_build(box->pos, box->nv, box->tri, box->nf, &bvh, &err), &err);
    CR_CHECK_OK(cr_drape_collision_create(bvh, CR_DRAPE_COLLIDE_SDF, eps, &c, &err), &err);
    CR_REQUIRE(c);
    cr_drape_collision_set_count(c, 3);
    cr_drape_collision_term(c, &t);
    const double pts[4][3] = {
        {0.03, 0.197, -0.05}, {0.196, 0.02, 0.07}, {-0.04, 0.06, -0.199}, {0.01, 0.2015, 0.02}};
    const double s_true[4] = {-0.003, -0.004, -0.001, 0.0015};
    for (int k = 0; k < 4; k++) {
        const double m = s_true[k] - eps;
        CR_CHECK_NEAR(fd_kval(&t, 0, pts[k]), m * m, 1e-9);
        CR_CHECK(fd_grad_rel_error(&t, 0, pts[k], 1e-5) < 1e-4);
        CR_CHECK(hess_rel_error(&t, 0, pts[k], 1e-5) < 1e-3); /* a plane: exact */
        CR_CHECK(kernel_hessian_psd(&t, 0, pts[k]));
    }
    const double clear[3] = {0.0, 0.21, 0.0};
    CR_CHECK(fd_kval(&t, 0, clear) == 0.0);
    cr_drape_collision_destroy(c);
    cr_bvh_destroy(bvh);

    /* a ball: below face centroids (the closest point inside that face), the
     * gradient follows the faceted surface; values (s - eps)^2 */
    CR_CHECK_OK(cr_prim_icosphere(0.3f, 4, &ball, &err), &err);
    CR_REQUIRE(ball);
    CR_CHECK_OK(cr_bvh_build(ball->pos, ball->nv, ball->tri, ball->nf, &bvh, &err), &err);
    CR_CHECK_OK(cr_drape_collision_create(bvh, CR_DRAPE_COLLIDE_SDF, eps, &c, &err), &err);
    cr_drape_collision_set_count(c, 1);
    cr_drape_collision_term(c, &t);
    const float *fn = cr_bvh_face_normals(bvh), *bp = cr_bvh_positions(bvh);
    const int32_t *tri = cr_bvh_triangles(bvh);
    for (int trial = 0; trial < 10; trial++) {
        const int32_t f = (int32_t)((trial * 977) % cr_bvh_face_count(bvh));
        const double depth = 0.0005 + 0.0003 * trial;
        double x[3];
        for (int d = 0; d < 3; d++) {
            double ctr = 0.0;
            for (int k = 0; k < 3; k++)
                ctr += bp[3 * tri[3 * f + k] + d] / 3.0;
            x[d] = ctr - depth * fn[3 * f + d];
        }
        CR_CHECK_NEAR(fd_kval(&t, 0, x), (depth + eps) * (depth + eps), 1e-9);
        /* the closest point comes back in float: 3e-8 m of noise in s, so a
         * longer step (s is linear in x within the face) */
        CR_CHECK(fd_grad_rel_error(&t, 0, x, 1e-4) < 1e-3);
        CR_CHECK(kernel_hessian_psd(&t, 0, x));
    }
    cr_drape_collision_destroy(c);
    cr_bvh_destroy(bvh);
    cr_mesh_destroy(ball);
    cr_mesh_destroy(box);
}
