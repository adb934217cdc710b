/* model.c: gdsr's networks: Mesh-Graph-Net H (sec. 4.2, Eq. 6-7), the
 * local-frame decoder E (sec. 4.3, Eq. 8-9) and the Mesh-Hyper-Net A with a
 * complex WIRE target per low triangle (sec. 4.4, Eq. 10-12). */
#include "gdsr_internal.h"

#include <cjson/cJSON.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

cr_gdsr_model_def cr_gdsr_model_default_def(void) {
    cr_gdsr_model_def d = {.latent = 64,
                           .steps = 4,
                           .mlp_hidden = 1,
                           .decoder_features = 32,
                           .hyper_features = 32,
                           .gen_hidden = 64,
                           .wire_layers = 5,
                           .wire_width = 16,
                           .omega0 = 5.0f,
                           .s0 = 10.0f,
                           .use_decoder = 1,
                           .sigma_b = 0.015f,
                           .layer_edges = -1,
                           .sigma_l = 0.020f,
                           .out_scale = 0.01f,
                           .seed = 1,
                           .cookie = CR_GDSR_COOKIE};
    return d;
}

cr_gdsr_model_def cr_gdsr_model_paper_def(void) {
    cr_gdsr_model_def d = cr_gdsr_model_default_def();
    d.latent = 128;
    d.steps = 6;
    d.mlp_hidden = 2;
    d.decoder_features = 128;
    d.hyper_features = 512;
    d.gen_hidden = 256;
    return d;
}

cr_status cr_gdsr_model_def_validate(const cr_gdsr_model_def *d, cr_error *err) {
    if (d->cookie != CR_GDSR_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr model def: not made by cr_gdsr_model_default_def");
#define RANGE(f, lo, hi)                                                                           \
    if (!(d->f >= (lo) && d->f <= (hi)))                                                           \
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr model def: " #f " outside [%g, %g]",             \
                       (double)(lo), (double)(hi));
    RANGE(latent, 4, 1024)
    RANGE(steps, 0, 32)
    RANGE(mlp_hidden, 0, 8)
    RANGE(decoder_features, 1, 1024)
    RANGE(hyper_features, 1, 2048)
    RANGE(gen_hidden, 4, 4096)
    RANGE(wire_layers, 2, 12)
    RANGE(wire_width, 2, CR_WIRE_MAX_WIDTH)
    RANGE(omega0, 0.01f, 100.0f)
    RANGE(s0, 0.0f, 100.0f)
    RANGE(sigma_b, 1e-4f, 1.0f)
    RANGE(layer_edges, -1, 1)
    RANGE(sigma_l, 1e-4f, 1.0f)
    RANGE(out_scale, 1e-6f, 10.0f)
#undef RANGE
    return CR_OK;
}

/* Floats of the WIRE target: a real first layer 2 -> w, complex w -> w
 * layers and a complex w -> 3 last layer (weights and biases, re and im). */
static int64_t wire_params(const cr_gdsr_model_def *d) {
    int64_t w = d->wire_width;
    return 3 * w + (int64_t)(d->wire_layers - 2) * 2 * (w * w + w) + 2 * (3 * w + 3);
}

void cr_gdsr_model_destroy(cr_gdsr_model *m) {
    if (!m) return;
    cr_mpnn_destroy(m->net);
    cr_mlp_destroy(m->dec);
    cr_mlp_destroy(m->gen);
    cr_nn_params_destroy(m->params);
    free(m);
}

cr_nn_params *cr_gdsr_model_params(cr_gdsr_model *m) {
    return m->params;
}
const cr_gdsr_model_def *cr_gdsr_model_get_def(const cr_gdsr_model *m) {
    return &m->def;
}

cr_status cr_gdsr_model_create(const cr_gdsr_model_def *def, cr_gdsr_model **out, cr_error *err) {
    *out = NULL;
    CR_TRY(cr_gdsr_model_def_validate(def, err));
    cr_gdsr_model *m = calloc(1, sizeof *m);
    if (!m) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    m->def = *def;
    if (m->def.layer_edges < 0) m->def.layer_edges = 0; /* auto is cr_gdsr_train's to settle */
    cr_status st;
    cr_rng rng = cr_rng_make(def->seed, 19);
    if ((st = cr_nn_params_create(&m->params, err)) != CR_OK) goto fail;
    cr_mpnn_def nd = cr_mpnn_default_def();
    nd.node_in = CR_GDSR_NODE_FEATURES;
    nd.edge_sets = m->def.layer_edges ? 3 : 2; /* Eq. 7's sum over layer edges */
    nd.edge_in[0] = nd.edge_in[1] = nd.edge_in[2] = CR_GDSR_EDGE_FEATURES;
    nd.node_out = (def->use_decoder ? def->decoder_features : 0) + def->hyper_features;
    nd.latent = def->latent;
    nd.steps = def->steps;
    nd.hidden_layers = def->mlp_hidden;
    if ((st = cr_mpnn_create(&nd, m->params, "H", &rng, &m->net, err)) != CR_OK) goto fail;
    if (def->use_decoder) {
        cr_mlp_def ed = cr_mlp_default_def();
        ed.nlayers = 2;
        ed.widths[0] = 3 * def->decoder_features;
        ed.widths[1] = def->latent;
        ed.widths[2] = 9;
        if ((st = cr_mlp_create(&ed, m->params, "E", &rng, &m->dec, err)) != CR_OK) goto fail;
        /* start at C^ = C: the last layer's weights at zero */
        cr_init_zero(m->dec->layer[1].weight);
        cr_init_zero(m->dec->layer[1].bias);
    }
    m->nparams = wire_params(def);
    cr_mlp_def gd = cr_mlp_default_def();
    gd.nlayers = 2;
    gd.widths[0] = 3 * def->hyper_features;
    gd.widths[1] = def->gen_hidden;
    gd.widths[2] = (int)m->nparams;
    if ((st = cr_mlp_create(&gd, m->params, "A.gen", &rng, &m->gen, err)) != CR_OK) goto fail;
    /* SIREN's hyper_weight_init: the head's weights scaled down, its bias one
     * initialisation of the target (PyTorch's U(+-1/sqrt(in))), with the last
     * WIRE layer at zero so the residual starts at zero. */
    {
        cr_linear *head = &m->gen->layer[1];
        for (int64_t i = 0; i < head->weight->numel; i++)
            head->weight->data[i] *= 0.01f;
        float *b = head->bias->data;
        int64_t w = def->wire_width, o = 0;
        float r0 = 1.0f / sqrtf(2.0f), r = 1.0f / sqrtf((float)w);
        for (int64_t i = 0; i < 3 * w; i++)
            b[o++] = r0 * (2.0f * cr_rng_uniformf(&rng) - 1.0f);
        for (int l = 1; l < def->wire_layers - 1; l++)
            for (int64_t i = 0; i < 2 * (w * w + w); i++)
                b[o++] = r * (2.0f * cr_rng_uniformf(&rng) - 1.0f);
        /* the last WIRE layer's rows of the head, weights and bias, at zero:
         * the residual is exactly zero until training moves them */
        int64_t last = 2 * (3 * w + 3), in = head->in; /* weight (P, in) */
        for (int64_t i = 0; i < last; i++)
            b[o++] = 0.0f;
        memset(head->weight->data + (m->nparams - last) * in, 0,
               (size_t)(last * in) * sizeof(float));
    }
    *out = m;
    return CR_OK;
fail:
    cr_gdsr_model_destroy(m);
    return st;
}

/* ---------------------------------------------------------- helpers -- */

int32_t *cr_gdsr_tri_column(const cr_mesh *m, int k) {
    int32_t *c = malloc((size_t)(m->nf > 0 ? m->nf : 1) * sizeof(int32_t));
    if (c)
        for (int32_t f = 0; f < m->nf; f++)
            c[f] = m->tri[3 * f + k];
    return c;
}

/* Column k of low's triangles, (F), in the step arena (NULL with the
 * context error set when it is full). */
static int32_t *tri_column(cr_nn_ctx *ctx, const cr_mesh *low, int k) {
    int32_t *c = cr_nn_scratch(ctx, "gdsr", (size_t)(low->nf > 0 ? low->nf : 1) * sizeof(int32_t));
    if (c)
        for (int32_t f = 0; f < low->nf; f++)
            c[f] = low->tri[3 * f + k];
    return c;
}

/* Per-face frames (F,3) e1, e2, n of positions x (V,3) (a tensor, so the
 * frame of C^ carries gradients). The index arrays of this and the
 * functions below live in the step arena, so a forward allocates nothing
 * on the heap (the runtime's rule). */
static void face_frames(cr_nn_ctx *ctx, cr_tensor *x, const cr_mesh *low, cr_tensor **e1,
                        cr_tensor **e2, cr_tensor **n) {
    int32_t *t0 = tri_column(ctx, low, 0), *t1 = tri_column(ctx, low, 1),
            *t2 = tri_column(ctx, low, 2);
    if (!t0 || !t1 || !t2) {
        *e1 = *e2 = *n = NULL;
        return;
    }
    cr_tensor *p0 = cr_nn_gather_rows(ctx, x, t0, low->nf);
    cr_tensor *u = cr_nn_sub(ctx, cr_nn_gather_rows(ctx, x, t1, low->nf), p0);
    cr_tensor *v = cr_nn_sub(ctx, cr_nn_gather_rows(ctx, x, t2, low->nf), p0);
    *e1 = cr_nn_normalize(ctx, u, 1e-12f);
    *n = cr_nn_normalize(ctx, cr_nn_cross(ctx, u, v), 1e-12f);
    *e2 = cr_nn_cross(ctx, *n, *e1);
}

/* Per-triangle concatenation of its corners' features: f (V,D) -> (F,3D). */
static cr_tensor *corner_concat(cr_nn_ctx *ctx, cr_tensor *f, const cr_mesh *low) {
    if (!f) return NULL;
    int64_t D = f->shape[1];
    cr_tensor *g = cr_nn_gather_rows(ctx, f, low->tri, 3 * (int64_t)low->nf);
    return cr_nn_reshape(ctx, g, 2, (int64_t[]){low->nf, 3 * D});
}

/* --------------------------------------------------------- decoder E -- */

/* One face's frame as face_frames makes it on the tape: e1 along its first
 * edge, n its normal, e2 = n x e1 (the engine's normalisation: the length in
 * double, at least 1e-12). */
static void face_frame(const float *p0, const float *p1, const float *p2, float e1[3], float e2[3],
                       float n[3]) {
    float u[3], v[3], c[3];
    for (int d = 0; d < 3; d++)
        u[d] = p1[d] - p0[d], v[d] = p2[d] - p0[d];
    c[0] = u[1] * v[2] - u[2] * v[1];
    c[1] = u[2] * v[0] - u[0] * v[2];
    c[2] = u[0] * v[1] - u[1] * v[0];
    const double lu = (double)u[0] * u[0] + (double)u[1] * u[1] + (double)u[2] * u[2];
    const double lc = (double)c[0] * c[0] + (double)c[1] * c[1] + (double)c[2] * c[2];
    const float iu = 1.0f / fmaxf((float)sqrt(lu), 1e-12f),
                ic = 1.0f / fmaxf((float)sqrt(lc), 1e-12f);
    for (int d = 0; d < 3; d++)
        e1[d] = u[d] * iu, n[d] = c[d] * ic;
    e2[0] = n[1] * e1[2] - n[2] * e1[1];
    e2[1] = n[2] * e1[0] - n[0] * e1[2];
    e2[2] = n[0] * e1[1] - n[1] * e1[0];
}

/* The decoder's displacements without the tape (the gradient off): each
 * face's three corner vectors turned into its frame and averaged at the
 * vertices in one loop, where the tape path takes a batched 1x3 by 3x3
 * product, a scatter and a dozen small ops (2.5 ms of a 10k-vertex frame). */
static cr_tensor *decode_infer(cr_nn_ctx *ctx, const cr_mesh *low, const cr_tensor *local,
                               const float *c) {
    const int64_t F = low->nf, V = low->nv;
    cr_tensor *out = cr_nn_new(ctx, 2, (int64_t[]){V, 3});
    float *cnt = cr_nn_scratch(ctx, "gdsr decode", sizeof(float) * (size_t)(V > 0 ? V : 1));
    if (!out || !cnt) return NULL;
    memset(out->data, 0, sizeof(float) * 3 * (size_t)V);
    memset(cnt, 0, sizeof(float) * (size_t)V);
    for (int64_t f = 0; f < F; f++) {
        const int32_t *t = low->tri + 3 * f;
        float e1[3], e2[3], n[3];
        face_frame(c + 3 * t[0], c + 3 * t[1], c + 3 * t[2], e1, e2, n);
        for (int j = 0; j < 3; j++) {
            const float *l = local->data + 9 * f + 3 * j;
            float *o = out->data + 3 * t[j];
            for (int d = 0; d < 3; d++)
                o[d] += l[0] * e1[d] + l[1] * e2[d] + l[2] * n[d];
            cnt[t[j]] += 1.0f;
        }
    }
    for (int64_t i = 0; i < V; i++) {
        const float inv = cnt[i] > 0 ? 1.0f / cnt[i] : 0.0f;
        for (int d = 0; d < 3; d++)
            out->data[3 * i + d] *= inv;
    }
    return out;
}

cr_tensor *cr_gdsr_decode(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_mesh *low, cr_tensor *f,
                          const float *c) {
    if (!m->dec || !f) return NULL;
    int64_t F = low->nf, V = low->nv;
    if (!cr_nn_ctx_grad_enabled(ctx)) {
        cr_tensor *local = cr_nn_mul_scalar(
            ctx, cr_mlp_forward(ctx, m->dec, corner_concat(ctx, f, low)), m->def.out_scale);
        return local ? decode_infer(ctx, low, local, c) : NULL;
    }
    cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){V, 3}, c);
    cr_tensor *e1, *e2, *n;
    face_frames(ctx, x, low, &e1, &e2, &n); /* x has no grad: constant frames */
    cr_tensor *local = cr_nn_mul_scalar(
        ctx, cr_mlp_forward(ctx, m->dec, corner_concat(ctx, f, low)), m->def.out_scale); /* (F,9) */
    local = cr_nn_reshape(ctx, local, 2, (int64_t[]){3 * F, 3});
    /* R per corner: rows e1, e2, n of its face */
    cr_tensor *R = cr_nn_concat(ctx, 3, (cr_tensor *[]){e1, e2, n}, 1); /* (F,9) */
    int32_t *rep =
        cr_nn_scratch(ctx, "gdsr decode", (size_t)(3 * F > 0 ? 3 * F : 1) * sizeof(int32_t));
    cr_tensor *invt = cr_nn_new(ctx, 2, (int64_t[]){V, 1});
    cr_tensor *out = NULL;
    if (rep && invt) {
        float *inv = invt->data;
        for (int64_t k = 0; k < 3 * F; k++)
            rep[k] = (int32_t)(k / 3);
        cr_tensor *Rc =
            cr_nn_reshape(ctx, cr_nn_gather_rows(ctx, R, rep, 3 * F), 3, (int64_t[]){3 * F, 3, 3});
        cr_tensor *dw = cr_nn_matmul(ctx, cr_nn_reshape(ctx, local, 3, (int64_t[]){3 * F, 1, 3}),
                                     Rc, 0, 0); /* (3F,1,3) */
        dw = cr_nn_reshape(ctx, dw, 2, (int64_t[]){3 * F, 3});
        cr_tensor *sum = cr_nn_scatter_add_rows(ctx, dw, low->tri, V);
        for (int64_t i = 0; i < V; i++)
            inv[i] = 0.0f;
        for (int64_t k = 0; k < 3 * F; k++)
            inv[low->tri[k]] += 1.0f;
        for (int64_t i = 0; i < V; i++)
            inv[i] = inv[i] > 0 ? 1.0f / inv[i] : 0.0f;
        out = cr_nn_mul(ctx, sum, invt);
    }
    return out;
}

/* ------------------------------------------------------ hyper-net A -- */

/* theta columns [off, off + rows*cols) as per-group weights (G,rows,cols). */
static cr_tensor *theta_w(cr_nn_ctx *ctx, cr_tensor *theta, int64_t *off, int64_t rows,
                          int64_t cols) {
    cr_tensor *s = cr_nn_slice(ctx, theta, 1, *off, rows * cols);
    *off += rows * cols;
    return s ? cr_nn_reshape(ctx, s, 3, (int64_t[]){theta->shape[0], rows, cols}) : NULL;
}

static cr_tensor *theta_b(cr_nn_ctx *ctx, cr_tensor *theta, int64_t *off, int64_t n,
                          const int32_t *group, int64_t M) {
    cr_tensor *s = cr_nn_slice(ctx, theta, 1, *off, n);
    *off += n;
    return cr_nn_gather_rows(ctx, s, group, M);
}

cr_tensor *cr_gdsr_hyper(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_mesh *low, cr_tensor *h,
                         int64_t M, const int32_t *face, const float *bary) {
    const cr_gdsr_model_def *d = &m->def;
    int64_t w = d->wire_width;
    cr_tensor *theta = cr_mlp_forward(ctx, m->gen, corner_concat(ctx, h, low)); /* (F,P) */
    if (!cr_nn_ctx_grad_enabled(ctx)) {
        /* each point evaluates its face's network from theta's row directly
         * (the tape path below slices theta into (F,o,w) copies, gathers each
         * bias to the points and sorts the points by face for every grouped
         * product: at 10k points on 5k faces that was 115 ms of a 10k-vertex
         * frame) */
        cr_tensor *y = theta ? cr_nn_new(ctx, 2, (int64_t[]){M, 3}) : NULL;
        if (!y || cr_wire_hyper_infer(ctx, theta->data, theta->shape[0], m->nparams, face, bary + 1,
                                      3, M, (int)w, d->wire_layers, 3, d->omega0, d->s0, y->data,
                                      NULL) != CR_OK)
            return NULL;
        return y;
    }
    cr_tensor *x = cr_nn_new(ctx, 2, (int64_t[]){M, 2});
    if (!x) return NULL;
    for (int64_t k = 0; k < M; k++) {
        x->data[2 * k] = bary[3 * k + 1];
        x->data[2 * k + 1] = bary[3 * k + 2];
    }
    int64_t off = 0;
    cr_tensor *W0 = theta_w(ctx, theta, &off, w, 2);
    cr_tensor *b0 = theta_b(ctx, theta, &off, w, face, M);
    cr_tensor *z = cr_nn_add(ctx, cr_nn_matmul_grouped(ctx, x, W0, face, 1), b0);
    cr_tensor *re = NULL, *im = NULL;
    cr_wire_activation(ctx, z, NULL, d->omega0, d->s0, &re, &im);
    for (int l = 1; l < d->wire_layers; l++) {
        int64_t o = l == d->wire_layers - 1 ? 3 : w;
        cr_tensor *Wr = theta_w(ctx, theta, &off, o, w);
        cr_tensor *Wi = theta_w(ctx, theta, &off, o, w);
        cr_tensor *br = theta_b(ctx, theta, &off, o, face, M);
        cr_tensor *bi = theta_b(ctx, theta, &off, o, face, M);
        cr_tensor *yr = cr_nn_add(ctx,
                                  cr_nn_sub(ctx, cr_nn_matmul_grouped(ctx, re, Wr, face, 1),
                                            cr_nn_matmul_grouped(ctx, im, Wi, face, 1)),
                                  br);
        if (l == d->wire_layers - 1) return yr; /* the real part of the last layer */
        cr_tensor *yi = cr_nn_add(ctx,
                                  cr_nn_add(ctx, cr_nn_matmul_grouped(ctx, re, Wi, face, 1),
                                            cr_nn_matmul_grouped(ctx, im, Wr, face, 1)),
                                  bi);
        cr_wire_activation(ctx, yr, yi, d->omega0, d->s0, &re, &im);
    }
    return NULL;
}

/* ---------------------------------------------------------- forward -- */

cr_tensor *cr_gdsr_forward(cr_nn_ctx *ctx, cr_gdsr_model *m, const cr_gdsr_data *d,
                           const cr_gdsr_graph *g, const float *node, const float *edge0,
                           const float *edge1, const float *edge2, const float *c,
                           cr_tensor **chat_out) {
    const cr_mesh *low = d->low;
    int64_t V = low->nv, Vh = d->high->nv;
    cr_nn_graph graphs[3];
    cr_tensor *ex[3] = {NULL, NULL, NULL};
    const float *ef[3] = {edge0, edge1, edge2};
    for (int s = 0; s < 3; s++) {
        int64_t ne = s < 2 || (m->def.layer_edges && edge2) ? g->ne[s] : 0;
        graphs[s] =
            (cr_nn_graph){.nodes = V, .edges = ne, .senders = g->snd[s], .receivers = g->rcv[s]};
        if (ne > 0) ex[s] = cr_nn_from(ctx, 2, (int64_t[]){ne, CR_GDSR_EDGE_FEATURES}, ef[s]);
    }
    cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){V, CR_GDSR_NODE_FEATURES}, node);
    cr_tensor *y = cr_mpnn_forward(ctx, m->net, x, graphs, ex, NULL);
    if (!y) return NULL;
    cr_tensor *cten = cr_nn_from(ctx, 2, (int64_t[]){V, 3}, c);
    cr_tensor *chat = cten, *hf = y;
    if (m->def.use_decoder) {
        int64_t Dd = m->def.decoder_features;
        cr_tensor *fd = cr_nn_slice(ctx, y, 1, 0, Dd);
        hf = cr_nn_slice(ctx, y, 1, Dd, m->def.hyper_features);
        chat = cr_nn_add(ctx, cten, cr_gdsr_decode(ctx, m, low, fd, c));
    }
    if (chat_out) *chat_out = chat;
    /* S[C^]: barycentric upsampling through Eq. 1, then the residual of A in
     * the frame of C^'s face (Eq. 12) */
    int32_t *corner[3];
    cr_tensor *bw[3];
    int ok = 1;
    for (int k = 0; k < 3; k++) {
        corner[k] = cr_nn_scratch(ctx, "gdsr forward", (size_t)(Vh > 0 ? Vh : 1) * sizeof(int32_t));
        bw[k] = cr_nn_new(ctx, 2, (int64_t[]){Vh, 1});
        ok = ok && corner[k] && bw[k];
    }
    if (!ok) return NULL;
    for (int64_t i = 0; i < Vh; i++)
        for (int k = 0; k < 3; k++) {
            corner[k][i] = low->tri[3 * d->face[i] + k];
            bw[k]->data[i] = d->bary[3 * i + k];
        }
    cr_tensor *s = NULL;
    for (int k = 0; k < 3; k++) {
        cr_tensor *t = cr_nn_mul(ctx, cr_nn_gather_rows(ctx, chat, corner[k], Vh), bw[k]);
        s = k == 0 ? t : cr_nn_add(ctx, s, t);
    }
    cr_tensor *r = cr_nn_mul_scalar(ctx, cr_gdsr_hyper(ctx, m, low, hf, Vh, d->face, d->bary),
                                    m->def.out_scale); /* (Vh,3) */
    cr_tensor *e1, *e2, *n;
    face_frames(ctx, chat, low, &e1, &e2, &n);
    cr_tensor *fr[3] = {e1, e2, n};
    cr_tensor *out = s;
    for (int k = 0; k < 3; k++)
        out = cr_nn_add(ctx, out,
                        cr_nn_mul(ctx, cr_nn_slice(ctx, r, 1, k, 1),
                                  cr_nn_gather_rows(ctx, fr[k], d->face, Vh)));
    return out;
}

/* ---------------------------------------------------- def as JSON -- */

/* Every stored field of the def, in the order written (ranges: cr_gdsr_model_def_validate). */
static const cr_config_key def_keys[] = {
#define K(name, type) CR_CONFIG_KEY(cr_gdsr_model_def, name, type, 1, 0, NULL, NULL, NULL)
    K(latent, CR_CFG_INT),         K(steps, CR_CFG_INT),
    K(mlp_hidden, CR_CFG_INT),     K(decoder_features, CR_CFG_INT),
    K(hyper_features, CR_CFG_INT), K(gen_hidden, CR_CFG_INT),
    K(wire_layers, CR_CFG_INT),    K(wire_width, CR_CFG_INT),
    K(omega0, CR_CFG_FLOAT),       K(s0, CR_CFG_FLOAT),
    K(use_decoder, CR_CFG_INT),    K(sigma_b, CR_CFG_FLOAT),
    K(layer_edges, CR_CFG_INT),    K(sigma_l, CR_CFG_FLOAT),
    K(out_scale, CR_CFG_FLOAT),    K(seed, CR_CFG_U64),
#undef K
};
enum { NDEF_KEYS = sizeof def_keys / sizeof def_keys[0] };

char *cr_gdsr_model_def_json(const cr_gdsr_model_def *d) {
    cJSON *j = cr_config_to_object(def_keys, NDEF_KEYS, d);
    char *s = j ? cJSON_PrintUnformatted(j) : NULL;
    cJSON_Delete(j);
    return s;
}

cr_status cr_gdsr_model_def_from_json(const char *json, const char *source, cr_gdsr_model_def *d,
                                      cr_error *err) {
    *d = cr_gdsr_model_default_def();
    cJSON *j = json ? cJSON_Parse(json) : NULL;
    if (!cJSON_IsObject(j)) {
        cJSON_Delete(j);
        return CR_FAIL(err, CR_ERR_PARSE, "%s: no or unreadable gdsr model definition", source);
    }
    char where[1100];
    snprintf(where, sizeof where, "%s: gdsr model definition", source);
    cr_status st = cr_config_parse_object(j, where, def_keys, NDEF_KEYS, d, err);
    /* Models written before layer edges lack the pair and have two edge sets
     * (docs/gdsr.md, "Layer edges"); every other field is required. */
    if (st == CR_OK && !cJSON_GetObjectItemCaseSensitive(j, "layer_edges") &&
        !cJSON_GetObjectItemCaseSensitive(j, "sigma_l")) {
        d->layer_edges = 0;
        cJSON_AddNumberToObject(j, "layer_edges", 0);
        cJSON_AddNumberToObject(j, "sigma_l", d->sigma_l);
    }
    const char *absent = st == CR_OK ? cr_config_absent(def_keys, NDEF_KEYS, j) : NULL;
    if (absent)
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: gdsr model definition lacks '%s'", source, absent);
    cJSON_Delete(j);
    CR_TRY(st);
    return cr_gdsr_model_def_validate(d, err);
}

const char *cr_gdsr_model_def_differ(const cr_gdsr_model_def *a, const cr_gdsr_model_def *b,
                                     double *va, double *vb) {
    const char *name = cr_config_diff(def_keys, NDEF_KEYS, a, b);
    for (int k = 0; name && k < NDEF_KEYS; k++)
        if (def_keys[k].name == name)
            *va = cr_config_number(&def_keys[k], a), *vb = cr_config_number(&def_keys[k], b);
    return name;
}
