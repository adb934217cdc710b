/* train_log.c: cutting a training run's JSON-lines log back to its
 * checkpoint (nn_checkpoint.h). */
#include "crease/nn_checkpoint.h"

#include <cjson/cJSON.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

typedef struct log_line {
    double epoch;
    size_t at, len, order; /* bytes of text, '\n' included; position in the file */
} log_line;

static int by_epoch(const void *pa, const void *pb) {
    const log_line *a = pa, *b = pb;
    if (a->epoch != b->epoch) return a->epoch < b->epoch ? -1 : 1;
    return a->order < b->order ? -1 : a->order > b->order;
}

/* The complete lines of text whose "epoch" is at most `epoch`, by epoch, then
 * by position, into *out (NULL for none), their count into *n. */
static cr_status kept_lines(const char *path, char *text, size_t len, int64_t epoch, log_line **out,
                            size_t *n, cr_error *err) {
    size_t cap = 0;
    for (size_t i = 0; i < len; i++)
        cap += text[i] == '\n';
    log_line *l = *out = cap ? malloc(cap * sizeof *l) : NULL;
    *n = 0;
    if (cap && !l) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", path);
    for (size_t at = 0; at < len;) {
        char *nl = memchr(text + at, '\n', len - at);
        if (!nl) break; /* a line cut short by a kill */
        *nl = '\0';
        cJSON *o = cJSON_Parse(text + at);
        *nl = '\n';
        const cJSON *e = cJSON_GetObjectItemCaseSensitive(o, "epoch");
        size_t end = (size_t)(nl - text) + 1;
        if (cJSON_IsNumber(e) && e->valuedouble <= (double)epoch)
            l[*n] = (log_line){e->valuedouble, at, end - at, *n}, (*n)++;
        cJSON_Delete(o);
        at = end;
    }
    if (l) qsort(l, *n, sizeof *l, by_epoch);
    return CR_OK;
}

cr_status cr_train_log_cut(const char *path, int64_t epoch, cr_error *err) {
    char *text = NULL;
    size_t len = 0, n = 0;
    log_line *l = NULL;
    struct stat sb;
    if (epoch > 0 && stat(path, &sb) == 0) {
        CR_TRY(cr_file_read_all(path, &text, &len, err));
        cr_status st = kept_lines(path, text, len, epoch, &l, &n, err);
        if (st != CR_OK) {
            free(text);
            return st;
        }
    }
    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st == CR_OK) {
        /* An epoch logged twice (a run killed past its checkpoint and resumed by
         * an older crease): the later line is the one the checkpoint continues. */
        for (size_t i = 0; i < n; i++)
            if (i + 1 == n || l[i + 1].epoch != l[i].epoch)
                fwrite(text + l[i].at, 1, l[i].len, f.fp);
        st = cr_atomic_commit(&f, err);
    }
    free(l);
    free(text);
    return st;
}
