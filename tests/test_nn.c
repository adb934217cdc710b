/* test_nn.c: the tensor engine's core: op names, tensors and views, a
 * 3-layer tanh MLP against a hand-written backward, an MLP input Jacobian
 * built from ops, the fused-op hook, error messages, arena reuse, the
 * parameter store, and thread-count independence. The op-by-op gradient
 * checks are in test_nn_ops.c.
 */
#include "crease/nn.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------ basics, views -- */

CR_TEST(nn, op_names_are_complete_and_distinct) {
    for (int i = 0; i < CR_OP_COUNT; i++) {
        const char *a = cr_op_name((cr_op)i);
        CR_CHECK(a && strcmp(a, "unknown op") != 0);
        for (int j = 0; j < i; j++)
            CR_CHECK(strcmp(a, cr_op_name((cr_op)j)) != 0);
    }
    CR_CHECK(strcmp(cr_op_name(CR_OP_COUNT), "unknown op") == 0);
    CR_CHECK(strcmp(cr_op_name(CR_OP_SEGMENT_SOFTMAX), "segment_softmax") == 0);
}

CR_TEST(nn, tensors_and_views) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    float v[6] = {1, 2, 3, 4, 5, 6};
    cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){2, 3}, v);
    CR_REQUIRE(x && x->numel == 6 && x->ndim == 2 && ((uintptr_t)x->data % 64) == 0);
    char s[64];
    CR_CHECK(strcmp(cr_nn_shape_str(x, s, sizeof s), "(2,3)") == 0);
    cr_tensor *r = cr_nn_reshape(ctx, x, 3, (int64_t[]){3, -1, 1});
    CR_REQUIRE(r && r->shape[0] == 3 && r->shape[1] == 2 && r->data == x->data);
    cr_tensor *row = cr_nn_slice(ctx, x, 0, 1, 1);
    CR_REQUIRE(row && row->data == x->data + 3 && row->op == CR_OP_NONE);
    cr_tensor *col = cr_nn_slice(ctx, x, 1, 1, 2); /* a copy */
    CR_REQUIRE(col && col->data[0] == 2 && col->data[1] == 3 && col->data[2] == 5);
    cr_tensor *sc = cr_nn_scalar(ctx, 2.5f);
    CR_CHECK(sc && sc->ndim == 0 && sc->numel == 1 && sc->data[0] == 2.5f);
    CR_CHECK(strcmp(cr_nn_shape_str(sc, s, sizeof s), "()") == 0);
    cr_tensor *w = cr_nn_wrap(ctx, 1, (int64_t[]){6}, v);
    CR_CHECK(w && w->data == v);
    /* Gradients flow through views into the base. */
    x->requires_grad = 1;
    cr_tensor *rv = cr_nn_reshape(ctx, x, 1, (int64_t[]){6});
    cr_tensor *first = cr_nn_slice(ctx, x, 0, 1, 1);
    cr_tensor *loss = cr_nn_add(ctx, cr_nn_sum(ctx, cr_nn_square(ctx, rv)), cr_nn_sum(ctx, first));
    cr_error err = {0};
    CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
    for (int i = 0; i < 6; i++)
        CR_CHECK_NEAR(x->grad[i], 2 * v[i] + (i >= 3), 1e-6);
    /* detach stops gradients */
    cr_nn_ctx_reset(ctx);
    x = cr_nn_from(ctx, 1, (int64_t[]){2}, v);
    x->requires_grad = 1;
    cr_tensor *d = cr_nn_detach(ctx, x);
    CR_CHECK(d && !d->requires_grad && !cr_nn_mul(ctx, d, d)->requires_grad);
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------- MLP vs hand-derived backward -- */

/* z (B,O) = in (B,I) W (I,O) + b, in double. */
static void dense(const double *in, int B, int I, const float *W, const float *b, int O,
                  double *z) {
    for (int r = 0; r < B; r++)
        for (int o = 0; o < O; o++) {
            double s = b[o];
            for (int i = 0; i < I; i++)
                s += in[r * I + i] * W[i * O + o];
            z[r * O + o] = s;
        }
}

/* Given dz (B,O): dW += in^T dz, db += colsum dz, din = dz W^T (when din). */
static void dense_back(const double *in, const double *dz, int B, int I, const float *W, int O,
                       double *dW, double *db, double *din) {
    for (int r = 0; r < B; r++)
        for (int o = 0; o < O; o++) {
            db[o] += dz[r * O + o];
            for (int i = 0; i < I; i++)
                dW[i * O + o] += in[r * I + i] * dz[r * O + o];
        }
    if (!din) return;
    for (int r = 0; r < B; r++)
        for (int i = 0; i < I; i++) {
            double s = 0;
            for (int o = 0; o < O; o++)
                s += dz[r * O + o] * W[i * O + o];
            din[r * I + i] = s;
        }
}

CR_TEST(nn, mlp_backward_matches_hand_derivation) {
    enum { B = 5, D0 = 3, D1 = 8, D2 = 6, D3 = 2 };
    const int dims[4] = {D0, D1, D2, D3};
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_tensor *W[3], *bias[3];
    cr_rng rng = cr_rng_make(9, 1);
    for (int l = 0; l < 3; l++) {
        char name[32];
        snprintf(name, sizeof name, "mlp.%d.weight", l);
        CR_CHECK_OK(cr_nn_params_add(P, name, 2, (int64_t[]){dims[l], dims[l + 1]}, &W[l], &err),
                    &err);
        snprintf(name, sizeof name, "mlp.%d.bias", l);
        CR_CHECK_OK(cr_nn_params_add(P, name, 1, (int64_t[]){dims[l + 1]}, &bias[l], &err), &err);
    }
    for (int l = 0; l < 3; l++) {
        cr_nn_fill_uniform(W[l], &rng, -0.7f, 0.7f);
        cr_nn_fill_uniform(bias[l], &rng, -0.3f, 0.3f);
    }
    float x[B * D0], t[B * D3];
    nn_gradcheck_fill(x, B * D0, -1, 1, 0, 81);
    nn_gradcheck_fill(t, B * D3, -1, 1, 0, 82);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *tx = cr_nn_from(ctx, 2, (int64_t[]){B, D0}, x);
    tx->requires_grad = 1;
    cr_tensor *h = tx;
    for (int l = 0; l < 3; l++) {
        h = cr_nn_add(ctx, cr_nn_matmul(ctx, h, W[l], 0, 0), bias[l]);
        if (l < 2) h = cr_nn_tanh(ctx, h);
    }
    cr_tensor *d = cr_nn_sub(ctx, h, cr_nn_from(ctx, 2, (int64_t[]){B, D3}, t));
    cr_tensor *loss = cr_nn_mul_scalar(ctx, cr_nn_sum(ctx, cr_nn_square(ctx, d)), 0.5f);
    cr_nn_params_zero_grad(P);
    CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);

    /* The same network and loss 0.5 |y - t|^2 by hand, in double. */
    double a0[B * D0], z1[B * D1], a1[B * D1], z2[B * D2], a2[B * D2], y[B * D3];
    for (int i = 0; i < B * D0; i++)
        a0[i] = x[i];
    dense(a0, B, D0, W[0]->data, bias[0]->data, D1, z1);
    for (int i = 0; i < B * D1; i++)
        a1[i] = tanh(z1[i]);
    dense(a1, B, D1, W[1]->data, bias[1]->data, D2, z2);
    for (int i = 0; i < B * D2; i++)
        a2[i] = tanh(z2[i]);
    dense(a2, B, D2, W[2]->data, bias[2]->data, D3, y);
    double L = 0, dy[B * D3], da2[B * D2], da1[B * D1], dx[B * D0];
    for (int i = 0; i < B * D3; i++)
        L += 0.5 * (y[i] - t[i]) * (y[i] - t[i]), dy[i] = y[i] - t[i];
    CR_CHECK_NEAR(loss->data[0], L, 1e-5 * fmax(1, L));
    double dW[3][D1 * D2] = {{0}}, db[3][D1] = {{0}};
    dense_back(a2, dy, B, D2, W[2]->data, D3, dW[2], db[2], da2);
    for (int i = 0; i < B * D2; i++)
        da2[i] *= 1 - a2[i] * a2[i]; /* now dz2 */
    dense_back(a1, da2, B, D1, W[1]->data, D2, dW[1], db[1], da1);
    for (int i = 0; i < B * D1; i++)
        da1[i] *= 1 - a1[i] * a1[i]; /* now dz1 */
    dense_back(a0, da1, B, D0, W[0]->data, D1, dW[0], db[0], dx);
    double worst = 0;
    for (int l = 0; l < 3; l++) {
        for (int i = 0; i < dims[l] * dims[l + 1]; i++)
            worst = fmax(worst, fabs(W[l]->grad[i] - dW[l][i]) / fmax(1, fabs(dW[l][i])));
        for (int i = 0; i < dims[l + 1]; i++)
            worst = fmax(worst, fabs(bias[l]->grad[i] - db[l][i]) / fmax(1, fabs(db[l][i])));
    }
    for (int i = 0; i < B * D0; i++)
        worst = fmax(worst, fabs(tx->grad[i] - dx[i]));
    CR_CHECK(worst < 1e-5);
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
}

/* Input Jacobian of y = W2 tanh(W1 x + b1) built from ordinary ops:
 * dy/dx_i = W2 (tanh'(z) * W1[:,i]). x (N,D), W1 (H,D), b1 (H), W2 (O,H);
 * output (N, D*O) with entry [n, i*O + o] = dy_o/dx_i at x_n. */
enum { JN = 4, JD = 3, JH = 5, JO = 2 };

static cr_tensor *build_jacobian(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    (void)user;
    cr_tensor *d = cr_nn_tanh_deriv(ctx, cr_nn_linear(ctx, in[0], in[1], in[2])); /* (N,H) */
    cr_tensor *cols[JD];
    for (int i = 0; i < JD; i++) {
        cr_tensor *w1i = cr_nn_reshape(ctx, cr_nn_slice(ctx, in[1], 1, i, 1), 1, (int64_t[]){JH});
        cols[i] = cr_nn_linear(ctx, cr_nn_mul(ctx, d, w1i), in[3], NULL);
    }
    return cr_nn_concat(ctx, JD, cols, 1);
}

static void mlp1(const double *x, const float *W1, const float *b1, const float *W2, double *y) {
    double h[JH];
    for (int k = 0; k < JH; k++) {
        double z = b1[k];
        for (int i = 0; i < JD; i++)
            z += W1[k * JD + i] * x[i];
        h[k] = tanh(z);
    }
    for (int o = 0; o < JO; o++) {
        y[o] = 0;
        for (int k = 0; k < JH; k++)
            y[o] += W2[o * JH + k] * h[k];
    }
}

CR_TEST(nn, mlp_input_jacobian_from_ops) {
    float x[JN * JD], W1[JH * JD], b1[JH], W2[JO * JH];
    nn_gradcheck_fill(x, JN * JD, -1, 1, 0, 121);
    nn_gradcheck_fill(W1, JH * JD, -1, 1, 0, 122);
    nn_gradcheck_fill(b1, JH, -0.5f, 0.5f, 0, 123);
    nn_gradcheck_fill(W2, JO * JH, -1, 1, 0, 124);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_tensor *in[4] = {
        cr_nn_from(ctx, 2, (int64_t[]){JN, JD}, x), cr_nn_from(ctx, 2, (int64_t[]){JH, JD}, W1),
        cr_nn_from(ctx, 1, (int64_t[]){JH}, b1), cr_nn_from(ctx, 2, (int64_t[]){JO, JH}, W2)};
    cr_tensor *J = build_jacobian(ctx, in, NULL);
    CR_REQUIRE(J && J->shape[0] == JN && J->shape[1] == JD * JO);
    const double h = 1e-5; /* in double: central differences are accurate to ~1e-10 */
    for (int n = 0; n < JN; n++)
        for (int i = 0; i < JD; i++) {
            double xp[JD], xm[JD], yp[JO], ym[JO];
            for (int k = 0; k < JD; k++)
                xp[k] = xm[k] = x[n * JD + k];
            xp[i] += h, xm[i] -= h;
            mlp1(xp, W1, b1, W2, yp);
            mlp1(xm, W1, b1, W2, ym);
            for (int o = 0; o < JO; o++)
                CR_CHECK_NEAR(J->data[n * JD * JO + i * JO + o], (yp[o] - ym[o]) / (2 * h), 1e-5);
        }
    cr_nn_ctx_destroy(ctx);
    /* Gradients flow through the Jacobian (second derivatives of tanh via ops). */
    nn_gradcheck_input gin[4] = {
        nn_gradcheck_in(2, (int64_t[]){JN, JD}, x), nn_gradcheck_in(2, (int64_t[]){JH, JD}, W1),
        nn_gradcheck_in(1, (int64_t[]){JH}, b1), nn_gradcheck_in(2, (int64_t[]){JO, JH}, W2)};
    CR_CHECK(nn_gradcheck_quick("input jacobian", 4, gin, NULL, build_jacobian, NULL) == 0);
}

/* ------------------------------------------------------------ fused op -- */

/* E = sum over edges (i,j) of |x_i - x_j|^2, with dE/dx_i = 2 (x_i - x_j). */
typedef struct edge_set {
    const int32_t *ij; /* (ne,2) */
    int64_t ne;
    float grad_scale; /* 1; anything else is a wrong backward the checker must catch */
} edge_set;

static cr_status edge_energy_forward(const cr_fused_op *def, cr_nn_ctx *ctx, cr_tensor *const *in,
                                     int nin, cr_tensor *const *out, int nout, void **stash,
                                     cr_error *err) {
    const edge_set *e = def->user;
    const cr_tensor *x = in[0];
    if (nin != 1 || nout != 1 || x->ndim != 2 || x->shape[1] != 3)
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: expects one input (V,3)", def->name);
    float *d = cr_nn_scratch(ctx, def->name, (size_t)e->ne * 3 * sizeof(float));
    if (!d) return CR_FAIL(err, CR_ERR_MEMORY, "%s: no scratch", def->name);
    double s = 0;
    for (int64_t k = 0; k < e->ne; k++)
        for (int c = 0; c < 3; c++) {
            d[3 * k + c] = x->data[3 * e->ij[2 * k] + c] - x->data[3 * e->ij[2 * k + 1] + c];
            s += (double)d[3 * k + c] * d[3 * k + c];
        }
    out[0]->data[0] = (float)s;
    *stash = d;
    return CR_OK;
}

static cr_status edge_energy_backward(const cr_fused_op *def, cr_nn_ctx *ctx, cr_tensor *const *in,
                                      int nin, cr_tensor *const *out, int nout, void *stash,
                                      cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)err;
    const edge_set *e = def->user;
    const float *d = stash;
    if (!in[0]->requires_grad) return CR_OK;
    float g = out[0]->grad[0] * e->grad_scale;
    for (int64_t k = 0; k < e->ne; k++)
        for (int c = 0; c < 3; c++) {
            in[0]->grad[3 * e->ij[2 * k] + c] += 2 * g * d[3 * k + c];
            in[0]->grad[3 * e->ij[2 * k + 1] + c] -= 2 * g * d[3 * k + c];
        }
    return CR_OK;
}

static cr_tensor *build_fused(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    cr_nn_shape scalar = {0, {1, 1, 1, 1}};
    cr_tensor *E = cr_nn_fused(ctx, user, 1, in, 1, &scalar, NULL);
    return cr_nn_mul(ctx, E, cr_nn_sum_axis(ctx, in[0], 0, 0)); /* composes with ops */
}

CR_TEST(nn, fused_op_edge_energy) {
    static const int32_t ij[5 * 2] = {0, 1, 1, 2, 2, 0, 2, 3, 3, 1};
    edge_set edges = {ij, 5, 1.0f};
    cr_fused_op def = {"edge_energy", edge_energy_forward, edge_energy_backward, &edges};
    float x[4 * 3];
    nn_gradcheck_fill(x, 12, -1, 1, 0, 91);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    /* value and gradient agree with the same energy composed from ops */
    cr_tensor *tx = cr_nn_from(ctx, 2, (int64_t[]){4, 3}, x);
    tx->requires_grad = 1;
    cr_nn_shape scalar = {0, {1, 1, 1, 1}};
    cr_tensor *E = cr_nn_fused(ctx, &def, 1, &tx, 1, &scalar, NULL);
    CR_REQUIRE(E && E->requires_grad && E->op == CR_OP_FUSED);
    int32_t ii[5], jj[5];
    for (int k = 0; k < 5; k++)
        ii[k] = ij[2 * k], jj[k] = ij[2 * k + 1];
    cr_tensor *diff =
        cr_nn_sub(ctx, cr_nn_gather_rows(ctx, tx, ii, 5), cr_nn_gather_rows(ctx, tx, jj, 5));
    cr_tensor *E2 = cr_nn_sum(ctx, cr_nn_square(ctx, diff));
    CR_REQUIRE(E2);
    CR_CHECK_NEAR(E->data[0], E2->data[0], 1e-5);
    cr_error err = {0};
    CR_CHECK_OK(cr_nn_backward(ctx, cr_nn_sub(ctx, E, cr_nn_mul_scalar(ctx, E2, 0.5f)), &err),
                &err);
    /* d(E - E2/2) = dE/2 */
    float g_fused[12];
    memcpy(g_fused, tx->grad, sizeof g_fused);
    cr_nn_ctx_reset(ctx);
    tx = cr_nn_from(ctx, 2, (int64_t[]){4, 3}, x);
    tx->requires_grad = 1;
    E2 = cr_nn_sum(ctx, cr_nn_square(ctx, cr_nn_sub(ctx, cr_nn_gather_rows(ctx, tx, ii, 5),
                                                    cr_nn_gather_rows(ctx, tx, jj, 5))));
    CR_CHECK_OK(cr_nn_backward(ctx, E2, &err), &err);
    for (int i = 0; i < 12; i++)
        CR_CHECK_NEAR(g_fused[i], 0.5f * tx->grad[i], 1e-5);
    /* A forward failure becomes the context's error, with the op's message. */
    cr_nn_ctx_reset(ctx);
    cr_tensor *bad = cr_nn_zeros(ctx, 2, (int64_t[]){4, 2});
    CR_CHECK(cr_nn_fused(ctx, &def, 1, &bad, 1, &scalar, NULL) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE && strstr(err.msg, "edge_energy:"));
    cr_nn_ctx_destroy(ctx);
    nn_gradcheck_input in = nn_gradcheck_in(2, (int64_t[]){4, 3}, x);
    CR_CHECK(nn_gradcheck_quick("fused edge energy", 1, &in, NULL, build_fused, &def) == 0);
    /* The checker catches a backward that is off by 2%. */
    edges.grad_scale = 1.02f;
    nn_gradcheck_def quiet = nn_gradcheck_default_def();
    quiet.max_reports = 0;
    CR_CHECK(nn_gradcheck(&quiet, 1, &in, NULL, build_fused, &def, NULL) > 0);
}

/* -------------------------------------------------------------- errors -- */

CR_TEST(nn, errors_name_the_op_and_chain) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_error err = {0};
    cr_tensor *a = cr_nn_zeros(ctx, 2, (int64_t[]){64, 3});
    cr_tensor *b = cr_nn_zeros(ctx, 2, (int64_t[]){4, 128});
    a->requires_grad = 1;
    cr_tensor *y = cr_nn_matmul(ctx, a, b, 0, 0);
    CR_CHECK(y == NULL);
    /* later ops return NULL quietly; the first error is kept */
    cr_tensor *z = cr_nn_sum(ctx, cr_nn_tanh(ctx, y));
    CR_CHECK(z == NULL && cr_nn_add(ctx, a, a) == NULL);
    CR_CHECK(cr_nn_backward(ctx, z, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "matmul: inner dimensions differ: (64,3) x (4,128)") != NULL);
    cr_nn_ctx_reset(ctx);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_OK);

    cr_tensor *u = cr_nn_zeros(ctx, 2, (int64_t[]){2, 3}),
              *v = cr_nn_zeros(ctx, 2, (int64_t[]){4, 3});
    CR_CHECK(cr_nn_sub(ctx, u, v) == NULL && cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "sub: shapes do not broadcast: (2,3) and (4,3)") != NULL);
    cr_nn_ctx_reset(ctx);

    static const int32_t idx[3] = {0, 7, 1};
    CR_CHECK(cr_nn_gather_rows(ctx, cr_nn_zeros(ctx, 2, (int64_t[]){5, 2}), idx, 3) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "gather_rows: index 7 at position 1") != NULL);
    cr_nn_ctx_reset(ctx);
    CR_CHECK(cr_nn_segment_softmax(ctx, cr_nn_zeros(ctx, 1, (int64_t[]){3}), idx, 2) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_RANGE && strstr(err.msg, "segment_softmax"));
    cr_nn_ctx_reset(ctx);

    float nan_v = NAN;
    cr_tensor *n = cr_nn_from(ctx, 1, (int64_t[]){1}, &nan_v);
    n->requires_grad = 1;
    CR_CHECK(cr_nn_backward(ctx, cr_nn_sum(ctx, n), &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "backward: loss is NaN") != NULL);
    cr_nn_ctx_reset(ctx);

    cr_tensor *m = cr_nn_zeros(ctx, 1, (int64_t[]){3});
    m->requires_grad = 1;
    CR_CHECK(cr_nn_backward(ctx, cr_nn_square(ctx, m), &err) == CR_ERR_SHAPE);
    cr_tensor *loss = cr_nn_sum(ctx, cr_nn_square(ctx, m));
    CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
    CR_CHECK(cr_nn_backward(ctx, loss, &err) == CR_ERR_INVALID); /* twice */
    CR_CHECK(cr_nn_backward(ctx, cr_nn_zeros(ctx, 0, NULL), &err) == CR_ERR_INVALID);
    cr_nn_ctx_destroy(ctx);

    /* Running out of arena names the op and the bytes. */
    ctx = nn_gradcheck_ctx(4096);
    CR_REQUIRE(ctx);
    CR_CHECK(cr_nn_zeros(ctx, 2, (int64_t[]){100, 100}) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_MEMORY);
    CR_CHECK(strstr(err.msg, "new: arena exhausted: need") && strstr(err.msg, "of 4096 free"));
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------------ arena reuse, params -- */

/* One training step of a small MLP; returns the loss tensor. */
static cr_tensor *train_step(cr_nn_ctx *ctx, cr_nn_params *P, const float *x, const float *t) {
    cr_nn_ctx_reset(ctx);
    cr_tensor *h = cr_nn_from(ctx, 2, (int64_t[]){64, 4}, x);
    for (int l = 0; l < 3; l++) {
        char wn[32], bn[32];
        snprintf(wn, sizeof wn, "l%d.weight", l);
        snprintf(bn, sizeof bn, "l%d.bias", l);
        h = cr_nn_linear(ctx, h, cr_nn_params_find(P, wn), cr_nn_params_find(P, bn));
        if (l < 2) h = cr_nn_softplus(ctx, h, 1.0f);
    }
    cr_tensor *d = cr_nn_sub(ctx, h, cr_nn_from(ctx, 2, (int64_t[]){64, 2}, t));
    cr_tensor *loss = cr_nn_mean(ctx, cr_nn_square(ctx, d));
    cr_nn_params_zero_grad(P);
    cr_error err = {0};
    return cr_nn_backward(ctx, loss, &err) == CR_OK ? loss : NULL;
}

CR_TEST(nn, arena_reuse_is_stable_and_bit_identical) {
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    const int64_t dims[4] = {4, 32, 32, 2};
    cr_rng rng = cr_rng_make(11, 0);
    for (int l = 0; l < 3; l++) {
        char name[32];
        cr_tensor *w, *b;
        snprintf(name, sizeof name, "l%d.weight", l);
        CR_CHECK_OK(cr_nn_params_add(P, name, 2, (int64_t[]){dims[l + 1], dims[l]}, &w, &err),
                    &err);
        snprintf(name, sizeof name, "l%d.bias", l);
        CR_CHECK_OK(cr_nn_params_add(P, name, 1, &dims[l + 1], &b, &err), &err);
        cr_nn_fill_normal(w, &rng, 0, 0.5f);
    }
    float x[64 * 4], t[64 * 2];
    nn_gradcheck_fill(x, 256, -1, 1, 0, 101);
    nn_gradcheck_fill(t, 128, -1, 1, 0, 102);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(4 << 20);
    CR_REQUIRE(ctx);
    int64_t n;
    float *g = cr_nn_params_grad(P, &n);
    float *g1 = malloc((size_t)n * sizeof(float));
    CR_REQUIRE(g1);
    cr_tensor *l1 = train_step(ctx, P, x, t);
    CR_REQUIRE(l1);
    float loss1 = l1->data[0];
    size_t used1 = cr_nn_ctx_arena_used(ctx), peak1 = cr_nn_ctx_arena_peak(ctx);
    int64_t nodes1 = cr_nn_ctx_tape_length(ctx);
    memcpy(g1, g, (size_t)n * sizeof(float));
    cr_tensor *l2 = train_step(ctx, P, x, t);
    CR_REQUIRE(l2);
    CR_CHECK(memcmp(&loss1, &l2->data[0], sizeof loss1) == 0);
    CR_CHECK(memcmp(g1, g, (size_t)n * sizeof(float)) == 0);
    CR_CHECK(cr_nn_ctx_arena_used(ctx) == used1 && cr_nn_ctx_arena_peak(ctx) == peak1);
    CR_CHECK(cr_nn_ctx_tape_length(ctx) == nodes1 && nodes1 == 8);
    /* grad mode off: nothing recorded, parameters do not make outputs require grad */
    cr_nn_ctx_reset(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_tensor *y = cr_nn_linear(ctx, cr_nn_from(ctx, 2, (int64_t[]){64, 4}, x),
                                cr_nn_params_find(P, "l0.weight"), NULL);
    CR_CHECK(y && !y->requires_grad && cr_nn_ctx_tape_length(ctx) == 0);
    free(g1);
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
}

CR_TEST(nn, params_store) {
    cr_nn_params *P = NULL;
    cr_error err = {0};
    CR_REQUIRE(cr_nn_params_create(&P, &err) == CR_OK);
    cr_tensor *a, *b, *c;
    CR_CHECK_OK(cr_nn_params_add(P, "a", 2, (int64_t[]){3, 5}, &a, &err), &err);
    a->data[14] = 7.0f;
    /* a large add forces the blocks to grow; a's data moves with them */
    CR_CHECK_OK(cr_nn_params_add(P, "b", 2, (int64_t[]){100, 100}, &b, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(P, "c", 0, NULL, &c, &err), &err);
    CR_CHECK(a->data[14] == 7.0f && b->data[9999] == 0.0f && c->numel == 1);
    int64_t n;
    float *data = cr_nn_params_data(P, &n), *grad = cr_nn_params_grad(P, &n);
    CR_CHECK(a->data == data && b->data - data == 16 && c->data - data == 10016 && n == 10017);
    CR_CHECK(a->grad == grad && ((uintptr_t)b->data % 64) == 0 && a->persistent);
    CR_CHECK(cr_nn_params_count(P) == 3 && cr_nn_params_numel(P) == 10016);
    const char *name;
    CR_CHECK(cr_nn_params_at(P, 1, &name) == b && strcmp(name, "b") == 0);
    CR_CHECK(cr_nn_params_find(P, "c") == c && cr_nn_params_find(P, "d") == NULL);
    cr_tensor *dup;
    CR_CHECK(cr_nn_params_add(P, "b", 1, (int64_t[]){2}, &dup, &err) == CR_ERR_INVALID);
    CR_CHECK(dup == NULL && strstr(err.msg, "'b' is already defined"));
    /* grads accumulate over backward passes until zero_grad; frozen ones stay 0 */
    cr_nn_ctx *ctx = nn_gradcheck_ctx(1 << 20);
    CR_REQUIRE(ctx);
    cr_nn_fill(a, 1.5f);
    cr_nn_fill(c, 2.0f);
    c->requires_grad = 0;
    for (int step = 0; step < 2; step++) {
        cr_nn_ctx_reset(ctx);
        cr_tensor *loss = cr_nn_sum(ctx, cr_nn_mul(ctx, cr_nn_square(ctx, a), c));
        CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
    }
    CR_CHECK_NEAR(a->grad[3], 2 * (2 * 1.5 * 2.0), 1e-6);
    CR_CHECK(c->grad[0] == 0.0f);
    cr_nn_params_zero_grad(P);
    CR_CHECK(a->grad[3] == 0.0f);
    cr_nn_ctx_destroy(ctx);
    cr_nn_params_destroy(P);
    cr_nn_params_destroy(NULL);
}

/* --------------------------------------------------------- determinism -- */

/* Several parallel kernels on tensors above the parallel grain; the results
 * must not depend on the thread count. */
static void big_ops(cr_nn_ctx *ctx, const float *x, const int32_t *seg, float *out) {
    enum { N = 40000, C = 8 };
    cr_nn_ctx_reset(ctx);
    cr_tensor *t = cr_nn_from(ctx, 2, (int64_t[]){N, C}, x);
    t->requires_grad = 1;
    cr_tensor *sm = cr_nn_segment_softmax(ctx, t, seg, 1000);
    cr_tensor *sc = cr_nn_scatter_add_rows(ctx, cr_nn_mul(ctx, sm, t), seg, 1000);
    cr_tensor *ln = cr_nn_layer_norm(ctx, sc, NULL, NULL, 1e-5f);
    cr_tensor *col = cr_nn_sum_axis(ctx, cr_nn_tanh(ctx, t), 0, 0);
    cr_tensor *loss = cr_nn_add(ctx, cr_nn_sum(ctx, cr_nn_square(ctx, ln)), cr_nn_sum(ctx, col));
    cr_error err = {0};
    if (cr_nn_backward(ctx, loss, &err) != CR_OK) return;
    out[0] = loss->data[0];
    memcpy(out + 1, t->grad, sizeof(float) * N * C);
}

CR_TEST(nn, results_do_not_depend_on_thread_count) {
    enum { N = 40000, C = 8 };
    float *x = malloc(sizeof(float) * N * C), *o1 = calloc(N * C + 1, sizeof(float)),
          *o2 = calloc(N * C + 1, sizeof(float));
    int32_t *seg = malloc(sizeof(int32_t) * N);
    CR_REQUIRE(x && o1 && o2 && seg);
    nn_gradcheck_fill(x, N * C, -2, 2, 0, 111);
    cr_rng r = cr_rng_make(5, 5);
    for (int i = 0; i < N; i++)
        seg[i] = (int32_t)cr_rng_below(&r, 1000);
    cr_nn_ctx *ctx = nn_gradcheck_ctx(64 << 20);
    CR_REQUIRE(ctx);
    int threads = cr_thread_count();
    big_ops(ctx, x, seg, o1);
    cr_set_thread_count(1);
    big_ops(ctx, x, seg, o2);
    cr_set_thread_count(threads > 1 ? threads : 4);
    float *o3 = calloc(N * C + 1, sizeof(float));
    CR_REQUIRE(o3);
    big_ops(ctx, x, seg, o3);
    cr_set_thread_count(threads);
    CR_CHECK(o1[0] != 0 && memcmp(o1, o2, sizeof(float) * (N * C + 1)) == 0);
    CR_CHECK(memcmp(o1, o3, sizeof(float) * (N * C + 1)) == 0);
    free(x), free(o1), free(o2), free(o3), free(seg);
    cr_nn_ctx_destroy(ctx);
}
