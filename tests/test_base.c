/* test_base.c: status messages, arena, RNG, parallel-for, config, atomic files. */
#define _POSIX_C_SOURCE 200809L
#include "base/atan2d.h"
#include "crease/base.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <math.h>

#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

CR_TEST(base, error_message_names_file_and_line) {
    cr_error err = {0};
    cr_status st = CR_FAIL(&err, CR_ERR_PARSE, "%s:%d: expected a number", "cloth.obj", 12);
    CR_CHECK(st == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "cloth.obj:12") != NULL);
    CR_CHECK(err.src_line > 0);
    CR_CHECK(strcmp(cr_status_str(CR_ERR_PARSE), "parse error") == 0);
}

CR_TEST(base, arena_alignment_and_exhaustion) {
    cr_arena a;
    cr_error err = {0};
    CR_CHECK_OK(cr_arena_init(&a, 1024, &err), &err);
    void *p = cr_arena_alloc(&a, 10, &err);
    void *q = cr_arena_alloc(&a, 10, &err);
    CR_CHECK(p && q && ((uintptr_t)q % 64) == 0 && (char *)q - (char *)p == 64);
    size_t mark = cr_arena_mark(&a);
    CR_CHECK(cr_arena_alloc(&a, 800, &err) != NULL);
    cr_arena_rewind(&a, mark);
    CR_CHECK(a.used == mark);
    CR_CHECK(cr_arena_alloc(&a, 5000, &err) == NULL);
    CR_CHECK(err.status == CR_ERR_MEMORY && strstr(err.msg, "need 5000") != NULL);
    cr_arena_reset(&a);
    CR_CHECK(a.used == 0 && a.peak >= 928);
    cr_arena_free(&a);
}

CR_TEST(base, philox_is_counter_based_and_uniform) {
    /* Same (seed, stream, counter) -> same block; a different stream differs. */
    uint32_t a[4], b[4], c[4];
    cr_philox4x32(42, 7, 1000, a);
    cr_philox4x32(42, 7, 1000, b);
    cr_philox4x32(42, 8, 1000, c);
    CR_CHECK(memcmp(a, b, sizeof a) == 0);
    CR_CHECK(memcmp(a, c, sizeof a) != 0);
    /* Known-answer test from the Random123 distribution (philox4x32_10, zero key and counter). */
    uint32_t zero[4];
    cr_philox4x32(0, 0, 0, zero);
    CR_CHECK(zero[0] == 0x6627e8d5u && zero[1] == 0xe169c58du && zero[2] == 0xbc57ac4cu &&
             zero[3] == 0x9b00dbd8u);
    cr_rng r = cr_rng_make(1, 0);
    double sum = 0, sum2 = 0;
    int n = 200000, below[10] = {0};
    for (int i = 0; i < n; i++) {
        double u = cr_rng_uniform(&r);
        CR_REQUIRE(u >= 0 && u < 1);
        sum += u;
        below[cr_rng_below(&r, 10)]++;
        double g = cr_rng_normal(&r);
        sum2 += g * g;
    }
    CR_CHECK_NEAR(sum / n, 0.5, 0.005);
    CR_CHECK_NEAR(sum2 / n, 1.0, 0.02);
    for (int k = 0; k < 10; k++)
        CR_CHECK_NEAR(below[k] / (double)n, 0.1, 0.005);
}

CR_TEST(base, shuffle_is_a_permutation) {
    int32_t a[100];
    for (int i = 0; i < 100; i++)
        a[i] = i;
    cr_rng r = cr_rng_make(3, 1);
    cr_rng_shuffle_i32(&r, a, 100);
    int seen[100] = {0}, moved = 0;
    for (int i = 0; i < 100; i++)
        seen[a[i]]++, moved += a[i] != i;
    for (int i = 0; i < 100; i++)
        CR_CHECK(seen[i] == 1);
    CR_CHECK(moved > 50);
}

typedef struct {
    int64_t *out;
} square_ctx;

static void square_range(void *ctx, int64_t begin, int64_t end) {
    square_ctx *c = ctx;
    for (int64_t i = begin; i < end; i++)
        c->out[i] += i * i;
}

CR_TEST(base, parallel_for_covers_every_index_once) {
    for (int64_t n = 0; n < 5000; n = n * 3 + 1) {
        int64_t *out = calloc((size_t)n + 1, sizeof *out);
        square_ctx c = {out};
        cr_parallel_for(n, 7, square_range, &c);
        for (int64_t i = 0; i < n; i++)
            CR_CHECK(out[i] == i * i);
        free(out);
    }
}

CR_TEST(base, wait_policy_spins_only_with_a_cpu_for_every_thread) {
    CR_CHECK(strcmp(cr_parallel_wait_policy_for(0.0, 2, 2), "spin") == 0);
    CR_CHECK(strcmp(cr_parallel_wait_policy_for(1.0, 2, 4), "spin") == 0);
    /* another runnable job on a 2-core machine, an unreadable count, more
     * threads than CPUs */
    CR_CHECK(strcmp(cr_parallel_wait_policy_for(1.0, 2, 2), "passive") == 0);
    CR_CHECK(strcmp(cr_parallel_wait_policy_for(-1.0, 1, 8), "passive") == 0);
    CR_CHECK(strcmp(cr_parallel_wait_policy_for(0.0, 4, 2), "passive") == 0);
}

typedef struct {
    float stiffness;
    int steps;
    int plastic;
    char name[16];
} demo_config;

static const cr_config_key demo_keys[] = {
    {"stiffness", CR_CFG_FLOAT, offsetof(demo_config, stiffness), 0, 0, 1e6, "N/m", NULL, NULL},
    {"steps", CR_CFG_INT, offsetof(demo_config, steps), 0, 1, 1000, "count", NULL, NULL},
    {"plastic", CR_CFG_BOOL, offsetof(demo_config, plastic), 0, 1, 0, "", NULL, NULL},
    {"name", CR_CFG_STRING, offsetof(demo_config, name), 16, 1, 0, "", NULL, NULL},
};

CR_TEST(base, config_fills_and_rejects_by_key) {
    demo_config c = {.stiffness = 1, .steps = 10};
    cr_error err = {0};
    CR_CHECK_OK(cr_config_parse("{\"stiffness\": 250.5, \"plastic\": true, \"name\": \"denim\"}",
                                "m.json", demo_keys, 4, &c, &err),
                &err);
    CR_CHECK_NEAR(c.stiffness, 250.5, 1e-6);
    CR_CHECK(c.steps == 10 && c.plastic == 1 && strcmp(c.name, "denim") == 0);

    CR_CHECK(cr_config_parse("{\"stiffnes\": 1}", "m.json", demo_keys, 4, &c, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "unknown key 'stiffnes'") && strstr(err.msg, "m.json"));
    CR_CHECK(cr_config_parse("{\"steps\": 2.5}", "m.json", demo_keys, 4, &c, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "'steps'") != NULL);
    CR_CHECK(cr_config_parse("{\"steps\": 5000}", "m.json", demo_keys, 4, &c, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(cr_config_parse("{\"name\": 3}", "m.json", demo_keys, 4, &c, &err) == CR_ERR_CONFIG);
    CR_CHECK(cr_config_parse("{\n\"steps\": 1,\n oops}", "m.json", demo_keys, 4, &c, &err) ==
             CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "m.json:3") != NULL);
}

CR_TEST(base, atomic_write_commits_or_leaves_nothing) {
    char path[512];
    snprintf(path, sizeof path, "%s/sub/dir/file.txt", cr_test_tmpdir());
    cr_error err = {0};
    char dir[512];
    snprintf(dir, sizeof dir, "%s/sub/dir", cr_test_tmpdir());
    CR_CHECK_OK(cr_mkdir_p(dir, &err), &err);
    cr_atomic_file f;
    CR_CHECK_OK(cr_atomic_open(&f, path, &err), &err);
    fputs("first", f.fp);
    cr_atomic_abort(&f);
    char *text = NULL;
    CR_CHECK(cr_file_read_all(path, &text, NULL, &err) == CR_ERR_IO);
    CR_CHECK_OK(cr_atomic_open(&f, path, &err), &err);
    fputs("second", f.fp);
    CR_CHECK_OK(cr_atomic_commit(&f, &err), &err);
    CR_CHECK_OK(cr_file_read_all(path, &text, NULL, &err), &err);
    CR_CHECK(text && strcmp(text, "second") == 0);
    free(text);
    /* a temporary left by a killed writer goes at the next commit; a live one stays */
    pid_t child = fork();
    if (child == 0) _exit(0);
    CR_CHECK(child > 0);
    waitpid(child, NULL, 0);
    char dead[600], live[600];
    snprintf(dead, sizeof dead, "%s.tmp.%ld", path, (long)child);
    snprintf(live, sizeof live, "%s.tmp.%ld", path, (long)getppid());
    FILE *leftover = fopen(dead, "w"), *other = fopen(live, "w");
    CR_CHECK(leftover && other);
    if (leftover) fclose(leftover);
    if (other) fclose(other);
    CR_CHECK_OK(cr_atomic_open(&f, path, &err), &err);
    fputs("third", f.fp);
    CR_CHECK_OK(cr_atomic_commit(&f, &err), &err);
    CR_CHECK(access(dead, F_OK) != 0);
    CR_CHECK(access(live, F_OK) == 0);
    remove(live);
    char ext[8];
    cr_path_ext("a/b.c/Mesh.GLB", ext, sizeof ext);
    CR_CHECK(strcmp(ext, "glb") == 0);
    cr_path_ext("a/b.c/mesh", ext, sizeof ext);
    CR_CHECK(ext[0] == 0);
}

static double ulp_distance(double a, double b) {
    if (a == b) return 0.0;
    const double u = nextafter(fabs(b), INFINITY) - fabs(b);
    return fabs(a - b) / u;
}

CR_TEST(base, atan2d_within_3_ulp_of_libm) {
    cr_rng r = cr_rng_make(77, 0);
    double worst = 0.0;
    for (int k = 0; k < 400000; k++) {
        double y, x;
        if (k % 4 == 0) { /* around the fold and the swap */
            const double q = k % 8 == 0 ? 0.41421356237309503 : 1.0;
            x = ldexp(1.0, (int)(cr_rng_uniform(&r) * 80.0) - 40);
            y = x * q * (1.0 + 1e-9 * (cr_rng_uniform(&r) - 0.5));
        } else {
            x = ldexp(cr_rng_uniform(&r) + 0.5, (int)(cr_rng_uniform(&r) * 120.0) - 60);
            y = ldexp(cr_rng_uniform(&r) + 0.5, (int)(cr_rng_uniform(&r) * 120.0) - 60);
        }
        if (k & 1) x = -x;
        if (k & 2) y = -y;
        worst = fmax(worst, ulp_distance(cr_atan2d(y, x), atan2(y, x)));
    }
    CR_CHECK(worst <= 3.0);
    printf("  cr_atan2d: %.1f ulp from libm's at worst\n", worst);
    const double sp[] = {0.0, -0.0, 1.0, -1.0, INFINITY, -INFINITY, 1e-310, -1e308};
    for (int i = 0; i < 8; i++)
        for (int j = 0; j < 8; j++) {
            const double a = cr_atan2d(sp[i], sp[j]), b = atan2(sp[i], sp[j]);
            CR_CHECK(ulp_distance(a, b) <= 3.0 && signbit(a) == signbit(b));
        }
    CR_CHECK(isnan(cr_atan2d(NAN, 1.0)) && isnan(cr_atan2d(1.0, NAN)));
}

/* One table per struct: JSON out and back in the table's order, and the
 * first key two structs differ in (what a resume names). */
CR_TEST(base, config_table_writes_reads_and_diffs) {
    typedef struct {
        int n;
        float x;
        double y;
        int flag;
        char name[8];
    } s_t;
    static const cr_config_key keys[] = {
        {"n", CR_CFG_INT, offsetof(s_t, n), 0, 0, 10, NULL, NULL, NULL},
        {"x", CR_CFG_FLOAT, offsetof(s_t, x), 0, 1, 0, NULL, NULL, NULL},
        {"y", CR_CFG_DOUBLE, offsetof(s_t, y), 0, 1, 0, NULL, NULL, NULL},
        {"flag", CR_CFG_BOOL, offsetof(s_t, flag), 0, 1, 0, NULL, NULL, NULL},
        {"name", CR_CFG_STRING, offsetof(s_t, name), 8, 1, 0, NULL, NULL, NULL},
    };
    s_t a = {3, 0.5f, -2.25, 1, "abc"}, b = {0, 0, 0, 0, ""};
    cJSON *o = cr_config_to_object(keys, 5, &a);
    CR_REQUIRE(o != NULL);
    char *text = cJSON_PrintUnformatted(o);
    CR_CHECK(strcmp(text, "{\"n\":3,\"x\":0.5,\"y\":-2.25,\"flag\":true,\"name\":\"abc\"}") == 0);
    cr_error err = {0};
    CR_CHECK_OK(cr_config_parse_object(o, "t", keys, 5, &b, &err), &err);
    CR_CHECK(cr_config_diff(keys, 5, &a, &b) == NULL);
    b.y = 1.0;
    CR_CHECK(strcmp(cr_config_diff(keys, 5, &a, &b), "y") == 0);
    b.n = 4;
    CR_CHECK(strcmp(cr_config_diff(keys, 5, &a, &b), "n") == 0);
    cJSON_AddNumberToObject(o, "n2", 1);
    CR_CHECK(cr_config_parse_object(o, "t", keys, 5, &b, &err) == CR_ERR_CONFIG &&
             strstr(err.msg, "n2"));
    CR_CHECK(cr_config_absent(keys, 5, o) == NULL);
    cJSON_DeleteItemFromObject(o, "y");
    CR_CHECK(strcmp(cr_config_absent(keys, 5, o), "y") == 0);
    CR_CHECK(cr_config_number(&keys[1], &a) == 0.5 && cr_config_number(&keys[0], &a) == 3.0);
    cJSON_free(text);
    cJSON_Delete(o);
    /* a seed: a non-negative integer up to 2^64 */
    typedef struct {
        uint64_t seed;
    } u_t;
    static const cr_config_key ukeys[] = {
        {"seed", CR_CFG_U64, offsetof(u_t, seed), 0, 1, 0, NULL, NULL, NULL}};
    u_t u = {0}, v = {0};
    CR_CHECK_OK(cr_config_parse("{\"seed\": 4294967297}", "u", ukeys, 1, &u, &err), &err);
    CR_CHECK(u.seed == 4294967297ull && strcmp(cr_config_diff(ukeys, 1, &u, &v), "seed") == 0);
    CR_CHECK(cr_config_parse("{\"seed\": -1}", "u", ukeys, 1, &u, &err) == CR_ERR_CONFIG &&
             strstr(err.msg, "non-negative integer"));
    CR_CHECK(cr_config_parse("{\"seed\": 1.5}", "u", ukeys, 1, &u, &err) == CR_ERR_CONFIG);
    cJSON *uo = cr_config_to_object(ukeys, 1, &u);
    char *ut = uo ? cJSON_PrintUnformatted(uo) : NULL;
    CR_CHECK(ut && strcmp(ut, "{\"seed\":4294967297}") == 0);
    cJSON_free(ut);
    cJSON_Delete(uo);
}

/* cr_config_check: the ranges a def's library checks it with, the table's own */
CR_TEST(base, config_check_holds_each_key_to_its_range) {
    cr_error err = {0};
    demo_config c = {.stiffness = 250, .steps = 10};
    CR_CHECK_OK(cr_config_check(demo_keys, 4, &c, "demo def", &err), &err);
    c.steps = 1001; /* steps in [1, 1000] */
    CR_CHECK(cr_config_check(demo_keys, 4, &c, "demo def", &err) == CR_ERR_INVALID &&
             strcmp(err.msg, "demo def: steps 1001 outside [1, 1000]") == 0);
    c.steps = 1, c.stiffness = NAN; /* NaN is outside every range */
    CR_CHECK(cr_config_check(demo_keys, 4, &c, "demo def", &err) == CR_ERR_INVALID &&
             strstr(err.msg, "stiffness"));
    c.stiffness = 0, c.plastic = 7; /* bools and strings and unchecked keys are not ranged */
    CR_CHECK_OK(cr_config_check(demo_keys, 4, &c, "demo def", &err), &err);
}
