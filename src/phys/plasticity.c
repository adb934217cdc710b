/* plasticity.c: the bending rest-angle update of elastoplastic cloth.
 *
 * Per hinge, the elastic bending strain is d = theta - theta_rest. Where |d|
 * exceeds the yield angle y, the rest angle moves toward theta by the excess
 * times a gain (Narain, Pfaff & O'Brien, "Folding and crumpling adaptive
 * sheets", SIGGRAPH 2013, sec. 5; gain 1 is perfect plasticity: the elastic
 * strain is capped at y). EPNet (eq. 3-5) smooths the onset with a logistic
 * sigmoid, theta_rest += sign(d) s(50 (|d| - y)) max(|d| - y, 0), which is the
 * CR_PLASTIC_SMOOTH rule at gain 1.
 *
 * Left out: hardening (a yield that grows with plastic strain), plasticity of
 * the membrane.
 */
#include "crease/phys_sim.h"

#include <math.h>

/* EPNet's sigmoid sharpness, 1/rad. */
#define SMOOTH_SHARPNESS 50.0

int32_t cr_plasticity_update(const double *theta, double *theta_rest, int32_t nh, double yield,
                             double gain, cr_plastic_rule rule) {
    int32_t yielded = 0;
    for (int32_t h = 0; h < nh; h++) {
        double d = theta[h] - theta_rest[h], excess = fabs(d) - yield;
        if (!(excess > 0.0)) continue;
        double amount = gain * excess;
        if (rule == CR_PLASTIC_SMOOTH) amount /= 1.0 + exp(-SMOOTH_SHARPNESS * excess);
        theta_rest[h] += d > 0.0 ? amount : -amount;
        yielded++;
    }
    return yielded;
}
