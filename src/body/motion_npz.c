/* motion_npz.c: motions in .npz archives: AMASS-style files and crease's own.
 *
 * Reads
 *   poses            (T, 3J) or (T, J, 3), J >= 22: SMPL (J = 24), SMPL+H (52),
 *                    SMPL-X (55); the first 22 joints are SMPL's body joints in
 *                    every one of them, the rest (hands, jaw, eyes) are dropped;
 *                    or root_orient (T, 3) with pose_body (T, 63) (AMASS's
 *                    SMPL-X release) when there is no 'poses';
 *   trans            (T, 3), m; optional (a motion in place without it);
 *   mocap_framerate  () or (1,), frames per second; also 'mocap_frame_rate'
 *                    or 'fps';
 *   up_axis          () int, 1 = +Y, 2 = +Z: written by crease; its absence
 *                    marks an AMASS file.
 * Other members (betas, gender, dmpls, ...) are ignored. Any float or integer
 * dtype npz.h reads is accepted.
 *
 * AMASS worlds are Z-up while SMPL's body is Y-up: the root orientation and
 * translation are turned by -90 degrees about X. With the import def's
 * `recenter` (default) an AMASS motion is then turned about +Y so frame 0
 * faces +Z and shifted so frame 0's root is at the origin (height included:
 * frame 0 is taken to stand at the body's rest height, since the rest pelvis
 * height of the capture subject is not in the file). crease's own files
 * (up_axis = 1) are read back exactly.
 *
 * References: AMASS (Mahmood et al. 2019) and its released .npz layout;
 * SMPL+H / SMPL-X joint orders (Romero et al. 2017, Pavlakos et al. 2019).
 */
#include "body/motion_internal.h"
#include "crease/body.h"

#include <stdlib.h>
#include <string.h>

enum { UP_Y = 1, UP_Z = 2 };
static const double FPS_MAX = 10000.0; /* frames per second; anything above is corrupt */

static void shape_str(const cr_npy *a, char *out, size_t cap) {
    int n = snprintf(out, cap, "(");
    for (int k = 0; k < a->ndim && n < (int)cap - 24; k++)
        n += snprintf(out + n, cap - (size_t)n, k ? ", %lld" : "%lld", (long long)a->shape[k]);
    snprintf(out + n, cap - (size_t)n, a->ndim == 1 ? ",)" : ")");
}

static cr_status read_scalar(const cr_npz *z, const char *source, const char *key, double *out,
                             cr_error *err) {
    cr_npy a;
    CR_TRY(cr_npz_get(z, key, CR_NPY_AS_F64, &a, err));
    int ok = a.count == 1 && a.ndim <= 1;
    if (ok) *out = a.f64[0];
    cr_npy_free(&a);
    if (!ok) return CR_FAIL(err, CR_ERR_SHAPE, "%s: %s: expected one number", source, key);
    return CR_OK;
}

static cr_status read_fps(const cr_npz *z, const char *source, double *fps, cr_error *err) {
    static const char *const keys[] = {"mocap_framerate", "mocap_frame_rate", "fps"};
    for (int i = 0; i < 3; i++)
        if (cr_npz_has(z, keys[i])) {
            CR_TRY(read_scalar(z, source, keys[i], fps, err));
            if (!(*fps > 0 && *fps <= FPS_MAX))
                return CR_FAIL(err, CR_ERR_RANGE, "%s: %s = %g, expected (0, %g]", source, keys[i],
                               *fps, FPS_MAX);
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_PARSE, "%s: no frame rate (expected 'mocap_framerate')", source);
}

/* The (T, 66) body poses as a row stride into `*poses` (caller frees). */
static cr_status read_poses(const cr_npz *z, const char *source, cr_npy *poses, int64_t *stride,
                            cr_error *err) {
    char shape[200];
    if (cr_npz_has(z, "poses")) {
        CR_TRY(cr_npz_get(z, "poses", CR_NPY_AS_F32, poses, err));
        int64_t cols = poses->ndim == 2                           ? poses->shape[1]
                       : poses->ndim == 3 && poses->shape[2] == 3 ? 3 * poses->shape[1]
                                                                  : -1;
        if (cols < 3 * CR_NJOINTS || cols % 3 != 0 || poses->shape[0] < 1) {
            shape_str(poses, shape, sizeof shape);
            cr_npy_free(poses);
            return CR_FAIL(err, CR_ERR_SHAPE,
                           "%s: poses: shape %s, expected (T, 3J) or (T, J, 3) with T >= 1 and "
                           "J >= 22 (SMPL (T, 72), SMPL+H (T, 156), SMPL-X (T, 165))",
                           source, shape);
        }
        *stride = cols;
        return CR_OK;
    }
    if (!cr_npz_has(z, "root_orient") || !cr_npz_has(z, "pose_body"))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: no 'poses' array (nor 'root_orient' with 'pose_body')", source);
    cr_npy root, body;
    CR_TRY(cr_npz_get(z, "root_orient", CR_NPY_AS_F32, &root, err));
    cr_status st = cr_npz_get(z, "pose_body", CR_NPY_AS_F32, &body, err);
    if (st == CR_OK && !(root.ndim == 2 && root.shape[1] == 3 && root.shape[0] >= 1 &&
                         body.ndim == 2 && body.shape[1] == 63 && body.shape[0] == root.shape[0]))
        st = CR_FAIL(err, CR_ERR_SHAPE,
                     "%s: root_orient and pose_body must be (T, 3) and (T, 63) with the same T",
                     source);
    if (st == CR_OK) {
        memset(poses, 0, sizeof *poses);
        poses->ndim = 2;
        poses->shape[0] = root.shape[0];
        poses->shape[1] = 66;
        poses->count = root.shape[0] * 66;
        poses->f32 = cr_malloc((size_t)poses->count * sizeof(float), err);
        if (!poses->f32) st = CR_ERR_MEMORY;
        for (int64_t f = 0; st == CR_OK && f < root.shape[0]; f++) {
            memcpy(poses->f32 + f * 66, root.f32 + f * 3, 3 * sizeof(float));
            memcpy(poses->f32 + f * 66 + 3, body.f32 + f * 63, 63 * sizeof(float));
        }
        *stride = 66;
    }
    cr_npy_free(&root);
    cr_npy_free(&body);
    return st;
}

cr_status cr_motion_from_npz(const cr_npz *z, const char *source, const cr_motion_import_def *def,
                             cr_motion **out, cr_error *err) {
    *out = NULL;
    cr_motion_import_def defaults = cr_motion_import_default_def();
    if (!def) def = &defaults;
    CR_ASSERT(def->cookie == MOTION_IMPORT_COOKIE);
    int up = 0;
    if (cr_npz_has(z, "up_axis")) {
        double v = 0.0;
        CR_TRY(read_scalar(z, source, "up_axis", &v, err));
        if (v != UP_Y && v != UP_Z)
            return CR_FAIL(err, CR_ERR_RANGE, "%s: up_axis = %g, expected 1 (+Y) or 2 (+Z)", source,
                           v);
        up = (int)v;
    }
    double fps = 0.0;
    CR_TRY(read_fps(z, source, &fps, err));
    cr_npy poses, trans = {0};
    int64_t stride;
    CR_TRY(read_poses(z, source, &poses, &stride, err));
    int64_t nframes = poses.shape[0];
    cr_status st = CR_OK;
    if (nframes > INT32_MAX)
        st = CR_FAIL(err, CR_ERR_RANGE, "%s: %lld frames is too many", source, (long long)nframes);
    if (st == CR_OK && cr_npz_has(z, "trans")) {
        st = cr_npz_get(z, "trans", CR_NPY_AS_F32, &trans, err);
        if (st == CR_OK && !(trans.ndim == 2 && trans.shape[0] == nframes && trans.shape[1] == 3)) {
            char shape[200];
            shape_str(&trans, shape, sizeof shape);
            st = CR_FAIL(err, CR_ERR_SHAPE, "%s: trans: shape %s, expected (%lld, 3)", source,
                         shape, (long long)nframes);
        }
    }
    cr_motion *m = NULL;
    if (st == CR_OK) st = cr_motion_create((int32_t)nframes, (float)fps, &m, err);
    if (st == CR_OK) {
        for (int64_t f = 0; f < nframes; f++)
            memcpy(m->poses + f * CR_NJOINTS * 3, poses.f32 + f * stride,
                   CR_NJOINTS * 3 * sizeof(float));
        if (trans.f32) memcpy(m->trans, trans.f32, (size_t)nframes * 3 * sizeof(float));
        if (up != UP_Y) {
            motion_frame_fix fix = {.recenter = up == 0 && def->recenter, .recenter_height = 1};
            q_axis(1, 0, 0, -M_PI / 2, fix.world); /* Z-up to Y-up: (x, y, z) -> (x, z, -y) */
            st = cr_motion_fix_frame(m, &fix, err);
        }
        if (st == CR_OK && up == 0 && def->retarget) {
            /* AMASS poses are relative to SMPL's T-pose: re-expressed against
             * the mannequin's A-pose, crease's one rest. */
            float apose[CR_NJOINTS * 3];
            cr_motion_apose_from_tpose(cr_mannequin_default_def().arm_angle_deg, apose);
            cr_motion_rebase(m, apose);
        }
    }
    cr_npy_free(&poses);
    cr_npy_free(&trans);
    if (st != CR_OK) {
        cr_motion_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_motion_read_npz_mem(const void *data, size_t len, const char *source,
                                 const cr_motion_import_def *def, cr_motion **out, cr_error *err) {
    *out = NULL;
    cr_npz *z = NULL;
    CR_TRY(cr_npz_open_mem(data, len, source, &z, err));
    cr_status st = cr_motion_from_npz(z, source, def, out, err);
    cr_npz_close(z);
    return st;
}

cr_status cr_motion_save(const char *path, const cr_motion *m, cr_error *err) {
    char ext[16];
    cr_path_ext(path, ext, sizeof ext);
    if (strcmp(ext, "npz") != 0)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: motions are written as .npz, not '.%s'", path,
                       ext);
    CR_TRY(cr_motion_validate(m, path, err));
    cr_npz_writer *w = NULL;
    CR_TRY(cr_npz_writer_open(path, 1, &w, err));
    int64_t pshape[2] = {m->nframes, CR_NJOINTS * 3}, tshape[2] = {m->nframes, 3};
    double fps = m->fps;
    int32_t up = UP_Y;
    cr_status st = cr_npz_writer_add(w, "poses", CR_NPY_F32, 2, pshape, m->poses, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "trans", CR_NPY_F32, 2, tshape, m->trans, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "mocap_framerate", CR_NPY_F64, 0, NULL, &fps, err);
    if (st == CR_OK) st = cr_npz_writer_add(w, "up_axis", CR_NPY_I32, 0, NULL, &up, err);
    if (st != CR_OK) {
        cr_npz_writer_abort(w);
        return st;
    }
    return cr_npz_writer_commit(w, err);
}
