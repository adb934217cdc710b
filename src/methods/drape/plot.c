/* plot.c: the drape method's loss curves as a PNG: the non-negative terms
 * (strain, bend, collision) on a log axis in the upper panel, gravity and
 * the potential (strain + bend + gravity; both may be negative: the height
 * zero is arbitrary) on a linear axis in the lower one, against epochs, with
 * tick labels and a legend in the bitmap font of text.c. The collision
 * penalty stays out of the lower panel: its spikes (a contact jittering into
 * the eps band) would flatten every other curve there. Values are the mean
 * weighted terms per fixed evaluation structure (loss.jsonl has them all).
 *
 * Leaves out: anti-aliased lines, axis titles beyond the legend.
 */
#include "drape_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum {
    PLOT_W = 960,
    PLOT_H = 720,
    MARGIN_L = 110,
    MARGIN_R = 20,
    MARGIN_T = 20,
    PANEL_GAP = 50,
    MARGIN_B = 50,
    TEXT_SCALE = 2
};

static const uint8_t BLACK[3] = {0, 0, 0}, GREY[3] = {200, 200, 200}, DARK[3] = {90, 90, 90};
static const uint8_t COLORS[5][3] = {
    {31, 119, 180}, /* strain */
    {255, 127, 14}, /* bend */
    {44, 160, 44},  /* gravity */
    {214, 39, 40},  /* collision */
    {0, 0, 0},      /* potential */
};
static const char *const NAMES[5] = {"strain", "bend", "gravity", "collision", "potential"};

typedef struct panel {
    int x0, y0, x1, y1; /* pixel box, y0 at the top */
    double xmin, xmax;  /* epochs */
    double ymin, ymax;  /* data (log10 of data in a log panel) */
    int log;
} panel;

static void put(cr_image *img, int x, int y, const uint8_t c[3]) {
    if (x < 0 || y < 0 || x >= img->width || y >= img->height) return;
    memcpy(&img->rgb[3 * ((size_t)y * img->width + x)], c, 3);
}

static void hline(cr_image *img, int x0, int x1, int y, const uint8_t c[3]) {
    for (int x = x0; x <= x1; x++)
        put(img, x, y, c);
}

static void vline(cr_image *img, int x, int y0, int y1, const uint8_t c[3]) {
    for (int y = y0; y <= y1; y++)
        put(img, x, y, c);
}

/* Two pixels wide, clipped to the panel (Bresenham). */
static void line(cr_image *img, const panel *p, int x0, int y0, int x1, int y1,
                 const uint8_t c[3]) {
    int dx = x1 > x0 ? x1 - x0 : x0 - x1, dy = y1 > y0 ? y0 - y1 : y1 - y0;
    int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1, e = dx + dy;
    for (int guard = 0; guard < 4 * (PLOT_W + PLOT_H); guard++) {
        for (int k = 0; k < 4; k++) {
            int x = x0 + (k & 1), y = y0 + (k >> 1);
            if (x >= p->x0 && x <= p->x1 && y >= p->y0 && y <= p->y1) put(img, x, y, c);
        }
        if (x0 == x1 && y0 == y1) break;
        int e2 = 2 * e;
        if (e2 >= dy) e += dy, x0 += sx;
        if (e2 <= dx) e += dx, y0 += sy;
    }
}

static int px(const panel *p, double x) {
    double t = p->xmax > p->xmin ? (x - p->xmin) / (p->xmax - p->xmin) : 0.5;
    return p->x0 + (int)lround(t * (p->x1 - p->x0));
}

static int py(const panel *p, double y) {
    double t = p->ymax > p->ymin ? (y - p->ymin) / (p->ymax - p->ymin) : 0.5;
    return p->y1 - (int)lround(t * (p->y1 - p->y0));
}

static double term(const drape_log_row *r, int k) {
    const double v[5] = {r->eval.strain, r->eval.bend, r->eval.gravity, r->eval.collision,
                         r->eval.strain + r->eval.bend + r->eval.gravity};
    return v[k];
}

/* Series k of the rows as connected points; non-positive values in a log
 * panel break the line. */
static void series(cr_image *img, const panel *p, const drape_log_row *rows, int n, int k) {
    int have = 0, lx = 0, ly = 0;
    for (int i = 0; i < n; i++) {
        double v = term(&rows[i], k);
        if (p->log) {
            if (!(v > 0.0)) {
                have = 0;
                continue;
            }
            v = log10(v);
        }
        if (!isfinite(v)) {
            have = 0;
            continue;
        }
        int x = px(p, rows[i].epoch), y = py(p, v);
        if (have)
            line(img, p, lx, ly, x, y, COLORS[k]);
        else
            line(img, p, x, y, x, y, COLORS[k]);
        lx = x, ly = y, have = 1;
    }
}

static void frame(cr_image *img, const panel *p) {
    hline(img, p->x0, p->x1, p->y0, DARK), hline(img, p->x0, p->x1, p->y1, DARK);
    vline(img, p->x0, p->y0, p->y1, DARK), vline(img, p->x1, p->y0, p->y1, DARK);
}

/* A round step giving about `n` ticks over [lo, hi]. */
static double nice_step(double lo, double hi, int n) {
    double raw = (hi - lo) / n, mag = pow(10.0, floor(log10(raw))), f = raw / mag;
    return (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0) * mag;
}

static void x_ticks(cr_image *img, const panel *p, int labels) {
    double step = nice_step(p->xmin, p->xmax, 6);
    for (double x = ceil(p->xmin / step) * step; x <= p->xmax + 1e-9; x += step) {
        int X = px(p, x);
        vline(img, X, p->y0 + 1, p->y1 - 1, GREY);
        if (!labels) continue;
        char s[32];
        snprintf(s, sizeof s, "%.0f", x);
        cr_drape_text(img, X - cr_drape_text_width(s, TEXT_SCALE) / 2, p->y1 + 8, TEXT_SCALE, s,
                      BLACK);
    }
}

static void y_ticks(cr_image *img, const panel *p) {
    if (p->log) {
        for (int d = (int)ceil(p->ymin); d <= (int)floor(p->ymax); d++) {
            int Y = py(p, d);
            hline(img, p->x0 + 1, p->x1 - 1, Y, GREY);
            char s[16];
            snprintf(s, sizeof s, "1e%d", d);
            cr_drape_text(img, p->x0 - 8 - cr_drape_text_width(s, TEXT_SCALE), Y - 7, TEXT_SCALE, s,
                          BLACK);
        }
        return;
    }
    double step = nice_step(p->ymin, p->ymax, 4);
    for (double y = ceil(p->ymin / step) * step; y <= p->ymax + 1e-12 * fabs(p->ymax); y += step) {
        int Y = py(p, y);
        hline(img, p->x0 + 1, p->x1 - 1, Y, GREY);
        char s[32];
        snprintf(s, sizeof s, "%.3g", fabs(y) < 1e-6 * step ? 0.0 : y);
        cr_drape_text(img, p->x0 - 8 - cr_drape_text_width(s, TEXT_SCALE), Y - 7, TEXT_SCALE, s,
                      BLACK);
    }
}

static void legend(cr_image *img, const panel *p, const int *ks, int n) {
    int y = p->y0 + 10;
    for (int i = 0; i < n; i++) {
        const char *s = NAMES[ks[i]];
        int x = p->x1 - 12 - cr_drape_text_width(s, TEXT_SCALE);
        for (int t = 0; t < 3; t++)
            hline(img, x - 34, x - 8, y + 6 + t, COLORS[ks[i]]);
        cr_drape_text(img, x, y, TEXT_SCALE, s, BLACK);
        y += 20;
    }
}

/* Data range of the given series over the rows (log10 in a log panel). */
static int range(const drape_log_row *rows, int n, const int *ks, int nk, int log, double *lo,
                 double *hi) {
    *lo = INFINITY, *hi = -INFINITY;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < nk; k++) {
            double v = term(&rows[i], ks[k]);
            if (log) v = v > 0.0 ? log10(v) : NAN;
            if (!isfinite(v)) continue;
            *lo = fmin(*lo, v), *hi = fmax(*hi, v);
        }
    if (!(*lo <= *hi)) return 0;
    if (log) {
        *lo = floor(*lo), *hi = ceil(*hi);
        if (*hi - *lo < 1.0) *hi = *lo + 1.0;
    } else {
        double pad = 0.05 * (*hi - *lo);
        if (pad <= 0.0) pad = fabs(*hi) > 0.0 ? 0.05 * fabs(*hi) : 1.0;
        *lo -= pad, *hi += pad;
    }
    return 1;
}

cr_status cr_drape_plot_losses(const drape_log_row *rows, int n, const char *path, cr_error *err) {
    cr_image img = {0};
    CR_TRY(cr_image_create(PLOT_W, PLOT_H, &img, err));
    memset(img.rgb, 255, (size_t)PLOT_W * PLOT_H * 3);
    int ph = (PLOT_H - MARGIN_T - PANEL_GAP - MARGIN_B) / 2;
    double xmax = n > 0 ? rows[n - 1].epoch : 1.0;
    panel top = {MARGIN_L, MARGIN_T, PLOT_W - MARGIN_R, MARGIN_T + ph, 0.0, xmax, 0, 1, 1};
    panel bot = {MARGIN_L,
                 MARGIN_T + ph + PANEL_GAP,
                 PLOT_W - MARGIN_R,
                 MARGIN_T + 2 * ph + PANEL_GAP,
                 0.0,
                 xmax,
                 0,
                 1,
                 0};
    const int log_terms[3] = {0, 1, 3}, lin_terms[2] = {2, 4};
    int have_top = range(rows, n, log_terms, 3, 1, &top.ymin, &top.ymax);
    int have_bot = range(rows, n, lin_terms, 2, 0, &bot.ymin, &bot.ymax);
    x_ticks(&img, &top, 0), x_ticks(&img, &bot, 1);
    if (have_top) y_ticks(&img, &top);
    if (have_bot) y_ticks(&img, &bot);
    for (int k = 0; have_top && k < 3; k++)
        series(&img, &top, rows, n, log_terms[k]);
    for (int k = 0; have_bot && k < 2; k++)
        series(&img, &bot, rows, n, lin_terms[k]);
    frame(&img, &top), frame(&img, &bot);
    legend(&img, &top, log_terms, 3), legend(&img, &bot, lin_terms, 2);
    const char *xl = "epoch";
    cr_drape_text(&img, (PLOT_W - cr_drape_text_width(xl, TEXT_SCALE)) / 2, PLOT_H - 20, TEXT_SCALE,
                  xl, BLACK);
    cr_status st = cr_image_write_png(&img, path, err);
    cr_image_free(&img);
    return st;
}
