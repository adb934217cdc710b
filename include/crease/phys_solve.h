/* crease/phys_solve.h: sparse Cholesky solves of the Newton system, through
 * SuiteSparse CHOLMOD.
 *
 *   cr_cholesky *c = NULL;
 *   CR_TRY(cr_cholesky_create(H, pinned, &c, err));   ordering + symbolic analysis, once
 *   per Newton iteration:
 *     CR_TRY(cr_cholesky_factor(c, H, &info, err));   numeric factorisation (shifted if needed)
 *     CR_TRY(cr_cholesky_solve(c, rhs, dx, err));      (H + shift I) dx = rhs on the free DOFs
 *
 * The pattern of the cr_hessian given at creation is analysed once (CHOLMOD
 * tries AMD, METIS and NESDIS and keeps the ordering of least fill) and
 * reused by every factorisation. Pinned vertices are removed from the system:
 * their three DOFs have no row or column, and their entries of the solution
 * are zero. A matrix that is not positive definite (a quasi-static solve with
 * a free rigid mode, a non-convex energy whose local Hessians were not
 * projected) is retried with a diagonal shift: 1e-8 of the largest diagonal
 * entry, ten times more on each of up to CR_CHOLESKY_MAX_SHIFTS retries (so
 * up to 100 times that entry). The shift used comes back in
 * cr_cholesky_info; the Newton step is then a damped one
 * (Levenberg-Marquardt).
 *
 * CHOLMOD's supernodal factorisation calls BLAS/LAPACK (dgemm, dsyrk,
 * dpotrf); at run time these resolve to the process's single OpenBLAS (see
 * docs/physics.md). Nothing is printed: CHOLMOD's own messages are off.
 * Thread safety: one caller per cr_cholesky.
 */
#ifndef CREASE_PHYS_SOLVE_H
#define CREASE_PHYS_SOLVE_H

#include "crease/phys_assemble.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_CHOLESKY_MAX_SHIFTS = 10 };

typedef struct cr_cholesky cr_cholesky;

typedef struct cr_cholesky_info {
    double shift;         /* diagonal shift of the last factorisation (0: none), N/m */
    int retries;          /* factorisations that failed before it */
    int64_t factor_nnz;   /* entries of L */
    const char *ordering; /* "AMD", "METIS", "NESDIS", "natural", ... */
} cr_cholesky_info;

/* Analyse the pattern of h with the vertices where pinned[v] != 0 removed
 * (pinned may be NULL). CR_ERR_INVALID when every vertex is pinned;
 * CR_ERR_MEMORY when CHOLMOD runs out. The caller destroys *out. */
cr_status cr_cholesky_create(const cr_hessian *h, const uint8_t *pinned, cr_cholesky **out,
                             cr_error *err);
void cr_cholesky_destroy(cr_cholesky *c);

/* Factorise the values of h (same pattern as at creation). Non-finite entries
 * give CR_ERR_NAN; a matrix still not positive definite after every shift
 * gives CR_ERR_DIVERGED. info (may be NULL) receives the shift used. */
cr_status cr_cholesky_factor(cr_cholesky *c, const cr_hessian *h, cr_cholesky_info *info,
                             cr_error *err);

/* Solve with the last factorisation: rhs, x (V,3) (may alias); pinned rows of
 * x come back zero. */
cr_status cr_cholesky_solve(cr_cholesky *c, const double *rhs, double *x, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
