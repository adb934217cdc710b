/* losses.c: physics energies as losses on the tape: the generic fused op
 * (losses_internal.h has its design), cr_loss_energy over any
 * cr_energy_term, and the weighted sum of loss terms.
 *
 * B batch items, V vertices per position input, P = npos V slots, NE
 * elements of nvert slots. Memory per call: forward NE doubles; backward
 * NE nvert 3 doubles of stash (one item at a time) plus the CSR, P + 1 +
 * NE nvert int32. The op borrows the term's element array and data.
 * Left out: Hessians (training needs gradients only), second-order
 * backward.
 */
#include "methods/common/losses_internal.h"

#include <math.h>
#include <string.h>

enum {
    ELEM_GRAIN = 256,  /* elements per parallel chunk */
    VERT_GRAIN = 1024, /* vertices per parallel chunk of the gather */
};

/* ------------------------------------------------------- validation -- */

static cr_status check_inputs(loss_spec *s, cr_tensor *const *in, int nin, int64_t *B_out,
                              cr_error *err) {
    char a[64], b[64];
    const char *t = s->term ? s->term : "?";
    if (nin != s->npos + s->has_aux)
        return CR_FAIL(err, CR_ERR_INVALID, "loss_energy(%s): %d inputs, expected %d", t, nin,
                       s->npos + s->has_aux);
    const cr_tensor *x = in[0];
    if (!((x->ndim == 2 && x->shape[1] == 3) || (x->ndim == 3 && x->shape[2] == 3)))
        return CR_FAIL(err, CR_ERR_SHAPE, "loss_energy(%s): x must be (V,3) or (B,V,3), got %s", t,
                       cr_nn_shape_str(x, a, sizeof a));
    for (int p = 1; p < s->npos; p++)
        if (!cr_nn_same_shape(in[p], x))
            return CR_FAIL(err, CR_ERR_SHAPE,
                           "loss_energy(%s): position input %d is %s, input 0 is %s", t, p,
                           cr_nn_shape_str(in[p], a, sizeof a), cr_nn_shape_str(x, b, sizeof b));
    const int64_t B = x->ndim == 3 ? x->shape[0] : 1, V = x->shape[x->ndim - 2];
    if (!(s->nvert >= 1 && s->nvert <= CR_ENERGY_MAX_VERTS) || s->nelem < 0 || !s->kernel)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "loss_energy(%s): malformed term (nelem %d, nvert %d, kernel %s)", t,
                       s->nelem, s->nvert, s->kernel ? "set" : "NULL");
    if (!isfinite(s->weight))
        return CR_FAIL(err, CR_ERR_INVALID, "loss_energy(%s): weight %g is not finite", t,
                       s->weight);
    const int64_t P = (int64_t)s->npos * V;
    if (!s->elem) {
        if (s->nvert != 1 || s->nelem != V)
            return CR_FAIL(err, CR_ERR_SHAPE,
                           "loss_energy(%s): per-vertex term of %d vertices, x has %lld", t,
                           s->nelem, (long long)V);
    } else {
        const int64_t n = (int64_t)s->nelem * s->nvert;
        for (int64_t k = 0; k < n; k++)
            if (s->elem[k] < 0 || s->elem[k] >= P)
                return CR_FAIL(err, CR_ERR_RANGE,
                               "loss_energy(%s): element %lld names vertex %d, outside [0,%lld)", t,
                               (long long)(k / s->nvert), s->elem[k], (long long)P);
    }
    if (s->has_aux) {
        const cr_tensor *r = in[s->npos];
        const int ok = (r->ndim == 1 && r->shape[0] == s->nelem) ||
                       (r->ndim == 2 && r->shape[0] == B && r->shape[1] == s->nelem);
        if (!ok)
            return CR_FAIL(err, CR_ERR_SHAPE,
                           "loss_energy(%s): per-element input must be (%d) or (%lld,%d), got %s",
                           t, s->nelem, (long long)B, s->nelem, cr_nn_shape_str(r, a, sizeof a));
    }
    s->V = V;
    *B_out = B;
    return CR_OK;
}

/* ------------------------------------------------------------- loops -- */

typedef struct range_job {
    const loss_spec *s;
    int64_t b;
    const float *x[3]; /* item b of each position input, (V,3) */
    const float *aux;  /* item b's per-element parameters (NE), or NULL */
    float *aux_grad;   /* their grads (NE), or NULL */
    double *val;       /* forward: (NE) energies */
    const float *gout; /* backward: dL/d(out) of item b, (NE) or (1) */
    double *stash;     /* backward: (NE, nvert, 3) or NULL when x needs no grad */
    const int32_t *csr_start, *csr_slot;
    float *x_grad[3]; /* item b of each position input's grad, or NULL */
} range_job;

static void gather_element(const range_job *j, int32_t e, double *xe) {
    const loss_spec *s = j->s;
    for (int k = 0; k < s->nvert; k++) {
        const int64_t u = s->elem ? s->elem[(int64_t)e * s->nvert + k] : e;
        const float *p = j->x[u / s->V] + 3 * (u % s->V);
        xe[3 * k] = p[0], xe[3 * k + 1] = p[1], xe[3 * k + 2] = p[2];
    }
}

static void forward_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    double xe[3 * CR_ENERGY_MAX_VERTS];
    for (int64_t e = begin; e < end; e++) {
        gather_element(j, (int32_t)e, xe);
        j->val[e] = j->s->kernel(j->s, j->b, (int32_t)e, xe, j->aux ? j->aux[e] : 0.0, NULL, NULL);
    }
}

/* Forward with the gradient as well: values into val, the unscaled
 * gradients into stash (NE, nvert, 3) for backward to scale. */
static void forward_grad_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    const int n = 3 * j->s->nvert;
    double xe[3 * CR_ENERGY_MAX_VERTS];
    for (int64_t e = begin; e < end; e++) {
        gather_element(j, (int32_t)e, xe);
        j->val[e] = j->s->kernel(j->s, j->b, (int32_t)e, xe, j->aux ? j->aux[e] : 0.0,
                                 j->stash + n * e, NULL);
    }
}

/* Scale forward's gradients by the output grad, in place (the same product
 * c * g the kernel call below makes, so the same bits). */
static void scale_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    const loss_spec *s = j->s;
    const int n = 3 * s->nvert;
    for (int64_t e = begin; e < end; e++) {
        const double c = s->weight * (s->per_element ? j->gout[e] : j->gout[0]);
        for (int k = 0; k < n; k++)
            j->stash[n * e + k] = c * j->stash[n * e + k];
    }
}

static void backward_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    const loss_spec *s = j->s;
    const int n = 3 * s->nvert;
    double xe[3 * CR_ENERGY_MAX_VERTS], g[3 * CR_ENERGY_MAX_VERTS], ga = 0.0;
    for (int64_t e = begin; e < end; e++) {
        const double c = s->weight * (s->per_element ? j->gout[e] : j->gout[0]);
        gather_element(j, (int32_t)e, xe);
        s->kernel(s, j->b, (int32_t)e, xe, j->aux ? j->aux[e] : 0.0, j->stash ? g : NULL,
                  j->aux_grad ? &ga : NULL);
        if (j->stash)
            for (int k = 0; k < n; k++)
                j->stash[n * e + k] = c * g[k];
        if (j->aux_grad) j->aux_grad[e] += (float)(c * ga);
    }
}

/* Each vertex row r sums its slots in element order, input by input (so
 * inputs that are one tensor still see one writer per row). */
static void gather_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    const loss_spec *s = j->s;
    for (int64_t r = begin; r < end; r++)
        for (int q = 0; q < s->npos; q++) {
            if (!j->x_grad[q]) continue;
            const int64_t u = q * s->V + r;
            double acc[3] = {0.0, 0.0, 0.0};
            for (int32_t k = j->csr_start[u]; k < j->csr_start[u + 1]; k++) {
                const double *g = j->stash + 3 * (int64_t)j->csr_slot[k];
                acc[0] += g[0], acc[1] += g[1], acc[2] += g[2];
            }
            float *out = j->x_grad[q] + 3 * r;
            out[0] += (float)acc[0], out[1] += (float)acc[1], out[2] += (float)acc[2];
        }
}

/* --------------------------------------------------------- the op -- */

static cr_status loss_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                              cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)nout;
    loss_spec *s = op->user;
    int64_t B = 0;
    CR_TRY(check_inputs(s, in, nin, &B, err));
    const int64_t NE = s->nelem, V = s->V;
    double *val = cr_nn_scratch(ctx, "loss_energy", sizeof(double) * (size_t)(NE + 1));
    if (!val) return CR_FAIL(err, CR_ERR_MEMORY, "loss_energy(%s): arena full", s->term);
    const cr_tensor *aux = s->has_aux ? in[s->npos] : NULL;
    const int64_t aux_stride = aux && aux->ndim == 2 ? NE : 0;
    /* One item whose positions will get a gradient (and no aux gradient):
     * the kernel's gradient comes with its value here, and backward only
     * scales it, instead of calling the kernel again (for the drape's
     * collision term that is a second nearest-vertex search per point). */
    int need_x = 0;
    for (int q = 0; q < s->npos; q++)
        need_x |= in[q]->requires_grad;
    double *g = NULL;
    if (B == 1 && need_x && !(aux && aux->requires_grad) && cr_nn_ctx_grad_enabled(ctx)) {
        g = cr_nn_scratch(ctx, "loss_energy", sizeof(double) * (size_t)(3 * NE * s->nvert + 1));
        if (!g) return CR_FAIL(err, CR_ERR_MEMORY, "loss_energy(%s): arena full", s->term);
    }
    *stash = g;
    float *y = out[0]->data;
    for (int64_t b = 0; b < B; b++) {
        range_job j = {.s = s, .b = b, .val = val, .stash = g};
        for (int q = 0; q < s->npos; q++)
            j.x[q] = in[q]->data + 3 * V * b;
        if (aux) j.aux = aux->data + aux_stride * b;
        if (s->prepare) CR_TRY(s->prepare(s, b, j.x[0], err));
        cr_parallel_for(NE, ELEM_GRAIN, g ? forward_grad_range : forward_range, &j);
        if (s->per_element) {
            for (int64_t e = 0; e < NE; e++)
                y[NE * b + e] = (float)(s->weight * val[e]);
        } else {
            double sum = 0.0;
            for (int64_t e = 0; e < NE; e++)
                sum += val[e];
            y[b] = (float)(s->weight * sum);
        }
    }
    return CR_OK;
}

static cr_status loss_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                               cr_tensor *const *out, int nout, void *stash, cr_error *err) {
    (void)nin, (void)nout;
    const loss_spec *s = op->user;
    const int64_t NE = s->nelem, V = s->V, P = s->npos * V, n = NE * s->nvert;
    const int64_t B = in[0]->ndim == 3 ? in[0]->shape[0] : 1;
    int need_x = 0;
    for (int q = 0; q < s->npos; q++)
        need_x |= in[q]->requires_grad;
    const cr_tensor *aux = s->has_aux ? in[s->npos] : NULL;
    const int need_aux = aux && aux->requires_grad;
    if (!need_x && !need_aux) return CR_OK;
    int32_t *start = NULL, *slot = NULL;
    double *st = NULL;
    if (need_x) {
        /* vertex -> slots CSR, slots in increasing element order */
        start = cr_nn_scratch(ctx, "loss_energy", sizeof(int32_t) * (size_t)(P + 1));
        slot = cr_nn_scratch(ctx, "loss_energy", sizeof(int32_t) * (size_t)(n + 1));
        st =
            stash ? stash : cr_nn_scratch(ctx, "loss_energy", sizeof(double) * (size_t)(3 * n + 1));
        if (!start || !slot || !st)
            return CR_FAIL(err, CR_ERR_MEMORY, "loss_energy(%s): arena full", s->term);
        memset(start, 0, sizeof(int32_t) * (size_t)(P + 1));
        for (int64_t k = 0; k < n; k++)
            start[(s->elem ? s->elem[k] : k) + 1]++;
        for (int64_t u = 0; u < P; u++)
            start[u + 1] += start[u];
        int32_t *fill = cr_nn_scratch(ctx, "loss_energy", sizeof(int32_t) * (size_t)(P + 1));
        if (!fill) return CR_FAIL(err, CR_ERR_MEMORY, "loss_energy(%s): arena full", s->term);
        memcpy(fill, start, sizeof(int32_t) * (size_t)P);
        for (int64_t k = 0; k < n; k++)
            slot[fill[s->elem ? s->elem[k] : k]++] = (int32_t)k;
    }
    const int64_t aux_stride = aux && aux->ndim == 2 ? NE : 0;
    for (int64_t b = 0; b < B; b++) {
        range_job j = {.s = s, .b = b, .stash = st, .csr_start = start, .csr_slot = slot};
        j.gout = out[0]->grad + (s->per_element ? NE * b : b);
        for (int q = 0; q < s->npos; q++) {
            j.x[q] = in[q]->data + 3 * V * b;
            j.x_grad[q] = in[q]->requires_grad ? in[q]->grad + 3 * V * b : NULL;
        }
        if (aux) {
            j.aux = aux->data + aux_stride * b;
            j.aux_grad = need_aux ? aux->grad + aux_stride * b : NULL;
        }
        cr_parallel_for(NE, ELEM_GRAIN, stash ? scale_range : backward_range, &j);
        if (need_x) cr_parallel_for(V, VERT_GRAIN, gather_range, &j);
    }
    return CR_OK;
}

loss_spec *cr_loss_spec_new(cr_nn_ctx *ctx) {
    loss_spec *s = cr_nn_scratch(ctx, "loss_energy", sizeof *s);
    if (!s) return NULL;
    memset(s, 0, sizeof *s);
    s->op = (cr_fused_op){
        .name = "loss_energy", .forward = loss_forward, .backward = loss_backward, .user = s};
    s->npos = 1;
    s->weight = 1.0;
    return s;
}

cr_tensor *cr_loss_spec_run(cr_nn_ctx *ctx, loss_spec *s, cr_tensor *const *in) {
    const cr_tensor *x = in[0];
    const int64_t B = x->ndim == 3 ? x->shape[0] : 1;
    cr_nn_shape shape;
    if (s->per_element)
        shape = x->ndim == 3 ? (cr_nn_shape){.ndim = 2, .d = {B, s->nelem}}
                             : (cr_nn_shape){.ndim = 1, .d = {s->nelem}};
    else
        shape = (cr_nn_shape){.ndim = 1, .d = {B}};
    return cr_nn_fused(ctx, &s->op, s->npos + s->has_aux, in, 1, &shape, NULL);
}

/* ----------------------------------------------------- plain terms -- */

static double term_kernel(const loss_spec *s, int64_t b, int32_t e, const double *xe, double aux,
                          double *g, double *g_aux) {
    (void)b, (void)aux, (void)g_aux;
    return s->t.kernel(s->t.data, e, xe, g, NULL);
}

static cr_tensor *plain(cr_nn_ctx *ctx, const cr_energy_term *term, cr_tensor *x, int per_element) {
    if (!ctx || !term || !x) return NULL;
    loss_spec *s = cr_loss_spec_new(ctx);
    if (!s) return NULL;
    s->t = *term;
    s->term = term->name ? term->name : "unnamed";
    s->nelem = term->nelem;
    s->nvert = term->nvert;
    s->elem = term->elem;
    s->weight = term->weight;
    s->per_element = per_element;
    s->kernel = term->kernel ? term_kernel : NULL;
    return cr_loss_spec_run(ctx, s, &x);
}

cr_tensor *cr_loss_energy(cr_nn_ctx *ctx, const cr_energy_term *term, cr_tensor *x) {
    return plain(ctx, term, x, 0);
}

cr_tensor *cr_loss_energy_per_element(cr_nn_ctx *ctx, const cr_energy_term *term, cr_tensor *x) {
    return plain(ctx, term, x, 1);
}

/* ------------------------------------------------------ weighted sum -- */

cr_tensor *cr_loss_weighted_sum(cr_nn_ctx *ctx, cr_tensor *const *terms, const float *w, int n,
                                cr_tensor **weighted) {
    if (!ctx) return NULL;
    if (n <= 0 || !terms) return cr_nn_scalar(ctx, 0.0f);
    cr_tensor *total = NULL;
    for (int k = 0; k < n; k++) {
        cr_tensor *sk = cr_nn_sum(ctx, terms[k]);
        if (w) sk = cr_nn_mul_scalar(ctx, sk, w[k]);
        if (weighted) weighted[k] = sk;
        if (!sk) return NULL;
        total = total ? cr_nn_add(ctx, total, sk) : sk;
    }
    return total;
}
