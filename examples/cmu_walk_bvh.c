/* cmu_walk_bvh.c: write a walk as the CMU motion-capture database's BVH
 * conversion (cgspeed) lays it out, to try crease's motion path on without
 * downloading a capture: the cgspeed skeleton (Hips, LHipJoint/RHipJoint,
 * LowerBack, Spine, Spine1, Neck, Neck1, Head, LeftShoulder, LeftArm, ...),
 * its offsets in the ASF's unit (about 0.0564 m), legs splayed 20 degrees
 * and arms horizontal in the rest pose, Z Y X rotation channels, 120 fps,
 * and a T-pose calibration frame 0 before the walk.
 *
 *   example_cmu_walk_bvh [out.bvh] [seconds]
 *   crease pose-body --motion out.bvh --fps 30 -o walk.pc2
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct joint {
    const char *name; /* NULL: an End Site */
    int parent;
    double off[3];
} joint;

/* cgspeed's skeleton for subject 01 (offsets as in 01_01.bvh, rounded). */
static const joint rig[] = {
    {"Hips", -1, {0, 0, 0}},
    {"LHipJoint", 0, {0, 0, 0}},
    {"LeftUpLeg", 1, {1.363, -1.795, 0.839}},
    {"LeftLeg", 2, {2.448, -6.726, 0}},
    {"LeftFoot", 3, {2.562, -7.040, 0}},
    {"LeftToeBase", 4, {0.158, -0.433, 2.323}},
    {NULL, 5, {0, 0, 1.190}},
    {"RHipJoint", 0, {0, 0, 0}},
    {"RightUpLeg", 7, {-1.306, -1.795, 0.839}},
    {"RightLeg", 8, {-2.543, -6.986, 0}},
    {"RightFoot", 9, {-2.568, -7.056, 0}},
    {"RightToeBase", 10, {-0.165, -0.453, 2.363}},
    {NULL, 11, {0, 0, 1.211}},
    {"LowerBack", 0, {0, 0, 0}},
    {"Spine", 13, {0.028, 2.036, -0.193}},
    {"Spine1", 14, {0.057, 2.049, -0.043}},
    {"Neck", 15, {0, 0, 0}},
    {"Neck1", 16, {-0.054, 1.746, 0.172}},
    {"Head", 17, {0.104, 1.761, -0.124}},
    {NULL, 18, {0, 0, 0}},
    {"LeftShoulder", 15, {0, 0, 0}},
    {"LeftArm", 20, {3.362, 1.201, -0.311}},
    {"LeftForeArm", 21, {4.983, 0, 0}},
    {"LeftHand", 22, {3.484, 0, 0}},
    {NULL, 23, {0.7, 0, 0}},
    {"RightShoulder", 15, {0, 0, 0}},
    {"RightArm", 25, {-3.137, 1.374, -0.405}},
    {"RightForeArm", 26, {-5.242, 0, 0}},
    {"RightHand", 27, {-3.444, 0, 0}},
    {NULL, 28, {-0.7, 0, 0}},
};
enum { N = sizeof rig / sizeof rig[0] };

typedef struct m3 {
    double m[3][3];
} m3;

static m3 mul(m3 a, m3 b) {
    m3 r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
    return r;
}

static m3 axis(int a, double rad) {
    m3 r = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    int i = (a + 1) % 3, j = (a + 2) % 3;
    r.m[i][i] = cos(rad), r.m[i][j] = -sin(rad);
    r.m[j][i] = sin(rad), r.m[j][j] = cos(rad);
    return r;
}

/* Local rotation of joint i at time t (s) of the walk: legs brought in from
 * the 20-degree splay and swinging, knees bending in the swing, arms down
 * and swinging against the legs, a little sway and nod. */
static m3 local(int i, double t) {
    const double w = 2 * M_PI * t / 1.1, splay = 20 * M_PI / 180; /* a 1.1 s stride */
    int left = i < 7 || (i >= 20 && i < 25);
    double ph = left ? 0 : M_PI, side = left ? 1 : -1;
    double knee = 0.12 + 0.55 * pow(fmax(0, sin(w + ph + 1.3)), 2);
    switch (i) {
    case 0:
        return mul(axis(1, 0.06 * sin(w)), axis(0, 0.04));
    case 2:
    case 8:
        return mul(axis(2, -side * splay), axis(0, -0.42 * sin(w + ph)));
    case 3:
    case 9:
        return axis(0, knee);
    case 4:
    case 10:
        return axis(0, -0.15 * sin(w + ph + 0.4));
    case 14:
        return axis(0, 0.03 * sin(2 * w));
    case 17:
        return axis(0, 0.12);
    case 18:
        return axis(0, -0.08 + 0.03 * sin(2 * w));
    case 21:
    case 26:
        return mul(axis(0, 0.3 * sin(w + ph)), axis(2, -side * 1.25));
    case 22:
    case 27:
        return axis(1, -side * (0.35 + 0.1 * sin(w + ph)));
    default:
        return axis(0, 0);
    }
}

/* Z Y X Euler angles (degrees) of R = Rz(a) Ry(b) Rx(c). */
static void euler_zyx(m3 r, double e[3]) {
    e[1] = asin(fmax(-1.0, fmin(1.0, -r.m[2][0]))) * 180 / M_PI;
    e[0] = atan2(r.m[1][0], r.m[0][0]) * 180 / M_PI;
    e[2] = atan2(r.m[2][1], r.m[2][2]) * 180 / M_PI;
}

int main(int argc, char **argv) {
    const char *out = argc > 1 ? argv[1] : "cmu_walk.bvh";
    double seconds = argc > 2 ? atof(argv[2]) : 4.0;
    if (!(seconds > 0 && seconds < 600)) {
        fprintf(stderr, "cmu_walk_bvh: seconds %g, expected (0, 600)\n", seconds);
        return 2;
    }
    FILE *f = fopen(out, "w");
    if (!f) {
        fprintf(stderr, "cmu_walk_bvh: cannot write %s\n", out);
        return 1;
    }
    const double fps = 120, unit = 0.056444; /* m per unit */
    int frames = 1 + (int)(seconds * fps);
    int depth[N];
    fprintf(f, "HIERARCHY\n");
    for (int i = 0; i < N; i++) {
        depth[i] = rig[i].parent < 0 ? 0 : depth[rig[i].parent] + 1;
        if (i > 0)
            for (int d = depth[i - 1]; d >= depth[i]; d--)
                fprintf(f, "%*s}\n", 2 * d, "");
        int d = 2 * depth[i];
        if (rig[i].name)
            fprintf(f, "%*s%s %s\n", d, "", i ? "JOINT" : "ROOT", rig[i].name);
        else
            fprintf(f, "%*sEnd Site\n", d, "");
        fprintf(f, "%*s{\n%*s  OFFSET %.5f %.5f %.5f\n", d, "", d, "", rig[i].off[0], rig[i].off[1],
                rig[i].off[2]);
        if (i == 0)
            fprintf(f,
                    "%*s  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
                    "Xrotation\n",
                    d, "");
        else if (rig[i].name)
            fprintf(f, "%*s  CHANNELS 3 Zrotation Yrotation Xrotation\n", d, "");
    }
    for (int d = depth[N - 1]; d >= 0; d--)
        fprintf(f, "%*s}\n", 2 * d, "");
    fprintf(f, "MOTION\nFrames: %d\nFrame Time: %.6f\n", frames, 1 / fps);
    for (int k = 0; k < frames; k++) {
        double t = k ? (k - 1) / fps : 0; /* frame 0: the calibration T-pose */
        double w = 2 * M_PI * t / 1.1;
        /* hips 0.93 m up, bobbing 1.5 cm twice a stride, walking 1.2 m/s along +Z */
        fprintf(f, "%.5f %.5f %.5f", 0.02 * sin(w) / unit, (0.93 + 0.015 * cos(2 * w)) / unit,
                1.2 * t / unit);
        for (int i = 0; i < N; i++) {
            if (!rig[i].name) continue;
            double e[3] = {0, 0, 0};
            if (k) euler_zyx(local(i, t), e);
            fprintf(f, " %.4f %.4f %.4f", e[0], e[1], e[2]);
        }
        fprintf(f, "\n");
    }
    if (fclose(f) != 0) {
        fprintf(stderr, "cmu_walk_bvh: writing %s failed\n", out);
        return 1;
    }
    printf("wrote %s: %d frames at %g fps (frame 0 a T-pose)\n", out, frames, fps);
    return 0;
}
