/* cpu_vmath_levels.h (private, no include guard: one inclusion per source
 * file): cpu_vmath_impl.h's vector functions instantiated for AVX2 + FMA
 * (name_avx2, 8 lanes) and AVX-512F (name_avx512, 16 lanes) on x86; nothing
 * elsewhere. The includer tests the same macro before calling them. */
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#include <string.h>

#define VW 8
#define VT __attribute__((target("avx2,fma")))
#define V(name) name##_avx2
#define VFMA(a, b, c) _mm256_fmadd_ps(a, b, c)
#include "nn/cpu/cpu_vmath_impl.h"
#undef VW
#undef VT
#undef V
#undef VFMA

#define VW 16
#define VT __attribute__((target("avx512f")))
#define V(name) name##_avx512
#define VFMA(a, b, c) _mm512_fmadd_ps(a, b, c)
#include "nn/cpu/cpu_vmath_impl.h"
#undef VW
#undef VT
#undef V
#undef VFMA
#endif
