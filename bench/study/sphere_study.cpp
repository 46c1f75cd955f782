// The sphere half of the speed-against-error study: a 5 cm ball pressed on its top cap, every
// model against the finest FEM (bench/speed_vs_error.cpp).
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
#include <optional>
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

std::vector<Vec3> SphereMarkers() {
  std::vector<Vec3> m;
  for (int k = 0; k < 10; ++k) {
    const double a = (5.0 * k) * std::numbers::pi / 180.0;
    m.emplace_back(kBallRadius * std::sin(a), 0.0, kBallRadius * std::cos(a));
  }
  return m;
}

}  // namespace

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

namespace {

// The reference: the finest FEM (16 cells; 8 quick), static under the press.
Reference SphereReference(const Config& cfg) {
  const int ref_cells = cfg.quick ? 8 : 16;
  auto ref_mesh = geometry::MakeTetBall({kBallRadius, ref_cells});
  auto ref_fem = tissue::FemModel::Create(*ref_mesh, BallTissue(), BottomCap(ref_mesh->positions));
  for (const auto& [i, f] : CapLoad(geometry::BoundarySurface(*ref_mesh), kPressForce))
    ref_fem->SetExternalForce(i, f);
  ref_fem->SolveStatic(30, 1e-8);
  std::vector<Vec3> ref_disp(ref_mesh->positions.size());
  for (size_t i = 0; i < ref_disp.size(); ++i)
    ref_disp[i] = ref_fem->positions()[i] - ref_mesh->positions[i];
  return InterpolatedReference(*ref_mesh, std::move(ref_disp));
}

// The FEM itself at coarser meshes: static under the press for the error, implicit steps timed.
void SphereFemRows(const Config& cfg, const Reference& ref, SceneOut& out, Progress& progress) {
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
}

void SphereReducedRows(const Config& cfg, const Reference& ref, SceneOut& out, Progress& progress) {
  // Reduced: the Green's-function contact table (common/tissue/reduced.h) precomputed from the
  // FEM at each refinement for every display vertex above the fixed cap, with the press's own
  // footprint (the 1 cm cap), on the 1,026-vertex display sphere; one press at the pole.
  {
    auto display = geometry::MakeSubdividedSphere({kBallRadius, 4});
    std::vector<int> reachable;
    const std::vector<int> fixed_display = BottomCap(display->positions);
    std::vector<uint8_t> is_fixed(display->positions.size(), 0);
    for (int i : fixed_display) is_fixed[i] = 1;
    for (int i = 0; i < display->VertexCount(); ++i)
      if (!is_fixed[i]) reachable.push_back(i);
    const int pole = Nearest(display->positions, Vec3(0, 0, kBallRadius));
    for (int cells : cfg.quick ? std::vector<int>{4} : std::vector<int>{8, 12}) {
      auto mesh = geometry::MakeTetBall({kBallRadius, cells});
      Row row{"reduced", out.scene,
              "contact table, FEM cells " + std::to_string(cells) + " (" +
                  std::to_string(mesh->TetCount()) + " tets), " +
                  std::to_string(display->VertexCount()) + " vertices"};
      const auto t0 = Clock::now();
      auto response =
          tissue::FemStaticResponse::Create(*mesh, BallTissue(), BottomCap(mesh->positions));
      tissue::ContactResponseParams cp;
      cp.footprint_radius = kCapRadius;
      auto table = response.ok()
                       ? tissue::PrecomputeContactResponse(*response, *display, reachable, cp)
                       : Expected<tissue::ContactResponse>(response.error());
      const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
      const int64_t bytes = table.ok() ? table->Bytes() : 0;
      auto model = table.ok() ? tissue::ReducedContactModel::Create(
                                    std::make_shared<tissue::ContactResponse>(std::move(*table)),
                                    display->positions, 10.0)
                              : Expected<tissue::ReducedContactModel>(table.error());
      if (!model.ok()) {
        row.note = model.error().message;
        out.rows.push_back(row);
        progress.Step("sphere reduced");
        continue;
      }
      row.size = model->VertexCount();
      row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
        model->Press(pole, Vec3(0, 0, -kPressForce * ((i % 2) ? 1.0 : 0.97)));
      });
      model->Press(pole, Vec3(0, 0, -kPressForce));
      Score(row, display->positions, model->positions(), SphereMarkerVertices(display->positions),
            ref);
      row.note = "precomputed in " + Num(precompute_s, 2) + " s; " +
                 std::to_string(reachable.size()) + " contacts, " + Num(bytes / 1048576.0, 3) +
                 " MB";
      out.rows.push_back(row);
      progress.Step("sphere reduced " + std::to_string(cells));
    }
  }
}

// The press of the mass-spring paper's sphere with the given springs: the inner layer for volume,
// the bottom cap fixed, the press's load on the top cap; implicit Euler until a variant sets its
// own integrator.
Expected<tissue::MassSpringModel> PressedMassSpring(const geometry::TriMesh& surface,
                                                    tissue::MassSpringBuildParams bp) {
  bp.total_mass = 1050 * 4.0 / 3.0 * std::numbers::pi * std::pow(kBallRadius, 3);
  bp.volume = tissue::VolumeMode::kInnerLayer;
  auto sys = tissue::BuildMassSpring(surface, bp);
  if (!sys.ok()) return sys.error();
  tissue::MassSpringStepParams sp;
  sp.integrator = tissue::Integrator::kImplicitEuler;
  auto model = tissue::MassSpringModel::Create(std::move(*sys), sp);
  if (!model.ok()) return model.error();
  for (int i : BottomCap(model->system().rest_positions)) model->SetFixed(i, true);
  for (const auto& [i, f] : CapLoad(surface, kPressForce)) model->SetExternalForce(i, f);
  return model;
}

// The scene file's proportions with structural stiffness `k`: bending and inner-layer springs at
// a tenth of it, the inner layer 4 mm deep, damping 0.005 s × k.
Expected<tissue::MassSpringModel> ProportionedMassSpring(const geometry::TriMesh& surface,
                                                         double k) {
  tissue::MassSpringBuildParams bp;
  bp.structural_stiffness = k;
  bp.bending_stiffness = 0.1 * k;
  bp.volume_stiffness = 0.1 * k;
  bp.damping = 0.005 * k;
  bp.layer_depth = 0.004;
  return PressedMassSpring(surface, bp);
}

// The structural stiffness that gives the pole the reference's depth, three secant steps from
// 20 N/m.
double FitMassSpringToPole(const geometry::TriMesh& surface, double pole_target) {
  const int pole = Nearest(surface.positions, Vec3(0, 0, kBallRadius));
  double k = 20;
  for (int it = 0; it < 3; ++it) {
    auto model = ProportionedMassSpring(surface, k);
    if (!model.ok()) break;
    for (int s = 0; s < 300; ++s) model->Step(0.05);
    const double got = (model->positions()[pole] - surface.positions[pole]).norm();
    if (!(got > 0) || !std::isfinite(got)) break;
    k *= got / pole_target;
  }
  return k;
}

struct MassSpringVariant {
  std::string model;
  tissue::Integrator integrator;
  bool scene;
};

// One integrator's row: the substeps its stability asks for at 1 ms, the median step, the error
// unless it diverged. Nothing when the model cannot be built.
std::optional<Row> MassSpringRow(const Config& cfg, const std::string& scene,
                                 const geometry::TriMesh& surface, const Reference& ref,
                                 const Expected<sim::Scene>& file, double k,
                                 const MassSpringVariant& v) {
  const tissue::Integrator integ = v.integrator;
  Row row{v.model, scene,
          std::to_string(surface.VertexCount()) + " particles, " + tissue::IntegratorName(integ) +
              (v.scene ? ", scene parameters (k " +
                             Num(file->region.mass_spring.structural_stiffness) + " N/m)"
                       : " (k fitted " + Num(k) + " N/m)")};
  auto model = v.scene ? PressedMassSpring(surface, file->region.mass_spring)
                       : ProportionedMassSpring(surface, k);
  if (!model.ok()) return std::nullopt;
  row.size = static_cast<int>(model->positions().size());
  model->SetIntegrator(integ);
  const double omega = model->MaxAngularFrequency(100);
  const double limit = StabilityLimit(integ);
  const int substeps =
      Substeps(omega, limit,
               v.scene ? file->region.mass_spring.damping /
                             std::max(1e-12, file->region.mass_spring.structural_stiffness)
                       : 0.005);
  row.setting += ", " + std::to_string(substeps) + " substep" + (substeps > 1 ? "s" : "") + "/ms";
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
                           model->system().rest_positions.begin() + surface.VertexCount());
    std::vector<Vec3> now(model->positions().begin(),
                          model->positions().begin() + surface.VertexCount());
    Score(row, rest, now, SphereMarkerVertices(surface.positions), ref);
  }
  return row;
}

// Mass-spring on the subdivided sphere (the mass-spring paper): the scene file's own parameters
// (on its 258 particles), then the same proportions with the stiffness fitted to the pole's depth
// on 258 and 1026 particles (the family at its most favourable). A sweep against this reference
// (bending 0–0.5, volume 0.05–8, depth 2–30 mm) found 12–13% RMS at the file's proportions where
// the earlier volume = k, 10 mm deep gave 21.6%.
void SphereMassSpringRows(const Config& cfg, const Reference& ref, double pole_target,
                          SceneOut& out, Progress& progress) {
  auto file = sim::LoadSceneByName(out.scene_file);
  for (int level : cfg.quick ? std::vector<int>{3} : std::vector<int>{3, 4}) {
    auto surface = geometry::MakeSubdividedSphere({kBallRadius, level});
    const double k = FitMassSpringToPole(*surface, pole_target);
    std::vector<MassSpringVariant> variants;
    if (level == 3 && file.ok() && file->region.kind == sim::ModelKind::kMassSpring)
      variants.push_back({"mass-spring-scene", file->region.integrator, true});
    for (tissue::Integrator integ : tissue::kAllIntegrators)
      variants.push_back({"mass-spring", integ, false});
    for (const MassSpringVariant& v : variants) {
      auto row = MassSpringRow(cfg, out.scene, *surface, ref, file, k, v);
      if (!row) continue;
      out.rows.push_back(std::move(*row));
      progress.Step("sphere msm " + std::string(tissue::IntegratorName(v.integrator)));
    }
  }
}

void SphereRingLayerRows(const Config& cfg, const Reference& ref, double pole_target, SceneOut& out,
                         Progress& progress) {
  // Ring layer (the mass-spring paper §3.3) on the 258-particle sphere: chain stiffness fitted to
  // the pole.
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
    // The scene file's own ring layer (sphere-palpation-rings: its rings, spacing, chain and
    // tethers), with ρ the straight distance from the contact as the simulation measures it.
    auto rings_file = sim::LoadSceneByName("sphere-palpation-rings");
    Row scene_row{"ring-layer-scene", out.scene, "scene parameters"};
    if (rings_file.ok() && rings_file->region.kind == sim::ModelKind::kRingLayer) {
      const tissue::RingLayerParams& rp = rings_file->region.ring;
      std::vector<double> chord(surface->positions.size());
      for (size_t i = 0; i < chord.size(); ++i) chord[i] = (surface->positions[i] - pole).norm();
      auto scene_model =
          tissue::RingLayerModel::Create(surface->positions, chord, masses, -Vec3::UnitZ(), rp);
      scene_row.setting = std::to_string(rp.rings) + " rings of " + Num(1000 * rp.ring_spacing) +
                          " mm, scene parameters (chain " + Num(rp.chain_stiffness) +
                          " N/m, tethers " + Num(rp.tether_stiffness) + " N/m)";
      if (scene_model.ok()) {
        scene_row.size = rp.rings + 1;
        scene_model->SetContactForce(kPressForce);
        for (int s = 0; s < 4000; ++s) scene_model->Step(1e-3);
        scene_row.time_us = TimeUs(cfg.repeats * 5, [&](int) {
          scene_model->Step(1e-3);
          scene_model->Apply();
        });
        Score(scene_row, surface->positions, scene_model->positions(),
              SphereMarkerVertices(surface->positions), ref);
      } else {
        scene_row.note = scene_model.error().message;
      }
    } else {
      scene_row.note = "scenes/sphere-palpation-rings.json has no ring layer";
    }
    out.rows.push_back(scene_row);
    progress.Step("sphere ring layer (scene)");
  }
}

}  // namespace

SceneOut RunSphere(const Config& cfg, Progress& progress) {
  SceneOut out = NewSceneOut("sphere-palpation", "sphere-palpation-256");
  out.checks = {{"sphere-palpation-256", "mass-spring-scene", "258 particles"},
                {"sphere-palpation-1024", "reduced",
                 cfg.quick ? "contact table" : "contact table, FEM cells 8 "},
                {"sphere-palpation-rings", "ring-layer-scene", ""}};
  const Reference ref = SphereReference(cfg);
  progress.Step("sphere reference fem");
  const double pole_target = ref(Vec3(0, 0, kBallRadius)).norm();
  SphereFemRows(cfg, ref, out, progress);
  SphereReducedRows(cfg, ref, out, progress);
  SphereMassSpringRows(cfg, ref, pole_target, out, progress);
  SphereRingLayerRows(cfg, ref, pole_target, out, progress);
  return out;
}

}  // namespace vsurg::bench::study
