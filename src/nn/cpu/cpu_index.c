/* cpu_index.c: CPU kernels for block copies, row gathers and scatters,
 * grouping positions by target (counting sort), segment sums and segment
 * softmax.
 *
 * Many-to-one reductions (scatter-add, gather backward, softmax sums) never
 * race: positions are first grouped by target row with a stable counting
 * sort, then each thread owns whole targets and sums their rows in position
 * order, in double, so results are deterministic whatever the thread count.
 * Leaves out: atomics, sorted-input fast paths.
 */
#include "nn/cpu/cpu.h"

#include <math.h>

enum { COL_BLOCK = 64 }; /* columns accumulated together in double */

/* -------------------------------------------------------------- copy2d -- */

typedef struct copy2d_args {
    const float *src;
    float *dst;
    int64_t src_stride, dst_stride, cols;
    int acc;
} copy2d_args;

static void copy2d_range(void *vctx, int64_t begin, int64_t end) {
    const copy2d_args *g = vctx;
    for (int64_t r = begin; r < end; r++) {
        const float *s = g->src + r * g->src_stride;
        float *d = g->dst + r * g->dst_stride;
        if (g->acc)
            for (int64_t c = 0; c < g->cols; c++)
                d[c] += s[c];
        else
            for (int64_t c = 0; c < g->cols; c++)
                d[c] = s[c];
    }
}

void cr_nn_cpu_copy2d(const float *src, int64_t src_stride, float *dst, int64_t dst_stride,
                      int64_t rows, int64_t cols, int acc) {
    copy2d_args g = {src, dst, src_stride, dst_stride, cols, acc};
    cr_parallel_for(rows, nn_cpu_row_grain(cols), copy2d_range, &g);
}

/* ------------------------------------------------------ gather/scatter -- */

typedef struct rows_args {
    const float *x;
    float *y;
    const int32_t *idx;
    int64_t C;
    int acc, scatter;
} rows_args;

static void rows_range(void *vctx, int64_t begin, int64_t end) {
    const rows_args *g = vctx;
    int64_t C = g->C;
    for (int64_t i = begin; i < end; i++) {
        const float *s = g->scatter ? g->x + i * C : g->x + (int64_t)g->idx[i] * C;
        float *d = g->scatter ? g->y + (int64_t)g->idx[i] * C : g->y + i * C;
        if (g->acc)
            for (int64_t c = 0; c < C; c++)
                d[c] += s[c];
        else
            for (int64_t c = 0; c < C; c++)
                d[c] = s[c];
    }
}

void cr_nn_cpu_gather_rows(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                           int acc) {
    rows_args g = {x, y, idx, C, acc, 0};
    cr_parallel_for(n, nn_cpu_row_grain(C), rows_range, &g);
}

void cr_nn_cpu_scatter_rows(const float *x, int64_t C, const int32_t *idx, int64_t n, float *y,
                            int acc) {
    rows_args g = {x, y, idx, C, acc, 1};
    cr_parallel_for(n, nn_cpu_row_grain(C), rows_range, &g);
}

int64_t cr_nn_cpu_index_check(const int32_t *idx, int64_t n, int64_t limit) {
    for (int64_t i = 0; i < n; i++)
        if (idx[i] < 0 || idx[i] >= limit) return i;
    return -1;
}

void cr_nn_cpu_csr_build(const int32_t *idx, int64_t n, int64_t nb, int64_t *off, int32_t *perm) {
    for (int64_t b = 0; b <= nb; b++)
        off[b] = 0;
    for (int64_t i = 0; i < n; i++)
        off[idx[i] + 1]++;
    for (int64_t b = 0; b < nb; b++)
        off[b + 1] += off[b];
    /* Place with off[b] as a cursor (it ends at the next bucket's start),
     * then shift the offsets back by one bucket. */
    for (int64_t i = 0; i < n; i++)
        perm[off[idx[i]]++] = (int32_t)i;
    for (int64_t b = nb; b > 0; b--)
        off[b] = off[b - 1];
    off[0] = 0;
}

/* ------------------------------------------------------------ segments -- */

typedef struct seg_args {
    const float *x, *y, *dy;
    float *out;
    const int64_t *off;
    const int32_t *perm;
    int64_t C;
    int acc;
} seg_args;

static void segment_sum_range(void *vctx, int64_t begin, int64_t end) {
    const seg_args *g = vctx;
    int64_t C = g->C;
    for (int64_t s = begin; s < end; s++) {
        for (int64_t c0 = 0; c0 < C; c0 += COL_BLOCK) {
            int64_t w = C - c0 < COL_BLOCK ? C - c0 : COL_BLOCK;
            double acc[COL_BLOCK];
            for (int64_t c = 0; c < w; c++)
                acc[c] = 0.0;
            for (int64_t j = g->off[s]; j < g->off[s + 1]; j++) {
                const float *row = g->x + (int64_t)g->perm[j] * C + c0;
                for (int64_t c = 0; c < w; c++)
                    acc[c] += row[c];
            }
            float *d = g->out + s * C + c0;
            for (int64_t c = 0; c < w; c++)
                d[c] = g->acc ? d[c] + (float)acc[c] : (float)acc[c];
        }
    }
}

/* Segments per chunk: aim at NN_CPU_GRAIN elements for the average segment. */
static int64_t segment_grain(const int64_t *off, int64_t nseg, int64_t C) {
    int64_t per = nseg > 0 ? off[nseg] / nseg : 1;
    return nn_cpu_row_grain((per > 0 ? per : 1) * C);
}

void cr_nn_cpu_segment_sum_rows(const float *x, int64_t C, const int64_t *off, const int32_t *perm,
                                int64_t nseg, float *y, int acc) {
    seg_args g = {x, NULL, NULL, y, off, perm, C, acc};
    cr_parallel_for(nseg, segment_grain(off, nseg, C), segment_sum_range, &g);
}

static void softmax_forward_range(void *vctx, int64_t begin, int64_t end) {
    const seg_args *g = vctx;
    int64_t H = g->C;
    for (int64_t s = begin; s < end; s++) {
        int64_t j0 = g->off[s], j1 = g->off[s + 1];
        for (int64_t c0 = 0; c0 < H; c0 += COL_BLOCK) {
            int64_t w = H - c0 < COL_BLOCK ? H - c0 : COL_BLOCK;
            float mx[COL_BLOCK];
            double sum[COL_BLOCK];
            for (int64_t c = 0; c < w; c++)
                mx[c] = -INFINITY, sum[c] = 0.0;
            for (int64_t j = j0; j < j1; j++) {
                const float *row = g->x + (int64_t)g->perm[j] * H + c0;
                for (int64_t c = 0; c < w; c++)
                    mx[c] = row[c] > mx[c] ? row[c] : mx[c];
            }
            for (int64_t j = j0; j < j1; j++) {
                int64_t r = (int64_t)g->perm[j] * H + c0;
                for (int64_t c = 0; c < w; c++) {
                    float e = expf(g->x[r + c] - mx[c]);
                    g->out[r + c] = e;
                    sum[c] += e;
                }
            }
            for (int64_t j = j0; j < j1; j++) {
                float *row = g->out + (int64_t)g->perm[j] * H + c0;
                for (int64_t c = 0; c < w; c++)
                    row[c] = (float)(row[c] / sum[c]);
            }
        }
    }
}

/* dx = y (dy - sum_seg(y dy)) */
static void softmax_backward_range(void *vctx, int64_t begin, int64_t end) {
    const seg_args *g = vctx;
    int64_t H = g->C;
    for (int64_t s = begin; s < end; s++) {
        int64_t j0 = g->off[s], j1 = g->off[s + 1];
        for (int64_t c0 = 0; c0 < H; c0 += COL_BLOCK) {
            int64_t w = H - c0 < COL_BLOCK ? H - c0 : COL_BLOCK;
            double dot[COL_BLOCK];
            for (int64_t c = 0; c < w; c++)
                dot[c] = 0.0;
            for (int64_t j = j0; j < j1; j++) {
                int64_t r = (int64_t)g->perm[j] * H + c0;
                for (int64_t c = 0; c < w; c++)
                    dot[c] += (double)g->y[r + c] * g->dy[r + c];
            }
            for (int64_t j = j0; j < j1; j++) {
                int64_t r = (int64_t)g->perm[j] * H + c0;
                for (int64_t c = 0; c < w; c++)
                    g->out[r + c] += g->y[r + c] * (float)(g->dy[r + c] - dot[c]);
            }
        }
    }
}

void cr_nn_cpu_segment_softmax_forward(const float *x, int64_t H, const int64_t *off,
                                       const int32_t *perm, int64_t nseg, float *y) {
    seg_args g = {x, NULL, NULL, y, off, perm, H, 0};
    cr_parallel_for(nseg, segment_grain(off, nseg, H), softmax_forward_range, &g);
}

void cr_nn_cpu_segment_softmax_backward(const float *y, const float *dy, int64_t H,
                                        const int64_t *off, const int32_t *perm, int64_t nseg,
                                        float *dx) {
    seg_args g = {NULL, y, dy, dx, off, perm, H, 1};
    cr_parallel_for(nseg, segment_grain(off, nseg, H), softmax_backward_range, &g);
}
