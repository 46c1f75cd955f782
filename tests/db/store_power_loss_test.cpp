// The store's promise under a power cut, not only a killed process: everything acknowledged is
// on the disk the machine finds when it comes back, and the store opens without repair.
//
// SQLite: the store runs on tests/support/power_cut_vfs.h, which keeps what was synced apart from
// what was only written; the power goes at a chosen I/O call, losing all, none, a random subset of
// the unsynced writes, or a random subset of their sectors (torn writes). The workload is the
// server's own writes: sessions created, started and ended with their trial metrics, and
// evaluations submitted. After the cut the disk image is opened as a new store: it passes
// PRAGMA integrity_check, and every acknowledged row is there.
//
// PostgreSQL keeps its own promise by its settings, which the store checks at open
// (db/postgres.cpp: fsync and full_page_writes on, synchronous_commit on for the store's
// sessions); tests/db/store_test.cpp reads them back.
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "db/store.h"
#include "tests/support/power_cut_vfs.h"
#include "tests/support/temp_dir.h"

namespace vsurg::db {
namespace {

namespace fs = std::filesystem;
using test::PowerCut;

// What the workload was told was done.
struct Acknowledged {
  std::vector<int64_t> created, ended;
  std::vector<std::pair<int64_t, int64_t>> evaluated;  // session, submission
  std::string last_error;                              // of the write that failed, if one did
};

// The server's writes from round `from` to `to`, one at a time; false at the first that fails
// (the power went).
bool RunRounds(Store& store, int from, int to, Acknowledged& ack) {
  for (int i = from; i < to; ++i) {
    auto s = store.CreateSession("trainee-" + std::to_string(i % 3), "arm-torsion");
    if (!s.ok()) return false;
    ack.created.push_back(s->id);
    if (!store.SetSessionState(s->id, SessionState::kRunning, 100 + i).ok()) return false;
    scoring::TrialMetrics m;
    m.score = 5 + i % 5;
    m.peak_force = 1.25;
    if (!store.EndSession(s->id, SessionState::kEnded, 200 + i, "done", m).ok()) return false;
    ack.ended.push_back(s->id);
    Submission e;
    e.idempotency_key = "k-" + std::to_string(i);
    e.evaluator = "dr-" + std::to_string(i % 2);
    e.evaluator_group = "chief";
    e.subject_kind = SubjectKind::kSession;
    e.subject = std::to_string(s->id);
    e.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
    e.submitted_by = "root";
    auto r = store.SubmitEvaluation(e);
    if (!r.ok()) {
      ack.last_error = r.error().message;
      return false;
    }
    ack.evaluated.push_back({s->id, r->submission_id});
  }
  return true;
}

// The workload on the store at `path`, with a restart of the server half way (the last
// connection's close checkpoints the WAL into the database and removes it).
Acknowledged RunWorkload(const std::string& path, int rounds) {
  Acknowledged ack;
  {
    auto store = Store::Open({.path = path});
    if (!store.ok() || !(*store)->InitAdmin("root").ok()) return ack;
    if (!RunRounds(**store, 0, rounds / 2, ack)) return ack;
  }
  auto store = Store::Open({.path = path});
  if (store.ok()) RunRounds(**store, rounds / 2, rounds, ack);
  return ack;
}

// The disk image opened as the machine would find it: sound, and holding every acknowledged row.
void ExpectAcknowledgedKept(const std::string& path, const Acknowledged& ack,
                            const std::string& where) {
  auto reopened = Store::Open({.path = path});
  ASSERT_TRUE(reopened.ok()) << where << ": " << reopened.error().message;
  Store& s = **reopened;
  EXPECT_EQ(s.IntegrityCheck().value(), "ok") << where;
  for (int64_t id : ack.created) EXPECT_TRUE(s.GetSession(id).ok()) << where << " session " << id;
  for (int64_t id : ack.ended) {
    auto rec = s.GetSession(id);
    ASSERT_TRUE(rec.ok()) << where << " session " << id;
    EXPECT_EQ(rec->state, SessionState::kEnded) << where << " session " << id;
    auto m = s.GetTrialMetrics(id);
    ASSERT_TRUE(m.ok() && m->has_value()) << where << " trial of session " << id;
    EXPECT_EQ((*m)->peak_force, 1.25) << where;
  }
  for (const auto& [session, submission] : ack.evaluated) {
    auto rows = s.ListSubmissionsOn(SubjectKind::kSession, std::to_string(session));
    ASSERT_TRUE(rows.ok()) << where;
    ASSERT_EQ(rows->size(), 1u) << where << " evaluation of session " << session;
    EXPECT_EQ((*rows)[0].id, submission) << where;
    EXPECT_EQ((*rows)[0].scores[2], 9) << where;
  }
  // The store goes on from where it was: a new write after the cut is taken and kept.
  EXPECT_TRUE(s.CreateSession("trainee-after", "arm-torsion").ok()) << where;
}

constexpr int kRounds = 6;

// The workload's I/O calls without a cut: the range the crash points are drawn from.
uint64_t IoCallsOfAFullRun() {
  test::TempDir dir("power_cut_count");
  PowerCut counter(0, PowerCut::Loss::kNoneLost, 1);
  const Acknowledged ack = RunWorkload((dir.path() / "vsurg.db").string(), kRounds);
  EXPECT_EQ(ack.evaluated.size(), static_cast<size_t>(kRounds)) << ack.last_error;
  return counter.io_calls();
}

TEST(StorePowerLossTest, EverythingAcknowledgedSurvivesACutAtAnyIoCall) {
  const uint64_t calls = IoCallsOfAFullRun();
  ASSERT_GT(calls, 50u);  // opening (the schema), then four synced writes a round
  const PowerCut::Loss kLosses[] = {PowerCut::Loss::kAllUnsynced, PowerCut::Loss::kNoneLost,
                                    PowerCut::Loss::kRandomWrites, PowerCut::Loss::kTornSectors};
  std::mt19937 pick(20261201);
  std::uniform_int_distribution<uint64_t> at(1, calls);
  constexpr int kPointsPerLoss = 50;
  int tried = 0, cut_after_an_ack = 0;
  for (const PowerCut::Loss loss : kLosses) {
    for (int n = 0; n < kPointsPerLoss; ++n, ++tried) {
      const uint64_t cut_at = at(pick);
      const std::string where = "loss " + std::to_string(static_cast<int>(loss)) + ", cut at " +
                                std::to_string(cut_at) + " of " + std::to_string(calls);
      test::TempDir live("power_cut_live"), after("power_cut_after");
      Acknowledged ack;
      {
        PowerCut power(cut_at, loss, static_cast<uint32_t>(cut_at * 7 + n));
        ack = RunWorkload((live.path() / "vsurg.db").string(), kRounds);
        EXPECT_TRUE(power.cut() || ack.evaluated.size() == kRounds) << where;
        power.WriteImage(fs::weakly_canonical(live.path()).string(), after.path().string());
      }
      cut_after_an_ack += !ack.created.empty();
      ExpectAcknowledgedKept((after.path() / "vsurg.db").string(), ack, where);
      if (HasFatalFailure() || HasFailure()) return;
    }
  }
  RecordProperty("crash_points", tried);
  std::printf(
      "power cuts tried: %d (%d after at least one acknowledged write), %llu I/O calls "
      "in a full run\n",
      tried, cut_after_an_ack, static_cast<unsigned long long>(calls));
  EXPECT_GT(cut_after_an_ack, tried / 2);  // the points reach into the workload, not only the open
}

}  // namespace
}  // namespace vsurg::db
