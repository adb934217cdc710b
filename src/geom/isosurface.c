/* isosurface.c: marching cubes with a consistent face rule, and tangential
 * relaxation of the result onto the level set.
 *
 * Instead of the classic 256-case table (whose complementary cases disagree
 * across faces and leave holes, Durst 1988), each cell's polygons are built
 * from its faces: on a face, the crossing on edge (c_k, c_k+1) is an entry
 * when c_k is outside and c_k+1 inside, and an exit the other way round, with
 * the face's corners taken counter-clockwise seen from outside the cell. Each
 * face contributes segments entry -> exit; a face with four crossings pairs
 * them around the corners the asymptotic decider (Nielson & Hamann 1991)
 * cuts off. Every crossed cell edge is an entry on one of its two faces and an
 * exit on the other, so the segments close into directed cycles, the inside
 * on their right seen from outside: the polygons are wound counter-clockwise
 * around the outward normal. The neighbour across a face sees the same four
 * values, makes the same decision (the decider compares two products of
 * floats in double, which is exact) and runs each shared segment the other
 * way, so the mesh is closed, manifold and consistently oriented.
 *
 * A cycle with more than three corners is triangulated by dynamic
 * programming over its diagonals, minimising the worst triangle's shape
 * ratio (sum of squared edges over 4 sqrt(3) area, 1 for equilateral). A
 * diagonal whose two ends lie on one face of the cell is refused: the cell
 * across that face could draw the same diagonal, making an edge with four
 * faces. When no triangulation avoids such diagonals (a rare cycle that
 * visits one face twice) the cycle is fanned from a new vertex at its
 * centroid, whose edges belong to this cell alone.
 *
 * Left out: sharp features (dual contouring), adaptive (octree) grids, and
 * the interior ambiguity of marching cubes 33 (Chernyaev 1995), which would
 * change the surface's topology inside a cell but not its manifoldness.
 *
 * References: Lorensen & Cline 1987, "Marching cubes"; Nielson & Hamann
 * 1991, "The asymptotic decider"; Taubin 1995 and Ohtake et al. 2003 for
 * tangential smoothing with reprojection onto an implicit surface.
 */
#include "crease/isosurface.h"

#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Corner c of a cell sits at offset (c & 1, c >> 1 & 1, c >> 2 & 1). */
static const uint8_t edge_corner[12][2] = {
    {0, 1}, {2, 3}, {4, 5}, {6, 7}, /* along x */
    {0, 2}, {1, 3}, {4, 6}, {5, 7}, /* along y */
    {0, 4}, {1, 5}, {2, 6}, {3, 7}  /* along z */
};
/* Corners of each face, counter-clockwise seen from outside the cell:
 * -x, +x, -y, +y, -z, +z. */
static const uint8_t face_corner[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                          {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};

/* Crossing points stay this fraction of a cell away from either sample, so
 * two crossings never coincide when a sample equals iso. */
#define CROSSING_MARGIN 1e-3f
/* The longest cycle a cell can hold visits each of its 12 edges once. */
#define MAX_CYCLE 12

/* Derived once per extraction: the cell edge under each face side, and
 * whether two cell edges share a face. */
typedef struct cell_tables {
    int8_t face_edge[6][4];    /* face_edge[f][k]: edge from corner k to k+1 of face f */
    uint8_t same_face[12][12]; /* 1 when the two edges lie on a common face */
} cell_tables;

static void build_tables(cell_tables *t) {
    memset(t, 0, sizeof *t);
    for (int f = 0; f < 6; f++)
        for (int k = 0; k < 4; k++) {
            int a = face_corner[f][k], b = face_corner[f][(k + 1) & 3];
            for (int e = 0; e < 12; e++)
                if ((edge_corner[e][0] == a && edge_corner[e][1] == b) ||
                    (edge_corner[e][0] == b && edge_corner[e][1] == a))
                    t->face_edge[f][k] = (int8_t)e;
        }
    for (int f = 0; f < 6; f++)
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++)
                t->same_face[t->face_edge[f][a]][t->face_edge[f][b]] = 1;
}

/* ------------------------------------------------------------ checking -- */

static cr_status check_grid(const cr_iso_grid *g, cr_error *err) {
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "isosurface: grid of %d x %d x %d samples (need >= 2 each)", g->nx, g->ny,
                       g->nz);
    if ((int64_t)g->nx * g->ny * g->nz > (int64_t)INT32_MAX)
        return CR_FAIL(err, CR_ERR_INVALID, "isosurface: grid of %d x %d x %d samples passes 2^31",
                       g->nx, g->ny, g->nz);
    if (!(g->spacing > 0.0f) || !isfinite(g->spacing))
        return CR_FAIL(err, CR_ERR_INVALID, "isosurface: spacing %g (need finite > 0)",
                       (double)g->spacing);
    for (int d = 0; d < 3; d++)
        if (!isfinite(g->origin[d]))
            return CR_FAIL(err, CR_ERR_INVALID, "isosurface: origin[%d] is not finite", d);
    return CR_OK;
}

/* -------------------------------------------------------------- sample -- */

typedef struct sample_ctx {
    const cr_iso_grid *g;
    cr_iso_fn fn;
    void *fn_ctx;
    float *values;
} sample_ctx;

static void sample_slices(void *vctx, int64_t begin, int64_t end) {
    sample_ctx *c = vctx;
    const cr_iso_grid *g = c->g;
    for (int64_t k = begin; k < end; k++)
        for (int32_t j = 0; j < g->ny; j++)
            for (int32_t i = 0; i < g->nx; i++) {
                float p[3] = {g->origin[0] + g->spacing * (float)i,
                              g->origin[1] + g->spacing * (float)j,
                              g->origin[2] + g->spacing * (float)k};
                c->values[i + (int64_t)g->nx * (j + (int64_t)g->ny * k)] = c->fn(c->fn_ctx, p);
            }
}

cr_status cr_isosurface_sample(const cr_iso_grid *g, cr_iso_fn fn, void *ctx, float *values,
                               cr_error *err) {
    CR_TRY(check_grid(g, err));
    sample_ctx c = {g, fn, ctx, values};
    cr_parallel_for(g->nz, 1, sample_slices, &c);
    int64_t n = (int64_t)g->nx * g->ny * g->nz;
    for (int64_t s = 0; s < n; s++)
        if (!isfinite(values[s]))
            return CR_FAIL(err, CR_ERR_NAN, "isosurface: field is %g at sample (%d,%d,%d)",
                           (double)values[s], (int)(s % g->nx), (int)(s / g->nx % g->ny),
                           (int)(s / g->nx / g->ny));
    return CR_OK;
}

/* ------------------------------------------------------------- extract -- */

/* Growable output arrays. */
typedef struct builder {
    float *pos;   /* (cap_v,3) */
    int32_t *tri; /* (cap_f,3) */
    int64_t nv, nf, cap_v, cap_f;
} builder;

static int grow(void **p, int64_t *cap, int64_t need, size_t item) {
    if (need <= *cap) return 1;
    int64_t c = *cap ? *cap : 1024;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, (size_t)c * item);
    if (!q) return 0;
    *p = q, *cap = c;
    return 1;
}

static cr_status add_vertex(builder *b, const float p[3], int32_t *id, cr_error *err) {
    if (b->nv >= INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "isosurface: more than 2^31 vertices");
    if (!grow((void **)&b->pos, &b->cap_v, b->nv + 1, 3 * sizeof(float)))
        return CR_FAIL(err, CR_ERR_MEMORY, "isosurface: out of memory at %lld vertices",
                       (long long)b->nv);
    memcpy(&b->pos[3 * b->nv], p, 3 * sizeof(float));
    *id = (int32_t)b->nv++;
    return CR_OK;
}

static cr_status add_tri(builder *b, int32_t a, int32_t c, int32_t d, cr_error *err) {
    if (b->nf >= INT32_MAX) return CR_FAIL(err, CR_ERR_RANGE, "isosurface: more than 2^31 faces");
    if (!grow((void **)&b->tri, &b->cap_f, b->nf + 1, 3 * sizeof(int32_t)))
        return CR_FAIL(err, CR_ERR_MEMORY, "isosurface: out of memory at %lld faces",
                       (long long)b->nf);
    int32_t *t = &b->tri[3 * b->nf++];
    t[0] = a, t[1] = c, t[2] = d;
    return CR_OK;
}

/* Shape ratio of triangle (a, b, c): 1 for equilateral, growing as it
 * degenerates; a huge finite value for zero area so a triangulation still
 * exists. */
static double tri_badness(const float *a, const float *b, const float *c) {
    double u[3], v[3], w[3];
    for (int d = 0; d < 3; d++)
        u[d] = b[d] - a[d], v[d] = c[d] - a[d], w[d] = c[d] - b[d];
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double twice_area = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    double sum2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2] + v[0] * v[0] + v[1] * v[1] +
                  v[2] * v[2] + w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if (!(twice_area > 1e-300)) return 1e300;
    return sum2 / (2.0 * sqrt(3.0) * twice_area);
}

/* Emit the triangles of sub-polygon (i..j) from the DP split table. */
static cr_status emit_split(builder *b, const int32_t *vid, int8_t split[MAX_CYCLE][MAX_CYCLE],
                            int i, int j, cr_error *err) {
    if (j - i < 2) return CR_OK;
    int k = split[i][j];
    CR_TRY(add_tri(b, vid[i], vid[k], vid[j], err));
    CR_TRY(emit_split(b, vid, split, i, k, err));
    return emit_split(b, vid, split, k, j, err);
}

/* Triangulate one cycle: vid (n) its vertices in order, edge (n) the cell
 * edge each lies on. */
static cr_status triangulate_cycle(builder *b, const cell_tables *t, const int32_t *vid,
                                   const int *edge, int n, cr_error *err) {
    if (n == 3) return add_tri(b, vid[0], vid[1], vid[2], err);
    double cost[MAX_CYCLE][MAX_CYCLE];
    int8_t split[MAX_CYCLE][MAX_CYCLE];
    for (int gap = 1; gap < n; gap++)
        for (int i = 0; i + gap < n; i++) {
            int j = i + gap;
            cost[i][j] = gap == 1 ? 0.0 : INFINITY;
            split[i][j] = -1;
            /* (i, j) is a diagonal unless it is the closing side (0, n-1). */
            int diagonal = gap > 1 && !(i == 0 && j == n - 1);
            if (gap == 1 || (diagonal && t->same_face[edge[i]][edge[j]])) continue;
            for (int k = i + 1; k < j; k++) {
                double c = tri_badness(&b->pos[3 * (int64_t)vid[i]], &b->pos[3 * (int64_t)vid[k]],
                                       &b->pos[3 * (int64_t)vid[j]]);
                if (cost[i][k] > c) c = cost[i][k];
                if (cost[k][j] > c) c = cost[k][j];
                if (c < cost[i][j]) cost[i][j] = c, split[i][j] = (int8_t)k;
            }
        }
    if (isfinite(cost[0][n - 1])) return emit_split(b, vid, split, 0, n - 1, err);
    float c[3] = {0, 0, 0};
    for (int i = 0; i < n; i++)
        for (int d = 0; d < 3; d++)
            c[d] += b->pos[3 * (int64_t)vid[i] + d] / (float)n;
    int32_t centre;
    CR_TRY(add_vertex(b, c, &centre, err));
    for (int i = 0; i < n; i++)
        CR_TRY(add_tri(b, vid[i], vid[(i + 1) % n], centre, err));
    return CR_OK;
}

typedef struct extract_state {
    const cr_iso_grid *g;
    float iso;
    cell_tables tables;
    int32_t *edge_vid[3]; /* (nz,ny,nx) per axis: vertex on the grid edge leaving each sample */
    builder b;
} extract_state;

/* The vertex on cell edge e of cell (i, j, k), created on first use. */
static cr_status edge_vertex(extract_state *s, int32_t i, int32_t j, int32_t k, int e, int32_t *out,
                             cr_error *err) {
    const cr_iso_grid *g = s->g;
    int ca = edge_corner[e][0], axis = e / 4;
    int32_t pi = i + (ca & 1), pj = j + (ca >> 1 & 1), pk = k + (ca >> 2 & 1);
    int64_t sa = pi + (int64_t)g->nx * (pj + (int64_t)g->ny * pk);
    int32_t *slot = &s->edge_vid[axis][sa];
    if (*slot >= 0) {
        *out = *slot;
        return CR_OK;
    }
    int64_t step = axis == 0 ? 1 : axis == 1 ? g->nx : (int64_t)g->nx * g->ny;
    float va = g->values[sa], vb = g->values[sa + step];
    float t = (s->iso - va) / (vb - va);
    if (!(t >= CROSSING_MARGIN)) t = CROSSING_MARGIN;
    if (!(t <= 1.0f - CROSSING_MARGIN)) t = 1.0f - CROSSING_MARGIN;
    float p[3] = {g->origin[0] + g->spacing * (float)pi, g->origin[1] + g->spacing * (float)pj,
                  g->origin[2] + g->spacing * (float)pk};
    p[axis] += g->spacing * t;
    CR_TRY(add_vertex(&s->b, p, slot, err));
    *out = *slot;
    return CR_OK;
}

static cr_status polygonise_cell(extract_state *s, int32_t i, int32_t j, int32_t k, cr_error *err) {
    const cr_iso_grid *g = s->g;
    double v[8];
    int inside = 0;
    for (int c = 0; c < 8; c++) {
        int64_t idx = (i + (c & 1)) +
                      (int64_t)g->nx * ((j + (c >> 1 & 1)) + (int64_t)g->ny * (k + (c >> 2 & 1)));
        v[c] = (double)g->values[idx] - (double)s->iso;
        if (g->values[idx] < s->iso) inside |= 1 << c;
    }
    if (inside == 0 || inside == 255) return CR_OK;

    /* next[e]: the edge the cycle runs to after the crossing on edge e. */
    int next[12];
    for (int e = 0; e < 12; e++)
        next[e] = -1;
    for (int f = 0; f < 6; f++) {
        const uint8_t *fc = face_corner[f];
        const int8_t *fe = s->tables.face_edge[f];
        int in[4], crossings = 0;
        for (int q = 0; q < 4; q++)
            in[q] = inside >> fc[q] & 1;
        for (int q = 0; q < 4; q++)
            crossings += in[q] != in[(q + 1) & 3];
        if (crossings == 2) {
            int entry = -1, exit = -1;
            for (int q = 0; q < 4; q++) {
                if (!in[q] && in[(q + 1) & 3]) entry = q;
                if (in[q] && !in[(q + 1) & 3]) exit = q;
            }
            next[fe[entry]] = fe[exit];
        } else if (crossings == 4) {
            /* Diagonal corners alike. The bilinear saddle is inside exactly
             * when the product of the inside pair exceeds that of the
             * outside pair (both products are positive or zero). */
            double p02 = v[fc[0]] * v[fc[2]], p13 = v[fc[1]] * v[fc[3]];
            double p_in = in[0] ? p02 : p13, p_out = in[0] ? p13 : p02;
            int cut_inside = !(p_in > p_out); /* separate the inside corners */
            for (int q = 0; q < 4; q++) {
                if (in[q] != cut_inside) continue;
                int before = fe[(q + 3) & 3], after = fe[q];
                /* An inside corner is entered on the side before it; an
                 * outside one on the side after it. */
                if (in[q])
                    next[before] = after;
                else
                    next[after] = before;
            }
        }
    }

    int done = 0;
    for (int e0 = 0; e0 < 12; e0++) {
        if (next[e0] < 0 || (done >> e0 & 1)) continue;
        int32_t vid[MAX_CYCLE];
        int edge[MAX_CYCLE], n = 0;
        for (int e = e0; !(done >> e & 1); e = next[e]) {
            CR_ASSERT(next[e] >= 0 && n < MAX_CYCLE);
            done |= 1 << e;
            edge[n] = e;
            CR_TRY(edge_vertex(s, i, j, k, e, &vid[n], err));
            n++;
        }
        CR_ASSERT(n >= 3);
        CR_TRY(triangulate_cycle(&s->b, &s->tables, vid, edge, n, err));
    }
    return CR_OK;
}

cr_status cr_isosurface_extract(const cr_iso_grid *g, float iso, cr_mesh **out, cr_error *err) {
    *out = NULL;
    CR_TRY(check_grid(g, err));
    if (!isfinite(iso)) return CR_FAIL(err, CR_ERR_INVALID, "isosurface: iso value is not finite");
    int64_t n = (int64_t)g->nx * g->ny * g->nz;
    for (int64_t s = 0; s < n; s++)
        if (!isfinite(g->values[s]))
            return CR_FAIL(err, CR_ERR_NAN, "isosurface: sample (%d,%d,%d) is %g", (int)(s % g->nx),
                           (int)(s / g->nx % g->ny), (int)(s / g->nx / g->ny),
                           (double)g->values[s]);

    extract_state s = {.g = g, .iso = iso};
    build_tables(&s.tables);
    cr_status st = CR_OK;
    for (int a = 0; a < 3 && st == CR_OK; a++) {
        s.edge_vid[a] = cr_malloc((size_t)n * sizeof(int32_t), err);
        if (!s.edge_vid[a])
            st = CR_ERR_MEMORY;
        else
            memset(s.edge_vid[a], 0xff, (size_t)n * sizeof(int32_t)); /* all -1 */
    }
    for (int32_t k = 0; k + 1 < g->nz && st == CR_OK; k++)
        for (int32_t j = 0; j + 1 < g->ny && st == CR_OK; j++)
            for (int32_t i = 0; i + 1 < g->nx && st == CR_OK; i++)
                st = polygonise_cell(&s, i, j, k, err);
    cr_mesh *m = NULL;
    if (st == CR_OK) st = cr_mesh_create((int32_t)s.b.nv, (int32_t)s.b.nf, 0, &m, err);
    if (st == CR_OK) {
        if (s.b.nv) memcpy(m->pos, s.b.pos, (size_t)s.b.nv * 3 * sizeof(float));
        if (s.b.nf) memcpy(m->tri, s.b.tri, (size_t)s.b.nf * 3 * sizeof(int32_t));
        *out = m;
    }
    for (int a = 0; a < 3; a++)
        free(s.edge_vid[a]);
    free(s.b.pos);
    free(s.b.tri);
    return st;
}

/* --------------------------------------------------------------- relax -- */

typedef struct relax_ctx {
    const cr_topology *t;
    cr_iso_fn fn;
    void *fn_ctx;
    float iso, h;
    const float *src; /* (V,3) positions before this round */
    float *dst;       /* (V,3) positions after; NaN where fn was not finite */
} relax_ctx;

/* Gradient of fn at p by central differences. */
static void field_grad(const relax_ctx *c, const float p[3], float g[3]) {
    for (int d = 0; d < 3; d++) {
        float a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
        a[d] += c->h, b[d] -= c->h;
        g[d] = (c->fn(c->fn_ctx, a) - c->fn(c->fn_ctx, b)) / (2.0f * c->h);
    }
}

/* Fraction of the tangential Laplacian applied per round. */
#define TANGENT_STEP 0.5f
/* Projection: chord-Newton steps x -= (f - iso) g / |g|^2 with the gradient
 * g taken once per round, until |f - iso| is below PROJECT_TOL times the
 * finite-difference step; one step is limited to 10 times that step (about
 * a grid cell) so a nearly flat spot cannot throw a vertex away. */
#define PROJECT_STEPS 6
#define PROJECT_TOL 1e-3

static void relax_range(void *vctx, int64_t begin, int64_t end) {
    relax_ctx *c = vctx;
    const cr_topology *t = c->t;
    for (int64_t v = begin; v < end; v++) {
        const float *x = &c->src[3 * v];
        float p[3] = {x[0], x[1], x[2]}, g[3];
        int32_t deg = t->vv_off[v + 1] - t->vv_off[v];
        field_grad(c, p, g);
        double gg = (double)g[0] * g[0] + (double)g[1] * g[1] + (double)g[2] * g[2];
        if (!isfinite(gg)) {
            c->dst[3 * v] = NAN;
            continue;
        }
        if (deg > 0 && !t->vertex_boundary[v]) {
            double mean[3] = {0, 0, 0};
            for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++)
                for (int d = 0; d < 3; d++)
                    mean[d] += c->src[3 * (int64_t)t->vv[q] + d];
            double dlt[3], dn = 0.0;
            for (int d = 0; d < 3; d++)
                dlt[d] = mean[d] / deg - p[d];
            if (gg > 0.0) {
                for (int d = 0; d < 3; d++)
                    dn += dlt[d] * g[d];
                for (int d = 0; d < 3; d++)
                    dlt[d] -= dn * g[d] / gg;
            }
            for (int d = 0; d < 3; d++)
                p[d] += TANGENT_STEP * (float)dlt[d];
        }
        for (int it = 0; it < PROJECT_STEPS && gg > 0.0; it++) {
            double f = (double)c->fn(c->fn_ctx, p) - c->iso;
            if (!isfinite(f)) {
                p[0] = NAN;
                break;
            }
            if (fabs(f) <= PROJECT_TOL * c->h) break;
            double s = f / gg, lim = 10.0 * c->h, len = fabs(s) * sqrt(gg);
            if (len > lim) s *= lim / len;
            for (int d = 0; d < 3; d++)
                p[d] -= (float)(s * g[d]);
        }
        memcpy(&c->dst[3 * v], p, sizeof p);
    }
}

cr_status cr_isosurface_relax(cr_mesh *m, cr_iso_fn fn, void *ctx, float iso, int32_t iterations,
                              float fd_step, cr_error *err) {
    if (iterations < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "isosurface relax: %d iterations (need >= 0)",
                       iterations);
    if (!(fd_step > 0.0f) || !isfinite(fd_step))
        return CR_FAIL(err, CR_ERR_INVALID, "isosurface relax: fd_step %g (need finite > 0)",
                       (double)fd_step);
    if (iterations == 0 || m->nv == 0) return CR_OK;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    float *tmp = cr_malloc((size_t)m->nv * 3 * sizeof(float), err);
    if (!tmp) {
        cr_topology_destroy(t);
        return CR_ERR_MEMORY;
    }
    relax_ctx c = {.t = t, .fn = fn, .fn_ctx = ctx, .iso = iso, .h = fd_step};
    cr_status st = CR_OK;
    for (int32_t it = 0; it < iterations; it++) {
        c.src = m->pos, c.dst = tmp;
        cr_parallel_for(m->nv, 256, relax_range, &c);
        for (int64_t i = 0; i < 3 * (int64_t)m->nv && st == CR_OK; i++)
            if (!isfinite(tmp[i]))
                st = CR_FAIL(err, CR_ERR_NAN,
                             "isosurface relax: field is not finite near vertex %lld",
                             (long long)(i / 3));
        if (st != CR_OK) break;
        float *swap = m->pos;
        m->pos = tmp, tmp = swap;
    }
    free(tmp);
    cr_topology_destroy(t);
    return st;
}
