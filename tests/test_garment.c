/* test_garment.c: procedural garments on the mannequin: every type at three
 * resolutions against the quality targets (vertex count within 15%, 99% of
 * faces above 20 degrees, 5 mm clearance, manifold with the right openings,
 * outward normals, welded seams cut in UV, UV areas equal to 3-D areas,
 * weights summing to 1), low/high correspondences (exact on the low mesh
 * itself, close on the high one), layers that do not cross, skinning,
 * user garments with good and bad files, bad defs, determinism, other body
 * shapes, and 30 frames of the reference simulator with a t-shirt on the
 * static body. The body and one template per type are built once and
 * shared (reachable from statics, so leak checkers stay quiet). */
#include "body_fixture.h"
#include "crease/body.h"
#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/phys_sim.h"
#include "crease/topology.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* Mannequin grid: coarser than the default (110) to keep the tests quick. */
enum { BODY_RES = 90 };

static cr_body_model *shared_body(void) {
    return fixture_mannequin(BODY_RES);
}

static cr_garment_template *shared_template(cr_garment_type type) {
    static cr_garment_template *t[CR_GARMENT_TYPE_COUNT];
    if (!t[type] && shared_body()) {
        cr_error err = {0};
        cr_garment_def def = cr_garment_default_def(type);
        if (cr_garment_template_create(&def, shared_body(), &t[type], &err) != CR_OK)
            cr_test_fail_here(__FILE__, __LINE__, "%s template: %s", cr_garment_type_name(type),
                              err.msg);
    }
    return t[type];
}

static cr_garment *instance(cr_garment_type type, int32_t target) {
    cr_garment_template *t = shared_template(type);
    cr_garment *g = NULL;
    cr_error err = {0};
    if (t && cr_garment_template_instantiate(t, target, shared_body(), &g, &err) != CR_OK)
        cr_test_fail_here(__FILE__, __LINE__, "%s at %d: %s", cr_garment_type_name(type), target,
                          err.msg);
    return g;
}

/* ------------------------------------------------------------- quality -- */

/* Number of UV charts: faces joined across edges whose UV corners match. */
static int32_t count_uv_charts(const cr_mesh *m) {
    int32_t *parent = malloc((size_t)m->nuv * sizeof(int32_t)), n = 0;
    for (int32_t i = 0; i < m->nuv; i++)
        parent[i] = i;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 1; k < 3; k++) {
            int32_t a = m->tri_uv[3 * f], b = m->tri_uv[3 * f + k];
            while (parent[a] != a)
                a = parent[a];
            while (parent[b] != b)
                b = parent[b];
            if (a != b) parent[a] = b;
        }
    for (int32_t i = 0; i < m->nuv; i++)
        n += parent[i] == i;
    free(parent);
    return n;
}

/* Seams welded in 3-D, cut in UV, charts unfolded and inside [0,1]^2. */
static void check_uvs(const cr_garment *g) {
    const cr_mesh *m = g->mesh;
    CR_REQUIRE(cr_mesh_has_uv(m));
    /* No UV index serves two panels; each panel is one chart. */
    int32_t *owner = malloc((size_t)m->nuv * sizeof(int32_t));
    for (int32_t i = 0; i < m->nuv; i++)
        owner[i] = -1;
    int shared = 0, flipped = 0, outside = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        for (int k = 0; k < 3; k++) {
            int32_t u = m->tri_uv[3 * f + k];
            if (owner[u] >= 0 && owner[u] != g->panel[f]) shared++;
            owner[u] = g->panel[f];
            outside += !(m->uv[2 * u] >= 0.0f && m->uv[2 * u] <= 1.0f && m->uv[2 * u + 1] >= 0.0f &&
                         m->uv[2 * u + 1] <= 1.0f);
        }
        const float *a = &m->uv[2 * m->tri_uv[3 * f]], *b = &m->uv[2 * m->tri_uv[3 * f + 1]],
                    *c = &m->uv[2 * m->tri_uv[3 * f + 2]];
        flipped += (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) <= 0.0f;
    }
    CR_CHECK(shared == 0);
    CR_CHECK(flipped == 0);
    CR_CHECK(outside == 0);
    CR_CHECK(count_uv_charts(m) == g->npanels);
    /* Seam vertices (faces of two panels around them) exist: seams are welded. */
    int32_t *vpanel = malloc((size_t)m->nv * sizeof(int32_t)), seam = 0;
    for (int32_t v = 0; v < m->nv; v++)
        vpanel[v] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t v = m->tri[3 * f + k];
            if (vpanel[v] >= 0 && vpanel[v] != g->panel[f] && vpanel[v] < CR_GARMENT_MAX_PANELS)
                seam++, vpanel[v] = CR_GARMENT_MAX_PANELS;
            else if (vpanel[v] < 0)
                vpanel[v] = g->panel[f];
        }
    CR_CHECK(seam > 0);
    free(owner);
    free(vpanel);
}

CR_TEST(garment, types_three_resolutions) {
    /* Openings and panels per type. */
    static const int loops[] = {4, 4, 2, 4, 3, 4, 5}, panels[] = {6, 6, 2, 2, 4, 2, 4};
    static const int32_t res[3] = {2000, 3000, 5000};
    cr_error err = {0};
    for (int type = 0; type < CR_GARMENT_USER; type++)
        for (int r = 0; r < 3; r++) {
            cr_garment *g = instance((cr_garment_type)type, res[r]);
            if (!g) continue;
            cr_garment_quality q;
            CR_CHECK_OK(cr_garment_measure(g, shared_body(), &q, &err), &err);
            printf("    %-10s %5d: %5d vertices, %.4f above 20 deg (min %.1f), clearance %.1f mm, "
                   "UV area error %.2f%%\n",
                   cr_garment_type_name((cr_garment_type)type), res[r], q.vertices,
                   (double)q.share_min_angle_above_20deg, (double)q.min_angle_deg,
                   1000.0 * q.min_clearance_m, 100.0 * q.uv_area_error);
            CR_CHECK(abs(q.vertices - res[r]) <= 0.15 * res[r]);
            CR_CHECK(q.share_min_angle_above_20deg >= 0.99f);
            CR_CHECK(q.min_clearance_m >= 0.005f);
            CR_CHECK(q.manifold);
            CR_CHECK(q.boundary_loops == loops[type]);
            CR_CHECK(q.panels == panels[type]);
            CR_CHECK(q.share_outward >= 0.99f);
            CR_CHECK(q.max_weight_sum_error < 1e-5f);
            CR_CHECK(q.uv_area_error < 0.03f);
            for (int32_t i = 0; i < 4 * g->mesh->nv; i++)
                CR_CHECK(g->skin_joint[i] >= 0 && g->skin_joint[i] < CR_NJOINTS);
            check_uvs(g);
            cr_garment_destroy(g);
        }
}

/* ------------------------------------------------------ correspondence -- */

CR_TEST(garment, correspondence_low_high) {
    cr_garment *lo = instance(CR_GARMENT_TSHIRT, 2000), *hi = instance(CR_GARMENT_TSHIRT, 4000);
    CR_REQUIRE(lo && hi);
    CR_CHECK(lo->uv_scale_m == hi->uv_scale_m);
    cr_error err = {0};
    int32_t nh = hi->mesh->nv, nl = lo->mesh->nv;
    int32_t *face = malloc((size_t)nh * sizeof(int32_t));
    float *bary = malloc((size_t)nh * 3 * sizeof(float)),
          *x = malloc((size_t)nh * 3 * sizeof(float));
    CR_CHECK_OK(cr_garment_correspondence(lo->mesh, hi->mesh, face, bary, &err), &err);
    cr_garment_apply_correspondence(lo->mesh, lo->mesh->pos, face, bary, nh, x);
    double worst = 0.0, mean = 0.0;
    for (int32_t v = 0; v < nh; v++) {
        CR_CHECK(face[v] >= 0 && face[v] < lo->mesh->nf);
        CR_CHECK_NEAR(bary[3 * v] + bary[3 * v + 1] + bary[3 * v + 2], 1.0, 1e-5);
        double d2 = 0.0;
        for (int k = 0; k < 3; k++)
            d2 += (x[3 * v + k] - hi->mesh->pos[3 * v + k]) *
                  (x[3 * v + k] - hi->mesh->pos[3 * v + k]);
        worst = fmax(worst, sqrt(d2));
        mean += sqrt(d2) / nh;
    }
    printf("    high from low through UV: mean %.2f mm, worst %.2f mm\n", 1000 * mean,
           1000 * worst);
    /* The low mesh's chords sag a few millimetres; the charts agree to the same. */
    CR_CHECK(mean < 0.003);
    CR_CHECK(worst < 0.02);
    /* A mesh's own correspondence reproduces it bit for bit. */
    int32_t *fl = malloc((size_t)nl * sizeof(int32_t));
    float *bl = malloc((size_t)nl * 3 * sizeof(float)),
          *xl = malloc((size_t)nl * 3 * sizeof(float));
    CR_CHECK_OK(cr_garment_correspondence(lo->mesh, lo->mesh, fl, bl, &err), &err);
    cr_garment_apply_correspondence(lo->mesh, lo->mesh->pos, fl, bl, nl, xl);
    CR_CHECK(memcmp(xl, lo->mesh->pos, (size_t)nl * 3 * sizeof(float)) == 0);
    /* Without UVs there is nothing to correspond through. */
    cr_mesh *bare = NULL;
    CR_CHECK_OK(cr_mesh_clone(lo->mesh, &bare, &err), &err);
    free(bare->uv), free(bare->tri_uv);
    bare->uv = NULL, bare->tri_uv = NULL, bare->nuv = 0;
    CR_CHECK(cr_garment_correspondence(bare, hi->mesh, face, bary, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "low mesh has no UVs") != NULL);
    cr_mesh_destroy(bare);
    free(face), free(bary), free(x), free(fl), free(bl), free(xl);
    cr_garment_destroy(lo);
    cr_garment_destroy(hi);
}

/* -------------------------------------------------------------- layers -- */

CR_TEST(garment, vest_over_tshirt) {
    cr_body_model *body = shared_body();
    CR_REQUIRE(body);
    cr_error err = {0};
    cr_garment_def defs[2] = {cr_garment_default_def(CR_GARMENT_TSHIRT),
                              cr_garment_default_def(CR_GARMENT_VEST)};
    defs[0].target_vertices = defs[1].target_vertices = 2000;
    cr_garment *g[2] = {NULL, NULL};
    CR_CHECK_OK(cr_garment_create_layers(defs, 2, body, g, &err), &err);
    CR_REQUIRE(g[0] && g[1]);
    CR_CHECK(cr_garment_count_crossings(g[0]->mesh, g[1]->mesh, &err) == 0);
    /* The check can fail: the shirt pushed 15 mm out crosses the vest. */
    cr_mesh *out = NULL;
    CR_CHECK_OK(cr_mesh_clone(g[0]->mesh, &out, &err), &err);
    for (int32_t v = 0; v < out->nv; v++)
        for (int k = 0; k < 3; k++)
            out->pos[3 * v + k] += 0.015f * out->normal[3 * v + k];
    CR_CHECK(cr_garment_count_crossings(out, g[1]->mesh, &err) > 0);
    cr_mesh_destroy(out);
    cr_garment_destroy(g[0]);
    cr_garment_destroy(g[1]);
    /* A vest not clearing the shirt by the gap is refused, naming both. */
    defs[1].clearance_m = defs[0].clearance_m + 0.5f * CR_GARMENT_LAYER_GAP;
    CR_CHECK(cr_garment_create_layers(defs, 2, body, g, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "layer 1 (vest") != NULL &&
             strstr(err.msg, "layer 0 (tshirt") != NULL);
    CR_CHECK(g[0] == NULL && g[1] == NULL);
}

/* ------------------------------------------------------------- skinning -- */

CR_TEST(garment, skinning) {
    cr_error err = {0};
    cr_body_model *body = shared_body();
    cr_garment *g = instance(CR_GARMENT_TSHIRT, 2000);
    CR_REQUIRE(body && g);
    /* The rest pose reproduces the rest mesh. */
    float pose[CR_NJOINTS * 3] = {0}, *x = malloc((size_t)g->mesh->nv * 3 * sizeof(float));
    CR_CHECK_OK(cr_garment_pose(g, body, pose, NULL, x, &err), &err);
    double worst = 0.0;
    for (int32_t i = 0; i < 3 * g->mesh->nv; i++)
        worst = fmax(worst, fabs(x[i] - g->mesh->pos[i]));
    CR_CHECK(worst < 1e-5);
    /* Sleeves follow the arm on their side: most of their weight on its joints. */
    int32_t good = 0, total = 0;
    for (int32_t f = 0; f < g->mesh->nf; f++) {
        int left = strncmp(g->panel_name[g->panel[f]], "left_sleeve", 11) == 0;
        if (!left) continue;
        int32_t v = g->mesh->tri[3 * f];
        float arm = 0.0f;
        for (int k = 0; k < 4; k++) {
            int32_t j = g->skin_joint[4 * v + k];
            if (j == CR_JOINT_LEFT_COLLAR || j == CR_JOINT_LEFT_SHOULDER ||
                j == CR_JOINT_LEFT_ELBOW)
                arm += g->skin_weight[4 * v + k];
        }
        good += arm > 0.5f, total++;
    }
    CR_CHECK(total > 0 && good > 0.95 * total);
    pose[3] = NAN;
    CR_CHECK(cr_garment_pose(g, body, pose, NULL, x, &err) == CR_ERR_NAN);
    free(x);
    cr_garment_destroy(g);
    /* Skirts: weights spread over the cloth, so neighbours differ little
     * (the closest point alone jumps between the legs). */
    cr_garment *s = instance(CR_GARMENT_SKIRT, 2000);
    CR_REQUIRE(s);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(s->mesh, &t, &err), &err);
    /* Below the hips, where the skirt hangs free of the body. */
    const float below = body->joints[3 * CR_JOINT_LEFT_HIP + 1] - 0.05f;
    double jump = 0.0;
    for (int32_t e = 0; e < t->ne; e++) {
        if (s->mesh->pos[3 * t->edge[2 * e] + 1] > below) continue;
        float wa[CR_NJOINTS] = {0}, wb[CR_NJOINTS] = {0};
        for (int k = 0; k < 4; k++) {
            wa[s->skin_joint[4 * t->edge[2 * e] + k]] += s->skin_weight[4 * t->edge[2 * e] + k];
            wb[s->skin_joint[4 * t->edge[2 * e + 1] + k]] +=
                s->skin_weight[4 * t->edge[2 * e + 1] + k];
        }
        double d = 0.0;
        for (int j = 0; j < CR_NJOINTS; j++)
            d += fabs(wa[j] - wb[j]);
        jump = fmax(jump, d);
    }
    printf("    skirt below the hips: largest L1 weight change along an edge %.3f\n", jump);
    CR_CHECK(jump < 0.3); /* the closest body point alone jumps by 2 between the legs */
    cr_topology_destroy(t);
    cr_garment_destroy(s);
}

/* ------------------------------------------------------- user garments -- */

static cr_status fit_file(const char *name, const cr_mesh *m, cr_garment **out, cr_error *err) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", cr_test_tmpdir(), name);
    cr_error werr = {0};
    if (cr_obj_write(path, m, &werr) != CR_OK) {
        cr_test_fail_here(__FILE__, __LINE__, "%s", werr.msg);
        return CR_ERR_IO;
    }
    cr_garment_user_def def = cr_garment_user_default_def();
    return cr_garment_load_user(path, &def, shared_body(), out, err);
}

CR_TEST(garment, user_obj) {
    cr_error err = {0};
    cr_garment *g = instance(CR_GARMENT_TSHIRT, 2000);
    CR_REQUIRE(g);
    cr_mesh *m = NULL;
    /* Sunk 15 mm into the body: fitting brings every vertex out to 1 cm. */
    CR_CHECK_OK(cr_mesh_clone(g->mesh, &m, &err), &err);
    for (int32_t v = 0; v < m->nv; v++)
        for (int k = 0; k < 3; k++)
            m->pos[3 * v + k] -= 0.015f * m->normal[3 * v + k];
    cr_garment *u = NULL;
    CR_CHECK_OK(fit_file("sunk.obj", m, &u, &err), &err);
    if (u) {
        cr_garment_quality q;
        CR_CHECK_OK(cr_garment_measure(u, shared_body(), &q, &err), &err);
        printf("    user shirt sunk 15 mm: clearance after fitting %.2f mm, %.4f above 20 deg\n",
               1000.0 * q.min_clearance_m, (double)q.share_min_angle_above_20deg);
        CR_CHECK(q.min_clearance_m >= 0.0099f);
        CR_CHECK(q.share_min_angle_above_20deg > 0.95f);
        CR_CHECK(q.manifold && q.boundary_loops == 4);
        CR_CHECK(u->npanels == 6 && u->type == CR_GARMENT_USER);
        CR_CHECK(q.max_weight_sum_error < 1e-5f);
        CR_CHECK(u->uv_scale_m > 0.5f * g->uv_scale_m && u->uv_scale_m < 2.0f * g->uv_scale_m);
        cr_garment_destroy(u);
    }
    cr_mesh_destroy(m);

    /* Without UVs (as research garments come): accepted, one piece, the
     * same fit and skinning; uv_scale_m 0 says there is no chart. */
    CR_CHECK_OK(cr_mesh_clone(g->mesh, &m, &err), &err);
    free(m->uv), free(m->tri_uv);
    m->uv = NULL, m->tri_uv = NULL, m->nuv = 0;
    CR_CHECK_OK(fit_file("nouv.obj", m, &u, &err), &err);
    if (u) {
        cr_garment_quality q;
        CR_CHECK_OK(cr_garment_measure(u, shared_body(), &q, &err), &err);
        CR_CHECK(!cr_mesh_has_uv(u->mesh) && u->uv_scale_m == 0.0f);
        CR_CHECK(u->npanels == 1 && strcmp(u->panel_name[0], "piece_0") == 0);
        CR_CHECK(q.min_clearance_m >= 0.0099f && q.max_weight_sum_error < 1e-5f);
        CR_CHECK(u->mesh->nv == g->mesh->nv);
        cr_garment_destroy(u);
    }
    cr_mesh_destroy(m);

    /* Bad files: each message names the file and the problem. */
    struct {
        const char *name, *expect;
        cr_status st;
    } bad[] = {{"flatuv.obj", "zero UV area", CR_ERR_INVALID},
               {"cm.obj", "centimetres", CR_ERR_INVALID},
               {"far.obj", "within 0.3 m of the body", CR_ERR_INVALID},
               {"inward.obj", "point into the body", CR_ERR_TOPOLOGY},
               {"fin.obj", "non-manifold edge", CR_ERR_TOPOLOGY},
               {"low.obj", "below the body", CR_ERR_INVALID}};
    for (int i = 0; i < 6; i++) {
        CR_CHECK_OK(cr_mesh_clone(g->mesh, &m, &err), &err);
        if (i == 0) {
            for (int32_t k = 0; k < 2 * m->nuv; k++)
                m->uv[k] = 0.5f;
        } else if (i == 1) {
            cr_mesh_transform(m, 100.0f, (float[3]){0, 0, 0});
        } else if (i == 2) {
            cr_mesh_transform(m, 1.0f, (float[3]){3.0f, 0, 0});
        } else if (i == 5) { /* made on SMPL's pelvis at the origin: on the shins */
            cr_mesh_transform(m, 1.0f, (float[3]){0, -1.15f, 0});
        } else if (i == 3) {
            for (int32_t f = 0; f < m->nf; f++) {
                int32_t t = m->tri[3 * f + 1];
                m->tri[3 * f + 1] = m->tri[3 * f + 2], m->tri[3 * f + 2] = t;
                t = m->tri_uv[3 * f + 1];
                m->tri_uv[3 * f + 1] = m->tri_uv[3 * f + 2], m->tri_uv[3 * f + 2] = t;
            }
        } else if (i == 4) {
            /* A third face on the first face's first edge. */
            cr_mesh *fin = NULL;
            CR_CHECK_OK(cr_mesh_create(m->nv, m->nf + 1, m->nuv, &fin, &err), &err);
            memcpy(fin->pos, m->pos, (size_t)m->nv * 3 * sizeof(float));
            memcpy(fin->tri, m->tri, (size_t)m->nf * 3 * sizeof(int32_t));
            memcpy(fin->uv, m->uv, (size_t)m->nuv * 2 * sizeof(float));
            memcpy(fin->tri_uv, m->tri_uv, (size_t)m->nf * 3 * sizeof(int32_t));
            int32_t *t = &fin->tri[3 * m->nf];
            t[0] = m->tri[0], t[1] = m->tri[1],
            t[2] = m->tri[5] != m->tri[0] ? m->tri[5] : m->tri[4];
            memcpy(&fin->tri_uv[3 * m->nf], m->tri_uv, 3 * sizeof(int32_t));
            cr_mesh_destroy(m);
            m = fin;
        }
        err = (cr_error){0};
        cr_status st = fit_file(bad[i].name, m, &u, &err);
        CR_CHECK(st == bad[i].st);
        CR_CHECK(u == NULL);
        if (!strstr(err.msg, bad[i].name) || !strstr(err.msg, bad[i].expect))
            cr_test_fail_here(__FILE__, __LINE__, "%s: message '%s' lacks the file or '%s'",
                              bad[i].name, err.msg, bad[i].expect);
        cr_mesh_destroy(m);
    }
    cr_garment_user_def def = cr_garment_user_default_def();
    CR_CHECK(cr_garment_load_user("/nonexistent/shirt.obj", &def, shared_body(), &u, &err) ==
             CR_ERR_IO);
    def.clearance_m = 0.0f;
    CR_CHECK(cr_garment_fit_user(g->mesh, "x.obj", &def, shared_body(), &u, &err) ==
             CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "clearance_m") != NULL);
    cr_garment_destroy(g);
}

/* Two ways exporters write a garment: one vertex per (position, UV) pair,
 * so every seam is open, and one `vt` per face corner. Both read as the
 * garment they draw: the seams welded, the panels by UV value. */
CR_TEST(garment, user_obj_exporter_quirks) {
    cr_error err = {0};
    cr_garment *g = instance(CR_GARMENT_TSHIRT, 2000);
    CR_REQUIRE(g);
    const cr_mesh *m = g->mesh;
    /* (a) a vertex per distinct (vertex, uv) corner */
    int32_t *key = malloc(sizeof(int32_t) * 3 * (size_t)m->nf * 2), n = 0;
    cr_mesh *split = NULL;
    CR_CHECK_OK(cr_mesh_create(3 * m->nf, m->nf, m->nuv, &split, &err), &err);
    CR_REQUIRE(key && split);
    for (int32_t c = 0; c < 3 * m->nf; c++) {
        int32_t found = -1;
        for (int32_t i = 0; i < n && found < 0; i++)
            if (key[2 * i] == m->tri[c] && key[2 * i + 1] == m->tri_uv[c]) found = i;
        if (found < 0) {
            key[2 * n] = m->tri[c], key[2 * n + 1] = m->tri_uv[c];
            memcpy(&split->pos[3 * n], &m->pos[3 * (size_t)m->tri[c]], 3 * sizeof(float));
            found = n++;
        }
        split->tri[c] = found, split->tri_uv[c] = m->tri_uv[c];
    }
    split->nv = n;
    memcpy(split->uv, m->uv, sizeof(float) * 2 * (size_t)m->nuv);
    printf("    t-shirt of %d vertices written as %d, one per UV\n", m->nv, n);
    CR_CHECK(n > m->nv);
    cr_garment *u = NULL;
    CR_CHECK_OK(fit_file("unwelded.obj", split, &u, &err), &err);
    if (u) {
        cr_garment_quality q;
        CR_CHECK_OK(cr_garment_measure(u, shared_body(), &q, &err), &err);
        CR_CHECK(u->mesh->nv == m->nv && q.manifold && q.boundary_loops == 4 && u->npanels == 6);
        cr_garment_destroy(u);
    }
    cr_mesh_destroy(split);
    free(key);
    /* (b) a vt per corner, the values unchanged */
    cr_mesh *corner = NULL;
    CR_CHECK_OK(cr_mesh_create(m->nv, m->nf, 3 * m->nf, &corner, &err), &err);
    CR_REQUIRE(corner);
    memcpy(corner->pos, m->pos, sizeof(float) * 3 * (size_t)m->nv);
    memcpy(corner->tri, m->tri, sizeof(int32_t) * 3 * (size_t)m->nf);
    for (int32_t c = 0; c < 3 * m->nf; c++) {
        corner->tri_uv[c] = c;
        memcpy(&corner->uv[2 * c], &m->uv[2 * (size_t)m->tri_uv[c]], 2 * sizeof(float));
    }
    CR_CHECK_OK(fit_file("per_corner_vt.obj", corner, &u, &err), &err);
    if (u) {
        printf("    one vt per corner: %d panels\n", u->npanels);
        CR_CHECK(u->npanels == 6);
        cr_garment_destroy(u);
    }
    cr_mesh_destroy(corner);
    cr_garment_destroy(g);
}

/* --------------------------------------------------------- definitions -- */

CR_TEST(garment, bad_defs_and_determinism) {
    cr_error err = {0};
    cr_body_model *body = shared_body();
    CR_REQUIRE(body);
    cr_garment_type type;
    CR_CHECK(cr_garment_type_parse("poncho", &type, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "poncho") != NULL && strstr(err.msg, "trousers") != NULL);
    CR_CHECK(cr_garment_type_parse("user", &type, &err) == CR_ERR_INVALID);
    CR_CHECK_OK(cr_garment_type_parse("dress", &type, &err), &err);
    CR_CHECK(type == CR_GARMENT_DRESS);
    cr_garment *g = NULL;
    cr_garment_def def = cr_garment_default_def(CR_GARMENT_SKIRT);
    def.clearance_m = 0.001f;
    CR_CHECK(cr_garment_create(&def, body, &g, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "clearance_m") != NULL && g == NULL);
    def = cr_garment_default_def(CR_GARMENT_SKIRT);
    def.target_vertices = 200;
    CR_CHECK(cr_garment_create(&def, body, &g, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "target_vertices") != NULL);
    CR_CHECK(cr_garment_template_instantiate(shared_template(CR_GARMENT_SKIRT), 10, body, &g,
                                             &err) == CR_ERR_INVALID);
    /* A template only instantiates on its own body. */
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 48;
    cr_body_model *other = NULL;
    CR_CHECK_OK(cr_mannequin_create(&md, &other, &err), &err);
    CR_CHECK(cr_garment_template_instantiate(shared_template(CR_GARMENT_SKIRT), 2000, other, &g,
                                             &err) == CR_ERR_SHAPE);
    cr_body_model_destroy(other);
    /* The same template and count give the same garment bit for bit. */
    cr_garment *a = instance(CR_GARMENT_SKIRT, 2000), *b = instance(CR_GARMENT_SKIRT, 2000);
    CR_REQUIRE(a && b);
    CR_CHECK(a->mesh->nv == b->mesh->nv && a->mesh->nf == b->mesh->nf);
    if (a->mesh->nv == b->mesh->nv && a->mesh->nf == b->mesh->nf) {
        CR_CHECK(memcmp(a->mesh->pos, b->mesh->pos, (size_t)a->mesh->nv * 12) == 0);
        CR_CHECK(memcmp(a->mesh->uv, b->mesh->uv, (size_t)a->mesh->nuv * 8) == 0);
        CR_CHECK(memcmp(a->skin_weight, b->skin_weight, (size_t)a->mesh->nv * 16) == 0);
    }
    cr_garment_destroy(a);
    cr_garment_destroy(b);
}

/* Other bodies: a heavy body in trousers, a slim one in a dress. */
CR_TEST(garment, other_shapes) {
    static const char *shape[2] = {"heavy", "slim"};
    static const cr_garment_type type[2] = {CR_GARMENT_TROUSERS, CR_GARMENT_DRESS};
    cr_error err = {0};
    for (int i = 0; i < 2; i++) {
        cr_mannequin_def md = cr_mannequin_default_def();
        CR_CHECK_OK(cr_mannequin_preset(shape[i], &md, &err), &err);
        md.resolution = 64;
        cr_body_model *body = NULL;
        CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
        if (!body) continue;
        cr_garment_def def = cr_garment_default_def(type[i]);
        def.target_vertices = 2000;
        cr_garment *g = NULL;
        CR_CHECK_OK(cr_garment_create(&def, body, &g, &err), &err);
        if (g) {
            cr_garment_quality q;
            CR_CHECK_OK(cr_garment_measure(g, body, &q, &err), &err);
            printf("    %s %s: %d vertices, %.4f above 20 deg, clearance %.1f mm\n", shape[i],
                   cr_garment_type_name(type[i]), q.vertices, (double)q.share_min_angle_above_20deg,
                   1000.0 * q.min_clearance_m);
            CR_CHECK(q.share_min_angle_above_20deg >= 0.99f && q.min_clearance_m >= 0.005f);
            CR_CHECK(q.manifold && q.share_outward >= 0.99f);
            CR_CHECK(abs(q.vertices - 2000) <= 300);
        }
        cr_garment_destroy(g);
        cr_body_model_destroy(body);
    }
}

/* -------------------------------------------------------------- physics -- */

/* The low-resolution t-shirt dropped on the static body: 30 frames of the
 * reference simulator, fewer than 0.5% of vertices inside the body on any
 * frame, no divergence. */
CR_TEST(garment, simulated_tshirt_stays_out) {
    cr_error err = {0};
    cr_body_model *body = shared_body();
    cr_garment *g = instance(CR_GARMENT_TSHIRT, 2000);
    CR_REQUIRE(body && g);
    cr_sim_def def = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &def.material, &err), &err);
    def.collider = body->rest;
    cr_sim *sim = NULL;
    CR_CHECK_OK(cr_sim_create(&def, g->mesh, &sim, &err), &err);
    cr_bvh *bvh = NULL;
    CR_CHECK_OK(
        cr_bvh_build(body->rest->pos, body->rest->nv, body->rest->tri, body->rest->nf, &bvh, &err),
        &err);
    const int32_t nv = g->mesh->nv;
    float *x = malloc((size_t)nv * 3 * sizeof(float)), *d = malloc((size_t)nv * sizeof(float));
    double worst_share = 0.0, max_drop = 0.0;
    for (int frame = 0; sim && bvh && frame < 30; frame++) {
        cr_sim_report rep;
        cr_status st = cr_sim_step(sim, &rep, &err);
        CR_CHECK(st == CR_OK && !rep.diverged);
        if (st != CR_OK) {
            printf("    frame %d: %s\n", frame, err.msg);
            break;
        }
        cr_sim_positions_f(sim, x);
        cr_bvh_signed_distance_batch(bvh, x, nv, 0.1f, d, NULL, NULL);
        int32_t inside = 0;
        for (int32_t v = 0; v < nv; v++) {
            inside += d[v] < 0.0f;
            max_drop = fmax(max_drop, g->mesh->pos[3 * v + 1] - x[3 * v + 1]);
        }
        worst_share = fmax(worst_share, (double)inside / nv);
    }
    printf("    30 frames: worst share inside %.3f%%, largest drop %.1f mm\n", 100.0 * worst_share,
           1000.0 * max_drop);
    CR_CHECK(worst_share < 0.005);
    /* It settles onto the shoulders rather than falling through. */
    CR_CHECK(max_drop < 0.1);
    free(x), free(d);
    cr_bvh_destroy(bvh);
    cr_sim_destroy(sim);
    cr_garment_destroy(g);
}
