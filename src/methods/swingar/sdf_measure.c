/* sdf_measure.c: how the neural body SDF compares with the exact BVH
 * distance (paper 002, sec. III-D and Table II) on frames held out from
 * training:
 *   - the SDF error |S - s| at points near the body (surface + N(0,
 *     (band/2)^2) per axis, kept when |s| < band) and at the garment's
 *     vertices within the band, and the sign agreement;
 *   - eq. 10 on a garment skinned to the pose garment_lag frames earlier
 *     (a trailing garment, the stand-in for a prediction), with the neural
 *     field and with the exact one: the share of vertices inside the body (by the exact
 *     distance) before and after, and the time per frame of each removal (the
 *     exact one also needs the posed body's BVH refit, timed on its own).
 * Times are medians over the frames, on the threads the caller allows.
 *
 * With garment_pc2 set, the garment is a recorded sequence instead (an
 * estimator's prediction), on the recorded body, both in world space; the
 * neural field's conditioning comes from the motion's poses and its
 * translation is subtracted.
 */
#include "methods/swingar/sdf.h"

#include "crease/bvh.h"
#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t MEASURE_DEF_COOKIE = 0x4d534446u;
/* A vertex counts as inside when its exact S is below -10 um: one moved
 * exactly onto the surface may read -1e-7 m from float32 rounding. */
static const float INSIDE_TOL_M = 1e-5f;

cr_swingar_sdf_measure_def cr_swingar_sdf_measure_default_def(void) {
    return (cr_swingar_sdf_measure_def){.motions = "walk",
                                        .shape = "normal",
                                        .body_resolution = 110,
                                        .clip_frames = 90,
                                        .first_frame = 3,
                                        .frame_stride = 6,
                                        .max_frames = 15,
                                        .garment = CR_GARMENT_TSHIRT,
                                        .garment_vertices = 10000,
                                        .garment_lag = 4,
                                        .band_m = 0.02f,
                                        .band_samples = 4000,
                                        .collide = cr_swingar_collide_default_def(),
                                        .seed = 1,
                                        .cookie = MEASURE_DEF_COOKIE};
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *t, int64_t n) {
    if (n < 1) return 0;
    qsort(t, (size_t)n, sizeof *t, cmp_double);
    return t[n / 2];
}

typedef struct measure_bufs {
    float *body;          /* (V,3) posed body */
    float *gpos, *gwork;  /* (G,3) posed garment, a copy to move */
    float *gs, *gs_net;   /* (G) exact and neural S */
    float *bx, *bs, *bsn; /* (K,3), (K), (K) band points, exact and neural S */
    double *t[5];         /* (frames) per-frame times */
    double *errs;         /* band errors (all frames) */
} measure_bufs;

static int64_t count_inside(const cr_bvh *bvh, const float *x, int64_t n, float *s) {
    cr_bvh_signed_distance_batch(bvh, x, n, INFINITY, s, NULL, NULL);
    int64_t c = 0;
    for (int64_t i = 0; i < n; i++)
        c += s[i] < -INSIDE_TOL_M;
    return c;
}

/* One frame with the body in b->body (V,3) and the garment in b->gpos
 * (G,3): the BVH refit, the errors, then both removals on fresh copies.
 * The neural field gets the conditioning cond and the root translation
 * trans (NULL: zero), subtracted from world positions. */
static cr_status measure_posed(const cr_swingar_sdf_measure_def *d, cr_swingar_sdf *net,
                               const float *cond, const float *trans, int64_t nv, int64_t ng,
                               const cr_topology *topo, cr_bvh *bvh, cr_rng *rng, measure_bufs *b,
                               int64_t fi, cr_swingar_sdf_measure_result *res, double *inside_sums,
                               cr_error *err) {
    double t0 = cr_time_now();
    CR_TRY(cr_bvh_refit(bvh, b->body, err));
    b->t[4][fi] = cr_time_now() - t0;
    cr_swingar_collide_stats st;
    cr_swingar_sdf_neural_source nu;
    cr_swingar_sdf_source src;
    cr_swingar_sdf_source_neural(net, cond, trans, &nu, &src);

    /* band points around the posed body's vertices (area-uniform enough at
     * the mannequin's near-isotropic resolution) */
    int64_t k = 0;
    for (int32_t i = 0; i < d->band_samples; i++) {
        int64_t v = (int64_t)cr_rng_below(rng, (uint32_t)nv);
        for (int c = 0; c < 3; c++)
            b->bx[3 * k + c] = b->body[3 * v + c] + 0.5f * d->band_m * (float)cr_rng_normal(rng);
        k++;
    }
    cr_bvh_signed_distance_batch(bvh, b->bx, k, INFINITY, b->bs, NULL, NULL);
    CR_TRY(src.eval(src.user, b->bx, k, b->bsn, NULL, err));
    for (int64_t i = 0; i < k; i++) {
        if (!(fabsf(b->bs[i]) < d->band_m)) continue;
        double e = fabs((double)b->bsn[i] - b->bs[i]);
        b->errs[res->band_points++] = e;
        res->sign_agree += (b->bsn[i] < 0) == (b->bs[i] < 0);
    }
    /* garment vertices: exact and neural S, detection quality */
    int64_t before = count_inside(bvh, b->gpos, ng, b->gs);
    CR_TRY(src.eval(src.user, b->gpos, ng, b->gs_net, NULL, err));
    for (int64_t i = 0; i < ng; i++) {
        int in = b->gs[i] < -INSIDE_TOL_M, flagged = b->gs_net[i] < 0;
        if (in && !flagged) res->missed += 1;
        if (!in && flagged) res->false_alarms += 1;
        if (fabsf(b->gs[i]) < d->band_m) {
            double e = fabs((double)b->gs_net[i] - b->gs[i]);
            res->garment_err_mean_mm += e;
            res->garment_err_max_mm = e > res->garment_err_max_mm ? e : res->garment_err_max_mm;
            inside_sums[2] += 1;
        }
    }
    inside_sums[0] += (double)before;

    memcpy(b->gwork, b->gpos, (size_t)ng * 3 * sizeof(float));
    t0 = cr_time_now();
    CR_TRY(cr_swingar_collision_remove(&d->collide, b->gwork, topo, &src, &st, err));
    b->t[0][fi] = cr_time_now() - t0;
    b->t[1][fi] = st.seconds_detect;
    res->mean_move_neural_mm += st.mean_move_m * (double)st.colliding;
    inside_sums[1] += (double)st.colliding;
    res->ratio_neural += (double)count_inside(bvh, b->gwork, ng, b->gs_net);

    cr_swingar_sdf_bvh_source bu;
    cr_swingar_sdf_source_bvh(bvh, INFINITY, &bu, &src);
    memcpy(b->gwork, b->gpos, (size_t)ng * 3 * sizeof(float));
    t0 = cr_time_now();
    CR_TRY(cr_swingar_collision_remove(&d->collide, b->gwork, topo, &src, &st, err));
    b->t[2][fi] = cr_time_now() - t0;
    b->t[3][fi] = st.seconds_detect;
    res->mean_move_exact_mm += st.mean_move_m * (double)st.colliding;
    res->moved_exact += (double)st.colliding;
    res->ratio_exact += (double)count_inside(bvh, b->gwork, ng, b->gs_net);
    return CR_OK;
}

/* One held-out frame of a procedural pose: body and lagging garment skinned. */
static cr_status measure_frame(const cr_swingar_sdf_measure_def *d, cr_swingar_sdf *net,
                               const cr_body_model *body, const cr_mannequin_def *md,
                               const cr_garment *g, const cr_topology *topo, const cr_motion *mo,
                               int32_t f, cr_bvh *bvh, cr_rng *rng, measure_bufs *b, int64_t fi,
                               cr_swingar_sdf_measure_result *res, double *inside_sums,
                               cr_error *err) {
    const float *pose = &mo->poses[(int64_t)f * 3 * CR_NJOINTS];
    CR_TRY(cr_body_pose(body, pose, NULL, b->body, err));
    int32_t fg = f > d->garment_lag ? f - d->garment_lag : 0;
    const float *gpose = &mo->poses[(int64_t)fg * 3 * CR_NJOINTS];
    /* the lag is in the joint rotations only: the garment keeps up with the
     * root translation (removed from both) */
    CR_TRY(cr_garment_pose(g, body, gpose, NULL, b->gpos, err));
    float cond[CR_SWINGAR_SDF_COND_MAX];
    cr_swingar_sdf_condition(md, body->joints, pose, cond);
    return measure_posed(d, net, cond, NULL, body->rest->nv, g->mesh->nv, topo, bvh, rng, b, fi,
                         res, inside_sums, err);
}

/* A recorded sequence (a prediction): body and garment meshes and their
 * per-frame positions, world space, with the motion that posed the body. */
typedef struct measure_seq {
    cr_mesh *body_mesh, *garment_mesh;
    cr_pc2 body, garment;
    int32_t nframes;
} measure_seq;

/* One frame of a recorded sequence; the conditioning from the motion's pose. */
static cr_status measure_seq_frame(const cr_swingar_sdf_measure_def *d, cr_swingar_sdf *net,
                                   const cr_body_model *body, const cr_mannequin_def *md,
                                   const measure_seq *sq, const cr_topology *topo,
                                   const cr_motion *mo, int32_t f, cr_bvh *bvh, cr_rng *rng,
                                   measure_bufs *b, int64_t fi, cr_swingar_sdf_measure_result *res,
                                   double *inside_sums, cr_error *err) {
    int64_t nv = sq->body.nv, ng = sq->garment.nv;
    memcpy(b->body, &sq->body.frames[(int64_t)f * nv * 3], (size_t)nv * 3 * sizeof(float));
    memcpy(b->gpos, &sq->garment.frames[(int64_t)f * ng * 3], (size_t)ng * 3 * sizeof(float));
    float cond[CR_SWINGAR_SDF_COND_MAX];
    cr_swingar_sdf_condition(md, body->joints, &mo->poses[(int64_t)f * 3 * CR_NJOINTS], cond);
    return measure_posed(d, net, cond, &mo->trans[3 * (int64_t)f], nv, ng, topo, bvh, rng, b, fi,
                         res, inside_sums, err);
}

/* Skinned garment on each motion (sq NULL) or the recorded sequence sq on
 * motions[0]. body gives the joints (and, without sq, the meshes). */
static cr_status measure_all(const cr_swingar_sdf_measure_def *d, cr_swingar_sdf *net,
                             const cr_body_model *body, const cr_mannequin_def *md,
                             const cr_garment *g, const measure_seq *sq, cr_motion **motions,
                             int nmotion, cr_swingar_sdf_measure_result *res, cr_error *err) {
    const cr_mesh *bm = sq ? sq->body_mesh : body->rest, *gm = sq ? sq->garment_mesh : g->mesh;
    int64_t nv = bm->nv, ng = gm->nv;
    int64_t frames = 0;
    for (int i = 0; i < nmotion; i++) {
        int32_t nf = sq ? sq->nframes : motions[i]->nframes;
        for (int32_t f = d->first_frame, c = 0; f < nf && c < d->max_frames;
             f += d->frame_stride, c++)
            frames++;
    }
    if (frames < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar sdf-measure: no frame from %d on in '%s'",
                       d->first_frame, d->motions);
    measure_bufs b = {0};
    b.body = malloc((size_t)nv * 3 * sizeof(float));
    b.gpos = malloc((size_t)ng * 3 * sizeof(float));
    b.gwork = malloc((size_t)ng * 3 * sizeof(float));
    b.gs = malloc((size_t)ng * sizeof(float));
    b.gs_net = malloc((size_t)ng * sizeof(float));
    b.bx = malloc((size_t)d->band_samples * 3 * sizeof(float) + 1);
    b.bs = malloc((size_t)d->band_samples * sizeof(float) + 1);
    b.bsn = malloc((size_t)d->band_samples * sizeof(float) + 1);
    b.errs = malloc((size_t)(frames * d->band_samples + 1) * sizeof(double));
    int ok = b.body && b.gpos && b.gwork && b.gs && b.gs_net && b.bx && b.bs && b.bsn && b.errs;
    for (int i = 0; i < 5; i++)
        ok = ok && (b.t[i] = malloc((size_t)frames * sizeof(double)));
    cr_bvh *bvh = NULL;
    cr_topology *topo = NULL;
    cr_status st = ok ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "swingar sdf-measure: buffers");
    if (st == CR_OK) st = cr_bvh_build(bm->pos, (int32_t)nv, bm->tri, bm->nf, &bvh, err);
    if (st == CR_OK) st = cr_topology_build(gm, &topo, err);
    cr_rng rng = cr_rng_make(d->seed, 0x3ea5);
    double sums[3] = {0};
    int64_t fi = 0;
    for (int i = 0; st == CR_OK && i < nmotion; i++) {
        int32_t nf = sq ? sq->nframes : motions[i]->nframes;
        for (int32_t f = d->first_frame, c = 0; st == CR_OK && f < nf && c < d->max_frames;
             f += d->frame_stride, c++)
            st = sq ? measure_seq_frame(d, net, body, md, sq, topo, motions[i], f, bvh, &rng, &b,
                                        fi++, res, sums, err)
                    : measure_frame(d, net, body, md, g, topo, motions[i], f, bvh, &rng, &b, fi++,
                                    res, sums, err);
    }
    if (st == CR_OK) {
        double total = (double)frames * (double)ng;
        res->frames = frames;
        res->body_vertices = nv;
        res->garment_vertices = ng;
        double sum = 0, mx = 0;
        for (int64_t i = 0; i < res->band_points; i++)
            sum += b.errs[i], mx = b.errs[i] > mx ? b.errs[i] : mx;
        res->err_mean_mm = res->band_points ? 1e3 * sum / (double)res->band_points : 0;
        res->err_max_mm = 1e3 * mx;
        qsort(b.errs, (size_t)res->band_points, sizeof(double), cmp_double);
        res->err_p99_mm =
            res->band_points ? 1e3 * b.errs[(int64_t)(0.99 * (double)(res->band_points - 1))] : 0;
        res->sign_agree = res->band_points ? res->sign_agree / (double)res->band_points : 0;
        res->garment_err_mean_mm = sums[2] > 0 ? 1e3 * res->garment_err_mean_mm / sums[2] : 0;
        res->garment_err_max_mm *= 1e3;
        res->missed = sums[0] > 0 ? res->missed / sums[0] : 0;
        res->false_alarms /= (double)frames;
        res->mean_move_neural_mm = sums[1] > 0 ? 1e3 * res->mean_move_neural_mm / sums[1] : 0;
        res->mean_move_exact_mm =
            res->moved_exact > 0 ? 1e3 * res->mean_move_exact_mm / res->moved_exact : 0;
        res->moved_neural = 100 * sums[1] / total;
        res->moved_exact = 100 * res->moved_exact / total;
        res->ratio_before = 100 * sums[0] / total;
        res->ratio_neural = 100 * res->ratio_neural / total;
        res->ratio_exact = 100 * res->ratio_exact / total;
        res->ms_neural = 1e3 * median(b.t[0], frames);
        res->ms_neural_detect = 1e3 * median(b.t[1], frames);
        res->ms_exact = 1e3 * median(b.t[2], frames);
        res->ms_exact_detect = 1e3 * median(b.t[3], frames);
        res->ms_bvh_refit = 1e3 * median(b.t[4], frames);
    }
    cr_bvh_destroy(bvh);
    cr_topology_destroy(topo);
    free(b.body), free(b.gpos), free(b.gwork), free(b.gs), free(b.gs_net);
    free(b.bx), free(b.bs), free(b.bsn), free(b.errs);
    for (int i = 0; i < 5; i++)
        free(b.t[i]);
    return st;
}

/* The recorded sequence's four files, checked against each other and the
 * motion (one motion, at least as many frames). */
static cr_status load_seq(const cr_swingar_sdf_measure_def *d, cr_motion **motions, int nmotion,
                          measure_seq *sq, cr_error *err) {
    if (!d->garment_mesh || !d->body_pc2 || !d->body_mesh)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-measure: a garment pc2 needs the garment mesh, the body pc2 "
                       "and the body mesh as well");
    if (nmotion != 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-measure: a recorded sequence takes one motion (its poses), "
                       "got %d in '%s'",
                       nmotion, d->motions);
    CR_TRY(cr_obj_read(d->garment_mesh, &sq->garment_mesh, err));
    CR_TRY(cr_obj_read(d->body_mesh, &sq->body_mesh, err));
    CR_TRY(cr_pc2_read(d->garment_pc2, &sq->garment, err));
    CR_TRY(cr_pc2_read(d->body_pc2, &sq->body, err));
    if (sq->garment.nv != sq->garment_mesh->nv)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d points per frame, %s has %d vertices",
                       d->garment_pc2, sq->garment.nv, d->garment_mesh, sq->garment_mesh->nv);
    if (sq->body.nv != sq->body_mesh->nv)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d points per frame, %s has %d vertices",
                       d->body_pc2, sq->body.nv, d->body_mesh, sq->body_mesh->nv);
    if (sq->garment.nframes != sq->body.nframes || sq->body.nframes > motions[0]->nframes)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-measure: %s has %d frames, %s %d, motion '%s' %d (need the "
                       "two pc2 equal and the motion at least as long)",
                       d->garment_pc2, sq->garment.nframes, d->body_pc2, sq->body.nframes,
                       d->motions, motions[0]->nframes);
    sq->nframes = sq->body.nframes;
    return CR_OK;
}

cr_status cr_swingar_sdf_measure(const cr_swingar_sdf_measure_def *d, cr_swingar_sdf *net,
                                 cr_swingar_sdf_measure_result *res, cr_error *err) {
    CR_ASSERT(d->cookie == MEASURE_DEF_COOKIE);
    memset(res, 0, sizeof *res);
    if (cr_swingar_sdf_get_def(net)->cond_dim != CR_SWINGAR_SDF_COND_DIM)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-measure: the model has no body conditioning (cond_dim %d)",
                       cr_swingar_sdf_get_def(net)->cond_dim);
    if (d->first_frame < 0 || d->garment_lag < 0 || d->frame_stride < 1 || d->max_frames < 1 ||
        d->band_samples < 0 || !(d->band_m > 0))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar sdf-measure: need first_frame, garment_lag >= 0, frame_stride, "
                       "max_frames >= 1, "
                       "band_samples >= 0, band_m > 0");
    cr_mannequin_def md = cr_mannequin_default_def();
    CR_TRY(cr_mannequin_preset(d->shape, &md, err));
    md.resolution = d->body_resolution;
    cr_body_model *body = NULL;
    cr_garment *g = NULL;
    cr_motion **motions = NULL;
    int nmotion = 0;
    measure_seq sq = {0};
    int seq = d->garment_pc2 != NULL;
    cr_status st = cr_mannequin_create(&md, &body, err);
    cr_garment_def gd = cr_garment_default_def((cr_garment_type)d->garment);
    gd.target_vertices = d->garment_vertices;
    if (st == CR_OK && !seq) st = cr_garment_create(&gd, body, &g, err);
    if (st == CR_OK)
        st = cr_swingar_sdf_motions_load(d->motions, d->clip_frames, &motions, &nmotion, err);
    if (st == CR_OK && seq) st = load_seq(d, motions, nmotion, &sq, err);
    if (st == CR_OK)
        st = measure_all(d, net, body, &md, g, seq ? &sq : NULL, motions, nmotion, res, err);
    cr_mesh_destroy(sq.body_mesh), cr_mesh_destroy(sq.garment_mesh);
    cr_pc2_free(&sq.body), cr_pc2_free(&sq.garment);
    cr_swingar_sdf_motions_free(motions, nmotion);
    cr_garment_destroy(g);
    cr_body_model_destroy(body);
    return st;
}
