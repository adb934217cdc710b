/* outputs.c: what `gdsr run` writes beside its PC2s: the high-resolution
 * result as a glb (morph-target animation through the project's glb
 * writer) and the side-by-side pictures of one frame (the project's
 * renderer, and normal maps over the UV chart as crease eval's SSIM sees
 * them). */
#include "gdsr_internal.h"

#include "crease/diffgeo.h"
#include "crease/eval.h"
#include "crease/mesh_io.h"
#include "crease/render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

cr_status cr_gdsr_write_glb(const cr_mesh *high, const float *x, int32_t nframes, float fps,
                            int32_t max_frames, const char *path, int *animated, cr_error *err) {
    if (nframes < 1 || !(fps > 0))
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr glb %s: %d frames at %g fps", path, nframes,
                       (double)fps);
    cr_mesh *m = NULL;
    CR_TRY(cr_mesh_clone(high, &m, err));
    int anim = nframes <= max_frames;
    int64_t n3 = (int64_t)high->nv * 3;
    cr_status st = CR_OK;
    if (anim) {
        /* the base mesh is the first frame (its normals give the targets' too) */
        memcpy(m->pos, x, (size_t)n3 * sizeof(float));
        st = cr_mesh_compute_normals(m, err);
        if (st == CR_OK) st = cr_glb_write_sequence(path, m, x, nframes, fps, err);
    } else {
        memcpy(m->pos, x + (int64_t)(nframes - 1) * n3, (size_t)n3 * sizeof(float));
        st = cr_mesh_compute_normals(m, err);
        if (st == CR_OK) st = cr_glb_write(path, m, err);
    }
    cr_mesh_destroy(m);
    if (animated) *animated = anim;
    return st;
}

/* The normal map of m over its UV chart, side x side, (n + 1) / 2 as sRGB
 * (crease eval's SSIM map; area-weighted vertex normals mixed by each
 * texel's barycentrics), light grey off the chart. */
static cr_status normal_map(const cr_mesh *m, int side, cr_image *img, cr_error *err) {
    int64_t np = (int64_t)side * side;
    int32_t *face = malloc((size_t)np * sizeof(int32_t));
    double *bary = malloc((size_t)np * 3 * sizeof(double));
    float *vn = malloc((size_t)m->nv * 3 * sizeof(float));
    cr_status st = face && bary && vn ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    if (st == CR_OK) st = cr_eval_uv_raster(m, side, face, bary, NULL, err);
    if (st == CR_OK) st = cr_image_create(side, side, img, err);
    if (st == CR_OK) {
        cr_mesh_vertex_normals(m, CR_NORMAL_AREA, vn);
        for (int64_t p = 0; p < np; p++) {
            uint8_t *px = img->rgb + 3 * p;
            if (face[p] < 0) {
                px[0] = px[1] = px[2] = 235;
                continue;
            }
            double n[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++) {
                const float *v = vn + 3 * m->tri[3 * face[p] + k];
                for (int c = 0; c < 3; c++)
                    n[c] += bary[3 * p + k] * v[c];
            }
            double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            for (int c = 0; c < 3; c++) {
                double u = l > 0 ? 0.5 * (n[c] / l + 1.0) : 0.5;
                px[c] = (uint8_t)lround(255.0 * fmin(1.0, fmax(0.0, u)));
            }
        }
    }
    free(face), free(bary), free(vn);
    return st;
}

static void label(cr_image *img, const char *text) {
    static const uint8_t ink[3] = {30, 30, 30};
    int scale = img->width >= 400 ? 3 : 2;
    cr_plot_text(img, (img->width - cr_plot_text_width(text, scale)) / 2, 4 * scale, scale, text,
                 ink);
}

/* Cloth colours by layer: the single garment's blue first. */
static const float layer_color[][3] = {
    {0.33f, 0.52f, 0.80f}, {0.85f, 0.58f, 0.30f}, {0.42f, 0.68f, 0.42f}, {0.72f, 0.40f, 0.58f}};
enum { NLAYER_COLORS = sizeof layer_color / sizeof layer_color[0] };

cr_status cr_gdsr_render_layers(const cr_render_def *rd, const cr_mesh *m, cr_image *out,
                                cr_error *err) {
    int32_t *layer = cr_malloc(sizeof(int32_t) * (size_t)(m->nv + 1), err);
    if (!layer) return CR_ERR_MEMORY;
    const int32_t nl = cr_gdsr_mesh_layers(m, layer);
    const int np = nl < 2 ? 1 : nl < NLAYER_COLORS ? (int)nl : NLAYER_COLORS;
    /* each layer a view of m (its positions) with that layer's faces, one
     * buffer of faces grouped by layer; the other vertices draw nothing */
    int32_t *tri = np > 1 ? cr_malloc(sizeof(int32_t) * 3 * (size_t)(m->nf + 1), err) : NULL;
    if (np > 1 && !tri) {
        free(layer);
        return CR_ERR_MEMORY;
    }
    cr_mesh part[NLAYER_COLORS];
    cr_render_object obj[NLAYER_COLORS];
    int32_t used = 0;
    for (int l = 0; l < np; l++) {
        part[l] = *m;
        if (np > 1) {
            part[l].tri = tri + 3 * (size_t)used;
            part[l].nf = 0;
            for (int32_t f = 0; f < m->nf; f++) {
                const int32_t want = layer[m->tri[3 * f]];
                if (want == l || (l == NLAYER_COLORS - 1 && want > l))
                    memcpy(part[l].tri + 3 * (size_t)part[l].nf++, m->tri + 3 * (size_t)f,
                           3 * sizeof(int32_t));
            }
            used += part[l].nf;
        }
        obj[l] = (cr_render_object){.mesh = &part[l]};
        memcpy(obj[l].color, layer_color[l], sizeof obj[l].color);
    }
    cr_status st = cr_render_scene(rd, obj, np, out, err);
    free(tri);
    free(layer);
    return st;
}

cr_status cr_gdsr_render_compare(const cr_gdsr_data *d, int clip, const cr_gdsr_rollout_result *r,
                                 int32_t frame, int size, const char *png_path,
                                 const char *normals_path, cr_error *err) {
    const cr_gdsr_clip *cl = &d->clip[clip];
    if (frame < 0 || frame >= cl->nframes || frame >= r->nframes)
        return CR_FAIL(err, CR_ERR_RANGE, "gdsr pictures: frame %d of %d", frame, cl->nframes);
    if (size < 16 || size > 4096)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr pictures: size %d px, need 16 to 4096", size);
    int64_t nh3 = (int64_t)d->high->nv * 3, nl3 = (int64_t)d->low->nv * 3;
    struct {
        const char *name;
        const cr_mesh *rest;
        const float *x;
    } panel[4] = {{"low input", d->low, cl->low + frame * nl3},
                  {"gdsr", d->high, r->gdsr + frame * nh3},
                  {"upsampling", d->high, r->upsampled + frame * nh3},
                  {"reference", d->high, cl->high ? cl->high + frame * nh3 : NULL}};
    int np = panel[3].x ? 4 : 3;
    cr_image shaded[4] = {{0}}, maps[4] = {{0}}, grid = {0};
    cr_mesh *m[4] = {NULL};
    cr_status st = CR_OK;
    cr_render_def rd = cr_render_default_def();
    rd.width = rd.height = size;
    rd.yaw_deg = 30.0f, rd.pitch_deg = 25.0f; /* crease render's defaults */
    for (int k = 0; k < np && st == CR_OK; k++) {
        st = cr_mesh_clone(panel[k].rest, &m[k], err);
        if (st != CR_OK) break;
        memcpy(m[k]->pos, panel[k].x, (size_t)panel[k].rest->nv * 3 * sizeof(float));
        /* the garment alone, framed on itself as `crease render` does (the low and high
           garments have nearly the same bounds, so the panels line up); with the body in
           the frame the folds would be a third as large. An outfit's layers get their
           own colours, or a vest could not be told from the shirt under it. */
        st = cr_gdsr_render_layers(&rd, m[k], &shaded[k], err);
        if (st == CR_OK) label(&shaded[k], panel[k].name);
        if (st == CR_OK && normals_path) st = normal_map(m[k], size, &maps[k], err);
        if (st == CR_OK && normals_path) label(&maps[k], panel[k].name);
    }
    static const float fill[3] = {1, 1, 1};
    if (st == CR_OK) st = cr_image_grid(shaded, np, np, 4, fill, &grid, err);
    if (st == CR_OK) st = cr_image_write_png(&grid, png_path, err);
    cr_image_free(&grid);
    if (st == CR_OK && normals_path) st = cr_image_grid(maps, np, np, 4, fill, &grid, err);
    if (st == CR_OK && normals_path) st = cr_image_write_png(&grid, normals_path, err);
    cr_image_free(&grid);
    for (int k = 0; k < 4; k++) {
        cr_image_free(&shaded[k]);
        cr_image_free(&maps[k]);
        cr_mesh_destroy(m[k]);
    }
    return st;
}
