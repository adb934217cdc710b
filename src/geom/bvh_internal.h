/* bvh_internal.h: the BVH's layout, shared by bvh.c (build, refit) and
 * bvh_query.c (traversals). Private to src/geom. */
#ifndef CREASE_BVH_INTERNAL_H
#define CREASE_BVH_INTERNAL_H

#include "crease/bvh.h"

/* Most triangles in a leaf. */
enum { BVH_LEAF_MAX = 4 };
/* Past this depth the builder splits at the object median, so a tree over at
 * most 2^31 faces is under BVH_MEDIAN_DEPTH + 32 levels deep; traversal
 * stacks hold BVH_STACK entries (depth + 1 suffice for ordered traversal). */
enum { BVH_MEDIAN_DEPTH = 48, BVH_STACK = 96 };

/* One node, 32 bytes. count == 0: internal, children at start and start + 1
 * (always after the parent in the array, so a reverse sweep is bottom-up).
 * count > 0: leaf over faces order[start .. start + count). */
typedef struct bvh_node {
    float lo[3];
    int32_t start;
    float hi[3];
    int32_t count;
} bvh_node;

/* min/max as plain compares: fminf/fmaxf are library calls on x86 (they must
 * honour NaN), which cost the build and traversal loops several times over.
 * Positions are checked finite, so boxes never hold a NaN. */
static inline float bvh_minf(float a, float b) {
    return a < b ? a : b;
}
static inline float bvh_maxf(float a, float b) {
    return a > b ? a : b;
}

struct cr_bvh {
    int32_t nv; /* V */
    int32_t nf; /* F */
    int32_t nnodes;
    int32_t depth;
    float *pos;        /* (V,3) own copy of the positions, m */
    int32_t *tri;      /* (F,3) */
    int32_t *adj;      /* (F,3) face across edge k (corner k to k+1), -1 on a boundary or
                          non-manifold edge */
    float *fnormal;    /* (F,3) unit face normals */
    float *vnormal;    /* (V,3) unit angle-weighted vertex normals; stale after a refit
                          until cr_bvh_vertex_normals (queries compute the ones they meet) */
    int vnormal_stale;
    int64_t *vf_start; /* (V+1) faces around vertex v are vf[vf_start[v] .. vf_start[v+1]) */
    int32_t *vf;       /* (3F) vertex-to-face incidence */
    int32_t *order;    /* (F) faces in leaf order */
    float *leaf_pos;   /* (F,9) corner positions of face order[i] at 9 i: leaves read their
                          triangles from one contiguous run instead of via tri and pos */
    bvh_node *nodes;   /* (nnodes), root first */
};

/* Vertex v's unit angle-weighted normal from the current positions and face
 * normals (what vnormal holds when not stale), into out. */
void cr_bvh_vertex_normal_of(const cr_bvh *b, int64_t v, float out[3]);

#endif
