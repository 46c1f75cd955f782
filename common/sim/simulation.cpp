#include "common/sim/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>

#include "common/core/realtime.h"
#include "common/core/state_archive.h"
#include "common/sim/rooms/room_support.h"
#include "common/tissue/reduced_cache.h"

namespace vsurg::sim {

using geometry::Vec3;
using haptics::ForceCommand;
using haptics::StylusSample;

namespace {

// m added to Snapshot::motion when the surface is set anew (back to rest, or a NaN published):
// farther than any kept list reaches, so each is made again.
constexpr double kSurfaceReset = 1e3;

}  // namespace

Expected<std::unique_ptr<Simulation>> Simulation::Create(const Scene& scene,
                                                         const SimulationOptions& options) {
  // Sizes are checked against the memory budget before anything big is made; should memory
  // still run out (other sessions, a small machine), it is an error for this session only.
  try {
    return CreateChecked(scene, options);
  } catch (const std::bad_alloc&) {
    return Error{ErrorCode::kResourceExhausted, "out of memory building scene '" + scene.name + "'",
                 "scene"};
  }
}

Expected<std::unique_ptr<Simulation>> Simulation::CreateChecked(const Scene& scene,
                                                                const SimulationOptions& options) {
  if (!(options.quasi_static_interval_s >= 0 && options.quasi_static_interval_s <= 0.1))
    return InvalidArgument("quasi_static_interval_s", "must be within [0, 0.1] s");
  auto mesh = BuildSceneMesh(scene.mesh);
  if (!mesh.ok()) return mesh.error();
  if (Status s = CheckSessionMemory(scene.region.kind, mesh->surface.positions.size(), "mesh",
                                    scene.region.reduced.mode != ReducedMode::kTwist);
      !s.ok())
    return s.error();
  geometry::TriMesh rest = std::move(mesh->surface);
  std::vector<Vec3> centreline = std::move(mesh->centreline);
  std::unique_ptr<Simulation> sim(new Simulation(scene, std::move(rest), options));
  sim->centreline_points_ = std::move(centreline);
  auto held = SupportedVertices(sim->rest_, scene.region, mesh->groups);
  if (!held.ok()) return held.error();
  sim->held_ = std::move(*held);
  if (Status s = sim->Build(); !s.ok()) return s.error();
  if (options.threaded && options.start_deformation) sim->SetDeformationRunning(true);
  return sim;
}

Simulation::Simulation(const Scene& scene, geometry::TriMesh rest, const SimulationOptions& options)
    : scene_(scene),
      rest_(std::move(rest)),
      options_(options),
      proxy_(*haptics::ProxyContact::Create({})),
      safety_(*haptics::SafetyFilter::Create(haptics::TouchLimits())),
      recorder_(scene.task),
      second_{*haptics::SafetyFilter::Create(haptics::TouchLimits())},
      instructor_safety_(*haptics::SafetyFilter::Create(haptics::TouchLimits())),
      quasi_static_interval_(std::chrono::duration_cast<DeformationPool::Clock::duration>(
          std::chrono::duration<double>(options.quasi_static_interval_s))) {}

Simulation::~Simulation() {
  SetDeformationRunning(false);
}

void Simulation::SetDeformationRunning(bool running) {
  if (running == deformation_running()) return;
  if (options_.pool) {
    if (running && !options_.threaded) return;
    if (running) {
      pool_next_ = DeformationPool::Clock::now();
      pool_seen_ = 0;  // as the thread's loop: a request already made is served at once
      pool_last_ = {};
      options_.pool->Add(this);
    } else {
      options_.pool->Remove(this);  // returns once no worker steps it
    }
    pooled_ = running;
    return;
  }
  if (running) {
    if (!options_.threaded) return;
    stop_.store(false);
    thread_ = std::thread([this] {
      NameThisThread("vsurg-deform");
      DeformationLoop();
    });
    return;
  }
  stop_.store(true);
  input_version_.fetch_add(1);
  input_version_.notify_all();
  thread_.join();
}

Status Simulation::Build() {
  if (Status s = geometry::Validate(rest_); !s.ok()) return s;
  haptics::ProxyParams pp = scene_.haptics.proxy;
  pp.stiffness = std::min(pp.stiffness, scene_.haptics.limits.max_stiffness);  // the device's limit
  auto proxy = haptics::ProxyContact::Create(pp);
  if (!proxy.ok()) return proxy.error();
  proxy_ = *proxy;
  auto safety = haptics::SafetyFilter::Create(scene_.haptics.limits);
  if (!safety.ok()) return safety.error();
  safety_ = *safety;
  // The instructor's hand is not in the tissue when it joins (its force is the guidance's, which
  // ramps in itself): its filter arms at once and ramps the output in, with no quiet wait that a
  // coupling to a trainee's tool a few centimetres away would never satisfy.
  auto instructor_safety = haptics::SafetyFilter::Create(
      scene_.haptics.limits,
      {.gate_force = std::numeric_limits<double>::infinity(), .gate_cycles = 0, .ramp_time = 0.5});
  if (!instructor_safety.ok()) return instructor_safety.error();
  instructor_safety_ = *instructor_safety;
  auto second_safety = haptics::SafetyFilter::Create(scene_.haptics.limits);
  if (!second_safety.ok()) return second_safety.error();
  second_.safety = *second_safety;
  const RoomInputs in{scene_,
                      rest_,
                      held_,
                      centreline_points_,
                      CacheDirectory(),
                      scene_.density * std::abs(geometry::SignedVolume(rest_)),
                      proxy_.params().stiffness,
                      proxy_.params().damping};
  auto room = BuildRoom(in);
  if (!room.ok()) return room.error();
  room_ = std::move(*room);
  room_has_contact_stiffness_ = std::visit(
      [](const auto& r) {
        return requires(const ContactQuery& q) {
          r.ContactStiffness(q);
        };
      },
      room_);
  station_surface_ = MakeStationSurface();
  if (Status s = BuildPalpation(); !s.ok()) return s;
  if (Status s = BuildNeedle(); !s.ok()) return s;
  if (Status s = BuildCut(); !s.ok()) return s;
  const geometry::Bvh bvh(rest_);
  // A surface back at rest: any list a query kept is void (Build also runs on a failed restore).
  surface_motion_ += kSurfaceReset;
  last_published_ = rest_.positions;
  surface_.ForEachSlot([&](Snapshot& s) {
    s.positions = rest_.positions;
    s.bvh = bvh;
    s.motion = surface_motion_;
  });
  visual_.ForEachSlot([&](VisualPositions& v) { v.positions = rest_.positions, v.turn.reset(); });
  last_sent_ = rest_.positions;
  sent_turn_.reset();
  return Status::Ok();
}

bool Simulation::TakeTelemetry(Telemetry& out) {
  const bool fresh = telemetry_.Acquire();
  out = telemetry_.Front();
  return fresh;
}

void Simulation::PublishInput() {
  const DeformInput& a = input_;
  const DeformInput& b = published_;
  // Only what the scene's model reads counts: a press on a twist scene changes the contact's
  // fields every sample, and waking its deformation for each would cost a thread switch per
  // session per millisecond for an update that returns nothing new.
  const bool same = std::visit(
      [&](const auto& room) {
        using Room = std::decay_t<decltype(room)>;
        if constexpr (requires { Room::SameRequest(a, b); }) {
          return Room::SameRequest(a, b);
        } else {
          return a == b;  // every field
        }
      },
      room_);
  if (same && input_version_.load(std::memory_order_relaxed) > 0) return;  // nothing new to ask for
  published_ = input_;
  inputs_.Back() = input_;
  inputs_.Publish();
  input_version_.fetch_add(1, std::memory_order_release);
  input_version_.notify_one();
}

void Simulation::Publish(const Deformed& d, bool surface) {
  const bool overload = d.overload, outside_model = d.outside_model;
  const size_t n = rest_.positions.size();
  if (surface) {
    if (!d.positions) tissue::CoilDeformer::TurnFromRest(*d.turn, *d.turn_state, made_);
    PublishSurface(d.positions ? *d.positions : made_, overload, outside_model);
  } else {
    grasp_overload_.store(overload, std::memory_order_relaxed);
    grasp_outside_model_.store(outside_model, std::memory_order_relaxed);
  }
  VisualPositions& v = visual_.Back();
  if (d.positions) {
    std::copy(d.positions->begin(), d.positions->begin() + n, v.positions.begin());
    v.turn.reset();
  } else {  // the view makes them if it needs them (TakeVisualFrame)
    v.turn = d.turn;
    v.turn_state = *d.turn_state;  // same sizes after the first: no allocation
  }
  v.id = ++publish_id_;
  v.twist = d.twist;
  v.focus = d.focus;
  if (d.faces && d.topology != published_topology_) published_topology_ = d.topology;
  if (d.faces && v.topology != published_topology_) {  // each slot once per change
    v.faces.assign(d.faces->begin(), d.faces->end());
    v.topology = published_topology_;
  }
  visual_.Publish();
  updates_.fetch_add(1, std::memory_order_relaxed);
}

// The surface the haptic path answers from: positions, their bounding boxes refitted, and the
// bound on how far it has moved (its id is the next visual frame's).
void Simulation::PublishSurface(const std::vector<Vec3>& positions, bool overload,
                                bool outside_model) {
  const size_t n = rest_.positions.size();
  Snapshot& back = surface_.Back();
  // The largest vertex move since the last surface published (a NaN counts as a reset).
  double moved2 = 0;
  for (size_t i = 0; i < n; ++i) {
    const double d2 = (positions[i] - last_published_[i]).squaredNorm();
    if (!(d2 <= moved2)) moved2 = d2;
    back.positions[i] = last_published_[i] = positions[i];
  }
  surface_motion_ += std::isfinite(moved2) ? std::sqrt(moved2) : kSurfaceReset;
  back.motion = surface_motion_;
  back.bvh.Refit(back.positions);
  back.id = publish_id_ + 1;
  back.overload = overload;
  back.outside_model = outside_model;
  surface_.Publish();
  surface_updates_.fetch_add(1, std::memory_order_relaxed);
}

void Simulation::Deform(const DeformInput& in) {
  const std::optional<Deformed> d = std::visit([&](auto& room) { return room.Deform(in); }, room_);
  // While a hand grasps, the haptic path answers from the grasp's own law and never reads the
  // surface: only the view is published (no copy, no refit), and the surface it answers from
  // stays the one from before the grasp, consistent with its boxes, until the grasp ends.
  if (d) Publish(*d, !in.grasping);
}

void Simulation::Replay(
    const std::vector<StylusSample>& samples,
    const std::function<void(const StylusSample&, const ForceCommand&)>& on_command) {
  const bool paced = Paced();
  const double dt = scene_.region.dt;
  // Deformation time follows the trial clock, which advances at most kMaxClockStepS per sample:
  // a recording whose clock jumps costs at most that many steps per sample, never a hang.
  double sim_time = trial_time_;
  for (const StylusSample& sample : samples) {
    const ForceCommand c = OnStylus(sample);
    if (paced) {
      while (sim_time + dt <= trial_time_) StepDeformation(), sim_time += dt;
    } else {
      StepDeformation();
    }
    if (on_command) on_command(sample, c);
  }
}

namespace {

// The snapshot's header: a format version (raised whenever any Persist list changes), then what
// the receiver must have built the same way.
constexpr uint32_t kStateMagic = 0x4D495356;  // "VSIM"
// 2: the contact's stiffness fit; 3: the viscoelastic fit; 4: a palpation's marks and coverage;
// 5: a needle's state, tracts and record; 6: the second hand's hold in the deformation's input.
constexpr uint32_t kStateVersion = 6;

}  // namespace

std::string Simulation::SaveState() {
  StateWriter w;
  w(kStateMagic, kStateVersion, scene_.name, static_cast<uint64_t>(rest_.positions.size()),
    static_cast<uint64_t>(rest_.triangles.size()), static_cast<uint64_t>(room_.index()));
  // The haptic side.
  w(recorder_, samples_, port_force_, port_x_, port_has_x_, released_j_, absorbed_j_,
    telemetry_grasping_, live_score_, input_, last_time_, trial_time_, clock_jumps_, has_time_,
    grasping_, grasp_q0_, axis_, axis_point_, lever_, rest_contact_, rest_normal_, last_contact_,
    grasp_query_, proxy_, safety_, stiffness_fit_, viscoelastic_fit_, palpation_, mark_button_,
    needle_);
  // The surface the haptic path answers from (the latest published).
  surface_.Acquire();
  const Snapshot& snap = surface_.Front();
  w(snap.positions, snap.overload, snap.outside_model);
  // The model's own state.
  std::visit(
      [&](const auto& room) {
        if constexpr (requires { room.Save(w); }) room.Save(w);
      },
      room_);
  return w.Take();
}

// The room's haptic side of a restored grasp (surface twist: the jaws' stiffness).
void Simulation::Regrasp(const GraspQuery& q) {
  GraspFrame frame;
  std::visit(
      [&](auto& room) {
        if constexpr (requires { room.StartGrasp(q, frame); }) room.StartGrasp(q, frame);
      },
      room_);
}

// A state's header: the format and what the receiver must have built the same way. Empty when
// it is this simulation's; else why not.
std::string Simulation::ReadStateHeader(StateReader& r) const {
  uint32_t magic = 0, version = 0;
  std::string scene;
  uint64_t vertices = 0, triangles = 0, kind = 0;
  r(magic, version);
  if (!r.ok() || magic != kStateMagic) return "not a simulation's state";
  if (version != kStateVersion)
    return "its state is of format " + std::to_string(version) + ", this server reads " +
           std::to_string(kStateVersion);
  r(scene, vertices, triangles, kind);
  if (!r.ok() || scene != scene_.name || vertices != rest_.positions.size() ||
      triangles != rest_.triangles.size() || kind != room_.index())
    return "it was built from another scene, mesh or model ('" + scene + "')";
  return {};
}

Status Simulation::RestoreState(std::string_view bytes) {
  const auto refuse = [&](const std::string& why) {
    return Error{ErrorCode::kFailedPrecondition,
                 "cannot take over a session of scene '" + scene_.name + "': " + why, "state"};
  };
  StateReader r(bytes);
  if (const std::string why = ReadStateHeader(r); !why.empty()) return refuse(why);
  // Read into a copy of the haptic side and commit only a whole read.
  scoring::TrialRecorder recorder = recorder_;
  haptics::ProxyContact proxy = proxy_;
  haptics::SafetyFilter safety = safety_;
  haptics::StiffnessFit stiffness_fit = stiffness_fit_;
  haptics::ViscoelasticFit viscoelastic_fit = viscoelastic_fit_;
  scoring::PalpationRecorder palpation = palpation_;
  NeedleSide needle = needle_;
  bool mark_button = false;
  DeformInput input;
  GraspQuery grasp_query;
  uint64_t samples = 0, clock_jumps = 0;
  Vec3 port_force, port_x, axis, axis_point, rest_contact, rest_normal;
  bool port_has_x = false, telemetry_grasping = false, has_time = false, grasping = false,
       last_contact = false;
  double released = 0, absorbed = 0, live_score = 0, last_time = 0, trial_time = 0, lever = 0;
  Eigen::Quaterniond grasp_q0;
  r(recorder, samples, port_force, port_x, port_has_x, released, absorbed, telemetry_grasping,
    live_score, input, last_time, trial_time, clock_jumps, has_time, grasping, grasp_q0, axis,
    axis_point, lever, rest_contact, rest_normal, last_contact, grasp_query, proxy, safety,
    stiffness_fit, viscoelastic_fit, palpation, mark_button, needle);
  std::vector<Vec3> positions(rest_.positions.size());
  bool overload = false, outside_model = false;
  r(positions, overload, outside_model);
  if (!r.ok() || (needle.model && !needle.model->Restored()))
    return refuse("its state does not read back whole");
  for (size_t i = 0; i < positions.size(); ++i)  // a surface within a metre of rest
    if ((positions[i] - rest_.positions[i]).squaredNorm() > 1.0)
      return refuse("its surface is out of range for the scene");
  const int n_tri = rest_.TriangleCount(), n_vert = rest_.VertexCount();
  const auto bad_triangle = [&](int t) { return t < -1 || t >= n_tri; };
  if (bad_triangle(input.triangle) || bad_triangle(grasp_query.triangle) ||
      bad_triangle(proxy.state().triangle) || input.grasp_vertex < -1 ||
      input.grasp_vertex >= n_vert || !(lever > 0) || !(grasp_q0.norm() > 0.5) ||
      (grasping && grasp_query.triangle < 0))
    return refuse("its state is out of range for the scene");
  // The model's own state, into the room as built (a failed read leaves it to be rebuilt).
  bool room_ok = true;
  std::visit(
      [&](auto& room) {
        if constexpr (requires { room.Load(r); }) room_ok = room.Load(r);
      },
      room_);
  if (!room_ok || !r.done()) {
    const Status rebuilt = Build();  // back to the room as Create made it
    return rebuilt.ok() ? refuse("its model state does not read back whole") : rebuilt;
  }
  if (grasping) Regrasp(grasp_query);
  recorder_ = recorder;
  palpation_ = palpation;
  needle_ = needle;
  needle_.face_tract = 0;  // the skin's face under the entry: found again for the restored tract
  mark_button_ = mark_button;
  proxy_ = proxy;
  safety_ = safety;
  stiffness_fit_ = stiffness_fit;
  viscoelastic_fit_ = viscoelastic_fit;
  samples_ = samples;
  port_force_ = port_force;
  port_x_ = port_x;
  port_has_x_ = port_has_x;
  released_j_ = released;
  absorbed_j_ = absorbed;
  telemetry_grasping_ = telemetry_grasping;
  live_score_ = live_score;
  input_ = input;
  last_time_ = last_time;
  trial_time_ = trial_time;
  clock_jumps_ = clock_jumps;
  has_time_ = has_time;
  grasping_ = grasping;
  grasp_q0_ = grasp_q0;
  axis_ = axis;
  axis_point_ = axis_point;
  lever_ = lever;
  rest_contact_ = rest_contact;
  rest_normal_ = rest_normal;
  last_contact_ = last_contact;
  grasp_query_ = grasp_query;
  Publish(Deformed{&positions, overload, outside_model, std::nullopt});
  surface_.Acquire();
  PublishInput();  // the deformation goes on from the carried input
  return Status::Ok();
}

std::string Simulation::CacheDirectory() const {
  return options_.cache_dir.empty() ? tissue::DefaultCacheDirectory() : options_.cache_dir;
}

bool Simulation::Paced() const {
  return std::visit([](const auto& room) { return std::decay_t<decltype(room)>::kPaced; }, room_);
}

void Simulation::StepDeformation() {
  inputs_.Acquire();
  Deform(inputs_.Front());
}

void Simulation::DeformationLoop() {
  using Clock = std::chrono::steady_clock;
  const bool paced = Paced();
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(scene_.region.dt));
  auto next = Clock::now();
  Clock::time_point last{};  // the last quasi-static update's start
  uint64_t seen = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    if (!paced) {
      // Coil and reduced (quasi-static): an update only follows a new request; sleep until there
      // is one. While the hand grasps, also until the interval since the last update has passed:
      // the requests meanwhile fold into the newest (a stop waits at most the interval).
      input_version_.wait(seen, std::memory_order_acquire);
      if (stop_.load(std::memory_order_relaxed)) break;
      seen = input_version_.load(std::memory_order_acquire);
      inputs_.Acquire();
      if (const auto due = last + quasi_static_interval_;
          inputs_.Front().grasping && Clock::now() < due) {
        std::this_thread::sleep_until(due);
        if (stop_.load(std::memory_order_relaxed)) break;
        seen = input_version_.load(std::memory_order_acquire);
        inputs_.Acquire();
      }
      last = Clock::now();
    } else {
      inputs_.Acquire();
    }
    Deform(inputs_.Front());
    if (paced) {
      next += period;
      const auto now = Clock::now();
      if (now - next > std::chrono::milliseconds(50)) next = now;  // fell behind: do not burst
      std::this_thread::sleep_until(next);
    }
  }
}

DeformationPool::Clock::time_point Simulation::StepDue(DeformationPool::Clock::time_point now) {
  using Clock = DeformationPool::Clock;
  if (Paced()) {  // the scene's dt, as DeformationLoop keeps it
    inputs_.Acquire();
    Deform(inputs_.Front());
    pool_next_ += std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(scene_.region.dt));
    if (now - pool_next_ > std::chrono::milliseconds(50)) pool_next_ = now;  // fell behind
    return pool_next_;
  }
  const uint64_t version = input_version_.load(std::memory_order_acquire);
  if (version != pool_seen_) {  // the haptic path asked for something new
    inputs_.Acquire();
    // While the hand grasps, at most once per interval, as DeformationLoop: until then the
    // requests fold into the newest.
    const Clock::time_point due = pool_last_ + quasi_static_interval_;
    if (inputs_.Front().grasping && now < due) return due;
    pool_seen_ = version;
    pool_last_ = now;
    Deform(inputs_.Front());
  }
  return now + options_.pool->poll();
}

void Simulation::MakeVertices(VisualPositions& v) {
  if (!v.turn) return;
  tissue::CoilDeformer::TurnFromRest(*v.turn, v.turn_state, v.positions);
  v.turn.reset();
}

bool Simulation::TakeVisualFrame(VisualFrame& out, uint64_t twist_key) {
  if (!visual_.Acquire()) return false;
  VisualPositions& v = visual_.Front();
  out.frame_id = v.id;
  out.twist = v.twist;
  out.indices.clear();
  out.positions.clear();
  if (v.turn && v.twist && twist_key != 0 && v.twist->key == twist_key) {
    // The station remakes this twist from its numbers: nothing to make or compare here. What it
    // shows is now this twist, which last_sent_ becomes when a frame next needs vertices.
    sent_turn_ = v.turn;
    sent_turn_state_ = v.turn_state;
    TakeTopology(v, out);
    std::lock_guard lock(shown_mutex_);
    shown_.turn = v.turn, shown_.turn_state = v.turn_state, shown_.id = v.id;
    return true;
  }
  MakeVertices(v);
  if (sent_turn_) {
    tissue::CoilDeformer::TurnFromRest(*sent_turn_, sent_turn_state_, last_sent_);
    sent_turn_.reset();
  }
  // A vertex is sent once it moved this far from where it was last sent: 1 µm, the wire's
  // quantum; a cut's patch 10 µm, an eighth of a pixel of a station's view of it (the session's
  // record keeps 10 µm units): the blade's cutting force moves the whole sheet by microns as it
  // travels, which would otherwise send most of the patch every frame (docs/BENCHMARKS.md). While
  // the blade works the patch, the threshold grows with a vertex's distance from it, 10 µm within
  // 5 mm to 40 µm from 20 mm on (half a pixel, where the trainee is not looking); once the blade
  // is off the tissue, every vertex is made good to 10 µm again.
  const double moved = scene_.cut ? 1e-5 : 1e-6;
  const auto threshold2 = [&](const geometry::Vec3& x) {
    if (!v.focus) return moved * moved;
    constexpr double kNear = 5e-3, kFar = 4e-5;  // m
    const double t = std::clamp(moved * (x - *v.focus).norm() / kNear, moved, kFar);
    return t * t;
  };
  for (size_t i = 0; i < v.positions.size(); ++i) {
    if ((v.positions[i] - last_sent_[i]).squaredNorm() > threshold2(v.positions[i])) {
      out.indices.push_back(static_cast<int32_t>(i));
      out.positions.push_back(v.positions[i]);
      last_sent_[i] = v.positions[i];
    }
  }
  TakeTopology(v, out);
  if (!out.indices.empty() || (out.topology != 0 && out.topology != shown_.topology)) {
    std::lock_guard lock(shown_mutex_);
    shown_.positions = last_sent_;
    shown_.turn.reset();
    shown_.id = v.id;
    if (out.topology != 0) shown_.faces = v.faces, shown_.topology = v.topology;
  }
  return true;
}

// A cut's faces that differ from the rest mesh, when the topology changed since the last frame
// taken and in the kTopologyRepeats frames after (a datagram lost on the way is sent again).
void Simulation::TakeTopology(const VisualPositions& v, VisualFrame& out) {
  out.topology = 0;
  out.face_indices.clear();
  out.faces.clear();
  if (v.topology != sent_topology_)
    sent_topology_ = v.topology, topology_repeats_ = kTopologyRepeats;
  if (topology_repeats_ <= 0 || v.faces.size() != rest_.triangles.size()) return;
  --topology_repeats_;
  out.topology = v.topology;
  for (size_t f = 0; f < v.faces.size(); ++f)
    if (v.faces[f] != rest_.triangles[f]) {
      out.face_indices.push_back(static_cast<int32_t>(f));
      out.faces.push_back(v.faces[f]);
    }
}

uint64_t Simulation::ShownSurface(std::vector<int32_t>& indices,
                                  std::vector<geometry::Vec3>& positions) const {
  indices.clear();
  positions.clear();
  std::lock_guard lock(shown_mutex_);
  MakeVertices(shown_);
  if (shown_.positions.size() != rest_.positions.size()) return shown_.id;
  constexpr double kMoved2 = 1e-12;  // (1 µm)², as for visual frames
  for (size_t i = 0; i < shown_.positions.size(); ++i)
    if ((shown_.positions[i] - rest_.positions[i]).squaredNorm() > kMoved2) {
      indices.push_back(static_cast<int32_t>(i));
      positions.push_back(shown_.positions[i]);
    }
  return shown_.id;
}

uint64_t Simulation::ShownTopology(std::vector<int32_t>& face_indices,
                                   std::vector<geometry::Triangle>& faces) const {
  face_indices.clear();
  faces.clear();
  std::lock_guard lock(shown_mutex_);
  if (shown_.faces.size() != rest_.triangles.size()) return 0;
  for (size_t f = 0; f < shown_.faces.size(); ++f)
    if (shown_.faces[f] != rest_.triangles[f]) {
      face_indices.push_back(static_cast<int32_t>(f));
      faces.push_back(shown_.faces[f]);
    }
  return shown_.topology;
}

}  // namespace vsurg::sim
