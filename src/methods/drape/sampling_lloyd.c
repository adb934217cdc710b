/* sampling_lloyd.c: Lloyd relaxation of the drape sampler's points (Eq. 13 of
 * Shu et al., "Spatially Adaptive Cloth Regression with Implicit Neural
 * Representations"): each point moves to the centroid of its Voronoi region,
 * the centroid being the weighted mean of the dense points nearest to it.
 *
 * Voronoi regions come from nearest-sample queries, one per dense point per
 * iteration, through two grids of buckets over the samples:
 *   fine    R_f buckets a side, sized so a query sees about BUCKET_OCCUPANCY
 *           samples a bucket on average; a dense point first looks at the
 *           3 x 3 fine buckets around its own, all points of one bucket
 *           together (a vectorised loop), and the answer stands when it is
 *           nearer than the edge of that block;
 *   coarse  R_f / ratio buckets a side, sized for the sparsest cells, for the
 *           rest: rings of coarse buckets outwards until the next ring cannot
 *           hold anything nearer, looking into the fine buckets of crowded
 *           coarse ones.
 * A flat PDF gives ratio 1; a PDF piled into a few cells gives fine buckets
 * for the pile and coarse ones for the rest, so neither scan is long.
 *
 * Leaves out: exact Voronoi cells (the dense points sample them), any
 * stopping test (the iteration count is fixed), points outside [0,1)^2.
 * References: Lloyd, "Least squares quantization in PCM", IEEE Trans. Inf.
 * Theory 28(2), 1982; Du, Faber & Gunzburger, "Centroidal Voronoi
 * tessellations", SIAM Review 41(4), 1999 (point density ~ rho^(d/(d+2))).
 *
 * n: samples; M: dense points, n * density; G: PDF cells per side.
 */
#include "sampling_lloyd.h"

#include <stdlib.h>
#include <string.h>

/* Fine buckets: at most 1024^2 (4 MiB of starts per grid), enough for 20k
 * samples piled into one PDF cell of 64^2. A query sees about
 * BUCKET_OCCUPANCY samples per bucket: 3 was fastest of 1, 2 and 3 for 20k
 * points on a flat PDF and on a Gaussian bump. */
enum { BUCKET_MAX_SIDE = 1024 };
static const double BUCKET_OCCUPANCY = 3.0;
/* Dense points of one fine bucket handled together: the vectorised loop's
 * fixed trip count. */
enum { QUERY_CHUNK = 16 };
/* A coarse bucket holding more samples than this is searched through its fine buckets. */
enum { DESCEND_COUNT = 24 };
/* Buckets per parallel chunk: a bucket holds a few samples and their dense
 * points, so a few dozen buckets already cost more than a thread start. */
enum { BUCKET_GRAIN = 16, DENSE_CELL_GRAIN = 64 };
/* Slack on pruning distances (UV units), far above float rounding of the
 * bucket edges (~1e-7) and far below any spacing Lloyd cares about. */
static const float PRUNE_SLACK = 1e-6f;

static void grid_free(drape_bucket_grid *g) {
    free(g->start);
    free(g->x);
    free(g->y);
    free(g->id);
    memset(g, 0, sizeof *g);
}

void cr_drape_lloyd_free(drape_lloyd *L) {
    if (!L) return;
    grid_free(&L->fine);
    grid_free(&L->coarse);
    grid_free(&L->dense);
    free(L->drawn);
    free(L->assign);
    free(L->scratch);
    free(L->acc);
    free(L->first);
    free(L->cell_w);
    memset(L, 0, sizeof *L);
}

static cr_status grid_points(drape_bucket_grid *g, int64_t count, int with_id, cr_error *err) {
    free(g->x), free(g->y), free(g->id);
    g->x = cr_malloc((size_t)count * sizeof(float), err);
    g->y = cr_malloc((size_t)count * sizeof(float), err);
    g->id = with_id ? cr_malloc((size_t)count * sizeof(int32_t), err) : NULL;
    return g->x && g->y && (!with_id || g->id) ? CR_OK : CR_ERR_MEMORY;
}

static cr_status grid_side(drape_bucket_grid *g, int32_t R, cr_error *err) {
    g->R = R;
    g->h = 1.0f / (float)R;
    int64_t nb = (int64_t)R * R + 1;
    if (nb <= g->cap_b) return CR_OK;
    free(g->start);
    g->start = cr_malloc((size_t)nb * sizeof(int32_t), err);
    g->cap_b = g->start ? nb : 0;
    return g->start ? CR_OK : CR_ERR_MEMORY;
}

static cr_status reserve(drape_lloyd *L, int32_t n, int64_t m, int64_t cells, cr_error *err) {
    if (n > L->cap_n || m > L->cap_m) {
        L->cap_n = L->cap_m = 0;
        free(L->drawn), free(L->assign), free(L->scratch), free(L->acc);
        L->drawn = cr_malloc((size_t)m * 2 * sizeof(float), err);
        L->assign = cr_malloc((size_t)m * sizeof(int32_t), err);
        L->scratch = cr_malloc((size_t)(m > n ? m : n) * sizeof(int32_t), err);
        L->acc = cr_malloc((size_t)n * 3 * sizeof(double), err);
        if (!L->drawn || !L->assign || !L->scratch || !L->acc) return CR_ERR_MEMORY;
        CR_TRY(grid_points(&L->fine, n, 1, err));
        CR_TRY(grid_points(&L->coarse, n, 1, err));
        CR_TRY(grid_points(&L->dense, m, 0, err));
        L->cap_n = n, L->cap_m = m;
    }
    if (cells > L->cap_cells) {
        L->cap_cells = 0;
        free(L->first), free(L->cell_w);
        L->first = cr_malloc((size_t)(cells + 1) * sizeof(int64_t), err);
        L->cell_w = cr_malloc((size_t)cells * sizeof(double), err);
        if (!L->first || !L->cell_w) return CR_ERR_MEMORY;
        L->cap_cells = cells;
    }
    return CR_OK;
}

/* ----------------------------------------------------------------- buckets -- */

static int32_t bucket_of(float x, int32_t R) {
    int32_t b = (int32_t)(x * (float)R);
    return b < 0 ? 0 : (b >= R ? R - 1 : b);
}

static int32_t clamp_side(double r) {
    return r < 1.0 ? 1 : (r > BUCKET_MAX_SIDE ? BUCKET_MAX_SIDE : (int32_t)lrint(r));
}

/* Sides of both grids for n samples following the cell masses rho (G*G, sum
 * 1; the dense points follow it too). Fine: a query lands in cell c with
 * probability rho_c and sees n rho_c G^2 / R^2 samples a bucket there, so
 * R_f^2 = n G^2 sum(rho^2) / BUCKET_OCCUPANCY makes the average that.
 * Coarse: the same occupancy in the sparsest cell with mass. */
static void choose_sides(const double *rho, int32_t G, int32_t n, int32_t *fine, int32_t *ratio) {
    double s2 = 0.0, lo = INFINITY, cells = (double)G * G;
    for (int64_t c = 0; c < (int64_t)G * G; c++) {
        s2 += rho[c] * rho[c];
        if (rho[c] > 0.0 && rho[c] < lo) lo = rho[c];
    }
    int32_t rf = clamp_side(sqrt((double)n * cells * s2 / BUCKET_OCCUPANCY));
    int32_t rc = clamp_side(sqrt((double)n * cells * lo / BUCKET_OCCUPANCY));
    if (rc > rf) rc = rf;
    *ratio = rf / rc;
    *fine = *ratio * rc;
}

/* Stable counting sort of `count` points into g's buckets; bucket[k] gets
 * point k's bucket on the way (or, when `from_fine` is not 0, already holds
 * its fine bucket and the coarse one is derived from it, so every coarse
 * bucket is exactly the union of ratio x ratio fine ones). */
static void grid_fill(drape_bucket_grid *g, const float *pts, int64_t count, int32_t *bucket,
                      int32_t from_fine_side, int32_t ratio) {
    int32_t R = g->R;
    int64_t nb = (int64_t)R * R;
    int32_t *start = g->start;
    memset(start, 0, (size_t)(nb + 1) * sizeof(int32_t));
    for (int64_t k = 0; k < count; k++) {
        int32_t b;
        if (from_fine_side) {
            int32_t f = bucket[k];
            b = (f / from_fine_side / ratio) * R + (f % from_fine_side) / ratio;
        } else {
            b = bucket_of(pts[2 * k + 1], R) * R + bucket_of(pts[2 * k], R);
            bucket[k] = b;
        }
        start[b + 1]++;
    }
    for (int64_t b = 0; b < nb; b++)
        start[b + 1] += start[b];
    for (int64_t k = 0; k < count; k++) {
        int32_t f = bucket[k];
        int32_t b =
            from_fine_side ? (f / from_fine_side / ratio) * R + (f % from_fine_side) / ratio : f;
        int32_t slot = start[b]++;
        g->x[slot] = pts[2 * k];
        g->y[slot] = pts[2 * k + 1];
        if (g->id) g->id[slot] = (int32_t)k;
    }
    for (int64_t b = nb; b > 0; b--) /* start[b] now ends bucket b: shift back */
        start[b] = start[b - 1];
    start[0] = 0;
}

/* ------------------------------------------------------------------ queries -- */

static inline float min_f(float a, float b) {
    return a < b ? a : b;
}

/* Distance from x to the interval [lo, hi], 0 inside. */
static inline float gap_to(float x, float lo, float hi) {
    return x < lo ? lo - x : (x > hi ? x - hi : 0.0f);
}

/* Nothing `gap` or more away can beat best_d2. */
static inline int pruned(float gap, float best_d2) {
    gap -= PRUNE_SLACK;
    return gap > 0.0f && gap * gap >= best_d2;
}

/* Box [x0,x1] x [y0,y1] too far from q to hold anything nearer than best_d2. */
static inline int box_pruned(float qx, float qy, float x0, float x1, float y0, float y1,
                             float best_d2) {
    float gx = gap_to(qx, x0, x1), gy = gap_to(qy, y0, y1);
    return pruned(sqrtf(gx * gx + gy * gy), best_d2);
}

static void scan_slots(const drape_bucket_grid *g, int32_t k0, int32_t k1, float qx, float qy,
                       float *best_d2, int32_t *best) {
    for (int32_t k = k0; k < k1; k++) {
        float dx = qx - g->x[k], dy = qy - g->y[k], d2 = dx * dx + dy * dy;
        if (d2 < *best_d2) *best_d2 = d2, *best = g->id[k];
    }
}

/* Coarse bucket (X, Y): its samples directly, or through its fine buckets
 * when it is crowded, each skipped when too far. */
static void visit_coarse(const drape_lloyd *L, int32_t X, int32_t Y, float qx, float qy,
                         float *best_d2, int32_t *best) {
    const drape_bucket_grid *c = &L->coarse, *f = &L->fine;
    if (box_pruned(qx, qy, X * c->h, (X + 1) * c->h, Y * c->h, (Y + 1) * c->h, *best_d2)) return;
    int64_t b = (int64_t)Y * c->R + X;
    int32_t k0 = c->start[b], k1 = c->start[b + 1];
    if (L->ratio == 1 || k1 - k0 <= DESCEND_COUNT) {
        scan_slots(c, k0, k1, qx, qy, best_d2, best);
        return;
    }
    int32_t s = L->ratio;
    for (int32_t y = Y * s; y < (Y + 1) * s; y++)
        for (int32_t x = X * s; x < (X + 1) * s; x++) {
            if (box_pruned(qx, qy, x * f->h, (x + 1) * f->h, y * f->h, (y + 1) * f->h, *best_d2))
                continue;
            int64_t fb = (int64_t)y * f->R + x;
            scan_slots(f, f->start[fb], f->start[fb + 1], qx, qy, best_d2, best);
        }
}

/* Nearest sample to q, improving on (*best_d2, *best): rings of coarse
 * buckets around q's, outwards, until the next ring cannot hold anything
 * nearer. Ties keep the first found in a fixed order: deterministic. */
static void ring_nearest(const drape_lloyd *L, float qx, float qy, float *best_d2, int32_t *best) {
    const drape_bucket_grid *c = &L->coarse;
    int32_t R = c->R;
    float h = c->h;
    int32_t bx = bucket_of(qx, L->fine.R) / L->ratio, by = bucket_of(qy, L->fine.R) / L->ratio;
    for (int32_t r = 0;; r++) {
        if (r > 0) {
            /* The nearest any bucket of ring r can be: its inner edge, on the
             * nearest of the sides that lie inside the grid. */
            float gap = INFINITY;
            if (bx - r >= 0) gap = min_f(gap, qx - (float)(bx - r + 1) * h);
            if (bx + r < R) gap = min_f(gap, (float)(bx + r) * h - qx);
            if (by - r >= 0) gap = min_f(gap, qy - (float)(by - r + 1) * h);
            if (by + r < R) gap = min_f(gap, (float)(by + r) * h - qy);
            if (gap == INFINITY || pruned(gap, *best_d2)) return;
        }
        int32_t y0 = by - r > 0 ? by - r : 0, y1 = by + r < R - 1 ? by + r : R - 1;
        int32_t x0 = bx - r > 0 ? bx - r : 0, x1 = bx + r < R - 1 ? bx + r : R - 1;
        for (int32_t y = y0; y <= y1; y++) {
            if (y == by - r || y == by + r) { /* a full row of the ring */
                for (int32_t x = x0; x <= x1; x++)
                    visit_coarse(L, x, y, qx, qy, best_d2, best);
            } else { /* only the ring's two sides */
                if (bx - r >= 0) visit_coarse(L, bx - r, y, qx, qy, best_d2, best);
                if (r > 0 && bx + r < R) visit_coarse(L, bx + r, y, qx, qy, best_d2, best);
            }
        }
    }
}

/* Nearest of the samples in fine slots [k0, k1) for each of QUERY_CHUNK
 * queries, improving on (best_d2, best). Queries run innermost over a fixed
 * count with a branch-free update, so the compiler vectorises the loop;
 * candidates go in slot order and only a strictly nearer one wins. */
static void scan_block(const drape_bucket_grid *g, int32_t k0, int32_t k1, const float *restrict qx,
                       const float *restrict qy, float *restrict best_d2, int32_t *restrict best) {
    for (int32_t k = k0; k < k1; k++) {
        float cx = g->x[k], cy = g->y[k];
        int32_t id = g->id[k];
        for (int32_t i = 0; i < QUERY_CHUNK; i++) {
            float dx = qx[i] - cx, dy = qy[i] - cy, d2 = dx * dx + dy * dy;
            int32_t nearer = -(int32_t)(d2 < best_d2[i]); /* all ones or zero */
            best_d2[i] = d2 < best_d2[i] ? d2 : best_d2[i];
            best[i] = (id & nearer) | (best[i] & ~nearer);
        }
    }
}

/* The nearest sample of every dense point in fine buckets [begin, end):
 * first among the samples of the 3 x 3 fine block around the point's bucket
 * (three runs of contiguous slots, shared by all the bucket's points); that
 * answer stands when it is nearer than the block's edge, else the coarse
 * rings settle it. */
static void assign_range(void *vctx, int64_t begin, int64_t end) {
    drape_lloyd *L = vctx;
    const drape_bucket_grid *f = &L->fine, *d = &L->dense;
    int32_t R = f->R;
    float h = f->h;
    float qx[QUERY_CHUNK], qy[QUERY_CHUNK], best_d2[QUERY_CHUNK];
    int32_t best[QUERY_CHUNK];
    for (int64_t b = begin; b < end; b++) {
        int32_t bx = (int32_t)(b % R), by = (int32_t)(b / R);
        int32_t x0 = bx > 0 ? bx - 1 : 0, x1 = bx < R - 1 ? bx + 1 : R - 1;
        int32_t y0 = by > 0 ? by - 1 : 0, y1 = by < R - 1 ? by + 1 : R - 1;
        /* Block edges; a side on the grid's border has nothing beyond it. */
        float lo_x = bx > 0 ? (float)x0 * h : -INFINITY;
        float hi_x = bx < R - 1 ? (float)(x1 + 1) * h : INFINITY;
        float lo_y = by > 0 ? (float)y0 * h : -INFINITY;
        float hi_y = by < R - 1 ? (float)(y1 + 1) * h : INFINITY;
        for (int32_t d0 = d->start[b]; d0 < d->start[b + 1]; d0 += QUERY_CHUNK) {
            int32_t count = d->start[b + 1] - d0;
            if (count > QUERY_CHUNK) count = QUERY_CHUNK;
            for (int32_t i = 0; i < QUERY_CHUNK; i++) { /* a short chunk repeats its last point */
                int32_t k = d0 + (i < count ? i : count - 1);
                qx[i] = d->x[k], qy[i] = d->y[k];
                best_d2[i] = INFINITY, best[i] = -1;
            }
            for (int32_t y = y0; y <= y1; y++)
                scan_block(f, f->start[(int64_t)y * R + x0], f->start[(int64_t)y * R + x1 + 1], qx,
                           qy, best_d2, best);
            for (int32_t i = 0; i < count; i++) {
                float gap =
                    min_f(min_f(qx[i] - lo_x, hi_x - qx[i]), min_f(qy[i] - lo_y, hi_y - qy[i]));
                if (best[i] < 0 || (gap != INFINITY && !pruned(gap, best_d2[i])))
                    ring_nearest(L, qx[i], qy[i], &best_d2[i], &best[i]);
                L->assign[d0 + i] = best[i];
            }
        }
    }
}

/* -------------------------------------------------------------- dense draw -- */

typedef struct dense_ctx {
    const int64_t *first;
    int32_t G;
    uint64_t key, stream;
    float *uv; /* (M,2) */
} dense_ctx;

static void dense_range(void *vctx, int64_t begin, int64_t end) {
    const dense_ctx *c = vctx;
    for (int64_t cell = begin; cell < end; cell++) {
        int32_t i = (int32_t)(cell / c->G), j = (int32_t)(cell % c->G);
        for (int64_t k = c->first[cell]; k < c->first[cell + 1]; k++) {
            uint32_t w[4];
            cr_philox4x32(c->key, c->stream, (uint64_t)k, w);
            c->uv[2 * k] = drape_cell_coord(j, (float)(w[0] >> 8) * 0x1p-24f, c->G);
            c->uv[2 * k + 1] = drape_cell_coord(i, (float)(w[1] >> 8) * 0x1p-24f, c->G);
        }
    }
}

/* m dense points of the cell masses rho (G*G, sum 1), stratified: cell c
 * gets round(m CDF_c) - round(m CDF_{c-1}) of them, uniform within it, so
 * their spread over the cells carries no sampling noise. */
static void draw_dense(drape_lloyd *L, const double *rho, int32_t G, int64_t m, uint64_t key,
                       uint64_t stream) {
    int64_t cells = (int64_t)G * G;
    double cum = 0.0;
    L->first[0] = 0;
    for (int64_t c = 0; c < cells; c++) {
        cum += rho[c];
        int64_t e = llround(cum * (double)m);
        L->first[c + 1] = e < L->first[c] ? L->first[c] : (e > m ? m : e);
    }
    L->first[cells] = m;
    dense_ctx ctx = {L->first, G, key, stream, L->drawn};
    cr_parallel_for(cells, DENSE_CELL_GRAIN, dense_range, &ctx);
}

/* ------------------------------------------------------------------- relax -- */

cr_status cr_drape_lloyd_relax(drape_lloyd *L, float *uv, int32_t n, int32_t density, int32_t iters,
                               const double *rho, double exponent, const uint8_t *mask, int32_t G,
                               uint64_t key, uint64_t stream, cr_error *err) {
    CR_ASSERT(L && uv && rho && mask && n >= 1 && density >= 1 && iters >= 1 && G >= 1);
    int64_t m = (int64_t)n * density, cells = (int64_t)G * G;
    CR_ASSERT(m <= INT32_MAX);
    CR_TRY(reserve(L, n, m, cells, err));
    int32_t rf, ratio;
    choose_sides(rho, G, n, &rf, &ratio);
    L->ratio = ratio;
    CR_TRY(grid_side(&L->fine, rf, err));
    CR_TRY(grid_side(&L->dense, rf, err));
    CR_TRY(grid_side(&L->coarse, rf / ratio, err));

    /* Dense points from rho, about `density` in every Voronoi region, each
     * weighted by rho^(exponent - 1) so that the centroids are those of the
     * density rho^exponent. */
    for (int64_t c = 0; c < cells; c++)
        L->cell_w[c] = rho[c] > 0.0 ? pow(rho[c], exponent - 1.0) : 0.0;
    draw_dense(L, rho, G, m, key, stream);
    grid_fill(&L->dense, L->drawn, m, L->scratch, 0, 1);

    const float below_one = nextafterf(1.0f, 0.0f);
    for (int32_t it = 0; it < iters; it++) {
        grid_fill(&L->fine, uv, n, L->scratch, 0, 1);
        grid_fill(&L->coarse, uv, n, L->scratch, rf, ratio);
        cr_parallel_for((int64_t)rf * rf, BUCKET_GRAIN, assign_range, L);
        /* Serially, in dense-grid order and in double, so the sums do not
         * depend on the thread count. */
        memset(L->acc, 0, (size_t)n * 3 * sizeof(double));
        for (int64_t k = 0; k < m; k++) {
            float x = L->dense.x[k], y = L->dense.y[k];
            double w = L->cell_w[(int64_t)drape_cell_index(y, G) * G + drape_cell_index(x, G)];
            double *a = L->acc + 3 * (int64_t)L->assign[k];
            a[0] += w * x;
            a[1] += w * y;
            a[2] += w;
        }
        /* Eq. 13. A sample whose region holds no dense point, or whose
         * centroid falls in a cell outside the mask (possible only for a
         * non-convex chart), stays put. */
        for (int32_t i = 0; i < n; i++) {
            const double *a = L->acc + 3 * (int64_t)i;
            if (a[2] == 0.0) continue;
            float u = min_f((float)(a[0] / a[2]), below_one);
            float v = min_f((float)(a[1] / a[2]), below_one);
            if (!mask[(int64_t)drape_cell_index(v, G) * G + drape_cell_index(u, G)]) continue;
            uv[2 * i] = u;
            uv[2 * i + 1] = v;
        }
    }
    return CR_OK;
}
