/* layer_gat.c: multi-head graph attention with Lipschitz normalisation
 * (GAT-LN), SwinGar's f_AttLN (paper 002, sec. III-A, eq. 2-5).
 *
 * Scores are GAT's (Velickovic et al., ICLR 2018, eq. 1-3): for edge j -> i
 * and head k, g_ij = a_dst . W_k x_i + a_src . W_k x_j, which is linear in
 * the input X, as eq. 2 of SwinGar requires of its score function g. Eq. 4
 * normalises them:
 *
 *   g*(X) = alpha g(X) / max{ ||g(X)||_(2,inf), ||X^T||_(inf,2) L_F,(2,inf)(g) }
 *
 * The paper defines the symbols only in words, so this is our reading, each
 * choice made so that the bound of Dasoulas et al. (ICML 2021, the paper's
 * [50]) holds and the layer stays linear-time on a mesh:
 *  - ||g(X)||_(2,inf): the score matrix is masked to the graph, so its row i
 *    holds the scores of i's incoming edges; the norm is the largest row
 *    2-norm, max_i sqrt(sum_{j->i} g_ij^2). It bounds every |g_ij|, which is
 *    what makes |g*_ij| <= alpha.
 *  - ||X^T||_(inf,2): the largest 2-norm of a node's input features (X is
 *    d x N with nodes as columns, so X^T has them as rows), max_n |x_n|.
 *  - L_F,(2,inf)(g), "the spectral norm of the parameters of g": g acts on
 *    an edge's input pair [x_i; x_j] through the 1 x 2IN matrix
 *    [ (W_k^T a_dst)^T, (W_k^T a_src)^T ], whose spectral norm is its
 *    2-norm, sqrt(|W_k^T a_dst|^2 + |W_k^T a_src|^2). This is the per-edge
 *    Lipschitz constant; the row-wise constant of the masked matrix picks up
 *    at most a factor sqrt(max in-degree) (about 2.6 on a triangle mesh),
 *    which alpha absorbs. It is never larger than |a| |W_k|_2, so it is the
 *    tightest choice and needs no power iteration; gradients flow through it.
 *  - Eq. 4 takes the norms over the whole graph (CR_GAT_NORM_GLOBAL). The
 *    reference code of Dasoulas et al. localises them to each receiver's
 *    neighbourhood; CR_GAT_NORM_RECEIVER does the same with eq. 4's terms
 *    (row norm of receiver i; largest |x| among i and its senders).
 *  - LeakyReLU(0.2) follows the normalisation, as in GAT and in Dasoulas et
 *    al.'s DeepGAT; it is 1-Lipschitz and shrinks |.|, so the bound survives.
 * Both denominator terms are positively homogeneous of degree 1 in X, so g*
 * is invariant to scaling the features, and the maximum is kept as a
 * selection (its gradient reaches the larger term, like torch.max).
 *
 * Maxima are taken on the host over the eagerly computed values and turned
 * into gathers of the winning entries, since the engine has no max op.
 * With the context's gradient off the layer runs the backend's forward-only
 * kernel instead (forward_infer, src/nn/cpu/cpu_gat.c): the same values
 * within float rounding, nothing on the tape.
 * Leaves out: dropout on attention, edge features in the score (GATv2,
 * HOOD-style edges go through the MPNN instead), bipartite graphs.
 */
#include "crease/nn_graph.h"

#include "nn/tape.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum { GAT_COOKIE = 0x67617431u }; /* "gat1" */

/* Floors that keep the normaliser finite on an all-zero graph without
 * changing any value of ordinary size: sqrt(r + ROW_TINY) has a finite
 * derivative at r = 0; DEN_TINY guards the division when X = 0. */
static const float ROW_TINY = 1e-24f;
static const float DEN_TINY = 1e-12f;
static const float NORM_EPS = 1e-12f; /* cr_nn_norm's floor for |x| */

cr_gat_def cr_gat_default_def(void) {
    cr_gat_def d;
    memset(&d, 0, sizeof d);
    d.heads = 1;
    d.concat = 1;
    d.self_loops = 1;
    d.bias = 1;
    d.negative_slope = 0.2f;
    d.norm = CR_GAT_NORM_GLOBAL;
    d.alpha = 2.0f;
    d.act = CR_ACT_NONE;
    d.cookie = GAT_COOKIE;
    return d;
}

int cr_gat_out_dim(const cr_gat_def *def) {
    return def->concat ? def->heads * def->out : def->out;
}

static cr_status gat_name(char *buf, size_t cap, const char *prefix, const char *leaf,
                          cr_error *err) {
    int n = prefix && prefix[0] ? snprintf(buf, cap, "%s.%s", prefix, leaf)
                                : snprintf(buf, cap, "%s", leaf);
    if (n < 0 || (size_t)n >= cap)
        return CR_FAIL(err, CR_ERR_INVALID, "gat: parameter name too long: prefix \"%s\"", prefix);
    return CR_OK;
}

cr_status cr_gat_create(const cr_gat_def *def, cr_nn_params *params, const char *prefix,
                        cr_rng *rng, cr_gat *out, cr_error *err) {
    CR_ASSERT(def && params && rng && out && def->cookie == GAT_COOKIE);
    memset(out, 0, sizeof *out);
    if (def->input < 1 || def->out < 1 || def->heads < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "gat: input (%d), out (%d), heads (%d) must be >= 1",
                       def->input, def->out, def->heads);
    if (!(def->alpha >= 0.0f) || !isfinite(def->alpha))
        return CR_FAIL(err, CR_ERR_INVALID, "gat: alpha must be finite and >= 0, got %g",
                       (double)def->alpha);
    if (!isfinite(def->negative_slope))
        return CR_FAIL(err, CR_ERR_INVALID, "gat: negative_slope is not finite");
    if ((unsigned)def->norm > (unsigned)CR_GAT_NORM_RECEIVER)
        return CR_FAIL(err, CR_ERR_INVALID, "gat: unknown norm %d", (int)def->norm);
    if ((unsigned)def->act >= (unsigned)CR_ACT_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID, "gat: unknown activation %d", (int)def->act);
    cr_gat g = {.def = *def};
    int64_t H = def->heads, F = def->out;
    char name[256];
    cr_linear_def ld = cr_linear_default_def();
    ld.in = def->input;
    ld.out = (int)(H * F);
    ld.bias = 0;
    ld.init = CR_INIT_GLOROT_UNIFORM;
    CR_TRY(gat_name(name, sizeof name, prefix, "lin", err));
    CR_TRY(cr_linear_create(&ld, params, name, rng, &g.lin, err));
    CR_TRY(gat_name(name, sizeof name, prefix, "att_src", err));
    CR_TRY(cr_nn_params_add(params, name, 2, (int64_t[]){H, F}, &g.att_src, err));
    CR_TRY(gat_name(name, sizeof name, prefix, "att_dst", err));
    CR_TRY(cr_nn_params_add(params, name, 2, (int64_t[]){H, F}, &g.att_dst, err));
    if (def->bias) {
        CR_TRY(gat_name(name, sizeof name, prefix, "bias", err));
        CR_TRY(cr_nn_params_add(params, name, 1, (int64_t[]){cr_gat_out_dim(def)}, &g.bias, err));
    }
    /* PyG's glorot on a (1,H,F) tensor uses fan_in + fan_out = H + F, which is
     * what cr_init_glorot_uniform computes for (H,F). */
    cr_init_glorot_uniform(g.att_src, rng, 1.0f);
    cr_init_glorot_uniform(g.att_dst, rng, 1.0f);
    *out = g;
    return CR_OK;
}

/* The edges attention runs over: the given ones, checked, minus self loops
 * plus one loop per node when asked. Arena arrays. Returns E' or -1. */
static int64_t build_edges(cr_nn_ctx *ctx, const cr_nn_graph *g, int self_loops, int32_t **snd,
                           int32_t **rcv) {
    int64_t N = g->nodes, E = g->edges;
    if (E < 0 || (E > 0 && (!g->senders || !g->receivers))) {
        NN_FAIL(ctx, CR_ERR_INVALID, "gat: graph: %lld edges with missing index arrays",
                (long long)E);
        return -1;
    }
    int64_t cap = E + (self_loops ? N : 0);
    int32_t *s = cr_nn_scratch(ctx, "gat", (size_t)(cap > 0 ? cap : 1) * sizeof *s);
    int32_t *r = cr_nn_scratch(ctx, "gat", (size_t)(cap > 0 ? cap : 1) * sizeof *r);
    if (!s || !r) return -1;
    int64_t n = 0;
    for (int64_t e = 0; e < E; e++) {
        int32_t a = g->senders[e], b = g->receivers[e];
        if (a < 0 || a >= N || b < 0 || b >= N) {
            NN_FAIL(ctx, CR_ERR_RANGE, "gat: edge %lld: %d -> %d outside the %lld nodes",
                    (long long)e, a, b, (long long)N);
            return -1;
        }
        if (self_loops && a == b) continue;
        s[n] = a;
        r[n] = b;
        n++;
    }
    for (int64_t i = 0; self_loops && i < N; i++) {
        s[n] = (int32_t)i;
        r[n] = (int32_t)i;
        n++;
    }
    *snd = s;
    *rcv = r;
    return n;
}

/* Column-wise maximum of t (R,C) within segments, as a gather of the winning
 * entries (so the gradient reaches them). seg NULL: one segment, result
 * (1,C). Otherwise seg (R) in [0,nseg) and the result is (R,C): each row gets
 * the maximum of its own segment. Ties go to the first row. */
static cr_tensor *seg_max(cr_nn_ctx *ctx, cr_tensor *t, const int32_t *seg, int64_t nseg) {
    if (!t) return NULL;
    int64_t R = t->shape[0], C = t->numel / (R > 0 ? R : 1), S = seg ? nseg : 1;
    CR_ASSERT(t->ndim == 2 && R >= 1);
    int32_t *best = cr_nn_scratch(ctx, "gat", (size_t)(S * C) * sizeof *best);
    int64_t nidx = seg ? R * C : C;
    int32_t *idx = cr_nn_scratch(ctx, "gat", (size_t)nidx * sizeof *idx);
    if (!best || !idx) return NULL;
    for (int64_t k = 0; k < S * C; k++)
        best[k] = -1;
    for (int64_t r = 0; r < R; r++) {
        int32_t *b = best + (seg ? seg[r] : 0) * C;
        for (int64_t c = 0; c < C; c++)
            if (b[c] < 0 || t->data[r * C + c] > t->data[b[c] * C + c]) b[c] = (int32_t)r;
    }
    for (int64_t k = 0; k < nidx; k++) {
        int64_t r = k / C, c = k % C;
        idx[k] = (int32_t)(best[(seg ? seg[r] : 0) * C + c] * C + c);
    }
    cr_tensor *flat = cr_nn_reshape(ctx, t, 2, (int64_t[]){R * C, 1});
    cr_tensor *m = cr_nn_gather_rows(ctx, flat, idx, nidx);
    return cr_nn_reshape(ctx, m, 2, (int64_t[]){seg ? R : 1, C});
}

/* Elementwise max{a, b} of equal shapes as a selection: b + [a >= b] (a - b). */
static cr_tensor *select_max(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b) {
    if (!a || !b) return NULL;
    CR_ASSERT(cr_nn_same_shape(a, b));
    cr_tensor *m = cr_nn_new(ctx, a->ndim, a->shape);
    if (!m) return NULL;
    for (int64_t i = 0; i < a->numel; i++)
        m->data[i] = a->data[i] >= b->data[i] ? 1.0f : 0.0f;
    return cr_nn_add(ctx, b, cr_nn_mul(ctx, m, cr_nn_sub(ctx, a, b)));
}

/* Lip(g) per head: |[W_k^T a_dst ; W_k^T a_src]| -> (1,H). */
static cr_tensor *score_lipschitz(cr_nn_ctx *ctx, const cr_gat *gat) {
    int64_t H = gat->def.heads, F = gat->def.out, IN = gat->def.input;
    cr_tensor *w3 = cr_nn_reshape(ctx, gat->lin.weight, 3, (int64_t[]){H, F, IN});
    cr_tensor *ad = cr_nn_reshape(ctx, gat->att_dst, 3, (int64_t[]){H, F, 1});
    cr_tensor *as = cr_nn_reshape(ctx, gat->att_src, 3, (int64_t[]){H, F, 1});
    cr_tensor *u[2] = {cr_nn_sum_axis(ctx, cr_nn_mul(ctx, w3, ad), 1, 0),  /* (H,IN) */
                       cr_nn_sum_axis(ctx, cr_nn_mul(ctx, w3, as), 1, 0)}; /* (H,IN) */
    if (!u[0] || !u[1]) return NULL;
    cr_tensor *L = cr_nn_norm(ctx, cr_nn_concat(ctx, 2, u, 1), NORM_EPS); /* (H,1) */
    return cr_nn_reshape(ctx, L, 2, (int64_t[]){1, H});
}

/* Eq. 4: alpha g / max{ ||g||_(2,inf), ||X^T||_(inf,2) Lip(g) }, g (E,H). */
static cr_tensor *lipschitz_normalise(cr_nn_ctx *ctx, const cr_gat *gat, cr_tensor *x, cr_tensor *g,
                                      const int32_t *snd, const int32_t *rcv, int64_t E,
                                      int64_t N) {
    cr_tensor *L = score_lipschitz(ctx, gat);                                    /* (1,H) */
    cr_tensor *xn = cr_nn_norm(ctx, x, NORM_EPS);                                /* (N,1) */
    cr_tensor *rows = cr_nn_scatter_add_rows(ctx, cr_nn_square(ctx, g), rcv, N); /* (N,H) */
    cr_tensor *row_norm, *x_max;
    if (gat->def.norm == CR_GAT_NORM_GLOBAL) {
        row_norm = cr_nn_sqrt(ctx, cr_nn_add_scalar(ctx, seg_max(ctx, rows, NULL, 0), ROW_TINY));
        x_max = seg_max(ctx, xn, NULL, 0); /* (1,1) */
    } else {
        /* Per edge, the terms of its receiver's neighbourhood. */
        row_norm = cr_nn_sqrt(
            ctx, cr_nn_add_scalar(ctx, cr_nn_gather_rows(ctx, rows, rcv, E), ROW_TINY)); /* (E,H) */
        cr_tensor *ends = select_max(ctx, cr_nn_gather_rows(ctx, xn, snd, E),
                                     cr_nn_gather_rows(ctx, xn, rcv, E)); /* (E,1) */
        x_max = seg_max(ctx, ends, rcv, N);                               /* (E,1) */
    }
    cr_tensor *lip_term = cr_nn_mul(ctx, x_max, L); /* like row_norm: (1,H) or (E,H) */
    cr_tensor *den = cr_nn_add_scalar(ctx, select_max(ctx, row_norm, lip_term), DEN_TINY);
    return cr_nn_mul_scalar(ctx, cr_nn_div(ctx, g, den), gat->def.alpha);
}

/* The edges and their CSR for inference: the step's cached ones when the
 * graph's arrays hold the same edges as at the last call (the layers of one
 * model share a graph), else built and cached. NULL on error. */
static const nn_gat_edges *infer_edges(cr_nn_ctx *ctx, const cr_nn_graph *g, int self_loops) {
    nn_gat_edges *c = ctx->gat_edges;
    size_t bytes = (size_t)g->edges * sizeof(int32_t);
    if (c && c->nodes == g->nodes && c->edges == g->edges && c->self_loops == self_loops &&
        (g->edges == 0 || (memcmp(c->given_snd, g->senders, bytes) == 0 &&
                           memcmp(c->given_rcv, g->receivers, bytes) == 0)))
        return c;
    c = cr_nn_scratch(ctx, "gat", sizeof *c);
    if (!c) return NULL;
    c->nodes = g->nodes, c->edges = g->edges, c->self_loops = self_loops;
    c->E = build_edges(ctx, g, self_loops, &c->snd, &c->rcv);
    if (c->E < 0) return NULL;
    c->given_snd = cr_nn_scratch(ctx, "gat", bytes + 1);
    c->given_rcv = cr_nn_scratch(ctx, "gat", bytes + 1);
    c->off = cr_nn_scratch(ctx, "gat", (size_t)(g->nodes + 1) * sizeof *c->off);
    c->perm = cr_nn_scratch(ctx, "gat", (size_t)(c->E > 0 ? c->E : 1) * sizeof *c->perm);
    if (!c->given_snd || !c->given_rcv || !c->off || !c->perm) return NULL;
    if (g->edges > 0) {
        memcpy(c->given_snd, g->senders, bytes);
        memcpy(c->given_rcv, g->receivers, bytes);
    }
    ctx->be->csr_build(c->rcv, c->E, g->nodes, c->off, c->perm);
    ctx->gat_edges = c;
    return c;
}

/* Inference (the context's gradient off): the projection's GEMM, then the
 * scores, normalisation, softmax, weighted sum, bias and activation in the
 * backend's one forward-only kernel (an activation it lacks, sin, after it);
 * nothing on the tape and no (E,H,F) array. Same values as the ops below within float
 * rounding (tests/test_nn_graph.c). NULL with no error recorded when the
 * graph has no edges (the caller's ops handle that). */
static cr_tensor *forward_infer(cr_nn_ctx *ctx, const cr_gat *gat, cr_tensor *x,
                                const cr_nn_graph *g) {
    const cr_gat_def *d = &gat->def;
    const cr_nn_backend *be = ctx->be;
    int64_t N = g->nodes, H = d->heads, F = d->out, C = cr_gat_out_dim(d);
    const nn_gat_edges *ed = infer_edges(ctx, g, d->self_loops);
    if (!ed || ed->E == 0) return NULL;
    /* Several heads read x (IN an edge) rather than p (H F an edge) when IN
     * is at most 2 F (averaged: one GEMM after the sums) or F (concatenated:
     * a GEMM per head): swingar's state and blend layers, the paper size's
     * graph LSTM input. */
    int agg_first = H > 1 && d->input <= (d->concat ? F : 2 * F);
    cr_tensor *p = agg_first ? NULL : cr_linear_forward(ctx, &gat->lin, x); /* (N,HF) */
    cr_tensor *out = cr_nn_new(ctx, 2, (int64_t[]){N, C});
    if ((!p && !agg_first) || !out) return NULL;
    nn_gat_attend_args a = {.N = N,
                            .IN = d->input,
                            .H = H,
                            .F = F,
                            .concat = d->concat,
                            .norm = (int)d->norm,
                            .alpha = d->alpha,
                            .slope = d->negative_slope,
                            .x = x->data,
                            .w = gat->lin.weight->data,
                            .p = p ? p->data : NULL,
                            .att_src = gat->att_src->data,
                            .att_dst = gat->att_dst->data,
                            .off = ed->off,
                            .perm = ed->perm,
                            .snd = ed->snd,
                            .bias = gat->bias ? gat->bias->data : NULL,
                            .out = out->data};
    a.scratch = cr_nn_scratch(ctx, "gat", be->gat_attend_scratch(&a) * sizeof(float));
    if (!a.scratch) return NULL;
    cr_op op = cr_nn_act_fused_op(d->act, d->act_param);
    a.act = op == CR_OP_COUNT ? CR_OP_NONE : op;
    a.act_p = d->act_param;
    be->gat_attend_forward(&a);
    return op == CR_OP_COUNT ? cr_act_forward(ctx, d->act, d->act_param, out) : out;
}

cr_tensor *cr_gat_forward(cr_nn_ctx *ctx, const cr_gat *gat, cr_tensor *x, const cr_nn_graph *g,
                          cr_gat_attention *att) {
    CR_ASSERT(gat && g);
    if (att) memset(att, 0, sizeof *att);
    if (!cr_nn_begin(ctx, "gat", 1, &x)) return NULL;
    const cr_gat_def *d = &gat->def;
    int64_t N = g->nodes, H = d->heads, F = d->out;
    if (x->ndim != 2 || x->shape[0] != N || x->shape[1] != d->input || N < 1) {
        char s[64];
        NN_FAIL(ctx, CR_ERR_SHAPE, "gat: x: expected (%lld,%d) for a graph of %lld nodes, got %s",
                (long long)N, d->input, (long long)N, cr_nn_shape_str(x, s, sizeof s));
        return NULL;
    }
    if (!att && !ctx->grad_enabled && H <= NN_GAT_MAX_HEADS) {
        cr_tensor *y = forward_infer(ctx, gat, x, g);
        if (y || ctx->err.status != CR_OK) return y;
    }
    int32_t *snd = NULL, *rcv = NULL;
    int64_t E = build_edges(ctx, g, d->self_loops, &snd, &rcv);
    if (E < 0) return NULL;
    cr_tensor *out;
    if (E == 0) {
        out = cr_nn_zeros(ctx, 2, (int64_t[]){N, cr_gat_out_dim(d)});
    } else {
        cr_tensor *p = cr_linear_forward(ctx, &gat->lin, x); /* (N,HF) */
        cr_tensor *p3 = cr_nn_reshape(ctx, p, 3, (int64_t[]){N, H, F});
        cr_tensor *s_src = cr_nn_sum_axis(ctx, cr_nn_mul(ctx, p3, gat->att_src), -1, 0); /* (N,H) */
        cr_tensor *s_dst = cr_nn_sum_axis(ctx, cr_nn_mul(ctx, p3, gat->att_dst), -1, 0);
        cr_tensor *score = cr_nn_add(ctx, cr_nn_gather_rows(ctx, s_dst, rcv, E),
                                     cr_nn_gather_rows(ctx, s_src, snd, E)); /* (E,H) */
        if (d->norm != CR_GAT_NORM_NONE)
            score = lipschitz_normalise(ctx, gat, x, score, snd, rcv, E, N);
        cr_tensor *w = cr_nn_segment_softmax(ctx, cr_nn_leaky_relu(ctx, score, d->negative_slope),
                                             rcv, N); /* (E,H) */
        cr_tensor *msg = cr_nn_mul(
            ctx, cr_nn_reshape(ctx, cr_nn_gather_rows(ctx, p, snd, E), 3, (int64_t[]){E, H, F}),
            cr_nn_reshape(ctx, w, 3, (int64_t[]){E, H, 1}));
        out = cr_nn_scatter_add_rows(ctx, msg, rcv, N); /* (N,H,F) */
        out = d->concat ? cr_nn_reshape(ctx, out, 2, (int64_t[]){N, H * F})
                        : cr_nn_mean_axis(ctx, out, 1, 0);
        if (att) {
            att->scores = score;
            att->weights = w;
        }
    }
    if (gat->bias) out = cr_nn_add(ctx, out, gat->bias);
    out = cr_act_forward(ctx, d->act, d->act_param, out);
    if (!out) {
        if (att) memset(att, 0, sizeof *att);
        return NULL;
    }
    if (att) {
        att->edges = E;
        att->senders = snd;
        att->receivers = rcv;
    }
    return out;
}
