// The cuttable patch of the speed-against-error study (bench/speed_vs_error.cpp): scenes/
// pattern-cut.json's taut skin patch in its frame, lifted 6 mm by the grasper's jaws (the scene's
// 2,000 N/m), uncut 10 mm left of the centre, and with the right half of the drill's circle cut,
// 8 mm right of the centre, inside the cut (the flap the cut frees opens). Every model against
// the membrane FEM (tissue::MembraneFem) of the same patch, cut along the same path, at four
// times the scene's lattice (96 cells across, 10,900 vertices; in a quick run twice). The scene's
// own model is the mass-spring membrane of its 24 cells (tissue::CutMembrane) stepped implicitly
// at 1 ms until it settles; its time is the mean step over the first 300 ms after the grasp (the
// motion a session pays for). A FEM row's time is one Newton iteration (assembly, factorisation,
// solve), the least an implicit step of it costs.
//
// Markers: rest points every 4 mm over the patch, leaving out 3 mm from the frame, 6 mm from the
// cut's line and from the jaws (a point load's displacement is singular, and across a cut a rest
// point has two sides); each model's displacement there is interpolated in its own triangle.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "bench/study/study.h"
#include "common/sim/scene.h"
#include "common/tissue/cut_membrane.h"
#include "common/tissue/membrane_fem.h"

namespace vsurg::bench::study {
namespace {

using Vec2 = Eigen::Vector2d;

constexpr double kLift = 0.006, kCutRadius = 0.015;  // m
constexpr double kClear = 0.006, kRim = 0.003, kMarkerStep = 0.004;

struct Case {
  std::string name;
  bool cut = false;
  Vec2 jaws;
};

const Case kCases[] = {{"lift, uncut", false, {-0.010, 0}},
                       {"lift, half the circle cut", true, {0.008, 0}}};

tissue::CutMembraneParams PatchParams(const sim::Scene& scene, int cells) {
  tissue::CutMembraneParams p = scene.mesh.membrane;
  p.cells = cells;
  return p;
}

// The right half of the drill's circle, in steps of a fifth of a millimetre, as the haptic loop
// hands a blade's path on.
void CutHalfCircle(tissue::CutMembrane& patch) {
  const int steps = static_cast<int>(std::ceil(std::numbers::pi * kCutRadius / 2e-4));
  for (int k = 0; k < steps; ++k) {
    const double a0 = -0.5 * std::numbers::pi + std::numbers::pi * k / steps;
    const double a1 = -0.5 * std::numbers::pi + std::numbers::pi * (k + 1) / steps;
    patch.Cut(kCutRadius * Vec2(std::cos(a0), std::sin(a0)),
              kCutRadius * Vec2(std::cos(a1), std::sin(a1)));
  }
}

double JawStiffness(const sim::Scene& scene) {
  return scene.cut->grasper ? scene.cut->grasper->stiffness
                            : sim::Scene::CutSpec::Grasper{}.stiffness;
}

std::optional<tissue::CutMembrane> MakePatch(const sim::Scene& scene, int cells, const Case& c) {
  auto patch = tissue::CutMembrane::Create(PatchParams(scene, cells));
  if (!patch.ok()) return std::nullopt;
  if (c.cut) CutHalfCircle(*patch);
  return std::move(*patch);
}

int NearestParticle(const tissue::CutMembrane& patch, const Vec2& at) {
  int best = 0;
  for (int i = 0; i < static_cast<int>(patch.positions().size()); ++i)
    if ((patch.Rest(i) - at).norm() < (patch.Rest(best) - at).norm()) best = i;
  return best;
}

std::vector<Vec2> Markers(const tissue::CutMembraneParams& p, const Case& c) {
  std::vector<Vec2> out;
  for (double x = -0.5 * p.size_x + kRim; x <= 0.5 * p.size_x - kRim; x += kMarkerStep)
    for (double y = -0.5 * p.size_y + kRim; y <= 0.5 * p.size_y - kRim; y += kMarkerStep) {
      const Vec2 m(x, y);
      const bool near_cut = c.cut && m.x() > -kClear && std::abs(m.norm() - kCutRadius) < kClear;
      if (!near_cut && (m - c.jaws).norm() >= kClear) out.push_back(m);
    }
  return out;
}

// A model's displacement at each marker, interpolated in the triangle (of `patch`'s faces, at
// their rest-plane corners) that holds it.
std::vector<Vec3> AtMarkers(const tissue::CutMembrane& patch, const std::vector<Vec3>& positions,
                            const std::vector<Vec2>& markers) {
  std::vector<Vec3> out(markers.size(), Vec3::Constant(kInf));
  for (int f = 0; f < patch.FaceCount(); ++f) {
    if (patch.Removed(f)) continue;
    const auto v = patch.face(f).v;
    const Vec2 a = patch.Rest(v[0]), b = patch.Rest(v[1]), c = patch.Rest(v[2]);
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    for (size_t m = 0; m < markers.size(); ++m) {
      const Vec2 q = markers[m] - a;
      const double l1 = (q.x() * (c - a).y() - q.y() * (c - a).x()) / area;
      const double l2 = ((b - a).x() * q.y() - (b - a).y() * q.x()) / area;
      if (l1 < -1e-12 || l2 < -1e-12 || l1 + l2 > 1 + 1e-12) continue;
      const double l0 = 1 - l1 - l2;
      const Vec3 rest =
          l0 * Vec3(a.x(), a.y(), 0) + l1 * Vec3(b.x(), b.y(), 0) + l2 * Vec3(c.x(), c.y(), 0);
      out[m] = l0 * positions[v[0]] + l1 * positions[v[1]] + l2 * positions[v[2]] - rest;
    }
  }
  return out;
}

// rms and max of |u − u_ref| over the markers, over the reference's largest |u_ref|.
void ScoreAgainst(Row& row, const std::vector<Vec3>& u, const std::vector<Vec3>& ref) {
  double sum = 0, worst = 0, peak = 0;
  for (size_t m = 0; m < u.size(); ++m) {
    const double e = (u[m] - ref[m]).norm();
    if (!std::isfinite(e)) {
      row.note = "diverged";
      return;
    }
    sum += e * e, worst = std::max(worst, e), peak = std::max(peak, ref[m].norm());
  }
  row.rms = std::sqrt(sum / static_cast<double>(u.size())) / peak;
  row.max = worst / peak;
}

struct Solved {
  std::vector<Vec3> at_markers;
  double time_us = 0;
  int size = 0;
  std::string note, solve;  // what went wrong; a FEM's solve (steps and residual)
};

tissue::MembraneFemParams FemParams(const tissue::CutMembraneParams& p) {
  return {.thickness = p.thickness, .youngs_modulus = p.youngs_modulus, .pretension = p.pretension};
}

Solved SolveFem(const sim::Scene& scene, int cells, const Case& c, const std::vector<Vec2>& markers,
                int repeats) {
  Solved s;
  auto patch = MakePatch(scene, cells, c);
  auto fem = patch ? tissue::MembraneFem::Create(tissue::MeshOf(*patch), FemParams(patch->params()))
                   : Expected<tissue::MembraneFem>(InvalidArgument("cut", "no patch"));
  if (!fem.ok()) return s.note = fem.error().message, s;
  const int jaws = NearestParticle(*patch, c.jaws);
  const Vec2 at = patch->Rest(jaws);
  fem->Hold(jaws, Vec3(at.x(), at.y(), kLift), JawStiffness(scene));
  s.size = fem->VertexCount();
  const std::vector<Vec3> flat = fem->positions();
  s.time_us = TimeUs(repeats, [&](int) {
    fem->SetPositions(flat);
    (void)fem->NewtonStep();
  });
  fem->SetPositions(flat);
  // The cut flap's slack triangles give up stiffness as they fold: the residual there falls
  // slowly while the shape stays put, so a step that moves nothing by 10 nm ends the solve too.
  auto solved = fem->SolveStatic(1e-9, 400, 1e-8);
  if (!solved.ok() || !solved->converged)
    s.note = solved.ok() ? "not converged" : solved.error().message;
  if (solved.ok())
    s.solve = std::to_string(solved->iterations) + " Newton steps, residual " +
              Num(solved->residual, 2) + " N";
  s.at_markers = AtMarkers(*patch, fem->positions(), markers);
  return s;
}

// The mass-spring membrane stepped at 1 ms until no particle moves 1 nm in a step (at most 8 s).
Solved SolveSprings(const sim::Scene& scene, int cells, const Case& c,
                    const std::vector<Vec2>& markers) {
  Solved s;
  auto patch = MakePatch(scene, cells, c);
  if (!patch) return s.note = "no patch", s;
  const Vec2 at = patch->Rest(NearestParticle(*patch, c.jaws));
  patch->Hold(at, Vec3(at.x(), at.y(), kLift), JawStiffness(scene));
  s.size = static_cast<int>(patch->positions().size());
  constexpr int kTimed = 300, kMaxSteps = 8000;
  double timed = 0;
  for (int step = 0; step < kMaxSteps; ++step) {
    const std::vector<Vec3> before = patch->positions();
    const auto t0 = Clock::now();
    if (!patch->Step(1e-3)) return s.note = "diverged", s;
    if (step < kTimed)
      timed += std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    double moved = 0;
    for (size_t i = 0; i < before.size(); ++i)
      moved = std::max(moved, (patch->positions()[i] - before[i]).norm());
    if (step >= kTimed && moved < 1e-9) break;
  }
  s.time_us = timed / kTimed;
  s.at_markers = AtMarkers(*patch, patch->positions(), markers);
  return s;
}

std::string Cells(int cells, int scene_cells) {
  return std::to_string(cells) + " cells" + (cells == scene_cells ? " (the scene's)" : "");
}

}  // namespace

SceneOut RunPatch(const Config& cfg, Progress& progress) {
  SceneOut out = NewSceneOut("pattern-cut", "pattern-cut");
  out.checks = {{"pattern-cut", "cut-membrane", "lift, uncut: 24 cells"}};
  auto scene = sim::LoadSceneByName("pattern-cut");
  if (!scene.ok() || !scene->cut) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0,
                        scene.ok() ? "no cut" : scene.error().message});
    return out;
  }
  const int own = scene->mesh.membrane.cells;
  for (const Case& c : kCases) {
    if (cfg.quick && c.cut) continue;  // the cut's reference takes minutes (its slack flap)
    const std::vector<Vec2> markers = Markers(PatchParams(*scene, own), c);
    const int ref_cells = (cfg.quick ? 2 : 4) * own;
    const Solved ref = SolveFem(*scene, ref_cells, c, markers, 1);
    const std::string against = "; reference " + std::to_string(ref_cells) + " cells, " +
                                (ref.note.empty() ? ref.solve : ref.note);
    progress.Step("patch reference fem");
    for (int cells : cfg.quick ? std::vector<int>{own} : std::vector<int>{16, own, 32, 48}) {
      const Solved s = SolveSprings(*scene, cells, c, markers);
      Row row{"cut-membrane", out.scene, c.name + ": " + Cells(cells, own), s.time_us};
      row.size = s.size, row.note = (s.note.empty() ? "settled" : s.note) + against;
      if (s.note.empty() && ref.note.empty()) ScoreAgainst(row, s.at_markers, ref.at_markers);
      out.rows.push_back(row);
      progress.Step("patch springs " + std::to_string(cells));
    }
    for (int cells : cfg.quick ? std::vector<int>{} : std::vector<int>{own, 2 * own}) {
      const Solved s = SolveFem(*scene, cells, c, markers, cfg.repeats);
      Row row{"fem", out.scene, c.name + ": membrane FEM, " + Cells(cells, own), s.time_us};
      row.size = s.size, row.note = (s.note.empty() ? s.solve : s.note) + against;
      if (s.note.empty() && ref.note.empty()) ScoreAgainst(row, s.at_markers, ref.at_markers);
      out.rows.push_back(row);
      progress.Step("patch fem " + std::to_string(cells));
    }
  }
  return out;
}

}  // namespace vsurg::bench::study
