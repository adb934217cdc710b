/* cpu_gemm_impl.h (private, no include guard): the register-tile
 * micro-kernel of cpu_gemm.c, written once over GCC/clang vector types and
 * instantiated per SIMD width. The includer defines
 *   VW         lanes (8: AVX2, 16: AVX-512)
 *   VT         the function attribute, e.g. __attribute__((target("avx2,fma")))
 *   V(name)    the instance's name for `name`, e.g. name##_avx2
 *   VFMA(a, b, c)  a * b + c rounded once (the target's FMA intrinsic)
 *   VBCAST(p)  *p in every lane (a broadcast load: `{0} + x` costs an add)
 *   VMR        rows of the tile, 6 or 12
 *   VHSUM(v)   the sum of v's lanes (a shuffle tree)
 *
 * The tile is VMR rows by 2 VW columns: 2 VMR accumulator registers, two
 * loads of packed B and VMR broadcasts of packed A per k. AVX2: 6 x 16, 12
 * accumulators of the 16 ymm registers; AVX-512: 12 x 32, 24 of the 32 zmm
 * (twice the multiply-adds per load of B). A is read through strides: row r,
 * step k at Ap[r rsa + k csa], so the tile runs on packed A (rsa 1, csa VMR)
 * or straight on the caller's matrix (row-major: rsa lda, csa 1; transposed:
 * rsa 1, csa lda); B likewise at Bp[k ldbp + c], packed (ldbp 2 VW) or the
 * caller's rows. The caller pads or packs the edges, so the k loop has no
 * tails.
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

/* acc[i][h] = sum_k Ap[k][i] Bp[k][h VW ..]: the k loop alone, so that
 * alpha and beta do not hold two of the registers the accumulators need
 * (AVX2 has 16: 12 accumulators, two B vectors, one broadcast). */
static VT __attribute__((noinline)) void V(gemm_acc)(int64_t kc, const float *Ap, int64_t rsa,
                                                     int64_t csa, const float *Bp, int64_t ldbp,
                                                     V(gf) acc[VMR][2]) {
#define GEMM_ACC(i) V(gf) c##i##_0 = {0}, c##i##_1 = {0}
#define GEMM_ROW(i)                                                                                \
    a = VBCAST(Ap + i * rsa);                                                                      \
    c##i##_0 = VFMA(a, b0, c##i##_0);                                                              \
    c##i##_1 = VFMA(a, b1, c##i##_1)
#define GEMM_SAVE(i) acc[i][0] = c##i##_0, acc[i][1] = c##i##_1
#define GEMM_ROWS(X)                                                                               \
    X(0);                                                                                          \
    X(1);                                                                                          \
    X(2);                                                                                          \
    X(3);                                                                                          \
    X(4);                                                                                          \
    X(5)
#define GEMM_ROWS12(X)                                                                             \
    X(6);                                                                                          \
    X(7);                                                                                          \
    X(8);                                                                                          \
    X(9);                                                                                          \
    X(10);                                                                                         \
    X(11)
    GEMM_ROWS(GEMM_ACC);
#if VMR > 6
    GEMM_ROWS12(GEMM_ACC);
#endif
    for (int64_t k = 0; k < kc; k++) {
        V(gf) b0 = V(gload)(Bp), b1 = V(gload)(Bp + VW), a;
        GEMM_ROWS(GEMM_ROW);
#if VMR > 6
        GEMM_ROWS12(GEMM_ROW);
#endif
        Ap += csa;
        Bp += ldbp;
    }
    GEMM_ROWS(GEMM_SAVE);
#if VMR > 6
    GEMM_ROWS12(GEMM_SAVE);
#endif
#undef GEMM_ACC
#undef GEMM_ROW
#undef GEMM_SAVE
#undef GEMM_ROWS
#undef GEMM_ROWS12
}

/* C[i rs + j cs] = alpha sum_k Ap[k][i] Bp[k][j] + beta C[..] for i < mr,
 * j < nr (C not read when beta is 0); mr <= VMR, nr <= 2 VW. */
static VT void V(gemm_tile)(int64_t kc, const float *Ap, int64_t rsa, int64_t csa,
                            const float *Bp, int64_t ldbp, float alpha, float beta, float *C,
                            int64_t rs, int64_t cs, int mr, int nr) {
    V(gf) acc[VMR][2];
    V(gemm_acc)(kc, Ap, rsa, csa, Bp, ldbp, acc);
    if (nr == 2 * VW && cs == 1) {
        for (int i = 0; i < mr; i++) {
            float *c = C + i * rs;
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
        float *c = C + i * rs;
        for (int j = 0; j < nr; j++)
            c[j * cs] = beta == 0.0f ? alpha * t[j] : alpha * t[j] + beta * c[j * cs];
    }
}

/* The narrow forward y = x W^T with few outputs (N <= 2 VW / 4, a 3-wide
 * output layer): C(i, j) = alpha <A row i, B row j> + beta C(i, j) for rows
 * [i0, i1), A (M x K, lda) and B (N x K, ldb) both read along their rows.
 * A dot product per element, VW lanes of k at a time, the lanes summed by a
 * shuffle tree, then the k tail in order: the tiled path padded N to a tile
 * 8-10x wider, or transposed the product and packed all of x, serially (a
 * 4,096 x 64 x 3 product: 288 us at one thread that way, 88 us this way on
 * AVX-512). */
static VT void V(gemm_dot_rows)(int64_t i0, int64_t i1, int64_t N, int64_t K, float alpha,
                                const float *A, int64_t lda, const float *B, int64_t ldb,
                                float beta, float *C, int64_t ldc) {
    enum { DOT_MAX_N = 8 };
    for (int64_t i = i0; i < i1; i++) {
        const float *a = A + i * lda;
        V(gf) acc[DOT_MAX_N];
        for (int64_t j = 0; j < N; j++)
            acc[j] = (V(gf)){0};
        int64_t k = 0;
        for (; k + VW <= K; k += VW) {
            V(gf) av = V(gload)(a + k);
            for (int64_t j = 0; j < N; j++)
                acc[j] = VFMA(av, V(gload)(B + j * ldb + k), acc[j]);
        }
        for (int64_t j = 0; j < N; j++) {
            float s = VHSUM(acc[j]);
            for (int64_t kk = k; kk < K; kk++)
                s += a[kk] * B[j * ldb + kk];
            float *c = C + i * ldc + j;
            *c = beta == 0.0f ? alpha * s : alpha * s + beta * *c;
        }
    }
}
