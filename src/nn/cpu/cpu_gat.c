/* cpu_gat.c: GAT-LN's attention for inference (layer_gat.c with the
 * context's gradient off): the scores, eq. 4's Lipschitz normalisation, the
 * LeakyReLU, the softmax over each receiver's incoming edges and the
 * weighted sum of the senders' features, in passes over the receivers in
 * CSR order instead of a dozen tape ops that each write an (E,H) or
 * (E,H,F) array (docs/swingar.md, issue 51).
 *
 * The formulas are layer_gat.c's:
 *   g_ij   = s_dst_i + s_src_j,  s_*_n = a_* . W_h x_n = (W_h^T a_*) . x_n   (E,H)
 *   rows_i = sum_{j->i} g_ij^2,  den = max{sqrt(rows + ROW_TINY), |x|_max Lip} + DEN_TINY
 *   e_ij   = LeakyReLU(alpha g_ij / den),  w_ij = softmax over i's edges
 *   out_i  = act(sum_j w_ij p_j + b),  p_j = W x_j, heads concatenated or averaged
 * with |x|_max and the row norm global or per receiver as the def asks.
 * Two orders of the last line: project first (the caller's GEMM gives p,
 * the sums read H F floats an edge), or aggregate first (p NULL: per head
 * sum_j w_ij x_j, IN floats an edge, then one GEMM over the heads side by
 * side when averaged, one per head when concatenated): the same products.
 * Passes: the s_* of every node (one GEMM with the score vectors W_h^T a),
 * per receiver |x_i|, the raw scores and row norms, then per block of 64
 * receivers the logits, their exponentials, the weighted sums, bias and
 * activation (the global norm's maxima between the last two).
 * Differences from the tape, all within float rounding (tests compare):
 * sums over edges in float (the tape's are double); alpha / den multiplied
 * where the tape divides; with the normalisation on and alpha <= 30 no
 * maximum is subtracted before exp (|g*| <= alpha, and softmax does not
 * depend on the shift); the softmax sums divide the summed row at the end.
 * Paths: portable, AVX2 + FMA and AVX-512F (cr_nn_cpu_simd); row updates,
 * dots and up-to-16-head score loops in intrinsics, the exponentials and
 * activations through cpu_vmath.c; the portable path is the reference.
 * Leaves out: any gradient.
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <string.h>

/* layer_gat.c's floors (see there). */
static const float ROW_TINY = 1e-24f;
static const float DEN_TINY = 1e-12f;

enum {
    GATHER_ROW = 1024,  /* output widths summed in a local row (wider ones in place) */
    GATHER_PAD = 16,    /* room past the row for a whole vector */
    ATTEND_BLOCK = 64,  /* receivers whose exponentials and activations go as one span */
    BOUNDED_ALPHA = 30, /* exp(30) ~ 1e13: a receiver's sum stays far from FLT_MAX */
    GATHER_DEG = 64,    /* receivers with at most this many edges keep their senders' rows */
    SCORE_GEMM_MIN = 16 /* 2H from which the scores' halves are one GEMM (measured, tiny: 2H = 4) */
};

/* ------------------------------------------------- dot and axpy, 3 paths -- */

static float dot_scalar(const float *a, const float *b, int64_t n) {
    float s = 0.0f;
    for (int64_t i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static inline void axpy_scalar(float a, const float *x, float *y, int64_t n) {
    for (int64_t i = 0; i < n; i++)
        y[i] += a * x[i];
}

#if NN_CPU_X86
#define NN_AVX2 __attribute__((target("avx2,fma")))
#define NN_AVX512 __attribute__((target("avx512f")))

static NN_AVX2 float dot_avx2(const float *a, const float *b, int64_t n) {
    __m256 acc = _mm256_setzero_ps();
    int64_t i = 0;
    for (; i + 8 <= n; i += 8)
        acc = _mm256_fmadd_ps(_mm256_loadu_ps(a + i), _mm256_loadu_ps(b + i), acc);
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps(acc, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    s = _mm_add_ss(s, _mm_movehdup_ps(s));
    float r = _mm_cvtss_f32(s);
    for (; i < n; i++)
        r += a[i] * b[i];
    return r;
}

static inline NN_AVX2 void axpy_avx2(float a, const float *x, float *y, int64_t n) {
    static const int32_t lanes[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
    __m256 va = _mm256_set1_ps(a);
    int64_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(y + i,
                         _mm256_fmadd_ps(va, _mm256_loadu_ps(x + i), _mm256_loadu_ps(y + i)));
    if (i < n) { /* the first n - i lanes */
        __m256i m = _mm256_loadu_si256((const __m256i *)(lanes + 8 - (n - i)));
        _mm256_maskstore_ps(
            y + i, m,
            _mm256_fmadd_ps(va, _mm256_maskload_ps(x + i, m), _mm256_maskload_ps(y + i, m)));
    }
}

static NN_AVX512 float dot_avx512(const float *a, const float *b, int64_t n) {
    __m512 acc = _mm512_setzero_ps();
    int64_t i = 0;
    for (; i + 16 <= n; i += 16)
        acc = _mm512_fmadd_ps(_mm512_loadu_ps(a + i), _mm512_loadu_ps(b + i), acc);
    if (i < n) {
        __mmask16 m = (__mmask16)((1u << (n - i)) - 1u);
        acc =
            _mm512_fmadd_ps(_mm512_maskz_loadu_ps(m, a + i), _mm512_maskz_loadu_ps(m, b + i), acc);
    }
    return _mm512_reduce_add_ps(acc);
}

#endif

#if NN_CPU_X86
/* y[0..n) += a x[0..n) where y has a vector of room past n (the gather's
 * local row): x's tail is a masked load, y is read and written whole, so
 * the next edge's load of y forwards from this store (a masked store does
 * not forward: it cost a third of the gather). The extra lanes add a * 0. */
static inline NN_AVX2 void axpy_pad_avx2(float a, const float *x, float *y, int64_t n) {
    static const int32_t lanes[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
    __m256 va = _mm256_set1_ps(a);
    for (int64_t i = 0; i < n; i += 8) {
        __m256i m = _mm256_loadu_si256((const __m256i *)(lanes + 8 - (n - i >= 8 ? 8 : n - i)));
        _mm256_storeu_ps(y + i,
                         _mm256_fmadd_ps(va, _mm256_maskload_ps(x + i, m), _mm256_loadu_ps(y + i)));
    }
}
#endif

typedef float (*dot_fn)(const float *, const float *, int64_t);

/* ------------------------------------------------------------- passes -- */

typedef struct gat_pass {
    const nn_gat_attend_args *a;
    float *s;     /* (N,2H): s_dst then s_src of each node */
    float *score; /* (E,H) in CSR order */
    float *rows;  /* (N,H) sum of squared scores per receiver */
    float *xn;    /* (N) |x_n| */
    float *lip;   /* (H) */
    float *den;   /* (H) alpha over the global denominators (1 without a norm) */
    float *u;     /* (2H,IN) W_h^T a_dst then W_h^T a_src */
    float *agg;   /* (N,H*IN) per-head weighted sums of x (aggregate-first) */
    float *wcat;  /* (F,H*IN) W's heads side by side (aggregate-first) */
    dot_fn dot;
} gat_pass;

/* |x_n| of eq. 4. */
static void node_range(void *vctx, int64_t begin, int64_t end) {
    const gat_pass *g = vctx;
    const nn_gat_attend_args *a = g->a;
    for (int64_t n = begin; n < end; n++) {
        const float *xn = a->x + n * a->IN;
        g->xn[n] = sqrtf(g->dot(xn, xn, a->IN));
    }
}

/* s_* of nodes [begin, end) as 2H dot products each (few heads: cheaper
 * than the GEMM's narrow path). */
static void score_halves_range(void *vctx, int64_t begin, int64_t end) {
    const gat_pass *g = vctx;
    const nn_gat_attend_args *a = g->a;
    for (int64_t n = begin; n < end; n++)
        for (int64_t h = 0; h < 2 * a->H; h++)
            g->s[n * 2 * a->H + h] = g->dot(a->x + n * a->IN, g->u + h * a->IN, a->IN);
}

#if NN_CPU_X86
/* Up to 16 heads in one register, masked to H lanes: the per-edge loops
 * over heads below for AVX-512 (the portable loops kept their sums in
 * memory, a store-to-load chain per edge). */
static inline NN_AVX512 __mmask16 head_mask(int64_t H) {
    return (__mmask16)((1u << H) - 1u);
}

static NN_AVX512 void score_range_avx512(void *vctx, int64_t begin, int64_t end) {
    const gat_pass *g = vctx;
    const nn_gat_attend_args *a = g->a;
    const int64_t H = a->H;
    const __mmask16 m = head_mask(H);
    node_range(vctx, begin, end);
    for (int64_t i = begin; i < end; i++) {
        __m512 sd = _mm512_maskz_loadu_ps(m, g->s + i * 2 * H), rows = _mm512_setzero_ps();
        for (int64_t k = a->off[i]; k < a->off[i + 1]; k++) {
            __m512 ss = _mm512_maskz_loadu_ps(m, g->s + (int64_t)a->snd[a->perm[k]] * 2 * H + H);
            __m512 v = _mm512_add_ps(sd, ss);
            _mm512_mask_storeu_ps(g->score + k * H, m, v);
            rows = _mm512_fmadd_ps(v, v, rows);
        }
        _mm512_mask_storeu_ps(g->rows + i * H, m, rows);
    }
}

/* The bounded logits of a block under the global norm as one flat span:
 * x = LeakyReLU(x den[k mod H]) for H dividing 16 (den's pattern fills a
 * register). */
static NN_AVX512 void logits_flat_avx512(float *x, int64_t n, const float *den, int64_t H,
                                         float slope) {
    float pat[16];
    for (int l = 0; l < 16; l++)
        pat[l] = den[l % H];
    const __m512 d = _mm512_loadu_ps(pat), sl = _mm512_set1_ps(slope), z = _mm512_setzero_ps();
    for (int64_t k = 0; k < n; k += 16) {
        __mmask16 m = n - k >= 16 ? (__mmask16)0xffff : (__mmask16)((1u << (n - k)) - 1u);
        __m512 v = _mm512_mul_ps(_mm512_maskz_loadu_ps(m, x + k), d);
        __mmask16 pos = _mm512_cmp_ps_mask(v, z, _CMP_GT_OQ);
        _mm512_mask_storeu_ps(x + k, m, _mm512_mask_blend_ps(pos, _mm512_mul_ps(v, sl), v));
    }
}
#endif

/* |x_i|, the raw scores in CSR order and their squared row sums of the
 * receivers [begin, end). */
static void score_range(void *vctx, int64_t begin, int64_t end) {
    const gat_pass *g = vctx;
    const nn_gat_attend_args *a = g->a;
    int64_t H = a->H;
    node_range(vctx, begin, end);
    for (int64_t i = begin; i < end; i++) {
        const float *sd = g->s + i * 2 * H;
        float *rows = g->rows + i * H;
        for (int64_t h = 0; h < H; h++)
            rows[h] = 0.0f;
        for (int64_t k = a->off[i]; k < a->off[i + 1]; k++) {
            const float *ss = g->s + (int64_t)a->snd[a->perm[k]] * 2 * H + H;
            float *sc = g->score + k * H;
            for (int64_t h = 0; h < H; h++) {
                float v = sd[h] + ss[h];
                sc[h] = v;
                rows[h] += v * v;
            }
        }
    }
}

/* Normalised, activated scores minus each receiver's maximum per head. */
static void logit_range(const gat_pass *g, int64_t begin, int64_t end, int level) {
    const nn_gat_attend_args *a = g->a;
    /* Normalised scores obey |g*| <= alpha (layer_gat.c), so up to
     * BOUNDED_ALPHA their exponentials neither overflow nor vanish and the
     * softmax needs no maximum subtracted (the same weights, a rounding
     * apart); plain GAT scores are unbounded and keep it. */
    const int bounded = a->norm != NN_GAT_NORM_NONE && a->alpha <= BOUNDED_ALPHA;
#if NN_CPU_X86
    if (bounded && a->norm == NN_GAT_NORM_GLOBAL && level >= NN_SIMD_AVX512 && 16 % a->H == 0) {
        logits_flat_avx512(g->score + a->off[begin] * a->H, (a->off[end] - a->off[begin]) * a->H,
                           g->den, a->H, a->slope);
        return;
    }
#else
    (void)level;
#endif
    int64_t H = a->H;
    float den[NN_GAT_MAX_HEADS], mx[NN_GAT_MAX_HEADS];
    for (int64_t i = begin; i < end; i++) {
        int64_t k0 = a->off[i], k1 = a->off[i + 1];
        if (a->norm == NN_GAT_NORM_RECEIVER) {
            float xm = g->xn[i];
            for (int64_t k = k0; k < k1; k++) {
                float v = g->xn[a->snd[a->perm[k]]];
                xm = v > xm ? v : xm;
            }
            for (int64_t h = 0; h < H; h++) {
                float rn = sqrtf(g->rows[i * H + h] + ROW_TINY), lt = xm * g->lip[h];
                den[h] = a->alpha / ((rn >= lt ? rn : lt) + DEN_TINY);
            }
        }
        const float *dh = a->norm == NN_GAT_NORM_RECEIVER ? den : g->den;
        if (bounded) { /* one streaming pass: no maximum to subtract */
            for (int64_t k = k0; k < k1; k++) {
                float *sc = g->score + k * H;
                for (int64_t h = 0; h < H; h++) {
                    float v = sc[h] * dh[h];
                    sc[h] = nn_cpu_select_pos(v, v, a->slope * v);
                }
            }
            continue;
        }
        for (int64_t h = 0; h < H; h++)
            mx[h] = -INFINITY;
        for (int64_t k = k0; k < k1; k++) {
            float *sc = g->score + k * H;
            for (int64_t h = 0; h < H; h++) {
                float v = sc[h] * dh[h];
                v = nn_cpu_select_pos(v, v, a->slope * v);
                sc[h] = v;
                mx[h] = v > mx[h] ? v : mx[h];
            }
        }
        for (int64_t k = k0; k < k1; k++)
            for (int64_t h = 0; h < H; h++)
                g->score[k * H + h] -= mx[h];
    }
}

/* Softmax weights from the exponentials, then the weighted sum (portable and
 * AVX2; AVX-512 has gather_regs_avx512): one body per level so the row
 * updates inline (rows of a few floats are common: a call per edge and head
 * cost more than its work). */
static inline __attribute__((always_inline)) void gather_body(const gat_pass *g, int64_t begin,
                                                              int64_t end, int level) {
    const nn_gat_attend_args *a = g->a;
    /* sums of p's head slices (F wide) or, aggregate-first, of x (IN wide) per head */
    const int agg = a->p == NULL;
    const int64_t H = a->H, F = agg ? a->IN : a->F, HF = H * F;
    const int64_t C = agg || a->concat ? HF : F, stride = agg ? a->IN : HF;
    const float *src = agg ? a->x : a->p, *bias = agg ? NULL : a->bias;
    float *out = agg ? g->agg : a->out;
    float inv[NN_GAT_MAX_HEADS], acc[2 * (GATHER_ROW + GATHER_PAD)];
    const float scale = a->concat || agg ? 1.0f : 1.0f / (float)H;
    /* local: the row sums in acc, heads apart (averaged at the end) and even
     * and odd edges apart, so the updates form 2 H independent chains, not
     * one of length degree x H; else in place in out */
    const int local = HF <= GATHER_ROW, mean = C != HF;
    float *acc1 = acc + HF + GATHER_PAD;
    for (int64_t i = begin; i < end; i++) {
        int64_t k0 = a->off[i], k1 = a->off[i + 1];
        for (int64_t h = 0; h < H; h++)
            inv[h] = 0.0f;
        /* in place the weights are normalised first; in acc the sums of the
         * exponentials are taken on the way and divide at the end */
        for (int64_t k = k0; k < k1 && !local; k++)
            for (int64_t h = 0; h < H; h++)
                inv[h] += g->score[k * H + h];
        for (int64_t h = 0; h < H && !local; h++)
            inv[h] = inv[h] != 0.0f ? scale / inv[h] : 0.0f; /* no edges: a zero row */
        float *o = out + i * C;
        if (local)
            memset(acc, 0, sizeof(float) * (size_t)(2 * (HF + GATHER_PAD)));
        else
            memset(o, 0, sizeof(float) * (size_t)C);
        for (int64_t k = k0; k < k1; k++) {
            const float *sj = src + (int64_t)a->snd[a->perm[k]] * stride;
            const float *sc = g->score + k * H;
            float *row = local ? ((k - k0) & 1 ? acc1 : acc) : o;
            for (int64_t h = 0; h < H; h++) {
                float wt = local ? sc[h] : sc[h] * inv[h];
                if (local) inv[h] += sc[h];
                const float *x = agg ? sj : sj + h * F;
                float *dst = row + (mean && !local ? 0 : h * F);
#if NN_CPU_X86
                if (level == NN_SIMD_AVX2)
                    local ? axpy_pad_avx2(wt, x, dst, F) : axpy_avx2(wt, x, dst, F);
                else
#endif
                    axpy_scalar(wt, x, dst, F);
            }
        }
        for (int64_t h = 0; h < H && local; h++)
            inv[h] = inv[h] != 0.0f ? scale / inv[h] : 0.0f;
        if (local && mean) {
            for (int64_t c = 0; c < C; c++) {
                float v = bias ? bias[c] : 0.0f;
                for (int64_t h = 0; h < H; h++)
                    v += inv[h] * (acc[h * F + c] + acc1[h * F + c]);
                o[c] = v;
            }
        } else if (local) {
            for (int64_t h = 0; h < H; h++)
                for (int64_t c = h * F; c < (h + 1) * F; c++)
                    o[c] = inv[h] * (acc[c] + acc1[c]) + (bias ? bias[c] : 0.0f);
        } else if (bias) {
            for (int64_t c = 0; c < C; c++)
                o[c] += bias[c];
        }
    }
}

#if NN_CPU_X86
/* gather_body for AVX-512 with the sums in registers: 64 columns of a
 * head's row at a time in four accumulators over all edges (the other
 * paths update a row in memory, a store-to-load chain per edge and head),
 * the weights normalised before, the bias added at the store. */
static NN_AVX512 void gather_regs_avx512(const gat_pass *g, int64_t begin, int64_t end) {
    const nn_gat_attend_args *a = g->a;
    const int agg = a->p == NULL;
    const int64_t H = a->H, F = agg ? a->IN : a->F, HF = H * F;
    const int64_t C = agg || a->concat ? HF : F, stride = agg ? a->IN : HF;
    const int mean = C != HF;
    const float *src = agg ? a->x : a->p, *bias = agg ? NULL : a->bias;
    float *out = agg ? g->agg : a->out;
    const float scale = a->concat || agg ? 1.0f : 1.0f / (float)H;
    float inv[NN_GAT_MAX_HEADS];
    for (int64_t i = begin; i < end; i++) {
        const int64_t k0 = a->off[i], k1 = a->off[i + 1];
        for (int64_t h = 0; h < H; h++) { /* a register sum per head, not a chain through inv */
            float sum = 0.0f;
            for (int64_t k = k0; k < k1; k++)
                sum += g->score[k * H + h];
            inv[h] = sum != 0.0f ? scale / sum : 0.0f; /* no edges: a zero row */
        }
        for (int64_t k = k0; k < k1; k++) /* the weights, in place of the exponentials */
            for (int64_t h = 0; h < H; h++)
                g->score[k * H + h] *= inv[h];
        float *o = out + i * C;
        /* the senders' rows once per receiver (not per head and column block) */
        const int64_t deg = k1 - k0;
        const float *rows[GATHER_DEG];
        for (int64_t k = k0; k < k1 && deg <= GATHER_DEG; k++)
            rows[k - k0] = src + (int64_t)a->snd[a->perm[k]] * stride;
        for (int64_t c0 = 0; c0 < F; c0 += 64) {
            const int64_t nc = F - c0 < 64 ? F - c0 : 64, nr = (nc + 15) / 16;
            __mmask16 m[4];
            for (int r = 0; r < 4; r++) {
                int64_t lanes = nc - 16 * r;
                m[r] = lanes >= 16 ? (__mmask16)0xffff
                       : lanes > 0 ? (__mmask16)((1u << lanes) - 1u)
                                   : (__mmask16)0;
            }
            /* even edges into s, odd into t: two chains per register */
            __m512 z = _mm512_setzero_ps(), s0 = z, s1 = z, s2 = z, s3 = z;
            __m512 t0 = z, t1 = z, t2 = z, t3 = z;
            for (int64_t h = 0; h < H; h++) {
                if (!mean) s0 = s1 = s2 = s3 = t0 = t1 = t2 = t3 = z;
                const int64_t off = (agg ? 0 : h * F) + c0;
                int64_t k = k0;
                for (; k + 2 <= k1; k += 2) {
                    const float *x =
                        (deg <= GATHER_DEG ? rows[k - k0]
                                           : src + (int64_t)a->snd[a->perm[k]] * stride) +
                        off;
                    const float *y =
                        (deg <= GATHER_DEG ? rows[k + 1 - k0]
                                           : src + (int64_t)a->snd[a->perm[k + 1]] * stride) +
                        off;
                    __m512 w = _mm512_set1_ps(g->score[k * H + h]);
                    __m512 v = _mm512_set1_ps(g->score[(k + 1) * H + h]);
                    s0 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[0], x), s0);
                    t0 = _mm512_fmadd_ps(v, _mm512_maskz_loadu_ps(m[0], y), t0);
                    if (nr > 1) {
                        s1 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[1], x + 16), s1);
                        t1 = _mm512_fmadd_ps(v, _mm512_maskz_loadu_ps(m[1], y + 16), t1);
                    }
                    if (nr > 2) {
                        s2 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[2], x + 32), s2);
                        t2 = _mm512_fmadd_ps(v, _mm512_maskz_loadu_ps(m[2], y + 32), t2);
                    }
                    if (nr > 3) {
                        s3 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[3], x + 48), s3);
                        t3 = _mm512_fmadd_ps(v, _mm512_maskz_loadu_ps(m[3], y + 48), t3);
                    }
                }
                if (k < k1) {
                    const float *x = src + (int64_t)a->snd[a->perm[k]] * stride + off; /* once */
                    __m512 w = _mm512_set1_ps(g->score[k * H + h]);
                    s0 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[0], x), s0);
                    if (nr > 1) s1 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[1], x + 16), s1);
                    if (nr > 2) s2 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[2], x + 32), s2);
                    if (nr > 3) s3 = _mm512_fmadd_ps(w, _mm512_maskz_loadu_ps(m[3], x + 48), s3);
                }
                if (mean && h + 1 < H) continue;
                const int64_t d = (mean ? 0 : h * F) + c0;
                __m512 acc[4] = {_mm512_add_ps(s0, t0), _mm512_add_ps(s1, t1),
                                 _mm512_add_ps(s2, t2), _mm512_add_ps(s3, t3)};
                for (int r = 0; r < nr; r++) {
                    __m512 v = acc[r];
                    if (bias) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m[r], bias + d + 16 * r));
                    _mm512_mask_storeu_ps(o + d + 16 * r, m[r], v);
                }
            }
        }
    }
}
#endif

/* Logits, their exponentials, the weighted sums and the activation over
 * blocks of ATTEND_BLOCK receivers: the block's scores and output rows are
 * contiguous (CSR order), so the exponentials and the activation are whole
 * vector spans, and one parallel pass does all four. */
static inline __attribute__((always_inline)) void attend_body(const gat_pass *g, int64_t begin,
                                                              int64_t end, int level) {
    const nn_gat_attend_args *a = g->a;
    const int64_t H = a->H, C = a->concat ? H * a->F : a->F;
    for (int64_t b0 = begin; b0 < end; b0 += ATTEND_BLOCK) {
        int64_t b1 = b0 + ATTEND_BLOCK < end ? b0 + ATTEND_BLOCK : end;
        logit_range(g, b0, b1, level);
        cr_nn_cpu_act_span(level, CR_OP_EXP, 0.0f, g->score + a->off[b0] * H,
                           g->score + a->off[b0] * H, (a->off[b1] - a->off[b0]) * H);
#if NN_CPU_X86
        if (level == NN_SIMD_AVX512)
            gather_regs_avx512(g, b0, b1);
        else
#endif
            gather_body(g, b0, b1, level);
        if (a->p)
            cr_nn_cpu_act_span(level, a->act, a->act_p, a->out + b0 * C, a->out + b0 * C,
                               (b1 - b0) * C);
    }
}

/* Aggregate-first: out = act(out + bias) after the GEMM, by blocks of rows. */
static inline __attribute__((always_inline)) void finish_body(const gat_pass *g, int64_t begin,
                                                              int64_t end, int level) {
    const nn_gat_attend_args *a = g->a;
    const int64_t F = a->concat ? a->H * a->F : a->F; /* the output's width */
    for (int64_t b0 = begin; b0 < end; b0 += ATTEND_BLOCK) {
        int64_t b1 = b0 + ATTEND_BLOCK < end ? b0 + ATTEND_BLOCK : end;
        for (int64_t r = b0; r < b1 && a->bias; r++)
            for (int64_t f = 0; f < F; f++)
                a->out[r * F + f] += a->bias[f];
        cr_nn_cpu_act_span(level, a->act, a->act_p, a->out + b0 * F, a->out + b0 * F,
                           (b1 - b0) * F);
    }
}

static void finish_scalar(void *vctx, int64_t begin, int64_t end) {
    finish_body(vctx, begin, end, NN_SIMD_SCALAR);
}

#if NN_CPU_X86
static NN_AVX2 void finish_avx2(void *vctx, int64_t begin, int64_t end) {
    finish_body(vctx, begin, end, NN_SIMD_AVX2);
}

static NN_AVX512 void finish_avx512(void *vctx, int64_t begin, int64_t end) {
    finish_body(vctx, begin, end, NN_SIMD_AVX512);
}
#endif

static void attend_scalar(void *vctx, int64_t begin, int64_t end) {
    attend_body(vctx, begin, end, NN_SIMD_SCALAR);
}

#if NN_CPU_X86
static NN_AVX2 void attend_avx2(void *vctx, int64_t begin, int64_t end) {
    attend_body(vctx, begin, end, NN_SIMD_AVX2);
}

static NN_AVX512 void attend_avx512(void *vctx, int64_t begin, int64_t end) {
    attend_body(vctx, begin, end, NN_SIMD_AVX512);
}
#endif

/* u_h = W_h^T a_dst, W_h^T a_src (u (2H,IN)) and Lip(g) per head,
 * |[u_dst ; u_src]|, W (H*F,IN). */
static void score_vectors(const nn_gat_attend_args *a, float *u, float *lip) {
    const int64_t H = a->H, IN = a->IN, F = a->F;
    for (int64_t h = 0; h < H; h++) {
        double acc = 0.0;
        for (int64_t k = 0; k < IN; k++) {
            double ud = 0.0, us = 0.0;
            for (int64_t f = 0; f < F; f++) {
                double w = a->w[(h * F + f) * IN + k];
                ud += w * a->att_dst[h * F + f];
                us += w * a->att_src[h * F + f];
            }
            acc += ud * ud + us * us;
            u[h * IN + k] = (float)ud;
            u[(H + h) * IN + k] = (float)us;
        }
        lip[h] = (float)sqrt(acc);
    }
}

size_t cr_nn_cpu_gat_attend_scratch(const nn_gat_attend_args *a) {
    const int64_t N = a->N, H = a->H, E = a->off[N], IN = a->IN;
    size_t agg = a->p ? 0 : (size_t)((N + a->F) * H * IN);
    return (size_t)(2 * N * H + E * H + N * H + N + 2 * H + 2 * H * IN) + agg;
}

void cr_nn_cpu_gat_attend_forward(const nn_gat_attend_args *a) {
    CR_ASSERT(a->H >= 1 && a->H <= NN_GAT_MAX_HEADS && a->N >= 1);
    int64_t N = a->N, H = a->H, E = a->off[N];
    gat_pass g = {.a = a, .dot = dot_scalar};
    cr_range_fn attend = attend_scalar, finish = finish_scalar;
#if NN_CPU_X86
    int level = cr_nn_cpu_simd();
    if (level >= NN_SIMD_AVX512)
        g.dot = dot_avx512, attend = attend_avx512, finish = finish_avx512;
    else if (level >= NN_SIMD_AVX2)
        g.dot = dot_avx2, attend = attend_avx2, finish = finish_avx2;
#endif
    g.s = a->scratch;
    g.score = g.s + 2 * N * H;
    g.rows = g.score + E * H;
    g.xn = g.rows + N * H;
    g.lip = g.xn + N;
    g.den = g.lip + H;
    g.u = g.den + H;
    g.agg = g.u + 2 * H * a->IN;
    g.wcat = g.agg + N * H * a->IN;
    int64_t per = E / N + 1;
    /* the scores' halves a . W_h x = (W_h^T a) . x for every node: one GEMM,
     * or dot products for a few heads */
    score_vectors(a, g.u, g.lip);
    if (2 * H >= SCORE_GEMM_MIN)
        cr_nn_cpu_gemm(0, 1, N, 2 * H, a->IN, 1.0f, a->x, a->IN, g.u, a->IN, 0.0f, g.s, 2 * H);
    else
        cr_parallel_for(N, nn_cpu_row_grain(2 * H * a->IN), score_halves_range, &g);
    cr_range_fn scores = score_range;
#if NN_CPU_X86
    if (level >= NN_SIMD_AVX512 && H <= 16) scores = score_range_avx512;
#endif
    cr_parallel_for(N, nn_cpu_row_grain(per * H + a->IN), scores, &g);
    if (a->norm == NN_GAT_NORM_GLOBAL) {
        float xmax = g.xn[0];
        for (int64_t n = 1; n < N; n++)
            xmax = g.xn[n] > xmax ? g.xn[n] : xmax;
        for (int64_t h = 0; h < H; h++) {
            float rmax = g.rows[h];
            for (int64_t n = 1; n < N; n++)
                rmax = g.rows[n * H + h] > rmax ? g.rows[n * H + h] : rmax;
            float rn = sqrtf(rmax + ROW_TINY), lt = xmax * g.lip[h];
            g.den[h] = a->alpha / ((rn >= lt ? rn : lt) + DEN_TINY);
        }
    } else if (a->norm == NN_GAT_NORM_NONE) {
        for (int64_t h = 0; h < H; h++)
            g.den[h] = 1.0f;
    }
    cr_parallel_for(N, nn_cpu_row_grain(per * H * a->F), attend, &g);
    if (a->p) return;
    const int64_t IN = a->IN, F = a->F, HIN = H * IN;
    if (a->concat) { /* out_h = agg_h W_h^T, a product per head */
        cr_nn_cpu_gemm_batched(0, 1, N, F, IN, g.agg, HIN, IN, a->w, IN, F * IN, 0.0f, a->out,
                               H * F, F, H);
    } else { /* out = (1/H) sum_h agg_h W_h^T, one GEMM over the heads side by side */
        for (int64_t f = 0; f < F; f++)
            for (int64_t h = 0; h < H; h++)
                memcpy(g.wcat + f * HIN + h * IN, a->w + (h * F + f) * IN,
                       sizeof(float) * (size_t)IN);
        cr_nn_cpu_gemm(0, 1, N, F, HIN, 1.0f / (float)H, g.agg, HIN, g.wcat, HIN, 0.0f, a->out, F);
    }
    cr_parallel_for(N, nn_cpu_row_grain(a->concat ? H * F : F), finish, &g);
}
