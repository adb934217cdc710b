/* cmd_drape_static.c: `crease drape-static`: the quasi-static equilibrium of
 * a 1 m square cloth laid flat above an object, the reference the drape
 * method is compared with: parse, one library call (cr_scene_drape_static,
 * crease/scene.h), report. */
#include "cli.h"
#include "crease/phys_sim.h"
#include "crease/scene.h"

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
           "  --json               end with a JSON summary on stdout\n"
           "  --solver S           newton (default: Newton + CHOLMOD, the converged reference)\n"
           "                       or vbd (vertex block descent, no "
           "factorisation)\n" CLI_SELF_CONTACT_HELP);
}

int cmd_drape_static(int argc, char **argv) {
    const char *object = NULL, *material = "cotton", *material_json = NULL, *out = NULL;
    const char *solver = NULL, *self_contact = NULL;
    float self_contact_thickness = 0.0f;
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
        CLI_CHOICE("--solver", &solver, cli_solvers),
        CLI_SELF_CONTACT_OPTS(&self_contact, &self_contact_thickness),
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
    cr_material m;
    if (cr_material_preset(material, &m, &err) != CR_OK)
        return cli_usage("drape-static", "%s", err.msg);
    cr_scene_drape_static_def def = cr_scene_drape_static_default_def();
    def.object = object, def.res = res, def.size = CLOTH_SIZE, def.gap = gap;
    def.material = material, def.material_json = material_json;
    def.max_frames = max_frames, def.coarse = coarse;
    def.solver = cr_sim_solver_parse(solver ? solver : "newton");
    def.self_contact = cli_self_contact(self_contact);
    def.self_thickness = self_contact_thickness;
    def.out_dir = out, def.render_size = RENDER_SIZE, def.quiet = quiet;
    cr_scene_drape_static_result r;
    if (cr_scene_drape_static(&def, &r, &err) != CR_OK) return cli_fail(&err);
    const cr_scene_settle_stats *stats = &r.settle;
    if (!quiet)
        fprintf(stderr,
                "drape-static: %d settling frames + static solve, %lld Newton "
                "iterations, %.2f s, deepest %.3g mm\n",
                stats->settle_frames, stats->newton, stats->seconds,
                1e3 * stats->max_penetration_m);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "drape-static");
        cJSON_AddStringToObject(j, "object", object);
        cJSON_AddNumberToObject(j, "res", res);
        cJSON_AddNumberToObject(j, "vertices", r.vertices);
        cJSON_AddStringToObject(j, "material", r.material);
        if (coarse > 0) cJSON_AddNumberToObject(j, "coarse", coarse);
        cJSON_AddNumberToObject(j, "settle_frames", stats->settle_frames);
        cJSON_AddBoolToObject(j, "converged", stats->converged);
        cJSON_AddNumberToObject(j, "max_penetration_m", stats->max_penetration_m);
        cJSON_AddNumberToObject(j, "newton_iterations", (double)stats->newton);
        cJSON_AddNumberToObject(j, "contacts", stats->contacts);
        cJSON_AddNumberToObject(j, "seconds", stats->seconds);
        cJSON *o = cJSON_AddObjectToObject(j, "outputs");
        cJSON_AddStringToObject(o, "obj", r.obj);
        cJSON_AddStringToObject(o, "png", r.png);
        cJSON_AddStringToObject(o, "log", r.log);
        cli_json_print(j);
    }
    return CLI_OK;
}
