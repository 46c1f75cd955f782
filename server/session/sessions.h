// The sessions as the control plane sees them (gRPC, HTTP, the domain rules): create, start, stop,
// join, watch. Two implementations: SessionManager runs the sessions in this process (the
// all-in-one server, and a simulation node); ClusterSessions (server/cluster/) places them on
// simulation nodes and reaches them through their internal API (DESIGN.md "Beyond one machine").
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/trial_metrics.h"
#include "common/sim/simulation.h"
#include "db/store.h"
#include "proto/wire/datagram.h"

namespace vsurg::server {

using sim::SessionTelemetry;

struct CreatedSession {
  db::SessionRecord record;
  wire::SessionKey key{};
  std::string udp_host;
  uint16_t udp_port = 0;
  // The tissue's surface and contact law the station renders ahead of its tool (null: none).
  std::shared_ptr<const haptics::TissueSurface> surface;
  // A needle scene's tissue for the station's own needle model (null: not a needle scene).
  std::shared_ptr<const haptics::NeedleTissueSpec> needle;
  // A cut scene's blade for the station's own fracture model (null: not a cut scene).
  std::shared_ptr<const haptics::BladeParams> blade;
  // The wire id the station's datagrams carry: the session's, or an instructor's channel into it
  // (server/net/udp_endpoint.h InstructorChannel). 0: the session's id.
  uint64_t channel = 0;
  // Two hands: the station's second device's channel (SecondHandChannel) and key, for a scene
  // with a second tool (0: none).
  uint64_t second_channel = 0;
  wire::SessionKey second_key{};
};

// Four-handed training (common/sim/guidance.h): who is in a live session and what the
// instructor asked for; `alpha` is the dominance as the haptic path has ramped it so far.
struct SessionGuidance {
  std::string trainee;
  std::string instructor;  // "" while no instructor is in the session
  sim::GuideRequest requested;
  double alpha = 0;
};

class Sessions {
 public:
  virtual ~Sessions() = default;

  // `scene` is a scene name from scenes/ (letters, digits, '-'), never a path; `task` changes
  // its task (an exercise's settings, scoring::ApplyTaskSettings), kInvalidArgument if they do
  // not fit it.
  virtual Expected<CreatedSession> Create(const std::string& trainee, const std::string& scene,
                                          const scoring::TaskSettings& task = {}) = 0;
  virtual Expected<db::SessionRecord> Start(uint64_t id) = 0;
  virtual Expected<db::SessionRecord> Stop(uint64_t id, const std::string& reason) = 0;
  virtual Expected<db::SessionRecord> Get(uint64_t id) = 0;  // the store's row, live state
  // A live session's station credentials (a session an instructor prepared, joined by the
  // trainee's station): the key and the UDP address, as Create returned them, and the station's
  // surface (with_surface: a remote node is asked for it; in process it costs nothing). kNotFound
  // once it left the live states.
  virtual Expected<CreatedSession> Join(uint64_t id, bool with_surface) = 0;
  // Four-handed training. An instructor's station joins a live session on a channel of its own
  // (CreatedSession::channel, a fresh key, no surface: its tip is not the tool's); one instructor
  // at a time: the same instructor joining again gets a new key and the old channel is closed,
  // another is refused (kFailedPrecondition). kNotFound once the session left the live states.
  // Leaving hands the tool back (ramped) and closes the channel. Guide sets the mode and the
  // dominance (sim::CheckGuideRequest) of the instructor in the session, `instructor`.
  // SessionManager runs them; ClusterSessions asks the session's node (NodeService.JoinInstructor,
  // LeaveInstructor, Guide, GetGuidance). The defaults answer kFailedPrecondition.
  virtual Expected<CreatedSession> JoinInstructor(uint64_t id, const std::string& instructor);
  virtual Status LeaveInstructor(uint64_t id, const std::string& instructor);
  virtual Expected<SessionGuidance> Guide(uint64_t id, const std::string& instructor,
                                          const sim::GuideRequest& request);
  virtual Expected<SessionGuidance> Guidance(uint64_t id) const;
  // A live session's surface at rest (the mesh the monitors' surface states move): positions in
  // metres, triangles as vertex indices. kNotFound once it left the live states.
  virtual Status RestSurface(uint64_t id, std::vector<geometry::Vec3>& positions,
                             std::vector<int32_t>& triangles) const = 0;
  // A live session's record so far (server/session/trace_recorder.h: its traces and surface
  // frames as JSON text), for a watcher who opens its page mid-session. kNotFound once it left
  // the live states: the store then has it (db::Store::GetSessionTrace).
  virtual Expected<std::string> Trace(uint64_t id) const = 0;
  virtual bool IsLive(uint64_t id) const = 0;
  // Aborts every live session of `user` (its trainee), e.g. when their tokens are revoked or the
  // account is disabled: access ends with the account, on the UDP channel too. Returns how many.
  virtual int EndSessionsOf(const std::string& user, const std::string& reason) = 0;

  // Telemetry subscribers: `fn` runs on a sampler thread at the telemetry rate with the latest
  // figures of every live session (or of `session` only, when not 0), and once more with an
  // empty list when that session leaves the live states. Unsubscribe waits for a running call
  // to finish, so after it returns `fn` is never called again.
  using Subscriber = std::function<void(const std::vector<SessionTelemetry>&, bool ended)>;
  virtual uint64_t Subscribe(uint64_t session, Subscriber fn) = 0;
  virtual void Unsubscribe(uint64_t token) = 0;

  // Ends what this process runs (live sessions aborted, threads stopped). Idempotent.
  virtual void Shutdown() = 0;
};

}  // namespace vsurg::server
