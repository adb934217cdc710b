/* bench_epnet.c: epnet's Table 1 on our data (docs/epnet.md): a trained
 * epnet and a zero-RB baseline against the plastic reference simulator on
 * held-out motions and bodies, through crease eval's library (cr_eval_run),
 * plus persistence (the share of hinges folded past a threshold at the last
 * frame of a motion that returns to rest and holds), inference speed, and
 * a side-by-side picture.
 *
 *   bench_epnet EPNET_DIR BASELINE_DIR OUT_DIR [motion,motion,...] [body,body,...] [hold]
 *               [friction]
 * friction: the reference's Coulomb friction against the body (default 0,
 * the training loss's physics; cotton's is 0.3).
 */
#include "crease/epnet.h"
#include "crease/eval.h"
#include "crease/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const cr_eval_metric shown[] = {CR_EVAL_BED, CR_EVAL_PE,  CR_EVAL_BE, CR_EVAL_MED,
                                       CR_EVAL_CD,  CR_EVAL_BEN, CR_EVAL_COL};
enum { NSHOWN = sizeof shown / sizeof shown[0] };

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

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr,
                "usage: bench_epnet EPNET_DIR BASELINE_DIR OUT_DIR [motions] [bodies] [hold] "
                "[friction]\n");
        return 2;
    }
    char mbuf[512], bbuf[256];
    snprintf(mbuf, sizeof mbuf, "%s", argc > 4 ? argv[4] : "bend,raise_arms,dodge");
    snprintf(bbuf, sizeof bbuf, "%s", argc > 5 ? argv[5] : "normal,slim,heavy");
    const int hold = argc > 6 ? atoi(argv[6]) : 30;
    const double friction = argc > 7 ? atof(argv[7]) : 0.0;
    const char *motions[16], *bodies[8];
    int nm = 0, nb = 0;
    for (char *t = strtok(mbuf, ","); t && nm < 16; t = strtok(NULL, ","))
        motions[nm++] = t;
    for (char *t = strtok(bbuf, ","); t && nb < 8; t = strtok(NULL, ","))
        bodies[nb++] = t;
    cr_error err;
    cr_epnet *ep = NULL, *bl = NULL;
    if (cr_epnet_open(argv[1], &ep, &err) != CR_OK) return fail(&err);
    if (cr_epnet_open(argv[2], &bl, &err) != CR_OK) return fail(&err);
    const cr_mesh *g = cr_epnet_garment(ep);
    const int32_t V = g->nv, H = cr_epnet_hinge_count(ep);
    const float *bar = cr_epnet_rest_angles(ep);
    printf("| motion | body | method | BED rad | PE rad | BE rad | MED m | CD | BEN J | COL m | "
           "folded share at the end, > 0.3 / > 0.1 rad | s/frame | RB realised |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int b = 0; b < nb; b++)
        for (int mi = 0; mi < nm; mi++) {
            cr_epnet_seq *s = NULL;
            if (cr_epnet_seq_create(ep, motions[mi], bodies[b], 0, hold, &s, &err) != CR_OK)
                return fail(&err);
            const int32_t T = cr_epnet_seq_frames(s);
            float *ref = malloc(sizeof(float) * 3 * (size_t)T * V),
                  *rrest = malloc(sizeof(float) * (size_t)T * H);
            float *pos = malloc(sizeof(float) * 3 * (size_t)T * V),
                  *rb = malloc(sizeof(float) * (size_t)T * H);
            float *th = malloc(sizeof(float) * (size_t)T * H),
                  *rth = malloc(sizeof(float) * (size_t)T * H);
            float *bpos = malloc(sizeof(float) * 3 * (size_t)T * V),
                  *th0 = malloc(sizeof(float) * (size_t)T * H);
            if (!ref || !rrest || !pos || !rb || !th || !rth || !bpos || !th0) return 1;
            if (cr_epnet_reference_friction(ep, s, 1, friction, ref, rrest, &err) != CR_OK)
                return fail(&err);
            absolute(rrest, bar, T, H);
            cr_epnet_angles(ep, ref, T, rth);
            for (int k = 0; k < 2; k++) {
                cr_epnet *m = k == 0 ? ep : bl;
                double t0 = cr_time_now();
                if (cr_epnet_rollout(m, s, k == 0, k == 0 ? pos : bpos, th, rb, &err) != CR_OK)
                    return fail(&err);
                const double spf = (cr_time_now() - t0) / T;
                /* RB realised: epnet's E-Net against itself with RB held at 0,
                 * at the last frame (whose E-Net input is RB of the frame
                 * before), over the hinges past 0.05 rad of RB */
                double realised = NAN;
                if (k == 0) {
                    if (cr_epnet_rollout(ep, s, 0, NULL, th0, NULL, &err) != CR_OK)
                        return fail(&err);
                    realised =
                        cr_epnet_rb_realised(th + (size_t)(T - 1) * H, th0 + (size_t)(T - 1) * H,
                                             rb + (size_t)(T - 2) * H, H, 0.05);
                }
                absolute(rb, bar, T, H);
                cr_eval_def ed = cr_eval_default_def();
                cr_epnet_material(&ed.material);
                cr_eval_input in = {.garment = g,
                                    .nframes = T,
                                    .pred = k == 0 ? pos : bpos,
                                    .ref = ref,
                                    .body_mesh = cr_epnet_seq_body_mesh(s),
                                    .body = cr_epnet_seq_body(s),
                                    .body_nframes = T,
                                    .ref_rest = rrest,
                                    .ref_rest_nframes = T,
                                    .pred_rest = rb,
                                    .pred_rest_nframes = T,
                                    .rest_nhinges = H};
                cr_eval_result r;
                if (cr_eval_run(&ed, &in, &r, &err) != CR_OK) return fail(&err);
                printf("| %s | %s | %s |", motions[mi], bodies[b], k == 0 ? "epnet" : "baseline");
                for (int q = 0; q < NSHOWN; q++)
                    printf(" %.4g |", r.summary[shown[q]].mean);
                printf(" %.3f / %.3f | %.3f |", cr_epnet_fold_share(th, bar, T - 1, H, 0.3),
                       cr_epnet_fold_share(th, bar, T - 1, H, 0.1), spf);
                if (k == 0)
                    printf(" %.3f |\n", realised);
                else
                    printf(" |\n");
                cr_eval_result_free(&r);
            }
            {
                float *rp = rrest + (size_t)(T - 1) * H;
                printf("| %s | %s | reference | | | | | | | | %.3f / %.3f (plastic rest past "
                       "0.3: %.3f) | | |\n",
                       motions[mi], bodies[b], cr_epnet_fold_share(rth, bar, T - 1, H, 0.3),
                       cr_epnet_fold_share(rth, bar, T - 1, H, 0.1),
                       cr_epnet_fold_share(rp, bar, 0, H, 0.3));
            }
            if (b == 0 && mi == 0) {
                cr_image im[3];
                const float *body =
                    cr_epnet_seq_body(s) + (size_t)(T - 1) * cr_epnet_seq_body_mesh(s)->nv * 3;
                const float *frames[3] = {ref + (size_t)(T - 1) * V * 3,
                                          pos + (size_t)(T - 1) * V * 3,
                                          bpos + (size_t)(T - 1) * V * 3};
                for (int k = 0; k < 3; k++)
                    if (render(g, frames[k], cr_epnet_seq_body_mesh(s), body, &im[k], &err))
                        return fail(&err);
                cr_image grid;
                if (cr_image_grid(im, 3, 3, 8, (float[]){1, 1, 1}, &grid, &err) != CR_OK)
                    return fail(&err);
                char path[1024];
                snprintf(path, sizeof path, "%s/side_by_side_%s.png", argv[3], motions[mi]);
                if (cr_image_write_png(&grid, path, &err) != CR_OK) return fail(&err);
            }
            free(ref), free(rrest), free(pos), free(rb), free(th), free(rth), free(bpos), free(th0);
            cr_epnet_seq_destroy(s);
            fflush(stdout);
        }
    cr_epnet_destroy(ep), cr_epnet_destroy(bl);
    return 0;
}
