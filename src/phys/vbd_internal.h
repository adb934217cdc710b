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

#endif
