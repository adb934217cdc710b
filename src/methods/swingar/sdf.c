/* sdf.c: SwinGar's body SDF network (paper 002, sec. III-D and IV): the
 * two-branch, eight-layer Softplus MLP, its input gradient as tape tensors
 * (forward-mode tangents), the eq. 8-9 loss, host evaluation in chunks, the
 * geometric initialisation and safetensors save/load. The architecture and
 * conventions are documented in sdf.h; the choices in docs/swingar_sdf.md.
 *
 * Leaves out: second derivatives beyond what the tape gives (the loss on
 * grad S is differentiated by the tape through the tangent ops).
 * References: Atzmon & Lipman, SAL, CVPR 2020 (geometric initialisation);
 * Gropp et al., IGR, ICML 2020 (eikonal term); Park et al., DeepSDF 2019.
 */
#include "methods/swingar/sdf.h"

#include "crease/body.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_layers.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t SDF_DEF_COOKIE = 0x53444631u;
/* Points per evaluation chunk; the arena holds one chunk's values and
 * tangents (about 50 (CH,W) float blocks; 64 to spare). */
enum { EVAL_CHUNK = 512, EVAL_BLOCKS = 64 };
/* Points used to calibrate the geometric initialisation. */
enum { INIT_PROBES = 512 };
static const float NORM_EPS = 1e-12f; /* |grad| guard; grad S is O(1) */

/* Eight layers: pos.0-2, body.0-2, fuse.0 (two weight blocks), fuse.1. */
typedef struct sdf_layer {
    cr_tensor *w, *b; /* (OUT,IN), (OUT) */
} sdf_layer;

struct cr_swingar_sdf {
    cr_swingar_sdf_def def;
    cr_nn_params *params;
    sdf_layer pos[3], body[3];
    cr_tensor *fuse_wp, *fuse_wq, *fuse_b; /* (W,W), (W,W) or NULL, (W) */
    sdf_layer out;                         /* (1,W), (1) */
    cr_nn_ctx *ctx;                        /* evaluation */
};

cr_swingar_sdf_def cr_swingar_sdf_default_def(void) {
    return (cr_swingar_sdf_def){.width = 512,
                                .cond_dim = CR_SWINGAR_SDF_COND_DIM,
                                .softplus_beta = 100.0f,
                                .center = {0, 0, 0},
                                .scale = 1.0f,
                                .init_radius = 0.5f,
                                .tau = 0.1f,
                                .seed = 1,
                                .cookie = SDF_DEF_COOKIE};
}

static cr_status check_def(const cr_swingar_sdf_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == SDF_DEF_COOKIE);
    if (d->width < 2 || d->width > 4096)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf: width %d outside [2, 4096]", d->width);
    if (d->cond_dim < 0 || d->cond_dim > 4096)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf: cond_dim %d outside [0, 4096]",
                       d->cond_dim);
    if (d->articulated < 0 || d->articulated > 2)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf: articulated %d is not 0, 1 or 2",
                       d->articulated);
    if (!(d->tau > 0))
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf: tau %g is not > 0", (double)d->tau);
    if (!(d->softplus_beta > 0) || !(d->scale > 0) || !(d->init_radius >= 0) ||
        !isfinite(d->center[0] + d->center[1] + d->center[2]))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf: need softplus_beta > 0, scale > 0, init_radius >= 0 and a "
                       "finite center");
    return CR_OK;
}

static cr_status add(cr_nn_params *p, const char *name, int64_t rows, int64_t cols, cr_tensor **out,
                     cr_error *err) {
    if (cols > 0) return cr_nn_params_add(p, name, 2, (int64_t[]){rows, cols}, out, err);
    return cr_nn_params_add(p, name, 1, (int64_t[]){rows}, out, err);
}

static cr_status add_layer(cr_nn_params *p, const char *prefix, int i, int64_t out, int64_t in,
                           sdf_layer *l, cr_error *err) {
    char name[64];
    snprintf(name, sizeof name, "%s.%d.weight", prefix, i);
    CR_TRY(add(p, name, out, in, &l->w, err));
    snprintf(name, sizeof name, "%s.%d.bias", prefix, i);
    return add(p, name, out, 0, &l->b, err);
}

/* SAL's geometric initialisation: hidden weights N(0, sqrt(2/out)), zero
 * biases, the last layer N(sqrt(pi/W), 1e-4) with bias -r, which makes a
 * ReLU-like net approximate |x~| - r. The residual skips change the output
 * scale, so the last layer is then rescaled by the measured mean output on
 * the unit sphere. The fusion block of the body
 * branch starts at zero, so the untrained field is the same sphere for every
 * pose and the body branch is learned from there. */
/* Inputs of the first position layer. */
static int64_t articulated_inputs(const cr_swingar_sdf_def *d) {
    return d->articulated == 0 ? 3 : d->articulated == 1 ? 3 * CR_NJOINTS : 4 * CR_NJOINTS;
}

static cr_status init_weights(cr_swingar_sdf *net, cr_error *err) {
    const cr_swingar_sdf_def *d = &net->def;
    cr_rng rng = cr_rng_make(d->seed, 0x5df);
    int64_t w = d->width;
    sdf_layer *hidden[6] = {&net->pos[0], &net->pos[1], &net->pos[2]};
    int nh = 3;
    if (d->cond_dim > 0)
        hidden[nh++] = &net->body[0], hidden[nh++] = &net->body[1], hidden[nh++] = &net->body[2];
    for (int i = 0; i < nh; i++) {
        /* articulated: in the rest pose all 22 inputs equal x~, so 1/sqrt(22)
         * keeps the first layer's output as for x~ alone */
        float sd =
            sqrtf(2.0f / (float)w) / (i == 0 && d->articulated == 1 ? sqrtf(CR_NJOINTS) : 1.0f);
        cr_nn_fill_normal(hidden[i]->w, &rng, 0.0f, sd);
        cr_nn_fill(hidden[i]->b, 0.0f);
    }
    cr_nn_fill_normal(net->fuse_wp, &rng, 0.0f, sqrtf(2.0f / (float)w));
    if (net->fuse_wq) cr_nn_fill(net->fuse_wq, 0.0f);
    cr_nn_fill(net->fuse_b, 0.0f);
    cr_nn_fill_normal(net->out.w, &rng, sqrtf((float)M_PI / (float)w), 1e-4f);
    cr_nn_fill(net->out.b, 0.0f);
    /* calibrate: mean net output (bias 0) over points on the unit sphere */
    float *x = malloc(INIT_PROBES * 3 * sizeof(float)), *s = malloc(INIT_PROBES * sizeof(float));
    float *cond = calloc((size_t)cr_swingar_sdf_cond_len(d) + 1, sizeof(float));
    if (cond && d->articulated) /* identity frames: the rest pose */
        for (int j = 0; j < CR_NJOINTS; j++)
            for (int k = 0; k < 3; k++)
                cond[d->cond_dim + CR_SWINGAR_SDF_JOINT_REC * j + 5 * k] = 1.0f;
    cr_status st = x && s && cond ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: init");
    for (int i = 0; st == CR_OK && i < INIT_PROBES; i++) {
        float v[3] = {(float)cr_rng_normal(&rng), (float)cr_rng_normal(&rng),
                      (float)cr_rng_normal(&rng)};
        float len = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 1e-12f;
        for (int k = 0; k < 3; k++)
            x[3 * i + k] = d->center[k] + d->scale * v[k] / len;
    }
    if (st == CR_OK) st = cr_swingar_sdf_eval(net, x, INIT_PROBES, cond, s, NULL, err);
    if (st == CR_OK) {
        double mean = 0;
        for (int i = 0; i < INIT_PROBES; i++)
            mean += s[i] / d->scale;
        mean /= INIT_PROBES;
        if (mean > 1e-6) {
            for (int64_t i = 0; i < net->out.w->numel; i++)
                net->out.w->data[i] = (float)(net->out.w->data[i] / mean);
        }
        net->out.b->data[0] = -d->init_radius;
    }
    free(x), free(s), free(cond);
    return st;
}

cr_status cr_swingar_sdf_create(const cr_swingar_sdf_def *def, cr_swingar_sdf **out,
                                cr_error *err) {
    *out = NULL;
    CR_TRY(check_def(def, err));
    cr_swingar_sdf *net = calloc(1, sizeof *net);
    if (!net) return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: out of memory");
    net->def = *def;
    int64_t w = def->width;
    cr_status st = cr_nn_params_create(&net->params, err);
    for (int i = 0; st == CR_OK && i < 3; i++)
        st = add_layer(net->params, "pos", i, w, i == 0 ? articulated_inputs(def) : w, &net->pos[i],
                       err);
    for (int i = 0; st == CR_OK && def->cond_dim > 0 && i < 3; i++)
        st = add_layer(net->params, "body", i, w, i == 0 ? def->cond_dim : w, &net->body[i], err);
    if (st == CR_OK) st = add(net->params, "fuse.0.weight_p", w, w, &net->fuse_wp, err);
    if (st == CR_OK && def->cond_dim > 0)
        st = add(net->params, "fuse.0.weight_q", w, w, &net->fuse_wq, err);
    if (st == CR_OK) st = add(net->params, "fuse.0.bias", w, 0, &net->fuse_b, err);
    if (st == CR_OK) st = add_layer(net->params, "fuse", 1, 1, w, &net->out, err);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes =
        (size_t)EVAL_CHUNK * (size_t)w * sizeof(float) * EVAL_BLOCKS + ((size_t)16 << 20);
    if (st == CR_OK) st = cr_nn_ctx_create(&cd, &net->ctx, err);
    if (st == CR_OK) st = init_weights(net, err);
    if (st != CR_OK) {
        cr_swingar_sdf_destroy(net);
        return st;
    }
    *out = net;
    return CR_OK;
}

void cr_swingar_sdf_destroy(cr_swingar_sdf *net) {
    if (!net) return;
    cr_nn_ctx_destroy(net->ctx);
    cr_nn_params_destroy(net->params);
    free(net);
}

const cr_swingar_sdf_def *cr_swingar_sdf_get_def(const cr_swingar_sdf *net) {
    return &net->def;
}

cr_nn_params *cr_swingar_sdf_params(cr_swingar_sdf *net) {
    return net->params;
}

int cr_swingar_sdf_cond_len(const cr_swingar_sdf_def *def) {
    return def->cond_dim + (def->articulated ? CR_SWINGAR_SDF_FRAME_DIM : 0);
}

void cr_swingar_sdf_condition(const cr_mannequin_def *shape, const float *joints, const float *pose,
                              float *cond) {
    cr_mannequin_def n = cr_mannequin_default_def();
    const cr_mannequin_def *s = shape ? shape : &n;
    cond[0] = s->height_m - n.height_m;
    cond[1] = s->girth - n.girth;
    cond[2] = s->chest - n.chest;
    cond[3] = s->hips - n.hips;
    for (int i = 0; i < 3 * CR_NJOINTS; i++)
        cond[CR_SWINGAR_SDF_SHAPE_DIM + i] = pose ? pose[i] : 0.0f;
    float *fr = &cond[CR_SWINGAR_SDF_COND_DIM];
    float xf[CR_NJOINTS * 12];
    if (joints) {
        float zero[3 * CR_NJOINTS] = {0};
        cr_body_skin_transforms(joints, pose ? pose : zero, NULL, xf);
    }
    for (int j = 0; j < CR_NJOINTS; j++) {
        /* the inverse of x = A u + b: u = A^T x - A^T b */
        const float *a = &xf[12 * j];
        float *m = &fr[CR_SWINGAR_SDF_JOINT_REC * j];
        for (int r = 0; r < 3; r++) {
            double t = 0;
            for (int k = 0; k < 3; k++) {
                float v = joints ? a[4 * k + r] : (float)(r == k);
                m[4 * r + k] = v;
                t -= joints ? (double)v * a[4 * k + 3] : 0.0;
            }
            m[4 * r + 3] = (float)t;
        }
        /* the bone's rest centre: halfway from the joint to its children's mean */
        float cc[3] = {0, 0, 0}, nc = 0;
        for (int c = 0; joints && c < CR_NJOINTS; c++)
            if (cr_joint_parent[c] == j) {
                for (int k = 0; k < 3; k++)
                    cc[k] += joints[3 * c + k];
                nc += 1;
            }
        for (int k = 0; k < 3; k++) {
            float jk = joints ? joints[3 * j + k] : 0.0f;
            m[12 + k] = nc > 0 ? 0.5f * (jk + cc[k] / nc) : jk;
        }
    }
}

/* The articulated first layer's pre-activation z (N,W) = W_0 u~ + b_0 with
 * u~ = (M x + m - center) / scale stacked over the joints, and its tangents
 * scale dz/dx (P or N, 3, W) (scale: the same convention as the plain path,
 * whose tangents are d/dx~). Per pose P: T_p = (M_p^T stacked) W_0^T and
 * e_p = W_0 (m_p - center) / scale + b_0, gathered per point. The frames are
 * read from the host data of cond's rows (constants on the tape). */
static cr_tensor *articulated_input(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *x2,
                                    cr_tensor *cond, const int32_t *cond_row, cr_tensor **tan) {
    const cr_swingar_sdf_def *d = &net->def;
    if (!cond || !x2) return NULL;
    int64_t p = cond->shape[0], len = cond->numel / p, n = x2->shape[0];
    int64_t nin = 3 * CR_NJOINTS, w = d->width;
    cr_tensor *jt = cr_nn_new(ctx, 2, (int64_t[]){3 * p, nin});
    cr_tensor *e = cr_nn_new(ctx, 2, (int64_t[]){p, nin});
    if (!jt || !e) return NULL;
    for (int64_t q = 0; q < p; q++) {
        const float *fr = &cond->data[q * len + d->cond_dim];
        for (int j = 0; j < CR_NJOINTS; j++)
            for (int r = 0; r < 3; r++) {
                for (int k = 0; k < 3; k++)
                    jt->data[(3 * q + k) * nin + 3 * j + r] =
                        fr[CR_SWINGAR_SDF_JOINT_REC * j + 4 * r + k];
                e->data[q * nin + 3 * j + r] =
                    (fr[CR_SWINGAR_SDF_JOINT_REC * j + 4 * r + 3] - d->center[r]) / d->scale;
            }
    }
    cr_tensor *t = cr_nn_linear(ctx, jt, net->pos[0].w, NULL);         /* (3P,W) */
    cr_tensor *b = cr_nn_linear(ctx, e, net->pos[0].w, net->pos[0].b); /* (P,W) */
    if (cond_row) {
        t = cr_nn_reshape(
            ctx,
            cr_nn_gather_rows(ctx, cr_nn_reshape(ctx, t, 2, (int64_t[]){p, 3 * w}), cond_row, n), 3,
            (int64_t[]){n, 3, w});
        b = cr_nn_gather_rows(ctx, b, cond_row, n);
    } else {
        t = cr_nn_reshape(ctx, t, 3, (int64_t[]){p, 3, w});
    }
    cr_tensor *xs =
        cr_nn_reshape(ctx, cr_nn_mul_scalar(ctx, x2, 1.0f / d->scale), 3, (int64_t[]){n, 3, 1});
    cr_tensor *z = cr_nn_add(ctx, cr_nn_sum_axis(ctx, cr_nn_mul(ctx, xs, t), 1, 0), b);
    if (tan) *tan = t;
    return z;
}

/* articulated = 2: the first layer on F = [w_j u~_j, w_j] (N,88), w =
 * softmax_j(-|u~_j - c~_j|^2 / tau), all in normalised units (u~_j = M_j x~ +
 * e_j, e_j = (M_j center + m_j - center) / scale, c~_j = (c_j - center) /
 * scale), and its tangents d/dx~ (N,3,W) through the weights: with
 * dU = M, d|D_j|^2 = 2 D_j . dU_j, dw = w (dl - sum_k w_k dl_k), dl = -d|D|^2 / tau,
 * dF = [dw u~ + w dU, dw]. */
static cr_tensor *weighted_input(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *xn,
                                 cr_tensor *cond, const int32_t *cond_row, cr_tensor **tan) {
    const cr_swingar_sdf_def *d = &net->def;
    if (!cond || !xn) return NULL;
    enum { J = CR_NJOINTS, R = CR_SWINGAR_SDF_JOINT_REC };
    int64_t p = cond->shape[0], len = cond->numel / p, n = xn->shape[0];
    const float itau = 1.0f / d->tau;
    cr_tensor *mt = cr_nn_new(ctx, 2, (int64_t[]){p, 9 * J}); /* (P, 3, 3J): dU/dx~ */
    cr_tensor *e = cr_nn_new(ctx, 2, (int64_t[]){p, 3 * J});
    cr_tensor *c = cr_nn_new(ctx, 2, (int64_t[]){p, 3 * J});
    int32_t *seg = malloc((size_t)n * J * sizeof(int32_t) + 1);
    if (!mt || !e || !c || !seg) {
        free(seg);
        return NULL;
    }
    for (int64_t q = 0; q < p; q++) {
        const float *fr = &cond->data[q * len + d->cond_dim];
        for (int j = 0; j < J; j++)
            for (int r = 0; r < 3; r++) {
                const float *row = &fr[R * j + 4 * r];
                double mc = 0;
                for (int k = 0; k < 3; k++) {
                    mt->data[q * 9 * J + k * 3 * J + 3 * j + r] = row[k];
                    mc += (double)row[k] * d->center[k];
                }
                e->data[q * 3 * J + 3 * j + r] = (float)((mc + row[3] - d->center[r]) / d->scale);
                c->data[q * 3 * J + 3 * j + r] = (fr[R * j + 12 + r] - d->center[r]) / d->scale;
            }
    }
    for (int64_t i = 0; i < n * J; i++)
        seg[i] = (int32_t)(i / J);
    int64_t nm = 1; /* rows of the per-pose tensors: 1 (broadcast) or n (gathered) */
    if (cond_row) {
        mt = cr_nn_gather_rows(ctx, mt, cond_row, n);
        e = cr_nn_gather_rows(ctx, e, cond_row, n);
        c = cr_nn_gather_rows(ctx, c, cond_row, n);
        nm = n;
    }
    cr_tensor *m3 = cr_nn_reshape(ctx, mt, 3, (int64_t[]){nm, 3, 3 * J});
    cr_tensor *u = cr_nn_add(
        ctx,
        cr_nn_sum_axis(ctx, cr_nn_mul(ctx, cr_nn_reshape(ctx, xn, 3, (int64_t[]){n, 3, 1}), m3), 1,
                       0),
        e); /* (N,3J) */
    cr_tensor *dd = cr_nn_sub(ctx, u, c);
    cr_tensor *d2 = cr_nn_sum_axis(
        ctx, cr_nn_square(ctx, cr_nn_reshape(ctx, dd, 3, (int64_t[]){n, J, 3})), 2, 0); /* (N,J) */
    cr_tensor *wt = cr_nn_segment_softmax(
        ctx, cr_nn_reshape(ctx, cr_nn_mul_scalar(ctx, d2, -itau), 1, (int64_t[]){n * J}), seg, n);
    free(seg);
    cr_tensor *w2 = cr_nn_reshape(ctx, wt, 2, (int64_t[]){n, J});
    cr_tensor *wu = cr_nn_reshape(ctx,
                                  cr_nn_mul(ctx, cr_nn_reshape(ctx, w2, 3, (int64_t[]){n, J, 1}),
                                            cr_nn_reshape(ctx, u, 3, (int64_t[]){n, J, 3})),
                                  2, (int64_t[]){n, 3 * J});
    cr_tensor *f = cr_nn_concat(ctx, 2, (cr_tensor *const[]){wu, w2}, 1); /* (N,4J) */
    if (tan) {
        cr_tensor *m4 = cr_nn_reshape(ctx, mt, 4, (int64_t[]){nm, 3, J, 3});
        cr_tensor *dl = cr_nn_mul_scalar(
            ctx,
            cr_nn_sum_axis(
                ctx, cr_nn_mul(ctx, cr_nn_reshape(ctx, dd, 4, (int64_t[]){n, 1, J, 3}), m4), 3, 0),
            -2.0f * itau); /* (N,3,J) */
        cr_tensor *w3 = cr_nn_reshape(ctx, w2, 3, (int64_t[]){n, 1, J});
        cr_tensor *sw = cr_nn_sum_axis(ctx, cr_nn_mul(ctx, w3, dl), 2, 1); /* (N,3,1) */
        cr_tensor *dw = cr_nn_mul(ctx, w3, cr_nn_sub(ctx, dl, sw));        /* (N,3,J) */
        cr_tensor *df1 =
            cr_nn_add(ctx,
                      cr_nn_mul(ctx, cr_nn_reshape(ctx, dw, 4, (int64_t[]){n, 3, J, 1}),
                                cr_nn_reshape(ctx, u, 4, (int64_t[]){n, 1, J, 3})),
                      cr_nn_mul(ctx, cr_nn_reshape(ctx, w2, 4, (int64_t[]){n, 1, J, 1}), m4));
        cr_tensor *df = cr_nn_concat(
            ctx, 2, (cr_tensor *const[]){cr_nn_reshape(ctx, df1, 3, (int64_t[]){n, 3, 3 * J}), dw},
            2);
        *tan = cr_nn_linear(ctx, df, net->pos[0].w, NULL); /* (N,3,W) */
    }
    return cr_nn_linear(ctx, f, net->pos[0].w, net->pos[0].b);
}

/* ------------------------------------------------------------- forward -- */

/* act(z) and, with tangents t (N,3,W) of z, the tangents of act(z). */
static cr_tensor *softplus_jvp(cr_nn_ctx *ctx, float beta, cr_tensor *z, cr_tensor **t) {
    if (t && *t) {
        cr_tensor *d = cr_act_deriv(ctx, CR_ACT_SOFTPLUS, beta, z);
        int64_t n = z ? z->shape[0] : 0, w = z ? z->shape[1] : 0;
        *t = cr_nn_mul(ctx, *t, cr_nn_reshape(ctx, d, 3, (int64_t[]){n, 1, w}));
    }
    return cr_act_forward(ctx, CR_ACT_SOFTPLUS, beta, z);
}

cr_tensor *cr_swingar_sdf_forward(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *x,
                                  cr_tensor *cond, const int32_t *cond_row, cr_tensor **grad) {
    const cr_swingar_sdf_def *d = &net->def;
    float beta = d->softplus_beta;
    if (grad) *grad = NULL;
    if (!x) return NULL;
    int64_t n = x->numel / 3;
    cr_tensor *x2 = cr_nn_reshape(ctx, x, 2, (int64_t[]){n, 3});
    cr_tensor *c = cr_nn_from(ctx, 1, (int64_t[]){3}, d->center);
    cr_tensor *xn = cr_nn_mul_scalar(ctx, cr_nn_sub(ctx, x2, c), 1.0f / d->scale);
    /* position branch with tangents d(.)/d(x~): T_0 W_0^T = W_0^T (1,3,W),
     * kept on the tape through linear(I, W_0) as layer_jacobian.c does. The
     * chain rule through x~ = (x - c)/scale and S = scale F cancels the
     * scale, so these are also the tangents of S with respect to x. */
    cr_tensor *t = NULL, *p1 = NULL;
    int64_t w = d->width;
    if (grad && !d->articulated) {
        cr_tensor *eye = cr_nn_zeros(ctx, 2, (int64_t[]){3, 3});
        if (!eye) return NULL;
        eye->data[0] = eye->data[4] = eye->data[8] = 1.0f;
        t = cr_nn_reshape(ctx, cr_nn_linear(ctx, eye, net->pos[0].w, NULL), 3,
                          (int64_t[]){1, 3, w});
    }
    if (d->articulated) {
        cr_tensor *z1 = d->articulated == 2
                            ? weighted_input(ctx, net, xn, cond, cond_row, grad ? &t : NULL)
                            : articulated_input(ctx, net, x2, cond, cond_row, grad ? &t : NULL);
        if (!z1) return NULL;
        p1 = softplus_jvp(ctx, beta, z1, grad ? &t : NULL);
    } else {
        p1 = softplus_jvp(ctx, beta, cr_nn_linear(ctx, xn, net->pos[0].w, net->pos[0].b),
                          grad ? &t : NULL);
    }
    cr_tensor *t1 = t;
    if (grad) t = cr_nn_linear(ctx, t1, net->pos[1].w, NULL);
    cr_tensor *p2 = softplus_jvp(ctx, beta, cr_nn_linear(ctx, p1, net->pos[1].w, net->pos[1].b),
                                 grad ? &t : NULL);
    if (grad) t = cr_nn_linear(ctx, t, net->pos[2].w, NULL);
    cr_tensor *p3 = softplus_jvp(ctx, beta, cr_nn_linear(ctx, p2, net->pos[2].w, net->pos[2].b),
                                 grad ? &t : NULL);
    p3 = cr_nn_add(ctx, p3, p1); /* residual: layer 1's output to the fusion's input */
    if (grad) t = cr_nn_add(ctx, t, t1);
    cr_tensor *zf = cr_nn_linear(ctx, p3, net->fuse_wp, net->fuse_b);
    if (d->cond_dim > 0) {
        /* body branch on the P conditioning rows, its fusion half per row */
        cr_tensor *cb = cond && cond->numel / cond->shape[0] != d->cond_dim
                            ? cr_nn_slice(ctx, cond, 1, 0, d->cond_dim)
                            : cond;
        cr_tensor *q1 =
            softplus_jvp(ctx, beta, cr_nn_linear(ctx, cb, net->body[0].w, net->body[0].b), NULL);
        cr_tensor *q2 =
            softplus_jvp(ctx, beta, cr_nn_linear(ctx, q1, net->body[1].w, net->body[1].b), NULL);
        cr_tensor *q3 =
            softplus_jvp(ctx, beta, cr_nn_linear(ctx, q2, net->body[2].w, net->body[2].b), NULL);
        cr_tensor *g = cr_nn_linear(ctx, cr_nn_add(ctx, q3, q1), net->fuse_wq, NULL); /* (P,W) */
        if (cond_row) g = cr_nn_gather_rows(ctx, g, cond_row, n);
        zf = cr_nn_add(ctx, zf, g);
    }
    if (grad) t = cr_nn_linear(ctx, t, net->fuse_wp, NULL);
    cr_tensor *f = softplus_jvp(ctx, beta, zf, grad ? &t : NULL);
    cr_tensor *s = cr_nn_mul_scalar(ctx, cr_nn_linear(ctx, f, net->out.w, net->out.b), d->scale);
    if (grad) {
        t = cr_nn_linear(ctx, t, net->out.w, NULL); /* (N,3,1) */
        /* an all-affine path cannot happen (every layer has softplus), but
         * keep one gradient row per point all the same */
        if (t && t->shape[0] != n) t = cr_nn_add(ctx, t, cr_nn_zeros(ctx, 3, (int64_t[]){n, 1, 1}));
        *grad = t;
    }
    return s;
}

cr_status cr_swingar_sdf_eval(cr_swingar_sdf *net, const float *x, int64_t n, const float *cond,
                              float *s, float *grad, cr_error *err) {
    const cr_swingar_sdf_def *d = &net->def;
    int len = cr_swingar_sdf_cond_len(d);
    if (len > 0 && !cond)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf: the model takes a conditioning vector of %d, got none", len);
    cr_nn_ctx *ctx = net->ctx;
    int was = cr_nn_ctx_grad_enabled(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_status st = CR_OK;
    for (int64_t start = 0; st == CR_OK && start < n; start += EVAL_CHUNK) {
        int64_t m = n - start < EVAL_CHUNK ? n - start : EVAL_CHUNK;
        cr_nn_ctx_reset(ctx);
        cr_tensor *xt = cr_nn_wrap(ctx, 2, (int64_t[]){m, 3}, (float *)&x[3 * start]);
        cr_tensor *ct = len > 0 ? cr_nn_wrap(ctx, 2, (int64_t[]){1, len}, (float *)cond) : NULL;
        cr_tensor *g = NULL;
        cr_tensor *y = cr_swingar_sdf_forward(ctx, net, xt, ct, NULL, grad ? &g : NULL);
        st = cr_nn_ctx_error(ctx, err);
        if (st != CR_OK) break;
        memcpy(&s[start], y->data, (size_t)m * sizeof(float));
        if (grad) memcpy(&grad[3 * start], g->data, (size_t)m * 3 * sizeof(float));
    }
    cr_nn_ctx_reset(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, was);
    return st;
}

/* ---------------------------------------------------------------- loss -- */

cr_tensor *cr_swingar_sdf_loss(cr_nn_ctx *ctx, const cr_swingar_sdf *net, cr_tensor *x,
                               cr_tensor *cond, const int32_t *cond_row, cr_tensor *s_target,
                               cr_tensor *n_target, float mu_e, cr_tensor *parts[3]) {
    cr_tensor *g = NULL;
    cr_tensor *s = cr_swingar_sdf_forward(ctx, net, x, cond, cond_row, &g);
    if (!s || !g) return NULL;
    int64_t n = s->shape[0];
    cr_tensor *g2 = cr_nn_reshape(ctx, g, 2, (int64_t[]){n, 3});
    /* eq. 8: |S - s| + |grad S - n|; eq. 9: (|grad S| - 1)^2 */
    cr_tensor *value = cr_nn_mean(ctx, cr_nn_abs(ctx, cr_nn_sub(ctx, s, s_target)));
    cr_tensor *normal = cr_nn_mean(ctx, cr_nn_norm(ctx, cr_nn_sub(ctx, g2, n_target), NORM_EPS));
    cr_tensor *eik = cr_nn_mean(
        ctx, cr_nn_square(ctx, cr_nn_add_scalar(ctx, cr_nn_norm(ctx, g2, NORM_EPS), -1.0f)));
    if (parts) parts[0] = value, parts[1] = normal, parts[2] = eik;
    return cr_nn_add(ctx, cr_nn_add(ctx, value, normal), cr_nn_mul_scalar(ctx, eik, mu_e));
}

/* ---------------------------------------------------------- save, load -- */

char *cr_swingar_sdf_def_json(const cr_swingar_sdf_def *def) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "kind", "swingar_sdf");
    cJSON_AddNumberToObject(j, "width", def->width);
    cJSON_AddNumberToObject(j, "cond_dim", def->cond_dim);
    cJSON_AddNumberToObject(j, "softplus_beta", def->softplus_beta);
    cJSON *c = cJSON_AddArrayToObject(j, "center");
    for (int k = 0; k < 3; k++)
        cJSON_AddItemToArray(c, cJSON_CreateNumber(def->center[k]));
    cJSON_AddNumberToObject(j, "scale", def->scale);
    cJSON_AddNumberToObject(j, "init_radius", def->init_radius);
    cJSON_AddNumberToObject(j, "articulated", def->articulated);
    cJSON_AddNumberToObject(j, "tau", def->tau);
    cJSON_AddNumberToObject(j, "seed", (double)def->seed);
    char *s = cJSON_PrintUnformatted(j);
    cJSON_Delete(j);
    return s;
}

static int json_num(const cJSON *j, const char *key, double *v) {
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(j, key);
    if (!cJSON_IsNumber(it)) return 0;
    *v = it->valuedouble;
    return 1;
}

cr_status cr_swingar_sdf_def_from_json(const char *json, const char *source,
                                       cr_swingar_sdf_def *def, cr_error *err) {
    *def = cr_swingar_sdf_default_def();
    cJSON *j = json ? cJSON_Parse(json) : NULL;
    const cJSON *kind = cJSON_GetObjectItemCaseSensitive(j, "kind");
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(j, "center");
    double v[7];
    int ok = cJSON_IsString(kind) && strcmp(kind->valuestring, "swingar_sdf") == 0 &&
             cJSON_IsArray(c) && cJSON_GetArraySize(c) == 3 && json_num(j, "width", &v[0]) &&
             json_num(j, "cond_dim", &v[1]) && json_num(j, "softplus_beta", &v[2]) &&
             json_num(j, "scale", &v[3]) && json_num(j, "init_radius", &v[4]) &&
             json_num(j, "seed", &v[5]);
    for (int k = 0; ok && k < 3; k++) {
        const cJSON *e = cJSON_GetArrayItem(c, k);
        ok = cJSON_IsNumber(e);
        if (ok) def->center[k] = (float)e->valuedouble;
    }
    if (ok) {
        def->width = (int)v[0];
        def->cond_dim = (int)v[1];
        def->softplus_beta = (float)v[2];
        def->scale = (float)v[3];
        def->init_radius = (float)v[4];
        def->seed = (uint64_t)v[5];
        /* absent in models saved before the articulated input existed */
        if (json_num(j, "articulated", &v[6])) def->articulated = (int)v[6];
        if (json_num(j, "tau", &v[6])) def->tau = (float)v[6];
    }
    cJSON_Delete(j);
    if (!ok)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: metadata 'config' is not a swingar_sdf model description (need kind, "
                       "width, cond_dim, softplus_beta, center[3], scale, init_radius, seed)",
                       source);
    return check_def(def, err);
}

cr_status cr_swingar_sdf_save(cr_swingar_sdf *net, const char *path, cr_error *err) {
    cr_checkpoint_meta meta = {.config_json = cr_swingar_sdf_def_json(&net->def)};
    cr_status st = cr_checkpoint_save(path, net->params, NULL, &meta, err);
    cJSON_free(meta.config_json);
    return st;
}

cr_status cr_swingar_sdf_load(const char *path, cr_swingar_sdf **out, cr_error *err) {
    *out = NULL;
    cr_safetensors st = {0};
    CR_TRY(cr_safetensors_read(path, &st, err));
    cr_swingar_sdf_def def;
    cr_status s = cr_swingar_sdf_def_from_json(cr_safetensors_meta(&st, "config"), path, &def, err);
    cr_swingar_sdf *net = NULL;
    if (s == CR_OK) s = cr_swingar_sdf_create(&def, &net, err);
    /* a training checkpoint also holds Adam's optim.* tensors: allow them */
    if (s == CR_OK) s = cr_safetensors_to_params(&st, path, net->params, 1, err);
    cr_safetensors_free(&st);
    if (s != CR_OK) {
        cr_swingar_sdf_destroy(net);
        return s;
    }
    *out = net;
    return CR_OK;
}
