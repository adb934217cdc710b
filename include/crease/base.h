/* crease/base.h: the ground floor every module stands on.
 *
 *   status codes + error message (file, line, what was expected)   cr_status, cr_error, CR_FAIL
 *   arena allocator (bump, reset per step, nested marks)           cr_arena_*
 *   counter-based RNG (Philox4x32-10, seed + stream + counter)      cr_rng_*
 *   OpenMP parallel-for over index ranges                          cr_parallel_for
 *   monotonic timer                                                cr_time_now
 *   terminal progress bar (rate, ETA; plain lines off a TTY)       cr_progress_*
 *   levelled logging to stderr                                     cr_log
 *   JSON config loading that rejects unknown keys                  cr_config_*
 *
 * The library never exits and never prints to stdout: failures come back as a
 * cr_status with the message in a caller-owned cr_error; people are reached
 * only through cr_log (stderr).
 */
#ifndef CREASE_BASE_H
#define CREASE_BASE_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- status -- */

typedef enum cr_status {
    CR_OK = 0,
    CR_ERR_IO,       /* file missing, unreadable, unwritable */
    CR_ERR_PARSE,    /* malformed file contents */
    CR_ERR_INVALID,  /* bad argument or impossible parameter */
    CR_ERR_RANGE,    /* index or count out of range */
    CR_ERR_NAN,      /* non-finite number where a finite one is required */
    CR_ERR_TOPOLOGY, /* non-manifold, empty or degenerate mesh where a method needs better */
    CR_ERR_MEMORY,   /* allocation failed or arena exhausted */
    CR_ERR_SHAPE,    /* tensor/array shape mismatch */
    CR_ERR_CONFIG,   /* unknown or mistyped configuration key */
    CR_ERR_DIVERGED, /* a solver or training run blew up */
    CR_ERR_UNSUPPORTED,
    CR_STATUS_COUNT
} cr_status;

/* Caller-owned error record. `msg` says what was wrong and where (file:line
 * of the input when there is one); `src_file`/`src_line` locate the code that
 * failed, for bug reports. */
typedef struct cr_error {
    cr_status status;
    const char *src_file;
    int src_line;
    char msg[512];
} cr_error;

const char *cr_status_str(cr_status st);

/* Fill `err` (may be NULL) and return `st`. Use through CR_FAIL. */
cr_status cr_error_set(cr_error *err, cr_status st, const char *src_file, int src_line,
                       const char *fmt, ...) __attribute__((format(printf, 5, 6)));

/* Fail with file and line of the caller: `return CR_FAIL(err, CR_ERR_PARSE, "...", ...);` */
#define CR_FAIL(err, st, ...) cr_error_set((err), (st), __FILE__, __LINE__, __VA_ARGS__)

/* Propagate a non-OK status. */
#define CR_TRY(expr)                                                                               \
    do {                                                                                           \
        cr_status cr_try_st_ = (expr);                                                             \
        if (cr_try_st_ != CR_OK) return cr_try_st_;                                                \
    } while (0)

/* Programming errors (broken invariants), never input errors. Always on. */
#define CR_ASSERT(cond)                                                                            \
    do {                                                                                           \
        if (!(cond)) cr_assert_fail(#cond, __FILE__, __LINE__);                                    \
    } while (0)
void cr_assert_fail(const char *expr, const char *file, int line) __attribute__((noreturn));

/* Allocation that reports failure through cr_error (NULL on failure). */
void *cr_malloc(size_t bytes, cr_error *err);
void *cr_calloc(size_t count, size_t size, cr_error *err);

/* ----------------------------------------------------------------- arena -- */

/* Bump allocator over one block. Allocations are 64-byte aligned; `reset`
 * frees everything at once, `mark`/`rewind` free a nested scope. */
typedef struct cr_arena {
    unsigned char *base;
    size_t capacity; /* bytes */
    size_t used;     /* bytes */
    size_t peak;     /* high-water mark, bytes */
} cr_arena;

cr_status cr_arena_init(cr_arena *a, size_t capacity, cr_error *err);
void cr_arena_free(cr_arena *a);
/* NULL and an error naming needed vs available bytes when the arena is full. */
void *cr_arena_alloc(cr_arena *a, size_t bytes, cr_error *err);
void cr_arena_reset(cr_arena *a);
static inline size_t cr_arena_mark(const cr_arena *a) {
    return a->used;
}
void cr_arena_rewind(cr_arena *a, size_t mark);

/* ------------------------------------------------------------------- rng -- */

/* Philox4x32-10 (Salmon et al., SC'11): output is a pure function of
 * (seed, stream, counter), so parallel draws are reproducible whatever the
 * thread count when each item uses its own counter. */
typedef struct cr_rng {
    uint64_t seed;
    uint64_t stream;
    uint64_t counter; /* advanced by one per block of four 32-bit outputs */
    uint32_t block[4];
    int used; /* outputs consumed from block, 4 = empty */
} cr_rng;

cr_rng cr_rng_make(uint64_t seed, uint64_t stream);
/* The raw counter-based function: four 32-bit words for (seed, stream, counter). */
void cr_philox4x32(uint64_t seed, uint64_t stream, uint64_t counter, uint32_t out[4]);
uint32_t cr_rng_u32(cr_rng *r);
double cr_rng_uniform(cr_rng *r);                          /* [0, 1) with 53 random bits */
float cr_rng_uniformf(cr_rng *r);                          /* [0, 1) */
double cr_rng_normal(cr_rng *r);                           /* standard normal (Box-Muller) */
uint32_t cr_rng_below(cr_rng *r, uint32_t n);              /* uniform in [0, n), unbiased */
void cr_rng_shuffle_i32(cr_rng *r, int32_t *a, int64_t n); /* Fisher-Yates */

/* ------------------------------------------------------------- parallel -- */

/* fn(ctx, begin, end) is called on disjoint chunks covering [0, n). Runs on
 * OpenMP threads when built with OpenMP, serially otherwise. `grain` is the
 * smallest chunk worth a thread (0 = pick). */
typedef void (*cr_range_fn)(void *ctx, int64_t begin, int64_t end);
void cr_parallel_for(int64_t n, int64_t grain, cr_range_fn fn, void *ctx);
int cr_thread_count(void);
void cr_set_thread_count(int n); /* n <= 0: leave as the runtime chose */
/* For a program's main, before anything else: when neither OMP_WAIT_POLICY
 * nor GOMP_SPINCOUNT is set, choose how idle OpenMP threads wait and
 * re-execute the program (argv as given) so the runtime reads it at load;
 * returns only when nothing was done or the re-execution failed.
 * libgomp's default spins for milliseconds after every parallel region: on
 * a machine shared with other jobs the spinning threads took the cores from
 * the working ones (a drape epoch 8x slower on 2 cores at load 5,
 * docs/drape.md). Sleeping at once (passive) costs a wake-up per region
 * instead, 20 % of a drape epoch on a quiet machine. So: when the other
 * processes' runnable threads leave a CPU for every thread of this run,
 * spin briefly (GOMP_SPINCOUNT CR_PARALLEL_SPIN_COUNT, some microseconds),
 * otherwise passive (cr_parallel_wait_policy_for). Neither changes a
 * result's bits. Built without OpenMP it does nothing. */
#define CR_PARALLEL_SPIN_COUNT "10000"
void cr_parallel_choose_wait_policy(char **argv);
/* "spin" or "passive" for the other processes' runnable threads (negative:
 * unknown), the threads a run will use and the CPUs it may use. */
const char *cr_parallel_wait_policy_for(double others, int threads, int cpus);
/* The same re-execution, always passive: for the test runner, whose
 * processes ctest runs side by side, so the load at start says nothing. */
void cr_parallel_prefer_passive_wait(char **argv);

/* ----------------------------------------------------------------- timer -- */

double cr_time_now(void); /* monotonic seconds */

/* -------------------------------------------------------------- progress -- */

/* A progress bar on stderr. On a TTY it redraws one line (bar, count, rate,
 * ETA, caller's status text); off a TTY it prints a plain line at most every
 * `plain_interval` seconds (default 5) and at the end. Quiet mode prints
 * nothing. */
typedef struct cr_progress {
    const char *label;
    int64_t total;
    int64_t done;
    double t_start, t_last_draw;
    double plain_interval;
    int tty;
    int quiet;
    char status[160];
} cr_progress;

void cr_progress_begin(cr_progress *p, const char *label, int64_t total, int quiet);
/* Advance to `done` units; `fmt` (may be NULL) sets the status text shown after the bar. */
void cr_progress_update(cr_progress *p, int64_t done, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void cr_progress_end(cr_progress *p);

/* ------------------------------------------------------------------- log -- */

typedef enum cr_log_level {
    CR_LOG_DEBUG = 0,
    CR_LOG_INFO,
    CR_LOG_WARN,
    CR_LOG_ERROR,
    CR_LOG_SILENT
} cr_log_level;

void cr_log_set_level(cr_log_level level);
cr_log_level cr_log_get_level(void);
void cr_log(cr_log_level level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ---------------------------------------------------------------- config -- */

/* Typed configuration keys: a table of these describes a struct, and
 * cr_config_load fills the struct from a JSON object, refusing unknown keys,
 * wrong types and out-of-range values with the key's name. */
typedef enum cr_config_type {
    CR_CFG_FLOAT,
    CR_CFG_DOUBLE,
    CR_CFG_INT,
    CR_CFG_BOOL,
    CR_CFG_STRING, /* fixed char array of `size` bytes inside the struct */
    CR_CFG_U64     /* uint64_t (a seed), written as a JSON number */
} cr_config_type;

typedef struct cr_config_key {
    const char *name;
    cr_config_type type;
    size_t offset;   /* offsetof(struct, field) */
    size_t size;     /* CR_CFG_STRING: capacity of the char array */
    double min, max; /* numeric range, inclusive; min > max means unchecked */
    const char *help;
    /* The command-line spelling ("--epochs") where the key is an option of a command, and
     * its value's name in the help ("N"); NULL where the key is not on a command line. A
     * command lists such a table as one row (CLI_KEYS, src/cli/cli.h): the option, its
     * range, its help and its default (the def's value) all come from here. */
    const char *flag;
    const char *arg;
} cr_config_key;

/* A key of a table describing struct `type_`, named as its field: the one place the
 * key's layout is spelt. flag_ and arg_ NULL: not on a command line. */
#define CR_CONFIG_KEY(type_, field_, cfg_type_, min_, max_, flag_, arg_, help_)                    \
    { #field_, cfg_type_, offsetof(type_, field_), 0, min_, max_, help_, flag_, arg_ }

/* Parse `json_text` (from `source`, a file name used in messages) into `out`. */
cr_status cr_config_parse(const char *json_text, const char *source, const cr_config_key *keys,
                          int nkeys, void *out, cr_error *err);
cr_status cr_config_load(const char *path, const cr_config_key *keys, int nkeys, void *out,
                         cr_error *err);
struct cJSON;
/* The same from a parsed JSON object (a part of a larger document). */
cr_status cr_config_parse_object(const struct cJSON *obj, const char *source,
                                 const cr_config_key *keys, int nkeys, void *out, cr_error *err);
/* The struct's keys as a new JSON object, in the table's order (the caller
 * deletes it); NULL when out of memory. What cr_config_parse_object reads back. */
struct cJSON *cr_config_to_object(const cr_config_key *keys, int nkeys, const void *in);
/* The first key whose value differs between a and b (two structs the table
 * describes), or NULL when they agree on every key: what a resume names when
 * its options are not the checkpoint's. */
const char *cr_config_diff(const cr_config_key *keys, int nkeys, const void *a, const void *b);
/* The first key the JSON object lacks, or NULL when it has every one: for
 * files that must state every key. */
const char *cr_config_absent(const cr_config_key *keys, int nkeys, const struct cJSON *obj);
/* A numeric key's value in `in` as a double (0 for a string), for messages. */
double cr_config_number(const cr_config_key *k, const void *in);
/* Every numeric key of `in` within its range (NaN is outside): else CR_ERR_INVALID,
 * "<what>: <key> <value> outside [min, max]". What a library checks a def with, from the
 * same table its command line takes the ranges from. */
cr_status cr_config_check(const cr_config_key *keys, int nkeys, const void *in, const char *what,
                          cr_error *err);

/* ------------------------------------------------------------ file utils -- */

/* Read a whole file into a NUL-terminated heap buffer (caller frees). */
cr_status cr_file_read_all(const char *path, char **out, size_t *out_len, cr_error *err);

/* Atomic writes: open `path`.tmp.<pid>, write, then commit renames it over
 * `path`; abort removes the temporary. A crash never leaves a half-written file.
 * A commit also removes `path`.tmp.<pid> files whose writer no longer runs
 * (a run killed mid-write), so a resumed run cleans up after the killed one. */
typedef struct cr_atomic_file {
    FILE *fp;
    char path[1024];
    char tmp_path[1100];
} cr_atomic_file;

cr_status cr_atomic_open(cr_atomic_file *f, const char *path, cr_error *err);
cr_status cr_atomic_commit(cr_atomic_file *f, cr_error *err);
void cr_atomic_abort(cr_atomic_file *f);
/* Create a directory and its parents (like mkdir -p). */
cr_status cr_mkdir_p(const char *path, cr_error *err);
/* Lower-case extension without the dot ("" when none); points into `path`'s own
 * storage only when already lower case, so it copies into `out`. */
void cr_path_ext(const char *path, char *out, size_t cap);

#ifdef __cplusplus
}
#endif
#endif
