/* cmd_primitive.c: `crease primitive KIND [size options] -o FILE`: write a primitive mesh with UVs.
 */
#include "cli.h"
#include "crease/mesh_io.h"
#include "crease/primitives.h"

#include <string.h>

void help_primitive(void) {
    printf("usage: crease primitive KIND [options] -o FILE\n\n"
           "Write a primitive mesh with UVs, centred at the origin, Y up. FILE is .obj, .ply or "
           ".glb.\n\n"
           "kinds and the options they use:\n"
           "  plane      --res N (vertices per side, default 32), --size S (m, default 1)\n"
           "  sphere     --radius R (0.3), --res N (segments; rings = N/2; default 64)\n"
           "  icosphere  --radius R (0.3), --subdiv K (4)\n"
           "  torus      --radius R (0.3), --minor r (0.1), --res N (major segments; minor = N/2; "
           "64)\n"
           "  prism      --size S (side, 0.4), --length L (0.8)\n"
           "  box        --size S (edge, 0.4), --subdiv K (per face, 8)\n"
           "  capsule    --radius R (0.1), --length L (cylinder part, 0.3), --res N (32)\n"
           "  cylinder   --radius R (0.2), --length L (height, 0.5), --res N (32), --open\n\n"
           "options:\n"
           "  -o FILE    output mesh (required)\n"
           "  --json     end with a JSON summary on stdout\n");
}

typedef struct {
    const char *kind;
    float radius, minor, size, length;
    int res, subdiv, open, res_set;
} prim_opts;

static cr_status make_primitive(const prim_opts *o, cr_mesh **m, cr_error *err) {
    const char *k = o->kind;
    int res = o->res;
    if (strcmp(k, "plane") == 0) return cr_prim_plane(res, res, o->size, o->size, m, err);
    if (strcmp(k, "sphere") == 0) return cr_prim_sphere_uv(o->radius, res, res / 2, m, err);
    if (strcmp(k, "icosphere") == 0) return cr_prim_icosphere(o->radius, o->subdiv, m, err);
    if (strcmp(k, "torus") == 0) return cr_prim_torus(o->radius, o->minor, res, res / 2, m, err);
    if (strcmp(k, "prism") == 0) return cr_prim_prism(o->size, o->length, m, err);
    if (strcmp(k, "box") == 0) return cr_prim_box(o->size, o->size, o->size, o->subdiv, m, err);
    if (strcmp(k, "capsule") == 0)
        return cr_prim_capsule(o->radius, o->length, res, res / 2, m, err);
    if (strcmp(k, "cylinder") == 0)
        return cr_prim_cylinder(o->radius, o->length, res, res / 4 > 1 ? res / 4 : 1, !o->open, m,
                                err);
    return CR_FAIL(err, CR_ERR_INVALID, "unknown primitive '%s'", k);
}

/* Defaults per kind, applied before the user's options override them. */
static void kind_defaults(prim_opts *o) {
    const char *k = o->kind;
    o->radius = 0.3f, o->minor = 0.1f, o->size = 0.4f, o->length = 0.8f;
    o->res = 64, o->subdiv = 4;
    if (strcmp(k, "plane") == 0) o->size = 1.0f, o->res = 32;
    if (strcmp(k, "box") == 0) o->subdiv = 8;
    if (strcmp(k, "capsule") == 0) o->radius = 0.1f, o->length = 0.3f, o->res = 32;
    if (strcmp(k, "cylinder") == 0) o->radius = 0.2f, o->length = 0.5f, o->res = 32;
}

int cmd_primitive(int argc, char **argv) {
    static const char *const kinds[] = {"plane", "sphere", "icosphere", "torus",
                                        "prism", "box",    "capsule",   "cylinder"};
    prim_opts o = {0};
    const char *out_path = NULL;
    int json = 0;
    /* The kind comes first so its defaults can be set before options override them. */
    const char *kind = argc > 1 ? argv[1] : NULL;
    if (!kind) return cli_usage("primitive", "missing KIND");
    for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++)
        if (strcmp(kind, kinds[i]) == 0) o.kind = kinds[i];
    if (!o.kind) return cli_usage("primitive", "unknown primitive '%s'", kind);
    kind_defaults(&o);
    const cli_opt opts[] = {
        CLI_FLAG("--json", &json),
        CLI_FLAG("--open", &o.open),
        CLI_OUTPUT(&out_path),
        CLI_FLOAT("--radius", &o.radius, 1e-6, 1e6),
        CLI_FLOAT("--minor", &o.minor, 1e-6, 1e6),
        CLI_FLOAT("--size", &o.size, 1e-6, 1e6),
        CLI_FLOAT("--length", &o.length, 1e-6, 1e6),
        CLI_INT("--res", &o.res, 2, 4096),
        CLI_INT("--subdiv", &o.subdiv, 0, 9),
        CLI_END,
    };
    /* argv + 1: KIND stands where the command's name would; no more positionals. */
    int npos = 0;
    int rc = cli_parse("primitive", argc - 1, argv + 1, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!out_path) return cli_usage("primitive", "missing -o FILE");
    cr_error err = {0};
    cr_mesh *m = NULL;
    if (make_primitive(&o, &m, &err) != CR_OK) return cli_fail(&err);
    cr_status st = cr_mesh_write(out_path, m, &err);
    if (st == CR_OK && json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "primitive");
        cJSON_AddStringToObject(j, "kind", o.kind);
        cJSON_AddNumberToObject(j, "vertices", m->nv);
        cJSON_AddNumberToObject(j, "faces", m->nf);
        cJSON_AddNumberToObject(j, "uvs", m->nuv);
        cJSON_AddStringToObject(j, "output", out_path);
        cli_json_print(j);
    }
    cr_mesh_destroy(m);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}
