/* train.c: training SwinGar's estimator (paper 002, sec. IV): Adam 1e-3
 * with cosine decay, batches of windows over sequences, the vertex loss
 * alone until the vertex error stalls, then every loss of eq. 11-14;
 * checkpoints each epoch and bit-exact resume; the def as JSON. */
#include "swingar_internal.h"

#include "crease/losses.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_optim.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SWG_TRAIN_COOKIE 0x53575431u

/* ------------------------------------------------------------ def JSON -- */

/* The model def's keys (crease/base.h's config table): what a model file's
 * config holds, read back with unknown keys refused by name; ranges are
 * cr_swingar_def_validate's. The norm enum is stored as its int value. */
#define DK_I(f, n)                                                                                 \
    { n, CR_CFG_INT, offsetof(cr_swingar_def, f), 0, 1, 0, NULL, NULL, NULL }
#define DK_F(f)                                                                                    \
    { #f, CR_CFG_FLOAT, offsetof(cr_swingar_def, f), 0, 1, 0, NULL, NULL, NULL }
static const cr_config_key def_keys[] = {
    DK_I(descriptor_len, "descriptor_len"),
    DK_I(garment_width[0], "garment_width0"),
    DK_I(garment_width[1], "garment_width1"),
    DK_I(garment_heads, "garment_heads"),
    DK_I(shape_width[0], "shape_width0"),
    DK_I(shape_width[1], "shape_width1"),
    DK_I(shape_width[2], "shape_width2"),
    DK_I(motion_window, "motion_window"),
    DK_I(motion_hidden, "motion_hidden"),
    DK_I(body_width[0], "body_width0"),
    DK_I(body_width[1], "body_width1"),
    DK_I(body_width[2], "body_width2"),
    DK_I(state_width, "state_width"),
    DK_I(state_heads, "state_heads"),
    DK_I(blend_width[0], "blend_width0"),
    DK_I(blend_width[1], "blend_width1"),
    DK_I(blend_heads, "blend_heads"),
    DK_I(corr_hidden, "corr_hidden"),
    DK_I(corr_heads, "corr_heads"),
    DK_I(corr_width, "corr_width"),
    DK_F(alpha),
    DK_I(norm, "norm"),
    DK_I(skin_prior, "skin_prior"),
    DK_I(use_descriptor, "use_descriptor"),
    DK_I(zero_last, "zero_last"),
    DK_F(corr_scale),
    /* the descriptor the model was trained on: run and --resume compute the same one
       (a model written before the field has none and is geodesic, the default) */
    DK_I(affinity, "affinity"),
};
enum { NDEF_KEYS = sizeof def_keys / sizeof def_keys[0] };
_Static_assert(sizeof(cr_gat_norm) == sizeof(int), "the norm enum is read and written as an int");

static cJSON *def_json(const cr_swingar_def *d) {
    return cr_config_to_object(def_keys, NDEF_KEYS, d);
}

char *cr_swingar_def_to_json(const cr_swingar_def *def) {
    cJSON *o = def_json(def);
    char *s = o ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    return s;
}

static cr_status def_parse(const cJSON *o, const char *source, cr_swingar_def *def, cr_error *err) {
    cr_swingar_def d = *def;
    CR_TRY(cr_config_parse_object(o, source, def_keys, NDEF_KEYS, &d, err));
    CR_TRY(cr_swingar_def_validate(&d, err));
    *def = d;
    return CR_OK;
}

cr_status cr_swingar_def_from_json(const char *json, const char *source, cr_swingar_def *def,
                                   cr_error *err) {
    cJSON *o = cJSON_Parse(json);
    if (!o) return CR_FAIL(err, CR_ERR_PARSE, "%s: model def is not JSON", source);
    cr_status st = def_parse(o, source, def, err);
    cJSON_Delete(o);
    return st;
}

/* ------------------------------------------------------- save and load -- */

static char *config_text(const cr_swingar_def *d, cJSON *train) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "format", "crease-swingar");
    cJSON_AddItemToObject(o, "model", def_json(d));
    if (train) cJSON_AddItemToObject(o, "train", train);
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

cr_status cr_swingar_save(const char *path, cr_swingar *m, cr_error *err) {
    cr_checkpoint_meta meta;
    memset(&meta, 0, sizeof meta);
    meta.config_json = config_text(&m->def, NULL);
    if (!meta.config_json) return CR_FAIL(err, CR_ERR_MEMORY, "swingar: out of memory");
    cr_status st = cr_checkpoint_save(path, m->P, NULL, &meta, err);
    free(meta.config_json);
    return st;
}

/* The model def stored in a checkpoint's config, and its "train" object
 * (a copy the caller deletes, or NULL). */
static cr_status read_config(const char *path, cr_swingar_def *def, cJSON **train, cr_error *err) {
    cr_safetensors st;
    CR_TRY(cr_safetensors_read(path, &st, err));
    const char *cfg = cr_safetensors_meta(&st, "config");
    cJSON *o = cfg ? cJSON_Parse(cfg) : NULL;
    cr_status s = CR_OK;
    const char *fmt =
        o ? cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, "format")) : NULL;
    if (!fmt || strcmp(fmt, "crease-swingar") != 0)
        s = CR_FAIL(err, CR_ERR_PARSE, "%s: not a swingar model (no swingar config)", path);
    if (s == CR_OK) {
        *def = cr_swingar_default_def();
        s = def_parse(cJSON_GetObjectItemCaseSensitive(o, "model"), path, def, err);
    }
    if (s == CR_OK && train) {
        cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "train");
        *train = t ? cJSON_Duplicate(t, 1) : NULL;
    }
    cJSON_Delete(o);
    cr_safetensors_free(&st);
    return s;
}

cr_status cr_swingar_read_def(const char *path, cr_swingar_def *def, cr_error *err) {
    return read_config(path, def, NULL, err);
}

cr_status cr_swingar_load(const char *path, cr_swingar **out, cr_error *err) {
    *out = NULL;
    cr_swingar_def d;
    CR_TRY(read_config(path, &d, NULL, err));
    cr_swingar *m = NULL;
    CR_TRY(cr_swingar_create(&d, 0, &m, err));
    cr_status st = cr_checkpoint_load(path, m->P, NULL, NULL, err);
    if (st != CR_OK) {
        cr_swingar_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

/* ------------------------------------------------------------ training -- */

cr_swingar_train_def cr_swingar_train_default_def(void) {
    cr_swingar_train_def d;
    memset(&d, 0, sizeof d);
    d.model = cr_swingar_default_def();
    d.loss = cr_swingar_loss_default_def();
    d.epochs = 10;
    d.window = 8;
    d.batch = 4;
    d.lr = 1e-3f;
    d.lr_final = 0.0f;
    d.stall_epochs = 0; /* relative to the run (stall_window) */
    d.stall_rel = 0.02f;
    d.seed = 1;
    d.arena_bytes = (size_t)1 << 30;
    d.cookie = SWG_TRAIN_COOKIE;
    return d;
}

/* The train def's numeric fields: the options of `crease swingar train` with their
 * ranges and help (CLI_KEYS). */
#define TK(...) CR_CONFIG_KEY(cr_swingar_train_def, __VA_ARGS__)
static const cr_config_key train_keys[] = {
    TK(epochs, CR_CFG_INT, 1, 1000000, "--epochs", "N", "epochs"),
    TK(window, CR_CFG_INT, 1, SWG_MAX_WINDOW, "--window", "K", "frames predicted per sample"),
    TK(batch, CR_CFG_INT, 1, 100000, "--batch", "B", "samples per Adam step"),
    TK(lr, CR_CFG_FLOAT, 1e-8, 1, "--lr", "X", "Adam's rate, cosine-annealed to 0"),
    TK(stall_epochs, CR_CFG_INT, 0, 1000000, "--stall-epochs", "N",
       "vertex loss alone until the vertex error improves by less than --stall-rel over N "
       "epochs (default a tenth of the epochs, at least 2, and at the latest after half of "
       "them; the paper's 50 are a sliver of its run)"),
    TK(stall_rel, CR_CFG_FLOAT, 0, 1, "--stall-rel", "X", "that relative improvement"),
    TK(seed, CR_CFG_U64, 0, 2147483647, "--seed", "N", "initialisation and shuffling"),
    TK(quiet, CR_CFG_BOOL, 0, 1, "--quiet", NULL, "no progress bar"),
};
#undef TK

const cr_config_key *cr_swingar_train_def_keys(int *n) {
    *n = (int)(sizeof train_keys / sizeof train_keys[0]);
    return train_keys;
}

typedef struct window {
    int32_t seq, t0, K;
} window;

/* The stall rule (sec. IV): switch to every loss when the epoch's vertex
 * error improved by less than stall_rel (relative) over the last
 * stall_epochs epochs. */
static int stalled(const float *hist, int e, int S, float rel) {
    if (e < S || S < 1) return 0;
    float then = hist[e - S], now = hist[e];
    return then <= 0 || (then - now) / then < rel;
}

/* The stall rule's window: stall_epochs, or (0) a tenth of the run, at
 * least 2: the paper's 50 epochs are a sliver of its 3.9 M steps, and a
 * window as long as a short run never closes. */
static int stall_window(const cr_swingar_train_def *def) {
    if (def->stall_epochs > 0) return def->stall_epochs;
    return def->epochs / 10 > 2 ? def->epochs / 10 : 2;
}

static cJSON *train_state(int supervised, int switched, const float *hist, int n) {
    cJSON *t = cJSON_CreateObject();
    cJSON_AddNumberToObject(t, "supervised", supervised);
    cJSON_AddNumberToObject(t, "switched_epoch", switched);
    cJSON *h = cJSON_AddArrayToObject(t, "vert_err_history");
    for (int i = 0; i < n; i++) {
        char buf[32]; /* 9 significant digits round-trip a float */
        snprintf(buf, sizeof buf, "%.9g", (double)hist[i]);
        cJSON_AddItemToArray(h, cJSON_CreateString(buf));
    }
    return t;
}

/* train_state's object back: the two flags and one history entry per epoch
 * done, each a decimal string. */
static cr_status read_train_state(const cJSON *t, const char *path, int epochs, float *hist,
                                  int *supervised, int *switched, cr_error *err) {
    if (!cJSON_IsObject(t))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: config has no training state ('train')", path);
    const char *keys[2] = {"supervised", "switched_epoch"};
    int *vals[2] = {supervised, switched};
    for (int k = 0; k < 2; k++) {
        const cJSON *x = cJSON_GetObjectItemCaseSensitive(t, keys[k]);
        if (!cJSON_IsNumber(x))
            return CR_FAIL(err, CR_ERR_PARSE, "%s: training state '%s' is %s", path, keys[k],
                           x ? "not a number" : "missing");
        *vals[k] = x->valueint;
    }
    const cJSON *h = cJSON_GetObjectItemCaseSensitive(t, "vert_err_history");
    if (!cJSON_IsArray(h) || cJSON_GetArraySize(h) != epochs)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: training state 'vert_err_history' is not an array of %d entries "
                       "(one per epoch done)",
                       path, epochs);
    for (int i = 0; i < epochs; i++) {
        const char *v = cJSON_GetStringValue(cJSON_GetArrayItem(h, i));
        char *end = NULL;
        if (v) hist[i] = strtof(v, &end);
        if (!v || end == v || *end)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: training state 'vert_err_history' entry %d is not a number "
                           "string",
                           path, i);
    }
    return CR_OK;
}

static double seq_error(cr_swingar *m, const cr_swingar_data *d, int32_t si, size_t arena,
                        cr_error *err, cr_status *st) {
    const cr_swingar_sequence *s = &d->sequences[si];
    const cr_swingar_garment *g = d->garments[s->garment_index];
    cr_swingar_motion mo = {s->nframes, d->bodies[s->body_index].model->joints, s->poses, s->trans};
    const int64_t V = g->rest->nv;
    float *pred = malloc(sizeof(float) * (size_t)(s->nframes * V * 3));
    if (!pred) {
        *st = CR_FAIL(err, CR_ERR_MEMORY, "swingar: out of memory");
        return 0;
    }
    *st = cr_swingar_predict(m, g, &mo, arena, pred, err);
    double sum = 0;
    for (int64_t i = 0; *st == CR_OK && i < s->nframes * V; i++) {
        const float *a = pred + 3 * i, *b = s->garment_pos + 3 * i;
        sum += sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) + (double)(a[1] - b[1]) * (a[1] - b[1]) +
                    (double)(a[2] - b[2]) * (a[2] - b[2]));
    }
    free(pred);
    return sum / (double)(s->nframes * V);
}

/* What a training run holds, released together. */
typedef struct train_run {
    const cr_swingar_train_def *def;
    const cr_swingar_data *d;
    window *win;    /* (nw) the training sequences cut into windows */
    int32_t *order; /* (nw) this epoch's shuffle */
    int32_t nw;
    float *hist;             /* (epochs) each epoch's mean vertex error, m */
    cr_loss_collider **coll; /* (bodies) */
    cr_swingar *m;
    cr_optim *opt;
    cr_nn_ctx *ctx;
    cr_rng rng;
    int supervised, switched; /* the data term alone; the epoch that switched, or -1 */
} train_run;

static void train_run_free(train_run *r) {
    cr_nn_ctx_destroy(r->ctx);
    for (int32_t b = 0; b < r->d->nbodies && r->coll; b++)
        cr_loss_collider_destroy(r->coll[b]);
    free(r->coll);
    cr_optim_destroy(r->opt);
    free(r->win), free(r->order), free(r->hist);
}

/* Windows of def->window frames over the training sequences. */
static cr_status make_windows(train_run *r, cr_error *err) {
    const cr_swingar_train_def *def = r->def;
    const cr_swingar_data *d = r->d;
    int32_t nw = 0;
    for (int32_t i = 0; i < d->nsequences; i++)
        if (!def->is_test || def->is_test[i] == 0)
            nw += (d->sequences[i].nframes + def->window - 1) / def->window;
    r->win = malloc(sizeof(window) * (size_t)(nw > 0 ? nw : 1));
    r->order = malloc(sizeof(int32_t) * (size_t)(nw > 0 ? nw : 1));
    r->hist = calloc((size_t)def->epochs, sizeof(float));
    r->coll = calloc((size_t)(d->nbodies > 0 ? d->nbodies : 1), sizeof *r->coll);
    if (!r->win || !r->order || !r->hist || !r->coll)
        return CR_FAIL(err, CR_ERR_MEMORY, "swingar: out of memory");
    if (nw == 0) return CR_FAIL(err, CR_ERR_INVALID, "swingar train: no training sequence");
    r->nw = 0;
    for (int32_t i = 0; i < d->nsequences; i++) {
        if (def->is_test && def->is_test[i] != 0) continue;
        int32_t T = d->sequences[i].nframes;
        for (int32_t t0 = 0; t0 < T; t0 += def->window) {
            r->win[r->nw] = (window){i, t0, T - t0 < def->window ? T - t0 : def->window};
            r->order[r->nw] = r->nw;
            r->nw++;
        }
    }
    return CR_OK;
}

/* The model and optimiser, resumed from def->resume's checkpoint (*epoch0
 * the epoch to start at), the bodies' colliders and the context. */
static cr_status start_run(train_run *r, const cr_swingar_def *mdef, const cJSON *tstate,
                           int *epoch0, cr_error *err) {
    const cr_swingar_train_def *def = r->def;
    const int64_t steps_per_epoch = (r->nw + def->batch - 1) / def->batch;
    CR_TRY(cr_swingar_create(mdef, def->seed, &r->m, err));
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.base = def->lr;
    od.lr.kind = CR_LR_COSINE;
    od.lr.final = def->lr_final;
    od.lr.total_steps = steps_per_epoch * def->epochs;
    CR_TRY(cr_optim_create(&od, r->m->P, &r->opt, err));
    r->rng = cr_rng_make(def->seed, 21);
    *epoch0 = 0, r->supervised = 1, r->switched = -1;
    if (!def->resume && mdef->use_descriptor) /* a resumed model has its own */
        CR_TRY(cr_swingar_standardise_descriptor_(r->m, r->d, def->is_test, err));
    if (def->resume) {
        cr_checkpoint_meta meta;
        memset(&meta, 0, sizeof meta);
        CR_TRY(cr_checkpoint_load(def->resume, r->m->P, r->opt, &meta, err));
        *epoch0 = (int)meta.epoch;
        r->rng = meta.rng;
        free(meta.config_json);
        if (*epoch0 > def->epochs)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: epoch %d is past --epochs %d", def->resume,
                           *epoch0, def->epochs);
        CR_TRY(read_train_state(tstate, def->resume, *epoch0, r->hist, &r->supervised, &r->switched,
                                err));
    }
    for (int32_t b = 0; b < r->d->nbodies; b++) {
        const cr_mesh *rest = r->d->bodies[b].model->rest;
        CR_TRY(cr_loss_collider_create(rest->pos, rest->nv, rest->tri, rest->nf, &r->coll[b], err));
    }
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = def->arena_bytes;
    return cr_nn_ctx_create(&cd, &r->ctx, err);
}

/* One epoch over the shuffled windows, def->batch a step: the sums of the
 * loss and of the vertex error over the windows. */
static cr_status train_epoch(train_run *r, int e, double *loss_sum, double *vert_sum,
                             cr_error *err) {
    const cr_swingar_train_def *def = r->def;
    const cr_swingar_data *d = r->d;
    for (int32_t i = 0; i < r->nw; i++) /* from the identity: resumable from the rng alone */
        r->order[i] = i;
    cr_rng_shuffle_i32(&r->rng, r->order, r->nw);
    cr_swingar_loss_def ld = def->loss;
    ld.supervised_only = r->supervised;
    *loss_sum = 0, *vert_sum = 0;
    cr_progress bar;
    char label[64];
    snprintf(label, sizeof label, "epoch %d/%d", e + 1, def->epochs);
    cr_progress_begin(&bar, label, r->nw, def->quiet);
    cr_status st = CR_OK;
    for (int32_t b0 = 0; st == CR_OK && b0 < r->nw; b0 += def->batch) {
        int32_t nb = r->nw - b0 < def->batch ? r->nw - b0 : def->batch;
        cr_nn_params_zero_grad(r->m->P);
        for (int32_t k = 0; st == CR_OK && k < nb; k++) {
            const window *w = &r->win[r->order[b0 + k]];
            const cr_swingar_sequence *s = &d->sequences[w->seq];
            const cr_swingar_garment *g = d->garments[s->garment_index];
            const cr_body_model *bm = d->bodies[s->body_index].model;
            cr_swingar_motion mo = {s->nframes, bm->joints, s->poses, s->trans};
            const int64_t V = g->rest->nv, Vb = bm->rest->nv;
            cr_nn_ctx_reset(r->ctx);
            cr_tensor *y = cr_swingar_forward(r->ctx, r->m, g, &mo, w->t0, w->K, NULL);
            cr_swingar_loss_terms terms;
            cr_tensor *loss = cr_swingar_loss(
                r->ctx, &ld, g, y, s->garment_pos + (size_t)w->t0 * V * 3, r->coll[s->body_index],
                s->body_pos + (size_t)w->t0 * Vb * 3, (int32_t)Vb, &terms);
            cr_tensor *scaled = cr_nn_mul_scalar(r->ctx, loss, 1.0f / (float)nb);
            st = cr_nn_backward(r->ctx, scaled, err);
            if (st == CR_OK) {
                *loss_sum += loss->data[0];
                *vert_sum += terms.vert_err_m;
            }
        }
        if (st == CR_OK && def->clip_norm > 0)
            st = cr_clip_grad_norm(r->m->P, def->clip_norm, NULL, err);
        if (st == CR_OK) st = cr_optim_step(r->opt, err);
        cr_progress_update(&bar, b0 + nb, "loss %.4g  vertex %.2f cm", *loss_sum / (b0 + nb),
                           100.0 * *vert_sum / (b0 + nb));
    }
    cr_progress_end(&bar);
    return st;
}

/* Epoch e's means into the result and the history, the supervised switch,
 * and the checkpoint. */
static cr_status end_epoch(train_run *r, int e, int epoch0, double loss_sum, double vert_sum,
                           cr_swingar_train_result *res, cr_error *err) {
    const cr_swingar_train_def *def = r->def;
    r->hist[e] = (float)(vert_sum / r->nw);
    if (e == epoch0 && epoch0 == 0) {
        res->first_loss = (float)(loss_sum / r->nw);
        res->first_vert_m = r->hist[e];
    }
    res->last_loss = (float)(loss_sum / r->nw);
    res->last_vert_m = r->hist[e];
    /* every loss from the stall on, and (the relative rule) at the latest for the run's
     * second half */
    if (r->supervised && (stalled(r->hist, e, stall_window(def), def->stall_rel) ||
                          (def->stall_epochs == 0 && e + 1 >= def->epochs / 2))) {
        r->supervised = 0;
        r->switched = e + 1;
    }
    if (!def->checkpoint) return CR_OK;
    cr_checkpoint_meta meta;
    memset(&meta, 0, sizeof meta);
    meta.epoch = e + 1;
    meta.step = cr_optim_step_count(r->opt);
    meta.seed = def->seed;
    meta.rng = r->rng;
    meta.loss = res->last_loss;
    meta.config_json =
        config_text(&r->m->def, train_state(r->supervised, r->switched, r->hist, e + 1));
    cr_status st = cr_checkpoint_save(def->checkpoint, r->m->P, r->opt, &meta, err);
    free(meta.config_json);
    return st;
}

cr_status cr_swingar_train(const cr_swingar_train_def *def, const cr_swingar_data *d,
                           cr_swingar **model, cr_swingar_train_result *res, cr_error *err) {
    *model = NULL;
    memset(res, 0, sizeof *res);
    res->switched_epoch = -1;
    res->test_vert_m = -1;
    if (!def || def->cookie != SWG_TRAIN_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar train: def not made by its default_def");
    if (def->epochs < 1 || def->window < 1 || def->window > SWG_MAX_WINDOW || def->batch < 1 ||
        !(def->lr > 0) || def->stall_epochs < 0 || !(def->stall_rel >= 0))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar train: epochs, window (1..%d), batch, lr or stall rule out of "
                       "range",
                       SWG_MAX_WINDOW);
    double t_start = cr_time_now();
    cr_swingar_def mdef = def->model;
    cJSON *tstate = NULL;
    if (def->resume) CR_TRY(read_config(def->resume, &mdef, &tstate, err));
    train_run r = {.def = def, .d = d};
    int epoch0 = 0;
    cr_status st = make_windows(&r, err);
    if (st == CR_OK) st = start_run(&r, &mdef, tstate, &epoch0, err);
    cJSON_Delete(tstate);
    res->params = r.m ? cr_nn_params_numel(r.m->P) : 0;
    int epochs_this_call = 0;
    for (int e = epoch0; st == CR_OK && e < def->epochs; e++) {
        double loss_sum, vert_sum;
        st = train_epoch(&r, e, &loss_sum, &vert_sum, err);
        if (st != CR_OK) break;
        epochs_this_call++;
        st = end_epoch(&r, e, epoch0, loss_sum, vert_sum, res, err);
        res->epochs_done = e + 1;
        if (def->stop_after > 0 && epochs_this_call >= def->stop_after) break;
    }
    res->switched_epoch = r.switched;
    /* held-out error */
    if (st == CR_OK && def->is_test) {
        double sum = 0;
        int n = 0;
        for (int32_t i = 0; st == CR_OK && i < d->nsequences; i++)
            if (def->is_test[i] == 1) {
                sum += seq_error(r.m, d, i, def->arena_bytes, err, &st);
                n++;
            }
        if (n > 0) res->test_vert_m = (float)(sum / n);
    }
    res->seconds = cr_time_now() - t_start;
    train_run_free(&r);
    if (st != CR_OK) {
        cr_swingar_destroy(r.m);
        return st;
    }
    *model = r.m;
    return CR_OK;
}
