/* garment_cut.c: cutting a triangle mesh along the zero levels of per-vertex
 * scalar fields, dropping one side, and keeping the largest piece.
 *
 * A garment's openings and seams are level sets on its surface: a plane for
 * the hem, a sphere for the neckline, the level 1/2 of the body's arm
 * weights for an armhole. Each is sampled at the vertices and interpolated
 * linearly along edges, so cutting splits every edge the field changes sign
 * along at its zero and splits each crossed face into a triangle and a quad
 * (two triangles, along the quad's shorter diagonal) or, where the level
 * passes through a vertex, into two triangles. Every field is interpolated
 * onto the new vertices, so later cuts see consistent values. Values within
 * eps of zero are snapped to zero first, so no sliver is thinner than that;
 * the remesher removes the short edges a cut leaves.
 *
 * Also here: 1-to-4 midpoint subdivision, which the remesher starts from when
 * the wanted edge is much shorter than its start mesh's (splitting long
 * edges one by one in arbitrary order cuts slivers first).
 *
 * Left out: cutting along curves that are not level sets of vertex fields.
 */
#include "base/vec3.h"
#include "garment_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void cr_gcut_free(gcutmesh *m) {
    free(m->pos);
    free(m->val);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

static cr_status grow(gcutmesh *m, int32_t nv, int32_t nf, cr_error *err) {
    if (nv > m->cap_v) {
        int32_t cap = nv + nv / 2 + 16;
        float *p = realloc(m->pos, (size_t)cap * 3 * sizeof(float));
        if (p) m->pos = p;
        float *v = realloc(m->val, (size_t)cap * (size_t)m->nfield * sizeof(float));
        if (v) m->val = v;
        if (!p || !v) return CR_FAIL(err, CR_ERR_MEMORY, "garment cut: out of memory");
        m->cap_v = cap;
    }
    if (nf > m->cap_f) {
        int32_t cap = nf + nf / 2 + 16;
        int32_t *t = realloc(m->tri, (size_t)cap * 3 * sizeof(int32_t));
        if (!t) return CR_FAIL(err, CR_ERR_MEMORY, "garment cut: out of memory");
        m->tri = t;
        m->cap_f = cap;
    }
    return CR_OK;
}

static int64_t edge_key(int32_t a, int32_t b) {
    int32_t lo = a < b ? a : b, hi = a < b ? b : a;
    return ((int64_t)lo << 32) | (uint32_t)hi;
}

static int cmp_i64(const void *pa, const void *pb) {
    int64_t a = *(const int64_t *)pa, b = *(const int64_t *)pb;
    return (a > b) - (a < b);
}

/* The corner after corner h (= 3f + k) of its face. */
static int64_t next_corner(int64_t h) {
    return h % 3 == 2 ? h - 2 : h + 1;
}

static int32_t find_key(const int64_t *keys, int32_t n, int64_t k) {
    int32_t lo = 0, hi = n - 1;
    while (lo <= hi) {
        int32_t mid = lo + (hi - lo) / 2;
        if (keys[mid] == k) return mid;
        if (keys[mid] < k)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

/* Triangulate the polygon poly (3 or 4 vertices, in order) into m as new
 * faces, the first one overwriting face `f`. */
static void emit_polygon(gcutmesh *m, int32_t f, const int32_t *poly, int n, int *first) {
    int32_t t[2][3];
    int nt = 1;
    if (n == 3) {
        memcpy(t[0], poly, sizeof t[0]);
    } else {
        const float *p[4];
        for (int i = 0; i < 4; i++)
            p[i] = &m->pos[3 * (size_t)poly[i]];
        nt = 2;
        if (dist2f(p[0], p[2]) <= dist2f(p[1], p[3])) {
            int32_t a[3] = {poly[0], poly[1], poly[2]}, b[3] = {poly[0], poly[2], poly[3]};
            memcpy(t[0], a, sizeof a), memcpy(t[1], b, sizeof b);
        } else {
            int32_t a[3] = {poly[1], poly[2], poly[3]}, b[3] = {poly[1], poly[3], poly[0]};
            memcpy(t[0], a, sizeof a), memcpy(t[1], b, sizeof b);
        }
    }
    for (int i = 0; i < nt; i++) {
        int32_t dst = *first ? f : m->nf++;
        *first = 0;
        memcpy(&m->tri[3 * (size_t)dst], t[i], sizeof t[i]);
    }
}

cr_status cr_gcut_split(gcutmesh *m, int32_t k, float eps, cr_error *err) {
    const int32_t K = m->nfield;
    for (int32_t v = 0; v < m->nv; v++)
        if (fabsf(m->val[(size_t)v * K + k]) < eps) m->val[(size_t)v * K + k] = 0.0f;
    /* Crossed edges, once each, sorted: the new vertex of edge i is nv + i. */
    int64_t *keys = cr_malloc((size_t)m->nf * 3 * sizeof(int64_t) + 8, err);
    if (!keys) return CR_ERR_MEMORY;
    int32_t nk = 0;
    for (int32_t f = 0; f < m->nf; f++)
        for (int c = 0; c < 3; c++) {
            int32_t a = m->tri[3 * f + c], b = m->tri[3 * f + (c + 1) % 3];
            float va = m->val[(size_t)a * K + k], vb = m->val[(size_t)b * K + k];
            if ((va < 0 && vb > 0) || (va > 0 && vb < 0)) keys[nk++] = edge_key(a, b);
        }
    qsort(keys, (size_t)nk, sizeof(int64_t), cmp_i64);
    int32_t nu = 0;
    for (int32_t i = 0; i < nk; i++)
        if (nu == 0 || keys[i] != keys[nu - 1]) keys[nu++] = keys[i];
    /* Each crossed face adds at most two faces. */
    cr_status st = grow(m, m->nv + nu, m->nf + 2 * nu, err);
    if (st != CR_OK) {
        free(keys);
        return st;
    }
    const int32_t nv0 = m->nv, nf0 = m->nf;
    for (int32_t i = 0; i < nu; i++) {
        int32_t a = (int32_t)(keys[i] >> 32), b = (int32_t)(keys[i] & 0xffffffff);
        double va = m->val[(size_t)a * K + k], vb = m->val[(size_t)b * K + k];
        float t = (float)(va / (va - vb)); /* in (0, 1): the signs differ */
        int32_t n = nv0 + i;
        for (int d = 0; d < 3; d++)
            m->pos[3 * (size_t)n + d] = m->pos[3 * (size_t)a + d] +
                                        t * (m->pos[3 * (size_t)b + d] - m->pos[3 * (size_t)a + d]);
        for (int j = 0; j < K; j++) {
            float fa = m->val[(size_t)a * K + j], fb = m->val[(size_t)b * K + j];
            m->val[(size_t)n * K + j] = fa + t * (fb - fa);
        }
        m->val[(size_t)n * K + k] = 0.0f;
    }
    m->nv = nv0 + nu;
    for (int32_t f = 0; f < nf0; f++) {
        int32_t pos[5], neg[5], np = 0, nn = 0, crossed = 0;
        for (int c = 0; c < 3; c++) {
            int32_t a = m->tri[3 * f + c], b = m->tri[3 * f + (c + 1) % 3];
            float va = m->val[(size_t)a * K + k], vb = m->val[(size_t)b * K + k];
            if (va >= 0) pos[np++] = a;
            if (va <= 0) neg[nn++] = a;
            if ((va < 0 && vb > 0) || (va > 0 && vb < 0)) {
                int32_t n = nv0 + find_key(keys, nu, edge_key(a, b));
                pos[np++] = n, neg[nn++] = n;
                crossed = 1;
            }
        }
        if (!crossed) continue;
        int first = 1;
        emit_polygon(m, f, pos, np, &first);
        emit_polygon(m, f, neg, nn, &first);
    }
    free(keys);
    return CR_OK;
}

int cr_gcut_face_sign(const gcutmesh *m, int32_t f, int32_t k) {
    double s = 0.0;
    for (int c = 0; c < 3; c++)
        s += m->val[(size_t)m->tri[3 * f + c] * m->nfield + k];
    return s < 0.0 ? -1 : 1;
}

void cr_gcut_remove_negative(gcutmesh *m, int32_t k) {
    int32_t n = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (cr_gcut_face_sign(m, f, k) > 0) {
            if (n != f) memcpy(&m->tri[3 * n], &m->tri[3 * f], 3 * sizeof(int32_t));
            n++;
        }
    m->nf = n;
}

static int32_t uf_find(int32_t *parent, int32_t x) {
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

cr_status cr_gcut_keep_largest(gcutmesh *m, cr_error *err) {
    const int32_t nf = m->nf, K = m->nfield;
    if (nf == 0) return CR_OK;
    /* Half-edges keyed by their undirected edge; faces sharing one join. */
    int64_t *he = cr_malloc((size_t)nf * 3 * sizeof(int64_t) * 2, err);
    int32_t *parent = cr_malloc((size_t)nf * sizeof(int32_t), err);
    double *area = cr_calloc((size_t)nf, sizeof(double), err);
    int32_t *remap = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    cr_status st = he && parent && area && remap ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        for (int32_t f = 0; f < nf; f++) {
            parent[f] = f;
            for (int c = 0; c < 3; c++) {
                he[2 * (3 * (size_t)f + c)] =
                    edge_key(m->tri[3 * f + c], m->tri[3 * f + (c + 1) % 3]);
                he[2 * (3 * (size_t)f + c) + 1] = f;
            }
        }
        qsort(he, (size_t)nf * 3, 2 * sizeof(int64_t), cmp_i64);
        for (size_t i = 1; i < (size_t)nf * 3; i++)
            if (he[2 * i] == he[2 * (i - 1)]) {
                int32_t a = uf_find(parent, (int32_t)he[2 * i + 1]);
                int32_t b = uf_find(parent, (int32_t)he[2 * (i - 1) + 1]);
                if (a != b) parent[a < b ? b : a] = a < b ? a : b;
            }
        for (int32_t f = 0; f < nf; f++) {
            const float *p0 = &m->pos[3 * (size_t)m->tri[3 * f]];
            const float *p1 = &m->pos[3 * (size_t)m->tri[3 * f + 1]];
            const float *p2 = &m->pos[3 * (size_t)m->tri[3 * f + 2]];
            double e1[3], e2[3];
            for (int d = 0; d < 3; d++)
                e1[d] = p1[d] - p0[d], e2[d] = p2[d] - p0[d];
            double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                   cz = e1[0] * e2[1] - e1[1] * e2[0];
            area[uf_find(parent, f)] += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        }
        int32_t best = 0;
        for (int32_t f = 1; f < nf; f++)
            if (area[f] > area[best]) best = f;
        int32_t n = 0;
        for (int32_t f = 0; f < nf; f++)
            if (uf_find(parent, f) == best) {
                if (n != f) memcpy(&m->tri[3 * n], &m->tri[3 * f], 3 * sizeof(int32_t));
                n++;
            }
        m->nf = n;
        for (int32_t v = 0; v < m->nv; v++)
            remap[v] = -1;
        for (int32_t i = 0; i < 3 * n; i++)
            remap[m->tri[i]] = 0;
        /* Used vertices keep their order, so each moves down or stays. */
        int32_t nv = 0;
        for (int32_t v = 0; v < m->nv; v++) {
            if (remap[v] < 0) continue;
            remap[v] = nv;
            if (nv != v) {
                memcpy(&m->pos[3 * (size_t)nv], &m->pos[3 * (size_t)v], 3 * sizeof(float));
                memcpy(&m->val[(size_t)nv * K], &m->val[(size_t)v * K], (size_t)K * sizeof(float));
            }
            nv++;
        }
        for (int32_t i = 0; i < 3 * n; i++)
            m->tri[i] = remap[m->tri[i]];
        m->nv = nv;
    }
    free(he);
    free(parent);
    free(area);
    free(remap);
    return st;
}

/* 1-to-4 midpoint subdivision of a mesh with panels: every edge gets its
 * midpoint (shared by the faces on it), every face four similar faces. */
cr_status cr_gcut_subdivide(const cr_mesh *in, const int32_t *panel, cr_mesh **out,
                            int32_t **out_panel, cr_error *err) {
    *out = NULL, *out_panel = NULL;
    const int64_t nh = 3 * (int64_t)in->nf;
    int64_t *key = cr_malloc((size_t)nh * 2 * sizeof(int64_t), err);
    int32_t *mid = cr_malloc((size_t)nh * sizeof(int32_t), err);
    cr_status st = key && mid ? CR_OK : CR_ERR_MEMORY;
    int32_t ne = 0;
    if (st == CR_OK) {
        for (int64_t h = 0; h < nh; h++) {
            key[2 * h] = edge_key(in->tri[h], in->tri[next_corner(h)]);
            key[2 * h + 1] = h;
        }
        qsort(key, (size_t)nh, 2 * sizeof(int64_t), cmp_i64);
        for (int64_t i = 0; i < nh; i++) {
            if (i > 0 && key[2 * i] != key[2 * (i - 1)]) ne++;
            mid[key[2 * i + 1]] = in->nv + ne;
        }
        ne++;
        st = cr_mesh_create(in->nv + ne, 4 * in->nf, 0, out, err);
    }
    if (st == CR_OK) {
        *out_panel = cr_malloc((size_t)in->nf * 4 * sizeof(int32_t), err);
        if (!*out_panel) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) {
        cr_mesh *o = *out;
        memcpy(o->pos, in->pos, (size_t)in->nv * 3 * sizeof(float));
        for (int64_t h = 0; h < nh; h++) {
            const float *a = &in->pos[3 * (size_t)in->tri[h]],
                        *b = &in->pos[3 * (size_t)in->tri[next_corner(h)]];
            for (int d = 0; d < 3; d++)
                o->pos[3 * (size_t)mid[h] + d] = 0.5f * (a[d] + b[d]);
        }
        for (int32_t f = 0; f < in->nf; f++) {
            const int32_t *t = &in->tri[3 * f];
            int32_t m0 = mid[3 * f], m1 = mid[3 * f + 1], m2 = mid[3 * f + 2];
            int32_t q[4][3] = {{t[0], m0, m2}, {m0, t[1], m1}, {m2, m1, t[2]}, {m0, m1, m2}};
            memcpy(&o->tri[12 * (size_t)f], q, sizeof q);
            for (int k = 0; k < 4; k++)
                (*out_panel)[4 * f + k] = panel[f];
        }
    }
    free(key);
    free(mid);
    if (st != CR_OK) {
        cr_mesh_destroy(*out);
        free(*out_panel);
        *out = NULL, *out_panel = NULL;
    }
    return st;
}
