// Numbers in the tissue models' error messages, as printf's %g prints them. Internal to
// common/tissue (one definition, so the library's sources can share a unity build).
#pragma once

#include <cstdio>
#include <string>

namespace vsurg::tissue::detail {

inline std::string Num(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

}  // namespace vsurg::tissue::detail
