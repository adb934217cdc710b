/* crease/phys_sim.h: the reference cloth simulator.
 *
 * Implicit Euler posed as the minimisation of an incremental potential
 * (Martin et al. 2011, "Example-based elastic materials"; Gast et al. 2015,
 * "Optimization integrator for large time steps"; IPC, Li et al. 2020):
 *
 *     x_{t+h} = argmin_x  1/(2h^2) (x - x_pred)^T M (x - x_pred) + P(x),
 *     x_pred = x_t + h v_t,      v_{t+h} = (x_{t+h} - x_t) / h,
 *
 * with P the membrane, bending, gravity, collision and friction energies of
 * phys_energies.h plus a linear air drag c/(2h) m |x - x_t|^2. Each substep
 * runs Newton's method: the assembled, PSD-projected Hessian is factorised by
 * CHOLMOD, the step is taken with a backtracking Armijo line search on the
 * incremental potential, and the collider's signed distances are queried
 * again at every Newton iterate. A quasi-static mode drops the inertia and
 * minimises P to equilibrium.
 *
 * A second solver for the same potential, vertex block descent (def.solver =
 * CR_SIM_SOLVER_VBD; Chen et al. 2024; src/phys/vbd.c): per-vertex 3x3
 * Newton steps from the element kernels' gradients and Hessian blocks,
 * Gauss-Seidel over a vertex colouring, no factorisation. It steps dynamic
 * substeps; static solves use Newton with either solver. Deterministic at
 * any thread count. Its accuracy and limits: docs/physics.md.
 *
 *   cr_sim_def def = cr_sim_default_def();
 *   CR_TRY(cr_material_preset("cotton", &def.material, err));
 *   def.collider = sphere;                           borrowed during create
 *   cr_sim *sim = NULL;
 *   CR_TRY(cr_sim_create(&def, garment, &sim, err));
 *   for (int f = 0; f < frames; f++) {
 *       cr_sim_report rep;
 *       CR_TRY(cr_sim_step(sim, &rep, err));         one frame of def.dt
 *       ... cr_sim_positions(sim) ...
 *   }
 *   cr_sim_destroy(sim);
 *
 * Robust unattended: a substep fails on a non-finite value, a line search
 * that finds no decrease away from a minimum, a vertex faster than
 * def.max_speed or deeper than def.max_penetration inside the collider. A
 * failed frame is restored to its start and retried with twice the substeps,
 * up to def.max_backoff times; if it still fails, cr_sim_step returns
 * CR_ERR_DIVERGED naming the frame and what failed, and the state stays the
 * last good one. Positions never hold a NaN.
 *
 * Cloth self-contact (def.self_contact; src/phys/self_contact.c): the
 * cloth's vertex-triangle and edge-edge pairs closer than a thickness,
 * found by a BVH over the cloth once per substep (VBD: again where its
 * conservative step bound was reached), as one more energy term in both
 * solvers. docs/physics.md, "Self-contact".
 *
 * After each substep, a vertex left inside the collider (signed distance
 * < 0) is projected onto its surface along the normal and its inward normal
 * velocity is removed; the report says how deep the deepest vertex was
 * before that (max_penetration_m) and how many moved.
 *
 * Plasticity (Narain, Pfaff & O'Brien 2013; EPNet eq. 3-5) runs after every
 * substep: per hinge, with d = theta - theta_rest, |d| > yield moves
 * theta_rest toward theta by gain (|d| - yield). Rest angles persist and are
 * saved with the state.
 *
 * Determinism: a frame is a pure function of (positions, velocities, rest
 * angles, frame, penetration left by the last substep, def), and the
 * assembly sums in a fixed order whatever the thread count, so the same
 * build and thread count give the same state bit for bit, and
 * cr_sim_state_save/load resume bit-identically. (Across thread counts the
 * BLAS inside CHOLMOD and LAPACK's eigensolver may round differently.)
 * Units: m, kg, s, rad; positions and velocities double.
 * Thread safety: one caller per cr_sim; it parallelises internally.
 */
#ifndef CREASE_PHYS_SIM_H
#define CREASE_PHYS_SIM_H

#include "crease/mesh.h"
#include "crease/phys_energies.h"
#include "crease/phys_material.h"

#ifdef __cplusplus
extern "C" {
#endif

/* -------------------------------------------------------- plasticity -- */

typedef enum cr_plastic_rule {
    CR_PLASTIC_LINEAR = 0, /* Narain 2013: theta_rest += gain sign(d) max(|d| - y, 0) */
    CR_PLASTIC_SMOOTH      /* EPNet eq. 5: ... gain sign(d) s(50 (|d| - y)) max(|d| - y, 0),
                              s the logistic sigmoid */
} cr_plastic_rule;

/* Update rest angles theta_rest (H), rad, in place from current angles theta
 * (H), rad. Returns how many hinges yielded. */
int32_t cr_plasticity_update(const double *theta, double *theta_rest, int32_t nh, double yield,
                             double gain, cr_plastic_rule rule);

/* ------------------------------------------------------------ simulator -- */

enum { CR_SIM_MAX_TERMS = 8 };

/* Called after every accepted Newton step (may be NULL): iteration (0-based
 * within the solve), the objective after the step, J, the gradient's largest
 * free-vertex norm before it, N, and the step's largest vertex move, m. */
typedef void (*cr_sim_iteration_fn)(void *ctx, int iteration, double energy, double grad_norm,
                                    double step);

#define CR_SIM_DEF_COOKIE 0x53494d31u

/* The solver of each substep's incremental potential. */
typedef enum cr_sim_solver {
    CR_SIM_SOLVER_NEWTON = 0, /* Newton + CHOLMOD with a line search: the converged reference */
    CR_SIM_SOLVER_VBD         /* vertex block descent (Chen et al. 2024): per-vertex 3x3 Newton
                                 steps, Gauss-Seidel over a vertex colouring; no factorisation */
} cr_sim_solver;

/* Name "newton" or "vbd" to a solver; -1 for anything else. */
int cr_sim_solver_parse(const char *name);
const char *cr_sim_solver_name(cr_sim_solver s);

typedef struct cr_sim_def {
    double dt;                  /* s, one frame (default 1/30) */
    int substeps;               /* implicit Euler steps per frame (default 1: stable in every
                                   test scene; a second halves the damping and doubles the cost) */
    int max_backoff;            /* times a failed frame is retried with twice the substeps (3) */
    double max_collider_step;   /* m: a frame whose collider moves further than this (largest
                                   vertex displacement) runs more substeps, ceil(motion / this),
                                   at most 16 (default 0: off). A running body's hands travel
                                   34 cm a frame; at one substep a long-sleeve top on it
                                   stretched to 100x its membrane energy at rest */
    int newton_max_iterations;  /* per substep (default 8); a capped substep keeps its last
                                   iterate, which every line search made better. Where cloth
                                   buckles Newton converges linearly (a swinging 5k tube: 0.3 mm
                                   per iteration after the third); a cap of 4 halves the cost
                                   but damps bending: a released elastic fold sprang back to
                                   24 degrees instead of below 5 in 3 s */
    double newton_tol;          /* converged when the Newton step's largest vertex move over h is
                                   below this, m/s (default 1e-3), */
    double newton_rtol;         /* ... or below this fraction of the largest move since the
                                   substep's start (default 1e-2: 1% of the velocity) */
    int static_max_iterations;  /* cr_sim_solve_static and quasi-static frames (default 500) */
    double static_tol;          /* static convergence: largest vertex move of a step, m (1e-6) */
    double static_max_step;     /* static Newton steps are shortened to this largest vertex move, m:
                                   a free mode (rotation about a pin line) has no curvature to
                                   bound the step (default 0.05) */
    int line_search_max;        /* step halvings before the line search gives up (default 30) */
    double armijo;              /* sufficient-decrease constant (default 1e-4) */
    int quasi_static;           /* 1: cr_sim_step drops inertia and solves each substep to
                                   equilibrium (velocities stay 0) */
    double gravity[3];          /* m/s^2 (default 0, -9.81, 0) */
    double damping;             /* linear air drag f = -damping m v, 1/s (default 0.5) */
    cr_material material;       /* required: set with cr_material_preset (checked) */
    int membrane_rest_from_uv;  /* 1: rest shape from the garment's UVs times uv_scale */
    float uv_scale;             /* m per UV unit (default 1) */
    int bending_rest_from_mesh; /* 1: initial rest angles from the garment mesh (default 1) */
    cr_hessian_mode bending_hessian; /* default CR_HESSIAN_GAUSS_NEWTON: no eigensolve per hinge */
    const int32_t *pinned; /* (npinned) vertices held at their initial positions, or moved by
                              pin_frames; read only during create */
    int32_t npinned;
    const float *pin_frames;      /* optional (T, npinned, 3) positions of the pinned vertices per
                                     frame, in the order of `pinned`, m: frame f of the run moves
                                     them from frames[f] to frames[f+1] (held at the last), e.g. a
                                     waistband skinned to the body; borrowed for the simulator's
                                     life */
    int32_t pin_nframes;          /* T */
    const cr_mesh *collider;      /* optional: a closed, outward-oriented mesh (body or object),
                                     copied into a BVH; read only during create */
    const float *collider_frames; /* optional (T, Vc, 3) collider positions per frame, m; frame
                                     f of the run goes from frames[f] to frames[f+1] (held at the
                                     last); borrowed for the simulator's life */
    int32_t collider_nframes;     /* T */
    double friction_eps;          /* m of slip per step below which friction is static (1e-4);
                                     friction acts when material.friction > 0 and a collider */
    int plasticity;               /* 1: update rest angles after every substep */
    cr_plastic_rule plastic_rule;
    double max_speed;           /* m/s: a faster vertex means the substep diverged (default 50) */
    double max_penetration;     /* m: a vertex deeper inside the collider means the substep
                                   diverged (default 0.05) */
    cr_sim_solver solver;       /* default CR_SIM_SOLVER_NEWTON; VBD steps dynamic substeps, static
                                   solves (cr_sim_solve_static, quasi_static) use Newton always */
    int vbd_iterations;         /* VBD sweeps per substep at most (default 30); stops earlier when
                                   a sweep's largest vertex move is below vbd_tol h */
    double vbd_tol;             /* m/s: VBD's stopping tolerance (default 0: newton_tol's). A
                                   sweep's move understates its error, which Gauss-Seidel
                                   shrinks by a factor near 1 a sweep: with the coarse
                                   correction, 1e-5 and 100 sweeps came within 2 mm of
                                   converged Newton on the 10k tube (docs/physics.md) */
    double vbd_chebyshev;       /* rho of the Chebyshev acceleration, [0, 1) (default 0.9; 0: off);
                                   an extrapolation that raises the objective is dropped */
    int vbd_hessian_every;      /* VBD re-evaluates the elastic terms' per-vertex Hessian blocks
                                   every this many sweeps, gradients every sweep (default 1: the
                                   vertex blocks are cheap, and a stale block overshoots) */
    double vbd_damping;         /* k_d, s: VBD's Rayleigh stiffness damping (default 0; it is not
                                   in Newton's potential, so it moves the solution) */
    double vbd_collision_scale; /* VBD's collider penalty is this many times the material's
                                   collision_stiffness (>= 1; default 10). Gauss-Seidel leaves
                                   an impact's load on the first vertices in contact (100 N
                                   where converged Newton spreads 10), which the material's
                                   penalty let sink 4 mm; 10x keeps them in the thickness
                                   band (docs/physics.md). Friction's normal force follows. */
    double vbd_requery_move;    /* before each sweep after the first, VBD queries the collider
                                   again only for the vertices that moved more than this
                                   fraction of collision_thickness since their last query and
                                   may be inside the thickness (default 0.05); 0: every vertex,
                                   every sweep (a quarter of a sweep on the sphere drop) */
    int vbd_coarse_every;       /* VBD's coarse-level correction every this many sweeps (0: off):
                                   one Newton step on aggregates of vertices, which removes the
                                   smooth error the sweeps hardly touch (vbd_coarse.c,
                                   docs/physics.md) */
    int vbd_coarse_rings;       /* an aggregate is a vertex and its free neighbours within this
                                   many rings, 1..8 (default 2: about 19 vertices of a grid) */
    int vbd_coarse_refresh;     /* the coarse matrix is evaluated and factorised again every this
                                   many corrections, and at each substep's first (default 1);
                                   the others reuse it with a fresh gradient, which saves the
                                   Hessian's evaluation */
    int self_contact;           /* 1: cloth self-contact, vertex-triangle and edge-edge pairs
                                   (self_contact.c; docs/physics.md, "Self-contact";
                                   default 0) */
    double self_contact_thickness;    /* m: pairs closer than this are pushed apart (default 4e-3:
                                         two layers of a 1-2 mm fabric with room; under the edge
                                         length of a 10k garment, so mesh neighbours are no
                                         pairs) */
    cr_sim_iteration_fn on_iteration; /* Newton steps, or VBD sweeps (energy after the sweep) */
    void *on_iteration_ctx;
    uint32_t cookie;
} cr_sim_def;

cr_sim_def cr_sim_default_def(void);

typedef struct cr_sim_report {
    int64_t frame; /* frames completed after this call */
    int nterms;
    const char *term_name[CR_SIM_MAX_TERMS]; /* "inertia", "membrane", ... */
    double term_energy[CR_SIM_MAX_TERMS];    /* J, at the end of the last substep */
    double kinetic_energy;                   /* J */
    double max_penetration_m; /* deepest vertex inside the collider before projection, m */
    int32_t projected;        /* vertex projections out of the collider, summed over substeps */
    int32_t contacts;         /* vertices within the collision thickness at the end */
    int32_t yielded;          /* hinge updates by plasticity, summed over substeps */
    int newton_iterations;    /* summed over substeps */
    int newton_capped;        /* substeps that stopped at the iteration limit */
    int factorisations;       /* Cholesky factorisations, shifted retries included */
    int substeps;             /* substeps of the successful attempt */
    int backoffs;             /* failed attempts before it */
    double max_shift;         /* largest diagonal shift the factorisations needed, N/m */
    int diverged;             /* 1 when the frame failed for good */
    char failure[200];        /* the last failure (of a backoff or the final one), or "" */
    double seconds;           /* wall time of the call */
    double seconds_assembly;  /* energy, gradient and Hessian evaluations (line search included) */
    double seconds_factor;    /* CHOLMOD numeric factorisations */
    double seconds_solve;     /* triangular solves */
    double seconds_collision; /* BVH refits and signed-distance queries */
    int vbd_retries;          /* VBD sweeps whose objective rose, run again with line searches */
    int64_t vbd_requeries;    /* vertex collider queries of VBD's sweeps after the first */
    int vbd_coarse_steps;     /* VBD coarse corrections taken (Armijo accepted), summed */
    int vbd_coarse_rejected;  /* ... and tried but not taken */
    double seconds_self_contact;  /* self-contact pair finding and the assembly rebuilt for it */
    int32_t self_contact_pairs;   /* pairs of the last detection */
    int self_contact_detections;  /* detections, summed over substeps (VBD: once, and again
                                     after a sweep where a vertex reached its step bound) */
    int32_t self_contact_bounded; /* VBD vertex moves cut by the step bound, summed */
} cr_sim_report;

typedef struct cr_sim cr_sim;

/* Build a simulator for `garment` (a manifold triangle mesh; its positions are
 * the initial state, velocities zero). Fails with CR_ERR_INVALID naming a bad
 * def field, CR_ERR_TOPOLOGY for a non-manifold garment, CR_ERR_RANGE for a
 * pinned index out of range. The caller destroys *out. */
cr_status cr_sim_create(const cr_sim_def *def, const cr_mesh *garment, cr_sim **out, cr_error *err);
void cr_sim_destroy(cr_sim *s);

/* Advance one frame (def.dt). report may be NULL. On CR_ERR_DIVERGED the
 * state is the frame's start. */
cr_status cr_sim_step(cr_sim *s, cr_sim_report *report, cr_error *err);

/* Minimise the potential (no inertia) at the collider's current pose to
 * equilibrium; velocities become 0, rest angles are not changed, the frame
 * counter does not move. CR_ERR_DIVERGED when Newton fails (state restored). */
cr_status cr_sim_solve_static(cr_sim *s, cr_sim_report *report, cr_error *err);

int32_t cr_sim_vertex_count(const cr_sim *s);
int32_t cr_sim_hinge_count(const cr_sim *s);
int64_t cr_sim_frame(const cr_sim *s);
const double *cr_sim_positions(const cr_sim *s);   /* (V,3) m, owned by s */
const double *cr_sim_velocities(const cr_sim *s);  /* (V,3) m/s, owned by s */
const double *cr_sim_rest_angles(const cr_sim *s); /* (H) rad, owned by s */
const double *cr_sim_masses(const cr_sim *s);      /* (V) kg, owned by s */
/* Positions as float (V,3) into out, e.g. for a PC2 frame or a render. */
void cr_sim_positions_f(const cr_sim *s, float *out);
/* 64-bit FNV-1a of positions, velocities, rest angles and frame (bit exact). */
uint64_t cr_sim_state_hash(const cr_sim *s);

/* State file: positions, velocities, rest angles and frame, bit exact, in a
 * small checked binary format (docs/physics.md), written atomically. Loading
 * needs a simulator built for the same mesh (vertex and hinge counts match,
 * CR_ERR_SHAPE otherwise; CR_ERR_PARSE for a damaged file). */
cr_status cr_sim_state_save(const cr_sim *s, const char *path, cr_error *err);
cr_status cr_sim_state_load(cr_sim *s, const char *path, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
