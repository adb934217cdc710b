/* cpu_wire.c: WIRE networks evaluated point by point from a hyper-network's
 * rows without the tape (cr_wire_hyper_infer, nn_layers.h; gdsr's fields,
 * two points a face at 10k vertices). Each point runs its row's layers in
 * order: the real first layer on its two inputs, then complex layers, WIRE
 * after every layer but the last, whose real part is the output.
 *
 * Two paths. Where the network is 16 wide and the CPU has AVX-512, a
 * layer's 16 values live in one register: each output row's complex
 * product with them is two vectors (real and imaginary parts over the
 * inputs), the 16 rows' sums come out of a tree of lane shuffles into one
 * register, and the activation runs on it in cpu_vmath_impl.h's vector exp
 * and sincos. Elsewhere the portable loop: each output a dot product summed
 * in 8 lanes, the activation vectorised over the width on AVX2 and
 * AVX-512. Arguments past SINCOS_MAX (8,192 rad) go to libm's sinf and cosf.
 * Differences from the tape's forward (a product per layer, libm's exp, sin
 * and cos), all within float rounding: sums in another order, the vector
 * functions' last bit (tests compare on every SIMD level).
 */
#include "crease/nn_layers.h"
#include "nn/cpu/cpu.h"

#include <math.h>
#include <string.h>

#include "nn/cpu/cpu_vmath_levels.h"

enum { WIRE_LANES = 8 };

static void wire_scalar(float *re, float *im, int64_t n, float omega0, float s2) {
    for (int64_t k = 0; k < n; k++) {
        const float a = re[k], b = im[k];
        const float e = expf(-omega0 * b - s2 * (a * a + b * b));
        re[k] = e * cosf(omega0 * a);
        im[k] = e * sinf(omega0 * a);
    }
}

#if defined(__x86_64__) || defined(__i386__)
/* The activation over whole vectors of n; returns how many were done. A
 * vector with an argument past SINCOS_MAX is done by the scalar code. */
#define WIRE_SPAN(V, VW, VT)                                                                       \
    static VT int64_t V(wire_span)(float *re, float *im, int64_t n, float omega0, float s2) {      \
        int64_t i = 0;                                                                             \
        for (; i + VW <= n; i += VW) {                                                             \
            V(vf) a = V(load)(re + i), b = V(load)(im + i);                                        \
            V(vi) big = V(abs)(a * omega0) > SINCOS_MAX;                                           \
            int any = 0;                                                                           \
            for (int l = 0; l < VW; l++)                                                           \
                any |= big[l];                                                                     \
            if (any) {                                                                             \
                wire_scalar(re + i, im + i, VW, omega0, s2);                                       \
                continue;                                                                          \
            }                                                                                      \
            V(wire)(&a, &b, omega0, s2);                                                           \
            V(store)(re + i, a), V(store)(im + i, b);                                              \
        }                                                                                          \
        return i;                                                                                  \
    }
#define NAME_AVX2(name) name##_avx2
#define NAME_AVX512(name) name##_avx512
WIRE_SPAN(NAME_AVX2, 8, __attribute__((target("avx2,fma"))))
WIRE_SPAN(NAME_AVX512, 16, __attribute__((target("avx512f"))))
#endif

static void wire_act(int level, float *re, float *im, int64_t n, float omega0, float s2) {
    int64_t k = 0;
#if defined(__x86_64__) || defined(__i386__)
    if (level >= NN_SIMD_AVX512)
        k = wire_span_avx512(re, im, n, omega0, s2);
    else if (level >= NN_SIMD_AVX2)
        k = wire_span_avx2(re, im, n, omega0, s2);
#else
    (void)level;
#endif
    wire_scalar(re + k, im + k, n - k, omega0, s2);
}

/* (yr + j yi) = sum_k (re_k + j im_k)(wr_k + j wi_k) + (br + j bi) over n,
 * summed in WIRE_LANES lanes (so the compiler's SLP pass vectorises the
 * block) and then across them. */
static void complex_dot(const float *re, const float *im, const float *wr, const float *wi, int n,
                        float *yr, float *yi, float br, float bi) {
    float pr[WIRE_LANES] = {0}, pi[WIRE_LANES] = {0};
    int k = 0;
    for (; k + WIRE_LANES <= n; k += WIRE_LANES)
        for (int l = 0; l < WIRE_LANES; l++) {
            const float a = re[k + l], b = im[k + l], c = wr[k + l], d = wi[k + l];
            pr[l] += a * c - b * d;
            pi[l] += a * d + b * c;
        }
    for (int l = 0; k < n; k++, l++) {
        pr[l] += re[k] * wr[k] - im[k] * wi[k];
        pi[l] += re[k] * wi[k] + im[k] * wr[k];
    }
    float sr = br, si = bi;
    for (int l = 0; l < WIRE_LANES; l++)
        sr += pr[l], si += pi[l];
    *yr = sr, *yi = si;
}

/* One point on the portable path. */
static void point_portable(const nn_wire_points_args *a, int level, const float *t, float u,
                           float v, float *y) {
    const int w = a->width;
    float re[CR_WIRE_MAX_WIDTH], im[CR_WIRE_MAX_WIDTH], yr[CR_WIRE_MAX_WIDTH],
        yi[CR_WIRE_MAX_WIDTH];
    const float *W0 = t, *b0 = t + 2 * w;
    for (int o = 0; o < w; o++)
        re[o] = u * W0[2 * o] + v * W0[2 * o + 1] + b0[o], im[o] = 0.0f;
    wire_act(level, re, im, w, a->omega0, a->s2);
    t += 3 * w;
    for (int l = 1; l < a->layers; l++) {
        const int last = l == a->layers - 1, no = last ? a->out : w;
        const float *Wr = t, *Wi = Wr + no * w, *br = Wi + no * w, *bi = br + no;
        for (int o = 0; o < no; o++)
            complex_dot(re, im, Wr + o * w, Wi + o * w, w, &yr[o], &yi[o], br[o], bi[o]);
        t += 2 * (int64_t)no * w + 2 * no;
        if (last) {
            memcpy(y, yr, sizeof(float) * (size_t)no);
            return;
        }
        memcpy(re, yr, sizeof(float) * (size_t)w);
        memcpy(im, yi, sizeof(float) * (size_t)w);
        wire_act(level, re, im, w, a->omega0, a->s2);
    }
}

#if defined(__x86_64__) || defined(__i386__)
/* The activation on one register of 16. */
static inline __attribute__((target("avx512f"), always_inline)) void act16(__m512 *re, __m512 *im,
                                                                           float omega0, float s2) {
    __m512 arg = _mm512_mul_ps(*re, _mm512_set1_ps(omega0));
    __m512 big = _mm512_abs_ps(arg);
    if (_mm512_cmp_ps_mask(big, _mm512_set1_ps(SINCOS_MAX), _CMP_GT_OQ)) {
        float r[16], i[16];
        _mm512_storeu_ps(r, *re), _mm512_storeu_ps(i, *im);
        wire_scalar(r, i, 16, omega0, s2);
        *re = _mm512_loadu_ps(r), *im = _mm512_loadu_ps(i);
        return;
    }
    vf_avx512 a = (vf_avx512)*re, b = (vf_avx512)*im;
    wire_avx512(&a, &b, omega0, s2);
    *re = (__m512)a, *im = (__m512)b;
}

/* out[o] = sum over lanes of v[o], o < 16, for v[o] produced by row(o): the
 * rows o and o + 8 are combined as they come (so 8 registers stay live),
 * then halved three times; the tree leaves the sums in lane order
 * 0 2 1 3 8 10 9 11 4 6 5 7 12 14 13 15, undone by one permutation. */
#define PAIR_HALVES(a, b)                                                                          \
    _mm512_add_ps(_mm512_shuffle_f32x4(a, b, 0x44), _mm512_shuffle_f32x4(a, b, 0xEE))
#define PAIR_QUARTERS(a, b)                                                                        \
    _mm512_add_ps(_mm512_shuffle_f32x4(a, b, 0x88), _mm512_shuffle_f32x4(a, b, 0xDD))
#define PAIR_PAIRS(a, b) _mm512_add_ps(_mm512_shuffle_ps(a, b, 0x44), _mm512_shuffle_ps(a, b, 0xEE))
#define PAIR_ONES(a, b) _mm512_add_ps(_mm512_shuffle_ps(a, b, 0x88), _mm512_shuffle_ps(a, b, 0xDD))

static inline __attribute__((target("avx512f"), always_inline)) __m512 sums16(const __m512 h[8]) {
    __m512 q0 = PAIR_QUARTERS(h[0], h[4]), q1 = PAIR_QUARTERS(h[1], h[5]);
    __m512 q2 = PAIR_QUARTERS(h[2], h[6]), q3 = PAIR_QUARTERS(h[3], h[7]);
    __m512 p0 = PAIR_PAIRS(q0, q2), p1 = PAIR_PAIRS(q1, q3);
    __m512 r = PAIR_ONES(p0, p1);
    const __m512i order = _mm512_setr_epi32(0, 2, 1, 3, 8, 10, 9, 11, 4, 6, 5, 7, 12, 14, 13, 15);
    return _mm512_permutexvar_ps(order, r);
}

/* One point of a 16-wide network on AVX-512. */
static __attribute__((target("avx512f"))) void point16(const nn_wire_points_args *a, const float *t,
                                                       float u, float v, float *y) {
    const __m512i even =
        _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    const __m512i odd =
        _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
    const __m512 w0 = _mm512_loadu_ps(t), w1 = _mm512_loadu_ps(t + 16);
    __m512 re =
        _mm512_fmadd_ps(_mm512_set1_ps(u), _mm512_permutex2var_ps(w0, even, w1),
                        _mm512_fmadd_ps(_mm512_set1_ps(v), _mm512_permutex2var_ps(w0, odd, w1),
                                        _mm512_loadu_ps(t + 32)));
    __m512 im = _mm512_setzero_ps();
    act16(&re, &im, a->omega0, a->s2);
    t += 48;
    for (int l = 1; l < a->layers; l++) {
        const int last = l == a->layers - 1, no = last ? a->out : 16;
        const float *Wr = t, *Wi = Wr + 16 * no, *br = Wi + 16 * no, *bi = br + no;
        if (last) {
            for (int o = 0; o < no; o++) {
                __m512 p = _mm512_fmsub_ps(re, _mm512_loadu_ps(Wr + 16 * o),
                                           _mm512_mul_ps(im, _mm512_loadu_ps(Wi + 16 * o)));
                y[o] = _mm512_reduce_add_ps(p) + br[o];
            }
            return;
        }
        __m512 hr[8], hi[8];
        for (int o = 0; o < 8; o++) {
            const __m512 ar = _mm512_loadu_ps(Wr + 16 * o), ai = _mm512_loadu_ps(Wi + 16 * o);
            const __m512 br8 = _mm512_loadu_ps(Wr + 16 * (o + 8));
            const __m512 bi8 = _mm512_loadu_ps(Wi + 16 * (o + 8));
            __m512 pr = _mm512_fmsub_ps(re, ar, _mm512_mul_ps(im, ai));
            __m512 pi = _mm512_fmadd_ps(re, ai, _mm512_mul_ps(im, ar));
            __m512 qr = _mm512_fmsub_ps(re, br8, _mm512_mul_ps(im, bi8));
            __m512 qi = _mm512_fmadd_ps(re, bi8, _mm512_mul_ps(im, br8));
            hr[o] = PAIR_HALVES(pr, qr), hi[o] = PAIR_HALVES(pi, qi);
        }
        re = _mm512_add_ps(sums16(hr), _mm512_loadu_ps(br));
        im = _mm512_add_ps(sums16(hi), _mm512_loadu_ps(bi));
        act16(&re, &im, a->omega0, a->s2);
        t += 2 * 16 * no + 2 * no;
    }
}
#endif

typedef struct wire_pass {
    const nn_wire_points_args *a;
    int level;
} wire_pass;

/* Groups [begin, end): each row's points one after another, so its weights
 * (7 KB a row for gdsr's 16-wide network, 17 MB over its faces) are read
 * from memory once a row, not once a point. */
static void points_range(void *ctx, int64_t begin, int64_t end) {
    const wire_pass *p = ctx;
    const nn_wire_points_args *a = p->a;
    for (int64_t k = a->off[begin]; k < a->off[end]; k++) {
        const int64_t m = a->perm[k];
        const float *t = a->theta + (int64_t)a->group[m] * a->P;
        const float u = a->x[m * a->ldx], v = a->x[m * a->ldx + 1];
        float *y = a->y + m * a->out;
#if defined(__x86_64__) || defined(__i386__)
        if (p->level >= NN_SIMD_AVX512 && a->width == 16) {
            point16(a, t, u, v, y);
            continue;
        }
#endif
        point_portable(a, p->level, t, u, v, y);
    }
}

void cr_nn_cpu_wire_points_forward(const nn_wire_points_args *a) {
    wire_pass p = {.a = a, .level = cr_nn_cpu_simd()};
    const int64_t grain = a->M > 0 ? 1 + 256 * a->G / a->M : a->G; /* about 256 points */
    cr_parallel_for(a->G, grain, points_range, &p);
}
