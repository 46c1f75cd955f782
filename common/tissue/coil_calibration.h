// Calibration of the coil-spring model against a reference (DESIGN.md "Model 1").
//
// The paper's parameters are phenomenological, so they are fitted to a reference torque–twist
// curve (the twist at the grasp for several torques) and twist profiles (the twist against the
// distance ρ from the grasp, at given torques), from Saint-Venant or the FEM.
//
// With the geometry (r, h, S, b, κ) fixed and F_t fixed, every twist the model predicts is
// linear in the coil compliances u_i = 1/(E·I_i):
//   θ(ρ; M) = Σ_i u_i · κ·M_i(M)·l_i·w_i(ρ),   w_i = 1 outside ρ's ring, 1 − t in it, 0 inside,
// so for a given F_t the best compliances are a linear least-squares problem. Two fits:
//   * two-parameter (the paper's model): one u for all coils, in closed form, and F_t by a
//     scan plus golden-section search on log F_t;
//   * per-ring (beyond the paper): one u_i per coil by non-negative least squares (Lawson &
//     Hanson 1974), same search on F_t, or F_t held (the capacity kept). The model keeps its cost
//     per update; it becomes a reduced-order model of the reference. The NNLS carries a Tikhonov
//     penalty on neighbouring coils' compliance differences (smooth, outward-growing rigidities
//     instead of a 30× zig-zag), so coils no load case reaches continue the last reached one; a
//     zero fitted compliance is floored (the ring is then nearly rigid).
// Residuals are reported relative to the reference's largest |twist|: for the curve over all
// its points, for each profile over that profile (RMS and max over all profile samples).
//
// Set-up code: allocates, may take tens of milliseconds.
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/torsion_reference.h"

namespace vsurg::tissue {

struct TwistProfile {
  double torque = 0;          // N·m
  std::vector<double> rho;    // distance from the grasp, m
  std::vector<double> twist;  // rad
  // Optional relative weights of the samples (empty: all 1). A surface grasp weights each
  // sample by its squared lever arm, so the fit matches displacements rather than angles.
  std::vector<double> weight;
};

struct CalibrationReference {
  std::vector<double> curve_torque;  // N·m
  std::vector<double> curve_twist;   // rad, the twist at the grasp (ρ = 0)
  std::vector<TwistProfile> profiles;
};

struct CalibrationFit {
  CoilSpringParams params;       // the fitted model's parameters
  double flexural_rigidity = 0;  // E·I of the two-parameter fit (N·m²); per-ring: their median
  double max_force = 0;          // F_t, N
  double curve_rms = 0, curve_max = 0;      // relative residuals of the torque–twist curve
  double profile_rms = 0, profile_max = 0;  // relative residuals of the profiles
};

// `geometry` supplies r, h, S, b, κ (and is validated); its E, F_t and per-coil rigidities are
// the unknowns.
Expected<CalibrationFit> CalibrateTwoParameter(const CoilSpringParams& geometry,
                                               const CalibrationReference& reference);
Expected<CalibrationFit> CalibratePerRing(const CoilSpringParams& geometry,
                                          const CalibrationReference& reference);
// Per ring with F_t held at the geometry's: the capacity Σ C_i (a scene's largest torque, e.g.
// the forearm's 3.3 N·m) stays what the scene says, and only the compliances are fitted (one
// NNLS). What a scene file's "coil_rigidity" comes from.
Expected<CalibrationFit> CalibratePerRingAtCapacity(const CoilSpringParams& geometry,
                                                    const CalibrationReference& reference);

// A Saint-Venant reference for a shaft grasped at its distal end: the torque–twist curve at
// `torques` torques evenly up to max_torque (N·m) and, at each, the profile at `samples` distances
// evenly from the grasp (ρ = 0) to the fixed end (ρ = L).
CalibrationReference SaintVenantCalibrationReference(const TaperedShaft& shaft, double max_torque,
                                                     int torques, int samples = 26);

// Relative residuals of a given model against a reference (what the fits report).
CalibrationFit Residuals(const CoilSpringModel& model, const CalibrationReference& reference);

}  // namespace vsurg::tissue
