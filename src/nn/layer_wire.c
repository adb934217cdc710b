/* layer_wire.c: WIRE, the complex Gabor wavelet activation, complex linear
 * layers on (re, im) pairs of real tensors, and a WIRE network.
 *
 * With z = a + j b:
 *   wire(z) = exp(j w0 z - |s0 z|^2)
 *           = E (cos(w0 a) + j sin(w0 a)),  E = exp(-w0 b - s0^2 (a^2 + b^2)),
 * as the WIRE reference code evaluates it (exp(1j*omega - scale.abs().square())
 * with omega = w0 z, scale = s0 z). The activation is one fused op; its
 * backward, with R + jI the output and gR, gI the incoming gradients:
 *   dL/da = gR (-2 s0^2 a R - w0 I) + gI (-2 s0^2 a I + w0 R)
 *   dL/db = (gR R + gI I) (-w0 - 2 s0^2 b).
 * The loss is real, so each output part carries its own real gradient and no
 * Wirtinger calculus is needed.
 * Leaves out: WIRE's 2-D (two-Gabor) variant; complex parameters as one
 * tensor (the store is real: weight_re / weight_im pairs instead).
 * Reference: Saragadam et al., WIRE: Wavelet Implicit Neural
 * Representations, CVPR 2023 (eq. 5 and the reference code); GDSR (paper 001)
 * sec. 4.4 for its use (omega0 5, spread 10).
 */
#include "crease/nn_layers.h"
#include "nn/tape.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { WIRE_MLP_COOKIE = 0x57495231u /* "WIR1" */ };

/* The op's constants live in the step arena beside its def, which the engine
 * needs valid until the reset. */
typedef struct wire_op {
    cr_fused_op def;
    float omega0, s0;
} wire_op;

typedef struct wire_job {
    const wire_op *w;
    const float *a, *b;     /* (n) input re, im (b may be NULL) */
    float *re, *im;         /* (n) outputs */
    const float *gre, *gim; /* (n) dL/d(outputs) */
    float *ga, *gb;         /* (n) dL/d(inputs), either may be NULL */
} wire_job;

static void wire_forward_range(void *arg, int64_t begin, int64_t end) {
    const wire_job *j = arg;
    float w0 = j->w->omega0, s2 = j->w->s0 * j->w->s0;
    for (int64_t k = begin; k < end; k++) {
        float a = j->a[k], b = j->b ? j->b[k] : 0.0f;
        float e = expf(-w0 * b - s2 * (a * a + b * b));
        j->re[k] = e * cosf(w0 * a);
        j->im[k] = e * sinf(w0 * a);
    }
}

static void wire_backward_range(void *arg, int64_t begin, int64_t end) {
    const wire_job *j = arg;
    float w0 = j->w->omega0, s2 = j->w->s0 * j->w->s0;
    for (int64_t k = begin; k < end; k++) {
        float a = j->a[k], b = j->b ? j->b[k] : 0.0f;
        float R = j->re[k], I = j->im[k], gR = j->gre[k], gI = j->gim[k];
        if (j->ga)
            j->ga[k] += gR * (-2.0f * s2 * a * R - w0 * I) + gI * (-2.0f * s2 * a * I + w0 * R);
        if (j->gb) j->gb[k] += (gR * R + gI * I) * (-w0 - 2.0f * s2 * b);
    }
}

static cr_status wire_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                              cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash;
    if (in[1] && !cr_nn_same_shape(in[0], in[1])) {
        char a[64], b[64];
        return CR_FAIL(err, CR_ERR_SHAPE, "wire: re %s and im %s differ",
                       cr_nn_shape_str(in[0], a, sizeof a), cr_nn_shape_str(in[1], b, sizeof b));
    }
    wire_job j = {.w = op->user,
                  .a = in[0]->data,
                  .b = in[1] ? in[1]->data : NULL,
                  .re = out[0]->data,
                  .im = out[1]->data};
    cr_parallel_for(in[0]->numel, 4096, wire_forward_range, &j);
    return CR_OK;
}

static cr_status wire_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                               cr_tensor *const *out, int nout, void *stash, cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    wire_job j = {.w = op->user,
                  .a = in[0]->data,
                  .b = in[1] ? in[1]->data : NULL,
                  .re = out[0]->data,
                  .im = out[1]->data,
                  .gre = out[0]->grad,
                  .gim = out[1]->grad,
                  .ga = in[0]->requires_grad ? in[0]->grad : NULL,
                  .gb = in[1] && in[1]->requires_grad ? in[1]->grad : NULL};
    cr_parallel_for(in[0]->numel, 4096, wire_backward_range, &j);
    return CR_OK;
}

cr_tensor *cr_wire_activation(cr_nn_ctx *ctx, cr_tensor *re, cr_tensor *im, float omega0, float s0,
                              cr_tensor **out_re, cr_tensor **out_im) {
    if (out_re) *out_re = NULL;
    if (out_im) *out_im = NULL;
    if (!cr_nn_begin(ctx, "wire", 1, &re)) return NULL;
    wire_op *w = cr_nn_scratch(ctx, "wire", sizeof *w);
    if (!w) return NULL;
    *w = (wire_op){.def = {.name = "wire", .forward = wire_forward, .backward = wire_backward},
                   .omega0 = omega0,
                   .s0 = s0};
    w->def.user = w;
    cr_nn_shape s = cr_nn_shape_of(re);
    cr_nn_shape shapes[2] = {s, s};
    cr_tensor *in[2] = {re, im}, *out[2];
    cr_tensor *y = cr_nn_fused(ctx, &w->def, 2, in, 2, shapes, out);
    if (!y) return NULL;
    if (out_re) *out_re = out[0];
    if (out_im) *out_im = out[1];
    return y;
}

cr_status cr_wire_hyper_infer(cr_nn_ctx *ctx, const float *theta, int64_t G, int64_t P,
                              const int32_t *group, const float *x, int64_t ldx, int64_t M,
                              int width, int layers, int out, float omega0, float s0, float *y,
                              cr_error *err) {
    if (!ctx || !theta || !group || !x || !y || M < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "wire hyper: NULL argument");
    if (layers < 2 || layers > CR_MLP_MAX_LAYERS || width < 1 || width > CR_WIRE_MAX_WIDTH ||
        out < 1 || ldx < 2)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "wire hyper: layers %d (2..%d), width %d (1..%d), out %d, ldx %lld", layers,
                       CR_MLP_MAX_LAYERS, width, CR_WIRE_MAX_WIDTH, out, (long long)ldx);
    const int64_t need = 3 * (int64_t)width +
                         (layers - 2) * (2 * (int64_t)width * width + 2 * width) +
                         2 * (int64_t)out * width + 2 * out;
    if (P < need)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "wire hyper: rows of %lld floats, the network needs %lld", (long long)P,
                       (long long)need);
    const int64_t bad = ctx->be->index_check(group, M, G);
    if (bad >= 0)
        return CR_FAIL(err, CR_ERR_INVALID, "wire hyper: point %lld's group %d is outside [0,%lld)",
                       (long long)bad, group[bad], (long long)G);
    int64_t *off = cr_nn_scratch(ctx, "wire hyper",
                                 sizeof(int64_t) * (size_t)(G + 1) + sizeof(int32_t) * (size_t)M);
    if (!off) return CR_FAIL(err, CR_ERR_MEMORY, "wire hyper: the context's arena is full");
    int32_t *perm = (int32_t *)(off + G + 1);
    ctx->be->csr_build(group, M, G, off, perm);
    nn_wire_points_args a = {.theta = theta,
                             .P = P,
                             .group = group,
                             .G = G,
                             .off = off,
                             .perm = perm,
                             .x = x,
                             .ldx = ldx,
                             .M = M,
                             .width = width,
                             .layers = layers,
                             .out = out,
                             .omega0 = omega0,
                             .s2 = s0 * s0,
                             .y = y};
    ctx->be->wire_points_forward(&a);
    return CR_OK;
}

cr_tensor *cr_complex_linear(cr_nn_ctx *ctx, cr_tensor *x_re, cr_tensor *x_im, cr_tensor *w_re,
                             cr_tensor *w_im, cr_tensor *b_re, cr_tensor *b_im, cr_tensor **y_re,
                             cr_tensor **y_im) {
    /* (xr + j xi)(Wr + j Wi)^T = (xr Wr^T - xi Wi^T) + j (xr Wi^T + xi Wr^T) */
    cr_tensor *re = cr_nn_linear(ctx, x_re, w_re, b_re);
    cr_tensor *im = cr_nn_linear(ctx, x_re, w_im, b_im);
    if (x_im) {
        re = cr_nn_sub(ctx, re, cr_nn_linear(ctx, x_im, w_im, NULL));
        im = cr_nn_add(ctx, im, cr_nn_linear(ctx, x_im, w_re, NULL));
    }
    if (y_re) *y_re = re && im ? re : NULL;
    if (y_im) *y_im = re && im ? im : NULL;
    return re && im ? re : NULL;
}

/* ---------------------------------------------------------- WIRE MLP -- */

cr_wire_mlp_def cr_wire_mlp_default_def(void) {
    cr_wire_mlp_def d;
    memset(&d, 0, sizeof d);
    d.omega0 = CR_WIRE_OMEGA0;
    d.s0 = CR_WIRE_S0;
    d.cookie = WIRE_MLP_COOKIE;
    return d;
}

int64_t cr_wire_mlp_param_count(const cr_wire_mlp_def *def) {
    int64_t n = 0;
    for (int i = 0; i < def->nlayers; i++) {
        int64_t in = def->widths[i], out = def->widths[i + 1];
        n += (i == 0 ? 1 : 2) * (in * out + out);
    }
    return n;
}

static cr_status add_uniform(cr_nn_params *params, const char *prefix, int i, const char *what,
                             int ndim, const int64_t *shape, double bound, cr_rng *rng,
                             cr_tensor **out, cr_error *err) {
    char name[128];
    int n = prefix && *prefix ? snprintf(name, sizeof name, "%s.%d.%s", prefix, i, what)
                              : snprintf(name, sizeof name, "%d.%s", i, what);
    if (n < 0 || n >= (int)sizeof name)
        return CR_FAIL(err, CR_ERR_INVALID, "wire_mlp: prefix \"%s\" is too long", prefix);
    CR_TRY(cr_nn_params_add(params, name, ndim, shape, out, err));
    cr_nn_fill_uniform(*out, rng, (float)-bound, (float)bound);
    return CR_OK;
}

static cr_status wire_mlp_layers(const cr_wire_mlp_def *def, cr_nn_params *params,
                                 const char *prefix, cr_rng *rng, cr_wire_mlp *m, cr_error *err) {
    cr_linear_def first = cr_linear_default_def();
    first.in = def->widths[0];
    first.out = def->widths[1];
    first.init = CR_INIT_TORCH;
    char name[128];
    int n = prefix && *prefix ? snprintf(name, sizeof name, "%s.0", prefix)
                              : snprintf(name, sizeof name, "0");
    if (n < 0 || n >= (int)sizeof name)
        return CR_FAIL(err, CR_ERR_INVALID, "wire_mlp: prefix \"%s\" is too long", prefix);
    CR_TRY(cr_linear_create(&first, params, name, rng, &m->first, err));
    for (int i = 1; i < def->nlayers; i++) {
        int64_t in = def->widths[i], out = def->widths[i + 1];
        double bound = 1.0 / sqrt((double)in);
        int64_t ws[2] = {out, in};
        CR_TRY(add_uniform(params, prefix, i, "weight_re", 2, ws, bound, rng, &m->w_re[i], err));
        CR_TRY(add_uniform(params, prefix, i, "weight_im", 2, ws, bound, rng, &m->w_im[i], err));
        CR_TRY(add_uniform(params, prefix, i, "bias_re", 1, &out, bound, rng, &m->b_re[i], err));
        CR_TRY(add_uniform(params, prefix, i, "bias_im", 1, &out, bound, rng, &m->b_im[i], err));
    }
    return CR_OK;
}

cr_status cr_wire_mlp_create(const cr_wire_mlp_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_wire_mlp **out, cr_error *err) {
    CR_ASSERT(def && def->cookie == WIRE_MLP_COOKIE && params && rng && out);
    *out = NULL;
    if (def->nlayers < 2 || def->nlayers > CR_MLP_MAX_LAYERS)
        return CR_FAIL(err, CR_ERR_INVALID, "wire_mlp: nlayers must be in 2..%d, got %d",
                       CR_MLP_MAX_LAYERS, def->nlayers);
    for (int i = 0; i <= def->nlayers; i++)
        if (def->widths[i] < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "wire_mlp: widths[%d] must be >= 1, got %d", i,
                           def->widths[i]);
    if (!isfinite(def->omega0) || !(def->s0 >= 0.0f) || !isfinite(def->s0))
        return CR_FAIL(err, CR_ERR_INVALID, "wire_mlp: omega0 (%g) and s0 (%g >= 0) must be finite",
                       (double)def->omega0, (double)def->s0);
    cr_wire_mlp *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->def = *def;
    cr_status st = wire_mlp_layers(def, params, prefix, rng, m, err);
    if (st != CR_OK) {
        free(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

void cr_wire_mlp_destroy(cr_wire_mlp *m) {
    free(m);
}

cr_tensor *cr_wire_mlp_forward(cr_nn_ctx *ctx, const cr_wire_mlp *m, cr_tensor *x) {
    const cr_wire_mlp_def *def = &m->def;
    cr_tensor *re = NULL, *im = NULL;
    cr_wire_activation(ctx, cr_linear_forward(ctx, &m->first, x), NULL, def->omega0, def->s0, &re,
                       &im);
    for (int i = 1; i < def->nlayers - 1; i++) {
        cr_tensor *zr, *zi;
        cr_complex_linear(ctx, re, im, m->w_re[i], m->w_im[i], m->b_re[i], m->b_im[i], &zr, &zi);
        cr_wire_activation(ctx, zr, zi, def->omega0, def->s0, &re, &im);
    }
    int last = def->nlayers - 1;
    return cr_complex_linear(ctx, re, im, m->w_re[last], m->w_im[last], m->b_re[last],
                             m->b_im[last], NULL, NULL);
}
