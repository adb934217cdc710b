/* test_eval_folds.c: the fold measures a chaotic reference can be held to,
 * on hand-made cases: a fold shifted by one hinge scores near zero on the
 * tolerant and location-free measures and high on the exact ones; the
 * prediction equal to the reference scores 0 on all; retention is 1 for a
 * fold that stays and 0 for one that springs back; a sine sheet's
 * curvature power over frames lands in its band, with bands under 3 edges
 * unresolved; the hem's swing has the sine's RMS and frequency in the world
 * and none in a body moving with it; the share of a baseline's error
 * removed, the admission rule and the table. */
#include "test.h"

#include "crease/diffgeo.h"
#include "crease/eval.h"
#include "crease/primitives.h"
#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { GRID = 12 };

/* The distinct x of the plane's grid lines, sorted. */
static void grid_lines(const cr_mesh *g, float *xs) {
    int n = 0;
    for (int32_t i = 0; i < g->nv && n < GRID; i++) {
        int seen = 0;
        for (int k = 0; k < n; k++)
            seen |= fabsf(xs[k] - g->pos[3 * i]) < 1e-6f;
        if (!seen) xs[n++] = g->pos[3 * i];
    }
    for (int a = 0; a < n; a++)
        for (int b = a + 1; b < n; b++)
            if (xs[b] < xs[a]) {
                float t = xs[a];
                xs[a] = xs[b], xs[b] = t;
            }
}

/* The plane folded by alpha along the grid line at x = x0 into pos (V,3). */
static void fold(const cr_mesh *g, float x0, double alpha, float *pos) {
    memcpy(pos, g->pos, (size_t)g->nv * 3 * sizeof(float));
    for (int32_t i = 0; i < g->nv; i++) {
        float *p = &pos[3 * i];
        double u = p[0] - x0;
        if (u <= 0.0) continue;
        p[0] = (float)(x0 + u * cos(alpha));
        p[1] = (float)(u * sin(alpha));
    }
}

/* Each hinge's dihedral angle at positions pos (H). */
static void angles(const cr_topology *t, const float *pos, float *out) {
    for (int32_t h = 0; h < t->nh; h++) {
        const int32_t *x = &t->hinge[4 * h];
        out[h] = cr_dihedral_angle(&pos[3 * x[0]], &pos[3 * x[1]], &pos[3 * x[2]], &pos[3 * x[3]]);
    }
}

CR_TEST(eval_folds, fold_shifted_by_one_hinge_is_forgiven_by_the_tolerant_measures) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(GRID, GRID, 0.3f, 0.3f, &g, &err) == CR_OK);
    float xs[GRID];
    grid_lines(g, xs);
    cr_topology *topo = NULL;
    CR_REQUIRE(cr_topology_build(g, &topo, &err) == CR_OK);
    const int32_t V = g->nv, H = topo->nh;
    const double alpha = 0.5;
    float *ref = malloc(sizeof(float) * 3 * V), *pred = malloc(sizeof(float) * 3 * V);
    float *rest_r = malloc(sizeof(float) * H), *rest_p = malloc(sizeof(float) * H);
    CR_REQUIRE(ref && pred && rest_r && rest_p);
    fold(g, xs[5], alpha, ref);
    fold(g, xs[6], alpha, pred);
    angles(topo, ref, rest_r);
    angles(topo, pred, rest_p);
    int32_t nfold = 0;
    for (int32_t h = 0; h < H; h++)
        nfold += fabsf(rest_r[h]) > 0.25f;
    CR_CHECK(nfold == GRID - 1);
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    def.bed_fraction = (float)nfold / H; /* BED's hinges: exactly the reference's fold */
    for (int same = 1; same >= 0; same--) {
        cr_eval_input in = {.garment = g,
                            .nframes = 1,
                            .pred = same ? ref : pred,
                            .ref = ref,
                            .ref_rest = rest_r,
                            .ref_rest_nframes = 1,
                            .pred_rest = same ? rest_r : rest_p,
                            .pred_rest_nframes = 1};
        cr_eval_result r = {0};
        CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
        CR_REQUIRE(r.frames != NULL);
        CR_CHECK(r.nbed_hinges == nfold);
        const double bed = r.summary[CR_EVAL_BED].mean, pe = r.summary[CR_EVAL_PE].mean;
        const double bed_ring = r.summary[CR_EVAL_BED_RING].mean;
        const double pe_ring = r.summary[CR_EVAL_PE_RING].mean;
        fprintf(stderr, "  %s: BED %.4f ring %.2g sorted %.2g; PE %.4f ring %.2g sorted %.2g rad\n",
                same ? "itself" : "shifted", bed, bed_ring, r.summary[CR_EVAL_BED_SORTED].mean, pe,
                pe_ring, r.summary[CR_EVAL_PE_SORTED].mean);
        if (same) {
            /* the tolerant measures equal the exact ones: all 0 */
            CR_CHECK(bed == 0.0 && bed_ring == 0.0 && pe == 0.0 && pe_ring == 0.0);
            CR_CHECK(r.summary[CR_EVAL_BED_SORTED].mean == 0.0);
            CR_CHECK(r.summary[CR_EVAL_PE_SORTED].mean == 0.0);
        } else {
            /* exact: the whole fold missed, and a spurious one beside it */
            CR_CHECK_NEAR(bed, alpha, 1e-4);
            CR_CHECK_NEAR(pe, 2.0 * alpha * nfold / H, 1e-4);
            /* tolerant and sorted: found one hinge over */
            CR_CHECK(bed_ring < 1e-4 && pe_ring < 1e-4);
            CR_CHECK(r.summary[CR_EVAL_BED_SORTED].mean < 1e-4);
            CR_CHECK(r.summary[CR_EVAL_PE_SORTED].mean < 1e-4);
        }
        /* RB = 0 against the same reference, and the fold shares */
        CR_CHECK_NEAR(r.summary[CR_EVAL_PE_RB0].mean, alpha * nfold / H, 1e-4);
        CR_CHECK(r.summary[CR_EVAL_PE_RING_RB0].mean > 0.4 * alpha * nfold / H);
        CR_CHECK_NEAR(r.summary[CR_EVAL_FOLD_SHARE].mean, (double)nfold / H, 1e-9);
        CR_CHECK_NEAR(r.summary[CR_EVAL_FOLD_SHARE_REF].mean, (double)nfold / H, 1e-9);
        cr_eval_result_free(&r);
    }
    /* a wider ring also forgives a shift by three lines; the first does not */
    fold(g, xs[8], alpha, pred);
    cr_eval_input in = {.garment = g, .nframes = 1, .pred = pred, .ref = ref};
    double ring_bed[2];
    for (int ring = 1; ring <= 2; ring++) {
        def.ring = ring;
        cr_eval_result r = {0};
        CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
        ring_bed[ring - 1] = r.summary[CR_EVAL_BED_RING].mean;
        cr_eval_result_free(&r);
    }
    fprintf(stderr, "  shifted by three lines: ring 1 %.3g, ring 2 %.3g rad\n", ring_bed[0],
            ring_bed[1]);
    CR_CHECK(ring_bed[0] > 0.4 * alpha && ring_bed[1] < 0.1 * alpha);
    def.ring = 9;
    cr_eval_result r = {0};
    CR_CHECK(cr_eval_run(&def, &in, &r, &err) == CR_ERR_INVALID && strstr(err.msg, "ring"));
    free(ref), free(pred), free(rest_r), free(rest_p);
    cr_topology_destroy(topo);
    cr_mesh_destroy(g);
}

CR_TEST(eval_folds, retention_is_one_for_a_fold_that_stays_and_zero_for_one_that_springs_back) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(GRID, GRID, 0.3f, 0.3f, &g, &err) == CR_OK);
    float xs[GRID];
    grid_lines(g, xs);
    const int T = 4;
    const size_t V3 = (size_t)g->nv * 3;
    float *stays = malloc(sizeof(float) * V3 * T), *back = malloc(sizeof(float) * V3 * T);
    CR_REQUIRE(stays && back);
    const double a_stays[4] = {0.0, 0.3, 0.6, 0.6}, a_back[4] = {0.0, 0.6, 0.6, 0.0};
    for (int t = 0; t < T; t++) {
        fold(g, xs[5], a_stays[t], stays + t * V3);
        fold(g, xs[5], a_back[t], back + t * V3);
    }
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_input in = {.garment = g, .nframes = T, .pred = stays, .ref = back};
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_CHECK_NEAR(r.retention_pred, 1.0, 1e-12);
    CR_CHECK_NEAR(r.retention_ref, 0.0, 1e-12);
    CR_CHECK(r.ring == 1 && fabs(r.fold_threshold_rad - 0.1) < 1e-6);
    cr_eval_result_free(&r);
    /* a flat sheet never folds: retention undefined */
    for (int t = 0; t < T; t++)
        fold(g, xs[5], 0.0, back + t * V3);
    in.pred = back;
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_CHECK(isnan(r.retention_pred) && isnan(r.retention_ref));
    cr_eval_result_free(&r);
    free(stays), free(back);
    cr_mesh_destroy(g);
}

/* A 0.4 m sheet of 81 x 81 vertices (edges 5-7 mm) rippled by a 5 cm sine:
 * the power over frames lands in the 4-8 cm band, twice the amplitude gives
 * four times the power, and the < 2 cm band (under 3 edges) is unresolved. */
CR_TEST(eval_folds, band_power_over_frames_lands_in_its_band_and_marks_unresolved_bands) {
    cr_error err = {0};
    cr_mesh *g = NULL;
    CR_REQUIRE(cr_prim_plane(81, 81, 0.4f, 0.4f, &g, &err) == CR_OK);
    const int T = 3;
    const double k = 2.0 * M_PI / 0.05;
    const size_t V3 = (size_t)g->nv * 3;
    float *ref = malloc(sizeof(float) * V3 * T), *pred = malloc(sizeof(float) * V3 * T);
    CR_REQUIRE(ref && pred);
    double expect = 0.0;
    for (int t = 0; t < T; t++) {
        const double a = 0.0002 * (t + 1);
        expect += a * a * k * k * k * k / 8.0 / T;
        for (int32_t i = 0; i < g->nv; i++)
            for (int d = 0; d < 3; d++) {
                float x = g->pos[3 * i + d];
                if (d == 1) x = (float)(a * sin(k * g->pos[3 * i]));
                ref[t * V3 + 3 * i + d] = x;
                pred[t * V3 + 3 * i + d] = d == 1 ? 2.0f * x : x;
            }
    }
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_input in = {.garment = g, .nframes = T, .pred = pred, .ref = ref};
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.has_band_power);
    fprintf(stderr, "  4-8 cm power over frames %.4g (1/m)^2, expected about %.4g; edge %.4g m\n",
            r.band_power_ref[2], expect, r.mean_edge_m);
    CR_CHECK(r.band_frames == T);
    CR_CHECK(fabs(r.band_power_ref[2] - expect) < 0.15 * expect);
    CR_CHECK(fabs(r.band_power_pred[2] / r.band_power_ref[2] - 4.0) < 0.05);
    for (int b = 0; b < CR_EVAL_H_BANDS; b++)
        if (b != 2) CR_CHECK(r.band_power_ref[b] < 0.1 * r.band_power_ref[2]);
    CR_CHECK(r.mean_edge_m > 0.0049 && r.mean_edge_m < 0.0071);
    CR_CHECK(r.band_resolved[0] && r.band_resolved[1] && r.band_resolved[2] && r.band_resolved[3] &&
             !r.band_resolved[4]);
    cr_eval_result_free(&r);
    /* more edges per wavelength asked: the 2-4 cm band (2.8 cm) spans under 6 */
    def.resolve_edges = 6.0f;
    def.band_every = 2;
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_CHECK(r.band_resolved[2] && !r.band_resolved[3] && r.band_frames == 2);
    char *json = cr_eval_summary_json(&r);
    CR_REQUIRE(json != NULL);
    CR_CHECK(strstr(json, "\"band_power\"") &&
             strstr(json, "\"resolved\":[true,true,true,false,false]"));
    CR_CHECK(strstr(json, "\"spectrum\"") && strstr(json, "\"folds\""));
    free(json);
    cr_eval_result_free(&r);
    free(ref), free(pred);
    cr_mesh_destroy(g);
}

/* A sheet swinging sideways by A sin(2 pi t / 30) at 30 fps over 60 frames:
 * the hem (its border) moves with RMS A / sqrt(2) at 1 Hz in the world; in the
 * frame of a body moving with it, not at all. */
CR_TEST(eval_folds, hem_swing_in_the_world_and_in_the_bodys_frame) {
    cr_error err = {0};
    cr_mesh *g = NULL, *body = NULL;
    CR_REQUIRE(cr_prim_plane(8, 8, 0.3f, 0.3f, &g, &err) == CR_OK);
    CR_REQUIRE(cr_prim_icosphere(0.1f, 1, &body, &err) == CR_OK);
    const int T = 60;
    const double A = 0.02;
    const size_t V3 = (size_t)g->nv * 3, B3 = (size_t)body->nv * 3;
    float *pred = malloc(sizeof(float) * V3 * T), *ref = malloc(sizeof(float) * V3 * T);
    float *bpos = malloc(sizeof(float) * B3 * T);
    CR_REQUIRE(pred && ref && bpos);
    for (int t = 0; t < T; t++) {
        const double dx = A * sin(2.0 * M_PI * t / 30.0);
        for (size_t k = 0; k < V3; k++) {
            pred[t * V3 + k] = g->pos[k] + (k % 3 == 0 ? (float)dx : 0.0f);
            ref[t * V3 + k] = g->pos[k] + (k % 3 == 0 ? (float)(2.0 * dx) : 0.0f);
        }
        for (size_t k = 0; k < B3; k++)
            bpos[t * B3 + k] = body->pos[k] + (k % 3 == 0 ? (float)dx : 0.0f);
    }
    cr_eval_def def = cr_eval_default_def();
    def.ssim_side = 32;
    cr_eval_input in = {.garment = g, .nframes = T, .pred = pred, .ref = ref};
    cr_eval_result r = {0};
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_REQUIRE(r.has_hem);
    CR_CHECK(!r.hem_in_body_frame && r.hem_vertices == 28);
    CR_CHECK_NEAR(r.hem_amplitude_pred_m, A / sqrt(2.0), 1e-5);
    CR_CHECK_NEAR(r.hem_amplitude_ref_m, 2.0 * A / sqrt(2.0), 1e-5);
    CR_CHECK_NEAR(r.hem_frequency_pred_hz, 1.0, 1e-9);
    CR_CHECK_NEAR(r.hem_frequency_ref_hz, 1.0, 1e-9);
    cr_eval_result_free(&r);
    in.body_mesh = body, in.body = bpos, in.body_nframes = T;
    CR_CHECK_OK(cr_eval_run(&def, &in, &r, &err), &err);
    CR_CHECK(r.has_hem && r.hem_in_body_frame);
    CR_CHECK(r.hem_amplitude_pred_m < 1e-5);
    CR_CHECK_NEAR(r.hem_amplitude_ref_m, A / sqrt(2.0), 1e-5);
    cr_eval_result_free(&r);
    free(pred), free(ref), free(bpos);
    cr_mesh_destroy(g), cr_mesh_destroy(body);
}

/* A result with only the summary means (and one frame) set. */
static cr_eval_result fake(double med, double ssim, double pe_ring, double rb0_ring, double rb0) {
    cr_eval_result r = {0};
    r.nframes = 1;
    r.frames = calloc(CR_EVAL_METRIC_COUNT, sizeof(double));
    for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++)
        r.summary[k].mean = NAN, r.frames[k] = NAN;
    r.summary[CR_EVAL_MED] = (cr_eval_summary){.mean = med, .count = 1};
    r.summary[CR_EVAL_SSIM] = (cr_eval_summary){.mean = ssim, .count = 1};
    r.summary[CR_EVAL_STE] = (cr_eval_summary){.mean = 1.0, .count = 1};
    r.summary[CR_EVAL_PE_RING].mean = pe_ring;
    r.summary[CR_EVAL_PE_RING_RB0].mean = rb0_ring;
    r.frames[CR_EVAL_PE_RB0] = rb0;
    r.retention_pred = NAN, r.retention_ref = NAN;
    return r;
}

CR_TEST(eval_folds, share_removed_admission_and_table) {
    cr_eval_result base = fake(0.05, 0.80, NAN, NAN, NAN);
    cr_eval_result p[2] = {fake(0.02, 0.90, NAN, NAN, NAN), fake(0.03, 0.85, NAN, NAN, NAN)};
    CR_CHECK_NEAR(cr_eval_removed(&p[0], &base, CR_EVAL_MED), 0.6, 1e-12);
    CR_CHECK_NEAR(cr_eval_removed(&p[0], &base, CR_EVAL_SSIM), 0.5, 1e-12); /* 1 - 0.1 / 0.2 */
    CR_CHECK(isnan(cr_eval_removed(&p[0], &base, CR_EVAL_STE)));            /* not an error */
    CR_CHECK(isnan(cr_eval_removed(&p[0], &base, CR_EVAL_BED)));            /* undefined */
    cr_eval_def def = cr_eval_default_def();
    cr_eval_admission a;
    cr_eval_result twin = fake(0.01, 0.95, 0.03, 0.05, 0.04);
    cr_eval_admit(&def, &twin, 1, &a);
    CR_CHECK(a.defined && a.admitted && a.twin_tested);
    twin.summary[CR_EVAL_PE_RING].mean = 0.04; /* 0.8 x RB = 0's */
    cr_eval_admit(&def, &twin, 1, &a);
    CR_CHECK(a.defined && !a.admitted && strstr(a.reason, "chaotic"));
    cr_eval_admit(&def, &twin, 0, &a); /* no twin: plastic bending alone */
    CR_CHECK(a.admitted && !a.twin_tested && strstr(a.reason, "no twin"));
    twin.frames[CR_EVAL_PE_RB0] = 0.01;
    cr_eval_admit(&def, &twin, 1, &a);
    CR_CHECK(!a.admitted && strstr(a.reason, "too little plasticity"));
    twin.frames[CR_EVAL_PE_RB0] = NAN;
    cr_eval_admit(&def, &twin, 1, &a);
    CR_CHECK(!a.defined && !a.admitted);
    /* the table: mean and spread over the two seeds, the twin, the baseline */
    cr_eval_table t = {.preds = p, .npreds = 2, .twin = &twin, .baseline = &base};
    char *json = cr_eval_table_json(&t), *md = cr_eval_table_text(&t);
    CR_REQUIRE(json && md);
    fprintf(stderr, "%s", md);
    CR_CHECK(strstr(json, "\"seeds\":{\"n\":2") && strstr(json, "\"med_m\":{\"mean\":0.025"));
    CR_CHECK(strstr(json, "\"twin\"") && strstr(json, "\"removed\"") &&
             strstr(json, "\"twin_removed\""));
    CR_CHECK(strstr(md, "| prediction (2 seeds) | 0.025 +- 0.0071 |") != NULL);
    CR_CHECK(strstr(md, "| share of the baseline's error removed | 0.500 +- 0.14 |") != NULL);
    free(json), free(md);
    cr_eval_result_free(&base), cr_eval_result_free(&p[0]), cr_eval_result_free(&p[1]);
    cr_eval_result_free(&twin);
}
