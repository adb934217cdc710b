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
    printf(
        "usage: crease gdsr train --dataset DIR [--motions M1,M2] -o OUT [options]\n"
        "       crease gdsr run --model OUT/model.safetensors --dataset DIR --motion M -o DIR\n"
        "       crease gdsr run --model F --simulate --motion CLIP|FILE.bvh|FILE.npz [--body B]\n"
        "                       [--garment G] [--dataset DIR] [--frames N] -o DIR\n\n"
        "Garment dynamic super-resolution (docs/gdsr.md): a low-resolution simulation and\n"
        "the body in, a high-resolution garment with wrinkles out, frame after frame.\n\n"
        "common:\n"
        "  --dataset DIR        a `crease dataset` folder with --res low,high\n"
        "  --garment G          garment type (default tshirt; with --simulate also a variant\n"
        "                       spec, as in `crease dataset`); train: G1,G2,... trains one\n"
        "                       model on several garments of the dataset (up to 8)\n"
        "  --body B             body preset (default normal)\n"
        "  --quiet              no progress\n"
        "  --json               end with a JSON summary on stdout\n"
        "train:\n"
        "  --motions LIST       training clips (default: every motion of the dataset with a\n"
        "                       finished low and high sequence of the garment, but\n"
        "                       --val-motions)\n"
        "  --epochs N           (default 20)\n"
        "  --lr R               AdamW base rate (default 1e-4, the paper's), halved every\n"
        "  --halve-every N      N epochs (default 50)\n"
        "  --noise M            input noise on C, m (default 0.003)\n"
        "  --w-coarse W --w-fine W --w-normal W   loss weights (default 1, 1, 0.01)\n"
        "  --w-stretch W --w-shear W   Baraff-Witkin stretch and shear of the output, area\n"
        "                       means of (|w_u|-1)^2+(|w_v|-1)^2 and (w_u.w_v)^2 (default 30, 30)\n"
        "  --w-bend W           dihedral angles toward the reference's, mean k_e/2 dtheta^2\n"
        "                       (default 0.1)\n"
        "  --w-laplacian W      L1 of the uniform Laplacian of the error, m (default 1)\n"
        "  --w-strain-l1 W      L1 of |w_u|, |w_v|, w_u.w_v against the reference's, mean\n"
        "                       over triangles (Eq. 16-18, 21-23; default 0)\n"
        "  --w-wrinkle W        L1 of a filter bank's responses to the output's and the\n"
        "                       reference's UV normal maps (Eq. 20 without VGG; default 0)\n"
        "  --wrinkle-side N     that normal map's side in texels (default 128)\n"
        "  --wrinkle-patches N  Eq. 24: the loss is the mean over N random square patches of\n"
        "                       the map a step (default 8, the paper's; 0: the whole chart)\n"
        "  --wrinkle-patch-side N  their side in texels (default 32), each around a chart\n"
        "                       texel drawn uniformly\n"
        "  --lambda-c0 L --lambda-w0 L   Eq. 25's weights of the coarse and the fine terms\n"
        "                       at the start (default 1, 1; the paper's 1.9, 0.1), moved\n"
        "  --lambda-step S --lambda-every N   S toward 1 every N epochs (default 0.2, 10)\n"
        "  --out-scale S        E's and A's outputs times S m (default 0.01; small = a gentle\n"
        "                       start from upsampling)\n"
        "  --val-motions LIST   held-out clips rolled out each epoch: log.jsonl's val_med_m\n"
        "                       against val_upsampled_med_m\n"
        "  --no-decoder         GDSR(-d): no decoder E, C^ = C\n"
        "  --layer-edges auto|on|off  edges between low vertices of different garment layers\n"
        "                       (connected components) closer than sigma_l, a third edge set\n"
        "                       of H (default auto: on when the garment has two layers)\n"
        "  --sigma-l M          their radius, m (default 0.02)\n"
        "  --paper-sizes        latent 128, 6 steps, 128/512 features (default 64, 4, 32/32)\n"
        "  --latent N --steps N --wire-width N   model sizes\n"
        "  --seed S             (default 1)\n"
        "  --resume             continue from OUT/checkpoint.safetensors; the model settings\n"
        "                       (sizes, --out-scale, --seed, ...) must be the ones it was\n"
        "                       trained with\n"
        "  --checkpoint-every N epochs (default 5)\n"
        "  -o OUT               model.safetensors, checkpoint.safetensors, log.jsonl\n"
        "run:\n"
        "  --model F            a model.safetensors from gdsr train\n"
        "  --baseline-model F   a GDSR(-d) model measured in the same table\n"
        "  --twin DIR           a twin dataset (crease dataset --twin, the same def): its high\n"
        "                       clip measured in the same table, the floor\n"
        "  --motion M           the clip to super-resolve\n"
        "  --eps E              collision margin, m (default 0.002)\n"
        "  --relax N            smoothing steps that spread the collision pushes (default 4)\n"
        "  --layer-test vertex|surface  Eq. 27 on an outfit: the nearest inner vertex and its\n"
        "                       normal (default, the paper's) or the closest point on the\n"
        "                       inner layer's triangles, none past its open edges\n"
        "  --frames N           only the clip's first N frames (with --simulate: frames to\n"
        "                       simulate, default 60)\n"
        "  --png-frame F        the frame of compare.png (default -1: the last)\n"
        "  --png-size N         pixels per panel (default 512)\n"
        "  --glb-max-frames N   gdsr.glb animates up to N frames (default 300), else it holds\n"
        "                       the last frame alone\n"
        "  --fps F              gdsr.glb's playback rate (default 30)\n"
        "  -o DIR               gdsr.pc2, gdsr_raw.pc2, upsampled.pc2, reference.pc2,\n"
        "                       high.obj, gdsr.glb (morph-target animation), compare.png\n"
        "                       (low input, gdsr, upsampling, reference side by side) and\n"
        "                       compare_normals.png (their UV normal maps), summary.json,\n"
        "                       strain.csv and strain.png (E_u, E_v, E_uv over the frames)\n"
        "run --simulate (the low-resolution input made from the motion by `crease dataset`'s\n"
        "machinery into DIR/sim: garment template, posed body, simulator):\n"
        "  --simulate           --motion is a clip name or a motion file (.bvh, .npz) to\n"
        "                       simulate the low garment on; --dataset (optional) is then the\n"
        "                       training data whose manifest gives the vertex counts, fps and\n"
        "                       material (else 2000, 8000, 30, cotton)\n"
        "  --reference          simulate the high resolution too: a reference and the\n"
        "                       metrics table (slow: the high simulation)\n"
        "  --low-vertices N --high-vertices N   the garment pair's target vertex counts\n"
        "  --scale S --start-frame N --end-frame N --ease-in S --ground G   a motion file's\n"
        "                       preparation, as in `crease dataset` (docs/motions.md)\n"
        "A motion without a high sequence in the dataset is rolled out without a reference\n"
        "(no metrics table; the strain over frames and collisions are still measured).\n");
}

static int split(char *s, const char **out, int cap) {
    int n = 0;
    for (char *t = strtok(s, ","); t && n < cap; t = strtok(NULL, ","))
        out[n++] = t;
    return n;
}

static int cmd_train(int argc, char **argv) {
    const char *dataset = NULL, *garment = "tshirt", *body = "normal", *motions = NULL;
    const char *val = NULL, *layer_edges = NULL;
    static const char *const layer_choices[] = {"auto", "on", "off", NULL};
    float out_scale = 0, sigma_l = 0;
    int quiet = 0, json = 0, nodec = 0, paper = 0, latent = 0, steps = -1, wirew = 0, seed = 1;
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    const cli_opt opts[] = {
        CLI_STR("--dataset", &dataset),
        CLI_STR("--garment", &garment),
        CLI_STR("--body", &body),
        CLI_STR("--motions", &motions),
        CLI_INT("--epochs", &def.epochs, 1, 100000),
        CLI_FLOAT("--lr", &def.lr, 1e-8, 1),
        CLI_INT("--halve-every", &def.lr_halve_every, 1, 100000),
        CLI_FLOAT("--noise", &def.noise_m, 0, 0.1),
        CLI_FLOAT("--w-coarse", &def.w_coarse, 0, 1e6),
        CLI_FLOAT("--w-fine", &def.w_fine, 0, 1e6),
        CLI_FLOAT("--w-normal", &def.w_normal, 0, 1e6),
        CLI_FLOAT("--w-stretch", &def.w_stretch, 0, 1e6),
        CLI_FLOAT("--w-shear", &def.w_shear, 0, 1e6),
        CLI_FLOAT("--w-bend", &def.w_bend, 0, 1e6),
        CLI_FLOAT("--w-laplacian", &def.w_laplacian, 0, 1e6),
        CLI_FLOAT("--w-strain-l1", &def.w_strain_l1, 0, 1e6),
        CLI_FLOAT("--w-wrinkle", &def.w_wrinkle, 0, 1e6),
        CLI_INT("--wrinkle-side", &def.wrinkle_side, 8, 2048),
        CLI_INT("--wrinkle-patches", &def.wrinkle_patches, 0, 1024),
        CLI_INT("--wrinkle-patch-side", &def.wrinkle_patch_side, 1, 2048),
        CLI_FLOAT("--lambda-c0", &def.lambda_c0, 1e-3, 100),
        CLI_FLOAT("--lambda-w0", &def.lambda_w0, 1e-3, 100),
        CLI_FLOAT("--lambda-step", &def.lambda_step, 0, 100),
        CLI_INT("--lambda-every", &def.lambda_every, 1, 100000),
        CLI_FLOAT("--out-scale", &out_scale, 1e-6, 10),
        CLI_STR("--val-motions", &val),
        CLI_FLAG("--no-decoder", &nodec),
        CLI_CHOICE("--layer-edges", &layer_edges, layer_choices),
        CLI_FLOAT("--sigma-l", &sigma_l, 1e-4, 1),
        CLI_FLAG("--paper-sizes", &paper),
        CLI_INT("--latent", &latent, 4, 1024),
        CLI_INT("--steps", &steps, 0, 32),
        CLI_INT("--wire-width", &wirew, 2, 256),
        CLI_INT("--seed", &seed, 0, 1000000000),
        CLI_FLAG("--resume", &def.resume),
        CLI_INT("--checkpoint-every", &def.checkpoint_every, 0, 100000),
        CLI_OUTPUT(&def.out_dir),
        CLI_FLAG("--quiet", &quiet),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse("gdsr train", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!dataset) return cli_usage("gdsr train", "missing --dataset DIR");
    if (!def.out_dir) return cli_usage("gdsr train", "missing -o OUT");
    if (paper) def.model = cr_gdsr_model_paper_def();
    if (latent) def.model.latent = latent;
    if (steps >= 0) def.model.steps = steps;
    if (wirew) def.model.wire_width = wirew;
    def.model.use_decoder = !nodec;
    if (layer_edges)
        def.model.layer_edges = !strcmp(layer_edges, "on")    ? 1
                                : !strcmp(layer_edges, "off") ? 0
                                                              : -1;
    if (sigma_l > 0) def.model.sigma_l = sigma_l;
    def.model.seed = (uint64_t)seed;
    if (out_scale > 0) def.model.out_scale = out_scale;
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
    char buf[1024], vbuf[1024], found[CR_GDSR_MAX_CLIPS][64];
    const char *ms[CR_GDSR_MAX_CLIPS], *vs[CR_GDSR_MAX_CLIPS];
    int nv = 0, nm = 0;
    if (val) {
        snprintf(vbuf, sizeof vbuf, "%s", val);
        nv = split(vbuf, vs, CR_GDSR_MAX_CLIPS);
    }
    if (motions) {
        snprintf(buf, sizeof buf, "%s", motions);
        nm = split(buf, ms, CR_GDSR_MAX_CLIPS);
    } else { /* the dataset's motions of the (first) garment, but the validation clips */
        nm = cr_gdsr_dataset_motions(dataset, gs[0], body, vs, nv, found, CR_GDSR_MAX_CLIPS - nv,
                                     &err);
        if (nm < 0) return cli_fail(&err);
        for (int k = 0; k < nm; k++)
            ms[k] = found[k];
        fprintf(stderr, "gdsr train: the dataset's motions:");
        for (int k = 0; k < nm; k++)
            fprintf(stderr, " %s", ms[k]);
        fprintf(stderr, "\n");
    }
    /* validation clips go last: cr_gdsr_train leaves them out of training */
    def.val_clips = 0;
    for (int k = 0; k < nv && nm < CR_GDSR_MAX_CLIPS; k++)
        ms[nm++] = vs[k], def.val_clips++;
    cr_gdsr_data ds[CR_GDSR_MAX_GARMENTS];
    const cr_gdsr_data *dp[CR_GDSR_MAX_GARMENTS];
    int vl[CR_GDSR_MAX_GARMENTS], vh[CR_GDSR_MAX_GARMENTS];
    memset(ds, 0, sizeof ds);
    cr_status st = CR_OK;
    for (int k = 0; k < ng && st == CR_OK; k++) {
        st = cr_gdsr_data_load(dataset, gs[k], body, ms, nm, &ds[k], &err);
        dp[k] = &ds[k];
    }
    cr_gdsr_train_result r;
    if (st == CR_OK) st = cr_gdsr_train_many(&def, dp, ng, &r, &err);
    for (int k = 0; k < ng; k++) {
        vl[k] = ds[k].low ? ds[k].low->nv : 0, vh[k] = ds[k].high ? ds[k].high->nv : 0;
        cr_gdsr_data_free(&ds[k]);
    }
    if (st != CR_OK) return cli_fail(&err);
    fprintf(stderr,
            "gdsr train: %lld parameters, %d garment%s (%d -> %d vertices%s), epochs %d..%d, "
            "loss %.4g -> %.4g (coarse %.3g m, fine %.3g m, normal %.3g, stretch %.3g, shear "
            "%.3g, bend %.3g, laplacian %.3g m), %.1f s\n  %s/model.safetensors\n",
            (long long)r.params, ng, ng > 1 ? "s" : "", vl[0], vh[0], ng > 1 ? " the first" : "",
            r.resumed_from, r.epochs, r.first_loss, r.last_loss, r.last_coarse, r.last_fine,
            r.last_normal, r.last_stretch, r.last_shear, r.last_bend, r.last_laplacian, r.seconds,
            def.out_dir);
    if (def.val_clips > 0)
        fprintf(stderr, "  held-out MED %.5f m, upsampling's %.5f m\n", r.last_val_med,
                r.val_upsampled_med);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "gdsr train");
        cJSON_AddNumberToObject(j, "params", (double)r.params);
        cJSON_AddNumberToObject(j, "low_vertices", vl[0]); /* the first garment's */
        cJSON_AddNumberToObject(j, "high_vertices", vh[0]);
        cJSON *ga = cJSON_AddArrayToObject(j, "garments");
        for (int k = 0; k < ng; k++) {
            cJSON *o = cJSON_CreateObject();
            cJSON_AddStringToObject(o, "garment", gs[k]);
            cJSON_AddNumberToObject(o, "low_vertices", vl[k]);
            cJSON_AddNumberToObject(o, "high_vertices", vh[k]);
            cJSON_AddItemToArray(ga, o);
        }
        cJSON_AddNumberToObject(j, "epochs", r.epochs);
        cJSON_AddNumberToObject(j, "resumed_from", r.resumed_from);
        cJSON_AddNumberToObject(j, "first_loss", r.first_loss);
        cJSON_AddNumberToObject(j, "loss", r.last_loss);
        cJSON_AddNumberToObject(j, "coarse_l1_m", r.last_coarse);
        cJSON_AddNumberToObject(j, "fine_l1_m", r.last_fine);
        cJSON_AddNumberToObject(j, "normal_l1", r.last_normal);
        cJSON_AddNumberToObject(j, "stretch", r.last_stretch);
        cJSON_AddNumberToObject(j, "shear", r.last_shear);
        cJSON_AddNumberToObject(j, "bend", r.last_bend);
        cJSON_AddNumberToObject(j, "laplacian_l1_m", r.last_laplacian);
        cJSON_AddNumberToObject(j, "strain_l1", r.last_strain_l1);
        cJSON_AddNumberToObject(j, "wrinkle", r.last_wrinkle);
        cJSON_AddNumberToObject(j, "coarse_normal_l1", r.last_coarse_normal);
        cJSON_AddNumberToObject(j, "coarse_smooth", r.last_coarse_smooth);
        cJSON_AddNumberToObject(j, "coarse_bend", r.last_coarse_bend);
        cJSON_AddNumberToObject(j, "coarse_strain_l1", r.last_coarse_strain);
        if (def.val_clips > 0) {
            cJSON_AddNumberToObject(j, "val_med_m", r.last_val_med);
            cJSON_AddNumberToObject(j, "val_upsampled_med_m", r.val_upsampled_med);
        }
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cli_json_print(j);
    }
    return CLI_OK;
}

static const cr_eval_metric shown[] = {
    CR_EVAL_MED, CR_EVAL_NORMAL_ANGLE, CR_EVAL_SSIM,           CR_EVAL_E_U,
    CR_EVAL_E_V, CR_EVAL_E_UV,         CR_EVAL_COLLISION_RATIO};
enum { NSHOWN = sizeof shown / sizeof shown[0] };
/* crease eval's curvature bands the table shows (cr_eval_h_band_edges_m) */
enum { BAND_4_8CM = 2, BAND_2_4CM = 3 };

/* On an outfit: edge-face crossings between the layers of frames 2.. of x,
 * their mean and largest count a frame and the frames with any, into o. */
static cr_status layer_crossings(const cr_gdsr_data *d, const float *x, int32_t T, cJSON *o,
                                 const char *name, cr_error *err) {
    int64_t nh3 = (int64_t)d->high->nv * 3, most = 0, sum = 0;
    int32_t frames = 0;
    for (int32_t t = 2; t < T; t++) {
        int64_t c = cr_gdsr_layer_crossings(d, x + t * nh3, err);
        if (c < 0) return err ? err->status : CR_ERR_MEMORY;
        sum += c, most = c > most ? c : most, frames += c > 0;
    }
    double mean = T > 2 ? (double)sum / (T - 2) : 0.0;
    cJSON_AddNumberToObject(o, "layer_crossings_mean", mean);
    cJSON_AddNumberToObject(o, "layer_crossings_max", (double)most);
    cJSON_AddNumberToObject(o, "layer_crossing_frames", frames);
    fprintf(stderr, "  %-10s layer crossings: mean %.2f, most %lld, on %d of %d frames\n", name,
            mean, (long long)most, frames, T > 2 ? T - 2 : 0);
    return CR_OK;
}

static cr_status measure(const cr_gdsr_data *d, const cr_gdsr_clip *cl, const float *pred,
                         const char *name, cJSON *table, cr_error *err) {
    cr_eval_def ed = cr_eval_default_def();
    /* frames 2.. (the model starts at frame 2) */
    int64_t nh3 = (int64_t)d->high->nv * 3;
    cr_eval_input in = {.garment = d->high,
                        .nframes = cl->nframes - 2,
                        .pred = pred + 2 * nh3,
                        .ref = cl->high + 2 * nh3,
                        .body_mesh = d->body,
                        .body = cl->body + (int64_t)2 * d->body->nv * 3,
                        .body_nframes = cl->nframes - 2,
                        .pred_name = name};
    cr_eval_result r = {0};
    CR_TRY(cr_eval_run(&ed, &in, &r, err));
    cJSON *o = cJSON_AddObjectToObject(table, name);
    fprintf(stderr, "  %-10s", name);
    for (int k = 0; k < NSHOWN; k++) {
        double v = r.summary[shown[k]].mean;
        cJSON_AddNumberToObject(o, cr_eval_metric_name(shown[k]), v);
        fprintf(stderr, " %11.4g", v);
    }
    if (r.has_band_power) {
        /* the curvature power of the 4-8 and 2-4 cm bands over the frames (crease eval's
           band_power), against the reference's; '*' marks a band the high mesh resolves */
        cJSON *bp = cJSON_AddArrayToObject(o, "band_power_pred");
        cJSON *br = cJSON_AddArrayToObject(o, "band_power_ref");
        cJSON *res = cJSON_AddArrayToObject(o, "band_resolved");
        for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
            cJSON_AddItemToArray(bp, cJSON_CreateNumber(r.band_power_pred[b]));
            cJSON_AddItemToArray(br, cJSON_CreateNumber(r.band_power_ref[b]));
            cJSON_AddItemToArray(res, cJSON_CreateBool(r.band_resolved[b]));
        }
        for (int b = BAND_4_8CM; b <= BAND_2_4CM; b++)
            fprintf(stderr, " %10.4g%c %10.4g%c", r.band_power_pred[b],
                    r.band_resolved[b] ? '*' : ' ', r.band_power_ref[b],
                    r.band_resolved[b] ? '*' : ' ');
    }
    fprintf(stderr, "\n");
    cr_eval_result_free(&r);
    return d->nlayers > 1 ? layer_crossings(d, pred, cl->nframes, o, name, err) : CR_OK;
}

/* E_u, E_v, E_uv of every frame of gdsr and of upsampling (crease eval's
 * functions; the prediction as its own reference): strain.csv and
 * strain.png (log axes), and the last frame's values against frame 2's in
 * the JSON (the roll-out's drift). */
static cr_status strain_over_frames(const cr_gdsr_data *d, const cr_gdsr_clip *cl,
                                    const cr_gdsr_rollout_result *r, const char *out, cJSON *j,
                                    cr_error *err) {
    static const cr_eval_metric em[3] = {CR_EVAL_E_U, CR_EVAL_E_V, CR_EVAL_E_UV};
    static const char *names[3] = {"e_u", "e_v", "e_uv"};
    int32_t T = cl->nframes;
    double *v = malloc((size_t)T * 7 * sizeof(double)); /* frame, 3 gdsr, 3 upsampled */
    if (!v) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr run: out of memory");
    cr_status st = CR_OK;
    for (int p = 0; p < 2 && st == CR_OK; p++) {
        const float *x = p ? r->upsampled : r->gdsr;
        cr_eval_def ed = cr_eval_default_def();
        ed.ssim_side = 16;
        cr_eval_input in = {.garment = d->high, .nframes = T, .pred = x, .ref = x};
        cr_eval_result er = {0};
        if ((st = cr_eval_run(&ed, &in, &er, err)) != CR_OK) break;
        for (int32_t t = 0; t < T; t++) {
            v[7 * t] = t;
            for (int k = 0; k < 3; k++)
                v[7 * t + 1 + 3 * p + k] = cr_eval_value(&er, t, em[k]);
        }
        cr_eval_result_free(&er);
    }
    char path[1100];
    cr_atomic_file f;
    snprintf(path, sizeof path, "%s/strain.csv", out);
    if (st == CR_OK && (st = cr_atomic_open(&f, path, err)) == CR_OK) {
        fprintf(f.fp, "frame,gdsr_e_u,gdsr_e_v,gdsr_e_uv,upsampled_e_u,upsampled_e_v,"
                      "upsampled_e_uv\n");
        for (int32_t t = 0; t < T; t++)
            fprintf(f.fp, "%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", t, v[7 * t + 1], v[7 * t + 2],
                    v[7 * t + 3], v[7 * t + 4], v[7 * t + 5], v[7 * t + 6]);
        st = cr_atomic_commit(&f, err);
    }
    double *col = st == CR_OK ? malloc((size_t)T * 7 * sizeof(double)) : NULL;
    if (st == CR_OK && !col) st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr run: out of memory");
    if (st == CR_OK) {
        for (int c = 0; c < 7; c++)
            for (int32_t t = 0; t < T; t++)
                col[(int64_t)c * T + t] = v[7 * t + c];
        cr_plot_series ser[6];
        cr_plot_panel pan[3];
        char label[6][48];
        for (int k = 0; k < 3; k++) {
            for (int p = 0; p < 2; p++) {
                snprintf(label[2 * k + p], sizeof label[0], "%s %s", p ? "upsampling" : "gdsr",
                         names[k]);
                ser[2 * k + p] =
                    (cr_plot_series){.name = label[2 * k + p],
                                     .x = col,
                                     .y = col + (int64_t)(1 + 3 * p + k) * T,
                                     .n = T,
                                     .rgb = {p ? 120 : 200, p ? 120 : 40, p ? 120 : 40}};
            }
            pan[k] = (cr_plot_panel){.series = ser + 2 * k, .nseries = 2, .log_y = 1};
        }
        cr_image img = {0};
        snprintf(path, sizeof path, "%s/strain.png", out);
        if ((st = cr_plot_lines(pan, 3, "frame", "gdsr roll-out: e_u, e_v, e_uv", 900, 700, &img,
                                err)) == CR_OK)
            st = cr_image_write_png(&img, path, err);
        cr_image_free(&img);
        /* frame 2 is the model's first; the last shows any drift */
        int32_t a = T > 2 ? 2 : 0, b = T - 1;
        cJSON *o = cJSON_AddObjectToObject(j, "strain");
        cJSON_AddNumberToObject(o, "first_frame", a);
        cJSON_AddNumberToObject(o, "last_frame", b);
        for (int k = 0; k < 3; k++) {
            char key[64];
            snprintf(key, sizeof key, "gdsr_%s_first", names[k]);
            cJSON_AddNumberToObject(o, key, v[7 * a + 1 + k]);
            snprintf(key, sizeof key, "gdsr_%s_last", names[k]);
            cJSON_AddNumberToObject(o, key, v[7 * b + 1 + k]);
            double mx = 0;
            for (int32_t t = a; t <= b; t++)
                mx = fmax(mx, v[7 * t + 1 + k]);
            snprintf(key, sizeof key, "gdsr_%s_max", names[k]);
            cJSON_AddNumberToObject(o, key, mx);
        }
        fprintf(stderr,
                "  strain, frame %d -> %d: e_u %.3g -> %.3g, e_v %.3g -> %.3g, e_uv %.3g -> %.3g "
                "(%s/strain.png)\n",
                a, b, v[7 * a + 1], v[7 * b + 1], v[7 * a + 2], v[7 * b + 2], v[7 * a + 3],
                v[7 * b + 3], out);
    }
    free(col);
    free(v);
    return st;
}

static int cmd_run(int argc, char **argv) {
    const char *dataset = NULL, *garment = "tshirt", *body = "normal", *motion = NULL;
    const char *model = NULL, *baseline = NULL, *out = NULL, *twin = NULL;
    float eps = 0.002f;
    int quiet = 0, json = 0, frames = 0, relax = CR_GDSR_RELAX_DEFAULT;
    const char *layer_test = NULL;
    static const char *const layer_tests[] = {"vertex", "surface", NULL};
    int simulate = 0, reference = 0, lowv = 0, highv = 0, png_frame = -1, png_size = 512;
    int glb_max = CR_GDSR_GLB_MAX_FRAMES;
    float fps = 30.0f;
    cli_motion_file mf = cli_motion_file_default(1.0f);
    const cli_opt opts[] = {
        CLI_STR("--dataset", &dataset),
        CLI_STR("--garment", &garment),
        CLI_STR("--body", &body),
        CLI_STR("--motion", &motion),
        CLI_STR("--model", &model),
        CLI_STR("--baseline-model", &baseline),
        CLI_STR("--twin", &twin),
        CLI_FLOAT("--eps", &eps, 0, 0.05),
        CLI_INT("--relax", &relax, 0, 1000),
        CLI_CHOICE("--layer-test", &layer_test, layer_tests),
        CLI_INT("--frames", &frames, 3, 1000000),
        CLI_FLAG("--simulate", &simulate),
        CLI_FLAG("--reference", &reference),
        CLI_INT("--low-vertices", &lowv, 500, 100000),
        CLI_INT("--high-vertices", &highv, 500, 100000),
        CLI_MOTION_FILE_OPTS(&mf),
        CLI_INT("--png-frame", &png_frame, -1, 1000000),
        CLI_INT("--png-size", &png_size, 16, 4096),
        CLI_INT("--glb-max-frames", &glb_max, 0, 100000),
        CLI_FLOAT("--fps", &fps, 0.01, 1000),
        CLI_OUTPUT(&out),
        CLI_FLAG("--quiet", &quiet),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int npos = 0;
    int rc = cli_parse("gdsr run", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!motion || !model || !out || (!dataset && !simulate))
        return cli_usage("gdsr run", "needs --motion, --model, -o and --dataset or --simulate");
    if (twin && simulate)
        return cli_usage("gdsr run", "--twin measures a dataset's clip, not --simulate");
    if (!simulate && (reference || lowv || highv))
        return cli_usage("gdsr run", "--reference, --low-vertices and --high-vertices need "
                                     "--simulate");
    cr_error err = {0};
    cr_gdsr_data d;
    cr_gdsr_sim_result sr = {0};
    char simdir[1100];
    if (simulate) {
        cr_motion_import_def imp;
        cr_motion_prepare_def pd;
        cli_motion_file_defs(&mf, &imp, &pd);
        snprintf(simdir, sizeof simdir, "%s/sim", out);
        cr_gdsr_sim_def sd = cr_gdsr_sim_default_def();
        sd.out_dir = simdir, sd.garment = garment, sd.body = body, sd.motion = motion;
        sd.like = dataset, sd.low_vertices = lowv, sd.high_vertices = highv;
        if (frames > 0) sd.frames = frames;
        sd.reference = reference, sd.quiet = quiet;
        sd.motion_import = &imp, sd.motion_prepare = &pd;
        if (cr_gdsr_simulate(&sd, &d, &sr, &err) != CR_OK) return cli_fail(&err);
        fprintf(stderr,
                "gdsr run: simulated %s on %s (%s), %d frames, %d low vertices%s, %.1f s "
                "(%s)\n",
                sr.garment, body, sr.motion, d.clip[0].nframes - 1, sr.low_vertices,
                reference ? " and the high reference" : "", sr.seconds, simdir);
        motion = sr.motion;
        frames = 0;
    } else if (cr_gdsr_data_load(dataset, garment, body, &motion, 1, &d, &err) != CR_OK)
        return cli_fail(&err);
    cr_gdsr_data dt = {0}; /* the twin dataset's clip */
    if (twin && cr_gdsr_data_load(twin, garment, body, &motion, 1, &dt, &err) != CR_OK) {
        cr_gdsr_data_free(&d); /* dt: the failed load freed it */
        return cli_fail(&err);
    }
    if (twin && (dt.high->nv != d.high->nv || dt.clip[0].nframes < d.clip[0].nframes)) {
        cr_gdsr_data_free(&d), cr_gdsr_data_free(&dt);
        CR_FAIL(&err, CR_ERR_SHAPE,
                "gdsr run: %s's high %s clip has %d vertices and %d frames, %s's %d and %d", twin,
                motion, dt.high->nv, dt.clip[0].nframes, dataset, d.high->nv, d.clip[0].nframes);
        return cli_fail(&err);
    }
    cr_gdsr_model *m = NULL, *mb = NULL;
    cr_gdsr_rollout_result r = {0}, rb = {0};
    cJSON *j = cJSON_CreateObject();
    cJSON *table = NULL;
    char path[1100];
    int status = CLI_BAD_INPUT;
    if (frames > 0 && frames < d.clip[0].nframes) d.clip[0].nframes = frames; /* the first N */
    const cr_gdsr_clip *cl = &d.clip[0];
    if (cr_mkdir_p(out, &err) != CR_OK) goto done;
    if (cr_gdsr_model_load(model, &m, &err) != CR_OK) goto done;
    const int surface = layer_test && !strcmp(layer_test, "surface");
    if (cr_gdsr_rollout(m, &d, 0, eps, relax, surface, &r, &err) != CR_OK) goto done;
    if (baseline && (cr_gdsr_model_load(baseline, &mb, &err) != CR_OK ||
                     cr_gdsr_rollout(mb, &d, 0, eps, relax, surface, &rb, &err) != CR_OK))
        goto done;
    struct {
        const char *name;
        const float *x;
    } outs[] = {{"gdsr", r.gdsr},
                {"gdsr_raw", r.gdsr_raw},
                {"upsampled", r.upsampled},
                {"reference", cl->high}, /* NULL: a low-only roll-out */
                {"gdsr_nodec", rb.gdsr}};
    for (int k = 0; k < 5; k++) {
        if (!outs[k].x) continue;
        snprintf(path, sizeof path, "%s/%s.pc2", out, outs[k].name);
        if (cr_pc2_write(path, outs[k].x, d.high->nv, cl->nframes, 0, 1, &err) != CR_OK) goto done;
    }
    snprintf(path, sizeof path, "%s/high.obj", out);
    if (cr_obj_write(path, d.high, &err) != CR_OK) goto done;
    int animated = 0;
    snprintf(path, sizeof path, "%s/gdsr.glb", out);
    if (cr_gdsr_write_glb(d.high, r.gdsr, cl->nframes, fps, glb_max, path, &animated, &err) !=
        CR_OK)
        goto done;
    if (png_frame < 0 || png_frame >= cl->nframes) png_frame = cl->nframes - 1;
    char npath[1100];
    snprintf(path, sizeof path, "%s/compare.png", out);
    snprintf(npath, sizeof npath, "%s/compare_normals.png", out);
    if (cr_gdsr_render_compare(&d, 0, &r, png_frame, png_size, path, npath, &err) != CR_OK)
        goto done;
    snprintf(path, sizeof path, "%s/body.pc2", out);
    if (cr_pc2_write(path, cl->body, d.body->nv, cl->nframes, 0, 1, &err) != CR_OK) goto done;
    snprintf(path, sizeof path, "%s/body.obj", out);
    if (cr_obj_write(path, d.body, &err) != CR_OK) goto done;
    fprintf(stderr,
            "gdsr run %s: %d frames, %d -> %d vertices, %.4f s per frame (gdsr + handling; "
            "%.4f s CPU); "
            "inside the body: %.3f %% before handling, %.3f %% after\n",
            motion, cl->nframes, d.low->nv, d.high->nv, r.seconds_per_frame,
            r.cpu_seconds_per_frame, 100 * r.inside_before, 100 * r.inside_after);
    fprintf(stderr,
            "  first frame through the networks %.4f s (with the warm-up); per frame after:",
            r.first_frame_seconds);
    for (int k = 0; k < 4; k++)
        fprintf(stderr, " %s %.4f s%s", cr_gdsr_stage_names[k], r.stage_seconds[k],
                k < 3 ? "," : "\n");
    if (d.nlayers > 1)
        fprintf(stderr, "  layers (Eq. 27): %lld coarse and %lld high vertices pushed out\n",
                (long long)r.layer_pushed, (long long)r.layer_pushed_high);
    if (cl->high) {
        fprintf(stderr, "  %-10s", "");
        for (int k = 0; k < NSHOWN; k++)
            fprintf(stderr, " %11.11s", cr_eval_metric_name(shown[k]));
        fprintf(stderr, " %11s %11s %11s %11s\n", "p4-8cm", "p4-8cm_ref", "p2-4cm", "p2-4cm_ref");
        table = cJSON_AddObjectToObject(j, "metrics");
        if (measure(&d, cl, r.upsampled, "upsampled", table, &err) != CR_OK) goto done;
        if (measure(&d, cl, r.gdsr, "gdsr", table, &err) != CR_OK) goto done;
        if (measure(&d, cl, r.gdsr_raw, "gdsr_raw", table, &err) != CR_OK) goto done;
        if (rb.gdsr && measure(&d, cl, rb.gdsr, "gdsr_nodec", table, &err) != CR_OK) goto done;
        if (twin && measure(&d, cl, dt.clip[0].high, "twin", table, &err) != CR_OK) goto done;
        if (d.nlayers > 1 &&
            layer_crossings(&d, cl->high, cl->nframes, cJSON_AddObjectToObject(table, "reference"),
                            "reference", &err) != CR_OK)
            goto done;
    }
    if (strain_over_frames(&d, cl, &r, out, j, &err) != CR_OK) goto done;
    cJSON_AddStringToObject(j, "command", "gdsr run");
    cJSON_AddStringToObject(j, "motion", motion);
    cJSON_AddNumberToObject(j, "frames", cl->nframes);
    cJSON_AddNumberToObject(j, "low_vertices", d.low->nv);
    cJSON_AddNumberToObject(j, "high_vertices", d.high->nv);
    cJSON_AddNumberToObject(j, "seconds_per_frame", r.seconds_per_frame);
    cJSON_AddNumberToObject(j, "cpu_seconds_per_frame", r.cpu_seconds_per_frame);
    cJSON_AddNumberToObject(j, "first_frame_seconds", r.first_frame_seconds);
    cJSON *stages = cJSON_AddObjectToObject(j, "stage_seconds_per_frame");
    for (int k = 0; k < 4; k++)
        cJSON_AddNumberToObject(stages, cr_gdsr_stage_names[k], r.stage_seconds[k]);
    cJSON_AddNumberToObject(j, "inside_before", r.inside_before);
    cJSON_AddNumberToObject(j, "inside_after", r.inside_after);
    cJSON_AddNumberToObject(j, "layer_pushed", (double)r.layer_pushed);
    cJSON_AddNumberToObject(j, "layer_pushed_high", (double)r.layer_pushed_high);
    cJSON_AddBoolToObject(j, "glb_animated", animated);
    cJSON_AddNumberToObject(j, "png_frame", png_frame);
    if (simulate) {
        cJSON *o = cJSON_AddObjectToObject(j, "simulated");
        cJSON_AddStringToObject(o, "dir", simdir);
        cJSON_AddStringToObject(o, "garment", sr.garment);
        cJSON_AddBoolToObject(o, "reference", reference);
        cJSON_AddNumberToObject(o, "seconds", sr.seconds);
        cJSON_AddNumberToObject(o, "max_inside_share", sr.max_inside_share);
    }
    {
        char *s = cJSON_Print(j);
        snprintf(path, sizeof path, "%s/summary.json", out);
        cr_atomic_file f;
        cr_status st = s ? cr_atomic_open(&f, path, &err)
                         : CR_FAIL(&err, CR_ERR_MEMORY, "%s: out of memory", path);
        if (st == CR_OK) {
            fputs(s, f.fp);
            st = cr_atomic_commit(&f, &err);
        }
        free(s);
        if (st != CR_OK) goto done;
    }
    if (json) {
        cli_json_print(j);
        j = NULL;
    }
    status = CLI_OK;
done:
    if (status != CLI_OK) cli_fail(&err);
    cJSON_Delete(j);
    cr_gdsr_rollout_free(&r);
    cr_gdsr_rollout_free(&rb);
    cr_gdsr_model_destroy(m);
    cr_gdsr_model_destroy(mb);
    cr_gdsr_data_free(&d);
    if (twin) cr_gdsr_data_free(&dt);
    return status;
}

int cmd_gdsr(int argc, char **argv) {
    if (argc < 2) return cli_usage("gdsr", "missing a subcommand: train or run");
    if (strcmp(argv[1], "train") == 0) return cmd_train(argc - 1, argv + 1);
    if (strcmp(argv[1], "run") == 0) return cmd_run(argc - 1, argv + 1);
    return cli_usage("gdsr", "unknown subcommand '%s' (train, run)", argv[1]);
}
