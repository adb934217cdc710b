/* cpu_rnn.c: an LSTM cell's gates for inference (layer_rnn.c with the
 * context's gradient off) in one pass over blocks of rows instead of the
 * tape's slices, adds, products, sigmoids and tanhs (a dozen (B,H) arrays):
 *
 *   z = zx + zh,  z_i += c w_ci, z_f += c w_cf, z_o += c w_co  (peepholes, optional)
 *   i, f, o = sigmoid(z_i, z_f, z_o),  g = tanh(z_g)
 *   c' = f c + i g,  h' = o tanh(c')
 *
 * Gates are PyTorch's [i, f, g, o] along the 4H axis. The block's tanh gate
 * is 2 sigmoid(2 z) - 1, so one vector sigmoid covers the whole contiguous
 * block (absolute error a few 1e-8 against tanhf); the vector levels go
 * through cpu_vmath.c, the portable level is tanhf and the logistic.
 * Leaves out: the GRU (its reset gate multiplies inside the candidate's
 * product) and any gradient.
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <string.h>

enum { LSTM_BLOCK = 1024 }; /* floats of z a block holds at most (the rows stay in L1) */

typedef struct lstm_pass {
    const nn_lstm_gates_args *a;
    int level;
} lstm_pass;

/* Row-wise loops over 8 floats at a time in GCC/clang vector types (the
 * bodies below are inlined into functions compiled for AVX2 or AVX-512, where
 * these become ymm operations; -O2 leaves plain loops scalar), then the
 * tail. 8, not 16: the tiny model's gates are 8 wide, and these loops are a
 * small part next to the sigmoid and tanh spans. */
typedef float v8 __attribute__((vector_size(32)));
#define ALWAYS static inline __attribute__((always_inline))

/* Loads and stores of unaligned vectors as copies (no vector crosses a call). */
#define V_LD(v, p) memcpy(&(v), (p), sizeof(v8))
#define V_ST(p, v) memcpy((p), &(v), sizeof(v8))

/* y = a + b */
ALWAYS void vadd(float *y, const float *a, const float *b, int64_t n) {
    int64_t k = 0;
    for (; k + 8 <= n; k += 8) {
        v8 u, v;
        V_LD(u, a + k), V_LD(v, b + k);
        u += v;
        V_ST(y + k, u);
    }
    for (; k < n; k++)
        y[k] = a[k] + b[k];
}

/* y += a w */
ALWAYS void vfma(float *y, const float *a, const float *w, int64_t n) {
    int64_t k = 0;
    for (; k + 8 <= n; k += 8) {
        v8 u, v, x;
        V_LD(u, y + k), V_LD(v, a + k), V_LD(x, w + k);
        u += v * x;
        V_ST(y + k, u);
    }
    for (; k < n; k++)
        y[k] += a[k] * w[k];
}

/* y *= s */
ALWAYS void vscale(float *y, float s, int64_t n) {
    int64_t k = 0;
    for (; k + 8 <= n; k += 8) {
        v8 u;
        V_LD(u, y + k);
        u *= s;
        V_ST(y + k, u);
    }
    for (; k < n; k++)
        y[k] *= s;
}

/* c1 = f c + i (2 s - 1), c NULL: zero (s is sigmoid(2 z_g): tanh's gate) */
ALWAYS void vcell(float *c1, const float *i, const float *f, const float *s, const float *c,
                  int64_t n) {
    int64_t k = 0;
    for (; k + 8 <= n; k += 8) {
        v8 g, ik, fk, ck;
        V_LD(g, s + k), V_LD(ik, i + k);
        g = ik * (2.0f * g - 1.0f);
        if (c) {
            V_LD(fk, f + k), V_LD(ck, c + k);
            g += fk * ck;
        }
        V_ST(c1 + k, g);
    }
    for (; k < n; k++) {
        float g = 2.0f * s[k] - 1.0f;
        c1[k] = (c ? f[k] * c[k] : 0.0f) + i[k] * g;
    }
}

/* y *= a */
ALWAYS void vmul(float *y, const float *a, int64_t n) {
    int64_t k = 0;
    for (; k + 8 <= n; k += 8) {
        v8 u, v;
        V_LD(u, y + k), V_LD(v, a + k);
        u *= v;
        V_ST(y + k, u);
    }
    for (; k < n; k++)
        y[k] *= a[k];
}

/* Rows [begin, end) of one block. */
ALWAYS void lstm_rows(const lstm_pass *L, int64_t begin, int64_t end) {
    const nn_lstm_gates_args *a = L->a;
    const int64_t H = a->H, G = 4 * H, R = end - begin;
    float *zb = a->z + begin * G;
    if (a->zh)
        vadd(zb, a->zx + begin * G, a->zh + begin * G, R * G);
    else
        memcpy(zb, a->zx + begin * G, sizeof(float) * (size_t)(R * G));
    for (int64_t r = begin; r < end; r++) {
        const float *c = a->c ? a->c + r * H : NULL;
        float *z = a->z + r * G;
        if (c && a->pw[0]) {
            vfma(z, c, a->pw[0], H);
            vfma(z + H, c, a->pw[1], H);
            vfma(z + 3 * H, c, a->pw[2], H);
        }
        vscale(z + 2 * H, 2.0f, H);
    }
    cr_nn_cpu_act_span(L->level, CR_OP_SIGMOID, 0.0f, zb, zb, R * G);
    for (int64_t r = begin; r < end; r++) {
        const float *z = a->z + r * G;
        vcell(a->c_out + r * H, z, z + H, z + 2 * H, a->c ? a->c + r * H : NULL, H);
    }
    cr_nn_cpu_act_span(L->level, CR_OP_TANH, 0.0f, a->c_out + begin * H, a->h + begin * H, R * H);
    for (int64_t r = begin; r < end; r++)
        vmul(a->h + r * H, a->z + r * G + 3 * H, H);
}

ALWAYS void lstm_body(void *vctx, int64_t begin, int64_t end) {
    const lstm_pass *L = vctx;
    int64_t rows = LSTM_BLOCK / (4 * L->a->H) > 0 ? LSTM_BLOCK / (4 * L->a->H) : 1;
    for (int64_t r = begin; r < end; r += rows)
        lstm_rows(L, r, r + rows < end ? r + rows : end);
}

static void lstm_scalar(void *vctx, int64_t begin, int64_t end) {
    lstm_body(vctx, begin, end);
}

#if defined(__x86_64__) || defined(__i386__)
static __attribute__((target("avx2,fma"))) void lstm_avx2(void *vctx, int64_t begin, int64_t end) {
    lstm_body(vctx, begin, end);
}

static __attribute__((target("avx512f"))) void lstm_avx512(void *vctx, int64_t begin, int64_t end) {
    lstm_body(vctx, begin, end);
}
#endif

void cr_nn_cpu_lstm_gates_forward(const nn_lstm_gates_args *a) {
    lstm_pass L = {a, cr_nn_cpu_simd()};
    cr_range_fn fn = lstm_scalar;
#if defined(__x86_64__) || defined(__i386__)
    if (L.level >= NN_SIMD_AVX512)
        fn = lstm_avx512;
    else if (L.level >= NN_SIMD_AVX2)
        fn = lstm_avx2;
#endif
    cr_parallel_for(a->B, nn_cpu_row_grain(8 * a->H), fn, &L);
}
