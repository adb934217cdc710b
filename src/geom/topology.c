/* topology.c: edges, hinges, adjacency, boundary loops and manifold checks.
 *
 * Edges are found by sorting half-edges: each half-edge (3f+k, from corner k
 * to corner k+1) goes into the bucket of its smaller vertex (a counting sort,
 * O(F)), and each bucket is sorted by (larger vertex, half-edge id), O(d log d)
 * for valence d. Runs of equal keys are the unique edges, and because the
 * half-edge id breaks ties the result is deterministic.
 *
 * A vertex is manifold when the faces around it, linked through the edges at
 * that vertex that have exactly two faces, form one connected fan (a union-find
 * over the fan) and no edge at it has more than two faces: then its link is one
 * path (half-disk) or one cycle (disk).
 *
 * Left out: repairing anything (welding, reorienting, splitting non-manifold
 * vertices); the counts say what is wrong, the caller decides.
 * Reference: Botsch et al., "Polygon Mesh Processing" (2010), ch. 2.
 */
#include "crease/topology.h"

#include <stdlib.h>
#include <string.h>

/* One half-edge in the bucket of its smaller vertex. */
typedef struct half_rec {
    int32_t other; /* larger vertex */
    int32_t he;    /* half-edge id 3f+k */
} half_rec;

static int cmp_half(const void *pa, const void *pb) {
    const half_rec *a = pa, *b = pb;
    if (a->other != b->other) return a->other < b->other ? -1 : 1;
    return (a->he > b->he) - (a->he < b->he);
}

static int face_degenerate(const int32_t *t) {
    return t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
}

void cr_topology_destroy(cr_topology *t) {
    if (!t) return;
    free(t->edge);
    free(t->edge_face);
    free(t->face_edge);
    free(t->face_face);
    free(t->hinge);
    free(t->hinge_edge);
    free(t->hinge_face);
    free(t->vf_off);
    free(t->vf);
    free(t->vv_off);
    free(t->vv);
    free(t->vertex_boundary);
    free(t->loop_off);
    free(t->loop_vert);
    free(t);
}

static int32_t uf_find(int32_t *parent, int32_t i) {
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

/* Local index of face f in the ascending face list of one vertex, -1 if absent. */
static int32_t find_sorted(const int32_t *a, int32_t n, int32_t f) {
    int32_t lo = 0, hi = n - 1;
    while (lo <= hi) {
        int32_t mid = lo + (hi - lo) / 2;
        if (a[mid] == f) return mid;
        if (a[mid] < f)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

/* Sorted half-edges and the run structure that defines edges. */
typedef struct edge_build {
    half_rec *rec; /* (3F') half-edges of non-degenerate faces, bucketed */
    int64_t nrec;
    int32_t *bucket;  /* (V+1) offsets of each smaller-vertex bucket in rec */
    int32_t *edge_nf; /* (E) faces on each edge */
    int32_t *edge_he; /* (E) first half-edge of each edge */
} edge_build;

static cr_status sort_half_edges(const cr_mesh *m, edge_build *b, cr_error *err) {
    int32_t nv = m->nv;
    b->bucket = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    b->rec = cr_malloc(((size_t)m->nf * 3 + 1) * sizeof(half_rec), err);
    if (!b->bucket || !b->rec) return CR_ERR_MEMORY;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        if (face_degenerate(t)) continue;
        for (int k = 0; k < 3; k++) {
            int32_t a = t[k], c = t[(k + 1) % 3];
            b->bucket[(a < c ? a : c) + 1]++;
        }
    }
    for (int32_t v = 0; v < nv; v++)
        b->bucket[v + 1] += b->bucket[v];
    b->nrec = b->bucket[nv];
    int32_t *fill = cr_malloc((size_t)nv * sizeof(int32_t) + 1, err);
    if (!fill) return CR_ERR_MEMORY;
    memcpy(fill, b->bucket, (size_t)nv * sizeof(int32_t));
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        if (face_degenerate(t)) continue;
        for (int k = 0; k < 3; k++) {
            int32_t a = t[k], c = t[(k + 1) % 3];
            int32_t lo = a < c ? a : c, hi = a < c ? c : a;
            b->rec[fill[lo]++] = (half_rec){hi, 3 * f + k};
        }
    }
    free(fill);
    for (int32_t v = 0; v < nv; v++) {
        int32_t n = b->bucket[v + 1] - b->bucket[v];
        if (n > 1) qsort(&b->rec[b->bucket[v]], (size_t)n, sizeof(half_rec), cmp_half);
    }
    return CR_OK;
}

/* Walk the sorted half-edges: unique edges, edge/face incidence, defects on edges. */
static cr_status build_edges(const cr_mesh *m, cr_topology *t, edge_build *b, cr_error *err) {
    int32_t ne = 0, nh = 0;
    for (int32_t v = 0; v < m->nv; v++)
        for (int32_t i = b->bucket[v]; i < b->bucket[v + 1];) {
            int32_t j = i + 1;
            while (j < b->bucket[v + 1] && b->rec[j].other == b->rec[i].other)
                j++;
            ne++;
            nh += (j - i) == 2;
            i = j;
        }
    t->ne = ne, t->nh = nh;
    t->edge = cr_malloc((size_t)ne * 2 * sizeof(int32_t) + 1, err);
    t->edge_face = cr_malloc((size_t)ne * 2 * sizeof(int32_t) + 1, err);
    t->hinge = cr_malloc((size_t)nh * 4 * sizeof(int32_t) + 1, err);
    t->hinge_edge = cr_malloc((size_t)nh * sizeof(int32_t) + 1, err);
    t->hinge_face = cr_malloc((size_t)nh * 2 * sizeof(int32_t) + 1, err);
    b->edge_nf = cr_malloc((size_t)ne * sizeof(int32_t) + 1, err);
    b->edge_he = cr_malloc((size_t)ne * sizeof(int32_t) + 1, err);
    if (!t->edge || !t->edge_face || !t->hinge || !t->hinge_edge || !t->hinge_face || !b->edge_nf ||
        !b->edge_he)
        return CR_ERR_MEMORY;

    const int32_t *tri = m->tri;
    int32_t e = 0, h = 0;
    for (int32_t v = 0; v < m->nv; v++)
        for (int32_t i = b->bucket[v]; i < b->bucket[v + 1];) {
            int32_t j = i + 1;
            while (j < b->bucket[v + 1] && b->rec[j].other == b->rec[i].other)
                j++;
            int32_t c = j - i;
            int32_t ha = b->rec[i].he, fa = ha / 3, ka = ha % 3;
            t->edge[2 * e] = v, t->edge[2 * e + 1] = b->rec[i].other;
            t->edge_face[2 * e] = fa;
            t->edge_face[2 * e + 1] = c >= 2 ? b->rec[i + 1].he / 3 : -1;
            b->edge_nf[e] = c, b->edge_he[e] = ha;
            for (int32_t r = i; r < j; r++)
                t->face_edge[b->rec[r].he] = e;
            if (c > t->max_edge_faces) t->max_edge_faces = c;
            if (c == 1) {
                t->n_boundary_edges++;
            } else if (c > 2) {
                if (t->n_nonmanifold_edges++ == 0) t->first_nonmanifold_edge = e;
            } else {
                int32_t hb = b->rec[i + 1].he, fb = hb / 3, kb = hb % 3;
                t->face_face[ha] = fb, t->face_face[hb] = fa;
                /* Same start vertex in both faces = both run the edge the same way. */
                if (tri[ha] == tri[hb] && t->n_inconsistent_edges++ == 0)
                    t->first_inconsistent_edge = e;
                int32_t *x = &t->hinge[4 * h];
                x[0] = tri[3 * fa + ka];
                x[1] = tri[3 * fa + (ka + 1) % 3];
                x[2] = tri[3 * fa + (ka + 2) % 3];
                x[3] = tri[3 * fb + (kb + 2) % 3];
                t->hinge_edge[h] = e;
                t->hinge_face[2 * h] = fa, t->hinge_face[2 * h + 1] = fb;
                h++;
            }
            e++;
            i = j;
        }
    return CR_OK;
}

static cr_status build_vertex_adjacency(const cr_mesh *m, cr_topology *t, cr_error *err) {
    int32_t nv = m->nv;
    t->vf_off = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    t->vv_off = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    if (!t->vf_off || !t->vv_off) return CR_ERR_MEMORY;
    for (int32_t f = 0; f < m->nf; f++) {
        if (face_degenerate(&m->tri[3 * f])) continue;
        for (int k = 0; k < 3; k++)
            t->vf_off[m->tri[3 * f + k] + 1]++;
    }
    for (int32_t e = 0; e < t->ne; e++) {
        t->vv_off[t->edge[2 * e] + 1]++;
        t->vv_off[t->edge[2 * e + 1] + 1]++;
    }
    for (int32_t v = 0; v < nv; v++) {
        t->vf_off[v + 1] += t->vf_off[v];
        t->vv_off[v + 1] += t->vv_off[v];
    }
    t->vf = cr_malloc((size_t)t->vf_off[nv] * sizeof(int32_t) + 1, err);
    t->vv = cr_malloc((size_t)t->vv_off[nv] * sizeof(int32_t) + 1, err);
    int32_t *fill = cr_malloc(((size_t)nv + 1) * 2 * sizeof(int32_t), err);
    if (!t->vf || !t->vv || !fill) {
        free(fill);
        return CR_ERR_MEMORY;
    }
    int32_t *ff = fill, *fv = fill + nv + 1;
    memcpy(ff, t->vf_off, (size_t)nv * sizeof(int32_t));
    memcpy(fv, t->vv_off, (size_t)nv * sizeof(int32_t));
    /* Faces in ascending order; neighbours too, since edges are sorted by
     * (smaller, larger): the edges (u, v) with u < v come before (v, w). */
    for (int32_t f = 0; f < m->nf; f++) {
        if (face_degenerate(&m->tri[3 * f])) continue;
        for (int k = 0; k < 3; k++) {
            int32_t v = m->tri[3 * f + k];
            t->vf[ff[v]++] = f;
        }
    }
    for (int32_t e = 0; e < t->ne; e++) {
        int32_t a = t->edge[2 * e], c = t->edge[2 * e + 1];
        t->vv[fv[a]++] = c;
        t->vv[fv[c]++] = a;
    }
    free(fill);
    for (int32_t v = 0; v < nv; v++)
        if (t->vf_off[v + 1] == t->vf_off[v] && t->n_isolated_vertices++ == 0)
            t->first_isolated_vertex = v;
    return CR_OK;
}

/* Union the faces of each vertex's fan across its two-face edges; more than
 * one component (a bow-tie) or an edge with more than two faces makes the
 * vertex non-manifold. */
static cr_status check_vertex_fans(const cr_mesh *m, cr_topology *t, const edge_build *b,
                                   cr_error *err) {
    int32_t maxd = 0;
    for (int32_t v = 0; v < m->nv; v++) {
        int32_t d = t->vf_off[v + 1] - t->vf_off[v];
        if (d > maxd) maxd = d;
    }
    int32_t *parent = cr_malloc((size_t)maxd * sizeof(int32_t) + 1, err);
    if (!parent) return CR_ERR_MEMORY;
    for (int32_t v = 0; v < m->nv; v++) {
        const int32_t *fan = &t->vf[t->vf_off[v]];
        int32_t d = t->vf_off[v + 1] - t->vf_off[v];
        if (d == 0) continue;
        int bad = 0;
        for (int32_t i = 0; i < d; i++)
            parent[i] = i;
        for (int32_t i = 0; i < d && !bad; i++) {
            int32_t f = fan[i];
            int c = m->tri[3 * f] == v ? 0 : m->tri[3 * f + 1] == v ? 1 : 2;
            int32_t at_v[2] = {t->face_edge[3 * f + c], t->face_edge[3 * f + (c + 2) % 3]};
            for (int s = 0; s < 2; s++) {
                int32_t e = at_v[s];
                if (b->edge_nf[e] > 2) bad = 1;
                if (b->edge_nf[e] != 2) continue;
                int32_t g =
                    t->edge_face[2 * e] == f ? t->edge_face[2 * e + 1] : t->edge_face[2 * e];
                int32_t j = find_sorted(fan, d, g);
                CR_ASSERT(j >= 0);
                parent[uf_find(parent, i)] = uf_find(parent, j);
            }
        }
        int32_t roots = 0;
        for (int32_t i = 0; i < d; i++)
            roots += uf_find(parent, i) == i;
        if ((bad || roots > 1) && t->n_nonmanifold_vertices++ == 0) t->first_nonmanifold_vertex = v;
    }
    free(parent);
    return CR_OK;
}

/* Chain boundary edges into loops following the face winding. */
static cr_status build_boundary_loops(const cr_mesh *m, cr_topology *t, const edge_build *b,
                                      cr_error *err) {
    int32_t nv = m->nv, nb = t->n_boundary_edges;
    t->vertex_boundary = cr_calloc((size_t)nv + 1, 1, err);
    t->loop_off = cr_calloc((size_t)nb + 1, sizeof(int32_t), err);
    /* An open chain has one vertex more than edges, so 2*nb bounds the total. */
    t->loop_vert = cr_malloc((size_t)nb * 2 * sizeof(int32_t) + 1, err);
    int32_t *inc_off = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    int32_t *inc = cr_malloc((size_t)nb * 2 * sizeof(int32_t) + 1, err);
    int32_t *bedges = cr_malloc((size_t)nb * sizeof(int32_t) + 1, err);
    uint8_t *used = cr_calloc((size_t)t->ne + 1, 1, err);
    cr_status st = CR_OK;
    if (!t->vertex_boundary || !t->loop_off || !t->loop_vert || !inc_off || !inc || !bedges ||
        !used) {
        st = CR_ERR_MEMORY;
        goto done;
    }
    int32_t nbe = 0;
    for (int32_t e = 0; e < t->ne; e++) {
        if (b->edge_nf[e] != 1) continue;
        bedges[nbe++] = e;
        for (int s = 0; s < 2; s++) {
            int32_t v = t->edge[2 * e + s];
            t->vertex_boundary[v] = 1;
            inc_off[v + 1]++;
        }
    }
    for (int32_t v = 0; v < nv; v++)
        inc_off[v + 1] += inc_off[v];
    {
        int32_t *fill = cr_malloc((size_t)nv * sizeof(int32_t) + 1, err);
        if (!fill) {
            st = CR_ERR_MEMORY;
            goto done;
        }
        memcpy(fill, inc_off, (size_t)nv * sizeof(int32_t));
        for (int32_t i = 0; i < nbe; i++) {
            int32_t e = bedges[i];
            inc[fill[t->edge[2 * e]]++] = e;
            inc[fill[t->edge[2 * e + 1]]++] = e;
        }
        free(fill);
    }
    const int32_t *tri = m->tri;
    int32_t nl = 0, nvert = 0;
    for (int32_t i = 0; i < nbe; i++) {
        int32_t e = bedges[i];
        if (used[e]) continue;
        int32_t he = b->edge_he[e];
        int32_t start = tri[he], cur = tri[3 * (he / 3) + (he % 3 + 1) % 3];
        used[e] = 1;
        t->loop_vert[nvert++] = start;
        while (cur != start) {
            t->loop_vert[nvert++] = cur;
            /* Prefer the edge leaving `cur` in its face's winding; take any
             * unused one when orientation is inconsistent. */
            int32_t next = -1;
            for (int32_t j = inc_off[cur]; j < inc_off[cur + 1]; j++) {
                int32_t g = inc[j];
                if (used[g]) continue;
                int outgoing = tri[b->edge_he[g]] == cur;
                if (next < 0 || outgoing) next = g;
                if (outgoing) break;
            }
            if (next < 0) break; /* open chain at a non-manifold vertex */
            used[next] = 1;
            cur = t->edge[2 * next] == cur ? t->edge[2 * next + 1] : t->edge[2 * next];
        }
        t->loop_off[++nl] = nvert;
    }
    t->nloop = nl;
done:
    free(inc_off);
    free(inc);
    free(bedges);
    free(used);
    return st;
}

cr_status cr_topology_build(const cr_mesh *m, cr_topology **out, cr_error *err) {
    *out = NULL;
    if (m->nf > INT32_MAX / 3)
        return CR_FAIL(err, CR_ERR_RANGE, "topology: %d faces, at most %d supported", m->nf,
                       INT32_MAX / 3);
    for (int64_t i = 0; i < (int64_t)m->nf * 3; i++)
        if (m->tri[i] < 0 || m->tri[i] >= m->nv)
            return CR_FAIL(err, CR_ERR_RANGE, "topology: face %lld uses vertex %d, mesh has %d",
                           (long long)(i / 3), m->tri[i], m->nv);
    cr_topology *t = cr_calloc(1, sizeof *t, err);
    if (!t) return CR_ERR_MEMORY;
    t->nv = m->nv, t->nf = m->nf;
    t->first_nonmanifold_edge = t->first_nonmanifold_vertex = t->first_inconsistent_edge = -1;
    t->first_isolated_vertex = t->first_degenerate_face = -1;
    edge_build b = {0};
    cr_status st = CR_ERR_MEMORY;
    t->face_edge = cr_malloc((size_t)m->nf * 3 * sizeof(int32_t) + 1, err);
    t->face_face = cr_malloc((size_t)m->nf * 3 * sizeof(int32_t) + 1, err);
    if (!t->face_edge || !t->face_face) goto fail;
    for (int64_t i = 0; i < (int64_t)m->nf * 3; i++)
        t->face_edge[i] = t->face_face[i] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        if (face_degenerate(&m->tri[3 * f]) && t->n_degenerate_faces++ == 0)
            t->first_degenerate_face = f;

    if ((st = sort_half_edges(m, &b, err)) != CR_OK) goto fail;
    if ((st = build_edges(m, t, &b, err)) != CR_OK) goto fail;
    if ((st = build_vertex_adjacency(m, t, err)) != CR_OK) goto fail;
    if ((st = check_vertex_fans(m, t, &b, err)) != CR_OK) goto fail;
    if ((st = build_boundary_loops(m, t, &b, err)) != CR_OK) goto fail;
    free(b.rec), free(b.bucket), free(b.edge_nf), free(b.edge_he);
    *out = t;
    return CR_OK;
fail:
    free(b.rec), free(b.bucket), free(b.edge_nf), free(b.edge_he);
    cr_topology_destroy(t);
    return st;
}

cr_status cr_topology_require_manifold(const cr_topology *t, const char *source, cr_error *err) {
    if (t->n_degenerate_faces > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s: face %d repeats a vertex (%d degenerate faces); remove them first",
                       source, t->first_degenerate_face, t->n_degenerate_faces);
    if (t->n_nonmanifold_edges > 0) {
        int32_t e = t->first_nonmanifold_edge;
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s: non-manifold edge (%d, %d) is shared by more than two faces "
                       "(%d such edges, up to %d faces on one)",
                       source, t->edge[2 * e], t->edge[2 * e + 1], t->n_nonmanifold_edges,
                       t->max_edge_faces);
    }
    if (t->n_nonmanifold_vertices > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s: non-manifold vertex %d: its faces do not form one disk or half-disk "
                       "(%d such vertices)",
                       source, t->first_nonmanifold_vertex, t->n_nonmanifold_vertices);
    if (t->n_inconsistent_edges > 0) {
        int32_t e = t->first_inconsistent_edge;
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s: faces %d and %d run edge (%d, %d) the same way: orientation is "
                       "inconsistent (%d such edges)",
                       source, t->edge_face[2 * e], t->edge_face[2 * e + 1], t->edge[2 * e],
                       t->edge[2 * e + 1], t->n_inconsistent_edges);
    }
    if (t->n_isolated_vertices > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s: vertex %d is used by no face (%d isolated vertices); remove "
                       "unreferenced vertices",
                       source, t->first_isolated_vertex, t->n_isolated_vertices);
    return CR_OK;
}

int64_t cr_topology_euler_characteristic(const cr_topology *t) {
    return (int64_t)(t->nv - t->n_isolated_vertices) - t->ne + (t->nf - t->n_degenerate_faces);
}

cr_status cr_topology_check_mesh(const cr_topology *t, const cr_mesh *m, const char *what,
                                 cr_error *err) {
    if (t->nv != m->nv || t->nf != m->nf)
        return CR_FAIL(err, CR_ERR_SHAPE,
                       "%s: topology built for V=%d, F=%d but the mesh has V=%d, F=%d", what, t->nv,
                       t->nf, m->nv, m->nf);
    return CR_OK;
}
