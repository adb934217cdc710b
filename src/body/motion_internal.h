/* motion_internal.h: what the motion files share: unit quaternions in
 * double precision (w, x, y, z), and the step that brings a foreign motion
 * into crease's frame.
 *
 * Quaternions rather than matrices because poses are compared, composed and
 * turned back into axis-angle many times per frame, and q and -q are the
 * same rotation: to_aa picks w >= 0 so angles stay in [0, pi].
 */
#ifndef CREASE_BODY_MOTION_INTERNAL_H
#define CREASE_BODY_MOTION_INTERNAL_H

#include "crease/motion.h"
#include "crease/npz.h"

#include <math.h>
#include <string.h>

static inline void q_identity(double q[4]) {
    q[0] = 1, q[1] = q[2] = q[3] = 0;
}

/* out = a b (apply b, then a); out may alias a or b. */
static inline void q_mul(const double a[4], const double b[4], double out[4]) {
    double w = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    double x = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    double y = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    double z = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
    out[0] = w, out[1] = x, out[2] = y, out[3] = z;
}

static inline void q_conj(const double q[4], double out[4]) {
    out[0] = q[0], out[1] = -q[1], out[2] = -q[2], out[3] = -q[3];
}

/* Rotation by `angle` radians about the unit axis (ax, ay, az). */
static inline void q_axis(double ax, double ay, double az, double angle, double q[4]) {
    double s = sin(0.5 * angle);
    q[0] = cos(0.5 * angle), q[1] = ax * s, q[2] = ay * s, q[3] = az * s;
}

static inline void q_from_aa(const float aa[3], double q[4]) {
    double x = aa[0], y = aa[1], z = aa[2], th = sqrt(x * x + y * y + z * z);
    if (th < 1e-12) {
        q[0] = 1, q[1] = 0.5 * x, q[2] = 0.5 * y, q[3] = 0.5 * z; /* first order */
        return;
    }
    q_axis(x / th, y / th, z / th, th, q);
}

static inline void q_to_aa(const double q_in[4], float aa[3]) {
    double s = q_in[0] < 0 ? -1 : 1;
    double w = s * q_in[0], x = s * q_in[1], y = s * q_in[2], z = s * q_in[3];
    double v = sqrt(x * x + y * y + z * z);
    double k = v < 1e-12 ? 2.0 : 2.0 * atan2(v, w) / v;
    aa[0] = (float)(k * x), aa[1] = (float)(k * y), aa[2] = (float)(k * z);
}

/* The ease-in from the rest pose into a motion's first frame, one joint at
 * a time (cr_motion_ease_in for crease's motions, cr_skin_motion_prepare for
 * any skeleton's): in the tangent space at the first frame's rotation q0, a
 * quintic Hermite from log(q0^-1) (the rest) to 0 (q0) that arrives with the
 * motion's first step as velocity, so the motion goes on without a jerk.
 * motion_ease_velocity: that velocity over the ease's span (q1 the second
 * frame's rotation, NULL for none; steps_per_span the motion's frames in the
 * span). motion_ease_rotation: the joint at u in [0, 1). motion_ease_value:
 * a translation coordinate, from 0 to x0 arriving with velocity v. */
static inline void motion_ease_velocity(const double q0[4], const double *q1, double steps_per_span,
                                        double vel[3]) {
    vel[0] = vel[1] = vel[2] = 0;
    if (!q1) return;
    double q0i[4], rel[4];
    float aa[3];
    q_conj(q0, q0i);
    q_mul(q0i, q1, rel);
    q_to_aa(rel, aa);
    for (int c = 0; c < 3; c++)
        vel[c] = aa[c] * steps_per_span;
}

static inline void motion_ease_weights(double u, double *h0, double *hv) {
    double u3 = u * u * u;
    *h0 = 1.0 - 10.0 * u3 + 15.0 * u3 * u - 6.0 * u3 * u * u;
    *hv = -4.0 * u3 + 7.0 * u3 * u - 3.0 * u3 * u * u;
}

static inline void motion_ease_rotation(const double q0[4], const double vel[3], double u,
                                        double out[4]) {
    double q0i[4], h0, hv, e[4];
    float start[3], p[3];
    q_conj(q0, q0i);
    q_to_aa(q0i, start);
    motion_ease_weights(u, &h0, &hv);
    for (int c = 0; c < 3; c++)
        p[c] = (float)(h0 * start[c] + hv * vel[c]);
    q_from_aa(p, e);
    q_mul(q0, e, out);
}

static inline double motion_ease_value(double x0, double v, double u) {
    double h0, hv;
    motion_ease_weights(u, &h0, &hv);
    return (1.0 - h0) * x0 + hv * v;
}

/* A calibration frame 0 (a T-pose before the capture): the largest joint
 * turn from frame 0 into frame 1, j0 rad, over 0.35 rad and over 5 times
 * the largest turn of the next frames' steps. One rule for crease's motions
 * (cr_motion_is_calibration_start) and any skeleton's
 * (cr_skin_motion_is_calibration_start). */
static inline int motion_calibration_rule(double j0, double next) {
    return j0 > 0.35 && j0 > 5.0 * fmax(next, 1e-3);
}

/* World rotations g (T,22,4) and translations t (T,3) into m's poses (local
 * = G_parent^-1 G, as axis-angles) and trans. */
static inline void motion_from_world(const double *g, const double *t, cr_motion *m) {
    for (size_t f = 0; f < (size_t)m->nframes; f++) {
        const double *gf = g + f * CR_NJOINTS * 4;
        for (int j = 0; j < CR_NJOINTS; j++) {
            double q[4];
            memcpy(q, gf + 4 * j, sizeof q);
            if (cr_joint_parent[j] >= 0) {
                double inv[4];
                q_conj(gf + 4 * cr_joint_parent[j], inv);
                q_mul(inv, q, q);
            }
            q_to_aa(q, m->poses + (f * CR_NJOINTS + (size_t)j) * 3);
        }
        for (int k = 0; k < 3; k++)
            m->trans[3 * f + (size_t)k] = (float)t[3 * f + (size_t)k];
    }
}

/* Angle of the rotation q, radians in [0, pi]. */
static inline double q_angle(const double q[4]) {
    double v = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    return 2.0 * atan2(v, fabs(q[0]));
}

/* out = q v q* (out may alias v). */
static inline void q_rotate(const double q[4], const double v[3], double out[3]) {
    double tx = 2 * (q[2] * v[2] - q[3] * v[1]);
    double ty = 2 * (q[3] * v[0] - q[1] * v[2]);
    double tz = 2 * (q[1] * v[1] - q[2] * v[0]);
    double x = v[0] + q[0] * tx + (q[2] * tz - q[3] * ty);
    double y = v[1] + q[0] * ty + (q[3] * tx - q[1] * tz);
    double z = v[2] + q[0] * tz + (q[1] * ty - q[2] * tx);
    out[0] = x, out[1] = y, out[2] = z;
}

/* A foreign motion's world frame turned into crease's. `world` rotates the
 * source world into crease's (Z-up to Y-up, say). With `conjugate` the
 * whole rig lives in the source frame, so every local rotation R becomes
 * world R world^-1 (BVH); without it only the root is turned (AMASS, whose
 * body rest is already Y-up while its world is Z-up). The turned
 * translation less `origin` (the rig's rest root position) is the root's
 * displacement from rest. With `recenter` the motion is then turned about
 * +Y so frame 0 faces +Z and shifted so frame 0's root is at x = z = 0, and
 * with `recenter_height` also at height 0 (for AMASS, where the rest root
 * height is unknown: frame 0 is taken to stand at rest height). */
typedef struct motion_frame_fix {
    double world[4];
    int conjugate;
    double origin[3]; /* m */
    int recenter;
    int recenter_height;
} motion_frame_fix;

cr_status cr_motion_fix_frame(cr_motion *m, const motion_frame_fix *fix, cr_error *err);

/* The motion in an open .npz (AMASS or crease's own). */
cr_status cr_motion_from_npz(const cr_npz *z, const char *source, const cr_motion_import_def *def,
                             cr_motion **out, cr_error *err);

#define MOTION_IMPORT_COOKIE 0x6d6f7431u

/* ---------------------------------------------- bodies from other files -- */

/* The four largest of a vertex's weights over J joints (w, >= 0 up to float
 * noise) merged into SMPL's 22 roles by merged (J), renormalised into idx,
 * wt (4); fails naming source and vertex v on a negative weight or none.
 * smpl_model.c's SMPL files and body_character.c's characters. */
cr_status cr_body_top_weights_(const float *w, int64_t J, const int *merged, int64_t v,
                               const char *source, int32_t *idx, float *wt, cr_error *err);
/* The shift standing a body on the ground as crease's bodies stand: its
 * lowest vertex (pos, (V,3)) on y = 0, its pelvis over x = z = 0. */
void cr_body_stand_shift_(const double *pos, int64_t V, const double pelvis[3], double shift[3]);

/* A file spec with an optional tail after a colon, "FILE.ext" or "FILE.ext:TAIL" (a
 * character's joint map, a body model's betas): 1 with path (cap bytes) and *tail (NULL or
 * what follows the colon, inside spec) when spec names a ".ext" file (ext with its dot), 0
 * otherwise (spec may be NULL); -1 when the path does not fit. */
int cr_spec_split(const char *spec, const char *ext, char *path, size_t cap, const char **tail);

#endif
