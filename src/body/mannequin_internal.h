/* mannequin_internal.h: the mannequin's implicit shape, shared by its
 * geometry (mannequin.c) and its skinning weights (mannequin_weights.c).
 *
 * The body is a sequence of primitives, each smooth-unioned into everything
 * before it with its own blend radius. Every primitive belongs to one part
 * (torso, neck and head, an arm, a leg); a part's skinning weights come from
 * its chain: planes across the part's joints, a bone between consecutive
 * planes, smooth steps across each plane.
 */
#ifndef CREASE_MANNEQUIN_INTERNAL_H
#define CREASE_MANNEQUIN_INTERNAL_H

#include "crease/body.h"

typedef enum prim_kind {
    PRIM_CONE,      /* capsule with radii ra at a, rb at b */
    PRIM_ELLIPSOID, /* centre a, semi-axes half along the rows of axes */
    PRIM_BOX,       /* centre a, half extents half along the rows of axes, edges rounded by ra */
    PRIM_TORSO      /* elliptic sections lofted along y (the shape's torso profile) */
} prim_kind;

typedef enum body_part {
    PART_TORSO = 0,
    PART_HEAD,
    PART_ARM_L,
    PART_ARM_R,
    PART_LEG_L,
    PART_LEG_R,
    PART_COUNT
} body_part;

typedef struct prim {
    prim_kind kind;
    body_part part;
    float blend;        /* smooth-union radius with the primitives before it, m */
    float a[3], b[3];   /* cone: axis ends; ellipsoid, box: centre in a */
    float ra, rb;       /* cone: end radii; box: edge rounding in ra; m */
    float axes[9];      /* ellipsoid, box: local x, y, z axes as rows (unit vectors) */
    float half[3];      /* ellipsoid: semi-axes; box: half extents; m */
    float centre[3], r; /* bounding sphere, m */
    /* The distance is at least cull_a |p - centre| - cull_b where |p - centre|
     * >= cull_min: lets the union skip primitives that cannot change it. */
    float cull_a, cull_b, cull_min;
} prim;

enum { TORSO_KEYS = 11, MAX_PRIMS = 32, MAX_PLANES = 4 };

/* Torso cross-sections: ellipses of half-width a (x), half-depth b (z),
 * centred at (0, y, c), interpolated by cubic Hermite splines in y and
 * capped by smooth maxima at y0 and y1. */
typedef struct torso_profile {
    float y[TORSO_KEYS], a[TORSO_KEYS], b[TORSO_KEYS], c[TORSO_KEYS];    /* m */
    float slope_a[TORSO_KEYS], slope_b[TORSO_KEYS], slope_c[TORSO_KEYS]; /* d/dy */
    float y0, y1, cap; /* bottom, top, cap rounding; m */
} torso_profile;

/* A part's skinning chain: bone[0] holds what lies behind plane 0, bone[i+1]
 * what lies past plane i (and behind plane i+1). */
typedef struct chain_plane {
    float p[3], n[3]; /* point, unit normal towards the next bone */
    float half;       /* half-width of the smooth step across the plane, m */
} chain_plane;

typedef struct body_chain {
    int nplanes;
    chain_plane plane[MAX_PLANES];
    int8_t bone[MAX_PLANES + 1];
} body_chain;

typedef struct mannequin_shape {
    float joints[CR_NJOINTS * 3]; /* rest joints, m */
    prim prims[MAX_PRIMS];
    int nprims;
    torso_profile torso;
    body_chain chain[PART_COUNT];
    float lo[3], hi[3];    /* bounds of the solid, m */
    float sole_round;      /* m: rounding where the soles meet the feet's sides */
    float membership_temp; /* m: softness of the part memberships (softmax of -d / temp) */
} mannequin_shape;

/* Signed distance (approximate away from the surface) of one primitive. */
float cr_mannequin_prim_distance(const mannequin_shape *s, const prim *q, const float p[3]);

/* The body's field: negative inside, about the distance near the surface. A
 * cr_iso_fn; ctx is a const mannequin_shape. */
float cr_mannequin_field(void *ctx, const float p[3]);

/* Four skinning joints and weights per vertex of `mesh` (V,4 each), from the
 * parts' memberships and chains. */
cr_status cr_mannequin_skin_weights(const mannequin_shape *s, const cr_mesh *mesh,
                                    int32_t *skin_joint, float *skin_weight, cr_error *err);

/* The rest joints the mannequin of `def` has, up to its scale and height
 * offset (directions are exact): what motions are retargeted onto without
 * building a mesh. */
void cr_mannequin_rest_joints(const cr_mannequin_def *def, float J[CR_NJOINTS * 3]);

#endif
