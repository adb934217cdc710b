/* npy.c: the .npy array format: parsing (header dict, dtype, byte order,
 * Fortran order, exact data length), conversion to float32, float64 or
 * int32 with range and finiteness checks, and encoding (version 1.0 header
 * padded to 64 bytes, little-endian C-order data). See crease/npz.h for
 * what is supported and left out; npz.c puts these in zip archives.
 *
 * Reference: numpy/lib/format.py (NEP 1, "A simple file format for NumPy
 * arrays").
 */
#include "crease/npz.h"
#include "geom/io_text.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { NPY_HEADER_ALIGN = 64 };

static const char *const dtype_names[CR_NPY_DTYPE_COUNT] = {"<f4", "<f8", "<i4", "<i8", "<u4"};
static const int dtype_size[CR_NPY_DTYPE_COUNT] = {4, 8, 4, 8, 4};

const char *cr_npy_dtype_str(cr_npy_dtype dtype) {
    CR_ASSERT(dtype >= 0 && dtype < CR_NPY_DTYPE_COUNT);
    return dtype_names[dtype];
}

static uint16_t le16(const unsigned char *p) {
    return (uint16_t)io_load(p, 2, 0);
}

/* ------------------------------------------------------------ npy header -- */

typedef struct npy_header {
    cr_npy_dtype dtype;
    int big_endian, fortran;
    int32_t ndim;
    int64_t shape[CR_NPY_MAX_DIMS];
    int64_t count;
    size_t data_off; /* bytes before the data */
} npy_header;

/* A cursor over the header's dict literal. */
typedef struct dict_cursor {
    const char *p, *e;
} dict_cursor;

static void skip_ws(dict_cursor *c) {
    while (c->p < c->e && (*c->p == ' ' || *c->p == '\t' || *c->p == '\n' || *c->p == '\r'))
        c->p++;
}

static int take(dict_cursor *c, char ch) {
    skip_ws(c);
    if (c->p < c->e && *c->p == ch) {
        c->p++;
        return 1;
    }
    return 0;
}

/* A quoted string without escapes into out (cap bytes); 0 when malformed. */
static int take_string(dict_cursor *c, char *out, size_t cap) {
    skip_ws(c);
    if (c->p >= c->e || (*c->p != '\'' && *c->p != '"')) return 0;
    char q = *c->p++;
    size_t n = 0;
    while (c->p < c->e && *c->p != q) {
        if (*c->p == '\\' || n + 1 >= cap) return 0;
        out[n++] = *c->p++;
    }
    if (c->p >= c->e) return 0;
    c->p++;
    out[n] = 0;
    return 1;
}

static int take_word(dict_cursor *c, const char *w) {
    skip_ws(c);
    size_t n = strlen(w);
    if ((size_t)(c->e - c->p) < n || memcmp(c->p, w, n) != 0) return 0;
    c->p += n;
    return 1;
}

/* (d0, d1, ...) with an optional trailing comma; Python 2's "3L" is accepted. */
static int take_shape(dict_cursor *c, npy_header *h) {
    if (!take(c, '(')) return 0;
    h->ndim = 0;
    for (;;) {
        skip_ws(c);
        if (c->p < c->e && *c->p == ')') break;
        if (c->p >= c->e || *c->p < '0' || *c->p > '9' || h->ndim == CR_NPY_MAX_DIMS) return 0;
        int64_t v = 0;
        while (c->p < c->e && *c->p >= '0' && *c->p <= '9') {
            if (v > (INT64_MAX / 4 - 9) / 10) return 0; /* keeps products checkable */
            v = v * 10 + (*c->p++ - '0');
        }
        if (c->p < c->e && *c->p == 'L') c->p++;
        h->shape[h->ndim++] = v;
        if (!take(c, ',')) break;
    }
    return take(c, ')');
}

static cr_status header_fail(const char *source, const char *what, cr_error *err) {
    return CR_FAIL(err, CR_ERR_PARSE, "%s: .npy header: %s", source, what);
}

static cr_status parse_dtype(const char *s, npy_header *h, const char *source, cr_error *err) {
    char canon[4] = {'<', 0, 0, 0};
    if (strlen(s) == 3 && (s[0] == '<' || s[0] == '>')) {
        canon[1] = s[1], canon[2] = s[2];
        for (int t = 0; t < CR_NPY_DTYPE_COUNT; t++)
            if (strcmp(canon, dtype_names[t]) == 0) {
                h->dtype = (cr_npy_dtype)t;
                h->big_endian = s[0] == '>';
                return CR_OK;
            }
    }
    return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                   "%s: dtype '%s' is not supported (crease reads <f4 <f8 <i4 <i8 <u4, either "
                   "byte order)",
                   source, s);
}

static cr_status parse_header(const unsigned char *d, size_t len, const char *source, npy_header *h,
                              cr_error *err) {
    memset(h, 0, sizeof *h);
    if (len < 10 || memcmp(d, "\x93NUMPY", 6) != 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: byte 0: expected the .npy magic '\\x93NUMPY'",
                       source);
    size_t hoff, hlen;
    if (d[6] == 1) {
        hoff = 10, hlen = le16(d + 8);
    } else if (d[6] == 2 || d[6] == 3) {
        if (len < 12) return header_fail(source, "truncated before the header length", err);
        hoff = 12, hlen = io_le32(d + 8);
    } else {
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: byte 6: .npy version %d.%d (expected 1, 2 or 3)", source, d[6], d[7]);
    }
    if (hlen > len - hoff)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: .npy header declares %zu bytes, %zu follow", source,
                       hlen, len - hoff);
    dict_cursor c = {(const char *)d + hoff, (const char *)d + hoff + hlen};
    int have_descr = 0, have_order = 0, have_shape = 0;
    if (!take(&c, '{')) return header_fail(source, "expected '{'", err);
    while (!take(&c, '}')) {
        char key[32], val[64];
        if (!take_string(&c, key, sizeof key) || !take(&c, ':'))
            return header_fail(source, "expected a quoted key and ':'", err);
        if (strcmp(key, "descr") == 0 && !have_descr) {
            if (!take_string(&c, val, sizeof val))
                return header_fail(source,
                                   "'descr' must be a dtype string (structured dtypes "
                                   "are not supported)",
                                   err);
            CR_TRY(parse_dtype(val, h, source, err));
            have_descr = 1;
        } else if (strcmp(key, "fortran_order") == 0 && !have_order) {
            if (take_word(&c, "True"))
                h->fortran = 1;
            else if (!take_word(&c, "False"))
                return header_fail(source, "'fortran_order' must be True or False", err);
            have_order = 1;
        } else if (strcmp(key, "shape") == 0 && !have_shape) {
            if (!take_shape(&c, h))
                return header_fail(source, "'shape' must be a tuple of at most 8 sizes", err);
            have_shape = 1;
        } else {
            char msg[80];
            snprintf(msg, sizeof msg, "unexpected or repeated key '%s'", key);
            return header_fail(source, msg, err);
        }
        if (!take(&c, ',')) {
            if (!take(&c, '}')) return header_fail(source, "expected ',' or '}'", err);
            break;
        }
    }
    skip_ws(&c);
    if (c.p != c.e) return header_fail(source, "text after the closing '}'", err);
    if (!have_descr || !have_order || !have_shape)
        return header_fail(source, "needs the keys 'descr', 'fortran_order' and 'shape'", err);
    h->count = 1;
    for (int k = 0; k < h->ndim; k++) {
        if (h->shape[k] != 0 && h->count > INT64_MAX / 8 / h->shape[k])
            return header_fail(source, "shape has too many elements", err);
        h->count *= h->shape[k];
    }
    h->data_off = hoff + hlen;
    uint64_t need = (uint64_t)h->count * (uint64_t)dtype_size[h->dtype];
    if (need != len - h->data_off) {
        char shape[160];
        int n = snprintf(shape, sizeof shape, "(");
        for (int k = 0; k < h->ndim && n < (int)sizeof shape - 24; k++)
            n += snprintf(shape + n, sizeof shape - (size_t)n, k ? ", %lld" : "%lld",
                          (long long)h->shape[k]);
        snprintf(shape + n, sizeof shape - (size_t)n, ")");
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: shape %s of %s needs %llu data bytes, the array holds %zu", source,
                       shape, dtype_names[h->dtype], (unsigned long long)need, len - h->data_off);
    }
    return CR_OK;
}

/* ----------------------------------------------------------- conversion -- */

/* Offset (in elements) in the file of the element at C-order index i. */
static int64_t file_index(const npy_header *h, int64_t i) {
    if (!h->fortran || h->ndim < 2) return i;
    int64_t off = 0, stride = 1, rest = i;
    int64_t idx[CR_NPY_MAX_DIMS];
    for (int k = h->ndim - 1; k >= 0; k--) {
        idx[k] = rest % h->shape[k];
        rest /= h->shape[k];
    }
    for (int k = 0; k < h->ndim; k++) {
        off += idx[k] * stride;
        stride *= h->shape[k];
    }
    return off;
}

/* "[2, 0, 1]" for the element at C-order index i. */
static void format_index(const npy_header *h, int64_t i, char *out, size_t cap) {
    int64_t idx[CR_NPY_MAX_DIMS];
    for (int k = h->ndim - 1; k >= 0; k--) {
        idx[k] = i % h->shape[k];
        i /= h->shape[k];
    }
    int n = snprintf(out, cap, "[");
    for (int k = 0; k < h->ndim && n < (int)cap - 24; k++)
        n += snprintf(out + n, cap - (size_t)n, k ? ", %lld" : "%lld", (long long)idx[k]);
    snprintf(out + n, cap - (size_t)n, "]");
}

static int is_float_dtype(cr_npy_dtype t) {
    return t == CR_NPY_F32 || t == CR_NPY_F64;
}

static double load_double(const unsigned char *p, const npy_header *h) {
    uint64_t u = io_load(p, dtype_size[h->dtype], h->big_endian);
    switch (h->dtype) {
    case CR_NPY_F32:
        return io_f32((uint32_t)u);
    case CR_NPY_F64:
        return io_f64(u);
    case CR_NPY_I32:
        return (int32_t)(uint32_t)u;
    case CR_NPY_I64:
        return (double)(int64_t)u;
    case CR_NPY_U32:
        return (uint32_t)u;
    default:
        CR_ASSERT(0 && "unhandled dtype");
        return 0;
    }
}

static int64_t load_int(const unsigned char *p, const npy_header *h) {
    uint64_t u = io_load(p, dtype_size[h->dtype], h->big_endian);
    switch (h->dtype) {
    case CR_NPY_I32:
        return (int32_t)(uint32_t)u;
    case CR_NPY_I64:
        return (int64_t)u;
    case CR_NPY_U32:
        return (int64_t)(uint32_t)u;
    default:
        CR_ASSERT(0 && "not an integer dtype");
        return 0;
    }
}

static cr_status convert(const unsigned char *data, const npy_header *h, const char *source,
                         cr_npy_as as, cr_npy *out, cr_error *err) {
    size_t n = (size_t)h->count, size = (size_t)dtype_size[h->dtype];
    if (as == CR_NPY_AS_I32 && is_float_dtype(h->dtype))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: dtype %s, expected integers", source,
                       dtype_names[h->dtype]);
    size_t elem = as == CR_NPY_AS_F64 ? sizeof(double) : 4;
    void *buf = cr_malloc(n ? n * elem : 1, err);
    if (!buf) return CR_ERR_MEMORY;
    for (size_t i = 0; i < n; i++) {
        const unsigned char *p = data + (size_t)file_index(h, (int64_t)i) * size;
        int bad = 0;
        if (as == CR_NPY_AS_I32) {
            int64_t v = load_int(p, h);
            bad = v < INT32_MIN || v > INT32_MAX;
            ((int32_t *)buf)[i] = (int32_t)v;
        } else {
            double v = load_double(p, h);
            bad = !isfinite(v) || (as == CR_NPY_AS_F32 && fabs(v) > FLT_MAX);
            if (as == CR_NPY_AS_F64)
                ((double *)buf)[i] = v;
            else
                ((float *)buf)[i] = (float)v;
        }
        if (bad) {
            char idx[200];
            format_index(h, (int64_t)i, idx, sizeof idx);
            free(buf);
            return CR_FAIL(err, as == CR_NPY_AS_I32 ? CR_ERR_RANGE : CR_ERR_NAN,
                           "%s: element %s is %s", source, idx,
                           as == CR_NPY_AS_I32 ? "out of int32 range"
                                               : "not finite (or overflows a float)");
        }
    }
    if (as == CR_NPY_AS_F32) out->f32 = buf;
    if (as == CR_NPY_AS_F64) out->f64 = buf;
    if (as == CR_NPY_AS_I32) out->i32 = buf;
    return CR_OK;
}

cr_status cr_npy_parse(const void *data, size_t len, const char *source, cr_npy_as as, cr_npy *out,
                       cr_error *err) {
    memset(out, 0, sizeof *out);
    npy_header h;
    CR_TRY(parse_header(data, len, source, &h, err));
    CR_TRY(convert((const unsigned char *)data + h.data_off, &h, source, as, out, err));
    out->dtype = h.dtype;
    out->ndim = h.ndim;
    memcpy(out->shape, h.shape, sizeof h.shape);
    out->count = h.count;
    return CR_OK;
}

cr_status cr_npy_read(const char *path, cr_npy_as as, cr_npy *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_npy_parse(buf, len, path, as, out, err);
    free(buf);
    return st;
}

void cr_npy_free(cr_npy *a) {
    if (!a) return;
    free(a->f32);
    free(a->f64);
    free(a->i32);
    memset(a, 0, sizeof *a);
}

/* ----------------------------------------------------------- npy writer -- */

cr_status cr_npy_encode(cr_npy_dtype dtype, int32_t ndim, const int64_t *shape, const void *data,
                        unsigned char **out, size_t *out_len, cr_error *err) {
    CR_ASSERT(dtype >= 0 && dtype < CR_NPY_DTYPE_COUNT);
    if (ndim < 0 || ndim > CR_NPY_MAX_DIMS)
        return CR_FAIL(err, CR_ERR_INVALID, "npy: %d dimensions (0 to %d allowed)", ndim,
                       CR_NPY_MAX_DIMS);
    char dict[400];
    int n = snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': (",
                     dtype_names[dtype]);
    int64_t count = 1;
    for (int k = 0; k < ndim; k++) {
        if (shape[k] < 0 || (shape[k] && count > INT64_MAX / 8 / shape[k]))
            return CR_FAIL(err, CR_ERR_INVALID, "npy: dimension %d has size %lld", k,
                           (long long)shape[k]);
        count *= shape[k];
        n += snprintf(dict + n, sizeof dict - (size_t)n, "%lld%s", (long long)shape[k],
                      ndim == 1      ? ","
                      : k + 1 < ndim ? ", "
                                     : "");
    }
    n += snprintf(dict + n, sizeof dict - (size_t)n, "), }");
    size_t hoff = 10, hlen = (size_t)n + 1; /* + '\n' */
    hlen += (NPY_HEADER_ALIGN - (hoff + hlen) % NPY_HEADER_ALIGN) % NPY_HEADER_ALIGN;
    size_t size = (size_t)dtype_size[dtype], bytes = hoff + hlen + (size_t)count * size;
    unsigned char *b = cr_malloc(bytes, err);
    if (!b) return CR_ERR_MEMORY;
    memcpy(b, "\x93NUMPY\x01\x00", 8);
    b[8] = (unsigned char)(hlen & 0xff), b[9] = (unsigned char)(hlen >> 8);
    memset(b + hoff, ' ', hlen);
    memcpy(b + hoff, dict, (size_t)n);
    b[hoff + hlen - 1] = '\n';
    const unsigned char *src = data;
    unsigned char *dst = b + hoff + hlen;
    for (int64_t i = 0; i < count; i++) {
        uint64_t v = 0;
        if (size == 4) {
            uint32_t u;
            memcpy(&u, src + (size_t)i * 4, 4);
            v = u;
        } else {
            memcpy(&v, src + (size_t)i * 8, 8);
        }
        for (size_t k = 0; k < size; k++)
            dst[(size_t)i * size + k] = (unsigned char)(v >> (8 * k));
    }
    *out = b;
    *out_len = bytes;
    return CR_OK;
}

cr_status cr_npy_write(const char *path, cr_npy_dtype dtype, int32_t ndim, const int64_t *shape,
                       const void *data, cr_error *err) {
    unsigned char *img;
    size_t len;
    CR_TRY(cr_npy_encode(dtype, ndim, shape, data, &img, &len, err));
    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st == CR_OK) {
        if (fwrite(img, 1, len, f.fp) != len) {
            cr_atomic_abort(&f);
            st = CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
        } else {
            st = cr_atomic_commit(&f, err);
        }
    }
    free(img);
    return st;
}
