/* crease/phys_assemble.h: sums energy terms into a value, a global gradient
 * and a symmetric block-sparse Hessian for the Newton solver.
 *
 *   cr_assembly *a = NULL;
 *   CR_TRY(cr_assembly_create(terms, nterms, V, &a, err));   pattern + colouring, once
 *   double e = cr_assembly_eval(a, terms, x, grad, 1, term_values);
 *   const cr_hessian *H = cr_assembly_hessian(a);            upper block triangle, filled
 *
 * Pattern: one 3x3 block per vertex pair that shares an element of some term,
 * plus every diagonal block, fixed at creation. Only the upper block triangle
 * (block row <= block column) is stored, column by column, in the order
 * CHOLMOD reads a symmetric upper matrix. Terms of one vertex per element
 * (inertia, gravity, collision, friction) touch only diagonal blocks, so their
 * active sets may change between calls without changing the pattern.
 *
 * Parallelism without races, and deterministic: at creation the elements of
 * each term are coloured greedily (in element order) so that no two elements
 * of one colour share a vertex; evaluation runs colour after colour, the
 * elements of a colour in parallel. Two elements of one colour then never
 * write the same gradient row or Hessian block, and every gradient entry and
 * block receives its contributions in the same order (term, colour, element)
 * whatever the thread count. Element values go to a buffer and are summed in
 * element order, so the value does not depend on the threads either. Each
 * element's Hessian entries go straight to precomputed block slots (no search
 * per evaluation).
 *
 * Units: x m, value J, gradient N, Hessian N/m.
 * Thread safety: an assembly is used by one caller at a time (it owns the
 * Hessian values and scratch); it parallelises internally with cr_parallel_for.
 */
#ifndef CREASE_PHYS_ASSEMBLE_H
#define CREASE_PHYS_ASSEMBLE_H

#include "crease/phys_energy.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Symmetric block-sparse matrix, upper block triangle stored by block column.
 * Block k holds A[3 row[k] .. +2][3 J .. +2] row-major for the column J with
 * col_off[J] <= k < col_off[J+1]; rows ascend within a column and the last
 * block of each column is its diagonal. B = col_off[V] blocks. */
typedef struct cr_hessian {
    int32_t nv;       /* V: block rows = block columns */
    int64_t nblock;   /* B */
    int64_t *col_off; /* (V+1) offsets into row / val */
    int32_t *row;     /* (B) block row of each block */
    int32_t *col;     /* (B) block column of each block */
    double *val;      /* (B,9) block entries, N/m */
    int64_t *row_off; /* (V+1) offsets into row_blk */
    int64_t *row_blk; /* (B) the blocks again, grouped by block row (columns ascending) */
} cr_hessian;

/* y = A x for x, y (V,3), both triangles of A. Each y row is summed by one
 * thread in a fixed order (deterministic). y must not alias x. */
void cr_hessian_multiply(const cr_hessian *h, const double *x, double *y);

typedef struct cr_assembly cr_assembly;

/* Pattern and colouring of `nterms` terms over V vertices. Every element's
 * vertex indices must lie in [0, V) (CR_ERR_RANGE naming the term and element
 * otherwise); nvert must be 1..CR_ENERGY_MAX_VERTS (CR_ERR_INVALID). The terms'
 * element arrays are read now and must not change afterwards; kernels, data
 * and weights may. The caller destroys *out. */
cr_status cr_assembly_create(const cr_energy_term *terms, int nterms, int32_t nv, cr_assembly **out,
                             cr_error *err);
void cr_assembly_destroy(cr_assembly *a);

/* Evaluate the terms given at creation (same count, order, elements) at
 * x (V,3), m. Returns the weighted total, J. grad (V,3), N, may be NULL;
 * with want_hessian the assembly's Hessian is overwritten; term_values
 * (nterms), J, weighted, may be NULL. A term with weight 0 is skipped. */
double cr_assembly_eval(cr_assembly *a, const cr_energy_term *terms, const double *x, double *grad,
                        int want_hessian, double *term_values);

const cr_hessian *cr_assembly_hessian(const cr_assembly *a);

/* Colours of term t (elements of one colour share no vertex), for reports. */
int cr_assembly_colour_count(const cr_assembly *a, int t);

#ifdef __cplusplus
}
#endif
#endif
