#include "common/sim/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>

#include "common/geometry/distances.h"
#include "common/geometry/tet_generators.h"
#include "common/geometry/tetrahedralize.h"
#include "common/tissue/reduced_cache.h"

namespace vsurg::sim {

using geometry::Vec3;
using haptics::ForceCommand;
using haptics::StylusSample;

namespace {

// Reduced tables (contact and surface twist) are read-only and large (72 and 12 B per vertex
// pair): the sessions of one scene share one, found by the key of its inputs while any session
// holds it (one map per table type). The map's lock is held only to look up; a table being built
// holds its own key's lock, so a second session of the same scene waits for it (and does not
// build it twice) while other scenes' sessions go on. `load` reads it from the cache or builds it.
template <class Table>
std::shared_ptr<const Table> SharedTable(const std::string& key,
                                         const std::function<Expected<Table>()>& load,
                                         Status& status) {
  struct Entry {
    std::weak_ptr<const Table> table;
    std::shared_ptr<std::mutex> building = std::make_shared<std::mutex>();
  };
  static std::mutex mutex;
  static std::map<std::string, Entry> tables;
  std::shared_ptr<std::mutex> building;
  {
    std::lock_guard<std::mutex> lock(mutex);
    Entry& e = tables[key];
    if (auto alive = e.table.lock()) return alive;
    building = e.building;
  }
  std::lock_guard<std::mutex> build_lock(*building);
  {
    std::lock_guard<std::mutex> lock(mutex);  // built while this one waited?
    if (auto alive = tables[key].table.lock()) return alive;
  }
  auto table = load();
  if (!table.ok()) {
    status = table.error();
    return nullptr;
  }
  auto shared = std::make_shared<const Table>(std::move(*table));
  std::lock_guard<std::mutex> lock(mutex);
  tables[key].table = shared;
  return shared;
}

// A point of the rest surface given by its triangle and barycentric coordinates.
Vec3 RestPoint(const geometry::TriMesh& rest, int triangle, const Vec3& barycentric) {
  const geometry::Triangle& t = rest.triangles[triangle];
  return barycentric[0] * rest.positions[t[0]] + barycentric[1] * rest.positions[t[1]] +
         barycentric[2] * rest.positions[t[2]];
}

// The scene's tissue as the FEM takes it (E = 2G(1 + ν)).
tissue::FemParams SceneMaterial(const Scene& scene) {
  tissue::FemParams p;
  p.poisson = scene.poisson_ratio;
  p.young = 2 * scene.shear_modulus * (1 + scene.poisson_ratio);
  p.density = scene.density;
  return p;
}

// A reduced table's inputs for a scene: its FEM held by the scene's support (as the surface's
// `held` vertices are), the display, and every display vertex not held, which a tool can reach.
template <class Params>
tissue::TableInputs<Params> TableInputsFor(const Scene& scene, const geometry::TriMesh& rest,
                                           const std::vector<int>& held, geometry::TetMesh fem) {
  tissue::TableInputs<Params> in;
  in.mesh = std::move(fem);
  in.material = SceneMaterial(scene);
  in.fixed = SupportedFemVertices(in.mesh, rest, held, scene.region);
  in.display = rest;
  std::vector<uint8_t> is_held(rest.VertexCount(), 0);
  for (int v : held) is_held[v] = 1;
  for (int v = 0; v < rest.VertexCount(); ++v)
    if (!is_held[v]) in.reachable.push_back(v);
  return in;
}

Vec3 AnyPerpendicular(const Vec3& a) {
  const Vec3 t = std::abs(a.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return a.cross(t).normalized();
}

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
      recorder_(scene.task) {}

Simulation::~Simulation() {
  SetDeformationRunning(false);
}

void Simulation::SetDeformationRunning(bool running) {
  if (running == thread_.joinable()) return;
  if (running) {
    if (!options_.threaded) return;
    stop_.store(false);
    thread_ = std::thread([this] { DeformationLoop(); });
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
  const RegionSpec& region = scene_.region;
  const double mass = scene_.density * std::abs(geometry::SignedVolume(rest_));
  if (region.kind == ModelKind::kCoil) {
    auto coil = tissue::CoilSpringModel::Create(region.coil);
    if (!coil.ok()) return coil.error();
    coil_ = std::make_unique<tissue::CoilSpringModel>(std::move(*coil));
    if (region.coil_mode == tissue::TwistMode::kLimb && centreline_points_.size() < 2) {
      return InvalidArgument("regions[0].model.mode",
                             "limb mode needs a limb mesh (with a centreline)");
    }
  } else {
    if (region.kind == ModelKind::kMassSpring) {
      tissue::MassSpringBuildParams bp = region.mass_spring;
      bp.total_mass = mass;
      auto sys = tissue::BuildMassSpring(rest_, bp);
      if (!sys.ok()) return sys.error();
      tissue::MassSpringStepParams sp;
      sp.integrator = region.integrator;
      auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
      if (!model.ok()) return model.error();
      msm_ = std::make_unique<tissue::MassSpringModel>(std::move(*model));
      const int n = rest_.VertexCount();
      for (int v : held_) {
        msm_->SetFixed(v, true);
        if (bp.volume == tissue::VolumeMode::kInnerLayer) msm_->SetFixed(n + v, true);
      }
    } else if (region.kind == ModelKind::kReduced) {
      if (Status st = BuildReduced(); !st.ok()) return st;
    } else {
      masses_.assign(rest_.VertexCount(), mass / rest_.VertexCount());
    }
  }
  const geometry::Bvh bvh(rest_);
  surface_.ForEachSlot([&](Snapshot& s) {
    s.positions = rest_.positions;
    s.bvh = bvh;
  });
  visual_.ForEachSlot([&](VisualPositions& v) { v.positions = rest_.positions; });
  last_sent_ = rest_.positions;
  return Status::Ok();
}

// The FEM of a reduced contact or surface-twist model: a tetrahedral ball of the scene sphere's
// radius, or the mesh file's closed surface tetrahedralised (CGAL).
Expected<geometry::TetMesh> Simulation::ReducedFemMesh() const {
  const RegionSpec& region = scene_.region;
  if (scene_.mesh.kind == MeshKind::kSphere)
    return geometry::MakeTetBall({scene_.mesh.radius, region.reduced.fem_cells});
  auto fem = geometry::Tetrahedralize(rest_, {region.reduced.fem_size, 0, 3.0});
  if (!fem.ok())
    return Error{fem.error().code, scene_.mesh.path + ": " + fem.error().message, "mesh"};
  return fem;
}

Status Simulation::BuildReduced() {
  const RegionSpec& region = scene_.region;
  if (region.reduced.mode == ReducedMode::kTwist) return BuildReducedTwist();
  auto fem = ReducedFemMesh();
  if (!fem.ok()) return fem.error();
  if (region.reduced.mode == ReducedMode::kSurfaceTwist) return BuildSurfaceTwist(std::move(*fem));
  auto in = TableInputsFor<tissue::ContactResponseParams>(scene_, rest_, held_, std::move(*fem));
  in.params.footprint_radius = region.reduced.footprint_radius;
  Status status = Status::Ok();
  const tissue::ReducedCache cache(CacheDirectory());
  auto table = SharedTable<tissue::ContactResponse>(
      tissue::ContactKey(in),
      [&] { return cache.ContactResponseFor(scene_.name + "-contact", in); }, status);
  if (!table) return status;
  auto model =
      tissue::ReducedContactModel::Create(table, rest_.positions, region.reduced.max_force);
  if (!model.ok()) return model.error();
  reduced_contact_ = std::make_unique<tissue::ReducedContactModel>(std::move(*model));
  return Status::Ok();
}

Status Simulation::BuildReducedTwist() {
  // The FEM: the limb's tapered cylinder (its proximal end fixed at z = 0, the torque on the
  // distal face), meshed for torsion.
  if (centreline_points_.size() < 2)
    return InvalidArgument("regions[0].model.mode", "a reduced twist model needs a limb mesh");
  const geometry::LimbParams& limb = scene_.mesh.limb;
  auto cylinder = geometry::MakeTetCylinder(geometry::TorsionCylinder(
      limb.length, limb.radius_proximal, limb.radius_distal, scene_.region.reduced.fem_rings));
  if (!cylinder.ok()) return cylinder.error();
  tissue::TwistFieldInputs in;
  in.mesh = cylinder->mesh;
  in.material = SceneMaterial(scene_);
  in.fixed = cylinder->base;
  in.face = cylinder->tip;
  in.face_area = cylinder->tip_area;
  in.origin = Vec3::Zero();
  in.axis = Vec3::UnitZ();
  in.display = rest_.positions;
  tissue::ReducedCache cache(CacheDirectory());
  auto field = cache.TwistFieldFor(scene_.name + "-twist", in);
  if (!field.ok()) return field.error();
  auto model =
      tissue::ReducedTwistModel::Create(*field, rest_.positions, scene_.region.reduced.max_twist);
  if (!model.ok()) return model.error();
  reduced_twist_ = std::make_unique<tissue::ReducedTwistModel>(std::move(*model));
  return Status::Ok();
}

// Forceps may grasp any vertex above the support: one twist field per such vertex (reduced.h,
// 4.), cached on disk.
Status Simulation::BuildSurfaceTwist(geometry::TetMesh fem) {
  auto in = TableInputsFor<tissue::SurfaceTwistParams>(scene_, rest_, held_, std::move(fem));
  in.params.jaw_radius = scene_.region.reduced.jaw_radius;
  const tissue::ReducedCache cache(CacheDirectory());
  Status status = Status::Ok();
  surface_twist_ = SharedTable<tissue::SurfaceTwistTable>(
      tissue::SurfaceTwistKey(in),
      [&] { return cache.SurfaceTwistFor(scene_.name + "-surface-twist", in); }, status);
  return surface_twist_ ? Status::Ok() : status;
}

ForceCommand Simulation::Zero(const StylusSample& s, uint32_t events) {
  ForceCommand c;
  c.time = std::isfinite(s.time) ? s.time : last_time_;
  c.events = events;
  c.local.position0 = s.position.allFinite() ? s.position : Vec3::Zero();
  return c;
}

ForceCommand Simulation::OnStylus(const StylusSample& s) {
  uint32_t events = 0;
  if (!safety_.AcceptInput(s, events)) {
    // Zero force, let go of everything; the next good sample passes the start-up gate again.
    if (grasping_) events |= haptics::kEventGraspEnd;
    grasping_ = false;
    last_contact_ = false;
    proxy_.Reset();
    safety_.Disarm();
    input_.grasping = false;
    input_.torque = 0;
    input_.triangle = -1;
    input_.force_on_tissue.setZero();
    PublishInput();
    return Zero(s, events);
  }
  // The trial clock follows the station's time in steps of at most kMaxClockStepS; a longer
  // step forward advances it by the bound, a step backwards by a nominal millisecond, and both
  // count as clock jumps. A repeated stamp does not advance it.
  double step = 0;
  if (has_time_) {
    const double station_dt = s.time - last_time_;  // may overflow to ±inf: still ordered
    if (station_dt >= 0 && station_dt <= kMaxClockStepS) {
      step = station_dt;
    } else {
      step = station_dt > 0 ? kMaxClockStepS : 1e-3;
      events |= haptics::kEventClockJump;
      ++clock_jumps_;
    }
  }
  trial_time_ += step;
  double dt = step;
  if (!(dt > 0 && dt < 0.1)) dt = 1e-3;  // repeated, or after a pause or a jump
  last_time_ = s.time;
  has_time_ = true;
  surface_.Acquire();
  const Snapshot& snap = surface_.Front();
  const bool button = (s.buttons & haptics::kButtonGrasp) != 0;
  const scoring::TaskKind task = scene_.task.kind;

  ForceCommand cmd;
  cmd.time = s.time;
  Vec3 force = Vec3::Zero();
  Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();
  double quantity = 0;
  bool overload = snap.overload;
  if (grasping_ && !button) {
    grasping_ = false;
    events |= haptics::kEventGraspEnd;
    input_.grasping = false;
    input_.torque = 0;
    proxy_.Reset();
  }
  if (grasping_) {
    // The twist about the axis is the twist part of the rotation since the grasp (swing-twist).
    const Eigen::Quaterniond rel = s.orientation.normalized() * grasp_q0_.conjugate();
    double twist = 2.0 * std::atan2(rel.vec().dot(axis_), rel.w());
    twist = std::remainder(twist, 2.0 * std::numbers::pi);
    tissue::CoilTorque answer;
    if (reduced_twist_ || surface_twist_) {
      // The FEM's twist field: linear, T = Φ·dT/dΦ up to the capacity (a surface grasp's were
      // read from the table when it started).
      const double capacity = reduced_twist_ ? reduced_twist_->torque_capacity() : grasp_capacity_;
      answer.torque =
          twist * (reduced_twist_ ? reduced_twist_->grasp_stiffness() : grasp_stiffness_);
      answer.overload = std::abs(answer.torque) > capacity;
      answer.torque = std::clamp(answer.torque, -capacity, capacity);
    } else {
      answer = coil_->Inverse(twist);
    }
    overload = overload || answer.overload;
    const Vec3 arm = input_.grasp_point - axis_point_;
    const Vec3 turned = axis_point_ + Eigen::AngleAxisd(twist, axis_) * arm;
    const Vec3 radial = turned - axis_point_;
    const Vec3 tangent =
        radial.norm() > 1e-9 ? Vec3(axis_.cross(radial).normalized()) : AnyPerpendicular(axis_);
    const double hold = scene_.haptics.hold_stiffness;
    force = scene_.haptics.force_scale * (-answer.torque / lever_) * tangent +
            hold * (turned - s.position);
    jacobian = -hold * Eigen::Matrix3d::Identity();
    input_.torque = answer.torque;
    quantity = twist;
    cmd.grasping = true;
    cmd.contact = true;
    cmd.proxy = turned;
    cmd.twist = twist;
    cmd.torque = answer.torque;
  } else {
    const haptics::ProxyState& ps = proxy_.Update(snap.positions, snap.bvh, s.position, dt);
    if (ps.contact) {
      const geometry::Triangle& tri = rest_.triangles[ps.triangle];
      if (!last_contact_) {
        ++input_.contact_id;
        rest_contact_ = RestPoint(rest_, ps.triangle, ps.barycentric);
        rest_normal_ = geometry::TriangleNormal(rest_, ps.triangle);
      }
      if (button && (coil_ || reduced_twist_ || surface_twist_)) {
        // Grasp the point under the proxy.
        grasping_ = true;
        events |= haptics::kEventGraspStart;
        ++input_.grasp_id;
        input_.grasping = true;
        input_.grasp_point = ps.scp;
        grasp_q0_ = s.orientation.normalized();
        if (surface_twist_) {
          // The jaws hold the contact triangle's nearest vertex; its stiffness and capacity are
          // read-only table reads (no allocation).
          int k = 0;
          for (int j = 1; j < 3; ++j)
            if (ps.barycentric[j] > ps.barycentric[k]) k = j;
          input_.grasp_vertex = tri[k];
          grasp_stiffness_ = tissue::SurfaceTwistStiffness(*surface_twist_, tri[k]);
          grasp_capacity_ = tissue::SurfaceTwistCapacity(*surface_twist_, tri[k],
                                                         scene_.region.reduced.max_twist);
        }
        if (reduced_twist_ || (coil_ && scene_.region.coil_mode == tissue::TwistMode::kLimb)) {
          const geometry::CentrelineProjection on_axis =
              geometry::ProjectPointOntoPolyline(centreline_points_, ps.scp);
          axis_point_ = on_axis.point;
          axis_ = on_axis.tangent;
          lever_ = std::max(scene_.haptics.min_lever, (ps.scp - axis_point_).norm());
        } else {
          axis_ = ps.normal;
          axis_point_ = ps.scp;
          lever_ = scene_.haptics.min_lever;
        }
      }
      force = ps.force;
      jacobian = ps.jacobian;
      if (reduced_contact_) {
        // The station's local model: the proxy's spring in series with the tissue behind it,
        // k/(1 + k·nᵀGn) (the table is read-only: safe beside the deformation thread).
        const double k = proxy_.params().stiffness;
        if (k > 0) {
          jacobian *=
              reduced_contact_->SeriesStiffness(
                  {tri[0], tri[1], tri[2]},
                  {ps.barycentric[0], ps.barycentric[1], ps.barycentric[2]}, rest_normal_, k) /
              k;
        }
      }
      input_.triangle = ps.triangle;
      input_.barycentric = ps.barycentric;
      input_.force_on_tissue = -ps.force;
      input_.hip = s.position;
      if (task == scoring::TaskKind::kPress)
        quantity = std::max(0.0, (rest_contact_ - s.position).dot(rest_normal_));
    } else {
      input_.triangle = -1;
      input_.force_on_tissue.setZero();
    }
    last_contact_ = ps.contact;
    cmd.contact = ps.contact;
    cmd.proxy = ps.scp;
  }
  PublishInput();

  const Vec3 out = safety_.Filter(force, dt, events);
  cmd.force = out;
  cmd.local.position0 = s.position;
  cmd.local.jacobian = jacobian;
  safety_.LimitLocalModel(cmd.local, out, events);
  if (overload) events |= haptics::kEventOverload;
  if (snap.outside_model && cmd.contact) events |= haptics::kEventOutsideModel;
  cmd.events = events;
  recorder_.Add(trial_time_, s.position, quantity, out.norm(), overload);
  ++samples_;
  // Telemetry for instructors (30 Hz): every 8th sample is plenty at ≥ 1 kHz and keeps the
  // metrics summary off most haptic cycles. Never allocates (TrialMetrics is plain data).
  if ((samples_ & 7) == 1 || cmd.grasping != telemetry_grasping_) {
    telemetry_grasping_ = cmd.grasping;
    Telemetry& t = telemetry_.Back();
    t.time = s.time;
    t.force = out;
    t.tip = s.position;
    t.twist = cmd.twist;
    t.torque = cmd.torque;
    t.depth = task == scoring::TaskKind::kPress ? quantity : 0;
    t.contact = cmd.contact;
    t.grasping = cmd.grasping;
    t.samples = samples_;
    t.clock_jumps = clock_jumps_;
    t.metrics = recorder_.Finish();
    live_score_ = t.metrics.score;
    telemetry_.Publish();
  }
  cmd.score = live_score_;
  return cmd;
}

bool Simulation::TakeTelemetry(Telemetry& out) {
  const bool fresh = telemetry_.Acquire();
  out = telemetry_.Front();
  return fresh;
}

void Simulation::PublishInput() {
  const DeformInput& a = input_;
  const DeformInput& b = published_;
  const bool same = a.grasp_id == b.grasp_id && a.grasping == b.grasping && a.torque == b.torque &&
                    a.triangle == b.triangle && a.contact_id == b.contact_id &&
                    a.barycentric == b.barycentric && a.force_on_tissue == b.force_on_tissue &&
                    a.hip == b.hip && a.grasp_point == b.grasp_point;
  if (same && input_version_.load(std::memory_order_relaxed) > 0) return;  // nothing new to ask for
  published_ = input_;
  inputs_.Back() = input_;
  inputs_.Publish();
  input_version_.fetch_add(1, std::memory_order_release);
  input_version_.notify_one();
}

void Simulation::Publish(const std::vector<Vec3>& positions, bool overload, bool outside_model) {
  const size_t n = rest_.positions.size();
  Snapshot& back = surface_.Back();
  std::copy(positions.begin(), positions.begin() + n, back.positions.begin());
  back.bvh.Refit(back.positions);
  back.id = ++publish_id_;
  back.overload = overload;
  back.outside_model = outside_model;
  surface_.Publish();
  VisualPositions& v = visual_.Back();
  std::copy(positions.begin(), positions.begin() + n, v.positions.begin());
  v.id = publish_id_;
  visual_.Publish();
  updates_.fetch_add(1, std::memory_order_relaxed);
}

void Simulation::Deform(const DeformInput& in) {
  const RegionSpec& region = scene_.region;
  switch (region.kind) {
    case ModelKind::kCoil: {
      if (in.grasping && in.grasp_id != seen_grasp_) {
        // A new grasp: bind a deformer around it (set-up work, on this thread).
        seen_grasp_ = in.grasp_id;
        Expected<tissue::CoilDeformer> d = InvalidArgument("grasp", "no grasp");
        if (region.coil_mode == tissue::TwistMode::kLimb) {
          const double arc =
              geometry::ProjectPointOntoPolyline(centreline_points_, in.grasp_point).s;
          d = tissue::CoilDeformer::CreateForLimb(*coil_, rest_.positions, centreline_points_, arc);
        } else {
          auto sp = geometry::ClosestSurfacePoint(rest_, in.grasp_point);
          if (sp.ok())
            d = tissue::CoilDeformer::CreateForSurface(*coil_, rest_, *sp,
                                                       geometry::GeodesicMethod::kHeat);
        }
        if (d.ok()) {
          if (deformer_) deformer_->Update(0.0);
          deformer_ = std::make_unique<tissue::CoilDeformer>(std::move(*d));
          applied_torque_ = NAN;
        }
      }
      if (!deformer_) return;
      const double torque = in.grasping ? in.torque : 0.0;
      if (torque == applied_torque_ && in.grasping == applied_grasp_) return;  // nothing new
      const tissue::DeformStats stats = deformer_->Update(torque);
      applied_torque_ = torque;
      applied_grasp_ = in.grasping;
      Publish(deformer_->positions(), stats.overload);
      return;
    }
    case ModelKind::kMassSpring: {
      msm_->ClearAnchors();
      if (in.triangle >= 0) {
        const auto& x = msm_->positions();
        const geometry::Triangle& tri = rest_.triangles[in.triangle];
        const Vec3 scp = in.barycentric[0] * x[tri[0]] + in.barycentric[1] * x[tri[1]] +
                         in.barycentric[2] * x[tri[2]];
        const Vec3 offset = in.hip - scp;
        const haptics::ProxyParams& pp = proxy_.params();
        for (int k = 0; k < 3; ++k) {
          msm_->SetAnchor(tri[k], x[tri[k]] + offset, in.barycentric[k] * pp.stiffness,
                          in.barycentric[k] * pp.damping);
        }
      }
      if (!msm_->Step(region.dt)) msm_->Reset();  // a divergence is reset to rest, never NaN
      Publish(msm_->positions(), false);
      return;
    }
    case ModelKind::kRingLayer: {
      if (in.triangle >= 0 && in.contact_id != seen_contact_) {
        seen_contact_ = in.contact_id;
        const Vec3 p = RestPoint(rest_, in.triangle, in.barycentric);
        std::vector<double> rho(rest_.VertexCount());
        for (int v = 0; v < rest_.VertexCount(); ++v) rho[v] = (rest_.positions[v] - p).norm();
        auto ring = tissue::RingLayerModel::Create(rest_.positions, rho, masses_,
                                                   -geometry::TriangleNormal(rest_, in.triangle),
                                                   region.ring);
        if (ring.ok()) ring_ = std::make_unique<tissue::RingLayerModel>(std::move(*ring));
      }
      if (!ring_) return;
      ring_->SetContactForce(
          in.triangle >= 0 ? in.force_on_tissue.dot(-geometry::TriangleNormal(rest_, in.triangle))
                           : 0.0);
      ring_->Step(region.dt);
      ring_->Apply();
      Publish(ring_->positions(), false);
      return;
    }
    case ModelKind::kReduced: {
      if (surface_twist_) {
        // A new grasp builds its twist model (allocates: once per grasp, on this thread); then
        // each new torque turns the organ about the normal at the jaws. Released: at rest.
        if (!in.grasping) {
          if (surface_grasp_) {
            surface_grasp_.reset();
            Publish(rest_.positions, false);
          }
          return;
        }
        if (!surface_grasp_ || in.grasp_id != surface_grasp_id_) {
          const tissue::TwistField field = tissue::SurfaceTwistField(
              *surface_twist_, in.grasp_vertex, rest_.positions, &surface_grasp_fallback_);
          auto model =
              tissue::ReducedTwistModel::Create(field, rest_.positions, region.reduced.max_twist);
          if (!model.ok()) return;
          surface_grasp_ = std::make_unique<tissue::ReducedTwistModel>(std::move(*model));
          surface_grasp_id_ = in.grasp_id;
          applied_torque_ = std::numeric_limits<double>::quiet_NaN();
        }
        if (in.torque == applied_torque_) return;  // nothing new
        const tissue::ReducedStats st = surface_grasp_->Update(in.torque);
        applied_torque_ = in.torque;
        Publish(surface_grasp_->positions(), st.saturated, surface_grasp_fallback_);
        return;
      }
      if (reduced_twist_) {
        // The twist field turns the limb for the torque at the grasp (applied on the distal
        // face, where the field was computed: a grasp elsewhere twists as if at the wrist).
        const double torque = in.grasping ? in.torque : 0.0;
        if (torque == applied_torque_ && in.grasping == applied_grasp_) return;  // nothing new
        const tissue::ReducedStats st = reduced_twist_->Update(torque);
        applied_torque_ = torque;
        applied_grasp_ = in.grasping;
        Publish(reduced_twist_->positions(), st.saturated);
        return;
      }
      // Quasi-static: the surface is the table's answer to the tool pressing at the contact
      // point, the proxy's spring and the tissue solved together (PressWithSpring: stable
      // whatever the spring's stiffness), the force spread over the contact triangle by the
      // contact point's barycentric coordinates.
      if (in.triangle == seen_triangle_ && in.hip == applied_hip_ &&
          in.barycentric == applied_barycentric_)
        return;  // nothing new
      seen_triangle_ = in.triangle;
      applied_hip_ = in.hip;
      applied_barycentric_ = in.barycentric;
      bool overload = false, outside_model = false;
      if (in.triangle >= 0) {
        const geometry::Triangle& tri = rest_.triangles[in.triangle];
        const Vec3 p0 = RestPoint(rest_, in.triangle, in.barycentric);
        const tissue::ReducedStats st = reduced_contact_->PressWithSpring(
            {tri[0], tri[1], tri[2]}, {in.barycentric[0], in.barycentric[1], in.barycentric[2]},
            in.hip, p0, geometry::TriangleNormal(rest_, in.triangle), proxy_.params().stiffness);
        if (!st.ok) reduced_contact_->Release();
        overload = st.saturated;
        outside_model = st.fallback;
      } else {
        reduced_contact_->Release();
      }
      Publish(reduced_contact_->positions(), overload, outside_model);
      return;
    }
  }
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

std::string Simulation::CacheDirectory() const {
  return options_.cache_dir.empty() ? tissue::DefaultCacheDirectory() : options_.cache_dir;
}

bool Simulation::Paced() const {
  return scene_.region.kind == ModelKind::kMassSpring ||
         scene_.region.kind == ModelKind::kRingLayer;
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
  uint64_t seen = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    if (!paced) {
      // Coil and reduced (quasi-static): an update only follows a new request; sleep until there
      // is one.
      input_version_.wait(seen, std::memory_order_acquire);
      seen = input_version_.load(std::memory_order_acquire);
      if (stop_.load(std::memory_order_relaxed)) break;
    }
    inputs_.Acquire();
    Deform(inputs_.Front());
    if (paced) {
      next += period;
      const auto now = Clock::now();
      if (now - next > std::chrono::milliseconds(50)) next = now;  // fell behind: do not burst
      std::this_thread::sleep_until(next);
    }
  }
}

bool Simulation::TakeVisualFrame(VisualFrame& out) {
  if (!visual_.Acquire()) return false;
  const VisualPositions& v = visual_.Front();
  out.frame_id = v.id;
  out.indices.clear();
  out.positions.clear();
  constexpr double kMoved2 = 1e-12;  // (1 µm)²: below that a vertex did not move
  for (size_t i = 0; i < v.positions.size(); ++i) {
    if ((v.positions[i] - last_sent_[i]).squaredNorm() > kMoved2) {
      out.indices.push_back(static_cast<int32_t>(i));
      out.positions.push_back(v.positions[i]);
      last_sent_[i] = v.positions[i];
    }
  }
  if (!out.indices.empty()) {
    std::lock_guard lock(shown_mutex_);
    shown_.positions = last_sent_;
    shown_.id = v.id;
  }
  return true;
}

uint64_t Simulation::ShownSurface(std::vector<int32_t>& indices,
                                  std::vector<geometry::Vec3>& positions) const {
  indices.clear();
  positions.clear();
  std::lock_guard lock(shown_mutex_);
  if (shown_.positions.size() != rest_.positions.size()) return shown_.id;
  constexpr double kMoved2 = 1e-12;  // (1 µm)², as for visual frames
  for (size_t i = 0; i < shown_.positions.size(); ++i)
    if ((shown_.positions[i] - rest_.positions[i]).squaredNorm() > kMoved2) {
      indices.push_back(static_cast<int32_t>(i));
      positions.push_back(shown_.positions[i]);
    }
  return shown_.id;
}

}  // namespace vsurg::sim
