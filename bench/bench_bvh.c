/* bench_bvh.c: BVH build and refit time, and query throughput, on a torus of
 * 100,000 triangles (cr_prim_torus(1.0, 0.3, 250, 200): 50,000 vertices).
 *
 * Queries are 1M points near the surface (a uniform random face, a uniform
 * random point on it, moved along its normal by up to +-0.03 m, a tenth of
 * the tube radius), run batched on all threads with no distance limit, as a
 * collision loss would. Times are the best of a few repeats.
 *
 * Usage: bench_bvh [queries] [threads]   (defaults: 1000000, all)
 */
#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/primitives.h"

#include <math.h>
#include <stdlib.h>

enum { REPEATS = 5 };

static void near_surface_points(const cr_mesh *m, int64_t n, float *pts) {
    cr_rng r = cr_rng_make(2024, 0);
    for (int64_t i = 0; i < n; i++) {
        const int32_t *t = &m->tri[3 * (size_t)cr_rng_below(&r, (uint32_t)m->nf)];
        float u = cr_rng_uniformf(&r), v = cr_rng_uniformf(&r);
        if (u + v > 1) u = 1 - u, v = 1 - v;
        const float *a = &m->pos[3 * t[0]], *b = &m->pos[3 * t[1]], *c = &m->pos[3 * t[2]];
        float nrm[3];
        cr_triangle_normal(a, b, c, nrm);
        float off = 0.03f * (2 * cr_rng_uniformf(&r) - 1);
        for (int d = 0; d < 3; d++)
            pts[3 * i + d] = a[d] + u * (b[d] - a[d]) + v * (c[d] - a[d]) + off * nrm[d];
    }
}

int main(int argc, char **argv) {
    int64_t nq = argc > 1 ? atoll(argv[1]) : 1000000;
    if (argc > 2) cr_set_thread_count(atoi(argv[2]));
    if (nq < 1) nq = 1;
    cr_error err = {0};
    cr_mesh *m = NULL;
    if (cr_prim_torus(1.0f, 0.3f, 250, 200, &m, &err) != CR_OK) {
        fprintf(stderr, "bench_bvh: %s\n", err.msg);
        return 1;
    }
    printf("bvh threads: %d\n", cr_thread_count());
    printf("bvh mesh: torus, %d tris, %d verts\n", m->nf, m->nv);

    cr_bvh *b = NULL;
    double best = INFINITY;
    for (int rep = 0; rep < REPEATS; rep++) {
        cr_bvh_destroy(b);
        double t0 = cr_time_now();
        if (cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err) != CR_OK) {
            fprintf(stderr, "bench_bvh: %s\n", err.msg);
            return 1;
        }
        best = fmin(best, cr_time_now() - t0);
    }
    printf("bvh build %d tris: %.2f ms (%d nodes, depth %d)\n", m->nf, 1e3 * best,
           cr_bvh_node_count(b), cr_bvh_depth(b));

    /* Refit to a swaying pose (the tree stays valid for any positions). */
    float *moved = malloc((size_t)m->nv * 3 * sizeof(float));
    float *pts = malloc((size_t)nq * 3 * sizeof(float));
    float *dist = malloc((size_t)nq * sizeof(float)), *nrm = malloc((size_t)nq * 3 * sizeof(float));
    int32_t *idx = malloc((size_t)nq * sizeof(int32_t));
    if (!moved || !pts || !dist || !nrm || !idx) {
        fprintf(stderr, "bench_bvh: out of memory\n");
        return 1;
    }
    for (int32_t v = 0; v < m->nv; v++) {
        const float *p = &m->pos[3 * v];
        moved[3 * v + 0] = p[0] + 0.1f * sinf(2 * p[1]);
        moved[3 * v + 1] = p[1] + 0.05f * p[0];
        moved[3 * v + 2] = p[2];
    }
    best = INFINITY;
    for (int rep = 0; rep < REPEATS; rep++) {
        double t0 = cr_time_now();
        if (cr_bvh_refit(b, rep % 2 ? m->pos : moved, &err) != CR_OK) {
            fprintf(stderr, "bench_bvh: %s\n", err.msg);
            return 1;
        }
        best = fmin(best, cr_time_now() - t0);
    }
    printf("bvh refit %d tris: %.2f ms\n", m->nf, 1e3 * best);
    if (cr_bvh_refit(b, m->pos, &err) != CR_OK) return 1;

    near_surface_points(m, nq, pts);

    double t_closest = INFINITY, t_signed = INFINITY, t_vertex = INFINITY, t_ray = INFINITY;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = cr_time_now();
        cr_bvh_closest_batch(b, pts, nq, INFINITY, idx, NULL, NULL, dist);
        double t1 = cr_time_now();
        cr_bvh_signed_distance_batch(b, pts, nq, INFINITY, dist, nrm, NULL);
        double t2 = cr_time_now();
        cr_bvh_nearest_vertex_batch(b, pts, nq, INFINITY, idx, dist);
        double t3 = cr_time_now();
        /* Rays from the near-surface points towards the Y axis (through the hole or the tube). */
        for (int64_t i = 0; i < nq; i++) {
            nrm[3 * i + 0] = -pts[3 * i];
            nrm[3 * i + 1] = 0.05f;
            nrm[3 * i + 2] = -pts[3 * i + 2];
        }
        double t4 = cr_time_now();
        cr_bvh_raycast_batch(b, pts, nrm, nq, INFINITY, idx, dist, NULL);
        double t5 = cr_time_now();
        t_closest = fmin(t_closest, t1 - t0);
        t_signed = fmin(t_signed, t2 - t1);
        t_vertex = fmin(t_vertex, t3 - t2);
        t_ray = fmin(t_ray, t5 - t4);
    }
    printf("bvh closest point %lld queries: %.3g queries/s\n", (long long)nq, nq / t_closest);
    printf("bvh signed distance %lld queries: %.3g queries/s\n", (long long)nq, nq / t_signed);
    printf("bvh nearest vertex %lld queries: %.3g queries/s\n", (long long)nq, nq / t_vertex);
    printf("bvh raycast %lld rays: %.3g rays/s\n", (long long)nq, nq / t_ray);

    free(moved), free(pts), free(dist), free(nrm), free(idx);
    cr_bvh_destroy(b);
    cr_mesh_destroy(m);
    return 0;
}
