/* test_motion.c: procedural clips (rest start, ease-in, joint limits,
 * smoothness, which way limbs move, checked with an independent
 * matrix-based FK of bone directions), BVH loading (Euler orders, folded
 * joints, cm, Z-up rigs, Mixamo and CMU names, recentering) against hand
 * computed rotations, AMASS-style and crease .npz motions, SMPL-style body
 * models, rebasing, and malformed inputs refused with file and line. */
#include "crease/mesh.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* --------------------------------------------------- rotation matrices -- */

typedef struct mat3 {
    double m[3][3];
} mat3;

static mat3 mat_identity(void) {
    mat3 r = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    return r;
}

/* Rodrigues' formula. */
static mat3 mat_aa(const float aa[3]) {
    double th = sqrt((double)aa[0] * aa[0] + (double)aa[1] * aa[1] + (double)aa[2] * aa[2]);
    if (th < 1e-12) return mat_identity();
    double k[3] = {aa[0] / th, aa[1] / th, aa[2] / th}, c = cos(th), s = sin(th);
    mat3 r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = (1 - c) * k[i] * k[j] + (i == j ? c : 0);
    r.m[0][1] -= s * k[2], r.m[1][0] += s * k[2];
    r.m[0][2] += s * k[1], r.m[2][0] -= s * k[1];
    r.m[1][2] -= s * k[0], r.m[2][1] += s * k[0];
    return r;
}

static mat3 mat_axis(int axis, double deg) {
    float aa[3] = {0, 0, 0};
    aa[axis] = (float)(deg * M_PI / 180.0);
    return mat_aa(aa);
}

static mat3 mat_mul(mat3 a, mat3 b) {
    mat3 r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
    return r;
}

static double mat_diff(mat3 a, mat3 b) {
    double d = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            d = fmax(d, fabs(a.m[i][j] - b.m[i][j]));
    return d;
}

/* World rotations of all joints of frame f: W_j = W_parent R_j. */
static void world_rotations(const cr_motion *m, int f, mat3 w[CR_NJOINTS]) {
    for (int j = 0; j < CR_NJOINTS; j++) {
        mat3 r = mat_aa(m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3);
        w[j] = cr_joint_parent[j] < 0 ? r : mat_mul(w[cr_joint_parent[j]], r);
    }
}

/* Direction of a bone: joint j's world rotation applied to its rest direction d. */
static void bone_dir(const cr_motion *m, int f, int j, double dx, double dy, double dz,
                     double out[3]) {
    mat3 w[CR_NJOINTS];
    world_rotations(m, f, w);
    double d[3] = {dx, dy, dz}, n = sqrt(dx * dx + dy * dy + dz * dz);
    for (int i = 0; i < 3; i++)
        out[i] = (w[j].m[i][0] * d[0] + w[j].m[i][1] * d[1] + w[j].m[i][2] * d[2]) / n;
}

static const float *pose_at(const cr_motion *m, int f, int j) {
    return m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3;
}

/* ------------------------------------------------------ procedural clips -- */

/* Plausible human ranges per joint, rad (the A-pose rest counts as zero). */
static const float angle_limit[CR_NJOINTS] = {1.0f, 1.8f, 1.8f, 0.7f, 2.2f, 2.2f, 0.7f, 0.7f,
                                              0.7f, 0.7f, 0.5f, 0.5f, 0.6f, 0.5f, 0.5f, 0.6f,
                                              2.4f, 2.4f, 2.3f, 2.3f, 1.0f, 1.0f};

CR_TEST(motion, clips_start_at_rest_and_stay_smooth_and_human) {
    cr_error err = {0};
    int n = 0;
    const char *const *names = cr_motion_clip_names(&n);
    CR_CHECK(n == 13 && names[13] == NULL);
    const double elbow_axis[2][3] = {{-M_SQRT1_2, -M_SQRT1_2, 0}, {-M_SQRT1_2, M_SQRT1_2, 0}};
    for (int c = 0; c < n; c++) {
        cr_motion *m = NULL;
        CR_CHECK_OK(cr_motion_clip(names[c], 150, 30.0f, &m, &err), &err);
        CR_REQUIRE(m && m->nframes == 150 && m->fps == 30.0f);
        CR_CHECK(cr_motion_clip_summary(names[c]) != NULL);
        CR_CHECK_OK(cr_motion_validate(m, names[c], &err), &err);
        for (int k = 0; k < CR_NJOINTS * 3; k++)
            CR_CHECK(m->poses[k] == 0.0f);
        CR_CHECK(m->trans[0] == 0.0f && m->trans[1] == 0.0f && m->trans[2] == 0.0f);
        double first = 0, biggest = 0, vel = 0, acc = 0, tvel = 0, tacc = 0;
        int bad_limit = -1, bad_sign = -1;
        for (int f = 0; f < m->nframes; f++)
            for (int j = 0; j < CR_NJOINTS; j++) {
                const float *p = pose_at(m, f, j);
                double a = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                biggest = fmax(biggest, a);
                if (a > angle_limit[j]) bad_limit = j;
                if ((j == CR_JOINT_LEFT_KNEE || j == CR_JOINT_RIGHT_KNEE) && p[0] < -0.02f)
                    bad_sign = j; /* knees only flex */
                if (j == CR_JOINT_LEFT_ELBOW || j == CR_JOINT_RIGHT_ELBOW) {
                    const double *ax = elbow_axis[j - CR_JOINT_LEFT_ELBOW];
                    if (p[0] * ax[0] + p[1] * ax[1] + p[2] * ax[2] < -0.02) bad_sign = j;
                }
                for (int k = 0; k < 3 && f >= 1; k++) {
                    double d1 = p[k] - pose_at(m, f - 1, j)[k];
                    if (f == 1) first = fmax(first, fabs(d1));
                    vel = fmax(vel, fabs(d1));
                    if (f >= 2)
                        acc = fmax(acc,
                                   fabs(d1 - (pose_at(m, f - 1, j)[k] - pose_at(m, f - 2, j)[k])));
                }
            }
        for (int f = 2; f < m->nframes; f++)
            for (int k = 0; k < 3; k++) {
                const float *t = m->trans + (size_t)f * 3 + k;
                tvel = fmax(tvel, fabs(t[0] - t[-3]));
                tacc = fmax(tacc, fabs(t[0] - 2 * t[-3] + t[-6]));
            }
        if (bad_limit >= 0 || bad_sign >= 0 || first > 0.01 || vel > 0.4 || acc > 0.15 ||
            tvel > 0.2 || tacc > 0.03 || biggest < 0.3)
            printf("    clip %s: limit %d sign %d first %.4f vel %.3f acc %.3f tvel %.3f tacc "
                   "%.4f biggest %.2f\n",
                   names[c], bad_limit, bad_sign, first, vel, acc, tvel, tacc, biggest);
        CR_CHECK(bad_limit < 0 && bad_sign < 0);
        CR_CHECK(first < 0.01);              /* eases in: frame 1 barely moves */
        CR_CHECK(vel < 0.4 && acc < 0.15);   /* rad per frame, per frame^2 at 30 fps */
        CR_CHECK(tvel < 0.2 && tacc < 0.03); /* m per frame, per frame^2: under 3 g */
        CR_CHECK(biggest > 0.3);             /* and it does move */
        CR_CHECK(cr_motion_max_angular_speed(m, NULL) < 12.0f);
        cr_motion_destroy(m);
    }
    cr_motion *m = NULL;
    CR_CHECK(cr_motion_clip("moonwalk", 10, 30, &m, &err) == CR_ERR_INVALID && !m);
    CR_CHECK(strstr(err.msg, "moonwalk") && strstr(err.msg, "raise_arms"));
    CR_CHECK(cr_motion_clip("walk", 0, 30, &m, &err) == CR_ERR_INVALID);
}

CR_TEST(motion, clips_move_limbs_the_right_way) {
    cr_error err = {0};
    cr_motion *m = NULL;
    double d[3], e[3];
    /* walk: at t = 1.375 s the left thigh is forward, the right one back; 1.27 m/s. */
    CR_CHECK_OK(cr_motion_clip("walk", 150, 30, &m, &err), &err);
    CR_REQUIRE(m);
    bone_dir(m, 41, CR_JOINT_LEFT_HIP, 0, -1, 0, d);
    bone_dir(m, 41, CR_JOINT_RIGHT_HIP, 0, -1, 0, e);
    CR_CHECK(d[2] > 0.3 && e[2] < -0.2);
    CR_CHECK_NEAR(m->trans[149 * 3 + 2], 1.27 * (149 / 30.0 - 0.25), 0.01);
    cr_motion_destroy(m);
    /* Twice the tempo covers twice the ground; zero amplitude stays at rest. */
    cr_motion_clip_def def = cr_motion_clip_default_def();
    def.nframes = 150;
    def.speed = 2;
    CR_CHECK_OK(cr_motion_clip_make(&def, &m, &err), &err);
    CR_CHECK_NEAR(m->trans[149 * 3 + 2], 2 * 1.27 * (149 / 30.0 - 0.25), 0.01);
    cr_motion_destroy(m);
    def.speed = 1, def.amplitude = 0;
    CR_CHECK_OK(cr_motion_clip_make(&def, &m, &err), &err);
    CR_CHECK(cr_motion_max_angular_speed(m, NULL) == 0 && m->trans[149 * 3 + 2] == 0);
    cr_motion_destroy(m);
    def.amplitude = 1, def.speed = 9;
    CR_CHECK(cr_motion_clip_make(&def, &m, &err) == CR_ERR_INVALID && strstr(err.msg, "speed"));
    /* raise_arms at 2 s: both arms (A-pose directions) point nearly straight up. */
    CR_CHECK_OK(cr_motion_clip("raise_arms", 61, 30, &m, &err), &err);
    bone_dir(m, 60, CR_JOINT_LEFT_SHOULDER, 1, -1, 0, d);
    bone_dir(m, 60, CR_JOINT_RIGHT_SHOULDER, -1, -1, 0, e);
    CR_CHECK(d[1] > 0.85 && e[1] > 0.85 && d[0] > 0 && e[0] < 0);
    cr_motion_destroy(m);
    /* squat at 1.75 s: thighs forward and near horizontal, shins leaning, pelvis 0.44 m down. */
    CR_CHECK_OK(cr_motion_clip("squat", 54, 30, &m, &err), &err);
    bone_dir(m, 53, CR_JOINT_LEFT_HIP, 0, -1, 0, d);
    bone_dir(m, 53, CR_JOINT_LEFT_KNEE, 0, -1, 0, e);
    CR_CHECK(d[2] > 0.8 && fabs(d[1]) < 0.35 && e[1] < -0.8 && e[2] < -0.2);
    CR_CHECK_NEAR(m->trans[53 * 3 + 1], -0.44, 0.01);
    cr_motion_destroy(m);
    /* bend at 2 s: the chest points forward, the thighs stay vertical. */
    CR_CHECK_OK(cr_motion_clip("bend", 61, 30, &m, &err), &err);
    bone_dir(m, 60, CR_JOINT_SPINE3, 0, 1, 0, d);
    bone_dir(m, 60, CR_JOINT_LEFT_HIP, 0, -1, 0, e);
    CR_CHECK(d[2] > 0.9 && e[1] < -0.99);
    cr_motion_destroy(m);
    /* reach at 0.5 s: the left arm overhead, the right one down; at 1.5 s the right arm up. */
    CR_CHECK_OK(cr_motion_clip("reach", 46, 30, &m, &err), &err);
    bone_dir(m, 15, CR_JOINT_LEFT_SHOULDER, 1, -1, 0, d);
    bone_dir(m, 15, CR_JOINT_RIGHT_SHOULDER, -1, -1, 0, e);
    CR_CHECK(d[1] > 0.85 && e[1] < -0.5);
    bone_dir(m, 45, CR_JOINT_RIGHT_SHOULDER, -1, -1, 0, e);
    CR_CHECK(e[1] > 0.9);
    cr_motion_destroy(m);
    /* lean at 0.6 s: the chest tipped forward about 1.25 rad, the thighs vertical;
     * at 1.8 s (the second lean) the chest leans to the body's left (+X). */
    CR_CHECK_OK(cr_motion_clip("lean", 55, 30, &m, &err), &err);
    bone_dir(m, 18, CR_JOINT_SPINE3, 0, 1, 0, d);
    bone_dir(m, 18, CR_JOINT_LEFT_HIP, 0, -1, 0, e);
    CR_CHECK(d[2] > 0.9 && e[1] < -0.99);
    bone_dir(m, 54, CR_JOINT_SPINE3, 0, 1, 0, d);
    CR_CHECK(d[0] > 0.3 && fabs(d[2]) < 0.1);
    cr_motion_destroy(m);
    /* stretch at 1.2 s: both arms up and forward, the chest bent to the left. */
    CR_CHECK_OK(cr_motion_clip("stretch", 37, 30, &m, &err), &err);
    bone_dir(m, 36, CR_JOINT_LEFT_SHOULDER, 1, -1, 0, d);
    bone_dir(m, 36, CR_JOINT_RIGHT_SHOULDER, -1, -1, 0, e);
    CR_CHECK(d[1] > 0.6 && e[1] > 0.6 && d[2] > 0.2 && e[2] > 0.2);
    bone_dir(m, 36, CR_JOINT_SPINE3, 0, 1, 0, d);
    CR_CHECK(d[0] > 0.2);
    cr_motion_destroy(m);
    /* run: forearms come forward; jump: 0.25 m of flight; stairs climb. */
    CR_CHECK_OK(cr_motion_clip("run", 60, 30, &m, &err), &err);
    bone_dir(m, 45, CR_JOINT_LEFT_ELBOW, 1, -1, 0, d);
    CR_CHECK(d[2] > 0.6);
    cr_motion_destroy(m);
    CR_CHECK_OK(cr_motion_clip("jump", 90, 30, &m, &err), &err);
    double hi = -1, lo = 1;
    for (int f = 0; f < 90; f++)
        hi = fmax(hi, m->trans[f * 3 + 1]), lo = fmin(lo, m->trans[f * 3 + 1]);
    CR_CHECK(hi > 0.2 && hi < 0.3 && lo < -0.2 && lo > -0.35);
    cr_motion_destroy(m);
    CR_CHECK_OK(cr_motion_clip("stairs", 150, 30, &m, &err), &err);
    CR_CHECK_NEAR(m->trans[149 * 3 + 1], 0.34 / 1.4 * (149 / 30.0 - 0.25), 0.01);
    cr_motion_destroy(m);
}

CR_TEST(motion, angular_speed_rebase_and_validate) {
    cr_error err = {0};
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_create(3, 30, &m, &err), &err);
    CR_REQUIRE(m);
    m->poses[(1 * CR_NJOINTS + CR_JOINT_LEFT_ELBOW) * 3] = 0.1f;
    m->poses[(2 * CR_NJOINTS + CR_JOINT_LEFT_ELBOW) * 3] = 0.3f;
    int j = -1;
    CR_CHECK_NEAR(cr_motion_max_angular_speed(m, &j), 6.0, 1e-4);
    CR_CHECK(j == CR_JOINT_LEFT_ELBOW);
    /* Rebase: with G the new rest's world rotations, W'_j G_j must equal W_j. */
    cr_rng rng = cr_rng_make(7, 0);
    for (int k = 0; k < 3 * CR_NJOINTS * 3; k++)
        m->poses[k] = (float)(cr_rng_uniform(&rng) - 0.5);
    float rest[CR_NJOINTS * 3];
    for (int k = 0; k < CR_NJOINTS * 3; k++)
        rest[k] = (float)(0.8 * (cr_rng_uniform(&rng) - 0.5));
    cr_motion *r = NULL;
    CR_CHECK_OK(cr_motion_create(3, 30, &r, &err), &err);
    memcpy(r->poses, m->poses, 3 * CR_NJOINTS * 3 * sizeof(float));
    cr_motion_rebase(r, rest);
    mat3 g[CR_NJOINTS];
    for (int k = 0; k < CR_NJOINTS; k++) {
        mat3 q = mat_aa(rest + 3 * k);
        g[k] = cr_joint_parent[k] < 0 ? q : mat_mul(g[cr_joint_parent[k]], q);
    }
    double worst = 0;
    for (int f = 0; f < 3; f++) {
        mat3 w[CR_NJOINTS], w2[CR_NJOINTS];
        world_rotations(m, f, w);
        world_rotations(r, f, w2);
        for (int k = 0; k < CR_NJOINTS; k++)
            worst = fmax(worst, mat_diff(mat_mul(w2[k], g[k]), w[k]));
    }
    CR_CHECK(worst < 1e-5);
    m->trans[4] = NAN;
    CR_CHECK(cr_motion_validate(m, "x", &err) == CR_ERR_NAN && strstr(err.msg, "frame 1"));
    cr_motion_destroy(m);
    cr_motion_destroy(r);
}

/* ------------------------------------------------------------------ BVH -- */

typedef struct tjoint {
    const char *cmu, *mixamo; /* NULL: an End Site */
    int parent;
    double off[3]; /* cm, Y-up, T-pose facing +Z */
} tjoint;

static const tjoint rig[] = {
    {"Hips", "mixamorig:Hips", -1, {0, 0, 0}},
    {"LHipJoint", "mixamorig:LeftHipHelper", 0, {5, -5, 0}},
    {"LeftUpLeg", "mixamorig:LeftUpLeg", 1, {4, -5, 0}},
    {"LeftLeg", "mixamorig:LeftLeg", 2, {0, -42, 0}},
    {"LeftFoot", "mixamorig:LeftFoot", 3, {0, -40, 0}},
    {"LeftToeBase", "mixamorig:LeftToeBase", 4, {0, -8, 12}},
    {NULL, NULL, 5, {0, 0, 5}},
    {"RHipJoint", "mixamorig:RightHipHelper", 0, {-5, -5, 0}},
    {"RightUpLeg", "mixamorig:RightUpLeg", 7, {-4, -5, 0}},
    {"RightLeg", "mixamorig:RightLeg", 8, {0, -42, 0}},
    {"RightFoot", "mixamorig:RightFoot", 9, {0, -40, 0}},
    {"RightToeBase", "mixamorig:RightToeBase", 10, {0, -8, 12}},
    {NULL, NULL, 11, {0, 0, 5}},
    {"LowerBack", "mixamorig:Spine", 0, {0, 5, 0}},
    {"Spine", "mixamorig:Spine1", 13, {0, 10, 0}},
    {"Spine1", "mixamorig:Spine2", 14, {0, 10, 0}},
    {"Neck", "mixamorig:Neck", 15, {0, 15, 0}},
    {"Neck1", "mixamorig:NeckHelper", 16, {0, 5, 0}},
    {"Head", "mixamorig:Head", 17, {0, 8, 0}},
    {NULL, NULL, 18, {0, 15, 0}},
    {"LeftShoulder", "mixamorig:LeftShoulder", 15, {3, 12, 0}},
    {"LeftArm", "mixamorig:LeftArm", 20, {15, 0, 0}},
    {"LeftForeArm", "mixamorig:LeftForeArm", 21, {28, 0, 0}},
    {"LeftHand", "mixamorig:LeftHand", 22, {25, 0, 0}},
    {"LeftFingerBase", "mixamorig:LeftHandIndex1", 23, {5, 0, 0}},
    {NULL, NULL, 24, {5, 0, 0}},
    {"RightShoulder", "mixamorig:RightShoulder", 15, {-3, 12, 0}},
    {"RightArm", "mixamorig:RightArm", 26, {-15, 0, 0}},
    {"RightForeArm", "mixamorig:RightForeArm", 27, {-28, 0, 0}},
    {"RightHand", "mixamorig:RightHand", 28, {-25, 0, 0}},
    {"RightFingerBase", "mixamorig:RightHandIndex1", 29, {-5, 0, 0}},
    {NULL, NULL, 30, {-5, 0, 0}},
};
enum { RIG_N = sizeof rig / sizeof rig[0] };

/* Euler angles (Z, X, Y order, degrees, Y-up) per rig joint for two frames. */
typedef struct rig_frames {
    double euler[2][RIG_N][3];
    double root[2][3]; /* cm */
} rig_frames;

static rig_frames test_frames(void) {
    rig_frames r;
    memset(&r, 0, sizeof r);
    for (int f = 0; f < 2; f++) {
        r.root[f][0] = 10, r.root[f][1] = 100, r.root[f][2] = f ? 70 : 20;
        r.euler[f][0][2] = 90;  /* Hips: turned to face +X */
        r.euler[f][1][0] = 10;  /* LHipJoint Z: folded into the left hip */
        r.euler[f][2][1] = -20; /* LeftUpLeg X */
        r.euler[f][3][1] = 30;  /* LeftLeg X: the knee */
        r.euler[f][17][1] = 15; /* Neck1 X: folded into the head */
        r.euler[f][18][1] = 5;  /* Head X */
        r.euler[f][21][0] = 20, r.euler[f][21][1] = 30, r.euler[f][21][2] = 40; /* LeftArm */
    }
    return r;
}

/* The rig as BVH text. zup: offsets and motion turned by +90 degrees about X
 * (a Z-up export), with channel orders rewritten so the rotations are the
 * same: Rz(a) Rx(b) Ry(c) in Y-up is Ry(-a) Rx(b) Rz(c) in Z-up. */
static char *bvh_text(int mixamo, int zup, const rig_frames *r) {
    size_t cap = 32768, n = 0;
    char *s = malloc(cap);
    int stack[RIG_N], sp = 0;
    n += (size_t)snprintf(s + n, cap - n, "HIERARCHY\n");
    for (int i = 0; i < RIG_N; i++) {
        while (sp > 0 && stack[sp - 1] != rig[i].parent)
            n += (size_t)snprintf(s + n, cap - n, "%*s}\n", 2 * --sp, "");
        const char *name = mixamo ? rig[i].mixamo : rig[i].cmu;
        const double *o = rig[i].off;
        double off[3] = {o[0], zup ? -o[2] : o[1], zup ? o[1] : o[2]};
        int d = 2 * sp;
        if (!name)
            n += (size_t)snprintf(s + n, cap - n, "%*sEnd Site\n", d, "");
        else
            n += (size_t)snprintf(s + n, cap - n, "%*s%s %s\n", d, "", i ? "JOINT" : "ROOT", name);
        n += (size_t)snprintf(s + n, cap - n, "%*s{\n%*s  OFFSET %g %g %g\n", d, "", d, "", off[0],
                              off[1], off[2]);
        const char *rot = zup ? "Yrotation Xrotation Zrotation" : "Zrotation Xrotation Yrotation";
        if (i == 0)
            n += (size_t)snprintf(s + n, cap - n,
                                  "%*s  CHANNELS 6 Xposition Yposition Zposition %s\n", d, "", rot);
        else if (name)
            n += (size_t)snprintf(s + n, cap - n, "%*s  CHANNELS 3 %s\n", d, "", rot);
        stack[sp++] = i;
    }
    while (sp > 0)
        n += (size_t)snprintf(s + n, cap - n, "%*s}\n", 2 * --sp, "");
    n += (size_t)snprintf(s + n, cap - n, "MOTION\nFrames: 2\nFrame Time: 0.0333333\n");
    for (int f = 0; f < 2; f++) {
        const double *p = r->root[f];
        n += (size_t)snprintf(s + n, cap - n, "%g %g %g", p[0], zup ? -p[2] : p[1],
                              zup ? p[1] : p[2]);
        for (int i = 0; i < RIG_N; i++) {
            const double *e = r->euler[f][i];
            if (rig[i].cmu)
                n += (size_t)snprintf(s + n, cap - n, " %g %g %g", zup ? -e[0] : e[0], e[1], e[2]);
        }
        n += (size_t)snprintf(s + n, cap - n, "\n");
    }
    return s;
}

static cr_status load_bvh(const char *text, int recenter, cr_motion **m, cr_error *err) {
    cr_motion_import_def def = cr_motion_import_default_def();
    def.recenter = recenter;
    def.retarget = 0; /* rotations relative to the rig's T-pose, as written */
    return cr_motion_read_bvh_mem(text, strlen(text), "rig.bvh", &def, m, err);
}

CR_TEST(motion, bvh_rotations_folding_units_and_frames) {
    cr_error err = {0};
    rig_frames fr = test_frames();
    /* Expected local rotations (the rig's T-pose is the rest). */
    mat3 hip = mat_mul(mat_axis(2, 10), mat_axis(0, -20));
    mat3 arm = mat_mul(mat_mul(mat_axis(2, 20), mat_axis(0, 30)), mat_axis(1, 40));
    cr_motion *ref = NULL;
    for (int variant = 0; variant < 3; variant++) { /* CMU Y-up, CMU Z-up, Mixamo */
        char *text = bvh_text(variant == 2, variant == 1, &fr);
        cr_motion *m = NULL;
        CR_CHECK_OK(load_bvh(text, 0, &m, &err), &err);
        free(text);
        if (!m) continue;
        CR_CHECK(m->nframes == 2 && m->fps == 30.0f);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 0, CR_JOINT_PELVIS)), mat_axis(1, 90)) < 1e-5);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 1, CR_JOINT_LEFT_HIP)), hip) < 1e-5);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 0, CR_JOINT_LEFT_KNEE)), mat_axis(0, 30)) < 1e-5);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 0, CR_JOINT_HEAD)), mat_axis(0, 20)) < 1e-5);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 0, CR_JOINT_LEFT_SHOULDER)), arm) < 1e-5);
        int zero[] = {CR_JOINT_RIGHT_HIP,   CR_JOINT_SPINE1,     CR_JOINT_NECK,
                      CR_JOINT_LEFT_COLLAR, CR_JOINT_LEFT_WRIST, CR_JOINT_LEFT_FOOT};
        for (int k = 0; k < 6; k++)
            CR_CHECK(mat_diff(mat_aa(pose_at(m, 1, zero[k])), mat_identity()) < 1e-6);
        /* cm to m; the rest pelvis stands 1 m above the toes, as the root does. */
        CR_CHECK_NEAR(m->trans[0], 0.1, 1e-6);
        CR_CHECK_NEAR(m->trans[1], 0.0, 1e-6);
        CR_CHECK_NEAR(m->trans[2], 0.2, 1e-6);
        CR_CHECK_NEAR(m->trans[5], 0.7, 1e-6);
        if (variant == 0) {
            ref = m;
            continue;
        }
        double worst = 0;
        for (int k = 0; k < 2 * CR_NJOINTS * 3; k++)
            worst = fmax(worst, fabs(m->poses[k] - ref->poses[k]));
        CR_CHECK(worst < 1e-5);
        cr_motion_destroy(m);
    }
    cr_motion_destroy(ref);
    /* Recentered (the default): frame 0 faces +Z at the origin; the walk of 0.5 m
     * along the rig's +Z, which was the body's right, becomes -X. */
    char *text = bvh_text(0, 0, &fr);
    cr_motion *m = NULL;
    CR_CHECK_OK(load_bvh(text, 1, &m, &err), &err);
    if (m) {
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 1, CR_JOINT_PELVIS)), mat_identity()) < 1e-6);
        CR_CHECK(fabs(m->trans[0]) < 1e-6 && fabs(m->trans[2]) < 1e-6);
        CR_CHECK_NEAR(m->trans[3], -0.5, 1e-6);
        CR_CHECK_NEAR(m->trans[5], 0.0, 1e-6);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 1, CR_JOINT_LEFT_KNEE)), mat_axis(0, 30)) < 1e-5);
        cr_motion_destroy(m);
    }
    /* A given scale overrides the guess. */
    cr_motion_import_def def = cr_motion_import_default_def();
    def.recenter = 0, def.bvh_scale = 0.1f, def.retarget = 0;
    CR_CHECK_OK(cr_motion_read_bvh_mem(text, strlen(text), "rig.bvh", &def, &m, &err), &err);
    if (m) CR_CHECK_NEAR(m->trans[2], 2.0, 1e-5);
    cr_motion_destroy(m);
    /* From a file, by extension. */
    char path[512];
    snprintf(path, sizeof path, "%s/rig.bvh", cr_test_tmpdir());
    FILE *fp = fopen(path, "wb");
    CR_REQUIRE(fp);
    fputs(text, fp);
    fclose(fp);
    CR_CHECK_OK(cr_motion_load(path, &m, &err), &err);
    CR_CHECK(m && m->nframes == 2);
    cr_motion_destroy(m);
    free(text);
}

/* text with the first occurrence of `from` replaced by `to` (caller frees). */
static char *replaced(const char *text, const char *from, const char *to) {
    const char *at = strstr(text, from);
    size_t n = strlen(text) + strlen(to) + 1;
    char *s = malloc(n);
    if (!at) {
        memcpy(s, text, strlen(text) + 1);
        return s;
    }
    size_t pre = (size_t)(at - text);
    memcpy(s, text, pre);
    strcpy(s + pre, to);
    strcat(s, at + strlen(from));
    return s;
}

static int line_of(const char *text, const char *at) {
    int line = 1;
    for (const char *p = text; p < at; p++)
        line += *p == '\n';
    return line;
}

CR_TEST(motion, bvh_refuses_malformed_files) {
    cr_error err = {0};
    rig_frames fr = test_frames();
    char *text = bvh_text(0, 0, &fr);
    cr_motion *m = NULL;
    /* A frame line one value short: "rig.bvh:<line>: expected 84 channel values, got 83". */
    char *last = strrchr(text, ' ');
    char *cut = malloc(strlen(text) + 1);
    memcpy(cut, text, (size_t)(last - text));
    strcpy(cut + (last - text), "\n");
    char want[64];
    snprintf(want, sizeof want, "rig.bvh:%d: expected 84 channel values, got 83",
             line_of(text, last));
    CR_CHECK(load_bvh(cut, 0, &m, &err) == CR_ERR_PARSE && !m);
    CR_CHECK(strstr(err.msg, want) != NULL);
    free(cut);
    struct {
        const char *from, *to;
        cr_status st;
        const char *says;
    } cases[] = {
        {"20 0 0 90", "20 0 0 nan", CR_ERR_NAN, "rig.bvh:%d: expected a finite channel value"},
        {"Frames: 2", "Frames: 1000000000", CR_ERR_PARSE, "expected 1000000000 frames, found 2"},
        {"Frames: 2", "Frames: 0", CR_ERR_RANGE, "0 frames declared"},
        {"Frames: 2", "Frames: 1", CR_ERR_PARSE, "more frame lines than the 1 declared"},
        {"Frame Time: 0.0333333", "Frame Time: 0", CR_ERR_RANGE, "Frame Time 0 s"},
        {"}\nMOTION", "MOTION", CR_ERR_PARSE, "got 'MOTION'"},
        {"CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Zrotation Yrotation",
         CR_ERR_PARSE, "a channel not listed before"},
        {"CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 7 Zrotation Xrotation Yrotation",
         CR_ERR_PARSE, "CHANNELS 7"},
        {"OFFSET 0 0 5", "OFFSET 0 0", CR_ERR_PARSE, "expected offset coordinate, got '}'"},
        {"JOINT LeftLeg", "JOINT LeftArmX", CR_ERR_PARSE, "not below"},
        {"HIERARCHY", "HIERARCHIES", CR_ERR_PARSE, "rig.bvh:1: expected 'HIERARCHY'"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *bad = replaced(text, cases[i].from, cases[i].to);
        if (strcmp(cases[i].says, "not below") == 0) { /* swap the knee and the left elbow */
            char *b2 = replaced(bad, "JOINT LeftForeArm", "JOINT LeftLeg");
            free(bad);
            bad = replaced(b2, "JOINT LeftArmX", "JOINT LeftForeArm");
            free(b2);
        }
        cr_status st = load_bvh(bad, 0, &m, &err);
        CR_CHECK(st == cases[i].st);
        char says[128]; /* the NaN case names the line of its frame */
        snprintf(says, sizeof says, cases[i].says, line_of(text, strstr(text, cases[i].from)));
        if (!strstr(err.msg, says)) printf("    case %zu: %s\n", i, err.msg);
        CR_CHECK(strstr(err.msg, says) != NULL);
        cr_motion_destroy(m);
        m = NULL;
        free(bad);
    }
    /* A frame missing at the end, past blank lines (which are skipped). */
    char *more = replaced(text, "Frames: 2", "Frames: 3");
    more = realloc(more, strlen(more) + 400);
    memset(more + strlen(more), '\n', 399);
    more[strlen(text) + 399] = 0;
    CR_CHECK(load_bvh(more, 0, &m, &err) == CR_ERR_PARSE &&
             strstr(err.msg, "expected 3 frames, found 2"));
    free(more);
    /* Names no rig table knows. */
    char *anon = strdup(text);
    for (char *p = anon; (p = strstr(p, "Left")) != NULL; p += 4)
        memcpy(p, "Lxft", 4);
    for (char *p = anon; (p = strstr(p, "Right")) != NULL; p += 5)
        memcpy(p, "Rxght", 5);
    CR_CHECK(load_bvh(anon, 0, &m, &err) == CR_ERR_UNSUPPORTED);
    CR_CHECK(strstr(err.msg, "cannot map") && strstr(err.msg, "CMU"));
    free(anon);
    /* Every prefix: a status, never a crash; cut before the last frame line, a failure. */
    const char *last_line = strrchr(text, '\n');
    while (last_line > text && last_line[-1] != '\n')
        last_line--;
    for (size_t n = 0; n < strlen(text); n++) {
        cr_status st = cr_motion_read_bvh_mem(text, n, "cut.bvh", NULL, &m, &err);
        if (n < (size_t)(last_line - text)) CR_CHECK(st != CR_OK && strstr(err.msg, "cut.bvh"));
        cr_motion_destroy(m);
        m = NULL;
    }
    free(text);
}

/* ------------------------------------------------------------ npz motions -- */

CR_TEST(motion, npz_round_trip_and_amass_files) {
    cr_error err = {0};
    char path[512];
    cr_motion *walk = NULL, *back = NULL;
    CR_CHECK_OK(cr_motion_clip("dance", 40, 25, &walk, &err), &err);
    CR_REQUIRE(walk);
    snprintf(path, sizeof path, "%s/dance.npz", cr_test_tmpdir());
    CR_CHECK_OK(cr_motion_save(path, walk, &err), &err);
    CR_CHECK_OK(cr_motion_load(path, &back, &err), &err);
    CR_REQUIRE(back);
    CR_CHECK(back->nframes == 40 && back->fps == 25.0f);
    CR_CHECK(memcmp(back->poses, walk->poses, 40 * CR_NJOINTS * 3 * sizeof(float)) == 0);
    CR_CHECK(memcmp(back->trans, walk->trans, 40 * 3 * sizeof(float)) == 0);
    cr_motion_destroy(back);
    snprintf(path, sizeof path, "%s/dance.bvh", cr_test_tmpdir());
    CR_CHECK(cr_motion_save(path, walk, &err) == CR_ERR_UNSUPPORTED);
    cr_motion_destroy(walk);
    /* An AMASS-style SMPL+H file: Z-up, 156 pose values, float64, extra members. */
    enum { T = 3 };
    double poses[T][156], trans[T][3] = {{1, 2, 0.9}, {1, 2.5, 1.0}, {1.2, 3, 0.9}};
    for (int f = 0; f < T; f++)
        for (int k = 0; k < 156; k++)
            poses[f][k] = 0.001 * (k + 1) * (f + 1);
    /* Root: standing up in a Z-up world (Rx 90), then at frame 1 turned 30 degrees about Z. */
    mat3 stand = mat_axis(0, 90), turned = mat_mul(mat_axis(2, 30), stand);
    double q30 = 30 * M_PI / 180;
    double root1[3] = {0, 0, 0};
    { /* axis-angle of `turned`: from its trace and antisymmetric part */
        double c = 0.5 * (turned.m[0][0] + turned.m[1][1] + turned.m[2][2] - 1), th = acos(c);
        double k = th / (2 * sin(th));
        root1[0] = k * (turned.m[2][1] - turned.m[1][2]);
        root1[1] = k * (turned.m[0][2] - turned.m[2][0]);
        root1[2] = k * (turned.m[1][0] - turned.m[0][1]);
    }
    for (int f = 0; f < T; f++) {
        poses[f][0] = f == 1 ? root1[0] : M_PI / 2;
        poses[f][1] = f == 1 ? root1[1] : 0;
        poses[f][2] = f == 1 ? root1[2] : 0;
    }
    double fps = 120, betas[16] = {0.5};
    int64_t sp[2] = {T, 156}, st3[2] = {T, 3}, sb[1] = {16};
    snprintf(path, sizeof path, "%s/amass.npz", cr_test_tmpdir());
    static const char gender[] = "\x93NUMPY\x01\x00\x76\x00{'descr': '<U6', 'fortran_order': "
                                 "False, 'shape': (), }";
    unsigned char gbytes[128 + 24] = {0};
    memcpy(gbytes, gender, sizeof gender - 1);
    memset(gbytes + sizeof gender - 1, ' ', 128 - (sizeof gender - 1));
    gbytes[127] = '\n';
    cr_npz_writer *w = NULL;
    CR_CHECK_OK(cr_npz_writer_open(path, 1, &w, &err), &err);
    CR_REQUIRE(w);
    CR_CHECK_OK(cr_npz_writer_add(w, "trans", CR_NPY_F64, 2, st3, trans, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add_raw(w, "gender.npy", gbytes, sizeof gbytes, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(w, "mocap_framerate", CR_NPY_F64, 0, NULL, &fps, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(w, "poses", CR_NPY_F64, 2, sp, poses, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(w, "betas", CR_NPY_F64, 1, sb, betas, &err), &err);
    CR_CHECK_OK(cr_npz_writer_commit(w, &err), &err);
    for (int recenter = 1; recenter >= 0; recenter--) {
        cr_motion_import_def def = cr_motion_import_default_def();
        def.recenter = recenter;
        def.retarget = 0; /* SMPL's T-pose rest, as written */
        cr_motion *m = NULL;
        CR_CHECK_OK(cr_motion_import(path, &def, &m, &err), &err);
        if (!m) continue;
        CR_CHECK(m->nframes == T && m->fps == 120.0f);
        /* Z-up to Y-up: standing is the rest; the turn about Z is a turn about Y. */
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 0, 0)), mat_identity()) < 1e-6);
        CR_CHECK(mat_diff(mat_aa(pose_at(m, 1, 0)), mat_axis(1, q30 * 180 / M_PI)) < 1e-6);
        for (int f = 0; f < T; f++)
            for (int k = 3; k < 66; k++)
                CR_CHECK(pose_at(m, f, 0)[k] == (float)poses[f][k]);
        /* (x, y, z) Z-up is (x, z, -y) Y-up; recentered on frame 0. */
        double o[3] = {recenter ? 0 : 1, recenter ? 0 : 0.9, recenter ? 0 : -2};
        CR_CHECK_NEAR(m->trans[0], o[0], 1e-6);
        CR_CHECK_NEAR(m->trans[1], o[1], 1e-6);
        CR_CHECK_NEAR(m->trans[2], o[2], 1e-6);
        CR_CHECK_NEAR(m->trans[3], o[0], 1e-6);
        CR_CHECK_NEAR(m->trans[4], o[1] + 0.1, 1e-6);
        CR_CHECK_NEAR(m->trans[5], o[2] - 0.5, 1e-6);
        CR_CHECK_NEAR(m->trans[6], o[0] + 0.2, 1e-6);
        CR_CHECK_NEAR(m->trans[8], o[2] - 1.0, 1e-6);
        cr_motion_destroy(m);
    }
}

/* An .npz in memory with the given float64 members (name, ndim, shape, data). */
typedef struct npz_arg {
    const char *name;
    int ndim;
    int64_t shape[3];
    const double *data;
} npz_arg;

static cr_status motion_from_args(const npz_arg *a, int n, cr_motion **m, cr_error *err) {
    char path[512];
    snprintf(path, sizeof path, "%s/args.npz", cr_test_tmpdir());
    cr_npz_writer *w = NULL;
    CR_TRY(cr_npz_writer_open(path, 0, &w, err));
    for (int i = 0; i < n; i++)
        CR_TRY(cr_npz_writer_add(w, a[i].name, CR_NPY_F64, a[i].ndim, a[i].shape, a[i].data, err));
    CR_TRY(cr_npz_writer_commit(w, err));
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_motion_read_npz_mem(buf, len, "bad.npz", NULL, m, err);
    free(buf);
    return st;
}

CR_TEST(motion, npz_layouts_and_refusals) {
    cr_error err = {0};
    static double zeros[4 * 200];
    double nan_poses[2 * 66] = {0}, fps = 60, up3 = 3;
    nan_poses[70] = NAN;
    cr_motion *m = NULL;
    /* AMASS SMPL-X layout: root_orient + pose_body instead of poses. */
    double root[2 * 3] = {0.1, 0.2, 0.3, 0, 0, 0}, body[2 * 63] = {0};
    body[63 + 5] = 0.25;
    npz_arg split[] = {{"root_orient", 2, {2, 3}, root},
                       {"pose_body", 2, {2, 63}, body},
                       {"mocap_frame_rate", 1, {1}, &fps}};
    CR_CHECK_OK(motion_from_args(split, 3, &m, &err), &err);
    if (m) {
        CR_CHECK(m->nframes == 2 && m->fps == 60.0f);
        CR_CHECK(pose_at(m, 1, 2)[2] == 0.25f); /* pose_body[5] is joint 2's z */
        cr_motion_destroy(m);
        m = NULL;
    }
    struct {
        npz_arg a[3];
        int n;
        cr_status st;
        const char *says;
    } cases[] = {
        {{{"poses", 2, {3, 60}, zeros}, {"mocap_framerate", 0, {0}, &fps}},
         2,
         CR_ERR_SHAPE,
         "bad.npz: poses: shape (3, 60)"},
        {{{"poses", 2, {3, 72}, zeros}, {"trans", 2, {2, 3}, zeros}, {"fps", 0, {0}, &fps}},
         3,
         CR_ERR_SHAPE,
         "trans: shape (2, 3), expected (3, 3)"},
        {{{"poses", 2, {3, 72}, zeros}}, 1, CR_ERR_PARSE, "no frame rate"},
        {{{"poses", 2, {2, 66}, nan_poses}, {"fps", 0, {0}, &fps}},
         2,
         CR_ERR_NAN,
         "bad.npz: poses.npy: element [1, 4]"},
        {{{"poses", 2, {3, 72}, zeros}, {"fps", 0, {0}, &zeros[0]}}, 2, CR_ERR_RANGE, "fps = 0"},
        {{{"poses", 2, {3, 72}, zeros}, {"fps", 0, {0}, &fps}, {"up_axis", 0, {0}, &up3}},
         3,
         CR_ERR_RANGE,
         "up_axis = 3"},
        {{{"trans", 2, {3, 3}, zeros}, {"fps", 0, {0}, &fps}}, 2, CR_ERR_PARSE, "no 'poses'"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        CR_CHECK(motion_from_args(cases[i].a, cases[i].n, &m, &err) == cases[i].st && !m);
        if (!strstr(err.msg, cases[i].says)) printf("    case %zu: %s\n", i, err.msg);
        CR_CHECK(strstr(err.msg, cases[i].says) != NULL);
    }
    CR_CHECK(cr_motion_load("walk.fbx", &m, &err) == CR_ERR_UNSUPPORTED && strstr(err.msg, ".fbx"));
}

/* ----------------------------------------------------------- SMPL models -- */

CR_TEST(motion, smpl_model_shapes_regresses_and_merges_weights) {
    cr_error err = {0};
    enum { V = 8, J = 24, B = 3, F = 4 };
    double tmpl[V][3], dirs[V][3][B], reg[J][V] = {{0}}, w[V][J] = {{0}}, kt[2][J];
    int64_t faces[F][3] = {{0, 1, 2}, {2, 3, 0}, {4, 5, 6}, {6, 7, 4}};
    cr_rng rng = cr_rng_make(3, 1);
    for (int v = 0; v < V; v++)
        for (int k = 0; k < 3; k++) {
            tmpl[v][k] = cr_rng_uniform(&rng) - 0.5;
            for (int b = 0; b < B; b++)
                dirs[v][k][b] = 0.1 * (cr_rng_uniform(&rng) - 0.5);
        }
    for (int j = 0; j < J; j++) {
        reg[j][j % V] = 0.75, reg[j][(j + 3) % V] = 0.25;
        kt[0][j] = j == 0 ? 4294967295.0 : j < CR_NJOINTS ? cr_joint_parent[j] : 20 + (j - 22);
        kt[1][j] = j;
    }
    for (int v = 0; v < V; v++) {
        w[v][(v + 1) % CR_NJOINTS] = 0.5;
        w[v][(v + 5) % CR_NJOINTS] = 0.2;
        w[v][(v + 9) % CR_NJOINTS] = 0.15;
        w[v][(v + 13) % CR_NJOINTS] = 0.1;
        w[v][(v + 17) % CR_NJOINTS] = 0.05;
    }
    /* Vertex 0: the left hand (22) adds to the left wrist (20). */
    memset(w[0], 0, sizeof w[0]);
    w[0][20] = 0.2, w[0][22] = 0.25, w[0][18] = 0.3, w[0][3] = 0.1, w[0][1] = 0.1, w[0][4] = 0.05;
    char path[512];
    snprintf(path, sizeof path, "%s/smpl.npz", cr_test_tmpdir());
    int64_t s_t[2] = {V, 3}, s_d[3] = {V, 3, B}, s_r[2] = {J, V}, s_w[2] = {V, J}, s_k[2] = {2, J},
            s_f[2] = {F, 3};
    cr_npz_writer *wr = NULL;
    CR_CHECK_OK(cr_npz_writer_open(path, 1, &wr, &err), &err);
    CR_REQUIRE(wr);
    CR_CHECK_OK(cr_npz_writer_add(wr, "v_template", CR_NPY_F64, 2, s_t, tmpl, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(wr, "shapedirs", CR_NPY_F64, 3, s_d, dirs, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(wr, "J_regressor", CR_NPY_F64, 2, s_r, reg, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(wr, "weights", CR_NPY_F64, 2, s_w, w, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(wr, "kintree_table", CR_NPY_F64, 2, s_k, kt, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(wr, "f", CR_NPY_I64, 2, s_f, faces, &err), &err);
    CR_CHECK_OK(cr_npz_writer_commit(wr, &err), &err);
    float betas[2] = {1.5f, -2.0f};
    cr_body_model body;
    CR_CHECK_OK(cr_smpl_load(path, betas, 2, &body, &err), &err);
    CR_REQUIRE(body.rest && body.rest->nv == V && body.rest->nf == F);
    double shaped[V][3], joints[CR_NJOINTS][3], lowest = 1e9;
    for (int v = 0; v < V; v++)
        for (int k = 0; k < 3; k++) {
            shaped[v][k] = tmpl[v][k] + dirs[v][k][0] * betas[0] + dirs[v][k][1] * betas[1];
            if (k == 1) lowest = fmin(lowest, shaped[v][1]);
        }
    for (int j = 0; j < CR_NJOINTS; j++)
        for (int k = 0; k < 3; k++)
            joints[j][k] = 0.75 * shaped[j % V][k] + 0.25 * shaped[(j + 3) % V][k];
    double shift[3] = {-joints[0][0], -lowest, -joints[0][2]};
    for (int v = 0; v < V; v++)
        for (int k = 0; k < 3; k++)
            CR_CHECK_NEAR(body.rest->pos[v * 3 + k], shaped[v][k] + shift[k], 1e-6);
    for (int j = 0; j < CR_NJOINTS; j++)
        for (int k = 0; k < 3; k++)
            CR_CHECK_NEAR(body.joints[j * 3 + k], joints[j][k] + shift[k], 1e-6);
    CR_CHECK(body.rest->tri[5] == 0 && body.rest->tri[11] == 4);
    /* Merged and renormalised: wrist 0.45, elbow 0.3, then two of 0.1 (sum 0.95). */
    CR_CHECK(body.skin_joint[0] == 20 && body.skin_joint[1] == 18);
    CR_CHECK_NEAR(body.skin_weight[0], 0.45 / 0.95, 1e-6);
    CR_CHECK_NEAR(body.skin_weight[1], 0.30 / 0.95, 1e-6);
    CR_CHECK_NEAR(body.skin_weight[2] + body.skin_weight[3], 0.2 / 0.95, 1e-6);
    for (int v = 0; v < V; v++) {
        double sum = 0;
        for (int s = 0; s < 4; s++) {
            sum += body.skin_weight[v * 4 + s];
            CR_CHECK(body.skin_joint[v * 4 + s] >= 0 && body.skin_joint[v * 4 + s] < CR_NJOINTS);
        }
        CR_CHECK_NEAR(sum, 1.0, 1e-6);
    }
    cr_smpl_free(&body);
    CR_CHECK(body.rest == NULL);
    /* Refusals: too many betas, and (from the same bytes, edited) a foreign tree. */
    float many[5] = {0};
    CR_CHECK(cr_smpl_load(path, many, 5, &body, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "5 betas") && strstr(err.msg, "3 shape components"));
    kt[0][4] = 2; /* left knee under the right hip */
    snprintf(path, sizeof path, "%s/smpl_bad.npz", cr_test_tmpdir());
    CR_CHECK_OK(cr_npz_writer_open(path, 0, &wr, &err), &err);
    CR_REQUIRE(wr);
    cr_npz_writer_add(wr, "v_template", CR_NPY_F64, 2, s_t, tmpl, &err);
    cr_npz_writer_add(wr, "J_regressor", CR_NPY_F64, 2, s_r, reg, &err);
    cr_npz_writer_add(wr, "weights", CR_NPY_F64, 2, s_w, w, &err);
    cr_npz_writer_add(wr, "kintree_table", CR_NPY_F64, 2, s_k, kt, &err);
    cr_npz_writer_add(wr, "f", CR_NPY_I64, 2, s_f, faces, &err);
    CR_CHECK_OK(cr_npz_writer_commit(wr, &err), &err);
    CR_CHECK(cr_smpl_load(path, NULL, 0, &body, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "joint 4 (left_knee) has parent 2"));
    CR_CHECK(body.rest == NULL);
}

/* "A clip name or a file", resolved one way for every command: a clip is
 * cr_motion_clip's, a file is cr_motion_import then cr_motion_prepare's,
 * cut to max_frames; anything else is refused naming the clips. */
CR_TEST(motion, resolve_takes_a_clip_or_a_file) {
    cr_error err = {0};
    cr_motion *a = NULL, *b = NULL, *raw = NULL, *c = NULL;
    cr_motion_resolve_def rd = cr_motion_resolve_default_def();
    rd.clip_frames = 40, rd.fps = 24.0f;
    cr_motion_prepare_report rep;
    CR_CHECK(cr_motion_is_clip("walk") && !cr_motion_is_clip("walk.npz"));
    CR_CHECK_OK(cr_motion_resolve("walk", &rd, &a, &rep, &err), &err);
    CR_CHECK_OK(cr_motion_clip("walk", 40, 24.0f, &b, &err), &err);
    CR_REQUIRE(a && b && a->nframes == 40 && b->nframes == 40);
    CR_CHECK(memcmp(a->poses, b->poses, sizeof(float) * 40 * CR_NJOINTS * 3) == 0);
    CR_CHECK(rep.source_frames == 40 && rep.last_frame == 39 && rep.source_fps == 24.0f);
    char path[600];
    snprintf(path, sizeof path, "%s/resolve.npz", cr_test_tmpdir());
    CR_CHECK_OK(cr_motion_save(path, a, &err), &err);
    rd.fps = 30.0f, rd.max_frames = 20;
    CR_CHECK_OK(cr_motion_resolve(path, &rd, &c, NULL, &err), &err);
    CR_CHECK_OK(cr_motion_load(path, &raw, &err), &err);
    cr_motion_prepare_def pd = cr_motion_prepare_default_def();
    pd.fps = 30.0f;
    cr_motion *prepared = NULL;
    CR_CHECK_OK(cr_motion_prepare(raw, &pd, NULL, &prepared, NULL, &err), &err);
    CR_REQUIRE(c && prepared && prepared->nframes > 20);
    CR_CHECK(c->nframes == 20 && c->fps == 30.0f);
    CR_CHECK(memcmp(c->poses, prepared->poses, sizeof(float) * 20 * CR_NJOINTS * 3) == 0);
    cr_motion *bad = NULL;
    CR_CHECK(cr_motion_resolve("strut", &rd, &bad, NULL, &err) == CR_ERR_INVALID &&
             strstr(err.msg, "strut") && strstr(err.msg, "walk"));
    CR_CHECK(cr_motion_resolve("nope/strut.bvh", &rd, &bad, NULL, &err) != CR_OK &&
             strstr(err.msg, "strut.bvh") && bad == NULL);
    cr_motion_destroy(a), cr_motion_destroy(b), cr_motion_destroy(c);
    cr_motion_destroy(raw), cr_motion_destroy(prepared);
}
