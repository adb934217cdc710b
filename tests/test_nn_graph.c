/* test_nn_graph.c: recurrent cells and graph layers (nn_graph.h).
 *
 * LSTM and GRU cells against steps written out with plain loops; runners
 * against repeated cell calls; central-difference gradient checks (step
 * 1e-3, tolerance 1e-2 relative, nn_gradcheck.h) of every layer with respect
 * to its inputs and all its parameters; GAT-LN against a loop reference of
 * eq. 4; permutation equivariance of GAT and MPNN; attention weights summing
 * to one; the bound and scale invariance the Lipschitz normalisation gives;
 * parameter names and error reporting.
 *
 * The graph is a 6-node ring plus one chord, both directions: 14 edges.
 */
#include "crease/nn_graph.h"
#include "nn/cpu/cpu.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { GN = 6, GE = 14 };
static const int32_t g_snd[GE] = {0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 0, 0, 3};
static const int32_t g_rcv[GE] = {1, 0, 2, 1, 3, 2, 4, 3, 5, 4, 0, 5, 3, 0};

static cr_nn_graph test_graph(void) {
    return (cr_nn_graph){.nodes = GN, .edges = GE, .senders = g_snd, .receivers = g_rcv};
}

/* Every parameter U(-r, r), so biases and norms are exercised away from init. */
static void randomise(cr_nn_params *P, float r, uint64_t seed) {
    cr_rng rng = cr_rng_make(seed, 3);
    for (int i = 0; i < cr_nn_params_count(P); i++)
        cr_nn_fill_uniform(cr_nn_params_at(P, i, NULL), &rng, -r, r);
}

static double sigm(double z) {
    return 1.0 / (1.0 + exp(-z));
}

/* --------------------------------------------------------- recurrent -- */

/* W x + b for row-major W (rows, cols), in double. */
static double affine(const float *W, const float *b, int row, int cols, const float *x) {
    double s = b ? b[row] : 0.0;
    for (int k = 0; k < cols; k++)
        s += (double)W[row * cols + k] * x[k];
    return s;
}

/* One LSTM and one GRU step against torch's formulas written out. */
CR_TEST(nn_graph, cells_match_hand_steps) {
    enum { B = 2, IN = 3, H = 2 };
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_rnn_def d = cr_rnn_default_def();
    d.input = IN;
    d.hidden = H;
    cr_rng rng = cr_rng_make(5, 0);
    cr_rnn_cell lstm, gru;
    CR_CHECK_OK(cr_lstm_cell_create(&d, P, "enc", &rng, &lstm, &err), &err);
    CR_CHECK_OK(cr_gru_cell_create(&d, P, "", &rng, &gru, &err), &err);
    cr_tensor *w = cr_nn_params_find(P, "enc.weight_ih");
    CR_REQUIRE(w && w->shape[0] == 4 * H && w->shape[1] == IN && lstm.weight_ih == w);
    CR_CHECK(cr_nn_params_find(P, "enc.bias_hh") != NULL);
    CR_REQUIRE(cr_nn_params_find(P, "weight_hh") == gru.weight_hh &&
               gru.weight_hh->shape[0] == 3 * H);
    randomise(P, 0.8f, 9);
    float x[B * IN], h[B * H], c[B * H];
    nn_gradcheck_fill(x, B * IN, -1, 1, 0, 1);
    nn_gradcheck_fill(h, B * H, -1, 1, 0, 2);
    nn_gradcheck_fill(c, B * H, -1, 1, 0, 3);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){B, IN}, x);
    cr_tensor *ht = cr_nn_from(ctx, 2, (int64_t[]){B, H}, h);
    cr_tensor *c1 = NULL;
    cr_tensor *h1 =
        cr_lstm_cell_forward(ctx, &lstm, xt, ht, cr_nn_from(ctx, 2, (int64_t[]){B, H}, c), &c1);
    cr_tensor *g1 = cr_gru_cell_forward(ctx, &gru, xt, ht);
    CR_REQUIRE(h1 && c1 && g1);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < H; j++) {
            const float *xb = x + b * IN, *hb = h + b * H;
            double z[4]; /* torch order i, f, g, o */
            for (int q = 0; q < 4; q++)
                z[q] = affine(lstm.weight_ih->data, lstm.bias_ih->data, q * H + j, IN, xb) +
                       affine(lstm.weight_hh->data, lstm.bias_hh->data, q * H + j, H, hb);
            double cn = sigm(z[1]) * c[b * H + j] + sigm(z[0]) * tanh(z[2]);
            CR_CHECK_NEAR(c1->data[b * H + j], cn, 1e-5);
            CR_CHECK_NEAR(h1->data[b * H + j], sigm(z[3]) * tanh(cn), 1e-5);
            double gi[3], gh[3]; /* torch order r, z, n */
            for (int q = 0; q < 3; q++) {
                gi[q] = affine(gru.weight_ih->data, gru.bias_ih->data, q * H + j, IN, xb);
                gh[q] = affine(gru.weight_hh->data, gru.bias_hh->data, q * H + j, H, hb);
            }
            double r = sigm(gi[0] + gh[0]), u = sigm(gi[1] + gh[1]);
            double n = tanh(gi[2] + r * gh[2]);
            CR_CHECK_NEAR(g1->data[b * H + j], (1 - u) * n + u * hb[j], 1e-5);
        }
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
}

typedef struct rnn_case {
    cr_rnn_cell cell;
    int lstm, T, B;
} rnn_case;

/* One cell step: in = x, h, c (LSTM) -> [h'; c'] or h'. */
static cr_tensor *build_cell(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    rnn_case *k = user;
    if (!k->lstm) return cr_gru_cell_forward(ctx, &k->cell, in[0], in[1]);
    cr_tensor *out[2] = {NULL, NULL};
    out[0] = cr_lstm_cell_forward(ctx, &k->cell, in[0], in[1], in[2], &out[1]);
    return cr_nn_concat(ctx, 2, out, 0);
}

/* A sequence: in = x (T,B,IN), h0, c0 -> all hidden states and the last c. */
static cr_tensor *build_seq(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    rnn_case *k = user;
    int64_t H = k->cell.hidden;
    cr_tensor *hl = NULL, *cl = NULL;
    cr_tensor *all = k->lstm ? cr_lstm_forward(ctx, &k->cell, in[0], in[1], in[2], &hl, &cl)
                             : cr_gru_forward(ctx, &k->cell, in[0], in[1], &hl);
    cr_tensor *parts[2] = {cr_nn_reshape(ctx, all, 2, (int64_t[]){k->T * k->B, H}),
                           k->lstm ? cl : hl};
    return cr_nn_concat(ctx, 2, parts, 0);
}

static void rnn_gradcheck(int lstm, int seq) {
    enum { T = 3, B = 2, IN = 3, H = 4 };
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_rnn_def d = cr_rnn_default_def();
    d.input = IN;
    d.hidden = H;
    cr_rng rng = cr_rng_make(7, 0);
    rnn_case k = {.lstm = lstm, .T = T, .B = B};
    CR_CHECK_OK(lstm ? cr_lstm_cell_create(&d, P, "rnn", &rng, &k.cell, &err)
                     : cr_gru_cell_create(&d, P, "rnn", &rng, &k.cell, &err),
                &err);
    randomise(P, 0.6f, 11);
    float x[T * B * IN], h[B * H], c[B * H];
    nn_gradcheck_fill(x, T * B * IN, -1, 1, 0, 21);
    nn_gradcheck_fill(h, B * H, -1, 1, 0, 22);
    nn_gradcheck_fill(c, B * H, -1, 1, 0, 23);
    nn_gradcheck_input in[3] = {seq ? nn_gradcheck_in(3, (int64_t[]){T, B, IN}, x)
                                    : nn_gradcheck_in(2, (int64_t[]){B, IN}, x),
                                nn_gradcheck_in(2, (int64_t[]){B, H}, h),
                                nn_gradcheck_in(2, (int64_t[]){B, H}, c)};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = lstm ? (seq ? "lstm sequence" : "lstm cell") : (seq ? "gru sequence" : "gru cell");
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, lstm ? 3 : 2, in, P, seq ? build_seq : build_cell, &k, &res) == 0);
    CR_CHECK(res.checked > 100);
    cr_nn_params_destroy(P);
}

CR_TEST(nn_graph, lstm_cell_gradcheck) {
    rnn_gradcheck(1, 0);
}

CR_TEST(nn_graph, gru_cell_gradcheck) {
    rnn_gradcheck(0, 0);
}

CR_TEST(nn_graph, lstm_sequence_gradcheck) {
    rnn_gradcheck(1, 1);
}

CR_TEST(nn_graph, gru_sequence_gradcheck) {
    rnn_gradcheck(0, 1);
}

CR_TEST(nn_graph, runner_equals_repeated_cells) {
    enum { T = 4, B = 3, IN = 2, H = 5 };
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_rnn_def d = cr_rnn_default_def();
    d.input = IN;
    d.hidden = H;
    cr_rng rng = cr_rng_make(8, 0);
    cr_rnn_cell lstm, gru;
    CR_CHECK_OK(cr_lstm_cell_create(&d, P, "a", &rng, &lstm, &err), &err);
    CR_CHECK_OK(cr_gru_cell_create(&d, P, "b", &rng, &gru, &err), &err);
    float x[T * B * IN];
    nn_gradcheck_fill(x, T * B * IN, -2, 2, 0, 31);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(4 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *xs = cr_nn_from(ctx, 3, (int64_t[]){T, B, IN}, x);
    cr_tensor *hl = NULL, *cl = NULL, *gl = NULL;
    cr_tensor *all = cr_lstm_forward(ctx, &lstm, xs, NULL, NULL, &hl, &cl);
    cr_tensor *gall = cr_gru_forward(ctx, &gru, xs, NULL, &gl);
    CR_REQUIRE(all && hl && cl && gall && gl);
    CR_CHECK(all->ndim == 3 && all->shape[0] == T && all->shape[1] == B && all->shape[2] == H);
    cr_tensor *h = NULL, *c = NULL, *g = NULL;
    for (int t = 0; t < T; t++) {
        cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){B, IN}, x + t * B * IN);
        h = cr_lstm_cell_forward(ctx, &lstm, xt, h, c, &c);
        g = cr_gru_cell_forward(ctx, &gru, xt, g);
        CR_REQUIRE(h && g);
        for (int i = 0; i < B * H; i++) {
            CR_CHECK_NEAR(all->data[t * B * H + i], h->data[i], 1e-6);
            CR_CHECK_NEAR(gall->data[t * B * H + i], g->data[i], 1e-6);
        }
    }
    for (int i = 0; i < B * H; i++) {
        CR_CHECK_NEAR(hl->data[i], h->data[i], 1e-6);
        CR_CHECK_NEAR(cl->data[i], c->data[i], 1e-6);
        CR_CHECK_NEAR(gl->data[i], g->data[i], 1e-6);
    }
    /* Shape errors are reported through the context. */
    cr_nn_ctx_reset(ctx);
    cr_tensor *bad = cr_nn_zeros(ctx, 3, (int64_t[]){T, B, IN + 1});
    CR_CHECK(cr_lstm_forward(ctx, &lstm, bad, NULL, NULL, NULL, NULL) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE && strstr(err.msg, "lstm") != NULL);
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
}

/* -------------------------------------------------------------- GAT-LN -- */

typedef struct gat_case {
    cr_gat gat;
    cr_nn_graph g;
} gat_case;

static cr_tensor *build_gat(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    gat_case *k = user;
    return cr_gat_forward(ctx, &k->gat, in[0], &k->g, NULL);
}

static cr_gat_def small_gat_def(cr_gat_norm norm, int concat) {
    cr_gat_def d = cr_gat_default_def();
    d.input = 4;
    d.out = 3;
    d.heads = 2;
    d.concat = concat;
    d.norm = norm;
    d.act = CR_ACT_TANH;
    return d;
}

static int make_gat(const cr_gat_def *d, cr_nn_params **P, gat_case *k, uint64_t seed) {
    cr_error err = {0};
    if (cr_nn_params_create(P, &err) != CR_OK) return 0;
    cr_rng rng = cr_rng_make(seed, 0);
    if (cr_gat_create(d, *P, "gat", &rng, &k->gat, &err) != CR_OK) {
        fprintf(stderr, "    %s\n", err.msg);
        return 0;
    }
    randomise(*P, 0.7f, seed + 1);
    k->g = test_graph();
    return 1;
}

CR_TEST(nn_graph, gat_gradcheck) {
    const cr_gat_norm norms[3] = {CR_GAT_NORM_NONE, CR_GAT_NORM_GLOBAL, CR_GAT_NORM_RECEIVER};
    for (int m = 0; m < 3; m++)
        for (int concat = 0; concat < 2; concat++) {
            cr_gat_def d = small_gat_def(norms[m], concat);
            cr_nn_params *P = NULL;
            gat_case k;
            CR_REQUIRE(make_gat(&d, &P, &k, 40 + (uint64_t)m));
            float x[GN * 4];
            nn_gradcheck_fill(x, GN * 4, -1, 1, 0, 50 + (uint64_t)m);
            nn_gradcheck_input in = nn_gradcheck_in(2, (int64_t[]){GN, 4}, x);
            char name[64];
            snprintf(name, sizeof name, "gat norm %d concat %d", m, concat);
            nn_gradcheck_def gd = nn_gradcheck_default_def();
            gd.name = name;
            CR_CHECK(nn_gradcheck(&gd, 1, &in, P, build_gat, &k, NULL) == 0);
            cr_nn_params_destroy(P);
        }
}

/* GAT-LN written out with loops in double, straight from eq. 4 and the
 * reading in layer_gat.c. The test graph has no self loops, so the layer's
 * edges are the given ones followed by one loop per node. */
static void gat_reference(const cr_gat *gat, const float *x, double *out) {
    const cr_gat_def *d = &gat->def;
    enum { EE = GE + GN, MAXH = 4, MAXF = 4, MAXI = 8 };
    int H = d->heads, F = d->out, IN = d->input;
    CR_ASSERT(H <= MAXH && F <= MAXF && IN <= MAXI);
    int snd[EE], rcv[EE];
    for (int e = 0; e < EE; e++) {
        snd[e] = e < GE ? g_snd[e] : e - GE;
        rcv[e] = e < GE ? g_rcv[e] : e - GE;
    }
    const float *W = gat->lin.weight->data, *as = gat->att_src->data, *ad = gat->att_dst->data;
    double p[GN][MAXH][MAXF], ss[GN][MAXH], sd[GN][MAXH], xn[GN], xmax = 0;
    for (int n = 0; n < GN; n++) {
        double q = 0;
        for (int i = 0; i < IN; i++)
            q += (double)x[n * IN + i] * x[n * IN + i];
        xn[n] = sqrt(q);
        xmax = fmax(xmax, xn[n]);
        for (int k = 0; k < H; k++) {
            ss[n][k] = sd[n][k] = 0;
            for (int f = 0; f < F; f++) {
                p[n][k][f] = affine(W, NULL, k * F + f, IN, x + n * IN);
                ss[n][k] += p[n][k][f] * as[k * F + f];
                sd[n][k] += p[n][k][f] * ad[k * F + f];
            }
        }
    }
    for (int i = 0; i < GN * cr_gat_out_dim(d); i++)
        out[i] = 0;
    for (int k = 0; k < H; k++) {
        double u2 = 0, w2 = 0; /* |W_k^T a_dst|^2, |W_k^T a_src|^2 */
        for (int i = 0; i < IN; i++) {
            double u = 0, w = 0;
            for (int f = 0; f < F; f++) {
                u += (double)W[(k * F + f) * IN + i] * ad[k * F + f];
                w += (double)W[(k * F + f) * IN + i] * as[k * F + f];
            }
            u2 += u * u;
            w2 += w * w;
        }
        double lip = sqrt(u2 + w2), g[EE], row[GN] = {0}, near[GN] = {0}, gmax = 0;
        for (int e = 0; e < EE; e++) {
            g[e] = sd[rcv[e]][k] + ss[snd[e]][k];
            row[rcv[e]] += g[e] * g[e];
            near[rcv[e]] = fmax(near[rcv[e]], fmax(xn[snd[e]], xn[rcv[e]]));
        }
        for (int n = 0; n < GN; n++)
            gmax = fmax(gmax, sqrt(row[n]));
        double logit[EE], zmax[GN], zsum[GN];
        for (int n = 0; n < GN; n++)
            zmax[n] = -1e300, zsum[n] = 0;
        for (int e = 0; e < EE; e++) {
            double den = 1;
            if (d->norm == CR_GAT_NORM_GLOBAL) den = fmax(gmax, xmax * lip);
            if (d->norm == CR_GAT_NORM_RECEIVER) den = fmax(sqrt(row[rcv[e]]), near[rcv[e]] * lip);
            double s = d->norm == CR_GAT_NORM_NONE ? g[e] : d->alpha * g[e] / den;
            logit[e] = s > 0 ? s : d->negative_slope * s;
            zmax[rcv[e]] = fmax(zmax[rcv[e]], logit[e]);
        }
        for (int e = 0; e < EE; e++)
            zsum[rcv[e]] += exp(logit[e] - zmax[rcv[e]]);
        for (int e = 0; e < EE; e++) {
            double a = exp(logit[e] - zmax[rcv[e]]) / zsum[rcv[e]];
            for (int f = 0; f < F; f++) {
                int col = d->concat ? k * F + f : f;
                out[rcv[e] * cr_gat_out_dim(d) + col] += a * p[snd[e]][k][f] / (d->concat ? 1 : H);
            }
        }
    }
    for (int i = 0; i < GN * cr_gat_out_dim(d); i++)
        out[i] = tanh(out[i] + (gat->bias ? gat->bias->data[i % cr_gat_out_dim(d)] : 0));
}

CR_TEST(nn_graph, gat_matches_loop_reference) {
    const cr_gat_norm norms[3] = {CR_GAT_NORM_NONE, CR_GAT_NORM_GLOBAL, CR_GAT_NORM_RECEIVER};
    cr_nn_ctx *ctx = nn_gradcheck_ctx(4 << 20);
    CR_REQUIRE(ctx);
    for (int m = 0; m < 3; m++)
        for (int concat = 0; concat < 2; concat++) {
            cr_gat_def d = small_gat_def(norms[m], concat);
            cr_nn_params *P = NULL;
            gat_case k;
            CR_REQUIRE(make_gat(&d, &P, &k, 60 + (uint64_t)m));
            float x[GN * 4];
            nn_gradcheck_fill(x, GN * 4, -1, 1, 0, 70 + (uint64_t)m);
            double ref[GN * 6];
            gat_reference(&k.gat, x, ref);
            cr_nn_ctx_reset(ctx);
            cr_tensor *y =
                cr_gat_forward(ctx, &k.gat, cr_nn_from(ctx, 2, (int64_t[]){GN, 4}, x), &k.g, NULL);
            CR_REQUIRE(y && y->shape[0] == GN && y->shape[1] == cr_gat_out_dim(&d));
            for (int i = 0; i < y->numel; i++)
                CR_CHECK_NEAR(y->data[i], ref[i], 2e-5);
            cr_nn_params_destroy(P);
        }
    cr_nn_ctx_destroy(ctx);
}

/* |a - b| over n floats, checked against tol (1 + |b|); returns the largest. */
static double near_all(const cr_tensor *a, const cr_tensor *b, double tol) {
    double worst = 0.0;
    CR_CHECK(a && b && cr_nn_same_shape(a, b));
    if (!a || !b || !cr_nn_same_shape(a, b)) return INFINITY;
    for (int64_t i = 0; i < a->numel; i++) {
        double e = fabs((double)a->data[i] - b->data[i]);
        worst = e > worst ? e : worst;
        CR_CHECK_NEAR(a->data[i], b->data[i], tol * (1.0 + fabs(b->data[i])));
    }
    return worst;
}

/* A ring of n nodes with chords i -> i + 7, one given self loop (dropped
 * and replaced by the layer's own), node 0 receiving from everyone (a long
 * segment) and the last node from no one (an empty segment without self
 * loops); senders and receivers as arena-free static storage. */
enum { IN_N = 71, IN_E = 4 * IN_N + 1 }; /* node 0: over 64 edges (cpu_gat.c GATHER_DEG) */
static int32_t in_snd[IN_E], in_rcv[IN_E];
static cr_nn_graph infer_graph(void) {
    int64_t e = 0;
    const int32_t pair[4][2] = {{0, 1}, {1, 0}, {0, 7}, {0, -1}}; /* sender, receiver offsets */
    for (int32_t i = 0; i < IN_N; i++)
        for (int q = 0; q < 4; q++) {
            int32_t a = (i + pair[q][0]) % IN_N, b = pair[q][1] < 0 ? 0 : (i + pair[q][1]) % IN_N;
            if (b == IN_N - 1) continue; /* the last node receives nothing but its self loop */
            in_snd[e] = a, in_rcv[e++] = b;
        }
    in_snd[e] = 5, in_rcv[e++] = 5;
    return (cr_nn_graph){.nodes = IN_N, .edges = e, .senders = in_snd, .receivers = in_rcv};
}

/* The forward-only path (gradient off: cpu_gat.c's fused kernel) against
 * the tape's ops (gradient on) on every SIMD path the machine has, every
 * norm, concatenated and averaged heads (projected first and aggregated
 * first, rows narrower and wider than 64), each activation on some path;
 * the widths leave vector tails. */
CR_TEST(nn_graph, gat_inference_matches_tape) {
    const cr_gat_norm norms[3] = {CR_GAT_NORM_NONE, CR_GAT_NORM_GLOBAL, CR_GAT_NORM_RECEIVER};
    cr_nn_ctx *ctx = nn_gradcheck_ctx(16 << 20);
    CR_REQUIRE(ctx);
    const cr_nn_graph g = infer_graph();
    const int prev = cr_nn_cpu_simd();
    double worst = 0.0;
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (int m = 0; m < 3; m++)
            for (int concat = 0; concat < 2; concat++) {
                cr_gat_def d = cr_gat_default_def();
                /* (IN, F): (13, 5) projects first, (80, 90) aggregates first, (150,
                 * 70) projects first over rows wider than 64 with tails */
                const int ins[3] = {13, 80, 150}, outs[3] = {5, 90, 70}, IN = ins[m];
                d.input = IN, d.out = outs[m], d.heads = m == 1 ? 4 : 3, d.concat = concat;
                d.self_loops = m != 2; /* without: the last node's segment is empty */
                d.norm = norms[m];
                /* every activation over the levels: the kernel's and sin, run after it */
                const cr_act acts[7] = {CR_ACT_TANH,       CR_ACT_NONE,    CR_ACT_RELU,
                                        CR_ACT_LEAKY_RELU, CR_ACT_SIGMOID, CR_ACT_SOFTPLUS,
                                        CR_ACT_SIN};
                const float params[7] = {0, 0, 0, 0.1f, 0, 2.0f, 3.0f};
                int ai = (2 * m + concat + 3 * level) % 7;
                d.act = acts[ai], d.act_param = params[ai];
                cr_nn_params *P = NULL;
                gat_case k;
                CR_REQUIRE(make_gat(&d, &P, &k, 90 + (uint64_t)m));
                static float x[IN_N * 150];
                nn_gradcheck_fill(x, IN_N * IN, -1, 1, 0, 91 + (uint64_t)m);
                cr_nn_ctx_reset(ctx);
                cr_nn_ctx_set_grad_enabled(ctx, 1);
                cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){IN_N, IN}, x);
                xt->requires_grad = 1;
                cr_tensor *ref = cr_gat_forward(ctx, &k.gat, xt, &g, NULL);
                cr_nn_ctx_set_grad_enabled(ctx, 0);
                cr_tensor *y = cr_gat_forward(ctx, &k.gat, xt, &g, NULL);
                CR_REQUIRE(ref && y && cr_nn_same_shape(ref, y));
                CR_CHECK(ref->requires_grad && !y->requires_grad);
                double e = near_all(y, ref, 2e-5);
                worst = e > worst ? e : worst;
                /* another graph in the same step, then the first again: the
                 * step's cached edges must follow the graph */
                const cr_nn_graph small = test_graph();
                cr_tensor *xs = cr_nn_from(ctx, 2, (int64_t[]){GN, IN}, x);
                cr_tensor *ys = cr_gat_forward(ctx, &k.gat, xs, &small, NULL);
                cr_tensor *y2 = cr_gat_forward(ctx, &k.gat, xt, &g, NULL);
                cr_nn_ctx_set_grad_enabled(ctx, 1);
                cr_tensor *refs = cr_gat_forward(ctx, &k.gat, xs, &small, NULL);
                CR_REQUIRE(ys && y2 && refs);
                near_all(ys, refs, 2e-5);
                near_all(y2, ref, 2e-5);
                cr_nn_params_destroy(P);
            }
    }
    cr_nn_cpu_set_simd(prev);
    cr_log(CR_LOG_INFO, "gat inference against the tape: max |diff| %.3g", worst);
    cr_nn_ctx_destroy(ctx);
}

/* The LSTM runner and the graph LSTM with the gradient off (cpu_rnn.c's
 * gates, cpu_gat.c's attention) against the tape on every SIMD path:
 * H = 19: a whole vector and a tail; zero and given states, with peepholes. */
CR_TEST(nn_graph, lstm_inference_matches_tape) {
    enum { T = 3, B = 5, IN = 4, H = 19 };
    cr_nn_ctx *ctx = nn_gradcheck_ctx(16 << 20);
    CR_REQUIRE(ctx);
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_rng rng = cr_rng_make(7, 0);
    cr_rnn_def rd = cr_rnn_default_def();
    rd.input = IN, rd.hidden = H;
    cr_rnn_cell lstm;
    CR_CHECK_OK(cr_lstm_cell_create(&rd, P, "lstm", &rng, &lstm, &err), &err);
    cr_gat_lstm_def gd = cr_gat_lstm_default_def();
    gd.input = IN, gd.hidden = H, gd.gat.heads = 2, gd.gat.concat = 0;
    cr_gat_lstm gl;
    CR_CHECK_OK(cr_gat_lstm_create(&gd, P, "gl", &rng, &gl, &err), &err);
    randomise(P, 0.8f, 8);
    const cr_nn_graph g = infer_graph();
    float x[T * IN_N * IN], s0[2 * IN_N * H];
    nn_gradcheck_fill(x, T * IN_N * IN, -1, 1, 0, 9);
    nn_gradcheck_fill(s0, 2 * IN_N * H, -1, 1, 0, 10);
    const int prev = cr_nn_cpu_simd();
    double worst = 0.0;
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (int given = 0; given < 2; given++) {
            cr_tensor *y[2], *hl[2], *cl[2], *gy[2], *ghl[2], *gcl[2];
            cr_nn_ctx_reset(ctx);
            for (int mode = 0; mode < 2; mode++) {
                cr_nn_ctx_set_grad_enabled(ctx, mode == 0);
                cr_tensor *xs = cr_nn_from(ctx, 3, (int64_t[]){T, B, IN}, x);
                cr_tensor *xg = cr_nn_from(ctx, 3, (int64_t[]){T, IN_N, IN}, x);
                xs->requires_grad = xg->requires_grad = 1;
                cr_tensor *h0 = given ? cr_nn_from(ctx, 2, (int64_t[]){B, H}, s0) : NULL;
                cr_tensor *c0 = given ? cr_nn_from(ctx, 2, (int64_t[]){B, H}, s0 + B * H) : NULL;
                cr_tensor *gh0 = given ? cr_nn_from(ctx, 2, (int64_t[]){IN_N, H}, s0) : NULL;
                cr_tensor *gc0 =
                    given ? cr_nn_from(ctx, 2, (int64_t[]){IN_N, H}, s0 + IN_N * H) : NULL;
                y[mode] = cr_lstm_forward(ctx, &lstm, xs, h0, c0, &hl[mode], &cl[mode]);
                gy[mode] = cr_gat_lstm_forward(ctx, &gl, xg, &g, gh0, gc0, &ghl[mode], &gcl[mode]);
                CR_REQUIRE(y[mode] && gy[mode]);
                CR_CHECK(y[mode]->requires_grad == (mode == 0));
            }
            cr_nn_ctx_set_grad_enabled(ctx, 1);
            double e[6] = {near_all(y[1], y[0], 2e-5),     near_all(hl[1], hl[0], 2e-5),
                           near_all(cl[1], cl[0], 2e-5),   near_all(gy[1], gy[0], 2e-5),
                           near_all(ghl[1], ghl[0], 2e-5), near_all(gcl[1], gcl[0], 2e-5)};
            for (int i = 0; i < 6; i++)
                worst = e[i] > worst ? e[i] : worst;
        }
    }
    cr_nn_cpu_set_simd(prev);
    cr_log(CR_LOG_INFO, "lstm inference against the tape: max |diff| %.3g", worst);
    cr_nn_params_destroy(P);
    cr_nn_ctx_destroy(ctx);
}

/* Receivers' incoming weights sum to one; scores obey |g*| <= alpha and,
 * row by row, ||g*_i||_2 <= alpha; scaling x by 100 leaves them unchanged,
 * while plain GAT saturates. */
CR_TEST(nn_graph, gat_lipschitz_bound_and_scale_invariance) {
    const cr_gat_norm norms[3] = {CR_GAT_NORM_NONE, CR_GAT_NORM_GLOBAL, CR_GAT_NORM_RECEIVER};
    cr_nn_ctx *ctx = nn_gradcheck_ctx(4 << 20);
    CR_REQUIRE(ctx);
    for (int m = 0; m < 3; m++) {
        cr_gat_def d = small_gat_def(norms[m], 1);
        d.heads = 3;
        cr_nn_params *P = NULL;
        gat_case k;
        CR_REQUIRE(make_gat(&d, &P, &k, 80));
        float x[GN * 4], x100[GN * 4];
        nn_gradcheck_fill(x, GN * 4, -1, 1, 0, 81);
        for (int i = 0; i < GN * 4; i++)
            x100[i] = 100.0f * x[i];
        cr_nn_ctx_reset(ctx);
        cr_gat_attention a1, a2;
        CR_REQUIRE(
            cr_gat_forward(ctx, &k.gat, cr_nn_from(ctx, 2, (int64_t[]){GN, 4}, x), &k.g, &a1));
        CR_REQUIRE(
            cr_gat_forward(ctx, &k.gat, cr_nn_from(ctx, 2, (int64_t[]){GN, 4}, x100), &k.g, &a2));
        CR_REQUIRE(a1.edges == GE + GN && a2.edges == a1.edges && a1.weights && a2.scores);
        int H = d.heads;
        double wsum[GN][3] = {{0}}, row2[GN][3] = {{0}}, max_w100 = 0, min_w100 = 1;
        for (int e = 0; e < a1.edges; e++)
            for (int h = 0; h < H; h++) {
                int r = a1.receivers[e];
                float w = a1.weights->data[e * H + h], s1 = a1.scores->data[e * H + h];
                float s2 = a2.scores->data[e * H + h];
                CR_CHECK(w > 0);
                wsum[r][h] += w;
                row2[r][h] += (double)s2 * s2;
                max_w100 = fmax(max_w100, a2.weights->data[e * H + h]);
                min_w100 = fmin(min_w100, a2.weights->data[e * H + h]);
                if (m == 0) {
                    CR_CHECK_NEAR(s2, 100.0 * s1, 1e-3 * fabs(100.0 * s1) + 1e-3);
                } else {
                    CR_CHECK(fabs(s2) <= d.alpha * (1 + 1e-6));
                    CR_CHECK_NEAR(s2, s1, 1e-5);
                }
            }
        for (int r = 0; r < GN; r++)
            for (int h = 0; h < H; h++) {
                CR_CHECK_NEAR(wsum[r][h], 1.0, 1e-6);
                if (m != 0) CR_CHECK(sqrt(row2[r][h]) <= d.alpha * (1 + 1e-6));
            }
        if (m == 0) {
            CR_CHECK(max_w100 > 0.99); /* unnormalised scores x100: one neighbour takes all */
        } else {
            /* Logits within [-alpha, alpha]: a receiver of degree deg <= 4
             * gives each edge at least 1 / (1 + (deg - 1) e^(2 alpha)). */
            CR_CHECK(min_w100 >= 1.0 / (1.0 + 3.0 * exp(2.0 * d.alpha)));
            CR_CHECK(max_w100 < 0.99);
        }
        cr_nn_params_destroy(P);
    }
    cr_nn_ctx_destroy(ctx);
}

/* ---------------------------------------------------------------- MPNN -- */

typedef struct mpnn_case {
    cr_mpnn *net;
    cr_nn_graph g[2];
} mpnn_case;

enum { MP_NODE_IN = 3, MP_EDGE_IN = 2, MP_LAYER_IN = 1, MP_LE = 4, MP_OUT = 2 };
static const int32_t mp_lsnd[MP_LE] = {0, 2, 4, 5};
static const int32_t mp_lrcv[MP_LE] = {3, 5, 1, 0};

/* in = node features, mesh-edge features, layer-edge features. */
static cr_tensor *build_mpnn(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    mpnn_case *k = user;
    cr_tensor *ex[2] = {in[1], in[2]};
    return cr_mpnn_forward(ctx, k->net, in[0], k->g, ex, NULL);
}

static int make_mpnn(cr_act act, cr_nn_params **P, mpnn_case *k) {
    cr_error err = {0};
    if (cr_nn_params_create(P, &err) != CR_OK) return 0;
    cr_mpnn_def d = cr_mpnn_default_def();
    d.node_in = MP_NODE_IN;
    d.edge_sets = 2;
    d.edge_in[0] = MP_EDGE_IN;
    d.edge_in[1] = MP_LAYER_IN;
    d.node_out = MP_OUT;
    d.latent = 6;
    d.steps = 2;
    d.hidden_layers = 1;
    d.act = act;
    cr_rng rng = cr_rng_make(90, 0);
    if (cr_mpnn_create(&d, *P, "mp", &rng, &k->net, &err) != CR_OK) {
        fprintf(stderr, "    %s\n", err.msg);
        return 0;
    }
    randomise(*P, 0.5f, 91);
    k->g[0] = test_graph();
    k->g[1] = (cr_nn_graph){.nodes = GN, .edges = MP_LE, .senders = mp_lsnd, .receivers = mp_lrcv};
    return 1;
}

CR_TEST(nn_graph, mpnn_gradcheck) {
    cr_nn_params *P = NULL;
    mpnn_case k;
    CR_REQUIRE(make_mpnn(CR_ACT_TANH, &P, &k));
    CR_CHECK(cr_nn_params_find(P, "mp.processor.1.edge1.0.weight") != NULL);
    CR_CHECK(cr_nn_params_find(P, "mp.processor.0.node.ln.bias") != NULL);
    CR_CHECK(cr_nn_params_find(P, "mp.decoder.1.weight") != NULL);
    CR_CHECK(cr_nn_params_find(P, "mp.decoder.ln.weight") == NULL);
    float x[GN * MP_NODE_IN], ex[GE * MP_EDGE_IN], lx[MP_LE * MP_LAYER_IN];
    nn_gradcheck_fill(x, GN * MP_NODE_IN, -1, 1, 0, 92);
    nn_gradcheck_fill(ex, GE * MP_EDGE_IN, -1, 1, 0, 93);
    nn_gradcheck_fill(lx, MP_LE * MP_LAYER_IN, -1, 1, 0, 94);
    nn_gradcheck_input in[3] = {nn_gradcheck_in(2, (int64_t[]){GN, MP_NODE_IN}, x),
                                nn_gradcheck_in(2, (int64_t[]){GE, MP_EDGE_IN}, ex),
                                nn_gradcheck_in(2, (int64_t[]){MP_LE, MP_LAYER_IN}, lx)};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "mpnn";
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 3, in, P, build_mpnn, &k, &res) == 0);
    CR_CHECK(res.checked ==
             GN * MP_NODE_IN + GE * MP_EDGE_IN + MP_LE * MP_LAYER_IN + cr_nn_params_numel(P));
    cr_mpnn_destroy(k.net);
    cr_nn_params_destroy(P);
}

/* y = W x + b for the store's "<name>.weight" (OUT,IN) and "<name>.bias". */
static void ref_linear(cr_nn_params *P, const char *name, const double *x, int in, double *y) {
    char w[128], b[128];
    snprintf(w, sizeof w, "%s.weight", name);
    snprintf(b, sizeof b, "%s.bias", name);
    cr_tensor *W = cr_nn_params_find(P, w), *B = cr_nn_params_find(P, b);
    CR_ASSERT(W && B && W->shape[1] == in);
    for (int o = 0; o < W->shape[0]; o++) {
        y[o] = B->data[o];
        for (int i = 0; i < in; i++)
            y[o] += (double)W->data[o * in + i] * x[i];
    }
}

/* y = W1 tanh(W0 x + b0) + b1: an MLP "<base>.0", "<base>.1" with one
 * hidden layer of width RL. */
enum { RL = 5 };
static void ref_mlp(cr_nn_params *P, const char *base, const double *x, int in, double *y) {
    char name[96];
    double hid[RL];
    snprintf(name, sizeof name, "%s.0", base);
    ref_linear(P, name, x, in, hid);
    for (int i = 0; i < RL; i++)
        hid[i] = tanh(hid[i]);
    snprintf(name, sizeof name, "%s.1", base);
    ref_linear(P, name, hid, RL, y);
}

/* Without LayerNorm, eq. 6-7 of GDSR written out with one-hidden-layer tanh
 * MLPs: edge input [e_ij, h_i, h_j] with i the receiver, node input
 * [h_i, sum over set 0, sum over set 1]. */
CR_TEST(nn_graph, mpnn_matches_loop_reference) {
    enum { L = RL, K = 2 };
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_mpnn_def d = cr_mpnn_default_def();
    d.node_in = MP_NODE_IN;
    d.edge_sets = 2;
    d.edge_in[0] = MP_EDGE_IN;
    d.edge_in[1] = MP_LAYER_IN;
    d.node_out = MP_OUT;
    d.latent = L;
    d.steps = K;
    d.hidden_layers = 1;
    d.act = CR_ACT_TANH;
    d.layer_norm = 0;
    cr_rng rng = cr_rng_make(95, 0);
    cr_mpnn *net = NULL;
    CR_CHECK_OK(cr_mpnn_create(&d, P, "mp", &rng, &net, &err), &err);
    CR_REQUIRE(net);
    randomise(P, 0.5f, 96);
    float x[GN * MP_NODE_IN], ex[GE * MP_EDGE_IN], lx[MP_LE];
    nn_gradcheck_fill(x, GN * MP_NODE_IN, -1, 1, 0, 97);
    nn_gradcheck_fill(ex, GE * MP_EDGE_IN, -1, 1, 0, 98);
    nn_gradcheck_fill(lx, MP_LE, -1, 1, 0, 99);
    const int32_t *snd[2] = {g_snd, mp_lsnd}, *rcv[2] = {g_rcv, mp_lrcv};
    const int ne[2] = {GE, MP_LE}, nin[2] = {MP_EDGE_IN, MP_LAYER_IN};
    const float *exs[2] = {ex, lx};
    double h[GN][L], e[2][GE][L], in[3 * L], upd[L];
    for (int n = 0; n < GN; n++) {
        for (int i = 0; i < MP_NODE_IN; i++)
            in[i] = x[n * MP_NODE_IN + i];
        ref_mlp(P, "mp.encoder.node", in, MP_NODE_IN, h[n]);
    }
    for (int s = 0; s < 2; s++)
        for (int j = 0; j < ne[s]; j++) {
            for (int i = 0; i < nin[s]; i++)
                in[i] = exs[s][j * nin[s] + i];
            ref_mlp(P, s ? "mp.encoder.edge1" : "mp.encoder.edge0", in, nin[s], e[s][j]);
        }
    for (int k = 0; k < K; k++) {
        double agg[2][GN][L] = {{{0}}};
        for (int s = 0; s < 2; s++)
            for (int j = 0; j < ne[s]; j++) {
                for (int c = 0; c < L; c++) {
                    in[c] = e[s][j][c];
                    in[L + c] = h[rcv[s][j]][c];
                    in[2 * L + c] = h[snd[s][j]][c];
                }
                char name[64];
                snprintf(name, sizeof name, "mp.processor.%d.edge%d", k, s);
                ref_mlp(P, name, in, 3 * L, upd);
                for (int c = 0; c < L; c++) {
                    e[s][j][c] += upd[c];
                    agg[s][rcv[s][j]][c] += e[s][j][c];
                }
            }
        double hn[GN][L];
        for (int n = 0; n < GN; n++) {
            for (int c = 0; c < L; c++) {
                in[c] = h[n][c];
                in[L + c] = agg[0][n][c];
                in[2 * L + c] = agg[1][n][c];
            }
            char name[64];
            snprintf(name, sizeof name, "mp.processor.%d.node", k);
            ref_mlp(P, name, in, 3 * L, upd);
            for (int c = 0; c < L; c++)
                hn[n][c] = h[n][c] + upd[c];
        }
        memcpy(h, hn, sizeof h);
    }
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *ea[2] = {cr_nn_from(ctx, 2, (int64_t[]){GE, MP_EDGE_IN}, ex),
                        cr_nn_from(ctx, 2, (int64_t[]){MP_LE, 1}, lx)};
    cr_nn_graph g[2] = {test_graph(),
                        {.nodes = GN, .edges = MP_LE, .senders = mp_lsnd, .receivers = mp_lrcv}};
    cr_tensor *y =
        cr_mpnn_forward(ctx, net, cr_nn_from(ctx, 2, (int64_t[]){GN, MP_NODE_IN}, x), g, ea, NULL);
    CR_REQUIRE(y && y->shape[0] == GN && y->shape[1] == MP_OUT);
    for (int n = 0; n < GN; n++) {
        double out[MP_OUT];
        ref_mlp(P, "mp.decoder", h[n], L, out);
        for (int c = 0; c < MP_OUT; c++)
            CR_CHECK_NEAR(y->data[n * MP_OUT + c], out[c], 1e-5);
    }
    cr_nn_ctx_destroy(ctx);
    cr_mpnn_destroy(net);
    cr_nn_params_destroy(P);
}

/* The forward-only path (gradient off: every block in cpu_mpnn.c) against
 * the tape's ops on every SIMD path: latents 6 (no whole vector), 16
 * (epnet's P-Net), 40 (two vectors and a tail) and 80 (a 64-column block
 * and a vector, gdsr's 64); without LayerNorm, and
 * with it after no hidden layer (not centred in the weights: the gathered
 * rows add to the one layer), one and two; two edge sets: infer_graph (a
 * long segment, an empty one, a self loop) and a set given sorted by
 * receiver (the path without a permutation), or that one empty; each
 * activation the kernel runs on some case. */
CR_TEST(nn_graph, mpnn_inference_matches_tape) {
    enum { LE = 3 * IN_N };
    cr_nn_ctx *ctx = nn_gradcheck_ctx(16 << 20);
    CR_REQUIRE(ctx);
    const cr_nn_graph big = infer_graph();
    static int32_t lsnd[LE], lrcv[LE];
    for (int32_t i = 0; i < LE; i++) /* a second set, given sorted by receiver: three a node */
        lsnd[i] = (i * 5 + 3) % IN_N, lrcv[i] = i / 3;
    const int prev = cr_nn_cpu_simd();
    double worst = 0.0;
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (int m = 0; m < 5; m++) {
            const int latents[5] = {6, 16, 40, 16, 80}, hidden[5] = {1, 1, 2, 0, 1};
            const cr_act acts[4] = {CR_ACT_TANH, CR_ACT_RELU, CR_ACT_SOFTPLUS, CR_ACT_LEAKY_RELU};
            cr_nn_params *P = NULL;
            cr_error err = {0};
            CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
            cr_mpnn_def d = cr_mpnn_default_def();
            d.node_in = 5, d.edge_sets = 2, d.edge_in[0] = 9, d.edge_in[1] = 2, d.node_out = 3;
            d.latent = latents[m], d.hidden_layers = hidden[m], d.steps = 3;
            d.act = acts[(m + level) % 4], d.layer_norm = m != 0;
            cr_rng rng = cr_rng_make(70 + (uint64_t)m, 0);
            cr_mpnn *net = NULL;
            CR_CHECK_OK(cr_mpnn_create(&d, P, "mp", &rng, &net, &err), &err);
            CR_REQUIRE(net);
            randomise(P, 0.5f, 80 + (uint64_t)m);
            static float x[IN_N * 5], ex[IN_E * 9], lx[LE * 2];
            nn_gradcheck_fill(x, IN_N * 5, -1, 1, 0, 81);
            nn_gradcheck_fill(ex, big.edges * 9, -1, 1, 0, 82);
            nn_gradcheck_fill(lx, LE * 2, -1, 1, 0, 83);
            cr_nn_graph g[2] = {
                big, {.nodes = IN_N, .edges = m == 3 ? 0 : LE, .senders = lsnd, .receivers = lrcv}};
            cr_tensor *y[2], *lat[2];
            cr_nn_ctx_reset(ctx);
            for (int mode = 0; mode < 2; mode++) {
                cr_nn_ctx_set_grad_enabled(ctx, mode == 0);
                cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){IN_N, 5}, x);
                cr_tensor *ea[2] = {cr_nn_from(ctx, 2, (int64_t[]){big.edges, 9}, ex),
                                    cr_nn_from(ctx, 2, (int64_t[]){LE, 2}, lx)};
                xt->requires_grad = 1;
                y[mode] = cr_mpnn_forward(ctx, net, xt, g, ea, &lat[mode]);
                CR_REQUIRE(y[mode] && lat[mode]);
                CR_CHECK(y[mode]->requires_grad == (mode == 0));
            }
            cr_nn_ctx_set_grad_enabled(ctx, 1);
            double e[2] = {near_all(y[1], y[0], 2e-5), near_all(lat[1], lat[0], 2e-5)};
            for (int i = 0; i < 2; i++)
                worst = e[i] > worst ? e[i] : worst;
            cr_mpnn_destroy(net);
            cr_nn_params_destroy(P);
        }
    }
    cr_nn_cpu_set_simd(prev);
    cr_log(CR_LOG_INFO, "mpnn inference against the tape: max |diff| %.3g", worst);
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------------- permutation equivariance -- */

/* Node i becomes node perm[i]; edges are relabelled and reversed in order. */
static void permute_graph(const int32_t *perm, const int32_t *s, const int32_t *r, int E,
                          int32_t *ps, int32_t *pr) {
    for (int e = 0; e < E; e++) {
        ps[E - 1 - e] = perm[s[e]];
        pr[E - 1 - e] = perm[r[e]];
    }
}

static void permute_rows(const int32_t *perm, const float *x, int n, int c, float *px) {
    for (int i = 0; i < n; i++)
        memcpy(px + perm[i] * c, x + i * c, (size_t)c * sizeof *x);
}

CR_TEST(nn_graph, graph_layers_are_permutation_equivariant) {
    int32_t perm[GN] = {0, 1, 2, 3, 4, 5};
    cr_rng rng = cr_rng_make(100, 0);
    cr_rng_shuffle_i32(&rng, perm, GN);
    int32_t ps[GE], pr[GE], pls[MP_LE], plr[MP_LE];
    permute_graph(perm, g_snd, g_rcv, GE, ps, pr);
    permute_graph(perm, mp_lsnd, mp_lrcv, MP_LE, pls, plr);
    float x[GN * 4], px[GN * 4], ex[GE * MP_EDGE_IN], pex[GE * MP_EDGE_IN];
    float lx[MP_LE], plx[MP_LE];
    nn_gradcheck_fill(x, GN * 4, -1, 1, 0, 101);
    nn_gradcheck_fill(ex, GE * MP_EDGE_IN, -1, 1, 0, 102);
    nn_gradcheck_fill(lx, MP_LE, -1, 1, 0, 103);
    permute_rows(perm, x, GN, 4, px);
    for (int e = 0; e < GE; e++)
        memcpy(pex + (GE - 1 - e) * MP_EDGE_IN, ex + e * MP_EDGE_IN, MP_EDGE_IN * sizeof(float));
    for (int e = 0; e < MP_LE; e++)
        plx[MP_LE - 1 - e] = lx[e];
    cr_nn_ctx *ctx = nn_gradcheck_ctx(4 << 20);
    CR_REQUIRE(ctx);
    /* GAT, every normalisation. */
    const cr_gat_norm norms[3] = {CR_GAT_NORM_NONE, CR_GAT_NORM_GLOBAL, CR_GAT_NORM_RECEIVER};
    for (int m = 0; m < 3; m++) {
        cr_gat_def d = small_gat_def(norms[m], 1);
        cr_nn_params *P = NULL;
        gat_case k;
        CR_REQUIRE(make_gat(&d, &P, &k, 110 + (uint64_t)m));
        cr_nn_graph pg = {.nodes = GN, .edges = GE, .senders = ps, .receivers = pr};
        cr_nn_ctx_reset(ctx);
        cr_tensor *y =
            cr_gat_forward(ctx, &k.gat, cr_nn_from(ctx, 2, (int64_t[]){GN, 4}, x), &k.g, NULL);
        cr_tensor *py =
            cr_gat_forward(ctx, &k.gat, cr_nn_from(ctx, 2, (int64_t[]){GN, 4}, px), &pg, NULL);
        CR_REQUIRE(y && py);
        int C = (int)y->shape[1];
        for (int i = 0; i < GN; i++)
            for (int c = 0; c < C; c++)
                CR_CHECK_NEAR(py->data[perm[i] * C + c], y->data[i * C + c], 1e-5);
        cr_nn_params_destroy(P);
    }
    /* MPNN with ReLU (its default), both edge sets. */
    cr_nn_params *P = NULL;
    mpnn_case k;
    CR_REQUIRE(make_mpnn(CR_ACT_RELU, &P, &k));
    float xm[GN * MP_NODE_IN], pxm[GN * MP_NODE_IN];
    for (int i = 0; i < GN * MP_NODE_IN; i++)
        xm[i] = x[i];
    permute_rows(perm, xm, GN, MP_NODE_IN, pxm);
    cr_nn_ctx_reset(ctx);
    cr_tensor *ea[2] = {cr_nn_from(ctx, 2, (int64_t[]){GE, MP_EDGE_IN}, ex),
                        cr_nn_from(ctx, 2, (int64_t[]){MP_LE, 1}, lx)};
    cr_tensor *pea[2] = {cr_nn_from(ctx, 2, (int64_t[]){GE, MP_EDGE_IN}, pex),
                         cr_nn_from(ctx, 2, (int64_t[]){MP_LE, 1}, plx)};
    cr_nn_graph pg[2] = {{.nodes = GN, .edges = GE, .senders = ps, .receivers = pr},
                         {.nodes = GN, .edges = MP_LE, .senders = pls, .receivers = plr}};
    cr_tensor *lat = NULL;
    cr_tensor *y = cr_mpnn_forward(ctx, k.net, cr_nn_from(ctx, 2, (int64_t[]){GN, MP_NODE_IN}, xm),
                                   k.g, ea, &lat);
    cr_tensor *py = cr_mpnn_forward(
        ctx, k.net, cr_nn_from(ctx, 2, (int64_t[]){GN, MP_NODE_IN}, pxm), pg, pea, NULL);
    CR_REQUIRE(y && py && lat && lat->shape[1] == 6);
    double spread = 0;
    for (int i = 0; i < GN; i++)
        for (int c = 0; c < MP_OUT; c++) {
            CR_CHECK_NEAR(py->data[perm[i] * MP_OUT + c], y->data[i * MP_OUT + c], 1e-5);
            spread += fabs(y->data[i * MP_OUT + c] - y->data[c]);
        }
    CR_CHECK(spread > 1e-3); /* nodes do differ, so the check above means something */
    cr_mpnn_destroy(k.net);
    cr_nn_params_destroy(P);
    cr_nn_ctx_destroy(ctx);
}

/* -------------------------------------------------- graph LSTM, errors -- */

typedef struct glstm_case {
    cr_gat_lstm cell;
    cr_nn_graph g;
} glstm_case;

static cr_tensor *build_glstm(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    glstm_case *k = user;
    cr_tensor *cl = NULL;
    cr_tensor *all = cr_gat_lstm_forward(ctx, &k->cell, in[0], &k->g, in[1], in[2], NULL, &cl);
    cr_tensor *parts[2] = {cr_nn_reshape(ctx, all, 2, (int64_t[]){-1, k->cell.def.hidden}), cl};
    return cr_nn_concat(ctx, 2, parts, 0);
}

CR_TEST(nn_graph, gat_lstm_gradcheck) {
    enum { T = 2, IN = 3, H = 2 };
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_gat_lstm_def d = cr_gat_lstm_default_def();
    d.input = IN;
    d.hidden = H;
    d.gat.heads = 2;
    cr_rng rng = cr_rng_make(120, 0);
    glstm_case k = {.g = test_graph()};
    CR_CHECK_OK(cr_gat_lstm_create(&d, P, "pd", &rng, &k.cell, &err), &err);
    cr_tensor *att = cr_nn_params_find(P, "pd.h.att_src");
    CR_REQUIRE(att && att->shape[0] == 2 && att->shape[1] == 4 * H / 2);
    CR_CHECK(cr_nn_params_find(P, "pd.w_co") && !cr_nn_params_find(P, "pd.h.bias"));
    randomise(P, 0.6f, 121);
    float x[T * GN * IN], h[GN * H], c[GN * H];
    nn_gradcheck_fill(x, T * GN * IN, -1, 1, 0, 122);
    nn_gradcheck_fill(h, GN * H, -1, 1, 0, 123);
    nn_gradcheck_fill(c, GN * H, -1, 1, 0, 124);
    nn_gradcheck_input in[3] = {nn_gradcheck_in(3, (int64_t[]){T, GN, IN}, x),
                                nn_gradcheck_in(2, (int64_t[]){GN, H}, h),
                                nn_gradcheck_in(2, (int64_t[]){GN, H}, c)};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "gat lstm";
    CR_CHECK(nn_gradcheck(&gd, 3, in, P, build_glstm, &k, NULL) == 0);
    /* 4H = 8 does not split over 3 concatenated heads. */
    d.gat.heads = 3;
    CR_CHECK(cr_gat_lstm_create(&d, P, "bad", &rng, &k.cell, &err) == CR_ERR_INVALID);
    cr_nn_params_destroy(P);
}

CR_TEST(nn_graph, bad_graphs_are_reported) {
    cr_nn_params *P = NULL;
    gat_case k;
    cr_gat_def d = small_gat_def(CR_GAT_NORM_GLOBAL, 1);
    CR_REQUIRE(make_gat(&d, &P, &k, 130));
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    int32_t bad_rcv[GE];
    memcpy(bad_rcv, g_rcv, sizeof bad_rcv);
    bad_rcv[5] = GN;
    cr_nn_graph bg = {.nodes = GN, .edges = GE, .senders = g_snd, .receivers = bad_rcv};
    cr_error err = {0};
    CR_CHECK(cr_gat_forward(ctx, &k.gat, cr_nn_zeros(ctx, 2, (int64_t[]){GN, 4}), &bg, NULL) ==
             NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_RANGE && strstr(err.msg, "edge 5") != NULL);
    cr_nn_ctx_reset(ctx);
    CR_CHECK(cr_gat_forward(ctx, &k.gat, cr_nn_zeros(ctx, 2, (int64_t[]){GN, 5}), &k.g, NULL) ==
             NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    /* An all-zero input stays finite under the normalisation. */
    cr_nn_ctx_reset(ctx);
    cr_tensor *z = cr_gat_forward(ctx, &k.gat, cr_nn_zeros(ctx, 2, (int64_t[]){GN, 4}), &k.g, NULL);
    CR_REQUIRE(z);
    for (int i = 0; i < z->numel; i++)
        CR_CHECK(isfinite(z->data[i]));
    cr_nn_params_destroy(P);

    mpnn_case m;
    CR_REQUIRE(make_mpnn(CR_ACT_RELU, &P, &m));
    cr_nn_ctx_reset(ctx);
    cr_tensor *ex[2] = {cr_nn_zeros(ctx, 2, (int64_t[]){GE, MP_EDGE_IN}), NULL};
    cr_nn_graph g2[2] = {test_graph(), {.nodes = GN, .edges = 0}};
    /* An empty edge set aggregates to zero and needs no features. */
    CR_CHECK(cr_mpnn_forward(ctx, m.net, cr_nn_zeros(ctx, 2, (int64_t[]){GN, MP_NODE_IN}), g2, ex,
                             NULL) != NULL);
    g2[0].receivers = bad_rcv;
    CR_CHECK(cr_mpnn_forward(ctx, m.net, cr_nn_zeros(ctx, 2, (int64_t[]){GN, MP_NODE_IN}), g2, ex,
                             NULL) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_RANGE);
    cr_nn_ctx_reset(ctx);
    g2[0].receivers = g_rcv;
    ex[0] = cr_nn_zeros(ctx, 2, (int64_t[]){GE, MP_EDGE_IN + 1});
    CR_CHECK(cr_mpnn_forward(ctx, m.net, cr_nn_zeros(ctx, 2, (int64_t[]){GN, MP_NODE_IN}), g2, ex,
                             NULL) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE && strstr(err.msg, "edge_x[0]") != NULL);
    cr_mpnn_destroy(m.net);
    cr_nn_params_destroy(P);
    cr_nn_ctx_destroy(ctx);
}
