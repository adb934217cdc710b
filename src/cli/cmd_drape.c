/* cmd_drape.c: `crease drape`: a cloth draped over an object by the drape
 * method (implicit neural surface, local structures, adaptive sampling), one
 * variant or all four side by side (--compare). */
#include "cli.h"
#include "crease/drape.h"

#include <math.h>
#include <string.h>

static const cli_doc drape_doc = {
    .usage = "crease drape [--scene S | --object F] [--variant V] -o DIR [options]",
    .about =
        "Drape a square cloth, laid flat above an object, by minimising strain, bend,\n"
        "gravity and collision losses over an implicit neural surface p = p0(u,v) + MLP(GE(u,v))\n"
        "(Shu et al., docs/drape.md). The losses are computed on local structures (a triangle\n"
        "and its three edge neighbours, side 0.001 in UV, randomly rotated) at points drawn from\n"
        "an adaptive PDF of the loss, or on a mesh for the mesh variants.\n",
    .after = "The default ball run stops at convergence (epoch 8,150 of seed 1): about 1.5\n"
             "CPU-minutes, 3-4 minutes on a loaded 2-core machine (docs/drape.md).\n"};

/* the help is the option table's (cli_parse_documented) */
void help_drape(void) {
    static char name[] = "drape", help[] = "--help";
    char *argv[] = {name, help, NULL};
    cmd_drape(2, argv);
}

static cJSON *terms_object(const cr_drape_terms *t) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "strain", t->strain);
    cJSON_AddNumberToObject(o, "bend", t->bend);
    cJSON_AddNumberToObject(o, "gravity", t->gravity);
    cJSON_AddNumberToObject(o, "collision", t->collision);
    cJSON_AddNumberToObject(o, "total", t->total);
    return o;
}

static void add_path(cJSON *o, const char *key, const char *path) {
    if (path[0]) cJSON_AddStringToObject(o, key, path);
}

static cJSON *result_json(const cr_drape_def *def, const cr_drape_result *r) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "scene",
                            def->scene == CR_DRAPE_OBJECT ? def->object_path
                                                          : cr_drape_scene_name(def->scene));
    cJSON_AddStringToObject(j, "variant", cr_drape_variant_name(def->variant));
    cJSON_AddStringToObject(j, "grid_interp", cr_grid_interp_name(def->grid_interp));
    cJSON_AddNumberToObject(j, "params", (double)r->params);
    cJSON_AddNumberToObject(j, "epochs", r->epochs);
    cJSON_AddNumberToObject(j, "seconds", r->seconds);
    cJSON_AddNumberToObject(j, "eval_seconds", r->eval_seconds);
    if (r->converged_epoch >= 0) {
        cJSON_AddNumberToObject(j, "converged_epoch", r->converged_epoch);
        cJSON_AddNumberToObject(j, "converged_seconds", r->converged_seconds);
    } else {
        cJSON_AddNullToObject(j, "converged_epoch");
        cJSON_AddNullToObject(j, "converged_seconds");
    }
    cJSON_AddNumberToObject(j, "strain", r->terms.strain);
    cJSON_AddNumberToObject(j, "bend", r->terms.bend);
    cJSON_AddNumberToObject(j, "gravity", r->terms.gravity);
    cJSON_AddNumberToObject(j, "collision", r->terms.collision);
    cJSON_AddNumberToObject(j, "total", r->terms.total);
    cJSON_AddItemToObject(j, "initial", terms_object(&r->initial));
    cJSON_AddNumberToObject(j, "max_penetration_m", r->max_penetration_m);
    if (isfinite(r->facet_ratio))
        cJSON_AddNumberToObject(j, "facet_ratio", r->facet_ratio);
    else
        cJSON_AddNullToObject(j, "facet_ratio");
    cJSON_AddNumberToObject(j, "cloth_size_m", r->cloth_size_m);
    cJSON_AddNumberToObject(j, "drop_height_m", r->drop_height_m);
    cJSON_AddNumberToObject(j, "resumed_from_epoch", r->resumed_from);
    cJSON *o = cJSON_AddObjectToObject(j, "outputs");
    add_path(o, "obj", r->obj_path);
    add_path(o, "glb", r->glb_path);
    add_path(o, "png", r->png_path);
    add_path(o, "loss_png", r->loss_png);
    add_path(o, "log", r->log_path);
    add_path(o, "sampler_png", r->sampler_png);
    add_path(o, "checkpoint", r->checkpoint_path);
    return j;
}

static void report(const cr_drape_def *def, const cr_drape_result *r) {
    char conv[64] = "not converged";
    if (r->converged_epoch >= 0)
        snprintf(conv, sizeof conv, "converged at epoch %d (%.1f s)", r->converged_epoch,
                 r->converged_seconds);
    char deepest[48] = "deepest not measured (open object)";
    if (isfinite(r->max_penetration_m))
        snprintf(deepest, sizeof deepest, "deepest %.3g mm", 1e3 * r->max_penetration_m);
    char facets[40] = "";
    if (isfinite(r->facet_ratio)) snprintf(facets, sizeof facets, ", facets %.2f", r->facet_ratio);
    fprintf(stderr,
            "drape %s: %lld free variables, %d epochs, %.1f s, %s; energy %.4g -> %.4g, %s%s\n",
            cr_drape_variant_name(def->variant), (long long)r->params, r->epochs, r->seconds, conv,
            r->initial.total, r->terms.total, deepest, facets);
    if (r->glb_path[0])
        fprintf(stderr, "view: crease view %s%s%s -o %s/view\n", r->glb_path,
                def->scene == CR_DRAPE_OBJECT ? "+" : "",
                def->scene == CR_DRAPE_OBJECT ? def->object_path : "", def->out_dir);
    if (r->png_path[0])
        fprintf(stderr, "  %s\n  %s\n  %s\n  %s%s%s\n", r->obj_path, r->png_path, r->loss_png,
                r->log_path, r->sampler_png[0] ? "\n  " : "", r->sampler_png);
}

int cmd_drape(int argc, char **argv) {
    static const char *const collisions[] = {"vertex", "sdf", NULL};
    static const char *const interps[] = {"bilinear", "bspline", NULL};
    cr_drape_def def = cr_drape_default_def(CR_DRAPE_BALL);
    const char *scene = NULL, *variant = NULL, *collision = NULL, *interp = NULL;
    int json = 0, compare = 0, npos = 0, no_stop = 0;
    float w[4] = {NAN, NAN, NAN, NAN}; /* NAN: the scene's Table 4 value */
    int n[CR_DRAPE_KEY_GROUPS];
    const cr_config_key *k[CR_DRAPE_KEY_GROUPS];
    for (int g = 0; g < CR_DRAPE_KEY_GROUPS; g++)
        k[g] = cr_drape_def_keys((cr_drape_key_group)g, &n[g]);
    const cli_opt opts[] = {
        CLI_HEADING("scene"),
        {CLI_ROW_STR("--scene", &scene), .arg = "S",
         .help = "ball (default), torus, prism or table (Table 4 weights)"},
        {CLI_ROW_STR("--object", &def.object_path), .arg = "F",
         .help = "drape over this mesh instead (OBJ, PLY, glb; metres, Y up)"},
        {CLI_ROW_STR("--cloth", &def.cloth_path), .arg = "F",
         .help = "rest cloth mesh with UVs in [0,1]^2, used where it is (metres)"},
        CLI_KEYS(k[CR_DRAPE_KEYS_SCENE], n[CR_DRAPE_KEYS_SCENE], &def),
        {CLI_ROW_FLOAT("--drop-height", &def.gap, 0.0, 1e3), .alias = "--gap", .arg = "H",
         .help = "its height above the object's top, m (default 5 % of its side)"},
        {CLI_ROW_STR("--variant", &variant), .arg = "V",
         .help = "inr-adaptive (default), inr-uniform, inr-mesh or mesh"},
        {CLI_ROW_FLAG("--compare", &compare),
         .help = "run all four variants into DIR/<variant>/ and write DIR/compare.png with "
                 "their renders side by side"},
        CLI_HEADING("training"),
        CLI_KEYS(k[CR_DRAPE_KEYS_TRAINING], n[CR_DRAPE_KEYS_TRAINING], &def),
        CLI_HEADING("losses (weights: the scene's Table 4 values, 0.005, 0.0005, 2, 1e7; 1e6 "
                    "for torus and prism)"),
        {CLI_ROW_FLOAT("--w-strain", &w[0], 0.0, 1e12), .arg = "W", .help = "strain weight"},
        {CLI_ROW_FLOAT("--w-bend", &w[1], 0.0, 1e12), .arg = "W", .help = "bend weight"},
        {CLI_ROW_FLOAT("--w-gravity", &w[2], 0.0, 1e12), .arg = "W", .help = "gravity weight"},
        {CLI_ROW_FLOAT("--w-collision", &w[3], 0.0, 1e15), .arg = "W", .help = "collision weight"},
        CLI_KEYS(k[CR_DRAPE_KEYS_LOSSES], n[CR_DRAPE_KEYS_LOSSES], &def),
        {CLI_ROW_CHOICE("--collision", &collision, collisions), .arg = "C",
         .help = "vertex (eq. 26, nearest object vertex; default) or sdf"},
        CLI_HEADING("model"),
        CLI_KEYS(k[CR_DRAPE_KEYS_MODEL], n[CR_DRAPE_KEYS_MODEL], &def),
        {CLI_ROW_CHOICE("--grid-interp", &interp, interps), .arg = "I",
         .help = "between the grid's nodes: bspline (default; C2, no grid facets) or bilinear "
                 "(the paper's, C0: its cells show as facets)"},
        CLI_HEADING("sampler"),
        CLI_KEYS(k[CR_DRAPE_KEYS_SAMPLER], n[CR_DRAPE_KEYS_SAMPLER], &def),
        CLI_HEADING("convergence (the same for every variant)"),
        CLI_KEYS(k[CR_DRAPE_KEYS_CONVERGENCE], n[CR_DRAPE_KEYS_CONVERGENCE], &def),
        {CLI_ROW_FLAG("--no-stop", &no_stop), .help = "train to --epochs whatever the convergence"},
        CLI_HEADING("outputs"),
        {CLI_ROW_OUTPUT(&def.out_dir), .arg = "DIR",
         .help = "drape.obj, drape.glb, drape.png, loss.png, loss.jsonl, sampler.png, "
                 "checkpoint.safetensors"},
        CLI_KEYS(k[CR_DRAPE_KEYS_OUTPUTS], n[CR_DRAPE_KEYS_OUTPUTS], &def),
        {CLI_ROW_FLAG("--json", &json), .help = "end with a JSON summary on stdout"},
        CLI_END,
    };
    int rc = cli_parse_documented("drape", &drape_doc, argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (scene && def.object_path)
        return cli_usage("drape", "--scene and --object exclude each other");
    if (!def.out_dir) return cli_usage("drape", "missing -o DIR");
    if (compare && variant)
        return cli_usage("drape", "--compare runs every variant; drop --variant");
    cr_error err = {0};
    cr_drape_scene sc = CR_DRAPE_BALL;
    if (def.object_path) sc = CR_DRAPE_OBJECT;
    if (scene && cr_drape_scene_parse(scene, &sc, &err) != CR_OK)
        return cli_usage("drape", "%s", err.msg);
    if (variant && cr_drape_variant_parse(variant, &def.variant, &err) != CR_OK)
        return cli_usage("drape", "%s", err.msg);
    if (interp && cr_grid_interp_parse(interp, &def.grid_interp, &err) != CR_OK)
        return cli_usage("drape", "%s", err.msg);
    if (collision)
        def.collision =
            strcmp(collision, "sdf") == 0 ? CR_DRAPE_COLLIDE_SDF : CR_DRAPE_COLLIDE_VERTEX;
    /* the scene's Table 4 weights, then any given on the command line */
    def.scene = sc;
    def.w = cr_drape_default_def(sc).w;
    float *wf[4] = {&def.w.strain, &def.w.bend, &def.w.gravity, &def.w.collision};
    for (int k = 0; k < 4; k++)
        if (!isnan(w[k])) *wf[k] = w[k];
    if (no_stop) def.stop_at_converged = 0;
    if (cr_drape_def_validate(&def, &err) != CR_OK) return cli_usage("drape", "%s", err.msg);

    if (compare) {
        cr_drape_result res[CR_DRAPE_VARIANT_COUNT];
        char png[1100];
        if (cr_drape_compare(&def, res, png, sizeof png, &err) != CR_OK) return cli_fail(&err);
        for (int i = 0; i < CR_DRAPE_VARIANT_COUNT; i++) {
            cr_drape_def d = def;
            d.variant = (cr_drape_variant)i;
            report(&d, &res[i]);
        }
        fprintf(stderr, "drape compare: %s\n", png);
        if (json) {
            cJSON *j = cJSON_CreateObject();
            cJSON_AddStringToObject(j, "command", "drape");
            cJSON_AddStringToObject(j, "compare_png", png);
            cJSON *arr = cJSON_AddArrayToObject(j, "variants");
            for (int i = 0; i < CR_DRAPE_VARIANT_COUNT; i++) {
                cr_drape_def d = def;
                d.variant = (cr_drape_variant)i;
                cJSON_AddItemToArray(arr, result_json(&d, &res[i]));
            }
            cJSON_AddNumberToObject(j, "threads", cr_thread_count());
            cli_json_print(j);
        }
        return CLI_OK;
    }
    cr_drape_result r;
    if (cr_drape_run(&def, &r, NULL, &err) != CR_OK) return cli_fail(&err);
    report(&def, &r);
    if (json) {
        cJSON *j = result_json(&def, &r);
        cJSON_AddStringToObject(j, "command", "drape");
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cli_json_print(j);
    }
    return CLI_OK;
}
