/* motion_bvh.c: Biovision hierarchy (.bvh) motions mapped onto SMPL's 22
 * joints.
 *
 * Parsing: HIERARCHY with one ROOT, nested JOINTs and End Sites, OFFSET,
 * CHANNELS with 0 to 6 of X/Y/Z position and rotation in any order; MOTION
 * with "Frames:", "Frame Time:" and one line of values per frame. Joint names
 * may hold spaces; braces may share a line with the name. A joint's
 * rotation is the product of its rotation channels in the order listed
 * (Zrotation Xrotation Yrotation means Rz Rx Ry, applied to column vectors),
 * in degrees. Position channels replace the joint's OFFSET, as in Blender's
 * importer. Errors name the file and line.
 *
 * Mapping: joint names are normalised (namespace before ':' dropped, as in
 * "mixamorig:Hips"; lower case; '_', '-', '.' and spaces removed; SMPL FBX's
 * "m_avg_" prefix dropped) and matched against per-rig tables (SMPL, Mixamo,
 * CMU, generic DAZ/Poser); the rig matching the most joints wins. Each SMPL
 * joint is retargeted by bone directions (see `retarget` below): its bone
 * points where the rig's bone points, with the rig's twist, whatever rest
 * the rig was written against. Unmapped joints between two mapped ones
 * (CMU's LHipJoint, Neck1, a DAZ chestLower) fold into the child below
 * them, and an SMPL joint the rig lacks (a collar) moves with its parent.
 * Joints below the mapped ones (fingers, toe ends) are dropped, and so are
 * translations of joints other than the pelvis.
 *
 * Frame: the rig's up axis (pelvis to head) and left axis (right to left hip)
 * are snapped to coordinate axes and the rig is turned so up is +Y and left
 * +X (the body facing +Z), which also reads Z-up exports. Lengths: with no
 * scale given, a rig whose rest height (highest minus lowest joint) is 0.8 to
 * 3 units is taken as metres, 80 to 300 as centimetres, anything else is
 * scaled to a 1.65 m joint height with a warning. The rest pelvis is taken to
 * stand with the rig's lowest rest joint on the ground, so the translation is
 * the pelvis's displacement from there; with `recenter` frame 0 is then moved
 * to x = z = 0 facing +Z. Known rigs' units come first (cgspeed's CMU
 * conversion: 0.056444 m; Mixamo: cm).
 *
 * References: Meredith and Maddock 2001, "Motion capture file formats
 * explained" (BVH); Blender's io_anim_bvh importer (channel order and
 * position semantics); the CMU mocap BVH conversion (cgspeed) and Mixamo's
 * rig for the joint names.
 */
#include "body/mannequin_internal.h"
#include "body/motion_internal.h"
#include "geom/io_text.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_JOINTS = 1024, NAME_MAX_LEN = 127, MIN_MAPPED = 12 };
enum { CH_XPOS, CH_YPOS, CH_ZPOS, CH_XROT, CH_YROT, CH_ZROT };
static const char *const channel_names[6] = {"Xposition", "Yposition", "Zposition",
                                             "Xrotation", "Yrotation", "Zrotation"};
static const double DEG = M_PI / 180.0;
static const double JOINT_HEIGHT_M = 1.65; /* head to toe joints of a 1.75 m person, m */
static const double FRAME_TIME_MAX = 10.0; /* s */
/* cgspeed's CMU BVH: the ASF's length unit, 0.45 inch scaled by 1 / 0.45 ...
 * as the conversion's readme gives it, (1 / 0.45) 2.54 / 100 m per unit. */
#define CMU_UNIT_M 0.056444

typedef struct bvh_joint {
    char name[NAME_MAX_LEN + 1];
    int parent; /* -1 for the root */
    int end_site;
    int has_offset;
    int line;
    double offset[3];
    int nchan;
    int chan[6];
    int col; /* first column of this joint's values in a frame line */
} bvh_joint;

typedef struct bvh_file {
    io_text t;
    bvh_joint *j;
    int n;
    int ncol; /* channel values per frame */
    int nframes;
    double frame_time; /* s */
    float *values;     /* (nframes, ncol) */
} bvh_file;

/* --------------------------------------------------------------- parsing -- */

static cr_status parse_fail(const bvh_file *b, const char *what, const char *tb, const char *te,
                            cr_error *err) {
    char snip[48] = "end of file";
    if (tb) cr_io_text_snippet(tb, te, snip, sizeof snip);
    return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %s, got '%s'", b->t.source,
                   (long long)b->t.line, what, snip);
}

/* Next token anywhere ahead; fails at the end of the input. */
static cr_status next_token(bvh_file *b, const char *what, const char **tb, const char **te,
                            cr_error *err) {
    int got;
    CR_TRY(cr_io_text_token_any(&b->t, tb, te, &got, err));
    if (!got) return parse_fail(b, what, NULL, NULL, err);
    return CR_OK;
}

static int token_is(const char *tb, const char *te, const char *word) {
    size_t n = strlen(word);
    return (size_t)(te - tb) == n && memcmp(tb, word, n) == 0;
}

static cr_status expect(bvh_file *b, const char *word, cr_error *err) {
    const char *tb, *te;
    char what[40];
    snprintf(what, sizeof what, "'%s'", word);
    CR_TRY(next_token(b, what, &tb, &te, err));
    if (!token_is(tb, te, word)) return parse_fail(b, what, tb, te, err);
    return CR_OK;
}

/* A joint name: the tokens up to '{' (which may end the last token). */
static cr_status parse_name(bvh_file *b, bvh_joint *jt, cr_error *err) {
    size_t n = 0;
    jt->name[0] = 0;
    for (;;) {
        const char *tb, *te;
        CR_TRY(next_token(b, "a joint name and '{'", &tb, &te, err));
        int brace = te[-1] == '{';
        if (brace) te--;
        if (te > tb) {
            if (n + (n > 0) + (size_t)(te - tb) > NAME_MAX_LEN)
                return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: joint name longer than %d bytes",
                               b->t.source, (long long)b->t.line, NAME_MAX_LEN);
            if (n) jt->name[n++] = ' ';
            memcpy(jt->name + n, tb, (size_t)(te - tb));
            n += (size_t)(te - tb);
            jt->name[n] = 0;
        }
        if (brace) break;
    }
    if (n == 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: joint without a name", b->t.source,
                       (long long)b->t.line);
    return CR_OK;
}

static cr_status add_joint(bvh_file *b, int parent, int end_site, cr_error *err) {
    if (b->n == MAX_JOINTS)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: more than %d joints", b->t.source,
                       (long long)b->t.line, MAX_JOINTS);
    bvh_joint *jt = &b->j[b->n++];
    memset(jt, 0, sizeof *jt);
    jt->parent = parent;
    jt->end_site = end_site;
    jt->line = (int)b->t.line;
    if (end_site) {
        snprintf(jt->name, sizeof jt->name, "End Site");
        return expect(b, "{", err);
    }
    return parse_name(b, jt, err);
}

static cr_status parse_channels(bvh_file *b, bvh_joint *jt, cr_error *err) {
    const char *tb, *te;
    int64_t n;
    CR_TRY(next_token(b, "a channel count", &tb, &te, err));
    CR_TRY(cr_io_text_int(&b->t, tb, te, "channel count", &n, err));
    if (jt->end_site || jt->nchan || n < 0 || n > 6)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s:%lld: CHANNELS %lld (0 to 6, once per joint, none in an End Site)",
                       b->t.source, (long long)b->t.line, (long long)n);
    for (int k = 0; k < (int)n; k++) {
        CR_TRY(next_token(b, "a channel name", &tb, &te, err));
        int c = -1;
        for (int i = 0; i < 6; i++)
            if (token_is(tb, te, channel_names[i])) c = i;
        for (int i = 0; i < k && c >= 0; i++)
            if (jt->chan[i] == c) c = -2;
        if (c < 0)
            return parse_fail(b,
                              c == -2 ? "a channel not listed before" : "Xposition ... Zrotation",
                              tb, te, err);
        jt->chan[k] = c;
    }
    jt->nchan = (int)n;
    jt->col = b->ncol;
    b->ncol += (int)n;
    return CR_OK;
}

static cr_status parse_hierarchy(bvh_file *b, cr_error *err) {
    CR_TRY(expect(b, "HIERARCHY", err));
    CR_TRY(expect(b, "ROOT", err));
    CR_TRY(add_joint(b, -1, 0, err));
    int cur = 0;
    while (cur >= 0) {
        const char *tb, *te;
        CR_TRY(next_token(b, "OFFSET, CHANNELS, JOINT, End Site or '}'", &tb, &te, err));
        bvh_joint *jt = &b->j[cur];
        if (token_is(tb, te, "OFFSET")) {
            if (jt->has_offset)
                return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: second OFFSET for '%s'", b->t.source,
                               (long long)b->t.line, jt->name);
            for (int k = 0; k < 3; k++) {
                CR_TRY(next_token(b, "an offset coordinate", &tb, &te, err));
                CR_TRY(cr_io_text_double(&b->t, tb, te, "offset coordinate", &jt->offset[k], err));
            }
            jt->has_offset = 1;
        } else if (token_is(tb, te, "CHANNELS")) {
            CR_TRY(parse_channels(b, jt, err));
        } else if (token_is(tb, te, "JOINT") || token_is(tb, te, "End")) {
            int end = token_is(tb, te, "End");
            if (jt->end_site)
                return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: an End Site has no children",
                               b->t.source, (long long)b->t.line);
            if (end) CR_TRY(expect(b, "Site", err));
            CR_TRY(add_joint(b, cur, end, err));
            cur = b->n - 1;
        } else if (token_is(tb, te, "}")) {
            if (!jt->has_offset)
                return CR_FAIL(err, CR_ERR_PARSE, "%s:%d: '%s' has no OFFSET", b->t.source,
                               jt->line, jt->name);
            cur = jt->parent;
        } else if (token_is(tb, te, "ROOT")) {
            return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s:%lld: a second ROOT (one skeleton only)",
                           b->t.source, (long long)b->t.line);
        } else {
            return parse_fail(b, "OFFSET, CHANNELS, JOINT, End Site or '}'", tb, te, err);
        }
    }
    if (b->ncol == 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: the skeleton has no channels", b->t.source);
    return CR_OK;
}

static cr_status parse_motion(bvh_file *b, cr_error *err) {
    const char *tb, *te;
    int64_t nframes;
    CR_TRY(expect(b, "MOTION", err));
    CR_TRY(expect(b, "Frames:", err));
    CR_TRY(next_token(b, "a frame count", &tb, &te, err));
    CR_TRY(cr_io_text_int(&b->t, tb, te, "frame count", &nframes, err));
    CR_TRY(expect(b, "Frame", err));
    CR_TRY(expect(b, "Time:", err));
    CR_TRY(next_token(b, "a frame time", &tb, &te, err));
    CR_TRY(cr_io_text_double(&b->t, tb, te, "frame time", &b->frame_time, err));
    if (!(b->frame_time > 0 && b->frame_time <= FRAME_TIME_MAX))
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: Frame Time %g s, expected (0, %g]", b->t.source,
                       (long long)b->t.line, b->frame_time, FRAME_TIME_MAX);
    if (nframes < 1 || nframes > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: %lld frames declared", b->t.source,
                       (long long)b->t.line, (long long)nframes);
    if (cr_io_text_token(&b->t, &tb, &te)) return parse_fail(b, "the end of the line", tb, te, err);
    b->nframes = (int)nframes;
    /* Rows grow with the lines actually read, so a huge declared count costs nothing. */
    int cap = 0, f = 0;
    for (;;) {
        int got;
        CR_TRY(cr_io_text_next_line(&b->t, &got, err));
        if (!got) break;
        if (!cr_io_text_token(&b->t, &tb, &te)) continue; /* blank line */
        if (f == b->nframes)
            return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: more frame lines than the %d declared",
                           b->t.source, (long long)b->t.line, b->nframes);
        if (f == cap) {
            int64_t want = cap ? 2 * (int64_t)cap : 64;
            cap = (int)(want < b->nframes ? want : b->nframes);
            float *grown = realloc(b->values, (size_t)cap * (size_t)b->ncol * sizeof(float));
            if (!grown) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", b->t.source);
            b->values = grown;
        }
        int k = 0;
        float *row = b->values + (size_t)f * (size_t)b->ncol;
        do {
            if (k < b->ncol) CR_TRY(cr_io_text_float(&b->t, tb, te, "channel value", &row[k], err));
            k++;
        } while (cr_io_text_token(&b->t, &tb, &te));
        if (k != b->ncol)
            return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %d channel values, got %d",
                           b->t.source, (long long)b->t.line, b->ncol, k);
        f++;
    }
    if (f != b->nframes)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %d frames, found %d (truncated?)",
                       b->t.source, (long long)b->t.line, b->nframes, f);
    return CR_OK;
}

/* --------------------------------------------------------------- mapping -- */

typedef struct bvh_rig {
    const char *name;
    const char *joints[CR_NJOINTS]; /* normalised candidates, '|'-separated, best first */
    /* The rig's known unit, m, taken when its rest height (units) is in
     * [unit_lo, unit_hi]; 0: infer from the height. */
    double unit_m, unit_lo, unit_hi;
} bvh_rig;

static const bvh_rig rigs[] = {
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
};
enum { NRIGS = sizeof rigs / sizeof rigs[0] };

static void normalise(const char *name, char *out, size_t cap) {
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
static int find_candidate(char (*norm)[NAME_MAX_LEN + 1], const bvh_file *b, const char *cands) {
    const char *c = cands;
    while (*c) {
        const char *bar = strchr(c, '|');
        size_t len = bar ? (size_t)(bar - c) : strlen(c);
        for (int i = 0; i < b->n; i++)
            if (!b->j[i].end_site && strlen(norm[i]) == len && memcmp(norm[i], c, len) == 0)
                return i;
        c += len + (bar != NULL);
    }
    return -1;
}

static int is_ancestor(const bvh_file *b, int anc, int j) {
    for (j = b->j[j].parent; j >= 0; j = b->j[j].parent)
        if (j == anc) return 1;
    return 0;
}

static cr_status map_joints(const bvh_file *b, int map[CR_NJOINTS], int *rig, cr_error *err) {
    char(*norm)[NAME_MAX_LEN + 1] = cr_malloc((size_t)b->n * sizeof *norm, err);
    if (!norm) return CR_ERR_MEMORY;
    for (int i = 0; i < b->n; i++)
        normalise(b->j[i].name, norm[i], sizeof norm[i]);
    int best = 0, best_score = -1;
    for (int r = 0; r < NRIGS; r++) {
        int score = 0, tmp[CR_NJOINTS];
        for (int j = 0; j < CR_NJOINTS; j++)
            score += (tmp[j] = find_candidate(norm, b, rigs[r].joints[j])) >= 0;
        if (tmp[0] < 0) score = 0;
        if (score > best_score) {
            best = r, best_score = score;
            memcpy(map, tmp, sizeof tmp);
        }
    }
    free(norm);
    if (best_score < MIN_MAPPED) {
        char names[240];
        int n = 0;
        for (int i = 0; i < b->n && n < (int)sizeof names - 40; i++)
            if (!b->j[i].end_site)
                n += snprintf(names + n, sizeof names - (size_t)n, "%s%s", n ? ", " : "",
                              b->j[i].name);
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: cannot map the skeleton onto SMPL's joints: the best rig (%s) "
                       "matches %d of 22 (known: SMPL, Mixamo, CMU, DAZ/Poser names; joints "
                       "here: %s)",
                       b->t.source, rigs[best].name, best_score, names);
    }
    for (int j = 1; j < CR_NJOINTS; j++) {
        if (map[j] < 0) continue;
        int a = cr_joint_parent[j];
        while (map[a] < 0)
            a = cr_joint_parent[a];
        if (!is_ancestor(b, map[a], map[j]))
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%d: joint '%s' (taken as SMPL's %s) is not below '%s' (%s)",
                           b->t.source, b->j[map[j]].line, b->j[map[j]].name, cr_joint_name[j],
                           b->j[map[a]].name, cr_joint_name[a]);
    }
    cr_log(CR_LOG_DEBUG, "%s: %s rig, %d of 22 joints mapped", b->t.source, rigs[best].name,
           best_score);
    *rig = best;
    return CR_OK;
}

/* -------------------------------------------------------------- the frame -- */

/* Rest positions in file units: the OFFSETs accumulated. */
static void rest_positions(const bvh_file *b, double (*p)[3]) {
    for (int i = 0; i < b->n; i++)
        for (int k = 0; k < 3; k++)
            p[i][k] = b->j[i].offset[k] + (b->j[i].parent >= 0 ? p[b->j[i].parent][k] : 0.0);
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

/* The joints "up" runs to from the pelvis, the first the rig has. */
static const int up_ends[] = {CR_JOINT_HEAD, CR_JOINT_NECK, CR_JOINT_SPINE3, CR_JOINT_SPINE2};

/* The rig's up and left as signed coordinate axes, from joint positions p:
 * pelvis to head, right to left hip. 0 when they cannot be told. */
static int rig_axes(const int map[CR_NJOINTS], double (*p)[3], int *up_axis, int *up_sign,
                    int *left_axis, int *left_sign) {
    static const int lr[][2] = {{CR_JOINT_LEFT_HIP, CR_JOINT_RIGHT_HIP},
                                {CR_JOINT_LEFT_SHOULDER, CR_JOINT_RIGHT_SHOULDER},
                                {CR_JOINT_LEFT_KNEE, CR_JOINT_RIGHT_KNEE}};
    double up[3] = {0}, left[3] = {0};
    *up_axis = -1, *left_axis = -1, *up_sign = 1, *left_sign = 1;
    for (int i = 0; i < 4 && *up_axis < 0; i++)
        if (map[up_ends[i]] >= 0) {
            for (int k = 0; k < 3; k++)
                up[k] = p[map[up_ends[i]]][k] - p[map[0]][k];
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

/* The turn taking signed axis `up` to +Y and `left` to +X. */
static void axes_turn(int up_axis, int up_sign, int left_axis, int left_sign, double q[4]) {
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

/* The turn taking the rig's up to +Y and its left to +X, from rest positions;
 * the up it found as a signed axis. */
static cr_status rig_frame(const bvh_file *b, const int map[CR_NJOINTS], double (*p)[3],
                           double q[4], int *up_axis, int *up_sign, cr_error *err) {
    int la, ls;
    if (!rig_axes(map, p, up_axis, up_sign, &la, &ls))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: cannot tell the rig's up and left axes from its rest pose (pelvis "
                       "to head, right to left hip)",
                       b->t.source);
    axes_turn(*up_axis, *up_sign, la, ls, q);
    return CR_OK;
}

static double rig_scale(const bvh_file *b, int rig, double (*p)[3], const double turn[4],
                        double given) {
    if (given > 0) return given;
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < b->n; i++) {
        double v[3];
        q_rotate(turn, p[i], v);
        lo = fmin(lo, v[1]), hi = fmax(hi, v[1]);
    }
    double h = hi - lo;
    /* Known rigs first: cgspeed's CMU conversion keeps the ASF's unit (0.45
     * inch, a joint height of about 24 units) and Mixamo writes centimetres. */
    if (rigs[rig].unit_m > 0 && h >= rigs[rig].unit_lo && h <= rigs[rig].unit_hi) {
        cr_log(rigs[rig].unit_m != 0.01 ? CR_LOG_INFO : CR_LOG_DEBUG,
               "%s: %s rig, %g units high: %g m per unit", b->t.source, rigs[rig].name, h,
               rigs[rig].unit_m);
        return rigs[rig].unit_m;
    }
    if (h >= 0.8 && h <= 3.0) return 1.0;
    if (h >= 80.0 && h <= 300.0) return 0.01;
    double s = h > 1e-9 ? JOINT_HEIGHT_M / h : 1.0;
    cr_log(CR_LOG_WARN,
           "%s: rig height %g units is neither metres nor centimetres: scaled by %g to %g m",
           b->t.source, h, s, JOINT_HEIGHT_M);
    return s;
}

/* World rotations and positions of every joint in one frame (file units). */
static void frame_pose(const bvh_file *b, const float *row, double (*w)[4], double (*pos)[3]) {
    for (int i = 0; i < b->n; i++) {
        const bvh_joint *jt = &b->j[i];
        double q[4], t[3] = {jt->offset[0], jt->offset[1], jt->offset[2]};
        q_identity(q);
        for (int c = 0; c < jt->nchan; c++) {
            int ch = jt->chan[c];
            if (ch < CH_XROT) {
                t[ch] = row[jt->col + c];
                continue;
            }
            double r[4];
            q_axis(ch == CH_XROT, ch == CH_YROT, ch == CH_ZROT, row[jt->col + c] * DEG, r);
            q_mul(q, r, q);
        }
        if (jt->parent >= 0) {
            q_mul(w[jt->parent], q, w[i]);
            q_rotate(w[jt->parent], t, t);
            for (int k = 0; k < 3; k++)
                pos[i][k] = pos[jt->parent][k] + t[k];
        } else {
            memcpy(w[i], q, sizeof q);
            memcpy(pos[i], t, sizeof t);
        }
    }
}

static int unit3(const double v[3], double out[3], double eps) {
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(n > eps) || !isfinite(n)) return 0; /* degenerate, or offsets past double's range */
    for (int k = 0; k < 3; k++)
        out[k] = v[k] / n;
    return 1;
}

/* Whether a skeleton at positions p stands: the legs (pelvis to the ankles,
 * or the knees) point against the spine (pelvis to head). 1 when a rig lacks
 * them (nothing to go by). A joint-oriented bind pose with every bone along
 * one axis does not. */
static int stands(const int map[CR_NJOINTS], double (*p)[3]) {
    static const int legs[][2] = {{CR_JOINT_LEFT_ANKLE, CR_JOINT_RIGHT_ANKLE},
                                  {CR_JOINT_LEFT_KNEE, CR_JOINT_RIGHT_KNEE}};
    int top = -1, l = -1;
    for (int i = 0; i < 4 && top < 0; i++)
        if (map[up_ends[i]] >= 0) top = map[up_ends[i]];
    for (int i = 0; i < 2 && l < 0; i++)
        if (map[legs[i][0]] >= 0 && map[legs[i][1]] >= 0) l = i;
    if (top < 0 || l < 0) return 1;
    double up[3], down[3];
    for (int k = 0; k < 3; k++) {
        up[k] = p[top][k] - p[map[0]][k];
        down[k] = 0.5 * (p[map[legs[l][0]]][k] + p[map[legs[l][1]]][k]) - p[map[0]][k];
    }
    if (!unit3(up, up, 1e-12) || !unit3(down, down, 1e-12)) return 0;
    return up[0] * down[0] + up[1] * down[1] + up[2] * down[2] < -0.5;
}

/* The world's up as the motion itself stands: pelvis to head in up to 64
 * frames spread over the clip, snapped to a signed axis, by vote. Where it
 * differs from the rest pose's (a joint-oriented rig whose bind skeleton lies
 * along another axis, as Maya and LAFAN1-style exports write them) the
 * frames are right and the rest pose's turn would lay the body down. Returns
 * 0 when fewer than half the frames agree on one axis (a clip spent lying or
 * tumbling: the rest pose is kept). *standing: the first of those frames that
 * stands along the winning axis (stands()), -1 when none does. */
static int posed_up(const bvh_file *b, const int map[CR_NJOINTS], double (*w)[4], double (*pos)[3],
                    int *up_axis, int *up_sign, int *agree, int *sampled, int32_t *standing) {
    int votes[6] = {0}, n = b->nframes < 64 ? b->nframes : 64;
    int32_t first[6] = {-1, -1, -1, -1, -1, -1};
    for (int i = 0; i < n; i++) {
        int32_t f = (int32_t)((int64_t)i * b->nframes / n);
        int ua, us, la, ls;
        frame_pose(b, b->values + (size_t)f * (size_t)b->ncol, w, pos);
        if (!rig_axes(map, pos, &ua, &us, &la, &ls)) continue;
        votes[2 * ua + (us < 0)]++;
        if (first[2 * ua + (us < 0)] < 0 && stands(map, pos)) first[2 * ua + (us < 0)] = f;
    }
    int best = 0;
    for (int k = 1; k < 6; k++)
        if (votes[k] > votes[best]) best = k;
    *up_axis = best / 2, *up_sign = best % 2 ? -1 : 1, *agree = votes[best], *sampled = n;
    *standing = first[best];
    return 2 * votes[best] > n;
}

/* ----------------------------------------------------------- retargeting -- */

/* The bone each SMPL joint turns: towards this child (-1: a leaf, which
 * moves with its parent's alignment). */
static const int8_t bone_child[CR_NJOINTS] = {3,  4,  5,  6,  7,  8,  9,  10, 11, 12, -1,
                                              -1, 15, 16, 17, -1, 18, 19, 20, 21, -1, -1};

/* Retargeting by bone directions. For SMPL joint j with bone child c, d_j is
 * the rig's rest bone (rig joint of j to rig joint of c) and e_j the body's
 * (canonical mannequin, turned into the rig's frame); A_j carries e_j onto
 * d_j by the shortest arc. A frame's world rotation of j is then
 * Q_j W_j A_j, W_j the rig joint's world rotation and Q_j the shortest arc
 * from W_j A_j e_j to the rig's bone as posed (the identity unless folded
 * joints lie between the two, CMU's Neck1). So the body's bone points where
 * the rig's does, with the rig's twist about it. */
typedef struct retarget {
    int child[CR_NJOINTS];   /* bone end per joint (descending past missing, coincident ones) */
    double e[CR_NJOINTS][3]; /* the body's rest bone, unit, rig frame */
    double align[CR_NJOINTS][4];
} retarget;

static void shortest_arc(const double a[3], const double b[3], double q[4]) {
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

/* turn: the file's frame to crease's; rest_turn: the rest pose's own upright
 * frame to crease's, which differs from turn when the bind skeleton lies
 * along another axis than the motion stands: each bone is then matched after
 * standing the rest pose up (D below), so a bone along the axis of that turn
 * keeps its twist, which a shortest arc alone would lose.
 *
 * ref_w: NULL to match against the rest pose (ref its positions). Otherwise
 * ref and ref_w are a standing frame's joint positions and world rotations,
 * for a bind pose that does not stand (stands()): a shortest arc from the
 * mannequin's bone to such a rest bone twists arbitrarily, so the bones are
 * matched as they stand in that frame, A_j = W_j^-1 B_j with B_j the arc
 * from the mannequin's bone to the posed one, and the pelvis by its spine
 * and its hips both (a frame, not an arc: a half turn about the spine would
 * swap the legs). */
static void retarget_setup(const int map[CR_NJOINTS], double (*ref)[3], double (*ref_w)[4],
                           const double turn[4], const double rest_turn[4], double height,
                           retarget *rt) {
    float canon[CR_NJOINTS * 3];
    cr_mannequin_def md = cr_mannequin_default_def();
    cr_mannequin_rest_joints(&md, canon);
    double turn_inv[4], stand[4], stand_inv[4];
    q_conj(turn, turn_inv);
    q_mul(turn_inv, rest_turn, stand); /* D: the rest pose stood along the motion's up */
    if (ref_w) q_identity(stand);
    q_conj(stand, stand_inv);
    for (int j = 0; j < CR_NJOINTS; j++) {
        int p = cr_joint_parent[j];
        rt->child[j] = -1;
        if (p >= 0)
            memcpy(rt->align[j], rt->align[p], sizeof rt->align[j]);
        else
            memcpy(rt->align[j], stand_inv, sizeof rt->align[j]);
        if (map[j] < 0) continue;
        for (int c = bone_child[j]; c >= 0; c = bone_child[c]) {
            if (map[c] < 0) continue;
            double d[3], e[3];
            for (int k = 0; k < 3; k++) {
                d[k] = ref[map[c]][k] - ref[map[j]][k];
                e[k] = (double)canon[3 * c + k] - (double)canon[3 * j + k];
            }
            q_rotate(turn_inv, e, e);
            q_rotate(stand, d, d);
            if (!unit3(d, d, 1e-3 * height) || !unit3(e, e, 1e-6)) continue;
            rt->child[j] = c;
            memcpy(rt->e[j], e, sizeof e);
            double arc[4];
            shortest_arc(e, d, arc);
            if (!ref_w) {
                q_mul(stand_inv, arc, rt->align[j]);
                break;
            }
            const int lh = map[CR_JOINT_LEFT_HIP], rh = map[CR_JOINT_RIGHT_HIP];
            if (p < 0 && lh >= 0 && rh >= 0) {
                /* the twist about the spine that turns the mannequin's hips onto the rig's */
                double el[3], dl[3], v[3];
                for (int k = 0; k < 3; k++) {
                    el[k] = (double)canon[3 * CR_JOINT_LEFT_HIP + k] -
                            (double)canon[3 * CR_JOINT_RIGHT_HIP + k];
                    dl[k] = ref[lh][k] - ref[rh][k];
                }
                q_rotate(turn_inv, el, el);
                q_rotate(arc, el, v);
                double vd = v[0] * d[0] + v[1] * d[1] + v[2] * d[2];
                double ld = dl[0] * d[0] + dl[1] * d[1] + dl[2] * d[2];
                for (int k = 0; k < 3; k++)
                    v[k] -= vd * d[k], dl[k] -= ld * d[k];
                if (unit3(v, v, 1e-9) && unit3(dl, dl, 1e-9)) {
                    double twist[4];
                    shortest_arc(v, dl, twist); /* about d: both are perpendicular to it */
                    q_mul(twist, arc, arc);
                }
            }
            double w_inv[4];
            q_conj(ref_w[map[j]], w_inv);
            q_mul(w_inv, arc, rt->align[j]);
            break;
        }
    }
}

/* World rotations of SMPL's joints in one frame, in the rig's frame. */
static void retarget_frame(const retarget *rt, const int map[CR_NJOINTS], double (*w)[4],
                           double (*pos)[3], double g[CR_NJOINTS][4]) {
    for (int j = 0; j < CR_NJOINTS; j++) {
        int p = cr_joint_parent[j];
        if (map[j] < 0) {
            memcpy(g[j], g[p], sizeof g[j]);
            continue;
        }
        q_mul(w[map[j]], rt->align[j], g[j]);
        int c = rt->child[j];
        if (c < 0) continue;
        double cur[3], act[3], q[4];
        q_rotate(g[j], rt->e[j], cur);
        for (int k = 0; k < 3; k++)
            act[k] = pos[map[c]][k] - pos[map[j]][k];
        if (!unit3(act, act, 1e-12)) continue;
        shortest_arc(cur, act, q);
        q_mul(q, g[j], g[j]);
    }
}

static cr_status build_motion(const bvh_file *b, const cr_motion_import_def *def, cr_motion **out,
                              cr_error *err) {
    int map[CR_NJOINTS], rig = 0;
    CR_TRY(map_joints(b, map, &rig, err));
    double(*rest)[3] = cr_malloc((size_t)b->n * sizeof *rest, err);
    double(*w)[4] = cr_malloc((size_t)b->n * sizeof *w, err);
    double(*pos)[3] = cr_malloc((size_t)b->n * sizeof *pos, err);
    double(*stand_pos)[3] = cr_malloc((size_t)b->n * sizeof *stand_pos, err);
    double(*stand_w)[4] = cr_malloc((size_t)b->n * sizeof *stand_w, err);
    cr_motion *m = NULL;
    cr_status st = rest && w && pos && stand_pos && stand_w ? CR_OK : CR_ERR_MEMORY;
    motion_frame_fix fix = {.conjugate = 1, .recenter = def->recenter};
    double rest_turn[4] = {1, 0, 0, 0}; /* the rest pose's own upright frame: its height and feet */
    int rest_axis = 1, rest_sign = 1;   /* the file axis the rest pose calls up */
    if (st == CR_OK) {
        rest_positions(b, rest);
        st = rig_frame(b, map, rest, rest_turn, &rest_axis, &rest_sign, err);
        memcpy(fix.world, rest_turn, sizeof rest_turn);
    }
    int up_axis, up_sign, agree, sampled;
    int32_t standing = -1;
    if (st == CR_OK && posed_up(b, map, w, pos, &up_axis, &up_sign, &agree, &sampled, &standing) &&
        (up_axis != rest_axis || up_sign != rest_sign)) {
        /* left: the first other axis in x, z, y order, so a Y-up file keeps its
         * heading and a Z-up one turns as (x, y, z) -> (x, z, -y) */
        axes_turn(up_axis, up_sign, up_axis == 0 ? 2 : 0, 1, fix.world);
        cr_log(CR_LOG_WARN,
               "%s: the rest skeleton stands along %c%c but the motion along %c%c (%d of %d "
               "frames): the motion's up is used",
               b->t.source, rest_sign > 0 ? '+' : '-', "XYZ"[rest_axis], up_sign > 0 ? '+' : '-',
               "XYZ"[up_axis], agree, sampled);
    }
    /* The height that gives the unit and the feet: the rest pose's, or where
     * it does not stand, the first standing frame's */
    double(*size_pose)[3] = rest;
    const double *size_turn = rest_turn;
    if (st == CR_OK && !stands(map, rest) && standing >= 0) {
        frame_pose(b, b->values + (size_t)standing * (size_t)b->ncol, stand_w, stand_pos);
        size_pose = stand_pos, size_turn = fix.world;
        cr_log(CR_LOG_WARN,
               "%s: the rest skeleton does not stand (legs along the spine): its height and "
               "feet are read from frame %d",
               b->t.source, (int)standing);
    }
    double fps = 1.0 / b->frame_time;
    if (fabs(fps - round(fps)) < 0.01) fps = round(fps); /* 0.0333333 s is 30 fps */
    if (st == CR_OK) st = cr_motion_create(b->nframes, (float)fps, &m, err);
    if (st == CR_OK) {
        double s = rig_scale(b, rig, size_pose, size_turn, def->bvh_scale), lowest = INFINITY,
               highest = -INFINITY, root_up[3];
        for (int i = 0; i < b->n; i++) {
            double v[3];
            q_rotate(size_turn, size_pose[i], v);
            lowest = fmin(lowest, s * v[1]), highest = fmax(highest, s * v[1]);
        }
        retarget rt;
        if (def->retarget)
            retarget_setup(map, size_pose, size_pose == rest ? NULL : stand_w, fix.world, rest_turn,
                           (highest - lowest) / s, &rt);
        q_rotate(fix.world, rest[map[0]], fix.origin);
        q_rotate(size_turn, size_pose[map[0]], root_up);
        for (int k = 0; k < 3; k++)
            fix.origin[k] *= s;
        fix.origin[1] = s * root_up[1] - lowest; /* the root's height over the feet */
        for (int f = 0; f < b->nframes; f++) {
            double wj[CR_NJOINTS][4];
            frame_pose(b, b->values + (size_t)f * (size_t)b->ncol, w, pos);
            if (def->retarget) retarget_frame(&rt, map, w, pos, wj);
            float *pose = m->poses + (size_t)f * CR_NJOINTS * 3;
            for (int j = 0; j < CR_NJOINTS; j++) {
                int p = cr_joint_parent[j];
                if (!def->retarget) {
                    if (map[j] >= 0)
                        memcpy(wj[j], w[map[j]], sizeof wj[j]);
                    else
                        memcpy(wj[j], wj[p], sizeof wj[j]);
                }
                double local[4];
                if (p < 0) {
                    memcpy(local, wj[j], sizeof local);
                } else {
                    double inv[4];
                    q_conj(wj[p], inv);
                    q_mul(inv, wj[j], local);
                }
                q_to_aa(local, pose + 3 * j);
            }
            for (int k = 0; k < 3; k++)
                m->trans[(size_t)f * 3 + (size_t)k] = (float)(s * pos[map[0]][k]);
        }
        cr_motion_fix_frame(m, &fix);
    }
    free(rest);
    free(w);
    free(pos);
    free(stand_pos);
    free(stand_w);
    if (st != CR_OK) {
        cr_motion_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_motion_read_bvh_mem(const void *data, size_t len, const char *source,
                                 const cr_motion_import_def *def, cr_motion **out, cr_error *err) {
    *out = NULL;
    cr_motion_import_def defaults = cr_motion_import_default_def();
    if (!def) def = &defaults;
    CR_ASSERT(def->cookie == MOTION_IMPORT_COOKIE);
    if (!(def->bvh_scale >= 0 && isfinite(def->bvh_scale)))
        return CR_FAIL(err, CR_ERR_INVALID, "bvh_scale %g: expected 0 (infer) or a positive scale",
                       (double)def->bvh_scale);
    bvh_file b;
    memset(&b, 0, sizeof b);
    cr_io_text_init(&b.t, data, len, source);
    b.j = cr_malloc(MAX_JOINTS * sizeof *b.j, err);
    if (!b.j) return CR_ERR_MEMORY;
    cr_status st = parse_hierarchy(&b, err);
    if (st == CR_OK) st = parse_motion(&b, err);
    if (st == CR_OK) st = build_motion(&b, def, out, err);
    free(b.j);
    free(b.values);
    return st;
}
