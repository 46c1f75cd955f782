// Sessions through the control plane: a trainee's session over UDP while an instructor watches,
// the per-trainee limit, sessions nobody drives, revoked users, backups and scene files.
#include "tests/server/control/control_plane_fixture.h"

namespace vsurg::server {
namespace {

using namespace test_control;  // the fixture and its names
using test::PressAndHold;

TEST_F(ControlPlaneTest, ATraineeRunsASessionOverUdpWhileAnInstructorWatches) {
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateSessionRequest create;
  create.set_scene("sphere-palpation-256");
  v1::CreateSessionResponse created;
  ASSERT_TRUE(sessions->Create(Ctx(db::Role::kTrainee).get(), create, &created).ok());
  EXPECT_EQ(created.session().trainee(), "tina");
  EXPECT_EQ(created.session().state(), v1::SESSION_STATE_CREATED);
  ASSERT_EQ(created.session_key().size(), 32u);
  EXPECT_EQ(created.udp_port(), endpoint_->port());
  const uint64_t id = created.session().id();

  // Another trainee may not touch it; a path is not a scene.
  v1::SessionRef ref;
  ref.set_id(id);
  v1::Session s;
  grpc::ClientContext other;
  other.AddMetadata("authorization", "Bearer " + tom_);
  other.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  EXPECT_EQ(sessions->Get(&other, ref, &s).error_code(), StatusCode::PERMISSION_DENIED);
  create.set_scene("../../etc/passwd");
  EXPECT_EQ(sessions->Create(Ctx(db::Role::kTrainee).get(), create, &created).error_code(),
            StatusCode::INVALID_ARGUMENT);
  create.set_scene("no-such-scene");
  EXPECT_EQ(sessions->Create(Ctx(db::Role::kTrainee).get(), create, &created).error_code(),
            StatusCode::NOT_FOUND);

  ASSERT_TRUE(sessions->Start(Ctx(db::Role::kTrainee).get(), ref, &s).ok());
  EXPECT_EQ(s.state(), v1::SESSION_STATE_RUNNING);

  // The instructor follows it while the station presses the tissue.
  auto monitor = v1::MonitorService::NewStub(channel_);
  v1::WatchRequest watch;
  watch.set_session_id(id);
  auto watch_ctx = Ctx(role_tokens_[db::Role::kInstructor], 30);
  auto reader = monitor->Watch(watch_ctx.get(), watch);

  client::ReplayDevice device(PressAndHold(1.5));
  client::StationOptions so;
  so.server_port = endpoint_->port();
  so.session = id;
  std::copy(created.session_key().begin(), created.session_key().end(), so.key.begin());
  auto station = client::StationChannel::Create(so, &device);
  ASSERT_TRUE(station.ok()) << station.error().message;

  v1::Telemetry t, best;
  int messages = 0, surfaces = 0, most_moved = 0;
  while (reader->Read(&t)) {
    ++messages;
    if (t.has_surface()) {
      ++surfaces;
      most_moved = std::max(most_moved, t.surface().indices_size());
      EXPECT_EQ(t.surface().positions_size(), 3 * t.surface().indices_size());
    }
    if (t.packets() > best.packets()) best = t;
    if (device.finished()) break;
  }
  (*station)->Stop();
  EXPECT_GT(messages, 10);
  EXPECT_EQ(best.session_id(), id);
  EXPECT_GT(best.packets(), 500u);
  EXPECT_TRUE(best.contact());
  EXPECT_GT(std::sqrt(best.force().x() * best.force().x() + best.force().y() * best.force().y() +
                      best.force().z() * best.force().z()),
            0.1);
  EXPECT_GT(best.rtt_us(), 0.0);
  EXPECT_GT(best.haptic_rate_hz(), 500.0);
  EXPECT_EQ(best.state(), v1::SESSION_STATE_RUNNING);
  EXPECT_FALSE(best.scene().empty());
  EXPECT_GT(std::abs(best.tip().x()) + std::abs(best.tip().y()) + std::abs(best.tip().z()), 0.0);
  // The monitor's view of the tissue: about every third message, the pressed vertices.
  EXPECT_GT(surfaces, 2);
  EXPECT_LT(surfaces, messages);
  EXPECT_GT(most_moved, 0) << "the press must show on the monitor's surface";

  // Stopping ends the instructor's stream with OK and records the trial.
  v1::StopSessionRequest stop;
  stop.set_id(id);
  stop.set_reason("done");
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kTrainee).get(), stop, &s).ok());
  EXPECT_EQ(s.state(), v1::SESSION_STATE_ENDED);
  EXPECT_EQ(s.end_reason(), "done");
  ASSERT_TRUE(s.has_metrics()) << "Stop answers with the recorded trial metrics";
  EXPECT_GT(s.metrics().peak_force_n(), 0.1);
  while (reader->Read(&t)) {
  }
  EXPECT_TRUE(reader->Finish().ok());
  auto metrics = store_->GetTrialMetrics(static_cast<int64_t>(id));
  ASSERT_TRUE(metrics.ok());
  ASSERT_TRUE(metrics->has_value());
  EXPECT_GT((*metrics)->peak_force, 0.1);
  EXPECT_GT((*metrics)->duration, 1.0);

  // A trainee cannot watch, even their own session.
  auto trainee_watch = Ctx(db::Role::kTrainee);
  auto denied = monitor->Watch(trainee_watch.get(), watch);
  while (denied->Read(&t)) {
  }
  EXPECT_EQ(denied->Finish().error_code(), StatusCode::PERMISSION_DENIED);
}

int ThreadCount() {
  int n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator("/proc/self/task")) ++n;
  return n;
}

v1::CreateSessionRequest CreateFor(const std::string& trainee, const std::string& scene) {
  v1::CreateSessionRequest r;
  r.set_trainee(trainee);
  r.set_scene(scene);
  return r;
}

// One trainee could create sessions until the server refused everyone (UNAVAILABLE for all).
TEST_F(ControlPlaneTest, ATraineeHasALimitOfLiveSessionsAndCannotLockOutOthers) {
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateSessionResponse created;
  std::vector<uint64_t> mine;
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(
        sessions
            ->Create(Ctx(db::Role::kTrainee).get(), CreateFor("", "sphere-palpation-256"), &created)
            .ok());
    mine.push_back(created.session().id());
  }
  for (int i = 0; i < 20; ++i) {
    const grpc::Status refused = sessions->Create(Ctx(db::Role::kTrainee).get(),
                                                  CreateFor("", "sphere-palpation-256"), &created);
    ASSERT_EQ(refused.error_code(), StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.error_message().find("limit is 2"), std::string::npos)
        << refused.error_message();
  }
  // An instructor cannot raise it by creating for her either.
  EXPECT_EQ(
      sessions->Create(Ctx(db::Role::kInstructor).get(), CreateFor("tina", "arm-torsion"), &created)
          .error_code(),
      StatusCode::RESOURCE_EXHAUSTED);
  // Everyone else still gets sessions.
  grpc::ClientContext other;
  other.AddMetadata("authorization", "Bearer " + tom_);
  other.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  ASSERT_TRUE(sessions->Create(&other, CreateFor("", "sphere-palpation-256"), &created).ok());
  // Stopping one frees a slot.
  v1::StopSessionRequest stop;
  stop.set_id(mine[0]);
  v1::Session s;
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kTrainee).get(), stop, &s).ok());
  EXPECT_TRUE(
      sessions
          ->Create(Ctx(db::Role::kTrainee).get(), CreateFor("", "sphere-palpation-256"), &created)
          .ok());
}

// Never-started sessions used to cost a deformation thread each (twelve mass-spring sessions
// took both cores) and never expired.
TEST_F(ControlPlaneTest, SessionsNobodyDrivesCostNoThreadAndNeverStartedOnesExpire) {
  SessionManagerOptions o;
  o.max_sessions_per_user = 16;
  o.start_timeout_s = 1.0;
  auto manager_owned = SessionManager::Open(*store_, endpoint_.get(), o).value();
  SessionManager& manager = *manager_owned;
  const int before = ThreadCount();
  std::vector<uint64_t> ids;
  for (int i = 0; i < 8; ++i) {
    auto c = manager.Create("tina", "sphere-palpation-256");
    ASSERT_TRUE(c.ok()) << c.error().message;
    ids.push_back(static_cast<uint64_t>(c->record.id));
  }
  EXPECT_LT(ThreadCount() - before, 4) << "a created session must not run a thread";

  // One is started and driven: it gets its deformation thread; the others still have none.
  auto c = manager.Create("tina", "sphere-palpation-256");
  ASSERT_TRUE(c.ok());
  const uint64_t driven = static_cast<uint64_t>(c->record.id);
  ASSERT_TRUE(manager.Start(driven).ok());
  const int idle = ThreadCount();
  client::ReplayDevice device(PressAndHold(1.0));
  client::StationOptions so;
  so.server_port = endpoint_->port();
  so.session = driven;
  so.key = c->key;
  auto station = client::StationChannel::Create(so, &device);
  ASSERT_TRUE(station.ok());
  int most = idle;
  while (!device.finished()) {
    most = std::max(most, ThreadCount());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  (*station)->Stop();
  // The station's own two threads, and exactly one deformation thread.
  EXPECT_EQ(most, idle + 2 + 1);

  // The eight never started expire (start_timeout_s = 1 s), recorded as aborted with why (the
  // store's row is written after the session leaves the live set).
  EXPECT_TRUE(test::Eventually(20, [&] {
    for (uint64_t id : ids) {
      const auto rec = store_->GetSession(static_cast<int64_t>(id));
      if (manager.IsLive(id) || !rec.ok() || rec->state != SessionState::kAborted) return false;
    }
    return true;
  }));
  for (uint64_t id : ids) {
    EXPECT_FALSE(manager.IsLive(id));
    auto rec = store_->GetSession(static_cast<int64_t>(id));
    ASSERT_TRUE(rec.ok());
    EXPECT_EQ(rec->state, SessionState::kAborted);
    EXPECT_NE(rec->end_reason.find("not started within"), std::string::npos) << rec->end_reason;
  }
  EXPECT_TRUE(manager.IsLive(driven));
}

// A retry that reuses an idempotency key with another payload was acknowledged as a duplicate
// and its values silently lost.
TEST_F(ControlPlaneTest, AReusedIdempotencyKeyWithAnotherPayloadIsRefused) {
  auto ev = v1::EvaluationService::NewStub(channel_);
  v1::SubmitEvaluationResponse first, r;
  ASSERT_TRUE(
      ev->Submit(Ctx(db::Role::kEvaluator).get(), Submission("key-1", "coil"), &first).ok());
  auto scores = Submission("key-1", "coil");
  scores.set_scores(8, 2.0);
  const grpc::Status differs = ev->Submit(Ctx(db::Role::kEvaluator).get(), scores, &r);
  EXPECT_EQ(differs.error_code(), StatusCode::ALREADY_EXISTS);
  EXPECT_NE(differs.error_message().find("texture score differs"), std::string::npos)
      << differs.error_message();
  auto subject = Submission("key-1", "msm");
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), subject, &r).error_code(),
            StatusCode::ALREADY_EXISTS);
  auto moment = Submission("key-1", "coil");
  moment.set_moment_min(20);
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), moment, &r).error_code(),
            StatusCode::ALREADY_EXISTS);
  // A comment to the trainee arrives with the scores (kept as it was written).
  auto commented = Submission("key-2", "msm");
  commented.set_comment("Feels right at the target; the release is too abrupt.");
  ASSERT_TRUE(ev->Submit(Ctx(db::Role::kEvaluator).get(), commented, &r).ok());
  EXPECT_EQ(store_->ListSubmissionsOn(db::SubjectKind::kModel, "msm").value().at(0).comment,
            "Feels right at the target; the release is too abrupt.");
  auto chatty = Submission("key-3", "reduced");
  chatty.set_comment(std::string(db::kMaxComment + 1, 'x'));
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), chatty, &r).error_code(),
            StatusCode::INVALID_ARGUMENT);
  // An admin importing the same key for another evaluator group.
  auto group = Submission("imp-key", "coil");
  group.set_evaluator("ext");
  group.set_evaluator_group("intern");
  ASSERT_TRUE(ev->Submit(Ctx(db::Role::kAdmin).get(), group, &r).ok());
  group.set_evaluator_group("chief");
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kAdmin).get(), group, &r).error_code(),
            StatusCode::ALREADY_EXISTS);
  // Only the identical submission is a duplicate; the stored scores are the first ones.
  ASSERT_TRUE(ev->Submit(Ctx(db::Role::kEvaluator).get(), Submission("key-1", "coil"), &r).ok());
  EXPECT_TRUE(r.duplicate());
  EXPECT_EQ(r.submission_id(), first.submission_id());
  EXPECT_EQ(store_->CountEvaluationRows().value(), 27);  // coil twice (two groups), msm
  const auto j = ModelReport("coil");
  EXPECT_NEAR(j["index_means"][8].get<double>(), (0.2 * 7 + 0.5 * 7) / 0.7, 1e-12);
}

// Access ends with the account: a trainee whose tokens are revoked, or who is disabled, kept a
// working UDP session.
TEST_F(ControlPlaneTest, RevokingOrDisablingAUserEndsTheirLiveSessions) {
  auto sessions = v1::SessionService::NewStub(channel_);
  auto admin = v1::AdminService::NewStub(channel_);
  struct Case {
    std::string user, token;
    bool disable;
  };
  for (const Case& c :
       {Case{"tina", role_tokens_[db::Role::kTrainee], false}, Case{"tom", tom_, true}}) {
    SCOPED_TRACE(c.user);
    v1::CreateSessionResponse created;
    ASSERT_TRUE(
        sessions->Create(Ctx(c.token).get(), CreateFor("", "sphere-palpation-256"), &created).ok());
    v1::SessionRef ref;
    ref.set_id(created.session().id());
    v1::Session s;
    ASSERT_TRUE(sessions->Start(Ctx(c.token).get(), ref, &s).ok());
    client::ReplayDevice device(PressAndHold(3.0));
    client::StationOptions so;
    so.server_port = endpoint_->port();
    so.session = created.session().id();
    std::copy(created.session_key().begin(), created.session_key().end(), so.key.begin());
    auto station = client::StationChannel::Create(so, &device);
    ASSERT_TRUE(station.ok());
    const auto answered = [&] { return (*station)->stats().received; };
    ASSERT_TRUE(test::Eventually(20, [&] { return answered() >= 200; }));
    v1::Empty e;
    if (c.disable) {
      v1::SetDisabledRequest d;
      d.set_name(c.user);
      d.set_disabled(true);
      ASSERT_TRUE(admin->SetDisabled(Ctx(db::Role::kAdmin).get(), d, &e).ok());
    } else {
      v1::UserRef u;
      u.set_name(c.user);
      ASSERT_TRUE(admin->RevokeTokens(Ctx(db::Role::kAdmin).get(), u, &e).ok());
    }
    EXPECT_FALSE(sessions_->IsLive(created.session().id()));
    auto rec = store_->GetSession(static_cast<int64_t>(created.session().id()));
    ASSERT_TRUE(rec.ok());
    EXPECT_EQ(rec->state, SessionState::kAborted);
    EXPECT_EQ(rec->end_reason, c.disable ? "account disabled" : "access revoked");
    // The UDP channel stops answering at once.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const uint64_t after = answered();
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    EXPECT_EQ(answered(), after) << "the endpoint still answers a revoked user's station";
    (*station)->Stop();
  }
}

// Backup wrote to any absolute path the server could write.
TEST_F(ControlPlaneTest, BackupWritesOnlyIntoTheBackupDirectory) {
  auto admin = v1::AdminService::NewStub(channel_);
  v1::Empty e;
  v1::BackupRequest req;
  for (const std::string& outside :
       {(dir_ / "elsewhere.db").string(), std::string("/tmp/vsurg-escape.db"),
        (dir_ / "backups" / ".." / "up.db").string()}) {
    req.set_path(outside);
    const grpc::Status s = admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e);
    EXPECT_EQ(s.error_code(), StatusCode::PERMISSION_DENIED) << outside;
    EXPECT_FALSE(fs::exists(outside)) << outside;
  }
  for (const char* bad : {"../up.db", "sub/dir.db", ".hidden", ""}) {
    req.set_path(bad);
    EXPECT_EQ(admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e).error_code(),
              StatusCode::INVALID_ARGUMENT)
        << bad;
  }
  req.set_path("nightly-1.db");
  ASSERT_TRUE(admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e).ok());
  EXPECT_GT(fs::file_size(dir_ / "backups" / "nightly-1.db"), 0u);
  EXPECT_EQ(admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e).error_code(),
            StatusCode::ALREADY_EXISTS);
  // The absolute path of a file inside the directory is the same thing.
  req.set_path((dir_ / "backups" / "nightly-2.db").string());
  EXPECT_TRUE(admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e).ok());
  // A symlink planted in the directory is not followed.
  fs::create_symlink(dir_ / "target.db", dir_ / "backups" / "link.db");
  req.set_path("link.db");
  EXPECT_EQ(admin->Backup(Ctx(db::Role::kAdmin).get(), req, &e).error_code(),
            StatusCode::ALREADY_EXISTS);
  EXPECT_FALSE(fs::exists(dir_ / "target.db"));
}

// A scene whose description was a number made ListScenes and Create fail for everyone.
TEST_F(ControlPlaneTest, ABadSceneFileIsSkippedAndReportedAndTheOthersStayAvailable) {
  const fs::path scenes = dir_ / "scenes";
  fs::create_directories(scenes);
  const std::string source = sim::ScenesDirectory();
  for (const char* name : {"arm-torsion.json", "sphere-palpation-256.json"})
    fs::copy_file(fs::path(source) / name, scenes / name);
  {
    std::ifstream in(fs::path(source) / "arm-torsion.json");
    auto j = nlohmann::json::parse(in);
    j["description"] = 42;
    std::ofstream(scenes / "broken.json") << j.dump();
  }
  ::setenv("VSURG_SCENES", scenes.c_str(), 1);
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::ListScenesResponse list;
  const grpc::Status listed = sessions->ListScenes(Ctx(db::Role::kTrainee).get(), {}, &list);
  v1::CreateSessionResponse created;
  const grpc::Status good = sessions->Create(Ctx(db::Role::kTrainee).get(),
                                             CreateFor("", "sphere-palpation-256"), &created);
  const grpc::Status bad =
      sessions->Create(Ctx(db::Role::kTrainee).get(), CreateFor("", "broken"), &created);
  ::unsetenv("VSURG_SCENES");
  ASSERT_TRUE(listed.ok()) << listed.error_message();
  ASSERT_EQ(list.scenes_size(), 2);
  EXPECT_EQ(list.scenes(0).name(), "arm-torsion");
  ASSERT_EQ(list.unusable_size(), 1);
  EXPECT_EQ(list.unusable(0).rfind("broken.json: ", 0), 0u) << list.unusable(0);
  EXPECT_EQ(list.unusable(0).find(scenes.string()), std::string::npos)
      << "a trainee is not shown the server's paths";
  EXPECT_NE(list.unusable(0).find("description: must be a string"), std::string::npos)
      << list.unusable(0);
  EXPECT_TRUE(good.ok()) << good.error_message();
  EXPECT_EQ(bad.error_code(), StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(bad.error_message().find("description"), std::string::npos) << bad.error_message();
}

}  // namespace
}  // namespace vsurg::server
