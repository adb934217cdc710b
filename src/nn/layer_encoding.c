/* layer_encoding.c: input encodings for coordinate networks.
 *
 *   Fourier positional encoding   [x, sin(2^k pi x), cos(2^k pi x)]_k, from ops
 *   multi-resolution grid encoding bilinear features of L nested UV grids, one fused op
 *
 * Grid encoding (drape paper, sec. 3.1, eq. 4-5). Level l holds
 * (r_l + 1) x (r_l + 1) nodes of F features, r_l = floor(R / 2^l) cells per
 * side, stored [iv][iu][f]; node (iu, iv) sits at (u, v) = (iu, iv) / r_l.
 * For a point, x = u r_l, i = min(floor(x), r_l - 1), fx = x - i (same for
 * v), and the level's feature is eq. 4 with unit cells:
 *   F(u,v) = (1-fx)(1-fy) G[i][j] + fx (1-fy) G[i+1][j] + (1-fx) fy G[i][j+1] + fx fy G[i+1][j+1]
 * (indices written [u][v]). Levels are concatenated finest first (eq. 5).
 *
 * Backward. d/dG is a scatter of the four bilinear weights. To keep it
 * race-free and deterministic whatever the thread count, points are sorted by
 * cell (a stable counting sort), then threads own whole rows of nodes and each
 * node gathers, in double, from the points of its (up to) four cells in a
 * fixed order; the naive serial scatter is what the tests compare against.
 * A level with at least half as many nodes as the batch has points (crease
 * fit's 4,096 points on 101 x 101 and 51 x 51 nodes) takes that plain scatter
 * instead, in point order, a thread per level: the gather's cost is in the
 * nodes, the scatter's in the points.
 * d/d(u,v) is the bilinear derivative, per point and so trivially parallel:
 *   dF/du = r_l ((1-fy)(G[i+1][j] - G[i][j]) + fy (G[i+1][j+1] - G[i][j+1])).
 * u and v are clamped to [0,1] (a UV layout's border, where float round-off
 * may step just outside); where the clamp acts the gradient along that axis
 * is zero.
 * Leaves out: hashing (Instant-NGP's hash tables; the paper's grids are dense
 * and small), 3-D grids, smoothstep interpolation.
 * References: drape paper (000) sec. 3.1; Mueller et al., Instant Neural
 * Graphics Primitives, 2022 (init range); Mildenhall et al., NeRF, 2020
 * (positional encoding).
 */
#include "crease/nn_layers.h"
#include "nn/tape.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { GRID_COOKIE = 0x47524431u /* "GRD1" */ };

/* ------------------------------------------------- Fourier encoding -- */

int64_t cr_fourier_encoding_dim(int64_t in_dim, int nfreq) {
    return in_dim * (1 + 2 * (int64_t)nfreq);
}

cr_tensor *cr_fourier_encoding_forward(cr_nn_ctx *ctx, cr_tensor *x, int nfreq) {
    /* 2^30 pi x is already far below float resolution of x: more is a bug. */
    CR_ASSERT(nfreq >= 0 && nfreq <= 30);
    if (!x || nfreq == 0) return x ? x : cr_nn_reshape(ctx, x, 0, NULL);
    int64_t d = x->ndim > 0 ? x->shape[x->ndim - 1] : 1, n = d > 0 ? x->numel / d : 0;
    float freq[30];
    for (int k = 0; k < nfreq; k++)
        freq[k] = (float)(ldexp(M_PI, k)); /* 2^k pi */
    cr_tensor *f = cr_nn_from(ctx, 3, (int64_t[]){1, nfreq, 1}, freq);
    cr_tensor *a = cr_nn_mul(ctx, cr_nn_reshape(ctx, x, 3, (int64_t[]){n, 1, d}), f); /* (N,K,D) */
    int64_t s4[4] = {n, nfreq, 1, d};
    cr_tensor *sc[2] = {cr_nn_reshape(ctx, cr_nn_sin(ctx, a), 4, s4),
                        cr_nn_reshape(ctx, cr_nn_cos(ctx, a), 4, s4)};
    cr_tensor *parts[2] = {
        cr_nn_reshape(ctx, x, 2, (int64_t[]){n, d}),
        cr_nn_reshape(ctx, cr_nn_concat(ctx, 2, sc, 2), 2, (int64_t[]){n, 2 * nfreq * d})};
    cr_tensor *y = cr_nn_concat(ctx, 2, parts, 1); /* (N, D + 2KD) */
    if (!y || x->ndim <= 1) return y;
    int64_t shape[CR_NN_MAX_DIMS];
    for (int i = 0; i < x->ndim; i++)
        shape[i] = x->shape[i];
    shape[x->ndim - 1] = cr_fourier_encoding_dim(d, nfreq);
    return cr_nn_reshape(ctx, y, x->ndim, shape);
}

/* ---------------------------------------------------- grid encoding -- */

cr_grid_encoding_def cr_grid_encoding_default_def(void) {
    cr_grid_encoding_def d;
    memset(&d, 0, sizeof d);
    d.levels = 2;
    d.resolution = 100;
    d.features = 3;
    d.init_range = 1e-4f;
    d.cookie = GRID_COOKIE;
    return d;
}

static int level_cells(const cr_grid_encoding_def *def, int l) {
    return def->resolution >> l;
}

int64_t cr_grid_encoding_param_count(const cr_grid_encoding_def *def) {
    int64_t n = 0;
    for (int l = 0; l < def->levels; l++) {
        int64_t s = level_cells(def, l) + 1;
        n += s * s * def->features;
    }
    return n;
}

int cr_grid_encoding_out_dim(const cr_grid_encoding_def *def) {
    return def->levels * def->features;
}

/* Cell index and fraction of a clamped coordinate c in [0,1] on r cells. */
static inline void locate(float c, int r, int *i, float *f) {
    double x = (double)c * r;
    int k = (int)x; /* x >= 0, so truncation is floor */
    if (k > r - 1) k = r - 1;
    *i = k;
    *f = (float)(x - k);
}

static inline float clamp01(float c) {
    return c < 0.0f ? 0.0f : c > 1.0f ? 1.0f : c;
}

typedef struct grid_job {
    const cr_grid_encoding *g;
    const float *uv;     /* (N,2) */
    float *uv_grad;      /* (N,2) or NULL */
    float *out;          /* (N,L*F) forward output */
    const float *gout;   /* (N,L*F) backward: dL/d(out) */
    float *const *lv;    /* (L) level grids */
    float *lv_grad;      /* backward, one level: (s,s,F) */
    int level;           /* backward, the level being gathered */
    const int64_t *off;  /* (r*r+1) points of each cell in sorted order */
    const int32_t *perm; /* (N) sorted position -> point */
    const float *frac;   /* (N,2) fx, fy of each point on this level */
    float *lv_grads[CR_GRID_MAX_LEVELS]; /* scatter: each level's gradient or NULL */
    int64_t npoints;                     /* scatter: N */
} grid_job;

static void grid_forward_range(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features;
    for (int64_t p = begin; p < end; p++) {
        float u = clamp01(job->uv[2 * p]), v = clamp01(job->uv[2 * p + 1]);
        float *o = job->out + p * L * F;
        for (int l = 0; l < L; l++) {
            int r = job->g->cells[l], s = r + 1, i, j;
            float fx, fy;
            locate(u, r, &i, &fx);
            locate(v, r, &j, &fy);
            const float *g00 = job->lv[l] + ((int64_t)j * s + i) * F, *g10 = g00 + F;
            const float *g01 = g00 + (int64_t)s * F, *g11 = g01 + F;
            float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy,
                  w11 = fx * fy;
            for (int f = 0; f < F; f++)
                o[l * F + f] = w00 * g00[f] + w10 * g10[f] + w01 * g01[f] + w11 * g11[f];
        }
    }
}

/* dL/d(u,v) of each point: the bilinear derivative, zero where clamped. */
static void grid_uv_grad_range(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features;
    for (int64_t p = begin; p < end; p++) {
        float ru = job->uv[2 * p], rv = job->uv[2 * p + 1];
        float u = clamp01(ru), v = clamp01(rv);
        const float *go = job->gout + p * L * F;
        double du = 0.0, dv = 0.0;
        for (int l = 0; l < L; l++) {
            int r = job->g->cells[l], s = r + 1, i, j;
            float fx, fy;
            locate(u, r, &i, &fx);
            locate(v, r, &j, &fy);
            const float *g00 = job->lv[l] + ((int64_t)j * s + i) * F, *g10 = g00 + F;
            const float *g01 = g00 + (int64_t)s * F, *g11 = g01 + F;
            double su = 0.0, sv = 0.0;
            for (int f = 0; f < F; f++) {
                double gf = go[l * F + f];
                su += gf * ((1 - fy) * (g10[f] - g00[f]) + fy * (g11[f] - g01[f]));
                sv += gf * ((1 - fx) * (g01[f] - g00[f]) + fx * (g11[f] - g10[f]));
            }
            du += r * su;
            dv += r * sv;
        }
        if (ru == u) job->uv_grad[2 * p] += (float)du;
        if (rv == v) job->uv_grad[2 * p + 1] += (float)dv;
    }
}

/* One level's grid gradient, rows [begin,end) of nodes: each node gathers
 * from the points of the cells around it. */
static void grid_gather_rows(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features, l = job->level;
    int r = job->g->cells[l], s = r + 1;
    double acc[CR_GRID_MAX_FEATURES];
    for (int64_t jn = begin; jn < end; jn++) {
        for (int in = 0; in < s; in++) {
            for (int f = 0; f < F; f++)
                acc[f] = 0.0;
            for (int cj = (int)jn - 1; cj <= (int)jn; cj++) {
                if (cj < 0 || cj >= r) continue;
                for (int ci = in - 1; ci <= in; ci++) {
                    if (ci < 0 || ci >= r) continue;
                    int64_t cell = (int64_t)cj * r + ci;
                    for (int64_t q = job->off[cell]; q < job->off[cell + 1]; q++) {
                        int32_t p = job->perm[q];
                        float fx = job->frac[2 * p], fy = job->frac[2 * p + 1];
                        double w = (ci == in ? 1 - fx : fx) * (double)(cj == jn ? 1 - fy : fy);
                        const float *go = job->gout + (int64_t)p * L * F + l * F;
                        for (int f = 0; f < F; f++)
                            acc[f] += w * go[f];
                    }
                }
            }
            float *gg = job->lv_grad + (jn * s + in) * F;
            for (int f = 0; f < F; f++)
                gg[f] += (float)acc[f];
        }
    }
}

/* Levels [begin,end) of a small batch: each level's gradient by the plain
 * scatter of its points' four bilinear weights, in point order (one thread
 * a level, so the sums are the same on any thread count). */
static void grid_scatter_levels(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features;
    int64_t n = job->npoints;
    for (int64_t l = begin; l < end; l++) {
        int r = job->g->cells[l], s = r + 1;
        float *lg = job->lv_grads[l];
        if (!lg) continue;
        for (int64_t p = 0; p < n; p++) {
            int i, j;
            float fx, fy;
            locate(clamp01(job->uv[2 * p]), r, &i, &fx);
            locate(clamp01(job->uv[2 * p + 1]), r, &j, &fy);
            const float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy,
                        w11 = fx * fy;
            const float *go = job->gout + p * L * F + l * F;
            float *g00 = lg + ((int64_t)j * s + i) * F, *g10 = g00 + F;
            float *g01 = g00 + (int64_t)s * F, *g11 = g01 + F;
            for (int f = 0; f < F; f++) {
                g00[f] += w00 * go[f];
                g10[f] += w10 * go[f];
                g01[f] += w01 * go[f];
                g11[f] += w11 * go[f];
            }
        }
    }
}

static cr_status grid_check(const cr_grid_encoding *g, cr_tensor *const *in, int nin,
                            cr_error *err) {
    if (nin != 1 + g->def.levels)
        return CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: %d inputs, expected %d", nin,
                       1 + g->def.levels);
    const cr_tensor *uv = in[0];
    if (uv->ndim != 2 || uv->shape[1] != 2) {
        char s[64];
        return CR_FAIL(err, CR_ERR_SHAPE, "grid_encoding: uv must be (N,2), got %s",
                       cr_nn_shape_str(uv, s, sizeof s));
    }
    for (int64_t k = 0; k < uv->numel; k++)
        if (!isfinite(uv->data[k]))
            return CR_FAIL(err, CR_ERR_NAN, "grid_encoding: uv of point %lld is not finite (%g)",
                           (long long)(k / 2), (double)uv->data[k]);
    return CR_OK;
}

static cr_status grid_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                              cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)ctx, (void)nout, (void)stash;
    const cr_grid_encoding *g = op->user;
    CR_TRY(grid_check(g, in, nin, err));
    float *lv[CR_GRID_MAX_LEVELS];
    for (int l = 0; l < g->def.levels; l++)
        lv[l] = in[1 + l]->data;
    grid_job job = {.g = g, .uv = in[0]->data, .out = out[0]->data, .lv = lv};
    cr_parallel_for(in[0]->shape[0], 256, grid_forward_range, &job);
    return CR_OK;
}

static cr_status grid_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                               cr_tensor *const *out, int nout, void *stash, cr_error *err) {
    (void)nin, (void)nout, (void)stash;
    const cr_grid_encoding *g = op->user;
    int64_t n = in[0]->shape[0];
    float *lv[CR_GRID_MAX_LEVELS];
    for (int l = 0; l < g->def.levels; l++)
        lv[l] = in[1 + l]->data;
    grid_job job = {.g = g, .uv = in[0]->data, .gout = out[0]->grad, .lv = lv};
    if (in[0]->requires_grad) {
        job.uv_grad = in[0]->grad;
        cr_parallel_for(n, 256, grid_uv_grad_range, &job);
    }
    /* A level with at least half as many nodes as the batch has points
     * scatters (the sorted gather visits every node, most of them with no
     * point, after a serial sort); on a finer batch it sorts and gathers. */
    int scatter = 0;
    for (int l = 0; l < g->def.levels; l++) {
        int64_t s = g->cells[l] + 1;
        job.lv_grads[l] = NULL;
        if (!in[1 + l]->requires_grad || n > 2 * s * s) continue;
        job.lv_grads[l] = in[1 + l]->grad;
        scatter = 1;
    }
    job.npoints = n;
    if (scatter) cr_parallel_for(g->def.levels, 1, grid_scatter_levels, &job);
    for (int l = 0; l < g->def.levels; l++) {
        if (!in[1 + l]->requires_grad || job.lv_grads[l]) continue;
        int r = g->cells[l];
        int64_t cells = (int64_t)r * r;
        int64_t *off = cr_nn_scratch(ctx, "grid_encoding", (size_t)(cells + 1) * sizeof(int64_t));
        int32_t *perm = cr_nn_scratch(ctx, "grid_encoding", (size_t)n * sizeof(int32_t));
        int32_t *cell = cr_nn_scratch(ctx, "grid_encoding", (size_t)n * sizeof(int32_t));
        float *frac = cr_nn_scratch(ctx, "grid_encoding", (size_t)n * 2 * sizeof(float));
        if (!off || !perm || !cell || !frac)
            return CR_FAIL(err, CR_ERR_MEMORY, "grid_encoding: backward scratch exhausted");
        /* Stable counting sort of the points by cell. */
        memset(off, 0, (size_t)(cells + 1) * sizeof(int64_t));
        for (int64_t p = 0; p < n; p++) {
            int i, j;
            locate(clamp01(job.uv[2 * p]), r, &i, &frac[2 * p]);
            locate(clamp01(job.uv[2 * p + 1]), r, &j, &frac[2 * p + 1]);
            cell[p] = j * r + i;
            off[cell[p] + 1]++;
        }
        for (int64_t c = 0; c < cells; c++)
            off[c + 1] += off[c];
        for (int64_t p = 0; p < n; p++)
            perm[off[cell[p]]++] = (int32_t)p;
        for (int64_t c = cells; c > 0; c--)
            off[c] = off[c - 1]; /* undo the fill's advance */
        off[0] = 0;
        job.level = l;
        job.lv_grad = in[1 + l]->grad;
        job.off = off;
        job.perm = perm;
        job.frac = frac;
        cr_parallel_for(r + 1, 1, grid_gather_rows, &job);
    }
    return CR_OK;
}

cr_status cr_grid_encoding_create(const cr_grid_encoding_def *def, cr_nn_params *params,
                                  const char *prefix, cr_rng *rng, cr_grid_encoding **out,
                                  cr_error *err) {
    CR_ASSERT(def && def->cookie == GRID_COOKIE && params && rng && out);
    *out = NULL;
    if (def->levels < 1 || def->levels > CR_GRID_MAX_LEVELS)
        return CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: levels must be in 1..%d, got %d",
                       CR_GRID_MAX_LEVELS, def->levels);
    if (def->resolution < 1 || (def->resolution >> (def->levels - 1)) < 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "grid_encoding: resolution %d leaves level %d without a cell "
                       "(need resolution >= 2^(levels-1))",
                       def->resolution, def->levels - 1);
    if (def->features < 1 || def->features > CR_GRID_MAX_FEATURES)
        return CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: features must be in 1..%d, got %d",
                       CR_GRID_MAX_FEATURES, def->features);
    if (!(def->init_range >= 0.0f) || !isfinite(def->init_range))
        return CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: init_range must be >= 0, got %g",
                       (double)def->init_range);
    /* Points are int32 indices into a level; nodes must fit the store. */
    if ((int64_t)def->resolution * def->resolution > INT32_MAX / 2)
        return CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: resolution %d is too large",
                       def->resolution);
    cr_grid_encoding *g = cr_calloc(1, sizeof *g, err);
    if (!g) return CR_ERR_MEMORY;
    g->def = *def;
    g->op = (cr_fused_op){
        .name = "grid_encoding", .forward = grid_forward, .backward = grid_backward, .user = g};
    for (int l = 0; l < def->levels; l++) {
        g->cells[l] = level_cells(def, l);
        int64_t s = g->cells[l] + 1;
        char name[128];
        int len = prefix && *prefix ? snprintf(name, sizeof name, "%s.level%d", prefix, l)
                                    : snprintf(name, sizeof name, "level%d", l);
        cr_status st = len < 0 || len >= (int)sizeof name
                           ? CR_FAIL(err, CR_ERR_INVALID, "grid_encoding: prefix too long")
                           : cr_nn_params_add(params, name, 3, (int64_t[]){s, s, def->features},
                                              &g->level[l], err);
        if (st != CR_OK) {
            free(g);
            return st;
        }
        cr_nn_fill_uniform(g->level[l], rng, -def->init_range, def->init_range);
    }
    *out = g;
    return CR_OK;
}

void cr_grid_encoding_destroy(cr_grid_encoding *g) {
    free(g);
}

cr_tensor *cr_grid_encoding_forward(cr_nn_ctx *ctx, const cr_grid_encoding *g, cr_tensor *uv) {
    cr_tensor *in[1 + CR_GRID_MAX_LEVELS];
    in[0] = uv;
    for (int l = 0; l < g->def.levels; l++)
        in[1 + l] = g->level[l];
    if (!cr_nn_begin(ctx, "grid_encoding", 1, &uv)) return NULL;
    cr_nn_shape shape = {.ndim = 2, .d = {uv->shape[0], cr_grid_encoding_out_dim(&g->def)}};
    return cr_nn_fused(ctx, &g->op, 1 + g->def.levels, in, 1, &shape, NULL);
}
