/* cli_common.c: the option parser (cli.h), error reporting and JSON output shared by the commands.
 */
#include "cli.h"
#include "crease/scene.h"

#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

const char *const cli_solvers[] = {"newton", "vbd", NULL};
const char *const cli_on_off[] = {"on", "off", NULL};

int cli_self_contact(const char *choice) {
    return !choice ? -1 : strcmp(choice, "on") == 0;
}

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

/* A finite number in [lo, hi] into *out, or 0 after printing the usage. */
static int parse_number(const char *cmd, const char *opt, const char *s, double lo, double hi,
                        double *out) {
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v) || v < lo || v > hi) {
        cli_usage(cmd, "%s expects a number in [%g, %g], got '%s'", opt, lo, hi, s);
        return 0;
    }
    *out = v;
    return 1;
}

int cli_parse_float(const char *cmd, const char *opt, const char *s, double lo, double hi,
                    float *out) {
    double v;
    if (!parse_number(cmd, opt, s, lo, hi, &v)) return 0;
    *out = (float)v;
    return 1;
}

int cli_is_help(const char *s) {
    return strcmp(s, "--help") == 0 || strcmp(s, "-h") == 0;
}

/* The option key k of a KEYS row stands for: its flag, range, help, and the field. */
static void key_row(const cli_opt *r, const cr_config_key *k, cli_opt *out) {
    static const double wide[] = {-FLT_MAX, FLT_MAX, -DBL_MAX, DBL_MAX, INT_MIN, INT_MAX};
    *out = (cli_opt){.name = k->flag, .arg = k->arg, .help = k->help};
    out->dst = (char *)r->dst + k->offset;
    int w = k->type == CR_CFG_FLOAT ? 0 : k->type == CR_CFG_DOUBLE ? 2 : 4;
    out->lo = k->min <= k->max ? k->min : wide[w];
    out->hi = k->min <= k->max ? k->max : wide[w + 1];
    out->kind = k->type == CR_CFG_FLOAT    ? CLI_OPT_FLOAT
                : k->type == CR_CFG_DOUBLE ? CLI_OPT_DOUBLE
                : k->type == CR_CFG_INT    ? CLI_OPT_INT
                : k->type == CR_CFG_BOOL   ? CLI_OPT_FLAG
                : k->type == CR_CFG_U64    ? CLI_OPT_U64
                                           : CLI_OPT_KEYS; /* a string key: refused */
    if (k->type == CR_CFG_U64 && k->min > k->max) out->lo = 0, out->hi = 9007199254740992.0;
}

/* The options of a table in order, KEYS rows expanded into their keys with a flag. */
typedef struct opt_iter {
    const cli_opt *row; /* the current row */
    int key;            /* within a KEYS row: the next key to look at */
    cli_opt scratch;    /* the option a key stands for */
} opt_iter;

/* The next option (in it->scratch when it is a key's), or NULL past the end. */
static const cli_opt *opt_next(opt_iter *it) {
    for (; it->row->name; it->row++, it->key = 0) {
        if (it->row->kind != CLI_OPT_KEYS) {
            if (it->key++ == 0) return it->row;
            continue;
        }
        while (it->key < it->row->nkeys) {
            const cr_config_key *k = &it->row->keys[it->key++];
            if (!k->flag) continue;
            key_row(it->row, k, &it->scratch);
            return &it->scratch;
        }
    }
    return NULL;
}

/* The option whose name or alias is `name` (the first len characters), in it->scratch
 * when it is a key's, or NULL. */
static const cli_opt *find_opt(const cli_opt *opts, const char *name, size_t len, opt_iter *it) {
    *it = (opt_iter){.row = opts};
    for (const cli_opt *o; (o = opt_next(it)) != NULL;) {
        if (strlen(o->name) == len && strncmp(o->name, name, len) == 0) return o;
        if (o->alias && strlen(o->alias) == len && strncmp(o->alias, name, len) == 0) return o;
    }
    return NULL;
}

/* "a", "a or b", "a, b or c": the accepted values of a CHOICE row. */
static void choice_list(const char *const *choices, char *buf, size_t cap) {
    int n = 0;
    while (choices[n])
        n++;
    buf[0] = '\0';
    size_t used = 0;
    for (int i = 0; i < n && used < cap; i++) {
        const char *sep = i == 0 ? "" : i == n - 1 ? " or " : ", ";
        int w = snprintf(buf + used, cap - used, "%s%s", sep, choices[i]);
        if (w < 0) break;
        used += (size_t)w;
    }
}

/* Store the values of option `o` (named `name` on the command line). */
static int apply_opt(const char *cmd, const cli_opt *o, const char *const *v) {
    switch (o->kind) {
    case CLI_OPT_FLAG:
        *(int *)o->dst = 1;
        return CLI_OK;
    case CLI_OPT_STRING:
        *(const char **)o->dst = v[0];
        return CLI_OK;
    case CLI_OPT_INT:
        return cli_parse_int(cmd, o->name, v[0], (long)o->lo, (long)o->hi, (int *)o->dst)
                   ? CLI_OK
                   : CLI_USAGE;
    case CLI_OPT_FLOAT:
        return cli_parse_float(cmd, o->name, v[0], o->lo, o->hi, (float *)o->dst) ? CLI_OK
                                                                                  : CLI_USAGE;
    case CLI_OPT_DOUBLE:
        return parse_number(cmd, o->name, v[0], o->lo, o->hi, (double *)o->dst) ? CLI_OK
                                                                                : CLI_USAGE;
    case CLI_OPT_U64: {
        double x;
        if (!parse_number(cmd, o->name, v[0], o->lo, o->hi, &x)) return CLI_USAGE;
        if (x != floor(x))
            return cli_usage(cmd, "%s expects a whole number, got '%s'", o->name, v[0]);
        *(uint64_t *)o->dst = (uint64_t)x;
        return CLI_OK;
    }
    case CLI_OPT_CHOICE:
        for (const char *const *c = o->choices; *c; c++)
            if (strcmp(*c, v[0]) == 0) {
                *(const char **)o->dst = *c;
                return CLI_OK;
            }
        char list[256];
        choice_list(o->choices, list, sizeof list);
        return cli_usage(cmd, "%s expects %s, got '%s'", o->name, list, v[0]);
    case CLI_OPT_CUSTOM:
        return o->fn(cmd, o->name, v, o->dst);
    case CLI_OPT_KEYS:
    case CLI_OPT_HEADING:
        break;
    }
    return cli_usage(cmd, "%s: bad option table", o->name);
}

int cli_parse(const char *cmd, int argc, char **argv, const cli_opt *opts, const char **pos,
              int max_pos, int *npos) {
    enum { MAX_VALUES = 4 };
    int only_positionals = 0;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (only_positionals || arg[0] != '-' || arg[1] == '\0') {
            if (!pos || *npos >= max_pos)
                return max_pos > 0
                           ? cli_usage(cmd, "too many arguments: '%s' (at most %d)", arg, max_pos)
                           : cli_usage(cmd, "unexpected argument '%s'", arg);
            pos[(*npos)++] = arg;
            continue;
        }
        if (strcmp(arg, "--") == 0) {
            only_positionals = 1;
            continue;
        }
        /* --name=value: the value is glued on. */
        const char *eq = arg[1] == '-' ? strchr(arg, '=') : NULL;
        size_t len = eq ? (size_t)(eq - arg) : strlen(arg);
        opt_iter it;
        const cli_opt *o = find_opt(opts, arg, len, &it);
        if (!o) return cli_usage(cmd, "unknown option '%.*s'", (int)len, arg);
        int want = o->kind == CLI_OPT_FLAG                       ? 0
                   : o->kind == CLI_OPT_CUSTOM && o->nvalues > 1 ? o->nvalues
                                                                 : 1;
        if (want > MAX_VALUES) return cli_usage(cmd, "%s: bad option table", o->name);
        if (want == 0 && eq) return cli_usage(cmd, "option %s takes no value", o->name);
        const char *values[MAX_VALUES] = {NULL};
        int have = 0;
        if (eq) values[have++] = eq + 1;
        while (have < want) {
            if (i + 1 >= argc) {
                if (want == 1) return cli_usage(cmd, "option %s needs a value", o->name);
                return cli_usage(cmd, "option %s needs %d values", o->name, want);
            }
            values[have++] = argv[++i];
        }
        int rc = apply_opt(cmd, o, values);
        if (rc != CLI_OK) return rc;
        if (o->seen) *o->seen = 1;
    }
    return CLI_OK;
}

/* A row's default: the value its field holds before parsing ("" when it has none to show). */
static void default_text(const cli_opt *o, char *buf, size_t cap) {
    buf[0] = '\0';
    switch (o->kind) {
    case CLI_OPT_INT:
        snprintf(buf, cap, "%d", *(const int *)o->dst);
        break;
    case CLI_OPT_FLOAT:
        snprintf(buf, cap, "%g", (double)*(const float *)o->dst);
        break;
    case CLI_OPT_DOUBLE:
        snprintf(buf, cap, "%g", *(const double *)o->dst);
        break;
    case CLI_OPT_U64:
        snprintf(buf, cap, "%llu", (unsigned long long)*(const uint64_t *)o->dst);
        break;
    case CLI_OPT_STRING:
    case CLI_OPT_CHOICE:
        if (*(const char *const *)o->dst) snprintf(buf, cap, "%s", *(const char *const *)o->dst);
        break;
    default:
        break;
    }
}

/* `text` from column `indent`, wrapped at spaces before column `width`; `col` is where the
 * line already is. Newlines in text are kept. */
static void print_wrapped(FILE *fp, const char *text, int col, int indent, int width) {
    const char *p = text;
    while (*p) {
        if (*p == '\n') {
            fputc('\n', fp), p++;
            col = 0;
            continue;
        }
        if (*p == ' ' && col > indent) {
            p++;
            continue;
        }
        size_t word = strcspn(p, " \n");
        if (col > indent && col + 1 + (int)word > width) fprintf(fp, "\n"), col = 0;
        if (col < indent)
            fprintf(fp, "%*s", indent - col, ""), col = indent;
        else if (col > indent)
            fputc(' ', fp), col++;
        fwrite(p, 1, word, fp);
        col += (int)word, p += word;
    }
    fputc('\n', fp);
}

void cli_print_options(FILE *fp, const cli_opt *opts) {
    enum { INDENT = 23, WIDTH = 92 };
    opt_iter it = {.row = opts};
    for (const cli_opt *o; (o = opt_next(&it)) != NULL;) {
        if (!o->help) continue;
        if (o->kind == CLI_OPT_HEADING) {
            fprintf(fp, "%s:\n", o->help);
            continue;
        }
        char head[160], def[64], text[1024];
        int n = snprintf(head, sizeof head, "  %s%s%s%s%s", o->name, o->alias ? ", " : "",
                         o->alias ? o->alias : "", o->arg ? " " : "", o->arg ? o->arg : "");
        default_text(o, def, sizeof def);
        int say = def[0] && !strstr(o->help, "default"); /* unless the help says it */
        snprintf(text, sizeof text, "%s%s%s%s", o->help, say ? " (default " : "", say ? def : "",
                 say ? ")" : "");
        fputs(head, fp);
        int col = n;
        if (col >= INDENT - 1) fputc('\n', fp), col = 0;
        print_wrapped(fp, text, col, INDENT, WIDTH);
    }
}

int cli_parse_documented(const char *cmd, const cli_doc *doc, int argc, char **argv,
                         const cli_opt *opts, const char **pos, int max_pos, int *npos) {
    for (int i = 1; i < argc && strcmp(argv[i], "--") != 0; i++)
        if (cli_is_help(argv[i])) {
            printf("usage: %s\n\n%s\n%s", doc->usage, doc->about,
                   opts[0].kind == CLI_OPT_HEADING ? "" : "options:\n");
            cli_print_options(stdout, opts);
            if (doc->after) printf("\n%s", doc->after);
            return CLI_HELP;
        }
    return cli_parse(cmd, argc, argv, opts, pos, max_pos, npos);
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
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, cJSON_CreateNumber(v[i]));
    return arr;
}

int cli_parse_list(const char *cmd, const char *opt, const char *const *v, void *dst) {
    cli_list *l = dst;
    if (strlen(v[0]) >= CLI_LIST_MAX_CHARS) return cli_usage(cmd, "%s: list too long", opt);
    strcpy(l->buf, v[0]);
    l->n = 0;
    for (char *save = NULL, *tok = strtok_r(l->buf, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        if (l->n == CLI_LIST_MAX_ITEMS)
            return cli_usage(cmd, "%s: at most %d items", opt, CLI_LIST_MAX_ITEMS);
        l->items[l->n++] = tok;
    }
    if (l->n == 0) return cli_usage(cmd, "%s: empty list", opt);
    return CLI_OK;
}

int cli_parse_vec3(const char *cmd, const char *opt, const char *const *v, void *dst) {
    float *out = dst;
    char buf[128], *save = NULL;
    snprintf(buf, sizeof buf, "%s", v[0]);
    int k = 0;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save), k++)
        if (k >= 3 || !cli_parse_float(cmd, opt, tok, -1e6, 1e6, &out[k])) return CLI_USAGE;
    if (k != 3) return cli_usage(cmd, "%s expects X,Y,Z, got '%s'", opt, v[0]);
    return CLI_OK;
}

/* A float option's value as the decimal the user typed (0.01, not 0.0099999998). */
static double typed(float v) {
    char b[32];
    snprintf(b, sizeof b, "%.7g", (double)v);
    return strtod(b, NULL);
}

void cli_twin_get(const cli_twin *t, cr_scene_twin *out) {
    *out = t->twin && !t->has_offset ? cr_scene_twin_default() : (cr_scene_twin){0};
    if (t->has_offset) memcpy(out->offset, t->offset, sizeof out->offset);
    out->friction_delta = typed(t->friction_delta);
}

void cli_twin_json(cJSON *j, const cr_scene_twin *t) {
    if (!cr_scene_twin_is_set(t)) return;
    cJSON *o = cJSON_AddObjectToObject(j, "twin");
    cJSON *off = cJSON_AddArrayToObject(o, "offset_m");
    for (int k = 0; k < 3; k++)
        cJSON_AddItemToArray(off, cJSON_CreateNumber(typed(t->offset[k])));
    cJSON_AddNumberToObject(o, "friction_delta", t->friction_delta);
}
