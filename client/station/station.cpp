#include "client/station/station.h"

#include <grpcpp/grpcpp.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>

#include "common/core/format.h"
#include "common/core/realtime.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::client {
namespace {

// The UDP host the server named (an address, or a name to resolve), as an IP address.
Expected<std::string> ResolveHost(const std::string& host) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0 || found == nullptr)
    return Error{ErrorCode::kUnavailable, "cannot resolve the UDP host '" + host + "'", "udp_host"};
  char text[NI_MAXHOST] = {0};
  const int rc =
      getnameinfo(found->ai_addr, found->ai_addrlen, text, sizeof text, nullptr, 0, NI_NUMERICHOST);
  freeaddrinfo(found);
  if (rc != 0) return Error{ErrorCode::kUnavailable, "cannot resolve '" + host + "'", "udp_host"};
  return std::string(text);
}

std::string Describe(const grpc::Status& s) {
  return s.error_message() + " (gRPC " + std::to_string(static_cast<int>(s.error_code())) + ")";
}

bool IsLive(v1::SessionState s) {
  const auto state = convert::FromProto(s);
  return state && vsurg::IsLive(*state);
}

SessionSummary SummaryOf(const v1::Session& session) {
  SessionSummary out;
  out.id = session.id();
  out.state = convert::FromProto(session.state()).value_or(SessionState::kAborted);
  out.end_reason = session.end_reason();
  out.has_metrics = session.has_metrics();
  out.metrics = convert::FromProto(session.metrics());
  if (session.has_palpation()) out.palpation = convert::FromProto(session.palpation());
  return out;
}

void Add(StationStats& sum, const StationStats& s) {
  sum.sent += s.sent;
  sum.received += s.received;
  sum.dropped += s.dropped;
  sum.stale += s.stale;
  sum.duplicates += s.duplicates;
  sum.lost += s.lost;
  sum.late += s.late;
  sum.energy_to_hand += s.energy_to_hand;
  sum.energy_from_hand += s.energy_from_hand;
  sum.force_log_rows += s.force_log_rows;
  sum.force_log_dropped += s.force_log_dropped;
  sum.watchdog_fades += s.watchdog_fades;
  sum.scene_chunks += s.scene_chunks;
  sum.scene_bytes += s.scene_bytes;
  sum.topology_bytes += s.topology_bytes;
  sum.passivity_energy_dissipated += s.passivity_energy_dissipated;
  sum.max_force = std::max(sum.max_force, s.max_force);
  sum.loop_iterations += s.loop_iterations;
  sum.loop_seconds += s.loop_seconds;
  if (s.loop_hz_min > 0 && (sum.loop_hz_min == 0 || s.loop_hz_min < sum.loop_hz_min))
    sum.loop_hz_min = s.loop_hz_min;
  sum.loop_hz_max = std::max(sum.loop_hz_max, s.loop_hz_max);
  sum.loop_hz =
      sum.loop_seconds > 0 ? static_cast<double>(sum.loop_iterations) / sum.loop_seconds : 0;
}

}  // namespace

const char* StationStateName(StationState s) {
  switch (s) {
    case StationState::kConnecting:
      return "connecting";
    case StationState::kLive:
      return "live";
    case StationState::kReconnecting:
      return "reconnecting";
    case StationState::kFinished:
      return "finished";
    case StationState::kFailed:
      return "failed";
  }
  return "unknown";
}

Station::Station(Remote remote, HapticDevice* device, StationConfig config)
    : remote_(std::move(remote)), device_(device), config_(std::move(config)) {}

Station::~Station() {
  StopSupervisor();
  if (channel_) channel_->Stop();
  if (second_channel_) second_channel_->Stop();
}

void Station::DropSecondHand() {
  std::unique_ptr<StationChannel> second;
  {
    std::lock_guard lock(mutex_);
    second = std::move(second_channel_);
  }
  if (!second) return;
  second->Stop();  // its device at zero force; the server fades its tool out
  std::lock_guard lock(mutex_);
  second_stopped_stats_ = second->stats();
}

StationStats Station::second_hand_stats() const {
  std::lock_guard lock(mutex_);
  return second_channel_ ? second_channel_->stats() : second_stopped_stats_;
}

bool Station::WithSecondChannel(const std::function<void(StationChannel&)>& fn) {
  std::lock_guard lock(mutex_);
  if (!second_channel_) return false;
  fn(*second_channel_);
  return true;
}

Expected<std::unique_ptr<StationChannel>> Station::OpenSecondHand(
    const v1::CreateSessionResponse& created, const StationOptions& first) {
  if (!second_device_ || created.second_channel() == 0) return std::unique_ptr<StationChannel>();
  if (created.second_key().size() != 32)
    return Error{ErrorCode::kUnavailable, "the server sent no usable key for the second hand",
                 "session"};
  StationOptions options = first;  // the same server, rate, passivity and deadband
  options.session = created.second_channel();
  std::copy(created.second_key().begin(), created.second_key().end(), options.key.begin());
  options.surface = nullptr;  // its tool is a grasper: the answers' own local model
  options.needle = nullptr;
  options.blade = nullptr;
  options.force_log.clear();
  options.twist_shape_key = 0;
  return StationChannel::Create(options, second_device_);
}

void Station::StartSupervisor(std::function<void(const StationStatus&)> on_change) {
  if (supervisor_.joinable()) return;
  {
    std::lock_guard lock(supervisor_mutex_);
    supervising_ = true;
  }
  supervisor_ = std::thread([this, on_change = std::move(on_change)] {
    NameThisThread("vsurg-supervise");
    StationStatus seen = status();
    if (on_change) on_change(seen);
    std::unique_lock lock(supervisor_mutex_);
    while (supervising_) {
      lock.unlock();
      Tick();
      const StationStatus now = status();
      if (on_change && (now.state != seen.state || now.session != seen.session)) on_change(now);
      seen = now;
      lock.lock();
      supervisor_cv_.wait_for(lock, std::chrono::duration<double>(config_.tick_s),
                              [&] { return !supervising_; });
    }
  });
}

void Station::StopSupervisor() {
  {
    std::lock_guard lock(supervisor_mutex_);
    supervising_ = false;
  }
  supervisor_cv_.notify_all();
  if (supervisor_.joinable()) supervisor_.join();
}

Expected<CourseExercise> NextCourseExercise(const Remote& remote, int64_t pick, double timeout_s) {
  auto stub = v1::TrainingService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx, timeout_s);
  v1::NextExerciseResponse next;
  const grpc::Status s = stub->Next(&ctx, v1::NextExerciseRequest{}, &next);
  if (!s.ok())
    return Error{ErrorCode::kUnavailable, "cannot ask for the next exercise: " + Describe(s),
                 "course"};
  if (!next.has_next())
    return Error{ErrorCode::kNotFound,
                 "no course to follow: not enrolled, or every exercise already reached", "course"};
  const int64_t want = pick != 0 ? pick : next.exercise_id();
  if (std::find(next.open().begin(), next.open().end(), want) == next.open().end())
    return Error{ErrorCode::kFailedPrecondition,
                 "exercise " + std::to_string(want) +
                     " is not open to you yet (open: the next one, " +
                     std::to_string(next.exercise_id()) + ", and those before it not reached)",
                 "exercise"};
  CourseExercise out;
  out.course = next.course().name();
  for (const v1::Exercise& e : next.course().exercises()) {
    if (e.id() != want) continue;
    out.exercise_id = e.id();
    out.title = e.title();
    out.scene = e.scene();
    out.position = e.position();
    out.consecutive = e.consecutive();
    out.task = convert::FromProto(e.task());
    for (const v1::ExerciseTarget& t : e.targets())
      out.targets.push_back(
          t.metric() + (t.metric() == "score" ? " >= " : " <= ") +
          (t.has_resolved() ? Fixed(t.resolved(), 2) : std::string("(waiting for expert trials)")));
  }
  if (want == next.exercise_id()) {
    out.attempts = next.progress().attempts();
    out.streak = next.progress().streak();
    out.may_attempt = next.may_attempt();
  }
  return out;
}

StationStatus Station::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

bool Station::WithChannel(const std::function<void(StationChannel&, const StationStatus&)>& fn) {
  std::lock_guard lock(mutex_);
  if (!channel_) return false;
  fn(*channel_, status_);
  return true;
}

double Station::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The tissue's surface the server sent with the session (null when it sent none, or one that
// does not read: the station then renders the surface ahead from the answers alone, and says so).
std::shared_ptr<const haptics::TissueSurface> Station::StationSurfaceOf(
    const v1::CreateSessionResponse& created) {
  if (!created.has_surface()) return nullptr;
  auto surface = convert::FromProto(created.surface());
  if (surface.ok()) return *surface;
  std::lock_guard lock(mutex_);
  status_.last_error = "the server's tissue surface was refused: " + surface.error().message;
  return nullptr;
}

// A needle scene's tissue from the server (null when it sent none, or one that does not read:
// the station then renders the answers' force, a round trip late, and says so).
std::shared_ptr<const haptics::NeedleTissueSpec> Station::StationNeedleOf(
    const v1::CreateSessionResponse& created) {
  if (!created.has_needle()) return nullptr;
  auto needle = convert::FromProto(created.needle());
  if (needle.ok()) return *needle;
  std::lock_guard lock(mutex_);
  status_.last_error = "the server's needle tissue was refused: " + needle.error().message;
  return nullptr;
}

std::shared_ptr<const haptics::BladeParams> Station::StationBladeOf(
    const v1::CreateSessionResponse& created) {
  if (!created.has_blade()) return nullptr;
  auto blade = convert::FromProto(created.blade());
  if (blade.ok()) return *blade;
  std::lock_guard lock(mutex_);
  status_.last_error = "the server's blade was refused: " + blade.error().message;
  return nullptr;
}

Expected<v1::CreateSessionResponse> Station::OpenSession(bool join) {
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::CreateSessionResponse created;
  grpc::ClientContext ctx;
  remote_.Prepare(ctx, std::max(config_.rpc_timeout_s, config_.create_timeout_s));
  const bool instructing = config_.instruct != 0;
  v1::JoinRequest prepared;
  prepared.set_id(instructing ? config_.instruct : config_.join);
  prepared.set_with_surface(true);
  if (instructing) {
    prepared.set_role(v1::ROLE_INSTRUCTOR);
    prepared.set_mode(static_cast<v1::GuideMode>(config_.guide.mode));
    prepared.set_alpha(config_.guide.alpha);
  }
  v1::CreateSessionRequest create;
  create.set_scene(config_.scene);
  create.set_exercise_id(config_.exercise_id);
  const grpc::Status s =
      join ? stub->Join(&ctx, prepared, &created) : stub->Create(&ctx, create, &created);
  if (s.ok()) return created;
  // A refusal (bad token, unknown scene, a session that ended) will not get better by retrying.
  const auto code = s.error_code();
  const bool fatal =
      code == grpc::StatusCode::UNAUTHENTICATED || code == grpc::StatusCode::PERMISSION_DENIED ||
      code == grpc::StatusCode::NOT_FOUND || code == grpc::StatusCode::INVALID_ARGUMENT ||
      (instructing && code == grpc::StatusCode::FAILED_PRECONDITION);
  return Error{fatal ? ErrorCode::kPermissionDenied : ErrorCode::kUnavailable,
               std::string(instructing ? "cannot join session " + std::to_string(config_.instruct) +
                                             " as its instructor"
                           : join ? "cannot join session " + std::to_string(config_.join)
                                  : "cannot create a session") +
                   ": " + Describe(s),
               "session"};
}

Status Station::Connect() {
  const bool instructing = config_.instruct != 0;
  const bool join = instructing || (config_.join != 0 && status_.generation == 0);
  auto opened = OpenSession(join);
  if (!opened.ok()) return opened.error();
  const v1::CreateSessionResponse& created = *opened;
  if (join && created.session().scene() != config_.scene)
    return Error{ErrorCode::kPermissionDenied,
                 "session " + std::to_string(created.session().id()) + " is prepared for scene '" +
                     created.session().scene() + "'; start the station with --scene " +
                     created.session().scene(),
                 "scene"};
  if (created.session_key().size() != 32)
    return Error{ErrorCode::kUnavailable, "the server sent no usable session key", "session"};
  if (!instructing) {  // the trainee's station starts its trial; an instructor joins it running
    auto stub = v1::SessionService::NewStub(remote_.channel);
    v1::SessionRef ref;
    ref.set_id(created.session().id());
    v1::Session started;
    grpc::ClientContext ctx;
    remote_.Prepare(ctx, config_.rpc_timeout_s);
    const grpc::Status s = stub->Start(&ctx, ref, &started);
    if (!s.ok())
      return Error{ErrorCode::kUnavailable, "cannot start the session: " + Describe(s), "session"};
  }
  auto host = ResolveHost(created.udp_host());
  if (!host.ok()) return host.error();
  StationOptions options;
  options.server_address = *host;
  options.server_port = static_cast<uint16_t>(created.udp_port());
  // The wire id the datagrams carry: an instructor's channel into the session, or the session's.
  options.session =
      instructing && created.channel() != 0 ? created.channel() : created.session().id();
  std::copy(created.session_key().begin(), created.session_key().end(), options.key.begin());
  options.rate_hz = config_.rate_hz;
  options.realtime_priority = config_.realtime_priority;
  options.rendering = config_.rendering;
  options.passivity_mode = config_.passivity;
  options.force_log = config_.force_log;
  options.deadband = config_.deadband;
  options.twist_shape_key = config_.twist_shape_key;
  options.model_hold_s = config_.model_hold_s;
  options.force_limit_n = config_.force_limit_n;
  options.surface = StationSurfaceOf(created);
  options.needle = StationNeedleOf(created);
  options.blade = StationBladeOf(created);
  auto channel = StationChannel::Create(options, device_);
  if (!channel.ok()) return channel.error();
  Expected<std::unique_ptr<StationChannel>> second =
      instructing ? std::unique_ptr<StationChannel>() : OpenSecondHand(created, options);
  if (!second.ok()) return second.error();
  channel_options_ = options;
  {
    std::lock_guard lock(mutex_);
    channel_ = std::move(*channel);
    second_channel_ = std::move(*second);
    status_.session = created.session().id();
    if (instructing) guide_ = config_.guide;
    ++status_.generation;
    if (status_.state == StationState::kReconnecting) ++status_.reconnects;
    status_.state = StationState::kLive;
    status_.last_error.clear();
  }
  last_received_ = 0;
  last_progress_ = Now();
  return Status::Ok();
}

void Station::StopChannel() {
  DropSecondHand();
  std::lock_guard lock(mutex_);
  if (!channel_) return;
  channel_->Stop();  // the device is left at zero force
  Add(finished_stats_, channel_->stats());
  channel_.reset();
}

void Station::Drop(const std::string& why) {
  StopChannel();
  {
    std::lock_guard lock(mutex_);
    status_.last_error = why;
    status_.drops.push_back(why);
    status_.state = config_.reconnect ? StationState::kReconnecting : StationState::kFailed;
  }
  if (!config_.reconnect) return;
  next_attempt_ = Now();
  remote_.Renew();
}

void Station::Probe(double now) {
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::SessionRef ref;
  ref.set_id(status_.session);
  v1::Session session;
  grpc::ClientContext ctx;
  remote_.Prepare(ctx, std::min(config_.rpc_timeout_s, 1.0));
  const grpc::Status s = stub->Get(&ctx, ref, &session);
  if (!s.ok()) {
    // Slow (a loaded control plane: a drain's migrations, a burst of stations) is not gone; a
    // refused connection is (UNAVAILABLE: gRPC's retry already tried every replica).
    const bool slow = s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
    if (slow && now - last_progress_ < config_.give_up_s) {
      last_probe_ = now;  // asked again at the next probe
      std::lock_guard lock(mutex_);
      status_.last_error = "the server does not answer (asking again): " + Describe(s);
      return;
    }
    return Drop("the server does not answer: " + Describe(s));
  }
  if (!IsLive(session.state()))
    return Drop("session " + std::to_string(status_.session) + " is " +
                convert::StateName(session.state()));
  last_probe_ = now;  // the server is there and the session live: slow, not gone (yet)
  if (config_.instruct != 0) return;  // an instructor's channel is not followed to another node
  // Where it runs: at once when the old node said the session moved, else at most every
  // follow_s (a silent station probes ten times a second; each Join is one more call to the
  // control plane and one to a node, which a loaded site does not need from every station).
  if (channel_->moved_notices() == 0 && now - last_follow_ < config_.follow_s) return;
  last_follow_ = now;
  auto moved = Follow();
  if (!moved.ok()) {
    std::lock_guard lock(mutex_);
    status_.last_error = moved.error().message;
  }
}

Expected<bool> Station::Follow() {
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::JoinRequest ref;  // the surface is the one it has
  ref.set_id(status_.session);
  v1::CreateSessionResponse where;
  grpc::ClientContext ctx;
  remote_.Prepare(ctx, std::min(config_.rpc_timeout_s, 1.0));
  const grpc::Status s = stub->Join(&ctx, ref, &where);
  if (!s.ok())
    return Error{ErrorCode::kUnavailable, "cannot ask where the session runs: " + Describe(s),
                 "session"};
  auto host = ResolveHost(where.udp_host());
  if (!host.ok()) return host.error();
  const auto port = static_cast<uint16_t>(where.udp_port());
  if (*host == channel_options_.server_address && port == channel_options_.server_port)
    return false;  // where it was: only slow
  if (where.session_key().size() != 32 || where.session().id() != status_.session)
    return Error{ErrorCode::kUnavailable, "the server sent no usable session key", "session"};
  StationOptions options = channel_options_;
  options.server_address = *host;
  options.server_port = port;
  std::copy(where.session_key().begin(), where.session_key().end(), options.key.begin());
  StopChannel();  // the old channel's figures are kept; the device at zero force meanwhile
  auto channel = StationChannel::Create(options, device_);
  if (!channel.ok()) {
    Drop("cannot follow session " + std::to_string(status_.session) +
         " to its new node: " + channel.error().message);
    return channel.error();
  }
  channel_options_ = options;
  {
    std::lock_guard lock(mutex_);
    channel_ = std::move(*channel);
    ++status_.generation;
    ++status_.moves;
    status_.last_error.clear();
  }
  last_received_ = 0;
  last_progress_ = Now();
  return true;
}

// Only the ticking thread changes status_ and channel_ (under mutex_, for the readers), so it
// reads them here without the lock.
void Station::Tick() {
  const double now = Now();
  switch (status_.state) {
    case StationState::kConnecting:
    case StationState::kReconnecting: {
      if (now < next_attempt_) return;
      if (Status s = Connect(); !s.ok()) {
        const bool fatal = s.error().code == ErrorCode::kPermissionDenied;
        {
          std::lock_guard lock(mutex_);
          status_.last_error = s.error().message;
          if (fatal) status_.state = StationState::kFailed;
        }
        if (fatal) return;
        next_attempt_ = now + config_.retry_s;
        remote_.Renew();  // the next attempt on a fresh channel
      }
      return;
    }
    case StationState::kLive: {
      std::optional<sim::GuideRequest> asked;
      {
        std::lock_guard lock(mutex_);
        asked.swap(pending_guide_);
      }
      if (asked) {
        const Status sent = SendGuide(*asked);
        std::lock_guard lock(mutex_);
        guide_error_ = sent.ok() ? "" : sent.error().message;
      }
      const uint64_t received = channel_->received();
      if (received != last_received_) {
        last_received_ = received;
        last_progress_ = now;
        if (last_answer_at_ >= 0 && now - last_answer_at_ > status_.longest_gap_s) {
          std::lock_guard lock(mutex_);
          status_.longest_gap_s = now - last_answer_at_;
        }
        last_answer_at_ = now;
      } else if ((now - last_progress_ > config_.silence_s || channel_->moved_notices() > 0) &&
                 now - last_probe_ >= config_.probe_s) {
        Probe(now);  // silent, or told that the session moved: ask where it runs
      }
      return;
    }
    case StationState::kFinished:
    case StationState::kFailed:
      return;
  }
}

void Station::RequestGuide(const sim::GuideRequest& r) {
  std::lock_guard lock(mutex_);
  pending_guide_ = r;
}

sim::GuideRequest Station::guide() const {
  std::lock_guard lock(mutex_);
  return guide_;
}

std::string Station::guide_error() const {
  std::lock_guard lock(mutex_);
  return guide_error_;
}

// SessionService/Guide for the session this station instructs.
grpc::Status Station::AskGuide(const sim::GuideRequest& r) {
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::GuideRequest ask;
  ask.set_id(config_.instruct);
  ask.set_mode(static_cast<v1::GuideMode>(r.mode));
  ask.set_alpha(r.alpha);
  v1::Guidance now;
  grpc::ClientContext ctx;
  remote_.Prepare(ctx, config_.rpc_timeout_s);
  return stub->Guide(&ctx, ask, &now);
}

Status Station::SendGuide(const sim::GuideRequest& r) {
  if (config_.instruct == 0)
    return Error{ErrorCode::kFailedPrecondition, "only an instructor's station guides", "mode"};
  if (Status s = sim::CheckGuideRequest(r); !s.ok()) return s;
  if (const grpc::Status s = AskGuide(r); !s.ok())
    return Error{ErrorCode::kUnavailable, "the mode was refused: " + Describe(s), "mode"};
  std::lock_guard lock(mutex_);
  guide_ = r;
  return Status::Ok();
}

// The instructor leaves (the tool ramps back to the trainee) and reads the session as it stands.
Expected<v1::Session> Station::LeaveAsInstructor() {
  (void)AskGuide({sim::GuideMode::kNone, 0});  // an ended session has nobody left to leave
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::SessionRef ref;
  ref.set_id(config_.instruct);
  v1::Session session;
  grpc::ClientContext get_ctx;
  remote_.Prepare(get_ctx, config_.rpc_timeout_s);
  const grpc::Status s = stub->Get(&get_ctx, ref, &session);
  if (!s.ok())
    return Error{ErrorCode::kUnavailable, "cannot read the session: " + Describe(s), "session"};
  return session;
}

Expected<SessionSummary> Station::Finish(const std::string& reason) {
  StopSupervisor();
  StopChannel();
  const bool had_session = status_.session != 0;
  {
    std::lock_guard lock(mutex_);
    status_.state = StationState::kFinished;
  }
  if (!had_session) return Error{ErrorCode::kUnavailable, "no session was started", "session"};
  v1::Session session;
  if (config_.instruct != 0) {
    auto left = LeaveAsInstructor();
    if (!left.ok()) return left.error();
    session = std::move(left).value();
    return SummaryOf(session);
  }
  auto stub = v1::SessionService::NewStub(remote_.channel);
  v1::StopSessionRequest stop;
  stop.set_id(status_.session);
  stop.set_reason(reason);
  grpc::Status s;
  // A control plane that is only slow (every station of a site stopping at once) is asked again;
  // a Stop that did land meanwhile makes the next one a refusal, read below as the session is.
  for (int attempt = 0; attempt < 3; ++attempt) {
    grpc::ClientContext ctx;
    remote_.Prepare(ctx, config_.rpc_timeout_s * (attempt + 1));
    s = stub->Stop(&ctx, stop, &session);
    if (s.error_code() != grpc::StatusCode::DEADLINE_EXCEEDED) break;
  }
  if (s.error_code() == grpc::StatusCode::FAILED_PRECONDITION) {
    // Already ended (stalled into disconnected, or aborted): read it as it is.
    grpc::ClientContext get_ctx;
    remote_.Prepare(get_ctx, config_.rpc_timeout_s);
    v1::SessionRef ref;
    ref.set_id(status_.session);
    s = stub->Get(&get_ctx, ref, &session);
  }
  if (!s.ok())
    return Error{ErrorCode::kUnavailable, "cannot stop the session: " + Describe(s), "session"};
  SessionSummary out = SummaryOf(session);
  if (config_.exercise_id != 0 && session.targets_size() == 0 && out.has_metrics) {
    // Stop answers with the session; its target checks come with Get.
    grpc::ClientContext get_ctx;
    remote_.Prepare(get_ctx, config_.rpc_timeout_s);
    v1::SessionRef ref;
    ref.set_id(session.id());
    if (stub->Get(&get_ctx, ref, &session).ok()) {
      for (const v1::TargetCheck& t : session.targets())
        out.targets.push_back({t.metric(), t.value(), t.target(), t.met()});
      out.targets_passed = session.targets_passed();
    }
  }
  return out;
}

StationStats Station::total_stats() const {
  std::lock_guard lock(mutex_);
  StationStats sum = finished_stats_;
  if (channel_) {
    const StationStats now = channel_->stats();
    Add(sum, now);
    sum.rtt_p50_us = now.rtt_p50_us;
    sum.rtt_p99_us = now.rtt_p99_us;
    sum.rtt_p999_us = now.rtt_p999_us;
    sum.jitter_us = now.jitter_us;
  }
  // Loss over all sessions: what never came back, over what was sent (each channel counts its
  // own up to its newest answer; the summed sends include the last in-flight few).
  sum.loss = sum.sent > 0 ? std::min(1.0, double(sum.lost) / double(sum.sent)) : 0.0;
  return sum;
}

}  // namespace vsurg::client
