/* crease/mesh.h: the triangle mesh every module shares.
 *
 * Positions and triangles are packed arrays (V,3) and (F,3). UVs are
 * optional and carry their own index triples, as OBJ allows, so a seam vertex
 * can have several UVs. Per-vertex normals and named per-vertex attributes
 * (skinning weights, scalars for colour maps) are optional.
 *
 * Ownership: a cr_mesh owns every array it points to; cr_mesh_destroy frees
 * them. Arrays are allocated with malloc so modules may grow them in place.
 */
#ifndef CREASE_MESH_H
#define CREASE_MESH_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_MESH_ATTR_NAME_MAX = 32 };

typedef struct cr_mesh_attr {
    char name[CR_MESH_ATTR_NAME_MAX];
    int32_t dim; /* values per vertex */
    float *data; /* (V, dim) */
} cr_mesh_attr;

typedef struct cr_mesh {
    int32_t nv;      /* V: vertex count */
    int32_t nf;      /* F: triangle count */
    int32_t nuv;     /* U: UV count; 0 when the mesh has no UVs */
    float *pos;      /* (V,3) positions, m */
    int32_t *tri;    /* (F,3) vertex indices, counter-clockwise seen from the front */
    float *uv;       /* (U,2) texture coordinates, NULL when nuv == 0 */
    int32_t *tri_uv; /* (F,3) indices into uv, NULL when nuv == 0 */
    float *normal;   /* (V,3) unit vertex normals, or NULL */
    int32_t nattr;
    cr_mesh_attr *attr; /* (nattr) named per-vertex attributes */
} cr_mesh;

/* Allocate a mesh with room for nv vertices, nf faces and nuv UVs (nuv = 0:
 * no UVs). Arrays are zeroed; normals are not allocated. */
cr_status cr_mesh_create(int32_t nv, int32_t nf, int32_t nuv, cr_mesh **out, cr_error *err);
void cr_mesh_destroy(cr_mesh *m);
cr_status cr_mesh_clone(const cr_mesh *m, cr_mesh **out, cr_error *err);

static inline int cr_mesh_has_uv(const cr_mesh *m) {
    return m->nuv > 0 && m->uv && m->tri_uv;
}

/* Allocate (zeroed) or fetch a named attribute of `dim` floats per vertex. */
cr_status cr_mesh_add_attr(cr_mesh *m, const char *name, int32_t dim, float **out, cr_error *err);
const cr_mesh_attr *cr_mesh_find_attr(const cr_mesh *m, const char *name);

/* Check indices are in range and all numbers finite. `source` names the mesh
 * in messages (a file name, or e.g. "garment"). */
cr_status cr_mesh_validate(const cr_mesh *m, const char *source, cr_error *err);

/* Axis-aligned bounds: lo, hi (3 each). An empty mesh gives lo = hi = 0. */
void cr_mesh_bounds(const cr_mesh *m, float lo[3], float hi[3]);
/* Length of the bounds' diagonal, in the mesh's unit (0 for an empty mesh). */
double cr_mesh_diagonal(const cr_mesh *m);

/* Apply x' = s * x + t to every position. */
void cr_mesh_transform(cr_mesh *m, float scale, const float translate[3]);

/* Append `b` to `a` (vertices, faces, UVs; attributes are dropped). */
cr_status cr_mesh_append(cr_mesh *a, const cr_mesh *b, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
