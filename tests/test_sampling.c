/* test_sampling.c: Dijkstra against Floyd-Warshall on small meshes built
 * independently from the face list, and against the Euclidean lower bound;
 * farthest point sampling returns distinct points, each the farthest from
 * those before it, with a coverage radius that never grows. */
#include "crease/primitives.h"
#include "crease/sampling.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static double vdist(const float *pos, int32_t a, int32_t b) {
    double s = 0;
    for (int d = 0; d < 3; d++) {
        double x = (double)pos[3 * a + d] - pos[3 * b + d];
        s += x * x;
    }
    return sqrt(s);
}

/* All-pairs shortest paths (V,V) over the edges of the face list. */
static double *floyd(const cr_mesh *m) {
    int32_t n = m->nv;
    double *D = malloc((size_t)n * n * sizeof(double));
    if (!D) return NULL;
    for (int64_t i = 0; i < (int64_t)n * n; i++)
        D[i] = INFINITY;
    for (int32_t i = 0; i < n; i++)
        D[(int64_t)i * n + i] = 0.0;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t a = m->tri[3 * f + k], b = m->tri[3 * f + (k + 1) % 3];
            double w = vdist(m->pos, a, b);
            D[(int64_t)a * n + b] = D[(int64_t)b * n + a] = w;
        }
    for (int32_t k = 0; k < n; k++)
        for (int32_t i = 0; i < n; i++)
            for (int32_t j = 0; j < n; j++) {
                double via = D[(int64_t)i * n + k] + D[(int64_t)k * n + j];
                if (via < D[(int64_t)i * n + j]) D[(int64_t)i * n + j] = via;
            }
    return D;
}

CR_TEST(sampling, dijkstra_matches_floyd) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(6, 5, 1.0f, 0.8f, &m, &err), &err);
    CR_REQUIRE(m);
    /* Jitter heights so edge weights differ and ties are rare. */
    cr_rng r = cr_rng_make(2, 0);
    for (int32_t v = 0; v < m->nv; v++)
        m->pos[3 * v + 1] = 0.1f * (float)cr_rng_uniform(&r);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    double *D = floyd(m);
    CR_REQUIRE(D);
    int32_t n = m->nv;
    float dist[30];
    for (int32_t s = 0; s < n; s++) {
        CR_CHECK_OK(cr_geodesic_dijkstra(m, t, &s, 1, dist, &err), &err);
        for (int32_t v = 0; v < n; v++) {
            CR_CHECK_NEAR(dist[v], D[(int64_t)s * n + v], 1e-6);
            CR_CHECK(dist[v] >= vdist(m->pos, s, v) - 1e-6);
        }
    }
    /* Several sources: the minimum over single-source runs. */
    const int32_t src[3] = {0, 17, 29};
    CR_CHECK_OK(cr_geodesic_dijkstra(m, t, src, 3, dist, &err), &err);
    for (int32_t v = 0; v < n; v++) {
        double want = INFINITY;
        for (int i = 0; i < 3; i++)
            want = fmin(want, D[(int64_t)src[i] * n + v]);
        CR_CHECK_NEAR(dist[v], want, 1e-6);
    }
    /* Bad arguments. */
    int32_t bad = n;
    CR_CHECK(cr_geodesic_dijkstra(m, t, &bad, 1, dist, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "vertex 30") != NULL);
    CR_CHECK(cr_geodesic_dijkstra(m, t, src, 0, dist, &err) == CR_ERR_INVALID);
    free(D);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(sampling, dijkstra_unreachable_is_infinite) {
    /* Two separate triangles. */
    cr_mesh *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mesh_create(6, 2, 0, &m, &err), &err);
    CR_REQUIRE(m);
    const int32_t tri[6] = {0, 1, 2, 3, 4, 5};
    memcpy(m->tri, tri, sizeof tri);
    for (int32_t v = 0; v < 6; v++)
        m->pos[3 * v] = (float)v, m->pos[3 * v + 1] = (float)(v % 3 == 2);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    float dist[6];
    int32_t s = 1;
    CR_CHECK_OK(cr_geodesic_dijkstra(m, t, &s, 1, dist, &err), &err);
    CR_CHECK(dist[1] == 0.0f && dist[0] == 1.0f && isfinite(dist[2]));
    CR_CHECK(isinf(dist[3]) && isinf(dist[4]) && isinf(dist[5]));
    /* Geodesic FPS reaches the other component with its second sample. */
    int32_t idx[6];
    CR_CHECK_OK(cr_fps_geodesic(m, t, 6, 1, idx, &err), &err);
    CR_CHECK(idx[0] == 1 && idx[1] >= 3);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(sampling, fps_euclidean_farthest_and_monotone) {
    const int32_t n = 600, k = 60;
    float *pts = malloc((size_t)n * 3 * sizeof(float));
    double *mind = malloc((size_t)n * sizeof(double));
    CR_REQUIRE(pts && mind);
    cr_rng r = cr_rng_make(9, 0);
    for (int32_t i = 0; i < 3 * n; i++)
        pts[i] = (float)cr_rng_normal(&r);
    int32_t idx[60];
    cr_error err = {0};
    CR_CHECK_OK(cr_fps_euclidean(pts, n, k, 5, idx, &err), &err);
    CR_CHECK(idx[0] == 5);
    for (int32_t i = 0; i < n; i++)
        mind[i] = INFINITY;
    double prev_radius = INFINITY;
    for (int32_t j = 0; j < k; j++) {
        CR_REQUIRE(idx[j] >= 0 && idx[j] < n);
        for (int32_t i = 0; i < j; i++)
            CR_CHECK(idx[i] != idx[j]);
        /* idx[j] is (one of) the farthest from the samples before it. */
        double radius = 0.0;
        for (int32_t i = 0; i < n; i++)
            radius = fmax(radius, mind[i]);
        if (j > 0) CR_CHECK_NEAR(mind[idx[j]], radius, 1e-6 * radius);
        CR_CHECK(radius <= prev_radius);
        prev_radius = radius;
        for (int32_t i = 0; i < n; i++)
            mind[i] = fmin(mind[i], vdist(pts, i, idx[j]));
    }
    /* Coincident points: still k distinct indices. */
    memset(pts, 0, (size_t)n * 3 * sizeof(float));
    CR_CHECK_OK(cr_fps_euclidean(pts, 8, 8, 3, idx, &err), &err);
    int seen[8] = {0};
    for (int j = 0; j < 8; j++)
        seen[idx[j]]++;
    for (int j = 0; j < 8; j++)
        CR_CHECK(seen[j] == 1);
    CR_CHECK(cr_fps_euclidean(pts, 8, 9, 0, idx, &err) == CR_ERR_RANGE);
    CR_CHECK(cr_fps_euclidean(pts, 8, 2, 8, idx, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "first = 8") != NULL);
    free(pts);
    free(mind);
}

CR_TEST(sampling, fps_geodesic_farthest_and_monotone) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 3, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    const int32_t k = 24;
    int32_t idx[24];
    CR_CHECK_OK(cr_fps_geodesic(m, t, k, 0, idx, &err), &err);
    float *dist = malloc((size_t)m->nv * sizeof(float));
    CR_REQUIRE(dist);
    double prev_radius = INFINITY;
    for (int32_t j = 1; j < k; j++) {
        for (int32_t i = 0; i < j; i++)
            CR_CHECK(idx[i] != idx[j]);
        /* Independent check: multi-source Dijkstra from the first j samples. */
        CR_CHECK_OK(cr_geodesic_dijkstra(m, t, idx, j, dist, &err), &err);
        double radius = 0.0;
        for (int32_t v = 0; v < m->nv; v++)
            radius = fmax(radius, dist[v]);
        CR_CHECK_NEAR(dist[idx[j]], radius, 1e-6);
        CR_CHECK(radius <= prev_radius);
        prev_radius = radius;
    }
    /* The second sample on a sphere is near the antipode of the first. */
    const float *a = &m->pos[3 * idx[0]], *b = &m->pos[3 * idx[1]];
    CR_CHECK(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < -0.95f);
    CR_CHECK(cr_fps_geodesic(m, t, m->nv + 1, 0, idx, &err) == CR_ERR_RANGE);
    free(dist);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}
