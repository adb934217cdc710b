/* simulate.c: the whole runs behind `crease simulate` (a garment against a
 * static or animated collider) and `crease drape-static` (a square cloth
 * settled over an object): read and set up the scene, run it, write the
 * outputs. The tool parses, calls one of these, and reports. */
#include "crease/scene.h"

#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum { DEFAULT_RENDER_SIZE = 800 };

/* --------------------------------------------------------------- twin -- */

cr_scene_twin cr_scene_twin_default(void) {
    return (cr_scene_twin){.offset = {0.0f, 0.0f, CR_SCENE_TWIN_OFFSET_M}};
}

int cr_scene_twin_is_set(const cr_scene_twin *t) {
    return t->offset[0] != 0.0f || t->offset[1] != 0.0f || t->offset[2] != 0.0f ||
           t->friction_delta != 0.0;
}

cr_status cr_scene_twin_material(const cr_scene_twin *t, cr_material *m, cr_error *err) {
    if (!isfinite(t->friction_delta) || !isfinite(t->offset[0]) || !isfinite(t->offset[1]) ||
        !isfinite(t->offset[2]))
        return CR_FAIL(err, CR_ERR_INVALID, "twin: the perturbation must be finite");
    if (m->friction + t->friction_delta < 0.0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "twin: friction %g + change %g is below 0 (material %s)", m->friction,
                       t->friction_delta, m->name);
    m->friction += t->friction_delta;
    return CR_OK;
}

/* ----------------------------------------------------------- simulate -- */

cr_scene_sim_def cr_scene_sim_default_def(void) {
    return (cr_scene_sim_def){.material = "cotton",
                              .fps = 30.0f,
                              .render_size = DEFAULT_RENDER_SIZE,
                              .self_contact = -1,
                              .vbd_coarse_every = -1,
                              .body_ease_in_s = 1.0f,
                              .body_start_frame = -1,
                              .body_end_frame = -1,
                              .pose_def = cr_motion_resolve_default_def()};
}

/* A .glb body carries its own animation (a skinned character or a morph-target sequence). */
static int is_glb(const char *path) {
    char ext[16];
    cr_path_ext(path, ext, sizeof ext);
    return strcmp(ext, "glb") == 0;
}

static cr_status sim_validate(const cr_scene_sim_def *d, cr_error *err) {
    if (!d->garment) return CR_FAIL(err, CR_ERR_INVALID, "simulate: no garment");
    if (!d->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "simulate: no output folder");
    if (d->frames < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: frames %d, expected >= 1", d->frames);
    if (!(d->fps > 0.0f) || !isfinite(d->fps))
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: fps %g, expected > 0", (double)d->fps);
    if (d->object && d->body_mesh)
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: an object or a body mesh, not both");
    if (d->body && !d->object && !d->body_mesh)
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: %s animates no collider", d->body);
    if (d->body_mesh && !d->body && !is_glb(d->body_mesh))
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: body mesh %s without its animation",
                       d->body_mesh);
    if (d->body_motion && (!d->body_mesh || d->body || !is_glb(d->body_mesh)))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "simulate: the motion %s drives a rigged .glb body mesh (and no PC2)",
                       d->body_motion);
    if (d->joint_map && !d->body_motion)
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: the joint map %s maps no motion",
                       d->joint_map);
    if (d->pose_motion && (d->object || d->body_mesh || d->body))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "simulate: the motion %s poses a body model: no object, body mesh or "
                       "PC2 beside it",
                       d->pose_motion);
    if (d->render_size < 16)
        return CR_FAIL(err, CR_ERR_INVALID, "simulate: render size %d, expected >= 16",
                       d->render_size);
    return CR_OK;
}

/* Everything a run holds, released together. */
typedef struct sim_run {
    cr_mesh *garment, *collider;
    cr_pc2 anim;
    cr_glb_character *character; /* a rigged body driven by body_motion */
    cr_skin_motion *character_motion;
    cr_body_model *pose_body; /* a body model posed by pose_motion */
    cr_motion *pose_motion;
    cr_sim *sim;
    cr_scene_record *rec;
} sim_run;

static void sim_run_free(sim_run *r) {
    cr_skin_motion_destroy(r->character_motion);
    cr_glb_character_destroy(r->character);
    cr_motion_destroy(r->pose_motion);
    cr_body_model_destroy(r->pose_body);
    cr_scene_record_destroy(r->rec);
    cr_sim_destroy(r->sim);
    cr_pc2_free(&r->anim);
    cr_mesh_destroy(r->collider);
    cr_mesh_destroy(r->garment);
}

/* A rigged .glb driven by a BVH or another character's animation: read, retarget, drop a
 * calibration frame, ease in from rest at the run's rate, pose; the collider is the character's
 * rest mesh and frames.
 */
static cr_status character_setup(const cr_scene_sim_def *o, sim_run *r, cr_error *err) {
    CR_TRY(cr_glb_read_character(o->body_mesh, &r->character, err));
    cr_retarget_def rd = cr_retarget_default_def();
    rd.joint_map = o->joint_map;
    rd.import.bvh_scale = o->body_bvh_scale;
    cr_skin_motion *raw = NULL;
    CR_TRY(cr_motion_retarget(o->body_motion, &r->character->skin, o->body_mesh, &rd, &raw, err));
    /* the frames asked for; without a start, a calibration T-pose at frame 0 is dropped, as
     * cr_motion_prepare drops one for the mannequin: eased into and left in one frame, the
     * arms would sweep through the garment */
    cr_skin_motion used = *raw;
    const int32_t first = o->body_start_frame > 0 ? o->body_start_frame : 0;
    const int32_t last = o->body_end_frame >= 0 ? o->body_end_frame : raw->nframes - 1;
    if (first >= raw->nframes || last < first || last >= raw->nframes) {
        const int count = raw->nframes;
        cr_skin_motion_destroy(raw);
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: frames %d..%d asked for, the file has 0..%d (start <= end < count)",
                       o->body_motion, (int)first, (int)last, count - 1);
    }
    used.rotation += 4 * (size_t)raw->njoints * first, used.translation += 3 * (size_t)first;
    used.nframes = last - first + 1;
    float jump = 0.0f;
    if (o->body_start_frame < 0 && used.nframes > 1 &&
        cr_skin_motion_is_calibration_start(&used, &jump)) {
        cr_log(CR_LOG_WARN,
               "%s: frame 0 is a calibration frame (joints turn by up to %.2f rad into frame 1): "
               "dropped",
               o->body_motion, (double)jump);
        used.rotation += 4 * (size_t)raw->njoints, used.translation += 3, used.nframes--;
    }
    cr_status st =
        cr_skin_motion_prepare(&used, o->fps, o->body_ease_in_s, &r->character_motion, err);
    cr_skin_motion_destroy(raw);
    CR_TRY(st);
    const cr_glb_skin_motion view = cr_skin_motion_view(r->character_motion);
    CR_TRY(cr_glb_character_pose(r->character, &view, &r->anim.frames, err));
    r->anim.nframes = r->character_motion->nframes;
    r->anim.nv = r->character->rest->nv;
    r->collider = r->character->rest;
    r->character->rest = NULL; /* the run owns the mesh now */
    if (r->anim.nframes < o->frames + 1)
        cr_log(CR_LOG_WARN, "%s: %d frames (with the ease-in) for %d; the body holds its last pose",
               o->body_motion, r->anim.nframes, o->frames);
    return CR_OK;
}

/* A body model posed by a motion (pose_motion): resolved, prepared against that body at
 * the run's rate, skinned, written as out_dir/body.obj and body.pc2; the collider is its
 * rest mesh and frames. */
static cr_status posed_setup(const cr_scene_sim_def *o, sim_run *r, cr_scene_sim_result *out,
                             cr_error *err) {
    CR_TRY(cr_mkdir_p(o->out_dir, err));
    CR_TRY(cr_body_resolve(o->pose_body ? o->pose_body : "normal", &r->pose_body, err));
    cr_motion_resolve_def rd = o->pose_def;
    rd.fps = o->fps, rd.body = r->pose_body;
    CR_TRY(cr_motion_resolve(o->pose_motion, &rd, &r->pose_motion, NULL, err));
    CR_TRY(cr_body_pose_motion(r->pose_body, r->pose_motion, &r->anim.frames, err));
    r->anim.nframes = r->pose_motion->nframes;
    r->anim.nv = r->pose_body->rest->nv;
    snprintf(out->body_mesh, sizeof out->body_mesh, "%s/body.obj", o->out_dir);
    snprintf(out->body_pc2, sizeof out->body_pc2, "%s/body.pc2", o->out_dir);
    CR_TRY(cr_mesh_write(out->body_mesh, r->pose_body->rest, err));
    CR_TRY(
        cr_pc2_write(out->body_pc2, r->anim.frames, r->anim.nv, r->anim.nframes, 0.0f, 1.0f, err));
    CR_TRY(cr_mesh_clone(r->pose_body->rest, &r->collider, err));
    if (r->anim.nframes < o->frames + 1)
        cr_log(CR_LOG_WARN, "%s: %d frames (with the ease-in) for %d; the body holds its last pose",
               o->pose_motion, r->anim.nframes, o->frames);
    return CR_OK;
}

static cr_status sim_setup(const cr_scene_sim_def *o, sim_run *r, cr_sim_def *def,
                           cr_scene_sim_result *out, cr_error *err) {
    CR_TRY(cr_material_preset(o->material, &def->material, err));
    if (o->material_json) CR_TRY(cr_material_load_json(o->material_json, &def->material, err));
    CR_TRY(cr_scene_twin_material(&o->twin, &def->material, err));
    CR_TRY(cr_mesh_read(o->garment, &r->garment, err));
    if (o->garment_offset) cr_mesh_transform(r->garment, 1.0f, o->garment_offset);
    if (cr_scene_twin_is_set(&o->twin)) cr_mesh_transform(r->garment, 1.0f, o->twin.offset);
    const char *cname = o->object ? o->object : o->body_mesh;
    if (o->body_motion || o->pose_motion) {
        CR_TRY(o->body_motion ? character_setup(o, r, err) : posed_setup(o, r, out, err));
        def->collider = r->collider;
        def->collider_frames = r->anim.frames;
        def->collider_nframes = r->anim.nframes;
        cname = NULL;
    } else if (o->body_mesh && !o->body && is_glb(o->body_mesh)) {
        /* Posed by the file's own animation: frame f of the run at its key f. */
        float fps = 0.0f;
        CR_TRY(cr_glb_read_sequence(o->body_mesh, &r->collider, &r->anim.frames, &r->anim.nframes,
                                    &fps, err));
        r->anim.nv = r->collider->nv;
        def->collider = r->collider;
        def->collider_frames = r->anim.frames;
        def->collider_nframes = r->anim.nframes;
        if (fps > 0.0f && fabsf(fps - o->fps) > 1e-3f * o->fps)
            cr_log(CR_LOG_WARN, "%s: animated at %g fps, simulated at %g: one key a frame",
                   o->body_mesh, (double)fps, (double)o->fps);
        cname = NULL;
    }
    if (cname) {
        CR_TRY(o->object ? cr_scene_object_create(o->object, &r->collider, err)
                         : cr_mesh_read(o->body_mesh, &r->collider, err));
        def->collider = r->collider;
    }
    if (o->body) {
        CR_TRY(cr_scene_animation_read(o->body, r->collider, cname, &r->anim, err));
        def->collider_frames = r->anim.frames;
        def->collider_nframes = r->anim.nframes;
        if (r->anim.nframes < o->frames + 1)
            cr_log(CR_LOG_WARN, "%s: %d samples for %d frames; the collider holds its last pose",
                   o->body, r->anim.nframes, o->frames);
    }
    def->dt = 1.0 / o->fps;
    if (o->substeps > 0) def->substeps = o->substeps;
    def->max_collider_step = o->max_collider_step;
    if (o->newton_iterations > 0) def->newton_max_iterations = o->newton_iterations;
    if (o->vbd_iterations > 0) def->vbd_iterations = o->vbd_iterations;
    if (o->vbd_tol > 0.0f) def->vbd_tol = o->vbd_tol;
    if (o->vbd_coarse_every >= 0) def->vbd_coarse_every = o->vbd_coarse_every;
    if (o->vbd_coarse_rings > 0) def->vbd_coarse_rings = o->vbd_coarse_rings;
    if (o->vbd_coarse_refresh > 0) def->vbd_coarse_refresh = o->vbd_coarse_refresh;
    def->plasticity = o->plastic;
    def->solver = (cr_sim_solver)o->solver;
    if (o->self_contact >= 0) def->self_contact = o->self_contact;
    if (o->self_thickness > 0.0f) def->self_contact_thickness = o->self_thickness;
    def->pinned = o->pins;
    def->npinned = o->npins;
    CR_TRY(cr_sim_create(def, r->garment, &r->sim, err));
    CR_TRY(cr_mkdir_p(o->out_dir, err));
    out->vertices = r->garment->nv;
    snprintf(out->material, sizeof out->material, "%s", def->material.name);
    snprintf(out->pc2, sizeof out->pc2, "%s/sim.pc2", o->out_dir);
    snprintf(out->glb, sizeof out->glb, "%s/sim.glb", o->out_dir);
    snprintf(out->png, sizeof out->png, "%s/last.png", o->out_dir);
    snprintf(out->log, sizeof out->log, "%s/frames.jsonl", o->out_dir);
    CR_TRY(cr_scene_record_create(out->log, r->sim, r->garment, o->frames + 1, &r->rec, err));
    if (!o->plastic) return CR_OK;
    snprintf(out->rest_angles, sizeof out->rest_angles, "%s/rest_angles.npy", o->out_dir);
    return cr_scene_record_keep_rest_angles(r->rec, r->sim, err);
}

static int character_roots(const cr_glb_skin *s) {
    int n = 0;
    for (int32_t j = 0; j < s->njoints; j++)
        n += s->parent[j] < 0;
    return n;
}

static cr_status sim_progress(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                              const cr_scene_run_stats *so_far, cr_error *err) {
    (void)sim, (void)err;
    cr_progress_update(ctx, so_far->frames, "%d Newton its, %.2f mm deepest",
                       rep->newton_iterations, 1e3 * rep->max_penetration_m);
    return CR_OK;
}

cr_status cr_scene_simulate(const cr_scene_sim_def *o, cr_scene_sim_result *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    CR_TRY(sim_validate(o, err));
    cr_sim_def def = cr_sim_default_def();
    sim_run r = {0};
    cr_status st = sim_setup(o, &r, &def, out, err);
    if (st == CR_OK) {
        cr_progress bar;
        cr_progress_begin(&bar, "simulate", o->frames, o->quiet);
        st = cr_scene_run(r.sim, o->frames, r.rec, sim_progress, &bar, &out->run, err);
        cr_progress_end(&bar);
        /* a divergence ends the run; what came before it is written */
        if (st == CR_ERR_DIVERGED && out->run.diverged) st = CR_OK;
    }
    if (st == CR_OK) st = cr_scene_record_write(r.rec, out->pc2, out->glb, o->fps, err);
    if (st == CR_OK && out->rest_angles[0])
        st = cr_scene_record_write_rest_angles(r.rec, out->rest_angles, err);
    if (st == CR_OK && r.pose_motion) {
        /* The body's frames and the garment's samples, as many as both have. */
        cr_motion m = *r.pose_motion;
        int32_t n = cr_scene_record_samples(r.rec);
        if (n < m.nframes) m.nframes = n;
        snprintf(out->scene, sizeof out->scene, "%s/scene.glb", o->out_dir);
        st = cr_body_write_glb(out->scene, r.pose_body, &m, r.garment, cr_scene_record_all(r.rec),
                               err);
    }
    if (st == CR_OK && r.character_motion && character_roots(&r.character->skin) == 1) {
        /* the character as driven (crease's writer moves one root), the garment beside it */
        cr_glb_skin_motion m = cr_skin_motion_view(r.character_motion);
        int32_t n = cr_scene_record_samples(r.rec);
        if (n < m.nframes) m.nframes = n;
        const cr_glb_cloth cloth = {r.garment, cr_scene_record_all(r.rec)};
        snprintf(out->scene, sizeof out->scene, "%s/scene.glb", o->out_dir);
        st = cr_glb_write_skinned(out->scene, r.collider, &r.character->skin, &m, &cloth, err);
    }
    if (st == CR_OK) {
        const float *cpos = NULL;
        if (r.anim.frames) {
            int32_t done = out->run.frames;
            int32_t k = done < r.anim.nframes - 1 ? done : r.anim.nframes - 1;
            cpos = r.anim.frames + (size_t)k * (size_t)r.anim.nv * 3;
        }
        st = cr_scene_render(out->png, r.garment, cr_scene_record_last(r.rec), r.collider, cpos,
                             o->render_size, err);
    }
    sim_run_free(&r);
    return st;
}

/* ------------------------------------------------------- drape-static -- */

cr_scene_drape_static_def cr_scene_drape_static_default_def(void) {
    return (cr_scene_drape_static_def){.res = 64,
                                       .size = 1.0f,
                                       .gap = 0.05f,
                                       .material = "cotton",
                                       .max_frames = 150,
                                       .self_contact = -1,
                                       .render_size = DEFAULT_RENDER_SIZE};
}

static cr_status drape_validate(const cr_scene_drape_static_def *d, cr_error *err) {
    if (!d->object) return CR_FAIL(err, CR_ERR_INVALID, "drape-static: no object");
    if (!d->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "drape-static: no output folder");
    if (d->res < 2)
        return CR_FAIL(err, CR_ERR_INVALID, "drape-static: res %d, expected >= 2", d->res);
    if (d->coarse < 0 || (d->coarse > 0 && (d->coarse < 2 || d->coarse >= d->res)))
        return CR_FAIL(err, CR_ERR_INVALID, "drape-static: coarse %d, expected 0 or 2 .. %d",
                       d->coarse, d->res - 1);
    if (d->max_frames < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "drape-static: max frames %d, expected >= 0",
                       d->max_frames);
    if (!(d->size > 0.0f) || !(d->gap >= 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape-static: size %g and gap %g, expected > 0 and >= 0", (double)d->size,
                       (double)d->gap);
    if (d->render_size < 16)
        return CR_FAIL(err, CR_ERR_INVALID, "drape-static: render size %d, expected >= 16",
                       d->render_size);
    return CR_OK;
}

/* Every state goes to the record; settling frames also move the bar. */
typedef struct state_ctx {
    cr_scene_record *rec;
    cr_progress bar;
} state_ctx;

static cr_status record_state(void *vctx, const cr_sim *sim, const cr_sim_report *rep, int frame,
                              double rms_speed, cr_error *err) {
    state_ctx *c = vctx;
    CR_TRY(cr_scene_record_frame(c->rec, sim, rep, err));
    if (frame > 0) cr_progress_update(&c->bar, frame, "rms speed %.2g m/s", rms_speed);
    return CR_OK;
}

static cr_status coarse_progress(void *vctx, const cr_sim *sim, const cr_sim_report *rep, int frame,
                                 double rms_speed, cr_error *err) {
    (void)sim, (void)rep, (void)err;
    if (frame > 0) cr_progress_update(vctx, frame, "coarse, rms speed %.2g m/s", rms_speed);
    return CR_OK;
}

cr_status cr_scene_drape_static(const cr_scene_drape_static_def *d,
                                cr_scene_drape_static_result *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    CR_TRY(drape_validate(d, err));
    cr_sim_def def = cr_sim_default_def();
    CR_TRY(cr_material_preset(d->material, &def.material, err));
    def.solver = (cr_sim_solver)d->solver;
    if (d->self_contact >= 0) def.self_contact = d->self_contact;
    if (d->self_thickness > 0.0f) def.self_contact_thickness = d->self_thickness;
    cr_mesh *obj = NULL, *cloth = NULL, *final = NULL;
    cr_sim *sim = NULL;
    cr_scene_record *rec = NULL;
    cr_status st = CR_OK;
    cr_scene_settle_stats stats = {0}, coarse_stats = {0};
    state_ctx ctx = {0};
    if (d->material_json) st = cr_material_load_json(d->material_json, &def.material, err);
    if (st == CR_OK) st = cr_scene_object_create(d->object, &obj, err);
    if (st == CR_OK) st = cr_scene_cloth_above(obj, d->res, d->size, d->gap, &cloth, err);
    def.collider = obj;
    if (st == CR_OK && d->coarse > 0) {
        /* Settle the coarse cloth, refine its rest shape onto the fine one,
         * and let the fine one only solve statically from there. */
        cr_progress bar;
        cr_progress_begin(&bar, "drape-static", d->max_frames, d->quiet);
        st = cr_scene_settle_coarse(&def, obj, d->coarse, d->size, d->gap, d->max_frames,
                                    CR_SCENE_SETTLED_SPEED, coarse_progress, &bar, cloth, d->res,
                                    &coarse_stats, err);
        cr_progress_end(&bar);
    }
    if (st == CR_OK) st = cr_sim_create(&def, cloth, &sim, err);
    if (st == CR_OK) st = cr_mkdir_p(d->out_dir, err);
    if (st == CR_OK) {
        snprintf(out->log, sizeof out->log, "%s/frames.jsonl", d->out_dir);
        st = cr_scene_record_create(out->log, sim, cloth, d->max_frames + 2, &rec, err);
    }
    if (st == CR_OK) {
        int frames = d->coarse > 0 ? 0 : d->max_frames;
        ctx.rec = rec;
        cr_progress_begin(&ctx.bar, "drape-static", frames, d->quiet || frames == 0);
        st = cr_scene_settle(sim, frames, CR_SCENE_SETTLED_SPEED, record_state, &ctx, &stats, err);
        cr_progress_end(&ctx.bar);
    }
    stats.seconds += coarse_stats.seconds;
    stats.newton += coarse_stats.newton;
    stats.settle_frames += coarse_stats.settle_frames;
    stats.max_penetration_m = fmax(stats.max_penetration_m, coarse_stats.max_penetration_m);
    out->settle = stats;
    if (st == CR_OK) {
        out->vertices = cloth->nv;
        snprintf(out->material, sizeof out->material, "%s", def.material.name);
        snprintf(out->obj, sizeof out->obj, "%s/final.obj", d->out_dir);
        snprintf(out->png, sizeof out->png, "%s/final.png", d->out_dir);
        snprintf(out->pc2, sizeof out->pc2, "%s/sim.pc2", d->out_dir);
        st = cr_scene_record_mesh(rec, &final, err);
        if (st == CR_OK) st = cr_mesh_write(out->obj, final, err);
        if (st == CR_OK) st = cr_scene_record_write(rec, out->pc2, NULL, 1.0f, err);
        if (st == CR_OK)
            st = cr_scene_render(out->png, final, NULL, obj, NULL, d->render_size, err);
    }
    cr_mesh_destroy(final);
    cr_scene_record_destroy(rec);
    cr_sim_destroy(sim);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(obj);
    return st;
}
