/* cpu_vmath.c: vectorised exp, log, tanh, sigmoid and softplus (values and
 * the derivatives the backward passes need) over spans of floats, for the
 * fused linear + activation kernels (cpu_fused.c) and the elementwise ops
 * (cpu_elementwise.c). One source (cpu_vmath_impl.h) instantiated for AVX2 +
 * FMA (8 lanes) and AVX-512F (16 lanes), each compiled with a target
 * attribute so the build needs no -march; the caller picks the level from
 * cr_nn_cpu_simd() and finishes the span's tail with the scalar code.
 * Accuracy against libm (tests/test_nn_vmath.c): a few ulp, NaN, infinities
 * and subnormals as on the scalar path.
 */
#include "nn/cpu/cpu.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "nn/cpu/cpu_vmath_levels.h"

int64_t cr_nn_cpu_vec_span(int level, nn_vec_fn fn, float p, const float *x, const float *b,
                           const float *mul, float *out, int acc, int64_t n) {
#if defined(__x86_64__) || defined(__i386__)
    if (level >= NN_SIMD_AVX512) return span_avx512(fn, p, x, b, mul, out, acc, n);
    if (level >= NN_SIMD_AVX2) return span_avx2(fn, p, x, b, mul, out, acc, n);
#else
    (void)level, (void)fn, (void)p, (void)x, (void)b, (void)mul, (void)out, (void)acc, (void)n;
#endif
    return 0;
}

void cr_nn_cpu_act_span(int level, cr_op act, float p, const float *x, float *out, int64_t n) {
    int vfn = act == CR_OP_TANH       ? NN_VEC_TANH
              : act == CR_OP_SIGMOID  ? NN_VEC_SIGMOID
              : act == CR_OP_SOFTPLUS ? NN_VEC_SOFTPLUS
              : act == CR_OP_EXP      ? NN_VEC_EXP
                                      : -1;
    int64_t k = 0;
    if (act == CR_OP_NONE) {
        if (out != x) memmove(out, x, sizeof(float) * (size_t)n);
        return;
    }
    if (vfn >= 0 && level >= NN_SIMD_AVX2)
        k = cr_nn_cpu_vec_span(level, (nn_vec_fn)vfn, p, x, NULL, NULL, out, 0, n);
    if (act == CR_OP_EXP)
        for (; k < n; k++)
            out[k] = expf(x[k]);
    else
        for (; k < n; k++)
            out[k] = nn_cpu_act(act, p, x[k]);
}
