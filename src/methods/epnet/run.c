/* run.c: `crease epnet run`: a trained model on a motion (cr_epnet_infer, the
 * proxy inference by default), written as garment.pc2, garment.glb, rb.npy and
 * pictures of its last frame, with the closest the garment comes to the body. */
#include "crease/bvh.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "crease/render.h"
#include "epnet_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

cr_epnet_run_def cr_epnet_run_default_def(void) {
    cr_epnet_run_def d;
    memset(&d, 0, sizeof d);
    d.infer = cr_epnet_infer_default_def();
    d.cookie = 0x45505232u;
    return d;
}

cr_status cr_epnet_render_(const cr_epnet *m, const float *pos, const float *body,
                           const cr_mesh *body_rest, const float *scalar, int size, float yaw_deg,
                           cr_image *img, cr_error *err) {
    cr_mesh gm = *m->garment->mesh, bm = *body_rest;
    gm.pos = (float *)pos, bm.pos = (float *)body;
    gm.normal = NULL, bm.normal = NULL;
    cr_render_def rd = cr_render_default_def();
    rd.width = rd.height = size, rd.yaw_deg = yaw_deg;
    cr_render_object o[2] = {{.mesh = &bm, .color = {0.8f, 0.75f, 0.7f}},
                             {.mesh = &gm, .color = {0.3f, 0.5f, 0.85f}, .scalar = scalar}};
    if (scalar) rd.colormap_auto = 0, rd.colormap_min = -0.5f, rd.colormap_max = 0.5f;
    return cr_render_scene(&rd, o, 2, img, err);
}

/* The garment over the body at its default view, 512 pixels, as a PNG. */
static cr_status render_pair(const cr_epnet *m, const float *pos, const float *body,
                             const cr_mesh *body_rest, const float *scalar, const char *path,
                             cr_error *err) {
    cr_image img;
    CR_TRY(cr_epnet_render_(m, pos, body, body_rest, scalar, 512, cr_render_default_def().yaw_deg,
                            &img, err));
    cr_status st = cr_image_write_png(&img, path, err);
    cr_image_free(&img);
    return st;
}

cr_status cr_epnet_run(const cr_epnet_run_def *def, cr_epnet_run_report *out, cr_error *err) {
    if (!def->model_dir || !def->motion || !def->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet run: model, motion and output are required");
    cr_epnet *m = NULL;
    CR_TRY(cr_epnet_open(def->model_dir, &m, err));
    cr_epnet_seq *s = NULL;
    cr_status st = cr_mkdir_p(def->out_dir, err);
    if (st == CR_OK)
        st = cr_epnet_seq_create(m, def->motion, def->body, def->frames, def->hold, &s, err);
    const int32_t T = s ? s->T : 0, V = m->nv, H = m->nh;
    if (s && def->frames > 0 && T < def->frames + def->hold)
        cr_log(CR_LOG_WARN, "epnet run: %s has %d frames, fewer than the %d asked for", def->motion,
               T - def->hold, def->frames);
    float *pos = NULL, *rb = NULL, *hs = NULL;
    if (st == CR_OK) {
        pos = malloc(sizeof(float) * 3 * (size_t)T * V);
        rb = malloc(sizeof(float) * (size_t)T * (H + 1));
        hs = calloc((size_t)V, sizeof(float));
        if (!pos || !rb || !hs) st = CR_FAIL(err, CR_ERR_MEMORY, "epnet run: out of memory");
    }
    double t0 = cr_time_now();
    cr_epnet_infer_def inf = def->infer;
    if (def->baseline || m->def.baseline) inf.mode = CR_EPNET_ZERO_RB;
    if (st == CR_OK) st = cr_epnet_infer(m, s, &inf, pos, NULL, rb, err);
    cr_epnet_run_report rep = {.frames = T, .vertices = V, .hinges = H};
    rep.seconds_per_frame = T > 0 ? (cr_time_now() - t0) / T : 0;
    char path[1100];
    if (st == CR_OK) {
        rep.finite = 1;
        for (int64_t i = 0; i < 3 * (int64_t)T * V; i++)
            if (!isfinite(pos[i])) rep.finite = 0;
        for (int64_t i = 0; i < (int64_t)T * H; i++)
            rep.max_abs_rb = fmax(rep.max_abs_rb, fabs(rb[i]));
        snprintf(path, sizeof path, "%s/garment.pc2", def->out_dir);
        st = cr_pc2_write(path, pos, V, T, 0, 1, err);
    }
    if (st == CR_OK) {
        snprintf(path, sizeof path, "%s/garment.glb", def->out_dir);
        st = cr_glb_write_sequence(path, m->garment->mesh, pos, T, m->def.fps, err);
    }
    if (st == CR_OK) {
        snprintf(path, sizeof path, "%s/rb.npy", def->out_dir);
        st = cr_npy_write(path, CR_NPY_F32, 2, (int64_t[]){T, H}, rb, err);
    }
    const float *last = pos + (size_t)(T - 1) * V * 3;
    const float *body = s ? s->body + (size_t)(T - 1) * s->vb * 3 : NULL;
    if (st == CR_OK) {
        snprintf(path, sizeof path, "%s/garment.png", def->out_dir);
        st = render_pair(m, last, body, s->body_rest, NULL, path, err);
    }
    if (st == CR_OK) {
        /* RB per vertex: the mean over its hinges of the last frame */
        int32_t *cnt = calloc((size_t)V, sizeof *cnt);
        if (!cnt) st = CR_FAIL(err, CR_ERR_MEMORY, "epnet run: out of memory");
        for (int32_t h = 0; st == CR_OK && h < H; h++)
            for (int k = 0; k < 2; k++) {
                const int32_t v = m->topo->hinge[4 * h + k];
                hs[v] += rb[(size_t)(T - 1) * H + h], cnt[v]++;
            }
        for (int32_t v = 0; st == CR_OK && v < V; v++)
            hs[v] = cnt[v] ? hs[v] / cnt[v] : 0;
        free(cnt);
        snprintf(path, sizeof path, "%s/rb.png", def->out_dir);
        if (st == CR_OK) st = render_pair(m, last, body, s->body_rest, hs, path, err);
    }
    if (st == CR_OK) {
        cr_bvh *bvh = NULL;
        st = cr_bvh_build(body, s->vb, s->body_rest->tri, s->body_rest->nf, &bvh, err);
        float *d = malloc(sizeof(float) * (size_t)V);
        if (st == CR_OK && d) {
            cr_bvh_signed_distance_batch(bvh, last, V, INFINITY, d, NULL, NULL);
            rep.min_body_distance = INFINITY;
            for (int32_t v = 0; v < V; v++)
                rep.min_body_distance = fmin(rep.min_body_distance, d[v]);
        }
        free(d);
        cr_bvh_destroy(bvh);
    }
    free(pos), free(rb), free(hs);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
    if (out) *out = rep;
    return st;
}
