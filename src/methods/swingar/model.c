/* model.c: SwinGar's dynamic deformation estimator (paper 002, sec. III-C,
 * IV): the encoders, the dynamic skinning weights and blend shapes, linear
 * blend skinning with the body's skeleton, and the LSTM-GAT-LN corrective
 * shapes. The information flow is drawn in include/crease/swingar.h; the
 * choices the paper leaves open are in docs/swingar_model.md. */
#include "swingar_internal.h"

#include "crease/body.h"
#include "crease/garment.h"
#include "crease/nn_layers.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SWG_COOKIE 0x53574731u

cr_swingar_def cr_swingar_default_def(void) {
    cr_swingar_def d;
    memset(&d, 0, sizeof d);
    d.descriptor_len = 256;
    d.garment_width[0] = 64, d.garment_width[1] = 128;
    d.garment_heads = 24;
    d.shape_width[0] = 256, d.shape_width[1] = 128, d.shape_width[2] = 24;
    d.motion_window = 64;
    d.motion_hidden = 128;
    d.body_width[0] = 256, d.body_width[1] = 128, d.body_width[2] = 64;
    d.state_width = 128;
    d.state_heads = 24;
    d.blend_width[0] = 256, d.blend_width[1] = 128;
    d.blend_heads = 3;
    d.corr_hidden = 64;
    d.corr_heads = 8;
    d.corr_width = 64;
    d.alpha = 2.0f;
    d.norm = CR_GAT_NORM_GLOBAL;
    d.skin_prior = 1;
    d.use_descriptor = 1;
    d.zero_last = 1;
    d.corr_scale = 0.1f;
    d.cookie = SWG_COOKIE;
    return d;
}

cr_status cr_swingar_size_def(const char *size, cr_swingar_def *d, cr_error *err) {
    if (!size || !d) return CR_FAIL(err, CR_ERR_INVALID, "swingar: NULL size or def");
    if (strcmp(size, "paper") == 0) return CR_OK;
    if (strcmp(size, "cpu") == 0) {
        d->garment_heads = 4, d->state_heads = 4;
    } else if (strcmp(size, "tiny") == 0) {
        d->descriptor_len = 16;
        d->garment_width[0] = 8, d->garment_width[1] = 12, d->garment_heads = 2;
        d->shape_width[0] = 16, d->shape_width[1] = 8, d->shape_width[2] = 4;
        d->motion_window = 8, d->motion_hidden = 12;
        d->body_width[0] = 16, d->body_width[1] = 8, d->body_width[2] = 8;
        d->state_width = 12, d->state_heads = 2;
        d->blend_width[0] = 8, d->blend_width[1] = 12, d->blend_heads = 2;
        d->corr_hidden = 8, d->corr_heads = 2, d->corr_width = 8;
    } else {
        return CR_FAIL(err, CR_ERR_INVALID, "swingar: unknown size '%s' (paper, cpu or tiny)",
                       size);
    }
    return CR_OK;
}

static int pos_int(int v) {
    return v >= 1 && v <= 65536;
}

cr_status cr_swingar_def_validate(const cr_swingar_def *d, cr_error *err) {
    if (!d || d->cookie != SWG_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar: def not made by cr_swingar_default_def");
#define SWG_CHECK(cond, field)                                                                     \
    if (!(cond)) return CR_FAIL(err, CR_ERR_INVALID, "swingar: bad %s", field)
    SWG_CHECK(pos_int(d->descriptor_len), "descriptor_len");
    SWG_CHECK(pos_int(d->garment_width[0]) && pos_int(d->garment_width[1]), "garment_width");
    SWG_CHECK(pos_int(d->garment_heads), "garment_heads");
    for (int i = 0; i < 3; i++) {
        SWG_CHECK(pos_int(d->shape_width[i]), "shape_width");
        SWG_CHECK(pos_int(d->body_width[i]), "body_width");
    }
    SWG_CHECK(pos_int(d->motion_window), "motion_window");
    SWG_CHECK(pos_int(d->motion_hidden), "motion_hidden");
    SWG_CHECK(pos_int(d->state_width) && pos_int(d->state_heads), "state_width/state_heads");
    SWG_CHECK(pos_int(d->blend_width[0]) && pos_int(d->blend_width[1]), "blend_width");
    SWG_CHECK(pos_int(d->blend_heads), "blend_heads");
    SWG_CHECK(pos_int(d->corr_hidden) && pos_int(d->corr_heads) && pos_int(d->corr_width),
              "corr_hidden/corr_heads/corr_width");
    SWG_CHECK(isfinite(d->alpha) && d->alpha >= 0, "alpha");
    SWG_CHECK(d->norm >= CR_GAT_NORM_NONE && d->norm <= CR_GAT_NORM_RECEIVER, "norm");
    SWG_CHECK(isfinite(d->corr_scale) && d->corr_scale > 0, "corr_scale");
    SWG_CHECK(d->affinity == 0 || d->affinity == 1, "affinity");
#undef SWG_CHECK
    /* The element-wise products of the paper fix three pairs of widths. */
    if (d->garment_width[1] != d->motion_hidden)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar: garment_width[1] (%d) must equal motion_hidden (%d): E_s reads "
                       "their product",
                       d->garment_width[1], d->motion_hidden);
    if (d->blend_width[1] != d->motion_hidden)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar: blend_width[1] (%d) must equal motion_hidden (%d)",
                       d->blend_width[1], d->motion_hidden);
    if (d->body_width[2] != d->corr_hidden)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar: body_width[2] (%d) must equal corr_hidden (%d)", d->body_width[2],
                       d->corr_hidden);
    if ((4 * d->corr_hidden) % d->corr_heads != 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar: 4 corr_hidden (%d) must be a multiple of corr_heads (%d)",
                       4 * d->corr_hidden, d->corr_heads);
    return CR_OK;
}

/* One GAT-LN layer as the paper uses them: tanh, heads averaged. */
static cr_status gat_make(const cr_swingar_def *d, int in, int out, int heads, cr_act act,
                          cr_nn_params *P, const char *name, cr_rng *rng, cr_gat *g,
                          cr_error *err) {
    cr_gat_def gd = cr_gat_default_def();
    gd.input = in, gd.out = out, gd.heads = heads, gd.concat = 0;
    gd.alpha = d->alpha, gd.norm = d->norm, gd.act = act;
    return cr_gat_create(&gd, P, name, rng, g, err);
}

static cr_status mlp_make(int in, const int w[3], cr_nn_params *P, const char *name, cr_rng *rng,
                          cr_mlp **out, cr_error *err) {
    cr_mlp_def md = cr_mlp_default_def();
    md.nlayers = 3;
    md.widths[0] = in, md.widths[1] = w[0], md.widths[2] = w[1], md.widths[3] = w[2];
    md.act = CR_ACT_RELU;
    md.init = CR_INIT_KAIMING_UNIFORM; /* the paper's Kaiming for fully connected layers */
    return cr_mlp_create(&md, P, name, rng, out, err);
}

cr_status cr_swingar_create(const cr_swingar_def *def, uint64_t seed, cr_swingar **out,
                            cr_error *err) {
    *out = NULL;
    CR_TRY(cr_swingar_def_validate(def, err));
    cr_swingar *m = calloc(1, sizeof *m);
    if (!m) return CR_FAIL(err, CR_ERR_MEMORY, "swingar: out of memory");
    m->def = *def;
    const cr_swingar_def *d = &m->def;
    cr_rng rng = cr_rng_make(seed, 20);
    cr_status st = cr_nn_params_create(&m->P, err);
    cr_nn_params *P = m->P;
    /* garment information */
    if (st == CR_OK)
        st = gat_make(d, SWG_VERTEX_FEATURES, d->garment_width[0], d->garment_heads, CR_ACT_TANH, P,
                      "garment.0", &rng, &m->g0, err);
    if (st == CR_OK)
        st = gat_make(d, d->garment_width[0], d->garment_width[1], d->garment_heads, CR_ACT_TANH, P,
                      "garment.1", &rng, &m->g1, err);
    if (st == CR_OK)
        st = mlp_make(d->descriptor_len, d->shape_width, P, "shape", &rng, &m->shape, err);
    /* the descriptor's standardisation, frozen: set from the training garments
     * (cr_swingar_standardise_descriptor_); until then times z, the eigenvalues
     * summing to about 1 (descriptor.h), so its entries are of order 1 */
    if (st == CR_OK)
        st = cr_nn_params_add(P, "descriptor.mean", 1, (int64_t[]){d->descriptor_len},
                              &m->desc_mean, err);
    if (st == CR_OK)
        st = cr_nn_params_add(P, "descriptor.std", 1, (int64_t[]){d->descriptor_len}, &m->desc_std,
                              err);
    /* body information */
    if (st == CR_OK) {
        cr_rnn_def rd = cr_rnn_default_def();
        rd.input = SWG_POSE_FEATURES, rd.hidden = d->motion_hidden;
        st = cr_lstm_cell_create(&rd, P, "motion", &rng, &m->motion, err);
    }
    if (st == CR_OK)
        st = mlp_make(SWG_BODY_FEATURES, d->body_width, P, "body", &rng, &m->body, err);
    /* dynamic garment */
    if (st == CR_OK)
        st = gat_make(d, d->garment_width[1], d->state_width, d->state_heads, CR_ACT_TANH, P,
                      "state", &rng, &m->state, err);
    if (st == CR_OK) {
        cr_linear_def ld = cr_linear_default_def();
        ld.in = d->shape_width[2], ld.out = d->state_width * CR_NJOINTS;
        st = cr_linear_create(&ld, P, "skin", &rng, &m->skin, err);
    }
    if (st == CR_OK)
        st = gat_make(d, d->state_width, d->blend_width[0], d->blend_heads, CR_ACT_TANH, P,
                      "blend.0", &rng, &m->b0, err);
    if (st == CR_OK)
        st = gat_make(d, d->blend_width[0], d->blend_width[1], d->blend_heads, CR_ACT_TANH, P,
                      "blend.1", &rng, &m->b1, err);
    if (st == CR_OK) {
        cr_linear_def ld = cr_linear_default_def();
        ld.in = d->blend_width[1], ld.out = 3;
        st = cr_linear_create(&ld, P, "blend.out", &rng, &m->bout, err);
    }
    if (st == CR_OK) {
        cr_gat_lstm_def gl = cr_gat_lstm_default_def();
        gl.input = SWG_CORR_FEATURES, gl.hidden = d->corr_hidden;
        gl.gat.heads = d->corr_heads, gl.gat.concat = 1;
        gl.gat.alpha = d->alpha, gl.gat.norm = d->norm;
        st = cr_gat_lstm_create(&gl, P, "corr.lstm", &rng, &m->corr, err);
    }
    if (st == CR_OK)
        st = gat_make(d, d->corr_hidden, d->corr_width, 1, CR_ACT_TANH, P, "corr.0", &rng, &m->c0,
                      err);
    if (st == CR_OK)
        st = gat_make(d, d->corr_width, 3, 1, CR_ACT_TANH, P, "corr.1", &rng, &m->c1, err);
    if (st != CR_OK) {
        cr_swingar_destroy(m);
        return st;
    }
    /* the adds may have moved the block: look both up again */
    m->desc_mean = cr_nn_params_find(P, "descriptor.mean");
    m->desc_std = cr_nn_params_find(P, "descriptor.std");
    m->desc_mean->requires_grad = m->desc_std->requires_grad = 0;
    cr_nn_fill(m->desc_std, 1.0f / (float)d->descriptor_len);
    if (d->zero_last) {
        cr_nn_fill(m->skin.weight, 0.0f);
        cr_nn_fill(m->bout.weight, 0.0f);
        cr_nn_fill(m->c1.lin.weight, 0.0f);
    }
    *out = m;
    return CR_OK;
}

void cr_swingar_destroy(cr_swingar *m) {
    if (!m) return;
    cr_mlp_destroy(m->shape);
    cr_mlp_destroy(m->body);
    cr_nn_params_destroy(m->P);
    free(m);
}

const cr_swingar_def *cr_swingar_get_def(const cr_swingar *m) {
    return &m->def;
}
cr_nn_params *cr_swingar_params(cr_swingar *m) {
    return m->P;
}

/* ------------------------------------------------------------ forward -- */

static int32_t clampi(int32_t v, int32_t lo, int32_t hi) {
    return v < lo ? lo : v > hi ? hi : v;
}

/* theta of frame f: the 66 axis-angles and the root's move since f - 1
 * (times SWG_TRANS_SCALE, so it is of the order of the angles). */
static void pose_features(const cr_swingar_motion *mo, int32_t f, float *out) {
    int32_t T = mo->nframes;
    int32_t a = clampi(f, 0, T - 1), b = clampi(f - 1, 0, T - 1);
    memcpy(out, mo->poses + (size_t)a * CR_NJOINTS * 3, sizeof(float) * CR_NJOINTS * 3);
    for (int k = 0; k < 3; k++)
        out[CR_NJOINTS * 3 + k] =
            f <= 0 ? 0.0f : SWG_TRANS_SCALE * (mo->trans[3 * a + k] - mo->trans[3 * b + k]);
}

/* (V,J) logits -> row-wise softmax through the engine's segment softmax. */
static cr_tensor *row_softmax(cr_nn_ctx *ctx, cr_tensor *logits, int64_t V, int64_t J) {
    int32_t *seg = cr_nn_scratch(ctx, "swingar skin softmax", sizeof(int32_t) * (size_t)(V * J));
    if (!seg || !logits) return NULL;
    for (int64_t i = 0; i < V * J; i++)
        seg[i] = (int32_t)(i / J);
    cr_tensor *flat = cr_nn_reshape(ctx, logits, 1, (int64_t[]){V * J});
    cr_tensor *w = cr_nn_segment_softmax(ctx, flat, seg, V);
    return cr_nn_reshape(ctx, w, 2, (int64_t[]){V, J});
}

/* Stack n tensors of one shape along a new leading axis. */
static cr_tensor *stack(cr_nn_ctx *ctx, cr_tensor **ts, int n) {
    cr_tensor *v[64];
    if (n > 64) return NULL;
    for (int i = 0; i < n; i++) {
        if (!ts[i]) return NULL;
        int64_t shape[CR_NN_MAX_DIMS] = {1};
        for (int k = 0; k < ts[i]->ndim; k++)
            shape[k + 1] = ts[i]->shape[k];
        v[i] = cr_nn_reshape(ctx, ts[i], ts[i]->ndim + 1, shape);
    }
    return cr_nn_concat(ctx, n, v, 0);
}

cr_status cr_swingar_standardise_descriptor_(cr_swingar *m, const cr_swingar_data *d,
                                             const int8_t *is_test, cr_error *err) {
    const int z = m->def.descriptor_len;
    int8_t *used = cr_calloc((size_t)(d->ngarments > 0 ? d->ngarments : 1), 1, err);
    if (!used) return err ? err->status : CR_ERR_MEMORY;
    int n = 0;
    for (int32_t i = 0; i < d->nsequences; i++) {
        int32_t g = d->sequences[i].garment_index;
        if ((!is_test || is_test[i] == 0) && g >= 0 && g < d->ngarments && !used[g])
            used[g] = 1, n++;
    }
    for (int k = 0; k < z && n > 0; k++) {
        double s = 0, q = 0;
        for (int32_t g = 0; g < d->ngarments; g++)
            if (used[g]) s += d->garments[g]->descriptor[k];
        const double mean = s / n;
        for (int32_t g = 0; g < d->ngarments; g++)
            if (used[g])
                q +=
                    (d->garments[g]->descriptor[k] - mean) * (d->garments[g]->descriptor[k] - mean);
        m->desc_mean->data[k] = (float)mean;
        m->desc_std->data[k] = (float)fmax(fmax(sqrt(q / n), 1e-3 * fabs(mean)), 1e-12);
    }
    free(used);
    return CR_OK;
}

/* ------------------------------------- skinning for inference (no tape) -- */

/* Skinning weights, linear blend skinning and the joint distances of eq. 6
 * in one pass over the vertices, for the gradient-off forward; the tape
 * path builds the same values from a (V,J,3) broadcast product and an axis
 * sum. Per vertex v:
 *   W_v  = softmax_j(logits_vj + logw0_vj)
 *   M_v  = sum_j W_vj [A_j | b_j]     (3,4): blend the transforms, then
 *   x'_v = M_v (rest_v + B_v, 1)      apply them once
 *   d_vj = |x'_v - joint_j|
 * in: logits (V,J), logw0 (V,J), rest (V,3), B (V,3), xf (J,12) the joints'
 * [A|b] rows, jpos (J,3); out: W (V,J), coarse (V,3), feat (V,3+J). */
typedef struct skin_pass {
    cr_tensor *const *in, *const *out;
} skin_pass;

static void skin_range(void *vctx, int64_t begin, int64_t end) {
    const skin_pass *sp = vctx;
    const int J = CR_NJOINTS;
    const float *logits = sp->in[0]->data, *logw0 = sp->in[1]->data, *rest = sp->in[2]->data;
    const float *B = sp->in[3]->data, *xf = sp->in[4]->data, *jpos = sp->in[5]->data;
    float *W = sp->out[0]->data, *coarse = sp->out[1]->data, *feat = sp->out[2]->data;
    for (int64_t v = begin; v < end; v++) {
        float *w = W + v * J, mx = -INFINITY;
        for (int j = 0; j < J; j++) {
            w[j] = logits[v * J + j] + logw0[v * J + j];
            mx = w[j] > mx ? w[j] : mx;
        }
        double sum = 0.0;
        for (int j = 0; j < J; j++) {
            w[j] = expf(w[j] - mx);
            sum += w[j];
        }
        float M[12] = {0};
        for (int j = 0; j < J; j++) {
            w[j] = (float)(w[j] / sum);
            for (int k = 0; k < 12; k++)
                M[k] += w[j] * xf[j * 12 + k];
        }
        float x[3], *y = coarse + v * 3, *f = feat + v * SWG_CORR_FEATURES;
        for (int r = 0; r < 3; r++)
            x[r] = rest[v * 3 + r] + B[v * 3 + r];
        for (int r = 0; r < 3; r++)
            y[r] = f[r] =
                M[r * 4] * x[0] + M[r * 4 + 1] * x[1] + M[r * 4 + 2] * x[2] + M[r * 4 + 3];
        for (int j = 0; j < J; j++) {
            double d0 = y[0] - jpos[j * 3], d1 = y[1] - jpos[j * 3 + 1],
                   d2 = y[2] - jpos[j * 3 + 2];
            f[3 + j] = (float)sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        }
    }
}

static cr_status skin_forward(const cr_fused_op *def, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                              cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)def, (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    skin_pass sp = {in, out};
    cr_parallel_for(in[0]->shape[0], 512, skin_range, &sp);
    return CR_OK;
}

/* Forward only: no backward, so the engine refuses it on inputs that need a gradient. */
static const cr_fused_op skin_op = {"swingar skinning (inference)", skin_forward, NULL, NULL};

/* Returns coarse (V,3) and sets *W (V,J) and *feat (V,3+J); NULL on error. */
static cr_tensor *skin_infer(cr_nn_ctx *ctx, cr_tensor *logits, cr_tensor *logw0, cr_tensor *rest,
                             cr_tensor *B, const float *xf, const float *jpos, cr_tensor **W,
                             cr_tensor **feat) {
    const int64_t V = rest->shape[0], J = CR_NJOINTS;
    cr_tensor *in[6] = {logits,
                        logw0,
                        rest,
                        B,
                        cr_nn_from(ctx, 2, (int64_t[]){J, 12}, xf),
                        cr_nn_from(ctx, 2, (int64_t[]){J, 3}, jpos)};
    for (int i = 0; i < 6; i++)
        if (!in[i]) return NULL;
    cr_nn_shape shapes[3] = {{2, {V, J}}, {2, {V, 3}}, {2, {V, SWG_CORR_FEATURES}}};
    cr_tensor *out[3];
    if (!cr_nn_fused(ctx, &skin_op, 6, in, 3, shapes, out)) return NULL;
    *W = out[0], *feat = out[2];
    return out[1];
}

int cr_swingar_encode_garment_(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                               swg_genc *e) {
    const cr_swingar_def *d = &m->def;
    const int64_t V = g->rest->nv, J = CR_NJOINTS;
    cr_nn_graph graph = {V, 2 * (int64_t)g->nedges, g->senders, g->receivers};
    cr_tensor *feat = cr_nn_wrap(ctx, 2, (int64_t[]){V, SWG_VERTEX_FEATURES}, g->features);
    e->G =
        cr_gat_forward(ctx, &m->g1, cr_gat_forward(ctx, &m->g0, feat, &graph, NULL), &graph, NULL);
    cr_tensor *desc = d->use_descriptor
                          ? cr_nn_wrap(ctx, 2, (int64_t[]){1, d->descriptor_len}, g->descriptor)
                          : cr_nn_zeros(ctx, 2, (int64_t[]){1, d->descriptor_len});
    cr_tensor *s = cr_mlp_forward(ctx, m->shape,
                                  cr_nn_div(ctx, cr_nn_sub(ctx, desc, m->desc_mean), m->desc_std));
    e->skinmat =
        cr_nn_reshape(ctx, cr_linear_forward(ctx, &m->skin, s), 2, (int64_t[]){d->state_width, J});
    e->logw0 = cr_nn_new(ctx, 2, (int64_t[]){V, J});
    if (!e->G || !e->skinmat || !e->logw0) return 0;
    for (int64_t i = 0; i < V * J; i++)
        e->logw0->data[i] = d->skin_prior ? logf(g->skin_weight[i] + SWG_SKIN_FLOOR) : 0.0f;
    return 1;
}

cr_tensor *cr_swingar_forward_frames_(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                                      const swg_genc *e, const cr_swingar_motion *mo, int32_t t0,
                                      int32_t K, float *prev, float *next,
                                      cr_swingar_parts *parts) {
    const cr_swingar_def *d = &m->def;
    const int64_t V = g->rest->nv, J = CR_NJOINTS;
    const int32_t Kc = K + 2; /* coarse frames t0-2 .. t0+K-1 */
    cr_nn_graph graph = {V, 2 * (int64_t)g->nedges, g->senders, g->receivers};
    cr_tensor *G = e->G, *skinmat = e->skinmat, *logw0 = e->logw0;

    /* body information for every coarse frame computed here (the first two
     * come with prev): the motion LSTM over m poses, the body encoder on
     * [beta, theta^t]; row k - k0 is coarse frame k */
    const int W = d->motion_window;
    const int32_t k0 = prev ? 2 : 0, Kb = Kc - k0;
    cr_tensor *seq = cr_nn_new(ctx, 3, (int64_t[]){W, Kb, SWG_POSE_FEATURES});
    cr_tensor *bin = cr_nn_new(ctx, 2, (int64_t[]){Kb, SWG_BODY_FEATURES});
    if (!seq || !bin) return NULL;
    for (int32_t k = k0; k < Kc; k++) {
        int32_t f = t0 - 2 + k;
        for (int w = 0; w < W; w++)
            pose_features(mo, f - (W - 1) + w,
                          seq->data + ((size_t)w * Kb + (k - k0)) * SWG_POSE_FEATURES);
        float *b = bin->data + (size_t)(k - k0) * SWG_BODY_FEATURES;
        memcpy(b, mo->joints, sizeof(float) * J * 3);
        pose_features(mo, f, b + J * 3);
    }
    cr_tensor *mfeat = NULL;
    cr_lstm_forward(ctx, &m->motion, seq, NULL, NULL, &mfeat, NULL); /* (Kb, H) */
    cr_tensor *bfeat = cr_mlp_forward(ctx, m->body, bin);            /* (Kb, 64) */

    /* rest positions in homogeneous form, (V,4) */
    cr_tensor *rest = cr_nn_wrap(ctx, 2, (int64_t[]){V, 3}, g->rest->pos);
    cr_tensor *ones = cr_nn_full(ctx, 2, (int64_t[]){V, 1}, 1.0f);

    cr_tensor *coarse_feat[SWG_MAX_WINDOW + 2], *coarse[SWG_MAX_WINDOW + 2];
    cr_tensor *skin[SWG_MAX_WINDOW + 2];
    const int64_t fsz = V * SWG_CORR_FEATURES;
    for (int32_t k = 0; k < Kc; k++) {
        if (prev && k < 2) { /* computed by the call before */
            coarse_feat[k] = cr_nn_wrap(ctx, 2, (int64_t[]){V, SWG_CORR_FEATURES}, prev + k * fsz);
            coarse[k] = skin[k] = NULL;
            continue;
        }
        if (k > 0 && t0 - 2 + k <= 0) { /* frames before 0 are frame 0 (pose, window): one copy */
            coarse_feat[k] = coarse_feat[k - 1], coarse[k] = coarse[k - 1], skin[k] = skin[k - 1];
            continue;
        }
        int32_t f = clampi(t0 - 2 + k, 0, mo->nframes - 1);
        const float *pose = mo->poses + (size_t)f * J * 3;
        cr_tensor *mk = cr_nn_slice(ctx, mfeat, 0, k - k0, 1); /* (1,H) */
        cr_tensor *q = cr_gat_forward(ctx, &m->state, cr_nn_mul(ctx, G, mk), &graph, NULL);
        /* unposed blend shape B^t */
        cr_tensor *bb =
            cr_gat_forward(ctx, &m->b1, cr_gat_forward(ctx, &m->b0, q, &graph, NULL), &graph, NULL);
        cr_tensor *B = cr_linear_forward(ctx, &m->bout, cr_nn_mul(ctx, bb, mk));
        /* linear blend skinning, rest joints' transforms without the root's
         * translation, and the posed joints of eq. 6 */
        float xf[CR_NJOINTS * 12], jpos[CR_NJOINTS * 3];
        cr_body_skin_transforms(mo->joints, pose, NULL, xf);
        cr_body_forward_kinematics(mo->joints, pose, NULL, NULL, jpos);
        /* dynamic skinning weights W^t = softmax(prior + q . (A s)) */
        cr_tensor *logits = cr_nn_matmul(ctx, q, skinmat, 0, 0);
        if (!cr_nn_ctx_grad_enabled(ctx)) {
            if (!logits || !B) return NULL;
            coarse[k] =
                skin_infer(ctx, logits, logw0, rest, B, xf, jpos, &skin[k], &coarse_feat[k]);
            if (!coarse[k]) return NULL;
            continue;
        }
        cr_tensor *Wt = row_softmax(ctx, cr_nn_add(ctx, logits, logw0), V, J);
        skin[k] = Wt;
        /* X (V,4) x [A_j | b_j]^T for all joints (4, 3J) */
        cr_tensor *Mt = cr_nn_new(ctx, 2, (int64_t[]){4, 3 * J});
        if (!Mt) return NULL;
        for (int64_t j = 0; j < J; j++)
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 4; c++)
                    Mt->data[c * 3 * J + j * 3 + r] = xf[j * 12 + r * 4 + c];
        cr_tensor *xh = cr_nn_concat(ctx, 2, (cr_tensor *[]){cr_nn_add(ctx, rest, B), ones}, 1);
        cr_tensor *Y = cr_nn_reshape(ctx, cr_nn_matmul(ctx, xh, Mt, 0, 0), 3, (int64_t[]){V, J, 3});
        cr_tensor *Wr = cr_nn_reshape(ctx, Wt, 3, (int64_t[]){V, J, 1});
        cr_tensor *Mc = cr_nn_reshape(ctx, cr_nn_sum_axis(ctx, cr_nn_mul(ctx, Y, Wr), 1, 0), 2,
                                      (int64_t[]){V, 3});
        coarse[k] = Mc;
        /* the graph M_c^t of eq. 6: positions and distances to the posed joints */
        cr_tensor *jt = cr_nn_from(ctx, 3, (int64_t[]){1, J, 3}, jpos);
        cr_tensor *dj = cr_nn_norm(
            ctx, cr_nn_sub(ctx, cr_nn_reshape(ctx, Mc, 3, (int64_t[]){V, 1, 3}), jt), 1e-12f);
        coarse_feat[k] = cr_nn_concat(
            ctx, 2, (cr_tensor *[]){Mc, cr_nn_reshape(ctx, dj, 2, (int64_t[]){V, J})}, 1);
    }

    /* corrective shapes over the three consecutive graphs, then translation */
    cr_tensor *outs[SWG_MAX_WINDOW], *coarse_out[SWG_MAX_WINDOW];
    for (int32_t k = 0; k < K; k++) {
        int32_t f = clampi(t0 + k, 0, mo->nframes - 1);
        cr_tensor *x3 = stack(ctx, coarse_feat + k, 3); /* (3,V,25) */
        cr_tensor *h = NULL;
        cr_gat_lstm_forward(ctx, &m->corr, x3, &graph, NULL, NULL, &h, NULL);
        cr_tensor *hb = cr_nn_mul(ctx, h, cr_nn_slice(ctx, bfeat, 0, k + 2 - k0, 1));
        cr_tensor *D = cr_nn_mul_scalar(
            ctx,
            cr_gat_forward(ctx, &m->c1, cr_gat_forward(ctx, &m->c0, hb, &graph, NULL), &graph,
                           NULL),
            d->corr_scale);
        cr_tensor *tr = cr_nn_from(ctx, 2, (int64_t[]){1, 3}, mo->trans + 3 * (size_t)f);
        coarse_out[k] = cr_nn_add(ctx, coarse[k + 2], tr);
        outs[k] = cr_nn_add(ctx, coarse_out[k], D);
    }
    if (next)
        for (int k = 0; k < 2; k++) {
            if (!coarse_feat[Kc - 2 + k]) return NULL;
            memmove(next + k * fsz, coarse_feat[Kc - 2 + k]->data, sizeof(float) * (size_t)fsz);
        }
    if (parts) {
        parts->skin = stack(ctx, skin + 2, K);
        parts->coarse = stack(ctx, coarse_out, K);
    }
    return stack(ctx, outs, K);
}

cr_tensor *cr_swingar_forward(cr_nn_ctx *ctx, cr_swingar *m, const cr_swingar_garment *g,
                              const cr_swingar_motion *mo, int32_t t0, int32_t K,
                              cr_swingar_parts *parts) {
    if (!g || !mo || K < 1 || K > SWG_MAX_WINDOW || mo->nframes < 1) return NULL;
    swg_genc e;
    if (!cr_swingar_encode_garment_(ctx, m, g, &e)) return NULL;
    return cr_swingar_forward_frames_(ctx, m, g, &e, mo, t0, K, NULL, NULL, parts);
}

cr_status cr_swingar_garment_of_(const cr_swingar *m, const cr_garment *garment, const char *source,
                                 const cr_body_model *b, cr_swingar_garment **out, cr_error *err) {
    const cr_swingar_def *d = &m->def;
    float *desc = calloc((size_t)d->descriptor_len, sizeof(float));
    if (!desc) return CR_FAIL(err, CR_ERR_MEMORY, "swingar: out of memory");
    cr_status st = CR_OK;
    if (d->use_descriptor && cr_swingar_compute_descriptor(garment->mesh, d->descriptor_len,
                                                           d->affinity, desc, err) != CR_OK)
        st = CR_FAIL(err, err ? err->status : CR_ERR_INVALID, "%s: %s", source,
                     err ? err->msg : "descriptor");
    if (st == CR_OK)
        st = cr_swingar_garment_create(garment->mesh, garment->skin_joint, garment->skin_weight, b,
                                       desc, d->descriptor_len, out, err);
    free(desc);
    return st;
}

cr_status cr_swingar_animate(cr_swingar *m, const cr_garment *garment, const char *source,
                             const cr_body_model *b, const cr_motion *mo, size_t arena_bytes,
                             float *out, cr_error *err) {
    cr_swingar_garment *sg = NULL;
    cr_status st = cr_swingar_garment_of_(m, garment, source, b, &sg, err);
    cr_swingar_motion sm = {mo->nframes, b->joints, mo->poses, mo->trans};
    if (st == CR_OK) st = cr_swingar_predict(m, sg, &sm, arena_bytes, out, err);
    cr_swingar_garment_destroy(sg);
    return st;
}
