// vsurg-sim: the headless command-line front of the core (a thin layer over common/).
//
// Contract (other tools and tests rely on it exactly):
//   vsurg-sim coil --torque M --core-radius r --thickness h --width b --coils S --modulus E
//                  --max-force Ft [--friction 1.25] [--json]
//       → P, overload, coil_torques, twist_turns, twist_angles, total_twist_rad,
//         boundary_angles (SI, radians)
//   vsurg-sim coil-inverse --twist PHI <same parameters> [--json]
//       → torque, stiffness, P, overload
//   vsurg-sim deform --scene arm --torque M --out arm.obj [--steps N] [--json]
//   vsurg-sim calibrate --scene arm [--max-torque M] [--shear-modulus G] [--json]
// Exit codes: 0 success, 1 a failure at run time (e.g. the output cannot be written), 2 bad
// arguments, with one line on stderr naming the argument and why. `--help` on every command.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace vsurg::cli {

// args excludes the program name. Writes results to `out`, diagnostics to `err`.
int RunVsurgSim(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace vsurg::cli
