/* safetensors.c: reading and writing safetensors files, and moving their
 * tensors in and out of a cr_nn_params store.
 *
 * Format (huggingface/safetensors, docs "Format"): u64 LE header length N,
 * N bytes of UTF-8 JSON, then the data buffer that the entries' data_offsets
 * index and must tile exactly. The reader trusts nothing: sizes are checked
 * against the file size before anything is allocated, and every allocation is
 * bounded by the file's own size (at most 2x for F16/BF16 converted to
 * float32). A file and a memory buffer go through the same code, behind a
 * small `source` that reads byte ranges.
 *
 * Byte order is handled by shifts, so the code is right on any host.
 * Leaves out: memory mapping, writing dtypes other than F32, the integer and
 * 8-bit float dtypes' data (validated, not loaded; see nn_checkpoint.h).
 */
#include "crease/nn_checkpoint.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    MAX_HEADER = 100000000, /* bytes; the reference implementation's limit */
    CHUNK = 16384,          /* bytes converted at a time; a multiple of every dtype size */
};
#define MAX_JSON_INT 9007199254740992.0 /* 2^53: larger integers are not exact in a double */

/* ------------------------------------------------------------- dtypes -- */

typedef struct dtype_info {
    const char *name;
    int size;    /* bytes per element */
    int convert; /* 1: loaded as float32 */
} dtype_info;

static const dtype_info DTYPES[CR_ST_DTYPE_COUNT] = {
    [CR_ST_F32] = {"F32", 4, 1},         [CR_ST_F64] = {"F64", 8, 1},
    [CR_ST_F16] = {"F16", 2, 1},         [CR_ST_BF16] = {"BF16", 2, 1},
    [CR_ST_BOOL] = {"BOOL", 1, 0},       [CR_ST_U8] = {"U8", 1, 0},
    [CR_ST_I8] = {"I8", 1, 0},           [CR_ST_U16] = {"U16", 2, 0},
    [CR_ST_I16] = {"I16", 2, 0},         [CR_ST_U32] = {"U32", 4, 0},
    [CR_ST_I32] = {"I32", 4, 0},         [CR_ST_U64] = {"U64", 8, 0},
    [CR_ST_I64] = {"I64", 8, 0},         [CR_ST_F8_E4M3] = {"F8_E4M3", 1, 0},
    [CR_ST_F8_E5M2] = {"F8_E5M2", 1, 0},
};

const char *cr_st_dtype_name(cr_st_dtype dt) {
    return dt >= 0 && dt < CR_ST_DTYPE_COUNT ? DTYPES[dt].name : "unknown";
}

static float bits_to_float(uint32_t b) {
    float f;
    memcpy(&f, &b, sizeof f);
    return f;
}

/* IEEE 754 binary16 -> binary32, exact (subnormals, Inf and NaN included). */
static float half_to_float(uint16_t h) {
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16, exp = (h >> 10) & 0x1fu, man = h & 0x3ffu;
    if (exp == 0) {
        float f = (float)man * 5.9604644775390625e-8f; /* man * 2^-24, exact */
        return sign ? -f : f;
    }
    if (exp == 31) return bits_to_float(sign | 0x7f800000u | (man << 13));
    return bits_to_float(sign | ((exp + 112u) << 23) | (man << 13));
}

static uint64_t load_u64le(const unsigned char *b) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | b[i];
    return v;
}

static void convert(cr_st_dtype dt, const unsigned char *b, int64_t n, float *out) {
    for (int64_t i = 0; i < n; i++) {
        switch (dt) {
        case CR_ST_F32:
            out[i] = bits_to_float((uint32_t)b[4 * i] | (uint32_t)b[4 * i + 1] << 8 |
                                   (uint32_t)b[4 * i + 2] << 16 | (uint32_t)b[4 * i + 3] << 24);
            break;
        case CR_ST_F64: {
            uint64_t u = load_u64le(b + 8 * i);
            double d;
            memcpy(&d, &u, sizeof d);
            out[i] = (float)d;
            break;
        }
        case CR_ST_F16:
            out[i] = half_to_float((uint16_t)(b[2 * i] | b[2 * i + 1] << 8));
            break;
        case CR_ST_BF16:
            out[i] = bits_to_float((uint32_t)b[2 * i] << 16 | (uint32_t)b[2 * i + 1] << 24);
            break;
        default:
            CR_ASSERT(!"dtype is not converted");
        }
    }
}

/* ----------------------------------------------------------- sources -- */

typedef struct source {
    const char *name;
    FILE *fp;                 /* a file, or */
    const unsigned char *mem; /* a buffer */
    uint64_t size;            /* bytes */
} source;

static cr_status source_read(const source *s, uint64_t off, void *dst, size_t len, cr_error *err) {
    CR_ASSERT(off <= s->size && len <= s->size - off);
    if (s->mem) {
        memcpy(dst, s->mem + off, len);
        return CR_OK;
    }
    errno = 0;
    if (fseeko(s->fp, (off_t)off, SEEK_SET) != 0 || fread(dst, 1, len, s->fp) != len)
        return CR_FAIL(err, CR_ERR_IO, "%s: read error at byte %llu%s%s", s->name,
                       (unsigned long long)off, errno ? ": " : "", errno ? strerror(errno) : "");
    return CR_OK;
}

/* ------------------------------------------------------------ reading -- */

/* Offset of the first byte that breaks UTF-8 (or is NUL), or len when valid.
 * Overlong forms, surrogates and code points past U+10FFFF are invalid. */
static size_t utf8_invalid_at(const unsigned char *s, size_t len) {
    size_t i = 0;
    while (i < len) {
        unsigned c = s[i];
        size_t n;
        uint32_t cp, min;
        if (c == 0) return i;
        if (c < 0x80) {
            i++;
            continue;
        } else if ((c & 0xe0) == 0xc0) {
            n = 1, cp = c & 0x1f, min = 0x80;
        } else if ((c & 0xf0) == 0xe0) {
            n = 2, cp = c & 0x0f, min = 0x800;
        } else if ((c & 0xf8) == 0xf0) {
            n = 3, cp = c & 0x07, min = 0x10000;
        } else {
            return i;
        }
        if (len - i <= n) return i;
        for (size_t k = 1; k <= n; k++) {
            if ((s[i + k] & 0xc0) != 0x80) return i;
            cp = (cp << 6) | (s[i + k] & 0x3f);
        }
        if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return i;
        i += n + 1;
    }
    return len;
}

typedef struct entry {
    cr_st_tensor t;
    uint64_t begin, end; /* bytes into the data buffer */
} entry;

static int by_name(const void *a, const void *b) {
    return strcmp(((const entry *)a)->t.name, ((const entry *)b)->t.name);
}

static int by_offset(const void *a, const void *b) {
    const entry *x = a, *y = b;
    if (x->begin != y->begin) return x->begin < y->begin ? -1 : 1;
    if (x->end != y->end) return x->end < y->end ? -1 : 1;
    return strcmp(x->t.name, y->t.name);
}

static int meta_by_key(const void *a, const void *b) {
    return strcmp(((const cr_st_meta *)a)->key, ((const cr_st_meta *)b)->key);
}

/* A JSON number that is an integer in [0, 2^53]. */
static int json_uint(const cJSON *j, uint64_t *out) {
    if (!cJSON_IsNumber(j)) return 0;
    double d = j->valuedouble;
    if (!(d >= 0.0 && d <= MAX_JSON_INT) || d != (double)(uint64_t)d) return 0;
    *out = (uint64_t)d;
    return 1;
}

static char *pool_copy(char **pool, const char *s) {
    char *dst = *pool;
    size_t n = strlen(s) + 1;
    memcpy(dst, s, n);
    *pool += n;
    return dst;
}

/* One header member "name": {"dtype", "shape", "data_offsets"} into e. */
static cr_status parse_entry(const source *s, const cJSON *item, uint64_t data_len, entry *e,
                             cr_error *err) {
    const char *name = e->t.name;
    if (!cJSON_IsObject(item))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: tensor '%s': entry is not a JSON object", s->name,
                       name);
    const cJSON *dt = cJSON_GetObjectItemCaseSensitive(item, "dtype");
    const cJSON *shape = cJSON_GetObjectItemCaseSensitive(item, "shape");
    const cJSON *offs = cJSON_GetObjectItemCaseSensitive(item, "data_offsets");
    if (!cJSON_IsString(dt) || !cJSON_IsArray(shape) || !cJSON_IsArray(offs))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: tensor '%s': needs \"dtype\" (string), \"shape\" and "
                       "\"data_offsets\" (arrays)",
                       s->name, name);
    int d = 0;
    while (d < CR_ST_DTYPE_COUNT && strcmp(DTYPES[d].name, dt->valuestring) != 0)
        d++;
    if (d == CR_ST_DTYPE_COUNT)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: tensor '%s': unknown dtype \"%.32s\"", s->name,
                       name, dt->valuestring);
    e->t.dtype = (cr_st_dtype)d;
    if (cJSON_GetArraySize(offs) != 2 || !json_uint(offs->child, &e->begin) ||
        !json_uint(offs->child->next, &e->end))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: tensor '%s': data_offsets must be two non-negative integers", s->name,
                       name);
    if (e->begin > e->end || e->end > data_len)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: tensor '%s': data_offsets [%llu, %llu] outside the %llu-byte data "
                       "buffer",
                       s->name, name, (unsigned long long)e->begin, (unsigned long long)e->end,
                       (unsigned long long)data_len);
    int ndim = cJSON_GetArraySize(shape);
    if (ndim > CR_ST_MAX_DIMS)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: tensor '%s': %d dimensions, at most %d read",
                       s->name, name, ndim, CR_ST_MAX_DIMS);
    e->t.ndim = ndim;
    int any_zero = 0, k = 0;
    const cJSON *j;
    cJSON_ArrayForEach(j, shape) {
        uint64_t v;
        if (!json_uint(j, &v))
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: tensor '%s': shape entry %d is not a non-negative integer", s->name,
                           name, k);
        e->t.shape[k++] = (int64_t)v;
        any_zero |= v == 0;
    }
    uint64_t span = e->end - e->begin, limit = span / (uint64_t)DTYPES[d].size, numel = 1;
    for (k = 0; k < ndim && !any_zero; k++) {
        uint64_t v = (uint64_t)e->t.shape[k];
        if (numel > limit / v)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: tensor '%s': shape product exceeds the %llu bytes its "
                           "data_offsets span",
                           s->name, name, (unsigned long long)span);
        numel *= v;
    }
    e->t.numel = any_zero ? 0 : (int64_t)numel;
    if ((uint64_t)e->t.numel * (uint64_t)DTYPES[d].size != span)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: tensor '%s': shape holds %lld %s values (%llu bytes) but "
                       "data_offsets span %llu bytes",
                       s->name, name, (long long)e->t.numel, DTYPES[d].name,
                       (unsigned long long)e->t.numel * (unsigned long long)DTYPES[d].size,
                       (unsigned long long)span);
    return CR_OK;
}

/* The members of the parsed header into `out` (names and metadata copied into
 * one pool) and `*entries` (ntensors, caller frees). */
static cr_status parse_header(const source *s, const cJSON *root, uint64_t data_len,
                              cr_safetensors *out, entry **entries, cr_error *err) {
    int nt = 0, nm = 0;
    size_t pool_bytes = 1;
    const cJSON *metadata = NULL, *it;
    cJSON_ArrayForEach(it, root) {
        pool_bytes += strlen(it->string) + 1;
        if (strcmp(it->string, "__metadata__") != 0) {
            nt++;
            continue;
        }
        if (metadata)
            return CR_FAIL(err, CR_ERR_PARSE, "%s: \"__metadata__\" appears twice", s->name);
        if (!cJSON_IsObject(it))
            return CR_FAIL(err, CR_ERR_PARSE, "%s: \"__metadata__\" is not an object", s->name);
        metadata = it;
        const cJSON *m;
        cJSON_ArrayForEach(m, it) {
            if (!cJSON_IsString(m))
                return CR_FAIL(err, CR_ERR_PARSE, "%s: metadata '%s' is not a string", s->name,
                               m->string);
            pool_bytes += strlen(m->string) + strlen(m->valuestring) + 2;
            nm++;
        }
    }
    out->strings_ = cr_malloc(pool_bytes, err);
    entry *e = cr_calloc((size_t)nt + 1, sizeof *e, err);
    out->meta = cr_calloc((size_t)nm + 1, sizeof *out->meta, err);
    *entries = e;
    if (!out->strings_ || !e || !out->meta) return CR_ERR_MEMORY;
    char *pool = out->strings_;
    int i = 0;
    cJSON_ArrayForEach(it, root) {
        if (it == metadata) continue;
        e[i].t.name = pool_copy(&pool, it->string);
        CR_TRY(parse_entry(s, it, data_len, &e[i], err));
        i++;
    }
    out->ntensors = nt;
    if (metadata) {
        const cJSON *m;
        i = 0;
        cJSON_ArrayForEach(m, metadata) {
            out->meta[i].key = pool_copy(&pool, m->string);
            out->meta[i].value = pool_copy(&pool, m->valuestring);
            i++;
        }
        out->nmeta = nm;
        qsort(out->meta, (size_t)nm, sizeof *out->meta, meta_by_key);
        for (i = 1; i < nm; i++)
            if (strcmp(out->meta[i - 1].key, out->meta[i].key) == 0)
                return CR_FAIL(err, CR_ERR_PARSE, "%s: metadata key '%s' appears twice", s->name,
                               out->meta[i].key);
    }
    qsort(e, (size_t)nt, sizeof *e, by_name);
    for (i = 1; i < nt; i++)
        if (strcmp(e[i - 1].t.name, e[i].t.name) == 0)
            return CR_FAIL(err, CR_ERR_PARSE, "%s: tensor '%s' appears twice", s->name,
                           e[i].t.name);
    /* The buffer must be tiled in offset order: no holes, no overlaps. */
    qsort(e, (size_t)nt, sizeof *e, by_offset);
    uint64_t at = 0;
    for (i = 0; i < nt; i++) {
        if (e[i].begin != at)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: tensor '%s': data starts at byte %llu, expected %llu (%s)", s->name,
                           e[i].t.name, (unsigned long long)e[i].begin, (unsigned long long)at,
                           e[i].begin > at ? "a hole" : "an overlap");
        at = e[i].end;
    }
    if (at != data_len)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: tensors cover %llu bytes of the %llu-byte data buffer", s->name,
                       (unsigned long long)at, (unsigned long long)data_len);
    return CR_OK;
}

/* Convert the data of every float tensor into one block. */
static cr_status read_data(const source *s, uint64_t data_start, entry *e, cr_safetensors *out,
                           cr_error *err) {
    int64_t total = 0;
    for (int i = 0; i < out->ntensors; i++)
        if (DTYPES[e[i].t.dtype].convert) total += e[i].t.numel;
    out->floats_ = cr_malloc((size_t)(total > 0 ? total : 1) * sizeof(float), err);
    if (!out->floats_) return CR_ERR_MEMORY;
    unsigned char buf[CHUNK];
    float *dst = out->floats_;
    for (int i = 0; i < out->ntensors; i++) {
        cr_st_tensor *t = &e[i].t;
        if (!DTYPES[t->dtype].convert) continue;
        t->data = dst;
        int size = DTYPES[t->dtype].size;
        for (uint64_t off = e[i].begin; off < e[i].end;) {
            size_t len = e[i].end - off < CHUNK ? (size_t)(e[i].end - off) : CHUNK;
            CR_TRY(source_read(s, data_start + off, buf, len, err));
            convert(t->dtype, buf, (int64_t)(len / (size_t)size), dst);
            dst += len / (size_t)size;
            off += len;
        }
    }
    return CR_OK;
}

/* The n-byte header as a JSON object: starts with '{', valid UTF-8, nothing
 * but whitespace after the object. */
static cr_status parse_json(const source *s, const char *hdr, size_t n, cJSON **root,
                            cr_error *err) {
    if (hdr[0] != '{')
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header does not start with '{'", s->name);
    size_t bad = utf8_invalid_at((const unsigned char *)hdr, n);
    if (bad < n)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header is not valid UTF-8 at byte %zu", s->name,
                       bad);
    const char *end = NULL;
    *root = cJSON_ParseWithLengthOpts(hdr, n, &end, 0);
    size_t at = end ? (size_t)(end - hdr) : 0;
    if (!*root)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header is not valid JSON (near byte %zu)", s->name,
                       at);
    while (at < n && (hdr[at] == ' ' || hdr[at] == '\t' || hdr[at] == '\n' || hdr[at] == '\r'))
        at++;
    if (at < n)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header has bytes after the JSON object (at %zu)",
                       s->name, at);
    return CR_OK;
}

static cr_status read_source(const source *s, cr_safetensors *out, cr_error *err) {
    unsigned char len8[8];
    if (s->size < 8)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %llu bytes, too short for the 8-byte header length",
                       s->name, (unsigned long long)s->size);
    CR_TRY(source_read(s, 0, len8, 8, err));
    uint64_t n = load_u64le(len8);
    if (n > s->size - 8)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: header length %llu exceeds the %llu bytes that follow it "
                       "(truncated or not a safetensors file)",
                       s->name, (unsigned long long)n, (unsigned long long)(s->size - 8));
    if (n > MAX_HEADER)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header length %llu exceeds the %d-byte limit",
                       s->name, (unsigned long long)n, MAX_HEADER);
    if (n < 2)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header of %llu bytes cannot hold an object", s->name,
                       (unsigned long long)n);
    char *hdr = cr_malloc((size_t)n + 1, err);
    if (!hdr) return CR_ERR_MEMORY;
    cJSON *root = NULL;
    entry *entries = NULL;
    cr_status st = source_read(s, 8, hdr, (size_t)n, err);
    hdr[n] = 0;
    if (st == CR_OK) st = parse_json(s, hdr, (size_t)n, &root, err);
    if (st == CR_OK) st = parse_header(s, root, s->size - 8 - n, out, &entries, err);
    if (st == CR_OK) st = read_data(s, 8 + n, entries, out, err);
    if (st == CR_OK) {
        out->tensors = cr_malloc(((size_t)out->ntensors + 1) * sizeof *out->tensors, err);
        if (!out->tensors) st = CR_ERR_MEMORY;
        for (int i = 0; st == CR_OK && i < out->ntensors; i++)
            out->tensors[i] = entries[i].t;
    }
    free(entries);
    cJSON_Delete(root);
    free(hdr);
    return st;
}

cr_status cr_safetensors_read_mem(const void *data, size_t size, const char *source_name,
                                  cr_safetensors *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    source s = {.name = source_name ? source_name : "(memory)", .mem = data, .size = size};
    cr_status st = read_source(&s, out, err);
    if (st != CR_OK) cr_safetensors_free(out);
    return st;
}

cr_status cr_safetensors_read(const char *path, cr_safetensors *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    FILE *fp = fopen(path, "rb");
    if (!fp) return CR_FAIL(err, CR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    source s = {.name = path, .fp = fp};
    cr_status st = CR_OK;
    off_t size = -1;
    if (fseeko(fp, 0, SEEK_END) != 0 || (size = ftello(fp)) < 0)
        st = CR_FAIL(err, CR_ERR_IO, "%s: cannot find the file size", path);
    s.size = (uint64_t)size;
    if (st == CR_OK) st = read_source(&s, out, err);
    fclose(fp);
    if (st != CR_OK) cr_safetensors_free(out);
    return st;
}

void cr_safetensors_free(cr_safetensors *st) {
    if (!st) return;
    free(st->tensors);
    free(st->meta);
    free(st->strings_);
    free(st->floats_);
    memset(st, 0, sizeof *st);
}

const cr_st_tensor *cr_safetensors_find(const cr_safetensors *st, const char *name) {
    for (int i = 0; i < st->ntensors; i++)
        if (strcmp(st->tensors[i].name, name) == 0) return &st->tensors[i];
    return NULL;
}

const char *cr_safetensors_meta(const cr_safetensors *st, const char *key) {
    for (int i = 0; i < st->nmeta; i++)
        if (strcmp(st->meta[i].key, key) == 0) return st->meta[i].value;
    return NULL;
}

/* ------------------------------------------------------------ writing -- */

/* A growing string for the header. */
typedef struct text {
    char *s;
    size_t len, cap;
    int failed;
} text;

static void put(text *t, const char *s, size_t n) {
    if (t->failed) return;
    if (t->len + n + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 4096;
        while (t->len + n + 1 > cap)
            cap *= 2;
        char *g = realloc(t->s, cap);
        if (!g) {
            t->failed = 1;
            return;
        }
        t->s = g;
        t->cap = cap;
    }
    memcpy(t->s + t->len, s, n);
    t->len += n;
    t->s[t->len] = 0;
}

static void puts_raw(text *t, const char *s) {
    put(t, s, strlen(s));
}

/* A JSON string literal: quotes, backslashes and control bytes escaped; the
 * rest is already valid UTF-8. */
static void put_json_string(text *t, const char *s) {
    put(t, "\"", 1);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        char esc[8];
        if (c == '"' || c == '\\') {
            esc[0] = '\\', esc[1] = (char)c;
            put(t, esc, 2);
        } else if (c < 0x20) {
            snprintf(esc, sizeof esc, "\\u%04x", c);
            put(t, esc, 6);
        } else {
            put(t, (const char *)&c, 1);
        }
    }
    put(t, "\"", 1);
}

static cr_status check_string(const char *path, const char *what, const char *s, cr_error *err) {
    if (!s || !*s) return CR_FAIL(err, CR_ERR_INVALID, "%s: %s is empty", path, what);
    size_t n = strlen(s);
    if (utf8_invalid_at((const unsigned char *)s, n) < n)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %s '%s' is not valid UTF-8", path, what, s);
    return CR_OK;
}

static cr_status check_write_args(const char *path, const cr_st_tensor *t, int n,
                                  const cr_st_meta *meta, int nmeta, cr_error *err) {
    for (int i = 0; i < n; i++) {
        CR_TRY(check_string(path, "tensor name", t[i].name, err));
        if (strcmp(t[i].name, "__metadata__") == 0)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: '__metadata__' cannot name a tensor", path);
        if (t[i].ndim < 0 || t[i].ndim > CR_ST_MAX_DIMS)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s': %d dimensions", path, t[i].name,
                           t[i].ndim);
        int64_t numel = 1;
        for (int d = 0; d < t[i].ndim; d++) {
            int64_t v = t[i].shape[d];
            if (v < 0 || (v > 0 && numel > INT64_MAX / 4 / v))
                return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s': bad size %lld", path,
                               t[i].name, (long long)v);
            numel *= v;
        }
        if (numel > 0 && !t[i].data)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s' has no data", path, t[i].name);
        for (int j = 0; j < i; j++)
            if (strcmp(t[i].name, t[j].name) == 0)
                return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s' given twice", path, t[i].name);
    }
    for (int i = 0; i < nmeta; i++) {
        CR_TRY(check_string(path, "metadata key", meta[i].key, err));
        if (!meta[i].value)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: metadata '%s' has no value", path,
                           meta[i].key);
        size_t vn = strlen(meta[i].value);
        if (utf8_invalid_at((const unsigned char *)meta[i].value, vn) < vn)
            return CR_FAIL(err, CR_ERR_INVALID, "%s: metadata '%s' is not valid UTF-8", path,
                           meta[i].key);
        for (int j = 0; j < i; j++)
            if (strcmp(meta[i].key, meta[j].key) == 0)
                return CR_FAIL(err, CR_ERR_INVALID, "%s: metadata '%s' given twice", path,
                               meta[i].key);
    }
    return CR_OK;
}

static int64_t shape_numel(int ndim, const int64_t *shape) {
    int64_t n = 1;
    for (int d = 0; d < ndim; d++)
        n *= shape[d];
    return n;
}

/* The header, padded with spaces so that 8 + its length is a multiple of 8. */
static cr_status build_header(const char *path, const cr_st_tensor *t, int n,
                              const cr_st_meta *meta, int nmeta, text *h, cr_error *err) {
    char num[64];
    puts_raw(h, "{");
    if (nmeta > 0) {
        puts_raw(h, "\"__metadata__\":{");
        for (int i = 0; i < nmeta; i++) {
            if (i) puts_raw(h, ",");
            put_json_string(h, meta[i].key);
            puts_raw(h, ":");
            put_json_string(h, meta[i].value);
        }
        puts_raw(h, "}");
    }
    uint64_t at = 0;
    for (int i = 0; i < n; i++) {
        if (i || nmeta > 0) puts_raw(h, ",");
        put_json_string(h, t[i].name);
        puts_raw(h, ":{\"dtype\":\"F32\",\"shape\":[");
        for (int d = 0; d < t[i].ndim; d++) {
            snprintf(num, sizeof num, "%s%lld", d ? "," : "", (long long)t[i].shape[d]);
            puts_raw(h, num);
        }
        uint64_t bytes = (uint64_t)shape_numel(t[i].ndim, t[i].shape) * sizeof(float);
        snprintf(num, sizeof num, "],\"data_offsets\":[%llu,%llu]}", (unsigned long long)at,
                 (unsigned long long)(at + bytes));
        puts_raw(h, num);
        at += bytes;
    }
    puts_raw(h, "}");
    while (!h->failed && (8 + h->len) % 8 != 0)
        puts_raw(h, " ");
    if (h->failed)
        return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory building the header", path);
    return CR_OK;
}

cr_status cr_safetensors_write(const char *path, const cr_st_tensor *tensors, int n,
                               const cr_st_meta *meta, int nmeta, cr_error *err) {
    CR_ASSERT(n >= 0 && nmeta >= 0 && (tensors || n == 0) && (meta || nmeta == 0));
    CR_TRY(check_write_args(path, tensors, n, meta, nmeta, err));
    text h = {0};
    CR_TRY(build_header(path, tensors, n, meta, nmeta, &h, err));
    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st != CR_OK) {
        free(h.s);
        return st;
    }
    unsigned char buf[CHUNK];
    for (int i = 0; i < 8; i++)
        buf[i] = (unsigned char)((uint64_t)h.len >> (8 * i));
    fwrite(buf, 1, 8, f.fp);
    fwrite(h.s, 1, h.len, f.fp);
    free(h.s);
    for (int i = 0; i < n; i++) {
        int64_t numel = shape_numel(tensors[i].ndim, tensors[i].shape);
        const float *src = tensors[i].data;
        for (int64_t k = 0; k < numel;) {
            int64_t m = numel - k < CHUNK / 4 ? numel - k : CHUNK / 4;
            for (int64_t j = 0; j < m; j++) {
                uint32_t b;
                memcpy(&b, &src[k + j], sizeof b);
                for (int q = 0; q < 4; q++)
                    buf[4 * j + q] = (unsigned char)(b >> (8 * q));
            }
            fwrite(buf, 1, (size_t)m * 4, f.fp);
            k += m;
        }
    }
    return cr_atomic_commit(&f, err);
}

/* ---------------------------------------------------------- parameters -- */

cr_status cr_safetensors_save_params(const char *path, cr_nn_params *p, const cr_st_meta *meta,
                                     int nmeta, cr_error *err) {
    int n = cr_nn_params_count(p);
    cr_st_tensor *t = cr_calloc((size_t)n + 1, sizeof *t, err);
    if (!t) return CR_ERR_MEMORY;
    for (int i = 0; i < n; i++) {
        cr_tensor *x = cr_nn_params_at(p, i, &t[i].name);
        t[i].dtype = CR_ST_F32;
        t[i].ndim = x->ndim;
        for (int d = 0; d < x->ndim; d++)
            t[i].shape[d] = x->shape[d];
        t[i].numel = x->numel;
        t[i].data = x->data;
    }
    cr_status st = cr_safetensors_write(path, t, n, meta, nmeta, err);
    free(t);
    return st;
}

static void st_shape_str(const cr_st_tensor *t, char *buf, size_t cap) {
    size_t at = (size_t)snprintf(buf, cap, "(");
    for (int d = 0; d < t->ndim && at < cap; d++)
        at += (size_t)snprintf(buf + at, cap - at, "%s%lld", d ? "," : "", (long long)t->shape[d]);
    if (at < cap) snprintf(buf + at, cap - at, ")");
}

cr_status cr_safetensors_check_tensor(const cr_safetensors *st, const char *source,
                                      const char *name, const cr_tensor *x, cr_error *err) {
    const cr_st_tensor *t = cr_safetensors_find(st, name);
    if (!t) return CR_FAIL(err, CR_ERR_PARSE, "%s: no tensor '%s'", source, name);
    int same = t->ndim == x->ndim;
    for (int d = 0; same && d < x->ndim; d++)
        same = t->shape[d] == x->shape[d];
    if (!same) {
        char a[160], b[64];
        st_shape_str(t, a, sizeof a);
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: tensor '%s' has shape %s, the model expects %s",
                       source, name, a, cr_nn_shape_str(x, b, sizeof b));
    }
    if (!DTYPES[t->dtype].convert)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: tensor '%s' has dtype %s; parameters load from F32, F64, F16 or BF16",
                       source, name, DTYPES[t->dtype].name);
    for (int64_t k = 0; k < t->numel; k++)
        if (!isfinite(t->data[k]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: tensor '%s' element %lld is %g", source, name,
                           (long long)k, (double)t->data[k]);
    return CR_OK;
}

cr_status cr_safetensors_to_params(const cr_safetensors *st, const char *source, cr_nn_params *p,
                                   int allow_extra, cr_error *err) {
    int n = cr_nn_params_count(p);
    for (int i = 0; i < n; i++) {
        const char *name;
        cr_tensor *x = cr_nn_params_at(p, i, &name);
        CR_TRY(cr_safetensors_check_tensor(st, source, name, x, err));
    }
    for (int i = 0; i < st->ntensors && !allow_extra; i++)
        if (!cr_nn_params_find(p, st->tensors[i].name))
            return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s' is not a parameter of the model",
                           source, st->tensors[i].name);
    for (int i = 0; i < n; i++) {
        const char *name;
        cr_tensor *x = cr_nn_params_at(p, i, &name);
        const cr_st_tensor *t = cr_safetensors_find(st, name);
        if (x->numel > 0) memcpy(x->data, t->data, (size_t)x->numel * sizeof(float));
    }
    return CR_OK;
}

cr_status cr_safetensors_load_params(const char *path, cr_nn_params *p, int allow_extra,
                                     cr_error *err) {
    cr_safetensors st;
    CR_TRY(cr_safetensors_read(path, &st, err));
    cr_status s = cr_safetensors_to_params(&st, path, p, allow_extra, err);
    cr_safetensors_free(&st);
    return s;
}
