/* ratchet.c: the ratchet and drive gating of epnet's proxy inference, one
 * frame over the hinges (epnet.h, cr_epnet_ratchet_step).
 *
 * P-Net rolls RB over the angles of E-Net at RB = 0 (the proxy); its
 * increment reaches RB only at a hinge the proxy keeps driven and only when
 * it is not negligible, and then never shrinks |RB|:
 *     driven_t  = |wrap(s_t - RB_t)| > drive            (s the proxy's theta - theta_bar)
 *     applied   = driven_t and driven in >= drive_frames of the last drive_window frames
 *                 and |delta| >= min_delta
 *     c         = RB_t + delta,  RB_{t+1} = sign(c) max(|RB_t|, |c|)
 * with sign(0) read as RB_t's (numpy's sign(0) = 0 would zero RB there).
 * After the authors' code (epnet/commands/predict_pnet_tf.py, output mode
 * "delta_direct"; read, not copied); the thresholds 0.05 rad in 3 of the
 * last 5 frames and 0.005 rad are issue 48's (their CLI's default cut-off
 * is 0.05). What it leaves out: P-Net itself (model.c's proxy rollout calls
 * it per frame). */
#include "crease/epnet.h"

#include <math.h>

#define RATCHET_COOKIE 0x45505243u

cr_epnet_ratchet_def cr_epnet_ratchet_default_def(void) {
    cr_epnet_ratchet_def d = {0};
    d.drive = 0.05;
    d.drive_frames = 3;
    d.drive_window = 5;
    d.min_delta = 0.005;
    d.cookie = RATCHET_COOKIE;
    return d;
}

cr_status cr_epnet_ratchet_check(const cr_epnet_ratchet_def *d, cr_error *err) {
    if (d->cookie != RATCHET_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet ratchet: def not made by its default");
    if (d->drive_window < 1 || d->drive_window > 32 || d->drive_frames < 1 ||
        d->drive_frames > d->drive_window)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "epnet ratchet: drive in %d of %d frames: expected 1 <= frames <= window "
                       "<= 32",
                       d->drive_frames, d->drive_window);
    if (!(d->drive >= 0) || !(d->min_delta >= 0))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "epnet ratchet: drive %g and min_delta %g must be >= 0 rad", d->drive,
                       d->min_delta);
    return CR_OK;
}

static int popcount32(uint32_t x) {
    int n = 0;
    for (; x; x &= x - 1)
        n++;
    return n;
}

int32_t cr_epnet_ratchet_step(const cr_epnet_ratchet_def *d, const float *strain,
                              const float *delta, int32_t nh, uint32_t *history, float *rb) {
    CR_ASSERT(d->cookie == RATCHET_COOKIE);
    const uint32_t window =
        d->drive_window >= 32 ? 0xffffffffu : ((uint32_t)1 << d->drive_window) - 1u;
    int32_t changed = 0;
    for (int32_t h = 0; h < nh; h++) {
        const double r = rb[h];
        const double drive = remainder((double)strain[h] - r, 2.0 * M_PI);
        const uint32_t now = fabs(drive) > d->drive;
        history[h] = ((history[h] << 1) | now) & window;
        const double dl = delta[h];
        if (!now || popcount32(history[h]) < d->drive_frames || !(fabs(dl) >= d->min_delta))
            continue;
        const double c = r + dl;
        const double sign = c > 0 ? 1.0 : c < 0 ? -1.0 : (r >= 0 ? 1.0 : -1.0);
        const float next = (float)(sign * fmax(fabs(r), fabs(c)));
        if (next != rb[h]) changed++;
        rb[h] = next;
    }
    return changed;
}
