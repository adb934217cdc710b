/* cholmod_solve.c: the Newton system's sparse Cholesky factorisation and
 * solves through SuiteSparse CHOLMOD (Chen, Davis, Hager & Rajamanickam,
 * "Algorithm 887: CHOLMOD", ACM TOMS 35(3), 2008).
 *
 * The block Hessian (upper block triangle by block column) becomes a scalar
 * CHOLMOD matrix once: stype 1 (upper triangle), columns of the free DOFs
 * only, rows sorted, with a gather map from each scalar entry to its place in
 * the block values; every factorisation copies the values through that map
 * and calls cholmod_factorize_p, which adds the diagonal shift itself
 * (factorising beta I + A). The factorisation is forced supernodal: that is
 * always LL', whose failure on a non-positive pivot is what detects an
 * indefinite matrix (CHOLMOD's simplicial LDL' accepts negative pivots), and
 * it is the fast path for meshes of thousands of vertices. Solves use
 * cholmod_solve2 with workspaces kept across calls, so no allocation happens
 * per Newton iteration once the first solve has run.
 *
 * Left out: updates/downdates of the factor, complex or pattern-changing
 * matrices, GPU factorisation (useGPU = 0).
 */
#include "crease/phys_solve.h"

#include <cblas.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/cholmod.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* Serialises cholmod_analyze across threads (see cr_cholesky_create). */
static pthread_mutex_t analyze_lock = PTHREAD_MUTEX_INITIALIZER;

/* First shift relative to the largest diagonal entry, and its growth per retry:
 * 1e-8 perturbs a well-posed system below the Newton tolerance; ten retries
 * reach 100 times the largest diagonal entry, past which the matrix is not a
 * Hessian worth damping (the caller reports divergence). */
#define SHIFT_FIRST 1e-8
#define SHIFT_GROWTH 10.0

struct cr_cholesky {
    cholmod_common cm;
    int started;
    cholmod_sparse *A; /* (n,n) stype 1, n = 3 * free vertices */
    cholmod_factor *L;
    cholmod_dense *B, *X, *Y, *E;
    int32_t nv, nfree;
    int32_t *free_vertex; /* (nfree) vertex of each reduced block */
    int64_t *gather;      /* (nnz) index into cr_hessian.val */
    int64_t nnz;
    int64_t nblock; /* pattern check */
    cr_cholesky_info info;
};

static const char *ordering_name(int ordering) {
    switch (ordering) {
    case CHOLMOD_NATURAL:
        return "natural";
    case CHOLMOD_GIVEN:
        return "given";
    case CHOLMOD_AMD:
        return "AMD";
    case CHOLMOD_METIS:
        return "METIS";
    case CHOLMOD_NESDIS:
        return "NESDIS";
    case CHOLMOD_COLAMD:
        return "COLAMD";
    case CHOLMOD_POSTORDERED:
        return "postordered";
    default:
        return "unknown";
    }
}

void cr_cholesky_destroy(cr_cholesky *c) {
    if (!c) return;
    if (c->started) {
        cholmod_free_sparse(&c->A, &c->cm);
        cholmod_free_factor(&c->L, &c->cm);
        cholmod_free_dense(&c->B, &c->cm);
        cholmod_free_dense(&c->X, &c->cm);
        cholmod_free_dense(&c->Y, &c->cm);
        cholmod_free_dense(&c->E, &c->cm);
        cholmod_finish(&c->cm);
    }
    free(c->free_vertex);
    free(c->gather);
    free(c);
}

cr_status cr_cholesky_create(const cr_hessian *h, const uint8_t *pinned, cr_cholesky **out,
                             cr_error *err) {
    *out = NULL;
    cr_cholesky *c = cr_calloc(1, sizeof(cr_cholesky), err);
    if (!c) return err ? err->status : CR_ERR_MEMORY;
    cr_status st = CR_OK;
    int32_t *reduced = NULL; /* (V) block index after removal, -1 when pinned */
    c->nv = h->nv;
    c->nblock = h->nblock;
    reduced = cr_malloc((size_t)h->nv * sizeof(int32_t), err);
    c->free_vertex = cr_malloc((size_t)h->nv * sizeof(int32_t), err);
    if (!reduced || !c->free_vertex) goto oom;
    for (int32_t v = 0; v < h->nv; v++) {
        reduced[v] = (pinned && pinned[v]) ? -1 : c->nfree;
        if (reduced[v] >= 0) c->free_vertex[c->nfree++] = v;
    }
    if (c->nfree == 0) {
        st =
            CR_FAIL(err, CR_ERR_INVALID, "cholesky: every one of the %d vertices is pinned", h->nv);
        goto fail;
    }
    /* Scalar entries: a free off-diagonal block gives 9, a diagonal block its
     * upper 6. */
    int64_t nnz = 0;
    for (int32_t j = 0; j < h->nv; j++) {
        if (reduced[j] < 0) continue;
        for (int64_t k = h->col_off[j]; k < h->col_off[j + 1]; k++)
            if (reduced[h->row[k]] >= 0) nnz += h->row[k] == j ? 6 : 9;
    }
    c->nnz = nnz;
    c->gather = cr_malloc((size_t)nnz * sizeof(int64_t), err);
    if (!c->gather) goto oom;
    cholmod_start(&c->cm);
    c->started = 1;
    c->cm.print = 0; /* the library never prints */
    c->cm.useGPU = 0;
    c->cm.supernodal = CHOLMOD_SUPERNODAL;
    /* Try AMD, METIS and NESDIS and keep the least fill: the analysis runs
     * once, the factorisation every Newton iteration (on cloth meshes the
     * nested dissections save about a fifth of AMD's fill). */
    c->cm.nmethods = 4;
    size_t n = 3 * (size_t)c->nfree;
    c->A = cholmod_allocate_sparse(n, n, (size_t)nnz, 1, 1, 1, CHOLMOD_REAL, &c->cm);
    c->B = cholmod_zeros(n, 1, CHOLMOD_REAL, &c->cm);
    if (!c->A || !c->B) goto oom_cholmod;
    int *Ap = c->A->p, *Ai = c->A->i;
    int64_t q = 0;
    for (int32_t jb = 0; jb < c->nfree; jb++) {
        int32_t j = c->free_vertex[jb];
        for (int col = 0; col < 3; col++) {
            Ap[3 * jb + col] = (int)q;
            for (int64_t k = h->col_off[j]; k < h->col_off[j + 1]; k++) {
                int32_t ib = reduced[h->row[k]];
                if (ib < 0) continue;
                for (int r = 0; r < 3; r++) {
                    if (ib == jb && r > col) break; /* lower part of a diagonal block */
                    Ai[q] = 3 * ib + r;
                    c->gather[q++] = 9 * k + 3 * r + col;
                }
            }
        }
    }
    Ap[n] = (int)q;
    CR_ASSERT(q == nnz);
    /* One analysis at a time in the process: the nested-dissection orderings
     * are METIS's, whose random-number state is process-wide (GKlib's
     * generator, reseeded at each call). Two analyses run side by side (a
     * dataset simulates several garments at once) interleave their draws and
     * get different permutations from one run to the next, hence different
     * factors and trajectories at rounding level; one at a time, each call
     * draws the same sequence from the same seed. */
    pthread_mutex_lock(&analyze_lock);
    c->L = cholmod_analyze(c->A, &c->cm);
    pthread_mutex_unlock(&analyze_lock);
    if (!c->L) goto oom_cholmod;
    c->info.ordering = ordering_name(c->cm.method[c->cm.selected].ordering);
    free(reduced);
    *out = c;
    return CR_OK;
oom_cholmod:
    st = CR_FAIL(err, CR_ERR_MEMORY,
                 "cholesky: CHOLMOD analysis of %d free vertices failed (status %d)", c->nfree,
                 c->cm.status);
    goto fail;
oom:
    st = err ? err->status : CR_ERR_MEMORY;
fail:
    free(reduced);
    cr_cholesky_destroy(c);
    return st;
}

/* The factorisation runs on the calling thread alone. On two cores, with
 * anything else running, threads in CHOLMOD's loops and OpenBLAS's level-3
 * kernels spent more time waking and spinning than computing: a 5k-vertex
 * cloth's factor (9e8 flops) took 0.55-1.7 s on two threads against
 * 0.15-0.25 s on one. CHOLMOD's loops ask for a fixed number of threads by a
 * num_threads clause, so parallel regions are switched off for the call
 * (OpenMP's max-active-levels 0); OpenBLAS is told to use one thread as well,
 * because its level-3 kernels otherwise queue work for a team that an
 * inactive region never provides, and spin forever. Both settings are
 * restored afterwards; assembly and collision queries stay parallel. The
 * triangular solves run the same way. */
typedef struct serial_scope {
    int active; /* 0 inside a parallel region: already on one thread, and the
                   process-wide settings must not be raced over (a dataset
                   simulates several garments at once) */
    int levels, blas_threads, omp_threads;
} serial_scope;

static serial_scope serial_begin(void) {
    serial_scope sc = {1, 0, 0, 1};
#ifdef _OPENMP
    if (omp_in_parallel()) {
        sc.active = 0;
        return sc;
    }
    sc.levels = omp_get_max_active_levels();
    sc.omp_threads = omp_get_max_threads();
    omp_set_max_active_levels(0);
#endif
    sc.blas_threads = openblas_get_num_threads();
    openblas_set_num_threads(1);
    return sc;
}

/* OpenBLAS's OpenMP build sets OpenMP's thread count along with its own, so
 * that is put back last. */
static void serial_end(serial_scope sc) {
    if (!sc.active) return;
    openblas_set_num_threads(sc.blas_threads);
#ifdef _OPENMP
    omp_set_max_active_levels(sc.levels);
    omp_set_num_threads(sc.omp_threads);
#endif
}

cr_status cr_cholesky_factor(cr_cholesky *c, const cr_hessian *h, cr_cholesky_info *info,
                             cr_error *err) {
    CR_ASSERT(h->nv == c->nv && h->nblock == c->nblock);
    double *Ax = c->A->x, maxdiag = 0.0;
    const int *Ap = c->A->p;
    for (int64_t q = 0; q < c->nnz; q++) {
        Ax[q] = h->val[c->gather[q]];
        if (!isfinite(Ax[q]))
            return CR_FAIL(err, CR_ERR_NAN, "cholesky: non-finite Hessian entry (%g) in block %lld",
                           Ax[q], (long long)(c->gather[q] / 9));
    }
    /* The last entry of each column is its diagonal (rows sorted, upper part). */
    for (size_t j = 0; j < c->A->ncol; j++)
        if (fabs(Ax[Ap[j + 1] - 1]) > maxdiag) maxdiag = fabs(Ax[Ap[j + 1] - 1]);
    if (maxdiag == 0.0) maxdiag = 1.0;
    c->info.retries = 0;
    double shift = 0.0;
    serial_scope sc = serial_begin();
    for (int attempt = 0; attempt <= CR_CHOLESKY_MAX_SHIFTS; attempt++) {
        double beta[2] = {shift, 0.0};
        cholmod_factorize_p(c->A, beta, NULL, 0, c->L, &c->cm);
        if (c->cm.status == CHOLMOD_OK && c->L->minor == c->L->n) {
            serial_end(sc);
            c->info.shift = shift;
            c->info.factor_nnz = (int64_t)c->cm.lnz;
            if (info) *info = c->info;
            return CR_OK;
        }
        if (c->cm.status != CHOLMOD_NOT_POSDEF) {
            serial_end(sc);
            return CR_FAIL(err, CR_ERR_MEMORY, "cholesky: CHOLMOD factorisation failed (status %d)",
                           c->cm.status);
        }
        c->info.retries++;
        shift = shift == 0.0 ? SHIFT_FIRST * maxdiag : shift * SHIFT_GROWTH;
    }
    serial_end(sc);
    c->info.shift = shift;
    if (info) *info = c->info;
    return CR_FAIL(err, CR_ERR_DIVERGED,
                   "cholesky: Hessian not positive definite even with a diagonal shift of %g "
                   "(largest diagonal %g)",
                   shift / SHIFT_GROWTH, maxdiag);
}

cr_status cr_cholesky_solve(cr_cholesky *c, const double *rhs, double *x, cr_error *err) {
    double *b = c->B->x;
    for (int32_t k = 0; k < c->nfree; k++)
        memcpy(b + 3 * (int64_t)k, rhs + 3 * (int64_t)c->free_vertex[k], 3 * sizeof(double));
    serial_scope sc = serial_begin(); /* as the factorisation: one thread is faster */
    int ok = cholmod_solve2(CHOLMOD_A, c->L, c->B, NULL, &c->X, NULL, &c->Y, &c->E, &c->cm);
    serial_end(sc);
    if (!ok)
        return CR_FAIL(err, CR_ERR_MEMORY, "cholesky: CHOLMOD solve failed (status %d)",
                       c->cm.status);
    const double *sol = c->X->x;
    /* Scatter after the gather: x may alias rhs. */
    memset(x, 0, (size_t)c->nv * 3 * sizeof(double));
    for (int32_t k = 0; k < c->nfree; k++)
        memcpy(x + 3 * (int64_t)c->free_vertex[k], sol + 3 * (int64_t)k, 3 * sizeof(double));
    return CR_OK;
}
