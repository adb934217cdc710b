/* log.c: levelled messages to stderr; the only way the library speaks to people. */
#include "crease/base.h"

/* Process-wide verbosity: set once by the tool from its flags. */
static cr_log_level current_level = CR_LOG_INFO;

void cr_log_set_level(cr_log_level level) {
    current_level = level;
}

cr_log_level cr_log_get_level(void) {
    return current_level;
}

void cr_log(cr_log_level level, const char *fmt, ...) {
    static const char *const prefix[] = {"debug: ", "", "warning: ", "error: ", ""};
    if (level < current_level || level >= CR_LOG_SILENT) return;
    fprintf(stderr, "crease: %s", prefix[level]);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}
