// Every not-found, refused and failing path of the store, taken twice in a row and then followed
// by a call that must succeed, on both backends. A cached statement that one of those paths left
// mid-result (its bindings or rows kept) answers the next caller of the same SQL with the old
// caller's: after one read of a record that is not there, every read of a record that is there
// said "not found". db/connection.h's ScopedStatement resets on every path; these tests hold it.
#include <string>

#include <gtest/gtest.h>

#include "db/store.h"
#include "tests/db/store_fixture.h"

namespace vsurg::db {
namespace {

class StoreErrorPathTest : public test_store::StoreTest {
 protected:
  // The session `trainee` was given, started, ended with trial metrics and (when not empty) a
  // trace.
  int64_t RecordedSession(const std::string& trainee, const std::string& trace) {
    auto s = store_->CreateSession(trainee, "arm-torsion");
    EXPECT_TRUE(s.ok());
    EXPECT_TRUE(store_->SetSessionState(s->id, SessionState::kRunning, 100).ok());
    scoring::TrialMetrics m;
    m.score = 7.5;
    EXPECT_TRUE(store_->EndSession(s->id, SessionState::kEnded, 200, "done", m, {}, trace).ok());
    return s->id;
  }
};

INSTANTIATE_TEST_SUITE_P(Backends, StoreErrorPathTest,
                         ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& p) { return std::string(BackendName(p.param)); });

// Asserts that `call` fails with `code` twice in a row.
template <class Call>
void FailsTwice(Call&& call, ErrorCode code, const char* what) {
  for (int i = 0; i < 2; ++i) {
    auto r = call();
    ASSERT_FALSE(r.ok()) << what << " #" << i + 1;
    EXPECT_EQ(r.error().code, code) << what << " #" << i + 1 << ": " << r.error().message;
  }
}

TEST_P(StoreErrorPathTest, ReadsOfMissingRowsLeaveTheNextReadRight) {
  const std::string trace = R"({"series":{"time_s":[0,0.1]}})";
  const int64_t recorded = RecordedSession("trainee-1", trace);
  auto undriven = store_->CreateSession("trainee-2", "arm-torsion");
  ASSERT_TRUE(undriven.ok());
  ASSERT_TRUE(store_->SetSessionState(undriven->id, SessionState::kEnded, 100, "stopped").ok());

  // The replay that broke every other: a trace that is not there, then one that is.
  FailsTwice([&] { return store_->GetSessionTrace(undriven->id); }, ErrorCode::kNotFound,
             "trace of an undriven session");
  FailsTwice([&] { return store_->GetSessionTrace(987654); }, ErrorCode::kNotFound,
             "trace of no session");
  for (int i = 0; i < 3; ++i) EXPECT_EQ(store_->GetSessionTrace(recorded).value(), trace);

  FailsTwice([&] { return store_->GetSession(987654); }, ErrorCode::kNotFound, "session");
  EXPECT_EQ(store_->GetSession(recorded).value().trainee, "trainee-1");

  for (int i = 0; i < 2; ++i) EXPECT_FALSE(store_->GetTrialMetrics(undriven->id).value());
  EXPECT_EQ(store_->GetTrialMetrics(recorded).value()->score, 7.5);

  FailsTwice([&] { return store_->GetWeightSet("nope"); }, ErrorCode::kNotFound, "weight set");
  ASSERT_TRUE(store_->PutWeightSet("site", R"({"w":1})").ok());
  EXPECT_EQ(store_->GetWeightSet("site").value(), R"({"w":1})");

  FailsTwice([&] { return store_->Authenticate("not-a-token"); }, ErrorCode::kUnauthenticated,
             "token");
  auto token = store_->InitAdmin("root");
  ASSERT_TRUE(token.ok());
  EXPECT_EQ(store_->Authenticate(*token).value().name, "root");
}

TEST_P(StoreErrorPathTest, TrainingReadsOfMissingRowsLeaveTheNextReadRight) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  CourseRecord course;
  course.name = "basics";
  course.owner = "root";
  ExerciseRecord twist;
  twist.position = 1;
  twist.title = "twist";
  twist.scene = "arm-torsion";
  twist.spec_json = "{}";
  course.exercises.push_back(twist);
  auto made = store_->CreateCourse(course);
  ASSERT_TRUE(made.ok()) << made.error().message;
  auto cohort = store_->CreateCohort("spring", "root", {"trainee-1"});
  ASSERT_TRUE(cohort.ok()) << cohort.error().message;

  FailsTwice([&] { return store_->GetCourse(987654); }, ErrorCode::kNotFound, "course");
  EXPECT_EQ(store_->GetCourse(made->id).value().name, "basics");
  FailsTwice([&] { return store_->GetExercise(987654); }, ErrorCode::kNotFound, "exercise");
  EXPECT_EQ(store_->GetExercise(made->exercises[0].id).value().title, "twist");
  FailsTwice([&] { return store_->GetCohort(987654); }, ErrorCode::kNotFound, "cohort");
  EXPECT_EQ(store_->GetCohort(cohort->id).value().members, std::vector<std::string>{"trainee-1"});
  FailsTwice([&] { return store_->SessionExercise(987654); }, ErrorCode::kNotFound,
             "session's exercise");
  auto live = store_->CreateSession("trainee-1", "arm-torsion");
  ASSERT_TRUE(live.ok());
  ASSERT_TRUE(store_->SetSessionExercise(live->id, made->exercises[0].id).ok());
  EXPECT_EQ(store_->SessionExercise(live->id).value(), made->exercises[0].id);
}

// The writer's connection: a refused or failed job leaves its statements ready for the next job,
// whichever session or row that job names.
TEST_P(StoreErrorPathTest, RefusedWritesLeaveTheNextWriteRight) {
  NodeRecord a = test_store::SimNode();
  NodeRecord b = a;
  b.name = "sim-1", b.instance = "process-b";
  a.epoch = store_->AcquireNode(a, 2000, "restarted").value().epoch;
  b.epoch = store_->AcquireNode(b, 2000, "restarted").value().epoch;
  auto on_a = store_->CreateSession("trainee-1", "arm-torsion", {"sim-0", a.epoch});
  auto on_b = store_->CreateSession("trainee-2", "arm-torsion", {"sim-1", b.epoch});
  ASSERT_TRUE(on_a.ok() && on_b.ok());

  // The lease check's refusal (a stale epoch), then a write under a good lease, of another
  // session and of the same one.
  auto stale = [&] {
    return store_->SetSessionState(on_a->id, SessionState::kRunning, 10, "",
                                   {"sim-0", a.epoch + 7});
  };
  FailsTwice(stale, ErrorCode::kFailedPrecondition, "stale epoch");
  EXPECT_TRUE(
      store_->SetSessionState(on_b->id, SessionState::kRunning, 11, "", {"sim-1", b.epoch}).ok());
  FailsTwice(stale, ErrorCode::kFailedPrecondition, "stale epoch again");
  EXPECT_TRUE(
      store_->SetSessionState(on_a->id, SessionState::kRunning, 12, "", {"sim-0", a.epoch}).ok());

  FailsTwice([&] { return store_->SetSessionState(987654, SessionState::kRunning, 13); },
             ErrorCode::kNotFound, "state of no session");
  scoring::TrialMetrics m;
  m.score = 6;
  FailsTwice(
      [&] {
        return store_->EndSession(on_a->id, SessionState::kEnded, 20, "done", m,
                                  {"sim-1", b.epoch});
      },
      ErrorCode::kFailedPrecondition, "end under another node's fence");
  ASSERT_TRUE(
      store_->EndSession(on_a->id, SessionState::kEnded, 21, "done", m, {"sim-0", a.epoch}).ok());
  EXPECT_EQ(store_->GetTrialMetrics(on_a->id).value()->score, 6);

  FailsTwice(
      [&] {
        return store_->MoveSession(on_b->id, {"sim-0", a.epoch}, {"sim-1", b.epoch});
      },
      ErrorCode::kFailedPrecondition, "move from a node that does not own it");
  EXPECT_TRUE(store_->MoveSession(on_b->id, {"sim-1", b.epoch}, {"sim-0", a.epoch}).ok());

  NodeRecord lost = a;
  lost.epoch = a.epoch + 3;
  FailsTwice([&] { return store_->BeatNode(lost); }, ErrorCode::kFailedPrecondition,
             "beat of a lost lease");
  a.heartbeat_us = 1500;
  EXPECT_TRUE(store_->BeatNode(a).ok());
}

TEST_P(StoreErrorPathTest, RefusedAccountAndTrainingWritesLeaveTheNextWriteRight) {
  ASSERT_TRUE(store_->CreateUser("dr-a", Role::kEvaluator, "chief").ok());
  FailsTwice([&] { return store_->CreateUser("dr-a", Role::kEvaluator, "chief"); },
             ErrorCode::kAlreadyExists, "a taken user name");
  EXPECT_TRUE(store_->CreateUser("dr-b", Role::kEvaluator, "intern").ok());
  FailsTwice([&] { return store_->IssueToken("nobody", "x"); }, ErrorCode::kNotFound,
             "token for no user");
  auto token = store_->IssueToken("dr-b", "x");
  ASSERT_TRUE(token.ok());
  EXPECT_EQ(store_->Authenticate(*token).value().name, "dr-b");
  FailsTwice([&] { return store_->SetUserDisabled("nobody", true); }, ErrorCode::kNotFound,
             "disable no user");
  EXPECT_TRUE(store_->SetUserDisabled("dr-a", true).ok());
  FailsTwice([&] { return store_->SetExpert("nobody", true); }, ErrorCode::kNotFound,
             "expert no trainee");
  const int64_t recorded = RecordedSession("trainee-1", "");
  EXPECT_TRUE(store_->SetExpert("trainee-1", true).ok());
  EXPECT_EQ(store_->ListExperts().value(), std::vector<std::string>{"trainee-1"});

  FailsTwice([&] { return store_->SetExerciseSpec(987654, "{}"); }, ErrorCode::kNotFound,
             "spec of no exercise");
  FailsTwice([&] { return store_->AddCohortMembers(987654, {"trainee-1"}); }, ErrorCode::kNotFound,
             "members of no cohort");
  EnrolmentRecord nowhere;
  nowhere.course_id = 987654;
  nowhere.trainee = "trainee-1";
  FailsTwice([&] { return store_->Enrol(nowhere); }, ErrorCode::kNotFound,
             "enrolment in no course");

  Submission s;
  s.idempotency_key = "k-1";
  s.evaluator = "dr-b";
  s.evaluator_group = "intern";
  s.subject_kind = SubjectKind::kSession;
  s.subject = "987654";
  s.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
  s.submitted_by = "dr-b";
  FailsTwice([&] { return store_->SubmitEvaluation(s); }, ErrorCode::kNotFound,
             "evaluation of no session");
  s.subject = std::to_string(recorded);
  auto ok = store_->SubmitEvaluation(s);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_FALSE(ok->duplicate);
  EXPECT_EQ(store_->LoadRatings(SubjectKind::kSession, s.subject).value().size(), 1u);
}

// What an evaluation judges: a session that was driven, live or ended (an evaluator watching a
// trainee live scores what they saw); never one that did not start; a moment within bounds.
TEST_P(StoreErrorPathTest, AnEvaluationJudgesOnlyASessionThatWasDriven) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  auto waiting = store_->CreateSession("trainee-1", "arm-torsion");
  auto never = store_->CreateSession("trainee-1", "arm-torsion");
  auto live = store_->CreateSession("trainee-1", "arm-torsion");
  ASSERT_TRUE(waiting.ok() && never.ok() && live.ok());
  ASSERT_TRUE(store_->SetSessionState(never->id, SessionState::kAborted, 10, "never started").ok());
  ASSERT_TRUE(store_->SetSessionState(live->id, SessionState::kRunning, 10).ok());
  const int64_t done = RecordedSession("trainee-1", "");
  Submission s;
  s.idempotency_key = "k-1";
  s.evaluator = "dr-a";
  s.evaluator_group = "chief";
  s.subject_kind = SubjectKind::kSession;
  s.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
  s.submitted_by = "root";
  for (const auto& [id, why] :
       {std::pair{waiting->id, "has not started yet"}, std::pair{never->id, "was never started"}}) {
    s.subject = std::to_string(id);
    auto refused = store_->SubmitEvaluation(s);
    ASSERT_FALSE(refused.ok()) << why;
    EXPECT_EQ(refused.error().code, ErrorCode::kFailedPrecondition);
    EXPECT_NE(refused.error().message.find(why), std::string::npos) << refused.error().message;
  }
  EXPECT_EQ(store_->CountEvaluationRows().value(), 0);
  s.subject = std::to_string(done);
  s.moment_min = 1e308;
  EXPECT_EQ(store_->SubmitEvaluation(s).error().field, "moment_min");
  s.moment_min = kMaxMomentMin;
  auto taken = store_->SubmitEvaluation(s);
  EXPECT_TRUE(taken.ok()) << taken.error().message;
  s.idempotency_key = "k-2";
  s.moment_min.reset();
  s.subject = std::to_string(live->id);
  taken = store_->SubmitEvaluation(s);
  EXPECT_TRUE(taken.ok()) << taken.error().message;
  EXPECT_EQ(store_->CountEvaluationRows().value(), 18);
}

// A search for text with a control character in it (a NUL from `?q=%00`) finds nothing: no
// name holds one. SQLite would have cut the pattern at the NUL and matched every row.
TEST_P(StoreErrorPathTest, ASearchWithAControlCharacterFindsNothing) {
  RecordedSession("trainee-1", "");
  RecordedSession("trainee-2", "");
  SessionQuery q;
  EXPECT_EQ(store_->FindSessions(q).value().total, 2);
  for (const std::string& text :
       {std::string("\0", 1), std::string("trainee\0", 8), std::string("\n")}) {
    q.search = text;
    auto page = store_->FindSessions(q);
    ASSERT_TRUE(page.ok()) << page.error().message;
    EXPECT_EQ(page->total, 0);
    EXPECT_TRUE(page->rows.empty());
  }
  q.search = "trainee-2";
  EXPECT_EQ(store_->FindSessions(q).value().total, 1);
}

}  // namespace
}  // namespace vsurg::db
