/* retarget_internal.h: bone-direction retargeting from a source rig (a BVH's
 * joints) onto a target skeleton, shared by the BVH loader (target: crease's
 * mannequin) and cr_motion_retarget_bvh (target: any skinned character).
 *
 * One copy of the logic: a target is its joints, parents, rest positions,
 * the source joint driving each and the bone each one turns; the mannequin
 * is the 22-joint target whose rest is cr_mannequin_rest_joints.
 *
 * Names: both sides' joints are given SMPL's 22 roles (pelvis, left_hip,
 * ...) through per-convention alias tables (cr_retarget_match_roles); the table that
 * matches the most joints wins.
 */
#ifndef CREASE_BODY_RETARGET_INTERNAL_H
#define CREASE_BODY_RETARGET_INTERNAL_H

#include "body/motion_internal.h"
#include "crease/mesh_io.h"

/* ------------------------------------------------------------- names -- */

enum { RT_NAME_MAX = 127 };

/* name normalised for matching: the namespace before the last ':' dropped
 * ("mixamorig:Hips"), lower case, '_', '-', '.' and spaces removed, SMPL
 * FBX's "m_avg_" / "f_avg_" prefix dropped. */
void cr_retarget_normalise(const char *name, char *out, size_t cap);

/* Roles of n joints by name: map[r] the joint given SMPL role r, or -1.
 * names[i] NULL skips joint i (a BVH End Site). *rig gets the winning
 * table; returns how many roles it matched (0 when it finds no pelvis). */
int cr_retarget_match_roles(int n, const char *const *names, int map[CR_NJOINTS], int *rig);
/* The table's convention ("CMU", "Mixamo", ...) and its known unit: m per
 * unit when the rig's height in units is in [lo, hi]; unit 0 when unknown. */
const char *cr_retarget_rig_name(int rig);
void cr_retarget_rig_unit(int rig, double *unit_m, double *lo, double *hi);
/* The conventions, for messages: "SMPL, Mixamo, CMU, ..." */
extern const char *const cr_retarget_rig_list;
/* The role whose joint each role's bone runs to (-1: a leaf, which moves
 * with its parent's alignment), and the roles "up" runs to from the pelvis. */
extern const int8_t cr_retarget_bone_child_role[CR_NJOINTS];
extern const int cr_retarget_up_ends[4];

/* ----------------------------------------------------------- geometry -- */

/* out = v / |v|; 0 (out untouched) when |v| <= eps or not finite. */
int cr_retarget_unit3(const double v[3], double out[3], double eps);
/* The least rotation taking unit a onto unit b (half a turn when opposite). */
void cr_retarget_shortest_arc(const double a[3], const double b[3], double q[4]);
/* The rig's up (pelvis to head) and left (right to left hip) as signed
 * coordinate axes, from joint positions p indexed through the role map; 0
 * when they cannot be told. */
int cr_retarget_rig_axes(const int map[CR_NJOINTS], double (*p)[3], int *up_axis, int *up_sign,
                         int *left_axis, int *left_sign);
/* The turn taking signed axis up to +Y and left to +X. */
void cr_retarget_axes_turn(int up_axis, int up_sign, int left_axis, int left_sign, double q[4]);

/* ------------------------------------------------------- retargeting -- */

/* A target skeleton, joints ordered parents first. */
typedef struct rt_target {
    int n;
    const int *parent;       /* (n) parent joint, -1 for a root */
    const double (*rest)[3]; /* (n,3) rest positions in crease's frame (+Y up, facing +Z) */
    const int *src;          /* (n) source joint driving each, -1: keeps its rest relation */
    const int *bone_child;   /* (n) joint its bone runs to first (chained), -1: a leaf */
    int pelvis;              /* the joint given the pelvis role */
    int lhip, rhip;          /* the hips, or -1: the pelvis's twist where the bind pose lies */
} rt_target;

/* Per target joint: the bone end, the rest bone (unit, rig frame) and the
 * rest alignment with the source joint's frame. */
typedef struct rt_state {
    int *child;
    double (*e)[3];
    double (*align)[4];
} rt_state;

cr_status cr_retarget_state_alloc(int n, rt_state *s, cr_error *err);
void cr_retarget_state_free(rt_state *s);

/* The alignment of target and source at rest (see retarget.c): ref (source
 * joints, file units) the source's rest positions, or with ref_w a standing
 * frame's positions and world rotations; turn: the file's frame to
 * crease's; rest_turn: the rest pose's upright frame to crease's; height:
 * the source's height in file units (degenerate-bone threshold). */
void cr_retarget_setup(const rt_target *t, double (*ref)[3], double (*ref_w)[4],
                       const double turn[4], const double rest_turn[4], double height, rt_state *s);

/* World rotations g (n,4) of the target joints in one frame, in the source
 * file's frame, from the source's world rotations w and positions pos. */
void cr_retarget_frame(const rt_target *t, const rt_state *s, double (*w)[4], double (*pos)[3],
                       double (*g)[4]);

/* motion_frame_fix on world rotations: g (T,n,4) each joint's world
 * rotation, t (T,3) the pelvis's position (source frame, m) in, its
 * displacement from rest (crease's frame) out; the heading is read from
 * joint `pelvis`. The one copy cr_motion_fix_frame goes through. */
void cr_retarget_fix_world(double *g, int n, int pelvis, double *t, int32_t T,
                           const motion_frame_fix *fix);

/* ---------------------------------------------------- a source rig -- */

/* A motion's source skeleton, whatever file it came from (a BVH, a rigged
 * glTF character's own animation): its joints, their rest positions in file
 * units and, frame by frame, their world rotations from that rest (the
 * identity at rest, as a BVH's channels at zero) and world positions. */
typedef struct rt_source {
    const char *source;      /* the file, for messages */
    int n;                   /* joints */
    const char *const *name; /* (n) names, NULL for an unnamed joint (a BVH End Site) */
    const int *parent;       /* (n) parent joint, -1 for a root */
    double (*rest)[3];       /* (n,3) rest positions, file units */
    int32_t nframes;         /* T >= 1 */
    double fps;              /* > 0 */
    /* frame f's world rotations w (n,4: w, x, y, z) and positions pos (n,3), file units */
    void (*pose)(const struct rt_source *s, int32_t f, double (*w)[4], double (*pos)[3]);
    const void *ctx; /* the file's own data, for pose */
} rt_source;

/* Drive target tg (tg->src: source joints; map: the source's roles; rig: the
 * name table that matched): per frame the target joints' world rotations in
 * crease's frame, g (T,n,4), and the pelvis's displacement from its rest
 * standing position, t (T,3), m. *hip_m: the source's rest pelvis height
 * over its lowest joint, m. def->retarget 0: each joint takes its source
 * joint's world rotation (no bone matching). Reads up, left and the unit off
 * the rest pose or, where it does not stand, off the frames (see
 * retarget_drive.c). */
cr_status cr_retarget_drive(const rt_source *s, const int map[CR_NJOINTS], int rig,
                            const cr_motion_import_def *def, const rt_target *tg, double *g,
                            double *t, double *hip_m, cr_error *err);

/* The source onto crease's mannequin: the 22-joint target whose rest is the
 * mannequin's, as SMPL-style local axis-angle poses at the source's rate. */
cr_status cr_retarget_onto_mannequin(const rt_source *s, const int map[CR_NJOINTS], int rig,
                                     const cr_motion_import_def *def, cr_motion **out,
                                     cr_error *err);

/* The source onto a skinned character's skeleton `skel` (`skel_source` in
 * messages): its joints given roles by name or def->joint_map (right-hand
 * sides: the source's joint names), each driven by the source joint of its
 * role; the root translation scaled by the hips' heights (character over
 * source). The one copy cr_motion_retarget_bvh and
 * cr_motion_retarget_character go through. def NULL: the defaults. */
cr_status cr_retarget_onto_character(const rt_source *s, const int map[CR_NJOINTS], int rig,
                                     const cr_glb_skin *skel, const char *skel_source,
                                     const cr_retarget_def *def, cr_skin_motion **out,
                                     cr_error *err);

/* ------------------------------------------------ a character target -- */

/* A skinned character's skeleton as a target: roles by name, overridden by
 * a joint map file, each joint driven by the source joint of its role. */
typedef struct rt_character {
    rt_target t;
    int *parent, *src, *bone_child; /* (n) */
    double (*rest)[3];              /* (n,3) rest joints in crease's frame, m */
    int role[CR_NJOINTS];           /* the joint given each role, or -1 */
    double turn[4];                 /* the character's frame to crease's */
    double hip_m;                   /* the pelvis's rest height over the lowest joint, m */
    int rig;                        /* the name table that matched */
    int nroles;                     /* roles matched by name */
    int nuser;                      /* joints the map file set */
} rt_character;

/* Build the target for skeleton `skel` (named `skel_source` in messages)
 * driven by a source of nsrc joints (src_names, NULL for unnamed ones such
 * as End Sites; src_role: the source joint of each role, `src_source` its
 * file). map_path (may be NULL): lines "character_joint = source_joint",
 * '#' comments, "joint =" leaves a joint unmapped; or a JSON object of
 * such pairs (null: unmapped). Fails naming the file
 * and line of a bad map line, or the character when its pelvis (hips) is
 * driven by nothing. */
cr_status cr_retarget_character_build(const cr_glb_skin *skel, const char *skel_source,
                                      const char *map_path, int nsrc, const char *const *src_names,
                                      const int src_role[CR_NJOINTS], const char *src_source,
                                      rt_character *c, cr_error *err);
void cr_retarget_character_free(rt_character *c);

#endif
