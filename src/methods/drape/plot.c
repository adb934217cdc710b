/* plot.c: the drape method's loss curves as a PNG: the non-negative terms
 * (strain, bend, collision) on a log axis in the upper panel, gravity and
 * the potential (strain + bend + gravity; both may be negative: the height
 * zero is arbitrary) on a linear axis in the lower one, against epochs. The
 * collision penalty stays out of the lower panel: its spikes (a contact
 * jittering into the eps band) would flatten every other curve there.
 * Values are the mean weighted terms per fixed evaluation structure
 * (loss.jsonl has them all). The drawing is eval's line plot (eval/plot.c).
 *
 * Leaves out: anti-aliased lines, axis titles beyond the legend.
 */
#include "drape_internal.h"

#include "crease/eval.h"

#include <stdlib.h>
#include <string.h>

enum { PLOT_W = 960, PLOT_H = 720, TERMS = 5 };

static const uint8_t COLORS[TERMS][3] = {
    {31, 119, 180}, /* strain */
    {255, 127, 14}, /* bend */
    {44, 160, 44},  /* gravity */
    {214, 39, 40},  /* collision */
    {0, 0, 0},      /* potential */
};
static const char *const NAMES[TERMS] = {"strain", "bend", "gravity", "collision", "potential"};

static double term(const drape_log_row *r, int k) {
    const double v[TERMS] = {r->eval.strain, r->eval.bend, r->eval.gravity, r->eval.collision,
                             r->eval.strain + r->eval.bend + r->eval.gravity};
    return v[k];
}

cr_status cr_drape_plot_losses(const drape_log_row *rows, int n, const char *path, cr_error *err) {
    double *x = cr_malloc(((size_t)n + 1) * (TERMS + 1) * sizeof(double), err);
    if (!x) return CR_ERR_MEMORY;
    double *y = x + n + 1; /* (TERMS, n) */
    for (int i = 0; i < n; i++) {
        x[i] = rows[i].epoch;
        for (int k = 0; k < TERMS; k++)
            y[(size_t)k * n + i] = term(&rows[i], k);
    }
    cr_plot_series s[TERMS];
    for (int k = 0; k < TERMS; k++) {
        s[k] = (cr_plot_series){.name = NAMES[k], .x = x, .y = y + (size_t)k * n, .n = n};
        memcpy(s[k].rgb, COLORS[k], 3);
    }
    /* upper: strain, bend, collision (log); lower: gravity, potential (linear) */
    cr_plot_series upper[3] = {s[0], s[1], s[3]}, lower[2] = {s[2], s[4]};
    cr_plot_panel panels[2] = {{upper, 3, 1}, {lower, 2, 0}};
    cr_image img = {0};
    cr_status st = cr_plot_lines(panels, 2, "epoch", NULL, PLOT_W, PLOT_H, &img, err);
    if (st == CR_OK) st = cr_image_write_png(&img, path, err);
    cr_image_free(&img);
    free(x);
    return st;
}
