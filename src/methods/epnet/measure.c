/* measure.c: `crease epnet measure`, epnet's Table 1 on our data (docs/epnet.md):
 * trained epnets and zero-RB baselines (one folder per seed) against the plastic
 * reference simulator on held-out motions and bodies, through crease eval's library
 * (cr_eval_run, cr_eval_table), with the twin row: the reference re-simulated with its
 * friction changed by a tiny amount, the floor any prediction is judged against
 * (docs/eval.md). Every paper metric and the tolerant, location-free and retention
 * measures; mean and spread over the seeds; the admission of each case (enough
 * plasticity, and a twin that meets it); persistence (the share of hinges folded past a
 * threshold at the last frame of a motion that returns to rest and holds), RB realised,
 * inference speed, and a side-by-side picture (reference, twin, epnet, baseline at the
 * last frame of the first case). Each table also goes to
 * OUT/table_{epnet,baseline}_<motion>_<body>.json (cr_eval_table_json). */
#include "crease/eval.h"
#include "crease/render.h"
#include "epnet_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MEASURE_COOKIE 0x45504d31u

static const char *const default_motions[] = {"bend", "raise_arms", "dodge"};
static const char *const default_bodies[] = {"normal", "slim", "heavy"};

cr_epnet_measure_def cr_epnet_measure_default_def(void) {
    cr_epnet_measure_def d;
    memset(&d, 0, sizeof d);
    d.motions = default_motions, d.nmotions = 3;
    d.bodies = default_bodies, d.nbodies = 3;
    d.hold = 30, d.friction = 0.0, d.twin_friction = 0.001;
    d.infer = cr_epnet_infer_default_def();
    d.cookie = MEASURE_COOKIE;
    return d;
}

/* The loaded models: epnet seeds then baselines. */
typedef struct models {
    cr_epnet *ep[CR_EPNET_MEASURE_MAX_SEEDS], *bl[CR_EPNET_MEASURE_MAX_SEEDS];
    int ns, nl;
} models;

static void models_close(models *ms) {
    for (int k = 0; k < ms->ns; k++)
        cr_epnet_destroy(ms->ep[k]);
    for (int k = 0; k < ms->nl; k++)
        cr_epnet_destroy(ms->bl[k]);
}

static void absolute(float *rb, const float *bar, int32_t T, int32_t H) {
    for (int32_t t = 0; t < T; t++)
        for (int32_t h = 0; h < H; h++)
            rb[(size_t)t * H + h] += bar[h];
}

/* One case's sequences: the reference, its twin, and a prediction's buffers. */
typedef struct buffers {
    float *ref, *rrest, *twin, *trest, *pos, *rb, *th, *rth, *th0, *last_ep;
} buffers;

static cr_status buffers_alloc(buffers *b, int32_t T, int32_t V, int32_t H, cr_error *err) {
    const size_t tv3 = (size_t)T * V * 3, th = (size_t)T * H;
    b->ref = malloc(sizeof(float) * tv3), b->twin = malloc(sizeof(float) * tv3);
    b->pos = malloc(sizeof(float) * tv3), b->last_ep = malloc(sizeof(float) * 3 * (size_t)V);
    b->rrest = malloc(sizeof(float) * th), b->trest = malloc(sizeof(float) * th);
    b->rb = malloc(sizeof(float) * th), b->th = malloc(sizeof(float) * th);
    b->rth = malloc(sizeof(float) * th), b->th0 = malloc(sizeof(float) * th);
    return b->ref && b->twin && b->pos && b->last_ep && b->rrest && b->trest && b->rb && b->th &&
                   b->rth && b->th0
               ? CR_OK
               : CR_FAIL(err, CR_ERR_MEMORY, "epnet measure: out of memory");
}

static void buffers_free(buffers *b) {
    free(b->ref), free(b->rrest), free(b->twin), free(b->trest), free(b->pos), free(b->rb);
    free(b->th), free(b->rth), free(b->th0), free(b->last_ep);
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

/* The table on def->print, and as JSON in out_dir/table_<name>_<motion>_<body>.json. */
static cr_status print_table(const cr_epnet_measure_def *def, const char *name, const char *motion,
                             const char *body, const char *what, const cr_eval_table *t,
                             cr_error *err) {
    char *md = cr_eval_table_text(t), *json = cr_eval_table_json(t), path[1200];
    cr_status st = md && json ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "epnet measure: out of memory");
    if (st == CR_OK && def->print)
        fprintf(def->print, "\n%s on %s, %s:\n\n%s", motion, body, what, md);
    snprintf(path, sizeof path, "%s/table_%s_%s_%s.json", def->out_dir, name, motion, body);
    cr_atomic_file f;
    if (st == CR_OK) st = cr_atomic_open(&f, path, err);
    if (st == CR_OK) {
        fprintf(f.fp, "%s\n", json);
        st = cr_atomic_commit(&f, err);
    }
    free(md), free(json);
    return st;
}

/* Reference, twin, epnet and baseline at the last frame, side by side. */
static cr_status side_by_side(const cr_epnet_measure_def *def, const cr_epnet *m,
                              const cr_epnet_seq *s, const buffers *b, const char *motion,
                              cr_error *err) {
    const int32_t T = cr_epnet_seq_frames(s), V = cr_epnet_garment(m)->nv;
    const cr_mesh *bm = cr_epnet_seq_body_mesh(s);
    const float *body = cr_epnet_seq_body(s) + (size_t)(T - 1) * bm->nv * 3;
    const float *frames[4] = {b->ref + (size_t)(T - 1) * V * 3, b->twin + (size_t)(T - 1) * V * 3,
                              b->last_ep, b->pos + (size_t)(T - 1) * V * 3};
    cr_image im[4] = {0}, grid = {0};
    cr_status st = CR_OK;
    for (int q = 0; q < 4 && st == CR_OK; q++)
        st = cr_epnet_render_(m, frames[q], body, bm, NULL, 400, 20.0f, &im[q], err);
    if (st == CR_OK) st = cr_image_grid(im, 4, 4, 8, (float[]){1, 1, 1}, &grid, err);
    char path[1200];
    snprintf(path, sizeof path, "%s/side_by_side_%s.png", def->out_dir, motion);
    if (st == CR_OK) st = cr_image_write_png(&grid, path, err);
    for (int q = 0; q < 4; q++)
        cr_image_free(&im[q]);
    cr_image_free(&grid);
    return st;
}

/* Model k (epnet seeds first) on the case: scored into r, its row of persistence, speed
 * and RB realised printed. */
static cr_status predict(const cr_epnet_measure_def *def, const models *ms, int k,
                         const cr_epnet_seq *s, buffers *b, cr_eval_result *r, cr_error *err) {
    const int is_ep = k < ms->ns;
    cr_epnet *m = is_ep ? ms->ep[k] : ms->bl[k - ms->ns];
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m);
    const float *bar = cr_epnet_rest_angles(ms->ep[0]);
    cr_epnet_infer_def zero = def->infer;
    zero.mode = CR_EPNET_ZERO_RB;
    const double t0 = cr_time_now();
    CR_TRY(cr_epnet_infer(m, s, is_ep ? &def->infer : &zero, b->pos, b->th, b->rb, err));
    const double spf = (cr_time_now() - t0) / T;
    /* RB realised: epnet's E-Net against itself with RB held at 0, at the last frame
     * (whose E-Net input is RB of the frame before), over the hinges past 0.05 rad of RB */
    double realised = NAN;
    if (is_ep) {
        CR_TRY(cr_epnet_infer(m, s, &zero, NULL, b->th0, NULL, err));
        realised = cr_epnet_rb_realised(b->th + (size_t)(T - 1) * H, b->th0 + (size_t)(T - 1) * H,
                                        b->rb + (size_t)(T - 2) * H, H, 0.05);
    }
    absolute(b->rb, bar, T, H);
    CR_TRY(score(m, s, b, b->pos, b->rb, r, err));
    if (def->print)
        fprintf(def->print, "| | | %s %d | %.3f / %.3f | %.3f | %.3f |\n",
                is_ep ? "epnet" : "baseline", is_ep ? k + 1 : k - ms->ns + 1,
                cr_epnet_fold_share(b->th, bar, T - 1, H, 0.3),
                cr_epnet_fold_share(b->th, bar, T - 1, H, 0.1), spf, realised);
    return CR_OK;
}

/* One motion on one body: the reference and its twin, every model, the tables. */
static cr_status measure_case(const cr_epnet_measure_def *def, const models *ms, const char *motion,
                              const char *body, int first, cr_error *err) {
    cr_epnet *m0 = ms->ep[0];
    cr_epnet_seq *s = NULL;
    CR_TRY(cr_epnet_seq_create(m0, motion, body, def->frames, def->hold, &s, err));
    const int32_t T = cr_epnet_seq_frames(s), V = cr_epnet_garment(m0)->nv,
                  H = cr_epnet_hinge_count(m0);
    const float *bar = cr_epnet_rest_angles(m0);
    buffers b = {0};
    cr_eval_result er[CR_EPNET_MEASURE_MAX_SEEDS] = {0}, br[CR_EPNET_MEASURE_MAX_SEEDS] = {0},
                   twin = {0};
    cr_status st = buffers_alloc(&b, T, V, H, err);
    if (st == CR_OK) st = cr_epnet_reference_friction(m0, s, 1, def->friction, b.ref, b.rrest, err);
    if (st == CR_OK)
        st = cr_epnet_reference_friction(m0, s, 1, def->friction + def->twin_friction, b.twin,
                                         b.trest, err);
    if (st == CR_OK) {
        absolute(b.rrest, bar, T, H), absolute(b.trest, bar, T, H);
        cr_epnet_angles(m0, b.ref, T, b.rth);
        st = score(m0, s, &b, b.twin, b.trest, &twin, err);
    }
    if (st == CR_OK && def->print)
        fprintf(def->print,
                "\n| %s | %s | model | folded share at the end, > 0.3 / > 0.1 rad | s/frame | RB "
                "realised |\n|---|---|---|---|---|---|\n",
                motion, body);
    for (int k = 0; st == CR_OK && k < ms->ns + ms->nl; k++) {
        st = predict(def, ms, k, s, &b, k < ms->ns ? &er[k] : &br[k - ms->ns], err);
        if (st == CR_OK && first && k == 0) /* epnet's last frame, for the picture */
            memcpy(b.last_ep, b.pos + (size_t)(T - 1) * V * 3, sizeof(float) * 3 * V);
        if (st == CR_OK && first && k == ms->ns) st = side_by_side(def, m0, s, &b, motion, err);
    }
    if (st == CR_OK && def->print)
        fprintf(def->print, "| | | reference | %.3f / %.3f (plastic rest past 0.3: %.3f) | | |\n",
                cr_epnet_fold_share(b.rth, bar, T - 1, H, 0.3),
                cr_epnet_fold_share(b.rth, bar, T - 1, H, 0.1),
                cr_epnet_fold_share(b.rrest + (size_t)(T - 1) * H, bar, 0, H, 0.3));
    if (st == CR_OK) {
        cr_eval_def ed = cr_eval_default_def();
        cr_eval_admission adm;
        cr_eval_admit(&ed, &twin, 1, &adm);
        cr_eval_table t = {
            .preds = er, .npreds = ms->ns, .twin = &twin, .baseline = &br[0], .admission = &adm};
        st = print_table(def, "epnet", motion, body, "epnet (baseline: the first zero-RB seed)", &t,
                         err);
        cr_eval_table tb = {.preds = br, .npreds = ms->nl};
        if (st == CR_OK)
            st = print_table(def, "baseline", motion, body, "the zero-RB baselines", &tb, err);
    }
    for (int k = 0; k < CR_EPNET_MEASURE_MAX_SEEDS; k++)
        cr_eval_result_free(&er[k]), cr_eval_result_free(&br[k]);
    cr_eval_result_free(&twin);
    buffers_free(&b);
    cr_epnet_seq_destroy(s);
    if (def->print) fflush(def->print);
    return st;
}

cr_status cr_epnet_measure(const cr_epnet_measure_def *def, cr_error *err) {
    CR_ASSERT(def && def->cookie == MEASURE_COOKIE);
    if (def->nmodels < 1 || def->nmodels > CR_EPNET_MEASURE_MAX_SEEDS || def->nbaselines < 1 ||
        def->nbaselines > CR_EPNET_MEASURE_MAX_SEEDS)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "epnet measure: %d epnet and %d baseline folders (1 to %d each)",
                       def->nmodels, def->nbaselines, CR_EPNET_MEASURE_MAX_SEEDS);
    if (!def->out_dir || def->nmotions < 1 || def->nbodies < 1 || def->hold < 0 ||
        def->frames < 0 || !isfinite(def->friction) || def->friction < 0 ||
        !isfinite(def->twin_friction))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "epnet measure: an output folder, motions, bodies, hold >= 0 and a "
                       "finite friction >= 0 are required");
    CR_TRY(cr_epnet_infer_check_(&def->infer, err));
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    models ms = {0};
    cr_status st = CR_OK;
    for (int k = 0; st == CR_OK && k < def->nmodels; k++)
        if ((st = cr_epnet_open(def->models[k], &ms.ep[k], err)) == CR_OK) ms.ns++;
    for (int k = 0; st == CR_OK && k < def->nbaselines; k++)
        if ((st = cr_epnet_open(def->baselines[k], &ms.bl[k], err)) == CR_OK) ms.nl++;
    if (st == CR_OK && def->print)
        fprintf(def->print,
                "epnet: %d seed%s (%s inference), baseline: %d; reference friction %g, twin %+g; "
                "warm-up %d frames\n",
                ms.ns, ms.ns == 1 ? "" : "s",
                def->infer.mode == CR_EPNET_PROXY ? "proxy" : "closed-loop", ms.nl, def->friction,
                def->twin_friction, def->infer.warmup);
    for (int b = 0; st == CR_OK && b < def->nbodies; b++)
        for (int mi = 0; st == CR_OK && mi < def->nmotions; mi++) {
            cr_log(CR_LOG_INFO, "epnet measure: %s on %s", def->motions[mi], def->bodies[b]);
            st = measure_case(def, &ms, def->motions[mi], def->bodies[b], b == 0 && mi == 0, err);
        }
    models_close(&ms);
    return st;
}
