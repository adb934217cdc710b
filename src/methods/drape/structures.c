/* structures.c: the drape method's local structures (sec. 3.3, Fig. 3, 5, 6)
 * and its four losses over them: strain (eq. 19) over the structures' edges,
 * bend (eq. 22) over their face pairs, gravity (eq. 24) and collision
 * (eq. 26) per point. The losses are energies of phys/ (drape_strain.c,
 * drape_bend.c, drape_gravity.c, drape_collision.c) on the tape through the
 * generic loss op (losses.h); the same terms serve the local structures and
 * the mesh variants' edges, hinges and vertices, and one weighted sum
 * (cr_loss_weighted_sum) builds the loss everywhere.
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
 * Leaves out: the paper's eq. 18 (unscaled strain) and eq. 21 (area-weighted
 * bend): eq. 19 and 22 are the forms the paper uses.
 */
#include "drape_internal.h"

#include "crease/losses.h"

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

static inline void sub3(const float *a, const float *b, double d[3]) {
    d[0] = (double)a[0] - b[0], d[1] = (double)a[1] - b[1], d[2] = (double)a[2] - b[2];
}
static inline double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* ---------------------------------------------------------- losses -- */

cr_status cr_drape_loss_ctx_create(const cr_drape_def *def, const cr_bvh *object,
                                   drape_loss_ctx *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    out->def = def;
    cr_status st = cr_drape_gravity_create(def->point_mass, def->gravity, &out->gravity, err);
    if (st == CR_OK)
        st = cr_drape_collision_create(object, def->collision, def->collision_eps, &out->collision,
                                       err);
    if (st != CR_OK) cr_drape_loss_ctx_free(out);
    return st;
}

void cr_drape_loss_ctx_free(drape_loss_ctx *lc) {
    cr_drape_gravity_destroy(lc->gravity);
    cr_drape_collision_destroy(lc->collision);
    memset(lc, 0, sizeof *lc);
}

void cr_drape_loss_terms(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const cr_drape_strain *strain,
                         const cr_drape_bend *bend, cr_tensor *x, int per_element,
                         cr_tensor *t[4]) {
    cr_energy_term e[4];
    const int32_t np = x ? (int32_t)x->shape[0] : 0;
    cr_drape_gravity_set_count(lc->gravity, np);
    cr_drape_collision_set_count(lc->collision, np);
    cr_drape_strain_term(strain, &e[0]);
    cr_drape_bend_term(bend, &e[1]);
    cr_drape_gravity_term(lc->gravity, &e[2]);
    cr_drape_collision_term(lc->collision, &e[3]);
    for (int k = 0; k < 4; k++)
        t[k] =
            per_element ? cr_loss_energy_per_element(ctx, &e[k], x) : cr_loss_energy(ctx, &e[k], x);
}

void cr_drape_loss_weights(const cr_drape_weights *w, int per_structure, float out[4]) {
    out[0] = w->strain, out[1] = w->bend;
    out[2] = per_structure ? w->gravity / 6.0f : w->gravity;
    out[3] = w->collision;
}

/* --------------------------------------------------------- batches -- */

cr_status cr_drape_batch_alloc(drape_batch *b, int64_t cap, cr_error *err) {
    memset(b, 0, sizeof *b);
    if (cap > INT32_MAX / 18)
        return CR_FAIL(err, CR_ERR_RANGE, "drape: %lld structures per batch is too many",
                       (long long)cap);
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
    cr_status st = CR_OK;
    if (!b->uv || !b->p0 || !b->rest || !b->edges || !b->hinges || !b->source || !b->all_uv ||
        !b->all_p0 || !b->valid)
        st = CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_drape_strain_create((int32_t)(9 * cap), &b->strain, err);
    if (st == CR_OK) st = cr_drape_bend_create((int32_t)(3 * cap), &b->bend, err);
    if (st != CR_OK) cr_drape_batch_free(b);
    return st;
}

void cr_drape_batch_free(drape_batch *b) {
    free(b->uv), free(b->p0), free(b->rest), free(b->edges), free(b->hinges), free(b->source);
    free(b->all_uv), free(b->all_p0), free(b->valid);
    cr_drape_strain_destroy(b->strain);
    cr_drape_bend_destroy(b->bend);
    memset(b, 0, sizeof *b);
}

cr_status cr_drape_batch_build(drape_batch *b, const cr_drape_model *m, const float *centre,
                               const float *theta, int64_t n, float side, int inset,
                               cr_error *err) {
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
    const int32_t np = (int32_t)(6 * b->n);
    CR_TRY(cr_drape_strain_set(b->strain, b->edges, b->rest, (int32_t)(9 * b->n), np, err));
    return cr_drape_bend_set(b->bend, b->hinges, (int32_t)(3 * b->n), np, err);
}

cr_tensor *cr_drape_batch_loss(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                               cr_tensor *x, cr_tensor **terms_out) {
    cr_tensor *t[4];
    float w[4];
    cr_drape_loss_terms(ctx, lc, b->strain, b->bend, x, 0, t);
    cr_drape_loss_weights(&lc->def->w, 1, w);
    return cr_loss_weighted_sum(ctx, t, w, 4, terms_out);
}

cr_status cr_drape_batch_eval(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                              const float *x, double sums[4], float *per_structure, cr_error *err) {
    int was = cr_nn_ctx_grad_enabled(ctx);
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    cr_tensor *xt = cr_nn_from(ctx, 2, (int64_t[]){6 * b->n, 3}, x);
    cr_tensor *t[4], *weighted[4];
    float w[4];
    cr_drape_loss_terms(ctx, lc, b->strain, b->bend, xt, 1, t);
    cr_drape_loss_weights(&lc->def->w, 1, w);
    cr_loss_weighted_sum(ctx, t, w, 4, weighted);
    cr_nn_ctx_set_grad_enabled(ctx, was);
    CR_TRY(cr_nn_ctx_error(ctx, err));
    for (int k = 0; k < 4; k++)
        sums[k] += weighted[k]->data[0];
    /* each structure's weighted total from the elements it owns, in order */
    const int per[4] = {9, 3, 6, 6}; /* elements of each term per structure */
    for (int64_t s = 0; per_structure && s < b->n; s++) {
        double total = 0.0;
        for (int k = 0; k < 4; k++) {
            double acc = 0.0;
            for (int i = 0; i < per[k]; i++)
                acc += t[k]->data[per[k] * s + i];
            total += (double)w[k] * acc;
        }
        per_structure[s] = (float)total;
    }
    return CR_OK;
}
