/* test_long_phys.c: the simulator's acceptance runs that take minutes, not
 * seconds, so `make check` leaves them out (ctest label "long"); `make
 * test-long` runs them with the 1,500-frame tube (bench_sim tube10k).
 *
 *   cloth_128_dropped_on_sphere: a 1 m cotton square of 128 x 128 vertices
 *   dropped from 4 cm above a sphere of radius 0.3 m for 45 frames (1.5 s):
 *   no NaN, no vertex ever more than 1 mm inside the sphere (measured before
 *   the end-of-step projection, so the projection cannot hide it), and the
 *   cloth rests on the sphere with its corners hanging below the top.
 */
#include "crease/bvh.h"
#include "crease/phys_sim.h"
#include "crease/primitives.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>

CR_TEST(long_phys, cloth_128_dropped_on_sphere) {
    enum { N = 128, FRAMES = 45 };
    cr_error err = {0};
    cr_mesh *cloth = NULL, *sphere = NULL;
    CR_CHECK_OK(cr_prim_plane(N, N, 1.0f, 1.0f, &cloth, &err), &err);
    CR_CHECK_OK(cr_prim_sphere_uv(0.3f, 96, 48, &sphere, &err), &err);
    CR_REQUIRE(cloth && sphere);
    for (int32_t v = 0; v < cloth->nv; v++)
        cloth->pos[3 * v + 1] = 0.34f;
    cr_sim_def d = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &d.material, &err), &err);
    d.collider = sphere;
    cr_sim *s = NULL;
    CR_CHECK_OK(cr_sim_create(&d, cloth, &s, &err), &err);
    CR_REQUIRE(s);
    double pen = 0.0, secs = 0.0;
    for (int f = 0; f < FRAMES; f++) {
        cr_sim_report rep;
        CR_CHECK_OK(cr_sim_step(s, &rep, &err), &err);
        pen = fmax(pen, rep.max_penetration_m);
        secs += rep.seconds;
    }
    const double *x = cr_sim_positions(s);
    int finite = 1;
    for (int64_t k = 0; k < 3 * (int64_t)cloth->nv; k++)
        finite &= isfinite(x[k]) != 0;
    CR_CHECK(finite);
    float *p = malloc(sizeof(float) * 3 * (size_t)cloth->nv);
    float *dist = malloc(sizeof(float) * (size_t)cloth->nv);
    CR_REQUIRE(p && dist);
    cr_sim_positions_f(s, p);
    cr_bvh *b = NULL;
    CR_CHECK_OK(cr_bvh_build(sphere->pos, sphere->nv, sphere->tri, sphere->nf, &b, &err), &err);
    CR_REQUIRE(b);
    cr_bvh_signed_distance_batch(b, p, cloth->nv, INFINITY, dist, NULL, NULL);
    double deepest = 0.0;
    for (int32_t i = 0; i < cloth->nv; i++)
        deepest = fmax(deepest, -(double)dist[i]);
    printf("    128x128 on a sphere: %.2f s/frame, deepest before projection %.3f mm, at the end "
           "%.3f mm\n",
           secs / FRAMES, 1e3 * pen, 1e3 * deepest);
    CR_CHECK(pen < 1e-3);
    CR_CHECK(deepest < 1e-3);
    int32_t centre = (N / 2) * N + N / 2;
    CR_CHECK(x[3 * centre + 1] > 0.298); /* on top of the sphere */
    CR_CHECK(x[1] < 0.25);               /* a corner hangs below it */
    cr_bvh_destroy(b);
    free(p), free(dist);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
}
