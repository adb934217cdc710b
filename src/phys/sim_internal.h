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

struct cr_sim {
    cr_sim_def def; /* a copy; def.pinned and def.collider are not used after create */
    int32_t nv, nh; /* V vertices, H hinges */
    cr_topology *topo;

    cr_membrane *membrane;
    cr_bending *bending;
    cr_gravity *gravity;
    cr_inertia *inertia;
    cr_collision *collision; /* NULL without a collider */
    cr_friction *friction;   /* NULL without a collider or with friction 0 */
    cr_energy_term terms[CR_SIM_MAX_TERMS];
    int nterms, t_inertia, t_drag, t_friction; /* t_friction -1 without friction */
    sim_drag drag;
    double term_values[CR_SIM_MAX_TERMS]; /* J, of the last evaluation */
    cr_assembly *assembly;
    cr_cholesky *chol;

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
    double *x_frame, *v_frame, *rest_frame;

    /* Scratch, allocated once. */
    double *x_start, *x_pred, *grad, *dx, *xt; /* (V,3) */
    double *disp;                              /* (V,3) collider motion under contacts, m */
    double *theta;                             /* (H) rad */
    float *xf, *dist, *normal;                 /* (V,3), (V), (V,3) */

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
