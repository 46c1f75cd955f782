#include <charconv>
#include <cmath>
#include <future>

#include "common/scoring/vocabulary.h"
#include "db/store_impl.h"

// Evaluation submissions (idempotent, validated, one row per index), the ratings and training
// rows the reports read, weight sets and recorded reports.
namespace vsurg::db {

namespace {

Status ValidateSubmission(const Submission& s) {
  if (s.idempotency_key.empty() || s.idempotency_key.size() > 128)
    return InvalidArgument("idempotency_key", "1 to 128 characters are required");
  if (s.evaluator.empty() || s.evaluator.size() > 128)
    return InvalidArgument("evaluator", "an evaluator name of 1 to 128 characters is required");
  if (!scoring::ParseGroup(s.evaluator_group))
    return InvalidArgument("evaluator_group", "unknown group '" + s.evaluator_group +
                                                  "' (intern, associate_chief or chief)");
  if (s.subject.empty() || s.subject.size() > 256)
    return InvalidArgument("subject", "a subject of 1 to 256 characters is required");
  if (s.moment_min && !(*s.moment_min >= 0 && *s.moment_min <= kMaxMomentMin))
    return InvalidArgument(
        "moment_min",
        "0 to " + std::to_string(static_cast<int64_t>(kMaxMomentMin)) + " minutes of training");
  if (s.comment.size() > kMaxComment)
    return InvalidArgument("comment", "at most " + std::to_string(kMaxComment) + " bytes");
  for (int j = 0; j < scoring::kIndexCount; ++j)
    if (!scoring::IsValidScore(s.scores[j]))
      return InvalidArgument("scores[" + std::to_string(j) + "]",
                             std::string(scoring::IndexName(j)) + " score must be within 0..10");
  return Status::Ok();
}

// A session is scored only once it was driven: one never started holds nothing to judge. A live
// one that has started may be scored: an evaluator watching a trainee live scores what they saw
// (the submission keeps when). kNotFound, or kFailedPrecondition saying why.
Status SessionToJudge(Connection& c, int64_t id) {
  auto st = c.Prepare("SELECT state, started_us FROM sessions WHERE id = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, id);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  const std::string subject = "session " + std::to_string(id);
  if (!*row) return Error{ErrorCode::kNotFound, "no " + subject, "subject"};
  if ((*st)->IsNull(1)) {
    const auto state = ParseSessionState((*st)->Text(0));
    return Error{ErrorCode::kFailedPrecondition,
                 subject +
                     (state && IsLive(*state) ? " has not started yet" : " was never started") +
                     ": there is nothing to judge",
                 "subject"};
  }
  return Status::Ok();
}

// What differs between a stored submission and a retry that reuses its key, or "" when the
// retry is the identical submission (only then is it a duplicate).
std::string SubmissionDifference(Connection& c, int64_t id, const Submission& s) {
  auto st = c.Prepare(
      "SELECT e.name, s.evaluator_group, s.subject_kind, s.subject, s.moment_min FROM submissions "
      "s JOIN evaluators e ON e.id = s.evaluator_id WHERE s.id = ?1");
  if (!st.ok()) return "it cannot be read back";
  (*st)->Bind(1, id);
  auto row = (*st)->Step();
  if (!row.ok() || !*row) return (*st)->Reset(), "it cannot be read back";
  std::string diff;
  if ((*st)->Text(0) != s.evaluator)
    diff = "the evaluator";
  else if ((*st)->Text(1) != s.evaluator_group)
    diff = "the evaluator group";
  else if ((*st)->Text(2) != SubjectKindName(s.subject_kind) || (*st)->Text(3) != s.subject)
    diff = "the subject";
  else if ((*st)->IsNull(4) != !s.moment_min || (s.moment_min && (*st)->Double(4) != *s.moment_min))
    diff = "the training moment";
  (*st)->Reset();
  if (!diff.empty()) return diff;
  auto sc = c.Prepare("SELECT index_no, score FROM evaluations WHERE submission_id = ?1");
  if (!sc.ok()) return "it cannot be read back";
  (*sc)->Bind(1, id);
  for (;;) {
    auto r = (*sc)->Step();
    if (!r.ok()) return (*sc)->Reset(), "it cannot be read back";
    if (!*r) break;
    const int64_t j = (*sc)->Int(0) - 1;
    if (j >= 0 && j < scoring::kIndexCount && (*sc)->Double(1) != s.scores[j]) {
      diff = std::string("the ") + scoring::IndexName(static_cast<int>(j)) + " score";
      break;
    }
  }
  (*sc)->Reset();
  return diff;
}

// The submission's subject exists, and a session subject is one that can be judged.
Status CheckSubject(Connection& c, const Submission& s) {
  switch (s.subject_kind) {
    case SubjectKind::kSession: {
      int64_t id = 0;
      const auto r = std::from_chars(s.subject.data(), s.subject.data() + s.subject.size(), id);
      if (r.ec != std::errc() || r.ptr != s.subject.data() + s.subject.size())
        return InvalidArgument("subject", "a session subject is a session id");
      return SessionToJudge(c, id);
    }
    case SubjectKind::kTrainee: {
      auto found = LookupId(c, "SELECT id FROM trainees WHERE name = ?1", s.subject);
      if (!found.ok()) return found.error();
      if (!*found) return Error{ErrorCode::kNotFound, "no trainee '" + s.subject + "'", "subject"};
      return Status::Ok();
    }
    case SubjectKind::kModel:
      return Status::Ok();
  }
  return Status::Ok();
}

// The body of one submission, inside the writer's savepoint.
Status InsertSubmission(Connection& c, const Submission& s, SubmitResult& out) {
  // A retry: the same key returns the first result, but only for the identical submission; a
  // reused key with another payload is refused, never acknowledged and dropped.
  {
    auto st = c.Prepare("SELECT id, submitted_us FROM submissions WHERE idempotency_key = ?1");
    if (!st.ok()) return st.error();
    (*st)->Bind(1, s.idempotency_key);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (*row) {
      const int64_t id = (*st)->Int(0), at = (*st)->Int(1);
      (*st)->Reset();
      const std::string diff = SubmissionDifference(c, id, s);
      if (!diff.empty())
        return Error{ErrorCode::kAlreadyExists,
                     "idempotency key '" + s.idempotency_key +
                         "' was used for a different submission (" + diff +
                         " differs); stored evaluations are not changed",
                     "idempotency_key"};
      out.submission_id = id;
      out.submitted_us = at;
      out.duplicate = true;
      return Status::Ok();
    }
    (*st)->Reset();
  }
  if (Status subject = CheckSubject(c, s); !subject.ok()) return subject;
  // The evaluator: created on first sight (imports), and always in one group.
  int64_t evaluator_id = 0;
  {
    auto st = c.Prepare("SELECT id, evaluator_group FROM evaluators WHERE name = ?1");
    if (!st.ok()) return st.error();
    (*st)->Bind(1, s.evaluator);
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (*row) {
      evaluator_id = (*st)->Int(0);
      const std::string group = (*st)->String(1);
      (*st)->Reset();
      if (group != s.evaluator_group)
        return InvalidArgument("evaluator_group", "evaluator '" + s.evaluator + "' is in group " +
                                                      group + ", not " + s.evaluator_group);
    } else {
      (*st)->Reset();
      Status ins = RunSql(c, "INSERT INTO evaluators(name, evaluator_group) VALUES (?1, ?2)",
                          [&](Statement& q) { q.Bind(1, s.evaluator).Bind(2, s.evaluator_group); });
      if (!ins.ok()) return ins;
      auto id = c.LastInsertId();
      if (!id.ok()) return id.error();
      evaluator_id = *id;
    }
  }
  auto by = LookupId(c, "SELECT id FROM users WHERE name = ?1", s.submitted_by);
  if (!by.ok()) return by.error();
  if (!*by) return Error{ErrorCode::kNotFound, "no user '" + s.submitted_by + "'", "submitted_by"};
  out.submitted_us = NowUs();
  // One statement each for the submission and its nine scores (a round trip each on
  // PostgreSQL): RETURNING gives the new id on both backends.
  auto sub = c.Prepare(
      "INSERT INTO submissions(idempotency_key, evaluator_id, evaluator_group, "
      "subject_kind, subject, moment_min, submitted_us, submitted_by, comment) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9) RETURNING id");
  if (!sub.ok()) return sub.error();
  Statement& q = **sub;
  q.Bind(1, s.idempotency_key).Bind(2, evaluator_id);
  q.Bind(3, s.evaluator_group).Bind(4, SubjectKindName(s.subject_kind));
  q.Bind(5, s.subject).Bind(6, s.moment_min).Bind(7, out.submitted_us);
  q.Bind(8, **by).Bind(9, s.comment);
  auto row = q.Step();
  if (row.ok() && *row) out.submission_id = q.Int(0);
  q.Reset();
  if (!row.ok()) {
    if (row.error().code == ErrorCode::kAlreadyExists)
      return Error{ErrorCode::kAlreadyExists,
                   "evaluator '" + s.evaluator + "' has already rated this " +
                       SubjectKindName(s.subject_kind) + (s.moment_min ? " at this moment" : ""),
                   "subject"};
    return row.error();
  }
  static_assert(scoring::kIndexCount == 9, "the scores statement lists nine rows");
  auto st = c.Prepare(
      "INSERT INTO evaluations(submission_id, index_no, score) VALUES (?1, 1, ?2), (?1, 2, ?3), "
      "(?1, 3, ?4), (?1, 4, ?5), (?1, 5, ?6), (?1, 6, ?7), (?1, 7, ?8), (?1, 8, ?9), "
      "(?1, 9, ?10)");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, out.submission_id);
  for (int j = 0; j < scoring::kIndexCount; ++j) (*st)->Bind(j + 2, s.scores[j]);
  if (Status r = (*st)->Run(); !r.ok()) return r;
  return Status::Ok();
}

}  // namespace

namespace {

// Rows ordered by submission then index_no, with the submission id in column 0 and
// (index_no, score) in columns `index_col`, `index_col + 1`: calls `first(q)` at each new
// submission (it appends a record and returns its scores) and fills the nine scores.
template <class First>
Status CollectScores(Statement& q, int index_col, First&& first) {
  int64_t current = -1;
  std::array<double, scoring::kIndexCount>* scores = nullptr;
  for (;;) {
    auto row = q.Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    if (q.Int(0) != current) {
      current = q.Int(0);
      scores = &first(q);
    }
    const int64_t j = q.Int(index_col);
    if (j >= 1 && j <= scoring::kIndexCount) (*scores)[j - 1] = q.Double(index_col + 1);
  }
  q.Reset();
  return Status::Ok();
}

// The submission columns 0..6 of ListSubmissionsBy/On (id, kind, subject, moment, time,
// comment, group) into `row`.
SubmittedRow& ReadSubmitted(Statement& q, SubmittedRow& row) {
  row.id = q.Int(0);
  row.subject_kind = ParseSubjectKind(q.Text(1)).value_or(SubjectKind::kSession);
  row.subject = q.String(2);
  if (!q.IsNull(3)) row.moment_min = q.Double(3);
  row.submitted_us = q.Int(4);
  row.comment = q.String(5);
  row.evaluator_group = q.String(6);
  return row;
}

}  // namespace

void Store::SubmitEvaluationAsync(Submission s, std::function<void(Expected<SubmitResult>)> done) {
  if (Status v = ValidateSubmission(s); !v.ok()) {
    done(v.error());
    return;
  }
  auto shared = std::make_shared<std::pair<Submission, SubmitResult>>(std::move(s), SubmitResult{});
  WriteAsync([shared](Connection& c) { return InsertSubmission(c, shared->first, shared->second); },
             [shared, done = std::move(done)](Status st) {
               if (!st.ok()) {
                 done(st.error());
               } else {
                 done(shared->second);
               }
             });
}

Expected<SubmitResult> Store::SubmitEvaluation(const Submission& s) {
  std::promise<Expected<SubmitResult>> p;
  auto f = p.get_future();
  SubmitEvaluationAsync(s, [&p](Expected<SubmitResult> r) { p.set_value(std::move(r)); });
  return f.get();
}

Expected<std::vector<RatingRow>> Store::LoadRatings(SubjectKind kind, const std::string& subject) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, e.name, s.evaluator_group, s.moment_min, v.index_no, v.score "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN evaluations v ON v.submission_id = s.id "
      "WHERE s.subject_kind = ?1 AND s.subject = ?2 ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, SubjectKindName(kind)).Bind(2, subject);
  std::vector<RatingRow> out;
  Status s = CollectScores(**st, 4, [&](Statement& q) -> std::array<double, scoring::kIndexCount>& {
    RatingRow& rr = out.emplace_back();
    rr.evaluator = q.String(1);
    rr.evaluator_group = q.String(2);
    if (!q.IsNull(3)) rr.moment_min = q.Double(3);
    return rr.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<SubmittedRow>> Store::ListSubmissionsBy(const std::string& evaluator,
                                                             int limit) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, s.subject_kind, s.subject, s.moment_min, s.submitted_us, s.comment, "
      "s.evaluator_group, v.index_no, v.score "
      "FROM (SELECT s.* FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "      WHERE e.name = ?1 ORDER BY s.id DESC LIMIT ?2) s "
      "JOIN evaluations v ON v.submission_id = s.id ORDER BY s.id DESC, v.index_no");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, evaluator).Bind(2, static_cast<int64_t>(limit));
  std::vector<SubmittedRow> out;
  Status s = CollectScores(**st, 7, [&](Statement& q) -> std::array<double, scoring::kIndexCount>& {
    SubmittedRow& row = ReadSubmitted(q, out.emplace_back());
    row.evaluator = evaluator;
    return row.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<SubmittedRow>> Store::ListSubmissionsOn(SubjectKind kind,
                                                             const std::string& subject) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, s.subject_kind, s.subject, s.moment_min, s.submitted_us, s.comment, "
      "s.evaluator_group, e.name, v.index_no, v.score "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN evaluations v ON v.submission_id = s.id "
      "WHERE s.subject_kind = ?1 AND s.subject = ?2 ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, SubjectKindName(kind)).Bind(2, subject);
  std::vector<SubmittedRow> out;
  Status s = CollectScores(**st, 8, [&](Statement& q) -> std::array<double, scoring::kIndexCount>& {
    SubmittedRow& row = ReadSubmitted(q, out.emplace_back());
    row.evaluator = q.String(7);
    return row.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<std::vector<std::string>> Store::ListRatedSubjects(SubjectKind kind) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT DISTINCT subject FROM submissions WHERE subject_kind = ?1 ORDER BY subject");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, SubjectKindName(kind));
  std::vector<std::string> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return (*st)->Reset(), row.error();
    if (!*row) break;
    out.push_back((*st)->String(0));
  }
  (*st)->Reset();
  return out;
}

Expected<std::vector<TrainingRow>> Store::LoadTrainingRows() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT s.id, s.subject, t.trainee_group, s.moment_min, e.name, v.index_no, v.score "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN trainees t ON t.name = s.subject JOIN evaluations v ON v.submission_id = s.id "
      "WHERE s.subject_kind = 'trainee' AND s.moment_min IS NOT NULL "
      "ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  std::vector<TrainingRow> out;
  Status s = CollectScores(**st, 5, [&](Statement& q) -> std::array<double, scoring::kIndexCount>& {
    TrainingRow& t = out.emplace_back();
    t.trainee = q.String(1);
    t.trainee_group = q.String(2);
    t.moment_min = q.Double(3);
    t.evaluator = q.String(4);
    return t.scores;
  });
  if (!s.ok()) return s.error();
  return out;
}

Expected<int64_t> Store::CountEvaluationRows() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT count(*) FROM evaluations");
  if (!st.ok()) return st.error();
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  const int64_t n = (*st)->Int(0);
  (*st)->Reset();
  return n;
}

Status Store::PutWeightSet(const std::string& name, const std::string& json) {
  return Write([=](Connection& c) {
    return RunSql(c,
                  "INSERT INTO weight_sets(name, json, created_us) VALUES (?1, ?2, ?3) "
                  "ON CONFLICT(name) DO UPDATE SET json = excluded.json, "
                  "created_us = excluded.created_us",
                  [&](Statement& st) { st.Bind(1, name).Bind(2, json).Bind(3, NowUs()); });
  });
}

Expected<std::string> Store::GetWeightSet(const std::string& name) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT json FROM weight_sets WHERE name = ?1");
  if (!st.ok()) return st.error();
  (*st)->Bind(1, name);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kNotFound, "no weight set '" + name + "'", "weights"};
  }
  std::string json = (*st)->String(0);
  (*st)->Reset();
  return json;
}

Expected<std::vector<std::string>> Store::ListWeightSets() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare("SELECT name FROM weight_sets ORDER BY name");
  if (!st.ok()) return st.error();
  std::vector<std::string> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    out.push_back((*st)->String(0));
  }
  (*st)->Reset();
  return out;
}

Status Store::RecordReport(const std::string& subject_kind, const std::string& subject,
                           const std::string& weights_json, const std::string& report_json) {
  return Write([=](Connection& c) {
    return RunSql(c,
                  "INSERT INTO reports(subject_kind, subject, weights_json, report_json, "
                  "created_us) VALUES (?1, ?2, ?3, ?4, ?5)",
                  [&](Statement& st) {
                    st.Bind(1, subject_kind).Bind(2, subject).Bind(3, weights_json);
                    st.Bind(4, report_json).Bind(5, NowUs());
                  });
  });
}

}  // namespace vsurg::db
