/* cmd_garment.c: `crease garment`: a procedural garment (or layers of them,
 * or a user's garment file) fitted to the mannequin's rest pose, written as
 * a mesh with UVs, optionally pictured on the body. Parse, one call
 * (cr_garment_make), report. */
#include "cli.h"
#include "crease/garment.h"
#include "crease/motion.h"

#include <string.h>

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
        "  --body B         another body instead of those three: an SMPL-family\n"
        "                   FILE.npz[:betas] or a rigged CHAR.glb[:MAP] (docs/body.md)\n"
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
    const char *shape;
    int json, body_res, seed;
    float height;
    int set_param[CR_GARMENT_NPARAMS], set_height, set_seed;
} garment_opts;

/* Into d (the garment and picture) and o (the body, the report). */
static int parse(int argc, char **argv, cr_garment_make_def *d, garment_opts *o) {
    int npos = 0;
    const cli_opt fixed[] = {
        CLI_FLAG("--json", &o->json),
        CLI_STR("--type", &d->types),
        CLI_STR("--user", &d->user),
        CLI_OUTPUT(&d->out),
        CLI_STR("--render", &d->render_png),
        CLI_STR("--shape", &o->shape),
        CLI_STR("--body", &d->body_spec),
        CLI_STR("--clip", &d->clip),
        CLI_INT("--res", &d->target_vertices, 500, 100000),
        CLI_INT("--body-res", &o->body_res, 32, 512),
        CLI_INT("--size", &d->render_size, 16, 8192),
        CLI_INT("--frame", &d->clip_frame, 0, 100000),
        CLI_FLOAT("--yaw", &d->render_yaw_deg, -1e4, 1e4),
        CLI_FLAG("--random", &d->random),
        {.name = "--seed",
         .kind = CLI_OPT_INT,
         .dst = &o->seed,
         .lo = 0,
         .hi = 2147483647.0,
         .seen = &o->set_seed},
        CLI_FLOAT("--grid", &d->grid_m, 0.004, 0.03),
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
                                     .dst = &d->param[i],
                                     .lo = p->lo,
                                     .hi = p->hi,
                                     .seen = &o->set_param[i]};
    }
    opts[NFIXED + CR_GARMENT_NPARAMS] = (cli_opt)CLI_END;
    int rc = cli_parse("garment", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!d->out) return cli_usage("garment", "missing -o FILE");
    if (!d->types == !d->user) return cli_usage("garment", "give one of --type or --user");
    if (o->set_seed && !d->random) return cli_usage("garment", "--seed needs --random");
    if (d->random && (d->user || strchr(d->types, ',')))
        return cli_usage("garment", "--random makes one --type, not a layer list or --user");
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        d->given |= (uint32_t)(o->set_param[i] != 0) << i;
    d->seed = (uint64_t)o->seed;
    return CLI_OK;
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

/* The parameters a garment was built with and its exact spec. */
static void params_json(cJSON *j, const cr_garment_def *d) {
    cJSON *p = cJSON_AddObjectToObject(j, "params");
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        cJSON_AddNumberToObject(p, cr_garment_param_at(i)->key, cr_garment_param_get(d, i));
    char spec[256];
    cr_garment_def_spec(d, spec, sizeof spec);
    cJSON_AddStringToObject(j, "spec", spec);
}

/* Top level: the whole set (sums, worst figures); per layer below. */
static void print_json(const cr_garment_make_def *d, const garment_opts *o,
                       const cr_garment_make_result *r) {
    const int n = r->n;
    const cr_garment_quality *q = r->quality;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "command", "garment");
    cJSON_AddStringToObject(j, "type", d->user ? "user" : d->types);
    cJSON_AddStringToObject(j, "shape", o->shape);
    if (d->body_spec) cJSON_AddStringToObject(j, "body", d->body_spec);
    double nv = 0, nf = 0, share = 1, angle = 180, clear = 1e9;
    cJSON *arr = cJSON_CreateArray(), *layers = cJSON_CreateArray();
    for (int i = 0; i < n; i++) {
        nv += q[i].vertices, nf += q[i].faces;
        share = share < q[i].share_min_angle_above_20deg ? share : q[i].share_min_angle_above_20deg;
        angle = angle < q[i].min_angle_deg ? angle : q[i].min_angle_deg;
        clear = clear < q[i].min_clearance_m ? clear : q[i].min_clearance_m;
        cJSON_AddItemToArray(arr, cJSON_CreateString(r->paths[i]));
        cJSON *lj = quality_json(r->garments[i], &q[i], r->paths[i]);
        if (!d->user) params_json(lj, &r->defs[i]);
        cJSON_AddItemToArray(layers, lj);
    }
    cJSON_AddNumberToObject(j, "vertices", nv);
    cJSON_AddNumberToObject(j, "faces", nf);
    cJSON_AddNumberToObject(j, "share_min_angle_above_20deg", share);
    cJSON_AddNumberToObject(j, "min_angle_deg", angle);
    cJSON_AddNumberToObject(j, "min_clearance_m", clear);
    cJSON_AddNumberToObject(j, "boundary_loops", q[0].boundary_loops);
    cJSON_AddNumberToObject(j, "panels", q[0].panels);
    cJSON_AddNumberToObject(j, "uv_scale_m", r->garments[0]->uv_scale_m);
    if (!d->user) params_json(j, &r->defs[0]);
    if (d->random) {
        cJSON_AddNumberToObject(j, "seed", o->seed);
        cJSON_AddNumberToObject(j, "attempts", r->variant.attempts);
        if (r->variant.rejected[0]) cJSON_AddStringToObject(j, "rejected", r->variant.rejected);
    }
    if (d->render_png) cJSON_AddItemToArray(arr, cJSON_CreateString(d->render_png));
    cJSON_AddItemToObject(j, "paths", arr);
    if (n > 1)
        cJSON_AddItemToObject(j, "layers", layers);
    else
        cJSON_Delete(layers);
    cJSON_AddNumberToObject(j, "seconds", r->seconds);
    cli_json_print(j);
}

int cmd_garment(int argc, char **argv) {
    cr_garment_make_def d = cr_garment_make_default_def();
    garment_opts o = {.shape = "normal", .seed = 1};
    int rc = parse(argc, argv, &d, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    if (d.body_spec && (strcmp(o.shape, "normal") || o.set_height || o.body_res))
        return cli_usage("garment", "--body replaces the mannequin: not with --shape, --height "
                                    "or --body-res");
    if (cr_mannequin_preset(o.shape, &d.body, &err) != CR_OK)
        return cli_usage("garment", "%s", err.msg);
    if (o.set_height) d.body.height_m = o.height;
    if (o.body_res) d.body.resolution = o.body_res;
    if (d.clip) {
        int count;
        const char *const *names = cr_motion_clip_names(&count);
        int known = 0;
        for (int i = 0; i < count; i++)
            known |= strcmp(names[i], d.clip) == 0;
        if (!known) return cli_usage("garment", "unknown clip '%s'", d.clip);
    }
    cr_garment_make_result r;
    if (cr_garment_make(&d, &r, &err) != CR_OK)
        return r.bad_types ? cli_usage("garment", "%s", err.msg) : cli_fail(&err);
    if (o.json)
        print_json(&d, &o, &r);
    else
        for (int i = 0; i < r.n; i++) {
            const cr_garment_quality *q = &r.quality[i];
            fprintf(stderr,
                    "garment: %s, %d vertices, %d faces, %.2f%% of faces above 20 deg (min "
                    "%.1f), clearance >= %.1f mm, %d openings, %d panels, written to %s\n",
                    cr_garment_type_name(r.garments[i]->type), q->vertices, q->faces,
                    100.0 * q->share_min_angle_above_20deg, (double)q->min_angle_deg,
                    1000.0 * q->min_clearance_m, q->boundary_loops, q->panels, r.paths[i]);
        }
    cr_garment_make_result_free(&r);
    return CLI_OK;
}
