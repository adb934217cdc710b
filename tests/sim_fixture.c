/* sim_fixture.c: see sim_fixture.h. */
#include "sim_fixture.h"

#include "crease/bvh.h"
#include "crease/phys_material.h"
#include "crease/primitives.h"

#include <math.h>
#include <stdlib.h>

cr_mesh *fixture_flat_cloth(int32_t n, float size, float y) {
    cr_mesh *m = NULL;
    cr_error err = {0};
    if (cr_prim_plane(n, n, size, size, &m, &err) != CR_OK) return NULL;
    for (int32_t v = 0; v < m->nv; v++)
        m->pos[3 * v + 1] = y;
    return m;
}

cr_sim_def fixture_cotton_def(void) {
    cr_sim_def d = cr_sim_default_def();
    cr_error err = {0};
    cr_material_preset("cotton", &d.material, &err);
    return d;
}

double fixture_deepest_inside(const cr_mesh *collider, const double *x, int32_t nv) {
    cr_bvh *b = NULL;
    cr_error err = {0};
    if (cr_bvh_build(collider->pos, collider->nv, collider->tri, collider->nf, &b, &err) != CR_OK)
        return INFINITY;
    float *p = malloc((size_t)nv * 3 * sizeof(float)), *d = malloc((size_t)nv * sizeof(float));
    for (int64_t k = 0; k < 3 * (int64_t)nv; k++)
        p[k] = (float)x[k];
    cr_bvh_signed_distance_batch(b, p, nv, INFINITY, d, NULL, NULL);
    double deepest = 0;
    for (int32_t i = 0; i < nv; i++)
        deepest = fmax(deepest, -(double)d[i]);
    cr_bvh_destroy(b);
    free(p), free(d);
    return deepest;
}

double fixture_deepest_centroid_inside(const cr_mesh *collider, const cr_mesh *cloth,
                                       const double *x) {
    double *c = malloc((size_t)(cloth->nf > 0 ? cloth->nf : 1) * 3 * sizeof(double));
    if (!c) return INFINITY;
    for (int32_t f = 0; f < cloth->nf; f++)
        for (int d = 0; d < 3; d++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                s += x[3 * (int64_t)cloth->tri[3 * (int64_t)f + k] + d];
            c[3 * (int64_t)f + d] = s / 3.0;
        }
    const double deepest = fixture_deepest_inside(collider, c, cloth->nf);
    free(c);
    return deepest;
}
