/* bvh_query.c: closest point, signed distance, nearest vertex and ray queries
 * on the BVH of bvh.c, single and batched.
 *
 * Distance queries walk the tree depth first with an explicit stack, visiting
 * the nearer child first and skipping any node whose box lies farther than
 * the best distance found so far. Exact per-triangle work is in double:
 * closest point by Voronoi regions (Ericson, Real-Time Collision Detection,
 * 2005, sec. 5.1.5), ray-triangle by Moller & Trumbore (JGT 1997). The sign of
 * the distance uses angle-weighted pseudo-normals (Baerentzen & Aanaes, IEEE
 * TVCG 2005) of the feature (face, edge, vertex) holding the closest point.
 *
 * Left out: packet/SIMD traversal, any-hit (shadow) rays, winding numbers.
 */
#include "base/vec3.h"
#include "bvh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct stack_item {
    int32_t node;
    float key; /* squared box distance, or ray entry t */
} stack_item;

/* Squared distance from p to the box (0 inside), written out per axis since
 * gcc -O2 leaves a 3-trip loop rolled and this is the traversal's inner step. */
static float box_dist2(const bvh_node *n, const float p[3]) {
    float ex = bvh_maxf(bvh_maxf(n->lo[0] - p[0], p[0] - n->hi[0]), 0.0f);
    float ey = bvh_maxf(bvh_maxf(n->lo[1] - p[1], p[1] - n->hi[1]), 0.0f);
    float ez = bvh_maxf(bvh_maxf(n->lo[2] - p[2], p[2] - n->hi[2]), 0.0f);
    return ex * ex + ey * ey + ez * ez;
}

/* -------------------------------------------------- point-triangle -- */

typedef struct tri_closest {
    double point[3];
    double bary[3];
    double d2;
    cr_bvh_feature feature;
    int local;
} tri_closest;

static void set_closest(tri_closest *r, const double *a, const double *ab, const double *ac,
                        double w1, double w2, const double p[3], cr_bvh_feature feature,
                        int local) {
    r->bary[0] = 1.0 - w1 - w2, r->bary[1] = w1, r->bary[2] = w2;
    double d2 = 0;
    for (int d = 0; d < 3; d++) {
        r->point[d] = a[d] + w1 * ab[d] + w2 * ac[d];
        double e = p[d] - r->point[d];
        d2 += e * e;
    }
    r->d2 = d2;
    r->feature = feature;
    r->local = local;
}

/* Closest point of a degenerate (zero-area) triangle: the best of its three
 * edges as segments. */
static void closest_degenerate(const double *a, const double *ab, const double *ac,
                               const double p[3], tri_closest *r) {
    r->d2 = INFINITY;
    for (int k = 0; k < 3; k++) {
        /* Edge k from corner k to corner k+1 in (w1, w2) coordinates. */
        static const double from[3][2] = {{0, 0}, {1, 0}, {0, 1}},
                            to[3][2] = {{1, 0}, {0, 1}, {0, 0}};
        double s[3], q[3], e[3];
        for (int d = 0; d < 3; d++) {
            s[d] = a[d] + from[k][0] * ab[d] + from[k][1] * ac[d];
            e[d] = a[d] + to[k][0] * ab[d] + to[k][1] * ac[d] - s[d];
            q[d] = p[d] - s[d];
        }
        double ee = dot3d(e, e), t = ee > 0 ? dot3d(q, e) / ee : 0.0;
        t = t < 0 ? 0 : (t > 1 ? 1 : t);
        tri_closest c;
        double w1 = from[k][0] + t * (to[k][0] - from[k][0]);
        double w2 = from[k][1] + t * (to[k][1] - from[k][1]);
        if (t == 0)
            set_closest(&c, a, ab, ac, w1, w2, p, CR_BVH_VERTEX, k);
        else if (t == 1)
            set_closest(&c, a, ab, ac, w1, w2, p, CR_BVH_VERTEX, (k + 1) % 3);
        else
            set_closest(&c, a, ab, ac, w1, w2, p, CR_BVH_EDGE, k);
        if (k == 0 || c.d2 < r->d2) *r = c; /* k == 0 first: a NaN stays NaN */
    }
}

/* Ericson 5.1.5: classify p against the Voronoi regions of the vertices,
 * edges and face of triangle (a, b, c). Edges: 0 = ab, 1 = bc, 2 = ca. */
static void closest_on_triangle_d(const double *fa, const double *fb, const double *fc,
                                  const double p[3], tri_closest *r) {
    double a[3], ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int d = 0; d < 3; d++) {
        a[d] = fa[d];
        ab[d] = fb[d] - fa[d];
        ac[d] = fc[d] - fa[d];
        ap[d] = p[d] - fa[d];
        bp[d] = p[d] - fb[d];
        cp[d] = p[d] - fc[d];
    }
    double d1 = dot3d(ab, ap), d2 = dot3d(ac, ap);
    double d3 = dot3d(ab, bp), d4 = dot3d(ac, bp);
    double d5 = dot3d(ab, cp), d6 = dot3d(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0) {
        set_closest(r, a, ab, ac, 0, 0, p, CR_BVH_VERTEX, 0);
    } else if (d3 >= 0 && d4 <= d3) {
        set_closest(r, a, ab, ac, 1, 0, p, CR_BVH_VERTEX, 1);
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        set_closest(r, a, ab, ac, d1 / (d1 - d3), 0, p, CR_BVH_EDGE, 0);
    } else if (d6 >= 0 && d5 <= d6) {
        set_closest(r, a, ab, ac, 0, 1, p, CR_BVH_VERTEX, 2);
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        set_closest(r, a, ab, ac, 0, d2 / (d2 - d6), p, CR_BVH_EDGE, 2);
    } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        set_closest(r, a, ab, ac, 1 - w, w, p, CR_BVH_EDGE, 1);
    } else if (va + vb + vc > 0) {
        set_closest(r, a, ab, ac, vb / (va + vb + vc), vc / (va + vb + vc), p, CR_BVH_FACE, 0);
    } else {
        closest_degenerate(a, ab, ac, p, r);
    }
}

/* The same for float corners (the BVH's leaves), converted exactly. */
static void closest_on_triangle(const float *fa, const float *fb, const float *fc,
                                const double p[3], tri_closest *r) {
    const double a[3] = {fa[0], fa[1], fa[2]}, b[3] = {fb[0], fb[1], fb[2]},
                 c[3] = {fc[0], fc[1], fc[2]};
    closest_on_triangle_d(a, b, c, p, r);
}

double cr_closest_point_triangle(const double p[3], const double a[3], const double b[3],
                                 const double c[3], double bary[3]) {
    tri_closest r;
    closest_on_triangle_d(a, b, c, p, &r);
    if (bary) bary[0] = r.bary[0], bary[1] = r.bary[1], bary[2] = r.bary[2];
    return r.d2;
}

/* ----------------------------------------------------- closest point -- */

/* Closest point within sqrt(best->d2) (initialised by the caller); returns the face or -1. */
static int32_t closest_search(const cr_bvh *b, const float p[3], tri_closest *best) {
    double pd[3] = {p[0], p[1], p[2]};
    int32_t best_face = -1;
    stack_item stack[BVH_STACK];
    int top = 0;
    stack[top++] = (stack_item){0, box_dist2(&b->nodes[0], p)};
    while (top > 0) {
        stack_item it = stack[--top];
        if (!(it.key <= best->d2)) continue;
        const bvh_node *n = &b->nodes[it.node];
        if (n->count > 0) {
            for (int32_t k = 0; k < n->count; k++) {
                const float *v = &b->leaf_pos[9 * (size_t)(n->start + k)];
                tri_closest c;
                closest_on_triangle(v, v + 3, v + 6, pd, &c);
                if (c.d2 < best->d2 || (best_face < 0 && c.d2 == best->d2)) {
                    *best = c;
                    best_face = b->order[n->start + k];
                }
            }
            continue;
        }
        int32_t l = n->start, r = n->start + 1;
        float dl = box_dist2(&b->nodes[l], p), dr = box_dist2(&b->nodes[r], p);
        /* Push the far child first so the near one is searched first. */
        if (dl <= dr) {
            stack[top++] = (stack_item){r, dr};
            stack[top++] = (stack_item){l, dl};
        } else {
            stack[top++] = (stack_item){l, dl};
            stack[top++] = (stack_item){r, dr};
        }
    }
    return best_face;
}

static double max_dist2(float max_dist) {
    return isinf(max_dist) ? INFINITY : (double)max_dist * max_dist;
}

int cr_bvh_closest(const cr_bvh *b, const float p[3], float max_dist, cr_bvh_hit *hit) {
    tri_closest best = {.d2 = max_dist2(max_dist)};
    int32_t f = closest_search(b, p, &best);
    memset(hit, 0, sizeof *hit);
    hit->face = f;
    if (f < 0) {
        hit->distance = max_dist;
        return 0;
    }
    for (int d = 0; d < 3; d++) {
        hit->point[d] = (float)best.point[d];
        hit->bary[d] = (float)best.bary[d];
    }
    hit->distance = (float)sqrt(best.d2);
    hit->feature = best.feature;
    hit->local = best.local;
    return 1;
}

/* --------------------------------------------------- signed distance -- */

/* Pseudo-normal of the feature holding the closest point (unnormalised for edges). */
static void pseudo_normal(const cr_bvh *b, int32_t f, const tri_closest *c, double n[3]) {
    const float *src = &b->fnormal[3 * (size_t)f];
    float vn[3];
    if (c->feature == CR_BVH_VERTEX) {
        const int32_t v = b->tri[3 * (size_t)f + c->local];
        if (b->vnormal_stale) {
            cr_bvh_vertex_normal_of(b, v, vn);
            src = vn;
        } else {
            src = &b->vnormal[3 * (size_t)v];
        }
    }
    for (int d = 0; d < 3; d++)
        n[d] = src[d];
    if (c->feature == CR_BVH_EDGE) {
        int32_t g = b->adj[3 * (size_t)f + c->local];
        if (g >= 0)
            for (int d = 0; d < 3; d++)
                n[d] += b->fnormal[3 * (size_t)g + d];
    }
    double len = sqrt(dot3d(n, n));
    if (len > 0)
        for (int d = 0; d < 3; d++)
            n[d] /= len;
}

int cr_bvh_signed_distance(const cr_bvh *b, const float p[3], float max_dist, float *dist,
                           float normal[3], cr_bvh_hit *hit) {
    tri_closest best = {.d2 = max_dist2(max_dist)};
    int32_t f = closest_search(b, p, &best);
    if (hit) {
        memset(hit, 0, sizeof *hit);
        hit->face = f;
        hit->distance = max_dist;
    }
    if (f < 0) {
        *dist = max_dist;
        if (normal) normal[0] = normal[1] = normal[2] = 0.0f;
        return 0;
    }
    double n[3], away = 0;
    pseudo_normal(b, f, &best, n);
    for (int d = 0; d < 3; d++)
        away += ((double)p[d] - best.point[d]) * n[d];
    double dd = sqrt(best.d2);
    *dist = (float)(away < 0 ? -dd : dd);
    if (normal)
        for (int d = 0; d < 3; d++)
            normal[d] = (float)n[d];
    if (hit) {
        for (int d = 0; d < 3; d++) {
            hit->point[d] = (float)best.point[d];
            hit->bary[d] = (float)best.bary[d];
        }
        hit->distance = (float)dd;
        hit->feature = best.feature;
        hit->local = best.local;
    }
    return 1;
}

/* ---------------------------------------------------- nearest vertex -- */

/* Every used vertex lies in the boxes of its faces, so the face tree serves:
 * a leaf tests its faces' corners. */
int32_t cr_bvh_nearest_vertex(const cr_bvh *b, const float p[3], float max_dist, float *dist) {
    double best = max_dist2(max_dist);
    int32_t best_v = -1;
    stack_item stack[BVH_STACK];
    int top = 0;
    stack[top++] = (stack_item){0, box_dist2(&b->nodes[0], p)};
    while (top > 0) {
        stack_item it = stack[--top];
        if (!(it.key <= best)) continue;
        const bvh_node *n = &b->nodes[it.node];
        if (n->count > 0) {
            for (int32_t k = 0; k < n->count; k++) {
                const int32_t *t = &b->tri[3 * (size_t)b->order[n->start + k]];
                /* a one-vertex face (v, v, v), as in a tree of vertices alone
                 * (drape_collision.c): one corner is all three */
                const int corners = t[1] == t[0] && t[2] == t[0] ? 1 : 3;
                for (int c = 0; c < corners; c++) {
                    const float *q = &b->pos[3 * (size_t)t[c]];
                    double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1],
                           dz = (double)p[2] - q[2];
                    double d2 = dx * dx + dy * dy + dz * dz;
                    /* ties to the lowest index, whatever the order of the visit
                     * (vertex_grid.c answers the same) */
                    if (d2 < best || (d2 == best && (best_v < 0 || t[c] < best_v)))
                        best = d2, best_v = t[c];
                }
            }
            continue;
        }
        int32_t l = n->start, r = n->start + 1;
        float dl = box_dist2(&b->nodes[l], p), dr = box_dist2(&b->nodes[r], p);
        if (dl <= dr) {
            stack[top++] = (stack_item){r, dr};
            stack[top++] = (stack_item){l, dl};
        } else {
            stack[top++] = (stack_item){l, dl};
            stack[top++] = (stack_item){r, dr};
        }
    }
    if (dist) *dist = best_v < 0 ? max_dist : (float)sqrt(best);
    return best_v;
}

/* ---------------------------------------------------------- raycast -- */

/* Entry t of the ray into the box, or INFINITY when it misses within
 * [0, t_far]. An axis the ray runs parallel to (inv = +-inf) only asks whether
 * the origin lies within that slab, avoiding 0 * inf. The far bound is padded
 * by a few ulps so rounding cannot miss a face lying on a box wall (Pharr,
 * Jakob & Humphreys, PBRT 3rd ed., sec. 3.9.2). */
static float ray_box(const bvh_node *n, const float o[3], const float inv[3], float t_far) {
    float tn = 0.0f, tf = t_far;
    for (int d = 0; d < 3; d++) {
        if (isinf(inv[d])) {
            if (o[d] < n->lo[d] || o[d] > n->hi[d]) return INFINITY;
            continue;
        }
        float t1 = (n->lo[d] - o[d]) * inv[d], t2 = (n->hi[d] - o[d]) * inv[d];
        tn = bvh_maxf(tn, bvh_minf(t1, t2));
        tf = bvh_minf(tf, bvh_maxf(t1, t2) * (1.0f + 4e-7f));
    }
    return tn <= tf ? tn : INFINITY;
}

/* Moller-Trumbore: t of the hit in [0, t_best], or -1. */
static double ray_triangle(const float *fa, const float *fb, const float *fc, const double o[3],
                           const double dir[3], double t_best, double *u_out, double *v_out) {
    double e1[3], e2[3], tv[3], pv[3], qv[3];
    for (int d = 0; d < 3; d++) {
        e1[d] = (double)fb[d] - fa[d];
        e2[d] = (double)fc[d] - fa[d];
        tv[d] = o[d] - fa[d];
    }
    pv[0] = dir[1] * e2[2] - dir[2] * e2[1];
    pv[1] = dir[2] * e2[0] - dir[0] * e2[2];
    pv[2] = dir[0] * e2[1] - dir[1] * e2[0];
    double det = dot3d(e1, pv);
    if (det == 0.0) return -1;
    double inv = 1.0 / det;
    double u = dot3d(tv, pv) * inv;
    if (u < 0 || u > 1) return -1;
    qv[0] = tv[1] * e1[2] - tv[2] * e1[1];
    qv[1] = tv[2] * e1[0] - tv[0] * e1[2];
    qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
    double v = dot3d(dir, qv) * inv;
    if (v < 0 || u + v > 1) return -1;
    double t = dot3d(e2, qv) * inv;
    if (t < 0 || t > t_best) return -1;
    *u_out = u, *v_out = v;
    return t;
}

int cr_bvh_raycast(const cr_bvh *b, const float origin[3], const float dir[3], float t_max,
                   cr_bvh_ray_hit *hit) {
    memset(hit, 0, sizeof *hit);
    hit->face = -1;
    hit->t = t_max;
    if (dir[0] == 0 && dir[1] == 0 && dir[2] == 0) return 0;
    float inv[3] = {1.0f / dir[0], 1.0f / dir[1], 1.0f / dir[2]};
    double o[3] = {origin[0], origin[1], origin[2]}, dd[3] = {dir[0], dir[1], dir[2]};
    double best_t = t_max, bu = 0, bv = 0;
    stack_item stack[BVH_STACK];
    int top = 0;
    float t0 = ray_box(&b->nodes[0], origin, inv, t_max);
    if (t0 != INFINITY) stack[top++] = (stack_item){0, t0};
    while (top > 0) {
        stack_item it = stack[--top];
        if (!(it.key <= best_t)) continue;
        const bvh_node *n = &b->nodes[it.node];
        if (n->count > 0) {
            for (int32_t k = 0; k < n->count; k++) {
                const float *q = &b->leaf_pos[9 * (size_t)(n->start + k)];
                double u, v;
                double th = ray_triangle(q, q + 3, q + 6, o, dd, best_t, &u, &v);
                if (th >= 0) best_t = th, bu = u, bv = v, hit->face = b->order[n->start + k];
            }
            continue;
        }
        float tf = (float)best_t;
        int32_t l = n->start, r = n->start + 1;
        float tl = ray_box(&b->nodes[l], origin, inv, tf),
              tr = ray_box(&b->nodes[r], origin, inv, tf);
        if (tl <= tr) {
            if (tr != INFINITY) stack[top++] = (stack_item){r, tr};
            if (tl != INFINITY) stack[top++] = (stack_item){l, tl};
        } else {
            if (tl != INFINITY) stack[top++] = (stack_item){l, tl};
            if (tr != INFINITY) stack[top++] = (stack_item){r, tr};
        }
    }
    if (hit->face < 0) return 0;
    hit->t = (float)best_t;
    hit->bary[0] = (float)(1 - bu - bv), hit->bary[1] = (float)bu, hit->bary[2] = (float)bv;
    return 1;
}

/* ----------------------------------------------------------- batches -- */

typedef struct batch_ctx {
    const cr_bvh *b;
    const float *pts, *dirs;
    float limit; /* max_dist or t_max */
    int32_t *index;
    float *point, *bary, *dist, *normal;
    const float *vn; /* the vertex normals, for smooth */
    float *smooth;
} batch_ctx;

enum { BATCH_GRAIN = 64 };

static void put3(float *dst, int64_t i, const float *src) {
    if (dst) memcpy(&dst[3 * i], src, 3 * sizeof(float));
}

static void closest_range(void *ctx, int64_t begin, int64_t end) {
    const batch_ctx *c = ctx;
    for (int64_t i = begin; i < end; i++) {
        cr_bvh_hit h;
        cr_bvh_closest(c->b, &c->pts[3 * i], c->limit, &h);
        if (c->index) c->index[i] = h.face;
        put3(c->point, i, h.point);
        put3(c->bary, i, h.bary);
        if (c->dist) c->dist[i] = h.distance;
    }
}

void cr_bvh_closest_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                          int32_t *face, float *point, float *bary, float *dist) {
    batch_ctx c = {.b = b,
                   .pts = pts,
                   .limit = max_dist,
                   .index = face,
                   .point = point,
                   .bary = bary,
                   .dist = dist};
    cr_parallel_for(n, BATCH_GRAIN, closest_range, &c);
}

static void signed_range(void *ctx, int64_t begin, int64_t end) {
    const batch_ctx *c = ctx;
    const int hits = c->point || c->smooth;
    for (int64_t i = begin; i < end; i++) {
        cr_bvh_hit h;
        float d, nrm[3];
        if (!cr_bvh_signed_distance(c->b, &c->pts[3 * i], c->limit, &d, nrm, hits ? &h : NULL))
            h.face = -1;
        if (c->dist) c->dist[i] = d;
        put3(c->normal, i, nrm);
        if (c->point) put3(c->point, i, h.point);
        if (c->smooth) cr_bvh_smooth_normal(c->b, c->vn, &h, &c->smooth[3 * i]);
    }
}

void cr_bvh_signed_distance_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                                  float *dist, float *normal, float *point) {
    cr_bvh_signed_distance_smooth_batch(b, pts, n, max_dist, dist, normal, point, NULL);
}

void cr_bvh_signed_distance_smooth_batch(const cr_bvh *b, const float *pts, int64_t n,
                                         float max_dist, float *dist, float *normal, float *point,
                                         float *smooth) {
    batch_ctx c = {.b = b,
                   .pts = pts,
                   .limit = max_dist,
                   .dist = dist,
                   .normal = normal,
                   .point = point,
                   .vn = smooth ? cr_bvh_vertex_normals(b) : NULL,
                   .smooth = smooth};
    cr_parallel_for(n, BATCH_GRAIN, signed_range, &c);
}

static void vertex_range(void *ctx, int64_t begin, int64_t end) {
    const batch_ctx *c = ctx;
    for (int64_t i = begin; i < end; i++) {
        float d;
        int32_t v = cr_bvh_nearest_vertex(c->b, &c->pts[3 * i], c->limit, &d);
        if (c->index) c->index[i] = v;
        if (c->dist) c->dist[i] = d;
    }
}

void cr_bvh_nearest_vertex_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                                 int32_t *vertex, float *dist) {
    batch_ctx c = {.b = b, .pts = pts, .limit = max_dist, .index = vertex, .dist = dist};
    cr_parallel_for(n, BATCH_GRAIN, vertex_range, &c);
}

static void ray_range(void *ctx, int64_t begin, int64_t end) {
    const batch_ctx *c = ctx;
    for (int64_t i = begin; i < end; i++) {
        cr_bvh_ray_hit h;
        cr_bvh_raycast(c->b, &c->pts[3 * i], &c->dirs[3 * i], c->limit, &h);
        if (c->index) c->index[i] = h.face;
        if (c->dist) c->dist[i] = h.t;
        put3(c->bary, i, h.bary);
    }
}

void cr_bvh_raycast_batch(const cr_bvh *b, const float *origins, const float *dirs, int64_t n,
                          float t_max, int32_t *face, float *t, float *bary) {
    batch_ctx c = {.b = b,
                   .pts = origins,
                   .dirs = dirs,
                   .limit = t_max,
                   .index = face,
                   .dist = t,
                   .bary = bary};
    cr_parallel_for(n, BATCH_GRAIN, ray_range, &c);
}

/* ------------------------------------------------------- box overlap -- */

int64_t cr_bvh_faces_in_box(const cr_bvh *b, const float lo[3], const float hi[3], int32_t *faces,
                            int64_t cap) {
    int64_t n = 0;
    int32_t stack[BVH_STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const bvh_node *nd = &b->nodes[stack[--top]];
        if (nd->lo[0] > hi[0] || nd->hi[0] < lo[0] || nd->lo[1] > hi[1] || nd->hi[1] < lo[1] ||
            nd->lo[2] > hi[2] || nd->hi[2] < lo[2])
            continue;
        if (nd->count == 0) {
            stack[top++] = nd->start + 1;
            stack[top++] = nd->start;
            continue;
        }
        for (int32_t k = 0; k < nd->count; k++) {
            const float *v = &b->leaf_pos[9 * (size_t)(nd->start + k)];
            float flo[3], fhi[3];
            for (int d = 0; d < 3; d++) {
                flo[d] = bvh_minf(bvh_minf(v[d], v[3 + d]), v[6 + d]);
                fhi[d] = bvh_maxf(bvh_maxf(v[d], v[3 + d]), v[6 + d]);
            }
            if (flo[0] > hi[0] || fhi[0] < lo[0] || flo[1] > hi[1] || fhi[1] < lo[1] ||
                flo[2] > hi[2] || fhi[2] < lo[2])
                continue;
            if (n < cap) faces[n] = b->order[nd->start + k];
            n++;
        }
    }
    return n;
}

/* ---------------------------------------------- self-intersections -- */

/* Six times the signed volume of (a, b, c, d). */
static double orient3(const double *a, const double *b, const double *c, const double *d) {
    double u[3], v[3], w[3];
    for (int k = 0; k < 3; k++)
        u[k] = b[k] - a[k], v[k] = c[k] - a[k], w[k] = d[k] - a[k];
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
           u[2] * (v[0] * w[1] - v[1] * w[0]);
}

/* Segment pq crosses triangle abc (touching counts; coplanar does not). */
static int segment_crosses(const double *p, const double *q, const double *a, const double *b,
                           const double *c) {
    double dp = orient3(a, b, c, p), dq = orient3(a, b, c, q);
    if ((dp > 0 && dq > 0) || (dp < 0 && dq < 0) || (dp == 0 && dq == 0)) return 0;
    double s1 = orient3(p, q, a, b), s2 = orient3(p, q, b, c), s3 = orient3(p, q, c, a);
    return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

/* Two non-coplanar triangles meet iff an edge of one crosses the other. */
static int triangles_cross(const double *t, const double *u) {
    for (int k = 0; k < 3; k++) {
        const double *p = t + 3 * k, *q = t + 3 * ((k + 1) % 3);
        if (segment_crosses(p, q, u, u + 3, u + 6)) return 1;
        p = u + 3 * k, q = u + 3 * ((k + 1) % 3);
        if (segment_crosses(p, q, t, t + 3, t + 6)) return 1;
    }
    return 0;
}

typedef struct isect_ctx {
    const cr_bvh *b;
    int64_t *count; /* (F) pairs (f, g > f) per face */
} isect_ctx;

static void isect_range(void *vctx, int64_t begin, int64_t end) {
    const isect_ctx *c = vctx;
    const cr_bvh *b = c->b;
    int32_t local[256], *faces = local;
    int64_t cap = 256;
    for (int64_t f = begin; f < end; f++) {
        const int32_t *tf = b->tri + 3 * f;
        double t[9];
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++) {
                float x = b->pos[3 * (int64_t)tf[k] + d];
                t[3 * k + d] = x;
                lo[d] = bvh_minf(lo[d], x), hi[d] = bvh_maxf(hi[d], x);
            }
        int64_t n = cr_bvh_faces_in_box(b, lo, hi, faces, cap);
        if (n > cap) {
            int32_t *nb = malloc((size_t)n * sizeof(int32_t));
            if (!nb) {
                c->count[f] = -1;
                continue;
            }
            if (faces != local) free(faces);
            faces = nb, cap = n;
            n = cr_bvh_faces_in_box(b, lo, hi, faces, cap);
        }
        int64_t hits = 0;
        for (int64_t q = 0; q < n; q++) {
            int32_t g = faces[q];
            if (g <= f) continue;
            const int32_t *tg = b->tri + 3 * (int64_t)g;
            int shared = 0;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    shared |= tf[i] == tg[j];
            if (shared) continue;
            double u[9];
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++)
                    u[3 * k + d] = b->pos[3 * (int64_t)tg[k] + d];
            hits += triangles_cross(t, u);
        }
        c->count[f] = hits;
    }
    if (faces != local) free(faces);
}

int64_t cr_bvh_self_intersections(const cr_bvh *b) {
    int64_t *count = calloc((size_t)b->nf + 1, sizeof(int64_t));
    if (!count) return -1;
    isect_ctx c = {b, count};
    cr_parallel_for(b->nf, 1024, isect_range, &c);
    int64_t total = 0;
    for (int32_t f = 0; f < b->nf; f++) {
        if (count[f] < 0) {
            total = -1;
            break;
        }
        total += count[f];
    }
    free(count);
    return total;
}
