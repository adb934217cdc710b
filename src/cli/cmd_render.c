/* cmd_render.c: `crease render MESH... -o out.png`: shaded pictures of one or
 * more meshes, with wireframe, a per-vertex colour map and turntables; a
 * mesh followed by `--pc2 SEQ.pc2` is drawn at frame `--frame N` of that
 * point cache (a simulated garment, a posed body). */
#include "cli.h"
#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "crease/render.h"
#include "crease/topology.h"

#include <stdlib.h>
#include <string.h>

enum { MAX_OBJECTS = 16 };

/* Object colours in order: cloth blue first, then a neutral grey for the body or object. */
static const float palette[][3] = {
    {0.33f, 0.52f, 0.80f}, {0.72f, 0.72f, 0.70f}, {0.85f, 0.55f, 0.30f},
    {0.45f, 0.70f, 0.45f}, {0.75f, 0.45f, 0.65f}, {0.80f, 0.75f, 0.40f},
};
enum { PALETTE_SIZE = sizeof palette / sizeof palette[0] };

void help_render(void) {
    printf("usage: crease render MESH... -o OUT.png [options]\n\n"
           "Render meshes (.obj, .ply, .glb) into one PNG with an automatically framed camera.\n"
           "The first mesh is drawn in cloth blue, the next ones in other colours.\n\n"
           "options:\n"
           "  -o OUT.png           output picture (required)\n"
           "  --size N             width and height in pixels (default 1024)\n"
           "  --ss N               supersampling per axis, 1..8 (default 2)\n"
           "  --wire               overlay the wireframe\n"
           "  --color-by KIND      colour the meshes by a per-vertex scalar: curvature (mean\n"
           "                       curvature magnitude, 1/m) or height (y, m)\n"
           "  --range LO HI        fixed colour-map range (default: the scalars' min and max)\n"
           "  --yaw D, --pitch D   camera orbit in degrees (default 30 and 25)\n"
           "  --turntable N        write N pictures OUT_000.png ... circling the scene\n"
           "  --pc2 SEQ.pc2        (after a mesh) draw that mesh with the positions of a PC2\n"
           "                       point cache of the same vertex count\n"
           "  --frame N            the point caches' frame, from 0 (default 0)\n"
           "  --json               end with a JSON summary on stdout\n");
}

typedef struct {
    const char *meshes[MAX_OBJECTS];
    const char *pc2[MAX_OBJECTS]; /* NULL: the mesh's own positions */
    int frame;
    int nmesh;
    const char *out;
    const char *color_by;
    int size, ss, wire, turntable, json, fixed_range;
    float yaw, pitch, range_lo, range_hi;
} render_opts;

/* --range LO HI: two numbers, LO < HI. */
static int parse_range(const char *cmd, const char *opt, const char *const *v, void *dst) {
    render_opts *o = dst;
    if (!cli_parse_float(cmd, opt, v[0], -1e30, 1e30, &o->range_lo) ||
        !cli_parse_float(cmd, opt, v[1], -1e30, 1e30, &o->range_hi))
        return CLI_USAGE;
    if (!(o->range_lo < o->range_hi)) return cli_usage(cmd, "--range LO HI needs LO < HI");
    o->fixed_range = 1;
    return CLI_OK;
}

/* --pc2 SEQ: the positions of the mesh given just before it. */
static int parse_pc2(const char *cmd, const char *opt, const char *const *v, void *dst) {
    render_opts *o = dst;
    if (o->nmesh == 0) return cli_usage(cmd, "%s %s must follow its mesh", opt, v[0]);
    o->pc2[o->nmesh - 1] = v[0];
    return CLI_OK;
}

static int parse(int argc, char **argv, render_opts *o) {
    static const char *const color_kinds[] = {"curvature", "height", NULL};
    const cli_opt opts[] = {
        CLI_FLAG("--json", &o->json),
        CLI_FLAG("--wire", &o->wire),
        CLI_OUTPUT(&o->out),
        CLI_CHOICE("--color-by", &o->color_by, color_kinds),
        CLI_INT("--size", &o->size, 16, 8192),
        CLI_INT("--ss", &o->ss, 1, 8),
        CLI_INT("--turntable", &o->turntable, 1, 3600),
        CLI_FLOAT("--yaw", &o->yaw, -1e4, 1e4),
        CLI_FLOAT("--pitch", &o->pitch, -89, 89),
        CLI_CUSTOM("--range", parse_range, o, 2),
        CLI_CUSTOM("--pc2", parse_pc2, o, 1),
        CLI_INT("--frame", &o->frame, 0, 100000000),
        CLI_END,
    };
    int rc = cli_parse("render", argc, argv, opts, o->meshes, MAX_OBJECTS, &o->nmesh);
    if (rc != CLI_OK) return rc;
    if (o->nmesh == 0) return cli_usage("render", "missing MESH");
    if (!o->out) return cli_usage("render", "missing -o OUT.png");
    return CLI_OK;
}

/* Per-vertex scalar for the colour map: (V) floats, heap-allocated. */
static cr_status vertex_scalar(const cr_mesh *m, const char *kind, float **out, cr_error *err) {
    float *s = cr_malloc((size_t)m->nv * sizeof(float) + 1, err);
    if (!s) return CR_ERR_MEMORY;
    cr_status st = CR_OK;
    if (strcmp(kind, "height") == 0) {
        for (int32_t i = 0; i < m->nv; i++)
            s[i] = m->pos[3 * i + 1];
    } else {
        cr_topology *t = NULL;
        st = cr_topology_build(m, &t, err);
        if (st == CR_OK) st = cr_mesh_mean_curvature(m, t, s, err);
        cr_topology_destroy(t);
    }
    if (st != CR_OK) {
        free(s);
        return st;
    }
    *out = s;
    return CR_OK;
}

/* The mesh's positions <- frame `frame` of the point cache at path. */
static cr_status pose_from_pc2(cr_mesh *m, const char *path, int frame, cr_error *err) {
    cr_pc2 seq = {0};
    CR_TRY(cr_pc2_read(path, &seq, err));
    cr_status st = CR_OK;
    if (seq.nv != m->nv)
        st = CR_FAIL(err, CR_ERR_INVALID, "%s: %d points per frame, but its mesh has %d vertices",
                     path, seq.nv, m->nv);
    else if (frame >= seq.nframes)
        st = CR_FAIL(err, CR_ERR_INVALID, "%s: no frame %d (it has %d, from 0)", path, frame,
                     seq.nframes);
    else
        memcpy(m->pos, seq.frames + (size_t)frame * 3 * (size_t)m->nv,
               3 * (size_t)m->nv * sizeof(float));
    cr_pc2_free(&seq);
    return st;
}

/* "dir/name.png" -> "dir/name_%03d.png" for the turntable frames. */
static void frame_pattern(const char *out, char *pattern, size_t cap) {
    const char *dot = strrchr(out, '.');
    const char *slash = strrchr(out, '/');
    if (!dot || (slash && dot < slash)) dot = out + strlen(out);
    snprintf(pattern, cap, "%.*s_%%03d%s", (int)(dot - out), out, *dot ? dot : ".png");
}

int cmd_render(int argc, char **argv) {
    render_opts o = {.size = 1024, .ss = 2, .yaw = 30.0f, .pitch = 25.0f};
    int rc = parse(argc, argv, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    cr_mesh *meshes[MAX_OBJECTS] = {0};
    float *scalars[MAX_OBJECTS] = {0};
    cr_render_object objs[MAX_OBJECTS];
    cr_status st = CR_OK;
    int64_t faces = 0;
    for (int i = 0; i < o.nmesh && st == CR_OK; i++) {
        st = cr_mesh_read(o.meshes[i], &meshes[i], &err);
        if (st == CR_OK && o.pc2[i]) st = pose_from_pc2(meshes[i], o.pc2[i], o.frame, &err);
        if (st == CR_OK && o.color_by) st = vertex_scalar(meshes[i], o.color_by, &scalars[i], &err);
        if (st != CR_OK) break;
        faces += meshes[i]->nf;
        objs[i] = (cr_render_object){.mesh = meshes[i], .scalar = scalars[i]};
        memcpy(objs[i].color, palette[i % PALETTE_SIZE], sizeof objs[i].color);
    }
    cr_render_def def = cr_render_default_def();
    def.width = def.height = o.size;
    def.supersample = o.ss;
    def.yaw_deg = o.yaw;
    def.pitch_deg = o.pitch;
    def.wireframe = o.wire;
    if (o.fixed_range) {
        def.colormap_auto = 0;
        def.colormap_min = o.range_lo;
        def.colormap_max = o.range_hi;
    }
    char pattern[1100];
    double t0 = cr_time_now();
    if (st == CR_OK) {
        if (o.turntable > 0) {
            frame_pattern(o.out, pattern, sizeof pattern);
            st = cr_render_turntable(&def, objs, o.nmesh, o.turntable, pattern, &err);
        } else {
            st = cr_render_to_png(&def, objs, o.nmesh, o.out, &err);
        }
    }
    double seconds = cr_time_now() - t0;
    if (st == CR_OK && o.json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "render");
        cJSON *in = cJSON_AddArrayToObject(j, "inputs");
        for (int i = 0; i < o.nmesh; i++)
            cJSON_AddItemToArray(in, cJSON_CreateString(o.meshes[i]));
        cJSON_AddNumberToObject(j, "faces", (double)faces);
        cJSON_AddNumberToObject(j, "width", o.size);
        cJSON_AddNumberToObject(j, "height", o.size);
        cJSON_AddNumberToObject(j, "frames", o.turntable > 0 ? o.turntable : 1);
        cJSON_AddStringToObject(j, "output", o.turntable > 0 ? pattern : o.out);
        cJSON_AddNumberToObject(j, "seconds", seconds);
        cli_json_print(j);
    }
    for (int i = 0; i < o.nmesh; i++) {
        cr_mesh_destroy(meshes[i]);
        free(scalars[i]);
    }
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}
