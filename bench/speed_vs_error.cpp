// vsurg-bench speed-vs-error: every model on the same scenes against the same reference
// (DESIGN.md "Speed against error"). See speed_vs_error.h for the command's contract.
//
// Scenes and references
//   arm-ramp     forearm, fixed at the elbow, a torque ramped at the wrist to seed 000's 2.07 N·m.
//                Reference: tapered Saint-Venant torsion with the effective shear modulus that
//                gives the arm scene's twist at 2.07 N·m (60°), i.e. the stiffness the scene uses.
//   arm-haptic   the same forearm with the tissue's own G = 12 kPa and a haptic-scale 0.02 N·m.
//   calf-ramp    the calf to 2.07 N·m, effective modulus as the calf scene (30°).
//   sphere-palpation  a 5 cm ball fixed on its lower cap, pressed on top by 0.2 N spread over a
//                1 cm cap. Reference: the finest FEM (no closed form exists).
// Markers: ten, like seed 000 Fig. 8. Limbs: on the top of the limb at z = (k − ½)/10 · L from
// the fixed end (marker 10 is next to the grasp); sphere: along a meridian from the pole,
// polar angle 5°·(k − 1). Each model reads each marker at its own nearest surface vertex, and
// the reference is evaluated at that same rest point. Error: |d_model − d_ref| (vectors),
// relative to the reference's largest marker displacement; RMS over the ten and max.
// Time per update: the median over repeats of what a deformation update costs the model in use:
// coil — one deformation for a new torque; FEM — one implicit step (h = 1 ms); mass-spring —
// advancing 1 ms (substeps where the integrator needs them to stay stable); ring layer — one
// step. Dynamic models are judged after a ramp (1 s) and a hold (2 s) at 1 kHz, so lag and
// ringing count against them; a diverged run is reported as such.
#include "bench/speed_vs_error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <tuple>

#include "bench/png_plot.h"
#include "common/cli/args.h"
#include "common/core/csv.h"
#include "common/geometry/distances.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/tet_generators.h"
#include "common/sim/limb_scene.h"
#include "common/sim/scene.h"
#include "common/tissue/coil_calibration.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/fem.h"
#include "common/tissue/mass_spring.h"
#include "common/tissue/ring_layer.h"
#include "common/tissue/torsion_reference.h"

namespace vsurg::bench {
namespace {

using geometry::Vec3;
using Clock = std::chrono::steady_clock;
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Row {
  std::string model = "", scene = "", setting = "";
  double time_us = 0, rms = kInf, max = kInf;
  int size = 0;  // particles / vertices / coils
  std::string note = "";
};

struct Trajectory {
  std::string label = "";
  std::vector<double> t = {}, d = {};  // s, m (marker 8's displacement)
};

struct SceneOut {
  std::string scene;
  std::string scene_file;    // the scenes/ file whose budget applies
  std::string scene_family;  // the model family that file uses
  double budget = 0;
  std::vector<Row> rows;
  std::vector<Trajectory> trajectories;
  std::string chosen;
};

struct Config {
  bool quick = false;
  int repeats = 9;
};

// --- progress bar (stderr) ---
class Progress {
 public:
  explicit Progress(int total) : total_(total) {}
  void Step(const std::string& what) {
    ++done_;
    const int width = 30, filled = width * done_ / std::max(1, total_);
    std::fprintf(stderr, "\r[%s%s] %3d%%  %-48.48s", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), 100 * done_ / std::max(1, total_),
                 what.c_str());
    if (done_ >= total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  int total_, done_ = 0;
};

double MedianUs(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

template <class F>
double TimeUs(int repeats, F&& f) {
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = Clock::now();
    f(i);
    t.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  }
  return MedianUs(t);
}

int Nearest(const std::vector<Vec3>& points, const Vec3& p) {
  int best = 0;
  double d = kInf;
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    const double e = (points[i] - p).squaredNorm();
    if (e < d) d = e, best = i;
  }
  return best;
}

// Relative marker errors: reference displacement function at a rest point.
using Reference = std::function<Vec3(const Vec3& rest)>;

void Score(Row& row, const std::vector<Vec3>& rest, const std::vector<Vec3>& now,
           const std::vector<int>& marker_vertices, const Reference& ref) {
  double scale = 0;
  std::vector<double> e;
  for (int v : marker_vertices) scale = std::max(scale, ref(rest[v]).norm());
  for (int v : marker_vertices) {
    const Vec3 d = now[v] - rest[v];
    if (!d.allFinite()) {
      row.rms = row.max = kInf;
      row.note = "diverged";
      return;
    }
    e.push_back((d - ref(rest[v])).norm() / std::max(scale, 1e-12));
  }
  double s2 = 0, mx = 0;
  for (double x : e) s2 += x * x, mx = std::max(mx, x);
  row.rms = std::sqrt(s2 / static_cast<double>(e.size()));
  row.max = mx;
}

// ======================= limb scenes =======================

struct LimbCase {
  std::string scene;
  std::string scene_file;
  sim::LimbScene limb;
  tissue::TaperedShaft shaft;  // the reference
  double torque = 0;           // N·m at the end of the ramp
};

Vec3 SaintVenantDisplacement(const tissue::TaperedShaft& shaft, double torque, const Vec3& x) {
  const double theta =
      tissue::SaintVenantTwistAt(shaft, torque, std::clamp(x.z(), 0.0, shaft.length));
  const Eigen::AngleAxisd r(theta, Vec3::UnitZ());
  return r * x - x;
}

std::vector<Vec3> LimbMarkers(const tissue::TaperedShaft& s) {
  std::vector<Vec3> m;
  for (int k = 1; k <= 10; ++k) {
    const double z = (k - 0.5) / 10.0 * s.length;
    const double a = s.radius_proximal + (s.radius_distal - s.radius_proximal) * z / s.length;
    m.emplace_back(0.0, a, z);
  }
  return m;
}

// Nearest vertex on the outer surface (radius within 2% of the limb's at that z).
std::vector<int> MarkerVertices(const std::vector<Vec3>& rest, const tissue::TaperedShaft& s) {
  std::vector<Vec3> outer;
  std::vector<int> index;
  for (int i = 0; i < static_cast<int>(rest.size()); ++i) {
    const double z = std::clamp(rest[i].z(), 0.0, s.length);
    const double a = s.radius_proximal + (s.radius_distal - s.radius_proximal) * z / s.length;
    if (rest[i].head<2>().norm() > 0.98 * a) outer.push_back(rest[i]), index.push_back(i);
  }
  std::vector<int> out;
  for (const Vec3& m : LimbMarkers(s)) out.push_back(index[Nearest(outer, m)]);
  return out;
}

double Ramp(double t, double ramp_s) {
  return std::clamp(t / ramp_s, 0.0, 1.0);
}

// Substeps per 1 ms update that keep an explicit scheme inside its stability limit on the
// stiffest mode ω (rad/s): undamped ω·h < limit; spring damping c = β·k gives that mode a damping
// ratio ζ = β·ω/2, which shrinks the limit to limit·(√(1 + ζ²) − ζ). 1.2× margin; capped at 100
// (a scheme that needs more is run at 100 and reported as it fares).
int Substeps(double omega, double limit, double beta) {
  if (!std::isfinite(limit)) return 1;
  const double zeta = 0.5 * beta * omega;
  const double h = limit / std::max(omega, 1e-9) * (std::sqrt(1 + zeta * zeta) - zeta) / 1.2;
  return std::clamp(static_cast<int>(std::ceil(1e-3 / h)), 1, 100);
}

void CoilRows(const LimbCase& c, const Config& cfg, SceneOut& out, Progress& progress) {
  auto limb = geometry::MakeLimb(c.limb.limb);
  if (!limb.ok()) return;
  const auto reference =
      tissue::SaintVenantCalibrationReference(c.shaft, c.torque, cfg.quick ? 4 : 8, 26);
  struct Variant {
    std::string name, setting;
    Expected<tissue::CoilSpringParams> params;
  };
  std::vector<Variant> variants;
  {
    auto fit = tissue::CalibrateTwoParameter(c.limb.coil, reference);
    variants.push_back({"coil-paper", "two-parameter fit",
                        fit.ok() ? Expected<tissue::CoilSpringParams>(fit->params)
                                 : Expected<tissue::CoilSpringParams>(fit.error())});
    auto ring = tissue::CalibratePerRing(c.limb.coil, reference);
    variants.push_back({"coil-per-ring", "per-ring fit",
                        ring.ok() ? Expected<tissue::CoilSpringParams>(ring->params)
                                  : Expected<tissue::CoilSpringParams>(ring.error())});
    variants.push_back({"coil-scene", "scene parameters", c.limb.coil});
  }
  const double grasp = geometry::ArcLengths(limb->centreline).back();
  const std::vector<int> markers = MarkerVertices(limb->surface.positions, c.shaft);
  const Reference ref = [&](const Vec3& x) {
    return SaintVenantDisplacement(c.shaft, c.torque, x);
  };
  for (auto& v : variants) {
    Row row{v.name, c.scene, v.setting};
    if (!v.params.ok()) {
      row.note = "fit failed: " + v.params.error().message;
      out.rows.push_back(row);
      progress.Step(c.scene + " " + v.name);
      continue;
    }
    auto model = tissue::CoilSpringModel::Create(*v.params);
    auto deformer = model.ok() ? tissue::CoilDeformer::CreateForLimb(
                                     *model, limb->surface.positions, limb->centreline, grasp)
                               : Expected<tissue::CoilDeformer>(model.error());
    if (!deformer.ok()) {
      row.note = deformer.error().message;
      out.rows.push_back(row);
      progress.Step(c.scene + " " + v.name);
      continue;
    }
    row.size = v.params->coils;
    row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
      deformer->Update(c.torque * (0.5 + 0.5 * ((i % 2) ? 1.0 : 0.97)));
    });
    deformer->Update(c.torque);
    Score(row, limb->surface.positions, deformer->positions(), markers, ref);
    out.rows.push_back(row);
    // Marker 8 over the ramp (quasi-static: the coil answers each torque at once).
    Trajectory tr{v.name, {}, {}};
    for (double t = 0; t <= 3.0 + 1e-9; t += 0.02) {
      deformer->Update(c.torque * Ramp(t, 1.0));
      tr.t.push_back(t);
      tr.d.push_back(
          (deformer->positions()[markers[7]] - limb->surface.positions[markers[7]]).norm());
    }
    if (v.name != "coil-scene") out.trajectories.push_back(std::move(tr));
    progress.Step(c.scene + " " + v.name);
  }
  // The reference's own marker-8 curve.
  Trajectory sv{"Saint-Venant", {}, {}};
  const Vec3 m8 = LimbMarkers(c.shaft)[7];
  for (double t = 0; t <= 3.0 + 1e-9; t += 0.02) {
    sv.t.push_back(t);
    sv.d.push_back(SaintVenantDisplacement(c.shaft, c.torque * Ramp(t, 1.0), m8).norm());
  }
  out.trajectories.insert(out.trajectories.begin(), std::move(sv));
}

struct TetLimb {
  geometry::TetCylinder cylinder;
  int level = 0;
};

TetLimb MakeTetLimb(const tissue::TaperedShaft& s, int rings) {
  const double a = 0.5 * (s.radius_proximal + s.radius_distal);
  // Linear tetrahedra need thin slices in torsion: about 3 layers per radius of length.
  const int layers = rings * static_cast<int>(std::ceil(3.0 * s.length / a));
  auto c = geometry::MakeTetCylinder({s.length, s.radius_proximal, s.radius_distal, rings, layers});
  return {*c, rings};
}

tissue::FemParams FemFor(const tissue::TaperedShaft& s, double poisson) {
  tissue::FemParams p;
  p.poisson = poisson;
  p.young = 2 * s.shear_modulus * (1 + poisson);
  return p;
}

// The end torque as a follower load: the nodal forces are recomputed from the current tip face
// (its centre vertex is tip[0]), so they stay tangential as the face turns. Dead loads would lose
// torque as cos θ and push the face outward at large twists.
std::vector<Vec3> FollowerTorque(const std::vector<Vec3>& x, const TetLimb& m, double t) {
  return tissue::TorqueNodalForces(x, m.cylinder.tip, m.cylinder.tip_area, x[m.cylinder.tip[0]],
                                   Vec3::UnitZ(), t);
}

void ApplyTorque(tissue::FemModel& fem, const TetLimb& m, double t) {
  const auto f = FollowerTorque(fem.positions(), m, t);
  for (size_t i = 0; i < f.size(); ++i) fem.SetExternalForce(m.cylinder.tip[i], f[i]);
}

void FemRows(const LimbCase& c, const Config& cfg, SceneOut& out, Progress& progress) {
  // Full: up to level 7 (≈ 136k tets) where Saint-Venant is exact (small torque); the ramps stop
  // at level 5: their static solves take several follower-load increments.
  std::vector<int> levels = {2, 3, 4, c.torque > 0.5 ? 5 : 7};
  if (cfg.quick) levels = {1, 2};
  const Reference ref = [&](const Vec3& x) {
    return SaintVenantDisplacement(c.shaft, c.torque, x);
  };
  const double poisson = c.limb.poisson_ratio;
  for (int level : levels) {
    const TetLimb m = MakeTetLimb(c.shaft, level);
    auto fem = tissue::FemModel::Create(m.cylinder.mesh, FemFor(c.shaft, poisson), m.cylinder.base);
    Row row{"fem", c.scene,
            "level " + std::to_string(level) + " (" + std::to_string(m.cylinder.mesh.TetCount()) +
                " tets)"};
    if (!fem.ok()) {
      row.note = fem.error().message;
      out.rows.push_back(row);
      progress.Step(c.scene + " fem");
      continue;
    }
    row.size = fem->VertexCount();
    // Static equilibrium at the final torque, in increments with the follower load updated
    // between them (large twists); the last increment repeated until the load stops moving.
    bool converged = true;
    const int increments = c.torque > 0.5 ? 3 : 1;
    for (int k = 1; k <= increments + (c.torque > 0.5 ? 1 : 0); ++k) {
      ApplyTorque(*fem, m, c.torque * std::min(k, increments) / increments);
      converged = fem->SolveStatic(40, 1e-6).converged;
    }
    const auto markers = MarkerVertices(m.cylinder.mesh.positions, c.shaft);
    Score(row, m.cylinder.mesh.positions, fem->positions(), markers, ref);
    if (!converged) row.note = "static solve not converged";
    // Time per update: implicit steps from the loaded equilibrium.
    row.time_us = TimeUs(cfg.quick ? 3 : 7, [&](int) { fem->StepImplicit(1e-3); });
    out.rows.push_back(row);
    progress.Step(c.scene + " fem level " + std::to_string(level));
  }
  // Marker 8 of a dynamic FEM (level 2) through the ramp at 1 kHz.
  const TetLimb m = MakeTetLimb(c.shaft, cfg.quick ? 1 : 2);
  auto fem = tissue::FemModel::Create(m.cylinder.mesh, FemFor(c.shaft, poisson), m.cylinder.base);
  if (!fem.ok()) return;
  const auto markers = MarkerVertices(m.cylinder.mesh.positions, c.shaft);
  Trajectory tr{"fem level " + std::to_string(m.level) + " (implicit, 1 ms)", {}, {}};
  const int steps = cfg.quick ? 600 : 3000;
  for (int k = 0; k <= steps; ++k) {
    const double t = k * 1e-3;
    ApplyTorque(*fem, m, c.torque * Ramp(t, 1.0));
    if (k % 20 == 0) {
      tr.t.push_back(t);
      tr.d.push_back((fem->positions()[markers[7]] - m.cylinder.mesh.positions[markers[7]]).norm());
    }
    fem->StepImplicit(1e-3);
  }
  out.trajectories.push_back(std::move(tr));
  progress.Step(c.scene + " fem dynamic");
}

// Mass-spring on the FEM's tetrahedra (one spring per edge), its single stiffness fitted so the
// grasp's twist matches the reference at the final torque (the one free parameter the model has).
void MassSpringLimbRows(const LimbCase& c, const Config& cfg, SceneOut& out, Progress& progress) {
  const TetLimb m = MakeTetLimb(c.shaft, cfg.quick ? 1 : 2);
  const Reference ref = [&](const Vec3& x) {
    return SaintVenantDisplacement(c.shaft, c.torque, x);
  };
  const auto markers = MarkerVertices(m.cylinder.mesh.positions, c.shaft);
  auto apply = [&](tissue::MassSpringModel& model, double torque) {
    const auto f = FollowerTorque(model.positions(), m, torque);
    for (size_t i = 0; i < f.size(); ++i) model.SetExternalForce(m.cylinder.tip[i], f[i]);
  };
  auto build = [&](double k, double c_damp) -> Expected<tissue::MassSpringModel> {
    auto sys = tissue::BuildMassSpring(m.cylinder.mesh, c.limb.density, k, c_damp);
    if (!sys.ok()) return sys.error();
    tissue::MassSpringStepParams sp;
    sp.integrator = tissue::Integrator::kImplicitEuler;
    sp.cg_max_iterations = 200;
    sp.cg_tolerance = 1e-6;
    auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
    if (!model.ok()) return model.error();
    for (int v : m.cylinder.base) model->SetFixed(v, true);
    return model;
  };
  auto settle = [&](tissue::MassSpringModel& model, double torque) {
    model.SetIntegrator(tissue::Integrator::kImplicitEuler);
    for (int k = 0; k < 400; ++k) {
      if (k % 10 == 0) apply(model, torque * std::min(1.0, (k + 10) / 200.0));
      model.Step(0.05);
    }
  };
  // Fit k: twist at marker 10 scales as 1/k for small twists; two corrections.
  const int tip_marker = markers[9];
  const Vec3 tip_rest = m.cylinder.mesh.positions[tip_marker];
  const double target = ref(tip_rest).norm();
  // Start from the spring of an elastic cube of the mean edge length l: k ≈ E·l.
  double edge = 0;
  int edges = 0;
  for (const auto& t : m.cylinder.mesh.tetrahedra)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        edge += (m.cylinder.mesh.positions[t[a]] - m.cylinder.mesh.positions[t[b]]).norm(), ++edges;
  edge /= std::max(1, edges);
  double k = 2 * c.shaft.shear_modulus * (1 + c.limb.poisson_ratio) * edge;
  for (int it = 0; it < 3; ++it) {
    auto model = build(k, 0.0);
    if (!model.ok()) break;
    settle(*model, c.torque);
    const double got = (model->positions()[tip_marker] - tip_rest).norm();
    if (!(got > 0) || !std::isfinite(got)) break;
    k *= got / target;
  }
  // Damping per spring c = 0.002·k: about ζ = 0.02 on the first torsion mode (ω ≈ 20 rad/s);
  // more would overdamp the highest modes and shrink the explicit schemes' stable step further.
  const double c_damp = 0.002 * k;
  for (tissue::Integrator integ : tissue::kAllIntegrators) {
    Row row{"mass-spring", c.scene,
            std::string(tissue::IntegratorName(integ)) + " (k fitted " +
                std::to_string(k).substr(0, 6) + " N/m)"};
    auto model = build(k, c_damp);
    if (!model.ok()) {
      row.note = model.error().message;
      out.rows.push_back(row);
      progress.Step(c.scene + " msm");
      continue;
    }
    row.size = static_cast<int>(model->positions().size());
    model->SetIntegrator(integ);
    // Substeps to stay inside each explicit scheme's stability limit (ω·dt < 2 symplectic,
    // 2√2 RK4; explicit Euler and midpoint grow at any step, damping holds them at ω·dt ≲ 1).
    const double omega = model->MaxAngularFrequency(100);
    double limit = 1.0;
    switch (integ) {
      case tissue::Integrator::kSymplecticEuler:
      case tissue::Integrator::kVerlet:
        limit = 1.8;
        break;
      case tissue::Integrator::kRk4:
        limit = 2.5;
        break;
      case tissue::Integrator::kImplicitEuler:
        limit = kInf;
        break;
      default:
        limit = 0.5;
        break;
    }
    const int substeps = Substeps(omega, limit, c_damp / k);
    Trajectory tr{"mass-spring " + std::string(tissue::IntegratorName(integ)), {}, {}};
    const int steps = cfg.quick ? 600 : 3000;
    std::vector<double> times;
    bool ok = true;
    for (int s = 0; s <= steps && ok; ++s) {
      const double t = s * 1e-3;
      apply(*model, c.torque * Ramp(t, 1.0));
      if (s % 20 == 0) {
        tr.t.push_back(t);
        tr.d.push_back(
            (model->positions()[markers[7]] - m.cylinder.mesh.positions[markers[7]]).norm());
      }
      const auto t0 = Clock::now();
      ok = model->Step(1e-3, substeps);
      times.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    }
    row.time_us = MedianUs(times);
    row.setting += ", " + std::to_string(substeps) + " substep" + (substeps > 1 ? "s" : "") + "/ms";
    if (!ok || model->diverged()) {
      row.note = "diverged";
    } else {
      Score(row, m.cylinder.mesh.positions, model->positions(), markers, ref);
    }
    out.rows.push_back(row);
    if (integ == tissue::Integrator::kMidpoint || integ == tissue::Integrator::kImplicitEuler)
      out.trajectories.push_back(std::move(tr));
    progress.Step(c.scene + " msm " + tissue::IntegratorName(integ));
  }
}

// The budget and the model family a scene file declares.
std::pair<double, std::string> SceneBudget(const std::string& file) {
  auto scene = sim::LoadSceneByName(file);
  if (!scene.ok()) return {0.1, "?"};
  return {scene->error_budget_rms, sim::ModelKindName(scene->region.kind)};
}

LimbCase MakeLimbCase(const std::string& scene, const std::string& builtin,
                      const std::string& scene_file, double torque, bool effective) {
  LimbCase c;
  c.scene = scene;
  c.scene_file = scene_file;
  c.limb = *sim::BuiltinLimbScene(builtin);
  c.shaft = c.limb.reference;
  c.torque = torque;

  if (effective) {
    // The shear modulus that makes Saint-Venant twist the grasp as far as the scene's coil
    // model does at this torque: the stiffness the scene was tuned to.
    auto model = tissue::CoilSpringModel::Create(c.limb.coil);
    const double coil_twist = model->Forward(torque).total_twist;
    const double sv_twist = tissue::SaintVenantTwistAt(c.shaft, torque, c.shaft.length);
    c.shaft.shear_modulus *= sv_twist / coil_twist;
  }
  return c;
}

SceneOut RunLimb(const LimbCase& c, const Config& cfg, Progress& progress) {
  SceneOut out;
  out.scene = c.scene;
  out.scene_file = c.scene_file;
  std::tie(out.budget, out.scene_family) = SceneBudget(c.scene_file);
  CoilRows(c, cfg, out, progress);
  FemRows(c, cfg, out, progress);
  MassSpringLimbRows(c, cfg, out, progress);
  return out;
}

// ======================= sphere palpation =======================

constexpr double kBallRadius = 0.05, kPressForce = 0.2, kCapRadius = 0.01;

std::vector<Vec3> SphereMarkers() {
  std::vector<Vec3> m;
  for (int k = 0; k < 10; ++k) {
    const double a = (5.0 * k) * std::numbers::pi / 180.0;
    m.emplace_back(kBallRadius * std::sin(a), 0.0, kBallRadius * std::cos(a));
  }
  return m;
}

std::vector<int> SphereMarkerVertices(const std::vector<Vec3>& rest) {
  std::vector<Vec3> outer;
  std::vector<int> index;
  for (int i = 0; i < static_cast<int>(rest.size()); ++i)
    if (rest[i].norm() > 0.98 * kBallRadius) outer.push_back(rest[i]), index.push_back(i);
  std::vector<int> out;
  for (const Vec3& m : SphereMarkers()) out.push_back(index[Nearest(outer, m)]);
  return out;
}

// The press: a uniform pressure F/(π a²) straight down on the top cap |xy| ≤ a, turned into
// nodal forces by sampling every surface triangle (28 barycentric points) and lumping each
// sample's share of the triangle's area onto its vertices by its barycentric weights, so every
// mesh carries the same load however fine it is (a point load would not converge).
std::vector<std::pair<int, Vec3>> CapLoad(const geometry::TriMesh& surface, double force) {
  const double pressure = force / (std::numbers::pi * kCapRadius * kCapRadius);
  std::map<int, Vec3> nodal;
  // (Eigen vectors are not zeroed by default construction: never `nodal[i] +=`.)
  auto add = [&](int i, double fz) { nodal.try_emplace(i, Vec3::Zero()).first->second.z() += fz; };
  constexpr int kN = 6;  // (kN+1)(kN+2)/2 = 28 samples
  for (const auto& t : surface.triangles) {
    const Vec3& a = surface.positions[t[0]];
    const Vec3& b = surface.positions[t[1]];
    const Vec3& c = surface.positions[t[2]];
    if (std::max({a.z(), b.z(), c.z()}) <= 0) continue;
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double w = area / ((kN + 1) * (kN + 2) / 2);
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const double u = static_cast<double>(i) / kN, v = static_cast<double>(j) / kN;
        const Vec3 p = (1 - u - v) * a + u * b + v * c;
        if (p.z() <= 0 || p.head<2>().norm() > kCapRadius) continue;
        add(t[0], -pressure * w * (1 - u - v));
        add(t[1], -pressure * w * u);
        add(t[2], -pressure * w * v);
      }
  }
  // The samples' area only approximates the cap's: scale to the exact total force.
  double total = 0;
  for (const auto& [i, f] : nodal) total -= f.z();
  std::vector<std::pair<int, Vec3>> out;
  for (const auto& [i, f] : nodal) out.emplace_back(i, total > 0 ? Vec3(f * force / total) : f);
  return out;
}

std::vector<int> BottomCap(const std::vector<Vec3>& rest) {
  std::vector<int> fixed;
  for (int i = 0; i < static_cast<int>(rest.size()); ++i)
    if (rest[i].z() < -0.7 * kBallRadius) fixed.push_back(i);
  return fixed;
}

tissue::FemParams BallTissue() {
  tissue::FemParams p;
  p.poisson = 0.45;
  p.young = 2 * 12000 * 1.45;
  return p;
}

SceneOut RunSphere(const Config& cfg, Progress& progress) {
  SceneOut out;
  out.scene = "sphere-palpation";
  out.scene_file = "sphere-palpation-256";
  std::tie(out.budget, out.scene_family) = SceneBudget(out.scene_file);
  // Reference: the finest FEM, static.
  const int ref_cells = cfg.quick ? 8 : 16;
  auto ref_mesh = geometry::MakeTetBall({kBallRadius, ref_cells});
  auto ref_fem = tissue::FemModel::Create(*ref_mesh, BallTissue(), BottomCap(ref_mesh->positions));
  for (const auto& [i, f] : CapLoad(geometry::BoundarySurface(*ref_mesh), kPressForce))
    ref_fem->SetExternalForce(i, f);
  ref_fem->SolveStatic(30, 1e-8);
  std::vector<Vec3> ref_surface_rest, ref_surface_disp;
  for (int i = 0; i < ref_mesh->VertexCount(); ++i)
    if (ref_mesh->positions[i].norm() > 0.98 * kBallRadius) {
      ref_surface_rest.push_back(ref_mesh->positions[i]);
      ref_surface_disp.push_back(ref_fem->positions()[i] - ref_mesh->positions[i]);
    }
  const Reference ref = [&](const Vec3& x) {
    return ref_surface_disp[Nearest(ref_surface_rest, x)];
  };
  progress.Step("sphere reference fem");
  const double pole_target = ref(Vec3(0, 0, kBallRadius)).norm();

  for (int cells : cfg.quick ? std::vector<int>{4} : std::vector<int>{4, 6, 8, 12}) {
    auto mesh = geometry::MakeTetBall({kBallRadius, cells});
    auto fem = tissue::FemModel::Create(*mesh, BallTissue(), BottomCap(mesh->positions));
    Row row{"fem", out.scene,
            "cells " + std::to_string(cells) + " (" + std::to_string(mesh->TetCount()) + " tets)"};
    row.size = fem->VertexCount();
    for (const auto& [i, f] : CapLoad(geometry::BoundarySurface(*mesh), kPressForce))
      fem->SetExternalForce(i, f);
    fem->SolveStatic(30, 1e-8);
    Score(row, mesh->positions, fem->positions(), SphereMarkerVertices(mesh->positions), ref);
    row.time_us = TimeUs(cfg.quick ? 3 : 7, [&](int) { fem->StepImplicit(1e-3); });
    out.rows.push_back(row);
    progress.Step("sphere fem " + std::to_string(cells));
  }

  // Mass-spring on the subdivided sphere (seed 001), one stiffness fitted to the pole's depth.
  for (int level : cfg.quick ? std::vector<int>{3} : std::vector<int>{3, 4}) {
    auto surface = geometry::MakeSubdividedSphere({kBallRadius, level});
    auto build = [&](double k) -> Expected<tissue::MassSpringModel> {
      tissue::MassSpringBuildParams bp;
      bp.total_mass = 1050 * 4.0 / 3.0 * std::numbers::pi * std::pow(kBallRadius, 3);
      bp.structural_stiffness = k;
      bp.bending_stiffness = 0.1 * k;
      bp.volume_stiffness = k;
      bp.damping = 0.005 * k;
      bp.volume = tissue::VolumeMode::kInnerLayer;
      auto sys = tissue::BuildMassSpring(*surface, bp);
      if (!sys.ok()) return sys.error();
      tissue::MassSpringStepParams sp;
      sp.integrator = tissue::Integrator::kImplicitEuler;
      auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
      if (!model.ok()) return model.error();
      for (int i : BottomCap(model->system().rest_positions)) model->SetFixed(i, true);
      for (const auto& [i, f] : CapLoad(*surface, kPressForce)) model->SetExternalForce(i, f);
      return model;
    };
    const int pole = Nearest(surface->positions, Vec3(0, 0, kBallRadius));
    double k = 20;
    for (int it = 0; it < 3; ++it) {
      auto model = build(k);
      if (!model.ok()) break;
      for (int s = 0; s < 300; ++s) model->Step(0.05);
      const double got = (model->positions()[pole] - surface->positions[pole]).norm();
      if (!(got > 0) || !std::isfinite(got)) break;
      k *= got / pole_target;
    }
    const auto markers = SphereMarkerVertices(surface->positions);
    for (tissue::Integrator integ : tissue::kAllIntegrators) {
      Row row{
          "mass-spring", out.scene,
          std::to_string(surface->VertexCount()) + " particles, " + tissue::IntegratorName(integ)};
      auto model = build(k);
      if (!model.ok()) continue;
      row.size = static_cast<int>(model->positions().size());
      model->SetIntegrator(integ);
      const double omega = model->MaxAngularFrequency(100);
      double limit =
          integ == tissue::Integrator::kImplicitEuler ? kInf
          : (integ == tissue::Integrator::kRk4)       ? 2.5
          : (integ == tissue::Integrator::kSymplecticEuler || integ == tissue::Integrator::kVerlet)
              ? 1.8
              : 0.5;
      const int substeps = Substeps(omega, limit, 0.005);
      row.setting +=
          ", " + std::to_string(substeps) + " substep" + (substeps > 1 ? "s" : "") + "/ms";
      std::vector<double> times;
      bool ok = true;
      for (int s = 0; s < (cfg.quick ? 300 : 500) && ok; ++s) {
        const auto t0 = Clock::now();
        ok = model->Step(1e-3, substeps);
        times.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
      }
      row.time_us = MedianUs(times);
      if (!ok || model->diverged()) {
        row.note = "diverged";
      } else {
        std::vector<Vec3> rest(model->system().rest_positions.begin(),
                               model->system().rest_positions.begin() + surface->VertexCount());
        std::vector<Vec3> now(model->positions().begin(),
                              model->positions().begin() + surface->VertexCount());
        Score(row, rest, now, markers, ref);
      }
      out.rows.push_back(row);
      progress.Step("sphere msm " + std::string(tissue::IntegratorName(integ)));
    }
  }

  // Ring layer (seed 001 §3.3) on the 258-particle sphere: chain stiffness fitted to the pole.
  {
    auto surface = geometry::MakeSubdividedSphere({kBallRadius, 4});
    std::vector<double> dist(surface->positions.size());
    const Vec3 pole(0, 0, kBallRadius);
    for (size_t i = 0; i < dist.size(); ++i) {
      const double c = std::clamp(surface->positions[i].normalized().dot(Vec3::UnitZ()), -1.0, 1.0);
      dist[i] = kBallRadius * std::acos(c);  // geodesic on the sphere
    }
    const std::vector<double> masses(
        surface->positions.size(), 1050 * 4.0 / 3.0 * std::numbers::pi * std::pow(kBallRadius, 3) /
                                       static_cast<double>(surface->positions.size()));
    auto build = [&](double k) {
      tissue::RingLayerParams rp;
      rp.rings = 8;
      rp.ring_spacing = 0.5 * std::numbers::pi * kBallRadius / 8;
      rp.chain_stiffness = k;
      rp.chain_damping = 0.05 * k * 1e-2;
      return tissue::RingLayerModel::Create(surface->positions, dist, masses, -Vec3::UnitZ(), rp);
    };
    double k = 10;
    for (int it = 0; it < 3; ++it) {
      auto model = build(k);
      if (!model.ok()) break;
      model->SetContactForce(kPressForce);
      for (int s = 0; s < 2000; ++s) model->Step(1e-2);
      model->Apply();
      const int p = Nearest(surface->positions, pole);
      const double got = (model->positions()[p] - surface->positions[p]).norm();
      if (!(got > 0)) break;
      k *= got / pole_target;
    }
    auto model = build(k);
    Row row{"ring-layer", out.scene, "8 rings, 1026 particles"};
    if (model.ok()) {
      row.size = 9;
      model->SetContactForce(kPressForce);
      for (int s = 0; s < 4000; ++s) model->Step(1e-3);
      row.time_us = TimeUs(cfg.repeats * 5, [&](int) {
        model->Step(1e-3);
        model->Apply();
      });
      Score(row, surface->positions, model->positions(), SphereMarkerVertices(surface->positions),
            ref);
    }
    out.rows.push_back(row);
    progress.Step("sphere ring layer");
  }
  return out;
}

// ======================= outputs =======================

void ChooseCheapest(SceneOut& s) {
  const Row* best = nullptr;
  for (const Row& r : s.rows)
    if (std::isfinite(r.rms) && r.rms <= s.budget && (!best || r.time_us < best->time_us))
      best = &r;
  s.chosen = best ? best->model + " (" + best->setting + ")" : "none within budget";
  const bool same = best && best->model.rfind(s.scene_family, 0) == 0;
  s.chosen += "; `scenes/" + s.scene_file + ".json` uses " + s.scene_family +
              (same ? ": consistent" : ": **not** the cheapest within its budget");
}

std::string Num(double v, int digits = 4) {
  if (!std::isfinite(v)) return "";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// One CSV text field (RFC 4180 quoting), through the project's writer.
std::string CsvField(const std::string& s) {
  std::string out;
  csv::AppendText(out, s);
  return out;
}

Status WriteCsv(const std::string& path, const std::vector<SceneOut>& scenes) {
  std::ofstream out(path);
  if (!out) return Error{ErrorCode::kIoError, "cannot write " + path, "out"};
  out << "model,scene,setting,time_per_update_us,rms_error,max_error,size,budget,meets_budget,"
         "note\n";
  for (const SceneOut& s : scenes)
    for (const Row& r : s.rows)
      out << CsvField(r.model) << "," << s.scene << "," << CsvField(r.setting) << ","
          << Num(r.time_us) << "," << Num(r.rms) << "," << Num(r.max) << "," << r.size << ","
          << s.budget << "," << (std::isfinite(r.rms) && r.rms <= s.budget ? "yes" : "no") << ","
          << CsvField(r.note) << "\n";
  return out ? Status::Ok() : Status(Error{ErrorCode::kIoError, "write failed: " + path, "out"});
}

std::string MarkdownTable(const std::vector<SceneOut>& scenes, const std::string& command) {
  std::ostringstream md;
  md << "Command: `" << command << "`. Error: marker displacement error relative to the "
     << "reference's largest marker displacement (RMS and max over the ten markers); time: median "
     << "time per deformation update on this machine.\n\n";
  for (const SceneOut& s : scenes) {
    md << "**" << s.scene << "** (error budget " << Num(100 * s.budget, 3) << "% RMS from `scenes/"
       << s.scene_file << ".json`; cheapest within it: " << s.chosen << ")\n\n";
    md << "| model | setting | time per update | RMS error | max error | note |\n";
    md << "| --- | --- | --- | --- | --- | --- |\n";
    for (const Row& r : s.rows) {
      const std::string t =
          r.time_us >= 1000 ? Num(r.time_us / 1000, 3) + " ms" : Num(r.time_us, 3) + " µs";
      md << "| " << r.model << " | " << r.setting << " | " << t << " | "
         << (std::isfinite(r.rms) ? Num(100 * r.rms, 3) + "%" : "—") << " | "
         << (std::isfinite(r.max) ? Num(100 * r.max, 3) + "%" : "—") << " | " << r.note << " |\n";
    }
    md << "\n";
  }
  return md.str();
}

// Replaces the block between the study's markers in BENCHMARKS.md (or appends it).
Status UpdateBenchmarks(const std::string& path, const std::string& table) {
  const std::string begin = "<!-- speed-vs-error:begin -->", end = "<!-- speed-vs-error:end -->";
  std::ifstream in(path);
  std::stringstream text;
  if (in) text << in.rdbuf();
  std::string s = text.str();
  const std::string block = begin + "\n" + table + end;
  const auto b = s.find(begin), e = s.find(end);
  if (b != std::string::npos && e != std::string::npos && e > b) {
    s.replace(b, e + end.size() - b, block);
  } else {
    s += "\n## Speed against error (FEM and speed-vs-error issue)\n\n" + block + "\n";
  }
  std::ofstream out(path);
  out << s;
  return out ? Status::Ok() : Status(Error{ErrorCode::kIoError, "cannot write " + path, "out"});
}

}  // namespace

int SpeedVsError(const std::vector<std::string>& args) {
  cli::ArgParser p("vsurg-bench speed-vs-error",
                   "Every model on the same scenes against the same reference: time per update\n"
                   "against marker error (DESIGN.md \"Speed against error\"). Writes\n"
                   "speed-vs-error.csv, speed-vs-error.png (Pareto plot), marker8.png (marker 8\n"
                   "during the arm ramp) into --out, and the Markdown table into\n"
                   "docs/BENCHMARKS.md when --out is docs/ (or --benchmarks FILE).");
  p.Option("out", cli::ArgParser::Kind::kString, "output folder", false, "docs")
      .Option("quick", cli::ArgParser::Kind::kFlag, "coarse levels and short runs (under a minute)")
      .Option("benchmarks", cli::ArgParser::Kind::kString,
              "Markdown file to update (default: BENCHMARKS.md in --out when --out is docs)");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  const std::string dir = p.String("out");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::cerr << p.command() << ": --out: cannot create " << dir << ": " << ec.message() << "\n";
    return 2;
  }
  Config cfg;
  cfg.quick = p.Flag("quick");
  cfg.repeats = cfg.quick ? 5 : 9;
  const auto t0 = Clock::now();
  const int per_limb = 3 + (cfg.quick ? 2 : 4) + 1 + 6;
  const int sphere = 1 + (cfg.quick ? 1 : 4) + (cfg.quick ? 6 : 12) + 1;
  Progress progress(3 * per_limb + sphere);
  std::vector<SceneOut> scenes;
  scenes.push_back(
      RunLimb(MakeLimbCase("arm-ramp", "arm", "arm-torsion", 2.07, true), cfg, progress));
  scenes.push_back(
      RunLimb(MakeLimbCase("arm-haptic", "arm", "arm-torsion", 0.02, false), cfg, progress));
  scenes.push_back(
      RunLimb(MakeLimbCase("calf-ramp", "calf", "calf-torsion", 2.07, true), cfg, progress));
  scenes.push_back(RunSphere(cfg, progress));
  for (SceneOut& s : scenes) ChooseCheapest(s);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  const std::string csv = (std::filesystem::path(dir) / "speed-vs-error.csv").string();
  if (Status s = WriteCsv(csv, scenes); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().message << "\n";
    return 1;
  }
  // Pareto plot: time per update against RMS error, one colour per model family.
  {
    Plot plot("time per update (us) vs RMS marker error, all scenes", "time per update (us)",
              "RMS error", true, true);
    std::map<std::string, int> colour;
    for (const SceneOut& s : scenes)
      for (const Row& r : s.rows) {
        if (!std::isfinite(r.rms) || !(r.time_us > 0)) continue;
        const std::string key = r.model;
        if (!colour.count(key)) colour[key] = static_cast<int>(colour.size());
        plot.Point(colour[key], key, r.time_us, std::max(r.rms, 1e-4));
      }
    if (Status s = plot.WritePng((std::filesystem::path(dir) / "speed-vs-error.png").string());
        !s.ok())
      std::cerr << p.command() << ": " << s.error().message << "\n";
  }
  {
    Plot plot("marker 8 during the arm ramp to 2.07 N*m (ramp 1 s, hold 2 s)", "time (s)",
              "displacement (mm)", false, false);
    int i = 0;
    for (const Trajectory& tr : scenes[0].trajectories) {
      std::vector<double> d;
      for (double v : tr.d) d.push_back(1000 * v);
      plot.Line(i++, tr.label, tr.t, d);
    }
    if (Status s = plot.WritePng((std::filesystem::path(dir) / "marker8.png").string()); !s.ok())
      std::cerr << p.command() << ": " << s.error().message << "\n";
  }
  const std::string command = std::string("build/bin/vsurg-bench speed-vs-error") +
                              (cfg.quick ? " --quick" : "") +
                              (dir == "docs" ? "" : " --out " + dir);
  const std::string table = MarkdownTable(scenes, command);
  std::string bench_md = p.Has("benchmarks") ? p.String("benchmarks") : "";
  if (bench_md.empty() && std::filesystem::path(dir).filename() == "docs")
    bench_md = (std::filesystem::path(dir) / "BENCHMARKS.md").string();
  if (!bench_md.empty()) {
    if (Status s = UpdateBenchmarks(bench_md, table); !s.ok())
      std::cerr << p.command() << ": " << s.error().message << "\n";
  }
  std::cout << table;
  std::cout << "speed-vs-error: " << Num(seconds, 3) << " s; wrote " << csv << ", "
            << (std::filesystem::path(dir) / "speed-vs-error.png").string() << ", "
            << (std::filesystem::path(dir) / "marker8.png").string()
            << (bench_md.empty() ? "" : ", " + bench_md) << "\n";
  return 0;
}

}  // namespace vsurg::bench
