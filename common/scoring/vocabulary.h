// The evaluation vocabulary, in one place for the scoring code, the store and the tools: the nine
// indexes, the three evaluator groups and the 0–10 rule (the coil-spring paper §4.4). Header-only
// and light (no Eigen, no JSON): db/ includes it without linking the scoring library.
//
// Indexes and groups are stored and exported by name: the names are never respelled, and adding
// an index means one more entry here (and a schema migration for the stored rows' check).
#pragma once

#include <cmath>
#include <optional>
#include <string_view>

namespace vsurg::scoring {

inline constexpr int kIndexCount = 9;
inline constexpr int kGroupCount = 3;
inline constexpr double kMinScore = 0.0, kMaxScore = 10.0;

// Index j in 0..8, as the coil-spring paper numbers them 1..9.
inline constexpr const char* kIndexNames[kIndexCount] = {
    "effectiveness", "force_feedback", "real_time", "stability", "deformation_efficiency",
    "fidelity",      "visual_fluency", "immersion", "texture"};

// Stored as text ("intern", "associate_chief", "chief"): never renumbered.
enum class EvaluatorGroup { kIntern = 0, kAssociateChief = 1, kChief = 2 };
inline constexpr const char* kGroupNames[kGroupCount] = {"intern", "associate_chief", "chief"};

inline constexpr const char* IndexName(int j) {
  return j >= 0 && j < kIndexCount ? kIndexNames[j] : "unknown";
}

inline constexpr const char* GroupName(EvaluatorGroup g) {
  return kGroupNames[static_cast<int>(g)];
}

inline std::optional<EvaluatorGroup> ParseGroup(std::string_view name) {
  for (int g = 0; g < kGroupCount; ++g)
    if (name == kGroupNames[g]) return static_cast<EvaluatorGroup>(g);
  return std::nullopt;
}

// The 0–10 rule: a score is finite and within [kMinScore, kMaxScore].
inline bool IsValidScore(double s) {
  return std::isfinite(s) && s >= kMinScore && s <= kMaxScore;
}

}  // namespace vsurg::scoring
