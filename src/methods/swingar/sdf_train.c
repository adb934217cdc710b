/* sdf_train.c: training SwinGar's body SDF (paper 002, eq. 8-9): posed
 * mannequins from motion clips or files, sample points with exact signed
 * distances and gradients from the BVH, Adam with a cosine schedule,
 * resumable checkpoints (nn_checkpoint.h).
 *
 * Samples per pose: area-weighted points on the surface (s = 0, n = the face
 * normal), the same perturbed by N(0, near_sigma^2) per axis, and uniform
 * points in the poses' bounding box padded by space_pad; off-surface
 * targets are the BVH's signed distance and the exact SDF gradient, the unit
 * vector from the closest point (sign-flipped inside), or the pseudo-normal
 * when the point is on the surface. Batches are drawn uniformly from the
 * whole pool by the run's generator, which the checkpoint stores, so a
 * resumed run draws the same batches.
 *
 * Leaves out: SMPL bodies (the mannequin only), per-epoch resampling (the
 * pool is fixed and made again, identically, on resume).
 */
#include "methods/swingar/sdf.h"

#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/motion.h"
#include "crease/nn_checkpoint.h"
#include "crease/nn_optim.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const uint32_t TRAIN_DEF_COOKIE = 0x53444654u;
enum { MAX_LIST = 32, NAME_CAP = 256 };
static const float ON_SURFACE_M = 1e-5f; /* closer than this: use the pseudo-normal */

cr_swingar_sdf_train_def cr_swingar_sdf_train_default_def(void) {
    return (cr_swingar_sdf_train_def){.model = cr_swingar_sdf_default_def(),
                                      .motions = "walk",
                                      .shapes = "normal",
                                      .body_resolution = 110,
                                      .clip_frames = 90,
                                      .frame_stride = 6,
                                      .samples_surface = 4000,
                                      .samples_near = 4000,
                                      .samples_space = 1000,
                                      .near_sigma = 0.02f,
                                      .space_pad = 0.15f,
                                      .steps = 2000,
                                      .batch = 2048,
                                      .lr = 1e-3f,
                                      .lr_final = 1e-5f,
                                      .mu_e = 0.15f,
                                      .seed = 1,
                                      .checkpoint_every = 200,
                                      .cookie = TRAIN_DEF_COOKIE};
}

/* The train def's whole-number and rate fields: the options of `crease swingar-sdf train`
 * with their ranges and help (CLI_KEYS). */
#define TK(...) CR_CONFIG_KEY(cr_swingar_sdf_train_def, __VA_ARGS__)
static const cr_config_key train_keys[] = {
    TK(model.width, CR_CFG_INT, 2, 4096, "--width", "W", "layer width"),
    TK(model.articulated, CR_CFG_INT, 0, 2, "--articulated", "N",
       "0: the paper's position input; joint-frame inputs (not the paper's): 1 all 22 frames, "
       "2 weighted by bone nearness (docs/swingar_sdf.md)"),
    TK(model.tau, CR_CFG_FLOAT, 1e-4, 10, "--tau", "T",
       "bone-weight temperature of --articulated 2"),
    TK(batch, CR_CFG_INT, 1, 1 << 20, "--batch", "B", "points per step"),
    TK(lr, CR_CFG_FLOAT, 1e-9, 10, "--lr", "R", "peak learning rate"),
    TK(clip_frames, CR_CFG_INT, 1, 100000, "--frames", "N", "frames per procedural clip"),
    TK(frame_stride, CR_CFG_INT, 1, 100000, "--stride", "K", "train on every K-th frame"),
    TK(samples_surface, CR_CFG_INT, 0, 10000000, "--surface", "N",
       "samples per pose on the surface"),
    TK(samples_near, CR_CFG_INT, 0, 10000000, "--near", "N", "samples per pose near it"),
    TK(samples_space, CR_CFG_INT, 0, 10000000, "--space", "N",
       "samples per pose in the box around the body"),
    TK(body_resolution, CR_CFG_INT, 32, 512, "--resolution", "N", "mannequin resolution"),
    TK(resume, CR_CFG_BOOL, 0, 1, "--resume", NULL, "continue from -o FILE when it exists"),
    TK(quiet, CR_CFG_BOOL, 0, 1, "--quiet", NULL, "no progress"),
};
#undef TK

const cr_config_key *cr_swingar_sdf_train_def_keys(int *n) {
    *n = (int)(sizeof train_keys / sizeof train_keys[0]);
    return train_keys;
}

/* The training points: pos (M,3) body frame, m; row (M) pose index; s (M);
 * n (M,3); cond (P,C). */
typedef struct sdf_pool {
    int64_t m, cap, p;
    float *pos, *s, *n, *cond;
    int32_t *row;
    float lo[3], hi[3];
} sdf_pool;

static void pool_free(sdf_pool *pl) {
    free(pl->pos), free(pl->s), free(pl->n), free(pl->cond), free(pl->row);
}

/* Split "a,b,c" into at most MAX_LIST names of NAME_CAP bytes. */
static cr_status split_list(const char *s, const char *what, char names[][NAME_CAP], int *count,
                            cr_error *err) {
    *count = 0;
    if (!s || !*s) return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf-train: empty %s list", what);
    const char *p = s;
    while (*p) {
        const char *e = strchr(p, ',');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len == 0 || len >= NAME_CAP || *count == MAX_LIST)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "swingar sdf-train: bad %s list '%s' (empty name, name over %d bytes "
                           "or more than %d names)",
                           what, s, NAME_CAP - 1, MAX_LIST);
        memcpy(names[*count], p, len);
        names[(*count)++][len] = 0;
        p = e ? e + 1 : p + len;
    }
    return CR_OK;
}

cr_status cr_swingar_sdf_motions_load(const char *list, int32_t clip_frames, cr_motion ***out,
                                      int *count, cr_error *err) {
    char names[MAX_LIST][NAME_CAP];
    *out = NULL;
    *count = 0;
    int n;
    CR_TRY(split_list(list, "motion", names, &n, err));
    cr_motion **m = calloc((size_t)n, sizeof *m);
    if (!m) return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: motions");
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < n; i++) {
        cr_motion_resolve_def rd = cr_motion_resolve_default_def();
        rd.clip_frames = clip_frames;
        st = cr_motion_resolve(names[i], &rd, &m[i], NULL, err);
    }
    if (st != CR_OK) {
        cr_swingar_sdf_motions_free(m, n);
        return st;
    }
    *out = m;
    *count = n;
    return CR_OK;
}

void cr_swingar_sdf_motions_free(cr_motion **m, int count) {
    for (int i = 0; m && i < count; i++)
        cr_motion_destroy(m[i]);
    free(m);
}

static cr_status pool_reserve(sdf_pool *pl, int64_t need, int64_t poses, cr_error *err) {
    if (pl->m + need > pl->cap) {
        int64_t cap = (pl->m + need) * 2;
        float *pos = realloc(pl->pos, (size_t)cap * 3 * sizeof(float));
        if (pos) pl->pos = pos;
        float *s = realloc(pl->s, (size_t)cap * sizeof(float));
        if (s) pl->s = s;
        float *n = realloc(pl->n, (size_t)cap * 3 * sizeof(float));
        if (n) pl->n = n;
        int32_t *row = realloc(pl->row, (size_t)cap * sizeof(int32_t));
        if (row) pl->row = row;
        if (!pos || !s || !n || !row) return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: samples");
        pl->cap = cap;
    }
    float *c = realloc(pl->cond, (size_t)poses * CR_SWINGAR_SDF_COND_MAX * sizeof(float));
    if (!c) return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: conditioning");
    pl->cond = c;
    return CR_OK;
}

/* Samples of one posed body (positions v (V,3) with the translation removed). */
static cr_status sample_pose(const cr_swingar_sdf_train_def *d, const cr_mesh *rest, const float *v,
                             const float *cond, const float lo[3], const float hi[3], cr_rng *rng,
                             sdf_pool *pl, cr_error *err) {
    int64_t ns = d->samples_surface, nn = d->samples_near, nu = d->samples_space;
    int64_t total = ns + nn + nu;
    CR_TRY(pool_reserve(pl, total, pl->p + 1, err));
    memcpy(&pl->cond[pl->p * CR_SWINGAR_SDF_COND_MAX], cond,
           CR_SWINGAR_SDF_COND_MAX * sizeof(float));
    cr_mesh posed = *rest;
    posed.pos = (float *)v;
    posed.normal = NULL;
    posed.nattr = 0;
    float *fn = malloc((size_t)rest->nf * 3 * sizeof(float));
    float *area = malloc((size_t)rest->nf * sizeof(float));
    double *cdf = malloc((size_t)rest->nf * sizeof(double));
    float *dist = malloc((size_t)(nn + nu) * sizeof(float));
    float *nrm = malloc((size_t)(nn + nu) * 3 * sizeof(float));
    float *cp = malloc((size_t)(nn + nu) * 3 * sizeof(float));
    cr_bvh *bvh = NULL;
    cr_status st = fn && area && cdf && dist && nrm && cp
                       ? CR_OK
                       : CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: samples");
    if (st == CR_OK) st = cr_bvh_build(v, rest->nv, rest->tri, rest->nf, &bvh, err);
    if (st == CR_OK) {
        cr_mesh_face_normals(&posed, fn, area);
        double acc = 0;
        for (int32_t f = 0; f < rest->nf; f++)
            cdf[f] = acc += area[f];
        float *P = &pl->pos[3 * pl->m], *S = &pl->s[pl->m], *N = &pl->n[3 * pl->m];
        for (int64_t i = 0; i < ns + nn; i++) {
            /* area-weighted face, uniform barycentric point */
            double u = cr_rng_uniform(rng) * acc;
            int32_t a = 0, b = rest->nf - 1;
            while (a < b) {
                int32_t mid = (a + b) / 2;
                if (cdf[mid] < u)
                    a = mid + 1;
                else
                    b = mid;
            }
            float r1 = sqrtf(cr_rng_uniformf(rng)), r2 = cr_rng_uniformf(rng);
            float w0 = 1 - r1, w1 = r1 * (1 - r2), w2 = r1 * r2;
            const int32_t *t = &rest->tri[3 * (int64_t)a];
            for (int k = 0; k < 3; k++) {
                P[3 * i + k] = w0 * v[3 * t[0] + k] + w1 * v[3 * t[1] + k] + w2 * v[3 * t[2] + k];
                N[3 * i + k] = fn[3 * (int64_t)a + k];
            }
            S[i] = 0;
            if (i >= ns)
                for (int k = 0; k < 3; k++)
                    P[3 * i + k] += d->near_sigma * (float)cr_rng_normal(rng);
        }
        for (int64_t i = ns + nn; i < total; i++)
            for (int k = 0; k < 3; k++)
                P[3 * i + k] = lo[k] + (hi[k] - lo[k]) * cr_rng_uniformf(rng);
        cr_bvh_signed_distance_batch(bvh, &P[3 * ns], nn + nu, INFINITY, dist, nrm, cp);
        for (int64_t j = 0; j < nn + nu; j++) {
            int64_t i = ns + j;
            S[i] = dist[j];
            float dx[3], len = 0;
            for (int k = 0; k < 3; k++)
                dx[k] = P[3 * i + k] - cp[3 * j + k], len += dx[k] * dx[k];
            len = sqrtf(len);
            float sg = dist[j] < 0 ? -1.0f : 1.0f;
            for (int k = 0; k < 3; k++)
                N[3 * i + k] = len > ON_SURFACE_M ? sg * dx[k] / len : nrm[3 * j + k];
        }
        for (int64_t i = 0; i < total; i++)
            pl->row[pl->m + i] = (int32_t)pl->p;
        pl->m += total;
        pl->p++;
    }
    cr_bvh_destroy(bvh);
    free(fn), free(area), free(cdf), free(dist), free(nrm), free(cp);
    return st;
}

/* Every training pose of every shape and motion: skinned, translation
 * removed, then the bounds, then the samples (which need the bounds). */
typedef struct pose_set {
    int64_t count;
    float **verts; /* (count) each (V,3) */
    float *cond;   /* (count, C) */
    cr_body_model **bodies;
    int nbodies;
    int32_t *body_of; /* (count) */
    cr_motion **motions;
    int nmotions;
} pose_set;

static void poses_free(pose_set *ps) {
    for (int64_t i = 0; i < ps->count; i++)
        free(ps->verts[i]);
    for (int i = 0; i < ps->nbodies; i++)
        cr_body_model_destroy(ps->bodies[i]);
    cr_swingar_sdf_motions_free(ps->motions, ps->nmotions);
    free(ps->verts), free(ps->cond), free(ps->bodies), free(ps->body_of);
}

static cr_status build_poses(const cr_swingar_sdf_train_def *d, pose_set *ps, cr_error *err) {
    char shapes[MAX_LIST][NAME_CAP];
    int nshape, nmotion;
    CR_TRY(split_list(d->shapes, "shape", shapes, &nshape, err));
    CR_TRY(cr_swingar_sdf_motions_load(d->motions, d->clip_frames, &ps->motions, &nmotion, err));
    ps->nmotions = nmotion;
    ps->bodies = calloc((size_t)nshape, sizeof *ps->bodies);
    if (!ps->bodies) return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: bodies");
    int64_t cap = 0;
    for (int b = 0; b < nshape; b++) {
        cr_mannequin_def md = cr_mannequin_default_def();
        CR_TRY(cr_mannequin_preset(shapes[b], &md, err));
        md.resolution = d->body_resolution;
        CR_TRY(cr_mannequin_create(&md, &ps->bodies[b], err));
        ps->nbodies = b + 1;
        const cr_body_model *body = ps->bodies[b];
        int64_t nv = body->rest->nv;
        for (int mi = 0; mi < nmotion; mi++) {
            const cr_motion *mo = ps->motions[mi];
            float *seq = NULL;
            cr_status st = cr_body_pose_motion(body, mo, &seq, err);
            for (int32_t f = 0; st == CR_OK && f < mo->nframes; f += d->frame_stride) {
                if (ps->count == cap) {
                    cap = cap ? 2 * cap : 64;
                    float **v = realloc(ps->verts, (size_t)cap * sizeof *v);
                    float *c = realloc(ps->cond, (size_t)cap * CR_SWINGAR_SDF_COND_MAX * 4);
                    int32_t *bo = realloc(ps->body_of, (size_t)cap * sizeof *bo);
                    if (v) ps->verts = v;
                    if (c) ps->cond = c;
                    if (bo) ps->body_of = bo;
                    if (!v || !c || !bo) st = CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: poses");
                    if (st != CR_OK) break;
                }
                float *pv = malloc((size_t)nv * 3 * sizeof(float));
                if (!pv) {
                    st = CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf: poses");
                    break;
                }
                const float *tr = &mo->trans[3 * (int64_t)f];
                for (int64_t i = 0; i < nv; i++)
                    for (int k = 0; k < 3; k++)
                        pv[3 * i + k] = seq[(int64_t)f * nv * 3 + 3 * i + k] - tr[k];
                ps->verts[ps->count] = pv;
                ps->body_of[ps->count] = b;
                cr_swingar_sdf_condition(&md, body->joints, &mo->poses[(int64_t)f * 3 * CR_NJOINTS],
                                         &ps->cond[ps->count * CR_SWINGAR_SDF_COND_MAX]);
                ps->count++;
            }
            free(seq);
            CR_TRY(st);
        }
    }
    return CR_OK;
}

static cr_status build_pool(const cr_swingar_sdf_train_def *d, sdf_pool *pl, cr_error *err) {
    pose_set ps = {0};
    cr_status st = build_poses(d, &ps, err);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t p = 0; st == CR_OK && p < ps.count; p++) {
        int64_t nv = ps.bodies[ps.body_of[p]]->rest->nv;
        for (int64_t i = 0; i < nv; i++)
            for (int k = 0; k < 3; k++) {
                float x = ps.verts[p][3 * i + k];
                lo[k] = x < lo[k] ? x : lo[k];
                hi[k] = x > hi[k] ? x : hi[k];
            }
    }
    for (int k = 0; k < 3; k++)
        lo[k] -= d->space_pad, hi[k] += d->space_pad;
    cr_rng rng = cr_rng_make(d->seed, 0x5a3f);
    for (int64_t p = 0; st == CR_OK && p < ps.count; p++)
        st = sample_pose(d, ps.bodies[ps.body_of[p]]->rest, ps.verts[p],
                         &ps.cond[p * CR_SWINGAR_SDF_COND_MAX], lo, hi, &rng, pl, err);
    memcpy(pl->lo, lo, sizeof lo);
    memcpy(pl->hi, hi, sizeof hi);
    poses_free(&ps);
    return st;
}

/* ------------------------------------------------------------ training -- */

static cr_status check_train_def(const cr_swingar_sdf_train_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == TRAIN_DEF_COOKIE);
    if (d->model.cond_dim != CR_SWINGAR_SDF_COND_DIM)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf-train: model.cond_dim must be %d",
                       CR_SWINGAR_SDF_COND_DIM);
    if (d->clip_frames < 1 || d->frame_stride < 1 || d->samples_surface < 0 ||
        d->samples_near < 0 || d->samples_space < 0 ||
        d->samples_surface + d->samples_near + d->samples_space < 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-train: need clip_frames, frame_stride >= 1 and some samples");
    if (!(d->near_sigma >= 0) || !(d->space_pad >= 0) || d->steps < 1 || d->batch < 1 ||
        !(d->lr > 0) || !(d->lr_final >= 0 && d->lr_final <= d->lr) || !(d->mu_e >= 0) ||
        d->checkpoint_every < 0 || d->stop_at < 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-train: need near_sigma, space_pad >= 0, steps, batch >= 1, "
                       "0 <= lr_final <= lr, mu_e >= 0, checkpoint_every, stop_at >= 0");
    if (d->resume && !d->checkpoint)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf-train: resuming needs a checkpoint path");
    return CR_OK;
}

static cr_status save(const cr_swingar_sdf_train_def *d, cr_swingar_sdf *net, cr_optim *opt,
                      int64_t step, cr_rng rng, float loss, cr_error *err) {
    cr_checkpoint_meta meta = {.step = step,
                               .seed = d->seed,
                               .rng = rng,
                               .loss = loss,
                               .config_json = cr_swingar_sdf_def_json(cr_swingar_sdf_get_def(net))};
    cr_status st = cr_checkpoint_save(d->checkpoint, cr_swingar_sdf_params(net), opt, &meta, err);
    free(meta.config_json);
    return st;
}

typedef struct train_run {
    const cr_swingar_sdf_train_def *def;
    sdf_pool pool;
    cr_swingar_sdf *net;
    cr_optim *opt;
    cr_nn_ctx *ctx;
    cr_rng rng;
    float *bx, *bs, *bn; /* (B,3), (B), (B,3) */
    int32_t *brow;       /* (B) */
} train_run;

static cr_status step_once(train_run *r, cr_swingar_sdf_train_result *res, cr_error *err) {
    const cr_swingar_sdf_train_def *d = r->def;
    const sdf_pool *pl = &r->pool;
    int64_t b = d->batch;
    for (int64_t i = 0; i < b; i++) {
        int64_t k = (int64_t)cr_rng_below(&r->rng, (uint32_t)pl->m);
        memcpy(&r->bx[3 * i], &pl->pos[3 * k], 3 * sizeof(float));
        memcpy(&r->bn[3 * i], &pl->n[3 * k], 3 * sizeof(float));
        r->bs[i] = pl->s[k];
        r->brow[i] = pl->row[k];
    }
    cr_nn_ctx *ctx = r->ctx;
    cr_nn_ctx_reset(ctx);
    cr_tensor *x = cr_nn_wrap(ctx, 2, (int64_t[]){b, 3}, r->bx);
    cr_tensor *s = cr_nn_wrap(ctx, 2, (int64_t[]){b, 1}, r->bs);
    cr_tensor *n = cr_nn_wrap(ctx, 2, (int64_t[]){b, 3}, r->bn);
    cr_tensor *c = cr_nn_wrap(ctx, 2, (int64_t[]){pl->p, CR_SWINGAR_SDF_COND_MAX}, pl->cond);
    cr_tensor *parts[3] = {0};
    cr_tensor *loss = cr_swingar_sdf_loss(ctx, r->net, x, c, r->brow, s, n, d->mu_e, parts);
    cr_nn_params_zero_grad(cr_swingar_sdf_params(r->net));
    CR_TRY(cr_nn_backward(ctx, loss, err));
    CR_TRY(cr_optim_step(r->opt, err));
    res->loss = loss->data[0];
    res->value = parts[0]->data[0];
    res->normal = parts[1]->data[0];
    res->eikonal = parts[2]->data[0];
    return CR_OK;
}

static cr_status setup(train_run *r, cr_swingar_sdf_train_result *res, cr_error *err) {
    const cr_swingar_sdf_train_def *d = r->def;
    CR_TRY(build_pool(d, &r->pool, err));
    res->poses = r->pool.p;
    res->samples = r->pool.m;
    cr_swingar_sdf_def md = d->model;
    float ext = 0;
    for (int k = 0; k < 3; k++) {
        md.center[k] = 0.5f * (r->pool.lo[k] + r->pool.hi[k]);
        float e = 0.5f * (r->pool.hi[k] - r->pool.lo[k]);
        ext = e > ext ? e : ext;
    }
    md.scale = ext;
    CR_TRY(cr_swingar_sdf_create(&md, &r->net, err));
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.kind = CR_LR_COSINE;
    od.lr.base = d->lr;
    od.lr.final = d->lr_final;
    od.lr.total_steps = d->steps;
    CR_TRY(cr_optim_create(&od, cr_swingar_sdf_params(r->net), &r->opt, err));
    /* the tape of one step: values, tangents and their grads, ~150 (B,W) blocks */
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)d->batch * (size_t)md.width * sizeof(float) * 160 + ((size_t)64 << 20);
    CR_TRY(cr_nn_ctx_create(&cd, &r->ctx, err));
    r->rng = cr_rng_make(d->seed, 0xba7c);
    r->bx = malloc((size_t)d->batch * 3 * sizeof(float));
    r->bn = malloc((size_t)d->batch * 3 * sizeof(float));
    r->bs = malloc((size_t)d->batch * sizeof(float));
    r->brow = malloc((size_t)d->batch * sizeof(int32_t));
    if (!r->bx || !r->bn || !r->bs || !r->brow)
        return CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf-train: batch buffers");
    if (r->pool.m > UINT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "swingar sdf-train: %lld samples, at most 2^32",
                       (long long)r->pool.m);
    return CR_OK;
}

static cr_status resume(train_run *r, cr_swingar_sdf_train_result *res, cr_error *err) {
    struct stat sb;
    if (!r->def->resume || stat(r->def->checkpoint, &sb) != 0) return CR_OK;
    cr_checkpoint_meta meta = {0};
    CR_TRY(
        cr_checkpoint_load(r->def->checkpoint, cr_swingar_sdf_params(r->net), r->opt, &meta, err));
    cr_swingar_sdf_def saved;
    cr_status st = cr_swingar_sdf_def_from_json(meta.config_json, r->def->checkpoint, &saved, err);
    free(meta.config_json);
    CR_TRY(st);
    const cr_swingar_sdf_def *now = cr_swingar_sdf_get_def(r->net);
    if (saved.width != now->width || saved.articulated != now->articulated ||
        saved.scale != now->scale || memcmp(saved.center, now->center, sizeof saved.center) != 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: checkpoint of another model or data (width %d, scale %g; now %d, %g)",
                       r->def->checkpoint, saved.width, (double)saved.scale, now->width,
                       (double)now->scale);
    r->rng = meta.rng;
    res->steps = res->resumed_from = meta.step;
    res->loss = meta.loss;
    return CR_OK;
}

cr_status cr_swingar_sdf_train(const cr_swingar_sdf_train_def *def, cr_swingar_sdf **out,
                               cr_swingar_sdf_train_result *res, cr_error *err) {
    *out = NULL;
    CR_TRY(check_train_def(def, err));
    memset(res, 0, sizeof *res);
    train_run r = {.def = def};
    cr_status st = setup(&r, res, err);
    if (st == CR_OK) st = resume(&r, res, err);
    cr_progress bar;
    cr_progress_begin(&bar, "swingar sdf", def->steps, def->quiet);
    bar.done = res->steps;
    double t0 = cr_time_now();
    int64_t last = def->stop_at > 0 && def->stop_at < def->steps ? def->stop_at : def->steps;
    while (st == CR_OK && res->steps < last) {
        st = step_once(&r, res, err);
        if (st != CR_OK) break;
        res->steps++;
        if (def->checkpoint && def->checkpoint_every > 0 && res->steps % def->checkpoint_every == 0)
            st = save(def, r.net, r.opt, res->steps, r.rng, res->loss, err);
        cr_progress_update(&bar, res->steps, "loss %.4f value %.2f mm normal %.4f eik %.4f",
                           (double)res->loss, 1e3 * res->value, (double)res->normal,
                           (double)res->eikonal);
    }
    cr_progress_end(&bar);
    res->seconds = cr_time_now() - t0;
    if (st == CR_OK && def->checkpoint)
        st = save(def, r.net, r.opt, res->steps, r.rng, res->loss, err);
    cr_optim_destroy(r.opt);
    cr_nn_ctx_destroy(r.ctx);
    pool_free(&r.pool);
    free(r.bx), free(r.bn), free(r.bs), free(r.brow);
    if (st != CR_OK) {
        cr_swingar_sdf_destroy(r.net);
        return st;
    }
    *out = r.net;
    return CR_OK;
}
