/* files.c: `crease eval` as one call (cr_eval_files_run): the reference,
 * the garment, the body and rest angles read and checked (vertex and frame
 * counts, metres against centimetres), every row scored against the
 * reference (the predictions of each seed, the twin, the baseline:
 * cr_eval_run) with its report (cr_eval_write_report: the first
 * prediction's in the output folder, the others in seed<k>/, twin/,
 * baseline/), the admission and the table (table.md, table.json).
 *
 * Leaves out: printing (the caller shows the table and the summary). */
#include "crease/eval.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "eval_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FILES_COOKIE 0x45564631u /* "EVF1" */

/* A sequence and its rest mesh in different units (cm against m) would
 * give energies and distances off by powers of 100, not an error. */
#define SIZE_RATIO_MAX 5.0

cr_eval_files_def cr_eval_files_default_def(void) {
    cr_eval_files_def d;
    memset(&d, 0, sizeof d);
    d.eval = cr_eval_default_def();
    d.cookie = FILES_COOKIE;
    return d;
}

void cr_eval_files_result_free(cr_eval_files_result *r) {
    if (!r) return;
    cr_eval_result_free(&r->first);
    free(r->table_json), free(r->table_text);
    memset(r, 0, sizeof *r);
}

/* A sequence scored against the reference: its positions and rest angles. */
typedef struct scored {
    cr_pc2 seq;
    cr_npy rest;
    cr_eval_result res;
} scored;

typedef struct eval_inputs {
    cr_pc2 ref, body;
    cr_mesh *garment, *body_mesh;
    cr_npy rest;
    scored *rows; /* the predictions, then the twin and the baseline when given */
    int nrows;
} eval_inputs;

static void inputs_free(eval_inputs *in) {
    cr_pc2_free(&in->ref), cr_pc2_free(&in->body);
    cr_mesh_destroy(in->garment), cr_mesh_destroy(in->body_mesh);
    cr_npy_free(&in->rest);
    for (int k = 0; k < in->nrows; k++) {
        cr_pc2_free(&in->rows[k].seq), cr_npy_free(&in->rows[k].rest);
        cr_eval_result_free(&in->rows[k].res);
    }
    free(in->rows);
}

/* Rest angles (T,H) or (H) into the input; H is checked by cr_eval_run. */
static cr_status rest_angles(const char *path, cr_npy *a, const float **out, int32_t *nframes,
                             int32_t *nhinges, cr_error *err) {
    CR_TRY(cr_npy_read(path, CR_NPY_AS_F32, a, err));
    if (a->ndim != 1 && a->ndim != 2)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: rest angles must be (T,H) or (H), got %d dims", path,
                       (int)a->ndim);
    int32_t h = (int32_t)a->shape[a->ndim - 1];
    if (*nhinges && h != *nhinges)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: %d hinges, the other rest angles have %d", path, h,
                       *nhinges);
    *nhinges = h;
    *nframes = a->ndim == 2 ? (int32_t)a->shape[0] : 1;
    *out = a->f32;
    return CR_OK;
}

/* Bounding-box diagonal of the garment's vertices at positions pos (V,3), m. */
static double diagonal(const cr_mesh *garment, float *pos) {
    cr_mesh at = *garment;
    at.pos = pos;
    return cr_mesh_diagonal(&at);
}

static cr_status check_units(const char *mesh_path, const cr_mesh *garment, const char *pc2_path,
                             const cr_pc2 *seq, cr_error *err) {
    double g = diagonal(garment, garment->pos), f = diagonal(garment, seq->frames);
    if (!(f > SIZE_RATIO_MAX * g || g > SIZE_RATIO_MAX * f)) return CR_OK; /* NaN: cr_eval_run */
    return CR_FAIL(err, CR_ERR_INVALID,
                   "%s is %.4g m across (bounding-box diagonal) but frame 0 of %s is %.4g m, "
                   "more than %g times %s: are both in metres (not centimetres or millimetres)?",
                   mesh_path, g, pc2_path, f, SIZE_RATIO_MAX, f > g ? "larger" : "smaller");
}

/* The reference, the garment, the body and the reference's rest angles. */
static cr_status load_common(const cr_eval_files_def *o, eval_inputs *d, cr_eval_input *in,
                             cr_error *err) {
    CR_TRY(cr_pc2_read(o->ref, &d->ref, err));
    CR_TRY(cr_mesh_read(o->garment, &d->garment, err));
    if (d->garment->nv != d->ref.nv)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d vertices but %s has %d per frame", o->garment,
                       d->garment->nv, o->ref, d->ref.nv);
    CR_TRY(check_units(o->garment, d->garment, o->ref, &d->ref, err));
    *in = (cr_eval_input){.garment = d->garment,
                          .nframes = d->ref.nframes,
                          .ref = d->ref.frames,
                          .ref_name = o->ref,
                          .body_name = o->body};
    if (o->body_mesh) {
        CR_TRY(cr_mesh_read(o->body_mesh, &d->body_mesh, err));
        in->body_mesh = d->body_mesh;
    }
    if (o->body) {
        CR_TRY(cr_pc2_read(o->body, &d->body, err));
        if (d->body.nv != d->body_mesh->nv)
            return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d points per frame but %s has %d vertices",
                           o->body, d->body.nv, o->body_mesh, d->body_mesh->nv);
        in->body = d->body.frames, in->body_nframes = d->body.nframes;
        if (d->body.nframes > 1 && d->body.nframes < d->ref.nframes)
            cr_log(CR_LOG_WARN,
                   "%s has %d frames, %s %d: frames past %d are measured against its last", o->body,
                   d->body.nframes, o->ref, d->ref.nframes, d->body.nframes);
    }
    if (o->rest)
        CR_TRY(rest_angles(o->rest, &d->rest, &in->ref_rest, &in->ref_rest_nframes,
                           &in->rest_nhinges, err));
    return CR_OK;
}

/* One scored sequence against the reference: read, check, run. */
static cr_status score(const char *path, const char *rest, const char *garment_path,
                       const cr_eval_def *def, const eval_inputs *d, cr_eval_input *in, scored *s,
                       cr_error *err) {
    CR_TRY(cr_pc2_read(path, &s->seq, err));
    if (s->seq.nv != d->ref.nv)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d vertices per frame but %s has %d", path,
                       s->seq.nv, in->ref_name, d->ref.nv);
    if (s->seq.nframes != d->ref.nframes)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d frames but %s has %d", path, s->seq.nframes,
                       in->ref_name, d->ref.nframes);
    CR_TRY(check_units(garment_path, d->garment, path, &s->seq, err));
    in->pred = s->seq.frames, in->pred_name = path;
    in->pred_rest = NULL, in->pred_rest_nframes = 0;
    if (rest)
        CR_TRY(rest_angles(rest, &s->rest, &in->pred_rest, &in->pred_rest_nframes,
                           &in->rest_nhinges, err));
    return cr_eval_run(def, in, &s->res, err);
}

/* Score every row and write each report; the first prediction's report is
 * the output folder's own. */
static cr_status score_rows(const cr_eval_files_def *o, eval_inputs *d, cr_eval_report *rep,
                            cr_error *err) {
    cr_eval_input in = {0};
    CR_TRY(load_common(o, d, &in, err));
    const int np = o->npred;
    d->rows = calloc((size_t)np + 2, sizeof(scored));
    if (!d->rows) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    for (int k = 0; k < np + 2; k++) {
        const char *path = k < np ? o->pred[k] : k == np ? o->twin : o->baseline;
        const char *rest = k < np ? (o->npred_rest ? o->pred_rest[o->npred_rest > 1 ? k : 0] : NULL)
                           : k == np ? o->twin_rest
                                     : o->baseline_rest;
        if (!path) continue;
        d->nrows = k + 1;
        if (k >= np || np > 1) cr_log(CR_LOG_INFO, "eval: scoring %s", path);
        CR_TRY(score(path, rest, o->garment, &o->eval, d, &in, &d->rows[k], err));
        char dir[1100];
        if (k == 0)
            snprintf(dir, sizeof dir, "%s", o->out_dir);
        else if (k < np)
            snprintf(dir, sizeof dir, "%s/seed%d", o->out_dir, k + 1);
        else
            snprintf(dir, sizeof dir, "%s/%s", o->out_dir, k == np ? "twin" : "baseline");
        cr_eval_report r = {0};
        CR_TRY(cr_eval_write_report(&d->rows[k].res, &in, dir, &r, err));
        if (k == 0) *rep = r;
    }
    return CR_OK;
}

/* The admission and the table of every row, written as table.md and table.json. */
static cr_status write_table(const cr_eval_files_def *o, const eval_inputs *d,
                             cr_eval_files_result *r, cr_error *err) {
    const int np = o->npred;
    cr_eval_result *preds = calloc((size_t)np, sizeof *preds);
    if (!preds) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    for (int k = 0; k < np; k++)
        preds[k] = d->rows[k].res;
    const cr_eval_result *twin = o->twin ? &d->rows[np].res : NULL;
    cr_eval_admit(&o->eval, twin && o->twin_rest ? twin : &preds[0], twin && o->twin_rest,
                  &r->admission);
    cr_eval_table t = {.preds = preds,
                       .npreds = np,
                       .twin = twin,
                       .baseline = o->baseline ? &d->rows[np + 1].res : NULL,
                       .admission = &r->admission};
    r->table_json = cr_eval_table_json(&t), r->table_text = cr_eval_table_text(&t);
    free(preds);
    cr_status st =
        r->table_json && r->table_text ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    char path[1200];
    snprintf(path, sizeof path, "%s/table.md", o->out_dir);
    if (st == CR_OK) st = cr_eval_write_text_(path, r->table_text, err);
    snprintf(path, sizeof path, "%s/table.json", o->out_dir);
    if (st == CR_OK) st = cr_eval_write_text_(path, r->table_json, err);
    return st;
}

cr_status cr_eval_files_run(const cr_eval_files_def *def, cr_eval_files_result *out,
                            cr_error *err) {
    CR_ASSERT(def && def->cookie == FILES_COOKIE && out); /* made by cr_eval_files_default_def */
    memset(out, 0, sizeof *out);
    if (def->npred < 1 || !def->pred || !def->ref || !def->garment || !def->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "eval: needs a prediction, a reference, the garment and an output folder");
    if (def->body && !def->body_mesh)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: %s: a body sequence needs its mesh", def->body);
    if (def->npred_rest > 1 && def->npred_rest != def->npred)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: %d rest angle files for %d predictions",
                       def->npred_rest, def->npred);
    if ((def->twin_rest && !def->twin) || (def->baseline_rest && !def->baseline))
        return CR_FAIL(err, CR_ERR_INVALID, "eval: rest angles of a twin or baseline not given");
    eval_inputs d = {0};
    cr_status st = score_rows(def, &d, &out->report, err);
    if (st == CR_OK) st = write_table(def, &d, out, err);
    if (st == CR_OK) { /* the first prediction's result leaves with out */
        out->first = d.rows[0].res;
        memset(&d.rows[0].res, 0, sizeof d.rows[0].res);
    }
    inputs_free(&d);
    if (st != CR_OK) cr_eval_files_result_free(out);
    return st;
}
