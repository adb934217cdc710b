/* skeleton.c: SMPL's joint table and the motion container.
 *
 * Parents and names follow the released SMPL model's kintree_table and the
 * order its papers list (Loper et al. 2015); the hand joints are left out.
 */
#include "crease/skeleton.h"

#include <stdlib.h>
#include <string.h>

const int8_t cr_joint_parent[CR_NJOINTS] = {-1, 0, 0, 0, 1,  2,  3,  4,  5,  6,  7,
                                            8,  9, 9, 9, 12, 13, 14, 16, 17, 18, 19};

const char *const cr_joint_name[CR_NJOINTS] = {
    "pelvis",     "left_hip",    "right_hip",    "spine1",     "left_knee",     "right_knee",
    "spine2",     "left_ankle",  "right_ankle",  "spine3",     "left_foot",     "right_foot",
    "neck",       "left_collar", "right_collar", "head",       "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist",   "right_wrist"};

int cr_joint_find(const char *name) {
    for (int j = 0; j < CR_NJOINTS; j++)
        if (!strcmp(cr_joint_name[j], name)) return j;
    return -1;
}

cr_status cr_motion_create(int32_t nframes, float fps, cr_motion **out, cr_error *err) {
    *out = NULL;
    if (nframes < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "motion: %d frames (need at least 1)", nframes);
    if (!(fps > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "motion: frame rate %g (need > 0)", (double)fps);
    cr_motion *m = cr_calloc(1, sizeof(cr_motion), err);
    if (!m) return err ? err->status : CR_ERR_MEMORY;
    m->nframes = nframes;
    m->fps = fps;
    m->poses = cr_calloc((size_t)nframes * CR_NJOINTS * 3, sizeof(float), err);
    m->trans = cr_calloc((size_t)nframes * 3, sizeof(float), err);
    if (!m->poses || !m->trans) {
        cr_motion_destroy(m);
        return err ? err->status : CR_ERR_MEMORY;
    }
    *out = m;
    return CR_OK;
}

void cr_motion_destroy(cr_motion *m) {
    if (!m) return;
    free(m->poses);
    free(m->trans);
    free(m);
}
