/* train.c: epnet's curriculum (paper 004, Algorithm 1), checkpoints, the
 * model folder, and `crease epnet run`'s outputs.
 *
 * Cycle k: (phase 0) E-Net epochs with the current RB per training clip
 * (zero in the first cycle); (phase 1) E-Net's angles on every clip give the
 * target RB by Eq. 4-5 (cr_epnet_plastic_rollout), on which P-Net is fitted
 * (MSE, teacher forcing), and the targets become the next cycle's RB. The
 * baseline (def.baseline) runs phase 0 only, with RB 0.
 * Checkpoints after every epoch: enet.safetensors and pnet.safetensors
 * (weights, Adam state, the position in the curriculum and the RNG) and
 * rb_train.npy (the RB per clip), with model.json (the def) at the first one:
 * a set that must agree, so it is committed as one (save_set). */
#define _POSIX_C_SOURCE 200809L /* open_memstream */
#include "epnet_internal.h"

#include "crease/nn_checkpoint.h"
#include "crease/npz.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------- checkpoints -- */

static int64_t pos_code(int cycle, int phase, int epoch) {
    return ((int64_t)cycle * 2 + phase) * 1000000 + epoch;
}

/* The files of one checkpoint. Each is written to NAME.next; then commit.json
 * is written (atomically) and each NAME.next renamed over NAME, then
 * commit.json removed. A kill before commit.json leaves the previous set
 * whole (its .next files are dropped at the next load); a kill after it is
 * finished at the next load (finish_commit). Each file alone is atomic, so
 * this only orders them. */
static const char *const set_files[] = {"model.json", "enet.safetensors", "pnet.safetensors",
                                        "rb_train.npy"};
enum { NSET = sizeof set_files / sizeof set_files[0] };

static int file_exists(const char *path) {
    FILE *f = fopen(path, "rb");
    if (f) fclose(f);
    return f != NULL;
}

static cr_status finish_commit(const char *dir, cr_error *err) {
    char marker[1024], from[1100], to[1100];
    snprintf(marker, sizeof marker, "%s/commit.json", dir);
    const int committed = file_exists(marker);
    for (int k = 0; k < NSET; k++) {
        snprintf(from, sizeof from, "%s/%s.next", dir, set_files[k]);
        snprintf(to, sizeof to, "%s/%s", dir, set_files[k]);
        if (!file_exists(from)) continue;
        if (!committed)
            remove(from);
        else if (rename(from, to) != 0)
            return CR_FAIL(err, CR_ERR_IO, "%s: cannot rename %s over %s", dir, from, to);
    }
    if (committed && remove(marker) != 0)
        return CR_FAIL(err, CR_ERR_IO, "%s: cannot remove %s", dir, marker);
    return CR_OK;
}

static cr_status save_rb(const char *path, float *const *rb, int n, int64_t T, int64_t H,
                         cr_error *err) {
    float *all = malloc(sizeof(float) * (size_t)(n * T * H + 1));
    if (!all) return CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory saving RB");
    for (int i = 0; i < n; i++)
        memcpy(all + i * T * H, rb[i], sizeof(float) * (size_t)(T * H));
    cr_status st = cr_npy_write(path, CR_NPY_F32, 3, (int64_t[]){n, T, H}, all, err);
    free(all);
    return st;
}

/* One checkpoint set: the two networks at (cycle, phase, epoch), and when rb
 * is given the RB per clip (n clips of T x H). A model.json.next written
 * before (the first save of a training) goes in with them. */
static cr_status save_set(cr_epnet *m, const char *dir, int cycle, int phase, int epoch,
                          float *const *rb, int n, int64_t T, int64_t H, cr_error *err) {
    char path[1100];
    cr_checkpoint_meta meta = {
        .epoch = pos_code(cycle, phase, epoch), .seed = m->def.seed, .rng = m->rng};
    snprintf(path, sizeof path, "%s/enet.safetensors.next", dir);
    CR_TRY(cr_checkpoint_save(path, m->pe, m->opt_e, &meta, err));
    snprintf(path, sizeof path, "%s/pnet.safetensors.next", dir);
    CR_TRY(cr_checkpoint_save(path, m->pp, m->opt_p, &meta, err));
    if (rb) {
        snprintf(path, sizeof path, "%s/rb_train.npy.next", dir);
        CR_TRY(save_rb(path, rb, n, T, H, err));
    }
    snprintf(path, sizeof path, "%s/commit.json", dir);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    fprintf(f.fp, "{\"position\": %lld}\n", (long long)meta.epoch);
    CR_TRY(cr_atomic_commit(&f, err));
    return finish_commit(dir, err);
}

cr_status cr_epnet_save(cr_epnet *m, const char *dir, int cycle, int phase, int epoch,
                        cr_error *err) {
    return save_set(m, dir, cycle, phase, epoch, NULL, 0, 0, 0, err);
}

/* One network's file of a committed set, dir/<net>.safetensors, into p and o
 * (meta without its config string). */
static cr_status load_net(const char *dir, const char *net, cr_nn_params *p, cr_optim *o,
                          cr_checkpoint_meta *meta, cr_error *err) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s.safetensors", dir, net);
    cr_status st = cr_checkpoint_load(path, p, o, meta, err);
    free(meta->config_json);
    meta->config_json = NULL;
    return st;
}

cr_status cr_epnet_load(cr_epnet *m, const char *dir, int *cycle, int *phase, int *epoch,
                        cr_error *err) {
    cr_checkpoint_meta me = {0}, mp = {0};
    CR_TRY(finish_commit(dir, err));
    CR_TRY(load_net(dir, "enet", m->pe, m->opt_e, &me, err));
    CR_TRY(load_net(dir, "pnet", m->pp, m->opt_p, &mp, err));
    if (mp.epoch != me.epoch)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: the E-Net and P-Net checkpoints disagree", dir);
    m->rng = mp.rng;
    const int64_t code = me.epoch;
    if (epoch) *epoch = (int)(code % 1000000);
    if (phase) *phase = (int)((code / 1000000) % 2);
    if (cycle) *cycle = (int)(code / 2000000);
    return CR_OK;
}

/* RB per training clip, (n, T, H) as one .npy. */
static cr_status load_rb(const char *dir, float **rb, int n, int64_t T, int64_t H, cr_error *err) {
    char path[1024];
    snprintf(path, sizeof path, "%s/rb_train.npy", dir);
    cr_npy a;
    CR_TRY(cr_npy_read(path, CR_NPY_AS_F32, &a, err));
    if (a.ndim != 3 || a.shape[0] != n || a.shape[1] != T || a.shape[2] != H) {
        cr_npy_free(&a);
        return CR_FAIL(err, CR_ERR_PARSE, "%s: expected shape (%d,%lld,%lld)", path, n,
                       (long long)T, (long long)H);
    }
    for (int i = 0; i < n; i++)
        memcpy(rb[i], a.f32 + i * T * H, sizeof(float) * (size_t)(T * H));
    cr_npy_free(&a);
    return CR_OK;
}

/* ------------------------------------------------------ model folder -- */

static void print_config(const cr_epnet_def *d, FILE *fp) {
    fprintf(
        fp,
        "{\"garment\": \"%s\", \"garment_vertices\": %d, \"body\": \"%s\", \"frames\": %d, "
        "\"fps\": %.9g, \"yield\": %.9g, \"sharpness\": %.9g, \"baseline\": %d, \"seed\": %llu,\n"
        " \"inertia_detach\": %d, \"pin_top\": %.9g, \"w_pin\": %.9g, \"w_bending\": %.9g,"
        " \"w_zero_rest\": %.9g, \"w_rest_response\": %.9g,\n \"pnet_rb_noise\": %.9g,"
        " \"pnet_inactive_weight\": %.9g, \"pnet_patience\": %d, \"pnet_val\": \"%s\",\n"
        " \"static\": [",
        d->garment, d->garment_vertices, d->body, d->frames, d->fps, d->material.yield_angle,
        d->sharpness, d->baseline, (unsigned long long)d->seed, d->experimental.inertia_detach,
        d->pin_top, d->w_pin, d->w_bending, d->w_zero_rest, d->w_rest_response, d->pnet_rb_noise,
        d->pnet_inactive_weight, d->pnet_patience, d->pnet_val_motion ? d->pnet_val_motion : "");
    for (int i = 0; i < d->nstatic; i++)
        fprintf(fp, "%s%d", i ? ", " : "", d->static_widths[i]);
    fprintf(fp, "], \"rb\": [");
    for (int i = 0; i < d->nrb; i++)
        fprintf(fp, "%s%d", i ? ", " : "", d->rb_widths[i]);
    fprintf(fp,
            "], \"dynamic\": %d, \"gru\": %d, \"decoder_width\": %d, \"decoder_layers\": %d,\n"
            " \"pnet_latent\": %d, \"pnet_hidden_layers\": %d, \"pnet_steps\": %d, \"motions\": [",
            d->dynamic_width, d->gru_hidden, d->decoder_width, d->decoder_layers, d->pnet_latent,
            d->pnet_hidden_layers, d->pnet_steps);
    for (int i = 0; i < d->nmotions; i++)
        fprintf(fp, "%s\"%s\"", i ? ", " : "", d->motions[i]);
    fprintf(fp, "]}\n");
}

/* model.json.next, committed with the first checkpoint (save_set). */
static cr_status write_config(const cr_epnet_def *d, const char *dir, cr_error *err) {
    char path[1100];
    snprintf(path, sizeof path, "%s/model.json.next", dir);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    print_config(d, f.fp);
    return cr_atomic_commit(&f, err);
}

/* A resume must train the model it finds: the def's model.json against the
 * folder's, key by key. */
static cr_status check_config(const cr_epnet_def *d, const char *dir, cr_error *err) {
    char path[1024], *txt = NULL, *mine = NULL;
    size_t len = 0, n = 0;
    snprintf(path, sizeof path, "%s/model.json", dir);
    CR_TRY(cr_file_read_all(path, &txt, &len, err));
    FILE *fp = open_memstream(&mine, &n);
    if (fp) print_config(d, fp), fclose(fp);
    cJSON *a = cJSON_Parse(txt), *b = mine ? cJSON_Parse(mine) : NULL;
    free(txt), free(mine);
    cr_status st = CR_OK;
    if (!a)
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: not JSON", path);
    else if (!b)
        st = CR_FAIL(err, CR_ERR_MEMORY, "epnet train: cannot print the options' model.json");
    for (const cJSON *e = b ? b->child : NULL; st == CR_OK && e; e = e->next) {
        const cJSON *f = cJSON_GetObjectItemCaseSensitive(a, e->string);
        if (f && cJSON_Compare(e, f, 1)) continue;
        char *want = cJSON_PrintUnformatted(e), *have = f ? cJSON_PrintUnformatted(f) : NULL;
        st = CR_FAIL(err, CR_ERR_INVALID,
                     "%s: the model has %s %s but the options give %s: resume with the model's "
                     "options, or train into another folder",
                     path, e->string, have ? have : "(none)", want ? want : "?");
        free(want), free(have);
    }
    cJSON_Delete(a), cJSON_Delete(b);
    return st;
}

static int jint(const cJSON *o, const char *k, int dflt) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(v) ? (int)v->valuedouble : dflt;
}
static double jnum(const cJSON *o, const char *k, double dflt) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(v) ? v->valuedouble : dflt;
}

/* garment NULL: the model's own, every weight loaded; else that garment at
 * `vertices` (0: the model's count) with P-Net's weights alone. */
static cr_status open_model(const char *dir, const char *garment_as, int32_t vertices,
                            cr_epnet **out, cr_error *err) {
    *out = NULL;
    char path[1024], *txt = NULL;
    size_t len = 0;
    snprintf(path, sizeof path, "%s/model.json", dir);
    CR_TRY(cr_file_read_all(path, &txt, &len, err));
    cJSON *o = cJSON_Parse(txt);
    free(txt);
    if (!o) return CR_FAIL(err, CR_ERR_PARSE, "%s: not JSON", path);
    /* A misspelt key would quietly take its default and change the model:
     * every key must be one print_config writes, and the sizes must be there
     * (keys added later default to off when missing). The RB options pruned
     * on 2026-12-07 (docs/notes/epnet_rounds.md) load ignored where they were
     * off; a model trained with one on is refused, naming it. */
    static const struct {
        const char *key;
        int required;
    } keys[] = {{"garment", 1},
                {"garment_vertices", 1},
                {"body", 0},
                {"frames", 0},
                {"fps", 0},
                {"yield", 1},
                {"sharpness", 0},
                {"baseline", 0},
                {"seed", 0},
                {"inertia_detach", 0},
                {"pin_top", 0},
                {"w_pin", 0},
                {"w_bending", 0},
                {"w_zero_rest", 0},
                {"w_rest_response", 0},
                {"pnet_rb_noise", 0},
                {"pnet_inactive_weight", 0},
                {"pnet_patience", 0},
                {"pnet_val", 0},
                {"static", 1},
                {"rb", 1},
                {"dynamic", 1},
                {"gru", 1},
                {"decoder_width", 1},
                {"decoder_layers", 1},
                {"pnet_latent", 1},
                {"pnet_hidden_layers", 1},
                {"pnet_steps", 1},
                {"motions", 0}};
    enum { NKEYS = sizeof keys / sizeof keys[0] };
    static const char *const pruned[] = {"w_rb_response", "rb_augment", "rb_fold",
                                         "rb_from_rollout"};
    const char *bad = NULL, *why = NULL;
    for (const cJSON *e = o->child; e && !bad; e = e->next) {
        int k = 0, p = 0;
        while (k < NKEYS && strcmp(keys[k].key, e->string))
            k++;
        while (p < 4 && strcmp(pruned[p], e->string))
            p++;
        if (p < 4 && cJSON_IsNumber(e) && e->valuedouble != 0)
            bad = e->string, why = "the model was trained with an option since removed (on "
                                   "2026-12-07, docs/notes/epnet_rounds.md): retrain without";
        else if (k == NKEYS && p == 4)
            bad = e->string, why = "unknown key";
    }
    for (int k = 0; k < NKEYS && !bad; k++)
        if (keys[k].required && !cJSON_GetObjectItemCaseSensitive(o, keys[k].key))
            bad = keys[k].key, why = "no key";
    if (bad) {
        cr_status st = CR_FAIL(err, CR_ERR_PARSE, "%s: %s '%s'", path, why, bad);
        cJSON_Delete(o);
        return st;
    }
    cr_epnet_def d = cr_epnet_default_def();
    char garment[1024] = "tshirt", body[1024] = "normal";
    const cJSON *g = cJSON_GetObjectItemCaseSensitive(o, "garment");
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(o, "body");
    if (cJSON_IsString(g)) snprintf(garment, sizeof garment, "%s", g->valuestring);
    if (cJSON_IsString(b)) snprintf(body, sizeof body, "%s", b->valuestring);
    d.garment = garment, d.body = body;
    d.garment_vertices = jint(o, "garment_vertices", d.garment_vertices);
    d.frames = jint(o, "frames", d.frames);
    d.fps = (float)jnum(o, "fps", d.fps);
    d.material.yield_angle = jnum(o, "yield", d.material.yield_angle);
    d.sharpness = jnum(o, "sharpness", d.sharpness);
    d.experimental.inertia_detach = jint(o, "inertia_detach", d.experimental.inertia_detach);
    d.pin_top = jnum(o, "pin_top", d.pin_top);
    d.w_pin = jnum(o, "w_pin", d.w_pin);
    d.w_bending = jnum(o, "w_bending", d.w_bending);
    /* added 2026-12: a folder without them was trained without the paired terms */
    d.w_zero_rest = jnum(o, "w_zero_rest", 0.0);
    d.w_rest_response = jnum(o, "w_rest_response", 0.0);
    d.baseline = jint(o, "baseline", 0);
    d.seed = (uint64_t)jnum(o, "seed", 1);
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(o, "static");
    d.nstatic = 0;
    for (const cJSON *e = a ? a->child : NULL; e && d.nstatic < CR_EPNET_MAX_LAYERS; e = e->next)
        d.static_widths[d.nstatic++] = (int)e->valuedouble;
    a = cJSON_GetObjectItemCaseSensitive(o, "rb");
    d.nrb = 0;
    for (const cJSON *e = a ? a->child : NULL; e && d.nrb < CR_EPNET_MAX_LAYERS; e = e->next)
        d.rb_widths[d.nrb++] = (int)e->valuedouble;
    d.dynamic_width = jint(o, "dynamic", d.dynamic_width);
    d.gru_hidden = jint(o, "gru", d.gru_hidden);
    d.decoder_width = jint(o, "decoder_width", d.decoder_width);
    d.decoder_layers = jint(o, "decoder_layers", d.decoder_layers);
    d.pnet_latent = jint(o, "pnet_latent", d.pnet_latent);
    d.pnet_hidden_layers = jint(o, "pnet_hidden_layers", d.pnet_hidden_layers);
    d.pnet_steps = jint(o, "pnet_steps", d.pnet_steps);
    cJSON_Delete(o);
    if (garment_as) {
        if (d.baseline)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "%s: a zero-RB baseline has no trained P-Net to run on %s", dir,
                           garment_as);
        snprintf(garment, sizeof garment, "%s", garment_as);
        if (vertices > 0) d.garment_vertices = vertices;
    }
    cr_epnet *m = NULL;
    CR_TRY(cr_epnet_create(&d, &m, err));
    cr_status st;
    if (garment_as) { /* P-Net's weights alone */
        cr_checkpoint_meta mp = {0};
        st = finish_commit(dir, err);
        if (st == CR_OK) st = load_net(dir, "pnet", m->pp, m->opt_p, &mp, err);
    } else {
        st = cr_epnet_load(m, dir, NULL, NULL, NULL, err);
    }
    if (st != CR_OK) {
        cr_epnet_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_epnet_open(const char *dir, cr_epnet **out, cr_error *err) {
    return open_model(dir, NULL, 0, out, err);
}

cr_status cr_epnet_open_pnet(const char *dir, const char *garment, int32_t vertices, cr_epnet **out,
                             cr_error *err) {
    if (!garment || !*garment) return CR_FAIL(err, CR_ERR_INVALID, "epnet: no garment named");
    return open_model(dir, garment, vertices, out, err);
}

/* ------------------------------------------------------------ training -- */

static void log_line(FILE *fp, int quiet, const char *line) {
    if (fp) fprintf(fp, "%s\n", line), fflush(fp);
    if (!quiet) cr_log(CR_LOG_INFO, "epnet: %s", line);
}

static void log_enet(FILE *fp, int quiet, int cycle, int epoch, const cr_epnet_losses *l) {
    char line[640];
    int n = snprintf(line, sizeof line,
                     "{\"cycle\": %d, \"phase\": \"enet\", \"epoch\": %d, \"loss\": %.6g", cycle,
                     epoch, l->total);
    for (int k = 0; k < CR_EPNET_NTERMS; k++)
        n += snprintf(line + n, sizeof line - (size_t)n, ", \"%s\": %.6g", cr_epnet_term_names[k],
                      l->term[k]);
    snprintf(line + n, sizeof line - (size_t)n, "}");
    log_line(fp, quiet, line);
}

/* val NaN: no validation clip (written as null) */
static void log_pnet(FILE *fp, int quiet, int cycle, int epoch, double loss, double val) {
    char line[256], v[32];
    if (isnan(val))
        snprintf(v, sizeof v, "null");
    else
        snprintf(v, sizeof v, "%.6g", val);
    snprintf(line, sizeof line,
             "{\"cycle\": %d, \"phase\": \"pnet\", \"epoch\": %d, \"l1_rad\": %.6g, "
             "\"val_l1_rad\": %s}",
             cycle, epoch, loss, v);
    log_line(fp, quiet, line);
}

/* E-Net's positions (T,V,3) and angles (T,H) on s given RB rb (NULL: the proxy);
 * either output may be NULL. */
static cr_status enet_angles(cr_epnet *m, const cr_epnet_seq *s, const float *rb, float *pos,
                             float *theta, cr_error *err) {
    cr_nn_ctx_reset(m->ctx);
    cr_nn_ctx_set_grad_enabled(m->ctx, 0);
    cr_tensor *x = cr_epnet_enet_forward_(m, s, rb);
    CR_TRY(cr_nn_ctx_error(m->ctx, err));
    if (pos) memcpy(pos, x->data, sizeof(float) * (size_t)s->T * m->nv * 3);
    if (theta) cr_epnet_angles_(m, x->data, s->T, theta);
    return CR_OK;
}

/* The validation loss: P-Net over the clip's proxy (vpos, vth) through the
 * default ratchet against its target, weighted as the fit's L1 (rad per
 * hinge and frame); R (T,H) scratch. */
static cr_status val_loss(cr_epnet *m, const float *vpos, const float *vth, const float *vtarget,
                          int32_t T, float *R, double *out, cr_error *err) {
    const cr_epnet_ratchet_def rd = cr_epnet_ratchet_default_def();
    CR_TRY(cr_epnet_pnet_proxy_(m, vpos, vth, T, &rd, R, err));
    double sum = 0;
    for (int64_t i = 0; i < (int64_t)T * m->nh; i++) {
        const double w = fabsf(vtarget[i]) > 1e-4f ? 1.0 : m->def.pnet_inactive_weight;
        sum += w * fabs((double)R[i] - vtarget[i]);
    }
    *out = sum / ((double)T * m->nh);
    return CR_OK;
}

cr_status cr_epnet_train(const cr_epnet_def *def, cr_epnet_train_report *out, cr_error *err) {
    cr_epnet_train_report rep;
    memset(&rep, 0, sizeof rep);
    if (!def->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "epnet train: no output folder");
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    cr_epnet *m = NULL;
    CR_TRY(cr_epnet_create(def, &m, err));
    const int n = def->nmotions;
    const int64_t T = def->frames, H = m->nh, V = m->nv;
    cr_epnet_seq *seq[CR_EPNET_MAX_MOTIONS] = {0};
    float *rb[CR_EPNET_MAX_MOTIONS] = {0}, *theta = NULL, *ppos = NULL, *pth = NULL;
    float *target = NULL, *vpos = NULL, *vth = NULL, *vR = NULL, *vtarget = NULL, *pbest = NULL;
    cr_epnet_seq *vseq = NULL;
    double t0 = cr_time_now();
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < n; i++) {
        st = cr_epnet_seq_create(m, def->motions[i], NULL, def->frames, 0, &seq[i], err);
        if (st == CR_OK && seq[i]->T != T)
            st = CR_FAIL(err, CR_ERR_INVALID, "epnet train: motion %s has %d frames, not %lld",
                         def->motions[i], seq[i]->T, (long long)T);
        if (st == CR_OK && !(rb[i] = calloc((size_t)(T * H), sizeof(float))))
            st = CR_FAIL(err, CR_ERR_MEMORY, "epnet train: out of memory");
    }
    if (st == CR_OK && def->pnet_val_motion && !def->baseline) {
        st = cr_epnet_seq_create(m, def->pnet_val_motion, NULL, def->frames, 0, &vseq, err);
        if (st == CR_OK && vseq->T != T)
            st = CR_FAIL(err, CR_ERR_INVALID,
                         "epnet train: validation motion %s has %d frames, not %lld",
                         def->pnet_val_motion, vseq->T, (long long)T);
    }
    int64_t npp = 0;
    cr_nn_params_data(m->pp, &npp);
    theta = malloc(sizeof(float) * (size_t)(T * H));
    ppos = malloc(sizeof(float) * (size_t)(n * T * V * 3));
    pth = malloc(sizeof(float) * (size_t)(n * T * H));
    target = malloc(sizeof(float) * (size_t)(n * T * H));
    vpos = malloc(sizeof(float) * (size_t)(T * V * 3));
    vth = malloc(sizeof(float) * (size_t)(T * H));
    vR = malloc(sizeof(float) * (size_t)(T * H));
    vtarget = malloc(sizeof(float) * (size_t)(T * H));
    pbest = malloc(sizeof(float) * (size_t)(npp + 1));
    if (st == CR_OK &&
        (!theta || !ppos || !pth || !target || !vpos || !vth || !vR || !vtarget || !pbest))
        st = CR_FAIL(err, CR_ERR_MEMORY, "epnet train: out of memory");
    int c0 = 0, p0 = 0, e0 = 0;
    if (st == CR_OK && def->resume) {
        st = check_config(def, def->out_dir, err);
        if (st == CR_OK) st = cr_epnet_load(m, def->out_dir, &c0, &p0, &e0, err);
        if (st == CR_OK) st = load_rb(def->out_dir, rb, n, T, H, err);
    } else if (st == CR_OK) {
        /* nothing in the folder changes until the first checkpoint commits */
        st = write_config(def, def->out_dir, err);
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/progress.jsonl", def->out_dir);
    FILE *log = st == CR_OK ? fopen(path, def->resume ? "a" : "w") : NULL;
    int first = 1;
    for (int c = c0; st == CR_OK && c < def->cycles; c++) {
        const int pstart = c == c0 ? p0 : 0;
        for (int e = (pstart == 0 && c == c0) ? e0 : (pstart == 0 ? 0 : def->enet_epochs);
             st == CR_OK && e < def->enet_epochs; e++) {
            cr_epnet_losses sum = {0}, l;
            for (int i = 0; st == CR_OK && i < n; i++) {
                st = cr_epnet_enet_step(m, seq[i], def->baseline ? NULL : rb[i], 1, &l, err);
                sum.total += l.total / n;
                for (int k = 0; k < CR_EPNET_NTERMS; k++)
                    sum.term[k] += l.term[k] / n;
            }
            if (st != CR_OK) break;
            if (first) rep.first = sum, rep.first_loss = sum.total, first = 0;
            rep.last = sum, rep.last_loss = sum.total;
            log_enet(log, def->quiet, c, e, &sum);
            st = save_set(m, def->out_dir, c, 0, e + 1, rb, n, T, H, err);
        }
        if (st != CR_OK || def->baseline) {
            if (st == CR_OK) rep.cycles_done = c + 1;
            continue;
        }
        /* phase 1: targets from E-Net's angles given RB (Eq. 4-5); P-Net's inputs the
         * proxy's (E-Net at RB = 0) */
        for (int i = 0; st == CR_OK && i < n; i++) {
            st = enet_angles(m, seq[i], NULL, ppos + i * T * V * 3, pth + i * T * H, err);
            if (st == CR_OK) st = enet_angles(m, seq[i], rb[i], NULL, theta, err);
            if (st != CR_OK) break;
            cr_epnet_plastic_rollout(theta, m->theta_bar, NULL, (int32_t)T, (int32_t)H,
                                     def->material.yield_angle, def->material.plastic_gain,
                                     def->sharpness, target + i * T * H);
        }
        /* the validation clip's target: Eq. 4-5 on E-Net given the RB the current
         * P-Net gives over its proxy (what inference would run) */
        if (st == CR_OK && vseq) {
            cr_epnet_ratchet_def rd = cr_epnet_ratchet_default_def();
            st = enet_angles(m, vseq, NULL, vpos, vth, err);
            if (st == CR_OK) st = cr_epnet_pnet_proxy_(m, vpos, vth, (int32_t)T, &rd, vR, err);
            if (st == CR_OK) st = enet_angles(m, vseq, vR, NULL, theta, err);
            if (st == CR_OK)
                cr_epnet_plastic_rollout(theta, m->theta_bar, NULL, (int32_t)T, (int32_t)H,
                                         def->material.yield_angle, def->material.plastic_gain,
                                         def->sharpness, vtarget);
        }
        double best = INFINITY;
        int worse = 0, have_best = 0;
        const int estart = (c == c0 && pstart == 1) ? e0 : 0;
        for (int e = estart; st == CR_OK && e < def->pnet_epochs; e++) {
            double loss = 0, l = 0, val = NAN;
            for (int i = 0; st == CR_OK && i < n; i++) {
                st = cr_epnet_pnet_fit(m, seq[i], ppos + i * T * V * 3, pth + i * T * H,
                                       target + i * T * H, 1, &l, err);
                loss += l / n;
            }
            if (st == CR_OK && vseq)
                st = val_loss(m, vpos, vth, vtarget, (int32_t)T, vR, &val, err);
            if (st != CR_OK) break;
            rep.pnet_loss = loss, rep.pnet_val_loss = val;
            log_pnet(log, def->quiet, c, e, loss, val);
            if (vseq && val < best) {
                best = val, worse = 0, have_best = 1;
                memcpy(pbest, cr_nn_params_data(m->pp, NULL), sizeof(float) * (size_t)npp);
            } else if (vseq) {
                worse++;
            }
            st = cr_epnet_save(m, def->out_dir, c, 1, e + 1, err);
            if (vseq && worse >= def->pnet_patience) break; /* early stopping */
        }
        /* the phase ends with the best validation weights */
        if (st == CR_OK && have_best)
            memcpy(cr_nn_params_data(m->pp, NULL), pbest, sizeof(float) * (size_t)npp);
        if (st != CR_OK) break;
        for (int i = 0; st == CR_OK && i < n; i++) {
            memcpy(rb[i], target + i * T * H, sizeof(float) * (size_t)(T * H));
        }
        if (st != CR_OK) break;
        st = save_set(m, def->out_dir, c + 1, 0, 0, rb, n, T, H, err);
        if (st == CR_OK) rep.cycles_done = c + 1;
    }
    if (log) fclose(log);
    rep.seconds = cr_time_now() - t0;
    rep.arena_peak_bytes = cr_nn_ctx_arena_peak(m->ctx);
    for (int i = 0; i < n; i++)
        cr_epnet_seq_destroy(seq[i]), free(rb[i]);
    free(theta), free(ppos), free(pth), free(target);
    free(vpos), free(vth), free(vR), free(vtarget), free(pbest);
    cr_epnet_seq_destroy(vseq);
    cr_epnet_destroy(m);
    if (out) *out = rep;
    return st;
}
