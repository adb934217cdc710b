/* test_bvh.c: BVH queries against brute force over all triangles.
 *
 * The references here are written independently of bvh_query.c: point to
 * triangle distance by projection onto the plane or else the nearest edge,
 * inside/outside by the generalised winding number (solid angles, van
 * Oosterom & Strackee 1983), rays by a plain loop over all faces. Meshes: an
 * icosphere and a torus (also against their analytic SDFs), a non-convex
 * "crater box" whose top face is pushed deep inside (concave edges and
 * corners), and the triangular prism, whose 120-degree edge turns make a
 * face-normal sign test fail where pseudo-normals succeed (checked by hand
 * by disabling the edge and vertex pseudo-normals: this test then fails). */
#include "base/vec3.h"
#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/primitives.h"
#include "geom/bvh_internal.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/* --------------------------------------------------------- references -- */

static double seg_dist2(const float *a, const float *b, const double p[3]) {
    double e[3], q[3];
    sub3fd(b, a, e);
    for (int d = 0; d < 3; d++)
        q[d] = p[d] - a[d];
    double ee = dot3d(e, e), t = ee > 0 ? dot3d(q, e) / ee : 0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    double r = 0;
    for (int d = 0; d < 3; d++)
        r += (q[d] - t * e[d]) * (q[d] - t * e[d]);
    return r;
}

static double ref_tri_dist2(const float *a, const float *b, const float *c, const double p[3]) {
    double ab[3], ac[3], n[3];
    sub3fd(b, a, ab);
    sub3fd(c, a, ac);
    cross3d(ab, ac, n);
    double nn = dot3d(n, n);
    if (nn > 0) {
        double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
        double h = dot3d(ap, n) / nn, q[3];
        for (int d = 0; d < 3; d++)
            q[d] = p[d] - h * n[d];
        const float *v[3] = {a, b, c};
        int inside = 1;
        for (int k = 0; k < 3; k++) {
            double e[3], w[3], x[3];
            sub3fd(v[(k + 1) % 3], v[k], e);
            for (int d = 0; d < 3; d++)
                w[d] = q[d] - v[k][d];
            cross3d(e, w, x);
            if (dot3d(x, n) < 0) inside = 0;
        }
        if (inside) return h * h * nn;
    }
    double d = seg_dist2(a, b, p);
    d = fmin(d, seg_dist2(b, c, p));
    return fmin(d, seg_dist2(c, a, p));
}

static double ref_dist(const cr_mesh *m, const double p[3]) {
    double best = INFINITY;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        best =
            fmin(best, ref_tri_dist2(&m->pos[3 * t[0]], &m->pos[3 * t[1]], &m->pos[3 * t[2]], p));
    }
    return sqrt(best);
}

/* Generalised winding number: ~1 inside a closed outward mesh, ~0 outside. */
static double winding(const cr_mesh *m, const double p[3]) {
    double w = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        double a[3], b[3], c[3], bc[3];
        for (int d = 0; d < 3; d++) {
            a[d] = m->pos[3 * m->tri[3 * f] + d] - p[d];
            b[d] = m->pos[3 * m->tri[3 * f + 1] + d] - p[d];
            c[d] = m->pos[3 * m->tri[3 * f + 2] + d] - p[d];
        }
        cross3d(b, c, bc);
        double la = sqrt(dot3d(a, a)), lb = sqrt(dot3d(b, b)), lc = sqrt(dot3d(c, c));
        w += 2 * atan2(dot3d(a, bc),
                       la * lb * lc + dot3d(a, b) * lc + dot3d(a, c) * lb + dot3d(b, c) * la);
    }
    return w / (4 * PI);
}

/* ------------------------------------------------------------- meshes -- */

/* A unit box whose top-face vertices with |x|, |z| < 0.3 are sunk to y = -0.2:
 * a closed heightfield crater with concave rim edges and corners. */
static cr_mesh *crater_box(void) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    if (cr_prim_box(1, 1, 1, 8, &m, &err) != CR_OK) return NULL;
    for (int32_t v = 0; v < m->nv; v++) {
        float *p = &m->pos[3 * v];
        if (p[1] == 0.5f && fabsf(p[0]) < 0.3f && fabsf(p[2]) < 0.3f) p[1] = -0.2f;
    }
    return m;
}

static float *random_points(const cr_mesh *m, int64_t n, float grow, uint64_t seed) {
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    float *pts = malloc((size_t)n * 3 * sizeof(float));
    cr_rng r = cr_rng_make(seed, 0);
    for (int64_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) {
            float ext = hi[d] - lo[d];
            pts[3 * i + d] = lo[d] - grow * ext + (1 + 2 * grow) * ext * cr_rng_uniformf(&r);
        }
    return pts;
}

/* Tree invariants: every face in exactly one leaf, leaves of 1..4 faces
 * containing their triangles, parents containing their children. */
static int bvh_is_valid(const cr_bvh *b) {
    int32_t *seen = calloc((size_t)b->nf, sizeof(int32_t));
    int ok = 1;
    for (int32_t i = 0; i < b->nnodes && ok; i++) {
        const bvh_node *n = &b->nodes[i];
        if (n->count > 0) {
            if (n->count > BVH_LEAF_MAX) ok = 0;
            for (int32_t k = 0; k < n->count && ok; k++) {
                int32_t f = b->order[n->start + k];
                seen[f]++;
                for (int c = 0; c < 3; c++)
                    for (int d = 0; d < 3; d++) {
                        float x = b->pos[3 * b->tri[3 * f + c] + d];
                        if (x < n->lo[d] || x > n->hi[d]) ok = 0;
                    }
            }
        } else {
            if (n->start <= i || n->start + 1 >= b->nnodes) ok = 0;
            for (int c = 0; c < 2 && ok; c++)
                for (int d = 0; d < 3; d++) {
                    const bvh_node *ch = &b->nodes[n->start + c];
                    if (ch->lo[d] < n->lo[d] || ch->hi[d] > n->hi[d]) ok = 0;
                }
        }
    }
    for (int32_t f = 0; f < b->nf && ok; f++)
        if (seen[f] != 1) ok = 0;
    free(seen);
    return ok;
}

/* -------------------------------------------------------------- tests -- */

/* Brute-force distance and winding number per point, split over threads
 * (the references cost O(F) per point). */
typedef struct ref_ctx {
    const cr_mesh *m;
    const float *pts;
    double *dist, *wind;
} ref_ctx;

static void ref_range(void *ctx, int64_t begin, int64_t end) {
    const ref_ctx *c = ctx;
    for (int64_t i = begin; i < end; i++) {
        double p[3] = {c->pts[3 * i], c->pts[3 * i + 1], c->pts[3 * i + 2]};
        c->dist[i] = ref_dist(c->m, p);
        c->wind[i] = winding(c->m, p);
    }
}

/* |d| against brute force to 1e-5 relative; the sign against the winding
 * number for every point farther than 1e-4 from the surface. */
static void check_signed_distance(const cr_mesh *m, const char *name, uint64_t seed,
                                  double (*sdf)(const double *), double sdf_tol) {
    cr_error err = {0};
    cr_bvh *b = NULL;
    CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err), &err);
    CR_REQUIRE(b);
    CR_CHECK(bvh_is_valid(b));
    const int64_t n = 10000;
    float *pts = random_points(m, n, 0.2f, seed);
    float *dist = malloc(n * sizeof(float)), *nrm = malloc(3 * n * sizeof(float));
    cr_bvh_signed_distance_batch(b, pts, n, INFINITY, dist, nrm, NULL);
    double *refd = malloc(n * sizeof(double)), *wind = malloc(n * sizeof(double));
    ref_ctx rc = {m, pts, refd, wind};
    cr_parallel_for(n, 64, ref_range, &rc);
    int64_t bad_dist = 0, bad_sign = 0, bad_sdf = 0, bad_normal = 0;
    for (int64_t i = 0; i < n; i++) {
        double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
        double ref = refd[i];
        if (!(fabs(fabs(dist[i]) - ref) <= 1e-5 * ref + 1e-7)) {
            if (bad_dist++ == 0) fprintf(stderr, "%s: |d| %.9g vs ref %.9g\n", name, dist[i], ref);
        }
        if (ref > 1e-4) {
            int inside = wind[i] > 0.5;
            if (inside != (dist[i] < 0)) {
                if (bad_sign++ == 0)
                    fprintf(stderr, "%s: point (%g %g %g) d %g winding %g\n", name, p[0], p[1],
                            p[2], dist[i], wind[i]);
            }
        }
        if (sdf && !(fabs(dist[i] - sdf(p)) <= sdf_tol)) bad_sdf++;
        double len =
            sqrt((double)nrm[3 * i] * nrm[3 * i] + (double)nrm[3 * i + 1] * nrm[3 * i + 1] +
                 (double)nrm[3 * i + 2] * nrm[3 * i + 2]);
        if (fabs(len - 1) > 1e-5) bad_normal++;
    }
    CR_CHECK(bad_dist == 0);
    CR_CHECK(bad_sign == 0);
    CR_CHECK(bad_sdf == 0);
    CR_CHECK(bad_normal == 0);
    free(pts), free(dist), free(nrm), free(refd), free(wind);
    cr_bvh_destroy(b);
}

static double sphere_sdf(const double *p) {
    return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 1.0;
}
static double torus_sdf(const double *p) {
    double q = sqrt(p[0] * p[0] + p[2] * p[2]) - 1.0;
    return sqrt(q * q + p[1] * p[1]) - 0.35;
}

CR_TEST(bvh, signed_distance_sphere) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 3, &m, &err), &err);
    CR_REQUIRE(m);
    /* The inscribed mesh is within its deepest face-plane distance of the sphere. */
    double sag = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        double ab[3], ac[3], n[3],
            a[3] = {m->pos[3 * m->tri[3 * f]], m->pos[3 * m->tri[3 * f] + 1],
                    m->pos[3 * m->tri[3 * f] + 2]};
        sub3fd(&m->pos[3 * m->tri[3 * f + 1]], &m->pos[3 * m->tri[3 * f]], ab);
        sub3fd(&m->pos[3 * m->tri[3 * f + 2]], &m->pos[3 * m->tri[3 * f]], ac);
        cross3d(ab, ac, n);
        sag = fmax(sag, 1.0 - dot3d(a, n) / sqrt(dot3d(n, n)));
    }
    check_signed_distance(m, "icosphere", 1, sphere_sdf, sag + 1e-5);
    cr_mesh_destroy(m);
}

CR_TEST(bvh, signed_distance_torus) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_torus(1.0f, 0.35f, 32, 16, &m, &err), &err);
    CR_REQUIRE(m);
    /* Chord sag of the major (outer radius) and minor polygons. */
    double sag = 1.35 * (1 - cos(PI / 32)) + 0.35 * (1 - cos(PI / 16));
    check_signed_distance(m, "torus", 2, torus_sdf, sag + 1e-5);
    cr_mesh_destroy(m);
}

CR_TEST(bvh, signed_distance_concave_crater) {
    cr_mesh *m = crater_box();
    CR_REQUIRE(m);
    check_signed_distance(m, "crater", 3, NULL, 0);
    /* Points just above the crater floor and just inside the rim walls are
     * outside; just below the floor, inside. */
    cr_error err = {0};
    cr_bvh *b = NULL;
    CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err), &err);
    CR_REQUIRE(b);
    float d, nrm[3];
    const float above[3] = {0.0f, -0.19f, 0.0f}, below[3] = {0.0f, -0.21f, 0.0f};
    CR_CHECK(cr_bvh_signed_distance(b, above, INFINITY, &d, nrm, NULL) == 1);
    CR_CHECK_NEAR(d, 0.01, 1e-6);
    CR_CHECK_NEAR(nrm[1], 1.0, 1e-6);
    CR_CHECK(cr_bvh_signed_distance(b, below, INFINITY, &d, NULL, NULL) == 1);
    CR_CHECK_NEAR(d, -0.01, 1e-6);
    cr_mesh_destroy(m);
    cr_bvh_destroy(b);
}

/* The prism's 120-degree turns at its edges and corners are where a plain
 * face normal gives the wrong sign and only pseudo-normals get it right. */
CR_TEST(bvh, signed_distance_sharp_prism) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_prism(1.0f, 1.5f, &m, &err), &err);
    CR_REQUIRE(m);
    check_signed_distance(m, "prism", 5, NULL, 0);
    cr_mesh_destroy(m);
}

CR_TEST(bvh, closest_point_features_on_one_triangle) {
    const float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0};
    const int32_t tri[6] = {0, 1, 2, 0, 3, 1}; /* second face is degenerate (collinear) */
    cr_error err = {0};
    cr_bvh *b = NULL;
    CR_CHECK_OK(cr_bvh_build(pos, 3, tri, 1, &b, &err), &err);
    CR_REQUIRE(b);
    cr_bvh_hit h;
    const float pv[3] = {-1, -1, 1}, pe[3] = {0.5f, -1, 0}, pf[3] = {0.2f, 0.2f, 1},
                pbc[3] = {1, 1, -0.5f};
    CR_CHECK(cr_bvh_closest(b, pv, INFINITY, &h) == 1);
    CR_CHECK(h.feature == CR_BVH_VERTEX && h.local == 0 && h.face == 0);
    CR_CHECK_NEAR(h.distance, sqrt(3.0), 1e-6);
    CR_CHECK(cr_bvh_closest(b, pe, INFINITY, &h) == 1);
    CR_CHECK(h.feature == CR_BVH_EDGE && h.local == 0);
    CR_CHECK_NEAR(h.bary[0], 0.5, 1e-7);
    CR_CHECK_NEAR(h.bary[1], 0.5, 1e-7);
    CR_CHECK(cr_bvh_closest(b, pf, INFINITY, &h) == 1);
    CR_CHECK(h.feature == CR_BVH_FACE);
    CR_CHECK_NEAR(h.bary[0], 0.6, 1e-6);
    CR_CHECK_NEAR(h.bary[1], 0.2, 1e-6);
    CR_CHECK_NEAR(h.bary[2], 0.2, 1e-6);
    CR_CHECK_NEAR(h.point[2], 0.0, 1e-7);
    CR_CHECK_NEAR(h.distance, 1.0, 1e-6);
    CR_CHECK(cr_bvh_closest(b, pbc, INFINITY, &h) == 1);
    CR_CHECK(h.feature == CR_BVH_EDGE && h.local == 1);
    CR_CHECK_NEAR(h.point[0], 0.5, 1e-6);
    CR_CHECK_NEAR(h.point[1], 0.5, 1e-6);
    /* max_dist prunes: nothing within 0.5 of pv. */
    CR_CHECK(cr_bvh_closest(b, pv, 0.5f, &h) == 0 && h.face == -1);
    cr_bvh_destroy(b);

    /* A zero-area triangle: the distance is to its longest edge as a segment. */
    CR_CHECK_OK(cr_bvh_build(pos, 4, tri + 3, 1, &b, &err), &err);
    CR_REQUIRE(b);
    const float q[3] = {1.5f, 0.3f, 0.4f};
    CR_CHECK(cr_bvh_closest(b, q, INFINITY, &h) == 1);
    CR_CHECK_NEAR(h.distance, 0.5, 1e-6);
    CR_CHECK_NEAR(h.point[0], 1.5, 1e-6);
    cr_bvh_destroy(b);
}

CR_TEST(bvh, refit_matches_rebuild) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 3, &m, &err), &err);
    CR_REQUIRE(m);
    cr_bvh *b = NULL, *fresh = NULL;
    CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err), &err);
    CR_REQUIRE(b);
    /* A smooth non-rigid motion: stretch, bend, shear and move. */
    for (int32_t v = 0; v < m->nv; v++) {
        float *p = &m->pos[3 * v];
        float x = p[0], y = p[1], z = p[2];
        p[0] = 1.3f * x + 0.2f * sinf(3 * y) + 0.5f;
        p[1] = 0.8f * y - 0.1f;
        p[2] = z + 0.3f * x * y;
    }
    CR_CHECK_OK(cr_bvh_refit(b, m->pos, &err), &err);
    CR_CHECK(bvh_is_valid(b));
    CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &fresh, &err), &err);
    CR_REQUIRE(fresh);

    const int64_t n = 2000;
    float *pts = random_points(m, n, 0.2f, 4);
    int64_t mismatches = 0;
    for (int64_t i = 0; i < n; i++) {
        const float *p = &pts[3 * i];
        float d1, d2, n1[3], n2[3], vd1, vd2;
        cr_bvh_signed_distance(b, p, INFINITY, &d1, n1, NULL);
        cr_bvh_signed_distance(fresh, p, INFINITY, &d2, n2, NULL);
        cr_bvh_nearest_vertex(b, p, INFINITY, &vd1);
        cr_bvh_nearest_vertex(fresh, p, INFINITY, &vd2);
        const float dir[3] = {-p[0], 0.3f, -p[2]};
        cr_bvh_ray_hit r1, r2;
        int h1 = cr_bvh_raycast(b, p, dir, INFINITY, &r1),
            h2 = cr_bvh_raycast(fresh, p, dir, INFINITY, &r2);
        if (d1 != d2 || vd1 != vd2 || h1 != h2 || r1.t != r2.t || fabsf(n1[0] - n2[0]) > 1e-6f ||
            fabsf(n1[1] - n2[1]) > 1e-6f || fabsf(n1[2] - n2[2]) > 1e-6f)
            mismatches++;
    }
    CR_CHECK(mismatches == 0);
    free(pts);
    cr_bvh_destroy(fresh);

    /* The queries above ran on the refit's stale vertex normals (each one
     * computed where a query met a vertex) and matched the fresh build; the
     * array, filled now, equals diffgeo's angle-weighted normals. */
    float *vn = malloc((size_t)m->nv * 3 * sizeof(float));
    cr_mesh_vertex_normals(m, CR_NORMAL_ANGLE, vn);
    double worst = 0;
    for (int32_t i = 0; i < 3 * m->nv; i++)
        worst = fmax(worst, fabs(vn[i] - cr_bvh_vertex_normals(b)[i]));
    CR_CHECK(worst < 1e-5);
    free(vn);

    /* Refit refuses non-finite positions and leaves the BVH as it was. */
    float keep = m->pos[7];
    m->pos[7] = NAN;
    CR_CHECK(cr_bvh_refit(b, m->pos, &err) == CR_ERR_NAN);
    CR_CHECK(cr_bvh_positions(b)[7] == keep);
    cr_bvh_destroy(b);
    cr_mesh_destroy(m);
}

/* Brute-force first hit over all faces, t in [0, t_max]. */
static double ref_ray(const cr_mesh *m, const float *o, const float *dir, double t_max,
                      int32_t *face) {
    double best = t_max;
    *face = -1;
    double dd[3] = {dir[0], dir[1], dir[2]};
    for (int32_t f = 0; f < m->nf; f++) {
        const float *a = &m->pos[3 * m->tri[3 * f]], *b = &m->pos[3 * m->tri[3 * f + 1]],
                    *c = &m->pos[3 * m->tri[3 * f + 2]];
        /* Solve o + t dir = a + u (b - a) + v (c - a) by Cramer's rule. */
        double e1[3], e2[3], s[3], n[3];
        sub3fd(b, a, e1);
        sub3fd(c, a, e2);
        sub3fd(o, a, s);
        cross3d(e1, e2, n);
        double det = -dot3d(dd, n);
        if (det == 0) continue;
        double t = dot3d(s, n) / det;
        double sxd[3];
        cross3d(s, dd, sxd);
        double u = dot3d(e2, sxd) / det, v = -dot3d(e1, sxd) / det;
        if (u >= 0 && v >= 0 && u + v <= 1 && t >= 0 && t <= best) best = t, *face = f;
    }
    return best;
}

CR_TEST(bvh, raycast_and_nearest_vertex_match_brute_force) {
    cr_mesh *meshes[2] = {crater_box(), NULL};
    cr_error err = {0};
    CR_CHECK_OK(cr_prim_torus(1.0f, 0.35f, 32, 16, &meshes[1], &err), &err);
    for (int k = 0; k < 2; k++) {
        cr_mesh *m = meshes[k];
        CR_REQUIRE(m);
        cr_bvh *b = NULL;
        CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err), &err);
        CR_REQUIRE(b);
        const int64_t n = 3000;
        float *pts = random_points(m, n, 0.2f, 10 + k);
        cr_rng r = cr_rng_make(20 + k, 0);
        int64_t bad_ray = 0, bad_vertex = 0, hits = 0;
        for (int64_t i = 0; i < n; i++) {
            const float *o = &pts[3 * i];
            float dir[3] = {(float)cr_rng_normal(&r), (float)cr_rng_normal(&r),
                            (float)cr_rng_normal(&r)};
            double t_max = (i % 3 == 0) ? 0.5 : INFINITY;
            int32_t rf;
            double rt = ref_ray(m, o, dir, t_max, &rf);
            cr_bvh_ray_hit h;
            int got = cr_bvh_raycast(b, o, dir, (float)t_max, &h);
            hits += got;
            if (got != (rf >= 0) || (got && fabs(h.t - rt) > 1e-5 * rt + 1e-7)) {
                if (bad_ray++ == 0)
                    fprintf(stderr, "ray %lld: got %d t %.9g face %d, ref face %d t %.9g\n",
                            (long long)i, got, h.t, h.face, rf, rt);
            }
            if (got) { /* the barycentric point is on the ray */
                const int32_t *t = &m->tri[3 * h.face];
                for (int d = 0; d < 3; d++) {
                    double x = h.bary[0] * m->pos[3 * t[0] + d] + h.bary[1] * m->pos[3 * t[1] + d] +
                               h.bary[2] * m->pos[3 * t[2] + d];
                    if (fabs(x - (o[d] + h.t * dir[d])) > 1e-5) bad_ray++;
                }
            }
            double best = INFINITY;
            for (int32_t v = 0; v < m->nv; v++) {
                double e[3];
                sub3fd(&m->pos[3 * v], o, e);
                best = fmin(best, dot3d(e, e));
            }
            float vd;
            int32_t v = cr_bvh_nearest_vertex(b, o, INFINITY, &vd);
            double e[3];
            sub3fd(&m->pos[3 * v], o, e);
            if (dot3d(e, e) != best || fabs(vd - sqrt(best)) > 1e-6 * sqrt(best)) bad_vertex++;
        }
        CR_CHECK(hits > n / 10);
        CR_CHECK(bad_ray == 0);
        CR_CHECK(bad_vertex == 0);
        free(pts);
        cr_bvh_destroy(b);
        cr_mesh_destroy(m);
    }
}

CR_TEST(bvh, batch_equals_single) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_torus(1.0f, 0.35f, 32, 16, &m, &err), &err);
    CR_REQUIRE(m);
    cr_bvh *b = NULL;
    CR_CHECK_OK(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b, &err), &err);
    CR_REQUIRE(b);
    const int64_t n = 5000;
    const float max_dist = 0.3f; /* some points find nothing */
    float *pts = random_points(m, n, 0.2f, 7), *dirs = random_points(m, n, 0.0f, 8);
    int32_t *face = malloc(n * sizeof(int32_t)), *vert = malloc(n * sizeof(int32_t)),
            *rface = malloc(n * sizeof(int32_t));
    float *point = malloc(3 * n * sizeof(float)), *bary = malloc(3 * n * sizeof(float)),
          *dist = malloc(n * sizeof(float)), *sd = malloc(n * sizeof(float)),
          *nrm = malloc(3 * n * sizeof(float)), *spoint = malloc(3 * n * sizeof(float)),
          *vd = malloc(n * sizeof(float)), *rt = malloc(n * sizeof(float)),
          *rbary = malloc(3 * n * sizeof(float));
    cr_bvh_closest_batch(b, pts, n, max_dist, face, point, bary, dist);
    cr_bvh_signed_distance_batch(b, pts, n, max_dist, sd, nrm, spoint);
    cr_bvh_nearest_vertex_batch(b, pts, n, max_dist, vert, vd);
    cr_bvh_raycast_batch(b, pts, dirs, n, 2.0f, rface, rt, rbary);
    int64_t bad = 0, misses = 0;
    for (int64_t i = 0; i < n; i++) {
        const float *p = &pts[3 * i];
        cr_bvh_hit h;
        int found = cr_bvh_closest(b, p, max_dist, &h);
        misses += !found;
        if (h.face != face[i] || h.distance != dist[i] || memcmp(h.point, &point[3 * i], 12) ||
            memcmp(h.bary, &bary[3 * i], 12))
            bad++;
        if (!found && (face[i] != -1 || dist[i] != max_dist || point[3 * i] != 0)) bad++;
        float d, nn[3];
        cr_bvh_signed_distance(b, p, max_dist, &d, nn, NULL);
        if (d != sd[i] || memcmp(nn, &nrm[3 * i], 12) || memcmp(h.point, &spoint[3 * i], 12)) bad++;
        float dv;
        if (cr_bvh_nearest_vertex(b, p, max_dist, &dv) != vert[i] || dv != vd[i]) bad++;
        cr_bvh_ray_hit rh;
        cr_bvh_raycast(b, p, &dirs[3 * i], 2.0f, &rh);
        if (rh.face != rface[i] || rh.t != rt[i] || memcmp(rh.bary, &rbary[3 * i], 12)) bad++;
    }
    CR_CHECK(bad == 0);
    CR_CHECK(misses > 0 && misses < n);
    free(pts), free(dirs), free(face), free(vert), free(rface), free(point), free(bary);
    free(dist), free(sd), free(nrm), free(spoint), free(vd), free(rt), free(rbary);
    cr_bvh_destroy(b);
    cr_mesh_destroy(m);
}

CR_TEST(bvh, rejects_bad_input) {
    cr_error err = {0};
    cr_bvh *b = (cr_bvh *)&err;
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const int32_t bad_tri[3] = {0, 1, 3}, tri[3] = {0, 1, 2};
    CR_CHECK(cr_bvh_build(pos, 3, bad_tri, 1, &b, &err) == CR_ERR_RANGE && b == NULL);
    CR_CHECK(strstr(err.msg, "vertex 3") != NULL);
    CR_CHECK(cr_bvh_build(pos, 3, tri, 0, &b, &err) == CR_ERR_TOPOLOGY);
    const float nan_pos[9] = {0, 0, 0, 1, NAN, 0, 0, 1, 0};
    CR_CHECK(cr_bvh_build(nan_pos, 3, tri, 1, &b, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "vertex 1") != NULL);
    cr_bvh_destroy(NULL);
    /* A NaN query finds nothing rather than looping or crashing. */
    CR_CHECK_OK(cr_bvh_build(pos, 3, tri, 1, &b, &err), &err);
    CR_REQUIRE(b);
    cr_bvh_hit h;
    const float q[3] = {NAN, 0, 0}, zero[3] = {0, 0, 0};
    CR_CHECK(cr_bvh_closest(b, q, INFINITY, &h) == 0 && h.face == -1);
    cr_bvh_ray_hit rh;
    CR_CHECK(cr_bvh_raycast(b, q, q, INFINITY, &rh) == 0);
    CR_CHECK(cr_bvh_raycast(b, q, zero, INFINITY, &rh) == 0);
    cr_bvh_destroy(b);
}

CR_TEST(bvh, mesh_diagonal_is_the_bounds_diagonal) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_box(1, 2, 2, 4, &m, &err), &err);
    CR_CHECK_NEAR(cr_mesh_diagonal(m), 3.0, 1e-6);
    cr_mesh_destroy(m);
    cr_mesh empty = {0};
    CR_CHECK(cr_mesh_diagonal(&empty) == 0.0);
}
