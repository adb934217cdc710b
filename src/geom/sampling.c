/* sampling.c: Dijkstra on the mesh edge graph and farthest point sampling.
 *
 * One Dijkstra kernel serves both: it takes a distance array already holding
 * tentative values and a heap of the vertices to expand, and only relaxes an
 * edge when it shortens a distance. From scratch (all INFINITY but the
 * sources) it is plain multi-source Dijkstra. For geodesic FPS the array holds
 * the distance to the samples so far and the new sample is pushed at 0: a
 * vertex is expanded only if the new sample is its nearest, which is exact,
 * because a shortest path through a vertex the new sample does not improve
 * cannot improve anything beyond it either (triangle inequality of the
 * running minimum). This is the early exit that keeps later samples cheap.
 *
 * Left out: exact surface geodesics (MMP, heat method); see sampling.h.
 * References: Dijkstra 1959; Eldar et al., "The farthest point strategy for
 * progressive image sampling" (IEEE TIP 1997); Moenning & Dodgson 2003.
 */
#include "crease/sampling.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Indexed binary min-heap on key[] with decrease-key. */
typedef struct heap {
    int32_t *item; /* (size) vertices in heap order */
    int32_t *slot; /* (V) position of each vertex in item, -1 when absent */
    int32_t size;
    const double *key; /* (V) distances */
} heap;

static void heap_swap(heap *h, int32_t a, int32_t b) {
    int32_t va = h->item[a], vb = h->item[b];
    h->item[a] = vb, h->item[b] = va;
    h->slot[vb] = a, h->slot[va] = b;
}

static void heap_up(heap *h, int32_t i) {
    while (i > 0) {
        int32_t p = (i - 1) / 2;
        if (h->key[h->item[p]] <= h->key[h->item[i]]) break;
        heap_swap(h, i, p);
        i = p;
    }
}

static void heap_down(heap *h, int32_t i) {
    for (;;) {
        int32_t l = 2 * i + 1, r = l + 1, s = i;
        if (l < h->size && h->key[h->item[l]] < h->key[h->item[s]]) s = l;
        if (r < h->size && h->key[h->item[r]] < h->key[h->item[s]]) s = r;
        if (s == i) return;
        heap_swap(h, i, s);
        i = s;
    }
}

/* Insert v, or restore order after its key decreased. */
static void heap_push(heap *h, int32_t v) {
    if (h->slot[v] < 0) {
        h->item[h->size] = v;
        h->slot[v] = h->size++;
    }
    heap_up(h, h->slot[v]);
}

static int32_t heap_pop(heap *h) {
    int32_t v = h->item[0];
    heap_swap(h, 0, --h->size);
    h->slot[v] = -1;
    heap_down(h, 0);
    return v;
}

static cr_status heap_init(heap *h, int32_t nv, const double *key, cr_error *err) {
    h->item = cr_malloc((size_t)nv * sizeof(int32_t) + 1, err);
    h->slot = cr_malloc((size_t)nv * sizeof(int32_t) + 1, err);
    h->size = 0;
    h->key = key;
    if (!h->item || !h->slot) return CR_ERR_MEMORY;
    for (int32_t v = 0; v < nv; v++)
        h->slot[v] = -1;
    return CR_OK;
}

static void heap_free(heap *h) {
    free(h->item);
    free(h->slot);
}

/* Expand the heap until empty, relaxing only edges that shorten dist. */
static void dijkstra_run(const float *pos, const cr_topology *t, heap *h, double *dist) {
    while (h->size > 0) {
        int32_t v = heap_pop(h);
        const float *pv = &pos[3 * (size_t)v];
        for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++) {
            int32_t w = t->vv[q];
            const float *pw = &pos[3 * (size_t)w];
            double dx = (double)pw[0] - pv[0], dy = (double)pw[1] - pv[1],
                   dz = (double)pw[2] - pv[2];
            double nd = dist[v] + sqrt(dx * dx + dy * dy + dz * dz);
            if (nd < dist[w]) {
                dist[w] = nd;
                heap_push(h, w);
            }
        }
    }
}

cr_status cr_geodesic_dijkstra(const cr_mesh *m, const cr_topology *t, const int32_t *sources,
                               int32_t nsrc, float *dist, cr_error *err) {
    CR_TRY(cr_topology_check_mesh(t, m, "geodesic", err));
    if (nsrc < 1) return CR_FAIL(err, CR_ERR_INVALID, "geodesic: nsrc = %d, need >= 1", nsrc);
    for (int32_t i = 0; i < nsrc; i++)
        if (sources[i] < 0 || sources[i] >= m->nv)
            return CR_FAIL(err, CR_ERR_RANGE, "geodesic: source %d is vertex %d, mesh has %d", i,
                           sources[i], m->nv);
    double *d = cr_malloc((size_t)m->nv * sizeof(double) + 1, err);
    if (!d) return CR_ERR_MEMORY;
    heap h;
    cr_status st = heap_init(&h, m->nv, d, err);
    if (st == CR_OK) {
        for (int32_t v = 0; v < m->nv; v++)
            d[v] = INFINITY;
        for (int32_t i = 0; i < nsrc; i++) {
            d[sources[i]] = 0.0;
            heap_push(&h, sources[i]);
        }
        dijkstra_run(m->pos, t, &h, d);
        for (int32_t v = 0; v < m->nv; v++)
            dist[v] = (float)d[v];
    }
    heap_free(&h);
    free(d);
    return st;
}

static cr_status check_fps_args(const char *what, int32_t n, int32_t k, int32_t first,
                                cr_error *err) {
    if (k < 1 || k > n)
        return CR_FAIL(err, CR_ERR_RANGE, "%s: k = %d samples of %d points, need 1 <= k <= %d",
                       what, k, n, n);
    if (first < 0 || first >= n)
        return CR_FAIL(err, CR_ERR_RANGE, "%s: first = %d, need 0 <= first < %d", what, first, n);
    return CR_OK;
}

/* The unpicked index with the largest distance, lowest index on ties. */
static int32_t farthest_unpicked(const double *d, const uint8_t *picked, int32_t n) {
    int32_t best = -1;
    for (int32_t i = 0; i < n; i++)
        if (!picked[i] && (best < 0 || d[i] > d[best])) best = i;
    return best;
}

cr_status cr_fps_euclidean(const float *pts, int32_t n, int32_t k, int32_t first, int32_t *out_idx,
                           cr_error *err) {
    CR_TRY(check_fps_args("fps", n, k, first, err));
    double *d2 = cr_malloc((size_t)n * sizeof(double), err); /* squared distance to the samples */
    uint8_t *picked = cr_calloc((size_t)n, 1, err);
    if (!d2 || !picked) {
        free(d2), free(picked);
        return CR_ERR_MEMORY;
    }
    for (int32_t i = 0; i < n; i++)
        d2[i] = INFINITY;
    int32_t s = first;
    for (int32_t j = 0; j < k; j++) {
        out_idx[j] = s;
        picked[s] = 1;
        const float *ps = &pts[3 * (size_t)s];
        for (int32_t i = 0; i < n; i++) {
            const float *p = &pts[3 * (size_t)i];
            double dx = (double)p[0] - ps[0], dy = (double)p[1] - ps[1], dz = (double)p[2] - ps[2];
            double q = dx * dx + dy * dy + dz * dz;
            if (q < d2[i]) d2[i] = q;
        }
        if (j + 1 < k) s = farthest_unpicked(d2, picked, n);
    }
    free(d2);
    free(picked);
    return CR_OK;
}

cr_status cr_fps_geodesic(const cr_mesh *m, const cr_topology *t, int32_t k, int32_t first,
                          int32_t *out_idx, cr_error *err) {
    CR_TRY(cr_topology_check_mesh(t, m, "geodesic fps", err));
    CR_TRY(check_fps_args("geodesic fps", m->nv, k, first, err));
    double *d = cr_malloc((size_t)m->nv * sizeof(double), err); /* distance to the samples */
    uint8_t *picked = cr_calloc((size_t)m->nv, 1, err);
    heap h = {0};
    cr_status st = d && picked ? heap_init(&h, m->nv, d, err) : CR_ERR_MEMORY;
    if (st == CR_OK) {
        for (int32_t v = 0; v < m->nv; v++)
            d[v] = INFINITY;
        int32_t s = first;
        for (int32_t j = 0; j < k; j++) {
            out_idx[j] = s;
            picked[s] = 1;
            d[s] = 0.0;
            heap_push(&h, s);
            dijkstra_run(m->pos, t, &h, d);
            if (j + 1 < k) s = farthest_unpicked(d, picked, m->nv);
        }
    }
    heap_free(&h);
    free(d);
    free(picked);
    return st;
}
