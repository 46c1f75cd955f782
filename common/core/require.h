// Parameter checks that name the field they refuse (set-up code: models' Create, scene readers).
#pragma once

#include <limits>
#include <string>

#include "common/core/expected.h"

namespace vsurg {

// A parameter that must be finite and > 0: "thickness: must be > 0 m", naming `field`.
inline Status RequirePositive(const char* field, double v, const char* unit) {
  if (v > 0 && v < std::numeric_limits<double>::infinity()) return Status::Ok();
  return InvalidArgument(field, std::string(field) + ": must be > 0 " + unit);
}

}  // namespace vsurg
