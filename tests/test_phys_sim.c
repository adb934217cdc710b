/* test_phys_sim.c: the simulator core. Assembly against a dense brute-force
 * sum, CHOLMOD against a dense solve, Newton's quadratic convergence on
 * springs, then whole scenes: a hanging cloth settling (dynamic, and
 * monotone in quasi-static mode), a cloth dropped on a sphere, a strip folded
 * in a press brake with and without plasticity, determinism, save/load
 * resumption and divergence handling. Meshes are small so each test runs in
 * about a second in release. */
#include "crease/bvh.h"
#include "crease/phys_assemble.h"
#include "crease/phys_sim.h"
#include "crease/phys_solve.h"
#include "crease/primitives.h"
#include "crease/scene.h"
#include "crease/topology.h"
#include "sim_fixture.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------ test energies -- */

/* Springs on edges, E = k/2 (|xi - xj| - L)^2, with the exact Hessian
 * (indefinite when compressed: fine for the assembly test). */
typedef struct springs {
    double k;
    const double *rest; /* (E) m */
} springs;

static double spring_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const springs *s = data;
    double d[3] = {xe[0] - xe[3], xe[1] - xe[4], xe[2] - xe[5]};
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), L = s->rest[e];
    double u[3] = {d[0] / l, d[1] / l, d[2] / l};
    if (g)
        for (int k = 0; k < 3; k++) {
            g[k] = s->k * (l - L) * u[k];
            g[3 + k] = -g[k];
        }
    if (H)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) {
                double K = s->k * (u[r] * u[c] + (1.0 - L / l) * ((r == c) - u[r] * u[c]));
                H[r * 6 + c] = H[(r + 3) * 6 + c + 3] = K;
                H[r * 6 + c + 3] = H[(r + 3) * 6 + c] = -K;
            }
    return 0.5 * s->k * (l - L) * (l - L);
}

/* Per-vertex anchor E = c/2 |x - a|^2; `anchors` (V,3). */
typedef struct anchor {
    double c;
    const double *a;
} anchor;

static double anchor_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const anchor *an = data;
    (void)e;
    double v = 0.0;
    const double *a = an->a ? an->a + 3 * (int64_t)e : NULL;
    for (int k = 0; k < 3; k++) {
        double r = xe[k] - (a ? a[k] : 0.0);
        v += 0.5 * an->c * r * r;
        if (g) g[k] = an->c * r;
    }
    if (H) {
        memset(H, 0, 9 * sizeof(double));
        H[0] = H[4] = H[8] = an->c;
    }
    return v;
}

/* Four-vertex quadratic E = 1/2 |x0 + x1 - x2 - 2 x3|^2 + x0.x3 (a hinge
 * stand-in that couples all four vertices, asymmetric in them). */
static double quad4_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    (void)data, (void)e;
    static const double w[4] = {1, 1, -1, -2};
    double r[3], v = 0.0;
    for (int k = 0; k < 3; k++) {
        r[k] = xe[k] + xe[3 + k] - xe[6 + k] - 2 * xe[9 + k];
        v += 0.5 * r[k] * r[k] + xe[k] * xe[9 + k];
    }
    if (g)
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++)
                g[3 * i + k] = w[i] * r[k] + (i == 0 ? xe[9 + k] : 0) + (i == 3 ? xe[k] : 0);
    if (H) {
        memset(H, 0, 144 * sizeof(double));
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++)
                for (int k = 0; k < 3; k++)
                    H[(3 * i + k) * 12 + 3 * j + k] =
                        w[i] * w[j] + ((i == 0 && j == 3) || (i == 3 && j == 0));
    }
    return v;
}

typedef struct scene {
    cr_mesh *mesh;
    cr_topology *topo;
    double *rest, *x, *anchors;
    int32_t *edges;
    springs sp;
    anchor an;
} scene;

static void scene_free(scene *s) {
    cr_mesh_destroy(s->mesh);
    cr_topology_destroy(s->topo);
    free(s->rest), free(s->x), free(s->anchors);
}

/* A small plane with springs at 10% stretch and anchors, positions jittered. */
static int scene_make(scene *s, int32_t n, uint64_t seed) {
    cr_error err = {0};
    memset(s, 0, sizeof *s);
    if (cr_prim_plane(n, n, 1.0f, 1.0f, &s->mesh, &err) != CR_OK) return 0;
    if (cr_topology_build(s->mesh, &s->topo, &err) != CR_OK) return 0;
    int32_t nv = s->mesh->nv, ne = s->topo->ne;
    s->rest = malloc((size_t)ne * sizeof(double));
    s->x = malloc((size_t)nv * 3 * sizeof(double));
    s->anchors = malloc((size_t)nv * 3 * sizeof(double));
    cr_rng r = cr_rng_make(seed, 0);
    for (int64_t k = 0; k < 3 * (int64_t)nv; k++) {
        s->anchors[k] = s->mesh->pos[k];
        s->x[k] = s->mesh->pos[k] + 0.02 * (cr_rng_uniform(&r) - 0.5);
    }
    for (int32_t e = 0; e < ne; e++) {
        const float *a = s->mesh->pos + 3 * s->topo->edge[2 * e],
                    *b = s->mesh->pos + 3 * s->topo->edge[2 * e + 1];
        double d2 = 0;
        for (int k = 0; k < 3; k++)
            d2 += (double)(a[k] - b[k]) * (a[k] - b[k]);
        s->rest[e] = 0.9 * sqrt(d2);
    }
    s->sp = (springs){100.0, s->rest};
    s->an = (anchor){1.0, s->anchors};
    return 1;
}

static void spring_terms(scene *s, cr_energy_term *t) {
    memset(t, 0, 2 * sizeof *t);
    t[0] = (cr_energy_term){"springs",     s->topo->ne, 2,   s->topo->edge,
                            spring_kernel, &s->sp,      1.0, NULL};
    t[1] = (cr_energy_term){"anchor", s->mesh->nv, 1, NULL, anchor_kernel, &s->an, 1.0, NULL};
}

/* Dense brute force: value, gradient (3V) and Hessian (3V x 3V). */
static double dense_eval(const cr_energy_term *terms, int nterms, int32_t nv, const double *x,
                         double *g, double *H) {
    int64_t n = 3 * (int64_t)nv;
    memset(g, 0, (size_t)n * sizeof(double));
    memset(H, 0, (size_t)(n * n) * sizeof(double));
    double v = 0.0;
    for (int t = 0; t < nterms; t++)
        for (int32_t e = 0; e < terms[t].nelem; e++) {
            int nv_ = terms[t].nvert, m = 3 * nv_;
            int32_t idx[4];
            double xe[12], ge[12], He[144];
            cr_energy_term_vertices(&terms[t], e, idx);
            for (int a = 0; a < nv_; a++)
                memcpy(xe + 3 * a, x + 3 * idx[a], 3 * sizeof(double));
            v += terms[t].weight * terms[t].kernel(terms[t].data, e, xe, ge, He);
            for (int a = 0; a < m; a++) {
                g[3 * idx[a / 3] + a % 3] += terms[t].weight * ge[a];
                for (int b = 0; b < m; b++)
                    H[(3 * idx[a / 3] + a % 3) * n + 3 * idx[b / 3] + b % 3] +=
                        terms[t].weight * He[a * m + b];
            }
        }
    return v;
}

/* The block matrix expanded to dense (both triangles). */
static void hessian_dense(const cr_hessian *h, double *D) {
    int64_t n = 3 * (int64_t)h->nv;
    memset(D, 0, (size_t)(n * n) * sizeof(double));
    for (int32_t j = 0; j < h->nv; j++)
        for (int64_t k = h->col_off[j]; k < h->col_off[j + 1]; k++) {
            int32_t i = h->row[k];
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) {
                    double v = h->val[9 * k + 3 * r + c];
                    D[(3 * i + r) * n + 3 * j + c] = v;
                    D[(3 * j + c) * n + 3 * i + r] = v;
                }
        }
}

CR_TEST(phys_sim, assembly_matches_dense_sum) {
    scene s;
    CR_REQUIRE(scene_make(&s, 5, 1));
    int32_t nv = s.mesh->nv;
    /* Terms of 1..4 vertices: springs, anchors, one quad4 per hinge and a
     * per-vertex term whose element list repeats a vertex. */
    static const int32_t rep_elem[] = {0, 5, 5, 3, 24};
    anchor extra = {3.0, NULL};
    cr_energy_term t[4];
    spring_terms(&s, t);
    t[2] = (cr_energy_term){"quad4", s.topo->nh, 4, s.topo->hinge, quad4_kernel, NULL, 0.5, NULL};
    t[3] = (cr_energy_term){"repeat", 5, 1, rep_elem, anchor_kernel, &extra, 2.0, NULL};
    cr_error err = {0};
    cr_assembly *a = NULL;
    CR_CHECK_OK(cr_assembly_create(t, 4, nv, &a, &err), &err);
    CR_REQUIRE(a);
    int64_t n = 3 * (int64_t)nv;
    double *g = malloc(n * sizeof(double)), *gd = malloc(n * sizeof(double));
    double *H = malloc(n * n * sizeof(double)), *Hd = malloc(n * n * sizeof(double));
    double tv[4];
    double e = cr_assembly_eval(a, t, s.x, g, 1, tv);
    double ed = dense_eval(t, 4, nv, s.x, gd, Hd);
    CR_CHECK_NEAR(e, ed, 1e-12 * fabs(ed));
    CR_CHECK_NEAR(tv[0] + tv[1] + tv[2] + tv[3], e, 1e-12 * fabs(e));
    double gerr = 0, herr = 0, hmax = 0;
    for (int64_t k = 0; k < n; k++)
        gerr = fmax(gerr, fabs(g[k] - gd[k]));
    hessian_dense(cr_assembly_hessian(a), H);
    for (int64_t k = 0; k < n * n; k++) {
        herr = fmax(herr, fabs(H[k] - Hd[k]));
        hmax = fmax(hmax, fabs(Hd[k]));
    }
    CR_CHECK(gerr < 1e-10);
    CR_CHECK(herr < 1e-12 * hmax);
    /* An interior grid vertex has 6 edges and lies on 12 hinges, which must
     * all get different colours. */
    CR_CHECK(cr_assembly_colour_count(a, 0) >= 6 && cr_assembly_colour_count(a, 2) >= 12);
    /* Determinism across thread counts: bit-identical. */
    int threads = cr_thread_count();
    cr_set_thread_count(1);
    double e1 = cr_assembly_eval(a, t, s.x, gd, 1, NULL);
    hessian_dense(cr_assembly_hessian(a), Hd);
    cr_set_thread_count(threads);
    CR_CHECK(e1 == e);
    CR_CHECK(memcmp(g, gd, n * sizeof(double)) == 0);
    CR_CHECK(memcmp(H, Hd, n * n * sizeof(double)) == 0);
    /* Out-of-range elements are refused. */
    int32_t bad[2] = {0, nv};
    cr_energy_term tb = {"bad", 1, 2, bad, spring_kernel, &s.sp, 1.0, NULL};
    cr_assembly *ab = NULL;
    CR_CHECK(cr_assembly_create(&tb, 1, nv, &ab, &err) == CR_ERR_RANGE && !ab);
    cr_assembly_destroy(a);
    free(g), free(gd), free(H), free(Hd);
    scene_free(&s);
}

/* Dense Cholesky solve of the n x n SPD system A x = b (row-major, in place). */
static int dense_solve(double *A, double *b, int64_t n) {
    for (int64_t j = 0; j < n; j++) {
        double d = A[j * n + j];
        for (int64_t k = 0; k < j; k++)
            d -= A[j * n + k] * A[j * n + k];
        if (!(d > 0)) return 0;
        A[j * n + j] = sqrt(d);
        for (int64_t i = j + 1; i < n; i++) {
            double v = A[i * n + j];
            for (int64_t k = 0; k < j; k++)
                v -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = v / A[j * n + j];
        }
    }
    for (int64_t i = 0; i < n; i++) {
        for (int64_t k = 0; k < i; k++)
            b[i] -= A[i * n + k] * b[k];
        b[i] /= A[i * n + i];
    }
    for (int64_t i = n - 1; i >= 0; i--) {
        for (int64_t k = i + 1; k < n; k++)
            b[i] -= A[k * n + i] * b[k];
        b[i] /= A[i * n + i];
    }
    return 1;
}

CR_TEST(phys_sim, cholmod_matches_dense_solve) {
    scene s;
    CR_REQUIRE(scene_make(&s, 6, 2));
    int32_t nv = s.mesh->nv;
    cr_energy_term t[2];
    spring_terms(&s, t);
    cr_error err = {0};
    cr_assembly *a = NULL;
    CR_CHECK_OK(cr_assembly_create(t, 2, nv, &a, &err), &err);
    CR_REQUIRE(a);
    cr_assembly_eval(a, t, s.x, NULL, 1, NULL);
    const cr_hessian *h = cr_assembly_hessian(a);
    uint8_t *pinned = calloc(nv, 1);
    pinned[0] = pinned[7] = pinned[nv - 1] = 1;
    int64_t n = 3 * (int64_t)nv;
    double *b = malloc(n * sizeof(double)), *x = malloc(n * sizeof(double));
    double *D = malloc(n * n * sizeof(double));
    cr_rng r = cr_rng_make(9, 0);
    for (int64_t k = 0; k < n; k++)
        b[k] = cr_rng_normal(&r);
    cr_cholesky *c = NULL;
    CR_CHECK_OK(cr_cholesky_create(h, pinned, &c, &err), &err);
    CR_REQUIRE(c);
    cr_cholesky_info info;
    CR_CHECK_OK(cr_cholesky_factor(c, h, &info, &err), &err);
    CR_CHECK(info.shift == 0.0 && info.retries == 0 && info.factor_nnz > 0);
    CR_CHECK_OK(cr_cholesky_solve(c, b, x, &err), &err);
    /* Dense reference on the free DOFs. */
    hessian_dense(h, D);
    int64_t m = 0;
    int64_t *map = malloc(n * sizeof(int64_t));
    for (int64_t k = 0; k < n; k++)
        if (!pinned[k / 3]) map[m++] = k;
    double *A = malloc(m * m * sizeof(double)), *y = malloc(m * sizeof(double));
    for (int64_t i = 0; i < m; i++) {
        y[i] = b[map[i]];
        for (int64_t j = 0; j < m; j++)
            A[i * m + j] = D[map[i] * n + map[j]];
    }
    CR_REQUIRE(dense_solve(A, y, m));
    double maxerr = 0, maxy = 0;
    for (int64_t i = 0; i < m; i++) {
        maxerr = fmax(maxerr, fabs(x[map[i]] - y[i]));
        maxy = fmax(maxy, fabs(y[i]));
    }
    CR_CHECK(maxerr < 1e-9 * maxy);
    for (int32_t v = 0; v < nv; v++)
        if (pinned[v]) CR_CHECK(x[3 * v] == 0 && x[3 * v + 1] == 0 && x[3 * v + 2] == 0);
    /* Indefinite: negate the anchors so the matrix has negative directions;
     * the factorisation must shift, and then solve (H + shift I) x = b. */
    s.an.c = -50.0;
    cr_assembly_eval(a, t, s.x, NULL, 1, NULL);
    CR_CHECK_OK(cr_cholesky_factor(c, h, &info, &err), &err);
    CR_CHECK(info.shift > 0.0 && info.retries > 0);
    CR_CHECK_OK(cr_cholesky_solve(c, b, x, &err), &err);
    double *Ax = malloc(n * sizeof(double)), res = 0, bn = 0;
    cr_hessian_multiply(h, x, Ax);
    for (int64_t k = 0; k < n; k++)
        if (!pinned[k / 3]) {
            res = fmax(res, fabs(Ax[k] + info.shift * x[k] - b[k]));
            bn = fmax(bn, fabs(b[k]));
        }
    CR_CHECK(res < 1e-8 * bn);
    cr_cholesky_destroy(c);
    cr_assembly_destroy(a);
    free(pinned), free(b), free(x), free(D), free(map), free(A), free(y), free(Ax);
    scene_free(&s);
}

CR_TEST(phys_sim, newton_converges_quadratically) {
    scene s;
    CR_REQUIRE(scene_make(&s, 6, 3));
    int32_t nv = s.mesh->nv;
    int64_t n = 3 * (int64_t)nv;
    /* Minimum known: springs at rest and anchors at the jittered (non-planar)
     * configuration; start 3 mm away from it. */
    memcpy(s.anchors, s.x, n * sizeof(double));
    for (int32_t e = 0; e < s.topo->ne; e++) {
        const double *p = s.x + 3 * s.topo->edge[2 * e], *q = s.x + 3 * s.topo->edge[2 * e + 1];
        s.rest[e] = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                         (p[2] - q[2]) * (p[2] - q[2]));
    }
    s.an.c = 10.0;
    cr_rng r = cr_rng_make(5, 0);
    for (int64_t k = 0; k < n; k++)
        s.x[k] += 0.006 * (cr_rng_uniform(&r) - 0.5);
    cr_energy_term t[2];
    spring_terms(&s, t);
    cr_error err = {0};
    cr_assembly *a = NULL;
    cr_cholesky *c = NULL;
    CR_CHECK_OK(cr_assembly_create(t, 2, nv, &a, &err), &err);
    CR_REQUIRE(a);
    CR_CHECK_OK(cr_cholesky_create(cr_assembly_hessian(a), NULL, &c, &err), &err);
    CR_REQUIRE(c);
    double *g = malloc(n * sizeof(double)), *dx = malloc(n * sizeof(double));
    double gn[8];
    int iters = 0;
    for (; iters < 8; iters++) {
        cr_assembly_eval(a, t, s.x, g, 1, NULL);
        double m = 0;
        for (int64_t k = 0; k < n; k++)
            m = fmax(m, fabs(g[k]));
        gn[iters] = m;
        if (m < 1e-11) break;
        cr_cholesky_info info;
        CR_CHECK_OK(cr_cholesky_factor(c, cr_assembly_hessian(a), &info, &err), &err);
        CR_CHECK(info.shift == 0.0); /* near the minimum: springs' + anchors' Hessian is SPD */
        for (int64_t k = 0; k < n; k++)
            dx[k] = -g[k];
        CR_CHECK_OK(cr_cholesky_solve(c, dx, dx, &err), &err);
        for (int64_t k = 0; k < n; k++)
            s.x[k] += dx[k];
    }
    /* Quadratic: g_{k+1} <= C g_k^2 (C ~ third derivative / Hessian^2). */
    CR_CHECK(iters <= 5);
    for (int k = 1; k <= iters && k < 8; k++) {
        printf("    newton %d: |g| = %.3e (|g|/|g_prev|^2 = %.3g)\n", k, gn[k],
               gn[k] / (gn[k - 1] * gn[k - 1]));
        if (gn[k] > 1e-10) CR_CHECK(gn[k] <= 20.0 * gn[k - 1] * gn[k - 1]);
    }
    cr_cholesky_destroy(c);
    cr_assembly_destroy(a);
    free(g), free(dx);
    scene_free(&s);
}

CR_TEST(phys_sim, plasticity_rules) {
    double theta[4] = {0.3, -0.3, 0.05, 1.0}, rest[4] = {0, 0, 0, 0.9};
    CR_CHECK(cr_plasticity_update(theta, rest, 4, 0.1, 1.0, CR_PLASTIC_LINEAR) == 2);
    CR_CHECK_NEAR(rest[0], 0.2, 1e-15);
    CR_CHECK_NEAR(rest[1], -0.2, 1e-15);
    CR_CHECK(rest[2] == 0.0 && rest[3] == 0.9);
    double r2[1] = {0};
    cr_plasticity_update(theta, r2, 1, 0.1, 0.5, CR_PLASTIC_LINEAR);
    CR_CHECK_NEAR(r2[0], 0.1, 1e-15);
    double r3[1] = {0};
    cr_plasticity_update(theta, r3, 1, 0.1, 1.0, CR_PLASTIC_SMOOTH);
    CR_CHECK_NEAR(r3[0], 0.2 / (1.0 + exp(-50.0 * 0.2)), 1e-15);
}

/* ------------------------------------------------------------ scenes -- */

static double max_speed_of(const cr_sim *s) {
    const double *v = cr_sim_velocities(s);
    double m = 0;
    for (int32_t i = 0; i < cr_sim_vertex_count(s); i++)
        m = fmax(m, sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] +
                         v[3 * i + 2] * v[3 * i + 2]));
    return m;
}

static int all_finite_d(const double *a, int64_t n) {
    for (int64_t k = 0; k < n; k++)
        if (!isfinite(a[k])) return 0;
    return 1;
}

CR_TEST(phys_sim, hanging_cloth_settles) {
    cr_mesh *m = fixture_flat_cloth(12, 0.5f, 0.0f);
    CR_REQUIRE(m);
    cr_sim_def d = fixture_cotton_def();
    int32_t pins[2] = {0, 11}; /* two corners of one edge: it swings down like a door */
    d.pinned = pins, d.npinned = 2;
    d.damping = 2.0; /* 1/s: settles within the test's 4 s */
    cr_error err = {0};
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    double ke_peak = 0, ke = 0;
    int iters = 0;
    for (int f = 0; f < 120; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        ke_peak = fmax(ke_peak, rep.kinetic_energy);
        ke = rep.kinetic_energy;
        iters += rep.newton_iterations;
    }
    printf("    hanging: KE peak %.3e J, after 4 s %.3e J, %.2f Newton iterations per substep\n",
           ke_peak, ke, iters / (120.0 * d.substeps));
    CR_CHECK(ke_peak > 1e-5);
    CR_CHECK(ke < 1e-4 * ke_peak);
    /* Pinned corners did not move. */
    const double *x = cr_sim_positions(s);
    CR_CHECK(x[0] == (double)m->pos[0] && x[3 * 11 + 1] == (double)m->pos[3 * 11 + 1]);
    CR_CHECK(all_finite_d(x, 3 * (int64_t)m->nv));
    cr_sim_destroy(s);
    cr_mesh_destroy(m);
}

typedef struct trace {
    int n;
    double e[256];
} trace;

static void record(void *ctx, int it, double energy, double gnorm, double step) {
    trace *t = ctx;
    (void)it, (void)gnorm, (void)step;
    if (t->n < 256) t->e[t->n++] = energy;
}

/* The n x n cloth of `flat_cloth` turned to hang in the XY plane from its
 * top edge (y = 0 down to -size), pushed out of plane by a smooth bump of
 * `bump` m so that a solve has work to do. */
static cr_mesh *hanging_cloth(int32_t n, float size, float bump) {
    cr_mesh *m = fixture_flat_cloth(n, size, 0.0f);
    if (!m) return NULL;
    for (int32_t v = 0; v < m->nv; v++) {
        float *p = m->pos + 3 * v;
        float u = p[0] / size + 0.5f, w = p[2] / size + 0.5f; /* [0,1]^2 */
        p[1] = -w * size;
        p[2] = bump * sinf(3.14159265f * u) * sinf(3.14159265f * w);
    }
    return m;
}

CR_TEST(phys_sim, quasi_static_energy_monotone) {
    cr_mesh *m = hanging_cloth(12, 0.5f, 0.03f);
    CR_REQUIRE(m);
    cr_sim_def d = fixture_cotton_def();
    int32_t pins[2] = {0, 11}; /* the top corners */
    d.pinned = pins, d.npinned = 2;
    d.static_tol = 1e-5;
    trace tr = {0};
    d.on_iteration = record, d.on_iteration_ctx = &tr;
    cr_error err = {0};
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    CR_CHECK_OK(cr_sim_solve_static(s, &rep, &err), &err);
    printf(
        "    static: %d Newton iterations, energy %.6e -> %.6e J, capped %d, %d factorisations\n",
        rep.newton_iterations, tr.e[0], tr.e[tr.n - 1], rep.newton_capped, rep.factorisations);
    CR_CHECK(tr.n >= 5 && rep.newton_capped == 0);
    for (int i = 1; i < tr.n; i++)
        CR_CHECK(tr.e[i] <= tr.e[i - 1]);
    CR_CHECK(max_speed_of(s) == 0.0);
    /* A second solve from equilibrium stops at once. */
    double e_static = tr.e[tr.n - 1];
    tr.n = 0;
    CR_CHECK_OK(cr_sim_solve_static(s, &rep, &err), &err);
    tr.e[tr.n++] = e_static;
    CR_CHECK(rep.newton_iterations <= 3);
    /* Quasi-static stepping from there: frames advance, nothing moves. */
    d.quasi_static = 1;
    d.on_iteration = NULL;
    cr_sim *q = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &q, &err), &err);
    CR_REQUIRE(q);
    for (int f = 0; f < 3; f++)
        CR_CHECK_OK(cr_sim_step(q, &rep, &err), &err);
    CR_CHECK(cr_sim_frame(q) == 3 && max_speed_of(q) == 0.0 && rep.kinetic_energy == 0.0);
    double qdiff = 0;
    for (int64_t k = 0; k < 3 * (int64_t)m->nv; k++)
        qdiff = fmax(qdiff, fabs(cr_sim_positions(q)[k] - cr_sim_positions(s)[k]));
    CR_CHECK(qdiff < 5e-3); /* the same equilibrium (up to the static tolerance) */
    cr_sim_destroy(q);
    cr_sim_destroy(s);
    cr_mesh_destroy(m);
}

CR_TEST(phys_sim, cloth_dropped_on_sphere) {
    enum { FRAMES = 30 };
    cr_mesh *cloth = fixture_flat_cloth(32, 1.0f, 0.34f), *sphere = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    cr_sim_def d = fixture_cotton_def();
    d.collider = sphere;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    double pen = 0, secs = 0, sa = 0, sf = 0, sc = 0, ss = 0;
    int iters = 0, backoffs = 0;
    for (int f = 0; f < FRAMES; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        pen = fmax(pen, rep.max_penetration_m);
        iters += rep.newton_iterations;
        backoffs += rep.backoffs;
        secs += rep.seconds, sa += rep.seconds_assembly, sf += rep.seconds_factor;
        sc += rep.seconds_collision, ss += rep.seconds_solve;
    }
    const double *x = cr_sim_positions(s);
    double deepest = fixture_deepest_inside(sphere, x, cloth->nv);
    printf(
        "    sphere 32x32: deepest %.2e m (before projection %.2e m), %d contacts, %.2f Newton "
        "iterations per substep, %d backoffs, %.1f ms per frame (assembly %.0f%%, factor %.0f%%, "
        "solve %.0f%%, collision %.0f%%)\n",
        deepest, pen, rep.contacts, iters / ((double)FRAMES * d.substeps), backoffs,
        1e3 * secs / FRAMES, 100 * sa / secs, 100 * sf / secs, 100 * ss / secs, 100 * sc / secs);
    CR_CHECK(all_finite_d(x, 3 * (int64_t)cloth->nv));
    CR_CHECK(deepest < 1e-3);
    CR_CHECK(pen < 2e-3);
    CR_CHECK(rep.contacts > 10);
    /* The cloth rests on the sphere (its centre on top; a coarse mesh folds
     * up there rather than lying flat) and hangs below its top. */
    int32_t centre = 16 * 32 + 16;
    CR_CHECK(x[3 * centre + 1] > 0.298);
    CR_CHECK(x[1] < 0.25);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* A coarse cloth (8.6 cm edges) over a 0.3 m sphere: a flat face's middle
 * sags about L^2 / (6 R) = 4 mm toward the sphere, twice the thickness, so a
 * penalty held at the vertices alone leaves the face centroids inside
 * (measured: 3.7 mm with Newton, 4.7 with VBD, every vertex outside). The
 * chord-sag thresholds hold the thickness at the centroids, with Newton and
 * with VBD. */
CR_TEST(phys_sim, coarse_faces_stay_outside_the_sphere) {
    cr_mesh *cloth = fixture_flat_cloth(8, 0.6f, 0.34f), *sphere = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 96, 48, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    for (int vbd = 0; vbd < 2; vbd++) {
        cr_sim_def d = fixture_cotton_def();
        d.collider = sphere;
        d.solver = vbd ? CR_SIM_SOLVER_VBD : CR_SIM_SOLVER_NEWTON;
        cr_sim *s = NULL;
        CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
        CR_REQUIRE(s);
        cr_sim_report rep;
        double faces = 0.0, vertices = 0.0;
        for (int f = 0; f < 20; f++) {
            CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
            const double *x = cr_sim_positions(s);
            faces = fmax(faces, fixture_deepest_centroid_inside(sphere, cloth, x));
            vertices = fmax(vertices, fixture_deepest_inside(sphere, x, cloth->nv));
        }
        printf("    %s: deepest face centroid %.2f mm, vertex %.2f mm, %d contacts\n",
               vbd ? "vbd" : "newton", 1e3 * faces, 1e3 * vertices, rep.contacts);
        CR_CHECK(rep.contacts >= 4);
        CR_CHECK(faces < 2e-4);
        CR_CHECK(vertices < 2e-4);
        cr_sim_destroy(s);
    }
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* A cloth lying on a plate 1 cm thick that then rises 3 cm a frame, three
 * times its thickness: queried where the plate went, the cloth would find
 * itself under the plate's bottom face and stay there (the plate passing
 * through it); tracked from where the plate was, it is lifted with it. */
CR_TEST(phys_sim, fast_collider_carries_the_cloth) {
    enum { FRAMES = 24, REST = 8 };
    const float thick = 0.01f, rise = 0.03f;
    cr_mesh *cloth = fixture_flat_cloth(20, 0.4f, 0.5f * thick + 0.003f), *plate = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_box(0.6f, thick, 0.6f, 4, &plate, &err), &err);
    CR_REQUIRE(cloth && plate);
    float *seq = malloc(sizeof(float) * 3 * (size_t)plate->nv * FRAMES);
    CR_REQUIRE(seq);
    for (int f = 0; f < FRAMES; f++)
        for (int32_t v = 0; v < plate->nv; v++)
            for (int k = 0; k < 3; k++)
                seq[3 * ((size_t)plate->nv * f + v) + k] =
                    plate->pos[3 * v + k] + (k == 1 && f > REST ? rise * (f - REST) : 0.0f);
    cr_sim_def d = fixture_cotton_def();
    d.collider = plate, d.collider_frames = seq, d.collider_nframes = FRAMES;
    d.max_collider_step = 0.02; /* two substeps while the plate rises, one at rest */
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    int32_t projected = 0;
    double pen = 0.0;
    for (int f = 0; f + 1 < FRAMES; f++) {
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        projected += rep.projected;
        pen = fmax(pen, rep.max_penetration_m);
        CR_CHECK(rep.substeps == (f >= REST ? 2 : 1));
    }
    const double *x = cr_sim_positions(s);
    double top = 0.5 * thick + rise * (FRAMES - 1 - REST), lowest = INFINITY;
    for (int32_t i = 0; i < cloth->nv; i++)
        if (fabs(x[3 * i]) < 0.1 && fabs(x[3 * i + 2]) < 0.1) lowest = fmin(lowest, x[3 * i + 1]);
    printf("    plate rising 3 cm a frame: middle of the cloth %.4f m (plate top %.4f m), %d "
           "projected, deepest %.2e m\n",
           lowest, top, projected, pen);
    CR_CHECK(lowest > top - 1e-3);
    CR_CHECK(projected == 0);
    CR_CHECK(pen < 1e-3);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(plate);
    free(seq);
}

/* ---------------------------------------------------------- plasticity -- */

/* A strip 0.2 m long (z) and 3 cm wide (x), in zero gravity, its z < 0 half
 * pinned; a thin capsule lying along x comes down on the free half at
 * z = 5 cm, folds it down by about 60 degrees about the pinned edge, then
 * slides off sideways. Returns the fold angle after `frames` frames:
 * between +z and the free arm (from the fold line to the tip), degrees. */
static double fold_strip(int plastic, int frames, uint64_t *hash) {
    enum { NX = 5, NZ = 41, DOWN = 20, SLIDE = 15 };
    cr_error err = {0};
    cr_mesh *strip = NULL, *cap = NULL;
    if (cr_prim_plane(NX, NZ, 0.03f, 0.2f, &strip, &err) != CR_OK) return NAN;
    if (cr_prim_capsule(0.01f, 0.08f, 16, 4, &cap, &err) != CR_OK) return NAN;
    for (int32_t v = 0; v < cap->nv; v++) { /* axis Y -> X: a rotation about z */
        float *p = cap->pos + 3 * v, x = p[0];
        p[0] = p[1], p[1] = -x;
    }
    float *seq = malloc(sizeof(float) * 3 * (size_t)cap->nv * frames);
    for (int f = 0; f < frames; f++) {
        float y = f < DOWN ? 0.02f - 0.12f * f / DOWN : -0.1f;
        float x = f < DOWN ? 0.0f : 0.2f * fminf(1.0f, (float)(f - DOWN) / SLIDE);
        for (int32_t v = 0; v < cap->nv; v++) {
            float *p = seq + 3 * ((size_t)cap->nv * f + v);
            p[0] = cap->pos[3 * v] + x, p[1] = cap->pos[3 * v + 1] + y;
            p[2] = cap->pos[3 * v + 2] + 0.05f;
        }
    }
    cr_sim_def d = fixture_cotton_def();
    d.material.bending = 1e-3;     /* paper-like: springs back within the test */
    d.material.yield_angle = 0.02; /* rad per hinge: low */
    d.material.friction = 0.0;
    d.gravity[1] = 0.0;
    d.damping = 2.0;
    d.plasticity = plastic;
    int32_t pins[NX * NZ / 2];
    for (int32_t i = 0; i < NX * (NZ / 2); i++)
        pins[i] = i;
    d.pinned = pins, d.npinned = NX * (NZ / 2);
    d.collider = cap, d.collider_frames = seq, d.collider_nframes = frames;
    cr_sim *s = NULL;
    double angle = NAN;
    if (cr_sim_create(&d, strip, &s, &err) == CR_OK) {
        cr_sim_report rep;
        int ok = 1, yielded = 0;
        for (int f = 0; f < frames && ok; f++) {
            ok = cr_sim_step(s, &rep, &err) == CR_OK;
            yielded += rep.yielded;
        }
        const double *x = cr_sim_positions(s);
        const double *a = x + 3 * ((NZ / 2 + 1) * NX + NX / 2),
                     *b = x + 3 * ((NZ - 1) * NX + NX / 2);
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        if (ok) angle = acos(u[2] / sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])) * 180.0 / M_PI;
        if (!ok) printf("    fold: %s\n", err.msg);
        if (plastic)
            CR_CHECK(yielded > 0);
        else
            CR_CHECK(yielded == 0);
        if (hash) *hash = cr_sim_state_hash(s);
    }
    cr_sim_destroy(s);
    cr_mesh_destroy(strip);
    cr_mesh_destroy(cap);
    free(seq);
    return angle;
}

CR_TEST(phys_sim, fold_persists_with_plasticity) {
    double plastic = fold_strip(1, 90, NULL), elastic = fold_strip(0, 90, NULL);
    printf("    fold angle after release: %.1f deg plastic, %.1f deg elastic\n", plastic, elastic);
    CR_CHECK(plastic > 30.0);
    CR_CHECK(elastic < 5.0);
}

/* ------------------------------------------------ determinism, resume -- */

static cr_sim *small_drop(cr_mesh **cloth, cr_mesh **sphere) {
    cr_error err = {0};
    *cloth = fixture_flat_cloth(12, 0.6f, 0.33f);
    if (cr_prim_sphere_uv(0.3f, 24, 12, sphere, &err) != CR_OK) return NULL;
    cr_sim_def d = fixture_cotton_def();
    d.collider = *sphere;
    d.plasticity = 1;
    d.material.yield_angle = 0.1;
    cr_sim *s = NULL;
    cr_sim_create(&d, *cloth, &s, &err);
    return s;
}

/* Same inputs, same thread count: the same state, bit for bit. (Across
 * thread counts the BLAS inside CHOLMOD and LAPACK's eigensolver may round
 * differently; the assembly itself sums in a fixed order.) */
CR_TEST(phys_sim, deterministic) {
    uint64_t h[2];
    for (int run = 0; run < 2; run++) {
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
    CR_CHECK(h[0] == h[1]);
    /* And the press scene, with an animated collider and plasticity. */
    uint64_t a = 0, b = 0;
    fold_strip(1, 30, &a);
    fold_strip(1, 30, &b);
    CR_CHECK(a == b && a != 0);
}

CR_TEST(phys_sim, state_save_load_resumes_bit_identically) {
    cr_mesh *cloth = NULL, *sphere = NULL;
    cr_sim *s = small_drop(&cloth, &sphere), *r = NULL;
    CR_REQUIRE(s);
    cr_error err = {0};
    char path[512], bad[512];
    snprintf(path, sizeof path, "%s/sim_state.bin", cr_test_tmpdir());
    snprintf(bad, sizeof bad, "%s/sim_state_bad.bin", cr_test_tmpdir());
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    CR_CHECK_OK(cr_sim_state_save(s, path, &err), &err);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    uint64_t straight = cr_sim_state_hash(s);
    /* A fresh simulator from the same inputs, loaded, runs the same 6 frames. */
    cr_mesh *c2 = NULL, *s2 = NULL;
    r = small_drop(&c2, &s2);
    CR_REQUIRE(r);
    CR_CHECK_OK(cr_sim_state_load(r, path, &err), &err);
    CR_CHECK(cr_sim_frame(r) == 6);
    for (int f = 0; f < 6; f++)
        CR_CHECK_OK(cr_sim_step(r, NULL, &err), &err);
    CR_CHECK(cr_sim_state_hash(r) == straight);
    CR_CHECK(memcmp(cr_sim_rest_angles(r), cr_sim_rest_angles(s),
                    (size_t)cr_sim_hinge_count(s) * sizeof(double)) == 0);
    /* A damaged file is refused and leaves the state alone. */
    char *buf = NULL;
    size_t len = 0;
    CR_CHECK_OK(cr_file_read_all(path, &buf, &len, &err), &err);
    buf[len / 2] ^= 0x40;
    FILE *fp = fopen(bad, "wb");
    CR_REQUIRE(fp);
    fwrite(buf, 1, len, fp);
    fclose(fp);
    uint64_t before = cr_sim_state_hash(r);
    CR_CHECK(cr_sim_state_load(r, bad, &err) == CR_ERR_PARSE);
    CR_CHECK(cr_sim_state_hash(r) == before);
    free(buf);
    /* A simulator of another mesh refuses the file by shape. */
    cr_mesh *other = fixture_flat_cloth(8, 0.5f, 0.5f);
    cr_sim_def d = fixture_cotton_def();
    cr_sim *o = NULL;
    CR_CHECK_OK(cr_sim_create(&d, other, &o, &err), &err);
    CR_CHECK(o && cr_sim_state_load(o, path, &err) == CR_ERR_SHAPE);
    cr_sim_destroy(o);
    cr_mesh_destroy(other);
    cr_sim_destroy(r);
    cr_mesh_destroy(c2);
    cr_mesh_destroy(s2);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}

/* -------------------------------------------------------- divergence -- */

CR_TEST(phys_sim, divergence_backs_off_or_reports) {
    cr_error err = {0};
    /* Absurd stiffness: energies overflow. Never NaN positions; a clean
     * CR_ERR_DIVERGED with the frame in the message, state unchanged. */
    cr_mesh *cloth = fixture_flat_cloth(8, 0.5f, 0.0f);
    cr_sim_def d = fixture_cotton_def();
    d.material.lame_mu = d.material.lame_lambda = 1e12;
    d.material.bending = 1e3;
    int32_t pins[1] = {0};
    d.pinned = pins, d.npinned = 1;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    cr_sim_report rep;
    int diverged = 0;
    for (int f = 0; f < 10; f++) {
        cr_status st = cr_sim_step(s, &rep, &err);
        CR_CHECK(st == CR_OK || st == CR_ERR_DIVERGED);
        CR_CHECK(all_finite_d(cr_sim_positions(s), 3 * (int64_t)cloth->nv));
        CR_CHECK(all_finite_d(cr_sim_velocities(s), 3 * (int64_t)cloth->nv));
        diverged |= st == CR_ERR_DIVERGED;
    }
    printf("    stiff: %s\n", diverged ? err.msg : "ran (no divergence)");
    cr_sim_destroy(s);
    /* Absurd time step, a vertex speed limit the fall must break: the frame
     * backs off to more substeps, then reports. */
    d = fixture_cotton_def();
    d.dt = 100.0;
    d.max_speed = 5.0;
    d.max_backoff = 2;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    uint64_t h0 = cr_sim_state_hash(s);
    cr_status st = cr_sim_step(s, &rep, &err);
    printf("    dt 100 s: %s (%d backoffs, %d substeps)\n", cr_status_str(st), rep.backoffs,
           rep.substeps);
    CR_CHECK(st == CR_ERR_DIVERGED && rep.diverged && rep.backoffs == 2);
    CR_CHECK(strstr(err.msg, "frame 0") != NULL);
    CR_CHECK(cr_sim_state_hash(s) == h0 && cr_sim_frame(s) == 0);
    cr_sim_destroy(s);
    /* A bad def is refused by name. */
    d = fixture_cotton_def();
    d.substeps = 0;
    CR_CHECK(cr_sim_create(&d, cloth, &s, &err) == CR_ERR_INVALID && !s);
    CR_CHECK(strstr(err.msg, "substeps") != NULL);
    cr_mesh_destroy(cloth);
}

/* ------------------------------------------------------- animated pins -- */

/* A 0.3 m cloth hanging from its top row, whose pins are carried 10 cm along
 * +x over 10 frames and then held: the pins end exactly on their targets,
 * and the cloth follows them (its centroid moves by nearly the same). */
CR_TEST(phys_sim, pinned_vertices_follow_their_frames) {
    enum { N = 8, T = 11, FRAMES = 40 };
    cr_mesh *m = hanging_cloth(N, 0.3f, 0.0f);
    CR_REQUIRE(m);
    int32_t pins[N];
    float *frames = malloc(sizeof(float) * 3 * N * T);
    CR_REQUIRE(frames);
    for (int32_t i = 0; i < N; i++)
        pins[i] = i; /* the top row */
    for (int f = 0; f < T; f++)
        for (int32_t i = 0; i < N; i++)
            for (int k = 0; k < 3; k++)
                frames[3 * (N * f + i) + k] = m->pos[3 * pins[i] + k] + (k == 0 ? 0.01f * f : 0.0f);
    cr_sim_def d = fixture_cotton_def();
    d.pinned = pins, d.npinned = N;
    d.pin_frames = frames, d.pin_nframes = T;
    cr_error err = {0};
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, m, &s, &err), &err);
    CR_REQUIRE(s);
    double cx0 = 0.0, cx1 = 0.0;
    const double *x = cr_sim_positions(s);
    for (int32_t v = 0; v < m->nv; v++)
        cx0 += x[3 * v] / m->nv;
    for (int f = 0; f < FRAMES; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    x = cr_sim_positions(s);
    for (int32_t v = 0; v < m->nv; v++)
        cx1 += x[3 * v] / m->nv;
    double worst = 0.0;
    for (int32_t i = 0; i < N; i++)
        for (int k = 0; k < 3; k++)
            worst = fmax(worst, fabs(x[3 * pins[i] + k] - frames[3 * (N * (T - 1) + i) + k]));
    printf("    pins off target by %.2e m; centroid moved %.4f m\n", worst, cx1 - cx0);
    CR_CHECK(worst < 1e-6);
    CR_CHECK_NEAR(cx1 - cx0, 0.1, 0.01);
    /* Bad frames are refused by name. */
    frames[5] = NAN;
    cr_sim *bad = NULL;
    CR_CHECK(cr_sim_create(&d, m, &bad, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "pin_frames") != NULL);
    cr_sim_destroy(bad);
    cr_sim_destroy(s);
    cr_mesh_destroy(m);
    free(frames);
}

/* Refining a cloth grid reproduces an affine deformation exactly (bilinear
 * interpolation), keeps the corners, and refuses meshes of the wrong size. */
CR_TEST(phys_sim, cloth_refine_interpolates) {
    cr_error err = {0};
    cr_mesh *coarse = NULL, *fine = NULL, *expect = NULL;
    CR_CHECK_OK(cr_prim_plane(5, 5, 1.0f, 1.0f, &coarse, &err), &err);
    CR_CHECK_OK(cr_prim_plane(13, 13, 1.0f, 1.0f, &fine, &err), &err);
    CR_CHECK_OK(cr_prim_plane(13, 13, 1.0f, 1.0f, &expect, &err), &err);
    cr_mesh *grids[2] = {coarse, expect};
    for (int g = 0; g < 2; g++)
        for (int32_t v = 0; v < grids[g]->nv; v++) {
            float *p = grids[g]->pos + 3 * v;
            p[1] = 0.3f * p[0] - 0.2f * p[2] + 0.1f;
            p[0] = 1.5f * p[0] + 0.25f * p[2];
        }
    CR_CHECK_OK(cr_scene_cloth_refine(coarse, 5, fine, 13, &err), &err);
    double worst = 0.0;
    for (int32_t k = 0; k < 3 * fine->nv; k++)
        worst = fmax(worst, fabs(fine->pos[k] - expect->pos[k]));
    CR_CHECK(worst < 1e-6);
    for (int d = 0; d < 3; d++) {
        CR_CHECK(fine->pos[d] == coarse->pos[d]);
        CR_CHECK(fine->pos[3 * (13 * 13 - 1) + d] == coarse->pos[3 * (5 * 5 - 1) + d]);
    }
    CR_CHECK(cr_scene_cloth_refine(coarse, 4, fine, 13, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "coarse cloth has 25 vertices, not 4 x 4"));
    CR_CHECK(cr_scene_cloth_refine(coarse, 5, fine, 12, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "fine cloth"));
    cr_mesh_destroy(coarse);
    cr_mesh_destroy(fine);
    cr_mesh_destroy(expect);
}
