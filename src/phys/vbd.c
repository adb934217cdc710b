/* vbd.c: vertex block descent (Chen, Liu, Yang & Yuksel 2024, "Vertex Block
 * Descent", SIGGRAPH; arXiv 2403.06321), the simulator's second solver for
 * the same incremental potential as Newton (crease/phys_sim.h).
 *
 * One iteration sweeps the vertices colour by colour (colour.c: no two
 * vertices of one colour share an element). For free vertex i, with the
 * others held,
 *     g_i = sum over the elements e around i of dE_e/dx_i,
 *     H_i = sum of the (i,i) 3x3 blocks of the elements' PSD Hessians,
 * both from the energies' own kernels (phys_energy.h; nothing is
 * re-derived here), plus the one-vertex terms (inertia, drag, gravity,
 * collision, friction); then dx = -H_i^-1 g_i (a Cholesky of the 3x3 block,
 * shifted when it is singular, as a static solve's can be). The vertices of
 * one colour step in parallel (one OpenMP region per sweep, a static `omp
 * for` per colour); each reads only vertices of
 * other colours, which do not move meanwhile, so a sweep is the same bit for
 * bit at any thread count. Colours run one after the other (Gauss-Seidel).
 *
 * Safeguards the paper leaves out, which make every iteration a descent on
 * the objective (for the collider's linearisation of that iteration):
 *   - the vertices take full Newton steps, and an iteration whose objective
 *     is above its start runs again from there with a per-vertex
 *     backtracking line search on the vertex's local energy (the elements
 *     around it plus its one-vertex terms, which is the whole objective as
 *     a function of x_i), Armijo with def.armijo, at most VBD_LINE_SEARCH
 *     halvings, else the vertex stays; the searches then stay on for the
 *     substep (almost every vertex takes its full step, so searching them
 *     all every sweep was a value evaluation of every element for nothing);
 *   - Chebyshev acceleration (paper sec. 3.7; Wang 2015):
 *       x^{n+1} = w_{n+1} (xbar^{n+1} - x^{n-1}) + x^{n-1},
 *       w_1 = 1, w_2 = 2/(2 - rho^2), w_{n+1} = 4/(4 - rho^2 w_n),
 *     is kept only when the objective at the extrapolated iterate is no
 *     higher than at the iteration's start; otherwise the sweep's own
 *     iterate is used and w restarts at 1.
 *
 * Damping (paper sec. 3.5): with def.vbd_damping k_d > 0, each vertex adds
 * the Rayleigh stiffness damping of its elements, k_d/h H_i (x_i - x_i^t) to
 * its gradient and k_d/h H_i to its block (H_i of the elastic terms at the
 * iterate). It changes the minimiser (it is not part of Newton's potential),
 * so it is 0 by default and the drag term both solvers share damps instead.
 *
 * The collider is queried again before every iteration after the first
 * (radius grown by twice the distance moved so far), as Newton does per
 * iterate, but only for the vertices that moved more than vbd_requery_move
 * of the thickness since their last query and may be within it: resting and
 * distant vertices keep their linearisation (re-querying every vertex every
 * sweep was a quarter of a sweep on the sphere drop; at 0.1 mm of slide on a
 * 0.3 m sphere the tangent plane's error is 2e-8 m). Converged when an
 * iteration's largest vertex move is below o->tol; o->rtol is not used: a
 * Gauss-Seidel sweep's move shrinks long before the iterate converges.
 * Pinned vertices are not coloured.
 *
 * Cost per iteration: every element's vertex-block kernel
 * (cr_energy_term.vertex_block: that vertex's gradient and 3x3 block only)
 * runs once per vertex of the element (a triangle 3 times, a hinge 4); a
 * term without one has its full kernel sliced. Plus one value-only
 * evaluation of the whole objective (two when the extrapolation is
 * rejected or the sweep retried).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "phys/vbd_internal.h"

/* Step halvings of the per-vertex line search. */
#define VBD_LINE_SEARCH 6
/* Free vertices per thread below which a sweep runs on one: a sweep is one
 * parallel region with a barrier per colour, each some microseconds (more on
 * a loaded machine). */
#define VBD_GRAIN 256
/* The step bound's fraction of the nearest pair's distance (the paper's
 * gamma_p; Warp's 0.4). */
#define VBD_BOUND 0.4
/* Step halvings of the coarse correction's line search. */
#define VBD_COARSE_LINE_SEARCH 8
/* Detections that walk the initial guess out in steps of the bound. */
#define VBD_GUESS_DETECTIONS 4

/* One incidence of a free vertex into a multi-vertex element, with the
 * element's vertices copied in (the gather streams these, not the terms'
 * element lists). */
typedef struct vbd_adj {
    int32_t elem;
    int16_t term;
    int16_t local;                   /* the vertex is ev[local] */
    int32_t ev[CR_ENERGY_MAX_VERTS]; /* the element's vertices (term->nvert of them) */
} vbd_adj;

struct cr_vbd {
    int32_t nv;
    int ncol;
    int32_t *col_off;  /* (ncol+1) into col_vert */
    int32_t *col_vert; /* the free vertices, by colour, ascending within one */
    int64_t *inc_off;  /* (V+1) */
    cr_vbd_incidence *inc;
    int64_t *adj_off;               /* (nfree+1): slot k = col_vert[k]'s incidences in adj */
    vbd_adj *adj;                   /* the incidences again, in colour order */
    int32_t *map[CR_SIM_MAX_TERMS]; /* one-vertex terms with an element list: vertex -> element */
    double *xa, *xb;                /* (V,3) the last two iterates, for Chebyshev */
    double *move, *gnorm;           /* (V) per vertex of the last sweep, m and N */
    double *hel;                    /* (V,9) each vertex's elastic Hessian block, N/m, as of
                                       the last sweep that evaluated it */
    int t_collision;                /* the term a collider query changes, or -1 */
    int32_t *colour;                /* (V) each vertex's colour, -1 when pinned */
    uint8_t *bounded;               /* (V) 1: the last sweep cut the vertex's move (step bound) */
};

void cr_vbd_destroy(cr_vbd *v) {
    if (!v) return;
    free(v->col_off), free(v->col_vert), free(v->inc_off), free(v->inc);
    free(v->adj_off), free(v->adj);
    for (int t = 0; t < CR_SIM_MAX_TERMS; t++)
        free(v->map[t]);
    free(v->xa), free(v->xb), free(v->move), free(v->gnorm), free(v->hel);
    free(v->colour), free(v->bounded);
    free(v);
}

int cr_vbd_colour_count(const cr_vbd *v) {
    return v->ncol;
}

cr_status cr_vbd_create(const cr_sim *s, cr_vbd **out, cr_error *err) {
    *out = NULL;
    const int32_t nv = s->nv;
    cr_vbd *v = cr_calloc(1, sizeof *v, err);
    if (!v) return err ? err->status : CR_ERR_MEMORY;
    v->nv = nv;
    v->t_collision = -1;
    for (int t = 0; t < s->nterms; t++)
        if (s->collision && s->terms[t].data == (const void *)s->collision) v->t_collision = t;
    cr_status st = CR_OK;
    int32_t *colour = NULL;
    v->inc_off = cr_calloc((size_t)nv + 1, sizeof(int64_t), err);
    size_t n3 = 3 * (size_t)(nv > 0 ? nv : 1);
    v->xa = cr_malloc(n3 * sizeof(double), err);
    v->xb = cr_malloc(n3 * sizeof(double), err);
    v->move = cr_calloc((size_t)nv + 1, sizeof(double), err);
    v->gnorm = cr_calloc((size_t)nv + 1, sizeof(double), err);
    v->hel = cr_calloc(9 * ((size_t)nv + 1), sizeof(double), err);
    colour = cr_malloc(((size_t)nv + 1) * sizeof(int32_t), err);
    v->bounded = cr_calloc((size_t)nv + 1, 1, err);
    if (!v->inc_off || !v->xa || !v->xb || !v->move || !v->gnorm || !v->hel || !colour ||
        !v->bounded)
        goto fail;
    /* Incidences of the multi-vertex terms, by counting sort on the vertex. */
    int64_t ninc = 0;
    for (int t = 0; t < s->nterms; t++) {
        const cr_energy_term *term = &s->terms[t];
        if (term->nvert == 1) {
            if (!(v->map[t] = cr_malloc(((size_t)nv + 1) * sizeof(int32_t), err))) goto fail;
            continue;
        }
        for (int64_t k = 0; k < (int64_t)term->nelem * term->nvert; k++)
            v->inc_off[term->elem[k] + 1]++;
        ninc += (int64_t)term->nelem * term->nvert;
    }
    for (int32_t i = 0; i < nv; i++)
        v->inc_off[i + 1] += v->inc_off[i];
    v->inc = cr_malloc((size_t)(ninc > 0 ? ninc : 1) * sizeof(cr_vbd_incidence), err);
    int64_t *fill = cr_malloc(((size_t)nv + 1) * sizeof(int64_t), err);
    if (!v->inc || !fill) {
        free(fill);
        goto fail;
    }
    memcpy(fill, v->inc_off, (size_t)nv * sizeof(int64_t));
    for (int t = 0; t < s->nterms; t++) {
        const cr_energy_term *term = &s->terms[t];
        if (term->nvert == 1) continue;
        for (int32_t e = 0; e < term->nelem; e++)
            for (int a = 0; a < term->nvert; a++) {
                int32_t i = term->elem[(int64_t)term->nvert * e + a];
                v->inc[fill[i]++] = (cr_vbd_incidence){e, (int16_t)t, (int16_t)a};
            }
    }
    free(fill);
    st = cr_vbd_colour(nv, v->inc_off, v->inc, s->terms, s->pinned, colour, &v->ncol, err);
    if (st != CR_OK) goto done;
    v->col_off = cr_calloc((size_t)v->ncol + 1, sizeof(int32_t), err);
    v->col_vert = cr_malloc(((size_t)nv + 1) * sizeof(int32_t), err);
    if (!v->col_off || !v->col_vert) goto fail;
    for (int32_t i = 0; i < nv; i++)
        if (colour[i] >= 0) v->col_off[colour[i] + 1]++;
    for (int c = 0; c < v->ncol; c++)
        v->col_off[c + 1] += v->col_off[c];
    {
        int32_t *at = cr_malloc(((size_t)v->ncol + 1) * sizeof(int32_t), err);
        if (!at) goto fail;
        memcpy(at, v->col_off, (size_t)v->ncol * sizeof(int32_t));
        for (int32_t i = 0; i < nv; i++)
            if (colour[i] >= 0) v->col_vert[at[colour[i]]++] = i;
        free(at);
    }
    {
        const int32_t nfree = v->col_off[v->ncol];
        v->adj_off = cr_malloc(((size_t)nfree + 1) * sizeof(int64_t), err);
        if (!v->adj_off) goto fail;
        v->adj_off[0] = 0;
        for (int32_t k = 0; k < nfree; k++) {
            const int32_t i = v->col_vert[k];
            v->adj_off[k + 1] = v->adj_off[k] + (v->inc_off[i + 1] - v->inc_off[i]);
        }
        v->adj = cr_malloc(
            (size_t)(v->adj_off[nfree] > 0 ? v->adj_off[nfree] : 1) * sizeof(vbd_adj), err);
        if (!v->adj) goto fail;
        for (int32_t k = 0; k < nfree; k++) {
            const int32_t i = v->col_vert[k];
            vbd_adj *ad = v->adj + v->adj_off[k];
            for (int64_t q = v->inc_off[i]; q < v->inc_off[i + 1]; q++, ad++) {
                const cr_vbd_incidence *in = &v->inc[q];
                const cr_energy_term *term = &s->terms[in->term];
                memset(ad, 0, sizeof *ad);
                ad->elem = in->elem, ad->term = in->term, ad->local = in->local;
                for (int b = 0; b < term->nvert; b++)
                    ad->ev[b] = term->elem[(int64_t)term->nvert * in->elem + b];
            }
        }
    }
    goto done;
fail:
    st = err && err->status != CR_OK ? err->status : CR_ERR_MEMORY;
done:
    v->colour = colour;
    if (st != CR_OK) {
        cr_vbd_destroy(v);
        return st;
    }
    *out = v;
    return CR_OK;
}

/* ------------------------------------------------------ initial guess -- */

/* x = x_t + h v_t + h^2 a~, a~ the part of the last substep's acceleration
 * along gravity, clamped to [0, |g|] (paper eq. 11): a vertex at rest on the
 * ground is not predicted into it, a falling one falls. */
void cr_vbd_initial_guess(cr_sim *s, double h) {
    const double *gv = s->def.gravity;
    double gl = sqrt(gv[0] * gv[0] + gv[1] * gv[1] + gv[2] * gv[2]);
    double gh[3] = {0.0, 0.0, 0.0};
    if (gl > 0.0)
        for (int k = 0; k < 3; k++)
            gh[k] = gv[k] / gl;
    for (int32_t i = 0; i < s->nv; i++) {
        const double *a = s->a_prev + 3 * (int64_t)i;
        double along = a[0] * gh[0] + a[1] * gh[1] + a[2] * gh[2];
        along = along < 0.0 ? 0.0 : (along > gl ? gl : along);
        for (int k = 0; k < 3; k++) {
            int64_t q = 3 * (int64_t)i + k;
            s->x[q] = s->x_start[q] + h * s->v[q] + h * h * along * gh[k];
        }
    }
}

/* ------------------------------------------------------------- sweep -- */

typedef struct sweep_ctx {
    cr_sim *s;
    cr_vbd *v;
    double kd_h;     /* damping k_d / h (k_d in s): a multiple of the Hessian */
    double max_step; /* m */
    int fresh;       /* 1: this sweep evaluates the elastic Hessian blocks into v->hel */
    int line_search; /* 1: each vertex backtracks on its local energy; 0: full steps */
} sweep_ctx;

/* Vertex i's share of the self-contact pairs around it (the pairs change
 * with every detection, so they are not in the incidences): its energy,
 * gradient into g and Hessian block into H (fresh every sweep, like the
 * one-vertex terms; both when g is not NULL). A partner of i's own colour
 * moves in the same parallel step, so it is read where it was at the sweep's
 * start (v->xb), which keeps the sweep deterministic; the others are read
 * where they are. */
static double gather_self(const cr_sim *s, const cr_vbd *v, int32_t i, const double xi[3],
                          double *g, double *H) {
    const cr_energy_term *term = &s->terms[s->t_self];
    if (term->weight == 0.0) return 0.0;
    const int64_t *off;
    const int32_t *pp;
    cr_self_contact_vertex_pairs(s->self, &off, &pp);
    const int32_t ci = v->colour[i];
    const double w = term->weight;
    double e = 0.0;
    for (int64_t q = off[i]; q < off[i + 1]; q++) {
        const int32_t p = pp[q] / 4;
        const int a = pp[q] % 4;
        const int32_t *ev = term->elem + 4 * (int64_t)p;
        double xe[12];
        for (int b = 0; b < 4; b++) {
            const double *src = xi;
            if (b != a)
                src = (ci >= 0 && v->colour[ev[b]] == ci ? v->xb : s->x) + 3 * (int64_t)ev[b];
            xe[3 * b] = src[0], xe[3 * b + 1] = src[1], xe[3 * b + 2] = src[2];
        }
        double gb[3], Hb[9];
        e += w * term->vertex_block(term->data, p, a, xe, g ? gb : NULL, g ? Hb : NULL);
        if (g) {
            for (int r = 0; r < 3; r++)
                g[r] += w * gb[r];
            for (int r = 0; r < 9; r++)
                H[r] += w * Hb[r];
        }
    }
    return e;
}

/* The local objective of vertex i (col_vert[slot]) with x_i = xi and the
 * other vertices at s->x. With g (3) not NULL, also its gradient and the
 * Hessian block H (9) of the one-vertex terms; with Hel (9) not NULL too,
 * the block of the multi-vertex (elastic) terms goes there (else their
 * kernels run without their Hessians). A weight of 1 is not multiplied in
 * (the same bits). */
static double gather(const cr_sim *s, const cr_vbd *v, int32_t slot, int32_t i, const double xi[3],
                     double *g, double *H, double *Hel) {
    double e = 0.0;
    if (g) {
        memset(g, 0, 3 * sizeof(double));
        memset(H, 0, 9 * sizeof(double));
    }
    if (Hel) memset(Hel, 0, 9 * sizeof(double));
    for (int t = 0; t < s->nterms; t++) {
        const cr_energy_term *term = &s->terms[t];
        if (term->nvert != 1 || term->weight == 0.0) continue;
        int32_t el = term->elem ? v->map[t][i] : i;
        if (el < 0) continue;
        double gl[3], Hl[9];
        double w = term->weight;
        const double el_e = term->kernel(term->data, el, xi, g ? gl : NULL, g ? Hl : NULL);
        if (w == 1.0) {
            e += el_e;
            if (g) {
                for (int k = 0; k < 3; k++)
                    g[k] += gl[k];
                for (int k = 0; k < 9; k++)
                    H[k] += Hl[k];
            }
            continue;
        }
        e += w * el_e;
        if (g) {
            for (int k = 0; k < 3; k++)
                g[k] += w * gl[k];
            for (int k = 0; k < 9; k++)
                H[k] += w * Hl[k];
        }
    }
    const vbd_adj *ad = v->adj + v->adj_off[slot], *const ad_end = v->adj + v->adj_off[slot + 1];
    for (; ad < ad_end; ad++) {
        const cr_energy_term *term = &s->terms[ad->term];
        const double w = term->weight;
        if (w == 0.0) continue;
        const int nvert = term->nvert, n = 3 * nvert, a = ad->local;
        double xe[3 * CR_ENERGY_MAX_VERTS];
        for (int b = 0; b < nvert; b++) {
            const double *src = s->x + 3 * (int64_t)ad->ev[b];
            xe[3 * b] = src[0], xe[3 * b + 1] = src[1], xe[3 * b + 2] = src[2];
        }
        xe[3 * a] = xi[0], xe[3 * a + 1] = xi[1], xe[3 * a + 2] = xi[2];
        if (term->vertex_block) {
            double gb[3], Hb[9];
            const double eb =
                term->vertex_block(term->data, ad->elem, a, xe, g ? gb : NULL, Hel ? Hb : NULL);
            if (w == 1.0) {
                e += eb;
                if (g)
                    for (int r = 0; r < 3; r++)
                        g[r] += gb[r];
                if (Hel)
                    for (int r = 0; r < 9; r++)
                        Hel[r] += Hb[r];
                continue;
            }
            e += w * eb;
            if (g)
                for (int r = 0; r < 3; r++)
                    g[r] += w * gb[r];
            if (Hel)
                for (int r = 0; r < 9; r++)
                    Hel[r] += w * Hb[r];
            continue;
        }
        /* No block kernel: slice the element's. */
        double ge[3 * CR_ENERGY_MAX_VERTS], He[9 * CR_ENERGY_MAX_VERTS * CR_ENERGY_MAX_VERTS];
        e += w * term->kernel(term->data, ad->elem, xe, g ? ge : NULL, Hel ? He : NULL);
        if (g)
            for (int r = 0; r < 3; r++)
                g[r] += w * ge[3 * a + r];
        if (Hel)
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    Hel[3 * r + c] += w * He[(3 * a + r) * n + 3 * a + c];
    }
    if (s->self) e += gather_self(s, v, i, xi, g, H);
    return e;
}

/* Solve the SPD 3x3 A x = b by Cholesky; 0 when A is not positive definite. */
static int solve3(const double *A, const double *b, double *x) {
    double l00 = A[0];
    if (!(l00 > 0.0)) return 0;
    l00 = sqrt(l00);
    double l10 = A[3] / l00, l20 = A[6] / l00;
    double d1 = A[4] - l10 * l10;
    if (!(d1 > 0.0)) return 0;
    double l11 = sqrt(d1);
    double l21 = (A[7] - l20 * l10) / l11;
    double d2 = A[8] - l20 * l20 - l21 * l21;
    if (!(d2 > 0.0)) return 0;
    double l22 = sqrt(d2);
    double y0 = b[0] / l00, y1 = (b[1] - l10 * y0) / l11, y2 = (b[2] - l20 * y0 - l21 * y1) / l22;
    x[2] = y2 / l22;
    x[1] = (y1 - l21 * x[2]) / l11;
    x[0] = (y0 - l10 * x[1] - l20 * x[2]) / l00;
    return 1;
}

static double quad_form(const double *A, const double *d) {
    double s = 0.0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            s += d[r] * A[3 * r + c] * d[c];
    return s;
}

/* VBD's conservative step bound (Chen et al. 2024, sec. 4): vertex i stays
 * within VBD_BOUND of the distance to its nearest self-contact pair (or the
 * query radius) from where the pairs were found, so two primitives that were
 * d apart close by at most 2 VBD_BOUND d < d before the next detection and
 * no move passes one layer through another. Returns 1 when xi was cut. */
static int bound_move(const cr_sim *s, int32_t i, double *xi) {
    const double *x0 = cr_self_contact_detected_at(s->self) + 3 * (int64_t)i;
    const double b = VBD_BOUND * cr_self_contact_nearest(s->self)[i];
    double d[3] = {xi[0] - x0[0], xi[1] - x0[1], xi[2] - x0[2]};
    double l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (!(l2 > b * b)) return 0;
    double f = b / sqrt(l2);
    for (int k = 0; k < 3; k++)
        xi[k] = x0[k] + f * d[k];
    return 1;
}

/* The bound over every free vertex of x; returns how many were cut. */
static int32_t bound_all(const cr_sim *s, cr_vbd *v, double *x) {
    int32_t n = 0;
    for (int32_t i = 0; i < s->nv; i++) {
        if (s->pinned[i]) continue;
        int cut = bound_move(s, i, x + 3 * (int64_t)i);
        v->bounded[i] |= (uint8_t)cut;
        n += cut;
    }
    return n;
}

/* After a vertex's step from xo: the bound, and the move recorded. */
static void finish_move(const cr_sim *s, cr_vbd *v, int32_t i, const double *xo, double *xi,
                        double len) {
    if (s->self && bound_move(s, i, xi)) {
        v->bounded[i] = 1;
        double d[3] = {xi[0] - xo[0], xi[1] - xo[1], xi[2] - xo[2]};
        len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    v->move[i] = len;
}

/* One vertex's block Newton step with its line search, in place in s->x:
 * the vertex in slot `slot` of the colour order. */
static void vertex_step(const sweep_ctx *c, int32_t slot) {
    cr_sim *s = c->s;
    cr_vbd *v = c->v;
    const int32_t i = v->col_vert[slot];
    double *xi = s->x + 3 * (int64_t)i;
    const double xo[3] = {xi[0], xi[1], xi[2]};
    double g[3], H[9], d0[3] = {0.0, 0.0, 0.0}, *Hel = v->hel + 9 * (int64_t)i;
    double e0 = gather(s, v, slot, i, xo, g, H, c->fresh ? Hel : NULL);
    for (int k = 0; k < 9; k++)
        H[k] += Hel[k];
    if (c->kd_h > 0.0) {
        for (int k = 0; k < 3; k++)
            d0[k] = xo[k] - s->x_start[3 * (int64_t)i + k];
        for (int r = 0; r < 3; r++)
            for (int q = 0; q < 3; q++) {
                g[r] += c->kd_h * Hel[3 * r + q] * d0[q];
                H[3 * r + q] += c->kd_h * Hel[3 * r + q];
            }
        e0 += 0.5 * c->kd_h * quad_form(Hel, d0);
    }
    double gn = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    v->gnorm[i] = isfinite(e0) ? gn : NAN;
    v->move[i] = 0.0;
    if (!(gn > 0.0) || !isfinite(gn)) return;
    /* dx = -(H + shift I)^-1 g, the shift only where H is singular. */
    double tr = H[0] + H[4] + H[8], dx[3], mg[3] = {-g[0], -g[1], -g[2]};
    double shift = 0.0, A[9];
    int ok = 0;
    for (int tries = 0; tries < 8 && !ok; tries++) {
        memcpy(A, H, sizeof A);
        A[0] += shift, A[4] += shift, A[8] += shift;
        ok = solve3(A, mg, dx);
        shift = shift == 0.0 ? 1e-8 * fabs(tr) + 1e-12 : 100.0 * shift;
    }
    if (!ok) return;
    double len = sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
    if (len > c->max_step)
        for (int k = 0; k < 3; k++)
            dx[k] *= c->max_step / len;
    double gd = g[0] * dx[0] + g[1] * dx[1] + g[2] * dx[2];
    if (!(gd < 0.0)) return;
    if (!c->line_search) {
        /* The sweep's objective is checked instead (cr_vbd_solve). */
        for (int k = 0; k < 3; k++)
            xi[k] = xo[k] + dx[k];
        finish_move(s, v, i, xo, xi, len);
        return;
    }
    double alpha = 1.0;
    for (int ls = 0; ls <= VBD_LINE_SEARCH; ls++, alpha *= 0.5) {
        double xn[3];
        for (int k = 0; k < 3; k++)
            xn[k] = xo[k] + alpha * dx[k];
        double en = gather(s, v, slot, i, xn, NULL, NULL, NULL);
        if (c->kd_h > 0.0) {
            double dn[3];
            for (int k = 0; k < 3; k++)
                dn[k] = xn[k] - s->x_start[3 * (int64_t)i + k];
            en += 0.5 * c->kd_h * quad_form(Hel, dn);
        }
        if (isfinite(en) && en <= e0 + s->def.armijo * alpha * gd) {
            memcpy(xi, xn, sizeof xn);
            finish_move(s, v, i, xo, xi, alpha * len);
            return;
        }
    }
}

/* --------------------------------------------------------------- solve -- */

cr_status cr_vbd_bound_guess(cr_sim *s, cr_error *err) {
    cr_vbd *v = s->vbd;
    if (!s->self) return CR_OK;
    /* Cut to the bound, the guess loses the inertial motion that the
     * sweeps, held back by the membrane, win back slowly (a falling cloth
     * fell in slow motion), so the pairs are found again where the cut
     * guess lies and the full guess tried from there, up to
     * VBD_GUESS_DETECTIONS times. The guess comes with the collider's clamp
     * (sim.c): a clamp after the walk moved vertices past the bound, and
     * lifted both layers of a fold on the floor to one height. */
    const size_t n3 = 3 * (size_t)s->nv;
    memcpy(v->xa, s->x, n3 * sizeof(double)); /* the full guess */
    for (int k = 0;; k++) {
        memset(v->bounded, 0, (size_t)s->nv);
        int32_t cut = bound_all(s, v, s->x);
        if (cut == 0 || k == VBD_GUESS_DETECTIONS) break;
        s->rep->self_contact_bounded += cut;
        CR_TRY(cr_sim_detect_self(s, s->x, 0, err));
        memcpy(s->x, v->xa, n3 * sizeof(double));
    }
    return CR_OK;
}

/* One sweep: the colours one after the other, each one's vertices in
 * parallel, in one parallel region with a static split of each colour and
 * its barrier (a vertex's step does not depend on which thread runs it). */
static void sweep(cr_sim *s, cr_vbd *v, sweep_ctx *c) {
    double t = cr_time_now();
    const int32_t nfree = v->col_off[v->ncol];
    int threads = cr_thread_count();
    if ((int64_t)threads * VBD_GRAIN > nfree) threads = (int)(nfree / VBD_GRAIN);
    if (threads <= 1) {
        for (int32_t k = 0; k < nfree; k++)
            vertex_step(c, k);
    } else {
#ifdef _OPENMP
#pragma omp parallel num_threads(threads)
        for (int col = 0; col < v->ncol; col++) {
#pragma omp for schedule(static)
            for (int32_t k = v->col_off[col]; k < v->col_off[col + 1]; k++)
                vertex_step(c, k);
        }
#endif
    }
    s->rep->seconds_assembly += cr_time_now() - t;
}

/* The largest vertex gradient of the last sweep into *gnorm, in a fixed
 * order; 0 when one was not finite. */
static int sweep_gnorm(const cr_vbd *v, double *gnorm) {
    int finite = 1;
    *gnorm = 0.0;
    for (int32_t k = 0; k < v->col_off[v->ncol]; k++) {
        double gk = v->gnorm[v->col_vert[k]];
        if (!isfinite(gk))
            finite = 0;
        else if (gk > *gnorm)
            *gnorm = gk;
    }
    return finite;
}

static int all_finite_vbd(const double *a, int64_t n) {
    for (int64_t k = 0; k < n; k++)
        if (!isfinite(a[k])) return 0;
    return 1;
}

/* The objective at x after term t (one-vertex, nvert 1) changed: its value
 * again, the others' from the last evaluation, summed as cr_assembly_eval
 * sums them (the same bits as evaluating everything). */
static double reeval_term(cr_sim *s, int t, const double *x) {
    if (t >= 0) {
        const cr_energy_term *term = &s->terms[t];
        double sum = 0.0;
        CR_ASSERT(term->nvert == 1 && !term->elem);
        if (term->weight != 0.0)
            for (int32_t e = 0; e < term->nelem; e++)
                sum += term->weight * term->kernel(term->data, e, x + 3 * (int64_t)e, NULL, NULL);
        s->term_values[t] = sum;
    }
    double total = 0.0;
    for (int k = 0; k < s->nterms; k++)
        total += s->term_values[k];
    return total;
}

/* Vertex block descent's coarse correction at s->x, whose objective is
 * *e_start: the direction from vbd_coarse.c (with P^T H P evaluated and
 * factorised again when `refresh`, else the last one's), cut to o->max_step
 * for the largest vertex move (and to the self-contact bound), and an Armijo
 * backtracking search on the whole objective. *taken = 1 when the step was
 * kept (s->x and *e_start moved, its largest vertex move added to *moved,
 * which grows the collider's query radius); else s->x and the term values
 * are as they were. */
static cr_status coarse_step(cr_sim *s, cr_vbd *v, const newton_opts *o, int refresh,
                             double *e_start, double *moved, int *taken, cr_error *err) {
    const int64_t n3 = 3 * (int64_t)s->nv;
    double tv[CR_SIM_MAX_TERMS];
    *taken = 0;
    memcpy(tv, s->term_values, sizeof tv);
    double e0 = cr_sim_eval(s, s->x, s->grad, refresh);
    for (int32_t i = 0; i < s->nv; i++)
        if (s->pinned[i]) memset(s->grad + 3 * (int64_t)i, 0, 3 * sizeof(double));
    int ok = isfinite(e0);
    double *dir = s->dx;
    if (ok && refresh) CR_TRY(cr_vbd_coarse_factor(s, s->vbd_coarse, &ok, err));
    if (ok) CR_TRY(cr_vbd_coarse_direction(s, s->vbd_coarse, s->grad, dir, &ok, err));
    double gd = 0.0, longest = 0.0;
    if (ok)
        for (int32_t i = 0; i < s->nv; i++) {
            const double *g = s->grad + 3 * (int64_t)i, *p = dir + 3 * (int64_t)i;
            gd += g[0] * p[0] + g[1] * p[1] + g[2] * p[2];
            double l2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            if (l2 > longest) longest = l2;
        }
    longest = sqrt(longest);
    if (ok && gd < 0.0 && isfinite(longest) && longest > 0.0) {
        double alpha = longest > o->max_step ? o->max_step / longest : 1.0;
        for (int ls = 0; ls <= VBD_COARSE_LINE_SEARCH; ls++, alpha *= 0.5) {
            for (int64_t k = 0; k < n3; k++)
                s->xt[k] = s->x[k] + alpha * dir[k];
            if (s->self) bound_all(s, v, s->xt);
            double e = cr_sim_eval(s, s->xt, NULL, 0);
            if (isfinite(e) && e <= e0 + s->def.armijo * alpha * gd) {
                memcpy(s->x, s->xt, (size_t)n3 * sizeof(double));
                *e_start = e, *taken = 1;
                *moved += alpha * longest;
                s->rep->vbd_coarse_steps++;
                return CR_OK;
            }
        }
    }
    s->rep->vbd_coarse_rejected++;
    /* reeval_term sums the term values of the last evaluation: those of s->x. */
    memcpy(s->term_values, tv, sizeof tv);
    return CR_OK;
}

cr_status cr_vbd_solve(cr_sim *s, const newton_opts *o, cr_error *err) {
    cr_vbd *v = s->vbd;
    cr_sim_report *rep = s->rep;
    const cr_sim_def *d = &s->def;
    const int64_t n3 = 3 * (int64_t)s->nv;
    const int dynamic = o->h > 0.0;
    /* One-vertex terms with an element list (friction's contacts): which
     * element is whose. */
    for (int t = 0; t < s->nterms; t++) {
        const cr_energy_term *term = &s->terms[t];
        if (term->nvert != 1 || !term->elem) continue;
        for (int32_t i = 0; i < s->nv; i++)
            v->map[t][i] = -1;
        for (int32_t e = 0; e < term->nelem; e++)
            v->map[t][term->elem[e]] = e;
    }
    sweep_ctx c = {s, v, dynamic ? d->vbd_damping / o->h : 0.0, o->max_step, 1, 0};
    const double rho = dynamic ? d->vbd_chebyshev : 0.0;
    double omega = 1.0, moved = 0.0, tv[CR_SIM_MAX_TERMS];
    int converged = 0, it, corrections = 0;
    /* The guess, the collider's clamp included, was walked out within the
     * bound (cr_vbd_bound_guess): every free vertex starts within it. */
    if (s->self) memset(v->bounded, 0, (size_t)s->nv);
    memcpy(v->xb, s->x, (size_t)n3 * sizeof(double));
    /* The objective at the sweep's start, for the current linearisation of
     * the collider (only the collision term changes with it). */
    double e_start = cr_sim_eval(s, s->x, NULL, 0);
    for (it = 0; it < o->max_iterations && !converged; it++) {
        if (it > 0 && s->bvh) {
            const double radius = o->base_radius + 2.0 * moved;
            if (d->vbd_requery_move > 0.0)
                cr_sim_requery_collider(s, s->x, radius,
                                        d->vbd_requery_move * d->material.collision_thickness);
            else
                cr_sim_query_collider(s, s->x, radius);
            e_start = reeval_term(s, v->t_collision, s->x);
        }
        /* A vertex reached its bound: find the pairs again where the cloth
         * is now, which resets the bounds there. */
        if (s->self) {
            int32_t cut = 0;
            for (int32_t i = 0; i < s->nv; i++)
                cut += v->bounded[i];
            if (cut > 0) {
                rep->self_contact_bounded += cut;
                CR_TRY(cr_sim_detect_self(s, s->x, 0, err));
                memset(v->bounded, 0, (size_t)s->nv);
                e_start = cr_sim_eval(s, s->x, NULL, 0);
            }
        }
        /* The coarse correction: a Newton step on the aggregates, where
         * the sweeps leave a region's smooth error (vbd_coarse.c). The
         * extrapolation restarts after it: the last two iterates no longer
         * lie on one sweep's path. */
        int coarse = 0;
        if (s->vbd_coarse && it > 0 && it % d->vbd_coarse_every == 0) {
            const int refresh = corrections % d->vbd_coarse_refresh == 0;
            CR_TRY(coarse_step(s, v, o, refresh, &e_start, &moved, &coarse, err));
            corrections++;
            if (coarse) omega = 1.0;
        }
        memcpy(v->xa, v->xb, (size_t)n3 * sizeof(double)); /* x^{n-1} */
        memcpy(v->xb, s->x, (size_t)n3 * sizeof(double));  /* x^n */
        c.fresh = it % d->vbd_hessian_every == 0;
        sweep(s, v, &c);
        double gnorm = 0.0;
        int finite = sweep_gnorm(v, &gnorm);
        /* Chebyshev's extrapolation, kept when the objective there is not
         * above the sweep's start; else the sweep's own iterate, when it is
         * not above either; else the sweep again from its start with the
         * vertices' line searches, which then stay on for the substep. */
        double e = NAN;
        int kept = 0;
        if (rho > 0.0 && it > 0 && !coarse && finite) {
            double w = omega == 1.0 ? 2.0 / (2.0 - rho * rho) : 4.0 / (4.0 - rho * rho * omega);
            double *xt = s->xt;
            for (int64_t k = 0; k < n3; k++)
                xt[k] = w * (s->x[k] - v->xa[k]) + v->xa[k];
            if (s->self) bound_all(s, v, xt);
            memcpy(tv, s->term_values, sizeof tv);
            double ea = cr_sim_eval(s, xt, NULL, 0);
            if (isfinite(ea) && ea <= e_start) {
                memcpy(s->x, xt, (size_t)n3 * sizeof(double));
                e = ea, omega = w, kept = 1;
            } else {
                memcpy(s->term_values, tv, sizeof tv);
            }
        }
        if (!kept) {
            omega = 1.0;
            e = cr_sim_eval(s, s->x, NULL, 0);
            if (!(finite && e <= e_start) && !c.line_search) {
                c.line_search = 1;
                rep->vbd_retries++;
                memcpy(s->x, v->xb, (size_t)n3 * sizeof(double));
                sweep(s, v, &c);
                finite = sweep_gnorm(v, &gnorm);
                e = cr_sim_eval(s, s->x, NULL, 0);
            }
        }
        if (!finite || !isfinite(e) || !all_finite_vbd(s->x, n3)) {
            snprintf(s->why, sizeof s->why,
                     "non-finite energy (%g) or gradient at VBD iteration %d", e, it);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        double step = 0.0;
        for (int32_t i = 0; i < s->nv; i++) {
            const double *a = s->x + 3 * (int64_t)i, *b = v->xb + 3 * (int64_t)i;
            double m2 = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                        (a[2] - b[2]) * (a[2] - b[2]);
            if (m2 > step) step = m2;
        }
        step = sqrt(step);
        moved += step;
        if (d->on_iteration) d->on_iteration(d->on_iteration_ctx, it, e, gnorm, step);
        if (step < o->tol) converged = 1;
        e_start = e;
    }
    rep->newton_iterations += it;
    if (!converged) rep->newton_capped++;
    return CR_OK;
}
