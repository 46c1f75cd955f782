// The limb half of the speed-against-error study: the forearm and the calf twisted at the grasp,
// every model against tapered Saint-Venant torsion (scenes and references:
// bench/speed_vs_error.cpp).
#include "bench/study/study.h"

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

#include "common/core/args.h"
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
#include "common/tissue/reduced.h"
#include "common/tissue/ring_layer.h"
#include "common/tissue/torsion_reference.h"

namespace vsurg::bench::study {
namespace {

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
    // The scene file's own coil (with its per-coil rigidities when it has them), on the
    // built-in limb the file names.
    auto file = sim::LoadSceneByName(c.scene_file);
    variants.push_back(
        {"coil-scene", "scene parameters",
         !file.ok() ? Expected<tissue::CoilSpringParams>(file.error())
         : file->region.kind == sim::ModelKind::kCoil
             ? Expected<tissue::CoilSpringParams>(file->region.coil)
             : Expected<tissue::CoilSpringParams>(
                   Error{ErrorCode::kInvalidArgument, "the scene file has no coil", "region"})});
  }
  const double grasp = geometry::ArcLengths(limb->centreline).back();
  const std::vector<int> markers = LimbMarkerVertices(limb->surface.positions, c.shaft);
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
  auto c = geometry::MakeTetCylinder(
      geometry::TorsionCylinder(s.length, s.radius_proximal, s.radius_distal, rings));
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
    const auto markers = LimbMarkerVertices(m.cylinder.mesh.positions, c.shaft);
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
  const auto markers = LimbMarkerVertices(m.cylinder.mesh.positions, c.shaft);
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

// The reduced twist field (common/tissue/reduced.h) precomputed from the FEM at each level and
// carried onto the limb's display surface, the mesh the coil model deforms: the same vertices,
// markers and reference as the coil rows. The note gives the precomputation's time.
void ReducedRows(const LimbCase& c, const Config& cfg, SceneOut& out, Progress& progress) {
  auto limb = geometry::MakeLimb(c.limb.limb);
  if (!limb.ok()) return;
  const auto& display = limb->surface.positions;
  const std::vector<int> markers = LimbMarkerVertices(display, c.shaft);
  const Reference ref = [&](const Vec3& x) {
    return SaintVenantDisplacement(c.shaft, c.torque, x);
  };
  for (int level : cfg.quick ? std::vector<int>{2} : std::vector<int>{4, 5}) {
    const TetLimb m = MakeTetLimb(c.shaft, level);
    Row row{"reduced", c.scene,
            "twist field, FEM level " + std::to_string(level) + " (" +
                std::to_string(m.cylinder.mesh.TetCount()) + " tets)"};
    const auto t0 = Clock::now();
    auto response = tissue::FemStaticResponse::Create(
        m.cylinder.mesh, FemFor(c.shaft, c.limb.poisson_ratio), m.cylinder.base);
    auto field = response.ok()
                     ? tissue::PrecomputeTwistField(*response, m.cylinder.tip, m.cylinder.tip_area,
                                                    Vec3::Zero(), Vec3::UnitZ(), display)
                     : Expected<tissue::TwistField>(response.error());
    auto model = field.ok() ? tissue::ReducedTwistModel::Create(*field, display, std::numbers::pi)
                            : Expected<tissue::ReducedTwistModel>(field.error());
    const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!model.ok()) {
      row.note = model.error().message;
      out.rows.push_back(row);
      progress.Step(c.scene + " reduced");
      continue;
    }
    row.size = model->VertexCount();
    row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
      model->Update(c.torque * (0.5 + 0.5 * ((i % 2) ? 1.0 : 0.97)));
    });
    const tissue::ReducedStats st = model->Update(c.torque);
    Score(row, display, model->positions(), markers, ref);
    row.note = "precomputed in " + Num(precompute_s, 2) + " s" +
               (st.saturated ? "; torque past capacity, clamped" : "");
    out.rows.push_back(row);
    progress.Step(c.scene + " reduced level " + std::to_string(level));
  }
}

// Mass-spring on the FEM's tetrahedra (one spring per edge), its single stiffness fitted so the
// grasp's twist matches the reference at the final torque (the one free parameter the model has).
// The limb's tetrahedra as one spring per edge (the mass-spring paper's model on the FEM's mesh),
// its base held, twisted by a follower torque on its tip.
class LimbMassSpring {
 public:
  LimbMassSpring(const LimbCase& c, const TetLimb& m) : c_(c), m_(m) {}

  Expected<tissue::MassSpringModel> Build(double k, double c_damp) const {
    auto sys = tissue::BuildMassSpring(m_.cylinder.mesh, c_.limb.density, k, c_damp);
    if (!sys.ok()) return sys.error();
    tissue::MassSpringStepParams sp;
    sp.integrator = tissue::Integrator::kImplicitEuler;
    sp.cg_max_iterations = 200;
    sp.cg_tolerance = 1e-6;
    auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
    if (!model.ok()) return model.error();
    for (int v : m_.cylinder.base) model->SetFixed(v, true);
    return model;
  }
  void Apply(tissue::MassSpringModel& model, double torque) const {
    const auto f = FollowerTorque(model.positions(), m_, torque);
    for (size_t i = 0; i < f.size(); ++i) model.SetExternalForce(m_.cylinder.tip[i], f[i]);
  }
  // Quasi-static: the torque ramped in over 200 large implicit steps, 400 in all.
  void Settle(tissue::MassSpringModel& model, double torque) const {
    model.SetIntegrator(tissue::Integrator::kImplicitEuler);
    for (int k = 0; k < 400; ++k) {
      if (k % 10 == 0) Apply(model, torque * std::min(1.0, (k + 10) / 200.0));
      model.Step(0.05);
    }
  }
  // The spring stiffness whose settled twist at marker `tip_marker` meets the reference: twist
  // scales as 1/k for small twists, so three corrections from the spring of an elastic cube of
  // the mean edge length l (k ≈ E·l).
  double FitStiffness(int tip_marker, double target) const {
    const auto& mesh = m_.cylinder.mesh;
    double edge = 0;
    int edges = 0;
    for (const auto& t : mesh.tetrahedra)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b)
          edge += (mesh.positions[t[a]] - mesh.positions[t[b]]).norm(), ++edges;
    edge /= std::max(1, edges);
    double k = 2 * c_.shaft.shear_modulus * (1 + c_.limb.poisson_ratio) * edge;
    const Vec3 tip_rest = mesh.positions[tip_marker];
    for (int it = 0; it < 3; ++it) {
      auto model = Build(k, 0.0);
      if (!model.ok()) break;
      Settle(*model, c_.torque);
      const double got = (model->positions()[tip_marker] - tip_rest).norm();
      if (!(got > 0) || !std::isfinite(got)) break;
      k *= got / target;
    }
    return k;
  }

 private:
  const LimbCase& c_;
  const TetLimb& m_;
};

// One integrator's row on the ramp: substeps within its stability limit, the median step, the
// error at the end unless it diverged; the marker-8 trajectory for the plot.
Row MassSpringLimbRow(const LimbCase& c, const Config& cfg, const TetLimb& m,
                      const LimbMassSpring& limb, const std::vector<int>& markers,
                      const Reference& ref, double k, double c_damp, tissue::Integrator integ,
                      Trajectory& tr) {
  Row row{"mass-spring", c.scene,
          std::string(tissue::IntegratorName(integ)) + " (k fitted " +
              std::to_string(k).substr(0, 6) + " N/m)"};
  auto model = limb.Build(k, c_damp);
  if (!model.ok()) {
    row.note = model.error().message;
    return row;
  }
  row.size = static_cast<int>(model->positions().size());
  model->SetIntegrator(integ);
  const int substeps = Substeps(model->MaxAngularFrequency(100), StabilityLimit(integ), c_damp / k);
  const int steps = cfg.quick ? 600 : 3000;
  std::vector<double> times;
  bool ok = true;
  for (int s = 0; s <= steps && ok; ++s) {
    const double t = s * 1e-3;
    limb.Apply(*model, c.torque * Ramp(t, 1.0));
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
  return row;
}

void MassSpringLimbRows(const LimbCase& c, const Config& cfg, SceneOut& out, Progress& progress) {
  const TetLimb m = MakeTetLimb(c.shaft, cfg.quick ? 1 : 2);
  const Reference ref = [&](const Vec3& x) {
    return SaintVenantDisplacement(c.shaft, c.torque, x);
  };
  const auto markers = LimbMarkerVertices(m.cylinder.mesh.positions, c.shaft);
  const LimbMassSpring limb(c, m);
  const double k = limb.FitStiffness(markers[9], ref(m.cylinder.mesh.positions[markers[9]]).norm());
  // Damping per spring c = 0.002·k: about ζ = 0.02 on the first torsion mode (ω ≈ 20 rad/s);
  // more would overdamp the highest modes and shrink the explicit schemes' stable step further.
  const double c_damp = 0.002 * k;
  for (tissue::Integrator integ : tissue::kAllIntegrators) {
    Trajectory tr{"mass-spring " + std::string(tissue::IntegratorName(integ)), {}, {}};
    out.rows.push_back(MassSpringLimbRow(c, cfg, m, limb, markers, ref, k, c_damp, integ, tr));
    if (out.rows.back().size > 0) {  // built (a model that cannot be built has no size)
      if (integ == tissue::Integrator::kMidpoint || integ == tissue::Integrator::kImplicitEuler)
        out.trajectories.push_back(std::move(tr));
      progress.Step(c.scene + " msm " + tissue::IntegratorName(integ));
    } else {
      progress.Step(c.scene + " msm");
    }
  }
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
  SceneOut out = NewSceneOut(c.scene, c.scene_file);
  out.checks.push_back({c.scene_file, "coil-scene", "scene parameters"});
  if (c.scene_file == "arm-torsion")  // its FEM: 4 rings, level 4 (the quick run has level 2)
    out.checks.push_back(
        {"arm-torsion-reduced", "reduced", cfg.quick ? "twist field" : "twist field, FEM level 4"});
  CoilRows(c, cfg, out, progress);
  ReducedRows(c, cfg, out, progress);
  FemRows(c, cfg, out, progress);
  MassSpringLimbRows(c, cfg, out, progress);
  return out;
}

}  // namespace

std::vector<SceneOut> RunLimbScenes(const Config& cfg, Progress& progress) {
  return {RunLimb(MakeLimbCase("arm-ramp", "arm", "arm-torsion", 2.07, true), cfg, progress),
          RunLimb(MakeLimbCase("arm-haptic", "arm", "arm-torsion", 0.02, false), cfg, progress),
          RunLimb(MakeLimbCase("calf-ramp", "calf", "calf-torsion", 2.07, true), cfg, progress)};
}

std::vector<int> LimbMarkerVertices(const std::vector<Vec3>& rest, const tissue::TaperedShaft& s) {
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

}  // namespace vsurg::bench::study
