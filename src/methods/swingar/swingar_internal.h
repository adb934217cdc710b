/* swingar_internal.h: what model.c, loss.c, data.c, train.c, run.c and measure.c share. */
#ifndef CREASE_SWINGAR_INTERNAL_H
#define CREASE_SWINGAR_INTERNAL_H

#include "crease/nn_graph.h"
#include "crease/nn_layers.h"
#include "crease/swingar.h"

enum {
    SWG_VERTEX_FEATURES = 7,                /* normal, position, fit attribute */
    SWG_POSE_FEATURES = CR_NJOINTS * 3 + 3, /* axis-angles, relative root translation */
    SWG_BODY_FEATURES = CR_NJOINTS * 3 + SWG_POSE_FEATURES, /* rest joints (beta), theta^t */
    SWG_CORR_FEATURES = 3 + CR_NJOINTS, /* position, distance to every joint (eq. 6) */
    SWG_MAX_WINDOW = 60,                /* frames one forward predicts */
    SWG_PREDICT_CHUNK = 8               /* frames per forward at inference */
};

/* The root's move per frame is scaled to the order of the angles (a few cm
 * a frame -> a few tenths). */
#define SWG_TRANS_SCALE 10.0f
/* `swingar run` and `swingar measure` move a vertex inside the posed body out to this
 * beyond the surface, m (eq. 10 on the exact distance). */
#define CR_SWINGAR_REMOVAL_MARGIN_M 0.001f
/* log(w + floor) keeps joints a garment vertex is not bound to reachable. */
#define SWG_SKIN_FLOOR 1e-4f

struct cr_swingar {
    cr_swingar_def def;
    cr_nn_params *P;
    cr_gat g0, g1;                   /* E_g */
    cr_mlp *shape;                   /* E_a */
    cr_tensor *desc_mean, *desc_std; /* (z) frozen: E_a reads (descriptor - mean) / std */
    cr_rnn_cell motion;              /* E_m */
    cr_mlp *body;                    /* E_b */
    cr_gat state;                    /* E_s */
    cr_linear skin;                  /* shape features -> (state width, joints) */
    cr_gat b0, b1;                   /* blend shapes */
    cr_linear bout;                  /* -> 3 */
    cr_gat_lstm corr;                /* P_d */
    cr_gat c0, c1;
};

/* The garment's part of a forward, the same for every frame and motion:
 * E_g, the skinning map A s of the shape features and the prior logits. */
typedef struct swg_genc {
    cr_tensor *G, *skinmat, *logw0; /* (V,H), (state width, J), (V,J) */
} swg_genc;

/* The descriptor's standardisation from the garments the training sequences
 * use (is_test NULL: all): per entry the mean and the standard deviation
 * (floored at 1e-3 of |mean| and 1e-12), into the model's frozen tensors. */
cr_status cr_swingar_standardise_descriptor_(cr_swingar *m, const cr_swingar_data *d,
                                             const int8_t *is_test, cr_error *err);

/* A fitted garment (cr_garment_load_user, cr_garment_create) on body b as
 * the model sees it: its descriptor when the model uses one (an error names
 * `source`), then cr_swingar_garment_create. */
cr_status cr_swingar_garment_of_(const cr_swingar *m, const struct cr_garment *garment,
                                 const char *source, const cr_body_model *b,
                                 cr_swingar_garment **out, cr_error *err);

/* 1 on success; 0 with the context's error set. */
int cr_swingar_encode_garment_(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                               swg_genc *e);

/* Frames [t0, t0 + K) given the garment's encoding. prev: NULL, or the
 * (2,V,SWG_CORR_FEATURES) graphs M_c of frames t0-2 and t0-1 from the call
 * before (so only the K new coarse frames are computed); next: NULL, or
 * where the graphs of frames t0+K-2 and t0+K-1 go (host floats; it may be
 * prev). Returns (K,V,3) world positions. */
cr_tensor *cr_swingar_forward_frames_(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                                      const swg_genc *e, const cr_swingar_motion *mo, int32_t t0,
                                      int32_t K, float *prev, float *next, cr_swingar_parts *parts);

#endif
