/* crease/motion.h: motions for the bodies garments are simulated on:
 * procedural clips, BVH and AMASS-style .npz loaders, the project's own
 * motion .npz, and SMPL-style body models.
 *
 *   cr_motion *walk = NULL;
 *   CR_TRY(cr_motion_clip("walk", 120, 30.0f, &walk, err));   // 4 s at 30 fps
 *   CR_TRY(cr_motion_save("walk.npz", walk, err));
 *   cr_motion *mocap = NULL;
 *   CR_TRY(cr_motion_load("jump.bvh", &mocap, err));          // or an AMASS .npz
 *
 * Poses follow crease/skeleton.h: per joint an axis-angle rotation relative
 * to the parent, in the rest pose's frame (all joint frames aligned with the
 * world: +Y up, the body facing +Z, its left side at +X), and a root
 * translation: the pelvis sits at rest position + trans.
 *
 * One rest pose: zero rotations are the default mannequin's A-pose (arms 40
 * degrees below horizontal) for every motion. Procedural clips and crease's
 * .npz are written against it; the loaders bring the rest into it (a BVH
 * retargeted by bone directions from its rig's own rest, AMASS re-expressed
 * from SMPL's T-pose; cr_motion_import_def.retarget = 0 keeps theirs).
 * cr_motion_rebase re-expresses a motion against another rest pose (an SMPL
 * body's T-pose). cr_motion_prepare makes a loaded motion ready to simulate a
 * garment on: frames used, calibration frame, rate, ground, ease-in.
 *
 * Foreign motions (BVH, AMASS) are brought into crease's frame on loading:
 * Z-up data is turned to Y-up, a rig facing another way is turned to face
 * +Z, lengths become metres, and with `recenter` (the default) the motion
 * starts at the origin facing +Z, so a garment fitted at rest starts on the
 * body. docs/motions.md says exactly what each loader does.
 *
 * References: Loper et al. 2015 (SMPL); Mahmood et al. 2019 (AMASS);
 * Biovision BVH as described by Meredith and Maddock 2001, "Motion capture
 * file formats explained"; Blender's BVH importer for the channel
 * conventions.
 */
#ifndef CREASE_MOTION_H
#define CREASE_MOTION_H

#include "crease/base.h"
#include "crease/mesh_io.h"
#include "crease/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------ procedural clips -- */

/* Options for a procedural clip. Every clip starts exactly at the rest pose
 * (zero rotations and translation) and eases in over `ease_in` seconds with
 * continuous velocity; then it repeats (walk, run, ...) or holds. */
typedef struct cr_motion_clip_def {
    const char *name; /* one of cr_motion_clip_names() */
    int32_t nframes;  /* T >= 1 (default 120) */
    float fps;        /* frames per second, (0, 1000] (default 30) */
    float speed;      /* tempo multiplier, [0.25, 4] (default 1): 2 walks twice as fast */
    float amplitude;  /* scales every angle and displacement, [0, 1.5] (default 1) */
    float ease_in;    /* s, ramp from rest, [0.05, 5] (default 0.5) */
    uint32_t cookie;  /* set by cr_motion_clip_default_def; a hand-zeroed def is a bug */
} cr_motion_clip_def;

cr_motion_clip_def cr_motion_clip_default_def(void);
cr_status cr_motion_clip_make(const cr_motion_clip_def *def, cr_motion **out, cr_error *err);
/* Shorthand with the default speed, amplitude and ease-in. */
cr_status cr_motion_clip(const char *name, int32_t nframes, float fps, cr_motion **out,
                         cr_error *err);
/* The clip names, NULL-terminated; *count (may be NULL) gets how many. */
const char *const *cr_motion_clip_names(int *count);
/* One line describing a clip, or NULL for an unknown name. */
const char *cr_motion_clip_summary(const char *name);

/* ------------------------------------------------------- loading, saving -- */

typedef struct cr_motion_import_def {
    float bvh_scale; /* metres per BVH length unit; 0 (default) infers it from the rig's height */
    int recenter;    /* 1 (default): foreign motions start at x = z = 0 facing +Z */
    /* 1 (default): foreign motions come out relative to crease's one rest
     * pose, the default mannequin's A-pose: a BVH retargeted by bone
     * directions from its rig's own rest (T-pose, A-pose, splayed legs, ...),
     * an AMASS file re-expressed from SMPL's T-pose. 0: rotations stay
     * relative to the rig's rest (BVH) or SMPL's T-pose (AMASS). */
    int retarget;
    uint32_t cookie; /* set by cr_motion_import_default_def */
} cr_motion_import_def;

cr_motion_import_def cr_motion_import_default_def(void);

/* Load by extension: .bvh, .npz (crease's own motions and AMASS-style
 * poses/trans/mocap_framerate), or a rigged glTF character's own animation,
 * "CHAR.glb" or "CHAR.glb:MAP" (cr_motion_read_character). def NULL means
 * the defaults. */
cr_status cr_motion_import(const char *path, const cr_motion_import_def *def, cr_motion **out,
                           cr_error *err);
/* A rigged glTF character's own animation (animations[0], at its key rate)
 * onto crease's mannequin: its joints given SMPL's 22 roles as
 * cr_body_from_character gives them (name tables, or joint_map: lines
 * "character_joint = smpl_joint" or a JSON object; may be NULL), then
 * retargeted by bone directions from the rest its nodes hold, as a BVH is
 * (frame, unit, recentring by def). So `--body CHAR.glb --motion CHAR.glb`
 * moves the character as its file does. Fails naming the file: no skin, no
 * animation, no joint for the hips, a bad map line. */
cr_status cr_motion_read_character(const char *path, const char *joint_map,
                                   const cr_motion_import_def *def, cr_motion **out, cr_error *err);
cr_status cr_motion_load(const char *path, cr_motion **out, cr_error *err);
/* The same from memory; `source` names the data in messages. */
cr_status cr_motion_read_bvh_mem(const void *data, size_t len, const char *source,
                                 const cr_motion_import_def *def, cr_motion **out, cr_error *err);
cr_status cr_motion_read_npz_mem(const void *data, size_t len, const char *source,
                                 const cr_motion_import_def *def, cr_motion **out, cr_error *err);

/* Write crease's motion .npz (deflated, via a temporary file): poses (T,66)
 * and trans (T,3) as '<f4', mocap_framerate () '<f8' and up_axis () '<i4'
 * = 1 (+Y). The keys are AMASS's, so Python tools read it; up_axis tells
 * the loader the file is crease's own and is read back exactly. */
cr_status cr_motion_save(const char *path, const cr_motion *m, cr_error *err);

/* ----------------------------------------------------------- operations -- */

/* Finite values, at least one frame, a positive frame rate. */
cr_status cr_motion_validate(const cr_motion *m, const char *source, cr_error *err);

/* Largest joint angular speed, rad/s: the angle of the relative rotation
 * between consecutive frames, times fps, over all joints and frames (0 for
 * one frame). *joint (may be NULL) gets the joint where it happens. */
float cr_motion_max_angular_speed(const cr_motion *m, int *joint);

/* Re-express every pose against a new rest pose. `rest` (22,3) is the new
 * rest written as a pose of the motion's current rest (axis-angle per
 * joint); bone directions and the pelvis path stay the same in the world.
 * For joint j with parent p and G = the rest's accumulated (world)
 * rotations: R'_j = G_p R_j G_j^-1. Example: a T-pose motion on the A-pose
 * mannequin takes the A-pose as a pose of the T-pose. */
void cr_motion_rebase(cr_motion *m, const float rest[CR_NJOINTS * 3]);

/* The A-pose of a mannequin with arms `arm_angle_deg` below horizontal as
 * a pose of the T-pose (each upper arm turned down about -+Z): what
 * cr_motion_rebase takes to play a T-pose motion on that A-pose. */
void cr_motion_apose_from_tpose(float arm_angle_deg, float rest[CR_NJOINTS * 3]);

/* Largest joint angular speed as cr_motion_max_angular_speed, with the frame
 * f where it happens (between frames f - 1 and f); either may be NULL. */
float cr_motion_max_angular_speed_at(const cr_motion *m, int *joint, int32_t *frame);

/* A copy of m at `fps`: the same duration T / fps (ceil-free: samples at
 * k / fps for k < floor((T - 1) fps / m->fps) + 1), joint rotations slerped
 * and the translation interpolated linearly between the two nearest frames.
 * fps in (0, 1000]. */
cr_status cr_motion_resample(const cr_motion *m, float fps, cr_motion **out, cr_error *err);

/* Frames [first, last] of m (inclusive) as a new motion. */
cr_status cr_motion_slice(const cr_motion *m, int32_t first, int32_t last, cr_motion **out,
                          cr_error *err);

/* 1 when frame 0 is a calibration frame: some joint turns by more than
 * 0.35 rad from frame 0 to frame 1 while the next steps are at least five
 * times smaller (a T-pose held before a capture starts). *jump (may be
 * NULL) gets the largest angle from frame 0 to 1, rad. */
int cr_motion_is_calibration_start(const cr_motion *m, float *jump);

/* A copy of m that starts at the rest pose (zero rotations and translation,
 * where a garment is fitted) and eases into m's frame 0 over `seconds` (the
 * first round(seconds fps) frames), then plays m. Per joint the rotation is
 * m_0 exp(p(u)), p a quintic in the tangent space at m_0 from log(m_0^-1)
 * with zero velocity and acceleration at the rest to zero with m's velocity
 * at frame 0 (so the velocity is continuous into the motion): a slerp from
 * the rest eased by 1 - 10u^3 + 15u^4 - 6u^5 plus the velocity term. The
 * translation likewise. seconds 0 copies m. */
cr_status cr_motion_ease_in(const cr_motion *m, float seconds, cr_motion **out, cr_error *err);

/* How a motion is grounded on a body (cr_motion_ground). */
typedef enum cr_motion_ground_mode {
    CR_MOTION_GROUND_NONE = 0,
    CR_MOTION_GROUND_CLIP, /* one shift: the lowest foot point over the clip on y = 0 */
    CR_MOTION_GROUND_FRAME /* per frame: each frame's lowest foot point on y = 0 */
} cr_motion_ground_mode;

/* Shift m's translation in y so the lowest point of body b's feet (the
 * vertices skinned mostly to the ankles and feet), posed by m, touches
 * y = 0 over the clip (CR_MOTION_GROUND_CLIP) or at each frame. *shift_m
 * (may be NULL) gets the clip's shift. b NULL: the default mannequin (a
 * coarse one, built here). */
cr_status cr_motion_ground(cr_motion *m, const cr_body_model *b, cr_motion_ground_mode mode,
                           float *shift_m, cr_error *err);

/* A motion file made ready to simulate a garment on (cr_motion_prepare). */
typedef struct cr_motion_prepare_def {
    float fps;            /* resample to this rate; 0 (default) keeps the motion's */
    int32_t start_frame;  /* first frame used, of the motion as loaded; default 0 */
    int32_t end_frame;    /* last frame used (inclusive); -1 (default) the last */
    int drop_calibration; /* 1 (default): a calibration frame 0 is dropped, with a note */
    float ease_in_s;      /* s from the rest pose into the first used frame; 1 (default); 0 none */
    cr_motion_ground_mode ground; /* CR_MOTION_GROUND_CLIP (default) */
    float max_angular_speed;      /* rad/s: above it, a warning names joint and frame; 30 */
    uint32_t cookie;              /* set by cr_motion_prepare_default_def */
} cr_motion_prepare_def;

cr_motion_prepare_def cr_motion_prepare_default_def(void);

typedef struct cr_motion_prepare_report {
    float source_fps;      /* the motion's rate before resampling */
    int32_t source_frames; /* its frames */
    int32_t first_frame;   /* the frames used, of the source */
    int32_t last_frame;
    int calibration_dropped; /* 1 when frame 0 was dropped as a calibration frame */
    int32_t ease_frames;     /* frames of ease-in before the first used frame */
    float ground_shift_m;    /* added to trans.y (CR_MOTION_GROUND_CLIP) */
    float max_angular_speed; /* rad/s, of the result */
    int max_speed_joint;     /* where */
    int32_t max_speed_frame;
} cr_motion_prepare_report;

/* Every step a loaded motion takes before a garment is simulated on it, in
 * this order: frames [start_frame, end_frame] (a calibration frame 0
 * dropped when start_frame is 0), resampled to def->fps, grounded on body b
 * (NULL: the default mannequin), eased in from the rest pose; then the
 * angular speed is checked. def NULL: the defaults; rep may be NULL. */
cr_status cr_motion_prepare(const cr_motion *m, const cr_motion_prepare_def *def,
                            const cr_body_model *b, cr_motion **out, cr_motion_prepare_report *rep,
                            cr_error *err);

/* 1 when spec names a procedural clip (cr_motion_clip_names), 0 otherwise (a file). */
int cr_motion_is_clip(const char *spec);

/* How a motion is taken "as a clip name or a file" (cr_motion_resolve). */
typedef struct cr_motion_resolve_def {
    int32_t clip_frames;           /* a clip's frames (default 120) */
    int32_t max_frames;            /* a file's motion cut to its first max_frames frames after
                                      its preparation (default 0: all of it) */
    float fps;                     /* a clip's rate, and a file's after preparation (default
                                      30; 0: a file keeps its own, a clip gets 30) */
    cr_motion_import_def import;   /* how a file is read (default: its defaults) */
    cr_motion_prepare_def prepare; /* how a file is made ready; its fps is replaced by fps */
    const cr_body_model *body;     /* the body a file is grounded on (NULL: the mannequin) */
    uint32_t cookie;               /* set by cr_motion_resolve_default_def */
} cr_motion_resolve_def;

cr_motion_resolve_def cr_motion_resolve_default_def(void);

/* A motion as every command takes it: a procedural clip (cr_motion_clip) or
 * a motion file (.bvh, .npz) imported and made ready by cr_motion_prepare.
 * rep (may be NULL) gets the preparation's report; a clip's gives its rate,
 * frames and last frame. Fails naming the file, or naming the spec and the
 * clips when it is neither a clip nor an existing file. */
cr_status cr_motion_resolve(const char *spec, const cr_motion_resolve_def *def, cr_motion **out,
                            cr_motion_prepare_report *rep, cr_error *err);

/* ------------------------------------------ retargeting onto any skeleton -- */

/* A motion of any skeleton, in cr_glb_skin_motion's convention: each
 * joint's rotation relative to its parent, with every rest (bind) frame
 * aligned with the world, so the zero motion (identity rotations, zero
 * translation) is the rest pose. cr_glb_write_skinned writes it as it is;
 * cr_glb_character_pose poses a character by it. Free with
 * cr_skin_motion_destroy. */
typedef struct cr_skin_motion {
    int32_t njoints;    /* J */
    int32_t nframes;    /* T */
    float fps;          /* > 0 */
    float *rotation;    /* (T,J,4) unit quaternions x, y, z, w */
    float *translation; /* (T,3) every root joint's displacement from its rest position, m */
} cr_skin_motion;

cr_status cr_skin_motion_create(int32_t njoints, int32_t nframes, float fps, cr_skin_motion **out,
                                cr_error *err);
void cr_skin_motion_destroy(cr_skin_motion *m);
/* The view cr_glb_write_skinned and cr_glb_character_pose take. */
cr_glb_skin_motion cr_skin_motion_view(const cr_skin_motion *m);

/* 1 when m's frame 0 is a calibration frame (a T-pose before the capture,
 * the rule cr_motion_prepare drops one by); *jump (may be NULL) the largest
 * joint turn into frame 1, rad. */
int cr_skin_motion_is_calibration_start(const cr_skin_motion *m, float *jump);

/* A copy of m that starts at the rest pose and eases into m's frame 0 over
 * `ease_in_s` seconds (cr_motion_ease_in's curve: each joint from the rest
 * to frame 0 arriving with the motion's first step as velocity, the
 * translation from zero likewise, so the motion goes on without a jerk),
 * then plays m resampled to
 * `fps` (slerp between the two nearest frames; 0 keeps m's rate): what a
 * garment fitted at rest needs. */
cr_status cr_skin_motion_prepare(const cr_skin_motion *m, float fps, float ease_in_s,
                                 cr_skin_motion **out, cr_error *err);

typedef struct cr_retarget_def {
    /* A joint map file (may be NULL) that overrides the names' matching:
     * lines "character_joint = bvh_joint" ('#' starts a comment; nothing
     * after '=' leaves the joint unmapped), or a JSON object
     * {"character_joint": "bvh_joint" or null, ...}. A mapped joint takes
     * the role of its BVH joint. */
    const char *joint_map;
    cr_motion_import_def import; /* bvh_scale, recenter, retarget (defaults) */
    uint32_t cookie;             /* set by cr_retarget_default_def */
} cr_retarget_def;

cr_retarget_def cr_retarget_default_def(void);

/* The BVH at `path` retargeted onto skeleton `skel` (its names, parents and
 * rest joints; the skin weights are not read), named `skel_source` in
 * messages, by bone directions: the character's joints take SMPL's roles
 * through the name tables of motion_bvh.c (SMPL, Mixamo, CMU, DAZ/Poser,
 * Unreal, Blender/Rigify) or the joint map, each driven by the BVH joint of
 * its role; every driven bone points where the BVH's bone points, turned
 * from the character's rest bone by the least rotation, with the BVH
 * joint's twist; joints driven by nothing keep their rest relation to
 * their parent. The root translation is the BVH pelvis's displacement
 * scaled by the ratio of the hip heights (character over BVH, each the
 * rest pelvis over the lowest joint). The character's own frame (its up
 * and left read from the skeleton) is kept. Fails naming the map file and
 * line of a bad line, or the character when nothing drives its hips. */
cr_status cr_motion_retarget_bvh(const char *path, const cr_glb_skin *skel, const char *skel_source,
                                 const cr_retarget_def *def, cr_skin_motion **out, cr_error *err);
cr_status cr_motion_retarget_bvh_mem(const void *data, size_t len, const char *source,
                                     const cr_glb_skin *skel, const char *skel_source,
                                     const cr_retarget_def *def, cr_skin_motion **out,
                                     cr_error *err);
/* Another rigged character's own animation (the .glb at path; its joints'
 * roles as cr_motion_read_character gives them, by names or joint_map, may
 * be NULL), retargeted onto skel as a BVH is: def->joint_map's right-hand
 * sides name that character's joints. */
cr_status cr_motion_retarget_character(const char *path, const char *joint_map,
                                       const cr_glb_skin *skel, const char *skel_source,
                                       const cr_retarget_def *def, cr_skin_motion **out,
                                       cr_error *err);
/* By the spec: a rigged character's "CHAR.glb" or "CHAR.glb:MAP"
 * (cr_motion_retarget_character), else a BVH (cr_motion_retarget_bvh). */
cr_status cr_motion_retarget(const char *spec, const cr_glb_skin *skel, const char *skel_source,
                             const cr_retarget_def *def, cr_skin_motion **out, cr_error *err);

/* ---------------------------------------------------------- SMPL bodies -- */

/* Load an SMPL-style body model .npz (v_template (V,3), shapedirs (V,3,B),
 * J_regressor (J,V) dense, weights (V,J), kintree_table (2,J), f (F,3);
 * SMPL's J = 24, SMPL+H's 52 and SMPL-X's 55 all work) and shape it with
 * `betas` (nbetas <= B; fewer are zero-padded). Joints past the 22 body
 * joints (SMPL's hands, fingers, jaw, eyes) are merged into their nearest
 * body ancestor (hands into the wrists); each vertex keeps its 4 largest
 * merged weights, renormalised. The body is moved so its lowest vertex is on
 * y = 0 and its pelvis over x = z = 0, like the mannequin. Pose blend shapes
 * (posedirs) are not applied: crease skins with LBS only. Free with
 * cr_smpl_free (or, for a heap struct, cr_body_model_destroy: the same
 * allocations). */
cr_status cr_smpl_load(const char *path, const float *betas, int nbetas, cr_body_model *out,
                       cr_error *err);
cr_status cr_smpl_read_mem(const void *data, size_t len, const char *source, const float *betas,
                           int nbetas, cr_body_model *out, cr_error *err);
/* Free what cr_smpl_load allocated and zero the struct; NULL is fine. */
void cr_smpl_free(cr_body_model *b);

#ifdef __cplusplus
}
#endif
#endif
