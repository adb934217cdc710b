/* crease/primitives.h: procedural meshes for scenes, tests and benchmarks.
 *
 * Every generator returns a new cr_mesh (caller destroys it) that is
 *   - centred at the origin (the centroid of the solid; for the plane, of the sheet), Y up;
 *   - made of counter-clockwise triangles whose normals point outward;
 *   - welded: one vertex per position, so closed shapes are watertight (every
 *     edge shared by exactly two faces) and seams exist only in the UVs, which
 *     carry their own index triples (mesh.h) and lie in [0,1]^2.
 * UVs are right-handed where a shape has an obvious "up": dP/du x dP/dv points
 * along the outward normal, with v growing towards +Y (sphere, torus, capsule,
 * cylinder sides). Normals (m->normal) are not filled: call
 * cr_mesh_compute_normals.
 *
 * Parameters are checked: non-finite or non-positive sizes, too few segments
 * and vertex or face counts that would overflow int32 give CR_ERR_INVALID
 * with the parameter's name; a failed allocation gives CR_ERR_MEMORY.
 * Lengths are in metres.
 */
#ifndef CREASE_PRIMITIVES_H
#define CREASE_PRIMITIVES_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* nx*nz vertex grid in the XZ plane at y = 0, normal +Y, uv in [0,1]^2 with u
 * along +x and v along +z (one UV per vertex). nx, nz >= 2. Open (boundary). */
cr_status cr_prim_plane(int32_t nx, int32_t nz, float size_x, float size_z, cr_mesh **out,
                        cr_error *err);

/* Latitude-longitude sphere: `segments` (>= 3) around Y, `rings` (>= 2)
 * latitude bands, a single vertex at each pole. V = 2 + (rings-1)*segments,
 * F = 2*segments*(rings-1). */
cr_status cr_prim_sphere_uv(float radius, int32_t segments, int32_t rings, cr_mesh **out,
                            cr_error *err);

/* Icosahedron (a vertex at each pole) subdivided `subdivisions` (0..13) times
 * by edge midpoints pushed onto the sphere: V = 10*4^s + 2, F = 20*4^s.
 * UVs by spherical mapping (u = longitude, v = latitude); triangles that
 * straddle the seam get their own, unwrapped UVs, and u is scaled by the
 * resulting width so all UVs stay in [0,1]. */
cr_status cr_prim_icosphere(float radius, int32_t subdivisions, cr_mesh **out, cr_error *err);

/* Torus around Y: tube centre circle of `major_radius` in the XZ plane, tube
 * radius `minor_radius` (< major_radius). V = major_segments*minor_segments,
 * each >= 3. */
cr_status cr_prim_torus(float major_radius, float minor_radius, int32_t major_segments,
                        int32_t minor_segments, cr_mesh **out, cr_error *err);

/* Closed equilateral triangular prism lying along X: cross-section of edge
 * `side` in the YZ plane with the ridge up (+Y) and a flat face down, length
 * `length` along X. Unsubdivided: 6 vertices, 8 triangles. */
cr_status cr_prim_prism(float side, float length, cr_mesh **out, cr_error *err);

/* Closed axis-aligned box, each face split into subdivisions x subdivisions
 * quads (subdivisions >= 1), welded along the edges. Each face gets its own
 * tile of a 3x2 UV atlas. */
cr_status cr_prim_box(float size_x, float size_y, float size_z, int32_t subdivisions, cr_mesh **out,
                      cr_error *err);

/* Capsule around Y: a cylinder of `length` (>= 0; 0 gives a sphere) capped by
 * two hemispheres of `radius`. `segments` (>= 3) around Y, `rings` (>= 1)
 * latitude bands per hemisphere; the cylindrical part gets bands of about the
 * same height. */
cr_status cr_prim_capsule(float radius, float length, int32_t segments, int32_t rings,
                          cr_mesh **out, cr_error *err);

/* Cylinder around Y of `height`, `segments` (>= 3) around, `rings` (>= 1)
 * bands along the height. capped != 0 closes both ends with a fan around a
 * centre vertex; capped == 0 leaves an open tube with two boundary loops. */
cr_status cr_prim_cylinder(float radius, float height, int32_t segments, int32_t rings, int capped,
                           cr_mesh **out, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
