/* energy_fd.h: central-difference checks of a phys/ element kernel, shared
 * by the energy tests. */
#ifndef CREASE_TESTS_ENERGY_FD_H
#define CREASE_TESTS_ENERGY_FD_H

#include "crease/phys_energy.h"

/* The kernel's value at x (3 nvert), no gradient or Hessian. */
double fd_kval(const cr_energy_term *t, int32_t e, const double *x);
double fd_max_abs(const double *a, int n);
/* Max |analytic - central difference| of element e's gradient at x0, step
 * h, relative to max |gradient|. */
double fd_grad_rel_error(const cr_energy_term *t, int32_t e, const double *x0, double h);

/* The term's vertex blocks (t->vertex_block) of element e at x0 against its
 * kernel, largest over the element's vertices k: relative differences of the
 * block's gradient (3) and Hessian (3x3) from the kernel's rows of vertex k
 * (grad, hess), of the block's gradient from central differences of the
 * value in x_k (fd_grad), and of the block's Hessian from central differences
 * of the block's gradient in x_k (fd_hess; meaningful where the Hessian is
 * exact); value_same is 1 when every block's value equals the kernel's bit for
 * bit. All relative to the largest entry of the kernel's gradient or Hessian. */
typedef struct fd_block_errors {
    double grad, hess, fd_grad, fd_hess;
    int value_same;
} fd_block_errors;
fd_block_errors fd_vertex_block_errors(const cr_energy_term *t, int32_t e, const double *x0,
                                       double h);

#endif
