/* dataset.c: garment sequences on moving bodies, simulated by the reference
 * simulator and written as a self-describing dataset (see crease/dataset.h
 * for the layout).
 *
 * Order of work: the assets first, on all threads inside each step (bodies,
 * motions, posed bodies, garment templates at each resolution, low/high
 * correspondences), then the sequences, several at once with each simulator
 * on one thread (sequences are independent and a simulator of a few thousand
 * vertices scales poorly past one core). A sequence's result.json is written
 * last, so a run that stops leaves every finished sequence marked and the
 * next run skips it.
 *
 * An outfit (garments worn over each other, "tshirt+vest") is built by
 * dataset_outfit.c into one garment of one component per layer and
 * simulated with self-contact on, so its layers collide.
 *
 * Bodies are body specs (cr_body_resolve: a mannequin preset or an
 * SMPL-family file with its betas); garments may be mesh files from other
 * tools (cr_garment_load_user, fitted to each body as given). Left out:
 * distributing sequences over machines.
 */
#include "crease/dataset.h"

#include "crease/body.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "crease/phys_material.h"
#include "dataset_internal.h"

#include "crease/base_mpi.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const uint32_t DATASET_COOKIE = 0x44415441u; /* "DATA" */

cr_dataset_def cr_dataset_default_def(void) {
    cr_dataset_def d;
    memset(&d, 0, sizeof d);
    d.low_vertices = 2000;
    d.high_vertices = 8000;
    d.frames = 150;
    d.fps = 30.0f;
    d.material = "cotton";
    d.seed = 1;
    d.max_collider_step = 0.15;
    d.self_contact = -1;
    d.motion_import = cr_motion_import_default_def();
    d.motion_prepare = cr_motion_prepare_default_def();
    d.cookie = DATASET_COOKIE;
    return d;
}

/* ------------------------------------------------------------- checks -- */

static cr_status check_list(const char *what, const char *const *items, int n, cr_error *err) {
    if (n < 1 || n > CR_DATASET_MAX_ITEMS || !items)
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: %s: %d given, need 1 to %d", what, n,
                       CR_DATASET_MAX_ITEMS);
    for (int i = 0; i < n; i++) {
        if (!items[i] || !items[i][0] || strlen(items[i]) > 200)
            return CR_FAIL(err, CR_ERR_INVALID, "dataset: %s[%d] is empty or too long", what, i);
        for (int j = 0; j < i; j++)
            if (!strcmp(items[i], items[j]))
                return CR_FAIL(err, CR_ERR_INVALID, "dataset: %s: '%s' is listed twice", what,
                               items[i]);
    }
    return CR_OK;
}

static cr_status check_def(const cr_dataset_def *d, dataset *ds, cr_error *err) {
    if (!d->out_dir || !d->out_dir[0])
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: out_dir is not set");
    CR_TRY(check_list("garments", d->garments, d->ngarments, err));
    CR_TRY(check_list("motions", d->motions, d->nmotions, err));
    CR_TRY(check_list("bodies", d->bodies, d->nbodies, err));
    CR_TRY(check_list("res", d->res, d->nres, err));
    if (d->nres > 2)
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: %d resolutions; at most two (low, high)",
                       d->nres);
    if (d->frames < 1 || d->frames > 100000)
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: frames = %d, need 1 to 100000", d->frames);
    if (!(d->fps > 0.0f && d->fps <= 1000.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: fps = %g, need (0, 1000]", (double)d->fps);
    if (!(d->max_collider_step >= 0.0 && d->max_collider_step <= 10.0))
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: max_collider_step = %g m, need 0 to 10",
                       d->max_collider_step);
    for (int i = 0; i < d->ngarments; i++) {
        if ((ds->user_garment[i] = cr_dataset_garment_is_file(d->garments[i]))) {
            /* a garment from another tool: its file's base name labels it */
            if (d->nres != 1)
                return CR_FAIL(err, CR_ERR_INVALID,
                               "dataset: garment file %s is used at its own resolution: ask "
                               "for one --res, not %d",
                               d->garments[i], d->nres);
            memset(&ds->variant[i], 0, sizeof ds->variant[i]);
            cr_dataset_motion_label(d->garments[i], ds->variant[i].label,
                                    sizeof ds->variant[i].label);
            ds->garment_type[i] = CR_GARMENT_USER;
        } else {
            CR_TRY(cr_dataset_outfit_parse(d->garments[i], &ds->outfit[i], &ds->variant[i], err));
            ds->garment_type[i] = ds->variant[i].def.type;
        }
        for (int j = 0; j < i; j++)
            if (!strcmp(ds->variant[i].label, ds->variant[j].label))
                return CR_FAIL(err, CR_ERR_INVALID,
                               "dataset: garments '%s' and '%s' have the same label '%s'",
                               d->garments[j], d->garments[i], ds->variant[i].label);
    }
    /* Labels name the motion's files and sequences, so two motions with one
     * label would overwrite each other's. */
    for (int i = 0; i < d->nmotions; i++) {
        cr_dataset_motion_label(d->motions[i], ds->motion_name[i], sizeof ds->motion_name[i]);
        for (int j = 0; j < i; j++)
            if (!strcmp(ds->motion_name[i], ds->motion_name[j]))
                return CR_FAIL(err, CR_ERR_INVALID,
                               "dataset: motions '%s' and '%s' have the same label '%s' (their "
                               "files would overwrite each other's); rename one file",
                               d->motions[j], d->motions[i], ds->motion_name[i]);
    }
    for (int i = 0; i < d->nbodies; i++) {
        if (!strstr(d->bodies[i], ".npz") && !strstr(d->bodies[i], ".glb")) {
            /* a preset, checked now; a file is read with the assets */
            cr_mannequin_def md = cr_mannequin_default_def();
            CR_TRY(cr_mannequin_preset(d->bodies[i], &md, err));
        }
        cr_dataset_body_label(d->bodies[i], ds->body_label[i], sizeof ds->body_label[i]);
        for (int j = 0; j < i; j++)
            if (!strcmp(ds->body_label[i], ds->body_label[j]))
                return CR_FAIL(err, CR_ERR_INVALID,
                               "dataset: bodies '%s' and '%s' have the same label '%s'",
                               d->bodies[j], d->bodies[i], ds->body_label[i]);
    }
    for (int i = 0; i < d->nres; i++) {
        if (!strcmp(d->res[i], "low"))
            ds->res_vertices[i] = d->low_vertices;
        else if (!strcmp(d->res[i], "high"))
            ds->res_vertices[i] = d->high_vertices;
        else
            return CR_FAIL(err, CR_ERR_INVALID, "dataset: resolution '%s': expected low or high",
                           d->res[i]);
        if (ds->res_vertices[i] < 500 || ds->res_vertices[i] > 100000)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "dataset: %s resolution of %d vertices: need 500 "
                           "to 100000",
                           d->res[i], ds->res_vertices[i]);
    }
    cr_material mat;
    return cr_material_preset(d->material ? d->material : "", &mat, err);
}

/* ------------------------------------------------------------- assets -- */

void cr_dataset_motion_label(const char *spec, char *out, size_t size) {
    const char *glb = strstr(spec, ".glb");
    if (glb && glb[4] == ':') { /* a character's own animation, by its joint map */
        cr_dataset_body_label(spec, out, size);
        return;
    }
    const char *base = strrchr(spec, '/');
    base = base ? base + 1 : spec;
    snprintf(out, size, "%s", base);
    char *dot = strrchr(out, '.');
    if (dot && dot != out) *dot = '\0';
}

int cr_dataset_garment_is_file(const char *spec) {
    const char *dot = spec ? strrchr(spec, '.') : NULL;
    return dot &&
           (!strcasecmp(dot, ".obj") || !strcasecmp(dot, ".ply") || !strcasecmp(dot, ".glb"));
}

void cr_dataset_body_label(const char *spec, char *out, size_t size) {
    const char *npz = strstr(spec, ".npz"), *glb = strstr(spec, ".glb");
    const char *ext = npz ? npz : glb;
    if (!ext || size < 2) {
        snprintf(out, size, "%s", spec);
        return;
    }
    const char *base = spec;
    for (const char *c = spec; c < ext; c++)
        if (*c == '/') base = c + 1;
    size_t n = 0;
    for (const char *c = base; c < ext && n + 1 < size; c++)
        out[n++] = *c;
    if (npz && npz[4] == ':' && n + 2 < size) { /* the betas, as a name can hold them */
        out[n++] = '_', out[n++] = 'b';
        for (const char *c = npz + 5; *c && n + 1 < size; c++)
            out[n++] = *c == '.' ? 'p' : *c == '-' ? 'm' : (*c == ',' || *c == ':') ? '_' : *c;
    } else if (!npz && glb[4] == ':' && n + 1 < size) { /* the joint map's base name */
        const char *map = glb + 5, *slash = strrchr(map, '/'), *dot;
        map = slash ? slash + 1 : map;
        dot = strrchr(map, '.');
        out[n++] = '_';
        for (const char *c = map; *c && c != dot && n + 1 < size; c++)
            out[n++] = *c;
    }
    out[n] = '\0';
}

/* The crossing triangle pairs of garment [b][g][r] as built, into
 * rest_crossings. */
static cr_status count_rest_crossings(dataset *ds, int b, int g, int r, cr_error *err) {
    const cr_mesh *gm = ds->garment[b][g][r]->mesh;
    cr_bvh *cloth = NULL;
    int64_t n = cr_dataset_crossings(&cloth, gm, gm->pos, err);
    cr_bvh_destroy(cloth);
    ds->rest_crossings[b][g][r] = n;
    return n < 0 ? (err ? err->status : CR_ERR_MEMORY) : CR_OK;
}

static cr_status write_body(const dataset *ds, const char *name, const cr_body_model *b,
                            cr_error *err) {
    char path[CR_DATASET_PATH];
    snprintf(path, sizeof path, "%s/bodies/%s/rest.obj", ds->def.out_dir, name);
    CR_TRY(cr_mesh_write(path, b->rest, err));
    snprintf(path, sizeof path, "%s/bodies/%s/skin.npz", ds->def.out_dir, name);
    cr_npz_writer *w = NULL;
    CR_TRY(cr_npz_writer_open(path, 1, &w, err));
    int64_t js[2] = {CR_NJOINTS, 3}, ws[2] = {b->rest->nv, 4};
    cr_status st = cr_npz_writer_add(w, "joints", CR_NPY_F32, 2, js, b->joints, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "skin_joint", CR_NPY_I32, 2, ws, b->skin_joint, err);
    if (st == CR_OK)
        st = cr_npz_writer_add(w, "skin_weight", CR_NPY_F32, 2, ws, b->skin_weight, err);
    if (st != CR_OK) {
        cr_npz_writer_abort(w);
        return st;
    }
    return cr_npz_writer_commit(w, err);
}

static cr_status write_garment(const dataset *ds, const char *body, const char *name,
                               const char *res, const cr_garment *g, cr_error *err) {
    char path[CR_DATASET_PATH];
    snprintf(path, sizeof path, "%s/garments/%s/%s_%s.obj", ds->def.out_dir, body, name, res);
    CR_TRY(cr_mesh_write(path, g->mesh, err));
    snprintf(path, sizeof path, "%s/garments/%s/%s_%s_skin.npz", ds->def.out_dir, body, name, res);
    cr_npz_writer *w = NULL;
    CR_TRY(cr_npz_writer_open(path, 1, &w, err));
    int64_t ws[2] = {g->mesh->nv, 4}, fs[1] = {g->mesh->nf};
    cr_status st = cr_npz_writer_add(w, "skin_joint", CR_NPY_I32, 2, ws, g->skin_joint, err);
    if (st == CR_OK)
        st = cr_npz_writer_add(w, "skin_weight", CR_NPY_F32, 2, ws, g->skin_weight, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "panel", CR_NPY_I32, 1, fs, g->panel, err);
    if (st != CR_OK) {
        cr_npz_writer_abort(w);
        return st;
    }
    return cr_npz_writer_commit(w, err);
}

/* gdsr Eq. 1: every high vertex's (low face, barycentric). */
static cr_status write_correspondence(const dataset *ds, const char *body, const char *name,
                                      const cr_garment *low, const cr_garment *high,
                                      cr_error *err) {
    int32_t nv = high->mesh->nv;
    int32_t *face = cr_malloc((size_t)nv * sizeof(int32_t), err);
    float *bary = cr_malloc((size_t)nv * 3 * sizeof(float), err);
    cr_status st = face && bary ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_garment_correspondence(low->mesh, high->mesh, face, bary, err);
    char path[CR_DATASET_PATH];
    snprintf(path, sizeof path, "%s/garments/%s/%s_high_from_low.npz", ds->def.out_dir, body, name);
    cr_npz_writer *w = NULL;
    if (st == CR_OK) st = cr_npz_writer_open(path, 1, &w, err);
    int64_t fs[1] = {nv}, bs[2] = {nv, 3};
    if (st == CR_OK) st = cr_npz_writer_add(w, "face", CR_NPY_I32, 1, fs, face, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "bary", CR_NPY_F32, 2, bs, bary, err);
    if (st == CR_OK)
        st = cr_npz_writer_commit(w, err);
    else
        cr_npz_writer_abort(w);
    free(face), free(bary);
    return st;
}

/* With both resolutions: garment g's correspondence on body b. */
static cr_status write_pair(const dataset *ds, int b, int g, cr_error *err) {
    int lo = -1, hi = -1;
    for (int r = 0; r < ds->def.nres; r++)
        if (!strcmp(ds->def.res[r], "low"))
            lo = r;
        else
            hi = r;
    if (lo < 0 || hi < 0) return CR_OK;
    return write_correspondence(ds, ds->body_label[b], ds->variant[g].label, ds->garment[b][g][lo],
                                ds->garment[b][g][hi], err);
}

static cr_status make_dirs(const dataset *ds, cr_error *err) {
    char path[CR_DATASET_PATH];
    const char *sub[] = {"motions", "sequences"};
    for (size_t i = 0; i < sizeof sub / sizeof sub[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", ds->def.out_dir, sub[i]);
        CR_TRY(cr_mkdir_p(path, err));
    }
    for (int b = 0; b < ds->def.nbodies; b++) {
        snprintf(path, sizeof path, "%s/bodies/%s", ds->def.out_dir, ds->body_label[b]);
        CR_TRY(cr_mkdir_p(path, err));
        snprintf(path, sizeof path, "%s/garments/%s", ds->def.out_dir, ds->body_label[b]);
        CR_TRY(cr_mkdir_p(path, err));
    }
    return CR_OK;
}

static cr_status make_assets(dataset *ds, cr_progress *bar, cr_error *err) {
    const cr_dataset_def *d = &ds->def;
    int64_t step = 0;
    for (int m = 0; m < d->nmotions; m++) {
        cr_motion_prepare_report *rep = &ds->motion_rep[m];
        cr_motion_resolve_def rd = cr_motion_resolve_default_def();
        rd.clip_frames = d->frames + 1, rd.fps = d->fps;
        rd.import = d->motion_import, rd.prepare = d->motion_prepare;
        CR_TRY(cr_motion_resolve(d->motions[m], &rd, &ds->motion[m], rep, err));
        char path[CR_DATASET_PATH];
        snprintf(path, sizeof path, "%s/motions/%s.npz", d->out_dir, ds->motion_name[m]);
        CR_TRY(cr_motion_save(path, ds->motion[m], err));
        cr_progress_update(bar, ++step, "motion %s", ds->motion_name[m]);
    }
    for (int b = 0; b < d->nbodies; b++) {
        const char *label = ds->body_label[b];
        CR_TRY(cr_body_resolve(d->bodies[b], &ds->body[b], err));
        CR_TRY(write_body(ds, label, ds->body[b], err));
        for (int m = 0; m < d->nmotions; m++) {
            CR_TRY(cr_body_pose_motion(ds->body[b], ds->motion[m], &ds->posed[b][m], err));
            char path[CR_DATASET_PATH];
            snprintf(path, sizeof path, "%s/bodies/%s/%s.pc2", d->out_dir, label,
                     ds->motion_name[m]);
            CR_TRY(cr_pc2_write(path, ds->posed[b][m], ds->body[b]->rest->nv,
                                ds->motion[m]->nframes, 0.0f, 1.0f, err));
        }
        for (int g = 0; g < d->ngarments; g++) {
            if (ds->user_garment[g]) { /* a mesh file, fitted to this body as given */
                ds->built[b][g] = ds->variant[g];
                cr_garment_user_def ud = cr_garment_user_default_def();
                CR_TRY(cr_garment_load_user(d->garments[g], &ud, ds->body[b], &ds->garment[b][g][0],
                                            err));
                CR_TRY(count_rest_crossings(ds, b, g, 0, err));
                CR_TRY(write_garment(ds, label, ds->variant[g].label, d->res[0],
                                     ds->garment[b][g][0], err));
                cr_progress_update(bar, ++step, "%s on %s", ds->variant[g].label, label);
                continue;
            }
            if (ds->outfit[g].nparts) { /* layers merged into one garment: dataset_outfit.c */
                ds->built[b][g] = ds->variant[g];
                CR_TRY(cr_dataset_outfit_build(ds, b, g, err));
                for (int r = 0; r < d->nres; r++)
                    CR_TRY(write_garment(ds, label, ds->variant[g].label, d->res[r],
                                         ds->garment[b][g][r], err));
                CR_TRY(write_pair(ds, b, g, err));
                cr_progress_update(bar, ++step, "%s on %s", ds->variant[g].label, label);
                continue;
            }
            /* A random variant is drawn and checked at the lowest resolution
             * asked; a fixed one is built as given. */
            cr_garment_variant *v = &ds->built[b][g];
            *v = ds->variant[g];
            v->def.target_vertices = ds->res_vertices[0];
            for (int r = 1; r < d->nres; r++)
                if (ds->res_vertices[r] < v->def.target_vertices)
                    v->def.target_vertices = ds->res_vertices[r];
            cr_garment_template *t = NULL;
            if (v->random)
                CR_TRY(cr_garment_variant_build(v, ds->body[b], &t, err));
            else
                CR_TRY(cr_garment_template_create(&v->def, ds->body[b], &t, err));
            cr_status st = CR_OK;
            for (int r = 0; r < d->nres && st == CR_OK; r++) {
                st = cr_garment_template_instantiate(t, ds->res_vertices[r], ds->body[b],
                                                     &ds->garment[b][g][r], err);
                if (st == CR_OK) st = count_rest_crossings(ds, b, g, r, err);
                if (st == CR_OK)
                    st = write_garment(ds, label, v->label, d->res[r], ds->garment[b][g][r], err);
            }
            cr_garment_template_destroy(t);
            CR_TRY(st);
            CR_TRY(write_pair(ds, b, g, err));
            cr_progress_update(bar, ++step, "%s on %s", v->label, label);
        }
    }
    return CR_OK;
}

/* ----------------------------------------------------------- generate -- */

static void dataset_free(dataset *ds) {
    for (int b = 0; b < CR_DATASET_MAX_ITEMS; b++) {
        for (int m = 0; m < CR_DATASET_MAX_ITEMS; m++)
            free(ds->posed[b][m]);
        for (int g = 0; g < CR_DATASET_MAX_ITEMS; g++)
            for (int r = 0; r < 2; r++)
                cr_garment_destroy(ds->garment[b][g][r]);
        cr_body_model_destroy(ds->body[b]);
    }
    for (int m = 0; m < CR_DATASET_MAX_ITEMS; m++)
        cr_motion_destroy(ds->motion[m]);
    free(ds->seq);
    free(ds);
}

cr_status cr_dataset_generate(const cr_dataset_def *def, cr_dataset_result *out, cr_error *err) {
    CR_ASSERT(def && def->cookie == DATASET_COOKIE); /* made by cr_dataset_default_def */
    memset(out, 0, sizeof *out);
    double t0 = cr_time_now();
    dataset *ds = cr_calloc(1, sizeof(dataset), err);
    if (!ds) return err ? err->status : CR_ERR_MEMORY;
    ds->def = *def;
    if (!ds->def.material) ds->def.material = "cotton";
    cr_status st = check_def(&ds->def, ds, err);
    if (st == CR_OK) st = make_dirs(ds, err);
    cr_progress bar;
    if (st == CR_OK) {
        cr_progress_begin(&bar, "assets", def->nmotions + (int64_t)def->nbodies * def->ngarments,
                          def->quiet);
        st = make_assets(ds, &bar, err);
        cr_progress_end(&bar);
    }
    /* Under MPI every rank makes the assets (each needs them in memory; the
     * files are the same bytes, renamed into place atomically), plans, and
     * waits for all to have planned before any sequence runs; rank 0 alone
     * writes the manifest. */
    const int root = cr_mpi_rank() == 0;
    if (st == CR_OK) st = cr_dataset_plan(ds, err);
    if (st == CR_OK && root) st = cr_dataset_write_manifest(ds, err);
    if (st == CR_OK) st = cr_mpi_barrier(err);
    if (st == CR_OK) {
        cr_dataset_run_sequences(ds);
        if (root) st = cr_dataset_write_manifest(ds, err);
    }
    if (st == CR_OK) {
        out->sequences = ds->nseq;
        out->ngarments = def->ngarments;
        for (int g = 0; g < def->ngarments; g++) {
            out->max_crossings[g] = -1;
            for (int b = 0; b < def->nbodies; b++)
                for (int r = 0; r < def->nres; r++)
                    if (ds->rest_crossings[b][g][r] > out->rest_crossings[g])
                        out->rest_crossings[g] = ds->rest_crossings[b][g][r];
        }
        for (int i = 0; i < ds->nseq; i++) {
            const dataset_seq *q = &ds->seq[i];
            out->done += q->state == SEQ_DONE;
            out->skipped += q->state == SEQ_SKIPPED;
            out->failed += q->state == SEQ_FAILED;
            out->failed_by_garment[q->g] += q->state == SEQ_FAILED;
            out->seconds_by_garment[q->g] += q->seconds;
            if (q->state == SEQ_FAILED) continue;
            if (q->max_crossings > out->max_crossings[q->g])
                out->max_crossings[q->g] = q->max_crossings;
            out->max_inside_share[q->g] = fmax(out->max_inside_share[q->g], q->max_inside_share);
            out->max_inside_share_solver[q->g] =
                fmax(out->max_inside_share_solver[q->g], q->max_inside_share_solver);
        }
    }
    out->seconds = cr_time_now() - t0;
    dataset_free(ds);
    return st;
}
