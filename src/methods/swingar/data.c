/* data.c: SwinGar's inputs: a garment prepared at its rest pose (vertex
 * features, graph, dense prior skinning weights, gravity), datasets written
 * by `crease dataset` (docs/datasets.md) and the split by garment, motion
 * and body. */
#include "swingar_internal.h"

#include "descriptor.h"

#include "crease/body.h"
#include "crease/bvh.h"
#include "crease/dataset.h"
#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "crease/phys_energies.h"
#include "crease/phys_material.h"
#include "crease/topology.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ garment -- */

void cr_swingar_garment_destroy(cr_swingar_garment *g) {
    if (!g) return;
    cr_mesh_destroy(g->rest);
    free(g->features);
    free(g->descriptor);
    free(g->skin_weight);
    free(g->edges);
    free(g->senders);
    free(g->receivers);
    free(g->adj);
    cr_gravity_destroy(g->gravity);
    free(g);
}

cr_status cr_swingar_garment_create(const cr_mesh *rest, const int32_t *skin_joint,
                                    const float *skin_weight, const cr_body_model *body,
                                    const float *descriptor, int32_t z, cr_swingar_garment **out,
                                    cr_error *err) {
    *out = NULL;
    if (!rest || rest->nv < 3 || rest->nf < 1 || !skin_joint || !skin_weight || !body || z < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar garment: missing mesh, weights or body");
    cr_swingar_garment *g = calloc(1, sizeof *g);
    if (!g) return CR_FAIL(err, CR_ERR_MEMORY, "swingar garment: out of memory");
    const int32_t V = rest->nv;
    cr_topology *topo = NULL;
    cr_bvh *bvh = NULL;
    float *dist = NULL;
    cr_status st = cr_mesh_clone(rest, &g->rest, err);
    if (st == CR_OK) st = cr_mesh_compute_normals(g->rest, err);
    if (st == CR_OK) st = cr_topology_build(g->rest, &topo, err);
    if (st == CR_OK)
        st = cr_bvh_build(body->rest->pos, body->rest->nv, body->rest->tri, body->rest->nf, &bvh,
                          err);
    if (st == CR_OK) {
        g->features = malloc(sizeof(float) * (size_t)V * SWG_VERTEX_FEATURES);
        g->descriptor = calloc((size_t)z, sizeof(float));
        g->skin_weight = calloc((size_t)V * CR_NJOINTS, sizeof(float));
        g->nedges = topo->ne;
        g->edges = malloc(sizeof(int32_t) * 2 * (size_t)topo->ne);
        g->senders = malloc(sizeof(int32_t) * 2 * (size_t)topo->ne);
        g->receivers = malloc(sizeof(int32_t) * 2 * (size_t)topo->ne);
        g->nadj = topo->nh;
        g->adj = malloc(sizeof(int32_t) * 2 * (size_t)(topo->nh > 0 ? topo->nh : 1));
        dist = malloc(sizeof(float) * (size_t)V);
        if (!g->features || !g->descriptor || !g->skin_weight || !g->edges || !g->senders ||
            !g->receivers || !g->adj || !dist)
            st = CR_FAIL(err, CR_ERR_MEMORY, "swingar garment: out of memory");
    }
    if (st == CR_OK) {
        /* the fit attribute (Li et al. 2023): how far each vertex sits from the body */
        cr_bvh_signed_distance_batch(bvh, g->rest->pos, V, INFINITY, dist, NULL, NULL);
        for (int32_t i = 0; i < V; i++) {
            float *f = g->features + (size_t)i * SWG_VERTEX_FEATURES;
            memcpy(f, g->rest->normal + 3 * (size_t)i, sizeof(float) * 3);
            memcpy(f + 3, g->rest->pos + 3 * (size_t)i, sizeof(float) * 3);
            f[6] = dist[i];
            for (int k = 0; k < 4; k++) {
                int32_t j = skin_joint[4 * i + k];
                if (j >= 0 && j < CR_NJOINTS)
                    g->skin_weight[(size_t)i * CR_NJOINTS + j] += skin_weight[4 * i + k];
            }
        }
        if (descriptor) memcpy(g->descriptor, descriptor, sizeof(float) * (size_t)z);
        for (int32_t e = 0; e < topo->ne; e++) {
            int32_t a = topo->edge[2 * e], b = topo->edge[2 * e + 1];
            g->edges[2 * e] = a, g->edges[2 * e + 1] = b;
            g->senders[2 * e] = a, g->receivers[2 * e] = b;
            g->senders[2 * e + 1] = b, g->receivers[2 * e + 1] = a;
        }
        for (int32_t h = 0; h < topo->nh; h++)
            g->adj[2 * h] = topo->hinge_face[2 * h],
                       g->adj[2 * h + 1] = topo->hinge_face[2 * h + 1];
        cr_material mat;
        st = cr_material_preset("silk", &mat, err); /* the paper's fabric (Blender's silk) */
        const double grav[3] = {0.0, -9.81, 0.0};
        if (st == CR_OK) st = cr_gravity_create(g->rest, &mat, grav, &g->gravity, err);
    }
    free(dist);
    cr_bvh_destroy(bvh);
    cr_topology_destroy(topo);
    if (st != CR_OK) {
        cr_swingar_garment_destroy(g);
        return st;
    }
    *out = g;
    return CR_OK;
}

/* --------------------------------------------------------- descriptor -- */

cr_status cr_swingar_compute_descriptor(const cr_mesh *mesh, int32_t z, int affinity, float *out,
                                        cr_error *err) {
    cr_swingar_descriptor_opts o = cr_swingar_descriptor_default_opts();
    o.samples = z;
    o.affinity = affinity ? CR_SWINGAR_AFFINITY_EUCLIDEAN : CR_SWINGAR_AFFINITY_GEODESIC;
    return cr_swingar_descriptor_full(mesh, &o, out, NULL, err);
}

/* ------------------------------------------------------------ dataset -- */

static cr_status npz_get(cr_npz *z, const char *path, const char *name, cr_npy_as as, int64_t n,
                         int32_t cols, cr_npy *out, cr_error *err) {
    CR_TRY(cr_npz_get(z, name, as, out, err));
    if (out->count != n * cols) {
        cr_npy_free(out);
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: %s has %lld values, expected %lld", path, name,
                       (long long)out->count, (long long)(n * cols));
    }
    return CR_OK;
}

static cr_status load_body(const cr_dataset_manifest *man, const cr_dataset_body_entry *e,
                           cr_swingar_body *b, cr_error *err) {
    snprintf(b->name, sizeof b->name, "%s", e->name);
    char path[CR_SCENE_PATH + 64];
    b->model = calloc(1, sizeof *b->model);
    if (!b->model) return CR_FAIL(err, CR_ERR_MEMORY, "swingar data: out of memory");
    CR_TRY(cr_dataset_path(man, e->rest, path, sizeof path, err));
    CR_TRY(cr_mesh_read(path, &b->model->rest, err));
    CR_TRY(cr_dataset_path(man, e->skin, path, sizeof path, err));
    cr_npz *z = NULL;
    CR_TRY(cr_npz_open(path, &z, err));
    cr_npy j = {0}, sj = {0}, sw = {0};
    int64_t V = b->model->rest->nv;
    cr_status st = npz_get(z, path, "joints", CR_NPY_AS_F32, CR_NJOINTS, 3, &j, err);
    if (st == CR_OK) st = npz_get(z, path, "skin_joint", CR_NPY_AS_I32, V, 4, &sj, err);
    if (st == CR_OK) st = npz_get(z, path, "skin_weight", CR_NPY_AS_F32, V, 4, &sw, err);
    if (st == CR_OK) {
        memcpy(b->model->joints, j.f32, sizeof(float) * CR_NJOINTS * 3);
        b->model->skin_joint = sj.i32, sj.i32 = NULL;
        b->model->skin_weight = sw.f32, sw.f32 = NULL;
    }
    cr_npy_free(&j);
    cr_npy_free(&sj);
    cr_npy_free(&sw);
    cr_npz_close(z);
    return st;
}

static cr_status load_garment(const cr_dataset_manifest *man, const cr_dataset_garment_entry *e,
                              const cr_swingar_data *d, int32_t z, int with_descriptor,
                              int affinity, cr_swingar_garment **out, char key[160],
                              cr_error *err) {
    /* a variant (dress:seed=3) is named by its label, which sequences refer to */
    snprintf(key, 160, "%s/%s_%s", e->body, e->label, e->res);
    const cr_body_model *bm = NULL;
    for (int32_t b = 0; b < d->nbodies; b++)
        if (strcmp(d->bodies[b].name, e->body) == 0) bm = d->bodies[b].model;
    if (!bm)
        return CR_FAIL(err, CR_ERR_PARSE, "%s/manifest.json: garment %s on unknown body %s",
                       man->dir, e->label, e->body);
    char path[CR_SCENE_PATH + 64];
    CR_TRY(cr_dataset_path(man, e->mesh, path, sizeof path, err));
    cr_mesh *m = NULL;
    CR_TRY(cr_mesh_read(path, &m, err));
    cr_npz *zf = NULL;
    cr_npy sj = {0}, sw = {0};
    float *desc = NULL;
    cr_status st = cr_dataset_path(man, e->skin, path, sizeof path, err);
    if (st == CR_OK) st = cr_npz_open(path, &zf, err);
    if (st == CR_OK) st = npz_get(zf, path, "skin_joint", CR_NPY_AS_I32, m->nv, 4, &sj, err);
    if (st == CR_OK) st = npz_get(zf, path, "skin_weight", CR_NPY_AS_F32, m->nv, 4, &sw, err);
    if (st == CR_OK && with_descriptor) {
        desc = malloc(sizeof(float) * (size_t)z);
        st = desc ? cr_swingar_compute_descriptor(m, z, affinity, desc, err)
                  : CR_FAIL(err, CR_ERR_MEMORY, "swingar data: out of memory");
        if (st != CR_OK && desc)
            st = CR_FAIL(err, st, "%s/%s: %s", man->dir, e->mesh,
                         err ? err->msg : "descriptor failed");
    }
    if (st == CR_OK) st = cr_swingar_garment_create(m, sj.i32, sw.f32, bm, desc, z, out, err);
    free(desc);
    cr_npy_free(&sj);
    cr_npy_free(&sw);
    cr_npz_close(zf);
    cr_mesh_destroy(m);
    return st;
}

static cr_status load_sequence(const cr_dataset_manifest *man, const cr_dataset_sequence_entry *e,
                               cr_swingar_data *d, cr_swingar_sequence *s, cr_error *err) {
    const char *id = e->id, *garment = e->garment, *res = e->res, *body = e->body;
    const char *motion = e->motion, *gpc2 = e->garment_pc2, *bpc2 = e->body_pc2;
    const char *dir = man->dir;
    snprintf(s->id, sizeof s->id, "%s", id);
    snprintf(s->garment, sizeof s->garment, "%s", garment);
    snprintf(s->body, sizeof s->body, "%s", body);
    snprintf(s->motion, sizeof s->motion, "%s", motion);
    char key[160];
    snprintf(key, sizeof key, "%s/%s_%s", body, garment, res);
    s->garment_index = s->body_index = -1;
    for (int32_t i = 0; i < d->ngarments; i++)
        if (strcmp(d->garment_key[i], key) == 0) s->garment_index = i;
    for (int32_t i = 0; i < d->nbodies; i++)
        if (strcmp(d->bodies[i].name, body) == 0) s->body_index = i;
    if (s->garment_index < 0 || s->body_index < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s/manifest.json: sequence %s: no garment %s", dir, id,
                       key);
    char path[CR_SCENE_PATH + 64];
    cr_pc2 gp = {0}, bp = {0};
    cr_motion *mo = NULL;
    cr_status st = cr_dataset_path(man, gpc2, path, sizeof path, err);
    if (st == CR_OK) st = cr_pc2_read(path, &gp, err);
    if (st == CR_OK) st = cr_dataset_path(man, bpc2, path, sizeof path, err);
    if (st == CR_OK) st = cr_pc2_read(path, &bp, err);
    snprintf(path, sizeof path, "%s/motions/%s.npz", dir, motion);
    for (int32_t i = 0; i < man->nmotions; i++)
        if (strcmp(man->motions[i].name, motion) == 0)
            cr_dataset_path(man, man->motions[i].path, path, sizeof path, NULL);
    if (st == CR_OK) st = cr_motion_load(path, &mo, err);
    const cr_swingar_garment *g = d->garments[s->garment_index];
    const cr_body_model *bm = d->bodies[s->body_index].model;
    if (st == CR_OK && (gp.nv != g->rest->nv || bp.nv != bm->rest->nv))
        st = CR_FAIL(err, CR_ERR_SHAPE,
                     "%s/%s: %d points, the garment has %d (or the body "
                     "%d, not %d)",
                     dir, gpc2, gp.nv, g->rest->nv, bp.nv, bm->rest->nv);
    if (st == CR_OK) {
        int32_t T = gp.nframes;
        if (bp.nframes < T) T = bp.nframes;
        if (mo->nframes < T) T = mo->nframes;
        s->nframes = T;
        s->garment_pos = gp.frames, gp.frames = NULL;
        s->body_pos = bp.frames, bp.frames = NULL;
        s->poses = mo->poses, mo->poses = NULL;
        s->trans = mo->trans, mo->trans = NULL;
    }
    cr_pc2_free(&gp);
    cr_pc2_free(&bp);
    cr_motion_destroy(mo);
    return st;
}

void cr_swingar_data_free(cr_swingar_data *d) {
    if (!d) return;
    for (int32_t i = 0; i < d->ngarments; i++)
        cr_swingar_garment_destroy(d->garments ? d->garments[i] : NULL);
    for (int32_t i = 0; i < d->nbodies; i++)
        cr_body_model_destroy(d->bodies[i].model);
    for (int32_t i = 0; i < d->nsequences; i++) {
        free(d->sequences[i].garment_pos);
        free(d->sequences[i].body_pos);
        free(d->sequences[i].poses);
        free(d->sequences[i].trans);
    }
    free(d->garments);
    free(d->garment_key);
    free(d->bodies);
    free(d->sequences);
    memset(d, 0, sizeof *d);
}

cr_status cr_swingar_data_load(const char *dir, int32_t z, int with_descriptor, int affinity,
                               cr_swingar_data *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    snprintf(out->dir, sizeof out->dir, "%s", dir);
    cr_dataset_manifest man;
    CR_TRY(cr_dataset_read(dir, &man, err));
    const int32_t nb = man.nbodies, ng = man.ngarments, ns = man.nsequences;
    cr_status st = CR_OK;
    out->bodies = calloc((size_t)(nb > 0 ? nb : 1), sizeof *out->bodies);
    out->garments = calloc((size_t)(ng > 0 ? ng : 1), sizeof *out->garments);
    out->garment_key = calloc((size_t)(ng > 0 ? ng : 1), sizeof *out->garment_key);
    out->sequences = calloc((size_t)(ns > 0 ? ns : 1), sizeof *out->sequences);
    if (!out->bodies || !out->garments || !out->garment_key || !out->sequences)
        st = CR_FAIL(err, CR_ERR_MEMORY, "swingar data: out of memory");
    for (int32_t i = 0; i < nb && st == CR_OK; i++) {
        st = load_body(&man, &man.bodies[i], &out->bodies[i], err);
        out->nbodies = i + 1;
    }
    for (int32_t i = 0; i < ng && st == CR_OK; i++) {
        st = load_garment(&man, &man.garments[i], out, z, with_descriptor, affinity,
                          &out->garments[i], out->garment_key[i], err);
        if (st == CR_OK) out->ngarments = i + 1;
    }
    for (int32_t i = 0; i < ns && st == CR_OK; i++) {
        if (!man.sequences[i].done) continue;
        cr_swingar_sequence *s = &out->sequences[out->nsequences];
        st = load_sequence(&man, &man.sequences[i], out, s, err);
        out->nsequences++;
    }
    if (st == CR_OK && out->nsequences == 0)
        st = CR_FAIL(err, CR_ERR_INVALID, "%s/manifest.json: no sequence is done", dir);
    cr_dataset_manifest_free(&man);
    if (st != CR_OK) cr_swingar_data_free(out);
    return st;
}

static int listed(const char *name, const char *const *list, int n) {
    for (int i = 0; i < n; i++)
        if (strcmp(name, list[i]) == 0) return 1;
    return 0;
}

void cr_swingar_split(const cr_swingar_data *d, const char *const *garments, int ng,
                      const char *const *motions, int nm, const char *const *bodies, int nb,
                      int8_t *is_test) {
    for (int32_t i = 0; i < d->nsequences; i++) {
        const cr_swingar_sequence *s = &d->sequences[i];
        int tg = listed(s->garment, garments, ng), tm = listed(s->motion, motions, nm);
        int tb = listed(s->body, bodies, nb);
        int held = ng + nm + nb > 0;
        /* a list that is empty holds nothing out on its axis: test needs the
         * non-empty axes all held out */
        int all = held && (ng == 0 || tg) && (nm == 0 || tm) && (nb == 0 || tb);
        int none = !tg && !tm && !tb;
        is_test[i] = all ? 1 : none ? 0 : -1;
    }
}
