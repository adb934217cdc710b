/* sampling.c: the drape method's spatially adaptive sampler (section 3.2 and
 * Algorithm 1 of Shu et al., "Spatially Adaptive Cloth Regression with
 * Implicit Neural Representations"): the discrete PDF over UV and its Eq. 7
 * update, inverse transform sampling (Eq. 8-12), the adaptive/uniform split
 * of Algorithm 1, and a heat-map picture. Lloyd relaxation (Eq. 13) is in
 * sampling_lloyd.c.
 *
 * Leaves out: computing the losses (the caller evaluates them at the cell
 * centres), any tempering of a peaked loss field (the paper has none; mu
 * keeps coverage), a mask finer than the PDF grid.
 * References: the paper above; Philox (Salmon et al., SC'11) through base.h.
 *
 * G: PDF cells per side; n: points drawn; M: dense points, n * lloyd_density.
 */
#include "crease/drape_sampling.h"

#include "sampling_lloyd.h"

#include "crease/render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t SAMPLER_COOKIE = 0x44525053u; /* "DRPS" */
/* Counter-based streams under the per-draw key, one per use, so that adding
 * points of one kind never shifts the random numbers of another. */
enum { STREAM_ADAPTIVE = 1, STREAM_UNIFORM = 2, STREAM_DENSE = 3 };
enum { DRAW_GRAIN = 4096, PNG_MIN_SIDE = 16, PNG_MAX_SIDE = 8192 };

/* Eq. 8-9 and 11 of one distribution over the cells. */
typedef struct cell_table {
    double *row_cdf; /* (G) marginal CDF over rows (v) */
    double *col_cdf; /* (G,G) each row's conditional CDF over columns (u) */
} cell_table;

struct cr_drape_sampler {
    int32_t G;
    float gamma, mu, lloyd_exponent;
    int32_t lloyd_iterations, lloyd_density;
    int64_t inside;  /* cells inside the mask */
    uint8_t *mask;   /* (G*G) 1 inside the chart */
    double *p;       /* (G*G) the PDF, kept in double across epochs */
    float *pdf_f;    /* (G*G) float copy handed out */
    float *centres;  /* (G*G,2) cell centres, UV */
    double *weights; /* (G*G) scratch: table weights, then the mixture's cell masses */
    cell_table uniform, adaptive;
    drape_lloyd lloyd;
};

cr_drape_sampler_def cr_drape_sampler_default_def(void) {
    cr_drape_sampler_def d;
    memset(&d, 0, sizeof d);
    d.grid = 64;
    d.gamma = 0.9f;
    d.mu = 0.5f;
    d.lloyd_iterations = 3;
    d.lloyd_density = 16;
    d.lloyd_exponent = 2.0f;
    d.mask = NULL;
    d.cookie = SAMPLER_COOKIE;
    return d;
}

/* -------------------------------------------------------------- cell tables -- */

/* Eq. 8-9 and 11 from cell weights w (G*G, >= 0, positive somewhere): the
 * marginal CDF over rows and each row's conditional CDF over columns. The last
 * row (column) with mass and all after it get exactly 1, so a uniform number
 * in [0,1) always finds an entry despite rounding. Sums in double. */
static void table_build(cell_table *t, int32_t G, const double *w) {
    double total = 0.0;
    int32_t last_row = -1;
    for (int32_t i = 0; i < G; i++) {
        const double *wr = w + (int64_t)i * G;
        double *cr = t->col_cdf + (int64_t)i * G;
        double rs = 0.0;
        int32_t last_col = -1;
        for (int32_t j = 0; j < G; j++) {
            rs += wr[j];
            cr[j] = rs;
            if (wr[j] > 0.0) last_col = j;
        }
        for (int32_t j = 0; j < G; j++)
            cr[j] = j >= last_col ? 1.0 : (rs > 0.0 ? cr[j] / rs : 1.0);
        total += rs;
        t->row_cdf[i] = total; /* Eq. 9 (unnormalised so far) */
        if (rs > 0.0) last_row = i;
    }
    CR_ASSERT(last_row >= 0 && total > 0.0);
    for (int32_t i = 0; i < G; i++)
        t->row_cdf[i] = i >= last_row ? 1.0 : t->row_cdf[i] / total;
}

/* First index k with cdf[k] > r. Eq. 10 and 12 ask for the first with
 * cdf >= r; the strict form only differs on ties of probability zero and
 * never picks an empty row or column (r = 0 would otherwise pick a leading
 * empty one). */
static int32_t cdf_find(const double *cdf, int32_t len, double r) {
    int32_t lo = 0, hi = len - 1;
    while (lo < hi) {
        int32_t mid = lo + (hi - lo) / 2;
        if (cdf[mid] > r)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* One point of the table's distribution from four random words: a row
 * (Eq. 10), a column in it (Eq. 12), then uniform within the cell. */
static void table_sample(const cell_table *t, int32_t G, const uint32_t w[4], float *uv) {
    const double inv32 = 1.0 / 4294967296.0;
    int32_t i = cdf_find(t->row_cdf, G, w[0] * inv32);
    int32_t j = cdf_find(t->col_cdf + (int64_t)i * G, G, w[1] * inv32);
    uv[0] = drape_cell_coord(j, (float)(w[2] >> 8) * 0x1p-24f, G);
    uv[1] = drape_cell_coord(i, (float)(w[3] >> 8) * 0x1p-24f, G);
}

/* ------------------------------------------------------------------ create -- */

static int in_range(float x, float lo, float hi) {
    return x >= lo && x <= hi; /* NaN fails */
}

static cr_status check_def(const cr_drape_sampler_def *d, cr_error *err) {
    CR_ASSERT(d && d->cookie == SAMPLER_COOKIE);
    if (d->grid < 2 || d->grid > CR_DRAPE_SAMPLER_MAX_GRID)
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: grid %d outside 2..%d", d->grid,
                       CR_DRAPE_SAMPLER_MAX_GRID);
    if (!isfinite(d->gamma))
        return CR_FAIL(err, CR_ERR_NAN, "drape sampler: gamma is %g", (double)d->gamma);
    if (!in_range(d->gamma, 0.0f, 1.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: gamma %g outside [0,1]",
                       (double)d->gamma);
    if (!isfinite(d->mu)) return CR_FAIL(err, CR_ERR_NAN, "drape sampler: mu is %g", (double)d->mu);
    if (!in_range(d->mu, 0.0f, 1.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: mu %g outside [0,1]", (double)d->mu);
    if (d->lloyd_iterations < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: lloyd_iterations %d < 0",
                       d->lloyd_iterations);
    if (d->lloyd_density < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: lloyd_density %d < 1",
                       d->lloyd_density);
    if (!isfinite(d->lloyd_exponent))
        return CR_FAIL(err, CR_ERR_NAN, "drape sampler: lloyd_exponent is %g",
                       (double)d->lloyd_exponent);
    if (!in_range(d->lloyd_exponent, 0.0f, 4.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler: lloyd_exponent %g outside [0,4]",
                       (double)d->lloyd_exponent);
    return CR_OK;
}

static cr_status table_alloc(cell_table *t, int32_t G, cr_error *err) {
    t->row_cdf = cr_malloc((size_t)G * sizeof(double), err);
    t->col_cdf = cr_malloc((size_t)G * (size_t)G * sizeof(double), err);
    return t->row_cdf && t->col_cdf ? CR_OK : CR_ERR_MEMORY;
}

static void table_free(cell_table *t) {
    free(t->row_cdf);
    free(t->col_cdf);
}

static void copy_pdf_out(cr_drape_sampler *s) {
    int64_t cells = (int64_t)s->G * s->G;
    for (int64_t c = 0; c < cells; c++)
        s->pdf_f[c] = (float)s->p[c];
}

cr_status cr_drape_sampler_create(const cr_drape_sampler_def *def, cr_drape_sampler **out,
                                  cr_error *err) {
    CR_ASSERT(out);
    *out = NULL;
    CR_TRY(check_def(def, err));
    int32_t G = def->grid;
    size_t cells = (size_t)G * (size_t)G;
    int64_t inside = 0;
    if (def->mask) {
        for (size_t c = 0; c < cells; c++)
            inside += def->mask[c] != 0;
        if (inside == 0)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "drape sampler: mask has no cell inside the chart (%dx%d cells)", G, G);
    } else {
        inside = (int64_t)cells;
    }

    cr_drape_sampler *s = cr_calloc(1, sizeof *s, err);
    if (!s) return CR_ERR_MEMORY;
    s->G = G;
    s->gamma = def->gamma;
    s->mu = def->mu;
    s->lloyd_iterations = def->lloyd_iterations;
    s->lloyd_density = def->lloyd_density;
    s->lloyd_exponent = def->lloyd_exponent;
    s->inside = inside;
    s->mask = cr_malloc(cells, err);
    s->p = cr_malloc(cells * sizeof(double), err);
    s->pdf_f = cr_malloc(cells * sizeof(float), err);
    s->centres = cr_malloc(2 * cells * sizeof(float), err);
    s->weights = cr_malloc(cells * sizeof(double), err);
    if (!s->mask || !s->p || !s->pdf_f || !s->centres || !s->weights ||
        table_alloc(&s->uniform, G, err) != CR_OK || table_alloc(&s->adaptive, G, err) != CR_OK) {
        cr_drape_sampler_destroy(s);
        return CR_ERR_MEMORY;
    }
    for (size_t c = 0; c < cells; c++) {
        s->mask[c] = def->mask ? (def->mask[c] != 0) : 1;
        s->p[c] = s->mask[c] ? 1.0 / (double)inside : 0.0; /* Algorithm 1 starts uniform */
        s->weights[c] = s->mask[c];
    }
    table_build(&s->uniform, G, s->weights);
    copy_pdf_out(s);
    for (int32_t i = 0; i < G; i++)
        for (int32_t j = 0; j < G; j++) {
            s->centres[2 * ((size_t)i * G + j) + 0] = (float)((j + 0.5) / G);
            s->centres[2 * ((size_t)i * G + j) + 1] = (float)((i + 0.5) / G);
        }
    *out = s;
    return CR_OK;
}

void cr_drape_sampler_destroy(cr_drape_sampler *s) {
    if (!s) return;
    free(s->mask);
    free(s->p);
    free(s->pdf_f);
    free(s->centres);
    free(s->weights);
    table_free(&s->uniform);
    table_free(&s->adaptive);
    cr_drape_lloyd_free(&s->lloyd);
    free(s);
}

int32_t cr_drape_sampler_grid(const cr_drape_sampler *s) {
    CR_ASSERT(s);
    return s->G;
}

const float *cr_drape_sampler_cell_centres(const cr_drape_sampler *s) {
    CR_ASSERT(s);
    return s->centres;
}

const float *cr_drape_sampler_pdf(const cr_drape_sampler *s) {
    CR_ASSERT(s);
    return s->pdf_f;
}

/* ------------------------------------------------------------------ update -- */

/* Sum (in double) of a field over the cells inside the mask, refusing a
 * NULL field and non-finite or negative values there (naming the cell);
 * cells outside the mask are not read. */
static cr_status field_sum(const cr_drape_sampler *s, const float *field, const char *what,
                           const char *name, double *sum, cr_error *err) {
    if (!field) return CR_FAIL(err, CR_ERR_INVALID, "drape sampler %s: %s is NULL", what, name);
    int32_t G = s->G;
    int64_t cells = (int64_t)G * G;
    double total = 0.0;
    for (int64_t c = 0; c < cells; c++) {
        if (!s->mask[c]) continue;
        float l = field[c];
        if (!isfinite(l))
            return CR_FAIL(err, CR_ERR_NAN,
                           "drape sampler %s: %s[%lld] (row %lld, column %lld) is %g", what, name,
                           (long long)c, (long long)(c / G), (long long)(c % G), (double)l);
        if (l < 0.0f)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "drape sampler %s: %s[%lld] (row %lld, column %lld) is negative (%g)",
                           what, name, (long long)c, (long long)(c / G), (long long)(c % G),
                           (double)l);
        total += l;
    }
    *sum = total;
    return CR_OK;
}

/* p /= sum(p), then the float copy. */
static void normalise(cr_drape_sampler *s) {
    int64_t cells = (int64_t)s->G * s->G;
    double total = 0.0;
    for (int64_t c = 0; c < cells; c++)
        total += s->p[c];
    for (int64_t c = 0; c < cells; c++)
        s->p[c] /= total;
    copy_pdf_out(s);
}

cr_status cr_drape_sampler_update(cr_drape_sampler *s, const float *cell_loss, cr_error *err) {
    CR_ASSERT(s);
    /* Validate everything before touching p, so a bad field changes nothing. */
    double sum;
    CR_TRY(field_sum(s, cell_loss, "update", "cell_loss", &sum, err));
    if (sum == 0.0) return CR_OK; /* no evidence anywhere: keep the PDF */
    int64_t cells = (int64_t)s->G * s->G;
    double g = s->gamma;
    for (int64_t c = 0; c < cells; c++)
        if (s->mask[c])
            s->p[c] = g * s->p[c] + (1.0 - g) * ((double)cell_loss[c] / sum); /* Eq. 7 */
    normalise(s); /* the paper's rescaling to sum 1 */
    return CR_OK;
}

cr_status cr_drape_sampler_set_pdf(cr_drape_sampler *s, const float *pdf, cr_error *err) {
    CR_ASSERT(s);
    double sum;
    CR_TRY(field_sum(s, pdf, "set_pdf", "pdf", &sum, err));
    if (sum == 0.0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape sampler set_pdf: pdf has no mass inside the "
                       "mask");
    int64_t cells = (int64_t)s->G * s->G;
    for (int64_t c = 0; c < cells; c++)
        s->p[c] = s->mask[c] ? (double)pdf[c] : 0.0;
    normalise(s);
    return CR_OK;
}

/* -------------------------------------------------------------------- draw -- */

typedef struct draw_ctx {
    const cell_table *table;
    int32_t G;
    uint64_t key, stream;
    float *uv; /* (count,2) */
} draw_ctx;

static void draw_range(void *vctx, int64_t begin, int64_t end) {
    const draw_ctx *c = vctx;
    for (int64_t k = begin; k < end; k++) {
        uint32_t w[4];
        cr_philox4x32(c->key, c->stream, (uint64_t)k, w);
        table_sample(c->table, c->G, w, c->uv + 2 * k);
    }
}

/* `count` points of `table` into uv (count,2), point k from counter k of `stream`. */
static void draw_points(const cell_table *table, int32_t G, uint64_t key, uint64_t stream,
                        int64_t count, float *uv) {
    draw_ctx c = {table, G, key, stream, uv};
    cr_parallel_for(count, DRAW_GRAIN, draw_range, &c);
}

cr_status cr_drape_sampler_draw(cr_drape_sampler *s, int32_t n, cr_rng *rng, float *uv_out,
                                cr_error *err) {
    CR_ASSERT(s && rng);
    if (n < 1) return CR_FAIL(err, CR_ERR_INVALID, "drape sampler draw: n = %d < 1", n);
    if (!uv_out) return CR_FAIL(err, CR_ERR_INVALID, "drape sampler draw: uv_out is NULL");
    int64_t m = (int64_t)n * s->lloyd_density;
    if (s->lloyd_iterations > 0 && m > INT32_MAX)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape sampler draw: n = %d times lloyd_density = %d exceeds 2^31 - 1", n,
                       s->lloyd_density);

    int32_t G = s->G;
    int64_t cells = (int64_t)G * G;
    uint64_t key = (uint64_t)cr_rng_u32(rng) << 32;
    key |= cr_rng_u32(rng);

    /* Algorithm 1: N_a = floor(mu N) adaptive, N_u = N - N_a uniform. */
    int32_t na = (int32_t)floor((double)s->mu * n);
    if (na > 0) {
        table_build(&s->adaptive, G, s->p);
        draw_points(&s->adaptive, G, key, STREAM_ADAPTIVE, na, uv_out);
    }
    draw_points(&s->uniform, G, key, STREAM_UNIFORM, n - na, uv_out + 2 * (int64_t)na);
    if (s->lloyd_iterations == 0) return CR_OK;

    /* Lloyd relaxation of the union, with centroids from the mixture the
     * points came from, cell masses f p + (1 - f) uniform. */
    double f = (double)na / n;
    for (int64_t c = 0; c < cells; c++)
        s->weights[c] = s->mask[c] ? f * s->p[c] + (1.0 - f) / (double)s->inside : 0.0;
    CR_TRY(cr_drape_lloyd_relax(&s->lloyd, uv_out, n, s->lloyd_density, s->lloyd_iterations,
                                s->weights, s->lloyd_exponent, s->mask, G, key, STREAM_DENSE, err));
    return CR_OK;
}

/* --------------------------------------------------------------------- PNG -- */

cr_status cr_drape_sampler_write_png(const cr_drape_sampler *s, const float *uv, int32_t n,
                                     const char *path, int size_px, cr_error *err) {
    CR_ASSERT(s);
    if (!path || !path[0]) return CR_FAIL(err, CR_ERR_INVALID, "drape sampler PNG: path is empty");
    if (size_px < PNG_MIN_SIDE || size_px > PNG_MAX_SIDE)
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler PNG %s: size_px %d outside %d..%d", path,
                       size_px, PNG_MIN_SIDE, PNG_MAX_SIDE);
    if (n < 0 || (n > 0 && !uv))
        return CR_FAIL(err, CR_ERR_INVALID, "drape sampler PNG %s: %d points with uv %s", path, n,
                       uv ? "given" : "NULL");
    for (int32_t k = 0; k < n; k++)
        if (!isfinite(uv[2 * k]) || !isfinite(uv[2 * k + 1]))
            return CR_FAIL(err, CR_ERR_NAN, "drape sampler PNG %s: point %d is (%g, %g)", path, k,
                           (double)uv[2 * k], (double)uv[2 * k + 1]);

    int32_t G = s->G;
    int64_t cells = (int64_t)G * G;
    double pmax = 0.0;
    for (int64_t c = 0; c < cells; c++)
        if (s->p[c] > pmax) pmax = s->p[c];
    cr_image img = {0};
    CR_TRY(cr_image_create(size_px, size_px, &img, err));
    static const float OUTSIDE_GREY = 0.45f; /* sRGB: off the viridis ramp, reads as "no chart" */
    for (int y = 0; y < size_px; y++) {
        float v = 1.0f - ((float)y + 0.5f) / (float)size_px; /* v up */
        int32_t i = drape_cell_index(v, G);
        for (int x = 0; x < size_px; x++) {
            int32_t j = drape_cell_index(((float)x + 0.5f) / (float)size_px, G);
            int64_t c = (int64_t)i * G + j;
            float rgb[3] = {OUTSIDE_GREY, OUTSIDE_GREY, OUTSIDE_GREY};
            if (s->mask[c]) cr_colormap_viridis((float)(s->p[c] / pmax), rgb);
            uint8_t *px = img.rgb + 3 * ((size_t)y * size_px + x);
            for (int ch = 0; ch < 3; ch++)
                px[ch] = (uint8_t)lrintf(rgb[ch] * 255.0f);
        }
    }
    /* Points as white squares, one pixel per 512 of image side. */
    int dot = size_px / 512 > 1 ? size_px / 512 : 1;
    for (int32_t k = 0; k < n; k++) {
        float u = uv[2 * k], v = uv[2 * k + 1];
        if (u < 0.0f || u > 1.0f || v < 0.0f || v > 1.0f) continue; /* off the picture */
        int x0 = (int)(u * size_px), y0 = (int)((1.0f - v) * size_px);
        for (int dy = 0; dy < dot; dy++)
            for (int dx = 0; dx < dot; dx++) {
                int x = x0 + dx, y = y0 + dy;
                if (x < 0 || x >= size_px || y < 0 || y >= size_px) continue;
                memset(img.rgb + 3 * ((size_t)y * size_px + x), 255, 3);
            }
    }
    cr_status st = cr_image_write_png(&img, path, err);
    cr_image_free(&img);
    return st;
}
