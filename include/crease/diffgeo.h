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
#include "crease/topology.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Unit normal of triangle (a, b, c); zero vector for a degenerate triangle.
 * Returns twice the area. */
float cr_triangle_normal(const float a[3], const float b[3], const float c[3], float n[3]);

/* Interior angle at corner a of triangle (a, b, c), radians, computed in double. */
double cr_triangle_corner_angle(const float a[3], const float b[3], const float c[3]);

/* Per-face unit normals (F,3) and areas (F) in m^2; either output may be NULL. */
void cr_mesh_face_normals(const cr_mesh *m, float *normals, float *areas);

typedef enum cr_normal_weight {
    CR_NORMAL_AREA, /* weight each face by its area */
    CR_NORMAL_ANGLE /* weight by the corner angle: the pseudo-normal of Baerentzen & Aanaes 2005 */
} cr_normal_weight;

/* Per-vertex unit normals (V,3). Isolated vertices get (0,0,0). */
void cr_mesh_vertex_normals(const cr_mesh *m, cr_normal_weight weight, float *normals);

/* Allocate m->normal if absent and fill it with area-weighted normals. */
cr_status cr_mesh_compute_normals(cr_mesh *m, cr_error *err);

/* ------------------------------------------------------ dihedral angles -- */

/* Signed dihedral angle of the hinge on edge x0-x1 between face A = (x0, x1,
 * x2) and face B = (x1, x0, x3), both wound counter-clockwise (cr_topology's
 * hinge order). With unit normals nA, nB and e = (x1 - x0)/|x1 - x0|:
 *
 *     theta = atan2((nB x nA) . e, nA . nB)       in (-pi, pi]
 *
 * theta is 0 when the faces are coplanar and positive when the wings fold
 * towards the side their normals point to (a valley seen from the front):
 * rotating x3 about the edge by +phi towards nB gives theta = phi. A convex
 * closed surface with outward normals therefore has theta < 0 on every hinge.
 * atan2 keeps it accurate near 0 and near +-pi, where acos of nA . nB is not.
 * The magnitude is the angle between the normals (pi minus the interior angle
 * between the faces). Computed in double; a degenerate face gives 0. */
float cr_dihedral_angle(const float x0[3], const float x1[3], const float x2[3], const float x3[3]);

/* theta (returned) and its gradient with respect to (x0, x1, x2, x3), packed
 * as grad[3*i+d] for vertex i, coordinate d. The standard closed form
 * (Bridson et al. 2003; Tamstorf & Grinspun 2013, "Discrete bending forces and
 * their Jacobians"): with hA, hB the heights of x2, x3 over the edge line and
 * aA, aB their projections' parameters along the edge from x0,
 *     d/dx2 = nA / hA,  d/dx3 = nB / hB,
 *     d/dx0 = -(1 - aA) d/dx2 - (1 - aB) d/dx3,   d/dx1 = -aA d/dx2 - aB d/dx3.
 * A degenerate face gives a zero gradient. */
float cr_dihedral_angle_grad(const float x0[3], const float x1[3], const float x2[3],
                             const float x3[3], float grad[12]);

/* theta of every hinge of `t` (built from `m`): theta (H), radians. */
void cr_mesh_hinge_angles(const cr_mesh *m, const cr_topology *t, float *theta);

/* ---------------------------------------------------- cotan Laplacian -- */

/* Compressed sparse rows; columns ascending within each row. */
typedef struct cr_csr {
    int32_t n;        /* rows = columns */
    int64_t nnz;      /* stored entries */
    int64_t *row_ptr; /* (n+1) offsets into col / val */
    int32_t *col;     /* (nnz) column of each entry */
    double *val;      /* (nnz) values */
} cr_csr;

/* Free the arrays and zero the struct (a zeroed struct is a no-op). */
void cr_csr_free(cr_csr *a);

/* y = A x for `k` right-hand sides stored row-major: x, y (n,k). */
void cr_csr_mul(const cr_csr *a, const double *x, int32_t k, double *y);

/* The cotangent Laplacian (Pinkall & Polthier 1993; Meyer et al. 2003), as the
 * symmetric positive semi-definite "stiffness" form
 *     L_ij = -w_ij (i != j, sharing an edge),  L_ii = sum_j w_ij,
 *     w_ij = (cot alpha_ij + cot beta_ij) / 2,
 * alpha, beta the angles opposite edge ij (one of them on a boundary edge), so
 * (L x)_i = sum_j w_ij (x_i - x_j) and rows sum to zero. Each row holds the
 * diagonal and the vertex's neighbours (nnz = V + 2E). Faces of zero area add
 * nothing (their cotangents are undefined). The caller frees with cr_csr_free.
 * CR_ERR_SHAPE when `t` was not built from a mesh of this size. */
cr_status cr_cotan_laplacian(const cr_mesh *m, const cr_topology *t, cr_csr *out, cr_error *err);

typedef enum cr_vertex_area {
    CR_AREA_BARYCENTRIC,  /* a third of each incident face's area */
    CR_AREA_MIXED_VORONOI /* Meyer et al. 2003, fig. 4 (area/2, area/4 on obtuse faces) */
} cr_vertex_area;

/* Area associated with each vertex: area (V), m^2. Both kinds sum to the
 * total surface area. */
void cr_mesh_vertex_areas(const cr_mesh *m, cr_vertex_area kind, float *area);

/* Mean curvature magnitude H = |(L x)_i| / (2 A_i) per vertex: H (V), 1/m,
 * with L the cotan Laplacian above and A_i the mixed Voronoi area (Meyer et
 * al. 2003, eq. 8): 1/R on a sphere of radius R. Boundary vertices, where
 * L x measures the boundary's curvature rather than the surface's, and
 * isolated vertices get 0. */
cr_status cr_mesh_mean_curvature(const cr_mesh *m, const cr_topology *t, float *H, cr_error *err);

/* ------------------------------------------------------ triangle quality -- */

/* Smallest interior angle of each face: deg (F), degrees; 0 for degenerate faces. */
void cr_mesh_face_min_angles(const cr_mesh *m, float *deg);

typedef struct cr_quality_stats {
    int32_t nf;          /* faces measured */
    float min_deg;       /* smallest face minimum angle, degrees */
    float mean_deg;      /* mean of the face minimum angles, degrees */
    float p01_deg;       /* 1st percentile (nearest rank) of the face minimum angles */
    float frac_above_20; /* fraction of faces whose minimum angle exceeds 20 degrees */
} cr_quality_stats;

/* Summary of cr_mesh_face_min_angles. An empty mesh gives zeros. */
cr_status cr_mesh_quality_stats(const cr_mesh *m, cr_quality_stats *out, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
