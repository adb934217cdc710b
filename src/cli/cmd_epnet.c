/* cmd_epnet.c: `crease epnet train|run`: the epnet method (paper 004),
 * self-supervised garment dynamics with a learnt plastic rest bending. */
#include "cli.h"
#include "crease/epnet.h"

#include <math.h>
#include <string.h>

void help_epnet(void) {
    printf(
        "usage: crease epnet train -o DIR [options]\n"
        "       crease epnet run --model DIR --motion M -o OUT [options]\n"
        "       crease epnet measure --models D,.. --baselines D,.. -o OUT [options]\n\n"
        "Train E-Net (pose + motion + rest bending -> garment) and P-Net (hinge-graph message\n"
        "passing -> rest bending) with physics energies only, alternating for --cycles cycles\n"
        "(paper 004, Algorithm 1; docs/epnet.md). Progress per epoch on stderr and in\n"
        "DIR/progress.jsonl; a checkpoint after every epoch.\n\n"
        "`crease epnet train --help` lists the training options.\n\n"
        "run:\n"
        "  --model DIR          a trained model\n"
        "  --motion M           clip name or motion file (.bvh, .npz, or a rigged\n"
        "                       CHAR.glb[:MAP]'s own animation)\n"
        "  --body B             another body: a preset, FILE.npz[:betas] or\n"
        "                       CHAR.glb[:MAP] (default the model's)\n"
        "  --frames N           frames of the motion (default its own)\n"
        "  --hold N             frames of its last pose after it (default 0)\n"
        "  --baseline           RB held at zero\n"
        "  --closed-loop        P-Net on the angles E-Net makes with RB (the earlier rounds')\n"
        "                       instead of the proxy inference (E-Net at RB = 0, P-Net over\n"
        "                       its angles through the ratchet, E-Net with that RB)\n"
        "  --drive R            proxy: RB moves only at hinges strained past R rad from RB in\n"
        "                       3 of the last 5 frames (default 0.05)\n"
        "  --min-delta R        proxy: P-Net increments under R rad are dropped (default 0.005)\n"
        "  --warmup N           frames from the rest pose to the first before it (default 0)\n"
        "  -o OUT               garment.pc2, garment.glb, garment.png, rb.png (RB colour map), "
        "rb.npy\n"
        "  --json               a summary on stdout\n"
        "measure (Table 1 against the plastic reference and its twin; docs/epnet.md):\n"
        "  --models D,D,...     epnet model folders, seeds of one recipe (at most 8)\n"
        "  --baselines D,D,...  zero-RB folders (`train --baseline`; the first is the tables')\n"
        "  --motions M,M,...    held-out motions (default bend,raise_arms,dodge)\n"
        "  --bodies B,B,...     bodies (default normal,slim,heavy)\n"
        "  --frames N           frames of each motion (default its own)\n"
        "  --hold N             frames of the last pose after each motion (default 30)\n"
        "  --friction F         the reference's friction against the body (default 0)\n"
        "  --twin-friction D    the twin's change of it (default 0.001)\n"
        "  --closed-loop, --warmup N  epnet's inference, as in run\n"
        "  -o OUT               table_{epnet,baseline}_<motion>_<body>.json,\n"
        "                       side_by_side_<motion>.png; the tables on stdout\n");
}

/* Split a comma list into buf (cap bytes): its items into out (at most max). */
static int split_list(const char *s, char *buf, size_t cap, const char **out, int max) {
    snprintf(buf, cap, "%s", s);
    int n = 0;
    for (char *tok = strtok(buf, ","); tok && n < max; tok = strtok(NULL, ","))
        out[n++] = tok;
    return n;
}

static const cli_doc train_doc = {
    .usage = "crease epnet train -o DIR [options]",
    .about = "Train E-Net (pose + motion + rest bending -> garment) and P-Net (hinge-graph\n"
             "message passing -> rest bending) with physics energies only, alternating for\n"
             "--cycles cycles (paper 004, Algorithm 1; docs/epnet.md). Progress per epoch on\n"
             "stderr and in DIR/progress.jsonl; a checkpoint after every epoch.\n"};

static int run_train(int argc, char **argv) {
    cr_epnet_def d = cr_epnet_default_def();
    const char *garment = "tshirt", *body = "normal", *motions = NULL, *out = NULL;
    const char *pval = d.pnet_val_motion;
    int paper = 0, json = 0, nkeys = 0;
    const cr_config_key *keys = cr_epnet_def_keys(&nkeys);
    float yield = (float)d.material.yield_angle, pin_top = -1, wz = (float)d.w_zero_rest,
          wr = (float)d.w_rest_response, pnoise = (float)d.pnet_rb_noise;
    const cli_opt opts[] = {
        {CLI_ROW_STR("--garment", &garment), .arg = "G",
         .help = "tshirt, dress, skirt, ... (garment.h types), or a garment mesh file (.obj, "
                 ".ply, .glb; UVs not needed) fitted to the body, --vertices unused"},
        {CLI_ROW_STR("--body", &body), .arg = "B",
         .help = "slim, normal, heavy, an SMPL-family model FILE.npz[:beta,beta,...], or a "
                 "rigged CHAR.glb[:MAP] (docs/body.md)"},
        {CLI_ROW_STR("--motions", &motions), .arg = "M,M,...",
         .help = "training clips or motion files, at most 16 (default walk,squat,twist,dance,"
                 "jump,reach,lean,stretch)"},
        {CLI_ROW_FLOAT("--yield", &yield, 0, 3.2), .arg = "Y", .help = "yield angle, rad"},
        CLI_KEYS(keys, nkeys, &d),
        {CLI_ROW_FLOAT("--zero-rest-weight", &wz, 0, 1e6), .arg = "W",
         .help = "the paired zero-rest consistency term: E-Net at RB = 0 stays near the "
                 "rest angles on the last frame (the authors'; 0: off)"},
        {CLI_ROW_FLOAT("--rest-response-weight", &wr, 0, 1e6), .arg = "W",
         .help = "the paired rest-response term: given RB, E-Net's angles move by RB from "
                 "its own at RB = 0 on the last frame (the authors'; 0: off)"},
        {CLI_ROW_FLOAT("--pin-top", &pin_top, 0, 10), .arg = "M",
         .help = "pin the vertices within M m of the garment's top to the skinning (default "
                 "0.01 for skirt and trousers, else 0)"},
        {CLI_ROW_FLOAT("--pnet-noise", &pnoise, 0, 3.2), .arg = "R",
         .help = "P-Net's teacher-forced RB noise, rad"},
        {CLI_ROW_STR("--pnet-val", &pval), .arg = "M",
         .help = "P-Net's validation clip: its phase stops after 5 epochs without a better "
                 "validation loss and keeps its best weights (none: all --pnet-epochs)"},
        {CLI_ROW_FLAG("--paper-sizes", &paper),
         .help = "the authors' layer widths (static 64-128-256-512, GRU 512, decoder 3x512, "
                 "P-Net latent 128 with 2 hidden layers)"},
        {CLI_ROW_OUTPUT(&out), .arg = "DIR",
         .help = "the model folder: model.json, the weights, progress.jsonl, checkpoints"},
        {CLI_ROW_FLAG("--json", &json), .help = "a summary on stdout"},
        CLI_END,
    };
    int rc = cli_parse_documented("epnet train", &train_doc, argc, argv, opts, NULL, 0, NULL);
    if (rc != CLI_OK) return rc;
    if (!out) return cli_usage("epnet train", "-o DIR is required");
    char buf[1024];
    const char *list[CR_EPNET_MAX_MOTIONS];
    if (motions) {
        d.nmotions = split_list(motions, buf, sizeof buf, list, CR_EPNET_MAX_MOTIONS);
        d.motions = list;
    }
    d.garment = garment, d.body = body, d.material.yield_angle = yield, d.out_dir = out;
    /* a waistband is held up by friction, which the loss has not */
    if (pin_top < 0)
        pin_top = !strcmp(garment, "skirt") || !strcmp(garment, "trousers") ? 0.01f : 0;
    d.pin_top = pin_top, d.w_zero_rest = wz, d.w_rest_response = wr;
    d.pnet_rb_noise = pnoise;
    d.pnet_val_motion = pval && strcmp(pval, "none") ? pval : NULL;
    if (paper) {
        const int w[4] = {64, 128, 256, 512};
        memcpy(d.static_widths, w, sizeof w), d.nstatic = 4;
        d.dynamic_width = 512, d.gru_hidden = 512;
        d.rb_widths[0] = 256, d.rb_widths[1] = 128, d.rb_widths[2] = 64, d.nrb = 3;
        d.decoder_width = 512, d.decoder_layers = 3;
        d.pnet_latent = 128, d.pnet_hidden_layers = 2;
    }
    cr_epnet_train_report r;
    cr_error err;
    if (cr_epnet_train(&d, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr,
            "epnet: %d cycles in %.1f s, E-Net loss %.5g -> %.5g J/frame, P-Net L1 %.3g rad\n",
            r.cycles_done, r.seconds, r.first_loss, r.last_loss, r.pnet_loss);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddNumberToObject(j, "cycles", r.cycles_done);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON_AddNumberToObject(j, "arena_peak_mib", (double)r.arena_peak_bytes / (1 << 20));
        cJSON_AddNumberToObject(j, "first_loss", r.first_loss);
        cJSON_AddNumberToObject(j, "last_loss", r.last_loss);
        for (int k = 0; k < CR_EPNET_NTERMS; k++) {
            char key[48];
            snprintf(key, sizeof key, "first_%s", cr_epnet_term_names[k]);
            cJSON_AddNumberToObject(j, key, r.first.term[k]);
            snprintf(key, sizeof key, "last_%s", cr_epnet_term_names[k]);
            cJSON_AddNumberToObject(j, key, r.last.term[k]);
        }
        cJSON_AddNumberToObject(j, "pnet_loss", r.pnet_loss);
        if (isnan(r.pnet_val_loss))
            cJSON_AddNullToObject(j, "pnet_val_loss");
        else
            cJSON_AddNumberToObject(j, "pnet_val_loss", r.pnet_val_loss);
        cli_json_print(j);
    }
    return CLI_OK;
}

static int run_run(int argc, char **argv) {
    cr_epnet_run_def d = cr_epnet_run_default_def();
    const char *model = NULL, *motion = NULL, *body = NULL, *out = NULL;
    int frames = 0, hold = 0, baseline = 0, json = 0, closed = 0, warmup = d.infer.warmup;
    float drive = (float)d.infer.ratchet.drive, min_delta = (float)d.infer.ratchet.min_delta;
    const cli_opt opts[] = {
        CLI_STR("--model", &model),
        CLI_STR("--motion", &motion),
        CLI_STR("--body", &body),
        CLI_INT("--frames", &frames, 0, 1000000),
        CLI_INT("--hold", &hold, 0, 1000000),
        CLI_FLAG("--baseline", &baseline),
        CLI_FLAG("--closed-loop", &closed),
        CLI_FLOAT("--drive", &drive, 0, 3.2),
        CLI_FLOAT("--min-delta", &min_delta, 0, 3.2),
        CLI_INT("--warmup", &warmup, 0, 100000),
        CLI_FLAG("--json", &json),
        CLI_OUTPUT(&out),
        CLI_END,
    };
    int rc = cli_parse("epnet run", argc, argv, opts, NULL, 0, NULL);
    if (rc != CLI_OK) return rc;
    if (!model || !motion || !out)
        return cli_usage("epnet run", "--model, --motion and -o are required");
    d.model_dir = model, d.motion = motion, d.body = body, d.frames = frames, d.hold = hold;
    d.baseline = baseline, d.out_dir = out;
    d.infer.mode = closed ? CR_EPNET_CLOSED_LOOP : CR_EPNET_PROXY;
    d.infer.warmup = warmup;
    d.infer.ratchet.drive = drive, d.infer.ratchet.min_delta = min_delta;
    cr_epnet_run_report r;
    cr_error err;
    if (cr_epnet_run(&d, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr,
            "epnet run: %d frames, %d vertices, %.4f s/frame, max |RB| %.3f rad, min body distance "
            "%.4f m%s\n",
            r.frames, r.vertices, r.seconds_per_frame, r.max_abs_rb, r.min_body_distance,
            r.finite ? "" : ", NOT FINITE");
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddNumberToObject(j, "frames", r.frames);
        cJSON_AddNumberToObject(j, "vertices", r.vertices);
        cJSON_AddNumberToObject(j, "hinges", r.hinges);
        cJSON_AddNumberToObject(j, "seconds_per_frame", r.seconds_per_frame);
        cJSON_AddNumberToObject(j, "max_abs_rb", r.max_abs_rb);
        cJSON_AddNumberToObject(j, "min_body_distance", r.min_body_distance);
        cJSON_AddBoolToObject(j, "finite", r.finite);
        cli_json_print(j);
    }
    return r.finite ? CLI_OK : CLI_BAD_INPUT;
}

static int run_measure(int argc, char **argv) {
    cr_epnet_measure_def d = cr_epnet_measure_default_def();
    const char *models = NULL, *baselines = NULL, *motions = NULL, *bodies = NULL, *out = NULL;
    int frames = d.frames, hold = d.hold, closed = 0, warmup = d.infer.warmup;
    const cli_opt opts[] = {
        CLI_STR("--models", &models),
        CLI_STR("--baselines", &baselines),
        CLI_STR("--motions", &motions),
        CLI_STR("--bodies", &bodies),
        CLI_INT("--frames", &frames, 0, 1000000),
        CLI_INT("--hold", &hold, 0, 100000),
        CLI_DOUBLE("--friction", &d.friction, 0, 10),
        CLI_DOUBLE("--twin-friction", &d.twin_friction, -1, 1),
        CLI_FLAG("--closed-loop", &closed),
        CLI_INT("--warmup", &warmup, 0, 100000),
        CLI_OUTPUT(&out),
        CLI_END,
    };
    int rc = cli_parse("epnet measure", argc, argv, opts, NULL, 0, NULL);
    if (rc != CLI_OK) return rc;
    if (!models || !baselines || !out)
        return cli_usage("epnet measure", "--models, --baselines and -o are required");
    char mb[2048], bb[2048], vb[1024], ob[1024];
    const char *ml[CR_EPNET_MEASURE_MAX_SEEDS + 1], *bl[CR_EPNET_MEASURE_MAX_SEEDS + 1];
    const char *vl[CR_EPNET_MAX_MOTIONS], *ol[16];
    d.nmodels = split_list(models, mb, sizeof mb, ml, CR_EPNET_MEASURE_MAX_SEEDS + 1);
    d.nbaselines = split_list(baselines, bb, sizeof bb, bl, CR_EPNET_MEASURE_MAX_SEEDS + 1);
    d.models = ml, d.baselines = bl;
    if (motions) d.nmotions = split_list(motions, vb, sizeof vb, vl, CR_EPNET_MAX_MOTIONS);
    if (motions) d.motions = vl;
    if (bodies) d.nbodies = split_list(bodies, ob, sizeof ob, ol, 16), d.bodies = ol;
    d.frames = frames, d.hold = hold, d.out_dir = out;
    d.infer.mode = closed ? CR_EPNET_CLOSED_LOOP : CR_EPNET_PROXY, d.infer.warmup = warmup;
    d.print = stdout;
    cr_error err;
    if (cr_epnet_measure(&d, &err) != CR_OK) return cli_fail(&err);
    return CLI_OK;
}

int cmd_epnet(int argc, char **argv) {
    if (argc < 2) return cli_usage("epnet", "expected train, run or measure");
    if (!strcmp(argv[1], "train")) return run_train(argc - 1, argv + 1);
    if (!strcmp(argv[1], "run")) return run_run(argc - 1, argv + 1);
    if (!strcmp(argv[1], "measure")) return run_measure(argc - 1, argv + 1);
    return cli_usage("epnet", "expected train, run or measure, got '%s'", argv[1]);
}
