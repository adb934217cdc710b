/* compare.c: the drape method's fidelity report against a reference drape
 * (Chamfer distance, penetration, mean-curvature spectrum) and the
 * side-by-side run of all four variants (the paper's Fig. 1 and 8-10).
 *
 * The spectrum answers "how much fine wrinkle detail": a fold of wavelength
 * lambda puts mean curvature at that wavelength, so the share of the
 * curvature field's power below a few centimetres measures wrinkling,
 * independently of the overall drape shape (which the Chamfer distance
 * measures).
 *
 * Leaves out: Hausdorff distance, curvature of the reference computed any
 * other way than the method's own surfaces (both go through the same code).
 */
#include "drape_internal.h"

#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* V vertices, S spectrum grid side. */

enum { SPECTRUM_SIDE = 256, LABEL_STRIP_PX = 44, COMPARE_RENDER_PX = 640 };

const double cr_drape_h_band_edges_m[CR_DRAPE_H_BANDS + 1] = {INFINITY, 0.16, 0.08,
                                                              0.04,     0.02, 0.0};

/* (L x)_i . n_i / (2 A_i): 1/R on a sphere with outward normals; 0 on the boundary. */
static cr_status signed_mean_curvature(const cr_mesh *m, float *H, cr_error *err) {
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

/* In-place DFT of `len` complex values (re, im interleaved) with stride `stride`. */
static void dft(double *data, int len, int64_t stride, const double *cs, const double *sn,
                double *tmp) {
    for (int k = 0; k < len; k++) {
        double re = 0.0, im = 0.0;
        for (int j = 0; j < len; j++) {
            int w = (int)(((int64_t)k * j) % len);
            double xr = data[2 * j * stride], xi = data[2 * j * stride + 1];
            re += xr * cs[w] + xi * sn[w];
            im += xi * cs[w] - xr * sn[w];
        }
        tmp[2 * k] = re, tmp[2 * k + 1] = im;
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

/* Power of the mean-removed field per wavelength band, as shares of the total. */
static cr_status curvature_spectrum(const cr_mesh *m, const float *H, double band[],
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
        double mpu = cr_drape_chart_scale(m), total = 0.0;
        for (int b = 0; b < CR_DRAPE_H_BANDS; b++)
            band[b] = 0.0;
        for (int i = 0; i < S; i++)
            for (int j = 0; j < S; j++) {
                int ki = i < S / 2 ? i : i - S, kj = j < S / 2 ? j : j - S;
                double k = sqrt((double)ki * ki + (double)kj * kj);
                if (k == 0.0) continue;
                double lambda = mpu / k, *c = &f[2 * ((int64_t)i * S + j)];
                double p = c[0] * c[0] + c[1] * c[1];
                total += p;
                for (int b = 0; b < CR_DRAPE_H_BANDS; b++)
                    if (lambda < cr_drape_h_band_edges_m[b] &&
                        lambda >= cr_drape_h_band_edges_m[b + 1])
                        band[b] += p;
            }
        for (int b = 0; total > 0.0 && b < CR_DRAPE_H_BANDS; b++)
            band[b] /= total;
    }
    free(f), free(cs), free(sn), free(in);
    cr_uv_lookup_destroy(lk);
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

cr_status cr_drape_fidelity_measure(const cr_mesh *surface, const cr_mesh *reference,
                                    const cr_mesh *object, cr_drape_fidelity *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    out->chamfer_m = NAN;
    if (!cr_mesh_has_uv(surface) || (reference && !cr_mesh_has_uv(reference)))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape fidelity: the surface and the reference need UVs for the spectrum");
    cr_bvh *ob = NULL, *sb = NULL, *rb = NULL;
    CR_TRY(cr_bvh_build(object->pos, object->nv, object->tri, object->nf, &ob, err));
    out->max_penetration_m = cr_drape_max_penetration(ob, surface);
    cr_bvh_destroy(ob);
    cr_status st = CR_OK;
    if (reference) {
        st = cr_bvh_build(surface->pos, surface->nv, surface->tri, surface->nf, &sb, err);
        if (st == CR_OK)
            st = cr_bvh_build(reference->pos, reference->nv, reference->tri, reference->nf, &rb,
                              err);
        if (st == CR_OK) {
            double ab = mean_closest(surface, rb, err, &st);
            double ba = st == CR_OK ? mean_closest(reference, sb, err, &st) : NAN;
            out->chamfer_m = 0.5 * (ab + ba);
        }
        cr_bvh_destroy(sb), cr_bvh_destroy(rb);
    }
    float *H = st == CR_OK ? cr_malloc((size_t)surface->nv * sizeof(float) + 1, err) : NULL;
    if (st == CR_OK && !H) st = CR_ERR_MEMORY;
    if (st == CR_OK) st = signed_mean_curvature(surface, H, err);
    if (st == CR_OK) {
        float *area = cr_malloc((size_t)surface->nv * sizeof(float) + 1, err);
        if (!area) st = CR_ERR_MEMORY;
        double s = 0.0, a = 0.0;
        if (st == CR_OK) {
            cr_mesh_vertex_areas(surface, CR_AREA_MIXED_VORONOI, area);
            for (int32_t i = 0; i < surface->nv; i++)
                s += (double)area[i] * H[i] * H[i], a += area[i];
        }
        free(area);
        out->h_rms = a > 0.0 ? sqrt(s / a) : 0.0;
    }
    if (st == CR_OK) st = curvature_spectrum(surface, H, out->h_band, err);
    free(H);
    return st;
}

/* ---------------------------------------------------------- compare -- */

/* The render with the variant's name underneath, into a new image. */
static cr_status labelled(const cr_image *render, const char *name, cr_image *out, cr_error *err) {
    CR_TRY(cr_image_create(render->width, render->height + LABEL_STRIP_PX, out, err));
    memset(out->rgb, 255, (size_t)out->width * out->height * 3);
    memcpy(out->rgb, render->rgb, (size_t)render->width * render->height * 3);
    const uint8_t ink[3] = {20, 20, 20};
    int scale = 3;
    cr_drape_text(out, (out->width - cr_drape_text_width(name, scale)) / 2, render->height + 10,
                  scale, name, ink);
    return CR_OK;
}

cr_status cr_drape_compare(const cr_drape_def *def, cr_drape_result *results, char *png_path,
                           size_t png_cap, cr_error *err) {
    CR_TRY(cr_drape_def_validate(def, err));
    if (!def->out_dir) return CR_FAIL(err, CR_ERR_INVALID, "drape compare: needs -o DIR");
    CR_TRY(cr_mkdir_p(def->out_dir, err));
    cr_mesh *object = NULL;
    CR_TRY(cr_drape_scene_object(def->scene, def->object_path, &object, err));
    cr_image cells[CR_DRAPE_VARIANT_COUNT] = {{0}};
    cr_status st = CR_OK;
    for (int v = 0; v < CR_DRAPE_VARIANT_COUNT && st == CR_OK; v++) {
        cr_drape_def d = *def;
        char dir[1200];
        snprintf(dir, sizeof dir, "%s/%s", def->out_dir,
                 cr_drape_variant_name((cr_drape_variant)v));
        d.variant = (cr_drape_variant)v;
        d.out_dir = dir;
        cr_drape_result res;
        cr_mesh *surface = NULL;
        st = cr_drape_run(&d, &res, &surface, err);
        if (st == CR_OK && results) results[v] = res;
        cr_image render = {0};
        if (st == CR_OK) st = cr_drape_render(surface, object, COMPARE_RENDER_PX, &render, err);
        if (st == CR_OK) st = labelled(&render, cr_drape_variant_name(d.variant), &cells[v], err);
        cr_image_free(&render);
        cr_mesh_destroy(surface);
    }
    cr_image grid = {0};
    const float white[3] = {1.0f, 1.0f, 1.0f};
    if (st == CR_OK) st = cr_image_grid(cells, CR_DRAPE_VARIANT_COUNT, 0, 8, white, &grid, err);
    if (st == CR_OK) {
        snprintf(png_path, png_cap, "%s/compare.png", def->out_dir);
        st = cr_image_write_png(&grid, png_path, err);
    }
    cr_image_free(&grid);
    for (int v = 0; v < CR_DRAPE_VARIANT_COUNT; v++)
        cr_image_free(&cells[v]);
    cr_mesh_destroy(object);
    return st;
}
