/* cmd_convert.c: `crease convert IN OUT`: mesh formats by extension, and a PC2
 * point cache plus its rest mesh into an animated glb. */
#include "cli.h"
#include "crease/mesh_io.h"

#include <string.h>

void help_convert(void) {
    printf("usage: crease convert IN OUT [--scale S] [--z-up] [--rest MESH] [--fps F] [--json]\n\n"
           "Convert a mesh between formats, chosen by extension:\n"
           "  IN:  .obj .ply .glb          OUT: .obj .ply .glb\n"
           "A point cache becomes an animated glb (morph targets) when its rest mesh is given:\n"
           "  crease convert sim.pc2 sim.glb --rest garment.obj\n\n"
           "options:\n"
           "  --scale S    multiply positions by S (a mesh in centimetres: 0.01; crease reads\n"
           "               metres)\n"
           "  --z-up       the mesh is Z-up: turn it to crease's Y-up, (x, y, z) -> (x, z, -y)\n"
           "  --rest MESH  the mesh whose vertices the .pc2 animates (same vertex order)\n"
           "  --fps F      frames per second of the animation (default 30)\n"
           "  --json       end with a JSON summary on stdout\n");
}

/* PC2 stores no frame rate (its sample rate counts frames between samples), so one is assumed. */
static const float DEFAULT_FPS = 30.0f;

static int convert_sequence(const char *in, const char *out, const char *rest_path, float fps,
                            cJSON *summary) {
    cr_error err = {0};
    char ext[16];
    cr_path_ext(out, ext, sizeof ext);
    if (!rest_path) return cli_usage("convert", "a .pc2 input needs --rest MESH");
    if (strcmp(ext, "glb") != 0)
        return cli_usage("convert", "a .pc2 input converts to .glb, not .%s", ext);
    cr_pc2 cache = {0};
    cr_mesh *rest = NULL;
    cr_status st = cr_pc2_read(in, &cache, &err);
    if (st == CR_OK) st = cr_mesh_read(rest_path, &rest, &err);
    if (st == CR_OK && rest->nv != cache.nv)
        st = CR_FAIL(&err, CR_ERR_SHAPE, "%s: has %d points but rest mesh %s has %d vertices", in,
                     cache.nv, rest_path, rest->nv);
    if (st == CR_OK) {
        if (fps <= 0) fps = DEFAULT_FPS;
        st = cr_glb_write_sequence(out, rest, cache.frames, cache.nframes, fps, &err);
    }
    if (st == CR_OK) {
        cJSON_AddNumberToObject(summary, "vertices", rest->nv);
        cJSON_AddNumberToObject(summary, "faces", rest->nf);
        cJSON_AddNumberToObject(summary, "frames", cache.nframes);
        cJSON_AddNumberToObject(summary, "fps", fps);
    }
    cr_pc2_free(&cache);
    cr_mesh_destroy(rest);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}

/* (x, y, z) -> (x, z, -y): a Z-up mesh stood up in crease's Y-up frame. */
static void z_up_to_y_up(cr_mesh *m) {
    for (int32_t v = 0; v < m->nv; v++) {
        float *p = &m->pos[3 * (size_t)v], y = p[1];
        p[1] = p[2], p[2] = -y;
        if (m->normal) {
            float *n = &m->normal[3 * (size_t)v], ny = n[1];
            n[1] = n[2], n[2] = -ny;
        }
    }
}

static int convert_mesh(const char *in, const char *out, float scale, int z_up, cJSON *summary) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    cr_status st = cr_mesh_read(in, &m, &err);
    if (st == CR_OK && z_up) z_up_to_y_up(m);
    if (st == CR_OK && scale != 1.0f) cr_mesh_transform(m, scale, (float[3]){0, 0, 0});
    if (st == CR_OK) st = cr_mesh_write(out, m, &err);
    if (st == CR_OK) {
        cJSON_AddNumberToObject(summary, "vertices", m->nv);
        cJSON_AddNumberToObject(summary, "faces", m->nf);
        cJSON_AddBoolToObject(summary, "has_uv", cr_mesh_has_uv(m));
    }
    cr_mesh_destroy(m);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}

int cmd_convert(int argc, char **argv) {
    const char *paths[2] = {NULL, NULL}, *rest = NULL;
    int npaths = 0, json = 0, z_up = 0;
    float fps = 0.0f, scale = 1.0f;
    const cli_opt opts[] = {
        CLI_FLAG("--json", &json),           CLI_STR("--rest", &rest),
        CLI_FLOAT("--fps", &fps, 1e-3, 1e4), CLI_FLOAT("--scale", &scale, 1e-6, 1e6),
        CLI_FLAG("--z-up", &z_up),           CLI_END,
    };
    int parsed = cli_parse("convert", argc, argv, opts, paths, 2, &npaths);
    if (parsed != CLI_OK) return parsed;
    if (npaths != 2) return cli_usage("convert", "expected IN and OUT");
    char ext[16];
    cr_path_ext(paths[0], ext, sizeof ext);
    cJSON *summary = cJSON_CreateObject();
    cJSON_AddStringToObject(summary, "command", "convert");
    cJSON_AddStringToObject(summary, "input", paths[0]);
    cJSON_AddStringToObject(summary, "output", paths[1]);
    if (strcmp(ext, "pc2") == 0 && (scale != 1.0f || z_up)) {
        cJSON_Delete(summary);
        return cli_usage("convert", "--scale and --z-up apply to meshes, not to a .pc2");
    }
    int rc = strcmp(ext, "pc2") == 0 ? convert_sequence(paths[0], paths[1], rest, fps, summary)
                                     : convert_mesh(paths[0], paths[1], scale, z_up, summary);
    if (rc == CLI_OK && json)
        cli_json_print(summary);
    else
        cJSON_Delete(summary);
    return rc;
}
