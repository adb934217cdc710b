/* primitives.c: procedural meshes (plane, UV sphere, icosphere, torus, prism, box, capsule,
 * cylinder), welded, outward-facing, with UVs in [0,1]^2 and seams only in UV.
 *
 * The round shapes (UV sphere, torus, capsule, cylinder) are one surface of
 * revolution around Y swept from a profile curve in the (r, y) half-plane; a
 * profile end on the axis (r = 0) becomes a single pole vertex. The icosphere
 * subdivides an icosahedron with a vertex at each pole, sharing edge midpoints
 * through a hash so the result stays welded; the box welds its six face grids
 * the same way, keyed by integer lattice coordinates.
 *
 * Left out: per-vertex normals (cr_mesh_compute_normals does them), tangents,
 * and any subdivision of the prism (it is the exact 8-triangle solid).
 */
#include "crease/primitives.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/* ------------------------------------------------------------- checks -- */

static cr_status check_length(double v, const char *fn, const char *name, cr_error *err) {
    if (!isfinite(v) || v <= 0)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %s must be finite and > 0, got %g", fn, name, v);
    return CR_OK;
}

static cr_status check_count(int32_t v, int32_t min, const char *fn, const char *name,
                             cr_error *err) {
    if (v < min)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %s must be >= %d, got %d", fn, name, min, v);
    return CR_OK;
}

/* Counts are estimated in double so products of large parameters cannot wrap. */
static cr_status check_size(double nv, double nf, double nuv, const char *fn, const char *params,
                            cr_error *err) {
    if (nv > INT32_MAX || nf > INT32_MAX || nuv > INT32_MAX)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: %s give %.0f vertices, %.0f faces and %.0f UVs, more than int32 holds",
                       fn, params, nv, nf, nuv);
    return CR_OK;
}

/* ---------------------------------------------------------------- hash -- */

/* Open-addressing map from 64-bit keys to int32 values, used to weld shared
 * edge midpoints (icosphere) and lattice points (box). */
typedef struct u64_map {
    uint64_t *keys; /* EMPTY_KEY marks a free slot */
    int32_t *vals;
    uint64_t mask;
} u64_map;

static const uint64_t EMPTY_KEY = UINT64_MAX;

static cr_status map_init(u64_map *m, int64_t n, cr_error *err) {
    uint64_t cap = 16;
    while (cap < (uint64_t)n * 2)
        cap <<= 1;
    m->mask = cap - 1;
    m->keys = cr_malloc(cap * sizeof *m->keys, err);
    m->vals = cr_malloc(cap * sizeof *m->vals, err);
    if (!m->keys || !m->vals) {
        free(m->keys), free(m->vals);
        m->keys = NULL, m->vals = NULL;
        return CR_ERR_MEMORY;
    }
    memset(m->keys, 0xff, cap * sizeof *m->keys);
    return CR_OK;
}

static void map_free(u64_map *m) {
    free(m->keys);
    free(m->vals);
}

static uint64_t mix64(uint64_t x) { /* splitmix64 finaliser */
    x ^= x >> 30, x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27, x *= 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

/* Value stored under `key`, inserting `val_if_new` (and setting *inserted) when absent. */
static int32_t map_get_or_put(u64_map *m, uint64_t key, int32_t val_if_new, int *inserted) {
    uint64_t h = mix64(key) & m->mask;
    while (m->keys[h] != EMPTY_KEY) {
        if (m->keys[h] == key) {
            *inserted = 0;
            return m->vals[h];
        }
        h = (h + 1) & m->mask;
    }
    m->keys[h] = key;
    m->vals[h] = val_if_new;
    *inserted = 1;
    return val_if_new;
}

/* ---------------------------------------------------------------- plane -- */

cr_status cr_prim_plane(int32_t nx, int32_t nz, float size_x, float size_z, cr_mesh **out,
                        cr_error *err) {
    static const char *fn = "cr_prim_plane";
    *out = NULL;
    CR_TRY(check_count(nx, 2, fn, "nx", err));
    CR_TRY(check_count(nz, 2, fn, "nz", err));
    CR_TRY(check_length(size_x, fn, "size_x", err));
    CR_TRY(check_length(size_z, fn, "size_z", err));
    double nv = (double)nx * nz, nf = 2.0 * (nx - 1) * (nz - 1);
    CR_TRY(check_size(nv, nf, nv, fn, "nx, nz", err));
    cr_mesh *m;
    CR_TRY(cr_mesh_create((int32_t)nv, (int32_t)nf, (int32_t)nv, &m, err));
    for (int32_t k = 0; k < nz; k++) {
        for (int32_t i = 0; i < nx; i++) {
            size_t v = (size_t)k * nx + i;
            double u = (double)i / (nx - 1), w = (double)k / (nz - 1);
            m->pos[3 * v + 0] = (float)((u - 0.5) * size_x);
            m->pos[3 * v + 1] = 0.0f;
            m->pos[3 * v + 2] = (float)((w - 0.5) * size_z);
            m->uv[2 * v + 0] = (float)u;
            m->uv[2 * v + 1] = (float)w;
        }
    }
    size_t f = 0;
    for (int32_t k = 0; k + 1 < nz; k++) {
        for (int32_t i = 0; i + 1 < nx; i++) {
            int32_t a = k * nx + i, b = a + 1, c = a + nx, d = c + 1;
            /* (a, c, b): x-step cross z-step is -Y, so z-step first for +Y. */
            int32_t t[6] = {a, c, b, b, c, d};
            memcpy(&m->tri[3 * f], t, sizeof t);
            memcpy(&m->tri_uv[3 * f], t, sizeof t);
            f += 2;
        }
    }
    *out = m;
    return CR_OK;
}

/* ------------------------------------------------------- revolution -- */

/* Sweep a profile of K points (r[k], y[k]) around Y with `segments` columns:
 * vertex (k, j) = (r cos phi, y, -r sin phi), phi = 2 pi j / segments. The
 * profile runs so that its tangent turned +90 degrees in the (r, y) plane
 * points out of the solid (top to bottom on the outside); that makes the
 * triangles (k,j), (k+1,j), (k,j+1) face outward. r == 0 at an open end
 * makes a pole. `closed` joins the last profile point back to the first
 * (torus). u = j / segments (seam column duplicated in UV), v = 1 - arc
 * length fraction along the profile. */
static cr_status revolve(const double *r, const double *y, int32_t K, int closed, int32_t segments,
                         cr_mesh **out, cr_error *err) {
    int pole0 = !closed && r[0] == 0.0, pole1 = !closed && r[K - 1] == 0.0;
    int32_t bands = closed ? K : K - 1;
    int32_t uv_rows = closed ? K + 1 : K;
    int64_t nv = (int64_t)K * segments - (pole0 + pole1) * (int64_t)(segments - 1);
    int64_t nf = 2 * (int64_t)bands * segments - (pole0 + pole1) * (int64_t)segments;
    int64_t nuv = (int64_t)uv_rows * (segments + 1) - (pole0 + pole1);
    cr_mesh *m;
    CR_TRY(cr_mesh_create((int32_t)nv, (int32_t)nf, (int32_t)nuv, &m, err));
    int32_t *row = cr_malloc((size_t)uv_rows * 2 * sizeof(int32_t), err);
    double *v_of = cr_malloc((size_t)uv_rows * sizeof(double), err);
    if (!row || !v_of) {
        free(row), free(v_of);
        cr_mesh_destroy(m);
        return CR_ERR_MEMORY;
    }
    int32_t *uv_row = row + uv_rows; /* first UV index of each UV row */

    /* Arc length along the profile gives v. */
    v_of[0] = 0;
    for (int32_t k = 1; k < uv_rows; k++) {
        int32_t a = k - 1, b = k % K;
        v_of[k] = v_of[k - 1] + hypot(r[b] - r[a], y[b] - y[a]);
    }
    double total = v_of[uv_rows - 1];
    for (int32_t k = 0; k < uv_rows; k++)
        v_of[k] = 1.0 - v_of[k] / total;

    int32_t nvtx = 0, nuvs = 0;
    for (int32_t k = 0; k < uv_rows; k++) {
        int pole = (k == 0 && pole0) || (k == K - 1 && pole1);
        if (k < K) {
            row[k] = nvtx;
            for (int32_t j = 0; j < (pole ? 1 : segments); j++, nvtx++) {
                double phi = 2 * PI * j / segments;
                m->pos[3 * (size_t)nvtx + 0] = (float)(r[k] * cos(phi));
                m->pos[3 * (size_t)nvtx + 1] = (float)y[k];
                m->pos[3 * (size_t)nvtx + 2] = (float)(-r[k] * sin(phi));
            }
        }
        /* A pole gets one UV per adjacent triangle, centred on its column. */
        uv_row[k] = nuvs;
        for (int32_t j = 0; j < (pole ? segments : segments + 1); j++, nuvs++) {
            m->uv[2 * (size_t)nuvs + 0] =
                (float)(pole ? (j + 0.5) / segments : (double)j / segments);
            m->uv[2 * (size_t)nuvs + 1] = (float)v_of[k];
        }
    }
    CR_ASSERT(nvtx == nv && nuvs == nuv);

    size_t f = 0;
    for (int32_t k = 0; k < bands; k++) {
        int32_t k1 = (k + 1) % K;
        int top_pole = k == 0 && pole0, bottom_pole = k1 == K - 1 && pole1;
        for (int32_t j = 0; j < segments; j++) {
            int32_t j1 = (j + 1) % segments;
            int32_t a = row[k] + (top_pole ? 0 : j), b = row[k] + (top_pole ? 0 : j1);
            int32_t c = row[k1] + (bottom_pole ? 0 : j), d = row[k1] + (bottom_pole ? 0 : j1);
            int32_t ua = uv_row[k] + j, ub = uv_row[k] + (top_pole ? j : j + 1);
            int32_t uc = uv_row[k + 1] + j, ud = uv_row[k + 1] + (bottom_pole ? j : j + 1);
            if (!top_pole) {
                int32_t t[3] = {a, c, b}, tu[3] = {ua, uc, ub};
                memcpy(&m->tri[3 * f], t, sizeof t);
                memcpy(&m->tri_uv[3 * f], tu, sizeof tu);
                f++;
            }
            if (!bottom_pole) {
                int32_t t[3] = {b, c, d}, tu[3] = {ub, uc, ud};
                memcpy(&m->tri[3 * f], t, sizeof t);
                memcpy(&m->tri_uv[3 * f], tu, sizeof tu);
                f++;
            }
        }
    }
    CR_ASSERT(f == (size_t)nf);
    free(row);
    free(v_of);
    *out = m;
    return CR_OK;
}

/* Allocate a K-point profile; the caller fills it and frees r (y lives in the same block). */
static cr_status profile_alloc(int32_t K, double **r, double **y, cr_error *err) {
    *r = cr_malloc((size_t)K * 2 * sizeof(double), err);
    if (!*r) return CR_ERR_MEMORY;
    *y = *r + K;
    return CR_OK;
}

static cr_status revolve_profile(double *r, double *y, int32_t K, int closed, int32_t segments,
                                 cr_mesh **out, cr_error *err) {
    cr_status st = revolve(r, y, K, closed, segments, out, err);
    free(r);
    return st;
}

cr_status cr_prim_sphere_uv(float radius, int32_t segments, int32_t rings, cr_mesh **out,
                            cr_error *err) {
    static const char *fn = "cr_prim_sphere_uv";
    *out = NULL;
    CR_TRY(check_length(radius, fn, "radius", err));
    CR_TRY(check_count(segments, 3, fn, "segments", err));
    CR_TRY(check_count(rings, 2, fn, "rings", err));
    double nv = 2 + (double)(rings - 1) * segments, nf = 2.0 * segments * (rings - 1);
    CR_TRY(check_size(nv, nf, (rings + 1.0) * (segments + 1.0), fn, "segments, rings", err));
    double *r, *y;
    CR_TRY(profile_alloc(rings + 1, &r, &y, err));
    for (int32_t k = 0; k <= rings; k++) {
        double th = PI * k / rings;
        r[k] = (k == 0 || k == rings) ? 0.0 : radius * sin(th);
        y[k] = radius * cos(th);
    }
    return revolve_profile(r, y, rings + 1, 0, segments, out, err);
}

cr_status cr_prim_torus(float major_radius, float minor_radius, int32_t major_segments,
                        int32_t minor_segments, cr_mesh **out, cr_error *err) {
    static const char *fn = "cr_prim_torus";
    *out = NULL;
    CR_TRY(check_length(major_radius, fn, "major_radius", err));
    CR_TRY(check_length(minor_radius, fn, "minor_radius", err));
    if (minor_radius >= major_radius)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: minor_radius (%g) must be < major_radius (%g)", fn,
                       minor_radius, major_radius);
    CR_TRY(check_count(major_segments, 3, fn, "major_segments", err));
    CR_TRY(check_count(minor_segments, 3, fn, "minor_segments", err));
    double nv = (double)major_segments * minor_segments;
    CR_TRY(check_size(nv, 2 * nv, (major_segments + 1.0) * (minor_segments + 1.0), fn,
                      "major_segments, minor_segments", err));
    double *r, *y;
    CR_TRY(profile_alloc(minor_segments, &r, &y, err));
    /* Clockwise round the tube section starting outermost: down the outside first. */
    for (int32_t k = 0; k < minor_segments; k++) {
        double th = 2 * PI * k / minor_segments;
        r[k] = major_radius + minor_radius * cos(th);
        y[k] = -minor_radius * sin(th);
    }
    return revolve_profile(r, y, minor_segments, 1, major_segments, out, err);
}

cr_status cr_prim_capsule(float radius, float length, int32_t segments, int32_t rings,
                          cr_mesh **out, cr_error *err) {
    static const char *fn = "cr_prim_capsule";
    *out = NULL;
    CR_TRY(check_length(radius, fn, "radius", err));
    if (!isfinite(length) || length < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: length must be finite and >= 0, got %g", fn,
                       length);
    CR_TRY(check_count(segments, 3, fn, "segments", err));
    CR_TRY(check_count(rings, 1, fn, "rings", err));
    /* Cylinder bands about as tall as a hemisphere band (arc pi r / 2 / rings). */
    double band = PI * radius / (2.0 * rings);
    double nb = length > 0 ? ceil(length / band - 1e-9) : 0;
    double K = 2.0 * rings + 1 + nb;
    CR_TRY(check_size((K - 2) * segments + 2, 2 * (K - 2) * segments, (K + 1) * (segments + 1), fn,
                      "radius, length, segments, rings", err));
    int32_t ncyl = (int32_t)nb, nk = (int32_t)K;
    double *r, *y;
    CR_TRY(profile_alloc(nk, &r, &y, err));
    int32_t k = 0;
    for (int32_t i = 0; i <= rings; i++, k++) { /* top hemisphere, pole to equator */
        double th = 0.5 * PI * i / rings;
        r[k] = i == 0 ? 0.0 : (i == rings ? radius : radius * sin(th));
        y[k] = 0.5 * length + (i == rings ? 0.0 : radius * cos(th));
    }
    for (int32_t i = 1; i <= ncyl; i++, k++) {
        r[k] = radius;
        y[k] = 0.5 * length - (double)length * i / ncyl;
    }
    for (int32_t i = 1; i <= rings; i++, k++) { /* bottom hemisphere, equator to pole */
        double th = 0.5 * PI * i / rings;
        r[k] = i == rings ? 0.0 : radius * cos(th);
        y[k] = -0.5 * length - radius * sin(th);
    }
    CR_ASSERT(k == nk);
    return revolve_profile(r, y, nk, 0, segments, out, err);
}

cr_status cr_prim_cylinder(float radius, float height, int32_t segments, int32_t rings, int capped,
                           cr_mesh **out, cr_error *err) {
    static const char *fn = "cr_prim_cylinder";
    *out = NULL;
    CR_TRY(check_length(radius, fn, "radius", err));
    CR_TRY(check_length(height, fn, "height", err));
    CR_TRY(check_count(segments, 3, fn, "segments", err));
    CR_TRY(check_count(rings, 1, fn, "rings", err));
    double K = rings + 1.0 + (capped ? 2 : 0);
    CR_TRY(check_size(K * segments, 2 * K * segments, (K + 1) * (segments + 1), fn,
                      "segments, rings", err));
    int32_t nk = (int32_t)K, k = 0;
    double *r, *y;
    CR_TRY(profile_alloc(nk, &r, &y, err));
    if (capped) r[k] = 0.0, y[k++] = 0.5 * height;
    for (int32_t i = 0; i <= rings; i++, k++) {
        r[k] = radius;
        y[k] = 0.5 * height - (double)height * i / rings;
    }
    if (capped) r[k] = 0.0, y[k++] = -0.5 * height;
    CR_ASSERT(k == nk);
    return revolve_profile(r, y, nk, 0, segments, out, err);
}

/* ------------------------------------------------------------ icosphere -- */

/* Longitude fraction in [0, 1) of a unit vector, matching revolve's phi. */
static double longitude_u(const double *p) {
    double u = atan2(-p[2], p[0]) / (2 * PI);
    return u < 0 ? u + 1.0 : u + 0.0; /* + 0.0 turns -0.0 into 0.0 */
}

/* Spherical UVs per corner: shared per vertex where possible, unwrapped
 * (u + 1) copies for triangles across the seam, one UV per pole corner. */
static cr_status icosphere_uvs(const double *unit, int32_t nv, const int32_t *tri, int32_t nf,
                               cr_mesh **out, cr_error *err) {
    size_t cap = 2 * (size_t)nv + (size_t)nf;
    float *uv = cr_malloc(cap * 2 * sizeof(float), err);
    int32_t *idx = cr_malloc((size_t)nv * 2 * sizeof(int32_t), err); /* base, unwrapped */
    int32_t *tri_uv = cr_malloc((size_t)nf * 3 * sizeof(int32_t), err);
    if (!uv || !idx || !tri_uv) {
        free(uv), free(idx), free(tri_uv);
        return CR_ERR_MEMORY;
    }
    for (size_t i = 0; i < 2 * (size_t)nv; i++)
        idx[i] = -1;
    int32_t nuv = 0;
    double umax = 1.0;
    for (int32_t f = 0; f < nf; f++) {
        const int32_t *t = &tri[3 * (size_t)f];
        double u[3], v[3];
        int pole[3];
        double lo = 1, hi = 0;
        for (int c = 0; c < 3; c++) {
            const double *p = &unit[3 * (size_t)t[c]];
            pole[c] = p[0] == 0.0 && p[2] == 0.0;
            u[c] = pole[c] ? 0.0 : longitude_u(p);
            v[c] = 1.0 - acos(fmax(-1.0, fmin(1.0, p[1]))) / PI;
            if (!pole[c]) lo = fmin(lo, u[c]), hi = fmax(hi, u[c]);
        }
        int wrap = hi - lo > 0.5;
        double usum = 0;
        int nreg = 0;
        for (int c = 0; c < 3; c++) {
            if (pole[c]) continue;
            if (wrap && u[c] < 0.5) u[c] += 1.0;
            usum += u[c], nreg++;
        }
        for (int c = 0; c < 3; c++) {
            int32_t *slot = pole[c] ? NULL : &idx[2 * (size_t)t[c] + (wrap && u[c] >= 1.0)];
            if (slot && *slot >= 0) {
                tri_uv[3 * (size_t)f + c] = *slot;
                continue;
            }
            if (pole[c]) u[c] = usum / nreg;
            uv[2 * (size_t)nuv] = (float)u[c];
            uv[2 * (size_t)nuv + 1] = (float)v[c];
            umax = fmax(umax, u[c]);
            if (slot) *slot = nuv;
            tri_uv[3 * (size_t)f + c] = nuv++;
        }
    }
    cr_status st = cr_mesh_create(nv, nf, nuv, out, err);
    if (st == CR_OK) {
        for (int32_t i = 0; i < nuv; i++) {
            (*out)->uv[2 * (size_t)i] = (float)(uv[2 * (size_t)i] / umax);
            (*out)->uv[2 * (size_t)i + 1] = uv[2 * (size_t)i + 1];
        }
        memcpy((*out)->tri_uv, tri_uv, (size_t)nf * 3 * sizeof(int32_t));
    }
    free(uv), free(idx), free(tri_uv);
    return st;
}

cr_status cr_prim_icosphere(float radius, int32_t subdivisions, cr_mesh **out, cr_error *err) {
    static const char *fn = "cr_prim_icosphere";
    *out = NULL;
    CR_TRY(check_length(radius, fn, "radius", err));
    CR_TRY(check_count(subdivisions, 0, fn, "subdivisions", err));
    if (subdivisions > 13)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: subdivisions must be <= 13 (int32 faces), got %d",
                       fn, subdivisions);
    double nf_final = 20.0 * pow(4.0, subdivisions);
    CR_TRY(check_size(nf_final / 2 + 2, nf_final, nf_final / 2 + 2 + 20 * pow(2.0, subdivisions),
                      fn, "subdivisions", err));
    int64_t nv_max = (int64_t)(nf_final / 2) + 2, nf_max = (int64_t)nf_final;
    double *p = cr_malloc((size_t)nv_max * 3 * sizeof(double), err); /* unit vectors */
    int32_t *ta = cr_malloc((size_t)nf_max * 3 * sizeof(int32_t), err);
    int32_t *tb = cr_malloc((size_t)nf_max * 3 * sizeof(int32_t), err);
    if (!p || !ta || !tb) {
        free(p), free(ta), free(tb);
        return CR_ERR_MEMORY;
    }
    /* Icosahedron with poles at +-Y: two rings of five at latitude +-atan(1/2),
     * the lower ring turned by 36 degrees. */
    int32_t nv = 12, nf = 20;
    double ry = 1.0 / sqrt(5.0), rr = 2.0 / sqrt(5.0);
    p[0] = 0, p[1] = 1, p[2] = 0;
    p[33] = 0, p[34] = -1, p[35] = 0;
    for (int i = 0; i < 5; i++) {
        double a = 2 * PI * i / 5, b = a + PI / 5;
        double *up = &p[3 * (1 + i)], *lo = &p[3 * (6 + i)];
        up[0] = rr * cos(a), up[1] = ry, up[2] = -rr * sin(a);
        lo[0] = rr * cos(b), lo[1] = -ry, lo[2] = -rr * sin(b);
        int32_t u0 = 1 + i, u1 = 1 + (i + 1) % 5, l0 = 6 + i, l1 = 6 + (i + 1) % 5;
        int32_t faces[12] = {0, u0, u1, u0, l0, u1, u1, l0, l1, l0, 11, l1};
        memcpy(&ta[12 * i], faces, sizeof faces);
    }
    cr_status st = CR_OK;
    for (int32_t s = 0; s < subdivisions && st == CR_OK; s++) {
        u64_map mid;
        st = map_init(&mid, 3 * (int64_t)nf / 2, err);
        if (st != CR_OK) break;
        for (int32_t f = 0; f < nf; f++) {
            const int32_t *t = &ta[3 * (size_t)f];
            int32_t m[3];
            for (int e = 0; e < 3; e++) {
                int32_t a = t[e], b = t[(e + 1) % 3];
                uint64_t key =
                    a < b ? ((uint64_t)a << 32 | (uint32_t)b) : ((uint64_t)b << 32 | (uint32_t)a);
                int inserted;
                m[e] = map_get_or_put(&mid, key, nv, &inserted);
                if (inserted) {
                    double *q = &p[3 * (size_t)nv];
                    for (int d = 0; d < 3; d++)
                        q[d] = p[3 * (size_t)a + d] + p[3 * (size_t)b + d];
                    double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
                    for (int d = 0; d < 3; d++)
                        q[d] /= len;
                    nv++;
                }
            }
            int32_t kids[12] = {t[0], m[0], m[2], m[0], t[1], m[1],
                                m[2], m[1], t[2], m[0], m[1], m[2]};
            memcpy(&tb[12 * (size_t)f], kids, sizeof kids);
        }
        map_free(&mid);
        nf *= 4;
        int32_t *tmp = ta;
        ta = tb, tb = tmp;
    }
    if (st == CR_OK) {
        CR_ASSERT(nv == nv_max && nf == nf_max);
        st = icosphere_uvs(p, nv, ta, nf, out, err);
    }
    if (st == CR_OK) {
        for (size_t i = 0; i < 3 * (size_t)nv; i++)
            (*out)->pos[i] = (float)(radius * p[i]);
        memcpy((*out)->tri, ta, (size_t)nf * 3 * sizeof(int32_t));
    }
    free(p), free(ta), free(tb);
    return st;
}

/* ---------------------------------------------------------------- prism -- */

cr_status cr_prim_prism(float side, float length, cr_mesh **out, cr_error *err) {
    static const char *fn = "cr_prim_prism";
    *out = NULL;
    CR_TRY(check_length(side, fn, "side", err));
    CR_TRY(check_length(length, fn, "length", err));
    /* Section centroid at the origin: ridge at 2h/3, base at -h/3. */
    double h = side * sqrt(3.0) / 2;
    float hx = 0.5f * length, top = (float)(2 * h / 3), bot = (float)(-h / 3), hz = 0.5f * side;
    /* 0,1,2 at x = -L/2 and 3,4,5 at x = +L/2: ridge, base +z, base -z. */
    const float pos[18] = {-hx, top, 0, -hx, bot, hz, -hx, bot, -hz,
                           hx,  top, 0, hx,  bot, hz, hx,  bot, -hz};
    const int32_t tri[24] = {0, 2, 1, 3, 4, 5,  /* end caps -X, +X */
                             0, 1, 4, 0, 4, 3,  /* upper face +z */
                             0, 3, 5, 0, 5, 2,  /* upper face -z */
                             1, 2, 5, 1, 5, 4}; /* base, -Y */
    /* UV atlas: the three sides as one strip going round the section (u: ridge,
     * +z face, base, -z face, ridge; v along x), the caps above it, each seen
     * from outside. */
    const float uv[28] = {0,        0,     0,        0.5f, 1.0f / 3, 0,    1.0f / 3, 0.5f,
                          2.0f / 3, 0,     2.0f / 3, 0.5f, 1,        0,    1,        0.5f,
                          0.25f,    0.95f, 0.05f,    0.6f, 0.45f,    0.6f,  /* -X cap */
                          0.75f,    0.95f, 0.55f,    0.6f, 0.95f,    0.6f}; /* +X cap */
    const int32_t tri_uv[24] = {8, 9, 10, 11, 12, 13, 0, 2, 3, 0, 3, 1,
                                6, 7, 5,  6,  5,  4,  2, 4, 5, 2, 5, 3};
    cr_mesh *m;
    CR_TRY(cr_mesh_create(6, 8, 14, &m, err));
    memcpy(m->pos, pos, sizeof pos);
    memcpy(m->tri, tri, sizeof tri);
    memcpy(m->uv, uv, sizeof uv);
    memcpy(m->tri_uv, tri_uv, sizeof tri_uv);
    *out = m;
    return CR_OK;
}

/* ------------------------------------------------------------------ box -- */

cr_status cr_prim_box(float size_x, float size_y, float size_z, int32_t subdivisions, cr_mesh **out,
                      cr_error *err) {
    static const char *fn = "cr_prim_box";
    *out = NULL;
    CR_TRY(check_length(size_x, fn, "size_x", err));
    CR_TRY(check_length(size_y, fn, "size_y", err));
    CR_TRY(check_length(size_z, fn, "size_z", err));
    CR_TRY(check_count(subdivisions, 1, fn, "subdivisions", err));
    const int32_t n = subdivisions;
    double n2 = (double)n * n;
    CR_TRY(check_size(6 * n2 + 2, 12 * n2, 6 * (n + 1.0) * (n + 1.0), fn, "subdivisions", err));
    int32_t nv = 6 * n * n + 2, nf = 12 * n * n, nuv = 6 * (n + 1) * (n + 1);
    cr_mesh *m;
    CR_TRY(cr_mesh_create(nv, nf, nuv, &m, err));
    u64_map map;
    cr_status st = map_init(&map, nv, err);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        return st;
    }
    /* Per face: lattice origin and two unit steps a, b with a x b = outward
     * normal, and the face's tile in the 3x2 UV atlas. */
    static const int face[6][9] = {
        {1, 0, 0, 0, 1, 0, 0, 0, 1}, /* +X: origin (n,0,0), a = +Y, b = +Z */
        {0, 0, 0, 0, 0, 1, 0, 1, 0}, /* -X */
        {0, 1, 0, 0, 0, 1, 1, 0, 0}, /* +Y */
        {0, 0, 0, 1, 0, 0, 0, 0, 1}, /* -Y */
        {0, 0, 1, 1, 0, 0, 0, 1, 0}, /* +Z */
        {0, 0, 0, 0, 1, 0, 1, 0, 0}, /* -Z */
    };
    const float size[3] = {size_x, size_y, size_z};
    int32_t nvtx = 0;
    size_t f = 0;
    int32_t *grid = cr_malloc((size_t)(n + 1) * (n + 1) * sizeof(int32_t), err);
    if (!grid) {
        map_free(&map);
        cr_mesh_destroy(m);
        return CR_ERR_MEMORY;
    }
    for (int fc = 0; fc < 6; fc++) {
        const int *o = face[fc], *a = face[fc] + 3, *b = face[fc] + 6;
        int32_t uv0 = fc * (n + 1) * (n + 1);
        for (int32_t q = 0; q <= n; q++) {
            for (int32_t p = 0; p <= n; p++) {
                int64_t l[3];
                for (int d = 0; d < 3; d++)
                    l[d] = (int64_t)o[d] * n + (int64_t)a[d] * p + (int64_t)b[d] * q;
                uint64_t key = (uint64_t)l[0] << 42 | (uint64_t)l[1] << 21 | (uint64_t)l[2];
                int inserted;
                int32_t v = map_get_or_put(&map, key, nvtx, &inserted);
                if (inserted) {
                    for (int d = 0; d < 3; d++)
                        m->pos[3 * (size_t)v + d] = (float)(((double)l[d] / n - 0.5) * size[d]);
                    nvtx++;
                }
                grid[(size_t)q * (n + 1) + p] = v;
                size_t t = (size_t)uv0 + (size_t)q * (n + 1) + p;
                m->uv[2 * t + 0] = (float)(((fc % 3) + (double)p / n) / 3.0);
                m->uv[2 * t + 1] = (float)(((fc / 3) + (double)q / n) / 2.0);
            }
        }
        for (int32_t q = 0; q < n; q++) {
            for (int32_t p = 0; p < n; p++) {
                int32_t i00 = q * (n + 1) + p, i10 = i00 + 1, i01 = i00 + n + 1, i11 = i01 + 1;
                int32_t c[6] = {i00, i10, i11, i00, i11, i01};
                for (int k = 0; k < 6; k++) {
                    m->tri[3 * f + k] = grid[c[k]];
                    m->tri_uv[3 * f + k] = uv0 + c[k];
                }
                f += 2;
            }
        }
    }
    CR_ASSERT(nvtx == nv && f == (size_t)nf);
    free(grid);
    map_free(&map);
    *out = m;
    return CR_OK;
}
