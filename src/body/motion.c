/* motion.c: what every motion shares once made or loaded: loading and
 * saving by extension, validation, angular speed, re-expressing poses
 * against another rest pose, and turning a foreign motion into crease's
 * frame (motion_internal.h).
 *
 * Resampling, slicing, grounding and the ease-in are in motion_prepare.c.
 *
 * Reference: Loper et al. 2015 (SMPL's pose convention: local axis-angle
 * rotations in world-aligned rest frames).
 */
#include "body/retarget_internal.h"

#include <stdlib.h>
#include <string.h>

cr_motion_import_def cr_motion_import_default_def(void) {
    cr_motion_import_def d;
    memset(&d, 0, sizeof d);
    d.bvh_scale = 0.0f;
    d.recenter = 1;
    d.retarget = 1;
    d.cookie = MOTION_IMPORT_COOKIE;
    return d;
}

cr_status cr_motion_import(const char *path, const cr_motion_import_def *def, cr_motion **out,
                           cr_error *err) {
    *out = NULL;
    char glb[1024], ext[16];
    const char *map = NULL;
    const int character = cr_spec_split(path, ".glb", glb, sizeof glb, &map);
    if (character < 0) return CR_FAIL(err, CR_ERR_INVALID, "motion: path too long: %s", path);
    if (character) return cr_motion_read_character(glb, map, def, out, err);
    cr_path_ext(path, ext, sizeof ext);
    if (strcmp(ext, "bvh") == 0) {
        char *buf;
        size_t len;
        CR_TRY(cr_file_read_all(path, &buf, &len, err));
        cr_status st = cr_motion_read_bvh_mem(buf, len, path, def, out, err);
        free(buf);
        return st;
    }
    if (strcmp(ext, "npz") == 0) {
        cr_npz *z = NULL;
        CR_TRY(cr_npz_open(path, &z, err));
        cr_status st = cr_motion_from_npz(z, path, def, out, err);
        cr_npz_close(z);
        return st;
    }
    if (!ext[0])
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: no file extension, so no motion format (crease reads .bvh, .npz and a "
                       "rigged character's .glb)",
                       path);
    return CR_FAIL(
        err, CR_ERR_UNSUPPORTED,
        "%s: unknown motion format '.%s' (crease reads .bvh, .npz and a rigged character's .glb)",
        path, ext);
}

cr_status cr_motion_retarget(const char *spec, const cr_glb_skin *skel, const char *skel_source,
                             const cr_retarget_def *def, cr_skin_motion **out, cr_error *err) {
    *out = NULL;
    char glb[1024];
    const char *map = NULL;
    const int character = cr_spec_split(spec, ".glb", glb, sizeof glb, &map);
    if (character < 0) return CR_FAIL(err, CR_ERR_INVALID, "motion: path too long: %s", spec);
    if (character) return cr_motion_retarget_character(glb, map, skel, skel_source, def, out, err);
    return cr_motion_retarget_bvh(spec, skel, skel_source, def, out, err);
}

int cr_spec_split(const char *spec, const char *ext, char *path, size_t cap, const char **tail) {
    *tail = NULL;
    const size_t len = strlen(ext);
    const char *at = spec ? strstr(spec, ext) : NULL;
    if (!at || (at[len] != '\0' && at[len] != ':')) return 0;
    const size_t n = (size_t)(at + len - spec);
    if (n >= cap) return -1;
    memcpy(path, spec, n);
    path[n] = '\0';
    if (at[len] == ':') *tail = at + len + 1;
    return 1;
}

cr_status cr_motion_load(const char *path, cr_motion **out, cr_error *err) {
    return cr_motion_import(path, NULL, out, err);
}

cr_status cr_motion_validate(const cr_motion *m, const char *source, cr_error *err) {
    if (m->nframes < 1 || !m->poses || !m->trans)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: motion has no frames", source);
    if (!isfinite(m->fps) || m->fps <= 0)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: frame rate %g (need > 0)", source, (double)m->fps);
    for (int32_t f = 0; f < m->nframes; f++) {
        for (int k = 0; k < CR_NJOINTS * 3; k++)
            if (!isfinite(m->poses[(size_t)f * CR_NJOINTS * 3 + (size_t)k]))
                return CR_FAIL(err, CR_ERR_NAN, "%s: frame %d: %s rotation is not finite", source,
                               f, cr_joint_name[k / 3]);
        for (int k = 0; k < 3; k++)
            if (!isfinite(m->trans[(size_t)f * 3 + (size_t)k]))
                return CR_FAIL(err, CR_ERR_NAN, "%s: frame %d: translation is not finite", source,
                               f);
    }
    return CR_OK;
}

float cr_motion_max_angular_speed_at(const cr_motion *m, int *joint, int32_t *frame) {
    double best = 0;
    int best_j = 0;
    int32_t best_f = 0;
    for (int32_t f = 1; f < m->nframes; f++)
        for (int j = 0; j < CR_NJOINTS; j++) {
            double a[4], b[4], ai[4], rel[4];
            q_from_aa(m->poses + ((size_t)(f - 1) * CR_NJOINTS + (size_t)j) * 3, a);
            q_from_aa(m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3, b);
            q_conj(a, ai);
            q_mul(ai, b, rel);
            double angle = q_angle(rel);
            if (angle > best) best = angle, best_j = j, best_f = f;
        }
    if (joint) *joint = best_j;
    if (frame) *frame = best_f;
    return (float)(best * m->fps);
}

float cr_motion_max_angular_speed(const cr_motion *m, int *joint) {
    return cr_motion_max_angular_speed_at(m, joint, NULL);
}

void cr_motion_apose_from_tpose(float arm_angle_deg, float rest[CR_NJOINTS * 3]) {
    memset(rest, 0, CR_NJOINTS * 3 * sizeof(float));
    float a = (float)(arm_angle_deg * M_PI / 180.0);
    rest[3 * CR_JOINT_LEFT_SHOULDER + 2] = -a; /* left arm (+X) turns towards -Y */
    rest[3 * CR_JOINT_RIGHT_SHOULDER + 2] = a;
}

void cr_motion_rebase(cr_motion *m, const float rest[CR_NJOINTS * 3]) {
    double g[CR_NJOINTS][4], g_inv[CR_NJOINTS][4];
    for (int j = 0; j < CR_NJOINTS; j++) {
        double r[4];
        q_from_aa(rest + 3 * j, r);
        if (cr_joint_parent[j] < 0)
            memcpy(g[j], r, sizeof r);
        else
            q_mul(g[cr_joint_parent[j]], r, g[j]);
        q_conj(g[j], g_inv[j]);
    }
    for (int32_t f = 0; f < m->nframes; f++)
        for (int j = 0; j < CR_NJOINTS; j++) {
            float *aa = m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3;
            double q[4];
            q_from_aa(aa, q);
            q_mul(q, g_inv[j], q);
            if (cr_joint_parent[j] >= 0) q_mul(g[cr_joint_parent[j]], q, q);
            q_to_aa(q, aa);
        }
}

cr_status cr_motion_fix_frame(cr_motion *m, const motion_frame_fix *fix, cr_error *err) {
    /* Through world rotations (cr_retarget_fix_world, the one copy shared with
     * retargeting onto other skeletons): local = G_parent^-1 G. */
    const size_t T = (size_t)m->nframes;
    double *g = cr_malloc(T * CR_NJOINTS * 4 * sizeof(double), err);
    double *t = cr_malloc(T * 3 * sizeof(double), err);
    if (!g || !t) {
        free(g), free(t);
        return CR_ERR_MEMORY;
    }
    for (size_t f = 0; f < T; f++) {
        double *gf = g + f * CR_NJOINTS * 4;
        for (int j = 0; j < CR_NJOINTS; j++) {
            double q[4];
            q_from_aa(m->poses + (f * CR_NJOINTS + (size_t)j) * 3, q);
            if (cr_joint_parent[j] >= 0) q_mul(gf + 4 * cr_joint_parent[j], q, q);
            memcpy(gf + 4 * j, q, sizeof q);
        }
        for (int k = 0; k < 3; k++)
            t[3 * f + (size_t)k] = m->trans[3 * f + (size_t)k];
    }
    cr_retarget_fix_world(g, CR_NJOINTS, CR_JOINT_PELVIS, t, m->nframes, fix);
    motion_from_world(g, t, m);
    free(g), free(t);
    return CR_OK;
}
