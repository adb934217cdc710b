/* report.c: crease eval's outputs from a cr_eval_result: per-frame JSON
 * lines, the summary JSON, one line plot per metric, the per-vertex error
 * of every frame as .npy (what `crease view --color-by DIR` colours by) and
 * a heat map of the per-vertex error at the worst frame, with a colour bar.
 *
 * Leaves out: HTML, turntables of the heat map, plots of several runs
 * against each other (compare summaries instead).
 */
#include "crease/eval.h"
#include "crease/npz.h"
#include "eval_internal.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    PLOT_W = 800,
    PLOT_H = 420,
    HEAT_PX = 720,
    BAR_STRIP_PX = 90,
};

static const uint8_t SERIES_RGB[2][3] = {{31, 119, 180}, {255, 127, 14}};

void cr_eval_json_number(cJSON *o, const char *key, double v) {
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

char *cr_eval_json_text(cJSON *o) {
    char *text = o ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    if (!text) return NULL;
    char *copy = malloc(strlen(text) + 1); /* cJSON's allocator need not be free()'s */
    if (copy) strcpy(copy, text);
    cJSON_free(text);
    return copy;
}

char *cr_eval_summary_json(const cr_eval_result *r) {
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    cJSON_AddNumberToObject(o, "frames", r->nframes);
    cJSON_AddNumberToObject(o, "vertices", r->nv);
    cJSON_AddNumberToObject(o, "hinges", r->nhinges);
    cJSON_AddNumberToObject(o, "bed_hinges", r->nbed_hinges);
    cJSON_AddBoolToObject(o, "bed_from_rest", r->bed_from_rest);
    cJSON_AddNumberToObject(o, "worst_frame", r->worst_frame);
    cJSON *m = cJSON_AddObjectToObject(o, "metrics");
    for (int k = 0; m && k < CR_EVAL_METRIC_COUNT; k++) {
        const cr_eval_summary *s = &r->summary[k];
        cJSON *e = cJSON_AddObjectToObject(m, cr_eval_metric_name((cr_eval_metric)k));
        if (!e) continue;
        cr_eval_json_number(e, "mean", s->mean);
        cr_eval_json_number(e, "max", s->max);
        cr_eval_json_number(e, "min", s->min);
        cJSON_AddNumberToObject(e, "worst_frame", s->worst_frame);
        cJSON_AddNumberToObject(e, "count", s->count);
        cJSON_AddStringToObject(e, "source", cr_eval_metric_source((cr_eval_metric)k));
    }
    if (r->has_spectrum) {
        cJSON *sp = cJSON_AddObjectToObject(o, "spectrum");
        cJSON *edges = cJSON_AddArrayToObject(sp, "band_edges_m");
        cJSON *p = cJSON_AddArrayToObject(sp, "pred"), *q = cJSON_AddArrayToObject(sp, "ref");
        /* the same bands' power in (1/m)^2 (cr_eval_curvature_spectrum) */
        cJSON *pp = cJSON_AddArrayToObject(sp, "pred_power");
        cJSON *qp = cJSON_AddArrayToObject(sp, "ref_power");
        for (int b = 0; b <= CR_EVAL_H_BANDS; b++)
            cJSON_AddItemToArray(edges, isfinite(cr_eval_h_band_edges_m[b])
                                            ? cJSON_CreateNumber(cr_eval_h_band_edges_m[b])
                                            : cJSON_CreateNull());
        for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
            cJSON_AddItemToArray(p, cJSON_CreateNumber(r->h_band_pred[b]));
            cJSON_AddItemToArray(q, cJSON_CreateNumber(r->h_band_ref[b]));
            cJSON_AddItemToArray(pp, cJSON_CreateNumber(r->h_power_pred[b]));
            cJSON_AddItemToArray(qp, cJSON_CreateNumber(r->h_power_ref[b]));
        }
    }
    if (r->has_band_power) {
        cJSON *bp = cJSON_AddObjectToObject(o, "band_power");
        cJSON *edges = cJSON_AddArrayToObject(bp, "band_edges_m");
        cr_eval_json_number(bp, "mean_edge_m", r->mean_edge_m);
        cJSON_AddNumberToObject(bp, "frames", r->band_frames);
        cJSON *res = cJSON_AddArrayToObject(bp, "resolved");
        cJSON *p = cJSON_AddArrayToObject(bp, "pred"), *q = cJSON_AddArrayToObject(bp, "ref");
        cJSON *ratio = cJSON_AddArrayToObject(bp, "ratio");
        for (int b = 0; b <= CR_EVAL_H_BANDS; b++)
            cJSON_AddItemToArray(edges, isfinite(cr_eval_h_band_edges_m[b])
                                            ? cJSON_CreateNumber(cr_eval_h_band_edges_m[b])
                                            : cJSON_CreateNull());
        for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
            double rt =
                r->band_power_ref[b] > 0.0 ? r->band_power_pred[b] / r->band_power_ref[b] : NAN;
            cJSON_AddItemToArray(res, cJSON_CreateBool(r->band_resolved[b]));
            cJSON_AddItemToArray(p, cJSON_CreateNumber(r->band_power_pred[b]));
            cJSON_AddItemToArray(q, cJSON_CreateNumber(r->band_power_ref[b]));
            cJSON_AddItemToArray(ratio, isfinite(rt) ? cJSON_CreateNumber(rt) : cJSON_CreateNull());
        }
    }
    cJSON *folds = cJSON_AddObjectToObject(o, "folds");
    cJSON_AddNumberToObject(folds, "ring", r->ring);
    cr_eval_json_number(folds, "threshold_rad", r->fold_threshold_rad);
    cr_eval_json_number(folds, "retention_pred", r->retention_pred);
    cr_eval_json_number(folds, "retention_ref", r->retention_ref);
    if (r->has_hem) {
        cJSON *h = cJSON_AddObjectToObject(o, "hem");
        cJSON_AddNumberToObject(h, "vertices", r->hem_vertices);
        cJSON_AddStringToObject(h, "frame", r->hem_in_body_frame ? "body" : "world");
        cr_eval_json_number(h, "amplitude_pred_m", r->hem_amplitude_pred_m);
        cr_eval_json_number(h, "amplitude_ref_m", r->hem_amplitude_ref_m);
        cr_eval_json_number(
            h, "amplitude_ratio",
            r->hem_amplitude_ref_m > 0.0 ? r->hem_amplitude_pred_m / r->hem_amplitude_ref_m : NAN);
        cr_eval_json_number(h, "frequency_pred_hz", r->hem_frequency_pred_hz);
        cr_eval_json_number(h, "frequency_ref_hz", r->hem_frequency_ref_hz);
    }
    return cr_eval_json_text(o);
}

cr_status cr_eval_write_text_(const char *path, const char *text, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    if (fputs(text, f.fp) < 0) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed: %s", path, strerror(errno));
    }
    return cr_atomic_commit(&f, err);
}

static cr_status write_frames(const cr_eval_result *r, const char *path, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    cr_status st = CR_OK;
    for (int32_t t = 0; st == CR_OK && t < r->nframes; t++) {
        cJSON *o = cJSON_CreateObject();
        if (!o) {
            st = CR_FAIL(err, CR_ERR_MEMORY, "out of memory writing %s", path);
            break;
        }
        cJSON_AddNumberToObject(o, "frame", t);
        for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++)
            cr_eval_json_number(o, cr_eval_metric_name((cr_eval_metric)k),
                                cr_eval_value(r, t, (cr_eval_metric)k));
        char *line = cJSON_PrintUnformatted(o);
        cJSON_Delete(o);
        if (!line) st = CR_FAIL(err, CR_ERR_MEMORY, "out of memory writing %s", path);
        if (line && fprintf(f.fp, "%s\n", line) < 0)
            st = CR_FAIL(err, CR_ERR_IO, "%s: write failed: %s", path, strerror(errno));
        cJSON_free(line);
    }
    if (st != CR_OK) {
        cr_atomic_abort(&f);
        return st;
    }
    return cr_atomic_commit(&f, err);
}

/* One PNG per metric defined on some frame; jitter_m also shows the reference's. */
static cr_status write_plots(const cr_eval_result *r, const char *dir, int *nplots, cr_error *err) {
    const int32_t T = r->nframes;
    double *x = cr_malloc(((size_t)T * 3 + 1) * sizeof(double), err);
    if (!x) return CR_ERR_MEMORY;
    double *y = x + T, *y2 = y + T;
    for (int32_t t = 0; t < T; t++)
        x[t] = t;
    cr_status st = CR_OK;
    *nplots = 0;
    for (int k = 0; st == CR_OK && k < CR_EVAL_METRIC_COUNT; k++) {
        if (k == CR_EVAL_JITTER_REF || r->summary[k].count == 0) continue;
        const char *name = cr_eval_metric_name((cr_eval_metric)k);
        for (int32_t t = 0; t < T; t++) {
            y[t] = cr_eval_value(r, t, (cr_eval_metric)k);
            y2[t] = cr_eval_value(r, t, CR_EVAL_JITTER_REF);
        }
        cr_plot_series s[2] = {
            {.name = k == CR_EVAL_JITTER ? "prediction" : NULL, .x = x, .y = y, .n = T},
            {.name = "reference", .x = x, .y = y2, .n = T}};
        memcpy(s[0].rgb, SERIES_RGB[0], 3), memcpy(s[1].rgb, SERIES_RGB[1], 3);
        cr_plot_panel panel = {s, k == CR_EVAL_JITTER ? 2 : 1, 0};
        char title[128], path[1200];
        const cr_eval_summary *sum = &r->summary[k];
        double worst = cr_eval_metric_higher_is_better((cr_eval_metric)k) ? sum->min : sum->max;
        snprintf(title, sizeof title, "%s (%s): mean %.4g, worst %.4g at frame %d", name,
                 cr_eval_metric_source((cr_eval_metric)k), sum->mean, worst, sum->worst_frame);
        snprintf(path, sizeof path, "%s/%s.png", dir, name);
        cr_image img = {0};
        st = cr_plot_lines(&panel, 1, "frame", title, PLOT_W, PLOT_H, &img, err);
        if (st == CR_OK) st = cr_image_write_png(&img, path, err);
        cr_image_free(&img);
        if (st == CR_OK) (*nplots)++;
    }
    free(x);
    return st;
}

static cr_status write_heatmap(const cr_eval_result *r, const cr_eval_input *in, const char *path,
                               cr_error *err) {
    const int32_t w = r->worst_frame, V = in->garment->nv;
    cr_mesh *g = NULL, *body = NULL;
    CR_TRY(cr_mesh_clone(in->garment, &g, err));
    memcpy(g->pos, in->pred + (size_t)w * V * 3, (size_t)V * 3 * sizeof(float));
    cr_status st = CR_OK;
    if (in->body_mesh) {
        st = cr_mesh_clone(in->body_mesh, &body, err);
        if (st == CR_OK && in->body) {
            int32_t tb = w < in->body_nframes ? w : in->body_nframes - 1;
            memcpy(body->pos, in->body + (size_t)tb * body->nv * 3,
                   (size_t)body->nv * 3 * sizeof(float));
        }
    }
    float hi = 0.0f;
    for (int32_t i = 0; i < V; i++)
        hi = fmaxf(hi, r->vertex_error[i]);
    if (!(hi > 0.0f)) hi = 1e-6f;
    cr_render_def def = cr_render_default_def();
    def.width = def.height = HEAT_PX;
    def.colormap_auto = 0;
    def.colormap_min = 0.0f, def.colormap_max = hi;
    cr_render_object objs[2] = {{.mesh = g, .scalar = r->vertex_error},
                                {.mesh = body, .color = {0.75f, 0.75f, 0.75f}}};
    cr_image render = {0}, img = {0};
    if (st == CR_OK) st = cr_render_scene(&def, objs, body ? 2 : 1, &render, err);
    if (st == CR_OK) st = cr_image_create(HEAT_PX, HEAT_PX + BAR_STRIP_PX, &img, err);
    if (st == CR_OK) {
        memset(img.rgb, 255, (size_t)img.width * img.height * 3);
        memcpy(img.rgb, render.rgb, (size_t)render.width * render.height * 3);
        char title[96];
        snprintf(title, sizeof title, "|pred - ref| at frame %d, m", w);
        const uint8_t ink[3] = {0, 0, 0};
        cr_plot_text(&img, 20, 16, 2, title, ink);
        cr_plot_colorbar(&img, 60, HEAT_PX + 10, HEAT_PX - 120, 22, 0.0, hi, "m");
        st = cr_image_write_png(&img, path, err);
    }
    cr_image_free(&render), cr_image_free(&img);
    cr_mesh_destroy(g), cr_mesh_destroy(body);
    return st;
}

/* (T,V) float32 |P_i - R_i| per frame, m. */
static cr_status write_vertex_error(const cr_eval_input *in, const char *path, cr_error *err) {
    const int64_t T = in->nframes, V = in->garment->nv;
    float *e = cr_malloc((size_t)(T * V) * sizeof(float) + 1, err);
    if (!e) return CR_ERR_MEMORY;
    for (int64_t k = 0; k < T * V; k++) {
        const float *p = in->pred + 3 * k, *q = in->ref + 3 * k;
        const double d0 = (double)p[0] - q[0], d1 = (double)p[1] - q[1], d2 = (double)p[2] - q[2];
        e[k] = (float)sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    }
    cr_status st = cr_npy_write(path, CR_NPY_F32, 2, (int64_t[]){T, V}, e, err);
    free(e);
    return st;
}

cr_status cr_eval_write_report(const cr_eval_result *r, const cr_eval_input *in, const char *dir,
                               cr_eval_report *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (!r->frames || r->nframes != in->nframes || r->nv != in->garment->nv)
        return CR_FAIL(err, CR_ERR_INVALID, "eval report: the result does not match its input");
    snprintf(out->frames_jsonl, sizeof out->frames_jsonl, "%s/frames.jsonl", dir);
    snprintf(out->summary_json, sizeof out->summary_json, "%s/summary.json", dir);
    snprintf(out->plots_dir, sizeof out->plots_dir, "%s/plots", dir);
    snprintf(out->heatmap_png, sizeof out->heatmap_png, "%s/heatmap.png", dir);
    snprintf(out->vertex_error_npy, sizeof out->vertex_error_npy, "%s/vertex_error.npy", dir);
    CR_TRY(cr_mkdir_p(out->plots_dir, err));
    CR_TRY(write_frames(r, out->frames_jsonl, err));
    char *summary = cr_eval_summary_json(r);
    if (!summary) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory writing %s", out->summary_json);
    size_t n = strlen(summary);
    char *line = malloc(n + 2);
    cr_status st = line ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    if (st == CR_OK) {
        memcpy(line, summary, n), line[n] = '\n', line[n + 1] = '\0';
        st = cr_eval_write_text_(out->summary_json, line, err);
    }
    free(line), free(summary);
    if (st == CR_OK) st = write_plots(r, out->plots_dir, &out->nplots, err);
    if (st == CR_OK) st = write_vertex_error(in, out->vertex_error_npy, err);
    if (st == CR_OK) st = write_heatmap(r, in, out->heatmap_png, err);
    return st;
}
