/* structures.c: the drape method's local structures (sec. 3.3, Fig. 3, 5, 6)
 * and its four losses as fused tape ops with analytic backward: strain
 * (eq. 19) over an edge list, bend (eq. 22) over a hinge list, gravity
 * (eq. 24) and collision (eq. 26) per point. The same ops serve the local
 * structures and the mesh variants' edges, hinges and vertices.
 *
 * Geometry of a structure (the paper's figure leaves the layout to the
 * reader; this is the one its text describes): the central equilateral
 * triangle ABC has its centroid at the sample point, side s, and its vertex A
 * at angle theta + pi/2; the three outer triangles share an edge with it and
 * have apexes D = B + C - A, E = C + A - B, F = A + B - C (the reflections of
 * A, B, C through the opposite edges' midpoints). That gives six vertices,
 * nine edges (the immediate edge set of Fig. 5) and three face pairs across
 * BC, CA and AB (Fig. 6). A rotation by 2 pi/3 maps the structure onto
 * itself, hence theta in [0, 2 pi/3).
 *
 * Backward passes scatter into shared vertices, so they run serially (a few
 * tens of thousands of elements: well under a millisecond); forward passes
 * and the collision's BVH queries run on cr_parallel_for.
 *
 * Leaves out: the paper's eq. 18 (unscaled strain) and eq. 21 (area-weighted
 * bend): eq. 19 and 22 are the forms the paper uses.
 */
#include "drape_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* P points, E edges, H hinges, N structures. */

const int32_t cr_drape_struct_edges[CR_DRAPE_STRUCT_EDGES][2] = {
    {0, 1}, {1, 2}, {2, 0}, {1, 3}, {3, 2}, {2, 4}, {4, 0}, {0, 5}, {5, 1}};
const int32_t cr_drape_struct_hinges[CR_DRAPE_STRUCT_HINGES][4] = {
    {1, 2, 0, 3}, {2, 0, 1, 4}, {0, 1, 2, 5}};

void cr_drape_structures(const float *centre, const float *theta, int64_t n, float side,
                         float *uv) {
    const double r = side / sqrt(3.0); /* centroid to vertex */
    for (int64_t k = 0; k < n; k++) {
        double c[2] = {centre[2 * k], centre[2 * k + 1]}, v[6][2];
        for (int i = 0; i < 3; i++) {
            double a = theta[k] + M_PI / 2 + i * (2.0 * M_PI / 3.0);
            v[i][0] = c[0] + r * cos(a);
            v[i][1] = c[1] + r * sin(a);
        }
        for (int i = 0; i < 3; i++) /* apex opposite vertex i: sum of the others minus it */
            for (int d = 0; d < 2; d++)
                v[3 + i][d] = v[(i + 1) % 3][d] + v[(i + 2) % 3][d] - v[i][d];
        for (int i = 0; i < 6; i++) {
            uv[12 * k + 2 * i] = (float)v[i][0];
            uv[12 * k + 2 * i + 1] = (float)v[i][1];
        }
    }
}

/* ------------------------------------------------------ op plumbing -- */

/* Everything one op call needs, in step memory (the fused-op def must live
 * until the context is reset). */
typedef struct loss_op {
    cr_fused_op op;
    const int32_t *index; /* edges (E,2) or hinges (H,4) */
    const float *rest;    /* (E) */
    int64_t n;            /* elements */
    float mass, g;        /* gravity */
    const cr_bvh *bvh;    /* collision */
    cr_drape_collision_mode mode;
    float eps;
    float lo[3], hi[3]; /* object box grown by eps */
} loss_op;

static loss_op *op_new(cr_nn_ctx *ctx, const char *name, cr_fused_forward_fn fwd,
                       cr_fused_backward_fn bwd) {
    loss_op *o = cr_nn_scratch(ctx, name, sizeof *o);
    if (!o) return NULL;
    memset(o, 0, sizeof *o);
    o->op = (cr_fused_op){.name = name, .forward = fwd, .backward = bwd, .user = o};
    return o;
}

static int32_t *copy_index(cr_nn_ctx *ctx, const char *name, const int32_t *idx, int64_t count) {
    int32_t *c = cr_nn_scratch(ctx, name, (size_t)count * sizeof(int32_t) + 1);
    if (c && count) memcpy(c, idx, (size_t)count * sizeof(int32_t));
    return c;
}

static cr_status check_points(const char *name, cr_tensor *const *in, int nin, cr_error *err) {
    if (nin != 1 || in[0]->ndim != 2 || in[0]->shape[1] != 3) {
        char s[64];
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: x must be (P,3), got %s", name,
                       cr_nn_shape_str(in[0], s, sizeof s));
    }
    return CR_OK;
}

static cr_status check_index(const char *name, const int32_t *idx, int64_t count, int64_t np,
                             cr_error *err) {
    for (int64_t k = 0; k < count; k++)
        if (idx[k] < 0 || idx[k] >= np)
            return CR_FAIL(err, CR_ERR_RANGE, "%s: index %d of element %lld outside [0,%lld)", name,
                           idx[k], (long long)k, (long long)np);
    return CR_OK;
}

static inline void sub3(const float *a, const float *b, double d[3]) {
    d[0] = (double)a[0] - b[0], d[1] = (double)a[1] - b[1], d[2] = (double)a[2] - b[2];
}
static inline void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

typedef struct range_job {
    const loss_op *o;
    const float *x;
    float *out;
    float *stash;
} range_job;

/* ------------------------------------------------------------ strain -- */

static void strain_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    for (int64_t e = begin; e < end; e++) {
        double d[3];
        sub3(&j->x[3 * (int64_t)j->o->index[2 * e]], &j->x[3 * (int64_t)j->o->index[2 * e + 1]], d);
        double L = j->o->rest[e], r = (sqrt(dot3(d, d)) - L) / L;
        j->out[e] = (float)(r * r);
    }
}

static cr_status strain_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                int nin, cr_tensor *const *out, int nout, void **stash,
                                cr_error *err) {
    (void)ctx, (void)nout, (void)stash;
    const loss_op *o = op->user;
    CR_TRY(check_points("drape_strain", in, nin, err));
    CR_TRY(check_index("drape_strain", o->index, 2 * o->n, in[0]->shape[0], err));
    for (int64_t e = 0; e < o->n; e++)
        if (!(o->rest[e] > 0.0f) || !isfinite(o->rest[e]))
            return CR_FAIL(err, CR_ERR_INVALID, "drape_strain: rest length of edge %lld is %g",
                           (long long)e, (double)o->rest[e]);
    range_job j = {.o = o, .x = in[0]->data, .out = out[0]->data};
    cr_parallel_for(o->n, 4096, strain_range, &j);
    return CR_OK;
}

/* d/dxi ((l - L)/L)^2 = 2 (l - L) / L^2 * (xi - xj) / l; xj gets the negative. */
static cr_status strain_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                 int nin, cr_tensor *const *out, int nout, void *stash,
                                 cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    const loss_op *o = op->user;
    const float *x = in[0]->data, *gout = out[0]->grad;
    float *gx = in[0]->grad;
    for (int64_t e = 0; e < o->n; e++) {
        int64_t a = o->index[2 * e], b = o->index[2 * e + 1];
        double d[3];
        sub3(&x[3 * a], &x[3 * b], d);
        double L = o->rest[e], l = sqrt(dot3(d, d));
        if (l <= 0.0) continue; /* coincident ends: no direction to push along */
        double s = gout[e] * 2.0 * (l - L) / (L * L * l);
        for (int c = 0; c < 3; c++) {
            gx[3 * a + c] += (float)(s * d[c]);
            gx[3 * b + c] -= (float)(s * d[c]);
        }
    }
    return CR_OK;
}

cr_tensor *cr_drape_strain(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *edges, const float *rest,
                           int64_t ne) {
    if (!x) return NULL;
    loss_op *o = op_new(ctx, "drape_strain", strain_forward, strain_backward);
    if (!o) return NULL;
    int32_t *idx = copy_index(ctx, "drape_strain", edges, 2 * ne);
    float *r = cr_nn_scratch(ctx, "drape_strain", (size_t)ne * sizeof(float) + 1);
    if (!idx || !r) return NULL;
    if (ne) memcpy(r, rest, (size_t)ne * sizeof(float));
    o->index = idx, o->rest = r, o->n = ne;
    cr_nn_shape shape = {.ndim = 1, .d = {ne}};
    return cr_nn_fused(ctx, &o->op, 1, &x, 1, &shape, NULL);
}

/* -------------------------------------------------------------- bend -- */

/* Unit normals of face A = (x0,x1,x2) and B = (x1,x0,x3) with the unnormalised
 * normals' lengths; 0 when a face is degenerate. */
static int hinge_normals(const float *x, const int32_t *h, double mA[3], double mB[3], double *lA,
                         double *lB) {
    const float *x0 = &x[3 * (int64_t)h[0]], *x1 = &x[3 * (int64_t)h[1]];
    double a[3], b[3], c[3], e[3];
    sub3(x1, x0, a), sub3(&x[3 * (int64_t)h[2]], x0, b);
    sub3(x0, x1, c), sub3(&x[3 * (int64_t)h[3]], x1, e);
    cross3(a, b, mA), cross3(c, e, mB);
    *lA = sqrt(dot3(mA, mA)), *lB = sqrt(dot3(mB, mB));
    return *lA > 0.0 && *lB > 0.0;
}

static void bend_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    for (int64_t k = begin; k < end; k++) {
        double mA[3], mB[3], lA, lB, s = 0.0;
        if (hinge_normals(j->x, &j->o->index[4 * k], mA, mB, &lA, &lB))
            for (int c = 0; c < 3; c++) {
                double d = mA[c] / lA - mB[c] / lB;
                s += d * d;
            }
        j->out[k] = (float)s;
    }
}

static cr_status bend_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                              cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)ctx, (void)nout, (void)stash;
    const loss_op *o = op->user;
    CR_TRY(check_points("drape_bend", in, nin, err));
    CR_TRY(check_index("drape_bend", o->index, 4 * o->n, in[0]->shape[0], err));
    range_job j = {.o = o, .x = in[0]->data, .out = out[0]->data};
    cr_parallel_for(o->n, 2048, bend_range, &j);
    return CR_OK;
}

/* dL/dm = (I - n n^T) dL/dn / |m| for n = m/|m|; for m = a x b,
 * dL/da = b x dL/dm and dL/db = dL/dm x a. */
static void cross_backward(const double m[3], double len, const double gn[3], const double a[3],
                           const double b[3], double ga[3], double gb[3]) {
    double n[3] = {m[0] / len, m[1] / len, m[2] / len}, gm[3];
    double nd = dot3(n, gn);
    for (int c = 0; c < 3; c++)
        gm[c] = (gn[c] - n[c] * nd) / len;
    cross3(b, gm, ga);
    cross3(gm, a, gb);
}

static cr_status bend_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                               cr_tensor *const *out, int nout, void *stash, cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    const loss_op *o = op->user;
    const float *x = in[0]->data, *gout = out[0]->grad;
    float *gx = in[0]->grad;
    for (int64_t k = 0; k < o->n; k++) {
        const int32_t *h = &o->index[4 * k];
        double mA[3], mB[3], lA, lB;
        if (!hinge_normals(x, h, mA, mB, &lA, &lB)) continue;
        double gnA[3], gnB[3];
        for (int c = 0; c < 3; c++) {
            gnA[c] = 2.0 * gout[k] * (mA[c] / lA - mB[c] / lB);
            gnB[c] = -gnA[c];
        }
        const float *x0 = &x[3 * (int64_t)h[0]], *x1 = &x[3 * (int64_t)h[1]];
        double a[3], b[3], c[3], e[3], ga[3], gb[3], gc[3], ge[3];
        sub3(x1, x0, a), sub3(&x[3 * (int64_t)h[2]], x0, b);
        sub3(x0, x1, c), sub3(&x[3 * (int64_t)h[3]], x1, e);
        cross_backward(mA, lA, gnA, a, b, ga, gb); /* a = x1 - x0, b = x2 - x0 */
        cross_backward(mB, lB, gnB, c, e, gc, ge); /* c = x0 - x1, e = x3 - x1 */
        for (int d = 0; d < 3; d++) {
            gx[3 * (int64_t)h[0] + d] += (float)(-ga[d] - gb[d] + gc[d]);
            gx[3 * (int64_t)h[1] + d] += (float)(ga[d] - gc[d] - ge[d]);
            gx[3 * (int64_t)h[2] + d] += (float)gb[d];
            gx[3 * (int64_t)h[3] + d] += (float)ge[d];
        }
    }
    return CR_OK;
}

cr_tensor *cr_drape_bend(cr_nn_ctx *ctx, cr_tensor *x, const int32_t *hinges, int64_t nh) {
    if (!x) return NULL;
    loss_op *o = op_new(ctx, "drape_bend", bend_forward, bend_backward);
    if (!o) return NULL;
    int32_t *idx = copy_index(ctx, "drape_bend", hinges, 4 * nh);
    if (!idx) return NULL;
    o->index = idx, o->n = nh;
    cr_nn_shape shape = {.ndim = 1, .d = {nh}};
    return cr_nn_fused(ctx, &o->op, 1, &x, 1, &shape, NULL);
}

/* ----------------------------------------------------------- gravity -- */

static cr_status gravity_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                 int nin, cr_tensor *const *out, int nout, void **stash,
                                 cr_error *err) {
    (void)ctx, (void)nout, (void)stash;
    const loss_op *o = op->user;
    CR_TRY(check_points("drape_gravity", in, nin, err));
    const float *x = in[0]->data;
    for (int64_t p = 0; p < in[0]->shape[0]; p++)
        out[0]->data[p] = o->mass * o->g * x[3 * p + 1];
    return CR_OK;
}

static cr_status gravity_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                  int nin, cr_tensor *const *out, int nout, void *stash,
                                  cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)stash, (void)err;
    const loss_op *o = op->user;
    for (int64_t p = 0; p < in[0]->shape[0]; p++)
        in[0]->grad[3 * p + 1] += o->mass * o->g * out[0]->grad[p];
    return CR_OK;
}

cr_tensor *cr_drape_gravity(cr_nn_ctx *ctx, cr_tensor *x, float mass, float g) {
    if (!x) return NULL;
    loss_op *o = op_new(ctx, "drape_gravity", gravity_forward, gravity_backward);
    if (!o) return NULL;
    o->mass = mass, o->g = g;
    cr_nn_shape shape = {.ndim = 1, .d = {x->shape[0]}};
    return cr_nn_fused(ctx, &o->op, 1, &x, 1, &shape, NULL);
}

/* --------------------------------------------------------- collision -- */

/* stash (P,4): the direction along which s grows (n), then s; s = +inf where
 * the point skipped the search. */
static void collision_range(void *p, int64_t begin, int64_t end) {
    const range_job *j = p;
    const loss_op *o = j->o;
    const float *vpos = cr_bvh_positions(o->bvh), *vnrm = cr_bvh_vertex_normals(o->bvh);
    for (int64_t k = begin; k < end; k++) {
        const float *x = &j->x[3 * k];
        float *st = &j->stash[4 * k];
        st[0] = st[1] = st[2] = 0.0f, st[3] = INFINITY;
        j->out[k] = 0.0f;
        int outside = 0;
        for (int c = 0; c < 3; c++)
            outside |= x[c] < o->lo[c] || x[c] > o->hi[c];
        if (outside) continue;
        double s;
        if (o->mode == CR_DRAPE_COLLIDE_VERTEX) {
            int32_t v = cr_bvh_nearest_vertex(o->bvh, x, INFINITY, NULL);
            if (v < 0) continue;
            double d[3];
            sub3(x, &vpos[3 * (int64_t)v], d);
            const float *n = &vnrm[3 * (int64_t)v];
            s = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            memcpy(st, n, 3 * sizeof(float));
        } else {
            float dist, nrm[3];
            cr_bvh_hit hit;
            if (!cr_bvh_signed_distance(o->bvh, x, INFINITY, &dist, nrm, &hit)) continue;
            s = dist;
            /* grad of the signed distance: away from the closest point, times the sign;
             * the pseudo-normal where the point sits on the surface */
            double d[3];
            sub3(x, hit.point, d);
            double l = sqrt(dot3(d, d)), sg = dist < 0 ? -1.0 : 1.0;
            for (int c = 0; c < 3; c++)
                st[c] = l > 1e-9 ? (float)(sg * d[c] / l) : nrm[c];
        }
        st[3] = (float)s;
        double m = s - o->eps < 0.0 ? s - o->eps : 0.0;
        j->out[k] = (float)(m * m);
    }
}

static cr_status collision_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                   int nin, cr_tensor *const *out, int nout, void **stash,
                                   cr_error *err) {
    (void)nout;
    const loss_op *o = op->user;
    CR_TRY(check_points("drape_collision", in, nin, err));
    int64_t np = in[0]->shape[0];
    float *st = cr_nn_scratch(ctx, "drape_collision", (size_t)np * 4 * sizeof(float) + 1);
    if (!st)
        return CR_FAIL(err, CR_ERR_MEMORY, "drape_collision: no room for %lld points",
                       (long long)np);
    range_job j = {.o = o, .x = in[0]->data, .out = out[0]->data, .stash = st};
    cr_parallel_for(np, 256, collision_range, &j);
    *stash = st;
    return CR_OK;
}

/* d/dx min(s - eps, 0)^2 = 2 min(s - eps, 0) ds/dx, ds/dx the stashed direction
 * (the nearest vertex is held fixed: the loss is piecewise smooth in x). */
static cr_status collision_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                    int nin, cr_tensor *const *out, int nout, void *stash,
                                    cr_error *err) {
    (void)ctx, (void)nin, (void)nout, (void)err;
    const loss_op *o = op->user;
    const float *st = stash;
    for (int64_t k = 0; k < in[0]->shape[0]; k++) {
        double m = (double)st[4 * k + 3] - o->eps;
        if (!(m < 0.0)) continue;
        double s = 2.0 * m * out[0]->grad[k];
        for (int c = 0; c < 3; c++)
            in[0]->grad[3 * k + c] += (float)(s * st[4 * k + c]);
    }
    return CR_OK;
}

cr_tensor *cr_drape_collision(cr_nn_ctx *ctx, cr_tensor *x, const cr_bvh *object,
                              cr_drape_collision_mode mode, float eps) {
    if (!x) return NULL;
    loss_op *o = op_new(ctx, "drape_collision", collision_forward, collision_backward);
    if (!o) return NULL;
    o->bvh = object, o->mode = mode, o->eps = eps;
    const float *pos = cr_bvh_positions(object);
    int32_t nv = cr_bvh_vertex_count(object);
    for (int c = 0; c < 3; c++)
        o->lo[c] = INFINITY, o->hi[c] = -INFINITY;
    for (int32_t v = 0; v < nv; v++)
        for (int c = 0; c < 3; c++) {
            o->lo[c] = fminf(o->lo[c], pos[3 * v + c]);
            o->hi[c] = fmaxf(o->hi[c], pos[3 * v + c]);
        }
    float grow = fabsf(eps);
    for (int c = 0; c < 3; c++)
        o->lo[c] -= grow, o->hi[c] += grow;
    cr_nn_shape shape = {.ndim = 1, .d = {x->shape[0]}};
    return cr_nn_fused(ctx, &o->op, 1, &x, 1, &shape, NULL);
}

/* --------------------------------------------------------- batches -- */

cr_status cr_drape_batch_alloc(drape_batch *b, int64_t cap, cr_error *err) {
    memset(b, 0, sizeof *b);
    b->cap = cap;
    b->uv = cr_malloc((size_t)cap * 12 * sizeof(float), err);
    b->p0 = cr_malloc((size_t)cap * 18 * sizeof(float), err);
    b->rest = cr_malloc((size_t)cap * 9 * sizeof(float), err);
    b->edges = cr_malloc((size_t)cap * 18 * sizeof(int32_t), err);
    b->hinges = cr_malloc((size_t)cap * 12 * sizeof(int32_t), err);
    b->source = cr_malloc((size_t)cap * sizeof(int32_t), err);
    b->all_uv = cr_malloc((size_t)cap * 12 * sizeof(float), err);
    b->all_p0 = cr_malloc((size_t)cap * 18 * sizeof(float), err);
    b->valid = cr_malloc((size_t)cap * 6, err);
    if (!b->uv || !b->p0 || !b->rest || !b->edges || !b->hinges || !b->source || !b->all_uv ||
        !b->all_p0 || !b->valid) {
        cr_drape_batch_free(b);
        return CR_ERR_MEMORY;
    }
    return CR_OK;
}

void cr_drape_batch_free(drape_batch *b) {
    free(b->uv), free(b->p0), free(b->rest), free(b->edges), free(b->hinges), free(b->source);
    free(b->all_uv), free(b->all_p0), free(b->valid);
    memset(b, 0, sizeof *b);
}

void cr_drape_batch_build(drape_batch *b, const cr_drape_model *m, const float *centre,
                          const float *theta, int64_t n, float side, int inset) {
    CR_ASSERT(n <= b->cap);
    float *c = b->all_p0; /* borrowed as centre scratch before the lookups fill it */
    const float *cen = centre;
    if (inset) {
        float r = 2.0f * side / sqrtf(3.0f), span = 1.0f - 2.0f * r;
        for (int64_t k = 0; k < 2 * n; k++)
            c[k] = r + span * centre[k];
        cen = c;
    }
    cr_drape_structures(cen, theta, n, side, b->all_uv);
    cr_drape_model_rest(m, b->all_uv, 6 * n, b->all_p0, b->valid);
    b->n = 0;
    for (int64_t k = 0; k < n; k++) {
        int ok = 1;
        for (int i = 0; i < 6; i++)
            ok &= b->valid[6 * k + i];
        const float *p = &b->all_p0[18 * k];
        float L[9];
        for (int e = 0; ok && e < 9; e++) {
            double d[3];
            sub3(&p[3 * cr_drape_struct_edges[e][0]], &p[3 * cr_drape_struct_edges[e][1]], d);
            L[e] = (float)sqrt(dot3(d, d)); /* eq. 17 */
            ok &= L[e] > 0.0f;
        }
        if (!ok) continue;
        int64_t s = b->n++;
        memcpy(&b->uv[12 * s], &b->all_uv[12 * k], 12 * sizeof(float));
        memcpy(&b->p0[18 * s], p, 18 * sizeof(float));
        memcpy(&b->rest[9 * s], L, sizeof L);
        for (int e = 0; e < 9; e++)
            for (int q = 0; q < 2; q++)
                b->edges[18 * s + 2 * e + q] = (int32_t)(6 * s + cr_drape_struct_edges[e][q]);
        for (int h = 0; h < 3; h++)
            for (int q = 0; q < 4; q++)
                b->hinges[12 * s + 4 * h + q] = (int32_t)(6 * s + cr_drape_struct_hinges[h][q]);
        b->source[s] = (int32_t)k;
    }
}

cr_tensor *cr_drape_batch_loss(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                               cr_tensor *x, cr_tensor **terms_out) {
    const cr_drape_def *d = lc->def;
    cr_tensor *t[4] = {
        cr_drape_strain(ctx, x, b->edges, b->rest, 9 * b->n),
        cr_drape_bend(ctx, x, b->hinges, 3 * b->n),
        cr_drape_gravity(ctx, x, d->point_mass, d->gravity),
        cr_drape_collision(ctx, x, lc->bvh, d->collision, d->collision_eps),
    };
    /* eq. 24 at the structure: the mean height of its six vertices (their
     * centroid is the sample point in UV) */
    const float w[4] = {d->w.strain, d->w.bend, d->w.gravity / 6.0f, d->w.collision};
    cr_tensor *loss = NULL;
    for (int k = 0; k < 4; k++) {
        cr_tensor *s = cr_nn_mul_scalar(ctx, cr_nn_sum(ctx, t[k]), w[k]);
        if (terms_out) terms_out[k] = s;
        loss = k == 0 ? s : cr_nn_add(ctx, loss, s);
    }
    return loss;
}

cr_status cr_drape_batch_eval(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                              const float *x, double sums[4], float *per_structure, cr_error *err) {
    const cr_drape_def *d = lc->def;
    int was = cr_nn_ctx_grad_enabled(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){6 * b->n, 3}, x);
    cr_tensor *t[4] = {
        cr_drape_strain(ctx, xt, b->edges, b->rest, 9 * b->n),
        cr_drape_bend(ctx, xt, b->hinges, 3 * b->n),
        cr_drape_gravity(ctx, xt, d->point_mass, d->gravity),
        cr_drape_collision(ctx, xt, lc->bvh, d->collision, d->collision_eps),
    };
    cr_nn_ctx_set_grad_enabled(ctx, was);
    CR_TRY(cr_nn_ctx_error(ctx, err));
    const double w[4] = {d->w.strain, d->w.bend, d->w.gravity / 6.0, d->w.collision};
    const int per[4] = {9, 3, 6, 6}; /* elements of each term per structure */
    for (int64_t s = 0; s < b->n; s++) {
        double total = 0.0;
        for (int k = 0; k < 4; k++) {
            double acc = 0.0;
            for (int i = 0; i < per[k]; i++)
                acc += t[k]->data[per[k] * s + i];
            sums[k] += w[k] * acc;
            total += w[k] * acc;
        }
        if (per_structure) per_structure[s] = (float)total;
    }
    return CR_OK;
}
