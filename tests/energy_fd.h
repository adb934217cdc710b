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

#endif
