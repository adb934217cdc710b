/* body_character.c: a rigged glTF character as a body model (issue 52), so
 * that every command taking a body (epnet, swingar, dataset) takes the
 * user's own character as it takes a mannequin preset or an SMPL file.
 *
 * The character's joints are given SMPL's 22 roles by name (the alias
 * tables of the BVH retargeting: SMPL, Mixamo, CMU, DAZ/Poser, Unreal,
 * Blender/Rigify) or by a joint map file whose right-hand side names SMPL
 * joints ("bone07 = left_knee"). Its skinning weights then go as SMPL's own
 * extra joints go (smpl_model.c): every joint's weight to its nearest
 * ancestor that has a role (none above: the pelvis), each vertex keeping its
 * four largest merged weights, renormalised. The rest mesh and joints are
 * turned into crease's frame (+Y up, facing +Z: the up and left read off
 * the skeleton, as the retargeting reads them), re-posed by its own
 * skinning so that every bone points as the mannequin's rest bone does (the
 * A-pose every motion in crease is written against: a T-posed character's
 * arms come down 40 degrees; each bone by the least rotation, so no twist),
 * and stood on the ground as SMPL's are (lowest vertex on y = 0, pelvis over
 * x = z = 0). A role no
 * joint has (a rig without a collar or a third spine joint) is placed
 * halfway along its chain between the nearest roles above and below it, or
 * past its parent along the parent's bone at a leaf; it then drives no
 * vertex.
 *
 * Leaves out: joints past four weights a vertex, morph targets, the
 * candy-wrapper loss of volume linear blend skinning gives a joint turned
 * far from its bind pose (the shoulders of a T-pose brought down).
 */
#include "body/mannequin_internal.h"
#include "body/retarget_internal.h"
#include "crease/body.h"
#include "crease/diffgeo.h"
#include "crease/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { SKIN_SLOTS = 4 };

/* A leaf role without a joint: this far past its parent along the parent's
 * own bone (its length's share). */
static const double LEAF_SHARE = 0.25;

/* The rest mesh's height over the ground, m. */
static double body_height(const cr_body_model *b) {
    double top = 0.0;
    for (int32_t v = 0; v < b->rest->nv; v++)
        top = fmax(top, b->rest->pos[3 * v + 1]);
    return top;
}

/* The role of each character joint: its own, else its nearest ancestor's,
 * else the pelvis's. */
static void joint_roles(const rt_character *c, int n, int *role_of) {
    for (int j = 0; j < n; j++) {
        role_of[j] = -1;
        for (int r = 0; r < CR_NJOINTS; r++)
            if (c->role[r] == j) role_of[j] = r;
        if (role_of[j] < 0)
            role_of[j] = c->parent[j] >= 0 ? role_of[c->parent[j]] : CR_JOINT_PELVIS;
    }
}

/* The 22 joints in crease's frame: the roles' joints, the missing ones
 * placed along their chains (see the top of the file). */
static void body_joints(const rt_character *c, double (*p)[3]) {
    int have[CR_NJOINTS];
    for (int r = 0; r < CR_NJOINTS; r++) { /* parents come first in SMPL's order */
        have[r] = c->role[r] >= 0;
        if (have[r]) memcpy(p[r], c->rest[c->role[r]], sizeof p[r]);
    }
    for (int r = 0; r < CR_NJOINTS; r++) {
        if (have[r]) continue;
        const int up = cr_joint_parent[r];
        int down = cr_retarget_bone_child_role[r];
        while (down >= 0 && !have[down])
            down = cr_retarget_bone_child_role[down];
        for (int k = 0; k < 3; k++)
            if (down >= 0)
                p[r][k] = 0.5 * (p[up][k] + p[down][k]);
            else if (cr_joint_parent[up] >= 0)
                p[r][k] = p[up][k] + LEAF_SHARE * (p[up][k] - p[cr_joint_parent[up]][k]);
            else
                p[r][k] = p[up][k];
        have[r] = 1;
    }
}

/* The pose (22,3 axis-angle) turning every bone of joints (22,3) between
 * two real joints (real[r]: role r is a joint of the character's, not
 * placed) to the direction the mannequin's rest gives it (the default
 * A-pose), each by the least rotation; the others (a leaf, a bone to or
 * from a placed joint) turn with their parent. */
static void rest_pose_to_mannequin(const float *joints, const int *real, float *pose) {
    cr_mannequin_def md = cr_mannequin_default_def();
    float m[CR_NJOINTS * 3];
    cr_mannequin_rest_joints(&md, m);
    double world[CR_NJOINTS][4];
    for (int r = 0; r < CR_NJOINTS; r++) { /* parents first */
        const int c = cr_retarget_bone_child_role[r], p = cr_joint_parent[r];
        double a[3], b[3], ua[3], ub[3];
        for (int k = 0; k < 3 && c >= 0; k++)
            a[k] = joints[3 * c + k] - joints[3 * r + k], b[k] = m[3 * c + k] - m[3 * r + k];
        if (c >= 0 && real[r] && real[c] && cr_retarget_unit3(a, ua, 1e-9) &&
            cr_retarget_unit3(b, ub, 1e-9))
            cr_retarget_shortest_arc(ua, ub, world[r]);
        else if (p >= 0)
            memcpy(world[r], world[p], sizeof world[r]);
        else
            q_identity(world[r]);
        double local[4], inv[4];
        if (p >= 0) {
            q_conj(world[p], inv);
            q_mul(inv, world[r], local);
        } else {
            memcpy(local, world[r], sizeof local);
        }
        q_to_aa(local, pose + 3 * r);
    }
}

/* b's rest re-posed into the mannequin's bone directions (real: as above) (the rest every
 * motion in crease is written against: a T-posed character's arms come down
 * to the A-pose), by b's own skinning; its joints follow. */
static cr_status repose_rest(cr_body_model *b, const int *real, cr_error *err) {
    float pose[CR_NJOINTS * 3], joints[CR_NJOINTS * 3];
    rest_pose_to_mannequin(b->joints, real, pose);
    float *pos = cr_malloc((size_t)b->rest->nv * 3 * sizeof *pos, err);
    if (!pos) return CR_ERR_MEMORY;
    cr_status st = cr_body_pose(b, pose, NULL, pos, err);
    if (st == CR_OK) {
        cr_body_forward_kinematics(b->joints, pose, NULL, NULL, joints);
        memcpy(b->rest->pos, pos, (size_t)b->rest->nv * 3 * sizeof *pos);
        memcpy(b->joints, joints, sizeof joints);
        if (b->rest->normal) st = cr_mesh_compute_normals(b->rest, err);
    }
    free(pos);
    return st;
}

/* The character's mesh and 22 joints turned into crease's frame and stood
 * on the ground, with the merged weights. */
static cr_status build_body(const cr_glb_character *ch, const char *path, const rt_character *c,
                            cr_body_model *b, cr_error *err) {
    const cr_mesh *src = ch->rest;
    const int n = ch->skin.njoints;
    const int64_t V = src->nv;
    double joints[CR_NJOINTS][3], *pos = cr_malloc((size_t)V * 3 * sizeof *pos, err);
    int *role_of = cr_malloc((size_t)n * sizeof *role_of, err);
    float *dense = cr_calloc((size_t)n, sizeof *dense, err);
    cr_status st = pos && role_of && dense ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_mesh_clone(src, &b->rest, err);
    if (st == CR_OK) {
        b->skin_joint = cr_malloc((size_t)V * SKIN_SLOTS * sizeof *b->skin_joint, err);
        b->skin_weight = cr_malloc((size_t)V * SKIN_SLOTS * sizeof *b->skin_weight, err);
        if (!b->skin_joint || !b->skin_weight) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) {
        joint_roles(c, n, role_of);
        body_joints(c, joints);
        for (int64_t v = 0; v < V; v++) {
            double x[3] = {src->pos[3 * v], src->pos[3 * v + 1], src->pos[3 * v + 2]};
            q_rotate(c->turn, x, pos + 3 * v);
            if (src->normal) {
                double nrm[3] = {src->normal[3 * v], src->normal[3 * v + 1],
                                 src->normal[3 * v + 2]},
                       out[3];
                q_rotate(c->turn, nrm, out);
                for (int k = 0; k < 3; k++)
                    b->rest->normal[3 * v + k] = (float)out[k];
            }
        }
        for (int64_t i = 0; i < V * 3; i++)
            b->rest->pos[i] = (float)pos[i];
        for (int r = 0; r < CR_NJOINTS; r++)
            for (int k = 0; k < 3; k++)
                b->joints[3 * r + k] = (float)joints[r][k];
    }
    for (int64_t v = 0; st == CR_OK && v < V; v++) {
        const int32_t *jv = ch->skin.skin_joint + SKIN_SLOTS * v;
        const float *wv = ch->skin.skin_weight + SKIN_SLOTS * v;
        for (int s = 0; s < SKIN_SLOTS; s++)
            dense[jv[s]] += wv[s];
        st = cr_body_top_weights_(dense, n, role_of, v, path, b->skin_joint + SKIN_SLOTS * v,
                                  b->skin_weight + SKIN_SLOTS * v, err);
        for (int s = 0; s < SKIN_SLOTS; s++)
            dense[jv[s]] = 0.0f;
    }
    int real[CR_NJOINTS];
    for (int r = 0; r < CR_NJOINTS; r++)
        real[r] = c->role[r] >= 0;
    if (st == CR_OK) st = repose_rest(b, real, err);
    if (st == CR_OK) { /* stood on the ground */
        double shift[3], pelvis[3];
        for (int64_t i = 0; i < V * 3; i++)
            pos[i] = b->rest->pos[i];
        for (int k = 0; k < 3; k++)
            pelvis[k] = b->joints[3 * CR_JOINT_PELVIS + k];
        cr_body_stand_shift_(pos, V, pelvis, shift);
        for (int64_t i = 0; i < V * 3; i++)
            b->rest->pos[i] = (float)(pos[i] + shift[i % 3]);
        for (int i = 0; i < 3 * CR_NJOINTS; i++)
            b->joints[i] = (float)(b->joints[i] + shift[i % 3]);
    }
    free(pos), free(role_of), free(dense);
    return st;
}

cr_status cr_body_from_character(const char *path, const char *joint_map, cr_body_model **out,
                                 cr_error *err) {
    if (!path || !out) return CR_FAIL(err, CR_ERR_INVALID, "body from a character: NULL argument");
    *out = NULL;
    cr_glb_character *ch = NULL;
    CR_TRY(cr_glb_read_character(path, &ch, err));
    int self[CR_NJOINTS];
    for (int r = 0; r < CR_NJOINTS; r++)
        self[r] = r;
    rt_character c;
    cr_status st =
        cr_retarget_character_build(&ch->skin, path, joint_map, CR_NJOINTS, cr_joint_name, self,
                                    "the body's 22 SMPL joints", &c, err);
    cr_body_model *b = st == CR_OK ? cr_calloc(1, sizeof *b, err) : NULL;
    if (st == CR_OK && !b) st = CR_ERR_MEMORY;
    if (st == CR_OK) {
        st = build_body(ch, path, &c, b, err);
        int found = 0;
        for (int r = 0; r < CR_NJOINTS; r++)
            found += c.role[r] >= 0;
        if (st == CR_OK)
            cr_log(CR_LOG_INFO,
                   "%s: %d vertices, %d of 22 body joints found (%s names%s), %.2f m tall", path,
                   (int)ch->rest->nv, found, cr_retarget_rig_name(c.rig),
                   c.nuser ? ", a joint map" : "", (double)body_height(b));
        cr_retarget_character_free(&c);
    }
    cr_glb_character_destroy(ch);
    if (st != CR_OK) {
        cr_body_model_destroy(b);
        return st;
    }
    *out = b;
    return CR_OK;
}
