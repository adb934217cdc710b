/* atan2d.h (private): a double atan2 within 2 ulp of libm's, inline, for the
 * hot loops that take many angles (the hinge angle of phys/, the body BVH's
 * vertex normals of geom/); tests/test_base.c checks the bound. */
#ifndef CREASE_BASE_ATAN2D_H
#define CREASE_BASE_ATAN2D_H

#include <math.h>

/* atan2(y, x) within 2 ulp of libm's (tested, bound 3): the
 * reduction r = min/max(|x|, |y|) in [0, 1], folded by atan r = pi/4 +
 * atan((r - 1)/(r + 1)) above tan(pi/8), leaves |t| <= 0.4143, where
 * fdlibm's odd polynomial for atan (Sun Microsystems 1993, s_atan.c; its
 * published coefficients, here summed by Estrin's scheme) is accurate to an
 * ulp; the quadrant follows from
 * the swap and the signs. glibc's correctly rounded atan2 spent 15 % of a VBD
 * sweep (the hinge angle) and 28 % of an epnet reference run (the body BVH's
 * angle-weighted vertex normals, geom/bvh.c). Zeros, infinities and NaNs go
 * to libm. */
static inline double cr_atan2d(double y, double x) {
    const double ax = fabs(x), ay = fabs(y), sum = ax + ay;
    if (!(sum > 0.0) || !(sum < INFINITY)) return atan2(y, x);
    const int swap = ay > ax;
    const double mn = swap ? ax : ay, mx = swap ? ay : ax;
    /* r = mn/mx; above tan(pi/8), t = (r - 1)/(r + 1) = (mn - mx)/(mn + mx):
     * one division either way. */
    const int fold = mn > 0.41421356237309503 * mx;
    const double t = fold ? (mn - mx) / (mn + mx) : mn / mx;
    /* atan t = t - t z P(z), z = t^2, P fdlibm's degree-10 polynomial, by
     * Estrin's scheme (a shorter dependency chain than Horner's). */
    const double z = t * t, z2 = z * z, z4 = z2 * z2, z8 = z4 * z4;
    const double p01 = 3.33333333333329318027e-01 + z * -1.99999999998764832476e-01;
    const double p23 = 1.42857142725034663711e-01 + z * -1.11111104054623557880e-01;
    const double p45 = 9.09088713343650656196e-02 + z * -7.69187620504482999495e-02;
    const double p67 = 6.66107313738753120669e-02 + z * -5.83357013379057348645e-02;
    const double p89 = 4.97687799461593236017e-02 + z * -3.65315727442169155270e-02;
    const double q0 = p01 + z2 * p23, q1 = p45 + z2 * p67;
    const double q2 = p89 + z2 * 1.62858201153657823623e-02;
    const double corr = t * (z * ((q0 + z4 * q1) + z8 * q2));
    /* pi/4, pi/2 and pi as a double and the rest. */
    double a =
        fold ? 7.85398163397448278999e-01 - ((corr - 3.06161699786838301793e-17) - t) : t - corr;
    if (swap) a = 1.57079632679489655800e+00 - (a - 6.12323399573676603587e-17);
    if (signbit(x)) a = 3.14159265358979311600e+00 - (a - 1.2246467991473531772e-16);
    return copysign(a, y);
}

#endif
