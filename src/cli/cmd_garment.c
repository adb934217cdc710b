/* cmd_garment.c: `crease garment`: a procedural garment (or layers of them,
 * or a user's garment file) fitted to the mannequin's rest pose, written as
 * a mesh with UVs, optionally pictured on the body. */
#include "cli.h"
#include "crease/body.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/render.h"

#include <stdlib.h>
#include <string.h>

enum { MAX_LAYERS = 4 };

void help_garment(void) {
    printf(
        "usage: crease garment --type TYPE[,TYPE...] [options] -o FILE\n"
        "       crease garment --type TYPE --random [--seed N] [options] -o FILE\n"
        "       crease garment --user GARMENT.obj [options] -o FILE\n\n"
        "Build a garment fitted to the procedural mannequin's rest pose: a manifold mesh with\n"
        "openings, outward normals, good triangles (at least 99%% with every angle above 20\n"
        "degrees), at least 5 mm outside the body, UV charts per panel (front, back, sleeve\n"
        "halves, trouser quarters) and skinning weights. FILE is .obj, .ply or .glb.\n\n"
        "options:\n"
        "  --type TYPE      tshirt, longsleeve, skirt, dress, trousers, vest or jumpsuit; a list\n"
        "                   builds layers worn over each other, innermost first (e.g.\n"
        "                   tshirt,vest), written as FILE with _TYPE before the extension\n"
        "  --user FILE      check a garment mesh (manifold, orientation, UVs if any, size\n"
        "                   in metres, placed on the body) and push it out of the body\n"
        "  --res N          target vertex count, 500 to 100000 (default 8000); met within\n"
        "                   15%% from 2k to 40k\n"
        "  --shape NAME     body preset: slim, normal (default) or heavy\n"
        "  --height M       body height, m, 1 to 2.5 (default 1.75)\n"
        "  --body-res N     mannequin grid cells over the height, 32 to 512 (default 110)\n"
        "  --grid M         level-set grid cell, m, 0.004 to 0.03 (default 0.01)\n"
        "  --random         draw the shape parameters of one --type (uniform in each one's\n"
        "                   sampled range, docs/garments.md); a draw failing the quality\n"
        "                   checks is replaced by the next (at most 8); named parameters\n"
        "                   below override the drawn values\n"
        "  --seed N         the draw, 0 to 2147483647 (default 1; needs --random)\n"
        "  -o FILE          output mesh (required)\n"
        "  --render PNG     picture of the garment on the body\n"
        "  --size N         picture size in pixels (default 720)\n"
        "  --yaw D          camera yaw in degrees (default 30)\n"
        "  --clip NAME      pose body and garment (linear blend skinning) at a frame of a\n"
        "                   procedural clip for the picture (walk, run, ...)\n"
        "  --frame N        the clip's frame (default 15)\n"
        "  --json           end with a JSON summary on stdout: type, vertices, faces,\n"
        "                   share_min_angle_above_20deg, min_angle_deg, min_clearance_m,\n"
        "                   boundary_loops, panels, uv_scale_m, paths, seconds, params and\n"
        "                   spec (the exact variant); with --random also seed, attempts and\n"
        "                   rejected (why the last rejected draw failed); layers for a list\n\n"
        "shape parameters (accepted range; the defaults per type rebuild the plain types;\n"
        "a layer list raises each layer's clearance to clear the one below):\n");
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
        const cr_garment_param *p = cr_garment_param_at(i);
        printf("  --%-10s %g to %g %s: %s\n", p->key, p->lo, p->hi, p->unit, p->help);
    }
}

typedef struct garment_opts {
    const char *types, *user, *out, *render, *shape, *clip;
    int res, size, frame, json, body_res, random, seed;
    float height, grid, yaw;
    float param[CR_GARMENT_NPARAMS];
    int set_param[CR_GARMENT_NPARAMS], set_grid, set_height, set_seed;
} garment_opts;

static int parse(int argc, char **argv, garment_opts *o) {
    int npos = 0;
    const cli_opt fixed[] = {
        CLI_FLAG("--json", &o->json),
        CLI_STR("--type", &o->types),
        CLI_STR("--user", &o->user),
        CLI_OUTPUT(&o->out),
        CLI_STR("--render", &o->render),
        CLI_STR("--shape", &o->shape),
        CLI_STR("--clip", &o->clip),
        CLI_INT("--res", &o->res, 500, 100000),
        CLI_INT("--body-res", &o->body_res, 32, 512),
        CLI_INT("--size", &o->size, 16, 8192),
        CLI_INT("--frame", &o->frame, 0, 100000),
        CLI_FLOAT("--yaw", &o->yaw, -1e4, 1e4),
        CLI_FLAG("--random", &o->random),
        {.name = "--seed",
         .kind = CLI_OPT_INT,
         .dst = &o->seed,
         .lo = 0,
         .hi = 2147483647.0,
         .seen = &o->set_seed},
        {.name = "--grid",
         .kind = CLI_OPT_FLOAT,
         .dst = &o->grid,
         .lo = 0.004,
         .hi = 0.03,
         .seen = &o->set_grid},
        {.name = "--height",
         .kind = CLI_OPT_FLOAT,
         .dst = &o->height,
         .lo = 1.0,
         .hi = 2.5,
         .seen = &o->set_height},
    };
    /* The shape parameters' rows come from the library's table. */
    enum { NFIXED = sizeof fixed / sizeof fixed[0] };
    static char names[CR_GARMENT_NPARAMS][32];
    cli_opt opts[NFIXED + CR_GARMENT_NPARAMS + 1];
    memcpy(opts, fixed, sizeof fixed);
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
        const cr_garment_param *p = cr_garment_param_at(i);
        snprintf(names[i], sizeof names[i], "--%s", p->key);
        opts[NFIXED + i] = (cli_opt){.name = names[i],
                                     .kind = CLI_OPT_FLOAT,
                                     .dst = &o->param[i],
                                     .lo = p->lo,
                                     .hi = p->hi,
                                     .seen = &o->set_param[i]};
    }
    opts[NFIXED + CR_GARMENT_NPARAMS] = (cli_opt)CLI_END;
    int rc = cli_parse("garment", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->out) return cli_usage("garment", "missing -o FILE");
    if (!o->types == !o->user) return cli_usage("garment", "give one of --type or --user");
    if (o->set_seed && !o->random) return cli_usage("garment", "--seed needs --random");
    if (o->random && (o->user || strchr(o->types, ',')))
        return cli_usage("garment", "--random makes one --type, not a layer list or --user");
    return CLI_OK;
}

/* path with "_suffix" before its extension. */
static void layer_path(const char *path, const char *suffix, char *out, size_t cap) {
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - path) : strlen(path);
    snprintf(out, cap, "%.*s_%s%s", (int)stem, path, suffix, path + stem);
}

/* The picture: body grey, garments in cloth colours, posed at a clip frame
 * when asked. */
static cr_status render(const garment_opts *o, const cr_body_model *body, cr_garment **g, int n,
                        cr_error *err) {
    static const float colors[MAX_LAYERS][3] = {
        {0.33f, 0.52f, 0.80f}, {0.80f, 0.45f, 0.30f}, {0.45f, 0.70f, 0.45f}, {0.80f, 0.75f, 0.40f}};
    cr_mesh *posed[MAX_LAYERS + 1] = {0};
    cr_render_object obj[MAX_LAYERS + 1];
    cr_motion *mo = NULL;
    cr_status st = CR_OK;
    if (o->clip) st = cr_motion_clip(o->clip, o->frame + 1, 30.0f, &mo, err);
    for (int i = 0; i <= n && st == CR_OK; i++) {
        const cr_mesh *rest = i == 0 ? body->rest : g[i - 1]->mesh;
        st = cr_mesh_clone(rest, &posed[i], err);
        if (st == CR_OK && mo) {
            const float *pose = &mo->poses[(size_t)o->frame * CR_NJOINTS * 3];
            const float *trans = &mo->trans[(size_t)o->frame * 3];
            st = i == 0 ? cr_body_pose(body, pose, trans, posed[i]->pos, err)
                        : cr_garment_pose(g[i - 1], body, pose, trans, posed[i]->pos, err);
        }
        if (st == CR_OK) {
            /* Rendering computes its own normals from the posed positions. */
            free(posed[i]->normal);
            posed[i]->normal = NULL;
            obj[i] = (cr_render_object){.mesh = posed[i]};
            const float grey[3] = {0.72f, 0.72f, 0.70f};
            memcpy(obj[i].color, i == 0 ? grey : colors[(i - 1) % MAX_LAYERS], sizeof obj[i].color);
        }
    }
    if (st == CR_OK) {
        cr_render_def def = cr_render_default_def();
        def.width = def.height = o->size;
        def.yaw_deg = o->yaw;
        def.pitch_deg = 10.0f;
        st = cr_render_to_png(&def, obj, n + 1, o->render, err);
    }
    for (int i = 0; i <= n; i++)
        cr_mesh_destroy(posed[i]);
    cr_motion_destroy(mo);
    return st;
}

static cJSON *quality_json(const cr_garment *g, const cr_garment_quality *q, const char *path) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "type", cr_garment_type_name(g->type));
    cJSON_AddNumberToObject(j, "vertices", q->vertices);
    cJSON_AddNumberToObject(j, "faces", q->faces);
    cJSON_AddNumberToObject(j, "share_min_angle_above_20deg", q->share_min_angle_above_20deg);
    cJSON_AddNumberToObject(j, "min_angle_deg", q->min_angle_deg);
    cJSON_AddNumberToObject(j, "min_clearance_m", q->min_clearance_m);
    cJSON_AddNumberToObject(j, "boundary_loops", q->boundary_loops);
    cJSON_AddNumberToObject(j, "panels", q->panels);
    cJSON_AddNumberToObject(j, "uv_scale_m", g->uv_scale_m);
    cJSON_AddStringToObject(j, "path", path);
    return j;
}

/* One --random variant: drawn, checked, instantiated at --res. */
static cr_status build_random(const garment_opts *o, const cr_body_model *body, cr_garment **g,
                              cr_garment_variant *v, int *usage, cr_error *err) {
    if (cr_garment_variant_parse(o->types, v, err) != CR_OK) {
        *usage = 1;
        return CR_ERR_INVALID;
    }
    v->random = 1, v->seed = (uint64_t)o->seed;
    v->def.target_vertices = o->res;
    if (o->set_grid) v->def.grid_m = o->grid;
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        if (o->set_param[i]) {
            CR_TRY(cr_garment_param_set(&v->def, cr_garment_param_at(i)->key, o->param[i], err));
            v->given |= 1u << i;
        }
    cr_garment_template *t = NULL;
    CR_TRY(cr_garment_variant_build(v, body, &t, err));
    cr_status st = cr_garment_template_instantiate(t, o->res, body, g, err);
    cr_garment_template_destroy(t);
    return st;
}

/* Build (or load) the garments into g; n of them; defs_out (n) the defs
 * built (not for --user). */
static cr_status build(const garment_opts *o, const cr_body_model *body, cr_garment **g, int *n,
                       cr_garment_def *defs, cr_garment_variant *v, int *usage, cr_error *err) {
    if (o->user) {
        cr_garment_user_def ud = cr_garment_user_default_def();
        int ic = cr_garment_param_find("clearance");
        if (o->set_param[ic]) ud.clearance_m = o->param[ic];
        *n = 1;
        return cr_garment_load_user(o->user, &ud, body, &g[0], err);
    }
    if (o->random) {
        *n = 1;
        cr_status st = build_random(o, body, g, v, usage, err);
        defs[0] = v->def;
        return st;
    }
    char list[256];
    snprintf(list, sizeof list, "%s", o->types);
    *n = 0;
    for (char *save = NULL, *tok = strtok_r(list, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        cr_garment_type type;
        if (*n == MAX_LAYERS || cr_garment_type_parse(tok, &type, err) != CR_OK) {
            if (*n == MAX_LAYERS)
                CR_FAIL(err, CR_ERR_INVALID, "garment: at most %d layers", MAX_LAYERS);
            *usage = 1;
            return CR_ERR_INVALID;
        }
        cr_garment_def d = cr_garment_default_def(type);
        d.target_vertices = o->res;
        for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
            if (o->set_param[i])
                CR_TRY(cr_garment_param_set(&d, cr_garment_param_at(i)->key, o->param[i], err));
        if (o->set_grid) d.grid_m = o->grid;
        /* Each layer clears the one below by at least the layer gap. */
        if (*n > 0 && d.clearance_m < defs[*n - 1].clearance_m + CR_GARMENT_LAYER_GAP)
            d.clearance_m = defs[*n - 1].clearance_m + CR_GARMENT_LAYER_GAP;
        defs[(*n)++] = d;
    }
    if (*n == 0) {
        *usage = 1;
        return CR_FAIL(err, CR_ERR_INVALID, "garment: --type names no type");
    }
    return cr_garment_create_layers(defs, *n, body, g, err);
}

/* The parameters a garment was built with and its exact spec. */
static void params_json(cJSON *j, const cr_garment_def *d) {
    cJSON *p = cJSON_AddObjectToObject(j, "params");
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        cJSON_AddNumberToObject(p, cr_garment_param_at(i)->key, cr_garment_param_get(d, i));
    char spec[256];
    cr_garment_def_spec(d, spec, sizeof spec);
    cJSON_AddStringToObject(j, "spec", spec);
}

int cmd_garment(int argc, char **argv) {
    garment_opts o = {
        .res = 8000, .size = 720, .frame = 15, .yaw = 30.0f, .shape = "normal", .seed = 1};
    int rc = parse(argc, argv, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    if (cr_mannequin_preset(o.shape, &md, &err) != CR_OK)
        return cli_usage("garment", "%s", err.msg);
    if (o.set_height) md.height_m = o.height;
    if (o.body_res) md.resolution = o.body_res;
    if (o.clip) {
        int count;
        const char *const *names = cr_motion_clip_names(&count);
        int known = 0;
        for (int i = 0; i < count; i++)
            known |= strcmp(names[i], o.clip) == 0;
        if (!known) return cli_usage("garment", "unknown clip '%s'", o.clip);
    }
    double t0 = cr_time_now();
    cr_body_model *body = NULL;
    if (cr_mannequin_create(&md, &body, &err) != CR_OK) return cli_fail(&err);
    cr_garment *g[MAX_LAYERS] = {0};
    int n = 0, usage = 0;
    cr_garment_def defs[MAX_LAYERS];
    cr_garment_variant v = {0};
    cr_status st = build(&o, body, g, &n, defs, &v, &usage, &err);
    double seconds = cr_time_now() - t0;
    char paths[MAX_LAYERS][1024];
    cr_garment_quality q[MAX_LAYERS];
    for (int i = 0; i < n && st == CR_OK; i++) {
        if (n == 1)
            snprintf(paths[i], sizeof paths[i], "%s", o.out);
        else
            layer_path(o.out, cr_garment_type_name(g[i]->type), paths[i], sizeof paths[i]);
        st = cr_mesh_write(paths[i], g[i]->mesh, &err);
        if (st == CR_OK) st = cr_garment_measure(g[i], body, &q[i], &err);
    }
    if (st == CR_OK && o.render) st = render(&o, body, g, n, &err);
    if (st == CR_OK) {
        if (o.json) {
            /* Top level: the whole set (sums, worst figures); per layer below. */
            cJSON *j = cJSON_CreateObject();
            cJSON_AddStringToObject(j, "command", "garment");
            cJSON_AddStringToObject(j, "type", o.user ? "user" : o.types);
            cJSON_AddStringToObject(j, "shape", o.shape);
            double nv = 0, nf = 0, share = 1, angle = 180, clear = 1e9;
            cJSON *arr = cJSON_CreateArray(), *layers = cJSON_CreateArray();
            for (int i = 0; i < n; i++) {
                nv += q[i].vertices, nf += q[i].faces;
                share = share < q[i].share_min_angle_above_20deg ? share
                                                                 : q[i].share_min_angle_above_20deg;
                angle = angle < q[i].min_angle_deg ? angle : q[i].min_angle_deg;
                clear = clear < q[i].min_clearance_m ? clear : q[i].min_clearance_m;
                cJSON_AddItemToArray(arr, cJSON_CreateString(paths[i]));
                cJSON *lj = quality_json(g[i], &q[i], paths[i]);
                if (!o.user) params_json(lj, &defs[i]);
                cJSON_AddItemToArray(layers, lj);
            }
            cJSON_AddNumberToObject(j, "vertices", nv);
            cJSON_AddNumberToObject(j, "faces", nf);
            cJSON_AddNumberToObject(j, "share_min_angle_above_20deg", share);
            cJSON_AddNumberToObject(j, "min_angle_deg", angle);
            cJSON_AddNumberToObject(j, "min_clearance_m", clear);
            cJSON_AddNumberToObject(j, "boundary_loops", q[0].boundary_loops);
            cJSON_AddNumberToObject(j, "panels", q[0].panels);
            cJSON_AddNumberToObject(j, "uv_scale_m", g[0]->uv_scale_m);
            if (!o.user) params_json(j, &defs[0]);
            if (o.random) {
                cJSON_AddNumberToObject(j, "seed", o.seed);
                cJSON_AddNumberToObject(j, "attempts", v.attempts);
                if (v.rejected[0]) cJSON_AddStringToObject(j, "rejected", v.rejected);
            }
            if (o.render) cJSON_AddItemToArray(arr, cJSON_CreateString(o.render));
            cJSON_AddItemToObject(j, "paths", arr);
            if (n > 1)
                cJSON_AddItemToObject(j, "layers", layers);
            else
                cJSON_Delete(layers);
            cJSON_AddNumberToObject(j, "seconds", seconds);
            cli_json_print(j);
        } else {
            for (int i = 0; i < n; i++)
                fprintf(stderr,
                        "garment: %s, %d vertices, %d faces, %.2f%% of faces above 20 deg (min "
                        "%.1f), clearance >= %.1f mm, %d openings, %d panels, written to %s\n",
                        cr_garment_type_name(g[i]->type), q[i].vertices, q[i].faces,
                        100.0 * q[i].share_min_angle_above_20deg, (double)q[i].min_angle_deg,
                        1000.0 * q[i].min_clearance_m, q[i].boundary_loops, q[i].panels, paths[i]);
        }
    }
    for (int i = 0; i < n; i++)
        cr_garment_destroy(g[i]);
    cr_body_model_destroy(body);
    if (st != CR_OK) return usage ? cli_usage("garment", "%s", err.msg) : cli_fail(&err);
    return CLI_OK;
}
