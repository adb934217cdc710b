/* sdf_collide.c: SwinGar's collision removal (paper 002, eq. 10) with any
 * signed distance field: the neural body SDF of one pose, or the exact BVH
 * distance for comparison.
 *
 * A vertex i with S(x_i) < 0 (inside) moves by
 *     grad S / |grad S| (|S(x_i)| + delta_i),
 *     delta_i = sum_k g_k |S(x_k)| / sum_k g_k,  g_k = exp(-|x_i - x_k|^2 / (2 sigma_i^2)),
 * over the one-ring neighbours k that do not collide. The paper defines
 * delta_i as sum_k w_k |S(x_k)| / |N_i| with Gaussian weights "which [are]
 * then normalized"; we read the normalisation as w_k = |N_i| g_k / sum g_k,
 * so delta_i is the Gaussian-weighted mean the paper calls it ("the weighted
 * average of the absolute SDF value"). sigma_i is sigma_scale times the mean
 * length of i's one-ring edges, so the weights do not depend on the mesh's
 * resolution. A collided vertex thus lands as far outside the body as its
 * free neighbours are, which keeps the local shape (no dent at the surface
 * and no bulge beyond the neighbours). Every delta uses the positions and S
 * from before any move.
 *
 * Leaves out: iterating (the paper moves once), edge-edge and face tests.
 */
#include "methods/swingar/sdf.h"

#include "crease/bvh.h"
#include "crease/swingar.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t COLLIDE_DEF_COOKIE = 0x434f4c31u;
static const float ON_SURFACE_M = 1e-6f; /* closer than this: use the pseudo-normal */

cr_swingar_collide_def cr_swingar_collide_default_def(void) {
    return (cr_swingar_collide_def){.sigma_scale = 1.0f,
                                    .delta_weight = 1.0f,
                                    .margin = 0.0f,
                                    .passes = 1,
                                    .cookie = COLLIDE_DEF_COOKIE};
}

/* ------------------------------------------------------------- sources -- */

static cr_status neural_eval(void *user, const float *x, int64_t n, float *s, float *grad,
                             cr_error *err) {
    cr_swingar_sdf_neural_source *u = user;
    float *xl = malloc((size_t)n * 3 * sizeof(float) + 1);
    if (!xl) return CR_FAIL(err, CR_ERR_MEMORY, "swingar collide: %lld points", (long long)n);
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            xl[3 * i + k] = x[3 * i + k] - u->trans[k];
    cr_status st = cr_swingar_sdf_eval(u->net, xl, n, u->cond, s, grad, err);
    free(xl);
    return st;
}

void cr_swingar_sdf_source_neural(cr_swingar_sdf *net, const float *cond, const float *trans,
                                  cr_swingar_sdf_neural_source *user, cr_swingar_sdf_source *out) {
    memset(user, 0, sizeof *user);
    user->net = net;
    int c = cr_swingar_sdf_cond_len(cr_swingar_sdf_get_def(net));
    c = c < CR_SWINGAR_SDF_COND_MAX ? c : CR_SWINGAR_SDF_COND_MAX;
    if (cond && c > 0) memcpy(user->cond, cond, (size_t)c * sizeof(float));
    if (trans) memcpy(user->trans, trans, sizeof user->trans);
    *out = (cr_swingar_sdf_source){.eval = neural_eval, .user = user};
}

static cr_status bvh_eval(void *user, const float *x, int64_t n, float *s, float *grad,
                          cr_error *err) {
    const cr_swingar_sdf_bvh_source *u = user;
    if (!grad) {
        cr_bvh_signed_distance_batch(u->bvh, x, n, u->max_dist, s, NULL, NULL);
        return CR_OK;
    }
    float *cp = malloc((size_t)n * 3 * sizeof(float) + 1);
    if (!cp) return CR_FAIL(err, CR_ERR_MEMORY, "swingar collide: %lld points", (long long)n);
    cr_bvh_signed_distance_batch(u->bvh, x, n, u->max_dist, s, grad, cp);
    /* the exact SDF gradient: from the closest point, flipped inside; the
     * pseudo-normal (already in grad) on the surface itself */
    for (int64_t i = 0; i < n; i++) {
        float d[3], len = 0;
        for (int k = 0; k < 3; k++)
            d[k] = x[3 * i + k] - cp[3 * i + k], len += d[k] * d[k];
        len = sqrtf(len);
        if (len > ON_SURFACE_M)
            for (int k = 0; k < 3; k++)
                grad[3 * i + k] = (s[i] < 0 ? -d[k] : d[k]) / len;
    }
    free(cp);
    return CR_OK;
}

void cr_swingar_sdf_source_bvh(const struct cr_bvh *bvh, float max_dist,
                               cr_swingar_sdf_bvh_source *user, cr_swingar_sdf_source *out) {
    user->bvh = bvh;
    user->max_dist = max_dist;
    *out = (cr_swingar_sdf_source){.eval = bvh_eval, .user = user};
}

/* ------------------------------------------------------------- removal -- */

static float dist2(const float *a, const float *b) {
    float d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return d0 * d0 + d1 * d1 + d2 * d2;
}

/* One pass of eq. 10. */
static cr_status remove_once(const cr_swingar_collide_def *def, float *pos, const cr_topology *topo,
                             const cr_swingar_sdf_source *src, cr_swingar_collide_stats *out,
                             cr_error *err) {
    memset(out, 0, sizeof *out);
    int64_t nv = topo->nv;
    float *s = malloc((size_t)nv * sizeof(float) + 1);
    int32_t *idx = malloc((size_t)nv * sizeof(int32_t) + 1);
    if (!s || !idx) {
        free(s), free(idx);
        return CR_FAIL(err, CR_ERR_MEMORY, "swingar collide: %lld vertices", (long long)nv);
    }
    double t0 = cr_time_now();
    cr_status st = src->eval(src->user, pos, nv, s, NULL, err);
    for (int64_t i = 0; st == CR_OK && def->offset > 0 && i < nv; i++)
        s[i] -= def->offset;
    double t1 = cr_time_now();
    out->seconds_detect = t1 - t0;
    int64_t c = 0;
    for (int64_t i = 0; st == CR_OK && i < nv; i++) {
        if (!isfinite(s[i])) {
            st = CR_FAIL(err, CR_ERR_NAN, "swingar collide: S is not finite at vertex %lld",
                         (long long)i);
            break;
        }
        if (s[i] < 0) idx[c++] = (int32_t)i;
    }
    out->colliding = c;
    float *buf = c > 0 && st == CR_OK ? malloc((size_t)c * 8 * sizeof(float)) : NULL;
    if (c > 0 && st == CR_OK && !buf) st = CR_FAIL(err, CR_ERR_MEMORY, "swingar collide");
    if (c > 0 && st == CR_OK) {
        float *xc = buf, *g = buf + 3 * c, *sc = buf + 6 * c, *mv = buf + 7 * c;
        for (int64_t j = 0; j < c; j++)
            memcpy(&xc[3 * j], &pos[3 * (int64_t)idx[j]], 3 * sizeof(float));
        st = src->eval(src->user, xc, c, sc, g, err);
        for (int64_t j = 0; st == CR_OK && def->offset > 0 && j < c; j++)
            sc[j] -= def->offset;
        for (int64_t j = 0; st == CR_OK && j < c; j++) {
            int64_t i = idx[j];
            const float *xi = &pos[3 * i];
            double elen = 0, gs = 0, gsum = 0;
            int32_t deg = topo->vv_off[i + 1] - topo->vv_off[i];
            for (int32_t e = topo->vv_off[i]; e < topo->vv_off[i + 1]; e++)
                elen += sqrt(dist2(xi, &pos[3 * (int64_t)topo->vv[e]]));
            double sigma = deg > 0 ? def->sigma_scale * elen / deg : 0;
            for (int32_t e = topo->vv_off[i]; sigma > 0 && e < topo->vv_off[i + 1]; e++) {
                int64_t k = topo->vv[e];
                if (s[k] < 0) continue;
                double w = exp(-dist2(xi, &pos[3 * k]) / (2 * sigma * sigma));
                gs += w * fabs(s[k]);
                gsum += w;
            }
            double delta = gsum > 0 ? gs / gsum : 0;
            out->mean_delta_m += delta;
            mv[j] = (float)(fabs(sc[j]) + def->delta_weight * delta + def->margin);
        }
        for (int64_t j = 0; st == CR_OK && j < c; j++) {
            float *gj = &g[3 * j];
            float len = sqrtf(gj[0] * gj[0] + gj[1] * gj[1] + gj[2] * gj[2]);
            if (!(len > 0) || !isfinite(len)) continue; /* no direction: leave it */
            float *p = &pos[3 * (int64_t)idx[j]];
            for (int k = 0; k < 3; k++)
                p[k] += gj[k] / len * mv[j];
            out->mean_move_m += mv[j];
            if (mv[j] > out->max_move_m) out->max_move_m = mv[j];
        }
        out->mean_move_m /= (double)c;
        out->mean_delta_m /= (double)c;
    }
    out->seconds_move = cr_time_now() - t1;
    free(buf), free(s), free(idx);
    return st;
}

cr_status cr_swingar_collision_remove(const cr_swingar_collide_def *def, float *pos,
                                      const cr_topology *topo, const cr_swingar_sdf_source *src,
                                      cr_swingar_collide_stats *stats, cr_error *err) {
    CR_ASSERT(def->cookie == COLLIDE_DEF_COOKIE);
    cr_swingar_collide_stats local;
    cr_swingar_collide_stats *out = stats ? stats : &local;
    memset(out, 0, sizeof *out);
    if (!(def->sigma_scale > 0) || !(def->delta_weight >= 0) || !(def->margin >= 0) ||
        !(def->offset >= 0) || def->passes < 1 || def->passes > 16)
        return CR_FAIL(
            err, CR_ERR_INVALID,
            "swingar collide: need sigma_scale > 0, delta_weight >= 0, margin, offset >= 0 "
            "and passes in [1, 16] (got %d)",
            def->passes);
    /* later passes catch what a move along an inexact gradient left inside */
    double moved = 0;
    for (int p = 0; p < def->passes; p++) {
        cr_swingar_collide_stats one;
        CR_TRY(remove_once(def, pos, topo, src, &one, err));
        if (p == 0) out->colliding = one.colliding, out->mean_delta_m = one.mean_delta_m;
        out->mean_move_m += one.mean_move_m * (double)one.colliding;
        moved += (double)one.colliding;
        out->max_move_m = one.max_move_m > out->max_move_m ? one.max_move_m : out->max_move_m;
        out->seconds_detect += one.seconds_detect;
        out->seconds_move += one.seconds_move;
        if (one.colliding == 0) break;
    }
    out->mean_move_m = moved > 0 ? out->mean_move_m / moved : 0;
    return CR_OK;
}

/* ---------------------------------------------- exact removal, a whole run -- */

/* The share of the n points inside the body (signed distance < 0). */
static double inside_share(const cr_bvh *bvh, const float *x, int64_t n, float *d) {
    cr_bvh_signed_distance_batch(bvh, x, n, 0.05f, d, NULL, NULL);
    int64_t in = 0;
    for (int64_t i = 0; i < n; i++)
        in += d[i] < 0.0f;
    return n ? (double)in / (double)n : 0.0;
}

cr_status cr_swingar_remove_collisions_exact(const cr_mesh *garment, const cr_mesh *body_rest,
                                             const float *body, int32_t T, float margin,
                                             float *pred, cr_swingar_removal_stats *stats,
                                             cr_error *err) {
    cr_swingar_removal_stats local = {0};
    cr_swingar_removal_stats *s = stats ? stats : &local;
    memset(s, 0, sizeof *s);
    if (!garment || !body_rest || !body || !pred || T < 1 || !(margin >= 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "swingar removal: NULL input, %d frames or margin %g",
                       T, (double)margin);
    const int64_t V = garment->nv, Vb = body_rest->nv;
    double t0 = cr_time_now();
    cr_topology *topo = NULL;
    cr_bvh *bvh = NULL;
    float *d = malloc(sizeof(float) * (size_t)V);
    cr_status st = d ? cr_topology_build(garment, &topo, err)
                     : CR_FAIL(err, CR_ERR_MEMORY, "swingar removal: out of memory");
    if (st == CR_OK) st = cr_bvh_build(body, (int32_t)Vb, body_rest->tri, body_rest->nf, &bvh, err);
    cr_swingar_collide_def cd = cr_swingar_collide_default_def();
    cd.margin = margin;
    cd.passes = 4; /* the exact field: a second pass finds what a neighbour's move left */
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        float *x = pred + (size_t)t * V * 3;
        if (t > 0) st = cr_bvh_refit(bvh, body + (size_t)t * Vb * 3, err);
        if (st != CR_OK) break;
        cr_swingar_sdf_bvh_source user;
        cr_swingar_sdf_source src;
        cr_swingar_sdf_source_bvh(bvh, INFINITY, &user, &src);
        cr_swingar_collide_stats cs;
        st = cr_swingar_collision_remove(&cd, x, topo, &src, &cs, err);
        /* the first pass's detection is the share inside before */
        s->inside_before = fmax(s->inside_before, (double)cs.colliding / (double)(V ? V : 1));
        s->moved += cs.colliding;
        if (st == CR_OK) s->inside_after = fmax(s->inside_after, inside_share(bvh, x, V, d));
    }
    s->seconds = cr_time_now() - t0;
    cr_bvh_destroy(bvh);
    cr_topology_destroy(topo);
    free(d);
    return st;
}
