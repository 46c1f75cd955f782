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
  auto station = client::StationChannel::Create(
      StationFor(endpoint_->port(), id, created.session_key()), &device);
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

// A search's samples on the coarse pad (top at z = 30 mm): a press over `at`, 3 mm in, the mark
// button held for 50 ms while in, then lifted; 1.6 s a press.
void PressAndMark(std::vector<haptics::StylusSample>& out, const Eigen::Vector2d& at) {
  for (int k = 0; k < 1600; ++k) {
    haptics::StylusSample s;
    const double in = k < 500 ? k / 500.0 : k < 1200 ? 1.0 : std::max(0.0, 1 - (k - 1200) / 300.0);
    s.position = Eigen::Vector3d(at.x(), at.y(), 0.040 - 0.013 * in);
    if (k >= 900 && k < 950) s.buttons = haptics::kButtonMark;
    out.push_back(s);
  }
}

// The station's end-of-trial summary draws where the lumps were and the trainee's marks: Stop's
// and Get's answers for an ended search carry them, each mark paired with the lump it found as
// the score pairs them; a record without them (another task) answers without.
TEST_F(ControlPlaneTest, AnEndedSearchAnswersWithWhereItsLumpsWereAndItsMarks) {
  const fs::path scenes = dir_ / "scenes";
  fs::create_directories(scenes);
  std::ofstream(scenes / "pad-one-lump.json") << R"({"name": "pad-one-lump",
      "mesh": {"type": "block", "size": [0.1, 0.1, 0.03], "cells": [10, 10, 3]},
      "tissue": {"shear_modulus": 1100, "poisson_ratio": 0.47,
                 "inclusions": [{"centre": [0.004, 0.002, 0.018], "radius": 0.006,
                                 "contrast": 5}]},
      "regions": [{"name": "r", "model": {"type": "reduced", "mode": "contact",
                   "footprint_radius": 0.009, "support": {"plane": {"point": [0, 0, 0.001],
                   "normal": [0, 0, 1]}}}}],
      "task": {"type": "palpate", "time_limit_s": 300},
      "error_budget": {"rms": 0.2}})";
  ::setenv("VSURG_SCENES", scenes.c_str(), 1);
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateSessionResponse created;
  const grpc::Status made = sessions->Create(Ctx(role_tokens_[db::Role::kTrainee], 120).get(),
                                             CreateFor("", "pad-one-lump"), &created);
  ::unsetenv("VSURG_SCENES");
  ASSERT_TRUE(made.ok()) << made.error_message();
  const uint64_t id = created.session().id();
  v1::SessionRef ref;
  ref.set_id(id);
  v1::Session s;
  ASSERT_TRUE(sessions->Start(Ctx(db::Role::kTrainee).get(), ref, &s).ok());

  std::vector<haptics::StylusSample> search;
  PressAndMark(search, {0.004, 0.002});  // over the lump
  PressAndMark(search, {-0.03, -0.03});  // 40 mm aside: a false mark
  client::ReplayDevice device(search);
  auto station = client::StationChannel::Create(
      StationFor(endpoint_->port(), id, created.session_key()), &device);
  ASSERT_TRUE(station.ok()) << station.error().message;
  // Until the server has answered past the second mark (its press lifts 0.6 s after it).
  ASSERT_TRUE(test::Eventually(60, [&] { return (*station)->stats().received > 1600 + 1300; }));
  (*station)->Stop();

  v1::StopSessionRequest stop;
  stop.set_id(id);
  stop.set_reason("done");
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kTrainee).get(), stop, &s).ok());
  for (int asked = 0; asked < 2; ++asked) {  // Stop's answer, then Get's
    if (asked == 1) {
      ASSERT_TRUE(sessions->Get(Ctx(db::Role::kTrainee).get(), ref, &s).ok());
    }
    ASSERT_TRUE(s.has_palpation()) << asked;
    EXPECT_EQ(s.metrics().lumps(), 1);
    EXPECT_EQ(s.metrics().lumps_found(), 1);
    EXPECT_EQ(s.metrics().false_marks(), 1);
    ASSERT_EQ(s.palpation().lumps_size(), 1);
    const v1::PalpationOutcome::Lump& lump = s.palpation().lumps(0);
    EXPECT_NEAR(lump.centre().z(), 0.018, 1e-6);
    EXPECT_NEAR(lump.radius(), 0.006, 1e-6);
    EXPECT_NEAR(lump.surface().z(), 0.03, 1e-3) << "the point above it, on the top";
    EXPECT_TRUE(lump.found());
    ASSERT_EQ(s.palpation().marks_size(), 2);
    EXPECT_EQ(s.palpation().marks(0).lump(), 0);
    EXPECT_EQ(s.palpation().marks(1).lump(), -1);
    EXPECT_NEAR(s.palpation().marks(0).position().x(), 0.004, 0.003);
    EXPECT_NEAR(s.palpation().marks(1).position().x(), -0.03, 0.003);
    EXPECT_LT(s.palpation().marks(0).time_s(), s.palpation().marks(1).time_s());
  }
  // The station reads the same, in the core's types.
  const scoring::PalpationOutcome read = convert::FromProto(s.palpation());
  ASSERT_EQ(read.lumps.size(), 1u);
  EXPECT_EQ(read.found, std::vector<bool>{true});
  ASSERT_EQ(read.marks.size(), 2u);
  EXPECT_EQ(read.marks[1].lump, -1);

  // Another task's ended session answers without one; so does a search whose record's member is
  // not what it should be (the store holds only valid JSON): the session's answer stands, the
  // drawing is what is left out.
  scoring::TrialMetrics searched;
  searched.lumps = 1;
  for (const auto& [metrics, record] : {std::pair{scoring::TrialMetrics{}, std::string("{}")},
                                        std::pair{searched, std::string("{\"palpation\": 3}")}}) {
    auto other = store_->CreateSession("tina", "sphere-palpation-256");
    ASSERT_TRUE(other.ok());
    const Status ended = store_->EndSession(other->id, SessionState::kEnded, db::NowUs(), "done",
                                            metrics, {}, record);
    ASSERT_TRUE(ended.ok()) << ended.error().message;
    ref.set_id(static_cast<uint64_t>(other->id));
    ASSERT_TRUE(sessions->Get(Ctx(db::Role::kTrainee).get(), ref, &s).ok()) << record;
    EXPECT_FALSE(s.has_palpation()) << record;
  }
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
