// The training programme's progress exports: a cohort's grid (page by page) or a trainee's own
// courses, as CSV (RFC 4180, every text cell formula-safe: common/core/csv.h), JSON lines, or xAPI
// statements (ADL's verbs) for a learning record store.
#include <algorithm>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/csv.h"
#include "common/core/time.h"
#include "common/scoring/xapi.h"
#include "server/domain/training.h"

namespace vsurg::server {
namespace {

using nlohmann::json;

// The progress an export writes: a cohort's, or a trainee's own courses.
Expected<std::vector<CourseProgress>> ProgressToExport(Domain& d, const db::Principal& p,
                                                       int64_t course_id, int64_t cohort_id) {
  std::vector<CourseProgress> parts;
  if (cohort_id != 0) {
    for (GridPage page;; page.offset += page.limit) {  // every page of the cohort
      auto cp = CohortProgress(d, p, cohort_id, course_id, page);
      if (!cp.ok()) return cp.error();
      const bool more = page.offset + page.limit < cp->total_trainees;
      parts.push_back(std::move(cp).value());
      if (!more) break;
    }
  } else if (p.role == db::Role::kTrainee) {
    auto mine = TraineeCourses(d, p, p.name);
    if (!mine.ok()) return mine.error();
    for (CourseProgress& c : *mine)
      if (course_id == 0 || c.course.record.id == course_id) parts.push_back(std::move(c));
  } else {
    return InvalidArgument("cohort", "an instructor exports one cohort's progress at a time");
  }
  return parts;
}

constexpr const char* kProgressCsvHeader =
    "course,exercise_position,exercise,scene,trainee,state,attempts,passes,streak,"
    "proficient_at_attempt,proficient_at,last_attempt_at\r\n";

// One CSV line: a trainee's progress at one exercise. Names an instructor or a trainee typed go
// through csv::AppendText, which quotes them and defuses a leading = + - @ TAB or CR.
void AppendCsvLine(std::string& out, const CourseView& c, const ExerciseView& ex,
                   const std::string& trainee, const ExerciseProgress& ep) {
  const scoring::Progress& pr = ep.progress;
  csv::AppendText(out, c.record.name);
  out += "," + std::to_string(ex.record.position) + ",";
  csv::AppendText(out, ex.record.title);
  out += ",";
  csv::AppendText(out, ex.record.scene);
  out += ",";
  csv::AppendText(out, trainee);
  out += std::string(",") + CellStateName(ep.state) + "," + std::to_string(pr.attempts) + "," +
         std::to_string(pr.passes) + "," + std::to_string(pr.streak) + "," +
         (pr.proficient_at ? std::to_string(*pr.proficient_at) : "") + "," +
         (ep.proficient_us ? IsoTimeUtc(ep.proficient_us) : "") + "," +
         (ep.last_us ? IsoTimeUtc(ep.last_us) : "") + "\r\n";
}

void AppendJsonLine(std::string& out, const json& j) {
  out += j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

void AppendJsonRow(std::string& out, const CourseView& c, const ExerciseView& ex,
                   const std::string& trainee, const ExerciseProgress& ep) {
  const scoring::Progress& pr = ep.progress;
  AppendJsonLine(
      out,
      {{"course", c.record.name},
       {"course_id", c.record.id},
       {"exercise_position", ex.record.position},
       {"exercise", ex.record.title},
       {"exercise_id", ex.record.id},
       {"scene", ex.record.scene},
       {"trainee", trainee},
       {"state", CellStateName(ep.state)},
       {"attempts", pr.attempts},
       {"passes", pr.passes},
       {"streak", pr.streak},
       {"proficient_at_attempt", pr.proficient_at ? json(*pr.proficient_at) : json(nullptr)},
       {"proficient_at", ep.proficient_us ? json(IsoTimeUtc(ep.proficient_us)) : json(nullptr)},
       {"last_attempt_at", ep.last_us ? json(IsoTimeUtc(ep.last_us)) : json(nullptr)}});
}

std::string CourseActivity(const CourseView& c) {
  return "urn:vsurg:course:" + std::to_string(c.record.id);
}

// xAPI (ADL verbs): `attempted` per attempt, `passed` when proficiency was reached.
void AppendXapiStatements(std::string& out, const CourseView& c, const ExerciseView& ex,
                          const std::string& trainee, const ExerciseProgress& ep) {
  const scoring::Progress& pr = ep.progress;
  const std::string activity = CourseActivity(c) + ":exercise:" + std::to_string(ex.record.id);
  const json object = xapi::Activity(activity, ex.record.title, "assessment");
  const json parent = {
      {"contextActivities", {{"parent", {xapi::Activity(CourseActivity(c), c.record.name)}}}}};
  for (size_t k = 0; k < pr.checks.size(); ++k) {
    json st = xapi::Statement("urn:vsurg:attempt:" + std::to_string(ep.attempt_sessions[k]),
                              ep.attempt_us[k], trainee, "attempted", object);
    st["result"] = {{"success", pr.checks[k].passed}};
    st["context"] = parent;
    xapi::AppendLine(out, st);
  }
  if (pr.proficient_at) {
    json st = xapi::Statement(activity + ":passed:" + trainee, ep.proficient_us, trainee, "passed",
                              object);
    st["result"] = {{"success", true}, {"completion", true}};
    st["context"] = parent;
    xapi::AppendLine(out, st);
  }
}

// xAPI `completed` once the trainee is proficient at every exercise of the course.
void AppendXapiCompleted(std::string& out, const CourseView& c, const TraineeProgress& tp) {
  int64_t at = 0;
  for (const ExerciseProgress& ep : tp.exercises) at = std::max(at, ep.proficient_us);
  json st =
      xapi::Statement(CourseActivity(c) + ":completed:" + tp.trainee, at, tp.trainee, "completed",
                      xapi::Activity(CourseActivity(c), c.record.name, "course"));
  st["result"] = {{"completion", true}, {"success", true}};
  xapi::AppendLine(out, st);
}

Status WriteProgress(const std::vector<CourseProgress>& parts, db::ExportFormat format,
                     const std::function<bool(std::string_view)>& sink) {
  // One trainee's lines at a time: an export of 100,000 attempts as xAPI is some 60 MB, never
  // held whole.
  std::string out;
  const auto flush = [&]() -> Status {
    if (!out.empty() && !sink(out))
      return Error{ErrorCode::kUnavailable, "the download was stopped", "export"};
    out.clear();
    return Status::Ok();
  };
  if (format == db::ExportFormat::kCsv) out += kProgressCsvHeader;
  for (const CourseProgress& cp : parts) {
    const CourseView& c = cp.course;
    for (const TraineeProgress& tp : cp.trainees) {
      for (size_t i = 0; i < tp.exercises.size(); ++i) {
        if (format == db::ExportFormat::kCsv)
          AppendCsvLine(out, c, c.exercises[i], tp.trainee, tp.exercises[i]);
        else if (format == db::ExportFormat::kJsonLines)
          AppendJsonRow(out, c, c.exercises[i], tp.trainee, tp.exercises[i]);
        else
          AppendXapiStatements(out, c, c.exercises[i], tp.trainee, tp.exercises[i]);
      }
      if (format == db::ExportFormat::kXapi && tp.completed) AppendXapiCompleted(out, c, tp);
      if (Status s = flush(); !s.ok()) return s;
    }
  }
  return flush();
}

}  // namespace

Status ExportProgress(Domain& d, const db::Principal& p, int64_t course_id, int64_t cohort_id,
                      db::ExportFormat format, const std::function<bool(std::string_view)>& sink) {
  auto parts = ProgressToExport(d, p, course_id, cohort_id);
  if (!parts.ok()) return parts.error();
  return WriteProgress(*parts, format, sink);
}

}  // namespace vsurg::server
