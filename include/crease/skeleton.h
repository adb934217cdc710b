/* skeleton.h: SMPL's 22 body joints (order, names, parent table) and the
 * pose and motion representation every body-driven module shares.
 *
 * A pose is one axis-angle rotation per joint, relative to its parent's frame
 * in the rest pose (SMPL's convention: joint 0's rotation is the global
 * orientation), plus a root translation in metres. A motion is a sequence of
 * poses at a frame rate. SMPL's two hand joints (22, 23) are left out: the
 * procedural mannequin has no fingers and loaders drop them.
 *
 * Reference: Loper et al. 2015, SMPL (kintree_table of the released model).
 */
#ifndef CREASE_SKELETON_H
#define CREASE_SKELETON_H

#include "crease/base.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

struct cr_mesh;

#define CR_NJOINTS 22

typedef enum cr_joint {
    CR_JOINT_PELVIS = 0,
    CR_JOINT_LEFT_HIP,
    CR_JOINT_RIGHT_HIP,
    CR_JOINT_SPINE1,
    CR_JOINT_LEFT_KNEE,
    CR_JOINT_RIGHT_KNEE,
    CR_JOINT_SPINE2,
    CR_JOINT_LEFT_ANKLE,
    CR_JOINT_RIGHT_ANKLE,
    CR_JOINT_SPINE3,
    CR_JOINT_LEFT_FOOT,
    CR_JOINT_RIGHT_FOOT,
    CR_JOINT_NECK,
    CR_JOINT_LEFT_COLLAR,
    CR_JOINT_RIGHT_COLLAR,
    CR_JOINT_HEAD,
    CR_JOINT_LEFT_SHOULDER,
    CR_JOINT_RIGHT_SHOULDER,
    CR_JOINT_LEFT_ELBOW,
    CR_JOINT_RIGHT_ELBOW,
    CR_JOINT_LEFT_WRIST,
    CR_JOINT_RIGHT_WRIST
} cr_joint;

/* Parent of each joint, -1 for the pelvis (SMPL's kintree_table row 0). */
extern const int8_t cr_joint_parent[CR_NJOINTS];
/* SMPL's names: "pelvis", "left_hip", ..., "right_wrist". */
extern const char *const cr_joint_name[CR_NJOINTS];

/* Index of a joint by its SMPL name, or -1. */
int cr_joint_find(const char *name);

/* A motion: T poses at fps frames per second. Owned buffers; free with
 * cr_motion_destroy. */
typedef struct cr_motion {
    int32_t nframes; /* T */
    float fps;
    float *poses; /* (T, 22, 3) axis-angle per joint, radians */
    float *trans; /* (T, 3) root translation, m */
} cr_motion;

/* A skinned body in its rest pose: what the procedural mannequin and a
 * loaded SMPL-style model both produce. Linear blend skinning with at most
 * four joints per vertex (weights sum to 1, unused slots weight 0). */
typedef struct cr_body_model {
    struct cr_mesh *rest;         /* rest-pose mesh (A-pose for the mannequin), m, +Y up */
    float joints[CR_NJOINTS * 3]; /* rest joint positions, m */
    int32_t *skin_joint;          /* (V, 4) joint indices */
    float *skin_weight;           /* (V, 4) weights */
} cr_body_model;

/* Zeroed poses and translations for T frames. */
cr_status cr_motion_create(int32_t nframes, float fps, cr_motion **out, cr_error *err);
void cr_motion_destroy(cr_motion *m);

#ifdef __cplusplus
}
#endif
#endif
