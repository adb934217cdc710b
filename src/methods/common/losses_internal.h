/* losses_internal.h: the engine behind crease/losses.h (private to
 * src/methods/common/).
 *
 * One fused op serves every loss: a spec names the elements (nelem of nvert
 * vertex slots), the position inputs (npos tensors, each (B,V,3) or (V,3);
 * slot index u in [0, npos V) reads row u % V of input u / V), an optional
 * per-element parameter input (aux, (B,nelem) or (nelem), one scalar per
 * element, e.g. a rest angle) and a per-item kernel. Forward runs the kernel
 * (values only) over the elements of each item; backward runs it again with
 * gradients, scaled by the output grad, into a per-item stash (nelem, nvert,
 * 3) of doubles (for one item needing position grads, forward already took
 * the gradients with the values and backward scales them), then gathers each vertex's slots in element order through a
 * vertex -> slot CSR. Both loops are cr_parallel_for over independent
 * elements / vertices, so the bits do not depend on the thread count.
 */
#ifndef CREASE_METHODS_COMMON_LOSSES_INTERNAL_H
#define CREASE_METHODS_COMMON_LOSSES_INTERNAL_H

#include "crease/losses.h"

typedef struct loss_spec loss_spec;

/* Element e of item b: xe (nvert,3) positions in double, aux its parameter
 * (0 without an aux input). Returns the unweighted energy, J; g (3 nvert) and
 * g_aux (1) get its gradients when not NULL. Pure: called from many threads. */
typedef double (*loss_kernel)(const loss_spec *s, int64_t b, int32_t e, const double *xe,
                              double aux, double *g, double *g_aux);

/* Per-item set-up run serially in forward before item b's elements (the
 * collision's distance queries); x_b (V,3) is item b's first position input. */
typedef cr_status (*loss_prepare)(loss_spec *s, int64_t b, const float *x_b, cr_error *err);

struct loss_spec {
    cr_fused_op op;      /* op.user = this spec; lives in step memory */
    const char *term;    /* the term's name, for messages */
    int32_t nelem;       /* elements */
    int nvert;           /* slots per element, 1..CR_ENERGY_MAX_VERTS */
    const int32_t *elem; /* (nelem, nvert) slot indices into [0, npos V); NULL: element e is
                            vertex e (nvert 1, nelem V) */
    int npos;            /* position inputs, 1..3 */
    int has_aux;         /* input npos is a per-element parameter tensor */
    int per_element;     /* output (B,nelem) instead of (B) */
    double weight;
    loss_kernel kernel;
    loss_prepare prepare; /* NULL for none */
    const void *data;     /* the kernel's own data (borrowed) */
    cr_energy_term t;     /* the plain term (cr_loss_energy); a copy */
    /* Per-item state left by prepare: (B, V, 4) signed distance and unit
       gradient of the distance per vertex (collision). */
    float *item;
    int64_t item_count; /* B as the caller saw it (the collision's body check) */
    int64_t V;          /* rows of each position input, set in forward */
};

/* A zeroed spec in step memory with the op's callbacks set; NULL on a full
 * arena (the context records it). */
loss_spec *cr_loss_spec_new(cr_nn_ctx *ctx);
/* Run the op: in = npos position tensors, then the aux tensor if has_aux. */
cr_tensor *cr_loss_spec_run(cr_nn_ctx *ctx, loss_spec *s, cr_tensor *const *in);

#endif
