// The organ scenes of the speed-against-error study (bench/speed_vs_error.cpp): the kidney of
// scenes/kidney-palpation.json (a surface file read by assimp, tetrahedralised by CGAL), resting
// on its lower fifth and pressed on its top by 0.2 N spread over a 1 cm cap, every model against
// the finest FEM of the same surface; and organ-surface-twist (below).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>

#include "bench/study/study.h"
#include "common/geometry/distances.h"
#include "common/geometry/mesh.h"
#include "common/geometry/tet_generators.h"
#include "common/geometry/tetrahedralize.h"
#include "common/sim/scene.h"
#include "common/tissue/coil_calibration.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/fem.h"
#include "common/tissue/reduced.h"

namespace vsurg::bench::study {
namespace {

struct Organ {
  sim::Scene scene;
  geometry::TriMesh surface;  // the display surface, m
  tissue::FemParams material;
  Vec3 top = Vec3::Zero();          // the highest surface point: the press's centre
  Vec3 top_normal = Vec3::UnitZ();  // the display's outward normal there
  double mid_z = 0;                 // halfway up: only the upper side is loaded and marked
  std::vector<Vec3> markers;        // rest points on the upper surface
};

// The press: 0.2 N straight down spread over the 1 cm footprint around the top, on a FEM's
// boundary by the rule the contact table uses for each of its contacts (tissue::FootprintWeights:
// the disc perpendicular to the top's normal, lumped by area), so the FEM rows, the reference and
// the table carry the same load and differ only by their discretisation.
std::vector<std::pair<int, Vec3>> OrganCapLoad(const Organ& o, const geometry::TriMesh& boundary) {
  std::map<int, double> share;  // a vertex appears once per sample that reaches it: summed
  for (const auto& [i, w] : tissue::FootprintWeights(boundary, o.top, o.top_normal, kCapRadius))
    share[i] += w;
  std::vector<std::pair<int, Vec3>> out;
  for (const auto& [i, w] : share) out.emplace_back(i, Vec3(0, 0, -kPressForce * w));
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
  {
    geometry::TriMesh normals = o.surface;
    geometry::ComputeVertexNormals(normals);
    o.top_normal = normals.normals[Nearest(o.surface.positions, o.top)];
  }
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

// An FEM of the organ's surface at a given tetrahedron size (m), statically pressed.
struct SolvedOrgan {
  geometry::TetMesh mesh;
  std::unique_ptr<tissue::FemModel> fem;
  std::vector<int> boundary;
  std::string note;
};

SolvedOrgan SolveOrgan(const Organ& o, double size) {
  SolvedOrgan s;
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
}

// The FEM itself at coarser sizes: static under the press for the error, implicit steps timed.
void OrganFemRows(const Config& cfg, const Organ& o, const Reference& reference, SceneOut& out,
                  Progress& progress) {
  for (double size :
       cfg.quick ? std::vector<double>{0.012} : std::vector<double>{0.012, 0.008, 0.006}) {
    SolvedOrgan s = SolveOrgan(o, size);
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
}

void OrganReducedRows(const Config& cfg, const Organ& o, const Reference& reference, SceneOut& out,
                      Progress& progress) {
  // Reduced: the contact table of the scene's own FEM size (6 mm), a coarser one, and one on the
  // reference's own 4 mm mesh (what is left there is the table's linearity and embedding), on the
  // scene's display surface, every vertex above the held fifth a contact, the press's 1 cm
  // footprint; one press at the top.
  std::vector<int> all(o.surface.VertexCount()), reachable;
  for (int i = 0; i < o.surface.VertexCount(); ++i) all[i] = i;
  std::vector<uint8_t> held(o.surface.VertexCount(), 0);
  for (int v : Held(o.surface.positions)) held[v] = 1;
  for (int i : all)
    if (!held[i]) reachable.push_back(i);
  const int top = Nearest(o.surface.positions, o.top);
  const std::vector<int> markers = OrganMarkerVertices(o, o.surface.positions, all);
  for (double size :
       cfg.quick ? std::vector<double>{0.012} : std::vector<double>{0.008, 0.006, 0.004}) {
    Row row{"reduced", out.scene,
            "contact table, FEM " + Num(1000 * size, 3) + " mm, " +
                std::to_string(o.surface.VertexCount()) + " vertices"};
    const auto t0 = Clock::now();
    auto mesh = geometry::Tetrahedralize(o.surface, {size, 0, 3.0});
    auto response =
        mesh.ok() ? tissue::FemStaticResponse::Create(*mesh, o.material, Held(mesh->positions))
                  : Expected<tissue::FemStaticResponse>(mesh.error());
    ContactTableRow(cfg, response, o.surface, reachable, o.scene.region.reduced.max_force, top,
                    markers, reference, t0, row);
    out.rows.push_back(row);
    progress.Step("organ reduced " + Num(1000 * size, 3) + " mm");
  }
}

}  // namespace

SceneOut RunOrgan(const Config& cfg, Progress& progress) {
  SceneOut out = NewSceneOut("kidney-palpation", "kidney-palpation");
  out.checks = {
      {"kidney-palpation", "reduced", cfg.quick ? "contact table" : "contact table, FEM 6 mm"}};
  auto organ = LoadOrgan(out.scene_file);
  if (!organ.ok()) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, organ.error().message});
    for (int k = 0; k < (cfg.quick ? 3 : 6); ++k) progress.Step("organ (not loaded)");
    return out;
  }
  const Organ& o = *organ;
  // Reference: the finest FEM; a rest point reads its nearest boundary vertex's displacement.
  const double ref_size = cfg.quick ? 0.008 : 0.004;
  SolvedOrgan ref = SolveOrgan(o, ref_size);
  if (!ref.fem) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, ref.note});
    return out;
  }
  std::vector<Vec3> ref_disp(ref.mesh.positions.size());
  for (size_t i = 0; i < ref_disp.size(); ++i)
    ref_disp[i] = ref.fem->positions()[i] - ref.mesh.positions[i];
  const Reference reference = InterpolatedReference(ref.mesh, std::move(ref_disp));
  progress.Step("organ reference fem");

  OrganFemRows(cfg, o, reference, out, progress);
  OrganReducedRows(cfg, o, reference, out, progress);
  return out;
}

}  // namespace vsurg::bench::study

namespace vsurg::bench::study {

namespace {

// What the organ twist's rows share: the scene's display surface, the grasp at its top, the
// material, the jaws, the task's twist, the reference field's torque for it, and the markers.
struct TwistSetup {
  const sim::Scene* scene = nullptr;
  const geometry::TriMesh* surface = nullptr;
  double radius = 0;
  int grasp = 0;
  Vec3 grasp_point = Vec3::Zero();
  double target = 0;  // rad
  tissue::FemParams material;
  tissue::SurfaceTwistParams jaws;
  double ref_torque = 0;  // N·m: the target at the jaws on the reference
  std::vector<int> markers;
};

// The twist field of a grasp at the top of an FEM ball of `cells`, as the scene precomputes it.
Expected<tissue::TwistField> TwistFieldOf(const TwistSetup& t, int cells) {
  auto ball = geometry::MakeTetBall({t.radius, cells});
  if (!ball.ok()) return ball.error();
  geometry::TriMesh points;
  points.positions = ball->positions;
  auto response = tissue::FemStaticResponse::Create(
      *ball, t.material, sim::SupportedVertices(points, sim::Support::kBottom));
  if (!response.ok()) return response.error();
  auto table = tissue::PrecomputeSurfaceTwist(*response, *t.surface, {t.grasp}, t.jaws);
  if (!table.ok()) return table.error();
  return tissue::SurfaceTwistField(*table, t.grasp, t.surface->positions);
}

// The scene's reduced surface twist at coarser FEMs, at the reference's torque.
void SurfaceTwistReducedRows(const Config& cfg, const TwistSetup& t, const Reference& reference,
                             SceneOut& out, Progress& progress) {
  const geometry::TriMesh& surface = *t.surface;
  const int scene_cells = t.scene->region.reduced.fem_cells;
  const double ref_torque = t.ref_torque;
  const tissue::SurfaceTwistParams& jaws = t.jaws;
  const std::vector<int>& markers = t.markers;
  std::vector<int> levels = {12, 16, 20};
  if (std::find(levels.begin(), levels.end(), scene_cells) == levels.end())
    levels.push_back(scene_cells);
  for (int cells : cfg.quick ? std::vector<int>{12} : levels) {
    Row row{"reduced", out.scene,
            "surface twist, FEM cells " + std::to_string(cells) + " (jaws " +
                Num(1000 * jaws.jaw_radius) + " mm, " + Num(ref_torque, 3) + " N·m)"};
    const auto t0 = Clock::now();
    auto f = TwistFieldOf(t, cells);
    const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
    auto model = f.ok() ? tissue::ReducedTwistModel::Create(*f, surface.positions, std::numbers::pi)
                        : Expected<tissue::ReducedTwistModel>(f.error());
    if (model.ok()) {
      row.size = model->VertexCount();
      row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
        model->Update(ref_torque * (0.5 + 0.5 * ((i % 2) ? 1.0 : 0.97)));
      });
      model->Update(ref_torque);
      Score(row, surface.positions, model->positions(), markers, reference);
      row.note = "one grasp's field in " + Num(precompute_s, 2) +
                 " s (the scene precomputes one per reachable vertex)";
    } else {
      row.note = model.error().message;
    }
    out.rows.push_back(row);
    progress.Step("organ twist reduced " + std::to_string(cells));
  }
}

// The coil: the paper's surface mode with the parameters this scene had, and its two-parameter
// and per-ring fits (F_t held) to the reference's twist against the geodesic distance from the
// grasp at eight torques up to 30°, each sample weighted by its squared lever arm (the fit
// matches displacements).
void SurfaceTwistCoilRows(const Config& cfg, const TwistSetup& setup,
                          const tissue::TwistField& field, const Reference& reference,
                          SceneOut& out, Progress& progress) {
  const geometry::TriMesh& surface = *setup.surface;
  const Vec3& grasp_point = setup.grasp_point;
  const double target = setup.target, ref_torque = setup.ref_torque;
  const std::vector<int>& markers = setup.markers;
  tissue::CoilSpringParams params;
  params.core_radius = 0.004, params.thickness = 0.004, params.width = 0.01, params.coils = 10;
  params.modulus = 1e8, params.max_force = 0.1, params.friction = 1.25;
  auto coil = tissue::CoilSpringModel::Create(params);
  auto at = geometry::ClosestSurfacePoint(surface, grasp_point);
  auto rho = at.ok() ? geometry::GeodesicDistances(surface, *at, geometry::GeodesicMethod::kHeat)
                     : Expected<std::vector<double>>(at.error());
  if (!coil.ok() || !rho.ok()) return;
  const double torque = coil->Inverse(target).torque;
  tissue::CalibrationReference cref;
  const double coil_reach = params.core_radius + params.coils * params.thickness;
  for (int k = 1; k <= 8; ++k) {
    const double s = k / 8.0;
    cref.curve_torque.push_back(s * torque);
    cref.curve_twist.push_back(s * target);
    tissue::TwistProfile p{s * torque, {}, {}, {}};
    for (size_t v = 0; v < rho->size(); ++v)
      if ((*rho)[v] <= coil_reach) {
        p.rho.push_back((*rho)[v]);
        p.twist.push_back(s * ref_torque * field.angle[v]);
        p.weight.push_back((surface.positions[v] - grasp_point).head<2>().squaredNorm());
      }
    cref.profiles.push_back(std::move(p));
  }
  struct Variant {
    std::string name, setting;
    Expected<tissue::CoilSpringParams> params;
  };
  std::vector<Variant> variants = {{"coil-surface", "the scene's former parameters", params}};
  {
    auto paper = tissue::CalibrateTwoParameter(params, cref);
    variants.push_back({"coil-paper", "two-parameter fit",
                        paper.ok() ? Expected<tissue::CoilSpringParams>(paper->params)
                                   : Expected<tissue::CoilSpringParams>(paper.error())});
    auto ring = tissue::CalibratePerRingAtCapacity(params, cref);
    variants.push_back({"coil-per-ring", "per-ring fit, F_t held",
                        ring.ok() ? Expected<tissue::CoilSpringParams>(ring->params)
                                  : Expected<tissue::CoilSpringParams>(ring.error())});
  }
  for (const Variant& v : variants) {
    auto model = v.params.ok() ? tissue::CoilSpringModel::Create(*v.params)
                               : Expected<tissue::CoilSpringModel>(v.params.error());
    const double t = model.ok() ? model->Inverse(target).torque : 0.0;
    Row row{v.name, out.scene,
            v.setting + ", surface mode (" + Num(t, 3) + " N·m for " +
                Num(target * 180 / std::numbers::pi, 3) + "°)"};
    auto deformer = model.ok() ? tissue::CoilDeformer::CreateForSurface(
                                     *model, surface, *at, geometry::GeodesicMethod::kHeat)
                               : Expected<tissue::CoilDeformer>(model.error());
    if (deformer.ok()) {
      row.size = params.coils;
      row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
        deformer->Update(t * (0.5 + 0.5 * ((i % 2) ? 1.0 : 0.97)));
      });
      deformer->Update(t);
      Score(row, surface.positions, deformer->positions(), markers, reference);
    } else {
      row.note = deformer.error().message;
    }
    out.rows.push_back(row);
    progress.Step("organ twist " + v.name);
  }
}

}  // namespace

// organ-surface-twist: forceps grasp the top of the 5 cm ball (resting on its lower fifth) and
// twist it about the surface normal to the task's 30°. No closed form exists; the reference is
// the finest FEM's static twist field for a torque on the jaws' disc (reduced.h, 4.: the same
// rule the scene's own model is precomputed with), turned exactly so 30° does not inflate it.
// Rows: the scene's reduced surface twist at coarser FEMs (at the reference's torque: their
// stiffness error counts too), and the paper's coil in surface mode with the parameters this
// scene had (and its two fits), each at its own torque for 30° (the shapes compared at the same
// grasp twist, as the limbs' effective modulus does).
SceneOut RunSurfaceTwist(const Config& cfg, Progress& progress) {
  SceneOut out = NewSceneOut("organ-twist", "organ-surface-twist");
  auto scene = sim::LoadSceneByName(out.scene_file);
  const int scene_cells = scene.ok() ? scene->region.reduced.fem_cells : 0;
  out.checks = {{"organ-surface-twist", "reduced",
                 cfg.quick ? "surface twist"
                           : "surface twist, FEM cells " + std::to_string(scene_cells) + " "}};
  auto display =
      scene.ok() ? sim::BuildSceneMesh(scene->mesh) : Expected<sim::SceneMesh>(scene.error());
  if (!display.ok() || scene->mesh.kind != sim::MeshKind::kSphere) {
    out.rows.push_back({"reduced", out.scene, "scene parameters", 0, kInf, kInf, 0,
                        display.ok() ? "the scene is not a sphere" : display.error().message});
    for (int k = 0; k < (cfg.quick ? 5 : 7); ++k) progress.Step("organ twist (not loaded)");
    return out;
  }
  const geometry::TriMesh& surface = display->surface;
  TwistSetup t;
  t.scene = &*scene;
  t.surface = &surface;
  t.radius = scene->mesh.radius;
  t.grasp = Nearest(surface.positions, Vec3(0, 0, t.radius));
  t.grasp_point = surface.positions[t.grasp];
  t.target = scene->task.target;
  t.material.poisson = scene->poisson_ratio;
  t.material.young = 2 * scene->shear_modulus * (1 + scene->poisson_ratio);
  t.jaws.jaw_radius = scene->region.reduced.jaw_radius;
  // The reference: 28 cells (a 20-cell table is 1.85% from it where a 16-cell one is 6.7%).
  auto field = TwistFieldOf(t, cfg.quick ? 12 : 28);
  if (!field.ok()) {
    out.rows.push_back({"fem", out.scene, "reference", 0, kInf, kInf, 0, field.error().message});
    return out;
  }
  t.ref_torque = t.target / field->grasp_compliance;  // N·m: 30° at the jaws
  auto ref_model = tissue::ReducedTwistModel::Create(*field, surface.positions, std::numbers::pi);
  if (!ref_model.ok()) return out;
  ref_model->Update(t.ref_torque);
  std::vector<Vec3> ref_disp(surface.positions.size());
  for (size_t i = 0; i < ref_disp.size(); ++i)
    ref_disp[i] = ref_model->positions()[i] - surface.positions[i];
  const Reference reference = [&](const Vec3& x) {
    return ref_disp[Nearest(surface.positions, x)];
  };
  // Markers: along a meridian from the grasp, as on the pressed sphere.
  for (int k = 0; k < 10; ++k) {
    const double a = (5.0 * k) * std::numbers::pi / 180.0;
    t.markers.push_back(
        Nearest(surface.positions, Vec3(t.radius * std::sin(a), 0.0, t.radius * std::cos(a))));
  }
  progress.Step("organ twist reference");

  SurfaceTwistReducedRows(cfg, t, reference, out, progress);
  SurfaceTwistCoilRows(cfg, t, *field, reference, out, progress);
  return out;
}

}  // namespace vsurg::bench::study
