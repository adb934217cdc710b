/* test_eval.c: the metrics on cases with known answers: a sequence against
 * itself, a rigid translation, a flat and a folded sheet, a cloth inside a
 * sphere, constant velocity and constant acceleration, SSIM of identical
 * and different images, bad input. */
#include "test.h"

#include "crease/diffgeo.h"
#include "crease/eval.h"
#include "crease/primitives.h"
#include "crease/topology.h"

#include <stdlib.h>
#include <string.h>

/* (T,V,3): the mesh's positions repeated T times. */
static float *repeat(const cr_mesh *m, int T) {
    float *s = malloc((size_t)T * m->nv * 3 * sizeof(float));
    for (int t = 0; t < T; t++)
        memcpy(s + (size_t)t * m->nv * 3, m->pos, (size_t)m->nv * 3 * sizeof(float));
    return s;
}

/* A 21x21 sheet of 0.4 m with a travelling wave over T frames. */
static float *wave(const cr_mesh *m, int T) {
    float *s = repeat(m, T);
    for (int t = 0; t < T; t++)
        for (int i = 0; i < m->nv; i++) {
            float *p = &s[((size_t)t * m->nv + i) * 3];
            p[1] = 0.03f * sinf(12.0f * p[0] + 0.7f * t) * cosf(9.0f * p[2]);
        }
    return s;
}

static cr_eval_input input(const cr_mesh *g, int T, const float *pred, const float *ref) {
    cr_eval_input in = {.garment = g, .nframes = T, .pred = pred, .ref = ref};
    return in;
}

CR_TEST(eval, self_is_zero) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(21, 21, 0.4f, 0.4f, &g, &err) == CR_OK);
    const int T = 4;
    float *seq = wave(g, T);
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 64;
    cr_eval_input in = input(g, T, seq, seq);
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    const cr_eval_metric zero[] = {CR_EVAL_MED,          CR_EVAL_E_DIST_CM, CR_EVAL_CD,
                                   CR_EVAL_CHAMFER,      CR_EVAL_BE,        CR_EVAL_BED,
                                   CR_EVAL_NORMAL_ANGLE, CR_EVAL_E_NORM};
    for (size_t k = 0; k < sizeof zero / sizeof zero[0]; k++) {
        CR_CHECK(r.summary[zero[k]].count == T);
        CR_CHECK_NEAR(r.summary[zero[k]].max, 0.0, 1e-9);
    }
    CR_CHECK_NEAR(r.summary[CR_EVAL_SSIM].min, 1.0, 1e-9);
    /* undefined without a body, without rest angles, before three frames */
    CR_CHECK(r.summary[CR_EVAL_COL].count == 0 && r.summary[CR_EVAL_PE].count == 0);
    CR_CHECK(r.summary[CR_EVAL_IE].count == T - 2 && r.summary[CR_EVAL_JITTER].count == T - 2);
    CR_CHECK_NEAR(r.summary[CR_EVAL_JITTER].mean, r.summary[CR_EVAL_JITTER_REF].mean, 1e-12);
    /* the wave bends the sheet: the energies are there, and equal to the reference's own */
    CR_CHECK(r.summary[CR_EVAL_BEN].mean > 0.0 && r.summary[CR_EVAL_STE].mean > 0.0);
    CR_CHECK(r.has_spectrum);
    for (int b = 0; b < CR_EVAL_H_BANDS; b++)
        CR_CHECK_NEAR(r.h_band_pred[b], r.h_band_ref[b], 1e-12);
    cr_eval_result_free(&r);
    free(seq);
    cr_mesh_destroy(g);
}

CR_TEST(eval, rigid_translation) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(21, 21, 0.4f, 0.4f, &g, &err) == CR_OK);
    const int T = 3;
    float *ref = wave(g, T), *pred = wave(g, T);
    const float d[3] = {0.03f, 0.0f, -0.04f}; /* |d| = 5 cm */
    for (int64_t k = 0; k < (int64_t)T * g->nv; k++)
        for (int c = 0; c < 3; c++)
            pred[3 * k + c] += d[c];
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 64;
    cr_eval_input in = input(g, T, pred, ref);
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    CR_CHECK_NEAR(r.summary[CR_EVAL_MED].mean, 0.05, 1e-6);
    CR_CHECK_NEAR(r.summary[CR_EVAL_MED].max, 0.05, 1e-6);
    CR_CHECK_NEAR(r.summary[CR_EVAL_E_DIST_CM].mean, 5.0, 1e-4);
    CR_CHECK_NEAR(r.summary[CR_EVAL_NORMAL_ANGLE].max, 0.0, 1e-3); /* float round-off, degrees */
    CR_CHECK_NEAR(r.summary[CR_EVAL_E_NORM].max, 0.0, 1e-3);
    CR_CHECK_NEAR(r.summary[CR_EVAL_BE].max, 0.0, 1e-4);
    CR_CHECK_NEAR(r.summary[CR_EVAL_SSIM].min, 1.0, 1e-6);
    CR_CHECK(r.summary[CR_EVAL_CHAMFER].mean > 0.0 && r.summary[CR_EVAL_CHAMFER].mean <= 0.05);
    for (int32_t i = 0; i < g->nv; i++)
        CR_CHECK_NEAR(r.vertex_error[i], 0.05, 1e-6);
    cr_eval_result_free(&r);
    free(ref), free(pred);
    cr_mesh_destroy(g);
}

CR_TEST(eval, flat_sheet_energies_zero) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(11, 11, 0.5f, 0.5f, &g, &err) == CR_OK);
    const float y0 = 0.8f; /* m */
    for (int32_t i = 0; i < g->nv; i++)
        g->pos[3 * i + 1] = y0;
    const int T = 3;
    float *seq = repeat(g, T);
    for (int flat_rest = 0; flat_rest < 2; flat_rest++) {
        cr_eval_def def = cr_eval_default_def();
        def.ssim_side = 32;
        def.bending_rest_from_mesh = !flat_rest;
        cr_eval_input in = input(g, T, seq, seq);
        cr_eval_result r = {0};
        CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
        CR_REQUIRE(r.frames != NULL);
        CR_CHECK_NEAR(r.summary[CR_EVAL_BEN].max, 0.0, 1e-15);
        CR_CHECK_NEAR(r.summary[CR_EVAL_STE].max, 0.0, 1e-12);
        CR_CHECK_NEAR(r.summary[CR_EVAL_SHE].max, 0.0, 1e-12);
        CR_CHECK_NEAR(r.summary[CR_EVAL_E_U].max, 0.0, 1e-12);
        CR_CHECK_NEAR(r.summary[CR_EVAL_E_V].max, 0.0, 1e-12);
        CR_CHECK_NEAR(r.summary[CR_EVAL_E_UV].max, 0.0, 1e-12);
        CR_CHECK_NEAR(r.summary[CR_EVAL_H_RMS].max, 0.0, 1e-4);
        /* at rest: no acceleration; GE = M g y0 with M = density * area */
        CR_CHECK_NEAR(r.summary[CR_EVAL_IE].max, 0.0, 1e-15);
        double M = def.material.density * 0.25;
        CR_CHECK_NEAR(r.summary[CR_EVAL_GE].mean, M * 9.81 * y0, 1e-6 * M * 9.81 * y0);
        cr_eval_result_free(&r);
    }
    free(seq);
    cr_mesh_destroy(g);
}

/* A 4x4-vertex sheet (3x3 quads) folded by alpha along the grid line x = x1. */
CR_TEST(eval, folded_sheet_bed) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(4, 4, 0.3f, 0.3f, &g, &err) == CR_OK);
    float xs[4], x1;
    int nx = 0;
    for (int32_t i = 0; i < g->nv && nx < 4; i++) {
        int seen = 0;
        for (int k = 0; k < nx; k++)
            seen |= fabsf(xs[k] - g->pos[3 * i]) < 1e-6f;
        if (!seen) xs[nx++] = g->pos[3 * i];
    }
    CR_REQUIRE(nx == 4);
    for (int a = 0; a < 4; a++)
        for (int b = a + 1; b < 4; b++)
            if (xs[b] < xs[a]) {
                float t = xs[a];
                xs[a] = xs[b], xs[b] = t;
            }
    x1 = xs[1];
    const double alpha = 0.5; /* rad */
    float *ref = repeat(g, 2), *pred = repeat(g, 2);
    for (int t = 0; t < 2; t++)
        for (int32_t i = 0; i < g->nv; i++) {
            float *p = &ref[((size_t)t * g->nv + i) * 3];
            double u = p[0] - x1;
            if (u <= 0.0) continue;
            p[0] = (float)(x1 + u * cos(alpha));
            p[1] = (float)(u * sin(alpha));
        }
    cr_topology *topo = NULL;
    CR_REQUIRE(cr_topology_build(g, &topo, &err) == CR_OK);
    const int32_t H = topo->nh;
    CR_CHECK(H == 21);
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_input in = input(g, 2, pred, ref);
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    CR_CHECK(r.nhinges == H && r.nbed_hinges == 3 && !r.bed_from_rest);
    CR_CHECK_NEAR(r.summary[CR_EVAL_BED].mean, alpha, 1e-5);
    CR_CHECK_NEAR(r.summary[CR_EVAL_BE].mean, alpha * 3.0 / H, 1e-5);
    /* the flat prediction has no bending energy; the folded reference would */
    CR_CHECK_NEAR(r.summary[CR_EVAL_BEN].max, 0.0, 1e-15);
    /* PE: the reference's plastic rest angles are its fold, the prediction has none */
    float *rest = calloc((size_t)H, sizeof(float));
    for (int32_t h = 0; h < H; h++) {
        const int32_t *x = &topo->hinge[4 * h];
        rest[h] = cr_dihedral_angle(&ref[3 * x[0]], &ref[3 * x[1]], &ref[3 * x[2]], &ref[3 * x[3]]);
    }
    in.ref_rest = rest, in.ref_rest_nframes = 1;
    cr_eval_result_free(&r);
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    CR_CHECK(r.bed_from_rest && r.nbed_hinges == 3);
    CR_CHECK_NEAR(r.summary[CR_EVAL_PE].mean, alpha * 3.0 / H, 1e-5);
    CR_CHECK_NEAR(r.summary[CR_EVAL_BED].mean, alpha, 1e-5);
    /* the prediction with the same rest angles: no plastic error, and its energy is the
     * energy of a flat sheet held away from a folded rest: k_e/2 alpha^2 on three hinges */
    in.pred_rest = rest, in.pred_rest_nframes = 1;
    cr_eval_result_free(&r);
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    CR_CHECK_NEAR(r.summary[CR_EVAL_PE].max, 0.0, 1e-9);
    CR_CHECK(r.summary[CR_EVAL_BEN].mean > 0.0);
    /* rest angles of the wrong shape */
    in.pred_rest_nframes = 5;
    cr_eval_result_free(&r);
    CR_CHECK(cr_eval_run(&def, &in, &r, &err) == CR_ERR_SHAPE);
    CR_CHECK(r.frames == NULL);
    free(rest), free(ref), free(pred);
    cr_topology_destroy(topo);
    cr_mesh_destroy(g);
}

/* g held still for 2 frames, as its own prediction and reference, on a
 * static body: 1 with *r filled, 0 (and a failed check) if the run fails. */
static int eval_at_rest_on(const cr_mesh *g, const cr_mesh *body, cr_eval_result *r) {
    cr_error err = {0};
    float *seq = repeat(g, 2), *bseq = repeat(body, 2);
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_input in = input(g, 2, seq, seq);
    in.body_mesh = body, in.body = bseq, in.body_nframes = 2;
    CR_CHECK_OK(cr_eval_run(&def, &in, r, &err), &err);
    free(seq), free(bseq);
    return r->frames != NULL;
}

CR_TEST(eval, cloth_inside_sphere) {
    cr_error err = {0};
    cr_mesh *body = NULL;
    const float R = 0.3f;
    CR_REQUIRE(cr_prim_icosphere(R, 4, &body, &err) == CR_OK);
    const float depth[2] = {0.01f, -0.02f}; /* 1 cm inside; 2 cm outside */
    for (int k = 0; k < 2; k++) {
        cr_mesh *g = NULL;
        CR_REQUIRE(cr_mesh_clone(body, &g, &err) == CR_OK);
        for (int64_t i = 0; i < 3 * (int64_t)g->nv; i++)
            g->pos[i] *= (R - depth[k]) / R;
        cr_eval_result r = {0};
        CR_REQUIRE(eval_at_rest_on(g, body, &r));
        double want = k == 0 ? 0.01 : 0.0;
        CR_CHECK_NEAR(r.summary[CR_EVAL_COL].mean, want, 1e-4);
        CR_CHECK_NEAR(r.summary[CR_EVAL_COL_MAX].max, want, 1e-4);
        CR_CHECK_NEAR(r.summary[CR_EVAL_COLLISION_RATIO].mean, k == 0 ? 1.0 : 0.0, 1e-12);
        cr_eval_result_free(&r);
        cr_mesh_destroy(g);
    }
    cr_mesh_destroy(body);
}

/* A coarse sphere just outside a fine one: every vertex outside, every face's
 * centroid inside by its chord's sag: R - |centroid|, less the fine sphere's
 * own sag under the point (its faces are 2 cm across: under 0.5 mm). */
CR_TEST(eval, coarse_faces_inside_a_sphere) {
    cr_error err = {0};
    cr_mesh *body = NULL, *g = NULL;
    const float R = 0.3f;
    CR_REQUIRE(cr_prim_icosphere(R, 4, &body, &err) == CR_OK);
    CR_REQUIRE(cr_prim_icosphere(R + 0.001f, 1, &g, &err) == CR_OK);
    double want = 0.0;
    for (int32_t f = 0; f < g->nf; f++) {
        double c[3] = {0.0, 0.0, 0.0};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                c[d] += g->pos[3 * g->tri[3 * f + k] + d] / 3.0;
        const double depth = R - sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        if (depth > want) want = depth;
    }
    CR_REQUIRE(want > 0.01);
    cr_eval_result r = {0};
    CR_REQUIRE(eval_at_rest_on(g, body, &r));
    CR_CHECK_NEAR(r.summary[CR_EVAL_COL_MAX].max, 0.0, 1e-12);
    CR_CHECK(r.summary[CR_EVAL_COL_FACE_MAX].max <= want);
    CR_CHECK(r.summary[CR_EVAL_COL_FACE_MAX].max > want - 5e-4);
    cr_eval_result_free(&r);
    cr_mesh_destroy(g);
    cr_mesh_destroy(body);
}

CR_TEST(eval, inertia_constant_acceleration) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(6, 6, 0.5f, 0.5f, &g, &err) == CR_OK);
    const int T = 5;
    const double h = 1.0 / 30.0, a = -2.0, v = 0.3; /* s, m/s^2, m/s */
    float *lin = repeat(g, T), *acc = repeat(g, T);
    for (int t = 0; t < T; t++)
        for (int32_t i = 0; i < g->nv; i++) {
            lin[((size_t)t * g->nv + i) * 3] += (float)(v * t * h);
            acc[((size_t)t * g->nv + i) * 3 + 1] += (float)(0.5 * a * (t * h) * (t * h));
        }
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_result r = {0};
    cr_eval_input in = input(g, T, lin, lin);
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    CR_CHECK_NEAR(r.summary[CR_EVAL_IE].max, 0.0, 1e-9);
    CR_CHECK_NEAR(r.summary[CR_EVAL_JITTER].max, 0.0, 1e-7);
    cr_eval_result_free(&r);
    in = input(g, T, acc, acc);
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.frames != NULL);
    double M = def.material.density * 0.25, want = 0.5 * M * a * a * h * h;
    CR_CHECK_NEAR(r.summary[CR_EVAL_IE].mean, want, 1e-3 * want);
    CR_CHECK_NEAR(r.summary[CR_EVAL_JITTER].mean, fabs(a) * h * h, 1e-3 * fabs(a) * h * h);
    cr_eval_result_free(&r);
    free(lin), free(acc);
    cr_mesh_destroy(g);
}

CR_TEST(eval, ssim) {
    cr_error err = {0};
    enum { W = 40, Hh = 30 };
    float *a = malloc(W * Hh * 3 * sizeof(float)), *b = malloc(W * Hh * 3 * sizeof(float));
    for (int i = 0; i < W * Hh * 3; i++)
        a[i] = b[i] = 0.5f + 0.4f * sinf(0.37f * i);
    double s = 0.0;
    CR_CHECK_OK(cr_eval_ssim(a, b, NULL, W, Hh, 3, 1.0f, &s, &err), &err);
    CR_CHECK_NEAR(s, 1.0, 1e-12);
    for (int i = 0; i < W * Hh * 3; i++)
        b[i] = 0.5f + 0.4f * sinf(0.37f * i + 1.3f);
    CR_CHECK_OK(cr_eval_ssim(a, b, NULL, W, Hh, 3, 1.0f, &s, &err), &err);
    CR_CHECK(s < 0.9 && s > -1.0);
    CR_CHECK(cr_eval_ssim(a, b, NULL, 0, Hh, 3, 1.0f, &s, &err) == CR_ERR_INVALID);
    free(a), free(b);
}

CR_TEST(eval, bad_input_named) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(5, 5, 0.3f, 0.3f, &g, &err) == CR_OK);
    float *p = repeat(g, 3), *q = repeat(g, 3);
    q[(size_t)(2 * g->nv + 7) * 3 + 1] = NAN;
    cr_eval_def def = cr_eval_default_def();
    cr_eval_input in = input(g, 3, p, q);
    in.ref_name = "ref.pc2";
    cr_eval_result r = {0};
    CR_CHECK(cr_eval_run(&def, &in, &r, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "ref.pc2") && strstr(err.msg, "frame 2") &&
             strstr(err.msg, "vertex 7"));
    def.bed_fraction = 0.0f;
    in.ref = p;
    CR_CHECK(cr_eval_run(&def, &in, &r, &err) == CR_ERR_INVALID);
    free(p), free(q);
    cr_mesh_destroy(g);
}

CR_TEST(eval, top_hinges) {
    const double score[10] = {0.1, 0.9, 0.3, 0.9, 0.0, 0.5, 0.2, 0.8, 0.4, 0.6};
    int32_t sel[10];
    CR_CHECK(cr_eval_top_hinges(score, 10, 0.1f, sel) == 1 && sel[0] == 1);
    CR_CHECK(cr_eval_top_hinges(score, 10, 0.3f, sel) == 3);
    CR_CHECK(sel[0] == 1 && sel[1] == 3 && sel[2] == 7);
    CR_CHECK(cr_eval_top_hinges(score, 10, 0.01f, sel) == 1);
    CR_CHECK(cr_eval_top_hinges(score, 10, 1.0f, sel) == 10);
}

CR_TEST(eval, plot_draws) {
    cr_error err = {0};
    double x[50], y[50];
    for (int i = 0; i < 50; i++)
        x[i] = i, y[i] = exp(-0.1 * i);
    cr_plot_series s = {.name = "decay", .x = x, .y = y, .n = 50, .rgb = {200, 30, 30}};
    cr_plot_panel p[2] = {{&s, 1, 1}, {&s, 1, 0}};
    cr_image img = {0};
    CR_CHECK_OK(cr_plot_lines(p, 2, "frame", "title", 640, 480, &img, &err), &err);
    CR_REQUIRE(img.rgb != NULL);
    int64_t red = 0;
    for (int64_t k = 0; k < (int64_t)img.width * img.height; k++)
        red += img.rgb[3 * k] == 200 && img.rgb[3 * k + 1] == 30;
    CR_CHECK(red > 200); /* two curves of ~500 px, two pixels wide */
    cr_plot_colorbar(&img, 100, 400, 300, 16, 0.0, 1.0, "m");
    cr_image_free(&img);
    CR_CHECK(cr_plot_lines(p, 0, NULL, NULL, 640, 480, &img, &err) == CR_ERR_INVALID);
}

/* The spectrum's power on a known field: a sheet with a 5 cm sine wave of
 * amplitude a has mean curvature H = z''/2 (small slopes), whose mean square
 * a^2 k^4 / 8 lies in the 4-8 cm band; twice the amplitude gives four times
 * the power and the same shares. */
CR_TEST(eval, spectrum_power_of_a_sine_sheet) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(161, 161, 0.4f, 0.4f, &g, &err) == CR_OK);
    const double lambda = 0.05, k = 2.0 * M_PI / lambda;
    float *flat = malloc(sizeof(float) * 3 * (size_t)g->nv);
    CR_REQUIRE(flat != NULL);
    memcpy(flat, g->pos, sizeof(float) * 3 * (size_t)g->nv);
    double share[2][CR_EVAL_H_BANDS], power[2][CR_EVAL_H_BANDS];
    for (int s = 0; s < 2; s++) {
        const double a = 0.0005 * (s + 1);
        for (int32_t i = 0; i < g->nv; i++)
            g->pos[3 * i + 1] = (float)(a * sin(k * flat[3 * i]));
        double rms;
        CR_REQUIRE(cr_eval_curvature_spectrum(g, &rms, share[s], power[s], &err) == CR_OK);
        const double expect = a * a * k * k * k * k / 8.0;
        double total = 0.0;
        for (int b = 0; b < CR_EVAL_H_BANDS; b++)
            total += power[s][b];
        fprintf(stderr, "  a %.1f mm: 4-8 cm power %.4g (1/m)^2, expected %.4g; share %.4f\n",
                a * 1e3, power[s][2], expect, share[s][2]);
        CR_CHECK(share[s][2] > 0.9);
        CR_CHECK(fabs(power[s][2] - expect) < 0.1 * expect);
        CR_CHECK_NEAR(power[s][2] / total, share[s][2], 1e-9);
    }
    CR_CHECK(fabs(power[1][2] / power[0][2] - 4.0) < 0.05);
    CR_CHECK_NEAR(share[1][2], share[0][2], 0.01);
    free(flat);
    cr_mesh_destroy(g);
}
