// The dashboard's JSON views of the domain's records: sessions, users, the training programme's
// courses, exercises, checks and progress, trial metrics. Positions in millimetres, non-finite
// numbers as null (JSON has no NaN). Private to server/http.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/geometry/mesh.h"
#include "common/scoring/metrics.h"
#include "db/store.h"
#include "server/domain/api.h"
#include "server/domain/training.h"

namespace vsurg::server::http {

using nlohmann::json;

std::string Iso(int64_t us);

json RecordJson(const db::SessionRecord& r);

json ViewJson(const SessionView& v);

json UserJson(const db::UserRecord& u);

double Finite(double x);

// Positions in metres as one flat array of millimetres to 0.01 mm (x, y, z, x, …): the form the
// page's 3D view reads for the rest surface and for the moved vertices alike.
json Millimetres(const std::vector<geometry::Vec3>& positions);

json FiniteOrNull(double x);

// A task in the units a trainee reads (degrees of twist or millimetres of press depth).
json TaskJson(const scoring::TaskSpec& t);

json ExerciseJson(const ExerciseView& e);

json CourseJson(const CourseView& c);

json ChecksJson(const scoring::AttemptCheck& a);

json ProgressJson(const ExerciseProgress& ep);

// `compact`: the grid's cells (state and counts only; 2,000 of them for 200 trainees).
json TraineeProgressJson(const TraineeProgress& t, bool compact = false);

json MetricsJson(const scoring::TrialMetrics& m);

}  // namespace vsurg::server::http
