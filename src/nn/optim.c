/* optim.c: SGD, Adam and AdamW over a cr_nn_params store, learning-rate
 * schedules, and clipping by global gradient norm.
 *
 * Layout (llm.c's train_gpt2.c): the moment buffers mirror the store's data
 * block float for float, allocated once at create, so a step is one
 * elementwise pass over [data, grad, m, v]. Trainable parameters that follow
 * each other are merged into one range (the zero padding between them stays
 * zero under every rule here: zero grad and zero data give a zero update), so
 * with nothing frozen the pass is a single parallel loop.
 *
 * Before touching anything a step scans the trainable gradients for NaN/Inf,
 * so a bad batch fails cleanly and leaves parameters and moments as they were.
 *
 * References: Kingma & Ba, "Adam", ICLR 2015 (Algorithm 1 with the bias
 * corrections folded into the step size and the eps placement of
 * torch.optim.Adam); Loshchilov & Hutter, "Decoupled weight decay
 * regularization", ICLR 2019 (AdamW, as torch.optim.AdamW); Sutskever et al.,
 * ICML 2013 (momentum, Nesterov in torch.optim.SGD's form); Loshchilov &
 * Hutter, "SGDR", ICLR 2017 (cosine annealing).
 * Leaves out: parameter groups, AMSGrad, sparse updates.
 */
#include "crease/nn_optim.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { OPTIM_COOKIE = 0x6f707469u }; /* "opti" */
enum { STEP_GRAIN = 16384 };         /* elements worth a thread for an update */

/* --------------------------------------------------------------- schedules -- */

cr_lr_schedule cr_lr_default_schedule(void) {
    cr_lr_schedule s;
    memset(&s, 0, sizeof s);
    s.kind = CR_LR_CONSTANT;
    s.base = 1e-3f;
    s.final = 0.0f;
    s.gamma = 0.5f;
    s.step_every = 1000;
    s.total_steps = 1000;
    s.warmup_steps = 0;
    return s;
}

cr_status cr_lr_check(const cr_lr_schedule *s, cr_error *err) {
    if (s->kind != CR_LR_CONSTANT && s->kind != CR_LR_STEP && s->kind != CR_LR_COSINE)
        return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: unknown kind %d", (int)s->kind);
    if (!(s->base > 0.0f) || !isfinite(s->base))
        return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: base must be positive and finite, got %g",
                       (double)s->base);
    if (s->warmup_steps < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: warmup_steps must be >= 0, got %lld",
                       (long long)s->warmup_steps);
    if (s->kind == CR_LR_STEP) {
        if (!(s->gamma > 0.0f && s->gamma <= 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: gamma must be in (0, 1], got %g",
                           (double)s->gamma);
        if (s->step_every < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: step_every must be >= 1, got %lld",
                           (long long)s->step_every);
    }
    if (s->kind == CR_LR_COSINE) {
        if (!(s->final >= 0.0f && s->final <= s->base))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "lr schedule: final must be in [0, base=%g], got %g", (double)s->base,
                           (double)s->final);
        if (s->total_steps < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "lr schedule: total_steps must be >= 1, got %lld",
                           (long long)s->total_steps);
    }
    return CR_OK;
}

float cr_lr_at(const cr_lr_schedule *s, int64_t step) {
    CR_ASSERT(step >= 0);
    double base = s->base;
    if (step < s->warmup_steps) return (float)(base * (double)(step + 1) / (double)s->warmup_steps);
    int64_t k = step - s->warmup_steps;
    switch (s->kind) {
    case CR_LR_CONSTANT:
        return s->base;
    case CR_LR_STEP:
        return (float)(base * pow((double)s->gamma, (double)(k / s->step_every)));
    case CR_LR_COSINE:
        if (k >= s->total_steps) return s->final;
        return (float)(s->final + (base - s->final) * 0.5 *
                                      (1.0 + cos(M_PI * (double)k / (double)s->total_steps)));
    }
    CR_ASSERT(!"unknown schedule kind");
    return 0.0f;
}

/* -------------------------------------------------------------- optimiser -- */

typedef struct range {
    int64_t begin, end; /* floats into the blocks */
} range;

struct cr_optim {
    cr_optim_def def;
    cr_nn_params *params;
    int64_t n;     /* floats in the blocks (padding included) when created */
    int nparams;   /* parameters when created */
    float *state;  /* (nstate, n) moments, one allocation */
    int nstate;    /* 0, 1 or 2 buffers */
    int64_t t;     /* steps taken */
    range *ranges; /* (nparams) scratch for the trainable ranges of a step */
};

const char *cr_optim_kind_name(cr_optim_kind kind) {
    static const char *const names[CR_OPTIM_KIND_COUNT] = {"sgd", "adam", "adamw"};
    return kind >= 0 && kind < CR_OPTIM_KIND_COUNT ? names[kind] : "unknown";
}

cr_optim_def cr_optim_default_def(cr_optim_kind kind) {
    cr_optim_def d;
    memset(&d, 0, sizeof d);
    d.kind = kind;
    d.lr = cr_lr_default_schedule();
    d.weight_decay = kind == CR_OPTIM_ADAMW ? 0.01f : 0.0f;
    d.momentum = 0.0f;
    d.dampening = 0.0f;
    d.nesterov = 0;
    d.beta1 = 0.9f;
    d.beta2 = 0.999f;
    d.eps = 1e-8f;
    d.cookie = OPTIM_COOKIE;
    return d;
}

static cr_status check_def(const cr_optim_def *d, cr_error *err) {
    if (d->kind < 0 || d->kind >= CR_OPTIM_KIND_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID, "optim: unknown kind %d", (int)d->kind);
    CR_TRY(cr_lr_check(&d->lr, err));
    if (!(d->weight_decay >= 0.0f) || !isfinite(d->weight_decay))
        return CR_FAIL(err, CR_ERR_INVALID, "optim: weight_decay must be >= 0 and finite, got %g",
                       (double)d->weight_decay);
    if (d->kind == CR_OPTIM_SGD) {
        if (!(d->momentum >= 0.0f && d->momentum < 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID, "optim: momentum must be in [0, 1), got %g",
                           (double)d->momentum);
        if (!(d->dampening >= 0.0f && d->dampening <= 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID, "optim: dampening must be in [0, 1], got %g",
                           (double)d->dampening);
        if (d->nesterov && (d->momentum <= 0.0f || d->dampening != 0.0f))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "optim: nesterov needs momentum > 0 and dampening 0 (got %g, %g)",
                           (double)d->momentum, (double)d->dampening);
    } else {
        if (!(d->beta1 >= 0.0f && d->beta1 < 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID, "optim: beta1 must be in [0, 1), got %g",
                           (double)d->beta1);
        if (!(d->beta2 >= 0.0f && d->beta2 < 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID, "optim: beta2 must be in [0, 1), got %g",
                           (double)d->beta2);
        if (!(d->eps > 0.0f) || !isfinite(d->eps))
            return CR_FAIL(err, CR_ERR_INVALID, "optim: eps must be positive and finite, got %g",
                           (double)d->eps);
    }
    return CR_OK;
}

cr_status cr_optim_create(const cr_optim_def *def, cr_nn_params *p, cr_optim **out, cr_error *err) {
    CR_ASSERT(def && p && out && def->cookie == OPTIM_COOKIE);
    *out = NULL;
    CR_TRY(check_def(def, err));
    int64_t n = 0;
    if (!cr_nn_params_data(p, &n) || n == 0 || cr_nn_params_count(p) == 0)
        return CR_FAIL(err, CR_ERR_INVALID, "optim: the parameter store is empty");
    cr_optim *o = cr_calloc(1, sizeof *o, err);
    if (!o) return CR_ERR_MEMORY;
    o->def = *def;
    o->params = p;
    o->n = n;
    o->nparams = cr_nn_params_count(p);
    o->nstate = def->kind == CR_OPTIM_SGD ? (def->momentum > 0.0f ? 1 : 0) : 2;
    o->ranges = cr_calloc((size_t)o->nparams, sizeof *o->ranges, err);
    if (o->ranges && o->nstate > 0)
        o->state = cr_calloc((size_t)o->nstate * (size_t)n, sizeof(float), err);
    if (!o->ranges || (o->nstate > 0 && !o->state)) {
        cr_optim_destroy(o);
        return CR_ERR_MEMORY;
    }
    *out = o;
    return CR_OK;
}

void cr_optim_destroy(cr_optim *o) {
    if (!o) return;
    free(o->state);
    free(o->ranges);
    free(o);
}

int64_t cr_optim_step_count(const cr_optim *o) {
    return o->t;
}

float cr_optim_lr(const cr_optim *o) {
    return cr_lr_at(&o->def.lr, o->t);
}

const cr_optim_def *cr_optim_get_def(const cr_optim *o) {
    return &o->def;
}

cr_nn_params *cr_optim_params(const cr_optim *o) {
    return o->params;
}

int cr_optim_state_count(const cr_optim *o) {
    return o->nstate;
}

float *cr_optim_state(cr_optim *o, int k, const char **name) {
    CR_ASSERT(k >= 0 && k < o->nstate);
    if (name) *name = o->def.kind == CR_OPTIM_SGD ? "momentum" : (k == 0 ? "m" : "v");
    return o->state + (size_t)k * (size_t)o->n;
}

void cr_optim_set_step_count(cr_optim *o, int64_t steps) {
    CR_ASSERT(steps >= 0);
    o->t = steps;
}

/* The trainable parameters as merged [begin, end) ranges of the blocks. */
static int trainable_ranges(cr_nn_params *p, const float *base, range *out) {
    int nr = 0, prev_trainable = 0;
    for (int i = 0; i < cr_nn_params_count(p); i++) {
        cr_tensor *t = cr_nn_params_at(p, i, NULL);
        if (t->numel == 0) continue; /* empty: neither joins nor splits ranges */
        if (!t->requires_grad) {
            prev_trainable = 0;
            continue;
        }
        int64_t begin = t->data - base, end = begin + t->numel;
        if (prev_trainable && nr > 0)
            out[nr - 1].end = end;
        else
            out[nr++] = (range){begin, end};
        prev_trainable = 1;
    }
    return nr;
}

/* CR_ERR_NAN naming the first trainable parameter with a NaN or infinite
 * gradient, and the element. */
static cr_status check_grads(cr_nn_params *p, const char *who, cr_error *err) {
    for (int k = 0; k < cr_nn_params_count(p); k++) {
        const char *name;
        const cr_tensor *t = cr_nn_params_at(p, k, &name);
        if (!t->requires_grad) continue;
        for (int64_t i = 0; i < t->numel; i++)
            if (!isfinite(t->grad[i]))
                return CR_FAIL(err, CR_ERR_NAN,
                               "%s: gradient of '%s' is %s at element %lld of %lld", who, name,
                               isnan(t->grad[i]) ? "NaN" : "infinite", (long long)i,
                               (long long)t->numel);
    }
    return CR_OK;
}

/* Everything one update needs, in float as the elementwise rule uses it. */
typedef struct update {
    float *p, *g, *m, *v; /* offset to the current range */
    float lr, wd, momentum, dampening, beta1, beta2, eps;
    float step_size; /* Adam: lr / (1 - beta1^t) */
    float bc2_sqrt;  /* Adam: sqrt(1 - beta2^t) */
    float decay;     /* AdamW: 1 - lr wd */
    int first;       /* SGD: t == 1, the buffer starts as the gradient */
    int nesterov;
    cr_optim_kind kind;
} update;

static void sgd_range(void *ctx, int64_t begin, int64_t end) {
    const update *u = ctx;
    for (int64_t i = begin; i < end; i++) {
        float g = u->g[i] + u->wd * u->p[i];
        if (u->m) {
            float b = u->first ? g : u->momentum * u->m[i] + (1.0f - u->dampening) * g;
            u->m[i] = b;
            g = u->nesterov ? g + u->momentum * b : b;
        }
        u->p[i] -= u->lr * g;
    }
}

/* Adam over n elements in blocks of a fixed width, the last one through a
 * padded copy: -O2's cost model vectorises only loops of a known count, and
 * only when sqrtf need not set errno (CMakeLists.txt builds this file with
 * -fno-math-errno). sqrt and division round as one element at a time does,
 * so the bits are the same. decay is 1 for Adam, wd 0 for AdamW. */
enum { ADAM_W = 8 };

static void adam_block(float *restrict p, float *restrict m, float *restrict v,
                       const float *restrict g, const update *u, float decay, float wd) {
    const float beta1 = u->beta1, beta2 = u->beta2, c1 = 1.0f - u->beta1, c2 = 1.0f - u->beta2;
    const float step = u->step_size, bc2 = u->bc2_sqrt, eps = u->eps;
    for (int k = 0; k < ADAM_W; k++) {
        const float pk = p[k] * decay, gk = g[k] + wd * pk;
        const float mk = beta1 * m[k] + c1 * gk, vk = beta2 * v[k] + c2 * gk * gk;
        m[k] = mk, v[k] = vk;
        p[k] = pk - step * mk / (sqrtf(vk) / bc2 + eps);
    }
}

static void adam_range(void *ctx, int64_t begin, int64_t end) {
    const update *u = ctx;
    const int w = u->kind == CR_OPTIM_ADAMW;
    const float decay = w ? u->decay : 1.0f, wd = w ? 0.0f : u->wd;
    for (int64_t i = begin; i < end; i += ADAM_W) {
        if (end - i >= ADAM_W) {
            adam_block(u->p + i, u->m + i, u->v + i, u->g + i, u, decay, wd);
            continue;
        }
        float t[4][ADAM_W] = {{0}};
        const size_t bytes = (size_t)(end - i) * sizeof(float);
        memcpy(t[0], u->p + i, bytes), memcpy(t[1], u->m + i, bytes);
        memcpy(t[2], u->v + i, bytes), memcpy(t[3], u->g + i, bytes);
        adam_block(t[0], t[1], t[2], t[3], u, decay, wd);
        memcpy(u->p + i, t[0], bytes), memcpy(u->m + i, t[1], bytes), memcpy(u->v + i, t[2], bytes);
    }
}

cr_status cr_optim_step(cr_optim *o, cr_error *err) {
    int64_t n = 0;
    float *data = cr_nn_params_data(o->params, &n);
    float *grad = cr_nn_params_grad(o->params, NULL);
    if (n != o->n || cr_nn_params_count(o->params) != o->nparams)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "optim: parameters were added after the optimiser was created (%d -> %d)",
                       o->nparams, cr_nn_params_count(o->params));
    int nr = trainable_ranges(o->params, data, o->ranges);
    CR_TRY(check_grads(o->params, "optim", err));

    const cr_optim_def *d = &o->def;
    int64_t t = o->t + 1;
    update u;
    memset(&u, 0, sizeof u);
    u.kind = d->kind;
    u.lr = cr_lr_at(&d->lr, o->t);
    u.wd = d->weight_decay;
    u.momentum = d->momentum;
    u.dampening = d->dampening;
    u.nesterov = d->nesterov;
    u.first = t == 1;
    u.beta1 = d->beta1;
    u.beta2 = d->beta2;
    u.eps = d->eps;
    u.step_size = (float)((double)u.lr / (1.0 - pow((double)d->beta1, (double)t)));
    u.bc2_sqrt = (float)sqrt(1.0 - pow((double)d->beta2, (double)t));
    u.decay = (float)(1.0 - (double)u.lr * (double)d->weight_decay);
    cr_range_fn fn = d->kind == CR_OPTIM_SGD ? sgd_range : adam_range;
    for (int k = 0; k < nr; k++) {
        int64_t b = o->ranges[k].begin;
        u.p = data + b;
        u.g = grad + b;
        u.m = o->nstate > 0 ? o->state + b : NULL;
        u.v = o->nstate > 1 ? o->state + o->n + b : NULL;
        cr_parallel_for(o->ranges[k].end - b, STEP_GRAIN, fn, &u);
    }
    o->t = t;
    return CR_OK;
}

/* --------------------------------------------------------------- clipping -- */

cr_status cr_clip_grad_norm(cr_nn_params *p, float max_norm, float *norm_before, cr_error *err) {
    if (norm_before) *norm_before = 0.0f;
    if (!(max_norm > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "clip_grad_norm: max_norm must be positive, got %g",
                       (double)max_norm);
    CR_TRY(check_grads(p, "clip_grad_norm", err));
    int np = cr_nn_params_count(p);
    double sq = 0.0;
    for (int k = 0; k < np; k++) {
        const cr_tensor *t = cr_nn_params_at(p, k, NULL);
        if (!t->requires_grad) continue;
        for (int64_t i = 0; i < t->numel; i++)
            sq += (double)t->grad[i] * (double)t->grad[i];
    }
    double norm = sqrt(sq);
    if (norm_before) *norm_before = (float)norm;
    if (norm <= (double)max_norm) return CR_OK;
    float scale = (float)((double)max_norm / norm);
    for (int k = 0; k < np; k++) {
        cr_tensor *t = cr_nn_params_at(p, k, NULL);
        if (!t->requires_grad) continue;
        for (int64_t i = 0; i < t->numel; i++)
            t->grad[i] *= scale;
    }
    return CR_OK;
}
