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

// Two padded 3-vectors side by side (one AVX-512 register, two AVX2 ones): one operation does the
// same arithmetic on both, as when two quantities share their scalar factors.
typedef double V8 __attribute__((vector_size(64), may_alias));

// Storage for a 3-vector padded to four doubles, aligned for a V4 view.
struct alignas(32) Lane4 {
  double v[4];
};
// Storage for two of them, aligned for a V8 view (the halves are aligned for V4 views).
struct alignas(64) Lane8 {
  double v[8];
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

// The sum of the four lanes.
inline double Sum(const V4& a) {
  return (a[0] + a[2]) + (a[1] + a[3]);
}

// The sum of the four products (a padded lane contributes 0 when either side has 0 there).
inline double Dot(const V4& a, const V4& b) {
  return Sum(a * b);
}

// The dot product broadcast over the four lanes (no scalar round trip).
inline void Dots(V4& out, const V4& a, const V4& b) {
  const V4 m = a * b;
  const V4 s = m + __builtin_shufflevector(m, m, 1, 0, 3, 2);
  out = s + __builtin_shufflevector(s, s, 2, 3, 0, 1);
}

// Each half's three-term dot product, broadcast over that half: {a₀·b₀ ×4, a₁·b₁ ×4} (the
// padded lanes must be 0 on one side).
inline void HalfDots(V8& out, const V8& a, const V8& b) {
  const V8 m = a * b;
  const V8 s = m + __builtin_shufflevector(m, m, 1, 0, 3, 2, 5, 4, 7, 6);
  out = s + __builtin_shufflevector(s, s, 2, 3, 0, 1, 6, 7, 4, 5);
}

}  // namespace vsurg::tissue::simd

// Put before a hot function's definition: GCC builds it three times, for x86-64-v4 (AVX-512),
// x86-64-v3 (AVX2, FMA) and the baseline, and the loader picks the one the CPU runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VSURG_SIMD_CLONES \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define VSURG_SIMD_CLONES
#endif
