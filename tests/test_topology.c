/* test_topology.c: edges, hinges, adjacency and boundary loops against closed
 * forms (grid counts, Euler characteristic) and brute force; defect detection
 * on bow-ties, fins, flipped faces, degenerate faces and isolated vertices. */
#include "crease/primitives.h"
#include "crease/topology.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static cr_mesh *mesh_from(int32_t nv, int32_t nf, const int32_t *tri) {
    cr_mesh *m = NULL;
    cr_error err = {0};
    if (cr_mesh_create(nv, nf, 0, &m, &err) != CR_OK) return NULL;
    memcpy(m->tri, tri, (size_t)nf * 3 * sizeof(int32_t));
    for (int32_t v = 0; v < nv; v++)
        m->pos[3 * v] = (float)v; /* positions are not used */
    return m;
}

/* Does face f run the directed edge a -> b? */
static int face_runs(const cr_mesh *m, int32_t f, int32_t a, int32_t b) {
    for (int k = 0; k < 3; k++)
        if (m->tri[3 * f + k] == a && m->tri[3 * f + (k + 1) % 3] == b) return 1;
    return 0;
}

static int face_has(const cr_mesh *m, int32_t f, int32_t v) {
    return m->tri[3 * f] == v || m->tri[3 * f + 1] == v || m->tri[3 * f + 2] == v;
}

/* Every table of a manifold mesh's topology checked against its definition
 * and against brute-force counts over all faces (small meshes only). */
static void check_consistency(const cr_mesh *m, const cr_topology *t) {
    /* face_edge joins corners k, k+1; edge_face lists the faces holding it. */
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t e = t->face_edge[3 * f + k];
            CR_REQUIRE(e >= 0 && e < t->ne);
            int32_t a = m->tri[3 * f + k], b = m->tri[3 * f + (k + 1) % 3];
            CR_CHECK(t->edge[2 * e] == (a < b ? a : b) && t->edge[2 * e + 1] == (a < b ? b : a));
            CR_CHECK(t->edge_face[2 * e] == f || t->edge_face[2 * e + 1] == f);
            int32_t g = t->face_face[3 * f + k];
            int32_t other =
                t->edge_face[2 * e] == f ? t->edge_face[2 * e + 1] : t->edge_face[2 * e];
            CR_CHECK(g == other);
            if (g >= 0) CR_CHECK(face_has(m, g, a) && face_has(m, g, b));
        }
    /* Each edge: brute-force count of faces holding both ends. */
    int32_t nb = 0;
    for (int32_t e = 0; e < t->ne; e++) {
        int32_t a = t->edge[2 * e], b = t->edge[2 * e + 1], count = 0;
        CR_CHECK(a < b);
        if (e > 0)
            CR_CHECK(t->edge[2 * e - 2] < a || (t->edge[2 * e - 2] == a && t->edge[2 * e - 1] < b));
        for (int32_t f = 0; f < m->nf; f++)
            count += face_has(m, f, a) && face_has(m, f, b);
        CR_CHECK(count == 1 || count == 2);
        CR_CHECK((t->edge_face[2 * e + 1] < 0) == (count == 1));
        nb += count == 1;
    }
    CR_CHECK(nb == t->n_boundary_edges);
    CR_CHECK(t->nh == t->ne - nb);
    /* Hinges: face A runs x0 -> x1 and holds x2, face B runs x1 -> x0 and holds x3. */
    for (int32_t h = 0; h < t->nh; h++) {
        const int32_t *x = &t->hinge[4 * h];
        int32_t fa = t->hinge_face[2 * h], fb = t->hinge_face[2 * h + 1], e = t->hinge_edge[h];
        CR_CHECK(face_runs(m, fa, x[0], x[1]) && face_has(m, fa, x[2]));
        CR_CHECK(face_runs(m, fb, x[1], x[0]) && face_has(m, fb, x[3]));
        CR_CHECK(x[2] != x[0] && x[2] != x[1] && x[3] != x[0] && x[3] != x[1]);
        int32_t lo = x[0] < x[1] ? x[0] : x[1];
        CR_CHECK(t->edge[2 * e] == lo);
    }
    /* vv: ascending and equal to the brute-force neighbour set; vf likewise. */
    uint8_t *nbr = calloc((size_t)m->nv, 1);
    CR_REQUIRE(nbr);
    for (int32_t v = 0; v < m->nv; v++) {
        memset(nbr, 0, (size_t)m->nv);
        int32_t nfaces = 0;
        for (int32_t f = 0; f < m->nf; f++)
            if (face_has(m, f, v)) {
                nfaces++;
                for (int k = 0; k < 3; k++)
                    nbr[m->tri[3 * f + k]] = 1;
            }
        nbr[v] = 0;
        int32_t count = 0;
        for (int32_t u = 0; u < m->nv; u++)
            count += nbr[u];
        CR_CHECK(t->vv_off[v + 1] - t->vv_off[v] == count);
        CR_CHECK(t->vf_off[v + 1] - t->vf_off[v] == nfaces);
        for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++) {
            CR_CHECK(nbr[t->vv[q]]);
            if (q > t->vv_off[v]) CR_CHECK(t->vv[q - 1] < t->vv[q]);
        }
        for (int32_t q = t->vf_off[v]; q < t->vf_off[v + 1]; q++)
            CR_CHECK(face_has(m, t->vf[q], v));
    }
    free(nbr);
    /* Boundary loops: consecutive vertices joined by a boundary edge whose
     * face runs it in loop order (surface on the left). */
    int32_t total = 0;
    for (int32_t l = 0; l < t->nloop; l++) {
        int32_t n = t->loop_off[l + 1] - t->loop_off[l];
        const int32_t *lv = &t->loop_vert[t->loop_off[l]];
        total += n;
        for (int32_t i = 0; i < n; i++) {
            int32_t a = lv[i], b = lv[(i + 1) % n], runs = 0, count = 0;
            CR_CHECK(t->vertex_boundary[a]);
            for (int32_t f = 0; f < m->nf; f++) {
                count += face_has(m, f, a) && face_has(m, f, b);
                runs += face_runs(m, f, a, b);
            }
            CR_CHECK(count == 1 && runs == 1);
        }
    }
    CR_CHECK(total == nb);
}

CR_TEST(topology, plane_grid_counts) {
    cr_error err = {0};
    const int32_t nx = 6, nz = 4;
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_plane(nx, nz, 2.0f, 1.0f, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    /* Horizontal + vertical + one diagonal per cell. */
    int32_t e_expect = (nx - 1) * nz + nx * (nz - 1) + (nx - 1) * (nz - 1);
    int32_t nb_expect = 2 * ((nx - 1) + (nz - 1));
    CR_CHECK(t->ne == e_expect);
    CR_CHECK(t->n_boundary_edges == nb_expect);
    CR_CHECK(t->nh == e_expect - nb_expect);
    CR_CHECK(cr_topology_euler_characteristic(t) == 1);
    CR_CHECK(t->nloop == 1);
    CR_CHECK(t->loop_off[1] == 2 * (nx + nz) - 4);
    CR_CHECK(t->n_nonmanifold_edges == 0 && t->n_nonmanifold_vertices == 0);
    CR_CHECK(t->n_inconsistent_edges == 0 && t->n_isolated_vertices == 0);
    CR_CHECK(t->n_degenerate_faces == 0 && t->max_edge_faces == 2);
    CR_CHECK_OK(cr_topology_require_manifold(t, "plane", &err), &err);
    /* Boundary vertices are exactly the grid's rim. */
    for (int32_t v = 0; v < m->nv; v++) {
        int32_t i = v % nx, k = v / nx;
        int rim = i == 0 || i == nx - 1 || k == 0 || k == nz - 1;
        CR_CHECK(t->vertex_boundary[v] == rim);
    }
    /* The loop runs counter-clockwise seen from +Y (the normal side): positive
     * signed area in the (z, x) plane, since z x x = +y. */
    double area2 = 0.0;
    int32_t n = t->loop_off[1];
    for (int32_t i = 0; i < n; i++) {
        const float *p = &m->pos[3 * t->loop_vert[i]], *q = &m->pos[3 * t->loop_vert[(i + 1) % n]];
        area2 += (double)p[2] * q[0] - (double)q[2] * p[0];
    }
    CR_CHECK_NEAR(area2, 2.0 * 2.0 * 1.0, 1e-5);
    check_consistency(m, t);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(topology, closed_surfaces_euler) {
    cr_error err = {0};
    struct {
        const char *name;
        cr_mesh *m;
        int64_t chi;
        int32_t loops;
    } cases[5] = {{"uv sphere", NULL, 2, 0},
                  {"icosphere", NULL, 2, 0},
                  {"torus", NULL, 0, 0},
                  {"capped cylinder", NULL, 2, 0},
                  {"open cylinder", NULL, 0, 2}};
    CR_CHECK_OK(cr_prim_sphere_uv(1.0f, 12, 7, &cases[0].m, &err), &err);
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 2, &cases[1].m, &err), &err);
    CR_CHECK_OK(cr_prim_torus(1.0f, 0.3f, 10, 6, &cases[2].m, &err), &err);
    CR_CHECK_OK(cr_prim_cylinder(0.5f, 1.0f, 9, 3, 1, &cases[3].m, &err), &err);
    CR_CHECK_OK(cr_prim_cylinder(0.5f, 1.0f, 9, 3, 0, &cases[4].m, &err), &err);
    for (int c = 0; c < 5; c++) {
        cr_mesh *m = cases[c].m;
        CR_REQUIRE(m);
        cr_topology *t = NULL;
        CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
        CR_REQUIRE(t);
        if (cr_topology_euler_characteristic(t) != cases[c].chi || t->nloop != cases[c].loops)
            fprintf(stderr, "  %s: chi %lld, loops %d\n", cases[c].name,
                    (long long)cr_topology_euler_characteristic(t), t->nloop);
        CR_CHECK(cr_topology_euler_characteristic(t) == cases[c].chi);
        CR_CHECK(t->nloop == cases[c].loops);
        if (cases[c].loops == 0) {
            CR_CHECK(2 * t->ne == 3 * m->nf && t->nh == t->ne && t->n_boundary_edges == 0);
        } else {
            for (int32_t l = 0; l < t->nloop; l++)
                CR_CHECK(t->loop_off[l + 1] - t->loop_off[l] == 9);
        }
        CR_CHECK_OK(cr_topology_require_manifold(t, cases[c].name, &err), &err);
        check_consistency(m, t);
        cr_topology_destroy(t);
        cr_mesh_destroy(m);
    }
}

CR_TEST(topology, bow_tie_is_a_nonmanifold_vertex) {
    /* Two triangles sharing only vertex 0. */
    const int32_t tri[] = {0, 1, 2, 0, 3, 4};
    cr_mesh *m = mesh_from(5, 2, tri);
    CR_REQUIRE(m);
    cr_error err = {0};
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->n_nonmanifold_vertices == 1 && t->first_nonmanifold_vertex == 0);
    CR_CHECK(t->n_nonmanifold_edges == 0 && t->ne == 6 && t->nh == 0);
    cr_status st = cr_topology_require_manifold(t, "bowtie.obj", &err);
    CR_CHECK(st == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "bowtie.obj") && strstr(err.msg, "vertex 0"));
    CR_CHECK(strstr(err.msg, "1 such vertices") != NULL);
    /* Each triangle's rim is a loop of its own (the walk stops at vertex 0). */
    CR_CHECK(t->loop_off[t->nloop] == 6 || t->loop_off[t->nloop] == 7);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(topology, three_faces_on_one_edge) {
    const int32_t tri[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    cr_mesh *m = mesh_from(5, 3, tri);
    CR_REQUIRE(m);
    cr_error err = {0};
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->n_nonmanifold_edges == 1 && t->max_edge_faces == 3);
    CR_CHECK(t->edge[2 * t->first_nonmanifold_edge] == 0);
    CR_CHECK(t->edge[2 * t->first_nonmanifold_edge + 1] == 1);
    CR_CHECK(t->nh == 0);
    CR_CHECK(t->n_nonmanifold_vertices == 2); /* both ends of the fin edge */
    for (int k = 0; k < 9; k++) {
        int32_t e = t->face_edge[k];
        if (t->edge[2 * e] == 0 && t->edge[2 * e + 1] == 1) CR_CHECK(t->face_face[k] == -1);
    }
    cr_status st = cr_topology_require_manifold(t, "fin", &err);
    CR_CHECK(st == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "fin: non-manifold edge (0, 1)") != NULL);
    CR_CHECK(strstr(err.msg, "1 such edges") != NULL);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(topology, orientation_degenerate_isolated) {
    cr_error err = {0};
    cr_topology *t = NULL;
    /* Faces 0 and 1 both run 0 -> 1. */
    const int32_t flipped[] = {0, 1, 2, 0, 1, 3};
    cr_mesh *m = mesh_from(4, 2, flipped);
    CR_REQUIRE(m);
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->n_inconsistent_edges == 1 && t->nh == 1 && t->n_nonmanifold_vertices == 0);
    CR_CHECK(cr_topology_require_manifold(t, "flip", &err) == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "orientation is inconsistent") && strstr(err.msg, "(0, 1)"));
    cr_topology_destroy(t);
    cr_mesh_destroy(m);

    /* Face 1 repeats vertex 2; vertex 4 is used by nothing. */
    const int32_t degen[] = {0, 1, 2, 2, 2, 3, 1, 3, 2};
    m = mesh_from(5, 3, degen);
    CR_REQUIRE(m);
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->n_degenerate_faces == 1 && t->first_degenerate_face == 1);
    CR_CHECK(t->n_isolated_vertices == 1 && t->first_isolated_vertex == 4);
    CR_CHECK(t->face_edge[3] == -1 && t->face_face[3] == -1 && t->ne == 5);
    CR_CHECK(cr_topology_euler_characteristic(t) == 4 - 5 + 2);
    CR_CHECK(cr_topology_require_manifold(t, "degen", &err) == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "face 1") != NULL);
    cr_topology_destroy(t);

    /* An index out of range is an input error, not a crash. */
    m->tri[4] = 9;
    CR_CHECK(cr_topology_build(m, &t, &err) == CR_ERR_RANGE && t == NULL);
    CR_CHECK(strstr(err.msg, "face 1 uses vertex 9") != NULL);
    cr_mesh_destroy(m);
}

CR_TEST(topology, large_mesh_matches_counts) {
    /* A bigger mesh: counts only (brute force would be quadratic). */
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 5, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->ne == 30 * 1024 && t->nh == t->ne);
    CR_CHECK(cr_topology_euler_characteristic(t) == 2);
    CR_CHECK_OK(cr_topology_require_manifold(t, "icosphere", &err), &err);
    /* Valence 5 at the 12 original vertices, 6 elsewhere. */
    int32_t v5 = 0, v6 = 0;
    for (int32_t v = 0; v < m->nv; v++) {
        int32_t d = t->vv_off[v + 1] - t->vv_off[v];
        v5 += d == 5, v6 += d == 6;
        CR_CHECK(t->vf_off[v + 1] - t->vf_off[v] == d);
    }
    CR_CHECK(v5 == 12 && v6 == m->nv - 12);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

CR_TEST(topology, empty_mesh) {
    cr_mesh *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mesh_create(0, 0, 0, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK(t->ne == 0 && t->nh == 0 && t->nloop == 0 && t->vf_off[0] == 0);
    CR_CHECK(cr_topology_euler_characteristic(t) == 0);
    CR_CHECK_OK(cr_topology_require_manifold(t, "empty", &err), &err);
    cr_topology_destroy(t);
    cr_topology_destroy(NULL);
    cr_mesh_destroy(m);
}
