/* vec3.h: the small 3-vector helpers the geometry, body and physics code
 * share, once, as static inline functions (private to the library: nothing
 * here is exported, so the names carry no cr_ prefix).
 *
 * A vector is a plain array of three: float[3] for the f helpers, double[3]
 * for the d ones; sub3fd takes float points and forms their difference in
 * double (exactly, as each float converts to double first). Results leave
 * through the last argument; cross3f and cross3d write it while still reading
 * their inputs, so `out` must not be `a` or `b`. The others allow aliasing.
 * Each helper keeps the operation order of the file-local copies it replaced
 * (src/geom, src/body, src/phys), so their callers' results are unchanged bit
 * for bit.
 *
 * Left out: 3x3 matrices and their products (each user needs its own layout;
 * phys/dihedral64.c keeps mul33), accumulating variants (nn/cpu/cpu_vector.c's
 * cross3 with `acc`), and vectors of any other length.
 */
#ifndef CREASE_BASE_VEC3_H
#define CREASE_BASE_VEC3_H

#include <math.h>

/* ------------------------------------------------------------------ float -- */

static inline void set3f(float v[3], float x, float y, float z) {
    v[0] = x, v[1] = y, v[2] = z;
}

/* out = a - b */
static inline void sub3f(const float a[3], const float b[3], float out[3]) {
    out[0] = a[0] - b[0], out[1] = a[1] - b[1], out[2] = a[2] - b[2];
}

static inline float dot3f(const float a[3], const float b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* out = a x b; out must not alias a or b. */
static inline void cross3f(const float a[3], const float b[3], float out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* |a - b|^2 */
static inline float dist2f(const float a[3], const float b[3]) {
    float d[3];
    sub3f(a, b, d);
    return dot3f(d, d);
}

/* v /= |v| as v * (1 / |v|), one division (the renderer's per-pixel shading);
 * a zero vector stays zero. */
static inline void normalize3f(float v[3]) {
    float len2 = dot3f(v, v);
    if (len2 > 0.0f) {
        float inv = 1.0f / sqrtf(len2);
        v[0] *= inv, v[1] *= inv, v[2] *= inv;
    }
}

/* v /= |v| by three divisions, each component rounded once: up to an ulp off
 * normalize3f, and what the mannequin's rest shape is built with (its body
 * mesh moves by up to 1.4 um with the other form). A zero vector stays zero. */
static inline void normalize3f_div(float v[3]) {
    float len2 = dot3f(v, v);
    if (len2 > 0.0f) {
        float len = sqrtf(len2);
        v[0] /= len, v[1] /= len, v[2] /= len;
    }
}

/* ----------------------------------------------------------------- double -- */

/* out = a - b */
static inline void sub3d(const double a[3], const double b[3], double out[3]) {
    out[0] = a[0] - b[0], out[1] = a[1] - b[1], out[2] = a[2] - b[2];
}

/* out = a - b of float points, in double. */
static inline void sub3fd(const float a[3], const float b[3], double out[3]) {
    out[0] = (double)a[0] - b[0], out[1] = (double)a[1] - b[1], out[2] = (double)a[2] - b[2];
}

static inline double dot3d(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* out = a x b; out must not alias a or b. */
static inline void cross3d(const double a[3], const double b[3], double out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

#endif
