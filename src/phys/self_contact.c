/* self_contact.c: cloth self-contact, a penalty on the distance of
 * vertex-triangle and edge-edge pairs of the cloth closer than a thickness.
 *
 * Detection (cr_self_contact_detect, once per substep, and again by VBD when
 * a vertex reaches its step bound): a BVH over the cloth's triangles
 * (geom/bvh.c) is refitted to the positions, then
 *   - per vertex p, the triangles whose box meets p's box inflated by the
 *     query radius r, and
 *   - per edge e, the triangles whose box meets e's box inflated by r; of
 *     each such face, its edges e2 > e (taken from the edge's lowest face
 *     only, so each edge pair once),
 * are measured exactly (point-triangle: the BVH's Ericson closest point;
 * edge-edge: Ericson 5.1.9). A pair within r is kept unless it shares a
 * vertex. A pair closer than r at rest (the garment's initial positions) is
 * a neighbour in the cloth (a vertex and the triangles two rings away on a
 * mesh of edges under r), not layers meeting: it is kept only within half
 * its rest distance d_r, with thickness d_r / 4 (REST_SHARE), so it carries
 * no force at rest but a fold tighter than an edge still meets one (left
 * out entirely, such pairs let the tall strip's tight folds cross). Both passes
 * count first and fill second, per item in parallel, so the pair list is
 * the same at any thread count.
 *
 * Energy per pair, with the pair's unit normal n and its weights w fixed at
 * detection (n from the closest point of the pair to the vertex or the
 * first edge, so d starts at the unsigned distance):
 *     d(x) = n . sum_k w_k x_k       VT: w = (1, -b0, -b1, -b2)
 *                                   EE: w = (1-s, s, -(1-t), -t)
 *     E = b(d) for d < eps, 0 above  (eps the pair's thickness)
 * with b IPC's log barrier -kappa (d - eps)^2 ln(d / eps), kappa = k eps (k
 * the body collision's stiffness: b is k (eps - d)^3, the body collision's
 * cubic, to leading order at eps), continued below d = BARRIER_FLOOR eps by
 * its second-order Taylor expansion there (pair_energy). d is linear in x,
 * so the gradient w_k b'(d) n and the Hessian w_a w_b b''(d) n n^T are
 * exact and PSD (b'' >= 0). A pair pushed through keeps its side: d goes
 * negative and the energy grows, instead of an unsigned distance's flipping
 * normal.
 */
#include "crease/phys_energies.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "crease/bvh.h"

/* Faces a query box collects before it reallocates. */
#define BOX_FACES 128
/* Vertices or edges of one detection task: each costs a few microseconds,
 * and a parallel region costs a scheduler quantum on a loaded machine. */
#define DETECT_GRAIN 2048
/* Partners per vertex or edge the count pass keeps for the fill pass. */
#define CACHE 12
/* A rest neighbour (a pair closer than r at rest) is a pair when it has
 * closed to this share of its rest distance, with thickness that radius
 * over CR_SELF_CONTACT_QUERY: mesh neighbours carry no force at rest, and
 * a fold tighter than an edge still meets a penalty. */
#define REST_SHARE 0.5

struct cr_self_contact {
    int32_t nv, nf, ne;
    int32_t *tri;       /* (F,3) */
    int32_t *edge;      /* (E,2) */
    int32_t *face_edge; /* (F,3) */
    int32_t *edge_face; /* (E) the lowest face on each edge */
    double *rest;       /* (V,3) rest positions (the initial garment), m */
    double eps, k, r;   /* thickness m, stiffness J/m^3, query radius m */
    cr_bvh *bvh;
    float *xf; /* (V,3) */
    /* Pairs of the last detection: VT first (by vertex), then EE (by edge). */
    int32_t npair, nvt, cap;
    int32_t *elem; /* (P,4) */
    double *w;     /* (P,4) */
    double *n;     /* (P,3) */
    double *d0;    /* (P) distance at detection, m */
    double *epsp;  /* (P) the pair's thickness: eps, or less for a rest neighbour, m */
    /* Per vertex: the nearest pair's distance (r when none), the positions
     * at detection, and the pairs it is in (4 pair + local). */
    double *dmin, *xdet;
    int64_t *vp_off;
    int32_t *vp;
    int64_t vp_cap;
    int32_t *cnt_v, *cnt_e; /* (V+1), (E+1) counts, then offsets */
    /* Rest neighbours, found once at create: per vertex the faces, per edge
     * the edges e2 > e, within r at rest (no pairs ever). */
    int64_t *vt_rest_off, *ee_rest_off;     /* (V+1), (E+1) */
    int32_t *vt_rest, *ee_rest;             /* faces, edges */
    double *vt_rest_d, *ee_rest_d;          /* their distances at rest, m */
    int32_t *vt_rest_off32, *ee_rest_off32; /* counts while they are built */
    int32_t *found, *cache; /* (V+E) pairs per vertex, then edge; (V+E, CACHE) their partners */
    double *cache_r;        /* (V+E, CACHE) the partners' query radii */
    const double *x;        /* positions being detected at */
};

static cr_status grow_pairs(cr_self_contact *sc, int64_t np, cr_error *err);
static cr_status rest_neighbours(cr_self_contact *sc, cr_error *err);

void cr_self_contact_destroy(cr_self_contact *sc) {
    if (!sc) return;
    free(sc->tri), free(sc->edge), free(sc->face_edge), free(sc->edge_face), free(sc->rest);
    cr_bvh_destroy(sc->bvh);
    free(sc->xf), free(sc->elem), free(sc->w), free(sc->n), free(sc->d0), free(sc->epsp);
    free(sc->dmin), free(sc->xdet), free(sc->vp_off), free(sc->vp);
    free(sc->cnt_v), free(sc->cnt_e);
    free(sc->vt_rest_off), free(sc->ee_rest_off), free(sc->vt_rest), free(sc->ee_rest);
    free(sc->vt_rest_d), free(sc->ee_rest_d), free(sc->cache_r);
    free(sc->vt_rest_off32), free(sc->ee_rest_off32), free(sc->found), free(sc->cache);
    free(sc);
}

cr_status cr_self_contact_create(const cr_mesh *garment, const cr_topology *topo, double thickness,
                                 double stiffness, cr_self_contact **out, cr_error *err) {
    CR_ASSERT(garment && topo && out);
    *out = NULL;
    if (!(isfinite(thickness) && thickness > 0.0) || !(isfinite(stiffness) && stiffness >= 0.0))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "self-contact: thickness %g m must be positive and stiffness %g J/m^3 "
                       ">= 0",
                       thickness, stiffness);
    cr_self_contact *sc = cr_calloc(1, sizeof *sc, err);
    if (!sc) return err ? err->status : CR_ERR_MEMORY;
    const int32_t nv = garment->nv, nf = garment->nf, ne = topo->ne;
    sc->nv = nv, sc->nf = nf, sc->ne = ne;
    sc->eps = thickness, sc->k = stiffness;
    sc->r = CR_SELF_CONTACT_QUERY * thickness;
    size_t v1 = (size_t)nv + 1, e1 = (size_t)ne + 1;
    sc->tri = cr_malloc(3 * (size_t)nf * sizeof(int32_t), err);
    sc->edge = cr_malloc(2 * e1 * sizeof(int32_t), err);
    sc->face_edge = cr_malloc(3 * (size_t)nf * sizeof(int32_t), err);
    sc->edge_face = cr_malloc(e1 * sizeof(int32_t), err);
    sc->rest = cr_malloc(3 * v1 * sizeof(double), err);
    sc->xf = cr_malloc(3 * v1 * sizeof(float), err);
    sc->dmin = cr_malloc(v1 * sizeof(double), err);
    sc->xdet = cr_malloc(3 * v1 * sizeof(double), err);
    sc->vp_off = cr_calloc(v1, sizeof(int64_t), err);
    sc->cnt_v = cr_calloc(v1, sizeof(int32_t), err);
    sc->cnt_e = cr_calloc(e1, sizeof(int32_t), err);
    sc->found = cr_calloc(v1 + e1, sizeof(int32_t), err);
    sc->cache = cr_malloc(CACHE * (v1 + e1) * sizeof(int32_t), err);
    sc->cache_r = cr_malloc(CACHE * (v1 + e1) * sizeof(double), err);
    if (!sc->tri || !sc->edge || !sc->face_edge || !sc->edge_face || !sc->rest || !sc->xf ||
        !sc->dmin || !sc->xdet || !sc->vp_off || !sc->cnt_v || !sc->cnt_e || !sc->found ||
        !sc->cache || !sc->cache_r) {
        cr_self_contact_destroy(sc);
        return err ? err->status : CR_ERR_MEMORY;
    }
    memcpy(sc->tri, garment->tri, 3 * (size_t)nf * sizeof(int32_t));
    memcpy(sc->edge, topo->edge, 2 * (size_t)ne * sizeof(int32_t));
    memcpy(sc->face_edge, topo->face_edge, 3 * (size_t)nf * sizeof(int32_t));
    for (int32_t e = 0; e < ne; e++)
        sc->edge_face[e] = topo->edge_face[2 * e];
    for (int64_t k = 0; k < 3 * (int64_t)nv; k++) {
        sc->rest[k] = garment->pos[k];
        sc->xf[k] = garment->pos[k];
        sc->xdet[k] = garment->pos[k];
    }
    for (int32_t i = 0; i < nv; i++)
        sc->dmin[i] = sc->r;
    cr_status st = cr_bvh_build(sc->xf, nv, sc->tri, nf, &sc->bvh, err);
    if (st == CR_OK) st = grow_pairs(sc, 1, err); /* a term's elem is never NULL */
    if (st == CR_OK) st = rest_neighbours(sc, err);
    if (st != CR_OK) {
        cr_self_contact_destroy(sc);
        return st;
    }
    *out = sc;
    return CR_OK;
}

/* ------------------------------------------------------------ distances -- */

static double dot3(const double *a, const double *b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Closest points of segments p1 + s (q1 - p1) and p2 + t (q2 - p2), s, t in
 * [0, 1] (Ericson, Real-Time Collision Detection, 5.1.9); returns the squared
 * distance. Parallel segments take s = 0 or the clamped projection. */
static double closest_segments(const double *p1, const double *q1, const double *p2,
                               const double *q2, double *s_out, double *t_out) {
    double d1[3], d2[3], r[3];
    for (int k = 0; k < 3; k++)
        d1[k] = q1[k] - p1[k], d2[k] = q2[k] - p2[k], r[k] = p1[k] - p2[k];
    double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r), s, t;
    const double tiny = 1e-30;
    if (a <= tiny && e <= tiny) {
        s = t = 0.0;
    } else if (a <= tiny) {
        s = 0.0;
        t = fmin(fmax(f / e, 0.0), 1.0);
    } else {
        double c = dot3(d1, r);
        if (e <= tiny) {
            t = 0.0;
            s = fmin(fmax(-c / a, 0.0), 1.0);
        } else {
            double b = dot3(d1, d2), den = a * e - b * b;
            s = den > 1e-12 * a * e ? fmin(fmax((b * f - c * e) / den, 0.0), 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = fmin(fmax(-c / a, 0.0), 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = fmin(fmax((b - c) / a, 0.0), 1.0);
            }
        }
    }
    double d2s = 0.0;
    for (int k = 0; k < 3; k++) {
        double u = p1[k] + s * d1[k] - (p2[k] + t * d2[k]);
        d2s += u * u;
    }
    *s_out = s, *t_out = t;
    return d2s;
}

/* A pair's normal and weights from its four positions X (4,3): returns the
 * distance, or -1 when no normal can be had (coincident degenerate
 * primitives). kind 0: vertex X0 against triangle X1 X2 X3 with barycentric
 * weights b; kind 1: edges X0 X1 and X2 X3 at parameters s, t. */
static double pair_frame(int kind, const double *X, const double *bst, double *n, double *w) {
    if (kind == 0) {
        w[0] = 1.0, w[1] = -bst[0], w[2] = -bst[1], w[3] = -bst[2];
    } else {
        w[0] = 1.0 - bst[0], w[1] = bst[0], w[2] = -(1.0 - bst[1]), w[3] = -bst[1];
    }
    double u[3]; /* the closest points' difference, sum_a w_a X_a */
    for (int k = 0; k < 3; k++)
        u[k] = w[0] * X[k] + w[1] * X[3 + k] + w[2] * X[6 + k] + w[3] * X[9 + k];
    double d = sqrt(dot3(u, u));
    if (!(d > 1e-12)) {
        /* Touching: the triangle's normal, or the edges' cross product. */
        double a[3], b[3];
        for (int k = 0; k < 3; k++) {
            a[k] = kind == 0 ? X[6 + k] - X[3 + k] : X[3 + k] - X[k];
            b[k] = kind == 0 ? X[9 + k] - X[3 + k] : X[9 + k] - X[6 + k];
        }
        u[0] = a[1] * b[2] - a[2] * b[1];
        u[1] = a[2] * b[0] - a[0] * b[2];
        u[2] = a[0] * b[1] - a[1] * b[0];
        d = sqrt(dot3(u, u));
        if (!(d > 0.0)) return -1.0;
        for (int k = 0; k < 3; k++)
            n[k] = u[k] / d;
        return 0.0;
    }
    for (int k = 0; k < 3; k++)
        n[k] = u[k] / d;
    return d;
}

static void gather4(const double *pos, const int32_t *idx, double *X) {
    for (int a = 0; a < 4; a++)
        for (int k = 0; k < 3; k++)
            X[3 * a + k] = pos[3 * (int64_t)idx[a] + k];
}

/* Squared distance of pair idx at positions pos, and its bst (bary or s, t). */
static double pair_dist2(int kind, const double *pos, const int32_t *idx, double *bst) {
    double X[12];
    gather4(pos, idx, X);
    if (kind == 0) return cr_closest_point_triangle(X, X + 3, X + 6, X + 9, bst);
    return closest_segments(X, X + 3, X + 6, X + 9, &bst[0], &bst[1]);
}

/* ------------------------------------------------------------ detection -- */

typedef struct detect_ctx {
    cr_self_contact *sc;
    int fill; /* 0: count into cnt_v / cnt_e; 1: write at their offsets */
    int rest; /* 1: list the pairs within r at rest (at create) instead of the pairs */
    int *oom; /* set to 1 by a task that could not allocate */
} detect_ctx;

/* Keep pair idx (kind), query radius r, at the current positions? Writes
 * it at slot `at` when filling, with thickness r / CR_SELF_CONTACT_QUERY. */
static int consider(cr_self_contact *sc, int kind, const int32_t *idx, double r, int fill,
                    int64_t at) {
    double bst[3], r2 = r * r;
    double d2 = pair_dist2(kind, sc->x, idx, bst);
    if (!(d2 < r2)) return 0;
    double X[12], n[3], w[4];
    gather4(sc->x, idx, X);
    double d = pair_frame(kind, X, bst, n, w);
    if (d < 0.0) return 0;
    if (fill) {
        memcpy(sc->elem + 4 * at, idx, 4 * sizeof(int32_t));
        memcpy(sc->w + 4 * at, w, sizeof w);
        memcpy(sc->n + 3 * at, n, sizeof n);
        sc->d0[at] = d;
        sc->epsp[at] = r == sc->r ? sc->eps : r / CR_SELF_CONTACT_QUERY;
    }
    return 1;
}

/* Faces whose boxes meet [lo, hi]: into *buf (grown as needed); count or -1. */
static int64_t box_faces(const cr_bvh *b, const float *lo, const float *hi, int32_t **buf,
                         int64_t *cap, int32_t *local) {
    int64_t n = cr_bvh_faces_in_box(b, lo, hi, *buf, *cap);
    if (n <= *cap) return n;
    int32_t *nb = malloc((size_t)n * sizeof(int32_t));
    if (!nb) return -1;
    if (*buf != local) free(*buf);
    *buf = nb, *cap = n;
    return cr_bvh_faces_in_box(b, lo, hi, *buf, *cap);
}

/* One candidate of item `item` (a vertex or an edge) with partner `other`
 * (a face or an edge): at create, listed when within r at rest; later,
 * measured against r, or against REST_SHARE of its rest distance when it
 * is listed (stamp[other] == item + 1, rest_d[other] that distance). */
static int candidate(const detect_ctx *c, int kind, int64_t item, int32_t other, const int32_t *idx,
                     const int32_t *stamp, const double *rest_d, int64_t at, int64_t found) {
    cr_self_contact *sc = c->sc;
    if (c->rest) {
        double bst[3], d2 = pair_dist2(kind, sc->rest, idx, bst);
        if (!(d2 < sc->r * sc->r)) return 0;
        if (c->fill) {
            (kind == 0 ? sc->vt_rest : sc->ee_rest)[at] = other;
            (kind == 0 ? sc->vt_rest_d : sc->ee_rest_d)[at] = sqrt(d2);
        }
        return 1;
    }
    double r = stamp[other] == item + 1 ? REST_SHARE * rest_d[other] : sc->r;
    int keep = consider(sc, kind, idx, r, c->fill, at);
    /* The count pass remembers the partners, so the fill pass need not search again. */
    int64_t slot = kind == 0 ? item : sc->nv + item;
    if (keep && !c->fill && found < CACHE) {
        sc->cache[CACHE * slot + found] = other;
        sc->cache_r[CACHE * slot + found] = r;
    }
    return keep;
}

/* The fill pass from the count pass's partners of item (a vertex, kind 0,
 * or an edge): 0 when they did not fit the cache (search again). */
static int replay(const detect_ctx *c, int kind, int64_t item, int64_t at) {
    cr_self_contact *sc = c->sc;
    int64_t slot = kind == 0 ? item : sc->nv + item;
    int32_t n = sc->found[slot];
    if (n > CACHE) return 0;
    for (int32_t q = 0; q < n; q++) {
        int32_t other = sc->cache[CACHE * slot + q], idx[4];
        if (kind == 0) {
            const int32_t *t = sc->tri + 3 * (int64_t)other;
            idx[0] = (int32_t)item, idx[1] = t[0], idx[2] = t[1], idx[3] = t[2];
        } else {
            const int32_t *a = sc->edge + 2 * item, *b = sc->edge + 2 * (int64_t)other;
            idx[0] = a[0], idx[1] = a[1], idx[2] = b[0], idx[3] = b[1];
        }
        consider(sc, kind, idx, sc->cache_r[CACHE * slot + q], 1, at + q);
    }
    return 1;
}

/* Mark item's rest neighbours (list[off[item] .. off[item+1])) in stamp,
 * their rest distances in rest_d. */
static void stamp_rest(const detect_ctx *c, const int64_t *off, const int32_t *list,
                       const double *dist, int64_t item, int32_t *stamp, double *rest_d) {
    if (c->rest) return;
    for (int64_t q = off[item]; q < off[item + 1]; q++) {
        stamp[list[q]] = (int32_t)(item + 1);
        rest_d[list[q]] = dist[q];
    }
}

static void vt_range(void *vctx, int64_t begin, int64_t end) {
    const detect_ctx *c = vctx;
    cr_self_contact *sc = c->sc;
    int32_t local[BOX_FACES], *faces = local;
    int64_t cap = BOX_FACES;
    int32_t *stamp = c->rest ? NULL : calloc((size_t)sc->nf + 1, sizeof(int32_t));
    double *rest_d = c->rest ? NULL : malloc(((size_t)sc->nf + 1) * sizeof(double));
    if (!c->rest && (!stamp || !rest_d)) {
        free(stamp), free(rest_d);
        *c->oom = 1;
        return;
    }
    const float r = (float)sc->r;
    int32_t *cnt = c->rest ? sc->vt_rest_off32 : sc->cnt_v;
    for (int64_t i = begin; i < end; i++) {
        if (c->fill && !c->rest && replay(c, 0, i, cnt[i])) continue;
        const float *p = sc->xf + 3 * i;
        float lo[3] = {p[0] - r, p[1] - r, p[2] - r}, hi[3] = {p[0] + r, p[1] + r, p[2] + r};
        int64_t nf = box_faces(sc->bvh, lo, hi, &faces, &cap, local);
        if (nf < 0) *c->oom = 1;
        stamp_rest(c, sc->vt_rest_off, sc->vt_rest, sc->vt_rest_d, i, stamp, rest_d);
        int64_t at = c->fill ? cnt[i] : 0, found = 0;
        for (int64_t q = 0; q < nf; q++) {
            const int32_t *t = sc->tri + 3 * (int64_t)faces[q];
            if (t[0] == i || t[1] == i || t[2] == i) continue;
            int32_t idx[4] = {(int32_t)i, t[0], t[1], t[2]};
            found += candidate(c, 0, i, faces[q], idx, stamp, rest_d, at + found, found);
        }
        if (!c->fill) cnt[i] = (int32_t)found;
        if (!c->fill && !c->rest) sc->found[i] = (int32_t)found;
    }
    if (faces != local) free(faces);
    free(stamp), free(rest_d);
}

static void ee_range(void *vctx, int64_t begin, int64_t end) {
    const detect_ctx *c = vctx;
    cr_self_contact *sc = c->sc;
    int32_t local[BOX_FACES], *faces = local;
    int64_t cap = BOX_FACES;
    int32_t *stamp = c->rest ? NULL : calloc((size_t)sc->ne + 1, sizeof(int32_t));
    double *rest_d = c->rest ? NULL : malloc(((size_t)sc->ne + 1) * sizeof(double));
    if (!c->rest && (!stamp || !rest_d)) {
        free(stamp), free(rest_d);
        *c->oom = 1;
        return;
    }
    const float r = (float)sc->r;
    int32_t *cnt = c->rest ? sc->ee_rest_off32 : sc->cnt_e;
    for (int64_t e = begin; e < end; e++) {
        if (c->fill && !c->rest && replay(c, 1, e, cnt[e])) continue;
        const int32_t *ev = sc->edge + 2 * e;
        const float *a = sc->xf + 3 * (int64_t)ev[0], *b = sc->xf + 3 * (int64_t)ev[1];
        float lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            lo[k] = (a[k] < b[k] ? a[k] : b[k]) - r;
            hi[k] = (a[k] > b[k] ? a[k] : b[k]) + r;
        }
        int64_t nf = box_faces(sc->bvh, lo, hi, &faces, &cap, local);
        if (nf < 0) *c->oom = 1;
        stamp_rest(c, sc->ee_rest_off, sc->ee_rest, sc->ee_rest_d, e, stamp, rest_d);
        int64_t at = c->fill ? cnt[e] : 0, found = 0;
        for (int64_t q = 0; q < nf; q++) {
            int32_t f = faces[q];
            for (int j = 0; j < 3; j++) {
                int32_t e2 = sc->face_edge[3 * (int64_t)f + j];
                if (e2 <= e || sc->edge_face[e2] != f) continue;
                const int32_t *ov = sc->edge + 2 * (int64_t)e2;
                if (ov[0] == ev[0] || ov[0] == ev[1] || ov[1] == ev[0] || ov[1] == ev[1]) continue;
                int32_t idx[4] = {ev[0], ev[1], ov[0], ov[1]};
                found += candidate(c, 1, e, e2, idx, stamp, rest_d, at + found, found);
            }
        }
        if (!c->fill) cnt[e] = (int32_t)found;
        if (!c->fill && !c->rest) sc->found[sc->nv + e] = (int32_t)found;
    }
    if (faces != local) free(faces);
    free(stamp), free(rest_d);
}

/* Turn counts (n) into exclusive offsets starting at base; returns the total. */
static int64_t offsets(int32_t *cnt, int32_t n, int64_t base) {
    int64_t sum = base;
    for (int32_t i = 0; i < n; i++) {
        int64_t c = cnt[i];
        cnt[i] = (int32_t)sum;
        sum += c;
    }
    return sum;
}

static cr_status grow_pairs(cr_self_contact *sc, int64_t np, cr_error *err) {
    if (np > INT32_MAX / 4)
        return CR_FAIL(err, CR_ERR_RANGE, "self-contact: %lld pairs, too many", (long long)np);
    if (np <= sc->cap) return CR_OK;
    int64_t cap = np + np / 2 + 64;
    int32_t *elem = realloc(sc->elem, 4 * (size_t)cap * sizeof(int32_t));
    if (elem) sc->elem = elem;
    double *w = realloc(sc->w, 4 * (size_t)cap * sizeof(double));
    if (w) sc->w = w;
    double *n = realloc(sc->n, 3 * (size_t)cap * sizeof(double));
    if (n) sc->n = n;
    double *d0 = realloc(sc->d0, (size_t)cap * sizeof(double));
    if (d0) sc->d0 = d0;
    double *epsp = realloc(sc->epsp, (size_t)cap * sizeof(double));
    if (epsp) sc->epsp = epsp;
    if (!elem || !w || !n || !d0 || !epsp)
        return CR_FAIL(err, CR_ERR_MEMORY, "self-contact: out of memory for %lld pairs",
                       (long long)np);
    sc->cap = (int32_t)cap;
    return CR_OK;
}

/* The rest neighbour lists: the same passes at the rest positions. */
static cr_status rest_neighbours(cr_self_contact *sc, cr_error *err) {
    const int32_t nv = sc->nv, ne = sc->ne;
    sc->vt_rest_off32 = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    sc->ee_rest_off32 = cr_calloc((size_t)ne + 1, sizeof(int32_t), err);
    sc->vt_rest_off = cr_calloc((size_t)nv + 1, sizeof(int64_t), err);
    sc->ee_rest_off = cr_calloc((size_t)ne + 1, sizeof(int64_t), err);
    if (!sc->vt_rest_off32 || !sc->ee_rest_off32 || !sc->vt_rest_off || !sc->ee_rest_off)
        return err ? err->status : CR_ERR_MEMORY;
    int oom = 0;
    detect_ctx c = {sc, 0, 1, &oom};
    cr_parallel_for(nv, DETECT_GRAIN, vt_range, &c);
    cr_parallel_for(ne, DETECT_GRAIN, ee_range, &c);
    for (int32_t i = 0; i < nv; i++)
        sc->vt_rest_off[i + 1] = sc->vt_rest_off[i] + sc->vt_rest_off32[i];
    for (int32_t e = 0; e < ne; e++)
        sc->ee_rest_off[e + 1] = sc->ee_rest_off[e] + sc->ee_rest_off32[e];
    if (sc->vt_rest_off[nv] > INT32_MAX || sc->ee_rest_off[ne] > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "self-contact: too many rest neighbours");
    sc->vt_rest = cr_malloc(((size_t)sc->vt_rest_off[nv] + 1) * sizeof(int32_t), err);
    sc->ee_rest = cr_malloc(((size_t)sc->ee_rest_off[ne] + 1) * sizeof(int32_t), err);
    sc->vt_rest_d = cr_malloc(((size_t)sc->vt_rest_off[nv] + 1) * sizeof(double), err);
    sc->ee_rest_d = cr_malloc(((size_t)sc->ee_rest_off[ne] + 1) * sizeof(double), err);
    if (!sc->vt_rest || !sc->ee_rest || !sc->vt_rest_d || !sc->ee_rest_d)
        return err ? err->status : CR_ERR_MEMORY;
    for (int32_t i = 0; i < nv; i++)
        sc->vt_rest_off32[i] = (int32_t)sc->vt_rest_off[i];
    for (int32_t e = 0; e < ne; e++)
        sc->ee_rest_off32[e] = (int32_t)sc->ee_rest_off[e];
    c.fill = 1;
    cr_parallel_for(nv, DETECT_GRAIN, vt_range, &c);
    cr_parallel_for(ne, DETECT_GRAIN, ee_range, &c);
    return CR_OK;
}

cr_status cr_self_contact_detect(cr_self_contact *sc, const double *x, cr_error *err) {
    const int32_t nv = sc->nv;
    for (int64_t k = 0; k < 3 * (int64_t)nv; k++)
        sc->xf[k] = (float)x[k];
    CR_TRY(cr_bvh_refit(sc->bvh, sc->xf, err));
    sc->x = x;
    int oom = 0;
    detect_ctx c = {sc, 0, 0, &oom};
    cr_parallel_for(nv, DETECT_GRAIN, vt_range, &c);
    cr_parallel_for(sc->ne, DETECT_GRAIN, ee_range, &c);
    if (oom) return CR_FAIL(err, CR_ERR_MEMORY, "self-contact: out of memory");
    int64_t nvt = offsets(sc->cnt_v, nv, 0);
    int64_t np = offsets(sc->cnt_e, sc->ne, nvt);
    CR_TRY(grow_pairs(sc, np, err));
    c.fill = 1;
    cr_parallel_for(nv, DETECT_GRAIN, vt_range, &c);
    cr_parallel_for(sc->ne, DETECT_GRAIN, ee_range, &c);
    sc->npair = (int32_t)np, sc->nvt = (int32_t)nvt;
    sc->x = NULL;
    if (oom) return CR_FAIL(err, CR_ERR_MEMORY, "self-contact: out of memory");
    /* Per vertex: the nearest pair, the detection positions, the pairs. */
    memcpy(sc->xdet, x, 3 * (size_t)nv * sizeof(double));
    memset(sc->vp_off, 0, ((size_t)nv + 1) * sizeof(int64_t));
    for (int32_t i = 0; i < nv; i++)
        sc->dmin[i] = sc->r;
    for (int64_t p = 0; p < np; p++)
        for (int a = 0; a < 4; a++) {
            int32_t i = sc->elem[4 * p + a];
            sc->vp_off[i + 1]++;
            if (sc->d0[p] < sc->dmin[i]) sc->dmin[i] = sc->d0[p];
        }
    for (int32_t i = 0; i < nv; i++)
        sc->vp_off[i + 1] += sc->vp_off[i];
    if (4 * np > sc->vp_cap) {
        int64_t cap = 4 * np + 2 * np + 64;
        int32_t *vp = realloc(sc->vp, (size_t)cap * sizeof(int32_t));
        if (!vp)
            return CR_FAIL(err, CR_ERR_MEMORY, "self-contact: out of memory for %lld pairs",
                           (long long)np);
        sc->vp = vp, sc->vp_cap = cap;
    }
    for (int64_t p = 0; p < np; p++)
        for (int a = 0; a < 4; a++) {
            int32_t i = sc->elem[4 * p + a];
            sc->vp[sc->vp_off[i]++] = (int32_t)(4 * p + a);
        }
    for (int32_t i = nv; i > 0; i--)
        sc->vp_off[i] = sc->vp_off[i - 1];
    sc->vp_off[0] = 0;
    return CR_OK;
}

/* --------------------------------------------------------------- kernel -- */

static double pair_d(const cr_self_contact *sc, int32_t e, const double *xe) {
    const double *n = sc->n + 3 * (int64_t)e, *w = sc->w + 4 * (int64_t)e;
    double d = 0.0;
    for (int a = 0; a < 4; a++)
        d += w[a] * (n[0] * xe[3 * a] + n[1] * xe[3 * a + 1] + n[2] * xe[3 * a + 2]);
    return d;
}

/* Below this share of a pair's thickness the barrier continues as its
 * second-order Taylor expansion there (finite for any d, crossed pairs
 * included). 0.05: 734 N at contact for eps = 4 mm, 150 N for a rest
 * neighbour's 1.8 mm (above the 38 N of membrane that beat the cubic's
 * 10 N); at 0.01 (3347 N) the barrier held sleeves pressed between a walking
 * body's arm and torso so firmly that the body went 5.25 cm into them and a
 * t-shirt's walk clip failed at frame 27. */
#define BARRIER_FLOOR 0.05

/* The pair energy as a function of d, with its first two derivatives:
 * IPC's log barrier b(d) = -kappa (d - eps)^2 ln(d / eps) for d < eps
 * (Li et al. 2020), kappa = k eps, which is k (eps - d)^3 to leading order at
 * the threshold (the body collision's cubic and stiffness) but grows without
 * bound as d -> 0: the cubic's force at contact is only 3 k eps^2 (10 N for a
 * rest neighbour's 1.8 mm), which membrane forces beat (38 N measured on the
 * 2.5k tall strip), and VBD's step bound then lets the pair close to 1e-12 m,
 * where its vertices can no longer move. Below BARRIER_FLOOR eps the
 * expansion at that point takes over (C^2, convex). */
static double pair_energy(double k, double eps, double d, double *d1, double *d2) {
    *d1 = *d2 = 0.0;
    if (!(d < eps)) return 0.0;
    const double kappa = k * eps, f = BARRIER_FLOOR * eps;
    const double z = d > f ? d : f, u = z - eps, l = log(z / eps);
    double b = -kappa * u * u * l;
    double b1 = -kappa * (2.0 * u * l + u * u / z);
    double b2 = -kappa * (2.0 * l + 4.0 * u / z - u * u / (z * z));
    if (d > f) {
        *d1 = b1, *d2 = b2;
        return b;
    }
    const double t = d - f;
    *d1 = b1 + b2 * t, *d2 = b2;
    return b + b1 * t + 0.5 * b2 * t * t;
}

/* Gradient (3) and Hessian (9) along n of the pair energy at d. */
static double self_penalty(const cr_self_contact *sc, int32_t e, double d, const double *n,
                           double *g3, double *H3) {
    double d1, d2, v = pair_energy(sc->k, sc->epsp[e], d, &d1, &d2);
    for (int p = 0; p < 3; p++) {
        g3[p] = d1 * n[p];
        for (int q = 0; q < 3; q++)
            H3[3 * p + q] = d2 * n[p] * n[q];
    }
    return v;
}

static double self_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const cr_self_contact *sc = data;
    const double *n = sc->n + 3 * (int64_t)e, *w = sc->w + 4 * (int64_t)e;
    double g3[3], H3[9];
    double v = self_penalty(sc, e, pair_d(sc, e, xe), n, g3, H3);
    if (g)
        for (int a = 0; a < 4; a++)
            for (int k = 0; k < 3; k++)
                g[3 * a + k] = w[a] * g3[k];
    if (H)
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++)
                for (int p = 0; p < 3; p++)
                    for (int q = 0; q < 3; q++)
                        H[(3 * a + p) * 12 + 3 * b + q] = w[a] * w[b] * H3[3 * p + q];
    return v;
}

static double self_vertex_block(const void *data, int32_t e, int k, const double *xe, double *g,
                                double *H) {
    const cr_self_contact *sc = data;
    const double *n = sc->n + 3 * (int64_t)e, *w = sc->w + 4 * (int64_t)e;
    double g3[3], H3[9];
    double v = self_penalty(sc, e, pair_d(sc, e, xe), n, g3, H3);
    if (g)
        for (int j = 0; j < 3; j++)
            g[j] = w[k] * g3[j];
    if (H)
        for (int j = 0; j < 9; j++)
            H[j] = w[k] * w[k] * H3[j];
    return v;
}

void cr_self_contact_term(const cr_self_contact *sc, cr_energy_term *out) {
    CR_ASSERT(sc && out);
    memset(out, 0, sizeof *out);
    out->name = "self_contact";
    out->nelem = sc->npair;
    out->nvert = 4;
    out->elem = sc->elem;
    out->kernel = self_kernel;
    out->data = sc;
    out->weight = 1.0;
    out->vertex_block = self_vertex_block;
}

/* ------------------------------------------------------------ accessors -- */

int32_t cr_self_contact_pair_count(const cr_self_contact *sc, int32_t *vertex_triangle) {
    if (vertex_triangle) *vertex_triangle = sc->nvt;
    return sc->npair;
}

double cr_self_contact_radius(const cr_self_contact *sc) {
    return sc->r;
}

const double *cr_self_contact_nearest(const cr_self_contact *sc) {
    return sc->dmin;
}

const double *cr_self_contact_detected_at(const cr_self_contact *sc) {
    return sc->xdet;
}

void cr_self_contact_vertex_pairs(const cr_self_contact *sc, const int64_t **off,
                                  const int32_t **pairs) {
    *off = sc->vp_off;
    *pairs = sc->vp;
}
