/* io_text.c: the line-counting tokenizer and number parsing shared by the OBJ
 * and ASCII PLY readers, and little-endian array writers for the binary
 * formats. See io_text.h.
 *
 * Numbers go through strtod/strtoll, which are correctly rounded (glibc), so
 * a float printed with %.9g reads back to the same bits; they follow the C
 * locale's decimal point, which crease never changes.
 */
#include "geom/io_text.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>

/* Longest number token we parse; longer ones are refused, not truncated. */
enum { NUMBER_MAX = 128 };

void cr_io_text_init(io_text *t, const void *data, size_t len, const char *source) {
    t->p = data;
    /* A UTF-8 byte-order mark (some Windows tools write one) is skipped. */
    if (len >= 3 && memcmp(t->p, "\xEF\xBB\xBF", 3) == 0) t->p += 3, len -= 3;
    t->end = t->p + len;
    t->source = source;
    t->line = 0;
    t->le = t->cur = t->p;
}

/* Length of the UTF-8 sequence starting at s (within [s, e)), 0 if malformed.
 * Overlong forms and surrogates are refused as RFC 3629 asks. */
static int utf8_len(const unsigned char *s, const unsigned char *e) {
    unsigned c = s[0];
    int n;
    unsigned lo = 0x80, hi = 0xbf;
    if (c >= 0xc2 && c <= 0xdf)
        n = 2;
    else if (c >= 0xe0 && c <= 0xef) {
        n = 3;
        if (c == 0xe0) lo = 0xa0;
        if (c == 0xed) hi = 0x9f;
    } else if (c >= 0xf0 && c <= 0xf4) {
        n = 4;
        if (c == 0xf0) lo = 0x90;
        if (c == 0xf4) hi = 0x8f;
    } else
        return 0;
    if (e - s < n) return 0;
    if (s[1] < lo || s[1] > hi) return 0;
    for (int i = 2; i < n; i++)
        if (s[i] < 0x80 || s[i] > 0xbf) return 0;
    return n;
}

static cr_status check_text(const io_text *t, const char *b, const char *e, cr_error *err) {
    const unsigned char *s = (const unsigned char *)b, *end = (const unsigned char *)e;
    while (s < end) {
        unsigned c = *s;
        if (c >= 0x20 && c < 0x7f) {
            s++;
            continue;
        }
        if (c == '\t' || c == '\r' || c == '\v' || c == '\f') {
            s++;
            continue;
        }
        int n = c >= 0x80 ? utf8_len(s, end) : 0;
        if (n == 0)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: expected text, found byte 0x%02x at column %lld "
                           "(binary data or not UTF-8)",
                           t->source, (long long)t->line, c,
                           (long long)(s - (const unsigned char *)b) + 1);
        s += n;
    }
    return CR_OK;
}

cr_status cr_io_text_next_line(io_text *t, int *got, cr_error *err) {
    *got = 0;
    if (t->p >= t->end) {
        t->cur = t->le = t->end;
        return CR_OK;
    }
    const char *b = t->p;
    const char *nl = memchr(b, '\n', (size_t)(t->end - b));
    const char *e = nl ? nl : t->end;
    t->p = nl ? nl + 1 : t->end;
    if (e > b && e[-1] == '\r') e--;
    t->line++;
    t->cur = b;
    t->le = e;
    CR_TRY(check_text(t, b, e, err));
    *got = 1;
    return CR_OK;
}

static int is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

int cr_io_text_token(io_text *t, const char **b, const char **e) {
    const char *s = t->cur;
    while (s < t->le && is_space(*s))
        s++;
    if (s >= t->le) {
        t->cur = t->le;
        return 0;
    }
    const char *f = s;
    while (f < t->le && !is_space(*f))
        f++;
    *b = s;
    *e = f;
    t->cur = f;
    return 1;
}

cr_status cr_io_text_token_any(io_text *t, const char **b, const char **e, int *got,
                               cr_error *err) {
    *got = 0;
    while (!cr_io_text_token(t, b, e)) {
        int more;
        CR_TRY(cr_io_text_next_line(t, &more, err));
        if (!more) return CR_OK;
    }
    *got = 1;
    return CR_OK;
}

void cr_io_text_snippet(const char *b, const char *e, char *out, size_t cap) {
    size_t n = (size_t)(e - b);
    if (n > 40) n = 40;
    if (n + 1 > cap) n = cap - 1;
    memcpy(out, b, n);
    out[n] = 0;
}

/* Copy the token into a NUL-terminated buffer; 0 if too long. */
static int token_copy(const char *b, const char *e, char buf[NUMBER_MAX]) {
    size_t n = (size_t)(e - b);
    if (n == 0 || n >= NUMBER_MAX) return 0;
    memcpy(buf, b, n);
    buf[n] = 0;
    return 1;
}

cr_status cr_io_text_double(const io_text *t, const char *b, const char *e, const char *what,
                            double *out, cr_error *err) {
    *out = 0;
    char buf[NUMBER_MAX], snip[48];
    cr_io_text_snippet(b, e, snip, sizeof snip);
    if (!token_copy(b, e, buf))
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %s, got '%s' (too long)", t->source,
                       (long long)t->line, what, snip);
    char *stop;
    errno = 0;
    double v = strtod(buf, &stop);
    if (stop == buf || *stop != 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %s, got '%s'", t->source,
                       (long long)t->line, what, snip);
    if (!isfinite(v))
        return CR_FAIL(err, CR_ERR_NAN, "%s:%lld: expected a finite %s, got '%s'", t->source,
                       (long long)t->line, what, snip);
    *out = v;
    return CR_OK;
}

cr_status cr_io_text_float(const io_text *t, const char *b, const char *e, const char *what,
                           float *out, cr_error *err) {
    *out = 0;
    double v;
    CR_TRY(cr_io_text_double(t, b, e, what, &v, err));
    if (fabs(v) > FLT_MAX) {
        char snip[48];
        cr_io_text_snippet(b, e, snip, sizeof snip);
        return CR_FAIL(err, CR_ERR_NAN, "%s:%lld: %s '%s' overflows a float", t->source,
                       (long long)t->line, what, snip);
    }
    *out = (float)v;
    return CR_OK;
}

cr_status cr_io_text_int(const io_text *t, const char *b, const char *e, const char *what,
                         int64_t *out, cr_error *err) {
    *out = 0;
    char buf[NUMBER_MAX], snip[48];
    cr_io_text_snippet(b, e, snip, sizeof snip);
    const char *s = b + (b < e && (*b == '-' || *b == '+'));
    int digits = s < e;
    for (const char *c = s; c < e; c++)
        digits &= *c >= '0' && *c <= '9';
    if (!digits || !token_copy(b, e, buf))
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: expected %s (an integer), got '%s'", t->source,
                       (long long)t->line, what, snip);
    errno = 0;
    long long v = strtoll(buf, NULL, 10);
    if (errno == ERANGE)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: %s '%s' is out of range", t->source,
                       (long long)t->line, what, snip);
    *out = v;
    return CR_OK;
}

/* Chunked conversion keeps the writers independent of the host byte order. */
enum { WRITE_CHUNK = 1024 };

int cr_io_write_f32le(FILE *fp, const float *x, size_t n) {
    unsigned char buf[4 * WRITE_CHUNK];
    for (size_t i = 0; i < n; i += WRITE_CHUNK) {
        size_t k = n - i < WRITE_CHUNK ? n - i : WRITE_CHUNK;
        for (size_t j = 0; j < k; j++)
            io_put_le32(buf + 4 * j, io_f32_bits(x[i + j]));
        if (fwrite(buf, 4, k, fp) != k) return 0;
    }
    return 1;
}

int cr_io_write_i32le(FILE *fp, const int32_t *x, size_t n) {
    unsigned char buf[4 * WRITE_CHUNK];
    for (size_t i = 0; i < n; i += WRITE_CHUNK) {
        size_t k = n - i < WRITE_CHUNK ? n - i : WRITE_CHUNK;
        for (size_t j = 0; j < k; j++)
            io_put_le32(buf + 4 * j, (uint32_t)x[i + j]);
        if (fwrite(buf, 4, k, fp) != k) return 0;
    }
    return 1;
}
