/* layer_mpnn.c: the encode-process-decode message-passing network of
 * MeshGraphNets (Pfaff et al., "Learning mesh-based simulation with graph
 * networks", ICLR 2021), in the form GDSR writes it (paper 001, sec. 4.2,
 * eq. 6-7: residual edge update from [e_ij, q_i, q_j], residual node update
 * from [q_i, sum_j e_ij, sum_l e_il] over several edge sets).
 *
 * Shapes: N nodes, E_s edges of set s, S edge sets, L latent width, K steps.
 * Gathers of the endpoint latents and the sum over received edges are the
 * engine's gather_rows and scatter_add_rows, so backward is their adjoint
 * pair and the result is deterministic whatever the thread count.
 *
 * The first layer of an edge MLP is split by columns, W [e; h_i; h_j] =
 * W_e e + (W_r h)_i + (W_s h)_j, so the latent products run once per node
 * rather than once per edge and the (E, 3L) concatenation is never built:
 * on a triangle mesh (E ~ 6N) this removes about a third of the processor's
 * multiply-adds and its largest buffers. The values are those of the
 * concatenated form (the loop reference in the tests writes it that way).
 *
 * With the context's gradient off every block runs in the backend's
 * forward-only kernel (cpu_mpnn.c): each edge set sorted by receiver once
 * (not at all when given so), the edge block's gathers, layers, LayerNorm,
 * residual and the receivers' sums in one pass, no tape.
 *
 * Leaves out: hierarchical graphs (HOOD's multi-level edges are ordinary
 * edge sets here; building the levels is geometry's job), weight sharing
 * across steps, mean or max aggregation.
 */
#include "crease/nn_graph.h"

#include "nn/tape.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    MPNN_COOKIE = 0x6d706e31u, /* "mpn1" */
    NAME_CAP = 256,
};

/* LayerNorm epsilon (PyTorch's default). */
static const float LN_EPS = 1e-5f;

/* An MLP with an optional LayerNorm on its output. */
typedef struct block {
    cr_mlp *mlp;
    cr_tensor *ln_w, *ln_b; /* (OUT) or NULL */
} block;

struct cr_mpnn {
    cr_mpnn_def def;
    block node_enc;
    block edge_enc[CR_MPNN_MAX_EDGE_SETS];
    block *edge_proc; /* (K S): step k, set s at k S + s */
    block *node_proc; /* (K) */
    block dec;
};

cr_mpnn_def cr_mpnn_default_def(void) {
    cr_mpnn_def d;
    memset(&d, 0, sizeof d);
    d.edge_sets = 1;
    d.latent = 128;
    d.steps = 3;
    d.hidden_layers = 2;
    d.act = CR_ACT_RELU;
    d.layer_norm = 1;
    d.cookie = MPNN_COOKIE;
    return d;
}

static cr_status block_create(const cr_mpnn_def *d, int in, int out, int norm, cr_nn_params *P,
                              const char *name, cr_rng *rng, block *b, cr_error *err) {
    cr_mlp_def md = cr_mlp_default_def();
    md.nlayers = d->hidden_layers + 1;
    md.widths[0] = in;
    for (int i = 1; i < md.nlayers; i++)
        md.widths[i] = d->latent;
    md.widths[md.nlayers] = out;
    md.act = d->act;
    CR_TRY(cr_mlp_create(&md, P, name, rng, &b->mlp, err));
    if (!norm) return CR_OK;
    char ln[NAME_CAP + 16];
    snprintf(ln, sizeof ln, "%s.ln.weight", name);
    CR_TRY(cr_nn_params_add(P, ln, 1, (int64_t[]){out}, &b->ln_w, err));
    snprintf(ln, sizeof ln, "%s.ln.bias", name);
    CR_TRY(cr_nn_params_add(P, ln, 1, (int64_t[]){out}, &b->ln_b, err));
    cr_nn_fill(b->ln_w, 1.0f); /* the bias starts at zero, as the store leaves it */
    return CR_OK;
}

static cr_tensor *block_norm(cr_nn_ctx *ctx, const block *b, cr_tensor *y) {
    return b->ln_w ? cr_nn_layer_norm(ctx, y, b->ln_w, b->ln_b, LN_EPS) : y;
}

static cr_tensor *block_forward(cr_nn_ctx *ctx, const block *b, cr_tensor *x) {
    return block_norm(ctx, b, cr_mlp_forward(ctx, b->mlp, x));
}

/* An edge block on [e, h[rcv], h[snd]] with its first layer split by
 * columns (see the top of the file). The block's MLP has no inner layer
 * norm or residual (block_create never asks for them), so after the first
 * layer it is linear -> activation per layer, as cr_mlp_forward runs it. */
static cr_tensor *edge_block_forward(cr_nn_ctx *ctx, const block *b, cr_tensor *e, cr_tensor *h,
                                     const cr_nn_graph *g, int64_t L) {
    const cr_mlp_def *md = &b->mlp->def;
    CR_ASSERT(!md->layer_norm && !md->residual && md->widths[0] == 3 * L);
    const cr_linear *first = &b->mlp->layer[0];
    cr_tensor *w_r = cr_nn_slice(ctx, first->weight, 1, L, L);
    cr_tensor *w_s = cr_nn_slice(ctx, first->weight, 1, 2 * L, L);
    cr_tensor *z = cr_nn_linear(ctx, e, cr_nn_slice(ctx, first->weight, 1, 0, L), first->bias);
    z = cr_nn_add(ctx, z,
                  cr_nn_gather_rows(ctx, cr_nn_linear(ctx, h, w_r, NULL), g->receivers, g->edges));
    z = cr_nn_add(ctx, z,
                  cr_nn_gather_rows(ctx, cr_nn_linear(ctx, h, w_s, NULL), g->senders, g->edges));
    for (int i = 0; i < md->nlayers; i++) {
        if (i > 0) z = cr_linear_forward(ctx, &b->mlp->layer[i], z);
        float param;
        cr_act act = cr_mlp_layer_act(md, i, &param);
        z = cr_act_forward(ctx, act, param, z);
    }
    return block_norm(ctx, b, z);
}

static cr_status check_def(const cr_mpnn_def *d, cr_error *err) {
    if (d->node_in < 1 || d->node_out < 1 || d->latent < 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "mpnn: node_in (%d), node_out (%d), latent (%d) must be >= 1", d->node_in,
                       d->node_out, d->latent);
    if (d->edge_sets < 1 || d->edge_sets > CR_MPNN_MAX_EDGE_SETS)
        return CR_FAIL(err, CR_ERR_INVALID, "mpnn: edge_sets %d outside [1,%d]", d->edge_sets,
                       CR_MPNN_MAX_EDGE_SETS);
    for (int s = 0; s < d->edge_sets; s++)
        if (d->edge_in[s] < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "mpnn: edge_in[%d] = %d must be >= 1", s,
                           d->edge_in[s]);
    if (d->steps < 0 || d->hidden_layers < 0 || d->hidden_layers > CR_MLP_MAX_LAYERS - 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "mpnn: steps (%d) must be >= 0 and hidden_layers (%d) in [0,%d]", d->steps,
                       d->hidden_layers, CR_MLP_MAX_LAYERS - 1);
    return CR_OK;
}

/* Everything after allocation; on failure the caller destroys the net. */
static cr_status mpnn_build(cr_mpnn *net, cr_nn_params *P, const char *prefix, cr_rng *rng,
                            cr_error *err) {
    const cr_mpnn_def *d = &net->def;
    int S = d->edge_sets, L = d->latent, ln = d->layer_norm;
    const char *p = prefix ? prefix : "";
    const char *dot = p[0] ? "." : "";
    char name[NAME_CAP];
    /* Longest name part appended here is ".processor.<k>.edge<s>". */
    if (strlen(p) > NAME_CAP - 48)
        return CR_FAIL(err, CR_ERR_INVALID, "mpnn: prefix \"%s\" too long", p);
    snprintf(name, sizeof name, "%s%sencoder.node", p, dot);
    CR_TRY(block_create(d, d->node_in, L, ln, P, name, rng, &net->node_enc, err));
    for (int s = 0; s < S; s++) {
        snprintf(name, sizeof name, "%s%sencoder.edge%d", p, dot, s);
        CR_TRY(block_create(d, d->edge_in[s], L, ln, P, name, rng, &net->edge_enc[s], err));
    }
    for (int k = 0; k < d->steps; k++) {
        for (int s = 0; s < S; s++) {
            snprintf(name, sizeof name, "%s%sprocessor.%d.edge%d", p, dot, k, s);
            CR_TRY(block_create(d, 3 * L, L, ln, P, name, rng, &net->edge_proc[k * S + s], err));
        }
        snprintf(name, sizeof name, "%s%sprocessor.%d.node", p, dot, k);
        CR_TRY(block_create(d, (1 + S) * L, L, ln, P, name, rng, &net->node_proc[k], err));
    }
    snprintf(name, sizeof name, "%s%sdecoder", p, dot);
    return block_create(d, L, d->node_out, 0, P, name, rng, &net->dec, err);
}

cr_status cr_mpnn_create(const cr_mpnn_def *def, cr_nn_params *params, const char *prefix,
                         cr_rng *rng, cr_mpnn **out, cr_error *err) {
    CR_ASSERT(def && params && rng && out && def->cookie == MPNN_COOKIE);
    *out = NULL;
    CR_TRY(check_def(def, err));
    cr_mpnn *net = cr_calloc(1, sizeof *net, err);
    if (!net) return CR_ERR_MEMORY;
    net->def = *def;
    size_t K = (size_t)def->steps;
    net->edge_proc = cr_calloc(K * (size_t)def->edge_sets + 1, sizeof *net->edge_proc, err);
    net->node_proc = cr_calloc(K + 1, sizeof *net->node_proc, err);
    cr_status st = net->edge_proc && net->node_proc ? mpnn_build(net, params, prefix, rng, err)
                                                    : CR_ERR_MEMORY;
    if (st != CR_OK) {
        cr_mpnn_destroy(net);
        return st;
    }
    *out = net;
    return CR_OK;
}

void cr_mpnn_destroy(cr_mpnn *net) {
    if (!net) return;
    const cr_mpnn_def *d = &net->def;
    cr_mlp_destroy(net->node_enc.mlp);
    for (int s = 0; s < d->edge_sets; s++)
        cr_mlp_destroy(net->edge_enc[s].mlp);
    for (int k = 0; k < d->steps; k++) {
        for (int s = 0; net->edge_proc && s < d->edge_sets; s++)
            cr_mlp_destroy(net->edge_proc[k * d->edge_sets + s].mlp);
        if (net->node_proc) cr_mlp_destroy(net->node_proc[k].mlp);
    }
    cr_mlp_destroy(net->dec.mlp);
    free(net->edge_proc);
    free(net->node_proc);
    free(net);
}

/* 1 when t is (rows, cols); else a context error naming `what`. */
static int check_shape(cr_nn_ctx *ctx, const char *what, const cr_tensor *t, int64_t rows,
                       int64_t cols) {
    if (t && t->ndim == 2 && t->shape[0] == rows && t->shape[1] == cols) return 1;
    char s[64];
    NN_FAIL(ctx, t ? CR_ERR_SHAPE : CR_ERR_INVALID, "mpnn: %s: expected (%lld,%lld), got %s", what,
            (long long)rows, (long long)cols, t ? cr_nn_shape_str(t, s, sizeof s) : "NULL");
    return 0;
}

/* ------------------------------------------------------------ inference -- */

/* The kernel's arguments for block b (its MLP's layers, activations and
 * LayerNorm); 0 when the kernel cannot run it (too many layers, a layer
 * too wide, an activation it lacks): the caller takes the ops instead. */
static int block_args(const block *b, nn_mpnn_block_args *a) {
    const cr_mlp_def *md = &b->mlp->def;
    if (md->nlayers > NN_MPNN_MAX_LAYERS || md->layer_norm || md->residual) return 0;
    memset(a, 0, sizeof *a);
    a->nl = md->nlayers;
    a->width[0] = md->widths[0];
    for (int i = 0; i < md->nlayers; i++) {
        const cr_linear *lin = &b->mlp->layer[i];
        float param;
        cr_act act = cr_mlp_layer_act(md, i, &param);
        cr_op op = cr_nn_act_fused_op(act, param);
        if (op == CR_OP_COUNT || lin->out > NN_MPNN_MAX_WIDTH) return 0;
        a->width[i + 1] = lin->out;
        a->w[i] = lin->weight->data;
        a->ldw[i] = lin->in;
        a->b[i] = lin->bias ? lin->bias->data : NULL;
        a->act[i] = op, a->act_p[i] = param;
    }
    a->ln_w = b->ln_w ? b->ln_w->data : NULL;
    a->ln_b = b->ln_b ? b->ln_b->data : NULL;
    a->ln_eps = LN_EPS;
    return 1;
}

/* Run a's block over R rows of x (ldx apart, 0: packed) into out. */
static int block_run(cr_nn_ctx *ctx, nn_mpnn_block_args *a, int64_t R, const float *x, int64_t ldx,
                     float *out) {
    a->R = R, a->x = x, a->ldx = ldx, a->out = out;
    a->scratch = cr_nn_scratch(ctx, "mpnn", ctx->be->mpnn_block_scratch(a) * sizeof(float));
    if (!a->scratch) return 0;
    ctx->be->mpnn_block_forward(a);
    return 1;
}

/* An edge set sorted by receiver for the kernel: off (N+1), perm (E: the
 * given edge of each sorted row; NULL when the given order is sorted), snd
 * and rcv in sorted order. */
typedef struct sorted_edges {
    int64_t *off;
    const int32_t *perm, *snd, *rcv;
} sorted_edges;

static int sort_edges(cr_nn_ctx *ctx, const cr_nn_graph *g, sorted_edges *se) {
    const int64_t E = g->edges, N = g->nodes;
    const int32_t *r = g->receivers;
    se->off = cr_nn_scratch(ctx, "mpnn", sizeof(int64_t) * (size_t)(N + 1));
    if (!se->off) return 0;
    if (ctx->be->index_check(g->senders, E, N) >= 0 || ctx->be->index_check(r, E, N) >= 0) {
        NN_FAIL(ctx, CR_ERR_INVALID, "mpnn: an edge index outside [0,%lld)", (long long)N);
        return 0;
    }
    int64_t k = 1;
    while (k < E && r[k - 1] <= r[k])
        k++;
    if (k >= E) { /* sorted already (a graph built receiver by receiver): the offsets only */
        se->perm = NULL, se->snd = g->senders, se->rcv = r;
        for (int64_t n = 0, e = 0; n <= N; n++) {
            while (e < E && r[e] < n)
                e++;
            se->off[n] = e;
        }
        return 1;
    }
    int32_t *perm = cr_nn_scratch(ctx, "mpnn", sizeof(int32_t) * (size_t)E);
    int32_t *snd = cr_nn_scratch(ctx, "mpnn", sizeof(int32_t) * (size_t)E);
    int32_t *rcv = cr_nn_scratch(ctx, "mpnn", sizeof(int32_t) * (size_t)E);
    if (!perm || !snd || !rcv) return 0;
    ctx->be->csr_build(r, E, N, se->off, perm);
    for (k = 0; k < E; k++)
        snd[k] = g->senders[perm[k]], rcv[k] = r[perm[k]];
    se->perm = perm, se->snd = snd, se->rcv = rcv;
    return 1;
}

/* Inference (the context's gradient off): every block in the backend's
 * forward-only kernel over the step's buffers, each edge set sorted by
 * receiver once so that the receivers' sums come out of the edge pass,
 * straight into the node block's input [h, sum over set 0, ...]. Returns
 * the output, *latent the last h. NULL with no error recorded when a block
 * is one the kernel does not run (the caller takes the ops). */
static cr_tensor *forward_infer(cr_nn_ctx *ctx, const cr_mpnn *net, cr_tensor *x,
                                const cr_nn_graph *graphs, cr_tensor *const *edge_x,
                                cr_tensor **latent) {
    const cr_mpnn_def *d = &net->def;
    const int S = d->edge_sets;
    const int64_t N = x->shape[0], L = d->latent, C = (1 + S) * L;
    nn_mpnn_block_args enc, dec, node, edge, prod;
    if (!block_args(&net->node_enc, &enc) || !block_args(&net->dec, &dec)) return NULL;
    for (int s = 0; s < S; s++)
        if (!block_args(&net->edge_enc[s], &edge)) return NULL;
    for (int k = 0; k < d->steps; k++) {
        if (!block_args(&net->node_proc[k], &node)) return NULL;
        for (int s = 0; s < S; s++)
            if (!block_args(&net->edge_proc[k * S + s], &edge)) return NULL;
    }
    cr_tensor *h = cr_nn_new(ctx, 2, (int64_t[]){N, L});
    cr_tensor *y = cr_nn_new(ctx, 2, (int64_t[]){N, d->node_out});
    float *cat = cr_nn_scratch(ctx, "mpnn", sizeof(float) * (size_t)(N * C));
    float *pr = cr_nn_scratch(ctx, "mpnn", sizeof(float) * (size_t)(2 * N * L)), *ps = pr + N * L;
    if (!h || !y || !cat || !pr || !block_run(ctx, &enc, N, x->data, 0, h->data)) return NULL;
    sorted_edges se[CR_MPNN_MAX_EDGE_SETS];
    float *e[CR_MPNN_MAX_EDGE_SETS] = {NULL};
    for (int s = 0; s < S; s++) {
        const cr_nn_graph *g = &graphs[s];
        if (g->edges == 0) { /* its sum stays zero */
            for (int64_t n = 0; n < N; n++)
                memset(cat + n * C + (1 + s) * L, 0, sizeof(float) * (size_t)L);
            continue;
        }
        e[s] = cr_nn_scratch(ctx, "mpnn", sizeof(float) * (size_t)(g->edges * L));
        if (!e[s] || !sort_edges(ctx, g, &se[s])) return NULL;
        block_args(&net->edge_enc[s], &edge);
        edge.x_rows = se[s].perm;
        if (!block_run(ctx, &edge, g->edges, edge_x[s]->data, 0, e[s])) return NULL;
    }
    for (int k = 0; k < d->steps; k++) {
        for (int s = 0; s < S; s++) {
            const cr_nn_graph *g = &graphs[s];
            if (g->edges == 0) continue;
            /* GDSR eq. 6 with the first layer split by columns (top of
             * file): the receivers' and senders' products W_r h, W_s h,
             * then the block on e with them gathered */
            const block *b = &net->edge_proc[k * S + s];
            const cr_linear *first = &b->mlp->layer[0];
            for (int part = 0; part < 2; part++) {
                memset(&prod, 0, sizeof prod);
                prod.nl = 1, prod.width[0] = L, prod.width[1] = L, prod.act[0] = CR_OP_NONE;
                prod.w[0] = first->weight->data + (1 + part) * L, prod.ldw[0] = 3 * L;
                if (!block_run(ctx, &prod, N, h->data, 0, part ? ps : pr)) return NULL;
            }
            block_args(b, &edge);
            edge.width[0] = L; /* the first L columns of the (L, 3L) weight: e's */
            edge.N = N, edge.res = e[s];
            edge.gath[0] = pr, edge.gath_idx[0] = se[s].rcv;
            edge.gath[1] = ps, edge.gath_idx[1] = se[s].snd;
            edge.agg = cat + (1 + s) * L, edge.ld_agg = C, edge.off = se[s].off;
            if (!block_run(ctx, &edge, g->edges, e[s], 0, e[s])) return NULL;
        }
        /* GDSR eq. 7: h += MLP([h, sum_j e_ij, ...]) */
        for (int64_t n = 0; n < N; n++)
            memcpy(cat + n * C, h->data + n * L, sizeof(float) * (size_t)L);
        block_args(&net->node_proc[k], &node);
        node.res = h->data;
        if (!block_run(ctx, &node, N, cat, C, h->data)) return NULL;
    }
    if (!block_run(ctx, &dec, N, h->data, 0, y->data)) return NULL;
    if (latent) *latent = h;
    return y;
}

cr_tensor *cr_mpnn_forward(cr_nn_ctx *ctx, const cr_mpnn *net, cr_tensor *x,
                           const cr_nn_graph *graphs, cr_tensor *const *edge_x,
                           cr_tensor **latent) {
    CR_ASSERT(net && graphs && edge_x);
    if (latent) *latent = NULL;
    if (!cr_nn_begin(ctx, "mpnn", 1, &x)) return NULL;
    const cr_mpnn_def *d = &net->def;
    int S = d->edge_sets;
    int64_t N = x->shape[0], L = d->latent;
    if (!check_shape(ctx, "x", x, N, d->node_in)) return NULL;
    cr_tensor *e[CR_MPNN_MAX_EDGE_SETS] = {NULL};
    for (int s = 0; s < S; s++) {
        const cr_nn_graph *g = &graphs[s];
        if (g->nodes != N || g->edges < 0 || (g->edges > 0 && (!g->senders || !g->receivers))) {
            NN_FAIL(ctx, CR_ERR_INVALID,
                    "mpnn: edge set %d: %lld nodes and %lld edges for "
                    "%lld node rows (or missing index arrays)",
                    s, (long long)g->nodes, (long long)g->edges, (long long)N);
            return NULL;
        }
        char what[32];
        snprintf(what, sizeof what, "edge_x[%d]", s);
        if (g->edges > 0 && !check_shape(ctx, what, edge_x[s], g->edges, d->edge_in[s]))
            return NULL;
    }
    if (!ctx->grad_enabled && ctx->be->mpnn_block_forward) {
        cr_tensor *y = forward_infer(ctx, net, x, graphs, edge_x, latent);
        if (y || ctx->err.status != CR_OK) return y;
    }
    cr_tensor *h = block_forward(ctx, &net->node_enc, x);
    for (int s = 0; s < S; s++)
        if (graphs[s].edges > 0) e[s] = block_forward(ctx, &net->edge_enc[s], edge_x[s]);
    cr_tensor *zero_agg = NULL; /* shared sum for edge sets with no edges */
    for (int k = 0; k < d->steps; k++) {
        cr_tensor *node_in[1 + CR_MPNN_MAX_EDGE_SETS] = {h};
        for (int s = 0; s < S; s++) {
            const cr_nn_graph *g = &graphs[s];
            if (g->edges == 0) {
                if (!zero_agg) zero_agg = cr_nn_zeros(ctx, 2, (int64_t[]){N, L});
                node_in[1 + s] = zero_agg;
                continue;
            }
            /* GDSR eq. 6: e_ij += MLP([e_ij, q_i, q_j]), i the receiver. */
            e[s] = cr_nn_add(ctx, e[s],
                             edge_block_forward(ctx, &net->edge_proc[k * S + s], e[s], h, g, L));
            node_in[1 + s] = cr_nn_scatter_add_rows(ctx, e[s], g->receivers, N);
        }
        /* GDSR eq. 7: q_i += MLP([q_i, sum_j e_ij, ...]). A NULL left by a
         * failed op makes concat return NULL quietly. */
        cr_tensor *upd =
            block_forward(ctx, &net->node_proc[k], cr_nn_concat(ctx, 1 + S, node_in, 1));
        h = cr_nn_add(ctx, h, upd);
    }
    cr_tensor *y = block_forward(ctx, &net->dec, h);
    if (!y) return NULL;
    if (latent) *latent = h;
    return y;
}
