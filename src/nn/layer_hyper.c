/* layer_hyper.c: a hyper-network: a generator MLP maps per-group features to
 * the weights of a small target MLP, evaluated on each group's own points
 * (GDSR's per-triangle implicit functions, paper 001 sec. 4.4).
 *
 * theta (G,P) holds, per group and per target layer in order, the weight
 * (OUT,IN) row-major then the bias (OUT): the order in which cr_mlp adds its
 * parameters, so a target initialised as a cr_mlp can be copied in flat.
 * Per target layer the rows x (M,IN) of all groups go through one
 * cr_nn_matmul_grouped against the layer's weight slice viewed as (G,OUT,IN)
 * (trans_w), and each row's bias is gathered by its group id. Every step is a
 * tape op, so gradients reach the generator's parameters, h and x.
 *
 * Initialisation: the generator's last layer starts with small weights
 * (scaled by head_scale) and a bias holding one properly initialised target,
 * so at the start every group's network is close to a standard init and the
 * features h only perturb it (the SIREN code's hyper_weight_init divides the
 * head's weights by 100 for the same reason).
 * Leaves out: complex (WIRE) target layers, layer norm or residuals in the
 * target; a method needing them slices theta and composes the layers itself.
 * References: Ha, Dai & Le, HyperNetworks, ICLR 2017; Sitzmann et al. 2020
 * (SIREN, meta_modules.py); GDSR (paper 001).
 */
#include "crease/nn_layers.h"
#include "nn/tape.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { HYPER_COOKIE = 0x48595031u /* "HYP1" */ };

cr_hyper_def cr_hyper_default_def(void) {
    cr_hyper_def d;
    memset(&d, 0, sizeof d);
    d.generator = cr_mlp_default_def();
    d.target = cr_mlp_default_def();
    d.head_scale = 0.01f;
    d.cookie = HYPER_COOKIE;
    return d;
}

/* Copy one freshly initialised target into the head's bias and shrink the
 * head's weights. */
static cr_status init_head(const cr_hyper_def *def, cr_linear *head, cr_rng *rng, cr_error *err) {
    cr_nn_params *tmp = NULL;
    cr_mlp *target = NULL;
    CR_TRY(cr_nn_params_create(&tmp, err));
    cr_status st = cr_mlp_create(&def->target, tmp, "", rng, &target, err);
    if (st == CR_OK) {
        float *b = head->bias->data;
        int64_t off = 0;
        for (int i = 0; i < cr_nn_params_count(tmp); i++) {
            const cr_tensor *t = cr_nn_params_at(tmp, i, NULL);
            memcpy(b + off, t->data, (size_t)t->numel * sizeof(float));
            off += t->numel;
        }
        CR_ASSERT(off == head->bias->numel);
        for (int64_t k = 0; k < head->weight->numel; k++)
            head->weight->data[k] *= def->head_scale;
    }
    cr_mlp_destroy(target);
    cr_nn_params_destroy(tmp);
    return st;
}

cr_status cr_hyper_create(const cr_hyper_def *def, cr_nn_params *params, const char *prefix,
                          cr_rng *rng, cr_hyper **out, cr_error *err) {
    CR_ASSERT(def && def->cookie == HYPER_COOKIE && params && rng && out);
    *out = NULL;
    CR_TRY(cr_mlp_def_validate(&def->target, err));
    if (def->target.layer_norm || def->target.residual)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "hyper: the target MLP cannot have layer_norm or residual");
    int64_t P = cr_mlp_param_count(&def->target);
    if (P > INT_MAX)
        return CR_FAIL(err, CR_ERR_INVALID, "hyper: target has %lld parameters, too many",
                       (long long)P);
    cr_hyper *hn = cr_calloc(1, sizeof *hn, err);
    if (!hn) return CR_ERR_MEMORY;
    hn->def = *def;
    hn->nparams = P;
    cr_mlp_def *gen = &hn->def.generator;
    cr_status st = CR_OK;
    if (gen->nlayers >= 1 && gen->nlayers <= CR_MLP_MAX_LAYERS) gen->widths[gen->nlayers] = (int)P;
    char name[128];
    int n = prefix && *prefix ? snprintf(name, sizeof name, "%s.gen", prefix)
                              : snprintf(name, sizeof name, "gen");
    if (n < 0 || n >= (int)sizeof name)
        st = CR_FAIL(err, CR_ERR_INVALID, "hyper: prefix \"%s\" is too long", prefix);
    if (st == CR_OK) st = cr_mlp_create(gen, params, name, rng, &hn->generator, err);
    if (st == CR_OK) st = init_head(def, &hn->generator->layer[gen->nlayers - 1], rng, err);
    if (st != CR_OK) {
        cr_hyper_destroy(hn);
        return st;
    }
    *out = hn;
    return CR_OK;
}

void cr_hyper_destroy(cr_hyper *hn) {
    if (!hn) return;
    cr_mlp_destroy(hn->generator);
    free(hn);
}

cr_tensor *cr_hyper_eval_target(cr_nn_ctx *ctx, const cr_mlp_def *target, cr_tensor *theta,
                                cr_tensor *x, const int32_t *group) {
    CR_ASSERT(target->nlayers >= 1 && target->nlayers <= CR_MLP_MAX_LAYERS && !target->layer_norm &&
              !target->residual);
    if (!cr_nn_begin(ctx, "hyper_eval_target", 2, (cr_tensor *const[]){theta, x})) return NULL;
    int64_t G = theta->shape[0], M = x->shape[0];
    /* A theta of the wrong width fails here with both shapes in the message. */
    theta = cr_nn_reshape(ctx, theta, 2, (int64_t[]){G, cr_mlp_param_count(target)});
    cr_tensor *h = x;
    int64_t off = 0;
    for (int i = 0; i < target->nlayers; i++) {
        int64_t in = target->widths[i], out = target->widths[i + 1];
        cr_tensor *w = cr_nn_reshape(ctx, cr_nn_slice(ctx, theta, 1, off, out * in), 3,
                                     (int64_t[]){G, out, in});
        cr_tensor *b = cr_nn_slice(ctx, theta, 1, off + out * in, out); /* (G,OUT) */
        off += out * in + out;
        cr_tensor *z = cr_nn_add(ctx, cr_nn_matmul_grouped(ctx, h, w, group, 1),
                                 cr_nn_gather_rows(ctx, b, group, M));
        float param;
        cr_act act = cr_mlp_layer_act(target, i, &param);
        h = cr_act_forward(ctx, act, param, z);
    }
    return h;
}

cr_tensor *cr_hyper_forward(cr_nn_ctx *ctx, const cr_hyper *hn, cr_tensor *h, cr_tensor *x,
                            const int32_t *group, cr_tensor **theta_out) {
    cr_tensor *theta = cr_mlp_forward(ctx, hn->generator, h); /* (G,P) */
    if (theta_out) *theta_out = theta;
    return cr_hyper_eval_target(ctx, &hn->def.target, theta, x, group);
}
