/* test_mocap.c: captured motions on the body: retargeting a BVH by bone
 * directions (a rig written here, T-posed arms and legs splayed 20 degrees,
 * and the same motion on an A-pose rig), resampling against analytic
 * values, grounding on the feet, the calibration frame and the ease-in. */
#include "crease/body.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------- matrices -- */

typedef struct m3 {
    double m[3][3];
} m3;

static m3 m3_id(void) {
    m3 r = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    return r;
}

static m3 m3_mul(m3 a, m3 b) {
    m3 r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
    return r;
}

static m3 m3_t(m3 a) {
    m3 r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = a.m[j][i];
    return r;
}

/* Rotation by `rad` about axis 0 (X), 1 (Y) or 2 (Z). */
static m3 m3_axis(int axis, double rad) {
    m3 r = m3_id();
    int a = (axis + 1) % 3, b = (axis + 2) % 3;
    r.m[a][a] = cos(rad), r.m[a][b] = -sin(rad);
    r.m[b][a] = sin(rad), r.m[b][b] = cos(rad);
    return r;
}

static void m3_apply(m3 a, const double v[3], double out[3]) {
    double t[3];
    for (int i = 0; i < 3; i++)
        t[i] = a.m[i][0] * v[0] + a.m[i][1] * v[1] + a.m[i][2] * v[2];
    memcpy(out, t, sizeof t);
}

/* Angle of the rotation a^T b, rad. */
static double m3_angle(m3 a, m3 b) {
    m3 r = m3_mul(m3_t(a), b);
    double c = 0.5 * (r.m[0][0] + r.m[1][1] + r.m[2][2] - 1);
    return acos(fmax(-1.0, fmin(1.0, c)));
}

static double angle3(const double a[3], const double b[3]) {
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    double na = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    double nb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    return acos(fmax(-1.0, fmin(1.0, d / (na * nb))));
}

/* Z X Y Euler angles (degrees) of R = Rz(a) Rx(b) Ry(c). */
static void m3_euler_zxy(m3 r, double e[3]) {
    double b = asin(fmax(-1.0, fmin(1.0, r.m[2][1])));
    e[0] = atan2(-r.m[0][1], r.m[1][1]) * 180 / M_PI;
    e[1] = b * 180 / M_PI;
    e[2] = atan2(-r.m[2][0], r.m[2][2]) * 180 / M_PI;
}

/* ------------------------------------------------------------------ rig -- */

/* A CMU-style (cgspeed) rig, cm, Y-up, facing +Z, in a T-pose with each leg
 * splayed 20 degrees out: LHipJoint and Neck1 lie between mapped joints. */
typedef struct rjoint {
    const char *name; /* NULL: an End Site */
    int parent;
    double off[3];
} rjoint;

#define SPLAY (20.0 * M_PI / 180.0)
enum {
    R_HIPS = 0,
    R_LHIPJ,
    R_LUPLEG,
    R_LLEG,
    R_LFOOT,
    R_LTOE,
    R_LTOE_END,
    R_RHIPJ,
    R_RUPLEG,
    R_RLEG,
    R_RFOOT,
    R_RTOE,
    R_RTOE_END,
    R_LOWERBACK,
    R_SPINE,
    R_SPINE1,
    R_NECK,
    R_NECK1,
    R_HEAD,
    R_HEAD_END,
    R_LSHOULDER,
    R_LARM,
    R_LFOREARM,
    R_LHAND,
    R_LHAND_END,
    R_RSHOULDER,
    R_RARM,
    R_RFOREARM,
    R_RHAND,
    R_RHAND_END,
    RN
};

static rjoint trig[RN];

static void rig_init(void) {
    static const char *names[RN] = {
        "Hips",          "LHipJoint",    "LeftUpLeg",    "LeftLeg",    "LeftFoot",
        "LeftToeBase",   NULL,           "RHipJoint",    "RightUpLeg", "RightLeg",
        "RightFoot",     "RightToeBase", NULL,           "LowerBack",  "Spine",
        "Spine1",        "Neck",         "Neck1",        "Head",       NULL,
        "LeftShoulder",  "LeftArm",      "LeftForeArm",  "LeftHand",   NULL,
        "RightShoulder", "RightArm",     "RightForeArm", "RightHand",  NULL};
    static const int parents[RN] = {-1, 0,  1,  2,  3,  4,  5,  0,  7,  8,  9,  10, 11, 0,  13,
                                    14, 15, 16, 17, 18, 15, 20, 21, 22, 23, 15, 25, 26, 27, 28};
    double s = sin(SPLAY), c = cos(SPLAY);
    double off[RN][3] = {{0, 0, 0},
                         {4, -3, 0},
                         {4, -3, 0},
                         {42 * s, -42 * c, 0},
                         {40 * s, -40 * c, 0},
                         {0, -6, 12},
                         {0, 0, 4},
                         {-4, -3, 0},
                         {-4, -3, 0},
                         {-42 * s, -42 * c, 0},
                         {-40 * s, -40 * c, 0},
                         {0, -6, 12},
                         {0, 0, 4},
                         {0, 6, 0},
                         {0, 10, 0},
                         {0, 10, 0},
                         {0, 15, 0},
                         {0, 5, 0},
                         {0, 8, 0},
                         {0, 15, 0},
                         {3, 12, 0},
                         {15, 0, 0},
                         {28, 0, 0},
                         {25, 0, 0},
                         {8, 0, 0},
                         {-3, 12, 0},
                         {-15, 0, 0},
                         {-28, 0, 0},
                         {-25, 0, 0},
                         {-8, 0, 0}};
    for (int i = 0; i < RN; i++) {
        trig[i].name = names[i];
        trig[i].parent = parents[i];
        memcpy(trig[i].off, off[i], sizeof off[i]);
    }
}

enum { NF = 24 };
static const double RIG_FPS = 30.0;

/* The motion as local rotations of the T-rig (a walk-like swing: the legs
 * brought in from their 20-degree splay, thighs and knees swinging, arms
 * down and swinging with a twist, the neck and head nodding). */
static m3 t_local(int i, int f) {
    double t = f / RIG_FPS, w = 2 * M_PI * 0.9 * t, sw = sin(w);
    switch (i) {
    case R_HIPS:
        return m3_mul(m3_axis(1, 0.2 * sw), m3_axis(0, 0.05));
    case R_LHIPJ:
        return m3_axis(2, 0.05);
    case R_LUPLEG:
        return m3_mul(m3_axis(2, -SPLAY - 0.05), m3_axis(0, -0.5 * sw));
    case R_RUPLEG:
        return m3_mul(m3_axis(2, SPLAY), m3_axis(0, 0.5 * sw));
    case R_LLEG:
        return m3_axis(0, 0.3 + 0.3 * sw);
    case R_RLEG:
        return m3_axis(0, 0.3 - 0.3 * sw);
    case R_LFOOT:
        return m3_axis(0, -0.1 * sw);
    case R_SPINE:
        return m3_axis(0, 0.1 * sw);
    case R_NECK1:
        return m3_axis(0, 0.25);
    case R_HEAD:
        return m3_axis(0, 0.15 * sw);
    case R_LARM:
        return m3_mul(m3_axis(2, -1.2), m3_axis(0, 0.4 * sw));
    case R_RARM:
        return m3_mul(m3_axis(2, 1.2), m3_axis(0, 0.3 + 0.4 * sw));
    case R_LFOREARM:
        return m3_axis(1, 0.6 + 0.2 * sw);
    case R_RFOREARM:
        return m3_axis(1, -0.5);
    default:
        return m3_id();
    }
}

/* Rigs of one motion (rest: RIG_T, RIG_A, RIG_LYING): rest bones of joint i
 * turned by rest_turn(i): the A-pose (arms 45 degrees down, legs straight) or
 * the whole bind skeleton lying along +X, as joint-oriented exports write it;
 * their locals S_p R S_i^T keep every bone's world direction, so it is the
 * same motion. */
enum { RIG_T, RIG_A, RIG_LYING, RIG_ALONG_X };

/* The rotation taking unit a to unit b by the shortest arc (Rodrigues). */
static m3 m3_arc(const double a[3], const double b[3]) {
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if (d < -1 + 1e-9) return m3_axis(fabs(a[2]) < 0.9 ? 2 : 1, M_PI); /* opposite */
    m3 k = {{{0, -c[2], c[1]}, {c[2], 0, -c[0]}, {-c[1], c[0], 0}}}, r = m3_id(), k2 = m3_mul(k, k);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] += k.m[i][j] + k2.m[i][j] / (1 + d);
    return r;
}

static m3 rest_turn(int rest, int i) {
    if (i < 0) return m3_id();
    if (rest == RIG_LYING) return m3_axis(2, -M_PI / 2);
    if (rest == RIG_ALONG_X) { /* joint-oriented: each joint's first bone along +X */
        for (int c = i + 1; c < RN; c++)
            if (trig[c].parent == i) {
                double n = sqrt(trig[c].off[0] * trig[c].off[0] + trig[c].off[1] * trig[c].off[1] +
                                trig[c].off[2] * trig[c].off[2]);
                if (n < 1e-9) continue; /* a joint on its parent (CMU's LowerBack) */
                double a[3] = {trig[c].off[0] / n, trig[c].off[1] / n, trig[c].off[2] / n};
                return a[0] < 1 - 1e-9 ? m3_arc(a, (double[3]){1, 0, 0}) : m3_id();
            }
        return m3_id();
    }
    switch (i) {
    case R_LARM:
    case R_LFOREARM:
    case R_LHAND:
        return m3_axis(2, -M_PI / 4);
    case R_RARM:
    case R_RFOREARM:
    case R_RHAND:
        return m3_axis(2, M_PI / 4);
    case R_LUPLEG:
    case R_LLEG:
        return m3_axis(2, -SPLAY);
    case R_RUPLEG:
    case R_RLEG:
        return m3_axis(2, SPLAY);
    default:
        return m3_id();
    }
}

static m3 rig_local(int rest, int i, int f) {
    m3 r = t_local(i, f);
    if (rest == RIG_T) return r;
    return m3_mul(m3_mul(rest_turn(rest, trig[i].parent), r), m3_t(rest_turn(rest, i)));
}

static void rig_offset(int rest, int i, double off[3]) {
    memcpy(off, trig[i].off, 3 * sizeof(double));
    if (rest != RIG_T) m3_apply(rest_turn(rest, trig[i].parent), off, off);
}

static void root_pos(int f, double p[3]) {
    p[0] = 3, p[1] = 95, p[2] = 20 + 130 * f / RIG_FPS;
}

/* World positions of the T-rig's joints at frame f (cm). */
static void rig_fk(int f, double pos[RN][3]) {
    m3 g[RN];
    for (int i = 0; i < RN; i++) {
        int p = trig[i].parent;
        m3 r = trig[i].name ? t_local(i, f) : m3_id();
        if (p < 0) {
            g[i] = r;
            root_pos(f, pos[i]);
            continue;
        }
        g[i] = m3_mul(g[p], r);
        double o[3];
        m3_apply(g[p], trig[i].off, o);
        for (int k = 0; k < 3; k++)
            pos[i][k] = pos[p][k] + o[k];
    }
}

static char *rig_bvh(int rest, int nframes) {
    size_t cap = (size_t)(16 + nframes) << 12, n = 0;
    char *s = malloc(cap);
    int stack[RN], sp = 0;
    n += (size_t)snprintf(s + n, cap - n, "HIERARCHY\n");
    for (int i = 0; i < RN; i++) {
        while (sp > 0 && stack[sp - 1] != trig[i].parent)
            n += (size_t)snprintf(s + n, cap - n, "}\n"), sp--;
        double o[3];
        rig_offset(rest, i, o);
        if (!trig[i].name)
            n += (size_t)snprintf(s + n, cap - n, "End Site\n");
        else
            n += (size_t)snprintf(s + n, cap - n, "%s %s\n", i ? "JOINT" : "ROOT", trig[i].name);
        n += (size_t)snprintf(s + n, cap - n, "{\nOFFSET %.9g %.9g %.9g\n", o[0], o[1], o[2]);
        if (i == 0)
            n += (size_t)snprintf(s + n, cap - n,
                                  "CHANNELS 6 Xposition Yposition Zposition Zrotation "
                                  "Xrotation Yrotation\n");
        else if (trig[i].name)
            n += (size_t)snprintf(s + n, cap - n, "CHANNELS 3 Zrotation Xrotation Yrotation\n");
        stack[sp++] = i;
    }
    while (sp-- > 0)
        n += (size_t)snprintf(s + n, cap - n, "}\n");
    n += (size_t)snprintf(s + n, cap - n, "MOTION\nFrames: %d\nFrame Time: %.9g\n", nframes,
                          1.0 / RIG_FPS);
    for (int f = 0; f < nframes; f++) {
        double p[3];
        root_pos(f, p);
        n += (size_t)snprintf(s + n, cap - n, "%.9g %.9g %.9g", p[0], p[1], p[2]);
        for (int i = 0; i < RN; i++) {
            if (!trig[i].name) continue;
            double e[3];
            m3_euler_zxy(rig_local(rest, i, f), e);
            n += (size_t)snprintf(s + n, cap - n, " %.9g %.9g %.9g", e[0], e[1], e[2]);
        }
        n += (size_t)snprintf(s + n, cap - n, "\n");
        CR_CHECK(n + 4096 < cap);
    }
    return s;
}

static cr_motion *load_rig(int rest, int retarget) {
    char *text = rig_bvh(rest, NF);
    cr_motion_import_def def = cr_motion_import_default_def();
    def.recenter = 0; /* the rig already faces +Z: world directions compare directly */
    def.retarget = retarget;
    cr_motion *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_motion_read_bvh_mem(text, strlen(text), "rig.bvh", &def, &m, &err), &err);
    free(text);
    return m;
}

/* Body bone (joint, child) and the rig joints at its ends. */
static const int bones[][4] = {
    {CR_JOINT_PELVIS, CR_JOINT_SPINE1, R_HIPS, R_LOWERBACK},
    {CR_JOINT_LEFT_HIP, CR_JOINT_LEFT_KNEE, R_LUPLEG, R_LLEG},
    {CR_JOINT_RIGHT_HIP, CR_JOINT_RIGHT_KNEE, R_RUPLEG, R_RLEG},
    {CR_JOINT_LEFT_KNEE, CR_JOINT_LEFT_ANKLE, R_LLEG, R_LFOOT},
    {CR_JOINT_RIGHT_KNEE, CR_JOINT_RIGHT_ANKLE, R_RLEG, R_RFOOT},
    {CR_JOINT_LEFT_ANKLE, CR_JOINT_LEFT_FOOT, R_LFOOT, R_LTOE},
    {CR_JOINT_RIGHT_ANKLE, CR_JOINT_RIGHT_FOOT, R_RFOOT, R_RTOE},
    {CR_JOINT_SPINE1, CR_JOINT_SPINE2, R_LOWERBACK, R_SPINE},
    {CR_JOINT_SPINE2, CR_JOINT_SPINE3, R_SPINE, R_SPINE1},
    {CR_JOINT_SPINE3, CR_JOINT_NECK, R_SPINE1, R_NECK},
    {CR_JOINT_NECK, CR_JOINT_HEAD, R_NECK, R_HEAD},
    {CR_JOINT_LEFT_COLLAR, CR_JOINT_LEFT_SHOULDER, R_LSHOULDER, R_LARM},
    {CR_JOINT_RIGHT_COLLAR, CR_JOINT_RIGHT_SHOULDER, R_RSHOULDER, R_RARM},
    {CR_JOINT_LEFT_SHOULDER, CR_JOINT_LEFT_ELBOW, R_LARM, R_LFOREARM},
    {CR_JOINT_RIGHT_SHOULDER, CR_JOINT_RIGHT_ELBOW, R_RARM, R_RFOREARM},
    {CR_JOINT_LEFT_ELBOW, CR_JOINT_LEFT_WRIST, R_LFOREARM, R_LHAND},
    {CR_JOINT_RIGHT_ELBOW, CR_JOINT_RIGHT_WRIST, R_RFOREARM, R_RHAND},
};
enum { NBONES = sizeof bones / sizeof bones[0] };

/* Worst angle between body and rig bones over the frames, rad; the thighs'
 * angle on the body against the rig's, and whether the knees ever cross. */
static double bone_error(const cr_motion *m, const float *joints, double *thigh_err, int *crossed) {
    double worst = 0;
    *thigh_err = 0, *crossed = 0;
    for (int f = 0; f < m->nframes; f++) {
        float pos[CR_NJOINTS * 3];
        cr_body_forward_kinematics(joints, m->poses + (size_t)f * CR_NJOINTS * 3, m->trans + 3 * f,
                                   NULL, pos);
        double rp[RN][3], body_dir[NBONES][3], rig_dir[NBONES][3];
        rig_fk(f, rp);
        for (int b = 0; b < NBONES; b++) {
            for (int k = 0; k < 3; k++) {
                body_dir[b][k] = pos[3 * bones[b][1] + k] - pos[3 * bones[b][0] + k];
                rig_dir[b][k] = rp[bones[b][3]][k] - rp[bones[b][2]][k];
            }
            worst = fmax(worst, angle3(body_dir[b], rig_dir[b]));
        }
        double tb = angle3(body_dir[1], body_dir[2]), tr = angle3(rig_dir[1], rig_dir[2]);
        *thigh_err = fmax(*thigh_err, fabs(tb - tr));
        if (pos[3 * CR_JOINT_LEFT_KNEE] <= pos[3 * CR_JOINT_RIGHT_KNEE]) *crossed = 1;
    }
    return worst;
}

CR_TEST(mocap, retargeting_follows_the_rig_bones_whatever_its_rest) {
    rig_init();
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 48;
    cr_body_model *body = NULL;
    CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
    CR_REQUIRE(body);
    const double two_deg = 2 * M_PI / 180;
    cr_motion *t = load_rig(RIG_T, 1), *a = load_rig(RIG_A, 1), *old = load_rig(RIG_T, 0);
    cr_motion *lying = load_rig(RIG_LYING, 1), *along_x = load_rig(RIG_ALONG_X, 1);
    CR_REQUIRE(t && a && old && lying && along_x);
    double thigh, worst;
    int crossed;
    worst = bone_error(t, body->joints, &thigh, &crossed);
    printf("    T-pose rig: worst bone %.3f deg, thigh angle off by %.3f deg, crossed %d\n",
           worst * 180 / M_PI, thigh * 180 / M_PI, crossed);
    CR_CHECK(worst < two_deg && thigh < two_deg && !crossed);
    worst = bone_error(a, body->joints, &thigh, &crossed);
    printf("    A-pose rig: worst bone %.3f deg, thigh angle off by %.3f deg, crossed %d\n",
           worst * 180 / M_PI, thigh * 180 / M_PI, crossed);
    CR_CHECK(worst < two_deg && thigh < two_deg && !crossed);
    /* Without retargeting (each joint taking its rig joint's world rotation)
     * the splayed rest puts the legs across each other: the check can fail. */
    worst = bone_error(old, body->joints, &thigh, &crossed);
    printf("    T-pose rig, no retargeting: worst bone %.1f deg, crossed %d\n", worst * 180 / M_PI,
           crossed);
    CR_CHECK(worst > 10 * two_deg && crossed);
    /* A bind skeleton lying along +X (the file's up, +Y, is the motion's):
     * the frames, not the rest pose, say which way is up. */
    worst = bone_error(lying, body->joints, &thigh, &crossed);
    printf("    lying rig: worst bone %.3f deg, thigh angle off by %.3f deg, crossed %d\n",
           worst * 180 / M_PI, thigh * 180 / M_PI, crossed);
    CR_CHECK(worst < two_deg && thigh < two_deg && !crossed);
    /* Every bind bone along +X (a joint-oriented export whose zero pose is
     * no pose at all): the bones still follow, the legs do not cross (the
     * pelvis matched by its hips too), and the height comes from the first
     * standing frame, so the root's path stays within 10 cm (the T rig's feet
     * are read from its splayed rest, these from a walking frame's bent knee). */
    worst = bone_error(along_x, body->joints, &thigh, &crossed);
    double path = 0;
    for (int f = 0; f < NF; f++)
        for (int k = 0; k < 3; k++)
            path = fmax(path, fabs(t->trans[3 * f + k] - along_x->trans[3 * f + k]));
    printf("    rig with every bone along +X: worst bone %.3f deg, crossed %d, root path off by "
           "%.3f m\n",
           worst * 180 / M_PI, crossed, path);
    CR_CHECK(worst < two_deg && !crossed && path < 0.1);
    /* The same body poses from every rig: every joint's world rotation, and
     * the root's path. */
    const cr_motion *other[] = {a, lying};
    for (int o = 0; o < 2; o++) {
        double pose_diff = 0, trans_diff = 0;
        for (int f = 0; f < NF; f++) {
            float rt[CR_NJOINTS * 9], ra[CR_NJOINTS * 9];
            cr_body_forward_kinematics(body->joints, t->poses + (size_t)f * CR_NJOINTS * 3, NULL,
                                       rt, NULL);
            cr_body_forward_kinematics(body->joints, other[o]->poses + (size_t)f * CR_NJOINTS * 3,
                                       NULL, ra, NULL);
            for (int j = 0; j < CR_NJOINTS; j++) {
                m3 x, y;
                for (int r = 0; r < 9; r++)
                    x.m[r / 3][r % 3] = rt[9 * j + r], y.m[r / 3][r % 3] = ra[9 * j + r];
                pose_diff = fmax(pose_diff, m3_angle(x, y));
            }
            for (int k = 0; k < 3; k++)
                trans_diff =
                    fmax(trans_diff, fabs(t->trans[3 * f + k] - other[o]->trans[3 * f + k]));
        }
        printf("    T-pose vs %s rig: body joint rotations differ by %.3f deg at most, the root's "
               "path by %.2g m\n",
               o ? "lying" : "A-pose", pose_diff * 180 / M_PI, trans_diff);
        /* the A-pose's straight legs stand its root higher at rest, which moves the path */
        CR_CHECK(pose_diff < two_deg && (o == 0 || trans_diff < 1e-3));
    }
    cr_motion_destroy(t);
    cr_motion_destroy(a);
    cr_motion_destroy(lying);
    cr_motion_destroy(along_x);
    cr_motion_destroy(old);
    cr_body_model_destroy(body);
}

/* ----------------------------------------------------------- resampling -- */

/* Joint 1 turns by a(t) = 0.8 sin(2 pi 1.5 t) about a fixed axis, the root
 * moves at 0.5 m/s: 2 s at 120 fps. */
static double sine_angle(double t) {
    return 0.8 * sin(2 * M_PI * 1.5 * t);
}

CR_TEST(mocap, resampling_matches_the_analytic_motion_and_keeps_the_duration) {
    cr_error err = {0};
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_create(240, 120.0f, &m, &err), &err);
    CR_REQUIRE(m);
    const double axis[3] = {0.6, 0.8, 0.0};
    for (int f = 0; f < 240; f++) {
        double a = sine_angle(f / 120.0);
        for (int k = 0; k < 3; k++)
            m->poses[(size_t)f * CR_NJOINTS * 3 + 3 + k] = (float)(a * axis[k]);
        m->trans[3 * f + 2] = (float)(0.5 * f / 120.0);
    }
    const float rates[2] = {30.0f, 50.0f};
    const double tol[2] = {1e-5, 1e-3}; /* 30 fps lands on samples; 50 fps slerps between */
    for (int r = 0; r < 2; r++) {
        cr_motion *s = NULL;
        CR_CHECK_OK(cr_motion_resample(m, rates[r], &s, &err), &err);
        if (!s) continue;
        CR_CHECK(s->fps == rates[r]);
        CR_CHECK_NEAR(s->nframes / s->fps, m->nframes / m->fps, 1e-6); /* 2 s either way */
        double worst = 0, worst_t = 0;
        for (int k = 0; k < s->nframes; k++) {
            double t = k / (double)rates[r], want = sine_angle(t);
            const float *aa = s->poses + (size_t)k * CR_NJOINTS * 3 + 3;
            double along = aa[0] * axis[0] + aa[1] * axis[1] + aa[2] * axis[2];
            double cx = aa[1] * axis[2] - aa[2] * axis[1], cy = aa[2] * axis[0] - aa[0] * axis[2],
                   cz = aa[0] * axis[1] - aa[1] * axis[0];
            double off = sqrt(cx * cx + cy * cy + cz * cz); /* off the axis */
            worst = fmax(worst, fabs(along - want) + off);
            worst_t = fmax(worst_t, fabs(s->trans[3 * k + 2] - 0.5 * t));
        }
        printf("    120 -> %g fps: %d frames, worst angle error %.2e rad, translation %.2e m\n",
               (double)rates[r], s->nframes, worst, worst_t);
        CR_CHECK(worst < tol[r] && worst_t < 1e-6);
        cr_motion_destroy(s);
    }
    /* 120 fps played at 30 without resampling would take 4x as long: the
     * prepared motion takes the requested rate. */
    cr_motion_prepare_def pd = cr_motion_prepare_default_def();
    pd.fps = 30.0f, pd.ease_in_s = 0.0f, pd.ground = CR_MOTION_GROUND_NONE;
    cr_motion *p = NULL;
    cr_motion_prepare_report rep;
    CR_CHECK_OK(cr_motion_prepare(m, &pd, NULL, &p, &rep, &err), &err);
    CR_CHECK(p && p->nframes == 60 && p->fps == 30.0f && rep.source_fps == 120.0f);
    cr_motion_destroy(p);
    cr_motion_destroy(m);
}

/* ------------------------------------------- ground, calibration, ease -- */

CR_TEST(mocap, feet_touch_the_ground_and_a_calibration_start_eases_in) {
    rig_init();
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 48;
    cr_body_model *body = NULL;
    CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
    CR_REQUIRE(body);
    /* The rig's walk with frame 0 replaced by its T-pose (all rotations 0),
     * the way the CMU files begin. */
    char *text = rig_bvh(RIG_T, NF);
    char *motion = strstr(text, "Frame Time:");
    CR_REQUIRE(motion);
    char *row0 = strchr(motion, '\n') + 1, *row1 = strchr(row0, '\n') + 1;
    char tpose[4096];
    int n = snprintf(tpose, sizeof tpose, "3 95 20");
    for (int i = 1; i < RN; i++)
        if (trig[i].name) n += snprintf(tpose + n, sizeof tpose - (size_t)n, " 0 0 0");
    n += snprintf(tpose + n, sizeof tpose - (size_t)n, " 0 0 0\n"); /* the root's rotation */
    size_t pre = (size_t)(row0 - text);
    char *cal = malloc(strlen(text) + sizeof tpose);
    memcpy(cal, text, pre);
    memcpy(cal + pre, tpose, (size_t)n);
    strcpy(cal + pre + n, row1);
    free(text);
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_read_bvh_mem(cal, strlen(cal), "cal.bvh", NULL, &m, &err), &err);
    free(cal);
    CR_REQUIRE(m && m->nframes == NF);
    float jump = 0;
    CR_CHECK(cr_motion_is_calibration_start(m, &jump));
    CR_CHECK(jump > 1.0f); /* the arms drop by 1.2 rad */
    /* Before grounding the rig's lowest rest joint set the height: the posed
     * feet float (splayed legs are shorter) or sink. */
    float *seq = NULL;
    CR_CHECK_OK(cr_body_pose_motion(body, m, &seq, &err), &err);
    double low0 = INFINITY;
    for (size_t i = 0; seq && i < (size_t)m->nframes * (size_t)body->rest->nv; i++)
        low0 = fmin(low0, seq[3 * i + 1]);
    free(seq);
    cr_motion_prepare_def pd = cr_motion_prepare_default_def();
    cr_motion_prepare_report rep;
    cr_motion *p = NULL;
    CR_CHECK_OK(cr_motion_prepare(m, &pd, body, &p, &rep, &err), &err);
    CR_REQUIRE(p);
    CR_CHECK(rep.calibration_dropped && rep.first_frame == 1 && rep.ease_frames == 30);
    CR_CHECK(p->nframes == 30 + NF - 1);
    /* Frame 0 is the rest pose exactly; frame 30 the first used frame. */
    for (int k = 0; k < CR_NJOINTS * 3; k++) {
        CR_CHECK(p->poses[k] == 0.0f);
        CR_CHECK(fabsf(p->poses[30 * CR_NJOINTS * 3 + k] - m->poses[CR_NJOINTS * 3 + k]) < 1e-5f);
    }
    CR_CHECK(p->trans[0] == 0.0f && p->trans[1] == 0.0f && p->trans[2] == 0.0f);
    /* Lowest body point over the clip, eased part included: on the ground. */
    CR_CHECK_OK(cr_body_pose_motion(body, p, &seq, &err), &err);
    double low = INFINITY;
    for (size_t i = 0; seq && i < (size_t)p->nframes * (size_t)body->rest->nv; i++) {
        low = fmin(low, seq[3 * i + 1]);
    }
    free(seq);
    printf("    lowest body point: %.1f cm as loaded, %.2f cm grounded (shift %.1f cm)\n",
           100 * low0, 100 * low, 100 * (double)rep.ground_shift_m);
    CR_CHECK(fabs(low) < 0.01);
    /* Smooth: no joint turns faster in the ease than the motion itself does,
     * and the step into the motion matches the motion's own first step. */
    float speed_motion = cr_motion_max_angular_speed(m, NULL); /* includes the 1.2 rad jump */
    cr_motion *used = NULL;
    CR_CHECK_OK(cr_motion_slice(m, 1, NF - 1, &used, &err), &err);
    float speed_used = used ? cr_motion_max_angular_speed(used, NULL) : 0;
    CR_CHECK(rep.max_angular_speed < 2.5f * speed_used + 1.0f);
    CR_CHECK(speed_motion > 30.0f); /* the calibration jump: 36 rad/s at 30 fps */
    double step_in = 0, step_motion = 0;
    for (int k = 0; k < CR_NJOINTS * 3; k++) {
        step_in = fmax(step_in, fabs(p->poses[30 * 66 + k] - p->poses[29 * 66 + k]));
        step_motion = fmax(step_motion, fabs(p->poses[31 * 66 + k] - p->poses[30 * 66 + k]));
    }
    printf("    speeds: %.1f rad/s with the calibration frame, %.2f used, %.2f prepared; "
           "last ease step %.4f rad vs first motion step %.4f\n",
           (double)speed_motion, (double)speed_used, (double)rep.max_angular_speed, step_in,
           step_motion);
    CR_CHECK(step_in < 1.5 * step_motion + 1e-3);
    cr_motion_destroy(used);
    cr_motion_destroy(p);
    cr_motion_destroy(m);
    cr_body_model_destroy(body);
}

/* ------------------------------------------------ one rest, speed check -- */

CR_TEST(mocap, every_format_comes_out_against_the_one_rest_and_fast_joints_are_named) {
    cr_error err = {0};
    /* An AMASS file at SMPL's T-pose (all zero poses, Z-up, no up_axis). */
    enum { T = 4 };
    static double poses[T][72], trans[T][3];
    for (int f = 0; f < T; f++)
        poses[f][0] = M_PI / 2; /* standing up in a Z-up world */
    double fps = 60;
    int64_t sp[2] = {T, 72}, st[2] = {T, 3};
    char path[512];
    snprintf(path, sizeof path, "%s/tpose_amass.npz", cr_test_tmpdir());
    cr_npz_writer *w = NULL;
    CR_CHECK_OK(cr_npz_writer_open(path, 0, &w, &err), &err);
    CR_REQUIRE(w);
    CR_CHECK_OK(cr_npz_writer_add(w, "poses", CR_NPY_F64, 2, sp, poses, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(w, "trans", CR_NPY_F64, 2, st, trans, &err), &err);
    CR_CHECK_OK(cr_npz_writer_add(w, "mocap_framerate", CR_NPY_F64, 0, NULL, &fps, &err), &err);
    CR_CHECK_OK(cr_npz_writer_commit(w, &err), &err);
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_load(path, &m, &err), &err);
    CR_REQUIRE(m);
    /* Against the A-pose, SMPL's T-pose is each arm raised 40 degrees about Z. */
    double a = cr_mannequin_default_def().arm_angle_deg * M_PI / 180;
    const float *ls = m->poses + 3 * CR_JOINT_LEFT_SHOULDER,
                *rs = m->poses + 3 * CR_JOINT_RIGHT_SHOULDER;
    CR_CHECK_NEAR(ls[2], a, 1e-5);
    CR_CHECK_NEAR(rs[2], -a, 1e-5);
    CR_CHECK(fabsf(ls[0]) < 1e-6f && fabsf(ls[1]) < 1e-6f);
    cr_motion_destroy(m);
    /* A glitch: the left elbow turns 1.5 rad in one frame at 30 fps (45 rad/s). */
    CR_CHECK_OK(cr_motion_create(20, 30.0f, &m, &err), &err);
    CR_REQUIRE(m);
    for (int f = 10; f < 20; f++)
        m->poses[(size_t)f * CR_NJOINTS * 3 + 3 * CR_JOINT_LEFT_ELBOW + 1] = 1.5f;
    cr_motion_prepare_def pd = cr_motion_prepare_default_def();
    pd.ease_in_s = 0, pd.ground = CR_MOTION_GROUND_NONE;
    cr_motion_prepare_report rep;
    cr_motion *p = NULL;
    CR_CHECK_OK(cr_motion_prepare(m, &pd, NULL, &p, &rep, &err), &err);
    CR_CHECK(p && rep.max_speed_joint == CR_JOINT_LEFT_ELBOW && rep.max_speed_frame == 10);
    CR_CHECK_NEAR(rep.max_angular_speed, 45.0, 1e-3);
    CR_CHECK(!rep.calibration_dropped); /* the jump is not at frame 0 */
    cr_motion_destroy(p);
    /* Frames out of range are refused, naming the range. */
    pd.start_frame = 25;
    CR_CHECK(cr_motion_prepare(m, &pd, NULL, &p, &rep, &err) == CR_ERR_RANGE && !p);
    CR_CHECK(strstr(err.msg, "frames 0 to 19") != NULL);
    cr_motion_destroy(m);
}
