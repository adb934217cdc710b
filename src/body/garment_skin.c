/* garment_skin.c: skinning weights from the body, keeping the clearance, and
 * low/high resolution correspondences.
 *
 * Weights: each garment vertex takes the body's weights at its closest body
 * point (barycentric blend of the three vertices' four weights each, up to
 * twelve joints), keeps the four largest and renormalises. Where a garment
 * hangs away from the body (skirts, the dress's skirt) the closest point
 * jumps from one leg to the other across the front and back, and skinning
 * would tear the cloth between the legs; there the weights are diffused
 * over the garment's own surface (Jacobi steps of the uniform Laplacian,
 * each vertex moving by mask * 1/2 towards its neighbours' mean, the mask
 * rising from 0 at the clearance to 1 five centimetres further out), about
 * 12 cm far, before the four largest are kept. So a skirt follows the pelvis
 * and both thighs smoothly, as CLOTH3D-style skirts do.
 *
 * Correspondence (gdsr, Eq. 1): a high-resolution vertex's UV is looked up
 * in the low mesh's UV layout (cr_uv_lookup); the face under it and the
 * barycentrics give S[C, f, u, v] = (1 - u - v) c0 + u c1 + v c2. A vertex on
 * a chart's rim outside the low chart takes the nearest point of it.
 *
 * Left out: dual-quaternion skinning, and weights for garments that hang
 * from something other than the body (a cape's corners, a bag).
 */
#include "garment_internal.h"

#include "crease/body.h"
#include "crease/topology.h"
#include "crease/uvlookup.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* How far the weights of loose parts spread over the garment, m. */
#define LOOSE_SPREAD_M 0.12
/* Mask ramp for loose parts: from the clearance to this much further out, m. */
#define LOOSE_RAMP_M 0.05f
#define LOOSE_MAX_STEPS 200

/* The four largest of w (22), renormalised, largest first. */
static void keep_four(const float *w, int32_t *joint, float *weight) {
    int used[CR_NJOINTS] = {0};
    double sum = 0.0;
    for (int k = 0; k < 4; k++) {
        int best = 0;
        while (used[best])
            best++;
        for (int j = best + 1; j < CR_NJOINTS; j++)
            if (!used[j] && w[j] > w[best]) best = j;
        used[best] = 1;
        joint[k] = best;
        weight[k] = w[best] > 0.0f ? w[best] : 0.0f;
        sum += weight[k];
    }
    if (!(sum > 0.0)) {
        weight[0] = 1.0f, weight[1] = weight[2] = weight[3] = 0.0f;
        return;
    }
    for (int k = 0; k < 4; k++)
        weight[k] = (float)(weight[k] / sum);
}

typedef struct spread_ctx {
    const cr_topology *t;
    const float *mask; /* (V) */
    const float *w;    /* (V,C) */
    float *next;       /* (V,C) */
    int32_t C;         /* channels: the joints any vertex has weight on */
} spread_ctx;

/* One Jacobi step of the masked diffusion over vertices [begin, end). */
static void spread_range(void *vctx, int64_t begin, int64_t end) {
    const spread_ctx *c = vctx;
    const int32_t C = c->C;
    for (int64_t v = begin; v < end; v++) {
        float *o = &c->next[v * C];
        const float *x = &c->w[v * C];
        int32_t n = c->t->vv_off[v + 1] - c->t->vv_off[v];
        memcpy(o, x, (size_t)C * sizeof(float));
        if (n == 0 || c->mask[v] == 0.0f) continue;
        float mean[CR_NJOINTS] = {0};
        for (int32_t q = c->t->vv_off[v]; q < c->t->vv_off[v + 1]; q++)
            for (int32_t j = 0; j < C; j++)
                mean[j] += c->w[(size_t)c->t->vv[q] * C + j];
        float a = 0.5f * c->mask[v];
        for (int32_t j = 0; j < C; j++)
            o[j] += a * (mean[j] / (float)n - x[j]);
    }
}

/* Diffuse the (V,22) weights over loose parts of the garment. */
static cr_status spread_loose(const cr_mesh *m, const float *dist, float clearance, float *w,
                              cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    /* Only the joints some vertex depends on take part (a skirt: a handful). */
    int32_t chan[CR_NJOINTS], C = 0;
    for (int j = 0; j < CR_NJOINTS; j++) {
        int used = 0;
        for (int32_t v = 0; v < m->nv && !used; v++)
            used = w[(size_t)v * CR_NJOINTS + j] > 0.0f;
        if (used) chan[C++] = j;
    }
    float *cw = cr_malloc((size_t)m->nv * (size_t)(C > 0 ? C : 1) * sizeof(float), err);
    float *next = cr_malloc((size_t)m->nv * (size_t)(C > 0 ? C : 1) * sizeof(float), err);
    float *mask = cr_malloc((size_t)m->nv * sizeof(float), err);
    cr_status st = cw && next && mask ? CR_OK : CR_ERR_MEMORY;
    double el = 0.0;
    for (int32_t e = 0; st == CR_OK && e < t->ne; e++) {
        const float *a = &m->pos[3 * (size_t)t->edge[2 * e]],
                    *b = &m->pos[3 * (size_t)t->edge[2 * e + 1]];
        el += sqrt((double)((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                            (a[2] - b[2]) * (a[2] - b[2])));
    }
    /* A random walk of n steps of length h/sqrt(2) spreads about h sqrt(n/2). */
    int steps = 0;
    if (st == CR_OK && t->ne > 0) {
        double h = el / t->ne, n = 2.0 * (LOOSE_SPREAD_M / h) * (LOOSE_SPREAD_M / h);
        steps = n > LOOSE_MAX_STEPS ? LOOSE_MAX_STEPS : (int)n;
    }
    for (int32_t v = 0; st == CR_OK && v < m->nv; v++) {
        float s = (dist[v] - clearance) / LOOSE_RAMP_M;
        mask[v] = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
        for (int32_t j = 0; j < C; j++)
            cw[(size_t)v * C + j] = w[(size_t)v * CR_NJOINTS + chan[j]];
    }
    for (int it = 0; st == CR_OK && it < steps; it++) {
        /* Serial: a step is too little work to pay for a parallel region's barrier. */
        spread_ctx c = {t, mask, cw, next, C};
        spread_range(&c, 0, m->nv);
        float *tmp = cw;
        cw = next, next = tmp;
    }
    for (int32_t v = 0; st == CR_OK && v < m->nv; v++)
        for (int32_t j = 0; j < C; j++)
            w[(size_t)v * CR_NJOINTS + chan[j]] = cw[(size_t)v * C + j];
    cr_topology_destroy(t);
    free(cw);
    free(next);
    free(mask);
    return st;
}

cr_status cr_garment_skin_transfer(const gbody *body, const cr_mesh *m, int loose, float clearance,
                                   int32_t *joint, float *weight, cr_error *err) {
    const cr_body_model *b = body->model;
    int32_t *face = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    float *bary = cr_malloc((size_t)m->nv * 3 * sizeof(float), err);
    float *dist = cr_malloc((size_t)m->nv * sizeof(float), err);
    float *w = cr_calloc((size_t)m->nv * CR_NJOINTS, sizeof(float), err);
    cr_status st = face && bary && dist && w ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        cr_bvh_closest_batch(body->bvh, m->pos, m->nv, INFINITY, face, NULL, bary, dist);
        for (int32_t v = 0; v < m->nv; v++) {
            float *wv = &w[(size_t)v * CR_NJOINTS];
            for (int k = 0; k < 3 && face[v] >= 0; k++) {
                int32_t bv = b->rest->tri[3 * face[v] + k];
                for (int q = 0; q < 4; q++)
                    wv[b->skin_joint[4 * bv + q]] += bary[3 * v + k] * b->skin_weight[4 * bv + q];
            }
        }
        if (loose) st = spread_loose(m, dist, clearance, w, err);
    }
    for (int32_t v = 0; st == CR_OK && v < m->nv; v++)
        keep_four(&w[(size_t)v * CR_NJOINTS], &joint[4 * v], &weight[4 * v]);
    free(face), free(bary), free(dist), free(w);
    return st;
}

int32_t cr_garment_push_out(const gbody *body, float *pos, int32_t nv, float min_m) {
    float d, n[3];
    int32_t moved = 0;
    for (int32_t v = 0; v < nv; v++) {
        float *p = &pos[3 * (size_t)v];
        /* The closest point moves as p does: a second look settles it. */
        for (int pass = 0; pass < 3; pass++) {
            cr_bvh_signed_distance(body->bvh, p, INFINITY, &d, n, NULL);
            if (d >= min_m) break;
            for (int k = 0; k < 3; k++)
                p[k] += (min_m - d) * n[k];
            moved += pass == 0;
        }
    }
    return moved;
}

cr_status cr_garment_pose(const cr_garment *g, const cr_body_model *body, const float *pose,
                          const float *trans, float *out, cr_error *err) {
    for (int i = 0; i < 3 * CR_NJOINTS; i++)
        if (!isfinite(pose[i]))
            return CR_FAIL(err, CR_ERR_NAN, "garment pose: joint %d's rotation is not finite",
                           i / 3);
    for (int i = 0; trans && i < 3; i++)
        if (!isfinite(trans[i]))
            return CR_FAIL(err, CR_ERR_NAN, "garment pose: the translation is not finite");
    float xf[CR_NJOINTS * 12];
    cr_body_skin_transforms(body->joints, pose, trans, xf);
    const cr_mesh *m = g->mesh;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *p = &m->pos[3 * (size_t)v];
        double acc[3] = {0, 0, 0};
        for (int k = 0; k < 4; k++) {
            const float *A = &xf[12 * g->skin_joint[4 * v + k]], w = g->skin_weight[4 * v + k];
            for (int r = 0; r < 3; r++)
                acc[r] += w * (A[4 * r] * p[0] + A[4 * r + 1] * p[1] + A[4 * r + 2] * p[2] +
                               A[4 * r + 3]);
        }
        for (int r = 0; r < 3; r++)
            out[3 * (size_t)v + r] = (float)acc[r];
    }
    return CR_OK;
}

/* --------------------------------------------------------- correspondence -- */

cr_status cr_garment_correspondence(const cr_mesh *low, const cr_mesh *high, int32_t *face,
                                    float *bary, cr_error *err) {
    if (!cr_mesh_has_uv(low) || !cr_mesh_has_uv(high))
        return CR_FAIL(err, CR_ERR_INVALID, "garment correspondence: the %s mesh has no UVs",
                       cr_mesh_has_uv(low) ? "high" : "low");
    int32_t *vuv = cr_malloc((size_t)high->nv * sizeof(int32_t), err);
    if (!vuv) return CR_ERR_MEMORY;
    for (int32_t v = 0; v < high->nv; v++)
        vuv[v] = -1;
    for (int32_t c = 0; c < 3 * high->nf; c++)
        if (vuv[high->tri[c]] < 0) vuv[high->tri[c]] = high->tri_uv[c];
    cr_uv_lookup *lk = NULL;
    cr_status st = cr_uv_lookup_build(low, 0, &lk, err);
    for (int32_t v = 0; st == CR_OK && v < high->nv; v++) {
        double b[3] = {1.0, 0.0, 0.0};
        int32_t f = 0;
        if (vuv[v] >= 0) {
            float u = high->uv[2 * (size_t)vuv[v]], w = high->uv[2 * (size_t)vuv[v] + 1];
            if (!cr_uv_lookup_find(lk, u, w, &f, b) && !cr_uv_lookup_nearest(lk, u, w, &f, b, NULL))
                st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                             "garment correspondence: the low mesh has no UV triangle of "
                             "non-zero area");
        }
        /* A vertex at a corner of the low face gets that corner alone, so a
         * mesh's correspondence to itself reproduces it exactly. */
        for (int k = 0; k < 3; k++)
            if (b[k] > 1.0 - 1e-6) b[0] = b[1] = b[2] = 0.0, b[k] = 1.0;
        face[v] = f;
        for (int k = 0; k < 3; k++)
            bary[3 * v + k] = (float)b[k];
    }
    cr_uv_lookup_destroy(lk);
    free(vuv);
    return st;
}

void cr_garment_apply_correspondence(const cr_mesh *low, const float *low_pos, const int32_t *face,
                                     const float *bary, int32_t nv_high, float *out) {
    for (int32_t v = 0; v < nv_high; v++) {
        const int32_t *t = &low->tri[3 * (size_t)face[v]];
        for (int d = 0; d < 3; d++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                s += (double)bary[3 * v + k] * low_pos[3 * (size_t)t[k] + d];
            out[3 * (size_t)v + d] = (float)s;
        }
    }
}
