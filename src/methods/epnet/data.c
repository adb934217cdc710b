/* data.c: epnet's inputs: a motion on a body as the sequence E-Net reads (cr_epnet_seq:
 * the motion resolved by cr_motion_resolve, the posed body, the garment's skinning
 * transforms and the networks' per-frame inputs), and the reference the method is
 * measured against: the plastic simulator run on that sequence from the skinned rest. */
#include "epnet_internal.h"

#include "crease/motion.h"
#include "crease/phys_sim.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------- sequences -- */

static cr_status load_motion(const char *name, int32_t frames, float fps, cr_motion **out,
                             cr_error *err) {
    cr_motion_resolve_def rd = cr_motion_resolve_default_def();
    rd.clip_frames = frames > 0 ? frames : 120, rd.max_frames = frames, rd.fps = fps;
    return cr_motion_resolve(name, &rd, out, NULL, err);
}

void cr_epnet_seq_destroy(cr_epnet_seq *s) {
    if (!s) return;
    free(s->A), free(s->b), free(s->body), free(s->stat), free(s->dyn);
    cr_body_model_destroy(s->own_body);
    free(s);
}
int32_t cr_epnet_seq_frames(const cr_epnet_seq *s) {
    return s->T;
}
const float *cr_epnet_seq_body(const cr_epnet_seq *s) {
    return s->body;
}
const cr_mesh *cr_epnet_seq_body_mesh(const cr_epnet_seq *s) {
    return s->body_rest;
}

void cr_epnet_frame_inputs_(const cr_epnet *m, const float *joints, const float *pose,
                            const float *tr, const float *prev_pose, const float *prev_tr,
                            float *stat, float *dyn, float *A_out, float *b_out) {
    const int32_t V = m->nv;
    const cr_garment *g = m->garment;
    float xf[CR_NJOINTS * 12], R[9];
    cr_body_skin_transforms(joints, pose, tr, xf);
    for (int32_t v = 0; v < V; v++) {
        float *A = A_out + (size_t)v * 9, *b = b_out + (size_t)v * 3;
        memset(A, 0, 9 * sizeof *A), memset(b, 0, 3 * sizeof *b);
        for (int k = 0; k < 4; k++) {
            const float w = g->skin_weight[4 * v + k];
            const float *X = xf + 12 * g->skin_joint[4 * v + k];
            for (int r = 0; r < 3; r++) {
                for (int c = 0; c < 3; c++)
                    A[3 * r + c] += w * X[4 * r + c];
                b[r] += w * X[4 * r + 3];
            }
        }
    }
    /* static: joints 1..21 and the world up in the root's frame */
    memcpy(stat, pose + 3, 63 * sizeof *stat);
    cr_body_rodrigues(pose, R);
    for (int r = 0; r < 3; r++)
        stat[63 + r] = R[3 * 1 + r]; /* R^T e_y */
    /* dynamic: joint angular velocity and root velocity in the root frame, per s */
    memset(dyn, 0, sizeof(float) * EP_DYN_IN);
    if (!prev_pose) return;
    for (int i = 0; i < 66; i++)
        dyn[i] = (pose[i] - prev_pose[i]) * 0.1f * m->def.fps;
    for (int r = 0; r < 3; r++) {
        double v = 0;
        for (int c = 0; c < 3; c++)
            v += R[3 * c + r] * (tr[c] - prev_tr[c]);
        dyn[66 + r] = (float)(v * m->def.fps);
    }
}

cr_status cr_epnet_seq_create(const cr_epnet *m, const char *motion, const char *body,
                              int32_t frames, int32_t hold, cr_epnet_seq **out, cr_error *err) {
    *out = NULL;
    cr_motion *mo = NULL;
    CR_TRY(load_motion(motion, frames, m->def.fps, &mo, err));
    cr_epnet_seq *s = cr_calloc(1, sizeof *s, err);
    if (!s) {
        cr_motion_destroy(mo);
        return CR_ERR_MEMORY;
    }
    cr_status st = CR_OK;
    const cr_body_model *bm = m->body;
    if (body && strcmp(body, m->body_name)) {
        st = cr_body_resolve(body, &s->own_body, err);
        bm = s->own_body;
    }
    const int32_t T0 = mo->nframes, T = T0 + (hold > 0 ? hold : 0), V = m->nv;
    s->T = T;
    if (st == CR_OK) {
        s->body_rest = bm->rest, s->vb = bm->rest->nv;
        s->A = malloc(sizeof(float) * 9 * (size_t)T * V);
        s->b = malloc(sizeof(float) * 3 * (size_t)T * V);
        s->body = malloc(sizeof(float) * 3 * (size_t)T * s->vb);
        s->stat = calloc((size_t)T * EP_STATIC_IN, sizeof(float));
        s->dyn = calloc((size_t)T * EP_DYN_IN, sizeof(float));
        if (!s->A || !s->b || !s->body || !s->stat || !s->dyn)
            st = CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory for %d frames", T);
    }
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        const int32_t f = t < T0 ? t : T0 - 1, fp = t == 0 ? -1 : (t - 1 < T0 ? t - 1 : T0 - 1);
        const float *pose = mo->poses + (size_t)f * CR_NJOINTS * 3, *tr = mo->trans + 3 * f;
        st = cr_body_pose(bm, pose, tr, s->body + (size_t)t * s->vb * 3, err);
        cr_epnet_frame_inputs_(
            m, bm->joints, pose, tr, fp < 0 ? NULL : mo->poses + (size_t)fp * CR_NJOINTS * 3,
            fp < 0 ? NULL : mo->trans + 3 * fp, s->stat + (size_t)t * EP_STATIC_IN,
            s->dyn + (size_t)t * EP_DYN_IN, s->A + (size_t)t * V * 9, s->b + (size_t)t * V * 3);
    }
    cr_motion_destroy(mo);
    if (st != CR_OK) {
        cr_epnet_seq_destroy(s);
        return st;
    }
    *out = s;
    return CR_OK;
}

/* ------------------------------------------------------------- E-Net -- */

/* Skinned positions (V,3) of frame t: A_t[v] p[v] + b_t[v]. */
void cr_epnet_skinned_frame_(const cr_epnet *m, const cr_epnet_seq *s, int32_t t, float *out) {
    const int32_t V = m->nv;
    for (int32_t v = 0; v < V; v++) {
        const float *A = s->A + ((size_t)t * V + v) * 9, *b = s->b + ((size_t)t * V + v) * 3,
                    *p = m->garment->mesh->pos + 3 * v;
        for (int r = 0; r < 3; r++)
            out[3 * v + r] = A[3 * r] * p[0] + A[3 * r + 1] * p[1] + A[3 * r + 2] * p[2] + b[r];
    }
}

/* ---------------------------------------------------------- reference -- */

cr_status cr_epnet_reference(const cr_epnet *m, const cr_epnet_seq *s, int plastic, float *pos,
                             float *rest, cr_error *err) {
    return cr_epnet_reference_friction(m, s, plastic, m->def.material.friction, pos, rest, err);
}

cr_status cr_epnet_reference_friction(const cr_epnet *m, const cr_epnet_seq *s, int plastic,
                                      double friction, float *pos, float *rest, cr_error *err) {
    if (!(friction >= 0))
        return CR_FAIL(err, CR_ERR_INVALID, "epnet reference: friction %g < 0", friction);
    const int32_t V = m->nv, H = m->nh, T = s->T;
    cr_mesh *start = NULL;
    CR_TRY(cr_mesh_create(V, m->garment->mesh->nf, 0, &start, err));
    /* the skinned rest of frame 0, with the rest mesh's own shape as rest */
    cr_epnet_skinned_frame_(m, s, 0, start->pos);
    /* the pinned vertices follow their skinned positions */
    float *pins = NULL, *frame = NULL;
    if (m->npin > 0) {
        pins = malloc(sizeof(float) * 3 * (size_t)T * m->npin);
        frame = malloc(sizeof(float) * 3 * (size_t)V);
        if (!pins || !frame) {
            free(pins), free(frame), cr_mesh_destroy(start);
            return CR_FAIL(err, CR_ERR_MEMORY, "epnet reference: out of memory for pins");
        }
        for (int32_t t = 0; t < T; t++) {
            cr_epnet_skinned_frame_(m, s, t, frame);
            for (int32_t k = 0; k < m->npin; k++)
                memcpy(pins + ((size_t)t * m->npin + k) * 3, frame + 3 * m->pin[k],
                       3 * sizeof(float));
        }
    }
    memcpy(start->tri, m->garment->mesh->tri, sizeof(int32_t) * 3 * (size_t)start->nf);
    cr_sim_def sd = cr_sim_default_def();
    sd.material = m->def.material;
    sd.material.plastic_gain = 1.0;
    /* the simulator's own contact (cotton's stiffness): the training loss's
     * soft penalty (matched to the authors' force at contact) let the
     * shoulders sink 1-2 cm through the shirt when the arms came down */
    {
        cr_material cot;
        cr_error e2;
        if (cr_material_preset("cotton", &cot, &e2) == CR_OK)
            sd.material.collision_stiffness = cot.collision_stiffness;
    }
    sd.material.friction = friction;
    sd.dt = 1.0 / m->def.fps;
    sd.plasticity = plastic;
    sd.plastic_rule = CR_PLASTIC_SMOOTH;
    sd.collider = s->body_rest;
    sd.collider_frames = s->body;
    sd.collider_nframes = T;
    sd.max_collider_step = 0.15;
    sd.pinned = m->npin > 0 ? m->pin : NULL, sd.npinned = m->npin;
    sd.pin_frames = pins, sd.pin_nframes = m->npin > 0 ? T : 0;
    cr_sim *sim = NULL;
    cr_status st = cr_sim_create(&sd, start, &sim, err);
    cr_sim_report rep;
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        if (t > 0) st = cr_sim_step(sim, &rep, err);
        if (st != CR_OK) break;
        const double *x = cr_sim_positions(sim);
        for (int64_t i = 0; i < 3 * (int64_t)V; i++)
            pos[(size_t)t * V * 3 + i] = (float)x[i];
        if (rest) {
            const double *ra = cr_sim_rest_angles(sim);
            for (int32_t h = 0; h < H; h++)
                rest[(size_t)t * H + h] = (float)(ra[h] - m->theta_bar[h]);
        }
    }
    cr_sim_destroy(sim);
    cr_mesh_destroy(start);
    free(pins), free(frame);
    return st;
}
