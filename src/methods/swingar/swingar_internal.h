/* swingar_internal.h: what model.c, loss.c, data.c and train.c share. */
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
/* log(w + floor) keeps joints a garment vertex is not bound to reachable. */
#define SWG_SKIN_FLOOR 1e-4f

struct cr_swingar {
    cr_swingar_def def;
    cr_nn_params *P;
    cr_gat g0, g1;      /* E_g */
    cr_mlp *shape;      /* E_a */
    cr_rnn_cell motion; /* E_m */
    cr_mlp *body;       /* E_b */
    cr_gat state;       /* E_s */
    cr_linear skin;     /* shape features -> (state width, joints) */
    cr_gat b0, b1;      /* blend shapes */
    cr_linear bout;     /* -> 3 */
    cr_gat_lstm corr;   /* P_d */
    cr_gat c0, c1;
};

#endif
