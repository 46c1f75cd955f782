#include <algorithm>
#include <unordered_map>

#include "db/store_impl.h"

// The training programme's rows: courses and their exercises, cohorts and their members,
// enrolments, experts, and the recorded trials the progress is computed from (the rules are in
// server/domain/training.h; the store only keeps).
namespace vsurg::db {

scoring::TrialMetrics ReadTrialMetrics(const Statement& q, int first) {
  scoring::TrialMetrics m;
  m.completed = q.Int(first) != 0;
  m.completion_time = q.Double(first + 1);
  m.task_error = q.Double(first + 2);
  m.peak_force = q.Double(first + 3);
  m.time_over_force_limit = q.Double(first + 4);
  m.path_length = q.Double(first + 5);
  m.rms_jerk = q.Double(first + 6);
  m.overload_events = static_cast<int>(q.Int(first + 7));
  m.duration = q.Double(first + 8);
  m.score = q.Double(first + 9);
  m.raw_score = q.Double(first + 10);
  m.caps = static_cast<uint32_t>(q.Int(first + 11));
  m.link.station_peak_force = q.Double(first + 12);
  m.link.station_time_over_limit = q.Double(first + 13);
  m.link.rtt_ms = q.Double(first + 14);
  m.link.jitter_ms = q.Double(first + 15);
  m.link.loss = q.Double(first + 16);
  m.link.rate_hz = q.Double(first + 17);
  m.guided_share = q.Double(first + 18);
  m.guided_alpha = q.Double(first + 19);
  m.lumps = static_cast<int>(q.Int(first + 20));
  m.lumps_found = static_cast<int>(q.Int(first + 21));
  m.false_marks = static_cast<int>(q.Int(first + 22));
  m.localisation_error = q.Double(first + 23);
  m.coverage = q.Double(first + 24);
  m.mean_force = q.Double(first + 25);
  m.depth_error = q.Double(first + 26);
  m.path_deviation = q.Double(first + 27);
  m.punctures = static_cast<int>(q.Int(first + 28));
  m.extra_punctures = static_cast<int>(q.Int(first + 29));
  m.back_wall_breaches = static_cast<int>(q.Int(first + 30));
  m.lateral_strain = q.Double(first + 31);
  m.cut_deviation_max = q.Double(first + 32);
  m.cut_outside = q.Double(first + 33);
  m.torn_length = q.Double(first + 34);
  m.cut_lifts = static_cast<int>(q.Int(first + 35));
  return m;
}

namespace {

Status CheckName(const std::string& name, const char* field) {
  if (name.empty() || name.size() > 128)
    return InvalidArgument(field, "a name of 1 to 128 characters is required");
  return Status::Ok();
}

Expected<int64_t> UserId(Connection& c, const std::string& name, const char* field) {
  auto id = LookupId(c, "SELECT id FROM users WHERE name = ?1", name);
  if (!id.ok()) return id.error();
  if (!*id) return Error{ErrorCode::kNotFound, "no user '" + name + "'", field};
  return **id;
}

// The trainee row of `name`, made when missing (as a session's trainee is).
Expected<int64_t> TraineeId(Connection& c, const std::string& name) {
  if (Status s = CheckName(name, "members"); !s.ok()) return s.error();
  Status s = RunSql(c, "INSERT INTO trainees(name) VALUES (?1) ON CONFLICT(name) DO NOTHING",
                    [&](Statement& st) { st.Bind(1, name); });
  if (!s.ok()) return s.error();
  auto id = LookupId(c, "SELECT id FROM trainees WHERE name = ?1", name);
  if (!id.ok()) return id.error();
  return **id;
}

Status InsertMembers(Connection& c, int64_t cohort_id, const std::vector<std::string>& members) {
  for (const std::string& m : members) {
    auto tid = TraineeId(c, m);
    if (!tid.ok()) return tid.error();
    Status s = RunSql(c,
                      "INSERT INTO cohort_members(cohort_id, trainee_id) VALUES (?1, ?2) "
                      "ON CONFLICT DO NOTHING",
                      [&](Statement& st) { st.Bind(1, cohort_id).Bind(2, *tid); });
    if (!s.ok()) return s;
  }
  return Status::Ok();
}

// Runs `sql` (bound by `bind`) and hands each row to `row`.
template <class Bind, class Row>
Status ForEachRow(Connection& c, const std::string& sql, Bind&& bind, Row&& row) {
  auto st = c.Prepare(sql);
  if (!st.ok()) return st.error();
  bind(**st);
  for (;;) {
    auto more = (*st)->Step();
    if (!more.ok()) {
      (*st)->Reset();
      return more.error();
    }
    if (!*more) break;
    row(**st);
  }
  (*st)->Reset();
  return Status::Ok();
}

constexpr const char* kCourseColumns =
    "SELECT c.id, c.name, c.description, u.name, c.created_us FROM courses c "
    "JOIN users u ON u.id = c.owner_id ";
constexpr const char* kCohortColumns =
    "SELECT h.id, h.name, u.name, h.created_us FROM cohorts h JOIN users u ON u.id = "
    "h.instructor_id ";

void ReadExercise(const Statement& q, ExerciseRecord& e) {
  e.id = q.Int(0);
  e.course_id = q.Int(1);
  e.position = static_cast<int>(q.Int(2));
  e.title = q.String(3);
  e.scene = q.String(4);
  e.spec_json = q.String(5);
}

// Courses (all, or the one `id`) with their exercises.
Expected<std::vector<CourseRecord>> ReadCourses(Connection& c, int64_t id) {
  std::vector<CourseRecord> out;
  Status s = ForEachRow(
      c, std::string(kCourseColumns) + "WHERE (?1 = 0 OR c.id = ?1) ORDER BY c.name",
      [&](Statement& q) { q.Bind(1, id); },
      [&](const Statement& q) {
        CourseRecord r;
        r.id = q.Int(0);
        r.name = q.String(1);
        r.description = q.String(2);
        r.owner = q.String(3);
        r.created_us = q.Int(4);
        out.push_back(std::move(r));
      });
  if (!s.ok()) return s.error();
  s = ForEachRow(
      c,
      "SELECT id, course_id, position, title, scene, spec_json FROM exercises "
      "WHERE (?1 = 0 OR course_id = ?1) ORDER BY course_id, position",
      [&](Statement& q) { q.Bind(1, id); },
      [&](const Statement& q) {
        ExerciseRecord e;
        ReadExercise(q, e);
        for (CourseRecord& r : out)
          if (r.id == e.course_id) r.exercises.push_back(e);
      });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<CohortRecord>> ReadCohorts(Connection& c, int64_t id) {
  std::vector<CohortRecord> out;
  Status s = ForEachRow(
      c, std::string(kCohortColumns) + "WHERE (?1 = 0 OR h.id = ?1) ORDER BY h.name",
      [&](Statement& q) { q.Bind(1, id); },
      [&](const Statement& q) {
        CohortRecord r;
        r.id = q.Int(0);
        r.name = q.String(1);
        r.instructor = q.String(2);
        r.created_us = q.Int(3);
        out.push_back(std::move(r));
      });
  if (!s.ok()) return s.error();
  s = ForEachRow(
      c,
      "SELECT m.cohort_id, t.name FROM cohort_members m JOIN trainees t ON t.id = m.trainee_id "
      "WHERE (?1 = 0 OR m.cohort_id = ?1) ORDER BY m.cohort_id, t.name",
      [&](Statement& q) { q.Bind(1, id); },
      [&](const Statement& q) {
        const int64_t cohort = q.Int(0);
        for (CohortRecord& r : out)
          if (r.id == cohort) r.members.push_back(q.String(1));
      });
  if (!s.ok()) return s.error();
  return out;
}

// An attempt's columns: the session, its trainee, exercise and end, then the metrics targets
// can name (scoring::ProficiencyMetrics; the rest of a trial's figures are not read).
// VSURG_PROFICIENCY_COLUMNS: every metric a target can name (scoring::ProficiencyMetrics), in
// ReadProficiencyMetrics' order. A macro, so that the two queries below join it at compile time.
#define VSURG_PROFICIENCY_COLUMNS                                                                \
  "m.completed, m.completion_time_s, m.task_error, m.peak_force_n, m.time_over_force_limit_s, "  \
  "m.path_length_m, m.rms_jerk, m.overload_events, m.score, m.guided_share, m.lumps, "           \
  "m.lumps_found, m.false_marks, m.localisation_error_m, m.coverage, m.depth_error_m, "          \
  "m.path_deviation_m, m.extra_punctures, m.back_wall_breaches, m.lateral_strain, m.punctures, " \
  "m.cut_deviation_max_m, m.cut_outside_m, m.torn_length_m, m.cut_lifts "
constexpr const char* kAttemptColumns =
    "SELECT s.id, t.name, s.exercise_id, s.ended_us, " VSURG_PROFICIENCY_COLUMNS;

// The metrics of kAttemptColumns from column `first` on.
void ReadProficiencyMetrics(const Statement& q, int first, scoring::TrialMetrics& m) {
  m.completed = q.Int(first) != 0;
  m.completion_time = q.Double(first + 1);
  m.task_error = q.Double(first + 2);
  m.peak_force = q.Double(first + 3);
  m.time_over_force_limit = q.Double(first + 4);
  m.path_length = q.Double(first + 5);
  m.rms_jerk = q.Double(first + 6);
  m.overload_events = static_cast<int>(q.Int(first + 7));
  m.score = q.Double(first + 8);
  m.guided_share = q.Double(first + 9);
  m.lumps = static_cast<int>(q.Int(first + 10));
  m.lumps_found = static_cast<int>(q.Int(first + 11));
  m.false_marks = static_cast<int>(q.Int(first + 12));
  m.localisation_error = q.Double(first + 13);
  m.coverage = q.Double(first + 14);
  m.depth_error = q.Double(first + 15);
  m.path_deviation = q.Double(first + 16);
  m.extra_punctures = static_cast<int>(q.Int(first + 17));
  m.back_wall_breaches = static_cast<int>(q.Int(first + 18));
  m.lateral_strain = q.Double(first + 19);
  m.punctures = static_cast<int>(q.Int(first + 20));  // no puncture: no placement to credit
  m.cut_deviation_max = q.Double(first + 21);
  m.cut_outside = q.Double(first + 22);
  m.torn_length = q.Double(first + 23);
  m.cut_lifts = static_cast<int>(q.Int(first + 24));
}

void ReadAttempt(const Statement& q, std::vector<AttemptRow>& out) {
  AttemptRow& a = out.emplace_back();
  a.session_id = q.Int(0);
  a.trainee = q.Text(1);
  a.exercise_id = q.IsNull(2) ? 0 : q.Int(2);
  a.ended_us = q.IsNull(3) ? 0 : q.Int(3);
  ReadProficiencyMetrics(q, 4, a.metrics);
}

}  // namespace

Expected<CourseRecord> Store::CreateCourse(const CourseRecord& course) {
  if (Status s = CheckName(course.name, "name"); !s.ok()) return s.error();
  if (course.description.size() > kMaxComment)
    return InvalidArgument("description", "at most 4000 bytes");
  if (course.exercises.empty() || course.exercises.size() > 64)
    return InvalidArgument("exercises", "a course has 1 to 64 exercises");
  CourseRecord out = course;
  out.created_us = NowUs();
  Status s = Write([&](Connection& c) -> Status {
    auto owner = UserId(c, course.owner, "owner");
    if (!owner.ok()) return owner.error();
    Status st = RunSql(c,
                       "INSERT INTO courses(name, description, owner_id, created_us) "
                       "VALUES (?1, ?2, ?3, ?4)",
                       [&](Statement& q) {
                         q.Bind(1, course.name).Bind(2, course.description);
                         q.Bind(3, *owner).Bind(4, out.created_us);
                       });
    if (!st.ok()) {
      if (st.error().code == ErrorCode::kAlreadyExists)
        return Error{ErrorCode::kAlreadyExists, "a course named '" + course.name + "' exists",
                     "name"};
      return st;
    }
    auto id = c.LastInsertId();
    if (!id.ok()) return id.error();
    out.id = *id;
    for (size_t i = 0; i < out.exercises.size(); ++i) {
      ExerciseRecord& e = out.exercises[i];
      e.course_id = out.id;
      e.position = static_cast<int>(i + 1);
      const std::string field = "exercises[" + std::to_string(i) + "]";
      if (e.title.empty() || e.title.size() > 128 || e.scene.empty() || e.scene.size() > 128)
        return InvalidArgument(field, "an exercise needs a title and a scene (1–128 characters)");
      st = RunSql(c,
                  "INSERT INTO exercises(course_id, position, title, scene, spec_json) "
                  "VALUES (?1, ?2, ?3, ?4, ?5)",
                  [&](Statement& q) {
                    q.Bind(1, out.id).Bind(2, int64_t{e.position}).Bind(3, e.title);
                    q.Bind(4, e.scene).Bind(5, e.spec_json);
                  });
      if (!st.ok()) return st;
      auto eid = c.LastInsertId();
      if (!eid.ok()) return eid.error();
      e.id = *eid;
    }
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return out;
}

Status Store::SetExerciseSpec(int64_t exercise_id, const std::string& spec_json) {
  return Write([=](Connection& c) -> Status {
    Status s = RunSql(c, "UPDATE exercises SET spec_json = ?2 WHERE id = ?1",
                      [&](Statement& q) { q.Bind(1, exercise_id).Bind(2, spec_json); });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no exercise " + std::to_string(exercise_id), "exercise"};
    return s;
  });
}

Expected<CohortRecord> Store::CreateCohort(const std::string& name, const std::string& instructor,
                                           const std::vector<std::string>& members) {
  if (Status s = CheckName(name, "name"); !s.ok()) return s.error();
  CohortRecord out;
  out.name = name;
  out.instructor = instructor;
  out.created_us = NowUs();
  Status s = Write([&](Connection& c) -> Status {
    auto owner = UserId(c, instructor, "instructor");
    if (!owner.ok()) return owner.error();
    Status st =
        RunSql(c, "INSERT INTO cohorts(name, instructor_id, created_us) VALUES (?1, ?2, ?3)",
               [&](Statement& q) { q.Bind(1, name).Bind(2, *owner).Bind(3, out.created_us); });
    if (!st.ok()) {
      if (st.error().code == ErrorCode::kAlreadyExists)
        return Error{ErrorCode::kAlreadyExists, "a cohort named '" + name + "' exists", "name"};
      return st;
    }
    auto id = c.LastInsertId();
    if (!id.ok()) return id.error();
    out.id = *id;
    return InsertMembers(c, out.id, members);
  });
  if (!s.ok()) return s.error();
  out.members = members;
  std::sort(out.members.begin(), out.members.end());
  out.members.erase(std::unique(out.members.begin(), out.members.end()), out.members.end());
  return out;
}

Status Store::AddCohortMembers(int64_t cohort_id, const std::vector<std::string>& members) {
  return Write([=](Connection& c) -> Status {
    auto st = c.Prepare("SELECT id FROM cohorts WHERE id = ?1");
    if (!st.ok()) return st.error();
    (*st)->Bind(1, cohort_id);
    auto row = (*st)->Step();
    (*st)->Reset();
    if (!row.ok()) return row.error();
    if (!*row)
      return Error{ErrorCode::kNotFound, "no cohort " + std::to_string(cohort_id), "cohort"};
    return InsertMembers(c, cohort_id, members);
  });
}

Expected<EnrolmentRecord> Store::Enrol(const EnrolmentRecord& e) {
  if (e.cohort_id.has_value() == !e.trainee.empty())
    return InvalidArgument("cohort", "enrol a cohort or one trainee, not both or neither");
  if (e.ends_us && *e.ends_us <= e.starts_us)
    return InvalidArgument("ends", "an enrolment ends after it starts");
  EnrolmentRecord out = e;
  out.created_us = NowUs();
  Status s = Write([&](Connection& c) -> Status {
    auto course = LookupId(c, "SELECT id FROM courses WHERE id = CAST(?1 AS BIGINT)",
                           std::to_string(e.course_id));
    if (!course.ok()) return course.error();
    if (!*course)
      return Error{ErrorCode::kNotFound, "no course " + std::to_string(e.course_id), "course"};
    if (e.cohort_id) {
      auto cohort = LookupId(c, "SELECT id FROM cohorts WHERE id = CAST(?1 AS BIGINT)",
                             std::to_string(*e.cohort_id));
      if (!cohort.ok()) return cohort.error();
      if (!*cohort)
        return Error{ErrorCode::kNotFound, "no cohort " + std::to_string(*e.cohort_id), "cohort"};
    }
    std::optional<int64_t> trainee_id;
    if (!e.trainee.empty()) {
      auto tid = TraineeId(c, e.trainee);
      if (!tid.ok()) return tid.error();
      trainee_id = *tid;
    }
    Status st = RunSql(c,
                       "INSERT INTO enrolments(course_id, cohort_id, trainee_id, starts_us, "
                       "ends_us, created_us) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                       [&](Statement& q) {
                         q.Bind(1, e.course_id).BindOrNull(2, e.cohort_id);
                         q.BindOrNull(3, trainee_id).Bind(4, e.starts_us);
                         q.BindOrNull(5, e.ends_us).Bind(6, out.created_us);
                       });
    if (!st.ok()) return st;
    auto id = c.LastInsertId();
    if (!id.ok()) return id.error();
    out.id = *id;
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return out;
}

Status Store::SetExpert(const std::string& trainee, bool expert) {
  return Write([=](Connection& c) -> Status {
    Status s = RunSql(c, "UPDATE trainees SET expert = ?2 WHERE name = ?1",
                      [&](Statement& q) { q.Bind(1, trainee).Bind(2, int64_t{expert ? 1 : 0}); });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no trainee '" + trainee + "'", "trainee"};
    return s;
  });
}

Status Store::SetSessionExercise(int64_t session_id, int64_t exercise_id) {
  return Write([=](Connection& c) -> Status {
    Status s =
        RunSql(c,
               "UPDATE sessions SET exercise_id = ?2 WHERE id = ?1 AND exercise_id IS NULL "
               "AND state IN (?3, ?4, ?5) AND EXISTS (SELECT 1 FROM exercises WHERE id = ?2)",
               [&](Statement& q) {
                 q.Bind(1, session_id).Bind(2, exercise_id);
                 q.Bind(3, SessionStateName(SessionState::kCreated));
                 q.Bind(4, SessionStateName(SessionState::kRunning));
                 q.Bind(5, SessionStateName(SessionState::kStalled));
               });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(session_id) +
                       " is not a live session without an exercise, or the exercise is unknown",
                   "session"};
    return s;
  });
}

Expected<std::vector<CourseRecord>> Store::ListCourses() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  return ReadCourses(**r, 0);
}

Expected<CourseRecord> Store::GetCourse(int64_t id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto list = ReadCourses(**r, id > 0 ? id : -1);
  if (!list.ok()) return list.error();
  if (list->empty())
    return Error{ErrorCode::kNotFound, "no course " + std::to_string(id), "course"};
  return std::move(list->front());
}

Expected<ExerciseRecord> Store::GetExercise(int64_t id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  std::optional<ExerciseRecord> out;
  Status s = ForEachRow(
      **r, "SELECT id, course_id, position, title, scene, spec_json FROM exercises WHERE id = ?1",
      [&](Statement& q) { q.Bind(1, id); },
      [&](const Statement& q) {
        out.emplace();
        ReadExercise(q, *out);
      });
  if (!s.ok()) return s.error();
  if (!out) return Error{ErrorCode::kNotFound, "no exercise " + std::to_string(id), "exercise"};
  return std::move(*out);
}

Expected<std::vector<CohortRecord>> Store::ListCohorts() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  return ReadCohorts(**r, 0);
}

Expected<CohortRecord> Store::GetCohort(int64_t id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto list = ReadCohorts(**r, id > 0 ? id : -1);
  if (!list.ok()) return list.error();
  if (list->empty())
    return Error{ErrorCode::kNotFound, "no cohort " + std::to_string(id), "cohort"};
  return std::move(list->front());
}

Expected<std::vector<EnrolmentRecord>> Store::ListEnrolments(const std::string& trainee) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  std::vector<EnrolmentRecord> out;
  Status s = ForEachRow(
      **r,
      "SELECT e.id, e.course_id, e.cohort_id, t.name, e.starts_us, e.ends_us, e.created_us "
      "FROM enrolments e LEFT JOIN trainees t ON t.id = e.trainee_id "
      "WHERE CAST(?1 AS TEXT) = '' OR t.name = ?1 OR e.cohort_id IN ("
      "SELECT m.cohort_id FROM cohort_members m JOIN trainees u ON u.id = m.trainee_id "
      "WHERE u.name = ?1) ORDER BY e.id",
      [&](Statement& q) { q.Bind(1, trainee); },
      [&](const Statement& q) {
        EnrolmentRecord e;
        e.id = q.Int(0);
        e.course_id = q.Int(1);
        if (!q.IsNull(2)) e.cohort_id = q.Int(2);
        e.trainee = q.IsNull(3) ? std::string() : q.String(3);
        e.starts_us = q.Int(4);
        if (!q.IsNull(5)) e.ends_us = q.Int(5);
        e.created_us = q.Int(6);
        out.push_back(std::move(e));
      });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<std::string>> Store::ListExperts() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  std::vector<std::string> out;
  Status s = ForEachRow(
      **r, "SELECT name FROM trainees WHERE expert = 1 ORDER BY name", [](Statement&) {},
      [&](const Statement& q) { out.push_back(q.String(0)); });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<AttemptRow>> Store::LoadAttempts(int64_t course_id, const std::string& trainee,
                                                      int64_t cohort_id, int64_t exercise_id,
                                                      const std::optional<NameRange>& range) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  // The trainees' names first (a cohort's few hundred), then their trials by id: a name looked
  // up per trial was a seventh of the grid's time at 100,000 trials.
  std::unordered_map<int64_t, std::string> names;
  Status s = ForEachRow(
      **r,
      "SELECT t.id, t.name FROM trainees t WHERE (CAST(?1 AS TEXT) = '' OR t.name = ?1) "
      "AND (?2 = 0 OR t.id IN (SELECT trainee_id FROM cohort_members WHERE cohort_id = ?2)) "
      "AND (?3 = 0 OR (t.name >= ?4 AND t.name <= ?5))",
      [&](Statement& q) {
        q.Bind(1, trainee).Bind(2, cohort_id).Bind(3, int64_t{range ? 1 : 0});
        q.Bind(4, range ? range->first : "").Bind(5, range ? range->last : "");
      },
      [&](const Statement& q) { names.emplace(q.Int(0), q.String(1)); });
  if (!s.ok()) return s.error();
  std::vector<int64_t> exercises;
  s = ForEachRow(
      **r,
      "SELECT id FROM exercises WHERE course_id = ?1 AND (?2 = 0 OR id = ?2) ORDER BY position",
      [&](Statement& q) { q.Bind(1, course_id).Bind(2, exercise_id); },
      [&](const Statement& q) { exercises.push_back(q.Int(0)); });
  if (!s.ok()) return s.error();
  // One exercise at a time, in the (exercise, trainee) index's order: each trainee's trials come
  // in the order they were made without a sort (an ORDER BY over the whole course made SQLite
  // sort its trials in a temporary B-tree spilled to a file, a fifth of the grid's time at
  // 100,000 trials). One trainee: only their part of the index.
  const int64_t one = !trainee.empty() && names.size() == 1 ? names.begin()->first : 0;
  const std::string sql =
      std::string(
          "SELECT s.id, s.trainee_id, s.ended_us, " VSURG_PROFICIENCY_COLUMNS
          "FROM sessions s JOIN trial_metrics m ON m.session_id = s.id WHERE s.exercise_id = ?1") +
      (one ? " AND s.trainee_id = ?2" : " AND ?2 = 0") + " ORDER BY s.trainee_id, s.id";
  std::vector<AttemptRow> out;
  for (const int64_t exercise : exercises) {
    s = ForEachRow(
        **r, sql, [&](Statement& q) { q.Bind(1, exercise).Bind(2, one); },
        [&](const Statement& q) {
          const auto who = names.find(q.Int(1));
          if (who == names.end()) return;  // not one of the trainees asked for
          AttemptRow& a = out.emplace_back();
          a.session_id = q.Int(0);
          a.trainee = who->second;
          a.exercise_id = exercise;
          a.ended_us = q.IsNull(2) ? 0 : q.Int(2);
          ReadProficiencyMetrics(q, 3, a.metrics);
        });
    if (!s.ok()) return s.error();
  }
  return out;
}

Expected<std::vector<AttemptRow>> Store::LoadExpertAttempts(const std::string& scene,
                                                            int64_t exercise_id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  std::vector<AttemptRow> out;
  Status s = ForEachRow(
      **r,
      std::string(kAttemptColumns) +
          "FROM trainees t JOIN sessions s ON s.trainee_id = t.id "
          "JOIN trial_metrics m ON m.session_id = s.id WHERE t.expert = 1 AND s.scene = ?1" +
          (exercise_id != 0 ? " AND s.exercise_id = ?2" : ""),
      [&](Statement& q) {
        q.Bind(1, scene);
        if (exercise_id != 0) q.Bind(2, exercise_id);
      },
      [&](const Statement& q) { ReadAttempt(q, out); });
  if (!s.ok()) return s.error();
  return out;
}

Expected<int64_t> Store::SessionExercise(int64_t session_id) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  int64_t out = 0;
  bool found = false;
  Status s = ForEachRow(
      **r, "SELECT exercise_id FROM sessions WHERE id = ?1",
      [&](Statement& q) { q.Bind(1, session_id); },
      [&](const Statement& q) {
        found = true;
        out = q.IsNull(0) ? 0 : q.Int(0);
      });
  if (!s.ok()) return s.error();
  if (!found)
    return Error{ErrorCode::kNotFound, "no session " + std::to_string(session_id), "session"};
  return out;
}

}  // namespace vsurg::db
