// Analytic torsion references (DESIGN.md "Model 3", validation): Saint-Venant torsion of a
// circular shaft. A shaft of radius a(z), shear modulus G, fixed at z = 0 and loaded by an end
// torque T at z = L twists at the rate dθ/dz = T / (G·J(z)), J(z) = π·a(z)⁴/2 (polar second
// moment). For the linear taper a(z) = a₀ + (a₁ − a₀)·z/L the integral is closed-form:
//   θ(z) = 2T/(πG) · L/(3(a₁ − a₀)) · (a₀⁻³ − a(z)⁻³),   and θ(z) = 2T·z/(πG·a₀⁴) when a₁ = a₀.
// Units: m, Pa, N·m, rad.
#pragma once

namespace vsurg::tissue {

struct TaperedShaft {
  double length = 0.25;           // L, m
  double radius_proximal = 0.04;  // a₀ at the fixed end z = 0, m
  double radius_distal = 0.03;    // a₁ at the loaded end z = L, m
  double shear_modulus = 12e3;    // G, Pa
};

// Rotation (rad) of the cross-section at z ∈ [0, L] relative to the fixed end.
double SaintVenantTwistAt(const TaperedShaft& shaft, double torque, double z);

// The same, as a function of the distance ρ from the loaded (grasped) end: θ(L − ρ).
inline double SaintVenantTwistFromGrasp(const TaperedShaft& shaft, double torque, double rho) {
  return SaintVenantTwistAt(shaft, torque, shaft.length - rho);
}

}  // namespace vsurg::tissue
