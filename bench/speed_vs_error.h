// vsurg-bench speed-vs-error [--quick] [--out DIR] [--benchmarks FILE]
//
// Runs every model (coil-spring as the paper gives it with the two-parameter calibration and
// with the per-ring calibration, the scene's own coil parameters, the mass-spring model with
// each integrator, the ring-layer model, the FEM at each refinement) on the same scenes against
// the same reference, and writes DIR/speed-vs-error.csv (one row per model and setting:
// model, scene, setting, time_per_update_us, rms_error, max_error, size, budget, meets_budget,
// note), DIR/speed-vs-error.png (time per update against error, log axes, one colour per
// model), DIR/marker8.png (marker 8 during the arm ramp, the coil-spring paper Fig. 10), and the
// Markdown table into BENCHMARKS.md (DIR/BENCHMARKS.md when DIR is docs, or --benchmarks). Each
// scene names the cheapest model within its error budget. A progress bar on stderr.
#pragma once

#include <string>
#include <vector>

namespace vsurg::bench {

int SpeedVsError(const std::vector<std::string>& args);

}  // namespace vsurg::bench
