#include "common/tissue/coil_calibration.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <Eigen/Dense>

namespace vsurg::tissue {
namespace {

constexpr double kFullTurn = 2.0 * std::numbers::pi;  // rad

struct Sample {
  double torque, rho, twist, weight;
  bool curve;
};

// Each group (the curve; each profile) contributes its mean squared relative error.
Expected<std::vector<Sample>> Samples(const CalibrationReference& ref) {
  std::vector<Sample> out;
  if (ref.curve_torque.size() != ref.curve_twist.size()) {
    return InvalidArgument("curve", "torque–twist curve has " +
                                        std::to_string(ref.curve_torque.size()) + " torques but " +
                                        std::to_string(ref.curve_twist.size()) + " twists");
  }
  auto finite = [](double x) { return std::isfinite(x); };
  double curve_scale = 0;
  for (double t : ref.curve_twist) curve_scale = std::max(curve_scale, std::abs(t));
  for (size_t i = 0; i < ref.curve_torque.size(); ++i) {
    if (!finite(ref.curve_torque[i]) || !finite(ref.curve_twist[i])) {
      return InvalidArgument("curve", "torque–twist point " + std::to_string(i) + " is not finite");
    }
    if (curve_scale > 0) {
      out.push_back({ref.curve_torque[i], 0.0, ref.curve_twist[i],
                     1.0 / (curve_scale * curve_scale * ref.curve_torque.size()), true});
    }
  }
  size_t profile_samples = 0;
  for (const TwistProfile& p : ref.profiles) profile_samples += p.rho.size();
  for (size_t k = 0; k < ref.profiles.size(); ++k) {
    const TwistProfile& p = ref.profiles[k];
    if (p.rho.size() != p.twist.size() || (!p.weight.empty() && p.weight.size() != p.rho.size())) {
      return InvalidArgument(
          "profiles", "profile " + std::to_string(k) + " has unequal rho, twist and weight sizes");
    }
    double mean_weight = 0;
    for (double w : p.weight) {
      if (!(w >= 0) || !std::isfinite(w))
        return InvalidArgument("profiles", "profile " + std::to_string(k) + " has a bad weight");
      mean_weight += w / p.weight.size();
    }
    double scale = 0;
    for (double t : p.twist) scale = std::max(scale, std::abs(t));
    if (!finite(p.torque))
      return InvalidArgument("profiles", "profile " + std::to_string(k) + " torque is not finite");
    for (size_t i = 0; i < p.rho.size(); ++i) {
      if (!finite(p.rho[i]) || !finite(p.twist[i]) || p.rho[i] < 0) {
        return InvalidArgument("profiles", "profile " + std::to_string(k) + " sample " +
                                               std::to_string(i) +
                                               " is not a finite twist at a distance ≥ 0");
      }
      const double w = p.weight.empty() || !(mean_weight > 0) ? 1.0 : p.weight[i] / mean_weight;
      if (scale > 0) {
        out.push_back(
            {p.torque, p.rho[i], p.twist[i], w / (scale * scale * profile_samples), false});
      }
    }
  }
  if (out.empty())
    return InvalidArgument("reference", "the reference has no non-zero twist to fit");
  return out;
}

// row_i = κ·M_i·l_i·w_i(ρ) for the capacities of `m` (its rigidities are ignored).
void BasisRow(const CoilSpringModel& m, double torque, double rho,
              Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> row) {
  row.setZero();
  const double sign = torque < 0 ? -1.0 : 1.0;
  const double a = std::min(std::abs(torque), m.Capacity());
  if (a == 0) return;
  const int s = m.coils();
  int p = 1;
  double below = 0;  // Q_{p−1}
  while (p < s && below + m.CoilCapacity(p) < a) below += m.CoilCapacity(p++);
  const double r = m.params().core_radius, h = m.params().thickness;
  for (int i = 1; i <= p; ++i) {
    const double m_i = i < p ? m.CoilCapacity(i) : a - below;
    double w = 0;
    if (rho <= r) {
      w = 1;
    } else if (rho < m.RingRadius(p)) {
      const int k = std::clamp(static_cast<int>(std::ceil((rho - r) / h)), 1, p);
      const double t = std::clamp((rho - m.RingRadius(k - 1)) / h, 0.0, 1.0);
      w = i > k ? 1.0 : (i == k ? 1.0 - t : 0.0);
    }
    row[i - 1] = sign * m.params().friction * m_i * kFullTurn * m.RingRadius(i) * w;
  }
}

// Lawson–Hanson active-set NNLS: min |A x − b| subject to x ≥ 0.
Eigen::VectorXd Nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const int n = static_cast<int>(A.cols());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  std::vector<bool> passive(n, false);
  const double tol = 1e-12 * std::max(1.0, A.norm() * b.norm());
  for (int outer = 0; outer < 3 * n + 10; ++outer) {
    const Eigen::VectorXd w = A.transpose() * (b - A * x);
    int j = -1;
    for (int i = 0; i < n; ++i) {
      if (!passive[i] && w[i] > tol && (j < 0 || w[i] > w[j])) j = i;
    }
    if (j < 0) break;
    passive[j] = true;
    for (int inner = 0; inner < 3 * n + 10; ++inner) {
      std::vector<int> idx;
      for (int i = 0; i < n; ++i)
        if (passive[i]) idx.push_back(i);
      Eigen::MatrixXd Ap(A.rows(), idx.size());
      for (size_t c = 0; c < idx.size(); ++c) Ap.col(c) = A.col(idx[c]);
      const Eigen::VectorXd sp = Ap.completeOrthogonalDecomposition().solve(b);
      Eigen::VectorXd s = Eigen::VectorXd::Zero(n);
      for (size_t c = 0; c < idx.size(); ++c) s[idx[c]] = sp[c];
      bool feasible = true;
      for (int i : idx) feasible = feasible && s[i] > 0;
      if (feasible) {
        x = s;
        break;
      }
      double alpha = 1;
      for (int i : idx) {
        if (s[i] <= 0) alpha = std::min(alpha, x[i] / (x[i] - s[i]));
      }
      x += alpha * (s - x);
      for (int i : idx) {
        if (x[i] <= tol) {
          x[i] = 0;
          passive[i] = false;
        }
      }
    }
  }
  return x;
}

struct Trial {
  double objective = INFINITY;  // ‖A·u − b‖² (weighted), without any smoothing penalty
  double reference_norm = 0;    // ‖b‖²
  Eigen::VectorXd compliance;   // u_i = 1/(E·I_i)
};

// Best compliances for one F_t, uniform or per ring.
Trial FitAt(const CoilSpringParams& geometry, double max_force, const std::vector<Sample>& samples,
            bool per_ring, double smoothing = 0) {
  CoilSpringParams p = geometry;
  p.max_force = max_force;
  p.coil_rigidity.clear();
  auto model = CoilSpringModel::Create(p);
  Trial trial;
  if (!model.ok()) return trial;
  const int s = p.coils, n = static_cast<int>(samples.size());
  Eigen::MatrixXd A(n, s);
  Eigen::VectorXd b(n);
  for (int k = 0; k < n; ++k) {
    BasisRow(*model, samples[k].torque, samples[k].rho, A.row(k));
    const double sw = std::sqrt(samples[k].weight);
    A.row(k) *= sw;
    b[k] = sw * samples[k].twist;
  }
  const Eigen::VectorXd g = A.rowwise().sum();
  const double gg = g.squaredNorm();
  if (!(gg > 0)) return trial;
  const double uniform = g.dot(b) / gg;
  if (!(uniform > 0)) return trial;
  trial.compliance = Eigen::VectorXd::Constant(s, uniform);
  if (per_ring && smoothing > 0) {
    // NNLS with a Tikhonov penalty on neighbouring coils' compliance differences, weighted
    // smoothing·‖A‖²/S (Calibrate picks the weight). Coils no load case reaches continue the
    // last reached one's compliance (the penalty's minimum).
    Eigen::MatrixXd as = Eigen::MatrixXd::Zero(n + s - 1, s);
    Eigen::VectorXd bs = Eigen::VectorXd::Zero(n + s - 1);
    as.topRows(n) = A;
    bs.head(n) = b;
    const double lambda = std::sqrt(smoothing * A.squaredNorm() / s);
    for (int i = 0; i + 1 < s; ++i) as(n + i, i) = -lambda, as(n + i, i + 1) = lambda;
    const Eigen::VectorXd u = Nnls(as, bs);
    for (int i = 0; i < s; ++i) trial.compliance[i] = std::max(u[i], 1e-6 * uniform);
  } else if (per_ring) {
    const Eigen::VectorXd u = Nnls(A, b);
    const double floor_u = 1e-6 * uniform;
    for (int i = 0; i < s; ++i) {
      const bool reached = A.col(i).cwiseAbs().maxCoeff() > 0;
      trial.compliance[i] = reached ? std::max(u[i], floor_u) : uniform;
    }
  }
  trial.reference_norm = b.squaredNorm();
  trial.objective = (A * trial.compliance - b).squaredNorm();
  return trial;
}

// The log F_t in [lo, hi] that minimises `objective`: a scan, then golden-section refinement
// inside the scan cell pair around the best point.
template <class Objective>
double SearchLogMaxForce(double lo, double hi, const Objective& objective) {
  constexpr int kScan = 160;
  int best = 0;
  std::vector<double> values(kScan + 1);
  for (int k = 0; k <= kScan; ++k) {
    values[k] = objective(lo + (hi - lo) * k / kScan);
    if (values[k] < values[best]) best = k;
  }
  double a = lo + (hi - lo) * std::max(0, best - 1) / kScan;
  double b = lo + (hi - lo) * std::min(kScan, best + 1) / kScan;
  const double invphi = (std::sqrt(5.0) - 1) / 2;
  double c = b - invphi * (b - a), d = a + invphi * (b - a);
  double fc = objective(c), fd = objective(d);
  for (int it = 0; it < 60; ++it) {
    if (fc < fd) {
      b = d, d = c, fd = fc;
      c = b - invphi * (b - a), fc = objective(c);
    } else {
      a = c, c = d, fc = fd;
      d = a + invphi * (b - a), fd = objective(d);
    }
  }
  double log_f = lo + (hi - lo) * best / kScan;
  if (std::min(fc, fd) < values[best]) log_f = fc < fd ? c : d;
  return log_f;
}

Expected<CalibrationFit> Calibrate(const CoilSpringParams& geometry,
                                   const CalibrationReference& ref, bool per_ring,
                                   bool fit_max_force) {
  if (auto check = CoilSpringModel::Create(geometry); !check.ok()) return check.error();
  auto samples = Samples(ref);
  if (!samples.ok()) return samples.error();
  double max_torque = 0;
  for (const Sample& s : *samples) max_torque = std::max(max_torque, std::abs(s.torque));
  if (!(max_torque > 0))
    return InvalidArgument("reference", "the reference has no non-zero torque");
  double sum_r = 0;
  for (int i = 1; i <= geometry.coils; ++i) sum_r += geometry.core_radius + i * geometry.thickness;
  // F_t from "capacity is 30% of the largest torque" to "coil 1 alone holds 3× the largest".
  const double lo = std::log(0.3 * max_torque / (kFullTurn * sum_r));
  const double hi =
      std::log(3.0 * max_torque / (kFullTurn * (geometry.core_radius + geometry.thickness)));
  auto objective = [&](double log_f) {
    return FitAt(geometry, std::exp(log_f), *samples, per_ring).objective;
  };
  double max_force = geometry.max_force;  // F_t held: the capacity stays the geometry's
  if (fit_max_force) max_force = std::exp(SearchLogMaxForce(lo, hi, objective));
  Trial trial = FitAt(geometry, max_force, *samples, per_ring);
  if (per_ring && std::isfinite(trial.objective)) {
    // The profiles pin down sums over neighbouring coils better than each coil, and NNLS alone
    // can alternate by 30× from one coil to the next (the arm against Saint-Venant: E·I_i from
    // 0.14 to 4.6 N·m²). Take the smoothest fit whose residual stays within 5% of the best
    // (the arm: 16.8% → 17.1% profile RMS, rigidities growing outwards, 0.6 → 3.3 N·m²); on
    // exact data the tolerance leaves no room and the fit is the plain NNLS one.
    for (double smoothing = 1.0; smoothing >= 1e-6; smoothing *= 0.1) {
      const Trial smooth = FitAt(geometry, max_force, *samples, per_ring, smoothing);
      if (smooth.objective <= 1.05 * trial.objective + 1e-14 * trial.reference_norm) {
        trial = smooth;
        break;
      }
    }
  }
  if (!std::isfinite(trial.objective)) {
    return Error{ErrorCode::kNumerical, "calibration found no positive compliance", "reference"};
  }
  CoilSpringParams fitted = geometry;
  fitted.max_force = max_force;
  const double section = geometry.width * std::pow(geometry.thickness, 3) / 12.0;  // I, m⁴
  std::vector<double> rigidity(geometry.coils);
  for (int i = 0; i < geometry.coils; ++i) rigidity[i] = 1.0 / trial.compliance[i];
  std::vector<double> sorted = rigidity;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double typical = sorted[sorted.size() / 2];
  fitted.modulus = typical / section;
  fitted.coil_rigidity = per_ring ? rigidity : std::vector<double>{};
  auto model = CoilSpringModel::Create(fitted);
  if (!model.ok()) return model.error();
  CalibrationFit fit = Residuals(*model, ref);
  fit.params = fitted;
  fit.flexural_rigidity = typical;
  fit.max_force = max_force;
  return fit;
}

}  // namespace

CalibrationReference SaintVenantCalibrationReference(const TaperedShaft& shaft, double max_torque,
                                                     int torques, int samples) {
  CalibrationReference ref;
  for (int k = 1; k <= torques; ++k) {
    const double m = max_torque * k / torques;
    ref.curve_torque.push_back(m);
    ref.curve_twist.push_back(SaintVenantTwistFromGrasp(shaft, m, 0.0));
    TwistProfile prof{m, {}, {}, {}};
    for (int i = 0; i < samples; ++i) {
      prof.rho.push_back(samples > 1 ? shaft.length * i / (samples - 1) : 0.0);
      prof.twist.push_back(SaintVenantTwistFromGrasp(shaft, m, prof.rho.back()));
    }
    ref.profiles.push_back(std::move(prof));
  }
  return ref;
}

CalibrationFit Residuals(const CoilSpringModel& model, const CalibrationReference& ref) {
  CalibrationFit fit;
  CoilState st = model.MakeState();
  double scale = 0;
  for (double t : ref.curve_twist) scale = std::max(scale, std::abs(t));
  double sq = 0;
  for (size_t i = 0; i < ref.curve_torque.size() && scale > 0; ++i) {
    model.Forward(ref.curve_torque[i], st);
    const double e = std::abs(st.total_twist - ref.curve_twist[i]) / scale;
    sq += e * e;
    fit.curve_max = std::max(fit.curve_max, e);
  }
  if (!ref.curve_torque.empty()) fit.curve_rms = std::sqrt(sq / ref.curve_torque.size());
  sq = 0;
  size_t count = 0;
  for (const TwistProfile& p : ref.profiles) {
    double pscale = 0;
    for (double t : p.twist) pscale = std::max(pscale, std::abs(t));
    if (!(pscale > 0)) continue;
    model.Forward(p.torque, st);
    for (size_t i = 0; i < p.rho.size(); ++i) {
      const double e = std::abs(model.TwistAt(p.rho[i], st) - p.twist[i]) / pscale;
      sq += e * e;
      fit.profile_max = std::max(fit.profile_max, e);
      ++count;
    }
  }
  if (count > 0) fit.profile_rms = std::sqrt(sq / count);
  fit.params = model.params();
  fit.max_force = model.params().max_force;
  return fit;
}

Expected<CalibrationFit> CalibrateTwoParameter(const CoilSpringParams& geometry,
                                               const CalibrationReference& reference) {
  return Calibrate(geometry, reference, false, true);
}

Expected<CalibrationFit> CalibratePerRing(const CoilSpringParams& geometry,
                                          const CalibrationReference& reference) {
  return Calibrate(geometry, reference, true, true);
}

Expected<CalibrationFit> CalibratePerRingAtCapacity(const CoilSpringParams& geometry,
                                                    const CalibrationReference& reference) {
  return Calibrate(geometry, reference, true, false);
}

}  // namespace vsurg::tissue
