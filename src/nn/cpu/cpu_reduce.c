/* cpu_reduce.c: CPU kernels for sums: over everything, over one axis, the
 * backward spread of an axis sum, and summing a broadcast gradient down to
 * an operand's shape.
 *
 * All sums accumulate in double. Work is split at boundaries that depend
 * only on the sizes (never on the thread count), and each output is summed
 * by one thread in a fixed order, so results are bit-reproducible.
 * Leaves out: pairwise/Kahan summation (double accumulators are enough for
 * float inputs).
 */
#include "nn/cpu/cpu.h"

#include <string.h>

enum {
    SUM_MAX_BLOCKS = 64, /* blocks of a whole-tensor sum */
    COL_BLOCK = 64,      /* columns summed together with double accumulators */
};

/* ---------------------------------------------------------- sum (all) -- */

typedef struct sum_all_args {
    const float *x;
    int64_t n, blocks;
    double partial[SUM_MAX_BLOCKS];
} sum_all_args;

static void sum_all_range(void *vctx, int64_t begin, int64_t end) {
    sum_all_args *s = vctx;
    for (int64_t blk = begin; blk < end; blk++) {
        int64_t i0 = s->n * blk / s->blocks, i1 = s->n * (blk + 1) / s->blocks;
        /* Four accumulators hide the add latency; the order is still fixed. */
        double acc[4] = {0, 0, 0, 0};
        int64_t i = i0;
        for (; i + 4 <= i1; i += 4)
            for (int k = 0; k < 4; k++)
                acc[k] += s->x[i + k];
        for (; i < i1; i++)
            acc[0] += s->x[i];
        s->partial[blk] = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
}

double cr_nn_cpu_sum_all(const float *x, int64_t n) {
    sum_all_args s;
    s.x = x;
    s.n = n;
    s.blocks = (n + NN_CPU_GRAIN - 1) / NN_CPU_GRAIN;
    if (s.blocks < 1) s.blocks = 1;
    if (s.blocks > SUM_MAX_BLOCKS) s.blocks = SUM_MAX_BLOCKS;
    cr_parallel_for(s.blocks, 1, sum_all_range, &s);
    double total = 0.0;
    for (int64_t b = 0; b < s.blocks; b++)
        total += s.partial[b];
    return total;
}

/* ---------------------------------------------------------- sum (axis) -- */

typedef struct axis_args {
    const float *x;
    float *y;
    int64_t outer, len, inner, col_blocks;
    float scale;
    int acc;
} axis_args;

/* One unit = one outer index x one block of up to COL_BLOCK inner columns. */
static void sum_axis_range(void *vctx, int64_t begin, int64_t end) {
    const axis_args *g = vctx;
    for (int64_t u = begin; u < end; u++) {
        int64_t o = u / g->col_blocks, c0 = (u % g->col_blocks) * COL_BLOCK;
        int64_t w = g->inner - c0 < COL_BLOCK ? g->inner - c0 : COL_BLOCK;
        double acc[COL_BLOCK];
        for (int64_t c = 0; c < w; c++)
            acc[c] = 0.0;
        const float *base = g->x + o * g->len * g->inner + c0;
        for (int64_t l = 0; l < g->len; l++) {
            const float *row = base + l * g->inner;
            for (int64_t c = 0; c < w; c++)
                acc[c] += row[c];
        }
        float *yo = g->y + o * g->inner + c0;
        for (int64_t c = 0; c < w; c++) {
            float v = (float)(g->scale * acc[c]);
            yo[c] = g->acc ? yo[c] + v : v;
        }
    }
}

void cr_nn_cpu_sum_axis(const float *x, int64_t outer, int64_t len, int64_t inner, float scale,
                        float *y, int acc) {
    if (inner == 0 || outer == 0) return;
    axis_args g = {x, y, outer, len, inner, (inner + COL_BLOCK - 1) / COL_BLOCK, scale, acc};
    int64_t work = len * (inner < COL_BLOCK ? inner : COL_BLOCK);
    int64_t grain = work >= NN_CPU_GRAIN ? 1 : NN_CPU_GRAIN / (work > 0 ? work : 1);
    cr_parallel_for(outer * g.col_blocks, grain, sum_axis_range, &g);
}

static void expand_range(void *vctx, int64_t begin, int64_t end) {
    const axis_args *g = vctx;
    for (int64_t r = begin; r < end; r++) {
        int64_t o = r / g->len;
        const float *src = g->x + o * g->inner;
        float *dst = g->y + r * g->inner;
        for (int64_t c = 0; c < g->inner; c++)
            dst[c] += g->scale * src[c];
    }
}

void cr_nn_cpu_expand_axis_acc(const float *dy, int64_t outer, int64_t len, int64_t inner,
                               float scale, float *dx) {
    axis_args g = {dy, dx, outer, len, inner, 0, scale, 1};
    cr_parallel_for(outer * len, nn_cpu_row_grain(inner), expand_range, &g);
}

/* ------------------------------------------------ reduce to a shape -- */

typedef struct shape_args {
    const float *src;
    float *dst;
    int64_t ys[4], ds[4];
} shape_args;

/* Each destination element sums its preimage (a box in the source). */
static void reduce_shape_range(void *vctx, int64_t begin, int64_t end) {
    const shape_args *g = vctx;
    const int64_t *ys = g->ys, *ds = g->ds;
    for (int64_t j = begin; j < end; j++) {
        int64_t idx[4], lo[4], hi[4], t = j;
        for (int k = 3; k >= 0; k--) {
            idx[k] = t % ds[k];
            t /= ds[k];
            lo[k] = ds[k] == ys[k] ? idx[k] : 0;
            hi[k] = ds[k] == ys[k] ? idx[k] + 1 : ys[k];
        }
        double s = 0.0;
        for (int64_t i0 = lo[0]; i0 < hi[0]; i0++)
            for (int64_t i1 = lo[1]; i1 < hi[1]; i1++)
                for (int64_t i2 = lo[2]; i2 < hi[2]; i2++) {
                    const float *row = g->src + ((i0 * ys[1] + i1) * ys[2] + i2) * ys[3];
                    for (int64_t i3 = lo[3]; i3 < hi[3]; i3++)
                        s += row[i3];
                }
        g->dst[j] += (float)s;
    }
}

void cr_nn_cpu_reduce_to_shape_acc(const float *src, const int64_t ys[4], float *dst,
                                   const int64_t ds[4]) {
    /* Common layouts go through the blocked axis sum:
     * leading axes reduced ((N,C) -> (C)) or trailing ((N,C) -> (N,1)). */
    for (int k = 0; k <= 4; k++) {
        int leading = 1, trailing = 1;
        int64_t before = 1, after = 1;
        for (int i = 0; i < 4; i++) {
            if (i < k) {
                leading &= ds[i] == 1;
                trailing &= ds[i] == ys[i];
                before *= ys[i];
            } else {
                leading &= ds[i] == ys[i];
                trailing &= ds[i] == 1;
                after *= ys[i];
            }
        }
        if (leading) {
            cr_nn_cpu_sum_axis(src, 1, before, after, 1.0f, dst, 1);
            return;
        }
        if (trailing) {
            cr_nn_cpu_sum_axis(src, before, after, 1, 1.0f, dst, 1);
            return;
        }
    }
    shape_args g;
    g.src = src;
    g.dst = dst;
    memcpy(g.ys, ys, sizeof g.ys);
    memcpy(g.ds, ds, sizeof g.ds);
    int64_t n = ds[0] * ds[1] * ds[2] * ds[3];
    int64_t per = n > 0 ? (ys[0] * ys[1] * ys[2] * ys[3]) / n : 1;
    cr_parallel_for(n, per >= NN_CPU_GRAIN ? 1 : NN_CPU_GRAIN / (per > 0 ? per : 1),
                    reduce_shape_range, &g);
}
