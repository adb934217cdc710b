/* cmd_eval.c: `crease eval`: every paper's metric of a predicted garment
 * sequence against a reference one (docs/eval.md), frame by frame, with a
 * report: per-frame JSON lines, the summary, a plot per metric and a heat
 * map of the per-vertex error at the worst frame; with seeds, a twin and a
 * baseline, every row of the table (cr_eval_table). Parse (cli_parse), read,
 * cr_eval_run and cr_eval_write_report per row, the table, report. */
#include "cli.h"
#include "crease/eval.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void help_eval(void) {
    printf("usage: crease eval --pred A.pc2 --ref B.pc2 --garment G.obj -o DIR [options]\n\n"
           "Compare a predicted garment sequence with a reference one of the same mesh, frame\n"
           "by frame, by every metric of the four papers (docs/eval.md): epnet's BED, BE, PE,\n"
           "MED, CD, BEN, COL, STE, SHE, GE, IE; gdsr's E_u, E_v, E_uv, normal-map SSIM and\n"
           "normal angle; swingar's E_dist, E_norm and collision ratio; drape's Chamfer\n"
           "distance and curvature spectrum; temporal jitter. Beside them, fold measures a\n"
           "chaotic reference can be held to: ring-tolerant and sorted BED and PE, fold\n"
           "share and retention, curvature band power over frames (resolved bands marked),\n"
           "the hem's swing; with a twin and a baseline, a table of all of them.\n\n"
           "options:\n"
           "  --pred A.pc2[,A2.pc2,..] predicted positions per frame; several: one per seed,\n"
           "                           reported as mean and spread\n"
           "  --ref B.pc2              reference positions per frame (same vertices and frames)\n"
           "  --garment G.obj          the rest mesh both animate (triangles, UVs, rest shape)\n"
           "  --twin T.pc2             the reference re-simulated with a tiny perturbation\n"
           "                           (crease simulate --twin): the floor, scored alike\n"
           "  --baseline S.pc2         a baseline (skinned garment, upsampled low simulation,\n"
           "                           zero-RB network): the share of its error removed\n"
           "  --body B.pc2             body positions per frame (with --body-mesh): COL, the\n"
           "                           collision ratio and the hem's frame\n"
           "  --body-mesh M.obj        the body mesh (alone: a static body)\n"
           "  --rest-angles R.npy      the reference's plastic rest angles, rad, (T,H) or (H)\n"
           "  --pred-rest-angles P.npy[,P2.npy,..]  the prediction's (one per --pred, or one\n"
           "                           for all), for PE and BEN (default: the rest mesh's)\n"
           "  --twin-rest-angles R.npy, --baseline-rest-angles R.npy  the same of the twin\n"
           "                           (admission needs it) and of the baseline\n"
           "  --fps F                  frames per second, for the inertial energy and the hem's\n"
           "                           frequency (default 30)\n"
           "  --material M             cotton (default), silk, denim or knit: the energies\n"
           "  --material-json F        override material fields from a JSON object\n"
           "  --bed-fraction X         share of hinges BED keeps, and the sorted measures' top\n"
           "                           share (default 0.1)\n"
           "  --ring N                 rings of the tolerant measures' neighbourhood (default 1)\n"
           "  --fold-threshold RAD     a hinge bent past it is folded (default 0.1)\n"
           "  --resolve-edges N        a curvature band is resolved when its wavelength spans N\n"
           "                           mean edges (default 3)\n"
           "  --band-every N           band power over every N-th frame (default 1)\n"
           "  --admit-plastic-bending RAD  admission: the reference's mean |plastic bending|\n"
           "                           at the last frame at least RAD (default 0.02)\n"
           "  --admit-twin-ratio X     and the twin's tolerant PE at most X times RB = 0's\n"
           "                           (default 0.7)\n"
           "  --ssim-side N            normal-map side in pixels (default 256)\n"
           "  -o DIR                   frames.jsonl, summary.json, plots/<metric>.png,\n"
           "                           heatmap.png, vertex_error.npy (T,V) for crease view (of\n"
           "                           the first prediction); the same for the other seeds in\n"
           "                           DIR/seed<k>/, the twin in DIR/twin/, the baseline in\n"
           "                           DIR/baseline/; table.md and table.json: every row\n"
           "  --json                   end with the summary as JSON on stdout\n");
}

enum { MAX_SEEDS = CLI_LIST_MAX_ITEMS };

typedef struct eval_opts {
    cli_list pred, pred_rest;
    const char *ref, *garment, *body, *body_mesh, *rest, *material, *material_json, *out;
    const char *twin, *twin_rest, *baseline, *baseline_rest;
    float fps, bed_fraction, fold_threshold, resolve_edges, admit_pb, admit_ratio;
    int ssim_side, json, ring, band_every;
} eval_opts;

static int parse(int argc, char **argv, eval_opts *o) {
    const cli_opt opts[] = {
        CLI_CUSTOM("--pred", cli_parse_list, &o->pred, 1),
        CLI_STR("--ref", &o->ref),
        CLI_STR("--garment", &o->garment),
        CLI_STR("--twin", &o->twin),
        CLI_STR("--baseline", &o->baseline),
        CLI_STR("--body", &o->body),
        CLI_STR("--body-mesh", &o->body_mesh),
        CLI_STR("--rest-angles", &o->rest),
        CLI_CUSTOM("--pred-rest-angles", cli_parse_list, &o->pred_rest, 1),
        CLI_STR("--twin-rest-angles", &o->twin_rest),
        CLI_STR("--baseline-rest-angles", &o->baseline_rest),
        CLI_STR("--material", &o->material),
        CLI_STR("--material-json", &o->material_json),
        CLI_FLOAT("--fps", &o->fps, 0.01, 100000),
        CLI_FLOAT("--bed-fraction", &o->bed_fraction, 1e-6, 1.0),
        CLI_INT("--ring", &o->ring, 1, 8),
        CLI_FLOAT("--fold-threshold", &o->fold_threshold, 1e-6, 3.14),
        CLI_FLOAT("--resolve-edges", &o->resolve_edges, 0.01, 1000),
        CLI_INT("--band-every", &o->band_every, 1, 1000000),
        CLI_FLOAT("--admit-plastic-bending", &o->admit_pb, 0, 3.14),
        CLI_FLOAT("--admit-twin-ratio", &o->admit_ratio, 1e-6, 1000),
        CLI_INT("--ssim-side", &o->ssim_side, 16, 2048),
        CLI_OUTPUT(&o->out),
        CLI_FLAG("--json", &o->json),
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse("eval", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->pred.n || !o->ref || !o->garment)
        return cli_usage("eval", "needs --pred, --ref and --garment");
    if (!o->out) return cli_usage("eval", "needs -o DIR");
    if (o->body && !o->body_mesh) return cli_usage("eval", "--body needs --body-mesh M.obj");
    if (o->pred_rest.n > 1 && o->pred_rest.n != o->pred.n)
        return cli_usage("eval",
                         "--pred-rest-angles: %d files for %d predictions (give one "
                         "per prediction, or one for all)",
                         o->pred_rest.n, o->pred.n);
    if (o->twin_rest && !o->twin) return cli_usage("eval", "--twin-rest-angles needs --twin");
    if (o->baseline_rest && !o->baseline)
        return cli_usage("eval", "--baseline-rest-angles needs --baseline");
    return CLI_OK;
}

/* A sequence scored against the reference: its positions and rest angles. */
typedef struct scored {
    const char *path;
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

/* A sequence and its rest mesh in different units (cm against m) would
 * give energies and distances off by powers of 100, not an error. */
#define SIZE_RATIO_MAX 5.0

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
static cr_status load_common(const eval_opts *o, eval_inputs *d, cr_eval_input *in, cr_error *err) {
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
    s->path = path;
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

static cr_status write_text(const char *path, const char *text, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    if (fputs(text, f.fp) < 0) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}

/* Score every row, write each report and the table; the first prediction's
 * report is DIR's own. */
static cr_status run(const eval_opts *o, const cr_eval_def *def, eval_inputs *d, cJSON **table,
                     cr_eval_report *rep, cr_error *err) {
    cr_eval_input in = {0};
    CR_TRY(load_common(o, d, &in, err));
    const int np = o->pred.n;
    d->rows = calloc((size_t)np + 2, sizeof(scored));
    if (!d->rows) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    for (int k = 0; k < np + 2; k++) {
        const char *path = k < np ? o->pred.items[k] : k == np ? o->twin : o->baseline;
        const char *rest =
            k < np    ? (o->pred_rest.n ? o->pred_rest.items[o->pred_rest.n > 1 ? k : 0] : NULL)
            : k == np ? o->twin_rest
                      : o->baseline_rest;
        if (!path) continue;
        d->nrows = k + 1;
        if (k >= np || np > 1) cr_log(CR_LOG_INFO, "eval: scoring %s", path);
        CR_TRY(score(path, rest, o->garment, def, d, &in, &d->rows[k], err));
        char dir[1100];
        if (k == 0)
            snprintf(dir, sizeof dir, "%s", o->out);
        else if (k < np)
            snprintf(dir, sizeof dir, "%s/seed%d", o->out, k + 1);
        else
            snprintf(dir, sizeof dir, "%s/%s", o->out, k == np ? "twin" : "baseline");
        cr_eval_report r = {0};
        CR_TRY(cr_eval_write_report(&d->rows[k].res, &in, dir, &r, err));
        if (k == 0) *rep = r;
    }
    cr_eval_result *preds = calloc(np > 0 && np <= MAX_SEEDS ? (size_t)np : 1, sizeof *preds);
    if (!preds) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    for (int k = 0; k < np; k++)
        preds[k] = d->rows[k].res;
    cr_eval_admission adm;
    const cr_eval_result *twin = o->twin ? &d->rows[np].res : NULL;
    cr_eval_admit(def, twin && o->twin_rest ? twin : &preds[0], twin && o->twin_rest, &adm);
    cr_eval_table t = {.preds = preds,
                       .npreds = np,
                       .twin = twin,
                       .baseline = o->baseline ? &d->rows[np + 1].res : NULL,
                       .admission = &adm};
    char *json = cr_eval_table_json(&t), *md = cr_eval_table_text(&t);
    free(preds);
    cr_status st = json && md ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    char path[1200];
    snprintf(path, sizeof path, "%s/table.md", o->out);
    if (st == CR_OK) st = write_text(path, md, err);
    snprintf(path, sizeof path, "%s/table.json", o->out);
    if (st == CR_OK) st = write_text(path, json, err);
    if (st == CR_OK) {
        fputs(md, stderr);
        if (adm.defined && !adm.admitted)
            cr_log(CR_LOG_WARN, "eval: not admitted for plasticity: %s", adm.reason);
        *table = cJSON_Parse(json);
    }
    free(json), free(md);
    return st;
}

int cmd_eval(int argc, char **argv) {
    eval_opts o = {.material = "cotton"};
    int rc = parse(argc, argv, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    cr_eval_def def = cr_eval_default_def();
    if (cr_material_preset(o.material, &def.material, &err) != CR_OK)
        return cli_usage("eval", "%s", err.msg);
    if (o.fps > 0.0f) def.fps = o.fps;
    if (o.bed_fraction > 0.0f) def.bed_fraction = o.bed_fraction;
    if (o.ssim_side > 0) def.ssim_side = o.ssim_side;
    if (o.ring > 0) def.ring = o.ring;
    if (o.fold_threshold > 0.0f) def.fold_threshold = o.fold_threshold;
    if (o.resolve_edges > 0.0f) def.resolve_edges = o.resolve_edges;
    if (o.band_every > 0) def.band_every = o.band_every;
    if (o.admit_pb > 0.0f) def.admit_plastic_bending = o.admit_pb;
    if (o.admit_ratio > 0.0f) def.admit_twin_ratio = o.admit_ratio;
    eval_inputs d = {0};
    cr_eval_report rep = {0};
    cJSON *table = NULL;
    cr_status st = CR_OK;
    if (o.material_json) st = cr_material_load_json(o.material_json, &def.material, &err);
    if (st == CR_OK) st = run(&o, &def, &d, &table, &rep, &err);
    const cr_eval_result *res = d.nrows ? &d.rows[0].res : NULL;
    char *text = st == CR_OK ? cr_eval_summary_json(res) : NULL;
    if (st == CR_OK && !text) st = CR_FAIL(&err, CR_ERR_MEMORY, "out of memory");
    if (st == CR_OK) {
        fprintf(stderr,
                "eval: %d frames, %d vertices: MED %.4g m (worst frame %d), BED %.4g rad, "
                "SSIM %.4g\n",
                res->nframes, res->nv, res->summary[CR_EVAL_MED].mean, res->worst_frame,
                res->summary[CR_EVAL_BED].mean, res->summary[CR_EVAL_SSIM].mean);
        if (o.json) {
            cJSON *j = cJSON_Parse(text);
            cJSON *head = cJSON_CreateObject();
            cJSON_AddStringToObject(head, "command", "eval");
            cJSON_AddStringToObject(head, "pred", o.pred.items[0]);
            cJSON_AddStringToObject(head, "ref", o.ref);
            cJSON_AddStringToObject(head, "material", def.material.name);
            for (cJSON *it = j ? j->child : NULL; it;) {
                cJSON *next = it->next;
                cJSON_AddItemToObject(head, it->string, cJSON_DetachItemViaPointer(j, it));
                it = next;
            }
            cJSON_Delete(j);
            if (table) cJSON_AddItemToObject(head, "table", table), table = NULL;
            cJSON *outs = cJSON_AddObjectToObject(head, "outputs");
            cJSON_AddStringToObject(outs, "frames", rep.frames_jsonl);
            cJSON_AddStringToObject(outs, "summary", rep.summary_json);
            cJSON_AddStringToObject(outs, "plots", rep.plots_dir);
            cJSON_AddNumberToObject(outs, "nplots", rep.nplots);
            cJSON_AddStringToObject(outs, "heatmap", rep.heatmap_png);
            cJSON_AddStringToObject(outs, "vertex_error", rep.vertex_error_npy);
            cli_json_print(head);
        }
    }
    cJSON_Delete(table);
    free(text);
    inputs_free(&d);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}
