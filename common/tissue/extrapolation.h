// The implicit solvers' first guess for a step's Δv: a polynomial extrapolation from the last
// steps' Δv, of the degree (1 to 3) whose guess for the last step was closest. A smooth drive is
// guessed better by the higher degrees; a loose tolerance's residual, carried in every Δv, is
// amplified more by them (their coefficients sum in magnitude to 3, 7 and 15): the measured
// choice takes the better of the two effects for each scene, tolerance and moment.
#pragma once

namespace vsurg::tissue {

// The guess of degree `degree` for the next value after x1 (the newest), x2, x3, x4: 2x₁ − x₂;
// 3(x₁ − x₂) + x₃; 4(x₁ + x₃) − 6x₂ − x₄. T: a 3-vector type with + − and scalar ×. By reference
// (simd::V4 is never passed by value: the hot loops' clones differ in ABI).
template <class T>
inline void Extrapolate(T& out, int degree, const T& x1, const T& x2, const T& x3, const T& x4) {
  if (degree <= 1) {
    out = 2.0 * x1 - x2;
  } else if (degree == 2) {
    out = 3.0 * (x1 - x2) + x3;
  } else {
    out = 4.0 * (x1 + x3) - 6.0 * x2 - x4;
  }
}

// The degree (1 to `most`) with the smallest summed squared miss, ties to the lower degree.
inline int BestDegree(double miss1, double miss2, double miss3, int most) {
  if (most >= 3 && miss3 < miss2 && miss3 < miss1) return 3;
  return most >= 2 && miss2 < miss1 ? 2 : 1;
}

}  // namespace vsurg::tissue
