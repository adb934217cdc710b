/* uv_fit.c: the drape paper's Table 1 (section 4.1): supervised regression of
 * a deformation over UV by a plain MLP, a positional-encoding MLP and the
 * multi-resolution grid encoding + MLP, with resumable checkpoints, a JSON
 * lines log and a picture of the learned surface coloured by its error.
 *
 * Left out: the unsupervised physics training of the drape method itself
 * (methods/drape, a later issue); this file only measures representations.
 */
#include "crease/uv_fit.h"

#include "crease/base_mpi.h"

#include "crease/mesh_io.h"
#include "crease/nn.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_layers.h"
#include "crease/nn_optim.h"
#include "crease/primitives.h"
#include "crease/render.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* N points, B batch rows. */

static const uint32_t FIT_DEF_COOKIE = 0x46495444u;
static const size_t FIT_ARENA_BYTES = (size_t)384 << 20;
enum { EVAL_CHUNK = 16384, SURFACE_MAX_SIDE = 256, PE_FREQUENCIES = 4 };
/* Error colour map range of the surface picture, m: 0 to 1% of the target's amplitude peak. */
static const float SURFACE_ERROR_RANGE_M = 0.0012f;

static const char *const model_names[CR_FIT_MODEL_COUNT] = {"mlp", "pe", "grid"};

const char *cr_fit_model_name(cr_fit_model m) {
    return (int)m >= 0 && m < CR_FIT_MODEL_COUNT ? model_names[m] : "?";
}

cr_status cr_fit_model_parse(const char *name, cr_fit_model *out, cr_error *err) {
    for (int i = 0; i < CR_FIT_MODEL_COUNT; i++)
        if (strcmp(name, model_names[i]) == 0) {
            *out = (cr_fit_model)i;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID, "unknown model '%s' (expected mlp, pe or grid)", name);
}

/* Learning rates: the paper gives none. 1e-3 is Adam's default and suits the
 * two MLPs; the grid model trains at Instant-NGP's 1e-2 (the peer's rate for
 * the grid; docs/nn.md gives the epochs measured at other rates). */
static float default_lr(cr_fit_model m) {
    return m == CR_FIT_GRID ? 1e-2f : 1e-3f;
}

cr_fit_def cr_fit_default_def(cr_fit_model model) {
    cr_fit_def d = {
        .model = model,
        .epochs = 2000,
        .train_res = 256,
        .eval_res = 512,
        .batch = 4096,
        .lr = 0.0f,
        .target_rel_l2 = 0.01f,
        .stop_at_target = 1,
        .eval_every = 1,
        .seed = 1,
        .checkpoint_every = 50,
        .cookie = FIT_DEF_COOKIE,
    };
    return d;
}

void cr_fit_target(float u, float v, float d[3]) {
    const double two_pi = 2.0 * M_PI;
    d[0] = 0.0f;
    d[1] = 0.0f;
    d[2] = (float)(0.10 * sin(two_pi * 2 * u) * sin(two_pi * 2 * v) +
                   0.02 * sin(two_pi * 8 * u) * sin(two_pi * 8 * v));
}

/* ------------------------------------------------------------- model -- */

typedef struct fit_model {
    cr_fit_model kind;
    cr_nn_params *params;
    cr_mlp *mlp;
    cr_grid_encoding *grid;
} fit_model;

static cr_status model_create(cr_fit_model kind, cr_rng *rng, fit_model *m, cr_error *err) {
    memset(m, 0, sizeof *m);
    m->kind = kind;
    CR_TRY(cr_nn_params_create(&m->params, err));
    cr_mlp_def mlp = cr_mlp_default_def();
    mlp.act = CR_ACT_RELU;
    mlp.nlayers = 4;
    /* PyTorch's nn.Linear start, as the peer (../shared/peers/torch_fit.py):
     * with cr_mlp's Kaiming default the grid model needed 11-20x the epochs
     * (docs/nn.md, "Convergence parity"). */
    mlp.init = CR_INIT_TORCH;
    int in, hidden;
    if (kind == CR_FIT_GRID) {
        cr_grid_encoding_def g = cr_grid_encoding_default_def(); /* 100 cells, 2 levels, F 3 */
        CR_TRY(cr_grid_encoding_create(&g, m->params, "grid", rng, &m->grid, err));
        in = cr_grid_encoding_out_dim(&g), hidden = 64;
    } else if (kind == CR_FIT_PE) {
        in = (int)cr_fourier_encoding_dim(2, PE_FREQUENCIES), hidden = 148;
    } else {
        in = 2, hidden = 152;
    }
    int widths[5] = {in, hidden, hidden, hidden, 3};
    memcpy(mlp.widths, widths, sizeof widths);
    return cr_mlp_create(&mlp, m->params, "mlp", rng, &m->mlp, err);
}

static void model_destroy(fit_model *m) {
    cr_mlp_destroy(m->mlp);
    cr_grid_encoding_destroy(m->grid);
    cr_nn_params_destroy(m->params);
}

/* uv (N,2) -> deformation (N,3). */
static cr_tensor *model_forward(cr_nn_ctx *ctx, const fit_model *m, cr_tensor *uv) {
    cr_tensor *features = uv;
    if (m->kind == CR_FIT_GRID) features = cr_grid_encoding_forward(ctx, m->grid, uv);
    if (m->kind == CR_FIT_PE) features = cr_fourier_encoding_forward(ctx, uv, PE_FREQUENCIES);
    return cr_mlp_forward(ctx, m->mlp, features);
}

/* ----------------------------------------------------------- samples -- */

/* uv (N,2) on a res x res grid of nodes over [0,1]^2 and the target there (N,3). */
static cr_status make_samples(int res, float **uv, float **target, cr_error *err) {
    size_t n = (size_t)res * res;
    *uv = cr_malloc(n * 2 * sizeof(float), err);
    *target = cr_malloc(n * 3 * sizeof(float), err);
    if (!*uv || !*target) return CR_ERR_MEMORY;
    for (int j = 0; j < res; j++)
        for (int i = 0; i < res; i++) {
            size_t k = (size_t)j * res + i;
            (*uv)[2 * k] = (float)i / (float)(res - 1);
            (*uv)[2 * k + 1] = (float)j / (float)(res - 1);
            cr_fit_target((*uv)[2 * k], (*uv)[2 * k + 1], &(*target)[3 * k]);
        }
    return CR_OK;
}

/* Model output at n points, in chunks, without recording a tape: pred (N,3). */
static cr_status predict(cr_nn_ctx *ctx, const fit_model *m, const float *uv, int64_t n,
                         float *pred, cr_error *err) {
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_status st = CR_OK;
    for (int64_t start = 0; start < n && st == CR_OK; start += EVAL_CHUNK) {
        int64_t len = n - start < EVAL_CHUNK ? n - start : EVAL_CHUNK;
        cr_nn_ctx_reset(ctx);
        cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){len, 2}, uv + 2 * start);
        cr_tensor *y = model_forward(ctx, m, x);
        st = cr_nn_ctx_error(ctx, err);
        if (st == CR_OK) memcpy(pred + 3 * start, y->data, (size_t)len * 3 * sizeof(float));
    }
    cr_nn_ctx_reset(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 1);
    return st;
}

/* ||pred - target|| / ||target|| over all points, in double. */
static double relative_l2(const float *pred, const float *target, int64_t n) {
    double num = 0, den = 0;
    for (int64_t i = 0; i < 3 * n; i++) {
        double d = (double)pred[i] - target[i];
        num += d * d;
        den += (double)target[i] * target[i];
    }
    return den > 0 ? sqrt(num / den) : sqrt(num);
}

/* ------------------------------------------------------------ training -- */

typedef struct fit_run {
    const cr_fit_def *def;
    fit_model model;
    cr_optim *opt;
    cr_nn_ctx *ctx;
    cr_rng rng;
    float *train_uv, *train_target; /* (N,2), (N,3) */
    float *eval_uv, *eval_target, *eval_pred;
    float *batch_uv, *batch_target; /* (B,2), (B,3) */
    int32_t *order;                 /* (N) shuffled point order */
    char ckpt_path[1024], log_path[1024];
} fit_run;

/* One epoch of shuffled mini-batches; *loss gets the mean of the batch losses. */
static cr_status train_epoch(fit_run *r, double *loss, cr_error *err) {
    const cr_fit_def *def = r->def;
    int64_t n = (int64_t)def->train_res * def->train_res;
    /* Shuffle from the identity, so an epoch's order depends on the generator
     * state alone and a resumed run draws the same batches. */
    for (int64_t i = 0; i < n; i++)
        r->order[i] = (int32_t)i;
    cr_rng_shuffle_i32(&r->rng, r->order, n);
    double sum = 0;
    int batches = 0;
    /* Under MPI each rank takes rows [lo, hi) of every global batch (the
     * same shuffled order on every rank: one generator stream), weights its
     * mean-loss gradient by its share of the rows, and the ranks' gradients
     * are summed in rank order (cr_mpi_allreduce_sum) before the step: every
     * rank takes the same step, that of the global batch up to float
     * summation order. */
    const int rank = cr_mpi_rank(), size = cr_mpi_size();
    for (int64_t start = 0; start < n; start += def->batch) {
        int64_t gb = n - start < def->batch ? n - start : def->batch;
        int64_t lo = gb * rank / size, hi = gb * (rank + 1) / size, b = hi - lo;
        for (int64_t i = 0; i < b; i++) {
            int32_t k = r->order[start + lo + i];
            memcpy(&r->batch_uv[2 * i], &r->train_uv[2 * (int64_t)k], 2 * sizeof(float));
            memcpy(&r->batch_target[3 * i], &r->train_target[3 * (int64_t)k], 3 * sizeof(float));
        }
        cr_nn_ctx_reset(r->ctx);
        float batch_loss = 0.0f;
        if (b == 0) cr_nn_params_zero_grad(r->model.params);
        if (b > 0) {
            cr_tensor *x = cr_nn_wrap(r->ctx, 2, (int64_t[]){b, 2}, r->batch_uv);
            cr_tensor *y = cr_nn_wrap(r->ctx, 2, (int64_t[]){b, 3}, r->batch_target);
            cr_tensor *l = cr_nn_mean(
                r->ctx,
                cr_nn_square(r->ctx, cr_nn_sub(r->ctx, model_forward(r->ctx, &r->model, x), y)));
            cr_nn_params_zero_grad(r->model.params);
            CR_TRY(cr_nn_backward(r->ctx, l, err));
            batch_loss = l->data[0];
        }
        if (size > 1) {
            int64_t ng = 0;
            float *g = cr_nn_params_grad(r->model.params, &ng);
            const float share = (float)b / (float)gb;
            if (g) {
                for (int64_t i = 0; i < ng; i++)
                    g[i] *= share;
                CR_TRY(cr_mpi_allreduce_sum(g, ng, err));
            }
            batch_loss *= share;
            CR_TRY(cr_mpi_allreduce_sum(&batch_loss, 1, err));
        }
        CR_TRY(cr_optim_step(r->opt, err));
        sum += batch_loss;
        batches++;
    }
    *loss = sum / batches;
    return CR_OK;
}

/* Progress kept in the checkpoint's config string, so a resumed run reports
 * totals over both parts. */
static char *progress_json(const fit_run *r, const cr_fit_result *res) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "model", cr_fit_model_name(r->def->model));
    cJSON_AddNumberToObject(j, "seconds", res->seconds);
    cJSON_AddNumberToObject(j, "eval_seconds", res->eval_seconds);
    cJSON_AddNumberToObject(j, "epochs_to_target", res->epochs_to_target);
    cJSON_AddNumberToObject(j, "seconds_to_target", res->seconds_to_target);
    char *s = cJSON_PrintUnformatted(j);
    cJSON_Delete(j);
    return s;
}

static cr_status save_checkpoint(fit_run *r, const cr_fit_result *res, double loss, cr_error *err) {
    if (cr_mpi_rank() != 0) return CR_OK; /* every rank holds the same model */
    cr_checkpoint_meta meta = {.epoch = res->epochs,
                               .step = cr_optim_step_count(r->opt),
                               .seed = r->def->seed,
                               .rng = r->rng,
                               .loss = (float)loss,
                               .config_json = progress_json(r, res)};
    cr_status st = cr_checkpoint_save(r->ckpt_path, r->model.params, r->opt, &meta, err);
    cJSON_free(meta.config_json);
    return st;
}

static cr_status resume(fit_run *r, cr_fit_result *res, cr_error *err) {
    struct stat sb;
    if (stat(r->ckpt_path, &sb) != 0) { /* nothing to resume: a fresh run, said */
        cr_log(CR_LOG_WARN, "fit: --resume: no checkpoint at %s; training from the start",
               r->ckpt_path);
        return CR_OK;
    }
    cr_checkpoint_meta meta = {0};
    CR_TRY(cr_checkpoint_load(r->ckpt_path, r->model.params, r->opt, &meta, err));
    cJSON *j = meta.config_json ? cJSON_Parse(meta.config_json) : NULL;
    const cJSON *model = cJSON_GetObjectItemCaseSensitive(j, "model");
    cr_status st = CR_OK;
    if (!cJSON_IsString(model) || strcmp(model->valuestring, cr_fit_model_name(r->def->model)))
        st = CR_FAIL(err, CR_ERR_INVALID, "%s: a checkpoint of another model, not '%s'",
                     r->ckpt_path, cr_fit_model_name(r->def->model));
    const char *keys[4] = {"seconds", "eval_seconds", "epochs_to_target", "seconds_to_target"};
    double v[4] = {0};
    for (int k = 0; k < 4 && st == CR_OK; k++) {
        const cJSON *x = cJSON_GetObjectItemCaseSensitive(j, keys[k]);
        if (!cJSON_IsNumber(x))
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: config '%s' is %s", r->ckpt_path, keys[k],
                         x ? "not a number" : "missing");
        else
            v[k] = x->valuedouble;
    }
    if (st == CR_OK) {
        res->epochs = res->resumed_from = (int)meta.epoch;
        res->seconds = v[0];
        res->eval_seconds = v[1];
        res->epochs_to_target = (int)v[2];
        res->seconds_to_target = v[3];
        res->final_loss = meta.loss;
        r->rng = meta.rng;
    }
    cJSON_Delete(j);
    free(meta.config_json);
    return st;
}

static void log_line(const fit_run *r, int epoch, double loss, double rel, double seconds) {
    if (cr_mpi_rank() != 0) return;
    if (!r->def->out_dir) return;
    FILE *fp = fopen(r->log_path, "a");
    if (!fp) return; /* the log is a convenience; the result and checkpoint carry the run */
    fprintf(fp, "{\"epoch\":%d,\"loss\":%.9g,\"rel_l2\":%.9g,\"seconds\":%.6f}\n", epoch, loss, rel,
            seconds);
    fclose(fp);
}

/* The learned surface on a grid, Z-up as the target is defined, coloured by
 * its error; drawn Y-up ((x,y,z) -> (x,z,-y)) so the relief faces the camera. */
static cr_status write_surface(fit_run *r, cr_fit_result *res, cr_error *err) {
    int side = r->def->eval_res < SURFACE_MAX_SIDE ? r->def->eval_res : SURFACE_MAX_SIDE;
    cr_mesh *mesh = NULL;
    CR_TRY(cr_prim_plane(side, side, 1.0f, 1.0f, &mesh, err));
    float *uv = cr_malloc((size_t)mesh->nv * 2 * sizeof(float), err);
    float *pred = cr_malloc((size_t)mesh->nv * 3 * sizeof(float), err);
    float *error = cr_malloc((size_t)mesh->nv * sizeof(float), err);
    cr_status st = uv && pred && error ? CR_OK : CR_ERR_MEMORY;
    for (int64_t c = 0; st == CR_OK && c < 3 * (int64_t)mesh->nf; c++)
        memcpy(&uv[2 * (int64_t)mesh->tri[c]], &mesh->uv[2 * (int64_t)mesh->tri_uv[c]],
               2 * sizeof(float));
    if (st == CR_OK) st = predict(r->ctx, &r->model, uv, mesh->nv, pred, err);
    for (int32_t i = 0; st == CR_OK && i < mesh->nv; i++) {
        float t[3], *p = &mesh->pos[3 * (int64_t)i];
        const float *d = &pred[3 * (int64_t)i];
        cr_fit_target(uv[2 * i], uv[2 * i + 1], t);
        error[i] = sqrtf((d[0] - t[0]) * (d[0] - t[0]) + (d[1] - t[1]) * (d[1] - t[1]) +
                         (d[2] - t[2]) * (d[2] - t[2]));
        p[0] = uv[2 * i] + d[0], p[1] = uv[2 * i + 1] + d[1], p[2] = d[2];
    }
    char path[1100];
    snprintf(path, sizeof path, "%s/surface.obj", r->def->out_dir);
    if (st == CR_OK) st = cr_mesh_write(path, mesh, err);
    for (int32_t i = 0; st == CR_OK && i < mesh->nv; i++) {
        float *p = &mesh->pos[3 * (int64_t)i], y = p[1];
        p[1] = p[2], p[2] = -y;
    }
    cr_render_def rd = cr_render_default_def();
    rd.width = rd.height = 768;
    rd.colormap_auto = 0;
    rd.colormap_min = 0.0f, rd.colormap_max = SURFACE_ERROR_RANGE_M;
    cr_render_object obj = {.mesh = mesh, .scalar = error};
    snprintf(res->surface_png, sizeof res->surface_png, "%s/surface.png", r->def->out_dir);
    if (st == CR_OK) st = cr_render_to_png(&rd, &obj, 1, res->surface_png, err);
    free(uv), free(pred), free(error);
    cr_mesh_destroy(mesh);
    return st;
}

static cr_status check_def(const cr_fit_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == FIT_DEF_COOKIE);
    if (d->epochs < 1) return CR_FAIL(err, CR_ERR_INVALID, "fit: epochs must be >= 1");
    if (d->train_res < 2 || d->train_res > 4096 || d->eval_res < 2 || d->eval_res > 4096)
        return CR_FAIL(err, CR_ERR_INVALID, "fit: grid sides must lie in [2, 4096]");
    if (d->batch < 1) return CR_FAIL(err, CR_ERR_INVALID, "fit: batch must be >= 1");
    if (!(d->lr >= 0) || !(d->target_rel_l2 > 0) || d->eval_every < 1 || d->checkpoint_every < 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "fit: need lr >= 0, target > 0, eval_every >= 1, checkpoint_every >= 0");
    if (d->resume && !d->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID, "fit: resuming needs an output directory");
    return CR_OK;
}

static cr_status run_setup(fit_run *r, cr_error *err) {
    const cr_fit_def *def = r->def;
    r->rng = cr_rng_make(def->seed, 0);
    CR_TRY(model_create(def->model, &r->rng, &r->model, err));
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.base = def->lr > 0 ? def->lr : default_lr(def->model);
    CR_TRY(cr_optim_create(&od, r->model.params, &r->opt, err));
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = FIT_ARENA_BYTES;
    CR_TRY(cr_nn_ctx_create(&cd, &r->ctx, err));
    CR_TRY(make_samples(def->train_res, &r->train_uv, &r->train_target, err));
    CR_TRY(make_samples(def->eval_res, &r->eval_uv, &r->eval_target, err));
    int64_t n = (int64_t)def->train_res * def->train_res,
            ne = (int64_t)def->eval_res * def->eval_res;
    r->eval_pred = cr_malloc((size_t)ne * 3 * sizeof(float), err);
    r->batch_uv = cr_malloc((size_t)def->batch * 2 * sizeof(float), err);
    r->batch_target = cr_malloc((size_t)def->batch * 3 * sizeof(float), err);
    r->order = cr_malloc((size_t)n * sizeof(int32_t), err);
    if (!r->eval_pred || !r->batch_uv || !r->batch_target || !r->order) return CR_ERR_MEMORY;
    if (def->out_dir) {
        CR_TRY(cr_mkdir_p(def->out_dir, err));
        snprintf(r->ckpt_path, sizeof r->ckpt_path, "%s/checkpoint.safetensors", def->out_dir);
        snprintf(r->log_path, sizeof r->log_path, "%s/log.jsonl", def->out_dir);
    }
    return CR_OK;
}

static void run_free(fit_run *r) {
    model_destroy(&r->model);
    cr_optim_destroy(r->opt);
    cr_nn_ctx_destroy(r->ctx);
    free(r->train_uv), free(r->train_target);
    free(r->eval_uv), free(r->eval_target), free(r->eval_pred);
    free(r->batch_uv), free(r->batch_target), free(r->order);
}

static cr_status train(fit_run *r, cr_fit_result *res, cr_error *err) {
    const cr_fit_def *def = r->def;
    int64_t ne = (int64_t)def->eval_res * def->eval_res;
    char label[32];
    snprintf(label, sizeof label, "fit %s", cr_fit_model_name(def->model));
    cr_progress bar;
    cr_progress_begin(&bar, label, def->epochs, def->quiet);
    double loss = res->final_loss;
    int reached = res->epochs_to_target > 0 && def->stop_at_target;
    while (res->epochs < def->epochs && !reached) {
        double t0 = cr_time_now();
        CR_TRY(train_epoch(r, &loss, err));
        res->seconds += cr_time_now() - t0;
        res->epochs++;
        int last = res->epochs == def->epochs;
        if (res->epochs % def->eval_every == 0 || last) {
            double t1 = cr_time_now();
            CR_TRY(predict(r->ctx, &r->model, r->eval_uv, ne, r->eval_pred, err));
            res->rel_l2 = relative_l2(r->eval_pred, r->eval_target, ne);
            res->eval_seconds += cr_time_now() - t1;
            log_line(r, res->epochs, loss, res->rel_l2, res->seconds);
            if (res->rel_l2 <= def->target_rel_l2 && res->epochs_to_target < 0) {
                res->epochs_to_target = res->epochs;
                res->seconds_to_target = res->seconds;
                reached = def->stop_at_target;
            }
        }
        res->final_loss = loss;
        if (def->out_dir && def->checkpoint_every > 0 && res->epochs % def->checkpoint_every == 0)
            CR_TRY(save_checkpoint(r, res, loss, err));
        cr_progress_update(&bar, res->epochs, "loss %.3e rel_l2 %.4f", loss, res->rel_l2);
    }
    cr_progress_end(&bar);
    return CR_OK;
}

cr_status cr_fit_run(const cr_fit_def *def, cr_fit_result *res, cr_error *err) {
    CR_TRY(check_def(def, err));
    memset(res, 0, sizeof *res);
    res->epochs_to_target = -1;
    res->seconds_to_target = -1;
    fit_run r = {.def = def};
    cr_status st = run_setup(&r, err);
    if (st == CR_OK) res->params = cr_nn_params_numel(r.model.params);
    if (st == CR_OK && def->resume) st = resume(&r, res, err);
    if (st == CR_OK && def->out_dir && cr_mpi_rank() == 0)
        st = cr_train_log_cut(r.log_path, res->resumed_from, err);
    if (st == CR_OK) st = train(&r, res, err);
    if (st == CR_OK && res->epochs == res->resumed_from) {
        /* nothing left to train: report the error of the resumed model */
        int64_t ne = (int64_t)def->eval_res * def->eval_res;
        st = predict(r.ctx, &r.model, r.eval_uv, ne, r.eval_pred, err);
        if (st == CR_OK) res->rel_l2 = relative_l2(r.eval_pred, r.eval_target, ne);
    }
    if (st == CR_OK && def->out_dir) st = save_checkpoint(&r, res, res->final_loss, err);
    if (st == CR_OK && def->out_dir && cr_mpi_rank() == 0) st = write_surface(&r, res, err);
    run_free(&r);
    return st;
}
