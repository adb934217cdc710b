/* swingar_side_by_side.c: a prediction beside its simulation, one frame, for
 * up to eight garments on one moving body: each pair is one scene (the
 * prediction on the left, the simulation moved 1.45 m to the right, seen
 * from the front), so both share the camera; the pairs are cropped to what
 * they show and laid out two to a row.
 *
 *   example_swingar_side_by_side OUT.png FRAME SIZE BODY.obj BODY.pc2 \
 *       PRED.obj PRED.pc2 SIM.obj SIM.pc2 [PRED.obj PRED.pc2 SIM.obj SIM.pc2 ...]
 *
 * SIZE: the side of each pair's render before cropping, pixels.
 */
#include "crease/mesh_io.h"
#include "crease/render.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_PAIRS = 8 };
#define SHIFT_M 1.45f

static int fail(const cr_error *e) {
    fprintf(stderr, "swingar_side_by_side: %s\n", e->msg);
    return 1;
}

/* A mesh at frame f of a point cache (shifted by dx along x), owned. */
static cr_status posed(const char *obj, const char *pc2, int f, float dx, cr_mesh **out,
                       cr_error *err) {
    cr_pc2 p = {0};
    CR_TRY(cr_obj_read(obj, out, err));
    cr_status st = cr_pc2_read(pc2, &p, err);
    if (st == CR_OK && (p.nv != (*out)->nv || f < 0 || f >= p.nframes))
        st = CR_FAIL(err, CR_ERR_SHAPE, "%s: %d points, %d frames; %s has %d vertices, frame %d",
                     pc2, p.nv, p.nframes, obj, (*out)->nv, f);
    if (st == CR_OK) {
        const float *x = p.frames + (size_t)f * 3 * (size_t)p.nv;
        for (int32_t i = 0; i < 3 * p.nv; i++)
            (*out)->pos[i] = x[i] + (i % 3 == 0 ? dx : 0.0f);
        free((*out)->normal), (*out)->normal = NULL;
    }
    cr_pc2_free(&p);
    if (st != CR_OK) cr_mesh_destroy(*out), *out = NULL;
    return st;
}

/* Crop img to the pixels that differ from white, with a 3-pixel border. */
static cr_status crop(cr_image *img, cr_error *err) {
    int x0 = img->width, x1 = -1, y0 = img->height, y1 = -1;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const uint8_t *p = img->rgb + 3 * ((size_t)y * img->width + x);
            if (p[0] < 250 || p[1] < 250 || p[2] < 250) {
                x0 = x < x0 ? x : x0, x1 = x > x1 ? x : x1;
                y0 = y < y0 ? y : y0, y1 = y > y1 ? y : y1;
            }
        }
    if (x1 < 0) return CR_OK;
    x0 = x0 > 3 ? x0 - 3 : 0, y0 = y0 > 3 ? y0 - 3 : 0;
    x1 = x1 + 3 < img->width ? x1 + 3 : img->width - 1;
    y1 = y1 + 3 < img->height ? y1 + 3 : img->height - 1;
    cr_image c;
    CR_TRY(cr_image_create(x1 - x0 + 1, y1 - y0 + 1, &c, err));
    for (int y = 0; y < c.height; y++)
        memcpy(c.rgb + 3 * (size_t)y * c.width, img->rgb + 3 * ((size_t)(y0 + y) * img->width + x0),
               3 * (size_t)c.width);
    cr_image_free(img);
    *img = c;
    return CR_OK;
}

int main(int argc, char **argv) {
    int n = (argc - 6) / 4;
    if (argc < 10 || (argc - 6) % 4 != 0 || n > MAX_PAIRS) {
        fprintf(stderr,
                "usage: example_swingar_side_by_side OUT.png FRAME SIZE BODY.obj BODY.pc2 "
                "(PRED.obj PRED.pc2 SIM.obj SIM.pc2){1..%d}\n",
                MAX_PAIRS);
        return 2;
    }
    const int f = atoi(argv[2]), size = atoi(argv[3]);
    cr_error err = {0};
    cr_image tiles[MAX_PAIRS];
    for (int k = 0; k < n; k++) {
        char **a = argv + 6 + 4 * k;
        cr_mesh *m[4] = {NULL, NULL, NULL, NULL};
        if (posed(a[0], a[1], f, 0.0f, &m[0], &err) ||
            posed(argv[4], argv[5], f, 0.0f, &m[1], &err) ||
            posed(a[2], a[3], f, SHIFT_M, &m[2], &err) ||
            posed(argv[4], argv[5], f, SHIFT_M, &m[3], &err))
            return fail(&err);
        cr_render_def rd = cr_render_default_def();
        rd.width = rd.height = size;
        rd.yaw_deg = 0.0f, rd.pitch_deg = 10.0f, rd.supersample = 3;
        cr_render_object o[4] = {{.mesh = m[0], .color = {0.25f, 0.45f, 0.80f}},
                                 {.mesh = m[1], .color = {0.78f, 0.72f, 0.66f}},
                                 {.mesh = m[2], .color = {0.85f, 0.45f, 0.25f}},
                                 {.mesh = m[3], .color = {0.78f, 0.72f, 0.66f}}};
        if (cr_render_scene(&rd, o, 4, &tiles[k], &err) || crop(&tiles[k], &err)) return fail(&err);
        for (int i = 0; i < 4; i++)
            cr_mesh_destroy(m[i]);
    }
    cr_image grid;
    if (cr_image_grid(tiles, n, 2, 6, (float[]){1, 1, 1}, &grid, &err) ||
        cr_image_write_png(&grid, argv[1], &err))
        return fail(&err);
    printf("%s: %d pairs, %d x %d pixels, frame %d\n", argv[1], n, grid.width, grid.height, f);
    for (int k = 0; k < n; k++)
        cr_image_free(&tiles[k]);
    cr_image_free(&grid);
    return 0;
}
