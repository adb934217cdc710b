/* crease/uv_fit.h: supervised regression of a 3-D deformation over UV, the
 * drape paper's section 4.1 and Table 1 (Shu et al., "Spatially Adaptive
 * Cloth Regression with Implicit Neural Representations").
 *
 * Three models of (almost) equal size learn the same target deformation
 *   dz(u,v) = 0.10 sin(2 pi 2u) sin(2 pi 2v) + 0.02 sin(2 pi 8u) sin(2 pi 8v),
 *   dx = dy = 0, on [0,1]^2,
 * from a 256x256 training grid; the error is the relative L2 error on a
 * 512x512 grid. It shows what the grid encoding buys: the paper reports 400
 * epochs for the grid model against 500,000 for a plain MLP.
 *
 *   model  architecture                                      parameters
 *   mlp    2-152-152-152-3, ReLU                              47,427
 *   pe     (u,v) + sin/cos(2^k pi u, 2^k pi v), k = 0..3
 *          -> 18-148-148-148-3, ReLU                          47,363
 *   grid   levels 101x101x3 and 51x51x3 -> 6-64-64-64-3, ReLU 47,369
 *
 * An epoch is one pass over the 65,536 training points in shuffled
 * mini-batches (4,096 by default) with Adam on the mean squared error.
 */
#ifndef CREASE_UV_FIT_H
#define CREASE_UV_FIT_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum cr_fit_model {
    CR_FIT_MLP = 0,
    CR_FIT_PE,
    CR_FIT_GRID,
    CR_FIT_MODEL_COUNT
} cr_fit_model;

const char *cr_fit_model_name(cr_fit_model m); /* "mlp", "pe", "grid" */
/* CR_ERR_INVALID naming the accepted names when `name` is none of them. */
cr_status cr_fit_model_parse(const char *name, cr_fit_model *out, cr_error *err);

typedef struct cr_fit_def {
    cr_fit_model model;
    int epochs;           /* cap on epochs, >= 1 (default 2000) */
    int train_res;        /* training grid side (default 256) */
    int eval_res;         /* evaluation grid side (default 512) */
    int batch;            /* mini-batch size (default 4096) */
    float lr;             /* Adam learning rate; 0 = the model's default (see uv_fit.c) */
    float target_rel_l2;  /* the error to reach (default 0.01) */
    int stop_at_target;   /* 1: stop once the target is reached (default 1) */
    int eval_every;       /* evaluate every N epochs (default 1) */
    uint64_t seed;        /* initialisation and shuffling (default 1) */
    const char *out_dir;  /* where outputs go (NULL: write nothing) */
    int checkpoint_every; /* epochs between checkpoints into out_dir (default 50; 0: never) */
    int resume;           /* 1: continue from out_dir/checkpoint.safetensors when present */
    int quiet;            /* 1: no progress bar */
    uint32_t cookie;      /* set by cr_fit_default_def */
} cr_fit_def;

cr_fit_def cr_fit_default_def(cr_fit_model model);

typedef struct cr_fit_result {
    int64_t params;           /* trainable floats */
    int epochs;               /* epochs trained in all (including resumed ones) */
    double seconds;           /* training wall time, evaluation excluded, s */
    double eval_seconds;      /* time spent evaluating, s */
    double rel_l2;            /* final relative L2 error on the evaluation grid */
    double final_loss;        /* mean squared error of the last epoch, m^2 */
    int epochs_to_target;     /* first evaluated epoch at or below the target; -1 if never */
    double seconds_to_target; /* training time to that epoch; -1 if never */
    int resumed_from;         /* epoch the run resumed from (0: fresh) */
    char surface_png[1024];   /* written picture (empty when out_dir is NULL) */
} cr_fit_result;

/* The target deformation at (u,v): d (3), m. */
void cr_fit_target(float u, float v, float d[3]);

/* Train and evaluate. With out_dir, writes there: log.jsonl (one line per
 * evaluation: epoch, loss, rel_l2, seconds), checkpoint.safetensors (every
 * checkpoint_every epochs and at the end; resumable), surface.obj (the
 * learned surface on the evaluation grid, at most 256x256 vertices) and
 * surface.png (that surface coloured by its error). */
cr_status cr_fit_run(const cr_fit_def *def, cr_fit_result *out, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
