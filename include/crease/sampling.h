/* crease/sampling.h: graph geodesics and farthest point sampling.
 *
 *   cr_geodesic_dijkstra   distances along mesh edges from one or many sources
 *   cr_fps_euclidean       farthest point sampling of a point set (straight-line distance)
 *   cr_fps_geodesic        farthest point sampling of mesh vertices (edge-graph distance)
 *
 * Geodesics here are shortest paths on the edge graph weighted by edge
 * length: an upper bound on the true surface geodesic, and a coarse one where
 * no edge runs in the path's direction (on a grid with one diagonal per cell,
 * a path along the other diagonal comes out sqrt(2) too long). Good enough
 * for spreading samples; not for measuring.
 * Farthest point sampling picks `first`, then repeatedly the point farthest
 * from all points picked so far; the coverage radius (largest such distance)
 * never grows as samples are added. Results are deterministic: ties go to the
 * lowest index. Points at infinite distance (another connected component)
 * are picked before any finite one, so every component gets a sample early.
 */
#ifndef CREASE_SAMPLING_H
#define CREASE_SAMPLING_H

#include "crease/mesh.h"
#include "crease/topology.h"

#ifdef __cplusplus
extern "C" {
#endif

/* dist (V), m: the shortest edge-path length from the nearest of the nsrc
 * sources; INFINITY where no path exists. Binary heap, O((V + E) log V),
 * summed in double. CR_ERR_RANGE for a source out of range, CR_ERR_INVALID for
 * nsrc < 1, CR_ERR_SHAPE when `t` was not built from `m`. */
cr_status cr_geodesic_dijkstra(const cr_mesh *m, const cr_topology *t, const int32_t *sources,
                               int32_t nsrc, float *dist, cr_error *err);

/* k samples of the n points pts (N,3), starting at index `first`: out_idx (k),
 * distinct indices in the order picked. O(k N). CR_ERR_RANGE unless
 * 1 <= k <= n and 0 <= first < n. */
cr_status cr_fps_euclidean(const float *pts, int32_t n, int32_t k, int32_t first, int32_t *out_idx,
                           cr_error *err);

/* k vertices of `m` by farthest point sampling under edge-graph distance,
 * starting at vertex `first`: out_idx (k), distinct. Each new sample runs a
 * Dijkstra that only expands vertices it brings closer than before, so later
 * samples touch ever smaller regions. Same errors as above (with V for n). */
cr_status cr_fps_geodesic(const cr_mesh *m, const cr_topology *t, int32_t k, int32_t first,
                          int32_t *out_idx, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
