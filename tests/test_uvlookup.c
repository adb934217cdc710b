/* test_uvlookup.c: the UV lookup inverts the rest mapping (every UV corner and
 * random points inside UV triangles land on the right 3D point to 1e-6) on a
 * plane, a cylinder with a UV seam and an icosphere; points outside are
 * refused; the closest-triangle query agrees with brute force. */
#include "crease/primitives.h"
#include "crease/uvlookup.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static const double POS_TOL = 1e-6; /* m, on meshes of unit size */

/* For every corner of every face and `nrand` random points in random UV
 * triangles: find, interpolate the rest position, compare with the position
 * interpolated directly from the known face and barycentrics. */
static void check_inverts(const cr_mesh *m, int32_t grid_res, int nrand, const char *name) {
    cr_error err = {0};
    cr_uv_lookup *lk = NULL;
    CR_CHECK_OK(cr_uv_lookup_build(m, grid_res, &lk, &err), &err);
    CR_REQUIRE(lk);
    double worst = 0.0;
    int missed = 0;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            const float *uv = &m->uv[2 * m->tri_uv[3 * f + k]];
            const float *want = &m->pos[3 * m->tri[3 * f + k]];
            float got[3];
            if (!cr_uv_lookup_rest_position(lk, m->pos, uv[0], uv[1], got)) {
                missed++;
                continue;
            }
            for (int d = 0; d < 3; d++)
                worst = fmax(worst, fabs((double)got[d] - want[d]));
        }
    cr_rng r = cr_rng_make(21, 0);
    for (int i = 0; i < nrand; i++) {
        int32_t f = (int32_t)cr_rng_below(&r, (uint32_t)m->nf);
        /* Uniform barycentrics (Osada et al. 2002). */
        double s = sqrt(cr_rng_uniform(&r)), t = cr_rng_uniform(&r);
        double b[3] = {1.0 - s, s * (1.0 - t), s * t};
        double u = 0, v = 0, want[3] = {0, 0, 0};
        for (int k = 0; k < 3; k++) {
            const float *uv = &m->uv[2 * m->tri_uv[3 * f + k]];
            const float *p = &m->pos[3 * m->tri[3 * f + k]];
            u += b[k] * uv[0], v += b[k] * uv[1];
            for (int d = 0; d < 3; d++)
                want[d] += b[k] * p[d];
        }
        int32_t face;
        double bary[3];
        if (!cr_uv_lookup_find(lk, (float)u, (float)v, &face, bary)) {
            missed++;
            continue;
        }
        CR_CHECK_NEAR(bary[0] + bary[1] + bary[2], 1.0, 1e-12);
        float got[3];
        cr_uv_lookup_interpolate(lk, m->pos, 3, face, bary, got);
        for (int d = 0; d < 3; d++)
            worst = fmax(worst, fabs(got[d] - want[d]));
    }
    if (missed || worst > POS_TOL)
        fprintf(stderr, "  %s (grid %d): %d missed, worst %.3g m\n", name, grid_res, missed, worst);
    CR_CHECK(missed == 0);
    CR_CHECK(worst <= POS_TOL);
    cr_uv_lookup_destroy(lk);
}

CR_TEST(uvlookup, inverts_plane_cylinder_icosphere) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(11, 7, 1.0f, 0.8f, &m, &err), &err);
    CR_REQUIRE(m);
    check_inverts(m, 0, 3000, "plane");
    check_inverts(m, 1, 300, "plane");  /* one cell holding every face */
    check_inverts(m, 37, 300, "plane"); /* cells smaller than faces */
    cr_mesh_destroy(m);
    /* The cylinder's side is cut along a seam: vertices there carry u = 0 and u = 1. */
    for (int capped = 0; capped < 2; capped++) {
        CR_CHECK_OK(cr_prim_cylinder(0.4f, 1.0f, 24, 5, capped, &m, &err), &err);
        CR_REQUIRE(m);
        CR_CHECK(m->nuv > m->nv);
        check_inverts(m, 0, 3000, capped ? "capped cylinder" : "open cylinder");
        cr_mesh_destroy(m);
    }
    CR_CHECK_OK(cr_prim_icosphere(0.5f, 2, &m, &err), &err);
    CR_REQUIRE(m);
    check_inverts(m, 0, 3000, "icosphere");
    cr_mesh_destroy(m);
}

CR_TEST(uvlookup, outside_points_and_bad_input) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(3, 3, 1.0f, 1.0f, &m, &err), &err);
    CR_REQUIRE(m);
    cr_uv_lookup *lk = NULL;
    CR_CHECK_OK(cr_uv_lookup_build(m, 0, &lk, &err), &err);
    CR_REQUIRE(lk);
    int32_t face = 7;
    double b[3];
    const float outside[][2] = {{1.01f, 0.5f}, {-0.2f, -0.2f}, {0.5f, 1.5f}, {1e30f, 0.5f}};
    for (int i = 0; i < 4; i++) {
        CR_CHECK(!cr_uv_lookup_find(lk, outside[i][0], outside[i][1], &face, b));
        CR_CHECK(face == -1);
    }
    CR_CHECK(!cr_uv_lookup_find(lk, NAN, 0.5f, &face, b));
    /* Within the edge tolerance counts as inside. */
    CR_CHECK(cr_uv_lookup_find(lk, 1.0f + 1e-7f, 0.5f, &face, b));
    float lo[2], hi[2];
    cr_uv_lookup_bounds(lk, lo, hi);
    CR_CHECK(lo[0] == 0.0f && lo[1] == 0.0f && hi[0] == 1.0f && hi[1] == 1.0f);
    cr_uv_lookup_destroy(lk);

    CR_CHECK(cr_uv_lookup_build(m, -1, &lk, &err) == CR_ERR_INVALID && lk == NULL);
    m->tri_uv[5] = 99;
    CR_CHECK(cr_uv_lookup_build(m, 0, &lk, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "face 1 uses UV 99") != NULL);
    cr_mesh_destroy(m);

    /* A mesh without UVs is refused with a reason. */
    CR_CHECK_OK(cr_mesh_create(3, 1, 0, &m, &err), &err);
    CR_REQUIRE(m);
    m->tri[1] = 1, m->tri[2] = 2;
    CR_CHECK(cr_uv_lookup_build(m, 0, &lk, &err) == CR_ERR_INVALID && lk == NULL);
    CR_CHECK(strstr(err.msg, "no UVs") != NULL);
    cr_mesh_destroy(m);
}

/* Brute-force UV distance from (u, v) to face f, in double. */
static double brute_dist(const cr_mesh *m, int32_t f, double u, double v) {
    double c[3][2];
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 2; a++)
            c[k][a] = m->uv[2 * m->tri_uv[3 * f + k] + a];
    double det =
        (c[1][0] - c[0][0]) * (c[2][1] - c[0][1]) - (c[1][1] - c[0][1]) * (c[2][0] - c[0][0]);
    int inside = 1;
    for (int k = 0; k < 3; k++) {
        const double *a = c[k], *b = c[(k + 1) % 3];
        double side = (b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]);
        if (side * det < 0) inside = 0;
    }
    if (inside) return 0.0;
    double best = INFINITY;
    for (int k = 0; k < 3; k++) {
        const double *a = c[k], *b = c[(k + 1) % 3];
        double ex = b[0] - a[0], ey = b[1] - a[1];
        double s = ((u - a[0]) * ex + (v - a[1]) * ey) / (ex * ex + ey * ey);
        s = fmin(1.0, fmax(0.0, s));
        best = fmin(best, hypot(u - a[0] - s * ex, v - a[1] - s * ey));
    }
    return best;
}

/* Closest-triangle queries on random points (some far outside) against brute force. */
static void check_nearest(const cr_mesh *m, int32_t res, uint64_t seed) {
    cr_error err = {0};
    cr_uv_lookup *lk = NULL;
    CR_CHECK_OK(cr_uv_lookup_build(m, res, &lk, &err), &err);
    CR_REQUIRE(lk);
    cr_rng r = cr_rng_make(8, seed);
    for (int i = 0; i < 500; i++) {
        double span = i % 10 == 0 ? 20.0 : 1.4;
        float u = (float)(0.5 + span * (cr_rng_uniform(&r) - 0.5));
        float v = (float)(0.5 + span * (cr_rng_uniform(&r) - 0.5));
        double want = INFINITY;
        for (int32_t f = 0; f < m->nf; f++)
            want = fmin(want, brute_dist(m, f, u, v));
        int32_t face;
        double b[3], dist;
        CR_REQUIRE(cr_uv_lookup_nearest(lk, u, v, &face, b, &dist));
        CR_CHECK_NEAR(dist, want, 1e-9);
        CR_CHECK(b[0] >= 0 && b[1] >= 0 && b[2] >= 0);
        CR_CHECK_NEAR(b[0] + b[1] + b[2], 1.0, 1e-12);
        /* The barycentrics name the closest point itself. */
        double pu = 0, pv = 0;
        for (int k = 0; k < 3; k++) {
            pu += b[k] * m->uv[2 * m->tri_uv[3 * face + k]];
            pv += b[k] * m->uv[2 * m->tri_uv[3 * face + k] + 1];
        }
        CR_CHECK_NEAR(hypot(pu - u, pv - v), want, 1e-6);
    }
    cr_uv_lookup_destroy(lk);
}

CR_TEST(uvlookup, nearest_matches_brute_force) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    /* The box's 3x2 atlas leaves gaps between charts. */
    CR_CHECK_OK(cr_prim_box(1.0f, 0.6f, 0.4f, 3, &m, &err), &err);
    CR_REQUIRE(m);
    check_nearest(m, 0, 0);
    check_nearest(m, 1, 1);
    check_nearest(m, 50, 2);
    cr_mesh_destroy(m);
    /* A few small triangles scattered over the square: the nearest is often
     * several rings of cells away, and not in the first ring that holds any. */
    const int32_t nf = 8;
    CR_CHECK_OK(cr_mesh_create(3 * nf, nf, 3 * nf, &m, &err), &err);
    CR_REQUIRE(m);
    cr_rng r = cr_rng_make(13, 0);
    for (int32_t f = 0; f < nf; f++) {
        double cu = cr_rng_uniform(&r), cv = cr_rng_uniform(&r);
        for (int k = 0; k < 3; k++) {
            int32_t i = 3 * f + k;
            m->tri[i] = m->tri_uv[i] = i;
            m->uv[2 * i] = (float)(cu + 0.04 * (k == 1) + 0.01 * cr_rng_uniform(&r));
            m->uv[2 * i + 1] = (float)(cv + 0.04 * (k == 2) + 0.01 * cr_rng_uniform(&r));
        }
    }
    check_nearest(m, 0, 3);
    check_nearest(m, 40, 4);
    cr_mesh_destroy(m);
}
