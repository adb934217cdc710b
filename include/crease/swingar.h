/* crease/swingar.h: SwinGar's dynamic deformation estimator (paper 002,
 * sec. III-C and IV): one network for many loose garments of any topology.
 *
 *   the estimator: encoders, dynamic skinning, blend and corrective shapes   cr_swingar_*
 *   its losses (eq. 11-14) on one predicted window                          cr_swingar_loss
 *   datasets written by `crease dataset`, split by garment, motion, body     cr_swingar_data_*
 *   training with Adam + cosine decay, the supervised-first rule, resume     cr_swingar_train
 *
 * Information flow for frame t of a garment on a moving body:
 *
 *   g_i  = E_g(n_i, x_i, a_i)          two GAT-LN layers on the rest garment graph
 *   s    = E_a(lambda)                 MLP on the spectral descriptor (z eigenvalues)
 *   m^t  = E_m(theta^(t-m+1..t))       LSTM over the last m poses (axis-angles + rel. trans)
 *   b^t  = E_b(beta, theta^t)          MLP; beta is the body's rest joints
 *   q^t  = E_s(g * m^t)                one GAT-LN layer (element-wise product)
 *   W^t  = softmax_j( log w0_ij + q^t_i . (A s)_j )      dynamic skinning weights
 *   B^t  = L( GAT(GAT(q^t)) * m^t )    unposed blend shapes
 *   M_c^t = LBS(x + B^t; W^t, pose^t)  skinning without the root translation
 *   D^t  = GAT(GAT( LSTM-GAT(M_c^(t-2..t) with joint distances) * b^t ))
 *   M^t  = M_c^t + D^t + trans^t
 *
 * The choices the paper leaves open (and their reasons) are in
 * docs/swingar_model.md; every width, head count and switch is a field of
 * cr_swingar_def. Implemented in src/methods/swingar/{model,train,data}.c.
 */
#ifndef CREASE_SWINGAR_H
#define CREASE_SWINGAR_H

#include "crease/base.h"
#include "crease/mesh.h"
#include "crease/motion.h"
#include "crease/nn.h"
#include "crease/nn_graph.h"
#include "crease/skeleton.h"

struct cr_garment;

struct cr_loss_collider;
struct cr_gravity;

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ the model -- */

typedef struct cr_swingar_def {
    int descriptor_len;   /* z, eigenvalues of the spectral descriptor (default 256) */
    int garment_width[2]; /* E_g GAT-LN widths (default 64, 128) */
    int garment_heads;    /* E_g heads (default 24) */
    int shape_width[3];   /* E_a fully connected widths (default 256, 128, 24) */
    int motion_window;    /* m, poses the motion LSTM reads (default 64) */
    int motion_hidden;    /* E_m output (default 128); must equal garment_width[1] */
    int body_width[3];    /* E_b widths (default 256, 128, 64); [2] must equal corr_hidden */
    int state_width;      /* E_s width (default 128) */
    int state_heads;      /* E_s heads (default 24) */
    int blend_width[2];   /* blend-shape GAT-LN widths (default 256, 128); [1] = motion_hidden */
    int blend_heads;      /* (default 3) */
    int corr_hidden;      /* LSTM-GAT-LN hidden (default 64) */
    int corr_heads;       /* (default 8) */
    int corr_width;       /* first single-head GAT-LN of P_d (default 64; the second is 3) */
    float alpha;          /* GAT-LN score bound, eq. 4 (default 2) */
    cr_gat_norm norm;     /* GAT-LN normaliser (default CR_GAT_NORM_GLOBAL, eq. 4 as written) */
    int skin_prior;       /* 1: skinning logits start from log of the garment's body-transferred
                             weights (default 1; 0: the paper's unbiased softmax) */
    int use_descriptor;   /* 0: E_a sees zeros (Table I's "without the global descriptor") */
    int zero_last;        /* 1: last layers of the blend, skinning and corrective heads start at
                             zero, so an untrained model is the skinned garment (default 1) */
    float corr_scale;     /* m: the corrective head's tanh output times this (default 0.1) */
    int affinity;         /* descriptor affinity: 0 geodesic (default), 1 Euclidean (ablation) */
    uint32_t cookie;      /* set by cr_swingar_default_def */
} cr_swingar_def;

/* The paper's sizes (sec. IV). */
cr_swingar_def cr_swingar_default_def(void);
/* A named size applied to d (a default def): "paper" (unchanged), "cpu"
 * (4 heads in E_g and E_s, for a 2-core machine) or "tiny" (tests). */
cr_status cr_swingar_size_def(const char *size, cr_swingar_def *d, cr_error *err);
/* CR_ERR_INVALID naming the field that is out of range or inconsistent. */
cr_status cr_swingar_def_validate(const cr_swingar_def *def, cr_error *err);
/* The def as a JSON object text (heap, caller frees) and back; unknown keys
 * are refused by name, missing ones keep def's defaults. */
char *cr_swingar_def_to_json(const cr_swingar_def *def);
cr_status cr_swingar_def_from_json(const char *json, const char *source, cr_swingar_def *def,
                                   cr_error *err);

/* A garment as the model sees it, prepared once at its rest pose on its body. */
typedef struct cr_swingar_garment {
    cr_mesh *rest;              /* owned: rest mesh (positions, triangles, normals), m */
    float *features;            /* (V,7): normal, position, fit attribute (signed distance to the
                                   rest body, m) */
    float *descriptor;          /* (z) spectral descriptor */
    float *skin_weight;         /* (V,22) dense prior weights (the garment's four, scattered) */
    int32_t nedges;             /* undirected mesh edges */
    int32_t *edges;             /* (E,2) */
    int32_t *senders;           /* (2E) directed graph for the GAT layers */
    int32_t *receivers;         /* (2E) */
    int32_t nadj;               /* face pairs sharing an edge (normal Laplacian) */
    int32_t *adj;               /* (nadj,2) */
    struct cr_gravity *gravity; /* the gravity energy of the rest mesh (losses.h, eq. 13) */
} cr_swingar_garment;

/* From a rest mesh and its four-joint skinning weights on `body` (whose rest
 * mesh gives the fit attribute). descriptor (z floats) is copied; NULL gives
 * zeros. */
cr_status cr_swingar_garment_create(const cr_mesh *rest, const int32_t *skin_joint,
                                    const float *skin_weight, const cr_body_model *body,
                                    const float *descriptor, int32_t z, cr_swingar_garment **out,
                                    cr_error *err);
void cr_swingar_garment_destroy(cr_swingar_garment *g); /* NULL is a no-op */

/* A body moving through a motion: rest joints, poses and translations. */
typedef struct cr_swingar_motion {
    int32_t nframes;     /* T */
    const float *joints; /* (22,3) rest joints, m */
    const float *poses;  /* (T,22,3) axis-angles, rad */
    const float *trans;  /* (T,3), m */
} cr_swingar_motion;

typedef struct cr_swingar cr_swingar;

/* Parameters go into their own store (cr_swingar_params). */
cr_status cr_swingar_create(const cr_swingar_def *def, uint64_t seed, cr_swingar **out,
                            cr_error *err);
void cr_swingar_destroy(cr_swingar *m); /* NULL is a no-op */
const cr_swingar_def *cr_swingar_get_def(const cr_swingar *m);
cr_nn_params *cr_swingar_params(cr_swingar *m);

/* What a forward can hand back beside the positions (all in the step arena). */
typedef struct cr_swingar_parts {
    cr_tensor *skin;   /* (K,V,22) dynamic skinning weights W^t of the K predicted frames */
    cr_tensor *coarse; /* (K,V,3) M_c^t + trans^t (no corrective shape) */
} cr_swingar_parts;

/* Predict frames [t0, t0 + K) of garment g on motion mo: returns (K,V,3)
 * positions in world space, m, with the gradient to every parameter. Frames
 * before 0 repeat frame 0 (the motion window and the corrective triple).
 * parts may be NULL. NULL on error (recorded on ctx). */
cr_tensor *cr_swingar_forward(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                              const cr_swingar_motion *mo, int32_t t0, int32_t K,
                              cr_swingar_parts *parts);

/* ---------------------------------------------------------------- losses -- */

/* Eq. 11-14. The gravity direction is -Y (crease's up axis is +Y). */
typedef struct cr_swingar_loss_def {
    float k_v, k_e, k_b, k_g, k_c; /* 50, 10, 3, 0.2, 1.5 */
    int supervised_only;           /* 1: the vertex term alone */
    float collision_eps;           /* m, epsilon of eq. 14 (default 0.004) */
} cr_swingar_loss_def;

cr_swingar_loss_def cr_swingar_loss_default_def(void);

typedef struct cr_swingar_loss_terms {
    float vert, edge, bend, gravity, collision; /* weighted, as summed into the loss */
    float vert_err_m;                           /* mean vertex distance, m (not weighted) */
} cr_swingar_loss_terms;

/* pred (K,V,3); gt (K,V,3) host floats; body (K,Vb,3) host floats of the
 * posed body of each frame, and a collider made on that body's triangles
 * (cr_loss_collider_create); both may be NULL when supervised_only or k_c is
 * 0. Returns the scalar loss; terms (may be NULL) gets each weighted term. */
cr_tensor *cr_swingar_loss(cr_nn_ctx *ctx, const cr_swingar_loss_def *def,
                           const cr_swingar_garment *g, cr_tensor *pred, const float *gt,
                           struct cr_loss_collider *collider, const float *body, int32_t body_nv,
                           cr_swingar_loss_terms *terms);

/* ------------------------------------------------------------------ data -- */

typedef struct cr_swingar_sequence {
    char id[160];
    char garment[64], body[64], motion[64];
    int32_t garment_index; /* into cr_swingar_data.garments */
    int32_t body_index;    /* into cr_swingar_data.bodies */
    int32_t nframes;       /* T samples (garment, body and motion agree) */
    float *garment_pos;    /* (T,V,3) simulated garment, m */
    float *body_pos;       /* (T,Vb,3) posed body, m */
    float *poses;          /* (T,22,3) */
    float *trans;          /* (T,3) */
} cr_swingar_sequence;

typedef struct cr_swingar_body {
    char name[64];
    cr_body_model *model; /* rest mesh, joints, skinning */
} cr_swingar_body;

typedef struct cr_swingar_data {
    char dir[512];
    int32_t ngarments, nbodies, nsequences;
    cr_swingar_garment **garments; /* one per (garment, body, res) entry of the manifest */
    char (*garment_key)[160];      /* "<body>/<garment>_<res>" */
    cr_swingar_body *bodies;
    cr_swingar_sequence *sequences; /* only sequences whose status is "done" */
} cr_swingar_data;

/* The spectral descriptor (sec. III-B, src/methods/swingar/descriptor.c) of
 * a rest mesh: z eigenvalues into out. affinity: 0 geodesic (the paper's),
 * 1 Euclidean (Table I's ablation). CR_ERR_RANGE when z exceeds the vertex
 * count. */
cr_status cr_swingar_compute_descriptor(const cr_mesh *mesh, int32_t z, int affinity, float *out,
                                        cr_error *err);

/* Read a dataset folder (manifest.json). Errors name the file. */
/* with_descriptor 0: the garments' descriptors stay zero. */
cr_status cr_swingar_data_load(const char *dir, int32_t z, int with_descriptor, int affinity,
                               cr_swingar_data *out, cr_error *err);
void cr_swingar_data_free(cr_swingar_data *d);

/* Split: a sequence is test when its garment, motion and body are held out
 * on every axis whose list is given (n > 0), train when none of the three is
 * held out, and unused otherwise, so no garment, motion or body is shared.
 * All lists empty: every sequence trains. is_test (nsequences) gets 1 test,
 * 0 train, -1 unused. Names are the manifest's (garment type, motion name,
 * body name). */
void cr_swingar_split(const cr_swingar_data *d, const char *const *garments, int ng,
                      const char *const *motions, int nm, const char *const *bodies, int nb,
                      int8_t *is_test);

/* -------------------------------------------------------------- training -- */

typedef struct cr_swingar_train_def {
    cr_swingar_def model;
    cr_swingar_loss_def loss;
    int epochs;       /* default 10 */
    int window;       /* K frames predicted per sample (default 8) */
    int batch;        /* samples (windows over sequences) per Adam step (default 4) */
    float lr;         /* 1e-3, cosine-annealed to lr_final over all steps */
    float lr_final;   /* default 0 */
    float clip_norm;  /* gradient clipping (default 0: off) */
    int stall_epochs; /* supervised only until the vertex error improves by less than
                         stall_rel over stall_epochs epochs (paper: 2 % over 50; default
                         0: a tenth of the run, at least 2, and at the latest once
                         half the epochs are done) */
    float stall_rel;  /* default 0.02 */
    uint64_t seed;
    size_t arena_bytes;     /* per-step memory (default 1 GiB) */
    const int8_t *is_test;  /* (nsequences) from cr_swingar_split, or NULL: all train */
    const char *checkpoint; /* written every epoch when set */
    const char *resume;     /* checkpoint to continue from, or NULL */
    int stop_after;         /* >0: return after this many epochs of this call (tests) */
    int quiet;
    uint32_t cookie;
} cr_swingar_train_def;

cr_swingar_train_def cr_swingar_train_default_def(void);
/* Its numeric fields as a table: the options of `crease swingar train` with their ranges
 * and help; n gets its length. */
const cr_config_key *cr_swingar_train_def_keys(int *n);

typedef struct cr_swingar_train_result {
    int epochs_done;                 /* total, resumed ones included */
    int switched_epoch;              /* epoch at which all losses were switched on, or -1 */
    float first_loss, last_loss;     /* mean training loss of the first / last epoch */
    float first_vert_m, last_vert_m; /* mean training vertex error, m */
    float test_vert_m;               /* mean vertex error on the test sequences (-1: none) */
    double seconds;
    int64_t params;
} cr_swingar_train_result;

/* Train a model on d, or continue def->resume (whose model def is used
 * instead of def->model); *model gets the trained model, which the caller
 * destroys. def->checkpoint is rewritten after every epoch. */
cr_status cr_swingar_train(const cr_swingar_train_def *def, const cr_swingar_data *d,
                           cr_swingar **model, cr_swingar_train_result *res, cr_error *err);

/* Save the weights and the def (in the checkpoint's config) / load them. */
cr_status cr_swingar_save(const char *path, cr_swingar *m, cr_error *err);
cr_status cr_swingar_load(const char *path, cr_swingar **out, cr_error *err);
/* The def stored in a model or checkpoint, without its weights. */
cr_status cr_swingar_read_def(const char *path, cr_swingar_def *def, cr_error *err);

/* Predict a whole motion (frames 0..T-1) without gradients, frame by frame
 * through the runtime below: out (T,V,3) caller-allocated. arena_bytes 0:
 * sized by trial (cr_swingar_runtime_create). */
cr_status cr_swingar_predict(cr_swingar *m, const cr_swingar_garment *g,
                             const cr_swingar_motion *mo, size_t arena_bytes, float *out,
                             cr_error *err);

/* A fitted garment (cr_garment_load_user, cr_garment_create) on body b
 * animated by motion mo: its descriptor when the model uses one (an error
 * names `source`), its swingar garment, cr_swingar_predict. out (T,V,3)
 * caller-allocated. */
cr_status cr_swingar_animate(cr_swingar *m, const struct cr_garment *garment, const char *source,
                             const cr_body_model *b, const cr_motion *mo, size_t arena_bytes,
                             float *out, cr_error *err);

/* Collision removal with the exact distance to the posed body (eq. 10 on
 * the BVH's signed distance, up to 4 passes; `swingar run`'s default, the
 * neural field of docs/swingar_sdf.md being the paper's): pred (T,V,3) in
 * place, garment its rest mesh (the one-ring of eq. 10), body (T,Vb,3) the
 * posed body_rest. margin, m, is added to every move. */
typedef struct cr_swingar_removal_stats {
    double inside_before, inside_after; /* largest share of vertices inside on a frame */
    int64_t moved;                      /* vertex moves, summed over the frames */
    double seconds;
} cr_swingar_removal_stats;
cr_status cr_swingar_remove_collisions_exact(const cr_mesh *garment, const cr_mesh *body_rest,
                                             const float *body, int32_t T, float margin,
                                             float *pred, cr_swingar_removal_stats *stats,
                                             cr_error *err);

/* `crease swingar run` as one call (src/methods/swingar/run.c). */
typedef struct cr_swingar_run_def {
    const char *model;   /* a trained model (.safetensors); unused with skinned */
    const char *garment; /* any garment mesh (.obj, .ply, .glb; UVs not needed), fitted to the
                            body (cr_garment_load_user) */
    const char *body;    /* cr_body_resolve spec (default "normal") */
    const char *motion;  /* a clip name or a motion file (cr_motion_resolve) */
    cr_motion_resolve_def motion_def; /* clip frames, rate (the glb plays at it), the file's
                                         import and preparation; its body is set here */
    int skinned;                      /* 1: the garment skinned by its own weights (the baseline) */
    int raw;                          /* 1: the network's output as it is, no collision removal */
    const char *out_dir; /* garment.pc2, body.pc2, garment.obj, garment.glb, last.png */
    uint32_t cookie;     /* set by cr_swingar_run_default_def */
} cr_swingar_run_def;
cr_swingar_run_def cr_swingar_run_default_def(void);

typedef struct cr_swingar_run_report {
    int32_t vertices, frames;
    double seconds;                   /* the prediction and removal, not the files */
    int removed;                      /* 1: the exact removal ran (a model, not raw) */
    cr_swingar_removal_stats removal; /* its shares inside the body, before and after */
} cr_swingar_run_report;

/* Fails naming the model, garment, body or motion it could not read. out may
 * be NULL. */
cr_status cr_swingar_run(const cr_swingar_run_def *def, cr_swingar_run_report *out, cr_error *err);

/* `crease swingar measure` (src/methods/swingar/measure.c): trained models, one file
 * per seed of one recipe, on the sequences of a test dataset against its simulated
 * reference through crease eval (every metric; E_dist the paper's), beside the garment
 * skinned by its own weights (the baseline; the share of its error removed) and the twin
 * (a `crease dataset --twin` of the same def: the floor). The prediction is `swingar
 * run`'s: collisions removed (exact distance) unless raw. def->print gets a table per
 * sequence and the summary; out_dir gets table_<sequence>.json (cr_eval_table_json) and
 * summary.json. */
enum { CR_SWINGAR_MEASURE_MAX_SEEDS = 8 };
typedef struct cr_swingar_measure_def {
    const char *const *models; /* model files; 1 to CR_SWINGAR_MEASURE_MAX_SEEDS */
    int nmodels;
    const char *dataset; /* the test dataset (a `crease dataset` folder); required */
    const char *twin;    /* its twin dataset, or NULL */
    /* held-out axes as cr_swingar_split: the sequences measured are the test ones; all
     * empty (default): every sequence of the dataset */
    const char *const *garments, *const *motions, *const *bodies;
    int ngarments, nmotions, nbodies;
    int raw;             /* 1: the network's output as it is (no collision removal) */
    const char *out_dir; /* required */
    FILE *print;         /* the tables as markdown (NULL: none) */
    uint32_t cookie;
} cr_swingar_measure_def;
cr_swingar_measure_def cr_swingar_measure_default_def(void);
typedef struct cr_swingar_measure_report {
    int32_t sequences;
    double model_cm, model_cm_spread; /* E_dist over the sequences: mean, spread over seeds */
    double skinned_cm;                /* the baseline's */
    double removed, removed_spread;   /* share of the baseline's E_dist removed */
    double twin_cm;                   /* NAN without a twin */
    double inside_after;              /* largest share of vertices inside on a frame after the
                                         removal (NAN when raw) */
} cr_swingar_measure_report;
/* rep may be NULL. Fails naming a model, the dataset or a sequence without its twin. */
cr_status cr_swingar_measure(const cr_swingar_measure_def *def, cr_swingar_measure_report *rep,
                             cr_error *err);

/* What a batched prediction measured. */
typedef struct cr_swingar_predict_stats {
    double encode_seconds;   /* the runtime's creation: the garment's encoding (E_g, E_a, the
                                skinning map) and the arena's two trial frames, once */
    size_t arena_peak_bytes; /* the arena's high-water mark: the garment's encoding and the
                                activations of one frame */
} cr_swingar_predict_stats;

/* nseq motions of one garment in one call: one runtime encodes the garment
 * once and steps each sequence in turn (reset between), so memory does not
 * grow with nseq. out[b] (T_b,V,3) caller-allocated; stats may be NULL.
 * cr_swingar_predict is this with nseq 1. */
cr_status cr_swingar_predict_batch(cr_swingar *m, const cr_swingar_garment *g,
                                   const cr_swingar_motion *mos, int32_t nseq, size_t arena_bytes,
                                   float *const *out, cr_swingar_predict_stats *stats,
                                   cr_error *err);

/* ------------------------------------------------------------- runtime -- */

/* Frame by frame, for a game loop or a renderer (src/methods/swingar/runtime.c):
 *
 *   cr_swingar_runtime *rt = NULL;
 *   CR_TRY(cr_swingar_runtime_open("model.safetensors", "dress.obj", "normal", 0, &rt, err));
 *   float *verts = malloc(sizeof(float) * 3 * cr_swingar_runtime_vertices(rt));
 *   for each frame: cr_swingar_runtime_step(rt, pose, root, verts, err);   // (22,3), (3)
 *   cr_swingar_runtime_destroy(rt);
 *
 * A step takes the frame's pose (22 axis-angles in the body's joint order,
 * rad, relative to its rest pose) and root translation (m) and writes the
 * garment's (V,3) world positions, m: the same as cr_swingar_predict of the
 * whole motion, frame for frame. All memory is taken at create (the arena
 * is sized by two trial frames); a step allocates nothing. Instances are
 * independent: each may step on its own thread, also when several share
 * one model (only read). */
typedef struct cr_swingar_runtime cr_swingar_runtime;

/* m, g and rest_joints (22,3) are borrowed (m and g must outlive the
 * runtime; the joints are copied). arena_bytes 0: sized by trial. */
cr_status cr_swingar_runtime_create(cr_swingar *m, const cr_swingar_garment *g,
                                    const float *rest_joints, size_t arena_bytes,
                                    cr_swingar_runtime **out, cr_error *err);
/* From files, owning what it loads: a model (cr_swingar_save), a garment
 * (OBJ, PLY or glb, with or without UVs: cr_garment_load_user) fitted on
 * the body `body_spec` (cr_body_resolve: a preset or an SMPL-family file;
 * NULL: the normal mannequin). Errors name the file. */
cr_status cr_swingar_runtime_open(const char *model_path, const char *garment_path,
                                  const char *body_spec, size_t arena_bytes,
                                  cr_swingar_runtime **out, cr_error *err);
void cr_swingar_runtime_destroy(cr_swingar_runtime *rt); /* NULL is a no-op */
/* Back to before the first frame (the pose history and kept graphs cleared). */
void cr_swingar_runtime_reset(cr_swingar_runtime *rt);
cr_status cr_swingar_runtime_step(cr_swingar_runtime *rt, const float *pose, const float *trans,
                                  float *out, cr_error *err);
/* n characters, one frame each: poses (n,22,3), trans (n,3), out[i] (V_i,3). */
cr_status cr_swingar_runtime_step_batch(cr_swingar_runtime *const *rts, int32_t n,
                                        const float *poses, const float *trans, float *const *out,
                                        cr_error *err);
int32_t cr_swingar_runtime_vertices(const cr_swingar_runtime *rt);
/* The garment's rest mesh (its triangles are the output's). */
const cr_mesh *cr_swingar_runtime_rest(const cr_swingar_runtime *rt);
/* The body an opened runtime fitted the garment on (NULL for a created one). */
const cr_body_model *cr_swingar_runtime_body(const cr_swingar_runtime *rt);
size_t cr_swingar_runtime_arena_bytes(const cr_swingar_runtime *rt);

#ifdef __cplusplus
}
#endif
#endif
