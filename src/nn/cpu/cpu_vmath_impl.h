/* cpu_vmath_impl.h (private, no include guard): the vector exp, log, tanh,
 * sigmoid and softplus of cpu_vmath.c, written once over GCC/clang vector
 * types and instantiated per SIMD width. The includer defines
 *   VW         lanes (8: AVX2, 16: AVX-512)
 *   VT         the function attribute, e.g. __attribute__((target("avx2,fma")))
 *   V(name)    the instance's name for `name`, e.g. name##_avx2
 *   VFMA(a, b, c)  a * b + c rounded once (the target's FMA intrinsic)
 *
 * Algorithms (Cephes' single-precision ones, about 1 ulp each):
 *   exp(x)  = 2^n exp(r), n = round(x / ln 2), r = x - n ln 2 (ln 2 in two
 *             parts), exp(r) by a degree-7 polynomial; 2^n applied as two
 *             factors 2^(n/2) 2^(n - n/2), so the result overflows to inf
 *             above 88.72 and goes through the subnormals to 0 below -87.3
 *             exactly as expf does (one rounding).
 *   log(x)  = e ln 2 + log(m), m in [sqrt(1/2), sqrt(2)), log(m) = f - f^2/2
 *             + f^3 P(f), f = m - 1; subnormal x scaled by 2^23 first;
 *             log(0) = -inf, log(inf) = inf, log(x < 0) = NaN.
 *   tanh(x) = x + x^3 P(x^2) for |x| < 0.625, else sign(x) (1 - 2 / (exp(2|x|) + 1)).
 *   sin, cos: z = |x| - n pi/2, n = round(|x| 2/pi) (pi/2 in three parts, so
 *             z is exact to about 1e-7 absolute for |x| < V(SINCOS_MAX)), the
 *             polynomials of Cephes' sinf and cosf on [-pi/4, pi/4], the
 *             quadrant's swap and signs; callers send larger |x| to libm.
 * NaN inputs give NaN everywhere, as on the scalar path. Rounding to the
 * nearest integer uses the 1.5 * 2^23 shift, so it assumes the default
 * rounding mode, as the rest of the engine does.
 */

typedef float V(vf) __attribute__((vector_size(VW * 4)));
typedef int32_t V(vi) __attribute__((vector_size(VW * 4)));

static inline VT V(vf) V(load)(const float *p) {
    V(vf) v;
    memcpy(&v, p, sizeof v);
    return v;
}

static inline VT void V(store)(float *p, V(vf) v) {
    memcpy(p, &v, sizeof v);
}

static inline VT V(vf) V(splat)(float c) {
    return (V(vf)){0} + c;
}

/* m ? a : b, m a comparison's lanes (all ones or zero). */
static inline VT V(vf) V(sel)(V(vi) m, V(vf) a, V(vf) b) {
    return (V(vf))(((V(vi))a & m) | ((V(vi))b & ~m));
}

static inline VT V(vf) V(abs)(V(vf) x) {
    return (V(vf))((V(vi))x & 0x7fffffff);
}

static inline VT V(vf) V(exp)(V(vf) x) {
    V(vf) xc = V(sel)(x > 89.0f, V(splat)(89.0f), V(sel)(x < -104.0f, V(splat)(-104.0f), x));
    V(vf) shift = V(splat)(12582912.0f); /* 1.5 * 2^23 */
    V(vf) n = VFMA(xc, V(splat)(1.44269504088896341f), shift) - shift;
    V(vf) r = VFMA(n, V(splat)(-0.693359375f), xc);
    r = VFMA(n, V(splat)(2.12194440e-4f), r);
    V(vf) p = V(splat)(1.9875691500e-4f);
    p = VFMA(p, r, V(splat)(1.3981999507e-3f));
    p = VFMA(p, r, V(splat)(8.3334519073e-3f));
    p = VFMA(p, r, V(splat)(4.1665795894e-2f));
    p = VFMA(p, r, V(splat)(1.6666665459e-1f));
    p = VFMA(p, r, V(splat)(5.0000001201e-1f));
    V(vf) y = VFMA(p, r * r, r) + 1.0f;
    V(vi) ni = __builtin_convertvector(n, V(vi));
    V(vi) n1 = ni >> 1, n2 = ni - n1;
    y = y * (V(vf))((n1 + 127) << 23) * (V(vf))((n2 + 127) << 23);
    return V(sel)(x != x, x, y);
}

#define SINCOS_MAX 8192.0f

/* sin and cos of x for |x| <= SINCOS_MAX (NaN stays NaN). */
static inline VT void V(sincos)(V(vf) x, V(vf) * s, V(vf) * c) {
    V(vf) ax = V(abs)(x);
    V(vf) shift = V(splat)(12582912.0f); /* 1.5 * 2^23 */
    V(vf) n = VFMA(ax, V(splat)(0.636619772367581343f), shift) - shift;
    V(vf) z = VFMA(n, V(splat)(-1.5703125f), ax);
    z = VFMA(n, V(splat)(-4.837512969970703125e-4f), z);
    z = VFMA(n, V(splat)(-7.54978995489188216e-8f), z);
    V(vf) zz = z * z;
    V(vf) ps = VFMA(V(splat)(-1.9515295891e-4f), zz, V(splat)(8.3321608736e-3f));
    ps = VFMA(ps, zz, V(splat)(-1.6666654611e-1f));
    V(vf) sp = VFMA(ps * zz, z, z);
    V(vf) pc = VFMA(V(splat)(2.443315711809948e-5f), zz, V(splat)(-1.388731625493765e-3f));
    pc = VFMA(pc, zz, V(splat)(4.166664568298827e-2f));
    V(vf) cp = VFMA(pc * zz, zz, VFMA(zz, V(splat)(-0.5f), V(splat)(1.0f)));
    V(vi) q = __builtin_convertvector(n, V(vi));
    V(vi) odd = (q & 1) != 0;
    V(vf) s0 = V(sel)(odd, cp, sp), c0 = V(sel)(odd, sp, cp);
    /* sin's sign: quadrants 2 and 3, flipped for x < 0; cos's: 1 and 2 */
    V(vi) sneg = ((q & 2) != 0) ^ (x < 0.0f), cneg = ((q + 1) & 2) != 0;
    *s = V(sel)(sneg, -s0, s0);
    *c = V(sel)(cneg, -c0, c0);
}

/* WIRE's activation (nn_layers.h) on (re, im) in place:
 * exp(-omega0 im - s2 (re^2 + im^2)) (cos omega0 re + j sin omega0 re). */
static inline VT void V(wire)(V(vf) * re, V(vf) * im, float omega0, float s2) {
    V(vf) a = *re, b = *im, s, c;
    V(vf) e = V(exp)(-omega0 * b - s2 * (a * a + b * b));
    V(sincos)(omega0 * a, &s, &c);
    *re = e * c, *im = e * s;
}

/* log(x) for positive, normal, finite x. */
static inline VT V(vf) V(log_normal)(V(vf) x) {
    V(vi) bits = (V(vi))x;
    V(vf) e = __builtin_convertvector(((bits >> 23) & 0xff) - 126, V(vf));
    V(vf) m = (V(vf))((bits & 0x007fffff) | 0x3f000000); /* [0.5, 1) */
    V(vi) low = m < 0.707106781186547524f;
    e = V(sel)(low, e - 1.0f, e);
    V(vf) f = V(sel)(low, m + m, m) - 1.0f;
    V(vf) z = f * f;
    V(vf) p = V(splat)(7.0376836292e-2f);
    p = VFMA(p, f, V(splat)(-1.1514610310e-1f));
    p = VFMA(p, f, V(splat)(1.1676998740e-1f));
    p = VFMA(p, f, V(splat)(-1.2420140846e-1f));
    p = VFMA(p, f, V(splat)(1.4249322787e-1f));
    p = VFMA(p, f, V(splat)(-1.6668057665e-1f));
    p = VFMA(p, f, V(splat)(2.0000714765e-1f));
    p = VFMA(p, f, V(splat)(-2.4999993993e-1f));
    p = VFMA(p, f, V(splat)(3.3333331174e-1f));
    V(vf) y = p * f * z;
    y = VFMA(e, V(splat)(-2.12194440e-4f), y);
    y = VFMA(z, V(splat)(-0.5f), y);
    return VFMA(e, V(splat)(0.693359375f), f + y);
}

static inline VT V(vf) V(log)(V(vf) x) {
    V(vi) sub = x < 1.17549435e-38f; /* FLT_MIN */
    V(vf) xs = V(sel)(sub, x * 8388608.0f, x);
    V(vf) y = V(log_normal)(xs);
    y = V(sel)(sub, y - 15.942385152878742f, y); /* 23 ln 2 */
    V(vf) inf = V(splat)(INFINITY);
    y = V(sel)(x == inf, inf, y);
    y = V(sel)(x == 0.0f, -inf, y);
    return V(sel)(x < 0.0f, V(splat)(NAN), V(sel)(x != x, x, y));
}

/* log(1 + e) for e in [0, 1] (softplus's), as e + e^2 R(e) with R a
 * degree-7 fit of (log1p(e) - e) / e^2 in relative error of the whole
 * (3.3e-8; 1.4 ulp at most in float over [0, 1], measured on 2M points):
 * 9 vector operations where log(1 + e) through log_normal took about 29,
 * and exact as e goes to 0. */
static inline VT V(vf) V(log1p01)(V(vf) e) {
    V(vf) r = V(splat)(5.364822689e-03f);
    r = VFMA(r, e, V(splat)(-3.006578609e-02f));
    r = VFMA(r, e, V(splat)(7.920452207e-02f));
    r = VFMA(r, e, V(splat)(-1.375380158e-01f));
    r = VFMA(r, e, V(splat)(1.915365458e-01f));
    r = VFMA(r, e, V(splat)(-2.485716343e-01f));
    r = VFMA(r, e, V(splat)(3.332132399e-01f));
    r = VFMA(r, e, V(splat)(-4.999964833e-01f));
    return VFMA(e * e, r, e);
}

static inline VT V(vf) V(tanh)(V(vf) x) {
    V(vf) a = V(abs)(x), s = x * x;
    V(vf) p = V(splat)(-5.70498872745e-3f);
    p = VFMA(p, s, V(splat)(2.06390887954e-2f));
    p = VFMA(p, s, V(splat)(-5.37397155531e-2f));
    p = VFMA(p, s, V(splat)(1.33314422036e-1f));
    p = VFMA(p, s, V(splat)(-3.33332819422e-1f));
    V(vf) small = VFMA(p * s, a, a);
    V(vf) big = 1.0f - 2.0f / (V(exp)(a + a) + 1.0f);
    V(vf) y = V(sel)(a < 0.625f, small, big);          /* tanh(|x|) */
    return (V(vf))((V(vi))y | ((V(vi))x & INT32_MIN)); /* x's sign, -0 included */
}

/* 1 / (1 + exp(-x)), as e / (1 + e) with e = exp(-|x|) below 0. */
static inline VT V(vf) V(sigmoid)(V(vf) x) {
    V(vf) e = V(exp)(-V(abs)(x));
    return V(sel)(x >= 0.0f, V(splat)(1.0f), e) / (1.0f + e);
}

static inline VT V(vf) V(softplus)(V(vf) x, float beta) {
    V(vf) bx = x * beta;
    V(vf) pos = V(sel)(bx > 0.0f, bx, V(splat)(0.0f));
    return (pos + V(log1p01)(V(exp)(-V(abs)(bx)))) * (1.0f / beta);
}

/* sigmoid(beta z) from y = softplus_beta(z), as nn_cpu_softplus_deriv_from_y. */
static inline VT V(vf) V(softplus_deriv_from_y)(V(vf) y, float beta) {
    V(vf) t = y * beta;
    V(vf) series = V(splat)(1.0f / 120.0f);
    series = 1.0f / 24.0f - t * series;
    series = 1.0f / 6.0f - t * series;
    series = 0.5f - t * series;
    series = t * (1.0f - t * series);
    return V(sel)(t < 0.1f, series, 1.0f - V(exp)(-t));
}

static inline VT __attribute__((always_inline)) V(vf) V(apply)(nn_vec_fn fn, float p, V(vf) v) {
    switch (fn) {
    case NN_VEC_EXP:
        return V(exp)(v);
    case NN_VEC_LOG:
        return V(log)(v);
    case NN_VEC_TANH:
        return V(tanh)(v);
    case NN_VEC_SIGMOID:
        return V(sigmoid)(v);
    case NN_VEC_SOFTPLUS:
        return V(softplus)(v, p);
    case NN_VEC_SIGMOID_SCALED:
        return V(sigmoid)(v * p);
    case NN_VEC_TANH_DERIV_FROM_Y:
        return 1.0f - v * v;
    case NN_VEC_SIGMOID_DERIV_FROM_Y:
        return v * (1.0f - v);
    case NN_VEC_SOFTPLUS_DERIV_FROM_Y:
        return V(softplus_deriv_from_y)(v, p);
    }
    return v;
}

/* The loop of cr_nn_cpu_vec_span for one constant fn (inlined per case). */
static inline VT __attribute__((always_inline)) int64_t V(span_fn)(nn_vec_fn fn, float p,
                                                                   const float *x, const float *b,
                                                                   const float *mul, float *out,
                                                                   int acc, int64_t n) {
    int64_t i = 0;
    for (; i + VW <= n; i += VW) {
        V(vf) v = V(load)(x + i);
        if (b) v = v + V(load)(b + i);
        v = V(apply)(fn, p, v);
        if (mul) v = v * V(load)(mul + i);
        if (acc) v = v + V(load)(out + i);
        V(store)(out + i, v);
    }
    return i;
}

static inline VT int64_t V(span)(nn_vec_fn fn, float p, const float *x, const float *b,
                                 const float *mul, float *out, int acc, int64_t n) {
    switch (fn) {
    case NN_VEC_EXP:
        return V(span_fn)(NN_VEC_EXP, p, x, b, mul, out, acc, n);
    case NN_VEC_LOG:
        return V(span_fn)(NN_VEC_LOG, p, x, b, mul, out, acc, n);
    case NN_VEC_TANH:
        return V(span_fn)(NN_VEC_TANH, p, x, b, mul, out, acc, n);
    case NN_VEC_SIGMOID:
        return V(span_fn)(NN_VEC_SIGMOID, p, x, b, mul, out, acc, n);
    case NN_VEC_SOFTPLUS:
        return V(span_fn)(NN_VEC_SOFTPLUS, p, x, b, mul, out, acc, n);
    case NN_VEC_SIGMOID_SCALED:
        return V(span_fn)(NN_VEC_SIGMOID_SCALED, p, x, b, mul, out, acc, n);
    case NN_VEC_TANH_DERIV_FROM_Y:
        return V(span_fn)(NN_VEC_TANH_DERIV_FROM_Y, p, x, b, mul, out, acc, n);
    case NN_VEC_SIGMOID_DERIV_FROM_Y:
        return V(span_fn)(NN_VEC_SIGMOID_DERIV_FROM_Y, p, x, b, mul, out, acc, n);
    case NN_VEC_SOFTPLUS_DERIV_FROM_Y:
        return V(span_fn)(NN_VEC_SOFTPLUS_DERIV_FROM_Y, p, x, b, mul, out, acc, n);
    }
    return 0;
}
