/* test_body_resolve.c: cr_body_resolve, the body spec every method takes: a
 * mannequin preset, or an SMPL-family model file with its shape
 * coefficients. The model file here is the mannequin written as SMPL's
 * arrays (24 joints, a girth direction in shapedirs), so a method built on
 * it can be checked against the mannequin itself. */
#include "crease/body.h"
#include "crease/bvh.h"
#include "crease/dataset.h"
#include "crease/epnet.h"
#include "crease/garment.h"
#include "crease/mesh.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The mannequin as an SMPL-style .npz: v_template its rest, shapedirs one
 * direction moving every vertex away from the vertical axis by 10 % per
 * unit, J_regressor each joint at its rest position from the K vertices
 * nearest it (the minimum-norm weights summing to 1: w = (1 + (p - m)^T C^-1
 * (joint - m)) / K with m, C their mean and covariance, as
 * scripts/smpl_style_body.py; their plain mean sits on the skin's near side
 * and the t-shirt's neckline then closed over the head), weights its own,
 * kintree SMPL's (hands as children of the wrists, unweighted), f its faces.
 * Not exact: each joint the plain mean of the 12 nearest. */
static int write_model(const char *path, const cr_body_model *b, int exact) {
    enum { J = 24, K = 48 };
    const int64_t V = b->rest->nv, F = b->rest->nf;
    double *tmpl = calloc((size_t)V * 3, sizeof(double));
    double *dirs = calloc((size_t)V * 3, sizeof(double));
    double *reg = calloc((size_t)J * V, sizeof(double));
    double *w = calloc((size_t)V * J, sizeof(double));
    int64_t *f = calloc((size_t)F * 3, sizeof(int64_t));
    double kt[2][J];
    float *d2 = malloc(sizeof(float) * (size_t)V);
    if (!tmpl || !dirs || !reg || !w || !f || !d2) return 0;
    for (int64_t v = 0; v < V; v++) {
        const float *p = b->rest->pos + 3 * v;
        for (int k = 0; k < 3; k++)
            tmpl[3 * v + k] = p[k];
        dirs[3 * v + 0] = 0.1 * p[0], dirs[3 * v + 2] = 0.1 * p[2];
        for (int k = 0; k < 4; k++)
            w[v * J + b->skin_joint[4 * v + k]] += b->skin_weight[4 * v + k];
    }
    for (int j = 0; j < J; j++) {
        const float *c = b->joints + 3 * (j < CR_NJOINTS ? j : (j == 22 ? 20 : 21));
        for (int64_t v = 0; v < V; v++) {
            const float *p = b->rest->pos + 3 * v;
            d2[v] = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                    (p[2] - c[2]) * (p[2] - c[2]);
        }
        int64_t near[K];
        for (int k = 0; k < K; k++) { /* the K nearest, by repeated selection */
            int64_t best = 0;
            for (int64_t v = 1; v < V; v++)
                if (d2[v] < d2[best]) best = v;
            near[k] = best;
            d2[best] = INFINITY;
        }
        double m[3] = {0, 0, 0}, C[9] = {0}, Ci[9];
        for (int k = 0; k < K; k++)
            for (int a = 0; a < 3; a++)
                m[a] += b->rest->pos[3 * near[k] + a] / (double)K;
        for (int k = 0; k < K; k++)
            for (int a = 0; a < 3; a++)
                for (int c2 = 0; c2 < 3; c2++)
                    C[3 * a + c2] += (b->rest->pos[3 * near[k] + a] - m[a]) *
                                     (b->rest->pos[3 * near[k] + c2] - m[c2]) / K;
        const double det = C[0] * (C[4] * C[8] - C[5] * C[7]) - C[1] * (C[3] * C[8] - C[5] * C[6]) +
                           C[2] * (C[3] * C[7] - C[4] * C[6]);
        for (int a = 0; a < 3; a++) /* the inverse by cofactors (C is symmetric) */
            for (int c2 = 0; c2 < 3; c2++) {
                const int r0 = (c2 + 1) % 3, r1 = (c2 + 2) % 3, q0 = (a + 1) % 3, q1 = (a + 2) % 3;
                Ci[3 * a + c2] =
                    (C[3 * r0 + q0] * C[3 * r1 + q1] - C[3 * r0 + q1] * C[3 * r1 + q0]) / det;
            }
        double y[3] = {0, 0, 0};
        for (int a = 0; a < 3; a++)
            for (int c2 = 0; c2 < 3; c2++)
                y[a] += Ci[3 * a + c2] * (c[c2] - m[c2]);
        for (int k = 0; k < K; k++) {
            double dot = 0.0;
            for (int a = 0; a < 3; a++)
                dot += (b->rest->pos[3 * near[k] + a] - m[a]) * y[a];
            reg[j * V + near[k]] = exact ? (1.0 + dot) / K : k < 12 ? 1.0 / 12 : 0.0;
        }
        kt[0][j] = j == 0 ? 4294967295.0 : j < CR_NJOINTS ? cr_joint_parent[j] : 20 + (j - 22);
        kt[1][j] = j;
    }
    for (int64_t i = 0; i < 3 * F; i++)
        f[i] = b->rest->tri[i];
    int64_t s_t[2] = {V, 3}, s_d[3] = {V, 3, 1}, s_r[2] = {J, V}, s_w[2] = {V, J}, s_k[2] = {2, J},
            s_f[2] = {F, 3};
    cr_error err = {0};
    cr_npz_writer *wr = NULL;
    int ok = cr_npz_writer_open(path, 1, &wr, &err) == CR_OK &&
             cr_npz_writer_add(wr, "v_template", CR_NPY_F64, 2, s_t, tmpl, &err) == CR_OK &&
             cr_npz_writer_add(wr, "shapedirs", CR_NPY_F64, 3, s_d, dirs, &err) == CR_OK &&
             cr_npz_writer_add(wr, "J_regressor", CR_NPY_F64, 2, s_r, reg, &err) == CR_OK &&
             cr_npz_writer_add(wr, "weights", CR_NPY_F64, 2, s_w, w, &err) == CR_OK &&
             cr_npz_writer_add(wr, "kintree_table", CR_NPY_F64, 2, s_k, kt, &err) == CR_OK &&
             cr_npz_writer_add(wr, "f", CR_NPY_I64, 2, s_f, f, &err) == CR_OK &&
             cr_npz_writer_commit(wr, &err) == CR_OK;
    if (!ok) printf("    %s\n", err.msg);
    free(tmpl), free(dirs), free(reg), free(w), free(f), free(d2);
    return ok;
}

static double width(const cr_body_model *b) {
    float lo[3], hi[3];
    cr_mesh_bounds(b->rest, lo, hi);
    return hi[0] - lo[0];
}

CR_TEST(body_resolve, presets_and_model_files) {
    cr_error err = {0};
    cr_body_model *normal = NULL, *plain = NULL, *wide = NULL, *bad = NULL;
    CR_CHECK_OK(cr_body_resolve("normal", &normal, &err), &err);
    CR_REQUIRE(normal);
    char path[512], spec[600];
    snprintf(path, sizeof path, "%s/mannequin_smpl.npz", cr_test_tmpdir());
    CR_REQUIRE(write_model(path, normal, 1));
    CR_CHECK_OK(cr_body_resolve(path, &plain, &err), &err);
    snprintf(spec, sizeof spec, "%s:1.5", path);
    CR_CHECK_OK(cr_body_resolve(spec, &wide, &err), &err);
    CR_REQUIRE(plain && wide);
    printf("    widths: mannequin %.4f m, its model file %.4f m, beta 1.5 %.4f m\n", width(normal),
           width(plain), width(wide));
    CR_CHECK(plain->rest->nv == normal->rest->nv);
    CR_CHECK_NEAR(width(plain), width(normal), 1e-4);
    CR_CHECK_NEAR(width(wide), 1.15 * width(normal), 2e-3);
    /* Refusals name the spec and what is wrong. */
    CR_CHECK(cr_body_resolve("giant", &bad, &err) == CR_ERR_INVALID && !bad);
    CR_CHECK(strstr(err.msg, "giant") && strstr(err.msg, "slim"));
    snprintf(spec, sizeof spec, "%s:1.5:x", path); /* ':' separates betas as ',' does */
    CR_CHECK(cr_body_resolve(spec, &bad, &err) == CR_ERR_INVALID && !bad);
    CR_CHECK(strstr(err.msg, "coefficient 2") != NULL);
    snprintf(spec, sizeof spec, "%s:1.5,x", path);
    CR_CHECK(cr_body_resolve(spec, &bad, &err) == CR_ERR_INVALID && !bad);
    CR_CHECK(strstr(err.msg, "coefficient 2") != NULL);
    CR_CHECK(cr_body_resolve("/nonexistent/smplx.npz:0.1", &bad, &err) != CR_OK && !bad);
    CR_CHECK(strstr(err.msg, "smplx.npz") != NULL);
    cr_body_model_destroy(normal), cr_body_model_destroy(plain), cr_body_model_destroy(wide);
}

/* epnet on an SMPL-family body with shape coefficients: its garment is fitted
 * to the wider body, every vertex outside it. */
CR_TEST(body_resolve, epnet_on_a_model_file) {
    cr_error err = {0};
    cr_body_model *normal = NULL;
    CR_CHECK_OK(cr_body_resolve("normal", &normal, &err), &err);
    CR_REQUIRE(normal);
    char path[512], spec[600];
    snprintf(path, sizeof path, "%s/mannequin_smpl2.npz", cr_test_tmpdir());
    CR_REQUIRE(write_model(path, normal, 1));
    snprintf(spec, sizeof spec, "%s:1.0", path);
    cr_epnet_def d = cr_epnet_default_def();
    d.body = spec;
    d.garment_vertices = 500;
    const char *motions[1] = {"squat"};
    d.motions = motions, d.nmotions = 1, d.frames = 4;
    cr_epnet *m = NULL;
    CR_CHECK_OK(cr_epnet_create(&d, &m, &err), &err);
    if (m) {
        const cr_mesh *g = cr_epnet_garment(m);
        float lo[3], hi[3];
        cr_mesh_bounds(g, lo, hi);
        printf("    t-shirt on the model file (beta 1): %d vertices, %.3f m wide (the body %.3f "
               "m)\n",
               g->nv, hi[0] - lo[0], 1.1 * width(normal));
        CR_CHECK(hi[0] - lo[0] > 0.3);
        /* fitted to the widened body: every vertex outside it */
        cr_body_model *wide = NULL;
        cr_bvh *bvh = NULL;
        CR_CHECK_OK(cr_body_resolve(spec, &wide, &err), &err);
        float *dist = malloc(sizeof(float) * (size_t)g->nv), nearest = INFINITY;
        if (wide && dist &&
            cr_bvh_build(wide->rest->pos, wide->rest->nv, wide->rest->tri, wide->rest->nf, &bvh,
                         &err) == CR_OK) {
            cr_bvh_signed_distance_batch(bvh, g->pos, g->nv, INFINITY, dist, NULL, NULL);
            for (int32_t v = 0; v < g->nv; v++)
                nearest = fminf(nearest, dist[v]);
        }
        printf("    nearest garment vertex %.4f m outside the body\n", (double)nearest);
        CR_CHECK(nearest > 0.002f && nearest < 0.1f);
        cr_bvh_destroy(bvh);
        free(dist);
        cr_body_model_destroy(wide);
        cr_epnet_destroy(m);
    }
    cr_body_model_destroy(normal);
}

/* A dataset on the user's own assets: an SMPL-family body file with a shape
 * coefficient beside a preset, and a garment from another tool (an OBJ
 * without UVs). Every sequence is simulated; the body's files are named by
 * its label; the garment keeps its file's vertex count on each body, has no
 * UVs, and less than 0.5 % of it is inside a body on any frame. */
/* A model whose joints are the plain means of the vertices nearest them (on
 * the skin's near side): the t-shirt's neckline misses the neck and the
 * garment would close over the head, so it is refused, saying so. */
CR_TEST(body_resolve, a_neckline_that_cannot_open_is_refused) {
    cr_error err = {0};
    cr_body_model *normal = NULL, *model = NULL;
    CR_CHECK_OK(cr_body_resolve("normal", &normal, &err), &err);
    CR_REQUIRE(normal);
    char path[512];
    snprintf(path, sizeof path, "%s/mannequin_smpl_mean12.npz", cr_test_tmpdir());
    CR_REQUIRE(write_model(path, normal, 0));
    CR_CHECK_OK(cr_body_resolve(path, &model, &err), &err);
    CR_REQUIRE(model);
    cr_garment_def d = cr_garment_default_def(CR_GARMENT_TSHIRT);
    d.target_vertices = 500;
    cr_garment *g = NULL;
    CR_CHECK(cr_garment_create(&d, model, &g, &err) == CR_ERR_TOPOLOGY && !g);
    printf("    %s\n", err.msg);
    CR_CHECK(strstr(err.msg, "neckline did not open") && strstr(err.msg, "head joint"));
    cr_garment_destroy(g);
    cr_body_model_destroy(model), cr_body_model_destroy(normal);
}

CR_TEST(body_resolve, dataset_with_a_model_file_and_a_garment_file) {
    cr_error err = {0};
    cr_body_model *normal = NULL;
    CR_CHECK_OK(cr_body_resolve("normal", &normal, &err), &err);
    CR_REQUIRE(normal);
    char model[512], spec[600], obj[512], dir[512];
    snprintf(model, sizeof model, "%s/mannequin_smpl3.npz", cr_test_tmpdir());
    CR_REQUIRE(write_model(model, normal, 1));
    snprintf(spec, sizeof spec, "%s:0.5", model);
    /* the garment as another tool exports it: positions and faces only */
    cr_garment_def gd = cr_garment_default_def(CR_GARMENT_SKIRT);
    gd.target_vertices = 600;
    cr_garment *made = NULL;
    CR_CHECK_OK(cr_garment_create(&gd, normal, &made, &err), &err);
    CR_REQUIRE(made);
    cr_mesh *bare = NULL;
    CR_CHECK_OK(cr_mesh_create(made->mesh->nv, made->mesh->nf, 0, &bare, &err), &err);
    CR_REQUIRE(bare);
    memcpy(bare->pos, made->mesh->pos, sizeof(float) * 3 * (size_t)bare->nv);
    memcpy(bare->tri, made->mesh->tri, sizeof(int32_t) * 3 * (size_t)bare->nf);
    snprintf(obj, sizeof obj, "%s/their_skirt.obj", cr_test_tmpdir());
    CR_CHECK_OK(cr_mesh_write(obj, bare, &err), &err);
    snprintf(dir, sizeof dir, "%s/user_dataset", cr_test_tmpdir());
    cr_dataset_def d = cr_dataset_default_def();
    const char *garments[] = {obj}, *motions[] = {"walk"}, *bodies[] = {"normal", spec};
    const char *res[] = {"low"};
    d.out_dir = dir;
    d.garments = garments, d.ngarments = 1;
    d.motions = motions, d.nmotions = 1;
    d.bodies = bodies, d.nbodies = 2;
    d.res = res, d.nres = 1;
    d.frames = CR_TEST_SIZE(8, 3);
    d.quiet = 1;
    cr_dataset_result r;
    CR_CHECK_OK(cr_dataset_generate(&d, &r, &err), &err);
    CR_CHECK(r.failed == 0 && r.done == 2);
    printf("    most of the garment inside a body on a frame: %.3f %%\n",
           100.0 * r.max_inside_share[0]);
    CR_CHECK(r.max_inside_share[0] < 0.005);
    cr_dataset_manifest man = {0};
    CR_CHECK_OK(cr_dataset_read(dir, &man, &err), &err);
    char label[64];
    cr_dataset_body_label(spec, label, sizeof label);
    printf("    body label %s; garment '%s'; %d sequences\n", label,
           man.ngarments ? man.garments[0].label : "?", man.nsequences);
    CR_CHECK(strcmp(label, "mannequin_smpl3_b0p5") == 0);
    CR_CHECK(man.nbodies == 2 && cr_dataset_find_body(&man, label) != NULL);
    CR_CHECK(man.ngarments == 2 && strcmp(man.garments[0].label, "their_skirt") == 0);
    CR_CHECK(man.nsequences == 2 && man.sequences[0].done && man.sequences[1].done);
    for (int32_t i = 0; i < man.ngarments && i < 2; i++) {
        char path[CR_SCENE_PATH];
        cr_mesh *gm = NULL;
        CR_CHECK_OK(cr_dataset_path(&man, man.garments[i].mesh, path, sizeof path, &err), &err);
        CR_CHECK_OK(cr_mesh_read(path, &gm, &err), &err);
        if (gm) CR_CHECK(gm->nv == bare->nv && gm->nuv == 0);
        cr_mesh_destroy(gm);
    }
    /* a garment file at two resolutions is refused by name */
    const char *two[] = {"low", "high"};
    d.res = two, d.nres = 2;
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "their_skirt.obj") != NULL);
    printf("    two resolutions: %s\n", err.msg);
    cr_dataset_manifest_free(&man);
    cr_mesh_destroy(bare);
    cr_garment_destroy(made);
    cr_body_model_destroy(normal);
}
