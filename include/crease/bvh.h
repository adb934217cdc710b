/* crease/bvh.h: bounding volume hierarchy over a triangle mesh, refittable
 * for animated meshes; closest point, signed distance, nearest vertex and ray
 * queries, single and batched.
 *
 *   cr_bvh *b = NULL;
 *   CR_TRY(cr_bvh_build(body->pos, body->nv, body->tri, body->nf, &b, err));
 *   float d[N], n[3 * N];
 *   cr_bvh_signed_distance_batch(b, cloth_pos, N, INFINITY, d, n, NULL);
 *   ... body moves ...
 *   CR_TRY(cr_bvh_refit(b, body_pos_next, err));   O(V + F), same topology
 *
 * Ownership: the BVH copies the triangle indices and keeps its own copy of the
 * positions, which refit overwrites; the caller's arrays may change or be
 * freed after build. It also keeps face normals, angle-weighted vertex
 * normals and face adjacency, recomputed (normals) on refit.
 *
 * Build: binned SAH (16 bins, all three axes) over triangle boxes, nodes in a
 * flat array, leaves of at most 4 triangles; a node deeper than 48 levels is
 * split at the object median, which bounds the depth. Refit keeps the tree and
 * recomputes every box bottom-up; quality degrades gracefully as the mesh
 * moves away from its build pose (rebuild after large deformations).
 *
 * Thread safety: queries only read the BVH and may run concurrently; build,
 * refit and destroy need exclusive access. Batched queries split the points
 * over threads with cr_parallel_for.
 *
 * Signed distance: negative inside. The sign comes from the angle-weighted
 * pseudo-normal of the feature holding the closest point (Baerentzen &
 * Aanaes, IEEE TVCG 11(3), 2005): the face normal in a face's interior, the
 * normalised sum of the two face normals on an edge, the angle-weighted vertex
 * normal at a vertex. It is exact for closed, consistently oriented
 * (counter-clockwise outward), manifold meshes; on open or non-manifold meshes
 * it is only the side of the nearest surface patch.
 *
 * Points farther than `max_dist` from the surface find nothing; pass INFINITY
 * for no limit. A finite limit prunes the search and makes far points cheap.
 */
#ifndef CREASE_BVH_H
#define CREASE_BVH_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cr_bvh cr_bvh;

/* Where on its face the closest point lies. */
typedef enum cr_bvh_feature {
    CR_BVH_FACE = 0, /* interior of the face */
    CR_BVH_EDGE,     /* on edge `local`: from corner local to corner (local + 1) % 3 */
    CR_BVH_VERTEX    /* at corner `local` */
} cr_bvh_feature;

typedef struct cr_bvh_hit {
    int32_t face;           /* closest face, -1 when none within max_dist */
    float point[3];         /* closest point on the surface, m */
    float bary[3];          /* its barycentric weights for tri[3*face + 0..2], sum 1 */
    float distance;         /* |p - point|, m */
    cr_bvh_feature feature; /* face interior, edge or vertex */
    int32_t local;          /* which edge or corner of the face (0..2); 0 for CR_BVH_FACE */
} cr_bvh_hit;

typedef struct cr_bvh_ray_hit {
    int32_t face;  /* first face hit, -1 when none within t_max */
    float t;       /* hit point = origin + t * dir (t in units of |dir|) */
    float bary[3]; /* barycentric weights of the hit point on the face */
} cr_bvh_ray_hit;

/* Build over F triangles `tri` (F,3) of positions `pos` (V,3), m. Fails with
 * CR_ERR_TOPOLOGY for nf < 1, CR_ERR_RANGE for an index outside [0, nv) and
 * CR_ERR_NAN for a non-finite position. Vertices no triangle uses are ignored
 * by every query. */
cr_status cr_bvh_build(const float *pos, int32_t nv, const int32_t *tri, int32_t nf, cr_bvh **out,
                       cr_error *err);

/* New positions (V,3) for the same triangles: copies them, recomputes normals
 * and every box, in parallel where it can. O(V + F), no allocation.
 * CR_ERR_NAN (BVH unchanged) for a non-finite position. */
cr_status cr_bvh_refit(cr_bvh *b, const float *pos, cr_error *err);

void cr_bvh_destroy(cr_bvh *b);

int32_t cr_bvh_vertex_count(const cr_bvh *b);
int32_t cr_bvh_face_count(const cr_bvh *b);
int32_t cr_bvh_node_count(const cr_bvh *b);
int32_t cr_bvh_depth(const cr_bvh *b);             /* levels below the root */
const float *cr_bvh_positions(const cr_bvh *b);    /* (V,3) the BVH's copy, m */
const int32_t *cr_bvh_triangles(const cr_bvh *b);  /* (F,3) */
const float *cr_bvh_face_normals(const cr_bvh *b); /* (F,3) unit; zero for degenerate faces */
/* (V,3) unit, angle-weighted. After a refit the first call recomputes them
 * (the queries do not need it): make that call before sharing the array with
 * other threads. */
const float *cr_bvh_vertex_normals(const cr_bvh *b);
/* The surface's smooth normal at a hit: the vertex normals vn (from
 * cr_bvh_vertex_normals(b), fetched before the threads share it) of the hit's
 * face interpolated by its barycentric weights, normalised; zero when
 * hit->face < 0. Unlike the pseudo-normal it turns continuously across the
 * faces' edges. */
void cr_bvh_smooth_normal(const cr_bvh *b, const float *vn, const cr_bvh_hit *hit, float out[3]);

/* Exact closest point on the mesh (Ericson, Real-Time Collision Detection,
 * 5.1.5, in double), visiting nodes nearest first and pruning by box
 * distance. Returns 1 and fills `hit` when a point lies within max_dist, else
 * 0 with hit->face = -1. */
int cr_bvh_closest(const cr_bvh *b, const float p[3], float max_dist, cr_bvh_hit *hit);

/* Signed distance (m, negative inside) and the unit outward pseudo-normal at
 * the closest point (`normal` may be NULL; `hit` may be NULL). Returns 0 when
 * nothing lies within max_dist: then *dist = max_dist (sign unknown, reported
 * as outside) and normal = 0. */
int cr_bvh_signed_distance(const cr_bvh *b, const float p[3], float max_dist, float *dist,
                           float normal[3], cr_bvh_hit *hit);

/* Mesh vertex closest to p (among vertices used by a triangle): its index, or
 * -1 when none within max_dist; of vertices at the same distance the lowest
 * index; *dist (may be NULL) gets its distance. Its
 * normal is cr_bvh_vertex_normals(b)[3 * v]. */
int32_t cr_bvh_nearest_vertex(const cr_bvh *b, const float p[3], float max_dist, float *dist);

/* First triangle hit by origin + t * dir for t in [0, t_max] (Moller &
 * Trumbore 1997, in double). Both sides of a triangle count. Returns 1 on a
 * hit; else 0 with hit->face = -1. dir need not be unit; a zero dir hits
 * nothing. */
int cr_bvh_raycast(const cr_bvh *b, const float origin[3], const float dir[3], float t_max,
                   cr_bvh_ray_hit *hit);

/* Faces whose bounding box overlaps the box [lo, hi] (m), in the tree's
 * leaf order (the same for the same tree and box): the first `cap` go to
 * faces; returns how many there are (more than cap: call again with more
 * room). For broad phases, e.g. cloth self-contact (a vertex's or an edge's
 * box inflated by a thickness). */
int64_t cr_bvh_faces_in_box(const cr_bvh *b, const float lo[3], const float hi[3], int32_t *faces,
                            int64_t cap);

/* Pairs of the BVH's triangles that share no vertex and cross each other
 * (an edge of one passes through the other, touching included; coplanar
 * overlaps are not counted), exactly in double from the BVH's positions: a
 * cloth's self-intersections. -1 when out of memory. */
int64_t cr_bvh_self_intersections(const cr_bvh *b);

/* Squared distance from p to the triangle (a, b, c) and the barycentric
 * weights of its closest point (bary may be NULL), in double (Ericson 5.1.5,
 * the BVH's own; degenerate triangles by their edges). */
double cr_closest_point_triangle(const double p[3], const double a[3], const double b[3],
                                 const double c[3], double bary[3]);

/* Batched versions over N points (N,3), in parallel; output arrays may be
 * NULL when not wanted. Entries with no result get face/vertex -1, distance
 * max_dist (or t_max), zero normal/point/bary. */
void cr_bvh_closest_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                          int32_t *face /* (N) */, float *point /* (N,3) */,
                          float *bary /* (N,3) */, float *dist /* (N) */);
void cr_bvh_signed_distance_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                                  float *dist /* (N) */, float *normal /* (N,3) */,
                                  float *point /* (N,3) */);
/* The same, and smooth (N,3): the surface's smooth normal at each closest
 * point (cr_bvh_smooth_normal; zero where none was found). */
void cr_bvh_signed_distance_smooth_batch(const cr_bvh *b, const float *pts, int64_t n,
                                         float max_dist, float *dist, float *normal, float *point,
                                         float *smooth /* (N,3) */);
void cr_bvh_nearest_vertex_batch(const cr_bvh *b, const float *pts, int64_t n, float max_dist,
                                 int32_t *vertex /* (N) */, float *dist /* (N) */);
void cr_bvh_raycast_batch(const cr_bvh *b, const float *origins /* (N,3) */,
                          const float *dirs /* (N,3) */, int64_t n, float t_max,
                          int32_t *face /* (N) */, float *t /* (N) */, float *bary /* (N,3) */);

#ifdef __cplusplus
}
#endif
#endif
