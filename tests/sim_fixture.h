/* sim_fixture.h: scenes and measures shared by the simulator tests
 * (test_phys_sim.c, test_phys_vbd.c, test_phys_qn.c). */
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

/* The plasticity scene of test_phys_sim.c with the given solver: a strip
 * folded about 60 degrees by a capsule that then slides off; the fold angle
 * after `frames` frames, degrees (NaN when a frame fails, or when hinges yield
 * without plasticity or none with it); the state's hash into *hash. */
double fixture_fold_strip(cr_sim_solver solver, int plastic, int frames, uint64_t *hash);

#endif
