/* cr_garment_remesh.c: isotropic remeshing of a panelled surface with its seams
 * and openings kept as feature lines.
 *
 * Botsch & Kobbelt 2004 ("A remeshing approach to multiresolution
 * modeling"), as in pmp-library: for a target edge length L, repeat
 *   1. split edges longer than 4/3 L at their midpoints,
 *   2. collapse edges shorter than 4/5 L (unless that makes an edge longer
 *      than 4/3 L, folds a face or breaks the link condition),
 *   3. flip edges where that brings the valences nearer 6 (4 on the
 *      boundary),
 *   4. move every vertex towards the area-weighted centroid of its faces
 *      within its tangent plane, then project it back onto the surface,
 * and finish with flips that raise the smaller angle of the two faces on
 * an edge (the Delaunay criterion on the surface) and more relaxation. The
 * surface is the zero level of the garment's field (cr_gfield_project).
 *
 * Features: an edge is a feature when it is a boundary or its two faces lie
 * in different panels; its key names the pair of panels. A vertex with two
 * feature edges of one key lies on that feature: it moves only along it
 * (towards the middle of its two feature neighbours) and is projected onto
 * the feature's polyline in the base mesh; it collapses only along its
 * feature. A vertex with any other number of feature edges, or two of
 * different keys, is a corner and never moves. Feature edges are never
 * flipped. So panels keep their outlines exactly and seams stay welded. A
 * face with two edges on one feature (an ear) would be flattened as the
 * feature straightens: its tip is collapsed along the feature.
 *
 * Guards against degenerate faces: an edge whose face is a cap over it (the
 * opposite corner close to the edge, between its ends) is not split, since
 * its midpoint would land on that corner; a split midpoint whose projection
 * folds a face stays on the chord (near a crease of the level set); a start
 * mesh much coarser than wanted is first subdivided 1-to-4 (cr_gcut_subdivide)
 * rather than split edge by edge. A sweep of splits is capped at eight per
 * face, so no configuration can split without end.
 *
 * The vertex count: with A the area and P the boundary length, a mesh of
 * equilateral triangles of edge L has about 2A/(sqrt(3) L^2) + P/(2L)
 * vertices; L is solved for from the target, then corrected twice by the
 * count the remesher actually reached.
 *
 * Data structure: a corner table. Half-edge h = 3f + k runs from corner k of
 * face f to corner k+1; twin[h] is the opposite half-edge (-1 on a
 * boundary). Dead faces have tri[3f] = -1 and are dropped at the end.
 *
 * Left out: curvature-adaptive edge lengths, and remeshing of non-manifold
 * input (the base mesh is checked manifold before it gets here).
 */
#include "base/vec3.h"
#include "garment_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    VK_INTERIOR = -1, /* vkey of a vertex on no feature */
    VK_CORNER = -2,   /* vkey of a vertex where features meet */
    NKEYS = (CR_GARMENT_MAX_PANELS + 1) * (CR_GARMENT_MAX_PANELS + 1),
    MAX_RING = 64 /* larger valences refuse the operation */
};

/* Largest angle between the faces on an edge that may be flipped, rad: past
 * it the flip would change the surface's shape. */
#define MAX_FLIP_DIHEDRAL 0.6f

typedef struct rm {
    int32_t nv, nf, cap_v, cap_f;
    float *pos;     /* (cap_v,3) m */
    int32_t *vhe;   /* (cap_v) an outgoing half-edge; -1 for a dead vertex */
    int32_t *vkey;  /* (cap_v) VK_INTERIOR, VK_CORNER or the feature's key */
    int32_t *tri;   /* (cap_f,3) tri[3f] < 0: dead */
    int32_t *twin;  /* (3 cap_f) */
    int32_t *panel; /* (cap_f) */
    const gfield *field;
    /* Feature polylines of the base mesh, grouped by key. */
    float *seg;       /* (S,6) segment end points */
    int32_t *key_off; /* (NKEYS+1) segments of key k: key_off[k] .. key_off[k+1] */
    float *scratch;   /* (cap_v,3) for relaxation */
} rm;

static inline int32_t nxt(int32_t h) {
    return h % 3 == 2 ? h - 2 : h + 1;
}

static inline int32_t prv(int32_t h) {
    return h % 3 == 0 ? h + 2 : h - 1;
}

static int32_t key_of(int32_t pa, int32_t pb) {
    int32_t lo = pa < pb ? pa : pb, hi = pa < pb ? pb : pa;
    return (lo + 1) * (CR_GARMENT_MAX_PANELS + 1) + (hi + 1);
}

/* Feature key of the edge of half-edge h, or -1 when it is not a feature. */
static int32_t edge_key(const rm *m, int32_t h) {
    int32_t t = m->twin[h], p = m->panel[h / 3];
    if (t < 0) return key_of(-1, p);
    return m->panel[t / 3] != p ? key_of(p, m->panel[t / 3]) : -1;
}

static float *P(const rm *m, int32_t v) {
    return &m->pos[3 * (size_t)v];
}

static void tri_normal(const float *a, const float *b, const float *c, float n[3]) {
    float u[3], v[3];
    sub3f(b, a, u), sub3f(c, a, v);
    cross3f(u, v, n);
}

/* Smallest angle of triangle (a, b, c), via the cosines (monotone). Returns
 * the largest cosine, so a smaller value is a better triangle. */
static float max_cos(const float *a, const float *b, const float *c) {
    const float *p[3] = {a, b, c};
    float worst = -1.0f;
    for (int k = 0; k < 3; k++) {
        const float *o = p[k], *x = p[(k + 1) % 3], *y = p[(k + 2) % 3];
        float u[3] = {x[0] - o[0], x[1] - o[1], x[2] - o[2]};
        float v[3] = {y[0] - o[0], y[1] - o[1], y[2] - o[2]};
        float d = sqrtf(dot3f(u, u) * dot3f(v, v));
        float cs = d > 0.0f ? dot3f(u, v) / d : 1.0f;
        if (cs > worst) worst = cs;
    }
    return worst;
}

/* Outgoing half-edges of v counter-clockwise, starting at the boundary when
 * v lies on one. Returns the count, or -1 when there are more than MAX_RING. */
static int ring(const rm *m, int32_t v, int32_t *he, int *boundary) {
    int32_t h = m->vhe[v], start = h;
    for (int guard = 0; m->twin[h] >= 0; guard++) {
        int32_t c = nxt(m->twin[h]);
        if (c == start || guard > MAX_RING) break;
        h = c;
    }
    *boundary = m->twin[h] < 0;
    if (!*boundary) h = start;
    int n = 0;
    int32_t first = h;
    do {
        if (n >= MAX_RING) return -1;
        he[n++] = h;
        h = m->twin[prv(h)];
    } while (h >= 0 && h != first);
    return n;
}

/* Neighbours of v (in ring order) and, for each, the key of the edge to it. */
static int neighbours(const rm *m, int32_t v, int32_t *nb, int32_t *key, int *boundary) {
    int32_t he[MAX_RING];
    int n = ring(m, v, he, boundary);
    if (n < 0 || n + 1 > MAX_RING) return -1;
    for (int i = 0; i < n; i++) {
        nb[i] = m->tri[nxt(he[i])];
        if (key) key[i] = edge_key(m, he[i]);
    }
    if (*boundary) {
        int32_t last = prv(he[n - 1]);
        nb[n] = m->tri[last];
        if (key) key[n] = edge_key(m, last);
        n++;
    }
    return n;
}

static void update_vkey(rm *m, int32_t v) {
    int32_t nb[MAX_RING], key[MAX_RING];
    int boundary, n = neighbours(m, v, nb, key, &boundary);
    int32_t k0 = -1, count = 0, same = 1;
    for (int i = 0; i < n; i++) {
        if (key[i] < 0) continue;
        if (count == 0)
            k0 = key[i];
        else
            same &= key[i] == k0;
        count++;
    }
    if (n < 0)
        m->vkey[v] = VK_CORNER;
    else if (count == 0)
        m->vkey[v] = VK_INTERIOR;
    else
        m->vkey[v] = count == 2 && same ? k0 : VK_CORNER;
}

/* ------------------------------------------------------------ set-up -- */

static void rm_free(rm *m) {
    free(m->pos), free(m->vhe), free(m->vkey);
    free(m->tri), free(m->twin), free(m->panel);
    free(m->seg), free(m->key_off), free(m->scratch);
    memset(m, 0, sizeof *m);
}

static cr_status rm_reserve(rm *m, int32_t nv, int32_t nf, cr_error *err) {
    if (nv > m->cap_v) {
        int32_t cap = nv + nv / 2 + 64;
        float *p = realloc(m->pos, (size_t)cap * 3 * sizeof(float));
        if (p) m->pos = p;
        int32_t *a = realloc(m->vhe, (size_t)cap * sizeof(int32_t));
        if (a) m->vhe = a;
        int32_t *b = realloc(m->vkey, (size_t)cap * sizeof(int32_t));
        if (b) m->vkey = b;
        float *s = realloc(m->scratch, (size_t)cap * 3 * sizeof(float));
        if (s) m->scratch = s;
        if (!p || !a || !b || !s)
            return CR_FAIL(err, CR_ERR_MEMORY, "garment remesh: out of memory");
        m->cap_v = cap;
    }
    if (nf > m->cap_f) {
        int32_t cap = nf + nf / 2 + 64;
        int32_t *t = realloc(m->tri, (size_t)cap * 3 * sizeof(int32_t));
        if (t) m->tri = t;
        int32_t *w = realloc(m->twin, (size_t)cap * 3 * sizeof(int32_t));
        if (w) m->twin = w;
        int32_t *q = realloc(m->panel, (size_t)cap * sizeof(int32_t));
        if (q) m->panel = q;
        if (!t || !w || !q) return CR_FAIL(err, CR_ERR_MEMORY, "garment remesh: out of memory");
        m->cap_f = cap;
    }
    return CR_OK;
}

static int cmp_i64x2(const void *pa, const void *pb) {
    const int64_t *a = pa, *b = pb;
    return (a[0] > b[0]) - (a[0] < b[0]);
}

/* Connectivity of `mesh` (manifold, consistently oriented) into m. */
static cr_status rm_build(rm *m, const gfield *field, const cr_mesh *mesh, const int32_t *panel,
                          cr_error *err) {
    memset(m, 0, sizeof *m);
    m->field = field;
    CR_TRY(rm_reserve(m, mesh->nv, mesh->nf, err));
    m->nv = mesh->nv, m->nf = mesh->nf;
    memcpy(m->pos, mesh->pos, (size_t)mesh->nv * 3 * sizeof(float));
    memcpy(m->tri, mesh->tri, (size_t)mesh->nf * 3 * sizeof(int32_t));
    memcpy(m->panel, panel, (size_t)mesh->nf * sizeof(int32_t));
    /* Twins: half-edges sorted by undirected edge; pairs are twins. */
    const int64_t nh = 3 * (int64_t)mesh->nf;
    int64_t *he = cr_malloc((size_t)nh * 2 * sizeof(int64_t), err);
    if (!he) return CR_ERR_MEMORY;
    for (int64_t h = 0; h < nh; h++) {
        int32_t a = m->tri[h], b = m->tri[nxt((int32_t)h)];
        int32_t lo = a < b ? a : b, hi = a < b ? b : a;
        he[2 * h] = ((int64_t)lo << 32) | (uint32_t)hi;
        he[2 * h + 1] = h;
        m->twin[h] = -1;
    }
    qsort(he, (size_t)nh, 2 * sizeof(int64_t), cmp_i64x2);
    for (int64_t i = 0; i + 1 < nh; i++)
        if (he[2 * i] == he[2 * (i + 1)]) {
            int32_t a = (int32_t)he[2 * i + 1], b = (int32_t)he[2 * (i + 1) + 1];
            m->twin[a] = b, m->twin[b] = a;
            i++;
        }
    free(he);
    for (int32_t v = 0; v < m->nv; v++)
        m->vhe[v] = -1;
    for (int32_t h = 0; h < (int32_t)nh; h++)
        m->vhe[m->tri[h]] = h;
    for (int32_t v = 0; v < m->nv; v++)
        update_vkey(m, v);
    return CR_OK;
}

/* The feature polylines of f (each feature edge once, from its lower
 * half-edge), handed to m. */
static cr_status take_features(rm *m, rm *f, cr_error *err) {
    const int32_t nh = 3 * f->nf;
    m->key_off = cr_calloc(NKEYS + 1, sizeof(int32_t), err);
    if (!m->key_off) return CR_ERR_MEMORY;
    int32_t ns = 0;
    for (int32_t h = 0; h < nh; h++) {
        int32_t k = edge_key(f, h);
        if (k >= 0 && (f->twin[h] < 0 || h < f->twin[h])) m->key_off[k + 1]++, ns++;
    }
    for (int k = 0; k < NKEYS; k++)
        m->key_off[k + 1] += m->key_off[k];
    m->seg = cr_malloc((size_t)(ns > 0 ? ns : 1) * 6 * sizeof(float), err);
    int32_t *fill = cr_calloc(NKEYS, sizeof(int32_t), err);
    if (!m->seg || !fill) {
        free(fill);
        return CR_ERR_MEMORY;
    }
    for (int32_t h = 0; h < nh; h++) {
        int32_t k = edge_key(f, h);
        if (k < 0 || !(f->twin[h] < 0 || h < f->twin[h])) continue;
        float *sg = &m->seg[6 * (size_t)(m->key_off[k] + fill[k]++)];
        memcpy(sg, P(f, f->tri[h]), 3 * sizeof(float));
        memcpy(sg + 3, P(f, f->tri[nxt(h)]), 3 * sizeof(float));
    }
    free(fill);
    return CR_OK;
}

/* Closest point to p on the base mesh's polyline of feature `key`. */
static void project_feature(const rm *m, int32_t key, float p[3]) {
    float best = INFINITY, q[3] = {p[0], p[1], p[2]};
    for (int32_t s = m->key_off[key]; s < m->key_off[key + 1]; s++) {
        const float *a = &m->seg[6 * (size_t)s], *b = a + 3;
        float ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
        float l2 = dot3f(ab, ab), t = l2 > 0.0f ? dot3f(ap, ab) / l2 : 0.0f;
        t = t < 0.0f ? 0.0f : t > 1.0f ? 1.0f : t;
        float c[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
        float d = dist2f(c, p);
        if (d < best) best = d, memcpy(q, c, sizeof q);
    }
    memcpy(p, q, sizeof q);
}

static void project_vertex(const rm *m, int32_t v) {
    if (m->vkey[v] >= 0)
        project_feature(m, m->vkey[v], P(m, v));
    else if (m->vkey[v] == VK_INTERIOR)
        cr_gfield_project(m->field, P(m, v));
}

/* ---------------------------------------------------------- operations -- */

static void set_twin(rm *m, int32_t a, int32_t b) {
    if (a >= 0) m->twin[a] = b;
    if (b >= 0) m->twin[b] = a;
}

/* Split the edge of half-edge h at its midpoint (projected onto the surface
 * or the feature). */
static cr_status split_edge(rm *m, int32_t h, cr_error *err) {
    CR_TRY(rm_reserve(m, m->nv + 1, m->nf + 2, err));
    const int32_t g = m->twin[h], key = edge_key(m, h);
    const int32_t a = m->tri[h], b = m->tri[nxt(h)], c = m->tri[prv(h)];
    const int32_t mid = m->nv++;
    for (int d = 0; d < 3; d++)
        P(m, mid)[d] = 0.5f * (P(m, a)[d] + P(m, b)[d]);
    m->vkey[mid] = key >= 0 ? key : VK_INTERIOR;
    /* f = (a, b, c) becomes (a, mid, c); f2 = (mid, b, c). */
    const int32_t f2 = m->nf++, t_bc = m->twin[nxt(h)];
    m->tri[nxt(h)] = mid;
    m->tri[3 * f2] = mid, m->tri[3 * f2 + 1] = b, m->tri[3 * f2 + 2] = c;
    m->panel[f2] = m->panel[h / 3];
    set_twin(m, 3 * f2 + 1, t_bc);
    set_twin(m, nxt(h), 3 * f2 + 2);
    if (m->vhe[b] == nxt(h)) m->vhe[b] = 3 * f2 + 1;
    m->vhe[mid] = 3 * f2;
    if (g >= 0) {
        /* g = (b, a, d) becomes (b, mid, d); g2 = (mid, a, d). */
        const int32_t d = m->tri[prv(g)], g2 = m->nf++, t_ad = m->twin[nxt(g)];
        m->tri[nxt(g)] = mid;
        m->tri[3 * g2] = mid, m->tri[3 * g2 + 1] = a, m->tri[3 * g2 + 2] = d;
        m->panel[g2] = m->panel[g / 3];
        set_twin(m, 3 * g2 + 1, t_ad);
        set_twin(m, nxt(g), 3 * g2 + 2);
        set_twin(m, h, 3 * g2);
        set_twin(m, g, 3 * f2);
        if (m->vhe[a] == nxt(g)) m->vhe[a] = 3 * g2 + 1;
    } else {
        m->twin[3 * f2] = -1;
    }
    /* Near a crease of the level set (a concave fillet) projection can pull
     * the midpoint onto a neighbour or across a face; then it stays on the
     * chord, which folds nothing. */
    float chord[3];
    memcpy(chord, P(m, mid), sizeof chord);
    project_vertex(m, mid);
    const int32_t faces[4] = {h / 3, f2, g >= 0 ? g / 3 : -1, g >= 0 ? m->nf - 1 : -1};
    for (int i = 0; i < 4; i++) {
        if (faces[i] < 0) continue;
        const int32_t *t = &m->tri[3 * faces[i]];
        float n0[3], n1[3];
        float *q[3] = {P(m, t[0]), P(m, t[1]), P(m, t[2])};
        tri_normal(q[0], q[1], q[2], n1);
        int k = t[0] == mid ? 0 : t[1] == mid ? 1 : 2;
        float keep[3];
        memcpy(keep, q[k], sizeof keep);
        memcpy(q[k], chord, sizeof chord);
        tri_normal(q[0], q[1], q[2], n0);
        memcpy(q[k], keep, sizeof keep);
        if (!(dot3f(n0, n1) > 0.5f * sqrtf(dot3f(n0, n0) * dot3f(n1, n1)))) {
            memcpy(P(m, mid), chord, sizeof chord);
            break;
        }
    }
    return CR_OK;
}

/* Point vhe[x] at an outgoing half-edge of x among the candidates. */
static void fix_vhe(rm *m, int32_t x, const int32_t *cand, int n) {
    for (int i = 0; i < n; i++) {
        int32_t e = cand[i];
        if (e >= 0 && m->tri[3 * (e / 3)] >= 0 && m->tri[e] == x) {
            m->vhe[x] = e;
            return;
        }
    }
    CR_ASSERT(!"collapse left a vertex without an outgoing half-edge");
}

static int contains(const int32_t *a, int n, int32_t x) {
    for (int i = 0; i < n; i++)
        if (a[i] == x) return 1;
    return 0;
}

/* Collapse the edge of half-edge h (a -> b), removing a when remove_origin,
 * else b, into the other's position. Returns 1 when done, 0 when refused. */
static int collapse_edge(rm *m, int32_t h, int remove_origin, float hi) {
    const int32_t a = m->tri[h], b = m->tri[nxt(h)], g = m->twin[h];
    const int32_t r = remove_origin ? a : b, k = remove_origin ? b : a;
    const int32_t key = edge_key(m, h);
    if (m->vkey[r] == VK_CORNER) return 0;
    if (m->vkey[r] >= 0 && key != m->vkey[r]) return 0;
    /* An ear (two boundary edges) would leave its third vertex without faces. */
    if (m->twin[nxt(h)] < 0 && m->twin[prv(h)] < 0) return 0;
    if (g >= 0 && m->twin[nxt(g)] < 0 && m->twin[prv(g)] < 0) return 0;
    const int32_t c = m->tri[prv(h)], d = g >= 0 ? m->tri[prv(g)] : -1;
    /* Link condition: a and b share exactly the neighbours c and d. */
    int32_t na[MAX_RING], nb[MAX_RING];
    int ba, bb;
    int n_a = neighbours(m, a, na, NULL, &ba), n_b = neighbours(m, b, nb, NULL, &bb);
    if (n_a < 0 || n_b < 0) return 0;
    int common = 0;
    for (int i = 0; i < n_a; i++)
        if (contains(nb, n_b, na[i])) {
            if (na[i] != c && na[i] != d) return 0;
            common++;
        }
    if (common != (g >= 0 ? 2 : 1)) return 0;
    /* Both ends on the boundary across an interior edge would pinch the mesh. */
    if (ba && bb && g >= 0) return 0;
    /* Geometry: r's other faces must not fold or grow an edge past hi. */
    int32_t he[MAX_RING];
    int br, nr = ring(m, r, he, &br);
    if (nr < 0) return 0;
    const float *pk = P(m, k);
    const int32_t fh = h / 3, fg = g >= 0 ? g / 3 : -1;
    for (int i = 0; i < nr; i++) {
        int32_t f = he[i] / 3;
        if (f == fh || f == fg) continue;
        const float *x = P(m, m->tri[nxt(he[i])]), *y = P(m, m->tri[prv(he[i])]);
        if (dist2f(pk, x) > hi * hi || dist2f(pk, y) > hi * hi) return 0;
        float n0[3], n1[3];
        tri_normal(P(m, r), x, y, n0);
        tri_normal(pk, x, y, n1);
        float l0 = sqrtf(dot3f(n0, n0)), l1 = sqrtf(dot3f(n1, n1));
        if (!(dot3f(n0, n1) > 0.5f * l0 * l1)) return 0;
    }
    /* Rename r to k in its surviving faces, glue the edges of the two dying
     * faces, kill them. */
    const int32_t t_bc = m->twin[nxt(h)], t_ca = m->twin[prv(h)];
    const int32_t t_ad = g >= 0 ? m->twin[nxt(g)] : -1, t_db = g >= 0 ? m->twin[prv(g)] : -1;
    for (int i = 0; i < nr; i++) {
        int32_t f = he[i] / 3;
        if (f != fh && f != fg) m->tri[he[i]] = k;
    }
    set_twin(m, t_bc, t_ca);
    if (g >= 0) set_twin(m, t_ad, t_db);
    for (int j = 0; j < 3; j++) {
        m->tri[3 * fh + j] = -1, m->twin[3 * fh + j] = -1;
        if (fg >= 0) m->tri[3 * fg + j] = -1, m->twin[3 * fg + j] = -1;
    }
    m->vhe[r] = -1;
    int32_t cand[8] = {t_bc, t_ca, t_ad, t_db, -1, -1, -1, -1};
    for (int i = 0; i < 4; i++)
        cand[4 + i] = cand[i] >= 0 ? nxt(cand[i]) : -1;
    fix_vhe(m, k, cand, 8);
    fix_vhe(m, c, cand, 8);
    if (d >= 0) fix_vhe(m, d, cand, 8);
    update_vkey(m, k);
    update_vkey(m, c);
    if (d >= 0) update_vkey(m, d);
    return 1;
}

enum { FLIP_VALENCE, FLIP_ANGLE };

static int valence_target(int boundary) {
    return boundary ? 4 : 6;
}

/* Flip the edge of half-edge h when mode's criterion improves. val (V) and
 * bnd (V) are the vertices' neighbour counts and boundary flags, kept up to
 * date here. */
static int flip_edge(rm *m, int32_t h, int mode, int32_t *val, const uint8_t *bnd) {
    const int32_t g = m->twin[h];
    if (g < 0 || edge_key(m, h) >= 0) return 0;
    const int32_t a = m->tri[h], b = m->tri[nxt(h)], c = m->tri[prv(h)], d = m->tri[prv(g)];
    if (c == d) return 0;
    /* a and b lose a face: interior ones keep at least three, boundary one. */
    if (val[a] <= (bnd[a] ? 2 : 3) || val[b] <= (bnd[b] ? 2 : 3)) return 0;
    if (mode == FLIP_VALENCE) {
        const int32_t q[4] = {a, b, c, d};
        int before = 0, after = 0;
        for (int i = 0; i < 4; i++) {
            int t = valence_target(bnd[q[i]]), dv = i < 2 ? -1 : 1;
            before += (val[q[i]] - t) * (val[q[i]] - t);
            after += (val[q[i]] + dv - t) * (val[q[i]] + dv - t);
        }
        if (after >= before) return 0;
    }
    const float *pa = P(m, a), *pb = P(m, b), *pc = P(m, c), *pd = P(m, d);
    float nf[3], ng[3], n1[3], n2[3];
    tri_normal(pa, pb, pc, nf);
    tri_normal(pb, pa, pd, ng);
    float lf = sqrtf(dot3f(nf, nf)), lg = sqrtf(dot3f(ng, ng));
    if (!(lf > 0.0f && lg > 0.0f) || dot3f(nf, ng) < cosf(MAX_FLIP_DIHEDRAL) * lf * lg) return 0;
    float avg[3] = {nf[0] / lf + ng[0] / lg, nf[1] / lf + ng[1] / lg, nf[2] / lf + ng[2] / lg};
    tri_normal(pa, pd, pc, n1);
    tri_normal(pd, pb, pc, n2);
    float l1 = sqrtf(dot3f(n1, n1)), l2 = sqrtf(dot3f(n2, n2));
    if (!(dot3f(n1, avg) > 0.5f * l1 && dot3f(n2, avg) > 0.5f * l2)) return 0;
    if (mode == FLIP_ANGLE) {
        float old_c = fmaxf(max_cos(pa, pb, pc), max_cos(pb, pa, pd));
        float new_c = fmaxf(max_cos(pa, pd, pc), max_cos(pd, pb, pc));
        if (!(new_c < old_c - 1e-4f)) return 0;
    }
    /* The new edge c-d must not exist already. */
    int32_t nbuf[MAX_RING];
    int bc, nc = neighbours(m, c, nbuf, NULL, &bc);
    if (nc < 0 || contains(nbuf, nc, d)) return 0;
    const int32_t f = h / 3, e = g / 3;
    const int32_t t_ad = m->twin[nxt(g)], t_db = m->twin[prv(g)];
    const int32_t t_bc = m->twin[nxt(h)], t_ca = m->twin[prv(h)];
    m->tri[3 * f] = a, m->tri[3 * f + 1] = d, m->tri[3 * f + 2] = c;
    m->tri[3 * e] = d, m->tri[3 * e + 1] = b, m->tri[3 * e + 2] = c;
    set_twin(m, 3 * f, t_ad);
    set_twin(m, 3 * f + 2, t_ca);
    set_twin(m, 3 * e, t_db);
    set_twin(m, 3 * e + 1, t_bc);
    set_twin(m, 3 * f + 1, 3 * e + 2);
    m->vhe[a] = 3 * f, m->vhe[b] = 3 * e + 1, m->vhe[c] = 3 * f + 2, m->vhe[d] = 3 * e;
    val[a]--, val[b]--, val[c]++, val[d]++;
    return 1;
}

/* ---------------------------------------------------------------- passes -- */

static float edge_len2(const rm *m, int32_t h) {
    return dist2f(P(m, m->tri[h]), P(m, m->tri[nxt(h)]));
}

/* Whether the face of half-edge h is a cap over its edge: the opposite
 * corner within a fifth of the edge's length of it, between its ends.
 * Splitting such an edge puts the midpoint onto that corner. */
static int is_cap(const rm *m, int32_t h) {
    const float *a = P(m, m->tri[h]), *b = P(m, m->tri[nxt(h)]), *c = P(m, m->tri[prv(h)]);
    float ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
          ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    float l2 = dot3f(ab, ab), t = dot3f(ac, ab) / l2, n[3];
    tri_normal(a, b, c, n);
    return t > 0.0f && t < 1.0f && dot3f(n, n) < 0.04f * l2 * l2;
}

static cr_status split_pass(rm *m, float hi, cr_error *err) {
    /* Each split halves an edge, so a pass needs a few splits per face; a
     * cap keeps a degenerate configuration from splitting without end. */
    int64_t live = 0;
    for (int32_t f = 0; f < m->nf; f++)
        live += m->tri[3 * f] >= 0;
    const int64_t cap = 8 * live + 1024;
    int64_t total = 0;
    for (int round = 0; round < 8 && total < cap; round++) {
        int64_t done = 0;
        /* Faces appended by splits are visited in the same sweep. */
        for (int32_t h = 0; h < 3 * m->nf && total < cap; h++) {
            if (m->tri[3 * (h / 3)] < 0 || edge_len2(m, h) <= hi * hi) continue;
            if (is_cap(m, h) || (m->twin[h] >= 0 && is_cap(m, m->twin[h]))) continue;
            CR_TRY(split_edge(m, h, err));
            done++, total++;
        }
        if (done == 0) break;
    }
    return CR_OK;
}

static int rank_of(const rm *m, int32_t v) {
    return m->vkey[v] == VK_INTERIOR ? 0 : m->vkey[v] == VK_CORNER ? 2 : 1;
}

static void collapse_pass(rm *m, float lo, float hi) {
    for (int32_t h = 0; h < 3 * m->nf; h++) {
        if (m->tri[3 * (h / 3)] < 0 || edge_len2(m, h) >= lo * lo) continue;
        int ra = rank_of(m, m->tri[h]), rb = rank_of(m, m->tri[nxt(h)]);
        if (ra <= rb && collapse_edge(m, h, 1, hi)) continue;
        if (rb <= ra) collapse_edge(m, h, 0, hi);
    }
}

/* An ear: a face with two edges on one feature, meeting at a vertex that is
 * not a corner. Relaxation straightens the feature through that vertex and
 * flattens the face, so the vertex is collapsed along the feature into one
 * of its two feature neighbours (removing the ear). Returns the ears fixed. */
static int64_t fix_ears(rm *m) {
    int64_t fixed = 0;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3 && m->tri[3 * f] >= 0; k++) {
            int32_t h1 = 3 * f + k, h0 = prv(h1), v = m->tri[h1], key = edge_key(m, h1);
            if (key < 0 || key != edge_key(m, h0) || m->vkey[v] != key) continue;
            if (collapse_edge(m, h1, 1, INFINITY) || collapse_edge(m, h0, 0, INFINITY)) fixed++;
            break;
        }
    return fixed;
}

static cr_status flip_pass(rm *m, int mode, cr_error *err) {
    int32_t *val = cr_calloc((size_t)m->nv, sizeof(int32_t), err);
    uint8_t *bnd = cr_calloc((size_t)m->nv, 1, err);
    if (!val || !bnd) {
        free(val);
        free(bnd);
        return CR_ERR_MEMORY;
    }
    /* Neighbours = faces around a vertex, plus one on the boundary. */
    for (int32_t h = 0; h < 3 * m->nf; h++) {
        if (m->tri[3 * (h / 3)] < 0) continue;
        val[m->tri[h]]++;
        if (m->twin[h] < 0) bnd[m->tri[h]] = 1;
    }
    for (int32_t v = 0; v < m->nv; v++)
        val[v] += bnd[v];
    for (int32_t h = 0; h < 3 * m->nf; h++)
        if (m->tri[3 * (h / 3)] >= 0 && m->twin[h] > h) flip_edge(m, h, mode, val, bnd);
    free(val);
    free(bnd);
    return CR_OK;
}

typedef struct relax_ctx {
    rm *m;
    float lambda;
} relax_ctx;

/* New position of v into scratch: tangential step towards the area-weighted
 * centroid of its faces (interior), along the feature (feature vertices). */
static void relax_range(void *vctx, int64_t begin, int64_t end) {
    const relax_ctx *c = vctx;
    rm *m = c->m;
    for (int64_t v = begin; v < end; v++) {
        float *out = &m->scratch[3 * v];
        memcpy(out, P(m, (int32_t)v), 3 * sizeof(float));
        if (m->vhe[v] < 0 || m->vkey[v] == VK_CORNER) continue;
        const float *p = P(m, (int32_t)v);
        int32_t nb[MAX_RING], key[MAX_RING], he[MAX_RING];
        int boundary;
        float q[3] = {0, 0, 0};
        if (m->vkey[v] >= 0) {
            int n = neighbours(m, (int32_t)v, nb, key, &boundary), found = 0;
            for (int i = 0; i < n; i++)
                if (key[i] == m->vkey[v]) {
                    for (int d = 0; d < 3; d++)
                        q[d] += 0.5f * P(m, nb[i])[d];
                    found++;
                }
            if (found != 2) continue;
            for (int d = 0; d < 3; d++)
                out[d] = p[d] + c->lambda * (q[d] - p[d]);
            project_feature(m, m->vkey[v], out);
            continue;
        }
        int n = ring(m, (int32_t)v, he, &boundary);
        if (n < 0) continue;
        double acc[3] = {0, 0, 0}, area = 0.0, nrm[3] = {0, 0, 0};
        for (int i = 0; i < n; i++) {
            const float *x = P(m, m->tri[nxt(he[i])]), *y = P(m, m->tri[prv(he[i])]);
            float fn[3];
            tri_normal(p, x, y, fn);
            double A = 0.5 * sqrt((double)dot3f(fn, fn));
            for (int d = 0; d < 3; d++) {
                acc[d] += A * (p[d] + x[d] + y[d]) / 3.0;
                nrm[d] += 0.5 * fn[d];
            }
            area += A;
        }
        double nl = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        if (!(area > 0.0) || !(nl > 0.0)) continue;
        double dlt[3], dn = 0.0;
        for (int d = 0; d < 3; d++) {
            dlt[d] = acc[d] / area - p[d];
            dn += dlt[d] * nrm[d] / nl;
        }
        for (int d = 0; d < 3; d++)
            out[d] = p[d] + c->lambda * (float)(dlt[d] - dn * nrm[d] / nl);
        cr_gfield_project(m->field, out);
    }
}

static void relax(rm *m, float lambda) {
    /* Serial: a round is too little work to pay for a parallel region's
     * barrier on a busy machine. */
    relax_ctx c = {m, lambda};
    relax_range(&c, 0, m->nv);
    memcpy(m->pos, m->scratch, (size_t)m->nv * 3 * sizeof(float));
}

static int32_t alive_vertices(const rm *m) {
    int32_t n = 0;
    for (int32_t v = 0; v < m->nv; v++)
        n += m->vhe[v] >= 0;
    return n;
}

static cr_status remesh_rounds(rm *m, float L, int32_t rounds, cr_error *err) {
    const float lo = 0.8f * L, hi = 4.0f / 3.0f * L;
    for (int32_t it = 0; it < rounds; it++) {
        CR_TRY(split_pass(m, hi, err));
        collapse_pass(m, lo, hi);
        fix_ears(m);
        CR_TRY(flip_pass(m, FLIP_VALENCE, err));
        relax(m, 1.0f);
    }
    return CR_OK;
}

static double mesh_area(const cr_mesh *m) {
    double area = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        float n[3];
        const int32_t *t = &m->tri[3 * f];
        tri_normal(&m->pos[3 * (size_t)t[0]], &m->pos[3 * (size_t)t[1]], &m->pos[3 * (size_t)t[2]],
                   n);
        area += 0.5 * sqrt((double)dot3f(n, n));
    }
    return area;
}

static float mean_edge(const cr_mesh *m) {
    double s = 0.0;
    for (int32_t h = 0; h < 3 * m->nf; h++)
        s += sqrt(
            (double)dist2f(&m->pos[3 * (size_t)m->tri[h]], &m->pos[3 * (size_t)m->tri[nxt(h)]]));
    return m->nf > 0 ? (float)(s / (3.0 * m->nf)) : 0.0f;
}

/* Edge length for `target` vertices on area A with boundary length P:
 * V = 2A / (sqrt(3) L^2) + P / (2L), solved for 1/L. */
static float edge_for(double A, double P, int32_t target) {
    double a = 2.0 * A / sqrt(3.0), b = 0.5 * P,
           x = (-b + sqrt(b * b + 4.0 * a * target)) / (2.0 * a);
    return (float)(1.0 / x);
}

cr_status cr_garment_remesh(const gfield *field, const cr_mesh *base, const int32_t *base_panel,
                            const cr_mesh *start, const int32_t *start_panel,
                            int32_t target_vertices, int32_t iterations, gremesh_out *out,
                            cr_error *err) {
    memset(out, 0, sizeof *out);
    rm m = {0}, b = {0};
    cr_status st = rm_build(&b, field, base, base_panel, err);
    if (st == CR_OK) st = take_features(&m, &b, err);
    rm_free(&b);
    /* From a start much coarser than wanted, subdivide it first (each
     * level halves the edges) until it is within 1.6 times the target. */
    cr_mesh *fine = NULL;
    int32_t *fine_panel = NULL;
    if (st == CR_OK && start) {
        const float want = edge_for(mesh_area(start), 0.0, target_vertices);
        for (float e = mean_edge(start); st == CR_OK && e > 1.6f * want; e *= 0.5f) {
            cr_mesh *next = NULL;
            int32_t *next_panel = NULL;
            st = cr_gcut_subdivide(fine ? fine : start, fine ? fine_panel : start_panel, &next,
                                   &next_panel, err);
            cr_mesh_destroy(fine);
            free(fine_panel);
            fine = next, fine_panel = next_panel;
        }
    }
    if (st == CR_OK) {
        /* rm_build clears m: keep the features across it. */
        float *seg = m.seg;
        int32_t *key_off = m.key_off;
        if (fine)
            st = rm_build(&m, field, fine, fine_panel, err);
        else
            st = rm_build(&m, field, start ? start : base, start ? start_panel : base_panel, err);
        m.seg = seg, m.key_off = key_off;
        for (int32_t v = 0; st == CR_OK && fine && v < m.nv; v++)
            project_vertex(&m, v);
    }
    cr_mesh_destroy(fine);
    free(fine_panel);
    double A = 0.0, Pb = 0.0;
    for (int32_t f = 0; st == CR_OK && f < m.nf; f++) {
        float n[3];
        tri_normal(P(&m, m.tri[3 * f]), P(&m, m.tri[3 * f + 1]), P(&m, m.tri[3 * f + 2]), n);
        A += 0.5 * sqrt((double)dot3f(n, n));
        for (int k = 0; k < 3; k++)
            if (m.twin[3 * f + k] < 0) Pb += sqrt((double)edge_len2(&m, 3 * f + k));
    }
    float L = edge_for(A, Pb, target_vertices);
    if (st == CR_OK) st = remesh_rounds(&m, L, iterations, err);
    /* Two corrections of L by the count reached (V ~ 1/L^2). */
    for (int pass = 0; pass < 2 && st == CR_OK; pass++) {
        double ratio = (double)alive_vertices(&m) / target_vertices;
        if (fabs(ratio - 1.0) < 0.06) break;
        L *= (float)sqrt(ratio);
        st = remesh_rounds(&m, L, iterations / 2 + 1, err);
    }
    for (int round = 0; round < 4 && st == CR_OK; round++) {
        st = flip_pass(&m, FLIP_ANGLE, err);
        relax(&m, 0.5f);
    }
    if (st == CR_OK) st = flip_pass(&m, FLIP_ANGLE, err);
    if (st == CR_OK) fix_ears(&m);
    /* Compact: live vertices in order, live faces in order. */
    int32_t *remap = st == CR_OK ? cr_malloc((size_t)m.nv * sizeof(int32_t), err) : NULL;
    if (st == CR_OK && !remap) st = CR_ERR_MEMORY;
    int32_t nv = 0, nf = 0;
    for (int32_t v = 0; st == CR_OK && v < m.nv; v++)
        remap[v] = m.vhe[v] >= 0 ? nv++ : -1;
    for (int32_t f = 0; st == CR_OK && f < m.nf; f++)
        nf += m.tri[3 * f] >= 0;
    if (st == CR_OK) st = cr_mesh_create(nv, nf, 0, &out->mesh, err);
    if (st == CR_OK) {
        out->panel = cr_malloc((size_t)nf * sizeof(int32_t), err);
        if (!out->panel) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) {
        for (int32_t v = 0; v < m.nv; v++)
            if (remap[v] >= 0)
                memcpy(&out->mesh->pos[3 * (size_t)remap[v]], P(&m, v), 3 * sizeof(float));
        int32_t j = 0;
        for (int32_t f = 0; f < m.nf; f++) {
            if (m.tri[3 * f] < 0) continue;
            for (int k = 0; k < 3; k++)
                out->mesh->tri[3 * j + k] = remap[m.tri[3 * f + k]];
            out->panel[j++] = m.panel[f];
        }
    }
    free(remap);
    rm_free(&m);
    if (st != CR_OK) {
        cr_mesh_destroy(out->mesh);
        free(out->panel);
        memset(out, 0, sizeof *out);
    }
    return st;
}
