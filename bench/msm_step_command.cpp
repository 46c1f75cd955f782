#include "bench/msm_step_command.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "bench/msm_scenes.h"
#include "common/core/args.h"

namespace vsurg::bench {
namespace {

// A scene as text (bench/peers/README.md "msm"): the step, then every particle as it is after the
// drive's ramp (position in m, mass in kg, 0 free / 1 fixed / 2 kinematic), then every spring
// (0-based ends, k in N/m, c in N·s/m, rest length in m), then every particle's rest position (m)
// and velocity (m/s) for the peers that step displacements from rest (VegaFEM); readers that need
// only the first parts stop before it.
Status Export(const MsmScene& s, const std::string& path) {
  std::ofstream out(path);
  if (!out) return Error{ErrorCode::kIoError, "cannot write " + path, "export"};
  const auto& sys = s.model.system();
  const auto& x = s.model.positions();
  std::vector<int> flag(x.size(), 0);
  for (size_t i = 0; i < x.size(); ++i) flag[i] = s.fixed[i] ? 1 : 0;
  for (int v : s.driven) flag[v] = 2;
  char line[160];
  out << "dt " << kMsmDt << "\nparticles " << x.size() << "\n";
  for (size_t i = 0; i < x.size(); ++i) {
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g %d\n", x[i].x(), x[i].y(), x[i].z(),
                  sys.masses[i], flag[i]);
    out << line;
  }
  out << "springs " << sys.springs.size() << "\n";
  for (const tissue::Spring& k : sys.springs) {
    std::snprintf(line, sizeof line, "%d %d %.17g %.17g %.17g\n", k.i, k.j, k.stiffness, k.damping,
                  k.rest_length);
    out << line;
  }
  const auto& v = s.model.velocities();
  out << "rest " << x.size() << "\n";
  for (size_t i = 0; i < x.size(); ++i) {
    const geometry::Vec3& r = sys.rest_positions[i];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g %.17g %.17g\n", r.x(), r.y(), r.z(),
                  v[i].x(), v[i].y(), v[i].z());
    out << line;
  }
  return out ? Status::Ok() : Error{ErrorCode::kIoError, "cannot write " + path, "export"};
}

}  // namespace

int MsmStep(const std::vector<std::string>& args) {
  cli::ArgParser p(
      "vsurg-bench msm-step",
      "The implicit-Euler mass-spring step (conjugate gradient to --tolerance) on\n"
      "the 1026-particle sphere pressed 5 mm and the 6182-particle arm twisted 60°,\n"
      "at dt = 0.2 ms: the median time per step over --steps steps, after the drive's\n"
      "ramp. --export DIR writes each scene as DIR/<scene>.msm for the peers.");
  p.Option("steps", cli::ArgParser::Kind::kInt, "timed steps per scene", false, "2000")
      .Option("tolerance", cli::ArgParser::Kind::kDouble,
              "the conjugate gradient's relative residual", false, "1e-3")
      .Option("energy-floor", cli::ArgParser::Kind::kDouble,
              "the solve also ends when its error's kinetic energy is below this, J (0: the "
              "relative residual alone, as a peer iterating to a tolerance)",
              false, "1e-13")
      .Option("export", cli::ArgParser::Kind::kString, "write the scenes' files here")
      .Option("json", cli::ArgParser::Kind::kFlag, "print one JSON line per scene");
  if (auto rc = cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  const int steps = p.Int("steps");
  if (steps < 10 || steps > 1000000) {
    std::cerr << p.command() << ": --steps: must be within 10..1000000\n";
    return 2;
  }
  const double tolerance = p.Double("tolerance");
  if (!(tolerance >= 1e-12 && tolerance <= 0.1)) {
    std::cerr << p.command() << ": --tolerance: must be within 1e-12..0.1\n";
    return 2;
  }
  const double floor = p.Double("energy-floor");
  if (!(floor >= 0 && floor <= 1)) {
    std::cerr << p.command() << ": --energy-floor: must be within 0..1 J\n";
    return 2;
  }
  char method[96];
  std::snprintf(method, sizeof method, "implicit Euler, CG %g%s", tolerance,
                floor > 0 ? "" : ", no energy floor");
  for (int which : {1, 2}) {
    MsmScene s = MakeMsmScene(which, tissue::Integrator::kImplicitEuler, tolerance, floor);
    if (p.Has("export")) {
      std::filesystem::create_directories(p.String("export"));
      const std::string path = p.String("export") + "/" + MsmSceneName(which) + ".msm";
      if (Status st = Export(s, path); !st.ok()) {
        std::cerr << p.command() << ": " << st.error().message << "\n";
        return 1;
      }
    }
    std::vector<double> us;
    us.reserve(steps);
    long cg = 0;
    for (int k = 0; k < steps; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      s.model.Step(kMsmDt);
      us.push_back(
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
      cg += s.model.last_cg_iterations();
    }
    std::sort(us.begin(), us.end());
    const double median = us[us.size() / 2], p90 = us[us.size() * 9 / 10];
    const nlohmann::json j = {{"who", "vsurg"},
                              {"scene", MsmSceneName(which)},
                              {"particles", s.model.positions().size()},
                              {"springs", s.model.system().springs.size()},
                              {"method", method},
                              {"step_us_median", median},
                              {"step_us_p90", p90},
                              {"cg_iterations", static_cast<double>(cg) / steps},
                              {"diverged", s.model.diverged()}};
    if (p.Flag("json")) {
      std::cout << j.dump() << "\n";
    } else {
      std::printf(
          "%-11s %5zu particles %6zu springs: %8.1f us per step (p90 %.1f), %.1f CG iterations\n",
          MsmSceneName(which), s.model.positions().size(), s.model.system().springs.size(), median,
          p90, static_cast<double>(cg) / steps);
    }
  }
  return 0;
}

}  // namespace vsurg::bench
