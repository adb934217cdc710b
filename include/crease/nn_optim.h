/* crease/nn_optim.h: optimisers, learning-rate schedules and gradient
 * clipping over a cr_nn_params store.
 *
 *   SGD (momentum, Nesterov, L2 weight decay)          CR_OPTIM_SGD
 *   Adam (Kingma & Ba 2015, as torch.optim.Adam)       CR_OPTIM_ADAM
 *   AdamW (Loshchilov & Hutter 2019, torch's AdamW)    CR_OPTIM_ADAMW
 *   constant / step decay / cosine schedules, linear warm-up    cr_lr_at
 *   clipping by global gradient norm                   cr_clip_grad_norm
 *
 * A tour:
 *
 *   cr_optim_def def = cr_optim_default_def(CR_OPTIM_ADAMW);
 *   def.lr.base = 3e-4f;
 *   def.lr.kind = CR_LR_COSINE;        // anneal to def.lr.final ...
 *   def.lr.total_steps = 10000;        // ... over 10k steps
 *   def.lr.warmup_steps = 500;
 *   cr_optim *opt = NULL;
 *   CR_TRY(cr_optim_create(&def, params, &opt, err));
 *   for (...) {
 *       cr_nn_params_zero_grad(params);
 *       ... forward, cr_nn_backward ...
 *       CR_TRY(cr_clip_grad_norm(params, 1.0f, &norm, err));
 *       CR_TRY(cr_optim_step(opt, err));   // lr = cr_lr_at(&def.lr, steps taken)
 *   }
 *   cr_optim_destroy(opt);
 *
 * State: the moment buffers mirror the parameter blocks float for float
 * (sized at create, allocated once), so a step is one elementwise pass over
 * the blocks, parallel over elements and bit-identical for any thread count.
 * Parameters whose requires_grad is 0 are skipped entirely (no update, no
 * weight decay, no moment change), like PyTorch's parameters without a grad.
 * The learning rate comes from the schedule in the def, evaluated at the
 * optimiser's own step count, so restoring the count (checkpoints do)
 * restores the schedule too.
 *
 * Leaves out: per-parameter groups (one set of hyper-parameters for the whole
 * store), AMSGrad, sparse gradients, learning-rate policies driven by the
 * loss (a caller can rebuild the optimiser or scale grads).
 */
#ifndef CREASE_NN_OPTIM_H
#define CREASE_NN_OPTIM_H

#include "crease/nn.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ schedules -- */

typedef enum cr_lr_kind {
    CR_LR_CONSTANT = 0, /* base */
    CR_LR_STEP,         /* base * gamma^floor(s / step_every) (gamma 0.5: halving) */
    CR_LR_COSINE        /* final + (base - final) (1 + cos(pi s / total_steps)) / 2, then final */
} cr_lr_kind;

/* Learning rate as a function of the step index (0 for the first step). With
 * warm-up, steps s < warmup_steps use base * (s + 1) / warmup_steps (so the
 * first step is not wasted at lr 0 and step warmup_steps - 1 reaches base),
 * and the decay above runs on s - warmup_steps. */
typedef struct cr_lr_schedule {
    cr_lr_kind kind;
    float base;           /* peak learning rate, > 0 (default 1e-3) */
    float final;          /* CR_LR_COSINE: value reached at total_steps, in [0, base] (default 0) */
    float gamma;          /* CR_LR_STEP: factor per period, in (0, 1] (default 0.5) */
    int64_t step_every;   /* CR_LR_STEP: period in steps, >= 1 (default 1000) */
    int64_t total_steps;  /* CR_LR_COSINE: annealing length after warm-up, >= 1 (default 1000) */
    int64_t warmup_steps; /* linear warm-up length, >= 0 (default 0: none) */
} cr_lr_schedule;

cr_lr_schedule cr_lr_default_schedule(void); /* constant 1e-3 */
/* CR_ERR_INVALID naming the field when a schedule is out of range. */
cr_status cr_lr_check(const cr_lr_schedule *s, cr_error *err);
/* The learning rate of step `step` (>= 0) of a checked schedule; computed in
 * double and rounded once. */
float cr_lr_at(const cr_lr_schedule *s, int64_t step);

/* ----------------------------------------------------------- optimisers -- */

typedef enum cr_optim_kind {
    CR_OPTIM_SGD = 0,
    CR_OPTIM_ADAM,
    CR_OPTIM_ADAMW,
    CR_OPTIM_KIND_COUNT
} cr_optim_kind;

const char *cr_optim_kind_name(cr_optim_kind kind); /* "sgd", "adam", "adamw" */

/* Update rules (g gradient, p parameter, t = steps taken + 1, lr from the schedule):
 *   SGD:   g += wd p;  b = t == 1 ? g : momentum b + (1 - dampening) g;
 *          p -= lr (nesterov ? g + momentum b : b)     (b = g when momentum is 0)
 *   Adam:  g += wd p;  m = b1 m + (1 - b1) g;  v = b2 v + (1 - b2) g^2;
 *          p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)
 *   AdamW: p *= 1 - lr wd; then Adam without the g += wd p term.
 * These are torch.optim's formulas (the SGD buffer starts as the first
 * gradient, eps is added after the bias-corrected square root). */
typedef struct cr_optim_def {
    cr_optim_kind kind;
    cr_lr_schedule lr;  /* learning rate and its schedule */
    float weight_decay; /* SGD, Adam: L2 added to the gradient; AdamW: decoupled. >= 0 */
    float momentum;     /* SGD: in [0, 1) (default 0) */
    float dampening;    /* SGD: in [0, 1] (default 0) */
    int nesterov;       /* SGD: needs momentum > 0 and dampening 0 (default 0) */
    float beta1;        /* Adam(W): in [0, 1) (default 0.9) */
    float beta2;        /* Adam(W): in [0, 1) (default 0.999) */
    float eps;          /* Adam(W): > 0 (default 1e-8) */
    uint32_t cookie;    /* set by cr_optim_default_def; a hand-zeroed def is a bug */
} cr_optim_def;

/* PyTorch's defaults for `kind`: lr 1e-3 constant; weight_decay 0, except
 * 0.01 for AdamW. */
cr_optim_def cr_optim_default_def(cr_optim_kind kind);

typedef struct cr_optim cr_optim;

/* Sizes the state from the store's blocks as they are now: add every
 * parameter first. The store must outlive the optimiser. CR_ERR_INVALID
 * naming the field for an out-of-range def, CR_ERR_INVALID for an empty store. */
cr_status cr_optim_create(const cr_optim_def *def, cr_nn_params *p, cr_optim **out, cr_error *err);
void cr_optim_destroy(cr_optim *o); /* NULL is a no-op */

/* One update from the grads in the store. When any trainable gradient is
 * NaN or infinite, fails with CR_ERR_NAN naming the parameter and element and
 * changes nothing (parameters, moments, step count). CR_ERR_INVALID when
 * parameters were added after create. */
cr_status cr_optim_step(cr_optim *o, cr_error *err);

int64_t cr_optim_step_count(const cr_optim *o); /* steps taken */
float cr_optim_lr(const cr_optim *o);           /* learning rate the next step will use */
const cr_optim_def *cr_optim_get_def(const cr_optim *o);
cr_nn_params *cr_optim_params(const cr_optim *o);

/* The state, for checkpoints: `count` buffers (SGD with momentum: 1,
 * "momentum"; SGD without: 0; Adam(W): 2, "m" and "v"), each mirroring
 * cr_nn_params_data element for element (same length, same offsets), owned
 * by the optimiser. Writing into them and setting the step count restores a
 * saved state exactly. */
int cr_optim_state_count(const cr_optim *o);
float *cr_optim_state(cr_optim *o, int k, const char **name);
void cr_optim_set_step_count(cr_optim *o, int64_t steps); /* steps >= 0 */

/* ------------------------------------------------------------- clipping -- */

/* Global L2 norm of all trainable gradients (accumulated in double) into
 * *norm_before (may be NULL); when it exceeds max_norm (> 0) every gradient
 * is scaled by max_norm / norm, so the norm becomes max_norm (torch adds 1e-6
 * to the divisor; this does not). CR_ERR_NAN naming the first parameter with
 * a non-finite gradient (grads left unchanged), CR_ERR_INVALID for
 * max_norm <= 0. */
cr_status cr_clip_grad_norm(cr_nn_params *p, float max_norm, float *norm_before, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
