// libFuzzer target: mesh import (geometry::ParseObj, the OBJ reader scenes use). A mesh that
// parses has its face indices in range.
#include <cstdint>
#include <sstream>
#include <string>

#include "common/geometry/obj_io.h"
#include "tests/fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  auto mesh = vsurg::geometry::ParseObj(in, "fuzz.obj");
  if (!mesh.ok()) return 0;
  const int n = mesh->VertexCount();
  for (const auto& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) VSURG_FUZZ_CHECK(t[k] >= 0 && t[k] < n);
  for (const auto& p : mesh->positions) VSURG_FUZZ_CHECK(p.allFinite());
  return 0;
}
