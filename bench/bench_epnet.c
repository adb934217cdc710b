/* bench_epnet.c: epnet's Table 1 on our data (docs/epnet.md): trained
 * epnets and zero-RB baselines (one per seed) against the plastic reference
 * simulator on held-out motions and bodies, through crease eval's library
 * (cr_eval_run, cr_eval_table), with the twin row: the reference re-simulated
 * with its friction changed by a tiny amount, the floor any prediction is
 * judged against (docs/eval.md). Every paper metric and the tolerant,
 * location-free and retention measures; mean and spread over the seeds; the
 * admission of each case (enough plasticity, and a twin that meets it);
 * persistence (the share of hinges folded past a threshold at the last
 * frame of a motion that returns to rest and holds), RB realised, inference
 * speed, and a side-by-side picture (reference, twin, epnet, baseline at the
 * last frame of the first case). Each table also goes to
 * OUT_DIR/table_{epnet,baseline}_<motion>_<body>.json (cr_eval_table_json).
 *
 *   bench_epnet EPNET_DIR[,DIR,..] BASELINE_DIR[,DIR,..] OUT_DIR [motion,motion,...]
 *               [body,body,...] [hold] [friction] [twin_friction_delta] [inference] [warmup]
 * Several model folders (comma-separated) are seeds of one recipe: the table
 * gives their mean and spread. friction: the reference's Coulomb friction
 * against the body (default 0, the training loss's physics; cotton's is
 * 0.3); twin_friction_delta: the twin's change of it (default 0.001);
 * inference: epnet's, proxy (default, cr_epnet_infer's) or closed-loop;
 * warmup: frames before frame 0 (default 0), for every model.
 */
#include "crease/epnet.h"
#include "crease/eval.h"
#include "crease/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_SEEDS = 8 };

static int fail(const cr_error *e) {
    fprintf(stderr, "bench_epnet: %s\n", e->msg);
    return 1;
}

static void absolute(float *rb, const float *bar, int32_t T, int32_t H) {
    for (int32_t t = 0; t < T; t++)
        for (int32_t h = 0; h < H; h++)
            rb[(size_t)t * H + h] += bar[h];
}

static int render(const cr_mesh *g, const float *pos, const cr_mesh *b, const float *body,
                  cr_image *img, cr_error *err) {
    cr_mesh gm = *g, bm = *b;
    gm.pos = (float *)pos, bm.pos = (float *)body, gm.normal = bm.normal = NULL;
    cr_render_def rd = cr_render_default_def();
    rd.width = rd.height = 400, rd.yaw_deg = 20;
    cr_render_object o[2] = {{.mesh = &bm, .color = {0.8f, 0.75f, 0.7f}},
                             {.mesh = &gm, .color = {0.3f, 0.5f, 0.85f}}};
    return cr_render_scene(&rd, o, 2, img, err) != CR_OK;
}

/* Split a comma list in place into items (at most max). */
static int split(char *list, const char **items, int max) {
    int n = 0;
    for (char *save = NULL, *t = strtok_r(list, ",", &save); t && n < max;
         t = strtok_r(NULL, ",", &save))
        items[n++] = t;
    return n;
}

/* One case's sequences: the reference, its twin, and a prediction's buffers. */
typedef struct buffers {
    float *ref, *rrest, *twin, *trest, *pos, *rb, *th, *rth, *th0;
} buffers;

static int buffers_alloc(buffers *b, int32_t T, int32_t V, int32_t H) {
    const size_t tv3 = (size_t)T * V * 3, th = (size_t)T * H;
    b->ref = malloc(sizeof(float) * tv3), b->twin = malloc(sizeof(float) * tv3);
    b->pos = malloc(sizeof(float) * tv3);
    b->rrest = malloc(sizeof(float) * th), b->trest = malloc(sizeof(float) * th);
    b->rb = malloc(sizeof(float) * th), b->th = malloc(sizeof(float) * th);
    b->rth = malloc(sizeof(float) * th), b->th0 = malloc(sizeof(float) * th);
    return b->ref && b->twin && b->pos && b->rrest && b->trest && b->rb && b->th && b->rth &&
           b->th0;
}

static void buffers_free(buffers *b) {
    free(b->ref), free(b->rrest), free(b->twin), free(b->trest), free(b->pos), free(b->rb);
    free(b->th), free(b->rth), free(b->th0);
}

/* Score positions pos with rest angles rest (absolute, (T,H); NULL: the rest mesh's)
 * against the case's reference. */
static cr_status score(const cr_epnet *ep, const cr_epnet_seq *s, const buffers *b,
                       const float *pos, const float *rest, cr_eval_result *r, cr_error *err) {
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(ep);
    cr_eval_def ed = cr_eval_default_def();
    cr_epnet_material(&ed.material);
    cr_eval_input in = {.garment = cr_epnet_garment(ep),
                        .nframes = T,
                        .pred = pos,
                        .ref = b->ref,
                        .body_mesh = cr_epnet_seq_body_mesh(s),
                        .body = cr_epnet_seq_body(s),
                        .body_nframes = T,
                        .ref_rest = b->rrest,
                        .ref_rest_nframes = T,
                        .pred_rest = rest,
                        .pred_rest_nframes = rest ? T : 0,
                        .rest_nhinges = H};
    return cr_eval_run(&ed, &in, r, err);
}

/* The table on stdout, and as JSON in dir/table_<name>_<motion>_<body>.json. */
static void print_table(const char *dir, const char *name, const char *motion, const char *body,
                        const char *what, const cr_eval_table *t) {
    char *md = cr_eval_table_text(t), *json = cr_eval_table_json(t), path[1200];
    printf("\n%s on %s, %s:\n\n%s", motion, body, what, md ? md : "(out of memory)\n");
    snprintf(path, sizeof path, "%s/table_%s_%s_%s.json", dir, name, motion, body);
    FILE *f = json ? fopen(path, "w") : NULL;
    if (f) fprintf(f, "%s\n", json), fclose(f);
    free(md), free(json);
}

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: bench_epnet EPNET_DIR[,DIR,..] BASELINE_DIR[,DIR,..] OUT_DIR "
                        "[motions] [bodies] [hold] [friction] [twin_friction_delta] "
                        "[proxy|closed-loop] [warmup]\n");
        return 2;
    }
    char ebuf[2048], lbuf[2048], mbuf[512], bbuf[256];
    snprintf(ebuf, sizeof ebuf, "%s", argv[1]);
    snprintf(lbuf, sizeof lbuf, "%s", argv[2]);
    snprintf(mbuf, sizeof mbuf, "%s", argc > 4 ? argv[4] : "bend,raise_arms,dodge");
    snprintf(bbuf, sizeof bbuf, "%s", argc > 5 ? argv[5] : "normal,slim,heavy");
    const int hold = argc > 6 ? atoi(argv[6]) : 30;
    const double friction = argc > 7 ? atof(argv[7]) : 0.0;
    const double twin_delta = argc > 8 ? atof(argv[8]) : 0.001;
    cr_epnet_infer_def inf = cr_epnet_infer_default_def(), zero;
    if (argc > 9 && !strcmp(argv[9], "closed-loop"))
        inf.mode = CR_EPNET_CLOSED_LOOP;
    else if (argc > 9 && strcmp(argv[9], "proxy")) {
        fprintf(stderr, "bench_epnet: inference '%s': expected proxy or closed-loop\n", argv[9]);
        return 2;
    }
    inf.warmup = argc > 10 ? atoi(argv[10]) : 0;
    zero = inf, zero.mode = CR_EPNET_ZERO_RB;
    const char *edirs[MAX_SEEDS], *ldirs[MAX_SEEDS], *motions[16], *bodies[8];
    const int ns = split(ebuf, edirs, MAX_SEEDS), nl = split(lbuf, ldirs, MAX_SEEDS);
    const int nm = split(mbuf, motions, 16), nb = split(bbuf, bodies, 8);
    cr_error err;
    cr_epnet *ep[MAX_SEEDS] = {0}, *bl[MAX_SEEDS] = {0};
    for (int k = 0; k < ns; k++)
        if (cr_epnet_open(edirs[k], &ep[k], &err) != CR_OK) return fail(&err);
    for (int k = 0; k < nl; k++)
        if (cr_epnet_open(ldirs[k], &bl[k], &err) != CR_OK) return fail(&err);
    const cr_mesh *g = cr_epnet_garment(ep[0]);
    const int32_t V = g->nv, H = cr_epnet_hinge_count(ep[0]);
    const float *bar = cr_epnet_rest_angles(ep[0]);
    float *last_ep = malloc(sizeof(float) * 3 * (size_t)V);
    if (!last_ep) return 1;
    printf("epnet: %d seed%s (%s inference), baseline: %d; reference friction %g, twin %+g; "
           "warm-up %d frames\n",
           ns, ns == 1 ? "" : "s", inf.mode == CR_EPNET_PROXY ? "proxy" : "closed-loop", nl,
           friction, twin_delta, inf.warmup);
    for (int b = 0; b < nb; b++)
        for (int mi = 0; mi < nm; mi++) {
            cr_epnet_seq *s = NULL;
            if (cr_epnet_seq_create(ep[0], motions[mi], bodies[b], 0, hold, &s, &err) != CR_OK)
                return fail(&err);
            const int32_t T = cr_epnet_seq_frames(s);
            buffers buf = {0};
            if (!buffers_alloc(&buf, T, V, H)) return 1;
            if (cr_epnet_reference_friction(ep[0], s, 1, friction, buf.ref, buf.rrest, &err) !=
                    CR_OK ||
                cr_epnet_reference_friction(ep[0], s, 1, friction + twin_delta, buf.twin, buf.trest,
                                            &err) != CR_OK)
                return fail(&err);
            absolute(buf.rrest, bar, T, H), absolute(buf.trest, bar, T, H);
            cr_epnet_angles(ep[0], buf.ref, T, buf.rth);
            cr_eval_result er[MAX_SEEDS] = {0}, br[MAX_SEEDS] = {0}, twin = {0};
            if (score(ep[0], s, &buf, buf.twin, buf.trest, &twin, &err) != CR_OK) return fail(&err);
            /* the predictions: persistence, RB realised and speed per seed */
            printf(
                "\n| %s | %s | model | folded share at the end, > 0.3 / > 0.1 rad | s/frame | RB "
                "realised |\n|---|---|---|---|---|---|\n",
                motions[mi], bodies[b]);
            for (int k = 0; k < ns + nl; k++) {
                const int is_ep = k < ns;
                cr_epnet *m = is_ep ? ep[k] : bl[k - ns];
                double t0 = cr_time_now();
                if (cr_epnet_infer(m, s, is_ep ? &inf : &zero, buf.pos, buf.th, buf.rb, &err) !=
                    CR_OK)
                    return fail(&err);
                const double spf = (cr_time_now() - t0) / T;
                /* RB realised: epnet's E-Net against itself with RB held at 0, at the
                 * last frame (whose E-Net input is RB of the frame before), over the
                 * hinges past 0.05 rad of RB */
                double realised = NAN;
                if (is_ep) {
                    if (cr_epnet_infer(m, s, &zero, NULL, buf.th0, NULL, &err) != CR_OK)
                        return fail(&err);
                    realised = cr_epnet_rb_realised(buf.th + (size_t)(T - 1) * H,
                                                    buf.th0 + (size_t)(T - 1) * H,
                                                    buf.rb + (size_t)(T - 2) * H, H, 0.05);
                }
                absolute(buf.rb, bar, T, H);
                if (score(m, s, &buf, buf.pos, buf.rb, is_ep ? &er[k] : &br[k - ns], &err) != CR_OK)
                    return fail(&err);
                printf("| | | %s %d | %.3f / %.3f | %.3f | %.3f |\n", is_ep ? "epnet" : "baseline",
                       is_ep ? k + 1 : k - ns + 1, cr_epnet_fold_share(buf.th, bar, T - 1, H, 0.3),
                       cr_epnet_fold_share(buf.th, bar, T - 1, H, 0.1), spf, realised);
                if (b == 0 && mi == 0 && k == 0) /* epnet's last frame, for the picture */
                    memcpy(last_ep, buf.pos + (size_t)(T - 1) * V * 3, sizeof(float) * 3 * V);
                if (b == 0 && mi == 0 && k == ns) {
                    /* reference, twin, epnet, baseline at the last frame */
                    cr_image im[4];
                    const float *body =
                        cr_epnet_seq_body(s) + (size_t)(T - 1) * cr_epnet_seq_body_mesh(s)->nv * 3;
                    const float *frames[4] = {buf.ref + (size_t)(T - 1) * V * 3,
                                              buf.twin + (size_t)(T - 1) * V * 3, last_ep,
                                              buf.pos + (size_t)(T - 1) * V * 3};
                    for (int q = 0; q < 4; q++)
                        if (render(g, frames[q], cr_epnet_seq_body_mesh(s), body, &im[q], &err))
                            return fail(&err);
                    cr_image grid;
                    if (cr_image_grid(im, 4, 4, 8, (float[]){1, 1, 1}, &grid, &err) != CR_OK)
                        return fail(&err);
                    char path[1024];
                    snprintf(path, sizeof path, "%s/side_by_side_%s.png", argv[3], motions[mi]);
                    if (cr_image_write_png(&grid, path, &err) != CR_OK) return fail(&err);
                    for (int q = 0; q < 4; q++)
                        cr_image_free(&im[q]);
                    cr_image_free(&grid);
                }
            }
            printf("| | | reference | %.3f / %.3f (plastic rest past 0.3: %.3f) | | |\n",
                   cr_epnet_fold_share(buf.rth, bar, T - 1, H, 0.3),
                   cr_epnet_fold_share(buf.rth, bar, T - 1, H, 0.1),
                   cr_epnet_fold_share(buf.rrest + (size_t)(T - 1) * H, bar, 0, H, 0.3));
            cr_eval_def ed = cr_eval_default_def();
            cr_eval_admission adm;
            cr_eval_admit(&ed, &twin, 1, &adm);
            cr_eval_table t = {
                .preds = er, .npreds = ns, .twin = &twin, .baseline = &br[0], .admission = &adm};
            print_table(argv[3], "epnet", motions[mi], bodies[b],
                        "epnet (baseline: the first zero-RB seed)", &t);
            cr_eval_table tb = {.preds = br, .npreds = nl};
            print_table(argv[3], "baseline", motions[mi], bodies[b], "the zero-RB baselines", &tb);
            for (int k = 0; k < MAX_SEEDS; k++)
                cr_eval_result_free(&er[k]), cr_eval_result_free(&br[k]);
            cr_eval_result_free(&twin);
            buffers_free(&buf);
            cr_epnet_seq_destroy(s);
            fflush(stdout);
        }
    for (int k = 0; k < ns; k++)
        cr_epnet_destroy(ep[k]);
    for (int k = 0; k < nl; k++)
        cr_epnet_destroy(bl[k]);
    free(last_ep);
    return 0;
}
