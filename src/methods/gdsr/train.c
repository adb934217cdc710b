/* train.c: gdsr training (sec. 4.5): each clip rolled out in frame order on
 * the model's own previous corrections, input noise on C, Eq. 13-19 on the
 * corrected coarse shape, L1 on the fine garment with its regularisers,
 * AdamW with the paper's halving schedule, resumable checkpoints; the model
 * file and its loader; roll-out with explicit collision handling (sec. 4.6). */
#include "gdsr_internal.h"

#include "crease/bvh.h"
#include "crease/losses.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_optim.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

cr_gdsr_train_def cr_gdsr_train_default_def(void) {
    cr_gdsr_train_def d = {.model = cr_gdsr_model_default_def(),
                           .epochs = 20,
                           .lr = 1e-4f,
                           .lr_halve_every = 50,
                           .weight_decay = 0.01f,
                           .noise_m = 0.003f,
                           .w_coarse = 1.0f,
                           .w_fine = 1.0f,
                           .w_normal = 0.01f,
                           /* Eq. 13, 15-18 on C^: off, measured (docs/gdsr.md) */
                           /* 30, not 1: measured on 3 x 120-frame clips, the
                              only setting ahead of upsampling on strain and
                              distance both (docs/gdsr.md, "Longer clips") */
                           .w_stretch = 30.0f,
                           .w_shear = 30.0f,
                           .w_bend = 0.1f,
                           .w_laplacian = 1.0f,
                           .experimental.wrinkle_side = 128,
                           .experimental.wrinkle_patches = 8,
                           .experimental.wrinkle_patch_side = 32,
                           .lambda_c0 = 1.0f,
                           .lambda_w0 = 1.0f,
                           .lambda_step = 0.2f,
                           .lambda_every = 10,
                           .checkpoint_every = 5,
                           .cookie = CR_GDSR_COOKIE};
    return d;
}

/* The train def's fields: their ranges (checked by check_train), and the options of
 * `crease gdsr train` with their help (CLI_KEYS). The model's sizes and seed are here as
 * options; model.c's table is what a model file stores. */
#define TK(...) CR_CONFIG_KEY(cr_gdsr_train_def, __VA_ARGS__)
static const cr_config_key train_keys[] = {
    TK(epochs, CR_CFG_INT, 1, 100000, "--epochs", "N", "passes over every training frame"),
    TK(lr, CR_CFG_FLOAT, 1e-8, 1, "--lr", "R",
       "AdamW base rate (the paper's), halved every --halve-every epochs"),
    TK(lr_halve_every, CR_CFG_INT, 1, 100000, "--halve-every", "N", "epochs between halvings"),
    TK(weight_decay, CR_CFG_FLOAT, 0, 1, NULL, NULL, NULL),
    TK(noise_m, CR_CFG_FLOAT, 0, 0.1, "--noise", "M", "Gaussian noise on the coarse input C, m"),
    TK(w_coarse, CR_CFG_FLOAT, 0, 1e6, "--w-coarse", "W", "weight of the L1 of C^ against C*"),
    TK(w_fine, CR_CFG_FLOAT, 0, 1e6, "--w-fine", "W",
       "weight of the L1 of the high garment against the reference"),
    TK(w_normal, CR_CFG_FLOAT, 0, 1e6, "--w-normal", "W",
       "weight of the L1 of the high garment's face normals"),
    TK(w_stretch, CR_CFG_FLOAT, 0, 1e6, "--w-stretch", "W",
       "Baraff-Witkin stretch of the output, area mean of (|w_u|-1)^2+(|w_v|-1)^2"),
    TK(w_shear, CR_CFG_FLOAT, 0, 1e6, "--w-shear", "W",
       "Baraff-Witkin shear of the output, area mean of (w_u.w_v)^2"),
    TK(w_bend, CR_CFG_FLOAT, 0, 1e6, "--w-bend", "W",
       "dihedral angles toward the reference's, mean k_e/2 dtheta^2"),
    TK(w_laplacian, CR_CFG_FLOAT, 0, 1e6, "--w-laplacian", "W",
       "L1 of the uniform Laplacian of the error, m"),
    TK(experimental.w_strain_l1, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(experimental.w_wrinkle, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(experimental.wrinkle_side, CR_CFG_INT, 8, 2048, NULL, NULL, NULL),
    TK(experimental.wrinkle_patches, CR_CFG_INT, 0, 1024, NULL, NULL, NULL),
    TK(experimental.wrinkle_patch_side, CR_CFG_INT, 1, 2048, NULL, NULL, NULL),
    TK(experimental.w_coarse_normal, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(experimental.w_coarse_smooth, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(experimental.w_coarse_bend, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(experimental.w_coarse_strain, CR_CFG_FLOAT, 0, 1e6, NULL, NULL, NULL),
    TK(lambda_c0, CR_CFG_FLOAT, 1e-3, 100, "--lambda-c0", "L",
       "Eq. 25's weight of the coarse term at the start (the paper's 1.9)"),
    TK(lambda_w0, CR_CFG_FLOAT, 1e-3, 100, "--lambda-w0", "L",
       "Eq. 25's weight of the fine terms at the start (the paper's 0.1)"),
    TK(lambda_step, CR_CFG_FLOAT, 0, 100, "--lambda-step", "S",
       "both move S toward 1 every --lambda-every epochs"),
    TK(lambda_every, CR_CFG_INT, 1, 100000, "--lambda-every", "N", "epochs between those steps"),
    TK(model.latent, CR_CFG_INT, 4, 1024, "--latent", "N", "model size: the latent width"),
    TK(model.steps, CR_CFG_INT, 0, 32, "--steps", "N", "model size: message-passing steps of H"),
    TK(model.wire_width, CR_CFG_INT, 2, CR_WIRE_MAX_WIDTH, "--wire-width", "N",
       "model size: WIRE's width"),
    TK(model.out_scale, CR_CFG_FLOAT, 1e-6, 10, "--out-scale", "S",
       "E's and A's outputs times S m (small: a gentle start from upsampling)"),
    TK(model.sigma_l, CR_CFG_FLOAT, 1e-4, 1, "--sigma-l", "M", "the layer edges' radius, m"),
    TK(model.seed, CR_CFG_U64, 0, 9007199254740992.0, "--seed", "S",
       "initial weights, noise and shuffles"),
    TK(checkpoint_every, CR_CFG_INT, 0, 100000, "--checkpoint-every", "N",
       "epochs between checkpoints (0: at the end)"),
    TK(resume, CR_CFG_BOOL, 0, 1, "--resume", NULL,
       "continue from OUT/checkpoint.safetensors; the model settings (sizes, --out-scale, "
       "--seed, ...) must be the ones it was trained with"),
};
#undef TK
enum { NTRAIN_KEYS = sizeof train_keys / sizeof train_keys[0] };

const cr_config_key *cr_gdsr_train_def_keys(int *n) {
    *n = NTRAIN_KEYS;
    return train_keys;
}

static float toward_one(float v0, float step, int k) {
    float v = v0 > 1.0f ? v0 - step * k : v0 + step * k;
    return (v0 > 1.0f) == (v > 1.0f) ? v : 1.0f;
}

void cr_gdsr_lambdas(const cr_gdsr_train_def *def, int ep, float *lambda_c, float *lambda_w) {
    int k = def->lambda_every > 0 ? ep / def->lambda_every : 0;
    *lambda_c = toward_one(def->lambda_c0, def->lambda_step, k);
    *lambda_w = toward_one(def->lambda_w0, def->lambda_step, k);
}

/* Closest body point of every low vertex of every frame of a clip. */
static cr_status body_points(const cr_gdsr_data *d, const cr_gdsr_clip *c, const float *low,
                             float *out, cr_error *err) {
    cr_bvh *b = NULL;
    CR_TRY(cr_bvh_build(c->body, d->body->nv, d->body->tri, d->body->nf, &b, err));
    int32_t nl = d->low->nv;
    for (int32_t t = 0; t < c->nframes; t++) {
        cr_status st = cr_bvh_refit(b, c->body + (int64_t)t * d->body->nv * 3, err);
        if (st != CR_OK) {
            cr_bvh_destroy(b);
            return st;
        }
        cr_bvh_closest_batch(b, low + (int64_t)t * nl * 3, nl, INFINITY, NULL,
                             out + (int64_t)t * nl * 3, NULL, NULL);
    }
    cr_bvh_destroy(b);
    return CR_OK;
}

/* Face normals (F,3) of positions x (V,3) of mesh m, as a tensor. */
static cr_tensor *face_normals_t(cr_nn_ctx *ctx, cr_tensor *x, const cr_mesh *m, int32_t **cols) {
    cr_tensor *p0 = cr_nn_gather_rows(ctx, x, cols[0], m->nf);
    cr_tensor *u = cr_nn_sub(ctx, cr_nn_gather_rows(ctx, x, cols[1], m->nf), p0);
    cr_tensor *v = cr_nn_sub(ctx, cr_nn_gather_rows(ctx, x, cols[2], m->nf), p0);
    return cr_nn_normalize(ctx, cr_nn_cross(ctx, u, v), 1e-12f);
}

/* The mean L1 of the face normals of x against those of ref (both (V,3) on m). */
static cr_tensor *normal_l1(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *ref, const cr_mesh *m,
                            int32_t **cols) {
    return cr_nn_mean(ctx, cr_nn_abs(ctx, cr_nn_sub(ctx, face_normals_t(ctx, x, m, cols),
                                                    face_normals_t(ctx, ref, m, cols))));
}

typedef struct frame_state {
    float *chat1, *chat2, *dprev; /* (Vl,3) C^_{t-1}, C^_{t-2}, d_{t-1} */
    int have;                     /* frames of the model's own output so far */
    float *e2;                    /* (cap, 8) this frame's layer edge features */
    int64_t e2cap;
} frame_state;

/* Features of frame t (t >= 2) of clip c, input positions cin (Vl,3); with
 * layer edges in the model and two layers or more, this frame's layer edges
 * (set 2 of g, found at cin) and their features (fs->e2). */
static cr_status frame_features(const cr_gdsr_data *d, const cr_gdsr_model_def *md,
                                cr_gdsr_graph *g, const float *low, int32_t t, const float *cin,
                                const float *bp, frame_state *fs, float *node, float *e0, float *e1,
                                cr_error *err) {
    int64_t nl3 = (int64_t)d->low->nv * 3;
    cr_gdsr_frame_in in = {.c = cin,
                           .c_prev = low + (t - 1) * nl3,
                           .c_prev2 = low + (t - 2) * nl3,
                           .d_prev = fs->have >= 1 ? fs->dprev : NULL,
                           .chat_prev = fs->have >= 2 ? fs->chat1 : NULL,
                           .chat_prev2 = fs->have >= 2 ? fs->chat2 : NULL,
                           .body_point = bp};
    float *nrm = malloc((size_t)nl3 * sizeof(float));
    cr_status st =
        cr_gdsr_frame_features_(d, md, g, &in, nrm, node, e0, e1, &fs->e2, &fs->e2cap, err);
    free(nrm);
    return st;
}

static void state_push(frame_state *fs, const float *chat, const float *c, int64_t n3) {
    memcpy(fs->chat2, fs->chat1, (size_t)n3 * sizeof(float));
    memcpy(fs->chat1, chat, (size_t)n3 * sizeof(float));
    for (int64_t i = 0; i < n3; i++)
        fs->dprev[i] = chat[i] - c[i];
    fs->have++;
}

static cr_status save_model(const char *path, cr_gdsr_model *m, cr_error *err) {
    char *js = cr_gdsr_model_def_json(&m->def);
    if (!js) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    cr_st_meta meta[1] = {{"gdsr_model", js}};
    cr_status st = cr_safetensors_save_params(path, m->params, meta, 1, err);
    free(js);
    return st;
}

cr_status cr_gdsr_model_load(const char *path, cr_gdsr_model **out, cr_error *err) {
    *out = NULL;
    cr_safetensors sf = {0};
    CR_TRY(cr_safetensors_read(path, &sf, err));
    cr_gdsr_model_def def;
    /* a checkpoint keeps the def as its "config" and loads as plain weights */
    const char *js = cr_safetensors_meta(&sf, "gdsr_model");
    int ckpt = !js;
    if (ckpt) js = cr_safetensors_meta(&sf, "config");
    cr_status st = cr_gdsr_model_def_from_json(js, path, &def, err);
    cr_gdsr_model *m = NULL;
    if (st == CR_OK) st = cr_gdsr_model_create(&def, &m, err);
    if (st == CR_OK)
        st = ckpt ? cr_checkpoint_load(path, m->params, NULL, NULL, err)
                  : cr_safetensors_to_params(&sf, path, m->params, 1, err);
    cr_safetensors_free(&sf);
    if (st != CR_OK) {
        cr_gdsr_model_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

/* A resume continues the model it loads: the checkpoint's def must be this run's. */
static cr_status check_resumed_def(const char *ckpt, const cr_gdsr_model_def *want, cr_error *err) {
    cr_safetensors sf = {0};
    CR_TRY(cr_safetensors_read(ckpt, &sf, err));
    cr_gdsr_model_def saved;
    cr_status st =
        cr_gdsr_model_def_from_json(cr_safetensors_meta(&sf, "config"), ckpt, &saved, err);
    cr_safetensors_free(&sf);
    CR_TRY(st);
    double a, b;
    const char *field = cr_gdsr_model_def_differ(&saved, want, &a, &b);
    if (field)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: the checkpoint's model has %s %.7g, this run asks for %.7g (a resume "
                       "keeps the model settings)",
                       ckpt, field, a, b);
    return CR_OK;
}

cr_status cr_gdsr_validate(cr_gdsr_model *m, const cr_gdsr_data *d, int first, double *s,
                           double *su, int64_t *n, cr_error *err) {
    int32_t Vh = d->high->nv;
    for (int c = first; c < d->nclips; c++) {
        cr_gdsr_rollout_result r;
        CR_TRY(cr_gdsr_rollout(m, d, c, 0.002f, 0, 0, &r, err)); /* val reads gdsr_raw */
        for (int32_t t = 2; t < r.nframes; t++)
            for (int32_t i = 0; i < Vh; i++) {
                const float *x = r.gdsr_raw + ((int64_t)t * Vh + i) * 3,
                            *u = r.upsampled + ((int64_t)t * Vh + i) * 3,
                            *h = d->clip[c].high + ((int64_t)t * Vh + i) * 3;
                double a = 0, b = 0;
                for (int k = 0; k < 3; k++)
                    a += (double)(x[k] - h[k]) * (x[k] - h[k]),
                        b += (double)(u[k] - h[k]) * (u[k] - h[k]);
                *s += sqrt(a), *su += sqrt(b), (*n)++;
            }
        cr_gdsr_rollout_free(&r);
    }
    return CR_OK;
}

/* What training keeps per garment: its graph, regularisers, scratch, the
 * roll-out state of the clip under way and the body points of its clips. */
typedef struct garment_train {
    const cr_gdsr_data *d;
    int ntrain; /* clips trained on: all but the last val_clips */
    cr_gdsr_graph g;
    gdsr_reg reg, creg; /* on the high mesh (the output), on the low one (C^) */
    gdsr_wrinkle wr;
    int32_t *hcols[3], *lcols[3];
    float *node, *e0, *e1, *cin, *cstar;
    frame_state fs;
    float *bp[CR_GDSR_MAX_CLIPS];
} garment_train;

static void garment_train_free(garment_train *gt) {
    for (int c = 0; c < CR_GDSR_MAX_CLIPS; c++)
        free(gt->bp[c]);
    for (int k = 0; k < 3; k++) {
        free(gt->hcols[k]);
        free(gt->lcols[k]);
    }
    free(gt->node);
    free(gt->e0);
    free(gt->e1);
    free(gt->cin);
    free(gt->cstar);
    free(gt->fs.chat1);
    free(gt->fs.chat2);
    free(gt->fs.dprev);
    free(gt->fs.e2);
    cr_gdsr_graph_free(&gt->g);
    cr_gdsr_reg_free(&gt->reg);
    cr_gdsr_reg_free(&gt->creg);
    cr_gdsr_wrinkle_free(&gt->wr);
    memset(gt, 0, sizeof *gt);
}

static cr_status garment_train_init(garment_train *gt, const cr_gdsr_data *d,
                                    const cr_gdsr_train_def *def, cr_error *err) {
    memset(gt, 0, sizeof *gt);
    gt->d = d;
    gt->ntrain = d->nclips - def->val_clips;
    const cr_mesh *low = d->low, *high = d->high;
    int64_t nl3 = (int64_t)low->nv * 3;
    cr_status st;
    if ((st = cr_gdsr_graph_build(low, &gt->g, err)) != CR_OK) goto fail;
    if ((st = cr_gdsr_reg_create(high, &gt->reg, err)) != CR_OK) goto fail;
    if ((def->experimental.w_coarse_smooth > 0 || def->experimental.w_coarse_bend > 0 ||
         def->experimental.w_coarse_strain > 0) &&
        (st = cr_gdsr_reg_create(low, &gt->creg, err)) != CR_OK)
        goto fail;
    if (def->experimental.w_wrinkle > 0 &&
        (st = cr_gdsr_wrinkle_create(high, def->experimental.wrinkle_side, &gt->wr, err)) != CR_OK)
        goto fail;
    gt->node = malloc((size_t)low->nv * CR_GDSR_NODE_FEATURES * sizeof(float));
    gt->e0 = malloc((size_t)gt->g.ne[0] * CR_GDSR_EDGE_FEATURES * sizeof(float));
    gt->e1 = malloc((size_t)(gt->g.ne[1] + 1) * CR_GDSR_EDGE_FEATURES * sizeof(float));
    gt->cin = malloc((size_t)nl3 * sizeof(float));
    gt->cstar = malloc((size_t)nl3 * sizeof(float));
    gt->fs.chat1 = malloc((size_t)nl3 * sizeof(float));
    gt->fs.chat2 = malloc((size_t)nl3 * sizeof(float));
    gt->fs.dprev = malloc((size_t)nl3 * sizeof(float));
    int ok = gt->node && gt->e0 && gt->e1 && gt->cin && gt->cstar && gt->fs.chat1 && gt->fs.chat2 &&
             gt->fs.dprev;
    for (int k = 0; k < 3; k++) {
        gt->hcols[k] = cr_gdsr_tri_column(high, k);
        gt->lcols[k] = cr_gdsr_tri_column(low, k);
        ok = ok && gt->hcols[k] && gt->lcols[k];
    }
    for (int c = 0; ok && c < gt->ntrain; c++)
        ok = (gt->bp[c] = malloc((size_t)d->clip[c].nframes * nl3 * sizeof(float))) != NULL;
    if (!ok) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto fail;
    }
    for (int c = 0; c < gt->ntrain; c++)
        if ((st = body_points(d, &d->clip[c], d->clip[c].low, gt->bp[c], err)) != CR_OK) goto fail;
    return CR_OK;
fail:
    garment_train_free(gt);
    return st;
}

cr_status cr_gdsr_train(const cr_gdsr_train_def *def, const cr_gdsr_data *d,
                        cr_gdsr_train_result *out, cr_error *err) {
    return cr_gdsr_train_many(def, &d, 1, out, err);
}

/* The def's ranges, and the steps of an epoch over every garment's training
 * clips; *any_layers when a garment is an outfit of layers. */
static cr_status check_train(const cr_gdsr_train_def *def, const cr_gdsr_data *const *data,
                             int ngarments, int64_t *steps_per_epoch, int *any_layers,
                             cr_error *err) {
    if (def->cookie != CR_GDSR_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr train def: not made by cr_gdsr_train_default_def");
    if (!def->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "gdsr train def: out_dir not set");
    if (ngarments < 1 || ngarments > CR_GDSR_MAX_GARMENTS)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr train: %d garments (1..%d)", ngarments,
                       CR_GDSR_MAX_GARMENTS);
    CR_TRY(cr_config_check(train_keys, NTRAIN_KEYS, def, "gdsr train def", err));
    *steps_per_epoch = 0, *any_layers = 0;
    for (int k = 0; k < ngarments; k++) {
        const cr_gdsr_data *d = data[k];
        if (def->val_clips < 0 || def->val_clips >= d->nclips)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "gdsr train def: val_clips %d with %d clips of garment %d (one or "
                           "more must train)",
                           def->val_clips, d->nclips, k + 1);
        for (int c = 0; c < d->nclips; c++) {
            if (!d->clip[c].high)
                return CR_FAIL(err, CR_ERR_INVALID,
                               "gdsr train: clip '%s' of garment %d has no high-resolution "
                               "reference",
                               d->clip[c].motion, k + 1);
            if (c < d->nclips - def->val_clips && d->clip[c].nframes > 2)
                *steps_per_epoch += d->clip[c].nframes - 2;
        }
        *any_layers |= d->nlayers > 1;
    }
    if (*steps_per_epoch < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr train: no clip has 3 frames or more");
    return CR_OK;
}

/* The loss terms, in the order of the log and the result: the coarse L1,
 * the fine L1, the normal term, the fine garment's six regularisers, C^'s
 * four. */
enum { NTERMS = CR_GDSR_NTERMS };
const char *const cr_gdsr_term_names[CR_GDSR_NTERMS] = {
    "coarse_l1_m",   "fine_l1_m",      "normal_l1",       "stretch", "shear",
    "bend",          "laplacian_l1_m", "strain_l1",       "wrinkle", "coarse_normal_l1",
    "coarse_smooth", "coarse_bend",    "coarse_strain_l1"};

/* What a training run holds, released together. */
typedef struct train_run {
    const cr_gdsr_train_def *def;
    cr_gdsr_model *m;
    cr_optim *opt;
    cr_nn_ctx *ctx;
    garment_train gts[CR_GDSR_MAX_GARMENTS];
    gdsr_patch *patches; /* Eq. 24's, or NULL */
    cr_rng rng;          /* the input noise's */
    int64_t steps_per_epoch;
    double sum[NTERMS + 1]; /* the epoch's sums: the weighted loss, then each term */
    int64_t n;              /* steps this epoch */
} train_run;

/* One step: frame t of training clip c of garment gt, on the state the
 * clip's earlier frames left (noisy input, Eq. 13-25, AdamW). */
static cr_status train_frame(train_run *r, garment_train *gt, int c, int32_t t, int ep, float lam_c,
                             float lam_w, cr_error *err) {
    const cr_gdsr_train_def *def = r->def;
    cr_nn_ctx *ctx = r->ctx;
    const cr_gdsr_data *d = gt->d;
    const cr_mesh *low = d->low, *high = d->high;
    const cr_gdsr_clip *cl = &d->clip[c];
    const int64_t nl3 = (int64_t)low->nv * 3, nh3 = (int64_t)high->nv * 3;
    const float *ct = cl->low + t * nl3, *ht = cl->high + t * nh3;
    for (int64_t i = 0; i < nl3; i++)
        gt->cin[i] = ct[i] + def->noise_m * (float)cr_rng_normal(&r->rng);
    cr_gdsr_coarse_target(d, ht, gt->cstar);
    CR_TRY(frame_features(d, &r->m->def, &gt->g, cl->low, t, gt->cin, gt->bp[c] + t * nl3, &gt->fs,
                          gt->node, gt->e0, gt->e1, err));
    cr_nn_ctx_reset(ctx);
    cr_tensor *chat = NULL;
    const float *base = gt->cin; /* noisy: the model learns to denoise */
    cr_tensor *X =
        cr_gdsr_forward(ctx, r->m, d, &gt->g, gt->node, gt->e0, gt->e1, gt->fs.e2, base, &chat);
    cr_tensor *Cs = cr_nn_from(ctx, 2, (int64_t[]){low->nv, 3}, gt->cstar);
    cr_tensor *Hs = cr_nn_from(ctx, 2, (int64_t[]){high->nv, 3}, ht);
    cr_tensor *all[NTERMS] = {0};
    all[0] = cr_nn_mean(ctx, cr_nn_abs(ctx, cr_nn_sub(ctx, chat, Cs)));
    all[1] = cr_nn_mean(ctx, cr_nn_abs(ctx, cr_nn_sub(ctx, X, Hs)));
    all[2] = normal_l1(ctx, X, Hs, high, gt->hcols);
    cr_gdsr_reg_terms(ctx, &gt->reg, X, ht, &all[3], &all[4], &all[5], &all[6]);
    if (def->experimental.w_strain_l1 > 0) all[7] = cr_gdsr_reg_strain_l1(ctx, &gt->reg, X, ht);
    if (def->experimental.w_wrinkle > 0) {
        /* Eq. 24's random patches, drawn from their own counter-based stream
           per step (a pure function of seed and step: resume stays exact) */
        cr_rng prng = cr_rng_make(def->model.seed ^ 0x7061746368ull,
                                  (uint64_t)(ep * r->steps_per_epoch + r->n));
        if (r->patches)
            cr_gdsr_wrinkle_draw_patches(&gt->wr, def->experimental.wrinkle_patches,
                                         def->experimental.wrinkle_patch_side, &prng, r->patches);
        all[8] = cr_gdsr_wrinkle_loss(ctx, &gt->wr, X, ht, r->patches,
                                      r->patches ? def->experimental.wrinkle_patches : 0,
                                      def->experimental.wrinkle_energy);
    }
    /* Eq. 13 and 15-18 on C^ against C* */
    if (def->experimental.w_coarse_normal > 0) all[9] = normal_l1(ctx, chat, Cs, low, gt->lcols);
    if (def->experimental.w_coarse_smooth > 0) all[10] = cr_gdsr_reg_smooth(ctx, &gt->creg, chat);
    if (def->experimental.w_coarse_bend > 0)
        all[11] = cr_gdsr_reg_bend(ctx, &gt->creg, chat, gt->cstar);
    if (def->experimental.w_coarse_strain > 0)
        all[12] = cr_gdsr_reg_strain_l1(ctx, &gt->creg, chat, gt->cstar);
    /* Eq. 25: lambda_c on the coarse terms, lambda_w on the fine garment's */
    const float wall[NTERMS] = {lam_c * def->w_coarse,
                                lam_w * def->w_fine,
                                lam_w * def->w_normal,
                                lam_w * def->w_stretch,
                                lam_w * def->w_shear,
                                lam_w * def->w_bend,
                                lam_w * def->w_laplacian,
                                lam_w * def->experimental.w_strain_l1,
                                lam_w * def->experimental.w_wrinkle,
                                lam_c * def->experimental.w_coarse_normal,
                                lam_c * def->experimental.w_coarse_smooth,
                                lam_c * def->experimental.w_coarse_bend,
                                lam_c * def->experimental.w_coarse_strain};
    cr_tensor *terms[NTERMS];
    float w[NTERMS];
    int nt = 0;
    for (int q = 0; q < NTERMS; q++) /* the terms off (weight 0) were not built */
        if (all[q]) terms[nt] = all[q], w[nt++] = wall[q];
    cr_tensor *loss = cr_loss_weighted_sum(ctx, terms, w, nt, NULL);
    CR_TRY(cr_nn_ctx_error(ctx, err));
    cr_nn_params_zero_grad(r->m->params);
    CR_TRY(cr_nn_backward(ctx, loss, err));
    CR_TRY(cr_optim_step(r->opt, err));
    r->sum[0] += loss->data[0];
    for (int q = 0; q < NTERMS; q++)
        r->sum[1 + q] += all[q] ? all[q]->data[0] : 0.0;
    r->n++;
    state_push(&gt->fs, chat->data, base, nl3);
    return CR_OK;
}

/* The epoch's means into the result, and its line of log.jsonl. */
static void end_epoch(const train_run *r, int ep, float lam_c, float lam_w, double seconds,
                      FILE *log, cr_gdsr_train_result *out) {
    const double n = (double)r->n;
    out->epochs = ep + 1;
    out->last_loss = r->sum[0] / n;
    fprintf(log, "{\"epoch\":%d,\"loss\":%.9g,", ep + 1, out->last_loss);
    for (int q = 0; q < NTERMS; q++) {
        out->last_term[q] = r->sum[1 + q] / n;
        fprintf(log, "\"%s\":%.9g,", cr_gdsr_term_names[q], out->last_term[q]);
    }
    fprintf(log,
            "\"lambda_c\":%.3g,\"lambda_w\":%.3g,\"val_med_m\":%.9g,"
            "\"val_upsampled_med_m\":%.9g,\"lr\":%.6g,\"seconds\":%.3f}\n",
            (double)lam_c, (double)lam_w, isnan(out->last_val_med) ? -1.0 : out->last_val_med,
            isnan(out->val_upsampled_med) ? -1.0 : out->val_upsampled_med,
            (double)cr_optim_lr(r->opt), seconds);
    fflush(log);
}

/* The model, optimiser, context and per-garment state; resumed from the
 * checkpoint with def->resume; *epoch0 the epoch to start at. */
static cr_status start_run(train_run *r, const cr_gdsr_data *const *data, int ngarments,
                           int any_layers, const char *ckpt, int *epoch0, cr_error *err) {
    const cr_gdsr_train_def *def = r->def;
    cr_gdsr_model_def md = def->model;
    if (md.layer_edges < 0) md.layer_edges = any_layers; /* auto: on for an outfit */
    CR_TRY(cr_gdsr_model_create(&md, &r->m, err));
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAMW);
    od.lr.kind = CR_LR_STEP;
    od.lr.base = def->lr;
    od.lr.gamma = 0.5f;
    od.lr.step_every = (int64_t)def->lr_halve_every * r->steps_per_epoch;
    od.weight_decay = def->weight_decay;
    CR_TRY(cr_optim_create(&od, r->m->params, &r->opt, err));
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)768 << 20;
    CR_TRY(cr_nn_ctx_create(&cd, &r->ctx, err));
    for (int k = 0; k < ngarments; k++)
        CR_TRY(garment_train_init(&r->gts[k], data[k], def, err));
    if (def->experimental.w_wrinkle > 0 && def->experimental.wrinkle_patches > 0 &&
        !(r->patches = malloc((size_t)def->experimental.wrinkle_patches * sizeof *r->patches)))
        return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    *epoch0 = 0;
    r->rng = cr_rng_make(def->model.seed, 7);
    if (!def->resume) return CR_OK;
    FILE *f = fopen(ckpt, "rb");
    if (!f) {
        cr_log(CR_LOG_WARN, "gdsr train: --resume: no checkpoint at %s; training from the start",
               ckpt);
        return CR_OK;
    }
    fclose(f);
    CR_TRY(check_resumed_def(ckpt, &r->m->def, err));
    cr_checkpoint_meta meta = {0};
    CR_TRY(cr_checkpoint_load(ckpt, r->m->params, r->opt, &meta, err));
    free(meta.config_json);
    *epoch0 = (int)meta.epoch;
    r->rng = meta.rng;
    return CR_OK;
}

static cr_status save_checkpoint(const train_run *r, const char *ckpt, int epochs, float loss,
                                 cr_error *err) {
    char *js = cr_gdsr_model_def_json(&r->m->def);
    cr_checkpoint_meta meta = {.epoch = epochs,
                               .step = cr_optim_step_count(r->opt),
                               .seed = r->def->model.seed,
                               .rng = r->rng,
                               .loss = loss,
                               .config_json = js};
    cr_status st = cr_checkpoint_save(ckpt, r->m->params, r->opt, &meta, err);
    free(js);
    return st;
}

cr_status cr_gdsr_train_many(const cr_gdsr_train_def *def, const cr_gdsr_data *const *data,
                             int ngarments, cr_gdsr_train_result *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    int any_layers = 0;
    train_run r = {.def = def};
    CR_TRY(check_train(def, data, ngarments, &r.steps_per_epoch, &any_layers, err));
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    char ckpt[1100], model_path[1100], log_path[1100];
    snprintf(ckpt, sizeof ckpt, "%s/checkpoint.safetensors", def->out_dir);
    snprintf(model_path, sizeof model_path, "%s/model.safetensors", def->out_dir);
    snprintf(log_path, sizeof log_path, "%s/log.jsonl", def->out_dir);
    double t0 = cr_time_now();
    FILE *log = NULL;
    int epoch0 = 0;
    cr_status st = start_run(&r, data, ngarments, any_layers, ckpt, &epoch0, err);
    if (r.m) out->params = cr_nn_params_numel(r.m->params);
    out->resumed_from = epoch0;
    out->epochs = epoch0;
    if (st == CR_OK) st = cr_train_log_cut(log_path, epoch0, err);
    if (st == CR_OK && !(log = fopen(log_path, "a")))
        st = CR_FAIL(err, CR_ERR_IO, "%s: cannot open for writing", log_path);
    for (int ep = epoch0; st == CR_OK && ep < def->epochs; ep++) {
        float lam_c, lam_w;
        cr_gdsr_lambdas(def, ep, &lam_c, &lam_w);
        memset(r.sum, 0, sizeof r.sum);
        r.n = 0;
        /* garment by garment, each one's clips in order (one garment: the clips in order) */
        for (int k = 0; k < ngarments && st == CR_OK; k++) {
            garment_train *gt = &r.gts[k];
            for (int c = 0; c < gt->ntrain && st == CR_OK; c++) {
                gt->fs.have = 0;
                for (int32_t t = 2; t < gt->d->clip[c].nframes && st == CR_OK; t++)
                    st = train_frame(&r, gt, c, t, ep, lam_c, lam_w, err);
            }
        }
        if (st != CR_OK) break;
        out->last_val_med = out->val_upsampled_med = NAN;
        if (def->val_clips > 0) { /* over every garment's held-out clips, vertex-frames weighted */
            double vs = 0, vsu = 0;
            int64_t vn = 0;
            for (int k = 0; k < ngarments && st == CR_OK; k++)
                st = cr_gdsr_validate(r.m, r.gts[k].d, r.gts[k].ntrain, &vs, &vsu, &vn, err);
            if (st != CR_OK) break;
            if (vn > 0) out->last_val_med = vs / vn, out->val_upsampled_med = vsu / vn;
        }
        end_epoch(&r, ep, lam_c, lam_w, cr_time_now() - t0, log, out);
        if (ep == epoch0) out->first_loss = out->last_loss;
        if (!def->quiet)
            fprintf(
                stderr,
                "\rgdsr train: epoch %d/%d loss %.4g (coarse %.3g m, fine %.3g m, val MED %.4g m "
                "vs upsampling %.4g m)",
                ep + 1, def->epochs, out->last_loss, out->last_term[CR_GDSR_TERM_COARSE],
                out->last_term[CR_GDSR_TERM_FINE], out->last_val_med, out->val_upsampled_med);
        int every = def->checkpoint_every;
        if ((every > 0 && (ep + 1) % every == 0) || ep + 1 == def->epochs)
            st = save_checkpoint(&r, ckpt, ep + 1, (float)out->last_loss, err);
    }
    if (st == CR_OK && !def->quiet) fprintf(stderr, "\n");
    if (st == CR_OK) st = save_model(model_path, r.m, err);
    out->seconds = cr_time_now() - t0;
    if (log) fclose(log);
    for (int k = 0; k < ngarments; k++)
        garment_train_free(&r.gts[k]);
    free(r.patches);
    cr_nn_ctx_destroy(r.ctx);
    cr_optim_destroy(r.opt);
    cr_gdsr_model_destroy(r.m);
    return st;
}

/* --------------------------------------------------------- roll-out -- */

const char *const cr_gdsr_stage_names[4] = {"body", "features", "networks", "handling"};

void cr_gdsr_rollout_free(cr_gdsr_rollout_result *r) {
    if (!r) return;
    free(r->gdsr);
    free(r->gdsr_raw);
    free(r->upsampled);
    memset(r, 0, sizeof *r);
}

/* The largest share of high vertices inside the body over the clip, before
 * and after the handling. */
static cr_status inside_shares(const cr_gdsr_data *d, const cr_gdsr_clip *cl,
                               cr_gdsr_rollout_result *out, cr_error *err) {
    const int32_t Vh = d->high->nv;
    const int64_t nh3 = (int64_t)Vh * 3;
    cr_bvh *bv = NULL;
    CR_TRY(cr_bvh_build(cl->body, d->body->nv, d->body->tri, d->body->nf, &bv, err));
    float *sd = malloc((size_t)Vh * sizeof(float) + 1);
    cr_status st = sd ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    for (int32_t t = 0; t < cl->nframes && st == CR_OK; t++) {
        if ((st = cr_bvh_refit(bv, cl->body + (int64_t)t * d->body->nv * 3, err)) != CR_OK) break;
        for (int pass = 0; pass < 2; pass++) {
            const float *x = (pass ? out->gdsr : out->gdsr_raw) + t * nh3;
            cr_bvh_signed_distance_batch(bv, x, Vh, 0.2f, sd, NULL, NULL);
            int64_t in = 0;
            for (int32_t i = 0; i < Vh; i++)
                in += sd[i] < 0;
            double share = (double)in / Vh;
            double *dst = pass ? &out->inside_after : &out->inside_before;
            if (share > *dst) *dst = share;
        }
    }
    free(sd);
    cr_bvh_destroy(bv);
    return st;
}

/* A runtime (runtime.c) stepped over the clip: its output is gdsr, its raw
 * output gdsr_raw; the timings are the steps'. */
cr_status cr_gdsr_rollout(cr_gdsr_model *m, const cr_gdsr_data *d, int clip, float eps, int relax,
                          int layer_surface, cr_gdsr_rollout_result *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (clip < 0 || clip >= d->nclips)
        return CR_FAIL(err, CR_ERR_RANGE, "gdsr rollout: clip %d of %d", clip, d->nclips);
    const cr_gdsr_clip *cl = &d->clip[clip];
    const int32_t T = cl->nframes, Vh = d->high->nv;
    const int64_t nl3 = (int64_t)d->low->nv * 3, nh3 = (int64_t)Vh * 3,
                  nb3 = (int64_t)d->body->nv * 3;
    out->nframes = T;
    out->nv_high = Vh;
    out->gdsr = malloc((size_t)T * nh3 * sizeof(float));
    out->gdsr_raw = malloc((size_t)T * nh3 * sizeof(float));
    out->upsampled = malloc((size_t)T * nh3 * sizeof(float));
    cr_gdsr_runtime_def rd = cr_gdsr_runtime_default_def();
    rd.eps = eps, rd.relax = relax, rd.layer_surface = layer_surface;
    cr_gdsr_runtime *rt = NULL;
    cr_status st = out->gdsr && out->gdsr_raw && out->upsampled
                       ? cr_gdsr_runtime_create(m, d, &rd, &rt, err)
                       : CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    double csum = 0, stage[4] = {0};
    int tcount = 0;
    for (int32_t t = 0; t < T && st == CR_OK; t++) {
        const float *ct = cl->low + t * nl3;
        cr_gdsr_upsample(d, ct, out->upsampled + t * nh3);
        clock_t c0 = clock();
        st = cr_gdsr_runtime_step(rt, ct, cl->body + t * nb3, out->gdsr + t * nh3, err);
        if (st != CR_OK) break;
        const cr_gdsr_runtime_stats s = cr_gdsr_runtime_last_stats(rt);
        const double cpu = (double)(clock() - c0) / CLOCKS_PER_SEC;
        memcpy(out->gdsr_raw + t * nh3, cr_gdsr_runtime_raw(rt), (size_t)nh3 * sizeof(float));
        out->layer_pushed += s.layer_pushed, out->layer_pushed_high += s.layer_pushed_high;
        if (t < 2) continue; /* no networks yet */
        if (t == 2 && T > 3) {
            out->first_frame_seconds = s.seconds[0] + s.seconds[1] + s.seconds[2] + s.seconds[3];
        } else {
            for (int k = 0; k < 4; k++)
                stage[k] += s.seconds[k];
            csum += cpu;
            tcount++;
        }
    }
    cr_gdsr_runtime_destroy(rt);
    if (st == CR_OK) st = inside_shares(d, cl, out, err);
    out->cpu_seconds_per_frame = tcount ? csum / tcount : 0;
    for (int k = 0; k < 4; k++) {
        out->stage_seconds[k] = tcount ? stage[k] / tcount : 0;
        out->seconds_per_frame += out->stage_seconds[k]; /* out was zeroed on entry */
    }
    if (st != CR_OK) cr_gdsr_rollout_free(out);
    return st;
}

/* The summary `gdsr train --json` prints (heap text, NULL without memory). */
static char *train_summary(const cr_gdsr_train_dataset_def *data,
                           const cr_gdsr_train_dataset_result *t) {
    const cr_gdsr_train_result *r = &t->train;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "command", "gdsr train");
    cJSON_AddNumberToObject(j, "params", (double)r->params);
    cJSON_AddNumberToObject(j, "low_vertices", t->low_vertices[0]); /* the first garment's */
    cJSON_AddNumberToObject(j, "high_vertices", t->high_vertices[0]);
    cJSON *ga = cJSON_AddArrayToObject(j, "garments");
    for (int k = 0; k < data->ngarments; k++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "garment", data->garments[k]);
        cJSON_AddNumberToObject(o, "low_vertices", t->low_vertices[k]);
        cJSON_AddNumberToObject(o, "high_vertices", t->high_vertices[k]);
        cJSON_AddItemToArray(ga, o);
    }
    const struct {
        const char *key;
        double value;
    } rows[] = {
        {"epochs", r->epochs},
        {"resumed_from", r->resumed_from},
        {"first_loss", r->first_loss},
        {"loss", r->last_loss},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++)
        cJSON_AddNumberToObject(j, rows[i].key, rows[i].value);
    for (int q = 0; q < NTERMS; q++)
        cJSON_AddNumberToObject(j, cr_gdsr_term_names[q], r->last_term[q]);
    if (data->nval > 0) {
        cJSON_AddNumberToObject(j, "val_med_m", r->last_val_med);
        cJSON_AddNumberToObject(j, "val_upsampled_med_m", r->val_upsampled_med);
    }
    cJSON_AddNumberToObject(j, "seconds", r->seconds);
    char *s = cJSON_PrintUnformatted(j);
    cJSON_Delete(j);
    return s;
}

cr_status cr_gdsr_train_dataset(const cr_gdsr_train_def *def, const cr_gdsr_train_dataset_def *data,
                                cr_gdsr_train_dataset_result *out, cr_error *err) {
    const int ng = data->ngarments, nv = data->nval;
    if (!data->dataset || ng < 1 || ng > CR_GDSR_MAX_GARMENTS || nv < 0 || nv > CR_GDSR_MAX_CLIPS ||
        data->nmotions < 0 || data->nmotions + nv > CR_GDSR_MAX_CLIPS)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr train: a dataset, 1 to %d garments and up to %d clips with the "
                       "held-out ones",
                       CR_GDSR_MAX_GARMENTS, CR_GDSR_MAX_CLIPS);
    memset(out, 0, sizeof *out);
    const char *body = data->body ? data->body : "normal";
    int nm = data->nmotions;
    if (nm > 0) {
        for (int k = 0; k < nm; k++)
            snprintf(out->motions[k], sizeof out->motions[k], "%s", data->motions[k]);
    } else { /* the dataset's motions of the first garment, but the validation clips */
        nm = cr_gdsr_dataset_motions(data->dataset, data->garments[0], body, data->val_motions, nv,
                                     out->motions, CR_GDSR_MAX_CLIPS - nv, err);
        if (nm < 0) return err ? err->status : CR_ERR_INVALID;
    }
    out->nmotions = nm;
    /* validation clips go last: cr_gdsr_train leaves them out of training */
    const char *ms[CR_GDSR_MAX_CLIPS];
    for (int k = 0; k < nm; k++)
        ms[k] = out->motions[k];
    for (int k = 0; k < nv; k++)
        ms[nm + k] = data->val_motions[k];
    cr_gdsr_train_def d = *def;
    d.val_clips = nv;
    cr_gdsr_data ds[CR_GDSR_MAX_GARMENTS];
    const cr_gdsr_data *dp[CR_GDSR_MAX_GARMENTS];
    memset(ds, 0, sizeof ds);
    cr_status st = CR_OK;
    for (int k = 0; k < ng && st == CR_OK; k++) {
        st = cr_gdsr_data_load(data->dataset, data->garments[k], body, ms, nm + nv, &ds[k], err);
        dp[k] = &ds[k];
    }
    if (st == CR_OK) st = cr_gdsr_train_many(&d, dp, ng, &out->train, err);
    for (int k = 0; k < ng; k++) {
        out->low_vertices[k] = ds[k].low ? ds[k].low->nv : 0;
        out->high_vertices[k] = ds[k].high ? ds[k].high->nv : 0;
        cr_gdsr_data_free(&ds[k]);
    }
    if (st == CR_OK && !(out->summary_json = train_summary(data, out)))
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr train: out of memory for the summary");
    return st;
}

void cr_gdsr_train_dataset_result_free(cr_gdsr_train_dataset_result *r) {
    if (!r) return;
    free(r->summary_json);
    r->summary_json = NULL;
}
