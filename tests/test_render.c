/* test_render.c: the software rasteriser: framing, symmetry, z-buffer, fill rule,
 * thread determinism, colour map, wireframe, back faces, PNG round trip,
 * turntable, image grid, errors. */
#include "crease/primitives.h"
#include "crease/render.h"
#include "test.h"

#include <png.h>
#include <stdlib.h>
#include <string.h>

static const uint8_t *px(const cr_image *img, int x, int y) {
    return img->rgb + ((size_t)y * img->width + x) * 3;
}

static int is_rgb(const uint8_t *p, int r, int g, int b) {
    return p[0] == r && p[1] == g && p[2] == b;
}

/* Small image, white background, light from the viewer, no highlight. */
static cr_render_def small_def(int w, int h) {
    cr_render_def def = cr_render_default_def();
    def.width = w, def.height = h;
    def.light_dir[0] = 0.0f, def.light_dir[1] = 0.0f, def.light_dir[2] = 1.0f;
    def.specular = 0.0f;
    return def;
}

/* Rotate +90 degrees about X: the XZ plane primitive turns to face +Z. */
static void rotate_x90(cr_mesh *m) {
    for (int32_t i = 0; i < m->nv; i++) {
        float y = m->pos[3 * i + 1], z = m->pos[3 * i + 2];
        m->pos[3 * i + 1] = -z, m->pos[3 * i + 2] = y;
    }
}

static cr_mesh *facing_plane(int n, float size) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    if (cr_prim_plane(n, n, size, size, &m, &err) != CR_OK) return NULL;
    rotate_x90(m);
    return m;
}

/* The t whose viridis colour is nearest to an sRGB pixel (brute force). */
static float viridis_t(const uint8_t *p) {
    float best = 0.0f, best_d = INFINITY;
    for (int i = 0; i <= 1000; i++) {
        float rgb[3], d = 0.0f;
        cr_colormap_viridis((float)i / 1000.0f, rgb);
        for (int c = 0; c < 3; c++)
            d += (255.0f * rgb[c] - p[c]) * (255.0f * rgb[c] - p[c]);
        if (d < best_d) best_d = d, best = (float)i / 1000.0f;
    }
    return best;
}

static int file_exists(const char *path) {
    FILE *f = fopen(path, "rb");
    if (f) fclose(f);
    return f != NULL;
}

CR_TEST(render, sphere_is_framed_and_centred) {
    cr_error err = {0};
    cr_mesh *sphere = NULL;
    CR_REQUIRE(cr_prim_icosphere(1.0f, 3, &sphere, &err) == CR_OK);
    cr_render_def def = small_def(128, 128);
    cr_render_object obj = {.mesh = sphere, .color = {0.8f, 0.2f, 0.2f}};
    cr_image img;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &img, &err), &err);
    CR_REQUIRE(img.rgb && img.width == 128 && img.height == 128);
    CR_CHECK(!is_rgb(px(&img, 64, 64), 255, 255, 255));
    CR_CHECK(px(&img, 64, 64)[0] > px(&img, 64, 64)[2] + 60); /* reddish */
    CR_CHECK(is_rgb(px(&img, 0, 0), 255, 255, 255));
    CR_CHECK(is_rgb(px(&img, 127, 0), 255, 255, 255));
    CR_CHECK(is_rgb(px(&img, 0, 127), 255, 255, 255));
    CR_CHECK(is_rgb(px(&img, 127, 127), 255, 255, 255));
    /* The camera fits the bounding sphere of the box (radius sqrt(3) R, grown
     * by the margin) to the view, so the sphere spans a known width: angular
     * radius asin(sin(fov/2) / (sqrt(3) (1 + margin))). */
    double h = 0.5 * def.fov_deg * M_PI / 180.0;
    double ang = asin(sin(h) / (sqrt(3.0) * (1.0 + def.margin)));
    double expect = 2.0 * 64.0 * tan(ang) / tan(h);
    int first = -1, last = -1;
    for (int x = 0; x < 128; x++)
        if (!is_rgb(px(&img, x, 64), 255, 255, 255)) {
            if (first < 0) first = x;
            last = x;
        }
    CR_CHECK_NEAR(last - first + 1, expect, 2.5);
    CR_CHECK_NEAR(0.5 * (first + last), 63.5, 1.0);
    cr_image_free(&img);
    CR_CHECK(img.rgb == NULL && img.width == 0);
    cr_mesh_destroy(sphere);
}

CR_TEST(render, sphere_is_mirror_symmetric_at_yaw_zero) {
    cr_error err = {0};
    cr_mesh *sphere = NULL;
    CR_REQUIRE(cr_prim_sphere_uv(1.0f, 48, 24, &sphere, &err) == CR_OK);
    cr_render_def def = small_def(96, 96);
    def.yaw_deg = 0.0f, def.pitch_deg = 15.0f;
    def.light_dir[1] = 0.5f;
    def.specular = 0.3f; /* the highlight must be symmetric too */
    cr_render_object obj = {.mesh = sphere, .color = {0.3f, 0.6f, 0.9f}};
    cr_image img;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &img, &err), &err);
    CR_REQUIRE(img.rgb != NULL);
    double sum = 0.0;
    int worst = 0;
    for (int y = 0; y < 96; y++)
        for (int x = 0; x < 48; x++)
            for (int c = 0; c < 3; c++) {
                int d = abs(px(&img, x, y)[c] - px(&img, 95 - x, y)[c]);
                sum += d;
                if (d > worst) worst = d;
            }
    CR_CHECK(sum / (96.0 * 48 * 3) < 0.5);
    CR_CHECK(worst <= 24);
    /* A light from the left breaks the symmetry: the test can fail. */
    def.light_dir[0] = -0.8f;
    cr_image lit;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &lit, &err), &err);
    CR_CHECK(px(&lit, 30, 48)[2] > px(&lit, 65, 48)[2] + 20);
    cr_image_free(&lit);
    cr_image_free(&img);
    cr_mesh_destroy(sphere);
}

CR_TEST(render, zbuffer_keeps_the_nearer_object) {
    cr_error err = {0};
    cr_mesh *box = NULL, *plane = NULL;
    CR_REQUIRE(cr_prim_box(0.8f, 0.8f, 0.8f, 1, &box, &err) == CR_OK);
    plane = facing_plane(8, 3.0f);
    CR_REQUIRE(plane != NULL);
    const float forward[3] = {0.0f, 0.0f, 0.5f}; /* box in front of the plane (camera on +Z) */
    cr_mesh_transform(box, 1.0f, forward);
    cr_render_def def = small_def(64, 64);
    def.yaw_deg = 0.0f, def.pitch_deg = 0.0f;
    /* Both orders: a painter's algorithm would get one of them wrong. */
    for (int order = 0; order < 2; order++) {
        cr_render_object objs[2] = {{.mesh = box, .color = {0.9f, 0.1f, 0.1f}},
                                    {.mesh = plane, .color = {0.1f, 0.1f, 0.9f}}};
        if (order) {
            cr_render_object t = objs[0];
            objs[0] = objs[1], objs[1] = t;
        }
        cr_image img;
        CR_CHECK_OK(cr_render_scene(&def, objs, 2, &img, &err), &err);
        CR_REQUIRE(img.rgb != NULL);
        const uint8_t *c = px(&img, 32, 32), *edge = px(&img, 16, 32);
        CR_CHECK(c[0] > 150 && c[2] < 100);       /* red box in the middle */
        CR_CHECK(edge[2] > 150 && edge[0] < 100); /* blue plane around it */
        cr_image_free(&img);
    }
    cr_mesh_destroy(box);
    cr_mesh_destroy(plane);
}

CR_TEST(render, shared_edges_leave_no_gaps) {
    /* A fine grid facing the camera on a red background: with ss = 1 and an
     * odd width the centre column of samples lies exactly on grid edges, so a
     * fill rule that drops shared-edge samples shows red, one that counts
     * them twice is harmless but a gap is not. */
    cr_mesh *plane = facing_plane(41, 2.0f);
    CR_REQUIRE(plane != NULL);
    cr_error err = {0};
    cr_render_def def = small_def(101, 101);
    def.yaw_deg = 0.0f, def.pitch_deg = 0.0f;
    def.supersample = 1;
    def.background[0] = 1.0f, def.background[1] = def.background[2] = 0.0f;
    cr_render_object obj = {.mesh = plane, .color = {0.0f, 1.0f, 0.0f}};
    cr_image img;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &img, &err), &err);
    CR_REQUIRE(img.rgb != NULL);
    /* The plane covers the central square (half-diagonal sqrt(2) in a view
     * fitted to radius sqrt(2) * 1.05): check its inner part. */
    int gaps = 0;
    const uint8_t *ref = px(&img, 50, 50);
    for (int y = 25; y <= 75; y++)
        for (int x = 25; x <= 75; x++)
            gaps += !is_rgb(px(&img, x, y), ref[0], ref[1], ref[2]);
    CR_CHECK(gaps == 0);
    CR_CHECK(ref[0] == 0 && ref[1] > 200);
    cr_image_free(&img);
    cr_mesh_destroy(plane);
}

CR_TEST(render, same_image_on_any_thread_count) {
    cr_error err = {0};
    cr_mesh *torus = NULL;
    CR_REQUIRE(cr_prim_torus(1.0f, 0.4f, 48, 24, &torus, &err) == CR_OK);
    cr_render_def def = small_def(160, 120);
    def.wireframe = 1;
    def.specular = 0.4f;
    cr_render_object obj = {.mesh = torus, .color = {0.7f, 0.7f, 0.2f}};
    int threads = cr_thread_count();
    cr_image one, many;
    cr_set_thread_count(1);
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &one, &err), &err);
    cr_set_thread_count(threads > 1 ? threads : 2);
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &many, &err), &err);
    cr_set_thread_count(threads);
    CR_REQUIRE(one.rgb && many.rgb);
    CR_CHECK(memcmp(one.rgb, many.rgb, (size_t)160 * 120 * 3) == 0);
    cr_image_free(&one);
    cr_image_free(&many);
    cr_mesh_destroy(torus);
}

CR_TEST(render, colormap_ramp_is_monotonic_and_ranged) {
    cr_mesh *plane = facing_plane(17, 2.0f);
    CR_REQUIRE(plane != NULL);
    float *s = malloc((size_t)plane->nv * sizeof *s);
    CR_REQUIRE(s != NULL);
    for (int32_t i = 0; i < plane->nv; i++)
        s[i] = plane->pos[3 * i]; /* x in [-1, 1] */
    cr_error err = {0};
    cr_render_def def = small_def(80, 80);
    def.yaw_deg = 0.0f, def.pitch_deg = 0.0f;
    def.ambient = 0.3f, def.diffuse = 0.7f; /* lit = 1 facing the light: the map's own colours */
    cr_render_object obj = {.mesh = plane, .color = {1.0f, 1.0f, 1.0f}, .scalar = s};
    cr_image img;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &img, &err), &err);
    CR_REQUIRE(img.rgb != NULL);
    int first = -1, last = -1;
    for (int x = 0; x < 80; x++)
        if (!is_rgb(px(&img, x, 40), 255, 255, 255)) {
            if (first < 0) first = x;
            last = x;
        }
    /* Viridis green rises monotonically from 0.005 to 0.906; the end pixels
     * blend with the background and are left out. */
    int ok = 1;
    for (int x = first + 2; x < last; x++)
        ok &= px(&img, x, 40)[1] >= px(&img, x - 1, 40)[1];
    CR_CHECK(ok);
    CR_REQUIRE(first >= 0 && last - first > 40);
    /* One pixel in from each end, off the anti-aliased border: the colour
     * found there must sit near the ends of the map. */
    CR_CHECK(viridis_t(px(&img, first + 1, 40)) < 0.06f);
    CR_CHECK(viridis_t(px(&img, last - 1, 40)) > 0.94f);
    /* A fixed range ten times wider squeezes everything round the middle. */
    def.colormap_auto = 0;
    def.colormap_min = -10.0f, def.colormap_max = 10.0f;
    cr_image fixed;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &fixed, &err), &err);
    CR_REQUIRE(fixed.rgb != NULL);
    float t_lo = viridis_t(px(&fixed, first + 1, 40)), t_hi = viridis_t(px(&fixed, last - 1, 40));
    CR_CHECK(t_lo > 0.44f && t_lo < 0.5f);
    CR_CHECK(t_hi > 0.5f && t_hi < 0.56f);
    cr_image_free(&fixed);
    cr_image_free(&img);
    free(s);
    cr_mesh_destroy(plane);
}

CR_TEST(render, colormap_matches_viridis_endpoints) {
    float rgb[3];
    cr_colormap_viridis(0.0f, rgb);
    CR_CHECK_NEAR(rgb[0], 0.267004, 1e-6);
    CR_CHECK_NEAR(rgb[2], 0.329415, 1e-6);
    cr_colormap_viridis(0.5f, rgb); /* matplotlib entries 127 and 128 */
    CR_CHECK_NEAR(rgb[1], 0.565, 0.003);
    cr_colormap_viridis(1.0f, rgb);
    CR_CHECK_NEAR(rgb[0], 0.993248, 1e-6);
    CR_CHECK_NEAR(rgb[1], 0.906157, 1e-6);
    cr_colormap_viridis(NAN, rgb);
    CR_CHECK_NEAR(rgb[0], 0.267004, 1e-6);
    cr_colormap_viridis(7.0f, rgb);
    CR_CHECK_NEAR(rgb[2], 0.143936, 1e-6);
}

CR_TEST(render, wireframe_darkens_edges_only) {
    cr_error err = {0};
    cr_mesh *sphere = NULL;
    CR_REQUIRE(cr_prim_icosphere(1.0f, 2, &sphere, &err) == CR_OK);
    cr_render_def def = small_def(128, 128);
    cr_render_object obj = {.mesh = sphere, .color = {0.9f, 0.9f, 0.9f}};
    cr_image off, on, per_object;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &off, &err), &err);
    def.wireframe = 1;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &on, &err), &err);
    def.wireframe = 0;
    obj.wireframe = 1;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &per_object, &err), &err);
    CR_REQUIRE(off.rgb && on.rgb && per_object.rgb);
    int darker = 0, brighter = 0, covered = 0;
    for (int y = 0; y < 128; y++)
        for (int x = 0; x < 128; x++) {
            const uint8_t *a = px(&off, x, y), *b = px(&on, x, y);
            covered += !is_rgb(a, 255, 255, 255);
            darker += b[1] + 30 < a[1];
            brighter += b[1] > a[1];
        }
    CR_CHECK(darker > covered / 10);
    CR_CHECK(darker < covered * 3 / 4); /* faces stay visible between the lines */
    CR_CHECK(brighter == 0);
    CR_CHECK(memcmp(on.rgb, per_object.rgb, (size_t)128 * 128 * 3) == 0);
    cr_image_free(&off);
    cr_image_free(&on);
    cr_image_free(&per_object);
    cr_mesh_destroy(sphere);
}

CR_TEST(render, back_faces_use_the_tint) {
    /* An XZ sheet seen from above shows its front, from below its back; a
     * black back tint with no highlight makes the back face black. */
    cr_error err = {0};
    cr_mesh *plane = NULL;
    CR_REQUIRE(cr_prim_plane(5, 5, 2.0f, 2.0f, &plane, &err) == CR_OK);
    cr_render_def def = small_def(48, 48);
    def.back_tint[0] = def.back_tint[1] = def.back_tint[2] = 0.0f;
    def.ambient = 0.5f;
    cr_render_object obj = {.mesh = plane, .color = {1.0f, 1.0f, 1.0f}};
    cr_image above, below;
    def.pitch_deg = 50.0f;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &above, &err), &err);
    def.pitch_deg = -50.0f;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &below, &err), &err);
    CR_REQUIRE(above.rgb && below.rgb);
    CR_CHECK(px(&above, 24, 24)[0] > 180);
    CR_CHECK(is_rgb(px(&below, 24, 24), 0, 0, 0));
    cr_image_free(&above);
    cr_image_free(&below);
    cr_mesh_destroy(plane);
}

CR_TEST(render, png_round_trip) {
    cr_error err = {0};
    cr_mesh *torus = NULL;
    CR_REQUIRE(cr_prim_torus(1.0f, 0.3f, 32, 16, &torus, &err) == CR_OK);
    cr_render_def def = small_def(97, 61); /* odd, not a multiple of the tile */
    def.specular = 0.3f;
    cr_render_object obj = {.mesh = torus, .color = {0.2f, 0.6f, 0.3f}};
    cr_image img;
    CR_CHECK_OK(cr_render_scene(&def, &obj, 1, &img, &err), &err);
    CR_REQUIRE(img.rgb != NULL);
    char path[512];
    snprintf(path, sizeof path, "%s/render_roundtrip.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_image_write_png(&img, path, &err), &err);

    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    CR_REQUIRE(png_image_begin_read_from_file(&pi, path) != 0);
    CR_CHECK(pi.width == 97 && pi.height == 61);
    pi.format = PNG_FORMAT_RGB;
    uint8_t *back = malloc(PNG_IMAGE_SIZE(pi));
    CR_REQUIRE(back != NULL);
    CR_CHECK(png_image_finish_read(&pi, NULL, back, 0, NULL) != 0);
    CR_CHECK(memcmp(back, img.rgb, (size_t)97 * 61 * 3) == 0);
    free(back);

    /* cr_render_to_png writes the same picture. */
    char path2[512];
    snprintf(path2, sizeof path2, "%s/render_to_png.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_render_to_png(&def, &obj, 1, path2, &err), &err);
    char *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    CR_CHECK_OK(cr_file_read_all(path, &a, &na, &err), &err);
    CR_CHECK_OK(cr_file_read_all(path2, &b, &nb, &err), &err);
    CR_CHECK(a && b && na == nb && memcmp(a, b, na) == 0);
    free(a);
    free(b);
    cr_image_free(&img);
    cr_mesh_destroy(torus);
}

CR_TEST(render, turntable_writes_every_frame) {
    cr_error err = {0};
    cr_mesh *box = NULL;
    CR_REQUIRE(cr_prim_box(1.0f, 0.5f, 2.0f, 1, &box, &err) == CR_OK);
    cr_render_def def = small_def(40, 30);
    cr_render_object obj = {.mesh = box, .color = {0.5f, 0.5f, 0.8f}};
    char pattern[512], path[512];
    snprintf(pattern, sizeof pattern, "%s/turn_%%03d.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_render_turntable(&def, &obj, 1, 4, pattern, &err), &err);
    for (int k = 0; k < 4; k++) {
        snprintf(path, sizeof path, pattern, k);
        CR_CHECK(file_exists(path));
    }
    snprintf(path, sizeof path, pattern, 4);
    CR_CHECK(!file_exists(path));
    /* Frame 1 is the scene rendered at yaw + 90. */
    cr_render_def quarter = def;
    quarter.yaw_deg += 90.0f;
    char single[512];
    snprintf(single, sizeof single, "%s/turn_single.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_render_to_png(&quarter, &obj, 1, single, &err), &err);
    snprintf(path, sizeof path, pattern, 1);
    char *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    CR_CHECK_OK(cr_file_read_all(path, &a, &na, &err), &err);
    CR_CHECK_OK(cr_file_read_all(single, &b, &nb, &err), &err);
    CR_CHECK(a && b && na == nb && memcmp(a, b, na) == 0);
    free(a);
    free(b);

    CR_CHECK(cr_render_turntable(&def, &obj, 1, 4, "x_%s.png", &err) == CR_ERR_INVALID);
    CR_CHECK(cr_render_turntable(&def, &obj, 1, 4, "plain.png", &err) == CR_ERR_INVALID);
    CR_CHECK(cr_render_turntable(&def, &obj, 1, 4, "%d_%d.png", &err) == CR_ERR_INVALID);
    CR_CHECK(cr_render_turntable(&def, &obj, 1, 0, pattern, &err) == CR_ERR_INVALID);
    cr_mesh_destroy(box);
}

CR_TEST(render, grid_places_images_in_cells) {
    cr_error err = {0};
    cr_image a, b, g;
    CR_REQUIRE(cr_image_create(10, 10, &a, &err) == CR_OK);
    CR_REQUIRE(cr_image_create(20, 4, &b, &err) == CR_OK);
    memset(a.rgb, 200, (size_t)10 * 10 * 3);
    memset(b.rgb, 100, (size_t)20 * 4 * 3);
    cr_image both[2] = {a, b};
    const float white[3] = {1.0f, 1.0f, 1.0f};
    CR_CHECK_OK(cr_image_grid(both, 2, 0, 3, white, &g, &err), &err);
    CR_REQUIRE(g.rgb != NULL);
    CR_CHECK(g.width == 20 + 3 + 20 && g.height == 10);
    CR_CHECK(is_rgb(px(&g, 4, 0), 255, 255, 255)); /* a is centred: columns 5..14 */
    CR_CHECK(is_rgb(px(&g, 5, 0), 200, 200, 200));
    CR_CHECK(is_rgb(px(&g, 14, 9), 200, 200, 200));
    CR_CHECK(is_rgb(px(&g, 15, 9), 255, 255, 255));
    CR_CHECK(is_rgb(px(&g, 21, 5), 255, 255, 255)); /* the gap */
    CR_CHECK(is_rgb(px(&g, 23, 2), 255, 255, 255)); /* b sits on rows 3..6 */
    CR_CHECK(is_rgb(px(&g, 23, 3), 100, 100, 100));
    CR_CHECK(is_rgb(px(&g, 42, 6), 100, 100, 100));
    CR_CHECK(is_rgb(px(&g, 42, 7), 255, 255, 255));
    cr_image_free(&g);
    CR_CHECK_OK(cr_image_grid(both, 2, 1, 2, white, &g, &err), &err);
    CR_CHECK(g.width == 20 && g.height == 10 + 2 + 10);
    cr_image_free(&g);
    CR_CHECK(cr_image_grid(both, 0, 1, 2, white, &g, &err) == CR_ERR_INVALID);
    cr_image_free(&a);
    cr_image_free(&b);
}

CR_TEST(render, errors_name_the_problem) {
    cr_error err = {0};
    cr_mesh *sphere = NULL, *bad = NULL;
    CR_REQUIRE(cr_prim_icosphere(1.0f, 1, &sphere, &err) == CR_OK);
    CR_REQUIRE(cr_mesh_clone(sphere, &bad, &err) == CR_OK);
    cr_render_def def = small_def(32, 32);
    cr_render_object objs[2] = {{.mesh = sphere, .color = {1, 0, 0}},
                                {.mesh = bad, .color = {0, 1, 0}}};
    cr_image img;

    def.width = 0;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "size 0x32") != NULL);
    CR_CHECK(img.rgb == NULL);
    def = small_def(32, 32);

    bad->pos[3 * 5 + 1] = NAN;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "object 1") != NULL && strstr(err.msg, "vertex 5") != NULL);
    CR_CHECK(img.rgb == NULL);
    bad->pos[3 * 5 + 1] = 0.0f;

    float *s = calloc((size_t)bad->nv, sizeof *s);
    CR_REQUIRE(s != NULL);
    s[3] = INFINITY;
    objs[1].scalar = s;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "object 1") != NULL);
    objs[1].scalar = NULL;
    free(s);

    bad->tri[7] = bad->nv;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "object 1") != NULL);
    bad->tri[7] = 0;

    objs[1].mesh = NULL;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_INVALID);
    objs[1].mesh = bad;

    def.pitch_deg = 90.0f;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "pitch") != NULL);
    def = small_def(32, 32);
    def.colormap_auto = 0, def.colormap_min = 1.0f, def.colormap_max = 1.0f;
    CR_CHECK(cr_render_scene(&def, objs, 2, &img, &err) == CR_ERR_INVALID);
    def = small_def(32, 32);

    CR_CHECK(cr_render_to_png(&def, objs, 2, "/nonexistent-dir/x/out.png", &err) == CR_ERR_IO);
    CR_CHECK(strstr(err.msg, "/nonexistent-dir/x/out.png") != NULL);

    /* No objects: just the background. */
    CR_CHECK_OK(cr_render_scene(&def, NULL, 0, &img, &err), &err);
    CR_CHECK(img.rgb && is_rgb(px(&img, 16, 16), 255, 255, 255));
    cr_image_free(&img);
    cr_mesh_destroy(sphere);
    cr_mesh_destroy(bad);
}
