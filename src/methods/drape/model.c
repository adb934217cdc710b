/* model.c: the drape method's surface representations.
 *
 *   INR (inr-mesh, inr-uniform, inr-adaptive): p = p0(u,v) + MLP(GE(u,v))
 *       (eq. 2, 6, 14), GE the multi-resolution grid encoding (interpolated
 *       by def->grid_interp: the cubic B-spline by default, since the
 *       paper's bilinear cells show as facets in the surface), p0 the rest
 *       position under (u,v) by barycentric interpolation over the rest
 *       cloth's UV triangles (eq. 15-17). Random initialisation as the paper
 *       has it (grid nodes U(+-1e-4), Instant-NGP's range; the MLP's layers
 *       by cr_mlp's defaults), with the last bias shifted so the output is
 *       zero at the chart centre: the start is the rest shape to about
 *       1e-4 m. The MLP's output is in units of the cloth's size (metres per
 *       UV unit), so clothes of any size drape at the same relative pace. A zero last layer would
 * start exactly there but blocks every gradient into the grid until that layer has grown. Hidden
 * activation: softplus (beta 10) by default, ReLU as an option. The paper names none; a ReLU
 * network is piecewise linear in the grid features, so its surface bends only along kinks that 1 mm
 * structures rarely straddle, and in our runs it stays a smooth dome where the softplus network
 * drapes and folds (docs/drape.md). mesh: the rest mesh's vertex positions are the free variables;
 * between vertices the surface is the piecewise-linear interpolation (one fused op), so it can be
 * scored on local structures like the INR.
 *
 * Leaves out: hash encodings, per-panel networks for multi-panel garments.
 */
#include "drape_internal.h"

#include "crease/nn_layers.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* N query points, V rest vertices. */

enum { EVAL_CHUNK = 32768 };

struct cr_drape_model {
    cr_drape_variant variant;
    const cr_mesh *rest;
    cr_uv_lookup *lookup;
    cr_nn_params *params;
    cr_grid_encoding *grid; /* INR */
    cr_mlp *mlp;            /* INR */
    float out_scale;        /* INR: metres per output unit, the rest chart's metres per UV */
    cr_tensor *verts;       /* mesh: (V,3) "vertices" */
    float *vert_uv;         /* (V,2) the first UV a face gives each vertex */
};

static int is_inr(cr_drape_variant v) {
    return v != CR_DRAPE_MESH;
}

/* Shift the last layer's bias so that the MLP outputs zero at the chart's
 * centre: the random start is then the rest shape up to the small variation
 * of the output over UV (softplus units output log(2)/beta at zero input,
 * which would otherwise lift the whole cloth by centimetres). */
static cr_status centre_output(cr_drape_model *m, cr_error *err) {
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)1 << 20;
    cr_nn_ctx *ctx = NULL;
    CR_TRY(cr_nn_ctx_create(&cd, &ctx, err));
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    const float uv[2] = {0.5f, 0.5f};
    cr_tensor *u = cr_nn_from(ctx, 2, (int64_t[]){1, 2}, uv);
    cr_tensor *y = cr_mlp_forward(ctx, m->mlp, cr_grid_encoding_forward(ctx, m->grid, u));
    cr_status st = cr_nn_ctx_error(ctx, err);
    cr_tensor *bias = m->mlp->layer[m->mlp->def.nlayers - 1].bias;
    if (st == CR_OK && bias)
        for (int c = 0; c < 3; c++)
            bias->data[c] -= y->data[c];
    cr_nn_ctx_destroy(ctx);
    return st;
}

cr_status cr_drape_model_create(const cr_drape_def *def, const cr_mesh *rest, cr_drape_model **out,
                                cr_error *err) {
    *out = NULL;
    if (!cr_mesh_has_uv(rest))
        return CR_FAIL(err, CR_ERR_INVALID, "drape: the rest cloth has no UVs");
    cr_drape_model *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->variant = def->variant;
    m->rest = rest;
    cr_status st = cr_uv_lookup_build(rest, 0, &m->lookup, err);
    if (st == CR_OK) st = cr_nn_params_create(&m->params, err);
    if (st == CR_OK) {
        m->vert_uv = cr_calloc((size_t)rest->nv * 2, sizeof(float), err);
        if (!m->vert_uv) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) {
        /* fill from the last corner first so the first one a face gives wins */
        for (int64_t c = 3 * (int64_t)rest->nf - 1; c >= 0; c--)
            memcpy(&m->vert_uv[2 * (int64_t)rest->tri[c]], &rest->uv[2 * (int64_t)rest->tri_uv[c]],
                   2 * sizeof(float));
    }
    cr_rng rng = cr_rng_make(def->seed, 0);
    if (st == CR_OK && is_inr(def->variant)) {
        cr_grid_encoding_def g = cr_grid_encoding_default_def();
        g.levels = def->grid_levels;
        g.resolution = def->grid_resolution;
        g.features = def->grid_features;
        g.interp = def->grid_interp;
        st = cr_grid_encoding_create(&g, m->params, "grid", &rng, &m->grid, err);
        cr_mlp_def md = cr_mlp_default_def();
        md.act = def->softplus_beta > 0.0f ? CR_ACT_SOFTPLUS : CR_ACT_RELU;
        md.softplus_beta = def->softplus_beta > 0.0f ? def->softplus_beta : 1.0f;
        md.nlayers = def->mlp_layers;
        md.widths[0] = cr_grid_encoding_out_dim(&g);
        for (int i = 1; i < def->mlp_layers; i++)
            md.widths[i] = def->mlp_hidden;
        md.widths[def->mlp_layers] = 3;
        if (st == CR_OK) st = cr_mlp_create(&md, m->params, "mlp", &rng, &m->mlp, err);
        /* The network moves the cloth in units of its own size, so Adam's
         * steps (about lr per parameter) drape a 5 m cloth as fast, relative
         * to its size, as a 1 m one; 1 exactly for the built-in 1 m cloth. */
        float scale = cr_eval_chart_scale(rest);
        m->out_scale = fabsf(scale - 1.0f) < 1e-5f || !(scale > 0.0f) ? 1.0f : scale;
        if (st == CR_OK) st = centre_output(m, err);
    } else if (st == CR_OK) {
        st = cr_nn_params_add(m->params, "vertices", 2, (int64_t[]){rest->nv, 3}, &m->verts, err);
        if (st == CR_OK) memcpy(m->verts->data, rest->pos, (size_t)rest->nv * 3 * sizeof(float));
    }
    if (st != CR_OK) {
        cr_drape_model_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

void cr_drape_model_destroy(cr_drape_model *m) {
    if (!m) return;
    cr_mlp_destroy(m->mlp);
    cr_grid_encoding_destroy(m->grid);
    cr_nn_params_destroy(m->params);
    cr_uv_lookup_destroy(m->lookup);
    free(m->vert_uv);
    free(m);
}

int64_t cr_drape_model_param_count(const cr_drape_model *m) {
    return cr_nn_params_numel(m->params);
}

cr_nn_params *cr_drape_model_params(cr_drape_model *m) {
    return m->params;
}

const cr_uv_lookup *cr_drape_model_lookup(const cr_drape_model *m) {
    return m->lookup;
}

/* ------------------------------------------------------------- rest -- */

enum { REST_CHUNKS = 64 };

typedef struct rest_job {
    const cr_drape_model *m;
    const float *uv;
    float *p0;
    uint8_t *valid;
    int64_t n, chunk;
    int64_t count[REST_CHUNKS]; /* on-chart points per chunk, summed after */
} rest_job;

/* Chunks [begin, end) of `chunk` points each. */
static void rest_range(void *p, int64_t begin, int64_t end) {
    rest_job *j = p;
    for (int64_t c = begin; c < end; c++) {
        int64_t found = 0, hi = (c + 1) * j->chunk < j->n ? (c + 1) * j->chunk : j->n;
        for (int64_t i = c * j->chunk; i < hi; i++) {
            int ok = cr_uv_lookup_rest_position(j->m->lookup, j->m->rest->pos, j->uv[2 * i],
                                                j->uv[2 * i + 1], &j->p0[3 * i]);
            if (!ok) j->p0[3 * i] = j->p0[3 * i + 1] = j->p0[3 * i + 2] = 0.0f;
            if (j->valid) j->valid[i] = (uint8_t)ok;
            found += ok;
        }
        j->count[c] = found;
    }
}

int64_t cr_drape_model_rest(const cr_drape_model *m, const float *uv, int64_t n, float *p0,
                            uint8_t *valid) {
    rest_job j = {.m = m, .uv = uv, .p0 = p0, .valid = valid, .n = n};
    j.chunk = n / REST_CHUNKS + 1;
    cr_parallel_for(REST_CHUNKS, 1, rest_range, &j);
    int64_t total = 0;
    for (int c = 0; c < REST_CHUNKS; c++)
        total += j.count[c];
    return total;
}

/* ------------------------------------------- piecewise-linear surface -- */

typedef struct interp_op {
    cr_fused_op op;
    const int32_t *corner; /* (N,3) vertex indices */
    const float *bary;     /* (N,3) */
    int64_t n;
} interp_op;

static cr_status interp_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                int nin, cr_tensor *const *out, int nout, void **stash,
                                cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    const interp_op *o = op->user;
    const float *v = in[0]->data;
    for (int64_t i = 0; i < o->n; i++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                s += (double)o->bary[3 * i + k] * v[3 * (int64_t)o->corner[3 * i + k] + c];
            out[0]->data[3 * i + c] = (float)s;
        }
    return CR_OK;
}

static cr_status interp_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                 int nin, cr_tensor *const *out, int nout, void *stash,
                                 cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    const interp_op *o = op->user;
    for (int64_t i = 0; i < o->n; i++)
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++)
                in[0]->grad[3 * (int64_t)o->corner[3 * i + k] + c] +=
                    o->bary[3 * i + k] * out[0]->grad[3 * i + c];
    return CR_OK;
}

/* Vertex grid interpolated at uv: points off the chart take the nearest
 * chart point (they are only ever asked for by output sampling at a border). */
static cr_tensor *interp_forward_at(cr_nn_ctx *ctx, cr_drape_model *m, const float *uv, int64_t n) {
    interp_op *o = cr_nn_scratch(ctx, "drape_interp", sizeof *o);
    int32_t *corner = cr_nn_scratch(ctx, "drape_interp", (size_t)n * 3 * sizeof(int32_t) + 1);
    float *bary = cr_nn_scratch(ctx, "drape_interp", (size_t)n * 3 * sizeof(float) + 1);
    if (!o || !corner || !bary) return NULL;
    for (int64_t i = 0; i < n; i++) {
        int32_t f;
        double b[3];
        if (!cr_uv_lookup_find(m->lookup, uv[2 * i], uv[2 * i + 1], &f, b))
            cr_uv_lookup_nearest(m->lookup, uv[2 * i], uv[2 * i + 1], &f, b, NULL);
        for (int k = 0; k < 3; k++) {
            corner[3 * i + k] = m->rest->tri[3 * (int64_t)f + k];
            bary[3 * i + k] = (float)b[k];
        }
    }
    *o = (interp_op){.op = {.name = "drape_interp",
                            .forward = interp_forward,
                            .backward = interp_backward,
                            .user = o},
                     .corner = corner,
                     .bary = bary,
                     .n = n};
    cr_nn_shape shape = {.ndim = 2, .d = {n, 3}};
    cr_tensor *v = m->verts;
    return cr_nn_fused(ctx, &o->op, 1, &v, 1, &shape, NULL);
}

/* ---------------------------------------------------------- forward -- */

cr_tensor *cr_drape_model_forward(cr_nn_ctx *ctx, cr_drape_model *m, const float *uv,
                                  const float *p0, int64_t n) {
    if (!is_inr(m->variant)) return interp_forward_at(ctx, m, uv, n);
    cr_tensor *u = cr_nn_from(ctx, 2, (int64_t[]){n, 2}, uv);
    cr_tensor *base = cr_nn_from(ctx, 2, (int64_t[]){n, 3}, p0);
    cr_tensor *d = cr_mlp_forward(ctx, m->mlp, cr_grid_encoding_forward(ctx, m->grid, u));
    if (m->out_scale != 1.0f) d = cr_nn_mul_scalar(ctx, d, m->out_scale);
    return cr_nn_add(ctx, base, d);
}

cr_tensor *cr_drape_model_vertices(cr_nn_ctx *ctx, cr_drape_model *m) {
    if (!is_inr(m->variant)) return m->verts;
    return cr_drape_model_forward(ctx, m, m->vert_uv, m->rest->pos, m->rest->nv);
}

cr_status cr_drape_model_eval(cr_nn_ctx *ctx, cr_drape_model *m, const float *uv, const float *p0,
                              int64_t n, float *x, cr_error *err) {
    int was = cr_nn_ctx_grad_enabled(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_status st = CR_OK;
    for (int64_t s = 0; s < n && st == CR_OK; s += EVAL_CHUNK) {
        int64_t len = n - s < EVAL_CHUNK ? n - s : EVAL_CHUNK;
        cr_nn_ctx_reset(ctx);
        cr_tensor *y = cr_drape_model_forward(ctx, m, uv + 2 * s, p0 + 3 * s, len);
        st = cr_nn_ctx_error(ctx, err);
        if (st == CR_OK) memcpy(x + 3 * s, y->data, (size_t)len * 3 * sizeof(float));
    }
    cr_nn_ctx_reset(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, was);
    return st;
}
