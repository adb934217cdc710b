/* tensor.c: the context (arena, error, grad mode), tensor allocation, views
 * and host-side fills.
 *
 * Every tensor of a step is one arena allocation: the struct, then its data
 * (64-byte aligned). Grads are allocated separately and only when a gradient
 * reaches the tensor. Views (reshape, detach, first-axis slices) are a new
 * struct over the same data; a view of a tensor that requires grad shares its
 * grad buffer too, so gradients flow through views without tape nodes.
 * Leaves out: strided views (every tensor is contiguous), dtypes other than
 * float32.
 */
#include "nn/tape.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { CTX_COOKIE = 0x6e6e6378u }; /* "nncx" */

/* ------------------------------------------------------------ context -- */

cr_nn_ctx_def cr_nn_ctx_default_def(void) {
    cr_nn_ctx_def d;
    memset(&d, 0, sizeof d);
    d.arena_bytes = (size_t)64 << 20;
    d.device = CR_DEVICE_CPU;
    d.cookie = CTX_COOKIE;
    return d;
}

cr_status cr_nn_ctx_create(const cr_nn_ctx_def *def, cr_nn_ctx **out, cr_error *err) {
    CR_ASSERT(def && out && def->cookie == CTX_COOKIE);
    *out = NULL;
    if (def->device != CR_DEVICE_CPU)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "nn context: only the CPU device is built");
    if (def->arena_bytes == 0)
        return CR_FAIL(err, CR_ERR_INVALID, "nn context: arena_bytes must be positive");
    cr_nn_ctx *ctx = cr_calloc(1, sizeof *ctx, err);
    if (!ctx) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = cr_arena_init(&ctx->arena, def->arena_bytes, err);
    if (st != CR_OK) {
        free(ctx);
        return st;
    }
    ctx->be = cr_nn_backend_cpu();
    ctx->device = def->device;
    ctx->grad_enabled = 1;
    *out = ctx;
    return CR_OK;
}

void cr_nn_ctx_destroy(cr_nn_ctx *ctx) {
    if (!ctx) return;
    cr_arena_free(&ctx->arena);
    free(ctx);
}

/* *ctx made again, gradient off, with an arena of `bytes`. */
static cr_status remake(cr_nn_ctx **ctx, size_t bytes, cr_error *err) {
    cr_nn_ctx_destroy(*ctx);
    *ctx = NULL;
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = bytes;
    CR_TRY(cr_nn_ctx_create(&cd, ctx, err));
    cr_nn_ctx_set_grad_enabled(*ctx, 0);
    return CR_OK;
}

cr_status cr_nn_ctx_fit(cr_nn_ctx **ctx, size_t arena_bytes, int keep,
                        cr_status (*trial)(void *user, cr_error *err), void *user, size_t *peak,
                        cr_error *err) {
    enum { RESERVE_GIB = 8, FLOOR_MIB = 64, SLACK_MIB = 1 };
    size_t bytes = arena_bytes ? arena_bytes : (size_t)RESERVE_GIB << 30;
    cr_status st;
    while ((st = remake(ctx, bytes, err)) != CR_OK && !arena_bytes &&
           bytes > ((size_t)FLOOR_MIB << 20))
        bytes /= 2;
    if (st == CR_OK) st = trial(user, err);
    if (st != CR_OK) return st;
    const size_t high = cr_nn_ctx_arena_peak(*ctx);
    if (peak) *peak = high;
    if (arena_bytes || keep) return CR_OK;
    return remake(ctx, high + high / 8 + ((size_t)SLACK_MIB << 20), err);
}

void cr_nn_ctx_reset(cr_nn_ctx *ctx) {
    cr_arena_reset(&ctx->arena);
    ctx->tail = NULL;
    ctx->tape_len = 0;
    ctx->backward_done = 0;
    ctx->fresh_grad = NULL;
    ctx->gat_edges = NULL;
    memset(&ctx->err, 0, sizeof ctx->err);
}

cr_status cr_nn_ctx_error(const cr_nn_ctx *ctx, cr_error *err) {
    if (ctx->err.status != CR_OK && err) *err = ctx->err;
    return ctx->err.status;
}

void cr_nn_ctx_set_grad_enabled(cr_nn_ctx *ctx, int enabled) {
    ctx->grad_enabled = enabled != 0;
}

int cr_nn_ctx_grad_enabled(const cr_nn_ctx *ctx) {
    return ctx->grad_enabled;
}

size_t cr_nn_ctx_arena_used(const cr_nn_ctx *ctx) {
    return ctx->arena.used;
}

size_t cr_nn_ctx_arena_peak(const cr_nn_ctx *ctx) {
    return ctx->arena.peak;
}

size_t cr_nn_ctx_arena_capacity(const cr_nn_ctx *ctx) {
    return ctx->arena.capacity;
}

int64_t cr_nn_ctx_tape_length(const cr_nn_ctx *ctx) {
    return ctx->tape_len;
}

void *cr_nn_scratch(cr_nn_ctx *ctx, const char *who, size_t bytes) {
    if (ctx->err.status != CR_OK) return NULL;
    return cr_nn_alloc(ctx, who, bytes);
}

/* ------------------------------------------------------------ helpers -- */

void cr_nn_fail(cr_nn_ctx *ctx, cr_status st, const char *file, int line, const char *fmt, ...) {
    if (ctx->err.status != CR_OK) return;
    ctx->err.status = st;
    ctx->err.src_file = file;
    ctx->err.src_line = line;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(ctx->err.msg, sizeof ctx->err.msg, fmt, ap);
    va_end(ap);
}

int cr_nn_begin(cr_nn_ctx *ctx, const char *op, int n, cr_tensor *const *ts) {
    if (ctx->err.status != CR_OK) return 0;
    for (int i = 0; i < n; i++) {
        if (!ts[i]) {
            NN_FAIL(ctx, CR_ERR_INVALID, "%s: input %d is NULL", op, i);
            return 0;
        }
    }
    return 1;
}

void *cr_nn_alloc(cr_nn_ctx *ctx, const char *who, size_t bytes) {
    void *p = cr_arena_alloc(&ctx->arena, bytes, NULL);
    if (!p) {
        size_t used = ctx->arena.used, cap = ctx->arena.capacity;
        NN_FAIL(ctx, CR_ERR_MEMORY,
                "%s: arena exhausted: need %zu bytes, %zu of %zu free "
                "(raise cr_nn_ctx_def.arena_bytes)",
                who, bytes, cap - (used < cap ? used : cap), cap);
    }
    return p;
}

/* Bytes of a tensor struct rounded up so the data after it stays aligned. */
static size_t header_bytes(void) {
    return (sizeof(cr_tensor) + 63) / 64 * 64;
}

/* Validate a shape and compute its element count; -1 on a bad shape. */
static int64_t shape_numel(cr_nn_ctx *ctx, const char *who, int ndim, const int64_t *shape) {
    if (ndim < 0 || ndim > CR_NN_MAX_DIMS) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: %d dimensions, at most %d supported", who, ndim,
                CR_NN_MAX_DIMS);
        return -1;
    }
    int64_t n = 1;
    for (int i = 0; i < ndim; i++) {
        if (shape[i] < 0 || (shape[i] > 0 && n > (INT64_MAX / 8) / shape[i])) {
            NN_FAIL(ctx, CR_ERR_SHAPE, "%s: bad size %lld in dimension %d", who,
                    (long long)shape[i], i);
            return -1;
        }
        n *= shape[i];
    }
    return n;
}

static void set_shape(cr_tensor *t, int ndim, const int64_t *shape, int64_t numel) {
    t->ndim = ndim;
    for (int i = 0; i < CR_NN_MAX_DIMS; i++)
        t->shape[i] = i < ndim ? shape[i] : 1;
    t->numel = numel;
}

/* A struct (and, when with_data, its data) from the arena. */
static cr_tensor *alloc_tensor(cr_nn_ctx *ctx, const char *who, int ndim, const int64_t *shape,
                               int with_data) {
    int64_t numel = shape_numel(ctx, who, ndim, shape);
    if (numel < 0) return NULL;
    size_t bytes = header_bytes() + (with_data ? (size_t)numel * sizeof(float) : 0);
    unsigned char *p = cr_nn_alloc(ctx, who, bytes);
    if (!p) return NULL;
    cr_tensor *t = (cr_tensor *)p;
    memset(t, 0, sizeof *t);
    set_shape(t, ndim, shape, numel);
    t->data = with_data ? (float *)(p + header_bytes()) : NULL;
    t->device = ctx->device;
    t->op = CR_OP_NONE;
    return t;
}

cr_tensor *cr_nn_tensor(cr_nn_ctx *ctx, const char *who, int ndim, const int64_t *shape) {
    return alloc_tensor(ctx, who, ndim, shape, 1);
}

float *cr_nn_grad_uninit(cr_nn_ctx *ctx, cr_tensor *t, const char *who) {
    if (t->grad) return t->grad;
    t->grad = cr_nn_alloc(ctx, who, (size_t)t->numel * sizeof(float));
    return t->grad;
}

float *cr_nn_grad(cr_nn_ctx *ctx, cr_tensor *t, const char *who) {
    if (t->grad) return t->grad;
    float *g = cr_nn_grad_uninit(ctx, t, who);
    if (g) ctx->be->fill(g, t->numel, 0.0f);
    return g;
}

int32_t *cr_nn_index_copy(cr_nn_ctx *ctx, const char *who, const int32_t *idx, int64_t n) {
    int32_t *c = cr_nn_alloc(ctx, who, (size_t)n * sizeof(int32_t));
    if (c && n > 0) memcpy(c, idx, (size_t)n * sizeof(int32_t));
    return c;
}

int cr_nn_axis(cr_nn_ctx *ctx, const char *op, const cr_tensor *t, int axis, int *out) {
    int a = axis < 0 ? axis + t->ndim : axis;
    if (a < 0 || a >= t->ndim) {
        char s[64];
        NN_FAIL(ctx, CR_ERR_SHAPE, "%s: axis %d out of range for shape %s", op, axis,
                cr_nn_shape_str(t, s, sizeof s));
        return 0;
    }
    *out = a;
    return 1;
}

void cr_nn_split_axis(const cr_tensor *t, int axis, int64_t *outer, int64_t *len, int64_t *inner) {
    int64_t o = 1, in = 1;
    for (int i = 0; i < axis; i++)
        o *= t->shape[i];
    for (int i = axis + 1; i < t->ndim; i++)
        in *= t->shape[i];
    *outer = o;
    *len = t->shape[axis];
    *inner = in;
}

void cr_nn_rows_cols(const cr_tensor *t, int64_t *rows, int64_t *cols) {
    int64_t r = 1;
    for (int i = 0; i + 1 < t->ndim; i++)
        r *= t->shape[i];
    *rows = r;
    *cols = t->ndim > 0 ? t->shape[t->ndim - 1] : 1;
}

void cr_nn_pad_shape(const cr_tensor *t, int64_t out[4]) {
    int lead = CR_NN_MAX_DIMS - t->ndim;
    for (int i = 0; i < CR_NN_MAX_DIMS; i++)
        out[i] = i < lead ? 1 : t->shape[i - lead];
}

/* ------------------------------------------------------------- shapes -- */

cr_nn_shape cr_nn_shape_of(const cr_tensor *t) {
    cr_nn_shape s;
    s.ndim = t->ndim;
    for (int i = 0; i < CR_NN_MAX_DIMS; i++)
        s.d[i] = t->shape[i];
    return s;
}

const char *cr_nn_shape_str(const cr_tensor *t, char *buf, size_t cap) {
    size_t k = 0;
    if (cap == 0) return buf;
    buf[0] = '\0';
    k += (size_t)snprintf(buf + k, cap - k, "(");
    for (int i = 0; i < t->ndim && k < cap; i++)
        k += (size_t)snprintf(buf + k, cap - k, i ? ",%lld" : "%lld", (long long)t->shape[i]);
    if (k < cap) snprintf(buf + k, cap - k, ")");
    return buf;
}

int cr_nn_same_shape(const cr_tensor *a, const cr_tensor *b) {
    if (a->ndim != b->ndim) return 0;
    for (int i = 0; i < a->ndim; i++)
        if (a->shape[i] != b->shape[i]) return 0;
    return 1;
}

/* ------------------------------------------------------ making tensors -- */

cr_tensor *cr_nn_new(cr_nn_ctx *ctx, int ndim, const int64_t *shape) {
    if (ctx->err.status != CR_OK) return NULL;
    return cr_nn_tensor(ctx, "new", ndim, shape);
}

cr_tensor *cr_nn_full(cr_nn_ctx *ctx, int ndim, const int64_t *shape, float value) {
    cr_tensor *t = cr_nn_new(ctx, ndim, shape);
    if (t) ctx->be->fill(t->data, t->numel, value);
    return t;
}

cr_tensor *cr_nn_zeros(cr_nn_ctx *ctx, int ndim, const int64_t *shape) {
    return cr_nn_full(ctx, ndim, shape, 0.0f);
}

cr_tensor *cr_nn_scalar(cr_nn_ctx *ctx, float value) {
    return cr_nn_full(ctx, 0, NULL, value);
}

cr_tensor *cr_nn_from(cr_nn_ctx *ctx, int ndim, const int64_t *shape, const float *data) {
    cr_tensor *t = cr_nn_new(ctx, ndim, shape);
    CR_ASSERT(!t || data || t->numel == 0);
    if (t && t->numel > 0) ctx->be->copy(t->data, data, t->numel);
    return t;
}

cr_tensor *cr_nn_wrap(cr_nn_ctx *ctx, int ndim, const int64_t *shape, float *data) {
    if (ctx->err.status != CR_OK) return NULL;
    cr_tensor *t = alloc_tensor(ctx, "wrap", ndim, shape, 0);
    CR_ASSERT(!t || data || t->numel == 0);
    if (t) t->data = data;
    return t;
}

/* A new struct over t's data; shares t's grad when the view requires grad. */
static cr_tensor *make_view(cr_nn_ctx *ctx, const char *who, cr_tensor *t, int ndim,
                            const int64_t *shape, int64_t offset, int keep_grad) {
    cr_tensor *v = alloc_tensor(ctx, who, ndim, shape, 0);
    if (!v) return NULL;
    v->data = t->data + offset;
    v->requires_grad = keep_grad && t->requires_grad && ctx->grad_enabled;
    if (v->requires_grad) {
        float *g = cr_nn_grad(ctx, t, who);
        if (!g) return NULL;
        v->grad = g + offset;
    }
    return v;
}

cr_tensor *cr_nn_reshape(cr_nn_ctx *ctx, cr_tensor *t, int ndim, const int64_t *shape) {
    if (!cr_nn_begin(ctx, "reshape", 1, &t)) return NULL;
    if (ndim < 0 || ndim > CR_NN_MAX_DIMS) {
        NN_FAIL(ctx, CR_ERR_SHAPE, "reshape: %d dimensions, at most %d supported", ndim,
                CR_NN_MAX_DIMS);
        return NULL;
    }
    int64_t s[CR_NN_MAX_DIMS], known = 1;
    int infer = -1;
    for (int i = 0; i < ndim; i++) {
        s[i] = shape[i];
        if (s[i] == -1 && infer < 0) {
            infer = i;
        } else if (s[i] < 0) {
            NN_FAIL(ctx, CR_ERR_SHAPE, "reshape: bad size %lld in dimension %d", (long long)s[i],
                    i);
            return NULL;
        } else {
            known *= s[i];
        }
    }
    if (infer >= 0) s[infer] = known > 0 ? t->numel / known : 0;
    int64_t n = 1;
    for (int i = 0; i < ndim; i++)
        n *= s[i];
    if (n != t->numel) {
        char a[64];
        NN_FAIL(ctx, CR_ERR_SHAPE, "reshape: %s has %lld elements, the new shape %lld",
                cr_nn_shape_str(t, a, sizeof a), (long long)t->numel, (long long)n);
        return NULL;
    }
    return make_view(ctx, "reshape", t, ndim, s, 0, 1);
}

cr_tensor *cr_nn_detach(cr_nn_ctx *ctx, cr_tensor *t) {
    if (!cr_nn_begin(ctx, "detach", 1, &t)) return NULL;
    return make_view(ctx, "detach", t, t->ndim, t->shape, 0, 0);
}

cr_tensor *cr_nn_slice_view(cr_nn_ctx *ctx, cr_tensor *x, int64_t start, int64_t len) {
    int64_t s[CR_NN_MAX_DIMS];
    for (int i = 0; i < x->ndim; i++)
        s[i] = x->shape[i];
    int64_t row = x->shape[0] > 0 ? x->numel / x->shape[0] : 0;
    s[0] = len;
    return make_view(ctx, "slice", x, x->ndim, s, start * row, 1);
}

/* --------------------------------------------------------------- fills -- */

void cr_nn_fill(cr_tensor *t, float value) {
    for (int64_t i = 0; i < t->numel; i++)
        t->data[i] = value;
}

void cr_nn_fill_uniform(cr_tensor *t, cr_rng *rng, float lo, float hi) {
    for (int64_t i = 0; i < t->numel; i++)
        t->data[i] = lo + (hi - lo) * (float)cr_rng_uniform(rng);
}

void cr_nn_fill_normal(cr_tensor *t, cr_rng *rng, float mean, float stddev) {
    for (int64_t i = 0; i < t->numel; i++)
        t->data[i] = mean + stddev * (float)cr_rng_normal(rng);
}
