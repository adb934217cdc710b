/* descriptor.h (private): swingar's spectral shape descriptor (paper 002,
 * section III-B), the z eigenvalues of a Nystrom-approximated affinity matrix
 * of the garment's vertices.
 *
 *   cr_swingar_descriptor_opts o = cr_swingar_descriptor_default_opts();
 *   float lambda[256];                                   (o.samples entries)
 *   cr_status st = cr_swingar_descriptor(garment_mesh, &o, lambda);
 *
 * Pipeline (docs/swingar.md, "Spectral descriptor", gives every choice and why):
 *   1. z vertices by geodesic furthest point sampling (cr_fps_geodesic), from a
 *      deterministic first vertex (the farthest from vertex 0; opts.seed != 0
 *      draws it at random, as the paper does);
 *   2. distances D (V,z) from every vertex to every sample: Dijkstra on the edge
 *      graph (geodesic, the paper's choice) or straight lines (Euclidean, the
 *      ablation of its Table I);
 *   3. affinity K = exp(-D^2 / (2 sigma^2)), sigma = sigma_scale x the median
 *      of the pairwise distances between the samples (so the descriptor does
 *      not change when the garment is scaled: the shape, not the size);
 *   4. B = K[samples] (z,z) = U Lambda U^T (LAPACK dsyev), Nystrom extension
 *      Q^ = K U Lambda^-1 (V,z) (Fowlkes et al. 2004), A^ = Q^ Lambda Q^T;
 *   5. the eigenvalues of W^1/2 A^ W^1/2, W = diag(vertex area / total area):
 *      an orthonormalisation of Q^ in the area-weighted inner product. They
 *      approximate the spectrum of the kernel's integral operator on the
 *      surface, hence do not depend on the vertex count (remeshing) and sum to
 *      about 1 (trace of the weighted kernel: sum_i w_i K(i,i) = 1).
 * Eigenvalues of B below 1e-10 of its largest (numerical noise of a smooth
 * kernel) are dropped; their entries of the descriptor are 0.
 */
#ifndef CREASE_METHODS_SWINGAR_DESCRIPTOR_H
#define CREASE_METHODS_SWINGAR_DESCRIPTOR_H

#include "crease/mesh.h"

typedef enum {
    CR_SWINGAR_AFFINITY_GEODESIC = 0, /* edge-graph Dijkstra distance (paper) */
    CR_SWINGAR_AFFINITY_EUCLIDEAN = 1 /* straight-line distance (Table I ablation) */
} cr_swingar_affinity;

typedef struct {
    int32_t samples; /* z: 256 (128 and 512 selectable) = number of eigenvalues returned;
                        any value in [2, V] is accepted */
    cr_swingar_affinity affinity;
    float sigma_scale; /* Gaussian kernel width sigma as a multiple of the median pairwise
                          distance between the z samples (> 0, default 0.25) */
    uint64_t seed;     /* 0 (default): deterministic first FPS vertex (the farthest from
                          vertex 0); otherwise the first vertex is drawn from this seed */
} cr_swingar_descriptor_opts;

cr_swingar_descriptor_opts cr_swingar_descriptor_default_opts(void);

/* eigenvalues[samples], sorted descending, normalised as documented above
 * (dimensionless; invariant to rigid motions, uniform scaling and, within the
 * Nystrom error, remeshing). The mesh must be one connected piece.
 * CR_ERR_RANGE for samples outside [2, V]; CR_ERR_INVALID for sigma_scale <= 0
 * or an unknown affinity; CR_ERR_TOPOLOGY for a disconnected mesh or one of
 * zero area; CR_ERR_NAN for non-finite positions; CR_ERR_MEMORY. The message
 * goes to the log (cr_log); cr_swingar_descriptor_full returns it. */
cr_status cr_swingar_descriptor(const cr_mesh *mesh, const cr_swingar_descriptor_opts *opts,
                                float *eigenvalues);

/* What the descriptor computed besides the eigenvalues. Any pointer may be NULL. */
typedef struct {
    float *eigenvectors; /* (V,z) row-major: column k is the Nystrom-extended eigenvector of
                            eigenvalue k, orthonormal in the area-weighted inner product
                            (sum_i w_i q_ik q_il = delta_kl); 0 columns for dropped values */
    int32_t *sample_idx; /* (z) the FPS vertices, in the order picked */
    float *sigma;        /* (1) the kernel width used, m */
} cr_swingar_descriptor_extra;

/* cr_swingar_descriptor with the error in `err` and the optional outputs. */
cr_status cr_swingar_descriptor_full(const cr_mesh *mesh, const cr_swingar_descriptor_opts *opts,
                                     float *eigenvalues, const cr_swingar_descriptor_extra *extra,
                                     cr_error *err);

/* The exact counterpart, for tests and small meshes: the eigenvalues of
 * W^1/2 K W^1/2 with K the (V,V) affinity of all vertices, at the kernel width
 * `sigma` (m), sorted descending: eigenvalues (V). O(V^2) memory, O(V^3) time. */
cr_status cr_swingar_descriptor_exact(const cr_mesh *mesh, cr_swingar_affinity affinity,
                                      float sigma, float *eigenvalues, cr_error *err);

#endif
