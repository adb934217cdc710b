/* sim_fixture.c: see sim_fixture.h. */
#include "sim_fixture.h"

#include "crease/bvh.h"
#include "crease/phys_material.h"
#include "crease/primitives.h"

#include <math.h>
#include <stdio.h>
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

/* A strip 0.2 m long (z) and 3 cm wide (x), in zero gravity, its z < 0 half
 * pinned; a thin capsule lying along x comes down on the free half at
 * z = 5 cm, folds it down by about 60 degrees about the pinned edge, then
 * slides off sideways. Returns the fold angle after `frames` frames:
 * between +z and the free arm (from the fold line to the tip), degrees; NaN
 * when a frame fails, or when hinges yield without plasticity or none with
 * it. */
double fixture_fold_strip(cr_sim_solver solver, int plastic, int frames, uint64_t *hash) {
    enum { NX = 5, NZ = 41, DOWN = 20, SLIDE = 15 };
    cr_error err = {0};
    cr_mesh *strip = NULL, *cap = NULL;
    if (cr_prim_plane(NX, NZ, 0.03f, 0.2f, &strip, &err) != CR_OK) return NAN;
    if (cr_prim_capsule(0.01f, 0.08f, 16, 4, &cap, &err) != CR_OK) return NAN;
    for (int32_t v = 0; v < cap->nv; v++) { /* axis Y -> X: a rotation about z */
        float *p = cap->pos + 3 * v, x = p[0];
        p[0] = p[1], p[1] = -x;
    }
    float *seq = malloc(sizeof(float) * 3 * (size_t)cap->nv * frames);
    for (int f = 0; f < frames; f++) {
        float y = f < DOWN ? 0.02f - 0.12f * f / DOWN : -0.1f;
        float x = f < DOWN ? 0.0f : 0.2f * fminf(1.0f, (float)(f - DOWN) / SLIDE);
        for (int32_t v = 0; v < cap->nv; v++) {
            float *p = seq + 3 * ((size_t)cap->nv * f + v);
            p[0] = cap->pos[3 * v] + x, p[1] = cap->pos[3 * v + 1] + y;
            p[2] = cap->pos[3 * v + 2] + 0.05f;
        }
    }
    cr_sim_def d = fixture_cotton_def();
    d.material.bending = 1e-3;     /* paper-like: springs back within the test */
    d.material.yield_angle = 0.02; /* rad per hinge: low */
    d.material.friction = 0.0;
    d.gravity[1] = 0.0;
    d.damping = 2.0;
    d.plasticity = plastic;
    d.solver = solver;
    int32_t pins[NX * NZ / 2];
    for (int32_t i = 0; i < NX * (NZ / 2); i++)
        pins[i] = i;
    d.pinned = pins, d.npinned = NX * (NZ / 2);
    d.collider = cap, d.collider_frames = seq, d.collider_nframes = frames;
    cr_sim *s = NULL;
    double angle = NAN;
    if (cr_sim_create(&d, strip, &s, &err) == CR_OK) {
        cr_sim_report rep;
        int ok = 1, yielded = 0;
        for (int f = 0; f < frames && ok; f++) {
            ok = cr_sim_step(s, &rep, &err) == CR_OK;
            yielded += rep.yielded;
        }
        const double *x = cr_sim_positions(s);
        const double *a = x + 3 * ((NZ / 2 + 1) * NX + NX / 2),
                     *b = x + 3 * ((NZ - 1) * NX + NX / 2);
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        if (ok) angle = acos(u[2] / sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])) * 180.0 / M_PI;
        if (!ok) printf("    fold: %s\n", err.msg);
        if ((yielded > 0) != (plastic != 0)) angle = NAN; /* plasticity yields, or nothing does */
        if (hash) *hash = cr_sim_state_hash(s);
    }
    cr_sim_destroy(s);
    cr_mesh_destroy(strip);
    cr_mesh_destroy(cap);
    free(seq);
    return angle;
}
