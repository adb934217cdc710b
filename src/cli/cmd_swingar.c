/* cmd_swingar.c: `crease swingar train|run`: train SwinGar's estimator on a
 * dataset written by `crease dataset`, and animate any garment OBJ
 * on a motion with a trained model (PC2 + glb + PNG). */
#include "cli.h"

#include "crease/body.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/render.h"
#include "crease/swingar.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void help_swingar(void) {
    printf("usage: crease swingar train --dataset DIR [--epochs N] -o MODEL [options]\n"
           "       crease swingar run --model MODEL --garment G.obj --motion M -o OUT [options]\n"
           "       crease swingar measure --models M1,M2,... --dataset TEST -o OUT [options]\n\n"
           "SwinGar (paper 002): one network that animates loose garments it has never seen,\n"
           "from a spectral descriptor of the garment and the body's motion "
           "(docs/swingar_model.md).\n\n"
           "`crease swingar train --help` and `crease swingar measure --help` list their\n"
           "options.\n\n"
           "run:\n"
           "  --model MODEL          a model written by `swingar train`\n"
           "  --garment G.obj        any garment mesh (UVs not needed), fitted to the body first\n"
           "  --motion M             a clip name (crease motion --list), a .bvh / .npz file or\n"
           "                         a rigged CHAR.glb[:MAP] (its own animation)\n"
           "  --body B               slim, normal (default), heavy, an SMPL-family model\n"
           "                         FILE.npz[:beta,beta,...], or a rigged CHAR.glb[:MAP]\n"
           "  --frames N             frames of a clip (default 120)\n"
           "  --fps F                frames per second (default 30)\n"

           "  --scale S, --start-frame N, --end-frame N, --ease-in S, --ground MODE   a motion\n"
           "                         file's preparation, as in crease motion (ease-in 1 s)\n"
           "  --raw                  the network's output as it is: no collision removal (by\n"
           "                         default every vertex inside the posed body is moved out\n"
           "                         by eq. 10 on its exact distance, 1 mm beyond)\n"
           "  --skinned              write the garment skinned by its own weights instead (the\n"
           "                         baseline the model improves on)\n"
           "  -o OUT                 OUT/garment.pc2, OUT/garment.glb, OUT/body.pc2,\n"
           "                         OUT/garment.obj (the fitted rest garment), OUT/last.png\n\n"
           "  --json                 end with a JSON summary on stdout\n");
}

static const char *const sizes[] = {"paper", "cpu", "tiny", NULL};
static const char *const affinities[] = {"geodesic", "euclidean", NULL};

static const cli_doc train_doc = {
    .usage = "crease swingar train --dataset DIR [--epochs N] -o MODEL [options]",
    .about = "Train SwinGar (paper 002; docs/swingar_model.md): one network that animates loose\n"
             "garments it has never seen, from a spectral descriptor of the garment and the\n"
             "body's motion.\n"};

static int cmd_train(int argc, char **argv) {
    static cli_list held[3];
    for (int i = 0; i < 3; i++)
        held[i].n = 0;
    cr_swingar_train_def t = cr_swingar_train_default_def();
    const char *dataset = NULL, *out = NULL, *resume = NULL, *size = "paper";
    const char *affinity = "geodesic";
    int json = 0, no_desc = 0, npos = 0, arena_mb = 1024, desc_z = 0, nkeys = 0;
    const cr_config_key *keys = cr_swingar_train_def_keys(&nkeys);
    const cli_opt opts[] = {
        {CLI_ROW_STR("--dataset", &dataset), .arg = "DIR",
         .help = "a dataset written by `crease dataset`"},
        {CLI_ROW_OUTPUT(&out), .arg = "MODEL",
         .help = "the model, a resumable checkpoint written every epoch"},
        {CLI_ROW_STR("--resume", &resume), .arg = "MODEL",
         .help = "continue a checkpoint (its widths and descriptor are used)"},
        CLI_KEYS(keys, nkeys, &t),
        {CLI_ROW_CHOICE("--size", &size, sizes), .arg = "S",
         .help = "paper (the paper's widths and heads), cpu (heads 4 / 4 / 3 / 8 for a 2-core "
                 "machine) or tiny (for tests)"},
        {CLI_ROW_CUSTOM("--test-garments", cli_parse_list, &held[0], 1), .arg = "A,B",
         .help = "held out: garment types, motions and bodies; a sequence is test when all its "
                 "given axes are held out, train when none is, unused otherwise"},
        {CLI_ROW_CUSTOM("--test-motions", cli_parse_list, &held[1], 1), .arg = "A,B",
         .help = "held-out motions"},
        {CLI_ROW_CUSTOM("--test-bodies", cli_parse_list, &held[2], 1), .arg = "A,B",
         .help = "held-out bodies"},
        {CLI_ROW_FLAG("--no-descriptor", &no_desc),
         .help = "E_a sees zeros (the ablation without the global descriptor)"},
        {CLI_ROW_CHOICE("--affinity", &affinity, affinities), .arg = "A",
         .help = "geodesic (the paper's) or euclidean (ablation)"},
        {CLI_ROW_INT("--descriptor-z", &desc_z, 2, 4096), .arg = "Z",
         .help = "furthest-point samples of the descriptor, and so its length (default: the "
                 "size's, paper and cpu 256, tiny 16; the paper compares 128, 256 and 512)"},
        {CLI_ROW_INT("--arena-mb", &arena_mb, 16, 1 << 20), .arg = "N",
         .help = "per-step memory, MiB"},
        {CLI_ROW_FLAG("--json", &json), .help = "end with a JSON summary on stdout"},
        CLI_END,
    };
    int rc = cli_parse_documented("swingar train", &train_doc, argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!dataset) return cli_usage("swingar train", "missing --dataset DIR");
    if (!out) return cli_usage("swingar train", "missing -o MODEL");
    cr_error serr = {0};
    if (cr_swingar_size_def(size, &t.model, &serr) != CR_OK) return cli_fail(&serr);
    t.model.use_descriptor = !no_desc;
    if (desc_z) t.model.descriptor_len = desc_z;
    t.arena_bytes = (size_t)arena_mb << 20;
    t.checkpoint = out;
    t.resume = resume;
    t.model.affinity = strcmp(affinity, "euclidean") == 0;
    cr_error err = {0};
    /* a resumed run keeps the checkpoint's widths and descriptor */
    if (resume && cr_swingar_read_def(resume, &t.model, &err) != CR_OK) return cli_fail(&err);
    cr_swingar_data data;
    cr_status st = cr_swingar_data_load(dataset, t.model.descriptor_len, t.model.use_descriptor,
                                        t.model.affinity, &data, &err);
    if (st != CR_OK) return cli_fail(&err);
    int8_t *is_test = malloc((size_t)data.nsequences);
    if (!is_test) {
        cr_swingar_data_free(&data);
        return cli_fail(&(cr_error){.msg = "out of memory"});
    }
    cr_swingar_split(&data, held[0].items, held[0].n, held[1].items, held[1].n, held[2].items,
                     held[2].n, is_test);
    int ntrain = 0, ntest = 0;
    for (int i = 0; i < data.nsequences; i++)
        ntrain += is_test[i] == 0, ntest += is_test[i] == 1;
    t.is_test = is_test;
    cr_swingar *m = NULL;
    cr_swingar_train_result r;
    st = cr_swingar_train(&t, &data, &m, &r, &err);
    if (st == CR_OK && !t.quiet)
        fprintf(stderr,
                "swingar: %d train / %d test sequences, %lld parameters, %d epochs in %.1f s; "
                "vertex error %.2f -> %.2f cm%s\n",
                ntrain, ntest, (long long)r.params, r.epochs_done, r.seconds, 100 * r.first_vert_m,
                100 * r.last_vert_m, t.model.use_descriptor ? "" : " (no descriptor)");
    if (st == CR_OK && json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "swingar train");
        cJSON_AddStringToObject(j, "model", out);
        cJSON_AddNumberToObject(j, "train_sequences", ntrain);
        cJSON_AddNumberToObject(j, "test_sequences", ntest);
        cJSON_AddNumberToObject(j, "params", (double)r.params);
        cJSON_AddNumberToObject(j, "epochs", r.epochs_done);
        cJSON_AddNumberToObject(j, "switched_epoch", r.switched_epoch);
        cJSON_AddNumberToObject(j, "first_loss", r.first_loss);
        cJSON_AddNumberToObject(j, "last_loss", r.last_loss);
        cJSON_AddNumberToObject(j, "first_vert_m", r.first_vert_m);
        cJSON_AddNumberToObject(j, "last_vert_m", r.last_vert_m);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON_AddBoolToObject(j, "descriptor", t.model.use_descriptor);
        cJSON_AddNumberToObject(j, "descriptor_z", t.model.descriptor_len);
        cJSON_AddStringToObject(j, "affinity", t.model.affinity ? "euclidean" : "geodesic");
        if (r.test_vert_m >= 0) cJSON_AddNumberToObject(j, "test_vert_m", r.test_vert_m);
        cli_json_print(j);
    }
    cr_swingar_destroy(m);
    free(is_test);
    cr_swingar_data_free(&data);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}

typedef struct run_opts {
    int frames, json;
    float fps;
    cli_motion_file mf;
} run_opts;

static int cmd_run(int argc, char **argv) {
    cr_swingar_run_def d = cr_swingar_run_default_def();
    run_opts o = {.frames = 120, .fps = 30.0f, .mf = cli_motion_file_default(1.0f)};
    int npos = 0;
    const cli_opt opts[] = {
        CLI_STR("--model", &d.model),
        CLI_STR("--garment", &d.garment),
        CLI_STR("--motion", &d.motion),
        CLI_STR("--body", &d.body),
        CLI_INT("--frames", &o.frames, 1, 1000000),
        CLI_FLOAT("--fps", &o.fps, 1e-3, 1000),
        CLI_FLAG("--skinned", &d.skinned),
        CLI_FLAG("--raw", &d.raw),
        CLI_MOTION_FILE_OPTS(&o.mf),
        CLI_OUTPUT(&d.out_dir),
        CLI_FLAG("--json", &o.json),
        CLI_END,
    };
    int rc = cli_parse("swingar run", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!d.model && !d.skinned) return cli_usage("swingar run", "missing --model MODEL");
    if (!d.garment) return cli_usage("swingar run", "missing --garment G.obj");
    if (!d.motion) return cli_usage("swingar run", "missing --motion M");
    if (!d.out_dir) return cli_usage("swingar run", "missing -o OUT");
    o.mf.fps = o.fps;
    d.motion_def = cli_motion_resolve_def(&o.mf, NULL);
    d.motion_def.clip_frames = o.frames;
    cr_error err = {0};
    cr_swingar_run_report r;
    if (cr_swingar_run(&d, &r, &err) != CR_OK) return cli_fail(&err);
    const cr_swingar_removal_stats *rs = &r.removal;
    if (r.removed)
        fprintf(stderr,
                "swingar run: collision removal (exact): at most %.3f %% of the garment "
                "inside the body on a frame before, %.3f %% after (%.2f s)\n",
                100 * rs->inside_before, 100 * rs->inside_after, rs->seconds);
    if (o.json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "swingar run");
        cJSON_AddStringToObject(j, "out", d.out_dir);
        cJSON_AddStringToObject(j, "mode", d.skinned ? "skinned" : "model");
        cJSON_AddNumberToObject(j, "vertices", r.vertices);
        cJSON_AddNumberToObject(j, "frames", r.frames);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON_AddNumberToObject(j, "fps", r.seconds > 0 ? r.frames / r.seconds : 0);
        if (r.removed) {
            cJSON_AddNumberToObject(j, "inside_before", rs->inside_before);
            cJSON_AddNumberToObject(j, "inside_after", rs->inside_after);
        }
        cli_json_print(j);
    }
    return CLI_OK;
}

static const cli_doc measure_doc = {
    .usage = "crease swingar measure --models M1,M2,... --dataset TEST -o OUT [options]",
    .about = "SwinGar's table on a test dataset (docs/swingar.md): each model (a seed of one\n"
             "recipe) on every sequence against the simulated reference, by crease eval's\n"
             "metrics, beside the garment skinned by its own weights (the share of its error\n"
             "removed) and a twin dataset (the floor); mean and spread over the seeds.\n",
    .after = "OUT gets table_<sequence>.json (every metric, as crease eval's table.json) and\n"
             "summary.json; the tables go to stdout.\n"};

static int cmd_measure(int argc, char **argv) {
    cr_swingar_measure_def d = cr_swingar_measure_default_def();
    static cli_list models, held[3];
    int json = 0;
    const cli_opt opts[] = {
        {CLI_ROW_CUSTOM("--models", cli_parse_list, &models, 1), .arg = "M1,M2,...",
         .help = "model files, seeds of one recipe (at most 8)"},
        {CLI_ROW_STR("--dataset", &d.dataset), .arg = "DIR", .help = "the test dataset"},
        {CLI_ROW_STR("--twin", &d.twin), .arg = "DIR",
         .help = "its twin (`crease dataset --twin`, the same def): the floor"},
        {CLI_ROW_CUSTOM("--test-garments", cli_parse_list, &held[0], 1), .arg = "A,B",
         .help = "measure only the sequences held out on the given axes, as in train (default: "
                 "every sequence)"},
        {CLI_ROW_CUSTOM("--test-motions", cli_parse_list, &held[1], 1), .arg = "A,B",
         .help = "held-out motions"},
        {CLI_ROW_CUSTOM("--test-bodies", cli_parse_list, &held[2], 1), .arg = "A,B",
         .help = "held-out bodies"},
        {CLI_ROW_FLAG("--raw", &d.raw),
         .help = "the network's output as it is (by default collisions are removed, as `swingar "
                 "run` does)"},
        {CLI_ROW_OUTPUT(&d.out_dir), .arg = "OUT", .help = "tables"},
        {CLI_ROW_FLAG("--json", &json), .help = "end with the summary on stdout"},
        CLI_END,
    };
    int rc = cli_parse_documented("swingar measure", &measure_doc, argc, argv, opts, NULL, 0, NULL);
    if (rc != CLI_OK) return rc;
    if (models.n < 1 || !d.dataset || !d.out_dir)
        return cli_usage("swingar measure", "needs --models, --dataset and -o");
    d.models = models.items, d.nmodels = models.n, d.print = stdout;
    d.garments = held[0].items, d.ngarments = held[0].n, d.motions = held[1].items;
    d.nmotions = held[1].n, d.bodies = held[2].items, d.nbodies = held[2].n;
    cr_error err = {0};
    cr_swingar_measure_report r;
    if (cr_swingar_measure(&d, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr,
            "swingar measure: E_dist %.3f cm (spread %.3f) on %d sequences, skinned %.3f: "
            "%.1f %% of its error removed\n  %s/summary.json\n",
            r.model_cm, r.model_cm_spread, r.sequences, r.skinned_cm, 100 * r.removed, d.out_dir);
    if (json) {
        char path[1100], *text = NULL;
        snprintf(path, sizeof path, "%s/summary.json", d.out_dir);
        if (cr_file_read_all(path, &text, NULL, &err) != CR_OK) return cli_fail(&err);
        printf("%s", text), free(text);
    }
    return CLI_OK;
}

int cmd_swingar(int argc, char **argv) {
    if (argc < 2) return cli_usage("swingar", "expected 'train', 'run' or 'measure'");
    if (strcmp(argv[1], "train") == 0) return cmd_train(argc - 1, argv + 1);
    if (strcmp(argv[1], "run") == 0) return cmd_run(argc - 1, argv + 1);
    if (strcmp(argv[1], "measure") == 0) return cmd_measure(argc - 1, argv + 1);
    return cli_usage("swingar", "unknown subcommand '%s' (train, run or measure)", argv[1]);
}
