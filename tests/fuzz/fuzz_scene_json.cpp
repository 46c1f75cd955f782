// libFuzzer target: a scene file (sim::ParseScene). Every field is type-checked and every error
// names the file; nothing throws, nothing crashes; a scene that parses fits the memory budget.
#include <cmath>
#include <cstdint>
#include <string>

#include "common/sim/scene.h"
#include "tests/fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto scene = vsurg::sim::ParseScene(text, "fuzz.json");
  if (!scene.ok()) {
    VSURG_FUZZ_CHECK(scene.error().message.rfind("fuzz.json: ", 0) == 0);
    return 0;
  }
  VSURG_FUZZ_CHECK(!scene->name.empty());
  VSURG_FUZZ_CHECK(std::isfinite(scene->region.dt) && scene->region.dt > 0);
  return 0;
}
