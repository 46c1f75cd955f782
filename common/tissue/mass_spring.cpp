#include "common/tissue/mass_spring.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <utility>

#include "common/tissue/extrapolation.h"
#include "common/tissue/simd.h"
#include "common/tissue/text.h"

namespace vsurg::tissue {
namespace {

// Springs shorter than this have no direction and exert no force.
constexpr double kMinLength = 1e-12;

bool Finite(double x) {
  return std::isfinite(x);
}

using detail::Num;

void AddSpring(MassSpringSystem& s, int i, int j, double k, double c, SpringKind kind) {
  s.springs.push_back({i, j, k, c, (s.rest_positions[j] - s.rest_positions[i]).norm()});
  s.kinds.push_back(kind);
}

// Orders springs by their first then second particle (i < j after the swap), so the spring loops
// walk the particle arrays forward, and keep the running sum for particle i in registers,
// writing it once per particle instead of once per spring (measured: neither faster nor slower
// on this machine, where the sqrt/div chain dominates; it halves the stores).
void SortSprings(MassSpringSystem& s) {
  for (Spring& sp : s.springs) {
    if (sp.i > sp.j) std::swap(sp.i, sp.j);
  }
  std::vector<size_t> order(s.springs.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return std::pair(s.springs[a].i, s.springs[a].j) < std::pair(s.springs[b].i, s.springs[b].j);
  });
  std::vector<Spring> springs(order.size());
  std::vector<SpringKind> kinds(order.size());
  for (size_t k = 0; k < order.size(); ++k)
    springs[k] = s.springs[order[k]], kinds[k] = s.kinds[order[k]];
  s.springs = std::move(springs);
  s.kinds = std::move(kinds);
}

}  // namespace

const char* IntegratorName(Integrator integrator) {
  switch (integrator) {
    case Integrator::kExplicitEuler:
      return "explicit-euler";
    case Integrator::kSymplecticEuler:
      return "symplectic-euler";
    case Integrator::kMidpoint:
      return "midpoint";
    case Integrator::kRk4:
      return "rk4";
    case Integrator::kVerlet:
      return "verlet";
    case Integrator::kImplicitEuler:
      return "implicit-euler";
  }
  return "?";
}

Expected<Integrator> ParseIntegrator(std::string_view name) {
  for (Integrator i : kAllIntegrators) {
    if (name == IntegratorName(i)) return i;
  }
  return InvalidArgument("integrator", "unknown integrator '" + std::string(name) +
                                           "' (explicit-euler, symplectic-euler, midpoint, rk4, "
                                           "verlet, implicit-euler)");
}

Expected<MassSpringSystem> BuildMassSpring(const geometry::TriMesh& mesh,
                                           const MassSpringBuildParams& p) {
  if (Status s = geometry::Validate(mesh); !s.ok()) return s.error();
  if (mesh.triangles.empty()) return InvalidArgument("mesh", "mesh has no triangles");
  if (!(Finite(p.total_mass) && p.total_mass > 0)) {
    return InvalidArgument("total_mass",
                           "total mass must be finite and > 0 kg, got " + Num(p.total_mass));
  }
  if (!(Finite(p.structural_stiffness) && p.structural_stiffness > 0)) {
    return InvalidArgument(
        "structural_stiffness",
        "structural stiffness must be finite and > 0 N/m, got " + Num(p.structural_stiffness));
  }
  if (!(Finite(p.bending_stiffness) && p.bending_stiffness >= 0)) {
    return InvalidArgument(
        "bending_stiffness",
        "bending stiffness must be finite and ≥ 0 N/m, got " + Num(p.bending_stiffness));
  }
  if (!(Finite(p.damping) && p.damping >= 0)) {
    return InvalidArgument("damping",
                           "damping must be finite and ≥ 0 N·s/m, got " + Num(p.damping));
  }
  const bool layer = p.volume == VolumeMode::kInnerLayer;
  if (layer && !(Finite(p.volume_stiffness) && p.volume_stiffness > 0)) {
    return InvalidArgument("volume_stiffness", "volume stiffness must be finite and > 0 N/m, got " +
                                                   Num(p.volume_stiffness));
  }
  if (layer && !(Finite(p.layer_depth) && p.layer_depth > 0)) {
    return InvalidArgument("layer_depth",
                           "inner layer depth must be finite and > 0 m, got " + Num(p.layer_depth));
  }

  MassSpringSystem s;
  const int n = mesh.VertexCount();
  s.surface_particles = n;
  s.rest_positions = mesh.positions;
  if (layer) {
    geometry::TriMesh copy = mesh;
    geometry::ComputeVertexNormals(copy);
    for (int i = 0; i < n; ++i)
      s.rest_positions.push_back(mesh.positions[i] - p.layer_depth * copy.normals[i]);
  }
  s.masses.assign(s.rest_positions.size(),
                  p.total_mass / static_cast<double>(s.rest_positions.size()));

  const auto edges = geometry::UniqueEdges(mesh);
  for (const auto& e : edges)
    AddSpring(s, e[0], e[1], p.structural_stiffness, p.damping, SpringKind::kStructural);
  if (p.bending_stiffness > 0) {
    // The two vertices opposite each interior edge.
    std::map<std::pair<int, int>, std::vector<int>> opposite;
    for (const geometry::Triangle& t : mesh.triangles) {
      for (int k = 0; k < 3; ++k) {
        const int a = t[k], b = t[(k + 1) % 3];
        opposite[{std::min(a, b), std::max(a, b)}].push_back(t[(k + 2) % 3]);
      }
    }
    for (const auto& [edge, opp] : opposite) {
      if (opp.size() == 2 && opp[0] != opp[1]) {
        AddSpring(s, std::min(opp[0], opp[1]), std::max(opp[0], opp[1]), p.bending_stiffness,
                  p.damping, SpringKind::kBending);
      }
    }
  }
  if (layer) {
    for (const auto& e : edges) {
      AddSpring(s, n + e[0], n + e[1], p.volume_stiffness, p.damping, SpringKind::kVolume);
      AddSpring(s, e[0], n + e[1], p.volume_stiffness, p.damping, SpringKind::kVolume);
      AddSpring(s, e[1], n + e[0], p.volume_stiffness, p.damping, SpringKind::kVolume);
    }
    for (int i = 0; i < n; ++i)
      AddSpring(s, i, n + i, p.volume_stiffness, p.damping, SpringKind::kVolume);
  }
  return s;
}

Expected<MassSpringSystem> BuildMassSpring(const geometry::TetMesh& mesh, double density,
                                           double stiffness, double damping) {
  if (Status s = geometry::Validate(mesh); !s.ok()) return s.error();
  if (!(Finite(density) && density > 0))
    return InvalidArgument("density", "density must be > 0 kg/m^3");
  if (!(Finite(stiffness) && stiffness > 0))
    return InvalidArgument("stiffness", "stiffness must be > 0 N/m");
  if (!(Finite(damping) && damping >= 0))
    return InvalidArgument("damping", "damping must be ≥ 0 N·s/m");
  MassSpringSystem s;
  s.rest_positions = mesh.positions;
  s.masses.assign(mesh.positions.size(), 0.0);
  std::vector<std::pair<int, int>> edges;
  for (int t = 0; t < mesh.TetCount(); ++t) {
    const double quarter = density * geometry::TetVolume(mesh, t) / 4.0;
    const auto& k = mesh.tetrahedra[t];
    for (int a = 0; a < 4; ++a) {
      s.masses[k[a]] += quarter;
      for (int b = a + 1; b < 4; ++b)
        edges.emplace_back(std::min(k[a], k[b]), std::max(k[a], k[b]));
    }
  }
  for (size_t i = 0; i < s.masses.size(); ++i) {
    if (!(s.masses[i] > 0))
      return InvalidArgument("tetrahedra", "vertex " + std::to_string(i) + " is in no tetrahedron");
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [a, b] : edges) AddSpring(s, a, b, stiffness, damping, SpringKind::kVolume);
  return s;
}

Expected<MassSpringModel> MassSpringModel::Create(MassSpringSystem sys,
                                                  const MassSpringStepParams& params) {
  const int n = static_cast<int>(sys.rest_positions.size());
  if (n == 0) return InvalidArgument("particles", "the system has no particles");
  if (static_cast<int>(sys.masses.size()) != n) {
    return InvalidArgument("masses", "need one mass per particle: " + std::to_string(n) +
                                         " particles, " + std::to_string(sys.masses.size()) +
                                         " masses");
  }
  for (int i = 0; i < n; ++i) {
    if (!sys.rest_positions[i].allFinite()) {
      return InvalidArgument("positions",
                             "particle " + std::to_string(i) + " position is not finite");
    }
    if (!(Finite(sys.masses[i]) && sys.masses[i] > 0)) {
      return InvalidArgument("masses", "particle " + std::to_string(i) +
                                           " mass must be finite and > 0 kg, got " +
                                           Num(sys.masses[i]));
    }
  }
  for (size_t s = 0; s < sys.springs.size(); ++s) {
    const Spring& sp = sys.springs[s];
    const std::string name = "spring " + std::to_string(s);
    if (sp.i < 0 || sp.i >= n || sp.j < 0 || sp.j >= n || sp.i == sp.j) {
      return InvalidArgument(
          "springs", name + " must join two distinct particles in 0.." + std::to_string(n - 1));
    }
    if (!(Finite(sp.stiffness) && sp.stiffness > 0)) {
      return InvalidArgument(
          "springs", name + " stiffness must be finite and > 0 N/m, got " + Num(sp.stiffness));
    }
    if (!(Finite(sp.damping) && sp.damping >= 0)) {
      return InvalidArgument(
          "springs", name + " damping must be finite and ≥ 0 N·s/m, got " + Num(sp.damping));
    }
    if (!(Finite(sp.rest_length) && sp.rest_length >= 0)) {
      return InvalidArgument(
          "springs", name + " rest length must be finite and ≥ 0 m, got " + Num(sp.rest_length));
    }
  }
  if (!(params.cg_max_iterations >= 1 && Finite(params.cg_tolerance) && params.cg_tolerance > 0)) {
    return InvalidArgument("cg", "conjugate gradient needs ≥ 1 iteration and a tolerance > 0");
  }
  if (!(params.cg_extrapolation >= 1 && params.cg_extrapolation <= 3)) {
    return InvalidArgument("cg_extrapolation", "the first guess's degree must be 1 to 3, got " +
                                                   std::to_string(params.cg_extrapolation));
  }
  if (!params.gravity.allFinite()) return InvalidArgument("gravity", "gravity must be finite");
  if (!(params.divergence_distance > 0))
    return InvalidArgument("divergence_distance", "must be > 0 m");
  if (sys.kinds.size() != sys.springs.size())
    sys.kinds.assign(sys.springs.size(), SpringKind::kStructural);
  SortSprings(sys);

  MassSpringModel m;
  m.params_ = params;
  m.role_.assign(n, Role::kFree);
  m.inv_mass_.resize(n);
  for (int i = 0; i < n; ++i) m.inv_mass_[i] = 1.0 / sys.masses[i];
  m.x_ = sys.rest_positions;
  m.v_.assign(n, Vec3::Zero());
  m.f_ext_.assign(n, Vec3::Zero());
  m.kin_start_.assign(n, Vec3::Zero());
  m.kin_target_.assign(n, Vec3::Zero());
  for (auto* buf :
       {&m.a_, &m.tx_, &m.tv_, &m.k1v_, &m.k2x_, &m.k2v_, &m.k3x_, &m.k3v_, &m.kin_final_}) {
    buf->assign(n, Vec3::Zero());
  }
  for (auto* buf : {&m.dv_, &m.r_, &m.p_, &m.q_, &m.precond_, &m.pos_, &m.diag_, &m.inv_diag_,
                    &m.history_[0], &m.history_[1], &m.history_[2], &m.history_[3]}) {
    buf->assign(n, simd::Lane4{});
  }
  m.state_.assign(n, simd::Lane8{});
  m.sums_.assign(n, simd::Lane8{});
  const size_t ns = sys.springs.size();
  m.ends_.reserve(ns);
  m.dirs_.assign(ns, simd::Lane4{});
  for (auto* buf : {&m.coef_a_, &m.coef_b_}) buf->assign(ns, 0.0);
  for (auto* buf : {&m.rest_, &m.stiffness_, &m.damping_}) buf->reserve(ns);
  m.constrained_.reserve(n);
  m.kinematic_.reserve(n);
  m.anchors_.reserve(kMaxAnchors);
  m.sys_ = std::move(sys);
  return m;
}

void MassSpringModel::SelectSolverSprings() {
  ends_.clear(), rest_.clear(), stiffness_.clear(), damping_.clear();  // capacity kept
  for (const Spring& sp : sys_.springs) {
    if (role_[sp.i] != Role::kFree && role_[sp.j] != Role::kFree) continue;
    ends_.push_back({sp.i, sp.j});
    rest_.push_back(sp.rest_length), stiffness_.push_back(sp.stiffness);
    damping_.push_back(sp.damping);
  }
  solver_springs_stale_ = false;
}

void MassSpringModel::SetFixed(int i, bool fixed) {
  if (role_[i] == Role::kKinematic) SetKinematic(i, false);
  role_[i] = fixed ? Role::kFixed : Role::kFree;
  solver_springs_stale_ = true;
  v_[i].setZero();
  verlet_primed_ = false;
  lanes_ = false;
}

void MassSpringModel::SetKinematic(int i, bool kinematic) {
  const auto it = std::find(kinematic_.begin(), kinematic_.end(), i);
  if (kinematic && it == kinematic_.end()) kinematic_.push_back(i);
  if (!kinematic && it != kinematic_.end()) kinematic_.erase(it);
  role_[i] = kinematic ? Role::kKinematic : Role::kFree;
  solver_springs_stale_ = true;
  kin_target_[i] = x_[i];
  v_[i].setZero();
  verlet_primed_ = false;
  lanes_ = false;
}

void MassSpringModel::SetKinematicTarget(int i, const Vec3& target) {
  if (role_[i] == Role::kKinematic && target.allFinite()) kin_target_[i] = target;
}

void MassSpringModel::SetExternalForce(int i, const Vec3& force) {
  f_ext_[i] = force.allFinite() ? force : Vec3::Zero();  // NaN never enters the state
  verlet_primed_ = false;
}

void MassSpringModel::ClearExternalForces() {
  std::fill(f_ext_.begin(), f_ext_.end(), Vec3::Zero());
  verlet_primed_ = false;
}

void MassSpringModel::SetAnchor(int i, const Vec3& target, double stiffness, double damping) {
  if (!target.allFinite() || !(stiffness >= 0) || !(damping >= 0) || !std::isfinite(stiffness) ||
      !std::isfinite(damping)) {
    return;  // NaN never enters the state
  }
  // At most kMaxAnchors, in storage reserved once (a copied model's vector has no spare
  // capacity: it reserves on its first anchor, not on every one).
  if (anchors_.size() >= kMaxAnchors) return;
  if (anchors_.capacity() < kMaxAnchors) anchors_.reserve(kMaxAnchors);
  anchors_.push_back({i, target, stiffness, damping});
  verlet_primed_ = false;
}

void MassSpringModel::ClearAnchors() {
  anchors_.clear();
  verlet_primed_ = false;
}

void MassSpringModel::SetIntegrator(Integrator integrator) {
  params_.integrator = integrator;
  verlet_primed_ = false;
  diag_age_ = kDiagEvery;  // the implicit step's diagonal may be from long ago: sum it again
}

// eq. 3-5, 3-6 with the damping sign of DESIGN.md; see the header.
void MassSpringModel::Forces(const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                             std::vector<Vec3>& f) const {
  const int n = static_cast<int>(x.size());
  for (int i = 0; i < n; ++i) f[i] = f_ext_[i] + sys_.masses[i] * params_.gravity;
  for (const Anchor& a : anchors_) f[a.i] += a.k * (a.target - x[a.i]) - a.c * v[a.i];
  // Scalar kernel over raw doubles: Eigen's 3-vectors cost about twice the instructions here.
  const double* X = x.data()->data();
  const double* V = v.data()->data();
  double* F = f.data()->data();
  int cur = -1;
  double ax = 0, ay = 0, az = 0;  // running force on particle `cur`
  for (const Spring& s : sys_.springs) {
    const int i = 3 * s.i, j = 3 * s.j;
    if (i != cur) {
      if (cur >= 0) F[cur] += ax, F[cur + 1] += ay, F[cur + 2] += az;
      cur = i, ax = ay = az = 0;
    }
    const double lx = X[j] - X[i], ly = X[j + 1] - X[i + 1], lz = X[j + 2] - X[i + 2];
    const double len = std::sqrt(lx * lx + ly * ly + lz * lz);
    if (len < kMinLength) continue;
    const double inv = 1.0 / len;
    const double dx = lx * inv, dy = ly * inv, dz = lz * inv;
    const double rel = (V[j] - V[i]) * dx + (V[j + 1] - V[i + 1]) * dy + (V[j + 2] - V[i + 2]) * dz;
    const double mag = s.stiffness * (len - s.rest_length) + s.damping * rel;
    const double fx = mag * dx, fy = mag * dy, fz = mag * dz;
    ax += fx, ay += fy, az += fz;
    F[j] -= fx, F[j + 1] -= fy, F[j + 2] -= fz;
  }
  if (cur >= 0) F[cur] += ax, F[cur + 1] += ay, F[cur + 2] += az;
}

void MassSpringModel::Accelerations(const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                                    std::vector<Vec3>& a) const {
  Forces(x, v, a);
  const int n = static_cast<int>(x.size());
  for (int i = 0; i < n; ++i)
    a[i] = role_[i] == Role::kFree ? Vec3(a[i] * inv_mass_[i]) : Vec3::Zero();
}

void MassSpringModel::PlaceKinematic(std::vector<Vec3>& x, std::vector<Vec3>& v, double alpha,
                                     double h) const {
  for (int i : kinematic_) {
    x[i] = kin_start_[i] + alpha * (kin_target_[i] - kin_start_[i]);
    v[i] = (kin_target_[i] - kin_start_[i]) / h;
  }
}

bool MassSpringModel::Step(double dt, int substeps) {
  if (diverged_) return false;
  if (!(Finite(dt) && dt > 0) || substeps < 1) return false;
  const double h = dt / substeps;
  // Each substep moves kinematic particles an equal share of the way to their targets.
  for (int i : kinematic_) kin_final_[i] = kin_target_[i];
  for (int s = 0; s < substeps; ++s) {
    for (int i : kinematic_) {
      kin_start_[i] = x_[i];
      kin_target_[i] = x_[i] + (kin_final_[i] - x_[i]) / static_cast<double>(substeps - s);
    }
    if (!StepOnce(h)) {
      Reset();
      diverged_ = true;
      return false;
    }
  }
  return true;
}

void MassSpringModel::Reset() {
  std::copy(sys_.rest_positions.begin(), sys_.rest_positions.end(), x_.begin());
  std::fill(v_.begin(), v_.end(), Vec3::Zero());
  std::fill(dv_.begin(), dv_.end(), simd::Lane4{});
  for (auto& h : history_) std::fill(h.begin(), h.end(), simd::Lane4{});
  extrapolation_ = last_extrapolation_ = 1;
  judge_age_ = kJudgeEvery - 1;
  diag_age_ = kDiagEvery;
  for (int i : kinematic_) kin_target_[i] = x_[i];
  verlet_primed_ = false;
  diverged_ = false;
  lanes_ = false;
}

bool MassSpringModel::CheckFinite() const {
  const double limit2 = params_.divergence_distance * params_.divergence_distance;
  for (size_t i = 0; i < x_.size(); ++i) {
    const double d2 = (x_[i] - sys_.rest_positions[i]).squaredNorm();
    if (!(d2 <= limit2) || !v_[i].allFinite()) return false;  // NaN fails the comparison
  }
  return true;
}

bool MassSpringModel::StepOnce(double h) {
  const int n = static_cast<int>(x_.size());
  auto free = [&](int i) { return role_[i] == Role::kFree; };
  if (params_.integrator != Integrator::kImplicitEuler) lanes_ = false;
  switch (params_.integrator) {
    case Integrator::kExplicitEuler:
      PlaceKinematic(x_, v_, 0.0, h);
      Accelerations(x_, v_, a_);
      for (int i = 0; i < n; ++i) {
        if (!free(i)) continue;
        x_[i] += h * v_[i];
        v_[i] += h * a_[i];
      }
      break;
    case Integrator::kSymplecticEuler:
      PlaceKinematic(x_, v_, 0.0, h);
      Accelerations(x_, v_, a_);
      for (int i = 0; i < n; ++i) {
        if (!free(i)) continue;
        v_[i] += h * a_[i];
        x_[i] += h * v_[i];
      }
      break;
    case Integrator::kMidpoint:
      PlaceKinematic(x_, v_, 0.0, h);
      Accelerations(x_, v_, a_);
      for (int i = 0; i < n; ++i) {
        tx_[i] = x_[i] + 0.5 * h * v_[i];
        tv_[i] = v_[i] + 0.5 * h * a_[i];
      }
      PlaceKinematic(tx_, tv_, 0.5, h);
      Accelerations(tx_, tv_, a_);
      for (int i = 0; i < n; ++i) {
        if (!free(i)) continue;
        x_[i] += h * tv_[i];
        v_[i] += h * a_[i];
      }
      break;
    case Integrator::kRk4: {
      PlaceKinematic(x_, v_, 0.0, h);
      Accelerations(x_, v_, k1v_);  // k1 = (v, a(x, v))
      for (int i = 0; i < n; ++i) {
        tx_[i] = x_[i] + 0.5 * h * v_[i];
        k2x_[i] = v_[i] + 0.5 * h * k1v_[i];
      }
      PlaceKinematic(tx_, k2x_, 0.5, h);
      Accelerations(tx_, k2x_, k2v_);
      for (int i = 0; i < n; ++i) {
        tx_[i] = x_[i] + 0.5 * h * k2x_[i];
        k3x_[i] = v_[i] + 0.5 * h * k2v_[i];
      }
      PlaceKinematic(tx_, k3x_, 0.5, h);
      Accelerations(tx_, k3x_, k3v_);
      for (int i = 0; i < n; ++i) {
        tx_[i] = x_[i] + h * k3x_[i];
        tv_[i] = v_[i] + h * k3v_[i];  // k4x
      }
      PlaceKinematic(tx_, tv_, 1.0, h);
      Accelerations(tx_, tv_, a_);  // k4v
      for (int i = 0; i < n; ++i) {
        if (!free(i)) continue;
        x_[i] += h / 6.0 * (v_[i] + 2.0 * k2x_[i] + 2.0 * k3x_[i] + tv_[i]);
        v_[i] += h / 6.0 * (k1v_[i] + 2.0 * k2v_[i] + 2.0 * k3v_[i] + a_[i]);
      }
      break;
    }
    case Integrator::kVerlet:
      // a_ holds a(x_n, ·) from the previous step when primed.
      if (!verlet_primed_) {
        PlaceKinematic(x_, v_, 0.0, h);
        Accelerations(x_, v_, a_);
      }
      for (int i = 0; i < n; ++i) {
        if (!free(i)) continue;
        v_[i] += 0.5 * h * a_[i];  // v_{n+½}
        x_[i] += h * v_[i];
        tv_[i] = v_[i] + 0.5 * h * a_[i];  // predicted v_{n+1} for the damper
      }
      PlaceKinematic(x_, tv_, 1.0, h);
      Accelerations(x_, tv_, a_);
      for (int i = 0; i < n; ++i) {
        if (free(i)) v_[i] += 0.5 * h * a_[i];
      }
      verlet_primed_ = kinematic_.empty();  // a moving boundary changes a(x_n) between steps
      break;
    case Integrator::kImplicitEuler:
      return StepImplicit(h);  // places the driven particles and checks in its last pass
  }
  PlaceKinematic(x_, v_, 1.0, h);
  return CheckFinite();
}

// Baraff & Witkin 1998, one Newton step of backward Euler:
//   (M + h C + h² K) Δv = h (f₀ − h K v₀),   v₁ = v₀ + Δv,   x₁ = x₀ + h v₁.
// Spring s contributes K_s = k [(1 − α) l̂l̂ᵀ + α I], α = max(0, 1 − L/|l|) (transverse term
// clamped: SPD), and C_s = c l̂l̂ᵀ. The system is never assembled: each spring keeps its block
// B_s = h C_s + h² K_s = a_s l̂l̂ᵀ + b_s I, and the product is a pass over the springs.
//
// The solver's per-particle vectors are 4 doubles (the fourth always 0) and its arithmetic is
// written with GCC's vector extension, so one instruction does a 3-vector: AVX2 in the clone
// the loader picks on CPUs that have it, two SSE2 halves in the baseline build.
using simd::Dot;
using simd::V4;
using simd::V8;

VSURG_SIMD_CLONES
bool MassSpringModel::StepImplicit(double h) {
  const int n = static_cast<int>(x_.size());
  // The springs' part of the Jacobi diagonal again this step? (A preconditioner only has to be
  // close: CG reaches the same tolerance from it. The diagonal moves with the springs' directions
  // and stretch, slowly at haptic steps; the anchors' part is added fresh every step.)
  const bool refresh_diag = solver_springs_stale_ || diag_age_ >= kDiagEvery || h != diag_h_;
  if (solver_springs_stale_) SelectSolverSprings();
  auto view = [](std::vector<simd::Lane4>& a) { return reinterpret_cast<V4*>(a.data()); };
  V4 *const dv = view(dv_), *const res = view(r_), *const p = view(p_), *const q = view(q_),
            *const pre = view(precond_), *const pos = view(pos_), *const diag = view(diag_),
            *const inv_diag = view(inv_diag_);
  V8* const state = reinterpret_cast<V8*>(state_.data());
  V4* const state_v = reinterpret_cast<V4*>(state_.data());  // state[i]'s v₀ is state_v[2 i]
  const bool lanes = lanes_;
  V8* const sums = reinterpret_cast<V8*>(sums_.data());
  // Plain pointers: the vector types may alias anything, so a member's data() would be read
  // again after every store through them.
  const SpringEnds* const ends = ends_.data();
  V4* const dirs = view(dirs_);
  double *const coef_a = coef_a_.data(), *const coef_b = coef_b_.data();
  const double *const rest = rest_.data(), *const stiffness = stiffness_.data(),
                      *const damping = damping_.data(), *const mass = sys_.masses.data();
  PlaceKinematic(x_, v_, 0.0, h);
  // Δv's first guess, extrapolated from the last steps' Δv by the polynomial of the degree
  // (1 to 3) that would have guessed the last step's Δv best: its error (over the free
  // particles) is measured here for every degree against Δv₋₁ (still in dv) from Δv₋₂..Δv₋₅.
  // Linear, 2 Δv₋₁ − Δv₋₂, halves the held arm's CG iterations against Δv₋₁ alone; the higher
  // degrees are closer on a smooth drive but carry more of the last solves' residual, so they
  // win at tight tolerances (at 1e-6 the arm needs 2.1 iterations instead of 4.1 with linear)
  // and lose at loose ones (docs/BENCHMARKS.md). Zero where there is no unknown (also for a
  // particle fixed since the last step: the product with the first guess must not see its old
  // Δv).
  //
  // rhs = h (f₀ − h K v₀), q = A Δv₀ (the warm start's product) and pre = diag(A) are summed
  // together: particle terms first (in the same loop), then one pass over the springs, then the
  // anchors. rhs and q are summed as the pair (rhs, −q), the particle state read as the pair
  // (v₀, Δv₀).
  // The history rotates: the oldest buffer (Δv₋₅) takes Δv₋₁ and becomes the newest.
  V4* const o1 = view(history_[h_]);            // Δv₋₂
  V4* const o2 = view(history_[(h_ + 3) % 4]);  // Δv₋₃
  V4* const o3 = view(history_[(h_ + 2) % 4]);  // Δv₋₄
  V4* const o4 = view(history_[(h_ + 1) % 4]);  // Δv₋₅, overwritten with Δv₋₁
  h_ = (h_ + 1) % 4;
  const int degree = last_extrapolation_ = extrapolation_;
  const double h2 = h * h;
  const V4 gravity{params_.gravity.x(), params_.gravity.y(), params_.gravity.z(), 0.0};
  constrained_.clear();
  // The degrees are compared every kJudgeEvery steps (three more extrapolations per particle);
  // the drive's character changes over tens of steps, not from one to the next.
  const bool judge = ++judge_age_ >= kJudgeEvery;
  if (judge) judge_age_ = 0;
  V4 miss1{}, miss2{}, miss3{};  // each degree's squared error on Δv₋₁
  for (int i = 0; i < n; ++i) {
    const V4 last = dv[i];
    V4 d{};
    if (role_[i] != Role::kFree) {
      constrained_.push_back(i);  // capacity reserved: no allocation
      o4[i] = V4{};
    } else {
      if (judge) {
        V4 e1, e2, e3;
        Extrapolate(e1, 1, o1[i], o2[i], o3[i], o4[i]);
        Extrapolate(e2, 2, o1[i], o2[i], o3[i], o4[i]);
        Extrapolate(e3, 3, o1[i], o2[i], o3[i], o4[i]);
        e1 -= last, e2 -= last, e3 -= last;
        miss1 += e1 * e1, miss2 += e2 * e2, miss3 += e3 * e3;
      }
      Extrapolate(d, degree, last, o1[i], o2[i], o3[i]);
      o4[i] = last;
    }
    dv[i] = d;
    const double m = mass[i];
    const V4 f = h * (V4{f_ext_[i].x(), f_ext_[i].y(), f_ext_[i].z(), 0.0} + m * gravity);
    const V4 mdv = -m * d;
    sums[i] = __builtin_shufflevector(f, mdv, 0, 1, 2, 3, 4, 5, 6, 7);
    if (refresh_diag) {
      pre[i] = V4{m, m, m, 1.0};  // the fourth 1: the reciprocal below stays finite
    } else {
      pre[i] = inv_diag[i];
    }
    if (lanes && role_[i] == Role::kFree) {
      state_v[2 * i + 1] = d;  // v₀ is there from the last update
    } else {  // placed by PlaceKinematic, or the lanes not kept since the last implicit step
      const V4 v{v_[i].x(), v_[i].y(), v_[i].z(), 0.0};
      state[i] = __builtin_shufflevector(v, d, 0, 1, 2, 3, 4, 5, 6, 7);
      pos[i] = V4{x_[i].x(), x_[i].y(), x_[i].z(), 0.0};
    }
  }
  if (judge)
    extrapolation_ = BestDegree(simd::Sum(miss1), simd::Sum(miss2), simd::Sum(miss3),
                                params_.cg_extrapolation);  // the next steps'
  const size_t ns = ends_.size();
  // One pass over the springs in chunks that stay in L1, three loops each. The first two have
  // no scatter, so consecutive springs overlap in the pipeline, and the second is vectorised:
  // the spring vectors l and |l|², then 1/|l| and the block's scalars a = h c + h² k (1 − α),
  // b = h² k α (α = max(0, 1 − L/|l|)) and the impulse h k (|l| − L) (one loop: as two, with
  // 1/|l| stored between them, the sphere's step was 1–2% slower). The third sums into the
  // particles. With w = v_j − v_i and e = Δv₀_i − Δv₀_j, spring s adds to end i
  // (end j: the negative) g = h [k (|l| − L) + c l̂·w] l̂ + h² K_s w = (h k (|l| − L) + a l̂·w) l̂
  // + b w to rhs, t = B_s e = a (l̂·e) l̂ + b e to q, and a l̂² + b to both ends' diagonals (on
  // the steps that refresh them). One
  // pair does both: (w, −e) is the difference of the ends' states, and (g, −t) comes out of the
  // same three operations with the impulse only in the first half. The first end's sums stay in
  // registers while the springs (sorted by first end) share it.
  constexpr size_t kChunk = 256;
  double len2[kChunk], inv_len[kChunk], impulse[kChunk];
  const V4 xyz{1.0, 1.0, 1.0, 0.0};
  int cur = -1;
  V8 si{}, acc{};
  V4 pi{};
  for (size_t c0 = 0; c0 < ns; c0 += kChunk) {
    const size_t cn = std::min(kChunk, ns - c0);
    for (size_t k = 0; k < cn; ++k) {
      const V4 l = pos[ends[c0 + k].j] - pos[ends[c0 + k].i];
      dirs[c0 + k] = l;
      len2[k] = Dot(l, l);
    }
    // 1/|l| by Newton's iteration from the exponent-halving first guess (relative error 3.4%,
    // squared each iteration: after four, 3e-16, as close as sqrt and division give): fourteen
    // multiply-adds in place of a square root and a division. 1e-300 keeps a zero length finite
    // and is below the rounding of any length kept; a spring shorter than kMinLength is zeroed
    // by a factor, since GCC (trapping math) vectorises no select of a computed value.
    for (size_t k = 0; k < cn; ++k) {
      const size_t s = c0 + k;
      const double x = len2[k] + 1e-300, half = 0.5 * x;
      double y = std::bit_cast<double>(0x5FE6EB50C7B537A9u - (std::bit_cast<uint64_t>(x) >> 1));
      for (int it = 0; it < 4; ++it) y *= 1.5 - half * y * y;
      const double on = len2[k] >= kMinLength * kMinLength ? 1.0 : 0.0;
      const double inv = on * y;
      const double alpha = std::max(0.0, 1.0 - rest[s] * inv);
      const double hk = h * stiffness[s];
      inv_len[k] = inv;
      coef_a[s] = on * (h * damping[s] + h * hk * (1.0 - alpha));
      coef_b[s] = on * (h * hk * alpha);
      impulse[k] = on * (hk * (len2[k] * inv - rest[s]));
    }
    for (size_t k = 0; k < cn; ++k) {
      const size_t s = c0 + k;
      const int j = ends[s].j;
      if (ends[s].i != cur) {
        if (cur >= 0) sums[cur] += acc, pre[cur] += pi;
        cur = ends[s].i;
        si = state[cur];
        acc = V8{};
        pi = V4{};
      }
      const V4 d = inv_len[k] * dirs[s];
      dirs[s] = d;
      const V8 d2 = __builtin_shufflevector(d, d, 0, 1, 2, 3, 0, 1, 2, 3);
      const double a = coef_a[s], b = coef_b[s], imp = impulse[k];
      const V8 w = state[j] - si;
      V8 dots;
      simd::HalfDots(dots, w, d2);
      const V8 g = (a * dots + V8{imp, imp, imp, imp, 0.0, 0.0, 0.0, 0.0}) * d2 + b * w;
      acc += g;
      sums[j] -= g;
      if (refresh_diag) {
        const V4 dg = a * d * d + b * xyz;
        pi += dg;
        pre[j] += dg;
      }
    }
  }
  if (cur >= 0) sums[cur] += acc, pre[cur] += pi;
  // The Jacobi preconditioner is the diagonal's reciprocal (the fourth lane 0 again): kept with
  // the springs' diagonal, so only the anchored particles divide again on the other steps (a
  // division per particle was 3% of the sphere's step and 2% of the arm's). The fourth lane tells
  // an anchored particle's sum (1) from a reciprocal (0), so a particle with two anchors divides
  // once.
  if (refresh_diag) {
    for (int i = 0; i < n; ++i) {
      diag[i] = pre[i];
      inv_diag[i] = xyz / pre[i];
      pre[i] = inv_diag[i];
    }
    diag_age_ = 0, diag_h_ = h;
  }
  ++diag_age_;
  for (const Anchor& a : anchors_) pre[a.i] = diag[a.i];
  for (const Anchor& a : anchors_) {
    // Zero-length spring-damper: f = k (target − x) − c v; K = k I, C = c I.
    const double d = h * a.c + h2 * a.k;
    const Vec3 f = h * (a.k * (a.target - x_[a.i]) - a.c * v_[a.i]) - h2 * a.k * v_[a.i];
    const V4 ddv = d * dv[a.i];
    sums[a.i] += V8{f.x(), f.y(), f.z(), 0.0, -ddv[0], -ddv[1], -ddv[2], 0.0};
    pre[a.i] += V4{d, d, d, 0.0};
  }
  // y = A u and pq = u·A u in one pass, with the rows of constrained particles filtered to zero
  // (Baraff & Witkin's filter). uᵀA u is summed per term: m |u|² per particle, eᵀB_s e =
  // a (l̂·e)² + b |e|² per spring (e·t below), (h c + h² k) |u|² per anchor; u is 0 on the
  // constrained particles, so the filter leaves it unchanged. From the second iteration on, the
  // first loop also makes u the next search direction, u = z + β u with z = pre r (z is not
  // stored: pre and r are read anyway). Three passes over the particles fewer per iteration
  // than a product, a dot product and an update of their own: the sphere's step 3–8% faster,
  // the arm's 2% (docs/BENCHMARKS.md).
  auto apply_dot = [&](V4* u, V4* y, bool next, double beta) {
    V4 uu{};
    if (next) {
      for (int i = 0; i < n; ++i) {
        const V4 ui = pre[i] * res[i] + beta * u[i];
        u[i] = ui;
        const V4 yi = mass[i] * ui;
        y[i] = yi;
        uu += yi * ui;
      }
    } else {
      for (int i = 0; i < n; ++i) {
        y[i] = mass[i] * u[i];
        uu += y[i] * u[i];
      }
    }
    int at = -1;
    V4 sum{}, ui{}, et{};  // running sum for particle `at`, its u, and the springs' eᵀB_s e
    for (size_t s = 0; s < ns; ++s) {
      const int j = ends[s].j;
      if (ends[s].i != at) {
        if (at >= 0) y[at] += sum;
        at = ends[s].i, sum = V4{}, ui = u[at];
      }
      const V4& d = dirs[s];
      const V4 e = ui - u[j];
      V4 de;  // l̂·e in every lane
      simd::Dots(de, e, d);
      const V4 t = (coef_a[s] * de) * d + coef_b[s] * e;
      sum += t;
      et += e * t;
      y[j] -= t;
    }
    if (at >= 0) y[at] += sum;
    for (const Anchor& a : anchors_) {
      const V4 t = (h * a.c + h2 * a.k) * u[a.i];
      y[a.i] += t;
      uu += t * u[a.i];
    }
    for (int i : constrained_) y[i] = V4{};
    return simd::Sum(uu + et);
  };
  for (const Anchor& a : anchors_)
    if (pre[a.i][3] != 0.0) pre[a.i] = xyz / pre[a.i];
  for (int i : constrained_) sums[i] = V8{}, pre[i] = V4{};
  // Preconditioned conjugate gradient (Jacobi), warm-started from the extrapolated Δv: the
  // residual rhs − A Δv₀ is the pair's sum.
  // The dot products are summed lane by lane and the lanes added at the end.
  double rhs_norm2 = 0, rz = 0, r2 = 0;
  {
    V4 rhs2{}, rz4{}, r24{};
    for (int i = 0; i < n; ++i) {
      const V8& pair = sums[i];
      const V4 rhs = __builtin_shufflevector(pair, pair, 0, 1, 2, 3);
      const V4 r = rhs + __builtin_shufflevector(pair, pair, 4, 5, 6, 7);
      res[i] = r;
      p[i] = pre[i] * r;
      rhs2 += rhs * rhs;
      rz4 += r * p[i];
      r24 += r * r;
    }
    rhs_norm2 = simd::Sum(rhs2), rz = simd::Sum(rz4), r2 = simd::Sum(r24);
  }
  const double tol2 = params_.cg_tolerance * params_.cg_tolerance * rhs_norm2;
  int it = 0;
  double beta = 0;
  for (; it < params_.cg_max_iterations && r2 > tol2; ++it) {
    const double pq = apply_dot(p, q, it > 0, beta);
    if (!(pq > 0)) break;  // the search direction vanished (or the system lost definiteness)
    const double step = rz / pq;
    V4 rz4{}, r24{};
    for (int i = 0; i < n; ++i) {
      dv[i] += step * p[i];
      const V4 r = res[i] - step * q[i];
      res[i] = r;
      rz4 += r * (pre[i] * r);
      r24 += r * r;
    }
    const double rz_new = simd::Sum(rz4);
    r2 = simd::Sum(r24);
    beta = rz_new / rz;
    rz = rz_new;
  }
  cg_iterations_ = it;
  // The update, and CheckFinite's test in the same pass: every particle within
  // divergence_distance of rest (false for NaN) and every velocity finite (v·0 is 0 unless v
  // has an infinity or a NaN). As a pass of its own, after the step, the test cost the sphere's
  // step 13% and the arm's 10%. The pass leaves x and v in the four-lane copies too (pos_ and
  // state_'s v₀), which the next step's set-up pass reads for the free particles instead of
  // converting x_ and v_ again (lanes_, cleared by whatever else writes x_ or v_: a reset, the
  // other integrators, a change of role, which zeroes v): with both passes in four lanes the
  // sphere's step is 3.5% faster, the arm's 3%.
  PlaceKinematic(x_, v_, 1.0, h);
  const double limit2 = params_.divergence_distance * params_.divergence_distance;
  const Vec3* const rest_x = sys_.rest_positions.data();
  bool near = true;
  V4 zero{};
  for (int i = 0; i < n; ++i) {
    V4 xi, vi;
    if (role_[i] == Role::kFree) {
      vi = state_v[2 * i] + dv[i];  // v₀, as the set-up pass read it
      xi = pos[i] + h * vi;
      v_[i] = Vec3(vi[0], vi[1], vi[2]);
      x_[i] = Vec3(xi[0], xi[1], xi[2]);
    } else {
      vi = V4{v_[i].x(), v_[i].y(), v_[i].z(), 0.0};
      xi = V4{x_[i].x(), x_[i].y(), x_[i].z(), 0.0};
    }
    state_v[2 * i] = vi, pos[i] = xi;
    const V4 r = xi - V4{rest_x[i].x(), rest_x[i].y(), rest_x[i].z(), 0.0};
    near &= Dot(r, r) <= limit2;
    zero += 0.0 * vi;
  }
  lanes_ = true;
  return near && zero[0] == 0.0 && zero[1] == 0.0 && zero[2] == 0.0;
}

double MassSpringModel::KineticEnergy() const {
  double e = 0;
  for (size_t i = 0; i < x_.size(); ++i) {
    if (role_[i] != Role::kFixed) e += 0.5 * sys_.masses[i] * v_[i].squaredNorm();
  }
  return e;
}

double MassSpringModel::PotentialEnergy() const {
  double e = 0;
  for (const Spring& s : sys_.springs) {
    const double stretch = (x_[s.j] - x_[s.i]).norm() - s.rest_length;
    e += 0.5 * s.stiffness * stretch * stretch;
  }
  for (size_t i = 0; i < x_.size(); ++i) {
    if (role_[i] == Role::kFree)
      e -= sys_.masses[i] * params_.gravity.dot(x_[i] - sys_.rest_positions[i]);
  }
  return e;
}

double MassSpringModel::MaxDisplacement() const {
  double d = 0;
  for (size_t i = 0; i < x_.size(); ++i) d = std::max(d, (x_[i] - sys_.rest_positions[i]).norm());
  return d;
}

Vec3 MassSpringModel::InternalForceOn(int particle) const {
  Vec3 f = Vec3::Zero();
  for (const Spring& s : sys_.springs) {
    if (s.i != particle && s.j != particle) continue;
    const Vec3 l = x_[s.j] - x_[s.i];
    const double len = l.norm();
    if (len < kMinLength) continue;
    const Vec3 dir = l / len;
    const Vec3 fi =
        (s.stiffness * (len - s.rest_length) + s.damping * (v_[s.j] - v_[s.i]).dot(dir)) * dir;
    f += s.i == particle ? fi : Vec3(-fi);
  }
  return f;
}

double MassSpringModel::MaxAngularFrequency(int iterations) const {
  const int n = static_cast<int>(x_.size());
  // Power iteration on M⁻¹K at rest (K_s = k l̂l̂ᵀ there), over free particles.
  std::vector<Vec3> u(n), ku(n);
  for (int i = 0; i < n; ++i) {
    u[i] = role_[i] == Role::kFree
               ? Vec3(std::sin(1.0 + i), std::cos(2.0 + 3 * i), std::sin(5.0 * i + 0.3))
               : Vec3::Zero();
  }
  double lambda = 0;
  for (int it = 0; it < iterations; ++it) {
    std::fill(ku.begin(), ku.end(), Vec3::Zero());
    for (const Spring& s : sys_.springs) {
      const Vec3 l = sys_.rest_positions[s.j] - sys_.rest_positions[s.i];
      const double len = l.norm();
      if (len < kMinLength) continue;
      const Vec3 dir = l / len;
      const Vec3 t = s.stiffness * dir.dot(u[s.i] - u[s.j]) * dir;
      ku[s.i] += t;
      ku[s.j] -= t;
    }
    double uku = 0, umu = 0, norm = 0;
    for (int i = 0; i < n; ++i) {
      if (role_[i] != Role::kFree) continue;
      uku += u[i].dot(ku[i]);
      umu += sys_.masses[i] * u[i].squaredNorm();
      u[i] = ku[i] * inv_mass_[i];
      norm += u[i].squaredNorm();
    }
    lambda = umu > 0 ? uku / umu : 0;
    norm = std::sqrt(norm);
    if (!(norm > 0)) break;
    for (Vec3& w : u) w /= norm;
  }
  return std::sqrt(std::max(0.0, lambda));
}

}  // namespace vsurg::tissue
