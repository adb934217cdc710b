/* crease/drape_sampling.h: the spatially adaptive sampler of the drape method
 * (Shu et al., "Spatially Adaptive Cloth Regression with Implicit Neural
 * Representations", section 3.2 and Algorithm 1).
 *
 *   cr_drape_sampler_def def = cr_drape_sampler_default_def();
 *   cr_drape_sampler *s = NULL;
 *   CR_TRY(cr_drape_sampler_create(&def, &s, &err));
 *   for each epoch:
 *       cr_drape_sampler_draw(s, N, &rng, uv, &err);    points to train on
 *       ... losses at the points; weighted loss at cr_drape_sampler_cell_centres(s) ...
 *       cr_drape_sampler_update(s, cell_loss, &err);    Eq. 7
 *   cr_drape_sampler_destroy(s);
 *
 * The PDF lives on a G x G grid of cells over UV [0,1]^2, row-major with rows
 * along v: cell (i, j) is index i*G + j, spans u in [j/G, (j+1)/G) and v in
 * [i/G, (i+1)/G), and holds the point (u, v) when i = min(G-1, floor(v G))
 * and j = min(G-1, floor(u G)). It starts uniform over the cells inside the
 * mask and is zero outside it.
 *
 * A draw of n points: N_a = floor(mu n) adaptive points (Algorithm 1) by
 * inverse transform sampling of the PDF (Eq. 8-12: a row from the marginal
 * CDF, a column from that row's conditional CDF, then uniform within the
 * cell), N_u = n - N_a uniform over the mask, then Lloyd relaxation of the
 * union (Eq. 13). The centroids of the Voronoi regions are weighted means of
 * n * lloyd_density dense points drawn from the mixture the points came from,
 * rho = f pdf + (1 - f) uniform, f = N_a / n (about lloyd_density in every
 * region), each weighted by rho^(lloyd_exponent - 1): the centroids are those
 * of the density rho^lloyd_exponent. A centroidal Voronoi tessellation of a
 * density w has about w^(1/2) points per unit area in 2-D (Gersho), so the
 * default exponent 2 keeps the drawn density rho while the points spread
 * out; 1 relaxes towards rho^(1/2), 0 towards uniform. Every point stays in
 * a cell inside the mask: a centroid landing outside it (a non-convex mask)
 * leaves its point where it was. See docs/drape_sampling.md.
 *
 * Cost: a draw is O(G^2 + n lloyd_density lloyd_iterations) with a small
 * constant: nearest-sample queries go through bucket grids sized from the
 * PDF, so a PDF piled into a few cells costs a few times a flat one, not
 * n times; queries run on cr_parallel_for. Results do not depend on the
 * thread count.
 *
 * Thread safety: a sampler is used by one thread at a time; different
 * samplers share nothing.
 */
#ifndef CREASE_DRAPE_SAMPLING_H
#define CREASE_DRAPE_SAMPLING_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_DRAPE_SAMPLER_MAX_GRID = 1024 };

typedef struct cr_drape_sampler_def {
    int32_t grid; /* PDF cells per side over [0,1]^2, 2..1024 (default 64) */
    float gamma;  /* Eq. 7 weight of the old PDF, [0,1] (default 0.9; the paper gives none) */
    float mu;     /* share of adaptive samples, [0,1] (default 0.5, Algorithm 1) */
    /* Lloyd relaxation (Eq. 13): iterations, >= 0 (default 3; the paper gives
     * none); dense points per sample for the centroids, >= 1 (default 16);
     * centroids of rho^exponent, [0,4] (default 2: keeps the density rho). */
    int32_t lloyd_iterations;
    int32_t lloyd_density;
    float lloyd_exponent;
    /* Optional (G*G) 1 where the cell is inside the UV chart, 0 outside,
     * same layout as the PDF; NULL = the whole square. Copied by create; at
     * least one cell must be inside. */
    const uint8_t *mask;
    uint32_t cookie; /* set by cr_drape_sampler_default_def; a hand-zeroed def is a bug */
} cr_drape_sampler_def;

cr_drape_sampler_def cr_drape_sampler_default_def(void);

typedef struct cr_drape_sampler cr_drape_sampler;

/* CR_ERR_INVALID naming the field for a value outside the ranges above or a
 * mask with no cell inside; CR_ERR_NAN for a non-finite gamma, mu or exponent. */
cr_status cr_drape_sampler_create(const cr_drape_sampler_def *def, cr_drape_sampler **out,
                                  cr_error *err);
void cr_drape_sampler_destroy(cr_drape_sampler *s); /* NULL is fine */

int32_t cr_drape_sampler_grid(const cr_drape_sampler *s); /* G */

/* (G*G, 2) cell centres in UV, row-major: where the caller evaluates the
 * weighted loss for update. Owned by the sampler. */
const float *cr_drape_sampler_cell_centres(const cr_drape_sampler *s);

/* Eq. 7: p' = gamma p + (1 - gamma) p_hat, p_hat = cell_loss / sum(cell_loss)
 * over the cells inside the mask, then rescaled to sum to 1 (sums in double).
 * cell_loss (G*G): >= 0 and finite inside the mask; cells outside it are not
 * read for validity and keep p = 0. A field that is zero everywhere inside
 * the mask carries no information and leaves the PDF as it was. Errors
 * (CR_ERR_NAN for a non-finite value, CR_ERR_INVALID for a negative one,
 * naming the cell) leave the PDF unchanged. */
cr_status cr_drape_sampler_update(cr_drape_sampler *s, const float *cell_loss, cr_error *err);

/* (G*G) the current PDF, sums to 1, zero outside the mask. Owned by the sampler. */
const float *cr_drape_sampler_pdf(const cr_drape_sampler *s);

/* Replace the PDF by pdf (G*G), e.g. one saved with a checkpoint: >= 0 and
 * finite inside the mask with some mass there, rescaled to sum 1; cells
 * outside the mask are not read and stay 0. Errors as for update (and
 * CR_ERR_INVALID for no mass) leave the PDF unchanged. */
cr_status cr_drape_sampler_set_pdf(cr_drape_sampler *s, const float *pdf, cr_error *err);

/* n points uv_out (n,2) in UV, as described at the top: floor(mu n) adaptive
 * (first in the output before relaxation), the rest uniform, all relaxed,
 * all in cells inside the mask. Takes two 32-bit words from `rng` as the key
 * of its own counter-based streams, so the same rng state gives the same
 * points on any thread count. CR_ERR_INVALID for n < 1 or n * lloyd_density
 * past 2^31 - 1. */
cr_status cr_drape_sampler_draw(cr_drape_sampler *s, int32_t n, cr_rng *rng, float *uv_out,
                                cr_error *err);

/* A size_px x size_px PNG (16..8192) of the PDF as a viridis heat map (0 to
 * the largest cell value; cells outside the mask grey) with the n points
 * uv (n,2) over it as white dots (uv may be NULL when n is 0). v points up
 * (v = 0 is the bottom row of the image). Written atomically. */
cr_status cr_drape_sampler_write_png(const cr_drape_sampler *s, const float *uv, int32_t n,
                                     const char *path, int size_px, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
