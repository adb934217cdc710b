/* crease/phys_energies.h: the cloth energies, each a cr_energy_term.
 *
 * Every energy is a small struct built once from the rest mesh (its _create),
 * destroyed by its _destroy (NULL is a no-op), and exposed to the simulator,
 * the neural losses and the metrics through a cr_energy_term filled by its
 * _term: a per-element kernel that returns the element's value, gradient and
 * PSD-projected Hessian (phys_energy.h). The term borrows the struct: keep it
 * alive while the term is used. Formulas and sources: docs/physics.md.
 *
 *   energy     element   E per element                                        file
 *   membrane   triangle  A0 psi(F), F = Ds Dm^-1; StVK or Baraff-Witkin       membrane_stvk.c,
 * _bw.c bending    hinge     k_e/2 (theta - theta_rest)^2, k_e = k_b l^2/(4(A1+A2)) bending.c
 *   gravity    vertex    -m_i g . x_i                                         gravity.c
 *   inertia    vertex    m_i/(2 h^2) |x_i - xpred_i|^2                        inertia.c
 *   collision  vertex    k max(m_i - d_i(x), 0)^3, d linearised per iterate   collision.c
 *   friction   contact   mu lambda_i f0(|T_i^T (x_i - anchor_i)|), lagged      friction.c
 *   pin        vertex    k/2 |x_i - target_i|^2 over the pinned vertices          pin.c
 *   self_contact pair    -k eps (d-eps)^2 ln(d/eps) for d < eps, d = n . sum w_k x_k self_contact.c
 *
 * Threading: _create/_update/_set mutate and must not overlap a kernel call;
 * kernels are pure and may run on many threads at once.
 * Units: positions m, energies J, gradients N, Hessians N/m.
 */
#ifndef CREASE_PHYS_ENERGIES_H
#define CREASE_PHYS_ENERGIES_H

#include "crease/mesh.h"
#include "crease/phys_energy.h"
#include "crease/phys_material.h"
#include "crease/topology.h"

#ifdef __cplusplus
extern "C" {
#endif

/* How a kernel makes its local Hessian positive semi-definite. */
typedef enum cr_hessian_mode {
    CR_HESSIAN_PROJECTED = 0, /* exact Hessian, negative eigenvalues clamped to 0 (dsyev) */
    CR_HESSIAN_GAUSS_NEWTON   /* drop the curvature term: PSD by construction, no eigensolve */
} cr_hessian_mode;

/* ------------------------------------------------------------ membrane -- */

/* Triangles of the rest mesh with their rest shape: the 3-D rest positions
 * laid flat in each triangle's plane, or (use_uv_rest) the triangle's UVs
 * times uv_scale (m per UV unit; needs UVs). Stores per triangle Dm^-1 (2x2)
 * and the rest area A0. StVK or Baraff-Witkin by mat->membrane. Fails with
 * CR_ERR_TOPOLOGY naming the first triangle whose rest shape is degenerate. */
typedef struct cr_membrane cr_membrane;
cr_status cr_membrane_create(const cr_mesh *rest, int use_uv_rest, float uv_scale,
                             const cr_material *mat, cr_membrane **out, cr_error *err);
void cr_membrane_destroy(cr_membrane *e);
/* Default CR_HESSIAN_PROJECTED: the 6x6 Hessian in F is eigen-clamped (split
 * into a 4x4 in-plane and a 2x2 normal block), which makes the 9x9 one PSD
 * (it is A^T H_F A with A of full row rank); skipped for StVK under tension,
 * where it is PSD already. CR_HESSIAN_GAUSS_NEWTON drops the stress term. */
void cr_membrane_set_hessian(cr_membrane *e, cr_hessian_mode mode);
const double *cr_membrane_rest_areas(const cr_membrane *e); /* (F) m^2 */
/* (F,4) Dm^-1 per triangle, row-major 2x2, 1/m: w_u, w_v = Ds Dm^-1's columns. */
const double *cr_membrane_rest_dminv(const cr_membrane *e);
void cr_membrane_term(const cr_membrane *e, cr_energy_term *out);

/* The membrane's stretch or shear part alone (epnet's STE and SHE). For
 * Baraff-Witkin, the stretch condition A0 k_s/2 ((|w_u| - 1)^2 + (|w_v| - 1)^2)
 * or the shear A0 k_sh/2 (w_u . w_v)^2. For StVK, with the Green strain E:
 * stretch A0 (mu (E11^2 + E22^2) + lambda/2 (E11 + E22)^2), shear
 * A0 2 mu E12^2; the two sum to the full density. CR_MEMBRANE_ALL gives
 * cr_membrane_term's term. Each part has its own gradient and Hessian
 * (projected per cr_membrane_set_hessian). Term names "membrane",
 * "membrane_stretch", "membrane_shear". */
typedef enum cr_membrane_part {
    CR_MEMBRANE_ALL = 0,
    CR_MEMBRANE_STRETCH,
    CR_MEMBRANE_SHEAR
} cr_membrane_part;
void cr_membrane_term_part(const cr_membrane *e, cr_membrane_part part, cr_energy_term *out);

/* ------------------------------------------------------------- bending -- */

/* Interior hinges of `t` (built from `rest`) with per-hinge stiffness
 * k_e = k_b l^2 / (4 (A1 + A2)) from the rest edge length l and rest face
 * areas (HOOD/SNUG form) and rest angles theta_rest: the rest mesh's dihedral
 * angles when rest_angles_from_mesh, else 0 (flat). */
typedef struct cr_bending cr_bending;
cr_status cr_bending_create(const cr_mesh *rest, const cr_topology *t, const cr_material *mat,
                            int rest_angles_from_mesh, cr_bending **out, cr_error *err);
void cr_bending_destroy(cr_bending *b);
/* Default CR_HESSIAN_GAUSS_NEWTON: k_e grad(theta) grad(theta)^T only, PSD
 * by construction (ARCSim's choice; ~0.35 us per hinge). CR_HESSIAN_PROJECTED:
 * the exact Hessian eigen-clamped (the reference; a 9x9 dsyev per hinge,
 * ~8 us). */
void cr_bending_set_hessian(cr_bending *b, cr_hessian_mode mode);
int32_t cr_bending_count(const cr_bending *b);           /* H */
const int32_t *cr_bending_hinges(const cr_bending *b);   /* (H,4) x0, x1, x2, x3 as topology.h */
const double *cr_bending_stiffness(const cr_bending *b); /* (H) k_e, J/rad^2 */
/* (H) rad, mutable: the plasticity update writes here. Owned by b. */
double *cr_bending_rest_angles(cr_bending *b);
/* Current dihedral angles at positions x (V,3) into theta (H), rad, in double
 * with diffgeo.h's sign convention. */
void cr_bending_angles(const cr_bending *b, const double *x, double *theta);
void cr_bending_term(const cr_bending *b, cr_energy_term *out);
/* The kernel of hinge h with the rest angle theta_rest (rad) given instead of
 * b's own (a plastic rest angle predicted per sample): value, gradient g (12)
 * and Hessian H (12x12) as cr_energy_kernel, and g_rest (may be NULL) gets
 * dE/dtheta_rest = -k_e (theta - theta_rest), wrapped as the energy is. */
double cr_bending_kernel_rest(const cr_bending *b, int32_t h, double theta_rest, const double *xe,
                              double *g, double *H, double *g_rest);
/* Hinge h's angle residual wrap(theta(xe) - theta_rest) in (-pi, pi], rad,
 * wrapped as the energy is, and g (12, may be NULL) its gradient
 * d theta / d xe (zero on a degenerate hinge). */
double cr_bending_residual(const cr_bending *b, int32_t h, double theta_rest, const double *xe,
                           double *g);

/* ------------------------------------------------------------- gravity -- */

/* Lumped vertex masses m_i = density * (sum of the 3-D rest areas of the
 * faces around i) / 3, and the acceleration g (m/s^2, e.g. 0, -9.81, 0). */
typedef struct cr_gravity cr_gravity;
cr_status cr_gravity_create(const cr_mesh *rest, const cr_material *mat, const double g[3],
                            cr_gravity **out, cr_error *err);
void cr_gravity_destroy(cr_gravity *g);
const double *cr_gravity_masses(const cr_gravity *g); /* (V) kg */
void cr_gravity_term(const cr_gravity *g, cr_energy_term *out);

/* ------------------------------------------------------------- inertia -- */

/* E = 1/(2 h^2) sum_i m_i |x_i - xpred_i|^2: implicit Euler's inertia as an
 * incremental potential, xpred = x_t + h v_t. Copies the masses. */
typedef struct cr_inertia cr_inertia;
cr_status cr_inertia_create(const double *masses /* (V) kg */, int32_t nv, cr_inertia **out,
                            cr_error *err);
void cr_inertia_destroy(cr_inertia *in);
/* Copy the predicted positions (V,3) m, and the step h (s, > 0). */
void cr_inertia_set(cr_inertia *in, const double *x_pred, double h);
void cr_inertia_term(const cr_inertia *in, cr_energy_term *out);

/* ----------------------------------------------------------- collision -- */

/* Penalty against a collider, per cloth vertex: E_i = k max(m_i - d_i(x), 0)^3
 * (HOOD/SNUG's cubic), with d_i linearised around the iterate last given to
 * cr_collision_update: d_i(x) = dist_i + n_i . (x - x_i). Gradient
 * -3 k (m_i - d)^2 n_i, Hessian 6 k (m_i - d) n_i n_i^T (PSD). The threshold
 * m_i is the thickness eps, plus, once the cloth's edges are given, the
 * largest chord sag of vertex i's edges when cr_collision_update_margins
 * last ran, so that the thickness holds at the faces' centroids and not only
 * at their corners. */
typedef struct cr_collision cr_collision;
cr_status cr_collision_create(int32_t nv, const cr_material *mat, cr_collision **out,
                              cr_error *err);
void cr_collision_destroy(cr_collision *c);
/* The cloth's edges (E,2), copied, for cr_collision_update_margins. Refuses
 * a vertex out of range. */
cr_status cr_collision_set_edges(cr_collision *c, const int32_t *edge, int32_t ne, cr_error *err);
/* Each vertex's threshold m_i = eps + the largest chord sag of its edges
 * (eps without edges), held until the next call: from the positions and
 * distances of the last update and normal (V,3), the collider's smooth unit
 * normal (vertex normals interpolated) at each vertex's closest point, zero
 * where the query reached nothing. An edge's sag fades to zero over the last
 * millimetre before `reach` (m, the query's radius) at its farther end. */
void cr_collision_update_margins(cr_collision *c, const float *normal, double reach);
/* How far the middle of a face sags below its corners toward a curved
 * collider, m, from one edge's ends x_a, x_b and the collider's unit outward
 * normals n_a, n_b at their closest points: (n_b - n_a) . (x_b - x_a) / 6,
 * exact at the centroid of an equilateral triangle over a sphere (edge
 * length L, radius R: L^2 / (6 R)); 0 where the surface is flat or concave
 * between them, faded out as the normals part from 46 to 60 degrees (the
 * edge then spans two parts of the collider, not one curved surface; the
 * fade keeps the sag continuous). */
double cr_collision_chord_sag(const double xa[3], const double na[3], const double xb[3],
                              const double nb[3]);
/* Per Newton iterate: x (V,3) the cloth positions, m; dist (V) the signed
 * distance to the collider at x, m, negative inside; normal (V,3) the unit
 * outward normal at the closest point. A vertex the query did not reach may
 * carry any dist >= eps (e.g. the query's max_dist) and a zero normal. */
void cr_collision_update(cr_collision *c, const double *x, const float *dist, const float *normal);
/* The same for the n vertices idx only (each at its x_i, dist_i, normal_i);
 * the others keep their linearisation. */
void cr_collision_update_vertices(cr_collision *c, const double *x, const float *dist,
                                  const float *normal, const int32_t *idx, int32_t n);
void cr_collision_term(const cr_collision *c, cr_energy_term *out);
/* The penalty's k, J/m^3 (created with the material's collision_stiffness):
 * the simulator's VBD sweeps take a stiffer one (crease/phys_sim.h). */
void cr_collision_set_stiffness(cr_collision *c, double k);
/* max(0, -min_i dist_i) at the last update, m. */
double cr_collision_max_penetration(const cr_collision *c);
/* Vertex i's threshold m_i, m (eps before the first margins update). */
double cr_collision_margin(const cr_collision *c, int32_t i);
/* The largest threshold (eps before the first margins update), m. */
double cr_collision_max_margin(const cr_collision *c);
/* The penalty of one vertex at signed distance d (m) from the collider whose
 * distance gradient (the outward unit normal) is n: k max(eps - d, 0)^3, J,
 * with k (J/m^3) and eps (m) from the material; g (3) gets its gradient
 * -3 k (eps - d)^2 n and H (3x3) its Hessian 6 k (eps - d) n n^T, each when
 * not NULL. The kernel of cr_collision_term, for callers with their own
 * distances (the losses). */
double cr_collision_penalty(double k, double eps, double d, const double n[3], double *g,
                            double *H);
/* 1 when vertex i lay within its threshold (dist_i < m_i) at the last update;
 * then normal (3) gets n_i and *force the penalty's normal force magnitude
 * 3 k (m_i - dist_i)^2, N. Else 0 and nothing is written. */
int cr_collision_contact(const cr_collision *c, int32_t i, double normal[3], double *force);

/* -------------------------------------------------------- self-contact -- */

/* Cloth self-contact: vertex-triangle (VT) and edge-edge (EE) pairs of the
 * cloth found within a query radius of CR_SELF_CONTACT_QUERY times the
 * thickness eps, each with its unit normal n and weights w fixed at
 * detection (d(x) = n . sum_k w_k x_k is the pair's distance there, and
 * keeps its sign when the pair is pushed through), penalised below eps by
 * IPC's log barrier -k eps (d - eps)^2 ln(d / eps) (k (eps - d)^3, the body
 * collision's cubic, to leading order at eps; unbounded force as d -> 0),
 * continued below d = eps / 20 by its quadratic Taylor expansion, so it is
 * finite for any d (Newton has no step bound). Elements of
 * four vertices: VT (p, a, b, c), EE (a, b, c, d). Pairs sharing a vertex
 * are left out; a pair closer than the query radius at rest (the garment
 * given to create) is a pair only within half its rest distance, with a
 * thickness of a quarter of it. Gradient and Hessian are exact (d is linear) and
 * PSD. Found by a BVH over the cloth, refitted at every detection; see
 * self_contact.c. */
#define CR_SELF_CONTACT_QUERY 2.0
typedef struct cr_self_contact cr_self_contact;
/* Copies the garment's triangles and positions (the rest state) and the
 * topology's edges. thickness eps > 0, m; stiffness k >= 0, J/m^3
 * (CR_ERR_INVALID otherwise). */
cr_status cr_self_contact_create(const cr_mesh *garment, const cr_topology *topo, double thickness,
                                 double stiffness, cr_self_contact **out, cr_error *err);
void cr_self_contact_destroy(cr_self_contact *sc);
/* Find the pairs at x (V,3), m: refits the BVH, replaces the pair list
 * (refresh a term with cr_self_contact_term: elements move). The same list
 * at any thread count: VT pairs by vertex, then EE pairs by first edge. */
cr_status cr_self_contact_detect(cr_self_contact *sc, const double *x, cr_error *err);
void cr_self_contact_term(const cr_self_contact *sc, cr_energy_term *out);
/* Pairs of the last detection; *vertex_triangle (may be NULL) gets how many
 * of them are VT (they come first). */
int32_t cr_self_contact_pair_count(const cr_self_contact *sc, int32_t *vertex_triangle);
double cr_self_contact_radius(const cr_self_contact *sc); /* the query radius, m */
/* (V) per vertex, the distance of the nearest pair it is in at the last
 * detection, or the query radius when none, m: a vertex that moves less than
 * half of it from where it was detected cannot pass through another part of
 * the cloth (VBD's step bound). */
const double *cr_self_contact_nearest(const cr_self_contact *sc);
const double *cr_self_contact_detected_at(const cr_self_contact *sc); /* (V,3) m */
/* The pairs around each vertex: pairs[off[i] .. off[i+1]) hold 4 p + k for
 * vertex i being vertex k of pair p. */
void cr_self_contact_vertex_pairs(const cr_self_contact *sc, const int64_t **off,
                                  const int32_t **pairs);

/* ----------------------------------------------------------------- pin -- */

/* Soft pinning of chosen vertices to targets: E = k/2 sum_j |x_{v_j} - t_j|^2
 * over the n pinned vertices v_j, gradient k (x - t), Hessian k I (PSD).
 * k in N/m. Targets start at 0: set them with cr_pin_set_targets. Fails with
 * CR_ERR_RANGE naming the first vertex outside [0, nv), CR_ERR_INVALID for
 * a negative or non-finite k. Copies the indices. */
typedef struct cr_pin cr_pin;
cr_status cr_pin_create(int32_t nv, const int32_t *vertices, int32_t n, double stiffness,
                        cr_pin **out, cr_error *err);
void cr_pin_destroy(cr_pin *p);
/* Copy the targets (n,3), m, in the order of the vertices given to create. */
void cr_pin_set_targets(cr_pin *p, const double *targets);
int32_t cr_pin_count(const cr_pin *p);
void cr_pin_term(const cr_pin *p, cr_energy_term *out);

/* ------------------------------------------------------------ friction -- */

/* Lagged, smoothed Coulomb friction (IPC, Li et al. 2020, sec. 5): for each
 * vertex in contact at the step start, with normal force lambda_i and a
 * tangent basis T_i (3x2) of the contact normal frozen there, and the
 * tangential slip u_i = T_i^T (x_i - x_start_i - db_i) (db_i: the collider
 * surface's displacement under the vertex over the step),
 *     D_i = mu lambda_i f0(|u_i|),
 * f0 C^1 with f0'(y) = f1(y) = 2y/eps_v - y^2/eps_v^2 below eps_v and 1
 * above: static friction is a stiff spring over slips under eps_v, kinetic
 * friction a constant force mu lambda_i opposing the slip. PSD Hessian by
 * construction (no eigensolve). */
typedef struct cr_friction cr_friction;
/* eps_v: slip (m over one step) below which friction acts as static (IPC's
 * eps_v h; 1e-4 m is a fair start at h = 1/30 s). */
cr_status cr_friction_create(int32_t nv, const cr_material *mat, double eps_v, cr_friction **out,
                             cr_error *err);
void cr_friction_destroy(cr_friction *f);
/* Once per step, after cr_collision_update at the step-start positions:
 * freeze lambda_i and T_i from c's contacts, and the anchors x_start + db.
 * x_start (V,3) m; collider_disp (V,3) m, NULL for a static collider. */
void cr_friction_update(cr_friction *f, const cr_collision *c, const double *x_start,
                        const double *collider_disp);
int32_t cr_friction_contact_count(const cr_friction *f);
void cr_friction_term(const cr_friction *f, cr_energy_term *out);

/* ------------------------------------------- drape losses (paper 000) -- */

/* The four losses of Shu et al.'s implicit neural drape (../shared/papers/000,
 * sec. 3.3), as energies over element arrays that change every training step
 * (the sampled local structures): each _set copies the new elements into
 * storage that only grows, so a warm term allocates nothing per step.
 * Kernels take the element's vertices in double (the positions are float
 * tensors on the tape; the kernels compute in double, as drape did).
 *
 *   energy          element  E per element                                  file
 *   drape strain    edge     ((l - L)/L)^2, L the edge's rest length (eq. 19) drape_strain.c
 *   drape bend      hinge    |n_A - n_B|^2, unit face normals (eq. 22)        drape_bend.c
 *   drape gravity   vertex   m g y, height along +Y (eq. 24)                  drape_gravity.c
 *   drape collision vertex   min(s - eps, 0)^2, s the distance to an object   drape_collision.c
 *                            along its normal (eq. 26)
 *
 * Hessians: strain exact with its negative eigenvalue (compressed edge)
 * clamped, in closed form; bend and collision Gauss-Newton (2 J^T J of the
 * residual), PSD by construction; gravity zero. */

/* Edges (E,2) with per-edge rest lengths. */
typedef struct cr_drape_strain cr_drape_strain;
/* cap: edges to allocate for up front (0 is fine: _set grows). */
cr_status cr_drape_strain_create(int32_t cap, cr_drape_strain **out, cr_error *err);
void cr_drape_strain_destroy(cr_drape_strain *s);
/* Copy ne edges (E,2), each index in [0, nv), and their rest lengths (E) m,
 * positive and finite. CR_ERR_RANGE or CR_ERR_INVALID naming the first bad
 * edge (the term is then empty). */
cr_status cr_drape_strain_set(cr_drape_strain *s, const int32_t *edges, const float *rest,
                              int32_t ne, int32_t nv, cr_error *err);
void cr_drape_strain_term(const cr_drape_strain *s, cr_energy_term *out);

/* Hinges (H,4) in topology.h's layout: face A = (x0,x1,x2), face B =
 * (x1,x0,x3). A degenerate face gives 0 and no gradient. */
typedef struct cr_drape_bend cr_drape_bend;
cr_status cr_drape_bend_create(int32_t cap, cr_drape_bend **out, cr_error *err);
void cr_drape_bend_destroy(cr_drape_bend *b);
/* Copy nh hinges (H,4), each index in [0, nv); CR_ERR_RANGE naming the first bad one. */
cr_status cr_drape_bend_set(cr_drape_bend *b, const int32_t *hinges, int32_t nh, int32_t nv,
                            cr_error *err);
void cr_drape_bend_term(const cr_drape_bend *b, cr_energy_term *out);

/* m g y per point: one mass m (kg) for every point, g (m/s^2) the
 * acceleration's magnitude, height along +Y. Gradient (0, m g, 0). */
typedef struct cr_drape_gravity cr_drape_gravity;
cr_status cr_drape_gravity_create(double mass, double g, cr_drape_gravity **out, cr_error *err);
void cr_drape_gravity_destroy(cr_drape_gravity *g);
void cr_drape_gravity_set_count(cr_drape_gravity *g, int32_t n); /* points: element i is vertex i */
void cr_drape_gravity_term(const cr_drape_gravity *g, cr_energy_term *out);

/* min(s - eps, 0)^2 per point against a static object, s by: */
typedef enum cr_drape_collision_mode {
    CR_DRAPE_COLLIDE_VERTEX = 0, /* eq. 26: s = (x - v) . n_v, v the nearest object vertex, n_v
                                    its angle-weighted normal (v held fixed in the gradient) */
    CR_DRAPE_COLLIDE_SDF         /* s the signed distance to the surface (BVH, pseudo-normals) */
} cr_drape_collision_mode;
typedef struct cr_bvh cr_bvh; /* crease/bvh.h */
typedef struct cr_drape_collision cr_drape_collision;
/* object: the object's BVH (borrowed, must outlive the term, not refitted);
 * eps: the band, m. Points outside the object's bounding box grown by |eps|
 * skip the search (value 0). */
cr_status cr_drape_collision_create(const cr_bvh *object, cr_drape_collision_mode mode, double eps,
                                    cr_drape_collision **out, cr_error *err);
void cr_drape_collision_destroy(cr_drape_collision *c);
void cr_drape_collision_set_count(cr_drape_collision *c, int32_t n); /* points */
void cr_drape_collision_term(const cr_drape_collision *c, cr_energy_term *out);

#ifdef __cplusplus
}
#endif
#endif
