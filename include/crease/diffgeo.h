/* crease/diffgeo.h: differential quantities on triangle meshes.
 *
 * Face normals and areas, vertex normals (area- or angle-weighted), signed
 * dihedral angles (robust near 0 and pi), the cotangent Laplacian, mean
 * curvature magnitude, and per-triangle quality (minimum angle).
 *
 * Conventions: positions (V,3) in m; triangles (F,3) counter-clockwise seen
 * from the side the normal points to.
 */
#ifndef CREASE_DIFFGEO_H
#define CREASE_DIFFGEO_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Unit normal of triangle (a, b, c); zero vector for a degenerate triangle.
 * Returns twice the area. */
float cr_triangle_normal(const float a[3], const float b[3], const float c[3], float n[3]);

/* Per-face unit normals (F,3) and areas (F) in m^2; either output may be NULL. */
void cr_mesh_face_normals(const cr_mesh *m, float *normals, float *areas);

typedef enum cr_normal_weight {
    CR_NORMAL_AREA,  /* weight each face by its area */
    CR_NORMAL_ANGLE  /* weight by the corner angle: the pseudo-normal of Baerentzen & Aanaes 2005 */
} cr_normal_weight;

/* Per-vertex unit normals (V,3). Isolated vertices get (0,0,0). */
void cr_mesh_vertex_normals(const cr_mesh *m, cr_normal_weight weight, float *normals);

/* Allocate m->normal if absent and fill it with area-weighted normals. */
cr_status cr_mesh_compute_normals(cr_mesh *m, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
