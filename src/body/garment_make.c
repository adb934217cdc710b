/* garment_make.c: `crease garment` as one call (cr_garment_make): the
 * mannequin, the garments (procedural layers worn over each other, one
 * seeded random variant, or a user's garment file pushed out of the body),
 * each written and measured, and a picture of them on the body, posed at a
 * procedural clip's frame when asked.
 *
 * Leaves out: printing (the caller reports the figures). */
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/render.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAKE_COOKIE 0x474d4b31u /* "GMK1" */
enum { MAX_LAYERS = CR_GARMENT_MAKE_MAX_LAYERS };

cr_garment_make_def cr_garment_make_default_def(void) {
    cr_garment_make_def d;
    memset(&d, 0, sizeof d);
    d.body = cr_mannequin_default_def();
    d.target_vertices = 8000;
    d.render_size = 720;
    d.render_yaw_deg = 30.0f;
    d.clip_frame = 15;
    d.cookie = MAKE_COOKIE;
    return d;
}

void cr_garment_make_result_free(cr_garment_make_result *r) {
    if (!r) return;
    for (int i = 0; i < r->n; i++)
        cr_garment_destroy(r->garments[i]);
    memset(r, 0, sizeof *r);
}

/* path with "_suffix" before its extension. */
static void layer_path(const char *path, const char *suffix, char *out, size_t cap) {
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - path) : strlen(path);
    snprintf(out, cap, "%.*s_%s%s", (int)stem, path, suffix, path + stem);
}

/* The picture: body grey, garments in cloth colours, posed at a clip frame
 * when asked. */
static cr_status render(const cr_garment_make_def *o, const cr_body_model *body, cr_garment **g,
                        int n, cr_error *err) {
    static const float colors[MAX_LAYERS][3] = {
        {0.33f, 0.52f, 0.80f}, {0.80f, 0.45f, 0.30f}, {0.45f, 0.70f, 0.45f}, {0.80f, 0.75f, 0.40f}};
    cr_mesh *posed[MAX_LAYERS + 1] = {0};
    cr_render_object obj[MAX_LAYERS + 1];
    cr_motion *mo = NULL;
    cr_status st = CR_OK;
    if (o->clip) st = cr_motion_clip(o->clip, o->clip_frame + 1, 30.0f, &mo, err);
    for (int i = 0; i <= n && st == CR_OK; i++) {
        const cr_mesh *rest = i == 0 ? body->rest : g[i - 1]->mesh;
        st = cr_mesh_clone(rest, &posed[i], err);
        if (st == CR_OK && mo) {
            const float *pose = &mo->poses[(size_t)o->clip_frame * CR_NJOINTS * 3];
            const float *trans = &mo->trans[(size_t)o->clip_frame * 3];
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
        def.width = def.height = o->render_size;
        def.yaw_deg = o->render_yaw_deg;
        def.pitch_deg = 10.0f;
        st = cr_render_to_png(&def, obj, n + 1, o->render_png, err);
    }
    for (int i = 0; i <= n; i++)
        cr_mesh_destroy(posed[i]);
    cr_motion_destroy(mo);
    return st;
}

/* One random variant: drawn, checked, instantiated at target_vertices. */
static cr_status build_random(const cr_garment_make_def *o, const cr_body_model *body,
                              cr_garment **g, cr_garment_variant *v, int *bad_types,
                              cr_error *err) {
    if (cr_garment_variant_parse(o->types, v, err) != CR_OK) {
        *bad_types = 1;
        return CR_ERR_INVALID;
    }
    v->random = 1, v->seed = o->seed;
    v->def.target_vertices = o->target_vertices;
    if (o->grid_m > 0) v->def.grid_m = o->grid_m;
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        if (o->given >> i & 1u) {
            CR_TRY(cr_garment_param_set(&v->def, cr_garment_param_at(i)->key, o->param[i], err));
            v->given |= 1u << i;
        }
    cr_garment_template *t = NULL;
    CR_TRY(cr_garment_variant_build(v, body, &t, err));
    cr_status st = cr_garment_template_instantiate(t, o->target_vertices, body, g, err);
    cr_garment_template_destroy(t);
    return st;
}

/* Build (or load) the garments into r->garments, r->n of them, with the defs
 * built (not for a user garment). */
static cr_status build(const cr_garment_make_def *o, const cr_body_model *body,
                       cr_garment_make_result *r, cr_error *err) {
    cr_garment_def *defs = r->defs;
    if (o->user) {
        cr_garment_user_def ud = cr_garment_user_default_def();
        int ic = cr_garment_param_find("clearance");
        if (o->given >> ic & 1u) ud.clearance_m = o->param[ic];
        r->n = 1;
        return cr_garment_load_user(o->user, &ud, body, &r->garments[0], err);
    }
    if (o->random) {
        r->n = 1;
        cr_status st = build_random(o, body, r->garments, &r->variant, &r->bad_types, err);
        defs[0] = r->variant.def;
        return st;
    }
    char list[256];
    snprintf(list, sizeof list, "%s", o->types);
    int n = 0;
    for (char *save = NULL, *tok = strtok_r(list, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        cr_garment_type type;
        if (n == MAX_LAYERS || cr_garment_type_parse(tok, &type, err) != CR_OK) {
            if (n == MAX_LAYERS)
                CR_FAIL(err, CR_ERR_INVALID, "garment: at most %d layers", MAX_LAYERS);
            r->bad_types = 1;
            return CR_ERR_INVALID;
        }
        cr_garment_def d = cr_garment_default_def(type);
        d.target_vertices = o->target_vertices;
        for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
            if (o->given >> i & 1u)
                CR_TRY(cr_garment_param_set(&d, cr_garment_param_at(i)->key, o->param[i], err));
        if (o->grid_m > 0) d.grid_m = o->grid_m;
        /* Each layer clears the one below by at least the layer gap. */
        if (n > 0 && d.clearance_m < defs[n - 1].clearance_m + CR_GARMENT_LAYER_GAP)
            d.clearance_m = defs[n - 1].clearance_m + CR_GARMENT_LAYER_GAP;
        defs[n++] = d;
    }
    if (n == 0) {
        r->bad_types = 1;
        return CR_FAIL(err, CR_ERR_INVALID, "garment: --type names no type");
    }
    r->n = n;
    return cr_garment_create_layers(defs, n, body, r->garments, err);
}

cr_status cr_garment_make(const cr_garment_make_def *def, cr_garment_make_result *out,
                          cr_error *err) {
    CR_ASSERT(def && def->cookie == MAKE_COOKIE && out); /* made by cr_garment_make_default_def */
    memset(out, 0, sizeof *out);
    if (!def->out || !def->types == !def->user || (def->random && def->user))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "garment: needs an output file and one of types or a user garment "
                       "(random: types)");
    double t0 = cr_time_now();
    cr_body_model *body = NULL;
    CR_TRY(def->body_spec ? cr_body_resolve(def->body_spec, &body, err)
                          : cr_mannequin_create(&def->body, &body, err));
    cr_status st = build(def, body, out, err);
    out->seconds = cr_time_now() - t0;
    for (int i = 0; i < out->n && st == CR_OK; i++) {
        if (out->n == 1)
            snprintf(out->paths[i], sizeof out->paths[i], "%s", def->out);
        else
            layer_path(def->out, cr_garment_type_name(out->garments[i]->type), out->paths[i],
                       sizeof out->paths[i]);
        st = cr_mesh_write(out->paths[i], out->garments[i]->mesh, err);
        if (st == CR_OK) st = cr_garment_measure(out->garments[i], body, &out->quality[i], err);
    }
    if (st == CR_OK && def->render_png) st = render(def, body, out->garments, out->n, err);
    cr_body_model_destroy(body);
    if (st != CR_OK) {
        int bad_types = out->bad_types;
        cr_garment_make_result_free(out);
        out->bad_types = bad_types;
    }
    return st;
}
