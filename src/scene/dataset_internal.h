/* dataset_internal.h: what dataset.c (assets) and dataset_run.c (the plan,
 * the sequences and the manifest) share. */
#ifndef CREASE_DATASET_INTERNAL_H
#define CREASE_DATASET_INTERNAL_H

#include "crease/body.h"
#include "crease/bvh.h"
#include "crease/dataset.h"
#include "crease/garment.h"

enum { CR_DATASET_PATH = 1024 };

typedef enum seq_state { SEQ_PENDING = 0, SEQ_SKIPPED, SEQ_DONE, SEQ_FAILED } seq_state;

typedef struct dataset_seq {
    int g, m, b, r; /* garment, motion, body, resolution indices */
    char id[256];   /* <garment label>_<res>_<body>_<motion> */
    seq_state state;
    double max_inside_share;        /* largest share of a stored frame's vertices inside the body */
    double max_inside_share_solver; /* ... of a substep's, before the simulator's projection */
    double max_penetration_m;
    int64_t max_crossings; /* most crossing triangle pairs on a stored frame (rest excluded) */
    int32_t frames_done;
    double seconds;
    char failure[200];
} dataset_seq;

/* An outfit: garment variants worn over each other, innermost first, merged
 * into one garment per resolution (dataset_outfit.c); nparts 0 for a single
 * garment. */
#define CR_DATASET_OUTFIT_SUBSTEPS 4 /* at least this many per frame for an outfit */
typedef struct dataset_outfit {
    int32_t nparts;
    cr_garment_variant part[CR_GARMENT_OUTFIT_MAX_LAYERS];                        /* as parsed */
    cr_garment_variant built[CR_DATASET_MAX_ITEMS][CR_GARMENT_OUTFIT_MAX_LAYERS]; /* [body] */
    float offset_m[CR_DATASET_MAX_ITEMS][2][CR_GARMENT_OUTFIT_MAX_LAYERS]; /* [body][res]: moved
                                                                              out at build */
} dataset_outfit;

typedef struct dataset {
    cr_dataset_def def;
    cr_garment_type garment_type[CR_DATASET_MAX_ITEMS];
    cr_garment_variant variant[CR_DATASET_MAX_ITEMS]; /* as parsed; .label names files */
    /* [body][garment]: the variant as built on that body (a random draw that
     * fails the checks on one body is replaced there only) */
    cr_garment_variant built[CR_DATASET_MAX_ITEMS][CR_DATASET_MAX_ITEMS];
    dataset_outfit outfit[CR_DATASET_MAX_ITEMS];
    int32_t res_vertices[2];
    char motion_name[CR_DATASET_MAX_ITEMS][64];
    cr_motion *motion[CR_DATASET_MAX_ITEMS];
    cr_motion_prepare_report motion_rep[CR_DATASET_MAX_ITEMS]; /* source rate, frames used */
    cr_body_model *body[CR_DATASET_MAX_ITEMS];
    char body_label[CR_DATASET_MAX_ITEMS][64]; /* names the body's files (cr_dataset_body_label) */
    int user_garment[CR_DATASET_MAX_ITEMS];    /* 1: garments[g] is a mesh file (no variant) */
    float *posed[CR_DATASET_MAX_ITEMS][CR_DATASET_MAX_ITEMS]; /* [body][motion] (T,Vb,3) */
    cr_garment *garment[CR_DATASET_MAX_ITEMS][CR_DATASET_MAX_ITEMS][2]; /* [body][garment][res] */
    /* [body][garment][res]: crossing triangle pairs of the garment as built */
    int64_t rest_crossings[CR_DATASET_MAX_ITEMS][CR_DATASET_MAX_ITEMS][2];
    dataset_seq *seq;
    int nseq;
} dataset;

/* A garment spec: a variant, or an outfit of '+'-joined variants (o->nparts
 * set, *v its first part under the outfit's label). CR_ERR_INVALID naming it. */
cr_status cr_dataset_outfit_parse(const char *spec, dataset_outfit *o, cr_garment_variant *v,
                                  cr_error *err);
/* Build outfit g on body b: ds->garment[b][g][r] for every resolution. */
cr_status cr_dataset_outfit_build(dataset *ds, int b, int g, cr_error *err);
/* Every combination, marked SEQ_SKIPPED where result.json says done. */
cr_status cr_dataset_plan(dataset *ds, cr_error *err);
/* Simulate the pending sequences, several at once; failures are recorded. */
void cr_dataset_run_sequences(dataset *ds);
/* Crossing triangle pairs of mesh m at positions pos (V,3): *bvh is built
 * over them when NULL, else refitted. -1 with err set on failure. */
int64_t cr_dataset_crossings(cr_bvh **bvh, const cr_mesh *m, const float *pos, cr_error *err);
/* manifest.json from the def, the assets and the sequences' states. */
cr_status cr_dataset_write_manifest(const dataset *ds, cr_error *err);

#endif
