/* test_drape_sampling.c: the drape method's adaptive sampler.
 *
 * The PDF update against Eq. 7 worked by hand; drawn points against the
 * densities they should follow (a loss field high in one half, a Gaussian
 * bump), before and after Lloyd relaxation; relaxation against the spread of
 * nearest-neighbour distances (brute force); masks (a disc and an annulus,
 * which is not convex); determinism over seeds and thread counts; refusal of
 * bad input; the heat-map PNG read back pixel by pixel; the bucket-grid
 * nearest-sample queries behind the Voronoi regions against brute force;
 * and the time of a 20k-point draw (printed).
 */
#include "crease/drape_sampling.h"
#include "crease/render.h"
#include "methods/drape/sampling_lloyd.h"
#include "test.h"

#include <png.h>
#include <stdlib.h>
#include <string.h>

static cr_drape_sampler *make(cr_drape_sampler_def d) {
    cr_error err = {0};
    cr_drape_sampler *s = NULL;
    CR_CHECK_OK(cr_drape_sampler_create(&d, &s, &err), &err);
    return s;
}

static int cell_of(float x, int G) {
    int k = (int)(x * (float)G);
    return k < 0 ? 0 : (k >= G ? G - 1 : k);
}

/* Draw n points with the given rng seed into a new buffer. */
static float *draw(cr_drape_sampler *s, int32_t n, uint64_t seed) {
    cr_error err = {0};
    float *uv = malloc((size_t)n * 2 * sizeof(float));
    if (!uv) return NULL;
    cr_rng rng = cr_rng_make(seed, 0);
    cr_status st = cr_drape_sampler_draw(s, n, &rng, uv, &err);
    CR_CHECK_OK(st, &err);
    if (st != CR_OK) {
        free(uv);
        return NULL;
    }
    return uv;
}

/* Coefficient of variation (std / mean) of each point's distance to its
 * nearest neighbour, brute force, over the points whose u lies in [u0, u1]
 * (neighbours may lie anywhere). */
static double nn_cv(const float *uv, int32_t n, float u0, float u1) {
    double s = 0.0, s2 = 0.0;
    int count = 0;
    for (int32_t i = 0; i < n; i++) {
        if (uv[2 * i] < u0 || uv[2 * i] > u1) continue;
        double best = INFINITY;
        for (int32_t j = 0; j < n; j++) {
            if (j == i) continue;
            double dx = uv[2 * i] - uv[2 * j], dy = uv[2 * i + 1] - uv[2 * j + 1];
            double d2 = dx * dx + dy * dy;
            if (d2 < best) best = d2;
        }
        double d = sqrt(best);
        s += d, s2 += d * d, count++;
    }
    double mean = s / count;
    return sqrt(s2 / count - mean * mean) / mean;
}

static double fraction_in(const float *uv, int32_t n, float u0, float u1, float v0, float v1) {
    int32_t in = 0;
    for (int32_t k = 0; k < n; k++)
        in += uv[2 * k] >= u0 && uv[2 * k] < u1 && uv[2 * k + 1] >= v0 && uv[2 * k + 1] < v1;
    return (double)in / n;
}

CR_TEST(drape_sampling, defaults_and_cells) {
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    CR_CHECK(d.grid == 64 && d.mu == 0.5f && d.lloyd_iterations == 3 && d.lloyd_density == 16);
    CR_CHECK(d.gamma == 0.9f && d.lloyd_exponent == 2.0f && d.mask == NULL);
    d.grid = 4;
    cr_drape_sampler *s = make(d);
    CR_REQUIRE(s);
    CR_CHECK(cr_drape_sampler_grid(s) == 4);
    const float *c = cr_drape_sampler_cell_centres(s);
    const float *p = cr_drape_sampler_pdf(s);
    /* Cell (i=2, j=1) is index 9: u in [0.25, 0.5), v in [0.5, 0.75). */
    CR_CHECK_NEAR(c[2 * 9], 0.375, 1e-7);
    CR_CHECK_NEAR(c[2 * 9 + 1], 0.625, 1e-7);
    for (int k = 0; k < 16; k++)
        CR_CHECK_NEAR(p[k], 1.0 / 16, 1e-8); /* Algorithm 1 starts uniform */
    cr_drape_sampler_destroy(s);
    cr_drape_sampler_destroy(NULL);
}

CR_TEST(drape_sampling, update_matches_eq7) {
    cr_error err = {0};
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.grid = 3;
    d.gamma = 0.7f;
    cr_drape_sampler *s = make(d);
    CR_REQUIRE(s);
    const float *p = cr_drape_sampler_pdf(s);

    /* p_hat = l / 36; p' = 0.7 / 9 + 0.3 l / 36 = 7/90 + l/120. */
    float l1[9] = {0, 1, 2, 3, 4, 5, 6, 7, 8};
    CR_CHECK_OK(cr_drape_sampler_update(s, l1, &err), &err);
    for (int c = 0; c < 9; c++)
        CR_CHECK_NEAR(p[c], 7.0 / 90.0 + c / 120.0, 1e-7);
    CR_CHECK_NEAR(p[0], 0.0777778, 1e-7);
    CR_CHECK_NEAR(p[8], 0.1444444, 1e-7);

    /* All the loss in cell 4: p'' = 0.7 p' + 0.3 [c == 4]. */
    float l2[9] = {0, 0, 0, 0, 2.5f, 0, 0, 0, 0};
    CR_CHECK_OK(cr_drape_sampler_update(s, l2, &err), &err);
    double sum = 0.0;
    for (int c = 0; c < 9; c++) {
        CR_CHECK_NEAR(p[c], 0.7 * (7.0 / 90.0 + c / 120.0) + (c == 4 ? 0.3 : 0.0), 1e-7);
        sum += p[c];
    }
    CR_CHECK_NEAR(sum, 1.0, 1e-6);

    /* A field that is zero everywhere carries no information: no change. */
    float before[9], zero[9] = {0};
    memcpy(before, p, sizeof before);
    CR_CHECK_OK(cr_drape_sampler_update(s, zero, &err), &err);
    CR_CHECK(memcmp(before, p, sizeof before) == 0);
    cr_drape_sampler_destroy(s);

    /* With a mask: 7 cells inside, p starts at 1/7 there and 0 outside; cells
     * outside are not read (NaN there is fine) and stay 0. */
    uint8_t mask[9] = {1, 1, 1, 1, 0, 1, 1, 1, 0};
    d.mask = mask;
    d.gamma = 0.25f;
    s = make(d);
    CR_REQUIRE(s);
    p = cr_drape_sampler_pdf(s);
    for (int c = 0; c < 9; c++)
        CR_CHECK_NEAR(p[c], mask[c] ? 1.0 / 7.0 : 0.0, 1e-8);
    float l3[9] = {1, 2, 3, 4, NAN, 6, 7, 8, -1};
    CR_CHECK_OK(cr_drape_sampler_update(s, l3, &err), &err);
    for (int c = 0; c < 9; c++)
        CR_CHECK_NEAR(p[c], mask[c] ? 0.25 / 7.0 + 0.75 * l3[c] / 31.0 : 0.0, 1e-7);
    cr_drape_sampler_destroy(s);
}

CR_TEST(drape_sampling, set_pdf_restores) {
    cr_error err = {0};
    uint8_t mask[9] = {1, 1, 1, 1, 0, 1, 1, 1, 1};
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.grid = 3;
    d.mask = mask;
    cr_drape_sampler *a = make(d), *b = make(d);
    CR_REQUIRE(a && b);
    float l[9] = {5, 1, 0, 2, 0, 7, 1, 3, 9};
    for (int k = 0; k < 4; k++)
        CR_CHECK_OK(cr_drape_sampler_update(a, l, &err), &err);
    float saved[9];
    memcpy(saved, cr_drape_sampler_pdf(a), sizeof saved);
    saved[4] = NAN; /* outside the mask: not read */
    CR_CHECK_OK(cr_drape_sampler_set_pdf(b, saved, &err), &err);
    for (int c = 0; c < 9; c++)
        CR_CHECK_NEAR(cr_drape_sampler_pdf(b)[c], cr_drape_sampler_pdf(a)[c], 1e-7);
    /* Any scale: it is rescaled to sum 1. */
    float twice[9];
    for (int c = 0; c < 9; c++)
        twice[c] = 2.0f * l[c];
    CR_CHECK_OK(cr_drape_sampler_set_pdf(b, twice, &err), &err);
    CR_CHECK_NEAR(cr_drape_sampler_pdf(b)[8], 9.0 / 28.0, 1e-7);
    float none[9] = {0, 0, 0, 0, 5, 0, 0, 0, 0}, neg[9] = {1, 1, 1, 1, 1, 1, -1, 1, 1};
    CR_CHECK(cr_drape_sampler_set_pdf(b, none, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "pdf") != NULL && strstr(err.msg, "mass") != NULL);
    CR_CHECK(cr_drape_sampler_set_pdf(b, neg, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "pdf[6]") != NULL);
    CR_CHECK_NEAR(cr_drape_sampler_pdf(b)[8], 9.0 / 28.0, 1e-7); /* unchanged */
    cr_drape_sampler_destroy(a);
    cr_drape_sampler_destroy(b);
}

/* Loss 1 on the left half (u < 0.5), 0 on the right; gamma 0 so the PDF is
 * the normalised field at once: adaptive points all land left, uniform ones
 * half and half, so a fraction mu + (1 - mu) / 2 of the points lies left. */
CR_TEST(drape_sampling, density_follows_half_field) {
    cr_error err = {0};
    const int32_t n = 8000;
    enum { G = 16 };
    float loss[G * G];
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++)
            loss[i * G + j] = j < G / 2 ? 1.0f : 0.0f;
    const float mus[2] = {0.5f, 0.0f};
    for (int t = 0; t < 2; t++) {
        for (int iters = 0; iters <= 3; iters += 3) {
            cr_drape_sampler_def d = cr_drape_sampler_default_def();
            d.grid = G;
            d.gamma = 0.0f;
            d.mu = mus[t];
            d.lloyd_iterations = iters;
            cr_drape_sampler *s = make(d);
            CR_REQUIRE(s);
            CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
            float *uv = draw(s, n, 11);
            CR_REQUIRE(uv);
            double na = floor(mus[t] * n);
            double expect = (na + 0.5 * (n - na)) / n;
            double left = fraction_in(uv, n, 0.0f, 0.5f, 0.0f, 1.0f);
            /* The uniform half is binomial: sd = sqrt(0.25 (n - na)) / n <= 0.006. */
            CR_CHECK_NEAR(left, expect, 0.02);
            if (mus[t] > 0.0f) {
                /* Densities left : right = (mu 2 + 1 - mu) : (1 - mu) = 3 : 1. */
                double ratio = left / (1.0 - left);
                CR_CHECK(ratio > 2.6 && ratio < 3.4);
            }
            free(uv);
            cr_drape_sampler_destroy(s);
        }
    }
}

/* A Gaussian bump of loss (sd 0.1) at the centre: the share of points in the
 * central 8 x 8 cells is f P_pdf(block) + (1 - f) 64 / 1024 whatever the
 * bump's shape, since both parts are uniform within cells. */
CR_TEST(drape_sampling, density_follows_bump) {
    cr_error err = {0};
    const int32_t n = 8000;
    enum { G = 32 };
    float loss[G * G];
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            double u = (j + 0.5) / G - 0.5, v = (i + 0.5) / G - 0.5;
            loss[i * G + j] = (float)exp(-(u * u + v * v) / (2.0 * 0.01));
        }
    double results[2];
    for (int t = 0; t < 2; t++) {
        cr_drape_sampler_def d = cr_drape_sampler_default_def();
        d.grid = G;
        d.gamma = 0.0f;
        d.lloyd_iterations = t == 0 ? 0 : 3;
        cr_drape_sampler *s = make(d);
        CR_REQUIRE(s);
        CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
        const float *p = cr_drape_sampler_pdf(s);
        double block = 0.0;
        for (int i = 12; i < 20; i++)
            for (int j = 12; j < 20; j++)
                block += p[i * G + j];
        double f = floor(0.5 * n) / n;
        double expect = f * block + (1.0 - f) * 64.0 / 1024.0;
        float *uv = draw(s, n, 5);
        CR_REQUIRE(uv);
        results[t] = fraction_in(uv, n, 0.375f, 0.625f, 0.375f, 0.625f);
        /* Drawn: binomial, sd = sqrt(e (1 - e) / n) ~ 0.005. Relaxed: Lloyd
         * moves points across the block's edge a little, both ways. */
        CR_CHECK_NEAR(results[t], expect, t == 0 ? 0.02 : 0.03);
        /* Far more than the block's area (6%): the bump draws points. */
        CR_CHECK(results[t] > 0.25);
        free(uv);
        cr_drape_sampler_destroy(s);
    }
    printf("  bump block share: drawn %.4f, relaxed %.4f\n", results[0], results[1]);
}

CR_TEST(drape_sampling, lloyd_evens_spacing) {
    cr_error err = {0};
    const int32_t n = 1500;
    enum { G = 16 };
    float loss[G * G];
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++)
            loss[i * G + j] = j < G / 2 ? 1.0f : 0.0f;
    for (int field = 0; field < 2; field++) {
        for (int e = 1; e <= 2; e++) {
            double cv[2][3];
            for (int t = 0; t < 2; t++) {
                cr_drape_sampler_def d = cr_drape_sampler_default_def();
                d.grid = G;
                d.gamma = 0.0f;
                d.lloyd_exponent = (float)e;
                d.lloyd_iterations = t == 0 ? 0 : 3;
                cr_drape_sampler *s = make(d);
                CR_REQUIRE(s);
                if (field) CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
                float *uv = draw(s, n, 3);
                CR_REQUIRE(uv);
                /* Each half on its own, away from the density step. */
                cv[t][0] = nn_cv(uv, n, 0.0f, 1.0f);
                cv[t][1] = nn_cv(uv, n, 0.05f, 0.45f);
                cv[t][2] = nn_cv(uv, n, 0.55f, 0.95f);
                free(uv);
                cr_drape_sampler_destroy(s);
            }
            /* Random points: CV about 0.52; after 3 iterations about 0.2. */
            for (int r = field ? 1 : 0; r < 3; r++) {
                CR_CHECK(cv[0][r] > 0.4);
                CR_CHECK(cv[1][r] < 0.6 * cv[0][r]);
            }
            if (field == 1 && e == 2)
                printf("  nn-distance CV, left half: drawn %.3f, relaxed %.3f\n", cv[0][1],
                       cv[1][1]);
        }
    }
}

/* Masks of cells whose centre lies at radius [r0, r1] from (0.5, 0.5). */
static void ring_mask(uint8_t *mask, int G, double r0, double r1) {
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            double u = (j + 0.5) / G - 0.5, v = (i + 0.5) / G - 0.5, r = sqrt(u * u + v * v);
            mask[i * G + j] = r >= r0 && r <= r1;
        }
}

CR_TEST(drape_sampling, mask_holds_every_point) {
    cr_error err = {0};
    enum { G = 32 };
    const int32_t n = 4000;
    uint8_t mask[G * G];
    float loss[G * G];
    const double inner[2] = {0.0, 0.2}; /* a disc, then an annulus */
    for (int shape = 0; shape < 2; shape++) {
        ring_mask(mask, G, inner[shape], 0.45);
        for (int c = 0; c < G * G; c++) /* rising with u; garbage outside the mask */
            loss[c] = mask[c] ? (float)(c % G) : (c % 2 ? NAN : -5.0f);
        for (int iters = 0; iters <= 5; iters += 5) {
            cr_drape_sampler_def d = cr_drape_sampler_default_def();
            d.grid = G;
            d.mask = mask;
            d.gamma = 0.5f;
            d.lloyd_iterations = iters;
            cr_drape_sampler *s = make(d);
            CR_REQUIRE(s);
            CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
            const float *p = cr_drape_sampler_pdf(s);
            int bad_pdf = 0;
            for (int c = 0; c < G * G; c++)
                bad_pdf += !mask[c] && p[c] != 0.0f;
            CR_CHECK(bad_pdf == 0);
            float *uv = draw(s, n, 17 + shape);
            CR_REQUIRE(uv);
            int outside = 0, off_square = 0;
            for (int32_t k = 0; k < n; k++) {
                float u = uv[2 * k], v = uv[2 * k + 1];
                off_square += !(u >= 0.0f && u < 1.0f && v >= 0.0f && v < 1.0f);
                outside += !mask[cell_of(v, G) * G + cell_of(u, G)];
            }
            CR_CHECK(outside == 0);
            CR_CHECK(off_square == 0);
            free(uv);
            cr_drape_sampler_destroy(s);
        }
    }
}

CR_TEST(drape_sampling, deterministic) {
    cr_error err = {0};
    enum { G = 16 };
    const int32_t n = 3000;
    float loss[G * G];
    for (int c = 0; c < G * G; c++)
        loss[c] = (float)((c * 7919) % 13);
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.grid = G;
    cr_drape_sampler *s = make(d);
    CR_REQUIRE(s);
    CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
    int threads = cr_thread_count();
    float *a = draw(s, n, 42);
    float *b = draw(s, n, 42);
    float *c = draw(s, n, 43);
    cr_set_thread_count(1);
    float *one = draw(s, n, 42);
    cr_set_thread_count(threads);
    CR_REQUIRE(a && b && c && one);
    size_t bytes = (size_t)n * 2 * sizeof(float);
    CR_CHECK(memcmp(a, b, bytes) == 0);
    CR_CHECK(memcmp(a, one, bytes) == 0);
    CR_CHECK(memcmp(a, c, bytes) != 0);
    /* The draw takes two words from the caller's rng, no more. */
    cr_rng r1 = cr_rng_make(9, 0), r2 = cr_rng_make(9, 0);
    CR_CHECK_OK(cr_drape_sampler_draw(s, n, &r1, c, &err), &err);
    cr_rng_u32(&r2), cr_rng_u32(&r2);
    CR_CHECK(cr_rng_u32(&r1) == cr_rng_u32(&r2));
    free(a), free(b), free(c), free(one);
    cr_drape_sampler_destroy(s);
}

static void expect_create_fails(cr_drape_sampler_def d, cr_status want, const char *name) {
    cr_error err = {0};
    cr_drape_sampler *s = (cr_drape_sampler *)&err; /* must come back NULL */
    cr_status st = cr_drape_sampler_create(&d, &s, &err);
    CR_CHECK(st == want);
    CR_CHECK(s == NULL);
    if (!strstr(err.msg, name)) printf("  message without '%s': %s\n", name, err.msg);
    CR_CHECK(strstr(err.msg, name) != NULL);
}

CR_TEST(drape_sampling, bad_input) {
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.grid = 1;
    expect_create_fails(d, CR_ERR_INVALID, "grid");
    d.grid = CR_DRAPE_SAMPLER_MAX_GRID + 1;
    expect_create_fails(d, CR_ERR_INVALID, "grid");
    d = cr_drape_sampler_default_def();
    d.gamma = -0.01f;
    expect_create_fails(d, CR_ERR_INVALID, "gamma");
    d.gamma = 1.5f;
    expect_create_fails(d, CR_ERR_INVALID, "gamma");
    d.gamma = NAN;
    expect_create_fails(d, CR_ERR_NAN, "gamma");
    d = cr_drape_sampler_default_def();
    d.mu = 1.01f;
    expect_create_fails(d, CR_ERR_INVALID, "mu");
    d = cr_drape_sampler_default_def();
    d.lloyd_iterations = -1;
    expect_create_fails(d, CR_ERR_INVALID, "lloyd_iterations");
    d = cr_drape_sampler_default_def();
    d.lloyd_density = 0;
    expect_create_fails(d, CR_ERR_INVALID, "lloyd_density");
    d = cr_drape_sampler_default_def();
    d.lloyd_exponent = 5.0f;
    expect_create_fails(d, CR_ERR_INVALID, "lloyd_exponent");
    uint8_t empty[4] = {0, 0, 0, 0};
    d = cr_drape_sampler_default_def();
    d.grid = 2;
    d.mask = empty;
    expect_create_fails(d, CR_ERR_INVALID, "mask");

    /* Bad loss fields name the cell and leave the PDF as it was. */
    cr_error err = {0};
    d = cr_drape_sampler_default_def();
    d.grid = 2;
    cr_drape_sampler *s = make(d);
    CR_REQUIRE(s);
    float good[4] = {1, 2, 3, 4};
    CR_CHECK_OK(cr_drape_sampler_update(s, good, &err), &err);
    float before[4];
    memcpy(before, cr_drape_sampler_pdf(s), sizeof before);
    float nan_field[4] = {1, 2, NAN, 4}, neg_field[4] = {1, -2, 3, 4},
          inf_field[4] = {INFINITY, 0, 0, 0};
    CR_CHECK(cr_drape_sampler_update(s, nan_field, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "cell_loss[2]") != NULL);
    CR_CHECK(cr_drape_sampler_update(s, inf_field, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "cell_loss[0]") != NULL);
    CR_CHECK(cr_drape_sampler_update(s, neg_field, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "cell_loss[1]") != NULL && strstr(err.msg, "negative") != NULL);
    CR_CHECK(cr_drape_sampler_update(s, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(memcmp(before, cr_drape_sampler_pdf(s), sizeof before) == 0);

    /* Bad draws and pictures. */
    cr_rng rng = cr_rng_make(1, 0);
    float uv[8];
    CR_CHECK(cr_drape_sampler_draw(s, 0, &rng, uv, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "n = 0") != NULL);
    CR_CHECK(cr_drape_sampler_draw(s, -3, &rng, uv, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "n = -3") != NULL);
    CR_CHECK(cr_drape_sampler_draw(s, 4, &rng, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "uv_out") != NULL);
    char path[512];
    snprintf(path, sizeof path, "%s/drape_bad.png", cr_test_tmpdir());
    CR_CHECK(cr_drape_sampler_write_png(s, NULL, 0, path, 8, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "size_px") != NULL);
    float nan_uv[2] = {NAN, 0.5f};
    CR_CHECK(cr_drape_sampler_write_png(s, nan_uv, 1, path, 64, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "point 0") != NULL);
    cr_drape_sampler_destroy(s);
}

CR_TEST(drape_sampling, heat_map_png) {
    cr_error err = {0};
    /* 4 x 4 cells, cell (i=3, j=0) (top left in the picture, v up) outside
     * the mask, all loss in cell (0, 3) (bottom right) so it is the maximum. */
    uint8_t mask[16];
    for (int c = 0; c < 16; c++)
        mask[c] = c != 12;
    float loss[16] = {0};
    loss[3] = 1.0f;
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.grid = 4;
    d.mask = mask;
    d.gamma = 0.0f;
    cr_drape_sampler *s = make(d);
    CR_REQUIRE(s);
    CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
    float pts[2] = {0.5f + 1.0f / 128.0f, 0.5f + 1.0f / 128.0f}; /* pixel (32, 31) of 64 */
    char path[512];
    snprintf(path, sizeof path, "%s/drape_heat.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_drape_sampler_write_png(s, pts, 1, path, 64, &err), &err);
    cr_drape_sampler_destroy(s);

    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    CR_REQUIRE(png_image_begin_read_from_file(&pi, path) != 0);
    CR_CHECK(pi.width == 64 && pi.height == 64);
    pi.format = PNG_FORMAT_RGB;
    uint8_t *px = malloc(PNG_IMAGE_SIZE(pi));
    CR_REQUIRE(px != NULL);
    CR_CHECK(png_image_finish_read(&pi, NULL, px, 0, NULL) != 0);
    const uint8_t *white = px + 3 * (31 * 64 + 32), *masked = px + 3 * (5 * 64 + 5);
    const uint8_t *hot = px + 3 * (60 * 64 + 60), *cold = px + 3 * (60 * 64 + 5);
    CR_CHECK(white[0] == 255 && white[1] == 255 && white[2] == 255);
    CR_CHECK(masked[0] == masked[1] && masked[1] == masked[2] && masked[0] > 90 && masked[0] < 140);
    float top[3], bottom[3];
    cr_colormap_viridis(1.0f, top);
    cr_colormap_viridis(0.0f, bottom);
    for (int ch = 0; ch < 3; ch++) {
        CR_CHECK(abs(hot[ch] - (int)lrintf(top[ch] * 255.0f)) <= 1);
        CR_CHECK(abs(cold[ch] - (int)lrintf(bottom[ch] * 255.0f)) <= 1);
    }
    free(px);
}

/* One Lloyd iteration leaves the dense points and their nearest samples in
 * the scratch: check every assignment against brute force over the samples'
 * positions before the move, on a flat PDF (one bucket grid), on a bump, and
 * on PDFs piled into one cell and into an 8 x 8 block (crowded coarse
 * buckets searched through their fine ones). */
CR_TEST(drape_sampling, voronoi_queries_match_brute_force) {
    cr_error err = {0};
    enum { G = 64 };
    const int32_t n = 1500, density = 8;
    double *rho = malloc(G * G * sizeof(double));
    uint8_t *mask = malloc(G * G);
    float *uv = malloc((size_t)n * 2 * sizeof(float)),
          *before = malloc((size_t)n * 2 * sizeof(float));
    CR_REQUIRE(rho && mask && uv && before);
    memset(mask, 1, G * G);
    for (int t = 0; t < 4; t++) {
        double sum = 0.0;
        for (int i = 0; i < G; i++)
            for (int j = 0; j < G; j++) {
                double u = (j + 0.5) / G - 0.3, v = (i + 0.5) / G - 0.6, w = 1.0;
                if (t == 1) w = 0.1 + exp(-(u * u + v * v) / 0.005);
                if (t == 2) w = i == 20 && j == 40 ? 4096.0 : 1.0;
                if (t == 3) w = i >= 16 && i < 24 && j >= 40 && j < 48 ? 64.0 : 1.0;
                rho[i * G + j] = w;
                sum += w;
            }
        for (int c = 0; c < G * G; c++)
            rho[c] /= sum;
        /* Samples from rho by rejection against its maximum. */
        double top = 0.0;
        for (int c = 0; c < G * G; c++)
            top = rho[c] > top ? rho[c] : top;
        cr_rng rng = cr_rng_make(100 + t, 0);
        for (int32_t k = 0; k < n;) {
            float u = cr_rng_uniformf(&rng), v = cr_rng_uniformf(&rng);
            if (cr_rng_uniform(&rng) * top < rho[cell_of(v, G) * G + cell_of(u, G)])
                uv[2 * k] = u, uv[2 * k + 1] = v, k++;
        }
        memcpy(before, uv, (size_t)n * 2 * sizeof(float));
        drape_lloyd L;
        memset(&L, 0, sizeof L);
        CR_CHECK_OK(cr_drape_lloyd_relax(&L, uv, n, density, 1, rho, 2.0, mask, G, 77, 3, &err),
                    &err);
        int64_t m = (int64_t)n * density;
        int wrong = 0;
        for (int64_t k = 0; k < m; k++) {
            float qx = L.dense.x[k], qy = L.dense.y[k];
            float best = INFINITY;
            for (int32_t i = 0; i < n; i++) {
                float dx = qx - before[2 * i], dy = qy - before[2 * i + 1];
                float d2 = dx * dx + dy * dy;
                best = d2 < best ? d2 : best;
            }
            int32_t a = L.assign[k];
            float dx = qx - before[2 * a], dy = qy - before[2 * a + 1];
            wrong += !(a >= 0 && a < n && dx * dx + dy * dy == best);
        }
        CR_CHECK(wrong == 0);
        if (t >= 2) CR_CHECK(L.ratio > 1); /* the two-grid path ran */
        cr_drape_lloyd_free(&L);
    }
    free(rho), free(mask), free(uv), free(before);
}

/* The figure the issue asks for: 20k points with the defaults (64^2 cells, 3
 * Lloyd iterations, 16 dense points per sample) on a bumpy PDF, and on a
 * PDF piled into one cell (the worst case for the buckets). */
CR_TEST(drape_sampling, timing_20k) {
    cr_error err = {0};
    enum { G = 64 };
    const int32_t n = 20000;
    float *loss = malloc(G * G * sizeof(float));
    float *uv = malloc((size_t)n * 2 * sizeof(float));
    CR_REQUIRE(loss && uv);
    cr_drape_sampler_def d = cr_drape_sampler_default_def();
    d.gamma = 0.0f;
    const char *names[2] = {"bumps", "one cell"};
    for (int t = 0; t < 2; t++) {
        for (int i = 0; i < G; i++)
            for (int j = 0; j < G; j++) {
                double u = (j + 0.5) / G, v = (i + 0.5) / G;
                loss[i * G + j] = t == 0 ? (float)(1.0 + sin(12.0 * u) * sin(9.0 * v))
                                         : (float)(i == 20 && j == 40);
            }
        cr_drape_sampler *s = make(d);
        CR_REQUIRE(s);
        CR_CHECK_OK(cr_drape_sampler_update(s, loss, &err), &err);
        cr_rng rng = cr_rng_make(7, 0);
        /* The first draw allocates the scratch; time the second, as in training. */
        CR_CHECK_OK(cr_drape_sampler_draw(s, n, &rng, uv, &err), &err);
        double t0 = cr_time_now();
        CR_CHECK_OK(cr_drape_sampler_draw(s, n, &rng, uv, &err), &err);
        double ms = (cr_time_now() - t0) * 1e3;
        printf("  20k points, 3 Lloyd iterations, %s: %.1f ms (%d threads)\n", names[t], ms,
               cr_thread_count());
        if (t == 1) {
            /* Half the points are adaptive and all of those land in the one cell. */
            double share = fraction_in(uv, n, 40.0f / G, 41.0f / G, 20.0f / G, 21.0f / G);
            CR_CHECK(share > 0.45 && share < 0.55);
        }
        cr_drape_sampler_destroy(s);
    }
    free(loss);
    free(uv);
}
