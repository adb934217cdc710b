/* progress.c: a one-line progress bar on stderr, with rate and ETA.
 * Off a TTY (CI logs, pipes) it prints plain lines at a bounded rate instead
 * of carriage-return redraws, so logs stay readable. */
#define _POSIX_C_SOURCE 200809L
#include "crease/base.h"

#include <string.h>
#include <unistd.h>

enum { BAR_WIDTH = 28 };
static const double TTY_REDRAW_S = 0.1; /* redraw at most 10 times a second */

static void format_duration(double s, char *out, size_t cap) {
    if (s < 0 || s > 1e7) {
        snprintf(out, cap, "--:--");
        return;
    }
    int t = (int)(s + 0.5);
    if (t >= 3600)
        snprintf(out, cap, "%d:%02d:%02d", t / 3600, t / 60 % 60, t % 60);
    else
        snprintf(out, cap, "%02d:%02d", t / 60, t % 60);
}

static void draw(cr_progress *p, double now, int final) {
    double elapsed = now - p->t_start;
    double rate = elapsed > 0 ? (double)p->done / elapsed : 0.0;
    double frac = p->total > 0 ? (double)p->done / (double)p->total : 0.0;
    if (frac > 1) frac = 1;
    char eta[32], el[32];
    format_duration(rate > 0 ? (double)(p->total - p->done) / rate : -1, eta, sizeof eta);
    format_duration(elapsed, el, sizeof el);
    if (p->tty) {
        char bar[BAR_WIDTH + 1];
        int filled = (int)(frac * BAR_WIDTH);
        for (int i = 0; i < BAR_WIDTH; i++) bar[i] = i < filled ? '#' : '.';
        bar[BAR_WIDTH] = 0;
        fprintf(stderr, "\r\033[K%s [%s] %lld/%lld %.1f/s %s<%s %s", p->label, bar,
                (long long)p->done, (long long)p->total, rate, el, eta, p->status);
        if (final) fputc('\n', stderr);
    } else {
        fprintf(stderr, "%s: %lld/%lld (%3.0f%%) %.1f/s elapsed %s eta %s %s\n", p->label,
                (long long)p->done, (long long)p->total, 100.0 * frac, rate, el, eta, p->status);
    }
    fflush(stderr);
    p->t_last_draw = now;
}

void cr_progress_begin(cr_progress *p, const char *label, int64_t total, int quiet) {
    memset(p, 0, sizeof *p);
    p->label = label;
    p->total = total;
    p->quiet = quiet;
    p->tty = isatty(STDERR_FILENO);
    p->plain_interval = 5.0;
    p->t_start = cr_time_now();
    p->t_last_draw = p->tty ? 0.0 : p->t_start;
}

void cr_progress_update(cr_progress *p, int64_t done, const char *fmt, ...) {
    p->done = done;
    if (fmt) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(p->status, sizeof p->status, fmt, ap);
        va_end(ap);
    }
    if (p->quiet) return;
    double now = cr_time_now();
    double interval = p->tty ? TTY_REDRAW_S : p->plain_interval;
    if (now - p->t_last_draw >= interval) draw(p, now, 0);
}

void cr_progress_end(cr_progress *p) {
    if (!p->quiet) draw(p, cr_time_now(), 1);
}
