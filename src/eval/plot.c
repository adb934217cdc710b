/* plot.c: line plots and colour bars as images, for report PNGs (crease
 * eval's metric curves, the drape method's loss curves): panels stacked top
 * to bottom over one x range, linear or log10 y axes, grey grid at round
 * ticks, tick labels and legends in the bitmap font of text.c. Moved here
 * from methods/drape/plot.c, which now only chooses its series.
 *
 * Leaves out: anti-aliased lines, axis titles beyond the legend and x label,
 * markers, more than one x range per picture.
 */
#include "crease/eval.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

enum {
    MARGIN_L = 110,
    MARGIN_R = 20,
    MARGIN_T = 20,
    TITLE_H = 24,
    PANEL_GAP = 50,
    MARGIN_B = 50,
    TEXT_SCALE = 2
};

static const uint8_t BLACK[3] = {0, 0, 0}, GREY[3] = {200, 200, 200}, DARK[3] = {90, 90, 90};

typedef struct panel {
    int x0, y0, x1, y1; /* pixel box, y0 at the top */
    double xmin, xmax;
    double ymin, ymax; /* data (log10 of data in a log panel) */
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
    for (int guard = 0; guard < 4 * (img->width + img->height); guard++) {
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

/* The value as plotted: log10 in a log panel, NAN where it cannot be. */
static double plotted(const panel *p, double v) {
    if (p->log) v = v > 0.0 ? log10(v) : NAN;
    return isfinite(v) ? v : NAN;
}

static void series(cr_image *img, const panel *p, const cr_plot_series *s) {
    int have = 0, lx = 0, ly = 0;
    for (int i = 0; i < s->n; i++) {
        double v = plotted(p, s->y[i]);
        if (isnan(v) || !isfinite(s->x[i])) {
            have = 0;
            continue;
        }
        int x = px(p, s->x[i]), y = py(p, v);
        if (have)
            line(img, p, lx, ly, x, y, s->rgb);
        else
            line(img, p, x, y, x, y, s->rgb);
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
    if (!(p->xmax > p->xmin)) return;
    double step = nice_step(p->xmin, p->xmax, 6);
    for (double x = ceil(p->xmin / step) * step; x <= p->xmax + 1e-9 * step; x += step) {
        int X = px(p, x);
        vline(img, X, p->y0 + 1, p->y1 - 1, GREY);
        if (!labels) continue;
        char s[32];
        snprintf(s, sizeof s, "%.6g", fabs(x) < 1e-9 * step ? 0.0 : x);
        cr_plot_text(img, X - cr_plot_text_width(s, TEXT_SCALE) / 2, p->y1 + 8, TEXT_SCALE, s,
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
            cr_plot_text(img, p->x0 - 8 - cr_plot_text_width(s, TEXT_SCALE), Y - 7, TEXT_SCALE, s,
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
        cr_plot_text(img, p->x0 - 8 - cr_plot_text_width(s, TEXT_SCALE), Y - 7, TEXT_SCALE, s,
                     BLACK);
    }
}

static void legend(cr_image *img, const panel *p, const cr_plot_panel *d) {
    int y = p->y0 + 10;
    for (int i = 0; i < d->nseries; i++) {
        const char *s = d->series[i].name;
        if (!s) continue;
        int x = p->x1 - 12 - cr_plot_text_width(s, TEXT_SCALE);
        for (int t = 0; t < 3; t++)
            hline(img, x - 34, x - 8, y + 6 + t, d->series[i].rgb);
        cr_plot_text(img, x, y, TEXT_SCALE, s, BLACK);
        y += 20;
    }
}

/* Data range of a panel's series (log10 in a log panel); 0 when it has no finite value. */
static int y_range(panel *p, const cr_plot_panel *d) {
    double lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < d->nseries; k++)
        for (int i = 0; i < d->series[k].n; i++) {
            double v = plotted(p, d->series[k].y[i]);
            if (isnan(v)) continue;
            lo = fmin(lo, v), hi = fmax(hi, v);
        }
    if (!(lo <= hi)) return 0;
    if (p->log) {
        lo = floor(lo), hi = ceil(hi);
        if (hi - lo < 1.0) hi = lo + 1.0;
    } else {
        double pad = 0.05 * (hi - lo);
        if (pad <= 0.0) pad = fabs(hi) > 0.0 ? 0.05 * fabs(hi) : 1.0;
        lo -= pad, hi += pad;
    }
    p->ymin = lo, p->ymax = hi;
    return 1;
}

cr_status cr_plot_lines(const cr_plot_panel *panels, int npanels, const char *x_label,
                        const char *title, int width, int height, cr_image *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (npanels < 1 || npanels > 16)
        return CR_FAIL(err, CR_ERR_INVALID, "plot: 1..16 panels, got %d", npanels);
    int top = MARGIN_T + (title ? TITLE_H : 0);
    int ph = (height - top - (npanels - 1) * PANEL_GAP - MARGIN_B) / npanels;
    if (ph < 20 || width < MARGIN_L + MARGIN_R + 20)
        return CR_FAIL(err, CR_ERR_INVALID, "plot: %dx%d pixels are too small for %d panels", width,
                       height, npanels);
    CR_TRY(cr_image_create(width, height, out, err));
    memset(out->rgb, 255, (size_t)width * height * 3);
    double xmin = INFINITY, xmax = -INFINITY;
    for (int k = 0; k < npanels; k++)
        for (int s = 0; s < panels[k].nseries; s++)
            for (int i = 0; i < panels[k].series[s].n; i++) {
                double x = panels[k].series[s].x[i];
                if (isfinite(x)) xmin = fmin(xmin, x), xmax = fmax(xmax, x);
            }
    if (!(xmin <= xmax)) xmin = 0.0, xmax = 1.0;
    for (int k = 0; k < npanels; k++) {
        int y0 = top + k * (ph + PANEL_GAP);
        panel p = {MARGIN_L, y0, width - MARGIN_R, y0 + ph, xmin, xmax, 0.0, 1.0, panels[k].log_y};
        int have = y_range(&p, &panels[k]);
        x_ticks(out, &p, k == npanels - 1);
        if (have) y_ticks(out, &p);
        for (int s = 0; have && s < panels[k].nseries; s++)
            series(out, &p, &panels[k].series[s]);
        frame(out, &p);
        legend(out, &p, &panels[k]);
    }
    if (x_label)
        cr_plot_text(out, (width - cr_plot_text_width(x_label, TEXT_SCALE)) / 2, height - 20,
                     TEXT_SCALE, x_label, BLACK);
    if (title) cr_plot_text(out, MARGIN_L, MARGIN_T, TEXT_SCALE, title, BLACK);
    return CR_OK;
}

void cr_plot_colorbar(cr_image *img, int x, int y, int w, int h, double lo, double hi,
                      const char *unit) {
    for (int i = 0; i < w; i++) {
        float c[3];
        cr_colormap_viridis(w > 1 ? (float)i / (float)(w - 1) : 0.5f, c);
        uint8_t rgb[3] = {(uint8_t)lroundf(255.0f * c[0]), (uint8_t)lroundf(255.0f * c[1]),
                          (uint8_t)lroundf(255.0f * c[2])};
        vline(img, x + i, y, y + h - 1, rgb);
    }
    hline(img, x - 1, x + w, y - 1, DARK), hline(img, x - 1, x + w, y + h, DARK);
    vline(img, x - 1, y - 1, y + h, DARK), vline(img, x + w, y - 1, y + h, DARK);
    const double v[3] = {lo, 0.5 * (lo + hi), hi};
    const int at[3] = {x, x + w / 2, x + w};
    for (int k = 0; k < 3; k++) {
        char s[48];
        snprintf(s, sizeof s, "%.3g%s%s", v[k], k == 2 && unit ? " " : "",
                 k == 2 && unit ? unit : "");
        int tw = cr_plot_text_width(s, TEXT_SCALE);
        int tx = k == 0 ? at[k] : k == 1 ? at[k] - tw / 2 : at[k] - tw;
        vline(img, at[k] - (k == 2), y + h, y + h + 5, DARK);
        cr_plot_text(img, tx, y + h + 10, TEXT_SCALE, s, BLACK);
    }
}
