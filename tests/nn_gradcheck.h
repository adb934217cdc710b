/* nn_gradcheck.h: a reusable central-difference gradient checker for tape
 * ops and layers (tests only).
 *
 * The caller supplies a build function that turns input tensors (and any
 * parameters it captures in `user`) into an output tensor y of any shape.
 * The checker reduces y to the scalar L = sum_i w_i y_i with fixed random
 * weights w in [-1, 1] (so constant sums, like a softmax's, still test every
 * direction), runs the tape backward once, then for each checked element x_k
 * of every input with requires_grad and of every parameter in `params` with
 * requires_grad evaluates
 *     g_fd = (L(x_k + h) - L(x_k - h)) / ((x_k + h) - (x_k - h))
 * with L summed in double from y's float values and the denominator taken
 * from the perturbed floats actually stored. An element passes when
 *     |g_tape - g_fd| <= tol * max(1, |g_fd|).
 * Defaults: h = 1e-3, tol = 1e-2 (float32 inputs of order 1: the rounding
 * error of the difference is about 1e-7 |y| / h ~ 1e-4, the truncation error
 * h^2 |f'''| / 6 ~ 1e-7). Keep inputs at least 2h away from kinks (relu, abs).
 *
 *   nn_gradcheck_input in[2] = {{2, {4, 3}, xdata, 1}, {1, {3}, bdata, 1}};
 *   nn_gradcheck_def def = nn_gradcheck_default_def();
 *   def.name = "add broadcast";
 *   CR_CHECK(nn_gradcheck(&def, 2, in, NULL, build_add, NULL, NULL) == 0);
 */
#ifndef CREASE_TESTS_NN_GRADCHECK_H
#define CREASE_TESTS_NN_GRADCHECK_H

#include "crease/nn.h"

/* Build y from the wrapped inputs (in the order given); NULL on error (the
 * context error is then printed). Called once per evaluation, after a reset. */
typedef cr_tensor *(*nn_gradcheck_fn)(cr_nn_ctx *ctx, cr_tensor *const *in, void *user);

typedef struct nn_gradcheck_input {
    int ndim;
    int64_t shape[CR_NN_MAX_DIMS];
    float *data;       /* host values; perturbed in place during the check, then restored */
    int requires_grad; /* 1: check d(L)/d(input); 0: a constant input */
} nn_gradcheck_input;

typedef struct nn_gradcheck_def {
    const char *name;   /* printed with each mismatch */
    double step;        /* h (default 1e-3) */
    double tol;         /* relative-or-absolute tolerance (default 1e-2) */
    int64_t max_elems;  /* per tensor: check a random subset of this size, 0 = all (default 0) */
    uint64_t seed;      /* weights and subsets */
    size_t arena_bytes; /* context arena (default 16 MiB) */
    int max_reports;    /* mismatches printed (default 5) */
} nn_gradcheck_def;

typedef struct nn_gradcheck_result {
    int64_t checked;
    int64_t failed;
    double max_err; /* max over checked elements of |g_tape - g_fd| / max(1, |g_fd|) */
} nn_gradcheck_result;

nn_gradcheck_def nn_gradcheck_default_def(void);

/* Number of failing elements (0 = pass), or -1 when the build or backward
 * failed (the error is printed). `params` and `res` may be NULL. */
int64_t nn_gradcheck(const nn_gradcheck_def *def, int nin, nn_gradcheck_input *in,
                     cr_nn_params *params, nn_gradcheck_fn fn, void *user,
                     nn_gradcheck_result *res);

/* ---- conveniences for tests built on the checker */

/* An input descriptor that requires grad. */
nn_gradcheck_input nn_gradcheck_in(int ndim, const int64_t *shape, float *data);
/* Check with the default def named `name`; failures, or -1 on error. */
int64_t nn_gradcheck_quick(const char *name, int nin, nn_gradcheck_input *in, cr_nn_params *params,
                           nn_gradcheck_fn fn, void *user);
/* Uniform values in [lo, hi] from `seed`, each pushed at least `gap` away
 * from 0 (to stay clear of kinks such as relu's and abs'). */
void nn_gradcheck_fill(float *x, int64_t n, float lo, float hi, float gap, uint64_t seed);
/* A context with an arena of `bytes`; NULL on failure. */
cr_nn_ctx *nn_gradcheck_ctx(size_t bytes);

#endif
