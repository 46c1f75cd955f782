// Sample counts for long randomised tests: a sanitizer build (VSURG_SANITIZED, set by CMake with
// VSURG_SANITIZE or VSURG_TSAN) runs 10-50x slower and is there to check memory, undefined
// behaviour and threads on every code path, which a tenth of the samples still reach; the main
// build runs them all.
#pragma once

namespace vsurg::test {

#ifdef VSURG_SANITIZED
inline constexpr int kSampleDivisor = 10;
#else
inline constexpr int kSampleDivisor = 1;
#endif

constexpr int Samples(int full) {
  return full / kSampleDivisor;
}

}  // namespace vsurg::test
