// The training programme: courses of exercises with proficiency targets, cohorts of
// trainees, enrolments, progress, learning curves and CUSUM, the station's next exercise, and the
// progress exports. The rules over trial metrics are common/scoring/proficiency.h; the rows are
// db::Store's; this file applies them with the caller's rights, as server/domain/api.h does.
//
// Who may do what (after the permission matrix, server/domain/auth.cpp):
//   courses       an instructor makes them and sets the targets of their own; an admin of any;
//                 every instructor may read every course (and assign it)
//   cohorts       an instructor makes theirs, adds members and enrols them; an admin any
//   experts       instructors and admins mark trainees as experts (their trials set benchmarks)
//   progress      a trainee reads their own only; an instructor their cohorts' and any single
//                 trainee's; an admin all
//
// An exercise's targets are fixed values or "from experts": the benchmark of the expert
// trainees' recorded trials on the exercise's scene (mean ± k·SD or the best quartile), computed
// again at every read, so it follows the experts as they train. With fewer than two expert
// trials a target is not ready and no attempt at the exercise can pass yet.
//
// An exercise's state for a trainee: locked (the previous one is not reached yet, when the
// course unlocks in order), not started, training, stalled (the last `stall_after` attempts all
// failed, or none for 14 days), or proficient (the rule's streak reached, at attempt n).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/proficiency.h"
#include "db/store.h"
#include "server/domain/api.h"

namespace vsurg::server {

struct TargetSpec {
  std::string metric;           // a scoring::ProficiencyMetrics() name
  std::optional<double> value;  // fixed; nullopt: the experts' benchmark
};

struct ExerciseSpec {
  std::vector<TargetSpec> targets;
  scoring::ProgressionRule rule;
  bool unlock_in_order = true;  // open once the previous exercise is reached
  scoring::BenchmarkMode benchmark = scoring::BenchmarkMode::kMeanSd;
  double k = 1.0;  // SDs of the mean ± k·SD benchmark
  scoring::CusumParams cusum;
  int stall_after = 5;  // failed attempts in a row that flag a trainee as stalled
  // The exercise's own settings of its scene's task (none: the scene's). An exercise that has
  // them takes its expert benchmark from expert trials at this exercise only (experts may run
  // any exercise without an enrolment), since the scene's other trials were a different task.
  scoring::TaskSettings task;
};
// The spec's JSON (stored in the exercise's row, and what the API takes):
//   {"targets":[{"metric":"peak_force_n","value":2.5},{"metric":"completion_time_s",
//    "from_experts":true}], "consecutive":2, "max_attempts_per_day":0, "unlock_in_order":true,
//    "benchmark":"mean_sd"|"best_quartile", "k":1, "cusum":{"p0":0.1,"p1":0.3,"alpha":0.05,
//    "beta":0.2}, "stall_after":5, "task":{"target_deg":60,"tolerance_deg":5,"hold_s":2,
//    "force_limit_n":2,"time_limit_s":45}}   (a press: "target_depth_m", "tolerance_m")
// kInvalidArgument naming the field for anything out of range.
Expected<ExerciseSpec> ParseExerciseSpec(std::string_view json);
std::string ExerciseSpecJson(const ExerciseSpec& spec);
struct SceneInfo;  // server/domain/scene_catalog.h
// The exercise's task settings must fit its scene's task (a twist's target on a twist scene, a
// time limit longer than the hold, …); `field` names the exercise in the error.
Status CheckTaskFits(const std::vector<SceneInfo>& scenes, const std::string& scene,
                     const ExerciseSpec& spec, const std::string& field);

struct ResolvedTarget {
  std::string metric;
  std::optional<double> value;  // nullopt: from experts and not ready yet
  bool from_experts = false;
  int expert_trials = 0;  // how many trials it came from
};
struct ExerciseView {
  db::ExerciseRecord record;
  ExerciseSpec spec;
  std::vector<ResolvedTarget> targets;
  bool ready = true;                             // every target has a value
  std::vector<scoring::Target> Targets() const;  // the resolved ones
  // The task a trainee does: the scene's with the exercise's settings (nullopt while the scene
  // does not load).
  std::optional<scoring::TaskSpec> task;
};
struct CourseView {
  db::CourseRecord record;  // its exercises' rows in `exercises` below
  std::vector<ExerciseView> exercises;
};

enum class CellState { kLocked, kNotStarted, kTraining, kStalled, kProficient };
const char* CellStateName(CellState s);

struct ExerciseProgress {
  int64_t exercise_id = 0;
  CellState state = CellState::kLocked;
  scoring::Progress progress;  // with each attempt's checks
  std::vector<int64_t> attempt_us, attempt_sessions;
  int64_t proficient_us = 0, last_us = 0;
  std::vector<std::string> to_improve;  // the targets the last attempt missed
};
struct TraineeProgress {
  std::string trainee;
  std::vector<ExerciseProgress> exercises;  // in the course's order
  std::optional<int64_t> next_exercise;     // the first open one not reached
  bool stalled = false, completed = false;
};
struct CourseProgress {
  CourseView course;
  std::vector<TraineeProgress> trainees;  // by name
  // A cohort's grid is read a page of trainees at a time (GridPage): where this page starts
  // among the cohort's members by name, and how many members there are in all.
  int64_t offset = 0, total_trainees = 0;
};

// A page of a cohort's grid: its members [offset, offset + limit) by name. One request's cost is
// bounded by the page: at most kMaxGridTrainees trainees × the course's exercises, however large
// the cohort (a grid of 2,000 trainees × 64 exercises is eight pages, each a fair turn on the
// read workers).
inline constexpr int64_t kMaxGridTrainees = 250;
struct GridPage {
  int64_t offset = 0;
  int64_t limit = kMaxGridTrainees;  // 1..kMaxGridTrainees
};

// --- courses, cohorts, enrolments, experts ---
struct NewExercise {
  std::string title, scene;
  ExerciseSpec spec;
};
Expected<CourseView> CreateCourse(Domain& d, const db::Principal& p, const std::string& name,
                                  const std::string& description,
                                  const std::vector<NewExercise>& exercises);
Expected<std::vector<CourseView>> ListCourses(Domain& d, const db::Principal& p);
Expected<CourseView> GetCourse(Domain& d, const db::Principal& p, int64_t id);
Status SetExerciseSpec(Domain& d, const db::Principal& p, int64_t exercise_id,
                       const ExerciseSpec& spec);
// `instructor` empty: the caller (an admin may name another instructor).
Expected<db::CohortRecord> CreateCohort(Domain& d, const db::Principal& p, const std::string& name,
                                        const std::string& instructor,
                                        const std::vector<std::string>& members);
Status AddCohortMembers(Domain& d, const db::Principal& p, int64_t cohort_id,
                        const std::vector<std::string>& members);
Expected<std::vector<db::CohortRecord>> ListCohorts(Domain& d, const db::Principal& p);
Expected<db::EnrolmentRecord> Enrol(Domain& d, const db::Principal& p, db::EnrolmentRecord e);
Status SetExpert(Domain& d, const db::Principal& p, const std::string& trainee, bool expert);
Expected<std::vector<std::string>> ListExperts(Domain& d, const db::Principal& p);

// --- progress ---
// The cohort grid: a page of its members × every exercise of the course. A limit outside
// 1..kMaxGridTrainees or a negative offset is kInvalidArgument; an offset past the last member
// gives an empty page.
Expected<CourseProgress> CohortProgress(Domain& d, const db::Principal& p, int64_t cohort_id,
                                        int64_t course_id, GridPage page = {});
// One trainee's courses (their enrolments', in the order enrolled) with their progress.
Expected<std::vector<CourseProgress>> TraineeCourses(Domain& d, const db::Principal& p,
                                                     const std::string& trainee);

struct LearningCurve {
  CourseView course;
  ExerciseView exercise;
  std::string trainee;
  std::vector<db::AttemptRow> attempts;  // oldest first
  ExerciseProgress progress;
  scoring::CusumCurve cusum;
};
Expected<LearningCurve> TraineeCurve(Domain& d, const db::Principal& p, const std::string& trainee,
                                     int64_t exercise_id);

// A metric over attempts across a cohort: at attempt n, the mean and SD of the members who made
// an n-th attempt; beside it the experts' mean and SD of all their trials.
struct CurvePoint {
  int attempt = 0, trainees = 0;
  double mean = 0, sd = 0;
};
struct MetricCurve {
  std::string metric;
  std::vector<CurvePoint> points;
  int expert_trials = 0;
  double expert_mean = 0, expert_sd = 0;
  std::optional<double> target;
};
struct CohortCurve {
  ExerciseView exercise;
  std::vector<MetricCurve> metrics;
};
Expected<CohortCurve> CohortCurveOf(Domain& d, const db::Principal& p, int64_t cohort_id,
                                    int64_t exercise_id);

// --- the station ---
struct NextExercise {
  std::optional<CourseView> course;  // none: not enrolled, or every course reached
  std::optional<int64_t> exercise_id;
  std::vector<int64_t> open;  // exercises the trainee may pick (open, not reached)
  ExerciseProgress progress;  // at the next exercise
};
// `trainee` empty: the caller.
Expected<NextExercise> NextExerciseOf(Domain& d, const db::Principal& p, std::string trainee);
// A session that is an attempt at an exercise the trainee is enrolled in and may attempt now
// (open, under the day's limit): created like CreateSession, then marked as the attempt.
Expected<CreatedSession> CreateExerciseSession(Domain& d, const db::Principal& p,
                                               std::string trainee, int64_t exercise_id);
// A session as its reader sees it (GetSession: read and authorised once) with, when it ended as
// an attempt at an exercise, its checks against that exercise's targets (nullopt: it was no
// attempt at one, or it has not ended).
struct SessionWithTargets {
  SessionView view;
  std::optional<scoring::AttemptCheck> targets;
};
Expected<SessionWithTargets> GetSessionWithTargets(Domain& d, const db::Principal& p,
                                                   uint64_t session_id);

// --- exports: progress per trainee × exercise (csv, jsonl) or xAPI statements (attempted per
// attempt, passed per exercise reached, completed per course reached), one trainee's lines per
// call of `sink` (false: stop, kCancelled) ---
Status ExportProgress(Domain& d, const db::Principal& p, int64_t course_id, int64_t cohort_id,
                      db::ExportFormat format, const std::function<bool(std::string_view)>& sink);
// What ExportProgress would refuse, checked cheaply (the rights and the arguments, no progress
// computed): a transport answers a refusal before it starts a download.
Status MayExportProgress(Domain& d, const db::Principal& p, int64_t course_id, int64_t cohort_id);

}  // namespace vsurg::server
