/* sim_internal.h: the simulator's struct, shared by sim.c (stepping) and
 * sim_setup.c (creation, accessors, state files). Private to src/phys. */
#ifndef CREASE_PHYS_SIM_INTERNAL_H
#define CREASE_PHYS_SIM_INTERNAL_H

#include "crease/bvh.h"
#include "crease/phys_assemble.h"
#include "crease/phys_sim.h"
#include "crease/phys_solve.h"
#include "crease/topology.h"

/* Air drag (sim.c): c/(2h) m |x - x_t|^2 per vertex, coef = c / h. */
typedef struct sim_drag {
    double coef;           /* 1/s^2 */
    const double *mass;    /* (V) kg */
    const double *x_start; /* (V,3) m, the substep's start */
} sim_drag;
void cr_sim_drag_term(const sim_drag *dr, int32_t nv, cr_energy_term *out);

/* What one substep's solver is asked (sim.c fills it, newton() or
 * cr_vbd_solve() reads it). */
typedef struct newton_opts {
    int max_iterations;
    double tol;         /* m: converged when the step's largest move is below */
    double rtol;        /* ... or below this fraction of the largest move since the start */
    double base_radius; /* m: query radius before the iterate's own motion */
    double max_step;    /* m: longest vertex move of one Newton step */
    double h;           /* s, the substep (0: a static solve) */
} newton_opts;

/* Vertex block descent (vbd.c): colouring and vertex-element incidences,
 * built once at create. */
typedef struct cr_vbd cr_vbd;
cr_status cr_vbd_create(const cr_sim *s, cr_vbd **out, cr_error *err);
void cr_vbd_destroy(cr_vbd *v);
int cr_vbd_colour_count(const cr_vbd *v);
/* Minimise the substep's objective from s->x in place, like sim.c's newton. */
cr_status cr_vbd_solve(cr_sim *s, const newton_opts *o, cr_error *err);
/* The paper's adaptive initial guess (Chen et al. 2024, sec. 3.6) into s->x. */
void cr_vbd_initial_guess(cr_sim *s, double h);
/* With self-contact, the guess in s->x within the step bound (vbd.c). */
cr_status cr_vbd_bound_guess(cr_sim *s, cr_error *err);

/* Self-contact pairs at x (sim.c): detection, the term's elements, and the
 * assembly (and Newton's Cholesky analysis when `newton`) rebuilt when the
 * pairs changed. No-op without self-contact. */
cr_status cr_sim_detect_self(cr_sim *s, const double *x, int newton, cr_error *err);

/* sim.c's evaluation (timed into the report) and collider query, for vbd.c. */
double cr_sim_eval(cr_sim *s, const double *x, double *grad, int hessian);
void cr_sim_query_collider(cr_sim *s, const double *x, double radius);
/* The same query for only the vertices whose linearisation may have gone
 * stale: moved more than move_tol since their last query and possibly within
 * the collision band now. The others keep theirs, which for a vertex outside
 * the band gives the same zero penalty as a new query. */
void cr_sim_requery_collider(cr_sim *s, const double *x, double radius, double move_tol);

struct cr_sim {
    cr_sim_def def; /* a copy; def.pinned and def.collider are not used after create */
    int32_t nv, nh; /* V vertices, H hinges */
    cr_topology *topo;

    cr_membrane *membrane;
    cr_bending *bending;
    cr_gravity *gravity;
    cr_inertia *inertia;
    cr_collision *collision; /* NULL without a collider */
    cr_self_contact *self;   /* NULL without self-contact */
    int t_self;              /* its term, -1 without */
    int32_t *self_prev;      /* (4 npair_prev) the pairs the assembly was built with */
    int32_t self_prev_n, self_prev_cap;
    cr_friction *friction; /* NULL without a collider or with friction 0 */
    cr_energy_term terms[CR_SIM_MAX_TERMS];
    int nterms, t_inertia, t_drag, t_friction; /* t_friction -1 without friction */
    sim_drag drag;
    double term_values[CR_SIM_MAX_TERMS]; /* J, of the last evaluation */
    cr_assembly *assembly;
    cr_cholesky *chol;                /* NULL with the VBD solver */
    cr_vbd *vbd;                      /* NULL with the Newton solver */
    struct cr_vbd_coarse *vbd_coarse; /* VBD's coarse correction, NULL when off */
    int64_t assembly_builds;          /* times s->assembly was made (the coarse map follows) */

    uint8_t *pinned;    /* (V) 1 = held */
    int32_t *pin_index; /* (npin) the pinned vertices in the order of def.pin_frames */
    int32_t npin;
    const double *mass; /* (V) kg, owned by gravity */

    /* State. */
    double *x, *v; /* (V,3) m, m/s */
    double *rest;  /* (H) rad: the bending term's rest angles (owned by bending) */
    int64_t frame;
    double pen_start; /* m, penetration left by the last substep (bounds the next query) */

    /* The frame's start, for backoff. */
    double *x_frame, *v_frame, *rest_frame, *a_frame;
    double *a_prev; /* (V,3) m/s^2, the last substep's acceleration (VBD's initial guess) */

    /* Scratch, allocated once. */
    double *x_start, *x_pred, *grad, *dx, *xt; /* (V,3) */
    double *disp;                              /* (V,3) collider motion under contacts, m */
    double *theta;                             /* (H) rad */
    float *xf, *dist, *normal;                 /* (V,3), (V), (V,3) */
    float *smooth; /* (V,3) collider's interpolated normal, step start */
    /* Each vertex's last collider query (cr_sim_requery_collider): where,
     * and a lower bound on its signed distance then, m; the selection and
     * its results, compact. */
    double *qx, *qlow;      /* (V,3), (V) */
    int32_t *qsel;          /* (V) */
    float *qdist, *qnormal; /* (V), (V,3) */

    /* Collider. */
    cr_bvh *bvh;             /* NULL without a collider */
    int32_t ncv;             /* Vc */
    float *collider_rest;    /* (Vc,3) positions of a static collider (or frame 0) */
    float *cpos, *cpos_prev; /* (Vc,3) poses at the substep's end and start */

    cr_sim_report *rep;           /* report being filled */
    cr_sim_report scratch_report; /* target of timers outside a step */
    char why[160];                /* the last substep failure */
};

#endif
