// The scene files' typed field access (scene.cpp and the parsers of each scene part): every
// error names its field by its path ("regions[0].model.coils: must be ≥ 1"). Set-up code.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/expected.h"
#include "common/haptics/blade.h"
#include "common/scoring/cut.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::sim::scene_detail {

using json = nlohmann::json;

// Typed field access with errors that name the field by its path.
class Reader {
 public:
  Reader(const json& j, std::string path) : j_(j), path_(std::move(path)) {}

  bool Has(const char* key) const { return j_.contains(key); }
  std::string Path(const char* key) const { return path_.empty() ? key : path_ + "." + key; }

  Expected<Reader> Object(const char* key) const {
    if (!j_.contains(key)) return Missing(key);
    if (!j_[key].is_object()) return Bad(key, "must be an object");
    return Reader(j_[key], Path(key));
  }
  Expected<double> Number(const char* key, double lo, double hi,
                          const double* fallback = nullptr) const {
    if (!j_.contains(key)) {
      if (fallback) return *fallback;
      return Missing(key);
    }
    if (!j_[key].is_number()) return Bad(key, "must be a number");
    const double v = j_[key].get<double>();
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream why;
      why << "must be in [" << lo << ", " << hi << "], got " << v;
      return Bad(key, why.str());
    }
    return v;
  }
  Expected<double> NumberOr(const char* key, double fallback, double lo, double hi) const {
    return Number(key, lo, hi, &fallback);
  }
  // Absent: nullopt.
  Expected<std::optional<bool>> OptionalBool(const char* key) const {
    if (!j_.contains(key)) return std::optional<bool>();
    if (!j_[key].is_boolean()) return Bad(key, "must be true or false");
    return std::optional<bool>(j_[key].get<bool>());
  }
  Expected<int> Integer(const char* key, int lo, int hi, const int* fallback = nullptr) const {
    if (!j_.contains(key)) {
      if (fallback) return *fallback;
      return Missing(key);
    }
    if (!j_[key].is_number_integer()) return Bad(key, "must be an integer");
    const long long v = j_[key].get<long long>();
    if (v < lo || v > hi)
      return Bad(key, "must be in " + std::to_string(lo) + ".." + std::to_string(hi));
    return static_cast<int>(v);
  }
  Expected<int> IntegerOr(const char* key, int fallback, int lo, int hi) const {
    return Integer(key, lo, hi, &fallback);
  }
  Expected<std::string> String(const char* key, const std::string* fallback = nullptr) const {
    if (!j_.contains(key)) {
      if (fallback) return *fallback;
      return Missing(key);
    }
    if (!j_[key].is_string() || j_[key].get<std::string>().empty())
      return Bad(key, "must be a non-empty string");
    return j_[key].get<std::string>();
  }
  Expected<std::string> StringOr(const char* key, const std::string& fallback) const {
    return String(key, &fallback);
  }
  // An optional array of `size` numbers in [lo, hi]; absent → empty.
  Expected<std::vector<double>> NumbersOr(const char* key, size_t size, double lo,
                                          double hi) const {
    if (!j_.contains(key)) return std::vector<double>{};
    if (!j_[key].is_array() || j_[key].size() != size)
      return Bad(key, "must be an array of " + std::to_string(size) + " numbers");
    std::vector<double> out;
    for (size_t i = 0; i < size; ++i) {
      const json& v = j_[key][i];
      const double x = v.is_number() ? v.get<double>() : NAN;
      if (!std::isfinite(x) || x < lo || x > hi) {
        std::ostringstream why;
        why << "[" << i << "] must be a number in [" << lo << ", " << hi << "]";
        return Bad(key, why.str());
      }
      out.push_back(x);
    }
    return out;
  }

  Error Missing(const char* key) const {
    return InvalidArgument(Path(key), Path(key) + ": is required");
  }
  Error Bad(const char* key, const std::string& why) const {
    return InvalidArgument(Path(key), Path(key) + ": " + why);
  }
  const json& raw() const { return j_; }
  const std::string& path() const { return path_; }

 private:
  const json& j_;
  std::string path_;
};

#define VSURG_TRY(var, expr)                           \
  auto var##_result = (expr);                          \
  if (!var##_result.ok()) return var##_result.error(); \
  auto var = std::move(*var##_result)

// A cut's patch, blade and pattern from the object `r` holds ("tissue", "blade", "pattern"), in
// people's units (mm, N, J/m²), each checked by name, the pattern inside the patch
// (scene_cut.cpp): a cut scene's "cut" object and a drill file's top level alike.
Status ParseCutParts(const Reader& r, tissue::CutMembraneParams& patch, haptics::BladeParams& blade,
                     scoring::CutPattern& pattern);

}  // namespace vsurg::sim::scene_detail
