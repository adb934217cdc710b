/* cpu_vector.c: CPU kernels for row-wise ops over rows of C floats: layer
 * norm, cross product (C = 3), dot product, norm and normalisation.
 *
 * Rows are independent, so forward and input-gradient kernels split rows
 * across threads. Layer norm's weight and bias gradients sum over rows; they
 * split columns instead (blocks of COL_BLOCK with double accumulators), so no
 * two threads write the same output. Formulas are in ops_vector.c.
 * Leaves out: fused layer-norm + linear.
 */
#include "nn/cpu/cpu.h"

#include <math.h>

enum { COL_BLOCK = 64 };

typedef struct vec_args {
    const float *a, *b, *dy, *w, *bias, *mean, *rstd, *y;
    float *out, *out2, *out3;
    float *mean_out, *rstd_out;
    int64_t R, C;
    float eps;
} vec_args;

/* ---------------------------------------------------------- layer norm -- */

static void ln_forward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        const float *x = g->a + r * C;
        double m = 0.0, v = 0.0;
        for (int64_t c = 0; c < C; c++)
            m += x[c];
        m /= (double)C;
        for (int64_t c = 0; c < C; c++)
            v += (x[c] - m) * (x[c] - m);
        v /= (double)C;
        float rs = (float)(1.0 / sqrt(v + g->eps));
        g->mean_out[r] = (float)m;
        g->rstd_out[r] = rs;
        float *y = g->out + r * C;
        for (int64_t c = 0; c < C; c++) {
            float h = (x[c] - (float)m) * rs;
            y[c] = h * (g->w ? g->w[c] : 1.0f) + (g->bias ? g->bias[c] : 0.0f);
        }
    }
}

void cr_nn_cpu_layer_norm_forward(const float *x, int64_t R, int64_t C, const float *w,
                                  const float *b, float eps, float *y, float *mean, float *rstd) {
    vec_args g = {.a = x,
                  .w = w,
                  .bias = b,
                  .out = y,
                  .mean_out = mean,
                  .rstd_out = rstd,
                  .R = R,
                  .C = C,
                  .eps = eps};
    cr_parallel_for(R, nn_cpu_row_grain(C), ln_forward_range, &g);
}

/* dx = rstd (g - mean(g) - xhat mean(g xhat)), g = dy w */
static void ln_dx_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        const float *x = g->a + r * C, *dy = g->dy + r * C;
        float m = g->mean[r], rs = g->rstd[r];
        double sg = 0.0, sgx = 0.0;
        for (int64_t c = 0; c < C; c++) {
            float gc = dy[c] * (g->w ? g->w[c] : 1.0f);
            sg += gc;
            sgx += (double)gc * ((x[c] - m) * rs);
        }
        float mg = (float)(sg / (double)C), mgx = (float)(sgx / (double)C);
        float *dx = g->out + r * C;
        for (int64_t c = 0; c < C; c++) {
            float gc = dy[c] * (g->w ? g->w[c] : 1.0f);
            dx[c] += rs * (gc - mg - (x[c] - m) * rs * mgx);
        }
    }
}

/* dw[c] += sum_r dy xhat, db[c] += sum_r dy, one column block per unit. */
static void ln_dwdb_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t u = begin; u < end; u++) {
        int64_t c0 = u * COL_BLOCK, w = C - c0 < COL_BLOCK ? C - c0 : COL_BLOCK;
        double sw[COL_BLOCK], sb[COL_BLOCK];
        for (int64_t c = 0; c < w; c++)
            sw[c] = sb[c] = 0.0;
        for (int64_t r = 0; r < g->R; r++) {
            const float *x = g->a + r * C + c0, *dy = g->dy + r * C + c0;
            float m = g->mean[r], rs = g->rstd[r];
            for (int64_t c = 0; c < w; c++) {
                sw[c] += (double)dy[c] * ((x[c] - m) * rs);
                sb[c] += dy[c];
            }
        }
        for (int64_t c = 0; c < w; c++) {
            if (g->out2) g->out2[c0 + c] += (float)sw[c];
            if (g->out3) g->out3[c0 + c] += (float)sb[c];
        }
    }
}

void cr_nn_cpu_layer_norm_backward(const float *x, const float *dy, int64_t R, int64_t C,
                                   const float *w, const float *mean, const float *rstd, float *dx,
                                   float *dw, float *db) {
    vec_args g = {.a = x,
                  .dy = dy,
                  .w = w,
                  .mean = mean,
                  .rstd = rstd,
                  .out = dx,
                  .out2 = dw,
                  .out3 = db,
                  .R = R,
                  .C = C};
    if (dx) cr_parallel_for(R, nn_cpu_row_grain(C), ln_dx_range, &g);
    if (dw || db) {
        int64_t blocks = (C + COL_BLOCK - 1) / COL_BLOCK;
        cr_parallel_for(blocks, R * COL_BLOCK >= NN_CPU_GRAIN ? 1 : blocks, ln_dwdb_range, &g);
    }
}

/* --------------------------------------------------------------- cross -- */

static void cross3(const float *a, const float *b, float *y, int acc) {
    float c0 = a[1] * b[2] - a[2] * b[1];
    float c1 = a[2] * b[0] - a[0] * b[2];
    float c2 = a[0] * b[1] - a[1] * b[0];
    if (acc) {
        y[0] += c0, y[1] += c1, y[2] += c2;
    } else {
        y[0] = c0, y[1] = c1, y[2] = c2;
    }
}

static void cross_forward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    for (int64_t r = begin; r < end; r++)
        cross3(g->a + 3 * r, g->b + 3 * r, g->out + 3 * r, 0);
}

/* d(a x b).dy: da += b x dy, db += dy x a */
static void cross_backward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    for (int64_t r = begin; r < end; r++) {
        if (g->out) cross3(g->b + 3 * r, g->dy + 3 * r, g->out + 3 * r, 1);
        if (g->out2) cross3(g->dy + 3 * r, g->a + 3 * r, g->out2 + 3 * r, 1);
    }
}

void cr_nn_cpu_cross_forward(const float *a, const float *b, int64_t R, float *y) {
    vec_args g = {.a = a, .b = b, .out = y, .R = R, .C = 3};
    cr_parallel_for(R, nn_cpu_row_grain(3), cross_forward_range, &g);
}

void cr_nn_cpu_cross_backward(const float *a, const float *b, const float *dy, int64_t R, float *da,
                              float *db) {
    vec_args g = {.a = a, .b = b, .dy = dy, .out = da, .out2 = db, .R = R, .C = 3};
    cr_parallel_for(R, nn_cpu_row_grain(3), cross_backward_range, &g);
}

/* ------------------------------------------------ dot, norm, normalize -- */

static double row_dot(const float *a, const float *b, int64_t C) {
    double s = 0.0;
    for (int64_t c = 0; c < C; c++)
        s += (double)a[c] * b[c];
    return s;
}

static void dot_forward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    for (int64_t r = begin; r < end; r++)
        g->out[r] = (float)row_dot(g->a + r * g->C, g->b + r * g->C, g->C);
}

static void dot_backward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        float d = g->dy[r];
        for (int64_t c = 0; c < C; c++) {
            if (g->out) g->out[r * C + c] += d * g->b[r * C + c];
            if (g->out2) g->out2[r * C + c] += d * g->a[r * C + c];
        }
    }
}

void cr_nn_cpu_dot_forward(const float *a, const float *b, int64_t R, int64_t C, float *y) {
    vec_args g = {.a = a, .b = b, .out = y, .R = R, .C = C};
    cr_parallel_for(R, nn_cpu_row_grain(C), dot_forward_range, &g);
}

void cr_nn_cpu_dot_backward(const float *a, const float *b, const float *dy, int64_t R, int64_t C,
                            float *da, float *db) {
    vec_args g = {.a = a, .b = b, .dy = dy, .out = da, .out2 = db, .R = R, .C = C};
    cr_parallel_for(R, nn_cpu_row_grain(C), dot_backward_range, &g);
}

static void norm_forward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    for (int64_t r = begin; r < end; r++) {
        const float *x = g->a + r * g->C;
        g->out[r] = (float)sqrt(row_dot(x, x, g->C));
    }
}

/* dx += dy x / max(|x|, eps) */
static void norm_backward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        float s = g->dy[r] / fmaxf(g->y[r], g->eps);
        for (int64_t c = 0; c < C; c++)
            g->out[r * C + c] += s * g->a[r * C + c];
    }
}

void cr_nn_cpu_norm_forward(const float *x, int64_t R, int64_t C, float *y) {
    vec_args g = {.a = x, .out = y, .R = R, .C = C};
    cr_parallel_for(R, nn_cpu_row_grain(C), norm_forward_range, &g);
}

void cr_nn_cpu_norm_backward(const float *x, const float *y, const float *dy, int64_t R, int64_t C,
                             float eps, float *dx) {
    vec_args g = {.a = x, .y = y, .dy = dy, .out = dx, .R = R, .C = C, .eps = eps};
    cr_parallel_for(R, nn_cpu_row_grain(C), norm_backward_range, &g);
}

static void normalize_forward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        const float *x = g->a + r * C;
        float inv = 1.0f / fmaxf((float)sqrt(row_dot(x, x, C)), g->eps);
        for (int64_t c = 0; c < C; c++)
            g->out[r * C + c] = x[c] * inv;
    }
}

/* Above eps: dx += (dy - y (y.dy)) / |x|; at or below: dx += dy / eps. */
static void normalize_backward_range(void *vctx, int64_t begin, int64_t end) {
    const vec_args *g = vctx;
    int64_t C = g->C;
    for (int64_t r = begin; r < end; r++) {
        const float *x = g->a + r * C, *y = g->y + r * C, *dy = g->dy + r * C;
        float *dx = g->out + r * C;
        float n = (float)sqrt(row_dot(x, x, C));
        if (n > g->eps) {
            float yd = (float)row_dot(y, dy, C);
            for (int64_t c = 0; c < C; c++)
                dx[c] += (dy[c] - y[c] * yd) / n;
        } else {
            for (int64_t c = 0; c < C; c++)
                dx[c] += dy[c] / g->eps;
        }
    }
}

void cr_nn_cpu_normalize_forward(const float *x, int64_t R, int64_t C, float eps, float *y) {
    vec_args g = {.a = x, .out = y, .R = R, .C = C, .eps = eps};
    cr_parallel_for(R, nn_cpu_row_grain(C), normalize_forward_range, &g);
}

void cr_nn_cpu_normalize_backward(const float *x, const float *y, const float *dy, int64_t R,
                                  int64_t C, float eps, float *dx) {
    vec_args g = {.a = x, .y = y, .dy = dy, .out = dx, .R = R, .C = C, .eps = eps};
    cr_parallel_for(R, nn_cpu_row_grain(C), normalize_backward_range, &g);
}
