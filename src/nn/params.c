/* params.c: the parameter store: named persistent tensors packed into one
 * data block with a mirroring grad block (llm.c's layout), so optimisers and
 * checkpoints see one array.
 *
 * Each add appends at a 16-float aligned offset; when the block is full it is
 * reallocated at twice the size and every tensor is re-pointed, so parameter
 * structs stay put while their data may move during set-up. Set-up happens
 * once per model, so the doubling costs nothing that matters.
 * Leaves out: removal, optimiser state (kept by the optimisers, mirroring the
 * same offsets), file formats (checkpoint code walks the store).
 */
#include "crease/nn.h"

#include <stdlib.h>
#include <string.h>

enum {
    PARAM_ALIGN = 16,      /* floats: 64 bytes, one cache line */
    NAME_CAP = 128,        /* bytes including the terminator */
    FIRST_CAPACITY = 4096, /* floats */
};

typedef struct param_entry {
    char name[NAME_CAP];
    int64_t offset; /* floats into the blocks */
    cr_tensor t;
} param_entry;

struct cr_nn_params {
    param_entry **entries; /* each entry allocated alone so tensor pointers stay valid */
    int count, cap;
    float *data, *grad; /* (capacity) */
    int64_t used;       /* floats, padding included */
    int64_t capacity;   /* floats */
    int64_t numel;      /* floats in parameters */
};

cr_status cr_nn_params_create(cr_nn_params **out, cr_error *err) {
    *out = cr_calloc(1, sizeof **out, err);
    return *out ? CR_OK : CR_ERR_MEMORY;
}

void cr_nn_params_destroy(cr_nn_params *p) {
    if (!p) return;
    for (int i = 0; i < p->count; i++)
        free(p->entries[i]);
    free(p->entries);
    free(p->data);
    free(p->grad);
    free(p);
}

/* Zeroed 64-byte aligned block of n floats. */
static float *block(int64_t n, cr_error *err) {
    size_t bytes = ((size_t)n * sizeof(float) + 63) / 64 * 64;
    float *b = aligned_alloc(64, bytes);
    if (!b) {
        CR_FAIL(err, CR_ERR_MEMORY, "params: cannot allocate %zu bytes", bytes);
        return NULL;
    }
    memset(b, 0, bytes);
    return b;
}

static cr_status grow(cr_nn_params *p, int64_t need, cr_error *err) {
    int64_t cap = p->capacity > 0 ? p->capacity : FIRST_CAPACITY;
    while (cap < need)
        cap *= 2;
    float *data = block(cap, err);
    float *grad = data ? block(cap, err) : NULL;
    if (!grad) {
        free(data);
        return CR_ERR_MEMORY;
    }
    if (p->used > 0) {
        memcpy(data, p->data, (size_t)p->used * sizeof(float));
        memcpy(grad, p->grad, (size_t)p->used * sizeof(float));
    }
    free(p->data);
    free(p->grad);
    p->data = data;
    p->grad = grad;
    p->capacity = cap;
    for (int i = 0; i < p->count; i++) {
        param_entry *e = p->entries[i];
        e->t.data = p->data + e->offset;
        e->t.grad = p->grad + e->offset;
    }
    return CR_OK;
}

cr_status cr_nn_params_add(cr_nn_params *p, const char *name, int ndim, const int64_t *shape,
                           cr_tensor **out, cr_error *err) {
    *out = NULL;
    size_t len = name ? strlen(name) : 0;
    if (len == 0 || len >= NAME_CAP)
        return CR_FAIL(err, CR_ERR_INVALID, "params: name must have 1 to %d characters",
                       NAME_CAP - 1);
    if (cr_nn_params_find(p, name))
        return CR_FAIL(err, CR_ERR_INVALID, "params: '%s' is already defined", name);
    if (ndim < 0 || ndim > CR_NN_MAX_DIMS)
        return CR_FAIL(err, CR_ERR_SHAPE, "params: '%s' has %d dimensions, at most %d", name, ndim,
                       CR_NN_MAX_DIMS);
    int64_t numel = 1;
    for (int i = 0; i < ndim; i++) {
        if (shape[i] < 0 || (shape[i] > 0 && numel > (INT64_MAX / 8) / shape[i]))
            return CR_FAIL(err, CR_ERR_SHAPE, "params: '%s' has bad size %lld in dimension %d",
                           name, (long long)shape[i], i);
        numel *= shape[i];
    }
    int64_t offset = (p->used + PARAM_ALIGN - 1) / PARAM_ALIGN * PARAM_ALIGN;
    if (p->capacity == 0 || offset + numel > p->capacity) CR_TRY(grow(p, offset + numel, err));
    if (p->count == p->cap) {
        int cap = p->cap ? 2 * p->cap : 16;
        param_entry **e = realloc(p->entries, (size_t)cap * sizeof *e);
        if (!e) return CR_FAIL(err, CR_ERR_MEMORY, "params: cannot grow the table");
        p->entries = e;
        p->cap = cap;
    }
    param_entry *e = cr_calloc(1, sizeof *e, err);
    if (!e) return CR_ERR_MEMORY;
    memcpy(e->name, name, len + 1);
    e->offset = offset;
    e->t.ndim = ndim;
    for (int i = 0; i < CR_NN_MAX_DIMS; i++)
        e->t.shape[i] = i < ndim ? shape[i] : 1;
    e->t.numel = numel;
    e->t.data = p->data + offset;
    e->t.grad = p->grad + offset;
    e->t.device = CR_DEVICE_CPU;
    e->t.requires_grad = 1;
    e->t.persistent = 1;
    e->t.op = CR_OP_NONE;
    p->entries[p->count++] = e;
    p->used = offset + numel;
    p->numel += numel;
    *out = &e->t;
    return CR_OK;
}

int cr_nn_params_count(const cr_nn_params *p) {
    return p->count;
}

cr_tensor *cr_nn_params_at(const cr_nn_params *p, int i, const char **name) {
    CR_ASSERT(i >= 0 && i < p->count);
    if (name) *name = p->entries[i]->name;
    return &p->entries[i]->t;
}

cr_tensor *cr_nn_params_find(const cr_nn_params *p, const char *name) {
    for (int i = 0; i < p->count; i++)
        if (strcmp(p->entries[i]->name, name) == 0) return &p->entries[i]->t;
    return NULL;
}

int64_t cr_nn_params_numel(const cr_nn_params *p) {
    return p->numel;
}

float *cr_nn_params_data(cr_nn_params *p, int64_t *n) {
    if (n) *n = p->used;
    return p->data;
}

float *cr_nn_params_grad(cr_nn_params *p, int64_t *n) {
    if (n) *n = p->used;
    return p->grad;
}

void cr_nn_params_zero_grad(cr_nn_params *p) {
    if (p->used > 0) memset(p->grad, 0, (size_t)p->used * sizeof(float));
}
