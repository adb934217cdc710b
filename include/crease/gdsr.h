/* crease/gdsr.h: garment dynamic super-resolution (GDSR, paper 001): a
 * low-resolution garment simulation C and the body go in, a high-resolution
 * garment with fine wrinkles comes out, frame after frame, feeding its own
 * previous correction back as an input.
 *
 *   load a low/high pair and clips from a `crease dataset` folder   cr_gdsr_data_load
 *   graph features of Eq. 2-5 for one frame                        cr_gdsr_features
 *   the model: Mesh-Graph-Net H, decoder E, Mesh-Hyper-Net A       cr_gdsr_model_*
 *   training (Eq. 13-25 subset), resumable checkpoints             cr_gdsr_train
 *   roll-out on a clip, collision handling (Eq. 26-27), baselines  cr_gdsr_rollout
 *   frame by frame for a game loop or a renderer                   cr_gdsr_runtime_*
 *
 * Pipeline per frame t (docs/gdsr.md):
 *   H:  node features (Eq. 4) and edge features (Eq. 5) on the low mesh
 *       over 1-ring and 2-ring edge sets -> per-vertex features split
 *       decoder_features / hyper_features (paper: 128 / 512)
 *   E:  per low triangle, displacements of its 3 corners in the triangle's
 *       local frame of C_t (Eq. 8), averaged per vertex (Eq. 9): C^ = C + d
 *   A:  per low triangle, the weights of a complex WIRE MLP from its three
 *       vertices' hyper features (Eq. 10), evaluated at each high vertex's
 *       barycentric coordinates (Eq. 11) for a residual in the triangle's
 *       frame of C^ (Eq. 12), added to the barycentric upsampling of C^.
 *
 * Units: m. Deterministic for a seed. The library prints nothing.
 */
#ifndef CREASE_GDSR_H
#define CREASE_GDSR_H

#include "crease/mesh.h"
#include "crease/nn.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- data -- */

/* One garment on one body at two resolutions, plus clips. */
typedef struct cr_gdsr_clip {
    char motion[64];
    int32_t nframes; /* T samples (the dataset's frames + 1) */
    float *low;      /* (T,Vl,3) low-resolution simulation C */
    float *high;     /* (T,Vh,3) high-resolution simulation (reference); NULL when the
                        dataset has none for the motion (roll-out only) */
    float *body;     /* (T,Vb,3) posed body */
} cr_gdsr_clip;

enum { CR_GDSR_MAX_CLIPS = 16 };

typedef struct cr_gdsr_data {
    cr_mesh *low, *high, *body; /* rest meshes (low and high with UVs) */
    int32_t *face;              /* (Vh) low face under each high vertex (Eq. 1) */
    float *bary;                /* (Vh,3) its barycentric weights */
    int32_t *coarse_face;       /* (Vl) high face under each low vertex through the UVs */
    float *coarse_bary;         /* (Vl,3) its barycentric weights: the ground-truth coarse
                                   shape C* = cr_gdsr_coarse_target(high simulation) */
    int32_t *layer;             /* (Vl) each low vertex's garment layer (cr_gdsr_mesh_layers) */
    int32_t nlayers;            /* 1 for a single-layer garment */
    int32_t nclips;
    cr_gdsr_clip clip[CR_GDSR_MAX_CLIPS];
} cr_gdsr_data;

/* Read, as the dataset's manifest.json lists them (cr_dataset_read), the low
 * and high garment of the label `garment` on `body`, their correspondence
 * (high_from_low), the body's rest mesh and, per motion, the low sequence,
 * the high one when it is finished (else clip.high is NULL: a low-only
 * input) and the posed body. nmotions 0: the pair and the body alone, no
 * clips (what a runtime needs, cr_gdsr_runtime_open). CR_ERR_IO naming the
 * manifest and what it lacks; the readers' errors naming a file. */
cr_status cr_gdsr_data_load(const char *dir, const char *garment, const char *body,
                            const char *const *motions, int nmotions, cr_gdsr_data *out,
                            cr_error *err);
/* The dataset's motions with a finished low and high sequence of `garment`
 * on `body`, in the manifest's order, leaving out those in skip (nskip): what
 * `gdsr train` trains on when no --motions are given. Returns how many were
 * written to names (at most max), or -1 with err set (none, or more than max). */
int cr_gdsr_dataset_motions(const char *dir, const char *garment, const char *body,
                            const char *const *skip, int nskip, char (*names)[64], int max,
                            cr_error *err);
/* Build data from meshes and arrays in memory (tests): copies everything;
 * the correspondence is computed through UVs (cr_garment_correspondence). */
cr_status cr_gdsr_data_from_arrays(const cr_mesh *low, const cr_mesh *high, const cr_mesh *body,
                                   int32_t nframes, const float *low_frames,
                                   const float *high_frames, const float *body_frames,
                                   cr_gdsr_data *out, cr_error *err);
void cr_gdsr_data_free(cr_gdsr_data *d); /* zeroes it; a zeroed struct is a no-op */

/* The low-resolution input simulated from a motion (`gdsr run --simulate`):
 * a `crease dataset` of one garment on one body and one motion is made in
 * out_dir by cr_dataset_generate (the same garment templates, body, motion
 * preparation and simulator as the training data), with the garment at
 * both resolutions and the low/high correspondence; only the low
 * resolution is simulated unless `reference` is set. */
typedef struct cr_gdsr_sim_def {
    const char *out_dir; /* the one-sequence dataset (required) */
    const char *garment; /* a garment type or variant spec (dataset.h; default "tshirt") */
    const char *body;    /* mannequin preset (default "normal") */
    const char *motion;  /* a clip name or a motion file (.npz, .bvh) (required) */
    const char *like;    /* NULL, or a dataset folder (the model's training data) whose
                            manifest.json gives low_vertices, high_vertices, fps and
                            material unless set below */
    int32_t low_vertices, high_vertices; /* 0: like's, else the dataset defaults */
    int32_t frames;                      /* simulated frames (default 60) */
    float fps;                           /* 0: like's, else 30 */
    const char *material;                /* NULL: like's, else "cotton" */
    int reference;                       /* 1: the high resolution too (a reference) */
    int quiet;
    const struct cr_motion_import_def *motion_import;   /* NULL: the dataset's defaults */
    const struct cr_motion_prepare_def *motion_prepare; /* NULL: the dataset's defaults */
} cr_gdsr_sim_def;

cr_gdsr_sim_def cr_gdsr_sim_default_def(void);

typedef struct cr_gdsr_sim_result {
    char garment[128]; /* the garment's label (its files' name in out_dir) */
    char motion[64];   /* the motion's label (a file's base name) */
    int32_t low_vertices, high_vertices;
    double seconds;          /* the dataset run, set-up included */
    double max_inside_share; /* the low garment's largest share inside the body */
} cr_gdsr_sim_result;

/* Simulate, then load the result as data with one clip (high NULL without
 * `reference`). CR_ERR_INVALID naming a bad field, a failed sequence with
 * the simulator's reason; like's manifest errors name the file. */
cr_status cr_gdsr_simulate(const cr_gdsr_sim_def *def, cr_gdsr_data *out, cr_gdsr_sim_result *res,
                           cr_error *err);

/* C*: the high positions high_pos (Vh,3) sampled at each low vertex's
 * point on the high mesh (coarse_face, coarse_bary): out (Vl,3). */
void cr_gdsr_coarse_target(const cr_gdsr_data *d, const float *high_pos, float *out);

/* Barycentric upsampling (Eq. 1 applied to low positions (Vl,3)): out (Vh,3). */
void cr_gdsr_upsample(const cr_gdsr_data *d, const float *low_pos, float *out);

/* --------------------------------------------------------- features -- */

enum { CR_GDSR_NODE_FEATURES = 19, CR_GDSR_EDGE_FEATURES = 8 };

/* The low mesh's graph: set 0 the 1-ring edges (both directions), set 1 the
 * 2-ring edges (vertex pairs at graph distance exactly 2, both directions),
 * both fixed; set 2 the layer edges of one frame (cr_gdsr_layer_edges; empty
 * after cr_gdsr_graph_build). Edge e of set s: message from snd[s][e] to
 * rcv[s][e]. */
typedef struct cr_gdsr_graph {
    int32_t nv;
    int64_t ne[3];
    int32_t *snd[3], *rcv[3];
    int64_t cap2; /* set 2's allocated edges */
} cr_gdsr_graph;

cr_status cr_gdsr_graph_build(const cr_mesh *low, cr_gdsr_graph *out, cr_error *err);
void cr_gdsr_graph_free(cr_gdsr_graph *g);

/* The layers of a garment (outfit) mesh: its connected components, numbered
 * from 0 in the order of their lowest vertex; layer (V). Returns how many.
 * (Two garments worn one over the other are two components; the paper's
 * double-layered dress, sewn at the waist, would need the layer given.) */
int32_t cr_gdsr_mesh_layers(const cr_mesh *m, int32_t *layer);

/* Layer edges (section 4.1): every pair of low vertices i, l on different
 * layers with |c_i - c_l| < sigma_l at positions c (Vl,3), both directions,
 * into set 2 of g, ordered by receiver then sender (a uniform grid of cell
 * sigma_l finds them). layer NULL or one layer: none. */
cr_status cr_gdsr_layer_edges(cr_gdsr_graph *g, const int32_t *layer, const float *c, float sigma_l,
                              cr_error *err);
/* Their features (ne[2], 8), laid out as Eq. 5's (cr_gdsr_features) with the
 * rest part replaced as the paper does: [0, 0, 0, sigma_l, c_l - c_i,
 * |c_l - c_i|] in dm for the edge from l to i (no rest state spans two
 * layers; the paper puts the constant sigma_l where the rest length was). */
void cr_gdsr_layer_edge_features(const cr_gdsr_graph *g, const float *c, float sigma_l,
                                 float *edge2);

/* What the features of one frame are made from (all (Vl,3) unless said). */
typedef struct cr_gdsr_frame_in {
    const float *c, *c_prev, *c_prev2;   /* C_t, C_{t-1}, C_{t-2} */
    const float *d_prev;                 /* the previous correction d_{t-1} (NULL: zero) */
    const float *chat_prev, *chat_prev2; /* C^_{t-1}, C^_{t-2} (NULL: C_{t-1}, C_{t-2}) */
    const float *body_point;             /* (Vl,3) closest body point to each C_t vertex */
} cr_gdsr_frame_in;

/* Node features (Vl, 19), Eq. 4: vertex normal of C_t (3); velocity and
 * acceleration of C in cm per frame (3 + 3); the body interaction vector
 * (closest body point - x) / sigma_b when closer than sigma_b, else 0, and
 * its length (3 + 1, Eq. 2-3); d_{t-1} in cm (3); the corrected velocity
 * C^_{t-1} - C^_{t-2} in cm (3). Edge features (E_s, 8) per edge set, Eq. 5:
 * rest offset x_j - x_i and its length, current offset and its length, in dm. */
void cr_gdsr_features(const cr_mesh *low, const cr_gdsr_graph *g, const cr_gdsr_frame_in *in,
                      float sigma_b, float *node, float *edge0, float *edge1);

/* ------------------------------------------------------------ model -- */

typedef struct cr_gdsr_model_def {
    int latent;           /* H's latent width (paper 128; default 64) */
    int steps;            /* message-passing steps (paper 6; default 4) */
    int mlp_hidden;       /* hidden layers per MLP of H (default 1; paper's code 2) */
    int decoder_features; /* features per vertex for E (paper 128; default 32) */
    int hyper_features;   /* features per vertex for A (paper 512; default 32) */
    int gen_hidden;       /* A's generator hidden width (default 64) */
    int wire_layers;      /* complex WIRE MLP layers (paper 5) */
    int wire_width;       /* its hidden width (default 16) */
    float omega0, s0;     /* WIRE (paper 5, 10) */
    int use_decoder;      /* 1: E on (gdsr); 0: GDSR(-d), C^ = C */
    float sigma_b;        /* body interaction radius, m (0.015) */
    int layer_edges;      /* 1: H has a third edge set, the layer edges (Eq. 7's sum over
                             l); 0: not; -1 (default): cr_gdsr_train turns it on when the
                             training garment has two layers or more */
    float sigma_l;        /* layer edge radius, m (0.020, the authors' code) */
    float out_scale;      /* E's and A's outputs times this, m per unit: a small start keeps
                             Adam's first steps below the data's mm errors (default 0.01) */
    uint64_t seed;        /* initialisation (default 1) */
    uint32_t cookie;
} cr_gdsr_model_def;

cr_gdsr_model_def cr_gdsr_model_default_def(void);
/* The paper's sizes: latent 128, 6 steps, 2 hidden layers, 128 / 512. */
cr_gdsr_model_def cr_gdsr_model_paper_def(void);
cr_status cr_gdsr_model_def_validate(const cr_gdsr_model_def *def, cr_error *err);

typedef struct cr_gdsr_model cr_gdsr_model;

cr_status cr_gdsr_model_create(const cr_gdsr_model_def *def, cr_gdsr_model **out, cr_error *err);
void cr_gdsr_model_destroy(cr_gdsr_model *m);
cr_nn_params *cr_gdsr_model_params(cr_gdsr_model *m);
const cr_gdsr_model_def *cr_gdsr_model_get_def(const cr_gdsr_model *m);

/* Decoder E alone (Eq. 8-9): per-vertex features f (Vl, decoder_features)
 * and the low positions c (Vl,3) -> displacement d (Vl,3): per triangle an
 * MLP on its three corners' features gives 9 numbers, three displacements
 * in the triangle's frame (e1 along the first edge, n the face normal,
 * e2 = n x e1), rotated to world and averaged over each vertex's triangles. */
cr_tensor *cr_gdsr_decode(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_mesh *low, cr_tensor *f,
                          const float *c);

/* Hyper-net A alone (Eq. 10-11): per-vertex hyper features h (Vl, hyper_features),
 * for M query points their low face and barycentric (b1, b2) -> (M,3), the
 * WIRE field of each face's generated network. With ctx's gradient off the
 * fields are evaluated point by point without the tape (the runtime's path;
 * the same values to float rounding, test_gdsr_runtime.c). */
cr_tensor *cr_gdsr_hyper(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_mesh *low, cr_tensor *h,
                         int64_t npoints, const int32_t *face, const float *bary);

/* One frame forward: features (Vl,19) and edge features (edge2: the layer
 * edges', ignored by a model without them) -> *chat (Vl,3),
 * the corrected coarse garment, and returns the high-resolution garment
 * (Vh,3) = S[C^] + residual in the frame of C^ (Eq. 12). */
cr_tensor *cr_gdsr_forward(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_gdsr_data *d,
                           const cr_gdsr_graph *g, const float *node, const float *edge0,
                           const float *edge1, const float *edge2, const float *c,
                           cr_tensor **chat);

/* --------------------------------------------------------- training -- */

typedef struct cr_gdsr_train_def {
    cr_gdsr_model_def model;
    int epochs;         /* passes over every training frame (default 20) */
    float lr;           /* AdamW base rate (paper 1e-4) */
    int lr_halve_every; /* epochs between halvings (paper 50) */
    float weight_decay; /* AdamW (default 0.01, torch's) */
    float noise_m;      /* Gaussian noise on the input C (paper 0.003 m) */
    float w_coarse;     /* lambda_c: L1 of C^ - C* (Eq. 13) (default 1) */
    float w_fine;       /* L1 of the high garment - reference (default 1) */
    float w_normal;     /* high-resolution face-normal L1 (Eq. 14-style) (default 0.01) */
    /* Regularisers on the high-resolution output X (Eq. 15-19), each a mean:
     *   w_stretch  Baraff-Witkin stretch ((|w_u|-1)^2 + (|w_v|-1)^2), area-weighted mean
     *   w_shear    Baraff-Witkin shear (w_u . w_v)^2, area-weighted mean
     *   w_bend     k_e/2 (theta(X) - theta(X_ref))^2 per hinge (dihedral angles toward the
     *              reference's as rest angles), mean over hinges, k_e with k_b = 1
     *   w_laplacian  L1 of the uniform Laplacian of X - X_ref, mean per coordinate
     * membrane and bending through the loss op (losses.h); rest shape the
     * rest high mesh laid flat (crease eval's default). */
    float w_stretch, w_shear, w_bend, w_laplacian;
    /* Kept without CLI flags: measured and not adopted (docs/notes/gdsr_rounds.md,
     * "Coarse terms"), kept for the paper's equations and the phase-free fold
     * statistics a fold branch can be trained by. */
    struct {
        /* Eq. 13 and 15-19 on the corrected coarse garment C^ against C*, each
         * times lambda_c beside w_coarse; the paper's weights (Eq. 13's and
         * Eq. 15's times Eq. 19's 0.01) in brackets. All 0 (off) by default: on
         * the t-shirt data the smoothing at 100 shrank C^ and tripled the held-out
         * strain, and the other three moved distance and strain away from
         * upsampling's:
         *   w_coarse_normal  L1 of C^'s face normals against C*'s (0.01)
         *   w_coarse_smooth  mean over (Vl,3) of C^'s squared uniform Laplacian
         *                    (Eq. 15's 10^4 ||Delta C^||^2: 10^4 x 0.01 = 100)
         *   w_coarse_bend    k_b/2 (theta(C^) - theta(C*))^2, mean over hinges
         *                    (Eq. 15's 0.1 |theta - theta*| squared: 0.001)
         *   w_coarse_strain  Eq. 16-18: as w_strain_l1, on C^ against C* (0.01) */
        float w_coarse_normal, w_coarse_smooth, w_coarse_bend, w_coarse_strain;
        /* 1: the wrinkle term compares per patch each response's RMS over the
         * patch (how strong the folds are there, not where their crests lie)
         * instead of the responses texel by texel (default 0) */
        int wrinkle_energy;
        /* measured and not adopted (docs/gdsr.md, "Options"): no CLI flags
         * w_strain_l1  Eq. 16-18 / 21-23: mean over triangles of ||w_u(X)| - |w_u(X_ref)|| +
         *              ||w_v(X)| - |w_v(X_ref)|| + |w_u.w_v(X) - w_u.w_v(X_ref)| (default 0)
         * w_wrinkle    Eq. 20's feature term, a fixed filter bank for VGG: L1 of oriented
         *              first and second differences (steps 1, 2, 4 texels) of X's and
         *              X_ref's normal maps over the UV chart, summed over steps (default 0)
         * wrinkle_side the normal map's side in texels (default 128)
         * wrinkle_patches  Eq. 24's random square patches of the map a step, the loss
         *              their mean (default 8, the paper's; 0: the whole chart as one patch)
         * wrinkle_patch_side  their side in texels (default 32, a quarter of the default
         *              map's), each around a chart texel drawn uniformly */
        float w_strain_l1, w_wrinkle;
        int wrinkle_side, wrinkle_patches, wrinkle_patch_side;
    } experimental;
    /* Eq. 25's schedule: lambda_c (coarse term) starts at lambda_c0 and lambda_w
     * (every fine-garment term) at lambda_w0; every lambda_every epochs each moves
     * lambda_step toward 1 and stops there. The paper: 1.9, 0.1, 0.2, 10. Default
     * 1, 1 (constant). */
    float lambda_c0, lambda_w0, lambda_step;
    int lambda_every;
    int val_clips;        /* the last val_clips clips of the data are not trained on: each epoch
                             rolls them out and logs their MED against upsampling's (default 0) */
    int checkpoint_every; /* epochs between checkpoints (default 5; 0: at the end) */
    int resume;           /* 1: continue from <out>/checkpoint.safetensors */
    const char *out_dir;  /* checkpoint.safetensors, log.jsonl, model.safetensors */
    int quiet;
    uint32_t cookie;
} cr_gdsr_train_def;

cr_gdsr_train_def cr_gdsr_train_default_def(void);
/* The train def's fields as a table (their ranges, and the options of `crease gdsr train`
 * with their help, docs/cli.md); n gets its length. */
const cr_config_key *cr_gdsr_train_def_keys(int *n);
/* lambda_c and lambda_w of Eq. 25 at epoch ep (0-based) under def's schedule. */
void cr_gdsr_lambdas(const cr_gdsr_train_def *def, int ep, float *lambda_c, float *lambda_w);

/* The loss terms of a training step, by name: the coarse L1 (Eq. 13), the fine garment's
 * L1, normals and regularisers, the experimental ones, and the experimental coarse terms
 * on C^. Their names are log.jsonl's and --json's keys. */
typedef enum cr_gdsr_term {
    CR_GDSR_TERM_COARSE,
    CR_GDSR_TERM_FINE,
    CR_GDSR_TERM_NORMAL,
    CR_GDSR_TERM_STRETCH,
    CR_GDSR_TERM_SHEAR,
    CR_GDSR_TERM_BEND,
    CR_GDSR_TERM_LAPLACIAN,
    CR_GDSR_TERM_STRAIN_L1,
    CR_GDSR_TERM_WRINKLE,
    CR_GDSR_TERM_COARSE_NORMAL,
    CR_GDSR_TERM_COARSE_SMOOTH,
    CR_GDSR_TERM_COARSE_BEND,
    CR_GDSR_TERM_COARSE_STRAIN,
    CR_GDSR_NTERMS
} cr_gdsr_term;
extern const char *const cr_gdsr_term_names[CR_GDSR_NTERMS];

typedef struct cr_gdsr_train_result {
    int epochs;                       /* completed (including resumed ones) */
    int resumed_from;                 /* epoch the run resumed at (0: fresh) */
    double first_loss;                /* mean loss of the first epoch this call ran */
    double last_loss;                 /* of the last */
    double last_term[CR_GDSR_NTERMS]; /* the last epoch's mean of each term, unweighted (0 when
                                         its weight is) */
    double last_val_med, val_upsampled_med; /* m, over the validation clips (NAN: none) */
    double seconds;
    int64_t params;
} cr_gdsr_train_result;

/* Train on every clip of d (frames in order, each clip rolled out on the
 * model's own previous corrections). Writes out_dir/checkpoint.safetensors
 * (resumable), model.safetensors (weights + the model def as JSON) and
 * log.jsonl (one line per epoch). progress (may be NULL) gets each epoch. */
cr_status cr_gdsr_train(const cr_gdsr_train_def *def, const cr_gdsr_data *d,
                        cr_gdsr_train_result *out, cr_error *err);

enum { CR_GDSR_MAX_GARMENTS = 8 };
/* One model trained on several garments (the paper's five outfits): each
 * epoch goes through the garments in order, each one's training clips in
 * order; the last val_clips clips of every garment are held out, and the
 * validation distance is over all of them (weighted by vertex-frames). The
 * garments may differ in mesh, vertex count and layers (layer edges auto:
 * on when any has two layers). With one garment it is cr_gdsr_train, bit
 * for bit. */
cr_status cr_gdsr_train_many(const cr_gdsr_train_def *def, const cr_gdsr_data *const *d,
                             int ngarments, cr_gdsr_train_result *out, cr_error *err);

/* `crease gdsr train` as one call (train.c): each garment's low/high pairs
 * of a `crease dataset` folder loaded, then cr_gdsr_train_many. */
typedef struct cr_gdsr_train_dataset_def {
    const char *dataset;         /* the folder (required) */
    const char *const *garments; /* (ngarments) 1 to CR_GDSR_MAX_GARMENTS types */
    int ngarments;
    const char *body;           /* default "normal" */
    const char *const *motions; /* (nmotions) training clips; 0: every motion of the
                                   dataset with both sequences of the first garment
                                   but the validation clips */
    int nmotions;
    const char *const *val_motions; /* (nval) held-out clips, rolled out each epoch */
    int nval;
} cr_gdsr_train_dataset_def;

typedef struct cr_gdsr_train_dataset_result {
    cr_gdsr_train_result train;
    int32_t low_vertices[CR_GDSR_MAX_GARMENTS], high_vertices[CR_GDSR_MAX_GARMENTS];
    char motions[CR_GDSR_MAX_CLIPS][64]; /* the training clips taken (nmotions) */
    int nmotions;
    char *summary_json; /* `gdsr train --json`'s object: sizes, every garment's, the last
                           epoch's terms, the held-out MED (heap; ..._result_free) */
} cr_gdsr_train_dataset_result;

/* def's val_clips is set from the validation clips. Fails naming the
 * dataset, a garment or a clip it cannot load. */
cr_status cr_gdsr_train_dataset(const cr_gdsr_train_def *def, const cr_gdsr_train_dataset_def *data,
                                cr_gdsr_train_dataset_result *out, cr_error *err);
void cr_gdsr_train_dataset_result_free(cr_gdsr_train_dataset_result *r); /* NULL: no-op */

/* Load model.safetensors (or a checkpoint) written by cr_gdsr_train. */
cr_status cr_gdsr_model_load(const char *path, cr_gdsr_model **out, cr_error *err);

/* --------------------------------------------------------- roll-out -- */

typedef struct cr_gdsr_rollout_result {
    int32_t nframes, nv_high;
    float *gdsr;                             /* (T,Vh,3) after collision handling */
    float *gdsr_raw;                         /* (T,Vh,3) before */
    float *upsampled;                        /* (T,Vh,3) barycentric upsampling of C */
    double inside_before, inside_after;      /* largest share of high vertices inside the body on a
                                                frame, before and after handling */
    int64_t layer_pushed, layer_pushed_high; /* Eq. 27 on an outfit: coarse and high vertices
                                                pushed out of the layer under them, summed
                                                over the frames */
    double seconds_per_frame;                /* gdsr per frame from frame 3, wall clock: the body
                                                refit, its closest points (their share), the
                                                features, the networks and the handling */
    double first_frame_seconds;              /* frame 2, the first through the networks, wall
                                                clock: it also pays the one-time warm-up (the
                                                arena's first touch, the thread pool), so it
                                                is left out of seconds_per_frame as the
                                                simulators' set-up is left out of theirs
                                                (0 on a clip of 3 frames or fewer, whose
                                                one network frame stays in the mean) */
    double cpu_seconds_per_frame;            /* the same in process CPU time (clock()) */
    double stage_seconds[4];                 /* seconds_per_frame split, wall clock: the body
                                                (refit and closest points), the graph
                                                features, the networks, the handling */
} cr_gdsr_rollout_result;

/* The names of cr_gdsr_rollout_result's stage_seconds, in order. */
extern const char *const cr_gdsr_stage_names[4];

/* Edge-face crossings between the layers of d's high garment (its connected
 * components, cr_gdsr_mesh_layers) at positions x (Vh,3): the sum over
 * pairs of layers of cr_garment_count_crossings; 0 for one layer, -1 with
 * err set on failure. */
int64_t cr_gdsr_layer_crossings(const cr_gdsr_data *d, const float *x, cr_error *err);

enum { CR_GDSR_RELAX_DEFAULT = 4 }; /* `relax` of cr_gdsr_rollout in `gdsr run` */
/* Eq. 27's constants (the authors' code): the gap kept between layers, m,
 * and how near an inner vertex must be to count (the garment is open). */
#define CR_GDSR_LAYER_SIGMA 0.005f
#define CR_GDSR_LAYER_GAMMA 0.025f

/* Run the model over clip k of d, feeding back its own corrections;
 * collision handling (Eq. 26-27) pushes C^ vertices out of the body to
 * `eps` along the body's normal, carries that push to the high vertices
 * through Eq. 1, then pushes out any high vertex still inside; `relax`
 * Laplacian steps (each followed by a push) spread the high vertices'
 * displacement over their neighbours so that it adds little strain (0:
 * the per-vertex push alone). On an outfit (two layers or more, layer k + 1
 * worn over layer k) Eq. 27 follows: outer C^ vertices closer than
 * CR_GDSR_LAYER_SIGMA to the layer under them are pushed out along its
 * normal, the push carried to the high vertices, and the high vertices
 * over a pushed one pushed to the same gap. layer_surface chooses what
 * "the layer under them" is: 0, the nearest inner vertex and its normal
 * (the paper's Eq. 27); 1, the closest point on the inner layer's triangles
 * and the normal there, skipping outer vertices whose closest point is on
 * the inner layer's open edge (past its hem or cuff). */
cr_status cr_gdsr_rollout(cr_gdsr_model *m, const cr_gdsr_data *d, int clip, float eps, int relax,
                          int layer_surface, cr_gdsr_rollout_result *out, cr_error *err);
void cr_gdsr_rollout_free(cr_gdsr_rollout_result *r);

/* ---------------------------------------------------------- runtime -- */

/* Frame by frame, for a game loop or a renderer (src/methods/gdsr/runtime.c):
 *
 *   cr_gdsr_runtime *rt = NULL;
 *   CR_TRY(cr_gdsr_runtime_open("model.safetensors", "data", "tshirt", "normal", NULL, &rt, err));
 *   float *high = malloc(sizeof(float) * 3 * cr_gdsr_runtime_vertices(rt));
 *   for each frame: cr_gdsr_runtime_step(rt, low, body, high, err);  // (Vl,3), (Vb,3) -> (Vh,3)
 *   cr_gdsr_runtime_destroy(rt);
 *
 * A step takes the frame's low-resolution garment C_t (Vl,3) (the low
 * simulation's, in the low rest mesh's vertex order) and the posed body
 * (Vb,3) (the rest body's vertex order), m, and writes the high-resolution
 * garment (Vh,3), m, into the caller's buffer: the frame cr_gdsr_rollout
 * gives for the same inputs (which steps a runtime over the clip). The
 * runtime keeps what the features read of earlier frames (C_{t-1}, C_{t-2},
 * its own C^_{t-1}, C^_{t-2} and d_{t-1}); the first two frames after
 * create or reset have no history and give the upsampled input. With
 * `handling` on (the default), Eq. 26-27 follow the networks as in the
 * roll-out's gdsr.pc2; off, the network's output (gdsr_raw.pc2).
 *
 * Memory: everything is allocated at create, the arena sized by trial
 * frames at rest; a step allocates nothing on a single-layer garment (the
 * engine's GEMM keeps its buffers per thread, docs/runtime.md). On an
 * outfit (two layers or more) the layer edges (Eq. 7) and Eq. 27 take their
 * scratch from the heap each frame, and the arena stays the trial's
 * generous reservation (touched only as used): a frame's layer edges are
 * not bounded by the trial's. Threads: instances are independent; several
 * may share one model and data (only read), each stepping on its own
 * thread. */
typedef struct cr_gdsr_runtime_def {
    int handling;       /* 1: Eq. 26-27 after the networks (default); 0: the raw output */
    float eps;          /* the handling's margin, m (default 0.002, `gdsr run`'s) */
    int relax;          /* its relaxation rounds (default CR_GDSR_RELAX_DEFAULT) */
    int layer_surface;  /* Eq. 27's rule: 0 the nearest vertex (default), 1 the surface */
    size_t arena_bytes; /* 0 (default): sized by trial frames at create */
    uint32_t cookie;
} cr_gdsr_runtime_def;

cr_gdsr_runtime_def cr_gdsr_runtime_default_def(void);

typedef struct cr_gdsr_runtime cr_gdsr_runtime;

/* m and d are borrowed and must outlive the runtime; of d only the pair,
 * its correspondence, the layers and the rest body are read (no clips
 * needed). def NULL: the defaults. */
cr_status cr_gdsr_runtime_create(cr_gdsr_model *m, const cr_gdsr_data *d,
                                 const cr_gdsr_runtime_def *def, cr_gdsr_runtime **out,
                                 cr_error *err);
/* From files, owning what it loads: a model (cr_gdsr_model_load) and the
 * low/high pair of `garment` on `body` in a `crease dataset` folder
 * (cr_gdsr_data_load with no motions; NULL garment "tshirt", body "normal"). */
cr_status cr_gdsr_runtime_open(const char *model_path, const char *dataset, const char *garment,
                               const char *body, const cr_gdsr_runtime_def *def,
                               cr_gdsr_runtime **out, cr_error *err);
void cr_gdsr_runtime_destroy(cr_gdsr_runtime *rt); /* NULL is a no-op */
/* Back to before the first frame (the history cleared). */
void cr_gdsr_runtime_reset(cr_gdsr_runtime *rt);
/* low (Vl,3), body (Vb,3) -> out (Vh,3). CR_ERR_NAN for a non-finite body
 * (the BVH's refit), CR_ERR_DIVERGED for a non-finite output. */
cr_status cr_gdsr_runtime_step(cr_gdsr_runtime *rt, const float *low, const float *body, float *out,
                               cr_error *err);
/* n characters, one frame each, one after another: low[i] (Vl_i,3),
 * body[i] (Vb_i,3), out[i] (Vh_i,3). */
cr_status cr_gdsr_runtime_step_batch(cr_gdsr_runtime *const *rts, int32_t n,
                                     const float *const *low, const float *const *body,
                                     float *const *out, cr_error *err);
int32_t cr_gdsr_runtime_vertices(const cr_gdsr_runtime *rt);      /* Vh */
int32_t cr_gdsr_runtime_low_vertices(const cr_gdsr_runtime *rt);  /* Vl */
int32_t cr_gdsr_runtime_body_vertices(const cr_gdsr_runtime *rt); /* Vb */
/* The high rest mesh (its triangles are the output's). */
const cr_mesh *cr_gdsr_runtime_rest(const cr_gdsr_runtime *rt);
/* The low rest mesh (what a simulator steps for the input) and the rest body. */
const cr_mesh *cr_gdsr_runtime_low_rest(const cr_gdsr_runtime *rt);
const cr_mesh *cr_gdsr_runtime_body_rest(const cr_gdsr_runtime *rt);
/* The last step's output before the handling, (Vh,3), owned by the runtime
 * (the same as the step's with handling off). */
const float *cr_gdsr_runtime_raw(const cr_gdsr_runtime *rt);
size_t cr_gdsr_runtime_arena_bytes(const cr_gdsr_runtime *rt);
/* What the last step did: its stages' wall seconds (cr_gdsr_stage_names:
 * the body's refit and closest points, the features, the networks, the
 * handling; all 0 for the first two frames, which run no networks) and
 * Eq. 27's pushes (coarse and high vertices). */
typedef struct cr_gdsr_runtime_stats {
    double seconds[4];
    int64_t layer_pushed, layer_pushed_high;
} cr_gdsr_runtime_stats;
cr_gdsr_runtime_stats cr_gdsr_runtime_last_stats(const cr_gdsr_runtime *rt);

/* ---------------------------------------------------------- outputs -- */

enum { CR_GDSR_GLB_MAX_FRAMES = 300 }; /* `gdsr run`'s animated glb at most (then the last) */

/* The high-resolution sequence x (T,Vh,3) as glb: a morph-target animation
 * (cr_glb_write_sequence, base mesh frame 0) when nframes <= max_frames,
 * else the last frame alone (the animation's weights grow as T^2 and its
 * targets as T); *animated (may be NULL) says which. */
cr_status cr_gdsr_write_glb(const cr_mesh *high, const float *x, int32_t nframes, float fps,
                            int32_t max_frames, const char *path, int *animated, cr_error *err);

/* Frame `frame` of clip `clip` side by side, size x size pixels a panel,
 * labelled: the low-resolution input, gdsr, barycentric upsampling and the
 * high-resolution reference when the clip has one, each garment rendered
 * alone (cr_render_scene, framed on itself) into png_path; with
 * normals_path (may be NULL) their normal maps over the UV chart, the SSIM
 * maps of crease eval (the low input's over its own chart). */
cr_status cr_gdsr_render_compare(const cr_gdsr_data *d, int clip, const cr_gdsr_rollout_result *r,
                                 int32_t frame, int size, const char *png_path,
                                 const char *normals_path, cr_error *err);

/* ------------------------------------------------------------ the run -- */

/* `crease gdsr run` as one call (src/methods/gdsr/run.c): a trained model
 * rolled out on a dataset's clip, or on a clip simulated first. */
typedef struct cr_gdsr_run_def {
    const char *dataset;  /* a crease dataset folder (with simulate: the model's training
                             data, whose sizes and rate the simulation takes; may be NULL) */
    const char *garment;  /* default "tshirt" */
    const char *body;     /* default "normal" */
    const char *motion;   /* a clip name or a motion file (required) */
    const char *model;    /* model.safetensors (required) */
    const char *baseline; /* a second model rolled out beside it (gdsr_nodec), or NULL */
    const char *twin;     /* a twin dataset (the same clip re-simulated): its row, or NULL */
    const char *out_dir;  /* required */
    float eps;            /* collision handling's margin, m (default 0.002) */
    int relax;            /* its relaxation rounds (default CR_GDSR_RELAX_DEFAULT) */
    int surface;          /* 1: Eq. 27's layer test against the surface, 0: nearest vertex */
    int32_t frames;       /* 0: the whole clip, else its first `frames` */
    int simulate;         /* 1: simulate the clip first (cr_gdsr_simulate) into out_dir/sim */
    int reference;        /* with simulate: the high reference too */
    int32_t low_vertices, high_vertices; /* with simulate; 0: the dataset's or defaults */
    const struct cr_motion_import_def *motion_import;   /* with simulate; NULL: defaults */
    const struct cr_motion_prepare_def *motion_prepare; /* with simulate; NULL: defaults */
    int32_t png_frame;      /* the comparison picture's frame (-1: the last) */
    int32_t png_size;       /* its side, px (default 512) */
    int32_t glb_max_frames; /* gdsr.glb animated up to this many frames (default
                               CR_GDSR_GLB_MAX_FRAMES) */
    float fps;              /* the glb's rate (default 30) */
    int quiet;
    uint32_t cookie;
} cr_gdsr_run_def;
cr_gdsr_run_def cr_gdsr_run_default_def(void);
/* Its numeric fields as a table: their ranges and the options of `crease gdsr run`. */
const cr_config_key *cr_gdsr_run_def_keys(int *n);

typedef struct cr_gdsr_run_report {
    int32_t frames, low_vertices, high_vertices;
    double seconds_per_frame; /* gdsr and handling (cr_gdsr_rollout_result) */
    double inside_before, inside_after;
    char *summary_json; /* OUT/summary.json's text (heap; cr_gdsr_run_report_free) */
} cr_gdsr_run_report;

/* Writes into out_dir: gdsr.pc2, gdsr_raw.pc2, upsampled.pc2, reference.pc2
 * (when the clip has one), gdsr_nodec.pc2 (with a baseline), high.obj,
 * gdsr.glb, compare.png, compare_normals.png, body.pc2, body.obj,
 * strain.csv, strain.png and summary.json (timings, the paper's metrics of
 * gdsr, upsampling, the baseline and the twin against the reference, band
 * power, strain drift). Progress and the table through cr_log. out may be
 * NULL. */
cr_status cr_gdsr_run(const cr_gdsr_run_def *def, cr_gdsr_run_report *out, cr_error *err);
void cr_gdsr_run_report_free(cr_gdsr_run_report *r); /* NULL is a no-op */

#ifdef __cplusplus
}
#endif
#endif
