/* skinning.c: linear blend skinning of a cr_body_model, one pose or a whole
 * motion, and the model's checks and cleanup.
 *
 * Each vertex moves by the weighted sum of its four joints' displacements,
 *     y = x + sum_k w_k ((A_k x + b_k) - x),
 * which equals sum_k w_k (A_k x + b_k) when the weights sum to one, and
 * gives y = x bit for bit in the rest pose (A_k = I, b_k = 0 exactly) even
 * though float weights never sum to exactly one.
 *
 * Left out: dual-quaternion skinning (Kavan et al. 2008), which avoids the
 * candy-wrapper collapse under twist that linear blending shows; the
 * mannequin's weights keep blend zones short instead, and SMPL, whose
 * weights the methods' papers were trained with, blends linearly.
 *
 * Reference: Magnenat-Thalmann et al. 1988 (linear blend skinning); Loper et
 * al. 2015, SMPL, eq. 2-4.
 */
#include "body/motion_internal.h"
#include "crease/body.h"
#include "crease/mesh_io.h"

#include <math.h>
#include <stdlib.h>

static void skin_range(const cr_body_model *b, const float *xf, int64_t begin, int64_t end,
                       float *out) {
    const float *x0 = b->rest->pos;
    for (int64_t v = begin; v < end; v++) {
        const float *x = &x0[3 * v];
        float d[3] = {0, 0, 0};
        for (int k = 0; k < 4; k++) {
            float w = b->skin_weight[4 * v + k];
            if (w == 0.0f) continue;
            const float *M = &xf[12 * b->skin_joint[4 * v + k]];
            for (int r = 0; r < 3; r++)
                d[r] += w * (M[4 * r] * x[0] + M[4 * r + 1] * x[1] + M[4 * r + 2] * x[2] +
                             M[4 * r + 3] - x[r]);
        }
        for (int r = 0; r < 3; r++)
            out[3 * v + r] = x[r] + d[r];
    }
}

static cr_status check_pose(const float *pose, const float *trans, const char *what, int32_t frame,
                            cr_error *err) {
    for (int i = 0; i < CR_NJOINTS * 3; i++)
        if (!isfinite(pose[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: pose of joint %s is not finite (frame %d)", what,
                           cr_joint_name[i / 3], frame);
    for (int d = 0; d < 3 && trans; d++)
        if (!isfinite(trans[d]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: root translation is not finite (frame %d)", what,
                           frame);
    return CR_OK;
}

typedef struct pose_ctx {
    const cr_body_model *b;
    const float *xf;
    float *out;
} pose_ctx;

static void pose_vertices(void *vctx, int64_t begin, int64_t end) {
    pose_ctx *c = vctx;
    skin_range(c->b, c->xf, begin, end, c->out);
}

cr_status cr_body_pose(const cr_body_model *b, const float *pose, const float *trans, float *out,
                       cr_error *err) {
    CR_TRY(check_pose(pose, trans, "body pose", 0, err));
    float xf[CR_NJOINTS * 12];
    cr_body_skin_transforms(b->joints, pose, trans, xf);
    pose_ctx c = {b, xf, out};
    cr_parallel_for(b->rest->nv, 2048, pose_vertices, &c);
    return CR_OK;
}

typedef struct motion_ctx {
    const cr_body_model *b;
    const cr_motion *m;
    float *out;
} motion_ctx;

static void pose_frames(void *vctx, int64_t begin, int64_t end) {
    motion_ctx *c = vctx;
    int64_t nv = c->b->rest->nv;
    for (int64_t t = begin; t < end; t++) {
        float xf[CR_NJOINTS * 12];
        cr_body_skin_transforms(c->b->joints, &c->m->poses[t * CR_NJOINTS * 3], &c->m->trans[3 * t],
                                xf);
        skin_range(c->b, xf, 0, nv, &c->out[t * nv * 3]);
    }
}

cr_status cr_body_pose_motion(const cr_body_model *b, const cr_motion *m, float **out,
                              cr_error *err) {
    *out = NULL;
    for (int32_t t = 0; t < m->nframes; t++)
        CR_TRY(check_pose(&m->poses[(int64_t)t * CR_NJOINTS * 3], &m->trans[3 * (int64_t)t],
                          "motion", t, err));
    float *seq = cr_malloc((size_t)m->nframes * (size_t)b->rest->nv * 3 * sizeof(float), err);
    if (!seq) return CR_ERR_MEMORY;
    motion_ctx c = {b, m, seq};
    cr_parallel_for(m->nframes, 1, pose_frames, &c);
    *out = seq;
    return CR_OK;
}

cr_status cr_body_write_glb(const char *path, const cr_body_model *b, const cr_motion *m,
                            const cr_mesh *garment, const float *garment_frames, cr_error *err) {
    for (int32_t t = 0; t < m->nframes; t++)
        CR_TRY(check_pose(&m->poses[(int64_t)t * CR_NJOINTS * 3], &m->trans[3 * (int64_t)t],
                          "motion", t, err));
    float *q = cr_malloc((size_t)m->nframes * CR_NJOINTS * 4 * sizeof(float), err);
    if (!q) return CR_ERR_MEMORY;
    /* glTF's quaternions are x, y, z, w; motion_internal.h's w, x, y, z. */
    for (int64_t i = 0; i < (int64_t)m->nframes * CR_NJOINTS; i++) {
        double qd[4];
        q_from_aa(&m->poses[3 * i], qd);
        for (int k = 0; k < 4; k++)
            q[4 * i + k] = (float)qd[(k + 1) % 4];
    }
    int32_t parent[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++)
        parent[j] = cr_joint_parent[j];
    const cr_glb_skin skin = {CR_NJOINTS, cr_joint_name, parent,
                              b->joints,  b->skin_joint, b->skin_weight};
    const cr_glb_skin_motion motion = {m->nframes, m->fps, q, m->trans};
    const cr_glb_cloth cloth = {garment, garment_frames};
    cr_status st =
        cr_glb_write_skinned(path, b->rest, &skin, &motion, garment ? &cloth : NULL, err);
    free(q);
    return st;
}

cr_status cr_body_model_validate(const cr_body_model *b, const char *source, cr_error *err) {
    if (!b->rest || !b->skin_joint || !b->skin_weight)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: body model without a rest mesh or skinning",
                       source);
    CR_TRY(cr_mesh_validate(b->rest, source, err));
    for (int j = 0; j < CR_NJOINTS * 3; j++)
        if (!isfinite(b->joints[j]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: rest position of joint %s is not finite", source,
                           cr_joint_name[j / 3]);
    for (int32_t v = 0; v < b->rest->nv; v++) {
        double sum = 0.0;
        for (int k = 0; k < 4; k++) {
            int32_t j = b->skin_joint[4 * v + k];
            float w = b->skin_weight[4 * v + k];
            if (j < 0 || j >= CR_NJOINTS)
                return CR_FAIL(err, CR_ERR_RANGE, "%s: vertex %d is bound to joint %d (need 0..%d)",
                               source, v, j, CR_NJOINTS - 1);
            if (!isfinite(w) || w < 0.0f)
                return CR_FAIL(err, CR_ERR_INVALID, "%s: vertex %d has skinning weight %g", source,
                               v, (double)w);
            sum += w;
        }
        if (fabs(sum - 1.0) > 1e-4)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: skinning weights of vertex %d sum to %.6f",
                           source, v, sum);
    }
    return CR_OK;
}

void cr_body_model_destroy(cr_body_model *b) {
    if (!b) return;
    cr_mesh_destroy(b->rest);
    free(b->skin_joint);
    free(b->skin_weight);
    free(b);
}
