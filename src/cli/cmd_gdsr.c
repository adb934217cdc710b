/* cmd_gdsr.c: `crease gdsr train|run`: garment dynamic super-resolution
 * (paper 001, docs/gdsr.md): train on low/high pairs of a `crease dataset`
 * folder, or roll a trained model out on a clip and measure it, with
 * barycentric upsampling and GDSR(-d) in the same table. */
#include "cli.h"
#include "crease/eval.h"
#include "crease/gdsr.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void help_gdsr(void) {
    printf("usage: crease gdsr train --dataset DIR [--motions M1,M2] -o OUT [options]\n"
           "       crease gdsr run --model OUT/model.safetensors --dataset DIR --motion M -o DIR\n"
           "       crease gdsr run --model F --simulate --motion CLIP|FILE [--body B]\n"
           "                       [--garment G] [--dataset DIR] [--frames N] -o DIR\n\n"
           "Garment dynamic super-resolution (docs/gdsr.md): a low-resolution simulation and\n"
           "the body in, a high-resolution garment with wrinkles out, frame after frame.\n\n"
           "`crease gdsr train --help` and `crease gdsr run --help` list their options.\n");
}

static const cli_doc run_doc = {
    .usage = "crease gdsr run --model F (--dataset DIR | --simulate) --motion M -o DIR [options]",
    .about = "Roll a trained gdsr model out on a clip's low-resolution sequence (of a dataset, or\n"
             "simulated from a motion with --simulate into DIR/sim by `crease dataset`'s\n"
             "machinery) and measure it against the high reference when there is one, beside\n"
             "barycentric upsampling, a GDSR(-d) baseline and the twin (docs/gdsr.md).\n",
    .after =
        "A motion file's preparation: --scale S, --start-frame N, --end-frame N, --ease-in S,\n"
        "--ground G, as in `crease dataset` (docs/motions.md). DIR gets gdsr.pc2,\n"
        "gdsr_raw.pc2, upsampled.pc2, reference.pc2, high.obj, gdsr.glb (morph-target\n"
        "animation), compare.png (low input, gdsr, upsampling, reference side by side),\n"
        "compare_normals.png (their UV normal maps), summary.json, strain.csv and\n"
        "strain.png (E_u, E_v, E_uv over the frames). A motion without a high sequence in\n"
        "the dataset is rolled out without a reference (no metrics table; the strain over\n"
        "frames and collisions are still measured).\n"};

static int split(char *s, const char **out, int cap) {
    int n = 0;
    for (char *t = strtok(s, ","); t && n < cap; t = strtok(NULL, ","))
        out[n++] = t;
    return n;
}

static const cli_doc train_doc = {
    .usage = "crease gdsr train --dataset DIR [--motions M1,M2] -o OUT [options]",
    .about = "Train gdsr (docs/gdsr.md) on the low/high pairs of a `crease dataset` folder: each\n"
             "clip rolled out in frame order on the model's own corrections, AdamW, resumable.\n",
    .after = "OUT gets model.safetensors, checkpoint.safetensors and log.jsonl (a line an epoch:\n"
             "the loss and its terms, and with --val-motions val_med_m, val_upsampled_med_m).\n"};

static int cmd_train(int argc, char **argv) {
    const char *dataset = NULL, *garment = "tshirt", *body = "normal", *motions = NULL;
    const char *val = NULL, *layer_edges = "auto";
    static const char *const layer_choices[] = {"auto", "on", "off", NULL};
    int quiet = 0, json = 0, nodec = 0, paper = 0, ntrain_keys = 0;
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    /* --paper-sizes sets the sizes that --latent, --steps and --wire-width then change,
     * wherever it stands */
    for (int i = 1; i < argc && strcmp(argv[i], "--") != 0; i++)
        if (strcmp(argv[i], "--paper-sizes") == 0) def.model = cr_gdsr_model_paper_def();
    const cr_config_key *train_keys = cr_gdsr_train_def_keys(&ntrain_keys);
    const cli_opt opts[] = {
        {CLI_ROW_STR("--dataset", &dataset), .arg = "DIR",
         .help = "a `crease dataset` folder made with --res low,high"},
        {CLI_ROW_STR("--garment", &garment), .arg = "G",
         .help = "garment type; G1,G2,... trains one model on several garments of the dataset "
                 "(up to 8)"},
        {CLI_ROW_STR("--body", &body), .arg = "B", .help = "body preset"},
        {CLI_ROW_STR("--motions", &motions), .arg = "LIST",
         .help = "training clips (default: every motion of the dataset with a finished low and "
                 "high sequence of the garment, but --val-motions)"},
        {CLI_ROW_STR("--val-motions", &val), .arg = "LIST",
         .help = "held-out clips rolled out each epoch: log.jsonl's val_med_m against "
                 "val_upsampled_med_m"},
        CLI_KEYS(train_keys, ntrain_keys, &def),
        {CLI_ROW_FLAG("--paper-sizes", &paper),
         .help = "the paper's sizes: latent 128, 6 steps, 128/512 features (default 64, 4, "
                 "32/32)"},
        {CLI_ROW_FLAG("--no-decoder", &nodec), .help = "GDSR(-d): no decoder E, C^ = C"},
        {CLI_ROW_CHOICE("--layer-edges", &layer_edges, layer_choices), .arg = "auto|on|off",
         .help = "edges between low vertices of different garment layers (connected "
                 "components) closer than --sigma-l, a third edge set of H (auto: on when the "
                 "garment has two layers)"},
        {CLI_ROW_OUTPUT(&def.out_dir), .arg = "OUT", .help = "the model folder"},
        {CLI_ROW_FLAG("--quiet", &quiet), .help = "no progress"},
        {CLI_ROW_FLAG("--json", &json), .help = "end with a JSON summary on stdout"},
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse_documented("gdsr train", &train_doc, argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!dataset) return cli_usage("gdsr train", "missing --dataset DIR");
    if (!def.out_dir) return cli_usage("gdsr train", "missing -o OUT");
    def.model.use_decoder = !nodec;
    def.model.layer_edges = !strcmp(layer_edges, "on") ? 1 : !strcmp(layer_edges, "off") ? 0 : -1;
    def.quiet = quiet;
    /* --garment A,B,...: one model for several garments (cr_gdsr_train_many) */
    char gbuf[1024];
    snprintf(gbuf, sizeof gbuf, "%s", garment);
    const char *gs[CR_GDSR_MAX_GARMENTS + 1];
    int ng = split(gbuf, gs, CR_GDSR_MAX_GARMENTS + 1);
    if (ng < 1 || ng > CR_GDSR_MAX_GARMENTS) {
        fprintf(stderr, "gdsr train: --garment: 1 to %d garments, comma-separated\n",
                CR_GDSR_MAX_GARMENTS);
        return CLI_USAGE;
    }
    cr_error err = {0};
    char buf[1024], vbuf[1024];
    const char *ms[CR_GDSR_MAX_CLIPS], *vs[CR_GDSR_MAX_CLIPS];
    cr_gdsr_train_dataset_def dd = {.dataset = dataset,
                                    .garments = gs,
                                    .ngarments = ng,
                                    .body = body,
                                    .motions = ms,
                                    .val_motions = vs};
    if (val) {
        snprintf(vbuf, sizeof vbuf, "%s", val);
        dd.nval = split(vbuf, vs, CR_GDSR_MAX_CLIPS);
    }
    if (motions) {
        snprintf(buf, sizeof buf, "%s", motions);
        dd.nmotions = split(buf, ms, CR_GDSR_MAX_CLIPS);
    }
    cr_gdsr_train_dataset_result tr;
    if (cr_gdsr_train_dataset(&def, &dd, &tr, &err) != CR_OK) return cli_fail(&err);
    if (!motions) {
        fprintf(stderr, "gdsr train: the dataset's motions:");
        for (int k = 0; k < tr.nmotions; k++)
            fprintf(stderr, " %s", tr.motions[k]);
        fprintf(stderr, "\n");
    }
    const cr_gdsr_train_result r = tr.train;
    fprintf(stderr,
            "gdsr train: %lld parameters, %d garment%s (%d -> %d vertices%s), epochs %d..%d, "
            "loss %.4g -> %.4g (coarse %.3g m, fine %.3g m, normal %.3g, stretch %.3g, shear "
            "%.3g, bend %.3g, laplacian %.3g m), %.1f s\n  %s/model.safetensors\n",
            (long long)r.params, ng, ng > 1 ? "s" : "", tr.low_vertices[0], tr.high_vertices[0],
            ng > 1 ? " the first" : "", r.resumed_from, r.epochs, r.first_loss, r.last_loss,
            r.last_term[CR_GDSR_TERM_COARSE], r.last_term[CR_GDSR_TERM_FINE],
            r.last_term[CR_GDSR_TERM_NORMAL], r.last_term[CR_GDSR_TERM_STRETCH],
            r.last_term[CR_GDSR_TERM_SHEAR], r.last_term[CR_GDSR_TERM_BEND],
            r.last_term[CR_GDSR_TERM_LAPLACIAN], r.seconds, def.out_dir);
    if (dd.nval > 0)
        fprintf(stderr, "  held-out MED %.5f m, upsampling's %.5f m\n", r.last_val_med,
                r.val_upsampled_med);
    if (json) cli_json_print(cJSON_Parse(tr.summary_json));
    cr_gdsr_train_dataset_result_free(&tr);
    return CLI_OK;
}

static int cmd_run(int argc, char **argv) {
    cr_gdsr_run_def d = cr_gdsr_run_default_def();
    const char *layer_test = NULL;
    static const char *const layer_tests[] = {"vertex", "surface", NULL};
    int json = 0;
    cli_motion_file mf = cli_motion_file_default(1.0f);
    int nkeys = 0;
    const cr_config_key *keys = cr_gdsr_run_def_keys(&nkeys);
    const cli_opt opts[] = {
        {CLI_ROW_STR("--model", &d.model), .arg = "F",
         .help = "a model.safetensors from gdsr train"},
        {CLI_ROW_STR("--dataset", &d.dataset), .arg = "DIR",
         .help = "a `crease dataset` folder with --res low,high"},
        {CLI_ROW_STR("--motion", &d.motion), .arg = "M", .help = "the clip to super-resolve"},
        {CLI_ROW_STR("--garment", &d.garment), .arg = "G",
         .help = "garment type (with --simulate also a variant spec, as in `crease dataset`)"},
        {CLI_ROW_STR("--body", &d.body), .arg = "B", .help = "body preset"},
        {CLI_ROW_STR("--baseline-model", &d.baseline), .arg = "F",
         .help = "a GDSR(-d) model measured in the same table"},
        {CLI_ROW_STR("--twin", &d.twin), .arg = "DIR",
         .help = "a twin dataset (crease dataset --twin, the same def): its high clip measured "
                 "in the same table, the floor"},
        {CLI_ROW_CHOICE("--layer-test", &layer_test, layer_tests), .arg = "vertex|surface",
         .help = "Eq. 27 on an outfit: the nearest inner vertex and its normal (default, the "
                 "paper's) or the closest point on the inner layer's triangles, none past its "
                 "open edges"},
        CLI_KEYS(keys, nkeys, &d),
        CLI_MOTION_FILE_OPTS(&mf),
        {CLI_ROW_OUTPUT(&d.out_dir), .arg = "DIR", .help = "the outputs"},
        {CLI_ROW_FLAG("--json", &json), .help = "end with a JSON summary on stdout"},
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse_documented("gdsr run", &run_doc, argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!d.motion || !d.model || !d.out_dir || (!d.dataset && !d.simulate))
        return cli_usage("gdsr run", "needs --motion, --model, -o and --dataset or --simulate");
    if (d.twin && d.simulate)
        return cli_usage("gdsr run", "--twin measures a dataset's clip, not --simulate");
    if (!d.simulate && (d.reference || d.low_vertices || d.high_vertices))
        return cli_usage("gdsr run", "--reference, --low-vertices and --high-vertices need "
                                     "--simulate");
    d.surface = layer_test && !strcmp(layer_test, "surface");
    cr_motion_import_def imp;
    cr_motion_prepare_def pd;
    cli_motion_file_defs(&mf, &imp, &pd);
    d.motion_import = &imp, d.motion_prepare = &pd;
    cr_error err = {0};
    cr_gdsr_run_report r = {0};
    if (cr_gdsr_run(&d, &r, &err) != CR_OK) return cli_fail(&err);
    if (json) cli_json_print(cJSON_Parse(r.summary_json));
    cr_gdsr_run_report_free(&r);
    return CLI_OK;
}

int cmd_gdsr(int argc, char **argv) {
    if (argc < 2) return cli_usage("gdsr", "missing a subcommand: train or run");
    if (strcmp(argv[1], "train") == 0) return cmd_train(argc - 1, argv + 1);
    if (strcmp(argv[1], "run") == 0) return cmd_run(argc - 1, argv + 1);
    return cli_usage("gdsr", "unknown subcommand '%s' (train, run)", argv[1]);
}
