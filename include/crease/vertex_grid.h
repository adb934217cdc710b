/* crease/vertex_grid.h: the nearest vertex of a static mesh by a grid of
 * candidate lists, exact, for many queries near the mesh.
 *
 * A uniform grid over a box holds, per cell, every vertex that can be the
 * nearest to some point of the cell (a superset of the Voronoi regions that
 * meet the cell); a query scans its cell's short list. Cells whose list would
 * be longer than a cap, or with a corner far from every vertex (deep inside a
 * large object, far outside it), keep none,
 * and their points, like points outside the box, go to the BVH. The answer is
 * the BVH's (cr_bvh_nearest_vertex): the same vertex, the lowest index among
 * vertices at exactly the same distance.
 *
 *     cr_vertex_grid *g;
 *     CR_TRY(cr_vertex_grid_build(tree, lo, hi, NULL, &g, err));   tree outlives g
 *     int32_t v = cr_vertex_grid_nearest(g, p, &d);
 *
 * Why: the drape's collision term asks for the nearest object vertex of
 * thousands of cloth points per epoch; the BVH's answer for a point a few
 * centimetres off the ball visits dozens of nodes (about 0.5 us), a list
 * scan a dozen vertices.
 *
 * Read-only once built, safe to share between threads. The BVH must not be
 * refitted while the grid is in use (the lists would be stale).
 */
#ifndef CREASE_VERTEX_GRID_H
#define CREASE_VERTEX_GRID_H

#include "crease/bvh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cr_vertex_grid cr_vertex_grid;

typedef struct cr_vertex_grid_opts {
    double cells_per_vertex; /* grid cells per mesh vertex (the cell size follows); default 2 */
    int32_t max_cells;       /* at most this many cells; default 2^21 */
    int32_t max_list;        /* a cell with more candidates keeps none (the BVH answers); 64 */
    double reach_cells;      /* a cell with a corner farther than this many cells from every
                                vertex keeps none (the BVH answers); 12 */
    int64_t max_entries;     /* list entries in all at most (16 bytes each; cells past the
                                budget keep none); 2^23, 128 MB */
} cr_vertex_grid_opts;

cr_vertex_grid_opts cr_vertex_grid_default_opts(void);

/* Build over the vertices the faces of `tree` use, for points in the box
 * [lo, hi] (m). opts may be NULL (the defaults). Fails with CR_ERR_INVALID
 * for an empty or non-finite box or options out of range. */
cr_status cr_vertex_grid_build(const cr_bvh *tree, const float lo[3], const float hi[3],
                               const cr_vertex_grid_opts *opts, cr_vertex_grid **out,
                               cr_error *err);
void cr_vertex_grid_destroy(cr_vertex_grid *g);

/* The vertex nearest to p and its distance (dist may be NULL): the same as
 * cr_bvh_nearest_vertex(tree, p, INFINITY, dist). */
int32_t cr_vertex_grid_nearest(const cr_vertex_grid *g, const float p[3], float *dist);

/* For reports and tests: cells along each axis, list entries in all, and
 * cells that keep no list (their points go to the BVH). */
void cr_vertex_grid_stats(const cr_vertex_grid *g, int32_t n[3], int64_t *entries,
                          int64_t *overfull);

#ifdef __cplusplus
}
#endif
#endif
