// vsurg-sim coil, coil-inverse, deform and calibrate: the coil-spring torsion model (the
// coil-spring paper).
#include "common/cli/commands.h"

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

#include "common/core/args.h"
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

namespace vsurg::cli::commands {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

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

std::vector<double> Head(const std::vector<double>& v, int n) {
  return {v.begin(), v.begin() + n};
}

}  // namespace

int Coil(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-sim coil",
              "Forward coil-spring torsion model (the coil-spring paper eq. 1-7): the cutoff "
              "layer, per-coil torques,\n"
              "turns and twist angles, and the boundary angles for a torque M (N*m, signed).");
  p.Option("torque", Kind::kDouble, "applied torque M, N*m", true);
  AddCoilOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
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

int CoilInverse(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim coil-inverse",
      "Inverse coil-spring model: the torque (N*m) and stiffness (N*m/rad) the tissue answers\n"
      "to an imposed twist PHI (rad, signed), in closed form.");
  p.Option("twist", Kind::kDouble, "imposed twist PHI, rad", true);
  AddCoilOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
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

int Deform(const Args& args, std::ostream& out, std::ostream& err) {
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
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
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

int Calibrate(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim calibrate",
      "Fits the coil model of a built-in limb scene to Saint-Venant torsion of the same tapered\n"
      "limb (fixed proximal end, torque at the distal end), twice: the paper's two parameters\n"
      "(E*I and F_t) and a per-ring rigidity, the latter with F_t fitted and with the scene's\n"
      "F_t held (its capacity kept: what a scene file's \"coil_rigidity\" comes from). Prints\n"
      "the fitted values and the residuals (relative to the reference's largest twist) of the\n"
      "torque-twist curve and the profiles.");
  p.Option("scene", Kind::kString, "built-in scene: arm or calf", false, "arm")
      .Option("max-torque", Kind::kDouble, "largest reference torque, N*m", false,
              "the scene's, 2.07")
      .Option("torques", Kind::kInt, "reference torques, evenly up to the largest, 1..1000", false,
              "8")
      .Option("shear-modulus", Kind::kDouble, "reference shear modulus G, Pa", false, "12000")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
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
  auto at_capacity = tissue::CalibratePerRingAtCapacity(scene->coil, ref);
  for (const auto* fit : {&paper, &per_ring, &at_capacity})
    if (!fit->ok()) {
      err << p.command() << ": calibration failed: " << fit->error().message << "\n";
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
    j["per_ring_at_capacity"] = FitJson(*at_capacity);
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
                  "%-18s E*I %.4g N*m^2, F_t %.4g N: curve rms %.1f%% max %.1f%%; profile rms "
                  "%.1f%% max %.1f%%\n",
                  name, f.flexural_rigidity, f.max_force, 100 * f.curve_rms, 100 * f.curve_max,
                  100 * f.profile_rms, 100 * f.profile_max);
    out << line;
  };
  row("two-parameter", *paper);
  row("per-ring", *per_ring);
  row("per-ring, F_t held", *at_capacity);
  return 0;
}

}  // namespace vsurg::cli::commands
