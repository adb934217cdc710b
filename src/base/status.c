/* status.c: status names, error records, checked allocation, assertion failure. */
#include "crease/base.h"

#include <stdlib.h>
#include <string.h>

static const char *const status_names[CR_STATUS_COUNT] = {
    [CR_OK] = "ok",
    [CR_ERR_IO] = "i/o error",
    [CR_ERR_PARSE] = "parse error",
    [CR_ERR_INVALID] = "invalid argument",
    [CR_ERR_RANGE] = "out of range",
    [CR_ERR_NAN] = "non-finite value",
    [CR_ERR_TOPOLOGY] = "bad topology",
    [CR_ERR_MEMORY] = "out of memory",
    [CR_ERR_SHAPE] = "shape mismatch",
    [CR_ERR_CONFIG] = "configuration error",
    [CR_ERR_DIVERGED] = "diverged",
    [CR_ERR_UNSUPPORTED] = "unsupported",
};

const char *cr_status_str(cr_status st) {
    if ((int)st < 0 || st >= CR_STATUS_COUNT) return "unknown status";
    return status_names[st];
}

cr_status cr_error_set(cr_error *err, cr_status st, const char *src_file, int src_line,
                       const char *fmt, ...) {
    if (!err) return st;
    err->status = st;
    err->src_file = src_file;
    err->src_line = src_line;
    /* through a copy, so a caller may wrap the previous message: CR_FAIL(err, st, "ctx: %s",
     * err->msg) */
    char msg[sizeof err->msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    memcpy(err->msg, msg, sizeof msg);
    return st;
}

void cr_assert_fail(const char *expr, const char *file, int line) {
    fprintf(stderr, "crease: internal error: assertion '%s' failed at %s:%d\n", expr, file, line);
    abort();
}

void *cr_malloc(size_t bytes, cr_error *err) {
    void *p = malloc(bytes ? bytes : 1);
    if (!p) CR_FAIL(err, CR_ERR_MEMORY, "out of memory allocating %zu bytes", bytes);
    return p;
}

void *cr_calloc(size_t count, size_t size, cr_error *err) {
    if (size && count > SIZE_MAX / size) {
        CR_FAIL(err, CR_ERR_MEMORY, "allocation of %zu x %zu bytes overflows", count, size);
        return NULL;
    }
    void *p = calloc(count ? count : 1, size ? size : 1);
    if (!p) CR_FAIL(err, CR_ERR_MEMORY, "out of memory allocating %zu x %zu bytes", count, size);
    return p;
}
