#include "server/domain/training.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include <nlohmann/json.hpp>

#include "common/core/time.h"
#include "server/domain/scene_catalog.h"

namespace vsurg::server {
namespace {

using nlohmann::json;
using scoring::ProficiencyMetrics;

constexpr int64_t kIdleUs = 14LL * 86'400 * 1'000'000;  // no attempt for 14 days: stalled

Error NotYours(const std::string& what) {
  return Error{ErrorCode::kPermissionDenied, what, ""};
}

bool IsAdmin(const db::Principal& p) {
  return p.role == db::Role::kAdmin;
}

Status CheckMembers(const std::vector<std::string>& members) {
  if (members.size() > 1000) return InvalidArgument("members", "at most 1000 at once");
  for (const std::string& m : members)
    if (m.empty() || m.size() > 128)
      return InvalidArgument("members", "a trainee name has 1 to 128 characters");
  return Status::Ok();
}

// --- targets ---

std::vector<double> MetricValues(const std::vector<db::AttemptRow>& rows,
                                 const scoring::MetricDef& def) {
  std::vector<double> out;
  for (const db::AttemptRow& r : rows) {
    const double v = scoring::MetricValue(r.metrics, def);
    if (std::isfinite(v)) out.push_back(v);
  }
  return out;
}

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}

double SampleSd(const std::vector<double>& v, double mean) {
  if (v.size() < 2) return 0;
  double ss = 0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return std::sqrt(ss / static_cast<double>(v.size() - 1));
}

// An exercise's row with its spec parsed and its targets resolved against the experts' trials.
// `scenes`: the catalogue's listing when the caller has one (a course lists it once).
Expected<ExerciseView> Resolve(Domain& d, const db::ExerciseRecord& e,
                               const SceneListing* scenes = nullptr) {
  ExerciseView v;
  v.record = e;
  auto spec = ParseExerciseSpec(e.spec_json);
  if (!spec.ok())
    return Error{ErrorCode::kIoError,
                 "exercise " + std::to_string(e.id) + "'s stored spec: " + spec.error().message,
                 "spec"};
  v.spec = std::move(spec).value();
  std::optional<SceneListing> listed;
  if (!scenes) {
    auto l = d.scenes.List();
    if (!l.ok()) return l.error();
    scenes = &listed.emplace(std::move(l).value());
  }
  for (const SceneInfo& info : scenes->scenes)
    if (info.name == e.scene) {
      auto task = scoring::ApplyTaskSettings(info.spec, v.spec.task);
      if (task.ok()) v.task = *task;
    }
  std::vector<db::AttemptRow> experts;
  bool loaded = false;
  for (const TargetSpec& t : v.spec.targets) {
    ResolvedTarget r{t.metric, t.value, !t.value.has_value(), 0};
    if (!t.value) {
      if (!loaded) {
        auto rows = d.store.LoadExpertAttempts(e.scene, v.spec.task.empty() ? 0 : e.id);
        if (!rows.ok()) return rows.error();
        experts = std::move(rows).value();
        loaded = true;
      }
      const scoring::MetricDef* def = scoring::FindMetric(t.metric);
      const std::vector<double> values = MetricValues(experts, *def);
      r.expert_trials = static_cast<int>(values.size());
      auto bench = scoring::ExpertBenchmark(values, def->better, v.spec.benchmark, v.spec.k);
      if (bench.ok()) r.value = *bench;
    }
    v.ready = v.ready && r.value.has_value();
    v.targets.push_back(std::move(r));
  }
  return v;
}

Expected<CourseView> ResolveCourse(Domain& d, db::CourseRecord c) {
  CourseView v;
  auto scenes = d.scenes.List();
  if (!scenes.ok()) return scenes.error();
  for (const db::ExerciseRecord& e : c.exercises) {
    auto ev = Resolve(d, e, &*scenes);
    if (!ev.ok()) return ev.error();
    v.exercises.push_back(std::move(ev).value());
  }
  v.record = std::move(c);
  return v;
}

// One trainee's progress through a course, from their attempts (oldest first, any exercise).
TraineeProgress Evaluate(const CourseView& course, const std::string& trainee,
                         const std::vector<const db::AttemptRow*>& attempts, int64_t now_us) {
  TraineeProgress tp;
  tp.trainee = trainee;
  bool previous_reached = true;
  tp.completed = !course.exercises.empty();
  for (const ExerciseView& ex : course.exercises) {
    ExerciseProgress ep;
    ep.exercise_id = ex.record.id;
    std::vector<scoring::Attempt> mine;
    mine.reserve(attempts.size());
    for (const db::AttemptRow* a : attempts) {
      if (a->exercise_id != ex.record.id) continue;
      mine.push_back({a->ended_us, a->metrics});
      ep.attempt_us.push_back(a->ended_us);
      ep.attempt_sessions.push_back(a->session_id);
    }
    ep.progress = scoring::EvaluateProgress(mine, ex.Targets(), ex.spec.rule, now_us);
    if (!ex.ready)  // a target still waits for the experts: nothing passes yet
      for (scoring::AttemptCheck& c : ep.progress.checks) c.passed = false;
    if (!ex.ready) {
      ep.progress.passes = ep.progress.streak = 0;
      ep.progress.proficient_at.reset();
    }
    ep.last_us = ep.attempt_us.empty() ? 0 : ep.attempt_us.back();
    if (ep.progress.proficient_at) ep.proficient_us = ep.attempt_us[*ep.progress.proficient_at - 1];
    if (!ep.progress.checks.empty())
      for (const scoring::TargetCheck& c : ep.progress.checks.back().checks)
        if (!c.met) ep.to_improve.emplace_back(c.metric);
    const bool open = previous_reached || !ex.spec.unlock_in_order;
    int failures_at_end = 0;
    for (auto it = ep.progress.checks.rbegin(); it != ep.progress.checks.rend() && !it->passed;
         ++it)
      ++failures_at_end;
    if (ep.progress.proficient_at)
      ep.state = CellState::kProficient;
    else if (!open)
      ep.state = CellState::kLocked;
    else if (ep.progress.attempts == 0)
      ep.state = CellState::kNotStarted;
    else if (failures_at_end >= std::max(1, ex.spec.stall_after) || now_us - ep.last_us > kIdleUs)
      ep.state = CellState::kStalled;
    else
      ep.state = CellState::kTraining;
    if (ep.state == CellState::kStalled) tp.stalled = true;
    if (!tp.next_exercise && open && ep.state != CellState::kProficient)
      tp.next_exercise = ex.record.id;
    previous_reached = ep.state == CellState::kProficient;
    tp.completed = tp.completed && ep.state == CellState::kProficient;
    tp.exercises.push_back(std::move(ep));
  }
  return tp;
}

// The course's trainees' progress from one load of their attempts.
CourseProgress EvaluateAll(CourseView course, const std::vector<std::string>& trainees,
                           const std::vector<db::AttemptRow>& rows, int64_t now_us) {
  std::map<std::string, std::vector<const db::AttemptRow*>> by_trainee;
  for (const std::string& t : trainees) by_trainee[t];
  // Rows come trainee by trainee within each exercise (db::Store::LoadAttempts): the last
  // trainee's list is reused while the name repeats.
  auto it = by_trainee.end();
  for (const db::AttemptRow& r : rows) {
    if (it == by_trainee.end() || it->first != r.trainee) it = by_trainee.find(r.trainee);
    if (it != by_trainee.end()) it->second.push_back(&r);
  }
  CourseProgress out;
  for (const auto& [name, attempts] : by_trainee)
    out.trainees.push_back(Evaluate(course, name, attempts, now_us));
  out.course = std::move(course);
  return out;
}

// One trainee's progress through the course `course_id` (its exercises resolved now), and the
// trials it came from when `rows` is given.
Expected<CourseProgress> OneTraineeProgress(Domain& d, int64_t course_id,
                                            const std::string& trainee,
                                            std::vector<db::AttemptRow>* rows = nullptr) {
  auto course = d.store.GetCourse(course_id);
  if (!course.ok()) return course.error();
  auto view = ResolveCourse(d, std::move(course).value());
  if (!view.ok()) return view.error();
  auto loaded = d.store.LoadAttempts(course_id, trainee, 0);
  if (!loaded.ok()) return loaded.error();
  CourseProgress out = EvaluateAll(std::move(view).value(), {trainee}, *loaded, NowUs());
  if (rows) *rows = std::move(loaded).value();
  return out;
}

// The cohort, when it is `p`'s (its instructor, or an admin).
Expected<db::CohortRecord> CohortFor(Domain& d, const db::Principal& p, int64_t cohort_id) {
  auto c = d.store.GetCohort(cohort_id);
  if (!c.ok()) return c.error();
  if (!IsAdmin(p) && c->instructor != p.name)
    return NotYours("cohort " + std::to_string(cohort_id) + " is another instructor's");
  return c;
}

// The cohort, when `p` may read its progress (the matrix, then not a trainee, then theirs).
Expected<db::CohortRecord> CohortToRead(Domain& d, const db::Principal& p, int64_t cohort_id) {
  if (Status s = Permit(p, Method::kTrainingProgress); !s.ok()) return s.error();
  if (p.role == db::Role::kTrainee) return NotYours("a trainee sees only their own progress");
  return CohortFor(d, p, cohort_id);
}

const ExerciseView* FindExercise(const CourseView& c, int64_t id) {
  for (const ExerciseView& e : c.exercises)
    if (e.record.id == id) return &e;
  return nullptr;
}

// A trainee reads a course (its exercises, their targets, their curves) only when enrolled in it,
// on their own or with a cohort; the other roles are not asked.
Status TraineeEnrolled(Domain& d, const db::Principal& p, int64_t course_id) {
  if (p.role != db::Role::kTrainee) return Status::Ok();
  auto enrolments = d.store.ListEnrolments(p.name);
  if (!enrolments.ok()) return enrolments.error();
  if (std::none_of(enrolments->begin(), enrolments->end(),
                   [&](const db::EnrolmentRecord& e) { return e.course_id == course_id; }))
    return NotYours("course " + std::to_string(course_id) + " is not one of yours");
  return Status::Ok();
}

// May `p` read `trainee`'s progress? A trainee only their own.
Status MayRead(const db::Principal& p, const std::string& trainee) {
  if (p.role == db::Role::kTrainee && trainee != p.name)
    return NotYours("a trainee sees only their own progress");
  return Status::Ok();
}

bool EnrolmentActive(const db::EnrolmentRecord& e, int64_t now_us) {
  return e.starts_us <= now_us && (!e.ends_us || *e.ends_us > now_us);
}

}  // namespace

// --- the spec: parsed and written in server/domain/exercise_spec.cpp ---

std::vector<scoring::Target> ExerciseView::Targets() const {
  std::vector<scoring::Target> out;
  for (const ResolvedTarget& t : targets)
    if (t.value) out.push_back({t.metric, *t.value});
  return out;
}

const char* CellStateName(CellState s) {
  switch (s) {
    case CellState::kLocked:
      return "locked";
    case CellState::kNotStarted:
      return "not_started";
    case CellState::kTraining:
      return "training";
    case CellState::kStalled:
      return "stalled";
    case CellState::kProficient:
      return "proficient";
  }
  return "locked";
}

// --- courses, cohorts, enrolments, experts ---

Expected<CourseView> CreateCourse(Domain& d, const db::Principal& p, const std::string& name,
                                  const std::string& description,
                                  const std::vector<NewExercise>& exercises) {
  if (Status s = Permit(p, Method::kTrainingCreateCourse); !s.ok()) return s.error();
  auto scenes = d.scenes.List();
  if (!scenes.ok()) return scenes.error();
  db::CourseRecord c;
  c.name = name;
  c.description = description;
  c.owner = p.name;
  for (size_t i = 0; i < exercises.size(); ++i) {
    const NewExercise& e = exercises[i];
    if (Status s =
            CheckTaskFits(scenes->scenes, e.scene, e.spec, "exercises[" + std::to_string(i) + "]");
        !s.ok())
      return s.error();
    c.exercises.push_back({0, 0, 0, e.title, e.scene, ExerciseSpecJson(e.spec)});
  }
  auto made = d.store.CreateCourse(c);
  if (!made.ok()) return made.error();
  return ResolveCourse(d, std::move(made).value());
}

Expected<std::vector<CourseView>> ListCourses(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kTrainingListCourses); !s.ok()) return s.error();
  auto list = d.store.ListCourses();
  if (!list.ok()) return list.error();
  std::vector<int64_t> mine;  // a trainee sees the courses they are enrolled in
  if (p.role == db::Role::kTrainee) {
    auto enrolments = d.store.ListEnrolments(p.name);
    if (!enrolments.ok()) return enrolments.error();
    for (const db::EnrolmentRecord& e : *enrolments) mine.push_back(e.course_id);
  }
  std::vector<CourseView> out;
  for (db::CourseRecord& c : *list) {
    if (p.role == db::Role::kTrainee && std::find(mine.begin(), mine.end(), c.id) == mine.end())
      continue;
    auto v = ResolveCourse(d, std::move(c));
    if (!v.ok()) return v.error();
    out.push_back(std::move(v).value());
  }
  return out;
}

Expected<CourseView> GetCourse(Domain& d, const db::Principal& p, int64_t id) {
  if (Status s = Permit(p, Method::kTrainingListCourses); !s.ok()) return s.error();
  auto c = d.store.GetCourse(id);
  if (!c.ok()) return c.error();
  if (Status s = TraineeEnrolled(d, p, id); !s.ok()) return s.error();
  return ResolveCourse(d, std::move(c).value());
}

Status SetExerciseSpec(Domain& d, const db::Principal& p, int64_t exercise_id,
                       const ExerciseSpec& spec) {
  if (Status s = Permit(p, Method::kTrainingUpdateExercise); !s.ok()) return s;
  auto e = d.store.GetExercise(exercise_id);
  if (!e.ok()) return e.error();
  auto c = d.store.GetCourse(e->course_id);
  if (!c.ok()) return c.error();
  if (!IsAdmin(p) && c->owner != p.name)
    return NotYours("course '" + c->name + "' is another instructor's");
  auto scenes = d.scenes.List();
  if (!scenes.ok()) return scenes.error();
  if (Status s = CheckTaskFits(scenes->scenes, e->scene, spec, "exercise"); !s.ok()) return s;
  return d.store.SetExerciseSpec(exercise_id, ExerciseSpecJson(spec));
}

Expected<db::CohortRecord> CreateCohort(Domain& d, const db::Principal& p, const std::string& name,
                                        const std::string& instructor,
                                        const std::vector<std::string>& members) {
  if (Status s = Permit(p, Method::kTrainingCreateCohort); !s.ok()) return s.error();
  if (Status s = CheckMembers(members); !s.ok()) return s.error();
  std::string who = instructor.empty() ? p.name : instructor;
  if (!IsAdmin(p) && who != p.name) return NotYours("an instructor makes cohorts for themself");
  return d.store.CreateCohort(name, who, members);
}

Status AddCohortMembers(Domain& d, const db::Principal& p, int64_t cohort_id,
                        const std::vector<std::string>& members) {
  if (Status s = Permit(p, Method::kTrainingAddMembers); !s.ok()) return s;
  if (Status s = CheckMembers(members); !s.ok()) return s;
  auto c = CohortFor(d, p, cohort_id);
  if (!c.ok()) return c.error();
  return d.store.AddCohortMembers(cohort_id, members);
}

Expected<std::vector<db::CohortRecord>> ListCohorts(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kTrainingListCohorts); !s.ok()) return s.error();
  auto list = d.store.ListCohorts();
  if (!list.ok()) return list.error();
  if (!IsAdmin(p))
    std::erase_if(*list, [&](const db::CohortRecord& c) { return c.instructor != p.name; });
  return list;
}

Expected<db::EnrolmentRecord> Enrol(Domain& d, const db::Principal& p, db::EnrolmentRecord e) {
  if (Status s = Permit(p, Method::kTrainingEnrol); !s.ok()) return s.error();
  if (e.cohort_id) {
    auto c = CohortFor(d, p, *e.cohort_id);
    if (!c.ok()) return c.error();
  }
  if (e.starts_us == 0) e.starts_us = NowUs();
  return d.store.Enrol(e);
}

Status SetExpert(Domain& d, const db::Principal& p, const std::string& trainee, bool expert) {
  if (Status s = Permit(p, Method::kTrainingSetExpert); !s.ok()) return s;
  return d.store.SetExpert(trainee, expert);
}

Expected<std::vector<std::string>> ListExperts(Domain& d, const db::Principal& p) {
  if (Status s = Permit(p, Method::kTrainingSetExpert); !s.ok()) return s.error();
  return d.store.ListExperts();
}

// --- progress ---

Expected<CourseProgress> CohortProgress(Domain& d, const db::Principal& p, int64_t cohort_id,
                                        int64_t course_id, GridPage page) {
  if (page.limit < 1 || page.limit > kMaxGridTrainees)
    return InvalidArgument("limit", "trainees per page: 1 to " + std::to_string(kMaxGridTrainees));
  if (page.offset < 0) return InvalidArgument("offset", "0 or more");
  auto cohort = CohortToRead(d, p, cohort_id);
  if (!cohort.ok()) return cohort.error();
  auto course = d.store.GetCourse(course_id);
  if (!course.ok()) return course.error();
  auto view = ResolveCourse(d, std::move(course).value());
  if (!view.ok()) return view.error();
  // The page's members (sorted by name, db::CohortRecord): their attempts only.
  const std::vector<std::string>& all = cohort->members;
  const size_t first = static_cast<size_t>(std::min<int64_t>(page.offset, std::ssize(all)));
  const size_t last = std::min(all.size(), first + static_cast<size_t>(page.limit));
  const std::vector<std::string> members(all.begin() + first, all.begin() + last);
  std::vector<db::AttemptRow> rows;
  if (!members.empty()) {
    auto loaded = d.store.LoadAttempts(course_id, "", cohort_id, 0,
                                       db::NameRange{members.front(), members.back()});
    if (!loaded.ok()) return loaded.error();
    rows = std::move(loaded).value();
  }
  CourseProgress out = EvaluateAll(std::move(view).value(), members, rows, NowUs());
  out.offset = static_cast<int64_t>(first);
  out.total_trainees = std::ssize(all);
  return out;
}

Expected<std::vector<CourseProgress>> TraineeCourses(Domain& d, const db::Principal& p,
                                                     const std::string& trainee) {
  if (Status s = Permit(p, Method::kTrainingProgress); !s.ok()) return s.error();
  if (trainee.empty()) return InvalidArgument("trainee", "required");
  if (Status s = MayRead(p, trainee); !s.ok()) return s.error();
  auto enrolments = d.store.ListEnrolments(trainee);
  if (!enrolments.ok()) return enrolments.error();
  std::vector<CourseProgress> out;
  std::vector<int64_t> seen;
  for (const db::EnrolmentRecord& e : *enrolments) {
    if (std::find(seen.begin(), seen.end(), e.course_id) != seen.end()) continue;
    seen.push_back(e.course_id);
    auto progress = OneTraineeProgress(d, e.course_id, trainee);
    if (!progress.ok()) return progress.error();
    out.push_back(std::move(progress).value());
  }
  return out;
}

Expected<LearningCurve> TraineeCurve(Domain& d, const db::Principal& p, const std::string& trainee,
                                     int64_t exercise_id) {
  if (Status s = Permit(p, Method::kTrainingCurve); !s.ok()) return s.error();
  if (trainee.empty()) return InvalidArgument("trainee", "required");
  if (Status s = MayRead(p, trainee); !s.ok()) return s.error();
  auto e = d.store.GetExercise(exercise_id);
  if (!e.ok()) return e.error();
  // A trainee sees the exercises of their own courses only, as on the course page.
  if (Status s = TraineeEnrolled(d, p, e->course_id); !s.ok()) return s.error();
  std::vector<db::AttemptRow> rows;
  auto all = OneTraineeProgress(d, e->course_id, trainee, &rows);
  if (!all.ok()) return all.error();
  LearningCurve out;
  out.trainee = trainee;
  for (const ExerciseProgress& ep : all->trainees.front().exercises)
    if (ep.exercise_id == exercise_id) out.progress = ep;
  out.exercise = *FindExercise(all->course, exercise_id);
  for (const db::AttemptRow& r : rows)
    if (r.exercise_id == exercise_id) out.attempts.push_back(r);
  std::vector<bool> failures;
  for (const scoring::AttemptCheck& c : out.progress.progress.checks) failures.push_back(!c.passed);
  auto cusum = scoring::Cusum(failures, out.exercise.spec.cusum);
  if (!cusum.ok()) return cusum.error();
  out.cusum = std::move(cusum).value();
  out.course = std::move(all->course);
  return out;
}

Expected<CohortCurve> CohortCurveOf(Domain& d, const db::Principal& p, int64_t cohort_id,
                                    int64_t exercise_id) {
  auto cohort = CohortToRead(d, p, cohort_id);
  if (!cohort.ok()) return cohort.error();
  auto e = d.store.GetExercise(exercise_id);
  if (!e.ok()) return e.error();
  auto view = Resolve(d, *e);
  if (!view.ok()) return view.error();
  auto rows = d.store.LoadAttempts(e->course_id, "", cohort_id, exercise_id);
  if (!rows.ok()) return rows.error();
  auto experts = d.store.LoadExpertAttempts(e->scene, view->spec.task.empty() ? 0 : e->id);
  if (!experts.ok()) return experts.error();
  // Each member's attempts at the exercise, in order.
  std::map<std::string, std::vector<const db::AttemptRow*>> by_trainee;
  for (const db::AttemptRow& r : *rows)
    if (r.exercise_id == exercise_id) by_trainee[r.trainee].push_back(&r);
  CohortCurve out;
  for (const TargetSpec& t : view->spec.targets) {
    const scoring::MetricDef* def = scoring::FindMetric(t.metric);
    MetricCurve mc;
    mc.metric = t.metric;
    for (const ResolvedTarget& rt : view->targets)
      if (rt.metric == t.metric) mc.target = rt.value;
    for (size_t n = 0;; ++n) {
      std::vector<double> at_n;
      bool any = false;
      for (const auto& [name, list] : by_trainee) {
        if (n >= list.size()) continue;
        any = true;
        const double v = scoring::MetricValue(list[n]->metrics, *def);
        if (std::isfinite(v)) at_n.push_back(v);
      }
      if (!any) break;
      const double mean = Mean(at_n);
      mc.points.push_back(
          {static_cast<int>(n + 1), static_cast<int>(at_n.size()), mean, SampleSd(at_n, mean)});
    }
    const std::vector<double> values = MetricValues(*experts, *def);
    mc.expert_trials = static_cast<int>(values.size());
    mc.expert_mean = Mean(values);
    mc.expert_sd = SampleSd(values, mc.expert_mean);
    out.metrics.push_back(std::move(mc));
  }
  out.exercise = std::move(view).value();
  return out;
}

// --- the station ---

Expected<NextExercise> NextExerciseOf(Domain& d, const db::Principal& p, std::string trainee) {
  if (Status s = Permit(p, Method::kTrainingNext); !s.ok()) return s.error();
  if (trainee.empty()) trainee = p.name;
  if (Status s = MayRead(p, trainee); !s.ok()) return s.error();
  auto courses = TraineeCourses(d, p, trainee);
  if (!courses.ok()) return courses.error();
  auto enrolments = d.store.ListEnrolments(trainee);
  if (!enrolments.ok()) return enrolments.error();
  const int64_t now = NowUs();
  NextExercise out;
  for (CourseProgress& c : *courses) {
    const bool active =
        std::any_of(enrolments->begin(), enrolments->end(), [&](const db::EnrolmentRecord& e) {
          return e.course_id == c.course.record.id && EnrolmentActive(e, now);
        });
    const TraineeProgress& tp = c.trainees.front();
    if (!active || !tp.next_exercise) continue;
    for (const ExerciseProgress& ep : tp.exercises) {
      if (ep.state == CellState::kLocked || ep.state == CellState::kProficient) continue;
      out.open.push_back(ep.exercise_id);
      if (ep.exercise_id == *tp.next_exercise) out.progress = ep;
    }
    out.exercise_id = tp.next_exercise;
    out.course = std::move(c.course);
    break;
  }
  return out;
}

namespace {
// A session for an attempt at `e`: its scene with the exercise's task settings, marked as an
// attempt (or stopped again if it cannot be marked).
Expected<CreatedSession> StartAttempt(Domain& d, const std::string& trainee,
                                      const db::ExerciseRecord& e,
                                      const scoring::TaskSettings& task) {
  auto created = d.sessions.Create(trainee, e.scene, task);
  if (!created.ok()) return created.error();
  if (Status s = d.store.SetSessionExercise(created->record.id, e.id); !s.ok()) {
    (void)d.sessions.Stop(static_cast<uint64_t>(created->record.id),
                          "could not be marked as an attempt");
    return s.error();
  }
  return created;
}
}  // namespace

Expected<CreatedSession> CreateExerciseSession(Domain& d, const db::Principal& p,
                                               std::string trainee, int64_t exercise_id) {
  if (Status s = Permit(p, Method::kSessionCreate); !s.ok()) return s.error();
  if (trainee.empty()) trainee = p.name;
  if (p.role == db::Role::kTrainee && trainee != p.name)
    return NotYours("a trainee creates sessions only for themself");
  auto e = d.store.GetExercise(exercise_id);
  if (!e.ok()) return e.error();
  auto spec = ParseExerciseSpec(e->spec_json);
  if (!spec.ok()) return spec.error();
  // An expert runs any exercise (their trials set its benchmark), enrolled or not.
  auto experts = d.store.ListExperts();
  if (!experts.ok()) return experts.error();
  if (std::find(experts->begin(), experts->end(), trainee) != experts->end())
    return StartAttempt(d, trainee, *e, spec->task);
  auto enrolments = d.store.ListEnrolments(trainee);
  if (!enrolments.ok()) return enrolments.error();
  const int64_t now = NowUs();
  if (std::none_of(enrolments->begin(), enrolments->end(), [&](const db::EnrolmentRecord& r) {
        return r.course_id == e->course_id && EnrolmentActive(r, now);
      }))
    return Error{
        ErrorCode::kFailedPrecondition,
        trainee + " is not enrolled (now) in the course of exercise " + std::to_string(exercise_id),
        "exercise"};
  auto cp = OneTraineeProgress(d, e->course_id, trainee);
  if (!cp.ok()) return cp.error();
  for (const ExerciseProgress& ep : cp->trainees.front().exercises) {
    if (ep.exercise_id != exercise_id) continue;
    if (ep.state == CellState::kLocked)
      return Error{ErrorCode::kFailedPrecondition,
                   "exercise '" + e->title + "' opens once the one before it is reached",
                   "exercise"};
    if (!ep.progress.may_attempt)
      return Error{ErrorCode::kResourceExhausted,
                   "today's attempts at '" + e->title + "' are used up; try tomorrow", "exercise"};
  }
  return StartAttempt(d, trainee, *e, spec->task);
}

Expected<SessionWithTargets> GetSessionWithTargets(Domain& d, const db::Principal& p,
                                                   uint64_t session_id) {
  auto v = GetSession(d, p, session_id);  // the reader's rights
  if (!v.ok()) return v.error();
  SessionWithTargets out{std::move(v).value(), std::nullopt};
  if (!out.view.metrics) return out;
  auto exercise_id = d.store.SessionExercise(static_cast<int64_t>(session_id));
  if (!exercise_id.ok()) return exercise_id.error();
  if (*exercise_id == 0) return out;
  auto e = d.store.GetExercise(*exercise_id);
  if (!e.ok()) return e.error();
  auto view = Resolve(d, *e);
  if (!view.ok()) return view.error();
  scoring::AttemptCheck check = scoring::CheckAttempt(*out.view.metrics, view->Targets());
  check.passed = check.passed && view->ready;
  out.targets = std::move(check);
  return out;
}

// --- exports (the writing: server/domain/training_export.cpp) ---

Status MayExportProgress(Domain& d, const db::Principal& p, int64_t course_id, int64_t cohort_id) {
  if (cohort_id != 0) {
    auto cohort = CohortToRead(d, p, cohort_id);
    if (!cohort.ok()) return cohort.error();
    if (course_id == 0) return InvalidArgument("course", "a cohort's progress is in one course");
    auto course = d.store.GetCourse(course_id);
    return course.ok() ? Status::Ok() : Status(course.error());
  }
  if (Status s = Permit(p, Method::kTrainingProgress); !s.ok()) return s;
  if (p.role != db::Role::kTrainee)
    return InvalidArgument("cohort", "an instructor exports one cohort's progress at a time");
  return Status::Ok();
}

}  // namespace vsurg::server
