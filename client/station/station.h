// A trainee's station, without its screen: logs in with a bearer token, creates and starts a
// session on the control plane, runs the UDP haptic channel with the device, and keeps the
// trainee going when the server goes away.
//
// Life of a station (Tick drives it; nothing here blocks longer than one RPC deadline):
//
//   connecting ──Create+Start ok──▶ live ──no answer for silence_s, and the server──▶ reconnecting
//       ▲   │                        │       is gone or the session is no longer live       │
//       │   └── fails: retry_s ──────┘                                                      │
//       └───────────────────────────────── every retry_s ───────────────────────────────────┘
//   any ──Finish──▶ finished (the session stopped and recorded; the device at zero force)
//
// Meanwhile the channel's watchdog has faded the force to zero (20 ms + 50 ms; a contact's or
// grasp's model is first held for up to its model_hold_s, 1 s, and a channel stopped sooner fades
// it out over 50 ms), and while reconnecting no channel runs and the device holds zero force. A
// session that is still live but silent may have moved to another node (a draining node's live
// migration; the old node answers with a "moved" notice, which the station takes as a reason to
// probe at once): the probe asks where it runs (Join) and, when that is somewhere else, the station
// follows it there with the same session and key (live → live, a new channel; the trial goes on
// where it was). A session is not resumed across a server restart: the server aborted it and
// recorded it; the station starts a new one (a new session id and key), and the render side resets
// the tissue (generation()).
//
// Two hands: a station given a second device (SetSecondDevice) drives it on a second channel of
// its own when the scene has a second tool (a cut scene's grasper: the session's Create and Join
// give its channel and key), with its own device thread, safety and local model. A second device
// that is lost (DropSecondHand) stops its channel alone: the server fades its tool out and the
// first hand's trial goes on. Two-handed sessions stay on their node (they are not followed).
//
// An instructor's station (StationConfig::instruct) joins another trainee's live session on a
// channel of its own (four-handed training, common/sim/guidance.h): connecting is that join
// alone, a lost server or an ended session is not followed by a session of its own (it ends the
// station), modes switch live (RequestGuide), and Finish leaves the session to its trainee.
//
// Threads: Tick runs on one thread at a time: the station's supervisor thread (StartSupervisor:
// every tick_s, so a render thread stalled for seconds by a first frame or a slow driver never
// delays noticing a lost server), or the caller's (tests). status(), WithChannel() and
// total_stats() may be called from any thread meanwhile; Finish from the owner's, once.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "client/device/device.h"
#include "client/net/remote.h"
#include "client/net/station_channel.h"
#include "common/core/expected.h"
#include "common/core/range.h"
#include "common/core/session_state.h"
#include "common/scoring/palpation.h"
#include "common/scoring/trial_metrics.h"
#include "common/sim/guidance.h"

namespace vsurg::v1 {
class CreateSessionResponse;
class Session;
}  // namespace vsurg::v1

namespace vsurg::client {

struct StationConfig {
  // The bounds the station's options take (vsurg-station --help shows them).
  static constexpr Range kRealtimePriority{0, 99}, kDeadband{0, 0.99}, kModelHoldS{0, 10};
  std::string scene = "arm-torsion";
  // A session prepared for this trainee (by an instructor) to join instead of creating one; a
  // reconnect after the server went away creates a new session as usual. 0: create.
  uint64_t join = 0;
  // Four-handed training: join this live session of another trainee as its instructor (on a
  // channel of the instructor's own) in `guide`'s mode, instead of running one's own; the
  // station never creates, starts or stops a session then, and leaving hands the tool back.
  uint64_t instruct = 0;
  sim::GuideRequest guide{sim::GuideMode::kObserve, 0};
  // An attempt at a course's exercise (TrainingService/Next): sessions are created for it (the
  // scene is the exercise's). 0: a free session of `scene`.
  int64_t exercise_id = 0;
  double rate_hz = 1000;     // device thread
  double rpc_timeout_s = 3;  // per control-plane call
  // Create and Join: the node builds the scene first (a reduced table's first build on a node
  // takes seconds, and a loaded machine more). Shorter, a slow Create is given up and asked
  // again, and every try builds the scene once more (each then aborted as abandoned).
  double create_timeout_s = 20;
  double silence_s = 0.5;  // no force update this long: ask the server how it is
  // While still silent, ask again this often: a node's loss is declared by the control plane
  // (2 s without its heartbeat), and the station should see it within a tenth of a second,
  // not up to another silence_s later.
  double probe_s = 0.1;
  // A probe the control plane does not answer in time (a loaded control plane) is asked again
  // while the silence is shorter than this; the session is given up as lost only after it (the
  // endpoint's own disconnect time). A probe that is refused outright (no replica answers), or
  // that says the session ended, gives it up at once.
  double give_up_s = 5;
  // While silent and live without a "moved" notice, asks where the session runs at most this
  // often (a session can move without a notice reaching the station: a lost datagram).
  double follow_s = 0.5;
  double retry_s = 0.5;        // between connection attempts
  double tick_s = 0.01;        // the supervisor thread's period
  bool reconnect = true;       // false: a lost server ends the station with an error
  int realtime_priority = 20;  // SCHED_FIFO for the haptic threads when permitted (0: off)
  LocalRendering rendering = LocalRendering::kModel;  // between the server's answers
  PassivityMode passivity = PassivityMode::kLocal;    // the station's passivity control
  std::string force_log;         // non-empty: the rendered force per servo cycle (StationOptions)
  double deadband = 0;           // StationOptions::deadband
  uint64_t twist_shape_key = 0;  // StationOptions::twist_shape_key (the view's coil limb)
  double model_hold_s = 1.0;     // StationOptions::model_hold_s
  double force_limit_n = 0;      // StationOptions::force_limit_n (the scene task's)
};

enum class StationState { kConnecting, kLive, kReconnecting, kFinished, kFailed };
const char* StationStateName(StationState s);

struct StationStatus {
  StationState state = StationState::kConnecting;
  uint64_t session = 0;     // the current (or last) session id
  uint64_t generation = 0;  // counts channels: sessions started, and each move of one
  int reconnects = 0;       // sessions started again after the server went away
  int moves = 0;            // times the session moved to another node and the station followed
  // The longest time without a force update while live, s (at the supervisor's tick): across a
  // move or a reconnection too, from the last answer of one channel to the first of the next.
  double longest_gap_s = 0;
  std::string last_error;          // why the last attempt or probe failed
  std::vector<std::string> drops;  // why each live session was given up, in order
};

struct SessionSummary {
  uint64_t id = 0;
  SessionState state = SessionState::kEnded;
  std::string end_reason;
  bool has_metrics = false;
  scoring::TrialMetrics metrics;
  // An attempt at an exercise: each target met or missed, and whether the attempt passed.
  struct TargetCheck {
    std::string metric;
    double value = 0, target = 0;
    bool met = false;
  };
  std::vector<TargetCheck> targets;
  bool targets_passed = false;
  // A palpation: where the lumps were and the trainee's marks (the summary draws them).
  std::optional<scoring::PalpationOutcome> palpation;
};

// The exercise a trainee's station runs when it follows their course (TrainingService/Next):
// the next one, or `pick` when it is one of the open ones (kFailedPrecondition otherwise, and
// kNotFound when the trainee has no course to follow).
struct CourseExercise {
  std::string course, title, scene;
  int64_t exercise_id = 0;
  int position = 0;
  int attempts = 0, streak = 0, consecutive = 0;
  bool may_attempt = true;
  std::vector<std::string> targets;  // "peak_force_n <= 1.5" …
  scoring::TaskSettings task;        // the exercise's settings of its scene's task
};
Expected<CourseExercise> NextCourseExercise(const Remote& remote, int64_t pick, double timeout_s);

class Station {
 public:
  Station(Remote remote, HapticDevice* device, StationConfig config);
  ~Station();  // stops the channel (the session is left to the server's stall/disconnect timers)
  Station(const Station&) = delete;
  Station& operator=(const Station&) = delete;

  // Two hands, before the first Tick (the owner's thread): the second device, driven when the
  // scene has a second tool. DropSecondHand (any thread): the second device is lost; its channel
  // stops until the next session.
  void SetSecondDevice(HapticDevice* device) { second_device_ = device; }
  void DropSecondHand();
  // Runs `fn` on the second hand's running channel; false while there is none.
  bool WithSecondChannel(const std::function<void(StationChannel&)>& fn);
  // The second hand's channel statistics: the running one's, else the last one stopped.
  StationStats second_hand_stats() const;

  void Tick();
  // Ticks on a thread of the station's own until Finish (or StopSupervisor); `on_change` is
  // called on that thread with the first status and at every change of state or session.
  void StartSupervisor(std::function<void(const StationStatus&)> on_change = {});
  void StopSupervisor();
  // Stops the session on the server (recorded with `reason`) and returns it with its metrics;
  // an instructor's station leaves the trainee's session instead, and returns it as it stands.
  Expected<SessionSummary> Finish(const std::string& reason);
  // An instructor's station: switch the mode (sent by the supervisor; any thread). The mode the
  // server last accepted, and why the last switch was refused ("" when it was not).
  void RequestGuide(const sim::GuideRequest& r);
  sim::GuideRequest guide() const;
  std::string guide_error() const;

  StationStatus status() const;
  // Runs `fn` on the running channel (for its view, stats and scene chunks) while holding it,
  // so the supervisor cannot replace it meanwhile; false while there is none (connecting).
  // `fn` also gets the status that goes with that channel (its session and generation).
  bool WithChannel(const std::function<void(StationChannel&, const StationStatus&)>& fn);
  // Datagrams answered over all sessions, and the channel statistics summed the same way.
  StationStats total_stats() const;

 private:
  Status Connect();
  // The session's first call: create one, join the one prepared for this trainee, or join
  // another's as its instructor.
  Expected<v1::CreateSessionResponse> OpenSession(bool join);
  Status SendGuide(const sim::GuideRequest& r);  // the ticking thread
  grpc::Status AskGuide(const sim::GuideRequest& r);
  Expected<v1::Session> LeaveAsInstructor();
  std::shared_ptr<const haptics::TissueSurface> StationSurfaceOf(
      const v1::CreateSessionResponse& created);
  std::shared_ptr<const haptics::NeedleTissueSpec> StationNeedleOf(
      const v1::CreateSessionResponse& created);
  std::shared_ptr<const haptics::BladeParams> StationBladeOf(
      const v1::CreateSessionResponse& created);
  void Probe(double now);
  // The session is live: when it now runs at another UDP address, a channel there. True: moved.
  Expected<bool> Follow();
  void StopChannel();  // both hands'; keeps the first's statistics in finished_stats_
  // The second hand's channel for a session whose scene has a second tool (null: none).
  Expected<std::unique_ptr<StationChannel>> OpenSecondHand(const v1::CreateSessionResponse& created,
                                                           const StationOptions& first);
  void Drop(const std::string& why);
  double Now() const;

  Remote remote_;
  HapticDevice* device_;
  StationConfig config_;
  mutable std::mutex mutex_;  // status_, channel_, finished_stats_ (written by the ticking thread)
  StationStatus status_;
  std::unique_ptr<StationChannel> channel_;
  HapticDevice* second_device_ = nullptr;
  std::unique_ptr<StationChannel> second_channel_;  // under mutex_
  StationStats second_stopped_stats_;               // under mutex_: the last one stopped
  StationStats finished_stats_;                     // of the channels already dropped
  std::mutex supervisor_mutex_;
  std::condition_variable supervisor_cv_;
  bool supervising_ = false;
  std::thread supervisor_;
  double next_attempt_ = 0, last_progress_ = 0, last_probe_ = 0;
  StationOptions channel_options_;  // the running channel's (ticking thread)
  double last_answer_at_ = -1;      // when an answer was last seen (ticking thread); −1: none yet
  double last_follow_ = -1e9;       // when Follow last asked (ticking thread)
  uint64_t last_received_ = 0;
  std::optional<sim::GuideRequest> pending_guide_;  // under mutex_
  sim::GuideRequest guide_;                         // under mutex_: as the server accepted it
  std::string guide_error_;                         // under mutex_
};

}  // namespace vsurg::client
