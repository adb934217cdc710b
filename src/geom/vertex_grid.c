/* vertex_grid.c: nearest vertex by a uniform grid of candidate lists.
 *
 * A vertex v can be the nearest to a point q of a cell only if q is at least
 * as close to v as to any other vertex c, in particular to each anchor: the
 * vertices nearest to the cell's eight corners (one BVH query per grid node,
 * shared by the eight cells around it).
 *     |q - c|^2 - |q - v|^2 = 2 q.(v - c) + |c|^2 - |v|^2 >= 0.
 * The left side is linear in q, so its largest value over the cell's box is
 * at the corner picked axis by axis by the sign of v - c. A cell's list is
 * every vertex for which that maximum is >= 0 against every anchor (less a
 * rounding slack, so the list errs on the long side): it holds the nearest
 * vertex of every point of the cell, exactly. The vertices to test come from
 * the BVH, pruned by the distance from a node's box to the cell's box against
 * the smallest over anchors of the farthest corner's distance (no point of
 * the cell has its nearest vertex farther). Cell boxes are grown by a
 * thousandth of a cell, so a point that rounding puts in the neighbouring
 * cell is still covered.
 *
 * Lists are sorted by vertex index and a query keeps the first strictly
 * closer vertex, so ties go to the lowest index, as in the BVH's query.
 * Lists are built in parallel over fixed chunks of cells and joined in cell
 * order: the grid is the same on any thread count, unless the entry budget
 * runs out (then which cells keep a list depends on the threads' timing;
 * the answers never do).
 */
#include "crease/vertex_grid.h"

#include "geom/bvh_internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

enum { CHUNK_CELLS = 256 };

struct cr_vertex_grid {
    const cr_bvh *tree;
    double lo[3]; /* grid origin, m */
    double h;     /* cell size, m */
    double inv_h;
    int32_t n[3];
    int64_t cells;
    int64_t *start;  /* (cells + 1): cell c lists entries start[c] .. start[c + 1]; none: the BVH */
    int32_t *vertex; /* (entries) ascending within a cell */
    float *pos;      /* (entries, 3) their positions */
    int64_t overfull;
};

cr_vertex_grid_opts cr_vertex_grid_default_opts(void) {
    return (cr_vertex_grid_opts){.cells_per_vertex = 2.0,
                                 .max_cells = 1 << 21,
                                 .max_list = 64,
                                 .reach_cells = 12.0,
                                 .max_entries = (int64_t)1 << 23};
}

void cr_vertex_grid_destroy(cr_vertex_grid *g) {
    if (!g) return;
    free(g->start);
    free(g->vertex);
    free(g->pos);
    free(g);
}

/* ------------------------------------------------------------- build -- */

typedef struct chunk_out {
    int32_t count[CHUNK_CELLS]; /* list length per cell of the chunk */
    int32_t *vertex;
    int64_t len, cap;
    int failed; /* out of memory */
} chunk_out;

typedef struct build_ctx {
    cr_vertex_grid *g;
    chunk_out *chunks;
    int32_t *node_vertex; /* ((n0 + 1) (n1 + 1) (n2 + 1)) nearest vertex of each grid node */
    float reach;          /* m: node searches stop there */
    int32_t max_list;
    int64_t max_entries;
    atomic_llong entries; /* listed so far, against max_entries */
} build_ctx;

static double box_box_dist2(const bvh_node *n, const double a[3], const double b[3]) {
    double s = 0.0;
    for (int d = 0; d < 3; d++) {
        double gap = fmax(fmax((double)n->lo[d] - b[d], a[d] - (double)n->hi[d]), 0.0);
        s += gap * gap;
    }
    return s;
}

/* Whether some point of the box [a, b] is at least as close to v as to c. */
static int may_be_nearer(const float *v, const float *c, const double a[3], const double b[3]) {
    double s = 0.0, mag = 0.0;
    for (int d = 0; d < 3; d++) {
        double dv = (double)v[d] - c[d], q = dv > 0.0 ? b[d] : a[d];
        double t = 2.0 * q * dv + ((double)c[d] * c[d] - (double)v[d] * v[d]);
        s += t;
        mag += fabs(2.0 * q * dv) + (double)c[d] * c[d] + (double)v[d] * v[d];
    }
    return s >= -1e-12 * mag;
}

static int cmp_i32(const void *x, const void *y) {
    int32_t a = *(const int32_t *)x, b = *(const int32_t *)y;
    return (a > b) - (a < b);
}

/* Sort and drop repeats (a face tree meets a vertex once per face). */
static int32_t unique_sorted(int32_t *list, int32_t n) {
    qsort(list, (size_t)n, sizeof *list, cmp_i32);
    int32_t m = 0;
    for (int32_t i = 0; i < n; i++)
        if (m == 0 || list[m - 1] != list[i]) list[m++] = list[i];
    return m;
}

/* Candidates of the cell box [a, b] into list (room for raw entries):
 * their count, or -1 when there are more than max_list. The anchors are the
 * vertices nearest to the cell's eight corners (-1: none within the reach);
 * a candidate must pass the test above against each (the nearest vertex of
 * any point of the cell passes against every vertex), which prunes far more
 * than one anchor where the mesh is dense. */
static int32_t cell_candidates(const cr_bvh *t, const int32_t corner_vertex[8], const double a[3],
                               const double b[3], int32_t max_list, int32_t *list, int32_t raw) {
    int32_t anchor[8];
    int nanchor = 0;
    for (int k = 0; k < 8; k++) {
        const int32_t v = corner_vertex[k];
        if (v < 0) return -1; /* a corner far from the mesh: the BVH answers there */
        int seen = 0;
        for (int j = 0; j < nanchor; j++)
            seen |= anchor[j] == v;
        if (!seen) anchor[nanchor++] = v;
    }
    /* no point of the cell has its nearest vertex farther than any anchor's
     * farthest corner */
    double reach2 = INFINITY;
    for (int m = 0; m < nanchor; m++) {
        const float *c = &t->pos[3 * (size_t)anchor[m]];
        double far2 = 0.0;
        for (int k = 0; k < 8; k++) {
            double s = 0.0;
            for (int d = 0; d < 3; d++) {
                double e = ((k >> d) & 1 ? b[d] : a[d]) - (double)c[d];
                s += e * e;
            }
            far2 = fmax(far2, s);
        }
        reach2 = fmin(reach2, far2 * (1.0 + 1e-9));
    }
    int32_t n = 0;
    int32_t stack[BVH_STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const bvh_node *node = &t->nodes[stack[--top]];
        if (box_box_dist2(node, a, b) > reach2) continue;
        if (node->count == 0) {
            stack[top++] = node->start;
            stack[top++] = node->start + 1;
            continue;
        }
        for (int32_t k = 0; k < node->count; k++) {
            const int32_t *f = &t->tri[3 * (size_t)t->order[node->start + k]];
            const int corners = f[1] == f[0] && f[2] == f[0] ? 1 : 3;
            for (int j = 0; j < corners; j++) {
                const float *v = &t->pos[3 * (size_t)f[j]];
                int keep = 1;
                for (int m = 0; m < nanchor && keep; m++)
                    keep = may_be_nearer(v, &t->pos[3 * (size_t)anchor[m]], a, b);
                if (!keep) continue;
                if (n == raw) {
                    n = unique_sorted(list, n);
                    if (n > max_list) return -1;
                }
                list[n++] = f[j];
            }
        }
    }
    n = unique_sorted(list, n);
    return n > max_list ? -1 : n;
}

/* (i, j, k) of flat index c over an n0 x n1 x n2 array, k fastest. */
static void unflatten(int64_t c, int64_t n1, int64_t n2, int64_t idx[3]) {
    idx[0] = c / (n1 * n2), idx[1] = c / n2 % n1, idx[2] = c % n2;
}

/* The vertex nearest to each grid node within the reach (-1 beyond). */
static void node_range(void *vctx, int64_t begin, int64_t end) {
    build_ctx *bc = vctx;
    const cr_vertex_grid *g = bc->g;
    const int64_t n1 = g->n[1] + 1, n2 = g->n[2] + 1;
    for (int64_t i = begin; i < end; i++) {
        int64_t idx[3];
        unflatten(i, n1, n2, idx);
        float q[3];
        for (int d = 0; d < 3; d++)
            q[d] = (float)(g->lo[d] + (double)idx[d] * g->h);
        bc->node_vertex[i] = cr_bvh_nearest_vertex(g->tree, q, bc->reach, NULL);
    }
}

static void build_range(void *vctx, int64_t begin, int64_t end) {
    build_ctx *bc = vctx;
    cr_vertex_grid *g = bc->g;
    const int32_t raw = 8 * bc->max_list + 8;
    const int64_t n1 = g->n[1] + 1, n2 = g->n[2] + 1;
    int32_t *list = malloc((size_t)raw * sizeof *list);
    for (int64_t ch = begin; ch < end; ch++) {
        chunk_out *o = &bc->chunks[ch];
        if (!list) {
            o->failed = 1;
            continue;
        }
        for (int64_t c = ch * CHUNK_CELLS; c < (ch + 1) * CHUNK_CELLS && c < g->cells; c++) {
            int64_t idx[3];
            unflatten(c, g->n[1], g->n[2], idx);
            double a[3], b[3];
            for (int d = 0; d < 3; d++) {
                a[d] = g->lo[d] + (double)idx[d] * g->h - 1e-3 * g->h;
                b[d] = g->lo[d] + (double)(idx[d] + 1) * g->h + 1e-3 * g->h;
            }
            int32_t corner_vertex[8];
            for (int k = 0; k < 8; k++)
                corner_vertex[k] = bc->node_vertex[((idx[0] + (k & 1)) * n1 + idx[1] + (k >> 1 & 1)) *
                                                       n2 +
                                                   idx[2] + (k >> 2 & 1)];
            int32_t n = cell_candidates(g->tree, corner_vertex, a, b, bc->max_list, list, raw);
            if (n < 0) n = 0; /* overfull or out of reach: the BVH answers */
            /* past the memory budget the remaining cells keep no list (which
             * ones then depends on the threads' timing; the answers do not) */
            if (n > 0 && atomic_fetch_add(&bc->entries, n) + n > bc->max_entries) n = 0;
            if (o->len + n > o->cap) {
                int64_t cap = o->cap ? 2 * o->cap : 4096;
                while (cap < o->len + n)
                    cap *= 2;
                int32_t *grown = realloc(o->vertex, (size_t)cap * sizeof *grown);
                if (!grown) {
                    o->failed = 1;
                    break;
                }
                o->vertex = grown, o->cap = cap;
            }
            if (n > 0) memcpy(o->vertex + o->len, list, (size_t)n * sizeof *list);
            o->len += n;
            o->count[c - ch * CHUNK_CELLS] = n;
        }
    }
    free(list);
}

/* Cells along each axis: about target cells of one size over the box. */
static void choose_cells(const double ext[3], double target, int32_t max_cells, double *h,
                         int32_t n[3]) {
    double e[3], emax = fmax(fmax(ext[0], ext[1]), ext[2]);
    for (int d = 0; d < 3; d++)
        e[d] = fmax(ext[d], fmax(1e-6 * emax, 1e-12));
    *h = cbrt(e[0] * e[1] * e[2] / target);
    for (;;) {
        double cells = 1.0;
        for (int d = 0; d < 3; d++) {
            double k = ceil(e[d] / *h);
            n[d] = (int32_t)fmax(1.0, fmin(k, (double)max_cells));
            cells *= n[d];
        }
        if (cells <= max_cells) return;
        *h *= 1.05;
    }
}

cr_status cr_vertex_grid_build(const cr_bvh *tree, const float lo[3], const float hi[3],
                               const cr_vertex_grid_opts *opts, cr_vertex_grid **out,
                               cr_error *err) {
    CR_ASSERT(tree && lo && hi && out);
    *out = NULL;
    const cr_vertex_grid_opts o = opts ? *opts : cr_vertex_grid_default_opts();
    if (!(o.cells_per_vertex > 0.0 && o.cells_per_vertex <= 1e6))
        return CR_FAIL(err, CR_ERR_INVALID, "vertex grid: cells_per_vertex %g not in (0, 1e6]",
                       o.cells_per_vertex);
    if (!(o.reach_cells > 0.0))
        return CR_FAIL(err, CR_ERR_INVALID, "vertex grid: reach_cells %g must be > 0",
                       o.reach_cells);
    if (o.max_entries < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "vertex grid: max_entries %lld must be >= 0",
                       (long long)o.max_entries);
    if (o.max_cells < 1 || o.max_list < 1 || o.max_list > (1 << 20))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "vertex grid: max_cells %d must be >= 1 and max_list %d in [1, 2^20]",
                       (int)o.max_cells, (int)o.max_list);
    double ext[3];
    for (int d = 0; d < 3; d++) {
        if (!isfinite(lo[d]) || !isfinite(hi[d]) || !(hi[d] >= lo[d]))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "vertex grid: box axis %d [%g, %g] is empty or not finite", d,
                           (double)lo[d], (double)hi[d]);
        ext[d] = (double)hi[d] - lo[d];
    }
    cr_vertex_grid *g = cr_calloc(1, sizeof *g, err);
    if (!g) return err ? err->status : CR_ERR_MEMORY;
    g->tree = tree;
    for (int d = 0; d < 3; d++)
        g->lo[d] = lo[d];
    double target = fmin(fmax(1.0, o.cells_per_vertex * cr_bvh_vertex_count(tree)), o.max_cells);
    choose_cells(ext, target, o.max_cells, &g->h, g->n);
    g->inv_h = 1.0 / g->h;
    g->cells = (int64_t)g->n[0] * g->n[1] * g->n[2];

    const int64_t nchunks = (g->cells + CHUNK_CELLS - 1) / CHUNK_CELLS;
    const int64_t nodes = (int64_t)(g->n[0] + 1) * (g->n[1] + 1) * (g->n[2] + 1);
    build_ctx bc = {.g = g,
                    .max_list = o.max_list,
                    .max_entries = o.max_entries,
                    .reach = (float)(o.reach_cells * g->h)};
    atomic_init(&bc.entries, 0);
    bc.chunks = cr_calloc((size_t)nchunks, sizeof *bc.chunks, err);
    bc.node_vertex = cr_malloc((size_t)nodes * sizeof *bc.node_vertex, err);
    g->start = cr_malloc((size_t)(g->cells + 1) * sizeof *g->start, err);
    cr_status st = bc.chunks && bc.node_vertex && g->start ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        cr_parallel_for(nodes, 64, node_range, &bc);
        cr_parallel_for(nchunks, 1, build_range, &bc);
        int64_t total = 0;
        for (int64_t ch = 0; ch < nchunks; ch++) {
            if (bc.chunks[ch].failed) st = CR_ERR_MEMORY;
            total += bc.chunks[ch].len;
        }
        if (st == CR_OK) {
            g->vertex = cr_malloc((size_t)(total > 0 ? total : 1) * sizeof *g->vertex, err);
            g->pos = cr_malloc((size_t)(total > 0 ? total : 1) * 3 * sizeof *g->pos, err);
            if (!g->vertex || !g->pos) st = CR_ERR_MEMORY;
        }
        int64_t at = 0;
        for (int64_t ch = 0; st == CR_OK && ch < nchunks; ch++) {
            const chunk_out *co = &bc.chunks[ch];
            if (co->len > 0)
                memcpy(g->vertex + at, co->vertex, (size_t)co->len * sizeof *g->vertex);
            for (int64_t c = ch * CHUNK_CELLS, k = at; c < (ch + 1) * CHUNK_CELLS && c < g->cells;
                 c++) {
                g->start[c] = k;
                k += co->count[c - ch * CHUNK_CELLS];
                g->overfull += co->count[c - ch * CHUNK_CELLS] == 0;
            }
            at += co->len;
        }
        if (st == CR_OK) {
            g->start[g->cells] = at;
            for (int64_t k = 0; k < at; k++)
                memcpy(&g->pos[3 * k], &tree->pos[3 * (size_t)g->vertex[k]], 3 * sizeof(float));
        }
    }
    for (int64_t ch = 0; bc.chunks && ch < nchunks; ch++)
        free(bc.chunks[ch].vertex);
    free(bc.chunks);
    free(bc.node_vertex);
    if (st != CR_OK) {
        const long long cells = (long long)g->cells;
        cr_vertex_grid_destroy(g);
        return CR_FAIL(err, st, "vertex grid: out of memory for %lld cells", cells);
    }
    *out = g;
    return CR_OK;
}

/* ------------------------------------------------------------- query -- */

int32_t cr_vertex_grid_nearest(const cr_vertex_grid *g, const float p[3], float *dist) {
    int64_t cell = 0;
    for (int d = 0; d < 3; d++) {
        double t = ((double)p[d] - g->lo[d]) * g->inv_h;
        if (!(t >= 0.0 && t < (double)g->n[d])) goto tree; /* outside, or NaN */
        cell = cell * g->n[d] + (int64_t)t;
    }
    const int64_t s = g->start[cell], e = g->start[cell + 1];
    if (s == e) goto tree;
    double best = INFINITY;
    int64_t at = s;
    for (int64_t k = s; k < e; k++) {
        const float *q = &g->pos[3 * k];
        double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
        double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < best) best = d2, at = k;
    }
    if (dist) *dist = (float)sqrt(best);
    return g->vertex[at];
tree:
    return cr_bvh_nearest_vertex(g->tree, p, INFINITY, dist);
}

void cr_vertex_grid_stats(const cr_vertex_grid *g, int32_t n[3], int64_t *entries,
                          int64_t *overfull) {
    if (n)
        for (int d = 0; d < 3; d++)
            n[d] = g->n[d];
    if (entries) *entries = g->start[g->cells];
    if (overfull) *overfull = g->overfull;
}
