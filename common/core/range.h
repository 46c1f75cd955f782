// The closed interval a numeric setting must lie in. A component's settings struct declares
// its bounds as constants, which its own validation and the programs' options both use (so a
// program's --help, its parser and the component never disagree).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

namespace vsurg {

// A number as help text and errors print it: the shortest text that reads back the same.
inline std::string NumberText(double v) {
  char buf[32];
  if (v == static_cast<double>(static_cast<long long>(v)) && v > -1e15 && v < 1e15) {
    std::snprintf(buf, sizeof buf, "%lld", static_cast<long long>(v));  // 100, not 1e+02
    return buf;
  }
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

struct Range {
  double lo, hi;
  constexpr bool Contains(double v) const { return v >= lo && v <= hi; }
  // Within both (a setting that feeds two components).
  constexpr Range And(Range o) const { return {lo > o.lo ? lo : o.lo, hi < o.hi ? hi : o.hi}; }
  constexpr Range Scaled(double k) const { return {lo * k, hi * k}; }          // other units
  std::string Text() const { return NumberText(lo) + ".." + NumberText(hi); }  // "lo..hi"
  std::string Must() const { return "must be within " + Text(); }
};

}  // namespace vsurg
