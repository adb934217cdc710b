/* cmd_swingar_sdf.c: `crease swingar-sdf train|measure`: SwinGar's neural
 * body SDF (paper 002, sec. III-D): train it on posed mannequins, or measure
 * it against the exact BVH distance on held-out frames (SDF error near the
 * body, collision removal on a skinned garment, time per frame). */
#include "cli.h"
#include "crease/garment.h"
#include "methods/swingar/sdf.h"

#include <string.h>

void help_swingar_sdf(void) {
    printf("usage: crease swingar-sdf train -o SDF.safetensors [options]\n"
           "       crease swingar-sdf measure --model SDF.safetensors [options]\n\n"
           "SwinGar's body SDF network (eight 512-wide Softplus layers, position and body\n"
           "branches, eq. 8-9 loss with mu_e 0.15), trained on posed mannequins against the\n"
           "BVH's exact signed distance; `measure` compares it with the exact distance on\n"
           "frames between the training ones, and runs eq. 10 collision removal with both on a\n"
           "garment skinned to each frame. S < 0 inside the body (see docs/swingar_sdf.md).\n\n"
           "`crease swingar-sdf train --help` lists the training options.\n\n"
           "measure options:\n"
           "  --model FILE         a trained model (required)\n"
           "  --motions LIST       test motions (default walk)\n"
           "  --shape NAME         mannequin preset (default normal)\n"
           "  --first F            first frame (default 3, between training's every 6th)\n"
           "  --stride K           frame step (default 6); --max-frames N per motion (15)\n"
           "  --garment TYPE       skinned garment type (default tshirt)\n"
           "  --garment-vertices N garment size (default 10000)\n"
           "  --lag N              garment skinned N frames behind the body (default 4)\n"
           "  --garment-pc2 FILE --garment-mesh OBJ --body-pc2 FILE --body-mesh OBJ\n"
           "                       a recorded sequence (a prediction) instead, posed by the\n"
           "                       one motion in --motions on --shape; --first 0 --stride 1\n"
           "                       for every frame\n"
           "  --margin M           m, added to every eq. 10 move (default 0)\n"
           "  --passes N           eq. 10 applied N times, S afresh each time (default 1)\n"
           "  --offset M           m, eq. 10 on S - M: within M of the body counts as inside\n"
           "  --frames N, --resolution N   as in training (90, 110)\n\n"
           "both: --quiet, --json (a summary on stdout)\n");
}

static const cli_doc train_doc = {
    .usage = "crease swingar-sdf train -o SDF.safetensors [options]",
    .about = "Train SwinGar's body SDF network (eight 512-wide Softplus layers, position and\n"
             "body branches, eq. 8-9 loss with mu_e 0.15) on posed mannequins against the BVH's\n"
             "exact signed distance (docs/swingar_sdf.md). S < 0 inside the body.\n"};

static int train(int argc, char **argv) {
    cr_swingar_sdf_train_def d = cr_swingar_sdf_train_default_def();
    int json = 0, steps = (int)d.steps, stop = 0, seed = 1, every = 200, npos = 0, nkeys = 0;
    const cr_config_key *keys = cr_swingar_sdf_train_def_keys(&nkeys);
    const cli_opt opts[] = {
        {CLI_ROW_OUTPUT(&d.checkpoint), .arg = "FILE",
         .help = "model and resumable checkpoint (safetensors)"},
        {CLI_ROW_STR("--motions", &d.motions), .arg = "LIST",
         .help = "clips or motion files, comma-separated"},
        {CLI_ROW_STR("--shapes", &d.shapes), .arg = "LIST",
         .help = "mannequin presets, comma-separated"},
        CLI_KEYS(keys, nkeys, &d),
        {CLI_ROW_INT("--steps", &steps, 1, 100000000), .arg = "N",
         .help = "Adam steps, cosine schedule length"},
        {CLI_ROW_INT("--stop-at", &stop, 0, 100000000), .arg = "N",
         .help = "stop after N steps (resume later; default: run all)"},
        {CLI_ROW_INT("--checkpoint-every", &every, 0, 100000000), .arg = "N",
         .help = "steps between checkpoints"},
        {CLI_ROW_INT("--seed", &seed, 0, 2147483647), .arg = "S",
         .help = "initialisation, samples and batches"},
        {CLI_ROW_FLAG("--json", &json), .help = "a summary on stdout"},
        CLI_END,
    };
    int rc =
        cli_parse_documented("swingar-sdf train", &train_doc, argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!d.checkpoint) return cli_usage("swingar-sdf train", "missing -o FILE");
    d.steps = steps;
    d.stop_at = stop;
    d.checkpoint_every = every;
    d.seed = d.model.seed = (uint64_t)seed;
    if (d.lr < d.lr_final) d.lr_final = d.lr;
    cr_error err = {0};
    cr_swingar_sdf *net = NULL;
    cr_swingar_sdf_train_result r;
    if (cr_swingar_sdf_train(&d, &net, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr,
            "swingar-sdf train: %lld poses, %lld samples, steps %lld (from %lld), %.1f s; loss "
            "%.5f (value %.2f mm, normal %.4f, eikonal %.5f) -> %s\n",
            (long long)r.poses, (long long)r.samples, (long long)r.steps, (long long)r.resumed_from,
            r.seconds, (double)r.loss, 1e3 * r.value, (double)r.normal, (double)r.eikonal,
            d.checkpoint);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "swingar-sdf train");
        cJSON_AddNumberToObject(j, "width", d.model.width);
        cJSON_AddNumberToObject(j, "articulated", d.model.articulated);
        cJSON_AddNumberToObject(j, "poses", (double)r.poses);
        cJSON_AddNumberToObject(j, "samples", (double)r.samples);
        cJSON_AddNumberToObject(j, "steps", (double)r.steps);
        cJSON_AddNumberToObject(j, "resumed_from", (double)r.resumed_from);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON_AddNumberToObject(j, "loss", r.loss);
        cJSON_AddNumberToObject(j, "value_m", r.value);
        cJSON_AddNumberToObject(j, "normal", r.normal);
        cJSON_AddNumberToObject(j, "eikonal", r.eikonal);
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cJSON_AddStringToObject(j, "output", d.checkpoint);
        cli_json_print(j);
    }
    cr_swingar_sdf_destroy(net);
    return CLI_OK;
}

static int measure(int argc, char **argv) {
    cr_swingar_sdf_measure_def d = cr_swingar_sdf_measure_default_def();
    const char *model = NULL, *garment = "tshirt";
    int json = 0, quiet = 0, npos = 0;
    const cli_opt opts[] = {
        CLI_STR("--model", &model),
        CLI_STR("--motions", &d.motions),
        CLI_STR("--shape", &d.shape),
        CLI_INT("--first", &d.first_frame, 0, 100000),
        CLI_INT("--stride", &d.frame_stride, 1, 100000),
        CLI_INT("--max-frames", &d.max_frames, 1, 100000),
        CLI_STR("--garment", &garment),
        CLI_INT("--garment-vertices", &d.garment_vertices, 500, 100000),
        CLI_INT("--lag", &d.garment_lag, 0, 100000),
        CLI_STR("--garment-pc2", &d.garment_pc2),
        CLI_STR("--garment-mesh", &d.garment_mesh),
        CLI_STR("--body-pc2", &d.body_pc2),
        CLI_STR("--body-mesh", &d.body_mesh),
        CLI_FLOAT("--margin", &d.collide.margin, 0, 1),
        CLI_INT("--passes", &d.collide.passes, 1, 16),
        CLI_FLOAT("--offset", &d.collide.offset, 0, 1),
        CLI_INT("--frames", &d.clip_frames, 1, 100000),
        CLI_INT("--resolution", &d.body_resolution, 32, 512),
        CLI_FLAG("--quiet", &quiet),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int rc = cli_parse("swingar-sdf measure", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!model) return cli_usage("swingar-sdf measure", "missing --model FILE");
    cr_error err = {0};
    cr_garment_type gt;
    if (cr_garment_type_parse(garment, &gt, &err) != CR_OK)
        return cli_usage("swingar-sdf measure", "%s", err.msg);
    d.garment = (int)gt;
    cr_swingar_sdf *net = NULL;
    if (cr_swingar_sdf_load(model, &net, &err) != CR_OK) return cli_fail(&err);
    cr_swingar_sdf_measure_result r;
    cr_status st = cr_swingar_sdf_measure(&d, net, &r, &err);
    cr_swingar_sdf_destroy(net);
    if (st != CR_OK) return cli_fail(&err);
    if (!quiet)
        fprintf(stderr,
                "swingar-sdf measure: %lld frames, body %lld vertices, %s %lld vertices, %d "
                "threads\n"
                "  SDF error within %.0f mm of the body: mean %.2f mm, p99 %.2f mm, max %.2f mm, "
                "sign agrees %.2f %% (%lld points)\n"
                "  at garment vertices within the band: mean %.2f mm, max %.2f mm\n"
                "  garment vertices inside: %.3f %% before, %.3f %% after neural removal, "
                "%.3f %% after exact removal\n"
                "  neural detection: %.1f %% of the inside vertices missed, %.1f false alarms "
                "per frame\n"
                "  per frame (median): neural removal %.2f ms (S at every vertex %.2f ms), exact "
                "removal %.2f ms (distances %.2f ms) + BVH refit %.2f ms\n"
                "  moved: neural %.2f %% of the vertices by %.2f mm on average, exact %.2f %% by "
                "%.2f mm\n",
                (long long)r.frames, (long long)r.body_vertices,
                d.garment_pc2 ? d.garment_pc2 : garment, (long long)r.garment_vertices,
                cr_thread_count(), 1e3 * d.band_m, r.err_mean_mm, r.err_p99_mm, r.err_max_mm,
                100 * r.sign_agree, (long long)r.band_points, r.garment_err_mean_mm,
                r.garment_err_max_mm, r.ratio_before, r.ratio_neural, r.ratio_exact, 100 * r.missed,
                r.false_alarms, r.ms_neural, r.ms_neural_detect, r.ms_exact, r.ms_exact_detect,
                r.ms_bvh_refit, r.moved_neural, r.mean_move_neural_mm, r.moved_exact,
                r.mean_move_exact_mm);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "swingar-sdf measure");
        cJSON_AddNumberToObject(j, "frames", (double)r.frames);
        cJSON_AddNumberToObject(j, "garment_vertices", (double)r.garment_vertices);
        cJSON_AddNumberToObject(j, "err_mean_mm", r.err_mean_mm);
        cJSON_AddNumberToObject(j, "err_p99_mm", r.err_p99_mm);
        cJSON_AddNumberToObject(j, "err_max_mm", r.err_max_mm);
        cJSON_AddNumberToObject(j, "sign_agree", r.sign_agree);
        cJSON_AddNumberToObject(j, "garment_err_mean_mm", r.garment_err_mean_mm);
        cJSON_AddNumberToObject(j, "garment_err_max_mm", r.garment_err_max_mm);
        cJSON_AddNumberToObject(j, "ratio_before_pct", r.ratio_before);
        cJSON_AddNumberToObject(j, "ratio_neural_pct", r.ratio_neural);
        cJSON_AddNumberToObject(j, "ratio_exact_pct", r.ratio_exact);
        cJSON_AddNumberToObject(j, "missed", r.missed);
        cJSON_AddNumberToObject(j, "false_alarms_per_frame", r.false_alarms);
        cJSON_AddNumberToObject(j, "ms_neural", r.ms_neural);
        cJSON_AddNumberToObject(j, "ms_neural_detect", r.ms_neural_detect);
        cJSON_AddNumberToObject(j, "ms_exact", r.ms_exact);
        cJSON_AddNumberToObject(j, "ms_exact_detect", r.ms_exact_detect);
        cJSON_AddNumberToObject(j, "ms_bvh_refit", r.ms_bvh_refit);
        cJSON_AddNumberToObject(j, "mean_move_neural_mm", r.mean_move_neural_mm);
        cJSON_AddNumberToObject(j, "mean_move_exact_mm", r.mean_move_exact_mm);
        cJSON_AddNumberToObject(j, "moved_neural_pct", r.moved_neural);
        cJSON_AddNumberToObject(j, "moved_exact_pct", r.moved_exact);
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cli_json_print(j);
    }
    return CLI_OK;
}

int cmd_swingar_sdf(int argc, char **argv) {
    const char *sub = argc > 1 ? argv[1] : "";
    if (strcmp(sub, "train") == 0) return train(argc - 1, argv + 1);
    if (strcmp(sub, "measure") == 0) return measure(argc - 1, argv + 1);
    return cli_usage("swingar-sdf", "expected 'train' or 'measure', got '%s'", sub);
}
