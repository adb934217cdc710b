/* garment_field.c: the sampled level-set field garments are cut from:
 * trilinear evaluation and projection, the body's blurred signed distance
 * on a grid, and the body measurements the garment code shares.
 *
 * The distance is exact (cr_bvh_signed_distance) but only needed in a shell
 * around the clearance: the blur that follows, one pass of [1 2 1]/4 per
 * axis, reaches sqrt(3) cells, so samples within 2 cells of the clearance
 * are queried and the rest clamped. A first pass on every other sample
 * finds most points off the shell (the distance is 1-Lipschitz, so a coarse
 * sample farther off than its distance to a point settles that point), and
 * a flood fill gives each region that no query reached the side of the
 * shell around it (inside the body or outside).
 *
 * Left out: narrow-band fast marching (the BVH answers exactly and fast
 * enough at these grid sizes).
 */
#include "garment_internal.h"

#include "crease/body.h"
#include "crease/isosurface.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Sentinel for grid points with no body surface within reach. */
#define FAR_SENTINEL 1e30f

/* ---------------------------------------------------------------- field -- */

static float clampf(float x, float lo, float hi) {
    return x < lo ? lo : x > hi ? hi : x;
}

float cr_gfield_eval(const gfield *f, const float p[3], float grad[3]) {
    const int32_t n[3] = {f->nx, f->ny, f->nz};
    int32_t i[3];
    float t[3];
    for (int d = 0; d < 3; d++) {
        float x = clampf((p[d] - f->origin[d]) / f->h, 0.0f, (float)(n[d] - 1));
        int32_t c = (int32_t)x;
        if (c > n[d] - 2) c = n[d] - 2;
        i[d] = c, t[d] = x - (float)c;
    }
    float c[8];
    for (int k = 0; k < 8; k++) {
        int32_t x = i[0] + (k & 1), y = i[1] + ((k >> 1) & 1), z = i[2] + (k >> 2);
        c[k] = f->v[(size_t)x + (size_t)f->nx * ((size_t)y + (size_t)f->ny * (size_t)z)];
    }
    float x00 = c[0] + t[0] * (c[1] - c[0]), x10 = c[2] + t[0] * (c[3] - c[2]);
    float x01 = c[4] + t[0] * (c[5] - c[4]), x11 = c[6] + t[0] * (c[7] - c[6]);
    float y0 = x00 + t[1] * (x10 - x00), y1 = x01 + t[1] * (x11 - x01);
    if (grad) {
        float dx00 = c[1] - c[0], dx10 = c[3] - c[2], dx01 = c[5] - c[4], dx11 = c[7] - c[6];
        float dx0 = dx00 + t[1] * (dx10 - dx00), dx1 = dx01 + t[1] * (dx11 - dx01);
        grad[0] = (dx0 + t[2] * (dx1 - dx0)) / f->h;
        grad[1] = ((x10 - x00) + t[2] * ((x11 - x01) - (x10 - x00))) / f->h;
        grad[2] = (y1 - y0) / f->h;
    }
    return y0 + t[2] * (y1 - y0);
}

void cr_gfield_project(const gfield *f, float p[3]) {
    for (int it = 0; it < 8; it++) {
        float g[3], v = cr_gfield_eval(f, p, g);
        float gg = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (fabsf(v) < 1e-6f || gg < 1e-12f) return;
        float s = v / gg;
        /* A step longer than a cell leaves the interpolant's cell: shorten. */
        float len = fabsf(s) * sqrtf(gg);
        if (len > f->h) s *= f->h / len;
        for (int d = 0; d < 3; d++)
            p[d] -= s * g[d];
    }
}

/* ----------------------------------------------------------------- body -- */

cr_status cr_gbody_init(gbody *b, const cr_body_model *model, cr_error *err) {
    memset(b, 0, sizeof *b);
    b->model = model;
    const cr_mesh *m = model->rest;
    CR_TRY(cr_body_model_validate(model, "garment body", err));
    CR_TRY(cr_bvh_build(m->pos, m->nv, m->tri, m->nf, &b->bvh, err));
    cr_mesh_bounds(m, b->lo, b->hi);
    b->scale = (b->hi[1] - b->lo[1]) / 1.75f;
    b->arm_w = cr_calloc((size_t)m->nv * 2, sizeof(float), err);
    if (!b->arm_w) {
        cr_gbody_free(b);
        return CR_ERR_MEMORY;
    }
    for (int32_t v = 0; v < m->nv; v++)
        for (int k = 0; k < 4; k++) {
            int32_t j = model->skin_joint[4 * v + k];
            float w = model->skin_weight[4 * v + k];
            if (j == CR_JOINT_LEFT_SHOULDER || j == CR_JOINT_LEFT_ELBOW || j == CR_JOINT_LEFT_WRIST)
                b->arm_w[2 * v] += w;
            if (j == CR_JOINT_RIGHT_SHOULDER || j == CR_JOINT_RIGHT_ELBOW ||
                j == CR_JOINT_RIGHT_WRIST)
                b->arm_w[2 * v + 1] += w;
        }
    return CR_OK;
}

void cr_gbody_free(gbody *b) {
    cr_bvh_destroy(b->bvh);
    free(b->arm_w);
    memset(b, 0, sizeof *b);
}

/* Circular [1 2 1]/4 smoothing along a row of n values with stride. */
void cr_garment_smooth_line(float *x, int32_t n, int32_t stride, int periodic, float *tmp) {
    for (int32_t i = 0; i < n; i++) {
        int32_t a = i - 1, c = i + 1;
        if (periodic)
            a = (a + n) % n, c = c % n;
        else
            a = a < 0 ? 0 : a, c = c >= n ? n - 1 : c;
        tmp[i] = 0.25f * x[(size_t)a * stride] + 0.5f * x[(size_t)i * stride] +
                 0.25f * x[(size_t)c * stride];
    }
    for (int32_t i = 0; i < n; i++)
        x[(size_t)i * stride] = tmp[i];
}

/* ---------------------------------------------------------- distance -- */

typedef struct sdf_ctx {
    const cr_bvh *bvh;
    float lo, hi;               /* m: distances are clamped to [lo, hi] */
    float box_lo[3], box_hi[3]; /* outside this box the tight field is not needed: hi */
    const gfield *coarse;       /* the clamped distance at every other sample, or NULL */
} sdf_ctx;

static float sdf_sample(void *vctx, const float p[3]) {
    const sdf_ctx *c = vctx;
    for (int d = 0; d < 3; d++)
        if (p[d] < c->box_lo[d] || p[d] > c->box_hi[d]) return c->hi;
    if (c->coarse) {
        /* The distance is 1-Lipschitz: a coarse sample beyond the shell by
         * more than its distance to p (at most sqrt(3) fine cells) settles p. */
        const gfield *g = c->coarse;
        int32_t i[3];
        for (int d = 0; d < 3; d++) {
            float x = (p[d] - g->origin[d]) / g->h + 0.5f;
            int32_t n = d == 0 ? g->nx : d == 1 ? g->ny : g->nz;
            i[d] = x < 0.0f ? 0 : (int32_t)x >= n ? n - 1 : (int32_t)x;
        }
        float v = g->v[(size_t)i[0] + (size_t)g->nx * ((size_t)i[1] + (size_t)g->ny * i[2])];
        float slack = 0.5f * 1.7321f * g->h + 1e-4f;
        if (v == FAR_SENTINEL) return FAR_SENTINEL;
        if (v > c->hi + slack) return c->hi;
        if (v < c->lo - slack) return c->lo;
    }
    float d, reach = fmaxf(c->hi, -c->lo);
    if (!cr_bvh_signed_distance(c->bvh, p, reach, &d, NULL, NULL)) return FAR_SENTINEL;
    return d < c->lo ? c->lo : d > c->hi ? c->hi : d;
}

/* The signed distance clamped to [lo, hi] on f's grid: exact in between,
 * FAR_SENTINEL (side unknown) or the bound beyond, sampled on every other
 * grid point first so most points off the shell need no query. */
static cr_status sample_distance(const gbody *b, const float box_lo[3], const float box_hi[3],
                                 float lo, float hi, gfield *f, cr_error *err) {
    gfield coarse = {
        .h = 2.0f * f->h, .nx = f->nx / 2 + 1, .ny = f->ny / 2 + 1, .nz = f->nz / 2 + 1};
    memcpy(coarse.origin, f->origin, sizeof coarse.origin);
    coarse.v = cr_malloc((size_t)coarse.nx * coarse.ny * coarse.nz * sizeof(float), err);
    if (!coarse.v) return CR_ERR_MEMORY;
    const float slack = 1.7321f * f->h + 2e-4f;
    sdf_ctx cc = {.bvh = b->bvh, .lo = lo - slack, .hi = hi + slack};
    for (int d = 0; d < 3; d++)
        cc.box_lo[d] = box_lo[d] - 2.0f * f->h, cc.box_hi[d] = box_hi[d] + 2.0f * f->h;
    cr_iso_grid cg = {.nx = coarse.nx, .ny = coarse.ny, .nz = coarse.nz, .spacing = coarse.h};
    memcpy(cg.origin, coarse.origin, sizeof cg.origin);
    cr_status st = cr_isosurface_sample(&cg, sdf_sample, &cc, coarse.v, err);
    if (st == CR_OK) {
        sdf_ctx c = {.bvh = b->bvh, .lo = lo, .hi = hi, .coarse = &coarse};
        memcpy(c.box_lo, box_lo, sizeof c.box_lo);
        memcpy(c.box_hi, box_hi, sizeof c.box_hi);
        cr_iso_grid g = {.nx = f->nx, .ny = f->ny, .nz = f->nz, .spacing = f->h};
        memcpy(g.origin, f->origin, sizeof g.origin);
        st = cr_isosurface_sample(&g, sdf_sample, &c, f->v, err);
    }
    free(coarse.v);
    return st;
}

/* Give every connected region of sentinel samples lo or hi, by the side of
 * the level `iso` the samples around it are on (it lies wholly inside or
 * wholly outside). */
static cr_status flood_sides(gfield *f, float iso, float lo, float hi, cr_error *err) {
    const int64_t n = (int64_t)f->nx * f->ny * f->nz;
    int32_t *queue = cr_malloc((size_t)n * sizeof(int32_t), err);
    if (!queue) return CR_ERR_MEMORY;
    const int64_t step[3] = {1, f->nx, (int64_t)f->nx * f->ny};
    const int32_t dim[3] = {f->nx, f->ny, f->nz};
    for (int64_t s = 0; s < n; s++) {
        if (f->v[s] != FAR_SENTINEL) continue;
        int64_t head = 0, tail = 0;
        float value = hi;
        int found = 0;
        queue[tail++] = (int32_t)s;
        f->v[s] = NAN; /* queued */
        while (head < tail) {
            int64_t q = queue[head++];
            int32_t c[3] = {(int32_t)(q % f->nx), (int32_t)((q / f->nx) % f->ny),
                            (int32_t)(q / step[2])};
            for (int d = 0; d < 3; d++)
                for (int dir = -1; dir <= 1; dir += 2) {
                    int32_t cc = c[d] + dir;
                    if (cc < 0 || cc >= dim[d]) continue;
                    int64_t nb = q + dir * step[d];
                    float v = f->v[nb];
                    if (v == FAR_SENTINEL) {
                        f->v[nb] = NAN;
                        queue[tail++] = (int32_t)nb;
                    } else if (!isnan(v) && !found) {
                        value = v < iso ? lo : hi;
                        found = 1;
                    }
                }
        }
        for (int64_t i = 0; i < tail; i++)
            f->v[queue[i]] = value;
    }
    free(queue);
    return CR_OK;
}

/* One pass of [1 2 1]/4 along each axis, edges clamped. */
static cr_status blur_grid(gfield *f, cr_error *err) {
    int32_t dim[3] = {f->nx, f->ny, f->nz}, big = f->nx;
    if (f->ny > big) big = f->ny;
    if (f->nz > big) big = f->nz;
    float *tmp = cr_malloc((size_t)big * sizeof(float), err);
    if (!tmp) return CR_ERR_MEMORY;
    const int64_t stride[3] = {1, f->nx, (int64_t)f->nx * f->ny};
    for (int d = 0; d < 3; d++) {
        int a = (d + 1) % 3, c = (d + 2) % 3;
        for (int32_t i = 0; i < dim[a]; i++)
            for (int32_t j = 0; j < dim[c]; j++)
                cr_garment_smooth_line(&f->v[i * stride[a] + j * stride[c]], dim[d],
                                       (int32_t)stride[d], 0, tmp);
    }
    free(tmp);
    return CR_OK;
}

cr_status cr_garment_distance_field(const gbody *b, const float box_lo[3], const float box_hi[3],
                                    float clearance, gfield *f, cr_error *err) {
    const float h = f->h, lo = clearance - 2.0f * h, hi = clearance + 2.0f * h;
    cr_status st = sample_distance(b, box_lo, box_hi, lo, hi, f, err);
    if (st == CR_OK) st = flood_sides(f, clearance, lo, hi, err);
    if (st == CR_OK) st = blur_grid(f, err);
    const int64_t n = (int64_t)f->nx * f->ny * f->nz;
    for (int64_t i = 0; st == CR_OK && i < n; i++)
        f->v[i] -= clearance;
    return st;
}
