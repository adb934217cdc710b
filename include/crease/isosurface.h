/* crease/isosurface.h: triangle meshes of level sets of scalar fields.
 *
 *   sample a field on a regular grid (in parallel)          cr_isosurface_sample
 *   polygonise the grid: marching cubes, one consistent     cr_isosurface_extract
 *     rule per face, so the mesh is watertight and manifold
 *   relax the triangles along the surface and project the   cr_isosurface_relax
 *     vertices back onto the level set
 *
 * Conventions. A sample is inside when its value is below `iso` (strictly);
 * a value equal to `iso` counts as outside. Triangles are counter-clockwise
 * seen from outside, so normals point towards growing values: outward for a
 * signed distance that is negative inside. The grid has cubic cells of edge
 * `spacing`; sample (i, j, k) sits at origin + spacing * (i, j, k) and is
 * values[i + nx * (j + ny * k)].
 *
 * Guarantees of cr_isosurface_extract, for any finite samples:
 *   - every edge has exactly two faces and the faces around every vertex form
 *     one disk, when no inside sample lies on the grid's outer layer (else the
 *     surface is open there, with boundary edges on the grid's faces);
 *   - faces are consistently oriented and none repeats a vertex index;
 *   - vertices are welded: one per crossed grid edge, plus one per cell cycle
 *     that had to be fanned from its centroid (see isosurface.c).
 * How: each cell's surface is the set of closed cycles its crossed edges
 * make on the cell's six faces. A face with two crossings has one segment; a
 * face with four (the ambiguous case) is resolved by the asymptotic decider
 * (Nielson & Hamann 1991), evaluated exactly, so the two cells that share a
 * face always agree. Each cycle is triangulated without chords that the
 * neighbouring cell could also draw.
 *
 * Thread safety: cr_isosurface_sample calls `fn` from several threads at
 * once; the functions are otherwise reentrant.
 */
#ifndef CREASE_ISOSURFACE_H
#define CREASE_ISOSURFACE_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A scalar field: the value at p (3), m. Must be safe to call from several
 * threads at once and return finite values. */
typedef float (*cr_iso_fn)(void *ctx, const float p[3]);

typedef struct cr_iso_grid {
    int32_t nx, ny, nz;  /* samples per axis, >= 2 each */
    float origin[3];     /* position of sample (0,0,0), m */
    float spacing;       /* cell edge, m, > 0 */
    const float *values; /* (nz,ny,nx) samples, x fastest */
} cr_iso_grid;

/* Fill `values` (nz*ny*nx, x fastest) with fn at every sample of a grid with
 * g's sizes, origin and spacing (g->values is not read). Parallel over z
 * slices. CR_ERR_INVALID for bad sizes or spacing, CR_ERR_NAN when fn
 * returns a non-finite value (naming the sample). */
cr_status cr_isosurface_sample(const cr_iso_grid *g, cr_iso_fn fn, void *ctx, float *values,
                               cr_error *err);

/* The level set {value = iso} of the grid as a new triangle mesh (caller
 * destroys it). Crossing points are linearly interpolated along grid edges
 * and kept at least 1e-3 of a cell from either sample, so no face has
 * coincident corners. A field with no crossing gives an empty mesh (0
 * vertices, 0 faces). CR_ERR_INVALID for bad sizes, spacing or a non-finite
 * iso; CR_ERR_NAN for a non-finite sample (naming it); CR_ERR_RANGE when the
 * mesh would pass 2^31 vertices or faces; CR_ERR_MEMORY. */
cr_status cr_isosurface_extract(const cr_iso_grid *g, float iso, cr_mesh **out, cr_error *err);

/* Improve triangle shapes without moving the surface: `iterations` rounds
 * of (1) moving each vertex half-way towards the mean of its neighbours
 * within the tangent plane (the tangential part of the uniform Laplacian)
 * and (2) projecting it back onto {fn = iso} by Newton steps along the
 * gradient, taken by central differences of step `fd_step` (m; a tenth of
 * the grid spacing is a good choice). Boundary vertices of an open mesh skip
 * the tangential move. Connectivity is untouched, so a
 * watertight mesh stays watertight. Vertices whose gradient vanishes are
 * left where the tangential step put them. Parallel over vertices, Jacobi
 * style, so the result does not depend on the thread count.
 * CR_ERR_INVALID for iterations < 0 or fd_step <= 0; CR_ERR_NAN when fn
 * returns a non-finite value; CR_ERR_RANGE / CR_ERR_MEMORY from the
 * topology build. */
cr_status cr_isosurface_relax(cr_mesh *m, cr_iso_fn fn, void *ctx, float iso, int32_t iterations,
                              float fd_step, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
