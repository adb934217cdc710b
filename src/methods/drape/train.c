/* train.c: the drape method's training loop (Algorithm 1 of the paper) for
 * all four variants, the convergence criterion, resumable checkpoints and the
 * loss log (cr_drape_train_; run.c turns the trained surface into outputs).
 *
 * One epoch:
 *   structure variants: (adaptive, every pdf_every epochs) score local
 *     structures at the PDF cell centres with the current surface and blend
 *     the PDF (eq. 7); draw N points (mu N adaptive, the rest uniform, Lloyd
 *     relaxed); build a structure at each with a random angle in
 *     [0, 2 pi/3); one Adam step on the weighted sum of the four losses.
 *   mesh variants: one Adam step on the mesh losses over the whole grid.
 * Every eval_every epochs: the energy of the current surface on the fixed
 * structures (same for all variants), logged; converged when the lowest
 * energy reached fell by less than converge_tol times its total decrease
 * since the first evaluation over the last converge_window epochs
 * (offset-free: the gravity term's zero is arbitrary; the running minimum
 * ignores the upward spikes of contacts jittering into the eps band).
 *
 * The PDF's per-cell loss leaves out gravity: its value depends on where
 * height zero is and may be negative, and a PDF should follow detail
 * (stretch, folds, contact), not altitude.
 *
 * Checkpoints hold the parameters, Adam's moments, the generator, the
 * evaluation history and the sampler's PDF. A resumed run is bit-identical
 * to one that never stopped for mesh, inr-mesh and inr-uniform; inr-adaptive
 * restores the PDF by repeated eq. 7 blends towards the saved one, exact to
 * float rounding (cr_drape_sampler_set_pdf would set it outright).
 */
#include "drape_internal.h"

#include "crease/drape_sampling.h"
#include "crease/losses.h"
#include "crease/mesh_io.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_optim.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* N training structures, M fixed evaluation structures, G PDF cells per side. */

enum { EVAL_BATCH = 4096 /* structures per evaluation chunk */ };
static const uint64_t EVAL_SEED = 0x65766131u; /* fixed rotations, the same for every run */
#define TWO_PI_3 (2.0 * M_PI / 3.0)
#define CLIP_RATE 0.05 /* running mean over about 20 epochs */

/* ------------------------------------------------------------ set-up -- */

static int64_t max3(int64_t a, int64_t b, int64_t c) {
    int64_t m = a > b ? a : b;
    return m > c ? m : c;
}

/* The UV chart as a mask over the sampler's cells (a user cloth). */
static cr_status chart_mask(const drape_run *r, int g, uint8_t **out, cr_error *err) {
    *out = cr_malloc((size_t)g * g, err);
    if (!*out) return CR_ERR_MEMORY;
    int any = 0;
    for (int i = 0; i < g; i++)
        for (int j = 0; j < g; j++) {
            int32_t f;
            double b[3];
            (*out)[i * g + j] = (uint8_t)cr_uv_lookup_find(cr_drape_model_lookup(r->model),
                                                           (j + 0.5f) / g, (i + 0.5f) / g, &f, b);
            any |= (*out)[i * g + j];
        }
    if (!any) {
        free(*out);
        *out = NULL;
        return CR_FAIL(err, CR_ERR_INVALID,
                       "--cloth %s: the UV chart covers no PDF cell centre (raise --pdf-grid)",
                       r->def->cloth_path);
    }
    return CR_OK;
}

static cr_status setup(drape_run *r, cr_error *err) {
    const cr_drape_def *def = r->def;
    r->rng = cr_rng_make(def->seed, 1);
    CR_TRY(cr_drape_scene_create(def, &r->scene, err));
    CR_TRY(cr_drape_model_create(def, r->scene.rest, &r->model, err));
    CR_TRY(cr_drape_loss_ctx_create(def, r->scene.bvh, &r->lc, err));
    r->structures = def->variant == CR_DRAPE_INR_UNIFORM || def->variant == CR_DRAPE_INR_ADAPTIVE;
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.base = def->lr;
    od.beta2 = def->beta2;
    if (def->lr_final >= 0.0f) {
        od.lr.kind = CR_LR_COSINE;
        od.lr.final = def->lr_final;
        od.lr.total_steps = def->epochs;
    } else if (def->settle_epochs > 0 && def->epochs >= 2) {
        /* one drop by ten for the last settle epochs, at most half the run (the
         * step schedule drops every step_every steps: so it drops once) */
        int settle = def->settle_epochs < def->epochs / 2 ? def->settle_epochs : def->epochs / 2;
        od.lr.kind = CR_LR_STEP;
        od.lr.gamma = 0.1f;
        od.lr.step_every = def->epochs - settle;
    }
    CR_TRY(cr_optim_create(&od, cr_drape_model_params(r->model), &r->opt, err));
    int64_t g2 = (int64_t)def->pdf_grid * def->pdf_grid;
    int64_t smax = max3(def->samples, g2, EVAL_BATCH);
    int64_t points = max3(6 * smax, r->scene.rest->nv, 32768);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = ((size_t)64 << 20) + (size_t)points * 4096;
    CR_TRY(cr_nn_ctx_create(&cd, &r->ctx, err));
    r->x = cr_malloc((size_t)smax * 18 * sizeof(float), err);
    r->per_structure = cr_malloc((size_t)smax * sizeof(float), err);
    if (!r->x || !r->per_structure) return CR_ERR_MEMORY;
    if (r->structures) {
        cr_drape_sampler_def sd = cr_drape_sampler_default_def();
        sd.grid = def->pdf_grid;
        sd.gamma = def->pdf_gamma;
        sd.mu = def->variant == CR_DRAPE_INR_ADAPTIVE ? def->mu : 0.0f;
        sd.lloyd_iterations = def->lloyd_iterations;
        uint8_t *mask = NULL;
        if (!r->scene.square) CR_TRY(chart_mask(r, def->pdf_grid, &mask, err));
        sd.mask = mask;
        cr_status st = cr_drape_sampler_create(&sd, &r->sampler, err);
        free(mask);
        CR_TRY(st);
        CR_TRY(cr_drape_batch_alloc(&r->train, def->samples, err));
        CR_TRY(cr_drape_batch_alloc(&r->cells, g2, err));
        r->centre = cr_malloc((size_t)def->samples * 2 * sizeof(float), err);
        r->theta = cr_malloc((size_t)def->samples * sizeof(float), err);
        r->cell_loss = cr_malloc((size_t)g2 * sizeof(float), err);
        r->cell_theta = cr_malloc((size_t)g2 * sizeof(float), err);
        if (!r->centre || !r->theta || !r->cell_loss || !r->cell_theta) return CR_ERR_MEMORY;
    } else {
        CR_TRY(cr_drape_mesh_losses_create(def, &r->scene, &r->ml, err));
    }
    /* the pin: the chart centre, when it lies on the chart */
    r->pin_uv[0] = r->pin_uv[1] = 0.5f;
    uint8_t on = 0;
    cr_drape_model_rest(r->model, r->pin_uv, 1, r->pin_p0, &on);
    r->pinned = def->pin > 0.0f && on;
    /* the fixed evaluation structures: cell centres of an eval_res grid */
    int e = def->eval_res;
    r->neval = (int64_t)e * e;
    r->eval_centre = cr_malloc((size_t)r->neval * 2 * sizeof(float), err);
    r->eval_theta = cr_malloc((size_t)r->neval * sizeof(float), err);
    if (!r->eval_centre || !r->eval_theta) return CR_ERR_MEMORY;
    cr_rng er = cr_rng_make(EVAL_SEED, 0);
    for (int i = 0; i < e; i++)
        for (int j = 0; j < e; j++) {
            int64_t k = (int64_t)i * e + j;
            r->eval_centre[2 * k] = (j + 0.5f) / e;
            r->eval_centre[2 * k + 1] = (i + 0.5f) / e;
            r->eval_theta[k] = (float)(TWO_PI_3 * cr_rng_uniform(&er));
        }
    r->neval_batches = (int)((r->neval + EVAL_BATCH - 1) / EVAL_BATCH);
    r->eval = cr_calloc((size_t)r->neval_batches, sizeof *r->eval, err);
    if (!r->eval) return CR_ERR_MEMORY;
    for (int k = 0; k < r->neval_batches; k++)
        CR_TRY(cr_drape_batch_alloc(&r->eval[k], EVAL_BATCH, err));
    if (def->out_dir) {
        CR_TRY(cr_mkdir_p(def->out_dir, err));
        snprintf(r->ckpt_path, sizeof r->ckpt_path, "%s/checkpoint.safetensors", def->out_dir);
        snprintf(r->log_path, sizeof r->log_path, "%s/loss.jsonl", def->out_dir);
    }
    return CR_OK;
}

static void run_free(drape_run *r) {
    cr_drape_sampler_destroy(r->sampler);
    cr_drape_batch_free(&r->train), cr_drape_batch_free(&r->cells);
    for (int k = 0; r->eval && k < r->neval_batches; k++)
        cr_drape_batch_free(&r->eval[k]);
    free(r->eval);
    free(r->centre), free(r->theta), free(r->cell_loss), free(r->cell_theta);
    free(r->eval_centre), free(r->eval_theta), free(r->x), free(r->per_structure);
    cr_drape_mesh_losses_free(&r->ml);
    cr_drape_loss_ctx_free(&r->lc);
    free(r->rows);
    cr_nn_ctx_destroy(r->ctx);
    cr_optim_destroy(r->opt);
    cr_drape_model_destroy(r->model);
    cr_drape_scene_free(&r->scene);
}

/* ------------------------------------------------------- evaluation -- */

/* The built structures of b scored with the current surface under `lc`:
 * weighted sums added into sums[4]; *kept (may be NULL) gets how many fitted
 * on the chart, r->per_structure their totals. */
static cr_status score_built(drape_run *r, drape_batch *b, const drape_loss_ctx *lc, double sums[4],
                             int64_t *kept, cr_error *err) {
    cr_status st = cr_drape_model_eval(r->ctx, r->model, b->uv, b->p0, 6 * b->n, r->x, err);
    if (st == CR_OK) st = cr_drape_batch_eval(r->ctx, lc, b, r->x, sums, r->per_structure, err);
    cr_nn_ctx_reset(r->ctx);
    if (kept) *kept += b->n;
    return st;
}

/* The same for structures built at centres (n,2) with angles (n). */
static cr_status score(drape_run *r, drape_batch *b, const drape_loss_ctx *lc, const float *centre,
                       const float *theta, int64_t n, double sums[4], int64_t *kept,
                       cr_error *err) {
    CR_TRY(cr_drape_batch_build(b, r->model, centre, theta, n, r->def->side, r->scene.square, err));
    return score_built(r, b, lc, sums, kept, err);
}

/* Mean weighted terms per fixed structure. */
static cr_status evaluate(drape_run *r, cr_drape_terms *out, cr_error *err) {
    double sums[4] = {0};
    int64_t kept = 0;
    /* The fixed structures depend on the rest chart alone: built at the
     * first evaluation, scored with the current surface at every one. */
    for (int k = 0; !r->eval_built && k < r->neval_batches; k++) {
        int64_t s = (int64_t)k * EVAL_BATCH;
        int64_t len = r->neval - s < EVAL_BATCH ? r->neval - s : EVAL_BATCH;
        CR_TRY(cr_drape_batch_build(&r->eval[k], r->model, r->eval_centre + 2 * s,
                                    r->eval_theta + s, len, r->def->side, r->scene.square, err));
    }
    r->eval_built = 1;
    for (int k = 0; k < r->neval_batches; k++)
        CR_TRY(score_built(r, &r->eval[k], &r->lc, sums, &kept, err));
    if (kept == 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape: no evaluation structure fits on the cloth's UV chart");
    out->strain = sums[0] / kept, out->bend = sums[1] / kept;
    out->gravity = sums[2] / kept, out->collision = sums[3] / kept;
    out->total = out->strain + out->bend + out->gravity + out->collision;
    return CR_OK;
}

/* eq. 7: the weighted loss (gravity left out, see the top) at the cell centres. */
static cr_status update_pdf(drape_run *r, cr_error *err) {
    int64_t g2 = (int64_t)r->def->pdf_grid * r->def->pdf_grid;
    for (int64_t k = 0; k < g2; k++)
        r->cell_theta[k] = (float)(TWO_PI_3 * cr_rng_uniform(&r->rng));
    cr_drape_def nograv = *r->def;
    nograv.w.gravity = 0.0f;
    nograv.w.collision *= r->def->pdf_collision;
    drape_loss_ctx lc = r->lc; /* the same energies, other weights */
    lc.def = &nograv;
    double sums[4] = {0};
    drape_batch *b = &r->cells;
    CR_TRY(score(r, b, &lc, cr_drape_sampler_cell_centres(r->sampler), r->cell_theta, g2, sums,
                 NULL, err));
    memset(r->cell_loss, 0, (size_t)g2 * sizeof(float));
    for (int64_t s = 0; s < b->n; s++)
        r->cell_loss[b->source[s]] = fmaxf(r->per_structure[s], 0.0f);
    return cr_drape_sampler_update(r->sampler, r->cell_loss, err);
}

/* --------------------------------------------------------- training -- */

/* Clip the gradient's norm to def->clip times the running mean of recent
 * (clipped) norms. Eq. 26 with w_collision 1e7 gives a cloth vertex that
 * steps 0.1 mm into the object a gradient some 1e6 times the whole cloth's
 * weight; unclipped, one such step fills Adam's second moment for thousands of
 * epochs (beta2 0.999) and, through the shared MLP, throws the whole cloth
 * off the object. The first epoch sets the mean. */
static cr_status clip_gradient(drape_run *r, cr_error *err) {
    cr_nn_params *p = cr_drape_model_params(r->model);
    float norm = 0.0f;
    if (r->def->clip <= 0.0f) return CR_OK;
    double limit = r->grad_mean > 0.0 ? r->def->clip * r->grad_mean : INFINITY;
    CR_TRY(cr_clip_grad_norm(p, isfinite(limit) ? (float)limit : 3.4e38f, &norm, err));
    double kept = fmin((double)norm, limit);
    r->grad_mean = r->grad_mean > 0.0 ? (1.0 - CLIP_RATE) * r->grad_mean + CLIP_RATE * kept : kept;
    return CR_OK;
}

/* The last step's weighted terms (scalar tensors), mean per structure or vertex. */
static void set_train_terms(drape_run *r, cr_tensor *const *t, double n) {
    cr_drape_terms *tt = &r->train_terms;
    tt->strain = t[0]->data[0] / n, tt->bend = t[1]->data[0] / n;
    tt->gravity = t[2]->data[0] / n, tt->collision = t[3]->data[0] / n;
    tt->total = tt->strain + tt->bend + tt->gravity + tt->collision;
}

/* pin * count * |horizontal displacement of the chart centre|^2, added to
 * `loss` (count: structures or vertices in the loss, so the pin keeps its
 * strength against a sum that grows with them). */
static cr_tensor *add_pin(drape_run *r, cr_tensor *loss, double count) {
    if (!r->pinned) return loss;
    cr_nn_ctx *ctx = r->ctx;
    cr_tensor *x = cr_drape_model_forward(ctx, r->model, r->pin_uv, r->pin_p0, 1);
    const float target[3] = {r->pin_p0[0], 0.0f, r->pin_p0[2]}, horizontal[3] = {1, 0, 1};
    cr_tensor *d = cr_nn_mul(ctx, cr_nn_sub(ctx, x, cr_nn_from(ctx, 1, (int64_t[]){3}, target)),
                             cr_nn_from(ctx, 1, (int64_t[]){3}, horizontal));
    cr_tensor *pin =
        cr_nn_mul_scalar(ctx, cr_nn_sum(ctx, cr_nn_square(ctx, d)), (float)(r->def->pin * count));
    return cr_nn_add(ctx, loss, pin);
}

static cr_status structure_epoch(drape_run *r, int epoch, cr_error *err) {
    const cr_drape_def *def = r->def;
    if (def->variant == CR_DRAPE_INR_ADAPTIVE && epoch % def->pdf_every == 0)
        CR_TRY(update_pdf(r, err));
    CR_TRY(cr_drape_sampler_draw(r->sampler, def->samples, &r->rng, r->centre, err));
    r->drawn = 1;
    for (int k = 0; k < def->samples; k++)
        r->theta[k] = (float)(TWO_PI_3 * cr_rng_uniform(&r->rng));
    drape_batch *b = &r->train;
    CR_TRY(cr_drape_batch_build(b, r->model, r->centre, r->theta, def->samples, def->side,
                                r->scene.square, err));
    if (b->n == 0)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: no sampled structure fits on the UV chart");
    cr_nn_ctx_reset(r->ctx);
    cr_tensor *x = cr_drape_model_forward(r->ctx, r->model, b->uv, b->p0, 6 * b->n);
    cr_tensor *t[4];
    cr_tensor *loss = add_pin(r, cr_drape_batch_loss(r->ctx, &r->lc, b, x, t), (double)b->n);
    cr_nn_params_zero_grad(cr_drape_model_params(r->model));
    CR_TRY(cr_nn_backward(r->ctx, loss, err));
    CR_TRY(clip_gradient(r, err));
    CR_TRY(cr_optim_step(r->opt, err));
    set_train_terms(r, t, (double)b->n);
    return CR_OK;
}

static cr_status mesh_epoch(drape_run *r, cr_error *err) {
    const drape_mesh_losses *ml = &r->ml;
    cr_nn_ctx *ctx = r->ctx;
    cr_nn_ctx_reset(ctx);
    cr_tensor *x = cr_drape_model_vertices(ctx, r->model);
    cr_tensor *e[4], *t[4];
    float w[4];
    cr_drape_loss_terms(ctx, &r->lc, ml->strain, ml->bend, x, 0, e);
    cr_drape_loss_weights(&ml->w, 0, w);
    cr_tensor *loss = cr_loss_weighted_sum(ctx, e, w, 4, t);
    double nv = (double)r->scene.rest->nv;
    loss = add_pin(r, loss, nv);
    cr_nn_params_zero_grad(cr_drape_model_params(r->model));
    CR_TRY(cr_nn_backward(ctx, loss, err));
    CR_TRY(clip_gradient(r, err));
    CR_TRY(cr_optim_step(r->opt, err));
    set_train_terms(r, t, nv);
    return CR_OK;
}

/* --------------------------------------------------------- the log -- */

static cr_status push_row(drape_run *r, const drape_log_row *row, cr_error *err) {
    if (r->nrows == r->caprows) {
        int cap = r->caprows ? 2 * r->caprows : 64;
        drape_log_row *n = realloc(r->rows, (size_t)cap * sizeof *n);
        if (!n) return CR_FAIL(err, CR_ERR_MEMORY, "drape: no memory for the loss log");
        r->rows = n, r->caprows = cap;
    }
    r->rows[r->nrows++] = *row;
    return CR_OK;
}

static void terms_json(cJSON *o, const char *prefix, const cr_drape_terms *t) {
    char k[64];
    const char *names[5] = {"strain", "bend", "gravity", "collision", "total"};
    const double v[5] = {t->strain, t->bend, t->gravity, t->collision, t->total};
    for (int i = 0; i < 5; i++) {
        snprintf(k, sizeof k, "%s%s", prefix, names[i]);
        cJSON_AddNumberToObject(o, k, v[i]);
    }
}

static void write_log_row(FILE *fp, const drape_log_row *row) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "epoch", row->epoch);
    cJSON_AddNumberToObject(o, "seconds", row->seconds);
    terms_json(o, "", &row->eval);
    terms_json(o, "train_", &row->train);
    char *s = cJSON_PrintUnformatted(o);
    if (s) fprintf(fp, "%s\n", s);
    cJSON_free(s);
    cJSON_Delete(o);
}

/* The log is a convenience (the checkpoint carries the history), so a
 * failure to append is not fatal. */
static void append_log(const drape_run *r, const drape_log_row *row, int truncate) {
    if (!r->def->out_dir) return;
    FILE *fp = fopen(r->log_path, truncate ? "w" : "a");
    if (!fp) return;
    if (row) write_log_row(fp, row);
    fclose(fp);
}

static void rewrite_log(const drape_run *r) {
    if (!r->def->out_dir) return;
    FILE *fp = fopen(r->log_path, "w");
    if (!fp) return;
    for (int i = 0; i < r->nrows; i++)
        write_log_row(fp, &r->rows[i]);
    fclose(fp);
}

/* ------------------------------------------------------ checkpoints -- */

static cJSON *terms_array(const cr_drape_terms *t) {
    const double v[4] = {t->strain, t->bend, t->gravity, t->collision};
    return cJSON_CreateDoubleArray(v, 4);
}

static cr_drape_terms terms_from(const cJSON *a) {
    cr_drape_terms t = {0};
    double v[4] = {0};
    for (int i = 0; i < 4; i++) {
        const cJSON *x = cJSON_GetArrayItem(a, i);
        v[i] = cJSON_IsNumber(x) ? x->valuedouble : 0.0;
    }
    t.strain = v[0], t.bend = v[1], t.gravity = v[2], t.collision = v[3];
    t.total = v[0] + v[1] + v[2] + v[3];
    return t;
}

static char *state_json(const drape_run *r, const cr_drape_result *res) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "variant", cr_drape_variant_name(r->def->variant));
    cJSON_AddStringToObject(j, "scene", cr_drape_scene_name(r->def->scene));
    cJSON_AddStringToObject(j, "grid_interp", cr_grid_interp_name(r->def->grid_interp));
    cJSON_AddNumberToObject(j, "seconds", res->seconds);
    cJSON_AddNumberToObject(j, "eval_seconds", res->eval_seconds);
    cJSON_AddNumberToObject(j, "converged_epoch", res->converged_epoch);
    cJSON_AddNumberToObject(j, "converged_seconds", res->converged_seconds);
    cJSON *h = cJSON_AddArrayToObject(j, "history");
    for (int i = 0; i < r->nrows; i++) {
        cJSON *row = cJSON_CreateArray();
        cJSON_AddItemToArray(row, cJSON_CreateNumber(r->rows[i].epoch));
        cJSON_AddItemToArray(row, cJSON_CreateNumber(r->rows[i].seconds));
        cJSON_AddItemToArray(row, terms_array(&r->rows[i].eval));
        cJSON_AddItemToArray(row, terms_array(&r->rows[i].train));
        cJSON_AddItemToArray(h, row);
    }
    cJSON_AddItemToObject(j, "train_terms", terms_array(&r->train_terms));
    cJSON_AddNumberToObject(j, "grad_mean", r->grad_mean);
    if (r->sampler) {
        int g = cr_drape_sampler_grid(r->sampler);
        cJSON_AddItemToObject(j, "pdf",
                              cJSON_CreateFloatArray(cr_drape_sampler_pdf(r->sampler), g * g));
    }
    char *s = cJSON_PrintUnformatted(j);
    cJSON_Delete(j);
    return s;
}

static cr_status save_checkpoint(drape_run *r, const cr_drape_result *res, cr_error *err) {
    cr_checkpoint_meta meta = {.epoch = res->epochs,
                               .step = cr_optim_step_count(r->opt),
                               .seed = r->def->seed,
                               .rng = r->rng,
                               .loss = (float)r->train_terms.total,
                               .config_json = state_json(r, res)};
    if (!meta.config_json) return CR_FAIL(err, CR_ERR_MEMORY, "drape: checkpoint state");
    cr_status st =
        cr_checkpoint_save(r->ckpt_path, cr_drape_model_params(r->model), r->opt, &meta, err);
    cJSON_free(meta.config_json);
    return st;
}

/* The saved PDF back into the sampler: eq. 7 blends towards it until the
 * start's weight gamma^k is below float resolution. */
static cr_status restore_pdf(drape_run *r, const cJSON *pdf, cr_error *err) {
    int g2 = cr_drape_sampler_grid(r->sampler) * cr_drape_sampler_grid(r->sampler);
    if (!cJSON_IsArray(pdf) || cJSON_GetArraySize(pdf) != g2)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: the saved PDF does not have %d cells", r->ckpt_path,
                       g2);
    for (int i = 0; i < g2; i++) {
        const cJSON *v = cJSON_GetArrayItem(pdf, i);
        r->cell_loss[i] = cJSON_IsNumber(v) ? (float)v->valuedouble : 0.0f;
    }
    double gamma = r->def->pdf_gamma;
    int reps = gamma <= 0.0 ? 1 : gamma >= 1.0 ? 0 : (int)ceil(log(1e-12) / log(gamma));
    if (reps > 2000) reps = 2000;
    for (int i = 0; i < reps; i++)
        CR_TRY(cr_drape_sampler_update(r->sampler, r->cell_loss, err));
    return CR_OK;
}

static double num_at(const cJSON *a, int i) {
    const cJSON *x = cJSON_GetArrayItem(a, i);
    return cJSON_IsNumber(x) ? x->valuedouble : 0.0;
}

static cr_status resume(drape_run *r, cr_drape_result *res, cr_error *err) {
    struct stat sb;
    if (stat(r->ckpt_path, &sb) != 0) { /* nothing to resume: a fresh run, said */
        cr_log(CR_LOG_WARN, "drape: --resume: no checkpoint at %s; training from the start",
               r->ckpt_path);
        return CR_OK;
    }
    cr_checkpoint_meta meta = {0};
    CR_TRY(cr_checkpoint_load(r->ckpt_path, cr_drape_model_params(r->model), r->opt, &meta, err));
    cJSON *j = meta.config_json ? cJSON_Parse(meta.config_json) : NULL;
    const cJSON *variant = cJSON_GetObjectItemCaseSensitive(j, "variant");
    const cJSON *scene = cJSON_GetObjectItemCaseSensitive(j, "scene");
    const cJSON *hist = cJSON_GetObjectItemCaseSensitive(j, "history");
    cr_status st = CR_OK;
    if (!cJSON_IsString(variant) || !cJSON_IsString(scene) || !cJSON_IsArray(hist))
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: not a drape checkpoint", r->ckpt_path);
    else if (strcmp(variant->valuestring, cr_drape_variant_name(r->def->variant)) ||
             strcmp(scene->valuestring, cr_drape_scene_name(r->def->scene)))
        st = CR_FAIL(err, CR_ERR_INVALID,
                     "%s: a checkpoint of variant '%s' on scene '%s', not '%s' on '%s'",
                     r->ckpt_path, variant->valuestring, scene->valuestring,
                     cr_drape_variant_name(r->def->variant), cr_drape_scene_name(r->def->scene));
    /* the same grid of floats means another surface under another
     * interpolation; a checkpoint from before the option is bilinear */
    const cJSON *interp = cJSON_GetObjectItemCaseSensitive(j, "grid_interp");
    const char *saved = cJSON_IsString(interp) ? interp->valuestring : "bilinear";
    if (st == CR_OK && r->def->variant != CR_DRAPE_MESH &&
        strcmp(saved, cr_grid_interp_name(r->def->grid_interp)) != 0)
        st = CR_FAIL(
            err, CR_ERR_INVALID,
            "%s: a checkpoint of the %s grid encoding, not %s (--grid-interp %s resumes it)",
            r->ckpt_path, saved, cr_grid_interp_name(r->def->grid_interp), saved);
    if (st == CR_OK) {
        res->epochs = res->resumed_from = (int)meta.epoch;
        r->rng = meta.rng;
        const cJSON *v;
#define NUM(key)                                                                                   \
    ((v = cJSON_GetObjectItemCaseSensitive(j, key)) && cJSON_IsNumber(v) ? v->valuedouble : 0.0)
        res->seconds = NUM("seconds");
        res->eval_seconds = NUM("eval_seconds");
        res->converged_epoch = (int)NUM("converged_epoch");
        res->converged_seconds = NUM("converged_seconds");
        r->grad_mean = NUM("grad_mean");
#undef NUM
        r->train_terms = terms_from(cJSON_GetObjectItemCaseSensitive(j, "train_terms"));
        r->nrows = 0;
        const cJSON *row;
        cJSON_ArrayForEach(row, hist) {
            drape_log_row lr = {.epoch = (int)num_at(row, 0),
                                .seconds = num_at(row, 1),
                                .eval = terms_from(cJSON_GetArrayItem(row, 2)),
                                .train = terms_from(cJSON_GetArrayItem(row, 3))};
            if (st == CR_OK) st = push_row(r, &lr, err);
        }
        if (st == CR_OK && r->nrows > 0) res->terms = r->rows[r->nrows - 1].eval;
        if (st == CR_OK && r->sampler)
            st = restore_pdf(r, cJSON_GetObjectItemCaseSensitive(j, "pdf"), err);
    }
    cJSON_Delete(j);
    free(meta.config_json);
    return st;
}

/* ----------------------------------------------------------- the loop -- */

/* Epochs at lr / 10 after convergence when the run stops there: the settle
 * phase the cap's schedule would have run at its end (a run that stops at
 * convergence never reaches it, and its contacts would be left jittering in
 * the eps band). */
static int settle_after(const cr_drape_def *def) {
    return def->stop_at_converged && def->lr_final < 0.0f ? def->settle_epochs : 0;
}

/* Move the schedule's one drop by ten to step `step` when it lies later:
 * a new optimiser with Adam's moments and step count carried over. */
static cr_status settle_from(drape_run *r, int64_t step, cr_error *err) {
    cr_optim_def od = *cr_optim_get_def(r->opt);
    if (od.lr.kind != CR_LR_STEP || od.lr.step_every <= step || step < 1) return CR_OK;
    od.lr.step_every = step;
    cr_optim *o = NULL;
    CR_TRY(cr_optim_create(&od, cr_drape_model_params(r->model), &o, err));
    int64_t n = 0;
    cr_nn_params_data(cr_drape_model_params(r->model), &n);
    for (int k = 0; k < cr_optim_state_count(o); k++)
        memcpy(cr_optim_state(o, k, NULL), cr_optim_state(r->opt, k, NULL),
               (size_t)n * sizeof(float));
    cr_optim_set_step_count(o, cr_optim_step_count(r->opt));
    cr_optim_destroy(r->opt);
    r->opt = o;
    return CR_OK;
}

/* Record an evaluation at the current epoch and test convergence. */
static cr_status evaluate_and_log(drape_run *r, cr_drape_result *res, cr_error *err) {
    double t0 = cr_time_now();
    drape_log_row row = {.epoch = res->epochs, .seconds = res->seconds, .train = r->train_terms};
    CR_TRY(evaluate(r, &row.eval, err));
    res->eval_seconds += cr_time_now() - t0;
    CR_TRY(push_row(r, &row, err));
    append_log(r, &row, 0);
    if (r->def->on_eval) r->def->on_eval(r->def->on_eval_user, row.epoch, row.seconds, &row.eval);
    res->terms = row.eval;
    /* best energy so far, now and one window back: upward spikes (a contact
     * overshooting into the eps band) then neither trigger nor delay the test */
    double best = INFINITY, best_back = INFINITY;
    int have_back = 0;
    for (int i = 0; i < r->nrows; i++) {
        best = fmin(best, r->rows[i].eval.total);
        if (r->rows[i].epoch <= row.epoch - r->def->converge_window) {
            best_back = fmin(best_back, r->rows[i].eval.total);
            have_back = 1;
        }
    }
    if (have_back && res->converged_epoch < 0) {
        double total = r->rows[0].eval.total - best, window = best_back - best;
        if (total > 0.0 && window < r->def->converge_tol * total) {
            res->converged_epoch = row.epoch;
            res->converged_seconds = row.seconds;
        }
    }
    return CR_OK;
}

static cr_status train(drape_run *r, cr_drape_result *res, cr_error *err) {
    const cr_drape_def *def = r->def;
    if (r->nrows == 0) CR_TRY(evaluate_and_log(r, res, err)); /* the start */
    char label[48];
    snprintf(label, sizeof label, "drape %s", cr_drape_variant_name(def->variant));
    cr_progress bar;
    cr_progress_begin(&bar, label, def->epochs, def->quiet);
    cr_status st = CR_OK;
    /* a resumed run that had converged settles from there */
    if (settle_after(def) > 0 && res->converged_epoch >= 0)
        st = settle_from(r, res->converged_epoch, err);
    while (res->epochs < def->epochs && st == CR_OK) {
        if (def->stop_at_converged && res->converged_epoch >= 0 &&
            res->epochs >= res->converged_epoch + settle_after(def))
            break;
        double t0 = cr_time_now();
        st = r->structures ? structure_epoch(r, res->epochs, err) : mesh_epoch(r, err);
        res->seconds += cr_time_now() - t0;
        if (st != CR_OK) break;
        res->epochs++;
        if (res->epochs % def->eval_every == 0 || res->epochs == def->epochs) {
            int was = res->converged_epoch;
            st = evaluate_and_log(r, res, err);
            if (st == CR_OK && was < 0 && res->converged_epoch >= 0 && settle_after(def) > 0)
                st = settle_from(r, cr_optim_step_count(r->opt), err);
        }
        if (st == CR_OK && def->out_dir && def->checkpoint_every > 0 &&
            res->epochs % def->checkpoint_every == 0)
            st = save_checkpoint(r, res, err);
        const cr_drape_terms *t = &r->train_terms;
        cr_progress_update(&bar, res->epochs, "E %.3e  strain %.2e bend %.2e grav %.3e coll %.2e",
                           t->total, t->strain, t->bend, t->gravity, t->collision);
    }
    cr_progress_end(&bar);
    if (st == CR_OK && r->rows[r->nrows - 1].epoch != res->epochs)
        st = evaluate_and_log(r, res, err); /* stopped between evaluations */
    return st;
}

/* ------------------------------------------------------------- entry -- */

cr_status cr_drape_train_(const cr_drape_def *def, drape_run *r, cr_drape_result *res,
                          cr_error *err) {
    *r = (drape_run){.def = def};
    cr_status st = setup(r, err);
    if (st == CR_OK) res->params = cr_drape_model_param_count(r->model);
    if (st == CR_OK && def->resume) st = resume(r, res, err);
    if (st == CR_OK) {
        if (res->resumed_from > 0)
            rewrite_log(r);
        else
            append_log(r, NULL, 1);
    }
    if (st == CR_OK) st = train(r, res, err);
    if (st == CR_OK && r->nrows > 0) res->initial = r->rows[0].eval;
    return st;
}

cr_status cr_drape_checkpoint_(drape_run *r, const cr_drape_result *res, cr_error *err) {
    return save_checkpoint(r, res, err);
}

void cr_drape_train_free_(drape_run *r) {
    run_free(r);
}
