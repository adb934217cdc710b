/* layer_rnn.c: GRU and LSTM cells in PyTorch's gate layout, their runners over
 * T steps, and SwinGar's graph LSTM ("LSTM-GAT-LN", eq. 6 of Zhang et al.,
 * "SwinGar", paper 002) whose input-to-state and state-to-state transforms
 * are GAT-LN layers (layer_gat.c).
 *
 * Shapes: B batch rows (or N graph nodes), IN input features, H hidden
 * features, T steps.
 *
 * LSTM (torch.nn.LSTMCell; Hochreiter & Schmidhuber 1997, with a forget gate),
 * gates stacked [i, f, g, o] along the 4H axis of the weights:
 *   z = x W_ih^T + b_ih + h W_hh^T + b_hh                      (B,4H)
 *   i, f, o = sigmoid(z_i), sigmoid(z_f), sigmoid(z_o);  g = tanh(z_g)
 *   c' = f c + i g;   h' = o tanh(c')
 * GRU (torch.nn.GRUCell; Cho et al. 2014), gates [r, z, n]:
 *   r = sigmoid(x_r + h_r);  z = sigmoid(x_z + h_z)  (x_* = x W_i*^T + b_i*, ...)
 *   n = tanh(x_n + r (h W_hn^T + b_hn));   h' = (1 - z) n + z h
 * Runners project all T inputs with one GEMM, then step through time; the
 * tape records every step, so backward is backpropagation through time.
 * With the context's gradient off the gates of every step run in the
 * backend's forward-only pass (lstm_gates_infer, src/nn/cpu/cpu_rnn.c).
 *
 * Leaves out: stacked layers, bidirectional runs, dropout and projections
 * (torch.nn.LSTM's proj_size); chain runners for depth.
 */
#include "crease/nn_graph.h"

#include "nn/tape.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum {
    RNN_COOKIE = 0x726e6e31u,   /* "rnn1" */
    GLSTM_COOKIE = 0x676c7331u, /* "gls1" */
    LSTM_GATES = 4,
    GRU_GATES = 3,
};

cr_rnn_def cr_rnn_default_def(void) {
    cr_rnn_def d;
    memset(&d, 0, sizeof d);
    d.input = 0; /* must be set */
    d.hidden = 128;
    d.bias = 1;
    d.cookie = RNN_COOKIE;
    return d;
}

/* Register prefix.leaf ("leaf" alone for an empty prefix). */
static cr_status add_param(cr_nn_params *P, const char *prefix, const char *leaf, int ndim,
                           const int64_t *shape, cr_tensor **out, cr_error *err) {
    char name[256];
    int n = prefix && prefix[0] ? snprintf(name, sizeof name, "%s.%s", prefix, leaf)
                                : snprintf(name, sizeof name, "%s", leaf);
    if (n < 0 || (size_t)n >= sizeof name)
        return CR_FAIL(err, CR_ERR_INVALID, "parameter name too long: prefix \"%s\"", prefix);
    return cr_nn_params_add(P, name, ndim, shape, out, err);
}

static cr_status cell_create(const cr_rnn_def *def, int gates, const char *what, cr_nn_params *P,
                             const char *prefix, cr_rng *rng, cr_rnn_cell *out, cr_error *err) {
    CR_ASSERT(def && P && rng && out && def->cookie == RNN_COOKIE);
    memset(out, 0, sizeof *out);
    if (def->input < 1 || def->hidden < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: input (%d) and hidden (%d) must be >= 1", what,
                       def->input, def->hidden);
    int64_t GH = (int64_t)gates * def->hidden;
    cr_rnn_cell c = {.input = def->input, .hidden = def->hidden, .gates = gates};
    CR_TRY(add_param(P, prefix, "weight_ih", 2, (int64_t[]){GH, def->input}, &c.weight_ih, err));
    CR_TRY(add_param(P, prefix, "weight_hh", 2, (int64_t[]){GH, def->hidden}, &c.weight_hh, err));
    if (def->bias) {
        CR_TRY(add_param(P, prefix, "bias_ih", 1, (int64_t[]){GH}, &c.bias_ih, err));
        CR_TRY(add_param(P, prefix, "bias_hh", 1, (int64_t[]){GH}, &c.bias_hh, err));
    }
    /* PyTorch's reset_parameters: everything U(-1/sqrt(H), 1/sqrt(H)). */
    float k = 1.0f / sqrtf((float)def->hidden);
    cr_tensor *all[4] = {c.weight_ih, c.weight_hh, c.bias_ih, c.bias_hh};
    for (int i = 0; i < 4; i++)
        if (all[i]) cr_nn_fill_uniform(all[i], rng, -k, k);
    *out = c;
    return CR_OK;
}

cr_status cr_lstm_cell_create(const cr_rnn_def *def, cr_nn_params *params, const char *prefix,
                              cr_rng *rng, cr_rnn_cell *out, cr_error *err) {
    return cell_create(def, LSTM_GATES, "lstm", params, prefix, rng, out, err);
}

cr_status cr_gru_cell_create(const cr_rnn_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_rnn_cell *out, cr_error *err) {
    return cell_create(def, GRU_GATES, "gru", params, prefix, rng, out, err);
}

/* 1 when t is (rows, cols); else a context error naming `what`. NULL is
 * allowed (a zero state) when `optional`. */
static int check_2d(cr_nn_ctx *ctx, const char *op, const char *what, const cr_tensor *t,
                    int64_t rows, int64_t cols, int optional) {
    if (!t) {
        if (optional) return 1;
        NN_FAIL(ctx, CR_ERR_INVALID, "%s: %s is NULL", op, what);
        return 0;
    }
    if (t->ndim == 2 && t->shape[0] == rows && t->shape[1] == cols) return 1;
    char s[64];
    NN_FAIL(ctx, CR_ERR_SHAPE, "%s: %s: expected (%lld,%lld), got %s", op, what, (long long)rows,
            (long long)cols, cr_nn_shape_str(t, s, sizeof s));
    return 0;
}

static cr_tensor *zero_state(cr_nn_ctx *ctx, cr_tensor *s, int64_t rows, int64_t cols) {
    return s ? s : cr_nn_zeros(ctx, 2, (int64_t[]){rows, cols});
}

/* Gates [i, f, g, o] of z (B,4H) applied to the cell state c (B,H); returns
 * h' and sets *c_out. Peephole terms (SwinGar eq. 6) are added when pw is
 * given: pw[0..2] (H) weight c for the i, f and o gates. */
static cr_tensor *lstm_gates(cr_nn_ctx *ctx, cr_tensor *z, cr_tensor *c, int64_t H,
                             cr_tensor *const *pw, cr_tensor **c_out) {
    cr_tensor *zi = cr_nn_slice(ctx, z, 1, 0, H);
    cr_tensor *zf = cr_nn_slice(ctx, z, 1, H, H);
    cr_tensor *zg = cr_nn_slice(ctx, z, 1, 2 * H, H);
    cr_tensor *zo = cr_nn_slice(ctx, z, 1, 3 * H, H);
    if (pw) {
        zi = cr_nn_add(ctx, zi, cr_nn_mul(ctx, c, pw[0]));
        zf = cr_nn_add(ctx, zf, cr_nn_mul(ctx, c, pw[1]));
        zo = cr_nn_add(ctx, zo, cr_nn_mul(ctx, c, pw[2]));
    }
    cr_tensor *i = cr_nn_sigmoid(ctx, zi), *f = cr_nn_sigmoid(ctx, zf);
    cr_tensor *g = cr_nn_tanh(ctx, zg), *o = cr_nn_sigmoid(ctx, zo);
    cr_tensor *c1 = cr_nn_add(ctx, cr_nn_mul(ctx, f, c), cr_nn_mul(ctx, i, g));
    *c_out = c1;
    return cr_nn_mul(ctx, o, cr_nn_tanh(ctx, c1));
}

/* Inference (the context's gradient off): the gates of z = zx + zh in the
 * backend's one forward-only pass (cpu_rnn.c); zh and c may be NULL (zero).
 * Same values as lstm_gates within float rounding (tests/test_nn_graph.c). */
static cr_tensor *lstm_gates_infer(cr_nn_ctx *ctx, cr_tensor *zx, cr_tensor *zh, cr_tensor *c,
                                   int64_t H, cr_tensor *const *pw, cr_tensor **c_out) {
    *c_out = NULL;
    if (!zx || ctx->err.status != CR_OK) return NULL;
    int64_t B = zx->shape[0];
    cr_tensor *h = cr_nn_new(ctx, 2, (int64_t[]){B, H});
    cr_tensor *c1 = cr_nn_new(ctx, 2, (int64_t[]){B, H});
    float *z = cr_nn_scratch(ctx, "lstm", (size_t)(B * 4 * H) * sizeof(float));
    if (!h || !c1 || !z) return NULL;
    nn_lstm_gates_args a = {
        .B = B,
        .H = H,
        .zx = zx->data,
        .zh = zh ? zh->data : NULL,
        .c = c ? c->data : NULL,
        .pw = {pw ? pw[0]->data : NULL, pw ? pw[1]->data : NULL, pw ? pw[2]->data : NULL},
        .z = z,
        .h = h->data,
        .c_out = c1->data};
    ctx->be->lstm_gates_forward(&a);
    *c_out = c1;
    return h;
}

/* One LSTM step from the input projection xi = x W_ih^T + b_ih (B,4H). */
static cr_tensor *lstm_step(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *xi, cr_tensor *h,
                            cr_tensor *c, cr_tensor **c_out) {
    if (!ctx->grad_enabled)
        return lstm_gates_infer(ctx, xi, cr_nn_linear(ctx, h, cell->weight_hh, cell->bias_hh), c,
                                cell->hidden, NULL, c_out);
    cr_tensor *z = cr_nn_add(ctx, xi, cr_nn_linear(ctx, h, cell->weight_hh, cell->bias_hh));
    return lstm_gates(ctx, z, c, cell->hidden, NULL, c_out);
}

/* One GRU step from the input projection xi (B,3H). */
static cr_tensor *gru_step(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *xi, cr_tensor *h) {
    int64_t H = cell->hidden;
    cr_tensor *gh = cr_nn_linear(ctx, h, cell->weight_hh, cell->bias_hh);
    cr_tensor *rz = cr_nn_sigmoid(
        ctx, cr_nn_add(ctx, cr_nn_slice(ctx, xi, 1, 0, 2 * H), cr_nn_slice(ctx, gh, 1, 0, 2 * H)));
    cr_tensor *r = cr_nn_slice(ctx, rz, 1, 0, H);
    cr_tensor *z = cr_nn_slice(ctx, rz, 1, H, H);
    cr_tensor *n = cr_nn_tanh(ctx, cr_nn_add(ctx, cr_nn_slice(ctx, xi, 1, 2 * H, H),
                                             cr_nn_mul(ctx, r, cr_nn_slice(ctx, gh, 1, 2 * H, H))));
    return cr_nn_add(ctx, n, cr_nn_mul(ctx, z, cr_nn_sub(ctx, h, n))); /* (1-z) n + z h */
}

cr_tensor *cr_lstm_cell_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h,
                                cr_tensor *c, cr_tensor **c_out) {
    CR_ASSERT(cell && cell->gates == LSTM_GATES && c_out);
    *c_out = NULL;
    if (!cr_nn_begin(ctx, "lstm_cell", 1, &x)) return NULL;
    int64_t B = x->shape[0], H = cell->hidden;
    if (!check_2d(ctx, "lstm_cell", "x", x, B, cell->input, 0) ||
        !check_2d(ctx, "lstm_cell", "h", h, B, H, 1) ||
        !check_2d(ctx, "lstm_cell", "c", c, B, H, 1))
        return NULL;
    cr_tensor *xi = cr_nn_linear(ctx, x, cell->weight_ih, cell->bias_ih);
    return lstm_step(ctx, cell, xi, zero_state(ctx, h, B, H), zero_state(ctx, c, B, H), c_out);
}

cr_tensor *cr_gru_cell_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x,
                               cr_tensor *h) {
    CR_ASSERT(cell && cell->gates == GRU_GATES);
    if (!cr_nn_begin(ctx, "gru_cell", 1, &x)) return NULL;
    int64_t B = x->shape[0];
    if (!check_2d(ctx, "gru_cell", "x", x, B, cell->input, 0) ||
        !check_2d(ctx, "gru_cell", "h", h, B, cell->hidden, 1))
        return NULL;
    cr_tensor *xi = cr_nn_linear(ctx, x, cell->weight_ih, cell->bias_ih);
    return gru_step(ctx, cell, xi, zero_state(ctx, h, B, cell->hidden));
}

/* Shared runner: x (T,B,IN) -> (T,B,H); c and *c_last only for the LSTM. */
static cr_tensor *run_sequence(cr_nn_ctx *ctx, const char *op, const cr_rnn_cell *cell,
                               cr_tensor *x, cr_tensor *h, cr_tensor *c, cr_tensor **h_last,
                               cr_tensor **c_last) {
    if (h_last) *h_last = NULL;
    if (c_last) *c_last = NULL;
    if (!cr_nn_begin(ctx, op, 1, &x)) return NULL;
    if (x->ndim != 3 || x->shape[2] != cell->input || x->shape[0] < 1) {
        char s[64];
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: x: expected (T,B,%d) with T >= 1, got %s", op, cell->input,
                cr_nn_shape_str(x, s, sizeof s));
        return NULL;
    }
    int64_t T = x->shape[0], B = x->shape[1], H = cell->hidden, GH = cell->gates * H;
    int lstm = cell->gates == LSTM_GATES;
    if (!check_2d(ctx, op, "h0", h, B, H, 1) || (lstm && !check_2d(ctx, op, "c0", c, B, H, 1)))
        return NULL;
    h = zero_state(ctx, h, B, H);
    if (lstm) c = zero_state(ctx, c, B, H);
    /* All input projections in one GEMM; per-step rows are views. */
    cr_tensor *xi = cr_nn_reshape(ctx, cr_nn_linear(ctx, x, cell->weight_ih, cell->bias_ih), 2,
                                  (int64_t[]){T * B, GH});
    cr_tensor **hs = cr_nn_scratch(ctx, op, (size_t)T * sizeof *hs);
    if (!xi || !hs) return NULL;
    for (int64_t t = 0; t < T; t++) {
        cr_tensor *xt = cr_nn_slice(ctx, xi, 0, t * B, B);
        h = lstm ? lstm_step(ctx, cell, xt, h, c, &c) : gru_step(ctx, cell, xt, h);
        hs[t] = cr_nn_reshape(ctx, h, 3, (int64_t[]){1, B, H});
        if (!hs[t]) return NULL;
    }
    cr_tensor *all = cr_nn_concat(ctx, (int)T, hs, 0);
    if (!all) return NULL;
    if (h_last) *h_last = h;
    if (c_last) *c_last = c;
    return all;
}

cr_tensor *cr_lstm_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h0,
                           cr_tensor *c0, cr_tensor **h_last, cr_tensor **c_last) {
    CR_ASSERT(cell && cell->gates == LSTM_GATES);
    return run_sequence(ctx, "lstm", cell, x, h0, c0, h_last, c_last);
}

cr_tensor *cr_gru_forward(cr_nn_ctx *ctx, const cr_rnn_cell *cell, cr_tensor *x, cr_tensor *h0,
                          cr_tensor **h_last) {
    CR_ASSERT(cell && cell->gates == GRU_GATES);
    return run_sequence(ctx, "gru", cell, x, h0, NULL, h_last, NULL);
}

/* ----------------------------------------------------------- graph LSTM -- */

cr_gat_lstm_def cr_gat_lstm_default_def(void) {
    cr_gat_lstm_def d;
    memset(&d, 0, sizeof d);
    d.hidden = 64;
    d.gat = cr_gat_default_def();
    d.peephole = 1;
    d.cookie = GLSTM_COOKIE;
    return d;
}

cr_status cr_gat_lstm_create(const cr_gat_lstm_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_gat_lstm *out, cr_error *err) {
    CR_ASSERT(def && params && rng && out && def->cookie == GLSTM_COOKIE);
    memset(out, 0, sizeof *out);
    int H = def->hidden, heads = def->gat.heads;
    if (def->input < 1 || H < 1 || heads < 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gat_lstm: input (%d), hidden (%d), heads (%d) "
                       "must be >= 1",
                       def->input, H, heads);
    if (def->gat.concat && (LSTM_GATES * H) % heads != 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gat_lstm: 4 hidden (%d) is not a multiple of the "
                       "%d concatenated heads",
                       LSTM_GATES * H, heads);
    cr_gat_lstm c = {.def = *def};
    cr_gat_def gd = def->gat;
    gd.out = gd.concat ? LSTM_GATES * H / heads : LSTM_GATES * H;
    gd.act = CR_ACT_NONE;
    char name[256];
    const char *p = prefix && prefix[0] ? prefix : NULL;
    gd.input = def->input;
    gd.bias = 1;
    snprintf(name, sizeof name, "%s%sx", p ? p : "", p ? "." : "");
    CR_TRY(cr_gat_create(&gd, params, name, rng, &c.gx, err));
    gd.input = H;
    gd.bias = 0; /* one bias per gate is enough; GAT_x carries it */
    snprintf(name, sizeof name, "%s%sh", p ? p : "", p ? "." : "");
    CR_TRY(cr_gat_create(&gd, params, name, rng, &c.gh, err));
    if (def->peephole) {
        static const char *const leaf[3] = {"w_ci", "w_cf", "w_co"};
        float k = 1.0f / sqrtf((float)H);
        for (int i = 0; i < 3; i++) {
            CR_TRY(add_param(params, prefix, leaf[i], 1, (int64_t[]){H}, &c.peep[i], err));
            cr_nn_fill_uniform(c.peep[i], rng, -k, k);
        }
    }
    *out = c;
    return CR_OK;
}

/* One step from the input transform zx = GAT_x(x) (N,4H). */
static cr_tensor *gat_lstm_step(cr_nn_ctx *ctx, const cr_gat_lstm *cell, const cr_nn_graph *g,
                                cr_tensor *zx, cr_tensor *h, cr_tensor *c, cr_tensor **c_out) {
    int64_t N = g->nodes, H = cell->def.hidden;
    /* A zero state gives GAT_h(0) = 0 (no bias, zero features, zero scores). */
    if (!ctx->grad_enabled)
        return lstm_gates_infer(ctx, zx, h ? cr_gat_forward(ctx, &cell->gh, h, g, NULL) : NULL, c,
                                H, cell->def.peephole ? cell->peep : NULL, c_out);
    cr_tensor *z = h ? cr_nn_add(ctx, zx, cr_gat_forward(ctx, &cell->gh, h, g, NULL)) : zx;
    return lstm_gates(ctx, z, zero_state(ctx, c, N, H), H, cell->def.peephole ? cell->peep : NULL,
                      c_out);
}

cr_tensor *cr_gat_lstm_cell_forward(cr_nn_ctx *ctx, const cr_gat_lstm *cell, cr_tensor *x,
                                    const cr_nn_graph *g, cr_tensor *h, cr_tensor *c,
                                    cr_tensor **c_out) {
    CR_ASSERT(cell && g && c_out);
    *c_out = NULL;
    if (!cr_nn_begin(ctx, "gat_lstm_cell", 1, &x)) return NULL;
    int64_t H = cell->def.hidden;
    if (!check_2d(ctx, "gat_lstm_cell", "h", h, g->nodes, H, 1) ||
        !check_2d(ctx, "gat_lstm_cell", "c", c, g->nodes, H, 1))
        return NULL;
    cr_tensor *zx = cr_gat_forward(ctx, &cell->gx, x, g, NULL);
    return gat_lstm_step(ctx, cell, g, zx, h, c, c_out);
}

cr_tensor *cr_gat_lstm_forward(cr_nn_ctx *ctx, const cr_gat_lstm *cell, cr_tensor *x,
                               const cr_nn_graph *g, cr_tensor *h0, cr_tensor *c0,
                               cr_tensor **h_last, cr_tensor **c_last) {
    CR_ASSERT(cell && g);
    if (h_last) *h_last = NULL;
    if (c_last) *c_last = NULL;
    const char *op = "gat_lstm";
    if (!cr_nn_begin(ctx, op, 1, &x)) return NULL;
    int64_t N = g->nodes, H = cell->def.hidden;
    if (x->ndim != 3 || x->shape[0] < 1 || x->shape[1] != N || x->shape[2] != cell->def.input) {
        char s[64];
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: x: expected (T,%lld,%d) with T >= 1, got %s", op,
                (long long)N, cell->def.input, cr_nn_shape_str(x, s, sizeof s));
        return NULL;
    }
    if (!check_2d(ctx, op, "h0", h0, N, H, 1) || !check_2d(ctx, op, "c0", c0, N, H, 1)) return NULL;
    int64_t T = x->shape[0];
    cr_tensor *rows = cr_nn_reshape(ctx, x, 2, (int64_t[]){T * N, cell->def.input});
    cr_tensor **hs = cr_nn_scratch(ctx, op, (size_t)T * sizeof *hs);
    if (!rows || !hs) return NULL;
    cr_tensor *h = h0, *c = c0;
    for (int64_t t = 0; t < T; t++) {
        cr_tensor *zx =
            cr_gat_forward(ctx, &cell->gx, cr_nn_slice(ctx, rows, 0, t * N, N), g, NULL);
        h = gat_lstm_step(ctx, cell, g, zx, h, c, &c);
        hs[t] = cr_nn_reshape(ctx, h, 3, (int64_t[]){1, N, H});
        if (!hs[t]) return NULL;
    }
    cr_tensor *all = cr_nn_concat(ctx, (int)T, hs, 0);
    if (!all) return NULL;
    if (h_last) *h_last = h;
    if (c_last) *c_last = c;
    return all;
}
