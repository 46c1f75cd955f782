// Four-handed training through the control plane: an instructor's station joins a trainee's live
// session on a channel of its own, sets the mode live, and the record says how much was guided;
// every refusal on the way (roles, other trainees, bad modes, ended sessions).
#include "tests/server/control/control_plane_fixture.h"

namespace vsurg::server {
namespace {

using namespace test_control;  // the fixture and its names
using test::PressAndHold;

TEST_F(ControlPlaneTest, AnInstructorJoinsALiveSessionOnItsOwnChannelAndGuidesIt) {
  auto sessions = v1::SessionService::NewStub(channel_);
  v1::CreateSessionRequest create;
  create.set_scene("sphere-palpation-256");
  v1::CreateSessionResponse created;
  ASSERT_TRUE(sessions->Create(Ctx(db::Role::kTrainee).get(), create, &created).ok());
  const uint64_t id = created.session().id();
  v1::SessionRef ref;
  ref.set_id(id);
  v1::Session s;
  ASSERT_TRUE(sessions->Start(Ctx(db::Role::kTrainee).get(), ref, &s).ok());
  client::ReplayDevice trainee_hand(PressAndHold(2.0));
  auto trainee = client::StationChannel::Create(
      StationFor(endpoint_->port(), id, created.session_key()), &trainee_hand);
  ASSERT_TRUE(trainee.ok()) << trainee.error().message;

  // Who may join as an instructor: not a trainee (the session's own or another), not an
  // evaluator; not a session that does not exist; a guide request before a join is refused.
  v1::JoinRequest join;
  join.set_id(id);
  join.set_role(v1::ROLE_INSTRUCTOR);
  join.set_mode(v1::GUIDE_MODE_OBSERVE);
  v1::CreateSessionResponse joined;
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kTrainee).get(), join, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(sessions->Join(Ctx(tom_).get(), join, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kEvaluator).get(), join, &joined).error_code(),
            StatusCode::PERMISSION_DENIED);
  v1::GuideRequest guide;
  guide.set_id(id);
  guide.set_mode(v1::GUIDE_MODE_GUIDE);
  guide.set_alpha(0.5);
  v1::Guidance g;
  EXPECT_EQ(sessions->Guide(Ctx(db::Role::kInstructor).get(), guide, &g).error_code(),
            StatusCode::FAILED_PRECONDITION);
  join.set_id(999);
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kInstructor).get(), join, &joined).error_code(),
            StatusCode::NOT_FOUND);
  join.set_id(id);
  join.set_alpha(0.3);  // alpha is the guide mode's
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kInstructor).get(), join, &joined).error_code(),
            StatusCode::INVALID_ARGUMENT);
  join.set_alpha(0);

  // The instructor's own channel: another wire id, another key, no surface (its tip is not the
  // tool's).
  const grpc::Status ok = sessions->Join(Ctx(db::Role::kInstructor).get(), join, &joined);
  ASSERT_TRUE(ok.ok()) << ok.error_message();
  EXPECT_EQ(joined.channel(), InstructorChannel(id));
  EXPECT_NE(joined.session_key(), created.session_key());
  EXPECT_FALSE(joined.has_surface());
  EXPECT_EQ(joined.session().trainee(), "tina");
  // Another instructor (here an administrator) waits for the first to leave.
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kAdmin).get(), join, &joined).error_code(),
            StatusCode::FAILED_PRECONDITION);
  client::ReplayDevice instructor_hand(PressAndHold(1.5));
  auto instructor = client::StationChannel::Create(
      StationFor(endpoint_->port(), joined.channel(), joined.session_key()), &instructor_hand);
  ASSERT_TRUE(instructor.ok()) << instructor.error().message;

  // Bad modes are refused; a good one is taken, and the trainee sees who is in the session.
  guide.set_alpha(1.5);
  EXPECT_EQ(sessions->Guide(Ctx(db::Role::kInstructor).get(), guide, &g).error_code(),
            StatusCode::INVALID_ARGUMENT);
  guide.set_alpha(0.5);
  ASSERT_TRUE(sessions->Guide(Ctx(db::Role::kInstructor).get(), guide, &g).ok());
  EXPECT_EQ(g.instructor(), "ida");
  EXPECT_EQ(g.mode(), v1::GUIDE_MODE_GUIDE);
  ASSERT_TRUE(sessions->GetGuidance(Ctx(db::Role::kTrainee).get(), ref, &g).ok());
  EXPECT_EQ(g.instructor(), "ida");
  EXPECT_EQ(g.trainee(), "tina");
  EXPECT_DOUBLE_EQ(g.alpha(), 0.5);
  EXPECT_EQ(sessions->GetGuidance(Ctx(tom_).get(), ref, &g).error_code(),
            StatusCode::PERMISSION_DENIED);
  // The dominance reaches the trainee's haptic path (ramped there), as the telemetry says.
  while (!instructor_hand.finished()) {
    ASSERT_TRUE(sessions->GetGuidance(Ctx(db::Role::kInstructor).get(), ref, &g).ok());
    if (g.alpha_now() > 0.45) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_GT(g.alpha_now(), 0.45);
  (*instructor)->Stop();
  EXPECT_GT((*instructor)->stats().received, 100u);

  // Leaving hands the tool back; then the trial ends with its guided share on record.
  guide.set_mode(v1::GUIDE_MODE_NONE);
  guide.set_alpha(0);
  ASSERT_TRUE(sessions->Guide(Ctx(db::Role::kInstructor).get(), guide, &g).ok());
  EXPECT_EQ(g.instructor(), "");
  while (!trainee_hand.finished()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  (*trainee)->Stop();
  v1::StopSessionRequest stop;
  stop.set_id(id);
  ASSERT_TRUE(sessions->Stop(Ctx(db::Role::kTrainee).get(), stop, &s).ok());
  ASSERT_TRUE(s.has_metrics());
  EXPECT_GT(s.metrics().guided_share(), 0.0);
  EXPECT_LT(s.metrics().guided_share(), 1.0);
  // An ended session is joined by no one.
  EXPECT_EQ(sessions->Join(Ctx(db::Role::kInstructor).get(), join, &joined).error_code(),
            StatusCode::FAILED_PRECONDITION);
}

}  // namespace
}  // namespace vsurg::server
