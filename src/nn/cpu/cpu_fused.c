/* cpu_fused.c: the passes a fused linear + activation layer runs around its
 * GEMMs: bias add and activation in one pass over the output (forward), and
 * the activation's derivative times the incoming gradient together with the
 * bias gradient's column sum in one pass (backward).
 *
 * Each kernel has a portable scalar path, written without branches on the
 * data (a ReLU's `z > 0 ? z : 0` compiled to a branch mispredicts on half the
 * elements), and an AVX2 + FMA path for the piecewise-linear activations,
 * compiled with a target attribute so the build needs no -march. The path is
 * chosen once at run time from the CPU's features; CREASE_NN_SIMD=scalar in
 * the environment, or cr_nn_cpu_set_simd, forces the scalar one (the
 * gradient tests run every path the machine has).
 * Column sums accumulate in double, each column over blocks of 512 rows in
 * order and then over the blocks in order, so the bias gradient does not
 * depend on the thread count or the path (up to the last bit of the float dz
 * each path rounds alike).
 * The piecewise-linear activations also have an AVX-512F path (16 lanes,
 * mask registers); tanh, sigmoid and softplus run through the vector
 * transcendental kernels of cpu_vmath.c on the AVX2 and AVX-512 levels.
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    SUM_COLS = 256, /* columns one backward unit owns: whole rows up to 256 wide, so the pass
                       streams through memory */
    SUM_ROWS = 512  /* rows one backward unit owns, so a narrow layer's pass runs in parallel */
};

/* ----------------------------------------------------------- dispatch -- */

static int simd_level = -1; /* -1: not chosen yet */

int cr_nn_cpu_simd_max(void) {
#if NN_CPU_X86
    if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return NN_SIMD_SCALAR;
    return __builtin_cpu_supports("avx512f") ? NN_SIMD_AVX512 : NN_SIMD_AVX2;
#else
    return NN_SIMD_SCALAR;
#endif
}

int cr_nn_cpu_simd(void) {
    if (simd_level < 0) {
        const char *env = getenv("CREASE_NN_SIMD");
        int max = cr_nn_cpu_simd_max();
        simd_level = max;
        if (env && (strcmp(env, "scalar") == 0 || strcmp(env, "0") == 0))
            simd_level = NN_SIMD_SCALAR;
        else if (env && strcmp(env, "avx2") == 0 && max > NN_SIMD_AVX2)
            simd_level = NN_SIMD_AVX2;
    }
    return simd_level;
}

int cr_nn_cpu_set_simd(int level) {
    int prev = cr_nn_cpu_simd(), max = cr_nn_cpu_simd_max();
    simd_level = level < NN_SIMD_SCALAR ? NN_SIMD_SCALAR : level > max ? max : level;
    return prev;
}

/* ------------------------------------------------------------ scalar -- */

/* dy f'(z) written with y = f(z) (for leaky ReLU with slope >= 0, y > 0 iff z > 0). */
static inline float df_of(cr_op act, float p, float y, float dy) {
    switch (act) {
    case CR_OP_RELU:
        return nn_cpu_select_pos(y, dy, 0.0f);
    case CR_OP_LEAKY_RELU:
        return nn_cpu_select_pos(y, dy, p * dy);
    case CR_OP_TANH:
        return dy * (1.0f - y * y);
    case CR_OP_SIGMOID:
        return dy * y * (1.0f - y);
    case CR_OP_SOFTPLUS:
        return dy * nn_cpu_softplus_deriv_from_y(y, p);
    default:
        return dy;
    }
}

static void bias_act_rows_scalar(cr_op act, float p, const float *b, float *y, int64_t r0,
                                 int64_t r1, int64_t C) {
    for (int64_t r = r0; r < r1; r++) {
        float *row = y + r * C;
        for (int64_t c = 0; c < C; c++)
            row[c] = nn_cpu_act(act, p, row[c] + (b ? b[c] : 0.0f));
    }
}

/* Columns [c0, c0+w) of dz = dy f'(y) over all R rows; acc += their sums. */
static void act_grad_cols_scalar(cr_op act, float p, const float *y, const float *dy, int64_t R,
                                 int64_t C, int64_t c0, int64_t w, float *dz, double *acc) {
    for (int64_t r = 0; r < R; r++) {
        const float *yr = y + r * C + c0, *dyr = dy + r * C + c0;
        float *dzr = dz ? dz + r * C + c0 : NULL;
        for (int64_t c = 0; c < w; c++) {
            float g = df_of(act, p, yr[c], dyr[c]);
            if (dzr) dzr[c] = g;
            if (acc) acc[c] += g;
        }
    }
}

/* -------------------------------------------------------------- AVX2 -- */

#if NN_CPU_X86
#define NN_AVX2 __attribute__((target("avx2,fma")))

static inline NN_AVX2 __m256 f_avx2(cr_op act, __m256 p, __m256 z) {
    __m256 zero = _mm256_setzero_ps();
    if (act == CR_OP_RELU) return _mm256_max_ps(z, zero); /* max(NaN, 0) = 0 as the scalar path */
    if (act == CR_OP_LEAKY_RELU)
        return _mm256_blendv_ps(_mm256_mul_ps(p, z), z, _mm256_cmp_ps(z, zero, _CMP_GT_OQ));
    return z;
}

static inline NN_AVX2 __m256 df_avx2(cr_op act, __m256 p, __m256 y, __m256 dy) {
    __m256 pos = _mm256_cmp_ps(y, _mm256_setzero_ps(), _CMP_GT_OQ);
    if (act == CR_OP_RELU) return _mm256_and_ps(dy, pos);
    if (act == CR_OP_LEAKY_RELU) return _mm256_blendv_ps(_mm256_mul_ps(p, dy), dy, pos);
    return dy;
}

static NN_AVX2 void bias_act_rows_avx2(cr_op act, float p, const float *b, float *y, int64_t r0,
                                       int64_t r1, int64_t C) {
    __m256 vp = _mm256_set1_ps(p);
    for (int64_t r = r0; r < r1; r++) {
        float *row = y + r * C;
        int64_t c = 0;
        for (; c + 8 <= C; c += 8) {
            __m256 z = _mm256_loadu_ps(row + c);
            if (b) z = _mm256_add_ps(z, _mm256_loadu_ps(b + c));
            _mm256_storeu_ps(row + c, f_avx2(act, vp, z));
        }
        for (; c < C; c++)
            row[c] = nn_cpu_act(act, p, row[c] + (b ? b[c] : 0.0f));
    }
}

static NN_AVX2 void act_grad_cols_avx2(cr_op act, float p, const float *y, const float *dy,
                                       int64_t R, int64_t C, int64_t c0, int64_t w, float *dz,
                                       double *acc) {
    __m256 vp = _mm256_set1_ps(p);
    int64_t w8 = w / 8 * 8;
    for (int64_t r = 0; r < R; r++) {
        const float *yr = y + r * C + c0, *dyr = dy + r * C + c0;
        float *dzr = dz ? dz + r * C + c0 : NULL;
        for (int64_t c = 0; c < w8; c += 8) {
            __m256 g = df_avx2(act, vp, _mm256_loadu_ps(yr + c), _mm256_loadu_ps(dyr + c));
            if (dzr) _mm256_storeu_ps(dzr + c, g);
            if (acc) {
                __m256d lo = _mm256_cvtps_pd(_mm256_castps256_ps128(g));
                __m256d hi = _mm256_cvtps_pd(_mm256_extractf128_ps(g, 1));
                _mm256_storeu_pd(acc + c, _mm256_add_pd(_mm256_loadu_pd(acc + c), lo));
                _mm256_storeu_pd(acc + c + 4, _mm256_add_pd(_mm256_loadu_pd(acc + c + 4), hi));
            }
        }
        for (int64_t c = w8; c < w; c++) {
            float g = df_of(act, p, yr[c], dyr[c]);
            if (dzr) dzr[c] = g;
            if (acc) acc[c] += g;
        }
    }
}

/* ----------------------------------------------------------- AVX-512 -- */

#define NN_AVX512 __attribute__((target("avx512f")))

static inline NN_AVX512 __m512 f_avx512(cr_op act, __m512 p, __m512 z) {
    __m512 zero = _mm512_setzero_ps();
    if (act == CR_OP_RELU) return _mm512_max_ps(z, zero); /* NaN -> 0, as AVX2 and scalar */
    if (act == CR_OP_LEAKY_RELU)
        return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(z, zero, _CMP_GT_OQ), _mm512_mul_ps(p, z),
                                    z);
    return z;
}

static inline NN_AVX512 __m512 df_avx512(cr_op act, __m512 p, __m512 y, __m512 dy) {
    __mmask16 pos = _mm512_cmp_ps_mask(y, _mm512_setzero_ps(), _CMP_GT_OQ);
    if (act == CR_OP_RELU) return _mm512_maskz_mov_ps(pos, dy);
    if (act == CR_OP_LEAKY_RELU) return _mm512_mask_blend_ps(pos, _mm512_mul_ps(p, dy), dy);
    return dy;
}

static NN_AVX512 void bias_act_rows_avx512(cr_op act, float p, const float *b, float *y, int64_t r0,
                                           int64_t r1, int64_t C) {
    __m512 vp = _mm512_set1_ps(p);
    for (int64_t r = r0; r < r1; r++) {
        float *row = y + r * C;
        int64_t c = 0;
        for (; c + 16 <= C; c += 16) {
            __m512 z = _mm512_loadu_ps(row + c);
            if (b) z = _mm512_add_ps(z, _mm512_loadu_ps(b + c));
            _mm512_storeu_ps(row + c, f_avx512(act, vp, z));
        }
        for (; c < C; c++)
            row[c] = nn_cpu_act(act, p, row[c] + (b ? b[c] : 0.0f));
    }
}

static NN_AVX512 void act_grad_cols_avx512(cr_op act, float p, const float *y, const float *dy,
                                           int64_t R, int64_t C, int64_t c0, int64_t w, float *dz,
                                           double *acc) {
    __m512 vp = _mm512_set1_ps(p);
    int64_t w16 = w / 16 * 16;
    for (int64_t r = 0; r < R; r++) {
        const float *yr = y + r * C + c0, *dyr = dy + r * C + c0;
        float *dzr = dz ? dz + r * C + c0 : NULL;
        for (int64_t c = 0; c < w16; c += 16) {
            __m512 g = df_avx512(act, vp, _mm512_loadu_ps(yr + c), _mm512_loadu_ps(dyr + c));
            if (dzr) _mm512_storeu_ps(dzr + c, g);
            if (acc) {
                __m512d lo = _mm512_cvtps_pd(_mm512_castps512_ps256(g));
                __m512d hi = _mm512_cvtps_pd(
                    _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(g), 1)));
                _mm512_storeu_pd(acc + c, _mm512_add_pd(_mm512_loadu_pd(acc + c), lo));
                _mm512_storeu_pd(acc + c + 8, _mm512_add_pd(_mm512_loadu_pd(acc + c + 8), hi));
            }
        }
        for (int64_t c = w16; c < w; c++) {
            float g = df_of(act, p, yr[c], dyr[c]);
            if (dzr) dzr[c] = g;
            if (acc) acc[c] += g;
        }
    }
}
#endif

/* Smooth activations on a SIMD level: rows through the vector transcendental
 * kernels (cpu_vmath.c), the row's tail in scalar. */
static void bias_act_rows_vec(int level, nn_vec_fn fn, cr_op act, float p, const float *b, float *y,
                              int64_t r0, int64_t r1, int64_t C) {
    for (int64_t r = r0; r < r1; r++) {
        float *row = y + r * C;
        for (int64_t c = cr_nn_cpu_vec_span(level, fn, p, row, b, NULL, row, 0, C); c < C; c++)
            row[c] = nn_cpu_act(act, p, row[c] + (b ? b[c] : 0.0f));
    }
}

static void act_grad_cols_vec(int level, nn_vec_fn fn, cr_op act, float p, const float *y,
                              const float *dy, int64_t R, int64_t C, int64_t c0, int64_t w,
                              float *dz, double *acc) {
    float tmp[SUM_COLS];
    for (int64_t r = 0; r < R; r++) {
        const float *yr = y + r * C + c0, *dyr = dy + r * C + c0;
        float *g = dz ? dz + r * C + c0 : tmp;
        for (int64_t c = cr_nn_cpu_vec_span(level, fn, p, yr, NULL, dyr, g, 0, w); c < w; c++)
            g[c] = df_of(act, p, yr[c], dyr[c]);
        if (acc)
            for (int64_t c = 0; c < w; c++)
                acc[c] += g[c];
    }
}

/* The vector kernel of a smooth activation (or of its derivative from y);
 * -1 for the others. */
static int smooth_fn(cr_op act, int deriv) {
    switch (act) {
    case CR_OP_TANH:
        return deriv ? NN_VEC_TANH_DERIV_FROM_Y : NN_VEC_TANH;
    case CR_OP_SIGMOID:
        return deriv ? NN_VEC_SIGMOID_DERIV_FROM_Y : NN_VEC_SIGMOID;
    case CR_OP_SOFTPLUS:
        return deriv ? NN_VEC_SOFTPLUS_DERIV_FROM_Y : NN_VEC_SOFTPLUS;
    default:
        return -1;
    }
}

/* The SIMD level of the piecewise-linear passes for this activation: the
 * current one for none, ReLU and leaky ReLU, scalar for the others (the
 * smooth ones go through cpu_vmath.c). */
static int linear_level(cr_op act) {
    int pl = act == CR_OP_NONE || act == CR_OP_RELU || act == CR_OP_LEAKY_RELU;
    return NN_CPU_X86 && pl ? cr_nn_cpu_simd() : NN_SIMD_SCALAR;
}

/* ------------------------------------------------------------ kernels -- */

typedef struct fused_args {
    cr_op act;
    float p;
    const float *b, *y, *dy;
    float *out, *dz, *db;
    double *partial; /* act_bias_backward: per row block column sums, or NULL */
    int64_t R, C, units, block_rows, col_blocks;
    int pl;         /* linear_level(act) */
    int level, vfn; /* vfn >= 0: the smooth activation's vector kernel on `level` */
} fused_args;

/* The vector kernel for act on the current level, or -1 (scalar, or not smooth). */
static int vec_fn_for(cr_op act, int deriv) {
    return cr_nn_cpu_simd() >= NN_SIMD_AVX2 ? smooth_fn(act, deriv) : -1;
}

static void bias_act_range(void *vctx, int64_t begin, int64_t end) {
    const fused_args *g = vctx;
    if (g->vfn >= 0) {
        bias_act_rows_vec(g->level, (nn_vec_fn)g->vfn, g->act, g->p, g->b, g->out, begin, end,
                          g->C);
        return;
    }
#if NN_CPU_X86
    if (g->pl >= NN_SIMD_AVX512) {
        bias_act_rows_avx512(g->act, g->p, g->b, g->out, begin, end, g->C);
        return;
    }
    if (g->pl >= NN_SIMD_AVX2) {
        bias_act_rows_avx2(g->act, g->p, g->b, g->out, begin, end, g->C);
        return;
    }
#endif
    bias_act_rows_scalar(g->act, g->p, g->b, g->out, begin, end, g->C);
}

void cr_nn_cpu_bias_act_forward(cr_op act, float p, const float *b, float *y, int64_t R,
                                int64_t C) {
    if (act == CR_OP_NONE && !b) return;
    fused_args g = {.act = act,
                    .p = p,
                    .b = b,
                    .out = y,
                    .R = R,
                    .C = C,
                    .pl = linear_level(act),
                    .level = cr_nn_cpu_simd(),
                    .vfn = vec_fn_for(act, 0)};
    cr_parallel_for(R, nn_cpu_row_grain(C), bias_act_range, &g);
}

/* One unit: a block of up to SUM_COLS columns over one block of
 * g->block_rows rows. With a bias gradient and more than one row block, each
 * unit writes its column sums to its own slot of g->partial (row block
 * major), which the caller adds up in row block order; the blocks are fixed
 * by the shape, not by the thread count. With one row block the unit adds
 * its sums to db itself, as no other unit touches those columns. */
static void act_grad_range(void *vctx, int64_t begin, int64_t end) {
    const fused_args *g = vctx;
    for (int64_t u = begin; u < end; u++) {
        int64_t cb = u % g->col_blocks, rb = u / g->col_blocks;
        int64_t c0 = cb * SUM_COLS, w = g->C - c0 < SUM_COLS ? g->C - c0 : SUM_COLS;
        int64_t r0 = rb * g->block_rows;
        int64_t rows = g->R - r0 < g->block_rows ? g->R - r0 : g->block_rows;
        const float *y = g->y + r0 * g->C, *dy = g->dy + r0 * g->C;
        float *dz = g->dz ? g->dz + r0 * g->C : NULL;
        double acc[SUM_COLS];
        for (int64_t c = 0; c < w; c++)
            acc[c] = 0.0;
        double *a = g->db ? acc : NULL;
        if (g->vfn >= 0)
            act_grad_cols_vec(g->level, (nn_vec_fn)g->vfn, g->act, g->p, y, dy, rows, g->C, c0, w,
                              dz, a);
        else if (g->pl == NN_SIMD_SCALAR)
            act_grad_cols_scalar(g->act, g->p, y, dy, rows, g->C, c0, w, dz, a);
#if NN_CPU_X86
        else if (g->pl >= NN_SIMD_AVX512)
            act_grad_cols_avx512(g->act, g->p, y, dy, rows, g->C, c0, w, dz, a);
        else
            act_grad_cols_avx2(g->act, g->p, y, dy, rows, g->C, c0, w, dz, a);
#endif
        if (!g->db) continue;
        if (g->partial)
            memcpy(g->partial + rb * g->C + c0, acc, (size_t)w * sizeof *acc);
        else
            for (int64_t c = 0; c < w; c++)
                g->db[c0 + c] += (float)acc[c];
    }
}

void cr_nn_cpu_act_bias_backward(cr_op act, float p, const float *y, const float *dy, int64_t R,
                                 int64_t C, float *dz, float *db) {
    if ((!dz && !db) || C == 0 || R == 0) return;
    fused_args g = {.act = act,
                    .p = p,
                    .y = y,
                    .dy = dy,
                    .dz = dz,
                    .db = db,
                    .R = R,
                    .C = C,
                    .block_rows = SUM_ROWS,
                    .col_blocks = (C + SUM_COLS - 1) / SUM_COLS,
                    .pl = linear_level(act),
                    .level = cr_nn_cpu_simd(),
                    .vfn = vec_fn_for(act, 1)};
    int64_t row_blocks = (R + SUM_ROWS - 1) / SUM_ROWS;
    if (db && row_blocks > 1) {
        g.partial = malloc((size_t)row_blocks * (size_t)C * sizeof *g.partial);
        if (!g.partial) row_blocks = 1, g.block_rows = R; /* no scratch: whole columns */
    }
    g.units = g.col_blocks * row_blocks;
    int64_t work = g.block_rows * (C < SUM_COLS ? C : SUM_COLS);
    int64_t grain = work >= NN_CPU_GRAIN ? 1 : NN_CPU_GRAIN / work;
    cr_parallel_for(g.units, grain, act_grad_range, &g);
    if (g.partial) {
        for (int64_t c = 0; c < C; c++) {
            double sum = 0.0;
            for (int64_t rb = 0; rb < row_blocks; rb++)
                sum += g.partial[rb * C + c];
            db[c] += (float)sum;
        }
        free(g.partial);
    }
}
