/* crease/body.h: posing bodies and the procedural mannequin.
 *
 *   axis-angle -> rotation matrix (Rodrigues)                  cr_body_rodrigues
 *   pose -> world joint rotations and positions                cr_body_forward_kinematics
 *   pose -> per-joint skinning transforms                      cr_body_skin_transforms
 *   linear blend skinning of one pose / a whole motion         cr_body_pose, cr_body_pose_motion
 *   checks and cleanup of a cr_body_model                      cr_body_model_validate, _destroy
 *   the procedural mannequin (shape presets, A-pose rest)      cr_mannequin_*
 *
 * Pose convention (SMPL's, skeleton.h): pose[3j..3j+2] is joint j's rotation
 * as an axis-angle vector (radians) in its parent's frame, relative to the
 * rest pose; joint 0's is the global orientation. With rest joints J_j and
 * R_j = Rodrigues(pose_j), the world transform of joint j is
 *     G_0 = [R_0 | J_0],   G_j = G_parent(j) [R_j | J_j - J_parent(j)],
 * and a rest point x bound to joint j goes to G_j (x - J_j) + trans. Linear
 * blend skinning sums these with the vertex's four weights. The zero pose
 * reproduces the rest mesh exactly (the rotations are exactly the identity).
 *
 *   cr_mannequin_def def = cr_mannequin_default_def();
 *   CR_TRY(cr_mannequin_preset("heavy", &def, err));
 *   def.height_m = 1.80f;
 *   cr_body_model *body = NULL;
 *   CR_TRY(cr_mannequin_create(&def, &body, err));
 *   float *seq = NULL;                                     (T,V,3), caller frees
 *   CR_TRY(cr_body_pose_motion(body, motion, &seq, err));
 *   cr_body_model_destroy(body);
 *
 * The mannequin: +Y up, feet on y = 0, facing +Z, its left on +X, in an
 * A-pose (arms def.arm_angle_deg below horizontal, palms towards the thighs).
 * Rest joints sit where SMPL puts them relative to the surface. See
 * src/body/mannequin.c and docs/body.md for the construction.
 *
 * Units: m, rad. Thread safety: every function is reentrant; a built
 * cr_body_model is read-only and may be shared between threads.
 */
#ifndef CREASE_BODY_H
#define CREASE_BODY_H

#include "crease/mesh.h"
#include "crease/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ----------------------------------------------------------- kinematics -- */

/* R (3,3) row-major = exp([aa]x), the rotation by |aa| radians about aa.
 * Near zero angle the Taylor series is used, so tiny vectors stay accurate and
 * the zero vector gives the identity exactly. */
void cr_body_rodrigues(const float aa[3], float R[9]);

/* World rotation rot (22,3,3) row-major and position pos (22,3), m, of every
 * joint for a pose (22,3) axis-angle, rad, and root translation trans (3), m,
 * given rest joint positions joints (22,3), m. trans may be NULL (zero).
 * Either output may be NULL. */
void cr_body_forward_kinematics(const float *joints, const float *pose, const float *trans,
                                float *rot, float *pos);

/* xf (22,3,4) row-major [A | b] per joint: a rest point x bound rigidly to
 * joint j goes to A x + b. Arguments as for cr_body_forward_kinematics. */
void cr_body_skin_transforms(const float *joints, const float *pose, const float *trans, float *xf);

/* Posed vertex positions out (V,3), m, of body b for pose (22,3) and trans
 * (3) (may be NULL). CR_ERR_NAN when the pose or translation is not finite. */
cr_status cr_body_pose(const cr_body_model *b, const float *pose, const float *trans, float *out,
                       cr_error *err);

/* Every frame of motion m skinned: *out (T,V,3), m, allocated here (caller
 * frees with free()). Parallel over frames. CR_ERR_NAN naming the first frame
 * with a non-finite pose or translation; CR_ERR_MEMORY. */
cr_status cr_body_pose_motion(const cr_body_model *b, const cr_motion *m, float **out,
                              cr_error *err);

/* Write body b animated by motion m as a skinned glTF character (.glb):
 * SMPL's 22 joints by name, the rest (A-)pose as the bind pose, one
 * animation of m's rotations and root translation at m->fps
 * (cr_glb_write_skinned); with `garment` (may be NULL), its frames (T,Vg,3)
 * beside the body on the same timeline. Blender and three.js play it;
 * without a garment cr_glb_read_sequence reads it back posed as
 * cr_body_pose_motion poses it. CR_ERR_NAN naming a non-finite frame. */
cr_status cr_body_write_glb(const char *path, const cr_body_model *b, const cr_motion *m,
                            const cr_mesh *garment, const float *garment_frames, cr_error *err);

/* ------------------------------------------------------------ the model -- */

/* CR_OK when b has a valid rest mesh (cr_mesh_validate), finite joints,
 * skinning joints in [0, 22) and weights that are finite, non-negative and
 * sum to 1 within 1e-4 per vertex. `source` names the model in messages. */
cr_status cr_body_model_validate(const cr_body_model *b, const char *source, cr_error *err);

/* Free the rest mesh, the skinning arrays and b; NULL is a no-op. */
void cr_body_model_destroy(cr_body_model *b);

/* ------------------------------------------------------------ mannequin -- */

typedef struct cr_mannequin_def {
    float height_m;      /* top of the head above the soles, m, in [1.0, 2.5]; 1.75 */
    float girth;         /* scale of every radius and cross-section, in [0.6, 1.6]; 1 */
    float chest;         /* extra scale of the chest's cross-section, in [0.7, 1.5]; 1 */
    float hips;          /* extra scale of the hips and buttocks, in [0.7, 1.5]; 1 */
    float arm_angle_deg; /* A-pose: upper arms this far below horizontal, in [0, 80]; 40 */
    /* Grid cells over the height, in [32, 512]; 110 gives about 9.5k vertices.
     * Below about 60 a thin shape's wrists may come apart (then create fails). */
    int32_t resolution;
    int32_t relax_iterations; /* tangential relaxation rounds, in [0, 100]; 10 */
    /* Softness of the skinning blends, m, in [0.001, 0.1]; 0.03: the temperature
     * of the part memberships (softmax of -distance / blend_m) and, in
     * proportion, the width of each joint's blend. */
    float blend_m;
    uint32_t cookie; /* set by cr_mannequin_default_def; a hand-zeroed def is a bug */
} cr_mannequin_def;

/* The `normal` body: 1.75 m, girth, chest and hips 1, arms 40 degrees down,
 * resolution 110, 10 relaxation rounds, 3 cm skinning blend. */
cr_mannequin_def cr_mannequin_default_def(void);

/* Set girth, chest and hips for "slim", "normal" or "heavy" (other fields
 * untouched). CR_ERR_INVALID naming an unknown preset. */
cr_status cr_mannequin_preset(const char *name, cr_mannequin_def *def, cr_error *err);

enum { CR_BODY_MAX_BETAS = 400 }; /* SMPL-X has 300 shape and 100 expression ones */

/* A body as the commands take it: a mannequin preset ("slim", "normal",
 * "heavy"), or an SMPL-family model file with its shape coefficients,
 * "FILE.npz" or "FILE.npz:b0,b1,..." (or "FILE.npz:b0:b1:...", for a list
 * that is itself comma-separated) (cr_smpl_load: SMPL, SMPL+H, SMPL-X; the
 * betas zero-padded), or a rigged glTF character "CHAR.glb" or
 * "CHAR.glb:MAP" (cr_body_from_character). *out is heap-allocated
 * (cr_body_model_destroy).
 * Fails naming the spec: an unknown preset lists the presets, a bad beta
 * names its position. */
cr_status cr_body_resolve(const char *spec, cr_body_model **out, cr_error *err);

/* A rigged glTF character (a skinned mesh: JOINTS_0, WEIGHTS_0, a skin) as a
 * body (body_character.c): its joints given SMPL's 22 roles by name
 * (SMPL, Mixamo, CMU, DAZ/Poser, Unreal, Blender/Rigify conventions) or by
 * joint_map (may be NULL: lines "character_joint = smpl_joint", '#'
 * comments, or a JSON object), its weights merged into those roles, turned
 * into crease's frame, its bind pose re-posed into the mannequin's rest bone
 * directions (the A-pose motions are written against) and stood on the
 * ground.
 * cr_body_resolve takes "CHAR.glb" and "CHAR.glb:MAP". Fails naming the
 * file: no skin, no joint for the hips, a bad map line (file and line). */
cr_status cr_body_from_character(const char *path, const char *joint_map, cr_body_model **out,
                                 cr_error *err);

/* Build the mannequin: a closed, manifold, outward-oriented genus-0 rest mesh
 * with vertex normals, rest joints and four skinning weights per vertex. The
 * caller destroys *out with cr_body_model_destroy. CR_ERR_INVALID naming a
 * field out of range; CR_ERR_TOPOLOGY when the resolution is too coarse for
 * the shape (the surface would not be one piece); CR_ERR_MEMORY. */
cr_status cr_mannequin_create(const cr_mannequin_def *def, cr_body_model **out, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
