// Four doubles as one value, for the solvers' hot loops (mass-spring, FEM): GCC's vector
// extension, so the same source is one AVX2 instruction per operation in a function built for
// x86-64-v3 (VSURG_SIMD_CLONES below) and two SSE2 instructions in the baseline build.
// A 3-vector is padded to four (the fourth 0 or ignored); may_alias makes it legal to view other
// storage as V4.
#pragma once

namespace vsurg::tissue::simd {

// V4 keeps the vector's natural 32-byte alignment (Clang does not honour a lowered alignment on a
// vector typedef in every context): data viewed as V4 in place must be 32-byte aligned (Lane4
// below); anything else goes through Load and AddTo, which copy (an unaligned move).
typedef double V4 __attribute__((vector_size(32), may_alias));

// Storage for a 3-vector padded to four doubles, aligned for a V4 view.
struct alignas(32) Lane4 {
  double v[4];
};

// By reference only: a V4 passed or returned by value changes the ABI between the clones.
inline void Load(V4& out, const double* p) {
  __builtin_memcpy(&out, p, sizeof(V4));
}
inline void AddTo(double* p, const V4& v) {
  V4 t;
  __builtin_memcpy(&t, p, sizeof(V4));
  t += v;
  __builtin_memcpy(p, &t, sizeof(V4));
}

// The sum of the four products (a padded lane contributes 0 when either side has 0 there).
inline double Dot(const V4& a, const V4& b) {
  const V4 m = a * b;
  return (m[0] + m[2]) + (m[1] + m[3]);
}

}  // namespace vsurg::tissue::simd

// Put before a hot function's definition: GCC builds it twice, for x86-64-v3 (AVX2, FMA) and the
// baseline, and the loader picks the one the CPU runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VSURG_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define VSURG_SIMD_CLONES
#endif
