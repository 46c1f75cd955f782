#include "common/tissue/reduced.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "common/geometry/tet_embedding.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;

}  // namespace

Vec3 WarpedDisplacement(const Vec3& w_in, const Vec3& u) {
  Vec3 w = w_in;
  const double kMax = std::numbers::pi / 2;
  double theta = w.norm();
  if (theta > kMax) w *= kMax / theta, theta = kMax;
  if (theta < 1e-12) return u;
  const double t2 = theta * theta;
  const double a = (1 - std::cos(theta)) / t2, b = (theta - std::sin(theta)) / (t2 * theta);
  return u + a * w.cross(u) + b * w.cross(w.cross(u));
}

// ---- 1. Twist field ---------------------------------------------------------------------------

namespace {

// A twist's load: a unit torque about the axis through the loaded face's own centre on the
// axis, as nodal forces on the FEM (one per vertex).
Expected<std::vector<Vec3>> TwistLoad(const FemStaticResponse& fem, const std::vector<int>& face,
                                      const std::vector<double>& face_area, const Vec3& origin,
                                      const Vec3& axis) {
  if (!origin.allFinite() || !axis.allFinite() || !(axis.norm() > 0))
    return InvalidArgument("axis", "the twist axis needs a finite point and a non-zero direction");
  if (face.empty()) return InvalidArgument("face", "no loaded face");
  for (int v : face)
    if (v < 0 || v >= fem.VertexCount())
      return InvalidArgument("face", "vertex " + std::to_string(v) + " is not in the FEM mesh");
  const Vec3 n = axis.normalized();
  const auto& rest = fem.rest().positions;
  Vec3 centre = Vec3::Zero();
  for (int v : face) centre += rest[v];
  centre /= static_cast<double>(face.size());
  centre = origin + (centre - origin).dot(n) * n;
  const auto nodal = TorqueNodalForces(rest, face, face_area, centre, n, 1.0);
  std::vector<Vec3> f(fem.VertexCount(), Vec3::Zero());
  for (size_t i = 0; i < face.size(); ++i) f[face[i]] += nodal[i];
  return f;
}

// The twist field from the FEM's displacements `u` under TwistLoad's load, on the display
// surface (its embedding in the FEM mesh given: computed once for the many grasps of a surface
// twist table).
Expected<TwistField> TwistFieldOf(const FemStaticResponse& fem, const std::vector<Vec3>& u,
                                  const std::vector<int>& face,
                                  const std::vector<double>& face_area, const Vec3& origin,
                                  const Vec3& axis, const std::vector<Vec3>& display_rest,
                                  const std::vector<geometry::EmbeddedPoint>& embedding) {
  const Vec3 n = axis.normalized();
  const auto& rest = fem.rest().positions;
  for (const Vec3& x : u)
    if (!x.allFinite())
      return Error{ErrorCode::kNumerical, "the unit-torque solve is not finite", "fem"};

  auto off_axis = [&](const Vec3& x) {  // the offset from the axis, ⊥ to it
    const Vec3 r = x - origin;
    return Vec3(r - r.dot(n) * n);
  };
  auto angle_of = [&](const Vec3& x, const Vec3& d) {
    const Vec3 r = off_axis(x);
    const double r2 = r.squaredNorm();
    return r2 > 1e-12 ? n.cross(r).dot(d) / r2 : 0.0;
  };
  TwistField out;
  out.origin = origin;
  out.axis = n;
  double grasp = 0, weight = 0;
  for (size_t i = 0; i < face.size(); ++i) {
    const double w = i < face_area.size() ? face_area[i] : 1.0;
    if (off_axis(rest[face[i]]).squaredNorm() < 1e-12) continue;
    grasp += w * angle_of(rest[face[i]], u[face[i]]);
    weight += w;
  }
  if (!(weight > 0)) return InvalidArgument("face", "the loaded face lies on the axis");
  out.grasp_compliance = grasp / weight;
  if (!(out.grasp_compliance > 0))
    return Error{ErrorCode::kFailedPrecondition,
                 "the loaded face does not turn with the torque (held)", "fem"};

  std::vector<Vec3> ud(display_rest.size());
  for (size_t i = 0; i < ud.size(); ++i) ud[i] = geometry::Interpolate(embedding[i], u);
  out.angle.resize(display_rest.size());
  out.warp.resize(display_rest.size());
  out.radial.resize(display_rest.size());
  out.lateral.assign(display_rest.size(), Vec3::Zero());
  for (size_t i = 0; i < display_rest.size(); ++i) {
    out.angle[i] = static_cast<float>(angle_of(display_rest[i], ud[i]));
    out.warp[i] = static_cast<float>(n.dot(ud[i]));
    const Vec3 r = off_axis(display_rest[i]);
    if (r.squaredNorm() > 1e-12) {
      out.radial[i] = static_cast<float>(r.dot(ud[i]) / r.squaredNorm());
    } else {
      out.radial[i] = 0.f;
      out.lateral[i] = ud[i] - ud[i].dot(n) * n;
    }
    out.max_distance = std::max(out.max_distance, embedding[i].distance);
  }
  return out;
}

}  // namespace

Expected<TwistField> PrecomputeTwistField(const FemStaticResponse& fem,
                                          const std::vector<int>& face,
                                          const std::vector<double>& face_area, const Vec3& origin,
                                          const Vec3& axis, const std::vector<Vec3>& display_rest) {
  auto embedding = geometry::EmbedPoints(fem.rest(), display_rest);
  if (!embedding.ok()) return embedding.error();
  auto f = TwistLoad(fem, face, face_area, origin, axis);
  if (!f.ok()) return f.error();
  return TwistFieldOf(fem, fem.Solve(*f), face, face_area, origin, axis, display_rest, *embedding);
}

// ---- 2. Contact responses ---------------------------------------------------------------------

// Nodal loads on the FEM's boundary for a unit total force in direction d spread over the disc
// of radius a around p (normal n): every boundary triangle sampled at 28 barycentric points,
// each sample inside the disc (distance ⊥ n ≤ a, and within a of the tangent plane) carrying its
// share of the triangle's area to the triangle's vertices. When the disc catches no sample (a
// footprint finer than the FEM), the nearest sample's triangle takes the whole load.
std::vector<std::pair<int, double>> FootprintWeights(const geometry::TriMesh& boundary,
                                                     const Vec3& p, const Vec3& n, double a) {
  constexpr int kN = 6;
  std::vector<std::pair<int, double>> w;
  double best = std::numeric_limits<double>::infinity();
  std::array<int, 3> best_tri = {0, 0, 0};
  std::array<double, 3> best_bary = {1, 0, 0};
  for (const auto& t : boundary.triangles) {
    const Vec3& x0 = boundary.positions[t[0]];
    const Vec3& x1 = boundary.positions[t[1]];
    const Vec3& x2 = boundary.positions[t[2]];
    const double lo = std::min({(x0 - p).norm(), (x1 - p).norm(), (x2 - p).norm()});
    const double edge = std::max({(x1 - x0).norm(), (x2 - x1).norm(), (x0 - x2).norm()});
    if (lo > std::max(a, best) + edge) continue;  // no sample of this triangle can count
    const double area = 0.5 * (x1 - x0).cross(x2 - x0).norm();
    const double share = area / ((kN + 1) * (kN + 2) / 2);
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const double u = static_cast<double>(i) / kN, v = static_cast<double>(j) / kN;
        const Vec3 s = (1 - u - v) * x0 + u * x1 + v * x2;
        const Vec3 d = s - p;
        const double along = d.dot(n);
        const double across = (d - along * n).norm();
        if (across <= a && std::abs(along) <= a) {
          w.emplace_back(t[0], share * (1 - u - v));
          w.emplace_back(t[1], share * u);
          w.emplace_back(t[2], share * v);
        }
        if (d.norm() < best) best = d.norm(), best_tri = t, best_bary = {1 - u - v, u, v};
      }
  }
  if (w.empty())
    for (int k = 0; k < 3; ++k) w.emplace_back(best_tri[k], best_bary[k]);
  double total = 0;
  for (const auto& [i, x] : w) total += x;
  for (auto& [i, x] : w) x /= total;
  return w;
}

namespace {

// The linearised rotation w = ½∇×u (rad) at every vertex of a tet mesh displaced by u (m): the
// axial vector of the skew part of each element's constant gradient H = Σ_a u_a ⊗ ∇N_a,
// averaged at the vertices weighted by element volume. `grad` holds each element's shape
// gradients ∇N_1..3 as the rows of Dm⁻¹ (∇N_0 = −their sum), `volume` its volume.
std::vector<Vec3> NodalRotations(const geometry::TetMesh& mesh,
                                 const std::vector<Eigen::Matrix3d>& grad,
                                 const std::vector<double>& volume,
                                 const std::vector<double>& vertex_volume,
                                 const std::vector<Vec3>& u) {
  std::vector<Vec3> w(mesh.positions.size(), Vec3::Zero());
  for (size_t e = 0; e < mesh.tetrahedra.size(); ++e) {
    const auto& t = mesh.tetrahedra[e];
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();  // ∂u_i/∂x_j
    const Vec3 u0 = u[t[0]];
    for (int a = 1; a < 4; ++a) h += (u[t[a]] - u0) * grad[e].row(a - 1);
    const Vec3 axial(h(2, 1) - h(1, 2), h(0, 2) - h(2, 0), h(1, 0) - h(0, 1));
    for (int a = 0; a < 4; ++a) w[t[a]] += 0.5 * volume[e] * axial;
  }
  for (size_t i = 0; i < w.size(); ++i)
    if (vertex_volume[i] > 0) w[i] /= vertex_volume[i];
  return w;
}

// R̃(w)·u for one vertex in float (reduced.h, 3.): θ² held at (π/2)², A and B by their Taylor
// series in θ² (errors < 2e-5 at π/2), no branch, so the loop over vertices vectorises.
inline void Warp(float wx, float wy, float wz, float ux, float uy, float uz, float& ox, float& oy,
                 float& oz) {
  constexpr float kMax2 = 2.4674011f;  // (π/2)²
  float t2 = wx * wx + wy * wy + wz * wz;
  const float s = t2 > kMax2 ? std::sqrt(kMax2 / t2) : 1.f;
  wx *= s, wy *= s, wz *= s;
  t2 = std::min(t2, kMax2);
  const float a =
      0.5f + t2 * (-1.f / 24 + t2 * (1.f / 720 + t2 * (-1.f / 40320 + t2 * (1.f / 3628800))));
  const float b = 1.f / 6 + t2 * (-1.f / 120 +
                                  t2 * (1.f / 5040 + t2 * (-1.f / 362880 + t2 * (1.f / 39916800))));
  const float c1x = wy * uz - wz * uy, c1y = wz * ux - wx * uz, c1z = wx * uy - wy * ux;
  const float c2x = wy * c1z - wz * c1y, c2y = wz * c1x - wx * c1z, c2z = wx * c1y - wy * c1x;
  ox = ux + a * c1x + b * c2x;
  oy = uy + a * c1y + b * c2y;
  oz = uz + a * c1z + b * c2z;
}

// For every display vertex, the slot (index into `slots`, display vertices) of the nearest one.
std::vector<int> NearestSlots(const std::vector<Vec3>& positions, const std::vector<int>& slots) {
  std::vector<int> out(positions.size(), 0);
  for (size_t i = 0; i < positions.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t s = 0; s < slots.size(); ++s) {
      const double d = (positions[slots[s]] - positions[i]).squaredNorm();
      if (d < best) best = d, out[i] = static_cast<int>(s);
    }
  }
  return out;
}

// The 3×3 block of a contact table: the displacement of `vertex` (rows) per unit force in x, y
// and z (columns) at the contact in `slot`, m/N.
Eigen::Matrix3d Block(const ContactResponse& r, size_t slot, int vertex) {
  Eigen::Matrix3d g;
  const size_t nv = static_cast<size_t>(r.vertices);
  for (int d = 0; d < 3; ++d)
    for (int k = 0; k < 3; ++k) g(k, d) = r.g[((slot * 3 + d) * nv + vertex) * 3 + k];
  return g;
}

}  // namespace

namespace {
thread_local const std::atomic<bool>* precompute_cancel = nullptr;
}  // namespace

void SetPrecomputeCancel(const std::atomic<bool>* flag) {
  precompute_cancel = flag;
}

bool PrecomputeCancelled() {
  return precompute_cancel && precompute_cancel->load(std::memory_order_relaxed);
}

Expected<ContactResponse> PrecomputeContactResponse(const FemStaticResponse& fem,
                                                    const geometry::TriMesh& display,
                                                    const std::vector<int>& reachable,
                                                    const ContactResponseParams& params) {
  const int nv = display.VertexCount();
  if (nv == 0) return InvalidArgument("display", "no vertices");
  if (!(params.footprint_radius > 0) || !std::isfinite(params.footprint_radius))
    return InvalidArgument("footprint_radius", "must be > 0 m");
  std::vector<int> contacts;
  std::vector<uint8_t> pre(nv, 0);
  for (int v : reachable) {
    if (v < 0 || v >= nv)
      return InvalidArgument("reachable", "vertex " + std::to_string(v) + " is not on the surface");
    if (!pre[v]) contacts.push_back(v), pre[v] = 1;
  }
  if (contacts.empty()) return InvalidArgument("reachable", "no vertex a tool can reach");
  const int64_t bytes =
      static_cast<int64_t>(contacts.size()) * nv * 9 * 4 * (params.rotation ? 2 : 1);
  if (bytes > params.max_bytes)
    return InvalidArgument("reachable", std::to_string(contacts.size()) + " contacts × " +
                                            std::to_string(nv) + " vertices need " +
                                            std::to_string(bytes >> 20) + " MB, over the " +
                                            std::to_string(params.max_bytes >> 20) + " MB bound");
  geometry::TriMesh normals_mesh = display;
  geometry::ComputeVertexNormals(normals_mesh);
  auto embedding = geometry::EmbedPoints(fem.rest(), display.positions);
  if (!embedding.ok()) return embedding.error();
  const geometry::TriMesh boundary = geometry::BoundarySurface(fem.rest());

  ContactResponse out;
  out.vertices = nv;
  out.contacts = contacts;
  out.precomputed = pre;
  out.footprint_radius = params.footprint_radius;
  for (const auto& e : *embedding) out.max_distance = std::max(out.max_distance, e.distance);
  out.g.assign(contacts.size() * 9 * static_cast<size_t>(nv), 0.f);
  if (params.rotation) out.w.assign(out.g.size(), 0.f);
  // The FEM's shape gradients and volumes, for the rotation responses.
  const geometry::TetMesh& tets = fem.rest();
  std::vector<Eigen::Matrix3d> grad(tets.tetrahedra.size());
  std::vector<double> volume(tets.tetrahedra.size()), vertex_volume(tets.positions.size(), 0.0);
  for (size_t e = 0; e < tets.tetrahedra.size() && params.rotation; ++e) {
    const auto& t = tets.tetrahedra[e];
    Eigen::Matrix3d dm;
    for (int a = 1; a < 4; ++a) dm.col(a - 1) = tets.positions[t[a]] - tets.positions[t[0]];
    volume[e] = std::abs(dm.determinant()) / 6.0;
    grad[e] = dm.inverse();
    for (int a = 0; a < 4; ++a) vertex_volume[t[a]] += volume[e];
  }
  // The contacts' unit loads solved a batch at a time (FemStaticResponse::SolveMany: the factor
  // read once per eight loads, on every core).
  constexpr size_t kBatch = 24;  // contacts: 72 loads
  std::vector<std::vector<Vec3>> loads, solved;
  for (size_t s = 0; s < contacts.size(); ++s) {
    if (s % kBatch == 0) {
      if (PrecomputeCancelled())
        return Error{ErrorCode::kUnavailable, "the precomputation was cancelled", "cancel"};
      const size_t end = std::min(contacts.size(), s + kBatch);
      loads.assign(3 * (end - s), std::vector<Vec3>(fem.VertexCount(), Vec3::Zero()));
      for (size_t k = s; k < end; ++k) {
        const int c = contacts[k];
        for (const auto& [i, w] : FootprintWeights(
                 boundary, display.positions[c], normals_mesh.normals[c], params.footprint_radius))
          for (int d = 0; d < 3; ++d) loads[3 * (k - s) + d][i][d] += w;
      }
      solved = fem.SolveMany(loads);
    }
    for (int d = 0; d < 3; ++d) {
      const std::vector<Vec3>& u = solved[3 * (s % kBatch) + d];
      float* g = out.g.data() + (s * 3 + d) * 3 * static_cast<size_t>(nv);
      for (int i = 0; i < nv; ++i) {
        const Vec3 x = geometry::Interpolate((*embedding)[i], u);
        if (!x.allFinite())
          return Error{ErrorCode::kNumerical, "a unit-force solve is not finite", "fem"};
        for (int k = 0; k < 3; ++k) g[3 * i + k] = static_cast<float>(x[k]);
      }
      if (!params.rotation) continue;
      const std::vector<Vec3> nodal = NodalRotations(tets, grad, volume, vertex_volume, u);
      float* w = out.w.data() + (s * 3 + d) * 3 * static_cast<size_t>(nv);
      for (int i = 0; i < nv; ++i) {
        const Vec3 x = geometry::Interpolate((*embedding)[i], nodal);
        if (!x.allFinite())
          return Error{ErrorCode::kNumerical, "a unit-force rotation is not finite", "fem"};
        for (int k = 0; k < 3; ++k) w[3 * i + k] = static_cast<float>(x[k]);
      }
    }
  }
  // Vertices without their own slot: the nearest precomputed contact.
  out.slot_of_vertex = NearestSlots(display.positions, contacts);
  return out;
}

Expected<ReducedContactModel> ReducedContactModel::Create(
    std::shared_ptr<const ContactResponse> table, const std::vector<Vec3>& display_rest,
    double max_force) {
  if (!table) return InvalidArgument("response", "no contact table");
  const ContactResponse& response = *table;
  const int nv = static_cast<int>(display_rest.size());
  if (response.vertices != nv || response.slot_of_vertex.size() != display_rest.size() ||
      response.precomputed.size() != display_rest.size() ||
      response.g.size() != response.contacts.size() * 9 * static_cast<size_t>(nv))
    return InvalidArgument("response", "the contact table does not match the surface (" +
                                           std::to_string(response.vertices) + " against " +
                                           std::to_string(nv) + " vertices)");
  if (!(max_force > 0) || !std::isfinite(max_force))
    return InvalidArgument("max_force", "must be > 0 N");
  for (int s : response.slot_of_vertex)
    if (s < 0 || s >= static_cast<int>(response.contacts.size()))
      return InvalidArgument("response", "a vertex names a contact slot out of range");
  if (!response.w.empty() && response.w.size() != response.g.size())
    return InvalidArgument("response", "the rotation table does not match the displacements");
  for (const std::vector<float>* values : {&response.g, &response.w})
    for (float x : *values)
      if (!std::isfinite(x)) return InvalidArgument("response", "the table is not finite");
  ReducedContactModel m;
  m.rest_ = display_rest;
  m.positions_ = display_rest;
  m.max_force_ = max_force;
  m.u_.assign(3 * static_cast<size_t>(nv), 0.f);
  if (!response.w.empty()) m.w_.assign(3 * static_cast<size_t>(nv), 0.f);
  m.compliance_.resize(response.contacts.size());
  for (size_t s = 0; s < response.contacts.size(); ++s) {
    const int c = response.contacts[s];
    Eigen::Matrix3d g = Block(response, s, c);
    g = 0.5 * (g + g.transpose());  // Maxwell–Betti reciprocity: symmetric up to sampling
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(g);
    if (eig.info() != Eigen::Success || !(eig.eigenvalues().minCoeff() > 0))
      return InvalidArgument("response", "contact vertex " + std::to_string(c) +
                                             " does not yield to a force (fixed, or the table is "
                                             "wrong)");
    m.compliance_[s] = g;
  }
  m.response_ = std::move(table);
  return m;
}

int ReducedContactModel::Slot(int contact, ReducedStats& stats) const {
  if (contact < 0 || contact >= VertexCount()) return -1;
  if (!response_->precomputed[contact]) stats.fallback = true;
  return response_->slot_of_vertex[contact];
}

ReducedStats ReducedContactModel::Press(int contact, const Vec3& force) {
  return Press({contact, contact, contact}, {1.0, 0.0, 0.0}, force);
}

ReducedStats ReducedContactModel::Press(const std::array<int, 3>& contacts,
                                        const std::array<double, 3>& weights, const Vec3& force) {
  ReducedStats stats;
  std::array<int, 3> slot;
  for (int k = 0; k < 3; ++k) {
    slot[k] = Slot(contacts[k], stats);
    if (slot[k] < 0 || !(weights[k] >= 0) || !std::isfinite(weights[k])) stats.ok = false;
  }
  if (!stats.ok || !force.allFinite()) {
    stats.ok = false;
    return stats;
  }
  Vec3 f = force;
  if (f.norm() > max_force_) {
    f *= max_force_ / f.norm();
    stats.saturated = true;
  }
  stats.load = f.norm();
  const int nv = VertexCount();
  const double sum = weights[0] + weights[1] + weights[2];
  const bool warp = !w_.empty();
  float* __restrict u = u_.data();
  float* __restrict rot = w_.data();
  std::fill(u_.begin(), u_.end(), 0.f);
  std::fill(w_.begin(), w_.end(), 0.f);
  for (int k = 0; k < 3; ++k) {
    if (!(weights[k] > 0)) continue;
    const double w = sum > 0 ? weights[k] / sum : 1.0;
    const float fx = static_cast<float>(w * f.x()), fy = static_cast<float>(w * f.y()),
                fz = static_cast<float>(w * f.z());
    const size_t at = static_cast<size_t>(slot[k]) * 9 * nv, col = 3 * static_cast<size_t>(nv);
    const float* __restrict gx = response_->g.data() + at;
    for (int j = 0; j < 3 * nv; ++j) u[j] += fx * gx[j] + fy * gx[col + j] + fz * gx[2 * col + j];
    if (!warp) continue;
    const float* __restrict px = response_->w.data() + at;
    for (int j = 0; j < 3 * nv; ++j) rot[j] += fx * px[j] + fy * px[col + j] + fz * px[2 * col + j];
  }
  const double* __restrict rest = rest_.data()->data();
  double* __restrict out = positions_.data()->data();
  for (int i = 0; i < nv; ++i) {
    float ox = u[3 * i], oy = u[3 * i + 1], oz = u[3 * i + 2];
    if (warp) Warp(rot[3 * i], rot[3 * i + 1], rot[3 * i + 2], ox, oy, oz, ox, oy, oz);
    out[3 * i] = rest[3 * i] + ox;
    out[3 * i + 1] = rest[3 * i + 1] + oy;
    out[3 * i + 2] = rest[3 * i + 2] + oz;
  }
  return stats;
}

Eigen::Matrix3d ReducedContactModel::ComplianceAt(const std::array<int, 3>& contacts,
                                                  const std::array<double, 3>& weights) const {
  // Reads only the immutable table (not positions_): the haptic thread calls this beside the
  // deformation thread's presses.
  Eigen::Matrix3d g = Eigen::Matrix3d::Zero();
  const ContactResponse& r = *response_;
  const int nv = r.vertices;
  for (int k = 0; k < 3; ++k) {  // the force's share at vertex k (its slot)
    if (contacts[k] < 0 || contacts[k] >= nv || !(weights[k] > 0)) continue;
    const size_t slot = r.slot_of_vertex[contacts[k]];
    for (int j = 0; j < 3; ++j) {  // the response at vertex j
      if (contacts[j] < 0 || contacts[j] >= nv || !(weights[j] > 0)) continue;
      g += weights[j] * weights[k] * Block(r, slot, contacts[j]);
    }
  }
  return 0.5 * (g + g.transpose());
}

double ReducedContactModel::SeriesStiffness(const std::array<int, 3>& contacts,
                                            const std::array<double, 3>& weights,
                                            const Vec3& normal, double k) const {
  const double g = std::max(0.0, normal.dot(ComplianceAt(contacts, weights) * normal));
  return k / (1.0 + k * g);
}

ReducedStats ReducedContactModel::PressWithSpring(const std::array<int, 3>& contacts,
                                                  const std::array<double, 3>& weights,
                                                  const Vec3& tip, const Vec3& rest_point,
                                                  const Vec3& normal, double k, Vec3* force_out) {
  if (force_out) force_out->setZero();
  ReducedStats stats;
  if (!tip.allFinite() || !rest_point.allFinite() || !normal.allFinite() || !(k >= 0) ||
      !std::isfinite(k) || !(normal.norm() > 0)) {
    stats.ok = false;
    return stats;
  }
  const Vec3 n = normal.normalized();
  const double d = n.dot(tip - rest_point);
  if (d >= 0) {
    Release();
    return stats;
  }
  const double f = SeriesStiffness(contacts, weights, n, k) * d;  // < 0: into the tissue
  stats = Press(contacts, weights, f * n);
  if (force_out && stats.ok) *force_out = stats.saturated ? Vec3(-max_force_ * n) : Vec3(f * n);
  return stats;
}

void ReducedContactModel::Release() {
  std::copy(rest_.begin(), rest_.end(), positions_.begin());  // (no reallocation, no resize)
}

ReducedStats ReducedContactModel::Displace(int contact, const Vec3& displacement, Vec3* force_out) {
  ReducedStats stats;
  const int slot = Slot(contact, stats);
  if (slot < 0 || !displacement.allFinite()) {
    stats.ok = false;
    return stats;
  }
  const Vec3 f = compliance_[slot].ldlt().solve(displacement);
  stats = Press(contact, f);
  if (force_out) *force_out = stats.saturated ? Vec3(f * (max_force_ / f.norm())) : f;
  return stats;
}

Eigen::Matrix3d ReducedContactModel::StiffnessAt(int contact) const {
  ReducedStats ignored;
  const int slot = Slot(contact, ignored);
  if (slot < 0) return Eigen::Matrix3d::Zero();
  return compliance_[slot].inverse();
}

// ---- 4. Surface twist ------------------------------------------------------------------------

std::vector<double> BoundaryAreas(const geometry::TetMesh& mesh) {
  const geometry::TriMesh boundary = geometry::BoundarySurface(mesh);
  std::vector<double> area(mesh.positions.size(), 0.0);
  for (const auto& t : boundary.triangles) {
    const double a = 0.5 * (boundary.positions[t[1]] - boundary.positions[t[0]])
                               .cross(boundary.positions[t[2]] - boundary.positions[t[0]])
                               .norm();
    for (int v : t) area[v] += a / 3;
  }
  return area;
}

std::vector<int> JawFace(const geometry::TetMesh& mesh, const std::vector<double>& area,
                         const Vec3& point, double jaw_radius, std::vector<double>* area_out) {
  // The boundary vertices by distance; the disc, or the four nearest when it catches fewer (a
  // coarse mesh: the jaws still hold something that can turn about the axis).
  std::vector<std::pair<double, int>> by_distance;
  for (int v = 0; v < static_cast<int>(mesh.positions.size()); ++v)
    if (area[v] > 0) by_distance.emplace_back((mesh.positions[v] - point).norm(), v);
  std::sort(by_distance.begin(), by_distance.end());
  std::vector<int> face;
  for (size_t k = 0; k < by_distance.size(); ++k)
    if (by_distance[k].first <= jaw_radius || k < 4) face.push_back(by_distance[k].second);
  if (area_out) {
    area_out->clear();
    for (int v : face) area_out->push_back(area[v]);
  }
  return face;
}

Expected<SurfaceTwistTable> PrecomputeSurfaceTwist(const FemStaticResponse& fem,
                                                   const geometry::TriMesh& display,
                                                   const std::vector<int>& reachable,
                                                   const SurfaceTwistParams& params) {
  const int nv = display.VertexCount();
  if (nv == 0) return InvalidArgument("display", "no vertices");
  if (!(params.jaw_radius > 0) || !std::isfinite(params.jaw_radius))
    return InvalidArgument("jaw_radius", "must be > 0 m");
  SurfaceTwistTable out;
  out.vertices = nv;
  out.jaw_radius = params.jaw_radius;
  out.precomputed.assign(nv, 0);
  for (int v : reachable) {
    if (v < 0 || v >= nv)
      return InvalidArgument("reachable", "vertex " + std::to_string(v) + " is not on the surface");
    if (!out.precomputed[v]) out.grasps.push_back(v), out.precomputed[v] = 1;
  }
  if (out.grasps.empty()) return InvalidArgument("reachable", "no vertex a tool can grasp");
  const int64_t bytes = static_cast<int64_t>(out.grasps.size()) * nv * 12;
  if (bytes > params.max_bytes)
    return InvalidArgument("reachable", std::to_string(out.grasps.size()) + " grasps × " +
                                            std::to_string(nv) + " vertices need " +
                                            std::to_string(bytes >> 20) + " MB, over the " +
                                            std::to_string(params.max_bytes >> 20) + " MB bound");
  geometry::TriMesh normals = display;
  geometry::ComputeVertexNormals(normals);
  auto embedding = geometry::EmbedPoints(fem.rest(), display.positions);
  if (!embedding.ok()) return embedding.error();
  const std::vector<double> boundary_area = BoundaryAreas(fem.rest());
  const std::vector<int> candidates = std::move(out.grasps);
  out.grasps.clear();
  std::fill(out.precomputed.begin(), out.precomputed.end(), 0);
  Error last = InvalidArgument("reachable", "no vertex a tool can grasp");
  // The grasps' loads solved a batch at a time (FemStaticResponse::SolveMany: the factor read
  // once per eight, on every core), each field then taken in the candidates' order.
  constexpr size_t kBatch = 64;
  struct Grasp {
    std::vector<int> face;
    std::vector<double> area;
  };
  std::vector<Grasp> grasps;
  std::vector<std::vector<Vec3>> loads, solved;
  for (size_t at = 0; at < candidates.size(); ++at) {
    if (at % kBatch == 0) {
      const size_t end = std::min(candidates.size(), at + kBatch);
      grasps.assign(end - at, {});
      loads.assign(end - at, {});
      for (size_t k = 0; k < grasps.size(); ++k) {
        const int c = candidates[at + k];
        grasps[k].face = JawFace(fem.rest(), boundary_area, display.positions[c], params.jaw_radius,
                                 &grasps[k].area);
        auto f = TwistLoad(fem, grasps[k].face, grasps[k].area, display.positions[c],
                           normals.normals[c]);
        if (!f.ok()) return f.error();
        loads[k] = std::move(f).value();
      }
      solved = fem.SolveMany(loads);
    }
    const int c = candidates[at];
    const Grasp& g = grasps[at % kBatch];
    auto field = TwistFieldOf(fem, solved[at % kBatch], g.face, g.area, display.positions[c],
                              normals.normals[c], display.positions, *embedding);
    if (!field.ok()) {
      // Jaws that hold only what the support holds turn nothing: not a grasp of its own (its
      // nearest graspable neighbour stands in, flagged).
      if (field.error().code != ErrorCode::kFailedPrecondition) return field.error();
      last = field.error();
      continue;
    }
    out.grasps.push_back(c);
    out.precomputed[c] = 1;
    out.angle.insert(out.angle.end(), field->angle.begin(), field->angle.end());
    out.warp.insert(out.warp.end(), field->warp.begin(), field->warp.end());
    out.radial.insert(out.radial.end(), field->radial.begin(), field->radial.end());
    out.axis.push_back(field->axis);
    out.grasp_compliance.push_back(field->grasp_compliance);
    out.max_distance = std::max(out.max_distance, field->max_distance);
  }
  if (out.grasps.empty()) return last;
  out.slot_of_vertex = NearestSlots(display.positions, out.grasps);
  return out;
}

Status ValidateSurfaceTwist(const SurfaceTwistTable& t, size_t display_vertices) {
  const size_t n = display_vertices, slots = t.grasps.size();
  if (t.vertices != static_cast<int>(n) || t.slot_of_vertex.size() != n ||
      t.precomputed.size() != n || slots == 0 || t.angle.size() != slots * n ||
      t.warp.size() != slots * n || t.radial.size() != slots * n || t.axis.size() != slots ||
      t.grasp_compliance.size() != slots)
    return InvalidArgument("response", "the surface twist table does not match the surface (" +
                                           std::to_string(t.vertices) + " against " +
                                           std::to_string(n) + " vertices)");
  for (int s : t.slot_of_vertex)
    if (s < 0 || s >= static_cast<int>(slots))
      return InvalidArgument("response", "a vertex names a grasp slot out of range");
  for (size_t s = 0; s < slots; ++s)
    if (!(t.grasp_compliance[s] > 0) || !std::isfinite(t.grasp_compliance[s]) ||
        !t.axis[s].allFinite() || std::abs(t.axis[s].norm() - 1) > 1e-6)
      return InvalidArgument("response", "grasp slot " + std::to_string(s) + " is not usable");
  for (const std::vector<float>* values : {&t.angle, &t.warp, &t.radial})
    for (float x : *values)
      if (!std::isfinite(x)) return InvalidArgument("response", "the table is not finite");
  return Status::Ok();
}

TwistField SurfaceTwistField(const SurfaceTwistTable& t, int vertex,
                             const std::vector<Vec3>& display_rest, bool* fallback) {
  const int clamped = std::clamp(vertex, 0, t.vertices - 1);
  const size_t slot = static_cast<size_t>(t.slot_of_vertex[clamped]);
  if (fallback) *fallback = !t.precomputed[clamped];
  const size_t n = static_cast<size_t>(t.vertices);
  TwistField f;
  f.origin = display_rest[t.grasps[slot]];
  f.axis = t.axis[slot];
  f.angle.assign(t.angle.begin() + slot * n, t.angle.begin() + (slot + 1) * n);
  f.warp.assign(t.warp.begin() + slot * n, t.warp.begin() + (slot + 1) * n);
  f.radial.assign(t.radial.begin() + slot * n, t.radial.begin() + (slot + 1) * n);
  f.lateral.assign(n, Vec3::Zero());  // the grasped vertex turns about itself
  f.grasp_compliance = t.grasp_compliance[slot];
  f.max_distance = t.max_distance;
  return f;
}

double SurfaceTwistStiffness(const SurfaceTwistTable& t, int vertex) {
  const int clamped = std::clamp(vertex, 0, t.vertices - 1);
  return 1.0 / t.grasp_compliance[static_cast<size_t>(t.slot_of_vertex[clamped])];
}

double SurfaceTwistCapacity(const SurfaceTwistTable& t, int vertex, double max_twist) {
  const int clamped = std::clamp(vertex, 0, t.vertices - 1);
  const size_t n = static_cast<size_t>(t.vertices);
  const size_t slot = static_cast<size_t>(t.slot_of_vertex[clamped]);
  float most = 0;
  for (size_t i = slot * n; i < (slot + 1) * n; ++i) most = std::max(most, std::abs(t.angle[i]));
  return most > 0 ? max_twist / most : 0.0;  // as ReducedTwistModel::Create computes it
}

}  // namespace vsurg::tissue
