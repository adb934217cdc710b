/* simulate.c: the low-resolution input of `gdsr run --simulate`, made by
 * the dataset machinery (cr_dataset_generate: garment templates, posed
 * body, motion preparation, simulator), so that one command goes from a
 * motion to wrinkles with exactly the kind of input the model was trained
 * on. No simulator loop of its own. */
#include "gdsr_internal.h"

#include "crease/dataset.h"
#include "crease/garment.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

cr_gdsr_sim_def cr_gdsr_sim_default_def(void) {
    cr_gdsr_sim_def d;
    memset(&d, 0, sizeof d);
    d.garment = "tshirt";
    d.body = "normal";
    d.frames = 60;
    return d;
}

/* like's manifest.json: the def fields not set in *dd. */
static cr_status read_like(const char *dir, cr_dataset_def *dd, int set_low, int set_high,
                           int set_fps, int set_mat, char *mat, size_t matsize, cr_error *err) {
    cr_dataset_manifest man;
    CR_TRY(cr_dataset_read(dir, &man, err));
    cr_status st = CR_OK;
    if (man.low_vertices <= 0 || man.high_vertices <= 0 || !(man.fps > 0.0f) || !man.material)
        st = CR_FAIL(err, CR_ERR_PARSE,
                     "%s/manifest.json: not a crease dataset manifest (def.low_vertices, "
                     "def.high_vertices, def.fps, def.material)",
                     dir);
    if (st == CR_OK) {
        if (!set_low) dd->low_vertices = man.low_vertices;
        if (!set_high) dd->high_vertices = man.high_vertices;
        if (!set_fps) dd->fps = man.fps;
        if (!set_mat) {
            snprintf(mat, matsize, "%s", man.material);
            dd->material = mat;
        }
    }
    cr_dataset_manifest_free(&man);
    return st;
}

cr_status cr_gdsr_simulate(const cr_gdsr_sim_def *def, cr_gdsr_data *out, cr_gdsr_sim_result *res,
                           cr_error *err) {
    memset(out, 0, sizeof *out);
    memset(res, 0, sizeof *res);
    if (!def->out_dir || !def->out_dir[0])
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr simulate: out_dir is not set");
    if (!def->motion || !def->motion[0])
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr simulate: no motion (a clip or a file)");
    const char *garment = def->garment ? def->garment : "tshirt";
    const char *body = def->body ? def->body : "normal";
    CR_TRY(cr_dataset_garment_label(garment, res->garment, sizeof res->garment, err));
    cr_dataset_motion_label(def->motion, res->motion, sizeof res->motion);

    cr_dataset_def dd = cr_dataset_default_def();
    char mat[64];
    if (def->like)
        CR_TRY(read_like(def->like, &dd, def->low_vertices > 0, def->high_vertices > 0,
                         def->fps > 0, def->material != NULL, mat, sizeof mat, err));
    if (def->low_vertices > 0) dd.low_vertices = def->low_vertices;
    if (def->high_vertices > 0) dd.high_vertices = def->high_vertices;
    if (def->fps > 0) dd.fps = def->fps;
    if (def->material) dd.material = def->material;
    static const char *const res_names[2] = {"low", "high"};
    dd.out_dir = def->out_dir;
    dd.garments = &garment, dd.ngarments = 1;
    dd.motions = &def->motion, dd.nmotions = 1;
    dd.bodies = &body, dd.nbodies = 1;
    dd.res = res_names, dd.nres = 2;
    dd.mesh_only_res = def->reference ? 0u : 2u; /* the high mesh and Eq. 1, no high run */
    dd.frames = def->frames > 0 ? def->frames : 60;
    dd.quiet = def->quiet;
    if (def->motion_import) dd.motion_import = *def->motion_import;
    if (def->motion_prepare) dd.motion_prepare = *def->motion_prepare;
    cr_dataset_result dr;
    CR_TRY(cr_dataset_generate(&dd, &dr, err));
    res->seconds = dr.seconds;
    res->max_inside_share = dr.max_inside_share[0];
    if (dr.failed > 0) {
        /* the reason is in the sequence's result.json (and the log) */
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr simulate: %d of %d sequences failed (see %s/sequences/*/result.json)",
                       dr.failed, dr.sequences, def->out_dir);
    }
    const char *m = res->motion;
    CR_TRY(cr_gdsr_data_load(def->out_dir, res->garment, body, &m, 1, out, err));
    res->low_vertices = out->low->nv;
    res->high_vertices = out->high->nv;
    return CR_OK;
}
