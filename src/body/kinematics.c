/* kinematics.c: axis-angle rotations and forward kinematics over SMPL's
 * 22-joint tree.
 *
 * Rodrigues' formula R = I + (sin t / t) K + ((1 - cos t) / t^2) K^2 with
 * K = [aa]x and t = |aa|, evaluated in double with Taylor series below
 * t = 1e-4 so small angles lose nothing and zero is exactly the identity.
 * The chain G_j = G_parent [R_j | J_j - J_parent] is accumulated in double
 * (Loper et al. 2015, SMPL, eq. 4). Parents precede children in SMPL's
 * joint order, so one pass in index order suffices.
 *
 * Left out: pose-dependent corrective shapes (SMPL's pose blend shapes) and
 * derivatives with respect to the pose.
 */
#include "crease/body.h"

#include <math.h>
#include <string.h>

/* Below this angle (rad) the series' next terms are under double precision. */
#define SMALL_ANGLE 1e-4

static void rodrigues_d(const float aa[3], double R[9]) {
    double x = aa[0], y = aa[1], z = aa[2];
    double t2 = x * x + y * y + z * z, a, b;
    if (t2 < SMALL_ANGLE * SMALL_ANGLE) {
        a = 1.0 - t2 / 6.0;
        b = 0.5 - t2 / 24.0;
    } else {
        double t = sqrt(t2);
        a = sin(t) / t;
        b = (1.0 - cos(t)) / t2;
    }
    /* K^2 = aa aa^T - t^2 I */
    R[0] = 1.0 + b * (x * x - t2), R[1] = -a * z + b * x * y, R[2] = a * y + b * x * z;
    R[3] = a * z + b * x * y, R[4] = 1.0 + b * (y * y - t2), R[5] = -a * x + b * y * z;
    R[6] = -a * y + b * x * z, R[7] = a * x + b * y * z, R[8] = 1.0 + b * (z * z - t2);
}

void cr_body_rodrigues(const float aa[3], float R[9]) {
    double Rd[9];
    rodrigues_d(aa, Rd);
    for (int i = 0; i < 9; i++)
        R[i] = (float)Rd[i];
}

/* World rotations (22,3,3) and positions (22,3) in double. */
static void fk_d(const float *joints, const float *pose, const float *trans, double *rot,
                 double *pos) {
    for (int j = 0; j < CR_NJOINTS; j++) {
        double Rl[9];
        rodrigues_d(&pose[3 * j], Rl);
        int p = cr_joint_parent[j];
        CR_ASSERT(p < j);
        if (p < 0) {
            memcpy(&rot[9 * j], Rl, sizeof Rl);
            for (int d = 0; d < 3; d++)
                pos[3 * j + d] = (double)joints[d] + (trans ? trans[d] : 0.0);
            continue;
        }
        const double *Rp = &rot[9 * p];
        double off[3];
        for (int d = 0; d < 3; d++)
            off[d] = (double)joints[3 * j + d] - (double)joints[3 * p + d];
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++)
                rot[9 * j + 3 * r + c] =
                    Rp[3 * r] * Rl[c] + Rp[3 * r + 1] * Rl[3 + c] + Rp[3 * r + 2] * Rl[6 + c];
            pos[3 * j + r] = pos[3 * p + r] + Rp[3 * r] * off[0] + Rp[3 * r + 1] * off[1] +
                             Rp[3 * r + 2] * off[2];
        }
    }
}

void cr_body_forward_kinematics(const float *joints, const float *pose, const float *trans,
                                float *rot, float *pos) {
    double R[CR_NJOINTS * 9], P[CR_NJOINTS * 3];
    fk_d(joints, pose, trans, R, P);
    if (rot)
        for (int i = 0; i < CR_NJOINTS * 9; i++)
            rot[i] = (float)R[i];
    if (pos)
        for (int i = 0; i < CR_NJOINTS * 3; i++)
            pos[i] = (float)P[i];
}

void cr_body_skin_transforms(const float *joints, const float *pose, const float *trans,
                             float *xf) {
    double R[CR_NJOINTS * 9], P[CR_NJOINTS * 3];
    fk_d(joints, pose, trans, R, P);
    for (int j = 0; j < CR_NJOINTS; j++)
        for (int r = 0; r < 3; r++) {
            const double *Rr = &R[9 * j + 3 * r];
            double b = P[3 * j + r] - (Rr[0] * joints[3 * j] + Rr[1] * joints[3 * j + 1] +
                                       Rr[2] * joints[3 * j + 2]);
            for (int c = 0; c < 3; c++)
                xf[12 * j + 4 * r + c] = (float)Rr[c];
            xf[12 * j + 4 * r + 3] = (float)b;
        }
}
