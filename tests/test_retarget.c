/* test_retarget.c: a BVH retargeted onto an arbitrary skinned character
 * (cr_motion_retarget_bvh, src/body/retarget.c) gives the same bone
 * directions as the same BVH retargeted onto crease's mannequin
 * (cr_motion_read_bvh_mem), for a character with Mixamo joint names and
 * other proportions written by crease's own skinned writer, for one with
 * Unreal names under a root joint, and for one with meaningless names mapped
 * by a joint map file (text or JSON); the name tables give every common
 * convention's joints their roles; bad map lines, a character without a skin
 * and one whose hips nothing drives are refused by name. */
#include "body/retarget_internal.h"
#include "crease/body.h"
#include "crease/dataset.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Paths under the test's folder, one buffer per name: they stay valid. */
static const char *tmp(const char *name) {
    enum { SLOTS = 16 };
    static char path[SLOTS][512];
    for (int k = 0; k < SLOTS; k++) {
        const size_t n = strlen(cr_test_tmpdir());
        if (path[k][0] && !strcmp(path[k] + n + 1, name)) return path[k];
        if (!path[k][0]) {
            snprintf(path[k], sizeof path[k], "%s/%s", cr_test_tmpdir(), name);
            return path[k];
        }
    }
    CR_CHECK(!"tmp: out of slots");
    return path[0];
}

/* ---------------------------------------------------------- the BVH -- */

/* A CMU-named rig in a T-pose, centimetres, with folded joints (LHipJoint,
 * Neck1) the mannequin lacks. */
enum { NB = 26, NF = 10 };
static const char *const bvh_name[NB] = {
    "Hips",      "LHipJoint",   "LeftUpLeg", "LeftLeg",       "LeftFoot",     "LeftToeBase",
    "RHipJoint", "RightUpLeg",  "RightLeg",  "RightFoot",     "RightToeBase", "LowerBack",
    "Spine",     "Spine1",      "Neck",      "Neck1",         "Head",         "LeftShoulder",
    "LeftArm",   "LeftForeArm", "LeftHand",  "RightShoulder", "RightArm",     "RightForeArm",
    "RightHand", "HeadTop"};
static const int bvh_parent[NB] = {-1, 0,  1,  2,  3,  4,  0,  6,  7,  8,  9,  0,  11,
                                   12, 13, 14, 15, 13, 17, 18, 19, 13, 21, 22, 23, 16};
static const double bvh_off[NB][3] = {
    {0, 95, 0},  {5, -5, 0},  {4, -5, 0},  {0, -42, 0}, {0, -40, 0}, {0, -6, 12}, {-5, -5, 0},
    {-4, -5, 0}, {0, -42, 0}, {0, -40, 0}, {0, -6, 12}, {0, 6, 0},   {0, 10, 0},  {0, 10, 0},
    {0, 15, 0},  {0, 5, 0},   {0, 8, 0},   {3, 12, 0},  {15, 0, 0},  {28, 0, 0},  {25, 0, 0},
    {-3, 12, 0}, {-15, 0, 0}, {-28, 0, 0}, {-25, 0, 0}, {0, 12, 0}};

/* Euler angles (Z X Y, degrees) of joint i at frame f: a swing of legs,
 * arms (brought down from the T-pose), spine and head. */
static void bvh_angles(int i, int f, double e[3]) {
    const double s = sin(0.6 * f), c = cos(0.4 * f);
    e[0] = e[1] = e[2] = 0.0;
    switch (i) {
    case 0:
        e[2] = 10 * s;
        break; /* Hips: yaw */
    case 2:
        e[1] = 30 * s, e[0] = 5 * c;
        break; /* LeftUpLeg */
    case 3:
        e[1] = 35 + 25 * c;
        break; /* LeftLeg */
    case 7:
        e[1] = -30 * s, e[0] = -5 * c;
        break; /* RightUpLeg */
    case 8:
        e[1] = 35 - 25 * c;
        break; /* RightLeg */
    case 12:
        e[1] = 8 * c, e[2] = 6 * s;
        break; /* Spine */
    case 15:
        e[1] = 15 * s;
        break; /* Neck1 (folded) */
    case 18:
        e[0] = -70 + 10 * s, e[1] = 20 * c;
        break; /* LeftArm down, swinging */
    case 19:
        e[2] = 30 + 20 * s;
        break; /* LeftForeArm */
    case 22:
        e[0] = 70 - 10 * s, e[1] = -20 * c;
        break; /* RightArm */
    case 23:
        e[2] = -30 - 20 * c;
        break; /* RightForeArm */
    default:
        break;
    }
}

/* Joints in depth-first order from i into order[*n]. */
static void dfs(int i, int *order, int *n) {
    order[(*n)++] = i;
    for (int c = 0; c < NB; c++)
        if (bvh_parent[c] == i) dfs(c, order, n);
}

static char *make_bvh(void) {
    size_t cap = 1 << 16, n = 0;
    char *s = malloc(cap);
    int order[NB], no = 0, stack[NB], sp = 0;
    dfs(0, order, &no);
    n += (size_t)snprintf(s + n, cap - n, "HIERARCHY\n");
    for (int o = 0; o < NB; o++) {
        const int i = order[o];
        while (sp > 0 && stack[sp - 1] != bvh_parent[i])
            n += (size_t)snprintf(s + n, cap - n, "}\n"), sp--;
        n += (size_t)snprintf(s + n, cap - n, "%s %s\n{\nOFFSET %g %g %g\n", i ? "JOINT" : "ROOT",
                              bvh_name[i], bvh_off[i][0], bvh_off[i][1], bvh_off[i][2]);
        n += (size_t)snprintf(s + n, cap - n, "CHANNELS %s Zrotation Xrotation Yrotation\n",
                              i ? "3" : "6 Xposition Yposition Zposition");
        stack[sp++] = i;
    }
    while (sp-- > 0)
        n += (size_t)snprintf(s + n, cap - n, "}\n");
    n += (size_t)snprintf(s + n, cap - n, "MOTION\nFrames: %d\nFrame Time: 0.0333333\n", NF);
    for (int f = 0; f < NF; f++) {
        n += (size_t)snprintf(s + n, cap - n, "%g 95 %g", 2.0 * f, 0.5 * f);
        for (int o = 0; o < NB; o++) {
            double e[3];
            bvh_angles(order[o], f, e);
            n += (size_t)snprintf(s + n, cap - n, " %g %g %g", e[0], e[1], e[2]);
        }
        n += (size_t)snprintf(s + n, cap - n, "\n");
    }
    return s;
}

/* ---------------------------------------------------- the character -- */

static const char *const mixamo[CR_NJOINTS] = {
    "mixamorig:Hips",        "mixamorig:LeftUpLeg",    "mixamorig:RightUpLeg",
    "mixamorig:Spine",       "mixamorig:LeftLeg",      "mixamorig:RightLeg",
    "mixamorig:Spine1",      "mixamorig:LeftFoot",     "mixamorig:RightFoot",
    "mixamorig:Spine2",      "mixamorig:LeftToeBase",  "mixamorig:RightToeBase",
    "mixamorig:Neck",        "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
    "mixamorig:Head",        "mixamorig:LeftArm",      "mixamorig:RightArm",
    "mixamorig:LeftForeArm", "mixamorig:RightForeArm", "mixamorig:LeftHand",
    "mixamorig:RightHand"};

/* Bone scale per joint (its offset from its parent): longer legs, shorter
 * arms, a longer spine than the mannequin's. */
static double bone_scale(int j) {
    switch (j) {
    case CR_JOINT_LEFT_KNEE:
    case CR_JOINT_RIGHT_KNEE:
    case CR_JOINT_LEFT_ANKLE:
    case CR_JOINT_RIGHT_ANKLE:
        return 1.15;
    case CR_JOINT_LEFT_ELBOW:
    case CR_JOINT_RIGHT_ELBOW:
    case CR_JOINT_LEFT_WRIST:
    case CR_JOINT_RIGHT_WRIST:
        return 0.85;
    case CR_JOINT_SPINE2:
    case CR_JOINT_SPINE3:
    case CR_JOINT_NECK:
        return 1.25;
    default:
        return 1.0;
    }
}

/* The mannequin written as a character by crease's skinned writer: its 22
 * joints named by `names` (NULL: Mixamo's), bones scaled by bone_scale when
 * `scaled` (the mesh keeps its shape), plus an end joint 0.15 m above the
 * head that no name table knows. */
/* Meaningless joint names, "bone00" to "bone21" in SMPL's order. */
static const char *const *bone_names(void) {
    static const char *bone[CR_NJOINTS];
    static char storage[CR_NJOINTS][16];
    for (int j = 0; j < CR_NJOINTS; j++) {
        snprintf(storage[j], sizeof storage[j], "bone%02d", j);
        bone[j] = storage[j];
    }
    return bone;
}

static void write_character(const cr_body_model *b, const char *path, const char *const *names,
                            int scaled) {
    enum { J = CR_NJOINTS + 1 };
    const char *nm[J];
    int32_t parent[J];
    float rest[J * 3];
    for (int j = 0; j < CR_NJOINTS; j++) {
        nm[j] = names ? names[j] : mixamo[j];
        parent[j] = cr_joint_parent[j];
        for (int k = 0; k < 3; k++) {
            const int p = parent[j];
            const double off = b->joints[3 * j + k] - (p >= 0 ? b->joints[3 * p + k] : 0.0f);
            rest[3 * j + k] =
                (float)(p >= 0 ? rest[3 * p + k] + (scaled ? bone_scale(j) : 1.0) * off : off);
        }
    }
    nm[CR_NJOINTS] = names ? "bone_top" : "mixamorig:HeadTop_End";
    parent[CR_NJOINTS] = CR_JOINT_HEAD;
    for (int k = 0; k < 3; k++)
        rest[3 * CR_NJOINTS + k] = rest[3 * CR_JOINT_HEAD + k] + (k == 1 ? 0.15f : 0.0f);
    float rot[J * 4] = {0}, tr[3] = {0};
    for (int j = 0; j < J; j++)
        rot[4 * j + 3] = 1.0f;
    const cr_glb_skin skin = {J, nm, parent, rest, b->skin_joint, b->skin_weight};
    const cr_glb_skin_motion still = {1, 30.0f, rot, tr};
    cr_error err = {0};
    CR_CHECK_OK(cr_glb_write_skinned(path, b->rest, &skin, &still, NULL, &err), &err);
}

static const char *const unreal[CR_NJOINTS] = {
    "pelvis",     "thigh_l",    "thigh_r",    "spine_01", "calf_l",     "calf_r",
    "spine_02",   "foot_l",     "foot_r",     "spine_03", "ball_l",     "ball_r",
    "neck_01",    "clavicle_l", "clavicle_r", "head",     "upperarm_l", "upperarm_r",
    "lowerarm_l", "lowerarm_r", "hand_l",     "hand_r"};

/* The mannequin as an Unreal-style character: a "root" joint on the floor
 * under the pelvis (driven by nothing) above SMPL's 22 joints. */
static void write_rooted_character(const cr_body_model *b, const char *path) {
    enum { J = CR_NJOINTS + 1 };
    const char *nm[J] = {"root"};
    int32_t parent[J] = {-1};
    float rest[J * 3] = {b->joints[0], 0.0f, b->joints[2]};
    for (int j = 0; j < CR_NJOINTS; j++) {
        nm[1 + j] = unreal[j];
        parent[1 + j] = 1 + cr_joint_parent[j];
        memcpy(rest + 3 * (1 + j), b->joints + 3 * j, 3 * sizeof(float));
    }
    const int64_t nv = b->rest->nv;
    int32_t *sj = malloc((size_t)nv * 4 * sizeof(int32_t));
    CR_REQUIRE(sj);
    for (int64_t i = 0; i < 4 * nv; i++)
        sj[i] = 1 + b->skin_joint[i];
    float rot[J * 4] = {0}, tr[3] = {0};
    for (int j = 0; j < J; j++)
        rot[4 * j + 3] = 1.0f;
    const cr_glb_skin skin = {J, nm, parent, rest, sj, b->skin_weight};
    const cr_glb_skin_motion still = {1, 30.0f, rot, tr};
    cr_error err = {0};
    CR_CHECK_OK(cr_glb_write_skinned(path, b->rest, &skin, &still, NULL, &err), &err);
    free(sj);
}

/* -------------------------------------------------------- comparing -- */

/* World positions (J,3) of a skin motion's frame f on skeleton s. */
static void skin_fk(const cr_glb_skin *s, const cr_skin_motion *m, int32_t f, double *pos) {
    double g[CR_GLB_MAX_JOINTS][4];
    for (int j = 0; j < s->njoints; j++) {
        const float *q = m->rotation + 4 * ((size_t)f * s->njoints + j);
        const double l[4] = {q[3], q[0], q[1], q[2]}; /* w, x, y, z */
        const int p = s->parent[j];
        double d[3];
        for (int k = 0; k < 3; k++)
            d[k] = s->rest_joint[3 * j + k] - (p >= 0 ? s->rest_joint[3 * p + k] : 0.0);
        if (p < 0) {
            memcpy(g[j], l, sizeof l);
            for (int k = 0; k < 3; k++)
                pos[3 * j + k] = d[k] + m->translation[3 * f + k];
            continue;
        }
        const double *a = g[p];
        g[j][0] = a[0] * l[0] - a[1] * l[1] - a[2] * l[2] - a[3] * l[3];
        g[j][1] = a[0] * l[1] + a[1] * l[0] + a[2] * l[3] - a[3] * l[2];
        g[j][2] = a[0] * l[2] - a[1] * l[3] + a[2] * l[0] + a[3] * l[1];
        g[j][3] = a[0] * l[3] + a[1] * l[2] - a[2] * l[1] + a[3] * l[0];
        /* d rotated by a: v + 2 w (u x v) + 2 u x (u x v) */
        double u[3] = {a[1], a[2], a[3]}, t[3], r[3];
        t[0] = 2 * (u[1] * d[2] - u[2] * d[1]), t[1] = 2 * (u[2] * d[0] - u[0] * d[2]);
        t[2] = 2 * (u[0] * d[1] - u[1] * d[0]);
        r[0] = d[0] + a[0] * t[0] + (u[1] * t[2] - u[2] * t[1]);
        r[1] = d[1] + a[0] * t[1] + (u[2] * t[0] - u[0] * t[2]);
        r[2] = d[2] + a[0] * t[2] + (u[0] * t[1] - u[1] * t[0]);
        for (int k = 0; k < 3; k++)
            pos[3 * j + k] = pos[3 * p + k] + r[k];
    }
}

static double angle3(const double *a, const double *b) {
    double d = 0, na = 0, nb = 0;
    for (int k = 0; k < 3; k++)
        d += a[k] * b[k], na += a[k] * a[k], nb += b[k] * b[k];
    double c = d / sqrt(na * nb);
    return acos(c > 1 ? 1 : c < -1 ? -1 : c);
}

/* Bones as SMPL joint pairs (joint, the joint its bone runs to). */
static const int bones[][2] = {{0, 3},   {1, 4},   {2, 5},   {4, 7},   {5, 8},   {7, 10},
                               {8, 11},  {3, 6},   {6, 9},   {9, 12},  {12, 15}, {13, 16},
                               {14, 17}, {16, 18}, {17, 19}, {18, 20}, {19, 21}};
enum { NBONES = sizeof bones / sizeof bones[0] };

/* Worst angle, rad, between the mannequin's bones under m and the
 * character's under sm, over frames; *moved the largest bone turn from
 * rest (so the comparison is not vacuous). index[j]: the character joint
 * of SMPL joint j. */
static double worst_bone_angle(const cr_body_model *b, const cr_motion *m,
                               const cr_glb_character *c, const cr_skin_motion *sm,
                               const int *index, double *moved) {
    double worst = 0.0;
    *moved = 0.0;
    double *cp = malloc((size_t)c->skin.njoints * 3 * sizeof(double));
    for (int32_t f = 0; f < m->nframes; f++) {
        float pos[CR_NJOINTS * 3];
        cr_body_forward_kinematics(b->joints, m->poses + (size_t)f * CR_NJOINTS * 3,
                                   m->trans + 3 * f, NULL, pos);
        skin_fk(&c->skin, sm, f, cp);
        for (int i = 0; i < NBONES; i++) {
            const int a = bones[i][0], e = bones[i][1];
            double dm[3], dc[3], d0[3];
            for (int k = 0; k < 3; k++) {
                dm[k] = (double)pos[3 * e + k] - pos[3 * a + k];
                dc[k] = cp[3 * index[e] + k] - cp[3 * index[a] + k];
                d0[k] = (double)c->skin.rest_joint[3 * index[e] + k] -
                        c->skin.rest_joint[3 * index[a] + k];
            }
            worst = fmax(worst, angle3(dm, dc));
            *moved = fmax(*moved, angle3(d0, dc));
        }
    }
    free(cp);
    return worst;
}

static int find_joint(const cr_glb_skin *s, const char *name) {
    for (int j = 0; j < s->njoints; j++)
        if (!strcmp(s->joint_name[j], name)) return j;
    return -1;
}

static void write_text(const char *path, const char *text) {
    FILE *fp = fopen(path, "w");
    CR_REQUIRE(fp);
    fputs(text, fp);
    fclose(fp);
}

/* The default mannequin at a coarse grid (48 cells over the height): what
 * every test here writes as a character. NULL (the failure reported) when
 * it cannot be built. */
static cr_body_model *small_mannequin(void) {
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 48;
    cr_body_model *b = NULL;
    CR_CHECK_OK(cr_mannequin_create(&md, &b, &err), &err);
    return b;
}

/* The mannequin T-posed: its shoulders raised 40 degrees, the mesh skinned there (a clone,
 * NULL with the failure reported) and the joints posed into tj. */
static cr_mesh *tposed(const cr_body_model *b, float tj[CR_NJOINTS * 3]) {
    cr_error err = {0};
    float pose[CR_NJOINTS * 3] = {0};
    pose[3 * CR_JOINT_LEFT_SHOULDER + 2] = (float)(40 * M_PI / 180);
    pose[3 * CR_JOINT_RIGHT_SHOULDER + 2] = (float)(-40 * M_PI / 180);
    cr_mesh *tm = NULL;
    CR_CHECK_OK(cr_mesh_clone(b->rest, &tm, &err), &err);
    if (!tm) return NULL;
    CR_CHECK_OK(cr_body_pose(b, pose, NULL, tm->pos, &err), &err);
    cr_body_forward_kinematics(b->joints, pose, NULL, NULL, tj);
    return tm;
}

/* ------------------------------------------------------------ tests -- */

CR_TEST(retarget, renamed_rescaled_character_follows_the_mannequins_bone_directions) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin();
    CR_REQUIRE(b);
    /* the mannequin's rest joints, as the BVH loader's target has them */
    const char *glb = tmp("mixamo.glb");
    write_character(b, glb, NULL, 1);
    cr_glb_character *c = NULL;
    CR_CHECK_OK(cr_glb_read_character(glb, &c, &err), &err);
    CR_REQUIRE(c);
    CR_CHECK(c->skin.njoints == CR_NJOINTS + 1 && c->rest->nv == b->rest->nv);
    int index[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++) {
        index[j] = find_joint(&c->skin, mixamo[j]);
        CR_REQUIRE(index[j] >= 0);
    }
    char *text = make_bvh();
    cr_motion_import_def id = cr_motion_import_default_def();
    id.bvh_scale = 0.01f;
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_read_bvh_mem(text, strlen(text), "walk.bvh", &id, &m, &err), &err);
    cr_retarget_def rd = cr_retarget_default_def();
    rd.import = id;
    cr_skin_motion *sm = NULL;
    CR_CHECK_OK(
        cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm, &err),
        &err);
    CR_REQUIRE(m && sm);
    CR_CHECK(sm->nframes == NF && sm->fps == 30.0f && sm->njoints == c->skin.njoints);
    /* the mannequin's rest joints sit where cr_mannequin_rest_joints puts
     * them up to scale; directions are what the two must share */
    double moved = 0.0;
    const double worst = worst_bone_angle(b, m, c, sm, index, &moved);
    printf("    Mixamo names, legs x1.15, arms x0.85, spine x1.25: bones off the mannequin's by "
           "%.2e deg at most over %d bones x %d frames (they turn up to %.0f deg from rest)\n",
           worst * 180 / M_PI, NBONES, NF, moved * 180 / M_PI);
    CR_CHECK(worst < 0.1 * M_PI / 180);
    CR_CHECK(moved > 30 * M_PI / 180);
    /* the unmapped end joint keeps its rest offset from the head */
    double *cp = malloc((size_t)c->skin.njoints * 3 * sizeof(double));
    skin_fk(&c->skin, sm, NF - 1, cp);
    const int top = find_joint(&c->skin, "mixamorig:HeadTop_End");
    CR_REQUIRE(top >= 0);
    double len = 0.0;
    for (int k = 0; k < 3; k++)
        len += pow(cp[3 * top + k] - cp[3 * index[CR_JOINT_HEAD] + k], 2);
    CR_CHECK_NEAR(sqrt(len), 0.15, 1e-5);
    /* posing the mesh: frame 0's pelvis vertex cloud moves with the pelvis */
    float *frames = NULL;
    const cr_glb_skin_motion view = cr_skin_motion_view(sm);
    CR_CHECK_OK(cr_glb_character_pose(c, &view, &frames, &err), &err);
    CR_REQUIRE(frames);
    double worst_skin = 0.0;
    for (int64_t i = 0; i < (int64_t)NF * c->rest->nv * 3; i++)
        if (!isfinite(frames[i])) worst_skin = INFINITY;
    CR_CHECK(isfinite(worst_skin));
    free(frames);
    free(cp);
    cr_skin_motion_destroy(sm);
    cr_motion_destroy(m);
    cr_glb_character_destroy(c);
    cr_body_model_destroy(b);
    free(text);
}

CR_TEST(retarget, joint_map_file_drives_meaningless_names_and_bad_lines_are_refused) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin();
    CR_REQUIRE(b);
    const char *const *bone = bone_names();
    const char *glb = tmp("bones.glb");
    write_character(b, glb, bone, 0);
    cr_glb_character *c = NULL;
    CR_CHECK_OK(cr_glb_read_character(glb, &c, &err), &err);
    CR_REQUIRE(c);
    char *text = make_bvh();
    cr_retarget_def rd = cr_retarget_default_def();
    rd.import.bvh_scale = 0.01f;
    cr_skin_motion *sm = NULL;
    /* no names known and no map: the hips are driven by nothing */
    CR_CHECK(cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm,
                                        &err) == CR_ERR_UNSUPPORTED);
    printf("    no map: %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "bones.glb") && strstr(err.msg, "hips") && !sm);
    /* a map naming the CMU joints (LeftShoulder is SMPL's collar) */
    static const char *const cmu[CR_NJOINTS] = {
        "Hips",        "LeftUpLeg",    "RightUpLeg",    "LowerBack", "LeftLeg",     "RightLeg",
        "Spine",       "LeftFoot",     "RightFoot",     "Spine1",    "LeftToeBase", "RightToeBase",
        "Neck",        "LeftShoulder", "RightShoulder", "Head",      "LeftArm",     "RightArm",
        "LeftForeArm", "RightForeArm", "LeftHand",      "RightHand"};
    char map[2048];
    int n = snprintf(map, sizeof map, "# bones to CMU\n\n");
    for (int j = 0; j < CR_NJOINTS; j++)
        n += snprintf(map + n, sizeof map - (size_t)n, "%s = %s   # SMPL %s\n", bone[j], cmu[j],
                      cr_joint_name[j]);
    const char *good = tmp("good_map.txt");
    write_text(good, map);
    rd.joint_map = good;
    CR_CHECK_OK(
        cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm, &err),
        &err);
    cr_motion_import_def id = rd.import;
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_motion_read_bvh_mem(text, strlen(text), "walk.bvh", &id, &m, &err), &err);
    CR_REQUIRE(m && sm);
    int index[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++)
        index[j] = find_joint(&c->skin, bone[j]);
    double moved = 0.0;
    const double worst = worst_bone_angle(b, m, c, sm, index, &moved);
    printf("    joint map file: bones off the mannequin's by %.2e deg at most (turning up to "
           "%.0f deg)\n",
           worst * 180 / M_PI, moved * 180 / M_PI);
    CR_CHECK(worst < 0.1 * M_PI / 180 && moved > 30 * M_PI / 180);
    /* the pelvis's path is the mannequin's (the BVH's, m) scaled by the hip
     * heights: the character's pelvis over its lowest joint, the rig's 0.98 m */
    double lowest = INFINITY, path_err = 0.0, travel = 0.0;
    for (int j = 0; j < c->skin.njoints; j++)
        lowest = fmin(lowest, c->skin.rest_joint[3 * j + 1]);
    const int pel = index[CR_JOINT_PELVIS];
    const double ratio = (c->skin.rest_joint[3 * pel + 1] - lowest) / 0.98;
    double *cp = malloc((size_t)c->skin.njoints * 3 * sizeof(double));
    for (int32_t f = 0; f < NF; f++) {
        skin_fk(&c->skin, sm, f, cp);
        for (int k = 0; k < 3; k++) {
            const double d = cp[3 * pel + k] - c->skin.rest_joint[3 * pel + k];
            path_err = fmax(path_err, fabs(d - ratio * m->trans[3 * f + k]));
            travel = fmax(travel, fabs(d));
        }
    }
    printf("    pelvis path: %.2e m off the BVH's scaled by %.3f (it travels %.3f m)\n", path_err,
           ratio, travel);
    CR_CHECK(path_err < 1e-5 && travel > 0.1);
    free(cp);
    cr_skin_motion_destroy(sm);
    sm = NULL;
    /* the same map as JSON drives the same bones */
    n = snprintf(map, sizeof map, "{\n");
    for (int j = 0; j < CR_NJOINTS; j++)
        n += snprintf(map + n, sizeof map - (size_t)n, "  \"%s\": \"%s\",\n", bone[j], cmu[j]);
    snprintf(map + n, sizeof map - (size_t)n, "  \"bone_top\": null\n}\n");
    const char *json = tmp("map.json");
    write_text(json, map);
    rd.joint_map = json;
    CR_CHECK_OK(
        cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm, &err),
        &err);
    CR_REQUIRE(sm);
    const double worst_json = worst_bone_angle(b, m, c, sm, index, &moved);
    CR_CHECK(worst_json < 0.1 * M_PI / 180);
    cr_skin_motion_destroy(sm);
    sm = NULL;
    /* bad lines: the file and line named */
    static const struct {
        const char *text, *want;
    } bad[] = {{"bone00 = Hips\nbone01 LeftUpLeg\n", "bad_map.txt:2: expected"},
               {"# c\nbone99 = Hips\n", "bad_map.txt:2: the character"},
               {"bone00 = Hips\n\nbone03 = Pelvis\n", "bad_map.txt:3: the motion walk.bvh has no "
                                                      "joint 'Pelvis'"},
               {"{\n  \"bone00\": \"Hips\",\n  \"bone77\": \"Spine\"\n}\n",
                "bad_map.txt:3: the character"},
               {"{\n  \"bone00\": \"Hips\",\n  \"bone01\" \"LeftUpLeg\"\n}\n",
                "bad_map.txt:3: expected a JSON object"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *path = tmp("bad_map.txt");
        write_text(path, bad[i].text);
        rd.joint_map = path;
        err = (cr_error){0};
        CR_CHECK(cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm,
                                            &err) == CR_ERR_PARSE);
        printf("    %s\n", err.msg);
        CR_CHECK(strstr(err.msg, bad[i].want) != NULL && !sm);
    }
    /* a glb without a skin is no character */
    const char *plain = tmp("plain.glb");
    CR_CHECK_OK(cr_glb_write(plain, b->rest, &err), &err);
    cr_glb_character *none = NULL;
    CR_CHECK(cr_glb_read_character(plain, &none, &err) == CR_ERR_UNSUPPORTED && !none);
    printf("    %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "plain.glb") && strstr(err.msg, "no skin"));
    cr_motion_destroy(m);
    cr_glb_character_destroy(c);
    cr_body_model_destroy(b);
    free(text);
}

/* Unreal names with a root joint on the floor above the pelvis: the root
 * is driven by nothing, and its translation is chosen so the pelvis follows
 * the BVH's path (scaled by the hip heights) all the same, turning with the
 * recentred heading. */
CR_TEST(retarget, root_joint_above_the_pelvis_unreal_names) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin();
    CR_REQUIRE(b);
    const char *glb = tmp("unreal.glb");
    write_rooted_character(b, glb);
    cr_glb_character *c = NULL;
    CR_CHECK_OK(cr_glb_read_character(glb, &c, &err), &err);
    CR_REQUIRE(c);
    int index[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++) {
        index[j] = find_joint(&c->skin, unreal[j]);
        CR_REQUIRE(index[j] >= 0);
    }
    CR_CHECK(c->skin.parent[index[CR_JOINT_PELVIS]] == find_joint(&c->skin, "root"));
    char *text = make_bvh();
    cr_retarget_def rd = cr_retarget_default_def();
    rd.import.bvh_scale = 0.01f;
    cr_skin_motion *sm = NULL;
    cr_motion *m = NULL;
    CR_CHECK_OK(
        cr_motion_retarget_bvh_mem(text, strlen(text), "walk.bvh", &c->skin, glb, &rd, &sm, &err),
        &err);
    CR_CHECK_OK(cr_motion_read_bvh_mem(text, strlen(text), "walk.bvh", &rd.import, &m, &err), &err);
    CR_REQUIRE(m && sm);
    double moved = 0.0;
    const double worst = worst_bone_angle(b, m, c, sm, index, &moved);
    double lowest = INFINITY, path_err = 0.0;
    for (int j = 0; j < c->skin.njoints; j++)
        lowest = fmin(lowest, c->skin.rest_joint[3 * j + 1]);
    const int pel = index[CR_JOINT_PELVIS];
    const double ratio = (c->skin.rest_joint[3 * pel + 1] - lowest) / 0.98;
    double *cp = malloc((size_t)c->skin.njoints * 3 * sizeof(double));
    for (int32_t f = 0; f < NF; f++) {
        skin_fk(&c->skin, sm, f, cp);
        for (int k = 0; k < 3; k++)
            path_err = fmax(path_err, fabs(cp[3 * pel + k] - c->skin.rest_joint[3 * pel + k] -
                                           ratio * m->trans[3 * f + k]));
    }
    printf("    Unreal names under a root joint: bones off the mannequin's by %.2e deg, pelvis "
           "path off the BVH's (x %.3f) by %.2e m\n",
           worst * 180 / M_PI, ratio, path_err);
    CR_CHECK(worst < 0.1 * M_PI / 180 && moved > 30 * M_PI / 180);
    CR_CHECK(path_err < 1e-5);
    free(cp);
    cr_skin_motion_destroy(sm);
    cr_motion_destroy(m);
    cr_glb_character_destroy(c);
    cr_body_model_destroy(b);
    free(text);
}

/* The name tables: each convention's names give SMPL's 22 roles, with the
 * words that differ between conventions (Mixamo's LeftShoulder is the
 * collar, SMPL's left_shoulder the upper arm) read by the table that wins. */
CR_TEST(retarget, name_tables_cover_the_common_conventions) {
    static const struct {
        const char *rig;
        const char *names[CR_NJOINTS];
    } sets[] = {
        {"SMPL", {"Pelvis",  "L_Hip",    "R_Hip",    "Spine1", "L_Knee",     "R_Knee",
                  "Spine2",  "L_Ankle",  "R_Ankle",  "Spine3", "L_Foot",     "R_Foot",
                  "Neck",    "L_Collar", "R_Collar", "Head",   "L_Shoulder", "R_Shoulder",
                  "L_Elbow", "R_Elbow",  "L_Wrist",  "R_Wrist"}},
        {"SMPL", {"m_avg_Pelvis", "left_hip",      "right_hip",      "spine1",      "left_knee",
                  "right_knee",   "spine2",        "left_ankle",     "right_ankle", "spine3",
                  "left_foot",    "right_foot",    "neck",           "left_collar", "right_collar",
                  "head",         "left_shoulder", "right_shoulder", "left_elbow",  "right_elbow",
                  "left_wrist",   "right_wrist"}},
        {"Mixamo", {"mixamorig:Hips",        "mixamorig:LeftUpLeg",    "mixamorig:RightUpLeg",
                    "mixamorig:Spine",       "mixamorig:LeftLeg",      "mixamorig:RightLeg",
                    "mixamorig:Spine1",      "mixamorig:LeftFoot",     "mixamorig:RightFoot",
                    "mixamorig:Spine2",      "mixamorig:LeftToeBase",  "mixamorig:RightToeBase",
                    "mixamorig:Neck",        "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
                    "mixamorig:Head",        "mixamorig:LeftArm",      "mixamorig:RightArm",
                    "mixamorig:LeftForeArm", "mixamorig:RightForeArm", "mixamorig:LeftHand",
                    "mixamorig:RightHand"}},
        {"Unreal",
         {"pelvis",     "thigh_l",    "thigh_r",    "spine_01", "calf_l",     "calf_r",
          "spine_02",   "foot_l",     "foot_r",     "spine_03", "ball_l",     "ball_r",
          "neck_01",    "clavicle_l", "clavicle_r", "head",     "upperarm_l", "upperarm_r",
          "lowerarm_l", "lowerarm_r", "hand_l",     "hand_r"}},
        {"Blender/Rigify",
         {"spine",     "thigh.L",    "thigh.R",    "spine.001", "shin.L",      "shin.R",
          "spine.002", "foot.L",     "foot.R",     "spine.003", "toe.L",       "toe.R",
          "spine.004", "shoulder.L", "shoulder.R", "spine.006", "upper_arm.L", "upper_arm.R",
          "forearm.L", "forearm.R",  "hand.L",     "hand.R"}},
        {"Blender/Rigify",
         {"DEF-spine",     "DEF-thigh.L",     "DEF-thigh.R",     "DEF-spine.001",  "DEF-shin.L",
          "DEF-shin.R",    "DEF-spine.002",   "DEF-foot.L",      "DEF-foot.R",     "DEF-spine.003",
          "DEF-toe.L",     "DEF-toe.R",       "DEF-spine.004",   "DEF-shoulder.L", "DEF-shoulder.R",
          "DEF-spine.006", "DEF-upper_arm.L", "DEF-upper_arm.R", "DEF-forearm.L",  "DEF-forearm.R",
          "DEF-hand.L",    "DEF-hand.R"}},
    };
    for (size_t i = 0; i < sizeof sets / sizeof sets[0]; i++) {
        int map[CR_NJOINTS], rig = -1;
        const int score = cr_retarget_match_roles(CR_NJOINTS, sets[i].names, map, &rig);
        int right = 0;
        for (int j = 0; j < CR_NJOINTS; j++)
            right += map[j] == j;
        CR_CHECK(score == CR_NJOINTS && right == CR_NJOINTS);
        CR_CHECK(!strcmp(cr_retarget_rig_name(rig), sets[i].rig));
        if (right != CR_NJOINTS)
            printf("    set %zu (%s): %d of 22 right\n", i, sets[i].rig, right);
    }
}

/* cr_skin_motion_prepare: the rest pose at frame 0, the motion's frame 0
 * after the ease-in, and a resampled rate keeping the duration. */
/* Per vertex, the weight each of the 22 roles gets from a body's four slots. */
static void role_weights(const cr_body_model *b, int64_t v, double w[CR_NJOINTS]) {
    memset(w, 0, CR_NJOINTS * sizeof *w);
    for (int s = 0; s < 4; s++)
        w[b->skin_joint[4 * v + s]] += b->skin_weight[4 * v + s];
}

/* A rigged character as a body (cr_body_from_character, cr_body_resolve
 * "X.glb"): the mannequin written as an Unreal-named character with a root
 * joint above its pelvis comes back as the mannequin (mesh, joints and each
 * vertex's weight per role); meaningless names with a map file naming SMPL
 * joints, the collars left out, put the collars halfway between the third
 * spine joint and the shoulders and give them no weight; without names or
 * map the refusal names the file and the hips; a T-posed character comes
 * back in the mannequin's A-pose. */
CR_TEST(retarget, character_as_a_body_comes_back_as_the_mannequin) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin(), *cb = NULL;
    CR_REQUIRE(b);
    const char *glb = tmp("unreal_body.glb");
    write_rooted_character(b, glb);
    CR_CHECK_OK(cr_body_resolve(glb, &cb, &err), &err);
    CR_REQUIRE(cb && cb->rest->nv == b->rest->nv && cb->rest->nf == b->rest->nf);
    /* the mannequin stands on y = 0 with its pelvis 5 mm off x = z = 0: the
     * character's body stands with it over the origin */
    const double shift[3] = {-b->joints[0], 0.0, -b->joints[2]};
    double dpos = 0.0, djoint = 0.0, dweight = 0.0;
    for (int64_t i = 0; i < 3 * (int64_t)b->rest->nv; i++)
        dpos = fmax(dpos, fabs(cb->rest->pos[i] - (b->rest->pos[i] + shift[i % 3])));
    for (int i = 0; i < 3 * CR_NJOINTS; i++)
        djoint = fmax(djoint, fabs(cb->joints[i] - (b->joints[i] + shift[i % 3])));
    for (int64_t v = 0; v < b->rest->nv; v++) {
        double wa[CR_NJOINTS], wb[CR_NJOINTS];
        role_weights(b, v, wa), role_weights(cb, v, wb);
        for (int r = 0; r < CR_NJOINTS; r++)
            dweight = fmax(dweight, fabs(wa[r] - wb[r]));
    }
    printf("    Unreal names and a root: mesh %.2e m, joints %.2e m, weights %.2e off the "
           "mannequin's\n",
           dpos, djoint, dweight);
    CR_CHECK(dpos < 1e-5 && djoint < 1e-5 && dweight < 1e-5);
    cr_body_model_destroy(cb);
    cb = NULL;
    /* meaningless names: refused without a map, mapped to SMPL's names with one */
    const char *const *bone = bone_names();
    const char *bones = tmp("bones_body.glb");
    write_character(b, bones, bone, 0);
    CR_CHECK(cr_body_from_character(bones, NULL, &cb, &err) == CR_ERR_UNSUPPORTED && !cb);
    printf("    no map: %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "bones_body.glb") && strstr(err.msg, "hips"));
    const char *map = tmp("bones_body.txt");
    FILE *f = fopen(map, "w");
    CR_REQUIRE(f);
    for (int j = 0; j < CR_NJOINTS; j++)
        if (j != CR_JOINT_LEFT_COLLAR && j != CR_JOINT_RIGHT_COLLAR)
            fprintf(f, "%s = %s\n", bone[j], cr_joint_name[j]);
    fclose(f);
    char spec[512];
    snprintf(spec, sizeof spec, "%s:%s", bones, map);
    CR_CHECK_OK(cr_body_resolve(spec, &cb, &err), &err);
    CR_REQUIRE(cb);
    for (int side = 0; side < 2; side++) {
        const int collar = side ? CR_JOINT_RIGHT_COLLAR : CR_JOINT_LEFT_COLLAR;
        const int shoulder = side ? CR_JOINT_RIGHT_SHOULDER : CR_JOINT_LEFT_SHOULDER;
        for (int k = 0; k < 3; k++)
            CR_CHECK_NEAR(cb->joints[3 * collar + k],
                          0.5 * (b->joints[3 * CR_JOINT_SPINE3 + k] + b->joints[3 * shoulder + k]) +
                              shift[k],
                          1e-5);
        for (int64_t v = 0; v < cb->rest->nv; v++) {
            double w[CR_NJOINTS];
            role_weights(cb, v, w);
            CR_CHECK(w[collar] == 0.0);
        }
    }
    for (int j = 0; j < CR_NJOINTS; j++)
        if (j != CR_JOINT_LEFT_COLLAR && j != CR_JOINT_RIGHT_COLLAR)
            for (int k = 0; k < 3; k++)
                CR_CHECK_NEAR(cb->joints[3 * j + k], b->joints[3 * j + k] + shift[k], 1e-5);
    cr_body_model_destroy(cb);
    cb = NULL;
    /* a T-posed character (the mannequin's shoulders raised 40 degrees, its
     * mesh skinned there and written as the bind pose) comes back in the
     * A-pose: the joints where the mannequin's are, the mesh within what
     * blend skinning there and back keeps */
    float tj[CR_NJOINTS * 3];
    cr_mesh *tm = tposed(b, tj);
    CR_REQUIRE(tm);
    CR_CHECK_NEAR(tj[3 * CR_JOINT_LEFT_WRIST + 1], tj[3 * CR_JOINT_LEFT_SHOULDER + 1], 0.03);
    cr_body_model tb = *b;
    tb.rest = tm;
    memcpy(tb.joints, tj, sizeof tj);
    const char *tglb = tmp("tpose_body.glb");
    write_character(&tb, tglb, NULL, 0);
    CR_CHECK_OK(cr_body_resolve(tglb, &cb, &err), &err);
    CR_REQUIRE(cb);
    djoint = 0.0, dpos = 0.0;
    double mean = 0.0;
    for (int i = 0; i < 3 * CR_NJOINTS; i++)
        djoint = fmax(djoint, fabs(cb->joints[i] - (b->joints[i] + shift[i % 3])));
    for (int64_t v = 0; v < b->rest->nv; v++) {
        double d2 = 0.0;
        for (int k = 0; k < 3; k++)
            d2 += pow(cb->rest->pos[3 * v + k] - (b->rest->pos[3 * v + k] + shift[k]), 2);
        dpos = fmax(dpos, sqrt(d2));
        mean += sqrt(d2) / b->rest->nv;
    }
    printf("    T-posed: joints %.2e m off the mannequin's A-pose, mesh %.2e m on average, %.2e "
           "at most\n",
           djoint, mean, dpos);
    CR_CHECK(djoint < 1e-4 && mean < 2e-3 && dpos < 0.03);
    /* its name in a dataset */
    char label[64];
    cr_dataset_body_label("chars/hero.glb:maps/bones.txt", label, sizeof label);
    CR_CHECK(strcmp(label, "hero_bones") == 0);
    cr_dataset_body_label("hero.glb", label, sizeof label);
    CR_CHECK(strcmp(label, "hero") == 0);
    cr_mesh_destroy(tm);
    cr_body_model_destroy(cb);
    cr_body_model_destroy(b);
}

CR_TEST(retarget, skin_motion_eases_in_from_rest_and_resamples) {
    cr_error err = {0};
    cr_skin_motion *m = NULL, *p = NULL, *half = NULL;
    CR_CHECK_OK(cr_skin_motion_create(2, 10, 30.0f, &m, &err), &err);
    CR_REQUIRE(m);
    for (int32_t f = 0; f < 10; f++) { /* joint 1 turns about +Y by 0.1 rad a frame */
        const double a = 0.1 * (f + 1);
        float *q = m->rotation + 4 * (2 * f + 1);
        q[0] = 0.0f, q[1] = (float)sin(a / 2), q[2] = 0.0f, q[3] = (float)cos(a / 2);
        m->translation[3 * f] = 0.01f * (float)(f + 1);
    }
    CR_CHECK_OK(cr_skin_motion_prepare(m, 30.0f, 0.1f, &p, &err), &err);
    CR_REQUIRE(p);
    CR_CHECK(p->nframes == 13 && p->fps == 30.0f);
    CR_CHECK_NEAR(p->rotation[4 * 1 + 3], 1.0f, 1e-7); /* frame 0: the rest */
    CR_CHECK_NEAR(p->translation[0], 0.0f, 1e-7);
    CR_CHECK_NEAR(p->rotation[4 * (2 * 3 + 1) + 1], (float)sin(0.05), 1e-6); /* frame 3: m's 0 */
    CR_CHECK_NEAR(p->translation[3 * 12], 0.1f, 1e-6);                       /* the last */
    CR_CHECK_OK(cr_skin_motion_prepare(m, 15.0f, 0.0f, &half, &err), &err);
    CR_REQUIRE(half);
    CR_CHECK(half->nframes == 5);
    CR_CHECK_NEAR(half->rotation[4 * (2 * 1 + 1) + 1], (float)sin(0.15), 1e-6); /* m's frame 2 */
    cr_skin_motion_destroy(half);
    cr_skin_motion_destroy(p);
    cr_skin_motion_destroy(m);
}

/* ------------------------------------------- a character's own animation -- */

/* Unit quaternion x, y, z, w of `deg` degrees about axis (ax, ay, az), unit. */
static void quat_deg(double ax, double ay, double az, double deg, float *q) {
    const double h = 0.5 * deg * M_PI / 180.0;
    q[0] = (float)(ax * sin(h)), q[1] = (float)(ay * sin(h)), q[2] = (float)(az * sin(h));
    q[3] = (float)cos(h);
}

/* The mannequin written with its walk as its own animation (cr_body_write_glb) comes back as
 * that walk: the same bone directions frame by frame, the pelvis on the same path. */
CR_TEST(retarget, own_animation_of_the_mannequin_comes_back_as_its_motion) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin();
    CR_REQUIRE(b);
    cr_motion *walk = NULL, *back = NULL;
    CR_CHECK_OK(cr_motion_clip("walk", 24, 30.0f, &walk, &err), &err);
    CR_REQUIRE(walk);
    const char *glb = tmp("own_walk.glb");
    CR_CHECK_OK(cr_body_write_glb(glb, b, walk, NULL, NULL, &err), &err);
    CR_CHECK_OK(cr_motion_import(glb, NULL, &back, &err), &err);
    CR_REQUIRE(back);
    CR_CHECK(back->nframes == walk->nframes && back->fps == walk->fps);
    double worst = 0.0, moved = 0.0, path = 0.0;
    float p0[CR_NJOINTS * 3], q0[CR_NJOINTS * 3];
    for (int32_t f = 0; f < walk->nframes; f++) {
        float p[CR_NJOINTS * 3], q[CR_NJOINTS * 3];
        cr_body_forward_kinematics(b->joints, walk->poses + (size_t)f * CR_NJOINTS * 3,
                                   walk->trans + 3 * f, NULL, p);
        cr_body_forward_kinematics(b->joints, back->poses + (size_t)f * CR_NJOINTS * 3,
                                   back->trans + 3 * f, NULL, q);
        if (f == 0) memcpy(p0, p, sizeof p), memcpy(q0, q, sizeof q);
        for (int i = 0; i < NBONES; i++) {
            double dp[3], dq[3], d0[3];
            for (int k = 0; k < 3; k++) {
                dp[k] = (double)p[3 * bones[i][1] + k] - p[3 * bones[i][0] + k];
                dq[k] = (double)q[3 * bones[i][1] + k] - q[3 * bones[i][0] + k];
                d0[k] = (double)b->joints[3 * bones[i][1] + k] - b->joints[3 * bones[i][0] + k];
            }
            worst = fmax(worst, angle3(dp, dq)), moved = fmax(moved, angle3(d0, dp));
        }
        for (int k = 0; k < 3; k++) /* the pelvis's path from frame 0 */
            path = fmax(path, fabs((p[k] - p0[k]) - (q[k] - q0[k])));
    }
    printf("    walk as the file's own animation: bones off by %.2e deg at most (they turn up to "
           "%.0f deg from rest), pelvis path off by %.2e m\n",
           worst * 180 / M_PI, moved * 180 / M_PI, path);
    CR_CHECK(worst < 1e-3 && moved > 0.3 && path < 1e-4);
    /* the file's animation onto another character (Mixamo names, legs x1.15, arms x0.85, spine
     * x1.25, an end joint): its bones follow the walk's */
    const char *mix = tmp("own_walk_target.glb");
    write_character(b, mix, NULL, 1);
    cr_glb_character *c = NULL;
    CR_CHECK_OK(cr_glb_read_character(mix, &c, &err), &err);
    CR_REQUIRE(c);
    int index[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++)
        CR_REQUIRE((index[j] = find_joint(&c->skin, mixamo[j])) >= 0);
    cr_skin_motion *sm = NULL;
    CR_CHECK_OK(cr_motion_retarget(glb, &c->skin, mix, NULL, &sm, &err), &err);
    CR_REQUIRE(sm && sm->nframes == walk->nframes);
    double onto = worst_bone_angle(b, walk, c, sm, index, &moved);
    printf("    onto a Mixamo-named character with other proportions: bones off the walk's by "
           "%.2e deg at most (turning up to %.0f deg)\n",
           onto * 180 / M_PI, moved * 180 / M_PI);
    CR_CHECK(onto < 1e-3 && moved > 0.3);
    cr_skin_motion_destroy(sm), cr_glb_character_destroy(c);
    /* a character holding one key is a one-frame motion at its rest; a mesh without a skin is
     * refused, naming the file */
    const char *still = tmp("still_character.glb"), *plain = tmp("plain_mesh.glb");
    write_character(b, still, NULL, 0);
    cr_motion *one = NULL;
    CR_CHECK_OK(cr_motion_import(still, NULL, &one, &err), &err);
    CR_REQUIRE(one);
    double turned = 0.0;
    for (int i = 0; i < CR_NJOINTS * 3; i++)
        turned = fmax(turned, fabs(one->poses[i]));
    CR_CHECK(one->nframes == 1 && turned < 1e-4);
    cr_motion_destroy(one), one = NULL;
    CR_CHECK_OK(cr_glb_write(plain, b->rest, &err), &err);
    CR_CHECK(cr_motion_import(plain, NULL, &one, &err) == CR_ERR_UNSUPPORTED && !one);
    printf("    a mesh without a skin: %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "plain_mesh.glb") && strstr(err.msg, "no skin"));
    cr_motion_destroy(walk), cr_motion_destroy(back), cr_body_model_destroy(b);
}

/* A T-posed character with Mixamo's names, longer legs and a shorter spine, animated in its own
 * file (arms brought down and swinging, a knee and a hip bending, the root walking forward), as
 * the body (cr_body_resolve) driven by its own animation (cr_motion_import of the same file):
 * its skin where the file's own skinning puts it, frame by frame. */
CR_TEST(retarget, a_character_driven_by_its_own_animation_moves_as_its_file) {
    cr_error err = {0};
    cr_body_model *b = small_mannequin(), *cb = NULL;
    CR_REQUIRE(b);
    float tj[CR_NJOINTS * 3];
    cr_mesh *tm = tposed(b, tj);
    CR_REQUIRE(tm);
    enum { T = 12 };
    const char *names[CR_NJOINTS];
    int32_t parent[CR_NJOINTS];
    float rest[CR_NJOINTS * 3], rot[T * CR_NJOINTS * 4], tr[T * 3];
    for (int j = 0; j < CR_NJOINTS; j++) {
        names[j] = mixamo[j], parent[j] = cr_joint_parent[j];
        for (int k = 0; k < 3; k++) /* legs x1.15, arms x0.85, spine x1.25: bones scaled */
            rest[3 * j + k] =
                parent[j] < 0 ? tj[3 * j + k]
                              : (float)(rest[3 * parent[j] + k] +
                                        bone_scale(j) * (tj[3 * j + k] - tj[3 * parent[j] + k]));
    }
    for (int f = 0; f < T; f++) {
        const double s = sin(0.5 * f);
        float *r = rot + (size_t)f * CR_NJOINTS * 4;
        for (int j = 0; j < CR_NJOINTS; j++)
            quat_deg(1, 0, 0, 0, r + 4 * j);
        quat_deg(0, 0, 1, -40 + 20 * s, r + 4 * CR_JOINT_LEFT_SHOULDER);
        quat_deg(0, 0, 1, 40 + 20 * s, r + 4 * CR_JOINT_RIGHT_SHOULDER);
        quat_deg(0, 1, 0, 30 + 20 * s, r + 4 * CR_JOINT_LEFT_ELBOW);
        quat_deg(1, 0, 0, -25 * s, r + 4 * CR_JOINT_LEFT_HIP);
        quat_deg(1, 0, 0, 25 * s, r + 4 * CR_JOINT_RIGHT_HIP);
        quat_deg(1, 0, 0, 20 + 20 * s, r + 4 * CR_JOINT_RIGHT_KNEE);
        quat_deg(0, 1, 0, 10 * s, r + 4 * CR_JOINT_SPINE2);
        tr[3 * f] = 0.0f, tr[3 * f + 1] = 0.0f, tr[3 * f + 2] = 0.03f * (float)f;
    }
    const cr_glb_skin skin = {CR_NJOINTS, names, parent, rest, b->skin_joint, b->skin_weight};
    const cr_glb_skin_motion anim = {T, 30.0f, rot, tr};
    const char *glb = tmp("own_animation_character.glb");
    CR_CHECK_OK(cr_glb_write_skinned(glb, tm, &skin, &anim, NULL, &err), &err);
    /* the file's own frames, and the body posed by the motion read from the file */
    cr_mesh *seq_rest = NULL;
    float *seq = NULL, fps = 0.0f;
    int32_t nseq = 0;
    CR_CHECK_OK(cr_glb_read_sequence(glb, &seq_rest, &seq, &nseq, &fps, &err), &err);
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_body_resolve(glb, &cb, &err), &err);
    CR_CHECK_OK(cr_motion_import(glb, NULL, &m, &err), &err);
    CR_REQUIRE(cb && m && seq && nseq == T && m->nframes == T && seq_rest->nv == cb->rest->nv);
    const int64_t nv = cb->rest->nv;
    float *posed = malloc((size_t)nv * 3 * sizeof(float));
    CR_REQUIRE(posed);
    double mean = 0.0, worst = 0.0, swing = 0.0;
    for (int f = 0; f < T; f++) {
        CR_CHECK_OK(
            cr_body_pose(cb, m->poses + (size_t)f * CR_NJOINTS * 3, m->trans + 3 * f, posed, &err),
            &err);
        const float *ref = seq + (size_t)f * (size_t)nv * 3;
        double ca[3] = {0}, cf[3] = {0}; /* each frame's centroid: the body stands elsewhere */
        for (int64_t v = 0; v < nv; v++)
            for (int k = 0; k < 3; k++)
                ca[k] += posed[3 * v + k] / (double)nv, cf[k] += ref[3 * v + k] / (double)nv;
        for (int64_t v = 0; v < nv; v++) {
            double d2 = 0.0, m2 = 0.0;
            for (int k = 0; k < 3; k++) {
                d2 += pow((posed[3 * v + k] - ca[k]) - (ref[3 * v + k] - cf[k]), 2);
                m2 += pow(ref[3 * v + k] - seq[3 * v + k], 2);
            }
            mean += sqrt(d2) / ((double)nv * T), worst = fmax(worst, sqrt(d2));
            swing = fmax(swing, sqrt(m2));
        }
    }
    printf("    T-posed Mixamo character, its own 12 frames: skin off its file's by %.2e m on "
           "average, %.2e m at most (vertices move up to %.2f m)\n",
           mean, worst, swing);
    CR_CHECK(swing > 0.3 && mean < 3e-3 && worst < 0.04);
    free(posed), free(seq);
    cr_mesh_destroy(seq_rest), cr_mesh_destroy(tm);
    cr_motion_destroy(m), cr_body_model_destroy(cb), cr_body_model_destroy(b);
}
