// vsurg-server as a real process: SIGKILL during a burst of submissions loses nothing that was
// acknowledged and leaves a sound database; SIGTERM shuts down cleanly and records the sessions
// it aborts.
#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "db/store.h"
#include "tests/support/processes.h"
#include "tests/support/temp_dir.h"
#include "vsurg/v1/services.grpc.pb.h"

extern char** environ;

namespace vsurg {
namespace {

namespace fs = std::filesystem;

using test::Shell;
using test::ShellRun;

struct ServerProcess : test::ServerProcess {
  static test::ServerProcess Start(const fs::path& dir, const fs::path& db) {
    return test::ServerProcess::Start(VSURG_SERVER_BINARY, dir, db);
  }
};

std::unique_ptr<grpc::ClientContext> Ctx(const std::string& token) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->AddMetadata("authorization", "Bearer " + token);
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  return ctx;
}

v1::SubmitEvaluationRequest Submission(const std::string& evaluator) {
  v1::SubmitEvaluationRequest r;
  r.set_idempotency_key("crash-" + evaluator);
  r.set_evaluator(evaluator);
  r.set_evaluator_group("chief");
  r.set_subject_kind("model");
  r.set_subject("crash-model");
  for (int j = 0; j < 9; ++j) r.add_scores(5 + 0.5 * (j % 3));
  return r;
}

TEST(ServerProcessTest, SigkillDuringABurstLosesNothingAcknowledged) {
  const test::TempDir dir("crash");
  const fs::path db = dir / "vsurg.db";
  std::string token;
  {
    auto store = db::Store::Open({.path = db.string()});
    ASSERT_TRUE(store.ok());
    token = (*store)->InitAdmin("root").value();
  }

  auto server = ServerProcess::Start(dir, db);
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(server.grpc_port),
                                     grpc::InsecureChannelCredentials());
  std::mutex mutex;
  std::set<std::string> acknowledged;
  std::atomic<bool> stop{false};
  std::atomic<int> next{0}, failures{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < 16; ++c) {
    clients.emplace_back([&] {
      auto stub = v1::EvaluationService::NewStub(channel);
      while (!stop.load()) {
        const std::string who = "rater-" + std::to_string(next.fetch_add(1));
        v1::SubmitEvaluationResponse resp;
        if (stub->Submit(Ctx(token).get(), Submission(who), &resp).ok()) {
          std::lock_guard lock(mutex);
          acknowledged.insert(who);
        } else if (failures.fetch_add(1) > 200) {
          return;  // the server is gone
        }
      }
    });
  }
  // Kill it in the middle of the burst.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (;;) {
    {
      std::lock_guard lock(mutex);
      if (acknowledged.size() >= 500) break;
    }
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "the burst did not get going";
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const int status = server.Signal(SIGKILL);
  EXPECT_TRUE(WIFSIGNALED(status));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  stop = true;
  for (auto& t : clients) t.join();

  {
    auto store = db::Store::Open({.path = db.string()});
    ASSERT_TRUE(store.ok()) << store.error().message;
    EXPECT_EQ((*store)->IntegrityCheck().value(), "ok");
    auto rows = (*store)->LoadRatings(db::SubjectKind::kModel, "crash-model");
    ASSERT_TRUE(rows.ok());
    std::set<std::string> stored;
    for (const auto& r : *rows) {
      stored.insert(r.evaluator);
      EXPECT_EQ(r.scores[1], 5.5);  // every stored submission is whole
    }
    size_t missing = 0;
    for (const std::string& who : acknowledged) missing += stored.count(who) == 0;
    EXPECT_EQ(missing, 0u) << "acknowledged but lost";
    EXPECT_GE(stored.size(), acknowledged.size());
    EXPECT_EQ((*store)->CountEvaluationRows().value(), static_cast<int64_t>(9 * stored.size()));
  }

  // Restarted on the same file: serving, and an acknowledged key is still known.
  auto again = ServerProcess::Start(dir, db);
  channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(again.grpc_port),
                                grpc::InsecureChannelCredentials());
  auto stub = v1::EvaluationService::NewStub(channel);
  v1::SubmitEvaluationResponse resp;
  ASSERT_TRUE(stub->Submit(Ctx(token).get(), Submission(*acknowledged.begin()), &resp).ok());
  EXPECT_TRUE(resp.duplicate());

  // SIGTERM with a live session: a clean exit, the session recorded as aborted.
  auto sessions = v1::SessionService::NewStub(channel);
  v1::CreateSessionRequest create;
  create.set_trainee("tina");
  create.set_scene("sphere-palpation-256");
  v1::CreateSessionResponse created;
  ASSERT_TRUE(sessions->Create(Ctx(token).get(), create, &created).ok());
  v1::SessionRef ref;
  ref.set_id(created.session().id());
  v1::Session s;
  ASSERT_TRUE(sessions->Start(Ctx(token).get(), ref, &s).ok());
  const int term = again.Signal(SIGTERM);
  ASSERT_TRUE(WIFEXITED(term));
  EXPECT_EQ(WEXITSTATUS(term), 0);
  auto store = db::Store::Open({.path = db.string()});
  ASSERT_TRUE(store.ok());
  auto rec = (*store)->GetSession(static_cast<int64_t>(created.session().id()));
  ASSERT_TRUE(rec.ok());
  EXPECT_EQ(rec->state, SessionState::kAborted);
  EXPECT_GT(rec->ended_us, 0);
  EXPECT_TRUE((*store)->GetTrialMetrics(rec->id).value().has_value());
  store->reset();
  fs::remove_all(dir);
}

// A fresh store initialised by `vsurg-server init` (its first administrator's token) and a
// vsurg-server on it; `remote` is the options every vsurg-admin call against it takes.
struct AdminCliSetup {
  test::TempDir dir;
  fs::path db;
  std::string admin = VSURG_ADMIN_BINARY, server_bin = VSURG_SERVER_BINARY, token, remote;
  test::ServerProcess server;
  explicit AdminCliSetup(const std::string& name) : dir(name), db(dir / "vsurg.db") {
    const ShellRun init = Shell(server_bin + " init --db " + db.string() + " 2>/dev/null");
    EXPECT_EQ(init.code, 0);
    token = init.out.substr(0, init.out.find('\n'));
    server = ServerProcess::Start(dir, db);
    remote = " --server 127.0.0.1:" + std::to_string(server.grpc_port) + " --token " + token;
  }
  ~AdminCliSetup() { server.Signal(SIGTERM); }
};

TEST(AdminCliTest, InitImportReportAndExportThroughTheServer) {
  AdminCliSetup setup("vsurg_admin_cli");
  const fs::path& dir = setup.dir;
  const fs::path& db = setup.db;
  const std::string& admin = setup.admin;
  const std::string& token = setup.token;
  const std::string& remote = setup.remote;
  test::ServerProcess& server = setup.server;
  EXPECT_EQ(token.rfind("vst_", 0), 0u);
  EXPECT_EQ(Shell(setup.server_bin + " init --db " + db.string() + " 2>/dev/null").code,
            1);  // once only
  // vsurg-admin is a pure gRPC client: it says where init went and touches no file.
  const ShellRun moved = Shell(admin + " init --db " + (dir / "other.db").string() + " 2>&1");
  EXPECT_EQ(moved.code, 2);
  EXPECT_NE(moved.out.find("vsurg-server init"), std::string::npos) << moved.out;
  EXPECT_FALSE(fs::exists(dir / "other.db"));
  const ShellRun import =
      Shell(admin + " import" + remote +
            " --input " VSURG_SAMPLES_DIR "/ratings-three-models.csv --subject-kind model");
  ASSERT_EQ(import.code, 0) << import.out;
  EXPECT_NE(import.out.find("imported 120"), std::string::npos) << import.out;
  const ShellRun report =
      Shell(admin + " report" + remote + " --subject-kind model --subjects coil-spring --json");
  ASSERT_EQ(report.code, 0);
  const auto j = nlohmann::json::parse(report.out);
  EXPECT_EQ(j["raters"], 40);
  EXPECT_EQ(j["index_means"].size(), 9u);

  const fs::path csv = dir / "scores.csv";
  ASSERT_EQ(
      Shell(admin + " export" + remote + " --format csv --out " + csv.string() + " 2>/dev/null")
          .code,
      0);
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("submission_id,submitted_at,evaluator,evaluator_group", 0), 0u);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  EXPECT_EQ(lines, 120 * 9);
  // The same export from the store file directly, read-only beside the running server.
  const fs::path local = dir / "local.csv";
  const std::string offline = setup.server_bin + " export --db ";
  ASSERT_EQ(
      Shell(offline + db.string() + " --format csv --out " + local.string() + " 2>/dev/null").code,
      0);
  EXPECT_EQ(fs::file_size(local), fs::file_size(csv));
  // A mistyped store path is an error and creates nothing; vsurg-admin has no --db any more.
  const fs::path typo = dir / "vsurg-typo.db";
  const ShellRun mistyped =
      Shell(offline + typo.string() + " --out " + (dir / "t.csv").string() + " 2>&1");
  EXPECT_EQ(mistyped.code, 2);
  EXPECT_NE(mistyped.out.find("no database file"), std::string::npos) << mistyped.out;
  EXPECT_FALSE(fs::exists(typo));
  EXPECT_FALSE(fs::exists(dir / "t.csv"));
  EXPECT_EQ(Shell(admin + " export --db " + db.string() + " --out y 2>/dev/null").code, 2);
  // An offline backup is a complete copy, and never overwrites.
  const fs::path copy = dir / "copy.db";
  const std::string backup = setup.server_bin + " backup --db " + db.string() + " --out ";
  ASSERT_EQ(Shell(backup + copy.string() + " 2>/dev/null").code, 0);
  const fs::path from_copy = dir / "from-copy.csv";
  ASSERT_EQ(Shell(offline + copy.string() + " --out " + from_copy.string() + " 2>/dev/null").code,
            0);
  EXPECT_EQ(fs::file_size(from_copy), fs::file_size(csv));
  EXPECT_EQ(Shell(backup + copy.string() + " 2>/dev/null").code, 2);

  // Bad arguments exit 2; a bad token exits 1 and names the cause.
  EXPECT_EQ(Shell(admin + " export" + remote + " --format pdf --out x 2>/dev/null").code, 2);
  EXPECT_EQ(Shell(admin + " export" + remote + " --from yesterday --out x 2>/dev/null").code, 2);
  EXPECT_EQ(Shell(admin + " frobnicate 2>/dev/null").code, 2);
  const ShellRun bad =
      Shell(admin + " users --server 127.0.0.1:" + std::to_string(server.grpc_port) +
            " --token vst_wrong 2>&1");
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.out.find("unknown token"), std::string::npos) << bad.out;
  EXPECT_FALSE(fs::exists(dir / "x"));
}

// Import keys cover the whole (kind, subject, evaluator) tuple: a long subject no longer makes
// two evaluators collide (their keys were cut at 128 characters), and a re-import says what
// happened to each row: identical rows are unchanged, corrected ones are refused and reported.
TEST(AdminCliTest, ImportSaysWhatHappenedToEachRowAndLongSubjectsNeverCollide) {
  AdminCliSetup setup("vsurg_admin_import");
  const fs::path& dir = setup.dir;
  const std::string& admin = setup.admin;
  const std::string& remote = setup.remote;
  const std::string subject(200, 'm');
  auto write_csv = [&](const fs::path& path, double chief_first) {
    std::ofstream out(path);
    out << "evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9,subject\n";
    out << "dr-a,intern,7,7,7,7,7,7,7,7,7," << subject << "\n";
    out << "dr-b,chief," << chief_first << ",8,8,8,8,8,8,8,8," << subject << "\n";
  };
  write_csv(dir / "first.csv", 8);
  write_csv(dir / "corrected.csv", 9);
  const std::string import = admin + " import" + remote + " --subject-kind model --input ";
  const ShellRun first = Shell(import + (dir / "first.csv").string() + " 2>&1");
  EXPECT_EQ(first.code, 0) << first.out;
  EXPECT_NE(first.out.find("imported 2 evaluations (0 unchanged, 0 refused)"), std::string::npos)
      << first.out;
  const ShellRun again = Shell(import + (dir / "first.csv").string() + " 2>&1");
  EXPECT_EQ(again.code, 0) << again.out;
  EXPECT_NE(again.out.find("line 2 (dr-a on " + subject + "): unchanged"), std::string::npos)
      << again.out;
  EXPECT_NE(again.out.find("imported 0 evaluations (2 unchanged, 0 refused)"), std::string::npos);
  const ShellRun corrected = Shell(import + (dir / "corrected.csv").string() + " 2>&1");
  EXPECT_EQ(corrected.code, 1) << corrected.out;
  EXPECT_NE(corrected.out.find("line 3 (dr-b on " + subject + "): refused:"), std::string::npos)
      << corrected.out;
  EXPECT_NE(corrected.out.find("differs"), std::string::npos) << corrected.out;
  EXPECT_NE(corrected.out.find("(1 unchanged, 1 refused)"), std::string::npos) << corrected.out;
  // The stored scores are the first ones: nothing was silently replaced or dropped.
  const ShellRun report =
      Shell(admin + " report" + remote + " --subject-kind model --subjects " + subject + " --json");
  ASSERT_EQ(report.code, 0) << report.out;
  const auto j = nlohmann::json::parse(report.out);
  EXPECT_EQ(j["raters"], 2);
  EXPECT_NEAR(j["index_means"][0].get<double>(), (0.2 * 7 + 0.5 * 8) / 0.7, 1e-9);
}

// The site roles refuse what cannot work, before opening anything: exit 2 with the flag named.
TEST(ServerRolesCliTest, BadRoleSettingsExitTwoNamingTheFlag) {
  const test::TempDir dir("roles_cli");
  const std::string token = (dir / "token").string();
  std::ofstream(token) << "a-cluster-token-of-32-characters\n";
  const std::string server = std::string(VSURG_SERVER_BINARY) + " ";
  const std::string pg = " --db postgresql://vsurg@127.0.0.1:1/vsurg";
  struct Case {
    std::string args, says;
  };
  for (const Case& c : std::vector<Case>{
           {"--role leader" + pg, "--role: must be all, control or sim"},
           {"--role control --db " + (dir / "x.db").string() + " --cluster-token-file " + token,
            "a postgresql:// URI is required"},
           {"--role sim" + pg + " --control 127.0.0.1:7000", "--cluster-token-file: required"},
           {"--role sim" + pg + " --cluster-token-file " + token, "--control: required"},
           {"--role control" + pg + " --cluster-token-file " + (dir / "missing").string(),
            "--cluster-token-file: cannot read"},
           {"--role control" + pg + " --cluster-token-file " + token +
                " --cluster-heartbeat-timeout 0.9",
            "--cluster-heartbeat-timeout: less 0.25 s of margin, must last two heartbeat"},
           {"--role control" + pg + " --cluster-token-file " + token +
                " --cluster-heartbeat-timeout 500",
            "--cluster-heartbeat-timeout: must be within 0.1..120"},
           {"--role sim" + pg + " --control 127.0.0.1:7000 --cluster-token-file " + token +
                " --cluster-heartbeat-period 0",
            "--cluster-heartbeat-period: must be within 0.05..10"},
           {"--db " + (dir / "x.db").string() + " --max-sessions 4 --max-sessions-per-user 5",
            "--max-sessions-per-user: must be at most --max-sessions"},
           {"--role control" + pg + " --cluster-token-file " + token +
                " --cluster-heartbeat-timeout nan",
            "--cluster-heartbeat-timeout"},
           {"--db " + (dir / "x.db").string() + " --quasi-static-interval-ms 500",
            "--quasi-static-interval-ms: must be within 0..100"},
           {"--db " + (dir / "x.db").string() + " --quasi-static-interval-ms nan",
            "--quasi-static-interval-ms: 'nan' is not a finite number"},
           {"--role sim" + pg + " --control 127.0.0.1:7000 --cluster-token-file " + token +
                " --capacity -1",
            "--capacity: must be within 0..4096"},
           {"--role sim --control 127.0.0.1:7000", "vsurg-server: --db: is required"},
       }) {
    const ShellRun r = Shell(server + c.args + " 2>&1");
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.says), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(r.out.find("----"), std::string::npos) << "the flag's dashes once: " << r.out;
  }
  EXPECT_FALSE(fs::exists(dir / "x.db")) << "nothing was created";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vsurg
