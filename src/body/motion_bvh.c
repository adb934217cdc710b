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
 * joint is retargeted by bone directions (retarget.c): its bone points
 * where the rig's bone points, with the rig's twist, whatever rest the rig
 * was written against. Unmapped joints between two mapped ones (CMU's
 * LHipJoint, Neck1, a DAZ chestLower) fold into the child below them, and an
 * SMPL joint the rig lacks (a collar) moves with its parent. Joints below the
 * mapped ones (fingers, toe ends) are dropped, and so are translations of
 * joints other than the pelvis.
 *
 * Frame and lengths: the file is a source rig (its OFFSETs accumulated as
 * the rest, each frame's world rotations and positions) of
 * retarget_drive.c, which turns it upright, gives it its unit (known rigs'
 * first: cgspeed's CMU conversion 0.056444 m, Mixamo cm) and drives the
 * target.
 *
 * References: Meredith and Maddock 2001, "Motion capture file formats
 * explained" (BVH); Blender's io_anim_bvh importer (channel order and
 * position semantics); the CMU mocap BVH conversion (cgspeed) and Mixamo's
 * rig for the joint names.
 */
#include "body/mannequin_internal.h"
#include "body/retarget_internal.h"
#include "geom/io_text.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_JOINTS = 1024, NAME_MAX_LEN = 127, MIN_MAPPED = 12 };
enum { CH_XPOS, CH_YPOS, CH_ZPOS, CH_XROT, CH_YROT, CH_ZROT };
static const char *const channel_names[6] = {"Xposition", "Yposition", "Zposition",
                                             "Xrotation", "Yrotation", "Zrotation"};
static const double DEG = M_PI / 180.0;
static const double FRAME_TIME_MAX = 10.0; /* s */

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

/* The whole file parsed into b (freed with bvh_free, also on failure). */
static cr_status bvh_parse(const void *data, size_t len, const char *source, bvh_file *b,
                           cr_error *err) {
    memset(b, 0, sizeof *b);
    cr_io_text_init(&b->t, data, len, source);
    b->j = cr_malloc(MAX_JOINTS * sizeof *b->j, err);
    if (!b->j) return CR_ERR_MEMORY;
    CR_TRY(parse_hierarchy(b, err));
    return parse_motion(b, err);
}

static void bvh_free(bvh_file *b) {
    free(b->j);
    free(b->values);
    b->j = NULL, b->values = NULL;
}

/* --------------------------------------------------------------- mapping -- */

static int is_ancestor(const bvh_file *b, int anc, int j) {
    for (j = b->j[j].parent; j >= 0; j = b->j[j].parent)
        if (j == anc) return 1;
    return 0;
}

/* The roles of the joints named `names` (b->n; NULL for End Sites). */
static cr_status map_joints(const bvh_file *b, const char *const *names, int map[CR_NJOINTS],
                            int *rig, cr_error *err) {
    int best_score = cr_retarget_match_roles(b->n, names, map, rig);
    if (best_score < MIN_MAPPED) {
        char list[240];
        int n = 0;
        for (int i = 0; i < b->n && n < (int)sizeof list - 40; i++)
            if (!b->j[i].end_site)
                n += snprintf(list + n, sizeof list - (size_t)n, "%s%s", n ? ", " : "",
                              b->j[i].name);
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: cannot map the skeleton onto SMPL's joints: the best rig (%s) "
                       "matches %d of 22 (known: %s names; joints here: %s)",
                       b->t.source, cr_retarget_rig_name(*rig), best_score, cr_retarget_rig_list,
                       list);
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
    cr_log(CR_LOG_DEBUG, "%s: %s rig, %d of 22 joints mapped", b->t.source,
           cr_retarget_rig_name(*rig), best_score);
    return CR_OK;
}

/* -------------------------------------------------------------- the frame -- */

/* Rest positions in file units: the OFFSETs accumulated. */
static void rest_positions(const bvh_file *b, double (*p)[3]) {
    for (int i = 0; i < b->n; i++)
        for (int k = 0; k < 3; k++)
            p[i][k] = b->j[i].offset[k] + (b->j[i].parent >= 0 ? p[b->j[i].parent][k] : 0.0);
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

static void source_pose(const rt_source *s, int32_t f, double (*w)[4], double (*pos)[3]) {
    const bvh_file *b = s->ctx;
    frame_pose(b, b->values + (size_t)f * (size_t)b->ncol, w, pos);
}

/* Frames per second of the file: 0.0333333 s is 30 fps. */
static double bvh_fps(const bvh_file *b) {
    double fps = 1.0 / b->frame_time;
    return fabs(fps - round(fps)) < 0.01 ? round(fps) : fps;
}

/* The file as a source rig: names (NULL for End Sites), parents and rest
 * positions (its OFFSETs accumulated) into the caller's arrays of b->n. */
static rt_source bvh_source(const bvh_file *b, const char **names, int *parent, double (*rest)[3]) {
    for (int i = 0; i < b->n; i++) {
        names[i] = b->j[i].end_site ? NULL : b->j[i].name;
        parent[i] = b->j[i].parent;
    }
    rest_positions(b, rest);
    return (rt_source){.source = b->t.source,
                       .n = b->n,
                       .name = names,
                       .parent = parent,
                       .rest = rest,
                       .nframes = b->nframes,
                       .fps = bvh_fps(b),
                       .pose = source_pose,
                       .ctx = b};
}

/* The file as a source rig with its roles: the arrays bvh_source fills, allocated together. */
typedef struct bvh_rig {
    const char **names;
    int *parent;
    double (*rest)[3];
    rt_source src;
    int map[CR_NJOINTS]; /* the joint given each SMPL role, or -1 */
    int rig;             /* the name table that matched */
} bvh_rig;

static void bvh_rig_free(bvh_rig *r) {
    free(r->names), free(r->parent), free(r->rest);
}

static cr_status bvh_rig_open(const bvh_file *b, bvh_rig *r, cr_error *err) {
    r->names = cr_malloc((size_t)b->n * sizeof *r->names, err);
    r->parent = cr_malloc((size_t)b->n * sizeof *r->parent, err);
    r->rest = cr_malloc((size_t)b->n * sizeof *r->rest, err);
    if (!r->names || !r->parent || !r->rest) return CR_ERR_MEMORY;
    r->src = bvh_source(b, r->names, r->parent, r->rest);
    return map_joints(b, r->names, r->map, &r->rig, err);
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
    bvh_rig r = {0};
    cr_status st = bvh_parse(data, len, source, &b, err);
    if (st == CR_OK) st = bvh_rig_open(&b, &r, err);
    if (st == CR_OK) st = cr_retarget_onto_mannequin(&r.src, r.map, r.rig, def, out, err);
    bvh_rig_free(&r);
    bvh_free(&b);
    return st;
}

/* ------------------------------------------------- onto any skeleton -- */

cr_status cr_motion_retarget_bvh_mem(const void *data, size_t len, const char *source,
                                     const cr_glb_skin *skel, const char *skel_source,
                                     const cr_retarget_def *def, cr_skin_motion **out,
                                     cr_error *err) {
    *out = NULL;
    bvh_file b;
    bvh_rig r = {0};
    cr_status st = bvh_parse(data, len, source, &b, err);
    if (st == CR_OK) st = bvh_rig_open(&b, &r, err);
    if (st == CR_OK)
        st = cr_retarget_onto_character(&r.src, r.map, r.rig, skel, skel_source, def, out, err);
    bvh_rig_free(&r);
    bvh_free(&b);
    return st;
}

cr_status cr_motion_retarget_bvh(const char *path, const cr_glb_skin *skel, const char *skel_source,
                                 const cr_retarget_def *def, cr_skin_motion **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_motion_retarget_bvh_mem(buf, len, path, skel, skel_source, def, out, err);
    free(buf);
    return st;
}
