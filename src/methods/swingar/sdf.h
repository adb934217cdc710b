/* methods/swingar/sdf.h: SwinGar's neural collision removal (paper 002,
 * sec. III-D, eq. 7-10, and sec. IV "collision handling model"): a body SDF
 * network conditioned on body shape and pose, its training on exact signed
 * distances from the BVH, and the removal of garment-body penetrations with
 * it (or with the exact BVH distance, for comparison).
 *
 *   cr_swingar_sdf_train_def td = cr_swingar_sdf_train_default_def();
 *   td.motions = "walk,dance";  td.shapes = "normal";  td.steps = 2000;
 *   td.checkpoint = "sdf.safetensors";
 *   cr_swingar_sdf *net = NULL;  cr_swingar_sdf_train_result tr;
 *   CR_TRY(cr_swingar_sdf_train(&td, &net, &tr, err));
 *   float cond[CR_SWINGAR_SDF_COND_MAX];
 *   cr_swingar_sdf_condition(&mannequin_def, body->joints, pose, cond);
 *   cr_swingar_sdf_source src;  cr_swingar_sdf_neural_source nsrc;
 *   cr_swingar_sdf_source_neural(net, cond, trans, &nsrc, &src);
 *   cr_swingar_collide_def cd = cr_swingar_collide_default_def();
 *   CR_TRY(cr_swingar_collision_remove(&cd, garment_pos, topo, &src, &stats, err));
 *
 * Sign convention: S < 0 inside the body, S > 0 outside, grad S the outward
 * normal on the surface (the BVH's convention, bvh.h). The paper writes
 * "positive inside" for eq. 7 but then asks grad S to match the normal n_i
 * (eq. 8) and moves a colliding vertex along +grad S (eq. 10); with outward
 * normals the three agree only for S negative inside, which is what we use:
 * a vertex collides when S(x) < 0 and moves by grad S / |grad S| (|S| + delta).
 *
 * Network (sec. IV): eight fully connected layers of width W (512), Softplus
 * with beta 100 after every layer but the last:
 *   position branch  p1 = sp(L1 x~), p2 = sp(L2 p1), p3 = sp(L3 p2) + p1
 *   body branch      q1 = sp(K1 c),  q2 = sp(K2 q1), q3 = sp(K3 q2) + q1
 *   fusion           f  = sp(F1 [p3, q3]),  S = scale * F2 f
 * with x~ = (x - center) / scale the body-frame position normalised to about
 * [-1, 1] (S and grad S come back in metres: the scaling cancels in the
 * gradient). "Each branch incorporates a residual connection that links the
 * output of the first layer to the layer preceding the fusion": the skip
 * from layer 1 to layer 3 of each branch. F1 is stored as two W x W blocks,
 * "fuse.0.weight_p" and "fuse.0.weight_q", so the body half (one row per
 * pose) is computed once per frame instead of once per vertex.
 *
 * Conditioning c (CR_SWINGAR_SDF_COND_DIM = 70): the mannequin's four shape
 * scalars as offsets from the `normal` body (height_m - 1.75, girth - 1,
 * chest - 1, hips - 1), then the 22 joint axis-angles (66, rad, SMPL order,
 * joint 0 the global orientation). The root translation is not an input: it
 * is subtracted from the positions first, as the paper removes body
 * translations before collision handling.
 *
 * Articulated input (def.articulated = 1, not the paper's): the first
 * position layer takes, instead of x~, the 22 rest-pose points u_j = M_j x +
 * m_j (normalised as x~), one per joint, from the pose's forward kinematics
 * (the inverse of each joint's skinning transform), as NASA/LEAP-style
 * articulated shapes do: most of the pose dependence becomes a known rigid
 * map and the net learns the rest shape plus a pose-conditioned residual (the
 * body branch stays). articulated = 2 weights each joint's u_j by w_j =
 * softmax_j(-|u~_j - c~_j|^2 / tau), c_j the bone's rest centre (the joint
 * and the mean of its children, halfway), tau in normalised units squared, and feeds [w_j u~_j,
 * w_j] (88 numbers): a soft assignment of the point to the nearest bones, as LEAP's learned inverse
 * skinning weights do, so each region reads its own bone's frame; the
 * gradient goes through the weights too. The frames ride in each conditioning row after the
 * cond_dim numbers: rows are cond_dim + CR_SWINGAR_SDF_FRAME_DIM long. They
 * are constants on the tape (no gradient reaches them).
 *
 * Ownership: a cr_swingar_sdf owns its parameter store and an evaluation
 * context; evaluation is not reentrant on one model (one thread at a time).
 */
#ifndef CREASE_METHODS_SWINGAR_SDF_H
#define CREASE_METHODS_SWINGAR_SDF_H

#include "crease/body.h"
#include "crease/nn.h"
#include "crease/topology.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    CR_SWINGAR_SDF_SHAPE_DIM = 4,
    CR_SWINGAR_SDF_COND_DIM = 4 + 3 * CR_NJOINTS,
    /* per joint [M | m] (3,4) row-major, u_j = M x + m taking a body-frame
     * point to where it sits in the rest pose if it moves rigidly with joint
     * j, then the bone's rest centre (3, m) */
    CR_SWINGAR_SDF_JOINT_REC = 15,
    CR_SWINGAR_SDF_FRAME_DIM = CR_SWINGAR_SDF_JOINT_REC * CR_NJOINTS,
    /* a full conditioning record: c, then the joint frames */
    CR_SWINGAR_SDF_COND_MAX = CR_SWINGAR_SDF_COND_DIM + CR_SWINGAR_SDF_FRAME_DIM
};

/* ------------------------------------------------------------- network -- */

typedef struct cr_swingar_sdf_def {
    int width;           /* W, hidden width of all eight layers, >= 2 (default 512, the paper's) */
    int cond_dim;        /* C, conditioning size (default CR_SWINGAR_SDF_COND_DIM; 0: no body
                            branch, a single shape such as the tests' sphere) */
    float softplus_beta; /* default 100 (the paper's "internal parameter") */
    float center[3];     /* input normalisation, m: x~ = (x - center) / scale */
    float scale;         /* m, > 0 (default 1) */
    /* Geometric initialisation (Atzmon & Lipman, SAL, 2020): the untrained
     * net approximates the SDF of a sphere of this radius (in normalised
     * units) around `center` (default 0.5). */
    float init_radius;
    int articulated; /* 0 (default, the paper's), 1 or 2: joint-frame inputs (above) */
    float tau;       /* bone-weight temperature of articulated = 2 (default 0.1) */
    uint64_t seed;   /* weight initialisation (default 1) */
    uint32_t cookie; /* set by cr_swingar_sdf_default_def */
} cr_swingar_sdf_def;

cr_swingar_sdf_def cr_swingar_sdf_default_def(void);

typedef struct cr_swingar_sdf cr_swingar_sdf;

/* CR_ERR_INVALID naming the field for an out-of-range def. */
cr_status cr_swingar_sdf_create(const cr_swingar_sdf_def *def, cr_swingar_sdf **out, cr_error *err);
void cr_swingar_sdf_destroy(cr_swingar_sdf *net); /* NULL is a no-op */
const cr_swingar_sdf_def *cr_swingar_sdf_get_def(const cr_swingar_sdf *net);
cr_nn_params *cr_swingar_sdf_params(cr_swingar_sdf *net);

/* Numbers per conditioning row the model reads: cond_dim, plus
 * CR_SWINGAR_SDF_FRAME_DIM when articulated. */
int cr_swingar_sdf_cond_len(const cr_swingar_sdf_def *def);

/* The conditioning record (CR_SWINGAR_SDF_COND_MAX) of a mannequin shape
 * (NULL: the normal body) and a pose (22,3) axis-angles, rad (NULL: rest):
 * c, then the joint frames from the rest joints `joints` (22,3), m, of that
 * body (NULL: identity frames, right for the rest pose only). */
void cr_swingar_sdf_condition(const cr_mannequin_def *shape, const float *joints, const float *pose,
                              float *cond);

/* On the tape: S (N,1) at body-frame positions x (N,3), m, for the per-row
 * conditioning cond (P,L), L = cr_swingar_sdf_cond_len (NULL when that is 0) with cond_row (N)
 * int32 in [0,P) naming each point's row (NULL: every point uses row 0). When grad is not NULL it
 * receives grad_x S (N,3,1), built by forward-mode tangents from differentiable ops (the engine's
 * layer_jacobian.c scheme, applied to the two-branch net), so losses on it reach the weights. NULL
 * on error (the context's error). */
cr_tensor *cr_swingar_sdf_forward(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *x,
                                  cr_tensor *cond, const int32_t *cond_row, cr_tensor **grad);

/* Host evaluation, in chunks, without a tape: s (N) and, when grad is not
 * NULL, grad S (N,3) at x (N,3), m, for one conditioning row cond
 * (cr_swingar_sdf_cond_len numbers; NULL when that is 0). */
cr_status cr_swingar_sdf_eval(cr_swingar_sdf *net, const float *x, int64_t n, const float *cond,
                              float *s, float *grad, cr_error *err);

/* Eq. 8-9 on the tape: mean_i (|S_i - s_i| + |grad S_i - n_i|) + mu_e mean_i
 * (|grad S_i| - 1)^2 over N points with targets s (N,1) and n (N,3) (the
 * exact signed distance and its gradient, the outward normal at the closest
 * point). The three parts (value, normal, eikonal) go to parts[3] (may be
 * NULL) as tensors on the tape. */
cr_tensor *cr_swingar_sdf_loss(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *x,
                               cr_tensor *cond, const int32_t *cond_row, cr_tensor *s_target,
                               cr_tensor *n_target, float mu_e, cr_tensor *parts[3]);

/* Weights (and the def, as metadata) to a safetensors file, atomically;
 * load makes a model from such a file. */
cr_status cr_swingar_sdf_save(cr_swingar_sdf *net, const char *path, cr_error *err);
cr_status cr_swingar_sdf_load(const char *path, cr_swingar_sdf **out, cr_error *err);
/* The def as a JSON object string (heap, caller frees) and back. */
char *cr_swingar_sdf_def_json(const cr_swingar_sdf_def *def);
cr_status cr_swingar_sdf_def_from_json(const char *json, const char *source,
                                       cr_swingar_sdf_def *def, cr_error *err);

/* ------------------------------------------------------------ training -- */

typedef struct cr_swingar_sdf_train_def {
    cr_swingar_sdf_def model; /* center and scale are set from the data's bounds */
    const char *motions;      /* comma-separated clip names or motion files (default "walk") */
    const char *shapes;       /* comma-separated mannequin presets (default "normal") */
    int32_t body_resolution;  /* mannequin grid resolution (default 110, ~9.5k vertices) */
    int32_t clip_frames;      /* frames of each procedural clip at 30 fps (default 90) */
    int32_t frame_stride;     /* train on every k-th frame (default 6) */
    /* Samples per training pose: on the surface (with the face normal), near
     * it (surface + N(0, near_sigma) per axis) and uniform in the padded
     * bounding box. */
    int32_t samples_surface;  /* default 4000 */
    int32_t samples_near;     /* default 4000 */
    int32_t samples_space;    /* default 1000 */
    float near_sigma;         /* m (default 0.02) */
    float space_pad;          /* m, box padding (default 0.15) */
    int64_t steps;            /* Adam steps, the cosine schedule's length (default 2000) */
    int64_t stop_at;          /* stop once this many steps are done (0: run to steps); a later
                                 resume continues the same schedule */
    int32_t batch;            /* points per step (default 2048) */
    float lr;                 /* Adam, cosine-decayed to lr_final over the steps (default 1e-3) */
    float lr_final;           /* default 1e-5 */
    float mu_e;               /* eikonal weight, eq. 8 (default 0.15, the paper's) */
    uint64_t seed;            /* samples and batches (default 1) */
    const char *checkpoint;   /* resumable checkpoint path, or NULL */
    int64_t checkpoint_every; /* steps (default 200; 0: only at the end) */
    int resume;               /* 1: continue from `checkpoint` when it exists */
    int quiet;                /* no progress bar */
    uint32_t cookie;          /* set by cr_swingar_sdf_train_default_def */
} cr_swingar_sdf_train_def;

cr_swingar_sdf_train_def cr_swingar_sdf_train_default_def(void);
/* Its whole-number and rate fields as a table: the options of `crease swingar-sdf train`
 * with their ranges and help; n gets its length. */
const cr_config_key *cr_swingar_sdf_train_def_keys(int *n);

typedef struct cr_swingar_sdf_train_result {
    int64_t steps;                      /* steps done in total (resumed ones included) */
    int64_t resumed_from;               /* step the run started at */
    int64_t poses;                      /* training poses */
    int64_t samples;                    /* training points */
    double seconds;                     /* training time of this run */
    float loss, value, normal, eikonal; /* last step's loss and its parts */
} cr_swingar_sdf_train_result;

/* Build the training poses (mannequin shapes x motions, every frame_stride-th
 * frame, translation removed), sample points with their exact signed
 * distances and gradients from a BVH of each posed body, and train with Adam
 * on eq. 8-9. *out gets the model (caller destroys). With a checkpoint path
 * the weights, Adam's moments, the step and the RNG are saved every
 * checkpoint_every steps and at the end; resuming continues bit-exactly. */
cr_status cr_swingar_sdf_train(const cr_swingar_sdf_train_def *def, cr_swingar_sdf **out,
                               cr_swingar_sdf_train_result *res, cr_error *err);

/* Motions named by a comma-separated list (at most 32): procedural clip
 * names (clip_frames frames at 30 fps) or motion files (a name with '.' or
 * '/', cr_motion_load). *out (count) and each motion belong to the caller:
 * cr_swingar_sdf_motions_free. */
cr_status cr_swingar_sdf_motions_load(const char *list, int32_t clip_frames, cr_motion ***out,
                                      int *count, cr_error *err);
void cr_swingar_sdf_motions_free(cr_motion **m, int count);

/* ------------------------------------------------- collision removal -- */

/* A signed distance field: fills s (N) at x (N,3), m, and, when grad is not
 * NULL, grad (N,3) (any length; it is normalised). Negative inside. */
typedef cr_status (*cr_swingar_sdf_fn)(void *user, const float *x, int64_t n, float *s, float *grad,
                                       cr_error *err);
typedef struct cr_swingar_sdf_source {
    cr_swingar_sdf_fn eval;
    void *user;
} cr_swingar_sdf_source;

/* The neural field for one pose: positions are taken in world space and
 * `trans` (3, m; NULL: zero) subtracted before the network. */
typedef struct cr_swingar_sdf_neural_source {
    cr_swingar_sdf *net;
    float cond[CR_SWINGAR_SDF_COND_MAX];
    float trans[3];
} cr_swingar_sdf_neural_source;
void cr_swingar_sdf_source_neural(cr_swingar_sdf *net, const float *cond, const float *trans,
                                  cr_swingar_sdf_neural_source *user, cr_swingar_sdf_source *out);

/* The exact field of a posed body's BVH: bvh.h's signed distance within
 * max_dist (farther points read +max_dist, outside), the direction to the
 * closest point as gradient. */
typedef struct cr_swingar_sdf_bvh_source {
    const struct cr_bvh *bvh;
    float max_dist; /* m; INFINITY: exact everywhere */
} cr_swingar_sdf_bvh_source;
void cr_swingar_sdf_source_bvh(const struct cr_bvh *bvh, float max_dist,
                               cr_swingar_sdf_bvh_source *user, cr_swingar_sdf_source *out);

typedef struct cr_swingar_collide_def {
    /* delta_i of eq. 10: the Gaussian-weighted mean of |S| over the
     * non-colliding one-ring neighbours k of i, weights
     * exp(-|x_i - x_k|^2 / (2 sigma_i^2)) normalised to sum 1, sigma_i =
     * sigma_scale x the mean length of i's one-ring edges; 0 when every
     * neighbour collides. */
    float sigma_scale;  /* default 1 */
    float delta_weight; /* multiplies delta_i (default 1; 0: move to the surface only) */
    float margin;       /* m, added to every move (default 0, the paper has none) */
    /* eq. 10 applied this many times, S evaluated afresh each time (default
     * 1, the paper's; stops early once nothing collides) */
    int passes;
    /* m: eq. 10 on the field S - offset (default 0, the paper's): a vertex
     * within offset of the body counts as colliding and moves out to it. Set
     * to about the field's error near the body, it catches the shallow
     * collisions an inexact field reads as just outside. */
    float offset;
    uint32_t cookie; /* set by cr_swingar_collide_default_def */
} cr_swingar_collide_def;

cr_swingar_collide_def cr_swingar_collide_default_def(void);

typedef struct cr_swingar_collide_stats {
    int64_t colliding;     /* vertices with S < 0 before */
    double mean_move_m;    /* mean displacement of the moved vertices */
    double max_move_m;     /* largest displacement */
    double mean_delta_m;   /* mean delta_i */
    double seconds_detect; /* S at every vertex */
    double seconds_move;   /* gradients and moves of the colliding ones */
} cr_swingar_collide_stats;

/* Eq. 10 on garment positions pos (V,3), m, in place: every vertex with S < 0
 * moves by grad S / |grad S| (|S| + delta_weight delta_i + margin). delta_i
 * uses S before any move (the paper's "state of the non-collision
 * neighbouring vertices"). topo gives the one-ring (cr_topology_build of the
 * garment; topo->nv must equal V). stats may be NULL. */
cr_status cr_swingar_collision_remove(const cr_swingar_collide_def *def, float *pos,
                                      const cr_topology *topo, const cr_swingar_sdf_source *src,
                                      cr_swingar_collide_stats *stats, cr_error *err);

/* ---------------------------------------------------------- measuring -- */

/* How well and how fast the neural field stands in for the exact one, on
 * held-out frames: the SDF error near the body, and eq. 10 with both fields
 * on a garment skinned to each frame (cr_garment_pose), judged by the exact
 * BVH distance. */
typedef struct cr_swingar_sdf_measure_def {
    const char *motions;      /* comma-separated clips or files (default "walk") */
    const char *shape;        /* mannequin preset (default "normal") */
    int32_t body_resolution;  /* default 110, as training */
    int32_t clip_frames;      /* default 90, as training */
    int32_t first_frame;      /* default 3: between training's every-6th frames */
    int32_t frame_stride;     /* default 6 */
    int32_t max_frames;       /* per motion (default 15) */
    int garment;              /* cr_garment_type (default CR_GARMENT_TSHIRT) */
    int32_t garment_vertices; /* default 10000 */
    /* The garment is skinned to the pose garment_lag frames earlier than the
     * body's (default 4, 0.13 s at 30 fps): skinned to the same pose it never
     * enters the body, and a lagging garment stands in for a prediction whose
     * cloth trails the limbs (where a network's collisions come from). */
    int32_t garment_lag;
    float band_m;         /* error band: points with |s| < band_m (default 0.02) */
    int32_t band_samples; /* points drawn near the surface per frame (default 4000) */
    /* A recorded sequence instead of the skinned garment (all four or none;
     * default NULL): the garment's and the body's OBJ meshes and PC2 frames,
     * world space, frame f posed by frame f of the single motion in
     * `motions` on the mannequin `shape` (which gives the conditioning). The
     * garment options and garment_lag are then unused. */
    const char *garment_pc2, *garment_mesh, *body_pc2, *body_mesh;
    cr_swingar_collide_def collide;
    uint64_t seed;   /* default 1 */
    uint32_t cookie; /* set by cr_swingar_sdf_measure_default_def */
} cr_swingar_sdf_measure_def;

cr_swingar_sdf_measure_def cr_swingar_sdf_measure_default_def(void);

typedef struct cr_swingar_sdf_measure_result {
    int64_t frames, body_vertices, garment_vertices;
    int64_t band_points;            /* points within the band, all frames */
    double err_mean_mm, err_max_mm; /* |S - s| over them */
    double err_p99_mm;
    double sign_agree;          /* share of band points with the right sign */
    double garment_err_mean_mm; /* |S - s| at garment vertices within the band */
    double garment_err_max_mm;
    double ratio_before, ratio_neural, ratio_exact; /* % garment vertices inside (exact s < 0) */
    double missed;       /* share of exactly-inside vertices the net did not flag */
    double false_alarms; /* vertices the net flagged that were outside, per frame */
    /* medians over frames, ms */
    double ms_neural, ms_neural_detect, ms_exact, ms_exact_detect, ms_bvh_refit;
    double mean_move_neural_mm, mean_move_exact_mm; /* over the moved vertices */
    double moved_neural, moved_exact; /* % garment vertices each removal moved (first pass) */
} cr_swingar_sdf_measure_result;

cr_status cr_swingar_sdf_measure(const cr_swingar_sdf_measure_def *def, cr_swingar_sdf *net,
                                 cr_swingar_sdf_measure_result *res, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
