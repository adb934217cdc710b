/* crease/epnet.h: EPNet (paper 004), a self-supervised neural garment
 * simulator with persistent wrinkles: E-Net predicts the garment per frame
 * from the body's pose and motion and the per-hinge rest bending RB, P-Net
 * (message passing on the hinge graph) rolls RB out over the sequence, and
 * the curriculum (Algorithm 1) alternates between them with targets from the
 * perfect-plastic rule (Eq. 4-5). Trained with physics energies only
 * (losses.h); the reference is the project's simulator with plasticity.
 *
 *   cr_epnet_def def = cr_epnet_default_def();
 *   def.garment = "tshirt"; def.cycles = 4; def.out_dir = "model";
 *   cr_epnet_train_report rep;
 *   CR_TRY(cr_epnet_train(&def, &rep, err));            // resumable
 *   cr_epnet_run_def rd = cr_epnet_run_default_def();
 *   rd.model_dir = "model"; rd.motion = "bend"; rd.out_dir = "out";
 *   CR_TRY(cr_epnet_run(&rd, NULL, err));               // PC2, glb, PNGs
 *
 * Shapes: V garment vertices, H interior hinges (cr_topology_build's order),
 * T frames, J = 22 joints. Design and every choice: docs/epnet.md.
 * Implemented in src/methods/epnet/.
 */
#ifndef CREASE_EPNET_H
#define CREASE_EPNET_H

#include "crease/base.h"
#include "crease/mesh.h"
#include "crease/phys_material.h"
#include "crease/topology.h"

#ifdef __cplusplus
extern "C" {
#endif

/* --------------------------------------------------------- plastic rule -- */

/* Eq. 4-5 (the perfect-plastic model, smoothed as the authors' code does):
 * for each frame t and hinge h, the elastic strain over the yield is moved
 * into the rest bending,
 *     d      = theta[t,h] - theta_bar[h] - rb[t-1,h]          (Eq. 4)
 *     rb[t,h] = rb[t-1,h] + gain sign(d) s(sharp (|d| - yield)) max(|d| - yield, 0)   (Eq. 5)
 * with s the logistic sigmoid (sharpness 50 in the authors' code; 0: the
 * plain linear rule). theta (T,H) total angles, rad; theta_bar (H) the rest
 * mesh's angles (NULL: 0); rb0 (H) RB before frame 0 (NULL: 0); rb (T,H) out.
 * Returns the number of (frame, hinge) updates. */
int64_t cr_epnet_plastic_rollout(const float *theta, const float *theta_bar, const float *rb0,
                                 int32_t nframes, int32_t nh, double yield, double gain,
                                 double sharpness, float *rb);

/* The hinge graph (P-Net's): a node per interior hinge of t, a directed edge
 * each way between two hinges whose four vertices share at least one vertex.
 * senders/receivers (E) are malloc'd (free()); edges sorted by receiver then
 * sender. */
cr_status cr_epnet_hinge_graph(const cr_topology *t, int32_t **senders, int32_t **receivers,
                               int64_t *nedges, cr_error *err);

/* The ratchet and drive gating of the proxy inference (cr_epnet_infer), one
 * frame over nh hinges (after the authors' predict_pnet_tf.py). With s the
 * proxy's strain theta - theta_bar (E-Net at RB = 0), a hinge is driven in a
 * frame when |wrap(s - RB)| > drive; P-Net's increment delta is applied only
 * at a hinge driven now and in at least drive_frames of the last drive_window
 * frames (this one included), and only when |delta| >= min_delta; then
 *     c = RB + delta,   RB' = sign(c) max(|RB|, |c|)
 * (sign(0) read as RB's), so |RB| never shrinks and RB' lies between RB and
 * c or keeps RB's size: a rollout's |RB| stays below max(|RB_0|, max |c|). */
typedef struct cr_epnet_ratchet_def {
    double drive;     /* rad (default 0.05) */
    int drive_frames; /* default 3 */
    int drive_window; /* frames, drive_frames..32 (default 5) */
    double min_delta; /* rad: smaller increments are dropped (default 0.005) */
    uint32_t cookie;
} cr_epnet_ratchet_def;
cr_epnet_ratchet_def cr_epnet_ratchet_default_def(void);
/* CR_ERR_INVALID naming the field when d is out of range. */
cr_status cr_epnet_ratchet_check(const cr_epnet_ratchet_def *d, cr_error *err);
/* One frame: strain (H) the proxy's theta - theta_bar, rad; delta (H) P-Net's
 * increments, rad; history (H) each hinge's drive over the last frames as
 * bits (bit 0 this frame; zero before the first frame), updated; rb (H) rad,
 * updated. Returns the number of hinges whose RB changed. O(H), no memory. */
int32_t cr_epnet_ratchet_step(const cr_epnet_ratchet_def *d, const float *strain,
                              const float *delta, int32_t nh, uint32_t *history, float *rb);

/* ------------------------------------------------------------- options -- */

enum { CR_EPNET_MAX_LAYERS = 8, CR_EPNET_MAX_MOTIONS = 16 };

typedef struct cr_epnet_def {
    /* scene */
    const char *garment;        /* garment type (garment.h), default "tshirt", or a garment mesh
                                   file (.obj, .ply, .glb; UVs not needed) fitted to the body
                                   (cr_garment_load_user; garment_vertices then unused); a
                                   model names the file and reads it again when opened */
    int32_t garment_vertices;   /* template target vertex count (default 600; authors ~4-5k) */
    const char *body;           /* a body spec (cr_body_resolve: a mannequin preset, default
                                   "normal", or an SMPL-family FILE.npz[:betas]) */
    const char *const *motions; /* training clips (motion.h names) or files; default the
                                   eight procedural clips walk, squat, twist, dance, jump,
                                   reach, lean, stretch (raise_arms and bend held out) */
    int nmotions;
    int32_t frames; /* frames per training clip (default 60 = 2 s; authors 93 = 3 s) */
    float fps;      /* default 30 (dt 1/30 s, the authors') */
    /* material and losses (the authors' constants, docs/epnet.md) */
    cr_material material; /* epnet preset: density 0.2, Baraff-Witkin stretch 20, shear 2,
                             bending 0.002, collision 4 mm, yield 0.52 rad, gain 1 */
    double w_stretch, w_shear, w_bending, w_gravity, w_collision, w_inertia; /* all 1 */
    double pin_top;   /* m: rest vertices within this of the garment's top are pinned to their
                         skinned positions (the loss's pinning term and the reference's pins):
                         a waistband, which the loss (no friction) cannot hold up otherwise.
                         Default 0 (none); train's default for a skirt or trousers 0.01 */
    double w_pin;     /* pinning weight, J/m^2 per vertex (default 100, the authors') */
    double sharpness; /* Eq. 5 sigmoid sharpness (default 50) */
    /* The authors' paired E-Net terms (model/ncs.py, paired_rest_consistency_loss): E-Net
     * runs a second time at RB = 0 and, on the clip's last frame, with r(x) = theta(x) -
     * theta_bar per hinge (rad, wrapped) and means over all H hinges,
     *     zero rest      w_zero_rest     mean_h r(x_0)^2
     *     rest response  w_rest_response mean_h (r(x_RB) - r(x_0) - RB)^2
     * (RB the input E-Net was given at that frame): the RB-free drape stays smooth and
     * the folds RB asks for appear, relative to it. Defaults 2 and 5 (the authors'
     * configs/epnet_demo.json); 0 turns a term off. Not applied to a baseline. */
    double w_zero_rest, w_rest_response;
    /* Kept without a CLI flag (measured with no effect, docs/notes/epnet_rounds.md), for
     * the authors' recipe: */
    struct {
        int inertia_detach; /* 1: the inertia term's frames t-1, t-2 held fixed (implicit
                               Euler per frame; the authors'); 0: gradients through all
                               three (default 0) */
    } experimental;
    /* E-Net sizes (authors: static 64-128-256-512, dynamic 2x32 + 2x512 + GRU 512,
     * RB 256-128-64, decoder 3x512) */
    int static_widths[CR_EPNET_MAX_LAYERS]; /* default 32, 64 */
    int nstatic;
    int dynamic_width;                  /* default 32 (two layers) */
    int gru_hidden;                     /* default 64 */
    int rb_widths[CR_EPNET_MAX_LAYERS]; /* default 32 */
    int nrb;
    int decoder_width;  /* default 128 */
    int decoder_layers; /* hidden layers (default 2; authors 3) */
    /* P-Net sizes (authors: latent 128, 2x128 MLPs, 3 steps) */
    int pnet_latent;        /* default 16 */
    int pnet_hidden_layers; /* default 1 */
    int pnet_steps;         /* default 3 */
    /* curriculum (authors: 4 cycles, E-Net 100 epochs lr 1e-4, P-Net 50-80 epochs lr 2e-5) */
    int cycles;      /* default 4 */
    int enet_epochs; /* per cycle, default 40 */
    int pnet_epochs; /* per cycle, default 20 */
    int pnet_frames; /* frames drawn per P-Net step (default 4) */
    float enet_lr;   /* default 1e-3 */
    float pnet_lr;   /* default 1e-3 */
    /* P-Net's fit, the authors' (train_pnet_tf.py): inputs the proxy's (E-Net at RB =
     * 0) positions and angles, targets the cycle's RB (Eq. 4-5 on E-Net's angles given
     * its RB), teacher-forced with the target's RB of the frame before plus Gaussian
     * noise, L1, hinges with no target RB weighted pnet_inactive_weight */
    double pnet_rb_noise;        /* rad, standard deviation (default 0.05) */
    double pnet_inactive_weight; /* default 0.03 */
    const char *pnet_val_motion; /* validation clip for early stopping, neither a training
                                    nor an evaluation clip (default "run"; NULL: none) */
    int pnet_patience;           /* P-Net epochs without a better validation loss before
                                    the phase stops, its best weights kept (default 5) */
    int baseline;                /* 1: RB fixed at zero, no P-Net (PBNS/SNUG/NCS) */
    uint64_t seed;               /* default 1 */
    const char *out_dir; /* model folder (checkpoint, config); required for cr_epnet_train */
    int resume;          /* 1: continue from out_dir's checkpoint */
    int quiet;           /* 1: no progress lines */
    uint32_t cookie;
} cr_epnet_def;

cr_epnet_def cr_epnet_default_def(void);
/* The def's whole-number and rate fields as a table: their ranges (checked when a model
 * is made or opened) and the options of `crease epnet train`; n gets its length. */
const cr_config_key *cr_epnet_def_keys(int *n);
/* The material above ("epnet"), derived from the cotton preset. */
void cr_epnet_material(cr_material *out);

/* -------------------------------------------------------- a trained model -- */

typedef struct cr_epnet cr_epnet;

/* Build the scene (body, garment, hinges) and the networks of def, randomly
 * initialised from def->seed. */
cr_status cr_epnet_create(const cr_epnet_def *def, cr_epnet **out, cr_error *err);
void cr_epnet_destroy(cr_epnet *m); /* NULL is a no-op */
/* The garment's rest mesh (borrowed) and sizes. */
const cr_mesh *cr_epnet_garment(const cr_epnet *m);
const cr_mesh *cr_epnet_body(const cr_epnet *m);
int32_t cr_epnet_hinge_count(const cr_epnet *m);
int64_t cr_epnet_param_count(const cr_epnet *m, int pnet);
/* The model's def (garment, sizes, material: yield, gain, sharpness), borrowed;
 * its motions and out_dir are not kept (NULL). */
const cr_epnet_def *cr_epnet_get_def(const cr_epnet *m);

/* Loss terms of one forward pass: the physics terms in J per frame, the paired
 * terms (unitless, rad^2 weighted) of the clip's last frame. */
enum { CR_EPNET_NTERMS = 9 };
extern const char *const cr_epnet_term_names[CR_EPNET_NTERMS];
typedef struct cr_epnet_losses {
    double total;
    double term[CR_EPNET_NTERMS]; /* stretch, shear, bending, gravity, collision, inertia,
                                     pinning, zero_rest, rest_response (each weighted) */
} cr_epnet_losses;

/* A sequence the model runs on: a motion (clip name or file) on a body
 * preset (NULL: the model's), T frames at the model's fps (0: the motion's
 * own length), then hold frames of its last pose. */
typedef struct cr_epnet_seq cr_epnet_seq;
cr_status cr_epnet_seq_create(const cr_epnet *m, const char *motion, const char *body,
                              int32_t frames, int32_t hold, cr_epnet_seq **out, cr_error *err);
void cr_epnet_seq_destroy(cr_epnet_seq *s);
int32_t cr_epnet_seq_frames(const cr_epnet_seq *s);
const float *cr_epnet_seq_body(const cr_epnet_seq *s); /* (T,Vb,3) posed body, m */
/* The rest mesh of the sequence's body (its triangles go with cr_epnet_seq_body). */
const cr_mesh *cr_epnet_seq_body_mesh(const cr_epnet_seq *s);

/* One E-Net training step on s (rb (T,H) rad or NULL: zero) when train is 1,
 * or only the loss when 0. rb[t] is the RB after frame t's update; frame t
 * is given rb[t-1] (frame 0: zero), as at inference, and its bending term's
 * rest is theta_bar + rb[t-1]. With RB, the paired terms take a second
 * decoder pass of the last frame at RB = 0. */
cr_status cr_epnet_enet_step(cr_epnet *m, const cr_epnet_seq *s, const float *rb, int train,
                             cr_epnet_losses *out, cr_error *err);
/* P-Net fit: steps of L1 between the RB P-Net gives from the target's RB of
 * the frame before (plus def.pnet_rb_noise rad of Gaussian noise: teacher
 * forcing) and the target's own, hinges with no target RB weighted
 * def.pnet_inactive_weight, over def.pnet_frames frames drawn from s. pos
 * (T,V,3) and theta (T,H) P-Net's inputs (in training the proxy's: E-Net at
 * RB = 0), rb_target (T,H). Returns the last step's weighted mean L1 per
 * hinge, rad, in *loss. */
cr_status cr_epnet_pnet_fit(cr_epnet *m, const cr_epnet_seq *s, const float *pos,
                            const float *theta, const float *rb_target, int steps, double *loss,
                            cr_error *err);

/* Inference over s: pos (T,V,3) m, theta (T,H) and rb (T,H) rad (each may
 * be NULL), each caller-allocated. Frame t uses RB of frame t-1 in E-Net
 * and P-Net then rolls RB to frame t from E-Net's angles (P-Net's lag of one
 * frame). use_pnet 0: RB stays 0 (the baseline). */
cr_status cr_epnet_rollout(cr_epnet *m, const cr_epnet_seq *s, int use_pnet, float *pos,
                           float *theta, float *rb, cr_error *err);

/* How a trained model runs over a sequence (cr_epnet_infer). */
typedef enum cr_epnet_inference {
    CR_EPNET_PROXY = 0,   /* the authors' open loop (default): E-Net at RB = 0 (the proxy),
                             P-Net over the proxy's angles through the ratchet, then E-Net
                             with that RB; RB never reads angles that RB made */
    CR_EPNET_CLOSED_LOOP, /* cr_epnet_rollout with P-Net: frame t's E-Net with RB_{t-1},
                             P-Net on its angles (the earlier rounds'; for comparison) */
    CR_EPNET_ZERO_RB,     /* E-Net with RB held at 0 (the baseline) */
} cr_epnet_inference;

typedef struct cr_epnet_infer_def {
    cr_epnet_inference mode;      /* default CR_EPNET_PROXY */
    int32_t warmup;               /* frames of E-Net's recurrent state before frame 0, blending the
                                     joints from the rest pose to frame 0's (root held), outputs
                                     dropped; every mode (default 0: see docs/epnet.md) */
    cr_epnet_ratchet_def ratchet; /* the proxy's gating (cr_epnet_ratchet_default_def) */
    uint32_t cookie;
} cr_epnet_infer_def;
cr_epnet_infer_def cr_epnet_infer_default_def(void);

/* The model over s by d's mode: pos (T,V,3) m, theta (T,H) and rb (T,H) rad,
 * each caller-allocated or NULL. rb[t] is the RB after frame t; frame t's
 * E-Net is given rb[t-1] (frame 0: zero) in every mode. Proxy: |rb| never
 * shrinks and stays below the largest |theta_proxy - theta_bar| + 0.2 rad
 * (P-Net's bounded correction) per hinge, however long s is. */
cr_status cr_epnet_infer(cr_epnet *m, const cr_epnet_seq *s, const cr_epnet_infer_def *d,
                         float *pos, float *theta, float *rb, cr_error *err);

/* P-Net alone on given positions pos (T,V,3), m (a reference simulation,
 * say): RB (T,H) rad rolled as in cr_epnet_rollout, frame t's increment from
 * frame t's angles and RB of frame t - 1, with no E-Net. It separates P-Net's
 * error from E-Net's: fed the reference's own angles, P-Net should give the
 * reference's plastic rest. */
cr_status cr_epnet_pnet_replay(cr_epnet *m, const float *pos, int32_t T, float *rb, cr_error *err);

/* The plastic reference: the simulator with perfect plasticity (gain 1,
 * the model's yield and material) on the same garment and body motion,
 * started at the garment's skinned rest. pos (T,V,3), rest (T,H) rad. */
cr_status cr_epnet_reference(const cr_epnet *m, const cr_epnet_seq *s, int plastic, float *pos,
                             float *rest, cr_error *err);

/* The same with the simulator's Coulomb friction against the body set to
 * friction (cr_epnet_reference uses the material's, cotton's 0.3). The
 * training loss has no friction term; friction 0 gives the reference the
 * loss's own physics (docs/epnet.md). */
cr_status cr_epnet_reference_friction(const cr_epnet *m, const cr_epnet_seq *s, int plastic,
                                      double friction, float *pos, float *rest, cr_error *err);

/* Checkpoints: weights, optimisers and the curriculum's position. */
cr_status cr_epnet_save(cr_epnet *m, const char *path, int cycle, int phase, int epoch,
                        cr_error *err);
cr_status cr_epnet_load(cr_epnet *m, const char *path, int *cycle, int *phase, int *epoch,
                        cr_error *err);

/* -------------------------------------------------------------- training -- */

typedef struct cr_epnet_train_report {
    int cycles_done;
    double first_loss, last_loss; /* E-Net loss per frame, J: first and last epoch */
    cr_epnet_losses first, last;
    double pnet_loss;     /* last P-Net epoch's mean fit loss (weighted L1 per hinge), rad */
    double pnet_val_loss; /* and on the validation clip (NaN: none), rad */
    double seconds;
    size_t arena_peak_bytes; /* the tape's high-water mark, bytes */
} cr_epnet_train_report;

/* The curriculum (Algorithm 1) into def->out_dir: enet.safetensors and
 * pnet.safetensors (weights, optimisers and the curriculum's position) and
 * rb_train.npy after every epoch (resumable, bit-exact), model.json (the def),
 * and progress.jsonl (a line per epoch with its loss terms). */
cr_status cr_epnet_train(const cr_epnet_def *def, cr_epnet_train_report *out, cr_error *err);

/* Load a trained model from its folder. */
cr_status cr_epnet_open(const char *model_dir, cr_epnet **out, cr_error *err);
/* A trained model's P-Net on another garment (a type of garment.h, at
 * `vertices`; 0: the model's count): the model's def with the garment
 * replaced, P-Net's weights loaded (its graph network reads per-hinge and
 * per-edge features, so it runs on any hinge graph) and E-Net left at its
 * initialisation (its decoder is per vertex of the training garment). For
 * cr_epnet_pnet_replay on a garment P-Net never saw (the paper's Table 3). */
cr_status cr_epnet_open_pnet(const char *model_dir, const char *garment, int32_t vertices,
                             cr_epnet **out, cr_error *err);

typedef struct cr_epnet_run_def {
    const char *model_dir;    /* required */
    const char *motion;       /* clip name or file; required */
    const char *body;         /* a body spec (cr_body_resolve); NULL: the model's */
    int32_t frames;           /* 0: the motion's own length */
    int32_t hold;             /* frames of its last pose after it (default 0) */
    int baseline;             /* 1: RB held at 0 (infer.mode CR_EPNET_ZERO_RB) */
    cr_epnet_infer_def infer; /* the inference (default: the proxy) */
    const char *out_dir;      /* garment.pc2, garment.glb, garment.png, rb.png, rb.npy */
    uint32_t cookie;
} cr_epnet_run_def;
cr_epnet_run_def cr_epnet_run_default_def(void);

typedef struct cr_epnet_run_report {
    int32_t frames, vertices, hinges;
    double seconds_per_frame;
    double max_abs_rb;        /* rad */
    double min_body_distance; /* smallest signed vertex distance to the body, m */
    int finite;               /* 1: no NaN anywhere */
} cr_epnet_run_report;
cr_status cr_epnet_run(const cr_epnet_run_def *def, cr_epnet_run_report *out, cr_error *err);

/* ------------------------------------------------------------- measure -- */

/* epnet's Table 1 on our data (src/methods/epnet/measure.c; docs/epnet.md
 * "Measuring it"): trained epnets (seeds of one recipe) and zero-RB baselines
 * against the plastic reference simulator and its twin on held-out motions
 * and bodies, through cr_eval_run and cr_eval_table: per case a row per model
 * of the folded share at the end, s/frame and RB realised; the tables (mean
 * and spread over the seeds, the twin row, the first baseline's error removed,
 * the admission) on `print` and as out_dir/table_{epnet,baseline}_<motion>_
 * <body>.json; out_dir/side_by_side_<motion>.png (reference, twin, epnet,
 * baseline at the last frame) for the first case. */
enum { CR_EPNET_MEASURE_MAX_SEEDS = 8 };
typedef struct cr_epnet_measure_def {
    const char *const *models;    /* epnet model folders, seeds of one recipe; required */
    int nmodels;                  /* 1 to CR_EPNET_MEASURE_MAX_SEEDS */
    const char *const *baselines; /* zero-RB folders (the first is the tables' baseline) */
    int nbaselines;               /* 1 to CR_EPNET_MEASURE_MAX_SEEDS */
    const char *const *motions;   /* held-out clips or files (default bend, raise_arms, dodge) */
    int nmotions;
    const char *const *bodies; /* body specs (default normal, slim, heavy) */
    int nbodies;
    int32_t frames;           /* frames of each motion (default 0: its own length) */
    int32_t hold;             /* frames of the last pose after the motion (default 30) */
    double friction;          /* the reference's Coulomb friction (default 0, the loss's) */
    double twin_friction;     /* the twin's change of it (default 0.001) */
    cr_epnet_infer_def infer; /* epnet's inference (default the proxy); baselines at zero RB */
    const char *out_dir;      /* required */
    FILE *print;              /* the tables as markdown (NULL: none) */
    uint32_t cookie;
} cr_epnet_measure_def;
cr_epnet_measure_def cr_epnet_measure_default_def(void);
cr_status cr_epnet_measure(const cr_epnet_measure_def *def, cr_error *err);

/* ------------------------------------------------------------- runtime -- */

/* Frame by frame, for a game loop or a renderer (src/methods/epnet/runtime.c):
 * each step takes the frame's pose (22 axis-angles, rad) and root (3, m) and
 * writes the garment's (V,3) positions, m: what cr_epnet_infer gives on the
 * whole motion, frame for frame (the proxy inference's three passes are
 * causal: E-Net at RB = 0, E-Net with the RB after the frame before, P-Net
 * through the ratchet). All memory is taken at create; a step allocates
 * nothing. The networks run in the model's arena, so a runtime needs its own
 * model to step beside another: cr_epnet_runtime_open loads one per
 * runtime, and those are independent (one per thread). */
typedef struct cr_epnet_runtime cr_epnet_runtime;

/* On model m (borrowed: it must outlive the runtime, and no other runtime or
 * inference may use it meanwhile). body: a body spec (cr_body_resolve) or
 * NULL, the model's. infer: the mode (proxy or zero RB; the closed loop is
 * refused), warm-up and ratchet; NULL: cr_epnet_infer_default_def. */
cr_status cr_epnet_runtime_create(cr_epnet *m, const char *body, const cr_epnet_infer_def *infer,
                                  cr_epnet_runtime **out, cr_error *err);
/* The same on its own copy of the model in model_dir (cr_epnet_open). */
cr_status cr_epnet_runtime_open(const char *model_dir, const char *body,
                                const cr_epnet_infer_def *infer, cr_epnet_runtime **out,
                                cr_error *err);
void cr_epnet_runtime_destroy(cr_epnet_runtime *rt); /* NULL is a no-op */
/* Back to before the first frame: RB, the ratchet's history and the GRU state zeroed. */
void cr_epnet_runtime_reset(cr_epnet_runtime *rt);
cr_status cr_epnet_runtime_step(cr_epnet_runtime *rt, const float *pose, const float *trans,
                                float *out, cr_error *err);
/* n characters, one frame each: poses (n,22,3), trans (n,3), out[i] (V_i,3). */
cr_status cr_epnet_runtime_step_batch(cr_epnet_runtime *const *rts, int32_t n, const float *poses,
                                      const float *trans, float *const *out, cr_error *err);
int32_t cr_epnet_runtime_vertices(const cr_epnet_runtime *rt);
const cr_mesh *cr_epnet_runtime_rest(const cr_epnet_runtime *rt); /* the model's garment */
/* The RB after the last frame (H, rad), in hinge order (cr_topology_build's). */
const float *cr_epnet_runtime_rb(const cr_epnet_runtime *rt);
int32_t cr_epnet_runtime_hinges(const cr_epnet_runtime *rt); /* H */
/* The model it steps (its def's fps is the rate the motion must have). */
const cr_epnet *cr_epnet_runtime_model(const cr_epnet_runtime *rt);

/* Persistence: the share of hinges whose |theta - theta_bar| at frame t
 * exceeds thresh (rad). theta (T,H), theta_bar (H). */
double cr_epnet_fold_share(const float *theta, const float *theta_bar, int32_t t, int32_t nh,
                           double thresh);
/* How much of its RB input E-Net realises in one frame: sum_h sign(RB_h)
 * (theta_h - theta0_h) / sum_h |RB_h| over the hinges with |RB_h| > thresh,
 * where theta (H) are E-Net's angles given RB (H, relative to the rest
 * angles) and theta0 the same E-Net's given RB = 0. 1: E-Net bends every such
 * hinge by its RB; 0: RB does not move it. NaN when no hinge passes thresh. */
double cr_epnet_rb_realised(const float *theta, const float *theta0, const float *rb, int32_t nh,
                            double thresh);
/* Dihedral angles theta (T,H), rad, of positions pos (T,V,3), m. */
void cr_epnet_angles(const cr_epnet *m, const float *pos, int32_t T, float *theta);
/* The rest mesh's angles theta_bar (H), borrowed. */
const float *cr_epnet_rest_angles(const cr_epnet *m);

#ifdef __cplusplus
}
#endif
#endif
