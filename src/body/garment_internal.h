/* garment_internal.h: what the garment files share: the sampled level-set
 * field, the cut surface a template keeps, mesh cutting along level sets,
 * the feature-preserving remesher, UV layout and transfer, weight transfer.
 *
 * Shapes: V vertices, F faces, K scalar fields per vertex, P panels.
 */
#ifndef CREASE_GARMENT_INTERNAL_H
#define CREASE_GARMENT_INTERNAL_H

#include "crease/bvh.h"
#include "crease/garment.h"

/* ----------------------------------------------------------- parameters -- */

/* lo <= v <= hi, with the decimal bounds widened by 1e-6 (a float field
 * holds them rounded). */
int cr_garment_in_range(double v, double lo, double hi);
/* Every shape parameter of d in its accepted range (garment_params.c);
 * CR_ERR_INVALID naming the field, its key and the range. */
cr_status cr_garment_params_check(const cr_garment_def *d, cr_error *err);

/* ---------------------------------------------------------------- field -- */

/* A scalar field on a regular grid, negative inside the garment's level set
 * (towards the body), evaluated by trilinear interpolation; positions
 * outside the grid clamp to its faces. */
typedef struct gfield {
    int32_t nx, ny, nz;
    float origin[3]; /* sample (0,0,0), m */
    float h;         /* cell edge, m */
    float *v;        /* (nz,ny,nx) samples, x fastest; owned */
} gfield;

/* Value at p; grad (may be NULL) gets the gradient of the interpolant. */
float cr_gfield_eval(const gfield *f, const float p[3], float grad[3]);
/* Move p onto the zero level by Newton steps along the gradient. */
void cr_gfield_project(const gfield *f, float p[3]);
/* [1 2 1]/4 smoothing of n values x[i * stride] in place, edges clamped or
 * periodic; tmp (n) scratch. */
void cr_garment_smooth_line(float *x, int32_t n, int32_t stride, int periodic, float *tmp);

/* ------------------------------------------------------- cutting meshes -- */

/* A triangle mesh carrying K scalar fields per vertex, for cutting along
 * their zero levels (garment_cut.c). Grows as it is cut. */
typedef struct gcutmesh {
    int32_t nv, nf, cap_v, cap_f;
    int32_t nfield; /* K */
    float *pos;     /* (cap_v,3) m */
    float *val;     /* (cap_v,K) */
    int32_t *tri;   /* (cap_f,3) */
} gcutmesh;

void cr_gcut_free(gcutmesh *m);
/* Split every edge that field k changes sign along at its zero (fields
 * interpolated linearly), so no face has vertices of both signs afterwards.
 * Values within eps of zero are set to zero first (no slivers thinner than
 * that). Orientation is kept. */
cr_status cr_gcut_split(gcutmesh *m, int32_t k, float eps, cr_error *err);
/* Sign of field k over face f after cr_gcut_split: +1, -1, or +1 for a face
 * lying in the zero level. */
int cr_gcut_face_sign(const gcutmesh *m, int32_t f, int32_t k);
/* Drop the faces where field k is negative. */
void cr_gcut_remove_negative(gcutmesh *m, int32_t k);
/* Keep the edge-connected component of largest area; drop unused vertices. */
cr_status cr_gcut_keep_largest(gcutmesh *m, cr_error *err);
/* 1-to-4 midpoint subdivision of `in` with a panel per face: every edge
 * gets its midpoint, every face four similar faces (panels inherited). */
cr_status cr_gcut_subdivide(const cr_mesh *in, const int32_t *panel, cr_mesh **out,
                            int32_t **out_panel, cr_error *err);

/* --------------------------------------------------------- remeshing -- */

/* Isotropic remeshing (cr_garment_remesh.c) of a panelled surface lying on
 * the field's zero level, to about target_vertices vertices. Boundaries and
 * edges between panels are feature lines: vertices on them stay on the
 * base mesh's feature polylines, and vertices where features meet (corners)
 * never move. The connectivity starts from `start` (a remesh of the base
 * with the same panels and corners), or from the base when start is NULL. */
typedef struct gremesh_out {
    cr_mesh *mesh;  /* positions and triangles only */
    int32_t *panel; /* (F) */
} gremesh_out;

cr_status cr_garment_remesh(const gfield *field, const cr_mesh *base, const int32_t *base_panel,
                            const cr_mesh *start, const int32_t *start_panel,
                            int32_t target_vertices, int32_t iterations, gremesh_out *out,
                            cr_error *err);

/* ------------------------------------------------------------- the cut -- */

/* The body as the garment code sees it: measurements, a BVH of the rest
 * mesh, and per-vertex arm weights. */
typedef struct gbody {
    const cr_body_model *model;
    cr_bvh *bvh;
    float scale; /* height / 1.75 m */
    float lo[3], hi[3];
    float *arm_w; /* (V,2) skin weight on the left and right arm (shoulder, elbow, wrist) */
} gbody;

cr_status cr_gbody_init(gbody *b, const cr_body_model *model, cr_error *err);
void cr_gbody_free(gbody *b);

/* What a template keeps: the field, the cut surface on its zero level with
 * a panel per face, and the panels' names. */
typedef struct gbase {
    gfield field;
    cr_mesh *mesh;  /* cut surface, vertices on the zero level */
    int32_t *panel; /* (F) */
    int32_t npanels;
    char panel_name[CR_GARMENT_MAX_PANELS][24];
    int loose; /* 1: parts hang away from the body (skirts): weights are smoothed */
} gbase;

/* The body's signed distance blurred, minus the clearance, on f's grid
 * (f's sizes, origin, h and v (allocated) set by the caller); outside the
 * box [box_lo, box_hi] the field is not needed and is set to the far side
 * (garment_field.c). */
cr_status cr_garment_distance_field(const gbody *b, const float box_lo[3], const float box_hi[3],
                                    float clearance, gfield *f, cr_error *err);

/* Sample the type's field, polygonise, cut and label (garment_shapes.c). */
cr_status cr_garment_build_base(const cr_garment_def *def, const gbody *body, gbase *out,
                                cr_error *err);
void cr_gbase_free(gbase *b);

/* ------------------------------------------------------------------ UV -- */

/* Flatten every panel of `m` (garment_uv.c): per-panel ARAP from an
 * orthographic start, oriented with the body's up as +v, each chart scaled
 * to its 3-D area, packed into [0,1]^2. Sets m's uv and tri_uv (seam
 * vertices get one UV per panel) and *uv_scale_m. */
cr_status cr_garment_uv_layout(cr_mesh *m, const int32_t *panel, int32_t npanels, float *uv_scale_m,
                               cr_error *err);
/* Give `m` UVs in `ref`'s layout: each vertex is projected along the field
 * normal onto ref's faces of the same panel and takes the interpolated UV. */
cr_status cr_garment_uv_transfer(const cr_mesh *ref, const int32_t *ref_panel, int32_t npanels,
                                 const gfield *field, cr_mesh *m, const int32_t *panel,
                                 cr_error *err);

/* ------------------------------------------------------------- weights -- */

/* Skin weights for garment vertices (garment_skin.c): joint (V,4), weight
 * (V,4) from the closest body point; `loose` smooths them where the garment
 * hangs away from the body. */
cr_status cr_garment_skin_transfer(const gbody *body, const cr_mesh *m, int loose, float clearance,
                                   int32_t *joint, float *weight, cr_error *err);
/* Push vertices closer to the body than `min_m` out to it along the
 * signed-distance gradient. Returns how many moved. */
int32_t cr_garment_push_out(const gbody *body, float *pos, int32_t nv, float min_m);

/* Allocate a cr_garment around mesh (taken over) and panel (taken over),
 * with skin weights and normals. */
cr_status cr_garment_finish(const gbody *body, cr_garment_type type, cr_mesh *mesh, int32_t *panel,
                            int32_t npanels, char (*names)[24], float uv_scale_m, float clearance,
                            int loose, cr_garment **out, cr_error *err);

#endif
