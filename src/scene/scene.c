/* scene.c: the scenes and outputs of `crease simulate` and `crease
 * drape-static`: named collider objects, animated colliders from PC2, a flat
 * cloth above an object, a two-object render, and a run's record (per-frame
 * JSON lines, PC2 and glb sequences).
 *
 * Left out: streaming the sequence to disk (samples stay in memory until
 * cr_scene_record_write), cameras beyond the default orbit.
 * The scene sizes follow the Blender peer harness (shared/peers/blender_drape.py)
 * so that the two simulate the same thing.
 */
#include "crease/scene.h"
#include "crease/npz.h"
#include "crease/primitives.h"
#include "crease/render.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Object sizes, m, and tessellations: the defaults of `crease primitive`. */
#define SPHERE_RADIUS 0.3f
#define TORUS_MAJOR 0.3f
#define TORUS_MINOR 0.1f
#define PRISM_SIDE 0.4f
#define PRISM_LENGTH 0.8f
#define BOX_EDGE 0.4f

cr_status cr_scene_object_create(const char *spec, cr_mesh **out, cr_error *err) {
    *out = NULL;
    if (strcmp(spec, "sphere") == 0) return cr_prim_sphere_uv(SPHERE_RADIUS, 64, 32, out, err);
    if (strcmp(spec, "torus") == 0)
        return cr_prim_torus(TORUS_MAJOR, TORUS_MINOR, 64, 32, out, err);
    if (strcmp(spec, "prism") == 0) return cr_prim_prism(PRISM_SIDE, PRISM_LENGTH, out, err);
    if (strcmp(spec, "box") == 0) return cr_prim_box(BOX_EDGE, BOX_EDGE, BOX_EDGE, 8, out, err);
    return cr_mesh_read(spec, out, err);
}

cr_status cr_scene_animation_read(const char *pc2_path, const cr_mesh *collider,
                                  const char *collider_name, cr_pc2 *out, cr_error *err) {
    CR_TRY(cr_pc2_read(pc2_path, out, err));
    if (out->nv != collider->nv) {
        int32_t nv = out->nv;
        cr_pc2_free(out);
        return CR_FAIL(err, CR_ERR_SHAPE,
                       "%s: %d vertices per frame, but the collider %s has %d vertices", pc2_path,
                       nv, collider_name, collider->nv);
    }
    return CR_OK;
}

cr_status cr_scene_cloth_above(const cr_mesh *object, int32_t res, float size, float gap,
                               cr_mesh **out, cr_error *err) {
    CR_TRY(cr_prim_plane(res, res, size, size, out, err));
    float lo[3], hi[3];
    cr_mesh_bounds(object, lo, hi);
    const float t[3] = {0.5f * (lo[0] + hi[0]), hi[1] + gap, 0.5f * (lo[2] + hi[2])};
    cr_mesh_transform(*out, 1.0f, t);
    return CR_OK;
}

cr_status cr_scene_cloth_refine(const cr_mesh *coarse, int32_t coarse_res, cr_mesh *fine,
                                int32_t fine_res, cr_error *err) {
    if (coarse_res < 2 || (int64_t)coarse_res * coarse_res != coarse->nv)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "cloth refine: the coarse cloth has %d vertices, not %d x %d", coarse->nv,
                       coarse_res, coarse_res);
    if (fine_res < 2 || (int64_t)fine_res * fine_res != fine->nv)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "cloth refine: the fine cloth has %d vertices, not %d x %d", fine->nv,
                       fine_res, fine_res);
    const double scale = (double)(coarse_res - 1) / (fine_res - 1);
    for (int32_t k = 0; k < fine_res; k++) {
        double gk = k * scale;
        int32_t k0 = gk >= coarse_res - 1 ? coarse_res - 2 : (int32_t)gk;
        double tk = gk - k0;
        for (int32_t i = 0; i < fine_res; i++) {
            double gi = i * scale;
            int32_t i0 = gi >= coarse_res - 1 ? coarse_res - 2 : (int32_t)gi;
            double ti = gi - i0;
            const float *p00 = coarse->pos + 3 * ((int64_t)k0 * coarse_res + i0);
            const float *p01 = p00 + 3, *p10 = p00 + 3 * (int64_t)coarse_res, *p11 = p10 + 3;
            float *q = fine->pos + 3 * ((int64_t)k * fine_res + i);
            for (int d = 0; d < 3; d++)
                q[d] = (float)((1 - tk) * ((1 - ti) * p00[d] + ti * p01[d]) +
                               tk * ((1 - ti) * p10[d] + ti * p11[d]));
        }
    }
    return CR_OK;
}

cr_status cr_scene_settle(cr_sim *sim, int max_frames, double settled_speed,
                          cr_scene_state_fn on_state, void *ctx, cr_scene_settle_stats *stats,
                          cr_error *err) {
    memset(stats, 0, sizeof *stats);
    const double *mass = cr_sim_masses(sim);
    double total_mass = 0.0;
    for (int32_t i = 0; i < cr_sim_vertex_count(sim); i++)
        total_mass += mass[i];
    cr_sim_report rep;
    int settled = max_frames <= 0; /* the static solve comes next */
    for (int frame = 0;; frame++) {
        cr_status solved =
            settled ? cr_sim_solve_static(sim, &rep, err) : cr_sim_step(sim, &rep, err);
        if (solved != CR_OK && solved != CR_ERR_DIVERGED) return solved;
        stats->seconds += rep.seconds, stats->newton += rep.newton_iterations;
        stats->max_penetration_m = fmax(stats->max_penetration_m, rep.max_penetration_m);
        stats->contacts = rep.contacts;
        double speed = sqrt(2.0 * rep.kinetic_energy / total_mass);
        if (!settled) stats->settle_frames++;
        if (on_state) CR_TRY(on_state(ctx, sim, &rep, settled ? 0 : frame + 1, speed, err));
        if (solved != CR_OK) return solved;
        if (settled) {
            stats->converged = rep.newton_capped == 0;
            return CR_OK;
        }
        settled = speed < settled_speed || frame + 1 >= max_frames;
    }
}

cr_status cr_scene_settle_coarse(const cr_sim_def *def, const cr_mesh *object, int32_t coarse_res,
                                 float size, float gap, int max_frames, double settled_speed,
                                 cr_scene_state_fn on_state, void *ctx, cr_mesh *fine,
                                 int32_t fine_res, cr_scene_settle_stats *stats, cr_error *err) {
    cr_mesh *cloth = NULL;
    cr_sim *sim = NULL;
    cr_status st = cr_scene_cloth_above(object, coarse_res, size, gap, &cloth, err);
    if (st == CR_OK) st = cr_sim_create(def, cloth, &sim, err);
    if (st == CR_OK)
        st = cr_scene_settle(sim, max_frames, settled_speed, on_state, ctx, stats, err);
    if (st == CR_OK) {
        cr_sim_positions_f(sim, cloth->pos);
        st = cr_scene_cloth_refine(cloth, coarse_res, fine, fine_res, err);
    }
    cr_sim_destroy(sim);
    cr_mesh_destroy(cloth);
    return st;
}

/* A clone of `m` with positions `pos` (NULL: unchanged). */
static cr_status posed_clone(const cr_mesh *m, const float *pos, cr_mesh **out, cr_error *err) {
    CR_TRY(cr_mesh_clone(m, out, err));
    if (pos) memcpy((*out)->pos, pos, (size_t)m->nv * 3 * sizeof(float));
    return CR_OK;
}

cr_status cr_scene_render(const char *png_path, const cr_mesh *garment, const float *garment_pos,
                          const cr_mesh *collider, const float *collider_pos, int size,
                          cr_error *err) {
    cr_mesh *g = NULL, *c = NULL;
    cr_status st = posed_clone(garment, garment_pos, &g, err);
    if (st == CR_OK && collider) st = posed_clone(collider, collider_pos, &c, err);
    if (st == CR_OK) {
        cr_render_object objs[2] = {
            {.mesh = g, .color = {0.33f, 0.52f, 0.80f}}, /* cloth blue, as `crease render` */
            {.mesh = c, .color = {0.72f, 0.72f, 0.70f}},
        };
        cr_render_def def = cr_render_default_def();
        def.width = def.height = size;
        st = cr_render_to_png(&def, objs, c ? 2 : 1, png_path, err);
    }
    cr_mesh_destroy(g);
    cr_mesh_destroy(c);
    return st;
}

/* ---------------------------------------------------------- recording -- */

struct cr_scene_record {
    const cr_mesh *garment; /* borrowed */
    int32_t nsamples, cap;
    float *samples; /* (cap, V, 3) garment positions, m */
    int32_t nh;     /* hinges whose rest angles are kept; 0: none kept */
    float *rest;    /* (cap, H) rest angles per sample, rad, or NULL */
    FILE *log;
    char log_path[1024];
};

cr_status cr_scene_record_create(const char *log_path, const cr_sim *sim, const cr_mesh *garment,
                                 int32_t max_samples, cr_scene_record **out, cr_error *err) {
    *out = NULL;
    CR_ASSERT(max_samples >= 1 && cr_sim_vertex_count(sim) == garment->nv);
    cr_scene_record *r = cr_calloc(1, sizeof *r, err);
    if (!r) return CR_ERR_MEMORY;
    r->garment = garment;
    r->cap = max_samples;
    r->samples = cr_malloc((size_t)max_samples * (size_t)garment->nv * 3 * sizeof(float), err);
    if (!r->samples) {
        free(r);
        return CR_ERR_MEMORY;
    }
    snprintf(r->log_path, sizeof r->log_path, "%s", log_path);
    r->log = fopen(log_path, "w");
    if (!r->log) {
        cr_status st = CR_FAIL(err, CR_ERR_IO, "%s: cannot write: %s", log_path, strerror(errno));
        cr_scene_record_destroy(r);
        return st;
    }
    cr_sim_positions_f(sim, r->samples);
    r->nsamples = 1;
    *out = r;
    return CR_OK;
}

static void keep_rest(cr_scene_record *r, const cr_sim *sim, int32_t k) {
    const double *theta = cr_sim_rest_angles(sim);
    for (int32_t h = 0; h < r->nh; h++)
        r->rest[(size_t)k * (size_t)r->nh + h] = (float)theta[h];
}

cr_status cr_scene_record_keep_rest_angles(cr_scene_record *r, const cr_sim *sim, cr_error *err) {
    CR_ASSERT(r->nsamples == 1 && !r->rest);
    const int32_t nh = cr_sim_hinge_count(sim);
    if (nh <= 0) return CR_OK;
    r->rest = cr_malloc((size_t)r->cap * (size_t)nh * sizeof(float), err);
    if (!r->rest) return CR_ERR_MEMORY;
    r->nh = nh;
    keep_rest(r, sim, 0);
    return CR_OK;
}

void cr_scene_record_destroy(cr_scene_record *r) {
    if (!r) return;
    if (r->log) fclose(r->log);
    free(r->rest);
    free(r->samples);
    free(r);
}

/* JSON numbers must be finite: a non-finite value (a diverged frame's) becomes null. */
static void add_number(cJSON *o, const char *key, double v) {
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

cr_status cr_scene_record_frame(cr_scene_record *r, const cr_sim *sim, const cr_sim_report *rep,
                                cr_error *err) {
    cJSON *o = cJSON_CreateObject();
    if (!o) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory writing %s", r->log_path);
    /* A diverged frame did not complete: it is the one after the last good frame. */
    cJSON_AddNumberToObject(o, "frame", (double)(rep->diverged ? rep->frame + 1 : rep->frame));
    for (int t = 0; t < rep->nterms; t++)
        add_number(o, rep->term_name[t], rep->term_energy[t]);
    add_number(o, "kinetic", rep->kinetic_energy);
    add_number(o, "max_penetration_m", rep->max_penetration_m);
    cJSON_AddNumberToObject(o, "newton_iterations", rep->newton_iterations);
    cJSON_AddNumberToObject(o, "substeps", rep->substeps);
    cJSON_AddNumberToObject(o, "backoffs", rep->backoffs);
    cJSON_AddNumberToObject(o, "contacts", rep->contacts);
    cJSON_AddNumberToObject(o, "yielded", rep->yielded);
    add_number(o, "seconds", rep->seconds);
    add_number(o, "seconds_assembly", rep->seconds_assembly);
    add_number(o, "seconds_factor", rep->seconds_factor);
    add_number(o, "seconds_solve", rep->seconds_solve);
    add_number(o, "seconds_collision", rep->seconds_collision);
    if (rep->self_contact_detections > 0) {
        add_number(o, "seconds_self_contact", rep->seconds_self_contact);
        add_number(o, "self_contact_pairs", rep->self_contact_pairs);
    }
    if (rep->diverged) {
        cJSON_AddTrueToObject(o, "diverged");
        cJSON_AddStringToObject(o, "failure", rep->failure);
    }
    char *line = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (!line) return CR_FAIL(err, CR_ERR_MEMORY, "out of memory writing %s", r->log_path);
    int bad = fprintf(r->log, "%s\n", line) < 0 || fflush(r->log) != 0;
    cJSON_free(line);
    if (bad) return CR_FAIL(err, CR_ERR_IO, "%s: write failed: %s", r->log_path, strerror(errno));
    if (rep->diverged) return CR_OK;
    if (r->nsamples >= r->cap)
        return CR_FAIL(err, CR_ERR_RANGE, "scene record: more than %d samples", r->cap);
    cr_sim_positions_f(sim, r->samples + (size_t)r->nsamples * (size_t)r->garment->nv * 3);
    if (r->rest) keep_rest(r, sim, r->nsamples);
    r->nsamples++;
    return CR_OK;
}

int32_t cr_scene_record_samples(const cr_scene_record *r) {
    return r->nsamples;
}

const float *cr_scene_record_all(const cr_scene_record *r) {
    return r->samples;
}

const float *cr_scene_record_last(const cr_scene_record *r) {
    return r->samples + (size_t)(r->nsamples - 1) * (size_t)r->garment->nv * 3;
}

cr_status cr_scene_record_write(const cr_scene_record *r, const char *pc2_path,
                                const char *glb_path, float fps, cr_error *err) {
    if (pc2_path)
        CR_TRY(cr_pc2_write(pc2_path, r->samples, r->garment->nv, r->nsamples, 0.0f, 1.0f, err));
    if (glb_path)
        CR_TRY(cr_glb_write_sequence(glb_path, r->garment, r->samples, r->nsamples, fps, err));
    return CR_OK;
}

cr_status cr_scene_record_write_rest_angles(const cr_scene_record *r, const char *npy_path,
                                            cr_error *err) {
    if (!r->rest)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: the record kept no rest angles", npy_path);
    return cr_npy_write(npy_path, CR_NPY_F32, 2, (int64_t[]){r->nsamples, r->nh}, r->rest, err);
}

cr_status cr_scene_record_mesh(const cr_scene_record *r, cr_mesh **out, cr_error *err) {
    CR_TRY(posed_clone(r->garment, cr_scene_record_last(r), out, err));
    /* The garment file's normals describe its initial shape, not this one. */
    free((*out)->normal);
    (*out)->normal = NULL;
    return CR_OK;
}
