/* vbd_internal.h: vertex block descent's private pieces (vbd.c, colour.c).
 * Private to src/phys. */
#ifndef CREASE_PHYS_VBD_INTERNAL_H
#define CREASE_PHYS_VBD_INTERNAL_H

#include "phys/sim_internal.h"

/* Vertex i's share of element `elem` of term `term`: it is the element's
 * vertex number `local`. */
typedef struct cr_vbd_incidence {
    int32_t elem;
    int16_t term;
    int16_t local;
} cr_vbd_incidence;

/* Greedy colouring (colour.c) of nv vertices whose incidences into the
 * multi-vertex terms are inc[inc_off[i] .. inc_off[i+1]): colour (nv) gets
 * 0..ncolours-1, or -1 where skip[i] (skip may be NULL). */
cr_status cr_vbd_colour(int32_t nv, const int64_t *inc_off, const cr_vbd_incidence *inc,
                        const cr_energy_term *terms, const uint8_t *skip, int32_t *colour,
                        int *ncolours, cr_error *err);

/* The coarse-level correction (vbd_coarse.c): aggregates of a vertex and
 * its free neighbours within `rings` rings of the Hessian's pattern, made
 * once from s->assembly (before any self-contact pair). */
typedef struct cr_vbd_coarse cr_vbd_coarse;
cr_status cr_vbd_coarse_create(const cr_sim *s, int rings, cr_vbd_coarse **out, cr_error *err);
void cr_vbd_coarse_destroy(cr_vbd_coarse *c);
int32_t cr_vbd_coarse_count(const cr_vbd_coarse *c);
/* The rotation blocks' relative diagonal shift (default 1e-6; 0 for the
 * tests that check the coarse system exactly, where no block is singular). */
void cr_vbd_coarse_set_rotation_shift(cr_vbd_coarse *c, double shift);
/* Each vertex's aggregate (V), -1 for pinned vertices. */
const int32_t *cr_vbd_coarse_aggregates(const cr_vbd_coarse *c);
/* P^T H P factorised, H the assembly's Hessian as the caller's last
 * cr_sim_eval(..., hessian 1) left it, P the aggregates' rigid motions about
 * their centroids at s->x (kept until the next factorisation). *ok = 0 when
 * there is none (no aggregate, or P^T H P indefinite after the Cholesky's
 * shifts); the directions then give none either. */
cr_status cr_vbd_coarse_factor(cr_sim *s, cr_vbd_coarse *c, int *ok, cr_error *err);
/* The coarse direction dir (V,3) = P (P^T H P)^-1 (-P^T grad) with the last
 * factorisation, grad the objective's gradient (pinned rows zero). */
cr_status cr_vbd_coarse_direction(cr_sim *s, cr_vbd_coarse *c, const double *grad, double *dir,
                                  int *ok, cr_error *err);

#endif
