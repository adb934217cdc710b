/* sim_fixture.h: scenes and measures shared by the simulator tests
 * (test_phys_sim.c, test_phys_vbd.c). */
#ifndef CREASE_TESTS_SIM_FIXTURE_H
#define CREASE_TESTS_SIM_FIXTURE_H

#include "crease/mesh.h"
#include "crease/phys_sim.h"

/* A square cloth of n x n vertices and side `size`, horizontal at height y. */
cr_mesh *fixture_flat_cloth(int32_t n, float size, float y);
/* cr_sim_default_def with the cotton material. */
cr_sim_def fixture_cotton_def(void);
/* Deepest vertex of x (nv, 3) inside the collider mesh, m (0 when none), by
 * an independent unbounded BVH query; INFINITY when the BVH cannot be built. */
double fixture_deepest_inside(const cr_mesh *collider, const double *x, int32_t nv);
/* The same of the centroids of cloth's faces at positions x (nv, 3). */
double fixture_deepest_centroid_inside(const cr_mesh *collider, const cr_mesh *cloth,
                                       const double *x);

#endif
