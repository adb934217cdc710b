/* test_scene.c: the scene layer's runs: cr_scene_run steps, records and sums
 * exactly what a hand-written loop does, stops at a divergence with the
 * diverged frame logged, stops at a failing callback; cr_scene_simulate
 * writes the same sequence as the simulator driven by hand and refuses bad
 * definitions by name; cr_scene_drape_static settles a cloth onto a ball. */
#include "crease/mesh_io.h"
#include "crease/primitives.h"
#include "crease/scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A 10 x 10 cloth, 1 m, `height` m above the origin, and the named sphere. */
static void cloth_and_ball(float height, cr_mesh **cloth, cr_mesh **ball, cr_error *err) {
    CR_CHECK_OK(cr_prim_plane(10, 10, 1.0f, 1.0f, cloth, err), err);
    CR_CHECK_OK(cr_scene_object_create("sphere", ball, err), err);
    const float up[3] = {0.0f, height, 0.0f};
    cr_mesh_transform(*cloth, 1.0f, up);
}

static int count_lines(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    int n = 0, c;
    while ((c = fgetc(f)) != EOF)
        n += c == '\n';
    fclose(f);
    return n;
}

static int file_has(const char *path, const char *needle) {
    char *text = NULL;
    size_t len = 0;
    if (cr_file_read_all(path, &text, &len, NULL) != CR_OK) return 0;
    int has = strstr(text, needle) != NULL;
    free(text);
    return has;
}

CR_TEST(scene, run_equals_the_hand_written_loop) {
    cr_error err = {0};
    cr_mesh *cloth = NULL, *ball = NULL;
    cloth_and_ball(0.33f, &cloth, &ball, &err);
    cr_sim_def def = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &def.material, &err), &err);
    def.collider = ball;
    cr_sim *a = NULL, *b = NULL;
    CR_REQUIRE(cr_sim_create(&def, cloth, &a, &err) == CR_OK);
    CR_REQUIRE(cr_sim_create(&def, cloth, &b, &err) == CR_OK);
    enum { FRAMES = 6 };
    /* by hand */
    double seconds = 0, pen = 0;
    long long newton = 0;
    for (int f = 0; f < FRAMES; f++) {
        cr_sim_report rep;
        CR_CHECK_OK(cr_sim_step(a, &rep, &err), &err);
        seconds += rep.seconds, newton += rep.newton_iterations;
        if (rep.max_penetration_m > pen) pen = rep.max_penetration_m;
    }
    /* through the loop, recorded */
    char log[600];
    snprintf(log, sizeof log, "%s/scene_run.jsonl", cr_test_tmpdir());
    cr_scene_record *rec = NULL;
    CR_REQUIRE(cr_scene_record_create(log, b, cloth, FRAMES + 1, &rec, &err) == CR_OK);
    cr_scene_run_stats st;
    CR_CHECK_OK(cr_scene_run(b, FRAMES, rec, NULL, NULL, &st, &err), &err);
    CR_CHECK(st.frames == FRAMES && !st.diverged);
    CR_CHECK(st.newton_iterations == newton && st.newton_iterations >= FRAMES);
    CR_CHECK(st.max_penetration_m == pen);
    CR_CHECK(st.seconds > 0 && st.seconds_assembly <= st.seconds);
    CR_CHECK(cr_scene_record_samples(rec) == FRAMES + 1);
    CR_CHECK(count_lines(log) == FRAMES);
    /* the same states, bit for bit */
    const double *xa = cr_sim_positions(a), *xb = cr_sim_positions(b);
    CR_CHECK(memcmp(xa, xb, 3 * sizeof(double) * (size_t)cloth->nv) == 0);
    float last[3 * 100];
    cr_sim_positions_f(a, last);
    CR_CHECK(memcmp(cr_scene_record_last(rec), last, sizeof last) == 0);
    (void)seconds;
    cr_scene_record_destroy(rec);
    cr_sim_destroy(a);
    cr_sim_destroy(b);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(ball);
}

CR_TEST(scene, run_stops_at_a_divergence_with_the_frame_logged) {
    cr_error err = {0};
    cr_mesh *cloth = NULL, *ball = NULL;
    cloth_and_ball(0.1f, &cloth, &ball, &err); /* through the ball: 18 cm inside */
    cr_sim_def def = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &def.material, &err), &err);
    def.collider = ball;
    cr_sim *s = NULL;
    CR_REQUIRE(cr_sim_create(&def, cloth, &s, &err) == CR_OK);
    char log[600];
    snprintf(log, sizeof log, "%s/scene_diverged.jsonl", cr_test_tmpdir());
    cr_scene_record *rec = NULL;
    CR_REQUIRE(cr_scene_record_create(log, s, cloth, 4, &rec, &err) == CR_OK);
    cr_scene_run_stats st;
    cr_error run_err = {0};
    CR_CHECK(cr_scene_run(s, 3, rec, NULL, NULL, &st, &run_err) == CR_ERR_DIVERGED);
    CR_CHECK(st.diverged == 1 && st.frames == 0 && st.failure[0]);
    CR_CHECK(strstr(run_err.msg, "inside") != NULL);
    CR_CHECK(cr_scene_record_samples(rec) == 1); /* the initial state only */
    CR_CHECK(count_lines(log) == 1);
    CR_CHECK(file_has(log, "\"diverged\":true"));
    cr_scene_record_destroy(rec);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(ball);
}

static cr_status stop_at_two(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                             const cr_scene_run_stats *so_far, cr_error *err) {
    (void)sim, (void)rep;
    ++*(int *)ctx;
    if (so_far->frames == 2) return CR_FAIL(err, CR_ERR_IO, "stop here");
    return CR_OK;
}

CR_TEST(scene, run_stops_when_the_callback_fails) {
    cr_error err = {0};
    cr_mesh *cloth = NULL, *ball = NULL;
    cloth_and_ball(0.33f, &cloth, &ball, &err);
    cr_sim_def def = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &def.material, &err), &err);
    def.collider = ball;
    cr_sim *s = NULL;
    CR_REQUIRE(cr_sim_create(&def, cloth, &s, &err) == CR_OK);
    int calls = 0;
    cr_scene_run_stats st;
    CR_CHECK(cr_scene_run(s, 5, NULL, stop_at_two, &calls, &st, &err) == CR_ERR_IO);
    CR_CHECK(calls == 2 && st.frames == 2 && !st.diverged);
    CR_CHECK(strstr(err.msg, "stop here") != NULL);
    cr_sim_destroy(s);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(ball);
}

CR_TEST(scene, simulate_writes_the_simulators_sequence) {
    cr_error err = {0};
    char dir[600], garment[700];
    snprintf(dir, sizeof dir, "%s/scene_sim", cr_test_tmpdir());
    snprintf(garment, sizeof garment, "%s/scene_cloth.obj", cr_test_tmpdir());
    cr_mesh *cloth = NULL, *ball = NULL;
    cloth_and_ball(0.0f, &cloth, &ball, &err);
    CR_REQUIRE(cr_mesh_write(garment, cloth, &err) == CR_OK);
    const float offset[3] = {0.0f, 0.33f, 0.0f};
    cr_scene_sim_def d = cr_scene_sim_default_def();
    d.garment = garment, d.garment_offset = offset, d.object = "sphere";
    d.frames = 4, d.out_dir = dir, d.quiet = 1, d.render_size = 64;
    cr_scene_sim_result r;
    CR_CHECK_OK(cr_scene_simulate(&d, &r, &err), &err);
    CR_CHECK(r.run.frames == 4 && !r.run.diverged && r.vertices == 100);
    CR_CHECK(strcmp(r.material, "cotton") == 0);
    CR_CHECK(count_lines(r.log) == 4);
    cr_pc2 seq = {0};
    CR_REQUIRE(cr_pc2_read(r.pc2, &seq, &err) == CR_OK);
    CR_CHECK(seq.nframes == 5 && seq.nv == 100);
    /* by hand: the same cloth, moved, on the same ball */
    cr_mesh_transform(cloth, 1.0f, offset);
    cr_sim_def def = cr_sim_default_def();
    CR_CHECK_OK(cr_material_preset("cotton", &def.material, &err), &err);
    def.collider = ball;
    cr_sim *s = NULL;
    CR_REQUIRE(cr_sim_create(&def, cloth, &s, &err) == CR_OK);
    for (int f = 0; f < 4; f++)
        CR_CHECK_OK(cr_sim_step(s, NULL, &err), &err);
    float last[300];
    cr_sim_positions_f(s, last);
    CR_CHECK(memcmp(seq.frames + 4 * 300, last, sizeof last) == 0);
    CR_CHECK(memcmp(seq.frames, cloth->pos, sizeof last) == 0);
    cr_sim_destroy(s);
    cr_pc2_free(&seq);
    FILE *png = fopen(r.png, "rb");
    CR_CHECK(png != NULL);
    if (png) fclose(png);

    /* bad definitions, by name (each call clears r) */
    char pc2[CR_SCENE_PATH];
    snprintf(pc2, sizeof pc2, "%s", r.pc2);
    cr_scene_sim_def bad = d;
    bad.garment = NULL;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_INVALID);
    bad = d, bad.body_mesh = garment;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_INVALID);
    bad = d, bad.object = NULL, bad.body = pc2;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_INVALID);
    bad = d, bad.frames = 0;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_INVALID);
    bad = d, bad.material = "velvet";
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) != CR_OK && strstr(err.msg, "velvet"));
    /* an animation with the wrong vertex count names both files */
    bad = d, bad.body = pc2;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_SHAPE && strstr(err.msg, "sim.pc2") &&
             strstr(err.msg, "sphere"));
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(ball);
}

CR_TEST(scene, drape_static_settles_onto_the_ball) {
    cr_error err = {0};
    char dir[600];
    snprintf(dir, sizeof dir, "%s/scene_drape", cr_test_tmpdir());
    cr_scene_drape_static_def d = cr_scene_drape_static_default_def();
    d.object = "sphere", d.res = 12, d.max_frames = 30, d.out_dir = dir, d.quiet = 1;
    d.render_size = 64;
    cr_scene_drape_static_result r;
    CR_CHECK_OK(cr_scene_drape_static(&d, &r, &err), &err);
    CR_CHECK(r.vertices == 144 && r.settle.settle_frames >= 1 && r.settle.settle_frames <= 30);
    CR_CHECK(r.settle.max_penetration_m < 1e-3);
    CR_CHECK(count_lines(r.log) == r.settle.settle_frames + 1); /* and the static solve */
    cr_mesh *m = NULL;
    CR_REQUIRE(cr_mesh_read(r.obj, &m, &err) == CR_OK);
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    CR_CHECK(hi[1] > 0.28f && hi[1] < 0.36f); /* resting on the ball's top (0.3 m) */
    CR_CHECK(lo[1] < hi[1] - 0.1f);           /* and hanging down its sides */
    cr_mesh_destroy(m);
    cr_scene_drape_static_def bad = d;
    bad.coarse = 12;
    CR_CHECK(cr_scene_drape_static(&bad, &r, &err) == CR_ERR_INVALID && strstr(err.msg, "coarse"));
    bad = d, bad.object = NULL;
    CR_CHECK(cr_scene_drape_static(&bad, &r, &err) == CR_ERR_INVALID);
}

/* The twin of a scene that is not chaotic: a cloth pinned along one edge,
 * swinging down under gravity with nothing to touch, moves exactly as its
 * reference shifted by the twin's 0.1 mm, and never further from it than
 * that; a friction change with nothing to rub against changes no bit. */
CR_TEST(scene, twin_of_a_cloth_hanging_free_stays_within_its_offset) {
    cr_error err = {0};
    char dir[3][600], garment[700];
    snprintf(garment, sizeof garment, "%s/scene_twin_cloth.obj", cr_test_tmpdir());
    cr_mesh *cloth = NULL;
    CR_REQUIRE(cr_prim_plane(8, 8, 0.5f, 0.5f, &cloth, &err) == CR_OK);
    CR_REQUIRE(cr_mesh_write(garment, cloth, &err) == CR_OK);
    int32_t pins[8], npins = 0;
    for (int32_t i = 0; i < cloth->nv; i++)
        if (cloth->pos[3 * i + 2] < -0.249f) pins[npins++] = i;
    CR_REQUIRE(npins == 8);
    cr_pc2 seq[3] = {{0}};
    for (int k = 0; k < 3; k++) {
        snprintf(dir[k], sizeof dir[k], "%s/scene_twin_%d", cr_test_tmpdir(), k);
        cr_scene_sim_def d = cr_scene_sim_default_def();
        d.garment = garment, d.frames = 6, d.out_dir = dir[k], d.quiet = 1, d.render_size = 64;
        d.pins = pins, d.npins = npins;
        if (k == 1) d.twin = cr_scene_twin_default();
        if (k == 2) d.twin.friction_delta = 0.01;
        cr_scene_sim_result r;
        CR_CHECK_OK(cr_scene_simulate(&d, &r, &err), &err);
        CR_REQUIRE(cr_pc2_read(r.pc2, &seq[k], &err) == CR_OK);
    }
    const int64_t n = (int64_t)seq[0].nframes * seq[0].nv;
    double worst = 0.0, off_by = 0.0, swing = 0.0;
    for (int64_t i = 0; i < n; i++) {
        const float *a = &seq[0].frames[3 * i], *b = &seq[1].frames[3 * i];
        double dz = (double)b[2] - a[2] - CR_SCENE_TWIN_OFFSET_M;
        double d = sqrt(((double)b[0] - a[0]) * ((double)b[0] - a[0]) +
                        ((double)b[1] - a[1]) * ((double)b[1] - a[1]) +
                        ((double)b[2] - a[2]) * ((double)b[2] - a[2]));
        worst = fmax(worst, d), off_by = fmax(off_by, fabs(dz));
        swing =
            fmax(swing, fabs(seq[0].frames[3 * i + 1] - seq[0].frames[3 * (i % seq[0].nv) + 1]));
    }
    fprintf(stderr,
            "  the cloth fell %.3f m; its twin at most %.3g mm away, %.2g mm off the offset\n",
            swing, 1e3 * worst, 1e3 * off_by);
    CR_CHECK(swing > 0.05);                             /* it moved */
    CR_CHECK(worst <= 1e-4 * 1.01 && worst >= 0.99e-4); /* the offset, not more */
    CR_CHECK(off_by < 2e-6);
    CR_CHECK(memcmp(seq[0].frames, seq[2].frames, sizeof(float) * 3 * (size_t)n) == 0);
    /* a friction change that drives friction below 0 is refused by name */
    cr_scene_sim_def bad = cr_scene_sim_default_def();
    bad.garment = garment, bad.frames = 1, bad.out_dir = dir[2], bad.quiet = 1;
    bad.twin.friction_delta = -5.0;
    cr_scene_sim_result r;
    CR_CHECK(cr_scene_simulate(&bad, &r, &err) == CR_ERR_INVALID && strstr(err.msg, "friction"));
    for (int k = 0; k < 3; k++)
        cr_pc2_free(&seq[k]);
    cr_mesh_destroy(cloth);
}
