/* test_io.c: mesh and point-cache file I/O.
 *
 * OBJ index forms and polygons against hand-worked triangle lists, trailing
 * comments and a byte-order mark; a UV-seam
 * round trip OBJ -> PLY (binary, ascii) -> glb -> OBJ compared bit for bit;
 * a foreign ascii PLY and a big-endian binary PLY built byte by byte; the glb
 * sequence's JSON (morph targets, animation) and target data; PC2 round
 * trip; and bad inputs, each with its status and "<file>:<line>" or byte
 * offset in the message.
 */
#include "crease/mesh_io.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *tmp(const char *name) {
    static char path[4][512];
    static int k;
    k = (k + 1) % 4;
    snprintf(path[k], sizeof path[k], "%s/%s", cr_test_tmpdir(), name);
    return path[k];
}

static cr_status read_text(const char *text, const char *name, cr_mesh **m, cr_error *err) {
    return cr_obj_read_mem(text, strlen(text), name, m, err);
}

static int has(const cr_error *err, const char *s) {
    if (strstr(err->msg, s)) return 1;
    fprintf(stderr, "    message '%s' lacks '%s'\n", err->msg, s);
    return 0;
}

static int tri_is(const cr_mesh *m, int f, int a, int b, int c) {
    return m->tri[3 * f] == a && m->tri[3 * f + 1] == b && m->tri[3 * f + 2] == c;
}

CR_TEST(io, obj_positions_polygons_negative_indices) {
    /* CRLF, comments and skipped statements; vertex 6 duplicates vertex 1
     * and must stay (the OBJ reader does not weld). */
    const char *text = "# a test\r\no thing\r\ng part\r\nmtllib x.mtl\r\n"
                       "v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\nv 0.5 1.5 0\r\nv 0 0 0\r\n"
                       "s off\r\nusemtl red\r\n"
                       "f 1 2 3\r\n"
                       "f -6 -4 -3\r\n"  /* relative: 1 3 4 */
                       "f 1 2 3 4\r\n"   /* quad */
                       "f 1 2 3 5 4\r\n" /* pentagon */
                       "l 1 2\r\n";
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(read_text(text, "poly.obj", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 6 && m->nf == 1 + 1 + 2 + 3);
    CR_CHECK(m->nuv == 0 && !m->uv && !m->normal);
    CR_CHECK(tri_is(m, 0, 0, 1, 2));
    CR_CHECK(tri_is(m, 1, 0, 2, 3));
    CR_CHECK(tri_is(m, 2, 0, 1, 2) && tri_is(m, 3, 0, 2, 3));
    CR_CHECK(tri_is(m, 4, 0, 1, 2) && tri_is(m, 5, 0, 2, 4) && tri_is(m, 6, 0, 4, 3));
    CR_CHECK(m->pos[3 * 4 + 0] == 0.5f && m->pos[3 * 4 + 1] == 1.5f);
    cr_mesh_destroy(m);
}

CR_TEST(io, obj_uv_and_normal_index_forms) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    /* v/vt with a relative face and a quad */
    const char *vt = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                     "vt 0 0\nvt 1 0\nvt 1 1\nvt 0.25 1\n"
                     "f 1/1 2/2 3/3\nf -4/-4 -2/-2 -1/-1\nf 1/4 2/3 3/2 4/1\n";
    CR_CHECK_OK(read_text(vt, "vt.obj", &m, &err), &err);
    CR_REQUIRE(m && cr_mesh_has_uv(m));
    CR_CHECK(m->nuv == 4 && m->nf == 4 && !m->normal);
    const int32_t want_uv[12] = {0, 1, 2, 0, 2, 3, 3, 2, 1, 3, 1, 0};
    const int32_t want_v[12] = {0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 3};
    CR_CHECK(memcmp(m->tri_uv, want_uv, sizeof want_uv) == 0);
    CR_CHECK(memcmp(m->tri, want_v, sizeof want_v) == 0);
    CR_CHECK(m->uv[2 * 3] == 0.25f && m->uv[2 * 3 + 1] == 1.0f);
    cr_mesh_destroy(m);

    /* v//vn: vertex normals are the normalised mean of the vn each gets */
    const char *vn = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\n"
                     "f 1//1 2//1 3//2\nf 1//2 3//1 4//-2\n";
    CR_CHECK_OK(read_text(vn, "vn.obj", &m, &err), &err);
    CR_REQUIRE(m && m->normal);
    CR_CHECK(m->nuv == 0);
    const float h = (float)(1.0 / sqrt(2.0));
    const float want_n[12] = {0, h, h, 0, 0, 1, 0, h, h, 0, 0, 1};
    for (int i = 0; i < 12; i++)
        CR_CHECK_NEAR(m->normal[i], want_n[i], 1e-7);
    cr_mesh_destroy(m);

    /* v/vt/vn with relative indices, then a face without vn: normals dropped */
    const char *vtn = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
                      "f 1/1/1 2/2/1 3/3/1\nf -3/-3/-1 -2/-2/-1 -1/-1/-1\n";
    CR_CHECK_OK(read_text(vtn, "vtn.obj", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nf == 2 && m->nuv == 3 && m->normal && m->normal[2] == 1.0f);
    cr_mesh_destroy(m);
    char mixed_vn[256];
    snprintf(mixed_vn, sizeof mixed_vn, "%sf 1/1 2/2 3/3\n", vtn);
    CR_CHECK_OK(read_text(mixed_vn, "mixvn.obj", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nf == 3 && m->nuv == 3 && !m->normal);
    cr_mesh_destroy(m);

    /* faces with and without vt cannot be mixed */
    const char *mixed = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 2 3\n";
    CR_CHECK(read_text(mixed, "mix.obj", &m, &err) == CR_ERR_PARSE && !m);
    CR_CHECK(has(&err, "mix.obj:6:") && has(&err, "line 5"));
}

/* A ring of N columns and M rows around the Y axis whose UVs wrap: the
 * column j = 0 of vertices meets u = 0 on one side and u = 1 on the other,
 * so PLY and glb must split it. v values are not dyadic on purpose. */
enum { RING_N = 8, RING_M = 3 };

static cr_mesh *make_ring(cr_error *err) {
    cr_mesh *m;
    int nv = RING_N * RING_M, nuv = (RING_N + 1) * RING_M, nf = 2 * RING_N * (RING_M - 1);
    if (cr_mesh_create(nv, nf, nuv, &m, err) != CR_OK) return NULL;
    m->normal = calloc((size_t)nv * 3, sizeof(float));
    for (int i = 0; i < RING_M; i++) {
        for (int j = 0; j < RING_N; j++) {
            float a = 2.0f * 3.14159265f * (float)j / RING_N;
            float *p = &m->pos[3 * (i * RING_N + j)], *n = &m->normal[3 * (i * RING_N + j)];
            p[0] = cosf(a), p[1] = 0.37f * (float)i, p[2] = sinf(a);
            n[0] = cosf(a), n[1] = 0.0f, n[2] = sinf(a);
        }
        for (int j = 0; j <= RING_N; j++) {
            m->uv[2 * (i * (RING_N + 1) + j)] = (float)j / RING_N + 0.013f;
            m->uv[2 * (i * (RING_N + 1) + j) + 1] = 0.1f + 0.3f * (float)i;
        }
    }
    int f = 0;
    for (int i = 0; i + 1 < RING_M; i++)
        for (int j = 0; j < RING_N; j++) {
            int v00 = i * RING_N + j, v01 = i * RING_N + (j + 1) % RING_N;
            int v10 = v00 + RING_N, v11 = v01 + RING_N;
            int t00 = i * (RING_N + 1) + j, t01 = t00 + 1, t10 = t00 + RING_N + 1, t11 = t10 + 1;
            const int q[2][6] = {{v00, v01, v11, t00, t01, t11}, {v00, v11, v10, t00, t11, t10}};
            for (int k = 0; k < 2; k++, f++)
                for (int c = 0; c < 3; c++) {
                    m->tri[3 * f + c] = q[k][c];
                    m->tri_uv[3 * f + c] = q[k][3 + c];
                }
        }
    return m;
}

/* Same vertex count, order and positions, same triangles, same UV per corner. */
static int same_mesh(const cr_mesh *a, const cr_mesh *b, const char *stage) {
    int ok = a->nv == b->nv && a->nf == b->nf && cr_mesh_has_uv(b) &&
             memcmp(a->pos, b->pos, (size_t)a->nv * 3 * sizeof(float)) == 0 &&
             memcmp(a->tri, b->tri, (size_t)a->nf * 3 * sizeof(int32_t)) == 0;
    for (int c = 0; ok && c < 3 * a->nf; c++)
        ok = memcmp(&a->uv[2 * a->tri_uv[c]], &b->uv[2 * b->tri_uv[c]], 2 * sizeof(float)) == 0;
    for (int i = 0; ok && a->normal && i < 3 * a->nv; i++)
        ok = b->normal && fabsf(a->normal[i] - b->normal[i]) < 1e-6f;
    if (!ok) fprintf(stderr, "    round trip differs after %s\n", stage);
    return ok;
}

CR_TEST(io, seam_round_trip_obj_ply_glb_obj) {
    cr_error err = {0};
    cr_mesh *orig = make_ring(&err), *a = NULL, *b = NULL, *c = NULL, *d = NULL, *e = NULL;
    CR_REQUIRE(orig && orig->normal);
    CR_CHECK_OK(cr_obj_write(tmp("a.obj"), orig, &err), &err);
    CR_CHECK_OK(cr_obj_read(tmp("a.obj"), &a, &err), &err);
    CR_REQUIRE(a);
    CR_CHECK(a->nuv == orig->nuv && same_mesh(orig, a, "obj"));
    CR_CHECK_OK(cr_ply_write(tmp("b.ply"), a, CR_PLY_BINARY, &err), &err);
    CR_CHECK_OK(cr_ply_read(tmp("b.ply"), &b, &err), &err);
    CR_REQUIRE(b);
    /* one seam copy per ring: the file had V + M vertices, welded back to V */
    CR_CHECK(b->nuv == RING_N * RING_M + RING_M);
    CR_CHECK(same_mesh(orig, b, "binary ply"));
    CR_CHECK_OK(cr_ply_write(tmp("c.ply"), b, CR_PLY_ASCII, &err), &err);
    CR_CHECK_OK(cr_mesh_read(tmp("c.ply"), &c, &err), &err);
    CR_REQUIRE(c);
    CR_CHECK(same_mesh(orig, c, "ascii ply"));
    CR_CHECK_OK(cr_mesh_write(tmp("d.glb"), c, &err), &err);
    CR_CHECK_OK(cr_mesh_read(tmp("d.glb"), &d, &err), &err);
    CR_REQUIRE(d);
    CR_CHECK(d->nuv == RING_N * RING_M + RING_M);
    CR_CHECK(same_mesh(orig, d, "glb"));
    CR_CHECK_OK(cr_mesh_write(tmp("e.obj"), d, &err), &err);
    CR_CHECK_OK(cr_mesh_read(tmp("e.obj"), &e, &err), &err);
    CR_REQUIRE(e);
    CR_CHECK(same_mesh(orig, e, "obj again"));
    cr_mesh_destroy(orig), cr_mesh_destroy(a), cr_mesh_destroy(b);
    cr_mesh_destroy(c), cr_mesh_destroy(d), cr_mesh_destroy(e);
}

CR_TEST(io, ply_foreign_ascii_skips_what_it_does_not_read) {
    /* double positions, a colour, a list inside the vertex, UVs named u v,
     * an extra element, face flags, vertex_index with uint8/uint16 types */
    const char *text = "ply\nformat ascii 1.0\ncomment by hand\n"
                       "element vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
                       "property uchar red\nproperty list uchar float junk\n"
                       "property float u\nproperty float v\n"
                       "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
                       "element face 2\nproperty uchar flags\n"
                       "property list uint8 uint16 vertex_index\nend_header\n"
                       "0 0 0 255 2 0.5 0.25 0 0\n"
                       "1 0 0 0 0 1 0\n"
                       "1 1 0.125 10 1 7 1 1\n"
                       "0 1 0 1 3 1 2 3 0 1\n"
                       "0 1\n"
                       "7 4 0 1 2 3\n"
                       "1 3 3 2 1\n";
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_ply_read_mem(text, strlen(text), "hand.ply", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 4 && m->nf == 3 && cr_mesh_has_uv(m) && !m->normal);
    CR_CHECK(tri_is(m, 0, 0, 1, 2) && tri_is(m, 1, 0, 2, 3) && tri_is(m, 2, 3, 2, 1));
    CR_CHECK(m->pos[3 * 2 + 2] == 0.125f);
    /* corner 2 of face 1 is vertex 3, whose UV is (0, 1) */
    CR_CHECK(m->uv[2 * m->tri_uv[5]] == 0.0f && m->uv[2 * m->tri_uv[5] + 1] == 1.0f);
    cr_mesh_destroy(m);
}

static unsigned char *put_be(unsigned char *p, uint64_t v, int size) {
    for (int i = 0; i < size; i++)
        p[i] = (unsigned char)(v >> (8 * (size - 1 - i)));
    return p + size;
}

CR_TEST(io, ply_big_endian_doubles_and_extra_lists) {
    const char *head = "ply\r\nformat binary_big_endian 1.0\r\n"
                       "element vertex 3\r\nproperty double x\r\nproperty double y\r\n"
                       "property double z\r\nproperty short nx\r\n"
                       "element material 1\r\nproperty list ushort int ids\r\n"
                       "element face 1\r\nproperty list uchar uint vertex_indices\r\n"
                       "end_header\r\n";
    unsigned char buf[512];
    size_t hl = strlen(head);
    memcpy(buf, head, hl);
    unsigned char *p = buf + hl;
    const double xyz[9] = {0.1, 0.2, 0.3, -1.5, 2.0, 1e-3, 3.0, -4.0, 5.5};
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 3; k++) {
            uint64_t bits;
            memcpy(&bits, &xyz[3 * i + k], 8);
            p = put_be(p, bits, 8);
        }
        p = put_be(p, (uint64_t)(int64_t)-7, 2);
    }
    p = put_be(p, 2, 2), p = put_be(p, 11, 4), p = put_be(p, 12, 4);
    p = put_be(p, 3, 1), p = put_be(p, 2, 4), p = put_be(p, 0, 4), p = put_be(p, 1, 4);
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_ply_read_mem(buf, (size_t)(p - buf), "be.ply", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 3 && m->nf == 1 && tri_is(m, 0, 2, 0, 1) && !m->normal && !m->uv);
    for (int i = 0; i < 9; i++)
        CR_CHECK(m->pos[i] == (float)xyz[i]);
    cr_mesh_destroy(m);
    /* one byte short: the message names the byte offset and the element */
    CR_CHECK(cr_ply_read_mem(buf, (size_t)(p - buf) - 1, "be.ply", &m, &err) == CR_ERR_PARSE);
    CR_CHECK(!m && has(&err, "be.ply: byte") && has(&err, "face 0"));
}

static unsigned char *slurp(const char *path, size_t *len) {
    char *buf = NULL;
    cr_error err = {0};
    if (cr_file_read_all(path, &buf, len, &err) != CR_OK) return NULL;
    return (unsigned char *)buf;
}

static uint32_t le32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* o[key] as an int; 0 when absent (glTF's default for offsets). */
static int json_int(const cJSON *o, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) ? (int)v->valuedouble : 0;
}

CR_TEST(io, glb_sequence_declares_targets_and_animation) {
    enum { T = 5 };
    const float fps = 24.0f;
    cr_error err = {0};
    cr_mesh *rest = make_ring(&err), *back = NULL;
    CR_REQUIRE(rest);
    int nv = rest->nv;
    float *frames = malloc(sizeof(float) * 3 * (size_t)nv * T);
    for (int t = 0; t < T; t++)
        for (int i = 0; i < nv; i++)
            for (int k = 0; k < 3; k++)
                frames[(t * nv + i) * 3 + k] =
                    rest->pos[3 * i + k] + (k == 1 ? 0.01f * (float)t * rest->pos[3 * i] : 0.0f);
    const char *path = tmp("seq.glb");
    CR_CHECK_OK(cr_glb_write_sequence(path, rest, frames, T, fps, &err), &err);
    CR_CHECK_OK(cr_glb_read(path, &back, &err), &err);
    CR_REQUIRE(back);
    CR_CHECK(same_mesh(rest, back, "glb sequence"));
    cr_mesh_destroy(back);

    size_t len = 0;
    unsigned char *file = slurp(path, &len);
    CR_REQUIRE(file && len > 28 && le32(file) == 0x46546c67u && le32(file + 8) == len);
    uint32_t jlen = le32(file + 12);
    CR_REQUIRE(jlen % 4 == 0 && 20 + jlen + 8 <= len);
    const unsigned char *bin = file + 20 + jlen + 8;
    CR_CHECK(le32(file + 20 + jlen) == len - 28 - jlen);
    cJSON *root = cJSON_ParseWithLength((const char *)file + 20, jlen);
    CR_REQUIRE(root);
    const cJSON *asset = cJSON_GetObjectItem(root, "asset");
    CR_CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(asset, "version")), "2.0") == 0);
    CR_CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(asset, "generator")), "crease") == 0);
    const cJSON *accessors = cJSON_GetObjectItem(root, "accessors");
    const cJSON *views = cJSON_GetObjectItem(root, "bufferViews");
    const cJSON *mesh = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "meshes"), 0);
    const cJSON *prim = cJSON_GetArrayItem(cJSON_GetObjectItem(mesh, "primitives"), 0);
    const cJSON *targets = cJSON_GetObjectItem(prim, "targets");
    CR_REQUIRE(cJSON_GetArraySize(targets) == T);
    CR_CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(mesh, "weights")) == T);
    for (int t = 0; t < T; t++) {
        const cJSON *a =
            cJSON_GetArrayItem(accessors, json_int(cJSON_GetArrayItem(targets, t), "POSITION"));
        CR_CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(a, "min")) == 3);
        CR_CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(a, "max")) == 3);
        CR_CHECK(cJSON_GetObjectItem(cJSON_GetArrayItem(targets, t), "NORMAL") != NULL);
    }
    const cJSON *anim = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "animations"), 0);
    CR_REQUIRE(anim);
    const cJSON *channel = cJSON_GetArrayItem(cJSON_GetObjectItem(anim, "channels"), 0);
    const cJSON *target = cJSON_GetObjectItem(channel, "target");
    CR_CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(target, "path")), "weights") == 0);
    CR_CHECK(json_int(target, "node") == 0);
    const cJSON *sampler = cJSON_GetArrayItem(cJSON_GetObjectItem(anim, "samplers"), 0);
    const cJSON *in = cJSON_GetArrayItem(accessors, json_int(sampler, "input"));
    const cJSON *outw = cJSON_GetArrayItem(accessors, json_int(sampler, "output"));
    CR_CHECK(json_int(in, "count") == T && json_int(outw, "count") == T * T);
    CR_CHECK(cJSON_GetNumberValue(cJSON_GetArrayItem(cJSON_GetObjectItem(in, "max"), 0)) ==
             (double)(float)((T - 1) / (double)fps));

    /* Decode target 3: base + displacement is frame 3 (original vertices come
     * first in the split, in order), and min/max match the data. */
    const cJSON *a3 =
        cJSON_GetArrayItem(accessors, json_int(cJSON_GetArrayItem(targets, 3), "POSITION"));
    const cJSON *v3 = cJSON_GetArrayItem(views, json_int(a3, "bufferView"));
    int count = json_int(a3, "count");
    CR_CHECK(count == nv + RING_M);
    const unsigned char *d = bin + json_int(v3, "byteOffset") + json_int(a3, "byteOffset");
    double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
    for (int i = 0; i < count; i++)
        for (int k = 0; k < 3; k++) {
            uint32_t bits = le32(d + 12 * i + 4 * k);
            float x;
            memcpy(&x, &bits, 4);
            lo[k] = fmin(lo[k], x), hi[k] = fmax(hi[k], x);
            if (i < nv) CR_CHECK_NEAR(rest->pos[3 * i + k] + x, frames[(3 * nv + i) * 3 + k], 1e-6);
        }
    for (int k = 0; k < 3; k++) {
        CR_CHECK(cJSON_GetNumberValue(cJSON_GetArrayItem(cJSON_GetObjectItem(a3, "min"), k)) ==
                 lo[k]);
        CR_CHECK(cJSON_GetNumberValue(cJSON_GetArrayItem(cJSON_GetObjectItem(a3, "max"), k)) ==
                 hi[k]);
    }
    cJSON_Delete(root);
    free(file);
    free(frames);
    cr_mesh_destroy(rest);
}

CR_TEST(io, pc2_round_trip_is_exact) {
    enum { V = 7, T = 4 };
    float frames[T * V * 3];
    cr_rng r = cr_rng_make(11, 0);
    for (int i = 0; i < T * V * 3; i++)
        frames[i] = (float)cr_rng_normal(&r);
    cr_error err = {0};
    const char *path = tmp("cache.pc2");
    CR_CHECK_OK(cr_pc2_write(path, frames, V, T, 3.0f, 0.5f, &err), &err);
    cr_pc2 pc = {0};
    CR_CHECK_OK(cr_pc2_read(path, &pc, &err), &err);
    CR_REQUIRE(pc.frames);
    CR_CHECK(pc.nv == V && pc.nframes == T && pc.start_frame == 3.0f && pc.sample_rate == 0.5f);
    CR_CHECK(memcmp(pc.frames, frames, sizeof frames) == 0);
    cr_pc2_free(&pc);
    CR_CHECK(pc.frames == NULL);
    size_t len = 0;
    unsigned char *file = slurp(path, &len);
    CR_REQUIRE(file);
    CR_CHECK(len == 32 + sizeof frames && memcmp(file, "POINTCACHE2", 12) == 0);
    /* truncated by one byte */
    CR_CHECK(cr_pc2_read_mem(file, len - 1, "cut.pc2", &pc, &err) == CR_ERR_PARSE);
    CR_CHECK(!pc.frames && has(&err, "cut.pc2: byte 32"));
    /* counts whose data would be ~12 EB: refused before allocating */
    file[16] = file[17] = file[18] = 0xff, file[19] = 0x3f;
    file[28] = file[29] = file[30] = 0xff, file[31] = 0x3f;
    CR_CHECK(cr_pc2_read_mem(file, len, "huge.pc2", &pc, &err) == CR_ERR_PARSE);
    CR_CHECK(!pc.frames && has(&err, "huge.pc2: byte 32"));
    free(file);
}

static void expect_obj_error(const char *text, size_t len, const char *name, cr_status want,
                             const char *where) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    cr_status st = cr_obj_read_mem(text, len, name, &m, &err);
    if (st != want || m || !strstr(err.msg, where))
        cr_test_fail_here(__FILE__, __LINE__, "%s: got %s '%s', expected %s at '%s'", name,
                          cr_status_str(st), err.msg, cr_status_str(want), where);
    cr_mesh_destroy(m);
}

#define TRI3 "v 0 0 0\nv 1 0 0\nv 0 1 0\n"

CR_TEST(io, bad_obj_inputs_name_file_and_line) {
    expect_obj_error(TRI3 "f 1 2\n", strlen(TRI3 "f 1 2\n"), "trunc.obj", CR_ERR_PARSE,
                     "trunc.obj:4:");
    const char *nan = "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n";
    expect_obj_error(nan, strlen(nan), "nan.obj", CR_ERR_NAN, "nan.obj:2:");
    const char *inf = "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n";
    expect_obj_error(inf, strlen(inf), "inf.obj", CR_ERR_NAN, "inf.obj:3:");
    expect_obj_error(TRI3 "f 1 2 4\n", strlen(TRI3 "f 1 2 4\n"), "range.obj", CR_ERR_RANGE,
                     "range.obj:4:");
    expect_obj_error(TRI3 "f 1 -4 3\n", strlen(TRI3 "f 1 -4 3\n"), "neg.obj", CR_ERR_RANGE,
                     "neg.obj:4:");
    expect_obj_error(TRI3 "\n\nf 0 1 2\n", strlen(TRI3 "\n\nf 0 1 2\n"), "zero.obj", CR_ERR_RANGE,
                     "zero.obj:6:");
    expect_obj_error("", 0, "empty.obj", CR_ERR_TOPOLOGY, "empty.obj:1: no faces");
    expect_obj_error(TRI3, strlen(TRI3), "nofaces.obj", CR_ERR_TOPOLOGY, "nofaces.obj:3: no faces");
    const char garbage[] = "\x7f\x45\x4c\x46\x02\x01\x01\x00\x00\xff\xfe";
    expect_obj_error(garbage, sizeof garbage - 1, "garbage.obj", CR_ERR_PARSE, "garbage.obj:1:");
    expect_obj_error(TRI3 "# caf\xe9\nf 1 2 3\n", strlen(TRI3 "# caf\xe9\nf 1 2 3\n"), "latin1.obj",
                     CR_ERR_PARSE, "latin1.obj:4:");
    expect_obj_error(TRI3 "f 1 2 3\nfoo 1\n", strlen(TRI3 "f 1 2 3\nfoo 1\n"), "kw.obj",
                     CR_ERR_PARSE, "kw.obj:5:");
    expect_obj_error(TRI3 "f 1 2 x\n", strlen(TRI3 "f 1 2 x\n"), "tok.obj", CR_ERR_PARSE,
                     "tok.obj:4:");
    /* UTF-8 in a comment is text */
    cr_error err = {0};
    cr_mesh *m = NULL;
    const char *utf8 = "# caf\xc3\xa9\n" TRI3 "f 1 2 3";
    CR_CHECK_OK(read_text(utf8, "utf8.obj", &m, &err), &err);
    cr_mesh_destroy(m);
}

CR_TEST(io, obj_trailing_comments_and_byte_order_mark) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    const char *text = "\xEF\xBB\xBF# exported\n"
                       "v 0 0 0 # origin\nv 1 0 0#x\nv 0 1 0\t# y\n"
                       "vt 0 0 # uv\nvt 1 0\nvt 0 1\n"
                       "g part # group\n"
                       "f 1/1 2/2 3/3 # face\n"
                       "   # indented comment\n";
    CR_CHECK_OK(read_text(text, "comments.obj", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == 3 && m->nf == 1 && m->nuv == 3);
    CR_CHECK(tri_is(m, 0, 0, 1, 2));
    CR_CHECK(m->pos[3] == 1.0f && m->pos[7] == 1.0f);
    cr_mesh_destroy(m);
    /* the mark is skipped only at the start of the file, and a comment does
     * not hide a short face */
    expect_obj_error(TRI3 "\xEF\xBB\xBF# late\nf 1 2 3\n",
                     strlen(TRI3 "\xEF\xBB\xBF# late\nf 1 2 3\n"), "late_bom.obj", CR_ERR_PARSE,
                     "late_bom.obj:4: unknown statement");
    expect_obj_error(TRI3 "f 1 2 # 3\n", strlen(TRI3 "f 1 2 # 3\n"), "short.obj", CR_ERR_PARSE,
                     "short.obj:4: face has 2 vertices");
}

static cr_status ply_text(const char *text, const char *name, cr_mesh **m, cr_error *err) {
    return cr_ply_read_mem(text, strlen(text), name, m, err);
}

CR_TEST(io, bad_ply_inputs) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    /* two billion vertices declared, a few bytes present: refused from the
     * header alone (an attempt to allocate 24 GB would trip the sanitizers) */
    const char *big = "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                      "\x01\x02\x03\x04";
    double t0 = cr_time_now();
    CR_CHECK(ply_text(big, "big.ply", &m, &err) == CR_ERR_PARSE && !m);
    CR_CHECK(cr_time_now() - t0 < 0.1);
    CR_CHECK(has(&err, "big.ply:3:") && has(&err, "2000000000"));
    const char *bigascii =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 2000000000\n"
        "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    CR_CHECK(ply_text(bigascii, "biga.ply", &m, &err) == CR_ERR_PARSE && has(&err, "biga.ply:7:"));
    const char *fmt = "ply\nformat binary_middle_endian 1.0\nend_header\n";
    CR_CHECK(ply_text(fmt, "fmt.ply", &m, &err) == CR_ERR_UNSUPPORTED && has(&err, "fmt.ply:2:"));
    CR_CHECK(ply_text("\x89PNG\r\n\x1a\n", "png.ply", &m, &err) == CR_ERR_PARSE &&
             has(&err, "png.ply:1:"));
    const char *nanv = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                       "property float y\nproperty float z\nelement face 1\n"
                       "property list uchar int vertex_indices\nend_header\n"
                       "0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n";
    CR_CHECK(ply_text(nanv, "nan.ply", &m, &err) == CR_ERR_NAN && has(&err, "nan.ply:12:"));
    const char *range = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                        "property float y\nproperty float z\nelement face 1\n"
                        "property list uchar int vertex_indices\nend_header\n"
                        "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
    CR_CHECK(ply_text(range, "range.ply", &m, &err) == CR_ERR_RANGE && has(&err, "range.ply:13:"));
    const char *noface = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                         "property float y\nproperty float z\nend_header\n0 0 0\n";
    CR_CHECK(ply_text(noface, "noface.ply", &m, &err) == CR_ERR_TOPOLOGY && has(&err, "no faces"));

    /* a valid binary file cut short */
    cr_mesh *ring = make_ring(&err);
    CR_REQUIRE(ring);
    CR_CHECK_OK(cr_ply_write(tmp("cut.ply"), ring, CR_PLY_BINARY, &err), &err);
    size_t len = 0;
    unsigned char *file = slurp(tmp("cut.ply"), &len);
    CR_REQUIRE(file);
    CR_CHECK(cr_ply_read_mem(file, len - 5, "cut.ply", &m, &err) == CR_ERR_PARSE && !m);
    CR_CHECK(has(&err, "cut.ply: byte") && has(&err, "face"));
    /* cut into the vertices: the header's counts no longer fit (27 vertices
     * of 32 bytes, declared on line 4) */
    CR_CHECK(cr_ply_read_mem(file, len - 500, "cut2.ply", &m, &err) == CR_ERR_PARSE && !m);
    CR_CHECK(has(&err, "cut2.ply:4:") && has(&err, "'vertex'"));
    free(file);
    cr_mesh_destroy(ring);
}

/* Reassemble a glb from a JSON document and a BIN payload. */
static unsigned char *make_glb(const char *json, const unsigned char *bin, uint32_t bin_len,
                               size_t *len) {
    uint32_t jl = (uint32_t)strlen(json), jp = (jl + 3) & ~3u;
    *len = 28 + jp + bin_len;
    unsigned char *g = calloc(1, *len);
    const uint32_t head[5] = {0x46546c67u, 2, (uint32_t)*len, jp, 0x4e4f534au};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 4; k++)
            g[4 * i + k] = (unsigned char)(head[i] >> (8 * k));
    memcpy(g + 20, json, jl);
    memset(g + 20 + jl, ' ', jp - jl);
    const uint32_t bh[2] = {bin_len, 0x004e4942u};
    for (int i = 0; i < 2; i++)
        for (int k = 0; k < 4; k++)
            g[20 + jp + 4 * i + k] = (unsigned char)(bh[i] >> (8 * k));
    memcpy(g + 28 + jp, bin, bin_len);
    return g;
}

CR_TEST(io, glb_texcoord_and_bad_glb_pc2_extension) {
    cr_error err = {0};
    cr_mesh *ring = make_ring(&err), *m = NULL;
    CR_REQUIRE(ring);
    CR_CHECK_OK(cr_glb_write(tmp("ok.glb"), ring, &err), &err);
    size_t len = 0;
    unsigned char *file = slurp(tmp("ok.glb"), &len);
    CR_REQUIRE(file);
    CR_CHECK_OK(cr_glb_read_mem(file, len, "ok.glb", &m, &err), &err);
    cr_mesh_destroy(m);
    uint32_t jlen = le32(file + 12);
    cJSON *root = cJSON_ParseWithLength((const char *)file + 20, jlen);
    CR_REQUIRE(root);
    const unsigned char *bin = file + 28 + jlen;
    uint32_t bin_len = le32(file + 20 + jlen);
    /* POSITION claims more elements than its buffer view holds */
    cJSON *attrs = cJSON_GetObjectItem(
        cJSON_GetArrayItem(
            cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(root, "meshes"), 0),
                                "primitives"),
            0),
        "attributes");
    /* without the exact copy, UVs come from TEXCOORD_0 = (u, 1 - v) flipped back */
    cJSON *exact = cJSON_DetachItemFromObject(attrs, "_CREASE_UV");
    CR_REQUIRE(exact);
    cJSON_Delete(exact);
    char *json = cJSON_PrintUnformatted(root);
    size_t blen = 0;
    unsigned char *bad = make_glb(json, bin, bin_len, &blen);
    CR_CHECK_OK(cr_glb_read_mem(bad, blen, "tex.glb", &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(m->nv == ring->nv && cr_mesh_has_uv(m));
    for (int c = 0; c < 3 * ring->nf; c++)
        for (int k = 0; k < 2; k++)
            CR_CHECK_NEAR(m->uv[2 * m->tri_uv[c] + k], ring->uv[2 * ring->tri_uv[c] + k], 6e-8);
    cr_mesh_destroy(m);
    free(bad), cJSON_free(json);
    int pos_acc = json_int(attrs, "POSITION");
    cJSON *acc = cJSON_GetArrayItem(cJSON_GetObjectItem(root, "accessors"), pos_acc);
    cJSON_SetNumberValue(cJSON_GetObjectItem(acc, "count"), 1000000);
    json = cJSON_PrintUnformatted(root);
    bad = make_glb(json, bin, bin_len, &blen);
    CR_CHECK(cr_glb_read_mem(bad, blen, "acc.glb", &m, &err) == CR_ERR_RANGE && !m);
    char want[64];
    snprintf(want, sizeof want, "acc.glb: accessors[%d]", pos_acc);
    CR_CHECK(has(&err, want));
    free(bad), cJSON_free(json);
    /* a buffer view reaching past the buffer */
    cJSON_SetNumberValue(cJSON_GetObjectItem(acc, "count"), ring->nv + RING_M);
    cJSON *view =
        cJSON_GetArrayItem(cJSON_GetObjectItem(root, "bufferViews"), json_int(acc, "bufferView"));
    cJSON_SetNumberValue(cJSON_GetObjectItem(view, "byteOffset"), bin_len);
    json = cJSON_PrintUnformatted(root);
    bad = make_glb(json, bin, bin_len, &blen);
    CR_CHECK(cr_glb_read_mem(bad, blen, "view.glb", &m, &err) == CR_ERR_RANGE && !m);
    CR_CHECK(has(&err, "view.glb: bufferViews["));
    free(bad), cJSON_free(json);
    cJSON_Delete(root);
    /* truncated container, and not a glb at all */
    CR_CHECK(cr_glb_read_mem(file, len - 4, "cut.glb", &m, &err) == CR_ERR_PARSE &&
             has(&err, "cut.glb: byte 8"));
    CR_CHECK(cr_glb_read_mem("garbage garbage garbage", 23, "g.glb", &m, &err) == CR_ERR_PARSE &&
             has(&err, "g.glb: byte 0"));
    free(file);

    /* PC2 header promising more than the file holds */
    unsigned char pc2[44] = "POINTCACHE2";
    const uint32_t fields[5] = {1, 1000000, 0, 0x3f800000u, 1000};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 4; k++)
            pc2[12 + 4 * i + k] = (unsigned char)(fields[i] >> (8 * k));
    cr_pc2 pc;
    CR_CHECK(cr_pc2_read_mem(pc2, sizeof pc2, "big.pc2", &pc, &err) == CR_ERR_PARSE);
    CR_CHECK(!pc.frames && has(&err, "big.pc2: byte 32") && has(&err, "1000000 points"));

    /* dispatch by extension */
    CR_CHECK(cr_mesh_read(tmp("x.stl"), &m, &err) == CR_ERR_UNSUPPORTED && has(&err, "'.stl'"));
    CR_CHECK(cr_mesh_write(tmp("x.fbx"), ring, &err) == CR_ERR_UNSUPPORTED && has(&err, "'.fbx'"));
    /* writers never leave a partial file behind a failure */
    CR_CHECK(cr_obj_write(tmp("missing/dir/x.obj"), ring, &err) == CR_ERR_IO);
    cr_mesh_destroy(ring);
}
