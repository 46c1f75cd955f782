// A property check inside a fuzz target: on failure, says which and aborts, so libFuzzer keeps
// the input as a crash and the corpus replay test fails.
#pragma once

#include <cstdio>
#include <cstdlib>

#define VSURG_FUZZ_CHECK(cond)                                                              \
  do {                                                                                      \
    if (!(cond)) {                                                                          \
      std::fprintf(stderr, "%s:%d: fuzz property failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                         \
    }                                                                                       \
  } while (0)
