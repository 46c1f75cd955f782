// Four-handed training in the session manager (sessions.h, common/sim/guidance.h): an
// instructor's channel into a live session, its mode and dominance, and who is in the session.
#include <openssl/rand.h>

#include "server/session/session_manager.h"

namespace vsurg::server {

namespace {

Error Unimplemented() {
  return Error{ErrorCode::kFailedPrecondition,
               "four-handed training runs on a server that holds its sessions (the all-in-one "
               "server); a site's control plane does not relay an instructor's channel",
               "id"};
}

Error NotLive(uint64_t id) {
  return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
}

}  // namespace

Expected<CreatedSession> Sessions::JoinInstructor(uint64_t, const std::string&) {
  return Unimplemented();
}
Status Sessions::LeaveInstructor(uint64_t, const std::string&) {
  return Unimplemented();
}
Expected<SessionGuidance> Sessions::Guide(uint64_t, const std::string&, const sim::GuideRequest&) {
  return Unimplemented();
}
Expected<SessionGuidance> Sessions::Guidance(uint64_t) const {
  return Unimplemented();
}

Expected<SessionManager::Live*> SessionManager::LiveSession(uint64_t id) const {
  const auto it = live_.find(id);
  if (it == live_.end()) return NotLive(id);
  if (it->second->moving)
    return Error{ErrorCode::kUnavailable,
                 "session " + std::to_string(id) + " is moving to another node", "id"};
  return it->second.get();
}

void SessionManager::RemoveChannels(uint64_t id, const Live& l) {
  endpoint_->RemoveSession(id);
  if (l.two_hands) endpoint_->RemoveSession(SecondHandChannel(id));
}

void SessionManager::CloseInstructor(uint64_t id, Live& l) {
  if (l.instructor.empty()) return;
  if (endpoint_) endpoint_->RemoveSession(InstructorChannel(id));
  l.simulation->RequestGuidance({});
  l.instructor.clear();
}

// The channel is added under the manager's lock, so an End that takes the session out after it
// also closes the channel (End removes both; the I/O threads never take this lock).
Expected<CreatedSession> SessionManager::JoinInstructor(uint64_t id,
                                                        const std::string& instructor) {
  if (!endpoint_)
    return Error{ErrorCode::kFailedPrecondition, "this server has no haptic channel", "id"};
  std::lock_guard lock(mutex_);
  auto live = LiveSession(id);
  if (!live.ok()) return live.error();
  Live& l = **live;
  if (!l.instructor.empty() && l.instructor != instructor)
    return Error{ErrorCode::kFailedPrecondition,
                 "instructor '" + l.instructor + "' is in session " + std::to_string(id) +
                     " already; one instructor at a time",
                 "id"};
  CreatedSession out;
  if (RAND_bytes(out.key.data(), static_cast<int>(out.key.size())) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "key"};
  const bool rejoin = !l.instructor.empty();
  if (rejoin) endpoint_->RemoveSession(InstructorChannel(id));  // the old key stops here
  l.instructor = instructor;
  l.instructor_key = out.key;
  endpoint_->AddInstructorChannel(InstructorChannel(id), l.instructor_key, l.simulation.get(),
                                  &l.instructor_link);
  out.record = l.record;
  out.record.state = l.state;
  out.udp_host = options_.udp_host;
  out.udp_port = AdvertisedUdpPort();
  out.channel = InstructorChannel(id);
  Log("instructor_joined", static_cast<int64_t>(id),
      {{"instructor", instructor}, {"again", rejoin ? "yes" : "no"}});
  return out;
}

Status SessionManager::LeaveInstructor(uint64_t id, const std::string& instructor) {
  std::lock_guard lock(mutex_);
  auto live = LiveSession(id);
  if (!live.ok()) return live.error();
  Live& l = **live;
  if (l.instructor != instructor)
    return Error{ErrorCode::kFailedPrecondition,
                 "'" + instructor + "' is not the instructor in session " + std::to_string(id),
                 "id"};
  CloseInstructor(id, l);
  Log("instructor_left", static_cast<int64_t>(id), {{"instructor", instructor}});
  return Status::Ok();
}

Expected<SessionGuidance> SessionManager::Guide(uint64_t id, const std::string& instructor,
                                                const sim::GuideRequest& request) {
  if (Status s = sim::CheckGuideRequest(request); !s.ok()) return s.error();
  {
    std::lock_guard lock(mutex_);
    auto live = LiveSession(id);
    if (!live.ok()) return live.error();
    Live& l = **live;
    if (l.instructor.empty() || l.instructor != instructor)
      return Error{ErrorCode::kFailedPrecondition,
                   "only the instructor who joined session " + std::to_string(id) +
                       " sets its mode; join it first",
                   "id"};
    l.simulation->RequestGuidance(request);
  }
  Log("guidance", static_cast<int64_t>(id),
      {{"mode", sim::GuideModeName(request.mode)}, {"alpha", request.alpha}});
  return Guidance(id);
}

Expected<SessionGuidance> SessionManager::Guidance(uint64_t id) const {
  std::lock_guard lock(mutex_);
  const auto it = live_.find(id);
  if (it == live_.end()) return NotLive(id);
  const Live& l = *it->second;
  SessionGuidance g;
  g.trainee = l.record.trainee;
  g.instructor = l.instructor;
  g.requested = l.simulation->requested_guidance();
  g.alpha = l.latest.sim.guide_alpha;
  return g;
}

}  // namespace vsurg::server
