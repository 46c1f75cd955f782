#include "server/domain/auth.h"

#include <array>
#include <cctype>

namespace vsurg::server {
namespace {

using db::Role;
constexpr uint32_t Bit(Role r) {
  return 1u << static_cast<int>(r);
}
constexpr uint32_t kTrainee = Bit(Role::kTrainee), kInstructor = Bit(Role::kInstructor),
                   kEvaluator = Bit(Role::kEvaluator), kAdmin = Bit(Role::kAdmin);

struct Row {
  const char* name;
  uint32_t roles;
};

// The matrix. Trainees run their own sessions; instructors run and watch anyone's; evaluators
// find sessions to score, submit, and read reports; administrators do everything.
constexpr std::array<Row, static_cast<size_t>(Method::kCount)> kMatrix = {{
    {"SessionService/Create", kTrainee | kInstructor | kAdmin},
    {"SessionService/Start", kTrainee | kInstructor | kAdmin},
    {"SessionService/Stop", kTrainee | kInstructor | kAdmin},
    {"SessionService/Get", kTrainee | kInstructor | kEvaluator | kAdmin},
    {"SessionService/List", kTrainee | kInstructor | kEvaluator | kAdmin},
    {"MonitorService/Watch", kInstructor | kAdmin},
    {"EvaluationService/Submit", kEvaluator | kAdmin},
    {"EvaluationService/Report", kInstructor | kEvaluator | kAdmin},
    {"EvaluationService/TrainingEffect", kInstructor | kEvaluator | kAdmin},
    {"AdminService/CreateUser", kAdmin},
    {"AdminService/IssueToken", kAdmin},
    {"AdminService/RevokeTokens", kAdmin},
    {"AdminService/SetDisabled", kAdmin},
    {"AdminService/ListUsers", kAdmin},
    {"AdminService/PutWeightSet", kAdmin},
    {"AdminService/ListWeightSets", kInstructor | kEvaluator | kAdmin},
    {"AdminService/Export", kAdmin},
    {"AdminService/Backup", kAdmin},
    {"SessionService/ListScenes", kTrainee | kInstructor | kEvaluator | kAdmin},
    // The station's key goes only to the session's own trainee (ownership, in the domain, refuses
    // every other caller, administrators too).
    {"SessionService/Join", kTrainee | kAdmin},
    // The training programme: instructors build courses and cohorts (server/domain/training.h
    // checks that a cohort or course is theirs); trainees read their own progress.
    {"TrainingService/CreateCourse", kInstructor | kAdmin},
    {"TrainingService/CreateCohort", kInstructor | kAdmin},
    {"TrainingService/Enrol", kInstructor | kAdmin},
    {"TrainingService/SetExpert", kInstructor | kAdmin},
    {"TrainingService/Progress", kTrainee | kInstructor | kAdmin},
    {"TrainingService/Next", kTrainee | kInstructor | kAdmin},
    {"TrainingService/ListCourses", kTrainee | kInstructor | kAdmin},
    {"TrainingService/UpdateExercise", kInstructor | kAdmin},
    {"TrainingService/ListCohorts", kInstructor | kAdmin},
    {"TrainingService/AddMembers", kInstructor | kAdmin},
    {"TrainingService/Curve", kTrainee | kInstructor | kAdmin},
    // Operations: the metrics a Prometheus scrape reads (an administrator's token).
    {"Ops/Metrics", kAdmin},
    // Four-handed training: an instructor's station joins a trainee's live session and sets its
    // mode (the domain refuses a session that ended, and one's own).
    {"SessionService/JoinAsInstructor", kInstructor | kAdmin},
    {"SessionService/Guide", kInstructor | kAdmin},
}};

}  // namespace

const char* MethodName(Method m) {
  return kMatrix[static_cast<size_t>(m)].name;
}

bool RoleMay(Role role, Method m) {
  const auto i = static_cast<size_t>(m);
  return i < kMatrix.size() && (kMatrix[i].roles & Bit(role)) != 0;
}

std::optional<std::string_view> BearerToken(std::string_view a) {
  constexpr std::string_view kScheme = "bearer ";
  if (a.size() <= kScheme.size()) return std::nullopt;
  for (size_t i = 0; i < kScheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != kScheme[i]) return std::nullopt;
  std::string_view token = a.substr(kScheme.size());
  for (char c : token)
    if (std::isspace(static_cast<unsigned char>(c)) || c == '\0') return std::nullopt;
  return token;
}

bool IsLoopbackHost(const std::string& listen) {
  std::string host = listen;
  if (!host.empty() && host.front() == '[') {
    host = host.substr(1, host.find(']') - 1);
  } else if (const auto colon = host.rfind(':');
             colon != std::string::npos && host.find(':') == colon) {
    host = host.substr(0, colon);
  }
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace vsurg::server
