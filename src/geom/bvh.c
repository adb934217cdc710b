/* bvh.c: building and refitting the triangle BVH (layout in bvh_internal.h;
 * queries in bvh_query.c).
 *
 * Build: top-down binned SAH (Wald, "On fast construction of SAH-based
 * bounding volume hierarchies", IEEE RT 2007): centroids are dropped into 16
 * bins per axis, the split minimising area_left * n_left + area_right *
 * n_right over all three axes wins. Nodes with no usable centroid spread, or
 * deeper than BVH_MEDIAN_DEPTH, split at the object median instead. The build
 * itself is serial; it also records vertex-to-face incidence (for the
 * angle-weighted vertex normals, gathered per vertex so they parallelise) and
 * face adjacency across each edge (for the edge pseudo-normals).
 *
 * Leaves read their triangles from leaf_pos, a copy of the corner positions
 * in leaf order, which saves two dependent loads per triangle in queries.
 *
 * Refit: copies new positions, regathers leaf_pos, recomputes normals and
 * leaf boxes (in parallel), then internal boxes in one reverse sweep, since
 * children always sit after their parent. The tree is not restructured.
 *
 * Left out: parallel build, spatial splits, tree rotations after refit.
 */
#include "bvh_internal.h"

#include "base/atan2d.h"

#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { SAH_BINS = 16 };

/* ------------------------------------------------------------ helpers -- */

static void box_empty(float lo[3], float hi[3]) {
    for (int d = 0; d < 3; d++)
        lo[d] = INFINITY, hi[d] = -INFINITY;
}

/* Written out per axis: gcc -O2 keeps a 3-trip loop here as a loop, and this
 * is the inner statement of the build. */
static void box_grow(float lo[3], float hi[3], const float blo[3], const float bhi[3]) {
    lo[0] = bvh_minf(lo[0], blo[0]), hi[0] = bvh_maxf(hi[0], bhi[0]);
    lo[1] = bvh_minf(lo[1], blo[1]), hi[1] = bvh_maxf(hi[1], bhi[1]);
    lo[2] = bvh_minf(lo[2], blo[2]), hi[2] = bvh_maxf(hi[2], bhi[2]);
}

static double box_half_area(const float lo[3], const float hi[3]) {
    double ex = (double)hi[0] - lo[0], ey = (double)hi[1] - lo[1], ez = (double)hi[2] - lo[2];
    return ex * ey + ey * ez + ez * ex;
}

static void corners_box(const float *p0, const float *p1, const float *p2, float lo[3],
                        float hi[3]) {
    for (int d = 0; d < 3; d++) {
        lo[d] = bvh_minf(p0[d], bvh_minf(p1[d], p2[d]));
        hi[d] = bvh_maxf(p0[d], bvh_maxf(p1[d], p2[d]));
    }
}

/* ------------------------------------------------------------ normals -- */

static void face_normals_range(void *ctx, int64_t begin, int64_t end) {
    cr_bvh *b = ctx;
    for (int64_t f = begin; f < end; f++) {
        const int32_t *t = &b->tri[3 * f];
        cr_triangle_normal(&b->pos[3 * (size_t)t[0]], &b->pos[3 * (size_t)t[1]],
                           &b->pos[3 * (size_t)t[2]], &b->fnormal[3 * f]);
    }
}

/* Angle-weighted vertex normals (Baerentzen & Aanaes 2005, eq. 3) gathered
 * over each vertex's faces; the interior angle comes from atan2 so it stays
 * accurate near 0 and pi. */
void cr_bvh_vertex_normal_of(const cr_bvh *b, int64_t v, float out[3]) {
    double acc[3] = {0, 0, 0};
    const float *pv = &b->pos[3 * v];
    for (int64_t i = b->vf_start[v]; i < b->vf_start[v + 1]; i++) {
        int32_t f = b->vf[i];
        const int32_t *t = &b->tri[3 * (size_t)f];
        int k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
        const float *pa = &b->pos[3 * (size_t)t[(k + 1) % 3]],
                    *pb = &b->pos[3 * (size_t)t[(k + 2) % 3]];
        double u[3], w[3];
        for (int d = 0; d < 3; d++)
            u[d] = (double)pa[d] - pv[d], w[d] = (double)pb[d] - pv[d];
        double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2],
               cz = u[0] * w[1] - u[1] * w[0];
        double angle =
            cr_atan2d(sqrt(cx * cx + cy * cy + cz * cz), u[0] * w[0] + u[1] * w[1] + u[2] * w[2]);
        for (int d = 0; d < 3; d++)
            acc[d] += angle * b->fnormal[3 * (size_t)f + d];
    }
    double len = sqrt(acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]);
    for (int d = 0; d < 3; d++)
        out[d] = len > 0 ? (float)(acc[d] / len) : 0.0f;
}

static void vertex_normals_range(void *ctx, int64_t begin, int64_t end) {
    cr_bvh *b = ctx;
    for (int64_t v = begin; v < end; v++)
        cr_bvh_vertex_normal_of(b, v, &b->vnormal[3 * v]);
}

static void update_vertex_normals(cr_bvh *b) {
    cr_parallel_for(b->nv, 1024, vertex_normals_range, b);
    b->vnormal_stale = 0;
}

/* Copy each face's corners into leaf order (build and refit). */
static void gather_leaf_pos_range(void *ctx, int64_t begin, int64_t end) {
    cr_bvh *b = ctx;
    for (int64_t i = begin; i < end; i++) {
        const int32_t *t = &b->tri[3 * (size_t)b->order[i]];
        for (int c = 0; c < 3; c++)
            memcpy(&b->leaf_pos[9 * i + 3 * c], &b->pos[3 * (size_t)t[c]], 12);
    }
}

/* --------------------------------------------------------- topology -- */

/* Vertex-to-face incidence as CSR (counting sort), then for each face edge
 * (a, b) the one other face around a that also holds b. */
static cr_status build_topology(cr_bvh *b, cr_error *err) {
    b->vf_start = cr_calloc((size_t)b->nv + 1, sizeof(int64_t), err);
    b->vf = cr_malloc((size_t)b->nf * 3 * sizeof(int32_t), err);
    b->adj = cr_malloc((size_t)b->nf * 3 * sizeof(int32_t), err);
    if (!b->vf_start || !b->vf || !b->adj) return CR_ERR_MEMORY;
    for (size_t i = 0; i < 3 * (size_t)b->nf; i++)
        b->vf_start[b->tri[i] + 1]++;
    for (int32_t v = 0; v < b->nv; v++)
        b->vf_start[v + 1] += b->vf_start[v];
    for (int32_t f = 0; f < b->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t v = b->tri[3 * (size_t)f + k];
            b->vf[b->vf_start[v]++] = f;
        }
    /* The fill advanced each start to the next vertex's start: shift back. */
    for (int32_t v = b->nv; v > 0; v--)
        b->vf_start[v] = b->vf_start[v - 1];
    b->vf_start[0] = 0;

    for (int32_t f = 0; f < b->nf; f++) {
        for (int k = 0; k < 3; k++) {
            int32_t va = b->tri[3 * (size_t)f + k], vb = b->tri[3 * (size_t)f + (k + 1) % 3];
            int32_t other = -1, found = 0;
            for (int64_t i = b->vf_start[va]; i < b->vf_start[va + 1]; i++) {
                int32_t g = b->vf[i];
                const int32_t *t = &b->tri[3 * (size_t)g];
                if (g == f || (t[0] != vb && t[1] != vb && t[2] != vb)) continue;
                other = g;
                found++;
            }
            b->adj[3 * (size_t)f + k] = found == 1 ? other : -1;
        }
    }
    return CR_OK;
}

/* ------------------------------------------------------------- build -- */

/* Per-face build record: box and box centre, read together while binning. */
typedef struct face_rec {
    float lo[3], hi[3], c[3];
} face_rec;

static void swap_i32(int32_t *a, int32_t *b) {
    int32_t t = *a;
    *a = *b, *b = t;
}

/* Rearrange order[lo, hi) so that order[nth] has the key it would have when
 * sorted, smaller keys before it and larger after (three-way quickselect). */
static void select_nth(int32_t *a, int64_t lo, int64_t hi, int64_t nth, const face_rec *rec,
                       int axis) {
    while (hi - lo > 1) {
        float pivot = rec[a[lo + (hi - lo) / 2]].c[axis];
        int64_t lt = lo, i = lo, gt = hi;
        while (i < gt) {
            float k = rec[a[i]].c[axis];
            if (k < pivot)
                swap_i32(&a[lt++], &a[i++]);
            else if (k > pivot)
                swap_i32(&a[i], &a[--gt]);
            else
                i++;
        }
        if (nth < lt)
            hi = lt;
        else if (nth >= gt)
            lo = gt;
        else
            return;
    }
}

static int bin_of(float c, float clo, float scale) {
    int i = (int)((c - clo) * scale);
    return i < 0 ? 0 : (i >= SAH_BINS ? SAH_BINS - 1 : i);
}

typedef struct sah_bin {
    float lo[3], hi[3];
    int64_t count;
} sah_bin;

/* Best SAH split of order[begin, end): returns the split position, or -1
 * when no binned split separates the faces. All three axes are binned in one
 * pass over the faces; an axis without centroid spread gets scale 0, so all
 * its faces share bin 0 and it offers no split. */
static int64_t sah_split(const face_rec *rec, int32_t *order, int64_t begin, int64_t end,
                         const float clo[3], const float chi[3]) {
    float scale[3];
    sah_bin bins[3][SAH_BINS];
    for (int axis = 0; axis < 3; axis++) {
        float extent = chi[axis] - clo[axis];
        scale[axis] = extent > 0 ? SAH_BINS / extent : 0.0f;
        for (int i = 0; i < SAH_BINS; i++) {
            box_empty(bins[axis][i].lo, bins[axis][i].hi);
            bins[axis][i].count = 0;
        }
    }
    for (int64_t i = begin; i < end; i++) {
        const face_rec *r = &rec[order[i]];
        for (int axis = 0; axis < 3; axis++) {
            sah_bin *bn = &bins[axis][bin_of(r->c[axis], clo[axis], scale[axis])];
            bn->count++;
            box_grow(bn->lo, bn->hi, r->lo, r->hi);
        }
    }
    double best_cost = INFINITY;
    int best_axis = -1, best_bin = -1;
    for (int axis = 0; axis < 3; axis++) {
        /* Right-to-left sweep: cost of everything right of each bin boundary. */
        double right_cost[SAH_BINS];
        float lo[3], hi[3];
        box_empty(lo, hi);
        int64_t n = 0;
        for (int i = SAH_BINS - 1; i > 0; i--) {
            box_grow(lo, hi, bins[axis][i].lo, bins[axis][i].hi);
            n += bins[axis][i].count;
            right_cost[i] = n ? box_half_area(lo, hi) * (double)n : 0;
        }
        box_empty(lo, hi);
        n = 0;
        for (int i = 0; i < SAH_BINS - 1; i++) {
            box_grow(lo, hi, bins[axis][i].lo, bins[axis][i].hi);
            n += bins[axis][i].count;
            if (n == 0 || n == end - begin) continue;
            double cost = box_half_area(lo, hi) * (double)n + right_cost[i + 1];
            if (cost < best_cost) best_cost = cost, best_axis = axis, best_bin = i;
        }
    }
    if (best_axis < 0) return -1;
    int64_t mid = begin;
    for (int64_t i = begin; i < end; i++)
        if (bin_of(rec[order[i]].c[best_axis], clo[best_axis], scale[best_axis]) <= best_bin)
            swap_i32(&order[i], &order[mid++]);
    return mid;
}

static void build_node(cr_bvh *b, const face_rec *rec, int32_t idx, int64_t begin, int64_t end,
                       int32_t depth) {
    bvh_node *node = &b->nodes[idx];
    float clo[3], chi[3];
    box_empty(node->lo, node->hi);
    box_empty(clo, chi);
    for (int64_t i = begin; i < end; i++) {
        const face_rec *r = &rec[b->order[i]];
        box_grow(node->lo, node->hi, r->lo, r->hi);
        box_grow(clo, chi, r->c, r->c);
    }
    if (depth > b->depth) b->depth = depth;
    if (end - begin <= BVH_LEAF_MAX) {
        node->start = (int32_t)begin;
        node->count = (int32_t)(end - begin);
        return;
    }
    int64_t mid = depth < BVH_MEDIAN_DEPTH ? sah_split(rec, b->order, begin, end, clo, chi) : -1;
    if (mid < 0) {
        int axis = 0;
        for (int d = 1; d < 3; d++)
            if (chi[d] - clo[d] > chi[axis] - clo[axis]) axis = d;
        mid = begin + (end - begin) / 2;
        select_nth(b->order, begin, end, mid, rec, axis);
    }
    int32_t left = b->nnodes;
    b->nnodes += 2;
    node->start = left;
    node->count = 0;
    build_node(b, rec, left, begin, mid, depth + 1);
    build_node(b, rec, left + 1, mid, end, depth + 1);
}

cr_status cr_bvh_build(const float *pos, int32_t nv, const int32_t *tri, int32_t nf, cr_bvh **out,
                       cr_error *err) {
    *out = NULL;
    if (nf < 1) return CR_FAIL(err, CR_ERR_TOPOLOGY, "bvh: need at least one triangle, got %d", nf);
    if (nv < 1) return CR_FAIL(err, CR_ERR_TOPOLOGY, "bvh: need vertices, got %d", nv);
    if (nf > INT32_MAX / 2)
        return CR_FAIL(err, CR_ERR_INVALID, "bvh: %d faces exceed the int32 node index range", nf);
    CR_ASSERT(pos && tri);
    for (size_t i = 0; i < 3 * (size_t)nf; i++)
        if (tri[i] < 0 || tri[i] >= nv)
            return CR_FAIL(err, CR_ERR_RANGE, "bvh: face %zu corner %zu: vertex %d not in [0, %d)",
                           i / 3, i % 3, tri[i], nv);
    for (size_t i = 0; i < 3 * (size_t)nv; i++)
        if (!isfinite(pos[i]))
            return CR_FAIL(err, CR_ERR_NAN, "bvh: vertex %zu has a non-finite coordinate", i / 3);

    cr_bvh *b = cr_calloc(1, sizeof *b, err);
    if (!b) return CR_ERR_MEMORY;
    b->nv = nv, b->nf = nf;
    b->pos = cr_malloc((size_t)nv * 3 * sizeof(float), err);
    b->tri = cr_malloc((size_t)nf * 3 * sizeof(int32_t), err);
    b->fnormal = cr_malloc((size_t)nf * 3 * sizeof(float), err);
    b->vnormal = cr_malloc((size_t)nv * 3 * sizeof(float), err);
    b->order = cr_malloc((size_t)nf * sizeof(int32_t), err);
    b->leaf_pos = cr_malloc((size_t)nf * 9 * sizeof(float), err);
    b->nodes = cr_malloc((2 * (size_t)nf - 1) * sizeof(bvh_node), err);
    face_rec *rec = cr_malloc((size_t)nf * sizeof(face_rec), err);
    cr_status st = CR_OK;
    if (!b->pos || !b->tri || !b->fnormal || !b->vnormal || !b->order || !b->leaf_pos ||
        !b->nodes || !rec)
        st = CR_ERR_MEMORY;
    if (st == CR_OK) {
        memcpy(b->pos, pos, (size_t)nv * 3 * sizeof(float));
        memcpy(b->tri, tri, (size_t)nf * 3 * sizeof(int32_t));
        st = build_topology(b, err);
    }
    if (st != CR_OK) {
        free(rec);
        cr_bvh_destroy(b);
        return st;
    }
    for (int32_t f = 0; f < nf; f++) {
        face_rec *r = &rec[f];
        const int32_t *t = &b->tri[3 * (size_t)f];
        corners_box(&pos[3 * (size_t)t[0]], &pos[3 * (size_t)t[1]], &pos[3 * (size_t)t[2]], r->lo,
                    r->hi);
        for (int d = 0; d < 3; d++)
            r->c[d] = 0.5f * (r->lo[d] + r->hi[d]);
        b->order[f] = f;
    }
    b->nnodes = 1;
    build_node(b, rec, 0, 0, nf, 0);
    CR_ASSERT(b->nnodes <= 2 * nf - 1 && b->depth < BVH_STACK - 1);
    free(rec);
    cr_parallel_for(nf, 4096, gather_leaf_pos_range, b);
    cr_parallel_for(b->nf, 1024, face_normals_range, b);
    update_vertex_normals(b);
    *out = b;
    return CR_OK;
}

/* ------------------------------------------------------------- refit -- */

static void refit_leaves_range(void *ctx, int64_t begin, int64_t end) {
    cr_bvh *b = ctx;
    for (int64_t i = begin; i < end; i++) {
        bvh_node *n = &b->nodes[i];
        if (n->count == 0) continue;
        box_empty(n->lo, n->hi);
        for (int32_t k = 0; k < n->count; k++) {
            const float *v = &b->leaf_pos[9 * (size_t)(n->start + k)];
            float lo[3], hi[3];
            corners_box(v, v + 3, v + 6, lo, hi);
            box_grow(n->lo, n->hi, lo, hi);
        }
    }
}

cr_status cr_bvh_refit(cr_bvh *b, const float *pos, cr_error *err) {
    CR_ASSERT(b && pos);
    for (size_t i = 0; i < 3 * (size_t)b->nv; i++)
        if (!isfinite(pos[i]))
            return CR_FAIL(err, CR_ERR_NAN, "bvh refit: vertex %zu has a non-finite coordinate",
                           i / 3);
    memcpy(b->pos, pos, (size_t)b->nv * 3 * sizeof(float));
    cr_parallel_for(b->nf, 4096, gather_leaf_pos_range, b);
    cr_parallel_for(b->nnodes, 1024, refit_leaves_range, b);
    for (int32_t i = b->nnodes - 1; i >= 0; i--) {
        bvh_node *n = &b->nodes[i];
        if (n->count > 0) continue;
        const bvh_node *l = &b->nodes[n->start], *r = &b->nodes[n->start + 1];
        for (int d = 0; d < 3; d++) {
            n->lo[d] = bvh_minf(l->lo[d], r->lo[d]);
            n->hi[d] = bvh_maxf(l->hi[d], r->hi[d]);
        }
    }
    /* The vertex normals wait until asked for: a moving body's refit every
     * substep recomputed all of them (six atan2 a vertex), 43 % of an epnet
     * reference run, while the garment's queries meet a vertex feature at a
     * few hundred of the body's vertices. Queries compute the ones they meet
     * (cr_bvh_vertex_normal_of); cr_bvh_vertex_normals fills the array. */
    cr_parallel_for(b->nf, 1024, face_normals_range, b);
    b->vnormal_stale = 1;
    return CR_OK;
}

void cr_bvh_destroy(cr_bvh *b) {
    if (!b) return;
    free(b->pos);
    free(b->tri);
    free(b->adj);
    free(b->fnormal);
    free(b->vnormal);
    free(b->vf_start);
    free(b->vf);
    free(b->order);
    free(b->leaf_pos);
    free(b->nodes);
    free(b);
}

int32_t cr_bvh_vertex_count(const cr_bvh *b) {
    return b->nv;
}
int32_t cr_bvh_face_count(const cr_bvh *b) {
    return b->nf;
}
int32_t cr_bvh_node_count(const cr_bvh *b) {
    return b->nnodes;
}
int32_t cr_bvh_depth(const cr_bvh *b) {
    return b->depth;
}
const float *cr_bvh_positions(const cr_bvh *b) {
    return b->pos;
}
const int32_t *cr_bvh_triangles(const cr_bvh *b) {
    return b->tri;
}
const float *cr_bvh_face_normals(const cr_bvh *b) {
    return b->fnormal;
}
const float *cr_bvh_vertex_normals(const cr_bvh *b) {
    /* the array is a cache of the positions: filling it does not change the tree */
    if (b->vnormal_stale) update_vertex_normals((cr_bvh *)b);
    return b->vnormal;
}

void cr_bvh_smooth_normal(const cr_bvh *b, const float *vn, const cr_bvh_hit *hit, float out[3]) {
    out[0] = out[1] = out[2] = 0.0f;
    if (hit->face < 0) return;
    const int32_t *f = b->tri + 3 * (int64_t)hit->face;
    double m[3] = {0.0, 0.0, 0.0};
    for (int k = 0; k < 3; k++)
        for (int j = 0; j < 3; j++)
            m[j] += (double)hit->bary[k] * vn[3 * (int64_t)f[k] + j];
    const double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    if (len > 1e-12)
        for (int j = 0; j < 3; j++)
            out[j] = (float)(m[j] / len);
}
