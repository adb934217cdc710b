/* test_diffgeo.c: dihedral angles against folded strips (closed form) and
 * their gradient against central differences; the cotan Laplacian against
 * its definition (symmetry, zero row sums, linear precision on flat meshes,
 * brute-force weights); mean curvature on spheres and cylinders; vertex areas;
 * triangle minimum angles on equilateral and right-angled meshes. */
#include "crease/diffgeo.h"
#include "crease/primitives.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/* The hinge of the folded strip: edge x0-x1 along +x, face A (x0, x1, x2)
 * with normal +Y and x2 at z < 0; x3 starts flat at z > 0 and is turned by
 * phi about the edge towards +Y. */
static void folded_hinge(double phi, float x[4][3]) {
    const float x0[3] = {0, 0, 0}, x1[3] = {1, 0, 0}, x2[3] = {0.3f, 0, -0.8f};
    memcpy(x[0], x0, sizeof x0);
    memcpy(x[1], x1, sizeof x1);
    memcpy(x[2], x2, sizeof x2);
    x[3][0] = 0.6f, x[3][1] = (float)(0.7 * sin(phi)), x[3][2] = (float)(0.7 * cos(phi));
}

/* A rigid motion: rotation from a unit quaternion (4 normals) plus a shift. */
static void random_rigid(cr_rng *r, double rot[9], double shift[3]) {
    double q[4], n = 0;
    for (int i = 0; i < 4; i++)
        q[i] = cr_rng_normal(r), n += q[i] * q[i];
    n = sqrt(n);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                   2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                   2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    memcpy(rot, R, sizeof R);
    for (int i = 0; i < 3; i++)
        shift[i] = 2.0 * cr_rng_uniform(r) - 1.0;
}

static void apply_rigid(const double rot[9], const double shift[3], const float in[3],
                        float out[3]) {
    for (int i = 0; i < 3; i++)
        out[i] = (float)(rot[3 * i] * in[0] + rot[3 * i + 1] * in[1] + rot[3 * i + 2] * in[2] +
                         shift[i]);
}

CR_TEST(diffgeo, dihedral_matches_folded_strip) {
    const double phis[] = {0.0,  0.1, -0.1, 1.0,       -1.0,        2.0,
                           -2.0, 3.1, -3.1, PI - 1e-4, -(PI - 1e-4)};
    cr_rng r = cr_rng_make(11, 0);
    for (size_t i = 0; i < sizeof phis / sizeof phis[0]; i++) {
        float x[4][3];
        folded_hinge(phis[i], x);
        CR_CHECK_NEAR(cr_dihedral_angle(x[0], x[1], x[2], x[3]), phis[i], 1e-5);
        /* The same hinge seen from face B: the fold is symmetric. */
        CR_CHECK_NEAR(cr_dihedral_angle(x[1], x[0], x[3], x[2]), phis[i], 1e-5);
        /* Invariant under rigid motions (translations up to 1 m: float rounding). */
        double rot[9], shift[3];
        random_rigid(&r, rot, shift);
        float y[4][3];
        for (int k = 0; k < 4; k++)
            apply_rigid(rot, shift, x[k], y[k]);
        CR_CHECK_NEAR(cr_dihedral_angle(y[0], y[1], y[2], y[3]), phis[i], 2e-5);
    }
    /* Degenerate face: 0 by definition. */
    float x[4][3];
    folded_hinge(1.0, x);
    memcpy(x[2], x[0], sizeof x[0]);
    CR_CHECK(cr_dihedral_angle(x[0], x[1], x[2], x[3]) == 0.0f);
}

CR_TEST(diffgeo, hinge_angles_of_folded_grid) {
    /* A 3x3 plane (x in [-1, 1]) folded along x = 0 by turning its x > 0
     * column about the z axis towards +Y. The two hinges on x = 0 carry phi,
     * every other hinge lies within one flat half and carries 0. */
    const double phis[] = {0.5, -1.0, 2.5};
    cr_error err = {0};
    for (int c = 0; c < 3; c++) {
        cr_mesh *m = NULL;
        CR_CHECK_OK(cr_prim_plane(3, 3, 2.0f, 2.0f, &m, &err), &err);
        CR_REQUIRE(m);
        for (int32_t v = 0; v < m->nv; v++) {
            float *p = &m->pos[3 * v];
            if (p[0] > 0.5f) {
                double xx = p[0];
                p[0] = (float)(xx * cos(phis[c]));
                p[1] = (float)(xx * sin(phis[c]));
            }
        }
        cr_topology *t = NULL;
        CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
        CR_REQUIRE(t);
        float theta[32];
        CR_REQUIRE(t->nh <= 32);
        cr_mesh_hinge_angles(m, t, theta);
        int on_fold = 0;
        for (int32_t h = 0; h < t->nh; h++) {
            const int32_t *x = &t->hinge[4 * h];
            int fold = fabsf(m->pos[3 * x[0]]) < 1e-6f && fabsf(m->pos[3 * x[1]]) < 1e-6f;
            on_fold += fold;
            CR_CHECK_NEAR(theta[h], fold ? phis[c] : 0.0, 1e-5);
        }
        CR_CHECK(on_fold == 2);
        cr_topology_destroy(t);
        cr_mesh_destroy(m);
    }
}

CR_TEST(diffgeo, dihedral_gradient_central_differences) {
    /* Random hinges, |theta| < 3 so that +-h stays off the branch cut at pi.
     * Step 1e-3 m; tolerance 2e-3 absolute + 1e-3 relative, dominated by
     * float rounding of the perturbed coordinates (~6e-8 / 2e-3). */
    const float step = 1e-3f;
    cr_rng r = cr_rng_make(5, 0);
    int tested = 0;
    double worst = 0.0;
    for (int trial = 0; trial < 200 && tested < 100; trial++) {
        float x[12];
        double phi = (2.0 * cr_rng_uniform(&r) - 1.0) * 2.9;
        float hx[4][3];
        folded_hinge(phi, hx);
        /* Random rigid motion plus a jitter of every vertex. */
        double rot[9], shift[3];
        random_rigid(&r, rot, shift);
        for (int k = 0; k < 4; k++) {
            float j[3];
            for (int d = 0; d < 3; d++)
                j[d] = hx[k][d] + 0.2f * (float)(cr_rng_uniform(&r) - 0.5);
            apply_rigid(rot, shift, j, &x[3 * k]);
        }
        float g[12];
        float theta = cr_dihedral_angle_grad(&x[0], &x[3], &x[6], &x[9], g);
        CR_CHECK_NEAR(theta, cr_dihedral_angle(&x[0], &x[3], &x[6], &x[9]), 1e-7);
        if (fabsf(theta) > 3.0f) continue;
        tested++;
        double sum[3] = {0, 0, 0};
        for (int i = 0; i < 12; i++) {
            float save = x[i];
            x[i] = save + step;
            double fp = cr_dihedral_angle(&x[0], &x[3], &x[6], &x[9]);
            x[i] = save - step;
            double fm = cr_dihedral_angle(&x[0], &x[3], &x[6], &x[9]);
            x[i] = save;
            double fd = (fp - fm) / (2.0 * step);
            double diff = fabs(fd - g[i]);
            if (diff > worst) worst = diff;
            CR_CHECK_NEAR(g[i], fd, 2e-3 + 1e-3 * fabs(fd));
            sum[i % 3] += g[i];
        }
        /* Translation invariance: the four vertex gradients cancel. */
        for (int d = 0; d < 3; d++)
            CR_CHECK_NEAR(sum[d], 0.0, 1e-5);
    }
    CR_CHECK(tested >= 50);
    CR_CHECK(worst < 2e-3);
}

/* Brute-force cotangent weight of edge (i, j): half the sum over the faces
 * holding it of cot(angle opposite), angles from acos in double. */
static double brute_weight(const cr_mesh *m, int32_t i, int32_t j) {
    double w = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        int hi = -1, hj = -1;
        for (int k = 0; k < 3; k++)
            hi = t[k] == i ? k : hi, hj = t[k] == j ? k : hj;
        if (hi < 0 || hj < 0) continue;
        int o = 3 - hi - hj;
        const float *po = &m->pos[3 * t[o]], *pi = &m->pos[3 * i], *pj = &m->pos[3 * j];
        double a[3], b[3], la = 0, lb = 0, dot = 0;
        for (int d = 0; d < 3; d++) {
            a[d] = (double)pi[d] - po[d], b[d] = (double)pj[d] - po[d];
            la += a[d] * a[d], lb += b[d] * b[d], dot += a[d] * b[d];
        }
        w += 0.5 / tan(acos(dot / sqrt(la * lb)));
    }
    return w;
}

CR_TEST(diffgeo, cotan_laplacian_definition) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    /* A torus with jittered vertices: curved, irregular, closed. */
    CR_CHECK_OK(cr_prim_torus(1.0f, 0.4f, 12, 8, &m, &err), &err);
    CR_REQUIRE(m);
    cr_rng r = cr_rng_make(3, 0);
    for (int32_t i = 0; i < 3 * m->nv; i++)
        m->pos[i] += 0.03f * (float)(cr_rng_uniform(&r) - 0.5);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    cr_csr L = {0};
    CR_CHECK_OK(cr_cotan_laplacian(m, t, &L, &err), &err);
    CR_REQUIRE(L.val);
    CR_CHECK(L.n == m->nv && L.nnz == m->nv + 2 * (int64_t)t->ne);
    for (int32_t i = 0; i < L.n; i++) {
        double rowsum = 0.0, diag = 0.0;
        for (int64_t p = L.row_ptr[i]; p < L.row_ptr[i + 1]; p++) {
            rowsum += L.val[p];
            int32_t j = L.col[p];
            if (p > L.row_ptr[i]) CR_CHECK(L.col[p - 1] < j);
            if (j == i) {
                diag = L.val[p];
                continue;
            }
            CR_CHECK_NEAR(-L.val[p], brute_weight(m, i, j), 1e-9 + 1e-9 * fabs(L.val[p]));
            /* Symmetry: the (j, i) entry. */
            int64_t q = L.row_ptr[j];
            while (q < L.row_ptr[j + 1] && L.col[q] != i)
                q++;
            CR_REQUIRE(q < L.row_ptr[j + 1]);
            CR_CHECK(L.val[q] == L.val[p]);
        }
        CR_CHECK_NEAR(rowsum, 0.0, 1e-12 * (1.0 + fabs(diag)));
        CR_CHECK(diag > 0.0);
    }
    cr_csr_free(&L);
    CR_CHECK(L.val == NULL && L.n == 0);
    cr_csr_free(&L); /* a zeroed struct is a no-op */
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(diffgeo, cotan_laplacian_is_zero_on_flat_interior) {
    /* Linear precision: on a flat mesh (even with vertices moved within the
     * plane) L x vanishes at interior vertices. */
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(9, 7, 2.0f, 1.5f, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    cr_rng r = cr_rng_make(4, 0);
    for (int jitter = 0; jitter < 2; jitter++) {
        if (jitter)
            for (int32_t v = 0; v < m->nv; v++)
                if (!t->vertex_boundary[v]) {
                    m->pos[3 * v] += 0.06f * (float)(cr_rng_uniform(&r) - 0.5);
                    m->pos[3 * v + 2] += 0.06f * (float)(cr_rng_uniform(&r) - 0.5);
                }
        cr_csr L = {0};
        CR_CHECK_OK(cr_cotan_laplacian(m, t, &L, &err), &err);
        double *x = malloc((size_t)m->nv * 3 * sizeof(double));
        double *y = malloc((size_t)m->nv * 3 * sizeof(double));
        CR_REQUIRE(x && y && L.val);
        for (int32_t i = 0; i < 3 * m->nv; i++)
            x[i] = m->pos[i];
        cr_csr_mul(&L, x, 3, y);
        int interior = 0;
        for (int32_t v = 0; v < m->nv; v++) {
            if (t->vertex_boundary[v]) continue;
            interior++;
            for (int d = 0; d < 3; d++)
                CR_CHECK_NEAR(y[3 * v + d], 0.0, 1e-6);
        }
        CR_CHECK(interior == 7 * 5);
        float H[63];
        CR_CHECK_OK(cr_mesh_mean_curvature(m, t, H, &err), &err);
        for (int32_t v = 0; v < m->nv; v++)
            CR_CHECK_NEAR(H[v], 0.0, 1e-4);
        free(x), free(y);
        cr_csr_free(&L);
    }
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(diffgeo, mean_curvature_sphere_and_cylinder) {
    cr_error err = {0};
    const float R = 2.0f;
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(R, 4, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    float *H = malloc((size_t)m->nv * sizeof(float));
    CR_REQUIRE(H);
    CR_CHECK_OK(cr_mesh_mean_curvature(m, t, H, &err), &err);
    double worst = 0.0;
    for (int32_t v = 0; v < m->nv; v++)
        worst = fmax(worst, fabs(H[v] * R - 1.0));
    CR_CHECK(worst < 0.03);
    /* Both area kinds sum to the surface area, close to 4 pi R^2. */
    float *A = malloc((size_t)m->nv * sizeof(float));
    float *fa = malloc((size_t)m->nf * sizeof(float));
    CR_REQUIRE(A && fa);
    cr_mesh_face_normals(m, NULL, fa);
    double total = 0.0;
    for (int32_t f = 0; f < m->nf; f++)
        total += fa[f];
    CR_CHECK_NEAR(total, 4 * PI * R * R, 0.01 * 4 * PI * R * R);
    for (int kind = 0; kind < 2; kind++) {
        cr_mesh_vertex_areas(m, kind ? CR_AREA_MIXED_VORONOI : CR_AREA_BARYCENTRIC, A);
        double s = 0.0;
        for (int32_t v = 0; v < m->nv; v++)
            s += A[v];
        CR_CHECK_NEAR(s, total, 1e-5 * total);
    }
    free(A), free(fa), free(H);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);

    /* Open cylinder of radius 0.5: H = 1/(2r) = 1 inside, 0 on both rims. */
    CR_CHECK_OK(cr_prim_cylinder(0.5f, 1.0f, 96, 12, 0, &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    H = malloc((size_t)m->nv * sizeof(float));
    CR_REQUIRE(H);
    CR_CHECK_OK(cr_mesh_mean_curvature(m, t, H, &err), &err);
    worst = 0.0;
    for (int32_t v = 0; v < m->nv; v++) {
        if (t->vertex_boundary[v])
            CR_CHECK(H[v] == 0.0f);
        else
            worst = fmax(worst, fabs(H[v] - 1.0));
    }
    CR_CHECK(worst < 0.03);
    free(H);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(diffgeo, vertex_areas_closed_form) {
    /* Right isosceles triangle (legs 1, right angle at 0): Voronoi shares
     * 1/4, 1/8, 1/8. Obtuse triangle (120 degrees at 0, legs 1): area/2 at
     * the obtuse corner, area/4 at the others. Barycentric: area/3 each. */
    cr_mesh *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mesh_create(6, 2, 0, &m, &err), &err);
    CR_REQUIRE(m);
    const float p[18] = {0,
                         0,
                         0,
                         1,
                         0,
                         0,
                         0,
                         1,
                         0,
                         5,
                         0,
                         0,
                         6,
                         0,
                         0,
                         (float)(5 + cos(2 * PI / 3)),
                         (float)sin(2 * PI / 3),
                         0};
    const int32_t tri[6] = {0, 1, 2, 3, 4, 5};
    memcpy(m->pos, p, sizeof p);
    memcpy(m->tri, tri, sizeof tri);
    float A[6];
    cr_mesh_vertex_areas(m, CR_AREA_MIXED_VORONOI, A);
    double obtuse = 0.5 * sin(2 * PI / 3);
    CR_CHECK_NEAR(A[0], 0.25, 1e-7);
    CR_CHECK_NEAR(A[1], 0.125, 1e-7);
    CR_CHECK_NEAR(A[2], 0.125, 1e-7);
    CR_CHECK_NEAR(A[3], obtuse / 2, 1e-6);
    CR_CHECK_NEAR(A[4], obtuse / 4, 1e-6);
    CR_CHECK_NEAR(A[5], obtuse / 4, 1e-6);
    cr_mesh_vertex_areas(m, CR_AREA_BARYCENTRIC, A);
    CR_CHECK_NEAR(A[0], 0.5 / 3, 1e-7);
    CR_CHECK_NEAR(A[4], obtuse / 3, 1e-6);
    cr_mesh_destroy(m);
}

CR_TEST(diffgeo, min_angles_and_quality_stats) {
    /* Equilateral lattice: rows of 5 vertices, odd rows shifted by half a side. */
    const int32_t nx = 5, ny = 4;
    cr_mesh *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mesh_create(nx * ny, 2 * (nx - 1) * (ny - 1), 0, &m, &err), &err);
    CR_REQUIRE(m);
    for (int32_t j = 0; j < ny; j++)
        for (int32_t i = 0; i < nx; i++) {
            float *p = &m->pos[3 * (j * nx + i)];
            p[0] = (float)(i + 0.5 * (j % 2));
            p[2] = (float)(j * sqrt(3.0) / 2.0);
        }
    int32_t f = 0;
    for (int32_t j = 0; j + 1 < ny; j++)
        for (int32_t i = 0; i + 1 < nx; i++) {
            int32_t a = j * nx + i, b = a + 1, c = a + nx, d = c + 1;
            /* Even rows lean right, odd rows left, so both halves of a
             * rhombus are equilateral. */
            int32_t t[6] = {a, c, b, b, c, d};
            if (j % 2) t[0] = a, t[1] = c, t[2] = d, t[3] = a, t[4] = d, t[5] = b;
            memcpy(&m->tri[3 * f], t, sizeof t);
            f += 2;
        }
    float deg[24];
    cr_mesh_face_min_angles(m, deg);
    for (int32_t k = 0; k < m->nf; k++)
        CR_CHECK_NEAR(deg[k], 60.0, 1e-4);
    cr_quality_stats q;
    CR_CHECK_OK(cr_mesh_quality_stats(m, &q, &err), &err);
    CR_CHECK(q.nf == m->nf && q.frac_above_20 == 1.0f);
    CR_CHECK_NEAR(q.min_deg, 60.0, 1e-4);
    CR_CHECK_NEAR(q.mean_deg, 60.0, 1e-4);
    CR_CHECK_NEAR(q.p01_deg, 60.0, 1e-4);
    /* Move vertex 0 (used by face 0 only) onto the line through face 0's
     * other two corners: a zero-area sliver with a 0-degree angle. */
    for (int d = 0; d < 3; d++)
        m->pos[d] = 2.0f * m->pos[3 * nx + d] - m->pos[3 + d];
    cr_mesh_face_min_angles(m, deg);
    CR_CHECK_NEAR(deg[0], 0.0, 1e-4);
    CR_CHECK_OK(cr_mesh_quality_stats(m, &q, &err), &err);
    CR_CHECK_NEAR(q.min_deg, 0.0, 1e-4);
    CR_CHECK_NEAR(q.p01_deg, 0.0, 1e-4); /* nearest rank of 24 faces: the smallest */
    CR_CHECK_NEAR(q.frac_above_20, (m->nf - 1.0) / m->nf, 1e-6);
    cr_mesh_destroy(m);

    /* The plane primitive's right isosceles halves: 45 degrees. */
    CR_CHECK_OK(cr_prim_plane(4, 4, 3.0f, 3.0f, &m, &err), &err);
    CR_REQUIRE(m);
    cr_mesh_face_min_angles(m, deg);
    for (int32_t k = 0; k < m->nf; k++)
        CR_CHECK_NEAR(deg[k], 45.0, 1e-4);
    cr_mesh_destroy(m);
}
