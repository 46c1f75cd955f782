// The imported-anatomy part of the speed-against-error study: the kidney of
// scenes/kidney-palpation.json (a surface file read by assimp, tetrahedralised by CGAL), resting
// on its lower fifth and pressed on its top by 0.2 N spread over a 1 cm cap, every model against
// the finest FEM of the same surface (bench/speed_vs_error.cpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>

#include "bench/study/study.h"
#include "common/geometry/mesh.h"
#include "common/geometry/tetrahedralize.h"
#include "common/sim/scene.h"
#include "common/tissue/fem.h"
#include "common/tissue/reduced.h"

namespace vsurg::bench::study {
namespace {

struct Organ {
  sim::Scene scene;
  geometry::TriMesh surface;  // the display surface, m
  tissue::FemParams material;
  Vec3 top = Vec3::Zero();    // the highest surface point: the press's centre
  double mid_z = 0;           // halfway up: only the upper side is loaded and marked
  std::vector<Vec3> markers;  // rest points on the upper surface
};

// The press: a uniform pressure F/(π a²) straight down on the upper surface within a of the top
// (in x, y), lumped onto the vertices of `surface` by sampling each triangle (28 barycentric
// points, like the sphere's CapLoad), scaled to the exact total force.
std::vector<std::pair<int, Vec3>> OrganCapLoad(const Organ& o, const geometry::TriMesh& surface) {
  const double pressure = kPressForce / (std::numbers::pi * kCapRadius * kCapRadius);
  std::map<int, double> nodal;
  constexpr int kN = 6;
  for (const auto& t : surface.triangles) {
    const Vec3& a = surface.positions[t[0]];
    const Vec3& b = surface.positions[t[1]];
    const Vec3& c = surface.positions[t[2]];
    if (std::max({a.z(), b.z(), c.z()}) <= o.mid_z) continue;
    const double w = 0.5 * (b - a).cross(c - a).norm() / ((kN + 1) * (kN + 2) / 2);
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const double u = static_cast<double>(i) / kN, v = static_cast<double>(j) / kN;
        const Vec3 p = (1 - u - v) * a + u * b + v * c;
        if (p.z() <= o.mid_z || (p - o.top).head<2>().norm() > kCapRadius) continue;
        nodal[t[0]] -= pressure * w * (1 - u - v);
        nodal[t[1]] -= pressure * w * u;
        nodal[t[2]] -= pressure * w * v;
      }
  }
  double total = 0;
  for (const auto& [i, fz] : nodal) total -= fz;
  std::vector<std::pair<int, Vec3>> out;
  for (const auto& [i, fz] : nodal)
    out.emplace_back(i, Vec3(0, 0, total > 0 ? fz * kPressForce / total : 0.0));
  return out;
}

// Each marker's nearest vertex among `candidates` (indices into `positions`).
std::vector<int> OrganMarkerVertices(const Organ& o, const std::vector<Vec3>& positions,
                                     const std::vector<int>& candidates) {
  std::vector<Vec3> pts;
  for (int i : candidates) pts.push_back(positions[i]);
  std::vector<int> out;
  for (const Vec3& m : o.markers) out.push_back(candidates[Nearest(pts, m)]);
  return out;
}

std::vector<int> BoundaryVertices(const geometry::TetMesh& mesh) {
  const geometry::TriMesh b = geometry::BoundarySurface(mesh);
  std::vector<uint8_t> on(mesh.VertexCount(), 0);
  for (const auto& t : b.triangles)
    for (int v : t) on[v] = 1;
  std::vector<int> out;
  for (int i = 0; i < mesh.VertexCount(); ++i)
    if (on[i]) out.push_back(i);
  return out;
}

std::vector<int> Held(const std::vector<Vec3>& positions) {
  geometry::TriMesh points;
  points.positions = positions;
  return sim::SupportedVertices(points, sim::Support::kBottom);
}

Expected<Organ> LoadOrgan(const std::string& file) {
  auto scene = sim::LoadSceneByName(file);
  if (!scene.ok()) return scene.error();
  auto mesh = sim::BuildSceneMesh(scene->mesh);
  if (!mesh.ok()) return mesh.error();
  Organ o;
  o.scene = *scene;
  o.surface = mesh->surface;
  o.material.poisson = scene->poisson_ratio;
  o.material.young = 2 * scene->shear_modulus * (1 + scene->poisson_ratio);
  o.top = o.surface.positions[0];
  double lo = o.top.z();
  for (const Vec3& p : o.surface.positions) {
    lo = std::min(lo, p.z());
    if (p.z() > o.top.z()) o.top = p;
  }
  const double hi = o.top.z();
  o.mid_z = 0.5 * (lo + hi);
  // Ten markers on the upper surface from the top along the organ's long axis (x), 5 mm apart
  // in x: each is the upper-side surface vertex nearest in (x, y) to its station.
  for (int k = 0; k < 10; ++k) {
    const Vec3 station = o.top + Vec3(0.005 * k, 0, 0);
    int best = -1;
    for (int i = 0; i < o.surface.VertexCount(); ++i) {
      const Vec3& p = o.surface.positions[i];
      if (p.z() <= o.mid_z) continue;
      if (best < 0 ||
          (p - station).head<2>().norm() < (o.surface.positions[best] - station).head<2>().norm())
        best = i;
    }
    o.markers.push_back(o.surface.positions[best]);
  }
  return o;
}

}  // namespace

SceneOut RunOrgan(const Config& cfg, Progress& progress) {
  SceneOut out;
  out.scene = "kidney-palpation";
  out.scene_file = "kidney-palpation";
  std::tie(out.budget, out.scene_family) = SceneBudget(out.scene_file);
  out.checks = {
      {"kidney-palpation", "reduced", cfg.quick ? "contact table" : "contact table, FEM 8 mm"}};
  auto organ = LoadOrgan(out.scene_file);
  if (!organ.ok()) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, organ.error().message});
    for (int k = 0; k < (cfg.quick ? 3 : 6); ++k) progress.Step("organ (not loaded)");
    return out;
  }
  const Organ& o = *organ;
  // An FEM of the surface at a given tetrahedron size (m), statically pressed.
  struct Solved {
    geometry::TetMesh mesh;
    std::unique_ptr<tissue::FemModel> fem;
    std::vector<int> boundary;
    std::string note;
  };
  auto solve = [&](double size) -> Solved {
    Solved s;
    geometry::TetQuality q;
    auto mesh = geometry::Tetrahedralize(o.surface, {size, 0, 3.0}, &q);
    if (!mesh.ok()) {
      s.note = mesh.error().message;
      return s;
    }
    s.mesh = std::move(*mesh);
    auto fem = tissue::FemModel::Create(s.mesh, o.material, Held(s.mesh.positions));
    if (!fem.ok()) {
      s.note = fem.error().message;
      return s;
    }
    s.fem = std::make_unique<tissue::FemModel>(std::move(*fem));
    s.boundary = BoundaryVertices(s.mesh);
    const geometry::TriMesh boundary = geometry::BoundarySurface(s.mesh);
    for (const auto& [i, f] : OrganCapLoad(o, boundary)) s.fem->SetExternalForce(i, f);
    if (!s.fem->SolveStatic(30, 1e-8).converged) s.note = "static solve not converged";
    return s;
  };
  // Reference: the finest FEM; a rest point reads its nearest boundary vertex's displacement.
  const double ref_size = cfg.quick ? 0.008 : 0.004;
  Solved ref = solve(ref_size);
  if (!ref.fem) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, ref.note});
    return out;
  }
  std::vector<Vec3> ref_rest, ref_disp;
  for (int i : ref.boundary) {
    ref_rest.push_back(ref.mesh.positions[i]);
    ref_disp.push_back(ref.fem->positions()[i] - ref.mesh.positions[i]);
  }
  const Reference reference = [&](const Vec3& x) { return ref_disp[Nearest(ref_rest, x)]; };
  progress.Step("organ reference fem");

  for (double size :
       cfg.quick ? std::vector<double>{0.012} : std::vector<double>{0.012, 0.008, 0.006}) {
    Solved s = solve(size);
    Row row{"fem", out.scene,
            Num(1000 * size, 3) + " mm (" + std::to_string(s.mesh.TetCount()) + " tets)"};
    row.note = s.note;
    if (s.fem) {
      row.size = s.fem->VertexCount();
      Score(row, s.mesh.positions, s.fem->positions(),
            OrganMarkerVertices(o, s.mesh.positions, s.boundary), reference);
      row.time_us = TimeUs(cfg.quick ? 3 : 7, [&](int) { s.fem->StepImplicit(1e-3); });
    }
    out.rows.push_back(row);
    progress.Step("organ fem " + Num(1000 * size, 3) + " mm");
  }

  // Reduced: the contact table of the scene's own FEM size (and a finer one) on the scene's
  // display surface, every vertex above the held fifth a contact, the press's 1 cm footprint;
  // one press at the top.
  std::vector<int> all(o.surface.VertexCount()), reachable;
  for (int i = 0; i < o.surface.VertexCount(); ++i) all[i] = i;
  std::vector<uint8_t> held(o.surface.VertexCount(), 0);
  for (int v : Held(o.surface.positions)) held[v] = 1;
  for (int i : all)
    if (!held[i]) reachable.push_back(i);
  const int top = Nearest(o.surface.positions, o.top);
  const std::vector<int> markers = OrganMarkerVertices(o, o.surface.positions, all);
  for (double size : cfg.quick ? std::vector<double>{0.012} : std::vector<double>{0.008, 0.006}) {
    Row row{"reduced", out.scene,
            "contact table, FEM " + Num(1000 * size, 3) + " mm, " +
                std::to_string(o.surface.VertexCount()) + " vertices"};
    const auto t0 = Clock::now();
    auto mesh = geometry::Tetrahedralize(o.surface, {size, 0, 3.0});
    auto response =
        mesh.ok() ? tissue::FemStaticResponse::Create(*mesh, o.material, Held(mesh->positions))
                  : Expected<tissue::FemStaticResponse>(mesh.error());
    tissue::ContactResponseParams cp;
    cp.footprint_radius = kCapRadius;
    auto table = response.ok()
                     ? tissue::PrecomputeContactResponse(*response, o.surface, reachable, cp)
                     : Expected<tissue::ContactResponse>(response.error());
    const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
    const int64_t bytes = table.ok() ? table->Bytes() : 0;
    auto model = table.ok() ? tissue::ReducedContactModel::Create(
                                  std::make_shared<tissue::ContactResponse>(std::move(*table)),
                                  o.surface.positions, o.scene.region.reduced.max_force)
                            : Expected<tissue::ReducedContactModel>(table.error());
    if (!model.ok()) {
      row.note = model.error().message;
      out.rows.push_back(row);
      progress.Step("organ reduced");
      continue;
    }
    row.size = model->VertexCount();
    row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
      model->Press(top, Vec3(0, 0, -kPressForce * ((i % 2) ? 1.0 : 0.97)));
    });
    model->Press(top, Vec3(0, 0, -kPressForce));
    Score(row, o.surface.positions, model->positions(), markers, reference);
    row.note = "precomputed in " + Num(precompute_s, 2) + " s (tetrahedra included); " +
               std::to_string(reachable.size()) + " contacts, " + Num(bytes / 1048576.0, 3) + " MB";
    out.rows.push_back(row);
    progress.Step("organ reduced " + Num(1000 * size, 3) + " mm");
  }
  return out;
}

}  // namespace vsurg::bench::study
