/* measure.c: the drape method's fidelity report against a reference drape
 * (Chamfer distance, penetration, mean-curvature spectrum: the measures
 * themselves live in eval/surface.c, shared with crease eval) and the
 * side-by-side run of all four variants (the paper's Fig. 1 and 8-10).
 *
 * Leaves out: curvature of the reference computed any other way than the
 * method's own surfaces (both go through the same code).
 */
#include "drape_internal.h"

#include "crease/eval.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* V vertices, S spectrum grid side. */

enum { LABEL_STRIP_PX = 44, COMPARE_RENDER_PX = 640 };

cr_status cr_drape_fidelity_measure(const cr_mesh *surface, const cr_mesh *reference,
                                    const cr_mesh *object, cr_drape_fidelity *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    out->chamfer_m = NAN;
    if (!cr_mesh_has_uv(surface) || (reference && !cr_mesh_has_uv(reference)))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape fidelity: the surface and the reference need UVs for the spectrum");
    cr_bvh *ob = NULL;
    CR_TRY(cr_bvh_build(object->pos, object->nv, object->tri, object->nf, &ob, err));
    out->max_penetration_m = cr_drape_max_penetration(ob, surface);
    cr_bvh_destroy(ob);
    if (reference) CR_TRY(cr_eval_chamfer_surface(surface, reference, &out->chamfer_m, err));
    return cr_eval_curvature_spectrum(surface, &out->h_rms, out->h_band, NULL, err);
}

/* ---------------------------------------------------------- compare -- */

/* The render with the variant's name underneath, into a new image. */
static cr_status labelled(const cr_image *render, const char *name, cr_image *out, cr_error *err) {
    CR_TRY(cr_image_create(render->width, render->height + LABEL_STRIP_PX, out, err));
    memset(out->rgb, 255, (size_t)out->width * out->height * 3);
    memcpy(out->rgb, render->rgb, (size_t)render->width * render->height * 3);
    const uint8_t ink[3] = {20, 20, 20};
    int scale = 3;
    cr_plot_text(out, (out->width - cr_plot_text_width(name, scale)) / 2, render->height + 10,
                 scale, name, ink);
    return CR_OK;
}

cr_status cr_drape_compare(const cr_drape_def *def, cr_drape_result *results, char *png_path,
                           size_t png_cap, cr_error *err) {
    CR_TRY(cr_drape_def_validate(def, err));
    if (!def->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "drape compare: needs -o DIR");
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    cr_mesh *object = NULL;
    CR_TRY(cr_drape_scene_object(def->scene, def->object_path, &object, err));
    cr_image cells[CR_DRAPE_VARIANT_COUNT] = {{0}};
    cr_status st = CR_OK;
    for (int v = 0; v < CR_DRAPE_VARIANT_COUNT && st == CR_OK; v++) {
        cr_drape_def d = *def;
        char dir[1200];
        snprintf(dir, sizeof dir, "%s/%s", def->out_dir,
                 cr_drape_variant_name((cr_drape_variant)v));
        d.variant = (cr_drape_variant)v;
        d.out_dir = dir;
        cr_drape_result res;
        cr_mesh *surface = NULL;
        st = cr_drape_run(&d, &res, &surface, err);
        if (st == CR_OK && results) results[v] = res;
        cr_image render = {0};
        if (st == CR_OK) st = cr_drape_render(surface, object, COMPARE_RENDER_PX, &render, err);
        if (st == CR_OK) st = labelled(&render, cr_drape_variant_name(d.variant), &cells[v], err);
        cr_image_free(&render);
        cr_mesh_destroy(surface);
    }
    cr_image grid = {0};
    const float white[3] = {1.0f, 1.0f, 1.0f};
    if (st == CR_OK) st = cr_image_grid(cells, CR_DRAPE_VARIANT_COUNT, 0, 8, white, &grid, err);
    if (st == CR_OK) {
        snprintf(png_path, png_cap, "%s/compare.png", def->out_dir);
        st = cr_image_write_png(&grid, png_path, err);
    }
    cr_image_free(&grid);
    for (int v = 0; v < CR_DRAPE_VARIANT_COUNT; v++)
        cr_image_free(&cells[v]);
    cr_mesh_destroy(object);
    return st;
}
