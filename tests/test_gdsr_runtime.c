/* test_gdsr_runtime.c: gdsr's runtime (include/crease/gdsr.h, "runtime")
 * against the public path frame by frame (the closest body points, the
 * features and the forward of gdsr.h, as the roll-out ran them before it
 * stepped a runtime) and against cr_gdsr_rollout: stepped frame by frame,
 * after a reset, with the handling off, two characters in one batch call,
 * two on their own threads sharing the model and data, no heap growth over
 * a pass; and on an outfit with layer edges. */
#include "crease/bvh.h"
#include "crease/gdsr.h"
#include "gdsr_fixture.h"
#include "test.h"

#include <malloc.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double max_diff(const float *a, const float *b, int64_t n) {
    double d = 0;
    for (int64_t i = 0; i < n; i++)
        d = fmax(d, fabs((double)a[i] - b[i]));
    return d;
}

/* A model of gdsr_tiny_def whose zero-initialised last layers (E's, and A's
 * rows of the last WIRE layer) are drawn at random, so that C^ and the
 * residual are not zero; with or without layer edges. */
static cr_gdsr_model *random_model(int layer_edges) {
    cr_gdsr_model_def def = gdsr_tiny_def();
    def.out_scale = 0.1f;
    def.layer_edges = layer_edges;
    cr_gdsr_model *m = NULL;
    cr_error err = {0};
    if (cr_gdsr_model_create(&def, &m, &err) != CR_OK) return NULL;
    cr_rng rng = cr_rng_make(7, 1);
    cr_nn_params *p = cr_gdsr_model_params(m);
    for (int i = 0; i < cr_nn_params_count(p); i++) {
        cr_tensor *t = cr_nn_params_at(p, i, NULL);
        cr_nn_fill_uniform(t, &rng, -0.3f, 0.3f);
    }
    return m;
}

/* The raw output (T,Vh,3) of clip 0 through gdsr.h's public pieces: frames
 * 0 and 1 the upsampled input, then per frame the closest body points on
 * the body built at that frame, the features of cr_gdsr_features (and the
 * layer edges of an outfit), cr_gdsr_forward with the gradient on, and the
 * network's C^ fed back. */
static float *public_path(cr_gdsr_model *m, const cr_gdsr_data *d) {
    const cr_gdsr_clip *cl = &d->clip[0];
    const cr_gdsr_model_def *md = cr_gdsr_model_get_def(m);
    const int32_t Vl = d->low->nv, Vh = d->high->nv, T = cl->nframes;
    const int64_t nl3 = 3 * (int64_t)Vl, nh3 = 3 * (int64_t)Vh;
    cr_error err = {0};
    cr_gdsr_graph g;
    if (cr_gdsr_graph_build(d->low, &g, &err) != CR_OK) return NULL;
    float *out = malloc(sizeof(float) * (size_t)(T * nh3));
    float *node = malloc(sizeof(float) * CR_GDSR_NODE_FEATURES * (size_t)Vl);
    float *e0 = malloc(sizeof(float) * CR_GDSR_EDGE_FEATURES * (size_t)g.ne[0]);
    float *e1 = malloc(sizeof(float) * CR_GDSR_EDGE_FEATURES * (size_t)g.ne[1]);
    float *e2 = malloc(sizeof(float) * CR_GDSR_EDGE_FEATURES * (size_t)Vl * Vl);
    float *bp = malloc(sizeof(float) * (size_t)nl3);
    float *hist = malloc(sizeof(float) * 3 * (size_t)nl3); /* C^_{t-1}, C^_{t-2}, d_{t-1} */
    cr_nn_ctx *ctx = NULL;
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    int ok =
        out && node && e0 && e1 && e2 && bp && hist && cr_nn_ctx_create(&cd, &ctx, &err) == CR_OK;
    int have = 0;
    for (int32_t t = 0; ok && t < T; t++) {
        const float *c = cl->low + t * nl3;
        if (t < 2) {
            cr_gdsr_upsample(d, c, out + t * nh3);
            continue;
        }
        cr_bvh *b = NULL;
        ok = cr_bvh_build(cl->body + (int64_t)t * d->body->nv * 3, d->body->nv, d->body->tri,
                          d->body->nf, &b, &err) == CR_OK;
        if (!ok) break;
        cr_bvh_closest_batch(b, c, Vl, INFINITY, NULL, bp, NULL, NULL);
        cr_bvh_destroy(b);
        cr_gdsr_frame_in in = {.c = c,
                               .c_prev = c - nl3,
                               .c_prev2 = c - 2 * nl3,
                               .d_prev = have >= 1 ? hist + 2 * nl3 : NULL,
                               .chat_prev = have >= 2 ? hist : NULL,
                               .chat_prev2 = have >= 2 ? hist + nl3 : NULL,
                               .body_point = bp};
        cr_gdsr_features(d->low, &g, &in, md->sigma_b, node, e0, e1);
        g.ne[2] = 0;
        if (md->layer_edges && d->nlayers > 1) {
            ok = cr_gdsr_layer_edges(&g, d->layer, c, md->sigma_l, &err) == CR_OK;
            cr_gdsr_layer_edge_features(&g, c, md->sigma_l, e2);
        }
        cr_nn_ctx_reset(ctx);
        cr_tensor *chat = NULL;
        cr_tensor *x = cr_gdsr_forward(ctx, m, d, &g, node, e0, e1, e2, c, &chat);
        ok = ok && x && chat;
        if (!ok) break;
        memcpy(out + t * nh3, x->data, sizeof(float) * (size_t)nh3);
        memcpy(hist + nl3, hist, sizeof(float) * (size_t)nl3);
        memcpy(hist, chat->data, sizeof(float) * (size_t)nl3);
        for (int64_t i = 0; i < nl3; i++)
            hist[2 * nl3 + i] = chat->data[i] - c[i];
        have++;
    }
    cr_nn_ctx_destroy(ctx);
    cr_gdsr_graph_free(&g);
    free(node), free(e0), free(e1), free(e2), free(bp), free(hist);
    if (!ok) free(out);
    return ok ? out : NULL;
}

/* Clip 0 stepped through rt into out (T,Vh,3) and its raw output into raw
 * (may be NULL). */
static cr_status steps(cr_gdsr_runtime *rt, const cr_gdsr_data *d, float *out, float *raw,
                       cr_error *err) {
    const cr_gdsr_clip *cl = &d->clip[0];
    const int64_t nl3 = 3 * (int64_t)d->low->nv, nh3 = 3 * (int64_t)d->high->nv,
                  nb3 = 3 * (int64_t)d->body->nv;
    cr_gdsr_runtime_reset(rt);
    for (int32_t t = 0; t < cl->nframes; t++) {
        CR_TRY(cr_gdsr_runtime_step(rt, cl->low + t * nl3, cl->body + t * nb3, out + t * nh3, err));
        if (raw) memcpy(raw + t * nh3, cr_gdsr_runtime_raw(rt), sizeof(float) * (size_t)nh3);
    }
    return CR_OK;
}

typedef struct runtime_job {
    cr_gdsr_runtime *rt;
    const cr_gdsr_data *d;
    float *out;
    cr_status st;
} runtime_job;

static void *runtime_thread(void *p) {
    runtime_job *j = p;
    for (int rep = 0; rep < 3 && j->st == CR_OK; rep++)
        j->st = steps(j->rt, j->d, j->out, NULL, NULL);
    return NULL;
}

CR_TEST(gdsr_runtime, steps_equal_the_rollout) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    /* the sphere up through the sheet's middle, so that the handling moves vertices */
    cr_gdsr_clip *cl = &d.clip[0];
    for (int64_t i = 1; i < (int64_t)cl->nframes * d.body->nv * 3; i += 3)
        cl->body[i] += 0.18f;
    for (int32_t i = 0; i < d.body->nv; i++) /* the rest body where the clip's is */
        d.body->pos[3 * i + 1] = cl->body[3 * i + 1];
    cr_gdsr_model *m = random_model(0);
    CR_REQUIRE(m);
    cr_error err = {0};
    const int32_t T = cl->nframes, Vh = d.high->nv;
    const int64_t n = (int64_t)T * Vh * 3;
    float *ref = public_path(m, &d);
    CR_REQUIRE(ref);
    cr_gdsr_rollout_result ro;
    CR_CHECK_OK(cr_gdsr_rollout(m, &d, 0, 0.002f, CR_GDSR_RELAX_DEFAULT, 0, &ro, &err), &err);
    CR_REQUIRE(ro.gdsr);
    double dr = max_diff(ro.gdsr_raw, ref, n), moved = max_diff(ro.gdsr, ro.gdsr_raw, n),
           learnt = max_diff(ro.gdsr_raw, ro.upsampled, n);
    printf("    rollout's raw output vs the public path: %.2e m (the network moves it %.3f m from "
           "upsampling, the handling %.3f m)\n",
           dr, learnt, moved);
    CR_CHECK(dr < 1e-5);
    CR_CHECK(learnt > 1e-3 && moved > 1e-3);

    float *out[2] = {malloc(sizeof(float) * (size_t)n), malloc(sizeof(float) * (size_t)n)};
    float *raw = malloc(sizeof(float) * (size_t)n);
    CR_REQUIRE(out[0] && out[1] && raw);
    cr_gdsr_runtime_def def = cr_gdsr_runtime_default_def();
    cr_gdsr_runtime *rt[2] = {NULL, NULL};
    for (int i = 0; i < 2; i++)
        CR_CHECK_OK(cr_gdsr_runtime_create(m, &d, &def, &rt[i], &err), &err);
    CR_REQUIRE(rt[0] && rt[1]);
    CR_CHECK(cr_gdsr_runtime_vertices(rt[0]) == Vh &&
             cr_gdsr_runtime_low_vertices(rt[0]) == d.low->nv &&
             cr_gdsr_runtime_body_vertices(rt[0]) == d.body->nv &&
             cr_gdsr_runtime_rest(rt[0]) == d.high);
    const size_t cap = cr_gdsr_runtime_arena_bytes(rt[0]);
    for (int rep = 0; rep < 2; rep++) {
        CR_CHECK_OK(steps(rt[0], &d, out[0], raw, &err), &err);
        double a = max_diff(out[0], ro.gdsr, n), b = max_diff(raw, ro.gdsr_raw, n);
        printf("    %s: |step - rollout| %.2e m, raw %.2e m; arena %zu bytes\n",
               rep ? "after a reset" : "stepped", a, b, cap);
        CR_CHECK(a < 1e-5 && b < 1e-5);
    }
    CR_CHECK(cr_gdsr_runtime_arena_bytes(rt[0]) == cap);
#ifdef __GLIBC__
    /* nothing held on the heap grows while stepping */
    size_t held = mallinfo2().uordblks;
    CR_CHECK_OK(steps(rt[0], &d, out[0], NULL, &err), &err);
    printf("    heap in use before / after a pass: %zu / %zu bytes\n", held,
           (size_t)mallinfo2().uordblks);
    CR_CHECK(mallinfo2().uordblks == held);
#endif
    /* the batch call: both characters' frame t at once */
    cr_gdsr_runtime_reset(rt[0]);
    cr_gdsr_runtime_reset(rt[1]);
    for (int32_t t = 0; t < T; t++) {
        const float *lo = cl->low + (int64_t)t * d.low->nv * 3,
                    *bo = cl->body + (int64_t)t * d.body->nv * 3;
        const float *los[2] = {lo, lo}, *bos[2] = {bo, bo};
        float *o[2] = {out[0] + (int64_t)t * Vh * 3, out[1] + (int64_t)t * Vh * 3};
        CR_CHECK_OK(cr_gdsr_runtime_step_batch(rt, 2, los, bos, o, &err), &err);
    }
    double db = fmax(max_diff(out[0], ro.gdsr, n), max_diff(out[1], ro.gdsr, n));
    printf("    batch of 2: %.2e m\n", db);
    CR_CHECK(db < 1e-5);
    /* side by side on two threads, three passes each, sharing the model and data */
    memset(out[0], 0, sizeof(float) * (size_t)n), memset(out[1], 0, sizeof(float) * (size_t)n);
    runtime_job jobs[2] = {{rt[0], &d, out[0], CR_OK}, {rt[1], &d, out[1], CR_OK}};
    pthread_t th[2];
    for (int i = 0; i < 2; i++)
        CR_REQUIRE(pthread_create(&th[i], NULL, runtime_thread, &jobs[i]) == 0);
    for (int i = 0; i < 2; i++)
        pthread_join(th[i], NULL);
    double dt = fmax(max_diff(out[0], ro.gdsr, n), max_diff(out[1], ro.gdsr, n));
    printf("    two threads: %.2e m\n", dt);
    CR_CHECK(jobs[0].st == CR_OK && jobs[1].st == CR_OK);
    CR_CHECK(dt < 1e-5);
    /* the handling off: the network's output */
    cr_gdsr_runtime *bare = NULL;
    def.handling = 0;
    CR_CHECK_OK(cr_gdsr_runtime_create(m, &d, &def, &bare, &err), &err);
    if (bare) {
        CR_CHECK_OK(steps(bare, &d, out[0], NULL, &err), &err);
        double dh = max_diff(out[0], ro.gdsr_raw, n);
        printf("    handling off: |step - raw rollout| %.2e m\n", dh);
        CR_CHECK(dh < 1e-5);
    }
    cr_gdsr_runtime_destroy(bare);
    def.cookie = 0;
    CR_CHECK(cr_gdsr_runtime_create(m, &d, &def, &bare, &err) == CR_ERR_INVALID && !bare);
    CR_CHECK(cr_gdsr_runtime_step(rt[0], NULL, cl->body, out[0], &err) == CR_ERR_INVALID);
    for (int i = 0; i < 2; i++)
        cr_gdsr_runtime_destroy(rt[i]);
    free(out[0]), free(out[1]), free(raw), free(ref);
    cr_gdsr_rollout_free(&ro);
    cr_gdsr_model_destroy(m);
    cr_gdsr_data_free(&d);
}

/* An outfit with layer edges in the model: the runtime's raw output is the
 * public path's, and its steps are the roll-out's (Eq. 27 included). */
CR_TEST(gdsr_runtime, outfit_steps_equal_the_rollout) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_two_layer_data(&d));
    CR_REQUIRE(d.nlayers == 2);
    /* the outer sheet 2 mm over the inner one, under Eq. 27's 5 mm */
    for (int32_t t = 0; t < d.clip[0].nframes; t++)
        for (int32_t i = 0; i < d.low->nv; i++)
            if (d.layer[i] == 1) d.clip[0].low[((int64_t)t * d.low->nv + i) * 3 + 1] -= 0.008f;
    cr_gdsr_model *m = random_model(1);
    CR_REQUIRE(m);
    cr_error err = {0};
    const int64_t n = (int64_t)d.clip[0].nframes * d.high->nv * 3;
    float *ref = public_path(m, &d), *out = malloc(sizeof(float) * (size_t)n),
          *raw = malloc(sizeof(float) * (size_t)n);
    CR_REQUIRE(ref && out && raw);
    cr_gdsr_rollout_result ro;
    CR_CHECK_OK(cr_gdsr_rollout(m, &d, 0, 0.002f, 0, 1, &ro, &err), &err);
    cr_gdsr_runtime_def def = cr_gdsr_runtime_default_def();
    def.relax = 0, def.layer_surface = 1;
    cr_gdsr_runtime *rt = NULL;
    CR_CHECK_OK(cr_gdsr_runtime_create(m, &d, &def, &rt, &err), &err);
    if (rt && ro.gdsr) {
        CR_CHECK_OK(steps(rt, &d, out, raw, &err), &err);
        double a = max_diff(raw, ref, n), b = max_diff(out, ro.gdsr, n);
        printf("    raw vs the public path %.2e m, steps vs the rollout %.2e m; %lld coarse "
               "vertices pushed off the inner layer\n",
               a, b, (long long)ro.layer_pushed);
        CR_CHECK(a < 1e-5 && b < 1e-5);
        CR_CHECK(ro.layer_pushed > 0);
    }
    cr_gdsr_runtime_destroy(rt);
    cr_gdsr_rollout_free(&ro);
    free(ref), free(out), free(raw);
    cr_gdsr_model_destroy(m);
    cr_gdsr_data_free(&d);
}
