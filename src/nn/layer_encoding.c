/* layer_encoding.c: input encodings for coordinate networks.
 *
 *   Fourier positional encoding   [x, sin(2^k pi x), cos(2^k pi x)]_k, from ops
 *   multi-resolution grid encoding features of L nested UV grids, one fused op
 *
 * Grid encoding (drape paper, sec. 3.1, eq. 4-5). Level l holds
 * (r_l + 1) x (r_l + 1) nodes of F features, r_l = floor(R / 2^l) cells per
 * side, stored [iv][iu][f]; node (iu, iv) sits at (u, v) = (iu, iv) / r_l.
 * For a point, x = u r_l, i = min(floor(x), r_l - 1), fx = x - i (same for
 * v), and the level's feature is a tensor product of per-axis weights over
 * a stencil of nodes around the cell (indices written [u][v]):
 *   F(u,v) = sum_a sum_b wx_a(fx) wy_b(fy) G[i+o+a][j+o+b]
 * bilinear (eq. 4 with unit cells): o = 0, a,b in {0,1}, w = (1-f, f);
 * the cubic B-spline: o = -1, a,b in 0..3, its cubic weights (node indices
 * clamped to 0..r_l, so a border cell repeats its edge node). Levels are concatenated finest first
 * (eq. 5). Why more than bilinear: bilinear is C0, its derivative jumps at every cell boundary, and
 * a surface p0 + MLP(GE) shows those jumps as grid-aligned facets that losses evaluated on small
 * local structures hardly see (docs/drape.md); the B-spline is C2. Smoothstep (Instant-NGP's) and
 * Catmull-Rom were measured and not adopted (terraces; slower to drape).
 * The generic loops add bilinear's four products in eq. 4's order, and
 * bilinear's weights and derivatives are exactly 1-f, f and -1, +1, so the
 * bilinear results are the same floats as the formula written out.
 *
 * Backward. d/dG is a scatter of the stencil weights. To keep it
 * race-free and deterministic whatever the thread count, points are sorted by
 * cell (a stable counting sort), then threads own whole rows of nodes and each
 * node gathers, in double, from the points of the cells whose stencils hold
 * it (up to 2 x 2 cells, 4 x 4 for the cubics) in a fixed order; the naive
 * serial scatter is what the tests compare against.
 * A level with at least half as many nodes as the batch has points (crease
 * fit's 4,096 points on 101 x 101 and 51 x 51 nodes; for the 4 x 4 stencils
 * an eighth as many) takes that plain scatter instead, in point
 * order, a thread per level: the gather's cost is in the nodes and their
 * stencil's cells, the scatter's in the points.
 * d/d(u,v) is the interpolant's derivative, per point and so trivially
 * parallel: dF/du = r_l sum_b wy_b sum_a wx_a'(fx) G[..], e.g. bilinear's
 *   dF/du = r_l ((1-fy)(G[i+1][j] - G[i][j]) + fy (G[i+1][j+1] - G[i][j+1])).
 * u and v are clamped to [0,1] (a UV layout's border, where float round-off
 * may step just outside); where the clamp acts the gradient along that axis
 * is zero.
 * Leaves out: hashing (Instant-NGP's hash tables; the paper's grids are dense
 * and small), 3-D grids, SIMD kernels (the encoding is a few per cent of a
 * drape epoch).
 * References: drape paper (000) sec. 3.1; Mueller et al., Instant Neural
 * Graphics Primitives, 2022 (init range); Mildenhall et al., NeRF, 2020
 * (positional encoding); Catmull & Rom, A class of local interpolating
 * splines, 1974; de Boor, A Practical Guide to Splines, 1978 (B-spline basis).
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
    d.interp = CR_GRID_BILINEAR;
    d.cookie = GRID_COOKIE;
    return d;
}

static const char *const interp_names[CR_GRID_INTERP_COUNT] = {"bilinear", "bspline"};

const char *cr_grid_interp_name(cr_grid_interp interp) {
    return (unsigned)interp < CR_GRID_INTERP_COUNT ? interp_names[interp] : "?";
}

cr_status cr_grid_interp_parse(const char *name, cr_grid_interp *out, cr_error *err) {
    for (int k = 0; k < CR_GRID_INTERP_COUNT; k++)
        if (name && strcmp(name, interp_names[k]) == 0) {
            *out = (cr_grid_interp)k;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID, "grid interpolation '%s': expected bilinear or bspline",
                   name ? name : "(null)");
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

static inline int clamp_node(int k, int r) {
    return k < 0 ? 0 : k > r ? r : k;
}

enum { STENCIL_MAX = 4 };

/* Nodes per axis of an interpolation's stencil and the first one's offset
 * from the cell index: i, i+1 or i-1..i+2. */
static inline int stencil_size(cr_grid_interp m) {
    return m == CR_GRID_BSPLINE ? 4 : 2;
}
static inline int stencil_offset(cr_grid_interp m) {
    return stencil_size(m) == 4 ? -1 : 0;
}

/* One axis's weights w (n) at fraction f of the cell and their derivatives
 * dw = dw/df (n). Bilinear's are exactly 1-f, f and -1, +1, so the generic
 * loops below add the same floats in the same order as eq. 4 written out. */
static inline void axis_weights(cr_grid_interp m, float f, float *w, float *dw) {
    switch (m) {
    case CR_GRID_BSPLINE: { /* uniform cubic B-spline basis (de Boor) */
        float f2 = f * f, f3 = f2 * f, g = 1.0f - f;
        w[0] = g * g * g / 6.0f;
        w[1] = (3.0f * f3 - 6.0f * f2 + 4.0f) / 6.0f;
        w[2] = (-3.0f * f3 + 3.0f * f2 + 3.0f * f + 1.0f) / 6.0f;
        w[3] = f3 / 6.0f;
        dw[0] = -0.5f * g * g;
        dw[1] = 0.5f * (3.0f * f2 - 4.0f * f);
        dw[2] = 0.5f * (-3.0f * f2 + 2.0f * f + 1.0f);
        dw[3] = 0.5f * f2;
        return;
    }
    case CR_GRID_BILINEAR:
    default:
        w[0] = 1.0f - f, w[1] = f;
        dw[0] = -1.0f, dw[1] = 1.0f;
        return;
    }
}

/* A point's stencil on one level: n x n nodes (iy[b], ix[a]) (clamped to
 * the grid), weight wx[a] wy[b], and the weights' derivatives along the
 * fraction of the cell. */
typedef struct stencil {
    int n;
    int ix[STENCIL_MAX], iy[STENCIL_MAX];
    float wx[STENCIL_MAX], wy[STENCIL_MAX], dwx[STENCIL_MAX], dwy[STENCIL_MAX];
} stencil;

/* The stencil of cell (i, j) at fractions (fx, fy) on r cells. */
static inline void stencil_in_cell(cr_grid_interp m, int r, int i, int j, float fx, float fy,
                                   stencil *st) {
    int n = stencil_size(m), off = stencil_offset(m);
    st->n = n;
    axis_weights(m, fx, st->wx, st->dwx);
    axis_weights(m, fy, st->wy, st->dwy);
    for (int k = 0; k < n; k++) {
        st->ix[k] = clamp_node(i + off + k, r);
        st->iy[k] = clamp_node(j + off + k, r);
    }
}

/* The stencil of clamped (u, v) on r cells. */
static inline void stencil_at(cr_grid_interp m, int r, float u, float v, stencil *st) {
    int i, j;
    float fx, fy;
    locate(u, r, &i, &fx);
    locate(v, r, &j, &fy);
    stencil_in_cell(m, r, i, j, fx, fy, st);
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
    const float *axis_w; /* (N,2,STENCIL_MAX) each point's u then v weights on this level */
    float *lv_grads[CR_GRID_MAX_LEVELS]; /* scatter: each level's gradient or NULL */
    int64_t npoints;                     /* scatter: N */
} grid_job;

/* A point's features on one level, o (F): the n x n stencil's products. */
static inline void level_features(const stencil *st, int n, const float *lv, int s, int F,
                                  float *o) {
    for (int f = 0; f < F; f++)
        o[f] = -0.0f; /* the exact identity of +, so the first term lands unchanged */
    for (int b = 0; b < n; b++)
        for (int a = 0; a < n; a++) {
            float w = st->wx[a] * st->wy[b];
            const float *gn = lv + ((int64_t)st->iy[b] * s + st->ix[a]) * F;
            for (int f = 0; f < F; f++)
                o[f] += w * gn[f];
        }
}

/* Scatter a point's dL/d(features) go (F) on one level into its nodes' gradient lg. */
static inline void level_scatter(const stencil *st, int n, const float *go, int s, int F,
                                 float *lg) {
    for (int b = 0; b < n; b++)
        for (int a = 0; a < n; a++) {
            float w = st->wx[a] * st->wy[b];
            float *gn = lg + ((int64_t)st->iy[b] * s + st->ix[a]) * F;
            for (int f = 0; f < F; f++)
                gn[f] += w * go[f];
        }
}

static void grid_forward_range(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features;
    for (int64_t p = begin; p < end; p++) {
        float u = clamp01(job->uv[2 * p]), v = clamp01(job->uv[2 * p + 1]);
        float *o = job->out + p * L * F;
        for (int l = 0; l < L; l++) {
            int r = job->g->cells[l], s = r + 1;
            stencil st;
            stencil_at(def->interp, r, u, v, &st);
            if (st.n == 4) /* a constant n at each call, so the loops unroll */
                level_features(&st, 4, job->lv[l], s, F, o + l * F);
            else
                level_features(&st, 2, job->lv[l], s, F, o + l * F);
        }
    }
}

/* dL/d(u,v) of each point: the interpolant's derivative, zero where clamped. */
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
            int r = job->g->cells[l], s = r + 1, n;
            stencil st;
            stencil_at(def->interp, r, u, v, &st);
            n = st.n;
            const float *gn[STENCIL_MAX][STENCIL_MAX]; /* [b][a] */
            for (int b = 0; b < n; b++)
                for (int a = 0; a < n; a++)
                    gn[b][a] = job->lv[l] + ((int64_t)st.iy[b] * s + st.ix[a]) * F;
            double su = 0.0, sv = 0.0;
            for (int f = 0; f < F; f++) {
                double gf = go[l * F + f];
                float dx = -0.0f, dy = -0.0f;
                for (int b = 0; b < n; b++) {
                    float t = -0.0f;
                    for (int a = 0; a < n; a++)
                        t += st.dwx[a] * gn[b][a][f];
                    dx += st.wy[b] * t;
                }
                for (int a = 0; a < n; a++) {
                    float t = -0.0f;
                    for (int b = 0; b < n; b++)
                        t += st.dwy[b] * gn[b][a][f];
                    dy += st.wx[a] * t;
                }
                su += gf * dx;
                sv += gf * dy;
            }
            du += r * su;
            dv += r * sv;
        }
        if (ru == u) job->uv_grad[2 * p] += (float)du;
        if (rv == v) job->uv_grad[2 * p + 1] += (float)dv;
    }
}

/* The stencil slots of cell c whose clamped node is k, on r cells: one
 * inside the grid, up to two at a clamped border. Returns their count. */
static inline int axis_slots(int c, int k, int r, int n, int off, int *slot) {
    /* at least one: the caller visits only cells whose stencil holds k */
    int m = 0;
    for (int a = 0; a < n; a++)
        if (clamp_node(c + off + a, r) == k) slot[m++] = a;
    return m;
}

/* One level's grid gradient, rows [begin,end) of nodes: each node gathers
 * from the points of the cells whose stencils hold it. */
static void grid_gather_rows(void *arg, int64_t begin, int64_t end) {
    const grid_job *job = arg;
    const cr_grid_encoding_def *def = &job->g->def;
    int L = def->levels, F = def->features, l = job->level;
    int r = job->g->cells[l], s = r + 1;
    int n = stencil_size(def->interp), off = stencil_offset(def->interp);
    double acc[CR_GRID_MAX_FEATURES];
    for (int64_t jn = begin; jn < end; jn++) {
        for (int in = 0; in < s; in++) {
            for (int f = 0; f < F; f++)
                acc[f] = 0.0;
            /* cell c's stencil holds nodes c+off .. c+off+n-1 (clamped) */
            for (int cj = (int)jn - off - (n - 1); cj <= (int)jn - off; cj++) {
                if (cj < 0 || cj >= r) continue;
                for (int ci = in - off - (n - 1); ci <= in - off; ci++) {
                    if (ci < 0 || ci >= r) continue;
                    int64_t cell = (int64_t)cj * r + ci;
                    int sx[STENCIL_MAX], sy[STENCIL_MAX];
                    int mx = axis_slots(ci, in, r, n, off, sx);
                    int my = axis_slots(cj, (int)jn, r, n, off, sy);
                    for (int64_t q = job->off[cell]; q < job->off[cell + 1]; q++) {
                        int32_t p = job->perm[q];
                        const float *aw = job->axis_w + (int64_t)p * 2 * STENCIL_MAX;
                        float wx = aw[sx[0]], wy = aw[STENCIL_MAX + sy[0]];
                        for (int k = 1; k < mx; k++) /* a clamped border's repeated node */
                            wx += aw[sx[k]];
                        for (int k = 1; k < my; k++)
                            wy += aw[STENCIL_MAX + sy[k]];
                        double w = wx * (double)wy;
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
 * scatter of its points' stencil weights, in point order (one thread a
 * level, so the sums are the same on any thread count). */
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
            stencil st;
            stencil_at(def->interp, r, clamp01(job->uv[2 * p]), clamp01(job->uv[2 * p + 1]), &st);
            const float *go = job->gout + p * L * F + l * F;
            if (st.n == 4)
                level_scatter(&st, 4, go, s, F, lg);
            else
                level_scatter(&st, 2, go, s, F, lg);
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
     * point, after a serial sort); on a finer batch it sorts and gathers.
     * A 4 x 4 stencil makes each node visit 4 times the cells, so the
     * cubics scatter up to 4 times the points (the drape's 6,144 points
     * then scatter on the 51 x 51 level too: the gather was 40 % of the
     * cubic encoding's time). */
    int64_t area = (int64_t)stencil_size(g->def.interp) * stencil_size(g->def.interp);
    int scatter = 0;
    for (int l = 0; l < g->def.levels; l++) {
        int64_t s = g->cells[l] + 1;
        job.lv_grads[l] = NULL;
        if (!in[1 + l]->requires_grad || 4 * n > 2 * s * s * area) continue;
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
        float *axis_w =
            cr_nn_scratch(ctx, "grid_encoding", (size_t)n * 2 * STENCIL_MAX * sizeof(float));
        if (!off || !perm || !cell || !axis_w)
            return CR_FAIL(err, CR_ERR_MEMORY, "grid_encoding: backward scratch exhausted");
        /* Stable counting sort of the points by cell. */
        memset(off, 0, (size_t)(cells + 1) * sizeof(int64_t));
        for (int64_t p = 0; p < n; p++) {
            int i, j;
            float fx, fy, dw[STENCIL_MAX];
            locate(clamp01(job.uv[2 * p]), r, &i, &fx);
            locate(clamp01(job.uv[2 * p + 1]), r, &j, &fy);
            axis_weights(g->def.interp, fx, axis_w + p * 2 * STENCIL_MAX, dw);
            axis_weights(g->def.interp, fy, axis_w + p * 2 * STENCIL_MAX + STENCIL_MAX, dw);
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
        job.axis_w = axis_w;
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
    if ((unsigned)def->interp >= CR_GRID_INTERP_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "grid_encoding: interpolation %d is not a cr_grid_interp", (int)def->interp);
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
