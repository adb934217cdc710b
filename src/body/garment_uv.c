/* garment_uv.c: UV charts for garment panels: flattening, packing, and
 * transfer of one layout to other resolutions.
 *
 * Flattening: each panel (a disc) is flattened by ARAP (Liu, Zhang, Xu,
 * Gotsman & Gortler 2008, "A local/global approach to mesh
 * parameterization"): alternately fit each triangle's best rotation R_t from
 * its flattened rest shape x to its current UVs u (the closed-form 2x2
 * polar decomposition, theta = atan2(S10 - S01, S00 + S11) with S =
 * sum_edges cot (u_i - u_j)(x_i - x_j)^T), then solve the Poisson system
 *     sum_j w_ij (u_i - u_j) = sum_t sum_j cot_ij^t R_t (x_i - x_j),
 * w_ij the summed cotangents (clamped positive), by Jacobi-preconditioned
 * conjugate gradients warm-started from the last iterate, with one vertex
 * pinned. The start is the orthographic projection onto the plane across
 * the panel's mean normal, with the body's up as +v; ARAP keeps that
 * orientation (the result is rotated back onto the start by 2-D Procrustes).
 * Each chart is then scaled so its UV area is its 3-D area (ARAP is not
 * exactly area-preserving; the residual is per triangle, not per panel).
 *
 * Packing: charts on shelves (tallest first, 2 cm apart), the whole layout
 * scaled into [0,1]^2 by one factor, uv_scale_m = metres per UV unit.
 *
 * Transfer: a garment at another resolution takes its UVs from the
 * template's reference mesh: each vertex is cast along the field's normal
 * onto the reference faces of the same panel (the two surfaces lie within
 * a chord's sag of each other) and the reference UVs are interpolated there;
 * a vertex whose ray misses (at a chart's rim) takes the closest point.
 *
 * Left out: seam-length matching between panels and chart cutting for
 * panels that are not discs (procedural panels always are).
 */
#include "garment_internal.h"

#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { ARAP_ITERATIONS = 12, CG_MAX_ITERATIONS = 400 };
#define CG_TOL 1e-6  /* relative residual of the conjugate gradients */
#define COT_MIN 1e-2 /* cotangent weights are clamped to [COT_MIN, COT_MAX] */
#define COT_MAX 1e2
#define CHART_GAP_M 0.02 /* space between packed charts, m */

/* One panel as its own small mesh. */
typedef struct chart {
    int32_t nv, nf;
    int32_t *gv;  /* (nv) vertex in the garment */
    int32_t *tri; /* (nf,3) local vertices */
    double *x;    /* (nf,3,2) each triangle flattened in its own frame */
    double *cot;  /* (nf,3) cotangent of the angle at corner k (opposite edge k+1, k+2) */
    double *u;    /* (nv,2) UVs */
} chart;

static void chart_free(chart *c) {
    free(c->gv), free(c->tri), free(c->x), free(c->cot), free(c->u);
    memset(c, 0, sizeof *c);
}

static double clampd(double x, double lo, double hi) {
    return x < lo ? lo : x > hi ? hi : x;
}

/* Local copy of panel p's faces; flattened triangles and cotangents. */
static cr_status chart_make(const cr_mesh *m, const int32_t *panel, int32_t p, int32_t *local,
                            chart *c, cr_error *err) {
    memset(c, 0, sizeof *c);
    for (int32_t f = 0; f < m->nf; f++)
        c->nf += panel[f] == p;
    for (int32_t v = 0; v < m->nv; v++)
        local[v] = -1;
    c->gv = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    c->tri = cr_malloc((size_t)c->nf * 3 * sizeof(int32_t), err);
    c->x = cr_malloc((size_t)c->nf * 6 * sizeof(double), err);
    c->cot = cr_malloc((size_t)c->nf * 3 * sizeof(double), err);
    if (!c->gv || !c->tri || !c->x || !c->cot) return CR_ERR_MEMORY;
    int32_t j = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (panel[f] != p) continue;
        const float *q[3];
        for (int k = 0; k < 3; k++) {
            int32_t v = m->tri[3 * f + k];
            if (local[v] < 0) local[v] = c->nv, c->gv[c->nv++] = v;
            c->tri[3 * j + k] = local[v];
            q[k] = &m->pos[3 * (size_t)v];
        }
        double e1[3], e2[3];
        for (int d = 0; d < 3; d++)
            e1[d] = q[1][d] - q[0][d], e2[d] = q[2][d] - q[0][d];
        double l1 = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        double dp = (e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]) / l1;
        double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
               cz = e1[0] * e2[1] - e1[1] * e2[0];
        double h = sqrt(cx * cx + cy * cy + cz * cz) / l1;
        double *x = &c->x[6 * (size_t)j];
        x[0] = 0, x[1] = 0, x[2] = l1, x[3] = 0, x[4] = dp, x[5] = h;
        for (int k = 0; k < 3; k++) {
            const double *o = &x[2 * k], *a = &x[2 * ((k + 1) % 3)], *b = &x[2 * ((k + 2) % 3)];
            double u0 = a[0] - o[0], u1 = a[1] - o[1], v0 = b[0] - o[0], v1 = b[1] - o[1];
            double cr = fabs(u0 * v1 - u1 * v0);
            c->cot[3 * j + k] =
                clampd(cr > 0 ? (u0 * v0 + u1 * v1) / cr : COT_MAX, COT_MIN, COT_MAX);
        }
        j++;
    }
    c->u = cr_malloc((size_t)c->nv * 2 * sizeof(double), err);
    return c->u ? CR_OK : CR_ERR_MEMORY;
}

/* Orthographic start: project onto the plane across the mean normal, +v
 * along the body's up (or its depth axis for a panel facing up or down). */
static void chart_project(const cr_mesh *m, chart *c) {
    double n[3] = {0, 0, 0};
    for (int32_t f = 0; f < c->nf; f++) {
        const float *q[3];
        for (int k = 0; k < 3; k++)
            q[k] = &m->pos[3 * (size_t)c->gv[c->tri[3 * f + k]]];
        float fn[3];
        cr_triangle_normal(q[0], q[1], q[2], fn);
        float a = 0.5f * cr_triangle_normal(q[0], q[1], q[2], fn);
        for (int d = 0; d < 3; d++)
            n[d] += a * fn[d];
    }
    double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int d = 0; d < 3; d++)
        n[d] = nl > 0 ? n[d] / nl : (d == 2);
    double up[3] = {0, 1, 0};
    if (fabs(n[1]) > 0.9) up[1] = 0, up[2] = -1;
    double dn = up[0] * n[0] + up[1] * n[1] + up[2] * n[2], v[3], u[3];
    for (int d = 0; d < 3; d++)
        v[d] = up[d] - dn * n[d];
    double vl = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int d = 0; d < 3; d++)
        v[d] /= vl;
    /* u = v x n, so (u, v, n) is right-handed and 3-D winding is kept. */
    u[0] = v[1] * n[2] - v[2] * n[1];
    u[1] = v[2] * n[0] - v[0] * n[2];
    u[2] = v[0] * n[1] - v[1] * n[0];
    for (int32_t i = 0; i < c->nv; i++) {
        const float *p = &m->pos[3 * (size_t)c->gv[i]];
        c->u[2 * i] = u[0] * p[0] + u[1] * p[1] + u[2] * p[2];
        c->u[2 * i + 1] = v[0] * p[0] + v[1] * p[1] + v[2] * p[2];
    }
}

/* Symmetric sparse rows of the weighted Laplacian (plus the pin). */
typedef struct spmat {
    int32_t n;
    int32_t *off; /* (n+1) */
    int32_t *col; /* (nnz) */
    double *val;  /* (nnz) */
    double *diag; /* (n) */
} spmat;

static void spmat_free(spmat *a) {
    free(a->off), free(a->col), free(a->val), free(a->diag);
    memset(a, 0, sizeof *a);
}

static int cmp_i32x2(const void *pa, const void *pb) {
    const int32_t *a = pa, *b = pb;
    if (a[0] != b[0]) return (a[0] > b[0]) - (a[0] < b[0]);
    return (a[1] > b[1]) - (a[1] < b[1]);
}

/* Off-diagonal entries from every half-edge (i, j, w) merged by (i, j). */
static cr_status laplacian(const chart *c, double pin_weight, spmat *a, cr_error *err) {
    memset(a, 0, sizeof *a);
    const int64_t ne = 6 * (int64_t)c->nf;
    int32_t *ij = cr_malloc((size_t)ne * 2 * sizeof(int32_t), err);
    double *w = cr_malloc((size_t)ne * sizeof(double), err);
    int32_t *order = cr_malloc((size_t)ne * 2 * sizeof(int32_t), err);
    a->n = c->nv;
    a->off = cr_calloc((size_t)c->nv + 1, sizeof(int32_t), err);
    a->col = cr_malloc((size_t)ne * sizeof(int32_t), err);
    a->val = cr_malloc((size_t)ne * sizeof(double), err);
    a->diag = cr_calloc((size_t)c->nv, sizeof(double), err);
    cr_status st =
        ij && w && order && a->off && a->col && a->val && a->diag ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        int64_t n = 0;
        for (int32_t f = 0; f < c->nf; f++)
            for (int k = 0; k < 3; k++) {
                int32_t i = c->tri[3 * f + (k + 1) % 3], j = c->tri[3 * f + (k + 2) % 3];
                double wk = c->cot[3 * f + k];
                ij[2 * n] = i, ij[2 * n + 1] = j, w[n] = wk, n++;
                ij[2 * n] = j, ij[2 * n + 1] = i, w[n] = wk, n++;
                a->diag[i] += wk, a->diag[j] += wk;
            }
        /* Half-edges sorted by row, then by their index (a stable order). */
        for (int64_t e = 0; e < ne; e++)
            order[2 * e] = ij[2 * e], order[2 * e + 1] = (int32_t)e;
        qsort(order, (size_t)ne, 2 * sizeof(int32_t), cmp_i32x2);
        int64_t nnz = 0;
        for (int64_t s = 0; s < ne;) {
            int32_t i = order[2 * s];
            int64_t t = s;
            /* Within row i, merge equal columns (small rows: linear scan). */
            int64_t row_start = nnz;
            for (; t < ne && order[2 * t] == i; t++) {
                int32_t e = order[2 * t + 1], j = ij[2 * e + 1];
                int64_t q = row_start;
                while (q < nnz && a->col[q] != j)
                    q++;
                if (q == nnz) a->col[nnz] = j, a->val[nnz] = 0.0, nnz++;
                a->val[q] -= w[e];
            }
            a->off[i + 1] = (int32_t)(nnz - row_start);
            s = t;
        }
        for (int32_t i = 0; i < c->nv; i++)
            a->off[i + 1] += a->off[i];
        a->diag[0] += pin_weight;
    }
    free(ij), free(w), free(order);
    if (st != CR_OK) spmat_free(a);
    return st;
}

static void spmv(const spmat *a, const double *x, double *y) {
    for (int32_t i = 0; i < a->n; i++) {
        double s = a->diag[i] * x[i];
        for (int32_t q = a->off[i]; q < a->off[i + 1]; q++)
            s += a->val[q] * x[a->col[q]];
        y[i] = s;
    }
}

/* Jacobi-preconditioned CG for A x = b, x warm-started. scratch (4n). */
static void cg_solve(const spmat *a, const double *b, double *x, double *scratch) {
    const int32_t n = a->n;
    double *r = scratch, *z = r + n, *p = z + n, *q = p + n;
    spmv(a, x, q);
    double bb = 0.0, rz = 0.0;
    for (int32_t i = 0; i < n; i++) {
        r[i] = b[i] - q[i];
        z[i] = r[i] / a->diag[i];
        p[i] = z[i];
        rz += r[i] * z[i];
        bb += b[i] * b[i];
    }
    const double tol2 = CG_TOL * CG_TOL * (bb > 0 ? bb : 1.0);
    for (int it = 0; it < CG_MAX_ITERATIONS; it++) {
        double rr = 0.0;
        for (int32_t i = 0; i < n; i++)
            rr += r[i] * r[i];
        if (rr <= tol2) break;
        spmv(a, p, q);
        double pq = 0.0;
        for (int32_t i = 0; i < n; i++)
            pq += p[i] * q[i];
        if (!(pq > 0.0)) break;
        double alpha = rz / pq, rz2 = 0.0;
        for (int32_t i = 0; i < n; i++) {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
            z[i] = r[i] / a->diag[i];
            rz2 += r[i] * z[i];
        }
        double beta = rz2 / rz;
        rz = rz2;
        for (int32_t i = 0; i < n; i++)
            p[i] = z[i] + beta * p[i];
    }
}

/* Signed UV area of local triangle f. */
static double uv_area(const chart *c, int32_t f) {
    const double *a = &c->u[2 * c->tri[3 * f]], *b = &c->u[2 * c->tri[3 * f + 1]],
                 *d = &c->u[2 * c->tri[3 * f + 2]];
    return 0.5 * ((b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]));
}

static cr_status chart_arap(chart *c, cr_error *err) {
    double area3 = 0.0;
    for (int32_t f = 0; f < c->nf; f++)
        area3 += 0.5 * c->x[6 * f + 2] * c->x[6 * f + 5];
    spmat a;
    CR_TRY(laplacian(c, 1.0, &a, err));
    const int32_t n = c->nv;
    double *b = cr_malloc((size_t)n * 2 * sizeof(double), err);
    double *xs = cr_malloc((size_t)n * 2 * sizeof(double), err);
    double *scratch = cr_malloc((size_t)n * 4 * sizeof(double), err);
    double *u0 = cr_malloc((size_t)n * 2 * sizeof(double), err);
    cr_status st = b && xs && scratch && u0 ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        /* Scale the start to the 3-D area, so the pin holds a sensible place. */
        memcpy(u0, c->u, (size_t)n * 2 * sizeof(double));
        double a2 = 0.0;
        for (int32_t f = 0; f < c->nf; f++)
            a2 += uv_area(c, f);
        double s = a2 > 0 ? sqrt(area3 / a2) : 1.0;
        for (int32_t i = 0; i < 2 * n; i++)
            c->u[i] *= s;
    }
    for (int it = 0; st == CR_OK && it < ARAP_ITERATIONS; it++) {
        memset(b, 0, (size_t)n * 2 * sizeof(double));
        for (int32_t f = 0; f < c->nf; f++) {
            const double *x = &c->x[6 * f], *w = &c->cot[3 * f];
            const int32_t *t = &c->tri[3 * f];
            double S[4] = {0, 0, 0, 0};
            for (int k = 0; k < 3; k++) {
                int i = (k + 1) % 3, j = (k + 2) % 3;
                double du[2] = {c->u[2 * t[i]] - c->u[2 * t[j]],
                                c->u[2 * t[i] + 1] - c->u[2 * t[j] + 1]};
                double dx[2] = {x[2 * i] - x[2 * j], x[2 * i + 1] - x[2 * j + 1]};
                S[0] += w[k] * du[0] * dx[0], S[1] += w[k] * du[0] * dx[1];
                S[2] += w[k] * du[1] * dx[0], S[3] += w[k] * du[1] * dx[1];
            }
            double th = atan2(S[2] - S[1], S[0] + S[3]), cs = cos(th), sn = sin(th);
            for (int k = 0; k < 3; k++) {
                int i = (k + 1) % 3, j = (k + 2) % 3;
                double dx[2] = {x[2 * i] - x[2 * j], x[2 * i + 1] - x[2 * j + 1]};
                double r0 = cs * dx[0] - sn * dx[1], r1 = sn * dx[0] + cs * dx[1];
                b[2 * t[i]] += w[k] * r0, b[2 * t[i] + 1] += w[k] * r1;
                b[2 * t[j]] -= w[k] * r0, b[2 * t[j] + 1] -= w[k] * r1;
            }
        }
        /* The pin: vertex 0 stays where it is. */
        b[0] += c->u[0], b[1] += c->u[1];
        /* One solve per coordinate: xs holds the unknowns, then the right side. */
        for (int d = 0; d < 2; d++) {
            for (int32_t i = 0; i < n; i++)
                xs[i] = c->u[2 * i + d], xs[n + i] = b[2 * i + d];
            cg_solve(&a, xs + n, xs, scratch);
            for (int32_t i = 0; i < n; i++)
                c->u[2 * i + d] = xs[i];
        }
    }
    if (st == CR_OK) {
        /* Rotate back onto the start (area-weighted Procrustes about the
         * centroids), then scale the chart's area to the 3-D area. */
        double cu[2] = {0, 0}, c0[2] = {0, 0};
        for (int32_t i = 0; i < n; i++)
            for (int d = 0; d < 2; d++)
                cu[d] += c->u[2 * i + d] / n, c0[d] += u0[2 * i + d] / n;
        double sdot = 0.0, scross = 0.0;
        for (int32_t i = 0; i < n; i++) {
            double p[2] = {c->u[2 * i] - cu[0], c->u[2 * i + 1] - cu[1]};
            double q[2] = {u0[2 * i] - c0[0], u0[2 * i + 1] - c0[1]};
            sdot += p[0] * q[0] + p[1] * q[1];
            scross += p[0] * q[1] - p[1] * q[0];
        }
        double th = atan2(scross, sdot), cs = cos(th), sn = sin(th), a2 = 0.0;
        for (int32_t i = 0; i < n; i++) {
            double p[2] = {c->u[2 * i] - cu[0], c->u[2 * i + 1] - cu[1]};
            c->u[2 * i] = cs * p[0] - sn * p[1];
            c->u[2 * i + 1] = sn * p[0] + cs * p[1];
        }
        for (int32_t f = 0; f < c->nf; f++)
            a2 += uv_area(c, f);
        if (!(a2 > 0.0))
            st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: a panel's UV chart came out folded");
        double s = st == CR_OK ? sqrt(area3 / a2) : 1.0;
        for (int32_t i = 0; i < 2 * n; i++)
            c->u[i] *= s;
    }
    spmat_free(&a);
    free(b), free(xs), free(scratch), free(u0);
    return st;
}

/* Set m's uv and tri_uv from one chart per panel (uv (U,2) in chart units). */
static cr_status write_uvs(cr_mesh *m, const int32_t *panel, int32_t npanels, const chart *c,
                           cr_error *err) {
    int32_t nuv = 0, base[CR_GARMENT_MAX_PANELS], seen[CR_GARMENT_MAX_PANELS] = {0};
    for (int32_t p = 0; p < npanels; p++)
        base[p] = nuv, nuv += c[p].nv;
    float *uv = cr_malloc((size_t)nuv * 2 * sizeof(float), err);
    int32_t *tri_uv = cr_malloc((size_t)m->nf * 3 * sizeof(int32_t), err);
    if (!uv || !tri_uv) {
        free(uv), free(tri_uv);
        return CR_ERR_MEMORY;
    }
    for (int32_t p = 0; p < npanels; p++)
        for (int32_t i = 0; i < 2 * c[p].nv; i++)
            uv[2 * (size_t)base[p] + i] = (float)c[p].u[i];
    /* A chart lists its panel's faces in mesh order. */
    for (int32_t f = 0; f < m->nf; f++) {
        int32_t p = panel[f], j = seen[p]++;
        for (int k = 0; k < 3; k++)
            tri_uv[3 * f + k] = base[p] + c[p].tri[3 * j + k];
    }
    free(m->uv), free(m->tri_uv);
    m->uv = uv, m->tri_uv = tri_uv, m->nuv = nuv;
    return CR_OK;
}

/* Lay charts of the given sizes (m) on shelves of width `shelf` in the
 * given order; returns the side of the square around the layout, and each
 * chart's lower-left corner in offset (may be NULL). */
static double shelf_extent(const double (*size)[2], const int32_t *order, int32_t n, double shelf,
                           double (*offset)[2]) {
    double x = 0.0, y = 0.0, row = 0.0, extent = 0.0;
    for (int32_t i = 0; i < n; i++) {
        int32_t p = order[i];
        if (x > 0.0 && x + size[p][0] + CHART_GAP_M > shelf + 1e-9) y += row, x = 0.0, row = 0.0;
        if (offset) offset[p][0] = x + 0.5 * CHART_GAP_M, offset[p][1] = y + 0.5 * CHART_GAP_M;
        x += size[p][0] + CHART_GAP_M;
        row = fmax(row, size[p][1] + CHART_GAP_M);
        extent = fmax(extent, fmax(x, y + row));
    }
    return extent;
}

cr_status cr_garment_uv_layout(cr_mesh *m, const int32_t *panel, int32_t npanels, float *uv_scale_m,
                               cr_error *err) {
    CR_ASSERT(npanels > 0 && npanels <= CR_GARMENT_MAX_PANELS);
    chart c[CR_GARMENT_MAX_PANELS];
    memset(c, 0, sizeof c);
    int32_t *local = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    cr_status st = local ? CR_OK : CR_ERR_MEMORY;
    for (int32_t p = 0; st == CR_OK && p < npanels; p++) {
        st = chart_make(m, panel, p, local, &c[p], err);
        if (st == CR_OK && c[p].nf == 0)
            st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: panel %d has no faces", p);
        if (st == CR_OK) chart_project(m, &c[p]);
        if (st == CR_OK) st = chart_arap(&c[p], err);
    }
    if (st == CR_OK) {
        /* Shelf packing, tallest chart first. */
        double lo[CR_GARMENT_MAX_PANELS][2], size[CR_GARMENT_MAX_PANELS][2];
        int32_t order[CR_GARMENT_MAX_PANELS];
        for (int32_t p = 0; p < npanels; p++) {
            lo[p][0] = lo[p][1] = INFINITY;
            double hi[2] = {-INFINITY, -INFINITY};
            for (int32_t i = 0; i < c[p].nv; i++)
                for (int d = 0; d < 2; d++) {
                    lo[p][d] = fmin(lo[p][d], c[p].u[2 * i + d]);
                    hi[d] = fmax(hi[d], c[p].u[2 * i + d]);
                }
            size[p][0] = hi[0] - lo[p][0], size[p][1] = hi[1] - lo[p][1];
            order[p] = p;
        }
        for (int32_t i = 1; i < npanels; i++)
            for (int32_t j = i; j > 0 && size[order[j]][1] > size[order[j - 1]][1]; j--) {
                int32_t t = order[j];
                order[j] = order[j - 1], order[j - 1] = t;
            }
        /* Shelf widths to try: the first i charts side by side; keep the one
         * whose layout has the smallest square around it. */
        double best_shelf = 0.0, best_extent = INFINITY, run = 0.0;
        for (int32_t i = 0; i < npanels; i++) {
            run += size[order[i]][0] + CHART_GAP_M;
            double e = shelf_extent(size, order, npanels, run, NULL);
            if (e < best_extent) best_extent = e, best_shelf = run;
        }
        double offset[CR_GARMENT_MAX_PANELS][2];
        double extent = shelf_extent(size, order, npanels, best_shelf, offset);
        for (int32_t p = 0; p < npanels; p++)
            for (int32_t k = 0; k < c[p].nv; k++) {
                c[p].u[2 * k] += offset[p][0] - lo[p][0];
                c[p].u[2 * k + 1] += offset[p][1] - lo[p][1];
            }
        for (int32_t p = 0; p < npanels; p++)
            for (int32_t k = 0; k < 2 * c[p].nv; k++)
                c[p].u[k] /= extent;
        *uv_scale_m = (float)extent;
        st = write_uvs(m, panel, npanels, c, err);
    }
    for (int32_t p = 0; p < npanels; p++)
        chart_free(&c[p]);
    free(local);
    return st;
}

cr_status cr_garment_uv_transfer(const cr_mesh *ref, const int32_t *ref_panel, int32_t npanels,
                                 const gfield *field, cr_mesh *m, const int32_t *panel,
                                 cr_error *err) {
    CR_ASSERT(cr_mesh_has_uv(ref));
    chart c[CR_GARMENT_MAX_PANELS];
    memset(c, 0, sizeof c);
    int32_t *local = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    int32_t *sub = cr_malloc((size_t)ref->nf * 3 * sizeof(int32_t), err);
    int32_t *sub_face = cr_malloc((size_t)ref->nf * sizeof(int32_t), err);
    cr_status st = local && sub && sub_face ? CR_OK : CR_ERR_MEMORY;
    /* Mean reference edge: how far off the other surface may lie. */
    double el = 0.0;
    for (int32_t f = 0; f < ref->nf; f++) {
        const float *a = &ref->pos[3 * (size_t)ref->tri[3 * f]],
                    *b = &ref->pos[3 * (size_t)ref->tri[3 * f + 1]];
        el += sqrt((double)((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                            (a[2] - b[2]) * (a[2] - b[2])));
    }
    const float reach = (float)(ref->nf > 0 ? el / ref->nf : 0.01);
    for (int32_t p = 0; st == CR_OK && p < npanels; p++) {
        int32_t ns = 0;
        for (int32_t f = 0; f < ref->nf; f++)
            if (ref_panel[f] == p) {
                memcpy(&sub[3 * ns], &ref->tri[3 * f], 3 * sizeof(int32_t));
                sub_face[ns++] = f;
            }
        cr_bvh *bvh = NULL;
        st = chart_make(m, panel, p, local, &c[p], err);
        if (st == CR_OK && (ns == 0 || c[p].nf == 0))
            st = CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: panel %d is empty at one resolution", p);
        if (st == CR_OK) st = cr_bvh_build(ref->pos, ref->nv, sub, ns, &bvh, err);
        for (int32_t i = 0; st == CR_OK && i < c[p].nv; i++) {
            const float *x = &m->pos[3 * (size_t)c[p].gv[i]];
            float g[3];
            cr_gfield_eval(field, x, g);
            float gl = sqrtf(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
            int32_t face = -1;
            float bary[3];
            if (gl > 0.0f) {
                float dir[3] = {g[0] / gl, g[1] / gl, g[2] / gl};
                float o[3] = {x[0] - reach * dir[0], x[1] - reach * dir[1], x[2] - reach * dir[2]};
                cr_bvh_ray_hit h;
                if (cr_bvh_raycast(bvh, o, dir, 2.0f * reach, &h))
                    face = h.face, memcpy(bary, h.bary, sizeof bary);
            }
            if (face < 0) {
                cr_bvh_hit h;
                cr_bvh_closest(bvh, x, INFINITY, &h);
                face = h.face, memcpy(bary, h.bary, sizeof bary);
            }
            const int32_t *tu = &ref->tri_uv[3 * (size_t)sub_face[face]];
            for (int d = 0; d < 2; d++) {
                double u = 0.0;
                for (int k = 0; k < 3; k++)
                    u += (double)bary[k] * ref->uv[2 * (size_t)tu[k] + d];
                c[p].u[2 * i + d] = u;
            }
        }
        cr_bvh_destroy(bvh);
    }
    if (st == CR_OK) st = write_uvs(m, panel, npanels, c, err);
    for (int32_t p = 0; p < npanels; p++)
        chart_free(&c[p]);
    free(local), free(sub), free(sub_face);
    return st;
}
