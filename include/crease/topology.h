/* crease/topology.h: connectivity of a triangle mesh, built once and shared.
 *
 *   unique undirected edges, edge -> faces, face -> edges      edge, edge_face, face_edge
 *   interior hinges for bending (two faces on one edge)        hinge, hinge_edge, hinge_face
 *   vertex -> faces, vertex -> vertices (CSR)                   vf_off/vf, vv_off/vv
 *   face -> face across each edge                               face_face
 *   boundary loops as ordered vertex cycles (CSR)               loop_off/loop_vert
 *   defects: non-manifold edges and vertices, inconsistently
 *   oriented edges, isolated vertices, degenerate faces         n_* counts, first_* offenders
 *
 * Conventions (E edges, H hinges, L boundary loops):
 *   - face_edge[3f+k] is the edge joining corners k and (k+1)%3 of face f, i.e.
 *     the edge opposite corner (k+2)%3. face_face[3f+k] is the face across that edge.
 *   - edge[2e] < edge[2e+1]; edges are sorted lexicographically, so the order
 *     depends only on the triangle list.
 *   - edge_face[2e] is the lowest-numbered face on edge e, edge_face[2e+1] the
 *     next one or -1 on a boundary edge. An edge with more than two faces keeps
 *     the first two here, gets no hinge, and has face_face = -1 across it.
 *   - hinge[4h..4h+3] = (x0, x1, x2, x3): the edge x0-x1, x2 the opposite vertex
 *     in face A = hinge_face[2h] and x3 the one in face B = hinge_face[2h+1].
 *     x0 -> x1 is the direction the edge runs in face A's winding, so face A is
 *     (x0, x1, x2) and, when the pair is consistently oriented, face B is
 *     (x1, x0, x3), as cr_dihedral_angle expects. On an inconsistently oriented
 *     edge the hinge is still emitted in the same form, but then the angle's
 *     sign has no meaning (the pair is counted in n_inconsistent_edges).
 *   - vv lists each vertex's neighbours in ascending order; vf lists its faces
 *     in ascending order.
 *   - Boundary loops run along the winding of their faces: seen from the side
 *     the normals point to, the surface lies to the left. A loop lists each
 *     vertex once (the first is not repeated at the end). At a non-manifold
 *     boundary vertex a walk may end before closing; it is then an open chain.
 *   - Degenerate faces (a repeated vertex index) are left out of every
 *     adjacency: their face_edge and face_face entries are -1.
 *
 * Construction is O(F log d) with d the largest vertex valence: half-edges are
 * bucketed by their smaller vertex (counting sort) and sorted within buckets.
 * A built topology is read-only and safe to share between threads.
 */
#ifndef CREASE_TOPOLOGY_H
#define CREASE_TOPOLOGY_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cr_topology {
    int32_t nv, nf;     /* V, F of the mesh it was built from */
    int32_t ne;         /* E: unique undirected edges */
    int32_t *edge;      /* (E,2) vertex indices, edge[2e] < edge[2e+1] */
    int32_t *edge_face; /* (E,2) faces on the edge, -1 where absent */
    int32_t *face_edge; /* (F,3) edge between corners k and k+1, -1 for degenerate faces */
    int32_t *face_face; /* (F,3) face across face_edge, -1 at boundary / non-manifold edges */

    int32_t nh;          /* H: interior hinges (edges with exactly two faces) */
    int32_t *hinge;      /* (H,4) x0, x1 (edge), x2 (opposite in face A), x3 (opposite in B) */
    int32_t *hinge_edge; /* (H) edge index */
    int32_t *hinge_face; /* (H,2) face A, face B */

    int32_t *vf_off; /* (V+1) offsets into vf */
    int32_t *vf;     /* (vf_off[V]) faces around each vertex */
    int32_t *vv_off; /* (V+1) offsets into vv */
    int32_t *vv;     /* (vv_off[V]) neighbouring vertices */

    int32_t n_boundary_edges;
    uint8_t *vertex_boundary; /* (V) 1 when the vertex lies on a boundary edge */
    int32_t nloop;            /* L: boundary loops (or open chains, see above) */
    int32_t *loop_off;        /* (L+1) offsets into loop_vert */
    int32_t *loop_vert;       /* (loop_off[L]) vertices of each loop in order */

    /* Defects and the first offender of each kind (-1 when none). */
    int32_t n_nonmanifold_edges;    /* edges with more than two faces */
    int32_t n_nonmanifold_vertices; /* faces around the vertex not one disk or half-disk */
    int32_t n_inconsistent_edges;   /* two faces run the edge in the same direction */
    int32_t n_isolated_vertices;    /* no (non-degenerate) face uses the vertex */
    int32_t n_degenerate_faces;     /* a vertex index repeated within the face */
    int32_t first_nonmanifold_edge;
    int32_t first_nonmanifold_vertex;
    int32_t first_inconsistent_edge;
    int32_t first_isolated_vertex;
    int32_t first_degenerate_face;
    int32_t max_edge_faces; /* largest face count on one edge */
} cr_topology;

/* Build the topology of `m`. Fails with CR_ERR_RANGE when a face uses a vertex
 * out of range, CR_ERR_MEMORY when allocation fails. Defects are counted, not
 * refused: call cr_topology_require_manifold where a method needs a manifold.
 * The caller destroys *out. */
cr_status cr_topology_build(const cr_mesh *m, cr_topology **out, cr_error *err);
void cr_topology_destroy(cr_topology *t);

/* CR_OK when the mesh is an oriented 2-manifold, possibly with boundary, with
 * no isolated vertex and no degenerate face. Otherwise CR_ERR_TOPOLOGY with a
 * message that starts with `source` (e.g. a file name), names the first
 * offending edge, vertex or face and gives how many there are. */
cr_status cr_topology_require_manifold(const cr_topology *t, const char *source, cr_error *err);

/* V - E + F, leaving out isolated vertices and degenerate faces: 2 for a
 * closed sphere-like surface, 1 for a disk, 0 for a torus or an open tube. */
int64_t cr_topology_euler_characteristic(const cr_topology *t);

/* CR_ERR_SHAPE, naming `what`, unless t was built for a mesh of m's vertex and face counts. */
cr_status cr_topology_check_mesh(const cr_topology *t, const cr_mesh *m, const char *what,
                                 cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
