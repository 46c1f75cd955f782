// libFuzzer target: a stylus trajectory CSV (`vsurg-sim run`, the replay device). What parses is
// a list of samples in the documented units; no input crashes the reader.
#include <cstdint>
#include <string>

#include "common/sim/trajectory.h"
#include "tests/fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto samples = vsurg::sim::ParseTrajectoryCsv(text, "fuzz.csv");
  if (!samples.ok()) {
    VSURG_FUZZ_CHECK(samples.error().message.find("fuzz.csv") != std::string::npos);
    return 0;
  }
  for (const auto& s : *samples) VSURG_FUZZ_CHECK(s.position.allFinite());
  return 0;
}
