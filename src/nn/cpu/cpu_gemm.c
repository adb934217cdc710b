/* cpu_gemm.c: the engine's own single-precision GEMM, so that the linear
 * layers do not depend on which kernel OpenBLAS picks at load time (its
 * Prescott fallback runs the MLP step 2-4x slower; docs/nn.md).
 *
 * Goto/BLIS blocking, with the packing cut to what pays at these shapes: a
 * transposed B is packed once per (KC x NC) block into panels of NR columns,
 * a row-major B and A are read in place through their strides, and only
 * the partial tiles at the edges are packed, zero-padded; a register-tile
 * micro-kernel runs over the tiles. The micro-kernels
 * (cpu_gemm_impl.h) are one source instantiated for AVX2 + FMA (6 x 16) and
 * AVX-512F (12 x 32) with target attributes; the portable level has a plain C
 * 4 x 8 tile. Work splits over the MC blocks of C with cr_parallel_for; every
 * element of C sums its k in the same order whatever the thread count.
 * Sized for the layers' shapes: M a batch of hundreds to thousands of rows,
 * N and K layer widths 3..512, any of the transposition cases.
 */
#include "nn/cpu/cpu.h"

#include <stdlib.h>
#include <string.h>
#include <threads.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define NN_GEMM_X86 1
#else
#define NN_GEMM_X86 0
#endif

enum {
    GEMM_KC = 256,                 /* k per packed block: an A panel and a B panel stay in L1 */
    GEMM_MC = 240,                 /* rows per thread block at most: packed A in L2 */
    GEMM_NC = 2048,                /* columns per packed B block */
    GEMM_PACK_BUDGET = 1 << 22,    /* floats of packed B per parallel region, at most (16 MB) */
    GEMM_GRAIN = 1 << 18,          /* multiply-adds a chunk is worth a thread from, about */
    GEMM_SPLIT_K_MIN = 2048,       /* k from which a product with a small C splits k */
    GEMM_SPLIT_K_ROWS = 512,       /* k per chunk, about */
    GEMM_SPLIT_K_CHUNKS = 16,      /* chunks at most */
    GEMM_SPLIT_K_FLOATS = 1 << 22, /* the partial products together at most (16 MB) */
    SCALAR_MR = 4,
    SCALAR_NR = 8,
};

typedef void (*gemm_tile_fn)(int64_t kc, const float *Ap, int64_t rsa, int64_t csa, const float *Bp,
                             int64_t ldbp, float alpha, float beta, float *C, int64_t rs,
                             int64_t cs, int mr, int nr);

#if NN_GEMM_X86
#define VW 8
#define VT __attribute__((target("avx2,fma")))
#define V(name) name##_avx2
#define VFMA(a, b, c) _mm256_fmadd_ps(a, b, c)
#define VBCAST(p) _mm256_broadcast_ss(p)
#define VMR 6
static inline __attribute__((target("avx2,fma"))) float hsum_avx2(__m256 v) {
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehdup_ps(s)));
}
#define VHSUM(v) hsum_avx2((__m256)(v))
#include "nn/cpu/cpu_gemm_impl.h"
#undef VW
#undef VT
#undef V
#undef VFMA
#undef VBCAST
#undef VMR
#undef VHSUM

#define VW 16
#define VT __attribute__((target("avx512f")))
#define V(name) name##_avx512
#define VFMA(a, b, c) _mm512_fmadd_ps(a, b, c)
#define VBCAST(p) _mm512_set1_ps(*(p))
#define VMR 12
#define VHSUM(v) _mm512_reduce_add_ps((__m512)(v))
#include "nn/cpu/cpu_gemm_impl.h"
#undef VW
#undef VT
#undef V
#undef VFMA
#undef VBCAST
#undef VMR
#undef VHSUM
#endif

static void gemm_tile_scalar(int64_t kc, const float *Ap, int64_t rsa, int64_t csa, const float *Bp,
                             int64_t ldbp, float alpha, float beta, float *C, int64_t rs,
                             int64_t cs, int mr, int nr) {
    float acc[SCALAR_MR][SCALAR_NR] = {{0}};
    for (int64_t k = 0; k < kc; k++, Ap += csa, Bp += ldbp)
        for (int i = 0; i < SCALAR_MR; i++)
            for (int j = 0; j < SCALAR_NR; j++)
                acc[i][j] += Ap[i * rsa] * Bp[j];
    for (int i = 0; i < mr; i++)
        for (int j = 0; j < nr; j++) {
            float *c = C + i * rs + j * cs;
            *c = beta == 0.0f ? alpha * acc[i][j] : alpha * acc[i][j] + beta * *c;
        }
}

static void gemm_dot_rows_scalar(int64_t i0, int64_t i1, int64_t N, int64_t K, float alpha,
                                 const float *A, int64_t lda, const float *B, int64_t ldb,
                                 float beta, float *C, int64_t ldc) {
    for (int64_t i = i0; i < i1; i++)
        for (int64_t j = 0; j < N; j++) {
            float s = 0.0f;
            for (int64_t k = 0; k < K; k++)
                s += A[i * lda + k] * B[j * ldb + k];
            float *c = C + i * ldc + j;
            *c = beta == 0.0f ? alpha * s : alpha * s + beta * *c;
        }
}

typedef void (*gemm_dot_fn)(int64_t i0, int64_t i1, int64_t N, int64_t K, float alpha,
                            const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                            float *C, int64_t ldc);

typedef struct gemm_kernel {
    int mr, nr;
    gemm_tile_fn tile;
    gemm_dot_fn dot;
} gemm_kernel;

static gemm_kernel kernel_for(int level) {
#if NN_GEMM_X86
    if (level >= NN_SIMD_AVX512)
        return (gemm_kernel){12, 32, gemm_tile_avx512, gemm_dot_rows_avx512};
    if (level >= NN_SIMD_AVX2) return (gemm_kernel){6, 16, gemm_tile_avx2, gemm_dot_rows_avx2};
#else
    (void)level;
#endif
    return (gemm_kernel){SCALAR_MR, SCALAR_NR, gemm_tile_scalar, gemm_dot_rows_scalar};
}

/* op(A) rows [i0, i0 + mc), k [p0, p0 + kc) into panels of mr rows:
 * panel p, step k at Ap[p kc mr + k mr + r]; rows past mc are zero. The
 * loops read A along its memory (a row of A, or a row of A^T, at a time). */
static void pack_a(int ta, const float *A, int64_t lda, int64_t i0, int64_t mc, int64_t p0,
                   int64_t kc, int mr, float *Ap) {
    for (int64_t ip = 0; ip < mc; ip += mr, Ap += kc * mr) {
        int64_t rows = mc - ip < mr ? mc - ip : mr;
        if (rows < mr)
            for (int64_t k = 0; k < kc; k++)
                for (int64_t r = rows; r < mr; r++)
                    Ap[k * mr + r] = 0.0f;
        if (ta)
            for (int64_t k = 0; k < kc; k++)
                memcpy(Ap + k * mr, A + (p0 + k) * lda + i0 + ip, (size_t)rows * sizeof(float));
        else
            for (int64_t r = 0; r < rows; r++) {
                const float *src = A + (i0 + ip + r) * lda + p0;
                for (int64_t k = 0; k < kc; k++)
                    Ap[k * mr + r] = src[k];
            }
    }
}

/* op(B) k [p0, p0 + kc), columns [j0, j0 + nc) into panels of nr columns:
 * panel q, step k at Bp[q kc nr + k nr + c]; columns past nc are zero. */
static void pack_b(int tb, const float *B, int64_t ldb, int64_t p0, int64_t kc, int64_t j0,
                   int64_t nc, int nr, float *Bp) {
    for (int64_t jp = 0; jp < nc; jp += nr, Bp += kc * nr) {
        int64_t cols = nc - jp < nr ? nc - jp : nr, j = j0 + jp;
        if (cols < nr)
            for (int64_t k = 0; k < kc; k++)
                for (int64_t c = cols; c < nr; c++)
                    Bp[k * nr + c] = 0.0f;
        if (tb)
            for (int64_t c = 0; c < cols; c++) {
                const float *src = B + (j + c) * ldb + p0;
                for (int64_t k = 0; k < kc; k++)
                    Bp[k * nr + c] = src[k];
            }
        else
            for (int64_t k = 0; k < kc; k++)
                memcpy(Bp + k * nr, B + (p0 + k) * ldb + j, (size_t)cols * sizeof(float));
    }
}

/* One (KC x NC) block of op(B): k [p0, p0 + kc), columns [j0, j0 + nc). */
typedef struct b_block {
    int64_t p0, kc, j0, nc;
    const float *Bp; /* packed panels; with b_direct only the last, partial one */
    float beta;      /* the caller's beta for the first k block, 1 after */
} b_block;

typedef struct gemm_block {
    gemm_kernel kern;
    int ta, tb;
    const float *A, *B;      /* unpacked: read in place, or rows_unpacked */
    int64_t lda, ldb, M, mc; /* mc: rows per block */
    const b_block *blocks;   /* the B blocks this parallel region runs, in k order per column */
    int64_t nblocks;
    int b_direct; /* full panels of B read in place (B row-major, tb 0) */
    float alpha;
    float *C;
    int64_t rs, cs; /* C's element (i, j) at C[i rs + j cs] */
} gemm_block;

static void rows_unpacked(const gemm_block *g, const b_block *bb, int64_t i_begin, int64_t i_end) {
    for (int64_t i = i_begin; i < i_end; i++)
        for (int64_t j = bb->j0; j < bb->j0 + bb->nc; j++) {
            float s = 0.0f;
            for (int64_t k = bb->p0; k < bb->p0 + bb->kc; k++)
                s += (g->ta ? g->A[k * g->lda + i] : g->A[i * g->lda + k]) *
                     (g->tb ? g->B[j * g->ldb + k] : g->B[k * g->ldb + j]);
            float *c = g->C + i * g->rs + j * g->cs;
            *c = bb->beta == 0.0f ? g->alpha * s : g->alpha * s + bb->beta * *c;
        }
}

/* The packing and partial buffers, one set per thread (C11 thread-specific
 * storage, freed when the thread ends), one per purpose, grown when a
 * product needs more and kept: once a runtime's first frames have sized
 * them, its steps call the heap no more (issue 51; they malloc'd and freed
 * about 3,000 times a gdsr frame). A purpose is never used twice at once on
 * one thread: a split-k chunk's blocked product, run inside the split's
 * region, takes the other purposes. */
enum { BUF_A, BUF_B, BUF_BLOCKS, BUF_BT, BUF_CT, BUF_PARTIAL, NBUF };
typedef struct thread_buffers {
    void *p[NBUF];
    size_t cap[NBUF];
} thread_buffers;

static tss_t buffers_key;
static once_flag buffers_once = ONCE_FLAG_INIT;
static int buffers_ok;

static void buffers_free(void *v) {
    thread_buffers *b = v;
    for (int i = 0; i < NBUF; i++)
        free(b->p[i]);
    free(b);
}

static void buffers_key_make(void) {
    buffers_ok = tss_create(&buffers_key, buffers_free) == thrd_success;
}

static void *thread_buffer(int which, size_t bytes) {
    call_once(&buffers_once, buffers_key_make);
    if (!buffers_ok) return NULL; /* the caller falls back (OpenBLAS, unpacked rows) */
    thread_buffers *b = tss_get(buffers_key);
    if (!b) {
        if (!(b = calloc(1, sizeof *b))) return NULL;
        if (tss_set(buffers_key, b) != thrd_success) {
            free(b);
            return NULL;
        }
    }
    bytes = (bytes + 63) & ~(size_t)63;
    if (bytes > b->cap[which]) {
        free(b->p[which]);
        b->p[which] = aligned_alloc(64, bytes);
        b->cap[which] = b->p[which] ? bytes : 0;
    }
    return b->p[which];
}

static float *thread_floats(int which, int64_t n) {
    return thread_buffer(which, (size_t)n * sizeof(float));
}

/* MC blocks [begin, end) of C's rows against every B block of the region,
 * the B blocks outer so that a block stays in cache over the chunk's rows.
 * Full tiles read A in place through its strides: at the layers' widths (K
 * up to a few hundred) packing A cost more than the multiply-adds it fed (a
 * drape epoch spent 12 % packing A, 11 % in the tile). Only a block's last,
 * partial tile is packed, into zero-padded rows. Each element of C sums its
 * k blocks in increasing order in one thread, so the bits do not depend on
 * the thread count or on how the blocks are grouped into regions. */
static void gemm_rows(void *vctx, int64_t begin, int64_t end) {
    gemm_block *g = vctx;
    int mr = g->kern.mr, nr = g->kern.nr;
    float *Ap = thread_floats(BUF_A, (int64_t)mr * GEMM_KC);
    const int64_t rsa = g->ta ? 1 : g->lda, csa = g->ta ? g->lda : 1;
    for (int64_t b = 0; b < g->nblocks; b++) {
        const b_block *bb = &g->blocks[b];
        if (!Ap) { /* out of memory: these rows unpacked, slowly */
            rows_unpacked(g, bb, begin * g->mc, end * g->mc < g->M ? end * g->mc : g->M);
            continue;
        }
        for (int64_t blk = begin; blk < end; blk++) {
            int64_t i0 = blk * g->mc, mc = g->M - i0 < g->mc ? g->M - i0 : g->mc;
            int64_t full = mc / mr * mr;
            if (full < mc)
                pack_a(g->ta, g->A, g->lda, i0 + full, mc - full, bb->p0, bb->kc, mr, Ap);
            for (int64_t jp = 0; jp < bb->nc; jp += nr) {
                int nrr = bb->nc - jp < nr ? (int)(bb->nc - jp) : nr;
                const float *bp = bb->Bp + (jp / nr) * bb->kc * nr;
                int64_t ldbp = nr;
                if (g->b_direct && nrr == nr) {
                    bp = g->B + bb->p0 * g->ldb + bb->j0 + jp;
                    ldbp = g->ldb;
                } else if (g->b_direct) {
                    bp = bb->Bp;
                }
                for (int64_t ip = 0; ip < mc; ip += mr) {
                    int mrr = mc - ip < mr ? (int)(mc - ip) : mr;
                    const float *a = ip < full ? g->A + (i0 + ip) * rsa + bb->p0 * csa : Ap;
                    g->kern.tile(bb->kc, a, ip < full ? rsa : 1, ip < full ? csa : mr, bp, ldbp,
                                 g->alpha, bb->beta,
                                 g->C + (i0 + ip) * g->rs + (bb->j0 + jp) * g->cs, g->rs, g->cs,
                                 mrr, nrr);
                }
            }
        }
    }
}

/* Items per parallel chunk when each costs `per` multiply-adds. */
static int64_t chunk_grain(int64_t per) {
    return per >= GEMM_GRAIN ? 1 : GEMM_GRAIN / per;
}

typedef struct gemm_dot {
    gemm_dot_fn fn;
    int64_t N, K;
    float alpha;
    const float *A;
    int64_t lda;
    const float *B;
    int64_t ldb;
    float beta;
    float *C;
    int64_t ldc;
} gemm_dot;

static void dot_rows(void *vctx, int64_t begin, int64_t end) {
    const gemm_dot *g = vctx;
    g->fn(begin, end, g->N, g->K, g->alpha, g->A, g->lda, g->B, g->ldb, g->beta, g->C, g->ldc);
}

static int gemm_blocked(int level, int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                        const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                        float *C, int64_t ldc);

/* Chunks of k for a product whose k (a batch's rows) dwarfs its output, 0 for
 * none: a fixed function of the shape, so the bits do not depend on the
 * thread count. */
static int64_t split_k_chunks(int64_t M, int64_t N, int64_t K) {
    if (K < GEMM_SPLIT_K_MIN || K < 8 * (M > N ? M : N)) return 0;
    int64_t chunks = K / GEMM_SPLIT_K_ROWS;
    if (chunks > GEMM_SPLIT_K_CHUNKS) chunks = GEMM_SPLIT_K_CHUNKS;
    while (chunks > 1 && chunks * M * N > GEMM_SPLIT_K_FLOATS)
        chunks--;
    return chunks >= 2 ? chunks : 0;
}

typedef struct gemm_split {
    int level, ta, tb;
    int64_t M, N, K, chunks;
    const float *A, *B;
    int64_t lda, ldb;
    float *partial; /* (chunks, M, N) */
    int failed;
    float alpha, beta;
    float *C;
    int64_t ldc;
} gemm_split;

static void split_k_range(void *vctx, int64_t begin, int64_t end) {
    gemm_split *g = vctx;
    for (int64_t c = begin; c < end; c++) {
        int64_t k0 = c * g->K / g->chunks, k1 = (c + 1) * g->K / g->chunks;
        const float *a = g->A + (g->ta ? k0 * g->lda : k0);
        const float *b = g->B + (g->tb ? k0 : k0 * g->ldb);
        if (gemm_blocked(g->level, g->ta, g->tb, g->M, g->N, k1 - k0, 1.0f, a, g->lda, b, g->ldb,
                         0.0f, g->partial + c * g->M * g->N, g->N) != 0)
            g->failed = 1;
    }
}

/* C's rows [begin, end) = alpha * the chunks' sum, in chunk order, in double. */
static void split_k_sum(void *vctx, int64_t begin, int64_t end) {
    const gemm_split *g = vctx;
    for (int64_t i = begin; i < end; i++)
        for (int64_t j = 0; j < g->N; j++) {
            double s = 0.0;
            for (int64_t c = 0; c < g->chunks; c++)
                s += g->partial[(c * g->M + i) * g->N + j];
            float *out = &g->C[i * g->ldc + j];
            *out = g->beta == 0.0f ? (float)(g->alpha * s) : (float)(g->alpha * s) + g->beta * *out;
        }
}

int cr_nn_cpu_gemm_own(int level, int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                       const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                       float *C, int64_t ldc) {
    if (M <= 0 || N <= 0 || K <= 0 || alpha == 0.0f) return -1; /* the caller's cases */
    /* A weights gradient, dW = dz^T x over a batch of thousands of rows: by
     * chunks of rows, each on one thread into its own partial product, then
     * summed. Split over C's rows instead (below), both threads read every
     * row of dz and x, which the forward had left in the other core's cache:
     * the layer path's step at width 64 was no faster on two threads than
     * on one. */
    const int64_t chunks = split_k_chunks(M, N, K);
    if (chunks > 0) {
        gemm_split g = {.level = level,
                        .ta = ta,
                        .tb = tb,
                        .M = M,
                        .N = N,
                        .K = K,
                        .chunks = chunks,
                        .A = A,
                        .B = B,
                        .lda = lda,
                        .ldb = ldb,
                        .alpha = alpha,
                        .beta = beta,
                        .C = C,
                        .ldc = ldc};
        g.partial = thread_floats(BUF_PARTIAL, chunks * M * N);
        if (g.partial) {
            cr_parallel_for(chunks, 1, split_k_range, &g);
            if (!g.failed) cr_parallel_for(M, chunk_grain(N * chunks), split_k_sum, &g);
            return g.failed ? -1 : 0;
        }
    }
    return gemm_blocked(level, ta, tb, M, N, K, alpha, A, lda, B, ldb, beta, C, ldc);
}

static int gemm_blocked(int level, int ta, int tb, int64_t M, int64_t N, int64_t K, float alpha,
                        const float *A, int64_t lda, const float *B, int64_t ldb, float beta,
                        float *C, int64_t ldc) {
    gemm_kernel kern = kernel_for(level);
    int64_t rs = ldc, cs = 1;
    if (!ta && N * 4 <= kern.nr && N <= 8 && M > N) {
        /* A narrow product (the 3-wide output layer's forward; dx of a
         * 6-wide input layer, B = W not transposed): a dot product per
         * element, parallel over the rows. An untransposed B (K x N) is
         * copied to N x K first; through the C^T path below its packing
         * ran serially and M = 6 left one thread for the whole product. */
        float *Bt = NULL;
        if (!tb) {
            Bt = thread_floats(BUF_BT, N * K);
            if (!Bt) return -1;
            for (int64_t k = 0; k < K; k++)
                for (int64_t j = 0; j < N; j++)
                    Bt[j * K + k] = B[k * ldb + j];
        }
        gemm_dot g = {kern.dot, N, K, alpha, A, lda, Bt ? Bt : B, Bt ? K : ldb, beta, C, ldc};
        cr_parallel_for(M, chunk_grain(N * K), dot_rows, &g);
        return 0;
    }
    if (!ta && tb && M * 4 <= kern.nr && M <= 8 && N > M) {
        /* A few rows against a weight read along its rows (y = x W^T for
         * one or two frames: epnet's decoder, 6,171 x 256 a pass): C^T =
         * W x^T by the dot products above, parallel over W's rows, into a
         * small buffer, then C. The tiled path packed all of W each call. */
        float *Ct = thread_floats(BUF_CT, N * M);
        if (!Ct) return -1;
        gemm_dot g = {kern.dot, M, K, 1.0f, B, ldb, A, lda, 0.0f, Ct, M};
        cr_parallel_for(N, chunk_grain(M * K), dot_rows, &g);
        for (int64_t i = 0; i < M; i++)
            for (int64_t j = 0; j < N; j++) {
                float *c = C + i * ldc + j;
                *c = beta == 0.0f ? alpha * Ct[j * M + i] : alpha * Ct[j * M + i] + beta * *c;
            }
        return 0;
    }
    if (N * 4 <= kern.nr && M > N) {
        /* N far below the tile's width (a 3-wide output layer, a 6-wide
         * input's dW): C^T = op(B)^T op(A)^T pads MR rows instead of NR
         * columns, C written through strides */
        const float *tA = A;
        int64_t tM = M, tlda = lda;
        int tta = ta;
        A = B, M = N, lda = ldb, ta = !tb;
        B = tA, N = tM, ldb = tlda, tb = !tta;
        rs = 1, cs = ldc;
    }
    /* blocks of equal height, at least one per thread (M = 256 in blocks of
     * 240 and 16 left the second of two threads idle) */
    int64_t blocks = (M + GEMM_MC - 1) / GEMM_MC, nt = cr_thread_count();
    if (blocks < nt) blocks = nt;
    int64_t mc = ((M + blocks - 1) / blocks + kern.mr - 1) / kern.mr * kern.mr;
    if (mc > GEMM_MC) mc = GEMM_MC;
    blocks = (M + mc - 1) / mc;
    int64_t nc_max = N < GEMM_NC ? N : GEMM_NC;
    int64_t grain = chunk_grain((M < mc ? M : mc) * nc_max * (K < GEMM_KC ? K : GEMM_KC));
    /* B's blocks, packed ahead as far as GEMM_PACK_BUDGET floats go, run in
     * one parallel region: a region per k block cost a thread wake-up every
     * 256 k, and a weights gradient (K = the batch) had 16 of them. */
    const int b_direct = !tb; /* a row-major B is read in place but for its last, partial panel */
    int64_t nj = (N + GEMM_NC - 1) / GEMM_NC, np = (K + GEMM_KC - 1) / GEMM_KC;
    int64_t per_b = b_direct ? (int64_t)GEMM_KC * kern.nr
                             : (int64_t)GEMM_KC * ((nc_max + kern.nr - 1) / kern.nr * kern.nr);
    int64_t group = GEMM_PACK_BUDGET / per_b;
    if (group < 1) group = 1;
    if (group > nj * np) group = nj * np;
    float *Bp = thread_floats(BUF_B, group * per_b);
    b_block *bbs = thread_buffer(BUF_BLOCKS, (size_t)group * sizeof *bbs);
    if (!Bp || !bbs) return -1;
    gemm_block g = {.kern = kern,
                    .ta = ta,
                    .tb = tb,
                    .A = A,
                    .B = B,
                    .lda = lda,
                    .ldb = ldb,
                    .M = M,
                    .mc = mc,
                    .blocks = bbs,
                    .b_direct = b_direct,
                    .alpha = alpha,
                    .C = C,
                    .rs = rs,
                    .cs = cs};
    for (int64_t first = 0; first < nj * np; first += group) {
        int64_t n = nj * np - first < group ? nj * np - first : group;
        for (int64_t q = 0; q < n; q++) {
            int64_t jb = (first + q) / np, pb = (first + q) % np;
            b_block *bb = &bbs[q];
            bb->j0 = jb * GEMM_NC, bb->nc = N - bb->j0 < GEMM_NC ? N - bb->j0 : GEMM_NC;
            bb->p0 = pb * GEMM_KC, bb->kc = K - bb->p0 < GEMM_KC ? K - bb->p0 : GEMM_KC;
            bb->beta = pb == 0 ? beta : 1.0f;
            float *dst = Bp + q * per_b;
            bb->Bp = dst;
            int64_t tail = b_direct ? bb->nc / kern.nr * kern.nr : 0;
            if (tail < bb->nc)
                pack_b(tb, B, ldb, bb->p0, bb->kc, bb->j0 + tail, bb->nc - tail, kern.nr, dst);
        }
        g.nblocks = n;
        cr_parallel_for(blocks, grain, gemm_rows, &g);
    }
    return 0;
}
