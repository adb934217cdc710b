/* runtime.c: EPNet frame by frame, for a game loop or a renderer
 * (include/crease/epnet.h, "runtime").
 *
 * The proxy inference (cr_epnet_infer) is causal frame by frame, so a step
 * does what its three passes do at one frame: E-Net at RB = 0 (the proxy),
 * E-Net with the RB after the frame before (the output), then P-Net over the
 * proxy's positions and angles through the ratchet, giving the RB the next
 * frame is given. The GRU state does not depend on RB, so both E-Net passes
 * start from the same state. Frame 0's inputs have no velocity, as a
 * sequence's first frame; a warm-up, when the def asks for one, runs before
 * it from the rest pose into frame 0's.
 *
 * Everything a step needs is allocated at create: the frame's inputs, the
 * proxy, its angles, the RB and the ratchet's history; the networks run in
 * the model's arena. */
#include "crease/body.h"
#include "epnet_internal.h"

#include <stdlib.h>
#include <string.h>

struct cr_epnet_runtime {
    cr_epnet *m; /* borrowed, or owned (owns_model) */
    int owns_model;
    cr_body_model *own_body;   /* when the body is not the model's */
    const float *joints;       /* the body's rest joints (22,3) */
    cr_epnet_infer_def infer;  /* proxy (default) or zero RB */
    cr_epnet_seq frame;        /* the frame's inputs (T = 1): own buffers, or a sequence's row */
    float *A, *b, *stat, *dyn; /* the own buffers */
    float *prev_pose, *prev_tr;
    float *proxy, *theta, *strain, *rb, *hstate;
    double *xd, *thd; /* angle scratch */
    uint32_t *hist;   /* the ratchet's drive history */
    int64_t frames;
};

void cr_epnet_runtime_reset(cr_epnet_runtime *rt) {
    if (!rt) return;
    rt->frames = 0;
    memset(rt->rb, 0, sizeof(float) * (size_t)rt->m->nh);
    memset(rt->hist, 0, sizeof(uint32_t) * (size_t)rt->m->nh);
    memset(rt->hstate, 0, sizeof(float) * (size_t)rt->m->def.gru_hidden);
}

void cr_epnet_runtime_destroy(cr_epnet_runtime *rt) {
    if (!rt) return;
    free(rt->A), free(rt->b), free(rt->stat), free(rt->dyn);
    free(rt->prev_pose), free(rt->prev_tr), free(rt->proxy), free(rt->theta), free(rt->strain);
    free(rt->rb), free(rt->hstate), free(rt->xd), free(rt->thd), free(rt->hist);
    cr_body_model_destroy(rt->own_body);
    if (rt->owns_model) cr_epnet_destroy(rt->m);
    free(rt);
}

cr_status cr_epnet_runtime_create(cr_epnet *m, const char *body, const cr_epnet_infer_def *infer,
                                  cr_epnet_runtime **out, cr_error *err) {
    if (!m || !out) return CR_FAIL(err, CR_ERR_INVALID, "epnet runtime: NULL model");
    *out = NULL;
    cr_epnet_infer_def d = infer ? *infer : cr_epnet_infer_default_def();
    CR_TRY(cr_epnet_infer_check_(&d, err));
    if (d.mode == CR_EPNET_CLOSED_LOOP)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "epnet runtime: the closed loop is not a runtime mode (proxy or zero RB)");
    cr_epnet_runtime *rt = cr_calloc(1, sizeof *rt, err);
    if (!rt) return err ? err->status : CR_ERR_MEMORY;
    rt->m = m;
    rt->infer = d;
    cr_status st = CR_OK;
    const cr_body_model *bm = m->body;
    if (body && strcmp(body, m->body_name)) {
        st = cr_body_resolve(body, &rt->own_body, err);
        bm = rt->own_body;
    }
    const size_t V = (size_t)m->nv, H = (size_t)m->nh, G = (size_t)m->def.gru_hidden;
    if (st == CR_OK) {
        rt->joints = bm->joints;
        rt->frame.T = 1;
        rt->frame.A = rt->A = malloc(sizeof(float) * 9 * V);
        rt->frame.b = rt->b = malloc(sizeof(float) * 3 * V);
        rt->frame.stat = rt->stat = calloc(EP_STATIC_IN, sizeof(float));
        rt->frame.dyn = rt->dyn = calloc(EP_DYN_IN, sizeof(float));
        rt->frame.body_rest = bm->rest;
        rt->prev_pose = malloc(sizeof(float) * CR_NJOINTS * 3);
        rt->prev_tr = malloc(sizeof(float) * 3);
        rt->proxy = malloc(sizeof(float) * 3 * V);
        rt->theta = malloc(sizeof(float) * H);
        rt->strain = malloc(sizeof(float) * H);
        rt->rb = malloc(sizeof(float) * H);
        rt->hstate = malloc(sizeof(float) * G);
        rt->xd = malloc(sizeof(double) * 3 * V);
        rt->thd = malloc(sizeof(double) * (H + 1));
        rt->hist = malloc(sizeof(uint32_t) * H);
        if (!rt->frame.A || !rt->frame.b || !rt->frame.stat || !rt->frame.dyn || !rt->prev_pose ||
            !rt->prev_tr || !rt->proxy || !rt->theta || !rt->strain || !rt->rb || !rt->hstate ||
            !rt->xd || !rt->thd || !rt->hist)
            st = CR_FAIL(err, CR_ERR_MEMORY, "epnet runtime: out of memory");
    }
    if (st != CR_OK) {
        cr_epnet_runtime_destroy(rt);
        return st;
    }
    cr_epnet_runtime_reset(rt);
    *out = rt;
    return CR_OK;
}

cr_status cr_epnet_runtime_open(const char *model_dir, const char *body,
                                const cr_epnet_infer_def *infer, cr_epnet_runtime **out,
                                cr_error *err) {
    if (!out) return CR_FAIL(err, CR_ERR_INVALID, "epnet runtime: NULL out");
    *out = NULL;
    cr_epnet *m = NULL;
    CR_TRY(cr_epnet_open(model_dir, &m, err));
    cr_status st = cr_epnet_runtime_create(m, body, infer, out, err);
    if (st != CR_OK) {
        cr_epnet_destroy(m);
        return st;
    }
    (*out)->owns_model = 1;
    return CR_OK;
}

int32_t cr_epnet_runtime_vertices(const cr_epnet_runtime *rt) {
    return rt ? rt->m->nv : 0;
}

const cr_mesh *cr_epnet_runtime_rest(const cr_epnet_runtime *rt) {
    return rt ? rt->m->garment->mesh : NULL;
}

const cr_epnet *cr_epnet_runtime_model(const cr_epnet_runtime *rt) {
    return rt ? rt->m : NULL;
}

int32_t cr_epnet_runtime_hinges(const cr_epnet_runtime *rt) {
    return rt ? rt->m->nh : 0;
}

const float *cr_epnet_runtime_rb(const cr_epnet_runtime *rt) {
    return rt ? rt->rb : NULL;
}

/* One frame on the inputs in rt->frame: E-Net's encoders and GRU once, its
 * decoder at RB = 0 (the proxy; with zero RB, the output) and, for the proxy,
 * with the RB after the frame before (the output); then P-Net through the
 * ratchet. */
static cr_status step_frame(cr_epnet_runtime *rt, float *out, cr_error *err) {
    cr_epnet *m = rt->m;
    const int64_t G = m->def.gru_hidden, V3 = 3 * (int64_t)m->nv;
    const int proxy = rt->infer.mode == CR_EPNET_PROXY;
    if (rt->frames == 0 && rt->infer.warmup > 0)
        CR_TRY(cr_epnet_warm_up_(m, &rt->frame, rt->infer.warmup, rt->hstate, err));
    cr_nn_ctx_reset(m->ctx);
    cr_nn_ctx_set_grad_enabled(m->ctx, 0);
    cr_tensor *h0 = rt->frames > 0 || rt->infer.warmup > 0
                        ? cr_nn_from(m->ctx, 2, (int64_t[]){1, G}, rt->hstate)
                        : NULL,
              *h1 = NULL, *x[2] = {NULL, NULL};
    const float *rb[2] = {NULL, rt->rb};
    cr_epnet_enet_frame_(m, &rt->frame, 0, proxy ? 2 : 1, rb, h0, &h1, x);
    CR_TRY(cr_nn_ctx_error(m->ctx, err));
    memcpy(rt->hstate, h1->data, sizeof(float) * (size_t)G);
    memcpy(out, x[proxy]->data, sizeof(float) * (size_t)V3);
    if (proxy) {
        memcpy(rt->proxy, x[0]->data, sizeof(float) * (size_t)V3);
        cr_epnet_frame_angles_(m, rt->proxy, rt->xd, rt->thd, rt->theta);
        CR_TRY(cr_epnet_pnet_ratchet_frame_(m, rt->proxy, rt->theta, &rt->infer.ratchet, rt->hist,
                                            rt->strain, rt->rb, err));
    }
    rt->frames++;
    return CR_OK;
}

cr_status cr_epnet_runtime_step(cr_epnet_runtime *rt, const float *pose, const float *trans,
                                float *out, cr_error *err) {
    if (!rt || !pose || !trans || !out)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet runtime step: NULL argument");
    cr_epnet_frame_inputs_(rt->m, rt->joints, pose, trans, rt->frames ? rt->prev_pose : NULL,
                           rt->frames ? rt->prev_tr : NULL, rt->stat, rt->dyn, rt->A, rt->b);
    CR_TRY(step_frame(rt, out, err));
    memcpy(rt->prev_pose, pose, sizeof(float) * CR_NJOINTS * 3);
    memcpy(rt->prev_tr, trans, sizeof(float) * 3);
    return CR_OK;
}

cr_status cr_epnet_runtime_infer_(cr_epnet *m, const cr_epnet_seq *s, const cr_epnet_infer_def *d,
                                  float *pos, float *theta, float *rb, cr_error *err) {
    const int32_t V = m->nv, H = m->nh;
    cr_epnet_runtime *rt = NULL;
    CR_TRY(cr_epnet_runtime_create(m, NULL, d, &rt, err));
    float *x = malloc(sizeof(float) * 3 * (size_t)V);
    cr_status st = x ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory");
    for (int32_t t = 0; st == CR_OK && t < s->T; t++) {
        /* the sequence's row t as the frame's inputs */
        rt->frame.A = s->A + (size_t)t * V * 9, rt->frame.b = s->b + (size_t)t * V * 3;
        rt->frame.stat = s->stat + (size_t)t * EP_STATIC_IN;
        rt->frame.dyn = s->dyn + (size_t)t * EP_DYN_IN;
        st = step_frame(rt, x, err);
        if (st != CR_OK) break;
        if (pos) memcpy(pos + (size_t)t * V * 3, x, sizeof(float) * 3 * (size_t)V);
        if (theta) cr_epnet_frame_angles_(m, x, rt->xd, rt->thd, theta + (size_t)t * H);
        if (rb) memcpy(rb + (size_t)t * H, rt->rb, sizeof(float) * (size_t)H);
    }
    free(x);
    cr_epnet_runtime_destroy(rt);
    return st;
}

cr_status cr_epnet_runtime_step_batch(cr_epnet_runtime *const *rts, int32_t n, const float *poses,
                                      const float *trans, float *const *out, cr_error *err) {
    if (!rts || n < 0 || (n > 0 && (!poses || !trans || !out)))
        return CR_FAIL(err, CR_ERR_INVALID, "epnet runtime batch: NULL argument or n %d", n);
    for (int32_t i = 0; i < n; i++)
        CR_TRY(cr_epnet_runtime_step(rts[i], poses + (size_t)i * CR_NJOINTS * 3,
                                     trans + (size_t)i * 3, out[i], err));
    return CR_OK;
}
