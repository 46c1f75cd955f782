// The control plane's doors: tokens and roles on every method, who may join a prepared session,
// and the health service.
#include "tests/server/control/control_plane_fixture.h"

namespace vsurg::server {
namespace {

using namespace test_control;  // the fixture and its names
using test::PressAndHold;

TEST_F(ControlPlaneTest, MissingOrBadTokensAreUnauthenticatedAndWrongRolesDenied) {
  auto admin = v1::AdminService::NewStub(channel_);
  v1::ListUsersResponse resp;
  EXPECT_EQ(admin->ListUsers(Ctx("").get(), {}, &resp).error_code(), StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(admin->ListUsers(Ctx("vst_not_a_real_token").get(), {}, &resp).error_code(),
            StatusCode::UNAUTHENTICATED);
  auto basic = Ctx("");
  basic->AddMetadata("authorization", "Basic cm9vdDpyb290");
  EXPECT_EQ(admin->ListUsers(basic.get(), {}, &resp).error_code(), StatusCode::UNAUTHENTICATED);
  const grpc::Status denied = admin->ListUsers(Ctx(db::Role::kTrainee).get(), {}, &resp);
  EXPECT_EQ(denied.error_code(), StatusCode::PERMISSION_DENIED);
  EXPECT_NE(denied.error_message().find("trainee"), std::string::npos);
  ASSERT_TRUE(admin->ListUsers(Ctx(db::Role::kAdmin).get(), {}, &resp).ok());
  EXPECT_EQ(resp.users_size(), 5);
  // A revoked token stops working at once.
  ASSERT_TRUE(store_->RevokeTokens("ida").ok());
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::ListSessionsResponse list;
  EXPECT_EQ(sessions->List(Ctx(db::Role::kInstructor).get(), {}, &list).error_code(),
            StatusCode::UNAUTHENTICATED);
}

// Calls `m` with harmless (often invalid) arguments and returns the status code.
StatusCode Call(const std::shared_ptr<grpc::Channel>& ch, Method m,
                const std::function<std::unique_ptr<grpc::ClientContext>()>& ctx) {
  auto s = v1::SessionService::NewStub(ch);
  auto mon = v1::MonitorService::NewStub(ch);
  auto ev = v1::EvaluationService::NewStub(ch);
  auto ad = v1::AdminService::NewStub(ch);
  auto tr = v1::TrainingService::NewStub(ch);
  v1::Session session;
  v1::Empty empty;
  switch (m) {
    case Method::kSessionCreate: {
      v1::CreateSessionResponse r;
      return s->Create(ctx().get(), {}, &r).error_code();
    }
    case Method::kSessionStart: {
      v1::SessionRef ref;
      ref.set_id(999);
      return s->Start(ctx().get(), ref, &session).error_code();
    }
    case Method::kSessionStop: {
      v1::StopSessionRequest req;
      req.set_id(999);
      return s->Stop(ctx().get(), req, &session).error_code();
    }
    case Method::kSessionGet: {
      v1::SessionRef ref;
      ref.set_id(999);
      return s->Get(ctx().get(), ref, &session).error_code();
    }
    case Method::kSessionList: {
      v1::ListSessionsResponse r;
      return s->List(ctx().get(), {}, &r).error_code();
    }
    case Method::kMonitorWatch: {
      v1::WatchRequest req;
      req.set_session_id(999);
      auto c = ctx();
      auto reader = mon->Watch(c.get(), req);
      v1::Telemetry t;
      while (reader->Read(&t)) {
      }
      return reader->Finish().error_code();
    }
    case Method::kEvaluationSubmit: {
      v1::SubmitEvaluationResponse r;
      return ev->Submit(ctx().get(), {}, &r).error_code();
    }
    case Method::kEvaluationReport: {
      v1::ReportResponse r;
      return ev->Report(ctx().get(), {}, &r).error_code();
    }
    case Method::kEvaluationTrainingEffect: {
      v1::TrainingEffectResponse r;
      return ev->TrainingEffect(ctx().get(), {}, &r).error_code();
    }
    case Method::kAdminCreateUser: {
      v1::User u;
      return ad->CreateUser(ctx().get(), {}, &u).error_code();
    }
    case Method::kAdminIssueToken: {
      v1::IssueTokenResponse r;
      return ad->IssueToken(ctx().get(), {}, &r).error_code();
    }
    case Method::kAdminRevokeTokens:
      return ad->RevokeTokens(ctx().get(), {}, &empty).error_code();
    case Method::kAdminSetDisabled:
      return ad->SetDisabled(ctx().get(), {}, &empty).error_code();
    case Method::kAdminListUsers: {
      v1::ListUsersResponse r;
      return ad->ListUsers(ctx().get(), {}, &r).error_code();
    }
    case Method::kAdminPutWeightSet:
      return ad->PutWeightSet(ctx().get(), {}, &empty).error_code();
    case Method::kAdminListWeightSets: {
      v1::ListWeightSetsResponse r;
      return ad->ListWeightSets(ctx().get(), {}, &r).error_code();
    }
    case Method::kAdminExport: {
      v1::ExportRequest req;
      req.set_format("bogus");
      auto c = ctx();
      auto reader = ad->Export(c.get(), req);
      v1::ExportChunk chunk;
      while (reader->Read(&chunk)) {
      }
      return reader->Finish().error_code();
    }
    case Method::kAdminBackup:
      return ad->Backup(ctx().get(), {}, &empty).error_code();
    case Method::kSessionListScenes: {
      v1::ListScenesResponse r;
      return s->ListScenes(ctx().get(), {}, &r).error_code();
    }
    case Method::kSessionJoin: {
      v1::JoinRequest ref;
      ref.set_id(999);
      v1::CreateSessionResponse r;
      return s->Join(ctx().get(), ref, &r).error_code();
    }
    case Method::kSessionJoinInstructor: {
      v1::JoinRequest ref;
      ref.set_id(999);
      ref.set_role(v1::ROLE_INSTRUCTOR);
      v1::CreateSessionResponse r;
      return s->Join(ctx().get(), ref, &r).error_code();
    }
    case Method::kSessionGuide: {
      v1::GuideRequest req;
      req.set_id(999);
      req.set_mode(v1::GUIDE_MODE_OBSERVE);
      v1::Guidance r;
      return s->Guide(ctx().get(), req, &r).error_code();
    }
    case Method::kTrainingCreateCourse: {
      v1::Course r;
      return tr->CreateCourse(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingCreateCohort: {
      v1::Cohort r;
      return tr->CreateCohort(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingEnrol: {
      v1::Enrolment r;
      return tr->Enrol(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingSetExpert:
      return tr->SetExpert(ctx().get(), {}, &empty).error_code();
    case Method::kTrainingProgress: {
      v1::ProgressResponse r;
      return tr->Progress(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingNext: {
      v1::NextExerciseResponse r;
      return tr->Next(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingListCourses: {
      v1::ListCoursesResponse r;
      return tr->ListCourses(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingUpdateExercise:
      return tr->UpdateExercise(ctx().get(), {}, &empty).error_code();
    case Method::kTrainingListCohorts: {
      v1::ListCohortsResponse r;
      return tr->ListCohorts(ctx().get(), {}, &r).error_code();
    }
    case Method::kTrainingAddMembers:
      return tr->AddMembers(ctx().get(), {}, &empty).error_code();
    case Method::kTrainingCurve: {
      v1::CurveResponse r;
      return tr->Curve(ctx().get(), {}, &r).error_code();
    }
    case Method::kOpsMetrics:  // HTTP only (http_api_test)
    case Method::kCount:
      break;
  }
  return StatusCode::UNKNOWN;
}

TEST_F(ControlPlaneTest, PermissionMatrixHoldsForEveryMethodAndRole) {
  // The matrix as the product asks for it, written out independently of auth.cpp.
  const std::map<db::Role, std::set<Method>> allowed = {
      {db::Role::kTrainee,
       {Method::kSessionCreate, Method::kSessionStart, Method::kSessionStop, Method::kSessionGet,
        Method::kSessionList, Method::kSessionListScenes, Method::kSessionJoin,
        Method::kTrainingProgress, Method::kTrainingNext, Method::kTrainingListCourses,
        Method::kTrainingCurve}},
      {db::Role::kInstructor, {Method::kSessionCreate,        Method::kSessionStart,
                               Method::kSessionStop,          Method::kSessionGet,
                               Method::kSessionList,          Method::kMonitorWatch,
                               Method::kEvaluationReport,     Method::kEvaluationTrainingEffect,
                               Method::kAdminListWeightSets,  Method::kSessionListScenes,
                               Method::kTrainingCreateCourse, Method::kTrainingCreateCohort,
                               Method::kTrainingEnrol,        Method::kTrainingSetExpert,
                               Method::kTrainingProgress,     Method::kTrainingNext,
                               Method::kTrainingListCourses,  Method::kTrainingUpdateExercise,
                               Method::kTrainingListCohorts,  Method::kTrainingAddMembers,
                               Method::kTrainingCurve,        Method::kSessionJoinInstructor,
                               Method::kSessionGuide}},
      {db::Role::kEvaluator,
       {Method::kSessionGet, Method::kSessionList, Method::kEvaluationSubmit,
        Method::kEvaluationReport, Method::kEvaluationTrainingEffect, Method::kAdminListWeightSets,
        Method::kSessionListScenes}},
  };
  for (db::Role role :
       {db::Role::kTrainee, db::Role::kInstructor, db::Role::kEvaluator, db::Role::kAdmin}) {
    for (int i = 0; i < static_cast<int>(Method::kCount); ++i) {
      const Method m = static_cast<Method>(i);
      const bool may = role == db::Role::kAdmin || allowed.at(role).count(m) > 0;
      EXPECT_EQ(RoleMay(role, m), may) << db::RoleName(role) << " " << MethodName(m);
      if (m == Method::kOpsMetrics) continue;  // no gRPC method: http_api_test calls it
      const StatusCode code = Call(channel_, m, [&] { return Ctx(role); });
      if (may) {
        EXPECT_NE(code, StatusCode::PERMISSION_DENIED)
            << db::RoleName(role) << " " << MethodName(m);
        EXPECT_NE(code, StatusCode::UNAUTHENTICATED) << db::RoleName(role) << " " << MethodName(m);
      } else {
        EXPECT_EQ(code, StatusCode::PERMISSION_DENIED)
            << db::RoleName(role) << " " << MethodName(m);
      }
      // Without credentials every method is UNAUTHENTICATED, never PERMISSION_DENIED.
      if (role == db::Role::kAdmin) {
        EXPECT_EQ(Call(channel_, m, [&] { return Ctx(""); }), StatusCode::UNAUTHENTICATED)
            << MethodName(m);
      }
    }
  }
}

// The training programme over gRPC: an instructor builds a course and a cohort and enrols it;
// the trainee's station asks for its next exercise, runs an attempt (created with the exercise,
// stopped), reads its target checks, and the progress and curve follow.

TEST_F(ControlPlaneTest, OnlyTheTraineeJoinsASessionPreparedForThem) {
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateSessionRequest create;
  create.set_trainee("tina");
  create.set_scene("sphere-palpation-256");
  v1::CreateSessionResponse prepared;
  ASSERT_TRUE(sessions->Create(Ctx(db::Role::kInstructor).get(), create, &prepared).ok());
  v1::JoinRequest ref;
  ref.set_id(prepared.session().id());
  v1::CreateSessionResponse joined;
  // Another trainee, the instructor who prepared it and an administrator get no key.
  EXPECT_EQ(sessions->Join(Ctx(tom_).get(), ref, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kInstructor).get(), ref, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kAdmin).get(), ref, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  const grpc::Status ok = sessions->Join(Ctx(db::Role::kTrainee).get(), ref, &joined);
  ASSERT_TRUE(ok.ok()) << ok.error_message();
  EXPECT_EQ(joined.session_key(), prepared.session_key());
  EXPECT_EQ(joined.udp_port(), prepared.udp_port());
  EXPECT_EQ(joined.session().scene(), "sphere-palpation-256");
  EXPECT_EQ(joined.session().trainee(), "tina");
  // The tissue's surface comes with the creation and with a join that asks for it (a station's
  // first), not with the probes that only ask where the session runs.
  ASSERT_TRUE(prepared.has_surface());
  EXPECT_GT(prepared.surface().triangles_size(), 0);
  EXPECT_EQ(prepared.surface().positions_size(), 3 * prepared.surface().stiffness_size());
  EXPECT_FALSE(joined.has_surface());
  ref.set_with_surface(true);
  ASSERT_TRUE(sessions->Join(Ctx(db::Role::kTrainee).get(), ref, &joined).ok());
  ASSERT_TRUE(joined.has_surface());
  EXPECT_EQ(joined.surface().SerializeAsString(), prepared.surface().SerializeAsString());
  auto surface = convert::FromProto(joined.surface());
  ASSERT_TRUE(surface.ok()) << surface.error().message;
  EXPECT_GT((*surface)->spec().reach, 0);
  ref.set_with_surface(false);
  // Once it has ended there is nothing to join.
  v1::StopSessionRequest stop;
  stop.set_id(ref.id());
  v1::Session s;
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kInstructor).get(), stop, &s).ok());
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kTrainee).get(), ref, &joined).error_code(),
            StatusCode::NOT_FOUND);
  ref.set_id(999);
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kTrainee).get(), ref, &joined).error_code(),
            StatusCode::NOT_FOUND);
}

TEST_F(ControlPlaneTest, HealthServiceReportsServing) {
  grpc::GenericStub stub(channel_);
  grpc::ByteBuffer request, response;  // HealthCheckRequest{service: ""} is empty on the wire
  grpc::Slice empty_slice("", 0);
  request = grpc::ByteBuffer(&empty_slice, 1);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  std::promise<grpc::Status> done;
  stub.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status s) { done.set_value(s); });
  ASSERT_TRUE(done.get_future().get().ok());
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(response.Dump(&slices).ok());
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // status: SERVING
}

using test::PressAndHold;

}  // namespace
}  // namespace vsurg::server
