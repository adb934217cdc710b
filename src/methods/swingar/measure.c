/* measure.c: `crease swingar measure`, SwinGar's table on our data (docs/swingar.md):
 * trained models (one file per seed of one recipe) on the sequences of a test dataset,
 * each against the simulated reference through crease eval's library (cr_eval_run,
 * cr_eval_table), beside the baseline the model improves on (the garment skinned by its
 * own weights, the share of its error removed) and, with a twin dataset, the twin row:
 * the reference re-simulated with a tiny perturbation, the floor. The prediction is
 * what `swingar run` writes: the network's output with every vertex inside the posed
 * body moved out (exact distance), unless raw. A table per sequence
 * (OUT/table_<sequence>.json) and a summary over them, mean and spread over the seeds
 * (OUT/summary.json). */
#include "crease/body.h"
#include "crease/dataset.h"
#include "crease/eval.h"
#include "swingar_internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MEASURE_COOKIE 0x53574d31u

cr_swingar_measure_def cr_swingar_measure_default_def(void) {
    cr_swingar_measure_def d;
    memset(&d, 0, sizeof d);
    d.cookie = MEASURE_COOKIE;
    return d;
}

/* The models and the dataset as each model reads it (its descriptor). */
typedef struct measured {
    cr_swingar *m[CR_SWINGAR_MEASURE_MAX_SEEDS];
    cr_swingar_data data[CR_SWINGAR_MEASURE_MAX_SEEDS];
    int of[CR_SWINGAR_MEASURE_MAX_SEEDS]; /* model k reads data[of[k]] */
    int nm, nd;
    cr_swingar_data twin;
    int has_twin;
    cr_eval_def ed;
} measured;

static void measured_free(measured *ms) {
    for (int k = 0; k < ms->nm; k++)
        cr_swingar_destroy(ms->m[k]);
    for (int k = 0; k < ms->nd; k++)
        cr_swingar_data_free(&ms->data[k]);
    if (ms->has_twin) cr_swingar_data_free(&ms->twin);
}

static int same_reading(const cr_swingar_def *a, const cr_swingar_def *b) {
    return a->descriptor_len == b->descriptor_len && a->use_descriptor == b->use_descriptor &&
           a->affinity == b->affinity;
}

static cr_status measured_open(const cr_swingar_measure_def *def, measured *ms, cr_error *err) {
    for (int k = 0; k < def->nmodels; k++) {
        CR_TRY(cr_swingar_load(def->models[k], &ms->m[k], err));
        ms->nm++;
        const cr_swingar_def *mk = cr_swingar_get_def(ms->m[k]);
        ms->of[k] = -1;
        for (int j = 0; j < k && ms->of[k] < 0; j++)
            if (same_reading(cr_swingar_get_def(ms->m[j]), mk)) ms->of[k] = ms->of[j];
        if (ms->of[k] >= 0) continue;
        CR_TRY(cr_swingar_data_load(def->dataset, mk->descriptor_len, mk->use_descriptor,
                                    mk->affinity, &ms->data[ms->nd], err));
        ms->of[k] = ms->nd++;
    }
    if (def->twin) {
        const cr_swingar_def *m0 = cr_swingar_get_def(ms->m[0]);
        CR_TRY(
            cr_swingar_data_load(def->twin, m0->descriptor_len, 0, m0->affinity, &ms->twin, err));
        ms->has_twin = 1;
    }
    /* the reference's material and rate, as the dataset simulated it */
    cr_dataset_manifest man;
    CR_TRY(cr_dataset_read(def->dataset, &man, err));
    ms->ed = cr_eval_default_def();
    ms->ed.fps = man.fps;
    cr_status st = man.material ? cr_material_preset(man.material, &ms->ed.material, err) : CR_OK;
    cr_dataset_manifest_free(&man);
    return st;
}

/* The garment of sequence s skinned by its own weights: out (T,V,3). */
static void skinned(const cr_swingar_garment *g, const float *joints, const cr_swingar_sequence *s,
                    float *out) {
    const int32_t V = (int32_t)g->rest->nv;
    float xf[CR_NJOINTS * 12];
    for (int32_t t = 0; t < s->nframes; t++) {
        cr_body_skin_transforms(joints, s->poses + (size_t)t * CR_NJOINTS * 3, s->trans + 3 * t,
                                xf);
        for (int32_t v = 0; v < V; v++) {
            const float *x = g->rest->pos + 3 * (size_t)v,
                        *w = g->skin_weight + (size_t)v * CR_NJOINTS;
            float *o = out + ((size_t)t * V + v) * 3;
            o[0] = o[1] = o[2] = 0;
            for (int j = 0; j < CR_NJOINTS; j++) {
                if (w[j] == 0) continue;
                const float *A = xf + 12 * j;
                for (int r = 0; r < 3; r++)
                    o[r] += w[j] * (A[4 * r] * x[0] + A[4 * r + 1] * x[1] + A[4 * r + 2] * x[2] +
                                    A[4 * r + 3]);
            }
        }
    }
}

static cr_status score(const measured *ms, const cr_swingar_data *d, const cr_swingar_sequence *s,
                       const float *pos, const char *name, cr_eval_result *r, cr_error *err) {
    const cr_body_model *b = d->bodies[s->body_index].model;
    cr_eval_input in = {.garment = d->garments[s->garment_index]->rest,
                        .nframes = s->nframes,
                        .pred = pos,
                        .ref = s->garment_pos,
                        .body_mesh = b->rest,
                        .body = s->body_pos,
                        .body_nframes = s->nframes,
                        .pred_name = name,
                        .ref_name = s->id};
    return cr_eval_run(&ms->ed, &in, r, err);
}

/* One sequence's figures for the summary. */
typedef struct row {
    double seed_cm[CR_SWINGAR_MEASURE_MAX_SEEDS], skinned_cm, twin_cm;
    double inside_before, inside_after; /* largest share on a frame over the seeds */
} row;

static cr_status write_json(const char *path, const char *text, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    fprintf(f.fp, "%s\n", text);
    return cr_atomic_commit(&f, err);
}

static cr_status measure_sequence(const cr_swingar_measure_def *def, const measured *ms, int32_t si,
                                  row *rw, cr_error *err) {
    const cr_swingar_data *d0 = &ms->data[0];
    const cr_swingar_sequence *s = &d0->sequences[si];
    const cr_swingar_garment *g0 = d0->garments[s->garment_index];
    const cr_body_model *b = d0->bodies[s->body_index].model;
    const int32_t T = s->nframes, V = (int32_t)g0->rest->nv;
    const cr_swingar_sequence *tw = NULL;
    for (int32_t i = 0; ms->has_twin && i < ms->twin.nsequences && !tw; i++)
        if (!strcmp(ms->twin.sequences[i].id, s->id)) tw = &ms->twin.sequences[i];
    if (ms->has_twin && (!tw || tw->nframes != T))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar measure: %s/manifest.json: no twin of sequence %s with %d frames",
                       def->twin, s->id, T);
    float *pos = malloc(sizeof(float) * (size_t)T * V * 3);
    if (!pos) return CR_FAIL(err, CR_ERR_MEMORY, "swingar measure: out of memory");
    cr_eval_result er[CR_SWINGAR_MEASURE_MAX_SEEDS], base, twin;
    memset(er, 0, sizeof er), memset(&base, 0, sizeof base), memset(&twin, 0, sizeof twin);
    rw->inside_before = rw->inside_after = 0;
    skinned(g0, b->joints, s, pos);
    cr_status st = score(ms, d0, s, pos, "skinned", &base, err);
    for (int k = 0; st == CR_OK && k < def->nmodels; k++) {
        const cr_swingar_data *dk = &ms->data[ms->of[k]];
        if (strcmp(dk->sequences[si].id, s->id) != 0)
            st = CR_FAIL(err, CR_ERR_INVALID, "swingar measure: %s read differently", def->dataset);
        cr_swingar_motion mo = {T, b->joints, s->poses, s->trans};
        if (st == CR_OK)
            st = cr_swingar_predict(ms->m[k], dk->garments[s->garment_index], &mo, 0, pos, err);
        cr_swingar_removal_stats rs = {0};
        if (st == CR_OK && !def->raw)
            st = cr_swingar_remove_collisions_exact(g0->rest, b->rest, s->body_pos, T,
                                                    CR_SWINGAR_REMOVAL_MARGIN_M, pos, &rs, err);
        rw->inside_before = fmax(rw->inside_before, rs.inside_before);
        rw->inside_after = fmax(rw->inside_after, rs.inside_after);
        if (st == CR_OK) st = score(ms, d0, s, pos, def->models[k], &er[k], err);
    }
    if (st == CR_OK && tw) st = score(ms, d0, s, tw->garment_pos, "twin", &twin, err);
    if (st == CR_OK) {
        cr_eval_table t = {
            .preds = er, .npreds = def->nmodels, .twin = tw ? &twin : NULL, .baseline = &base};
        char *md = cr_eval_table_text(&t), *json = cr_eval_table_json(&t), path[1200];
        if (!md || !json) st = CR_FAIL(err, CR_ERR_MEMORY, "swingar measure: out of memory");
        if (st == CR_OK && def->print)
            fprintf(def->print, "\n%s (baseline: the garment skinned by its own weights):\n\n%s",
                    s->id, md);
        snprintf(path, sizeof path, "%s/table_%s.json", def->out_dir, s->id);
        if (st == CR_OK) st = write_json(path, json, err);
        free(md), free(json);
    }
    for (int k = 0; st == CR_OK && k < def->nmodels; k++)
        rw->seed_cm[k] = er[k].summary[CR_EVAL_E_DIST_CM].mean;
    rw->skinned_cm = base.summary[CR_EVAL_E_DIST_CM].mean;
    rw->twin_cm = tw ? twin.summary[CR_EVAL_E_DIST_CM].mean : NAN;
    for (int k = 0; k < CR_SWINGAR_MEASURE_MAX_SEEDS; k++)
        cr_eval_result_free(&er[k]);
    cr_eval_result_free(&base), cr_eval_result_free(&twin);
    free(pos);
    if (def->print) fflush(def->print);
    return st;
}

static cJSON *num(double v) {
    return isfinite(v) ? cJSON_CreateNumber(v) : cJSON_CreateNull();
}

/* The summary over the sequences: each seed's mean E_dist and the share of skinning's it
 * removes, their mean and spread over the seeds, the twin's; printed and as JSON. */
static cr_status summarise(const cr_swingar_measure_def *def, const row *rows,
                           const char *const *ids, int n, cr_swingar_measure_report *rep,
                           cr_error *err) {
    double seed_cm[CR_SWINGAR_MEASURE_MAX_SEEDS] = {0}, removed[CR_SWINGAR_MEASURE_MAX_SEEDS];
    double sk = 0, tw = 0, inside = 0;
    for (int i = 0; i < n; i++) {
        sk += rows[i].skinned_cm / n, tw += rows[i].twin_cm / n;
        inside = fmax(inside, rows[i].inside_after);
        for (int k = 0; k < def->nmodels; k++)
            seed_cm[k] += rows[i].seed_cm[k] / n;
    }
    for (int k = 0; k < def->nmodels; k++)
        removed[k] = 1.0 - seed_cm[k] / sk;
    memset(rep, 0, sizeof *rep);
    rep->sequences = n, rep->skinned_cm = sk, rep->twin_cm = def->twin ? tw : NAN;
    rep->inside_after = def->raw ? NAN : inside;
    cr_eval_mean_spread(seed_cm, def->nmodels, &rep->model_cm, &rep->model_cm_spread);
    cr_eval_mean_spread(removed, def->nmodels, &rep->removed, &rep->removed_spread);
    if (def->print) {
        fprintf(def->print, "\nE_dist, cm, over %d sequence%s (%d seed%s, %s):\n\n", n,
                n == 1 ? "" : "s", def->nmodels, def->nmodels == 1 ? "" : "s",
                def->raw ? "raw" : "collisions removed");
        fprintf(def->print, "| sequence | swingar mean | spread | skinned | removed | twin |\n"
                            "|---|---|---|---|---|---|\n");
        for (int i = 0; i < n; i++) {
            double m, sp;
            cr_eval_mean_spread(rows[i].seed_cm, def->nmodels, &m, &sp);
            fprintf(def->print, "| %s | %.3f | %.3f | %.3f | %.1f %% | %.3f |\n", ids[i], m, sp,
                    rows[i].skinned_cm, 100 * (1 - m / rows[i].skinned_cm), rows[i].twin_cm);
        }
        fprintf(def->print, "| **mean** | %.3f | %.3f | %.3f | %.1f %% (spread %.1f) | %.3f |\n",
                rep->model_cm, rep->model_cm_spread, sk, 100 * rep->removed,
                100 * rep->removed_spread, rep->twin_cm);
        fflush(def->print);
    }
    cJSON *j = cJSON_CreateObject(), *seqs = cJSON_AddArrayToObject(j, "sequences");
    for (int i = 0; i < n; i++) {
        cJSON *o = cJSON_CreateObject(), *a = cJSON_AddArrayToObject(o, "seeds_e_dist_cm");
        cJSON_AddStringToObject(o, "sequence", ids[i]);
        for (int k = 0; k < def->nmodels; k++)
            cJSON_AddItemToArray(a, num(rows[i].seed_cm[k]));
        cJSON_AddItemToObject(o, "skinned_e_dist_cm", num(rows[i].skinned_cm));
        cJSON_AddItemToObject(o, "twin_e_dist_cm", num(rows[i].twin_cm));
        cJSON_AddItemToObject(o, "inside_after", num(def->raw ? NAN : rows[i].inside_after));
        cJSON_AddItemToArray(seqs, o);
    }
    cJSON *a = cJSON_AddArrayToObject(j, "seeds_e_dist_cm"),
          *r = cJSON_AddArrayToObject(j, "seeds_removed");
    for (int k = 0; k < def->nmodels; k++)
        cJSON_AddItemToArray(a, num(seed_cm[k])), cJSON_AddItemToArray(r, num(removed[k]));
    cJSON_AddItemToObject(j, "e_dist_cm", num(rep->model_cm));
    cJSON_AddItemToObject(j, "e_dist_cm_spread", num(rep->model_cm_spread));
    cJSON_AddItemToObject(j, "skinned_e_dist_cm", num(sk));
    cJSON_AddItemToObject(j, "removed", num(rep->removed));
    cJSON_AddItemToObject(j, "removed_spread", num(rep->removed_spread));
    cJSON_AddItemToObject(j, "twin_e_dist_cm", num(rep->twin_cm));
    cJSON_AddItemToObject(j, "inside_after", num(rep->inside_after));
    cJSON_AddBoolToObject(j, "raw", def->raw);
    char *text = cJSON_PrintUnformatted(j), path[1200];
    cJSON_Delete(j);
    if (!text) return CR_FAIL(err, CR_ERR_MEMORY, "swingar measure: out of memory");
    snprintf(path, sizeof path, "%s/summary.json", def->out_dir);
    cr_status st = write_json(path, text, err);
    free(text);
    return st;
}

cr_status cr_swingar_measure(const cr_swingar_measure_def *def, cr_swingar_measure_report *rep,
                             cr_error *err) {
    if (!def || def->cookie != MEASURE_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar measure: def not made by its default");
    if (def->nmodels < 1 || def->nmodels > CR_SWINGAR_MEASURE_MAX_SEEDS || !def->dataset ||
        !def->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar measure: 1 to %d models, a dataset and an output folder are "
                       "required",
                       CR_SWINGAR_MEASURE_MAX_SEEDS);
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    measured ms;
    memset(&ms, 0, sizeof ms);
    cr_status st = measured_open(def, &ms, err);
    const cr_swingar_data *d0 = &ms.data[0];
    int8_t *is_test = st == CR_OK ? malloc((size_t)d0->nsequences + 1) : NULL;
    row *rows = st == CR_OK ? calloc((size_t)d0->nsequences + 1, sizeof *rows) : NULL;
    const char **ids = st == CR_OK ? calloc((size_t)d0->nsequences + 1, sizeof *ids) : NULL;
    if (st == CR_OK && (!is_test || !rows || !ids))
        st = CR_FAIL(err, CR_ERR_MEMORY, "swingar measure: out of memory");
    int n = 0;
    if (st == CR_OK) {
        cr_swingar_split(d0, def->garments, def->ngarments, def->motions, def->nmotions,
                         def->bodies, def->nbodies, is_test);
        const int all = def->ngarments + def->nmotions + def->nbodies == 0;
        if (def->print)
            fprintf(def->print, "swingar measure: %d model%s on %s%s\n", def->nmodels,
                    def->nmodels == 1 ? "" : "s", def->dataset, def->twin ? " with its twin" : "");
        for (int32_t i = 0; st == CR_OK && i < d0->nsequences; i++) {
            if (!(all || is_test[i] == 1)) continue;
            cr_log(CR_LOG_INFO, "swingar measure: %s", d0->sequences[i].id);
            ids[n] = d0->sequences[i].id;
            st = measure_sequence(def, &ms, i, &rows[n], err);
            n++;
        }
        if (st == CR_OK && n == 0)
            st = CR_FAIL(err, CR_ERR_INVALID,
                         "swingar measure: %s: no sequence is held out on the given axes",
                         def->dataset);
    }
    cr_swingar_measure_report r;
    if (st == CR_OK) st = summarise(def, rows, ids, n, &r, err);
    if (st == CR_OK && rep) *rep = r;
    free(is_test), free(rows), free(ids);
    measured_free(&ms);
    return st;
}
