/* nn_gradcheck.c: the central-difference gradient checker (see nn_gradcheck.h). */
#include "nn_gradcheck.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

nn_gradcheck_def nn_gradcheck_default_def(void) {
    nn_gradcheck_def d;
    memset(&d, 0, sizeof d);
    d.name = "gradcheck";
    d.step = 1e-3;
    d.tol = 1e-2;
    d.seed = 1234;
    d.arena_bytes = (size_t)16 << 20;
    d.max_reports = 5;
    return d;
}

typedef struct checker {
    const nn_gradcheck_def *def;
    cr_nn_ctx *ctx;
    int nin;
    nn_gradcheck_input *in;
    cr_nn_params *params;
    nn_gradcheck_fn fn;
    void *user;
    float *w; /* (numel of y) loss weights */
    int64_t nw;
    cr_rng rng;
    nn_gradcheck_result res;
    int reports;
} checker;

/* Build y from the current host values. wrapped[i] receives the input
 * tensors (for reading their grads). */
static cr_tensor *build(checker *c, int with_grad, cr_tensor **wrapped) {
    cr_nn_ctx_reset(c->ctx);
    cr_nn_ctx_set_grad_enabled(c->ctx, with_grad);
    for (int i = 0; i < c->nin; i++) {
        wrapped[i] = cr_nn_wrap(c->ctx, c->in[i].ndim, c->in[i].shape, c->in[i].data);
        if (wrapped[i]) wrapped[i]->requires_grad = (uint8_t)(with_grad && c->in[i].requires_grad);
    }
    cr_tensor *y = c->fn(c->ctx, wrapped, c->user);
    cr_error err = {0};
    if (cr_nn_ctx_error(c->ctx, &err) != CR_OK || !y) {
        fprintf(stderr, "    gradcheck %s: build failed: %s\n", c->def->name,
                err.status != CR_OK ? err.msg : "NULL output");
        return NULL;
    }
    return y;
}

/* L = sum_i w_i y_i in double. */
static int loss_fd(checker *c, double *L) {
    cr_tensor *wrapped[16];
    cr_tensor *y = build(c, 0, wrapped);
    if (!y || y->numel != c->nw) return 0;
    double s = 0.0;
    for (int64_t i = 0; i < y->numel; i++)
        s += (double)c->w[i] * y->data[i];
    *L = s;
    return 1;
}

static void compare(checker *c, const char *label, int64_t k, double g_tape, double g_fd) {
    double err = fabs(g_tape - g_fd) / fmax(1.0, fabs(g_fd));
    c->res.checked++;
    if (err > c->res.max_err) c->res.max_err = err;
    if (err <= c->def->tol) return;
    c->res.failed++;
    if (c->reports++ < c->def->max_reports)
        fprintf(stderr, "    gradcheck %s: %s[%lld]: tape %.7g, finite difference %.7g\n",
                c->def->name, label, (long long)k, g_tape, g_fd);
}

/* Check elements of one host array against its tape gradient. */
static int check_array(checker *c, const char *label, float *data, const float *grad, int64_t n) {
    int64_t count = c->def->max_elems > 0 && n > c->def->max_elems ? c->def->max_elems : n;
    for (int64_t t = 0; t < count; t++) {
        int64_t k = count == n ? t : (int64_t)cr_rng_below(&c->rng, (uint32_t)n);
        float orig = data[k];
        float xp = (float)(orig + c->def->step), xm = (float)(orig - c->def->step);
        double Lp, Lm;
        data[k] = xp;
        int ok = loss_fd(c, &Lp);
        data[k] = xm;
        ok = ok && loss_fd(c, &Lm);
        data[k] = orig;
        if (!ok) return 0;
        compare(c, label, k, grad ? grad[k] : 0.0, (Lp - Lm) / ((double)xp - (double)xm));
    }
    return 1;
}

int64_t nn_gradcheck(const nn_gradcheck_def *def, int nin, nn_gradcheck_input *in,
                     cr_nn_params *params, nn_gradcheck_fn fn, void *user,
                     nn_gradcheck_result *res) {
    CR_ASSERT(nin >= 0 && nin <= 16);
    checker c;
    memset(&c, 0, sizeof c);
    c.def = def;
    c.nin = nin;
    c.in = in;
    c.params = params;
    c.fn = fn;
    c.user = user;
    c.rng = cr_rng_make(def->seed, 77);
    int64_t result = -1;
    float **in_grads = calloc((size_t)nin + 1, sizeof *in_grads);
    float *param_grads = NULL;
    cr_nn_ctx_def cdef = cr_nn_ctx_default_def();
    cdef.arena_bytes = def->arena_bytes;
    cr_error err = {0};
    if (!in_grads || cr_nn_ctx_create(&cdef, &c.ctx, &err) != CR_OK) goto done;

    /* Tape gradients at the base point. */
    cr_tensor *wrapped[16];
    cr_tensor *y = build(&c, 1, wrapped);
    if (!y) goto done;
    c.nw = y->numel;
    c.w = malloc((size_t)(c.nw > 0 ? c.nw : 1) * sizeof(float));
    if (!c.w) goto done;
    for (int64_t i = 0; i < c.nw; i++)
        c.w[i] = 2.0f * cr_rng_uniformf(&c.rng) - 1.0f;
    cr_tensor *wt = cr_nn_from(c.ctx, y->ndim, y->shape, c.w);
    cr_tensor *loss = cr_nn_sum(c.ctx, cr_nn_mul(c.ctx, y, wt));
    if (params) cr_nn_params_zero_grad(params);
    if (cr_nn_backward(c.ctx, loss, &err) != CR_OK) {
        fprintf(stderr, "    gradcheck %s: backward failed: %s\n", def->name, err.msg);
        goto done;
    }
    for (int i = 0; i < nin; i++) {
        if (!in[i].requires_grad || !wrapped[i]->grad) continue;
        in_grads[i] = malloc((size_t)wrapped[i]->numel * sizeof(float));
        if (!in_grads[i]) goto done;
        memcpy(in_grads[i], wrapped[i]->grad, (size_t)wrapped[i]->numel * sizeof(float));
    }
    if (params) {
        int64_t n;
        float *g = cr_nn_params_grad(params, &n);
        param_grads = malloc((size_t)(n > 0 ? n : 1) * sizeof(float));
        if (!param_grads) goto done;
        if (n > 0) memcpy(param_grads, g, (size_t)n * sizeof(float));
    }

    /* Finite differences. */
    for (int i = 0; i < nin; i++) {
        if (!in[i].requires_grad) continue;
        char label[32];
        snprintf(label, sizeof label, "input %d", i);
        int64_t n = 1;
        for (int d = 0; d < in[i].ndim; d++)
            n *= in[i].shape[d];
        if (!check_array(&c, label, in[i].data, in_grads[i], n)) goto done;
    }
    if (params) {
        float *base = cr_nn_params_data(params, NULL);
        for (int p = 0; p < cr_nn_params_count(params); p++) {
            const char *name;
            cr_tensor *t = cr_nn_params_at(params, p, &name);
            if (!t->requires_grad) continue;
            if (!check_array(&c, name, t->data, param_grads + (t->data - base), t->numel))
                goto done;
        }
    }
    result = c.res.failed;

done:
    if (res) *res = c.res;
    for (int i = 0; in_grads && i < nin; i++)
        free(in_grads[i]);
    free(in_grads);
    free(param_grads);
    free(c.w);
    cr_nn_ctx_destroy(c.ctx);
    return result;
}

/* ------------------------------------------------------- conveniences -- */

nn_gradcheck_input nn_gradcheck_in(int ndim, const int64_t *shape, float *data) {
    nn_gradcheck_input in;
    memset(&in, 0, sizeof in);
    in.ndim = ndim;
    for (int i = 0; i < ndim; i++)
        in.shape[i] = shape[i];
    in.data = data;
    in.requires_grad = 1;
    return in;
}

int64_t nn_gradcheck_quick(const char *name, int nin, nn_gradcheck_input *in, cr_nn_params *params,
                           nn_gradcheck_fn fn, void *user) {
    nn_gradcheck_def def = nn_gradcheck_default_def();
    def.name = name;
    return nn_gradcheck(&def, nin, in, params, fn, user, NULL);
}

void nn_gradcheck_fill(float *x, int64_t n, float lo, float hi, float gap, uint64_t seed) {
    cr_rng r = cr_rng_make(seed, 3);
    for (int64_t i = 0; i < n; i++) {
        float v = lo + (hi - lo) * cr_rng_uniformf(&r);
        if (fabsf(v) < gap) v = v < 0 ? v - gap : v + gap;
        x[i] = v;
    }
}

cr_nn_ctx *nn_gradcheck_ctx(size_t bytes) {
    cr_nn_ctx_def def = cr_nn_ctx_default_def();
    def.arena_bytes = bytes;
    cr_nn_ctx *ctx = NULL;
    cr_error err = {0};
    return cr_nn_ctx_create(&def, &ctx, &err) == CR_OK ? ctx : NULL;
}
