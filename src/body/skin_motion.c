/* skin_motion.c: motions of any skeleton (cr_skin_motion, crease/motion.h):
 * the container, and the preparation a garment fitted at rest needs (an
 * ease-in from the rest pose, the simulation's frame rate).
 *
 * Leaves out what cr_motion_prepare does for the mannequin beyond that
 * (calibration frames, grounding on the body, the angular-speed check): a
 * character's feet are not known by name here.
 */
#include "body/motion_internal.h"

#include <stdlib.h>
#include <string.h>

cr_status cr_skin_motion_create(int32_t njoints, int32_t nframes, float fps, cr_skin_motion **out,
                                cr_error *err) {
    *out = NULL;
    if (njoints < 1 || nframes < 1 || !(fps > 0.0f) || !isfinite(fps))
        return CR_FAIL(err, CR_ERR_INVALID, "skin motion: %d joints, %d frames at %g fps", njoints,
                       nframes, (double)fps);
    cr_skin_motion *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->njoints = njoints, m->nframes = nframes, m->fps = fps;
    m->rotation = cr_calloc((size_t)nframes * (size_t)njoints * 4, sizeof(float), err);
    m->translation = cr_calloc((size_t)nframes * 3, sizeof(float), err);
    if (!m->rotation || !m->translation) {
        cr_skin_motion_destroy(m);
        return CR_ERR_MEMORY;
    }
    for (size_t i = 0; i < (size_t)nframes * (size_t)njoints; i++)
        m->rotation[4 * i + 3] = 1.0f;
    *out = m;
    return CR_OK;
}

void cr_skin_motion_destroy(cr_skin_motion *m) {
    if (!m) return;
    free(m->rotation);
    free(m->translation);
    free(m);
}

cr_glb_skin_motion cr_skin_motion_view(const cr_skin_motion *m) {
    return (cr_glb_skin_motion){m->nframes, m->fps, m->rotation, m->translation};
}

/* Slerp of unit quaternions in x, y, z, w order: (1 - u) a + u b on the sphere. */
static void slerp(const float *a, const float *b, double u, float *out) {
    double d = 0.0, bb[4];
    for (int k = 0; k < 4; k++)
        d += (double)a[k] * b[k];
    for (int k = 0; k < 4; k++)
        bb[k] = d < 0 ? -b[k] : b[k];
    d = fabs(d);
    double wa = 1.0 - u, wb = u;
    if (d < 0.9995) {
        double th = acos(d), sn = sin(th);
        wa = sin((1.0 - u) * th) / sn, wb = sin(u * th) / sn;
    }
    double q[4], n = 0.0;
    for (int k = 0; k < 4; k++)
        q[k] = wa * a[k] + wb * bb[k], n += q[k] * q[k];
    n = sqrt(n);
    for (int k = 0; k < 4; k++)
        out[k] = (float)(q[k] / n);
}

/* Frame i of out: the rest eased into m's frame 0 over `ease` frames, then m
 * at time (i - ease) / fps. */
static void prepare_frame(const cr_skin_motion *m, float fps, int32_t ease, int32_t i, float *rot,
                          float *tr) {
    const int32_t J = m->njoints;
    if (i < ease) { /* the mannequin's ease-in (motion_internal.h), in x, y, z, w order */
        const double u = (double)i / ease, span = ease / (double)fps; /* s */
        const int has_next = m->nframes > 1;
        for (int32_t j = 0; j < J; j++) {
            const float *a = m->rotation + 4 * (size_t)j, *b = a + 4 * (size_t)J;
            double q0[4] = {a[3], a[0], a[1], a[2]}, q1[4] = {0}, vel[3], q[4];
            if (has_next) q1[0] = b[3], q1[1] = b[0], q1[2] = b[1], q1[3] = b[2];
            motion_ease_velocity(q0, has_next ? q1 : NULL, m->fps * span, vel);
            motion_ease_rotation(q0, vel, u, q);
            float *o = rot + 4 * (size_t)j;
            o[0] = (float)q[1], o[1] = (float)q[2], o[2] = (float)q[3], o[3] = (float)q[0];
        }
        for (int k = 0; k < 3; k++) {
            const double x0 = m->translation[k];
            const double v = has_next ? (m->translation[3 + k] - x0) * m->fps * span : 0.0;
            tr[k] = (float)motion_ease_value(x0, v, u);
        }
        return;
    }
    const double s = (double)(i - ease) * m->fps / fps;
    int32_t f0 = (int32_t)floor(s);
    if (f0 > m->nframes - 1) f0 = m->nframes - 1;
    const int32_t f1 = f0 + 1 < m->nframes ? f0 + 1 : f0;
    const double u = f1 > f0 ? s - f0 : 0.0;
    for (int32_t j = 0; j < J; j++)
        slerp(m->rotation + 4 * ((size_t)f0 * (size_t)J + (size_t)j),
              m->rotation + 4 * ((size_t)f1 * (size_t)J + (size_t)j), u, rot + 4 * (size_t)j);
    for (int k = 0; k < 3; k++)
        tr[k] = (float)((1.0 - u) * m->translation[3 * (size_t)f0 + (size_t)k] +
                        u * m->translation[3 * (size_t)f1 + (size_t)k]);
}

/* Largest joint turn between frames f and f + 1, rad. */
static double skin_frame_step(const cr_skin_motion *m, int32_t f) {
    double best = 0;
    for (int32_t j = 0; j < m->njoints; j++) {
        const float *a = m->rotation + 4 * ((size_t)f * m->njoints + j);
        const float *b = a + 4 * (size_t)m->njoints;
        double d = fabs((double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2] +
                        (double)a[3] * b[3]);
        best = fmax(best, 2.0 * acos(fmin(d, 1.0)));
    }
    return best;
}

int cr_skin_motion_is_calibration_start(const cr_skin_motion *m, float *jump) {
    if (jump) *jump = 0.0f;
    if (m->nframes < 4) return 0;
    double j0 = skin_frame_step(m, 0), next = fmax(skin_frame_step(m, 1), skin_frame_step(m, 2));
    if (jump) *jump = (float)j0;
    return motion_calibration_rule(j0, next);
}

cr_status cr_skin_motion_prepare(const cr_skin_motion *m, float fps, float ease_in_s,
                                 cr_skin_motion **out, cr_error *err) {
    *out = NULL;
    if (fps == 0.0f) fps = m->fps;
    if (!(fps > 0.0f && fps <= 1000.0f) || !(ease_in_s >= 0.0f && ease_in_s <= 60.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "skin motion: rate %g fps, ease-in %g s", (double)fps,
                       (double)ease_in_s);
    const int32_t ease = (int32_t)lround((double)ease_in_s * fps);
    const double played = floor((double)(m->nframes - 1) * fps / m->fps + 1e-6) + 1.0;
    if (played + ease > 1e7)
        return CR_FAIL(err, CR_ERR_RANGE, "skin motion: %.0f frames at %g fps", played + ease,
                       (double)fps);
    const int32_t T = ease + (int32_t)played;
    CR_TRY(cr_skin_motion_create(m->njoints, T, fps, out, err));
    for (int32_t i = 0; i < T; i++)
        prepare_frame(m, fps, ease, i, (*out)->rotation + 4 * (size_t)i * (size_t)m->njoints,
                      (*out)->translation + 3 * (size_t)i);
    return CR_OK;
}
