/* crease/uvlookup.h: from a point in UV space to the triangle under it.
 *
 * Garment methods sample the UV square (a texture of offsets, a mask of the
 * pattern) and need the face and barycentrics under each texel, to map it to
 * the rest shape or to any per-vertex field. A uniform grid over the UV
 * bounding box lists, per cell, the UV triangles whose bounding boxes overlap
 * it: building is O(F + cells), a lookup O(1) on average.
 *
 *     cr_uv_lookup *lk;
 *     cr_uv_lookup_build(garment, 0, &lk, &err);
 *     int32_t f; double b[3];
 *     if (cr_uv_lookup_find(lk, u, v, &f, b))
 *         cr_uv_lookup_interpolate(lk, garment->pos, 3, f, b, xyz);
 *     cr_uv_lookup_destroy(lk);
 *
 * Barycentrics are double and sum to one. A point counts as inside a triangle
 * when every barycentric is >= -CR_UV_LOOKUP_EPS, so points on shared edges
 * and corners are found (by whichever triangle holds them most deeply; in
 * overlapping charts by one of the triangles that hold them).
 * Triangles of zero UV area are never returned. The lookup copies what it
 * needs from the mesh (UVs and both index triples), so the mesh may change or
 * go away afterwards; it is read-only once built and safe to share between
 * threads.
 */
#ifndef CREASE_UVLOOKUP_H
#define CREASE_UVLOOKUP_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Barycentric tolerance for points on triangle edges (scale-free). */
#define CR_UV_LOOKUP_EPS 1e-6

typedef struct cr_uv_lookup cr_uv_lookup;

/* Build the grid for `m`'s UV triangles. grid_res > 0 sets the cells along
 * each axis; 0 picks about one cell per face with near-square cells. Fails
 * with CR_ERR_INVALID when the mesh has no UVs or grid_res is negative or above
 * 16384, CR_ERR_RANGE for a UV index out of range, CR_ERR_NAN for a non-finite
 * UV. The caller destroys *out. */
cr_status cr_uv_lookup_build(const cr_mesh *m, int32_t grid_res, cr_uv_lookup **out, cr_error *err);
void cr_uv_lookup_destroy(cr_uv_lookup *lk);

/* 1 and the face and barycentrics (w.r.t. the face's corners 0, 1, 2) when
 * (u, v) lies in a UV triangle, else 0 (face = -1, bary untouched). */
int cr_uv_lookup_find(const cr_uv_lookup *lk, float u, float v, int32_t *face, double bary[3]);

/* The UV triangle closest to (u, v) and the barycentrics of the closest point
 * on it (all >= 0); *dist (may be NULL) gets the UV distance, 0 when inside.
 * For samples just outside every chart (a mask's antialiased rim). Returns 0
 * only when the mesh has no UV triangle of non-zero area. */
int cr_uv_lookup_nearest(const cr_uv_lookup *lk, float u, float v, int32_t *face, double bary[3],
                         double *dist);

/* out (dim) = sum_k bary[k] * attr[tri[face][k]] for a per-vertex field attr
 * (V,dim) of the mesh the lookup was built from, accumulated in double. */
void cr_uv_lookup_interpolate(const cr_uv_lookup *lk, const float *attr, int32_t dim, int32_t face,
                              const double bary[3], float *out);

/* Rest position under (u, v): out = interpolated pos (V,3), m. Returns 1 when
 * (u, v) lies in a UV triangle, else 0 and out is untouched. */
int cr_uv_lookup_rest_position(const cr_uv_lookup *lk, const float *pos, float u, float v,
                               float out[3]);

/* The UV bounding box (lo, hi) and the grid size, for callers that rasterise it. */
void cr_uv_lookup_bounds(const cr_uv_lookup *lk, float lo[2], float hi[2]);
void cr_uv_lookup_grid_size(const cr_uv_lookup *lk, int32_t *nu, int32_t *nv);

#ifdef __cplusplus
}
#endif
#endif
