/* crease/scene.h: the scene layer above the simulator (phys/) and the
 * bodies (body/): scenes, a run's record, the one step-record-report loop,
 * and the runs behind `crease simulate` and `crease drape-static` (the
 * datasets of `crease dataset` are in crease/dataset.h).
 *
 * A whole run, as `crease simulate` does it:
 *   cr_scene_sim_def d = cr_scene_sim_default_def();
 *   d.garment = "cloth.obj", d.object = "sphere", d.frames = 30, d.out_dir = "out";
 *   cr_scene_sim_result r;
 *   CR_TRY(cr_scene_simulate(&d, &r, err));       r.run: frames, timings, divergence
 *
 * Or by parts:
 *   cr_mesh *obj = NULL;
 *   CR_TRY(cr_scene_object_create("sphere", &obj, err));     or "F.obj"
 *   ... cr_sim_create with def.collider = obj ...
 *   cr_scene_record *rec = NULL;
 *   CR_TRY(cr_scene_record_create("out/frames.jsonl", sim, garment, frames + 1, &rec, err));
 *   cr_scene_run_stats stats;
 *   cr_scene_run(sim, frames, rec, NULL, NULL, &stats, err);  step, record, sum
 *   cr_scene_record_write(rec, "out/sim.pc2", "out/sim.glb", 30, err);
 *
 * What it leaves out: cameras and colours beyond a fixed two-object render,
 * streaming of the sequence (samples are held in memory, (T,V,3) floats, and
 * written at the end).
 */
#ifndef CREASE_SCENE_H
#define CREASE_SCENE_H

#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/phys_sim.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The named objects of the physics scenes, closed meshes centred at the
 * origin, Y up, as `crease primitive` makes them: "sphere" (UV sphere r =
 * 0.3 m, 64 x 32, the Blender peer's), "torus" (0.3 / 0.1 m), "prism" (side
 * 0.4 m, length 0.8 m along X, ridge up), "box" (0.4 m edges). Any other
 * spec is read as a mesh file (cr_mesh_read), kept where it is. */
cr_status cr_scene_object_create(const char *spec, cr_mesh **out, cr_error *err);

/* Read a PC2 animating `collider` (named `collider_name` in messages) and
 * check that every sample has the collider's vertex count: CR_ERR_SHAPE
 * naming both files and both counts otherwise. `out` is freed with
 * cr_pc2_free. */
cr_status cr_scene_animation_read(const char *pc2_path, const cr_mesh *collider,
                                  const char *collider_name, cr_pc2 *out, cr_error *err);

/* A square cloth of `size` m with res x res vertices (cr_prim_plane, Y up),
 * centred over `object` in x and z, `gap` m above its highest point. */
cr_status cr_scene_cloth_above(const cr_mesh *object, int32_t res, float size, float gap,
                               cr_mesh **out, cr_error *err);

/* Positions of the res x res cloth `fine` from the coarse_res x coarse_res
 * cloth `coarse` (both cr_scene_cloth_above grids, vertex k * res + i at
 * (i, k) / (res - 1) over the square), by bilinear interpolation of the
 * coarse positions at each fine vertex's grid coordinates: a settled coarse
 * drape becomes the start of a fine one. Fails naming the mesh whose vertex
 * count is not its res squared. */
cr_status cr_scene_cloth_refine(const cr_mesh *coarse, int32_t coarse_res, cr_mesh *fine,
                                int32_t fine_res, cr_error *err);

/* RMS vertex speed, m/s, below which a settling cloth counts as at rest
 * (drape-static's threshold). */
#define CR_SCENE_SETTLED_SPEED 5e-3

/* What cr_scene_settle did. */
typedef struct cr_scene_settle_stats {
    int settle_frames;        /* dynamic frames run */
    long long newton;         /* Newton iterations, static solve included */
    double seconds;           /* solver time */
    double max_penetration_m; /* deepest vertex inside the collider before projection */
    int converged;            /* the static solve met its tolerance */
    int32_t contacts;         /* vertices within the thickness at the end */
} cr_scene_settle_stats;

/* Called with every state cr_scene_settle reaches, a diverged one too
 * (rep->diverged): frame is the settling frame (1-based), or 0 for the
 * static solve; rms_speed is the RMS vertex speed, m/s. A failure stops the
 * settling and is returned. */
typedef cr_status (*cr_scene_state_fn)(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                                       int frame, double rms_speed, cr_error *err);

/* The quasi-static rest shape: step `sim` dynamically until its RMS vertex
 * speed is below settled_speed (m/s) or max_frames frames have run (damping
 * and friction hold the cloth where it lands), then minimise the potential
 * without inertia (cr_sim_solve_static). on_state may be NULL. Returns the
 * solver's status (CR_ERR_DIVERGED with the frame in err) or on_state's. */
cr_status cr_scene_settle(cr_sim *sim, int max_frames, double settled_speed,
                          cr_scene_state_fn on_state, void *ctx, cr_scene_settle_stats *stats,
                          cr_error *err);

/* The coarse stage of a coarse-to-fine drape: a coarse_res x coarse_res
 * cloth laid over `object` as cr_scene_cloth_above(size, gap) settles with
 * cr_scene_settle(max_frames, settled_speed, on_state) under `def` (its
 * collider is `object`), and its rest shape, interpolated by
 * cr_scene_cloth_refine, becomes the positions of the fine_res x fine_res
 * cloth `fine`. */
cr_status cr_scene_settle_coarse(const cr_sim_def *def, const cr_mesh *object, int32_t coarse_res,
                                 float size, float gap, int max_frames, double settled_speed,
                                 cr_scene_state_fn on_state, void *ctx, cr_mesh *fine,
                                 int32_t fine_res, cr_scene_settle_stats *stats, cr_error *err);

/* Render `garment` at positions `garment_pos` (V,3, m; NULL: its own) in
 * cloth blue with `collider` (may be NULL) at `collider_pos` (Vc,3, m; NULL:
 * its own) in grey into a `size` x `size` PNG. */
cr_status cr_scene_render(const char *png_path, const cr_mesh *garment, const float *garment_pos,
                          const cr_mesh *collider, const float *collider_pos, int size,
                          cr_error *err);

/* ---------------------------------------------------------------- twin -- */

/* A twin: the same simulation re-run with a tiny perturbation of its input.
 * The simulator is deterministic, but a garment's folds are chosen
 * chaotically in its first frames, so the twin is as close as the reference
 * can come to itself: the floor a prediction is judged against
 * (docs/eval.md, "The twin"). A twin within 0.1 mm of its reference
 * everywhere says the scene is not chaotic. */
typedef struct cr_scene_twin {
    float offset[3];       /* m: the garment's start moved by this */
    double friction_delta; /* added to the material's Coulomb friction */
} cr_scene_twin;

/* The default perturbation: the start moved 0.1 mm along +Z. */
#define CR_SCENE_TWIN_OFFSET_M 1e-4f
cr_scene_twin cr_scene_twin_default(void);
/* 1 when the twin perturbs anything. */
int cr_scene_twin_is_set(const cr_scene_twin *t);
/* Apply the friction change to a material: CR_ERR_INVALID when the friction
 * would fall below 0 or the change is not finite. */
cr_status cr_scene_twin_material(const cr_scene_twin *t, cr_material *m, cr_error *err);

/* ---------------------------------------------------------- recording -- */

/* A run's record: garment positions per frame (sample 0 the initial state)
 * and a JSON lines log with one object per frame:
 *   {"frame", one field per energy term (J, named as in cr_sim_report),
 *    "kinetic", "max_penetration_m", "newton_iterations", "substeps",
 *    "backoffs", "contacts", "yielded", "seconds", "seconds_assembly",
 *    "seconds_factor", "seconds_solve", "seconds_collision"}
 * plus "diverged": true and "failure" on a frame that failed. Each line is
 * flushed as it is written, so a run that stops leaves its log. */
typedef struct cr_scene_record cr_scene_record;

/* Open (truncate) the log at `log_path` and take sample 0 from `sim`.
 * `garment` (borrowed for the record's life) gives faces and UVs;
 * `max_samples` >= 1 bounds the samples held. */
cr_status cr_scene_record_create(const char *log_path, const cr_sim *sim, const cr_mesh *garment,
                                 int32_t max_samples, cr_scene_record **out, cr_error *err);
void cr_scene_record_destroy(cr_scene_record *r);

/* Log the frame `rep` describes; when it did not diverge, also keep the
 * simulator's positions as the next sample (CR_ERR_RANGE past max_samples). */
cr_status cr_scene_record_frame(cr_scene_record *r, const cr_sim *sim, const cr_sim_report *rep,
                                cr_error *err);

int32_t cr_scene_record_samples(const cr_scene_record *r);
/* (V,3) positions of the last sample, m; owned by the record. */
const float *cr_scene_record_last(const cr_scene_record *r);
/* (T,V,3) positions of every sample so far, m, T = cr_scene_record_samples;
 * owned by the record. */
const float *cr_scene_record_all(const cr_scene_record *r);

/* Also keep the simulator's rest angles (plasticity's) with every sample
 * from now on, sample 0 included: call right after create. Hinges in
 * cr_topology_build's order on the garment, as cr_eval_input's rest angles. */
cr_status cr_scene_record_keep_rest_angles(cr_scene_record *r, const cr_sim *sim, cr_error *err);
/* Write the kept rest angles as a float32 (T,H) .npy, rad (what `crease
 * eval --rest-angles` reads); CR_ERR_INVALID when none were kept. */
cr_status cr_scene_record_write_rest_angles(const cr_scene_record *r, const char *npy_path,
                                            cr_error *err);

/* Write the samples as a PC2 (start frame 0, one sample per frame) and a glb
 * morph-target sequence at `fps`; either path may be NULL to skip it. */
cr_status cr_scene_record_write(const cr_scene_record *r, const char *pc2_path,
                                const char *glb_path, float fps, cr_error *err);

/* The garment at the last sample, as a new mesh (faces and UVs kept). */
cr_status cr_scene_record_mesh(const cr_scene_record *r, cr_mesh **out, cr_error *err);

/* --------------------------------------------------------------- runs -- */

/* What cr_scene_run did, summed over the frames it finished (a frame that
 * diverged counts in none of the sums). */
typedef struct cr_scene_run_stats {
    int frames;              /* frames finished */
    double seconds;          /* solver wall time, s */
    double seconds_assembly; /* its split, as in cr_sim_report */
    double seconds_factor;
    double seconds_solve;
    double seconds_collision;
    double seconds_self_contact;       /* self-contact detection (cr_sim_report) */
    long long self_contact_detections; /* summed */
    long long self_contact_pairs;      /* summed over frames (pairs at each frame's end) */
    long long newton_iterations;
    long long factorisations;
    long long newton_capped;    /* substeps that stopped at the iteration limit */
    long long vbd_retries;      /* VBD sweeps run again with line searches (cr_sim_report) */
    long long vbd_requeries;    /* vertex collider queries of VBD's later sweeps (cr_sim_report) */
    long long vbd_coarse_steps; /* VBD coarse corrections taken (cr_sim_report) */
    long long backoffs;         /* failed attempts retried with more substeps */
    double max_penetration_m;   /* deepest vertex inside the collider before projection */
    double max_projected_share; /* largest share of the vertices projected out of the
                                   collider per substep in a frame (rep.projected / (V *
                                   substeps)): what the solver let through */
    int diverged;               /* 1: frame `frames + 1` failed for good */
    char failure[200];          /* then: the solver's reason */
} cr_scene_run_stats;

/* Called after every finished frame (1-based sim frame in rep->frame) with the
 * stats so far, this frame included. A failure stops the run and is returned. */
typedef cr_status (*cr_scene_frame_fn)(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                                       const cr_scene_run_stats *so_far, cr_error *err);

/* The step-record-report loop of every run: step `sim` `frames` times; log
 * each frame in `rec` (may be NULL; a diverged frame is logged too, with its
 * failure) and keep its positions; sum the stats; call on_frame (may be NULL).
 * A frame that diverges ends the run: CR_ERR_DIVERGED with the solver's
 * message in err, stats->diverged and stats->failure set, the frames before it
 * recorded. Any other failure (solver, record, on_frame) is returned as is. */
cr_status cr_scene_run(cr_sim *sim, int frames, cr_scene_record *rec, cr_scene_frame_fn on_frame,
                       void *ctx, cr_scene_run_stats *stats, cr_error *err);

/* Size of the output paths in the results below. */
#define CR_SCENE_PATH 1200

/* `crease simulate`: a garment against a collider, static or animated. */
typedef struct cr_scene_sim_def {
    const char *garment;         /* garment mesh (.obj, .ply, .glb): the initial state; required */
    const float *garment_offset; /* NULL, or (3) m: the garment is moved by it first */
    cr_scene_twin twin;          /* a twin's perturbation (default none: all zero), on top */
    const char *object;          /* collider: a named object or a mesh (cr_scene_object_create) */
    const char *body_mesh;       /* or a body mesh as the collider (not with object) */
    const char *body;            /* PC2 animating the collider (frame f moves from sample f to
                                    f + 1, held at the last); needs object or body_mesh */
    /* A .bvh driving a rigged .glb body_mesh instead of its own animation:
     * retargeted onto its skeleton (cr_motion_retarget_bvh), eased in from
     * the rest pose over body_ease_in_s, one frame a simulated frame at fps;
     * then out_dir/scene.glb holds the character so driven and the garment. */
    const char *body_motion;
    const char *joint_map; /* cr_retarget_def.joint_map (may be NULL) */
    float body_bvh_scale;  /* m per BVH unit, 0 (default): the rig's known unit or inferred */
    float body_ease_in_s;  /* s, default 1 */
    /* The BVH's frames used, before the ease-in: [body_start_frame,
     * body_end_frame] (-1, -1 by default: all; a calibration frame 0 is then
     * dropped, as cr_motion_prepare drops one; a given start keeps it). */
    int body_start_frame, body_end_frame;
    const char *material;      /* preset (default "cotton") */
    const char *material_json; /* field overrides (cr_material_load_json), or NULL */
    int frames;                /* frames to simulate, >= 1 (required) */
    float fps;                 /* default 30 */
    int substeps;              /* 0: cr_sim_def's default */
    int newton_iterations;     /* per substep at most; 0: cr_sim_def's default */
    int vbd_iterations;        /* VBD sweeps per substep at most; 0: cr_sim_def's default */
    float vbd_tol;             /* VBD's stopping tolerance, m/s; 0: cr_sim_def's default */
    int vbd_coarse_every;      /* VBD's coarse correction every N sweeps; 0: off, -1 (what
                                  cr_scene_sim_default_def gives): cr_sim_def's default */
    int vbd_coarse_rings;      /* its aggregates' rings; 0: cr_sim_def's default */
    int vbd_coarse_refresh;    /* corrections per coarse factorisation; 0: cr_sim_def's */
    float max_collider_step;   /* cr_sim_def.max_collider_step, m (default 0: off) */
    int plastic;               /* 1: plastic bending */
    int solver;                /* cr_sim_solver (default 0: CR_SIM_SOLVER_NEWTON) */
    int self_contact;          /* cloth self-contact: 1 on, 0 off, -1 (default) cr_sim_def's */
    float self_thickness;      /* its thickness, m; 0 (default): cr_sim_def's */
    const int32_t *pins;       /* (npins) vertices held at their initial positions */
    int32_t npins;
    const char *out_dir; /* created when missing; required */
    int render_size;     /* last.png's side, pixels (default 800) */
    int quiet;           /* 1: no progress bar */
    /* Or a body model posed by a motion as the collider: pose_motion, a clip name or a
     * .bvh/.npz file (cr_motion_resolve with pose_def, at fps, starting at the rest pose
     * the garment is fitted on), on pose_body (cr_body_resolve: a preset, an SMPL file or a
     * rigged CHAR.glb[:MAP]; NULL: the normal mannequin); written as out_dir/body.obj and
     * body.pc2 and, with the garment, out_dir/scene.glb (the body as a skinned, animated
     * character and the garment beside it on one timeline, cr_body_write_glb). Not with
     * object, body_mesh or body. */
    const char *pose_motion, *pose_body;
    cr_motion_resolve_def pose_def; /* cr_motion_resolve_default_def() */
} cr_scene_sim_def;

cr_scene_sim_def cr_scene_sim_default_def(void);

typedef struct cr_scene_sim_result {
    cr_scene_run_stats run; /* frames simulated, timings, divergence */
    int32_t vertices;       /* the garment's */
    char material[32];      /* the material's name */
    /* outputs under out_dir: sim.pc2 and sim.glb (sample 0 the initial state),
       frames.jsonl (a line per frame), last.png (the last frame with the collider) and,
       with plasticity, rest_angles.npy ((T,H) float32 rad per sample; else rest_angles[0] 0) */
    char pc2[CR_SCENE_PATH], glb[CR_SCENE_PATH], log[CR_SCENE_PATH], png[CR_SCENE_PATH];
    char rest_angles[CR_SCENE_PATH];
    char scene[CR_SCENE_PATH]; /* scene.glb with a character, else "" */
    /* with pose_motion: body.obj and body.pc2, the posed body; else "" */
    char body_mesh[CR_SCENE_PATH], body_pc2[CR_SCENE_PATH];
} cr_scene_sim_result;

/* Read, set up, simulate (cr_scene_run), write the outputs. A run that
 * diverges still writes the frames before it and returns CR_OK with
 * out->run.diverged set; a bad input fails naming it (CR_ERR_INVALID for a
 * bad def field or material, the readers' errors for files, CR_ERR_SHAPE for
 * an animation whose vertex count is not the collider's). */
cr_status cr_scene_simulate(const cr_scene_sim_def *def, cr_scene_sim_result *out, cr_error *err);

/* `crease drape-static`: the quasi-static drape of a square cloth over an object. */
typedef struct cr_scene_drape_static_def {
    const char *object;        /* a named object or a mesh (cr_scene_object_create); required */
    int32_t res;               /* cloth vertices per side, >= 2 (default 64) */
    float size;                /* cloth side, m (default 1) */
    float gap;                 /* cloth height above the object's top, m (default 0.05) */
    const char *material;      /* preset (default "cotton") */
    const char *material_json; /* field overrides, or NULL */
    int max_frames;            /* dynamic settling frames at most (default 150; 0: static
                                  solve from the flat start) */
    int32_t coarse;            /* > 0: settle a coarse x coarse cloth and start the res x res
                                  static solve from its rest shape (cr_scene_settle_coarse);
                                  below res. 0 (default): off */
    int solver;                /* cr_sim_solver (default 0: CR_SIM_SOLVER_NEWTON) */
    int self_contact;          /* cloth self-contact: 1 on, 0 off, -1 (default) cr_sim_def's */
    float self_thickness;      /* its thickness, m; 0 (default): cr_sim_def's */
    const char *out_dir;       /* required */
    int render_size;           /* final.png's side (default 800) */
    int quiet;                 /* 1: no progress bar */
} cr_scene_drape_static_def;

cr_scene_drape_static_def cr_scene_drape_static_default_def(void);

typedef struct cr_scene_drape_static_result {
    cr_scene_settle_stats settle; /* both stages summed (the coarse one's frames included) */
    int32_t vertices;
    char material[32];
    /* outputs under out_dir: final.obj, final.png, frames.jsonl (a line per frame and the
       static solve), sim.pc2 (every state) */
    char obj[CR_SCENE_PATH], png[CR_SCENE_PATH], log[CR_SCENE_PATH], pc2[CR_SCENE_PATH];
} cr_scene_drape_static_result;

/* Lay the cloth above the object, settle it to rest (cr_scene_settle, or the
 * coarse-to-fine path), write the outputs. */
cr_status cr_scene_drape_static(const cr_scene_drape_static_def *def,
                                cr_scene_drape_static_result *out, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
