/* cpu_elementwise.c: CPU kernels for fills, copies, unary ops and
 * broadcast binary ops (values and the two gradient contributions).
 *
 * Each kernel picks its loop by op once, outside the element loop. The
 * binary loop is written once (binary_loop) and instantiated per (op, mode)
 * by calling it with constant arguments, which the compiler folds.
 * Numerics: sigmoid and softplus branch on the sign so exp never overflows
 * (softplus(x) = max(x,0) + log1p(exp(-|x|))).
 * exp, log, tanh, sigmoid and softplus (and softplus's gradient) run their
 * leading whole vectors through cpu_vmath.c on the AVX2 and AVX-512 levels.
 * Leaves out: explicit SIMD for the other ops (left to the auto-vectoriser).
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void cr_nn_cpu_bad_op(const char *kernel, cr_op op, const char *file, int line) {
    char msg[96];
    snprintf(msg, sizeof msg, "%s kernel has no case for op %s", kernel, cr_op_name(op));
    cr_assert_fail(msg, file, line);
}

/* -------------------------------------------------------- fill / copy -- */

typedef struct fill_args {
    float *dst;
    const float *src; /* NULL: fill with value */
    float value;
} fill_args;

static void fill_range(void *vctx, int64_t begin, int64_t end) {
    const fill_args *f = vctx;
    if (f->src) {
        memcpy(f->dst + begin, f->src + begin, (size_t)(end - begin) * sizeof(float));
    } else {
        for (int64_t i = begin; i < end; i++)
            f->dst[i] = f->value;
    }
}

void cr_nn_cpu_fill(float *x, int64_t n, float value) {
    fill_args f = {x, NULL, value};
    cr_parallel_for(n, NN_CPU_GRAIN, fill_range, &f);
}

void cr_nn_cpu_copy(float *dst, const float *src, int64_t n) {
    fill_args f = {dst, src, 0.0f};
    cr_parallel_for(n, NN_CPU_GRAIN, fill_range, &f);
}

/* -------------------------------------------------------------- unary -- */

typedef struct unary_args {
    cr_op op;
    float p;
    const float *x, *y, *dy;
    float *out;
    int level, vfn; /* vfn >= 0: the leading whole vectors go through cpu_vmath.c */
} unary_args;

/* The vector kernel of op's forward (or backward) on the current SIMD level,
 * or -1. The other ops' loops are left to the compiler. */
static int unary_vec_fn(cr_op op, int backward) {
    if (cr_nn_cpu_simd() < NN_SIMD_AVX2) return -1;
    if (backward) return op == CR_OP_SOFTPLUS ? NN_VEC_SIGMOID_SCALED : -1;
    switch (op) {
    case CR_OP_EXP:
        return NN_VEC_EXP;
    case CR_OP_LOG:
        return NN_VEC_LOG;
    case CR_OP_TANH:
        return NN_VEC_TANH;
    case CR_OP_SIGMOID:
        return NN_VEC_SIGMOID;
    case CR_OP_SOFTPLUS:
        return NN_VEC_SOFTPLUS;
    default:
        return -1;
    }
}

static void unary_forward_range(void *vctx, int64_t begin, int64_t end) {
    const unary_args *u = vctx;
    const float *x = u->x;
    float *y = u->out, p = u->p;
    int64_t i;
    if (u->vfn >= 0)
        begin += cr_nn_cpu_vec_span(u->level, (nn_vec_fn)u->vfn, p, x + begin, NULL, NULL,
                                    y + begin, 0, end - begin);
    switch (u->op) {
    case CR_OP_ADD_SCALAR:
        for (i = begin; i < end; i++)
            y[i] = x[i] + p;
        break;
    case CR_OP_MUL_SCALAR:
        for (i = begin; i < end; i++)
            y[i] = p * x[i];
        break;
    case CR_OP_POW:
        for (i = begin; i < end; i++)
            y[i] = powf(x[i], p);
        break;
    case CR_OP_RELU:
        for (i = begin; i < end; i++)
            y[i] = nn_cpu_select_pos(x[i], x[i], 0.0f);
        break;
    case CR_OP_LEAKY_RELU:
        for (i = begin; i < end; i++)
            y[i] = nn_cpu_select_pos(x[i], x[i], p * x[i]);
        break;
    case CR_OP_LEAKY_RELU_DERIV:
        for (i = begin; i < end; i++)
            y[i] = x[i] > 0.0f ? 1.0f : p;
        break;
    case CR_OP_TANH:
        for (i = begin; i < end; i++)
            y[i] = tanhf(x[i]);
        break;
    case CR_OP_SIGMOID:
        for (i = begin; i < end; i++)
            y[i] = nn_cpu_sigmoidf(x[i]);
        break;
    case CR_OP_SOFTPLUS:
        for (i = begin; i < end; i++)
            y[i] = nn_cpu_softplusf(x[i], p);
        break;
    case CR_OP_SIN:
        for (i = begin; i < end; i++)
            y[i] = sinf(x[i]);
        break;
    case CR_OP_COS:
        for (i = begin; i < end; i++)
            y[i] = cosf(x[i]);
        break;
    case CR_OP_EXP:
        for (i = begin; i < end; i++)
            y[i] = expf(x[i]);
        break;
    case CR_OP_LOG:
        for (i = begin; i < end; i++)
            y[i] = logf(x[i]);
        break;
    case CR_OP_SQRT:
        for (i = begin; i < end; i++)
            y[i] = sqrtf(x[i]);
        break;
    case CR_OP_ABS:
        for (i = begin; i < end; i++)
            y[i] = fabsf(x[i]);
        break;
    case CR_OP_SQUARE:
        for (i = begin; i < end; i++)
            y[i] = x[i] * x[i];
        break;
    default:
        cr_nn_cpu_bad_op("unary forward", u->op, __FILE__, __LINE__);
    }
}

/* dx += dy f'(x); f' written with the forward output y where cheaper. */
static void unary_backward_range(void *vctx, int64_t begin, int64_t end) {
    const unary_args *u = vctx;
    const float *x = u->x, *y = u->y, *dy = u->dy;
    float *dx = u->out, p = u->p;
    int64_t i;
    if (u->vfn >= 0)
        begin += cr_nn_cpu_vec_span(u->level, (nn_vec_fn)u->vfn, p, x + begin, NULL, dy + begin,
                                    dx + begin, 1, end - begin);
    switch (u->op) {
    case CR_OP_ADD_SCALAR:
        for (i = begin; i < end; i++)
            dx[i] += dy[i];
        break;
    case CR_OP_MUL_SCALAR:
        for (i = begin; i < end; i++)
            dx[i] += p * dy[i];
        break;
    case CR_OP_POW:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * p * powf(x[i], p - 1.0f);
        break;
    case CR_OP_RELU:
        for (i = begin; i < end; i++)
            dx[i] += nn_cpu_select_pos(x[i], dy[i], 0.0f);
        break;
    case CR_OP_LEAKY_RELU:
        for (i = begin; i < end; i++)
            dx[i] += nn_cpu_select_pos(x[i], dy[i], p * dy[i]);
        break;
    case CR_OP_LEAKY_RELU_DERIV:
        break; /* piecewise constant: zero gradient */
    case CR_OP_TANH:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * (1.0f - y[i] * y[i]);
        break;
    case CR_OP_SIGMOID:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * y[i] * (1.0f - y[i]);
        break;
    case CR_OP_SOFTPLUS:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * nn_cpu_sigmoidf(p * x[i]);
        break;
    case CR_OP_SIN:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * cosf(x[i]);
        break;
    case CR_OP_COS:
        for (i = begin; i < end; i++)
            dx[i] -= dy[i] * sinf(x[i]);
        break;
    case CR_OP_EXP:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] * y[i];
        break;
    case CR_OP_LOG:
        for (i = begin; i < end; i++)
            dx[i] += dy[i] / x[i];
        break;
    case CR_OP_SQRT:
        for (i = begin; i < end; i++)
            dx[i] += 0.5f * dy[i] / y[i];
        break;
    case CR_OP_ABS:
        for (i = begin; i < end; i++)
            dx[i] += x[i] > 0.0f ? dy[i] : (x[i] < 0.0f ? -dy[i] : 0.0f);
        break;
    case CR_OP_SQUARE:
        for (i = begin; i < end; i++)
            dx[i] += 2.0f * x[i] * dy[i];
        break;
    default:
        cr_nn_cpu_bad_op("unary backward", u->op, __FILE__, __LINE__);
    }
}

void cr_nn_cpu_unary_forward(cr_op op, float p, const float *x, float *y, int64_t n) {
    unary_args u = {op, p, x, NULL, NULL, y, cr_nn_cpu_simd(), unary_vec_fn(op, 0)};
    cr_parallel_for(n, NN_CPU_GRAIN, unary_forward_range, &u);
}

void cr_nn_cpu_unary_backward(cr_op op, float p, const float *x, const float *y, const float *dy,
                              float *dx, int64_t n) {
    unary_args u = {op, p, x, y, dy, dx, cr_nn_cpu_simd(), unary_vec_fn(op, 1)};
    cr_parallel_for(n, NN_CPU_GRAIN, unary_backward_range, &u);
}

/* ------------------------------------------------------------- binary -- */

static inline float binop(cr_op op, nn_binary_mode mode, float a, float b, float dy) {
    switch (mode) {
    case NN_BINARY_VALUE:
        return op == CR_OP_ADD ? a + b : op == CR_OP_SUB ? a - b : op == CR_OP_MUL ? a * b : a / b;
    case NN_BINARY_GRAD_A:
        return op == CR_OP_MUL ? dy * b : op == CR_OP_DIV ? dy / b : dy;
    case NN_BINARY_GRAD_B:
        return op == CR_OP_ADD   ? dy
               : op == CR_OP_SUB ? -dy
               : op == CR_OP_MUL ? dy * a
                                 : -dy * a / (b * b);
    }
    return 0.0f;
}

/* n outputs from a (stride sa), b (stride sb) and dy (contiguous; read only
 * in the gradient modes). */
static inline __attribute__((always_inline)) void
binary_loop(cr_op op, nn_binary_mode mode, const float *a, int64_t sa, const float *b, int64_t sb,
            const float *dy, float *out, int64_t n, int acc) {
    for (int64_t j = 0; j < n; j++) {
        float d = mode == NN_BINARY_VALUE ? 0.0f : dy[j];
        float v = binop(op, mode, a[j * sa], b[j * sb], d);
        if (acc)
            out[j] += v;
        else
            out[j] = v;
    }
}

static void binary_span(cr_op op, nn_binary_mode mode, const float *a, int64_t sa, const float *b,
                        int64_t sb, const float *dy, float *out, int64_t n, int acc) {
    /* One constant (op, mode) pair per call so binop folds away. */
    switch ((int)mode * 4 + (int)(op - CR_OP_ADD)) {
    case 0:
        binary_loop(CR_OP_ADD, NN_BINARY_VALUE, a, sa, b, sb, dy, out, n, acc);
        break;
    case 1:
        binary_loop(CR_OP_SUB, NN_BINARY_VALUE, a, sa, b, sb, dy, out, n, acc);
        break;
    case 2:
        binary_loop(CR_OP_MUL, NN_BINARY_VALUE, a, sa, b, sb, dy, out, n, acc);
        break;
    case 3:
        binary_loop(CR_OP_DIV, NN_BINARY_VALUE, a, sa, b, sb, dy, out, n, acc);
        break;
    case 4:
        binary_loop(CR_OP_ADD, NN_BINARY_GRAD_A, a, sa, b, sb, dy, out, n, acc);
        break;
    case 5:
        binary_loop(CR_OP_SUB, NN_BINARY_GRAD_A, a, sa, b, sb, dy, out, n, acc);
        break;
    case 6:
        binary_loop(CR_OP_MUL, NN_BINARY_GRAD_A, a, sa, b, sb, dy, out, n, acc);
        break;
    case 7:
        binary_loop(CR_OP_DIV, NN_BINARY_GRAD_A, a, sa, b, sb, dy, out, n, acc);
        break;
    case 8:
        binary_loop(CR_OP_ADD, NN_BINARY_GRAD_B, a, sa, b, sb, dy, out, n, acc);
        break;
    case 9:
        binary_loop(CR_OP_SUB, NN_BINARY_GRAD_B, a, sa, b, sb, dy, out, n, acc);
        break;
    case 10:
        binary_loop(CR_OP_MUL, NN_BINARY_GRAD_B, a, sa, b, sb, dy, out, n, acc);
        break;
    case 11:
        binary_loop(CR_OP_DIV, NN_BINARY_GRAD_B, a, sa, b, sb, dy, out, n, acc);
        break;
    default:
        cr_nn_cpu_bad_op("binary", op, __FILE__, __LINE__);
    }
}

typedef struct binary_args {
    cr_op op;
    nn_binary_mode mode;
    const float *a, *b, *dy;
    float *out;
    int acc;
    int flat;             /* both operands full-size or single elements: one span */
    int64_t sa[4], sb[4]; /* element strides, 0 along broadcast axes */
    int64_t ys[4];
} binary_args;

static void binary_range(void *vctx, int64_t begin, int64_t end) {
    const binary_args *g = vctx;
    const float *dy = g->mode == NN_BINARY_VALUE ? NULL : g->dy;
    if (g->flat) {
        binary_span(g->op, g->mode, g->a + begin * g->sa[3], g->sa[3], g->b + begin * g->sb[3],
                    g->sb[3], dy ? dy + begin : NULL, g->out + begin, end - begin, g->acc);
        return;
    }
    /* Rows over the first three axes, the last axis inside. */
    int64_t inner = g->ys[3];
    for (int64_t r = begin; r < end; r++) {
        int64_t i2 = r % g->ys[2], t = r / g->ys[2];
        int64_t i1 = t % g->ys[1], i0 = t / g->ys[1];
        int64_t ao = i0 * g->sa[0] + i1 * g->sa[1] + i2 * g->sa[2];
        int64_t bo = i0 * g->sb[0] + i1 * g->sb[1] + i2 * g->sb[2];
        binary_span(g->op, g->mode, g->a + ao, g->sa[3], g->b + bo, g->sb[3],
                    dy ? dy + r * inner : NULL, g->out + r * inner, inner, g->acc);
    }
}

/* Element strides of a padded shape against the output shape. */
static void broadcast_strides(const int64_t s[4], int64_t st[4]) {
    int64_t step = 1;
    for (int k = 3; k >= 0; k--) {
        st[k] = s[k] == 1 ? 0 : step;
        step *= s[k];
    }
}

static int64_t numel4(const int64_t s[4]) {
    return s[0] * s[1] * s[2] * s[3];
}

void cr_nn_cpu_binary(cr_op op, nn_binary_mode mode, const float *a, const int64_t as[4],
                      const float *b, const int64_t bs[4], const float *dy, const int64_t ys[4],
                      float *out, int acc) {
    binary_args g = {.op = op, .mode = mode, .a = a, .b = b, .dy = dy, .out = out, .acc = acc};
    memcpy(g.ys, ys, sizeof g.ys);
    broadcast_strides(as, g.sa);
    broadcast_strides(bs, g.sb);
    int64_t n = numel4(ys);
    int a_flat = memcmp(as, ys, sizeof g.ys) == 0 || numel4(as) == 1;
    int b_flat = memcmp(bs, ys, sizeof g.ys) == 0 || numel4(bs) == 1;
    if (a_flat && b_flat) {
        g.flat = 1;
        g.sa[3] = numel4(as) == 1 ? 0 : 1;
        g.sb[3] = numel4(bs) == 1 ? 0 : 1;
        cr_parallel_for(n, NN_CPU_GRAIN, binary_range, &g);
        return;
    }
    int64_t rows = ys[0] * ys[1] * ys[2];
    cr_parallel_for(rows, nn_cpu_row_grain(ys[3]), binary_range, &g);
}
