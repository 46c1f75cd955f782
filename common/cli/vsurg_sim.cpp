#include "common/cli/vsurg_sim.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <numbers>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/cli/args.h"
#include "common/core/file.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/obj_io.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "common/sim/limb_scene.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/tissue/coil_calibration.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::cli {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

constexpr int kExitRuntime = 1;
constexpr int kExitUsage = 2;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Model parameter field → the option that sets it, so model validation errors name the option.
const std::map<std::string, std::string> kCoilFieldToOption = {
    {"core_radius", "--core-radius"},
    {"thickness", "--thickness"},
    {"width", "--width"},
    {"coils", "--coils"},
    {"modulus", "--modulus"},
    {"max_force", "--max-force"},
    {"friction", "--friction"},
};

int UsageError(std::ostream& err, const std::string& command, const Error& e) {
  err << command << ": " << (e.field.empty() ? "" : e.field + ": ") << e.message << "\n";
  return kExitUsage;
}

void AddCoilOptions(ArgParser& p) {
  p.Option("core-radius", Kind::kDouble, "core radius r, m", true)
      .Option("thickness", Kind::kDouble, "coil thickness h, m", true)
      .Option("width", Kind::kDouble, "coil width b, m", true)
      .Option("coils", Kind::kInt, "coil count S", true)
      .Option("modulus", Kind::kDouble, "elastic modulus E, Pa", true)
      .Option("max-force", Kind::kDouble, "maximum force per coil point F_t, N", true)
      .Option("friction", Kind::kDouble, "friction factor kappa", false, "1.25")
      .Option("json", Kind::kFlag, "print one JSON object");
}

Expected<tissue::CoilSpringModel> CoilFromArgs(const ArgParser& p) {
  tissue::CoilSpringParams c;
  c.core_radius = p.Double("core-radius");
  c.thickness = p.Double("thickness");
  c.width = p.Double("width");
  c.coils = p.Int("coils");
  c.modulus = p.Double("modulus");
  c.max_force = p.Double("max-force");
  c.friction = p.Double("friction");
  auto model = tissue::CoilSpringModel::Create(c);
  if (!model.ok()) {
    Error e = model.error();
    if (auto it = kCoilFieldToOption.find(e.field); it != kCoilFieldToOption.end())
      e.field = it->second;
    return e;
  }
  return model;
}

// Parses; on --help prints help and returns 0; on error prints one line and returns 2.
// Returns -1 when the command should go on.
int ParseOrExit(ArgParser& p, const std::vector<std::string>& args, std::ostream& out,
                std::ostream& err) {
  if (Status s = p.Parse(args); !s.ok()) return UsageError(err, p.command(), s.error());
  if (p.HelpRequested()) {
    out << p.Help();
    return 0;
  }
  return -1;
}

std::vector<double> Head(const std::vector<double>& v, int n) {
  return {v.begin(), v.begin() + n};
}

int Coil(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim coil",
      "Forward coil-spring torsion model (seed 000 eq. 1-7): the cutoff layer, per-coil torques,\n"
      "turns and twist angles, and the boundary angles for a torque M (N*m, signed).");
  p.Option("torque", Kind::kDouble, "applied torque M, N*m", true);
  AddCoilOptions(p);
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto model = CoilFromArgs(p);
  if (!model.ok()) return UsageError(err, p.command(), model.error());
  const tissue::CoilState st = model->Forward(p.Double("torque"));
  const int n = st.cutoff;
  if (p.Flag("json")) {
    json j;
    j["P"] = n;
    j["overload"] = st.overload;
    j["requested_torque"] = st.requested_torque;
    j["applied_torque"] = st.torque;
    j["capacity"] = model->Capacity();
    j["cutoff_radius"] = n > 0 ? model->RingRadius(n) : 0.0;
    j["coil_torques"] = Head(st.coil_torques, n);
    j["twist_turns"] = Head(st.twist_turns, n);
    j["twist_angles"] = Head(st.twist_angles, n);
    j["total_twist_rad"] = st.total_twist;
    j["boundary_angles"] = Head(st.boundary_angles, n + 1);
    out << j.dump() << "\n";
    return 0;
  }
  char line[256];
  std::snprintf(line, sizeof line, "cutoff layer P = %d of %d (R_P = %.4g m)%s\n", n,
                model->coils(), n > 0 ? model->RingRadius(n) : 0.0,
                st.overload ? "  OVERLOAD: torque clamped to capacity" : "");
  out << line;
  std::snprintf(line, sizeof line, "torque %.6g N*m applied (capacity %.6g N*m)\n", st.torque,
                model->Capacity());
  out << line;
  std::snprintf(line, sizeof line, "total twist %.6g rad (%.3f deg)\n", st.total_twist,
                st.total_twist * kRadToDeg);
  out << line;
  out << "coil  torque_Nm      turns          angle_rad\n";
  for (int i = 0; i < n; ++i) {
    std::snprintf(line, sizeof line, "%4d  %-13.6g  %-13.6g  %-13.6g\n", i + 1, st.coil_torques[i],
                  st.twist_turns[i], st.twist_angles[i]);
    out << line;
  }
  return 0;
}

int CoilInverse(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim coil-inverse",
      "Inverse coil-spring model: the torque (N*m) and stiffness (N*m/rad) the tissue answers\n"
      "to an imposed twist PHI (rad, signed), in closed form.");
  p.Option("twist", Kind::kDouble, "imposed twist PHI, rad", true);
  AddCoilOptions(p);
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto model = CoilFromArgs(p);
  if (!model.ok()) return UsageError(err, p.command(), model.error());
  const tissue::CoilTorque r = model->Inverse(p.Double("twist"));
  if (p.Flag("json")) {
    json j;
    j["torque"] = r.torque;
    j["stiffness"] = r.stiffness;
    j["P"] = r.cutoff;
    j["overload"] = r.overload;
    j["twist_at_capacity"] = model->TwistAtCapacity();
    out << j.dump() << "\n";
    return 0;
  }
  char line[256];
  std::snprintf(line, sizeof line, "torque %.6g N*m, stiffness %.6g N*m/rad, P = %d%s\n", r.torque,
                r.stiffness, r.cutoff, r.overload ? "  OVERLOAD: twist past capacity" : "");
  out << line;
  return 0;
}

Expected<sim::LimbScene> SceneFromArgs(const ArgParser& p) {
  auto scene = sim::BuiltinLimbScene(p.String("scene"));
  if (!scene.ok()) {
    Error e = scene.error();
    e.field = "--scene";
    return e;
  }
  return scene;
}

int Deform(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim deform",
      "Twists a built-in limb scene with the coil-spring model, grasped at its distal end and\n"
      "fixed at its proximal end, ramping the torque in equal steps; prints per step the cutoff\n"
      "layer, the total twist, the overload flag and how many vertices moved, then writes the\n"
      "deformed mesh as OBJ.");
  p.Option("scene", Kind::kString, "built-in scene: arm or calf", false, "arm")
      .Option("torque", Kind::kDouble, "final torque, N*m", false, "the scene's, 2.07")
      .Option("steps", Kind::kInt, "torque steps from torque/steps to torque, 1..100000", false,
              "1")
      .Option("out", Kind::kString, "OBJ file to write the deformed mesh to", true)
      .Option("json", Kind::kFlag, "print one JSON object");
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto scene = SceneFromArgs(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  const int steps = p.Has("steps") ? p.Int("steps") : 1;
  if (steps < 1 || steps > 100000) {
    return UsageError(err, p.command(), InvalidArgument("--steps", "must be in 1..100000"));
  }
  const double torque = p.Has("torque") ? p.Double("torque") : scene->default_torque;
  auto inst = sim::Instantiate(*scene);
  if (!inst.ok()) {
    err << p.command() << ": cannot build scene '" << scene->name << "': " << inst.error().message
        << "\n";
    return kExitRuntime;
  }
  const bool as_json = p.Flag("json");
  json j_steps = json::array();
  if (!as_json) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "scene %s: %d vertices, %d triangles, %d coils, capacity %.4g N*m\n",
                  scene->name.c_str(), inst->limb.surface.VertexCount(),
                  inst->limb.surface.TriangleCount(), inst->model.coils(), inst->model.Capacity());
    out << line
        << "step  requested_Nm  applied_Nm   P   twist_rad   twist_deg  overload  moved_vertices\n";
  }
  tissue::DeformStats stats;
  double update_us_total = 0;
  for (int k = 1; k <= steps; ++k) {
    const double m = torque * k / steps;
    const auto t0 = std::chrono::steady_clock::now();
    stats = inst->deformer.Update(m);
    update_us_total +=
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
    if (as_json) {
      j_steps.push_back({{"step", k},
                         {"torque", stats.torque},
                         {"requested_torque", m},
                         {"P", stats.cutoff},
                         {"total_twist_rad", stats.total_twist},
                         {"overload", stats.overload},
                         {"moved_vertices", stats.moved_vertices}});
    } else {
      char line[256];
      std::snprintf(line, sizeof line, "%4d  %-12.4g  %-10.4g  %2d  %-10.5g  %-9.3f  %-8s  %d\n", k,
                    m, stats.torque, stats.cutoff, stats.total_twist, stats.total_twist * kRadToDeg,
                    stats.overload ? "yes" : "no", stats.moved_vertices);
      out << line;
    }
  }
  geometry::TriMesh deformed = inst->limb.surface;
  deformed.positions = inst->deformer.positions();
  geometry::ComputeVertexNormals(deformed);
  const std::string path = p.String("out");
  char comment[256];
  std::snprintf(comment, sizeof comment,
                "vsurg %s twisted by %.6g N*m: P=%d twist=%.6g rad overload=%s",
                scene->name.c_str(), stats.torque, stats.cutoff, stats.total_twist,
                stats.overload ? "yes" : "no");
  if (Status s = geometry::WriteObj(deformed, path, comment); !s.ok()) {
    err << p.command() << ": --out: " << s.error().message << "\n";
    return kExitRuntime;
  }
  if (as_json) {
    json j;
    j["scene"] = scene->name;
    j["vertices"] = deformed.VertexCount();
    j["triangles"] = deformed.TriangleCount();
    j["capacity"] = inst->model.Capacity();
    j["steps"] = j_steps;
    j["out"] = path;
    j["mean_update_us"] = update_us_total / steps;
    out << j.dump() << "\n";
  } else {
    out << "wrote " << path << "\n";
  }
  return 0;
}

json FitJson(const tissue::CalibrationFit& f) {
  auto model = tissue::CoilSpringModel::Create(f.params);  // a fit's parameters are valid
  return {{"flexural_rigidity", f.flexural_rigidity},
          {"modulus", f.params.modulus},
          {"max_force", f.max_force},
          {"capacity", model.ok() ? model->Capacity() : 0.0},
          {"coil_rigidity", f.params.coil_rigidity},
          {"curve_rms", f.curve_rms},
          {"curve_max", f.curve_max},
          {"profile_rms", f.profile_rms},
          {"profile_max", f.profile_max}};
}

int Calibrate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim calibrate",
      "Fits the coil model of a built-in limb scene to Saint-Venant torsion of the same tapered\n"
      "limb (fixed proximal end, torque at the distal end), twice: the paper's two parameters\n"
      "(E*I and F_t) and a per-ring rigidity. Prints the fitted values and the residuals\n"
      "(relative to the reference's largest twist) of the torque-twist curve and the profiles.");
  p.Option("scene", Kind::kString, "built-in scene: arm or calf", false, "arm")
      .Option("max-torque", Kind::kDouble, "largest reference torque, N*m", false,
              "the scene's, 2.07")
      .Option("torques", Kind::kInt, "reference torques, evenly up to the largest, 1..1000", false,
              "8")
      .Option("shear-modulus", Kind::kDouble, "reference shear modulus G, Pa", false, "12000")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto scene = SceneFromArgs(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  tissue::TaperedShaft shaft = scene->reference;
  if (p.Has("shear-modulus")) shaft.shear_modulus = p.Double("shear-modulus");
  if (!(shaft.shear_modulus > 0)) {
    return UsageError(err, p.command(), InvalidArgument("--shear-modulus", "must be > 0 Pa"));
  }
  const double max_torque = p.Has("max-torque") ? p.Double("max-torque") : scene->default_torque;
  if (!(max_torque > 0))
    return UsageError(err, p.command(), InvalidArgument("--max-torque", "must be > 0 N*m"));
  const int torques = p.Has("torques") ? p.Int("torques") : 8;
  if (torques < 1 || torques > 1000) {
    return UsageError(err, p.command(), InvalidArgument("--torques", "must be in 1..1000"));
  }
  const tissue::CalibrationReference ref =
      tissue::SaintVenantCalibrationReference(shaft, max_torque, torques);
  auto paper = tissue::CalibrateTwoParameter(scene->coil, ref);
  auto per_ring = tissue::CalibratePerRing(scene->coil, ref);
  if (!paper.ok() || !per_ring.ok()) {
    err << p.command()
        << ": calibration failed: " << (paper.ok() ? per_ring.error() : paper.error()).message
        << "\n";
    return kExitRuntime;
  }
  if (p.Flag("json")) {
    json j;
    j["scene"] = scene->name;
    j["reference"] = {{"model", "saint-venant"},
                      {"shear_modulus", shaft.shear_modulus},
                      {"max_torque", max_torque},
                      {"torques", torques},
                      {"twist_at_max_torque", ref.curve_twist.back()}};
    j["two_parameter"] = FitJson(*paper);
    j["per_ring"] = FitJson(*per_ring);
    out << j.dump() << "\n";
    return 0;
  }
  char line[320];
  std::snprintf(
      line, sizeof line,
      "reference: Saint-Venant, G = %.6g Pa, %d torques up to %.4g N*m (twist %.4g rad)\n",
      shaft.shear_modulus, torques, max_torque, ref.curve_twist.back());
  out << line;
  auto row = [&](const char* name, const tissue::CalibrationFit& f) {
    std::snprintf(line, sizeof line,
                  "%-13s E*I %.4g N*m^2, F_t %.4g N: curve rms %.1f%% max %.1f%%; profile rms "
                  "%.1f%% max %.1f%%\n",
                  name, f.flexural_rigidity, f.max_force, 100 * f.curve_rms, 100 * f.curve_max,
                  100 * f.profile_rms, 100 * f.profile_max);
    out << line;
  };
  row("two-parameter", *paper);
  row("per-ring", *per_ring);
  return 0;
}

// A mesh to press: the subdivided sphere, a limb, or an OBJ file. `press` is the vertex the tool
// drives, `direction` the way it pushes, `fixed` the support.
struct PressScene {
  geometry::TriMesh mesh;
  int press = 0;
  geometry::Vec3 direction = geometry::Vec3(0, 0, -1);
  std::vector<int> fixed;
};

Expected<PressScene> MakePressScene(const std::string& name, int particles, double radius) {
  PressScene s;
  const bool limb = name == "arm" || name == "calf";
  sim::MeshSpec spec;
  if (name == "sphere") {
    spec.kind = sim::MeshKind::kSphere;
    spec.radius = radius;
    spec.particles = particles;
  } else if (limb) {
    spec.kind = sim::MeshKind::kLimb;
    spec.limb = geometry::WithResolution(
        name == "arm" ? geometry::ForearmPreset() : geometry::CalfPreset(), particles);
  } else {
    spec.kind = sim::MeshKind::kObj;
    spec.path = name;
  }
  auto mesh = sim::BuildSceneMesh(spec);
  if (!mesh.ok()) return mesh.error();
  s.mesh = std::move(mesh->surface);
  // Limbs lie along z: press the top (+y) of the middle and hold both ends. Anything else:
  // press the top (+z) and rest the bottom fifth on a table.
  s.fixed = sim::SupportedVertices(s.mesh, limb ? sim::Support::kEnds : sim::Support::kBottom);
  Eigen::Vector3d lo = s.mesh.positions[0], hi = lo;
  for (const auto& p : s.mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double mid_z = 0.5 * (lo.z() + hi.z());
  double best = -1e300;
  for (int v = 0; v < s.mesh.VertexCount(); ++v) {
    const auto& p = s.mesh.positions[v];
    const double score = limb ? p.y() - 10 * std::abs(p.z() - mid_z) : p.z();
    if (score > best) best = score, s.press = v;
  }
  if (limb) s.direction = geometry::Vec3(0, -1, 0);
  return s;
}

int Msm(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim msm",
      "Presses a mass-spring tissue at a point (seed 001): the tool drives the top vertex in by\n"
      "--press metres over the first half of the run and holds it; the support is fixed (the\n"
      "sphere's bottom fifth, a limb's ends). Prints the final kinetic and potential energy (J),\n"
      "the largest displacement (m), the contact force the tool feels (N), steps per second\n"
      "and whether the run diverged.");
  p.Option("mesh", Kind::kString, "sphere, arm, calf or an OBJ file", false, "sphere")
      .Option("particles", Kind::kInt, "about this many surface particles (sphere, limbs)", false,
              "1024")
      .Option("radius", Kind::kDouble, "sphere radius, m", false, "0.05")
      .Option("integrator", Kind::kString,
              "explicit-euler, symplectic-euler, midpoint, rk4, verlet or implicit-euler", false,
              "midpoint")
      .Option("dt", Kind::kDouble, "time step, s", false, "0.001")
      .Option("steps", Kind::kInt, "number of steps", false, "1000")
      .Option("substeps", Kind::kInt, "substeps per step", false, "1")
      .Option("press", Kind::kDouble, "press depth, m", false, "0.005")
      .Option("stiffness", Kind::kDouble, "structural spring stiffness, N/m", false, "50")
      .Option("bending", Kind::kDouble, "bending spring stiffness, N/m (0: none)", false, "5")
      .Option("damping", Kind::kDouble, "spring damping, N*s/m", false, "0.05")
      .Option("density", Kind::kDouble, "tissue density for the mass, kg/m^3", false, "1050")
      .Option("volume", Kind::kString, "none or inner-layer", false, "none")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto integrator = tissue::ParseIntegrator(p.String("integrator"));
  if (!integrator.ok()) {
    return UsageError(err, p.command(),
                      InvalidArgument("--integrator", integrator.error().message));
  }
  const double dt = p.Double("dt"), press = p.Double("press"), radius = p.Double("radius");
  const int steps = p.Int("steps"), substeps = p.Int("substeps"), particles = p.Int("particles");
  if (!(dt > 0 && dt <= 1))
    return UsageError(err, p.command(), InvalidArgument("--dt", "must be in (0, 1] s"));
  if (steps < 1 || steps > 10'000'000) {
    return UsageError(err, p.command(), InvalidArgument("--steps", "must be in 1..10000000"));
  }
  if (substeps < 1 || substeps > 1000) {
    return UsageError(err, p.command(), InvalidArgument("--substeps", "must be in 1..1000"));
  }
  if (particles < 6 || particles > 300000) {
    return UsageError(err, p.command(), InvalidArgument("--particles", "must be in 6..300000"));
  }
  if (!(radius > 0))
    return UsageError(err, p.command(), InvalidArgument("--radius", "must be > 0 m"));
  if (!(std::abs(press) < 0.1)) {
    return UsageError(err, p.command(), InvalidArgument("--press", "must be within ±0.1 m"));
  }
  if (!(p.Double("density") > 0))
    return UsageError(err, p.command(), InvalidArgument("--density", "must be > 0"));
  const std::string volume = p.String("volume");
  if (volume != "none" && volume != "inner-layer") {
    return UsageError(err, p.command(), InvalidArgument("--volume", "must be none or inner-layer"));
  }
  auto scene = MakePressScene(p.String("mesh"), particles, radius);
  if (!scene.ok()) {
    Error e = scene.error();
    if (e.code == ErrorCode::kIoError || e.code == ErrorCode::kParseError) {
      err << p.command() << ": --mesh: " << e.message << "\n";
      return kExitUsage;
    }
    e.field = "--mesh";
    return UsageError(err, p.command(), e);
  }
  tissue::MassSpringBuildParams bp;
  bp.total_mass = p.Double("density") * std::abs(geometry::SignedVolume(scene->mesh));
  bp.structural_stiffness = p.Double("stiffness");
  bp.bending_stiffness = p.Double("bending");
  bp.volume_stiffness = bp.structural_stiffness;
  bp.damping = p.Double("damping");
  bp.volume = volume == "inner-layer" ? tissue::VolumeMode::kInnerLayer : tissue::VolumeMode::kNone;
  bp.layer_depth = 0.2 * radius;
  auto system = tissue::BuildMassSpring(scene->mesh, bp);
  if (!system.ok()) {
    const std::map<std::string, std::string> option = {{"structural_stiffness", "--stiffness"},
                                                       {"bending_stiffness", "--bending"},
                                                       {"damping", "--damping"},
                                                       {"total_mass", "--density"},
                                                       {"volume_stiffness", "--stiffness"}};
    Error e = system.error();
    e.field = option.count(e.field) ? option.at(e.field) : "--mesh";
    return UsageError(err, p.command(), e);
  }
  const int n_particles = static_cast<int>(system->rest_positions.size());
  const int n_springs = static_cast<int>(system->springs.size());
  tissue::MassSpringStepParams sp;
  sp.integrator = *integrator;
  auto model = tissue::MassSpringModel::Create(std::move(*system), sp);
  if (!model.ok()) return UsageError(err, p.command(), model.error());
  for (int v : scene->fixed) model->SetFixed(v, true);
  if (bp.volume == tissue::VolumeMode::kInnerLayer) {
    const int n = scene->mesh.VertexCount();
    for (int v : scene->fixed) model->SetFixed(n + v, true);
  }
  model->SetKinematic(scene->press, true);
  const geometry::Vec3 rest = scene->mesh.positions[scene->press];
  const int ramp = std::max(1, steps / 2);
  const auto t0 = std::chrono::steady_clock::now();
  int done = 0;
  for (; done < steps; ++done) {
    const double depth = press * std::min(1.0, static_cast<double>(done + 1) / ramp);
    model->SetKinematicTarget(scene->press, rest + depth * scene->direction);
    if (!model->Step(dt, substeps)) break;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The tissue's push on the tool, as a force along the outward direction (−press direction).
  const geometry::Vec3 on_tool = model->InternalForceOn(scene->press);
  const double contact = on_tool.dot(-scene->direction);
  const double rate = seconds > 0 ? done / seconds : 0.0;
  if (p.Flag("json")) {
    json j;
    j["mesh"] = p.String("mesh");
    j["particles"] = n_particles;
    j["springs"] = n_springs;
    j["integrator"] = tissue::IntegratorName(*integrator);
    j["dt"] = dt;
    j["steps"] = done;
    j["kinetic_energy"] = model->KineticEnergy();
    j["potential_energy"] = model->PotentialEnergy();
    j["max_displacement"] = model->MaxDisplacement();
    j["contact_force"] = contact;
    j["contact_force_vector"] = {on_tool.x(), on_tool.y(), on_tool.z()};
    j["steps_per_second"] = rate;
    j["diverged"] = model->diverged();
    if (*integrator == tissue::Integrator::kImplicitEuler)
      j["cg_iterations_last"] = model->last_cg_iterations();
    out << j.dump() << "\n";
    return 0;
  }
  char line[320];
  std::snprintf(line, sizeof line,
                "%s: %d particles, %d springs, %s, dt %.3g s x %d steps\n"
                "kinetic %.6g J, potential %.6g J, max displacement %.6g m, contact force %.6g N\n"
                "%.0f steps/s%s\n",
                p.String("mesh").c_str(), n_particles, n_springs,
                tissue::IntegratorName(*integrator), dt, done, model->KineticEnergy(),
                model->PotentialEnergy(), model->MaxDisplacement(), contact, rate,
                model->diverged() ? "  DIVERGED: the state was reset to rest" : "");
  out << line;
  return 0;
}

Expected<sim::Scene> SceneOption(const ArgParser& p) {
  auto scene = sim::LoadSceneByName(p.String("scene"));
  if (!scene.ok()) {
    Error e = scene.error();
    e.field = "--scene";
    return e;
  }
  return scene;
}

int Run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim run",
      "Replays a stylus trajectory headless through a scene's simulation (contact, "
      "grasp-and-twist,\n"
      "device safety, deformation, scoring) and prints the trial metrics and force statistics.\n"
      "The trajectory is a CSV with the header t,x,y,z,qw,qx,qy,qz,buttons (s, m, unit\n"
      "quaternion, button bits: 1 = grasp); `vsurg-sim trainee` writes scripted ones.");
  p.Option("scene", Kind::kString, "scene name in scenes/ (e.g. arm-torsion) or a .json path", true)
      .Option("trajectory", Kind::kString, "trajectory CSV", true)
      .Option("json", Kind::kFlag, "print one JSON object");
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto scene = SceneOption(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  auto samples = sim::ReadTrajectoryCsv(p.String("trajectory"));
  if (!samples.ok()) {
    err << p.command() << ": --trajectory: " << samples.error().message << "\n";
    return kExitUsage;
  }
  sim::SimulationOptions options;
  options.threaded = false;  // deterministic replay: deformation stepped in simulated time
  auto simulation = sim::Simulation::Create(*scene, options);
  if (!simulation.ok()) {
    err << p.command() << ": cannot build scene '" << scene->name
        << "': " << simulation.error().message << "\n";
    return kExitRuntime;
  }
  sim::Simulation& s = **simulation;
  double force_sum = 0;
  int forces = 0, contacts = 0, grasps = 0;
  std::map<std::string, int> events;
  const std::pair<uint32_t, const char*> kEvents[] = {
      {haptics::kEventNonFiniteInput, "non_finite_input"},
      {haptics::kEventOutOfWorkspace, "out_of_workspace"},
      {haptics::kEventForceClamped, "force_clamped"},
      {haptics::kEventRateLimited, "rate_limited"},
      {haptics::kEventGated, "gated"},
      {haptics::kEventStiffnessClamped, "stiffness_clamped"},
      {haptics::kEventOverload, "overload"}};
  double peak = 0;
  s.Replay(*samples, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    const double f = c.force.norm();
    peak = std::max(peak, f);
    force_sum += f;
    ++forces;
    contacts += c.contact;
    grasps += (c.events & haptics::kEventGraspStart) != 0;
    for (const auto& [bit, name] : kEvents) {
      if (c.events & bit) ++events[name];
    }
  });
  const scoring::TrialMetrics m = s.Metrics();
  if (p.Flag("json")) {
    json j;
    j["scene"] = scene->name;
    j["samples"] = samples->size();
    j["metrics"] = scoring::TrialMetricsToJson(m);
    j["peak_force"] = peak;
    j["mean_force"] = forces ? force_sum / forces : 0.0;
    j["contact_samples"] = contacts;
    j["grasps"] = grasps;
    j["events"] = events;
    j["deformation_updates"] = s.deformation_updates();
    out << j.dump() << "\n";
    return 0;
  }
  char line[400];
  std::snprintf(
      line, sizeof line,
      "%s: %zu samples, peak force %.3f N (after device limits), mean %.3f N\n"
      "completed %s in %.2f s, task error %.4g, %.2f s over the force limit, overloads %d\n"
      "path %.3f m, RMS jerk %.3g m/s^3, score %.1f / 10 (before gates %.1f)\n",
      scene->name.c_str(), samples->size(), peak, forces ? force_sum / forces : 0.0,
      m.completed ? "yes" : "no", m.completion_time, m.task_error, m.time_over_force_limit,
      m.overload_events, m.path_length, m.rms_jerk, m.score, m.raw_score);
  out << line;
  return 0;
}

int Trainee(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim trainee",
      "Writes a scripted trainee's stylus trajectory for a scene's task, as the CSV `run` reads:\n"
      "good (smooth, on target), hesitant (slow, stepwise corrections), rough (fast, jerky,\n"
      "overshooting, over the force limit).");
  p.Option("scene", Kind::kString, "scene name or .json path", true)
      .Option("style", Kind::kString, "good, hesitant or rough", false, "good")
      .Option("rate", Kind::kDouble, "samples per second", false, "1000")
      .Option("seed", Kind::kInt, "tremor seed (rough)", false, "1")
      .Option("out", Kind::kString, "CSV file to write", true);
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  auto scene = SceneOption(p);
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  auto style = sim::ParseTraineeStyle(p.String("style"));
  if (!style.ok())
    return UsageError(err, p.command(), InvalidArgument("--style", style.error().message));
  auto samples =
      sim::ScriptedTrainee(*scene, *style, p.Double("rate"), static_cast<unsigned>(p.Int("seed")));
  if (!samples.ok())
    return UsageError(err, p.command(), InvalidArgument("--rate", samples.error().message));
  if (Status st = sim::WriteTrajectoryCsv(*samples, p.String("out")); !st.ok()) {
    err << p.command() << ": --out: " << st.error().message << "\n";
    return kExitRuntime;
  }
  out << "wrote " << samples->size() << " samples to " << p.String("out") << "\n";
  return 0;
}

void PrintReportTable(std::ostream& out, const scoring::EvaluationReport& r) {
  out << std::fixed << std::setprecision(3);
  out << "raters " << r.raters << " (intern " << r.raters_per_group[0] << ", associate_chief "
      << r.raters_per_group[1] << ", chief " << r.raters_per_group[2] << "), weights '"
      << r.weights.name << "'\n";
  if (r.renormalised) {
    out << "absent groups:";
    for (const auto& g : r.absent_groups) out << " " << g;
    out << " (present group weights renormalised)\n";
  }
  out << "index                    weight   M_j (eq.9)   s_j (eq.10)\n";
  for (int j = 0; j < scoring::kIndexCount; ++j)
    out << std::left << std::setw(24) << scoring::IndexName(j) << std::right << std::setw(7)
        << r.weights.index[j] << std::setw(13) << r.index_means[j] << std::setw(14)
        << r.index_variances[j] << "\n";
  out << "comprehensive N (eq.11): " << r.comprehensive << "\n";
  out << "ICC(2,k) over indexes:   " << r.icc2k_indexes << "\n";
  out << "Cronbach alpha:          " << r.cronbach_alpha << "\n";
}

int Score(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-sim score",
              "Computes the weighted evaluation report of seed 000 section 4.4 offline: per index\n"
              "the group-weighted mean M_j (eq. 9) and variance s_j (eq. 10), the comprehensive\n"
              "score N (eq. 11), and how far the raters agree (ICC(2,k), Cronbach's alpha).\n"
              "Input rows: evaluator_id,group,i1,...,i9 (group intern, associate_chief or chief;\n"
              "scores 0-10), an optional header row, an optional 12th column naming the subject\n"
              "(several subjects: one report each and ICC(2,k) per index across them).");
  p.Option("input", Kind::kString, "ratings CSV", true)
      .Option("weights", Kind::kString,
              "weight set JSON {name, group{...}, index[9]} (default: seed 000)")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (int rc = ParseOrExit(p, args, out, err); rc >= 0) return rc;
  scoring::WeightSet weights;
  if (p.Has("weights")) {
    auto text = ReadTextFile(p.String("weights"), "--weights");
    if (!text.ok()) return UsageError(err, p.command(), text.error());
    auto w = scoring::WeightSetFromJsonText(*text);
    if (!w.ok())
      return UsageError(err, p.command(),
                        Error{w.error().code, w.error().message, "--weights: " + w.error().field});
    weights = *w;
  }
  auto text = ReadTextFile(p.String("input"), "--input");
  if (!text.ok()) return UsageError(err, p.command(), text.error());
  auto subjects = scoring::ParseRatingsCsv(*text, p.String("input"));
  if (!subjects.ok()) {
    err << p.command() << ": --input: " << subjects.error().message << "\n";
    return kExitUsage;
  }
  if (subjects->size() == 1) {
    auto report = scoring::Evaluate(subjects->front().ratings, weights);
    if (!report.ok()) return UsageError(err, p.command(), report.error());
    if (p.Flag("json")) {
      json j = scoring::ReportToJson(*report);
      if (!subjects->front().subject.empty()) j["subject"] = subjects->front().subject;
      out << j.dump() << "\n";
    } else {
      PrintReportTable(out, *report);
    }
    return 0;
  }
  auto comparison = scoring::Compare(*subjects, weights);
  if (!comparison.ok()) return UsageError(err, p.command(), comparison.error());
  std::vector<std::string> names;
  for (const auto& s : *subjects) names.push_back(s.subject);
  if (p.Flag("json")) {
    out << scoring::ComparisonToJson(*comparison, names).dump() << "\n";
    return 0;
  }
  for (size_t s = 0; s < names.size(); ++s) {
    out << "== subject '" << names[s] << "'\n";
    PrintReportTable(out, comparison->subjects[s]);
  }
  out << "ICC(2,k) per index across subjects (" << comparison->common_raters << " common raters):";
  for (double v : comparison->icc2k_per_index) out << " " << v;
  out << "\n";
  return 0;
}

const char* kTopHelp =
    "usage: vsurg-sim <command> [options]\n\n"
    "The headless front of the vsurg simulation core.\n\n"
    "commands:\n"
    "  coil          forward coil-spring torsion model: torque -> cutoff layer, twist\n"
    "  coil-inverse  inverse coil-spring model: twist -> torque and stiffness\n"
    "  deform        twist a built-in limb scene and write the deformed mesh as OBJ\n"
    "  calibrate     fit the coil model to Saint-Venant torsion and report the residuals\n"
    "  msm           press a mass-spring tissue (sphere, limb or OBJ) and report energies and "
    "force\n"
    "  run           replay a stylus trajectory through a scene and print the trial metrics\n"
    "  trainee       write a scripted trainee's trajectory (good, hesitant, rough)\n"
    "  score         weighted evaluation report (seed 000 eq. 9-11) with rater reliability\n\n"
    "`vsurg-sim <command> --help` describes each command's options.\n";

}  // namespace

int RunVsurgSim(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (args.empty()) {
    err << "vsurg-sim: a command is required (coil, coil-inverse, deform, calibrate, msm, run, "
           "trainee, score; see --help)\n";
    return kExitUsage;
  }
  const std::string& cmd = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    out << kTopHelp;
    return 0;
  }
  if (cmd == "coil") return Coil(rest, out, err);
  if (cmd == "coil-inverse") return CoilInverse(rest, out, err);
  if (cmd == "deform") return Deform(rest, out, err);
  if (cmd == "calibrate") return Calibrate(rest, out, err);
  if (cmd == "msm") return Msm(rest, out, err);
  if (cmd == "run") return Run(rest, out, err);
  if (cmd == "trainee") return Trainee(rest, out, err);
  if (cmd == "score") return Score(rest, out, err);
  err << "vsurg-sim: unknown command '" << cmd
      << "' (coil, coil-inverse, deform, calibrate, msm, run, trainee, score; see --help)\n";
  return kExitUsage;
}

}  // namespace vsurg::cli
