// The store's names for roles, subject kinds and export formats: stored and typed by users as
// text, never renumbered or respelled. Header-only and light, so a gRPC client (vsurg-admin)
// validates its options with the same table without linking the store.
#pragma once

#include <optional>
#include <string_view>

namespace vsurg::db {

enum class Role { kTrainee, kInstructor, kEvaluator, kAdmin };
inline constexpr const char* kRoleNames[] = {"trainee", "instructor", "evaluator", "admin"};

enum class SubjectKind { kSession, kTrainee, kModel };
inline constexpr const char* kSubjectKindNames[] = {"session", "trainee", "model"};

enum class ExportFormat { kCsv, kJsonLines, kXapi };
inline constexpr const char* kExportFormatNames[] = {"csv", "jsonl", "xapi"};

namespace detail {
template <class Enum, size_t N>
std::optional<Enum> ParseName(const char* const (&names)[N], std::string_view name) {
  for (size_t i = 0; i < N; ++i)
    if (name == names[i]) return static_cast<Enum>(i);
  return std::nullopt;
}
}  // namespace detail

inline const char* RoleName(Role r) {
  return kRoleNames[static_cast<int>(r)];
}
inline std::optional<Role> ParseRole(std::string_view name) {
  return detail::ParseName<Role>(kRoleNames, name);
}
inline const char* SubjectKindName(SubjectKind k) {
  return kSubjectKindNames[static_cast<int>(k)];
}
inline std::optional<SubjectKind> ParseSubjectKind(std::string_view name) {
  return detail::ParseName<SubjectKind>(kSubjectKindNames, name);
}
inline const char* ExportFormatName(ExportFormat f) {
  return kExportFormatNames[static_cast<int>(f)];
}
inline std::optional<ExportFormat> ParseExportFormat(std::string_view name) {
  return detail::ParseName<ExportFormat>(kExportFormatNames, name);
}

}  // namespace vsurg::db
