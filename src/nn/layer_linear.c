/* layer_linear.c: activations, weight initialisers, the Linear layer and the
 * MLP (hidden activation, optional layer norm and residual connections).
 *
 * Everything is composed from the engine's ops, so gradients come from the
 * tape; this file only decides shapes, names and initial values.
 * Leaves out: dropout and batch norm (no method here needs them), the input
 * Jacobian (layer_jacobian.c).
 * References: Glorot & Bengio 2010 (Xavier init); He et al. 2015 (Kaiming
 * init); Sitzmann et al. 2020, SIREN (sine layers and their init, sec. 3.2
 * and the supplement); PyTorch's torch.nn.Linear and calculate_gain for the
 * defaults that keep checkpoints interchangeable.
 */
#include "crease/nn_layers.h"
#include "nn/mlp_fused.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    LINEAR_COOKIE = 0x4c494e31u, /* "LIN1" */
    MLP_COOKIE = 0x4d4c5031u,    /* "MLP1" */
    NAME_CAP = 128,              /* the parameter store's name capacity, terminator included */
};

/* SIREN's omega_0 (Sitzmann et al. 2020, sec. 3.2): the first layer's
 * frequency scale; the paper uses it for hidden layers too. */
static const float SIREN_OMEGA = 30.0f;

/* ---------------------------------------------------------- activations -- */

static const char *const act_names[CR_ACT_COUNT] = {
    [CR_ACT_NONE] = "none", [CR_ACT_RELU] = "relu",       [CR_ACT_LEAKY_RELU] = "leaky_relu",
    [CR_ACT_TANH] = "tanh", [CR_ACT_SIGMOID] = "sigmoid", [CR_ACT_SOFTPLUS] = "softplus",
    [CR_ACT_SIN] = "sin",
};

const char *cr_act_name(cr_act act) {
    if ((unsigned)act >= (unsigned)CR_ACT_COUNT) return "unknown activation";
    return act_names[act];
}

cr_tensor *cr_act_forward(cr_nn_ctx *ctx, cr_act act, float param, cr_tensor *z) {
    switch (act) {
    case CR_ACT_NONE:
        return z;
    case CR_ACT_RELU:
        return cr_nn_relu(ctx, z);
    case CR_ACT_LEAKY_RELU:
        return cr_nn_leaky_relu(ctx, z, param);
    case CR_ACT_TANH:
        return cr_nn_tanh(ctx, z);
    case CR_ACT_SIGMOID:
        return cr_nn_sigmoid(ctx, z);
    case CR_ACT_SOFTPLUS:
        return cr_nn_softplus(ctx, z, param);
    case CR_ACT_SIN:
        return cr_nn_sin(ctx, cr_nn_mul_scalar(ctx, z, param));
    default:
        CR_ASSERT(!"cr_act_forward: unknown activation");
        return NULL;
    }
}

cr_tensor *cr_act_deriv(cr_nn_ctx *ctx, cr_act act, float param, cr_tensor *z) {
    switch (act) {
    case CR_ACT_NONE:
        return z ? cr_nn_full(ctx, z->ndim, z->shape, 1.0f) : NULL;
    case CR_ACT_RELU:
        return cr_nn_leaky_relu_deriv(ctx, z, 0.0f);
    case CR_ACT_LEAKY_RELU:
        return cr_nn_leaky_relu_deriv(ctx, z, param);
    case CR_ACT_TANH:
        return cr_nn_tanh_deriv(ctx, z);
    case CR_ACT_SIGMOID:
        return cr_nn_sigmoid_deriv(ctx, z);
    case CR_ACT_SOFTPLUS:
        return cr_nn_softplus_deriv(ctx, z, param);
    case CR_ACT_SIN: /* d/dz sin(omega z) = omega cos(omega z) */
        return cr_nn_mul_scalar(ctx, cr_nn_cos(ctx, cr_nn_mul_scalar(ctx, z, param)), param);
    default:
        CR_ASSERT(!"cr_act_deriv: unknown activation");
        return NULL;
    }
}

/* --------------------------------------------------------------- init -- */

static void fans(const cr_tensor *t, double *fan_in, double *fan_out) {
    int64_t in = t->ndim > 0 ? t->shape[t->ndim - 1] : 1;
    *fan_in = (double)(in > 0 ? in : 1);
    *fan_out = in > 0 ? (double)(t->numel / in) : 1.0;
}

static void fill_symmetric(cr_tensor *t, cr_rng *rng, double bound) {
    cr_nn_fill_uniform(t, rng, (float)-bound, (float)bound);
}

void cr_init_zero(cr_tensor *t) {
    cr_nn_fill(t, 0.0f);
}

void cr_init_glorot_uniform(cr_tensor *w, cr_rng *rng, float gain) {
    double in, out;
    fans(w, &in, &out);
    fill_symmetric(w, rng, gain * sqrt(6.0 / (in + out)));
}

void cr_init_kaiming_uniform(cr_tensor *w, cr_rng *rng, float gain) {
    double in, out;
    fans(w, &in, &out);
    fill_symmetric(w, rng, gain * sqrt(3.0 / in));
}

void cr_init_kaiming_normal(cr_tensor *w, cr_rng *rng, float gain) {
    double in, out;
    fans(w, &in, &out);
    cr_nn_fill_normal(w, rng, 0.0f, (float)(gain / sqrt(in)));
}

void cr_init_siren(cr_tensor *w, cr_rng *rng, int first, float omega) {
    double in, out;
    fans(w, &in, &out);
    CR_ASSERT(first || omega > 0.0f);
    fill_symmetric(w, rng, first ? 1.0 / in : sqrt(6.0 / in) / omega);
}

float cr_init_gain(cr_act act, float param) {
    switch (act) {
    case CR_ACT_RELU:
    case CR_ACT_SOFTPLUS:
        return sqrtf(2.0f);
    case CR_ACT_LEAKY_RELU:
        return sqrtf(2.0f / (1.0f + param * param));
    case CR_ACT_TANH:
        return 5.0f / 3.0f;
    default:
        return 1.0f;
    }
}

/* ------------------------------------------------------------- linear -- */

cr_linear_def cr_linear_default_def(void) {
    cr_linear_def d;
    memset(&d, 0, sizeof d);
    d.bias = 1;
    d.init = CR_INIT_GLOROT_UNIFORM;
    d.gain = 1.0f;
    d.omega = SIREN_OMEGA;
    d.cookie = LINEAR_COOKIE;
    return d;
}

/* "<prefix>.<suffix>" (or just suffix for an empty prefix) into buf. */
static cr_status param_name(char *buf, const char *prefix, const char *suffix, cr_error *err) {
    int n = prefix && *prefix ? snprintf(buf, NAME_CAP, "%s.%s", prefix, suffix)
                              : snprintf(buf, NAME_CAP, "%s", suffix);
    if (n < 0 || n >= NAME_CAP)
        return CR_FAIL(err, CR_ERR_INVALID, "parameter name \"%s.%s\" is longer than %d characters",
                       prefix ? prefix : "", suffix, NAME_CAP - 1);
    return CR_OK;
}

static void init_weight(cr_tensor *w, const cr_linear_def *def, cr_rng *rng) {
    switch (def->init) {
    case CR_INIT_ZERO:
        cr_init_zero(w);
        break;
    case CR_INIT_AUTO:
    case CR_INIT_GLOROT_UNIFORM:
        cr_init_glorot_uniform(w, rng, def->gain);
        break;
    case CR_INIT_KAIMING_UNIFORM:
        cr_init_kaiming_uniform(w, rng, def->gain);
        break;
    case CR_INIT_KAIMING_NORMAL:
        cr_init_kaiming_normal(w, rng, def->gain);
        break;
    case CR_INIT_SIREN_FIRST:
        cr_init_siren(w, rng, 1, def->omega);
        break;
    case CR_INIT_SIREN:
        cr_init_siren(w, rng, 0, def->omega);
        break;
    case CR_INIT_TORCH:
        fill_symmetric(w, rng, 1.0 / sqrt((double)def->in));
        break;
    default:
        CR_ASSERT(!"linear: unknown init");
    }
}

cr_status cr_linear_create(const cr_linear_def *def, cr_nn_params *params, const char *prefix,
                           cr_rng *rng, cr_linear *out, cr_error *err) {
    CR_ASSERT(def && def->cookie == LINEAR_COOKIE && params && rng && out);
    memset(out, 0, sizeof *out);
    if (def->in < 1 || def->out < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "linear %s: in (%d) and out (%d) must be >= 1",
                       prefix ? prefix : "", def->in, def->out);
    if (def->init == CR_INIT_SIREN && !(def->omega > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "linear %s: SIREN init needs omega > 0, got %g",
                       prefix ? prefix : "", (double)def->omega);
    char name[NAME_CAP];
    cr_linear l = {.in = def->in, .out = def->out};
    CR_TRY(param_name(name, prefix, "weight", err));
    CR_TRY(cr_nn_params_add(params, name, 2, (int64_t[]){def->out, def->in}, &l.weight, err));
    init_weight(l.weight, def, rng);
    if (def->bias) {
        CR_TRY(param_name(name, prefix, "bias", err));
        CR_TRY(cr_nn_params_add(params, name, 1, (int64_t[]){def->out}, &l.bias, err));
        int torch_bias = def->init == CR_INIT_TORCH || def->init == CR_INIT_SIREN_FIRST ||
                         def->init == CR_INIT_SIREN;
        if (torch_bias)
            fill_symmetric(l.bias, rng, 1.0 / sqrt((double)def->in));
        else
            cr_init_zero(l.bias);
    }
    *out = l;
    return CR_OK;
}

cr_tensor *cr_linear_forward(cr_nn_ctx *ctx, const cr_linear *lin, cr_tensor *x) {
    return cr_nn_linear(ctx, x, lin->weight, lin->bias);
}

/* ---------------------------------------------------------------- MLP -- */

cr_mlp_def cr_mlp_default_def(void) {
    cr_mlp_def d;
    memset(&d, 0, sizeof d);
    d.act = CR_ACT_RELU;
    d.leaky_slope = 0.01f;
    d.softplus_beta = 1.0f;
    d.first_omega = SIREN_OMEGA;
    d.hidden_omega = SIREN_OMEGA;
    d.out_act = CR_ACT_NONE;
    d.ln_eps = 1e-5f;
    d.init = CR_INIT_AUTO;
    d.cookie = MLP_COOKIE;
    return d;
}

static float act_param(const cr_mlp_def *def, cr_act act, int i) {
    switch (act) {
    case CR_ACT_LEAKY_RELU:
        return def->leaky_slope;
    case CR_ACT_SOFTPLUS:
        return def->softplus_beta;
    case CR_ACT_SIN:
        return i == 0 ? def->first_omega : def->hidden_omega;
    default:
        return 0.0f;
    }
}

cr_act cr_mlp_layer_act(const cr_mlp_def *def, int i, float *param) {
    CR_ASSERT(i >= 0 && i < def->nlayers);
    cr_act act = i == def->nlayers - 1 ? def->out_act : def->act;
    if (param) *param = act_param(def, act, i);
    return act;
}

int cr_mlp_layer_residual(const cr_mlp_def *def, int i) {
    return def->residual && i > 0 && i < def->nlayers - 1 && def->widths[i] == def->widths[i + 1];
}

cr_status cr_mlp_def_validate(const cr_mlp_def *def, cr_error *err) {
    CR_ASSERT(def && def->cookie == MLP_COOKIE);
    if (def->nlayers < 1 || def->nlayers > CR_MLP_MAX_LAYERS)
        return CR_FAIL(err, CR_ERR_INVALID, "mlp: nlayers must be in 1..%d, got %d",
                       CR_MLP_MAX_LAYERS, def->nlayers);
    for (int i = 0; i <= def->nlayers; i++)
        if (def->widths[i] < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "mlp: widths[%d] must be >= 1, got %d", i,
                           def->widths[i]);
    cr_act acts[2] = {def->act, def->out_act};
    for (int k = 0; k < 2; k++)
        if ((unsigned)acts[k] >= (unsigned)CR_ACT_COUNT)
            return CR_FAIL(err, CR_ERR_INVALID, "mlp: %s is not an activation (%d)",
                           k ? "out_act" : "act", (int)acts[k]);
    int uses_sin = def->act == CR_ACT_SIN || def->out_act == CR_ACT_SIN;
    if (uses_sin && !(def->first_omega > 0.0f && def->hidden_omega > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "mlp: sin needs first_omega, hidden_omega > 0");
    int uses_softplus = def->act == CR_ACT_SOFTPLUS || def->out_act == CR_ACT_SOFTPLUS;
    if (uses_softplus && !(def->softplus_beta > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "mlp: softplus_beta must be > 0, got %g",
                       (double)def->softplus_beta);
    if (def->layer_norm && !(def->ln_eps > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "mlp: ln_eps must be > 0, got %g", (double)def->ln_eps);
    return CR_OK;
}

int64_t cr_mlp_param_count(const cr_mlp_def *def) {
    int64_t n = 0;
    for (int i = 0; i < def->nlayers; i++) {
        int64_t in = def->widths[i], out = def->widths[i + 1];
        n += in * out + out;
        if (def->layer_norm && i < def->nlayers - 1) n += 2 * out;
    }
    return n;
}

/* The linear def of layer i under the MLP's init rule. */
static cr_linear_def layer_def(const cr_mlp_def *def, int i) {
    cr_linear_def l = cr_linear_default_def();
    l.in = def->widths[i];
    l.out = def->widths[i + 1];
    float param;
    cr_act act = cr_mlp_layer_act(def, i, &param);
    l.gain = cr_init_gain(act, param);
    l.omega = def->hidden_omega;
    cr_init init = def->init;
    if (init == CR_INIT_AUTO) {
        if (def->act == CR_ACT_SIN)
            init = CR_INIT_SIREN;
        else if (act == CR_ACT_RELU || act == CR_ACT_LEAKY_RELU || act == CR_ACT_SOFTPLUS)
            init = CR_INIT_KAIMING_UNIFORM;
        else
            init = CR_INIT_GLOROT_UNIFORM;
    }
    if (init == CR_INIT_SIREN && i == 0) init = CR_INIT_SIREN_FIRST;
    l.init = init;
    return l;
}

cr_status cr_mlp_create(const cr_mlp_def *def, cr_nn_params *params, const char *prefix,
                        cr_rng *rng, cr_mlp **out, cr_error *err) {
    CR_ASSERT(def && params && rng && out);
    *out = NULL;
    CR_TRY(cr_mlp_def_validate(def, err));
    cr_mlp *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->def = *def;
    char sub[NAME_CAP], name[NAME_CAP];
    cr_status st = CR_OK;
    for (int i = 0; i < def->nlayers && st == CR_OK; i++) {
        snprintf(sub, sizeof sub, "%d", i);
        st = param_name(name, prefix, sub, err);
        cr_linear_def ld = layer_def(def, i);
        if (st == CR_OK) st = cr_linear_create(&ld, params, name, rng, &m->layer[i], err);
        if (st != CR_OK || !def->layer_norm || i == def->nlayers - 1) continue;
        int64_t c = def->widths[i + 1];
        snprintf(sub, sizeof sub, "%d.ln.weight", i);
        st = param_name(name, prefix, sub, err);
        if (st == CR_OK) st = cr_nn_params_add(params, name, 1, &c, &m->ln_weight[i], err);
        if (st != CR_OK) continue;
        cr_nn_fill(m->ln_weight[i], 1.0f);
        snprintf(sub, sizeof sub, "%d.ln.bias", i);
        st = param_name(name, prefix, sub, err);
        if (st == CR_OK) st = cr_nn_params_add(params, name, 1, &c, &m->ln_bias[i], err);
    }
    if (st != CR_OK) {
        cr_mlp_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

void cr_mlp_destroy(cr_mlp *mlp) {
    free(mlp);
}

/* The op of an activation the fused linear runs, or CR_OP_COUNT for one it
 * does not (sin's derivative needs the pre-activation). */
cr_op cr_nn_act_fused_op(cr_act act, float param) {
    switch (act) {
    case CR_ACT_NONE:
        return CR_OP_NONE;
    case CR_ACT_RELU:
        return CR_OP_RELU;
    case CR_ACT_LEAKY_RELU:
        return param >= 0.0f ? CR_OP_LEAKY_RELU : CR_OP_COUNT;
    case CR_ACT_TANH:
        return CR_OP_TANH;
    case CR_ACT_SIGMOID:
        return CR_OP_SIGMOID;
    case CR_ACT_SOFTPLUS:
        return param > 0.0f ? CR_OP_SOFTPLUS : CR_OP_COUNT;
    default:
        return CR_OP_COUNT;
    }
}

/* The whole MLP as one op over blocks of rows (mlp_fused.c) when every
 * layer is a fused linear without layer norm or residual link. */
static cr_tensor *forward_fused(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *x) {
    const cr_mlp_def *def = &mlp->def;
    if (!cr_nn_mlp_fused_usable(ctx)) return NULL;
    cr_tensor *w[CR_MLP_MAX_LAYERS], *b[CR_MLP_MAX_LAYERS];
    cr_op op[CR_MLP_MAX_LAYERS];
    float p[CR_MLP_MAX_LAYERS];
    for (int i = 0; i < def->nlayers; i++) {
        cr_act act = cr_mlp_layer_act(def, i, &p[i]);
        op[i] = cr_nn_act_fused_op(act, p[i]);
        if (op[i] == CR_OP_COUNT || mlp->ln_weight[i] || cr_mlp_layer_residual(def, i)) return NULL;
        w[i] = mlp->layer[i].weight, b[i] = mlp->layer[i].bias;
    }
    return cr_nn_mlp_fused(ctx, x, def->nlayers, w, b, op, p);
}

cr_tensor *cr_mlp_forward(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *x) {
    const cr_mlp_def *def = &mlp->def;
    if (x && cr_nn_mlp_fused_enabled()) {
        cr_tensor *y = forward_fused(ctx, mlp, x);
        if (y || cr_nn_ctx_error(ctx, NULL) != CR_OK) return y;
    }
    cr_tensor *h = x;
    for (int i = 0; i < def->nlayers; i++) {
        float param;
        cr_act act = cr_mlp_layer_act(def, i, &param);
        cr_op op = cr_nn_act_fused_op(act, param);
        if (!mlp->ln_weight[i] && op != CR_OP_COUNT) { /* one op: GEMM, bias, activation */
            const cr_linear *l = &mlp->layer[i];
            cr_tensor *a = cr_nn_linear_act(ctx, h, l->weight, l->bias, op, param);
            h = cr_mlp_layer_residual(def, i) ? cr_nn_add(ctx, h, a) : a;
            continue;
        }
        cr_tensor *z = cr_linear_forward(ctx, &mlp->layer[i], h);
        if (mlp->ln_weight[i])
            z = cr_nn_layer_norm(ctx, z, mlp->ln_weight[i], mlp->ln_bias[i], def->ln_eps);
        cr_tensor *a = cr_act_forward(ctx, act, param, z);
        h = cr_mlp_layer_residual(def, i) ? cr_nn_add(ctx, h, a) : a;
    }
    return h;
}
