/* test_phys_pin.c: kernels added for the losses: the pin energy, the
 * membrane's stretch and shear parts, bending with an explicit rest angle
 * and the collision penalty. Gradients against central differences of the
 * kernel values, Hessians against central differences of the gradients
 * (step 1e-6, relative 1e-5, in double), projected Hessians PSD.
 */
#include "crease/phys_energies.h"
#include "crease/primitives.h"
#include "crease/topology.h"
#include "phys/lapack.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define STEP 1e-6
#define RTOL 1e-5

static double max_abs(const double *a, int n) {
    double m = 0.0;
    for (int i = 0; i < n; i++)
        m = fmax(m, fabs(a[i]));
    return m;
}

/* Max |analytic - FD| of the gradient, relative to max |gradient|. */
static double grad_err(const cr_energy_term *t, int32_t e, const double *x0) {
    const int n = 3 * t->nvert;
    double x[12], g[12], err = 0.0;
    t->kernel(t->data, e, x0, g, NULL);
    memcpy(x, x0, sizeof(double) * (size_t)n);
    for (int i = 0; i < n; i++) {
        x[i] = x0[i] + STEP;
        const double ep = t->kernel(t->data, e, x, NULL, NULL);
        x[i] = x0[i] - STEP;
        const double em = t->kernel(t->data, e, x, NULL, NULL);
        x[i] = x0[i];
        err = fmax(err, fabs(g[i] - (ep - em) / (2.0 * STEP)));
    }
    return err / fmax(max_abs(g, n), 1e-300);
}

/* Max |H - FD(g)|, relative to max |H|. */
static double hess_err(const cr_energy_term *t, int32_t e, const double *x0) {
    const int n = 3 * t->nvert;
    double x[12], H[144], gp[12], gm[12], err = 0.0;
    t->kernel(t->data, e, x0, gp, H);
    memcpy(x, x0, sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        x[j] = x0[j] + STEP;
        t->kernel(t->data, e, x, gp, NULL);
        x[j] = x0[j] - STEP;
        t->kernel(t->data, e, x, gm, NULL);
        x[j] = x0[j];
        for (int i = 0; i < n; i++)
            err = fmax(err, fabs(H[i * n + j] - (gp[i] - gm[i]) / (2 * STEP)));
    }
    return err / fmax(max_abs(H, n * n), 1e-300);
}

/* Smallest eigenvalue of the kernel's Hessian relative to its largest |.|. */
static double hess_min_eig(const cr_energy_term *t, int32_t e, const double *x0) {
    int n = 3 * t->nvert, lwork = 12 * 34, info = 0;
    double H[144], w[12], work[12 * 34], g[12];
    t->kernel(t->data, e, x0, g, H);
    dsyev_("N", "U", &n, H, &n, w, work, &lwork, &info);
    CR_CHECK(info == 0);
    const double big = fmax(fabs(w[0]), fabs(w[n - 1]));
    return big > 0.0 ? w[0] / big : 0.0;
}

CR_TEST(phys_pin, pin_kernel) {
    cr_error err;
    cr_pin *p = NULL;
    const int32_t v[3] = {4, 0, 2};
    CR_CHECK_OK(cr_pin_create(5, v, 3, 120.0, &p, &err), &err);
    CR_REQUIRE(p);
    const double tg[9] = {0.1, 0.2, 0.3, -1, 0, 1, 0.5, 0.5, 0.5};
    cr_pin_set_targets(p, tg);
    cr_energy_term t;
    cr_pin_term(p, &t);
    CR_CHECK(t.nelem == 3 && t.nvert == 1 && t.elem && t.elem[0] == 4 && cr_pin_count(p) == 3);
    const double x[3] = {0.15, 0.1, 0.35};
    CR_CHECK_NEAR(t.kernel(t.data, 0, x, NULL, NULL), 60.0 * (0.0025 + 0.01 + 0.0025), 1e-12);
    CR_CHECK_NEAR(t.kernel(t.data, 0, tg, NULL, NULL), 0.0, 0.0); /* at the target */
    CR_CHECK(grad_err(&t, 0, x) < RTOL);
    CR_CHECK(hess_err(&t, 2, x) < RTOL);
    CR_CHECK(hess_min_eig(&t, 1, x) >= 0.0);
    cr_pin_destroy(p);
    /* bad input */
    const int32_t bad[1] = {5};
    CR_CHECK(cr_pin_create(5, bad, 1, 1.0, &p, &err) == CR_ERR_RANGE && p == NULL);
    CR_CHECK(strstr(err.msg, "vertex 5") != NULL);
    CR_CHECK(cr_pin_create(5, v, 3, -1.0, &p, &err) == CR_ERR_INVALID);
    cr_pin_destroy(NULL);
}

/* One triangle's vertices (9): its rest shape (the UV triangle, z = 0)
 * scaled by (sx, sy), sheared by `shear` and rotated out of plane. */
static void tri_state(const cr_mesh *m, double sx, double sy, double shear, double *x) {
    for (int k = 0; k < 3; k++) {
        const double u = m->uv[2 * k] * 0.5, v = m->uv[2 * k + 1] * 0.5;
        const double px = sx * u + shear * v, py = sy * v;
        /* a rotation: columns (0.8, 0.6, 0) and (-0.48, 0.64, 0.6) */
        x[3 * k] = 0.8 * px - 0.48 * py, x[3 * k + 1] = 0.6 * px + 0.64 * py;
        x[3 * k + 2] = 0.6 * py;
    }
}

static cr_mesh *one_triangle(void) {
    cr_mesh *m = NULL;
    cr_error err;
    CR_CHECK_OK(cr_mesh_create(3, 1, 3, &m, &err), &err);
    if (!m) return NULL;
    const float p[9] = {0.01f, 0.02f, 0, 0.11f, 0.03f, 0, 0.04f, 0.10f, 0};
    memcpy(m->pos, p, sizeof p);
    for (int k = 0; k < 3; k++) {
        m->tri[k] = m->tri_uv[k] = k;
        m->uv[2 * k] = p[3 * k] * 2.0f, m->uv[2 * k + 1] = p[3 * k + 1] * 2.0f;
    }
    return m;
}

CR_TEST(phys_pin, membrane_parts) {
    cr_error err;
    cr_mesh *m = one_triangle();
    CR_REQUIRE(m);
    for (int model = 0; model < 2; model++) {
        cr_material mat;
        CR_CHECK_OK(cr_material_preset("cotton", &mat, &err), &err);
        mat.membrane = model ? CR_MEMBRANE_BARAFF_WITKIN : CR_MEMBRANE_STVK;
        cr_membrane *mem = NULL;
        CR_CHECK_OK(cr_membrane_create(m, 1, 0.5f, &mat, &mem, &err), &err);
        CR_REQUIRE(mem);
        cr_energy_term t[3];
        for (int p = 0; p < 3; p++)
            cr_membrane_term_part(mem, (cr_membrane_part)p, &t[p]);
        cr_energy_term whole;
        cr_membrane_term(mem, &whole);
        CR_CHECK(whole.kernel == t[0].kernel && strcmp(t[1].name, "membrane_stretch") == 0 &&
                 strcmp(t[2].name, "membrane_shear") == 0);
        double x[9];
        /* a pure stretch has no shear energy; a shear has some */
        tri_state(m, 1.1, 0.95, 0.0, x);
        CR_CHECK(t[1].kernel(t[1].data, 0, x, NULL, NULL) > 0.0);
        CR_CHECK_NEAR(t[2].kernel(t[2].data, 0, x, NULL, NULL), 0.0, 1e-12);
        tri_state(m, 1.0, 1.0, 0.2, x);
        CR_CHECK(t[2].kernel(t[2].data, 0, x, NULL, NULL) > 0.0);
        /* the closed forms at a known state: StVK stretch-only F = diag(s1, s2) */
        if (!model) {
            tri_state(m, 1.1, 0.9, 0.0, x);
            const double E11 = 0.5 * (1.21 - 1.0), E22 = 0.5 * (0.81 - 1.0);
            const double A0 = cr_membrane_rest_areas(mem)[0];
            const double want = A0 * (mat.lame_mu * (E11 * E11 + E22 * E22) +
                                      0.5 * mat.lame_lambda * (E11 + E22) * (E11 + E22));
            CR_CHECK_NEAR(t[1].kernel(t[1].data, 0, x, NULL, NULL), want, 1e-9 * want);
        }
        /* gradients at general states, parts sum to the whole */
        const double states[4][3] = {
            {1.1, 0.95, 0.1}, {0.8, 0.9, -0.2}, {1.3, 1.05, 0.3}, {0.7, 1.2, 0.05}};
        for (int s = 0; s < 4; s++) {
            tri_state(m, states[s][0], states[s][1], states[s][2], x);
            double g[3][9];
            for (int p = 0; p < 3; p++) {
                CR_CHECK(grad_err(&t[p], 0, x) < RTOL);
                t[p].kernel(t[p].data, 0, x, g[p], NULL);
                CR_CHECK(hess_min_eig(&t[p], 0, x) > -1e-9);
            }
            const double e0 = t[0].kernel(t[0].data, 0, x, NULL, NULL);
            CR_CHECK_NEAR(t[1].kernel(t[1].data, 0, x, NULL, NULL) +
                              t[2].kernel(t[2].data, 0, x, NULL, NULL),
                          e0, 1e-12 * e0);
            for (int i = 0; i < 9; i++)
                CR_CHECK_NEAR(g[1][i] + g[2][i], g[0][i], 1e-9 * max_abs(g[0], 9));
        }
        /* Hessians where the exact ones are PSD (no projection): the
         * stretch part under tension, the shear part without shear */
        tri_state(m, 1.2, 1.1, 0.0, x);
        CR_CHECK(hess_err(&t[1], 0, x) < RTOL);
        CR_CHECK(hess_err(&t[2], 0, x) < RTOL);
        /* Gauss-Newton mode: the shear part's Hessian is its outer product */
        cr_membrane_set_hessian(mem, CR_HESSIAN_GAUSS_NEWTON);
        tri_state(m, 1.0, 1.0, 0.0, x);
        CR_CHECK(hess_err(&t[2], 0, x) < RTOL);
        cr_membrane_destroy(mem);
    }
    cr_mesh_destroy(m);
}

CR_TEST(phys_pin, bending_rest_and_collision_penalty) {
    cr_error err;
    cr_mesh *m = NULL;
    cr_topology *topo = NULL;
    cr_bending *b = NULL;
    cr_material mat;
    CR_CHECK_OK(cr_material_preset("cotton", &mat, &err), &err);
    CR_CHECK_OK(cr_prim_plane(2, 2, 0.1f, 0.1f, &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK_OK(cr_topology_build(m, &topo, &err), &err);
    CR_REQUIRE(topo);
    CR_CHECK_OK(cr_bending_create(m, topo, &mat, 0, &b, &err), &err);
    CR_REQUIRE(b && cr_bending_count(b) == 1);
    const int32_t *h = cr_bending_hinges(b);
    double x[12];
    for (int k = 0; k < 4; k++)
        for (int d = 0; d < 3; d++)
            x[3 * k + d] = m->pos[3 * h[k] + d];
    x[3 * 2 + 1] += 0.02, x[3 * 3 + 1] += 0.015; /* fold the two wings */
    const double rest = 0.3;
    double g[12], gr = 0.0;
    const double e = cr_bending_kernel_rest(b, 0, rest, x, g, NULL, &gr);
    CR_CHECK(e > 0.0);
    const double ep = cr_bending_kernel_rest(b, 0, rest + STEP, x, NULL, NULL, NULL);
    const double em = cr_bending_kernel_rest(b, 0, rest - STEP, x, NULL, NULL, NULL);
    CR_CHECK_NEAR(gr, (ep - em) / (2 * STEP), RTOL * fabs(gr));
    /* with b's own rest angle it is the term's kernel */
    cr_energy_term t;
    cr_bending_term(b, &t);
    CR_CHECK_NEAR(cr_bending_kernel_rest(b, 0, cr_bending_rest_angles(b)[0], x, NULL, NULL, NULL),
                  t.kernel(t.data, 0, x, NULL, NULL), 0.0);
    /* collision penalty: value, gradient along n, zero outside eps */
    const double n[3] = {0.0, 0.6, 0.8}, k = 1e6, eps = 2e-3;
    double gc[3], Hc[9];
    CR_CHECK_NEAR(cr_collision_penalty(k, eps, -1e-3, n, gc, Hc), k * 27e-9, 1e-15);
    CR_CHECK_NEAR(gc[2], -3.0 * k * 9e-6 * 0.8, 1e-9);
    CR_CHECK_NEAR(Hc[4], 6.0 * k * 3e-3 * 0.36, 1e-9);
    const double dp = cr_collision_penalty(k, eps, -1e-3 + STEP, n, NULL, NULL);
    const double dm = cr_collision_penalty(k, eps, -1e-3 - STEP, n, NULL, NULL);
    CR_CHECK_NEAR(-3.0 * k * 9e-6, (dp - dm) / (2 * STEP), 1e-5); /* dE/dd; FD error k h^2 */
    CR_CHECK(cr_collision_penalty(k, eps, 3e-3, n, gc, NULL) == 0.0 && gc[1] == 0.0);
    cr_bending_destroy(b);
    cr_topology_destroy(topo);
    cr_mesh_destroy(m);
}
