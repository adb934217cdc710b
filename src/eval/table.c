/* table.c: one case scored several ways against one reference, side by
 * side (cr_eval_table): the predictions of several seeds as mean and
 * spread, the twin (the floor: the reference against itself re-run with a
 * tiny perturbation), a baseline, the share of the baseline's error removed
 * and the admission of a plasticity case; as JSON and as a Markdown table.
 *
 * Leaves out: significance tests (three seeds do not carry one; a
 * difference inside the spread is reported as such by the reader).
 */
#include "crease/eval.h"
#include "eval_internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The columns of the text table, in order, where defined. */
static const cr_eval_metric COLUMNS[] = {
    CR_EVAL_MED,       CR_EVAL_NORMAL_ANGLE,
    CR_EVAL_E_NORM,    CR_EVAL_SSIM,
    CR_EVAL_BE,        CR_EVAL_BED,
    CR_EVAL_BED_RING,  CR_EVAL_BED_SORTED,
    CR_EVAL_PE,        CR_EVAL_PE_RING,
    CR_EVAL_PE_SORTED, CR_EVAL_FOLD_SHARE,
    CR_EVAL_COL,       CR_EVAL_COLLISION_RATIO,
};
enum { NCOLUMNS = sizeof COLUMNS / sizeof COLUMNS[0] };

typedef struct stats {
    double mean, spread, min, max; /* spread: sample standard deviation, NAN for n < 2 */
    int n;
} stats;

/* Stats of v over the seeds, skipping non-finite values. */
static stats stats_of(const double *v, int n) {
    stats s = {NAN, NAN, NAN, NAN, 0};
    double sum = 0.0;
    for (int k = 0; k < n; k++) {
        if (!isfinite(v[k])) continue;
        if (!s.n || v[k] < s.min) s.min = v[k];
        if (!s.n || v[k] > s.max) s.max = v[k];
        sum += v[k], s.n++;
    }
    if (!s.n) return s;
    s.mean = sum / s.n;
    if (s.n > 1) {
        double q = 0.0;
        for (int k = 0; k < n; k++)
            if (isfinite(v[k])) q += (v[k] - s.mean) * (v[k] - s.mean);
        s.spread = sqrt(q / (s.n - 1));
    }
    return s;
}

void cr_eval_mean_spread(const double *v, int n, double *mean, double *spread) {
    stats s = stats_of(v, n);
    *mean = s.mean, *spread = s.spread;
}

/* What one row shows of a result: a metric's mean, or a summary-level figure. */
enum { FIG_RETENTION = -1, FIG_HEM = -2, FIG_BAND0 = -100 };

static double figure(const cr_eval_result *r, int what) {
    if (what >= 0) return r->summary[what].mean;
    if (what == FIG_RETENTION) return r->retention_pred;
    if (what == FIG_HEM) return r->has_hem ? r->hem_amplitude_pred_m : NAN;
    int b = what - FIG_BAND0;
    return r->has_band_power ? r->band_power_pred[b] : NAN;
}

static stats seed_stats(const cr_eval_table *t, int what, double *scratch) {
    for (int k = 0; k < t->npreds; k++)
        scratch[k] = figure(&t->preds[k], what);
    return stats_of(scratch, t->npreds);
}

static void add_stats(cJSON *o, const char *key, stats s) {
    cJSON *e = cJSON_AddObjectToObject(o, key);
    cr_eval_json_number(e, "mean", s.mean);
    cr_eval_json_number(e, "spread", s.spread);
    cr_eval_json_number(e, "min", s.min);
    cr_eval_json_number(e, "max", s.max);
}

char *cr_eval_table_json(const cr_eval_table *t) {
    if (!t || t->npreds < 1) return NULL;
    double *v = malloc((size_t)t->npreds * sizeof(double));
    cJSON *o = cJSON_CreateObject();
    if (!v || !o) {
        free(v), cJSON_Delete(o);
        return NULL;
    }
    const cr_eval_result *p0 = &t->preds[0];
    cJSON *seeds = cJSON_AddObjectToObject(o, "seeds");
    cJSON_AddNumberToObject(seeds, "n", t->npreds);
    cJSON *m = cJSON_AddObjectToObject(seeds, "metrics");
    for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++)
        if (p0->summary[k].count > 0)
            add_stats(m, cr_eval_metric_name((cr_eval_metric)k), seed_stats(t, k, v));
    add_stats(seeds, "retention", seed_stats(t, FIG_RETENTION, v));
    if (p0->has_hem) add_stats(seeds, "hem_amplitude_m", seed_stats(t, FIG_HEM, v));
    if (p0->has_band_power) {
        cJSON *bp = cJSON_AddArrayToObject(seeds, "band_power");
        for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
            cJSON *e = cJSON_CreateObject();
            stats s = seed_stats(t, FIG_BAND0 + b, v);
            cr_eval_json_number(e, "mean", s.mean), cr_eval_json_number(e, "spread", s.spread);
            cJSON_AddItemToArray(bp, e);
        }
    }
    const cr_eval_result *rows[2] = {t->twin, t->baseline};
    const char *names[2] = {"twin", "baseline"};
    for (int r = 0; r < 2; r++) {
        if (!rows[r]) continue;
        cJSON *e = cJSON_AddObjectToObject(o, names[r]);
        for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++)
            if (rows[r]->summary[k].count > 0)
                cr_eval_json_number(e, cr_eval_metric_name((cr_eval_metric)k),
                                    rows[r]->summary[k].mean);
        cr_eval_json_number(e, "retention", rows[r]->retention_pred);
        if (rows[r]->has_hem)
            cr_eval_json_number(e, "hem_amplitude_m", rows[r]->hem_amplitude_pred_m);
    }
    if (t->baseline) {
        cJSON *rm = cJSON_AddObjectToObject(o, "removed");
        cJSON *tw = t->twin ? cJSON_AddObjectToObject(o, "twin_removed") : NULL;
        for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++) {
            if (!isfinite(cr_eval_removed(p0, t->baseline, (cr_eval_metric)k))) continue;
            for (int s = 0; s < t->npreds; s++)
                v[s] = cr_eval_removed(&t->preds[s], t->baseline, (cr_eval_metric)k);
            stats st = stats_of(v, t->npreds);
            cJSON *e = cJSON_AddObjectToObject(rm, cr_eval_metric_name((cr_eval_metric)k));
            cr_eval_json_number(e, "mean", st.mean), cr_eval_json_number(e, "spread", st.spread);
            if (tw)
                cr_eval_json_number(tw, cr_eval_metric_name((cr_eval_metric)k),
                                    cr_eval_removed(t->twin, t->baseline, (cr_eval_metric)k));
        }
    }
    if (t->admission && t->admission->defined) {
        const cr_eval_admission *a = t->admission;
        cJSON *e = cJSON_AddObjectToObject(o, "admission");
        cJSON_AddBoolToObject(e, "admitted", a->admitted);
        cJSON_AddBoolToObject(e, "twin_tested", a->twin_tested);
        cr_eval_json_number(e, "plastic_bending_rad", a->plastic_bending_rad);
        cr_eval_json_number(e, "twin_pe_ring_rad", a->twin_pe_ring_rad);
        cr_eval_json_number(e, "rb0_pe_ring_rad", a->rb0_pe_ring_rad);
        cJSON_AddStringToObject(e, "reason", a->reason);
    }
    free(v);
    return cr_eval_json_text(o);
}

/* ----------------------------------------------------------------- text -- */

typedef struct text {
    char *buf;
    size_t len, cap;
    int failed;
} text;

static void put(text *t, const char *fmt, ...) {
    if (t->failed) return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0 || t->len + (size_t)n + 1 > t->cap) {
        size_t cap = 2 * (t->cap + (size_t)(n > 0 ? n : 0)) + 256;
        char *b = realloc(t->buf, cap);
        if (n < 0 || !b) {
            t->failed = 1;
            return;
        }
        t->buf = b, t->cap = cap;
    }
    va_start(ap, fmt);
    vsnprintf(t->buf + t->len, t->cap - t->len, fmt, ap);
    va_end(ap);
    t->len += (size_t)n;
}

char *cr_eval_table_text(const cr_eval_table *t) {
    if (!t || t->npreds < 1) return NULL;
    const cr_eval_result *p0 = &t->preds[0];
    int cols[NCOLUMNS + 2 + CR_EVAL_H_BANDS], nc = 0;
    for (int k = 0; k < NCOLUMNS; k++)
        if (p0->summary[COLUMNS[k]].count > 0) cols[nc++] = COLUMNS[k];
    cols[nc++] = FIG_RETENTION;
    if (p0->has_hem) cols[nc++] = FIG_HEM;
    for (int b = 0; p0->has_band_power && b < CR_EVAL_H_BANDS; b++)
        if (p0->band_resolved[b]) cols[nc++] = FIG_BAND0 + b;
    double *v = malloc((size_t)t->npreds * sizeof(double));
    text out = {0};
    if (!v) return NULL;
    put(&out, "| row |");
    for (int c = 0; c < nc; c++) {
        if (cols[c] >= 0)
            put(&out, " %s |", cr_eval_metric_name((cr_eval_metric)cols[c]));
        else if (cols[c] == FIG_RETENTION)
            put(&out, " retention |");
        else if (cols[c] == FIG_HEM)
            put(&out, " hem_amplitude_m |");
        else {
            int b = cols[c] - FIG_BAND0;
            double hi = cr_eval_h_band_edges_m[b], lo = cr_eval_h_band_edges_m[b + 1];
            if (isfinite(hi))
                put(&out, " power %g-%g cm |", 100.0 * lo, 100.0 * hi);
            else
                put(&out, " power > %g cm |", 100.0 * lo);
        }
    }
    put(&out, "\n|---|");
    for (int c = 0; c < nc; c++)
        put(&out, "---|");
    put(&out, "\n| prediction (%d seed%s) |", t->npreds, t->npreds == 1 ? "" : "s");
    for (int c = 0; c < nc; c++) {
        stats s = seed_stats(t, cols[c], v);
        if (s.n > 1)
            put(&out, " %.4g +- %.2g |", s.mean, s.spread);
        else
            put(&out, " %.4g |", s.mean);
    }
    const cr_eval_result *rows[2] = {t->twin, t->baseline};
    const char *names[2] = {"twin", "baseline"};
    for (int r = 0; r < 2; r++) {
        if (!rows[r]) continue;
        put(&out, "\n| %s |", names[r]);
        for (int c = 0; c < nc; c++)
            put(&out, " %.4g |", figure(rows[r], cols[c]));
    }
    if (p0->has_band_power) {
        put(&out, "\n| reference |");
        for (int c = 0; c < nc; c++) {
            int b = cols[c] - FIG_BAND0;
            if (cols[c] < FIG_BAND0 + CR_EVAL_H_BANDS && cols[c] >= FIG_BAND0)
                put(&out, " %.4g |", p0->band_power_ref[b]);
            else if (cols[c] == FIG_RETENTION)
                put(&out, " %.4g |", p0->retention_ref);
            else if (cols[c] == FIG_HEM)
                put(&out, " %.4g |", p0->hem_amplitude_ref_m);
            else
                put(&out, " |");
        }
    }
    if (t->baseline) {
        const cr_eval_result *who[2] = {NULL, t->twin};
        for (int w = 0; w < 2; w++) {
            if (w == 1 && !who[1]) continue;
            put(&out, "\n| share of the baseline's error removed%s |", w ? ", twin" : "");
            for (int c = 0; c < nc; c++) {
                if (cols[c] < 0 || !cr_eval_metric_is_error((cr_eval_metric)cols[c])) {
                    put(&out, " |");
                    continue;
                }
                if (w == 1) {
                    put(&out, " %.3f |",
                        cr_eval_removed(t->twin, t->baseline, (cr_eval_metric)cols[c]));
                    continue;
                }
                for (int s = 0; s < t->npreds; s++)
                    v[s] = cr_eval_removed(&t->preds[s], t->baseline, (cr_eval_metric)cols[c]);
                stats s = stats_of(v, t->npreds);
                if (s.n > 1)
                    put(&out, " %.3f +- %.2g |", s.mean, s.spread);
                else
                    put(&out, " %.3f |", s.mean);
            }
        }
    }
    put(&out, "\n");
    if (t->admission && t->admission->defined) {
        const cr_eval_admission *a = t->admission;
        put(&out, "admission: %s (the reference's mean |plastic bending| %.4g rad", a->reason,
            a->plastic_bending_rad);
        if (a->twin_tested)
            put(&out, "; tolerant PE: twin %.4g rad, RB = 0 %.4g", a->twin_pe_ring_rad,
                a->rb0_pe_ring_rad);
        put(&out, ")\n");
    }
    free(v);
    if (out.failed) {
        free(out.buf);
        return NULL;
    }
    return out.buf;
}
