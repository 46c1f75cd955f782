// The palpation pad of the speed-against-error study (bench/speed_vs_error.cpp): scenes/
// lump-search.json's 12 × 12 × 4 cm block on its table, holding the palpation goal's lump (10 mm
// across, five times as stiff, its centre 15 mm under the top), pressed over the lump by 0.2 N
// spread over a 1 cm cap; every model against the heterogeneous FEM of the same block at twice
// the scene's grid in each direction (153,600 tetrahedra). The scene's own model is the contact
// table of its own 20 × 20 × 8 grid, built as a session builds it (sim::TableInputsFor).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>

#include "bench/study/study.h"
#include "common/geometry/mesh.h"
#include "common/geometry/tet_generators.h"
#include "common/sim/rooms/room_support.h"
#include "common/sim/scene.h"
#include "common/tissue/fem.h"
#include "common/tissue/reduced.h"

namespace vsurg::bench::study {
namespace {

// The goal's lump (tests/common/sim/palpation_test.cpp) and the point of the top above it.
const tissue::Inclusion kPadLump{{0.013, -0.009, 0.025}, 0.005, 5};

struct Pad {
  sim::Scene scene;
  geometry::TriMesh rest;  // the scene's display surface
  std::vector<int> held;   // its vertices on the table
  Vec3 top = Vec3::Zero();
  std::vector<Vec3> markers;  // ten rest points on the top, 5 mm apart in x across the press
};

Expected<Pad> LoadPad() {
  auto scene = sim::LoadSceneByName("lump-search");
  if (!scene.ok()) return scene.error();
  Pad p;
  p.scene = *scene;
  p.scene.cases.reset();
  p.scene.inclusions = {kPadLump};
  auto mesh = sim::BuildSceneMesh(p.scene.mesh);
  if (!mesh.ok()) return mesh.error();
  p.rest = mesh->surface;
  auto held = sim::SupportedVertices(p.rest, p.scene.region, mesh->groups);
  if (!held.ok()) return held.error();
  p.held = *held;
  const double height = p.scene.mesh.block.size.z();
  p.top = Vec3(kPadLump.centre.x(), kPadLump.centre.y(), height);
  for (int k = 0; k < 10; ++k) p.markers.push_back(p.top + Vec3(0.005 * k - 0.0225, 0, 0));
  return p;
}

geometry::TetMesh PadGrid(const Pad& p, double scale) {
  geometry::TetBoxParams box = p.scene.mesh.block;
  for (int& c : box.cells) c = static_cast<int>(std::lround(c * scale));
  return *geometry::MakeTetBox(box);
}

std::string Times(double scale) {
  return Num(scale, 2) + "×";
}

// The press on a FEM's boundary: the table's footprint rule (tissue::FootprintWeights), a load
// per vertex of `mesh`.
std::vector<Vec3> Press(const geometry::TetMesh& mesh, const Vec3& top) {
  std::vector<Vec3> f(mesh.VertexCount(), Vec3::Zero());
  for (const auto& [i, w] :
       tissue::FootprintWeights(geometry::BoundarySurface(mesh), top, Vec3::UnitZ(), kCapRadius))
    f[i] += Vec3(0, 0, -kPressForce * w);
  return f;
}

// Each marker's nearest top vertex of `positions` (z at the block's height).
std::vector<int> TopMarkers(const Pad& p, const std::vector<Vec3>& positions) {
  std::vector<int> top;
  std::vector<Vec3> points;
  for (int i = 0; i < static_cast<int>(positions.size()); ++i)
    if (positions[i].z() > p.top.z() - 1e-9) top.push_back(i), points.push_back(positions[i]);
  std::vector<int> out;
  for (const Vec3& m : p.markers) out.push_back(top[Nearest(points, m)]);
  return out;
}

// The heterogeneous FEM of the pad at `scale` times the scene's grid, pressed: its small-strain
// static answer (one factorisation; the tables are made of the same K₀⁻¹, and at 0.2 N the pad's
// top turns by under a degree), and the corotational model for the timing of a dynamic step.
struct SolvedPad {
  geometry::TetMesh mesh;
  std::vector<Vec3> positions;  // pressed
  std::unique_ptr<tissue::FemModel> fem;
  std::string note;
};

SolvedPad SolvePad(const Pad& p, double scale) {
  SolvedPad s;
  auto in = sim::TableInputsFor<tissue::ContactResponseParams>(p.scene, p.rest, p.held,
                                                               PadGrid(p, scale));
  auto response = in.ok() ? tissue::FemStaticResponse::Create(in->mesh, in->material, in->fixed)
                          : Expected<tissue::FemStaticResponse>(in.error());
  // The corotational model keeps its volume per element (only the static answers take the
  // scene's choice; the timing is the same).
  tissue::FemParams dynamic = in.ok() ? in->material : tissue::FemParams{};
  dynamic.nodal_volume = false;
  auto fem = in.ok() ? tissue::FemModel::Create(in->mesh, dynamic, in->fixed)
                     : Expected<tissue::FemModel>(in.error());
  if (!response.ok() || !fem.ok()) {
    s.note = (response.ok() ? fem.error() : response.error()).message;
    return s;
  }
  s.mesh = in->mesh;
  s.positions = s.mesh.positions;
  const std::vector<Vec3> load = Press(s.mesh, p.top);
  const std::vector<Vec3> u = response->Solve(load);  // m
  for (size_t i = 0; i < u.size(); ++i) s.positions[i] += u[i];
  s.fem = std::make_unique<tissue::FemModel>(std::move(*fem));
  for (int v = 0; v < static_cast<int>(load.size()); ++v)
    if (!load[v].isZero()) s.fem->SetExternalForce(v, load[v]);
  return s;
}

void PadFemRows(const Config& cfg, const Pad& p, const Reference& reference, SceneOut& out,
                Progress& progress) {
  for (double scale : cfg.quick ? std::vector<double>{1} : std::vector<double>{1, 1.5}) {
    SolvedPad s = SolvePad(p, scale);
    Row row{"fem", out.scene,
            Times(scale) + " the scene's grid (" + std::to_string(s.mesh.TetCount()) + " tets)"};
    row.note = s.note;
    if (s.fem) {
      row.size = s.fem->VertexCount();
      Score(row, s.mesh.positions, s.positions, TopMarkers(p, s.mesh.positions), reference);
      row.time_us = TimeUs(cfg.quick ? 3 : 5, [&](int) { s.fem->StepImplicit(1e-3); });
    }
    out.rows.push_back(row);
    progress.Step("pad fem " + Times(scale));
  }
}

// The contact table of the scene's grid (the session's own) and of twice as fine, one press
// above the lump.
void PadReducedRows(const Config& cfg, const Pad& p, const Reference& reference, SceneOut& out,
                    Progress& progress) {
  const int top = Nearest(p.rest.positions, p.top);
  const std::vector<int> markers = TopMarkers(p, p.rest.positions);
  for (double scale : cfg.quick ? std::vector<double>{1} : std::vector<double>{1, 1.5, 2}) {
    Row row{"reduced", out.scene,
            "contact table, FEM " + Times(scale) + " the scene's grid, " +
                std::to_string(p.rest.VertexCount()) + " vertices"};
    const auto t0 = Clock::now();
    auto in = sim::TableInputsFor<tissue::ContactResponseParams>(p.scene, p.rest, p.held,
                                                                 PadGrid(p, scale));
    auto response = in.ok() ? tissue::FemStaticResponse::Create(in->mesh, in->material, in->fixed)
                            : Expected<tissue::FemStaticResponse>(in.error());
    ContactTableRow(cfg, response, p.rest, in.ok() ? in->reachable : std::vector<int>{},
                    p.scene.region.reduced.max_force, top, markers, reference, t0, row);
    out.rows.push_back(row);
    progress.Step("pad reduced " + Times(scale));
  }
}

}  // namespace

SceneOut RunPad(const Config& cfg, Progress& progress) {
  SceneOut out = NewSceneOut("lump-search", "lump-search");
  out.checks = {{"lump-search", "reduced", "contact table, FEM 1×"}};
  auto pad = LoadPad();
  if (!pad.ok()) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, pad.error().message});
    return out;
  }
  // Reference: the heterogeneous FEM at twice the scene's grid (1.5× in a quick run; three times,
  // 518k tetrahedra, took Eigen's simplicial factorisation over 6 minutes and was left out).
  SolvedPad ref = SolvePad(*pad, cfg.quick ? 1.5 : 2);
  if (!ref.fem) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, ref.note});
    return out;
  }
  std::vector<Vec3> ref_disp(ref.mesh.positions.size());
  for (size_t i = 0; i < ref_disp.size(); ++i)
    ref_disp[i] = ref.positions[i] - ref.mesh.positions[i];
  const Reference reference = InterpolatedReference(ref.mesh, std::move(ref_disp));
  progress.Step("pad reference fem");
  PadFemRows(cfg, *pad, reference, out, progress);
  PadReducedRows(cfg, *pad, reference, out, progress);
  return out;
}

}  // namespace vsurg::bench::study
