/* test_npz.c: .npy parsing (dtypes, byte orders, Fortran order, versions),
 * .npz archives built by hand here (stored and zlib-deflated members, a
 * ZIP64 local extra as np.savez writes), the writer's round trips, and
 * malformed inputs: truncations, flipped bytes, bad CRCs, unknown dtypes,
 * zip bombs, size lies. */
#include "crease/npz.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* ---------------------------------------------------- hand-made .npy bytes -- */

typedef struct buf {
    unsigned char *p;
    size_t n, cap;
} buf;

static void put(buf *b, const void *data, size_t n) {
    if (b->n + n > b->cap) {
        b->cap = 2 * (b->n + n) + 64;
        b->p = realloc(b->p, b->cap);
    }
    if (n) memcpy(b->p + b->n, data, n);
    b->n += n;
}

static void put_le(buf *b, uint64_t v, int bytes) {
    unsigned char t[8];
    for (int i = 0; i < bytes; i++)
        t[i] = (unsigned char)(v >> (8 * i));
    put(b, t, (size_t)bytes);
}

/* A .npy image written the way numpy does it (version 1 or 2 header). */
static buf npy(const char *dict, const void *data, size_t n, int version) {
    buf b = {0};
    size_t pre = version == 1 ? 10 : 12, len = strlen(dict) + 1;
    size_t pad = (64 - (pre + len) % 64) % 64;
    put(&b, "\x93NUMPY", 6);
    unsigned char v[2] = {(unsigned char)version, 0};
    put(&b, v, 2);
    put_le(&b, len + pad, version == 1 ? 2 : 4);
    put(&b, dict, strlen(dict));
    for (size_t i = 0; i < pad; i++)
        put(&b, " ", 1);
    put(&b, "\n", 1);
    put(&b, data, n);
    return b;
}

CR_TEST(npz, npy_dtypes_orders_and_versions) {
    cr_error err = {0};
    cr_npy a;
    double d[6] = {1.5, -2, 3.25, 4, 5, 6e10};
    buf b = npy("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }", d, sizeof d, 1);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "a.npy", CR_NPY_AS_F32, &a, &err), &err);
    CR_CHECK(a.dtype == CR_NPY_F64 && a.ndim == 2 && a.shape[0] == 2 && a.shape[1] == 3);
    CR_CHECK(a.count == 6 && a.f32 && a.f32[2] == 3.25f && a.f32[5] == 6e10f);
    cr_npy_free(&a);
    free(b.p);
    /* Fortran order: file holds columns; reading gives C order. */
    float fo[6] = {1, 4, 2, 5, 3, 6}; /* the (2,3) matrix [[1,2,3],[4,5,6]] by columns */
    b = npy("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }", fo, sizeof fo, 1);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "f.npy", CR_NPY_AS_F64, &a, &err), &err);
    for (int i = 0; i < 6; i++)
        CR_CHECK(a.f64[i] == i + 1);
    cr_npy_free(&a);
    free(b.p);
    /* Big-endian float32 and a version 2.0 header. */
    unsigned char be[8] = {0x3f, 0x80, 0, 0, 0xc0, 0x20, 0, 0}; /* 1.0, -2.5 */
    b = npy("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }", be, 8, 2);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "b.npy", CR_NPY_AS_F32, &a, &err), &err);
    CR_CHECK(a.count == 2 && a.f32[0] == 1.0f && a.f32[1] == -2.5f);
    cr_npy_free(&a);
    free(b.p);
    /* Integers: int64 to int32 (Python 2's "3L" shape), uint32 as double, a scalar. */
    int64_t i8[3] = {-7, 0, 2147483647};
    b = npy("{'descr': '<i8', 'fortran_order': False, 'shape': (3L,), }", i8, sizeof i8, 1);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "i.npy", CR_NPY_AS_I32, &a, &err), &err);
    CR_CHECK(a.i32[0] == -7 && a.i32[2] == 2147483647);
    cr_npy_free(&a);
    free(b.p);
    uint32_t u4 = 4294967295u;
    b = npy("{'shape': (), 'fortran_order': False, 'descr': '<u4'}", &u4, 4, 1);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "u.npy", CR_NPY_AS_F64, &a, &err), &err);
    CR_CHECK(a.ndim == 0 && a.count == 1 && a.f64[0] == 4294967295.0);
    cr_npy_free(&a);
    /* ... but not as int32. */
    CR_CHECK(cr_npy_parse(b.p, b.n, "u.npy", CR_NPY_AS_I32, &a, &err) == CR_ERR_RANGE);
    CR_CHECK(strstr(err.msg, "u.npy") && strstr(err.msg, "int32"));
    free(b.p);
    /* An empty array is fine. */
    b = npy("{'descr': '<f4', 'fortran_order': False, 'shape': (0, 3), }", NULL, 0, 1);
    CR_CHECK_OK(cr_npy_parse(b.p, b.n, "e.npy", CR_NPY_AS_F32, &a, &err), &err);
    CR_CHECK(a.count == 0 && a.shape[1] == 3);
    cr_npy_free(&a);
    free(b.p);
}

CR_TEST(npz, npy_refuses_bad_headers_and_values) {
    cr_error err = {0};
    cr_npy a;
    float f[4] = {1, 2, NAN, 4};
    struct {
        const char *dict;
        size_t n;
        cr_status st;
        const char *says;
    } cases[] = {
        {"{'descr': '<U6', 'fortran_order': False, 'shape': (1,), }", 24, CR_ERR_UNSUPPORTED,
         "'<U6'"},
        {"{'descr': '|O', 'fortran_order': False, 'shape': (1,), }", 8, CR_ERR_UNSUPPORTED, "'|O'"},
        {"{'descr': '<f4', 'fortran_order': False, }", 16, CR_ERR_PARSE, "'shape'"},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (3,), }", 16, CR_ERR_PARSE,
         "needs 12 data bytes, the array holds 16"},
        {"{'descr': '<f4', 'fortran_order': Maybe, 'shape': (4,), }", 16, CR_ERR_PARSE, "True"},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (4,), 'x': 1}", 16, CR_ERR_PARSE,
         "'x'"},
        {"{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (4,), }", 16, CR_ERR_PARSE,
         "structured"},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999,), }", 16,
         CR_ERR_PARSE, "'shape'"},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (4,), }", 16, CR_ERR_NAN,
         "element [2]"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        buf b = npy(cases[i].dict, f, cases[i].n <= 16 ? cases[i].n : 16, 1);
        if (cases[i].n > 16) put(&b, f, cases[i].n - 16);
        cr_status st = cr_npy_parse(b.p, b.n, "bad.npy", CR_NPY_AS_F32, &a, &err);
        CR_CHECK(st == cases[i].st);
        CR_CHECK(strstr(err.msg, "bad.npy") && strstr(err.msg, cases[i].says));
        if (st == CR_OK) cr_npy_free(&a);
        free(b.p);
    }
    /* Floats are not integers. */
    buf b = npy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }", f, 8, 1);
    CR_CHECK(cr_npy_parse(b.p, b.n, "g.npy", CR_NPY_AS_I32, &a, &err) == CR_ERR_PARSE);
    /* Every truncation fails cleanly. */
    for (size_t n = 0; n < b.n; n++)
        CR_CHECK(cr_npy_parse(b.p, n, "t.npy", CR_NPY_AS_F32, &a, &err) != CR_OK);
    free(b.p);
}

/* ------------------------------------------------- hand-made zip archives -- */

typedef struct member {
    const char *name;
    const unsigned char *data;
    size_t n;
    int deflate, zip64_local;
    uint32_t lie_usize; /* when nonzero, the directory declares this size */
    uint16_t flags, method_override;
    int bad_crc;
} member;

static buf raw_deflate(const unsigned char *p, size_t n) {
    z_stream s;
    memset(&s, 0, sizeof s);
    deflateInit2(&s, 9, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
    buf out = {0};
    out.cap = deflateBound(&s, (uLong)n) + 16;
    out.p = malloc(out.cap);
    s.next_in = (Bytef *)p;
    s.avail_in = (uInt)n;
    s.next_out = out.p;
    s.avail_out = (uInt)out.cap;
    deflate(&s, Z_FINISH);
    out.n = s.total_out;
    deflateEnd(&s);
    return out;
}

/* A zip archive assembled field by field (APPNOTE 4.3.7, 4.3.12, 4.3.16). */
static buf zip(const member *m, int n) {
    buf z = {0}, cd = {0};
    for (int i = 0; i < n; i++) {
        buf packed = m[i].deflate ? raw_deflate(m[i].data, m[i].n) : (buf){0};
        const unsigned char *body = m[i].deflate ? packed.p : m[i].data;
        size_t bn = m[i].deflate ? packed.n : m[i].n, nl = strlen(m[i].name);
        uint32_t crc = (uint32_t)crc32(0, m[i].data, (uInt)m[i].n) ^ (m[i].bad_crc ? 1u : 0u);
        uint32_t usize = m[i].lie_usize ? m[i].lie_usize : (uint32_t)m[i].n;
        uint16_t method = m[i].method_override ? m[i].method_override : m[i].deflate ? 8 : 0;
        size_t off = z.n;
        put_le(&z, 0x04034b50, 4);
        put_le(&z, m[i].zip64_local ? 45 : 20, 2);
        put_le(&z, m[i].flags, 2);
        put_le(&z, method, 2);
        put_le(&z, 0, 4); /* time, date */
        put_le(&z, crc, 4);
        put_le(&z, bn, 4);
        put_le(&z, usize, 4);
        put_le(&z, nl, 2);
        put_le(&z, m[i].zip64_local ? 20 : 0, 2);
        put(&z, m[i].name, nl);
        if (m[i].zip64_local) { /* as np.savez (force_zip64) writes it */
            put_le(&z, 1, 2);
            put_le(&z, 16, 2);
            put_le(&z, m[i].n, 8);
            put_le(&z, bn, 8);
        }
        put(&z, body, bn);
        put_le(&cd, 0x02014b50, 4);
        put_le(&cd, 20, 2);
        put_le(&cd, 20, 2);
        put_le(&cd, m[i].flags, 2);
        put_le(&cd, method, 2);
        put_le(&cd, 0, 4);
        put_le(&cd, crc, 4);
        put_le(&cd, bn, 4);
        put_le(&cd, usize, 4);
        put_le(&cd, nl, 2);
        put_le(&cd, 0, 2);
        put_le(&cd, 0, 2);
        put_le(&cd, 0, 4); /* disk, internal attributes */
        put_le(&cd, 0, 4);
        put_le(&cd, off, 4);
        put(&cd, m[i].name, nl);
        free(packed.p);
    }
    size_t cd_off = z.n;
    put(&z, cd.p, cd.n);
    put_le(&z, 0x06054b50, 4);
    put_le(&z, 0, 4);
    put_le(&z, (uint64_t)n, 2);
    put_le(&z, (uint64_t)n, 2);
    put_le(&z, cd.n, 4);
    put_le(&z, cd_off, 4);
    put_le(&z, 0, 2);
    free(cd.p);
    return z;
}

CR_TEST(npz, reads_stored_deflated_and_zip64_members) {
    cr_error err = {0};
    float x[300];
    for (int i = 0; i < 300; i++)
        x[i] = (float)(i % 7) * 0.5f;
    int32_t k[4] = {3, 1, 4, 1};
    buf a = npy("{'descr': '<f4', 'fortran_order': False, 'shape': (100, 3), }", x, sizeof x, 1);
    buf b = npy("{'descr': '<i4', 'fortran_order': False, 'shape': (2, 2), }", k, sizeof k, 1);
    buf s = npy("{'descr': '<U6', 'fortran_order': False, 'shape': (), }",
                "f\0\0\0e\0\0\0m\0\0\0"
                "a\0\0\0l\0\0\0e\0\0\0",
                24, 1);
    member m[3] = {{"poses.npy", a.p, a.n, 1, 1, 0, 0, 0, 0},
                   {"faces.npy", b.p, b.n, 0, 0, 0, 0, 0, 0},
                   {"gender.npy", s.p, s.n, 1, 0, 0, 0, 0, 0}};
    buf z = zip(m, 3);
    cr_npz *npz = NULL;
    CR_CHECK_OK(cr_npz_open_mem(z.p, z.n, "hand.npz", &npz, &err), &err);
    CR_REQUIRE(npz);
    CR_CHECK(cr_npz_count(npz) == 3 && strcmp(cr_npz_name(npz, 0), "poses") == 0);
    CR_CHECK(cr_npz_has(npz, "faces") && !cr_npz_has(npz, "faces.npy"));
    cr_npy p, f, g;
    CR_CHECK_OK(cr_npz_get(npz, "poses", CR_NPY_AS_F32, &p, &err), &err);
    CR_CHECK(p.shape[0] == 100 && p.shape[1] == 3 && memcmp(p.f32, x, sizeof x) == 0);
    CR_CHECK_OK(cr_npz_get(npz, "faces", CR_NPY_AS_I32, &f, &err), &err);
    CR_CHECK(f.count == 4 && memcmp(f.i32, k, sizeof k) == 0);
    /* The string member is listed but refused by name; the others still load. */
    CR_CHECK(cr_npz_get(npz, "gender", CR_NPY_AS_F32, &g, &err) == CR_ERR_UNSUPPORTED);
    CR_CHECK(strstr(err.msg, "hand.npz: gender.npy") && strstr(err.msg, "<U6"));
    CR_CHECK(cr_npz_get(npz, "betas", CR_NPY_AS_F32, &g, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "'betas'") && strstr(err.msg, "poses, faces, gender"));
    cr_npy_free(&p);
    cr_npy_free(&f);
    cr_npz_close(npz);
    /* Every prefix and every flipped byte: a status, never a crash (ASan watches). */
    for (size_t n = 0; n < z.n; n++) {
        if (cr_npz_open_mem(z.p, n, "cut.npz", &npz, &err) == CR_OK) {
            cr_npz_get(npz, "poses", CR_NPY_AS_F32, &p, &err);
            cr_npy_free(&p);
            cr_npz_close(npz);
        }
        CR_CHECK(strstr(err.msg, "cut.npz") != NULL);
    }
    int opened = 0;
    for (size_t i = 0; i < z.n; i++) {
        z.p[i] ^= 0xA5;
        if (cr_npz_open_mem(z.p, z.n, "flip.npz", &npz, &err) == CR_OK) {
            for (int32_t j = 0; j < cr_npz_count(npz); j++) {
                if (cr_npz_get(npz, cr_npz_name(npz, j), CR_NPY_AS_F64, &p, &err) == CR_OK)
                    opened++;
                cr_npy_free(&p);
            }
            cr_npz_close(npz);
        }
        z.p[i] ^= 0xA5;
    }
    CR_CHECK(opened > 0); /* flips in names and padding leave members readable */
    free(z.p);
    free(a.p);
    free(b.p);
    free(s.p);
}

CR_TEST(npz, refuses_bombs_lies_and_corruption) {
    cr_error err = {0};
    unsigned char zeros[4096] = {0};
    buf a =
        npy("{'descr': '<f4', 'fortran_order': False, 'shape': (1024,), }", zeros, sizeof zeros, 1);
    struct {
        member m;
        cr_status st;
        const char *says;
    } cases[] = {
        /* 4 KiB of zeros deflate to a few bytes; declaring 2 GiB is a bomb. */
        {{"a.npy", a.p, a.n, 1, 0, 0x80000000u, 0, 0, 0}, CR_ERR_PARSE, "more than deflate"},
        {{"a.npy", a.p, a.n, 1, 0, (uint32_t)a.n - 1, 0, 0, 0}, CR_ERR_PARSE, "inflates past"},
        {{"a.npy", a.p, a.n, 1, 0, (uint32_t)a.n + 8, 0, 0, 0}, CR_ERR_PARSE, "ends early"},
        {{"a.npy", a.p, a.n, 0, 0, (uint32_t)a.n + 8, 0, 0, 0}, CR_ERR_PARSE, "stored"},
        {{"a.npy", a.p, a.n, 1, 0, 0, 0, 0, 1}, CR_ERR_PARSE, "CRC-32"},
        {{"a.npy", a.p, a.n, 0, 0, 0, 1, 0, 0}, CR_ERR_UNSUPPORTED, "encrypted"},
        {{"a.npy", a.p, a.n, 0, 0, 0, 0, 12, 0}, CR_ERR_UNSUPPORTED, "method 12"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        buf z = zip(&cases[i].m, 1);
        cr_npz *npz = NULL;
        cr_npy x;
        CR_CHECK_OK(cr_npz_open_mem(z.p, z.n, "bomb.npz", &npz, &err), &err);
        if (npz) {
            CR_CHECK(cr_npz_get(npz, "a", CR_NPY_AS_F32, &x, &err) == cases[i].st);
            CR_CHECK(strstr(err.msg, "bomb.npz: a.npy") && strstr(err.msg, cases[i].says));
            cr_npz_close(npz);
        }
        free(z.p);
    }
    /* Duplicate names; a directory pointing past the end; not a zip at all. */
    member twice[2] = {{"a.npy", a.p, a.n, 0, 0, 0, 0, 0, 0},
                       {"a.npy", a.p, a.n, 1, 0, 0, 0, 0, 0}};
    buf z = zip(twice, 2);
    cr_npz *npz = NULL;
    CR_CHECK(cr_npz_open_mem(z.p, z.n, "dup.npz", &npz, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "'a' appears twice"));
    z.p[z.n - 3] = 0x7f; /* top byte of the central directory's offset */
    CR_CHECK(cr_npz_open_mem(z.p, z.n, "off.npz", &npz, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "outside the archive"));
    free(z.p);
    CR_CHECK(cr_npz_open_mem(a.p, a.n, "plain.npy", &npz, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "end-of-central-directory") && npz == NULL);
    free(a.p);
}

CR_TEST(npz, writer_round_trips_every_dtype) {
    cr_error err = {0};
    char path[512];
    float f4[6] = {0.1f, -2, 3e-30f, 4e30f, 5, 6};
    double f8[3] = {0.1, -1e300, 12345.678};
    int32_t i4[4] = {-2147483647 - 1, -1, 0, 2147483647};
    int64_t i8[2] = {-5, 1};
    uint32_t u4[2] = {0, 4294967295u};
    int64_t s23[2] = {2, 3}, s3[1] = {3}, s4[1] = {4}, s2[1] = {2};
    for (int deflate = 0; deflate < 2; deflate++) {
        snprintf(path, sizeof path, "%s/all_%d.npz", cr_test_tmpdir(), deflate);
        cr_npz_writer *w = NULL;
        CR_CHECK_OK(cr_npz_writer_open(path, deflate, &w, &err), &err);
        CR_REQUIRE(w);
        CR_CHECK_OK(cr_npz_writer_add(w, "f4", CR_NPY_F32, 2, s23, f4, &err), &err);
        CR_CHECK_OK(cr_npz_writer_add(w, "f8", CR_NPY_F64, 1, s3, f8, &err), &err);
        CR_CHECK_OK(cr_npz_writer_add(w, "i4", CR_NPY_I32, 1, s4, i4, &err), &err);
        CR_CHECK_OK(cr_npz_writer_add(w, "i8", CR_NPY_I64, 1, s2, i8, &err), &err);
        CR_CHECK_OK(cr_npz_writer_add(w, "u4", CR_NPY_U32, 1, s2, u4, &err), &err);
        CR_CHECK_OK(cr_npz_writer_add(w, "zeros", CR_NPY_F32, 0, NULL, &f4[0], &err), &err);
        CR_CHECK(cr_npz_writer_add(w, "f4", CR_NPY_F32, 1, s2, f4, &err) == CR_ERR_INVALID);
        CR_CHECK_OK(cr_npz_writer_commit(w, &err), &err);
        cr_npz *z = NULL;
        CR_CHECK_OK(cr_npz_open(path, &z, &err), &err);
        CR_REQUIRE(z);
        CR_CHECK(cr_npz_count(z) == 6);
        cr_npy a;
        CR_CHECK_OK(cr_npz_get(z, "f4", CR_NPY_AS_F32, &a, &err), &err);
        CR_CHECK(a.dtype == CR_NPY_F32 && a.ndim == 2 && memcmp(a.f32, f4, sizeof f4) == 0);
        cr_npy_free(&a);
        CR_CHECK_OK(cr_npz_get(z, "f8", CR_NPY_AS_F64, &a, &err), &err);
        CR_CHECK(a.dtype == CR_NPY_F64 && memcmp(a.f64, f8, sizeof f8) == 0);
        cr_npy_free(&a);
        CR_CHECK(cr_npz_get(z, "f8", CR_NPY_AS_F32, &a, &err) == CR_ERR_NAN); /* -1e300 */
        CR_CHECK_OK(cr_npz_get(z, "i4", CR_NPY_AS_I32, &a, &err), &err);
        CR_CHECK(memcmp(a.i32, i4, sizeof i4) == 0);
        cr_npy_free(&a);
        CR_CHECK_OK(cr_npz_get(z, "i8", CR_NPY_AS_I32, &a, &err), &err);
        CR_CHECK(a.i32[0] == -5 && a.i32[1] == 1);
        cr_npy_free(&a);
        CR_CHECK_OK(cr_npz_get(z, "u4", CR_NPY_AS_F64, &a, &err), &err);
        CR_CHECK(a.dtype == CR_NPY_U32 && a.f64[1] == 4294967295.0);
        cr_npy_free(&a);
        CR_CHECK_OK(cr_npz_get(z, "zeros", CR_NPY_AS_F32, &a, &err), &err);
        CR_CHECK(a.ndim == 0 && a.f32[0] == f4[0]);
        cr_npy_free(&a);
        cr_npz_close(z);
    }
    /* Deflating shrinks a compressible array; the standalone .npy round trip. */
    float big[2048] = {0};
    int64_t sb[1] = {2048};
    size_t sizes[2];
    for (int deflate = 0; deflate < 2; deflate++) {
        snprintf(path, sizeof path, "%s/big_%d.npz", cr_test_tmpdir(), deflate);
        cr_npz_writer *w = NULL;
        CR_CHECK_OK(cr_npz_writer_open(path, deflate, &w, &err), &err);
        CR_REQUIRE(w);
        CR_CHECK_OK(cr_npz_writer_add(w, "big", CR_NPY_F32, 1, sb, big, &err), &err);
        CR_CHECK_OK(cr_npz_writer_commit(w, &err), &err);
        FILE *fp = fopen(path, "rb");
        CR_REQUIRE(fp);
        fseek(fp, 0, SEEK_END);
        sizes[deflate] = (size_t)ftell(fp);
        fclose(fp);
    }
    CR_CHECK(sizes[0] > sizeof big && sizes[1] < 400);
    snprintf(path, sizeof path, "%s/one.npy", cr_test_tmpdir());
    CR_CHECK_OK(cr_npy_write(path, CR_NPY_F64, 1, s3, f8, &err), &err);
    cr_npy a;
    CR_CHECK_OK(cr_npy_read(path, CR_NPY_AS_F64, &a, &err), &err);
    CR_CHECK(a.count == 3 && memcmp(a.f64, f8, sizeof f8) == 0);
    cr_npy_free(&a);
    /* The header is padded to 64 bytes like numpy's. */
    FILE *fp = fopen(path, "rb");
    unsigned char head[128];
    CR_REQUIRE(fp && fread(head, 1, sizeof head, fp) >= 64);
    fclose(fp);
    CR_CHECK((10 + head[8] + 256 * head[9]) % 64 == 0 && head[9 + head[8]] == '\n');
}
