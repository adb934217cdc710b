/* folds.c: fold measures a chaotic reference can be held to, and the hem's
 * swing (docs/eval.md, "Folds", its `hem` row).
 *
 * A garment's folds are chosen chaotically in its first frames: the same
 * simulation from a start moved 0.1 mm folds one hinge over
 * (../shared/RESEARCH_WAVE3.md, section 0). Compared hinge by hinge, a fold
 * one hinge away counts twice (once missing, once spurious) and the smooth
 * average scores best. The measures here forgive the place: the best match
 * within a few rings of hinges (tolerant), or the sorted distribution of the
 * largest bends (location-free), or the share of hinges folded at all.
 *
 * The hem's swing is measured in the body's frame, found as the body's best
 * rigid fit to its first frame (Horn's absolute orientation, here through
 * the polar decomposition of the cross-covariance): a garment that swings
 * with the motion and one that is carried rigidly differ there, not in the
 * world frame where the walk dominates.
 *
 * Leaves out: a skeleton's pelvis (eval has only the body's vertices; the
 * whole-body fit is the root's frame where the limbs are a small share of
 * the vertices), fold correlation between two runs (a statistic of a pair
 * of references, not of a prediction).
 */
#include "eval_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- rings -- */

cr_status cr_eval_hinge_rings(const cr_topology *t, int ring, int32_t **off_out, int32_t **idx_out,
                              cr_error *err) {
    const int32_t V = t->nv, H = t->nh;
    *off_out = *idx_out = NULL;
    /* vertex -> hinges with the vertex in their stencil (CSR) */
    int32_t *vh_off = cr_calloc((size_t)V + 1, sizeof(int32_t), err);
    int32_t *vh = cr_malloc((size_t)4 * H * sizeof(int32_t) + 1, err);
    int32_t *mark_v = cr_malloc((size_t)V * sizeof(int32_t) + 1, err);
    int32_t *mark_h = cr_malloc((size_t)H * sizeof(int32_t) + 1, err);
    int32_t *front = cr_malloc((size_t)V * sizeof(int32_t) + 1, err);
    int32_t *off = cr_calloc((size_t)H + 1, sizeof(int32_t), err);
    int32_t *idx = NULL, cap = 0;
    cr_status st = vh_off && vh && mark_v && mark_h && front && off ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        for (int32_t h = 0; h < H; h++)
            for (int k = 0; k < 4; k++)
                vh_off[t->hinge[4 * h + k] + 1]++;
        for (int32_t v = 0; v < V; v++)
            vh_off[v + 1] += vh_off[v];
        int32_t *fill = mark_v; /* borrowed as a cursor, reset below */
        memcpy(fill, vh_off, (size_t)V * sizeof(int32_t));
        for (int32_t h = 0; h < H; h++)
            for (int k = 0; k < 4; k++)
                vh[fill[t->hinge[4 * h + k]]++] = h;
        for (int32_t v = 0; v < V; v++)
            mark_v[v] = -1;
        for (int32_t h = 0; h < H; h++)
            mark_h[h] = -1;
    }
    int32_t n = 0;
    for (int32_t h = 0; st == CR_OK && h < H; h++) {
        /* the vertices within ring - 1 edges of h's stencil, breadth first */
        int32_t nf = 0;
        for (int k = 0; k < 4; k++) {
            int32_t v = t->hinge[4 * h + k];
            if (mark_v[v] != h) mark_v[v] = h, front[nf++] = v;
        }
        for (int r = 1, begin = 0; r < ring; r++) {
            int32_t end = nf;
            for (int32_t q = begin; q < end; q++)
                for (int32_t j = t->vv_off[front[q]]; j < t->vv_off[front[q] + 1]; j++) {
                    int32_t w = t->vv[j];
                    if (mark_v[w] != h) mark_v[w] = h, front[nf++] = w;
                }
            begin = end;
        }
        off[h] = n;
        for (int32_t q = 0; q < nf; q++)
            for (int32_t j = vh_off[front[q]]; j < vh_off[front[q] + 1]; j++) {
                int32_t g = vh[j];
                if (mark_h[g] == h) continue;
                mark_h[g] = h;
                if (n == cap) {
                    cap = cap ? 2 * cap : 16 * H + 16;
                    int32_t *grown = realloc(idx, (size_t)cap * sizeof(int32_t));
                    if (!grown) {
                        st = CR_FAIL(err, CR_ERR_MEMORY, "eval: out of memory for hinge rings");
                        break;
                    }
                    idx = grown;
                }
                idx[n++] = g;
            }
    }
    if (st == CR_OK) off[H] = n;
    free(vh_off), free(vh), free(mark_v), free(mark_h), free(front);
    if (st != CR_OK) {
        free(off), free(idx);
        return st;
    }
    *off_out = off, *idx_out = idx;
    return CR_OK;
}

double cr_eval_ring_match(const double *a, const double *b, const int32_t *sel, int32_t nsel,
                          const int32_t *off, const int32_t *idx) {
    if (nsel <= 0) return NAN;
    double s = 0.0;
    for (int32_t j = 0; j < nsel; j++) {
        int32_t h = sel ? sel[j] : j;
        double best = INFINITY;
        for (int32_t q = off[h]; q < off[h + 1]; q++)
            best = fmin(best, fabs(a[idx[q]] - b[h]));
        s += best;
    }
    return s / nsel;
}

static int descending(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return (a < b) - (a > b);
}

double cr_eval_sorted_top(const double *a, const double *b, int32_t n, int32_t k, double *scratch) {
    if (n <= 0 || k <= 0) return NAN;
    if (k > n) k = n;
    double *sa = scratch, *sb = scratch + n;
    for (int32_t h = 0; h < n; h++)
        sa[h] = fabs(a[h]), sb[h] = fabs(b[h]);
    qsort(sa, (size_t)n, sizeof(double), descending);
    qsort(sb, (size_t)n, sizeof(double), descending);
    double s = 0.0;
    for (int32_t j = 0; j < k; j++)
        s += fabs(sa[j] - sb[j]);
    return s / k;
}

double cr_eval_fold_share(const double *a, int32_t n, double threshold) {
    if (n <= 0) return NAN;
    int32_t c = 0;
    for (int32_t h = 0; h < n; h++)
        c += fabs(a[h]) > threshold;
    return (double)c / n;
}

double cr_eval_mean_edge(const cr_mesh *g, const cr_topology *t) {
    double s = 0.0;
    for (int32_t e = 0; e < t->ne; e++) {
        const float *a = &g->pos[3 * (int64_t)t->edge[2 * e]],
                    *b = &g->pos[3 * (int64_t)t->edge[2 * e + 1]];
        double d0 = (double)a[0] - b[0], d1 = (double)a[1] - b[1], d2 = (double)a[2] - b[2];
        s += sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    }
    return t->ne ? s / t->ne : NAN;
}

/* ----------------------------------------------------------- hem swing -- */

/* The rotation of the polar decomposition M = R S (det M > 0), by Higham's
 * iteration X <- (X + X^-T) / 2; identity when M is singular. Row-major. */
static void polar_rotation(const double M[9], double R[9]) {
    double X[9];
    memcpy(X, M, sizeof X);
    for (int it = 0; it < 50; it++) {
        double c[9] = {X[4] * X[8] - X[5] * X[7], X[5] * X[6] - X[3] * X[8],
                       X[3] * X[7] - X[4] * X[6], X[2] * X[7] - X[1] * X[8],
                       X[0] * X[8] - X[2] * X[6], X[1] * X[6] - X[0] * X[7],
                       X[1] * X[5] - X[2] * X[4], X[2] * X[3] - X[0] * X[5],
                       X[0] * X[4] - X[1] * X[3]}; /* cofactors: X^-T = c / det */
        double det = X[0] * c[0] + X[1] * c[1] + X[2] * c[2];
        if (!(fabs(det) > 1e-300)) {
            memset(R, 0, 9 * sizeof(double));
            R[0] = R[4] = R[8] = 1.0;
            return;
        }
        double change = 0.0;
        for (int k = 0; k < 9; k++) {
            double nx = 0.5 * (X[k] + c[k] / det);
            change += fabs(nx - X[k]);
            X[k] = nx;
        }
        if (change < 1e-13) break;
    }
    memcpy(R, X, sizeof X);
}

/* The body's best rigid fit from frame 0 to frame t: x_t ~ R (x_0 - c0) + ct. */
static void body_fit(const float *b0, const float *bt, int32_t nv, double R[9], double ct[3]) {
    double c0[3] = {0, 0, 0};
    for (int d = 0; d < 3; d++)
        ct[d] = 0.0;
    for (int32_t i = 0; i < nv; i++)
        for (int d = 0; d < 3; d++)
            c0[d] += b0[3 * i + d], ct[d] += bt[3 * i + d];
    for (int d = 0; d < 3; d++)
        c0[d] /= nv, ct[d] /= nv;
    double M[9] = {0}; /* sum (x_t - ct)(x_0 - c0)^T: R maximises tr(R^T M) */
    for (int32_t i = 0; i < nv; i++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                M[3 * r + c] += ((double)bt[3 * i + r] - ct[r]) * ((double)b0[3 * i + c] - c0[c]);
    polar_rotation(M, R);
}

/* The boundary loop whose vertices are lowest (mean y) on the rest mesh; -1 when none. */
static int32_t lowest_loop(const cr_mesh *g, const cr_topology *t) {
    int32_t best = -1;
    double best_y = INFINITY;
    for (int32_t l = 0; l < t->nloop; l++) {
        int32_t n = t->loop_off[l + 1] - t->loop_off[l];
        if (n < 3) continue;
        double y = 0.0;
        for (int32_t q = t->loop_off[l]; q < t->loop_off[l + 1]; q++)
            y += g->pos[3 * (int64_t)t->loop_vert[q] + 1];
        y /= n;
        if (y < best_y) best_y = y, best = l;
    }
    return best;
}

/* Amplitude (RMS about each vertex's mean) and dominant frequency of the hem's
 * motion y (T, n, 3), in place (the mean is removed). */
static void swing(double *y, int32_t T, int32_t n, float fps, double *amp, double *freq) {
    double s = 0.0;
    for (int32_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) {
            double m = 0.0;
            for (int32_t t = 0; t < T; t++)
                m += y[((int64_t)t * n + i) * 3 + d];
            m /= T;
            for (int32_t t = 0; t < T; t++) {
                double *v = &y[((int64_t)t * n + i) * 3 + d];
                *v -= m;
                s += *v * *v;
            }
        }
    *amp = sqrt(s / ((double)T * n));
    double best = -1.0;
    int32_t kbest = 0;
    for (int32_t k = 1; k <= T / 2; k++) {
        double p = 0.0, w = 2.0 * M_PI * k / T;
        for (int32_t i = 0; i < n; i++)
            for (int d = 0; d < 3; d++) {
                double re = 0.0, im = 0.0;
                for (int32_t t = 0; t < T; t++) {
                    double v = y[((int64_t)t * n + i) * 3 + d];
                    re += v * cos(w * t), im -= v * sin(w * t);
                }
                p += re * re + im * im;
            }
        if (p > best) best = p, kbest = k;
    }
    *freq = (double)kbest * fps / T;
}

cr_status cr_eval_hem_swing(const cr_eval_def *def, const cr_eval_input *in, const cr_topology *t,
                            cr_eval_result *r, cr_error *err) {
    r->has_hem = 0;
    const int32_t T = in->nframes, V = in->garment->nv;
    int32_t l = lowest_loop(in->garment, t);
    if (l < 0 || T < 4) return CR_OK;
    const int32_t n = t->loop_off[l + 1] - t->loop_off[l];
    const int32_t *hem = &t->loop_vert[t->loop_off[l]];
    const int body = in->body_mesh && in->body && in->body_nframes > 1;
    double *y = cr_malloc((size_t)T * n * 3 * sizeof(double), err);
    double *frame = cr_malloc((size_t)T * 12 * sizeof(double), err); /* (T) R (9), c (3) */
    if (!y || !frame) {
        free(y), free(frame);
        return CR_ERR_MEMORY;
    }
    for (int32_t f = 0; f < T; f++) {
        double *R = &frame[12 * f], *c = R + 9;
        memset(R, 0, 12 * sizeof(double));
        R[0] = R[4] = R[8] = 1.0;
        if (body) {
            const int32_t nb = in->body_mesh->nv,
                          tb = f < in->body_nframes ? f : in->body_nframes - 1;
            body_fit(in->body, in->body + (int64_t)tb * nb * 3, nb, R, c);
        }
    }
    for (int s = 0; s < 2; s++) {
        const float *seq = s ? in->ref : in->pred;
        for (int32_t f = 0; f < T; f++) {
            const double *R = &frame[12 * f], *c = R + 9;
            for (int32_t i = 0; i < n; i++) {
                const float *x = &seq[((int64_t)f * V + hem[i]) * 3];
                double q[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
                for (int d = 0; d < 3; d++) /* R^T q: back into the first frame's axes */
                    y[((int64_t)f * n + i) * 3 + d] =
                        R[d] * q[0] + R[3 + d] * q[1] + R[6 + d] * q[2];
            }
        }
        swing(y, T, n, def->fps, s ? &r->hem_amplitude_ref_m : &r->hem_amplitude_pred_m,
              s ? &r->hem_frequency_ref_hz : &r->hem_frequency_pred_hz);
    }
    free(y), free(frame);
    r->has_hem = 1, r->hem_in_body_frame = body, r->hem_vertices = n;
    return CR_OK;
}
