/* crease/phys_energy.h: the one interface every physics energy shares.
 *
 * An energy is a sum over elements (a vertex, a triangle, a hinge); each
 * element touches `nvert` vertices and has a kernel that gives its value, its
 * gradient and its positive semi-definite projected Hessian from the
 * element's vertex positions alone. The reference simulator sums the terms
 * (value, global gradient, sparse Hessian of 3x3 blocks) and Newton-solves;
 * the neural losses wrap the same kernels as fused tape ops; the metrics
 * evaluate values. Box2D's joints are the model: one energy per file in
 * src/phys/, each filling a cr_energy_term with the same signatures.
 *
 *   cr_energy_term terms[8];
 *   cr_membrane_term(membrane, &terms[0]);      // StVK or Baraff-Witkin
 *   cr_bending_term(bending, &terms[1]);
 *   ...
 *   double e = cr_assembly_eval(assembly, terms, x, grad, ...);   (phys_assemble.h)
 *
 * Units: positions m, energies J, gradients N (J/m), Hessians N/m.
 * Positions are double (V,3) in the solver.
 */
#ifndef CREASE_PHYS_ENERGY_H
#define CREASE_PHYS_ENERGY_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_ENERGY_MAX_VERTS = 4 }; /* hinges touch four vertices: 12x12 Hessians */

/* Kernel of one element e: xe (nvert,3) are its vertices' positions, m.
 * Returns the element's energy, J. When g is not NULL, writes (not adds) the
 * gradient (3 nvert) there; when H is not NULL, writes the PSD-projected
 * Hessian (3 nvert x 3 nvert, row-major, symmetric) there. Kernels are pure
 * functions of (data, e, xe): safe to call from many threads at once. */
typedef double (*cr_energy_kernel)(const void *data, int32_t e, const double *xe, double *g,
                                   double *H);

/* Vertex block of element e for its local vertex k (0 <= k < nvert), for
 * solvers that move one vertex at a time (vertex block descent): returns the
 * element's energy, the same bits as the kernel's value; when g is not NULL,
 * writes dE/dx_k (3) there, and when H is not NULL, the (k,k) 3x3 block of
 * the kernel's PSD-projected Hessian (row-major); both equal the kernel's
 * up to roundoff, at a fraction of its cost (no full gradient, no 3n x 3n
 * Hessian). Pure like the kernel. */
typedef double (*cr_energy_vertex_kernel)(const void *data, int32_t e, int k, const double *xe,
                                          double *g, double *H);

typedef struct cr_energy_term {
    const char *name;    /* "membrane", "bending", "gravity", ... (JSON field names) */
    int32_t nelem;       /* elements */
    int nvert;           /* vertices per element, 1..CR_ENERGY_MAX_VERTS */
    const int32_t *elem; /* (nelem, nvert) vertex indices; NULL when nvert == 1 and
                            element e is vertex e */
    cr_energy_kernel kernel;
    const void *data;                     /* the energy's own struct (borrowed) */
    double weight;                        /* multiplies value, gradient and Hessian (default 1) */
    cr_energy_vertex_kernel vertex_block; /* optional (NULL: callers slice the kernel's) */
} cr_energy_term;

/* Element e's vertex indices into idx (nvert). */
void cr_energy_term_vertices(const cr_energy_term *t, int32_t e, int32_t *idx);

/* Project a symmetric n x n matrix (row-major, n <= 12) onto the PSD cone by
 * clamping negative eigenvalues to zero (cyclic Jacobi up to 6 x 6, LAPACK
 * dsyev above). In place. */
void cr_psd_project(double *H, int n);

#ifdef __cplusplus
}
#endif
#endif
