/* colour.c: greedy vertex colouring for vertex block descent (vbd.c).
 *
 * Two vertices conflict when they share an element of some term of more than
 * one vertex (a triangle, a hinge: a hinge's wing tips conflict too). Each
 * vertex, in index order, takes the smallest colour none of its
 * already-coloured neighbours holds (Welsh-Powell without the degree sort:
 * the order is the mesh's, so the colouring is a pure function of the
 * elements). A cloth mesh of valence 6 needs 8 to 12 colours this way with
 * bending's wing-tip couplings, against 7 for triangles alone.
 *
 * Vertices with skip[i] != 0 (pinned) get colour -1 and no list entry.
 */
#include <stdlib.h>
#include <string.h>

#include "phys/vbd_internal.h"

cr_status cr_vbd_colour(int32_t nv, const int64_t *inc_off, const cr_vbd_incidence *inc,
                        const cr_energy_term *terms, const uint8_t *skip, int32_t *colour,
                        int *ncolours, cr_error *err) {
    /* Colours held by neighbours of the current vertex, stamped with it. */
    int cap = 64;
    int32_t *stamp = cr_malloc((size_t)cap * sizeof(int32_t), err);
    if (!stamp) return err ? err->status : CR_ERR_MEMORY;
    for (int c = 0; c < cap; c++)
        stamp[c] = -1;
    int used = 0;
    for (int32_t i = 0; i < nv; i++)
        colour[i] = -1;
    for (int32_t i = 0; i < nv; i++) {
        if (skip && skip[i]) continue;
        for (int64_t k = inc_off[i]; k < inc_off[i + 1]; k++) {
            const cr_energy_term *t = &terms[inc[k].term];
            const int32_t *ev = t->elem + (int64_t)t->nvert * inc[k].elem;
            for (int a = 0; a < t->nvert; a++) {
                int32_t j = ev[a];
                if (j != i && colour[j] >= 0) stamp[colour[j]] = i;
            }
        }
        int c = 0;
        while (c < cap && stamp[c] == i)
            c++;
        if (c == cap) {
            int32_t *grown = realloc(stamp, 2 * (size_t)cap * sizeof(int32_t));
            if (!grown) {
                free(stamp);
                return CR_FAIL(err, CR_ERR_MEMORY, "vbd: colouring needs more than %d colours",
                               cap);
            }
            stamp = grown;
            for (int q = cap; q < 2 * cap; q++)
                stamp[q] = -1;
            cap *= 2;
        }
        colour[i] = c;
        if (c + 1 > used) used = c + 1;
    }
    free(stamp);
    *ncolours = used;
    return CR_OK;
}
