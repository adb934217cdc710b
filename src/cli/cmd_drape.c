/* cmd_drape.c: `crease drape`: a cloth draped over an object by the drape
 * method (implicit neural surface, local structures, adaptive sampling), one
 * variant or all four side by side (--compare). */
#include "cli.h"
#include "crease/drape.h"

#include <math.h>
#include <string.h>

void help_drape(void) {
    printf(
        "usage: crease drape [--scene S | --object F] [--variant V] -o DIR [options]\n\n"
        "Drape a square cloth, laid flat above an object, by minimising strain, bend,\n"
        "gravity and collision losses over an implicit neural surface p = p0(u,v) + MLP(GE(u,v))\n"
        "(Shu et al., docs/drape.md). The losses are computed on local structures (a triangle\n"
        "and its three edge neighbours, side 0.001 in UV, randomly rotated) at points drawn from\n"
        "an adaptive PDF of the loss, or on a mesh for the mesh variants.\n\n"
        "scene:\n"
        "  --scene S            ball (default), torus, prism or table (Table 4 weights)\n"
        "  --object F           drape over this mesh instead (OBJ, PLY, glb; metres, Y up)\n"
        "  --cloth F            rest cloth mesh with UVs in [0,1]^2, used where it is (metres)\n"
        "  --cloth-size S       side of the square cloth, m (default: 1 on the built-in scenes,\n"
        "                       5/3 of the object's larger horizontal extent with --object)\n"
        "  --drop-height H      its height above the object's top, m (default 5 %% of its side;\n"
        "                       --gap is the same option)\n"
        "  --variant V          inr-adaptive (default), inr-uniform, inr-mesh or mesh\n"
        "  --compare            run all four variants into DIR/<variant>/ and write\n"
        "                       DIR/compare.png with their renders side by side\n"
        "training:\n"
        "  --epochs N           cap on epochs (default 15000; the default run stops at\n"
        "                       convergence, see --stop)\n"
        "  --samples N          local structures per epoch (default 1024)\n"
        "  --lr R               Adam learning rate (default 0.0005)\n"
        "  --lr-final R         anneal to R by the last epoch (cosine; default: none)\n"
        "  --settle N           without --lr-final: N epochs at lr/10 after convergence (or\n"
        "                       the last N before the cap), so contacts settle (default 250;\n"
        "                       0: constant lr)\n"
        "  --beta2 B            Adam's second-moment decay (default 0.999)\n"
        "  --clip C             clip the gradient norm at C times its running mean (default 3;\n"
        "                       0: off)\n"
        "  --seed S             initialisation, sampling and rotations (default 1)\n"
        "  --resume             continue from DIR/checkpoint.safetensors\n"
        "  --checkpoint-every N epochs between checkpoints (default 250; 0: at the end)\n"
        "losses:\n"
        "  --w-strain W --w-bend W --w-gravity W --w-collision W\n"
        "                       weights (Table 4: 0.005, 0.0005, 2, 1e7; 1e6 for torus, prism)\n"
        "  --point-mass M       kg per structure or vertex in the gravity loss (default 1e-4)\n"
        "  --eps E              collision threshold, m (default 0.002)\n"
        "  --collision C        vertex (eq. 26, nearest object vertex; default) or sdf\n"
        "  --side S             structure side in UV (default 0.001)\n"
        "  --pin W              hold the cloth centre's horizontal position with weight W per\n"
        "                       structure (default 1; 0: free to slide off the object)\n"
        "model:\n"
        "  --grid-levels L --grid-res R --grid-features F\n"
        "                       grid encoding (default 2 levels, 100 cells, 3 features)\n"
        "  --grid-interp I      between the grid's nodes: bspline (default; C2, no grid\n"
        "                       facets) or bilinear (the paper's, C0: its cells show as\n"
        "                       facets)\n"
        "  --hidden W --layers N   MLP width and linear layers (default 64, 4)\n"
        "  --softplus B         hidden activation softplus with beta B (default 10); 0: ReLU\n"
        "  --mesh-res N         vertices per side of the mesh variants' grid (default 128)\n"
        "sampler:\n"
        "  --pdf-grid G         PDF cells per side (default 32)\n"
        "  --gamma G            eq. 7 blend (default 0.9)\n"
        "  --mu M               adaptive share of the samples (default 0.5)\n"
        "  --lloyd N            Lloyd iterations (default 2)\n"
        "  --pdf-every N        epochs between PDF updates (default 5)\n"
        "  --pdf-collision W    the collision term's weight in the PDF, times its training\n"
        "                       weight (default 1; gravity is always left out)\n"
        "convergence (the same for every variant):\n"
        "  --eval-res N         fixed evaluation structures per side (default 128)\n"
        "  --eval-every N       epochs between evaluations (default 50)\n"
        "  --window N           converged when the energy fell by less than --tol times its\n"
        "  --tol T              total decrease over the last N epochs (default 2000, 0.01)\n"
        "  --stop               stop at convergence, after --settle epochs (the default)\n"
        "  --no-stop            train to --epochs whatever the convergence\n"
        "outputs:\n"
        "  -o DIR               drape.obj, drape.glb, drape.png, loss.png, loss.jsonl,\n"
        "                       sampler.png, checkpoint.safetensors\n"
        "  --res N              output surface vertices per side (default 256)\n"
        "  --render-size N      PNG side in pixels (default 1024)\n"
        "  --quiet              no progress bar\n"
        "  --json               end with a JSON summary on stdout\n\n"
        "The default ball run stops at convergence (epoch 8,150 of seed 1): about 1.5 "
        "CPU-minutes,\n"
        "3-4 minutes on a loaded 2-core machine (docs/drape.md).\n");
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
    int json = 0, compare = 0, seed = 1, npos = 0, no_stop = 0;
    float w[4] = {NAN, NAN, NAN, NAN}; /* NAN: the scene's Table 4 value */
    const cli_opt opts[] = {
        CLI_STR("--scene", &scene),
        CLI_STR("--object", &def.object_path),
        CLI_STR("--cloth", &def.cloth_path),
        CLI_STR("--variant", &variant),
        CLI_CHOICE("--collision", &collision, collisions),
        CLI_CHOICE("--grid-interp", &interp, interps),
        CLI_OUTPUT(&def.out_dir),
        CLI_FLAG("--compare", &compare),
        CLI_FLAG("--stop", &def.stop_at_converged),
        CLI_FLAG("--no-stop", &no_stop),
        CLI_FLAG("--resume", &def.resume),
        CLI_FLAG("--quiet", &def.quiet),
        CLI_FLAG("--json", &json),
        CLI_INT("--epochs", &def.epochs, 1, 100000000),
        CLI_INT("--samples", &def.samples, 1, 1 << 22),
        CLI_INT("--seed", &seed, 0, 2147483647),
        CLI_INT("--res", &def.out_res, 2, 4096),
        CLI_INT("--render-size", &def.render_size, 16, 8192),
        CLI_INT("--checkpoint-every", &def.checkpoint_every, 0, 100000000),
        CLI_INT("--grid-levels", &def.grid_levels, 1, 8),
        CLI_INT("--grid-res", &def.grid_resolution, 1, 4096),
        CLI_INT("--grid-features", &def.grid_features, 1, 64),
        CLI_INT("--hidden", &def.mlp_hidden, 1, 4096),
        CLI_INT("--layers", &def.mlp_layers, 1, 16),
        CLI_INT("--mesh-res", &def.mesh_res, 2, 2048),
        CLI_INT("--pdf-grid", &def.pdf_grid, 2, 1024),
        CLI_INT("--lloyd", &def.lloyd_iterations, 0, 1000),
        CLI_INT("--pdf-every", &def.pdf_every, 1, 1000000),
        CLI_INT("--eval-res", &def.eval_res, 2, 1024),
        CLI_INT("--eval-every", &def.eval_every, 1, 1000000),
        CLI_INT("--window", &def.converge_window, 1, 100000000),
        CLI_INT("--settle", &def.settle_epochs, 0, 100000000),
        CLI_FLOAT("--lr", &def.lr, 1e-12, 10.0),
        CLI_FLOAT("--lr-final", &def.lr_final, 0.0, 10.0),
        CLI_FLOAT("--beta2", &def.beta2, 0.0, 0.999999),
        CLI_FLOAT("--clip", &def.clip, 0.0, 1e6),
        CLI_FLOAT("--w-strain", &w[0], 0.0, 1e12),
        CLI_FLOAT("--w-bend", &w[1], 0.0, 1e12),
        CLI_FLOAT("--w-gravity", &w[2], 0.0, 1e12),
        CLI_FLOAT("--w-collision", &w[3], 0.0, 1e15),
        CLI_FLOAT("--point-mass", &def.point_mass, 0.0, 1e6),
        CLI_FLOAT("--eps", &def.collision_eps, 0.0, 1.0),
        CLI_FLOAT("--side", &def.side, 1e-6, 0.1),
        CLI_FLOAT("--softplus", &def.softplus_beta, 0.0, 1e3),
        CLI_FLOAT("--pin", &def.pin, 0.0, 1e12),
        CLI_FLOAT("--gamma", &def.pdf_gamma, 0.0, 1.0),
        CLI_FLOAT("--mu", &def.mu, 0.0, 1.0),
        CLI_FLOAT("--pdf-collision", &def.pdf_collision, 0.0, 1e6),
        CLI_FLOAT("--tol", &def.converge_tol, 0.0, 1.0),
        CLI_FLOAT("--drop-height", &def.gap, 0.0, 1e3),
        CLI_FLOAT("--gap", &def.gap, 0.0, 1e3),
        CLI_FLOAT("--cloth-size", &def.cloth_size, 1e-3, 1e3),
        CLI_END,
    };
    int rc = cli_parse("drape", argc, argv, opts, NULL, 0, &npos);
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
    def.seed = (uint64_t)seed;
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
