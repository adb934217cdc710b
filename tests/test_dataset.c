/* test_dataset.c: a small dataset end to end: the layout and manifest, the
 * sequences simulated with few vertices inside the body, a second run that
 * skips everything, a skirt's waistband carried by the body, and bad
 * definitions refused by name. */
#include "crease/dataset.h"
#include "crease/mesh_io.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static cJSON *read_json(const char *path) {
    char *text = NULL;
    size_t len = 0;
    if (cr_file_read_all(path, &text, &len, NULL) != CR_OK) return NULL;
    cJSON *j = cJSON_Parse(text);
    free(text);
    return j;
}

CR_TEST(dataset, small_dataset_is_complete_and_resumes) {
    char dir[512];
    snprintf(dir, sizeof dir, "%s/dataset", cr_test_tmpdir());
    const char *garments[] = {"tshirt", "skirt"}, *motions[] = {"raise_arms"};
    const char *bodies[] = {"normal"}, *res[] = {"low", "high"};
    cr_dataset_def d = cr_dataset_default_def();
    d.out_dir = dir;
    d.garments = garments, d.ngarments = 2;
    d.motions = motions, d.nmotions = 1;
    d.bodies = bodies, d.nbodies = 1;
    d.res = res, d.nres = 2;
    d.low_vertices = 600, d.high_vertices = 1200;
    d.frames = 8;
    d.quiet = 1;
    cr_error err = {0};
    cr_dataset_result r;
    CR_CHECK_OK(cr_dataset_generate(&d, &r, &err), &err);
    printf("    4 sequences of 8 frames: %.1f s; inside share tshirt %.4f skirt %.4f\n", r.seconds,
           r.max_inside_share[0], r.max_inside_share[1]);
    CR_CHECK(r.sequences == 4 && r.done == 4 && r.skipped == 0 && r.failed == 0);
    CR_CHECK(r.max_inside_share[0] < 0.005 && r.max_inside_share[1] < 0.005);
    printf("    crossing triangle pairs, most on a frame (as built): tshirt %lld (%lld), skirt "
           "%lld (%lld); seconds %.1f, %.1f\n",
           (long long)r.max_crossings[0], (long long)r.rest_crossings[0],
           (long long)r.max_crossings[1], (long long)r.rest_crossings[1], r.seconds_by_garment[0],
           r.seconds_by_garment[1]);
    CR_CHECK(r.max_crossings[0] >= 0 && r.max_crossings[1] >= 0);
    CR_CHECK(r.rest_crossings[0] >= 0 && r.rest_crossings[1] >= 0);
    CR_CHECK(r.failed_by_garment[0] == 0 && r.failed_by_garment[1] == 0);
    CR_CHECK(r.seconds_by_garment[0] > 0.0 && r.seconds_by_garment[1] > 0.0);
    /* Sequences run side by side on the threads, so a garment's seconds (the sum over
     * its sequences) may pass the wall time, but no sequence outlasts the run: each of
     * these garments has two (low and high). */
    CR_CHECK(r.seconds_by_garment[0] <= 2.0 * r.seconds &&
             r.seconds_by_garment[1] <= 2.0 * r.seconds);
    const cr_dataset_result first = r;

    char path[700];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    cJSON *m = read_json(path);
    CR_REQUIRE(m);
    const cJSON *seqs = cJSON_GetObjectItemCaseSensitive(m, "sequences");
    CR_CHECK(cJSON_GetArraySize(seqs) == 4);
    const cJSON *q;
    cJSON_ArrayForEach(q, seqs) {
        const cJSON *st = cJSON_GetObjectItemCaseSensitive(q, "status");
        CR_CHECK(cJSON_IsString(st) && !strcmp(st->valuestring, "done"));
        const cJSON *pc2 = cJSON_GetObjectItemCaseSensitive(q, "garment_pc2");
        CR_REQUIRE(cJSON_IsString(pc2));
        snprintf(path, sizeof path, "%s/%s", dir, pc2->valuestring);
        cr_pc2 p = {0};
        CR_CHECK_OK(cr_pc2_read(path, &p, &err), &err);
        CR_CHECK(p.nframes == 9); /* the rest state and 8 frames */
        cr_pc2_free(&p);
        /* the crossings in the manifest and in result.json, the same number */
        const cJSON *mc = cJSON_GetObjectItemCaseSensitive(q, "max_crossings");
        const cJSON *id = cJSON_GetObjectItemCaseSensitive(q, "id");
        CR_REQUIRE(cJSON_IsNumber(mc) && cJSON_IsString(id));
        snprintf(path, sizeof path, "%s/sequences/%s/result.json", dir, id->valuestring);
        cJSON *res = read_json(path);
        CR_REQUIRE(res);
        const cJSON *rc = cJSON_GetObjectItemCaseSensitive(res, "max_crossings");
        const cJSON *rr = cJSON_GetObjectItemCaseSensitive(res, "rest_crossings");
        CR_CHECK(cJSON_IsNumber(rc) && rc->valuedouble == mc->valuedouble);
        CR_CHECK(cJSON_IsNumber(rr) && rr->valuedouble >= 0);
        cJSON_Delete(res);
    }
    const cJSON *gms = cJSON_GetObjectItemCaseSensitive(m, "garments");
    CR_CHECK(cJSON_GetArraySize(gms) == 4);
    cJSON_ArrayForEach(q, gms) {
        const cJSON *rc = cJSON_GetObjectItemCaseSensitive(q, "rest_crossings");
        CR_CHECK(cJSON_IsNumber(rc) && rc->valuedouble >= 0);
    }
    cJSON_Delete(m);
    snprintf(path, sizeof path, "%s/garments/normal/skirt_high_from_low.npz", dir);
    FILE *f = fopen(path, "rb");
    CR_CHECK(f != NULL);
    if (f) fclose(f);

    /* The reader gives back what the writer wrote: every entry, found by name. */
    cr_dataset_manifest man;
    CR_CHECK_OK(cr_dataset_read(dir, &man, &err), &err);
    CR_CHECK(man.nbodies == 1 && man.ngarments == 4 && man.nmotions == 1 && man.nsequences == 4);
    CR_CHECK(man.frames == 8 && man.low_vertices == 600 && man.high_vertices == 1200);
    CR_CHECK(fabs(man.fps - 30.0f) < 1e-6f && !man.plastic && !strcmp(man.material, "cotton"));
    const cr_dataset_garment_entry *sh = cr_dataset_find_garment(&man, "skirt", "normal", "high");
    CR_REQUIRE(sh != NULL);
    CR_CHECK(!strcmp(sh->mesh, "garments/normal/skirt_high.obj") && sh->high_from_low);
    const cr_dataset_sequence_entry *sq =
        cr_dataset_find_sequence(&man, "tshirt", "low", "normal", "raise_arms");
    CR_REQUIRE(sq != NULL);
    CR_CHECK(sq->done && !strcmp(sq->id, "tshirt_low_normal_raise_arms"));
    CR_CHECK(cr_dataset_find_id(&man, NULL) == &man.sequences[0]);
    CR_CHECK(cr_dataset_find_id(&man, sq->id) == sq);
    CR_CHECK(!cr_dataset_find_garment(&man, "dress", "normal", "low"));
    CR_CHECK(!cr_dataset_find_body(&man, "heavy") && cr_dataset_find_body(&man, "normal"));
    char full[CR_SCENE_PATH];
    CR_CHECK_OK(cr_dataset_path(&man, sq->garment_pc2, full, sizeof full, &err), &err);
    cr_pc2 again = {0};
    CR_CHECK_OK(cr_pc2_read(full, &again, &err), &err);
    cr_pc2_free(&again);
    cr_dataset_manifest_free(&man);
    cr_dataset_manifest_free(&man); /* zeroed: a no-op */
    /* a folder that is no dataset, and a manifest of something else: named */
    CR_CHECK(cr_dataset_read(cr_test_tmpdir(), &man, &err) != CR_OK &&
             strstr(err.msg, "manifest.json"));
    char other[600];
    snprintf(other, sizeof other, "%s/not_a_dataset", cr_test_tmpdir());
    CR_CHECK_OK(cr_mkdir_p(other, &err), &err);
    snprintf(path, sizeof path, "%s/manifest.json", other);
    f = fopen(path, "w");
    CR_REQUIRE(f != NULL);
    fputs("{\"format\": \"something-else\", \"def\": {}}", f);
    fclose(f);
    CR_CHECK(cr_dataset_read(other, &man, &err) == CR_ERR_PARSE &&
             strstr(err.msg, "not a crease dataset"));

    /* The same definition again: nothing left to do. */
    CR_CHECK_OK(cr_dataset_generate(&d, &r, &err), &err);
    CR_CHECK(r.done == 0 && r.skipped == 4 && r.failed == 0);
    /* The figures of skipped sequences come back from their result.json. */
    for (int g = 0; g < 2; g++) {
        CR_CHECK(r.max_crossings[g] == first.max_crossings[g]);
        CR_CHECK(r.rest_crossings[g] == first.rest_crossings[g]);
        CR_CHECK(fabs(r.seconds_by_garment[g] - first.seconds_by_garment[g]) < 1e-6);
    }
}

CR_TEST(dataset, bad_definitions_are_refused_by_name) {
    const char *garments[] = {"poncho"}, *motions[] = {"walk"}, *bodies[] = {"normal"},
               *res[] = {"low"};
    cr_dataset_def d = cr_dataset_default_def();
    char dir[512];
    snprintf(dir, sizeof dir, "%s/dataset_bad", cr_test_tmpdir());
    d.out_dir = dir;
    d.garments = garments, d.ngarments = 1;
    d.motions = motions, d.nmotions = 1;
    d.bodies = bodies, d.nbodies = 1;
    d.res = res, d.nres = 1;
    cr_error err = {0};
    cr_dataset_result r;
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "poncho") != NULL);
    garments[0] = "tshirt";
    res[0] = "medium";
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "medium") != NULL);
    res[0] = "low";
    bodies[0] = "giant";
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "giant") != NULL);
    bodies[0] = "normal";
    d.frames = 0;
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "frames") != NULL);
    /* a clip and a file of one base name would share motions/walk.npz */
    d.frames = 2;
    const char *clash[] = {"walk", "mocap/walk.bvh"};
    d.motions = clash, d.nmotions = 2;
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "'walk' and 'mocap/walk.bvh' have the same label 'walk'") != NULL);
}
