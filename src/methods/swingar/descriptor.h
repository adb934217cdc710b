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
 *      not change when the garment is scaled: it describes the shape, the size
 *      reaches the network through the vertex positions);
 *   4. B (z,z), the affinity of the samples, weighted as a quadrature of the
 *      kernel's integral operator: B_w = W_s^1/2 B W_s^1/2, W_s = share of the
 *      surface area in each sample's geodesic Voronoi cell; its eigenvalues
 *      (LAPACK dsyev) are the descriptor: the paper's Lambda, normalised so
 *      that they approximate the operator's spectrum (independent of V and z
 *      in the limit) and sum to exactly 1 (the trace);
 *   5. on request, the Nystrom extension of the eigenvectors to every vertex,
 *      Q^ = K U Lambda^-1 in weighted form (Fowlkes et al. 2004; the paper's
 *      Fig. 4 shows these).
 * The geodesic kernel is not positive definite: the smallest entries can be
 * negative (a few 1e-4 at the default width); they stay, sorted last.
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
    float *eigenvectors; /* (V,z) row-major: column k is the Nystrom-extended eigenfunction of
                            eigenvalue k, f_k(x) = sum_a K(x, s_a) ws_a f_k(s_a) / lambda_k,
                            orthonormal on the samples in the cell weights (sum_a ws_a f_k f_l
                            = delta_kl) and about so over all vertices in the vertex-area
                            weights; 0 columns for eigenvalues under 1e-9 of the largest */
    int32_t *sample_idx; /* (z) the FPS vertices, in the order picked */
    float *sigma;        /* (1) the kernel width used, m */
} cr_swingar_descriptor_extra;

/* cr_swingar_descriptor with the error in `err` and the optional outputs. */
cr_status cr_swingar_descriptor_full(const cr_mesh *mesh, const cr_swingar_descriptor_opts *opts,
                                     float *eigenvalues, const cr_swingar_descriptor_extra *extra,
                                     cr_error *err);

/* The exact counterpart, for tests and small meshes: the eigenvalues of
 * W^1/2 K W^1/2 with K the (V,V) affinity of all vertices and W their area
 * shares, at the kernel width `sigma` (m), sorted descending: eigenvalues (V).
 * Equal to cr_swingar_descriptor with samples = V at the same sigma.
 * O(V^2) memory, O(V^3) time. */
cr_status cr_swingar_descriptor_exact(const cr_mesh *mesh, cr_swingar_affinity affinity,
                                      float sigma, float *eigenvalues, cr_error *err);

#endif
