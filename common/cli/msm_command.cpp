// vsurg-sim msm: the press experiment of the mass-spring paper (common/sim/press_experiment.h) from
// the command line.
#include <cstdio>
#include <map>
#include <ostream>

#include <nlohmann/json.hpp>

#include "common/cli/commands.h"
#include "common/core/args.h"
#include "common/sim/press_experiment.h"

namespace vsurg::cli::commands {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

// The experiment's field → the option that sets it, so errors name the option.
const std::map<std::string, std::string> kFieldToOption = {
    {"mesh", "--mesh"},
    {"particles", "--particles"},
    {"radius", "--radius"},
    {"dt", "--dt"},
    {"steps", "--steps"},
    {"substeps", "--substeps"},
    {"press", "--press"},
    {"density", "--density"},
    {"total_mass", "--density"},
    {"structural_stiffness", "--stiffness"},
    {"volume_stiffness", "--stiffness"},
    {"bending_stiffness", "--bending"},
    {"damping", "--damping"},
};

}  // namespace

int Msm(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim msm",
      "Presses a mass-spring tissue at a point (the mass-spring paper): the tool drives the top "
      "vertex in by\n"
      "--press metres over the first half of the run and holds it; the support is fixed (the\n"
      "sphere's bottom fifth, a limb's ends). Prints the final kinetic and potential energy (J),\n"
      "the largest displacement (m), the contact force the tool feels (N), steps per second\n"
      "and whether the run diverged.");
  p.Option("mesh", Kind::kString,
           "sphere, arm, calf or a mesh file in metres (OBJ, STL, PLY, glTF: assimp)", false,
           "sphere")
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
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  sim::PressExperimentSpec spec;
  auto integrator = tissue::ParseIntegrator(p.String("integrator"));
  if (!integrator.ok())
    return UsageError(err, p.command(),
                      InvalidArgument("--integrator", integrator.error().message));
  spec.integrator = *integrator;
  const std::string volume = p.String("volume");
  if (volume != "none" && volume != "inner-layer")
    return UsageError(err, p.command(), InvalidArgument("--volume", "must be none or inner-layer"));
  spec.volume =
      volume == "inner-layer" ? tissue::VolumeMode::kInnerLayer : tissue::VolumeMode::kNone;
  spec.mesh = p.String("mesh");
  spec.particles = p.Int("particles");
  spec.radius = p.Double("radius");
  spec.dt = p.Double("dt");
  spec.steps = p.Int("steps");
  spec.substeps = p.Int("substeps");
  spec.press = p.Double("press");
  spec.stiffness = p.Double("stiffness");
  spec.bending = p.Double("bending");
  spec.damping = p.Double("damping");
  spec.density = p.Double("density");
  auto r = sim::RunPressExperiment(spec);
  if (!r.ok()) {
    Error e = r.error();
    if (auto it = kFieldToOption.find(e.field); it != kFieldToOption.end()) e.field = it->second;
    return UsageError(err, p.command(), e);
  }
  if (p.Flag("json")) {
    json j;
    j["mesh"] = spec.mesh;
    j["particles"] = r->particles;
    j["springs"] = r->springs;
    j["integrator"] = tissue::IntegratorName(spec.integrator);
    j["dt"] = spec.dt;
    j["steps"] = r->steps;
    j["kinetic_energy"] = r->kinetic_energy;
    j["potential_energy"] = r->potential_energy;
    j["max_displacement"] = r->max_displacement;
    j["contact_force"] = r->contact_force;
    const geometry::Vec3& f = r->contact_force_vector;
    j["contact_force_vector"] = {f.x(), f.y(), f.z()};
    j["steps_per_second"] = r->steps_per_second;
    j["diverged"] = r->diverged;
    if (spec.integrator == tissue::Integrator::kImplicitEuler)
      j["cg_iterations_last"] = r->cg_iterations_last;
    out << j.dump() << "\n";
    return 0;
  }
  char line[320];
  std::snprintf(line, sizeof line,
                "%s: %d particles, %d springs, %s, dt %.3g s x %d steps\n"
                "kinetic %.6g J, potential %.6g J, max displacement %.6g m, contact force %.6g N\n"
                "%.0f steps/s%s\n",
                spec.mesh.c_str(), r->particles, r->springs,
                tissue::IntegratorName(spec.integrator), spec.dt, r->steps, r->kinetic_energy,
                r->potential_energy, r->max_displacement, r->contact_force, r->steps_per_second,
                r->diverged ? "  DIVERGED: the state was reset to rest" : "");
  out << line;
  return 0;
}

}  // namespace vsurg::cli::commands
