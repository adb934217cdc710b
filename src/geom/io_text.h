/* io_text.h: private helpers shared by the mesh format readers and writers.
 *
 * A line-counting tokenizer for the text formats (OBJ, ASCII PLY): it hands
 * out lines without their end-of-line (LF or CRLF), refuses bytes that are
 * not text (control characters, NUL, malformed UTF-8) with the line and
 * column, splits lines into whitespace-separated tokens and parses numbers
 * with messages "<source>:<line>: expected ..., got '...'".
 *
 * Byte-order loads and stores for the binary formats (PLY, glb, PC2), written
 * byte by byte so they work on any host and on unaligned data.
 */
#ifndef CREASE_GEOM_IO_TEXT_H
#define CREASE_GEOM_IO_TEXT_H

#include "crease/base.h"

#include <string.h>

typedef struct io_text {
    const char *p, *end; /* unread input */
    const char *source;  /* file name for messages */
    int64_t line;        /* 1-based number of the current line, 0 before the first */
    const char *le;      /* end of the current line (end-of-line excluded) */
    const char *cur;     /* tokenizer cursor within the current line */
} io_text;

/* Skips a leading UTF-8 byte-order mark. */
void cr_io_text_init(io_text *t, const void *data, size_t len, const char *source);

/* Move to the next line; *got = 0 at the end of the input. Fails on bytes
 * that are not text. */
cr_status cr_io_text_next_line(io_text *t, int *got, cr_error *err);

/* Next whitespace-separated token [*b, *e) of the current line; 0 when the
 * line has no more. */
int cr_io_text_token(io_text *t, const char **b, const char **e);

/* Next token, moving on to later lines as needed (ASCII PLY bodies); *got = 0
 * at the end of the input. */
cr_status cr_io_text_token_any(io_text *t, const char **b, const char **e, int *got, cr_error *err);

/* Parse the whole token as a number. `what` names the expected value in the
 * message ("x coordinate"). Non-finite values fail with CR_ERR_NAN.
 * cr_io_text_double, _float and _int set *out to 0 when they fail. */
cr_status cr_io_text_double(const io_text *t, const char *b, const char *e, const char *what,
                            double *out, cr_error *err);
/* Like cr_io_text_double, also refusing values a float cannot hold. */
cr_status cr_io_text_float(const io_text *t, const char *b, const char *e, const char *what,
                           float *out, cr_error *err);
/* A decimal integer, optional sign, nothing else. */
cr_status cr_io_text_int(const io_text *t, const char *b, const char *e, const char *what,
                         int64_t *out, cr_error *err);

/* Token text for messages: at most 40 bytes, quoted by the caller. */
void cr_io_text_snippet(const char *b, const char *e, char *out, size_t cap);

/* ------------------------------------------------------- byte order -- */

/* Unsigned load of `size` (1, 2, 4 or 8) bytes. */
static inline uint64_t io_load(const unsigned char *p, int size, int big_endian) {
    uint64_t v = 0;
    for (int i = 0; i < size; i++) {
        int k = big_endian ? i : size - 1 - i;
        v = (v << 8) | p[k];
    }
    return v;
}

static inline uint32_t io_le32(const unsigned char *p) {
    return (uint32_t)io_load(p, 4, 0);
}

static inline float io_f32(uint32_t bits) {
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static inline double io_f64(uint64_t bits) {
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

static inline void io_put_le32(unsigned char *p, uint32_t v) {
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static inline uint32_t io_f32_bits(float f) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* Write n floats as little-endian float32; 0 on a write error. */
int cr_io_write_f32le(FILE *fp, const float *x, size_t n);
/* Write n int32 as little-endian; 0 on a write error. */
int cr_io_write_i32le(FILE *fp, const int32_t *x, size_t n);

#endif
