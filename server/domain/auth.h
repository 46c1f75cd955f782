// Who may call what (the control plane's permission matrix), and the bearer-token header.
//
// Authentication (a token in `authorization: Bearer …`, looked up by hash in the store) decides
// UNAUTHENTICATED; this matrix decides PERMISSION_DENIED. Row ownership (a trainee sees only
// their own sessions, an evaluator submits only as themself) is checked in the service, after
// the matrix.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "db/store.h"

namespace vsurg::server {

enum class Method {
  kSessionCreate,
  kSessionStart,
  kSessionStop,
  kSessionGet,
  kSessionList,
  kMonitorWatch,
  kEvaluationSubmit,
  kEvaluationReport,
  kEvaluationTrainingEffect,
  kAdminCreateUser,
  kAdminIssueToken,
  kAdminRevokeTokens,
  kAdminSetDisabled,
  kAdminListUsers,
  kAdminPutWeightSet,
  kAdminListWeightSets,
  kAdminExport,
  kAdminBackup,
  kSessionListScenes,
  kSessionJoin,
  kTrainingCreateCourse,
  kTrainingCreateCohort,
  kTrainingEnrol,
  kTrainingSetExpert,
  kTrainingProgress,
  kTrainingNext,
  kTrainingListCourses,
  kTrainingUpdateExercise,
  kTrainingListCohorts,
  kTrainingAddMembers,
  kTrainingCurve,
  kOpsMetrics,             // GET /api/v1/metrics (HTTP only): the Prometheus scrape
  kSessionJoinInstructor,  // SessionService/Join with ROLE_INSTRUCTOR (four-handed training)
  kSessionGuide,
  kCount
};

const char* MethodName(Method m);
bool RoleMay(db::Role role, Method m);

// "Bearer <token>" (scheme case-insensitive, one space) → the token; nullopt when malformed.
std::optional<std::string_view> BearerToken(std::string_view authorization);

// Is the host of `listen` (host:port) a loopback address (127.0.0.0/8, ::1, localhost)?
// Plaintext transports (gRPC, HTTP) listen only there unless allowed explicitly.
bool IsLoopbackHost(const std::string& listen);

}  // namespace vsurg::server
