// The study's load axis for the limb (DESIGN.md "Speed against error"): the forearm of
// scenes/arm-torsion-reduced.json (its FEM cylinder, its display surface, its material) under a
// hyperelastic law, the neo-Hookean one and the exponential one (b = 5), turned at the grasp to
// 22.5°, 45°, 67.5° and 90° (twice the task's 45°). The reference at each angle is the hyperelastic
// FEM's static state, the grasp held rigidly there (tissue/twist_table.h, SolveTwisted). Rated
// against it: the coil model of scenes/arm-torsion.json and the linear twist field
// arm-torsion-reduced runs (each driven at the torque its own law gives for that angle), and the
// table of load levels (levels every 15°, so 22.5° and 67.5° fall between two). Each row's note
// gives the torque it answers against the FEM's: what the trainee's hand feels, and its error is
// the larger of the markers' RMS and the torque's relative error.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "bench/study/study.h"
#include "common/geometry/distances.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/tet_generators.h"
#include "common/sim/scene.h"
#include "common/tissue/coil_deformation.h"
#include "common/tissue/fem.h"
#include "common/tissue/hyperelastic.h"
#include "common/tissue/reduced.h"
#include "common/tissue/twist_table.h"

namespace vsurg::bench::study {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

std::vector<double> Angles(const Config& cfg) {  // rad at the grasp
  return cfg.quick ? std::vector<double>{45 * kDeg, 90 * kDeg}
                   : std::vector<double>{22.5 * kDeg, 45 * kDeg, 67.5 * kDeg, 90 * kDeg};
}

struct Law {
  std::string name;
  double stiffening;
};

// What every law's rows share: the scene, its FEM, its display surface and markers, the linear
// model.
struct TwistSetting {
  sim::Scene scene;
  std::vector<Vec3> display;
  std::vector<int> markers;
  tissue::TwistTableInputs inputs;  // the law set per law
};
struct ArmSetting : TwistSetting {
  geometry::TetCylinder cylinder;
};

Expected<ArmSetting> Setting(const Config& cfg) {
  auto scene = sim::LoadSceneByName("arm-torsion-reduced");
  if (!scene.ok()) return scene.error();
  const geometry::LimbParams& limb = scene->mesh.limb;
  const int rings = cfg.quick ? 2 : scene->region.reduced.fem_rings;
  auto cylinder = geometry::MakeTetCylinder(
      geometry::TorsionCylinder(limb.length, limb.radius_proximal, limb.radius_distal, rings));
  if (!cylinder.ok()) return cylinder.error();
  auto surface = geometry::MakeLimb(limb);
  if (!surface.ok()) return surface.error();
  ArmSetting s;
  s.scene = *scene;
  s.cylinder = *cylinder;
  s.display = surface->surface.positions;
  s.markers = LimbMarkerVertices(
      s.display, {limb.length, limb.radius_proximal, limb.radius_distal, scene->shear_modulus});
  s.inputs.mesh = cylinder->mesh;
  s.inputs.material.poisson = scene->poisson_ratio;
  s.inputs.material.young = 2 * scene->shear_modulus * (1 + scene->poisson_ratio);
  s.inputs.fixed = cylinder->base;
  s.inputs.face = cylinder->tip;
  s.inputs.display = s.display;
  s.inputs.max_twist = std::numbers::pi / 2;
  s.inputs.levels = scene->region.reduced.levels;
  return s;
}

// The scene's linear model: the corotational FEM's twist field per unit torque.
Expected<tissue::ReducedTwistModel> LinearModel(const ArmSetting& s) {
  tissue::FemParams material;
  material.young = s.inputs.material.young;
  material.poisson = s.inputs.material.poisson;
  auto fem = tissue::FemStaticResponse::Create(s.cylinder.mesh, material, s.cylinder.base);
  if (!fem.ok()) return fem.error();
  auto field = tissue::PrecomputeTwistField(*fem, s.cylinder.tip, s.cylinder.tip_area, Vec3::Zero(),
                                            Vec3::UnitZ(), s.display);
  if (!field.ok()) return field.error();
  return tissue::ReducedTwistModel::Create(*field, s.display, std::numbers::pi);
}

// What a row drives: the torque its own law answers at a twist, an update to a torque, and the
// surface it leaves.
struct Driven {
  std::function<double(double)> torque_at;
  std::function<void(double)> update;
  std::function<const std::vector<Vec3>&()> positions;
  int size = 0;
};

// A model's row at one angle: driven at the torque its own law answers there, timed, scored.
Row RateAt(const Driven& model, const std::string& name, const std::string& setting,
           const std::string& scene, double twist, const tissue::TwistedState& ref,
           const TwistSetting& s, const Config& cfg) {
  Row row{name, scene, setting};
  const double torque = model.torque_at(twist);
  row.size = model.size;
  row.time_us = TimeUs(cfg.repeats * 5,
                       [&](int i) { model.update(torque * (0.5 + 0.5 * ((i % 2) ? 1.0 : 0.97))); });
  model.update(torque);
  std::vector<Vec3> u(ref.positions.size());
  for (size_t v = 0; v < u.size(); ++v) u[v] = ref.positions[v] - s.inputs.mesh.positions[v];
  Score(row, s.display, model.positions(), s.markers,
        InterpolatedReference(s.inputs.mesh, std::move(u)));
  // The hand feels the torque: a row's error is the larger of its markers' RMS and its torque's.
  const double torque_error = (torque - ref.torque) / ref.torque;
  row.note = "markers " + Num(100 * row.rms, 3) + "% RMS; torque " + Num(torque, 4) +
             " N·m against the FEM's " + Num(ref.torque, 4) + " (" + Num(100 * torque_error, 2) +
             "%)";
  if (std::isfinite(row.rms)) {
    row.rms = std::max(row.rms, std::abs(torque_error));
    row.max = std::max(row.max, std::abs(torque_error));
  }
  return row;
}

Driven Drive(tissue::ReducedTwistModel& m) {
  return {[&m](double twist) { return m.TorqueAt(twist).torque; },
          [&m](double torque) { m.Update(torque); },
          [&m]() -> const std::vector<Vec3>& { return m.positions(); }, m.VertexCount()};
}

// scenes/arm-torsion.json's coil model on the same surface: its inverse gives the torque for the
// twist, its deformer the surface (the grasp at the wrist).
struct Coil {
  tissue::CoilSpringModel model;
  tissue::CoilDeformer deformer;
};
Expected<Coil> CoilModel(const ArmSetting& s) {
  auto file = sim::LoadSceneByName("arm-torsion");
  if (!file.ok()) return file.error();
  auto limb = geometry::MakeLimb(file->mesh.limb);
  if (!limb.ok()) return limb.error();
  if (limb->surface.positions.size() != s.display.size())
    return InvalidArgument("arm-torsion", "its limb is not the reduced arm's surface");
  auto model = tissue::CoilSpringModel::Create(file->region.coil);
  if (!model.ok()) return model.error();
  auto deformer = tissue::CoilDeformer::CreateForLimb(
      *model, s.display, limb->centreline, geometry::ArcLengths(limb->centreline).back());
  if (!deformer.ok()) return deformer.error();
  return Coil{std::move(*model), std::move(*deformer)};
}

Driven Drive(Coil& c) {
  return {[&c](double twist) { return c.model.Inverse(twist).torque; },
          [&c](double torque) { c.deformer.Update(torque); },
          [&c]() -> const std::vector<Vec3>& { return c.deformer.positions(); },
          static_cast<int>(c.deformer.positions().size())};
}

}  // namespace

int ArmLawSteps(const Config& cfg) {
  return 1 + 2 * (1 + static_cast<int>(Angles(cfg).size()));
}

std::vector<SceneOut> RunArmLaws(const Config& cfg, Progress& progress) {
  std::vector<SceneOut> out;
  auto setting = Setting(cfg);
  auto linear =
      setting.ok() ? LinearModel(*setting) : Expected<tissue::ReducedTwistModel>(setting.error());
  auto coil = setting.ok() ? CoilModel(*setting) : Expected<Coil>(setting.error());
  progress.Step("arm laws: the linear field and the coil");
  for (const Law& law : {Law{"neo-Hookean", 0.0}, Law{"exponential b = 5", 5.0}}) {
    tissue::TwistTableInputs in = setting.ok() ? setting->inputs : tissue::TwistTableInputs{};
    in.material.stiffening = law.stiffening;
    const auto t0 = Clock::now();
    auto table = setting.ok() ? tissue::PrecomputeTwistTable(in)
                              : Expected<tissue::TwistTable>(setting.error());
    const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
    auto model = table.ok()
                     ? tissue::ReducedTwistModel::Create(*table, in.display, std::numbers::pi)
                     : Expected<tissue::ReducedTwistModel>(table.error());
    progress.Step("arm laws: " + law.name + " table");
    tissue::TwistedState last;  // each angle solved from the one before
    last.positions = in.mesh.positions;
    for (const double twist : Angles(cfg)) {
      const std::string scene = "arm " + law.name + " " + Num(twist / kDeg, 3) + "°";
      SceneOut s = NewSceneOut(scene, "arm-torsion-reduced");
      auto ref = setting.ok() ? tissue::SolveTwisted(in, twist, &last, 2)
                              : Expected<tissue::TwistedState>(setting.error());
      if (!ref.ok() || !linear.ok() || !model.ok()) {
        const std::string why = !ref.ok()      ? ref.error().message
                                : !linear.ok() ? linear.error().message
                                               : model.error().message;
        s.rows.push_back(Row{"reduced", scene, "", 0, kInf, kInf, 0, why});
      } else {
        last = *ref;
        if (coil.ok())
          s.rows.push_back(RateAt(Drive(*coil), "coil-scene", "arm-torsion's coil", scene, twist,
                                  *ref, *setting, cfg));
        s.rows.push_back(RateAt(Drive(*linear), "reduced", "linear twist field", scene, twist, *ref,
                                *setting, cfg));
        Row row = RateAt(Drive(*model), "reduced-table",
                         std::to_string(in.levels) + " levels a side (" +
                             std::to_string(in.mesh.TetCount()) + " tets)",
                         scene, twist, *ref, *setting, cfg);
        row.note += "; built in " + Num(precompute_s, 3) + " s";
        s.rows.push_back(row);
      }
      out.push_back(std::move(s));
      progress.Step(scene);
    }
  }
  return out;
}

namespace {

std::vector<double> BallLoads(const Config& cfg) {  // N on the top cap
  return cfg.quick ? std::vector<double>{0.2, 2.0} : std::vector<double>{0.2, 2.0, 5.0, 10.0};
}

// The ball under the press of `force` (N) and the law (b), statically, from `start` (its
// positions at a smaller press): the hyperelastic FEM's positions.
Expected<std::vector<Vec3>> PressedBall(const geometry::TetMesh& mesh, double stiffening,
                                        double force, const std::vector<Vec3>& start) {
  const tissue::FemParams tissue = BallTissue();
  auto fem = tissue::HyperelasticFem::Create(
      mesh, {tissue.young, tissue.poisson, stiffening, tissue.nodal_volume});
  if (!fem.ok()) return fem.error();
  fem->SetPositions(start);
  for (int v : BottomCap(mesh.positions))
    for (int a = 0; a < 3; ++a) fem->Hold(v, a, mesh.positions[v][a]);
  for (const auto& [i, f] : CapLoad(geometry::BoundarySurface(mesh), force))
    fem->SetExternalForce(i, f);
  const tissue::HyperelasticSolve solve = fem->SolveStatic(60, 1e-9);
  if (!solve.converged)
    return Error{ErrorCode::kNumerical, "the press of " + Num(force, 3) + " N did not converge",
                 "fem"};
  return fem->positions();
}

// N: the ball's tables' capacity, past the study's largest press (10 N).
constexpr double kBallTableCapacity = 20.0;

// A contact table the ball's scenes run (the press at the pole), from the linear FEM at `cells`.
struct BallTable {
  std::vector<Vec3> display;
  int pole = 0;
  int cells = 0;
  bool rotation = true;  // the table's rotation correction (reduced.h, 3.)
  std::optional<tissue::ReducedContactModel> model;
  std::string why;  // when it could not be built
};

BallTable BuildBallTable(int cells) {
  BallTable m;
  m.cells = cells;
  auto display = geometry::MakeSubdividedSphere({kBallRadius, 4});
  if (!display.ok()) {
    m.why = display.error().message;
    return m;
  }
  m.display = display->positions;
  m.pole = Nearest(m.display, Vec3(0, 0, kBallRadius));
  std::vector<uint8_t> fixed(m.display.size(), 0);
  for (int i : BottomCap(m.display)) fixed[i] = 1;
  std::vector<int> reachable;
  for (int i = 0; i < display->VertexCount(); ++i)
    if (!fixed[i]) reachable.push_back(i);
  auto mesh = geometry::MakeTetBall({kBallRadius, cells});
  if (!mesh.ok()) {
    m.why = mesh.error().message;
    return m;
  }
  auto response =
      tissue::FemStaticResponse::Create(*mesh, BallTissue(), BottomCap(mesh->positions));
  tissue::ContactResponseParams cp;
  cp.footprint_radius = kCapRadius;
  auto table = response.ok() ? tissue::PrecomputeContactResponse(*response, *display, reachable, cp)
                             : Expected<tissue::ContactResponse>(response.error());
  auto model = table.ok() ? tissue::ReducedContactModel::Create(
                                std::make_shared<tissue::ContactResponse>(std::move(*table)),
                                m.display, kBallTableCapacity)
                          : Expected<tissue::ReducedContactModel>(table.error());
  if (!model.ok()) {
    m.why = model.error().message;
    return m;
  }
  m.model = std::move(*model);
  return m;
}

// The same table without its rotation correction (the displacement responses alone).
BallTable WithoutRotation(const BallTable& t) {
  BallTable m;
  m.display = t.display, m.pole = t.pole, m.cells = t.cells, m.rotation = false, m.why = t.why;
  if (!t.model) return m;
  auto response = std::make_shared<tissue::ContactResponse>(t.model->response());
  response->w.clear();
  auto model =
      tissue::ReducedContactModel::Create(std::move(response), m.display, kBallTableCapacity);
  if (model.ok())
    m.model = std::move(*model);
  else
    m.why = model.error().message;
  return m;
}

// The scene's table (8 cells) and, in the whole study, one on the reference's own mesh, each
// also without the rotation correction: what is left there is the linear table itself against the
// law, not its mesh, and what its rotation correction does at a deep press.
std::vector<BallTable> BuildBallTables(const Config& cfg, int ref_cells) {
  std::vector<BallTable> out;
  out.push_back(BuildBallTable(cfg.quick ? 4 : 8));
  if (cfg.quick) return out;
  out.push_back(WithoutRotation(out.back()));
  out.push_back(BuildBallTable(ref_cells));
  out.push_back(WithoutRotation(out.back()));
  return out;
}

Row BallTableRow(const Config& cfg, BallTable& t, const std::string& scene, double force,
                 const Reference& reference) {
  Row row{"reduced", scene,
          "contact table, FEM cells " + std::to_string(t.cells) +
              (t.rotation ? "" : ", without the rotation correction")};
  if (!t.model) {
    row.rms = row.max = kInf;
    row.note = t.why;
    return row;
  }
  row.size = t.model->VertexCount();
  row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
    t.model->Press(t.pole, Vec3(0, 0, -force * ((i % 2) ? 1.0 : 0.97)));
  });
  t.model->Press(t.pole, Vec3(0, 0, -force));
  Score(row, t.display, t.model->positions(), SphereMarkerVertices(t.display), reference);
  row.note =
      "the pole " + Num(1e3 * reference(Vec3(0, 0, kBallRadius)).norm(), 3) + " mm down in the FEM";
  return row;
}

}  // namespace

int BallLawSteps(const Config& cfg) {
  return 1 + 2 * static_cast<int>(BallLoads(cfg).size());
}

// The ball of the sphere scenes pressed by 0.2 N (the study's press) up to 10 N (about 15 mm at
// the pole) against the hyperelastic FEM at 12 cells (6 quick), each law: the contact table
// (the scene's 8 cells, and one on the reference's mesh) and the corotational FEM on the
// reference's mesh (the linear law itself).
std::vector<SceneOut> RunBallLaws(const Config& cfg, Progress& progress) {
  std::vector<SceneOut> out;
  const int ref_cells = cfg.quick ? 6 : 12;
  std::vector<BallTable> tables = BuildBallTables(cfg, ref_cells);
  auto ref_mesh = geometry::MakeTetBall({kBallRadius, ref_cells});
  progress.Step("ball laws: the contact table");
  for (const Law& law : {Law{"neo-Hookean", 0.0}, Law{"exponential b = 5", 5.0}}) {
    std::vector<Vec3> last = ref_mesh.ok() ? ref_mesh->positions : std::vector<Vec3>{};
    auto corotational = ref_mesh.ok() ? tissue::FemModel::Create(*ref_mesh, BallTissue(),
                                                                 BottomCap(ref_mesh->positions))
                                      : Expected<tissue::FemModel>(ref_mesh.error());
    for (const double force : BallLoads(cfg)) {
      const std::string scene = "ball " + law.name + " " + Num(force, 3) + " N";
      SceneOut s = NewSceneOut(scene, "sphere-palpation-1024");
      auto ref = ref_mesh.ok() ? PressedBall(*ref_mesh, law.stiffening, force, last)
                               : Expected<std::vector<Vec3>>(ref_mesh.error());
      if (!ref.ok()) {
        s.rows.push_back(Row{"reduced", scene, "", 0, kInf, kInf, 0, ref.error().message});
        out.push_back(std::move(s));
        progress.Step(scene);
        continue;
      }
      last = *ref;
      std::vector<Vec3> u(last.size());
      for (size_t v = 0; v < u.size(); ++v) u[v] = last[v] - ref_mesh->positions[v];
      const Reference reference = InterpolatedReference(*ref_mesh, std::move(u));
      for (BallTable& t : tables) s.rows.push_back(BallTableRow(cfg, t, scene, force, reference));
      // The linear law on the same mesh: how far the law alone moves the answer (solved from
      // the last press's state, as the reference is).
      Row linear{"fem", scene, "corotational, cells " + std::to_string(ref_cells)};
      if (corotational.ok()) {
        for (const auto& [i, f] : CapLoad(geometry::BoundarySurface(*ref_mesh), force))
          corotational->SetExternalForce(i, f);
        const auto t0 = Clock::now();
        const tissue::FemStaticStats st = corotational->SolveStatic(60, 1e-8);
        linear.time_us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
        linear.size = corotational->VertexCount();
        Score(linear, ref_mesh->positions, corotational->positions(),
              SphereMarkerVertices(ref_mesh->positions), reference);
        linear.note =
            "a static solve, " + std::to_string(st.iterations) + " Newton steps" +
            (st.converged ? "" : ", not converged (residual " + Num(st.residual, 3) + ")");
      } else {
        linear.note = corotational.error().message;
      }
      s.rows.push_back(linear);
      out.push_back(std::move(s));
      progress.Step(scene);
    }
  }
  return out;
}

namespace {

// organ-surface-twist's setting under a law: its display surface and grasp (the top), the
// meridian's markers, and the hyperelastic FEM's inputs (the ball of 12 cells, 6 quick, resting
// on its lower fifth; the jaws' disc on it, turned rigidly about the normal at the grasp).
Expected<TwistSetting> OrganTwist(const Config& cfg) {
  auto scene = sim::LoadSceneByName("organ-surface-twist");
  if (!scene.ok()) return scene.error();
  if (scene->mesh.kind != sim::MeshKind::kSphere)
    return InvalidArgument("organ-surface-twist", "the scene is not a sphere");
  auto display = sim::BuildSceneMesh(scene->mesh);
  if (!display.ok()) return display.error();
  TwistSetting o;
  o.scene = *scene;
  o.display = display->surface.positions;
  const double r = scene->mesh.radius;
  const int grasp = Nearest(o.display, Vec3(0, 0, r));
  for (int k = 0; k < 10; ++k) {  // along a meridian from the grasp, 5° apart
    const double a = 5.0 * k * kDeg;
    o.markers.push_back(Nearest(o.display, Vec3(r * std::sin(a), 0.0, r * std::cos(a))));
  }
  auto ball = geometry::MakeTetBall({r, cfg.quick ? 6 : 12});
  if (!ball.ok()) return ball.error();
  tissue::TwistTableInputs& in = o.inputs;
  in.mesh = std::move(*ball);
  in.material.young = 2 * scene->shear_modulus * (1 + scene->poisson_ratio);
  in.material.poisson = scene->poisson_ratio;
  in.fixed = BottomCap(in.mesh.positions);
  in.origin = o.display[grasp];
  in.axis = in.origin.normalized();
  in.face = tissue::JawFace(in.mesh, tissue::BoundaryAreas(in.mesh), in.origin,
                            scene->region.reduced.jaw_radius);
  in.display = o.display;
  return o;
}

// A model of one grasp's twist for the rows below: the law's table over `levels` a side up to
// `max_twist` (rad), and the time it took (s).
struct OrganTwistModel {
  Expected<tissue::ReducedTwistModel> model = Error{};
  double precompute_s = 0;
  int levels = 0;
};
OrganTwistModel OrganTwistTable(const Expected<TwistSetting>& setting, double stiffening,
                                double max_twist, int levels) {
  if (!setting.ok()) return {setting.error()};
  tissue::TwistTableInputs in = setting->inputs;
  in.material.stiffening = stiffening;
  in.max_twist = max_twist;
  in.levels = levels;
  const auto t0 = Clock::now();
  auto table = tissue::PrecomputeTwistTable(in);
  OrganTwistModel out{table.ok()
                          ? tissue::ReducedTwistModel::Create(*table, in.display, std::numbers::pi)
                          : Expected<tissue::ReducedTwistModel>(table.error()),
                      std::chrono::duration<double>(Clock::now() - t0).count(), levels};
  return out;
}

}  // namespace

int OrganTwistLawSteps(const Config&) {
  return 2 * 4;
}

// The forceps' twist on organ-surface-twist to the task's angle and twice it, against the
// hyperelastic FEM of each law, the jaws' disc held rigidly turned. Rated: the law's own answer
// at a tenth of the task's angle, carried on linearly (a table of one level a side, extended):
// the linear model of the same load, so its error is the law's nonlinearity alone; and a table
// of 5 levels a side to 2.2 times the task's angle (13.2° apart at 30°: both angles rated fall
// between two levels). (The scene's own field is precomputed for a torque spread on the disc, not a
// rigid disc: the organ-twist rows rate it against the linear FEM of that load.)
std::vector<SceneOut> RunOrganTwistLaws(const Config& cfg, Progress& progress) {
  std::vector<SceneOut> out;
  auto setting = OrganTwist(cfg);
  const double target = setting.ok() ? setting->scene.task.target : 0.0;
  const std::string tets =
      setting.ok() ? std::to_string(setting->inputs.mesh.TetCount()) + " tets" : "";
  for (const Law& law : {Law{"neo-Hookean", 0.0}, Law{"exponential b = 5", 5.0}}) {
    OrganTwistModel small = OrganTwistTable(setting, law.stiffening, 0.1 * target, 1);
    progress.Step("organ twist laws: " + law.name + " at " + Num(0.1 * target / kDeg, 2) + "°");
    OrganTwistModel levels = OrganTwistTable(setting, law.stiffening, 2.2 * target, 5);
    progress.Step("organ twist laws: " + law.name + " table");
    tissue::TwistTableInputs in = setting.ok() ? setting->inputs : tissue::TwistTableInputs{};
    in.material.stiffening = law.stiffening;
    tissue::TwistedState last;
    last.positions = in.mesh.positions;
    for (const double twist : {target, 2 * target}) {
      const std::string scene = "organ twist " + law.name + " " + Num(twist / kDeg, 3) + "°";
      SceneOut s = NewSceneOut(scene, "organ-surface-twist");
      auto ref = setting.ok() ? tissue::SolveTwisted(in, twist, &last, 4)
                              : Expected<tissue::TwistedState>(setting.error());
      if (!ref.ok() || !small.model.ok() || !levels.model.ok()) {
        s.rows.push_back(Row{"reduced", scene, "", 0, kInf, kInf, 0,
                             !ref.ok()           ? ref.error().message
                             : !small.model.ok() ? small.model.error().message
                                                 : levels.model.error().message});
      } else {
        last = *ref;
        s.rows.push_back(RateAt(
            Drive(*small.model), "reduced",
            "the law at " + Num(0.1 * target / kDeg, 2) + "°, carried on linearly (" + tets + ")",
            scene, twist, *ref, *setting, cfg));
        Row row = RateAt(Drive(*levels.model), "reduced-table",
                         std::to_string(levels.levels) + " levels a side to " +
                             Num(2.2 * target / kDeg, 3) + "° (" + tets + ")",
                         scene, twist, *ref, *setting, cfg);
        row.note += "; built in " + Num(levels.precompute_s, 3) + " s for one grasp";
        s.rows.push_back(row);
      }
      out.push_back(std::move(s));
      progress.Step(scene);
    }
  }
  return out;
}

}  // namespace vsurg::bench::study
