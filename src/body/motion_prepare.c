/* motion_prepare.c: what a loaded motion goes through before a garment is
 * simulated on it: the frames used, a calibration frame dropped, resampling
 * to the simulation's rate, grounding on the body's feet, the ease-in from
 * the rest pose and the angular-speed check (motion.h, cr_motion_prepare).
 *
 * Resampling: slerp of each joint's local rotation between the two nearest
 * frames (Shoemake 1985), linear translation; the duration T / fps is kept.
 * The ease-in: a quintic Hermite curve in the tangent space at the first used
 * frame (zero velocity and acceleration at the rest pose, the motion's own
 * velocity at the join), so cloth starts from rest without a jolt either end.
 *
 * Reference: Shoemake 1985, "Animating rotation with quaternion curves".
 */
#include "body/motion_internal.h"
#include "crease/body.h"
#include "crease/mesh.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PREPARE_COOKIE 0x70726570u

cr_motion_prepare_def cr_motion_prepare_default_def(void) {
    cr_motion_prepare_def d;
    memset(&d, 0, sizeof d);
    d.fps = 0.0f;
    d.start_frame = 0;
    d.end_frame = -1;
    d.drop_calibration = 1;
    d.ease_in_s = 1.0f;
    d.ground = CR_MOTION_GROUND_CLIP;
    d.max_angular_speed = 30.0f;
    d.cookie = PREPARE_COOKIE;
    return d;
}

static const float *pose_at(const cr_motion *m, int32_t f, int j) {
    return m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3;
}

/* q = slerp(a, b, t) on the shorter arc. */
static void q_slerp(const double a[4], const double b_in[4], double t, double q[4]) {
    double b[4], d = a[0] * b_in[0] + a[1] * b_in[1] + a[2] * b_in[2] + a[3] * b_in[3];
    double s = d < 0 ? -1.0 : 1.0;
    for (int k = 0; k < 4; k++)
        b[k] = s * b_in[k];
    d = fabs(d);
    double wa, wb;
    if (d > 1.0 - 1e-9) {
        wa = 1.0 - t, wb = t;
    } else {
        double th = acos(d), sn = sin(th);
        wa = sin((1.0 - t) * th) / sn, wb = sin(t * th) / sn;
    }
    double n = 0;
    for (int k = 0; k < 4; k++)
        q[k] = wa * a[k] + wb * b[k], n += q[k] * q[k];
    n = sqrt(n);
    for (int k = 0; k < 4; k++)
        q[k] /= n;
}

cr_status cr_motion_slice(const cr_motion *m, int32_t first, int32_t last, cr_motion **out,
                          cr_error *err) {
    *out = NULL;
    if (first < 0 || last < first || last >= m->nframes)
        return CR_FAIL(err, CR_ERR_RANGE, "frames %d to %d of a motion of %d frames (0 to %d)",
                       first, last, m->nframes, m->nframes - 1);
    int32_t n = last - first + 1;
    CR_TRY(cr_motion_create(n, m->fps, out, err));
    memcpy((*out)->poses, m->poses + (size_t)first * CR_NJOINTS * 3,
           (size_t)n * CR_NJOINTS * 3 * sizeof(float));
    memcpy((*out)->trans, m->trans + (size_t)first * 3, (size_t)n * 3 * sizeof(float));
    return CR_OK;
}

cr_status cr_motion_resample(const cr_motion *m, float fps, cr_motion **out, cr_error *err) {
    *out = NULL;
    if (!(fps > 0.0f && fps <= 1000.0f))
        return CR_FAIL(err, CR_ERR_RANGE, "resampling to %g fps, need (0, 1000]", (double)fps);
    double ratio = (double)fps / (double)m->fps;
    int64_t n = (int64_t)floor((double)(m->nframes - 1) * ratio + 1e-6) + 1;
    if (n > INT32_MAX) return CR_FAIL(err, CR_ERR_RANGE, "%lld frames is too many", (long long)n);
    CR_TRY(cr_motion_create((int32_t)n, fps, out, err));
    cr_motion *r = *out;
    for (int64_t k = 0; k < n; k++) {
        double x = (double)k / ratio; /* source frame */
        int32_t f0 = (int32_t)floor(x + 1e-9);
        if (f0 > m->nframes - 1) f0 = m->nframes - 1;
        int32_t f1 = f0 + 1 < m->nframes ? f0 + 1 : f0;
        double t = f1 > f0 ? x - f0 : 0.0;
        if (t < 0) t = 0;
        for (int j = 0; j < CR_NJOINTS; j++) {
            double a[4], b[4], q[4];
            q_from_aa(pose_at(m, f0, j), a);
            q_from_aa(pose_at(m, f1, j), b);
            q_slerp(a, b, t, q);
            q_to_aa(q, r->poses + ((size_t)k * CR_NJOINTS + (size_t)j) * 3);
        }
        for (int c = 0; c < 3; c++)
            r->trans[3 * k + c] = (float)((1.0 - t) * m->trans[3 * (size_t)f0 + (size_t)c] +
                                          t * m->trans[3 * (size_t)f1 + (size_t)c]);
    }
    return CR_OK;
}

/* Largest joint angle between frames f and f + 1. */
static double frame_step(const cr_motion *m, int32_t f) {
    double best = 0;
    for (int j = 0; j < CR_NJOINTS; j++) {
        double a[4], b[4], rel[4];
        q_from_aa(pose_at(m, f, j), a);
        q_from_aa(pose_at(m, f + 1, j), b);
        q_conj(a, a);
        q_mul(a, b, rel);
        best = fmax(best, q_angle(rel));
    }
    return best;
}

int cr_motion_is_calibration_start(const cr_motion *m, float *jump) {
    if (jump) *jump = 0.0f;
    if (m->nframes < 3) return 0;
    double j0 = frame_step(m, 0), next = frame_step(m, 1);
    if (m->nframes > 3) next = fmax(next, frame_step(m, 2));
    if (jump) *jump = (float)j0;
    return motion_calibration_rule(j0, next);
}

cr_status cr_motion_ease_in(const cr_motion *m, float seconds, cr_motion **out, cr_error *err) {
    *out = NULL;
    if (!(seconds >= 0.0f && seconds <= 60.0f))
        return CR_FAIL(err, CR_ERR_RANGE, "ease-in %g s, need [0, 60]", (double)seconds);
    int64_t ne = (int64_t)lround((double)seconds * m->fps);
    if (ne + m->nframes > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "an ease-in of %lld frames is too long", (long long)ne);
    CR_TRY(cr_motion_create((int32_t)(ne + m->nframes), m->fps, out, err));
    cr_motion *r = *out;
    memcpy(r->poses + (size_t)ne * CR_NJOINTS * 3, m->poses,
           (size_t)m->nframes * CR_NJOINTS * 3 * sizeof(float));
    memcpy(r->trans + (size_t)ne * 3, m->trans, (size_t)m->nframes * 3 * sizeof(float));
    if (ne == 0) return CR_OK;
    double span = (double)ne / m->fps; /* s */
    int has_next = m->nframes > 1;
    for (int j = 0; j < CR_NJOINTS; j++) {
        double q0[4], q1[4], vel[3];
        q_from_aa(pose_at(m, 0, j), q0);
        if (has_next) q_from_aa(pose_at(m, 1, j), q1);
        motion_ease_velocity(q0, has_next ? q1 : NULL, m->fps * span, vel);
        for (int64_t k = 0; k < ne; k++) {
            double q[4];
            motion_ease_rotation(q0, vel, (double)k / (double)ne, q);
            float *dst = r->poses + ((size_t)k * CR_NJOINTS + (size_t)j) * 3;
            q_to_aa(q, dst);
            if (k == 0) dst[0] = dst[1] = dst[2] = 0.0f; /* the rest, exactly */
        }
    }
    for (int c = 0; c < 3; c++) {
        double t0 = m->trans[c];
        double v = has_next ? (m->trans[3 + c] - t0) * m->fps * span : 0.0;
        for (int64_t k = 0; k < ne; k++)
            r->trans[3 * k + c] = (float)motion_ease_value(t0, v, (double)k / (double)ne);
    }
    return CR_OK;
}

/* The vertices of b skinned mostly (half or more) to the ankles and feet. */
static cr_status foot_vertices(const cr_body_model *b, int32_t **idx, int32_t *n, cr_error *err) {
    static const int feet[] = {CR_JOINT_LEFT_ANKLE, CR_JOINT_RIGHT_ANKLE, CR_JOINT_LEFT_FOOT,
                               CR_JOINT_RIGHT_FOOT};
    int32_t nv = b->rest->nv;
    *n = 0;
    *idx = cr_malloc((size_t)nv * sizeof **idx, err);
    if (!*idx) return CR_ERR_MEMORY;
    for (int32_t v = 0; v < nv; v++) {
        float w = 0.0f;
        for (int k = 0; k < 4; k++)
            for (int f = 0; f < 4; f++)
                if (b->skin_joint[4 * v + k] == feet[f]) w += b->skin_weight[4 * v + k];
        if (w >= 0.5f) (*idx)[(*n)++] = v;
    }
    if (*n == 0) {
        free(*idx);
        *idx = NULL;
        return CR_FAIL(err, CR_ERR_INVALID, "grounding: the body has no foot vertices");
    }
    return CR_OK;
}

/* Lowest y of the foot vertices idx posed by frame f of m. */
static float foot_low(const cr_body_model *b, const int32_t *idx, int32_t n, const cr_motion *m,
                      int32_t f) {
    float xf[CR_NJOINTS * 12];
    cr_body_skin_transforms(b->joints, pose_at(m, f, 0), m->trans + 3 * (size_t)f, xf);
    float lo = INFINITY;
    for (int32_t i = 0; i < n; i++) {
        int32_t v = idx[i];
        const float *x = b->rest->pos + 3 * (size_t)v;
        float y = 0.0f;
        for (int k = 0; k < 4; k++) {
            float w = b->skin_weight[4 * v + k];
            if (w == 0.0f) continue;
            const float *M = &xf[12 * b->skin_joint[4 * v + k] + 4];
            y += w * (M[0] * x[0] + M[1] * x[1] + M[2] * x[2] + M[3]);
        }
        lo = fminf(lo, y);
    }
    return lo;
}

static cr_status default_body(const cr_body_model **b, cr_body_model **own, cr_error *err) {
    *own = NULL;
    if (*b) return CR_OK;
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 64;
    CR_TRY(cr_mannequin_create(&md, own, err));
    *b = *own;
    return CR_OK;
}

cr_status cr_motion_ground(cr_motion *m, const cr_body_model *b, cr_motion_ground_mode mode,
                           float *shift_m, cr_error *err) {
    if (shift_m) *shift_m = 0.0f;
    if (mode == CR_MOTION_GROUND_NONE) return CR_OK;
    cr_body_model *own = NULL;
    CR_TRY(default_body(&b, &own, err));
    int32_t *idx = NULL, nfoot = 0;
    float *low = cr_malloc((size_t)m->nframes * sizeof *low, err);
    cr_status st = low ? foot_vertices(b, &idx, &nfoot, err) : CR_ERR_MEMORY;
    float lowest = INFINITY;
    for (int32_t f = 0; st == CR_OK && f < m->nframes; f++) {
        low[f] = foot_low(b, idx, nfoot, m, f);
        lowest = fminf(lowest, low[f]);
    }
    if (st == CR_OK) {
        for (int32_t f = 0; f < m->nframes; f++)
            m->trans[3 * (size_t)f + 1] -= mode == CR_MOTION_GROUND_FRAME ? low[f] : lowest;
        if (shift_m) *shift_m = -lowest;
    }
    free(idx);
    free(low);
    cr_body_model_destroy(own);
    return st;
}

/* The ease's blends may take a foot below the floor (a leg straightening
 * before the pelvis drops): those frames are lifted by what they sink. */
static cr_status lift_ease(cr_motion *m, int32_t nease, const cr_body_model *b, cr_error *err) {
    int32_t *idx = NULL, nfoot = 0;
    CR_TRY(foot_vertices(b, &idx, &nfoot, err));
    for (int32_t f = 1; f < nease; f++) {
        float lo = foot_low(b, idx, nfoot, m, f);
        if (lo < 0.0f) m->trans[3 * (size_t)f + 1] -= lo;
    }
    free(idx);
    return CR_OK;
}

static void replace(cr_motion **cur, cr_motion *next) {
    cr_motion_destroy(*cur);
    *cur = next;
}

cr_status cr_motion_prepare(const cr_motion *m, const cr_motion_prepare_def *def,
                            const cr_body_model *b, cr_motion **out, cr_motion_prepare_report *rep,
                            cr_error *err) {
    *out = NULL;
    cr_motion_prepare_def defaults = cr_motion_prepare_default_def();
    if (!def) def = &defaults;
    CR_ASSERT(def->cookie == PREPARE_COOKIE);
    cr_motion_prepare_report r;
    memset(&r, 0, sizeof r);
    r.source_fps = m->fps, r.source_frames = m->nframes;
    int32_t first = def->start_frame, last = def->end_frame < 0 ? m->nframes - 1 : def->end_frame;
    if (first < 0 || first >= m->nframes || last < first || last >= m->nframes)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "start frame %d, end frame %d: the motion has frames 0 to %d", first,
                       def->end_frame, m->nframes - 1);
    float jump = 0.0f;
    if (def->drop_calibration && first == 0 && last >= 3 &&
        cr_motion_is_calibration_start(m, &jump)) {
        cr_log(CR_LOG_WARN,
               "motion: frame 0 is a calibration frame (joints turn by up to %.2f rad into "
               "frame 1): dropped; --start-frame 0 keeps it",
               (double)jump);
        first = 1, r.calibration_dropped = 1;
    }
    r.first_frame = first, r.last_frame = last;
    cr_motion *cur = NULL, *next = NULL;
    cr_body_model *own = NULL;
    if (def->ground != CR_MOTION_GROUND_NONE) CR_TRY(default_body(&b, &own, err));
    cr_status st = cr_motion_slice(m, first, last, &cur, err);
    if (def->fps > 0.0f && def->fps != cur->fps) {
        st = cr_motion_resample(cur, def->fps, &next, err);
        if (st == CR_OK) replace(&cur, next);
    }
    if (st == CR_OK) st = cr_motion_ground(cur, b, def->ground, &r.ground_shift_m, err);
    if (st == CR_OK && def->ease_in_s > 0.0f) {
        st = cr_motion_ease_in(cur, def->ease_in_s, &next, err);
        if (st == CR_OK) {
            r.ease_frames = next->nframes - cur->nframes;
            replace(&cur, next);
        }
        if (st == CR_OK && def->ground != CR_MOTION_GROUND_NONE)
            st = lift_ease(cur, r.ease_frames, b, err);
    }
    cr_body_model_destroy(own);
    if (st != CR_OK) {
        cr_motion_destroy(cur);
        return st;
    }
    r.max_angular_speed =
        cr_motion_max_angular_speed_at(cur, &r.max_speed_joint, &r.max_speed_frame);
    if (r.max_angular_speed > def->max_angular_speed)
        cr_log(CR_LOG_WARN,
               "motion: %s turns at %.1f rad/s at frame %d (of %d at %g fps), beyond what a body "
               "does (%g rad/s): a glitch in the capture, or a rate mismatch?",
               cr_joint_name[r.max_speed_joint], (double)r.max_angular_speed, r.max_speed_frame,
               cur->nframes, (double)cur->fps, (double)def->max_angular_speed);
    if (rep) *rep = r;
    *out = cur;
    return CR_OK;
}

/* ------------------------------------------------------------- resolve -- */

#define RESOLVE_DEF_COOKIE 0x4d525356u /* "MRSV" */

int cr_motion_is_clip(const char *spec) {
    return spec && cr_motion_clip_summary(spec) != NULL;
}

cr_motion_resolve_def cr_motion_resolve_default_def(void) {
    cr_motion_resolve_def d;
    memset(&d, 0, sizeof d);
    d.clip_frames = 120;
    d.fps = 30.0f;
    d.import = cr_motion_import_default_def();
    d.prepare = cr_motion_prepare_default_def();
    d.cookie = RESOLVE_DEF_COOKIE;
    return d;
}

cr_status cr_motion_resolve(const char *spec, const cr_motion_resolve_def *def, cr_motion **out,
                            cr_motion_prepare_report *rep, cr_error *err) {
    CR_ASSERT(def && def->cookie == RESOLVE_DEF_COOKIE);
    *out = NULL;
    if (!spec || !*spec) return CR_FAIL(err, CR_ERR_INVALID, "motion: no clip name or file given");
    if (cr_motion_is_clip(spec)) {
        float fps = def->fps > 0.0f ? def->fps : 30.0f;
        int32_t n = def->clip_frames > 0 ? def->clip_frames : 120;
        CR_TRY(cr_motion_clip(spec, n, fps, out, err));
        if (rep) {
            memset(rep, 0, sizeof *rep);
            rep->source_fps = fps, rep->source_frames = (*out)->nframes;
            rep->last_frame = (*out)->nframes - 1;
        }
        return CR_OK;
    }
    if (!strchr(spec, '.') && !strchr(spec, '/')) {
        int n = 0;
        const char *const *names = cr_motion_clip_names(&n);
        char list[512] = "";
        for (int i = 0; i < n; i++)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", i ? ", " : "",
                     names[i]);
        return CR_FAIL(err, CR_ERR_INVALID,
                       "motion '%s': neither a clip (%s) nor a motion file (.bvh, .npz, .glb)",
                       spec, list);
    }
    cr_motion_prepare_def pd = def->prepare;
    pd.fps = def->fps;
    cr_motion *raw = NULL;
    CR_TRY(cr_motion_import(spec, &def->import, &raw, err));
    cr_status st = cr_motion_prepare(raw, &pd, def->body, out, rep, err);
    cr_motion_destroy(raw);
    if (st == CR_OK && def->max_frames > 0 && (*out)->nframes > def->max_frames)
        (*out)->nframes = def->max_frames;
    return st;
}
