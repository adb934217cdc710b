/* test_vertex_grid.c: the grid's nearest vertex against brute force over all
 * vertices (ties to the lowest index) and against the BVH it stands in for.
 *
 * Meshes: a UV sphere (vertices crowd at the poles, the drape ball's case), a
 * torus (concave), a regular plane whose query points sit exactly halfway
 * between vertices (four-way ties), each as a face tree and as a tree of
 * one-vertex faces (v, v, v), the drape's. Points: uniform in the box,
 * within a few millimetres of the surface, on vertices, outside the box. */
#include "crease/bvh.h"
#include "crease/primitives.h"
#include "crease/vertex_grid.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int32_t brute_nearest(const cr_mesh *m, const float p[3], double *d2_out) {
    double best = INFINITY;
    int32_t at = -1;
    for (int32_t v = 0; v < m->nv; v++) {
        double dx = (double)p[0] - m->pos[3 * v], dy = (double)p[1] - m->pos[3 * v + 1],
               dz = (double)p[2] - m->pos[3 * v + 2];
        double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < best) best = d2, at = v;
    }
    if (d2_out) *d2_out = best;
    return at;
}

static void mesh_box(const cr_mesh *m, float grow, float lo[3], float hi[3]) {
    for (int d = 0; d < 3; d++)
        lo[d] = INFINITY, hi[d] = -INFINITY;
    for (int32_t v = 0; v < m->nv; v++)
        for (int d = 0; d < 3; d++) {
            lo[d] = fminf(lo[d], m->pos[3 * v + d]);
            hi[d] = fmaxf(hi[d], m->pos[3 * v + d]);
        }
    for (int d = 0; d < 3; d++)
        lo[d] -= grow, hi[d] += grow;
}

static cr_bvh *vertex_tree(const cr_mesh *m) {
    int32_t *tri = malloc(3 * (size_t)m->nv * sizeof *tri);
    for (int32_t v = 0; v < m->nv; v++)
        tri[3 * v] = tri[3 * v + 1] = tri[3 * v + 2] = v;
    cr_bvh *b = NULL;
    cr_error err = {0};
    cr_status st = cr_bvh_build(m->pos, m->nv, tri, m->nv, &b, &err);
    free(tri);
    return st == CR_OK ? b : NULL;
}

/* Points: uniform in the box grown by a tenth, near vertices, on vertices. */
static float *test_points(const cr_mesh *m, const float lo[3], const float hi[3], int64_t n,
                          uint64_t seed) {
    float *p = malloc(3 * (size_t)n * sizeof *p);
    cr_rng r = cr_rng_make(seed, 0);
    for (int64_t i = 0; i < n; i++) {
        const int32_t v = (int32_t)cr_rng_below(&r, (uint32_t)m->nv);
        for (int d = 0; d < 3; d++) {
            const float ext = hi[d] - lo[d];
            switch (i % 3) {
            case 0: p[3 * i + d] = lo[d] - 0.1f * ext + 1.2f * ext * cr_rng_uniformf(&r); break;
            case 1: p[3 * i + d] = m->pos[3 * v + d] + 0.01f * (float)cr_rng_normal(&r); break;
            default: p[3 * i + d] = m->pos[3 * v + d];
            }
        }
    }
    return p;
}

/* Every point: the grid's vertex and distance equal brute force's and the
 * tree's; returns the mismatches. */
static int64_t mismatches(const cr_mesh *m, const cr_bvh *tree, const cr_vertex_grid *g,
                          const float *pts, int64_t n) {
    int64_t bad = 0;
    for (int64_t i = 0; i < n; i++) {
        double d2;
        const int32_t want = brute_nearest(m, &pts[3 * i], &d2);
        float dg, dt;
        const int32_t got = cr_vertex_grid_nearest(g, &pts[3 * i], &dg);
        const int32_t tv = cr_bvh_nearest_vertex(tree, &pts[3 * i], INFINITY, &dt);
        if (got != want || tv != want || dg != (float)sqrt(d2) || dt != dg) {
            if (bad++ == 0)
                fprintf(stderr, "point %lld (%.9g %.9g %.9g): grid %d tree %d brute %d\n",
                        (long long)i, pts[3 * i], pts[3 * i + 1], pts[3 * i + 2], got, tv, want);
        }
    }
    return bad;
}

CR_TEST(vertex_grid, matches_brute_force_and_the_tree) {
    cr_error err = {0};
    cr_mesh *meshes[2] = {NULL, NULL};
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &meshes[0], &err), &err);
    CR_CHECK_OK(cr_prim_torus(0.3f, 0.1f, 32, 16, &meshes[1], &err), &err);
    const int64_t n = CR_TEST_SIZE(6000, 1500);
    for (int k = 0; k < 2; k++) {
        const cr_mesh *m = meshes[k];
        CR_REQUIRE(m);
        float lo[3], hi[3];
        mesh_box(m, 0.002f, lo, hi);
        float *pts = test_points(m, lo, hi, n, 7 + k);
        for (int face_tree = 0; face_tree < 2; face_tree++) {
            cr_bvh *tree = NULL;
            if (face_tree)
                CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &tree, &err), &err);
            else
                tree = vertex_tree(m);
            CR_REQUIRE(tree);
            cr_vertex_grid *g = NULL;
            CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, NULL, &g, &err), &err);
            CR_REQUIRE(g);
            int64_t entries = 0, overfull = 0;
            int32_t cells[3];
            cr_vertex_grid_stats(g, cells, &entries, &overfull);
            /* the lists answer most cells: the grid is not the tree in disguise */
            CR_CHECK((double)overfull < 0.5 * cells[0] * cells[1] * cells[2]);
            CR_CHECK(entries > 0);
            CR_CHECK(mismatches(m, tree, g, pts, n) == 0);
            cr_vertex_grid_destroy(g);
            cr_bvh_destroy(tree);
        }
        free(pts);
        cr_mesh_destroy(meshes[k]);
    }
}

/* A regular plane with dyadic spacing: points halfway between four vertices
 * are exactly equidistant from them; both answer the lowest index. */
CR_TEST(vertex_grid, ties_go_to_the_lowest_index) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(9, 9, 1.0f, 1.0f, &m, &err), &err); /* 0.125 apart */
    CR_REQUIRE(m);
    cr_bvh *tree = vertex_tree(m);
    CR_REQUIRE(tree);
    float lo[3], hi[3];
    mesh_box(m, 0.002f, lo, hi);
    cr_vertex_grid *g = NULL;
    CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, NULL, &g, &err), &err);
    CR_REQUIRE(g);
    int64_t n = 0, ties = 0;
    float *pts = malloc(3 * 64 * sizeof *pts);
    for (int i = 0; i < 8; i++)
        for (int j = 0; j < 8; j++, n++) {
            pts[3 * n] = -0.5f + 0.0625f + 0.125f * (float)i;
            pts[3 * n + 1] = 0.0f;
            pts[3 * n + 2] = -0.5f + 0.0625f + 0.125f * (float)j;
            int equal = 0;
            double best;
            brute_nearest(m, &pts[3 * n], &best);
            for (int32_t v = 0; v < m->nv; v++) {
                double dx = pts[3 * n] - m->pos[3 * v], dz = pts[3 * n + 2] - m->pos[3 * v + 2];
                equal += dx * dx + dz * dz == best;
            }
            ties += equal >= 2;
        }
    CR_CHECK(ties == n); /* the premise: every point is a tie */
    CR_CHECK(mismatches(m, tree, g, pts, n) == 0);
    free(pts);
    cr_vertex_grid_destroy(g);
    cr_bvh_destroy(tree);
    cr_mesh_destroy(m);
}

/* Short lists, a short reach or a small memory budget send cells to the
 * tree; the answers do not change, nor do they with the thread count. */
CR_TEST(vertex_grid, fallbacks_and_threads_change_nothing) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 48, 24, &m, &err), &err);
    CR_REQUIRE(m);
    cr_bvh *tree = vertex_tree(m);
    CR_REQUIRE(tree);
    float lo[3], hi[3];
    mesh_box(m, 0.002f, lo, hi);
    const int64_t n = CR_TEST_SIZE(3000, 900);
    float *pts = test_points(m, lo, hi, n, 3);
    cr_vertex_grid_opts tight = cr_vertex_grid_default_opts();
    tight.max_list = 3, tight.reach_cells = 1.5;
    cr_vertex_grid *g = NULL;
    CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, &tight, &g, &err), &err);
    CR_REQUIRE(g);
    int64_t overfull = 0;
    cr_vertex_grid_stats(g, NULL, NULL, &overfull);
    CR_CHECK(overfull > 0);
    CR_CHECK(mismatches(m, tree, g, pts, n) == 0);
    cr_vertex_grid_destroy(g);
    /* a memory budget of 500 entries: the cells past it keep no list */
    cr_vertex_grid_opts small = cr_vertex_grid_default_opts();
    small.max_entries = 500;
    CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, &small, &g, &err), &err);
    CR_REQUIRE(g);
    int64_t listed = 0;
    cr_vertex_grid_stats(g, NULL, &listed, NULL);
    CR_CHECK(listed > 0 && listed <= 500);
    CR_CHECK(mismatches(m, tree, g, pts, n) == 0);
    cr_vertex_grid_destroy(g);

    int64_t entries[2] = {0, 0};
    int32_t *answers[2];
    const int threads = cr_thread_count();
    for (int k = 0; k < 2; k++) {
        cr_set_thread_count(k == 0 ? 1 : threads);
        CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, NULL, &g, &err), &err);
        CR_REQUIRE(g);
        cr_vertex_grid_stats(g, NULL, &entries[k], NULL);
        answers[k] = malloc((size_t)n * sizeof(int32_t));
        for (int64_t i = 0; i < n; i++)
            answers[k][i] = cr_vertex_grid_nearest(g, &pts[3 * i], NULL);
        cr_vertex_grid_destroy(g);
    }
    cr_set_thread_count(threads);
    CR_CHECK(entries[0] == entries[1]);
    CR_CHECK(memcmp(answers[0], answers[1], (size_t)n * sizeof(int32_t)) == 0);
    free(answers[0]);
    free(answers[1]);
    free(pts);
    cr_bvh_destroy(tree);
    cr_mesh_destroy(m);
}

CR_TEST(vertex_grid, rejects_bad_input) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 1, &m, &err), &err);
    CR_REQUIRE(m);
    cr_bvh *tree = vertex_tree(m);
    CR_REQUIRE(tree);
    const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1}, nan_hi[3] = {1, NAN, 1},
                flipped[3] = {1, -2, 1};
    cr_vertex_grid *g = NULL;
    CR_CHECK(cr_vertex_grid_build(tree, lo, nan_hi, NULL, &g, &err) == CR_ERR_INVALID && !g);
    CR_CHECK(strstr(err.msg, "axis 1") != NULL);
    CR_CHECK(cr_vertex_grid_build(tree, lo, flipped, NULL, &g, &err) == CR_ERR_INVALID && !g);
    cr_vertex_grid_opts o = cr_vertex_grid_default_opts();
    o.cells_per_vertex = 0.0;
    CR_CHECK(cr_vertex_grid_build(tree, lo, hi, &o, &g, &err) == CR_ERR_INVALID && !g);
    o = cr_vertex_grid_default_opts();
    o.reach_cells = NAN;
    CR_CHECK(cr_vertex_grid_build(tree, lo, hi, &o, &g, &err) == CR_ERR_INVALID && !g);
    o = cr_vertex_grid_default_opts();
    o.max_entries = -1;
    CR_CHECK(cr_vertex_grid_build(tree, lo, hi, &o, &g, &err) == CR_ERR_INVALID && !g);
    o = cr_vertex_grid_default_opts();
    o.max_list = 0;
    CR_CHECK(cr_vertex_grid_build(tree, lo, hi, &o, &g, &err) == CR_ERR_INVALID && !g);
    /* a point that is not a number: what the tree says (-1) */
    CR_CHECK_OK(cr_vertex_grid_build(tree, lo, hi, NULL, &g, &err), &err);
    const float p[3] = {0.0f, NAN, 0.0f};
    CR_CHECK(cr_vertex_grid_nearest(g, p, NULL) == cr_bvh_nearest_vertex(tree, p, INFINITY, NULL));
    cr_vertex_grid_destroy(g);
    cr_bvh_destroy(tree);
    cr_mesh_destroy(m);
}
