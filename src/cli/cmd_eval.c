/* cmd_eval.c: `crease eval`: every paper's metric of a predicted garment
 * sequence against a reference one (docs/eval.md), frame by frame, with a
 * report: per-frame JSON lines, the summary, a plot per metric and a heat
 * map of the per-vertex error at the worst frame. Parse (cli_parse), read, one
 * cr_eval_run, one cr_eval_write_report, report. */
#include "cli.h"
#include "crease/eval.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void help_eval(void) {
    printf(
        "usage: crease eval --pred A.pc2 --ref B.pc2 --garment G.obj -o DIR [options]\n\n"
        "Compare a predicted garment sequence with a reference one of the same mesh, frame\n"
        "by frame, by every metric of the four papers (docs/eval.md): epnet's BED, BE, PE,\n"
        "MED, CD, BEN, COL, STE, SHE, GE, IE; gdsr's E_u, E_v, E_uv, normal-map SSIM and\n"
        "normal angle; swingar's E_dist, E_norm and collision ratio; drape's Chamfer\n"
        "distance and curvature spectrum; temporal jitter.\n\n"
        "options:\n"
        "  --pred A.pc2             predicted positions per frame\n"
        "  --ref B.pc2              reference positions per frame (same vertices and frames)\n"
        "  --garment G.obj          the rest mesh both animate (triangles, UVs, rest shape)\n"
        "  --body B.pc2             body positions per frame (with --body-mesh): COL and the\n"
        "                           collision ratio\n"
        "  --body-mesh M.obj        the body mesh (alone: a static body)\n"
        "  --rest-angles R.npy      the reference's plastic rest angles, rad, (T,H) or (H)\n"
        "  --pred-rest-angles P.npy the prediction's, for PE and BEN (default: the rest mesh's)\n"
        "  --fps F                  frames per second, for the inertial energy (default 30)\n"
        "  --material M             cotton (default), silk, denim or knit: the energies\n"
        "  --material-json F        override material fields from a JSON object\n"
        "  --bed-fraction X         share of hinges BED keeps (default 0.1)\n"
        "  --ssim-side N            normal-map side in pixels (default 256)\n"
        "  -o DIR                   frames.jsonl, summary.json, plots/<metric>.png,\n"
        "                           heatmap.png, vertex_error.npy (T,V) for crease view\n"
        "  --json                   end with the summary as JSON on stdout\n");
}

typedef struct eval_opts {
    const char *pred, *ref, *garment, *body, *body_mesh, *rest, *pred_rest, *material,
        *material_json, *out;
    float fps, bed_fraction;
    int ssim_side, json;
} eval_opts;

static int parse(int argc, char **argv, eval_opts *o) {
    const cli_opt opts[] = {
        CLI_STR("--pred", &o->pred),
        CLI_STR("--ref", &o->ref),
        CLI_STR("--garment", &o->garment),
        CLI_STR("--body", &o->body),
        CLI_STR("--body-mesh", &o->body_mesh),
        CLI_STR("--rest-angles", &o->rest),
        CLI_STR("--pred-rest-angles", &o->pred_rest),
        CLI_STR("--material", &o->material),
        CLI_STR("--material-json", &o->material_json),
        CLI_FLOAT("--fps", &o->fps, 0.01, 100000),
        CLI_FLOAT("--bed-fraction", &o->bed_fraction, 1e-6, 1.0),
        CLI_INT("--ssim-side", &o->ssim_side, 16, 2048),
        CLI_OUTPUT(&o->out),
        CLI_FLAG("--json", &o->json),
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse("eval", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->pred || !o->ref || !o->garment)
        return cli_usage("eval", "needs --pred, --ref and --garment");
    if (!o->out) return cli_usage("eval", "needs -o DIR");
    if (o->body && !o->body_mesh) return cli_usage("eval", "--body needs --body-mesh M.obj");
    return CLI_OK;
}

typedef struct eval_inputs {
    cr_pc2 pred, ref, body;
    cr_mesh *garment, *body_mesh;
    cr_npy rest, pred_rest;
} eval_inputs;

static void inputs_free(eval_inputs *in) {
    cr_pc2_free(&in->pred), cr_pc2_free(&in->ref), cr_pc2_free(&in->body);
    cr_mesh_destroy(in->garment), cr_mesh_destroy(in->body_mesh);
    cr_npy_free(&in->rest), cr_npy_free(&in->pred_rest);
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

static cr_status load(const eval_opts *o, eval_inputs *d, cr_eval_input *in, cr_error *err) {
    CR_TRY(cr_pc2_read(o->pred, &d->pred, err));
    CR_TRY(cr_pc2_read(o->ref, &d->ref, err));
    CR_TRY(cr_mesh_read(o->garment, &d->garment, err));
    if (d->pred.nv != d->ref.nv)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d vertices per frame but %s has %d", o->pred,
                       d->pred.nv, o->ref, d->ref.nv);
    if (d->pred.nframes != d->ref.nframes)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d frames but %s has %d", o->pred,
                       d->pred.nframes, o->ref, d->ref.nframes);
    if (d->garment->nv != d->pred.nv)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s has %d vertices but %s has %d per frame", o->garment,
                       d->garment->nv, o->pred, d->pred.nv);
    CR_TRY(check_units(o->garment, d->garment, o->pred, &d->pred, err));
    CR_TRY(check_units(o->garment, d->garment, o->ref, &d->ref, err));
    *in = (cr_eval_input){.garment = d->garment,
                          .nframes = d->pred.nframes,
                          .pred = d->pred.frames,
                          .ref = d->ref.frames,
                          .pred_name = o->pred,
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
        if (d->body.nframes > 1 && d->body.nframes < d->pred.nframes)
            cr_log(CR_LOG_WARN,
                   "%s has %d frames, %s %d: frames past %d are measured against its last", o->body,
                   d->body.nframes, o->pred, d->pred.nframes, d->body.nframes);
    }
    if (o->rest)
        CR_TRY(rest_angles(o->rest, &d->rest, &in->ref_rest, &in->ref_rest_nframes,
                           &in->rest_nhinges, err));
    if (o->pred_rest)
        CR_TRY(rest_angles(o->pred_rest, &d->pred_rest, &in->pred_rest, &in->pred_rest_nframes,
                           &in->rest_nhinges, err));
    return CR_OK;
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
    eval_inputs d = {0};
    cr_eval_input in = {0};
    cr_eval_result res = {0};
    cr_eval_report rep = {0};
    cr_status st = CR_OK;
    if (o.material_json) st = cr_material_load_json(o.material_json, &def.material, &err);
    if (st == CR_OK) st = load(&o, &d, &in, &err);
    if (st == CR_OK) st = cr_eval_run(&def, &in, &res, &err);
    if (st == CR_OK) st = cr_eval_write_report(&res, &in, o.out, &rep, &err);
    char *text = st == CR_OK ? cr_eval_summary_json(&res) : NULL;
    if (st == CR_OK && !text) st = CR_FAIL(&err, CR_ERR_MEMORY, "out of memory");
    if (st == CR_OK) {
        fprintf(stderr,
                "eval: %d frames, %d vertices: MED %.4g m (worst frame %d), BED %.4g rad, "
                "SSIM %.4g\n",
                res.nframes, res.nv, res.summary[CR_EVAL_MED].mean, res.worst_frame,
                res.summary[CR_EVAL_BED].mean, res.summary[CR_EVAL_SSIM].mean);
        if (o.json) {
            cJSON *j = cJSON_Parse(text);
            cJSON *head = cJSON_CreateObject();
            cJSON_AddStringToObject(head, "command", "eval");
            cJSON_AddStringToObject(head, "pred", o.pred);
            cJSON_AddStringToObject(head, "ref", o.ref);
            cJSON_AddStringToObject(head, "material", def.material.name);
            for (cJSON *it = j ? j->child : NULL; it;) {
                cJSON *next = it->next;
                cJSON_AddItemToObject(head, it->string, cJSON_DetachItemViaPointer(j, it));
                it = next;
            }
            cJSON_Delete(j);
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
    free(text);
    cr_eval_result_free(&res);
    inputs_free(&d);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}
