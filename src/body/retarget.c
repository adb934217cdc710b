/* retarget.c: bone-direction retargeting from a source rig onto a target
 * skeleton (retarget_internal.h): the joint-name tables both sides are
 * matched through, the alignment at rest, the per-frame rotations and the
 * turn into crease's frame.
 *
 * Names: each table lists, per SMPL role, the normalised names a convention
 * gives it, best first: SMPL ("L_Shoulder", "left_shoulder"), Mixamo
 * ("mixamorig:LeftArm"), CMU's BVH (LeftArm, LowerBack, Spine1), generic
 * DAZ/Poser, Unreal ("upperarm_l", "thigh_r", "spine_01") and Blender's
 * metarig / Rigify ("upper_arm.L", "DEF-thigh.R", "spine.003"). Note that the
 * same word means different joints by convention: Mixamo's and CMU's
 * "LeftShoulder" is SMPL's left_collar, SMPL's "left_shoulder" the upper arm;
 * the table matching the most joints decides.
 *
 * What it leaves out: finger and toe chains, twist bones, IK and pole
 * joints (they keep their rest relation to their parent).
 *
 * References: Mixamo's, Unreal's and Rigify's published rigs for the names;
 * bone-direction retargeting as in Blender's and MotionBuilder's "match bone
 * direction" retargeters (shortest arcs, twist taken from the source joint).
 */
#include "body/retarget_internal.h"
#include "geom/io_text.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

/* -------------------------------------------------------------- names -- */

/* cgspeed's CMU BVH: the ASF's length unit, 0.45 inch scaled by 1 / 0.45 ...
 * as the conversion's readme gives it, (1 / 0.45) 2.54 / 100 m per unit. */
#define CMU_UNIT_M 0.056444

typedef struct rt_rig {
    const char *name;
    const char *joints[CR_NJOINTS]; /* normalised candidates, '|'-separated, best first */
    /* The rig's known unit, m, taken when its rest height (units) is in
     * [unit_lo, unit_hi]; 0: infer from the height. */
    double unit_m, unit_lo, unit_hi;
} rt_rig;

static const rt_rig rigs[] = {
    {"SMPL",
     {"pelvis",
      "lefthip|lhip",
      "righthip|rhip",
      "spine1",
      "leftknee|lknee",
      "rightknee|rknee",
      "spine2",
      "leftankle|lankle",
      "rightankle|rankle",
      "spine3",
      "leftfoot|lfoot",
      "rightfoot|rfoot",
      "neck",
      "leftcollar|lcollar",
      "rightcollar|rcollar",
      "head",
      "leftshoulder|lshoulder",
      "rightshoulder|rshoulder",
      "leftelbow|lelbow",
      "rightelbow|relbow",
      "leftwrist|lwrist",
      "rightwrist|rwrist"},
     0.0,
     0.0,
     0.0},
    {"Mixamo",
     {"hips",        "leftupleg",    "rightupleg",    "spine",    "leftleg",     "rightleg",
      "spine1",      "leftfoot",     "rightfoot",     "spine2",   "lefttoebase", "righttoebase",
      "neck",        "leftshoulder", "rightshoulder", "head",     "leftarm",     "rightarm",
      "leftforearm", "rightforearm", "lefthand",      "righthand"},
     0.01,
     80.0,
     300.0},
    {"CMU",
     {"hips",        "leftupleg",    "rightupleg",    "lowerback", "leftleg",     "rightleg",
      "spine",       "leftfoot",     "rightfoot",     "spine1",    "lefttoebase", "righttoebase",
      "neck",        "leftshoulder", "rightshoulder", "head",      "leftarm",     "rightarm",
      "leftforearm", "rightforearm", "lefthand",      "righthand"},
     CMU_UNIT_M,
     12.0,
     45.0},
    {"generic (DAZ/Poser)",
     {"hip|hips",
      "lthigh|lthighbend|leftthigh",
      "rthigh|rthighbend|rightthigh",
      "abdomen|abdomenlower|abdomen1",
      "lshin|lshinbend|leftshin",
      "rshin|rshinbend|rightshin",
      "abdomen2|abdomenupper",
      "lfoot",
      "rfoot",
      "chest|chestupper|chestlower",
      "ltoe|ltoes",
      "rtoe|rtoes",
      "neck|necklower",
      "lcollar|lclavicle",
      "rcollar|rclavicle",
      "head",
      "lshldr|lshldrbend|lupperarm",
      "rshldr|rshldrbend|rupperarm",
      "lforearm|lforearmbend",
      "rforearm|rforearmbend",
      "lhand",
      "rhand"},
     0.0,
     0.0,
     0.0},
    {"Unreal",
     {"pelvis", "thighl",    "thighr",      "spine01",   "calfl",
      "calfr",  "spine02",   "footl",       "footr",     "spine05|spine03",
      "balll",  "ballr",     "neck01|neck", "claviclel", "clavicler",
      "head",   "upperarml", "upperarmr",   "lowerarml", "lowerarmr",
      "handl",  "handr"},
     0.0,
     0.0,
     0.0},
    {"Blender/Rigify",
     {"spine|defspine|hips",
      "thighl|defthighl",
      "thighr|defthighr",
      "spine001|defspine001",
      "shinl|defshinl",
      "shinr|defshinr",
      "spine002|defspine002",
      "footl|deffootl",
      "footr|deffootr",
      "spine003|defspine003|chest",
      "toel|deftoel",
      "toer|deftoer",
      "spine004|defspine004|neck",
      "shoulderl|defshoulderl",
      "shoulderr|defshoulderr",
      "spine006|defspine006|spine005|defspine005|head",
      "upperarml|defupperarml",
      "upperarmr|defupperarmr",
      "forearml|defforearml",
      "forearmr|defforearmr",
      "handl|defhandl",
      "handr|defhandr"},
     0.0,
     0.0,
     0.0},
};

enum { NRIGS = sizeof rigs / sizeof rigs[0] };

const char *const cr_retarget_rig_list = "SMPL, Mixamo, CMU, DAZ/Poser, Unreal, Blender/Rigify";

const char *cr_retarget_rig_name(int rig) {
    return rigs[rig].name;
}

void cr_retarget_rig_unit(int rig, double *unit_m, double *lo, double *hi) {
    *unit_m = rigs[rig].unit_m, *lo = rigs[rig].unit_lo, *hi = rigs[rig].unit_hi;
}

void cr_retarget_normalise(const char *name, char *out, size_t cap) {
    const char *colon = strrchr(name, ':');
    if (colon) name = colon + 1;
    size_t n = 0;
    for (; *name && n + 1 < cap; name++) {
        char c = *name;
        if (c == '_' || c == '-' || c == '.' || c == ' ') continue;
        out[n++] = (char)tolower((unsigned char)c);
    }
    out[n] = 0;
    if (strncmp(out, "mavg", 4) == 0 || strncmp(out, "favg", 4) == 0) memmove(out, out + 4, n - 3);
}

/* Index of the first joint whose normalised name is among `cands`, or -1. */
static int find_candidate(int n, char (*norm)[RT_NAME_MAX + 1], const char *cands) {
    const char *c = cands;
    while (*c) {
        const char *bar = strchr(c, '|');
        size_t len = bar ? (size_t)(bar - c) : strlen(c);
        for (int i = 0; i < n; i++)
            if (norm[i][0] && strlen(norm[i]) == len && memcmp(norm[i], c, len) == 0) return i;
        c += len + (bar != NULL);
    }
    return -1;
}

int cr_retarget_match_roles(int n, const char *const *names, int map[CR_NJOINTS], int *rig) {
    char(*norm)[RT_NAME_MAX + 1] = malloc((size_t)(n > 0 ? n : 1) * sizeof *norm);
    for (int j = 0; j < CR_NJOINTS; j++)
        map[j] = -1;
    *rig = 0;
    if (!norm) return 0;
    for (int i = 0; i < n; i++) {
        norm[i][0] = 0;
        if (names[i]) cr_retarget_normalise(names[i], norm[i], sizeof norm[i]);
    }
    int best_score = -1;
    for (int r = 0; r < NRIGS; r++) {
        int score = 0, tmp[CR_NJOINTS];
        for (int j = 0; j < CR_NJOINTS; j++)
            score += (tmp[j] = find_candidate(n, norm, rigs[r].joints[j])) >= 0;
        if (tmp[0] < 0) score = 0;
        if (score > best_score) {
            *rig = r, best_score = score;
            memcpy(map, tmp, sizeof tmp);
        }
    }
    free(norm);
    return best_score;
}

/* ----------------------------------------------------------- geometry -- */

int cr_retarget_unit3(const double v[3], double out[3], double eps) {
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(n > eps) || !isfinite(n)) return 0; /* degenerate, or offsets past double's range */
    for (int k = 0; k < 3; k++)
        out[k] = v[k] / n;
    return 1;
}

void cr_retarget_shortest_arc(const double a[3], const double b[3], double q[4]) {
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    if (d < -1.0 + 1e-12) { /* opposite: half a turn about any perpendicular axis */
        double p[3] = {0, 0, 0};
        p[fabs(a[0]) < 0.9 ? 0 : 1] = 1;
        c[0] = a[1] * p[2] - a[2] * p[1], c[1] = a[2] * p[0] - a[0] * p[2];
        c[2] = a[0] * p[1] - a[1] * p[0];
        d = -1.0;
        q[0] = 0;
    } else {
        q[0] = 1.0 + d;
    }
    q[1] = c[0], q[2] = c[1], q[3] = c[2];
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++)
        q[k] /= n;
}

/* Signed coordinate axis nearest to v, as (axis index, sign); -1 when v is 0
 * or its largest component is `skip`. */
static int snap_axis(const double v[3], int skip, int *sign) {
    int a = -1;
    double best = 1e-9;
    for (int k = 0; k < 3; k++)
        if (k != skip && fabs(v[k]) > best) best = fabs(v[k]), a = k;
    if (a >= 0) *sign = v[a] > 0 ? 1 : -1;
    return a;
}

const int cr_retarget_up_ends[4] = {CR_JOINT_HEAD, CR_JOINT_NECK, CR_JOINT_SPINE3, CR_JOINT_SPINE2};

const int8_t cr_retarget_bone_child_role[CR_NJOINTS] = {3,  4,  5,  6,  7,  8,  9,  10, 11, 12, -1,
                                                        -1, 15, 16, 17, -1, 18, 19, 20, 21, -1, -1};

int cr_retarget_rig_axes(const int map[CR_NJOINTS], double (*p)[3], int *up_axis, int *up_sign,
                         int *left_axis, int *left_sign) {
    static const int lr[][2] = {{CR_JOINT_LEFT_HIP, CR_JOINT_RIGHT_HIP},
                                {CR_JOINT_LEFT_SHOULDER, CR_JOINT_RIGHT_SHOULDER},
                                {CR_JOINT_LEFT_KNEE, CR_JOINT_RIGHT_KNEE}};
    double up[3] = {0}, left[3] = {0};
    *up_axis = -1, *left_axis = -1, *up_sign = 1, *left_sign = 1;
    for (int i = 0; i < 4 && *up_axis < 0; i++)
        if (map[cr_retarget_up_ends[i]] >= 0) {
            for (int k = 0; k < 3; k++)
                up[k] = p[map[cr_retarget_up_ends[i]]][k] - p[map[0]][k];
            *up_axis = snap_axis(up, -1, up_sign);
        }
    for (int i = 0; i < 3 && *up_axis >= 0 && *left_axis < 0; i++)
        if (map[lr[i][0]] >= 0 && map[lr[i][1]] >= 0) {
            for (int k = 0; k < 3; k++)
                left[k] = p[map[lr[i][0]]][k] - p[map[lr[i][1]]][k];
            *left_axis = snap_axis(left, *up_axis, left_sign);
        }
    return *up_axis >= 0 && *left_axis >= 0;
}

void cr_retarget_axes_turn(int up_axis, int up_sign, int left_axis, int left_sign, double q[4]) {
    /* Rows of the turn: left -> x, up -> y, left x up (forward) -> z. */
    double m[3][3] = {{0}};
    m[0][left_axis] = left_sign;
    m[1][up_axis] = up_sign;
    for (int k = 0; k < 3; k++) {
        int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        m[2][k] = m[0][k1] * m[1][k2] - m[0][k2] * m[1][k1];
    }
    /* A signed permutation with det +1: Shepperd's matrix-to-quaternion. */
    double tr = m[0][0] + m[1][1] + m[2][2];
    if (tr > 0) {
        double s = 2 * sqrt(1 + tr);
        q[0] = s / 4, q[1] = (m[2][1] - m[1][2]) / s, q[2] = (m[0][2] - m[2][0]) / s,
        q[3] = (m[1][0] - m[0][1]) / s;
    } else {
        int i = m[1][1] > m[0][0] ? (m[2][2] > m[1][1] ? 2 : 1) : (m[2][2] > m[0][0] ? 2 : 0);
        int j = (i + 1) % 3, k = (i + 2) % 3;
        double s = 2 * sqrt(1 + m[i][i] - m[j][j] - m[k][k]);
        q[0] = (m[k][j] - m[j][k]) / s;
        q[1 + i] = s / 4;
        q[1 + j] = (m[j][i] + m[i][j]) / s;
        q[1 + k] = (m[k][i] + m[i][k]) / s;
    }
}

/* -------------------------------------------------------- retargeting -- */

cr_status cr_retarget_state_alloc(int n, rt_state *s, cr_error *err) {
    s->child = cr_malloc((size_t)n * sizeof *s->child, err);
    s->e = cr_malloc((size_t)n * sizeof *s->e, err);
    s->align = cr_malloc((size_t)n * sizeof *s->align, err);
    if (s->child && s->e && s->align) return CR_OK;
    cr_retarget_state_free(s);
    return CR_ERR_MEMORY;
}

void cr_retarget_state_free(rt_state *s) {
    free(s->child), free(s->e), free(s->align);
    s->child = NULL, s->e = NULL, s->align = NULL;
}

/* Retargeting by bone directions. For target joint j with bone child c, d_j
 * is the source's rest bone (source joint of j to source joint of c) and e_j
 * the target's (turned into the source's frame); A_j carries e_j onto d_j by
 * the shortest arc. A frame's world rotation of j is then Q_j W_j A_j, W_j
 * the source joint's world rotation and Q_j the shortest arc from
 * W_j A_j e_j to the source's bone as posed (the identity unless folded
 * joints lie between the two, CMU's Neck1). So the target's bone points
 * where the source's does, with the source's twist about it.
 *
 * turn: the file's frame to crease's; rest_turn: the rest pose's own upright
 * frame to crease's, which differs from turn when the bind skeleton lies
 * along another axis than the motion stands: each bone is then matched after
 * standing the rest pose up (D below), so a bone along the axis of that turn
 * keeps its twist, which a shortest arc alone would lose.
 *
 * ref_w: NULL to match against the rest pose (ref its positions). Otherwise
 * ref and ref_w are a standing frame's joint positions and world rotations,
 * for a bind pose that does not stand: a shortest arc from the target's bone
 * to such a rest bone twists arbitrarily, so the bones are matched as they
 * stand in that frame, A_j = W_j^-1 B_j with B_j the arc from the target's
 * bone to the posed one, and the pelvis by its spine and its hips both (a
 * frame, not an arc: a half turn about the spine would swap the legs). */
void cr_retarget_setup(const rt_target *t, double (*ref)[3], double (*ref_w)[4],
                       const double turn[4], const double rest_turn[4], double height,
                       rt_state *s) {
    double turn_inv[4], stand[4], stand_inv[4];
    q_conj(turn, turn_inv);
    q_mul(turn_inv, rest_turn, stand); /* D: the rest pose stood along the motion's up */
    if (ref_w) q_identity(stand);
    q_conj(stand, stand_inv);
    for (int j = 0; j < t->n; j++) {
        int p = t->parent[j];
        s->child[j] = -1;
        if (p >= 0)
            memcpy(s->align[j], s->align[p], sizeof s->align[j]);
        else
            memcpy(s->align[j], stand_inv, sizeof s->align[j]);
        if (t->src[j] < 0) continue;
        for (int c = t->bone_child[j]; c >= 0; c = t->bone_child[c]) {
            if (t->src[c] < 0) continue;
            double d[3], e[3];
            for (int k = 0; k < 3; k++) {
                d[k] = ref[t->src[c]][k] - ref[t->src[j]][k];
                e[k] = t->rest[c][k] - t->rest[j][k];
            }
            q_rotate(turn_inv, e, e);
            q_rotate(stand, d, d);
            if (!cr_retarget_unit3(d, d, 1e-3 * height) || !cr_retarget_unit3(e, e, 1e-6)) continue;
            s->child[j] = c;
            memcpy(s->e[j], e, sizeof e);
            double arc[4];
            cr_retarget_shortest_arc(e, d, arc);
            if (!ref_w) {
                q_mul(stand_inv, arc, s->align[j]);
                break;
            }
            const int lh = t->lhip >= 0 ? t->src[t->lhip] : -1;
            const int rh = t->rhip >= 0 ? t->src[t->rhip] : -1;
            if (j == t->pelvis && lh >= 0 && rh >= 0) {
                /* the twist about the spine that turns the target's hips onto the rig's */
                double el[3], dl[3], v[3];
                for (int k = 0; k < 3; k++) {
                    el[k] = t->rest[t->lhip][k] - t->rest[t->rhip][k];
                    dl[k] = ref[lh][k] - ref[rh][k];
                }
                q_rotate(turn_inv, el, el);
                q_rotate(arc, el, v);
                double vd = v[0] * d[0] + v[1] * d[1] + v[2] * d[2];
                double ld = dl[0] * d[0] + dl[1] * d[1] + dl[2] * d[2];
                for (int k = 0; k < 3; k++)
                    v[k] -= vd * d[k], dl[k] -= ld * d[k];
                if (cr_retarget_unit3(v, v, 1e-9) && cr_retarget_unit3(dl, dl, 1e-9)) {
                    double twist[4];
                    cr_retarget_shortest_arc(v, dl,
                                             twist); /* about d: both are perpendicular to it */
                    q_mul(twist, arc, arc);
                }
            }
            double w_inv[4];
            q_conj(ref_w[t->src[j]], w_inv);
            q_mul(w_inv, arc, s->align[j]);
            break;
        }
    }
}

void cr_retarget_frame(const rt_target *t, const rt_state *s, double (*w)[4], double (*pos)[3],
                       double (*g)[4]) {
    for (int j = 0; j < t->n; j++) {
        int p = t->parent[j];
        if (t->src[j] < 0) {
            if (p >= 0)
                memcpy(g[j], g[p], sizeof g[j]);
            else
                q_identity(g[j]);
            continue;
        }
        q_mul(w[t->src[j]], s->align[j], g[j]);
        int c = s->child[j];
        if (c < 0) continue;
        double cur[3], act[3], q[4];
        q_rotate(g[j], s->e[j], cur);
        for (int k = 0; k < 3; k++)
            act[k] = pos[t->src[c]][k] - pos[t->src[j]][k];
        if (!cr_retarget_unit3(act, act, 1e-12)) continue;
        cr_retarget_shortest_arc(cur, act, q);
        q_mul(q, g[j], g[j]);
    }
}

void cr_retarget_fix_world(double *g, int n, int pelvis, double *t, int32_t T,
                           const motion_frame_fix *fix) {
    double w_inv[4];
    q_conj(fix->world, w_inv);
    for (int32_t f = 0; f < T; f++) {
        for (int j = 0; j < n; j++) {
            double *q = g + 4 * ((size_t)f * (size_t)n + (size_t)j);
            q_mul(fix->world, q, q);
            if (fix->conjugate) q_mul(q, w_inv, q);
        }
        double *v = t + 3 * (size_t)f;
        q_rotate(fix->world, v, v);
        for (int k = 0; k < 3; k++)
            v[k] -= fix->origin[k];
    }
    if (!fix->recenter) return;
    /* Heading of frame 0: where the pelvis turns the body's forward axis +Z. */
    double fwd[3] = {0, 0, 1}, heading[4];
    q_rotate(g + 4 * (size_t)pelvis, fwd, fwd);
    double yaw = fabs(fwd[0]) + fabs(fwd[2]) > 1e-9 ? atan2(fwd[0], fwd[2]) : 0.0;
    q_axis(0, 1, 0, -yaw, heading);
    double t0[3] = {t[0], fix->recenter_height ? t[1] : 0.0, t[2]};
    for (int32_t f = 0; f < T; f++) {
        for (int j = 0; j < n; j++) {
            double *q = g + 4 * ((size_t)f * (size_t)n + (size_t)j);
            q_mul(heading, q, q);
        }
        double *v = t + 3 * (size_t)f;
        for (int k = 0; k < 3; k++)
            v[k] -= t0[k];
        q_rotate(heading, v, v);
    }
}

/* ------------------------------------------------- a character target -- */

void cr_retarget_character_free(rt_character *c) {
    free(c->parent), free(c->src), free(c->bone_child), free(c->rest);
    memset(c, 0, sizeof *c);
}

static int is_below(const int *parent, int anc, int j) {
    for (j = parent[j]; j >= 0; j = parent[j])
        if (j == anc) return 1;
    return 0;
}

static int find_exact(int n, const char *const *names, const char *b, const char *e) {
    for (int i = 0; i < n; i++)
        if (names[i] && strlen(names[i]) == (size_t)(e - b) &&
            memcmp(names[i], b, (size_t)(e - b)) == 0)
            return i;
    return -1;
}

/* One side of a map line, trimmed: [*b, *e). */
static void trim(const char **b, const char **e) {
    while (*b < *e && isspace((unsigned char)**b))
        (*b)++;
    while (*e > *b && isspace((unsigned char)(*e)[-1]))
        (*e)--;
}

/* What a joint map line needs: the skeletons on both sides and what the
 * lines have set so far. */
typedef struct joint_map {
    rt_character *c;
    const cr_glb_skin *skel;
    const char *skel_source, *path, *src_source;
    int nsrc;
    const char *const *src_names;
    const int *src_role;
    int *by_user;
} joint_map;

/* One pair: character joint [lb, le) driven by source joint [rb, re)
 * (empty: none), at `line` of the file. */
static cr_status map_pair(joint_map *jm, int line, const char *lb, const char *le, const char *rb,
                          const char *re, cr_error *err) {
    rt_character *c = jm->c;
    int j = find_exact(jm->skel->njoints, jm->skel->joint_name, lb, le);
    if (j < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%d: the character %s has no joint '%.*s'", jm->path,
                       line, jm->skel_source, (int)(le - lb), lb);
    int s = rb == re ? -1 : find_exact(jm->nsrc, jm->src_names, rb, re);
    if (rb != re && s < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%d: the motion %s has no joint '%.*s'", jm->path,
                       line, jm->src_source, (int)(re - rb), rb);
    /* The character joint takes the source joint's role, if it has one. */
    int r = -1;
    for (int k = 0; k < CR_NJOINTS && s >= 0; k++)
        if (jm->src_role[k] == s) r = k;
    for (int k = 0; k < CR_NJOINTS; k++)
        if (c->role[k] == j) c->role[k] = -1;
    if (r >= 0 && c->role[r] >= 0 && c->role[r] != j && !jm->by_user[c->role[r]])
        c->src[c->role[r]] = -1; /* the joint that had the role by name gives it up */
    if (r >= 0) c->role[r] = j;
    c->src[j] = s;
    jm->by_user[j] = 1;
    c->nuser++;
    return CR_OK;
}

/* Line number (from 1) of position p in buf. */
static int line_of(const char *buf, const char *p) {
    int line = 1;
    for (const char *q = buf; q < p; q++)
        line += *q == '\n';
    return line;
}

/* A JSON joint map: {"character_joint": "bvh_joint" or null, ...}; each
 * pair's line is its key's. */
static cr_status map_json(joint_map *jm, const char *buf, size_t len, cr_error *err) {
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(buf, len, &end, 0);
    if (!root || !cJSON_IsObject(root)) {
        const char *at = root ? buf : (end ? end : buf);
        cJSON_Delete(root);
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s:%d: expected a JSON object {\"character_joint\": \"bvh_joint\", ...}",
                       jm->path, line_of(buf, at));
    }
    cr_status st = CR_OK;
    const char *from = buf;
    for (const cJSON *e = root->child; e && st == CR_OK; e = e->next) {
        char quoted[RT_NAME_MAX + 3];
        snprintf(quoted, sizeof quoted, "\"%s\"", e->string);
        const char *at = strstr(from, quoted);
        if (at) from = at + 1;
        const int line = line_of(buf, at ? at : from);
        if (!cJSON_IsString(e) && !cJSON_IsNull(e)) {
            st = CR_FAIL(err, CR_ERR_PARSE, "%s:%d: \"%s\": expected a BVH joint's name or null",
                         jm->path, line, e->string);
            break;
        }
        const char *v = cJSON_IsString(e) ? e->valuestring : "";
        st = map_pair(jm, line, e->string, e->string + strlen(e->string), v, v + strlen(v), err);
    }
    cJSON_Delete(root);
    return st;
}

/* The joint map file: "character_joint = source_joint" a line, or JSON. */
static cr_status read_joint_map(joint_map *jm, cr_error *err) {
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(jm->path, &buf, &len, err));
    const char *first = buf;
    while (first < buf + len && isspace((unsigned char)*first))
        first++;
    if (first < buf + len && *first == '{') {
        cr_status st = map_json(jm, buf, len, err);
        free(buf);
        return st;
    }
    cr_status st = CR_OK;
    int line = 0;
    for (const char *p = buf, *end = buf + len; st == CR_OK && p < end; line++) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *b = p, *e = eol, *hash = memchr(b, '#', (size_t)(e - b));
        p = eol + 1;
        if (hash) e = hash;
        trim(&b, &e);
        if (b == e) continue;
        const char *eq = memchr(b, '=', (size_t)(e - b));
        const char *lb = b, *le = eq ? eq : e, *rb = eq ? eq + 1 : e, *re = e;
        trim(&lb, &le), trim(&rb, &re);
        char snip[48];
        cr_io_text_snippet(b, e, snip, sizeof snip);
        if (!eq || lb == le || memchr(rb, '=', (size_t)(re - rb)))
            st = CR_FAIL(err, CR_ERR_PARSE,
                         "%s:%d: expected 'character_joint = bvh_joint', got '%s'", jm->path,
                         line + 1, snip);
        else
            st = map_pair(jm, line + 1, lb, le, rb, re, err);
    }
    free(buf);
    return st;
}

cr_status cr_retarget_character_build(const cr_glb_skin *skel, const char *skel_source,
                                      const char *map_path, int nsrc, const char *const *src_names,
                                      const int src_role[CR_NJOINTS], const char *src_source,
                                      rt_character *c, cr_error *err) {
    memset(c, 0, sizeof *c);
    const int n = skel->njoints;
    c->parent = cr_malloc((size_t)n * sizeof *c->parent, err);
    c->src = cr_malloc((size_t)n * sizeof *c->src, err);
    c->bone_child = cr_malloc((size_t)n * sizeof *c->bone_child, err);
    c->rest = cr_malloc((size_t)n * sizeof *c->rest, err);
    int *by_user = cr_calloc((size_t)n, sizeof *by_user, err);
    int *depth = cr_calloc((size_t)n, sizeof *depth, err);
    cr_status st =
        c->parent && c->src && c->bone_child && c->rest && by_user && depth ? CR_OK : CR_ERR_MEMORY;
    for (int j = 0; st == CR_OK && j < n; j++) {
        c->parent[j] = skel->parent[j];
        CR_ASSERT(c->parent[j] < j); /* cr_glb_skin's order: parents first */
        depth[j] = c->parent[j] >= 0 ? depth[c->parent[j]] + 1 : 0;
    }
    if (st == CR_OK) {
        c->nroles = cr_retarget_match_roles(n, skel->joint_name, c->role, &c->rig);
        for (int j = 0; j < n; j++)
            c->src[j] = -1;
        for (int r = 0; r < CR_NJOINTS; r++)
            if (c->role[r] >= 0) c->src[c->role[r]] = src_role[r];
        joint_map jm = {c,    skel,      skel_source, map_path, src_source,
                        nsrc, src_names, src_role,    by_user};
        if (map_path) st = read_joint_map(&jm, err);
    }
    const int pelvis = st == CR_OK ? c->role[CR_JOINT_PELVIS] : -1;
    if (st == CR_OK && (pelvis < 0 || c->src[pelvis] < 0)) {
        char names[240];
        int k = 0;
        for (int j = 0; j < n && k < (int)sizeof names - 40; j++)
            k += snprintf(names + k, sizeof names - (size_t)k, "%s%s", k ? ", " : "",
                          skel->joint_name[j]);
        st = CR_FAIL(err, CR_ERR_UNSUPPORTED,
                     "%s: no joint of the character is mapped to the hips (pelvis), so %s "
                     "cannot drive it (names known: %s; joints here: %s); name it in a joint "
                     "map file, 'character_joint = bvh_joint' a line",
                     skel_source, src_source, cr_retarget_rig_list, names);
    }
    if (st == CR_OK) {
        /* The character's frame: pelvis to head up, right to left hip left. */
        double(*raw)[3] = c->rest;
        for (int j = 0; j < n; j++)
            for (int k = 0; k < 3; k++)
                raw[j][k] = skel->rest_joint[3 * j + k];
        int ua, us, la, ls;
        q_identity(c->turn);
        if (cr_retarget_rig_axes(c->role, raw, &ua, &us, &la, &ls))
            cr_retarget_axes_turn(ua, us, la, ls, c->turn);
        else
            cr_log(CR_LOG_WARN,
                   "%s: cannot tell up and left from the skeleton (no head, neck or hips "
                   "mapped): taken as glTF's +Y up, facing +Z",
                   skel_source);
        double lowest = INFINITY;
        for (int j = 0; j < n; j++) {
            q_rotate(c->turn, raw[j], raw[j]);
            lowest = fmin(lowest, raw[j][1]);
        }
        c->hip_m = raw[pelvis][1] - lowest;
        /* Bones: along the role chain, else to the nearest driven joint below. */
        for (int j = 0; j < n; j++) {
            c->bone_child[j] = -1;
            int r = -1;
            for (int k = 0; k < CR_NJOINTS; k++)
                if (c->role[k] == j) r = k;
            if (r >= 0) {
                for (int cr = cr_retarget_bone_child_role[r]; cr >= 0 && c->bone_child[j] < 0;
                     cr = cr_retarget_bone_child_role[cr])
                    if (c->role[cr] >= 0 && is_below(c->parent, j, c->role[cr]))
                        c->bone_child[j] = c->role[cr];
                continue;
            }
            for (int i = j + 1; i < n; i++)
                if (c->src[i] >= 0 && is_below(c->parent, j, i) &&
                    (c->bone_child[j] < 0 || depth[i] < depth[c->bone_child[j]]))
                    c->bone_child[j] = i;
        }
        c->t = (rt_target){.n = n,
                           .parent = c->parent,
                           .rest = (const double(*)[3])c->rest,
                           .src = c->src,
                           .bone_child = c->bone_child,
                           .pelvis = pelvis,
                           .lhip = c->role[CR_JOINT_LEFT_HIP],
                           .rhip = c->role[CR_JOINT_RIGHT_HIP]};
    }
    free(by_user), free(depth);
    if (st != CR_OK) cr_retarget_character_free(c);
    return st;
}
