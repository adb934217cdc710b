/* descriptor.c: swingar's spectral shape descriptor (paper 002, section III-B):
 * furthest point samples, a Gaussian affinity of geodesic (or Euclidean)
 * distances on them, its eigen-decomposition and the Nystrom extension of the
 * eigenvectors to every vertex. descriptor.h lists the steps, docs/swingar.md
 * the choices and the measurements behind them.
 *
 * Shapes: V vertices, z samples.
 *
 * The eigenvalues are those of the paper's B = U Lambda U^T, with B weighted
 * as a quadrature of the kernel's integral operator on the surface,
 * (Tf)(x) = int K(x, y) f(y) dA(y) / area: B_w = W_s^1/2 B W_s^1/2, W_s the
 * share of the area in each sample's geodesic Voronoi cell (Williams & Seeger's
 * reading of the Nystrom method). With uniform weights this is the paper's
 * Lambda / z; the cell areas make it converge to T's spectrum however unevenly
 * FPS spreads the samples, so two meshes of one garment agree, and with every
 * vertex a sample it is exactly W^1/2 K W^1/2 (cr_swingar_descriptor_exact).
 * The trace is sum_a ws_a K(s_a, s_a) = 1. Not the eigenvalues of the
 * extended A^ = Q^ Lambda Q^T: they were tried and are unstable for the
 * geodesic kernel, which is indefinite (geodesics do not embed in a Euclidean
 * space) and whose small eigenvalues Lambda^-1 amplifies (docs/swingar.md).
 *
 * Left out: exact surface geodesics (sampling.h explains the edge-graph
 * bound), the heat kernel or Laplace-Beltrami spectra of other descriptors.
 * References: Fowlkes, Belongie, Chung, Malik, "Spectral grouping using the
 * Nystrom method" (PAMI 2004); Williams & Seeger, "Using the Nystrom method
 * to speed up kernel machines" (NIPS 2001).
 */
#include "methods/swingar/descriptor.h"

#include "crease/diffgeo.h"
#include "crease/sampling.h"
#include "crease/topology.h"
#include "phys/lapack.h"

#include <cblas.h>
#include <math.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdlib.h>
#include <string.h>

/* Eigenvectors of eigenvalues under this share of the largest are not
 * extended (their columns are 0): 1/mu would amplify the ~1e-7 relative
 * noise of float positions and distances into them. */
#define DROP_REL 1e-9

cr_swingar_descriptor_opts cr_swingar_descriptor_default_opts(void) {
    cr_swingar_descriptor_opts o;
    memset(&o, 0, sizeof o);
    o.samples = 256;
    o.affinity = CR_SWINGAR_AFFINITY_GEODESIC;
    o.sigma_scale = 0.25f;
    o.seed = 0;
    return o;
}

/* Symmetric eigen-decomposition of the (n,n) matrix a, in place: w (n)
 * ascending; with vectors, eigenvector k is a[k n + i], i < n. */
static cr_status eig_sym(double *a, int n, double *w, int vectors, cr_error *err) {
    const char *jobz = vectors ? "V" : "N";
    int info = 0, lwork = -1;
    double query = 0;
    dsyev_(jobz, "U", &n, a, &n, w, &query, &lwork, &info);
    lwork = info == 0 && query > 3 * n ? (int)query : 3 * n;
    double *work = cr_malloc((size_t)lwork * sizeof(double), err);
    if (!work) return CR_ERR_MEMORY;
#ifdef _OPENMP
    /* As in phys/energy.c: OpenBLAS's OpenMP build spreads the BLAS calls
     * inside dsyev over omp_get_max_threads() threads; for z <= 512 one is
     * faster, and on a loaded machine two were measured 15x slower. */
    const int team = omp_in_parallel() ? 0 : omp_get_max_threads();
    if (team > 1) omp_set_num_threads(1);
    dsyev_(jobz, "U", &n, a, &n, w, work, &lwork, &info);
    if (team > 1) omp_set_num_threads(team);
#else
    dsyev_(jobz, "U", &n, a, &n, w, work, &lwork, &info);
#endif
    free(work);
    if (info != 0)
        return CR_FAIL(err, CR_ERR_DIVERGED,
                       "swingar descriptor: dsyev on a %d x %d affinity: info %d", n, n, info);
    return CR_OK;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ---------------------------------------------------------- distances -- */

typedef struct dist_ctx {
    const cr_mesh *m;
    const cr_topology *t;
    const int32_t *src; /* (n) source vertices */
    float *d;           /* (n,V) edge-graph distance of every vertex from each source, m */
    cr_status *st;      /* (n) per source */
} dist_ctx;

static void dist_rows(void *ctx_, int64_t begin, int64_t end) {
    dist_ctx *c = ctx_;
    for (int64_t j = begin; j < end; j++) {
        cr_error e = {0};
        c->st[j] = cr_geodesic_dijkstra(c->m, c->t, &c->src[j], 1, &c->d[(size_t)j * c->m->nv], &e);
    }
}

/* d (n,V): geodesic distances from each of the n sources to every vertex. */
static cr_status distances(const cr_mesh *m, const cr_topology *t, const int32_t *src, int32_t n,
                           float *d, cr_error *err) {
    cr_status *st = cr_calloc((size_t)n, sizeof(cr_status), err);
    if (!st) return CR_ERR_MEMORY;
    dist_ctx c = {m, t, src, d, st};
    cr_parallel_for(n, 1, dist_rows, &c);
    cr_status out = CR_OK;
    for (int32_t j = 0; j < n && out == CR_OK; j++)
        if (st[j] != CR_OK)
            out = CR_FAIL(err, st[j], "swingar descriptor: distances from vertex %d: %s", src[j],
                          cr_status_str(st[j]));
    free(st);
    return out;
}

/* ----------------------------------------------------------- checks -- */

static cr_status check_mesh(const cr_mesh *m, cr_error *err) {
    if (!m || m->nv < 1 || m->nf < 1 || !m->pos || !m->tri)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "swingar descriptor: empty mesh (%d vertices, %d faces)", m ? m->nv : 0,
                       m ? m->nf : 0);
    for (int64_t i = 0; i < 3 * (int64_t)m->nv; i++)
        if (!isfinite(m->pos[i]))
            return CR_FAIL(err, CR_ERR_NAN,
                           "swingar descriptor: vertex %d has a non-finite position",
                           (int32_t)(i / 3));
    return CR_OK;
}

/* w (V): vertex area / total area (barycentric), summing to 1. */
static cr_status area_weights(const cr_mesh *m, double *w, cr_error *err) {
    float *a = cr_malloc((size_t)m->nv * sizeof(float), err);
    if (!a) return CR_ERR_MEMORY;
    cr_mesh_vertex_areas(m, CR_AREA_BARYCENTRIC, a);
    double total = 0;
    for (int32_t i = 0; i < m->nv; i++)
        total += a[i];
    if (!(total > 0)) {
        free(a);
        return CR_FAIL(err, CR_ERR_TOPOLOGY, "swingar descriptor: mesh has zero area (%d faces)",
                       m->nf);
    }
    for (int32_t i = 0; i < m->nv; i++)
        w[i] = a[i] / total;
    free(a);
    return CR_OK;
}

/* Every vertex reachable from vertex 0 along edges; first: the farthest of
 * them (lowest index on ties), a start for FPS that depends on the shape
 * only through vertex 0's place on it. */
static cr_status check_connected(const cr_mesh *m, const cr_topology *t, int32_t *first,
                                 cr_error *err) {
    float *d = cr_malloc((size_t)m->nv * sizeof(float), err);
    if (!d) return CR_ERR_MEMORY;
    const int32_t src = 0;
    cr_status st = cr_geodesic_dijkstra(m, t, &src, 1, d, err);
    int32_t unreached = 0, example = -1, far = 0;
    for (int32_t i = 0; st == CR_OK && i < m->nv; i++) {
        if (!isfinite(d[i])) {
            if (example < 0) example = i;
            unreached++;
        } else if (d[i] > d[far]) {
            far = i;
        }
    }
    free(d);
    CR_TRY(st);
    if (unreached > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "swingar descriptor: mesh is not one connected piece: %d of %d vertices "
                       "(e.g. vertex %d) have no edge path to vertex 0",
                       unreached, m->nv, example);
    *first = far;
    return CR_OK;
}

static cr_status check_opts(const cr_mesh *m, const cr_swingar_descriptor_opts *o, cr_error *err) {
    if (!o) return CR_FAIL(err, CR_ERR_INVALID, "swingar descriptor: opts is NULL");
    if (o->samples < 2 || o->samples > m->nv)
        return CR_FAIL(
            err, CR_ERR_RANGE,
            "swingar descriptor: samples = %d, need 2 <= samples <= %d (the vertex count)",
            o->samples, m->nv);
    if (o->affinity != CR_SWINGAR_AFFINITY_GEODESIC && o->affinity != CR_SWINGAR_AFFINITY_EUCLIDEAN)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "swingar descriptor: affinity = %d, need 0 (geodesic) or 1 (euclidean)",
                       (int)o->affinity);
    if (!(o->sigma_scale > 0) || !isfinite(o->sigma_scale))
        return CR_FAIL(err, CR_ERR_INVALID, "swingar descriptor: sigma_scale = %g, need > 0",
                       (double)o->sigma_scale);
    return CR_OK;
}

/* --------------------------------------------------------- nystrom -- */

/* sigma = scale x the median distance between distinct samples (dS symmetric). */
static cr_status median_sigma(const double *dS, int32_t z, float scale, double *sigma,
                              cr_error *err) {
    const size_t np = (size_t)z * (size_t)(z - 1) / 2;
    double *pair = cr_malloc(np * sizeof(double), err);
    if (!pair) return CR_ERR_MEMORY;
    size_t n = 0;
    for (int32_t a = 0; a < z; a++)
        for (int32_t b = a + 1; b < z; b++)
            pair[n++] = dS[(size_t)a * z + b];
    qsort(pair, np, sizeof(double), cmp_double);
    double med = np % 2 ? pair[np / 2] : 0.5 * (pair[np / 2 - 1] + pair[np / 2]);
    free(pair);
    if (!(med > 0))
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "swingar descriptor: median distance between samples is %g m (coincident "
                       "vertices?)",
                       med);
    *sigma = scale * med;
    return CR_OK;
}

static double euclid(const float *p, const float *q) {
    double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

typedef struct work {
    float *d;   /* (z,V) geodesic distances from the samples, m */
    double *w;  /* (V) area weights, sum 1 */
    double *ws; /* (z) quadrature weights: area of each sample's geodesic Voronoi cell, sum 1 */
    double *dS; /* (z,z) affinity distance between samples, m */
    double *B;  /* (z,z) W_s^1/2 B W_s^1/2, then its eigenvectors (row a = vector a) */
    double *mu; /* (z) its eigenvalues, ascending */
    float *K;   /* (V,z) affinity of every vertex to the samples (eigenvectors only) */
    float *P;   /* (z,z) Nystrom projection (eigenvectors only) */
} work;

static void work_free(work *k) {
    free(k->d), free(k->w), free(k->ws), free(k->dS), free(k->B), free(k->mu), free(k->K);
    free(k->P);
}

/* ws: each vertex's area goes to its nearest sample (lowest index on ties).
 * Row by row, so d is read in memory order. */
static cr_status voronoi_weights(const work *k, int32_t nv, int32_t z, double *ws, cr_error *err) {
    float *best = cr_malloc((size_t)nv * sizeof(float), err);
    int32_t *cell = cr_malloc((size_t)nv * sizeof(int32_t), err);
    if (!best || !cell) {
        free(best), free(cell);
        return CR_ERR_MEMORY;
    }
    memcpy(best, k->d, (size_t)nv * sizeof(float));
    memset(cell, 0, (size_t)nv * sizeof(int32_t));
    for (int32_t a = 1; a < z; a++) {
        const float *row = &k->d[(size_t)a * nv];
        for (int32_t i = 0; i < nv; i++)
            if (row[i] < best[i]) best[i] = row[i], cell[i] = a;
    }
    for (int32_t a = 0; a < z; a++)
        ws[a] = 0;
    for (int32_t i = 0; i < nv; i++)
        ws[cell[i]] += k->w[i];
    free(best), free(cell);
    return CR_OK;
}

/* f_c(x) = 1/mu_c sum_a K(x, s_a) sqrt(ws_a) v_c[a] for the eigenpairs above
 * DROP_REL x the largest (the Nystrom extension, Fowlkes et al. eq. 8 with
 * quadrature weights): on the samples f_c(s_a) = v_c[a] / sqrt(ws_a), hence
 * sum_a ws_a f_c(s_a) f_e(s_a) = delta_ce; over all vertices it holds
 * approximately. Columns in descending order of mu, 0 for dropped ones. */
static cr_status extend(const cr_mesh *m, const cr_swingar_descriptor_opts *o, work *k,
                        const int32_t *idx, double sigma, float *vec, cr_error *err) {
    const int32_t nv = m->nv, z = o->samples;
    const size_t V = (size_t)nv, Z = (size_t)z;
    k->K = cr_malloc(V * Z * sizeof(float), err);
    k->P = cr_malloc(Z * Z * sizeof(float), err);
    if (!k->K || !k->P) return CR_ERR_MEMORY;
    const double inv2s2 = 1.0 / (2.0 * sigma * sigma);
    for (size_t a = 0; a < Z; a++)
        for (size_t i = 0; i < V; i++) {
            double dai = o->affinity == CR_SWINGAR_AFFINITY_GEODESIC
                             ? (double)k->d[a * V + i]
                             : euclid(&m->pos[3 * i], &m->pos[3 * (size_t)idx[a]]);
            k->K[i * Z + a] = (float)exp(-dai * dai * inv2s2);
        }
    const double mumax = fmax(k->mu[z - 1], 0.0);
    for (size_t c = 0; c < Z; c++) {
        const double mu = k->mu[Z - 1 - c];
        const double *v = &k->B[(Z - 1 - c) * Z];
        const int keep = mu > DROP_REL * mumax;
        for (size_t a = 0; a < Z; a++)
            k->P[a * Z + c] = keep ? (float)(sqrt(k->ws[a]) * v[a] / mu) : 0.0f;
    }
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, nv, z, z, 1.0f, k->K, z, k->P, z, 0.0f,
                vec, z);
    return CR_OK;
}

cr_status cr_swingar_descriptor_full(const cr_mesh *m, const cr_swingar_descriptor_opts *o,
                                     float *eigenvalues, const cr_swingar_descriptor_extra *extra,
                                     cr_error *err) {
    CR_TRY(check_mesh(m, err));
    CR_TRY(check_opts(m, o, err));
    if (!eigenvalues)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar descriptor: eigenvalues is NULL");
    const int32_t nv = m->nv, z = o->samples;
    const size_t V = (size_t)nv, Z = (size_t)z;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    work k = {0};
    int32_t *idx = cr_malloc(Z * sizeof(int32_t), err);
    k.w = cr_malloc(V * sizeof(double), err);
    k.d = cr_malloc(Z * V * sizeof(float), err);
    k.ws = cr_malloc(Z * sizeof(double), err);
    k.dS = cr_malloc(Z * Z * sizeof(double), err);
    k.B = cr_malloc(Z * Z * sizeof(double), err);
    k.mu = cr_malloc(Z * sizeof(double), err);
    cr_status st = idx && k.w && k.d && k.ws && k.dS && k.B && k.mu ? CR_OK : CR_ERR_MEMORY;
    int32_t first = 0;
    if (st == CR_OK) st = area_weights(m, k.w, err);
    if (st == CR_OK) st = check_connected(m, t, &first, err);
    if (st == CR_OK && o->seed != 0) {
        cr_rng rng = cr_rng_make(o->seed, 0);
        first = (int32_t)cr_rng_below(&rng, (uint32_t)nv);
    }
    if (st == CR_OK) st = cr_fps_geodesic(m, t, z, first, idx, err);
    /* Geodesic distances from every sample, for the affinity and the cells. */
    if (st == CR_OK) st = distances(m, t, idx, z, k.d, err);
    double sigma = 0;
    if (st == CR_OK) {
        st = voronoi_weights(&k, nv, z, k.ws, err);
        for (size_t a = 0; st == CR_OK && a < Z; a++)
            for (size_t b = 0; b < Z; b++)
                k.dS[a * Z + b] =
                    o->affinity == CR_SWINGAR_AFFINITY_GEODESIC
                        ? 0.5 * ((double)k.d[a * V + idx[b]] + k.d[b * V + idx[a]])
                        : euclid(&m->pos[3 * (size_t)idx[a]], &m->pos[3 * (size_t)idx[b]]);
        if (st == CR_OK) st = median_sigma(k.dS, z, o->sigma_scale, &sigma, err);
    }
    if (st == CR_OK) {
        /* The quadrature of the kernel's integral operator on the samples
         * (Williams & Seeger): the paper's B, weighted by the cell areas. */
        const double inv2s2 = 1.0 / (2.0 * sigma * sigma);
        for (size_t a = 0; a < Z; a++)
            for (size_t b = 0; b < Z; b++) {
                double dab = k.dS[a * Z + b];
                k.B[a * Z + b] = sqrt(k.ws[a] * k.ws[b]) * exp(-dab * dab * inv2s2);
            }
        st = eig_sym(k.B, z, k.mu, extra && extra->eigenvectors, err);
    }
    for (int32_t a = 0; st == CR_OK && a < z; a++)
        eigenvalues[a] = (float)k.mu[z - 1 - a];
    if (st == CR_OK && extra && extra->eigenvectors)
        st = extend(m, o, &k, idx, sigma, extra->eigenvectors, err);
    if (st == CR_OK && extra && extra->sample_idx)
        memcpy(extra->sample_idx, idx, Z * sizeof(int32_t));
    if (st == CR_OK && extra && extra->sigma) *extra->sigma = (float)sigma;
    work_free(&k);
    free(idx);
    cr_topology_destroy(t);
    return st;
}

cr_status cr_swingar_descriptor(const cr_mesh *mesh, const cr_swingar_descriptor_opts *opts,
                                float *eigenvalues) {
    cr_error err = {0};
    cr_status st = cr_swingar_descriptor_full(mesh, opts, eigenvalues, NULL, &err);
    if (st != CR_OK) cr_log(CR_LOG_ERROR, "%s:%d: %s", err.src_file, err.src_line, err.msg);
    return st;
}

cr_status cr_swingar_descriptor_exact(const cr_mesh *m, cr_swingar_affinity affinity, float sigma,
                                      float *eigenvalues, cr_error *err) {
    CR_TRY(check_mesh(m, err));
    if (!(sigma > 0) || !isfinite(sigma))
        return CR_FAIL(err, CR_ERR_INVALID, "swingar descriptor: sigma = %g m, need > 0",
                       (double)sigma);
    if (affinity != CR_SWINGAR_AFFINITY_GEODESIC && affinity != CR_SWINGAR_AFFINITY_EUCLIDEAN)
        return CR_FAIL(err, CR_ERR_INVALID, "swingar descriptor: affinity = %d, need 0 or 1",
                       (int)affinity);
    const int32_t nv = m->nv;
    const size_t V = (size_t)nv;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    int32_t *all = cr_malloc(V * sizeof(int32_t), err);
    float *d = cr_malloc(V * V * sizeof(float), err);
    double *w = cr_malloc(V * sizeof(double), err), *A = cr_malloc(V * V * sizeof(double), err);
    double *lam = cr_malloc(V * sizeof(double), err);
    cr_status st = all && d && w && A && lam ? CR_OK : CR_ERR_MEMORY;
    int32_t first = 0;
    if (st == CR_OK) st = area_weights(m, w, err);
    if (st == CR_OK) st = check_connected(m, t, &first, err);
    for (int32_t i = 0; st == CR_OK && i < nv; i++)
        all[i] = i;
    if (st == CR_OK) st = distances(m, t, all, nv, d, err);
    if (st == CR_OK) {
        const double inv2s2 = 1.0 / (2.0 * (double)sigma * sigma);
        for (size_t i = 0; i < V; i++)
            for (size_t j = 0; j < V; j++) {
                double dij = affinity == CR_SWINGAR_AFFINITY_GEODESIC
                                 ? 0.5 * ((double)d[i * V + j] + d[j * V + i])
                                 : euclid(&m->pos[3 * i], &m->pos[3 * j]);
                A[i * V + j] = sqrt(w[i] * w[j]) * exp(-dij * dij * inv2s2);
            }
        st = eig_sym(A, nv, lam, 0, err);
    }
    for (int32_t i = 0; st == CR_OK && i < nv; i++)
        eigenvalues[i] = (float)lam[nv - 1 - i];
    free(all), free(d), free(w), free(A), free(lam);
    cr_topology_destroy(t);
    return st;
}
