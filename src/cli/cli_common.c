/* cli_common.c: option parsing, error reporting and JSON output shared by the commands. */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int cli_fail(const cr_error *err) {
    fprintf(stderr, "crease: %s\n", err->msg[0] ? err->msg : cr_status_str(err->status));
    return CLI_BAD_INPUT;
}

int cli_usage(const char *cmd, const char *fmt, ...) {
    fprintf(stderr, "crease %s: ", cmd);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n(see 'crease %s --help')\n", cmd);
    return CLI_USAGE;
}

cli_args cli_args_make(int argc, char **argv) {
    cli_args a = {.argc = argc, .argv = argv, .i = 1, .cmd = argv[0]};
    return a;
}

int cli_args_done(const cli_args *a) {
    return a->i >= a->argc;
}

const char *cli_args_next(cli_args *a) {
    return a->i < a->argc ? a->argv[a->i++] : NULL;
}

const char *cli_args_value(cli_args *a, const char *opt) {
    if (a->i >= a->argc) {
        cli_usage(a->cmd, "option %s needs a value", opt);
        return NULL;
    }
    return a->argv[a->i++];
}

int cli_parse_int(const char *cmd, const char *opt, const char *s, long lo, long hi, int *out) {
    char *end = NULL;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) {
        cli_usage(cmd, "%s expects an integer in [%ld, %ld], got '%s'", opt, lo, hi, s);
        return 0;
    }
    *out = (int)v;
    return 1;
}

int cli_parse_float(const char *cmd, const char *opt, const char *s, double lo, double hi,
                    float *out) {
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v) || v < lo || v > hi) {
        cli_usage(cmd, "%s expects a number in [%g, %g], got '%s'", opt, lo, hi, s);
        return 0;
    }
    *out = (float)v;
    return 1;
}

int cli_is_help(const char *s) {
    return strcmp(s, "--help") == 0 || strcmp(s, "-h") == 0;
}

void cli_json_print(cJSON *obj) {
    char *text = cJSON_PrintUnformatted(obj);
    if (text) {
        printf("%s\n", text);
        fflush(stdout);
        cJSON_free(text);
    }
    cJSON_Delete(obj);
}

cJSON *cli_json_float_array(const float *v, int n) {
    cJSON *arr = cJSON_CreateArray();
    for (int i = 0; i < n; i++) cJSON_AddItemToArray(arr, cJSON_CreateNumber(v[i]));
    return arr;
}
