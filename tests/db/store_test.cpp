#include "db/store.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/core/csv.h"
#include "db/connection.h"
#include "db/migrations.h"
#include "db/postgres.h"
#include "tests/db/store_fixture.h"
#include "tests/support/postgres.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::db {
namespace {

namespace fs = std::filesystem;
using test_store::StoreTest;

INSTANTIATE_TEST_SUITE_P(Backends, StoreTest,
                         ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& p) { return std::string(BackendName(p.param)); });

int64_t PragmaInt(Connection& c, const char* pragma) {  // SQLite
  auto st = c.Prepare(pragma);
  EXPECT_TRUE(st.ok());
  EXPECT_TRUE((*st)->Step().value());
  const int64_t v = (*st)->Int(0);
  (*st)->Reset();
  return v;
}

TEST_P(StoreTest, OpensDurableWithTheCurrentSchema) {
  EXPECT_EQ(store_->backend(), GetParam());
  EXPECT_EQ(Version(), Store::SchemaVersion());
  EXPECT_EQ(store_->IntegrityCheck().value(), "ok");
  if (!sqlite()) {
    std::string commit, fsync, pages;
    ASSERT_TRUE(store_
                    ->Write([&](Connection& c) {
                      auto st = c.Prepare(
                          "SELECT current_setting('synchronous_commit'), current_setting('fsync'), "
                          "current_setting('full_page_writes')");
                      EXPECT_TRUE(st.ok() && (*st)->Step().value());
                      commit = (*st)->String(0);
                      fsync = (*st)->String(1);
                      pages = (*st)->String(2);
                      return Status::Ok();
                    })
                    .ok());
    EXPECT_EQ(commit, "on");  // COMMIT returns after the WAL flush,
    EXPECT_EQ(fsync, "on");   // which reaches the disk,
    EXPECT_EQ(pages, "on");   // and a page torn by a power cut is rebuilt from the WAL
    return;
  }
  int64_t sync = -1, fk = -1, version = -1;
  std::string mode;
  ASSERT_TRUE(store_
                  ->Write([&](Connection& c) {
                    sync = PragmaInt(c, "PRAGMA synchronous");
                    fk = PragmaInt(c, "PRAGMA foreign_keys");
                    version = PragmaInt(c, "PRAGMA user_version");
                    auto st = c.Prepare("PRAGMA journal_mode");
                    EXPECT_TRUE((*st)->Step().value());
                    mode = (*st)->String(0);
                    (*st)->Reset();
                    return Status::Ok();
                  })
                  .ok());
  EXPECT_EQ(sync, 2);  // FULL
  EXPECT_EQ(fk, 1);
  EXPECT_EQ(mode, "wal");
  EXPECT_EQ(version, Store::SchemaVersion());
}

TEST_P(StoreTest, ReopeningKeepsDataAndAFileFromTheFutureIsRefused) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  store_.reset();
  auto again = Store::Open({.path = path_});
  ASSERT_TRUE(again.ok());
  EXPECT_EQ((*again)->ListUsers().value().size(), 1u);
  again->reset();

  SetVersion(99);
  auto future = Store::Open({.path = path_});
  ASSERT_FALSE(future.ok());
  EXPECT_NE(future.error().message.find("newer than this binary"), std::string::npos);
}

TEST_P(StoreTest, TokensAreStoredHashedAndAuthenticateToTheirUser) {
  auto admin = store_->InitAdmin("root");
  ASSERT_TRUE(admin.ok()) << admin.error().message;
  EXPECT_EQ(store_->InitAdmin("root2").error().code, ErrorCode::kAlreadyExists);
  ASSERT_TRUE(store_->CreateUser("dr-a", Role::kEvaluator, "chief").ok());
  EXPECT_EQ(store_->CreateUser("dr-a", Role::kEvaluator, "chief").error().code,
            ErrorCode::kAlreadyExists);
  EXPECT_EQ(store_->CreateUser("dr-b", Role::kEvaluator, "resident").error().field, "group");
  auto token = store_->IssueToken("dr-a", "laptop");
  ASSERT_TRUE(token.ok());

  auto p = store_->Authenticate(*token);
  ASSERT_TRUE(p.ok()) << p.error().message;
  EXPECT_EQ(p->name, "dr-a");
  EXPECT_EQ(p->role, Role::kEvaluator);
  EXPECT_EQ(p->group, "chief");
  EXPECT_EQ(store_->Authenticate(*admin)->role, Role::kAdmin);
  EXPECT_EQ(store_->Authenticate("vst_00000000000000000000").error().code,
            ErrorCode::kUnauthenticated);
  EXPECT_EQ(store_->Authenticate("").error().code, ErrorCode::kUnauthenticated);

  // The secret itself is nowhere in the file (or its WAL); on PostgreSQL, nowhere in a row.
  store_.reset();
  for (const char* suffix : {"", "-wal"}) {
    if (!sqlite()) break;
    std::ifstream in(path_ + suffix, std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    EXPECT_EQ(bytes.str().find(token->substr(4)), std::string::npos) << suffix;
  }
  store_ = std::move(Store::Open({.path = path_})).value();
  ASSERT_TRUE(store_->RevokeTokens("dr-a").ok());
  EXPECT_EQ(store_->Authenticate(*token).error().code, ErrorCode::kUnauthenticated);
  ASSERT_TRUE(store_->SetUserDisabled("root", true).ok());
  EXPECT_EQ(store_->Authenticate(*admin).error().code, ErrorCode::kUnauthenticated);
}

// A sign-in through the identity provider: an unknown user is created with the provider's role
// and given a web session's token; a known one with that role is given another; a disabled
// account or one whose role here differs is refused naming it, twice in a row, and writes nothing.
TEST_P(StoreTest, AFederatedSignInCreatesTheUserOrRefusesByName) {
  auto first = store_->SignInFederated("dr-lee", Role::kInstructor, 3600);
  ASSERT_TRUE(first.ok()) << first.error().message;
  auto p = store_->Authenticate(*first);
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->name, "dr-lee");
  EXPECT_EQ(p->role, Role::kInstructor);
  auto second = store_->SignInFederated("dr-lee", Role::kInstructor, 3600);
  ASSERT_TRUE(second.ok());
  EXPECT_NE(*second, *first);
  EXPECT_TRUE(store_->Authenticate(*first).ok()) << "a web session within its lifetime stays";
  // A ttl of 0: every earlier web session's token has outlived it and is revoked.
  auto third = store_->SignInFederated("dr-lee", Role::kInstructor, 0);
  ASSERT_TRUE(third.ok());
  EXPECT_EQ(store_->Authenticate(*first).error().code, ErrorCode::kUnauthenticated);
  EXPECT_TRUE(store_->Authenticate(*third).ok());
  for (int twice = 0; twice < 2; ++twice) {
    const auto other = store_->SignInFederated("dr-lee", Role::kAdmin, 3600);
    ASSERT_FALSE(other.ok());
    EXPECT_EQ(other.error().code, ErrorCode::kPermissionDenied);
    EXPECT_EQ(other.error().field, "role");
  }
  ASSERT_TRUE(store_->SetUserDisabled("dr-lee", true).ok());
  for (int twice = 0; twice < 2; ++twice) {
    const auto off = store_->SignInFederated("dr-lee", Role::kInstructor, 3600);
    ASSERT_FALSE(off.ok());
    EXPECT_EQ(off.error().code, ErrorCode::kPermissionDenied);
    EXPECT_NE(off.error().message.find("disabled"), std::string::npos);
  }
  EXPECT_EQ(store_->SignInFederated("", Role::kTrainee, 3600).error().field, "name");
  auto users = store_->ListUsers();
  ASSERT_TRUE(users.ok());
  EXPECT_EQ(users->size(), 1u);
}

TEST_P(StoreTest, ASubmissionIsNineRawRowsAndARetryIsNotASecond) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  auto r = store_->SubmitEvaluation(Valid("k1"));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->duplicate);
  EXPECT_EQ(Rows(), 9);
  auto again = store_->SubmitEvaluation(Valid("k1"));
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->duplicate);
  EXPECT_EQ(again->submission_id, r->submission_id);
  EXPECT_EQ(Rows(), 9);
  // The same rater on the same subject under another key is a second opinion: refused.
  auto second = store_->SubmitEvaluation(Valid("k2"));
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error().code, ErrorCode::kAlreadyExists);
  // A key reused for a different submission is refused, not silently matched.
  auto reused = store_->SubmitEvaluation(Valid("k1", "dr-b"));
  ASSERT_FALSE(reused.ok());
  EXPECT_EQ(reused.error().field, "idempotency_key");
  auto ratings = store_->LoadRatings(SubjectKind::kModel, "coil-spring");
  ASSERT_TRUE(ratings.ok());
  ASSERT_EQ(ratings->size(), 1u);
  EXPECT_EQ((*ratings)[0].scores[2], 9);
  EXPECT_EQ((*ratings)[0].evaluator_group, "chief");
}

TEST_P(StoreTest, BadSubmissionsWriteNothing) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  Submission s = Valid("bad1");
  s.scores[4] = 10.01;
  EXPECT_EQ(store_->SubmitEvaluation(s).error().field, "scores[4]");
  s = Valid("bad2");
  s.scores[0] = std::nan("");
  EXPECT_FALSE(store_->SubmitEvaluation(s).ok());
  s = Valid("bad3");
  s.evaluator_group = "resident";
  EXPECT_EQ(store_->SubmitEvaluation(s).error().field, "evaluator_group");
  s = Valid("bad4");
  s.subject_kind = SubjectKind::kSession;
  s.subject = "4711";
  EXPECT_EQ(store_->SubmitEvaluation(s).error().code, ErrorCode::kNotFound);
  s.subject = "12; DROP TABLE evaluations";
  EXPECT_EQ(store_->SubmitEvaluation(s).error().code, ErrorCode::kInvalidArgument);
  s = Valid("bad5");
  s.subject_kind = SubjectKind::kTrainee;
  s.subject = "nobody";
  EXPECT_EQ(store_->SubmitEvaluation(s).error().code, ErrorCode::kNotFound);
  EXPECT_EQ(Rows(), 0);
  // The evaluator keeps one group: a later row claiming another is refused.
  ASSERT_TRUE(store_->SubmitEvaluation(Valid("ok")).ok());
  s = Valid("bad6", "dr-a", "msm");
  s.evaluator_group = "intern";
  EXPECT_EQ(store_->SubmitEvaluation(s).error().field, "evaluator_group");
  EXPECT_EQ(Rows(), 9);
  EXPECT_EQ(store_->IntegrityCheck().value(), "ok");
}

TEST_P(StoreTest, GroupCommitBatchesABurstAndAFailedJobRollsBackAlone) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  constexpr int kN = 600;
  std::atomic<int> ok{0}, failed{0};
  std::promise<void> all;
  std::atomic<int> left{kN};
  for (int i = 0; i < kN; ++i) {
    Submission s = Valid("burst-" + std::to_string(i), "dr-" + std::to_string(i));
    if (i % 10 == 3) s.subject_kind = SubjectKind::kSession, s.subject = "999";  // no session
    store_->SubmitEvaluationAsync(s, [&](Expected<SubmitResult> r) {
      (r.ok() ? ok : failed).fetch_add(1);
      if (left.fetch_sub(1) == 1) all.set_value();
    });
  }
  all.get_future().wait();
  EXPECT_EQ(ok.load(), kN - kN / 10);
  EXPECT_EQ(failed.load(), kN / 10);
  EXPECT_EQ(Rows(), 9 * (kN - kN / 10));
  const StoreStats st = store_->stats();
  EXPECT_LT(st.commits, st.jobs / 4) << "a burst should share commits";
  // Every commit timed into one bucket; refused jobs are not the store failing.
  uint64_t timed = 0;
  for (uint64_t n : st.commit_buckets) timed += n;
  EXPECT_EQ(timed, st.commits);
  EXPECT_GT(st.commit_seconds, 0);
  EXPECT_GE(st.failed_jobs, static_cast<uint64_t>(kN / 10));
  EXPECT_EQ(st.failed_commits, 0u);
  EXPECT_EQ(st.queued, 0u);
}

TEST_P(StoreTest, SessionsRecordTheirLifeCycleAndMetrics) {
  auto s = store_->CreateSession("trainee-1", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_TRUE(store_->SetSessionState(s->id, SessionState::kRunning, 100).ok());
  scoring::TrialMetrics m;
  m.completed = true;
  m.score = 8.5;
  m.peak_force = 2.5;
  m.link = {3.25, 0.5, 112.5, 4.25, 0.02, 998};
  ASSERT_TRUE(store_->EndSession(s->id, SessionState::kEnded, 200, "stopped by trainee", m).ok());
  const auto recorded = store_->GetTrialMetrics(s->id);
  ASSERT_TRUE(recorded.ok() && recorded->has_value());
  EXPECT_EQ((*recorded)->link.station_peak_force, 3.25);
  EXPECT_EQ((*recorded)->link.station_time_over_limit, 0.5);
  EXPECT_EQ((*recorded)->link.rtt_ms, 112.5);
  EXPECT_EQ((*recorded)->link.jitter_ms, 4.25);
  EXPECT_EQ((*recorded)->link.loss, 0.02);
  EXPECT_EQ((*recorded)->link.rate_hz, 998);
  EXPECT_EQ(store_->SetSessionState(777, SessionState::kEnded, 300).error().code,
            ErrorCode::kNotFound);
  // An ended session never changes again, and its trial is recorded once.
  EXPECT_EQ(store_->SetSessionState(s->id, SessionState::kRunning, 250).error().code,
            ErrorCode::kFailedPrecondition);
  scoring::TrialMetrics again = m;
  again.score = 10;
  EXPECT_EQ(store_->EndSession(s->id, SessionState::kDisconnected, 300, "late", again).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->EndSession(s->id, SessionState::kRunning, 300, "", m).error().code,
            ErrorCode::kInvalidArgument);
  auto got = store_->GetSession(s->id);
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->state, SessionState::kEnded);
  EXPECT_EQ(got->started_us, 100);
  EXPECT_EQ(got->ended_us, 200);
  EXPECT_EQ(got->end_reason, "stopped by trainee");
  EXPECT_EQ(store_->GetTrialMetrics(s->id).value()->score, 8.5);
  EXPECT_EQ(store_->ListSessions(std::string("trainee-1")).value().size(), 1u);
  EXPECT_EQ(store_->ListSessions(std::string("someone")).value().size(), 0u);
  ASSERT_TRUE(store_->RecordTrainingMoment("trainee-1", 20, s->id).ok());
  EXPECT_FALSE(store_->RecordTrainingMoment("trainee-1", 20, s->id).ok());  // once per moment
}

TEST_P(StoreTest, EndedSessionsAreRecordsFoundByFiltersAndPages) {
  // Five trials: trainee-1 on the arm (scores 2, 5, 8) and on the kidney (9), trainee-2 on the
  // arm (6); one of trainee-1's still live; the second has a record.
  struct Trial {
    const char* trainee;
    const char* scene;
    double score;
  };
  const Trial trials[] = {{"trainee-1", "arm-torsion", 2},
                          {"trainee-1", "arm-torsion", 5},
                          {"trainee-1", "arm-torsion", 8},
                          {"trainee-1", "kidney-palpation", 9},
                          {"trainee-2", "arm-torsion", 6}};
  std::vector<int64_t> ids;
  for (const Trial& t : trials) {
    auto s = store_->CreateSession(t.trainee, t.scene);
    ASSERT_TRUE(s.ok()) << s.error().message;
    ids.push_back(s->id);
    ASSERT_TRUE(store_->SetSessionState(s->id, SessionState::kRunning, 100).ok());
    scoring::TrialMetrics m;
    m.score = t.score;
    m.completed = t.score >= 5;
    const std::string trace = ids.size() == 2 ? R"({"series":{"time_s":[0,0.1]}})" : "";
    ASSERT_TRUE(store_->EndSession(s->id, SessionState::kEnded, 200, "done", m, {}, trace).ok());
  }
  const int64_t live = store_->CreateSession("trainee-1", "arm-torsion").value().id;

  EXPECT_EQ(store_->GetSessionTrace(ids[1]).value(), R"({"series":{"time_s":[0,0.1]}})");
  EXPECT_EQ(store_->GetSessionTrace(ids[0]).error().code, ErrorCode::kNotFound);
  // A record is valid JSON or nothing: the store refuses a broken one with the trial.
  auto bad = store_->CreateSession("trainee-2", "arm-torsion").value().id;
  EXPECT_FALSE(store_->EndSession(bad, SessionState::kEnded, 300, "", {}, {}, "{broken").ok());
  EXPECT_TRUE(IsLive(store_->GetSession(bad)->state));  // nothing of it was written

  SessionQuery all;
  auto page = store_->FindSessions(all).value();
  EXPECT_EQ(page.total, 5);  // the two live ones are not records
  ASSERT_EQ(page.rows.size(), 5u);
  EXPECT_EQ(page.rows.front().record.id, ids.back());  // newest first
  for (const SessionRow& r : page.rows) EXPECT_NE(r.record.id, live);
  EXPECT_TRUE(page.rows[3].has_trace);
  EXPECT_FALSE(page.rows[4].has_trace);
  EXPECT_EQ(page.rows[4].score, 2);
  EXPECT_FALSE(page.rows[4].completed);

  SessionQuery q;
  q.trainee = "trainee-1";
  q.scene = "arm-torsion";
  q.min_score = 4;
  page = store_->FindSessions(q).value();
  EXPECT_EQ(page.total, 2);  // 5 and 8
  ASSERT_EQ(page.rows.size(), 2u);
  EXPECT_EQ(page.rows[0].score, 8);
  EXPECT_EQ(page.rows[1].score, 5);
  q = {};
  q.max_score = 5.5;
  EXPECT_EQ(store_->FindSessions(q)->total, 2);  // 2 and 5
  q = {};
  q.search = "ney";  // kidney-palpation, by a part of the scene's name
  EXPECT_EQ(store_->FindSessions(q)->total, 1);
  q.search = "inee-2";  // trainee-2, by a part of the name
  EXPECT_EQ(store_->FindSessions(q)->total, 1);
  q.search = "%";  // taken literally, not as a wildcard
  EXPECT_EQ(store_->FindSessions(q)->total, 0);
  q = {};
  q.limit = 2;
  q.offset = 4;
  page = store_->FindSessions(q).value();
  EXPECT_EQ(page.total, 5);
  ASSERT_EQ(page.rows.size(), 1u);  // the last page holds the oldest
  EXPECT_EQ(page.rows[0].record.id, ids.front());
  q = {};
  q.from_us = NowUs() + 60'000'000;  // nothing created in the future
  EXPECT_EQ(store_->FindSessions(q)->total, 0);
  q = {};
  q.ended_only = false;
  EXPECT_EQ(store_->FindSessions(q)->total, 7);
  q.limit = 0;
  EXPECT_EQ(store_->FindSessions(q).error().field, "limit");

  // Ratings of a session carry their moment and comment; too long a comment is refused.
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  Submission sub = Valid("k-session");
  sub.subject_kind = SubjectKind::kSession;
  sub.subject = std::to_string(ids[1]);
  sub.comment = "Steady twist; eased off at the target. Work on a smoother approach.";
  auto submitted = store_->SubmitEvaluation(sub);
  ASSERT_TRUE(submitted.ok()) << submitted.error().message;
  auto on = store_->ListSubmissionsOn(SubjectKind::kSession, sub.subject).value();
  ASSERT_EQ(on.size(), 1u);
  EXPECT_EQ(on[0].comment, sub.comment);
  EXPECT_EQ(on[0].evaluator, "dr-a");
  EXPECT_EQ(on[0].evaluator_group, "chief");
  EXPECT_EQ(on[0].scores[0], 8);
  EXPECT_EQ(store_->ListSubmissionsBy("dr-a", 10).value().at(0).comment, sub.comment);
  Submission chatty = Valid("k-long");
  chatty.comment.assign(kMaxComment + 1, 'x');
  EXPECT_EQ(store_->SubmitEvaluation(chatty).error().field, "comment");
}

TEST_P(StoreTest, SessionsAKilledServerLeftLiveAreAbortedAtStartUp) {
  auto ended = store_->CreateSession("trainee-1", "arm-torsion");
  auto running = store_->CreateSession("trainee-1", "arm-torsion");
  auto created = store_->CreateSession("trainee-2", "sphere-palpation-256");
  ASSERT_TRUE(ended.ok() && running.ok() && created.ok());
  ASSERT_TRUE(store_->SetSessionState(ended->id, SessionState::kEnded, 200, "done").ok());
  ASSERT_TRUE(store_->SetSessionState(running->id, SessionState::kRunning, 300).ok());
  EXPECT_EQ(store_->AbortOrphanedSessions(900, "server restarted").value(), 2);
  EXPECT_EQ(store_->GetSession(ended->id)->state, SessionState::kEnded);
  EXPECT_EQ(store_->GetSession(ended->id)->end_reason, "done");
  for (int64_t id : {running->id, created->id}) {
    const auto r = store_->GetSession(id);
    EXPECT_EQ(r->state, SessionState::kAborted);
    EXPECT_EQ(r->ended_us, 900);
    EXPECT_EQ(r->end_reason, "server restarted");
  }
  EXPECT_EQ(store_->AbortOrphanedSessions(901, "again").value(), 0);
}

TEST(PostgresDialectTest, TheSchemaMapsToSixtyFourBitDoublePrecisionAndIdentityColumns) {
  const std::string ddl = PgConnection::PostgresDialect(Migrations()[0]);
  for (const char* gone : {"INTEGER", " REAL", "BLOB", "WITHOUT ROWID", "json_valid", "ifnull"})
    EXPECT_EQ(ddl.find(gone), std::string::npos) << gone;
  EXPECT_NE(ddl.find("id          BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY"),
            std::string::npos);
  EXPECT_NE(ddl.find("session_id              BIGINT PRIMARY KEY"), std::string::npos)
      << "a key that is not a row id stays a plain column";
  EXPECT_NE(ddl.find("hash        BYTEA"), std::string::npos);
  EXPECT_NE(ddl.find("score         DOUBLE PRECISION"), std::string::npos);
  EXPECT_NE(ddl.find("(json::jsonb IS NOT NULL)"), std::string::npos);

  int params = 0;
  EXPECT_EQ(PgConnection::Renumber("a = ?1 AND b = '?2' AND c = ?12", params).value(),
            "a = $1 AND b = '?2' AND c = $12");
  EXPECT_EQ(params, 12);
  EXPECT_FALSE(PgConnection::Renumber("a = ?", params).ok());
  EXPECT_FALSE(PgConnection::Renumber("a = ?0", params).ok());
}

// Several control replicas on one PostgreSQL: each opens the store (migrating it once between
// them), and each has its own writer.
class SharedStoreTest : public ::testing::Test {
 protected:
  static Submission Valid(const std::string& key, const std::string& evaluator) {
    Submission s;
    s.idempotency_key = key;
    s.evaluator = evaluator;
    s.evaluator_group = "chief";
    s.subject_kind = SubjectKind::kModel;
    s.subject = "coil-spring";
    s.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
    s.submitted_by = "root";
    return s;
  }
  test::PostgresDatabase db_;
};

TEST_F(SharedStoreTest, ReplicasMigrateOnceAndShareEveryAcknowledgedWrite) {
  std::vector<std::future<Expected<std::unique_ptr<Store>>>> opening;
  for (int i = 0; i < 3; ++i)
    opening.push_back(
        std::async(std::launch::async, [&] { return Store::Open({.path = db_.uri()}); }));
  std::vector<std::unique_ptr<Store>> replicas;
  for (auto& f : opening) {
    auto s = f.get();
    ASSERT_TRUE(s.ok()) << s.error().message;
    replicas.push_back(std::move(s).value());
  }
  ASSERT_TRUE(replicas[0]->InitAdmin("root").ok());
  EXPECT_EQ(replicas[1]->InitAdmin("root2").error().code, ErrorCode::kAlreadyExists);

  // Bursts through all three at once: every acknowledged submission is there, from any replica.
  constexpr int kEach = 200;
  std::atomic<int> acknowledged{0};
  std::vector<std::thread> writers;
  for (int r = 0; r < 3; ++r)
    writers.emplace_back([&, r] {
      std::vector<std::future<bool>> done;
      for (int i = 0; i < kEach; ++i) {
        auto p = std::make_shared<std::promise<bool>>();
        done.push_back(p->get_future());
        const std::string id = std::to_string(r) + "-" + std::to_string(i);
        replicas[r]->SubmitEvaluationAsync(Valid("k" + id, "dr-" + id),
                                           [p](Expected<SubmitResult> x) { p->set_value(x.ok()); });
      }
      for (auto& f : done) acknowledged += f.get() ? 1 : 0;
    });
  for (auto& t : writers) t.join();
  EXPECT_EQ(acknowledged.load(), 3 * kEach);
  for (auto& replica : replicas) EXPECT_EQ(replica->CountEvaluationRows().value(), 9 * 3 * kEach);

  // A client retrying on another replica with the same key gets the first result.
  auto first = replicas[0]->SubmitEvaluation(Valid("retry", "dr-retry"));
  auto retry = replicas[2]->SubmitEvaluation(Valid("retry", "dr-retry"));
  ASSERT_TRUE(first.ok() && retry.ok());
  EXPECT_TRUE(retry->duplicate);
  EXPECT_EQ(retry->submission_id, first->submission_id);
}

TEST_F(SharedStoreTest, ALostConnectionAcknowledgesNothingAndTheNextWriteReconnects) {
  auto store = Store::Open({.path = db_.uri()});
  ASSERT_TRUE(store.ok()) << store.error().message;
  ASSERT_TRUE((*store)->InitAdmin("root").ok());
  ASSERT_TRUE((*store)->SubmitEvaluation(Valid("before", "dr-a")).ok());
  // The server drops every connection of this database (a restart or a failover looks the same).
  test::PostgresAdmin("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = '" +
                      db_.uri().substr(db_.uri().rfind('/') + 1) + "' AND pid <> pg_backend_pid()");
  // The first write after the loss fails (never acknowledged) or, when the loss was noticed
  // first, succeeds on a new connection; in both cases what is acknowledged is stored.
  int stored = 1;
  for (int i = 0; i < 3; ++i) {
    auto r =
        (*store)->SubmitEvaluation(Valid("after" + std::to_string(i), "dr-" + std::to_string(i)));
    if (r.ok()) {
      ++stored;
    } else {
      EXPECT_EQ(r.error().code, ErrorCode::kUnavailable) << r.error().message;
    }
  }
  EXPECT_GE(stored, 3) << "the store reconnects";
  auto rows = (*store)->CountEvaluationRows();
  if (!rows.ok()) rows = (*store)->CountEvaluationRows();  // a pooled reader met the loss
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  EXPECT_EQ(*rows, 9 * stored);
}

TEST(SessionStateTest, NamesAndWireNumbersRoundTrip) {
  for (int n = 1; n <= 6; ++n) {
    const auto s = SessionStateFromNumber(n);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(static_cast<int>(*s), n);
    EXPECT_EQ(ParseSessionState(SessionStateName(*s)), s);
  }
  EXPECT_FALSE(SessionStateFromNumber(0).has_value());
  EXPECT_FALSE(SessionStateFromNumber(7).has_value());
  EXPECT_FALSE(ParseSessionState("exploded").has_value());
  EXPECT_TRUE(IsLive(SessionState::kStalled));
  EXPECT_FALSE(IsLive(SessionState::kDisconnected));
}

// The training programme's rows on both backends: a course with its exercises in order, a
// cohort, enrolments that reach a member, experts, and the attempts read back in one query.
TEST_P(StoreTest, ATrainingProgrammeIsKeptAndItsAttemptsReadBack) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  ASSERT_TRUE(store_->CreateUser("ian", Role::kInstructor, "").ok());
  CourseRecord c;
  c.name = "Basics";
  c.owner = "ian";
  c.exercises = {{0, 0, 0, "Press", "sphere", R"({"targets":[]})"},
                 {0, 0, 0, "Twist", "arm", R"({"targets":[]})"}};
  auto made = store_->CreateCourse(c);
  ASSERT_TRUE(made.ok()) << made.error().message;
  EXPECT_EQ(made->exercises[1].position, 2);
  EXPECT_EQ(store_->CreateCourse(c).error().code, ErrorCode::kAlreadyExists);
  c.name = "Broken";
  c.exercises[0].spec_json = "{not json";
  EXPECT_FALSE(store_->CreateCourse(c).ok());
  EXPECT_EQ(store_->ListCourses()->size(), 1u);  // nothing of the broken one was kept
  auto cohort = store_->CreateCohort("Residents", "ian", {"tina", "tom", "tina"});
  ASSERT_TRUE(cohort.ok()) << cohort.error().message;
  EXPECT_EQ(store_->GetCohort(cohort->id)->members, (std::vector<std::string>{"tina", "tom"}));
  EnrolmentRecord e;
  e.course_id = made->id;
  e.cohort_id = cohort->id;
  ASSERT_TRUE(store_->Enrol(e).ok());
  e.cohort_id = 999;
  EXPECT_EQ(store_->Enrol(e).error().code, ErrorCode::kNotFound);
  e.cohort_id.reset();
  EXPECT_EQ(store_->Enrol(e).error().field, "cohort");  // neither a cohort nor a trainee
  EXPECT_EQ(store_->ListEnrolments("tina")->size(), 1u);
  EXPECT_TRUE(store_->ListEnrolments("una")->empty());
  ASSERT_TRUE(store_->SetExpert("tom", true).ok());
  EXPECT_EQ(store_->SetExpert("nobody", true).error().code, ErrorCode::kNotFound);
  EXPECT_EQ(*store_->ListExperts(), std::vector<std::string>{"tom"});
  // Two trials of tina at the press, one of tom on the sphere outside the course.
  scoring::TrialMetrics m;
  m.completed = true;
  m.completion_time = 12;
  m.peak_force = 1.5;
  m.score = 7;
  for (const char* who : {"tina", "tina", "tom"}) {
    auto s = store_->CreateSession(who, "sphere");
    ASSERT_TRUE(s.ok());
    if (std::string(who) == "tina") {
      ASSERT_TRUE(store_->SetSessionExercise(s->id, made->exercises[0].id).ok());
    }
    ASSERT_TRUE(store_->EndSession(s->id, SessionState::kEnded, NowUs(), "done", m).ok());
    EXPECT_EQ(store_->SetSessionExercise(s->id, made->exercises[0].id).error().code,
              ErrorCode::kFailedPrecondition);  // ended: no longer
  }
  auto attempts = store_->LoadAttempts(made->id, "", cohort->id);
  ASSERT_TRUE(attempts.ok()) << attempts.error().message;
  ASSERT_EQ(attempts->size(), 2u);
  EXPECT_EQ((*attempts)[0].trainee, "tina");
  EXPECT_EQ((*attempts)[0].exercise_id, made->exercises[0].id);
  EXPECT_DOUBLE_EQ((*attempts)[1].metrics.peak_force, 1.5);
  EXPECT_TRUE(store_->LoadAttempts(made->id, "tom", 0)->empty());
  EXPECT_EQ(store_->LoadExpertAttempts("sphere")->size(), 1u);
}

// A PostgreSQL that would lose acknowledged writes in a power cut (fsync off) is refused for
// writing, by name; reading from it (an export) is still allowed.
TEST(StorePostgresDurabilityTest, AServerWithFsyncOffIsRefused) {
  test::TempDir dir("pg_fsync_off");
  const std::string script = std::string(VSURG_SOURCE_DIR) + "/deploy/postgres.sh";
  const std::string data = (dir / "pg").string();
  ASSERT_EQ(
      std::system(("VSURG_PG_SETTINGS='-c fsync=off' " + script + " start " + data + " >/dev/null")
                      .c_str()),
      0);
  std::string uri;
  std::getline(std::ifstream(data + "/uri"), uri);
  auto s = Store::Open({.path = uri});
  const int stopped = std::system((script + " stop " + data).c_str());
  EXPECT_EQ(stopped, 0);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kFailedPrecondition);
  EXPECT_NE(s.error().message.find("fsync = off"), std::string::npos) << s.error().message;
}

}  // namespace
}  // namespace vsurg::db
