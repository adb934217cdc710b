/* cmd_body.c: `crease body`: build the procedural mannequin and write its
 * rest mesh (A-pose, +Y up, feet on y = 0, facing +Z). */
#include "cli.h"
#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/topology.h"

#include <string.h>

void help_body(void) {
    printf("usage: crease body [--shape slim|normal|heavy] [options] -o FILE\n\n"
           "Build the procedural mannequin: a watertight, smooth body in an A-pose on SMPL's\n"
           "22-joint skeleton, +Y up, soles on y = 0, facing +Z, with skinning weights.\n"
           "FILE is .obj or .ply (the rest mesh with normals), or .glb: the mannequin as a\n"
           "skinned character (named joints, skin, a one-frame animation at the rest pose).\n\n"
           "options:\n"
           "  --shape NAME     preset: slim, normal (default) or heavy; the options below\n"
           "                   override it\n"
           "  --height M       top of the head above the soles, m, 1 to 2.5 (default 1.75)\n"
           "  --girth F        scale of every limb and torso radius, 0.6 to 1.6\n"
           "  --chest F        extra scale of the chest, 0.7 to 1.5\n"
           "  --hips F         extra scale of the hips and buttocks, 0.7 to 1.5\n"
           "  --arm-angle DEG  arms below horizontal in the rest pose, 0 to 80 (default 40)\n"
           "  --res N          grid cells over the height, 32 to 512 (default 110, about\n"
           "                   9.5k vertices; vertices grow as N^2)\n"
           "  -o FILE          output mesh (required)\n"
           "  --json           end with a JSON summary on stdout: vertices, faces, height_m,\n"
           "                   watertight, output, seconds\n");
}

/* Options that override the preset, applied after it whatever their order. */
typedef struct body_overrides {
    float height, girth, chest, hips, arm;
    int res;
    int set; /* bit per field above, in that order */
} body_overrides;

static void apply_overrides(const body_overrides *o, cr_mannequin_def *def) {
    if (o->set & 1) def->height_m = o->height;
    if (o->set & 2) def->girth = o->girth;
    if (o->set & 4) def->chest = o->chest;
    if (o->set & 8) def->hips = o->hips;
    if (o->set & 16) def->arm_angle_deg = o->arm;
    if (o->set & 32) def->resolution = o->res;
}

int cmd_body(int argc, char **argv) {
    const char *shape = "normal", *out_path = NULL;
    body_overrides ov = {0};
    int json = 0, npos = 0;
    int seen[6] = {0};
    const cli_opt opts[] = {
        CLI_FLAG("--json", &json),
        CLI_STR("--shape", &shape),
        CLI_OUTPUT(&out_path),
        {.name = "--height",
         .kind = CLI_OPT_FLOAT,
         .dst = &ov.height,
         .lo = 1.0,
         .hi = 2.5,
         .seen = &seen[0]},
        {.name = "--girth",
         .kind = CLI_OPT_FLOAT,
         .dst = &ov.girth,
         .lo = 0.6,
         .hi = 1.6,
         .seen = &seen[1]},
        {.name = "--chest",
         .kind = CLI_OPT_FLOAT,
         .dst = &ov.chest,
         .lo = 0.7,
         .hi = 1.5,
         .seen = &seen[2]},
        {.name = "--hips",
         .kind = CLI_OPT_FLOAT,
         .dst = &ov.hips,
         .lo = 0.7,
         .hi = 1.5,
         .seen = &seen[3]},
        {.name = "--arm-angle",
         .kind = CLI_OPT_FLOAT,
         .dst = &ov.arm,
         .lo = 0.0,
         .hi = 80.0,
         .seen = &seen[4]},
        {.name = "--res",
         .kind = CLI_OPT_INT,
         .dst = &ov.res,
         .lo = 32,
         .hi = 512,
         .seen = &seen[5]},
        CLI_END,
    };
    int rc = cli_parse("body", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    for (int i = 0; i < 6; i++)
        ov.set |= seen[i] << i;
    if (!out_path) return cli_usage("body", "missing -o FILE");
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    if (cr_mannequin_preset(shape, &def, &err) != CR_OK) return cli_usage("body", "%s", err.msg);
    apply_overrides(&ov, &def);

    double t0 = cr_time_now();
    cr_body_model *b = NULL;
    if (cr_mannequin_create(&def, &b, &err) != CR_OK) return cli_fail(&err);
    double seconds = cr_time_now() - t0;
    cr_topology *t = NULL;
    cr_status st = cr_topology_build(b->rest, &t, &err);
    int watertight = st == CR_OK && t->n_boundary_edges == 0 &&
                     cr_topology_require_manifold(t, "body", NULL) == CR_OK;
    cr_topology_destroy(t);
    char ext[16];
    cr_path_ext(out_path, ext, sizeof ext);
    if (st == CR_OK && strcmp(ext, "glb") == 0) {
        cr_motion *rest = NULL; /* one frame, every rotation zero: the rest pose */
        st = cr_motion_create(1, 30.0f, &rest, &err);
        if (st == CR_OK) st = cr_body_write_glb(out_path, b, rest, NULL, NULL, &err);
        cr_motion_destroy(rest);
    } else if (st == CR_OK) {
        st = cr_mesh_write(out_path, b->rest, &err);
    }
    if (st != CR_OK) {
        cr_body_model_destroy(b);
        return cli_fail(&err);
    }
    float lo[3], hi[3];
    cr_mesh_bounds(b->rest, lo, hi);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "body");
        cJSON_AddStringToObject(j, "shape", shape);
        cJSON_AddNumberToObject(j, "vertices", b->rest->nv);
        cJSON_AddNumberToObject(j, "faces", b->rest->nf);
        cJSON_AddNumberToObject(j, "height_m", hi[1] - lo[1]);
        cJSON_AddBoolToObject(j, "watertight", watertight);
        cJSON_AddStringToObject(j, "output", out_path);
        cJSON_AddNumberToObject(j, "seconds", seconds);
        cli_json_print(j);
    } else {
        fprintf(stderr, "body: %s, %d vertices, %d faces, %.3f m tall, %s, %.2f s, written to %s\n",
                shape, b->rest->nv, b->rest->nf, (double)(hi[1] - lo[1]),
                watertight ? "watertight" : "NOT watertight", seconds, out_path);
    }
    cr_body_model_destroy(b);
    return CLI_OK;
}
