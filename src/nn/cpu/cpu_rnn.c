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

enum { LSTM_BLOCK = 1024 }; /* floats of z a block holds at most (the rows stay in L1) */

typedef struct lstm_pass {
    const nn_lstm_gates_args *a;
    int level;
} lstm_pass;

/* out[k] = fn(x[k]) over n floats: the vector span, then the portable tail. */
static void span(int level, nn_vec_fn fn, const float *x, float *out, int64_t n) {
    int64_t k =
        level >= NN_SIMD_AVX2 ? cr_nn_cpu_vec_span(level, fn, 0.0f, x, NULL, NULL, out, 0, n) : 0;
    for (; k < n; k++)
        out[k] = fn == NN_VEC_TANH ? tanhf(x[k]) : nn_cpu_sigmoidf(x[k]);
}

static void lstm_range(void *vctx, int64_t begin, int64_t end) {
    const lstm_pass *L = vctx;
    const nn_lstm_gates_args *a = L->a;
    const int64_t H = a->H, G = 4 * H;
    for (int64_t r = begin; r < end; r++) {
        const float *zx = a->zx + r * G, *zh = a->zh ? a->zh + r * G : NULL;
        const float *c = a->c ? a->c + r * H : NULL;
        float *z = a->z + r * G;
        for (int64_t k = 0; k < G; k++)
            z[k] = zh ? zx[k] + zh[k] : zx[k];
        if (c && a->pw[0])
            for (int64_t k = 0; k < H; k++) {
                z[k] += c[k] * a->pw[0][k];
                z[H + k] += c[k] * a->pw[1][k];
                z[3 * H + k] += c[k] * a->pw[2][k];
            }
        for (int64_t k = 2 * H; k < 3 * H; k++)
            z[k] *= 2.0f;
    }
    span(L->level, NN_VEC_SIGMOID, a->z + begin * G, a->z + begin * G, (end - begin) * G);
    for (int64_t r = begin; r < end; r++) {
        const float *z = a->z + r * G, *c = a->c ? a->c + r * H : NULL;
        float *c1 = a->c_out + r * H;
        for (int64_t k = 0; k < H; k++) {
            float g = 2.0f * z[2 * H + k] - 1.0f;
            c1[k] = (c ? z[H + k] * c[k] : 0.0f) + z[k] * g;
        }
    }
    span(L->level, NN_VEC_TANH, a->c_out + begin * H, a->h + begin * H, (end - begin) * H);
    for (int64_t r = begin; r < end; r++)
        for (int64_t k = 0; k < H; k++)
            a->h[r * H + k] *= a->z[r * G + 3 * H + k];
}

static void lstm_blocks(void *vctx, int64_t begin, int64_t end) {
    const lstm_pass *L = vctx;
    int64_t rows = LSTM_BLOCK / (4 * L->a->H) > 0 ? LSTM_BLOCK / (4 * L->a->H) : 1;
    for (int64_t r = begin; r < end; r += rows)
        lstm_range(vctx, r, r + rows < end ? r + rows : end);
}

void cr_nn_cpu_lstm_gates_forward(const nn_lstm_gates_args *a) {
    lstm_pass L = {a, cr_nn_cpu_simd()};
    cr_parallel_for(a->B, nn_cpu_row_grain(8 * a->H), lstm_blocks, &L);
}
