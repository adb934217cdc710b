/* test_phys_vbd.c: vertex block descent (src/phys/vbd.c) against Newton on
 * the same incremental potential, and the physical outcomes the Newton tests
 * check (test_phys_sim.c), run with def.solver = CR_SIM_SOLVER_VBD. */
#include "crease/bvh.h"
#include "crease/phys_sim.h"
#include "crease/primitives.h"
#include "phys/sim_internal.h"
#include "sim_fixture.h"
#include "test.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

static cr_sim_def vbd_def(void) {
    cr_sim_def d = fixture_cotton_def();
    d.solver = CR_SIM_SOLVER_VBD;
    return d;
}

static double max_diff(const double *a, const double *b, int64_t n) {
    double m = 0.0;
    for (int64_t k = 0; k < n; k++)
        m = fmax(m, fabs(a[k] - b[k]));
    return m;
}

typedef struct trace {
    int n;
    double e[4096];
} trace;

static void record(void *ctx, int it, double energy, double gnorm, double step) {
    trace *t = ctx;
    (void)it, (void)gnorm, (void)step;
    if (t->n < 4096) t->e[t->n++] = energy;
}

CR_TEST(phys_vbd, solver_names) {
    CR_CHECK(cr_sim_solver_parse("vbd") == CR_SIM_SOLVER_VBD);
    CR_CHECK(cr_sim_solver_parse("newton") == CR_SIM_SOLVER_NEWTON);
    CR_CHECK(cr_sim_solver_parse("cg") == -1 && cr_sim_solver_parse(NULL) == -1);
    CR_CHECK(strcmp(cr_sim_solver_name(CR_SIM_SOLVER_VBD), "vbd") == 0);
    cr_sim_def d = vbd_def();
    d.vbd_chebyshev = 1.0;
    cr_mesh *m = fixture_flat_cloth(4, 0.2f, 0.0f);
    cr_sim *s = NULL;
    cr_error err = {0};
    CR_CHECK(cr_sim_create(&d, m, &s, &err) == CR_ERR_INVALID && !s);
    CR_CHECK(strstr(err.msg, "vbd_chebyshev") != NULL);
    cr_mesh_destroy(m);
}

static double total_energy(const cr_sim_report *r) {
    double e = 0.0;
    for (int t = 0; t < r->nterms; t++)
        e += r->term_energy[t];
    return e;
}

/* A swinging, bumped 10 x 10 cloth. At a substep of 1/300 s VBD run to
 * convergence follows Newton's converged trajectory: within 1e-5 m after
 * each of 10 frames (3e-6 m measured; the cloth is 0.5 m wide and moves 2 mm). At
 * 1/30 s Gauss-Seidel's tail is long (the membrane is some 1e4 times stiffer
 * than the inertia per vertex): after 3000 sweeps the iterate is still
 * 0.8 mm from Newton's, but its objective is within 1e-4 of Newton's
 * minimum, and above it, as it must be. */
CR_TEST(phys_vbd, converges_to_newton) {
    cr_mesh *m = hanging_cloth(10, 0.5f, 0.04f);
    CR_REQUIRE(m);
    for (int pass = 0; pass < 2; pass++) {
        cr_sim_def d = vbd_def();
        int32_t pins[2] = {0, 9};
        d.pinned = pins, d.npinned = 2;
        d.dt = pass == 0 ? 1.0 / 300.0 : 1.0 / 30.0;
        d.newton_tol = 1e-9, d.newton_rtol = 0.0, d.newton_max_iterations = 200;
        d.vbd_iterations = pass == 0 ? 1000 : 3000;
        d.vbd_hessian_every = 1;
        cr_error err = {0};
        cr_sim *v = NULL, *n = NULL;
        CR_CHECK_OK(cr_sim_create(&d, m, &v, &err), &err);
        d.solver = CR_SIM_SOLVER_NEWTON;
        CR_CHECK_OK(cr_sim_create(&d, m, &n, &err), &err);
        CR_REQUIRE(v && n);
        cr_sim_report rv, rn;
        int frames = pass == 0 ? 10 : 1;
        double worst = 0.0, far = 0.0;
        for (int f = 0; f < frames; f++) {
            CR_CHECK_OK(cr_sim_step(v, &rv, &err), &err);
            CR_CHECK_OK(cr_sim_step(n, &rn, &err), &err);
            worst =
                fmax(worst, max_diff(cr_sim_positions(v), cr_sim_positions(n), 3 * (int64_t)m->nv));
        }
        for (int64_t k = 0; k < 3 * (int64_t)m->nv; k++)
            far = fmax(far, fabs(cr_sim_positions(n)[k] - m->pos[k]));
        double ev = total_energy(&rv), en = total_energy(&rn);
        printf("    dt %.4f s, %d frames: largest difference %.2e m (the cloth moved %.2e m); "
               "objective VBD %.9e, Newton %.9e J\n",
               d.dt, frames, worst, far, ev, en);
        CR_CHECK(far > 5e-4);
        CR_CHECK(rv.factorisations == 0 && rn.factorisations > 0);
        if (pass == 0) {
            CR_CHECK(worst < 1e-5);
        } else {
            CR_CHECK(ev >= en - 1e-12);
            CR_CHECK(ev - en < 1e-4 * fabs(en));
        }
        cr_sim_destroy(v);
        cr_sim_destroy(n);
    }
    cr_mesh_destroy(m);
}

/* The sweep gathers each vertex's gradient and Hessian block from the
 * energies' vertex-block kernels (cr_energy_term.vertex_block); without them
 * (terms that have none) it slices the element kernels' full gradient and
 * Hessian instead. Both give the same trajectory, to roundoff. */
CR_TEST(phys_vbd, vertex_blocks_match_full_kernels) {
    cr_mesh *m = hanging_cloth(10, 0.5f, 0.04f);
    CR_REQUIRE(m);
    cr_sim_def d = vbd_def();
    int32_t pins[2] = {0, 9};
    d.pinned = pins, d.npinned = 2;
    cr_error err = {0};
    cr_sim *a = NULL, *b = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &a, &err), &err);
    CR_CHECK_OK(cr_sim_create(&d, m, &b, &err), &err);
    CR_REQUIRE(a && b);
    int blocks = 0;
    for (int t = 0; t < b->nterms; t++) {
        blocks += b->terms[t].vertex_block != NULL;
        b->terms[t].vertex_block = NULL;
    }
    CR_CHECK(blocks == 2); /* membrane and bending */
    double worst = 0.0;
    for (int f = 0; f < 5; f++) {
        CR_CHECK_OK(cr_sim_step(a, NULL, &err), &err);
        CR_CHECK_OK(cr_sim_step(b, NULL, &err), &err);
        worst = fmax(worst, max_diff(cr_sim_positions(a), cr_sim_positions(b), 3 * (int64_t)m->nv));
    }
    printf("    blocks vs full kernels: largest difference %.2e m after 5 frames\n", worst);
    CR_CHECK(worst < 1e-9);
    cr_sim_destroy(a);
    cr_sim_destroy(b);
    cr_mesh_destroy(m);
}

/* Every sweep lowers the objective, with and without Chebyshev. */
CR_TEST(phys_vbd, energy_decreases_per_iteration) {
    cr_mesh *m = hanging_cloth(12, 0.5f, 0.03f);
    CR_REQUIRE(m);
    for (int cheb = 0; cheb < 2; cheb++) {
        cr_sim_def d = vbd_def();
        int32_t pins[2] = {0, 11};
        d.pinned = pins, d.npinned = 2;
        d.vbd_chebyshev = cheb ? 0.9 : 0.0;
        d.vbd_iterations = 60;
        d.newton_tol = 1e-12;
        static trace tr;
        tr.n = 0;
        d.on_iteration = record, d.on_iteration_ctx = &tr;
        cr_error err = {0};
        cr_sim *s = NULL;
        CR_CHECK_OK(cr_sim_create(&d, m, &s, &err), &err);
        CR_REQUIRE(s);
        int bad = 0;
        for (int f = 0; f < 3; f++) {
            tr.n = 0;
            CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
            CR_CHECK(tr.n >= 10);
            for (int i = 1; i < tr.n; i++)
                bad += tr.e[i] > tr.e[i - 1];
        }
        printf("    chebyshev %.1f: last frame energy %.6e -> %.6e J over %d sweeps, %d rises\n",
               d.vbd_chebyshev, tr.e[0], tr.e[tr.n - 1], tr.n, bad);
        CR_CHECK(bad == 0);
        CR_CHECK(tr.e[tr.n - 1] < tr.e[0]);
        cr_sim_destroy(s);
    }
    cr_mesh_destroy(m);
}

/* The 32 x 32 drop of test_phys_sim.c with VBD: rests outside the sphere,
 * draped over its top, and no vertex is more than 1 mm inside before the
 * projection of any substep (the fast-solver issue's bound). With the
 * material's collider penalty (vbd_collision_scale 1) VBD left 3.6 mm at 30
 * sweeps: its Gauss-Seidel leaves the impact's load on the first vertices in
 * contact (about 100 N each); at the default scale 10, 0 mm. */
CR_TEST(phys_vbd, cloth_dropped_on_sphere) {
    enum { FRAMES = 30 };
    cr_mesh *cloth = fixture_flat_cloth(32, 1.0f, 0.34f), *sphere = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    cr_sim_def d = vbd_def();
    d.collider = sphere;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    double pen = 0, secs = 0;
    int iters = 0, backoffs = 0;
    for (int f = 0; f < FRAMES; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        pen = fmax(pen, rep.max_penetration_m);
        iters += rep.newton_iterations, backoffs += rep.backoffs, secs += rep.seconds;
    }
    const double *x = cr_sim_positions(s);
    double deepest = fixture_deepest_inside(sphere, x, cloth->nv);
    printf("    VBD sphere 32x32: deepest %.2e m (before projection %.2e m), %d contacts, %.1f "
           "sweeps per substep, %d backoffs, %.1f ms per frame\n",
           deepest, pen, rep.contacts, iters / (double)FRAMES, backoffs, 1e3 * secs / FRAMES);
    CR_CHECK(deepest < 1e-3);
    CR_CHECK(pen < 1e-3);
    CR_CHECK(rep.contacts > 10);
    /* It drapes over the top. The cloth's centre creeps sideways: the
     * unconverged membrane leaves a residual force that friction does not
     * hold (converged Newton: no creep). Measured over the 30 frames: 10 cm
     * at 20 sweeps before the vertex blocks (the centre then back at y 0.307
     * by chance), 7 cm at 20 sweeps after, 2.8 cm at 30 (the default). */
    int32_t centre = 16 * 32 + 16;
    double top = -INFINITY;
    for (int32_t i = 0; i < cloth->nv; i++)
        top = fmax(top, x[3 * i + 1]);
    const double creep = hypot(x[3 * centre] - cloth->pos[3 * centre],
                               x[3 * centre + 2] - cloth->pos[3 * centre + 2]);
    printf("    highest vertex %.4f m, centre at %.4f m, crept %.1f cm\n", top, x[3 * centre + 1],
           1e2 * creep);
    CR_CHECK(top > 0.298 && top < 0.34);
    CR_CHECK(x[3 * centre + 1] > 0.28 && creep < 0.1);
    CR_CHECK(x[1] < 0.25);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* The selective re-query of the collider between sweeps (vbd_requery_move)
 * against querying every vertex every sweep (0), on the sphere drop.
 * - At a move tolerance of 1e-9 of the thickness only the skip of vertices
 *   that cannot be within the thickness is left: the same bits (the skip is
 *   exact, by the distance's 1-Lipschitz bound).
 * - At the default 0.05, the trajectories differ by less than the sweeps' own
 *   stopping tolerance (newton_tol h, 33 um). That tolerance is the solver's
 *   noise floor: a 1 um nudge of one vertex of the falling cloth moved the
 *   first frame by 10-100 um (the sweep count changes), and from the first
 *   buckles on, any difference grows (Newton's too: 1 um became 2 mm by
 *   frame 8), so the comparison stops at 6 frames (13 contacts). Measured:
 *   2.9 um after 6 frames, 0.78 mm after 12 (0.22 mm at a tolerance of 0.005). */
CR_TEST(phys_vbd, selective_requery_matches_full) {
    enum { FRAMES = 6 };
    static const double move[3] = {0.05, 1e-9, 0.0};
    cr_mesh *cloth = fixture_flat_cloth(24, 1.0f, 0.34f), *sphere = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    cr_sim *s[3] = {NULL, NULL, NULL};
    cr_sim_def d = vbd_def();
    d.collider = sphere;
    for (int k = 0; k < 3; k++) {
        d.vbd_requery_move = move[k];
        CR_CHECK_OK(cr_sim_create(&d, cloth, &s[k], &err), &err);
        CR_REQUIRE(s[k]);
    }
    int64_t requeries[3] = {0, 0, 0};
    int contacts = 0;
    for (int f = 0; f < FRAMES; f++) {
        cr_sim_report rep;
        for (int k = 0; k < 3; k++) {
            CR_CHECK_OK(cr_sim_step(s[k], &rep, &err), &err);
            requeries[k] += rep.vbd_requeries;
        }
        contacts = rep.contacts;
    }
    const int64_t n3 = 3 * (int64_t)cloth->nv;
    const double diff = max_diff(cr_sim_positions(s[0]), cr_sim_positions(s[2]), n3);
    const double exact = max_diff(cr_sim_positions(s[1]), cr_sim_positions(s[2]), n3);
    printf("    after %d frames (%d contacts): vertex re-queries %lld at 0.05, %lld at 1e-9; "
           "largest difference from the full re-query %.2e m and %.2e m\n",
           FRAMES, contacts, (long long)requeries[0], (long long)requeries[1], diff, exact);
    CR_CHECK(contacts > 10);
    CR_CHECK(requeries[2] == 0); /* 0 takes cr_sim_query_collider's path */
    CR_CHECK(requeries[0] > 0 && requeries[0] < requeries[1]);
    CR_CHECK(exact == 0.0);
    CR_CHECK(diff < d.newton_tol * d.dt / d.substeps);
    for (int k = 0; k < 3; k++)
        cr_sim_destroy(s[k]);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* The door-like swing of test_phys_sim.c. Unconverged (every substep takes
 * all its sweeps), VBD dissipates far less than converged implicit Euler
 * (whose numerical damping ends the swing in 4 s): the kinetic energy falls
 * non-monotonically and can surge again (a later peak above the first: the
 * unconverged iterate adds energy), to 2 % of its peak after 10 s (measured
 * at 30 sweeps; 2 % at 20 before the vertex blocks, 5.1 % at 20 after: the
 * outcome is chaotic in roundoff; 36 % after the faster kernels of issue
 * 16), so the test runs 10 s and asks the mean over its last 2 s for 30 %. */
CR_TEST(phys_vbd, hanging_cloth_settles) {
    cr_mesh *m = fixture_flat_cloth(12, 0.5f, 0.0f);
    CR_REQUIRE(m);
    cr_sim_def d = vbd_def();
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
        if (f >= 240) ke += rep.kinetic_energy / 60.0; /* the last 2 s */
    }
    const double *x = cr_sim_positions(s);
    double cy = 0.0;
    for (int32_t v = 0; v < m->nv; v++)
        cy += x[3 * v + 1] / m->nv;
    printf("    VBD hanging: KE peak %.3e J, mean over 8-10 s %.3e J, centroid %.3f m below the "
           "pins\n",
           ke_peak, ke, -cy);
    CR_CHECK(ke_peak > 1e-5);
    /* The cloth still flaps at 10 s (VBD damps less than converged implicit
     * Euler, docs/physics.md), so the kinetic energy of one frame there is a
     * draw: perturbing the damping or the Chebyshev rho by 1e-12 relative, or
     * slicing the full kernels instead of the vertex blocks (roundoff), moved
     * the last frame's KE from 0.4 % to 36 % of the peak and the 2-second mean
     * from 0.5 % to 20 %. The mean is what is checked. */
    CR_CHECK(ke < 0.3 * ke_peak);
    CR_CHECK(cy < -0.15); /* it hangs (the 0.5 m cloth's centroid: 0.25 m when straight) */
    CR_CHECK(x[0] == (double)m->pos[0] && x[3 * 11 + 1] == (double)m->pos[3 * 11 + 1]);
    cr_sim_destroy(s);
    cr_mesh_destroy(m);
}

/* A small drop with plasticity and friction, for determinism and resume. */
static cr_sim *small_drop(cr_mesh **cloth, cr_mesh **sphere) {
    cr_error err = {0};
    *cloth = fixture_flat_cloth(12, 0.6f, 0.33f);
    if (cr_prim_sphere_uv(0.3f, 24, 12, sphere, &err) != CR_OK) return NULL;
    cr_sim_def d = vbd_def();
    d.collider = *sphere;
    d.plasticity = 1;
    d.material.yield_angle = 0.1;
    cr_sim *s = NULL;
    cr_sim_create(&d, *cloth, &s, &err);
    return s;
}

/* The same bits at 1, 2 and 3 threads: a colour's vertices read only other
 * colours, and every reduction runs in a fixed order. */
CR_TEST(phys_vbd, deterministic_across_threads) {
    int saved = cr_thread_count();
    uint64_t h[3];
    for (int run = 0; run < 3; run++) {
        cr_set_thread_count(run + 1);
        cr_mesh *cloth = NULL, *sphere = NULL;
        cr_sim *s = small_drop(&cloth, &sphere);
        CR_REQUIRE(s);
        cr_error err = {0};
        for (int f = 0; f < 12; f++)
            CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
        h[run] = cr_sim_state_hash(s);
        cr_sim_destroy(s);
        cr_mesh_destroy(cloth);
        cr_mesh_destroy(sphere);
    }
    cr_set_thread_count(saved);
    printf("    hashes %016llx %016llx %016llx\n", (unsigned long long)h[0],
           (unsigned long long)h[1], (unsigned long long)h[2]);
    CR_CHECK(h[0] == h[1] && h[1] == h[2]);
}

CR_TEST(phys_vbd, state_save_load_resumes_bit_identically) {
    cr_mesh *cloth = NULL, *sphere = NULL, *c2 = NULL, *s2 = NULL;
    cr_sim *s = small_drop(&cloth, &sphere), *r = small_drop(&c2, &s2);
    CR_REQUIRE(s && r);
    cr_error err = {0};
    char path[512];
    snprintf(path, sizeof path, "%s/vbd_state.bin", cr_test_tmpdir());
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    CR_CHECK_OK(cr_sim_state_save(s, path, &err), &err);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    CR_CHECK_OK(cr_sim_state_load(r, path, &err), &err);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(r, NULL, &err), &err);
    CR_CHECK(cr_sim_frame(r) == 12);
    CR_CHECK(cr_sim_state_hash(r) == cr_sim_state_hash(s));
    /* A damaged file is refused. */
    char *buf = NULL;
    size_t len = 0;
    CR_CHECK_OK(cr_file_read_all(path, &buf, &len, &err), &err);
    CR_CHECK(memcmp(buf, "CRSIMST2", 8) == 0);
    buf[len - 3] ^= 0x10; /* in the acceleration block */
    FILE *fp = fopen(path, "wb");
    CR_REQUIRE(fp);
    fwrite(buf, 1, len, fp);
    fclose(fp);
    CR_CHECK(cr_sim_state_load(r, path, &err) == CR_ERR_PARSE);
    free(buf);
    cr_sim_destroy(s), cr_sim_destroy(r);
    cr_mesh_destroy(cloth), cr_mesh_destroy(sphere), cr_mesh_destroy(c2), cr_mesh_destroy(s2);
}

CR_TEST(phys_vbd, divergence_backs_off_or_reports) {
    cr_error err = {0};
    cr_mesh *cloth = fixture_flat_cloth(8, 0.5f, 0.0f);
    cr_sim_def d = vbd_def();
    d.max_speed = 0.02; /* a free fall breaks it in any substep of a frame */
    d.max_backoff = 2;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    uint64_t h0 = cr_sim_state_hash(s);
    cr_sim_report rep;
    cr_status st = cr_sim_step(s, &rep, &err);
    printf("    VBD speed limit: %s (%d backoffs, %d substeps)\n", cr_status_str(st), rep.backoffs,
           rep.substeps);
    CR_CHECK(st == CR_ERR_DIVERGED && rep.diverged && rep.backoffs == 2);
    CR_CHECK(strstr(err.msg, "frame 0") != NULL);
    CR_CHECK(cr_sim_state_hash(s) == h0 && cr_sim_frame(s) == 0);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
}
