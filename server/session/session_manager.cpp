#include "server/session/session_manager.h"

#include <openssl/rand.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "common/core/log.h"
#include "common/core/realtime.h"
#include "common/core/state_archive.h"
#include "common/core/time.h"
#include "common/sim/palpation_case.h"
#include "common/sim/scene.h"

namespace vsurg::server {
namespace {

bool IsSceneName(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-')) return false;
  return true;
}

}  // namespace

Expected<std::unique_ptr<SessionManager>> SessionManager::Open(
    db::Store& store, UdpEndpoint* endpoint, const SessionManagerOptions& options) {
  const SessionManagerOptions& o = options;
  if (o.udp_host.empty() || o.udp_host.size() > 253)
    return InvalidArgument("udp_host", "the host stations are told to send to is required");
  using O = SessionManagerOptions;
  if (!O::kTelemetryHz.Contains(o.telemetry_hz))
    return InvalidArgument("telemetry_hz", O::kTelemetryHz.Must() + " Hz");
  if (!O::kMaxLiveSessions.Contains(o.max_live_sessions))
    return InvalidArgument("max_live_sessions", O::kMaxLiveSessions.Must());
  if (o.max_sessions_per_user < 1 || o.max_sessions_per_user > o.max_live_sessions)
    return InvalidArgument("max_sessions_per_user", "must be within 1..max_live_sessions");
  if (!O::kStartTimeoutS.Contains(o.start_timeout_s))
    return InvalidArgument("start_timeout_s", O::kStartTimeoutS.Must() + " s");
  if (o.node.size() > 64) return InvalidArgument("node", "a node name has at most 64 characters");
  if (!O::kDeformationWorkers.Contains(o.deformation_workers))
    return InvalidArgument("deformation_workers",
                           O::kDeformationWorkers.Must() + " (0: one per core)");
  if (!O::kQuasiStaticIntervalS.Contains(o.quasi_static_interval_s))
    return InvalidArgument("quasi_static_interval_s", O::kQuasiStaticIntervalS.Must() + " s");
  if (!O::kCasesReady.Contains(o.cases_ready))
    return InvalidArgument("cases_ready", O::kCasesReady.Must());
  if (!o.node.empty() && !o.lease)
    return InvalidArgument("lease", "a simulation node's sessions need its lease");
  // Nothing is live in a new process: what the store says is live was left by one that died.
  // (A node's leftovers are aborted when it acquires its name, not here: a second process
  // started under a live node's name must not take that node's sessions away.)
  if (o.node.empty())
    if (auto aborted = store.AbortOrphanedSessions(db::NowUs(), "server restarted", o.node);
        !aborted.ok())
      return Error{
          aborted.error().code,
          "cannot record the sessions a previous server left live: " + aborted.error().message,
          "db"};
  std::unique_ptr<SessionManager> m(new SessionManager(store, endpoint, options));
  if (o.cases_ready > 0) m->KeepCases();
  m->sampler_ = std::thread([p = m.get()] {
    NameThisThread("vsurg-sampler");
    p->SamplerLoop();
  });
  return m;
}

SessionManager::SessionManager(db::Store& store, UdpEndpoint* endpoint,
                               const SessionManagerOptions& options)
    : store_(store),
      endpoint_(endpoint),
      options_(options),
      clock_(options.clock ? *options.clock : DefaultClock()) {
  if (options.deformation_workers >= 0)
    pool_ = std::make_unique<sim::DeformationPool>(options.deformation_workers);
  cases_ = std::make_unique<sim::CaseBank>(sim::CaseBank::Options{"", options.cases_ready});
  pending_.reserve(64);
}

void SessionManager::Log(const char* event, int64_t session, LogFields fields) const {
  fields.insert(fields.begin(), {"session", session});
  if (!options_.node.empty()) fields.emplace_back("node", options_.node);
  LogEvent("vsurg-sessions", event, fields);
}

Status SessionManager::Write(const PendingWrite& w) {
  if (w.metrics)
    return store_.EndSession(w.id, w.state, w.at_us, w.reason, *w.metrics, {options_.node, w.epoch},
                             w.trace);
  return store_.SetSessionState(w.id, w.state, w.at_us, w.reason, {options_.node, w.epoch});
}

void SessionManager::WriteOrKeep(PendingWrite w) {
  const Status s = Write(w);
  if (s.ok()) return;
  if (s.error().code == ErrorCode::kUnavailable) {
    if (pending_.size() >= kMaxPending) {
      LogEvent("vsurg-sessions", "store_write_dropped",
               {{"session", pending_.front().id}, {"pending", pending_.size()}});
      pending_.erase(pending_.begin());
    }
    pending_.push_back(std::move(w));
    return;
  }
  LogEvent("vsurg-sessions", "store_write_refused",
           {{"session", w.id}, {"state", SessionStateName(w.state)}, {"error", s.error().message}});
}

void SessionManager::RetryPending() {
  if (pending_.empty()) return;
  std::vector<PendingWrite> again;
  again.swap(pending_);
  for (size_t i = 0; i < again.size(); ++i) {
    const Status s = Write(again[i]);
    if (s.ok()) continue;
    if (s.error().code == ErrorCode::kUnavailable) {  // still down: this and the rest, in order
      pending_.insert(pending_.end(), std::make_move_iterator(again.begin() + i),
                      std::make_move_iterator(again.end()));
      return;
    }
    LogEvent("vsurg-sessions", "store_write_refused",
             {{"session", again[i].id}, {"error", s.error().message}});
  }
}

SessionManager::~SessionManager() {
  Shutdown();
}

Expected<CreatedSession> SessionManager::Create(const std::string& trainee,
                                                const std::string& scene,
                                                const scoring::TaskSettings& task) {
  return Create(trainee, scene, task, "");
}

Expected<CreatedSession> SessionManager::Create(const std::string& trainee,
                                                const std::string& scene_name,
                                                const scoring::TaskSettings& task,
                                                const std::string& placement) {
  if (!IsSceneName(scene_name))
    return InvalidArgument("scene", "a scene name (letters, digits and '-'), not a path");
  // The limits are checked again when the session is inserted (two concurrent creates).
  if (Status s = CheckLimits(trainee); !s.ok()) return s.error();
  std::optional<uint64_t> case_seed;
  auto simulation = BuildSimulation(scene_name, task, case_seed);
  if (!simulation.ok()) return simulation.error();
  CreatedSession out;
  if (RAND_bytes(out.key.data(), static_cast<int>(out.key.size())) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "key"};
  const sim::Scene& scene = (*simulation)->scene();
  const bool two_hands = scene.cut && scene.cut->grasper;
  if (two_hands && RAND_bytes(out.second_key.data(), static_cast<int>(out.second_key.size())) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "key"};
  const int64_t epoch = options_.lease ? options_.lease->epoch() : 0;
  if (options_.lease && !(options_.lease->Valid() && epoch > 0))
    return Error{ErrorCode::kUnavailable,
                 "node " + options_.node + " holds no lease now: it takes no session", "scene"};
  auto record = store_.CreateSession(trainee, scene_name, {options_.node, epoch}, placement);
  if (!record.ok()) return record.error();
  out.record = *record;
  out.udp_host = options_.udp_host;
  out.udp_port = AdvertisedUdpPort();
  out.surface = (*simulation)->station_surface();
  out.needle = (*simulation)->station_needle();
  out.blade = (*simulation)->station_blade();
  if (two_hands) out.second_channel = SecondHandChannel(static_cast<uint64_t>(record->id));
  auto live = std::make_unique<Live>();
  live->simulation = std::move(simulation).value();
  live->trace.SetRest(live->simulation->rest_mesh());
  live->state = SessionState::kCreated;
  live->record = *record;
  live->latest.id = static_cast<uint64_t>(record->id);
  live->latest.state = SessionState::kCreated;
  live->key = out.key;
  live->two_hands = two_hands;
  live->second_key = out.second_key;
  live->created_s = clock_.Now();
  live->epoch = epoch;
  live->task = task;
  live->case_seed = case_seed;
  {
    std::lock_guard lock(mutex_);
    if (Status s = CheckLimitsLocked(trainee); s.ok()) {
      live_[static_cast<uint64_t>(record->id)] = std::move(live);
      Log("session_created", record->id, {{"scene", scene_name}});
      return out;
    }
  }
  // Lost the race for the last slot: the row exists, so record it as aborted.
  if (Status s = store_.SetSessionState(record->id, SessionState::kAborted, db::NowUs(),
                                        "session limit reached", {options_.node, epoch});
      !s.ok())
    LogEvent("vsurg-sessions", "store_write_failed",
             {{"session", record->id}, {"error", s.error().message}});
  return CheckLimits(trainee).error();
}

Expected<std::unique_ptr<sim::Simulation>> SessionManager::BuildSimulation(
    const std::string& scene_name, const scoring::TaskSettings& task,
    std::optional<uint64_t>& case_seed) {
  if (!IsSceneName(scene_name))
    return InvalidArgument("scene", "a scene name (letters, digits and '-'), not a path");
  auto scene = sim::LoadSceneByName(scene_name);
  if (!scene.ok()) {
    // A missing scene is NOT_FOUND; a scene file that does not load is the server's problem to
    // fix, refused with why (FAILED_PRECONDITION), and touches no other scene.
    const bool missing = scene.error().code == ErrorCode::kNotFound;
    return Error{missing ? ErrorCode::kNotFound : ErrorCode::kFailedPrecondition,
                 missing ? scene.error().message
                         : "scene '" + scene_name + "' is unusable: " + scene.error().message,
                 "scene"};
  }
  if (!task.empty()) {
    auto applied = scoring::ApplyTaskSettings(scene->task, task);
    if (!applied.ok())
      return InvalidArgument("task." + applied.error().field, applied.error().message);
    scene->task = *applied;
  }
  if (scene->cases) {  // a palpation's own case: no two attempts alike
    if (!case_seed) case_seed = cases_->Take(*scene).value_or(sim::CaseBank::NewSeed());
    auto drawn = sim::DrawCase(*scene, *case_seed);
    if (!drawn.ok())
      return Error{ErrorCode::kFailedPrecondition,
                   "scene '" + scene_name + "' draws no case: " + drawn.error().message, "scene"};
    *scene = std::move(*drawn);
  }
  // No deformation thread until a station drives the session (invariant 5).
  // Reduced scenes cache their precomputation in the default folder
  // (tissue::DefaultCacheDirectory).
  auto simulation = sim::Simulation::Create(
      *scene, {.threaded = true,
               .start_deformation = false,
               .cache_dir = {},
               .pool = pool_.get(),
               .quasi_static_interval_s = options_.quasi_static_interval_s});
  if (case_seed) cases_->Discard(scene_name, *case_seed);  // loaded: its file is done with
  if (!simulation.ok())
    return Error{ErrorCode::kFailedPrecondition,
                 "scene '" + scene_name + "' does not build: " + simulation.error().message,
                 "scene"};
  return simulation;
}

// Every scene in the scenes folder that draws palpation cases gets its bank filled from the start.
void SessionManager::KeepCases() {
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(sim::ScenesDirectory(), error)) {
    if (entry.path().extension() != ".json") continue;
    auto scene = sim::LoadScene(entry.path().string());
    if (scene.ok() && scene->cases) cases_->Keep(*scene);
  }
}

Status SessionManager::CheckLimits(const std::string& trainee) const {
  std::lock_guard lock(mutex_);
  return CheckLimitsLocked(trainee);
}

Status SessionManager::CheckLimitsLocked(const std::string& trainee) const {
  if (static_cast<int>(live_.size()) >= options_.max_live_sessions)
    return Error{ErrorCode::kUnavailable,
                 "the server runs its maximum of " + std::to_string(options_.max_live_sessions) +
                     " sessions",
                 "scene"};
  int mine = 0;
  for (const auto& [id, l] : live_) mine += l->record.trainee == trainee;
  if (mine >= options_.max_sessions_per_user)
    return Error{ErrorCode::kResourceExhausted,
                 "trainee '" + trainee + "' already has " + std::to_string(mine) +
                     " live sessions (the limit is " +
                     std::to_string(options_.max_sessions_per_user) + "); stop one first",
                 "trainee"};
  return Status::Ok();
}

int SessionManager::EndSessionsOf(const std::string& user, const std::string& reason) {
  std::vector<uint64_t> ids;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, l] : live_)
      if (l->record.trainee == user) ids.push_back(id);
  }
  int ended = 0;
  for (uint64_t id : ids) ended += End(id, SessionState::kAborted, reason).ok();
  return ended;
}

Expected<db::SessionRecord> SessionManager::Start(uint64_t id) {
  if (!endpoint_)
    return Error{ErrorCode::kFailedPrecondition, "this server has no haptic channel", "id"};
  int64_t epoch = 0;
  bool started = false;
  {
    std::lock_guard lock(mutex_);
    auto it = live_.find(id);
    if (it == live_.end()) {
      auto rec = store_.GetSession(static_cast<int64_t>(id));
      if (!rec.ok()) return rec.error();
      return Error{
          ErrorCode::kFailedPrecondition,
          "session " + std::to_string(id) + " is " + SessionStateName(rec->state) + ", not live",
          "id"};
    }
    Live& l = *it->second;
    if (l.moving)
      return Error{ErrorCode::kUnavailable,
                   "session " + std::to_string(id) + " is moving to another node", "id"};
    started = l.state != SessionState::kCreated;
    if (!started) {
      l.state = SessionState::kRunning;
      l.latest.state = SessionState::kRunning;
      epoch = l.epoch;
      // The channels open under the lock: an End that takes the session after it is released
      // finds them open and removes them before the simulation goes. The endpoint's lanes
      // never take this lock, so waiting for them here cannot deadlock.
      endpoint_->AddSession(id, l.key, l.simulation.get(), &l.link);
      if (l.two_hands)
        endpoint_->AddChannel(SecondHandChannel(id), ChannelRole::kSecondHand, l.second_key,
                              l.simulation.get(), &l.second_link);
    }
  }
  if (started) return Get(id);  // already started: idempotent
  if (Status s = store_.SetSessionState(static_cast<int64_t>(id), SessionState::kRunning,
                                        db::NowUs(), "", {options_.node, epoch});
      !s.ok())
    return s.error();
  Log("session_started", static_cast<int64_t>(id));
  return Get(id);
}

namespace {

// The most force any haptic device a station drives can render (N): the strongest desktop
// devices peak at some 35 N (Haption's Virtuose 6D; Force Dimension's sigma.7 20 N, Touch-class
// 3.3 N). A station that reports more is wrong or lying, and its record keeps the bound.
constexpr double kMaxStationForceN = 50;

// A figure the station reports, as the record keeps it: within [0, max] (not finite: 0).
double Bounded(double reported, double max) {
  return std::isfinite(reported) ? std::clamp(reported, 0.0, max) : 0.0;
}

// The trial's link figures from the endpoint's counters (read after the session left it). The
// station's own figures are its word: bounded by what the server can check (a device's force, and
// no more time over the limit than the server saw the station's datagrams for).
scoring::LinkFigures LinkFiguresOf(const LinkStats& l) {
  scoring::LinkFigures f;
  const auto relaxed = std::memory_order_relaxed;
  const uint64_t applied = l.applied.load(relaxed), lost = l.lost.load(relaxed);
  f.station_peak_force = Bounded(l.rendered_peak_n.load(relaxed), kMaxStationForceN);
  f.station_time_over_limit = Bounded(l.rendered_over_limit_s.load(relaxed), l.span_s());
  f.rtt_ms = l.rtt_us.load(relaxed) / 1e3;
  f.jitter_ms = l.jitter_us.load(relaxed) / 1e3;
  f.loss = applied + lost > 0 ? static_cast<double>(lost) / static_cast<double>(applied + lost) : 0;
  const double span = l.span_s();
  f.rate_hz = span > 0 ? static_cast<double>(applied) / span : 0;
  return f;
}

}  // namespace

Status SessionManager::End(uint64_t id, SessionState state, const std::string& reason, bool retry,
                           bool unstarted_only) {
  std::unique_ptr<Live> live;
  {
    std::lock_guard lock(mutex_);
    auto it = live_.find(id);
    if (it == live_.end()) return Error{ErrorCode::kNotFound, "no live session", "id"};
    if (unstarted_only && it->second->state != SessionState::kCreated)
      return Error{ErrorCode::kFailedPrecondition,
                   "session " + std::to_string(id) + " has been started: not abandoned", "id"};
    if (it->second->moving)  // invariant 7: the move decides; the next try reaches its node
      return Error{ErrorCode::kUnavailable,
                   "session " + std::to_string(id) + " is moving to another node", "id"};
    live = std::move(it->second);
    live_.erase(it);
  }
  if (endpoint_ && live->state != SessionState::kCreated) RemoveChannels(id, *live);
  CloseInstructor(id, *live);
  scoring::TrialMetrics metrics = live->simulation->Metrics();  // the haptic path is off
  metrics.link = LinkFiguresOf(live->link);
  if (live->simulation->scene().task.kind == scoring::TaskKind::kPalpate)
    live->trace.SetPalpation(live->simulation->palpation());
  if (const haptics::NeedleModel* needle = live->simulation->needle())
    live->trace.SetNeedle(*needle);
  live->simulation.reset();
  std::string trace = live->trace.samples() > 0 ? live->trace.Json() : std::string();
  // The state, the trial and its record in one transaction, under the session's epoch
  // (invariant 3).
  const int64_t at = db::NowUs();
  Status s = store_.EndSession(static_cast<int64_t>(id), state, at, reason, metrics,
                               {options_.node, live->epoch}, trace);
  const bool kept = retry && !s.ok() && s.error().code == ErrorCode::kUnavailable;
  Log("session_ended", static_cast<int64_t>(id),
      {{"state", SessionStateName(state)},
       {"reason", reason},
       {"score", metrics.score},
       {"record", s.ok() ? "written"
                  : kept ? "pending"
                         : "refused"}});
  if (kept)  // again next tick
    pending_.push_back(
        {static_cast<int64_t>(id), state, at, reason, metrics, live->epoch, std::move(trace)});
  NotifyEnded(id);
  return s;
}

void SessionManager::NotifyEnded(uint64_t id) {
  std::lock_guard lock(subscribers_mutex_);
  for (auto& [token, sub] : subscribers_)
    if (sub.first == id) sub.second({}, true);
}

int SessionManager::AbandonAll(const std::string& reason) {
  std::map<uint64_t, std::unique_ptr<Live>> dropped;
  {
    std::lock_guard lock(mutex_);
    dropped.swap(live_);
  }
  for (auto& [id, live] : dropped) {
    if (endpoint_ && live->state != SessionState::kCreated && !live->moving)
      RemoveChannels(id, *live);
    if (!live->moving) CloseInstructor(id, *live);
    live->simulation.reset();
    NotifyEnded(id);
    Log("session_dropped", static_cast<int64_t>(id), {{"reason", reason}});  // no record written
  }
  return static_cast<int>(dropped.size());
}

Expected<db::SessionRecord> SessionManager::Stop(uint64_t id, const std::string& reason) {
  Status s = End(id, SessionState::kEnded, reason.empty() ? "stopped" : reason);
  if (!s.ok() && s.error().code != ErrorCode::kNotFound) return s.error();
  return Get(id);  // stopping an ended session is idempotent: its record
}

Expected<db::SessionRecord> SessionManager::Abandon(uint64_t id, const std::string& reason) {
  Status s = End(id, SessionState::kAborted, reason, false, /*unstarted_only=*/true);
  if (!s.ok()) return s.error();
  return Get(id);
}

Expected<db::SessionRecord> SessionManager::Get(uint64_t id) {
  auto rec = store_.GetSession(static_cast<int64_t>(id));
  if (!rec.ok()) return rec;
  std::lock_guard lock(mutex_);
  if (auto it = live_.find(id); it != live_.end()) rec->state = it->second->state;
  return rec;
}

Expected<CreatedSession> SessionManager::Join(uint64_t id, bool /*with_surface: in-process*/) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = live_.find(id);
  if (it == live_.end())
    return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
  CreatedSession out;
  out.record = it->second->record;
  out.record.state = it->second->state;
  out.key = it->second->key;
  if (it->second->two_hands) {
    out.second_channel = SecondHandChannel(id);
    out.second_key = it->second->second_key;
  }
  out.udp_host = options_.udp_host;
  out.udp_port = AdvertisedUdpPort();
  out.surface = it->second->simulation->station_surface();
  out.needle = it->second->simulation->station_needle();
  out.blade = it->second->simulation->station_blade();
  return out;
}

Status SessionManager::RestSurface(uint64_t id, std::vector<geometry::Vec3>& positions,
                                   std::vector<int32_t>& triangles) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = live_.find(id);
  if (it == live_.end())
    return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
  const geometry::TriMesh& mesh = it->second->simulation->rest_mesh();  // immutable
  positions = mesh.positions;
  triangles.clear();
  triangles.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) triangles.push_back(static_cast<int32_t>(t[k]));
  return Status::Ok();
}

Expected<std::string> SessionManager::Trace(uint64_t id) const {
  std::optional<TraceRecorder> copy;  // serialised outside the lock: deflating takes a while
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = live_.find(id);
    if (it == live_.end())
      return Error{ErrorCode::kNotFound, "session " + std::to_string(id) + " is not live", "id"};
    copy.emplace(it->second->trace);
  }
  return copy->Json();
}

bool SessionManager::IsLive(uint64_t id) const {
  std::lock_guard lock(mutex_);
  return live_.count(id) > 0;
}

std::vector<uint64_t> SessionManager::LiveIds() const {
  std::lock_guard lock(mutex_);
  std::vector<uint64_t> ids;
  for (const auto& [id, l] : live_)
    if (!l->moving) ids.push_back(id);
  return ids;
}

uint16_t SessionManager::AdvertisedUdpPort() const {
  return options_.udp_port ? options_.udp_port : endpoint_ ? endpoint_->port() : 0;
}

int SessionManager::LiveCount() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(live_.size());
}

uint64_t SessionManager::Subscribe(uint64_t session, Subscriber fn) {
  std::lock_guard lock(subscribers_mutex_);
  const uint64_t token = next_token_++;
  subscribers_[token] = {session, std::move(fn)};
  return token;
}

void SessionManager::Unsubscribe(uint64_t token) {
  std::lock_guard lock(subscribers_mutex_);  // waits for a running delivery
  subscribers_.erase(token);
}

void SessionManager::Pump() {
  RetryPending();
  // Sessions never started expire; a deformation thread runs only for a driven session.
  std::vector<uint64_t> expired;
  {
    const double now = clock_.Now();
    std::lock_guard lock(mutex_);
    for (auto& [id, l] : live_) {
      if (l->moving) continue;  // invariant 7
      if (l->state == SessionState::kCreated && now - l->created_s > options_.start_timeout_s)
        expired.push_back(id);
      l->simulation->SetDeformationRunning(l->state == SessionState::kRunning &&
                                           l->latest.sim.samples > 0);
    }
  }
  for (uint64_t id : expired) {
    char reason[64];
    std::snprintf(reason, sizeof reason, "not started within %g s", options_.start_timeout_s);
    (void)End(id, SessionState::kAborted, reason, /*retry=*/true);
  }
  if (!endpoint_) return;
  for (const SessionEvent& e : endpoint_->TakeEvents()) {
    const SessionState state = e.state;
    if (state == SessionState::kDisconnected) {
      (void)End(e.session, SessionState::kDisconnected, "no stylus data for 5 s", /*retry=*/true);
      continue;
    }
    int64_t epoch = 0;
    {
      std::lock_guard lock(mutex_);
      auto it = live_.find(e.session);
      if (it == live_.end() || it->second->state == state) continue;
      it->second->state = state;
      it->second->latest.state = state;
      epoch = it->second->epoch;
    }
    // Stalls and resumptions are rare; the sampler waits for their commit (a few ms of delayed
    // telemetry at most), and the single writer keeps their order. A refusal (the node lost its
    // lease) changes nothing here: the agent drops the sessions when it learns of the loss.
    Log("session_state", static_cast<int64_t>(e.session), {{"state", SessionStateName(state)}});
    WriteOrKeep({static_cast<int64_t>(e.session), state, db::NowUs(), "", std::nullopt, epoch, {}});
  }
}

// Counting arrivals in the sampler's 33 ms windows of the server's clock read a steady 1 kHz
// station as 898–1111 Hz (±2 datagrams of network and scheduling jitter in 33); the station's
// own stamps over a second measure the loop itself: a 1 kHz loop reads 1000 ± 1 Hz. Samples the
// network lost count against the rate (it is the rate the server got). A station clock that goes
// back, or a session that stops running, starts a new window.
void SessionManager::UpdateHapticRate(Live& l, SessionTelemetry& t) {
  const uint64_t n = t.sim.samples;
  const double at = t.sim.time;
  if (l.state != SessionState::kRunning || n == 0) {
    t.haptic_rate_hz = 0;
    l.rate_time = -1;
    return;
  }
  if (l.rate_time < 0 || n < l.rate_samples || !(at >= l.rate_time)) {
    l.rate_samples = n;
    l.rate_time = at;
    return;
  }
  constexpr double kWindowS = 1.0;
  if (at - l.rate_time >= kWindowS) {
    t.haptic_rate_hz = static_cast<double>(n - l.rate_samples) / (at - l.rate_time);
    l.rate_samples = n;
    l.rate_time = at;
  }
}

void SessionManager::SamplerLoop() {
  const auto period = std::chrono::duration<double>(1.0 / options_.telemetry_hz);
  std::vector<SessionTelemetry> all;
  std::vector<int32_t> face_indices;  // a cut's topology, for its record
  std::vector<geometry::Triangle> faces;
  for (uint64_t tick = 0;; ++tick) {
    {
      std::unique_lock lock(stop_mutex_);
      if (stop_cv_.wait_for(lock, period, [this] { return stopping_; })) return;
    }
    Pump();
    all.clear();
    {
      std::lock_guard lock(mutex_);
      for (auto& [id, l] : live_) {
        SessionTelemetry& t = l->latest;
        l->simulation->TakeTelemetry(t.sim);
        t.server_time_us = db::NowUs();
        const uint64_t applied = l->link.applied.load(std::memory_order_relaxed);
        const uint64_t lost = l->link.lost.load(std::memory_order_relaxed);
        t.packets = applied;
        t.packet_loss = applied + lost > 0 ? static_cast<double>(lost) / (applied + lost) : 0.0;
        t.rtt_us = l->link.rtt_us.load(std::memory_order_relaxed);
        UpdateHapticRate(*l, t);
        t.scene = l->record.scene;
        t.trainee = l->record.trainee;
        t.has_surface = tick % 3 == 0;
        if (t.has_surface)
          t.surface_frame = l->simulation->ShownSurface(t.surface_indices, t.surface_positions);
        else
          t.surface_indices.clear(), t.surface_positions.clear();
        l->trace.AddSample(t);
        if (t.has_surface && t.surface_frame != 0)
          l->trace.AddSurface(t.sim.time, t.surface_indices, t.surface_positions);
        if (t.has_surface && l->simulation->scene().cut) {
          const uint64_t topology = l->simulation->ShownTopology(face_indices, faces);
          l->trace.AddTopology(t.sim.time, topology, face_indices, faces);
        }
        all.push_back(t);
      }
    }
    std::lock_guard lock(subscribers_mutex_);
    std::vector<SessionTelemetry> one;
    for (auto& [token, sub] : subscribers_) {
      if (sub.first == 0) {
        sub.second(all, false);
        continue;
      }
      one.clear();
      for (const SessionTelemetry& t : all)
        if (t.id == sub.first) one.push_back(t);
      if (!one.empty()) sub.second(one, false);
    }
  }
}

void SessionManager::Shutdown() {
  {
    std::lock_guard lock(stop_mutex_);
    if (stopping_ && !sampler_.joinable()) return;
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (sampler_.joinable()) sampler_.join();
  std::vector<uint64_t> ids;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, l] : live_)
      if (!l->moving) ids.push_back(id);
  }
  for (uint64_t id : ids) (void)End(id, SessionState::kAborted, "server shut down");
}

}  // namespace vsurg::server
