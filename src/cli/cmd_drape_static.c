/* cmd_drape_static.c: `crease drape-static`: the quasi-static equilibrium of
 * a 1 m square cloth laid flat above an object, the reference the drape
 * method is compared with. Scene and outputs come from scene.h; the
 * equilibrium from cr_sim_solve_static. */
#include "cli.h"
#include "crease/scene.h"

#include <math.h>
#include <string.h>

enum { RENDER_SIZE = 800 };
#define CLOTH_SIZE 1.0f /* m, side of the square cloth */

void help_drape_static(void) {
    printf("usage: crease drape-static --object O --res N -o DIR [options]\n\n"
           "Lay a 1 m square cloth of N x N vertices flat above an object and find its\n"
           "equilibrium under gravity: it first settles dynamically (30 fps, damping and friction\n"
           "keep it where it lands) until its RMS speed is below 5 mm/s, then a static solve\n"
           "(no inertia: the potential of docs/physics.md minimised by Newton's method) polishes\n"
           "the rest state. A static solve straight from the flat start finds an equilibrium\n"
           "too, but friction cannot act without motion and the cloth often slides off to one\n"
           "side. Objects are centred at the origin.\n\n"
           "options:\n"
           "  --object O           sphere (r 0.3 m), torus (0.3/0.1), prism (side 0.4), box (0.4)\n"
           "                       or a mesh file (required)\n"
           "  --res N              cloth vertices per side, 2..1024 (default 64)\n"
           "  --gap G              height of the cloth above the object's top, m (default 0.05)\n"
           "  --material M         cotton (default), silk, denim or knit\n"
           "  --material-json F    override material fields from a JSON object\n"
           "  --max-frames N       dynamic settling frames at most before the static solve\n"
           "                       (default 150; 0: static solve from the flat start)\n"
           "  --coarse C           settle a C x C cloth instead and start the N x N static solve\n"
           "                       from its rest shape, interpolated (large N: the settling is\n"
           "                       what costs, and it costs less on fewer vertices)\n"
           "  --quiet              no progress bar\n"
           "  -o DIR               outputs: final.obj, final.png, frames.jsonl (one line per\n"
           "                       frame and the static solve), sim.pc2 (every state)\n"
           "  --json               end with a JSON summary on stdout\n");
}

/* Every state goes to the record; settling frames also move the bar. */
typedef struct state_ctx {
    cr_scene_record *rec;
    cr_progress bar;
} state_ctx;

static cr_status record_state(void *vctx, const cr_sim *sim, const cr_sim_report *rep, int frame,
                              double rms_speed, cr_error *err) {
    state_ctx *c = vctx;
    CR_TRY(cr_scene_record_frame(c->rec, sim, rep, err));
    if (frame > 0) cr_progress_update(&c->bar, frame, "rms speed %.2g m/s", rms_speed);
    return CR_OK;
}

static cr_status coarse_progress(void *vctx, const cr_sim *sim, const cr_sim_report *rep, int frame,
                                 double rms_speed, cr_error *err) {
    (void)sim, (void)rep, (void)err;
    if (frame > 0) cr_progress_update(vctx, frame, "coarse, rms speed %.2g m/s", rms_speed);
    return CR_OK;
}

int cmd_drape_static(int argc, char **argv) {
    const char *object = NULL, *material = "cotton", *material_json = NULL, *out = NULL;
    int res = 64, json = 0, quiet = 0, max_frames = 150, coarse = 0, npos = 0;
    float gap = 0.05f;
    const cli_opt opts[] = {
        CLI_STR("--object", &object),
        CLI_STR("--material", &material),
        CLI_STR("--material-json", &material_json),
        CLI_OUTPUT(&out),
        CLI_INT("--res", &res, 2, 1024),
        CLI_FLOAT("--gap", &gap, 0.0, 10.0),
        CLI_INT("--max-frames", &max_frames, 0, 1000000),
        CLI_INT("--coarse", &coarse, 2, 1024),
        CLI_FLAG("--quiet", &quiet),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int rc = cli_parse("drape-static", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!object) return cli_usage("drape-static", "missing --object sphere|torus|prism|box|F.obj");
    if (!out) return cli_usage("drape-static", "missing -o DIR");
    if (coarse >= res)
        return cli_usage("drape-static", "--coarse %d must be below --res %d", coarse, res);
    cr_error err = {0};
    cr_sim_def def = cr_sim_default_def();
    if (cr_material_preset(material, &def.material, &err) != CR_OK)
        return cli_usage("drape-static", "%s", err.msg);

    cr_mesh *obj = NULL, *cloth = NULL, *final = NULL;
    cr_sim *sim = NULL;
    cr_scene_record *rec = NULL;
    char path[1200], obj_path[1200], png_path[1200];
    cr_status st = CR_OK;
    cr_scene_settle_stats stats = {0}, coarse_stats = {0};
    state_ctx ctx = {0};
    if (material_json) st = cr_material_load_json(material_json, &def.material, &err);
    if (st == CR_OK) st = cr_scene_object_create(object, &obj, &err);
    if (st == CR_OK) st = cr_scene_cloth_above(obj, res, CLOTH_SIZE, gap, &cloth, &err);
    def.collider = obj;
    if (st == CR_OK && coarse > 0) {
        /* Settle the coarse cloth, refine its rest shape onto the fine one,
         * and let the fine one only solve statically from there. */
        cr_progress bar;
        cr_progress_begin(&bar, "drape-static", max_frames, quiet);
        st = cr_scene_settle_coarse(&def, obj, coarse, CLOTH_SIZE, gap, max_frames,
                                    CR_SCENE_SETTLED_SPEED, coarse_progress, &bar, cloth, res,
                                    &coarse_stats, &err);
        cr_progress_end(&bar);
    }
    if (st == CR_OK) st = cr_sim_create(&def, cloth, &sim, &err);
    if (st == CR_OK) st = cr_mkdir_p(out, &err);
    if (st == CR_OK) {
        snprintf(path, sizeof path, "%s/frames.jsonl", out);
        st = cr_scene_record_create(path, sim, cloth, max_frames + 2, &rec, &err);
    }
    if (st == CR_OK) {
        int frames = coarse > 0 ? 0 : max_frames;
        ctx.rec = rec;
        cr_progress_begin(&ctx.bar, "drape-static", frames, quiet || frames == 0);
        st = cr_scene_settle(sim, frames, CR_SCENE_SETTLED_SPEED, record_state, &ctx, &stats, &err);
        cr_progress_end(&ctx.bar);
    }
    stats.seconds += coarse_stats.seconds;
    stats.newton += coarse_stats.newton;
    stats.settle_frames += coarse_stats.settle_frames;
    stats.max_penetration_m = fmax(stats.max_penetration_m, coarse_stats.max_penetration_m);
    if (st == CR_OK) {
        snprintf(obj_path, sizeof obj_path, "%s/final.obj", out);
        snprintf(png_path, sizeof png_path, "%s/final.png", out);
        snprintf(path, sizeof path, "%s/sim.pc2", out);
        st = cr_scene_record_mesh(rec, &final, &err);
        if (st == CR_OK) st = cr_mesh_write(obj_path, final, &err);
        if (st == CR_OK) st = cr_scene_record_write(rec, path, NULL, 1.0f, &err);
        if (st == CR_OK) st = cr_scene_render(png_path, final, NULL, obj, NULL, RENDER_SIZE, &err);
    }
    if (st == CR_OK) {
        if (!quiet)
            fprintf(stderr,
                    "drape-static: %d settling frames + static solve, %lld Newton "
                    "iterations, %.2f s, deepest %.3g mm\n",
                    stats.settle_frames, stats.newton, stats.seconds,
                    1e3 * stats.max_penetration_m);
        if (json) {
            cJSON *j = cJSON_CreateObject();
            cJSON_AddStringToObject(j, "command", "drape-static");
            cJSON_AddStringToObject(j, "object", object);
            cJSON_AddNumberToObject(j, "res", res);
            cJSON_AddNumberToObject(j, "vertices", cloth->nv);
            cJSON_AddStringToObject(j, "material", def.material.name);
            if (coarse > 0) cJSON_AddNumberToObject(j, "coarse", coarse);
            cJSON_AddNumberToObject(j, "settle_frames", stats.settle_frames);
            cJSON_AddBoolToObject(j, "converged", stats.converged);
            cJSON_AddNumberToObject(j, "max_penetration_m", stats.max_penetration_m);
            cJSON_AddNumberToObject(j, "newton_iterations", (double)stats.newton);
            cJSON_AddNumberToObject(j, "contacts", stats.contacts);
            cJSON_AddNumberToObject(j, "seconds", stats.seconds);
            cJSON *o = cJSON_AddObjectToObject(j, "outputs");
            cJSON_AddStringToObject(o, "obj", obj_path);
            cJSON_AddStringToObject(o, "png", png_path);
            snprintf(path, sizeof path, "%s/frames.jsonl", out);
            cJSON_AddStringToObject(o, "log", path);
            cli_json_print(j);
        }
    }
    cr_mesh_destroy(final);
    cr_scene_record_destroy(rec);
    cr_sim_destroy(sim);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(obj);
    if (st != CR_OK) return cli_fail(&err);
    return CLI_OK;
}
