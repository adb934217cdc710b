/* laplacian.c: cotangent Laplacian (CSR), vertex areas, mean curvature.
 *
 * Each face adds half the cotangent of each corner angle to the weight of the
 * opposite edge, which gives w_ij = (cot alpha_ij + cot beta_ij) / 2 summed
 * over the faces on edge ij (Pinkall & Polthier, "Computing discrete minimal
 * surfaces and their conjugates", 1993). Mixed Voronoi areas and the mean
 * curvature normal K(x_i) = (L x)_i / A_i = 2 H n follow Meyer, Desbrun,
 * Schroeder & Barr, "Discrete differential-geometry operators for triangulated
 * 2-manifolds" (2003), eq. 8 and fig. 4.
 *
 * Left out: intrinsic-Delaunay or robust Laplacians (Sharp & Crane 2020) for
 * meshes with many obtuse or needle triangles, and Gaussian curvature.
 */
#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Corner geometry of one face, all in double: cot[k] is the cotangent of the
 * angle at corner k, len2[k] the squared length of the edge opposite it. */
typedef struct face_corners {
    double cot[3];
    double len2[3];
    double area;
} face_corners;

static void corners_of(const float *pos, const int32_t *t, face_corners *fc) {
    const float *p[3] = {&pos[3 * (size_t)t[0]], &pos[3 * (size_t)t[1]], &pos[3 * (size_t)t[2]]};
    double twice_area = 0.0;
    for (int k = 0; k < 3; k++) {
        const float *a = p[k], *b = p[(k + 1) % 3], *c = p[(k + 2) % 3];
        double u[3], v[3];
        for (int d = 0; d < 3; d++)
            u[d] = (double)b[d] - a[d], v[d] = (double)c[d] - a[d];
        double cx = u[1] * v[2] - u[2] * v[1];
        double cy = u[2] * v[0] - u[0] * v[2];
        double cz = u[0] * v[1] - u[1] * v[0];
        double cr = sqrt(cx * cx + cy * cy + cz * cz);
        double dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        fc->cot[k] = cr > 0.0 ? dot / cr : 0.0;
        double w[3] = {v[0] - u[0], v[1] - u[1], v[2] - u[2]};
        fc->len2[k] = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        if (k == 0) twice_area = cr;
    }
    fc->area = 0.5 * twice_area;
}

void cr_csr_free(cr_csr *a) {
    free(a->row_ptr);
    free(a->col);
    free(a->val);
    memset(a, 0, sizeof *a);
}

void cr_csr_mul(const cr_csr *a, const double *x, int32_t k, double *y) {
    for (int32_t i = 0; i < a->n; i++) {
        double *yi = &y[(size_t)i * k];
        for (int32_t c = 0; c < k; c++)
            yi[c] = 0.0;
        for (int64_t p = a->row_ptr[i]; p < a->row_ptr[i + 1]; p++) {
            const double *xj = &x[(size_t)a->col[p] * k];
            for (int32_t c = 0; c < k; c++)
                yi[c] += a->val[p] * xj[c];
        }
    }
}

/* Position of column j in row i (columns ascending), -1 when absent. */
static int64_t csr_find(const cr_csr *a, int32_t i, int32_t j) {
    int64_t lo = a->row_ptr[i], hi = a->row_ptr[i + 1] - 1;
    while (lo <= hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (a->col[mid] == j) return mid;
        if (a->col[mid] < j)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

cr_status cr_cotan_laplacian(const cr_mesh *m, const cr_topology *t, cr_csr *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    CR_TRY(cr_topology_check_mesh(t, m, "cotan Laplacian", err));
    cr_csr a = {0};
    a.n = m->nv;
    a.nnz = (int64_t)m->nv + 2 * (int64_t)t->ne;
    a.row_ptr = cr_malloc(((size_t)m->nv + 1) * sizeof(int64_t), err);
    a.col = cr_malloc((size_t)a.nnz * sizeof(int32_t) + 1, err);
    a.val = cr_calloc((size_t)a.nnz + 1, sizeof(double), err);
    if (!a.row_ptr || !a.col || !a.val) {
        cr_csr_free(&a);
        return CR_ERR_MEMORY;
    }
    /* Row i: the ascending neighbours of i with i merged in at its place. */
    for (int32_t i = 0; i < m->nv; i++) {
        int64_t p = (int64_t)t->vv_off[i] + i;
        a.row_ptr[i] = p;
        int placed = 0;
        for (int32_t q = t->vv_off[i]; q < t->vv_off[i + 1]; q++) {
            if (!placed && t->vv[q] > i) a.col[p++] = i, placed = 1;
            a.col[p++] = t->vv[q];
        }
        if (!placed) a.col[p++] = i;
    }
    a.row_ptr[m->nv] = a.nnz;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *tri = &m->tri[3 * f];
        face_corners fc;
        corners_of(m->pos, tri, &fc);
        if (fc.area == 0.0) continue;
        for (int k = 0; k < 3; k++) {
            int32_t i = tri[(k + 1) % 3], j = tri[(k + 2) % 3];
            double w = 0.5 * fc.cot[k];
            int64_t pij = csr_find(&a, i, j), pji = csr_find(&a, j, i);
            int64_t pii = csr_find(&a, i, i), pjj = csr_find(&a, j, j);
            CR_ASSERT(pij >= 0 && pji >= 0 && pii >= 0 && pjj >= 0);
            a.val[pij] -= w, a.val[pji] -= w;
            a.val[pii] += w, a.val[pjj] += w;
        }
    }
    *out = a;
    return CR_OK;
}

/* Mixed Voronoi share of each corner of one face (Meyer et al. 2003, fig. 4). */
static void mixed_voronoi(const face_corners *fc, double share[3]) {
    int obtuse = -1;
    for (int k = 0; k < 3; k++)
        if (fc->cot[k] < 0.0) obtuse = k;
    for (int k = 0; k < 3; k++) {
        if (obtuse < 0) {
            /* Voronoi region of corner k: 1/8 sum over its two edges of
             * |edge|^2 cot(angle opposite that edge). */
            int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
            share[k] = 0.125 * (fc->len2[k1] * fc->cot[k1] + fc->len2[k2] * fc->cot[k2]);
        } else {
            share[k] = obtuse == k ? 0.5 * fc->area : 0.25 * fc->area;
        }
    }
}

void cr_mesh_vertex_areas(const cr_mesh *m, cr_vertex_area kind, float *area) {
    for (int32_t v = 0; v < m->nv; v++)
        area[v] = 0.0f;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *tri = &m->tri[3 * f];
        face_corners fc;
        corners_of(m->pos, tri, &fc);
        double share[3] = {fc.area / 3.0, fc.area / 3.0, fc.area / 3.0};
        if (kind == CR_AREA_MIXED_VORONOI && fc.area > 0.0) mixed_voronoi(&fc, share);
        for (int k = 0; k < 3; k++)
            area[tri[k]] += (float)share[k];
    }
}

cr_status cr_mesh_mean_curvature(const cr_mesh *m, const cr_topology *t, float *H, cr_error *err) {
    CR_TRY(cr_topology_check_mesh(t, m, "mean curvature", err));
    /* lx (V,3) then area (V), both accumulated in double. */
    double *acc = cr_calloc((size_t)m->nv * 4 + 1, sizeof(double), err);
    if (!acc) return CR_ERR_MEMORY;
    double *lx = acc, *area = acc + 3 * (size_t)m->nv;
    const float *pos = m->pos;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *tri = &m->tri[3 * f];
        face_corners fc;
        corners_of(pos, tri, &fc);
        if (fc.area == 0.0) continue;
        double share[3];
        mixed_voronoi(&fc, share);
        for (int k = 0; k < 3; k++) {
            area[tri[k]] += share[k];
            int32_t i = tri[(k + 1) % 3], j = tri[(k + 2) % 3];
            double w = 0.5 * fc.cot[k];
            for (int d = 0; d < 3; d++) {
                double dx = (double)pos[3 * (size_t)i + d] - pos[3 * (size_t)j + d];
                lx[3 * (size_t)i + d] += w * dx;
                lx[3 * (size_t)j + d] -= w * dx;
            }
        }
    }
    for (int32_t v = 0; v < m->nv; v++) {
        const double *l = &lx[3 * (size_t)v];
        double len = sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
        H[v] = (t->vertex_boundary[v] || area[v] <= 0.0) ? 0.0f : (float)(len / (2.0 * area[v]));
    }
    free(acc);
    return CR_OK;
}
