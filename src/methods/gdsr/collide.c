/* collide.c: gdsr's collision handling (sec. 4.6, Eq. 26-27) on the high
 * garment: the per-vertex push out of the body, and a relaxation that
 * spreads each push over the pushed vertex's neighbourhood.
 *
 * A push of height h on one vertex stretches its one-ring's edges by about
 * (h / l)^2 / 2 (l the edge length); the same push spread as a smooth bump
 * of radius R = n l stretches each edge by (h / R)^2 / 2, so the strain
 * energy falls by about (l / R)^2. The relaxation smooths the displacement
 * D = x - raw by Jacobi steps of the uniform Laplacian on the vertices that
 * moved and their one-ring, then pushes out again whatever the smoothing
 * lowered back under the margin: each iteration spreads D by one ring while
 * the pushed vertices stay outside.
 *
 * Layers (Eq. 27): on an outfit (layer k + 1 worn over layer k, the
 * dataset's order, innermost first), each coarse vertex c_e of an outer
 * layer takes the nearest vertex c_i of the layers under it within gamma
 * (the paper's |c_e - c_i| < gamma, needed because a garment is an open
 * surface: an inner vertex past the outer one's edge is not a collision);
 * when sigma - (c_e - c_i) . n_i > 0 (n_i the inner layer's normal at C^)
 * c_e is pushed out along n_i to sigma, the push carried to the high
 * vertices through Eq. 1, and then every high vertex g whose nearest coarse
 * vertex (its face's corner of largest weight, the nearest in UV) was one of
 * those is pushed as Eq. 27 says: g += max(sigma - (g - c_i) . n_i, 0) n_i.
 * The inner layer is not moved. Constants: the authors' code's 5 mm
 * between layers and 5 times that for gamma (RESEARCH_WAVE2 A1).
 *
 * Leaves out: cotangent weights; a tangential-only or strain-limiting
 * projection (the smoothed D has a tangential part too).
 */
#include "gdsr_internal.h"

#include "crease/diffgeo.h"
#include "crease/garment.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int64_t cr_gdsr_push_out(const cr_bvh *b, float *x, int64_t n, float eps, float *sd, float *nrm,
                         float *push) {
    cr_bvh_signed_distance_batch(b, x, n, 0.2f, sd, nrm, NULL);
    int64_t inside = 0;
    for (int64_t i = 0; i < n; i++) {
        if (sd[i] < 0) inside++;
        if (sd[i] < eps) {
            float s = eps - sd[i];
            for (int k = 0; k < 3; k++) {
                x[3 * i + k] += s * nrm[3 * i + k];
                if (push) push[3 * i + k] = s * nrm[3 * i + k];
            }
        } else if (push) {
            push[3 * i] = push[3 * i + 1] = push[3 * i + 2] = 0.0f;
        }
    }
    return inside;
}

/* A vertex whose distance to the body after the first push was lb, and that
 * has since moved m, is at least lb - m from it (the distance is 1-Lipschitz):
 * with lb - m >= eps (plus a micrometre against rounding) a query would find
 * no push to make, and is skipped. */
#define RELAX_BOUND_MARGIN 1e-6f

/* Pushes out the listed vertices of x (idx[0..c)) that the bound leaves in
 * doubt, gathered into s->d. */
static void push_listed(const cr_bvh *b, float *x, int32_t *idx, int64_t c, float eps,
                        const cr_gdsr_relax_scratch *s) {
    int64_t q = 0;
    for (int64_t k = 0; k < c; k++) {
        const int32_t i = idx[k];
        const float *p = x + 3 * (int64_t)i;
        if (s->lb) {
            const float *p0 = s->x0 + 3 * (int64_t)i;
            const float dx = p[0] - p0[0], dy = p[1] - p0[1], dz = p[2] - p0[2];
            if (s->lb[i] - sqrtf(dx * dx + dy * dy + dz * dz) >= eps + RELAX_BOUND_MARGIN) continue;
        }
        idx[q] = i;
        memcpy(&s->d[3 * q++], p, 3 * sizeof(float));
    }
    cr_gdsr_push_out(b, s->d, q, eps, s->sd, s->nrm, NULL);
    for (int64_t k = 0; k < q; k++)
        memcpy(&x[3 * (int64_t)idx[k]], &s->d[3 * k], 3 * sizeof(float));
}

void cr_gdsr_relax_push(const cr_bvh *b, const cr_topology *t, const float *raw, float *x,
                        float eps, int iters, const cr_gdsr_relax_scratch *s) {
    int32_t n = t->nv;
    float *d = s->d, *dn = s->dn;
    uint8_t *moved = s->moved;
    cr_gdsr_push_out(b, x, n, eps, s->sd, s->nrm, NULL);
    if (s->lb) {
        memcpy(s->x0, x, sizeof(float) * 3 * (size_t)n);
        for (int32_t i = 0; i < n; i++) /* a pushed vertex's new distance is not known */
            s->lb[i] = s->sd[i] >= eps ? s->sd[i] : -INFINITY;
    }
    for (int it = 0; it < iters; it++) {
        for (int64_t i = 0; i < 3 * (int64_t)n; i++)
            d[i] = x[i] - raw[i];
        for (int32_t i = 0; i < n; i++)
            moved[i] = d[3 * i] != 0.0f || d[3 * i + 1] != 0.0f || d[3 * i + 2] != 0.0f;
        /* smooth on the moved vertices and their one-ring (moved[i] |= 2) */
        for (int32_t i = 0; i < n; i++) {
            int32_t b0 = t->vv_off[i], b1 = t->vv_off[i + 1];
            int near = moved[i] & 1;
            for (int32_t e = b0; !near && e < b1; e++)
                near = moved[t->vv[e]] & 1;
            if (!near || b1 == b0) continue;
            float sum[3] = {0, 0, 0};
            for (int32_t e = b0; e < b1; e++)
                for (int k = 0; k < 3; k++)
                    sum[k] += d[3 * (int64_t)t->vv[e] + k];
            for (int k = 0; k < 3; k++)
                dn[3 * (int64_t)i + k] = 0.5f * d[3 * (int64_t)i + k] + 0.5f * sum[k] / (b1 - b0);
            moved[i] |= 2;
        }
        /* only the smoothed vertices moved: push those */
        int64_t c = 0;
        for (int32_t i = 0; i < n; i++)
            if (moved[i] & 2) {
                for (int k = 0; k < 3; k++)
                    x[3 * (int64_t)i + k] = raw[3 * (int64_t)i + k] + dn[3 * (int64_t)i + k];
                s->idx[c++] = i;
            }
        push_listed(b, x, s->idx, c, eps, s);
    }
    /* concave spots: once more, on the vertices that moved; one that did not
     * is where the first push found it at eps or more (the same point, the
     * same body), so a pass over all would leave it too */
    int64_t c = 0;
    for (int32_t i = 0; i < n; i++) {
        const float *p = x + 3 * (int64_t)i, *q = raw + 3 * (int64_t)i;
        if (p[0] != q[0] || p[1] != q[1] || p[2] != q[2]) s->idx[c++] = i;
    }
    push_listed(b, x, s->idx, c, eps, s);
}

/* The surface rule's partners: for each outer coarse vertex o, the closest
 * point of the layers under its own on their triangles at C^ within gamma,
 * unless that point lies on an open edge of that layer and o is more to the
 * side of it than above or below it (o is then past the inner garment's hem
 * or cuff, not over it); pp gets the point and pn the normal there (the
 * vertex normals blended by its barycentric weights). has[o] = 1 where
 * found. */
static cr_status surface_partners(const cr_gdsr_data *d, const float *chat, const float *nrm,
                                  float gamma, uint8_t *has, float *pp, float *pn, cr_error *err) {
    const cr_mesh *low = d->low;
    const int32_t nl = low->nv, nf = low->nf;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(low, &t, err));
    int32_t *tri = malloc(sizeof(int32_t) * 3 * (size_t)nf);
    int32_t *fmap = malloc(sizeof(int32_t) * (size_t)nf); /* layer face -> low face */
    float *best = malloc(sizeof(float) * (size_t)nl);
    cr_status st = tri && fmap && best ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    for (int32_t o = 0; o < nl; o++)
        has[o] = 0, best[o] = INFINITY;
    for (int32_t k = 0; st == CR_OK && k + 1 < d->nlayers; k++) {
        int32_t n = 0; /* layer k's triangles */
        for (int32_t f = 0; f < nf; f++)
            if (d->layer[low->tri[3 * f]] == k) {
                memcpy(tri + 3 * n, low->tri + 3 * f, 3 * sizeof(int32_t));
                fmap[n++] = f;
            }
        if (n == 0) continue;
        cr_bvh *b = NULL;
        if ((st = cr_bvh_build(chat, nl, tri, n, &b, err)) != CR_OK) break;
        for (int32_t o = 0; o < nl; o++) {
            cr_bvh_hit h;
            if (d->layer[o] <= k || !cr_bvh_closest(b, chat + 3 * o, gamma, &h)) continue;
            if (!(h.distance < best[o])) continue;
            const int32_t f = fmap[h.face];
            const int32_t *c = low->tri + 3 * f;
            int open = h.feature == CR_BVH_EDGE     ? t->face_face[3 * f + h.local] < 0
                       : h.feature == CR_BVH_VERTEX ? t->vertex_boundary[c[h.local]]
                                                    : 0;
            best[o] = h.distance;
            float q[3] = {0, 0, 0};
            for (int j = 0; j < 3; j++)
                for (int e = 0; e < 3; e++)
                    q[e] += h.bary[j] * nrm[3 * c[j] + e];
            float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
            for (int e = 0; e < 3; e++)
                pp[3 * o + e] = h.point[e], pn[3 * o + e] = len > 0 ? q[e] / len : 0.0f;
            /* on the open edge, o is over the layer when the offset is mostly along the
               normal there (over or under the hem), past it when mostly sideways */
            float along = 0, off2 = 0;
            for (int e = 0; e < 3; e++) {
                float r = chat[3 * o + e] - h.point[e];
                along += r * pn[3 * o + e], off2 += r * r;
            }
            const int past = open && off2 - along * along > along * along;
            has[o] = len > 0 && !past;
        }
        cr_bvh_destroy(b);
    }
    free(tri), free(fmap), free(best);
    cr_topology_destroy(t);
    return st;
}

int64_t cr_gdsr_layer_push(const cr_gdsr_data *d, float *chat, float *x, float sigma, float gamma,
                           int surface, int64_t *fine_pushed, cr_error *err) {
    if (fine_pushed) *fine_pushed = 0;
    if (d->nlayers < 2 || !d->layer) return 0;
    const cr_mesh *low = d->low;
    const int32_t nl = low->nv, nh = d->high->nv;
    cr_gdsr_graph g = {0};
    g.nv = nl;
    uint8_t *has = malloc((size_t)nl + 1);
    float *pp = malloc(sizeof(float) * 3 * (size_t)nl); /* each outer vertex's partner point */
    float *pn = malloc(sizeof(float) * 3 * (size_t)nl); /* and the normal there */
    float *nrm = malloc(sizeof(float) * 3 * (size_t)nl);
    float *lpush = calloc(3 * (size_t)nl, sizeof(float));
    float *hpush = malloc(sizeof(float) * 3 * (size_t)nh);
    float *bestd = malloc(sizeof(float) * (size_t)nl); /* squared distance to partner */
    int64_t pushed = -1;
    if (!has || !pp || !pn || !nrm || !lpush || !hpush || !bestd) {
        CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory (layer collisions)");
        goto done;
    }
    cr_mesh view = *low;
    view.pos = chat;
    cr_mesh_vertex_normals(&view, CR_NORMAL_AREA, nrm);
    if (surface) {
        if (surface_partners(d, chat, nrm, gamma, has, pp, pn, err) != CR_OK) goto done;
    } else {
        /* the paper's: the nearest vertex of a layer under o's within gamma, its normal;
           pairs on different layers closer than gamma: the layer edges' grid */
        if (cr_gdsr_layer_edges(&g, d->layer, chat, gamma, err) != CR_OK) goto done;
        for (int32_t i = 0; i < nl; i++)
            has[i] = 0;
        for (int64_t e = 0; e < g.ne[2]; e++) {
            int32_t o = g.rcv[2][e], i = g.snd[2][e];
            if (d->layer[i] >= d->layer[o]) continue; /* i must be under o */
            float d2 = 0;
            for (int k = 0; k < 3; k++) {
                float q = chat[3 * o + k] - chat[3 * i + k];
                d2 += q * q;
            }
            if (has[o] && !(d2 < bestd[o])) continue;
            has[o] = 1, bestd[o] = d2;
            for (int k = 0; k < 3; k++)
                pp[3 * o + k] = chat[3 * i + k], pn[3 * o + k] = nrm[3 * i + k];
        }
    }
    pushed = 0;
    for (int32_t o = 0; o < nl; o++) {
        if (!has[o]) continue;
        const float *p = pp + 3 * o, *n = pn + 3 * o;
        float s = sigma - ((chat[3 * o] - p[0]) * n[0] + (chat[3 * o + 1] - p[1]) * n[1] +
                           (chat[3 * o + 2] - p[2]) * n[2]);
        if (!(s > 0)) {
            has[o] = 0; /* no collision: its high vertices are left alone */
            continue;
        }
        for (int k = 0; k < 3; k++) {
            lpush[3 * o + k] = s * n[k];
            chat[3 * o + k] += s * n[k];
        }
        pushed++;
    }
    cr_gdsr_upsample(d, lpush, hpush);
    int64_t fine = 0;
    for (int32_t v = 0; v < nh; v++) {
        for (int k = 0; k < 3; k++)
            x[3 * v + k] += hpush[3 * v + k];
        const int32_t *tri = low->tri + 3 * (int64_t)d->face[v];
        const float *b = d->bary + 3 * (int64_t)v;
        int c = b[1] > b[0] ? (b[2] > b[1] ? 2 : 1) : (b[2] > b[0] ? 2 : 0);
        int32_t o = tri[c];
        if (!has[o]) continue;
        const float *p = pp + 3 * o, *n = pn + 3 * o;
        float s = sigma - ((x[3 * v] - p[0]) * n[0] + (x[3 * v + 1] - p[1]) * n[1] +
                           (x[3 * v + 2] - p[2]) * n[2]);
        if (s > 0) {
            for (int k = 0; k < 3; k++)
                x[3 * v + k] += s * n[k];
            fine++;
        }
    }
    if (fine_pushed) *fine_pushed = fine;
done:
    free(has), free(pp), free(pn), free(nrm), free(lpush), free(hpush), free(bestd);
    cr_gdsr_graph_free(&g);
    return pushed;
}

/* The triangles of layer k of m as a mesh over all of m's vertices at x. */
static cr_mesh *layer_mesh(const cr_mesh *m, const int32_t *layer, int32_t k, const float *x,
                           cr_error *err) {
    int32_t nf = 0;
    for (int32_t f = 0; f < m->nf; f++)
        nf += layer[m->tri[3 * f]] == k;
    cr_mesh *s = NULL;
    if (cr_mesh_create(m->nv, nf, 0, &s, err) != CR_OK) return NULL;
    memcpy(s->pos, x, sizeof(float) * 3 * (size_t)m->nv);
    nf = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (layer[m->tri[3 * f]] == k) memcpy(s->tri + 3 * (size_t)nf++, m->tri + 3 * f, 12);
    return s;
}

int64_t cr_gdsr_layer_crossings(const cr_gdsr_data *d, const float *x, cr_error *err) {
    const cr_mesh *m = d->high;
    int32_t *layer = malloc(sizeof(int32_t) * (size_t)m->nv + 1);
    if (!layer) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory (crossings)"), -1;
    int32_t n = cr_gdsr_mesh_layers(m, layer);
    int64_t total = 0;
    for (int32_t a = 0; a < n && total >= 0; a++)
        for (int32_t b = a + 1; b < n && total >= 0; b++) {
            cr_mesh *ma = layer_mesh(m, layer, a, x, err), *mb = layer_mesh(m, layer, b, x, err);
            int64_t c = ma && mb ? cr_garment_count_crossings(ma, mb, err) : -1;
            total = c < 0 ? -1 : total + c;
            cr_mesh_destroy(ma), cr_mesh_destroy(mb);
        }
    free(layer);
    return total;
}
