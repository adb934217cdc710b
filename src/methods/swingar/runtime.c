/* runtime.c: SwinGar frame by frame, for a game loop or a renderer
 * (include/crease/swingar.h, "runtime").
 *
 * The garment's encoding (E_g, the skinning map, the prior logits) is
 * computed once at create and kept on the host. Each step appends the
 * frame's pose to a history of the last motion_window + 1 poses, presents
 * that history to the frame forward as a motion whose last frame is the new
 * one, and keeps the two latest coarse graphs (M_c of eq. 6) for the next
 * step's corrective shape: the same inputs, frame for frame, as a batched
 * prediction of the whole motion. While fewer than motion_window + 1 frames
 * have been stepped the history starts at frame 0, whose pose the window
 * repeats before it, as the batch does; once full it slides, and its first
 * pose only gives the root's move into the second.
 *
 * All memory is taken at create: the arena is sized by two trial frames run
 * in a generous reservation, then made again at the high-water mark plus an
 * eighth, so a step never allocates. */
#include "crease/body.h"
#include "crease/garment.h"
#include "crease/swingar.h"
#include "swingar_internal.h"

#include <stdlib.h>
#include <string.h>

struct cr_swingar_runtime {
    cr_swingar *model;            /* borrowed, or owned by an opened runtime */
    const cr_swingar_garment *g;  /* borrowed, or owned (owned_garment) */
    float joints[CR_NJOINTS * 3]; /* the body's rest joints */
    cr_nn_ctx *ctx;               /* one frame's activations, grad off */
    float *enc;                   /* G (V,H), skinning map (S,J), prior logits (V,J) */
    float *prev;                  /* (2,V,SWG_CORR_FEATURES) the last two coarse graphs */
    float *poses;                 /* (W+1,J,3) the last poses, oldest first */
    float *trans;                 /* (W+1,3) */
    int32_t nhist;                /* poses held, <= W + 1 */
    int64_t frames;               /* frames stepped since create or reset */
    size_t trial_peak;            /* the encoding's and two trial frames' arena, bytes */
    /* what an opened runtime owns */
    cr_swingar_garment *owned_garment;
    cr_garment *garment;
    cr_body_model *body;
    int owns_model;
};

/* the encoding's three parts inside rt->enc */
static swg_genc wrap_encoding(cr_swingar_runtime *rt) {
    const cr_swingar_def *d = &rt->model->def;
    const int64_t V = rt->g->rest->nv, H = d->garment_width[1], S = d->state_width;
    float *G = rt->enc, *skin = G + V * H, *logw0 = skin + S * CR_NJOINTS;
    swg_genc e = {cr_nn_wrap(rt->ctx, 2, (int64_t[]){V, H}, G),
                  cr_nn_wrap(rt->ctx, 2, (int64_t[]){S, CR_NJOINTS}, skin),
                  cr_nn_wrap(rt->ctx, 2, (int64_t[]){V, CR_NJOINTS}, logw0)};
    return e;
}

/* One frame: the pose goes into the history, the frame forward reads it. */
static cr_status step_one(cr_swingar_runtime *rt, const float *pose, const float *trans, float *out,
                          cr_error *err) {
    const int32_t cap = rt->model->def.motion_window + 1, J3 = CR_NJOINTS * 3;
    if (rt->nhist == cap) { /* slide: drop the oldest */
        memmove(rt->poses, rt->poses + J3, sizeof(float) * (size_t)(cap - 1) * J3);
        memmove(rt->trans, rt->trans + 3, sizeof(float) * (size_t)(cap - 1) * 3);
        rt->nhist--;
    }
    memcpy(rt->poses + (size_t)rt->nhist * J3, pose, sizeof(float) * J3);
    memcpy(rt->trans + (size_t)rt->nhist * 3, trans, sizeof(float) * 3);
    rt->nhist++;
    cr_swingar_motion mo = {rt->nhist, rt->joints, rt->poses, rt->trans};
    cr_nn_ctx_reset(rt->ctx);
    swg_genc e = wrap_encoding(rt);
    cr_tensor *y = cr_swingar_forward_frames_(rt->ctx, rt->model, rt->g, &e, &mo, rt->nhist - 1, 1,
                                              rt->frames > 0 ? rt->prev : NULL, rt->prev, NULL);
    cr_status st = cr_nn_ctx_error(rt->ctx, err);
    if (st == CR_OK && !y) st = CR_FAIL(err, CR_ERR_INVALID, "swingar runtime: bad frame input");
    if (st != CR_OK) return st;
    memcpy(out, y->data, sizeof(float) * (size_t)rt->g->rest->nv * 3);
    rt->frames++;
    return CR_OK;
}

void cr_swingar_runtime_reset(cr_swingar_runtime *rt) {
    if (!rt) return;
    rt->nhist = 0;
    rt->frames = 0;
}

/* The garment's encoding into rt->enc, kept on the host for every step. */
static cr_status encode(cr_swingar_runtime *rt, cr_error *err) {
    const cr_swingar_def *d = &rt->model->def;
    const int64_t V = rt->g->rest->nv, H = d->garment_width[1], S = d->state_width;
    cr_nn_ctx_reset(rt->ctx);
    swg_genc e;
    if (!cr_swingar_encode_garment_(rt->ctx, rt->model, rt->g, &e) || !e.G || !e.skinmat ||
        !e.logw0) {
        cr_status st = cr_nn_ctx_error(rt->ctx, err);
        return st != CR_OK ? st
                           : CR_FAIL(err, CR_ERR_INVALID, "swingar runtime: bad garment encoding");
    }
    memcpy(rt->enc, e.G->data, sizeof(float) * (size_t)(V * H));
    memcpy(rt->enc + V * H, e.skinmat->data, sizeof(float) * (size_t)(S * CR_NJOINTS));
    memcpy(rt->enc + V * H + S * CR_NJOINTS, e.logw0->data,
           sizeof(float) * (size_t)(V * CR_NJOINTS));
    return CR_OK;
}

/* Two trial frames at the rest pose (the second with kept graphs), then a
 * reset: what a step needs of the arena. */
static cr_status try_frames(cr_swingar_runtime *rt, cr_error *err) {
    float zero[CR_NJOINTS * 3] = {0};
    float *frame = cr_malloc(sizeof(float) * (size_t)rt->g->rest->nv * 3, err);
    if (!frame) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = step_one(rt, zero, zero, frame, err);
    if (st == CR_OK) st = step_one(rt, zero, zero, frame, err);
    free(frame);
    cr_swingar_runtime_reset(rt);
    return st;
}

/* The garment encoded and two frames tried: the arena's trial (cr_nn_ctx_fit). */
static cr_status trial(void *user, cr_error *err) {
    cr_swingar_runtime *rt = user;
    CR_TRY(encode(rt, err));
    return try_frames(rt, err);
}

/* The arena at the encoding's and the trial's high-water mark plus an eighth,
 * or arena_bytes: the encoding stays on the host. */
static cr_status size_arena(cr_swingar_runtime *rt, size_t arena_bytes, cr_error *err) {
    return cr_nn_ctx_fit(&rt->ctx, arena_bytes, 0, trial, rt, &rt->trial_peak, err);
}

cr_status cr_swingar_runtime_create(cr_swingar *m, const cr_swingar_garment *g,
                                    const float *rest_joints, size_t arena_bytes,
                                    cr_swingar_runtime **out, cr_error *err) {
    if (!m || !g || !rest_joints || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar runtime: NULL model, garment or joints");
    *out = NULL;
    const cr_swingar_def *d = &m->def;
    const int64_t V = g->rest->nv, H = d->garment_width[1], S = d->state_width;
    const int64_t cap = d->motion_window + 1;
    cr_swingar_runtime *rt = cr_calloc(1, sizeof *rt, err);
    if (!rt) return err ? err->status : CR_ERR_MEMORY;
    rt->model = m;
    rt->g = g;
    memcpy(rt->joints, rest_joints, sizeof rt->joints);
    rt->enc = cr_malloc(sizeof(float) * (size_t)(V * H + S * CR_NJOINTS + V * CR_NJOINTS), err);
    rt->prev = cr_malloc(sizeof(float) * (size_t)(2 * V * SWG_CORR_FEATURES), err);
    rt->poses = cr_malloc(sizeof(float) * (size_t)(cap * CR_NJOINTS * 3), err);
    rt->trans = cr_malloc(sizeof(float) * (size_t)(cap * 3), err);
    cr_status st = rt->enc && rt->prev && rt->poses && rt->trans
                       ? size_arena(rt, arena_bytes, err)
                       : (err ? err->status : CR_ERR_MEMORY);
    if (st != CR_OK) {
        cr_swingar_runtime_destroy(rt);
        return st;
    }
    *out = rt;
    return CR_OK;
}

cr_status cr_swingar_runtime_open(const char *model_path, const char *garment_path,
                                  const char *body_spec, size_t arena_bytes,
                                  cr_swingar_runtime **out, cr_error *err) {
    if (!model_path || !garment_path || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar runtime: a model and a garment are needed");
    *out = NULL;
    cr_swingar *m = NULL;
    cr_body_model *b = NULL;
    cr_garment *garment = NULL;
    cr_swingar_garment *sg = NULL;
    CR_TRY(cr_swingar_load(model_path, &m, err));
    cr_status st = cr_body_resolve(body_spec, &b, err);
    if (st == CR_OK) {
        cr_garment_user_def ud = cr_garment_user_default_def();
        st = cr_garment_load_user(garment_path, &ud, b, &garment, err);
    }
    if (st == CR_OK) st = cr_swingar_garment_of_(m, garment, garment_path, b, &sg, err);
    cr_swingar_runtime *rt = NULL;
    if (st == CR_OK) st = cr_swingar_runtime_create(m, sg, b->joints, arena_bytes, &rt, err);
    if (st != CR_OK) {
        cr_swingar_garment_destroy(sg);
        cr_garment_destroy(garment);
        cr_body_model_destroy(b);
        cr_swingar_destroy(m);
        return st;
    }
    rt->owns_model = 1;
    rt->owned_garment = sg;
    rt->garment = garment;
    rt->body = b;
    *out = rt;
    return CR_OK;
}

void cr_swingar_runtime_destroy(cr_swingar_runtime *rt) {
    if (!rt) return;
    cr_nn_ctx_destroy(rt->ctx);
    free(rt->enc);
    free(rt->prev);
    free(rt->poses);
    free(rt->trans);
    cr_swingar_garment_destroy(rt->owned_garment);
    cr_garment_destroy(rt->garment);
    cr_body_model_destroy(rt->body);
    if (rt->owns_model) cr_swingar_destroy(rt->model);
    free(rt);
}

int32_t cr_swingar_runtime_vertices(const cr_swingar_runtime *rt) {
    return rt ? rt->g->rest->nv : 0;
}

const cr_mesh *cr_swingar_runtime_rest(const cr_swingar_runtime *rt) {
    return rt ? rt->g->rest : NULL;
}

const cr_body_model *cr_swingar_runtime_body(const cr_swingar_runtime *rt) {
    return rt ? rt->body : NULL;
}

size_t cr_swingar_runtime_arena_bytes(const cr_swingar_runtime *rt) {
    return rt ? cr_nn_ctx_arena_capacity(rt->ctx) : 0;
}

cr_status cr_swingar_runtime_step(cr_swingar_runtime *rt, const float *pose, const float *trans,
                                  float *out, cr_error *err) {
    if (!rt || !pose || !trans || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar runtime step: NULL argument");
    return step_one(rt, pose, trans, out, err);
}

cr_status cr_swingar_runtime_step_batch(cr_swingar_runtime *const *rts, int32_t n,
                                        const float *poses, const float *trans, float *const *out,
                                        cr_error *err) {
    if (!rts || n < 0 || (n > 0 && (!poses || !trans || !out)))
        return CR_FAIL(err, CR_ERR_INVALID, "swingar runtime batch: NULL argument or n %d", n);
    /* one character after another: each frame's kernels already use every
     * thread, and a CPU gains nothing from stacking characters into one GEMM
     * (a frame's products are already V x width) */
    for (int32_t i = 0; i < n; i++) {
        cr_status st = cr_swingar_runtime_step(rts[i], poses + (size_t)i * CR_NJOINTS * 3,
                                               trans + (size_t)i * 3, out[i], err);
        if (st != CR_OK) return st;
    }
    return CR_OK;
}

cr_status cr_swingar_predict(cr_swingar *m, const cr_swingar_garment *g,
                             const cr_swingar_motion *mo, size_t arena_bytes, float *out,
                             cr_error *err) {
    return cr_swingar_predict_batch(m, g, mo, 1, arena_bytes, &out, NULL, err);
}

cr_status cr_swingar_predict_batch(cr_swingar *m, const cr_swingar_garment *g,
                                   const cr_swingar_motion *mos, int32_t nseq, size_t arena_bytes,
                                   float *const *out, cr_swingar_predict_stats *stats,
                                   cr_error *err) {
    if (!m || !g || !mos || !out || nseq < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar predict: NULL input or %d sequences", nseq);
    for (int32_t b = 0; b < nseq; b++)
        if (mos[b].nframes < 1 || !mos[b].joints || !mos[b].poses || !mos[b].trans)
            return CR_FAIL(err, CR_ERR_INVALID, "swingar predict: sequence %d has no frames", b);
    double t0 = cr_time_now();
    cr_swingar_runtime *rt = NULL;
    CR_TRY(cr_swingar_runtime_create(m, g, mos[0].joints, arena_bytes, &rt, err));
    if (stats) {
        stats->encode_seconds = cr_time_now() - t0;
        stats->arena_peak_bytes = rt->trial_peak;
    }
    const int64_t V = g->rest->nv, J3 = CR_NJOINTS * 3;
    cr_status st = CR_OK;
    for (int32_t b = 0; b < nseq && st == CR_OK; b++) {
        cr_swingar_runtime_reset(rt);
        memcpy(rt->joints, mos[b].joints, sizeof rt->joints); /* each sequence's body */
        for (int32_t t = 0; t < mos[b].nframes && st == CR_OK; t++)
            st = step_one(rt, mos[b].poses + (size_t)t * J3, mos[b].trans + 3 * (size_t)t,
                          out[b] + (size_t)t * V * 3, err);
    }
    cr_swingar_runtime_destroy(rt);
    return st;
}
