/* cmd_drape_static.c: `crease drape-static`: the quasi-static equilibrium of
 * a 1 m square cloth laid flat above an object, the reference the drape
 * method is compared with. Scene and outputs come from phys_scene.h; the
 * equilibrium from cr_sim_solve_static. */
#include "cli.h"
#include "crease/phys_scene.h"

#include <math.h>
#include <string.h>

enum { RENDER_SIZE = 800 };
#define SETTLED_SPEED 5e-3 /* m/s, RMS vertex speed below which the cloth counts as at rest */
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
           "  --quiet              no progress bar\n"
           "  -o DIR               outputs: final.obj, final.png, frames.jsonl (one line per\n"
           "                       frame and the static solve), sim.pc2 (every state)\n"
           "  --json               end with a JSON summary on stdout\n");
}

int cmd_drape_static(int argc, char **argv) {
    cli_args a = cli_args_make(argc, argv);
    const char *object = NULL, *material = "cotton", *material_json = NULL, *out = NULL, *v;
    int res = 64, json = 0, quiet = 0, max_frames = 150;
    float gap = 0.05f;
    while (!cli_args_done(&a)) {
        const char *opt = cli_args_next(&a);
        if (strcmp(opt, "--object") == 0) {
            if (!(object = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (strcmp(opt, "--material") == 0) {
            if (!(material = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (strcmp(opt, "--material-json") == 0) {
            if (!(material_json = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (strcmp(opt, "-o") == 0 || strcmp(opt, "--output") == 0) {
            if (!(out = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (strcmp(opt, "--res") == 0) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("drape-static", opt, v, 2, 1024, &res))
                return CLI_USAGE;
        } else if (strcmp(opt, "--gap") == 0) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_float("drape-static", opt, v, 0.0, 10.0, &gap))
                return CLI_USAGE;
        } else if (strcmp(opt, "--max-frames") == 0) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("drape-static", opt, v, 0, 1000000, &max_frames))
                return CLI_USAGE;
        } else if (strcmp(opt, "--quiet") == 0) {
            quiet = 1;
        } else if (strcmp(opt, "--json") == 0) {
            json = 1;
        } else {
            return cli_usage("drape-static", "unknown option '%s'", opt);
        }
    }
    if (!object) return cli_usage("drape-static", "missing --object sphere|torus|prism|box|F.obj");
    if (!out) return cli_usage("drape-static", "missing -o DIR");
    cr_error err = {0};
    cr_sim_def def = cr_sim_default_def();
    if (cr_material_preset(material, &def.material, &err) != CR_OK)
        return cli_usage("drape-static", "%s", err.msg);

    cr_mesh *obj = NULL, *cloth = NULL, *final = NULL;
    cr_sim *sim = NULL;
    cr_scene_record *rec = NULL;
    cr_sim_report rep = {0};
    char path[1200], obj_path[1200], png_path[1200];
    cr_status st = CR_OK;
    if (material_json) st = cr_material_load_json(material_json, &def.material, &err);
    if (st == CR_OK) st = cr_scene_object_create(object, &obj, &err);
    if (st == CR_OK) st = cr_scene_cloth_above(obj, res, CLOTH_SIZE, gap, &cloth, &err);
    if (st == CR_OK) {
        def.collider = obj;
        st = cr_sim_create(&def, cloth, &sim, &err);
    }
    if (st == CR_OK) st = cr_mkdir_p(out, &err);
    if (st == CR_OK) {
        snprintf(path, sizeof path, "%s/frames.jsonl", out);
        st = cr_scene_record_create(path, sim, cloth, max_frames + 2, &rec, &err);
    }
    cr_status solved = CR_OK;
    int settle_frames = 0;
    double seconds = 0.0, max_pen = 0.0;
    long long newton = 0;
    if (st == CR_OK) {
        double mass = 0.0;
        for (int32_t i = 0; i < cloth->nv; i++) mass += cr_sim_masses(sim)[i];
        cr_progress bar;
        cr_progress_begin(&bar, "drape-static", max_frames, quiet);
        /* Settle dynamically (damping and friction hold the cloth where it lands) until the
         * RMS speed drops below SETTLED_SPEED, then polish with a static solve. */
        while (settle_frames < max_frames) {
            solved = cr_sim_step(sim, &rep, &err);
            if (solved == CR_OK || solved == CR_ERR_DIVERGED)
                st = cr_scene_record_frame(rec, sim, &rep, &err);
            if (solved != CR_OK || st != CR_OK) break;
            settle_frames++;
            seconds += rep.seconds, newton += rep.newton_iterations;
            max_pen = fmax(max_pen, rep.max_penetration_m);
            double speed = sqrt(2.0 * rep.kinetic_energy / mass);
            cr_progress_update(&bar, settle_frames, "rms speed %.2g m/s", speed);
            if (speed < SETTLED_SPEED) break;
        }
        cr_progress_end(&bar);
        if (solved == CR_OK && st == CR_OK) {
            solved = cr_sim_solve_static(sim, &rep, &err);
            if (solved == CR_OK || solved == CR_ERR_DIVERGED)
                st = cr_scene_record_frame(rec, sim, &rep, &err);
            seconds += rep.seconds, newton += rep.newton_iterations;
            max_pen = fmax(max_pen, rep.max_penetration_m);
        }
        if (solved != CR_OK && solved != CR_ERR_DIVERGED && st == CR_OK) st = solved;
    }
    if (st == CR_OK && solved == CR_OK) {
        snprintf(obj_path, sizeof obj_path, "%s/final.obj", out);
        snprintf(png_path, sizeof png_path, "%s/final.png", out);
        snprintf(path, sizeof path, "%s/sim.pc2", out);
        st = cr_scene_record_mesh(rec, &final, &err);
        if (st == CR_OK) st = cr_mesh_write(obj_path, final, &err);
        if (st == CR_OK) st = cr_scene_record_write(rec, path, NULL, 1.0f, &err);
        if (st == CR_OK) st = cr_scene_render(png_path, final, NULL, obj, NULL, RENDER_SIZE, &err);
    }
    if (st == CR_OK && solved == CR_OK) {
        if (!quiet)
            fprintf(stderr, "drape-static: %d settling frames + static solve, %lld Newton "
                            "iterations, %.2f s, deepest %.3g mm\n",
                    settle_frames, newton, seconds, 1e3 * max_pen);
        if (json) {
            cJSON *j = cJSON_CreateObject();
            cJSON_AddStringToObject(j, "command", "drape-static");
            cJSON_AddStringToObject(j, "object", object);
            cJSON_AddNumberToObject(j, "res", res);
            cJSON_AddNumberToObject(j, "vertices", cloth->nv);
            cJSON_AddStringToObject(j, "material", def.material.name);
            cJSON_AddNumberToObject(j, "settle_frames", settle_frames);
            cJSON_AddBoolToObject(j, "converged", rep.newton_capped == 0);
            cJSON_AddNumberToObject(j, "max_penetration_m", max_pen);
            cJSON_AddNumberToObject(j, "newton_iterations", (double)newton);
            cJSON_AddNumberToObject(j, "contacts", rep.contacts);
            cJSON_AddNumberToObject(j, "seconds", seconds);
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
    if (st != CR_OK || solved != CR_OK) return cli_fail(&err);
    return CLI_OK;
}
