/* qn.c: quasi-Newton, the simulator's third solver for the same incremental
 * potential as Newton (crease/phys_sim.h): L-BFGS (Nocedal & Wright, alg.
 * 7.4) whose initial Hessian H0 is a factorised Newton Hessian kept over many
 * iterations (after Liu, Bouaziz & Kavan 2017, "Quasi-Newton Methods for
 * Real-time Simulation of Hyperelastic Materials", TOG 36(3), who keep a
 * constant one for the whole run).
 *
 * H0 is the Hessian of every term (inertia, drag, membrane, bending,
 * collider, friction, self-contact: the assembly's, as Newton's) at the
 * first iterate of each frame, factorised by Newton's CHOLMOD analysis; it
 * is factorised again, at the current iterate with the history dropped,
 * when def.qn_refresh iterations have passed since the last factorisation
 * without converging, when the substep changes (backoff, collider speed)
 * or when self-contact rebuilt the pattern. Each frame's first
 * factorisation is at a point the frame's start state decides, so a run
 * resumed from a state file factorises what the uninterrupted run did: the
 * same bits.
 *
 * Why not a constant matrix, as the paper has: measured on this cloth
 * (docs/physics.md, "Quasi-Newton"), the membrane is some 1e6 times stiffer
 * than a vertex's inertia per substep and a collider's penalty stiffer
 * still. The rest-state Hessian points its stiff directions where the rest
 * shape's triangles lay, so folded and swinging cloth needed the iteration
 * cap every substep; its isotropic form (a stiffness-weighted Laplacian)
 * resists bending as it resists stretch, so the steps understate the error
 * and stop early; and neither holds the contacts' stiffness, so a vertex the
 * collider starts to push got a step of metres. Both failed the fold test
 * (a strip folded by a capsule and released swung to 100-160 degrees where
 * converged Newton reaches 70).
 *
 * One iteration (at most def.qn_iterations per substep; the history of
 * def.qn_history pairs starts empty at each substep and factorisation):
 *   1. the collider queried again for the vertices that moved more than
 *      vbd_requery_move of the thickness since their last query and may be
 *      in its band (as VBD does); only the collision term changes, so its
 *      old value and gradient are replaced by the new (two one-vertex
 *      evaluations, no full one);
 *   2. d = -H g by the two-loop recursion, H0^-1 by two triangular solves;
 *   3. backtracking Armijo line search on the objective (def.armijo,
 *      def.line_search_max halvings), the gradient evaluated with the value:
 *      every accepted step lowers the objective and its gradient is the next
 *      iteration's. A direction that is no descent, or a search that fails,
 *      drops the history and tries the H0 step once more;
 *   4. the pair (x_new - x, g_new - g), damped (Powell) where the objective
 *      curves less along the step than H0 does (bending and buckling are not
 *      convex), so the update stays positive definite.
 * Converged when the residual force would change no free vertex's velocity
 * by more than def.qn_tol over the substep against its inertia: max_i h
 * |g_i| / m_i < qn_tol. Newton's rule (a step shorter than a tolerance) does
 * not carry over: with a lagged H0 a step understates the error wherever the
 * cloth turned since the factorisation (a degree of rotation mixes stiffness
 * 1e6 times higher into the soft directions), and quasi-Newton so ruled
 * stopped after two iterations with the strip of the fold test swinging to
 * 160 degrees. Since H >= M/h^2, h^2 |g_i| / m_i bounds what a vertex
 * moving against its inertia alone is still off, so the rule holds whatever
 * H0 was.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crease/phys_solve.h"
#include "phys/sim_internal.h"

/* Line-search halvings of an L-BFGS step before H0 is made again. */
#define QN_HALVINGS 4

struct cr_qn {
    int m;                   /* history length */
    int64_t n3;              /* 3V */
    double *s, *y, *rho, *a; /* (m,3V), (m,3V), (m), (m) */
    int count, head;         /* pairs held; the slot the next one goes to */
    double *g_new, *d, *hs;  /* (3V) the trial's gradient, the direction, H0 s */
    double *gc, *gc_before;  /* (3V) the collision term's gradient after and before a requery */
    int t_collision;         /* its index in s->terms, -1 without a collider */
    double h;                /* the substep of the factorisation; 0: none */
    int64_t builds;          /* s->assembly_builds then */
};

void cr_qn_destroy(cr_qn *q) {
    if (!q) return;
    free(q->s), free(q->y), free(q->rho), free(q->a);
    free(q->g_new), free(q->d), free(q->hs), free(q->gc), free(q->gc_before);
    free(q);
}

cr_status cr_qn_create(cr_sim *s, cr_qn **out, cr_error *err) {
    *out = NULL;
    cr_qn *q = cr_calloc(1, sizeof *q, err);
    if (!q) return err ? err->status : CR_ERR_MEMORY;
    q->m = s->def.qn_history;
    q->n3 = 3 * (int64_t)s->nv;
    const size_t n3 = (size_t)q->n3, m = (size_t)q->m;
    q->s = cr_calloc(m * n3, sizeof(double), err);
    q->y = cr_calloc(m * n3, sizeof(double), err);
    q->rho = cr_calloc(m, sizeof(double), err);
    q->a = cr_calloc(m, sizeof(double), err);
    q->g_new = cr_calloc(n3, sizeof(double), err);
    q->d = cr_calloc(n3, sizeof(double), err);
    q->hs = cr_calloc(n3, sizeof(double), err);
    q->gc = cr_calloc(n3, sizeof(double), err);
    q->gc_before = cr_calloc(n3, sizeof(double), err);
    if (!q->s || !q->y || !q->rho || !q->a || !q->g_new || !q->d || !q->hs || !q->gc ||
        !q->gc_before) {
        cr_qn_destroy(q);
        return err ? err->status : CR_ERR_MEMORY;
    }
    q->t_collision = -1;
    for (int t = 0; t < s->nterms; t++)
        if (!strcmp(s->terms[t].name, "collision")) q->t_collision = t;
    *out = q;
    return CR_OK;
}

static double dot(const double *a, const double *b, int64_t n) {
    double r = 0.0;
    for (int64_t k = 0; k < n; k++)
        r += a[k] * b[k];
    return r;
}

static double max_vertex_norm(const cr_sim *s, const double *a) {
    double m2 = 0.0;
    for (int32_t i = 0; i < s->nv; i++) {
        if (s->pinned[i]) continue;
        const double *p = a + 3 * (int64_t)i;
        double n2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        if (!(n2 <= m2)) m2 = n2; /* NaN propagates */
    }
    return sqrt(m2);
}

static void zero_pinned(const cr_sim *s, double *g) {
    for (int32_t i = 0; i < s->nv; i++)
        if (s->pinned[i]) memset(g + 3 * (int64_t)i, 0, 3 * sizeof(double));
}

/* H0 at s->x: the objective's value, gradient (into s->grad) and Hessian,
 * factorised; the history dropped. */
static cr_status factor(cr_sim *s, cr_qn *q, double h, double *e, cr_error *err) {
    cr_sim_report *rep = s->rep;
    if (!s->chol)
        CR_TRY(cr_cholesky_create(cr_assembly_hessian(s->assembly), s->pinned, &s->chol, err));
    *e = cr_sim_eval(s, s->x, s->grad, 1);
    zero_pinned(s, s->grad);
    double t = cr_time_now();
    cr_cholesky_info info;
    cr_status st = cr_cholesky_factor(s->chol, cr_assembly_hessian(s->assembly), &info, err);
    rep->seconds_factor += cr_time_now() - t;
    rep->factorisations += 1 + info.retries;
    if (info.shift > rep->max_shift) rep->max_shift = info.shift;
    if (st != CR_OK) {
        snprintf(s->why, sizeof s->why, "quasi-Newton's factorisation: %.120s",
                 err ? err->msg : cr_status_str(st));
        return st == CR_ERR_NAN || st == CR_ERR_DIVERGED
                   ? CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why)
                   : st;
    }
    q->h = h, q->builds = s->assembly_builds;
    q->count = 0, q->head = 0;
    return CR_OK;
}

/* q->d = -H g by the two-loop recursion over the pairs held. */
static cr_status direction(cr_sim *s, cr_qn *q, const double *g, cr_error *err) {
    const int64_t n3 = q->n3;
    double *r = q->d;
    memcpy(r, g, sizeof(double) * (size_t)n3);
    for (int j = 0; j < q->count; j++) {
        int i = (q->head - 1 - j + 2 * q->m) % q->m; /* newest first */
        q->a[i] = q->rho[i] * dot(q->s + i * n3, r, n3);
        const double *yi = q->y + i * n3;
        for (int64_t k = 0; k < n3; k++)
            r[k] -= q->a[i] * yi[k];
    }
    double t = cr_time_now();
    cr_status st = cr_cholesky_solve(s->chol, r, r, err);
    s->rep->seconds_solve += cr_time_now() - t;
    if (st != CR_OK) return st;
    for (int j = q->count - 1; j >= 0; j--) {
        int i = (q->head - 1 - j + 2 * q->m) % q->m; /* oldest first */
        double b = q->rho[i] * dot(q->y + i * n3, r, n3);
        const double *si = q->s + i * n3;
        for (int64_t k = 0; k < n3; k++)
            r[k] += (q->a[i] - b) * si[k];
    }
    for (int64_t k = 0; k < n3; k++)
        r[k] = -r[k];
    return CR_OK;
}

/* Keep the pair of the step from s->x to s->xt (gradients s->grad, q->g_new),
 * damped as the file comment says. */
static void keep_pair(cr_sim *s, cr_qn *q) {
    const int64_t n3 = q->n3;
    double *si = q->s + q->head * n3, *yi = q->y + q->head * n3;
    for (int64_t k = 0; k < n3; k++) {
        si[k] = s->xt[k] - s->x[k];
        yi[k] = q->g_new[k] - s->grad[k];
    }
    cr_hessian_multiply(cr_assembly_hessian(s->assembly), si, q->hs);
    zero_pinned(s, q->hs);
    double sy = dot(si, yi, n3), shs = dot(si, q->hs, n3);
    if (shs > 0.0 && sy < 0.2 * shs) {
        const double theta = 0.8 * shs / (shs - sy);
        for (int64_t k = 0; k < n3; k++)
            yi[k] = theta * yi[k] + (1.0 - theta) * q->hs[k];
        sy = dot(si, yi, n3);
    }
    if (!(sy > 0.0)) return;
    q->rho[q->head] = 1.0 / sy;
    q->head = (q->head + 1) % q->m;
    if (q->count < q->m) q->count++;
}

/* The collision term alone at s->x: its value, and its gradient into g. */
static double collision_alone(cr_sim *s, const cr_qn *q, double *g) {
    double w[CR_SIM_MAX_TERMS];
    for (int t = 0; t < s->nterms; t++) {
        w[t] = s->terms[t].weight;
        if (t != q->t_collision) s->terms[t].weight = 0.0;
    }
    double e = cr_sim_eval(s, s->x, g, 0);
    for (int t = 0; t < s->nterms; t++)
        s->terms[t].weight = w[t];
    return e;
}

cr_status cr_qn_solve(cr_sim *s, const newton_opts *o, cr_error *err) {
    cr_qn *q = s->qn;
    const cr_sim_def *d = &s->def;
    cr_sim_report *rep = s->rep;
    const int64_t n3 = q->n3;
    double moved = 0.0, e = 0.0;
    int converged = 0, it, since = 0; /* since: iterations since the factorisation */
    int verify = 0;                   /* 1: L-BFGS took a short step; check with Newton's */
    if (o->first || q->h != o->h || q->builds != s->assembly_builds)
        CR_TRY(factor(s, q, o->h, &e, err));
    else {
        q->count = 0, q->head = 0;
        e = cr_sim_eval(s, s->x, s->grad, 0);
        zero_pinned(s, s->grad);
    }
    for (it = 0; it < o->max_iterations && !converged; it++, since++) {
        const int refresh = since >= d->qn_refresh || verify;
        if (it > 0 && s->bvh) {
            /* Only the collision term changes: its old value and gradient
             * out, the new in (a refresh evaluates everything anyway). */
            double before = refresh ? 0.0 : collision_alone(s, q, q->gc_before);
            int32_t requeried =
                cr_sim_requery_collider(s, s->x, o->base_radius + 2.0 * moved,
                                        d->vbd_requery_move * d->material.collision_thickness);
            if (requeried > 0 && !refresh) {
                e += collision_alone(s, q, q->gc) - before;
                for (int64_t k = 0; k < n3; k++)
                    s->grad[k] += q->gc[k] - q->gc_before[k];
                zero_pinned(s, s->grad);
            }
        }
        if (refresh) {
            CR_TRY(factor(s, q, o->h, &e, err));
            since = 0, verify = 0;
        }
        double gnorm = max_vertex_norm(s, s->grad);
        if (!isfinite(e) || !isfinite(gnorm)) {
            snprintf(s->why, sizeof s->why,
                     "non-finite energy (%g) or gradient at quasi-Newton iteration %d", e, it);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        /* At least one step: the first is Newton's when the frame's
         * factorisation was made at this iterate. */
        if (gnorm == 0.0) {
            converged = 1;
            break;
        }
        double tol = o->tol;
        if (o->rtol > 0.0) {
            double far = 0.0;
            for (int64_t k = 0; k < n3; k++)
                far = fmax(far, fabs(s->x[k] - s->x_start[k]));
            tol = fmax(tol, o->rtol * far);
        }
        double alpha = 1.0, et = e, gd = 0.0, dmax = 0.0;
        int accepted = 0, newton_step = since == 0 && q->count == 0;
        CR_TRY(direction(s, q, s->grad, err));
        gd = dot(s->grad, q->d, n3);
        dmax = max_vertex_norm(s, q->d);
        if (!isfinite(gd) || !isfinite(dmax)) {
            snprintf(s->why, sizeof s->why, "non-finite quasi-Newton step at iteration %d", it);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        /* Newton's step gets Newton's search; an L-BFGS step that needs more
         * than QN_HALVINGS halvings says H0 went stale. */
        const int halvings = newton_step ? d->line_search_max : QN_HALVINGS;
        for (int ls = 0; gd < 0.0 && ls <= halvings; ls++, alpha *= 0.5) {
            for (int64_t k = 0; k < n3; k++)
                s->xt[k] = s->x[k] + alpha * q->d[k];
            et = cr_sim_eval(s, s->xt, q->g_new, 0);
            if (isfinite(et) && et <= e + d->armijo * alpha * gd) {
                accepted = 1;
                break;
            }
        }
        if (!accepted && !newton_step) {
            /* A stale H0: factorise at this iterate and take Newton's step. */
            verify = 1;
            continue;
        }
        if (!accepted) {
            /* Converged already, or below round-off (Newton's at_floor). */
            if (dmax < tol || -gd <= 1e-14 * (fabs(e) + 1e-300)) {
                cr_sim_eval(s, s->x, NULL, 0); /* the report's energies are those at x */
                converged = 1;
                break;
            }
            snprintf(s->why, sizeof s->why,
                     "line search found no decrease at quasi-Newton iteration %d (energy %.6g J, "
                     "gradient %.3g N, step %.3g m)",
                     it, e, gnorm, dmax);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        zero_pinned(s, q->g_new);
        keep_pair(s, q);
        memcpy(s->x, s->xt, (size_t)n3 * sizeof(double));
        memcpy(s->grad, q->g_new, (size_t)n3 * sizeof(double));
        e = et;
        const double step = alpha * dmax;
        moved += step;
        if (d->on_iteration) d->on_iteration(d->on_iteration_ctx, it, et, gnorm, step);
        /* Newton's rule on a Newton step (made at this iterate); an L-BFGS
         * step that short only calls for that check. */
        if (alpha == 1.0 && step < tol) {
            if (newton_step)
                converged = 1;
            else
                verify = 1;
        }
    }
    rep->newton_iterations += it;
    if (!converged) rep->newton_capped++;
    return CR_OK;
}
