// Four doubles as one value, for the solvers' hot loops (mass-spring, FEM): GCC's vector
// extension, so the same source is one AVX2 instruction per operation in a function built for
// x86-64-v3 (VSURG_SIMD_CLONES below) and two SSE2 instructions in the baseline build.
// A 3-vector is padded to four (the fourth 0 or ignored). may_alias and 8-byte alignment make it
// legal to view a std::vector<double> (or Eigen's 3-vectors) as V4 in place.
#pragma once

namespace vsurg::tissue::simd {

using V4 = double __attribute__((vector_size(32), aligned(8), may_alias));

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
