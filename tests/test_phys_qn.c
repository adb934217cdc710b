/* test_phys_qn.c: quasi-Newton (src/phys/qn.c) against Newton on the same
 * incremental potential, and the physical outcomes the Newton tests check
 * (test_phys_sim.c), run with def.solver = CR_SIM_SOLVER_QN. */
#include "crease/phys_sim.h"
#include "crease/primitives.h"
#include "sim_fixture.h"
#include "test.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static cr_sim_def qn_def(void) {
    cr_sim_def d = fixture_cotton_def();
    d.solver = CR_SIM_SOLVER_QN;
    return d;
}

/* Hanging in the XY plane from its top edge, pushed out of plane by a bump. */
static cr_mesh *hanging_cloth(int32_t n, float size, float bump) {
    cr_mesh *m = fixture_flat_cloth(n, size, 0.0f);
    if (!m) return NULL;
    for (int32_t v = 0; v < m->nv; v++) {
        float *p = m->pos + 3 * v;
        float u = p[0] / size + 0.5f, w = p[2] / size + 0.5f;
        p[1] = -w * size;
        p[2] = bump * sinf(3.14159265f * u) * sinf(3.14159265f * w);
    }
    return m;
}

static double max_diff(const double *a, const double *b, int64_t n) {
    double m = 0.0;
    for (int64_t k = 0; k < n; k++)
        m = fmax(m, fabs(a[k] - b[k]));
    return m;
}

CR_TEST(phys_qn, solver_names_and_fields) {
    CR_CHECK(cr_sim_solver_parse("qn") == CR_SIM_SOLVER_QN);
    CR_CHECK(strcmp(cr_sim_solver_name(CR_SIM_SOLVER_QN), "qn") == 0);
    cr_mesh *m = fixture_flat_cloth(4, 0.2f, 0.0f);
    CR_REQUIRE(m);
    const char *field[3] = {"qn_history", "qn_tol", "qn_iterations"};
    for (int k = 0; k < 3; k++) {
        cr_sim_def d = qn_def();
        if (k == 0) d.qn_history = 0;
        if (k == 1) d.qn_tol = -1.0;
        if (k == 2) d.qn_iterations = 0;
        cr_sim *s = NULL;
        cr_error err = {0};
        CR_CHECK(cr_sim_create(&d, m, &s, &err) == CR_ERR_INVALID && !s);
        CR_CHECK(strstr(err.msg, field[k]) != NULL);
    }
    cr_mesh_destroy(m);
}

typedef struct trace {
    int n, rises;
    double last;
} trace;

static void record(void *ctx, int it, double energy, double gnorm, double step) {
    trace *t = ctx;
    (void)gnorm, (void)step;
    if (it > 0 && energy > t->last) t->rises++;
    t->last = energy;
    t->n++;
}

/* Run to a tight tolerance, quasi-Newton reaches Newton's minimiser: a
 * swinging, bumped 10 x 10 cloth at a substep of 1/300 s (inertia makes each
 * substep's objective convex enough for one minimiser), within 1e-6 m of
 * converged Newton after each of 10 frames, every iteration lowering the
 * objective (no collider: one objective per substep), one factorisation a
 * frame where no substep needs a refresh. */
CR_TEST(phys_qn, converges_to_newton) {
    cr_mesh *m = hanging_cloth(10, 0.5f, 0.04f);
    CR_REQUIRE(m);
    cr_sim_def d = qn_def();
    int32_t pins[2] = {0, 9};
    d.pinned = pins, d.npinned = 2;
    d.dt = 1.0 / 300.0;
    d.newton_tol = 1e-9, d.newton_rtol = 0.0, d.newton_max_iterations = 100;
    d.qn_tol = 1e-5, d.qn_iterations = 500;
    trace tr = {0, 0, 0.0};
    d.on_iteration = record, d.on_iteration_ctx = &tr;
    cr_error err = {0};
    cr_sim *q = NULL, *n = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &q, &err), &err);
    d.solver = CR_SIM_SOLVER_NEWTON, d.on_iteration = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &n, &err), &err);
    CR_REQUIRE(q && n);
    cr_sim_report rq, rn;
    double worst = 0.0, far = 0.0;
    int iterations = 0, factorisations = 0, newton = 0;
    for (int f = 0; f < 10; f++) {
        CR_CHECK_OK(cr_sim_step(q, &rq, &err), &err);
        CR_CHECK_OK(cr_sim_step(n, &rn, &err), &err);
        iterations += rq.newton_iterations, factorisations += rq.factorisations;
        newton += rn.factorisations;
        CR_CHECK(rq.newton_capped == 0);
        worst = fmax(worst, max_diff(cr_sim_positions(q), cr_sim_positions(n), 3 * (int64_t)m->nv));
    }
    for (int64_t k = 0; k < 3 * (int64_t)m->nv; k++)
        far = fmax(far, fabs(cr_sim_positions(n)[k] - m->pos[k]));
    printf("    largest difference %.2e m (the cloth moved %.2e m); %d iterations and %d "
           "factorisations (Newton %d), %d rises in %d\n",
           worst, far, iterations, factorisations, newton, tr.rises, tr.n);
    CR_CHECK(far > 5e-4);
    CR_CHECK(worst < 1e-6);
    CR_CHECK(tr.n > 0 && tr.rises == 0);
    cr_sim_destroy(q);
    cr_sim_destroy(n);
    cr_mesh_destroy(m);
}

/* The drop on the sphere: nothing inside at the end or deeper than 1 mm in
 * any substep; the cloth drapes over the top. */
CR_TEST(phys_qn, cloth_dropped_on_sphere) {
    enum { FRAMES = 30 };
    cr_mesh *cloth = fixture_flat_cloth(32, 1.0f, 0.34f), *sphere = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    cr_sim_def d = qn_def();
    d.collider = sphere;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    double pen = 0;
    int iters = 0, backoffs = 0, factorisations = 0;
    for (int f = 0; f < FRAMES; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        pen = fmax(pen, rep.max_penetration_m);
        iters += rep.newton_iterations, backoffs += rep.backoffs;
        factorisations += rep.factorisations;
    }
    const double *x = cr_sim_positions(s);
    double deepest = fixture_deepest_inside(sphere, x, cloth->nv), top = -INFINITY;
    for (int32_t i = 0; i < cloth->nv; i++)
        top = fmax(top, x[3 * i + 1]);
    int32_t centre = 16 * 32 + 16;
    printf("    qn sphere 32x32: deepest %.2e m (before projection %.2e m), %d contacts, %.1f "
           "iterations per frame, %d backoffs, %d factorisations; highest vertex %.4f m, centre "
           "%.4f m\n",
           deepest, pen, rep.contacts, iters / (double)FRAMES, backoffs, factorisations, top,
           x[3 * centre + 1]);
    CR_CHECK(deepest < 1e-3);
    CR_CHECK(pen < 1e-3);
    CR_CHECK(rep.contacts > 10);
    CR_CHECK(top > 0.298 && top < 0.34);
    CR_CHECK(x[3 * centre + 1] > 0.28);
    CR_CHECK(x[1] < 0.25);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* The door-like swing of test_phys_sim.c: pinned at two corners, it swings
 * down and settles (implicit Euler's damping). */
CR_TEST(phys_qn, hanging_cloth_settles) {
    cr_mesh *m = fixture_flat_cloth(12, 0.5f, 0.0f);
    CR_REQUIRE(m);
    cr_sim_def d = qn_def();
    int32_t pins[2] = {0, 11};
    d.pinned = pins, d.npinned = 2;
    d.damping = 2.0;
    cr_error err = {0};
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    double ke_peak = 0, ke = 0;
    for (int f = 0; f < 300; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        ke_peak = fmax(ke_peak, rep.kinetic_energy);
        if (f >= 240) ke += rep.kinetic_energy / 60.0;
    }
    const double *x = cr_sim_positions(s);
    double cy = 0.0;
    for (int32_t v = 0; v < m->nv; v++)
        cy += x[3 * v + 1] / m->nv;
    printf("    qn hanging: KE peak %.3e J, mean over 8-10 s %.3e J, centroid %.3f m below the "
           "pins\n",
           ke_peak, ke, -cy);
    CR_CHECK(ke_peak > 1e-5);
    CR_CHECK(ke < 0.01 * ke_peak);
    CR_CHECK(cy < -0.15);
    CR_CHECK(x[0] == (double)m->pos[0] && x[3 * 11 + 1] == (double)m->pos[3 * 11 + 1]);
    cr_sim_destroy(s);
    cr_mesh_destroy(m);
}

CR_TEST(phys_qn, fold_persists_with_plasticity) {
    double plastic = fixture_fold_strip(CR_SIM_SOLVER_QN, 1, 90, NULL),
           elastic = fixture_fold_strip(CR_SIM_SOLVER_QN, 0, 90, NULL);
    printf("    qn fold angle after release: %.1f deg plastic, %.1f deg elastic\n", plastic,
           elastic);
    CR_CHECK(plastic > 30.0);
    CR_CHECK(elastic < 5.0);
}

/* A small drop with plasticity and friction, for determinism and resume. */
static cr_sim *small_drop(cr_mesh **cloth, cr_mesh **sphere) {
    cr_error err = {0};
    *cloth = fixture_flat_cloth(12, 0.6f, 0.33f);
    if (cr_prim_sphere_uv(0.3f, 24, 12, sphere, &err) != CR_OK) return NULL;
    cr_sim_def d = qn_def();
    d.collider = *sphere;
    d.plasticity = 1;
    d.material.yield_angle = 0.1;
    cr_sim *s = NULL;
    cr_sim_create(&d, *cloth, &s, &err);
    return s;
}

/* Same inputs: the same bits. A run resumed from a state file factorises
 * the same initial matrix (it depends on the mesh, the material and h only)
 * and continues bit for bit. */
CR_TEST(phys_qn, deterministic_and_resumes_bit_identically) {
    cr_mesh *cloth = NULL, *sphere = NULL, *c2 = NULL, *s2 = NULL, *c3 = NULL, *s3 = NULL;
    cr_sim *s = small_drop(&cloth, &sphere), *r = small_drop(&c2, &s2),
           *again = small_drop(&c3, &s3);
    CR_REQUIRE(s && r && again);
    cr_error err = {0};
    char path[512];
    snprintf(path, sizeof path, "%s/qn_state.bin", cr_test_tmpdir());
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    CR_CHECK_OK(cr_sim_state_save(s, path, &err), &err);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    for (int f = 0; f < 12; f++)
        CR_CHECK_OK(cr_sim_step(again, NULL, &err), &err);
    CR_CHECK_OK(cr_sim_state_load(r, path, &err), &err);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(r, NULL, &err), &err);
    CR_CHECK(cr_sim_frame(r) == 12);
    CR_CHECK(cr_sim_state_hash(again) == cr_sim_state_hash(s));
    CR_CHECK(cr_sim_state_hash(r) == cr_sim_state_hash(s));
    cr_sim_destroy(s), cr_sim_destroy(r), cr_sim_destroy(again);
    cr_mesh_destroy(cloth), cr_mesh_destroy(sphere), cr_mesh_destroy(c2), cr_mesh_destroy(s2);
    cr_mesh_destroy(c3), cr_mesh_destroy(s3);
}

/* A frame that fails backs off to more substeps (a new h: the matrix is
 * factorised again) and, failing for good, restores the frame's start. */
CR_TEST(phys_qn, divergence_backs_off_or_reports) {
    cr_error err = {0};
    cr_mesh *cloth = fixture_flat_cloth(8, 0.5f, 0.0f);
    cr_sim_def d = qn_def();
    d.max_speed = 0.02; /* a free fall breaks it in any substep of a frame */
    d.max_backoff = 2;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    uint64_t h0 = cr_sim_state_hash(s);
    cr_sim_report rep;
    cr_status st = cr_sim_step(s, &rep, &err);
    printf("    qn speed limit: %s (%d backoffs, %d substeps, %d factorisations)\n",
           cr_status_str(st), rep.backoffs, rep.substeps, rep.factorisations);
    CR_CHECK(st == CR_ERR_DIVERGED && rep.diverged && rep.backoffs == 2);
    CR_CHECK(rep.factorisations >= 3); /* at h, h/2 and h/4 at least */
    CR_CHECK(strstr(err.msg, "frame 0") != NULL);
    CR_CHECK(cr_sim_state_hash(s) == h0 && cr_sim_frame(s) == 0);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
}
