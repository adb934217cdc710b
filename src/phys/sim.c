/* sim.c: the reference cloth simulator (see crease/phys_sim.h for the method).
 *
 * One substep of length h from collider time t0 to t1 (in frames):
 *   1. the collider's positions are interpolated at t0 and t1 (implicit
 *      Euler evaluates the collider at the end);
 *   2. x_pred = x + h v goes to the inertia term, x_t to the drag term;
 *   3. the collider is queried at x_t within a radius R = m (the collision
 *      term's largest threshold at the last query: the thickness eps plus
 *      the chord sag of coarse faces over a curved collider, collision.c) +
 *      (penetration left by the last substep) + (collider motion over the
 *      substep) + 2 (h max|v| + h^2 |g|) + 1 mm, which covers every vertex
 *      that can reach its threshold during the step; the collision term is
 *      linearised there (d(x) = d_i + n_i . (x - x_i)). A moving collider is
 *      queried in its pose at t0 and each closest point is carried to t1 with
 *      its face (track_collider); then the BVH is refitted to t1. The lagged friction
 *      freezes the contacts (normal force, tangent frame, and an anchor moved
 *      with the collider surface under the vertex);
 *   4. Newton starts from x_pred, with every vertex that the prediction puts
 *      deeper than half its threshold (by the linearisation) moved back to it;
 *   5. Newton: assemble, factorise with CHOLMOD (shifted if not positive
 *      definite), solve, backtracking Armijo line search on the incremental
 *      potential; every later iterate queries the collider again (R grows by
 *      twice the distance moved so far) and relinearises. Converged when an
 *      unshifted step's largest vertex move is below max(newton_tol h,
 *      newton_rtol |x - x_t|_inf) (static: static_tol);
 *   6. a last query: penetration, projection of vertices with d < 0 to a
 *      quarter of the thickness outside the surface (exactly onto it, half of
 *      them ended a rounding error inside; their inward normal velocity
 *      removed), velocities, checks,
 *      plasticity.
 * A frame runs `substeps` substeps; a failed one restores the frame's start
 * and retries with twice the substeps (max_backoff times).
 *
 * Pinned vertices are left out of the solve; with def.pin_frames they are
 * moved to their positions at t1 before Newton starts (step 4).
 *
 * With def.self_contact, the cloth's own pairs are found at x_t after step 3
 * (cr_sim_detect_self) and held through the solve: Newton sees them once per
 * substep; VBD finds them again where its step bound was reached (vbd.c).
 *
 * Left out: continuous collision detection, adaptive time
 * steps inside a frame beyond the backoff. Two ways to factorise less were tried and dropped:
 * reusing a factorisation as the preconditioner of conjugate gradients on later iterations
 * (contacts and rotations change a cloth Hessian so much between iterations that CG rarely
 * converged in the time of a new factor), and factorising a sparser matrix without bending's
 * couplings between hinge wing tips, moved to the diagonal by their norm (half the fill, but the
 * matrix then misses the smooth bending modes: a folded paper strip stayed
 * folded).
 */
#include "crease/phys_sim.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "crease/bvh.h"
#include "crease/phys_assemble.h"
#include "crease/phys_solve.h"
#include "crease/topology.h"
#include "phys/sim_internal.h"

cr_sim_def cr_sim_default_def(void) {
    cr_sim_def d;
    memset(&d, 0, sizeof d);
    d.dt = 1.0 / 30.0;
    d.substeps = 1;
    d.max_backoff = 3;
    d.newton_max_iterations = 8;
    d.newton_tol = 1e-3;
    d.newton_rtol = 1e-2;
    d.damping = 0.5;
    /* The static solve creeps: the cloth slides on the collider's facets a
     * millimetre an iteration, re-linearised each time. From the settled 12 x 12
     * drape on the sphere it took 250 (Newton's settling) to 362 (VBD's)
     * iterations (2026-12-04); 200 capped both. */
    d.static_max_iterations = 500;
    d.static_tol = 1e-6;
    d.static_max_step = 0.05;
    d.line_search_max = 30;
    d.armijo = 1e-4;
    d.gravity[1] = -9.81;
    d.uv_scale = 1.0f;
    d.bending_rest_from_mesh = 1;
    d.bending_hessian = CR_HESSIAN_GAUSS_NEWTON;
    d.friction_eps = 1e-4;
    d.plastic_rule = CR_PLASTIC_LINEAR;
    d.max_speed = 50.0;
    d.max_penetration = 0.05;
    d.solver = CR_SIM_SOLVER_NEWTON;
    d.vbd_iterations = 30;
    d.vbd_tol = 0.0; /* newton_tol's */
    d.vbd_chebyshev = 0.9;
    d.vbd_damping = 0.0;
    d.vbd_hessian_every = 1;
    d.vbd_collision_scale = 10.0;
    d.vbd_requery_move = 0.05;
    d.vbd_coarse_every = 0;
    d.vbd_coarse_rings = 2;
    d.vbd_coarse_refresh = 1;
    d.self_contact = 0;
    d.self_contact_thickness = 4e-3;
    d.cookie = CR_SIM_DEF_COOKIE;
    return d;
}

int cr_sim_solver_parse(const char *name) {
    if (!name) return -1;
    if (strcmp(name, "newton") == 0) return CR_SIM_SOLVER_NEWTON;
    if (strcmp(name, "vbd") == 0) return CR_SIM_SOLVER_VBD;
    return -1;
}

const char *cr_sim_solver_name(cr_sim_solver s) {
    return s == CR_SIM_SOLVER_VBD ? "vbd" : "newton";
}

/* ---------------------------------------------------------------- drag -- */

/* Linear air drag f = -c m v, integrated implicitly: with v = (x - x_t)/h its
 * incremental potential is c/(2h) m |x - x_t|^2 (Rayleigh mass damping). */
static double drag_kernel(const void *data, int32_t e, const double *xe, double *g, double *H) {
    const sim_drag *dr = data;
    double k = dr->coef * dr->mass[e], v = 0.0;
    for (int j = 0; j < 3; j++) {
        double r = xe[j] - dr->x_start[3 * (int64_t)e + j];
        v += 0.5 * k * r * r;
        if (g) g[j] = k * r;
    }
    if (H) {
        memset(H, 0, 9 * sizeof(double));
        H[0] = H[4] = H[8] = k;
    }
    return v;
}

void cr_sim_drag_term(const sim_drag *dr, int32_t nv, cr_energy_term *out) {
    memset(out, 0, sizeof *out);
    out->name = "damping";
    out->nelem = nv;
    out->nvert = 1;
    out->kernel = drag_kernel;
    out->data = dr;
    out->weight = 1.0;
}

/* ------------------------------------------------------------ collider -- */

/* Collider positions at time t (frames), linear between stored frames. */
static void collider_pose(const cr_sim *s, double t, float *out) {
    const cr_sim_def *d = &s->def;
    int64_t nc3 = 3 * (int64_t)s->ncv;
    if (!d->collider_frames) {
        memcpy(out, s->collider_rest, (size_t)nc3 * sizeof(float));
        return;
    }
    double f = floor(t), a = t - f;
    int64_t last = d->collider_nframes - 1;
    int64_t i0 = (int64_t)f, i1 = i0 + 1;
    i0 = i0 < 0 ? 0 : (i0 > last ? last : i0);
    i1 = i1 < 0 ? 0 : (i1 > last ? last : i1);
    const float *p0 = d->collider_frames + i0 * nc3, *p1 = d->collider_frames + i1 * nc3;
    for (int64_t k = 0; k < nc3; k++)
        out[k] = (float)((1.0 - a) * p0[k] + a * p1[k]);
}

/* Pinned vertices driven by def.pin_frames go to their positions at time t
 * (frames), linear between stored frames as the collider. */
static void move_pins(cr_sim *s, double t) {
    const cr_sim_def *d = &s->def;
    if (!d->pin_frames) return;
    double f = floor(t), a = t - f;
    int64_t last = d->pin_nframes - 1, i0 = (int64_t)f, i1 = i0 + 1;
    i0 = i0 < 0 ? 0 : (i0 > last ? last : i0);
    i1 = i1 < 0 ? 0 : (i1 > last ? last : i1);
    const float *p0 = d->pin_frames + 3 * i0 * s->npin, *p1 = d->pin_frames + 3 * i1 * s->npin;
    for (int32_t i = 0; i < s->npin; i++)
        for (int k = 0; k < 3; k++)
            s->x[3 * (int64_t)s->pin_index[i] + k] = (1.0 - a) * p0[3 * i + k] + a * p1[3 * i + k];
}

/* Poses at t0 (cpos_prev, into the BVH) and t1 (cpos); returns the largest
 * collider vertex displacement, m. A static collider never moves. */
static cr_status move_collider(cr_sim *s, double t0, double t1, double *motion, cr_error *err) {
    *motion = 0.0;
    if (!s->bvh || !s->def.collider_frames) return CR_OK;
    collider_pose(s, t0, s->cpos_prev);
    collider_pose(s, t1, s->cpos);
    double m2 = 0.0;
    for (int32_t i = 0; i < s->ncv; i++) {
        double d2 = 0.0;
        for (int k = 0; k < 3; k++) {
            double dk = (double)s->cpos[3 * i + k] - s->cpos_prev[3 * i + k];
            d2 += dk * dk;
        }
        if (d2 > m2) m2 = d2;
    }
    *motion = sqrt(m2);
    return cr_bvh_refit(s->bvh, s->cpos_prev, err);
}

/* Where each vertex was queried (x) and a lower bound on its signed distance
 * to the collider there: the distance found (a miss reports the query's
 * radius) less `slack`. The signed distance is 1-Lipschitz, so a vertex that
 * has since moved by m is at least qlow - m from the collider. */
static void remember_queries(cr_sim *s, const double *x, double slack) {
    memcpy(s->qx, x, 3 * (size_t)s->nv * sizeof(double));
    for (int32_t i = 0; i < s->nv; i++)
        s->qlow[i] = (double)s->dist[i] - slack;
}

/* Signed distances of x within radius into s->dist / s->normal and the
 * collision term's linearisation. */
void cr_sim_query_collider(cr_sim *s, const double *x, double radius) {
    if (!s->bvh) return;
    double t = cr_time_now();
    for (int64_t k = 0; k < 3 * (int64_t)s->nv; k++)
        s->xf[k] = (float)x[k];
    cr_bvh_signed_distance_batch(s->bvh, s->xf, s->nv, (float)radius, s->dist, s->normal, NULL);
    cr_collision_update(s->collision, x, s->dist, s->normal);
    remember_queries(s, x, 0.0);
    s->rep->seconds_collision += cr_time_now() - t;
}

void cr_sim_requery_collider(cr_sim *s, const double *x, double radius, double move_tol) {
    if (!s->bvh) return;
    double t = cr_time_now();
    const double band = cr_collision_max_margin(s->collision);
    int32_t m = 0;
    for (int32_t i = 0; i < s->nv; i++) {
        const double *xi = x + 3 * (int64_t)i, *qi = s->qx + 3 * (int64_t)i;
        const double d[3] = {xi[0] - qi[0], xi[1] - qi[1], xi[2] - qi[2]};
        const double m2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        /* Still where it was queried, or still outside the penalty's band
         * (then its linearised distance is too: it moved less than that). */
        if (!(m2 > move_tol * move_tol) || s->qlow[i] - sqrt(m2) > band) continue;
        s->qsel[m] = i;
        for (int k = 0; k < 3; k++)
            s->xf[3 * (int64_t)m + k] = (float)xi[k];
        m++;
    }
    cr_bvh_signed_distance_batch(s->bvh, s->xf, m, (float)radius, s->qdist, s->qnormal, NULL);
    for (int32_t k = 0; k < m; k++) {
        const int32_t i = s->qsel[k];
        s->dist[i] = s->qdist[k];
        for (int j = 0; j < 3; j++) {
            s->normal[3 * (int64_t)i + j] = s->qnormal[3 * (int64_t)k + j];
            s->qx[3 * (int64_t)i + j] = x[3 * (int64_t)i + j];
        }
        s->qlow[i] = (double)s->qdist[k];
    }
    cr_collision_update_vertices(s->collision, x, s->dist, s->normal, s->qsel, m);
    s->rep->vbd_requeries += m;
    s->rep->seconds_collision += cr_time_now() - t;
}

/* (b - a) x (c - a) of face f at positions pos, normalised (zero when degenerate). */
static void face_normal(const float *pos, const int32_t *f, double n[3]) {
    const float *a = pos + 3 * (int64_t)f[0], *b = pos + 3 * (int64_t)f[1],
                *c = pos + 3 * (int64_t)f[2];
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++)
        e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; k++)
        n[k] = len > 0.0 ? n[k] / len : 0.0;
}

typedef struct start_ctx {
    cr_sim *s;
    const float *vn; /* the collider's vertex normals at t0 */
    float radius;
    int carry; /* a moving collider: carry each closest point to t1 */
} start_ctx;

/* Per vertex of s->xf, the step-start query: the signed distance and
 * pseudo-normal on the collider at t0 (the BVH's pose) into s->dist /
 * s->normal and the smooth normal there into s->smooth; with `carry`, the
 * closest point carried to t1 with its face: the surface's displacement into
 * s->disp and the normal turned with the face. */
static void start_range(void *vctx, int64_t begin, int64_t end) {
    const start_ctx *c = vctx;
    cr_sim *s = c->s;
    const int32_t *tri = cr_bvh_triangles(s->bvh);
    for (int64_t i = begin; i < end; i++) {
        float *n = s->normal + 3 * i;
        cr_bvh_hit hit;
        const int reached =
            cr_bvh_signed_distance(s->bvh, s->xf + 3 * i, c->radius, &s->dist[i], n, &hit);
        if (!reached) hit.face = -1;
        cr_bvh_smooth_normal(s->bvh, c->vn, &hit, s->smooth + 3 * i);
        if (!c->carry) continue;
        double *di = s->disp + 3 * i;
        di[0] = di[1] = di[2] = 0.0;
        if (!reached) continue;
        const int32_t *f = tri + 3 * (int64_t)hit.face;
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                di[j] += hit.bary[k] * ((double)s->cpos[3 * f[k] + j] - s->cpos_prev[3 * f[k] + j]);
        /* The normal turns with its face (to first order: add the face
         * normal's change), and the plane moves by the displacement. */
        double f0[3], f1[3], m[3];
        face_normal(s->cpos_prev, f, f0);
        face_normal(s->cpos, f, f1);
        for (int k = 0; k < 3; k++)
            m[k] = n[k] + f1[k] - f0[k];
        double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
        if (len > 1e-6)
            for (int k = 0; k < 3; k++)
                n[k] = (float)(m[k] / len);
    }
}

/* The step-start query at x (start_range), the collision term linearised
 * there and its thresholds set. */
static void query_start(cr_sim *s, const double *x, double radius, int carry) {
    for (int64_t k = 0; k < 3 * (int64_t)s->nv; k++)
        s->xf[k] = (float)x[k];
    start_ctx c = {s, cr_bvh_vertex_normals(s->bvh), (float)radius, carry};
    cr_parallel_for(s->nv, 512, start_range, &c);
    cr_collision_update(s->collision, x, s->dist, s->normal);
    cr_collision_update_margins(s->collision, s->smooth, radius);
}

static void update_friction(cr_sim *s, const double *x_start) {
    if (!s->friction) return;
    double t = cr_time_now();
    cr_friction_update(s->friction, s->collision, x_start, s->def.collider_frames ? s->disp : NULL);
    /* The contact list changed: refresh the term's element count. */
    cr_friction_term(s->friction, &s->terms[s->t_friction]);
    s->rep->seconds_collision += cr_time_now() - t;
}

/* The collision term's linearisation at x_start for a moving collider, taken
 * where the collider was rather than where it went: the closest point at t0,
 * carried to t1 by the collider's own motion. Querying x_start against the
 * pose at t1 goes wrong wherever the body moves further than it is thick in
 * a substep: a vertex an arm swept over lies deep inside the arm at t1, its
 * nearest surface is the arm's far side, and Newton pushes it through.
 *
 * Friction takes its normal forces from the contacts at t0, before the
 * collider's motion is added: the linearisation at t1 puts a vertex the body
 * walks into centimetres deep, and its penalty force (hundreds of newtons)
 * glued the cloth to the skin and tore it (membrane energies of 1e3 J on a
 * walking t-shirt). The BVH is at t0 on entry and refitted to t1 on return. */
static cr_status track_collider(cr_sim *s, const double *x_start, double radius, double motion,
                                cr_error *err) {
    double t = cr_time_now();
    query_start(s, x_start, radius, 1);
    s->rep->seconds_collision += cr_time_now() - t;
    update_friction(s, x_start);
    t = cr_time_now();
    for (int32_t i = 0; i < s->nv; i++) {
        const float *n = s->normal + 3 * (int64_t)i;
        const double *di = s->disp + 3 * (int64_t)i;
        s->dist[i] -= (float)(n[0] * di[0] + n[1] * di[1] + n[2] * di[2]);
    }
    cr_collision_update(s->collision, x_start, s->dist, s->normal);
    /* At t1 the distance from t0 is off by up to the collider's motion, and
     * the carried one by up to that again. */
    remember_queries(s, x_start, 2.0 * motion);
    cr_status st = cr_bvh_refit(s->bvh, s->cpos, err);
    s->rep->seconds_collision += cr_time_now() - t;
    return st;
}

/* -------------------------------------------------------- self-contact -- */

cr_status cr_sim_detect_self(cr_sim *s, const double *x, int newton, cr_error *err) {
    if (!s->self) return CR_OK;
    double t = cr_time_now();
    CR_TRY(cr_self_contact_detect(s->self, x, err));
    cr_energy_term *term = &s->terms[s->t_self];
    cr_self_contact_term(s->self, term);
    s->rep->self_contact_detections++;
    s->rep->self_contact_pairs = term->nelem;
    /* The assembly's pattern holds the pairs: rebuild it when they changed
     * (the same pairs in the same order need nothing). */
    int64_t n4 = 4 * (int64_t)term->nelem;
    int same = term->nelem == s->self_prev_n &&
               (n4 == 0 || memcmp(term->elem, s->self_prev, (size_t)n4 * sizeof(int32_t)) == 0);
    if (!same) {
        if (n4 > s->self_prev_cap) {
            int32_t *p = realloc(s->self_prev, (size_t)n4 * sizeof(int32_t));
            if (!p) return CR_FAIL(err, CR_ERR_MEMORY, "simulator: out of memory for pairs");
            s->self_prev = p, s->self_prev_cap = (int32_t)n4;
        }
        if (n4 > 0) memcpy(s->self_prev, term->elem, (size_t)n4 * sizeof(int32_t));
        s->self_prev_n = term->nelem;
        cr_assembly_destroy(s->assembly);
        s->assembly = NULL;
        CR_TRY(cr_assembly_create(s->terms, s->nterms, s->nv, &s->assembly, err));
        s->assembly_builds++;
        cr_cholesky_destroy(s->chol);
        s->chol = NULL;
    }
    if (newton && !s->chol)
        CR_TRY(cr_cholesky_create(cr_assembly_hessian(s->assembly), s->pinned, &s->chol, err));
    s->rep->seconds_self_contact += cr_time_now() - t;
    return CR_OK;
}

/* -------------------------------------------------------------- newton -- */

double cr_sim_eval(cr_sim *s, const double *x, double *grad, int hessian) {
    double t = cr_time_now();
    double e = cr_assembly_eval(s->assembly, s->terms, x, grad, hessian, s->term_values);
    s->rep->seconds_assembly += cr_time_now() - t;
    return e;
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

static int all_finite(const double *a, int64_t n) {
    for (int64_t k = 0; k < n; k++)
        if (!isfinite(a[k])) return 0;
    return 1;
}

/* Newton's first guess: x_pred, except that a vertex whose linearised
 * distance there falls below half its threshold (the thickness and its
 * edges' chord sag) is moved out to it along the normal. Starting deep
 * inside the penalty (a falling cloth predicted centimetres into the body)
 * costs many damped iterations; starting on its rim with no curvature lets
 * the first step overshoot; at half the threshold the penalty's curvature is
 * there and the step is short. */
static void clamp_guess(cr_sim *s) {
    for (int32_t i = 0; i < s->nv; i++) {
        const double target = 0.5 * cr_collision_margin(s->collision, i);
        const float *n = s->normal + 3 * (int64_t)i;
        if (s->pinned[i] || (n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f)) continue;
        double *x = s->x + 3 * (int64_t)i;
        const double *x0 = s->x_start + 3 * (int64_t)i;
        double d =
            s->dist[i] + n[0] * (x[0] - x0[0]) + n[1] * (x[1] - x0[1]) + n[2] * (x[2] - x0[2]);
        if (d < target)
            for (int k = 0; k < 3; k++)
                x[k] += (target - d) * n[k];
    }
}

/* Minimise the current objective from s->x (in place); s->x_start holds the
 * start. Fails with CR_ERR_DIVERGED and a message in s->why. */
static cr_status newton(cr_sim *s, const newton_opts *o, cr_error *err) {
    cr_sim_report *rep = s->rep;
    const int64_t n3 = 3 * (int64_t)s->nv;
    double moved = 0.0;
    int converged = 0, it;
    for (it = 0; it < o->max_iterations && !converged; it++) {
        if (it > 0) cr_sim_query_collider(s, s->x, o->base_radius + 2.0 * moved);
        double e = cr_sim_eval(s, s->x, s->grad, 1);
        for (int32_t i = 0; i < s->nv; i++)
            if (s->pinned[i]) memset(s->grad + 3 * (int64_t)i, 0, 3 * sizeof(double));
        double gnorm = max_vertex_norm(s, s->grad);
        if (!isfinite(e) || !isfinite(gnorm)) {
            snprintf(s->why, sizeof s->why,
                     "non-finite energy (%g) or gradient at Newton iteration %d", e, it);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        if (gnorm == 0.0) {
            converged = 1;
            break;
        }
        /* Newton direction: (H + shift I) dx = -g. A shifted (damped) step is
         * not a Newton step, so its length says nothing about convergence. */
        double t = cr_time_now();
        cr_cholesky_info info;
        cr_status st = cr_cholesky_factor(s->chol, cr_assembly_hessian(s->assembly), &info, err);
        rep->seconds_factor += cr_time_now() - t;
        rep->factorisations += 1 + info.retries;
        if (info.shift > rep->max_shift) rep->max_shift = info.shift;
        if (st != CR_OK) {
            snprintf(s->why, sizeof s->why, "factorisation at Newton iteration %d: %.110s", it,
                     err ? err->msg : cr_status_str(st));
            return st == CR_ERR_NAN || st == CR_ERR_DIVERGED
                       ? CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why)
                       : st;
        }
        int exact = info.shift == 0.0;
        t = cr_time_now();
        for (int64_t k = 0; k < n3; k++)
            s->dx[k] = -s->grad[k];
        st = cr_cholesky_solve(s->chol, s->dx, s->dx, err);
        rep->seconds_solve += cr_time_now() - t;
        if (st != CR_OK) return st;
        double gd = 0.0;
        for (int64_t k = 0; k < n3; k++)
            gd += s->grad[k] * s->dx[k];
        double dmax = max_vertex_norm(s, s->dx);
        if (!isfinite(gd) || !isfinite(dmax)) {
            snprintf(s->why, sizeof s->why, "non-finite Newton step at iteration %d", it);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        if (dmax > o->max_step) {
            /* A (nearly) free mode of a static Hessian: walk along it in bounded steps. */
            double scale = o->max_step / dmax;
            for (int64_t k = 0; k < n3; k++)
                s->dx[k] *= scale;
            gd *= scale, dmax = o->max_step;
        }
        double tol = o->tol;
        if (o->rtol > 0.0) {
            double far = 0.0;
            for (int32_t i = 0; i < s->nv; i++)
                for (int k = 0; k < 3; k++)
                    far =
                        fmax(far, fabs(s->x[3 * (int64_t)i + k] - s->x_start[3 * (int64_t)i + k]));
            tol = fmax(tol, o->rtol * far);
        }
        /* Converged already, or below round-off: the objective cannot tell
         * the step from no step, so a failed line search is no failure. */
        int at_floor = exact && (-gd <= 1e-14 * (fabs(e) + 1e-300) || dmax < tol);
        double alpha = 1.0, et = e;
        int accepted = 0;
        for (int ls = 0; ls <= s->def.line_search_max; ls++, alpha *= 0.5) {
            for (int64_t k = 0; k < n3; k++)
                s->xt[k] = s->x[k] + alpha * s->dx[k];
            et = cr_sim_eval(s, s->xt, NULL, 0);
            if (isfinite(et) && et <= e + s->def.armijo * alpha * gd) {
                accepted = 1;
                break;
            }
        }
        if (!accepted) {
            if (at_floor) {
                cr_sim_eval(s, s->x, NULL, 0); /* the report's energies are those at x */
                converged = 1;
                break;
            }
            snprintf(s->why, sizeof s->why,
                     "line search found no decrease at Newton iteration %d (energy %.6g J, "
                     "gradient %.3g N, step %.3g m)",
                     it, e, gnorm, dmax);
            return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
        }
        memcpy(s->x, s->xt, (size_t)n3 * sizeof(double));
        double step = alpha * dmax;
        moved += step;
        if (s->def.on_iteration) s->def.on_iteration(s->def.on_iteration_ctx, it, et, gnorm, step);
        if (exact && step < tol) converged = 1;
    }
    rep->newton_iterations += it;
    if (!converged) rep->newton_capped++;
    return CR_OK;
}

/* ------------------------------------------------------------- substep -- */

static void save_frame_state(cr_sim *s) {
    size_t n3 = 3 * (size_t)s->nv * sizeof(double);
    memcpy(s->x_frame, s->x, n3);
    memcpy(s->v_frame, s->v, n3);
    memcpy(s->rest_frame, s->rest, (size_t)s->nh * sizeof(double));
    memcpy(s->a_frame, s->a_prev, n3);
}

static void restore_frame_state(cr_sim *s) {
    size_t n3 = 3 * (size_t)s->nv * sizeof(double);
    memcpy(s->x, s->x_frame, n3);
    memcpy(s->v, s->v_frame, n3);
    memcpy(s->rest, s->rest_frame, (size_t)s->nh * sizeof(double));
    memcpy(s->a_prev, s->a_frame, n3);
}

/* Where a vertex found inside is put: this fraction of the thickness outside. */
#define PROJECT_CLEARANCE 0.25

/* One implicit Euler substep of length h from collider time t0 to t1
 * (dynamic), or an equilibrium solve at t1 (dynamic = 0). */
static cr_status substep(cr_sim *s, double h, double t0, double t1, int dynamic, int plastic,
                         cr_error *err) {
    const cr_sim_def *d = &s->def;
    cr_sim_report *rep = s->rep;
    const int64_t n3 = 3 * (int64_t)s->nv;
    double motion = 0.0, t = cr_time_now();
    CR_TRY(move_collider(s, t0, t1, &motion, err));
    rep->seconds_collision += cr_time_now() - t;

    memcpy(s->x_start, s->x, (size_t)n3 * sizeof(double));
    double vmax = 0.0;
    if (dynamic) {
        for (int64_t k = 0; k < n3; k++)
            s->x_pred[k] = s->x[k] + h * s->v[k];
        cr_inertia_set(s->inertia, s->x_pred, h);
        vmax = max_vertex_norm(s, s->v);
    }
    s->terms[s->t_inertia].weight = dynamic ? 1.0 : 0.0;
    s->drag.coef = d->damping / h;
    s->terms[s->t_drag].weight = dynamic && d->damping > 0.0 ? 1.0 : 0.0;
    double g = sqrt(d->gravity[0] * d->gravity[0] + d->gravity[1] * d->gravity[1] +
                    d->gravity[2] * d->gravity[2]);
    /* VBD steps dynamic substeps; static solves (cr_sim_solve_static,
     * quasi-static frames) use Newton with either solver: without inertia a
     * Gauss-Seidel sweep has no mass term to bound its blocks, and 4000
     * sweeps left a 16 x 16 drape unconverged. */
    const int vbd = d->solver == CR_SIM_SOLVER_VBD && dynamic;
    if (!vbd && !s->chol)
        CR_TRY(cr_cholesky_create(cr_assembly_hessian(s->assembly), s->pinned, &s->chol, err));
    newton_opts o;
    if (vbd)
        o.max_iterations = d->vbd_iterations;
    else
        o.max_iterations = dynamic ? d->newton_max_iterations : d->static_max_iterations;
    o.h = dynamic ? h : 0.0;
    const double tol = vbd && d->vbd_tol > 0.0 ? d->vbd_tol : d->newton_tol;
    o.tol = dynamic ? tol * h : d->static_tol;
    o.rtol = dynamic ? d->newton_rtol : 0.0;
    o.max_step = dynamic ? INFINITY : d->static_max_step;
    /* Radius of the collider query (see the file comment). */
    const double margin =
        s->collision ? cr_collision_max_margin(s->collision) : d->material.collision_thickness;
    o.base_radius = margin + s->pen_start + motion + 2.0 * (h * vmax + h * h * g) + 1e-3;
    /* VBD's sweeps take the collider's penalty vbd_collision_scale times
     * stiffer (crease/phys_sim.h says why), friction's normal force with it;
     * Newton's solves, static ones of a VBD simulator included, the material's. */
    if (s->collision)
        cr_collision_set_stiffness(s->collision, d->material.collision_stiffness *
                                                     (vbd ? d->vbd_collision_scale : 1.0));
    /* Linearise the collider at the step's start (friction freezes its
     * contacts there too, the collision term its thresholds), then start
     * Newton from x_pred with every vertex the prediction would push into its
     * threshold put back to half of it. */
    if (s->bvh && s->def.collider_frames)
        CR_TRY(track_collider(s, s->x_start, o.base_radius, motion, err));
    else {
        if (s->bvh) {
            double t = cr_time_now();
            query_start(s, s->x_start, o.base_radius, 0);
            remember_queries(s, s->x_start, 0.0);
            s->rep->seconds_collision += cr_time_now() - t;
        }
        update_friction(s, s->x_start);
    }
    CR_TRY(cr_sim_detect_self(s, s->x_start, !vbd, err));
    if (dynamic) {
        if (vbd) {
            /* The clamp before the walk within the self-contact bound: after
             * it, the clamp lifted both layers of a fold on the floor to one
             * height, outside the bound, and the layers crossed. */
            cr_vbd_initial_guess(s, h);
            if (s->bvh) clamp_guess(s);
            CR_TRY(cr_vbd_bound_guess(s, err));
        } else {
            memcpy(s->x, s->x_pred, (size_t)n3 * sizeof(double));
            if (s->bvh) clamp_guess(s);
        }
    }
    move_pins(s, t1);
    if (vbd)
        CR_TRY(cr_vbd_solve(s, &o, err));
    else
        CR_TRY(newton(s, &o, err));

    /* Final query, projection, velocities. */
    double moved = 0.0;
    for (int32_t i = 0; i < s->nv; i++) {
        const double *a = s->x + 3 * (int64_t)i, *b = s->x_start + 3 * (int64_t)i;
        double m2 = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                    (a[2] - b[2]) * (a[2] - b[2]);
        if (m2 > moved) moved = m2;
    }
    cr_sim_query_collider(s, s->x, o.base_radius + 2.0 * sqrt(moved));
    for (int64_t k = 0; k < n3; k++)
        s->v[k] = dynamic ? (s->x[k] - s->x_start[k]) / h : 0.0;
    double pen = 0.0;
    int32_t contacts = 0;
    if (s->bvh)
        for (int32_t i = 0; i < s->nv; i++) {
            if (s->dist[i] < cr_collision_margin(s->collision, i)) contacts++;
            if (!(s->dist[i] < 0.0) || s->pinned[i]) continue;
            const float *n = s->normal + 3 * (int64_t)i;
            double *x = s->x + 3 * (int64_t)i, *v = s->v + 3 * (int64_t)i;
            double depth = -(double)s->dist[i];
            if (depth > pen) pen = depth;
            double vn = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
            for (int k = 0; k < 3; k++) {
                x[k] += (depth + PROJECT_CLEARANCE * d->material.collision_thickness) * n[k];
                if (vn < 0.0) v[k] -= vn * n[k];
            }
            rep->projected++;
        }
    rep->contacts = contacts;
    /* The substep's acceleration (after projection), for VBD's next guess. */
    for (int64_t k = 0; k < n3; k++)
        s->a_prev[k] = dynamic ? (s->v[k] - (s->x_pred[k] - s->x_start[k]) / h) / h : 0.0;
    if (pen > rep->max_penetration_m) rep->max_penetration_m = pen;
    s->pen_start = pen;
    if (!all_finite(s->x, n3) || !all_finite(s->v, n3)) {
        snprintf(s->why, sizeof s->why, "non-finite positions or velocities after the solve");
        return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
    }
    double speed = max_vertex_norm(s, s->v);
    if (speed > d->max_speed) {
        snprintf(s->why, sizeof s->why, "a vertex moves at %.3g m/s (limit %.3g)", speed,
                 d->max_speed);
        return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
    }
    if (pen > d->max_penetration) {
        snprintf(s->why, sizeof s->why, "a vertex is %.3g m inside the collider (limit %.3g)", pen,
                 d->max_penetration);
        return CR_FAIL(err, CR_ERR_DIVERGED, "%s", s->why);
    }
    if (plastic && s->nh > 0) {
        cr_bending_angles(s->bending, s->x, s->theta);
        rep->yielded += cr_plasticity_update(s->theta, s->rest, s->nh, d->material.yield_angle,
                                             d->material.plastic_gain, d->plastic_rule);
    }
    return CR_OK;
}

static void report_begin(cr_sim *s, cr_sim_report *rep) {
    memset(rep, 0, sizeof *rep);
    rep->nterms = s->nterms;
    for (int t = 0; t < s->nterms; t++)
        rep->term_name[t] = s->terms[t].name;
    s->rep = rep;
    s->why[0] = '\0';
}

static void report_end(cr_sim *s, cr_sim_report *rep, double t_start) {
    for (int t = 0; t < s->nterms; t++)
        rep->term_energy[t] = s->term_values[t];
    double ke = 0.0;
    for (int32_t i = 0; i < s->nv; i++) {
        const double *v = s->v + 3 * (int64_t)i;
        ke += 0.5 * s->mass[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    }
    rep->kinetic_energy = ke;
    rep->frame = s->frame;
    snprintf(rep->failure, sizeof rep->failure, "%s", s->why);
    rep->seconds = cr_time_now() - t_start;
    s->rep = &s->scratch_report;
}

/* Substeps for this frame: def.substeps, or more where the collider moves
 * further than def.max_collider_step between this frame and the next. */
static int frame_substeps(const cr_sim *s) {
    const cr_sim_def *d = &s->def;
    if (!(d->max_collider_step > 0.0) || !d->collider_frames) return d->substeps;
    int64_t last = d->collider_nframes - 1, i0 = s->frame < last ? s->frame : last;
    int64_t i1 = i0 + 1 < last ? i0 + 1 : last, nc3 = 3 * (int64_t)s->ncv;
    const float *p0 = d->collider_frames + i0 * nc3, *p1 = d->collider_frames + i1 * nc3;
    double m2 = 0.0;
    for (int64_t k = 0; k < nc3; k += 3) {
        double dx = p1[k] - p0[k], dy = p1[k + 1] - p0[k + 1], dz = p1[k + 2] - p0[k + 2];
        double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 > m2) m2 = d2;
    }
    double need = ceil(sqrt(m2) / d->max_collider_step);
    int n = need > 16.0 ? 16 : (int)need;
    return n > d->substeps ? n : d->substeps;
}

cr_status cr_sim_step(cr_sim *s, cr_sim_report *report, cr_error *err) {
    cr_sim_report local;
    cr_sim_report *rep = report ? report : &local;
    double t_start = cr_time_now();
    report_begin(s, rep);
    save_frame_state(s);
    double pen_frame = s->pen_start;
    int nsub = frame_substeps(s);
    int dynamic = !s->def.quasi_static;
    cr_status st = CR_OK;
    for (int attempt = 0; attempt <= s->def.max_backoff; attempt++, nsub *= 2) {
        st = CR_OK;
        rep->substeps = nsub;
        for (int k = 0; k < nsub && st == CR_OK; k++) {
            double t0 = (double)s->frame + (double)k / nsub;
            double t1 = (double)s->frame + (double)(k + 1) / nsub;
            st = substep(s, s->def.dt / nsub, t0, t1, dynamic, s->def.plasticity, err);
        }
        if (st == CR_OK) break;
        restore_frame_state(s);
        s->pen_start = pen_frame;
        if (st != CR_ERR_DIVERGED) break; /* out of memory and the like: no retry helps */
        if (attempt < s->def.max_backoff) rep->backoffs++;
    }
    if (st == CR_OK)
        s->frame++;
    else if (st == CR_ERR_DIVERGED) {
        rep->diverged = 1;
        st = CR_FAIL(err, CR_ERR_DIVERGED, "simulator: frame %lld failed with %d substeps: %s",
                     (long long)s->frame, nsub / 2, s->why);
    }
    report_end(s, rep, t_start);
    return st;
}

cr_status cr_sim_solve_static(cr_sim *s, cr_sim_report *report, cr_error *err) {
    cr_sim_report local;
    cr_sim_report *rep = report ? report : &local;
    double t_start = cr_time_now();
    report_begin(s, rep);
    save_frame_state(s);
    double pen_frame = s->pen_start;
    rep->substeps = 1;
    double t = (double)s->frame;
    cr_status st = substep(s, s->def.dt, t, t, 0, 0, err);
    if (st != CR_OK) {
        restore_frame_state(s);
        s->pen_start = pen_frame;
        rep->diverged = st == CR_ERR_DIVERGED;
        if (st == CR_ERR_DIVERGED)
            st = CR_FAIL(err, CR_ERR_DIVERGED, "simulator: static solve at frame %lld failed: %s",
                         (long long)s->frame, s->why);
    }
    report_end(s, rep, t_start);
    return st;
}
