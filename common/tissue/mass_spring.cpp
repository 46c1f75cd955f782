#include "common/tissue/mass_spring.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "common/tissue/simd.h"
#include "common/tissue/text.h"

namespace vsurg::tissue {
namespace {

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
  if (!(Finite(params.cg_energy_floor) && params.cg_energy_floor >= 0)) {
    return InvalidArgument(
        "cg_energy_floor",
        "the solve's energy floor must be finite and ≥ 0 J, got " + Num(params.cg_energy_floor));
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

Status MassSpringModel::SetState(const std::vector<Vec3>& x, const std::vector<Vec3>& v) {
  if (x.size() != x_.size() || v.size() != v_.size())
    return InvalidArgument("state", "the state is of another number of particles");
  const double limit2 = params_.divergence_distance * params_.divergence_distance;
  for (size_t i = 0; i < x.size(); ++i)
    if (!x[i].allFinite() || !v[i].allFinite() ||
        (x[i] - sys_.rest_positions[i]).squaredNorm() > limit2)
      return InvalidArgument("state", "a particle's state is not finite or beyond divergence");
  Reset();
  std::copy(x.begin(), x.end(), x_.begin());
  std::copy(v.begin(), v.end(), v_.begin());
  for (int i : kinematic_) kin_target_[i] = x_[i];
  return Status::Ok();
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
