// Live migration of a session between simulation nodes (server/cluster/: a draining node hands
// its sessions to others): the handoff's bytes, and SessionManager's side of a move: BeginMove
// (take the session out of service and save its whole state), FinishMove or CancelMove, and Adopt
// on the receiving node (build it, set it to the handoff's state, make the store's row this
// node's, serve it).
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include "common/core/log.h"
#include "common/core/state_archive.h"
#include "common/core/time.h"
#include "server/session/session_manager.h"

namespace vsurg::server {

namespace {

template <class T>
void PersistOptional(StateWriter& w, const std::optional<T>& o) {
  w(o.has_value());
  if (o) w(*o);
}
template <class T>
void PersistOptional(StateReader& r, std::optional<T>& o) {
  bool has = false;
  r(has);
  if (!has) return o.reset();
  T v{};
  r(v);
  o = v;
}

constexpr uint32_t kHandoffVersion = 2;  // 2: a palpation's case

template <class A, class H>
void PersistHandoff(A& a, H& h) {
  a(h.id, h.trainee, h.scene, h.state, h.created_us, h.started_us, h.key);
  PersistOptional(a, h.task.kind);
  PersistOptional(a, h.task.target);
  PersistOptional(a, h.task.tolerance);
  PersistOptional(a, h.task.hold_s);
  PersistOptional(a, h.task.force_limit);
  PersistOptional(a, h.task.time_limit);
  PersistOptional(a, h.case_seed);
  a(h.simulation, h.trace, h.applied, h.lost, h.span_s, h.rtt_us, h.jitter_us, h.rendered_peak_n,
    h.rendered_over_limit_s, h.from_node, h.from_epoch);
}

}  // namespace

// A handoff as sent: its size before deflating (8 bytes), then the deflated bytes (zlib, level 1:
// the record's surface frames are mostly unchanged, and deflating a forearm's handoff of
// 2–3 MB takes a few milliseconds).
constexpr uint64_t kMaxHandoffBytes = 64ull << 20;

std::string SessionHandoff::Bytes() const {
  StateWriter w;
  w(kHandoffVersion);
  PersistHandoff(w, *this);
  const std::string& raw = w.bytes();
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string out(8 + size, '\0');
  const uint64_t n = raw.size();
  std::memcpy(out.data(), &n, 8);
  if (compress2(reinterpret_cast<Bytef*>(out.data() + 8), &size,
                reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()),
                1) != Z_OK)
    return {};  // refused by the receiver as not a handoff
  out.resize(8 + size);
  return out;
}

Expected<SessionHandoff> SessionHandoff::FromBytes(std::string_view sent) {
  const auto refused = [](const std::string& why) {
    return Error{ErrorCode::kInvalidArgument, "a session handoff that " + why, "handoff"};
  };
  uint64_t n = 0;
  if (sent.size() < 8) return refused("is cut short");
  std::memcpy(&n, sent.data(), 8);
  if (n > kMaxHandoffBytes) return refused("claims more than 64 MB");
  std::string raw(n, '\0');
  uLongf size = static_cast<uLongf>(n);
  if (uncompress(reinterpret_cast<Bytef*>(raw.data()), &size,
                 reinterpret_cast<const Bytef*>(sent.data() + 8),
                 static_cast<uLong>(sent.size() - 8)) != Z_OK ||
      size != n)
    return refused("does not inflate to the size it claims");
  const std::string_view bytes = raw;
  StateReader r(bytes);
  uint32_t version = 0;
  r(version);
  if (!r.ok() || version != kHandoffVersion)
    return Error{ErrorCode::kFailedPrecondition,
                 "a session handoff of format " + std::to_string(version) + "; this server reads " +
                     std::to_string(kHandoffVersion),
                 "handoff"};
  SessionHandoff h;
  PersistHandoff(r, h);
  if (!r.done() || h.key.size() != 32 || !vsurg::IsLive(h.state) || h.id <= 0 ||
      h.from_node.empty())
    return Error{ErrorCode::kInvalidArgument, "a session handoff that does not read back whole",
                 "handoff"};
  return h;
}

Expected<SessionHandoff> SessionManager::BeginMove(uint64_t id) {
  sim::Simulation* simulation = nullptr;
  SessionState state;
  {
    std::lock_guard lock(mutex_);
    auto it = live_.find(id);
    if (it == live_.end())
      return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
    if (it->second->moving)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(id) + " is moving already", "id"};
    // A cut's patch is not carried (rooms/cut_room.h), nor a second hand's channel: a draining
    // node keeps such a session until it ends.
    if (it->second->two_hands)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(id) + " holds two hands: it stays on its node",
                   "id"};
    it->second->moving = true;  // from here Pump, Start and End leave it alone (invariant 7)
    // An instructor's channel does not move: they join the session again where it runs.
    CloseInstructor(id, *it->second);
    simulation = it->second->simulation.get();
    state = it->second->state;
  }
  // The haptic path off (RemoveSession waits for a datagram being answered), then the
  // deformation: the simulation stands still and its state can be read.
  if (endpoint_ && state != SessionState::kCreated) endpoint_->RemoveSession(id);
  simulation->SetDeformationRunning(false);
  SessionHandoff h;
  h.simulation = simulation->SaveState();
  std::lock_guard lock(mutex_);
  const Live& l = *live_.at(id);  // moving: nothing else removes it
  h.id = l.record.id;
  h.trainee = l.record.trainee;
  h.scene = l.record.scene;
  h.state = l.state;
  h.created_us = l.record.created_us;
  h.started_us = l.record.started_us;
  h.key.assign(l.key.begin(), l.key.end());
  h.task = l.task;
  h.case_seed = l.case_seed;
  StateWriter trace;
  trace(l.trace);
  h.trace = trace.Take();
  const auto relaxed = std::memory_order_relaxed;
  h.applied = l.link.applied.load(relaxed);
  h.lost = l.link.lost.load(relaxed);
  h.span_s = l.link.span_s();
  h.rtt_us = l.link.rtt_us.load(relaxed);
  h.jitter_us = l.link.jitter_us.load(relaxed);
  h.rendered_peak_n = l.link.rendered_peak_n.load(relaxed);
  h.rendered_over_limit_s = l.link.rendered_over_limit_s.load(relaxed);
  h.from_node = options_.node;
  h.from_epoch = l.epoch;
  Log("session_moving", h.id, {{"state", SessionStateName(h.state)}});
  return h;
}

void SessionManager::FinishMove(uint64_t id) {
  std::unique_ptr<Live> live;
  {
    std::lock_guard lock(mutex_);
    auto it = live_.find(id);
    if (it == live_.end() || !it->second->moving) return;
    live = std::move(it->second);
    live_.erase(it);
  }
  live->simulation.reset();
  // Its station learns at its next datagram that the session is no longer here.
  if (endpoint_) endpoint_->NoticeMoved(id, live->key);
  NotifyEnded(id);  // here: its watchers find it on its new node
  Log("session_moved", static_cast<int64_t>(id));
}

void SessionManager::CancelMove(uint64_t id) {
  // An answer lost on the way back may hide an adoption that did happen.
  if (auto row = store_.GetSession(static_cast<int64_t>(id));
      row.ok() && (row->node != options_.node || !vsurg::IsLive(row->state))) {
    Log("session_moved_unanswered", static_cast<int64_t>(id), {{"now_on", row->node}});
    return FinishMove(id);
  }
  std::lock_guard lock(mutex_);
  auto it = live_.find(id);
  if (it == live_.end() || !it->second->moving) return;
  Live& l = *it->second;
  if (endpoint_ && l.state != SessionState::kCreated)
    endpoint_->AddSession(id, l.key, l.simulation.get(), &l.link);
  l.moving = false;  // Pump turns its deformation on again once it is driven
  Log("session_move_cancelled", static_cast<int64_t>(id));
}

Expected<CreatedSession> SessionManager::Adopt(const SessionHandoff& h,
                                               std::chrono::system_clock::time_point deadline,
                                               const std::string& placement) {
  if (options_.node.empty() || !options_.lease)
    return Error{ErrorCode::kFailedPrecondition, "only a simulation node adopts sessions", "node"};
  if (h.from_node == options_.node)
    return InvalidArgument("node", "a session moves to another node than its own");
  const int64_t epoch = options_.lease->epoch();
  if (!(options_.lease->Valid() && epoch > 0))
    return Error{ErrorCode::kUnavailable,
                 "node " + options_.node + " holds no lease now: it takes no session", "node"};
  {
    std::lock_guard lock(mutex_);
    if (static_cast<int>(live_.size()) >= options_.max_live_sessions)
      return Error{ErrorCode::kUnavailable,
                   "the server runs its maximum of " + std::to_string(options_.max_live_sessions) +
                       " sessions",
                   "id"};
    if (live_.count(static_cast<uint64_t>(h.id)))
      return Error{ErrorCode::kAlreadyExists,
                   "session " + std::to_string(h.id) + " is live here already", "id"};
  }
  std::optional<uint64_t> case_seed = h.case_seed;
  auto simulation = BuildSimulation(h.scene, h.task, case_seed);
  if (!simulation.ok()) return simulation.error();
  if (Status s = (*simulation)->RestoreState(h.simulation); !s.ok()) return s.error();
  auto live = std::make_unique<Live>();
  live->simulation = std::move(simulation).value();
  live->trace.SetRest(live->simulation->rest_mesh());
  {
    StateReader r(h.trace);
    r(live->trace);
    if (!r.done() || !live->trace.Consistent())
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(h.id) + "'s record does not read back whole",
                   "handoff"};
  }
  // The store's row becomes this node's: the move is decided here, once.
  if (std::chrono::system_clock::now() >= deadline)
    return Error{ErrorCode::kUnavailable,
                 "session " + std::to_string(h.id) + " was built too late to be taken over",
                 "deadline"};
  if (Status s =
          store_.MoveSession(h.id, {h.from_node, h.from_epoch}, {options_.node, epoch}, placement);
      !s.ok())
    return s.error();
  const bool started = h.state != SessionState::kCreated;
  live->state = started ? SessionState::kRunning : SessionState::kCreated;
  live->record.id = h.id;
  live->record.trainee = h.trainee;
  live->record.scene = h.scene;
  live->record.state = live->state;
  live->record.created_us = h.created_us;
  live->record.started_us = h.started_us;
  live->record.node = options_.node;
  live->latest.id = static_cast<uint64_t>(h.id);
  live->latest.state = live->state;
  std::copy(h.key.begin(), h.key.end(), live->key.begin());
  live->created_s = clock_.Now();
  live->epoch = epoch;
  live->task = h.task;
  live->case_seed = h.case_seed;
  const auto relaxed = std::memory_order_relaxed;
  live->link.applied.store(h.applied, relaxed);
  live->link.lost.store(h.lost, relaxed);
  live->link.carried_s.store(h.span_s, relaxed);
  live->link.rtt_us.store(h.rtt_us, relaxed);
  live->link.jitter_us.store(h.jitter_us, relaxed);
  live->link.rendered_peak_n.store(h.rendered_peak_n, relaxed);
  live->link.rendered_over_limit_s.store(h.rendered_over_limit_s, relaxed);
  CreatedSession out;
  out.record = live->record;
  out.key = live->key;
  out.udp_host = options_.udp_host;
  out.udp_port = AdvertisedUdpPort();
  out.surface = live->simulation->station_surface();
  out.needle = live->simulation->station_needle();
  // Served before it is listed: nothing here can end it before it is in the endpoint.
  if (started && endpoint_)
    endpoint_->AddSession(static_cast<uint64_t>(h.id), live->key, live->simulation.get(),
                          &live->link);
  {
    std::lock_guard lock(mutex_);
    live_[static_cast<uint64_t>(h.id)] = std::move(live);
  }
  // A stalled session (its station silent when it moved) is running again here, until the
  // endpoint says otherwise.
  if (h.state == SessionState::kStalled)
    if (Status s = store_.SetSessionState(h.id, SessionState::kRunning, db::NowUs(), "",
                                          {options_.node, epoch});
        !s.ok())
      LogEvent("vsurg-sessions", "store_write_failed",
               {{"session", h.id}, {"error", s.error().message}});
  Log("session_adopted", h.id,
      {{"from", h.from_node}, {"state", SessionStateName(h.state)}, {"scene", h.scene}});
  return out;
}

}  // namespace vsurg::server
