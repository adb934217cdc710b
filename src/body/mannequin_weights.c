/* mannequin_weights.c: the mannequin's skinning weights.
 *
 * Distance to bones alone binds the side of the chest to the upper arm in an
 * A-pose (the arm bone is nearer than the spine), so weights come from the
 * implicit shape instead, in two steps:
 *
 *  1. Part membership: each primitive's share is a softmax of its negative
 *     distance, exp(-d_i / tau) normalised over primitives, summed per part
 *     (torso, neck and head, each arm, each leg). A vertex on one primitive
 *     belongs to its part; in a fillet (armpit, groin, neck) the share moves
 *     smoothly over a few tau.
 *  2. Within a part, its chain splits the weight between bones: planes
 *     across the joints (spine joints, collar, shoulder, elbow, wrist, hip,
 *     knee, ankle, ball of the foot), each crossed by a smooth step of its
 *     own half-width, nested so the weights of a chain sum to one.
 * Each vertex then keeps its four largest weights, renormalised. The weights
 * are smooth functions of position (softmax and smoothsteps), so they need
 * no smoothing on the mesh and do not depend on its resolution: a coarse and
 * a fine mannequin of one shape deform alike.
 *
 * Blend zones stay a few centimetres wide, the same trade-off SMPL's
 * artist-made weights make: wide zones spread a bend smoothly but collapse
 * volume under twist (the candy wrapper), narrow ones crease.
 *
 * Left out: bone heat diffusion (Baran & Popovic 2007) and bounded
 * biharmonic weights (Jacobson et al. 2011), which need no part labels but a
 * sparse solve and visibility tests.
 */
#include "mannequin_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Add `scale` times the chain's bone weights at p to w (22). */
static void chain_weights(const body_chain *c, const float p[3], float scale, float *w) {
    float run = 1.0f;
    for (int i = 0; i < c->nplanes; i++) {
        const chain_plane *pl = &c->plane[i];
        float d[3] = {p[0] - pl->p[0], p[1] - pl->p[1], p[2] - pl->p[2]};
        float t = 0.5f * ((d[0] * pl->n[0] + d[1] * pl->n[1] + d[2] * pl->n[2]) / pl->half + 1.0f);
        t = fminf(fmaxf(t, 0.0f), 1.0f);
        float past = t * t * (3.0f - 2.0f * t); /* smoothstep */
        w[c->bone[i]] += scale * run * (1.0f - past);
        run *= past;
    }
    w[c->bone[c->nplanes]] += scale * run;
}

typedef struct weight_ctx {
    const mannequin_shape *s;
    const float *pos; /* (V,3) */
    float *w;         /* (V,22) */
} weight_ctx;

static void part_weights(void *vctx, int64_t begin, int64_t end) {
    weight_ctx *c = vctx;
    const mannequin_shape *s = c->s;
    for (int64_t v = begin; v < end; v++) {
        const float *p = &c->pos[3 * v];
        float d[MAX_PRIMS], dmin = INFINITY, share[PART_COUNT] = {0}, total = 0.0f;
        for (int i = 0; i < s->nprims; i++) {
            d[i] = cr_mannequin_prim_distance(s, &s->prims[i], p);
            dmin = fminf(dmin, d[i]);
        }
        for (int i = 0; i < s->nprims; i++) {
            float m = expf(-(d[i] - dmin) / s->membership_temp);
            share[s->prims[i].part] += m;
            total += m;
        }
        float *w = &c->w[v * CR_NJOINTS];
        memset(w, 0, CR_NJOINTS * sizeof(float));
        for (int q = 0; q < PART_COUNT; q++)
            if (share[q] > 1e-6f * total) chain_weights(&s->chain[q], p, share[q] / total, w);
    }
}

/* The four largest weights of w (22), renormalised. */
static void keep_four(const float *w, int32_t *joint, float *weight) {
    int used[CR_NJOINTS] = {0};
    double sum = 0.0;
    for (int k = 0; k < 4; k++) {
        int best = -1;
        for (int j = 0; j < CR_NJOINTS; j++)
            if (!used[j] && (best < 0 || w[j] > w[best])) best = j;
        used[best] = 1;
        joint[k] = best;
        weight[k] = fmaxf(w[best], 0.0f);
        sum += weight[k];
    }
    /* The chains' weights sum to one, so the largest is at least 1/22. */
    CR_ASSERT(sum > 0.0);
    for (int k = 0; k < 4; k++)
        weight[k] = (float)(weight[k] / sum);
}

cr_status cr_mannequin_skin_weights(const mannequin_shape *s, const cr_mesh *mesh,
                                    int32_t *skin_joint, float *skin_weight, cr_error *err) {
    int64_t nv = mesh->nv;
    float *w = cr_malloc((size_t)nv * CR_NJOINTS * sizeof(float), err);
    if (!w) return CR_ERR_MEMORY;
    weight_ctx wc = {s, mesh->pos, w};
    cr_parallel_for(nv, 512, part_weights, &wc);
    for (int64_t v = 0; v < nv; v++)
        keep_four(&w[v * CR_NJOINTS], &skin_joint[4 * v], &skin_weight[4 * v]);
    free(w);
    return CR_OK;
}
