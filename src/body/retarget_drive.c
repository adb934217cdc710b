/* retarget_drive.c: a source rig's frames onto a target skeleton (the
 * mannequin, or any skinned character), one copy for every motion file: a
 * BVH (motion_bvh.c) and a rigged glTF character's own animation
 * (motion_glb.c).
 *
 * Frame: the rig's up axis (pelvis to head) and left axis (right to left
 * hip) are snapped to coordinate axes and the rig is turned so up is +Y and
 * left +X (the body facing +Z), which also reads Z-up files. Where the rest
 * skeleton stands along another axis than the frames do (a joint-oriented
 * bind pose lying along one axis), the frames' up wins, and the height and
 * feet come from the first standing frame. Lengths: with no scale given, a
 * known rig's unit when its height fits it (cgspeed's CMU conversion:
 * 0.056444 m; Mixamo: cm), else a rig 0.8 to 3 units high is taken as
 * metres, 80 to 300 as centimetres, anything else is scaled to a 1.65 m
 * joint height with a warning. The rest pelvis stands with the rig's lowest
 * rest joint on the ground, so the translation is the pelvis's displacement
 * from there; with `recenter` frame 0 is moved to x = z = 0 facing +Z.
 * Each target joint is then turned by bone directions (retarget.c).
 */
#include "body/mannequin_internal.h"
#include "body/retarget_internal.h"

#include <stdlib.h>
#include <string.h>

static const double JOINT_HEIGHT_M = 1.65; /* head to toe joints of a 1.75 m person, m */

/* The turn taking the rig's up to +Y and its left to +X, from rest positions;
 * the up it found as a signed axis. */
static cr_status rig_frame(const rt_source *s, const int map[CR_NJOINTS], double (*p)[3],
                           double q[4], int *up_axis, int *up_sign, cr_error *err) {
    int la, ls;
    if (!cr_retarget_rig_axes(map, p, up_axis, up_sign, &la, &ls))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: cannot tell the rig's up and left axes from its rest pose (pelvis "
                       "to head, right to left hip)",
                       s->source);
    cr_retarget_axes_turn(*up_axis, *up_sign, la, ls, q);
    return CR_OK;
}

static double rig_scale(const rt_source *s, int rig, double (*p)[3], const double turn[4],
                        double given) {
    if (given > 0) return given;
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < s->n; i++) {
        double v[3];
        q_rotate(turn, p[i], v);
        lo = fmin(lo, v[1]), hi = fmax(hi, v[1]);
    }
    double h = hi - lo;
    /* Known rigs first: cgspeed's CMU conversion keeps the ASF's unit (0.45
     * inch, a joint height of about 24 units) and Mixamo writes centimetres. */
    double unit_m, unit_lo, unit_hi;
    cr_retarget_rig_unit(rig, &unit_m, &unit_lo, &unit_hi);
    if (unit_m > 0 && h >= unit_lo && h <= unit_hi) {
        cr_log(unit_m != 0.01 ? CR_LOG_INFO : CR_LOG_DEBUG,
               "%s: %s rig, %g units high: %g m per unit", s->source, cr_retarget_rig_name(rig), h,
               unit_m);
        return unit_m;
    }
    if (h >= 0.8 && h <= 3.0) return 1.0;
    if (h >= 80.0 && h <= 300.0) return 0.01;
    double unit = h > 1e-9 ? JOINT_HEIGHT_M / h : 1.0;
    cr_log(CR_LOG_WARN,
           "%s: rig height %g units is neither metres nor centimetres: scaled by %g to %g m",
           s->source, h, unit, JOINT_HEIGHT_M);
    return unit;
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
        if (map[cr_retarget_up_ends[i]] >= 0) top = map[cr_retarget_up_ends[i]];
    for (int i = 0; i < 2 && l < 0; i++)
        if (map[legs[i][0]] >= 0 && map[legs[i][1]] >= 0) l = i;
    if (top < 0 || l < 0) return 1;
    double up[3], down[3];
    for (int k = 0; k < 3; k++) {
        up[k] = p[top][k] - p[map[0]][k];
        down[k] = 0.5 * (p[map[legs[l][0]]][k] + p[map[legs[l][1]]][k]) - p[map[0]][k];
    }
    if (!cr_retarget_unit3(up, up, 1e-12) || !cr_retarget_unit3(down, down, 1e-12)) return 0;
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
static int posed_up(const rt_source *s, const int map[CR_NJOINTS], double (*w)[4], double (*pos)[3],
                    int *up_axis, int *up_sign, int *agree, int *sampled, int32_t *standing) {
    int votes[6] = {0}, n = s->nframes < 64 ? s->nframes : 64;
    int32_t first[6] = {-1, -1, -1, -1, -1, -1};
    for (int i = 0; i < n; i++) {
        int32_t f = (int32_t)((int64_t)i * s->nframes / n);
        int ua, us, la, ls;
        s->pose(s, f, w, pos);
        if (!cr_retarget_rig_axes(map, pos, &ua, &us, &la, &ls)) continue;
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

cr_status cr_retarget_drive(const rt_source *s, const int map[CR_NJOINTS], int rig,
                            const cr_motion_import_def *def, const rt_target *tg, double *g,
                            double *t, double *hip_m, cr_error *err) {
    double(*rest)[3] = cr_malloc((size_t)s->n * sizeof *rest, err);
    double(*w)[4] = cr_malloc((size_t)s->n * sizeof *w, err);
    double(*pos)[3] = cr_malloc((size_t)s->n * sizeof *pos, err);
    double(*stand_pos)[3] = cr_malloc((size_t)s->n * sizeof *stand_pos, err);
    double(*stand_w)[4] = cr_malloc((size_t)s->n * sizeof *stand_w, err);
    cr_status st = rest && w && pos && stand_pos && stand_w ? CR_OK : CR_ERR_MEMORY;
    motion_frame_fix fix = {.conjugate = 1, .recenter = def->recenter};
    double rest_turn[4] = {1, 0, 0, 0}; /* the rest pose's own upright frame: its height and feet */
    int rest_axis = 1, rest_sign = 1;   /* the file axis the rest pose calls up */
    if (st == CR_OK) {
        memcpy(rest, s->rest, (size_t)s->n * sizeof *rest);
        st = rig_frame(s, map, rest, rest_turn, &rest_axis, &rest_sign, err);
        memcpy(fix.world, rest_turn, sizeof rest_turn);
    }
    int up_axis, up_sign, agree, sampled;
    int32_t standing = -1;
    if (st == CR_OK && posed_up(s, map, w, pos, &up_axis, &up_sign, &agree, &sampled, &standing) &&
        (up_axis != rest_axis || up_sign != rest_sign)) {
        /* left: the first other axis in x, z, y order, so a Y-up file keeps its
         * heading and a Z-up one turns as (x, y, z) -> (x, z, -y) */
        cr_retarget_axes_turn(up_axis, up_sign, up_axis == 0 ? 2 : 0, 1, fix.world);
        cr_log(CR_LOG_WARN,
               "%s: the rest skeleton stands along %c%c but the motion along %c%c (%d of %d "
               "frames): the motion's up is used",
               s->source, rest_sign > 0 ? '+' : '-', "XYZ"[rest_axis], up_sign > 0 ? '+' : '-',
               "XYZ"[up_axis], agree, sampled);
    }
    /* The height that gives the unit and the feet: the rest pose's, or where
     * it does not stand, the first standing frame's */
    double(*size_pose)[3] = rest;
    const double *size_turn = rest_turn;
    if (st == CR_OK && !stands(map, rest) && standing >= 0) {
        s->pose(s, standing, stand_w, stand_pos);
        size_pose = stand_pos, size_turn = fix.world;
        cr_log(CR_LOG_WARN,
               "%s: the rest skeleton does not stand (legs along the spine): its height and "
               "feet are read from frame %d",
               s->source, (int)standing);
    }
    rt_state rs = {0};
    if (st == CR_OK && def->retarget) st = cr_retarget_state_alloc(tg->n, &rs, err);
    if (st == CR_OK) {
        const double unit = rig_scale(s, rig, size_pose, size_turn, def->bvh_scale);
        double lowest = INFINITY, highest = -INFINITY, root_up[3];
        for (int i = 0; i < s->n; i++) {
            double v[3];
            q_rotate(size_turn, size_pose[i], v);
            lowest = fmin(lowest, unit * v[1]), highest = fmax(highest, unit * v[1]);
        }
        if (def->retarget)
            cr_retarget_setup(tg, size_pose, size_pose == rest ? NULL : stand_w, fix.world,
                              rest_turn, (highest - lowest) / unit, &rs);
        q_rotate(fix.world, rest[map[0]], fix.origin);
        q_rotate(size_turn, size_pose[map[0]], root_up);
        for (int k = 0; k < 3; k++)
            fix.origin[k] *= unit;
        fix.origin[1] = unit * root_up[1] - lowest; /* the root's height over the feet */
        for (int f = 0; f < s->nframes; f++) {
            double(*gf)[4] = (double(*)[4])(g + 4 * (size_t)f * (size_t)tg->n);
            s->pose(s, f, w, pos);
            if (def->retarget) cr_retarget_frame(tg, &rs, w, pos, gf);
            for (int j = 0; !def->retarget && j < tg->n; j++) {
                if (tg->src[j] >= 0)
                    memcpy(gf[j], w[tg->src[j]], sizeof gf[j]);
                else if (tg->parent[j] >= 0)
                    memcpy(gf[j], gf[tg->parent[j]], sizeof gf[j]);
                else
                    q_identity(gf[j]);
            }
            for (int k = 0; k < 3; k++)
                t[(size_t)f * 3 + (size_t)k] = unit * pos[map[0]][k];
        }
        cr_retarget_fix_world(g, tg->n, tg->pelvis, t, s->nframes, &fix);
        *hip_m = fix.origin[1];
    }
    cr_retarget_state_free(&rs);
    free(rest);
    free(w);
    free(pos);
    free(stand_pos);
    free(stand_w);
    return st;
}

cr_status cr_retarget_onto_mannequin(const rt_source *s, const int map[CR_NJOINTS], int rig,
                                     const cr_motion_import_def *def, cr_motion **out,
                                     cr_error *err) {
    *out = NULL;
    float canon[CR_NJOINTS * 3];
    cr_mannequin_def md = cr_mannequin_default_def();
    cr_mannequin_rest_joints(&md, canon);
    double rest[CR_NJOINTS][3];
    int parent[CR_NJOINTS], bone[CR_NJOINTS];
    for (int j = 0; j < CR_NJOINTS; j++) {
        for (int k = 0; k < 3; k++)
            rest[j][k] = canon[3 * j + k];
        parent[j] = cr_joint_parent[j], bone[j] = cr_retarget_bone_child_role[j];
    }
    const rt_target tg = {.n = CR_NJOINTS,
                          .parent = parent,
                          .rest = (const double(*)[3])rest,
                          .src = map,
                          .bone_child = bone,
                          .pelvis = CR_JOINT_PELVIS,
                          .lhip = CR_JOINT_LEFT_HIP,
                          .rhip = CR_JOINT_RIGHT_HIP};
    const size_t T = (size_t)s->nframes;
    cr_motion *m = NULL;
    double *g = cr_malloc(T * CR_NJOINTS * 4 * sizeof(double), err);
    double *t = cr_malloc(T * 3 * sizeof(double), err), hip_m;
    cr_status st = g && t ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_motion_create(s->nframes, (float)s->fps, &m, err);
    if (st == CR_OK) st = cr_retarget_drive(s, map, rig, def, &tg, g, t, &hip_m, err);
    if (st == CR_OK) motion_from_world(g, t, m); /* the mannequin's parents are SMPL's */
    free(g), free(t);
    if (st != CR_OK) {
        cr_motion_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

/* ------------------------------------------------- onto any skeleton -- */

#define RETARGET_COOKIE 0x72746731u

cr_retarget_def cr_retarget_default_def(void) {
    return (cr_retarget_def){.import = cr_motion_import_default_def(), .cookie = RETARGET_COOKIE};
}

/* The character's motion from its joints' world rotations g (T,n,4) and
 * pelvis displacement t (T,3), both in crease's frame: turned back into the
 * character's frame, made local, and the roots' translation chosen so the
 * pelvis lands at its rest position plus t. */
static cr_status character_motion(const rt_character *c, const cr_glb_skin *skel, const double *g,
                                  const double *t, cr_skin_motion *m, cr_error *err) {
    const int n = c->t.n;
    double inv[4];
    q_conj(c->turn, inv);
    double(*pos)[3] = cr_malloc((size_t)n * sizeof *pos, err);
    double(*gw)[4] = cr_malloc((size_t)n * sizeof *gw, err);
    if (!pos || !gw) {
        free(pos), free(gw);
        return CR_ERR_MEMORY;
    }
    for (int32_t f = 0; f < m->nframes; f++) {
        float *rot = m->rotation + 4 * (size_t)f * (size_t)n;
        for (int j = 0; j < n; j++) { /* G in the character's frame: C^-1 G C */
            q_mul(inv, g + 4 * ((size_t)f * (size_t)n + (size_t)j), gw[j]);
            q_mul(gw[j], c->turn, gw[j]);
        }
        for (int j = 0; j < n; j++) {
            const int p = c->parent[j];
            double local[4], d[3];
            memcpy(local, gw[j], sizeof local);
            if (p >= 0) {
                double pinv[4];
                q_conj(gw[p], pinv);
                q_mul(pinv, local, local);
            }
            rot[4 * j] = (float)local[1], rot[4 * j + 1] = (float)local[2];
            rot[4 * j + 2] = (float)local[3], rot[4 * j + 3] = (float)local[0];
            for (int k = 0; k < 3; k++) /* forward kinematics with the roots at rest */
                d[k] = skel->rest_joint[3 * j + k] - (p >= 0 ? skel->rest_joint[3 * p + k] : 0.0);
            if (p >= 0) q_rotate(gw[p], d, d);
            for (int k = 0; k < 3; k++)
                pos[j][k] = (p >= 0 ? pos[p][k] : 0.0) + d[k];
        }
        double want[3];
        q_rotate(inv, t + 3 * (size_t)f, want);
        for (int k = 0; k < 3; k++)
            m->translation[3 * f + k] =
                (float)(skel->rest_joint[3 * c->t.pelvis + k] + want[k] - pos[c->t.pelvis][k]);
    }
    free(pos), free(gw);
    return CR_OK;
}

cr_status cr_retarget_onto_character(const rt_source *s, const int map[CR_NJOINTS], int rig,
                                     const cr_glb_skin *skel, const char *skel_source,
                                     const cr_retarget_def *def, cr_skin_motion **out,
                                     cr_error *err) {
    *out = NULL;
    cr_retarget_def defaults = cr_retarget_default_def();
    if (!def) def = &defaults;
    CR_ASSERT(def->cookie == RETARGET_COOKIE && def->import.cookie == MOTION_IMPORT_COOKIE);
    if (skel->njoints < 1 || skel->njoints > CR_GLB_MAX_JOINTS)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d joints (1 to %d)", skel_source, skel->njoints,
                       CR_GLB_MAX_JOINTS);
    double *g = NULL, *t = NULL, hip_m = 0.0;
    rt_character c = {0};
    cr_skin_motion *m = NULL;
    cr_status st = cr_retarget_character_build(skel, skel_source, def->joint_map, s->n, s->name,
                                               map, s->source, &c, err);
    const size_t T = (size_t)s->nframes, n = (size_t)skel->njoints;
    if (st == CR_OK) {
        g = cr_malloc(T * n * 4 * sizeof(double), err);
        t = cr_malloc(T * 3 * sizeof(double), err);
        if (!g || !t) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = cr_skin_motion_create(skel->njoints, s->nframes, (float)s->fps, &m, err);
    if (st == CR_OK) st = cr_retarget_drive(s, map, rig, &def->import, &c.t, g, t, &hip_m, err);
    const double scale = hip_m > 1e-6 ? c.hip_m / hip_m : 1.0; /* the hips' heights */
    if (st == CR_OK) {
        for (size_t i = 0; i < 3 * T; i++)
            t[i] *= scale;
        st = character_motion(&c, skel, g, t, m, err);
    }
    if (st == CR_OK) {
        int driven = 0;
        for (size_t j = 0; j < n; j++)
            driven += c.src[j] >= 0;
        cr_log(CR_LOG_INFO,
               "%s: %s joint names, %d of 22 body joints found by name%s%s%s; %d of %d joints "
               "driven by %s (%s rig), the rest keep their rest pose; translation scaled by "
               "%.3f (hips %.3f m over %.3f m)",
               skel_source, c.nroles > 0 ? cr_retarget_rig_name(c.rig) : "no known", c.nroles,
               def->joint_map ? ", " : "", def->joint_map ? def->joint_map : "",
               def->joint_map ? " read" : "", driven, (int)n, s->source, cr_retarget_rig_name(rig),
               scale, c.hip_m, hip_m);
    }
    cr_retarget_character_free(&c);
    free(g), free(t);
    if (st != CR_OK) {
        cr_skin_motion_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}
