/* crease/nn_graph.h: recurrent cells and graph layers on the tensor engine.
 *
 *   GRU and LSTM cells in PyTorch's layout, runners over T steps  cr_gru_*, cr_lstm_*
 *   graph attention with Lipschitz normalisation (GAT-LN)         cr_gat_*
 *   SwinGar's graph LSTM whose transforms are GAT-LN layers       cr_gat_lstm_*
 *   encode-process-decode message passing (MeshGraphNets)         cr_mpnn_*
 *
 * House pattern: a def made by its _default_def, a _create that registers
 * the weights in a cr_nn_params store under a name prefix, and a _forward
 * that builds on the tape of a cr_nn_ctx. Forwards follow the engine's error
 * model: NULL on failure with the error recorded on the context (bad shapes
 * and out-of-range node indices are reported, not asserted), and a NULL
 * input passes through quietly, so a whole model is checked once.
 *
 * Graphs are edge lists: edge e carries a message from senders[e] to
 * receivers[e]; an undirected mesh edge is two directed edges. Node order is
 * free: every graph layer here is permutation equivariant (permute the nodes
 * and relabel the edges, and the output rows permute the same way).
 *
 * Shapes: B batch rows, T steps, IN input features, H hidden features,
 * N nodes, E edges, F features per attention head, L latent width.
 */
#ifndef CREASE_NN_GRAPH_H
#define CREASE_NN_GRAPH_H

#include "crease/nn.h"
#include "crease/nn_layers.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ----------------------------------------------------------- recurrent -- */

/* Weights follow torch.nn.LSTMCell / torch.nn.GRUCell one to one, under
 * prefix.weight_ih (G H, IN), prefix.weight_hh (G H, H), prefix.bias_ih and
 * prefix.bias_hh (G H), with the gates stacked in PyTorch's order: LSTM
 * [i, f, g, o] (G = 4), GRU [r, z, n] (G = 3). A torch.nn.LSTM layer's
 * weight_ih_l0 etc. are the same tensors under another name. Initialised as
 * PyTorch does: U(-1/sqrt(H), 1/sqrt(H)). */
typedef struct cr_rnn_def {
    int input;       /* IN, features per step; must be set (>= 1) */
    int hidden;      /* H (default 128, SwinGar's motion feature size) */
    int bias;        /* 1: bias_ih and bias_hh (default, as PyTorch) */
    uint32_t cookie; /* set by cr_rnn_default_def */
} cr_rnn_def;

cr_rnn_def cr_rnn_default_def(void);

/* A cell is a handful of pointers into the params store (which owns them);
 * there is nothing to destroy. */
typedef struct cr_rnn_cell {
    int input, hidden;
    int gates;            /* 4: LSTM, 3: GRU */
    cr_tensor *weight_ih; /* (G H, IN) */
    cr_tensor *weight_hh; /* (G H, H) */
    cr_tensor *bias_ih;   /* (G H) or NULL */
    cr_tensor *bias_hh;   /* (G H) or NULL */
} cr_rnn_cell;

cr_status cr_lstm_cell_create(const cr_rnn_def *def, cr_nn_params *params, const char *prefix,
                              cr_rng *rng, cr_rnn_cell *out, cr_error *err);
cr_status cr_gru_cell_create(const cr_rnn_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_rnn_cell *out, cr_error *err);

/* One step. x (B,IN), h and c (B,H) or NULL for a zero state. Returns the
 * new h (B,H); the LSTM also gives the new cell state in *c_out. */
cr_tensor *cr_lstm_cell_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h,
                                cr_tensor *c, cr_tensor **c_out);
cr_tensor *cr_gru_cell_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h);

/* Run over a sequence: x (T,B,IN), time first as torch.nn.LSTM's default.
 * Returns every hidden state (T,B,H); *h_last (B,H) and *c_last (B,H) (each
 * may be NULL) get the final state. Input projections of all steps are one
 * GEMM; backward through the result is backpropagation through time. */
cr_tensor *cr_lstm_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h0,
                           cr_tensor *c0, cr_tensor **h_last, cr_tensor **c_last);
cr_tensor *cr_gru_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h0,
                          cr_tensor **h_last);

/* --------------------------------------------------------------- graphs -- */

/* Borrowed index arrays (int32, host memory); layers copy what they keep. */
typedef struct cr_nn_graph {
    int64_t nodes;            /* N */
    int64_t edges;            /* E */
    const int32_t *senders;   /* (E) in [0,N): where the message of edge e comes from */
    const int32_t *receivers; /* (E) in [0,N): where it is aggregated */
} cr_nn_graph;

/* ------------------------------------------------------------- GAT-LN -- */

/* Multi-head graph attention (Velickovic et al., ICLR 2018) with the
 * Lipschitz-normalised score of SwinGar (paper 002, eq. 4), which follows
 * Dasoulas et al., "Lipschitz normalization for self-attention layers with
 * application to graph neural networks", ICML 2021. Per head k, with
 * projected features p_j = W_k x_j (F) and score vectors a_src, a_dst (F):
 *
 *   g_ij  = a_dst . p_i + a_src . p_j                 raw score of edge j -> i
 *   g*_ij = alpha g_ij / max{ ||g||_(2,inf), ||X||_(inf,2) Lip(g) }   (eq. 4)
 *   w_ij  = softmax over i's incoming edges of LeakyReLU(g*_ij)
 *   out_i = sum_j w_ij p_j,   heads concatenated (H F) or averaged (F)
 *
 * with ||g||_(2,inf) = max_i sqrt(sum_{j->i} g_ij^2) (largest receiver row
 * of the masked score matrix), ||X||_(inf,2) = max_n |x_n| (largest input
 * feature vector) and Lip(g) = sqrt(|W_k^T a_dst|^2 + |W_k^T a_src|^2), the
 * spectral norm of the linear map (x_i, x_j) -> g_ij (a 1 x 2 IN matrix).
 * Because |g_ij| <= ||g||_(2,inf), every normalised score obeys
 * |g*_ij| <= alpha (per receiver, even sqrt(sum_j g*_ij^2) <= alpha): the
 * softmax cannot saturate (with a LeakyReLU slope in [0,1], weights of one
 * receiver differ by at most a factor exp(2 alpha)), and g* is unchanged
 * when the input features are scaled by any s > 0. alpha is the paper's
 * frequency control (it uses 2; 1..3 in its ablation). With
 * CR_GAT_NORM_GLOBAL the normaliser couples all nodes of one call, so
 * disjoint graphs batched together influence each other's attention; use
 * CR_GAT_NORM_RECEIVER (or one call per graph) when that matters. See
 * layer_gat.c for the reading of the paper's norms. */
typedef enum cr_gat_norm {
    CR_GAT_NORM_NONE = 0, /* plain GAT scores (the paper's ablation baseline) */
    CR_GAT_NORM_GLOBAL,   /* eq. 4 as written: norms over the whole graph (default) */
    CR_GAT_NORM_RECEIVER  /* eq. 4 over each receiver's neighbourhood, as Dasoulas et
                             al.'s code localises it: batched disjoint graphs stay
                             independent and the layer stays local */
} cr_gat_norm;

typedef struct cr_gat_def {
    int input;            /* IN; must be set */
    int out;              /* F, features per head; must be set */
    int heads;            /* H (default 1; SwinGar uses 24 in its encoders, 3 or 8 elsewhere) */
    int concat;           /* 1: output (N, H F), heads side by side (default); 0: mean, (N, F) */
    int self_loops;       /* 1: drop given self loops, add one per node (default, as GAT) */
    int bias;             /* 1: learnt bias added after aggregation (default) */
    float negative_slope; /* LeakyReLU on the scores (default 0.2, GAT's) */
    cr_gat_norm norm;     /* default CR_GAT_NORM_GLOBAL */
    float alpha;          /* score bound of eq. 4, >= 0 (default 2, SwinGar's) */
    cr_act act;           /* applied last (default CR_ACT_NONE; SwinGar uses tanh) */
    float act_param;      /* the activation's parameter (cr_act_forward) */
    uint32_t cookie;      /* set by cr_gat_default_def */
} cr_gat_def;

/* Parameters, named after PyTorch Geometric's GATConv: "<prefix>.lin.weight"
 * (H F, IN) (no bias), "<prefix>.att_src" and "<prefix>.att_dst" (H, F)
 * (GATConv stores them (1, H, F): the same floats), "<prefix>.bias" (H F or
 * F). Glorot-uniform weights and scores, zero bias (GATConv's init). */
typedef struct cr_gat {
    cr_gat_def def;
    cr_linear lin;
    cr_tensor *att_src, *att_dst;
    cr_tensor *bias; /* or NULL */
} cr_gat;

/* What a forward attended to, for tests, plots and losses. Arrays and
 * tensors live in the step arena (valid until the context is reset). */
typedef struct cr_gat_attention {
    int64_t edges;            /* E': edges after self-loop handling */
    const int32_t *senders;   /* (E') */
    const int32_t *receivers; /* (E') */
    cr_tensor *scores;        /* (E',H) g* (g without normalisation), before LeakyReLU */
    cr_tensor *weights;       /* (E',H) w, summing to 1 over each receiver's edges */
} cr_gat_attention;

cr_gat_def cr_gat_default_def(void);
cr_status cr_gat_create(const cr_gat_def *def, cr_nn_params *params, const char *prefix,
                        cr_rng *rng, cr_gat *out, cr_error *err);
/* x (N,IN) -> (N, H F) or (N, F). A node without incoming edges (possible
 * only without self loops) gets the bias alone. att may be NULL. Node
 * indices outside [0,N) fail with CR_ERR_RANGE. */
cr_tensor *cr_gat_forward(cr_nn_ctx *ctx, const cr_gat *gat, cr_tensor *x, const cr_nn_graph *g,
                          cr_gat_attention *att);
int cr_gat_out_dim(const cr_gat_def *def); /* H F or F */

/* ----------------------------------------------------------- graph LSTM -- */

/* SwinGar's LSTM-GAT-LN (paper 002, eq. 6 and Fig. 5): an LSTM over a
 * sequence of graphs of one topology, whose input-to-state and
 * state-to-state transforms are GAT-LN layers and whose i, f, o gates also
 * see the previous cell state through per-feature peephole weights:
 *
 *   z   = GAT_x(X^t) + GAT_h(H^(t-1))                (N,4H), gates [i, f, g, o]
 *   i   = sigmoid(z_i + w_i C^(t-1)),  f = sigmoid(z_f + w_f C^(t-1)),
 *   o   = sigmoid(z_o + w_o C^(t-1))
 *   C^t = f C^(t-1) + i tanh(z_g),     H^t = o tanh(C^t)
 *
 * Eq. 6 as printed closes a parenthesis after f C^(t-1), putting it inside
 * the tanh; we read that as a typo for the usual cell update above. The o
 * gate uses C^(t-1) as eq. 6 writes (Graves' peephole LSTM would use C^t).
 * Eq. 6 writes one f_AttLN for all gates: here each transform is one GAT-LN
 * layer with 4H outputs, sliced into the gates. */
typedef struct cr_gat_lstm_def {
    int input;  /* IN per node; must be set */
    int hidden; /* H per node (default 64, SwinGar's) */
    /* Attention settings shared by both transforms (heads, concat,
     * self_loops, negative_slope, norm, alpha). create fills input, out
     * (4H / heads when concatenating, which needs 4H to be a multiple of
     * heads; else 4H), bias
     * (on GAT_x only) and act (none). */
    cr_gat_def gat;
    int peephole;    /* 1: the w C terms (default) */
    uint32_t cookie; /* set by cr_gat_lstm_default_def */
} cr_gat_lstm_def;

/* Parameters: "<prefix>.x.*" and "<prefix>.h.*" (cr_gat), "<prefix>.w_ci",
 * "<prefix>.w_cf", "<prefix>.w_co" (H), initialised U(-1/sqrt(H), 1/sqrt(H)). */
typedef struct cr_gat_lstm {
    cr_gat_lstm_def def;
    cr_gat gx, gh;
    cr_tensor *peep[3]; /* w_ci, w_cf, w_co, or NULL */
} cr_gat_lstm;

cr_gat_lstm_def cr_gat_lstm_default_def(void);
cr_status cr_gat_lstm_create(const cr_gat_lstm_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_gat_lstm *out, cr_error *err);
/* One step on graph g: x (N,IN), h and c (N,H) or NULL (zero state).
 * Returns H^t; *c_out gets C^t. */
cr_tensor *cr_gat_lstm_cell_forward(cr_nn_ctx *ctx, const cr_gat_lstm *cell, cr_tensor *x,
                                    const cr_nn_graph *g, cr_tensor *h, cr_tensor *c,
                                    cr_tensor **c_out);
/* x (T,N,IN), the same graph at every step -> (T,N,H); *h_last, *c_last
 * (may be NULL) get the final state. */
cr_tensor *cr_gat_lstm_forward(cr_nn_ctx *ctx, const cr_gat_lstm *cell, cr_tensor *x,
                               const cr_nn_graph *g, cr_tensor *h0, cr_tensor *c0,
                               cr_tensor **h_last, cr_tensor **c_last);

/* ------------------------------------------------------ message passing -- */

/* Encode-process-decode graph network (Battaglia et al. 2018; MeshGraphNets,
 * Pfaff et al., ICLR 2021), as GDSR (paper 001, sec. 4.2, eq. 6-7), HOOD and
 * EPNet use it. With S edge sets (GDSR: mesh edges and cross-layer edges;
 * HOOD: mesh and body edges) and K processor steps:
 *
 *   encode   h_i = MLP_v(v_i),   e^s_ij = MLP_e^s(u^s_ij)             (latent L)
 *   process  e^s_ij += MLP^(k,s)_e([e^s_ij, h_i, h_j])   (i receiver, j sender)
 *            h_i    += MLP^(k)_v([h_i, sum_j e^0_ij, ..., sum_j e^(S-1)_ij])
 *   decode   y_i = MLP_d(h_i)
 *
 * Sums run over the edges received by i (zero for a node with none), the
 * processor weights are not shared between steps, and every MLP but the
 * decoder ends in a LayerNorm when layer_norm is set (MeshGraphNets). */
enum { CR_MPNN_MAX_EDGE_SETS = 4 };

typedef struct cr_mpnn_def {
    int node_in;                        /* node input features; must be set */
    int edge_sets;                      /* S, 1..CR_MPNN_MAX_EDGE_SETS (default 1) */
    int edge_in[CR_MPNN_MAX_EDGE_SETS]; /* input features per edge set; must be set */
    int node_out;                       /* decoded features per node; must be set */
    int latent;                         /* L (default 128: HOOD, EPNet, GDSR) */
    int steps;                          /* K >= 0 (default 3, EPNet's; GDSR 6, HOOD 15) */
    int hidden_layers;                  /* hidden layers of width L per MLP, 0..15 (default 2) */
    cr_act act;                         /* hidden activation (default CR_ACT_RELU) */
    int layer_norm;                     /* 1: LayerNorm ends every MLP but the decoder (default) */
    uint32_t cookie;                    /* set by cr_mpnn_default_def */
} cr_mpnn_def;

/* Parameters, each MLP named as nn_layers' cr_mlp ("<mlp>.0.weight", ...)
 * with its LayerNorm at "<mlp>.ln.weight" / ".ln.bias", where <mlp> is
 * <prefix>.encoder.node, <prefix>.encoder.edge<s>, <prefix>.processor.<k>.edge<s>,
 * <prefix>.processor.<k>.node or <prefix>.decoder. */
typedef struct cr_mpnn cr_mpnn;

cr_mpnn_def cr_mpnn_default_def(void);
cr_status cr_mpnn_create(const cr_mpnn_def *def, cr_nn_params *params, const char *prefix,
                         cr_rng *rng, cr_mpnn **out, cr_error *err);
void cr_mpnn_destroy(cr_mpnn *net); /* NULL is a no-op; the parameters stay in the store */
/* x (N, node_in); graphs[s] (nodes N) and edge_x[s] (E_s, edge_in[s]) for
 * each of the S edge sets (edge_x[s] may be NULL when E_s is 0). Returns
 * (N, node_out); *latent (may be NULL) gets the processed h (N,L). */
cr_tensor *cr_mpnn_forward(cr_nn_ctx *ctx, const cr_mpnn *net, cr_tensor *x,
                           const cr_nn_graph *graphs, cr_tensor *const *edge_x, cr_tensor **latent);

#ifdef __cplusplus
}
#endif
#endif
