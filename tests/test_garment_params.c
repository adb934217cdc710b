/* test_garment_params.c: garment shape parameters (crease/garment.h's
 * cr_garment_params table): the defaults build the very garments the
 * templates built before they had parameters (hashes recorded then), random
 * variants of every type pass the quality checks, out-of-range values are
 * refused naming the key, seeded generation is deterministic, the
 * jumpsuit has its openings, UVs and weights, and a long t-shirt passes the
 * crotch. */
#include "body_fixture.h"
#include "crease/body.h"
#include "crease/garment.h"
#include "crease/topology.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Mannequin grid: coarse to keep the tests quick. */
enum { BODY_RES = 64 };

static cr_body_model *body64(void) {
    return fixture_mannequin(BODY_RES);
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

/* Variants per type and their vertex count: 5 here to keep `make check`
 * short (about 2 s a type; 2 in a quick run); the 20 per type
 * were measured once (docs/garments.md) with NVARIANTS = 20. */
enum { NVARIANTS = 5, NVARIANTS_QUICK = 2, VARIANT_VERTICES = 1000 };

/* Every draw of seeds 1..NVARIANTS of one type passes cr_garment_check at its
 * first attempt (the generator would resample otherwise: counted, must be
 * rare) and lies in the type's sampled ranges. */
static void random_variants(cr_garment_type type) {
    cr_error err = {0};
    CR_REQUIRE(body64());
    int resampled = 0;
    double t0 = cr_time_now();
    clock_t c0 = clock();
    float worst_angle = 1.0f, worst_clear = 1.0f;
    const int nvariants = CR_TEST_SIZE(NVARIANTS, NVARIANTS_QUICK);
    for (int s = 1; s <= nvariants; s++) {
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
        /* The figures cr_garment_check held to the targets. */
        worst_angle = fminf(worst_angle, v.quality.share_min_angle_above_20deg);
        worst_clear = fminf(worst_clear, v.quality.min_clearance_m);
        CR_CHECK(v.quality.vertices > 0 && v.quality.boundary_loops == cr_garment_openings(type));
        cr_garment_template_destroy(t);
    }
    printf("    %-10s %d variants, %d resampled, worst share above 20 deg %.4f, clearance %.1f mm, "
           "%.1f s (%.1f s CPU)\n",
           cr_garment_type_name(type), nvariants, resampled, (double)worst_angle,
           1000.0 * worst_clear, cr_time_now() - t0, (double)(clock() - c0) / CLOCKS_PER_SEC);
    CR_CHECK(resampled <= 1);
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

/* ----------------------------------------------------- keys and ranges -- */

CR_TEST(garment_params, out_of_range_refused) {
    cr_error err = {0};
    cr_garment_def d = cr_garment_default_def(CR_GARMENT_DRESS);
    CR_CHECK(cr_garment_param_set(&d, "length", 2.0, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "length") && strstr(err.msg, "0.5 to 1.5"));
    CR_CHECK(d.length_scale == 1.0f); /* unchanged */
    CR_CHECK(cr_garment_param_set(&d, "colour", 1.0, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "colour") && strstr(err.msg, "neck"));
    CR_CHECK_OK(cr_garment_param_set(&d, "flare", 45.0, &err), &err); /* ends included */
    CR_CHECK(d.flare_deg == 45.0f);
    cr_garment_variant v;
    CR_CHECK(cr_garment_variant_parse("dress:flare=60", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "dress:flare=60") && strstr(err.msg, "flare") &&
             strstr(err.msg, "0 to 45"));
    CR_CHECK(cr_garment_variant_parse("dress:neck=-0.5", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "neck") && strstr(err.msg, "-0.02 to 0.08"));
    CR_CHECK(cr_garment_variant_parse("dress:flare", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_garment_variant_parse("dress:flare=abc", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_garment_variant_parse("dress:seed=1.5", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(cr_garment_variant_parse("poncho:seed=1", &v, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "jumpsuit") != NULL); /* the known types are listed */
    /* The library refuses a def whose field is off, naming field and key. */
    d = cr_garment_default_def(CR_GARMENT_TSHIRT);
    d.sleeve_scale = 3.0f;
    cr_garment *g = NULL;
    CR_CHECK(cr_garment_create(&d, body64(), &g, &err) == CR_ERR_INVALID && !g);
    CR_CHECK(strstr(err.msg, "sleeve_scale") && strstr(err.msg, "sleeve") &&
             strstr(err.msg, "0.5 to 1.5"));
    /* Given keys and labels. */
    CR_CHECK_OK(cr_garment_variant_parse("tshirt:length=0.8:sleeve=1.2:seed=4", &v, &err), &err);
    CR_CHECK(v.random && v.seed == 4 && v.def.length_scale == 0.8f && v.def.sleeve_scale == 1.2f);
    CR_CHECK(v.given ==
             (1u << cr_garment_param_find("length") | 1u << cr_garment_param_find("sleeve")));
    CR_CHECK(!strcmp(v.label, "tshirt_length0.8_sleeve1.2_seed4"));
    /* Every sampled range lies in the accepted one; empty ranges only for
     * the types that ignore the key. */
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
        const cr_garment_param *p = cr_garment_param_at(i);
        CR_CHECK(cr_garment_param_find(p->key) == i);
        for (int t = 0; t < CR_GARMENT_USER; t++) {
            float lo = p->sample_lo[t], hi = p->sample_hi[t];
            cr_garment_def d0 = cr_garment_default_def((cr_garment_type)t);
            float def = cr_garment_param_get(&d0, i);
            if (lo == 0.0f && hi == 0.0f) continue;
            CR_CHECK(lo < hi && lo >= p->lo - 1e-6 && hi <= p->hi + 1e-6);
            /* The default lies in the sampled range (the variants surround it). */
            CR_CHECK(def >= lo && def <= hi);
        }
    }
    CR_CHECK(cr_garment_param_at(CR_GARMENT_NPARAMS) == NULL);
}

/* ----------------------------------------------------------- determinism -- */

CR_TEST(garment_params, seeded_generation_is_deterministic) {
    cr_error err = {0};
    for (int t = 0; t < CR_GARMENT_USER; t++) {
        cr_garment_def a = cr_garment_random_def((cr_garment_type)t, 7, 0);
        cr_garment_def b = cr_garment_random_def((cr_garment_type)t, 7, 0);
        cr_garment_def c = cr_garment_random_def((cr_garment_type)t, 8, 0);
        cr_garment_def r = cr_garment_random_def((cr_garment_type)t, 7, 1);
        CR_CHECK(memcmp(&a, &b, sizeof a) == 0);
        CR_CHECK(a.length_scale != c.length_scale && a.length_scale != r.length_scale);
        /* The exact spec reads back bit for bit. */
        char spec[256];
        cr_garment_def_spec(&a, spec, sizeof spec);
        cr_garment_variant v;
        CR_CHECK_OK(cr_garment_variant_parse(spec, &v, &err), &err);
        for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
            CR_CHECK(cr_garment_param_get(&v.def, i) == cr_garment_param_get(&a, i));
    }
    /* The same spec builds the same garment, bit for bit. */
    uint64_t h[2] = {0, 1};
    cr_garment_def used[2];
    for (int k = 0; k < 2; k++) {
        cr_garment_variant v;
        CR_CHECK_OK(cr_garment_variant_parse("skirt:seed=11:res=1000", &v, &err), &err);
        cr_garment_template *t = NULL;
        CR_CHECK_OK(cr_garment_variant_build(&v, body64(), &t, &err), &err);
        cr_garment *g = NULL;
        if (t) CR_CHECK_OK(cr_garment_template_instantiate(t, 1000, body64(), &g, &err), &err);
        if (g) h[k] = garment_hash(g);
        used[k] = v.def;
        cr_garment_destroy(g);
        cr_garment_template_destroy(t);
    }
    CR_CHECK(h[0] == h[1]);
    CR_CHECK(memcmp(&used[0], &used[1], sizeof used[0]) == 0);
    /* ... and differs from the default skirt. */
    CR_CHECK(used[0].flare_deg != cr_garment_default_def(CR_GARMENT_SKIRT).flare_deg);
}

/* -------------------------------------------------------------- jumpsuit -- */

/* One piece from the neck to the ankles: closed at the waist and crotch
 * (no opening between the armholes and the leg ends), its five openings at
 * the right heights, one UV chart per panel, legs skinned to the legs. */
CR_TEST(garment_params, jumpsuit) {
    cr_error err = {0};
    cr_body_model *body = body64();
    CR_REQUIRE(body);
    cr_garment_def def = cr_garment_default_def(CR_GARMENT_JUMPSUIT);
    def.target_vertices = 2000;
    cr_garment *g = NULL;
    CR_CHECK_OK(cr_garment_create(&def, body, &g, &err), &err);
    CR_REQUIRE(g);
    cr_garment_quality q;
    CR_CHECK_OK(cr_garment_check(g, body, &q, &err), &err);
    CR_CHECK(q.boundary_loops == 5 && q.panels == 4 && q.uv_flipped == 0);
    printf("    jumpsuit: %d vertices, %.4f above 20 deg (min %.1f), clearance %.1f mm, UV area "
           "error %.2f%%\n",
           q.vertices, (double)q.share_min_angle_above_20deg, (double)q.min_angle_deg,
           1000.0 * q.min_clearance_m, 100.0 * q.uv_area_error);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(g->mesh, &t, &err), &err);
    CR_REQUIRE(t);
    const float knee = body->joints[3 * CR_JOINT_LEFT_KNEE + 1];
    const float hip = body->joints[3 * CR_JOINT_LEFT_HIP + 1];
    const float neck = body->joints[3 * CR_JOINT_NECK + 1];
    int low = 0, high = 0;
    for (int32_t l = 0; l < t->nloop; l++) {
        double y = 0.0;
        for (int32_t k = t->loop_off[l]; k < t->loop_off[l + 1]; k++)
            y += g->mesh->pos[3 * t->loop_vert[k] + 1];
        y /= t->loop_off[l + 1] - t->loop_off[l];
        low += y < knee;                      /* the leg ends */
        high += y > hip + 0.5 * (neck - hip); /* neck and armholes */
    }
    CR_CHECK(low == 2 && high == 3);
    cr_topology_destroy(t);
    /* Below the knees every vertex follows a leg's joints. */
    int off_leg = 0, below = 0;
    for (int32_t v = 0; v < g->mesh->nv; v++) {
        if (g->mesh->pos[3 * v + 1] > knee - 0.05f) continue;
        below++;
        int j = g->skin_joint[4 * v];
        off_leg +=
            !(j == CR_JOINT_LEFT_KNEE || j == CR_JOINT_RIGHT_KNEE || j == CR_JOINT_LEFT_ANKLE ||
              j == CR_JOINT_RIGHT_ANKLE || j == CR_JOINT_LEFT_FOOT || j == CR_JOINT_RIGHT_FOOT);
    }
    CR_CHECK(below > 100 && off_leg == 0);
    /* Every panel is one chart: a face's UV corners are its panel's only. */
    int32_t *owner = malloc((size_t)g->mesh->nuv * sizeof(int32_t)), shared = 0;
    for (int32_t i = 0; i < g->mesh->nuv; i++)
        owner[i] = -1;
    for (int32_t f = 0; f < g->mesh->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t u = g->mesh->tri_uv[3 * f + k];
            shared += owner[u] >= 0 && owner[u] != g->panel[f];
            owner[u] = g->panel[f];
        }
    CR_CHECK(shared == 0);
    free(owner);
    /* The checks are not vacuous: spoilt weights, then a flipped UV
     * triangle, are refused by name. */
    g->skin_weight[0] += 0.1f;
    CR_CHECK(cr_garment_check(g, body, NULL, &err) == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "skin weights") != NULL);
    g->skin_weight[0] -= 0.1f;
    CR_CHECK_OK(cr_garment_check(g, body, NULL, &err), &err);
    int32_t *c = &g->mesh->tri_uv[0], keep = c[1];
    c[1] = c[2], c[2] = keep;
    CR_CHECK(cr_garment_check(g, body, NULL, &err) == CR_ERR_TOPOLOGY);
    CR_CHECK(strstr(err.msg, "UVs") != NULL);
    cr_garment_destroy(g);
}

/* ------------------------------------------------------------ long shirt -- */

/* A t-shirt at length 1.4 reaches below the crotch as one skirt (the
 * dress's envelope below the waist): the top's four openings, the hem loop
 * below the hip joints, every check passed; at length 1 it stays a t-shirt
 * ending above the crotch. */
CR_TEST(garment_params, long_shirt) {
    cr_error err = {0};
    cr_body_model *body = body64();
    CR_REQUIRE(body);
    const float hip = body->joints[3 * CR_JOINT_LEFT_HIP + 1];
    for (int k = 0; k < 2; k++) {
        cr_garment_variant v;
        CR_CHECK_OK(cr_garment_variant_parse(k ? "tshirt:length=1.4:res=1500" : "tshirt:res=1500",
                                             &v, &err),
                    &err);
        cr_garment_template *t = NULL;
        CR_CHECK_OK(cr_garment_variant_build(&v, body, &t, &err), &err);
        cr_garment *g = NULL;
        if (t) CR_CHECK_OK(cr_garment_template_instantiate(t, 1500, body, &g, &err), &err);
        cr_garment_template_destroy(t);
        if (!g) continue;
        CR_CHECK(v.quality.boundary_loops == 4 && v.quality.panels == 6);
        float lowest = INFINITY;
        for (int32_t i = 0; i < g->mesh->nv; i++)
            lowest = fminf(lowest, g->mesh->pos[3 * i + 1]);
        printf("    tshirt length %.1f: hem at %.3f m, hip joints at %.3f m\n", k ? 1.4 : 1.0,
               (double)lowest, (double)hip);
        CR_CHECK(k ? lowest < hip - 0.1f : lowest > hip - 0.03f);
        cr_garment_destroy(g);
    }
}
