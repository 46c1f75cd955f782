// Evaluations and training through the control plane (submissions, their weights and export,
// the training effect, a course from creation to its curve), and the plane's own configuration.
#include "tests/server/control/control_plane_fixture.h"

namespace vsurg::server {
namespace {

using namespace test_control;  // the fixture and its names
using test::PressAndHold;

TEST_F(ControlPlaneTest, TrainingServiceRunsACourseFromCreationToTheCurve) {
  auto training = v1::TrainingService::NewStub(channel_);
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateCourseRequest course;
  course.set_name("Basics");
  v1::Exercise* e = course.add_exercises();
  e->set_title("Palpate");
  e->set_scene("sphere-palpation-256");
  e->set_consecutive(1);
  v1::ExerciseTarget* t = e->add_targets();
  t->set_metric("peak_force_n");
  t->set_value(5.0);
  e->mutable_task()->set_kind("press");  // the exercise's own press: 4 mm within 2 mm
  e->mutable_task()->set_target(0.004);
  e->mutable_task()->set_tolerance(0.002);
  v1::Course made;
  ASSERT_TRUE(training->CreateCourse(Ctx(db::Role::kInstructor).get(), course, &made).ok());
  ASSERT_EQ(made.exercises_size(), 1);
  EXPECT_DOUBLE_EQ(made.exercises(0).targets(0).resolved(), 5.0);
  EXPECT_DOUBLE_EQ(made.exercises(0).task().target(), 0.004);
  EXPECT_FALSE(made.exercises(0).task().has_hold_s());  // the scene's
  // Settings for another kind of task, or a target without its kind, are refused.
  v1::CreateCourseRequest twist = course;
  twist.mutable_exercises(0)->mutable_task()->set_kind("twist");
  v1::Course refused;
  EXPECT_EQ(training->CreateCourse(Ctx(db::Role::kInstructor).get(), twist, &refused).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  twist.mutable_exercises(0)->mutable_task()->clear_kind();
  EXPECT_EQ(training->CreateCourse(Ctx(db::Role::kInstructor).get(), twist, &refused).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // A bad target is refused naming it; a trainee may not build courses.
  v1::CreateCourseRequest bad = course;
  bad.set_name("Bad");
  bad.mutable_exercises(0)->mutable_targets(0)->set_metric("speed");
  v1::Course ignored;
  EXPECT_EQ(training->CreateCourse(Ctx(db::Role::kInstructor).get(), bad, &ignored).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(training->CreateCourse(Ctx(db::Role::kTrainee).get(), course, &ignored).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  v1::CreateCohortRequest cohort;
  cohort.set_name("Residents");
  cohort.add_members("tina");
  v1::Cohort group;
  ASSERT_TRUE(training->CreateCohort(Ctx(db::Role::kInstructor).get(), cohort, &group).ok());
  v1::EnrolRequest enrol;
  enrol.set_course_id(made.id());
  enrol.set_cohort_id(group.id());
  v1::Enrolment enrolment;
  ASSERT_TRUE(training->Enrol(Ctx(db::Role::kInstructor).get(), enrol, &enrolment).ok());

  // The station's side, as tina.
  v1::NextExerciseResponse next;
  ASSERT_TRUE(training->Next(Ctx(db::Role::kTrainee).get(), {}, &next).ok());
  ASSERT_TRUE(next.has_next());
  EXPECT_EQ(next.exercise_id(), made.exercises(0).id());
  v1::CreateSessionRequest create;
  create.set_exercise_id(next.exercise_id());
  v1::CreateSessionResponse created;
  ASSERT_TRUE(sessions->Create(Ctx(db::Role::kTrainee).get(), create, &created).ok());
  EXPECT_EQ(created.session().scene(), "sphere-palpation-256");  // the exercise's
  v1::StopSessionRequest stop;
  stop.set_id(created.session().id());
  v1::Session stopped;
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kTrainee).get(), stop, &stopped).ok());
  v1::SessionRef ref;
  ref.set_id(created.session().id());
  v1::Session got;
  ASSERT_TRUE(sessions->Get(Ctx(db::Role::kTrainee).get(), ref, &got).ok());
  ASSERT_EQ(got.targets_size(), 1);  // a trial without touching: no force, the target met
  EXPECT_EQ(got.targets(0).metric(), "peak_force_n");
  EXPECT_TRUE(got.targets(0).met());
  EXPECT_TRUE(got.targets_passed());

  v1::ProgressRequest mine;
  v1::ProgressResponse progress;
  ASSERT_TRUE(training->Progress(Ctx(db::Role::kTrainee).get(), mine, &progress).ok());
  ASSERT_EQ(progress.rows_size(), 1);
  EXPECT_EQ(progress.rows(0).state(), "proficient");
  EXPECT_EQ(progress.rows(0).proficient_at(), 1);
  v1::CurveRequest curve_req;
  curve_req.set_exercise_id(next.exercise_id());
  v1::CurveResponse curve;
  ASSERT_TRUE(training->Curve(Ctx(db::Role::kTrainee).get(), curve_req, &curve).ok());
  ASSERT_EQ(curve.attempts_size(), 1);
  EXPECT_NEAR(curve.attempts(0).cusum(), -curve.s(), 1e-12);  // one pass
  // Another trainee's curve is refused; the instructor sees the cohort's grid.
  curve_req.set_trainee("tom");
  EXPECT_EQ(training->Curve(Ctx(db::Role::kTrainee).get(), curve_req, &curve).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  v1::ProgressRequest grid;
  grid.set_cohort_id(group.id());
  grid.set_course_id(made.id());
  ASSERT_TRUE(training->Progress(Ctx(db::Role::kInstructor).get(), grid, &progress).ok());
  EXPECT_EQ(progress.rows_size(), 1);
  v1::ListCohortsResponse cohorts;
  ASSERT_TRUE(training->ListCohorts(Ctx(db::Role::kInstructor).get(), {}, &cohorts).ok());
  EXPECT_EQ(cohorts.cohorts_size(), 1);
  // Every course reached: nothing next.
  ASSERT_TRUE(training->Next(Ctx(db::Role::kTrainee).get(), {}, &next).ok());
  EXPECT_FALSE(next.has_next());
}

TEST_F(ControlPlaneTest, SubmissionsAreValidatedIdempotentAndReportedWithTheirWeights) {
  auto ev = v1::EvaluationService::NewStub(channel_);
  v1::SubmitEvaluationResponse r1, r2;
  ASSERT_TRUE(ev->Submit(Ctx(db::Role::kEvaluator).get(), Submission("k1", "coil"), &r1).ok());
  EXPECT_FALSE(r1.duplicate());
  ASSERT_TRUE(ev->Submit(Ctx(db::Role::kEvaluator).get(), Submission("k1", "coil"), &r2).ok());
  EXPECT_TRUE(r2.duplicate());
  EXPECT_EQ(r2.submission_id(), r1.submission_id());
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), Submission("k2", "coil"), &r2).error_code(),
            StatusCode::ALREADY_EXISTS);

  auto bad = Submission("k3", "msm");
  bad.set_scores(4, 10.5);
  const grpc::Status out_of_range = ev->Submit(Ctx(db::Role::kEvaluator).get(), bad, &r2);
  EXPECT_EQ(out_of_range.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(out_of_range.error_message().find("scores[4]"), std::string::npos);
  bad = Submission("k4", "msm");
  bad.mutable_scores()->RemoveLast();
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), bad, &r2).error_code(),
            StatusCode::INVALID_ARGUMENT);
  bad = Submission("k5", "msm");
  bad.set_subject_kind("hospital");
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), bad, &r2).error_code(),
            StatusCode::INVALID_ARGUMENT);
  bad = Submission("k6", "msm");
  bad.set_evaluator("someone-else");
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kEvaluator).get(), bad, &r2).error_code(),
            StatusCode::PERMISSION_DENIED);
  bad = Submission("k7", "msm");
  bad.set_evaluator("imported");
  bad.set_evaluator_group("resident");
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kAdmin).get(), bad, &r2).error_code(),
            StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(ev->Submit(Ctx(db::Role::kTrainee).get(), Submission("k8", "msm"), &r2).error_code(),
            StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(store_->CountEvaluationRows().value(), 9);  // nothing partly written

  // An admin imports two more raters; the report is the coil-spring paper eq. 9–11 of the stored
  // rows.
  for (auto [name, group, score] :
       {std::tuple{"a1", "intern", 5.0}, {"b1", "associate_chief", 6.0}}) {
    auto s = Submission(std::string("imp-") + name, "coil");
    s.set_evaluator(name);
    s.set_evaluator_group(group);
    for (int j = 0; j < 9; ++j) s.set_scores(j, score);
    ASSERT_TRUE(ev->Submit(Ctx(db::Role::kAdmin).get(), s, &r2).ok());
  }
  v1::ReportRequest rq;
  rq.set_subject_kind("model");
  rq.add_subjects("coil");
  v1::ReportResponse rep;
  ASSERT_TRUE(ev->Report(Ctx(db::Role::kInstructor).get(), rq, &rep).ok());
  const auto j = nlohmann::json::parse(rep.report_json());
  EXPECT_NEAR(j["index_means"][0].get<double>(), 0.2 * 5 + 0.3 * 6 + 0.5 * 8, 1e-12);
  EXPECT_EQ(j["raters"], 3);
  EXPECT_EQ(j["weights"]["name"], "coil-spring-paper");

  auto admin = v1::AdminService::NewStub(channel_);
  v1::WeightSet w;
  w.set_json(R"({"name":"flat","group":{"intern":0.5,"associate_chief":0.25,"chief":0.25},)"
             R"("index":[0.2,0.1,0.1,0.1,0.1,0.1,0.1,0.1,0.1]})");
  v1::Empty e;
  ASSERT_TRUE(admin->PutWeightSet(Ctx(db::Role::kAdmin).get(), w, &e).ok());
  rq.set_weight_set("flat");
  ASSERT_TRUE(ev->Report(Ctx(db::Role::kEvaluator).get(), rq, &rep).ok());
  const auto k = nlohmann::json::parse(rep.report_json());
  EXPECT_NEAR(k["index_means"][0].get<double>(), 0.5 * 5 + 0.25 * 6 + 0.25 * 8, 1e-12);
  EXPECT_EQ(k["weights"]["name"], "flat");
  w.set_json(R"({"name":"bad","group":{"intern":1,"associate_chief":1,"chief":1},"index":[1]})");
  EXPECT_EQ(admin->PutWeightSet(Ctx(db::Role::kAdmin).get(), w, &e).error_code(),
            StatusCode::INVALID_ARGUMENT);
  rq.set_weight_set("missing");
  EXPECT_EQ(ev->Report(Ctx(db::Role::kEvaluator).get(), rq, &rep).error_code(),
            StatusCode::NOT_FOUND);
}

TEST_F(ControlPlaneTest, TrainingEffectGroupsTraineesByMoment) {
  auto ev = v1::EvaluationService::NewStub(channel_);
  // (trainee, moment, evaluator, uniform score): tina is in group virtual-40, tom in real-40.
  const std::vector<std::tuple<std::string, double, std::string, double>> rows = {
      {"tina", 0, "c1", 4}, {"tina", 0, "c2", 6}, {"tina", 20, "c1", 7},
      {"tom", 0, "c1", 5},  {"tom", 0, "c2", 5},
  };
  for (const auto& [trainee, moment, evaluator, score] : rows) {
    v1::SubmitEvaluationRequest r;
    r.set_idempotency_key(trainee + std::to_string(moment) + evaluator);
    r.set_evaluator(evaluator);
    r.set_evaluator_group("chief");
    r.set_subject_kind("trainee");
    r.set_subject(trainee);
    r.set_moment_min(moment);
    for (int j = 0; j < 9; ++j) r.add_scores(score);
    v1::SubmitEvaluationResponse resp;
    ASSERT_TRUE(ev->Submit(Ctx(db::Role::kAdmin).get(), r, &resp).ok());
  }
  v1::TrainingEffectResponse resp;
  ASSERT_TRUE(ev->TrainingEffect(Ctx(db::Role::kInstructor).get(), {}, &resp).ok());
  const auto cells = nlohmann::json::parse(resp.cells_json());
  ASSERT_EQ(cells.size(), 3u);  // sorted by group, then moment
  EXPECT_EQ(cells[0]["trainee_group"], "real-40");
  EXPECT_NEAR(cells[0]["mean"].get<double>(), 5.0, 1e-12);
  EXPECT_EQ(cells[1]["trainee_group"], "virtual-40");
  EXPECT_EQ(cells[1]["moment_min"], 0.0);
  EXPECT_NEAR(cells[1]["mean"].get<double>(), 5.0, 1e-12);  // mean of the evaluators 4 and 6
  EXPECT_NEAR(cells[2]["mean"].get<double>(), 7.0, 1e-12);
  EXPECT_EQ(cells[2]["moment_min"], 20.0);
}

TEST_F(ControlPlaneTest, ExportStreamsEveryRowAsTheStoreHasIt) {
  auto ev = v1::EvaluationService::NewStub(channel_);
  for (int i = 0; i < 300; ++i) {
    auto s = Submission("x" + std::to_string(i), "coil");
    s.set_evaluator("rater-" + std::to_string(i));
    s.set_evaluator_group("chief");
    v1::SubmitEvaluationResponse r;
    ASSERT_TRUE(ev->Submit(Ctx(db::Role::kAdmin).get(), s, &r).ok());
  }
  std::string local;
  ASSERT_TRUE(store_
                  ->Export({}, db::ExportFormat::kCsv,
                           [&](std::string_view c) {
                             local.append(c);
                             return true;
                           })
                  .ok());
  auto admin = v1::AdminService::NewStub(channel_);
  v1::ExportRequest req;
  req.set_format("csv");
  auto ctx = Ctx(db::Role::kAdmin);
  auto reader = admin->Export(ctx.get(), req);
  std::string remote;
  v1::ExportChunk chunk;
  int chunks = 0;
  while (reader->Read(&chunk)) remote += chunk.data(), ++chunks;
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_EQ(remote, local);
  EXPECT_GT(chunks, 1);  // streamed, not one message
  EXPECT_EQ(std::count(remote.begin(), remote.end(), '\n'), 1 + 300 * 9);
}

TEST(ControlPlaneConfigTest, PlaintextOffLoopbackIsRefused) {
  EXPECT_TRUE(IsLoopbackHost("127.0.0.1:50051"));
  EXPECT_TRUE(IsLoopbackHost("localhost:1"));
  EXPECT_TRUE(IsLoopbackHost("[::1]:50051"));
  EXPECT_FALSE(IsLoopbackHost("0.0.0.0:50051"));
  EXPECT_FALSE(IsLoopbackHost("10.1.2.3:50051"));
  const test::TempDir tmp("cp_cfg");
  const fs::path path = tmp / "vsurg.db";
  auto store = db::Store::Open({.path = path.string()});
  ASSERT_TRUE(store.ok());
  auto sessions_owned = SessionManager::Open(**store, nullptr, {}).value();
  SessionManager& sessions = *sessions_owned;
  ControlPlaneOptions o;
  o.listen = "0.0.0.0:0";
  auto cp = ControlPlane::Start(**store, sessions, o);
  ASSERT_FALSE(cp.ok());
  EXPECT_EQ(cp.error().field, "listen");
  o.listen = "127.0.0.1:0";
  o.tls_cert_file = "/nonexistent/cert.pem";
  EXPECT_FALSE(ControlPlane::Start(**store, sessions, o).ok());  // half a TLS config
  sessions.Shutdown();
  store->reset();
  fs::remove(path);
}

TEST(ControlPlaneTlsTest, ACertificateInTheConfigTurnsOnTls) {
  const test::TempDir dir("cp_tls");
  const auto [cert, key] = test::SelfSigned();
  std::ofstream(dir / "cert.pem") << cert;
  std::ofstream(dir / "key.pem") << key;
  auto store = std::move(db::Store::Open({.path = (dir / "vsurg.db").string()})).value();
  const std::string token = store->InitAdmin("root").value();
  auto sessions_owned = SessionManager::Open(*store, nullptr, {}).value();
  SessionManager& sessions = *sessions_owned;
  ControlPlaneOptions o;
  o.tls_cert_file = (dir / "cert.pem").string();
  o.tls_key_file = (dir / "key.pem").string();
  auto cp = ControlPlane::Start(*store, sessions, o);
  ASSERT_TRUE(cp.ok()) << cp.error().message;
  EXPECT_TRUE((*cp)->tls());
  const std::string target = "localhost:" + std::to_string((*cp)->port());
  auto call = [&](const std::shared_ptr<grpc::ChannelCredentials>& creds) {
    auto stub = v1::AdminService::NewStub(grpc::CreateChannel(target, creds));
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer " + token);
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    v1::ListUsersResponse r;
    return stub->ListUsers(&ctx, {}, &r);
  };
  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = cert;
  const grpc::Status secure = call(grpc::SslCredentials(ssl));
  EXPECT_TRUE(secure.ok()) << secure.error_message();
  EXPECT_FALSE(call(grpc::InsecureChannelCredentials()).ok());  // no plaintext on a TLS port
  (*cp)->Shutdown();
  sessions.Shutdown();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vsurg::server
