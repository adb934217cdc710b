/* sampling_lloyd.h: private to methods/drape: the cell conventions of the
 * adaptive sampler's PDF grid and the Lloyd relaxation (Eq. 13 of the drape
 * paper) that sampling.c runs after drawing. See sampling_lloyd.c. */
#ifndef CREASE_DRAPE_SAMPLING_LLOYD_H
#define CREASE_DRAPE_SAMPLING_LLOYD_H

#include "crease/base.h"

#include <math.h>

/* Cell of coordinate x in [0,1] on a G-cell axis: min(G-1, floor(x G)). */
static inline int32_t drape_cell_index(float x, int32_t G) {
    int32_t k = (int32_t)(x * (float)G);
    return k < 0 ? 0 : (k >= G ? G - 1 : k);
}

/* (k + t) / G for t in [0,1), as a float that drape_cell_index maps back to
 * k: rounding to float can land on the next cell's edge, so step back by
 * ulps when it does. */
static inline float drape_cell_coord(int32_t k, float t, int32_t G) {
    float x = (float)(((double)k + (double)t) / (double)G);
    while (drape_cell_index(x, G) > k)
        x = nextafterf(x, 0.0f);
    while (drape_cell_index(x, G) < k)
        x = nextafterf(x, 1.0f);
    return x;
}

/* Points sorted into an R x R grid of buckets over [0,1]^2, row-major along v. */
typedef struct drape_bucket_grid {
    int32_t R;      /* buckets per side */
    float h;        /* bucket side, 1 / R */
    int64_t cap_b;  /* capacity of start, entries */
    int32_t *start; /* (R*R+1) first slot of each bucket */
    float *x, *y;   /* (count) coordinates in bucket order */
    int32_t *id;    /* (count) original index at each slot, or NULL */
} drape_bucket_grid;

/* Scratch of the relaxation, grown to the largest draw seen; zero-initialise. */
typedef struct drape_lloyd {
    int64_t cap_n, cap_m, cap_cells;
    drape_bucket_grid fine, coarse, dense; /* samples twice, dense points once */
    int32_t ratio;                         /* fine buckets per coarse bucket side */
    float *drawn;                          /* (M,2) dense points as drawn, in cell order */
    int32_t *assign;  /* (M) nearest sample of each dense point (in dense-grid order) */
    int32_t *scratch; /* (max(n, M)) bucket of each point while sorting */
    double *acc;      /* (n,3) per-sample weighted sums of u, v and 1 */
    int64_t *first;   /* (G*G+1) first dense point of each cell, as drawn */
    double *cell_w;   /* (G*G) weight of a dense point in each cell */
} drape_lloyd;

void cr_drape_lloyd_free(drape_lloyd *L);

/* Relax the n points uv (n,2), all in cells inside mask (G*G), by `iters`
 * Lloyd iterations whose centroids come from n * density dense points drawn
 * (stratified) from the cell masses rho (G*G, sum 1, zero outside the mask)
 * and weighted by rho^(exponent - 1), using counters of `stream` under
 * `key`. Points stay in cells inside the mask. Deterministic for any thread
 * count. CR_ERR_MEMORY only. */
cr_status cr_drape_lloyd_relax(drape_lloyd *L, float *uv, int32_t n, int32_t density, int32_t iters,
                               const double *rho, double exponent, const uint8_t *mask, int32_t G,
                               uint64_t key, uint64_t stream, cr_error *err);

#endif
