/* garment_shapes.c: each garment type as a level set around the body, cut by
 * its openings and split into panels by its seams.
 *
 * Fields (negative on the body's side):
 *  - tight parts: the body's signed distance (exact, from its BVH) sampled on
 *    a grid of def.grid_m cells, blurred by one pass of a [1 2 1]/4 kernel
 *    per axis, minus the clearance. The blur rounds the creases an exact
 *    offset has in concave places (armpits, crotch, between neck and
 *    shoulders) into fillets about a cell wide, as cloth bridges them. Only
 *    a shell of distances around the clearance is needed exactly; a coarse
 *    pass (every other sample) skips the points well off it, and a flood
 *    fill gives each region no query reached the side of the shell around it.
 *  - loose parts (skirt, dress below the waist): a vertical tube around the
 *    pelvis whose radius at angle theta and height y is
 *        R = smax(r(theta, y) + c, r(theta, y_waist) + c + (y_waist - y) tan(flare)),
 *    r the outermost point of the torso and legs (arms left out) on the ray
 *    from far outside towards the axis, dilated by one table cell; the field
 *    is rho - R with rho the distance from the axis. So the skirt is tight
 *    at the waist, clears the hips, and falls as a cone below.
 *  - the dress joins the two with a smooth minimum, each faded out on the
 *    other's side of the waist.
 * Openings and seams: the hem and waist are horizontal planes, the neckline
 * a sphere above the neck joint (its radius from the neck's measured
 * thickness), sleeve ends planes across the arm that only act where the
 * body's arm skinning weight exceeds 1/2, armholes (sleeveless garments) and
 * sleeve seams the level 1/2 of that weight (smoothed on the surface), the
 * front/back seam the coronal plane through the shoulders (side seams and
 * shoulder seams at once), and for trousers also the sagittal plane. Heights
 * and lengths follow the body's joints, so other heights and shapes (and
 * SMPL bodies) get garments that fit.
 *
 * The zero level is polygonised (cr_isosurface_extract), cut
 * (garment_cut.c), the largest piece kept (hands and head fall away), and
 * every vertex projected back onto the level.
 *
 * Left out: darts, collars, pockets, waistbands, and panels drawn as 2-D
 * patterns and sewn (the surface comes first here, the pattern from
 * flattening it).
 *
 * References: Quilez, smooth minimum; Lorensen & Cline 1987 with Nielson &
 * Hamann 1991 (cr_isosurface_extract).
 */
#include "garment_internal.h"

#include "base/vec3.h"
#include "crease/body.h"
#include "crease/isosurface.h"
#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Scale of the arm-weight terms in cut and seam fields: (w - 1/2) times this
 * reads like metres next to the planes' distances. */
#define WEIGHT_SCALE_M 0.1f
/* Passes of arm-weight smoothing on the polygonised surface. */
#define WEIGHT_SMOOTH_PASSES 6

void cr_gbase_free(gbase *b) {
    free(b->field.v);
    cr_mesh_destroy(b->mesh);
    free(b->panel);
    memset(b, 0, sizeof *b);
}

/* ------------------------------------------------------- cuts and seams -- */

typedef enum fn_kind {
    FN_PLANE,   /* (p - p0) . n */
    FN_SPHERE,  /* |p - p0| - r */
    FN_ARM_END, /* max(r - (p - p0) . n, S (1/2 - w_side)): a plane across one arm only */
    FN_ARM      /* sign S (w_side - 1/2): the armhole */
} fn_kind;

/* A scalar function of position and arm weights; cuts keep where it is >= 0,
 * seams set a panel bit where it is > 0. */
typedef struct gfn {
    fn_kind kind;
    float p[3], n[3]; /* point and unit normal (plane, arm end); centre (sphere) */
    float r;          /* sphere radius, or how far past p0 an arm end lies, m */
    int side;         /* arm functions: 0 left, 1 right */
    float sign;       /* FN_ARM: +1 positive on the arm, -1 off it */
} gfn;

static float fn_eval(const gfn *c, const float p[3], const float w[2]) {
    float d[3] = {p[0] - c->p[0], p[1] - c->p[1], p[2] - c->p[2]};
    switch (c->kind) {
    case FN_PLANE:
        return dot3f(d, c->n);
    case FN_SPHERE:
        return sqrtf(dot3f(d, d)) - c->r;
    case FN_ARM_END:
        return fmaxf(c->r - dot3f(d, c->n), WEIGHT_SCALE_M * (0.5f - w[c->side]));
    case FN_ARM:
        return c->sign * WEIGHT_SCALE_M * (w[c->side] - 0.5f);
    }
    CR_ASSERT(!"unknown garment function");
    return 0.0f;
}

enum { MAX_CUTS = 6, MAX_SEAMS = 3 };

/* Everything that differs between garment types. */
typedef struct gspec {
    int tight, loose;         /* which fields make the surface */
    int no_arms;              /* the garment stays off the arms (sizes the grid without them) */
    float clearance;          /* level of the tight field, m */
    float loose_clear;        /* the envelope's clearance, m */
    float waist_y;            /* loose: where the flare starts (and the dress's junction), m */
    float flare;              /* rad */
    float loose_lo;           /* loose: lowest height the envelope is needed at, m */
    float tight_lo, tight_hi; /* heights the tight field is sampled between, m */
    int ncut, nseam;
    gfn cut[MAX_CUTS], seam[MAX_SEAMS];
    int npanel;
    const char *names[CR_GARMENT_MAX_PANELS];
    int8_t panel_of[1 << MAX_SEAMS]; /* seam bits -> panel */
} gspec;

static const float *joint(const gbody *b, int j) {
    return &b->model->joints[3 * j];
}

static gfn plane_y(float y, float up) {
    gfn c = {.kind = FN_PLANE};
    set3f(c.p, 0.0f, y, 0.0f);
    set3f(c.n, 0.0f, up, 0.0f);
    return c;
}

static gfn arm_fn(int side, float sign) {
    gfn c = {.kind = FN_ARM, .side = side, .sign = sign};
    return c;
}

/* A plane across one arm at `frac` of the way from joint a to joint b (or
 * `back` metres before b when frac < 0). */
static gfn arm_end(const gbody *b, int side, int ja, int jb, float frac, float back) {
    const float *A = joint(b, ja), *B = joint(b, jb);
    gfn c = {.kind = FN_ARM_END, .side = side};
    float d[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, len = sqrtf(dot3f(d, d));
    memcpy(c.p, A, sizeof c.p);
    for (int k = 0; k < 3; k++)
        c.n[k] = d[k] / len;
    c.r = frac >= 0.0f ? frac * len : len - back;
    return c;
}

static void spec_build(const cr_garment_def *def, const gbody *b, gspec *sp) {
    memset(sp, 0, sizeof *sp);
    const float s = b->scale, ls = def->length_scale;
    const float *N = joint(b, CR_JOINT_NECK), *P = joint(b, CR_JOINT_PELVIS);
    const float *LS = joint(b, CR_JOINT_LEFT_SHOULDER), *RS = joint(b, CR_JOINT_RIGHT_SHOULDER);
    const float hip_y = joint(b, CR_JOINT_LEFT_HIP)[1], knee_y = joint(b, CR_JOINT_LEFT_KNEE)[1];
    const float ankle_y = joint(b, CR_JOINT_LEFT_ANKLE)[1], waist_y = joint(b, CR_JOINT_SPINE1)[1];
    /* Neckline: a sphere above the neck joint, its radius from the neck's
     * thickness (distance from the joint to the skin). */
    cr_bvh_hit hit;
    cr_bvh_closest(b->bvh, N, INFINITY, &hit);
    gfn neck = {.kind = FN_SPHERE};
    set3f(neck.p, N[0], N[1] + 0.055f * s, N[2] + 0.02f * s);
    neck.r = hit.distance + 0.055f * s + def->neck_m;
    gfn front = {.kind = FN_PLANE};
    set3f(front.p, 0.0f, 0.0f, 0.5f * (LS[2] + RS[2]));
    set3f(front.n, 0.0f, 0.0f, 1.0f);

    /* Tops end above the crotch (below it a tight hem would split round
     * each leg). */
    const float top_hem_min = hip_y - 0.02f * s;
    sp->clearance = def->clearance_m;
    sp->tight_hi = N[1] + 0.15f * s;
    static const char *two[] = {"front", "back"};
    static const int8_t two_of[8] = {1, 0, 1, 0, 1, 0, 1, 0};
    switch (def->type) {
    case CR_GARMENT_TSHIRT:
    case CR_GARMENT_LONGSLEEVE: {
        float hem = N[1] - ls * (N[1] - (hip_y + 0.005f * s));
        sp->tight = 1;
        if (hem >= top_hem_min) {
            sp->tight_lo = hem;
        } else {
            /* A long shirt: below the waist the dress's envelope takes over
             * (a tight hem would split round each leg). */
            sp->tight_lo = waist_y - 0.06f * s;
            sp->loose = 1;
            sp->loose_clear = def->clearance_m + 0.005f;
            sp->waist_y = waist_y;
            sp->flare = def->flare_deg * (float)M_PI / 180.0f;
            sp->loose_lo = hem;
        }
        sp->cut[sp->ncut++] = plane_y(hem, 1.0f);
        sp->cut[sp->ncut++] = neck;
        for (int side = 0; side < 2; side++) {
            int sh = side ? CR_JOINT_RIGHT_SHOULDER : CR_JOINT_LEFT_SHOULDER;
            int el = side ? CR_JOINT_RIGHT_ELBOW : CR_JOINT_LEFT_ELBOW;
            int wr = side ? CR_JOINT_RIGHT_WRIST : CR_JOINT_LEFT_WRIST;
            gfn end =
                def->type == CR_GARMENT_TSHIRT
                    ? arm_end(b, side, sh, el, fminf(0.6f * ls * def->sleeve_scale, 0.95f), 0.0f)
                    : arm_end(b, side, el, wr, -1.0f, 0.015f * s);
            if (def->type == CR_GARMENT_LONGSLEEVE) end.r *= fminf(def->sleeve_scale, 1.0f);
            sp->cut[sp->ncut++] = end;
        }
        sp->seam[sp->nseam++] = front;
        sp->seam[sp->nseam++] = arm_fn(0, 1.0f);
        sp->seam[sp->nseam++] = arm_fn(1, 1.0f);
        static const char *six[] = {"front",
                                    "back",
                                    "left_sleeve_front",
                                    "left_sleeve_back",
                                    "right_sleeve_front",
                                    "right_sleeve_back"};
        static const int8_t six_of[8] = {1, 0, 3, 2, 5, 4, 3, 2};
        sp->npanel = 6;
        memcpy(sp->names, six, sizeof six);
        memcpy(sp->panel_of, six_of, sizeof six_of);
        return;
    }
    case CR_GARMENT_VEST:
    case CR_GARMENT_DRESS: {
        int dress = def->type == CR_GARMENT_DRESS;
        float hem = dress ? waist_y - ls * (waist_y - (knee_y - 0.03f * s))
                          : fmaxf(N[1] - ls * (N[1] - (hip_y + 0.05f * s)), top_hem_min);
        sp->tight = 1;
        sp->no_arms = 1;
        sp->tight_lo = dress ? waist_y - 0.06f * s : hem;
        if (dress) {
            sp->loose = 1;
            sp->loose_clear = def->clearance_m + 0.005f;
            sp->waist_y = waist_y;
            sp->flare = def->flare_deg * (float)M_PI / 180.0f;
            sp->loose_lo = hem;
        }
        sp->cut[sp->ncut++] = plane_y(hem, 1.0f);
        if (!dress) neck.r += 0.015f * s; /* a vest's neckline sits outside the shirt's */
        sp->cut[sp->ncut++] = neck;
        sp->cut[sp->ncut++] = arm_fn(0, -1.0f);
        sp->cut[sp->ncut++] = arm_fn(1, -1.0f);
        break;
    }
    case CR_GARMENT_SKIRT: {
        float hem = waist_y - ls * (waist_y - (knee_y + 0.06f * s));
        sp->loose = 1;
        sp->loose_clear = def->clearance_m;
        sp->waist_y = waist_y;
        sp->flare = def->flare_deg * (float)M_PI / 180.0f;
        sp->loose_lo = hem;
        sp->cut[sp->ncut++] = plane_y(waist_y, -1.0f);
        sp->cut[sp->ncut++] = plane_y(hem, 1.0f);
        break;
    }
    case CR_GARMENT_TROUSERS:
    case CR_GARMENT_JUMPSUIT: {
        /* The jumpsuit: the trousers' legs and a sleeveless top in one
         * level set, with the trousers' four panels running up to the
         * shoulders. */
        int jump = def->type == CR_GARMENT_JUMPSUIT;
        float top = P[1] + 0.045f * s;
        float end = fmaxf(top - ls * (top - (ankle_y + 0.045f * s)), ankle_y + 0.03f * s);
        float hip_z = 0.5f * (joint(b, CR_JOINT_LEFT_HIP)[2] + joint(b, CR_JOINT_RIGHT_HIP)[2]);
        sp->tight = 1;
        sp->no_arms = 1;
        sp->tight_lo = end;
        if (!jump) {
            sp->tight_hi = top;
            sp->cut[sp->ncut++] = plane_y(top, -1.0f);
        }
        sp->cut[sp->ncut++] = plane_y(end, 1.0f);
        if (jump) {
            sp->cut[sp->ncut++] = neck;
            sp->cut[sp->ncut++] = arm_fn(0, -1.0f);
            sp->cut[sp->ncut++] = arm_fn(1, -1.0f);
            /* Side seams halfway between the shoulders' and the hips' planes. */
            front.p[2] = 0.5f * (front.p[2] + hip_z);
        } else {
            front.p[2] = hip_z;
        }
        gfn left = {.kind = FN_PLANE};
        set3f(left.p, P[0], 0.0f, 0.0f);
        set3f(left.n, 1.0f, 0.0f, 0.0f);
        sp->seam[sp->nseam++] = front;
        sp->seam[sp->nseam++] = left;
        static const char *four[] = {"front_left", "front_right", "back_left", "back_right"};
        static const int8_t four_of[8] = {3, 1, 2, 0, 3, 1, 2, 0};
        sp->npanel = 4;
        memcpy(sp->names, four, sizeof four);
        memcpy(sp->panel_of, four_of, sizeof four_of);
        return;
    }
    case CR_GARMENT_USER:
    case CR_GARMENT_TYPE_COUNT:
        CR_ASSERT(!"no procedural shape for this garment type");
    }
    sp->seam[sp->nseam++] = front;
    sp->npanel = 2;
    memcpy(sp->names, two, sizeof two);
    memcpy(sp->panel_of, two_of, sizeof two_of);
}

/* ------------------------------------------------------------ envelope -- */

enum { ENV_ANGLES = 72 }; /* 5 degree columns */

/* The loose parts' radius table R (rows over height, columns over the angle
 * theta from +Z towards +X) around a vertical axis through (ax, az). */
typedef struct envelope {
    int32_t ny;
    float y0, dy, ax, az;
    float *R; /* (ny, ENV_ANGLES) m */
} envelope;

static float clampf(float x, float lo, float hi) {
    return x < lo ? lo : x > hi ? hi : x;
}

static float smin(float a, float b, float k) {
    float h = fmaxf(k - fabsf(a - b), 0.0f) / k;
    return fminf(a, b) - 0.25f * h * h * k;
}

static float envelope_radius(const envelope *e, float theta, float y) {
    float u = theta * (float)(ENV_ANGLES / (2.0 * M_PI));
    u -= floorf(u / ENV_ANGLES) * ENV_ANGLES;
    int32_t i0 = (int32_t)u % ENV_ANGLES, i1 = (i0 + 1) % ENV_ANGLES;
    float tu = u - floorf(u);
    float v = clampf((y - e->y0) / e->dy, 0.0f, (float)(e->ny - 1));
    int32_t j0 = (int32_t)v < e->ny - 1 ? (int32_t)v : e->ny - 2;
    float tv = v - (float)j0;
    const float *r0 = &e->R[(size_t)j0 * ENV_ANGLES], *r1 = r0 + ENV_ANGLES;
    float a = r0[i0] + tu * (r0[i1] - r0[i0]), c = r1[i0] + tu * (r1[i1] - r1[i0]);
    return a + tv * (c - a);
}

static float envelope_field(const envelope *e, const float p[3]) {
    float dx = p[0] - e->ax, dz = p[2] - e->az;
    return sqrtf(dx * dx + dz * dz) - envelope_radius(e, atan2f(dx, dz), p[1]);
}

static cr_status envelope_build(const gbody *b, const gspec *sp, float y_lo, float y_hi,
                                envelope *e, cr_error *err) {
    const cr_mesh *m = b->model->rest;
    const float *P = joint(b, CR_JOINT_PELVIS);
    memset(e, 0, sizeof *e);
    e->ax = P[0], e->az = P[2];
    e->dy = 0.01f * b->scale;
    e->y0 = y_lo;
    e->ny = (int32_t)ceilf((y_hi - y_lo) / e->dy) + 1;
    if (e->ny < 2) e->ny = 2;
    /* Torso and legs only: the hands hang beside the hips in an A-pose. */
    int32_t *tri = cr_malloc((size_t)m->nf * 3 * sizeof(int32_t), err);
    float *r = cr_malloc((size_t)e->ny * ENV_ANGLES * sizeof(float), err);
    e->R = cr_malloc((size_t)e->ny * ENV_ANGLES * sizeof(float), err);
    cr_bvh *bvh = NULL;
    cr_status st = tri && r && e->R ? CR_OK : CR_ERR_MEMORY;
    int32_t nf = 0;
    for (int32_t f = 0; st == CR_OK && f < m->nf; f++) {
        int arm = 0;
        for (int k = 0; k < 3; k++) {
            int32_t v = m->tri[3 * f + k];
            arm |= b->arm_w[2 * v] + b->arm_w[2 * v + 1] > 0.5f;
        }
        if (!arm) memcpy(&tri[3 * nf++], &m->tri[3 * f], 3 * sizeof(int32_t));
    }
    if (st == CR_OK) st = cr_bvh_build(m->pos, m->nv, tri, nf, &bvh, err);
    const float far = 2.0f * b->scale;
    for (int32_t j = 0; st == CR_OK && j < e->ny; j++)
        for (int32_t i = 0; i < ENV_ANGLES; i++) {
            float th = (float)(2.0 * M_PI * i / ENV_ANGLES), y = e->y0 + e->dy * (float)j;
            float dir[3] = {-sinf(th), 0.0f, -cosf(th)};
            float o[3] = {e->ax - far * dir[0], y, e->az - far * dir[2]};
            cr_bvh_ray_hit h;
            r[(size_t)j * ENV_ANGLES + i] = cr_bvh_raycast(bvh, o, dir, far, &h) ? far - h.t : 0.0f;
        }
    if (st == CR_OK) {
        /* Dilate by a cell each way, so nothing pokes out between samples. */
        for (int32_t j = 0; j < e->ny; j++)
            for (int32_t i = 0; i < ENV_ANGLES; i++) {
                float mx = 0.0f;
                for (int32_t dj = -1; dj <= 1; dj++)
                    for (int32_t di = -1; di <= 1; di++) {
                        int32_t jj = j + dj, ii = (i + di + ENV_ANGLES) % ENV_ANGLES;
                        if (jj >= 0 && jj < e->ny) mx = fmaxf(mx, r[(size_t)jj * ENV_ANGLES + ii]);
                    }
                e->R[(size_t)j * ENV_ANGLES + i] = mx;
            }
        int32_t jw =
            (int32_t)clampf(roundf((sp->waist_y - e->y0) / e->dy), 0.0f, (float)(e->ny - 1));
        float waist[ENV_ANGLES], t = tanf(sp->flare), k = 0.02f * b->scale;
        for (int32_t i = 0; i < ENV_ANGLES; i++)
            waist[i] = e->R[(size_t)jw * ENV_ANGLES + i] + sp->loose_clear;
        for (int32_t j = 0; j < e->ny; j++)
            for (int32_t i = 0; i < ENV_ANGLES; i++) {
                float y = e->y0 + e->dy * (float)j;
                float cone = waist[i] + fmaxf(sp->waist_y - y, 0.0f) * t;
                float *R = &e->R[(size_t)j * ENV_ANGLES + i];
                *R = -smin(-(*R + sp->loose_clear), -cone, k);
            }
        /* r is free now: it holds a row or column while smoothing. */
        for (int pass = 0; pass < 2; pass++) {
            for (int32_t j = 0; j < e->ny; j++)
                cr_garment_smooth_line(&e->R[(size_t)j * ENV_ANGLES], ENV_ANGLES, 1, 1, r);
            for (int32_t i = 0; i < ENV_ANGLES; i++)
                cr_garment_smooth_line(&e->R[i], e->ny, ENV_ANGLES, 0, r);
        }
    }
    cr_bvh_destroy(bvh);
    free(tri);
    free(r);
    if (st != CR_OK) {
        free(e->R);
        e->R = NULL;
    }
    return st;
}

/* ---------------------------------------------------------------- base -- */

/* Box around the body vertices every cut keeps (within `slack`) between the
 * tight part's heights. Returns 0 when there are none. */
static int tight_box(const gbody *b, const gspec *sp, float slack, float lo[3], float hi[3]) {
    const cr_mesh *m = b->model->rest;
    int any = 0;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *p = &m->pos[3 * (size_t)v];
        if (p[1] < sp->tight_lo - slack || p[1] > sp->tight_hi + slack) continue;
        /* Arm weights are not distances: their terms get a fixed slack. */
        const float *w = &b->arm_w[2 * v];
        int keep = !sp->no_arms || w[0] + w[1] < 0.5f;
        for (int c = 0; c < sp->ncut && keep; c++) {
            const gfn *fn = &sp->cut[c];
            keep = fn_eval(fn, p, w) >= (fn->kind == FN_ARM ? -0.02f : -slack);
        }
        if (!keep) continue;
        for (int d = 0; d < 3; d++) {
            lo[d] = any ? fminf(lo[d], p[d]) : p[d];
            hi[d] = any ? fmaxf(hi[d], p[d]) : p[d];
        }
        any = 1;
    }
    return any;
}

typedef struct env_ctx {
    const envelope *e;
} env_ctx;

static float env_sample(void *vctx, const float p[3]) {
    return envelope_field(((const env_ctx *)vctx)->e, p);
}

/* The type's field on a grid aligned to multiples of h (so two garments
 * sample the body at the same points and nested levels stay nested). */
static cr_status sample_field(const cr_garment_def *def, const gbody *b, const gspec *sp, gfield *f,
                              cr_error *err) {
    const float h = def->grid_m, s = b->scale;
    float lo[3] = {0}, hi[3] = {0}, tlo[3] = {0}, thi[3] = {0};
    int have = 0;
    envelope env = {0};
    if (sp->tight) {
        if (!tight_box(b, sp, sp->clearance + 2.0f * h, tlo, thi))
            return CR_FAIL(err, CR_ERR_TOPOLOGY,
                           "garment %s: no part of the body lies where the garment goes",
                           cr_garment_type_name(def->type));
        for (int d = 0; d < 3; d++) {
            tlo[d] -= sp->clearance + 4.0f * h, thi[d] += sp->clearance + 4.0f * h;
            lo[d] = tlo[d], hi[d] = thi[d];
        }
        have = 1;
    }
    if (sp->loose) {
        float top = sp->waist_y + (sp->tight ? 0.1f * s : 4.0f * h);
        CR_TRY(envelope_build(b, sp, sp->loose_lo - 4.0f * h, top, &env, err));
        float rmax = 0.0f;
        for (int32_t i = 0; i < env.ny * ENV_ANGLES; i++)
            rmax = fmaxf(rmax, env.R[i]);
        float elo[3] = {env.ax - rmax - 3.0f * h, sp->loose_lo - 4.0f * h,
                        env.az - rmax - 3.0f * h};
        float ehi[3] = {env.ax + rmax + 3.0f * h, top, env.az + rmax + 3.0f * h};
        for (int d = 0; d < 3; d++) {
            lo[d] = have ? fminf(lo[d], elo[d]) : elo[d];
            hi[d] = have ? fmaxf(hi[d], ehi[d]) : ehi[d];
        }
    }
    int32_t n[3];
    for (int d = 0; d < 3; d++) {
        f->origin[d] = floorf(lo[d] / h) * h;
        n[d] = (int32_t)ceilf((hi[d] - f->origin[d]) / h) + 1;
    }
    f->nx = n[0], f->ny = n[1], f->nz = n[2], f->h = h;
    int64_t total = (int64_t)n[0] * n[1] * n[2];
    cr_status st = CR_OK;
    if (total > 64 * 1024 * 1024)
        st = CR_FAIL(err, CR_ERR_RANGE,
                     "garment: grid of %d x %d x %d samples is too large; raise grid_m (%g m)",
                     n[0], n[1], n[2], (double)h);
    float *loose = NULL;
    if (st == CR_OK) {
        f->v = cr_malloc((size_t)total * sizeof(float), err);
        if (sp->loose && sp->tight) loose = cr_malloc((size_t)total * sizeof(float), err);
        if (!f->v || (sp->loose && sp->tight && !loose)) st = CR_ERR_MEMORY;
    }
    cr_iso_grid g = {.nx = n[0], .ny = n[1], .nz = n[2], .spacing = h};
    memcpy(g.origin, f->origin, sizeof g.origin);
    if (st == CR_OK && sp->tight)
        st = cr_garment_distance_field(b, tlo, thi, sp->clearance, f, err);
    if (st == CR_OK && sp->loose) {
        env_ctx c = {&env};
        st = cr_isosurface_sample(&g, env_sample, &c, loose ? loose : f->v, err);
    }
    if (st == CR_OK && loose) {
        /* Dress: the top above the waist, the envelope below, blended. */
        const float k = 0.03f * s, ramp = 2.0f;
        for (int32_t z = 0; z < n[2]; z++)
            for (int32_t y = 0; y < n[1]; y++) {
                float py = f->origin[1] + h * (float)y;
                float up = ramp * fmaxf(py - sp->waist_y, 0.0f);
                float down = ramp * fmaxf(sp->waist_y - py, 0.0f);
                size_t row = (size_t)n[0] * ((size_t)y + (size_t)n[1] * (size_t)z);
                for (int32_t x = 0; x < n[0]; x++)
                    f->v[row + x] = smin(f->v[row + x] + down, loose[row + x] + up, k);
            }
    }
    free(loose);
    free(env.R);
    if (st != CR_OK) {
        free(f->v);
        f->v = NULL;
    }
    return st;
}

/* Arm weights at the surface's vertices, from the closest body points,
 * smoothed over the surface so the armhole is a smooth curve. */
static cr_status surface_arm_weights(const gbody *b, const cr_mesh *m, float *w, cr_error *err) {
    int32_t *face = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    float *bary = cr_malloc((size_t)m->nv * 3 * sizeof(float), err);
    float *next = cr_malloc((size_t)m->nv * 2 * sizeof(float), err);
    cr_topology *t = NULL;
    cr_status st = face && bary && next ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_topology_build(m, &t, err);
    if (st == CR_OK) {
        cr_bvh_closest_batch(b->bvh, m->pos, m->nv, INFINITY, face, NULL, bary, NULL);
        const int32_t *btri = b->model->rest->tri;
        for (int32_t v = 0; v < m->nv; v++) {
            w[2 * v] = w[2 * v + 1] = 0.0f;
            for (int k = 0; k < 3 && face[v] >= 0; k++) {
                int32_t bv = btri[3 * face[v] + k];
                w[2 * v] += bary[3 * v + k] * b->arm_w[2 * bv];
                w[2 * v + 1] += bary[3 * v + k] * b->arm_w[2 * bv + 1];
            }
        }
        for (int pass = 0; pass < WEIGHT_SMOOTH_PASSES; pass++) {
            for (int32_t v = 0; v < m->nv; v++) {
                float sum[2] = {0, 0};
                int32_t cnt = t->vv_off[v + 1] - t->vv_off[v];
                for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++)
                    sum[0] += w[2 * t->vv[q]], sum[1] += w[2 * t->vv[q] + 1];
                for (int k = 0; k < 2; k++)
                    next[2 * v + k] =
                        cnt ? 0.5f * w[2 * v + k] + 0.5f * sum[k] / (float)cnt : w[2 * v + k];
            }
            memcpy(w, next, (size_t)m->nv * 2 * sizeof(float));
        }
    }
    cr_topology_destroy(t);
    free(face);
    free(bary);
    free(next);
    return st;
}

/* Polygonise, evaluate the cut and seam functions at the vertices, cut. */
static cr_status cut_surface(const gbody *b, const gspec *sp, const gfield *f, gcutmesh *cm,
                             cr_error *err) {
    cr_iso_grid g = {.nx = f->nx, .ny = f->ny, .nz = f->nz, .spacing = f->h, .values = f->v};
    memcpy(g.origin, f->origin, sizeof g.origin);
    cr_mesh *mc = NULL;
    CR_TRY(cr_isosurface_extract(&g, 0.0f, &mc, err));
    const int32_t K = sp->ncut + sp->nseam;
    memset(cm, 0, sizeof *cm);
    cm->nfield = K;
    cm->nv = cm->cap_v = mc->nv;
    cm->nf = cm->cap_f = mc->nf;
    cm->pos = mc->pos, mc->pos = NULL;
    cm->tri = mc->tri, mc->tri = NULL;
    cm->val = cr_malloc((size_t)mc->nv * (size_t)(K > 0 ? K : 1) * sizeof(float), err);
    float *w = cr_malloc((size_t)mc->nv * 2 * sizeof(float), err);
    cr_status st = cm->val && w ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK && mc->nf == 0)
        st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: the level set around the body is empty");
    if (st == CR_OK) {
        /* surface_arm_weights reads the mesh: lend it the arrays back. */
        mc->pos = cm->pos, mc->tri = cm->tri;
        st = surface_arm_weights(b, mc, w, err);
        mc->pos = NULL, mc->tri = NULL;
    }
    for (int32_t v = 0; st == CR_OK && v < cm->nv; v++)
        for (int k = 0; k < K; k++) {
            const gfn *fn = k < sp->ncut ? &sp->cut[k] : &sp->seam[k - sp->ncut];
            cm->val[(size_t)v * K + k] = fn_eval(fn, &cm->pos[3 * (size_t)v], &w[2 * v]);
        }
    cr_mesh_destroy(mc);
    free(w);
    const float eps = 1e-4f * f->h;
    for (int k = 0; st == CR_OK && k < sp->ncut; k++) {
        st = cr_gcut_split(cm, k, eps, err);
        if (st == CR_OK) cr_gcut_remove_negative(cm, k);
    }
    if (st == CR_OK) st = cr_gcut_keep_largest(cm, err);
    /* The head falls away at the neckline; a garment still above the head
     * joint (the skull's base) closed over it: met on an SMPL-style body
     * whose joints were the means of the vertices nearest them (on the
     * skin's near side), where the neckline's sphere missed the neck. */
    const float head_y = joint(b, CR_JOINT_HEAD)[1];
    float top = -INFINITY;
    for (int32_t v = 0; st == CR_OK && v < cm->nv; v++)
        top = fmaxf(top, cm->pos[3 * (size_t)v + 1]);
    if (st == CR_OK && top > head_y) {
        cr_bvh_hit hit;
        cr_bvh_closest(b->bvh, joint(b, CR_JOINT_NECK), INFINITY, &hit);
        st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                     "garment: the neckline did not open on this body: the garment reaches "
                     "%.0f mm above the head joint (the neckline is a sphere 55 mm above the "
                     "neck joint, sized by the joint's %.1f mm to the skin: are the neck and "
                     "head joints inside the neck and at the skull's base?)",
                     1e3 * (top - head_y), 1e3 * hit.distance);
    }
    for (int k = 0; st == CR_OK && k < sp->nseam; k++)
        st = cr_gcut_split(cm, sp->ncut + k, eps, err);
    if (st == CR_OK && cm->nf == 0)
        st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: the cuts leave nothing of the surface");
    return st;
}

cr_status cr_garment_build_base(const cr_garment_def *def, const gbody *b, gbase *out,
                                cr_error *err) {
    memset(out, 0, sizeof *out);
    gspec sp;
    spec_build(def, b, &sp);
    CR_TRY(sample_field(def, b, &sp, &out->field, err));
    gcutmesh cm = {0};
    cr_status st = cut_surface(b, &sp, &out->field, &cm, err);
    if (st == CR_OK) st = cr_mesh_create(cm.nv, cm.nf, 0, &out->mesh, err);
    if (st == CR_OK) {
        out->panel = cr_malloc((size_t)cm.nf * sizeof(int32_t), err);
        if (!out->panel) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) {
        memcpy(out->mesh->pos, cm.pos, (size_t)cm.nv * 3 * sizeof(float));
        memcpy(out->mesh->tri, cm.tri, (size_t)cm.nf * 3 * sizeof(int32_t));
        for (int32_t v = 0; v < cm.nv; v++)
            cr_gfield_project(&out->field, &out->mesh->pos[3 * (size_t)v]);
        int32_t count[CR_GARMENT_MAX_PANELS] = {0};
        for (int32_t f = 0; f < cm.nf; f++) {
            int bits = 0;
            for (int k = 0; k < sp.nseam; k++)
                bits |= (cr_gcut_face_sign(&cm, f, sp.ncut + k) > 0) << k;
            out->panel[f] = sp.panel_of[bits];
            count[out->panel[f]]++;
        }
        out->npanels = sp.npanel;
        for (int p = 0; p < sp.npanel; p++) {
            snprintf(out->panel_name[p], sizeof out->panel_name[p], "%s", sp.names[p]);
            if (count[p] == 0 && st == CR_OK)
                st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                             "garment %s: panel '%s' is empty on this body (its seams miss the "
                             "surface)",
                             cr_garment_type_name(def->type), sp.names[p]);
        }
        out->loose = sp.loose;
    }
    cr_gcut_free(&cm);
    cr_topology *t = NULL;
    if (st == CR_OK) st = cr_topology_build(out->mesh, &t, err);
    if (st == CR_OK) st = cr_topology_require_manifold(t, "garment surface", err);
    if (st == CR_OK && t->nloop == 0)
        st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment %s: the cut surface has no opening",
                     cr_garment_type_name(def->type));
    cr_topology_destroy(t);
    if (st != CR_OK) cr_gbase_free(out);
    return st;
}
