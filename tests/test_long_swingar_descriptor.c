/* test_long_swingar_descriptor.c: the cost of swingar's spectral descriptor
 * on a 10k-vertex dress at z = 128, 256 and 512 (the paper's choices), both
 * affinities, with and without the Nystrom-extended eigenvectors; the numbers
 * docs/swingar.md reports. A measurement, so only loose checks: the result is
 * finite and sums to 1, and each call takes under a minute. Wall and CPU
 * time both print: on a shared machine the CPU time is the steadier figure.
 * sigma_study prints the table behind the default kernel width.
 */
#include "crease/body.h"
#include "crease/garment.h"
#include "methods/swingar/descriptor.h"
#include "test.h"

#include <stdlib.h>
#include <time.h>

CR_TEST(long_swingar_descriptor, timing_10k_dress) {
    cr_error err = {0};
    cr_body_model *body = NULL;
    cr_mannequin_def md = cr_mannequin_default_def();
    CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
    CR_REQUIRE(body);
    cr_garment_def gd = cr_garment_default_def(CR_GARMENT_DRESS);
    gd.target_vertices = 10000;
    cr_garment *g = NULL;
    CR_CHECK_OK(cr_garment_create(&gd, body, &g, &err), &err);
    CR_REQUIRE(g);
    const int32_t nv = g->mesh->nv;
    float *vec = malloc((size_t)nv * 512 * sizeof(float));
    CR_REQUIRE(vec);
    printf("  dress, %d vertices, %d threads\n", nv, cr_thread_count());
    const int32_t zs[3] = {128, 256, 512};
    for (int aff = 0; aff < 2; aff++)
        for (int i = 0; i < 3; i++)
            for (int with_vec = 0; with_vec < 2; with_vec++) {
                cr_swingar_descriptor_opts o = cr_swingar_descriptor_default_opts();
                o.samples = zs[i];
                o.affinity = (cr_swingar_affinity)aff;
                float lam[512];
                cr_swingar_descriptor_extra ex = {.eigenvectors = with_vec ? vec : NULL};
                double t0 = cr_time_now(), c0 = (double)clock() / CLOCKS_PER_SEC;
                CR_CHECK_OK(cr_swingar_descriptor_full(g->mesh, &o, lam, &ex, &err), &err);
                double dt = cr_time_now() - t0, sum = 0;
                double cpu = (double)clock() / CLOCKS_PER_SEC - c0;
                for (int32_t k = 0; k < zs[i]; k++)
                    sum += lam[k];
                CR_CHECK_NEAR(sum, 1.0, 1e-4);
                CR_CHECK(dt < 60);
                printf("  %-9s z = %3d%-10s: %.3f s wall, %.3f s cpu (lambda_1 %.4f, "
                       "lambda_z %.2e)\n",
                       aff ? "euclidean" : "geodesic", zs[i], with_vec ? " + vectors" : "", dt, cpu,
                       lam[0], lam[zs[i] - 1]);
            }
    free(vec);
    cr_garment_destroy(g);
    cr_body_model_destroy(body);
}

static cr_garment *make(const cr_body_model *body, cr_garment_type type, int32_t verts,
                        float length_scale) {
    cr_error err = {0};
    cr_garment_def d = cr_garment_default_def(type);
    d.target_vertices = verts;
    d.length_scale = length_scale;
    cr_garment *g = NULL;
    if (cr_garment_create(&d, body, &g, &err) != CR_OK)
        cr_test_fail_here(__FILE__, __LINE__, "%s: %s", cr_garment_type_name(type), err.msg);
    return g;
}

/* The choice of sigma_scale (docs/swingar.md): for each width, how far the
 * descriptor moves when a dress is remeshed (2k -> 8k vertices) against how
 * far it moves to a longer dress and to other garment types (relative L2). */
CR_TEST(long_swingar_descriptor, sigma_study) {
    cr_error err = {0};
    cr_body_model *body = NULL;
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 90;
    CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
    CR_REQUIRE(body);
    enum { N = 6, Z = 256 };
    const char *name[N] = {"dress 2k", "dress 8k", "dress x1.3", "skirt", "t-shirt", "trousers"};
    cr_garment *g[N] = {
        make(body, CR_GARMENT_DRESS, 2000, 1.0f),  make(body, CR_GARMENT_DRESS, 8000, 1.0f),
        make(body, CR_GARMENT_DRESS, 8000, 1.3f),  make(body, CR_GARMENT_SKIRT, 8000, 1.0f),
        make(body, CR_GARMENT_TSHIRT, 8000, 1.0f), make(body, CR_GARMENT_TROUSERS, 8000, 1.0f)};
    for (int i = 0; i < N; i++)
        CR_REQUIRE(g[i]);
    printf("  relative L2 distance to the 2k dress's descriptor (z = %d)\n", Z);
    printf("  %-9s %5s", "affinity", "scale");
    for (int i = 1; i < N; i++)
        printf(" %10s", name[i]);
    printf("  lambda_1 lambda_64 lambda_256 (8k dress)\n");
    const float scale[4] = {0.1f, 0.25f, 0.5f, 1.0f};
    for (int aff = 0; aff < 2; aff++)
        for (int s = 0; s < 4; s++) {
            cr_swingar_descriptor_opts o = cr_swingar_descriptor_default_opts();
            o.affinity = (cr_swingar_affinity)aff;
            o.sigma_scale = scale[s];
            static float lam[N][Z];
            for (int i = 0; i < N; i++)
                CR_CHECK_OK(cr_swingar_descriptor_full(g[i]->mesh, &o, lam[i], NULL, &err), &err);
            printf("  %-9s %5.2f", aff ? "euclidean" : "geodesic", (double)scale[s]);
            for (int i = 1; i < N; i++) {
                double d = 0, n = 0;
                for (int k = 0; k < Z; k++) {
                    d += ((double)lam[i][k] - lam[0][k]) * ((double)lam[i][k] - lam[0][k]);
                    n += (double)lam[0][k] * lam[0][k];
                }
                printf(" %10.4f", sqrt(d / n));
            }
            printf("  %.4f %.2e %.2e\n", lam[1][0], lam[1][63], lam[1][Z - 1]);
        }
    for (int i = 0; i < N; i++)
        cr_garment_destroy(g[i]);
    cr_body_model_destroy(body);
}
