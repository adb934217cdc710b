/* npz.c: .npz archives (zip files of .npy members), read and written. See
 * crease/npz.h for what is supported and left out; npy.c holds the .npy
 * format itself.
 *
 * Reading: find the end-of-central-directory record (in the last 22 +
 * 65,535 bytes), walk the central directory (the authority on sizes, CRCs
 * and offsets: np.savez's local headers may carry ZIP64 extras and, from
 * streams, zero sizes), check each member's local header and data range
 * once at open, and inflate a member only when it is asked for.
 *
 * References: PKWARE APPNOTE.TXT 6.3, sections 4.3.7 (local header),
 * 4.3.12 (central directory), 4.3.16 (end record), 4.5.3 (ZIP64 extra);
 * zlib's inflateInit2 with negative window bits for raw deflate (RFC 1951).
 */
#include "crease/npz.h"
#include "geom/io_text.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* Deflate codes at most 258 bytes per 2-bit-ish symbol pair: no stream
 * expands past about 1032:1 (zlib's FAQ; RFC 1951 section 3.2.5). A member
 * declaring more is a bomb or corrupt; the slack covers tiny members. */
enum { DEFLATE_MAX_RATIO = 1032, DEFLATE_SLACK = 64 };
/* zlib counts in 32-bit uInt; larger members would need chunked calls. */
#define ZLIB_MAX_BYTES 0xFFFFFFFFull
enum { ZIP_LOCAL = 30, ZIP_CENTRAL = 46, ZIP_END = 22, ZIP_COMMENT_MAX = 65535 };
enum { SIG_LOCAL = 0x04034b50, SIG_CENTRAL = 0x02014b50, SIG_END = 0x06054b50 };
enum { METHOD_STORED = 0, METHOD_DEFLATED = 8, NAME_MAX_BYTES = 1024 };

static uint16_t le16(const unsigned char *p) {
    return (uint16_t)io_load(p, 2, 0);
}

static uint64_t le64(const unsigned char *p) {
    return io_load(p, 8, 0);
}

/* ----------------------------------------------------------- zip reader -- */

typedef struct npz_member {
    char *name; /* without ".npy" */
    uint16_t flags, method;
    uint32_t crc;
    uint64_t csize, usize;
    uint64_t data_off; /* start of the member's bytes in the archive */
} npz_member;

struct cr_npz {
    unsigned char *data;
    size_t len;
    char *source;
    int32_t n;
    npz_member *m;
};

void cr_npz_close(cr_npz *z) {
    if (!z) return;
    for (int32_t i = 0; i < z->n; i++)
        free(z->m[i].name);
    free(z->m);
    free(z->data);
    free(z->source);
    free(z);
}

int32_t cr_npz_count(const cr_npz *z) {
    return z->n;
}

const char *cr_npz_name(const cr_npz *z, int32_t i) {
    CR_ASSERT(i >= 0 && i < z->n);
    return z->m[i].name;
}

static const npz_member *find_member(const cr_npz *z, const char *name) {
    for (int32_t i = 0; i < z->n; i++)
        if (strcmp(z->m[i].name, name) == 0) return &z->m[i];
    return NULL;
}

int cr_npz_has(const cr_npz *z, const char *name) {
    return find_member(z, name) != NULL;
}

/* The ZIP64 extra field (id 1) replaces, in order, those of usize, csize
 * and the local offset whose 32-bit fields are all ones. */
static cr_status read_zip64_extra(const cr_npz *z, const unsigned char *x, size_t xlen,
                                  uint64_t *usize, uint64_t *csize, uint64_t *off, size_t at,
                                  cr_error *err) {
    uint64_t *want[3] = {*usize == 0xFFFFFFFFu ? usize : NULL, *csize == 0xFFFFFFFFu ? csize : NULL,
                         *off == 0xFFFFFFFFu ? off : NULL};
    if (!want[0] && !want[1] && !want[2]) return CR_OK;
    for (size_t p = 0; p + 4 <= xlen;) {
        uint16_t id = le16(x + p), sz = le16(x + p + 2);
        if (sz > xlen - p - 4) break;
        if (id == 1) {
            size_t q = p + 4;
            for (int k = 0; k < 3; k++) {
                if (!want[k]) continue;
                if (q + 8 > p + 4 + sz) break;
                *want[k] = le64(x + q);
                want[k] = NULL;
                q += 8;
            }
            break;
        }
        p += 4 + (size_t)sz;
    }
    if (want[0] || want[1] || want[2])
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte %zu: member sizes need a ZIP64 extra field that is missing",
                       z->source, at);
    return CR_OK;
}

static int name_cmp(const void *a, const void *b) {
    return strcmp(((const npz_member *)a)->name, ((const npz_member *)b)->name);
}

static cr_status check_unique_names(const cr_npz *z, cr_error *err) {
    if (z->n < 2) return CR_OK;
    npz_member *copy = cr_malloc((size_t)z->n * sizeof *copy, err);
    if (!copy) return CR_ERR_MEMORY;
    memcpy(copy, z->m, (size_t)z->n * sizeof *copy);
    qsort(copy, (size_t)z->n, sizeof *copy, name_cmp);
    cr_status st = CR_OK;
    for (int32_t i = 1; i < z->n && st == CR_OK; i++)
        if (strcmp(copy[i - 1].name, copy[i].name) == 0)
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: member '%s' appears twice", z->source,
                         copy[i].name);
    free(copy);
    return st;
}

static cr_status read_directory(cr_npz *z, cr_error *err) {
    const unsigned char *d = z->data;
    size_t len = z->len;
    if (len < ZIP_END)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %zu bytes, too short for a zip archive", z->source,
                       len);
    size_t end = 0;
    int found = 0;
    size_t lowest = len - ZIP_END > ZIP_COMMENT_MAX ? len - ZIP_END - ZIP_COMMENT_MAX : 0;
    for (size_t i = len - ZIP_END + 1; i-- > lowest;)
        if (io_le32(d + i) == SIG_END && i + ZIP_END + le16(d + i + 20) <= len) {
            end = i, found = 1;
            break;
        }
    if (!found)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: no zip end-of-central-directory record (not an .npz, or truncated)",
                       z->source);
    uint16_t disk = le16(d + end + 4), cd_disk = le16(d + end + 6);
    uint16_t n_disk = le16(d + end + 8), n = le16(d + end + 10);
    uint64_t cd_size = io_le32(d + end + 12), cd_off = io_le32(d + end + 16);
    if (n == 0xFFFF || cd_size == 0xFFFFFFFFu || cd_off == 0xFFFFFFFFu)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: byte %zu: ZIP64 end record (over 65,535 members or 4 GiB) is not "
                       "supported",
                       z->source, end);
    if (disk != 0 || cd_disk != 0 || n_disk != n)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: byte %zu: split (multi-disk) zip archive",
                       z->source, end);
    if (cd_off > end || cd_size > end - cd_off)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte %zu: central directory at %llu (+%llu bytes) lies outside the "
                       "archive",
                       z->source, end, (unsigned long long)cd_off, (unsigned long long)cd_size);
    z->m = cr_calloc(n ? n : 1, sizeof *z->m, err);
    if (!z->m) return CR_ERR_MEMORY;
    size_t p = (size_t)cd_off, cd_end = (size_t)(cd_off + cd_size);
    for (uint16_t k = 0; k < n; k++) {
        if (cd_end - p < ZIP_CENTRAL || io_le32(d + p) != SIG_CENTRAL)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: byte %zu: expected central directory entry %d of %d", z->source, p,
                           k + 1, n);
        npz_member *m = &z->m[k];
        m->flags = le16(d + p + 8);
        m->method = le16(d + p + 10);
        m->crc = io_le32(d + p + 16);
        m->csize = io_le32(d + p + 20);
        m->usize = io_le32(d + p + 24);
        size_t nlen = le16(d + p + 28), xlen = le16(d + p + 30), clen = le16(d + p + 32);
        uint64_t local = io_le32(d + p + 42);
        if (nlen + xlen + clen > cd_end - p - ZIP_CENTRAL)
            return CR_FAIL(err, CR_ERR_PARSE, "%s: byte %zu: entry %d overruns the directory",
                           z->source, p, k + 1);
        const char *name = (const char *)d + p + ZIP_CENTRAL;
        if (nlen == 0 || nlen > NAME_MAX_BYTES || memchr(name, 0, nlen))
            return CR_FAIL(err, CR_ERR_PARSE, "%s: byte %zu: entry %d has a bad name", z->source, p,
                           k + 1);
        size_t keep = nlen >= 4 && memcmp(name + nlen - 4, ".npy", 4) == 0 ? nlen - 4 : nlen;
        m->name = cr_malloc(keep + 1, err);
        if (!m->name) return CR_ERR_MEMORY;
        z->n = k + 1;
        memcpy(m->name, name, keep);
        m->name[keep] = 0;
        CR_TRY(read_zip64_extra(z, d + p + ZIP_CENTRAL + nlen, xlen, &m->usize, &m->csize, &local,
                                p, err));
        p += ZIP_CENTRAL + nlen + xlen + clen;
        /* The local header repeats the name and has its own extra field. */
        if (local > len || len - local < ZIP_LOCAL || io_le32(d + local) != SIG_LOCAL)
            return CR_FAIL(err, CR_ERR_PARSE, "%s: byte %llu: expected the local header of '%s'",
                           z->source, (unsigned long long)local, m->name);
        uint64_t start = local + ZIP_LOCAL + le16(d + local + 26) + le16(d + local + 28);
        if (start > len || m->csize > len - start)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: member '%s' declares %llu bytes at byte %llu, past the end of "
                           "the archive (truncated?)",
                           z->source, m->name, (unsigned long long)m->csize,
                           (unsigned long long)start);
        m->data_off = start;
    }
    return check_unique_names(z, err);
}

static cr_status open_owned(unsigned char *data, size_t len, const char *source, cr_npz **out,
                            cr_error *err) {
    *out = NULL;
    cr_npz *z = cr_calloc(1, sizeof *z, err);
    char *src = cr_malloc(strlen(source) + 1, err);
    if (!z || !src) {
        free(z);
        free(src);
        free(data);
        return CR_ERR_MEMORY;
    }
    strcpy(src, source);
    z->data = data, z->len = len, z->source = src;
    cr_status st = read_directory(z, err);
    if (st != CR_OK) {
        cr_npz_close(z);
        return st;
    }
    *out = z;
    return CR_OK;
}

cr_status cr_npz_open(const char *path, cr_npz **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    return open_owned((unsigned char *)buf, len, path, out, err);
}

cr_status cr_npz_open_mem(const void *data, size_t len, const char *source, cr_npz **out,
                          cr_error *err) {
    *out = NULL;
    unsigned char *copy = cr_malloc(len ? len : 1, err);
    if (!copy) return CR_ERR_MEMORY;
    if (len) memcpy(copy, data, len);
    return open_owned(copy, len, source, out, err);
}

/* Inflate member m into `out` (its declared size); `source` names it. */
static cr_status inflate_member(const cr_npz *z, const npz_member *m, const char *source,
                                unsigned char *out, cr_error *err) {
    z_stream s;
    memset(&s, 0, sizeof s);
    if (inflateInit2(&s, -MAX_WBITS) != Z_OK)
        return CR_FAIL(err, CR_ERR_MEMORY, "%s: zlib could not start inflating", source);
    s.next_in = z->data + m->data_off;
    s.avail_in = (uInt)m->csize;
    s.next_out = out;
    s.avail_out = (uInt)m->usize;
    int ret = inflate(&s, Z_FINISH);
    uint64_t produced = s.total_out;
    int out_full = s.avail_out == 0;
    char why[120];
    snprintf(why, sizeof why, "%s", s.msg ? s.msg : "corrupt data");
    inflateEnd(&s);
    if (ret == Z_STREAM_END && produced == m->usize) return CR_OK;
    if (ret == Z_MEM_ERROR)
        return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory inflating", source);
    if (ret == Z_DATA_ERROR || ret == Z_NEED_DICT)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: corrupt deflate data (%s)", source, why);
    if (out_full && ret != Z_STREAM_END)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: inflates past the %llu bytes its directory entry "
                       "declares",
                       source, (unsigned long long)m->usize);
    return CR_FAIL(err, CR_ERR_PARSE,
                   "%s: deflate stream ends early, after %llu of the %llu bytes declared "
                   "(truncated?)",
                   source, (unsigned long long)produced, (unsigned long long)m->usize);
}

cr_status cr_npz_get(const cr_npz *z, const char *name, cr_npy_as as, cr_npy *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    const npz_member *m = find_member(z, name);
    if (!m) {
        char have[300];
        int n = 0;
        have[0] = 0;
        for (int32_t i = 0; i < z->n && n < (int)sizeof have - 40; i++)
            n += snprintf(have + n, sizeof have - (size_t)n, "%s%s", i ? ", " : "", z->m[i].name);
        return CR_FAIL(err, CR_ERR_PARSE, "%s: no array '%s' (the archive holds: %s)", z->source,
                       name, z->n ? have : "nothing");
    }
    char source[600];
    snprintf(source, sizeof source, "%s: %s.npy", z->source, m->name);
    if (m->flags & 1) return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: member is encrypted", source);
    const unsigned char *bytes = z->data + m->data_off;
    unsigned char *inflated = NULL;
    if (m->method == METHOD_STORED) {
        if (m->usize != m->csize)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: stored member declares %llu bytes uncompressed, %llu stored",
                           source, (unsigned long long)m->usize, (unsigned long long)m->csize);
    } else if (m->method == METHOD_DEFLATED) {
        if (m->usize > m->csize * DEFLATE_MAX_RATIO + DEFLATE_SLACK)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: declares %llu bytes from %llu compressed, more than deflate can "
                           "expand to (a zip bomb or a corrupt directory)",
                           source, (unsigned long long)m->usize, (unsigned long long)m->csize);
        if (m->usize > ZLIB_MAX_BYTES || m->csize > ZLIB_MAX_BYTES)
            return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                           "%s: deflated members over 4 GiB are not supported", source);
        inflated = cr_malloc(m->usize ? (size_t)m->usize : 1, err);
        if (!inflated) return CR_ERR_MEMORY;
        cr_status st = inflate_member(z, m, source, inflated, err);
        if (st != CR_OK) {
            free(inflated);
            return st;
        }
        bytes = inflated;
    } else {
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: compression method %d (crease reads stored and deflated members)",
                       source, m->method);
    }
    uLong crc = crc32(0L, Z_NULL, 0);
    for (uint64_t done = 0; done < m->usize;) {
        uint64_t chunk = m->usize - done > (1u << 30) ? (1u << 30) : m->usize - done;
        crc = crc32(crc, bytes + done, (uInt)chunk);
        done += chunk;
    }
    cr_status st = CR_OK;
    if ((uint32_t)crc != m->crc)
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: CRC-32 %08x, the directory says %08x (corrupt)",
                     source, (unsigned)crc, (unsigned)m->crc);
    else
        st = cr_npy_parse(bytes, (size_t)m->usize, source, as, out, err);
    free(inflated);
    return st;
}

/* ----------------------------------------------------------- zip writer -- */

typedef struct npz_entry {
    char *name;
    uint16_t method;
    uint32_t crc, csize, usize, offset;
} npz_entry;

struct cr_npz_writer {
    cr_atomic_file f;
    int deflate;
    uint64_t offset; /* bytes written so far */
    int32_t n, cap;
    npz_entry *e;
};

/* DOS date 1980-01-01 00:00: fixed so archives are reproducible. */
enum { DOS_TIME = 0, DOS_DATE = (0 << 9) | (1 << 5) | 1, ZIP_VERSION = 20 };

static void put16(unsigned char *p, uint32_t v) {
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8);
}

static void free_writer(cr_npz_writer *w) {
    for (int32_t i = 0; i < w->n; i++)
        free(w->e[i].name);
    free(w->e);
    free(w);
}

cr_status cr_npz_writer_open(const char *path, int deflate, cr_npz_writer **out, cr_error *err) {
    *out = NULL;
    cr_npz_writer *w = cr_calloc(1, sizeof *w, err);
    if (!w) return CR_ERR_MEMORY;
    w->deflate = deflate;
    cr_status st = cr_atomic_open(&w->f, path, err);
    if (st != CR_OK) {
        free(w);
        return st;
    }
    *out = w;
    return CR_OK;
}

void cr_npz_writer_abort(cr_npz_writer *w) {
    if (!w) return;
    cr_atomic_abort(&w->f);
    free_writer(w);
}

/* Raw-deflate `len` bytes; *out = NULL (no error) when it would not shrink them. */
static cr_status deflate_bytes(const void *bytes, size_t len, unsigned char **out, size_t *out_len,
                               cr_error *err) {
    *out = NULL;
    z_stream s;
    memset(&s, 0, sizeof s);
    if (deflateInit2(&s, Z_DEFAULT_COMPRESSION, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY) !=
        Z_OK)
        return CR_FAIL(err, CR_ERR_MEMORY, "npz: zlib could not start deflating");
    uLong bound = deflateBound(&s, (uLong)len);
    unsigned char *buf = cr_malloc(bound, err);
    if (!buf) {
        deflateEnd(&s);
        return CR_ERR_MEMORY;
    }
    s.next_in = (Bytef *)bytes;
    s.avail_in = (uInt)len;
    s.next_out = buf;
    s.avail_out = (uInt)bound;
    int ret = deflate(&s, Z_FINISH);
    size_t n = s.total_out;
    deflateEnd(&s);
    if (ret != Z_STREAM_END) {
        free(buf);
        return CR_FAIL(err, CR_ERR_MEMORY, "npz: deflate failed (%d)", ret);
    }
    if (n >= len) {
        free(buf);
        return CR_OK;
    }
    *out = buf;
    *out_len = n;
    return CR_OK;
}

cr_status cr_npz_writer_add_raw(cr_npz_writer *w, const char *name, const void *bytes, size_t len,
                                cr_error *err) {
    size_t nlen = strlen(name);
    if (nlen == 0 || nlen > NAME_MAX_BYTES)
        return CR_FAIL(err, CR_ERR_INVALID, "npz: member name of %zu bytes (1 to %d)", nlen,
                       NAME_MAX_BYTES);
    for (int32_t i = 0; i < w->n; i++)
        if (strcmp(w->e[i].name, name) == 0)
            return CR_FAIL(err, CR_ERR_INVALID, "npz: member '%s' added twice", name);
    if ((uint64_t)len >= 0xFFFFFFFFull || w->offset + ZIP_LOCAL + nlen + len >= 0xFFFFFFFFull ||
        w->n >= 0xFFFF)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "%s: member '%s' would take the archive past 4 GiB or 65,535 members "
                       "(ZIP64 is not written)",
                       w->f.path, name);
    unsigned char *packed = NULL;
    size_t plen = len;
    if (w->deflate) CR_TRY(deflate_bytes(bytes, len, &packed, &plen, err));
    char *copy = cr_malloc(nlen + 1, err);
    if (copy && w->n == w->cap) {
        int32_t cap = w->cap ? 2 * w->cap : 8;
        npz_entry *grown = realloc(w->e, (size_t)cap * sizeof *grown);
        if (grown) {
            w->e = grown, w->cap = cap;
        } else {
            free(copy);
            copy = NULL;
            CR_FAIL(err, CR_ERR_MEMORY, "npz: out of memory");
        }
    }
    if (!copy) {
        free(packed);
        return CR_ERR_MEMORY;
    }
    memcpy(copy, name, nlen + 1);
    npz_entry *e = &w->e[w->n++];
    e->name = copy;
    e->crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), bytes, (uInt)len);
    e->usize = (uint32_t)len;
    e->offset = (uint32_t)w->offset;
    e->method = packed ? METHOD_DEFLATED : METHOD_STORED;
    e->csize = (uint32_t)plen;
    unsigned char h[ZIP_LOCAL];
    io_put_le32(h, SIG_LOCAL);
    put16(h + 4, ZIP_VERSION);
    put16(h + 6, 0);
    put16(h + 8, e->method);
    put16(h + 10, DOS_TIME);
    put16(h + 12, DOS_DATE);
    io_put_le32(h + 14, e->crc);
    io_put_le32(h + 18, e->csize);
    io_put_le32(h + 22, e->usize);
    put16(h + 26, (uint32_t)nlen);
    put16(h + 28, 0);
    int ok = fwrite(h, 1, sizeof h, w->f.fp) == sizeof h &&
             fwrite(name, 1, nlen, w->f.fp) == nlen &&
             fwrite(packed ? packed : bytes, 1, plen, w->f.fp) == plen;
    free(packed);
    if (!ok) return CR_FAIL(err, CR_ERR_IO, "%s: write failed", w->f.path);
    w->offset += sizeof h + nlen + plen;
    return CR_OK;
}

cr_status cr_npz_writer_add(cr_npz_writer *w, const char *name, cr_npy_dtype dtype, int32_t ndim,
                            const int64_t *shape, const void *data, cr_error *err) {
    char full[NAME_MAX_BYTES + 8];
    if (strlen(name) > NAME_MAX_BYTES - 4)
        return CR_FAIL(err, CR_ERR_INVALID, "npz: array name too long");
    snprintf(full, sizeof full, "%s.npy", name);
    unsigned char *img;
    size_t len;
    CR_TRY(cr_npy_encode(dtype, ndim, shape, data, &img, &len, err));
    cr_status st = cr_npz_writer_add_raw(w, full, img, len, err);
    free(img);
    return st;
}

cr_status cr_npz_writer_commit(cr_npz_writer *w, cr_error *err) {
    uint64_t cd_off = w->offset, cd_size = 0;
    int ok = 1;
    for (int32_t i = 0; i < w->n && ok; i++) {
        const npz_entry *e = &w->e[i];
        size_t nlen = strlen(e->name);
        unsigned char h[ZIP_CENTRAL];
        io_put_le32(h, SIG_CENTRAL);
        put16(h + 4, (3u << 8) | ZIP_VERSION); /* made by: Unix, so attributes mean rw-r--r-- */
        put16(h + 6, ZIP_VERSION);
        put16(h + 8, 0);
        put16(h + 10, e->method);
        put16(h + 12, DOS_TIME);
        put16(h + 14, DOS_DATE);
        io_put_le32(h + 16, e->crc);
        io_put_le32(h + 20, e->csize);
        io_put_le32(h + 24, e->usize);
        put16(h + 28, (uint32_t)nlen);
        put16(h + 30, 0);
        put16(h + 32, 0);
        put16(h + 34, 0);
        put16(h + 36, 0);
        io_put_le32(h + 38, 0100644u << 16);
        io_put_le32(h + 42, e->offset);
        ok = fwrite(h, 1, sizeof h, w->f.fp) == sizeof h &&
             fwrite(e->name, 1, nlen, w->f.fp) == nlen;
        cd_size += sizeof h + nlen;
    }
    if (ok && cd_off + cd_size >= 0xFFFFFFFFull) ok = 0;
    unsigned char end[ZIP_END];
    io_put_le32(end, SIG_END);
    put16(end + 4, 0);
    put16(end + 6, 0);
    put16(end + 8, (uint32_t)w->n);
    put16(end + 10, (uint32_t)w->n);
    io_put_le32(end + 12, (uint32_t)cd_size);
    io_put_le32(end + 16, (uint32_t)cd_off);
    put16(end + 20, 0);
    if (ok) ok = fwrite(end, 1, sizeof end, w->f.fp) == sizeof end;
    if (!ok) {
        cr_status st = CR_FAIL(err, CR_ERR_IO, "%s: writing the zip directory failed", w->f.path);
        cr_npz_writer_abort(w);
        return st;
    }
    cr_status st = cr_atomic_commit(&w->f, err);
    free_writer(w);
    return st;
}
