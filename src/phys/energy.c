/* energy.c: what every energy term shares: element vertex lookup and the
 * projection of a small symmetric matrix onto the PSD cone.
 *
 * cr_psd_project clamps negative eigenvalues to zero (the nearest PSD matrix
 * in the Frobenius norm; Teran et al. 2005, "Robust quasistatic finite
 * elements and flesh simulation", sec. 5). Two cheap exits come first: a
 * Cholesky factorisation that succeeds proves the matrix positive definite,
 * and when no eigenvalue is negative beyond roundoff the input is left
 * untouched, so an already PSD Hessian comes back bit for bit. Eigenvalues
 * come from LAPACK's dsyev for n > 6 and from cyclic Jacobi below that.
 *
 * Cost note: OpenBLAS's OpenMP build threads the BLAS calls inside dsyev when
 * it is called outside a parallel region; on a busy 2-core machine that made
 * one 9x9 call take 0.1-10 ms instead of ~10 us. The call is therefore made
 * with this thread's OpenMP team size pinned to 1.
 */
#include "crease/phys_energy.h"

#include <math.h>
#include <string.h>

#include "phys/lapack.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum {
    PSD_MAX_N = 12,
    /* Up to this size a Jacobi sweep beats dsyev, whose fixed costs dominate
     * small matrices (docs/physics.md has the timings). */
    JACOBI_MAX_N = 6,
    JACOBI_MAX_SWEEPS = 50
};
/* Negative eigenvalues smaller than this times the largest |eigenvalue| are
 * roundoff of a PSD matrix, not indefiniteness. */
#define PSD_ROUNDOFF 1e-12

void cr_energy_term_vertices(const cr_energy_term *t, int32_t e, int32_t *idx) {
    CR_ASSERT(t && idx && e >= 0 && e < t->nelem);
    if (!t->elem) {
        CR_ASSERT(t->nvert == 1);
        idx[0] = e;
        return;
    }
    const int32_t *src = t->elem + (int64_t)e * t->nvert;
    for (int k = 0; k < t->nvert; k++)
        idx[k] = src[k];
}

/* 1 when the Cholesky factorisation of H (n x n, row-major, symmetric) has
 * every pivot above a relative floor: H is then positive definite. */
static int cholesky_ok(const double *H, int n) {
    double L[PSD_MAX_N * PSD_MAX_N];
    double scale = 0.0;
    for (int i = 0; i < n; i++)
        scale = fmax(scale, fabs(H[i * n + i]));
    if (!(scale > 0.0)) return 0;
    const double floor_ = 1e-10 * scale;
    for (int j = 0; j < n; j++) {
        double d = H[j * n + j];
        for (int k = 0; k < j; k++)
            d -= L[j * n + k] * L[j * n + k];
        if (!(d > floor_)) return 0;
        const double ljj = sqrt(d);
        L[j * n + j] = ljj;
        for (int i = j + 1; i < n; i++) {
            double s = H[i * n + j];
            for (int k = 0; k < j; k++)
                s -= L[i * n + k] * L[j * n + k];
            L[i * n + j] = s / ljj;
        }
    }
    return 1;
}

/* Cyclic Jacobi eigen-decomposition of the symmetric n x n matrix A
 * (row-major, destroyed): eigenvalues w (n), eigenvectors as the columns of V
 * (row-major n x n). Rotations as in Golub & Van Loan, "Matrix
 * Computations", sec. 8.5 (the 2x2 symmetric Schur decomposition). */
static void jacobi_eig(double *A, int n, double *w, double *V) {
    for (int i = 0; i < n * n; i++)
        V[i] = 0.0;
    for (int i = 0; i < n; i++)
        V[i * n + i] = 1.0;
    for (int sweep = 0; sweep < JACOBI_MAX_SWEEPS; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int i = 0; i < n; i++) {
            diag += A[i * n + i] * A[i * n + i];
            for (int j = i + 1; j < n; j++)
                off += A[i * n + j] * A[i * n + j];
        }
        if (off <= 1e-32 * diag || off == 0.0) break;
        for (int p = 0; p < n; p++)
            for (int q = p + 1; q < n; q++) {
                const double apq = A[p * n + q];
                if (apq == 0.0) continue;
                const double tau = (A[q * n + q] - A[p * n + p]) / (2.0 * apq);
                const double t = (tau >= 0.0 ? 1.0 : -1.0) / (fabs(tau) + sqrt(tau * tau + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < n; k++) {
                    const double akp = A[k * n + p], akq = A[k * n + q];
                    A[k * n + p] = c * akp - s * akq;
                    A[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) {
                    const double apk = A[p * n + k], aqk = A[q * n + k];
                    A[p * n + k] = c * apk - s * aqk;
                    A[q * n + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; k++) {
                    const double vkp = V[k * n + p], vkq = V[k * n + q];
                    V[k * n + p] = c * vkp - s * vkq;
                    V[k * n + q] = s * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < n; i++)
        w[i] = A[i * n + i];
}

void cr_psd_project(double *H, int n) {
    CR_ASSERT(H && n >= 1 && n <= PSD_MAX_N);
    if (cholesky_ok(H, n)) return;
    double a[PSD_MAX_N * PSD_MAX_N], w[PSD_MAX_N] = {0}, V[PSD_MAX_N * PSD_MAX_N];
    memcpy(a, H, sizeof(double) * (size_t)n * (size_t)n);
    const double *vec; /* eigenvector k is vec[i * vs + k * ks] */
    int vs, ks;
    if (n <= JACOBI_MAX_N) {
        jacobi_eig(a, n, w, V);
        vec = V, vs = n, ks = 1;
    } else {
        /* Symmetric, so row-major H is its own column-major copy; eigenvectors
         * come back as columns of the column-major a. */
        double work[PSD_MAX_N * 34];
        const int lwork = (int)(sizeof work / sizeof work[0]);
        int info = 0;
#ifdef _OPENMP
        /* Outside a parallel region OpenBLAS would spread this tiny problem's
         * BLAS calls over the OpenMP team (milliseconds per call on a busy
         * machine); it sizes that team by omp_get_max_threads(), which is
         * this thread's own setting, so pin it to 1 for the call. */
        const int team = omp_in_parallel() ? 0 : omp_get_max_threads();
        if (team > 1) omp_set_num_threads(1);
        dsyev_("V", "U", &n, a, &n, w, work, &lwork, &info);
        if (team > 1) omp_set_num_threads(team);
#else
        dsyev_("V", "U", &n, a, &n, w, work, &lwork, &info);
#endif
        if (info != 0) {
            /* No convergence (NaN input): a zero Hessian keeps Newton's system
             * PSD; the caller's divergence check sees the NaN in the value. */
            memset(H, 0, sizeof(double) * (size_t)n * (size_t)n);
            return;
        }
        vec = a, vs = 1, ks = n;
    }
    double wmin = w[0], wmax = 0.0;
    for (int k = 0; k < n; k++) {
        if (!isfinite(w[k])) {
            memset(H, 0, sizeof(double) * (size_t)n * (size_t)n);
            return;
        }
        wmin = fmin(wmin, w[k]);
        wmax = fmax(wmax, fabs(w[k]));
    }
    /* Roundoff makes a singular PSD matrix look slightly indefinite: leave it. */
    if (wmin >= -PSD_ROUNDOFF * wmax) return;
    /* H = sum over positive eigenvalues of w_k v_k v_k^T. */
    memset(H, 0, sizeof(double) * (size_t)n * (size_t)n);
    for (int k = 0; k < n; k++) {
        if (!(w[k] > 0.0)) continue;
        for (int i = 0; i < n; i++) {
            const double wi = w[k] * vec[i * vs + k * ks];
            for (int j = i; j < n; j++)
                H[i * n + j] += wi * vec[j * vs + k * ks];
        }
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            H[i * n + j] = H[j * n + i];
}
