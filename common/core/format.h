// Numbers as people read them.
#pragma once

#include <cstdio>
#include <string>

namespace vsurg {

// `v` with `digits` decimals ("%.*f"): "nan" and "inf" as printf writes them.
inline std::string Fixed(double v, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

}  // namespace vsurg
