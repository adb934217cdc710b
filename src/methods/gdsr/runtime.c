/* runtime.c: gdsr frame by frame, for a game loop or a renderer
 * (include/crease/gdsr.h, "runtime"), and the one copy of a frame's work
 * that cr_gdsr_rollout steps over a clip.
 *
 * A step refits the body's BVH to the frame, finds the closest body point
 * of each low vertex (Eq. 2-3), builds the graph features of Eq. 4-5 from
 * C_t and the history it keeps (C_{t-1}, C_{t-2}, its own C^_{t-1},
 * C^_{t-2} and d_{t-1} = C^_{t-1} - C_{t-1}), runs H, E and A (Eq. 6-12)
 * with the gradient off, then, with the handling on, Eq. 26-27: C^ pushed
 * out of the body, that push carried to the high vertices through Eq. 1,
 * the high vertices still inside pushed and relaxed (collide.c), and on an
 * outfit the layers pushed apart. The history is fed from the network's
 * C^ before the handling moves it, as training sees it. The first two
 * frames have no history: they give the upsampled input, handled.
 *
 * Memory: the graph, the BVH (built on the rest body, refitted each frame),
 * the high mesh's topology, the features and every scratch buffer are
 * allocated at create; the arena is sized by trial frames at rest (the
 * high-water mark plus an eighth, after a trial in a generous reservation
 * touched only as used), as swingar's runtime does. The forward's index
 * arrays come from the arena (model.c). An outfit's layer edges and Eq. 27
 * allocate (data.c, collide.c), and their arena needs are not bounded by a
 * trial at rest, so an outfit keeps the reservation. */
#include "gdsr_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define RUNTIME_COOKIE 0x67727274u

enum { TRIAL_FRAMES = 4 }; /* two with no history, two through the networks */

struct cr_gdsr_runtime {
    cr_gdsr_model *m;      /* borrowed, or owned (owns) */
    const cr_gdsr_data *d; /* borrowed, or owned (owned_data) */
    cr_gdsr_runtime_def def;
    int layer_edges;       /* the model has them and the garment is an outfit */
    cr_gdsr_graph g;       /* the low mesh's graph; set 2 the frame's layer edges */
    cr_topology *htopo;    /* the high mesh's, for the relaxation */
    cr_bvh *bv;            /* the body, refitted to each frame */
    cr_nn_ctx *ctx;        /* one frame's activations, grad off */
    float *c1, *c2;        /* (Vl,3) C_{t-1}, C_{t-2} */
    float *chat1, *chat2;  /* (Vl,3) C^_{t-1}, C^_{t-2}: the network's */
    float *dprev;          /* (Vl,3) d_{t-1} */
    float *chat;           /* (Vl,3) this frame's C^, then pushed */
    float *bp, *lnrm;      /* (Vl,3) closest body points; the features' normals */
    float *node, *e0, *e1; /* (Vl,19), (E0,8), (E1,8) features */
    float *e2;             /* (e2cap,8) the layer edges' features */
    int64_t e2cap;
    float *raw;                 /* (Vh,3) the last output before the handling */
    float *lpush, *hpush;       /* (Vl,3), (Vh,3) the coarse push and its upsampling */
    float *sd, *nrm, *rd;       /* (Vmax), (Vmax,3), (3,Vh,3) the handling's scratch */
    float *lb;                  /* (Vh) */
    int32_t *idx;               /* (Vh) */
    uint8_t *moved;             /* (Vh) */
    int64_t frames;             /* stepped since create or reset */
    int have;                   /* frames of the network's own output in the history */
    cr_gdsr_runtime_stats last; /* the last step's */
    cr_gdsr_data *owned_data;
    int owns_model;
};

cr_gdsr_runtime_def cr_gdsr_runtime_default_def(void) {
    cr_gdsr_runtime_def d = {.handling = 1,
                             .eps = 0.002f,
                             .relax = CR_GDSR_RELAX_DEFAULT,
                             .layer_surface = 0,
                             .arena_bytes = 0,
                             .cookie = RUNTIME_COOKIE};
    return d;
}

void cr_gdsr_runtime_reset(cr_gdsr_runtime *rt) {
    if (!rt) return;
    rt->frames = 0;
    rt->have = 0;
}

/* C_t into the history (C_{t-1}, C_{t-2}) after a frame. */
static void keep_input(cr_gdsr_runtime *rt, const float *low) {
    const size_t n3 = (size_t)rt->d->low->nv * 3;
    memcpy(rt->c2, rt->c1, n3 * sizeof(float));
    memcpy(rt->c1, low, n3 * sizeof(float));
    rt->frames++;
}

/* Features and the networks: rt->raw (Vh,3) and rt->chat (Vl,3); C^ and d
 * into the history as the network gives them, before the handling moves C^
 * (training feeds back the same). */
static cr_status networks(cr_gdsr_runtime *rt, const float *low, double *dt, cr_error *err) {
    const cr_gdsr_data *d = rt->d;
    const cr_gdsr_model_def *md = cr_gdsr_model_get_def(rt->m);
    double t0 = cr_time_now();
    cr_gdsr_frame_in in = {.c = low,
                           .c_prev = rt->c1,
                           .c_prev2 = rt->c2,
                           .d_prev = rt->have >= 1 ? rt->dprev : NULL,
                           .chat_prev = rt->have >= 2 ? rt->chat1 : NULL,
                           .chat_prev2 = rt->have >= 2 ? rt->chat2 : NULL,
                           .body_point = rt->bp};
    CR_TRY(cr_gdsr_frame_features_(d, md, &rt->g, &in, rt->lnrm, rt->node, rt->e0, rt->e1, &rt->e2,
                                   &rt->e2cap, err));
    double t1 = cr_time_now();
    cr_nn_ctx_reset(rt->ctx);
    cr_tensor *ch = NULL;
    cr_tensor *X =
        cr_gdsr_forward(rt->ctx, rt->m, d, &rt->g, rt->node, rt->e0, rt->e1, rt->e2, low, &ch);
    CR_TRY(cr_nn_ctx_error(rt->ctx, err));
    if (!X || !ch)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr runtime: forward failed at frame %lld",
                       (long long)rt->frames);
    memcpy(rt->raw, X->data, sizeof(float) * 3 * (size_t)d->high->nv);
    const size_t n3 = (size_t)d->low->nv * 3;
    memcpy(rt->chat, ch->data, n3 * sizeof(float));
    memcpy(rt->chat2, rt->chat1, n3 * sizeof(float));
    memcpy(rt->chat1, rt->chat, n3 * sizeof(float));
    for (size_t i = 0; i < n3; i++)
        rt->dprev[i] = rt->chat[i] - low[i];
    rt->have++;
    dt[1] = t1 - t0, dt[2] = cr_time_now() - t1;
    return CR_OK;
}

/* Eq. 26-27 on the frame: C^ (rt->chat) and out (Vh,3), from rt->raw. The
 * first frames' upsampled input has no C^ push: its high vertices are
 * pushed, relaxed and pushed again (the roll-out's order). */
static cr_status handle(cr_gdsr_runtime *rt, int networks, float *out, cr_gdsr_runtime_stats *s,
                        cr_error *err) {
    const cr_gdsr_data *d = rt->d;
    const cr_gdsr_runtime_def *def = &rt->def;
    const int32_t Vh = d->high->nv;
    const int64_t nh3 = 3 * (int64_t)Vh;
    memcpy(out, rt->raw, (size_t)nh3 * sizeof(float));
    if (networks) {
        cr_gdsr_push_out(rt->bv, rt->chat, d->low->nv, def->eps, rt->sd, rt->nrm, rt->lpush);
        cr_gdsr_upsample(d, rt->lpush, rt->hpush);
        for (int64_t i = 0; i < nh3; i++)
            out[i] += rt->hpush[i];
    } else {
        cr_gdsr_push_out(rt->bv, out, Vh, 0.5f * def->eps, rt->sd, rt->nrm, NULL);
    }
    const cr_gdsr_relax_scratch rs = {.sd = rt->sd,
                                      .nrm = rt->nrm,
                                      .d = rt->rd,
                                      .dn = rt->rd + nh3,
                                      .x0 = rt->rd + 2 * nh3,
                                      .lb = rt->lb,
                                      .idx = rt->idx,
                                      .moved = rt->moved};
    cr_gdsr_relax_push(rt->bv, rt->htopo, rt->raw, out, 0.5f * def->eps, def->relax, &rs);
    if (!networks) cr_gdsr_push_out(rt->bv, out, Vh, 0.5f * def->eps, rt->sd, rt->nrm, NULL);
    int64_t fine = 0;
    int64_t n = cr_gdsr_layer_push(d, rt->chat, out, CR_GDSR_LAYER_SIGMA, CR_GDSR_LAYER_GAMMA,
                                   def->layer_surface, &fine, err);
    if (n < 0) return err ? err->status : CR_ERR_MEMORY;
    s->layer_pushed += n, s->layer_pushed_high += fine;
    return CR_OK;
}

cr_status cr_gdsr_runtime_step(cr_gdsr_runtime *rt, const float *low, const float *body, float *out,
                               cr_error *err) {
    if (!rt || !low || !body || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr runtime step: NULL argument");
    cr_gdsr_runtime_stats s = {{0, 0, 0, 0}, 0, 0};
    const cr_gdsr_data *d = rt->d;
    const int32_t Vh = d->high->nv;
    const int nets = rt->frames >= 2;
    double t0 = cr_time_now();
    CR_TRY(cr_bvh_refit(rt->bv, body, err));
    if (nets) {
        cr_bvh_closest_batch(rt->bv, low, d->low->nv, INFINITY, NULL, rt->bp, NULL, NULL);
        s.seconds[0] = cr_time_now() - t0;
        CR_TRY(networks(rt, low, s.seconds, err));
    } else { /* no history yet: the upsampled input */
        cr_gdsr_upsample(d, low, rt->raw);
        memcpy(rt->chat, low, sizeof(float) * 3 * (size_t)d->low->nv);
    }
    double t3 = cr_time_now();
    if (rt->def.handling)
        CR_TRY(handle(rt, nets, out, &s, err));
    else
        memcpy(out, rt->raw, sizeof(float) * 3 * (size_t)Vh);
    if (nets) s.seconds[3] = cr_time_now() - t3;
    for (int64_t i = 0; i < 3 * (int64_t)Vh; i++)
        if (!isfinite(out[i]))
            return CR_FAIL(err, CR_ERR_DIVERGED, "gdsr runtime: non-finite output at frame %lld",
                           (long long)rt->frames);
    keep_input(rt, low);
    rt->last = s;
    return CR_OK;
}

cr_status cr_gdsr_runtime_step_batch(cr_gdsr_runtime *const *rts, int32_t n,
                                     const float *const *low, const float *const *body,
                                     float *const *out, cr_error *err) {
    if (!rts || n < 0 || (n > 0 && (!low || !body || !out)))
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr runtime batch: NULL argument or n %d", n);
    /* one character after another: each frame's kernels already use every thread */
    for (int32_t i = 0; i < n; i++)
        CR_TRY(cr_gdsr_runtime_step(rts[i], low[i], body[i], out[i], err));
    return CR_OK;
}

/* TRIAL_FRAMES steps of the rest garment on the rest body, then a reset:
 * the arena's trial (cr_nn_ctx_fit). */
static cr_status try_frames(void *user, cr_error *err) {
    cr_gdsr_runtime *rt = user;
    float *frame = cr_malloc(sizeof(float) * 3 * (size_t)rt->d->high->nv, err);
    if (!frame) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = CR_OK;
    for (int k = 0; k < TRIAL_FRAMES && st == CR_OK; k++)
        st = cr_gdsr_runtime_step(rt, rt->d->low->pos, rt->d->body->pos, frame, err);
    free(frame);
    cr_gdsr_runtime_reset(rt);
    return st;
}

/* The trial in def.arena_bytes or a generous reservation, then the arena
 * at its high-water mark plus an eighth, unless the garment's layer edges
 * can grow past the trial's. */
static cr_status size_arena(cr_gdsr_runtime *rt, cr_error *err) {
    return cr_nn_ctx_fit(&rt->ctx, rt->def.arena_bytes, rt->layer_edges, try_frames, rt, NULL, err);
}

static cr_status check_def(const cr_gdsr_runtime_def *d, cr_error *err) {
    if (d->cookie != RUNTIME_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr runtime def: not made by cr_gdsr_runtime_default_def");
    if (!(d->eps >= 0.0f && d->eps <= 0.1f) || d->relax < 0 || d->relax > 1000 ||
        (d->layer_surface != 0 && d->layer_surface != 1) || (d->handling != 0 && d->handling != 1))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr runtime def: eps %g m (0..0.1), relax %d (0..1000), layer_surface "
                       "%d and handling %d (0 or 1)",
                       (double)d->eps, d->relax, d->layer_surface, d->handling);
    return CR_OK;
}

cr_status cr_gdsr_runtime_create(cr_gdsr_model *m, const cr_gdsr_data *d,
                                 const cr_gdsr_runtime_def *def, cr_gdsr_runtime **out,
                                 cr_error *err) {
    if (!m || !d || !d->low || !d->high || !d->body || !d->face || !d->bary || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr runtime: NULL model or data without its pair");
    *out = NULL;
    cr_gdsr_runtime_def rd = def ? *def : cr_gdsr_runtime_default_def();
    CR_TRY(check_def(&rd, err));
    cr_gdsr_runtime *rt = cr_calloc(1, sizeof *rt, err);
    if (!rt) return err ? err->status : CR_ERR_MEMORY;
    rt->m = m;
    rt->d = d;
    rt->def = rd;
    rt->layer_edges = cr_gdsr_model_get_def(m)->layer_edges && d->nlayers >= 2 && d->layer;
    const size_t Vl = (size_t)d->low->nv, Vh = (size_t)d->high->nv, Vmax = Vh > Vl ? Vh : Vl;
    cr_status st = cr_gdsr_graph_build(d->low, &rt->g, err);
    if (st == CR_OK) st = cr_topology_build(d->high, &rt->htopo, err);
    if (st == CR_OK)
        st = cr_bvh_build(d->body->pos, d->body->nv, d->body->tri, d->body->nf, &rt->bv, err);
    if (st == CR_OK) {
        float **vl[] = {&rt->c1,   &rt->c2, &rt->chat1, &rt->chat2, &rt->dprev,
                        &rt->chat, &rt->bp, &rt->lnrm,  &rt->lpush};
        for (size_t k = 0; k < sizeof vl / sizeof vl[0]; k++)
            *vl[k] = malloc(sizeof(float) * 3 * Vl);
        rt->node = malloc(sizeof(float) * CR_GDSR_NODE_FEATURES * Vl);
        rt->e0 = malloc(sizeof(float) * CR_GDSR_EDGE_FEATURES * (size_t)(rt->g.ne[0] + 1));
        rt->e1 = malloc(sizeof(float) * CR_GDSR_EDGE_FEATURES * (size_t)(rt->g.ne[1] + 1));
        rt->raw = malloc(sizeof(float) * 3 * Vh);
        rt->hpush = malloc(sizeof(float) * 3 * Vh);
        rt->sd = malloc(sizeof(float) * Vmax);
        rt->nrm = malloc(sizeof(float) * 3 * Vmax);
        rt->rd = malloc(sizeof(float) * 9 * Vh);
        rt->lb = malloc(sizeof(float) * Vh);
        rt->idx = malloc(sizeof(int32_t) * Vh);
        rt->moved = malloc(Vh + 1);
        int ok = rt->node && rt->e0 && rt->e1 && rt->raw && rt->hpush && rt->sd && rt->nrm &&
                 rt->rd && rt->lb && rt->idx && rt->moved;
        for (size_t k = 0; k < sizeof vl / sizeof vl[0]; k++)
            ok = ok && *vl[k];
        if (!ok) st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr runtime: out of memory");
    }
    if (st == CR_OK) st = size_arena(rt, err);
    if (st != CR_OK) {
        cr_gdsr_runtime_destroy(rt);
        return st;
    }
    *out = rt;
    return CR_OK;
}

cr_status cr_gdsr_runtime_open(const char *model_path, const char *dataset, const char *garment,
                               const char *body, const cr_gdsr_runtime_def *def,
                               cr_gdsr_runtime **out, cr_error *err) {
    if (!model_path || !dataset || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr runtime: a model and a dataset are needed");
    *out = NULL;
    cr_gdsr_data *d = cr_calloc(1, sizeof *d, err);
    if (!d) return err ? err->status : CR_ERR_MEMORY;
    cr_gdsr_model *m = NULL;
    cr_status st = cr_gdsr_model_load(model_path, &m, err);
    if (st == CR_OK)
        st = cr_gdsr_data_load(dataset, garment ? garment : "tshirt", body ? body : "normal", NULL,
                               0, d, err);
    if (st == CR_OK) st = cr_gdsr_runtime_create(m, d, def, out, err);
    if (st != CR_OK) {
        cr_gdsr_data_free(d);
        free(d);
        cr_gdsr_model_destroy(m);
        return st;
    }
    (*out)->owned_data = d;
    (*out)->owns_model = 1;
    return CR_OK;
}

void cr_gdsr_runtime_destroy(cr_gdsr_runtime *rt) {
    if (!rt) return;
    cr_nn_ctx_destroy(rt->ctx);
    cr_bvh_destroy(rt->bv);
    cr_topology_destroy(rt->htopo);
    cr_gdsr_graph_free(&rt->g);
    free(rt->c1), free(rt->c2), free(rt->chat1), free(rt->chat2), free(rt->dprev);
    free(rt->chat), free(rt->bp), free(rt->lnrm), free(rt->lpush);
    free(rt->node), free(rt->e0), free(rt->e1), free(rt->e2);
    free(rt->raw), free(rt->hpush), free(rt->sd), free(rt->nrm), free(rt->rd), free(rt->lb),
        free(rt->idx), free(rt->moved);
    if (rt->owned_data) {
        cr_gdsr_data_free(rt->owned_data);
        free(rt->owned_data);
    }
    if (rt->owns_model) cr_gdsr_model_destroy(rt->m);
    free(rt);
}

int32_t cr_gdsr_runtime_vertices(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->high->nv : 0;
}

int32_t cr_gdsr_runtime_low_vertices(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->low->nv : 0;
}

int32_t cr_gdsr_runtime_body_vertices(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->body->nv : 0;
}

const cr_mesh *cr_gdsr_runtime_rest(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->high : NULL;
}

const cr_mesh *cr_gdsr_runtime_low_rest(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->low : NULL;
}

const cr_mesh *cr_gdsr_runtime_body_rest(const cr_gdsr_runtime *rt) {
    return rt ? rt->d->body : NULL;
}

const float *cr_gdsr_runtime_raw(const cr_gdsr_runtime *rt) {
    return rt ? rt->raw : NULL;
}

cr_gdsr_runtime_stats cr_gdsr_runtime_last_stats(const cr_gdsr_runtime *rt) {
    cr_gdsr_runtime_stats s = {{0, 0, 0, 0}, 0, 0};
    return rt ? rt->last : s;
}

size_t cr_gdsr_runtime_arena_bytes(const cr_gdsr_runtime *rt) {
    return rt ? cr_nn_ctx_arena_capacity(rt->ctx) : 0;
}
