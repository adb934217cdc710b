/* test_swingar.c: SwinGar's estimator on a tiny dataset made here with the
 * dataset API (a dress of about 500 vertices, two short clips): dynamic
 * skinning weights sum to 1, the losses' gradients match central
 * differences, the def survives JSON, the split shares nothing, a tiny
 * model lowers its loss, and resumed training is bit-exact. */
#include "crease/bvh.h"
#include "crease/dataset.h"
#include "crease/mesh_io.h"
#include "crease/nn_checkpoint.h"
#include "crease/swingar.h"
#include "nn/cpu/cpu.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <malloc.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static cr_swingar_data g_data;
static int g_loaded = 0;

static const cr_swingar_data *tiny_data(void) {
    if (g_loaded) return g_loaded > 0 ? &g_data : NULL;
    g_loaded = -1;
    char dir[512];
    snprintf(dir, sizeof dir, "%s/swingar_data", cr_test_tmpdir());
    const char *garments[] = {"dress"}, *motions[] = {"walk", "twist"};
    const char *bodies[] = {"normal"}, *res[] = {"low"};
    cr_dataset_def d = cr_dataset_default_def();
    d.out_dir = dir;
    d.garments = garments, d.ngarments = 1;
    d.motions = motions, d.nmotions = 2;
    d.bodies = bodies, d.nbodies = 1;
    d.res = res, d.nres = 1;
    d.low_vertices = 500;
    d.frames = 6;
    d.quiet = 1;
    cr_error err = {0};
    cr_dataset_result r;
    if (cr_dataset_generate(&d, &r, &err) != CR_OK || r.failed) {
        printf("    dataset: %s\n", err.msg);
        return NULL;
    }
    if (cr_swingar_data_load(dir, 16, 1, 0, &g_data, &err) != CR_OK) {
        printf("    load: %s\n", err.msg);
        return NULL;
    }
    /* the spectral descriptor: 16 eigenvalues, largest first, not all zero */
    const float *l = g_data.garments[0]->descriptor;
    printf("    descriptor %.4f %.4f ... %.4f\n", l[0], l[1], l[15]);
    if (!(l[0] > 0 && l[0] >= l[1])) return NULL;
    g_loaded = 1;
    return &g_data;
}

static cr_swingar_def tiny_def(void) {
    cr_swingar_def d = cr_swingar_default_def();
    d.descriptor_len = 16;
    d.garment_width[0] = 8, d.garment_width[1] = 12;
    d.garment_heads = 2;
    d.shape_width[0] = 16, d.shape_width[1] = 8, d.shape_width[2] = 4;
    d.motion_window = 4;
    d.motion_hidden = 12;
    d.body_width[0] = 16, d.body_width[1] = 8, d.body_width[2] = 8;
    d.state_width = 12, d.state_heads = 2;
    d.blend_width[0] = 8, d.blend_width[1] = 12, d.blend_heads = 2;
    d.corr_hidden = 8, d.corr_heads = 2, d.corr_width = 8;
    return d;
}

/* A tiny model with random heads (zero_last off: its output differs from the
 * skinned prior), seeded; NULL (the failure reported) when it cannot be
 * made. */
static cr_swingar *random_tiny_model(uint64_t seed) {
    cr_swingar_def def = tiny_def();
    def.zero_last = 0;
    cr_error err = {0};
    cr_swingar *m = NULL;
    CR_CHECK_OK(cr_swingar_create(&def, seed, &m, &err), &err);
    return m;
}

static cr_swingar_motion seq_motion(const cr_swingar_data *d, int i) {
    const cr_swingar_sequence *s = &d->sequences[i];
    cr_swingar_motion mo = {s->nframes, d->bodies[s->body_index].model->joints, s->poses, s->trans};
    return mo;
}

/* A context with an arena of `mib` MiB, NULL when it cannot be made. */
static cr_nn_ctx *test_ctx(size_t mib) {
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = mib << 20;
    cr_nn_ctx *ctx = NULL;
    cr_error err = {0};
    return cr_nn_ctx_create(&cd, &ctx, &err) == CR_OK ? ctx : NULL;
}

CR_TEST(swingar, skinning_weights_sum_to_one) {
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_error err = {0};
    cr_swingar *m = random_tiny_model(3);
    CR_REQUIRE(m);
    cr_nn_ctx *ctx = test_ctx(128);
    CR_REQUIRE(ctx);
    const cr_swingar_garment *g = d->garments[d->sequences[0].garment_index];
    cr_swingar_motion mo = seq_motion(d, 0);
    cr_swingar_parts parts;
    cr_tensor *y = cr_swingar_forward(ctx, m, g, &mo, 2, 3, &parts);
    CR_CHECK_OK(cr_nn_ctx_error(ctx, &err), &err);
    CR_REQUIRE(y && parts.skin);
    const int64_t V = g->rest->nv;
    CR_CHECK(y->shape[0] == 3 && y->shape[1] == V && y->shape[2] == 3);
    double worst = 0, moved = 0;
    for (int64_t r = 0; r < 3 * V; r++) {
        double s = 0;
        for (int j = 0; j < CR_NJOINTS; j++) {
            float w = parts.skin->data[r * CR_NJOINTS + j];
            CR_CHECK(w >= 0.0f && w <= 1.0f);
            s += w;
            moved += fabs(w - g->skin_weight[(r % V) * CR_NJOINTS + j]);
        }
        worst = fmax(worst, fabs(s - 1.0));
    }
    printf("    max |sum - 1| %.2e, mean |W - prior| per vertex %.3f\n", worst, moved / (3 * V));
    CR_CHECK(worst < 1e-5);
    CR_CHECK(moved / (3 * V) > 1e-3); /* the weights are predicted, not the prior copied */
    for (int64_t i = 0; i < y->numel; i++)
        CR_CHECK(isfinite(y->data[i]));
    cr_nn_ctx_destroy(ctx);
    cr_swingar_destroy(m);
}

CR_TEST(swingar, untrained_model_is_the_skinned_garment) {
    /* zero_last: the blend and corrective heads start at zero and the
     * skinning logits at the prior, so the coarse and final outputs agree */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_swingar_def def = tiny_def();
    cr_error err = {0};
    cr_swingar *m = NULL;
    CR_CHECK_OK(cr_swingar_create(&def, 3, &m, &err), &err);
    CR_REQUIRE(m);
    cr_nn_ctx *ctx = test_ctx(128);
    CR_REQUIRE(ctx);
    const cr_swingar_garment *g = d->garments[d->sequences[0].garment_index];
    cr_swingar_motion mo = seq_motion(d, 0);
    cr_swingar_parts parts;
    cr_tensor *y = cr_swingar_forward(ctx, m, g, &mo, 0, 2, &parts);
    CR_REQUIRE(y && parts.coarse);
    double dmax = 0, dfirst = 0;
    for (int64_t i = 0; i < y->numel; i++)
        dmax = fmax(dmax, fabs(y->data[i] - parts.coarse->data[i]));
    /* frame 0 is the rest pose: the output is the rest garment there */
    for (int64_t i = 0; i < g->rest->nv * 3; i++)
        dfirst = fmax(dfirst, fabs(y->data[i] - g->rest->pos[i] - mo.trans[i % 3]));
    printf("    |final - coarse| %.2e m, frame 0 vs rest %.2e m\n", dmax, dfirst);
    CR_CHECK(dmax < 1e-6);
    CR_CHECK(dfirst < 1e-3);
    cr_nn_ctx_destroy(ctx);
    cr_swingar_destroy(m);
}

/* Frames [0, T) of motion i in one forward, the reference for predict:
 * with the gradient on (grad 1) the tape's ops, off the inference kernels.
 * skin and coarse, when given, receive the parts (malloc'd). */
static float *forward_grad(cr_swingar *m, const cr_swingar_garment *g, const cr_swingar_motion *mo,
                           int grad, float **skin, float **coarse) {
    cr_nn_ctx *ctx = test_ctx(256);
    if (!ctx) return NULL;
    cr_nn_ctx_set_grad_enabled(ctx, grad);
    cr_swingar_parts parts;
    cr_tensor *y = cr_swingar_forward(ctx, m, g, mo, 0, mo->nframes, skin ? &parts : NULL);
    float *out = y ? malloc(sizeof(float) * (size_t)y->numel) : NULL;
    if (out) memcpy(out, y->data, sizeof(float) * (size_t)y->numel);
    if (out && grad) CR_CHECK(y->requires_grad);
    cr_tensor *pt[2] = {skin ? parts.skin : NULL, skin ? parts.coarse : NULL};
    float **dst[2] = {skin, coarse};
    for (int i = 0; i < 2 && skin; i++) {
        *dst[i] = out && pt[i] ? malloc(sizeof(float) * (size_t)pt[i]->numel) : NULL;
        if (*dst[i]) memcpy(*dst[i], pt[i]->data, sizeof(float) * (size_t)pt[i]->numel);
    }
    cr_nn_ctx_destroy(ctx);
    return out;
}

static float *one_forward(cr_swingar *m, const cr_swingar_garment *g, const cr_swingar_motion *mo) {
    return forward_grad(m, g, mo, 0, NULL, NULL);
}

static double max_diff(const float *a, const float *b, int64_t n) {
    double d = 0;
    for (int64_t i = 0; i < n; i++)
        d = fmax(d, fabs((double)a[i] - b[i]));
    return d;
}

CR_TEST(swingar, predict_and_batch_agree) {
    /* predict steps the runtime frame by frame, keeping the last two coarse
     * graphs, and encodes the garment once: alone or batched it gives what
     * one forward over the whole motion gives (random heads, so the
     * corrective shape depends on the frame triple) */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d && d->nsequences >= 2);
    cr_error err = {0};
    cr_swingar *m = random_tiny_model(5);
    CR_REQUIRE(m);
    const cr_swingar_garment *g = d->garments[d->sequences[0].garment_index];
    CR_REQUIRE(d->sequences[1].garment_index == d->sequences[0].garment_index);
    cr_swingar_motion mo[2] = {seq_motion(d, 0), seq_motion(d, 1)};
    const int64_t V = g->rest->nv;
    float *ref[2] = {one_forward(m, g, &mo[0]), one_forward(m, g, &mo[1])};
    CR_REQUIRE(ref[0] && ref[1]);
    int64_t n[2] = {mo[0].nframes * V * 3, mo[1].nframes * V * 3};
    float *out[2] = {malloc(sizeof(float) * (size_t)n[0]), malloc(sizeof(float) * (size_t)n[1])};
    CR_REQUIRE(out[0] && out[1]);
    /* the two motions differ: a mix-up of sequences would show */
    double apart = max_diff(ref[0], ref[1], n[0] < n[1] ? n[0] : n[1]);
    CR_CHECK_OK(cr_swingar_predict(m, g, &mo[0], 0, out[0], &err), &err);
    double dc = max_diff(out[0], ref[0], n[0]);
    printf("    alone: max |predict - one forward| %.2e m\n", dc);
    CR_CHECK(dc < 1e-5);
    cr_swingar_predict_stats ps;
    CR_CHECK_OK(cr_swingar_predict_batch(m, g, mo, 2, 0, out, &ps, &err), &err);
    double db = fmax(max_diff(out[0], ref[0], n[0]), max_diff(out[1], ref[1], n[1]));
    printf("    batch of 2: %.2e m (the motions %.2e m apart); arena peak %zu bytes\n", db, apart,
           ps.arena_peak_bytes);
    CR_CHECK(db < 1e-5);
    CR_CHECK(apart > 1e-3);
    CR_CHECK(ps.arena_peak_bytes > 0);
    CR_CHECK(cr_swingar_predict_batch(m, g, mo, 0, 0, out, NULL, &err) == CR_ERR_INVALID);
    free(out[0]), free(out[1]), free(ref[0]), free(ref[1]);
    cr_swingar_destroy(m);
}

CR_TEST(swingar, inference_matches_the_tape_forward) {
    /* issue 51: with the gradient off the GAT, LSTM and skinning run fused
     * forward-only kernels; predict (the runtime, gradient off) and a
     * gradient-off forward's parts give the tape's values (gradient on)
     * within float rounding, on every SIMD path the machine has (random
     * heads, so every layer reaches the output) */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_error err = {0};
    cr_swingar *m = random_tiny_model(7);
    CR_REQUIRE(m);
    const cr_swingar_garment *g = d->garments[d->sequences[0].garment_index];
    cr_swingar_motion mo = seq_motion(d, 0);
    const int64_t V = g->rest->nv, n = mo.nframes * V * 3, ns = mo.nframes * V * CR_NJOINTS;
    float *skin[2] = {0}, *coarse[2] = {0};
    float *ref = forward_grad(m, g, &mo, 1, &skin[0], &coarse[0]);
    float *out = malloc(sizeof(float) * (size_t)n);
    CR_REQUIRE(ref && skin[0] && coarse[0] && out);
    const int prev = cr_nn_cpu_simd();
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        CR_CHECK_OK(cr_swingar_predict(m, g, &mo, 0, out, &err), &err);
        double dp = max_diff(out, ref, n);
        printf("    simd %d: max |predict - tape forward| %.2e m\n", level, dp);
        CR_CHECK(dp < 1e-5);
        float *y = forward_grad(m, g, &mo, 0, &skin[1], &coarse[1]);
        CR_REQUIRE(y && skin[1] && coarse[1]);
        double dy = max_diff(y, ref, n), dw = max_diff(skin[1], skin[0], ns);
        double dc = max_diff(coarse[1], coarse[0], n);
        printf("    simd %d forward: output %.2e m, skinning weights %.2e, coarse %.2e m\n", level,
               dy, dw, dc);
        CR_CHECK(dy < 1e-5 && dw < 1e-6 && dc < 1e-5);
        free(y), free(skin[1]), free(coarse[1]);
    }
    cr_nn_cpu_set_simd(prev);
    free(out), free(ref), free(skin[0]), free(coarse[0]);
    cr_swingar_destroy(m);
}

/* One runtime stepping motion mo frame by frame into out (T,V,3). */
static cr_status runtime_steps(cr_swingar_runtime *rt, const cr_swingar_motion *mo, float *out,
                               cr_error *err) {
    const int64_t V = cr_swingar_runtime_vertices(rt);
    for (int32_t t = 0; t < mo->nframes; t++)
        CR_TRY(cr_swingar_runtime_step(rt, mo->poses + (size_t)t * CR_NJOINTS * 3,
                                       mo->trans + 3 * t, out + (size_t)t * V * 3, err));
    return CR_OK;
}

typedef struct runtime_job {
    cr_swingar_runtime *rt;
    const cr_swingar_motion *mo;
    float *out;
    cr_status st;
} runtime_job;

static void *runtime_thread(void *p) {
    runtime_job *j = p;
    for (int rep = 0; rep < 3 && j->st == CR_OK; rep++) {
        cr_swingar_runtime_reset(j->rt);
        j->st = runtime_steps(j->rt, j->mo, j->out, NULL);
    }
    return NULL;
}

CR_TEST(swingar, runtime_steps_equal_the_whole_motion) {
    /* frame by frame (the motion window of 4 slides over the 6 frames), after
     * a reset, two characters in one batch call, and two on their own
     * threads sharing one model: each equals one forward over the motion */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d && d->nsequences >= 2);
    cr_error err = {0};
    cr_swingar *m = random_tiny_model(5);
    CR_REQUIRE(m);
    const cr_swingar_garment *g = d->garments[d->sequences[0].garment_index];
    cr_swingar_motion mo[2] = {seq_motion(d, 0), seq_motion(d, 1)};
    CR_REQUIRE(mo[0].nframes > cr_swingar_get_def(m)->motion_window + 1);
    const int64_t V = g->rest->nv;
    float *ref[2] = {one_forward(m, g, &mo[0]), one_forward(m, g, &mo[1])};
    int64_t n[2] = {mo[0].nframes * V * 3, mo[1].nframes * V * 3};
    float *out[2] = {malloc(sizeof(float) * (size_t)n[0]), malloc(sizeof(float) * (size_t)n[1])};
    CR_REQUIRE(ref[0] && ref[1] && out[0] && out[1]);
    cr_swingar_runtime *rt[2] = {NULL, NULL};
    for (int i = 0; i < 2; i++)
        CR_CHECK_OK(cr_swingar_runtime_create(m, g, mo[i].joints, 0, &rt[i], &err), &err);
    CR_REQUIRE(rt[0] && rt[1]);
    CR_CHECK(cr_swingar_runtime_vertices(rt[0]) == V);
    size_t cap = cr_swingar_runtime_arena_bytes(rt[0]);
    for (int rep = 0; rep < 2; rep++) {
        cr_swingar_runtime_reset(rt[0]);
        CR_CHECK_OK(runtime_steps(rt[0], &mo[0], out[0], &err), &err);
        double dr = max_diff(out[0], ref[0], n[0]);
        printf("    %s: max |step - one forward| %.2e m, arena %zu bytes\n",
               rep ? "after reset" : "stepped", dr, cap);
        CR_CHECK(dr < 1e-5);
    }
    CR_CHECK(cr_swingar_runtime_arena_bytes(rt[0]) == cap);
#ifdef __GLIBC__
    /* nothing held on the heap grows while stepping (the arena is the
     * frame's memory; glibc's count of bytes in use stays put) */
    size_t held = mallinfo2().uordblks;
    cr_swingar_runtime_reset(rt[0]);
    CR_CHECK_OK(runtime_steps(rt[0], &mo[0], out[0], &err), &err);
    printf("    heap in use before / after a pass: %zu / %zu bytes\n", held,
           (size_t)mallinfo2().uordblks);
    CR_CHECK(mallinfo2().uordblks == held);
#endif
    /* the batch call: frame t of both characters at once */
    cr_swingar_runtime_reset(rt[0]);
    for (int32_t t = 0; t < mo[0].nframes && t < mo[1].nframes; t++) {
        float poses[2 * CR_NJOINTS * 3], trans[6];
        float *o[2] = {out[0] + (size_t)t * V * 3, out[1] + (size_t)t * V * 3};
        for (int i = 0; i < 2; i++) {
            memcpy(poses + i * CR_NJOINTS * 3, mo[i].poses + (size_t)t * CR_NJOINTS * 3,
                   sizeof(float) * CR_NJOINTS * 3);
            memcpy(trans + 3 * i, mo[i].trans + 3 * t, sizeof(float) * 3);
        }
        CR_CHECK_OK(cr_swingar_runtime_step_batch(rt, 2, poses, trans, o, &err), &err);
    }
    int64_t nb = (mo[0].nframes < mo[1].nframes ? mo[0].nframes : mo[1].nframes) * V * 3;
    double db = fmax(max_diff(out[0], ref[0], nb), max_diff(out[1], ref[1], nb));
    printf("    batch of 2: %.2e m\n", db);
    CR_CHECK(db < 1e-5);
    /* side by side on two threads, three passes each */
    runtime_job jobs[2] = {{rt[0], &mo[0], out[0], CR_OK}, {rt[1], &mo[1], out[1], CR_OK}};
    pthread_t th[2];
    for (int i = 0; i < 2; i++)
        CR_REQUIRE(pthread_create(&th[i], NULL, runtime_thread, &jobs[i]) == 0);
    for (int i = 0; i < 2; i++)
        pthread_join(th[i], NULL);
    double dt = fmax(max_diff(out[0], ref[0], n[0]), max_diff(out[1], ref[1], n[1]));
    printf("    two threads: %.2e m\n", dt);
    CR_CHECK(jobs[0].st == CR_OK && jobs[1].st == CR_OK);
    CR_CHECK(dt < 1e-5);
    CR_CHECK(cr_swingar_runtime_step(rt[0], NULL, mo[0].trans, out[0], &err) == CR_ERR_INVALID);
    for (int i = 0; i < 2; i++)
        cr_swingar_runtime_destroy(rt[i]);
    free(out[0]), free(out[1]), free(ref[0]), free(ref[1]);
    cr_swingar_destroy(m);
}

CR_TEST(swingar, runtime_opens_files_and_names_a_missing_one) {
    /* a saved model and the garment written as OBJ, fitted on the normal
     * mannequin: the untrained model is the skinned garment, so frame 0
     * (the rest pose) is the fitted rest garment moved by the root */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_swingar_def def = tiny_def();
    cr_error err = {0};
    cr_swingar *m = NULL;
    CR_CHECK_OK(cr_swingar_create(&def, 3, &m, &err), &err);
    CR_REQUIRE(m);
    char model[512], obj[512];
    snprintf(model, sizeof model, "%s/swingar_runtime.safetensors", cr_test_tmpdir());
    snprintf(obj, sizeof obj, "%s/swingar_runtime_dress.obj", cr_test_tmpdir());
    CR_CHECK_OK(cr_swingar_save(model, m, &err), &err);
    CR_CHECK_OK(cr_mesh_write(obj, d->garments[0]->rest, &err), &err);
    cr_swingar_runtime *rt = NULL;
    CR_CHECK_OK(cr_swingar_runtime_open(model, obj, "normal", 0, &rt, &err), &err);
    CR_REQUIRE(rt);
    const cr_mesh *rest = cr_swingar_runtime_rest(rt);
    const int64_t V = cr_swingar_runtime_vertices(rt);
    CR_CHECK(V == rest->nv && cr_swingar_runtime_body(rt));
    float pose[CR_NJOINTS * 3] = {0}, root[3] = {0.1f, 0.0f, -0.2f};
    float *out = malloc(sizeof(float) * (size_t)V * 3);
    CR_REQUIRE(out);
    CR_CHECK_OK(cr_swingar_runtime_step(rt, pose, root, out, &err), &err);
    double dr = 0;
    for (int64_t i = 0; i < V * 3; i++)
        dr = fmax(dr, fabs(out[i] - rest->pos[i] - root[i % 3]));
    printf("    opened: %lld vertices, frame 0 vs rest %.2e m\n", (long long)V, dr);
    CR_CHECK(dr < 1e-3);
    free(out);
    cr_swingar_runtime_destroy(rt);
    rt = NULL;
    char missing[600];
    snprintf(missing, sizeof missing, "%s/no_such_model.safetensors", cr_test_tmpdir());
    CR_CHECK(cr_swingar_runtime_open(missing, obj, NULL, 0, &rt, &err) != CR_OK);
    printf("    missing model: %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "no_such_model") != NULL && rt == NULL);
    cr_swingar_destroy(m);
}

CR_TEST(swingar, exact_removal_leaves_no_vertex_inside) {
    /* the simulated garment with every 7th vertex put 5 mm inside the posed
     * body (at its closest point, against the outward normal): after the
     * exact removal no vertex is inside on any frame */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d && d->nsequences >= 1);
    const cr_swingar_sequence *q = &d->sequences[0];
    const cr_swingar_garment *g = d->garments[q->garment_index];
    const cr_mesh *br = d->bodies[q->body_index].model->rest;
    const int64_t V = g->rest->nv, T = q->nframes;
    float *x = malloc(sizeof(float) * (size_t)(T * V * 3));
    float *pt = malloc(sizeof(float) * (size_t)(V * 3)),
          *nr = malloc(sizeof(float) * (size_t)(V * 3));
    float *dist = malloc(sizeof(float) * (size_t)V);
    CR_REQUIRE(x && pt && nr && dist);
    memcpy(x, q->garment_pos, sizeof(float) * (size_t)(T * V * 3));
    cr_error err = {0};
    int64_t pushed = 0;
    for (int64_t t = 0; t < T; t++) {
        cr_bvh *b = NULL;
        CR_REQUIRE(cr_bvh_build(q->body_pos + (size_t)t * br->nv * 3, br->nv, br->tri, br->nf, &b,
                                &err) == CR_OK);
        float *xt = x + (size_t)t * V * 3;
        cr_bvh_signed_distance_batch(b, xt, V, INFINITY, dist, nr, pt);
        for (int64_t i = 0; i < V; i += 7, pushed++)
            for (int k = 0; k < 3; k++)
                xt[3 * i + k] = pt[3 * i + k] - 0.005f * nr[3 * i + k];
        cr_bvh_destroy(b);
    }
    cr_swingar_removal_stats rs;
    CR_CHECK_OK(cr_swingar_remove_collisions_exact(g->rest, br, q->body_pos, (int32_t)T, 0.001f, x,
                                                   &rs, &err),
                &err);
    printf("    %lld vertex pushes (every 7th, each frame): inside before %.2f %%, after %.3f %%, "
           "%lld moves, %.3f s\n",
           (long long)pushed, 100 * rs.inside_before, 100 * rs.inside_after, (long long)rs.moved,
           rs.seconds);
    CR_CHECK(rs.inside_before > 0.1);
    CR_CHECK(rs.inside_after == 0.0);
    free(x), free(pt), free(nr), free(dist);
}

typedef struct loss_case {
    const cr_swingar_garment *g;
    const float *gt;
    cr_swingar_loss_def def;
} loss_case;

static cr_tensor *build_loss(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const loss_case *c = user;
    return cr_swingar_loss(ctx, &c->def, c->g, in[0], c->gt, NULL, NULL, 0, NULL);
}

CR_TEST(swingar, loss_gradients_match_differences) {
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    const cr_swingar_sequence *s = &d->sequences[0];
    const cr_swingar_garment *g = d->garments[s->garment_index];
    const int64_t V = g->rest->nv;
    /* prediction: frames 3, 4 of the simulation, perturbed by 5 mm */
    float *x = malloc(sizeof(float) * (size_t)(2 * V * 3));
    CR_REQUIRE(x);
    cr_rng rng = cr_rng_make(5, 0);
    for (int64_t i = 0; i < 2 * V * 3; i++)
        x[i] = s->garment_pos[3 * V * 3 + i] + 0.005f * (float)cr_rng_normal(&rng);
    loss_case c = {g, s->garment_pos + 3 * V * 3, cr_swingar_loss_default_def()};
    c.def.k_c = 0; /* the collision energy has its own test (test_losses) */
    nn_gradcheck_input in[1] = {{3, {2, V, 3}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "swingar loss";
    gd.step = 1e-4;
    gd.tol = 2e-2;
    gd.max_elems = 60;
    gd.arena_bytes = (size_t)256 << 20;
    nn_gradcheck_result r;
    CR_CHECK(nn_gradcheck(&gd, 1, in, NULL, build_loss, &c, &r) == 0);
    printf("    %lld elements, max error %.2e\n", (long long)r.checked, r.max_err);
    free(x);
}

CR_TEST(swingar, size_defs_are_valid) {
    /* the CLI's --size and bench_runtime's sizes: each a valid def, the
     * paper's unchanged, cpu with fewer heads, an unknown name refused */
    cr_error err = {0};
    const char *names[] = {"paper", "cpu", "tiny"};
    int heads[3];
    for (int i = 0; i < 3; i++) {
        cr_swingar_def d = cr_swingar_default_def();
        CR_CHECK_OK(cr_swingar_size_def(names[i], &d, &err), &err);
        CR_CHECK_OK(cr_swingar_def_validate(&d, &err), &err);
        heads[i] = d.garment_heads;
    }
    CR_CHECK(heads[0] == 24 && heads[1] == 4 && heads[2] == 2);
    cr_swingar_def d = cr_swingar_default_def();
    CR_CHECK(cr_swingar_size_def("huge", &d, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "huge") != NULL);
}

CR_TEST(swingar, def_round_trips_through_json) {
    cr_swingar_def a = tiny_def();
    a.alpha = 1.5f, a.norm = CR_GAT_NORM_RECEIVER, a.use_descriptor = 0;
    a.affinity = 1; /* Euclidean: saved, so run computes the same descriptor */
    char *s = cr_swingar_def_to_json(&a);
    CR_REQUIRE(s);
    cr_swingar_def b = cr_swingar_default_def();
    cr_error err = {0};
    CR_CHECK_OK(cr_swingar_def_from_json(s, "test", &b, &err), &err);
    CR_CHECK(memcmp(&a, &b, sizeof a) == 0);
    free(s);
    /* an unknown key is a config error naming it (the config table's), malformed JSON a
       parse error */
    CR_CHECK(cr_swingar_def_from_json("{\"widht\":3}", "test", &b, &err) == CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "widht") != NULL);
    cr_swingar_def bad = tiny_def();
    bad.motion_hidden = 7;
    CR_CHECK(cr_swingar_def_validate(&bad, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "motion_hidden") != NULL);
}

CR_TEST(swingar, split_shares_no_motion) {
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    int8_t t[8];
    CR_REQUIRE(d->nsequences == 2);
    const char *motions[] = {"twist"};
    cr_swingar_split(d, NULL, 0, motions, 1, NULL, 0, t);
    for (int i = 0; i < 2; i++)
        CR_CHECK(t[i] == (strcmp(d->sequences[i].motion, "twist") == 0 ? 1 : 0));
    const char *garments[] = {"dress"};
    cr_swingar_split(d, garments, 1, motions, 1, NULL, 0, t);
    for (int i = 0; i < 2; i++) /* walk on the held-out dress: unused */
        CR_CHECK(t[i] == (strcmp(d->sequences[i].motion, "twist") == 0 ? 1 : -1));
}

static cr_swingar_train_def tiny_train(void) {
    cr_swingar_train_def t = cr_swingar_train_default_def();
    t.model = tiny_def();
    t.window = 3;
    t.batch = 2;
    t.epochs = 8;
    t.stall_epochs = 2;
    t.stall_rel = 0.5f; /* switch early so both phases run */
    t.arena_bytes = (size_t)128 << 20;
    t.quiet = 1;
    t.seed = 11;
    return t;
}

CR_TEST(swingar, tiny_model_lowers_its_loss) {
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_swingar_train_def t = tiny_train();
    t.stall_epochs = 1000; /* vertex loss only: one objective from start to end */
    t.lr = 3e-3f;
    t.epochs = CR_TEST_SIZE(16, 2);
    cr_error err = {0};
    cr_swingar *m = NULL;
    cr_swingar_train_result r;
    CR_CHECK_OK(cr_swingar_train(&t, d, &m, &r, &err), &err);
    printf("    %lld params, %d epochs in %.1f s: loss %.5f -> %.5f, vertex %.2f -> %.2f cm\n",
           (long long)r.params, r.epochs_done, r.seconds, r.first_loss, r.last_loss,
           100 * r.first_vert_m, 100 * r.last_vert_m);
    CR_CHECK(r.epochs_done == t.epochs);
    CR_CHECK(isfinite(r.last_loss));
    if (!cr_test_quick()) { /* 8 epochs: a full run */
        CR_CHECK(r.last_loss < 0.9f * r.first_loss);
        CR_CHECK(r.last_vert_m < r.first_vert_m);
    }
    cr_swingar_destroy(m);
}

CR_TEST(swingar, supervised_first_switch_fires_in_a_short_run) {
    /* the default rule is relative to the run: 6 epochs switch to every loss
     * by the third at the latest (a window of 2 epochs, or half the run) */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_swingar_train_def t = tiny_train();
    t.stall_epochs = cr_swingar_train_default_def().stall_epochs;
    t.stall_rel = cr_swingar_train_default_def().stall_rel;
    t.epochs = CR_TEST_SIZE(6, 4);
    cr_error err = {0};
    cr_swingar *m = NULL;
    cr_swingar_train_result r;
    CR_CHECK_OK(cr_swingar_train(&t, d, &m, &r, &err), &err);
    printf("    %d epochs: every loss from epoch %d\n", r.epochs_done, r.switched_epoch);
    CR_CHECK(t.stall_epochs == 0);
    CR_CHECK(r.switched_epoch >= 1 && r.switched_epoch <= t.epochs / 2);
    cr_swingar_destroy(m);
}

CR_TEST(swingar, descriptor_standardisation_round_trips) {
    /* training sets the descriptor's mean and spread from its training
     * garments (here one: the mean is its descriptor, the spread the floor,
     * 1e-3 of |mean|); they are frozen (Adam leaves them) and come back from
     * the model file */
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    cr_swingar_train_def t = tiny_train();
    t.epochs = 1;
    cr_error err = {0};
    cr_swingar *m = NULL, *back = NULL;
    cr_swingar_train_result r;
    CR_CHECK_OK(cr_swingar_train(&t, d, &m, &r, &err), &err);
    CR_REQUIRE(m);
    char path[512];
    snprintf(path, sizeof path, "%s/swingar_std.safetensors", cr_test_tmpdir());
    CR_CHECK_OK(cr_swingar_save(path, m, &err), &err);
    CR_CHECK_OK(cr_swingar_load(path, &back, &err), &err);
    CR_REQUIRE(back);
    const cr_tensor *mean = cr_nn_params_find(cr_swingar_params(back), "descriptor.mean");
    const cr_tensor *sd = cr_nn_params_find(cr_swingar_params(back), "descriptor.std");
    CR_REQUIRE(mean && sd && mean->numel == t.model.descriptor_len);
    const float *desc = d->garments[d->sequences[0].garment_index]->descriptor;
    double dm = 0, ds = 0;
    for (int64_t k = 0; k < mean->numel; k++) {
        dm = fmax(dm, fabs(mean->data[k] - desc[k]));
        ds = fmax(ds, fabs(sd->data[k] - 1e-3 * fabs(desc[k])) / (1e-3 * fabs(desc[k]) + 1e-30));
    }
    printf("    mean vs the garment's descriptor %.2e, spread vs the floor %.2e (relative)\n", dm,
           ds);
    CR_CHECK(dm < 1e-7 && ds < 1e-5);
    cr_swingar_destroy(back);
    cr_swingar_destroy(m);
}

static int params_equal(cr_swingar *a, cr_swingar *b) {
    int64_t na, nb;
    float *pa = cr_nn_params_data(cr_swingar_params(a), &na);
    float *pb = cr_nn_params_data(cr_swingar_params(b), &nb);
    return na == nb && memcmp(pa, pb, sizeof(float) * (size_t)na) == 0;
}

CR_TEST(swingar, resume_is_bit_exact) {
    const cr_swingar_data *d = tiny_data();
    CR_REQUIRE(d);
    char ck[600], full[600];
    snprintf(ck, sizeof ck, "%s/swg_half.safetensors", cr_test_tmpdir());
    snprintf(full, sizeof full, "%s/swg_full.safetensors", cr_test_tmpdir());
    cr_swingar_train_def t = tiny_train();
    t.epochs = 4;
    cr_error err = {0};
    cr_swingar *a = NULL, *b = NULL, *c = NULL;
    cr_swingar_train_result ra, rb, rc;
    t.checkpoint = full;
    CR_CHECK_OK(cr_swingar_train(&t, d, &a, &ra, &err), &err);
    t.checkpoint = ck;
    t.stop_after = 2;
    CR_CHECK_OK(cr_swingar_train(&t, d, &b, &rb, &err), &err);
    CR_CHECK(rb.epochs_done == 2);
    t.resume = ck;
    t.stop_after = 0;
    CR_CHECK_OK(cr_swingar_train(&t, d, &c, &rc, &err), &err);
    printf("    switched to all losses at epoch %d; resumed to %d epochs\n", ra.switched_epoch,
           rc.epochs_done);
    CR_REQUIRE(a && b && c);
    CR_CHECK(rc.epochs_done == 4);
    CR_CHECK(ra.switched_epoch > 0 && ra.switched_epoch == rc.switched_epoch);
    CR_CHECK(params_equal(a, c));
    CR_CHECK(!params_equal(a, b));
    /* the saved weights load into an equal model */
    cr_swingar *l = NULL;
    CR_CHECK_OK(cr_swingar_load(full, &l, &err), &err);
    CR_CHECK(l && params_equal(a, l));
    cr_swingar_destroy(a);
    cr_swingar_destroy(b);
    cr_swingar_destroy(c);
    cr_swingar_destroy(l);
}
