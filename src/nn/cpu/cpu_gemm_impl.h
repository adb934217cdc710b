/* cpu_gemm_impl.h (private, no include guard): the register-tile
 * micro-kernel of cpu_gemm.c, written once over GCC/clang vector types and
 * instantiated per SIMD width. The includer defines
 *   VW         lanes (8: AVX2, 16: AVX-512)
 *   VT         the function attribute, e.g. __attribute__((target("avx2,fma")))
 *   V(name)    the instance's name for `name`, e.g. name##_avx2
 *   VFMA(a, b, c)  a * b + c rounded once (the target's FMA intrinsic)
 *
 * The tile is GEMM_MR rows by 2 VW columns: 12 accumulator registers, two
 * loads of packed B and six broadcasts of packed A per k (16 of the 16 ymm
 * registers on AVX2; AVX-512 has 32 and uses the same shape at twice the
 * width). Packed A holds GEMM_MR values per k, packed B 2 VW per k, both
 * zero-padded at the edges, so the k loop has no tails.
 */

typedef float V(gf) __attribute__((vector_size(VW * 4)));

static inline VT V(gf) V(gload)(const float *p) {
    V(gf) v;
    memcpy(&v, p, sizeof v);
    return v;
}

static inline VT void V(gstore)(float *p, V(gf) v) {
    memcpy(p, &v, sizeof v);
}

/* C[0..mr)[0..nr) = alpha sum_k Ap[k][i] Bp[k][j] + beta C (C not read when
 * beta is 0); mr <= GEMM_MR, nr <= 2 VW. */
static VT void V(gemm_tile)(int64_t kc, const float *Ap, const float *Bp, float alpha, float beta,
                            float *C, int64_t ldc, int mr, int nr) {
    V(gf) c00 = {0}, c01 = {0}, c10 = {0}, c11 = {0}, c20 = {0}, c21 = {0};
    V(gf) c30 = {0}, c31 = {0}, c40 = {0}, c41 = {0}, c50 = {0}, c51 = {0};
    for (int64_t k = 0; k < kc; k++) {
        V(gf) b0 = V(gload)(Bp), b1 = V(gload)(Bp + VW), a;
#define GEMM_ROW(i)                                                                                \
    a = (V(gf)){0} + Ap[i];                                                                        \
    c##i##0 = VFMA(a, b0, c##i##0);                                                                \
    c##i##1 = VFMA(a, b1, c##i##1)
        GEMM_ROW(0);
        GEMM_ROW(1);
        GEMM_ROW(2);
        GEMM_ROW(3);
        GEMM_ROW(4);
        GEMM_ROW(5);
#undef GEMM_ROW
        Ap += GEMM_MR;
        Bp += 2 * VW;
    }
    V(gf)
    acc[GEMM_MR][2] = {{c00, c01}, {c10, c11}, {c20, c21}, {c30, c31}, {c40, c41}, {c50, c51}};
    if (nr == 2 * VW) {
        for (int i = 0; i < mr; i++) {
            float *c = C + i * ldc;
            for (int h = 0; h < 2; h++) {
                V(gf) v = alpha * acc[i][h];
                if (beta != 0.0f) v += beta * V(gload)(c + h * VW);
                V(gstore)(c + h * VW, v);
            }
        }
        return;
    }
    float t[2 * VW];
    for (int i = 0; i < mr; i++) {
        V(gstore)(t, acc[i][0]);
        V(gstore)(t + VW, acc[i][1]);
        float *c = C + i * ldc;
        for (int j = 0; j < nr; j++)
            c[j] = beta == 0.0f ? alpha * t[j] : alpha * t[j] + beta * c[j];
    }
}
