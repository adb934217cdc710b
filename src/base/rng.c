/* rng.c: Philox4x32-10 counter-based generator.
 * Reference: Salmon, Moraes, Dror, Shaw, "Parallel random numbers: as easy as
 * 1, 2, 3", SC 2011 (the multipliers and Weyl constants below are theirs). */
#include "crease/base.h"

#include <math.h>

#define PHILOX_M0 0xD2511F53u
#define PHILOX_M1 0xCD9E8D57u
#define PHILOX_W0 0x9E3779B9u
#define PHILOX_W1 0xBB67AE85u

static inline void mulhilo(uint32_t a, uint32_t b, uint32_t *hi, uint32_t *lo) {
    uint64_t p = (uint64_t)a * b;
    *hi = (uint32_t)(p >> 32);
    *lo = (uint32_t)p;
}

void cr_philox4x32(uint64_t seed, uint64_t stream, uint64_t counter, uint32_t out[4]) {
    /* 128-bit counter = (counter, stream); 64-bit key = seed */
    uint32_t c0 = (uint32_t)counter, c1 = (uint32_t)(counter >> 32);
    uint32_t c2 = (uint32_t)stream, c3 = (uint32_t)(stream >> 32);
    uint32_t k0 = (uint32_t)seed, k1 = (uint32_t)(seed >> 32);
    for (int round = 0; round < 10; round++) {
        uint32_t hi0, lo0, hi1, lo1;
        mulhilo(PHILOX_M0, c0, &hi0, &lo0);
        mulhilo(PHILOX_M1, c2, &hi1, &lo1);
        uint32_t n0 = hi1 ^ c1 ^ k0, n1 = lo1, n2 = hi0 ^ c3 ^ k1, n3 = lo0;
        c0 = n0, c1 = n1, c2 = n2, c3 = n3;
        k0 += PHILOX_W0;
        k1 += PHILOX_W1;
    }
    out[0] = c0, out[1] = c1, out[2] = c2, out[3] = c3;
}

cr_rng cr_rng_make(uint64_t seed, uint64_t stream) {
    cr_rng r = {.seed = seed, .stream = stream, .counter = 0, .used = 4};
    return r;
}

uint32_t cr_rng_u32(cr_rng *r) {
    if (r->used >= 4) {
        cr_philox4x32(r->seed, r->stream, r->counter++, r->block);
        r->used = 0;
    }
    return r->block[r->used++];
}

double cr_rng_uniform(cr_rng *r) {
    uint64_t hi = cr_rng_u32(r) >> 5, lo = cr_rng_u32(r) >> 6; /* 27 + 26 bits */
    return (double)(hi * 67108864.0 + lo) * (1.0 / 9007199254740992.0);
}

float cr_rng_uniformf(cr_rng *r) {
    return (float)(cr_rng_u32(r) >> 8) * (1.0f / 16777216.0f);
}

double cr_rng_normal(cr_rng *r) {
    double u1 = 1.0 - cr_rng_uniform(r); /* (0, 1]: log is finite */
    double u2 = cr_rng_uniform(r);
    return sqrt(-2.0 * log(u1)) * cos(2.0 * M_PI * u2);
}

uint32_t cr_rng_below(cr_rng *r, uint32_t n) {
    CR_ASSERT(n > 0);
    /* Lemire's multiply-shift with rejection: unbiased */
    uint64_t m = (uint64_t)cr_rng_u32(r) * n;
    uint32_t low = (uint32_t)m;
    if (low < n) {
        uint32_t threshold = (uint32_t)(-n) % n;
        while (low < threshold) {
            m = (uint64_t)cr_rng_u32(r) * n;
            low = (uint32_t)m;
        }
    }
    return (uint32_t)(m >> 32);
}

void cr_rng_shuffle_i32(cr_rng *r, int32_t *a, int64_t n) {
    for (int64_t i = n - 1; i > 0; i--) {
        int64_t j = cr_rng_below(r, (uint32_t)(i + 1));
        int32_t t = a[i];
        a[i] = a[j];
        a[j] = t;
    }
}
