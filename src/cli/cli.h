/* cli.h: what the `crease` subcommands share: the command table, option
 * parser (cli_parse over a table of cli_opt rows), the --json summary, and exit codes.
 *
 * Exit codes: 0 success, 1 bad input (one-line message on stderr), 2 usage.
 */
#ifndef CREASE_CLI_H
#define CREASE_CLI_H

#include "crease/base.h"

#include <cjson/cJSON.h>

/* CLI_HELP: cli_parse_documented printed the help; main exits 0 for it. */
enum { CLI_OK = 0, CLI_BAD_INPUT = 1, CLI_USAGE = 2, CLI_HELP = 3 };

typedef struct cli_command {
    const char *name;
    const char *summary;
    int (*run)(int argc, char **argv); /* argv[0] is the command name */
    void (*help)(void);
    /* Subcommands whose help is their option table (cli_parse_documented): `--help` after
     * one of these reaches the command instead of help(); NULL-ended, or NULL. */
    const char *const *documented;
} cli_command;

/* Report a library failure: "crease: <msg>" on stderr; returns CLI_BAD_INPUT. */
int cli_fail(const cr_error *err);
/* Report a usage error for `cmd` and point at --help; returns CLI_USAGE. */
int cli_usage(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ---- Option parsing: one table per command -------------------------------------------
 *
 * A command describes its options in a table of cli_opt rows ended by CLI_END and hands
 * argv to cli_parse, which fills the fields the rows point at:
 *
 *     int frames = 150, json = 0;
 *     float fps = 30.0f;
 *     const char *out = NULL, *pos[1];
 *     int npos = 0;
 *     const cli_opt opts[] = {
 *         CLI_INT("--frames", &frames, 1, 100000),
 *         CLI_FLOAT("--fps", &fps, 0.01, 1000),
 *         CLI_OUTPUT(&out),                     // -o and --output
 *         CLI_FLAG("--json", &json),
 *         CLI_END,
 *     };
 *     int rc = cli_parse("mycmd", argc, argv, opts, pos, 1, &npos);
 *     if (rc != CLI_OK) return rc;
 *
 * What the user gets from every command alike:
 *   - options and positionals in any order; `--` ends the options (what follows is
 *     positional); a lone `-` is a positional (a path meaning stdin/stdout);
 *   - a value as the next argument (`--fps 24`) or after `=` (`--fps=24`); a value may
 *     start with '-' (`--yaw -30`); flags take no value (`--json=1` is refused);
 *   - a repeated option: the last one wins (CLI_OPT_CUSTOM sees every one, e.g. to append);
 *   - typed values checked in full (no trailing junk, finite, in [lo, hi]);
 *   - usage errors (exit CLI_USAGE) on stderr that name the command, the option and the
 *     bad value, then point at --help:
 *         crease simulate: --frames expects an integer in [1, 100000000], got 'x'
 *         crease simulate: unknown option '--frams'
 *         crease simulate: option --frames needs a value
 *         crease drape: --collision expects vertex or sdf, got 'box'
 *   - `--help` / `-h` anywhere: main.c prints the command's help_<cmd>() before the
 *     command runs, or, for a command parsed by cli_parse_documented, the help is the
 *     table's: each row's value name, help and default (the value its dst holds before
 *     parsing), so the help cannot drift from the parser; docs/cli.md holds the same
 *     text (scripts/cli_reference.py, checked by tests/cli.sh).
 *
 * Checks across options (required ones, exclusive pairs) stay in the command, after
 * cli_parse, with cli_usage. A row's optional `seen` is set to 1 when the option was given,
 * for options that override a preset whatever their order (several rows may share one).
 * Rows with `seen` or other extra fields are written with designated initializers:
 *     {.name = "--height", .kind = CLI_OPT_FLOAT, .dst = &h, .lo = 1, .hi = 2.5, .seen = &set}
 */
typedef enum cli_opt_kind {
    CLI_OPT_FLAG,    /* no value: *(int *)dst = 1 */
    CLI_OPT_STRING,  /* *(const char **)dst = the value (points into argv) */
    CLI_OPT_INT,     /* *(int *)dst: a decimal integer in [lo, hi] */
    CLI_OPT_FLOAT,   /* *(float *)dst: a finite number in [lo, hi] */
    CLI_OPT_DOUBLE,  /* *(double *)dst: a finite number in [lo, hi], kept in double */
    CLI_OPT_U64,     /* *(uint64_t *)dst: a whole number in [lo, hi] (a seed) */
    CLI_OPT_CHOICE,  /* *(const char **)dst = the entry of choices (NULL-ended) equal to it */
    CLI_OPT_CUSTOM,  /* fn(cmd, name, values, dst) with nvalues values (0 means 1) */
    CLI_OPT_KEYS,    /* the keys with a flag of a def's cr_config_key table; dst: the def */
    CLI_OPT_HEADING, /* no option: `help` heads the rows after it in the help */
} cli_opt_kind;

/* A custom value parser: returns CLI_OK, or CLI_USAGE after printing with cli_usage. `opt`
 * is the option's name as in the table; `values` holds the option's nvalues values. */
typedef int (*cli_opt_fn)(const char *cmd, const char *opt, const char *const *values, void *dst);

typedef struct cli_opt {
    const char *name;  /* "--frames" or "-o"; NULL ends the table */
    const char *alias; /* a second spelling ("--output"), or NULL */
    cli_opt_kind kind;
    void *dst;                  /* where the value goes (see the kinds) */
    double lo, hi;              /* INT and FLOAT: the accepted range, both ends included */
    const char *const *choices; /* CHOICE: the accepted values, NULL-ended */
    cli_opt_fn fn;              /* CUSTOM: the parser */
    int nvalues;                /* CUSTOM: values it takes, 0 (meaning 1) to 4 */
    int *seen;                  /* optional: set to 1 when the option is given */
    const char *arg;            /* the value's name in the help ("N"), NULL for a flag */
    const char *help;           /* the help; "(default V)" is added from dst unless it says */
    const cr_config_key *keys;  /* KEYS: the table and its length */
    int nkeys;
} cli_opt;

/* Table rows. The dst pointer's type is checked against the kind at compile time. Each
 * CLI_X(...) is { CLI_ROW_X(...) }; a documented row adds its value name and help:
 *     {CLI_ROW_INT("--frames", &frames, 1, 100000), .arg = "N", .help = "frames to run"} */
#define CLI_ROW_FLAG(name_, dst_) .name = (name_), .kind = CLI_OPT_FLAG, .dst = CLI_PTR_(int, dst_)
#define CLI_ROW_STR(name_, dst_)                                                                   \
    .name = (name_), .kind = CLI_OPT_STRING, .dst = CLI_PTR_(const char *, dst_)
#define CLI_ROW_INT(name_, dst_, lo_, hi_)                                                         \
    .name = (name_), .kind = CLI_OPT_INT, .dst = CLI_PTR_(int, dst_), .lo = (lo_), .hi = (hi_)
#define CLI_ROW_FLOAT(name_, dst_, lo_, hi_)                                                       \
    .name = (name_), .kind = CLI_OPT_FLOAT, .dst = CLI_PTR_(float, dst_), .lo = (lo_), .hi = (hi_)
#define CLI_ROW_DOUBLE(name_, dst_, lo_, hi_)                                                      \
    .name = (name_), .kind = CLI_OPT_DOUBLE, .dst = CLI_PTR_(double, dst_), .lo = (lo_), .hi = (hi_)
#define CLI_ROW_CHOICE(name_, dst_, choices_)                                                      \
    .name = (name_), .kind = CLI_OPT_CHOICE, .dst = CLI_PTR_(const char *, dst_),                  \
    .choices = (choices_)
#define CLI_ROW_CUSTOM(name_, fn_, dst_, nvalues_)                                                 \
    .name = (name_), .kind = CLI_OPT_CUSTOM, .fn = (fn_), .dst = (dst_), .nvalues = (nvalues_)
#define CLI_FLAG(name_, dst_)                                                                      \
    { CLI_ROW_FLAG(name_, dst_) }
#define CLI_STR(name_, dst_)                                                                       \
    { CLI_ROW_STR(name_, dst_) }
#define CLI_INT(name_, dst_, lo_, hi_)                                                             \
    { CLI_ROW_INT(name_, dst_, lo_, hi_) }
#define CLI_FLOAT(name_, dst_, lo_, hi_)                                                           \
    { CLI_ROW_FLOAT(name_, dst_, lo_, hi_) }
#define CLI_DOUBLE(name_, dst_, lo_, hi_)                                                          \
    { CLI_ROW_DOUBLE(name_, dst_, lo_, hi_) }
#define CLI_CHOICE(name_, dst_, choices_)                                                          \
    { CLI_ROW_CHOICE(name_, dst_, choices_) }
#define CLI_CUSTOM(name_, fn_, dst_, nvalues_)                                                     \
    { CLI_ROW_CUSTOM(name_, fn_, dst_, nvalues_) }
/* A heading over the rows that follow it in a documented command's help ("training"). */
#define CLI_HEADING(text_)                                                                         \
    { .name = "", .kind = CLI_OPT_HEADING, .help = (text_) }
/* Every key of `keys_` (n_ of them) that has a flag, as an option writing into the def at
 * base_: its range, value name and help from the key. */
#define CLI_KEYS(keys_, n_, base_)                                                                 \
    { .name = "", .kind = CLI_OPT_KEYS, .keys = (keys_), .nkeys = (n_), .dst = (base_) }
/* -o FILE / --output FILE, the output of every command. */
#define CLI_ROW_OUTPUT(dst_)                                                                       \
    .name = "-o", .alias = "--output", .kind = CLI_OPT_STRING, .dst = CLI_PTR_(const char *, dst_)
#define CLI_OUTPUT(dst_)                                                                           \
    { CLI_ROW_OUTPUT(dst_) }
/* --solver's values (cli_common.c): "newton", "vbd", NULL; parse with cr_sim_solver_parse. */
extern const char *const cli_solvers[];
/* --self-contact on|off and --self-contact-thickness M (simulate, drape-static, dataset):
 * cli_self_contact gives the defs' 1, 0, or -1 when the option was not given. */
extern const char *const cli_on_off[];
int cli_self_contact(const char *choice);
#define CLI_SELF_CONTACT_OPTS(choice_, thickness_)                                                 \
    CLI_CHOICE("--self-contact", choice_, cli_on_off),                                             \
        CLI_FLOAT("--self-contact-thickness", thickness_, 1e-5, 0.5)
#define CLI_SELF_CONTACT_HELP                                                                      \
    "  --self-contact on|off  cloth self-contact (default off; docs/physics.md)\n"                 \
    "  --self-contact-thickness M  pairs closer than M metres are pushed apart (default\n"         \
    "                       0.004)\n"
#define CLI_END                                                                                    \
    { .name = NULL }
#define CLI_PTR_(type_, p_) ((void *)(1 ? (p_) : (type_ *)0))

/* Parse argv[1 .. argc) (argv[0] is the command's name) against opts. Positionals are
 * stored in pos[(*npos)++] (in order; *npos is updated as they come, so a CUSTOM parser may
 * read it), at most max_pos of them; pos may be NULL when the command takes none. Returns
 * CLI_OK, or CLI_USAGE after one message on stderr. */
int cli_parse(const char *cmd, int argc, char **argv, const cli_opt *opts, const char **pos,
              int max_pos, int *npos);

/* A command whose help is its table: "usage: <usage>", the about text, the options (each
 * row's name, value name, help and default) and the closing text. */
typedef struct cli_doc {
    const char *usage; /* "crease gdsr train --dataset DIR -o OUT [options]" */
    const char *about; /* a paragraph, lines ending in '\n' */
    const char *after; /* text after the options (outputs, notes), or NULL */
} cli_doc;
/* cli_parse, but `--help` or `-h` anywhere (before `--`) prints doc with opts on stdout
 * and returns CLI_HELP, before any other argument is looked at. */
int cli_parse_documented(const char *cmd, const cli_doc *doc, int argc, char **argv,
                         const cli_opt *opts, const char **pos, int max_pos, int *npos);
/* The options part of that help. */
void cli_print_options(FILE *fp, const cli_opt *opts);

/* Typed value checks for custom parsers; both print the usage message and return 0 on a
 * bad value, 1 when *out was set. */
int cli_parse_int(const char *cmd, const char *opt, const char *s, long lo, long hi, int *out);
int cli_parse_float(const char *cmd, const char *opt, const char *s, double lo, double hi,
                    float *out);
/* "--help" or "-h". */
int cli_is_help(const char *s);

/* A comma-separated list option, "a,b,c": CLI_CUSTOM(name, cli_parse_list, &list, 1)
 * copies the value into buf and points items into it. */
enum { CLI_LIST_MAX_ITEMS = 64, CLI_LIST_MAX_CHARS = 4096 };
typedef struct cli_list {
    char buf[CLI_LIST_MAX_CHARS];
    const char *items[CLI_LIST_MAX_ITEMS];
    int n;
} cli_list;
int cli_parse_list(const char *cmd, const char *opt, const char *const *v, void *dst);

/* Print the summary object on stdout (one line) and free it. */
void cli_json_print(cJSON *obj);
cJSON *cli_json_float_array(const float *v, int n);

/* The options of every command that reads a motion file (cli_motion.c): --scale,
 * --start-frame, --end-frame, --ease-in, --ground; --fps is each command's own (it also
 * sets a clip's rate). cli_motion_file_load imports the file (scale) and prepares it
 * (cr_motion_prepare: frames, calibration frame, rate, ground, ease-in). */
typedef struct cli_motion_file {
    float fps;          /* 0: the file's rate */
    float scale;        /* metres per BVH unit, 0: the rig's known unit or inferred */
    float ease_in;      /* s */
    int start_frame;    /* of the file */
    int end_frame;      /* -1: the last */
    int start_set;      /* --start-frame given: a calibration frame 0 is kept */
    int no_recenter;    /* keep the file's position and heading */
    const char *ground; /* clip, frame or none */
} cli_motion_file;
extern const char *const cli_ground_choices[];
#define CLI_MOTION_FILE_OPTS(mf_)                                                                  \
    CLI_FLOAT("--scale", &(mf_)->scale, 1e-6, 1e6),                                                \
        {.name = "--start-frame",                                                                  \
         .kind = CLI_OPT_INT,                                                                      \
         .dst = &(mf_)->start_frame,                                                               \
         .lo = 0,                                                                                  \
         .hi = 1e9,                                                                                \
         .seen = &(mf_)->start_set},                                                               \
        CLI_INT("--end-frame", &(mf_)->end_frame, 0, 1e9),                                         \
        CLI_FLOAT("--ease-in", &(mf_)->ease_in, 0, 60),                                            \
        CLI_CHOICE("--ground", &(mf_)->ground, cli_ground_choices)
/* Defaults: the file's rate and frames, clip grounding, `ease_in` seconds. */
cli_motion_file cli_motion_file_default(float ease_in);
struct cr_motion;
struct cr_body_model;
struct cr_motion_prepare_report;
struct cr_motion_import_def;
struct cr_motion_prepare_def;
/* The library's defs for these options (what cli_motion_file_load uses). */
void cli_motion_file_defs(const cli_motion_file *mf, struct cr_motion_import_def *imp,
                          struct cr_motion_prepare_def *pd);
struct cr_motion_resolve_def;
/* The library's resolve def for these options, grounded on b (NULL: the mannequin). */
struct cr_motion_resolve_def cli_motion_resolve_def(const cli_motion_file *mf,
                                                    const struct cr_body_model *b);
/* A clip name or a motion file by cr_motion_resolve with these options (a clip at --fps,
 * default 30, of 120 frames); b: the body grounded on (NULL: the default mannequin); rep
 * may be NULL. */
cr_status cli_motion_file_load(const char *path, const cli_motion_file *mf,
                               const struct cr_body_model *b, struct cr_motion **out,
                               struct cr_motion_prepare_report *rep, cr_error *err);
/* The prepared file in a --json summary: source_fps, source_frames, first_frame,
 * last_frame, calibration_dropped, ease_in_frames, ground_shift_m. */
void cli_motion_file_json(cJSON *j, const struct cr_motion_prepare_report *rep);

/* "X,Y,Z" into float[3] (a CLI_OPT_CUSTOM parser; dst is the float[3]). */
int cli_parse_vec3(const char *cmd, const char *opt, const char *const *v, void *dst);

/* A twin's options (crease simulate, crease dataset): the same simulation re-run with a
 * tiny perturbation, the floor a prediction is judged against (cr_scene_twin). */
typedef struct cli_twin {
    int twin;             /* --twin: the default perturbation, the start moved 0.1 mm */
    int has_offset;       /* --twin-offset given */
    float offset[3];      /* m */
    float friction_delta; /* --friction-delta */
} cli_twin;
#define CLI_TWIN_OPTS(t_)                                                                          \
    CLI_FLAG("--twin", &(t_)->twin),                                                               \
        {.name = "--twin-offset",                                                                  \
         .kind = CLI_OPT_CUSTOM,                                                                   \
         .fn = cli_parse_vec3,                                                                     \
         .dst = (t_)->offset,                                                                      \
         .seen = &(t_)->has_offset},                                                               \
        CLI_FLOAT("--friction-delta", &(t_)->friction_delta, -10, 10)
#define CLI_TWIN_HELP                                                                              \
    "  --twin               a twin of the run: the garment's start moved 0.1 mm along +Z\n"        \
    "                       (docs/eval.md: the floor a prediction is judged against)\n"            \
    "  --twin-offset X,Y,Z  a twin with the start moved by this vector instead, m\n"               \
    "  --friction-delta D   a twin with the friction against the body changed by D\n"
struct cr_scene_twin;
/* The perturbation the options ask for (all zero: none). */
void cli_twin_get(const cli_twin *t, struct cr_scene_twin *out);
/* "twin": {offset_m, friction_delta} into a --json summary when the twin is set. */
void cli_twin_json(cJSON *j, const struct cr_scene_twin *t);

/* Commands */
int cmd_info(int argc, char **argv);
void help_info(void);
int cmd_convert(int argc, char **argv);
void help_convert(void);
int cmd_render(int argc, char **argv);
void help_render(void);
int cmd_primitive(int argc, char **argv);
void help_primitive(void);
int cmd_fit(int argc, char **argv);
void help_fit(void);
int cmd_simulate(int argc, char **argv);
void help_simulate(void);
int cmd_drape_static(int argc, char **argv);
void help_drape_static(void);
int cmd_motion(int argc, char **argv);
void help_motion(void);
int cmd_body(int argc, char **argv);
void help_body(void);
int cmd_pose_body(int argc, char **argv);
void help_pose_body(void);
int cmd_dataset(int argc, char **argv);
void help_dataset(void);
int cmd_drape(int argc, char **argv);
void help_drape(void);
int cmd_gdsr(int argc, char **argv);
void help_gdsr(void);
int cmd_epnet(int argc, char **argv);
void help_epnet(void);
int cmd_garment(int argc, char **argv);
void help_garment(void);
int cmd_eval(int argc, char **argv);
void help_eval(void);
int cmd_view(int argc, char **argv);
void help_view(void);
int cmd_swingar(int argc, char **argv);
void help_swingar(void);
int cmd_swingar_sdf(int argc, char **argv);
void help_swingar_sdf(void);

#endif
