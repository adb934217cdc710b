/* lapack.h: the Fortran LAPACK prototypes phys/ calls. OpenBLAS carries the
 * Fortran symbols but not LAPACKE, so they are declared here: column-major
 * arrays, every argument by pointer, hidden string lengths left to the
 * default calling convention (gfortran accepts their absence for length-1
 * character arguments). */
#ifndef CREASE_PHYS_LAPACK_H
#define CREASE_PHYS_LAPACK_H

/* Eigenvalues (ascending, in w) and, with jobz = 'V', orthonormal
 * eigenvectors (columns of a) of the symmetric n x n matrix a. */
void dsyev_(const char *jobz, const char *uplo, const int *n, double *a, const int *lda, double *w,
            double *work, const int *lwork, int *info);

#endif
