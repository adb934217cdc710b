/* cmd_eval.c: `crease eval`: every paper's metric of a predicted garment
 * sequence against a reference one (docs/eval.md), frame by frame, with a
 * report: per-frame JSON lines, the summary, a plot per metric and a heat
 * map of the per-vertex error at the worst frame; with seeds, a twin and a
 * baseline, every row of the table (cr_eval_table). Parse (cli_parse), one
 * call (cr_eval_files_run: read, score and report every row, the table),
 * report. */
#include "cli.h"
#include "crease/eval.h"

#include <stdlib.h>

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

typedef struct eval_opts {
    cli_list pred, pred_rest;
    const char *material, *material_json;
    float admit_pb; /* 0: the default (a given 0 keeps it too) */
    int json;
} eval_opts;

/* Into d and o; checks across options. */
static int parse(int argc, char **argv, cr_eval_files_def *d, eval_opts *o) {
    cr_eval_def *e = &d->eval;
    const cli_opt opts[] = {
        CLI_CUSTOM("--pred", cli_parse_list, &o->pred, 1),
        CLI_STR("--ref", &d->ref),
        CLI_STR("--garment", &d->garment),
        CLI_STR("--twin", &d->twin),
        CLI_STR("--baseline", &d->baseline),
        CLI_STR("--body", &d->body),
        CLI_STR("--body-mesh", &d->body_mesh),
        CLI_STR("--rest-angles", &d->rest),
        CLI_CUSTOM("--pred-rest-angles", cli_parse_list, &o->pred_rest, 1),
        CLI_STR("--twin-rest-angles", &d->twin_rest),
        CLI_STR("--baseline-rest-angles", &d->baseline_rest),
        CLI_STR("--material", &o->material),
        CLI_STR("--material-json", &o->material_json),
        CLI_FLOAT("--fps", &e->fps, 0.01, 100000),
        CLI_FLOAT("--bed-fraction", &e->bed_fraction, 1e-6, 1.0),
        CLI_INT("--ring", &e->ring, 1, 8),
        CLI_FLOAT("--fold-threshold", &e->fold_threshold, 1e-6, 3.14),
        CLI_FLOAT("--resolve-edges", &e->resolve_edges, 0.01, 1000),
        CLI_INT("--band-every", &e->band_every, 1, 1000000),
        CLI_FLOAT("--admit-plastic-bending", &o->admit_pb, 0, 3.14),
        CLI_FLOAT("--admit-twin-ratio", &e->admit_twin_ratio, 1e-6, 1000),
        CLI_INT("--ssim-side", &e->ssim_side, 16, 2048),
        CLI_OUTPUT(&d->out_dir),
        CLI_FLAG("--json", &o->json),
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse("eval", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->pred.n || !d->ref || !d->garment)
        return cli_usage("eval", "needs --pred, --ref and --garment");
    if (!d->out_dir) return cli_usage("eval", "needs -o DIR");
    if (d->body && !d->body_mesh) return cli_usage("eval", "--body needs --body-mesh M.obj");
    if (o->pred_rest.n > 1 && o->pred_rest.n != o->pred.n)
        return cli_usage("eval",
                         "--pred-rest-angles: %d files for %d predictions (give one "
                         "per prediction, or one for all)",
                         o->pred_rest.n, o->pred.n);
    if (d->twin_rest && !d->twin) return cli_usage("eval", "--twin-rest-angles needs --twin");
    if (d->baseline_rest && !d->baseline)
        return cli_usage("eval", "--baseline-rest-angles needs --baseline");
    d->pred = o->pred.items, d->npred = o->pred.n;
    d->pred_rest = o->pred_rest.items, d->npred_rest = o->pred_rest.n;
    if (o->admit_pb > 0.0f) e->admit_plastic_bending = o->admit_pb;
    return CLI_OK;
}

/* The summary of the first prediction with the command's fields, the table and the
 * report's paths. */
static void print_json(const cr_eval_files_def *d, const cr_eval_files_result *r,
                       const char *text) {
    cJSON *j = cJSON_Parse(text);
    cJSON *head = cJSON_CreateObject();
    cJSON_AddStringToObject(head, "command", "eval");
    cJSON_AddStringToObject(head, "pred", d->pred[0]);
    cJSON_AddStringToObject(head, "ref", d->ref);
    cJSON_AddStringToObject(head, "material", d->eval.material.name);
    for (cJSON *it = j ? j->child : NULL; it;) {
        cJSON *next = it->next;
        cJSON_AddItemToObject(head, it->string, cJSON_DetachItemViaPointer(j, it));
        it = next;
    }
    cJSON_Delete(j);
    cJSON *table = cJSON_Parse(r->table_json);
    if (table) cJSON_AddItemToObject(head, "table", table);
    const cr_eval_report *rep = &r->report;
    cJSON *outs = cJSON_AddObjectToObject(head, "outputs");
    cJSON_AddStringToObject(outs, "frames", rep->frames_jsonl);
    cJSON_AddStringToObject(outs, "summary", rep->summary_json);
    cJSON_AddStringToObject(outs, "plots", rep->plots_dir);
    cJSON_AddNumberToObject(outs, "nplots", rep->nplots);
    cJSON_AddStringToObject(outs, "heatmap", rep->heatmap_png);
    cJSON_AddStringToObject(outs, "vertex_error", rep->vertex_error_npy);
    cli_json_print(head);
}

int cmd_eval(int argc, char **argv) {
    cr_eval_files_def d = cr_eval_files_default_def();
    eval_opts o = {.material = "cotton"};
    int rc = parse(argc, argv, &d, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    if (cr_material_preset(o.material, &d.eval.material, &err) != CR_OK)
        return cli_usage("eval", "%s", err.msg);
    if (o.material_json && cr_material_load_json(o.material_json, &d.eval.material, &err) != CR_OK)
        return cli_fail(&err);
    cr_eval_files_result r;
    if (cr_eval_files_run(&d, &r, &err) != CR_OK) return cli_fail(&err);
    fputs(r.table_text, stderr);
    if (r.admission.defined && !r.admission.admitted)
        cr_log(CR_LOG_WARN, "eval: not admitted for plasticity: %s", r.admission.reason);
    const cr_eval_result *res = &r.first;
    char *text = cr_eval_summary_json(res);
    if (!text) {
        cr_eval_files_result_free(&r);
        CR_FAIL(&err, CR_ERR_MEMORY, "out of memory");
        return cli_fail(&err);
    }
    fprintf(stderr,
            "eval: %d frames, %d vertices: MED %.4g m (worst frame %d), BED %.4g rad, SSIM %.4g\n",
            res->nframes, res->nv, res->summary[CR_EVAL_MED].mean, res->worst_frame,
            res->summary[CR_EVAL_BED].mean, res->summary[CR_EVAL_SSIM].mean);
    if (o.json) print_json(&d, &r, text);
    free(text);
    cr_eval_files_result_free(&r);
    return CLI_OK;
}
