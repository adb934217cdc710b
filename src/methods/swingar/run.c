/* run.c: `crease swingar run` as one call (cr_swingar_run): a trained model,
 * or the garment's own skinning (the baseline), animating any garment mesh
 * on a body posed by a clip or a motion file, the exact collision removal,
 * and the outputs a user opens (PC2, OBJ, glb, a picture of the last frame).
 */
#include "crease/body.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/render.h"
#include "swingar_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { RUN_COOKIE = 0x53525231u, /* "SRR1" */ PICTURE_SIZE = 512, PATH_CAP = 1200 };

/* Vertices inside the posed body are moved out this far beyond its surface, m. */

cr_swingar_run_def cr_swingar_run_default_def(void) {
    cr_swingar_run_def d;
    memset(&d, 0, sizeof d);
    d.body = "normal";
    d.motion_def = cr_motion_resolve_default_def();
    d.cookie = RUN_COOKIE;
    return d;
}

/* The last frame, garment on body, as out_dir/last.png. */
static cr_status picture(const char *path, const cr_mesh *garment, const cr_mesh *body_rest,
                         const float *pred, const float *body, int32_t T, cr_error *err) {
    cr_mesh *gm = NULL, *bm = NULL;
    cr_status st = cr_mesh_clone(garment, &gm, err);
    if (st == CR_OK) st = cr_mesh_clone(body_rest, &bm, err);
    if (st == CR_OK) {
        memcpy(gm->pos, pred + (size_t)(T - 1) * gm->nv * 3, sizeof(float) * gm->nv * 3);
        memcpy(bm->pos, body + (size_t)(T - 1) * bm->nv * 3, sizeof(float) * bm->nv * 3);
        free(gm->normal), gm->normal = NULL;
        free(bm->normal), bm->normal = NULL;
        cr_render_def rd = cr_render_default_def();
        rd.width = rd.height = PICTURE_SIZE;
        cr_render_object objs[2] = {{.mesh = bm, .color = {0.78f, 0.72f, 0.66f}},
                                    {.mesh = gm, .color = {0.25f, 0.45f, 0.80f}}};
        st = cr_render_to_png(&rd, objs, 2, path, err);
    }
    cr_mesh_destroy(gm);
    cr_mesh_destroy(bm);
    return st;
}

static cr_status write_outputs(const cr_swingar_run_def *d, const cr_garment *g,
                               const cr_body_model *b, const float *pred, const float *body,
                               int32_t T, cr_error *err) {
    char path[PATH_CAP];
    const float fps = d->motion_def.fps > 0.0f ? d->motion_def.fps : 30.0f;
    CR_TRY(cr_mkdir_p(d->out_dir, err));
    snprintf(path, sizeof path, "%s/garment.pc2", d->out_dir);
    CR_TRY(cr_pc2_write(path, pred, g->mesh->nv, T, 0, 1, err));
    snprintf(path, sizeof path, "%s/body.pc2", d->out_dir);
    CR_TRY(cr_pc2_write(path, body, b->rest->nv, T, 0, 1, err));
    snprintf(path, sizeof path, "%s/garment.obj", d->out_dir);
    CR_TRY(cr_obj_write(path, g->mesh, err));
    snprintf(path, sizeof path, "%s/garment.glb", d->out_dir);
    CR_TRY(cr_glb_write_sequence(path, g->mesh, pred, T, fps, err));
    snprintf(path, sizeof path, "%s/last.png", d->out_dir);
    return picture(path, g->mesh, b->rest, pred, body, T, err);
}

cr_status cr_swingar_run(const cr_swingar_run_def *d, cr_swingar_run_report *out, cr_error *err) {
    if (!d || d->cookie != RUN_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar run: def not made by its default");
    if ((!d->model && !d->skinned) || !d->garment || !d->motion || !d->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar run: a model (or skinned), a garment, a motion and an output "
                       "folder are required");
    cr_swingar_run_report rep;
    memset(&rep, 0, sizeof rep);
    cr_swingar *m = NULL;
    cr_body_model *b = NULL;
    cr_garment *g = NULL;
    cr_motion *mo = NULL;
    float *pred = NULL, *body = NULL;
    cr_status st = d->skinned ? CR_OK : cr_swingar_load(d->model, &m, err);
    if (st == CR_OK) st = cr_body_resolve(d->body, &b, err);
    if (st == CR_OK) {
        cr_garment_user_def ud = cr_garment_user_default_def();
        st = cr_garment_load_user(d->garment, &ud, b, &g, err);
    }
    cr_motion_resolve_def rd = d->motion_def;
    rd.body = b;
    if (st == CR_OK) st = cr_motion_resolve(d->motion, &rd, &mo, NULL, err);
    if (st == CR_OK) st = cr_body_pose_motion(b, mo, &body, err);
    const int32_t T = mo ? mo->nframes : 0, V = g ? g->mesh->nv : 0;
    if (st == CR_OK && !(pred = malloc(sizeof(float) * (size_t)T * V * 3)))
        st = CR_FAIL(err, CR_ERR_MEMORY, "swingar run: out of memory");
    const double t0 = cr_time_now();
    for (int32_t t = 0; st == CR_OK && d->skinned && t < T; t++)
        st = cr_garment_pose(g, b, mo->poses + (size_t)t * CR_NJOINTS * 3, mo->trans + 3 * t,
                             pred + (size_t)t * V * 3, err);
    if (st == CR_OK && !d->skinned) st = cr_swingar_animate(m, g, d->garment, b, mo, 0, pred, err);
    if (st == CR_OK && !d->skinned && !d->raw) {
        st = cr_swingar_remove_collisions_exact(
            g->mesh, b->rest, body, T, CR_SWINGAR_REMOVAL_MARGIN_M, pred, &rep.removal, err);
        rep.removed = st == CR_OK;
    }
    rep.seconds = cr_time_now() - t0;
    rep.vertices = V, rep.frames = T;
    if (st == CR_OK) st = write_outputs(d, g, b, pred, body, T, err);
    free(pred);
    free(body);
    cr_motion_destroy(mo);
    cr_garment_destroy(g);
    cr_body_model_destroy(b);
    cr_swingar_destroy(m);
    if (st == CR_OK && out) *out = rep;
    return st;
}
