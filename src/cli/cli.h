/* cli.h: what the `crease` subcommands share: the command table, option
 * parsing helpers, the --json summary, and exit codes.
 *
 * Exit codes: 0 success, 1 bad input (one-line message on stderr), 2 usage.
 */
#ifndef CREASE_CLI_H
#define CREASE_CLI_H

#include "crease/base.h"

#include <cjson/cJSON.h>

enum { CLI_OK = 0, CLI_BAD_INPUT = 1, CLI_USAGE = 2 };

typedef struct cli_command {
    const char *name;
    const char *summary;
    int (*run)(int argc, char **argv); /* argv[0] is the command name */
    void (*help)(void);
} cli_command;

/* Report a library failure: "crease: <msg>" on stderr; returns CLI_BAD_INPUT. */
int cli_fail(const cr_error *err);
/* Report a usage error for `cmd` and point at --help; returns CLI_USAGE. */
int cli_usage(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Option parsing over argv: options may come before or after positionals.
 * `cli_args_next` returns the next token; helpers parse values with checks. */
typedef struct cli_args {
    int argc, i;
    char **argv;
    const char *cmd;
} cli_args;

cli_args cli_args_make(int argc, char **argv);
int cli_args_done(const cli_args *a);
const char *cli_args_next(cli_args *a);
/* Value after option `opt`; NULL (and a usage message) when missing. */
const char *cli_args_value(cli_args *a, const char *opt);
int cli_parse_int(const char *cmd, const char *opt, const char *s, long lo, long hi, int *out);
int cli_parse_float(const char *cmd, const char *opt, const char *s, double lo, double hi,
                    float *out);
int cli_is_help(const char *s);

/* Print the summary object on stdout (one line) and free it. */
void cli_json_print(cJSON *obj);
cJSON *cli_json_float_array(const float *v, int n);

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
int cmd_garment(int argc, char **argv);
void help_garment(void);
int cmd_eval(int argc, char **argv);
void help_eval(void);

#endif
