/* motion_glb.c: a rigged glTF character's own animation as a motion of
 * crease's mannequin (issue 52), so `--motion CHAR.glb` drives every body
 * (the character itself through `--body CHAR.glb`, or any other) as a BVH
 * does.
 *
 * The character is read as cr_glb_read_character reads it (its skeleton,
 * animations[0] sampled at its key rate over its time range); its joints
 * are given SMPL's 22 roles exactly as cr_body_from_character gives them
 * (the BVH retargeting's name tables, or a joint map file after a colon,
 * "CHAR.glb:MAP"), so the body made of the character and the motion read
 * from it agree on every joint. Each frame's joint world rotations, taken
 * relative to the rest the nodes hold (the pose the body is built from),
 * and world positions are the source rig of retarget_drive.c: the same
 * frame, unit and bone-direction retargeting a BVH gets. glTF is in metres;
 * an armature node's scale (a centimetre rig under a 0.01 scale) is in the
 * world positions.
 *
 * Reference: The Khronos glTF 2.0 Specification, sections 3.5, 3.7.3, 3.11.
 */
#include "body/mannequin_internal.h"
#include "body/retarget_internal.h"

#include <stdlib.h>
#include <string.h>

static void glb_pose(const rt_source *s, int32_t f, double (*w)[4], double (*pos)[3]) {
    const cr_glb_skin_anim *a = s->ctx;
    const float *r = a->rotation + 4 * (size_t)f * (size_t)s->n;
    const float *p = a->position + 3 * (size_t)f * (size_t)s->n;
    for (int j = 0; j < s->n; j++) {
        w[j][0] = r[4 * j + 3], w[j][1] = r[4 * j], w[j][2] = r[4 * j + 1];
        w[j][3] = r[4 * j + 2];
        for (int k = 0; k < 3; k++)
            pos[j][k] = p[3 * j + k];
    }
}

/* A character opened as a source rig: its file, the roles of its joints and the arrays
 * its rt_source points into. */
typedef struct glb_source {
    cr_glb_character *ch;
    rt_character roles; /* the character's joints as the body's 22 roles' target */
    int *parent;
    double (*rest)[3];
    rt_source src;
} glb_source;

static void glb_source_close(glb_source *g) {
    cr_retarget_character_free(&g->roles);
    free(g->parent), free(g->rest);
    cr_glb_character_destroy(g->ch);
    memset(g, 0, sizeof *g);
}

static cr_status glb_source_open(const char *path, const char *joint_map, glb_source *g,
                                 cr_error *err) {
    memset(g, 0, sizeof *g);
    CR_TRY(cr_glb_read_character(path, &g->ch, err));
    const cr_glb_skin *sk = &g->ch->skin;
    const int n = sk->njoints;
    if (!g->ch->anim.animated) {
        glb_source_close(g);
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: no animation (animations[0] moves none of its nodes): a character "
                       "drives a body by its own animation only",
                       path);
    }
    int self[CR_NJOINTS];
    for (int r = 0; r < CR_NJOINTS; r++)
        self[r] = r;
    cr_status st = cr_retarget_character_build(sk, path, joint_map, CR_NJOINTS, cr_joint_name, self,
                                               "the body's 22 SMPL joints", &g->roles, err);
    if (st == CR_OK) {
        g->parent = cr_malloc((size_t)n * sizeof *g->parent, err);
        g->rest = cr_malloc((size_t)n * sizeof *g->rest, err);
        if (!g->parent || !g->rest) st = CR_ERR_MEMORY;
    }
    if (st != CR_OK) {
        glb_source_close(g);
        return st;
    }
    for (int j = 0; j < n; j++) {
        g->parent[j] = sk->parent[j];
        for (int k = 0; k < 3; k++)
            g->rest[j][k] = sk->rest_joint[3 * j + k];
    }
    g->src = (rt_source){.source = path,
                         .n = n,
                         .name = sk->joint_name,
                         .parent = g->parent,
                         .rest = g->rest,
                         .nframes = g->ch->anim.nframes,
                         .fps = g->ch->anim.fps,
                         .pose = glb_pose,
                         .ctx = &g->ch->anim};
    int found = 0;
    for (int r = 0; r < CR_NJOINTS; r++)
        found += g->roles.role[r] >= 0;
    cr_log(CR_LOG_INFO,
           "%s: its own animation, %d frame%s at %g fps; %d of 22 body joints found (%s names%s)",
           path, (int)g->ch->anim.nframes, g->ch->anim.nframes == 1 ? "" : "s",
           (double)g->ch->anim.fps, found, cr_retarget_rig_name(g->roles.rig),
           g->roles.nuser ? ", a joint map" : "");
    return CR_OK;
}

cr_status cr_motion_read_character(const char *path, const char *joint_map,
                                   const cr_motion_import_def *def, cr_motion **out,
                                   cr_error *err) {
    *out = NULL;
    cr_motion_import_def defaults = cr_motion_import_default_def();
    if (!def) def = &defaults;
    glb_source g;
    CR_TRY(glb_source_open(path, joint_map, &g, err));
    cr_status st = cr_retarget_onto_mannequin(&g.src, g.roles.role, g.roles.rig, def, out, err);
    glb_source_close(&g);
    return st;
}

cr_status cr_motion_retarget_character(const char *path, const char *joint_map,
                                       const cr_glb_skin *skel, const char *skel_source,
                                       const cr_retarget_def *def, cr_skin_motion **out,
                                       cr_error *err) {
    *out = NULL;
    glb_source g;
    CR_TRY(glb_source_open(path, joint_map, &g, err));
    cr_status st = cr_retarget_onto_character(&g.src, g.roles.role, g.roles.rig, skel, skel_source,
                                              def, out, err);
    glb_source_close(&g);
    return st;
}
