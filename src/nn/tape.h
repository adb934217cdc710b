/* tape.h (private): the context, the tape node, and what tape.c, tensor.c and
 * the ops_*.c files share.
 *
 * An op builder (cr_nn_add, ...) checks shapes, allocates the output, fills a
 * node on its stack and hands it to cr_nn_run: cr_nn_run calls the op's forward
 * through the one forward switch (tape.c), then, when a gradient is wanted,
 * copies the node into the arena and links it to the tape. cr_nn_backward
 * walks the links backwards through the one backward switch.
 */
#ifndef CREASE_NN_TAPE_H
#define CREASE_NN_TAPE_H

#include "crease/nn.h"
#include "crease/nn_layers.h"
#include "nn/backend.h"

/* Typed per-op parameters (one struct per op family, no untyped int bags). */
typedef struct nn_unary_params {
    float p; /* constant, exponent, slope or beta */
} nn_unary_params;

typedef struct nn_matmul_params {
    int trans_a, trans_b;
} nn_matmul_params;

typedef struct nn_linear_params {
    cr_op act; /* CR_OP_NONE for a plain linear */
    float p;   /* leaky ReLU's slope */
} nn_linear_params;

typedef struct nn_grouped_params {
    int trans_w;
    int64_t groups;
    const int64_t *off;  /* (G+1) row offsets of each group in sorted order */
    const int32_t *perm; /* (M) sorted position -> row */
    float *xs;           /* (M,K) rows of x in sorted order, kept for backward */
} nn_grouped_params;

typedef struct nn_reduce_params {
    int axis; /* -1 for a reduction over all elements */
    float scale;
} nn_reduce_params;

typedef struct nn_slice_params {
    int axis;
    int64_t start; /* slice: first index along axis */
} nn_slice_params;

typedef struct nn_index_params {
    const int32_t *index; /* arena copy */
    int64_t n;            /* entries in index */
    /* gather backward and scatter-add forward group positions by target row;
     * segment softmax by segment. (rows+1) offsets and (n) positions. */
    const int64_t *off;
    const int32_t *perm;
    int64_t rows; /* target rows (scatter-add), segments (softmax) */
} nn_index_params;

typedef struct nn_layer_norm_params {
    float eps;
    float *mean, *rstd; /* (R) saved by forward */
} nn_layer_norm_params;

typedef struct nn_eps_params {
    float eps;
} nn_eps_params;

typedef struct nn_fused_params {
    const cr_fused_op *def;
    void *stash; /* whatever forward left for backward */
} nn_fused_params;

typedef struct nn_node {
    cr_op op;
    int nsrc, nout;
    cr_tensor **src; /* inputs; an optional input may be NULL */
    cr_tensor **out;
    union {
        nn_unary_params unary;
        nn_matmul_params matmul;
        nn_linear_params linear;
        nn_grouped_params grouped;
        nn_reduce_params reduce;
        nn_slice_params slice;
        nn_index_params index;
        nn_layer_norm_params layer_norm;
        nn_eps_params eps;
        nn_fused_params fused;
    } p;
    struct nn_node *prev; /* the node recorded before this one */
} nn_node;

/* The edges GAT-LN's inference ran over last in this step (layer_gat.c):
 * the given arrays (copies, compared before reuse), the edges with self
 * loops made and their CSR by receiver. Arena memory, gone at reset. */
typedef struct nn_gat_edges {
    int64_t nodes, edges; /* as given */
    int self_loops;
    int32_t *given_snd, *given_rcv; /* (edges) copies of the given arrays */
    int64_t E;                      /* edges attention runs over */
    int32_t *snd, *rcv, *perm;      /* (E) */
    int64_t *off;                   /* (nodes+1) */
} nn_gat_edges;

struct cr_nn_ctx {
    cr_arena arena;
    const cr_nn_backend *be;
    cr_device device;
    nn_node *tail; /* last recorded node */
    int64_t tape_len;
    int grad_enabled;
    int backward_done;
    /* The input whose grad prepare_grads allocated for this node without
     * zeroing it: the node's backward assigns it instead of adding. */
    const cr_tensor *fresh_grad;
    cr_error err;            /* first error of the step */
    nn_gat_edges *gat_edges; /* layer_gat.c's cache for the step, or NULL */
};

/* ---- tensor.c */
/* Record the first error of the step (later ones are dropped). */
void cr_nn_fail(cr_nn_ctx *ctx, cr_status st, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
#define NN_FAIL(ctx, st, ...) cr_nn_fail((ctx), (st), __FILE__, __LINE__, __VA_ARGS__)
/* 1 when the context has no error and all n inputs are non-NULL (a NULL
 * input with no recorded error is recorded as CR_ERR_INVALID naming `op`). */
int cr_nn_begin(cr_nn_ctx *ctx, const char *op, int n, cr_tensor *const *ts);
void *cr_nn_alloc(cr_nn_ctx *ctx, const char *who, size_t bytes);
/* New arena tensor with uninitialised data. */
cr_tensor *cr_nn_tensor(cr_nn_ctx *ctx, const char *who, int ndim, const int64_t *shape);
/* t->grad, allocated zeroed from the arena on first use. */
float *cr_nn_grad(cr_nn_ctx *ctx, cr_tensor *t, const char *who);
/* t->grad, allocated uninitialised on first use (for a backward that
 * assigns it whole; see cr_nn_ctx.fresh_grad). */
float *cr_nn_grad_uninit(cr_nn_ctx *ctx, cr_tensor *t, const char *who);
/* Copy of a host index array into the arena. */
int32_t *cr_nn_index_copy(cr_nn_ctx *ctx, const char *who, const int32_t *idx, int64_t n);
/* Normalise a possibly negative axis of t; 0 and an error when out of range. */
int cr_nn_axis(cr_nn_ctx *ctx, const char *op, const cr_tensor *t, int axis, int *out);
/* t viewed as (outer, shape[axis], inner). */
void cr_nn_split_axis(const cr_tensor *t, int axis, int64_t *outer, int64_t *len, int64_t *inner);
/* Leading axes flattened: rows = product of all but the last axis, cols = the last. */
void cr_nn_rows_cols(const cr_tensor *t, int64_t *rows, int64_t *cols);
/* Padded right-aligned 4-D shape. */
void cr_nn_pad_shape(const cr_tensor *t, int64_t out[4]);
/* Rows [start, start+len) of x as a view sharing data and grad. */
cr_tensor *cr_nn_slice_view(cr_nn_ctx *ctx, cr_tensor *x, int64_t start, int64_t len);

/* The grad an op's backward should add into: NULL when t is absent, does
 * not require grad (a frozen parameter keeps its buffer) or got none. */
static inline float *nn_gout(const cr_tensor *t) {
    return t && t->requires_grad ? t->grad : NULL;
}

/* ---- layer_linear.c */
/* The op a fused bias + activation pass runs for act (backend
 * bias_act_forward), or CR_OP_COUNT for one it does not (sin). */
cr_op cr_nn_act_fused_op(cr_act act, float param);

/* ---- tape.c */
/* Run the node's forward, then record it if a gradient is wanted. Returns
 * out[0], NULL on error. */
cr_tensor *cr_nn_run(cr_nn_ctx *ctx, nn_node *node);

/* ---- op families: forward fills node->out from node->src; backward adds
 * into the grads of node->src that are non-NULL (outputs' grads are set). */
void cr_nn_unary_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_unary_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_binary_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_binary_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_reduce_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_reduce_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_matmul_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_matmul_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_grouped_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_grouped_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_linear_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_linear_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_concat_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_concat_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_slice_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_slice_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_gather_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_gather_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_scatter_add_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_scatter_add_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_segment_softmax_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_segment_softmax_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_layer_norm_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_layer_norm_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_rowwise_forward(cr_nn_ctx *ctx, nn_node *n); /* cross, dot, norm, normalize */
void cr_nn_rowwise_backward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_fused_forward(cr_nn_ctx *ctx, nn_node *n);
void cr_nn_fused_backward(cr_nn_ctx *ctx, nn_node *n);

#endif
