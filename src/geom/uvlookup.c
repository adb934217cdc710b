/* uvlookup.c: uniform grid over UV triangles; point location, closest
 * triangle, barycentric interpolation.
 *
 * Each UV triangle is registered in every cell its bounding box (grown by the
 * edge tolerance) overlaps, as a CSR list built by counting then filling.
 * Barycentrics are ratios of signed areas in double, so mirrored (clockwise)
 * UV charts work unchanged. The closest-triangle query searches
 * rings of cells around the point's cell and stops once a ring's distance
 * lower bound exceeds the best distance found.
 *
 * Left out: overlapping UV charts are not resolved: a point in two
 * overlapping charts gets the first face of its cell that holds it by more
 * than INSIDE_STOP, else the one that holds it most deeply.
 * Reference: Ericson, "Real-Time Collision Detection" (2005), 3.4 and 5.1.5.
 */
#include "crease/uvlookup.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { AUTO_GRID_MAX = 4096, GRID_RES_MAX = 16384 };
/* Smallest barycentric that ends a cell's search in cr_uv_lookup_find. */
static const double INSIDE_STOP = 1e-9;

struct cr_uv_lookup {
    int32_t nf;
    int32_t *tri;   /* (F,3) vertex indices */
    double *corner; /* (F,6) UV corners u0 v0 u1 v1 u2 v2 */
    double *det;    /* (F) twice the signed UV area; 0 = never matched */
    double lo[2], hi[2];
    double cell[2];     /* cell width and height in UV units */
    int32_t n[2];       /* cells along u and v */
    int32_t *cell_off;  /* (cells+1) */
    int32_t *cell_face; /* (cell_off[cells]) */
};

static double cross2(double ax, double ay, double bx, double by) {
    return ax * by - ay * bx;
}

/* Barycentrics of (u, v) in face f from areas measured at corner 0, so far
 * points keep their signs (no cancellation in a normalising sum); the
 * smallest is returned. */
static double face_bary(const cr_uv_lookup *lk, int32_t f, double u, double v, double b[3]) {
    const double *c = &lk->corner[6 * (size_t)f];
    double e1x = c[2] - c[0], e1y = c[3] - c[1], e2x = c[4] - c[0], e2y = c[5] - c[1];
    double dx = u - c[0], dy = v - c[1];
    b[1] = cross2(dx, dy, e2x, e2y) / lk->det[f];
    b[2] = cross2(e1x, e1y, dx, dy) / lk->det[f];
    b[0] = 1.0 - b[1] - b[2];
    double lo = b[0] < b[1] ? b[0] : b[1];
    return lo < b[2] ? lo : b[2];
}

static int32_t cell_coord(const cr_uv_lookup *lk, int axis, double x) {
    double c = floor((x - lk->lo[axis]) / lk->cell[axis]);
    if (!(c > 0.0)) return 0; /* also catches NaN */
    if (c >= lk->n[axis] - 1) return lk->n[axis] - 1;
    return (int32_t)c;
}

void cr_uv_lookup_destroy(cr_uv_lookup *lk) {
    if (!lk) return;
    free(lk->tri);
    free(lk->corner);
    free(lk->det);
    free(lk->cell_off);
    free(lk->cell_face);
    free(lk);
}

/* Cell range [c0, c1] per axis covered by face f's grown bounding box. */
static void face_cells(const cr_uv_lookup *lk, int32_t f, int32_t c0[2], int32_t c1[2]) {
    const double *c = &lk->corner[6 * (size_t)f];
    for (int a = 0; a < 2; a++) {
        double mn = fmin(c[a], fmin(c[2 + a], c[4 + a]));
        double mx = fmax(c[a], fmax(c[2 + a], c[4 + a]));
        double grow = 0.0;
        for (int b = 0; b < 2; b++) {
            double ext =
                fmax(c[b], fmax(c[2 + b], c[4 + b])) - fmin(c[b], fmin(c[2 + b], c[4 + b]));
            /* A point at barycentric -EPS lies at most EPS times the longest
             * edge (<= sqrt(2) * largest extent) outside the triangle. */
            grow = fmax(grow, 2.0 * CR_UV_LOOKUP_EPS * ext);
        }
        c0[a] = cell_coord(lk, a, mn - grow);
        c1[a] = cell_coord(lk, a, mx + grow);
    }
}

static cr_status copy_faces(const cr_mesh *m, cr_uv_lookup *lk, cr_error *err) {
    int32_t nf = m->nf;
    lk->tri = cr_malloc((size_t)nf * 3 * sizeof(int32_t) + 1, err);
    lk->corner = cr_malloc((size_t)nf * 6 * sizeof(double) + 1, err);
    lk->det = cr_malloc((size_t)nf * sizeof(double) + 1, err);
    if (!lk->tri || !lk->corner || !lk->det) return CR_ERR_MEMORY;
    memcpy(lk->tri, m->tri, (size_t)nf * 3 * sizeof(int32_t));
    lk->lo[0] = lk->lo[1] = INFINITY;
    lk->hi[0] = lk->hi[1] = -INFINITY;
    for (int32_t f = 0; f < nf; f++) {
        double *c = &lk->corner[6 * (size_t)f];
        for (int k = 0; k < 3; k++) {
            int32_t t = m->tri_uv[3 * f + k];
            if (t < 0 || t >= m->nuv)
                return CR_FAIL(err, CR_ERR_RANGE, "uv lookup: face %d uses UV %d, mesh has %d", f,
                               t, m->nuv);
            for (int a = 0; a < 2; a++) {
                double x = m->uv[2 * (size_t)t + a];
                if (!isfinite(x))
                    return CR_FAIL(err, CR_ERR_NAN, "uv lookup: UV %d is not finite", t);
                c[2 * k + a] = x;
                lk->lo[a] = fmin(lk->lo[a], x);
                lk->hi[a] = fmax(lk->hi[a], x);
            }
        }
        lk->det[f] = cross2(c[2] - c[0], c[3] - c[1], c[4] - c[0], c[5] - c[1]);
    }
    if (nf == 0) lk->lo[0] = lk->lo[1] = lk->hi[0] = lk->hi[1] = 0.0;
    return CR_OK;
}

cr_status cr_uv_lookup_build(const cr_mesh *m, int32_t grid_res, cr_uv_lookup **out,
                             cr_error *err) {
    *out = NULL;
    if (!cr_mesh_has_uv(m))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "uv lookup: the mesh has no UVs (export it with texture coordinates)");
    if (grid_res < 0 || grid_res > GRID_RES_MAX)
        return CR_FAIL(err, CR_ERR_INVALID, "uv lookup: grid_res = %d, expected 0..%d", grid_res,
                       GRID_RES_MAX);
    cr_uv_lookup *lk = cr_calloc(1, sizeof *lk, err);
    if (!lk) return CR_ERR_MEMORY;
    lk->nf = m->nf;
    cr_status st = copy_faces(m, lk, err);
    if (st != CR_OK) goto fail;

    double w = lk->hi[0] - lk->lo[0], h = lk->hi[1] - lk->lo[1];
    if (grid_res > 0) {
        lk->n[0] = lk->n[1] = grid_res;
    } else {
        /* About one cell per face, cells near square. */
        double ww = w > 0 ? w : 1.0, hh = h > 0 ? h : 1.0, nf = m->nf > 0 ? m->nf : 1;
        double nu = ceil(sqrt(nf * ww / hh)), nv = ceil(sqrt(nf * hh / ww));
        lk->n[0] = (int32_t)fmin(fmax(nu, 1.0), AUTO_GRID_MAX);
        lk->n[1] = (int32_t)fmin(fmax(nv, 1.0), AUTO_GRID_MAX);
    }
    lk->cell[0] = w > 0 ? w / lk->n[0] : 1.0;
    lk->cell[1] = h > 0 ? h / lk->n[1] : 1.0;

    int64_t ncell = (int64_t)lk->n[0] * lk->n[1];
    lk->cell_off = cr_calloc((size_t)ncell + 1, sizeof(int32_t), err);
    if (!lk->cell_off) {
        st = CR_ERR_MEMORY;
        goto fail;
    }
    int64_t total = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (lk->det[f] == 0.0) continue;
        int32_t c0[2], c1[2];
        face_cells(lk, f, c0, c1);
        for (int32_t j = c0[1]; j <= c1[1]; j++)
            for (int32_t i = c0[0]; i <= c1[0]; i++)
                lk->cell_off[(int64_t)j * lk->n[0] + i + 1]++;
        total += (int64_t)(c1[0] - c0[0] + 1) * (c1[1] - c0[1] + 1);
    }
    if (total > INT32_MAX) {
        st = CR_FAIL(err, CR_ERR_INVALID,
                     "uv lookup: %lld cell entries overflow; use a coarser grid_res than %d",
                     (long long)total, grid_res);
        goto fail;
    }
    for (int64_t c = 0; c < ncell; c++)
        lk->cell_off[c + 1] += lk->cell_off[c];
    lk->cell_face = cr_malloc((size_t)total * sizeof(int32_t) + 1, err);
    int32_t *fill = cr_malloc((size_t)ncell * sizeof(int32_t), err);
    if (!lk->cell_face || !fill) {
        free(fill);
        st = CR_ERR_MEMORY;
        goto fail;
    }
    memcpy(fill, lk->cell_off, (size_t)ncell * sizeof(int32_t));
    for (int32_t f = 0; f < m->nf; f++) {
        if (lk->det[f] == 0.0) continue;
        int32_t c0[2], c1[2];
        face_cells(lk, f, c0, c1);
        for (int32_t j = c0[1]; j <= c1[1]; j++)
            for (int32_t i = c0[0]; i <= c1[0]; i++)
                lk->cell_face[fill[(int64_t)j * lk->n[0] + i]++] = f;
    }
    free(fill);
    *out = lk;
    return CR_OK;
fail:
    cr_uv_lookup_destroy(lk);
    return st;
}

int cr_uv_lookup_find(const cr_uv_lookup *lk, float u, float v, int32_t *face, double bary[3]) {
    *face = -1;
    if (!isfinite(u) || !isfinite(v)) return 0;
    int64_t c = (int64_t)cell_coord(lk, 1, v) * lk->n[0] + cell_coord(lk, 0, u);
    double best = -INFINITY, bb[3] = {0, 0, 0};
    for (int32_t p = lk->cell_off[c]; p < lk->cell_off[c + 1]; p++) {
        int32_t f = lk->cell_face[p];
        double b[3];
        double lo = face_bary(lk, f, u, v, b);
        if (lo > best) {
            best = lo, *face = f;
            memcpy(bb, b, sizeof bb);
            /* well inside: no other face of a chart that does not overlap
             * itself can hold the point as deeply, so the cell's other faces
             * are not tested (half of a drape epoch's lookups' work) */
            if (lo > INSIDE_STOP) break;
        }
    }
    if (*face < 0 || best < -CR_UV_LOOKUP_EPS) {
        *face = -1;
        return 0;
    }
    memcpy(bary, bb, sizeof bb);
    return 1;
}

/* Squared distance from (u, v) to face f and the barycentrics of the closest point. */
static double face_closest(const cr_uv_lookup *lk, int32_t f, double u, double v, double b[3]) {
    if (face_bary(lk, f, u, v, b) >= 0.0) return 0.0;
    const double *c = &lk->corner[6 * (size_t)f];
    double best = INFINITY;
    for (int k = 0; k < 3; k++) {
        int k1 = (k + 1) % 3;
        double ex = c[2 * k1] - c[2 * k], ey = c[2 * k1 + 1] - c[2 * k + 1];
        double px = u - c[2 * k], py = v - c[2 * k + 1];
        double len2 = ex * ex + ey * ey;
        double s = len2 > 0 ? (px * ex + py * ey) / len2 : 0.0;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        double dx = px - s * ex, dy = py - s * ey, d2 = dx * dx + dy * dy;
        if (d2 < best) {
            best = d2;
            b[k] = 1.0 - s, b[k1] = s, b[(k + 2) % 3] = 0.0;
        }
    }
    return best;
}

int cr_uv_lookup_nearest(const cr_uv_lookup *lk, float u, float v, int32_t *face, double bary[3],
                         double *dist) {
    if (cr_uv_lookup_find(lk, u, v, face, bary)) {
        if (dist) *dist = 0.0;
        return 1;
    }
    *face = -1;
    if (!isfinite(u) || !isfinite(v)) return 0;
    int32_t ci = cell_coord(lk, 0, u), cj = cell_coord(lk, 1, v);
    double cmin = fmin(lk->cell[0], lk->cell[1]);
    double best2 = INFINITY;
    int32_t rmax = lk->n[0] > lk->n[1] ? lk->n[0] : lk->n[1];
    /* The point's projection onto the grid lies in cell (ci, cj), so every cell
     * of ring r (Chebyshev distance r) is at least (r - 1) cells away. */
    for (int32_t r = 0; r <= rmax; r++) {
        double lb = r > 0 ? (r - 1) * cmin : 0.0;
        if (*face >= 0 && lb * lb > best2) break;
        for (int32_t j = cj - r; j <= cj + r; j++) {
            if (j < 0 || j >= lk->n[1]) continue;
            int on_edge_row = j == cj - r || j == cj + r;
            for (int32_t i = ci - r; i <= ci + r; i += on_edge_row ? 1 : 2 * r) {
                if (i >= 0 && i < lk->n[0]) {
                    int64_t c = (int64_t)j * lk->n[0] + i;
                    for (int32_t p = lk->cell_off[c]; p < lk->cell_off[c + 1]; p++) {
                        int32_t f = lk->cell_face[p];
                        double b[3];
                        double d2 = face_closest(lk, f, u, v, b);
                        if (d2 < best2) {
                            best2 = d2, *face = f;
                            memcpy(bary, b, 3 * sizeof(double));
                        }
                    }
                }
                if (r == 0) break;
            }
        }
    }
    if (*face < 0) return 0;
    if (dist) *dist = sqrt(best2);
    return 1;
}

void cr_uv_lookup_interpolate(const cr_uv_lookup *lk, const float *attr, int32_t dim, int32_t face,
                              const double bary[3], float *out) {
    CR_ASSERT(face >= 0 && face < lk->nf);
    const int32_t *t = &lk->tri[3 * (size_t)face];
    for (int32_t d = 0; d < dim; d++) {
        double s = 0.0;
        for (int k = 0; k < 3; k++)
            s += bary[k] * attr[(size_t)t[k] * dim + d];
        out[d] = (float)s;
    }
}

int cr_uv_lookup_rest_position(const cr_uv_lookup *lk, const float *pos, float u, float v,
                               float out[3]) {
    int32_t f;
    double b[3];
    if (!cr_uv_lookup_find(lk, u, v, &f, b)) return 0;
    cr_uv_lookup_interpolate(lk, pos, 3, f, b, out);
    return 1;
}

void cr_uv_lookup_bounds(const cr_uv_lookup *lk, float lo[2], float hi[2]) {
    for (int a = 0; a < 2; a++)
        lo[a] = (float)lk->lo[a], hi[a] = (float)lk->hi[a];
}

void cr_uv_lookup_grid_size(const cr_uv_lookup *lk, int32_t *nu, int32_t *nv) {
    *nu = lk->n[0];
    *nv = lk->n[1];
}
