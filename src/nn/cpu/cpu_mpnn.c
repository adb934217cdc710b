/* cpu_mpnn.c: one MLP block of a message-passing net for inference
 * (layer_mpnn.c with the context's gradient off): per row the gathers of
 * the endpoints' products, every layer's product, bias and activation, the
 * LayerNorm, the residual and the sum into the receiver, with the row's
 * activations in registers or L1, instead of the tape's dozen passes that
 * each write an (E, L) array (issue 51: epnet's P-Net runs its blocks over
 * 163,004 hinge pairs, four a frame).
 *
 * Two paths. Where every layer's output is 16 wide (epnet's P-Net) and the
 * CPU has AVX-512, a row lives in one register: eight rows side by side so
 * their chains of multiply-adds overlap, the LayerNorm's sums as lane
 * shuffles, 1/sqrt as the 14-bit estimate and a Newton step. Elsewhere
 * tiles of 32 rows: each layer's products a 16-column block at a time over
 * 4 rows sharing each weight load (fused multiply-adds in AVX-512, or AVX2
 * halves; the ISO C build contracts none in plain code), the columns past
 * the last whole block and the portable level in GCC/clang vector types,
 * activations through cpu_vmath.c's spans (ReLU and LeakyReLU as selects).
 * The weights are transposed once a call into the scratch; with a
 * LayerNorm after a last layer without activation, that layer's weights and
 * bias are centred over its outputs, so the mean need not be taken.
 * The sums into receivers run over rows sorted by receiver, each receiver's
 * rows in one thread in order: the same result whatever the thread count.
 * Differences from the tape, all within float rounding (tests compare):
 * products summed in another order, the LayerNorm's statistics in float.
 * Leaves out: any gradient.
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <string.h>

enum {
    TILE = 32,       /* rows whose activations stay in L1 (32 x 256 floats x 2: 64 KiB) */
    ROW_GRAIN = 256, /* rows worth a thread */
    ROWS16 = 8,      /* rows side by side in the 16-wide path */
};

typedef float v16 __attribute__((vector_size(64)));
typedef int32_t vi16 __attribute__((vector_size(64)));
#define ALWAYS static inline __attribute__((always_inline))
#define V_LD(v, p) memcpy(&(v), (p), sizeof(v16))
#define V_ST(p, v) memcpy((p), &(v), sizeof(v16))

typedef struct mpnn_pass {
    const nn_mpnn_block_args *a;
    const float *wt[NN_MPNN_MAX_LAYERS]; /* layer l: (width[l], width[l+1]) */
    const float *b[NN_MPNN_MAX_LAYERS];  /* a's, or the last one centred */
    int centred; /* the last layer's outputs have mean zero (see block_forward) */
    int level;
} mpnn_pass;

size_t cr_nn_cpu_mpnn_block_scratch(const nn_mpnn_block_args *a) {
    size_t n = 1 + (size_t)a->width[a->nl];
    for (int l = 0; l < a->nl; l++)
        n += (size_t)(a->width[l] * a->width[l + 1]);
    return n;
}

/* y[r] += x[r] wt over R rows (y rows ldy apart, wt's ldwt): 16 columns by 4 rows at a
 * time, then the rows left, then the columns left. */
ALWAYS void rows_matmul(float *y, int64_t ldy, const float *const *x, int64_t in, const float *wt,
                        int64_t out, int64_t R, int64_t ldwt) {
    int64_t j = 0;
    for (; j + 16 <= out; j += 16) {
        int64_t r = 0;
        for (; r + 4 <= R; r += 4) {
            const float *x0 = x[r], *x1 = x[r + 1], *x2 = x[r + 2], *x3 = x[r + 3];
            float *y0 = y + r * ldy + j;
            v16 a0, a1, a2, a3;
            V_LD(a0, y0), V_LD(a1, y0 + ldy), V_LD(a2, y0 + 2 * ldy), V_LD(a3, y0 + 3 * ldy);
            for (int64_t k = 0; k < in; k++) {
                v16 w;
                V_LD(w, wt + k * ldwt + j);
                a0 += x0[k] * w, a1 += x1[k] * w, a2 += x2[k] * w, a3 += x3[k] * w;
            }
            V_ST(y0, a0), V_ST(y0 + ldy, a1), V_ST(y0 + 2 * ldy, a2), V_ST(y0 + 3 * ldy, a3);
        }
        for (; r < R; r++) {
            const float *x0 = x[r];
            float *y0 = y + r * ldy + j;
            v16 a0;
            V_LD(a0, y0);
            for (int64_t k = 0; k < in; k++) {
                v16 w;
                V_LD(w, wt + k * ldwt + j);
                a0 += x0[k] * w;
            }
            V_ST(y0, a0);
        }
    }
    for (; j < out; j++)
        for (int64_t r = 0; r < R; r++) {
            float s = y[r * ldy + j];
            for (int64_t k = 0; k < in; k++)
                s += x[r][k] * wt[k * ldwt + j];
            y[r * ldy + j] = s;
        }
}

/* The sum of *v's lanes, as a tree of halves (by pointer: a 64-byte vector
 * passed by value changes the ABI on the lower levels). */
ALWAYS float hsum(v16 *v) {
    v16 u = *v;
#if defined(__clang__)
    u += __builtin_shufflevector(u, u, 8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 6, 7);
    u += __builtin_shufflevector(u, u, 4, 5, 6, 7, 0, 1, 2, 3, 12, 13, 14, 15, 8, 9, 10, 11);
    u += __builtin_shufflevector(u, u, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13);
    u += __builtin_shufflevector(u, u, 1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14);
#else
    u += __builtin_shuffle(u, (vi16){8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 6, 7});
    u += __builtin_shuffle(u, (vi16){4, 5, 6, 7, 0, 1, 2, 3, 12, 13, 14, 15, 8, 9, 10, 11});
    u += __builtin_shuffle(u, (vi16){2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13});
    u += __builtin_shuffle(u, (vi16){1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14});
#endif
    return u[0];
}

/* y = a + b over n floats (y may be a) */
ALWAYS void vadd3(float *y, const float *a, const float *b, int64_t n) {
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) {
        v16 u, v;
        V_LD(u, a + i), V_LD(v, b + i);
        u += v;
        V_ST(y + i, u);
    }
    for (; i < n; i++)
        y[i] = a[i] + b[i];
}

/* y += a over n floats */
ALWAYS void vadd_to(float *y, const float *a, int64_t n) {
    vadd3(y, y, a, n);
}

/* sum of (a - c)^2 (sq) or of a (!sq) over n floats */
ALWAYS float vsum(const float *a, float c, int sq, int64_t n) {
    v16 acc = {0};
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) {
        v16 u;
        V_LD(u, a + i);
        if (sq) u = (u - c) * (u - c);
        acc += u;
    }
    float s = hsum(&acc);
    for (; i < n; i++)
        s += sq ? (a[i] - c) * (a[i] - c) : a[i];
    return s;
}

/* z = (z - mean) rstd w + b over n floats (b may be NULL) */
ALWAYS void vnorm(float *z, float mean, float rstd, const float *w, const float *b, int64_t n) {
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) {
        v16 u, wv, bv = {0};
        V_LD(u, z + i), V_LD(wv, w + i);
        if (b) V_LD(bv, b + i);
        u = (u - mean) * rstd * wv + bv;
        V_ST(z + i, u);
    }
    for (; i < n; i++)
        z[i] = (z[i] - mean) * rstd * w[i] + (b ? b[i] : 0.0f);
}

/* z = act(z) over n floats: ReLU and LeakyReLU here in vectors (the
 * common case, a select), the others through cpu_vmath.c's spans. */
ALWAYS void act_span(int level, cr_op act, float p, float *z, int64_t n) {
    if (act != CR_OP_RELU && act != CR_OP_LEAKY_RELU) {
        cr_nn_cpu_act_span(level, act, p, z, z, n);
        return;
    }
    const float slope = act == CR_OP_RELU ? 0.0f : p;
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) {
        v16 v, neg;
        V_LD(v, z + i);
        neg = v * slope;
        vi16 pos = v > 0.0f;
        v = (v16)((pos & (vi16)v) | (~pos & (vi16)neg));
        V_ST(z + i, v);
    }
    for (; i < n; i++)
        z[i] = nn_cpu_act(act, p, z[i]);
}

#if NN_CPU_X86
/* rows_matmul on whole 16-column blocks with fused multiply-adds (the
 * build's ISO C mode contracts no a + x w in the vector-type code), in
 * AVX-512 or as two AVX2 halves; the rest of the columns left to
 * rows_matmul. Returns the columns done. */
static __attribute__((target("avx512f"), noinline)) int64_t
rows_matmul_avx512(float *y, int64_t ldy, const float *const *x, int64_t in, const float *wt,
                   int64_t out, int64_t R) {
    int64_t j = 0;
    /* 64 columns over 4 rows: 16 independent chains of multiply-adds, enough
     * to hide the FMA's latency (4 x 16 had 4: latency-bound) */
    for (; j + 64 <= out; j += 64) {
        int64_t r = 0;
        for (; r + 4 <= R; r += 4) {
            /* named accumulators: an array of them was kept in memory */
#define ROW4_LOAD(i)                                                                               \
    __m512 a##i##0 = _mm512_loadu_ps(y + (r + i) * ldy + j),                                       \
           a##i##1 = _mm512_loadu_ps(y + (r + i) * ldy + j + 16),                                  \
           a##i##2 = _mm512_loadu_ps(y + (r + i) * ldy + j + 32),                                  \
           a##i##3 = _mm512_loadu_ps(y + (r + i) * ldy + j + 48)
#define ROW4_FMA(i)                                                                                \
    do {                                                                                           \
        const __m512 b = _mm512_set1_ps(x[r + i][k]);                                              \
        a##i##0 = _mm512_fmadd_ps(b, w0, a##i##0), a##i##1 = _mm512_fmadd_ps(b, w1, a##i##1);      \
        a##i##2 = _mm512_fmadd_ps(b, w2, a##i##2), a##i##3 = _mm512_fmadd_ps(b, w3, a##i##3);      \
    } while (0)
#define ROW4_STORE(i)                                                                              \
    _mm512_storeu_ps(y + (r + i) * ldy + j, a##i##0),                                              \
        _mm512_storeu_ps(y + (r + i) * ldy + j + 16, a##i##1),                                     \
        _mm512_storeu_ps(y + (r + i) * ldy + j + 32, a##i##2),                                     \
        _mm512_storeu_ps(y + (r + i) * ldy + j + 48, a##i##3)
            ROW4_LOAD(0);
            ROW4_LOAD(1);
            ROW4_LOAD(2);
            ROW4_LOAD(3);
            for (int64_t k = 0; k < in; k++) {
                const float *wk = wt + k * out + j;
                const __m512 w0 = _mm512_loadu_ps(wk), w1 = _mm512_loadu_ps(wk + 16);
                const __m512 w2 = _mm512_loadu_ps(wk + 32), w3 = _mm512_loadu_ps(wk + 48);
                ROW4_FMA(0);
                ROW4_FMA(1);
                ROW4_FMA(2);
                ROW4_FMA(3);
            }
            ROW4_STORE(0);
            ROW4_STORE(1);
            ROW4_STORE(2);
            ROW4_STORE(3);
#undef ROW4_LOAD
#undef ROW4_FMA
#undef ROW4_STORE
        }
        for (; r < R; r++) {
            float *y0 = y + r * ldy + j;
            __m512 a0 = _mm512_loadu_ps(y0), a1 = _mm512_loadu_ps(y0 + 16);
            __m512 a2 = _mm512_loadu_ps(y0 + 32), a3 = _mm512_loadu_ps(y0 + 48);
            for (int64_t k = 0; k < in; k++) {
                const float *wk = wt + k * out + j;
                const __m512 b = _mm512_set1_ps(x[r][k]);
                a0 = _mm512_fmadd_ps(b, _mm512_loadu_ps(wk), a0);
                a1 = _mm512_fmadd_ps(b, _mm512_loadu_ps(wk + 16), a1);
                a2 = _mm512_fmadd_ps(b, _mm512_loadu_ps(wk + 32), a2);
                a3 = _mm512_fmadd_ps(b, _mm512_loadu_ps(wk + 48), a3);
            }
            _mm512_storeu_ps(y0, a0), _mm512_storeu_ps(y0 + 16, a1);
            _mm512_storeu_ps(y0 + 32, a2), _mm512_storeu_ps(y0 + 48, a3);
        }
    }
    for (; j + 16 <= out; j += 16) {
        int64_t r = 0;
        for (; r + 4 <= R; r += 4) {
            const float *x0 = x[r], *x1 = x[r + 1], *x2 = x[r + 2], *x3 = x[r + 3];
            float *y0 = y + r * ldy + j;
            __m512 a0 = _mm512_loadu_ps(y0), a1 = _mm512_loadu_ps(y0 + ldy);
            __m512 a2 = _mm512_loadu_ps(y0 + 2 * ldy), a3 = _mm512_loadu_ps(y0 + 3 * ldy);
            for (int64_t k = 0; k < in; k++) {
                __m512 w = _mm512_loadu_ps(wt + k * out + j);
                a0 = _mm512_fmadd_ps(_mm512_set1_ps(x0[k]), w, a0);
                a1 = _mm512_fmadd_ps(_mm512_set1_ps(x1[k]), w, a1);
                a2 = _mm512_fmadd_ps(_mm512_set1_ps(x2[k]), w, a2);
                a3 = _mm512_fmadd_ps(_mm512_set1_ps(x3[k]), w, a3);
            }
            _mm512_storeu_ps(y0, a0), _mm512_storeu_ps(y0 + ldy, a1);
            _mm512_storeu_ps(y0 + 2 * ldy, a2), _mm512_storeu_ps(y0 + 3 * ldy, a3);
        }
        for (; r < R; r++) {
            float *y0 = y + r * ldy + j;
            __m512 a0 = _mm512_loadu_ps(y0);
            for (int64_t k = 0; k < in; k++)
                a0 =
                    _mm512_fmadd_ps(_mm512_set1_ps(x[r][k]), _mm512_loadu_ps(wt + k * out + j), a0);
            _mm512_storeu_ps(y0, a0);
        }
    }
    return j;
}

static __attribute__((target("avx2,fma"), noinline)) int64_t
rows_matmul_avx2(float *y, int64_t ldy, const float *const *x, int64_t in, const float *wt,
                 int64_t out, int64_t R) {
    int64_t j = 0;
    for (; j + 16 <= out; j += 16)
        for (int64_t r = 0; r < R; r++) {
            float *y0 = y + r * ldy + j;
            __m256 a0 = _mm256_loadu_ps(y0), a1 = _mm256_loadu_ps(y0 + 8);
            for (int64_t k = 0; k < in; k++) {
                __m256 xk = _mm256_set1_ps(x[r][k]);
                a0 = _mm256_fmadd_ps(xk, _mm256_loadu_ps(wt + k * out + j), a0);
                a1 = _mm256_fmadd_ps(xk, _mm256_loadu_ps(wt + k * out + j + 8), a1);
            }
            _mm256_storeu_ps(y0, a0), _mm256_storeu_ps(y0 + 8, a1);
        }
    return j;
}
#endif

/* y[r] += x[r] wt on SIMD `level`. */
ALWAYS void rows_product(int level, float *y, int64_t ldy, const float *const *x, int64_t in,
                         const float *wt, int64_t out, int64_t R) {
    int64_t j = 0;
#if NN_CPU_X86
    if (level >= NN_SIMD_AVX512)
        j = rows_matmul_avx512(y, ldy, x, in, wt, out, R);
    else if (level >= NN_SIMD_AVX2)
        j = rows_matmul_avx2(y, ldy, x, in, wt, out, R);
#else
    (void)level;
#endif
    if (j < out) rows_matmul(y + j, ldy, x, in, wt + j, out - j, R, out);
}

/* Rows [r0, r0 + R) of the block, into out (and agg from node n0 on). */
ALWAYS void mpnn_tile(const mpnn_pass *P, int64_t r0, int64_t R, int64_t *node, float *za,
                      float *zb) {
    const nn_mpnn_block_args *a = P->a;
    const float *xr[TILE];
    const int64_t ldx = a->ldx > 0 ? a->ldx : a->width[0];
    for (int64_t r = 0; r < R; r++)
        xr[r] = a->x + (a->x_rows ? a->x_rows[r0 + r] : r0 + r) * ldx;
    float *z = za, *zn = zb;
    for (int l = 0; l < a->nl; l++) {
        const int64_t in = a->width[l], out = a->width[l + 1];
        for (int64_t r = 0; r < R; r++) {
            float *zr = zn + r * out;
            if (P->b[l])
                memcpy(zr, P->b[l], sizeof(float) * (size_t)out);
            else
                memset(zr, 0, sizeof(float) * (size_t)out);
            for (int g = 0; l == 0 && g < 2; g++)
                if (a->gath[g])
                    vadd_to(zr, a->gath[g] + (int64_t)a->gath_idx[g][r0 + r] * out, out);
        }
        const float *rows[TILE];
        for (int64_t r = 0; r < R; r++)
            rows[r] = l == 0 ? xr[r] : z + r * in;
        rows_product(P->level, zn, out, rows, in, P->wt[l], out, R);
        act_span(P->level, a->act[l], a->act_p[l], zn, R * out);
        float *t = z;
        z = zn, zn = t;
    }
    const int64_t C = a->width[a->nl];
    for (int64_t r = 0; r < R; r++) {
        float *zr = z + r * C;
        if (a->ln_w) {
            const float mean = vsum(zr, 0.0f, 0, C) / (float)C;
            const float var = vsum(zr, mean, 1, C) / (float)C;
            vnorm(zr, mean, 1.0f / sqrtf(var + a->ln_eps), a->ln_w, a->ln_b, C);
        }
        float *o = a->out + (r0 + r) * C;
        if (a->res)
            vadd3(o, a->res + (r0 + r) * C, zr, C);
        else
            memcpy(o, zr, sizeof(float) * (size_t)C);
        if (a->agg) {
            while (a->off[*node + 1] <= r0 + r)
                (*node)++;
            vadd_to(a->agg + *node * (a->ld_agg > 0 ? a->ld_agg : C), o, C);
        }
    }
}

/* Rows [begin, end) in tiles; node: the first row's receiver (agg). */
ALWAYS void mpnn_rows(const mpnn_pass *P, int64_t begin, int64_t end, int64_t node) {
    float za[TILE * NN_MPNN_MAX_WIDTH], zb[TILE * NN_MPNN_MAX_WIDTH];
    for (int64_t r = begin; r < end; r += TILE)
        mpnn_tile(P, r, end - r < TILE ? end - r : TILE, &node, za, zb);
}

/* Over rows (no agg), or over receivers: their sums zeroed, then their rows. */
ALWAYS void mpnn_body(void *vctx, int64_t begin, int64_t end) {
    const mpnn_pass *P = vctx;
    const nn_mpnn_block_args *a = P->a;
    if (!a->agg) {
        mpnn_rows(P, begin, end, 0);
        return;
    }
    const int64_t C = a->width[a->nl];
    const int64_t ld = a->ld_agg > 0 ? a->ld_agg : C;
    for (int64_t n = begin; n < end; n++)
        memset(a->agg + n * ld, 0, sizeof(float) * (size_t)C);
    mpnn_rows(P, a->off[begin], a->off[end], begin);
}

static void mpnn_scalar(void *vctx, int64_t begin, int64_t end) {
    mpnn_body(vctx, begin, end);
}

#if defined(__x86_64__) || defined(__i386__)
static __attribute__((target("avx2,fma"))) void mpnn_avx2(void *vctx, int64_t begin, int64_t end) {
    mpnn_body(vctx, begin, end);
}

static __attribute__((target("avx512f"))) void mpnn_avx512(void *vctx, int64_t begin, int64_t end) {
    mpnn_body(vctx, begin, end);
}
#endif

#if NN_CPU_X86
/* ------------------------------------- 16 wide, one row in one register -- */

/* act(z) on one register: ReLU and LeakyReLU as a max and a blend, the
 * others one float at a time through nn_cpu_act. */
static inline __attribute__((target("avx512f"), always_inline)) __m512 act16(cr_op act, float p,
                                                                             __m512 z) {
    if (act == CR_OP_NONE) return z;
    if (act == CR_OP_RELU) return _mm512_max_ps(z, _mm512_setzero_ps());
    if (act == CR_OP_LEAKY_RELU) {
        __mmask16 pos = _mm512_cmp_ps_mask(z, _mm512_setzero_ps(), _CMP_GT_OQ);
        return _mm512_mask_blend_ps(pos, _mm512_mul_ps(z, _mm512_set1_ps(p)), z);
    }
    float t[16];
    _mm512_storeu_ps(t, z);
    for (int i = 0; i < 16; i++)
        t[i] = nn_cpu_act(act, p, t[i]);
    return _mm512_loadu_ps(t);
}

/* Each lane the sum of v's lanes. */
static inline __attribute__((target("avx512f"), always_inline)) __m512 sum16(__m512 v) {
    v = _mm512_add_ps(v, _mm512_shuffle_f32x4(v, v, 0x4e)); /* 256-bit halves swapped */
    v = _mm512_add_ps(v, _mm512_shuffle_f32x4(v, v, 0xb1)); /* 128-bit pairs swapped */
    v = _mm512_add_ps(v, _mm512_permute_ps(v, 0x4e));       /* 64-bit pairs */
    return _mm512_add_ps(v, _mm512_permute_ps(v, 0xb1));    /* neighbours */
}

/* 1 / sqrt(v): the 14-bit estimate and a Newton step (relative error
 * about 1e-7, where the divide and square root cost 20 cycles a row). */
static inline __attribute__((target("avx512f"), always_inline)) __m512 rsqrt16(__m512 v) {
    const __m512 y = _mm512_rsqrt14_ps(v);
    const __m512 vyy = _mm512_mul_ps(_mm512_mul_ps(v, y), y);
    return _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f), y),
                         _mm512_sub_ps(_mm512_set1_ps(3.0f), vyy));
}

/* The block on rows r .. r + n - 1 (n in 1..ROWS16, every layer 16 wide) in
 * registers, ROWS16 rows side by side so that their chains of multiply-adds overlap (two
 * FMA units of four cycles' latency) (lanes
 * past n repeat the last row and are not stored): out's rows written, their
 * values left in z (for the receiver's sum). */
static inline __attribute__((target("avx512f"), always_inline)) void
rows16(const mpnn_pass *P, int64_t r, int n, __m512 z[ROWS16]) {
    const nn_mpnn_block_args *a = P->a;
    const float *x[ROWS16];
#pragma GCC unroll 8
    for (int i = 0; i < ROWS16; i++) {
        const int64_t ri = r + (i < n ? i : n - 1);
        x[i] = a->x + (a->x_rows ? a->x_rows[ri] : ri) * (a->ldx > 0 ? a->ldx : a->width[0]);
        z[i] = P->b[0] ? _mm512_loadu_ps(P->b[0]) : _mm512_setzero_ps();
        for (int g = 0; g < 2; g++)
            if (a->gath[g])
                z[i] = _mm512_add_ps(
                    z[i], _mm512_loadu_ps(a->gath[g] + 16 * (int64_t)a->gath_idx[g][ri]));
    }
    const float *in[ROWS16];
    float t[ROWS16][16];
    memcpy(in, x, sizeof in);
    for (int l = 0; l < a->nl; l++) {
        const float *wt = P->wt[l];
        if (l > 0) {
#pragma GCC unroll 8
            for (int i = 0; i < ROWS16; i++) {
                _mm512_storeu_ps(t[i], z[i]);
                in[i] = t[i];
                z[i] = P->b[l] ? _mm512_loadu_ps(P->b[l]) : _mm512_setzero_ps();
            }
        }
        for (int64_t k = 0; k < a->width[l]; k++) {
            const __m512 w = _mm512_loadu_ps(wt + 16 * k);
#pragma GCC unroll 8
            for (int i = 0; i < ROWS16; i++)
                z[i] = _mm512_fmadd_ps(_mm512_set1_ps(in[i][k]), w, z[i]);
        }
#pragma GCC unroll 8
        for (int i = 0; i < ROWS16; i++)
            z[i] = act16(a->act[l], a->act_p[l], z[i]);
    }
    const __m512 inv = _mm512_set1_ps(1.0f / 16.0f);
#pragma GCC unroll 8
    for (int i = 0; i < ROWS16; i++) {
        if (a->ln_w) {
            const __m512 d =
                P->centred ? z[i] : _mm512_sub_ps(z[i], _mm512_mul_ps(sum16(z[i]), inv));
            const __m512 var = _mm512_mul_ps(sum16(_mm512_mul_ps(d, d)), inv);
            const __m512 rstd = rsqrt16(_mm512_add_ps(var, _mm512_set1_ps(a->ln_eps)));
            z[i] = _mm512_mul_ps(_mm512_mul_ps(d, rstd), _mm512_loadu_ps(a->ln_w));
            if (a->ln_b) z[i] = _mm512_add_ps(z[i], _mm512_loadu_ps(a->ln_b));
        }
        const int64_t ri = r + (i < n ? i : n - 1);
        if (a->res) z[i] = _mm512_add_ps(z[i], _mm512_loadu_ps(a->res + 16 * ri));
        if (i < n) _mm512_storeu_ps(a->out + 16 * ri, z[i]);
    }
}

/* Rows [r0, r1), ROWS16 at a time; the sum of their values. */
static inline __attribute__((target("avx512f"), always_inline)) __m512
span16(const mpnn_pass *P, int64_t r0, int64_t r1) {
    __m512 s = _mm512_setzero_ps(), z[ROWS16];
    for (int64_t r = r0; r < r1; r += ROWS16) {
        const int n = r1 - r < ROWS16 ? (int)(r1 - r) : ROWS16;
        rows16(P, r, n, z);
#pragma GCC unroll 8
        for (int i = 0; i < ROWS16; i++)
            if (i < n) s = _mm512_add_ps(s, z[i]);
    }
    return s;
}

/* Rows [begin, end), or with agg receivers [begin, end) and their rows. */
static __attribute__((target("avx512f"))) void mpnn16_avx512(void *vctx, int64_t begin,
                                                             int64_t end) {
    const mpnn_pass *P = vctx;
    const nn_mpnn_block_args *a = P->a;
    if (!a->agg) {
        span16(P, begin, end);
        return;
    }
    for (int64_t n = begin; n < end; n++)
        _mm512_storeu_ps(a->agg + (a->ld_agg > 0 ? a->ld_agg : 16) * n,
                         span16(P, a->off[n], a->off[n + 1]));
}

/* 1 when every layer's output is 16 wide (epnet's P-Net). */
static int all_16(const nn_mpnn_block_args *a) {
    for (int l = 1; l <= a->nl; l++)
        if (a->width[l] != 16) return 0;
    return 1;
}
#endif

/* The weights transposed into the scratch. With a LayerNorm after a last
 * layer without activation (and no gathered rows added to it), that layer's
 * weights and bias are centred over its outputs: z - mean(z) is then the
 * layer's own output, and the LayerNorm skips a sum across the row. */
void cr_nn_cpu_mpnn_block_forward(const nn_mpnn_block_args *a) {
    mpnn_pass P = {.a = a, .level = cr_nn_cpu_simd()};
    const int last = a->nl - 1;
    P.centred = a->ln_w && a->act[last] == CR_OP_NONE && (last > 0 || (!a->gath[0] && !a->gath[1]));
    float *t = a->scratch;
    for (int l = 0; l < a->nl; l++) {
        const int64_t in = a->width[l], out = a->width[l + 1];
        for (int64_t k = 0; k < in; k++) {
            float mean = 0.0f;
            for (int64_t j = 0; j < out; j++)
                mean += t[k * out + j] = a->w[l][j * a->ldw[l] + k];
            for (int64_t j = 0; P.centred && l == last && j < out; j++)
                t[k * out + j] -= mean / (float)out;
        }
        P.wt[l] = t, P.b[l] = a->b[l];
        t += in * out;
    }
    if (P.centred && a->b[last]) {
        const int64_t out = a->width[a->nl];
        float mean = 0.0f;
        for (int64_t j = 0; j < out; j++)
            mean += a->b[last][j];
        for (int64_t j = 0; j < out; j++)
            t[j] = a->b[last][j] - mean / (float)out;
        P.b[last] = t;
    }
    cr_range_fn fn = mpnn_scalar;
#if defined(__x86_64__) || defined(__i386__)
    if (P.level >= NN_SIMD_AVX512)
        fn = all_16(a) ? mpnn16_avx512 : mpnn_avx512;
    else if (P.level >= NN_SIMD_AVX2)
        fn = mpnn_avx2;
#endif
    if (!a->agg)
        cr_parallel_for(a->R, ROW_GRAIN, fn, &P);
    else /* receivers per chunk for about ROW_GRAIN rows */
        cr_parallel_for(a->N, a->R > 0 ? 1 + ROW_GRAIN * a->N / a->R : a->N, fn, &P);
}
