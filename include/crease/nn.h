/* crease/nn.h: the tensor engine: float32 tensors, a per-step context that
 * owns their memory, reverse-mode autodiff on a tape, the differentiable ops,
 * a fused-op hook for hand-written kernels, and the parameter store.
 *
 * The engine knows no physics or geometry (it includes only base.h); layers,
 * optimisers and checkpoints are built on top of this header.
 *
 * ------------------------------------------------------------- a tour ----
 *
 *   cr_nn_ctx_def def = cr_nn_ctx_default_def();
 *   def.arena_bytes = (size_t)256 << 20;         // per-step memory
 *   cr_nn_ctx *ctx = NULL;
 *   CR_TRY(cr_nn_ctx_create(&def, &ctx, err));
 *
 *   cr_nn_params *P = NULL;                       // persistent weights
 *   CR_TRY(cr_nn_params_create(&P, err));
 *   cr_tensor *W, *b;
 *   CR_TRY(cr_nn_params_add(P, "fc.weight", 2, (int64_t[]){OUT, IN}, &W, err));
 *   CR_TRY(cr_nn_params_add(P, "fc.bias", 1, (int64_t[]){OUT}, &b, err));
 *   cr_nn_fill_uniform(W, &rng, -0.1f, 0.1f);
 *
 *   for (int step = 0; step < steps; step++) {
 *       cr_nn_ctx_reset(ctx);                     // frees the last step at once
 *       cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){B, IN}, host_x);
 *       cr_tensor *y = cr_nn_tanh(ctx, cr_nn_linear(ctx, x, W, b));
 *       cr_tensor *d = cr_nn_sub(ctx, y, target);
 *       cr_tensor *loss = cr_nn_mean(ctx, cr_nn_square(ctx, d));
 *       cr_nn_params_zero_grad(P);
 *       CR_TRY(cr_nn_backward(ctx, loss, err));   // also reports any op's error
 *       ... the optimiser walks cr_nn_params_data / cr_nn_params_grad ...
 *   }
 *
 * -------------------------------------------------------------- model ----
 *
 * Tensors: float32, 0..4 dims, row-major, contiguous. A tensor made inside a
 * step (every op output, cr_nn_new/from/wrap, views) lives in the context's
 * arena: its struct, data and grad are all freed by cr_nn_ctx_reset, so no
 * pointer to it may be kept across a reset. Parameters live in a
 * cr_nn_params store and survive resets.
 *
 * Eager tape: every op computes its output at once. When grad mode is on and
 * any input has requires_grad, the op also appends a node to the tape and its
 * output gets requires_grad. cr_nn_backward walks the tape backwards and each
 * op's backward ADDS into its inputs' grad buffers (allocated zeroed on first
 * use). Parameter grads therefore accumulate over steps until
 * cr_nn_params_zero_grad. To get d(loss)/d(input), set input->requires_grad
 * = 1 before using it in ops and read input->grad after backward.
 *
 * Errors: an op that fails (shape mismatch, bad index, arena exhausted)
 * returns NULL and records the error on the context; every later op given a
 * NULL input or called on a failed context returns NULL quietly, so a whole
 * forward pass can be written as a chain and checked once, with
 * cr_nn_ctx_error or by cr_nn_backward (which returns the recorded error).
 * Only the first error is kept; its message names the op, e.g.
 *   "matmul: inner dimensions differ: (64,3) x (4,128)".
 * cr_nn_ctx_reset clears it.
 *
 * Memory: no op calls malloc. Everything a step needs comes from the arena,
 * so after the first step of a loop the arena peak is fixed; when the arena
 * is too small the failing op says how many bytes it needed and how many were
 * free (raise cr_nn_ctx_def.arena_bytes).
 *
 * Threads: a context is used by one thread at a time. Kernels run on the
 * OpenMP pool (cr_parallel_for) when a tensor has about 16k elements or more;
 * matmuls use the engine's own GEMM or OpenBLAS, chosen by shape
 * (CREASE_NN_GEMM, docs/nn.md). Reductions are blocked in a fixed order, so
 * results do not depend on the thread count (except inside the BLAS). OpenMP's
 * idle threads spin after each parallel region and then compete with
 * OpenBLAS's own threads: the tool and the test runner ask for passive waiting
 * (cr_parallel_prefer_passive_wait); a program of your own should too.
 *
 * Shapes in comments: N rows, C columns (features), B batch, E edges (rows of
 * a message-passing layer), H heads, G groups.
 */
#ifndef CREASE_NN_H
#define CREASE_NN_H

#include "crease/base.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- tensors -- */

enum { CR_NN_MAX_DIMS = 4 };

typedef enum cr_device {
    CR_DEVICE_CPU = 0,
    CR_DEVICE_CUDA /* reserved: creating a context on it gives CR_ERR_UNSUPPORTED */
} cr_device;

/* Every op the tape can record. cr_op_name gives the lower-case name used in
 * messages ("matmul", "segment_softmax"). */
typedef enum cr_op {
    CR_OP_NONE = 0, /* leaf (created, wrapped, a parameter) or a view */
    /* matrix products */
    CR_OP_MATMUL,
    CR_OP_MATMUL_BATCHED,
    CR_OP_MATMUL_GROUPED,
    CR_OP_LINEAR,
    /* binary elementwise with broadcasting */
    CR_OP_ADD,
    CR_OP_SUB,
    CR_OP_MUL,
    CR_OP_DIV,
    /* unary elementwise (one float parameter at most) */
    CR_OP_ADD_SCALAR,
    CR_OP_MUL_SCALAR,
    CR_OP_POW,
    CR_OP_RELU,
    CR_OP_LEAKY_RELU,
    CR_OP_LEAKY_RELU_DERIV,
    CR_OP_TANH,
    CR_OP_SIGMOID,
    CR_OP_SOFTPLUS,
    CR_OP_SIN,
    CR_OP_COS,
    CR_OP_EXP,
    CR_OP_LOG,
    CR_OP_SQRT,
    CR_OP_ABS,
    CR_OP_SQUARE,
    /* reductions */
    CR_OP_SUM,
    CR_OP_MEAN,
    CR_OP_SUM_AXIS,
    CR_OP_MEAN_AXIS,
    /* indexing */
    CR_OP_CONCAT,
    CR_OP_SLICE,
    CR_OP_GATHER_ROWS,
    CR_OP_SCATTER_ADD_ROWS,
    CR_OP_SEGMENT_SOFTMAX,
    /* row-wise vector ops (over the last axis) */
    CR_OP_LAYER_NORM,
    CR_OP_CROSS,
    CR_OP_DOT,
    CR_OP_NORM,
    CR_OP_NORMALIZE,
    /* user kernels registered through cr_nn_fused */
    CR_OP_FUSED,
    CR_OP_COUNT
} cr_op;

const char *cr_op_name(cr_op op);

typedef struct cr_tensor {
    int ndim;                      /* 0 (scalar) to CR_NN_MAX_DIMS */
    int64_t shape[CR_NN_MAX_DIMS]; /* entries past ndim are 1 */
    int64_t numel;                 /* product of shape; 1 for a scalar */
    float *data;                   /* (numel) row-major, contiguous */
    float *grad;                   /* (numel) dL/d(data); NULL until a gradient reaches it */
    cr_device device;              /* where data and grad live */
    uint8_t requires_grad;         /* leaves: set before use in ops; op outputs: derived */
    uint8_t persistent;            /* owned by a cr_nn_params store, survives resets */
    cr_op op;                      /* op that produced it; CR_OP_NONE for leaves and views */
} cr_tensor;

/* A shape by value, for fused-op outputs. */
typedef struct cr_nn_shape {
    int ndim;
    int64_t d[CR_NN_MAX_DIMS];
} cr_nn_shape;

cr_nn_shape cr_nn_shape_of(const cr_tensor *t);
/* "(64,3)" into buf; returns buf. 64 bytes always suffice. */
const char *cr_nn_shape_str(const cr_tensor *t, char *buf, size_t cap);
/* 1 when both have the same ndim and shape. */
int cr_nn_same_shape(const cr_tensor *a, const cr_tensor *b);

/* ------------------------------------------------------------- context -- */

typedef struct cr_nn_ctx cr_nn_ctx;

typedef struct cr_nn_ctx_def {
    size_t arena_bytes; /* per-step memory: tensors, grads, tape, scratch (default 64 MiB) */
    cr_device device;   /* CR_DEVICE_CPU */
    uint32_t cookie;    /* set by cr_nn_ctx_default_def; a hand-zeroed def is a bug */
} cr_nn_ctx_def;

cr_nn_ctx_def cr_nn_ctx_default_def(void);
/* Allocates the arena once (the only allocation the context makes). */
cr_status cr_nn_ctx_create(const cr_nn_ctx_def *def, cr_nn_ctx **out, cr_error *err);
void cr_nn_ctx_destroy(cr_nn_ctx *ctx); /* NULL is a no-op */
/* A gradient-off context sized for a runtime's steps (the runtimes'
 * create): *ctx (destroyed first when it holds one) made with an arena of
 * arena_bytes, or (0) a generous reservation, touched only as used and
 * halved while the system refuses it; trial(user) run in it (the runtime
 * reads the context through *ctx); then, unless arena_bytes was given or
 * keep is set, the context made again at the trial's high-water mark plus an
 * eighth and 1 MiB. *peak (may be NULL) gets that high-water mark. */
cr_status cr_nn_ctx_fit(cr_nn_ctx **ctx, size_t arena_bytes, int keep,
                        cr_status (*trial)(void *user, cr_error *err), void *user, size_t *peak,
                        cr_error *err);
/* Free every tensor, grad and tape node of the step, clear the error. O(1). */
void cr_nn_ctx_reset(cr_nn_ctx *ctx);
/* CR_OK, or the first error an op recorded (copied into err). */
cr_status cr_nn_ctx_error(const cr_nn_ctx *ctx, cr_error *err);
/* Grad mode (on after create): when off, ops record nothing and their outputs
 * do not require grad, even from parameters (inference). Survives resets. */
void cr_nn_ctx_set_grad_enabled(cr_nn_ctx *ctx, int enabled);
int cr_nn_ctx_grad_enabled(const cr_nn_ctx *ctx);
size_t cr_nn_ctx_arena_used(const cr_nn_ctx *ctx);     /* bytes */
size_t cr_nn_ctx_arena_peak(const cr_nn_ctx *ctx);     /* bytes, high-water mark since create */
size_t cr_nn_ctx_arena_capacity(const cr_nn_ctx *ctx); /* bytes */
/* Floating-point operations of every matrix product (2MNK) since the process
 * started, on every thread and context: a benchmark's count of a step's
 * GEMM work (element-wise passes are not counted). */
uint64_t cr_nn_gemm_flops(void);
/* The CPU kernels' vector level in use: "scalar" (the portable path), "avx2"
 * or "avx512" (CREASE_NN_SIMD caps it). */
const char *cr_nn_kernel_level(void);
int64_t cr_nn_ctx_tape_length(const cr_nn_ctx *ctx); /* nodes recorded this step */
/* Uninitialised, 64-byte aligned step memory (freed by reset); NULL and a
 * context error naming `who` when the arena is full. For fused ops' scratch. */
void *cr_nn_scratch(cr_nn_ctx *ctx, const char *who, size_t bytes);

/* ------------------------------------------------------ making tensors -- */

/* All return a tensor in the step arena, or NULL with the context error set.
 * `shape` has `ndim` entries (ndim 0: a scalar, shape may be NULL). */
cr_tensor *cr_nn_new(cr_nn_ctx *ctx, int ndim, const int64_t *shape); /* uninitialised */
cr_tensor *cr_nn_zeros(cr_nn_ctx *ctx, int ndim, const int64_t *shape);
cr_tensor *cr_nn_full(cr_nn_ctx *ctx, int ndim, const int64_t *shape, float value);
cr_tensor *cr_nn_scalar(cr_nn_ctx *ctx, float value);
/* Copies numel floats from host memory. */
cr_tensor *cr_nn_from(cr_nn_ctx *ctx, int ndim, const int64_t *shape, const float *data);
/* No copy: the tensor's data is the caller's buffer, which must outlive the
 * step; only the struct (and a grad, if one is needed) come from the arena. */
cr_tensor *cr_nn_wrap(cr_nn_ctx *ctx, int ndim, const int64_t *shape, float *data);
/* View with a new shape (same numel; one entry may be -1 and is inferred).
 * Shares data and grad with `t`, so gradients flow through without a node. */
cr_tensor *cr_nn_reshape(cr_nn_ctx *ctx, cr_tensor *t, int ndim, const int64_t *shape);
/* View of the same data that does not require grad: gradients stop here. */
cr_tensor *cr_nn_detach(cr_nn_ctx *ctx, cr_tensor *t);

/* Host-side fills of t->data (any tensor, parameters included). */
void cr_nn_fill(cr_tensor *t, float value);
void cr_nn_fill_uniform(cr_tensor *t, cr_rng *rng, float lo, float hi);
void cr_nn_fill_normal(cr_tensor *t, cr_rng *rng, float mean, float stddev);

/* ----------------------------------------------------------------- ops -- */

/* Matrix products (GEMM through cblas_sgemm).
 *   2-D:  a (M,K) x b (K,N) -> (M,N). trans_a: a is stored (K,M); trans_b: b is
 *         stored (N,K).
 *   3-D:  a (B,M,K) x b (B,K,N) -> (B,M,N), one product per batch entry; the
 *         flags apply to the last two axes. */
cr_tensor *cr_nn_matmul(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b, int trans_a, int trans_b);
/* Per-group weights (hyper-networks): x (M,K), w (G,K,N) (or (G,N,K) with
 * trans_w), group (M) int32 in [0,G) names each row's weight:
 * y[i] = x[i] w[group[i]] -> (M,N). Rows need not be sorted by group. */
cr_tensor *cr_nn_matmul_grouped(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, const int32_t *group,
                                int trans_w);
/* Affine layer in PyTorch's layout, so checkpoints map one to one onto
 * torch.nn.Linear: y = x W^T + b with x (...,IN), W (OUT,IN), b (OUT) or
 * NULL -> (...,OUT). Leading axes of x are flattened into rows. */
cr_tensor *cr_nn_linear(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b);
/* act(x W^T + b) as one op: the GEMM, then bias and activation in one pass;
 * the backward reads act' off the output (no pre-activation is kept) and
 * sums the bias gradient in the same pass. act: CR_OP_NONE, CR_OP_RELU,
 * CR_OP_LEAKY_RELU (p = slope >= 0), CR_OP_TANH, CR_OP_SIGMOID or
 * CR_OP_SOFTPLUS (p = beta > 0); any other is an error. Same values and gradients as the ops one
 * after the other. */
cr_tensor *cr_nn_linear_act(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b, cr_op act,
                            float p);

/* Binary elementwise with numpy broadcasting (shapes aligned at the right;
 * each axis equal or 1): (N,3)+(3), (N,1)*(N,3), (2,1,3)-(1,4,1). */
cr_tensor *cr_nn_add(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b);
cr_tensor *cr_nn_sub(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b);
cr_tensor *cr_nn_mul(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b);
cr_tensor *cr_nn_div(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b);

/* Unary elementwise; the output has x's shape. */
cr_tensor *cr_nn_add_scalar(cr_nn_ctx *ctx, cr_tensor *x, float c); /* x + c */
cr_tensor *cr_nn_mul_scalar(cr_nn_ctx *ctx, cr_tensor *x, float c); /* c x */
cr_tensor *cr_nn_pow(cr_nn_ctx *ctx, cr_tensor *x, float p); /* x^p (x > 0 unless p integral) */
cr_tensor *cr_nn_relu(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_leaky_relu(cr_nn_ctx *ctx, cr_tensor *x, float slope); /* x<0: slope x */
cr_tensor *cr_nn_tanh(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_sigmoid(cr_nn_ctx *ctx, cr_tensor *x);
/* log(1 + exp(beta x)) / beta, evaluated without overflow; beta > 0. */
cr_tensor *cr_nn_softplus(cr_nn_ctx *ctx, cr_tensor *x, float beta);
cr_tensor *cr_nn_sin(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_cos(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_exp(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_log(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_sqrt(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_abs(cr_nn_ctx *ctx, cr_tensor *x); /* gradient sign(x), 0 at 0 */
cr_tensor *cr_nn_square(cr_nn_ctx *ctx, cr_tensor *x);

/* Activation derivatives as ordinary differentiable tensors, for building
 * input Jacobians of MLPs from ops. leaky_relu_deriv is one op (1 for x > 0,
 * else slope; its own gradient is zero); the smooth ones are compositions:
 *   tanh'(x) = 1 - tanh(x)^2,  sigmoid'(x) = s (1 - s),
 *   softplus'(x) = sigmoid(beta x). */
cr_tensor *cr_nn_leaky_relu_deriv(cr_nn_ctx *ctx, cr_tensor *x, float slope);
cr_tensor *cr_nn_tanh_deriv(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_sigmoid_deriv(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_softplus_deriv(cr_nn_ctx *ctx, cr_tensor *x, float beta);

/* Reductions, accumulated in double. sum/mean give a scalar (ndim 0); the
 * _axis forms reduce one axis (negative counts from the end) and keep it as
 * size 1 when keepdim. */
cr_tensor *cr_nn_sum(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_mean(cr_nn_ctx *ctx, cr_tensor *x);
cr_tensor *cr_nn_sum_axis(cr_nn_ctx *ctx, cr_tensor *x, int axis, int keepdim);
cr_tensor *cr_nn_mean_axis(cr_nn_ctx *ctx, cr_tensor *x, int axis, int keepdim);

/* Indexing. Index arrays are host int32 buffers, copied into the arena, so
 * the caller may reuse them at once. Rows are the first axis; a row is the
 * rest of the tensor (C = numel / rows). */
/* Join n >= 1 tensors along `axis`; the other axes must agree. */
cr_tensor *cr_nn_concat(cr_nn_ctx *ctx, int n, cr_tensor *const *ts, int axis);
/* [start, start+len) along `axis`. Along axis 0 this is a view (no copy, no
 * node); along other axes a copy whose gradient flows back. */
cr_tensor *cr_nn_slice(cr_nn_ctx *ctx, cr_tensor *x, int axis, int64_t start, int64_t len);
/* y[i] = x[index[i]]: x (R,...) -> (n,...). CR_ERR_RANGE for an index outside [0,R). */
cr_tensor *cr_nn_gather_rows(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *index, int64_t n);
/* y[index[e]] += x[e]: x (E,...), index (E) in [0,rows) -> (rows,...), zero
 * where nothing lands. Message-passing aggregation; deterministic. */
cr_tensor *cr_nn_scatter_add_rows(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *index, int64_t rows);
/* Softmax over the rows sharing a segment id, separately for each column:
 * x (E,H) (or (E)), segment (E) in [0,nseg) -> same shape. Shifted by the
 * segment maximum, so large logits do not overflow (attention over
 * neighbour lists). Rows need not be sorted by segment. */
cr_tensor *cr_nn_segment_softmax(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *segment,
                                 int64_t nseg);

/* Row-wise ops over the last axis (C); "rows" are all leading axes. */
/* (x - mean) / sqrt(var + eps) * w + b, biased variance; w, b (C) or NULL. */
cr_tensor *cr_nn_layer_norm(cr_nn_ctx *ctx, cr_tensor *x, cr_tensor *w, cr_tensor *b, float eps);
cr_tensor *cr_nn_cross(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b); /* (...,3) x (...,3) */
/* The following keep the last axis as size 1: (N,C) -> (N,1), so the result
 * broadcasts back against (N,C). */
cr_tensor *cr_nn_dot(cr_nn_ctx *ctx, cr_tensor *a, cr_tensor *b);
/* |x| exactly; the gradient x / max(|x|, eps) stays finite at 0. eps > 0
 * (1e-12 is a fine default for lengths in metres). */
cr_tensor *cr_nn_norm(cr_nn_ctx *ctx, cr_tensor *x, float eps);
/* x / max(|x|, eps) -> same shape as x. */
cr_tensor *cr_nn_normalize(cr_nn_ctx *ctx, cr_tensor *x, float eps);

/* ------------------------------------------------------------ backward -- */

/* Seed d(loss)/d(loss) = 1 and run the tape backwards, accumulating grads into
 * every tensor that requires them. Returns the context's recorded error if an
 * op failed; CR_ERR_SHAPE unless loss has one element; CR_ERR_NAN when the
 * loss is NaN or infinite ("backward: loss is NaN"); CR_ERR_INVALID when the
 * loss depends on nothing that requires grad or backward already ran since
 * the last reset. */
cr_status cr_nn_backward(cr_nn_ctx *ctx, cr_tensor *loss, cr_error *err);

/* ------------------------------------------------------------ fused ops -- */

/* A hand-written op: the physics energies and the grid encoding are
 * registered this way, so the tape sees one node whose backward is an
 * analytic gradient instead of a chain of small ops.
 *
 * forward: fill out[k]->data (allocated by the engine with the requested
 *   shapes) from in[i]->data. It may take step memory with cr_nn_scratch and
 *   leave a pointer in *stash for backward.
 * backward: every out[k]->grad holds dL/d(out[k]) (never NULL: zero where no
 *   gradient arrived). ADD dL/d(in[i]) into in[i]->grad for every input with
 *   requires_grad set (its grad is then allocated); leave the others alone.
 * Both return CR_OK or fail through err (name the op in the message); the
 * engine records the failure on the context. `def` (with `user`) must stay
 * valid until the context is reset. backward may be NULL for an op that is
 * never differentiated; using it on inputs that require grad is then an error. */
typedef struct cr_fused_op cr_fused_op;
typedef cr_status (*cr_fused_forward_fn)(const cr_fused_op *def, cr_nn_ctx *ctx,
                                         cr_tensor *const *in, int nin, cr_tensor *const *out,
                                         int nout, void **stash, cr_error *err);
typedef cr_status (*cr_fused_backward_fn)(const cr_fused_op *def, cr_nn_ctx *ctx,
                                          cr_tensor *const *in, int nin, cr_tensor *const *out,
                                          int nout, void *stash, cr_error *err);
struct cr_fused_op {
    const char *name;
    cr_fused_forward_fn forward;
    cr_fused_backward_fn backward;
    void *user; /* the op's own context (a mesh, material constants, ...) */
};

/* Run def->forward on nin inputs, making nout (>= 1) outputs of the given
 * shapes. Returns out[0] (NULL on error); `out` (may be NULL when nout is 1)
 * receives all outputs. Inputs may be NULL only where the op says so. */
cr_tensor *cr_nn_fused(cr_nn_ctx *ctx, const cr_fused_op *def, int nin, cr_tensor *const *in,
                       int nout, const cr_nn_shape *out_shapes, cr_tensor **out);

/* ----------------------------------------------------------- parameters -- */

/* Named persistent tensors (the weights of a model). All data lives in one
 * contiguous block and all grads in a mirroring block, so an optimiser is one
 * loop over cr_nn_params_data/grad. Parameters are added at set-up; each add
 * may move the blocks (t->data and t->grad of earlier parameters are
 * re-pointed), so read data pointers after the last add and never add during
 * training. Parameters start zeroed, with requires_grad = 1 (clear it to
 * freeze one). Offsets are 16-float aligned; the padding stays zero. */
typedef struct cr_nn_params cr_nn_params;

cr_status cr_nn_params_create(cr_nn_params **out, cr_error *err);
void cr_nn_params_destroy(cr_nn_params *p); /* NULL is a no-op; frees its tensors */
/* Names are unique, 1..127 characters (checkpoint keys, e.g. "mlp.0.weight").
 * The tensor is owned by the store and its pointer stays valid until destroy. */
cr_status cr_nn_params_add(cr_nn_params *p, const char *name, int ndim, const int64_t *shape,
                           cr_tensor **out, cr_error *err);
int cr_nn_params_count(const cr_nn_params *p);
/* i-th parameter in order of addition; *name (may be NULL) gets its name. */
cr_tensor *cr_nn_params_at(const cr_nn_params *p, int i, const char **name);
cr_tensor *cr_nn_params_find(const cr_nn_params *p, const char *name); /* NULL if absent */
int64_t cr_nn_params_numel(const cr_nn_params *p);                     /* sum of parameter sizes */
/* The whole blocks, padding included (*n floats); NULL before the first add. */
float *cr_nn_params_data(cr_nn_params *p, int64_t *n);
float *cr_nn_params_grad(cr_nn_params *p, int64_t *n);
void cr_nn_params_zero_grad(cr_nn_params *p);

#ifdef __cplusplus
}
#endif
#endif
