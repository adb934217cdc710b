/* test_primitives.c: procedural meshes are watertight, consistently oriented,
 * outward-facing, welded, of the right volume and counts, with sane UVs.
 *
 * Volumes are checked against closed forms: exact ones for the polyhedra
 * (box, prism, n-gon cylinder), and for curved shapes the analytic volume
 * with a tolerance that shrinks with resolution (an inscribed polygon of n
 * sides loses a fraction ~ (2 pi / n)^2 / 6 of its area), plus a convergence
 * check that doubling the resolution reduces the error. */
#include "crease/primitives.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Every directed edge appears once and its reverse also appears: each
 * undirected edge is used by exactly two faces with opposite orientation. */
static int is_watertight_oriented(const cr_mesh *m) {
    size_t ne = 3 * (size_t)m->nf;
    uint64_t *e = malloc(ne * sizeof *e);
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = (uint32_t)m->tri[3 * f + k], b = (uint32_t)m->tri[3 * f + (k + 1) % 3];
            if (a == b) {
                free(e);
                return 0;
            }
            e[3 * (size_t)f + k] = (uint64_t)a << 32 | b;
        }
    qsort(e, ne, sizeof *e, cmp_u64);
    int ok = 1;
    for (size_t i = 0; i < ne && ok; i++) {
        if (i > 0 && e[i] == e[i - 1]) ok = 0;
        uint64_t rev = (e[i] << 32) | (e[i] >> 32);
        if (!bsearch(&rev, e, ne, sizeof *e, cmp_u64)) ok = 0;
    }
    free(e);
    return ok;
}

/* Enclosed volume by the divergence theorem: sum of signed tetrahedra to the origin. */
static double mesh_volume(const cr_mesh *m) {
    double vol = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const float *a = &m->pos[3 * m->tri[3 * f]], *b = &m->pos[3 * m->tri[3 * f + 1]],
                    *c = &m->pos[3 * m->tri[3 * f + 2]];
        double cx = (double)b[1] * c[2] - (double)b[2] * c[1];
        double cy = (double)b[2] * c[0] - (double)b[0] * c[2];
        double cz = (double)b[0] * c[1] - (double)b[1] * c[0];
        vol += (a[0] * cx + a[1] * cy + a[2] * cz) / 6.0;
    }
    return vol;
}

static int32_t count_edges(const cr_mesh *m) { /* closed meshes: every edge twice */
    return 3 * m->nf / 2;
}

/* UVs in [0,1], and (for shapes with a right-handed map) every UV triangle
 * has positive area: no flipped or collapsed triangles across the seams. */
static void check_uvs(const cr_mesh *m, int expect_ccw) {
    CR_REQUIRE(cr_mesh_has_uv(m));
    for (int32_t i = 0; i < 2 * m->nuv; i++)
        CR_REQUIRE(m->uv[i] >= 0.0f && m->uv[i] <= 1.0f);
    int32_t flipped = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const float *a = &m->uv[2 * m->tri_uv[3 * f]], *b = &m->uv[2 * m->tri_uv[3 * f + 1]],
                    *c = &m->uv[2 * m->tri_uv[3 * f + 2]];
        double area = ((double)b[0] - a[0]) * ((double)c[1] - a[1]) -
                      ((double)b[1] - a[1]) * ((double)c[0] - a[0]);
        if (expect_ccw ? !(area > 0) : !(area < 0)) flipped++;
    }
    CR_CHECK(flipped == 0);
}

/* Shared checks for closed shapes; `convex` adds a per-face outward test. */
static void check_closed(const cr_mesh *m, double volume, double rel_tol, int euler, int convex) {
    cr_error err = {0};
    CR_CHECK_OK(cr_mesh_validate(m, "primitive", &err), &err);
    CR_CHECK(is_watertight_oriented(m));
    CR_CHECK(m->nv - count_edges(m) + m->nf == euler);
    double v = mesh_volume(m);
    CR_CHECK(v > 0);
    CR_CHECK_NEAR(v / volume, 1.0, rel_tol);
    if (convex) {
        int32_t inward = 0;
        for (int32_t f = 0; f < m->nf; f++) {
            const float *a = &m->pos[3 * m->tri[3 * f]], *b = &m->pos[3 * m->tri[3 * f + 1]],
                        *c = &m->pos[3 * m->tri[3 * f + 2]];
            double e1[3], e2[3], n[3], g[3];
            for (int d = 0; d < 3; d++)
                e1[d] = b[d] - a[d], e2[d] = c[d] - a[d];
            n[0] = e1[1] * e2[2] - e1[2] * e2[1];
            n[1] = e1[2] * e2[0] - e1[0] * e2[2];
            n[2] = e1[0] * e2[1] - e1[1] * e2[0];
            for (int d = 0; d < 3; d++)
                g[d] = (a[d] + b[d] + c[d]) / 3.0;
            if (!(n[0] * g[0] + n[1] * g[1] + n[2] * g[2] > 0)) inward++;
        }
        CR_CHECK(inward == 0);
    }
}

CR_TEST(primitives, plane_counts_normals_uvs) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(5, 3, 2.0f, 1.0f, &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 15 && m->nf == 16 && m->nuv == 15);
    CR_CHECK_OK(cr_mesh_validate(m, "plane", &err), &err);
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    CR_CHECK_NEAR(lo[0], -1.0, 1e-6);
    CR_CHECK_NEAR(hi[0], 1.0, 1e-6);
    CR_CHECK_NEAR(lo[2], -0.5, 1e-6);
    CR_CHECK_NEAR(hi[2], 0.5, 1e-6);
    CR_CHECK(lo[1] == 0.0f && hi[1] == 0.0f);
    double area = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const float *a = &m->pos[3 * m->tri[3 * f]], *b = &m->pos[3 * m->tri[3 * f + 1]],
                    *c = &m->pos[3 * m->tri[3 * f + 2]];
        /* y component of (b - a) x (c - a) = twice the area projected, signed by +Y. */
        double ny = (double)(b[2] - a[2]) * (c[0] - a[0]) - (double)(b[0] - a[0]) * (c[2] - a[2]);
        CR_CHECK(ny > 0);
        area += 0.5 * ny;
    }
    CR_CHECK_NEAR(area, 2.0, 1e-6);
    /* u follows x and v follows z, spanning [0,1]. */
    for (int32_t v = 0; v < m->nv; v++) {
        CR_CHECK_NEAR(m->uv[2 * v], m->pos[3 * v] / 2.0 + 0.5, 1e-6);
        CR_CHECK_NEAR(m->uv[2 * v + 1], m->pos[3 * v + 2] / 1.0 + 0.5, 1e-6);
    }
    check_uvs(m, 0); /* u along x, v along z under +Y is a mirrored frame */
    cr_mesh_destroy(m);
}

/* Relative volume deficit allowed for a curved shape with n segments round its
 * tightest circle: 1.5 times the leading term 2 (2 pi/n)^2 / 6 of two
 * independent polygonal approximations. */
static double curved_tol(int32_t n) {
    double h = 2 * PI / n;
    return 1.5 * 2 * h * h / 6;
}

CR_TEST(primitives, sphere_uv_closed_volume_converges) {
    cr_error err = {0};
    double prev = 1;
    for (int32_t n = 16; n <= 64; n *= 2) {
        cr_mesh *m = NULL;
        CR_CHECK_OK(cr_prim_sphere_uv(1.5f, n, n / 2, &m, &err), &err);
        CR_REQUIRE(m);
        CR_CHECK(m->nv == 2 + (n / 2 - 1) * n && m->nf == 2 * n * (n / 2 - 1));
        double exact = 4.0 / 3.0 * PI * 1.5 * 1.5 * 1.5;
        check_closed(m, exact, curved_tol(n), 2, 1);
        check_uvs(m, 1);
        double e = fabs(mesh_volume(m) / exact - 1);
        CR_CHECK(e < prev / 3); /* second order: the error falls ~4x per doubling */
        prev = e;
        for (int32_t v = 0; v < m->nv; v++) {
            const float *p = &m->pos[3 * v];
            CR_CHECK_NEAR(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 1.5, 1e-5);
        }
        cr_mesh_destroy(m);
    }
}

CR_TEST(primitives, icosphere_counts_closed_uvs) {
    cr_error err = {0};
    for (int32_t s = 0; s <= 4; s++) {
        cr_mesh *m = NULL;
        CR_CHECK_OK(cr_prim_icosphere(2.0f, s, &m, &err), &err);
        CR_REQUIRE(m);
        int32_t p4 = 1 << (2 * s);
        CR_CHECK(m->nv == 10 * p4 + 2 && m->nf == 20 * p4);
        double exact = 4.0 / 3.0 * PI * 8.0;
        /* Icosahedron edge subtends ~63.4 deg; each subdivision halves it. */
        int32_t n_equiv = (int32_t)(360.0 / 63.4 * (1 << s));
        check_closed(m, exact, curved_tol(n_equiv), 2, 1);
        check_uvs(m, 1);
        for (int32_t v = 0; v < m->nv; v++) {
            const float *p = &m->pos[3 * v];
            CR_CHECK_NEAR(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 2.0, 1e-5);
        }
        /* UV v is the latitude: v = 1/2 + asin(y / r) / pi at every corner. */
        for (int32_t f = 0; f < m->nf; f++)
            for (int k = 0; k < 3; k++) {
                float y = m->pos[3 * m->tri[3 * f + k] + 1];
                float v = m->uv[2 * m->tri_uv[3 * f + k] + 1];
                CR_CHECK_NEAR(v, 0.5 + asin(fmax(-1.0, fmin(1.0, y / 2.0))) / PI, 1e-5);
            }
        cr_mesh_destroy(m);
    }
}

CR_TEST(primitives, torus_closed_genus_one) {
    cr_error err = {0};
    double prev = 1;
    for (int32_t n = 16; n <= 64; n *= 2) {
        cr_mesh *m = NULL;
        CR_CHECK_OK(cr_prim_torus(1.0f, 0.3f, 2 * n, n, &m, &err), &err);
        CR_REQUIRE(m);
        CR_CHECK(m->nv == 2 * n * n && m->nf == 4 * n * n);
        double exact = 2 * PI * PI * 1.0 * 0.3 * 0.3;
        check_closed(m, exact, curved_tol(n), 0, 0);
        check_uvs(m, 1);
        double e = fabs(mesh_volume(m) / exact - 1);
        CR_CHECK(e < prev / 3);
        prev = e;
        cr_mesh_destroy(m);
    }
}

CR_TEST(primitives, box_exact_volume_and_welding) {
    cr_error err = {0};
    for (int32_t n = 1; n <= 5; n += 2) {
        cr_mesh *m = NULL;
        CR_CHECK_OK(cr_prim_box(1.0f, 2.0f, 0.5f, n, &m, &err), &err);
        CR_REQUIRE(m);
        CR_CHECK(m->nv == 6 * n * n + 2 && m->nf == 12 * n * n);
        check_closed(m, 1.0, 1e-6, 2, 1);
        check_uvs(m, 1);
        float lo[3], hi[3];
        cr_mesh_bounds(m, lo, hi);
        CR_CHECK_NEAR(hi[1] - lo[1], 2.0, 1e-6);
        CR_CHECK_NEAR(hi[1] + lo[1], 0.0, 1e-6);
        cr_mesh_destroy(m);
    }
}

CR_TEST(primitives, prism_exact_volume_ridge_up) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_prism(0.5f, 2.0f, &m, &err), &err);
    CR_REQUIRE(m);
    check_closed(m, sqrt(3.0) / 4 * 0.25 * 2.0, 1e-6, 2, 1);
    check_uvs(m, 1);
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    CR_CHECK_NEAR(hi[0] - lo[0], 2.0, 1e-6);             /* axis along X */
    CR_CHECK_NEAR(hi[2] - lo[2], 0.5, 1e-6);             /* base edge across Z */
    CR_CHECK_NEAR(hi[1], sqrt(3.0) / 6 * 0.5 * 2, 1e-6); /* ridge at 2h/3 */
    int32_t ridge = 0; /* two vertices at the top, on the z = 0 line */
    for (int32_t v = 0; v < m->nv; v++)
        if (fabsf(m->pos[3 * v + 1] - hi[1]) < 1e-6f && m->pos[3 * v + 2] == 0.0f) ridge++;
    CR_CHECK(ridge == 2);
    cr_mesh_destroy(m);
}

CR_TEST(primitives, capsule_and_cylinder_volumes) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    int32_t n = 48;
    CR_CHECK_OK(cr_prim_capsule(0.4f, 1.0f, n, n / 4, &m, &err), &err);
    CR_REQUIRE(m);
    check_closed(m, PI * 0.16 * 1.0 + 4.0 / 3 * PI * 0.064, curved_tol(n), 2, 1);
    check_uvs(m, 1);
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    CR_CHECK_NEAR(hi[1], 0.9, 1e-6);
    CR_CHECK_NEAR(lo[1], -0.9, 1e-6);
    cr_mesh_destroy(m);

    CR_CHECK_OK(cr_prim_capsule(0.4f, 0.0f, n, n / 4, &m, &err), &err); /* a sphere */
    CR_REQUIRE(m);
    check_closed(m, 4.0 / 3 * PI * 0.064, curved_tol(n), 2, 1);
    cr_mesh_destroy(m);

    /* A capped n-gon prism: exactly height * n/2 r^2 sin(2 pi / n). */
    for (int32_t rings = 1; rings <= 3; rings++) {
        CR_CHECK_OK(cr_prim_cylinder(0.5f, 2.0f, 7, rings, 1, &m, &err), &err);
        CR_REQUIRE(m);
        check_closed(m, 2.0 * 3.5 * 0.25 * sin(2 * PI / 7), 1e-6, 2, 1);
        check_uvs(m, 1);
        cr_mesh_destroy(m);
    }

    /* Open tube: two boundary loops of `segments` edges each, no caps. */
    CR_CHECK_OK(cr_prim_cylinder(0.5f, 2.0f, 12, 3, 0, &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 12 * 4 && m->nf == 2 * 12 * 3);
    CR_CHECK(!is_watertight_oriented(m));
    check_uvs(m, 1);
    cr_mesh_destroy(m);
}

CR_TEST(primitives, rejects_bad_parameters) {
    cr_error err = {0};
    cr_mesh *m = (cr_mesh *)&err; /* must be reset to NULL on failure */
    CR_CHECK(cr_prim_plane(1, 4, 1, 1, &m, &err) == CR_ERR_INVALID && m == NULL);
    CR_CHECK(strstr(err.msg, "nx") != NULL);
    CR_CHECK(cr_prim_sphere_uv(NAN, 8, 4, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "radius") != NULL);
    CR_CHECK(cr_prim_sphere_uv(1, 2, 4, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "segments") != NULL);
    CR_CHECK(cr_prim_torus(1, 1.5f, 8, 8, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "minor_radius") != NULL);
    CR_CHECK(cr_prim_box(1, -1, 1, 1, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "size_y") != NULL);
    CR_CHECK(cr_prim_box(1, 1, 1, 100000, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "int32") != NULL);
    CR_CHECK(cr_prim_sphere_uv(1, 1 << 30, 1 << 20, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_prim_icosphere(1, 14, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_prim_capsule(1, INFINITY, 8, 2, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "length") != NULL);
    CR_CHECK(cr_prim_capsule(1e-30f, 1e30f, 8, 2, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_prim_cylinder(1, 1, 8, 0, 1, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "rings") != NULL);
    CR_CHECK(cr_prim_prism(0, 1, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(m == NULL);
}
