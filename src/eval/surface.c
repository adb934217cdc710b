/* surface.c: measures of one surface or two: the symmetric Chamfer distance
 * between two surfaces, the signed mean curvature, its RMS and its spectrum
 * over the UV chart (the drape paper's fidelity measures, moved here from
 * methods/drape/measure.c so every method and crease eval share them).
 *
 * The spectrum answers "how much fine wrinkle detail": a fold of wavelength
 * lambda puts mean curvature at that wavelength, so the share of the
 * curvature field's power below a few centimetres measures wrinkling,
 * independently of the overall shape (which the Chamfer distance measures).
 *
 * Leaves out: Hausdorff distance. The 256-point DFT is a radix-2 FFT per row
 * and column (crease eval takes the spectrum at every frame).
 */
#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/eval.h"
#include "crease/topology.h"
#include "crease/uvlookup.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* V vertices, S spectrum grid side. */

enum { SPECTRUM_SIDE = 256 };

const double cr_eval_h_band_edges_m[CR_EVAL_H_BANDS + 1] = {INFINITY, 0.16, 0.08, 0.04, 0.02, 0.0};

cr_status cr_eval_mean_curvature(const cr_mesh *m, float *H, cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    cr_csr L = {0};
    cr_status st = cr_cotan_laplacian(m, t, &L, err);
    double *x = cr_malloc((size_t)m->nv * 3 * sizeof(double), err);
    double *y = cr_malloc((size_t)m->nv * 3 * sizeof(double), err);
    float *n = cr_malloc((size_t)m->nv * 3 * sizeof(float), err);
    float *a = cr_malloc((size_t)m->nv * sizeof(float), err);
    if (st == CR_OK && (!x || !y || !n || !a)) st = CR_ERR_MEMORY;
    if (st == CR_OK) {
        for (int64_t i = 0; i < 3 * (int64_t)m->nv; i++)
            x[i] = m->pos[i];
        cr_csr_mul(&L, x, 3, y);
        cr_mesh_vertex_normals(m, CR_NORMAL_ANGLE, n);
        cr_mesh_vertex_areas(m, CR_AREA_MIXED_VORONOI, a);
        for (int32_t i = 0; i < m->nv; i++) {
            double d =
                y[3 * i] * n[3 * i] + y[3 * i + 1] * n[3 * i + 1] + y[3 * i + 2] * n[3 * i + 2];
            H[i] = t->vertex_boundary[i] || !(a[i] > 0.0f) ? 0.0f : (float)(d / (2.0 * a[i]));
        }
    }
    free(x), free(y), free(n), free(a);
    cr_csr_free(&L);
    cr_topology_destroy(t);
    return st;
}

float cr_eval_chart_scale(const cr_mesh *m) {
    if (!cr_mesh_has_uv(m)) return 1.0f;
    double a3 = 0.0, a2 = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        float n[3];
        const int32_t *t = &m->tri[3 * (int64_t)f], *tu = &m->tri_uv[3 * (int64_t)f];
        a3 += 0.5 * cr_triangle_normal(&m->pos[3 * (int64_t)t[0]], &m->pos[3 * (int64_t)t[1]],
                                       &m->pos[3 * (int64_t)t[2]], n);
        const float *p = &m->uv[2 * (int64_t)tu[0]], *q = &m->uv[2 * (int64_t)tu[1]],
                    *r = &m->uv[2 * (int64_t)tu[2]];
        a2 += 0.5 * fabs(((double)q[0] - p[0]) * ((double)r[1] - p[1]) -
                         ((double)q[1] - p[1]) * ((double)r[0] - p[0]));
    }
    return a2 > 0.0 ? (float)sqrt(a3 / a2) : 1.0f;
}

/* In-place DFT of `len` (a power of two) complex values (re, im interleaved)
 * with stride `stride`, X_k = sum_j x_j e^(-2 pi i k j / len), by the
 * radix-2 FFT on a contiguous copy; cs, sn the cosines and sines of 2 pi k /
 * len. */
static void dft(double *data, int len, int64_t stride, const double *cs, const double *sn,
                double *tmp) {
    for (int j = 0, r = 0; j < len; j++) { /* bit-reversed order */
        tmp[2 * r] = data[2 * j * stride], tmp[2 * r + 1] = data[2 * j * stride + 1];
        int bit = len >> 1;
        for (; r & bit; bit >>= 1)
            r ^= bit;
        r |= bit;
    }
    for (int m = 2; m <= len; m <<= 1)
        for (int base = 0; base < len; base += m)
            for (int j = 0; j < m / 2; j++) {
                int w = j * (len / m);
                double *a = &tmp[2 * (base + j)], *b = &tmp[2 * (base + j + m / 2)];
                double br = b[0] * cs[w] + b[1] * sn[w], bi = b[1] * cs[w] - b[0] * sn[w];
                b[0] = a[0] - br, b[1] = a[1] - bi;
                a[0] += br, a[1] += bi;
            }
    for (int k = 0; k < len; k++)
        data[2 * k * stride] = tmp[2 * k], data[2 * k * stride + 1] = tmp[2 * k + 1];
}

typedef struct dft_job {
    double *f;
    const double *cs, *sn;
    int axis; /* 0: rows, 1: columns */
} dft_job;

static void dft_range(void *p, int64_t begin, int64_t end) {
    const dft_job *j = p;
    double tmp[2 * SPECTRUM_SIDE];
    for (int64_t r = begin; r < end; r++) {
        if (j->axis == 0)
            dft(j->f + 2 * r * SPECTRUM_SIDE, SPECTRUM_SIDE, 1, j->cs, j->sn, tmp);
        else
            dft(j->f + 2 * r, SPECTRUM_SIDE, SPECTRUM_SIDE, j->cs, j->sn, tmp);
    }
}

/* Power of the mean-removed field per wavelength band, as shares of the
 * total (band) and, when power is not NULL, in the field's units squared. */
static cr_status spectrum(const cr_mesh *m, const float *H, double band[], double power[],
                          cr_error *err) {
    const int S = SPECTRUM_SIDE;
    cr_uv_lookup *lk = NULL;
    CR_TRY(cr_uv_lookup_build(m, 0, &lk, err));
    double *f = cr_calloc((size_t)S * S * 2, sizeof(double), err);
    double *cs = cr_malloc((size_t)S * sizeof(double), err);
    double *sn = cr_malloc((size_t)S * sizeof(double), err);
    uint8_t *in = cr_calloc((size_t)S * S, 1, err);
    cr_status st = f && cs && sn && in ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        double mean = 0.0;
        int64_t count = 0;
        for (int i = 0; i < S; i++)
            for (int j = 0; j < S; j++) {
                int32_t face;
                double b[3];
                float h;
                if (!cr_uv_lookup_find(lk, (j + 0.5f) / S, (i + 0.5f) / S, &face, b)) continue;
                cr_uv_lookup_interpolate(lk, H, 1, face, b, &h);
                f[2 * ((int64_t)i * S + j)] = h;
                in[(int64_t)i * S + j] = 1;
                mean += h, count++;
            }
        mean = count ? mean / count : 0.0;
        for (int64_t k = 0; k < (int64_t)S * S; k++)
            if (in[k]) f[2 * k] -= mean;
        for (int k = 0; k < S; k++)
            cs[k] = cos(2.0 * M_PI * k / S), sn[k] = sin(2.0 * M_PI * k / S);
        dft_job job = {.f = f, .cs = cs, .sn = sn, .axis = 0};
        cr_parallel_for(S, 8, dft_range, &job);
        job.axis = 1;
        cr_parallel_for(S, 8, dft_range, &job);
        double mpu = cr_eval_chart_scale(m), total = 0.0;
        for (int b = 0; b < CR_EVAL_H_BANDS; b++)
            band[b] = 0.0;
        for (int i = 0; i < S; i++)
            for (int j = 0; j < S; j++) {
                int ki = i < S / 2 ? i : i - S, kj = j < S / 2 ? j : j - S;
                double k = sqrt((double)ki * ki + (double)kj * kj);
                if (k == 0.0) continue;
                double lambda = mpu / k, *c = &f[2 * ((int64_t)i * S + j)];
                double p = c[0] * c[0] + c[1] * c[1];
                total += p;
                for (int b = 0; b < CR_EVAL_H_BANDS; b++)
                    if (lambda < cr_eval_h_band_edges_m[b] &&
                        lambda >= cr_eval_h_band_edges_m[b + 1])
                        band[b] += p;
            }
        /* Parseval: sum_k |F_k|^2 = S^2 sum_x f(x)^2, and f is 0 off the chart */
        const double per_pixel = count ? 1.0 / ((double)S * S * (double)count) : 0.0;
        for (int b = 0; power && b < CR_EVAL_H_BANDS; b++)
            power[b] = band[b] * per_pixel;
        for (int b = 0; total > 0.0 && b < CR_EVAL_H_BANDS; b++)
            band[b] /= total;
    }
    free(f), free(cs), free(sn), free(in);
    cr_uv_lookup_destroy(lk);
    return st;
}

cr_status cr_eval_curvature_spectrum(const cr_mesh *m, double *h_rms, double band[CR_EVAL_H_BANDS],
                                     double power[CR_EVAL_H_BANDS], cr_error *err) {
    if (!cr_mesh_has_uv(m))
        return CR_FAIL(err, CR_ERR_INVALID, "curvature spectrum: the surface needs UVs");
    float *H = cr_malloc((size_t)m->nv * sizeof(float) + 1, err);
    float *area = cr_malloc((size_t)m->nv * sizeof(float) + 1, err);
    cr_status st = H && area ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_eval_mean_curvature(m, H, err);
    if (st == CR_OK) {
        double s = 0.0, a = 0.0;
        cr_mesh_vertex_areas(m, CR_AREA_MIXED_VORONOI, area);
        for (int32_t i = 0; i < m->nv; i++)
            s += (double)area[i] * H[i] * H[i], a += area[i];
        *h_rms = a > 0.0 ? sqrt(s / a) : 0.0;
    }
    if (st == CR_OK) st = spectrum(m, H, band, power, err);
    free(H), free(area);
    return st;
}

/* Mean distance from a's vertices to b's surface. */
static double mean_closest(const cr_mesh *a, const cr_bvh *b, cr_error *err, cr_status *st) {
    float *d = cr_malloc((size_t)a->nv * sizeof(float) + 1, err);
    if (!d) {
        *st = CR_ERR_MEMORY;
        return NAN;
    }
    cr_bvh_closest_batch(b, a->pos, a->nv, INFINITY, NULL, NULL, NULL, d);
    double s = 0.0;
    for (int32_t i = 0; i < a->nv; i++)
        s += d[i];
    free(d);
    return a->nv ? s / a->nv : NAN;
}

cr_status cr_eval_chamfer_surface(const cr_mesh *a, const cr_mesh *b, double *out, cr_error *err) {
    *out = NAN;
    cr_bvh *ab = NULL, *bb = NULL;
    cr_status st = cr_bvh_build(a->pos, a->nv, a->tri, a->nf, &ab, err);
    if (st == CR_OK) st = cr_bvh_build(b->pos, b->nv, b->tri, b->nf, &bb, err);
    if (st == CR_OK) {
        double d_ab = mean_closest(a, bb, err, &st);
        double d_ba = st == CR_OK ? mean_closest(b, ab, err, &st) : NAN;
        if (st == CR_OK) *out = 0.5 * (d_ab + d_ba);
    }
    cr_bvh_destroy(ab), cr_bvh_destroy(bb);
    return st;
}
