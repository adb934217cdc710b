/* checkpoint.c: a training run's whole state in one safetensors file, so a run
 * resumes bit-identically: model parameters under their own names, optimiser
 * buffers as "optim.<buffer>.<name>" (float32, stored bit for bit), and the
 * integers and strings in __metadata__ (integers as decimal strings, the loss
 * with 9 significant digits, which round-trips any float).
 *
 * The RNG is saved as seed, stream, counter and the count of outputs used
 * from the current block; the block itself is recomputed on load as
 * Philox(seed, stream, counter - 1), which is what the generator held.
 *
 * Loading checks everything (names, shapes, finite values, optimiser kind,
 * metadata syntax) before it writes anything, so a mismatched file leaves the
 * run untouched.
 * Leaves out: several optimisers per file, sharded checkpoints.
 */
#include "crease/nn_checkpoint.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#define FORMAT_KEY "crease.checkpoint"
#define FORMAT_VERSION "1"
#define OPTIM_PREFIX "optim."

enum { NAME_CAP = 192, META_MAX = 16, NUM_CAP = 32 };

/* "optim.<buffer>.<param>" */
static void state_name(char *out, const char *buffer, const char *param) {
    snprintf(out, NAME_CAP, OPTIM_PREFIX "%s.%s", buffer, param);
}

cr_status cr_checkpoint_save(const char *path, cr_nn_params *model, cr_optim *opt,
                             const cr_checkpoint_meta *meta, cr_error *err) {
    CR_ASSERT(!opt || cr_optim_params(opt) == model);
    int np = cr_nn_params_count(model), ns = opt ? cr_optim_state_count(opt) : 0;
    int n = np * (1 + ns);
    for (int i = 0; i < np; i++) {
        const char *name;
        cr_nn_params_at(model, i, &name);
        if (strncmp(name, OPTIM_PREFIX, strlen(OPTIM_PREFIX)) == 0)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "%s: parameter '%s' starts with '" OPTIM_PREFIX
                           "', which checkpoints reserve for optimiser state",
                           path, name);
    }
    cr_st_tensor *t = cr_calloc((size_t)n + 1, sizeof *t, err);
    char *names = t ? cr_malloc((size_t)(np * ns + 1) * NAME_CAP, err) : NULL;
    if (!t || !names) {
        free(t);
        return CR_ERR_MEMORY;
    }
    float *base = cr_nn_params_data(model, NULL);
    for (int k = -1; k < ns; k++) {
        const char *buffer = NULL;
        float *state = k >= 0 ? cr_optim_state(opt, k, &buffer) : NULL;
        for (int i = 0; i < np; i++) {
            cr_st_tensor *e = &t[(k + 1) * np + i];
            const char *name;
            cr_tensor *x = cr_nn_params_at(model, i, &name);
            e->ndim = x->ndim;
            for (int d = 0; d < x->ndim; d++)
                e->shape[d] = x->shape[d];
            e->data = state ? state + (x->data - base) : x->data;
            if (state) {
                char *nm = names + ((size_t)k * (size_t)np + (size_t)i) * NAME_CAP;
                state_name(nm, buffer, name);
                e->name = nm;
            } else {
                e->name = name;
            }
        }
    }

    char num[META_MAX][NUM_CAP];
    cr_st_meta m[META_MAX];
    int nm = 0;
    m[nm++] = (cr_st_meta){FORMAT_KEY, FORMAT_VERSION};
    if (opt) {
        m[nm++] = (cr_st_meta){"optim.kind", cr_optim_kind_name(cr_optim_get_def(opt)->kind)};
        snprintf(num[nm], NUM_CAP, "%lld", (long long)cr_optim_step_count(opt));
        m[nm] = (cr_st_meta){"optim.step", num[nm]};
        nm++;
    }
    if (meta) {
        const struct {
            const char *key;
            unsigned long long u;
            int is_signed;
        } ints[] = {
            {"epoch", (unsigned long long)meta->epoch, 1},
            {"step", (unsigned long long)meta->step, 1},
            {"seed", meta->seed, 0},
            {"rng.seed", meta->rng.seed, 0},
            {"rng.stream", meta->rng.stream, 0},
            {"rng.counter", meta->rng.counter, 0},
            {"rng.used", (unsigned long long)meta->rng.used, 1},
        };
        for (size_t i = 0; i < sizeof ints / sizeof ints[0]; i++) {
            if (ints[i].is_signed)
                snprintf(num[nm], NUM_CAP, "%lld", (long long)ints[i].u);
            else
                snprintf(num[nm], NUM_CAP, "%llu", ints[i].u);
            m[nm] = (cr_st_meta){ints[i].key, num[nm]};
            nm++;
        }
        snprintf(num[nm], NUM_CAP, "%.9g", (double)meta->loss);
        m[nm] = (cr_st_meta){"loss", num[nm]};
        nm++;
        if (meta->config_json) m[nm++] = (cr_st_meta){"config", meta->config_json};
    }
    CR_ASSERT(nm <= META_MAX);
    cr_status st = cr_safetensors_write(path, t, n, m, nm, err);
    free(names);
    free(t);
    return st;
}

/* ------------------------------------------------------------- loading -- */

/* Whole-string decimal integers: no sign for unsigned, no spaces, no overflow. */
static int parse_u64(const char *s, uint64_t *out) {
    if (!s || *s < '0' || *s > '9') return 0;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || *end) return 0;
    *out = v;
    return 1;
}

static int parse_i64(const char *s, int64_t *out) {
    if (!s || !((*s >= '0' && *s <= '9') || (*s == '-' && s[1] >= '0' && s[1] <= '9'))) return 0;
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (errno || *end) return 0;
    *out = v;
    return 1;
}

static cr_status meta_u64(const cr_safetensors *st, const char *path, const char *key,
                          uint64_t *out, cr_error *err) {
    const char *v = cr_safetensors_meta(st, key);
    if (!v) return CR_FAIL(err, CR_ERR_PARSE, "%s: checkpoint metadata lacks '%s'", path, key);
    if (!parse_u64(v, out))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: metadata '%s' = \"%.40s\" is not an unsigned integer", path, key, v);
    return CR_OK;
}

static cr_status meta_i64(const cr_safetensors *st, const char *path, const char *key, int64_t *out,
                          cr_error *err) {
    const char *v = cr_safetensors_meta(st, key);
    if (!v) return CR_FAIL(err, CR_ERR_PARSE, "%s: checkpoint metadata lacks '%s'", path, key);
    if (!parse_i64(v, out))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: metadata '%s' = \"%.40s\" is not an integer", path,
                       key, v);
    return CR_OK;
}

/* The metadata into *m (config_json left NULL: copied last, once all else passed). */
static cr_status parse_meta(const cr_safetensors *st, const char *path, cr_checkpoint_meta *m,
                            cr_error *err) {
    memset(m, 0, sizeof *m);
    int64_t used;
    CR_TRY(meta_i64(st, path, "epoch", &m->epoch, err));
    CR_TRY(meta_i64(st, path, "step", &m->step, err));
    CR_TRY(meta_u64(st, path, "seed", &m->seed, err));
    CR_TRY(meta_u64(st, path, "rng.seed", &m->rng.seed, err));
    CR_TRY(meta_u64(st, path, "rng.stream", &m->rng.stream, err));
    CR_TRY(meta_u64(st, path, "rng.counter", &m->rng.counter, err));
    CR_TRY(meta_i64(st, path, "rng.used", &used, err));
    if (used < 0 || used > 4 || (used < 4 && m->rng.counter == 0))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: rng.used = %lld does not fit rng.counter = %llu",
                       path, (long long)used, (unsigned long long)m->rng.counter);
    m->rng.used = (int)used;
    if (m->rng.counter > 0)
        cr_philox4x32(m->rng.seed, m->rng.stream, m->rng.counter - 1, m->rng.block);
    const char *loss = cr_safetensors_meta(st, "loss");
    if (!loss) return CR_FAIL(err, CR_ERR_PARSE, "%s: checkpoint metadata lacks 'loss'", path);
    char *end;
    m->loss = strtof(loss, &end);
    if (end == loss || *end)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: metadata 'loss' = \"%.40s\" is not a number", path,
                       loss);
    return CR_OK;
}

/* Every optimiser buffer of every parameter present with the parameter's shape
 * and finite. */
static cr_status check_optim(const cr_safetensors *st, const char *path, cr_nn_params *model,
                             cr_optim *opt, int64_t *steps, cr_error *err) {
    const char *kind = cr_safetensors_meta(st, "optim.kind");
    const char *want = cr_optim_kind_name(cr_optim_get_def(opt)->kind);
    if (!kind)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: the checkpoint holds no optimiser state", path);
    if (strcmp(kind, want) != 0)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: optimiser state is for %.20s, the optimiser is %s",
                       path, kind, want);
    CR_TRY(meta_i64(st, path, "optim.step", steps, err));
    if (*steps < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: optim.step = %lld is negative", path,
                       (long long)*steps);
    char nm[NAME_CAP];
    for (int k = 0; k < cr_optim_state_count(opt); k++) {
        const char *buffer;
        cr_optim_state(opt, k, &buffer);
        for (int i = 0; i < cr_nn_params_count(model); i++) {
            const char *name;
            cr_tensor *x = cr_nn_params_at(model, i, &name);
            state_name(nm, buffer, name);
            CR_TRY(cr_safetensors_check_tensor(st, path, nm, x, err));
        }
    }
    return CR_OK;
}

static void restore_optim(const cr_safetensors *st, cr_nn_params *model, cr_optim *opt,
                          int64_t steps) {
    const float *base = cr_nn_params_data(model, NULL);
    char nm[NAME_CAP];
    for (int k = 0; k < cr_optim_state_count(opt); k++) {
        const char *buffer;
        float *state = cr_optim_state(opt, k, &buffer);
        for (int i = 0; i < cr_nn_params_count(model); i++) {
            const char *name;
            cr_tensor *x = cr_nn_params_at(model, i, &name);
            state_name(nm, buffer, name);
            const cr_st_tensor *t = cr_safetensors_find(st, nm);
            if (x->numel > 0)
                memcpy(state + (x->data - base), t->data, (size_t)x->numel * sizeof(float));
        }
    }
    cr_optim_set_step_count(opt, steps);
}

static cr_status load(const cr_safetensors *st, const char *path, cr_nn_params *model,
                      cr_optim *opt, cr_checkpoint_meta *meta, cr_error *err) {
    if ((opt || meta) && !cr_safetensors_meta(st, FORMAT_KEY))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: not a crease checkpoint (no '" FORMAT_KEY "' in the metadata)", path);
    for (int i = 0; i < st->ntensors; i++) {
        const char *name = st->tensors[i].name;
        if (strncmp(name, OPTIM_PREFIX, strlen(OPTIM_PREFIX)) != 0 &&
            !cr_nn_params_find(model, name))
            return CR_FAIL(err, CR_ERR_INVALID, "%s: tensor '%s' is not a parameter of the model",
                           path, name);
    }
    int64_t steps = 0;
    if (opt) CR_TRY(check_optim(st, path, model, opt, &steps, err));
    cr_checkpoint_meta m;
    if (meta) CR_TRY(parse_meta(st, path, &m, err));
    const char *config = meta ? cr_safetensors_meta(st, "config") : NULL;
    if (config) {
        size_t len = strlen(config) + 1;
        m.config_json = cr_malloc(len, err);
        if (!m.config_json) return CR_ERR_MEMORY;
        memcpy(m.config_json, config, len);
    }
    /* Checks the model's names and shapes before it writes anything. */
    cr_status s = cr_safetensors_to_params(st, path, model, 1, err);
    if (s != CR_OK) {
        if (meta) free(m.config_json);
        return s;
    }
    if (opt) restore_optim(st, model, opt, steps);
    if (meta) *meta = m;
    return CR_OK;
}

cr_status cr_checkpoint_load(const char *path, cr_nn_params *model, cr_optim *opt,
                             cr_checkpoint_meta *meta, cr_error *err) {
    CR_ASSERT(!opt || cr_optim_params(opt) == model);
    cr_safetensors st;
    CR_TRY(cr_safetensors_read(path, &st, err));
    cr_status s = load(&st, path, model, opt, meta, err);
    cr_safetensors_free(&st);
    return s;
}
