/* crease/garment.h: procedural garment templates fitted to a body's rest pose,
 * low/high resolution correspondences, and user garments brought onto a body.
 *
 *   build a garment of a type at a target vertex count       cr_garment_create
 *   one fitted template, many resolutions sharing its UVs     cr_garment_template_*
 *   layers worn over each other (vest over t-shirt)           cr_garment_create_layers
 *   layers merged into one outfit garment (two components)    cr_garment_outfit
 *   quality figures (angles, clearance, topology)             cr_garment_measure
 *   skinning the garment with the body's pose                 cr_garment_pose
 *   high vertex -> (low face, barycentric), gdsr Eq. 1        cr_garment_correspondence
 *   a user OBJ checked and pushed out of the body             cr_garment_load_user, _fit_user
 *   shape parameters by key, seeded random variants           cr_garment_param_*, _random_def,
 *     ("dress:seed=3", "tshirt:length=0.8"), quality targets    cr_garment_variant_*, _check
 *   `crease garment` as one call: built, written, measured,   cr_garment_make
 *     pictured on the body
 *
 *   cr_garment_def def = cr_garment_default_def(CR_GARMENT_TSHIRT);
 *   def.target_vertices = 8000;
 *   cr_garment *g = NULL;
 *   CR_TRY(cr_garment_create(&def, body, &g, err));     g->mesh, g->skin_*, g->panel
 *   cr_garment_quality q;
 *   CR_TRY(cr_garment_measure(g, body, &q, err));
 *   cr_garment_destroy(g);
 *
 * What a garment is: a manifold triangle mesh with boundary (open at the neck,
 * hem, sleeve and leg ends), consistently oriented with normals pointing away
 * from the body, in the body's rest pose and frame (m, +Y up), at least 5 mm
 * outside the body at every vertex. Faces belong to panels (front, back,
 * sleeve halves, trouser quarters); seams between panels are welded in 3-D
 * (one vertex) but cut in UV (cr_mesh.tri_uv gives each panel its own UV
 * chart). UV charts are flattened near-isometrically, each scaled so its UV
 * area times uv_scale_m^2 equals its 3-D area, and packed into [0,1]^2:
 * uv * uv_scale_m is metres along the cloth. Every vertex carries four
 * skinning weights transferred from the body (closest point on the body,
 * barycentric blend, four largest kept, renormalised; smoothed over the loose
 * parts of skirts and dresses, which would otherwise tear between the legs).
 *
 * Construction (src/body/garment_shapes.c and docs/garments.md): tight parts
 * are a level set of the body's signed distance, sampled on a grid and
 * blurred (so armpits and crotch get a smooth fillet instead of a crease);
 * skirts and the dress's lower half are a flared envelope around the hips
 * and legs. The level set is polygonised, cut by the garment's openings and
 * seams (planes, spheres and the level 1/2 of the body's arm skinning
 * weights, which gives a natural armhole on any body), remeshed isotropically
 * with the seams and openings kept as feature lines, then flattened per
 * panel. All resolutions of one template share its UV layout, so a low and a
 * high resolution garment correspond through UV space (gdsr, Eq. 1).
 *
 * Deterministic: the same def and body give the same garment bit for bit,
 * whatever the thread count (the build has no random element; a random
 * variant is a def drawn from a seed before the build).
 * Units: m. Thread safety: reentrant; a built template or garment is read-only.
 */
#ifndef CREASE_GARMENT_H
#define CREASE_GARMENT_H

#include "crease/body.h"
#include "crease/mesh.h"
#include "crease/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum cr_garment_type {
    CR_GARMENT_TSHIRT = 0, /* short sleeves to mid upper arm, hem at the hips */
    CR_GARMENT_LONGSLEEVE, /* sleeves to the wrists */
    CR_GARMENT_SKIRT,      /* A-line, waist to just above the knees */
    CR_GARMENT_DRESS,      /* sleeveless top and a flared skirt to the knees */
    CR_GARMENT_TROUSERS,   /* waist to the ankles */
    CR_GARMENT_VEST,       /* sleeveless, worn over a t-shirt (more clearance) */
    CR_GARMENT_JUMPSUIT,   /* sleeveless top and trousers in one piece, neck to the ankles */
    CR_GARMENT_USER,       /* loaded from a file (cr_garment_load_user) */
    CR_GARMENT_TYPE_COUNT
} cr_garment_type;

/* "tshirt", "longsleeve", "skirt", "dress", "trousers", "vest", "jumpsuit", "user". */
const char *cr_garment_type_name(cr_garment_type type);
/* Type by name; CR_ERR_INVALID naming the unknown type and listing the known
 * ones ("user" is not accepted: user garments come from a file). */
cr_status cr_garment_type_parse(const char *name, cr_garment_type *out, cr_error *err);

/* Most panels a garment may have (procedural ones have 2 to 6; a user
 * garment has one per UV chart). */
#define CR_GARMENT_MAX_PANELS 32

typedef struct cr_garment_def {
    cr_garment_type type;
    int32_t target_vertices;   /* wanted vertex count, [500, 100000]; met within 15% from
                                  2k to 40k (default 8000) */
    float clearance_m;         /* offset of the tight parts from the body, m, [0.005, 0.1]; default
                                  0.01 (t-shirt, long sleeve, dress top), 0.02 (vest), 0.015
                                  (trousers, skirt waist). Every vertex ends at least 5 mm out. */
    float flare_deg;           /* skirt, dress and long shirts: half-angle of the cone the skirt
                                  widens along below the waist, degrees, [0, 45] (default 15
                                  dress, 12 the others; ignored by trousers, vest, jumpsuit) */
    float length_scale;        /* hem, sleeve and leg lengths as a multiple of the type's
                                  default, [0.5, 1.5] (default 1); a t-shirt or long sleeve
                                  whose hem would pass 2 cm below the hip joints becomes a
                                  long shirt (below the waist the dress's flared envelope, as
                                  a tight hem would split round each leg), long sleeves
                                  always reach the wrists (see sleeve_scale), trousers and
                                  jumpsuit legs stop above the ankles; vest hems stop 2 cm
                                  below the hip joints */
    float grid_m;              /* cell of the grid the level set is sampled on, m, [0.004, 0.03]
                                  (default 0.01): finer follows the body more closely, costs
                                  cubically */
    int32_t remesh_iterations; /* isotropic remeshing rounds from the polygonised surface,
                                  [1, 50] (default 8); an instance refines the template's
                                  reference mesh in half as many (at least 3) */
    float sleeve_scale;        /* t-shirt: sleeve end as a multiple of its default place (60% of
                                  the upper arm, times length_scale; at most 95% of it); long
                                  sleeve: the share of the way from the elbow to 1.5 cm before
                                  the wrist (above 1 changes nothing); [0.5, 1.5] (default 1;
                                  ignored by the sleeveless types) */
    float neck_m;              /* neckline: added to the radius of the sphere that cuts it, m,
                                  [-0.02, 0.08] (default 0; ignored by skirt and trousers) */
    uint32_t cookie;           /* set by cr_garment_default_def; a hand-zeroed def is a bug */
} cr_garment_def;

/* Defaults for a type (not CR_GARMENT_USER), as listed field by field above. */
cr_garment_def cr_garment_default_def(cr_garment_type type);

/* Quality figures of a garment (cr_garment_measure, cr_garment_check below). */
typedef struct cr_garment_quality {
    int32_t vertices, faces;
    int32_t boundary_loops; /* openings: neck, hem, sleeves, legs */
    int32_t panels;
    float share_min_angle_above_20deg; /* faces whose smallest angle exceeds 20 deg, 0..1 */
    float min_angle_deg;               /* smallest angle of any face, degrees */
    float min_clearance_m;             /* smallest signed distance from a vertex to the body, m */
    float share_outward;               /* faces whose normal points away from the body, 0..1 */
    float max_weight_sum_error;        /* max |sum of a vertex's skin weights - 1| */
    float uv_area_error; /* max over panels of |UV area * uv_scale^2 / 3-D area - 1| */
    int manifold;        /* 1: an oriented 2-manifold with boundary, no defects */
    int32_t uv_flipped;  /* faces whose UV triangle has non-positive area */
    int32_t bad_joints;  /* skin joint indices outside the skeleton */
} cr_garment_quality;

/* A garment fitted to a body at no particular resolution (see templates below). */
typedef struct cr_garment_template cr_garment_template;

/* ---------------------------------------------------- shape parameters -- */

/* The shape parameters of cr_garment_def by key, one row each: what the
 * CLI's options (--length ...), variant specs ("dress:length=0.9") and the
 * random generator go through. A row's accepted range is what
 * cr_garment_create takes; its sampled range (per type) is where the random
 * generator draws and where every variant has been checked to pass
 * cr_garment_check. A type whose sampled range is empty (lo = hi = 0) does
 * not use the parameter. */
typedef struct cr_garment_param {
    const char *key;   /* "length", "sleeve", "flare", "clearance", "neck" */
    const char *field; /* the cr_garment_def field: "length_scale", ... */
    const char *unit;  /* "x" (a multiple), "deg", "m" */
    const char *help;  /* one line */
    double lo, hi;     /* accepted range, both ends included */
    float sample_lo[CR_GARMENT_USER], sample_hi[CR_GARMENT_USER]; /* per type */
} cr_garment_param;

#define CR_GARMENT_NPARAMS 5

/* Row i (0 <= i < CR_GARMENT_NPARAMS); NULL past the end. */
const cr_garment_param *cr_garment_param_at(int i);
/* Row index of a key, or -1. */
int cr_garment_param_find(const char *key);
/* Read and write def's field of row i. */
float cr_garment_param_get(const cr_garment_def *def, int i);
/* Set a parameter by key: CR_ERR_INVALID naming an unknown key (and listing
 * the keys) or the key and its range for a value outside it. */
cr_status cr_garment_param_set(cr_garment_def *def, const char *key, double value, cr_error *err);

/* A random variant's def: each parameter the type uses drawn uniformly in
 * its sampled range from cr_rng_make(seed, type + CR_GARMENT_TYPE_COUNT *
 * attempt) in row order; the others keep their defaults. attempt 0 is the
 * first draw; cr_garment_variant_build takes further attempts when a draw
 * fails the checks. Pure: no body, no build. */
cr_garment_def cr_garment_random_def(cr_garment_type type, uint64_t seed, int32_t attempt);

/* A garment variant as text: "TYPE" or "TYPE:key=value:key=value..." with
 * the keys of the table, plus "seed=N" for a random variant (given keys
 * override the drawn values), "res=N" for target_vertices. */
typedef struct cr_garment_variant {
    cr_garment_def def; /* defaults, then given values (drawn ones after _build) */
    int random;         /* seed= was given */
    uint64_t seed;
    uint32_t given;             /* bit i: table row i given explicitly */
    int32_t attempts;           /* set by _build: draws made until one passed (1 for the first) */
    char rejected[160];         /* set by _build: why the last rejected draw failed ("" if none) */
    cr_garment_quality quality; /* set by _build: the checked instance's figures */
    char label[128];            /* file-name safe: "dress", "dress_seed3", "tshirt_length0.8" */
} cr_garment_variant;

/* Parse a spec (CR_ERR_INVALID naming the spec and the bad part). */
cr_status cr_garment_variant_parse(const char *spec, cr_garment_variant *out, cr_error *err);

/* Most draws a random variant takes before giving up. */
#define CR_GARMENT_RANDOM_ATTEMPTS 8

/* Fix v->def on `body` and build its template (*out, may be NULL to only
 * check): a random variant draws (attempt 0, 1, ...; given keys override),
 * builds, instantiates at v->def.target_vertices and keeps the first draw
 * that passes cr_garment_check; after CR_GARMENT_RANDOM_ATTEMPTS failures
 * CR_ERR_TOPOLOGY with the last reason. A fixed variant is built and
 * checked once. */
cr_status cr_garment_variant_build(cr_garment_variant *v, const cr_body_model *body,
                                   cr_garment_template **out, cr_error *err);

/* The exact spec of a def: every table key the type uses, with %.9g values
 * (reads back bit for bit), and res, e.g. "dress:length=1.1:flare=20.5:...". */
void cr_garment_def_spec(const cr_garment_def *def, char *out, size_t cap);

typedef struct cr_garment {
    cr_garment_type type;
    cr_mesh *mesh;       /* rest mesh with vertex normals, m, and UVs (per-corner, tri_uv);
                            a user garment may have none (cr_garment_fit_user) */
    int32_t *skin_joint; /* (V,4) joint indices into the body's skeleton */
    float *skin_weight;  /* (V,4) weights, sum 1, largest first */
    int32_t *panel;      /* (F) panel of each face, in [0, npanels) */
    int32_t npanels;
    char panel_name[CR_GARMENT_MAX_PANELS][24]; /* "front", "back", "left_sleeve_front", ...
                                                   ("chart_0", ... for user garments;
                                                   "piece_0", ... for one without UVs) */
    float uv_scale_m;  /* metres per UV unit (the same for every resolution of a template);
                          0 without UVs */
    float clearance_m; /* the clearance it was built with, m */
} cr_garment;

/* Free everything; NULL is a no-op. */
void cr_garment_destroy(cr_garment *g);

/* Build a garment of def->type on `body` (its rest mesh must be closed and
 * outward-oriented: the mannequin or a loaded SMPL body). CR_ERR_INVALID
 * naming a def field out of range; CR_ERR_TOPOLOGY when the body leaves no
 * clean surface for the type (e.g. arms fused to the torso); CR_ERR_MEMORY.
 * The caller destroys *out. */
cr_status cr_garment_create(const cr_garment_def *def, const cr_body_model *body, cr_garment **out,
                            cr_error *err);

/* ----------------------------------------------------------- templates -- */

/* A garment fitted to a body at no particular resolution: the cut surface,
 * its seams and the UV layout. Instantiating it at two vertex counts gives a
 * low/high pair sharing the UV layout (and uv_scale_m). */
cr_status cr_garment_template_create(const cr_garment_def *def, const cr_body_model *body,
                                     cr_garment_template **out, cr_error *err);
/* A garment with about target_vertices vertices ([500, 100000]). The body
 * must be the one the template was made for. */
cr_status cr_garment_template_instantiate(const cr_garment_template *t, int32_t target_vertices,
                                          const cr_body_model *body, cr_garment **out,
                                          cr_error *err);
void cr_garment_template_destroy(cr_garment_template *t);

/* ------------------------------------------------------------- layers -- */

/* Space between the offsets of two layers worn over each other, m. */
#define CR_GARMENT_LAYER_GAP 0.006f

/* Build n garments worn over each other, innermost first (a t-shirt, then a
 * vest). Layer i's clearance must exceed layer i-1's by at least
 * CR_GARMENT_LAYER_GAP and all layers must share grid_m (CR_ERR_INVALID
 * naming the layers otherwise): then each is a level set of one blurred
 * distance field, nested in the one below. The built layers are checked not
 * to intersect (CR_ERR_TOPOLOGY naming the pair and the crossing count).
 * out (n) receives the garments; on failure all are NULL. */
cr_status cr_garment_create_layers(const cr_garment_def *defs, int32_t n, const cr_body_model *body,
                                   cr_garment **out, cr_error *err);

/* Outfits: garments worn over each other merged into one garment, one
 * connected component per layer (vertices, faces, UVs, panels and skinning
 * in layer order, innermost first), so a simulator treats them as one cloth
 * and its self-contact keeps the layers apart. Layer k's UV charts are
 * scaled into the strip u in [k/n, (k+1)/n) of one layout with one
 * uv_scale_m (uv * uv_scale_m stays metres along the cloth), so a UV
 * correspondence (cr_garment_correspondence) maps each layer onto itself
 * and every resolution of the same templates shares the layout. Each layer
 * is checked against those inside it: no edge of one crosses a face of the
 * other, and every inner vertex whose closest point on the layer lies
 * inside one of its faces within 5 cm is at least CR_GARMENT_OUTFIT_MIN_GAP
 * behind it; a layer that fails is moved out along its normals by 1 mm
 * steps, up to CR_GARMENT_OUTFIT_MAX_STEPS mm (offset_m (n), may be NULL,
 * receives each layer's move), else CR_ERR_TOPOLOGY naming the layer. The
 * outfit's type and clearance are its first layer's; panels are named
 * "<layer>_<panel>". CR_ERR_INVALID for n outside [2,
 * CR_GARMENT_OUTFIT_MAX_LAYERS], a layer without UVs or normals, or more
 * than CR_GARMENT_MAX_PANELS panels in all. */
#define CR_GARMENT_OUTFIT_MAX_LAYERS 4
#define CR_GARMENT_OUTFIT_MIN_GAP 0.004f
#define CR_GARMENT_OUTFIT_MAX_STEPS 20
cr_status cr_garment_outfit(const cr_garment *const *layers, int32_t n, cr_garment **out,
                            float *offset_m, cr_error *err);

/* Number of edges of `a` that cross a face of `b` plus edges of `b` that
 * cross a face of `a` (0 for layers that do not intersect), or -1 with err
 * set on failure. */
int64_t cr_garment_count_crossings(const cr_mesh *a, const cr_mesh *b, cr_error *err);

/* Linear blend skinning of the garment's rest mesh with its own weights:
 * out (V,3), m, for a pose (22,3) axis-angle, rad, and root translation
 * trans (3), m (may be NULL), of the body the garment was made for
 * (crease/body.h's convention). CR_ERR_NAN for a non-finite pose. */
cr_status cr_garment_pose(const cr_garment *g, const cr_body_model *body, const float *pose,
                          const float *trans, float *out, cr_error *err);

/* ------------------------------------------------------------ quality -- */

/* Measure g against its body (rest pose). CR_ERR_MEMORY, or errors from
 * building the body's BVH. */
cr_status cr_garment_measure(const cr_garment *g, const cr_body_model *body,
                             cr_garment_quality *out, cr_error *err);

/* Openings a procedural type has: 4 tops and dress, 2 skirt, 3 trousers,
 * 5 jumpsuit. */
int32_t cr_garment_openings(cr_garment_type type);

/* Measure g (into *q, may be NULL) and hold it to the quality targets: at
 * least 99% of faces with every angle above 20 degrees, every vertex 5 mm
 * out of the body, manifold with the type's openings, 99% of faces facing
 * away from the body, UVs present and unflipped with panel areas within 3%,
 * weights summing to 1 within 1e-5 on valid joints. CR_ERR_TOPOLOGY naming
 * the first figure that misses. */
cr_status cr_garment_check(const cr_garment *g, const cr_body_model *body, cr_garment_quality *q,
                           cr_error *err);

/* ----------------------------------------------------- correspondence -- */

/* For every vertex k of `high`, the face of `low` under it in UV space and
 * barycentric weights b (gdsr, Eq. 1: S[C, f, u, v] = (1-u-v) c0 + u c1 +
 * v c2 with (u, v) = (b1, b2)), so the high mesh is resampled from the low one
 * as sum_i b_i low.pos[low.tri[3 face + i]]. Vertices outside every UV chart
 * of `low` (on a chart's rim) take the nearest point of the nearest chart.
 * A high vertex whose UV coincides with a low vertex's gets that corner with
 * weight exactly 1, so applying a mesh's correspondence to itself reproduces
 * it bit for bit. Both meshes need UVs sharing one layout (two instances of
 * one template). face (Vh), bary (Vh,3). CR_ERR_INVALID when either mesh has
 * no UVs. */
cr_status cr_garment_correspondence(const cr_mesh *low, const cr_mesh *high, int32_t *face,
                                    float *bary, cr_error *err);

/* out (Vh,3) = the high mesh resampled from low positions low_pos (Vl,3)
 * through a correspondence, summed in double. */
void cr_garment_apply_correspondence(const cr_mesh *low, const float *low_pos, const int32_t *face,
                                     const float *bary, int32_t nv_high, float *out);

/* -------------------------------------------------------- user garments -- */

typedef struct cr_garment_user_def {
    float clearance_m;        /* push every vertex at least this far out of the body, m,
                                 [0.005, 0.1] (default 0.01) */
    int32_t relax_iterations; /* smoothing rounds after each push, [0, 200] (default 10) */
    int32_t max_rounds;       /* push-and-relax rounds before the last exact push, [1, 100]
                                 (default 20) */
    uint32_t cookie;          /* set by cr_garment_user_default_def */
} cr_garment_user_def;

cr_garment_user_def cr_garment_user_default_def(void);

/* Check a garment mesh and fit it to the body's rest pose. `source` names it
 * in messages (the file name). Checks, each failing with CR_ERR_TOPOLOGY or
 * CR_ERR_INVALID and a message starting with `source`: an oriented 2-manifold
 * (cr_topology_require_manifold), UVs not degenerate where present, plausible
 * size in metres (bounding box diagonal 0.1 to 4 m; a diagonal of 10 to 400
 * suggests centimetres and says so), near the body (most vertices within
 * 0.3 m of it), and normals pointing away from the body. Fitting: vertices
 * closer than the clearance are pushed out along the body's signed-distance
 * gradient, the displacement is relaxed over the mesh (Laplacian smoothing
 * of what moved), repeated, then a last push guarantees the clearance at
 * every vertex. Panels are the UV charts (faces connected through shared UV
 * corners), or without UVs the connected pieces (uv_scale_m 0: the membrane
 * rests on the 3-D mesh; drape and gdsr refuse such a garment); skin weights
 * come from the body's nearest surface as for procedural garments. */
cr_status cr_garment_fit_user(const cr_mesh *mesh, const char *source,
                              const cr_garment_user_def *def, const cr_body_model *body,
                              cr_garment **out, cr_error *err);

/* Read an OBJ, PLY or glb (by extension) and cr_garment_fit_user it. */
cr_status cr_garment_load_user(const char *path, const cr_garment_user_def *def,
                               const cr_body_model *body, cr_garment **out, cr_error *err);

/* ----------------------------------------------------- crease garment -- */

/* `crease garment` as one call (src/body/garment_make.c): the mannequin, the
 * garments (procedural layers, one random variant, or a user's file), each
 * written and measured, and a picture of them on the body. */
#define CR_GARMENT_MAKE_MAX_LAYERS 4

typedef struct cr_garment_make_def {
    cr_mannequin_def body;   /* the body they fit (cr_mannequin_default_def) ... */
    const char *body_spec;   /* ... or this body (cr_body_resolve: a preset, an SMPL file, a
                                rigged CHAR.glb[:MAP]) when not NULL */
    const char *types;       /* "TYPE" or layers worn over each other, innermost first
                                ("tshirt,vest"); with random a variant spec (cr_garment_variant);
                                NULL with user */
    const char *user;        /* a user's garment file (cr_garment_load_user), or NULL */
    const char *out;         /* the mesh file (.obj, .ply, .glb); of layers, each one's with _TYPE
                                before the extension (required) */
    int32_t target_vertices; /* of a procedural garment (default 8000) */
    float grid_m;            /* level-set grid cell, m; 0: each type's default */
    float param[CR_GARMENT_NPARAMS]; /* shape parameters by table row ... */
    uint32_t given;                  /* ... bit i: param[i] overrides (a user garment: only
                                        clearance) */
    int random;                      /* draw one variant of types (seeded) */
    uint64_t seed;
    const char *render_png; /* a picture of the garments on the body, or NULL */
    int32_t render_size;    /* its side, px (default 720) */
    float render_yaw_deg;   /* camera yaw (default 30) */
    const char *clip;       /* body and garments posed at a frame of this procedural clip
                               (cr_motion_clip), or NULL: the rest pose */
    int32_t clip_frame;     /* the clip's frame (default 15) */
    uint32_t cookie;        /* set by cr_garment_make_default_def */
} cr_garment_make_def;
cr_garment_make_def cr_garment_make_default_def(void);

typedef struct cr_garment_make_result {
    int32_t n;                                              /* garments built */
    cr_garment *garments[CR_GARMENT_MAKE_MAX_LAYERS];       /* (n), owned */
    cr_garment_def defs[CR_GARMENT_MAKE_MAX_LAYERS];        /* (n) what each was built with (not
                                                               for a user garment) */
    cr_garment_quality quality[CR_GARMENT_MAKE_MAX_LAYERS]; /* (n) cr_garment_measure */
    char paths[CR_GARMENT_MAKE_MAX_LAYERS][1024];           /* (n) the files written */
    cr_garment_variant variant;                             /* with random: attempts, rejected */
    double seconds;                                         /* body and build, s */
    int bad_types; /* on failure, 1 when def->types itself is wrong (an unknown type, more
                      than CR_GARMENT_MAKE_MAX_LAYERS layers, no type): the caller's
                      spelling */
} cr_garment_make_result;

/* On failure out holds no garments (bad_types set as above). */
cr_status cr_garment_make(const cr_garment_make_def *def, cr_garment_make_result *out,
                          cr_error *err);
void cr_garment_make_result_free(cr_garment_make_result *r); /* NULL is a no-op */

#ifdef __cplusplus
}
#endif
#endif
