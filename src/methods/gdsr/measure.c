/* measure.c: gdsr's table (what `crease gdsr run` reports, docs/gdsr.md): each output of a
 * roll-out (gdsr, its raw output, upsampling, a GDSR(-d) baseline, the twin) against the
 * high reference through crease eval (cr_eval_run): the paper's metrics and the band power
 * of the folds the high mesh resolves; the edge-face crossings between an outfit's layers;
 * and the strain over the frames (strain.csv, strain.png), the roll-out's drift. */
#include "crease/eval.h"
#include "gdsr_internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static const cr_eval_metric shown[] = {
    CR_EVAL_MED, CR_EVAL_NORMAL_ANGLE, CR_EVAL_SSIM,           CR_EVAL_E_U,
    CR_EVAL_E_V, CR_EVAL_E_UV,         CR_EVAL_COLLISION_RATIO};
enum { NSHOWN = sizeof shown / sizeof shown[0] };
/* crease eval's curvature bands the table shows (cr_eval_h_band_edges_m) */
enum { BAND_4_8CM = 2, BAND_2_4CM = 3 };

/* On an outfit: edge-face crossings between the layers of frames 2.. of x,
 * their mean and largest count a frame and the frames with any, into o. */
void cr_gdsr_measure_header_(void) {
    char line[512];
    int n = snprintf(line, sizeof line, "  %-10s", "");
    for (int k = 0; k < NSHOWN; k++)
        n += snprintf(line + n, sizeof line - (size_t)n, " %11.11s", cr_eval_metric_name(shown[k]));
    snprintf(line + n, sizeof line - (size_t)n, " %11s %11s %11s %11s", "p4-8cm", "p4-8cm_ref",
             "p2-4cm", "p2-4cm_ref");
    cr_log(CR_LOG_INFO, "%s", line);
}

cr_status cr_gdsr_measure_crossings_(const cr_gdsr_data *d, const float *x, int32_t T,
                                     struct cJSON *o, const char *name, cr_error *err) {
    int64_t nh3 = (int64_t)d->high->nv * 3, most = 0, sum = 0;
    int32_t frames = 0;
    for (int32_t t = 2; t < T; t++) {
        int64_t c = cr_gdsr_layer_crossings(d, x + t * nh3, err);
        if (c < 0) return err ? err->status : CR_ERR_MEMORY;
        sum += c, most = c > most ? c : most, frames += c > 0;
    }
    double mean = T > 2 ? (double)sum / (T - 2) : 0.0;
    cJSON_AddNumberToObject(o, "layer_crossings_mean", mean);
    cJSON_AddNumberToObject(o, "layer_crossings_max", (double)most);
    cJSON_AddNumberToObject(o, "layer_crossing_frames", frames);
    cr_log(CR_LOG_INFO, "  %-10s layer crossings: mean %.2f, most %lld, on %d of %d frames", name,
           mean, (long long)most, frames, T > 2 ? T - 2 : 0);
    return CR_OK;
}

cr_status cr_gdsr_measure_row_(const cr_gdsr_data *d, const cr_gdsr_clip *cl, const float *pred,
                               const char *name, struct cJSON *table, cr_error *err) {
    cr_eval_def ed = cr_eval_default_def();
    /* frames 2.. (the model starts at frame 2) */
    int64_t nh3 = (int64_t)d->high->nv * 3;
    cr_eval_input in = {.garment = d->high,
                        .nframes = cl->nframes - 2,
                        .pred = pred + 2 * nh3,
                        .ref = cl->high + 2 * nh3,
                        .body_mesh = d->body,
                        .body = cl->body + (int64_t)2 * d->body->nv * 3,
                        .body_nframes = cl->nframes - 2,
                        .pred_name = name};
    cr_eval_result r = {0};
    CR_TRY(cr_eval_run(&ed, &in, &r, err));
    cJSON *o = cJSON_AddObjectToObject(table, name);
    char line[512];
    int n = snprintf(line, sizeof line, "  %-10s", name);
    for (int k = 0; k < NSHOWN; k++) {
        double v = r.summary[shown[k]].mean;
        cJSON_AddNumberToObject(o, cr_eval_metric_name(shown[k]), v);
        n += snprintf(line + n, sizeof line - (size_t)n, " %11.4g", v);
    }
    if (r.has_band_power) {
        /* the curvature power of the 4-8 and 2-4 cm bands over the frames (crease eval's
           band_power), against the reference's; '*' marks a band the high mesh resolves */
        cJSON *bp = cJSON_AddArrayToObject(o, "band_power_pred");
        cJSON *br = cJSON_AddArrayToObject(o, "band_power_ref");
        cJSON *res = cJSON_AddArrayToObject(o, "band_resolved");
        for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
            cJSON_AddItemToArray(bp, cJSON_CreateNumber(r.band_power_pred[b]));
            cJSON_AddItemToArray(br, cJSON_CreateNumber(r.band_power_ref[b]));
            cJSON_AddItemToArray(res, cJSON_CreateBool(r.band_resolved[b]));
        }
        for (int b = BAND_4_8CM; b <= BAND_2_4CM; b++)
            n += snprintf(line + n, sizeof line - (size_t)n, " %10.4g%c %10.4g%c",
                          r.band_power_pred[b], r.band_resolved[b] ? '*' : ' ', r.band_power_ref[b],
                          r.band_resolved[b] ? '*' : ' ');
    }
    cr_log(CR_LOG_INFO, "%s", line);
    cr_eval_result_free(&r);
    return d->nlayers > 1 ? cr_gdsr_measure_crossings_(d, pred, cl->nframes, o, name, err) : CR_OK;
}

/* E_u, E_v, E_uv of every frame of gdsr and of upsampling (crease eval's
 * functions; the prediction as its own reference): strain.csv and
 * strain.png (log axes), and the last frame's values against frame 2's in
 * the JSON (the roll-out's drift). */
cr_status cr_gdsr_measure_strain_(const cr_gdsr_data *d, const cr_gdsr_clip *cl,
                                  const cr_gdsr_rollout_result *r, const char *out, struct cJSON *j,
                                  cr_error *err) {
    static const cr_eval_metric em[3] = {CR_EVAL_E_U, CR_EVAL_E_V, CR_EVAL_E_UV};
    static const char *names[3] = {"e_u", "e_v", "e_uv"};
    int32_t T = cl->nframes;
    double *v = malloc((size_t)T * 7 * sizeof(double)); /* frame, 3 gdsr, 3 upsampled */
    if (!v) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr run: out of memory");
    cr_status st = CR_OK;
    for (int p = 0; p < 2 && st == CR_OK; p++) {
        const float *x = p ? r->upsampled : r->gdsr;
        cr_eval_def ed = cr_eval_default_def();
        ed.ssim_side = 16;
        cr_eval_input in = {.garment = d->high, .nframes = T, .pred = x, .ref = x};
        cr_eval_result er = {0};
        if ((st = cr_eval_run(&ed, &in, &er, err)) != CR_OK) break;
        for (int32_t t = 0; t < T; t++) {
            v[7 * t] = t;
            for (int k = 0; k < 3; k++)
                v[7 * t + 1 + 3 * p + k] = cr_eval_value(&er, t, em[k]);
        }
        cr_eval_result_free(&er);
    }
    char path[1100];
    cr_atomic_file f;
    snprintf(path, sizeof path, "%s/strain.csv", out);
    if (st == CR_OK && (st = cr_atomic_open(&f, path, err)) == CR_OK) {
        fprintf(f.fp, "frame,gdsr_e_u,gdsr_e_v,gdsr_e_uv,upsampled_e_u,upsampled_e_v,"
                      "upsampled_e_uv\n");
        for (int32_t t = 0; t < T; t++)
            fprintf(f.fp, "%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", t, v[7 * t + 1], v[7 * t + 2],
                    v[7 * t + 3], v[7 * t + 4], v[7 * t + 5], v[7 * t + 6]);
        st = cr_atomic_commit(&f, err);
    }
    double *col = st == CR_OK ? malloc((size_t)T * 7 * sizeof(double)) : NULL;
    if (st == CR_OK && !col) st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr run: out of memory");
    if (st == CR_OK) {
        for (int c = 0; c < 7; c++)
            for (int32_t t = 0; t < T; t++)
                col[(int64_t)c * T + t] = v[7 * t + c];
        cr_plot_series ser[6];
        cr_plot_panel pan[3];
        char label[6][48];
        for (int k = 0; k < 3; k++) {
            for (int p = 0; p < 2; p++) {
                snprintf(label[2 * k + p], sizeof label[0], "%s %s", p ? "upsampling" : "gdsr",
                         names[k]);
                ser[2 * k + p] =
                    (cr_plot_series){.name = label[2 * k + p],
                                     .x = col,
                                     .y = col + (int64_t)(1 + 3 * p + k) * T,
                                     .n = T,
                                     .rgb = {p ? 120 : 200, p ? 120 : 40, p ? 120 : 40}};
            }
            pan[k] = (cr_plot_panel){.series = ser + 2 * k, .nseries = 2, .log_y = 1};
        }
        cr_image img = {0};
        snprintf(path, sizeof path, "%s/strain.png", out);
        if ((st = cr_plot_lines(pan, 3, "frame", "gdsr roll-out: e_u, e_v, e_uv", 900, 700, &img,
                                err)) == CR_OK)
            st = cr_image_write_png(&img, path, err);
        cr_image_free(&img);
        /* frame 2 is the model's first; the last shows any drift */
        int32_t a = T > 2 ? 2 : 0, b = T - 1;
        cJSON *o = cJSON_AddObjectToObject(j, "strain");
        cJSON_AddNumberToObject(o, "first_frame", a);
        cJSON_AddNumberToObject(o, "last_frame", b);
        for (int k = 0; k < 3; k++) {
            char key[64];
            snprintf(key, sizeof key, "gdsr_%s_first", names[k]);
            cJSON_AddNumberToObject(o, key, v[7 * a + 1 + k]);
            snprintf(key, sizeof key, "gdsr_%s_last", names[k]);
            cJSON_AddNumberToObject(o, key, v[7 * b + 1 + k]);
            double mx = 0;
            for (int32_t t = a; t <= b; t++)
                mx = fmax(mx, v[7 * t + 1 + k]);
            snprintf(key, sizeof key, "gdsr_%s_max", names[k]);
            cJSON_AddNumberToObject(o, key, mx);
        }
        cr_log(CR_LOG_INFO,
               "  strain, frame %d -> %d: e_u %.3g -> %.3g, e_v %.3g -> %.3g, e_uv %.3g -> %.3g "
               "(%s/strain.png)",
               a, b, v[7 * a + 1], v[7 * b + 1], v[7 * a + 2], v[7 * b + 2], v[7 * a + 3],
               v[7 * b + 3], out);
    }
    free(col);
    free(v);
    return st;
}
