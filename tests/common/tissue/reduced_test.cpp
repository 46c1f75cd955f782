#include "common/tissue/reduced.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <thread>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "common/geometry/mesh.h"
#include "common/geometry/tet_generators.h"

namespace vsurg::tissue::reduced_test {
namespace {

using Vec3 = Eigen::Vector3d;

constexpr double kShear = 12000;  // Pa
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

FemParams Tissue(double poisson = 0.45) {
  FemParams p;
  p.poisson = poisson;
  p.young = 2 * kShear * (1 + poisson);
  return p;
}

struct Bar {
  geometry::TetCylinder cylinder;
  FemStaticResponse response;
};

Bar MakeBar(double a, double length, int rings, int layers) {
  auto c = geometry::MakeTetCylinder({length, a, a, rings, layers});
  EXPECT_TRUE(c.ok());
  auto r = FemStaticResponse::Create(c->mesh, Tissue(), c->base);
  EXPECT_TRUE(r.ok()) << r.error().message;
  return {*c, std::move(r).value()};
}

TwistField FieldOn(const Bar& bar, const std::vector<Vec3>& display) {
  auto f = PrecomputeTwistField(bar.response, bar.cylinder.tip, bar.cylinder.tip_area, Vec3::Zero(),
                                Vec3::UnitZ(), display);
  EXPECT_TRUE(f.ok()) << f.error().message;
  return std::move(f).value();
}

TEST(FemStaticResponseTest, MatchesTheCorotationalStaticSolveAtASmallLoad) {
  // The linear response is the corotational FEM's tangent at rest: at a load that turns the
  // bar by 1e-4 rad the two agree to O(θ) relative.
  auto c = geometry::MakeTetCylinder({0.1, 0.01, 0.01, 2, 10});
  ASSERT_TRUE(c.ok());
  auto linear = FemStaticResponse::Create(c->mesh, Tissue(), c->base);
  auto full = FemModel::Create(c->mesh, Tissue(), c->base);
  ASSERT_TRUE(linear.ok() && full.ok());
  std::vector<Vec3> f(c->mesh.VertexCount(), Vec3::Zero());
  for (int v : c->tip) f[v] = Vec3(1e-6, 0, -2e-6);
  for (int v : c->tip) full->SetExternalForce(v, f[v]);
  ASSERT_TRUE(full->SolveStatic(30, 1e-7).converged);
  const auto u = linear->Solve(f);
  double num = 0, den = 0;
  for (int i = 0; i < c->mesh.VertexCount(); ++i) {
    num += (u[i] - (full->positions()[i] - c->mesh.positions[i])).squaredNorm();
    den += u[i].squaredNorm();
  }
  EXPECT_LT(std::sqrt(num / den), 1e-3);
  for (int v : c->base) EXPECT_EQ(u[v].norm(), 0.0);
  // Linear: twice the load, twice the response.
  for (Vec3& x : f) x *= 2;
  const auto u2 = linear->Solve(f);
  for (int i = 0; i < c->mesh.VertexCount(); ++i) EXPECT_LT((u2[i] - 2 * u[i]).norm(), 1e-15);
}

// The many-load solve the tables use gives every load's displacements to the last bit of the
// one-load solve, whatever the batch's size (not a multiple of its eight), the threads, short or
// non-finite loads (ignored entries) and the fixed vertices (zero); under either fill-reducing
// ordering, which agree to round-off.
TEST(FemStaticResponseTest, ManyLoadsAtOnceSolveToTheLastBitOfOneAtATime) {
  auto c = geometry::MakeTetCylinder({0.1, 0.01, 0.01, 2, 10});
  ASSERT_TRUE(c.ok());
  auto r = FemStaticResponse::Create(c->mesh, Tissue(), c->base);
  auto amd = FemStaticResponse::Create(c->mesh, Tissue(), c->base, FillOrdering::kMinimumDegree);
  ASSERT_TRUE(r.ok() && amd.ok());
  const int nv = c->mesh.VertexCount();
  std::vector<std::vector<Vec3>> loads;
  uint32_t seed = 12345;
  auto uniform = [&seed] {  // deterministic, in (-1, 1)
    seed = seed * 1664525u + 1013904223u;
    return (seed >> 8) / double(1 << 24) * 2 - 1;
  };
  for (int k = 0; k < 19; ++k) {
    std::vector<Vec3> f(k == 5 ? nv / 2 : nv, Vec3::Zero());
    for (Vec3& x : f) x = Vec3(uniform(), uniform(), uniform()) * 1e-3;
    if (k == 7) f[nv / 3] = Vec3(kNan, 0, 0);
    loads.push_back(std::move(f));
  }
  for (size_t k = 0; k < loads.size(); ++k) {
    const auto nd = r->Solve(loads[k]), md = amd->Solve(loads[k]);
    double diff = 0, size = 0;
    for (int i = 0; i < nv; ++i) diff += (nd[i] - md[i]).squaredNorm(), size += nd[i].squaredNorm();
    EXPECT_LT(std::sqrt(diff), 1e-10 * std::sqrt(size)) << "load " << k;
  }
  for (int threads : {1, 3}) {
    const auto many = (threads == 1 ? *amd : *r).SolveMany(loads, threads);
    ASSERT_EQ(many.size(), loads.size());
    for (size_t k = 0; k < loads.size(); ++k) {
      const auto one = (threads == 1 ? *amd : *r).Solve(loads[k]);
      ASSERT_EQ(many[k].size(), one.size());
      for (int i = 0; i < nv; ++i) {
        ASSERT_TRUE(many[k][i].allFinite()) << "load " << k << " vertex " << i;
        ASSERT_EQ(many[k][i], one[i])
            << "load " << k << " vertex " << i << ", " << threads << " threads";
      }
      for (int v : c->base) EXPECT_EQ(many[k][v].norm(), 0.0);
    }
  }
  EXPECT_TRUE(r->SolveMany({}).empty());
}

TEST(FemStaticResponseTest, AMeshWithNothingFixedIsRefused) {
  auto c = geometry::MakeTetCylinder({0.1, 0.01, 0.01, 1, 4});
  ASSERT_TRUE(c.ok());
  EXPECT_FALSE(FemStaticResponse::Create(c->mesh, Tissue(), {}).ok());
}

TEST(ReducedTwistTest, AgreesWithTheFullFemAtASmallTorque) {
  Bar bar = MakeBar(0.01, 0.1, 2, 10);
  const auto& rest = bar.cylinder.mesh.positions;
  const TwistField field = FieldOn(bar, rest);
  auto model = ReducedTwistModel::Create(field, rest, 1.0);
  ASSERT_TRUE(model.ok()) << model.error().message;
  const double torque = 2e-6;  // N·m: ≈ 3e-4 rad at the tip
  auto full = FemModel::Create(bar.cylinder.mesh, Tissue(), bar.cylinder.base);
  ASSERT_TRUE(full.ok());
  const auto f = TorqueNodalForces(rest, bar.cylinder.tip, bar.cylinder.tip_area, Vec3(0, 0, 0.1),
                                   Vec3::UnitZ(), torque);
  for (size_t i = 0; i < f.size(); ++i) full->SetExternalForce(bar.cylinder.tip[i], f[i]);
  ASSERT_TRUE(full->SolveStatic(30, 1e-7).converged);
  EXPECT_TRUE(model->Update(torque).ok);
  double num = 0, den = 0;
  for (size_t i = 0; i < rest.size(); ++i) {
    const Vec3 uf = full->positions()[i] - rest[i];
    num += (model->positions()[i] - full->positions()[i]).squaredNorm();
    den += uf.squaredNorm();
  }
  // To the static solve's tolerance and the O(θ) between a rotation and its linearisation.
  EXPECT_LT(std::sqrt(num / den), 1e-3) << std::sqrt(num / den);
}

TEST(ReducedTwistTest, ReproducesSaintVenantOnAFinerDisplaySurface) {
  // θ(z) = T·z/(G·J) on a round bar; the display is a finer cylinder than the FEM, so every
  // display vertex is interpolated (some lie just outside the faceted FEM boundary). The FEM at
  // this size is ≈ 5% stiffer than Saint-Venant (linear tetrahedra; fem_test's convergence).
  const double a = 0.02, length = 0.2, torque = 1e-2;
  const double j = std::numbers::pi * std::pow(a, 4) / 2;
  Bar bar = MakeBar(a, length, 4, 80);
  auto display = geometry::MakeTetCylinder({length, a, a, 6, 120});
  ASSERT_TRUE(display.ok());
  const auto& rest = display->mesh.positions;
  const TwistField field = FieldOn(bar, rest);
  EXPECT_LT(field.max_distance, 0.002 * a * 6);
  auto model = ReducedTwistModel::Create(field, rest, std::numbers::pi);
  ASSERT_TRUE(model.ok());
  model->Update(torque);
  double sum2 = 0, worst = 0;
  int n = 0;
  const double tip = torque * length / (kShear * j);
  for (size_t i = 0; i < rest.size(); ++i) {
    const Vec3& x0 = rest[i];
    if (x0.head<2>().norm() < 0.5 * a) continue;
    const Vec3& x = model->positions()[i];
    const double got = std::atan2(x0.x() * x.y() - x0.y() * x.x(), x0.x() * x.x() + x0.y() * x.y());
    const double e = (got - torque * x0.z() / (kShear * j)) / tip;
    sum2 += e * e, worst = std::max(worst, std::abs(e)), ++n;
  }
  EXPECT_LT(std::sqrt(sum2 / n), 0.06) << "rms " << std::sqrt(sum2 / n) << " worst " << worst;
  // The grasp's stiffness is the bar's G·J/L.
  EXPECT_NEAR(model->grasp_stiffness(), kShear * j / length, 0.07 * kShear * j / length);
  EXPECT_NEAR(model->grasp_twist(torque), tip, 0.07 * tip);
}

TEST(ReducedTwistTest, ALargeTwistKeepsEveryVertexsDistanceToTheAxis) {
  Bar bar = MakeBar(0.01, 0.1, 2, 10);
  const auto& rest = bar.cylinder.mesh.positions;
  const TwistField field = FieldOn(bar, rest);
  auto model = ReducedTwistModel::Create(field, rest, std::numbers::pi);
  ASSERT_TRUE(model.ok());
  // The vertex the field turns most turns by 0.9 π at 0.9 of the capacity.
  const double torque = 0.9 * model->torque_capacity();
  const ReducedStats s = model->Update(torque);
  EXPECT_FALSE(s.saturated);
  for (size_t i = 0; i < rest.size(); ++i) {
    // The distance changes by the field's radial strain only (end effects near the face).
    if (field.lateral[i].norm() > 0) continue;
    EXPECT_NEAR(model->positions()[i].head<2>().norm(),
                rest[i].head<2>().norm() * std::clamp(1 + torque * field.radial[i], 0.5, 1.5), 1e-6)
        << i;
  }
  double most = 0;
  for (size_t i = 0; i < rest.size(); ++i) {
    const Vec3& x0 = rest[i];
    const Vec3& x = model->positions()[i];
    if (x0.head<2>().norm() < 1e-3) continue;
    most = std::max(most, std::abs(std::atan2(x0.x() * x.y() - x0.y() * x.x(),
                                              x0.x() * x.x() + x0.y() * x.y())));
  }
  EXPECT_NEAR(most, 0.9 * std::numbers::pi, 1e-4);  // the polynomial sine and cosine
}

TEST(ReducedTwistTest, TorquePastCapacityIsClampedAndNanChangesNothing) {
  Bar bar = MakeBar(0.01, 0.1, 1, 6);
  const auto& rest = bar.cylinder.mesh.positions;
  auto model = ReducedTwistModel::Create(FieldOn(bar, rest), rest, 0.5);
  ASSERT_TRUE(model.ok());
  const ReducedStats s = model->Update(-100 * model->torque_capacity());
  EXPECT_TRUE(s.saturated);
  EXPECT_DOUBLE_EQ(s.load, -model->torque_capacity());
  const auto before = model->positions();
  for (const Vec3& x : before) ASSERT_TRUE(x.allFinite());
  for (double bad : {kNan, std::numeric_limits<double>::infinity()}) {
    const ReducedStats n = model->Update(bad);
    EXPECT_FALSE(n.ok);
    EXPECT_EQ(model->positions(), before);
  }
  // A field that does not match the surface, or a capacity beyond π, is refused.
  EXPECT_FALSE(ReducedTwistModel::Create(FieldOn(bar, rest), {rest[0]}, 0.5).ok());
  EXPECT_FALSE(ReducedTwistModel::Create(FieldOn(bar, rest), rest, 4.0).ok());
}

// ---- contact ----

struct Ball {
  geometry::TetMesh mesh;
  geometry::TriMesh surface;  // the FEM's boundary (same vertex indices)
  std::vector<int> fixed, reachable;
  FemStaticResponse response;
};

Ball MakeBall(int cells) {
  auto mesh = geometry::MakeTetBall({0.05, cells});
  EXPECT_TRUE(mesh.ok());
  std::vector<int> fixed, reachable;
  geometry::TriMesh surface = geometry::BoundarySurface(*mesh);
  std::vector<uint8_t> on_surface(mesh->VertexCount(), 0);
  for (const auto& t : surface.triangles)
    for (int v : t) on_surface[v] = 1;
  for (int i = 0; i < mesh->VertexCount(); ++i) {
    if (mesh->positions[i].z() < -0.035) {
      fixed.push_back(i);
    } else if (on_surface[i] && mesh->positions[i].z() > 0) {
      reachable.push_back(i);
    }
  }
  auto r = FemStaticResponse::Create(*mesh, Tissue(), fixed);
  EXPECT_TRUE(r.ok());
  return {*mesh, surface, fixed, reachable, std::move(r).value()};
}

int Top(const Ball& b) {
  int best = 0;
  for (int i = 0; i < b.mesh.VertexCount(); ++i)
    if (b.mesh.positions[i].z() > b.mesh.positions[best].z()) best = i;
  return best;
}

// The contact model of a ball, every reachable vertex precomputed.
ReducedContactModel BallModel(const Ball& b, double max_force,
                              const ContactResponseParams& p = {}) {
  auto table = PrecomputeContactResponse(b.response, b.surface, b.reachable, p);
  EXPECT_TRUE(table.ok()) << table.error().message;
  auto model = ReducedContactModel::Create(std::make_shared<ContactResponse>(std::move(*table)),
                                           b.mesh.positions, max_force);
  EXPECT_TRUE(model.ok()) << model.error().message;
  return std::move(model).value();
}

TEST(ReducedContactTest, APointPressAgreesWithTheFullFemAndIsReciprocal) {
  Ball b = MakeBall(4);
  ContactResponseParams p;
  p.footprint_radius = 1e-9;  // a point load on the contact vertex itself
  auto model = std::make_unique<ReducedContactModel>(BallModel(b, 5.0, p));
  const int top = Top(b);
  const Vec3 force(2e-4, -1e-4, -5e-4);  // N: ≈ 10 µm deep
  EXPECT_TRUE(model->Press(top, force).ok);
  auto full = FemModel::Create(b.mesh, Tissue(), b.fixed);
  ASSERT_TRUE(full.ok());
  full->SetExternalForce(top, force);
  ASSERT_TRUE(full->SolveStatic(30, 1e-7).converged);
  double num = 0, den = 0;
  for (int i = 0; i < b.mesh.VertexCount(); ++i) {
    num += (model->positions()[i] - full->positions()[i]).squaredNorm();
    den += (full->positions()[i] - b.mesh.positions[i]).squaredNorm();
  }
  EXPECT_LT(std::sqrt(num / den), 1e-3);
  // Maxwell–Betti: the response at i to a force at j is the transpose of j's to i.
  const auto& t = model->response();
  const int nv = t.vertices;
  auto g = [&](int slot, int d, int vertex, int k) {
    return t.g[((static_cast<size_t>(slot) * 3 + d) * nv + vertex) * 3 + k];
  };
  for (size_t s1 = 0; s1 < t.contacts.size(); s1 += 7)
    for (size_t s2 = 0; s2 < t.contacts.size(); s2 += 5)
      for (int d = 0; d < 3; ++d)
        for (int k = 0; k < 3; ++k) {
          const double a = g(s1, d, t.contacts[s2], k), c = g(s2, k, t.contacts[s1], d);
          EXPECT_NEAR(a, c, 1e-4 * std::abs(g(s1, d, t.contacts[s1], d)));
        }
}

// The linear table (no rotation correction): its answers are exact linear algebra.
ContactResponseParams Linear() {
  ContactResponseParams p;
  p.rotation = false;
  return p;
}

TEST(ReducedContactTest, ADisplacedContactMovesByTheDisplacementWithAPositiveStiffness) {
  Ball b = MakeBall(4);
  auto model = std::make_unique<ReducedContactModel>(BallModel(b, 5.0, Linear()));
  const int top = Top(b);
  const Vec3 delta(0.0005, 0, -0.002);
  Vec3 force;
  const ReducedStats s = model->Displace(top, delta, &force);
  ASSERT_TRUE(s.ok);
  EXPECT_FALSE(s.saturated);
  EXPECT_LT((model->positions()[top] - b.mesh.positions[top] - delta).norm(), 1e-6);
  EXPECT_LT(force.z(), 0);  // pressing down takes a downward push
  const Eigen::Matrix3d k = model->StiffnessAt(top);
  EXPECT_LT((k - k.transpose()).norm(), 1e-9 * k.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(k).eigenvalues().minCoeff(), 0);
  EXPECT_LT((k * delta - force).norm(), 1e-9 * force.norm());
}

TEST(ReducedContactTest, ASpringCoupledToolReachesTheExactEquilibriumAtAnyStiffness) {
  Ball b = MakeBall(4);
  auto model = std::make_unique<ReducedContactModel>(BallModel(b, 100.0, Linear()));
  const int top = Top(b);
  const Vec3 p0 = b.mesh.positions[top], n = Vec3::UnitZ();
  const Vec3 tip = p0 - 0.004 * n;
  // Stiff and soft springs alike (k·nᵀGn from ≪ 1 to ≫ 1): the spring's force at the moved
  // contact point is the force the tissue carries, the point lies between the rest surface and
  // the tip, and a stiffer spring pushes the surface further.
  double last_depth = 0;
  for (double k : {10.0, 300.0, 1e4}) {
    Vec3 f;
    const ReducedStats st = model->PressWithSpring({top, top, top}, {1, 0, 0}, tip, p0, n, k, &f);
    ASSERT_TRUE(st.ok);
    const Vec3 p = model->positions()[top];
    EXPECT_NEAR(k * n.dot(tip - p), f.dot(n), 1e-6 * std::abs(f.dot(n))) << k;
    const double depth = n.dot(p0 - p);
    EXPECT_GT(depth, last_depth) << k;
    EXPECT_LT(depth, 0.004) << k;
    last_depth = depth;
    EXPECT_NEAR(model->SeriesStiffness({top, top, top}, {1, 0, 0}, n, k), -f.dot(n) / 0.004,
                1e-9 * k);
  }
  // The tip outside: no force, the surface at rest.
  Vec3 f;
  EXPECT_TRUE(
      model->PressWithSpring({top, top, top}, {1, 0, 0}, p0 + 0.001 * n, p0, n, 300, &f).ok);
  EXPECT_EQ(f, Vec3::Zero());
  EXPECT_EQ(model->positions(), b.mesh.positions);
  // A force spread half-and-half over two vertices is the mean of the two presses.
  int second = -1;
  for (const auto& t : b.surface.triangles)
    for (int k = 0; k < 3; ++k)
      if (t[k] == top) second = t[(k + 1) % 3];
  ASSERT_GE(second, 0);
  const Vec3 force(0, 0, -0.05);
  model->Press(top, force);
  const auto a = model->positions();
  model->Press(second, force);
  const auto c = model->positions();
  model->Press({top, second, top}, {0.5, 0.5, 0.0}, force);
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_LT((model->positions()[i] - 0.5 * (a[i] + c[i])).norm(), 1e-9) << i;
}

TEST(ReducedContactTest, HardCasesStayBoundedAndSaySo) {
  Ball b = MakeBall(4);
  auto model = std::make_unique<ReducedContactModel>(BallModel(b, 1.0));
  const int top = Top(b);
  // A press deeper than the ball: the force is clamped to capacity, nothing is NaN.
  Vec3 force;
  ReducedStats s = model->Displace(top, Vec3(0, 0, -0.2), &force);
  EXPECT_TRUE(s.saturated);
  EXPECT_NEAR(force.norm(), 1.0, 1e-9);
  for (const Vec3& x : model->positions()) ASSERT_TRUE(x.allFinite());
  // A vertex never precomputed (on the bottom, out of reach): the nearest contact, flagged.
  int low = -1;
  for (int i = 0; i < b.mesh.VertexCount(); ++i)
    if (b.mesh.positions[i].z() < -0.02 && b.mesh.positions[i].norm() > 0.045) low = i;
  ASSERT_GE(low, 0);
  s = model->Press(low, Vec3(0, 0, 0.1));
  EXPECT_TRUE(s.ok);
  EXPECT_TRUE(s.fallback);
  for (const Vec3& x : model->positions()) ASSERT_TRUE(x.allFinite());
  // NaN and an index off the surface change nothing.
  const auto before = model->positions();
  EXPECT_FALSE(model->Press(top, Vec3(kNan, 0, 0)).ok);
  EXPECT_FALSE(model->Displace(top, Vec3(0, kNan, 0)).ok);
  EXPECT_FALSE(model->Press(-1, Vec3(0, 0, 1)).ok);
  EXPECT_FALSE(model->Press(b.mesh.VertexCount(), Vec3(0, 0, 1)).ok);
  EXPECT_EQ(model->positions(), before);
  // The memory bound is enforced with a message that gives the size.
  ContactResponseParams small;
  small.max_bytes = 1 << 10;
  auto refused = PrecomputeContactResponse(b.response, b.surface, b.reachable, small);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("MB"), std::string::npos);
}

// A background builder told to stop (a palpation's case bank as its node shuts down) gives up its
// table between batches of solves, refused as unavailable; other threads never see the flag, and
// with it cleared the same table builds.
TEST(ReducedContactTest, APrecomputationOnAThreadToldToStopGivesUp) {
  const Ball b = MakeBall(4);
  std::atomic<bool> stop{true};
  SetPrecomputeCancel(&stop);
  auto cancelled = PrecomputeContactResponse(b.response, b.surface, b.reachable, {});
  std::thread other(
      [&] { EXPECT_FALSE(PrecomputeCancelled()) << "the flag is this thread's alone"; });
  other.join();
  stop.store(false);
  auto built = PrecomputeContactResponse(b.response, b.surface, b.reachable, {});
  SetPrecomputeCancel(nullptr);
  ASSERT_FALSE(cancelled.ok());
  EXPECT_EQ(cancelled.error().code, ErrorCode::kUnavailable);
  EXPECT_TRUE(built.ok()) << built.error().message;
}

// The rotation correction's operator (reduced.h, 3.): a rigid turn's linearised displacement
// w × r becomes the exact turn (R(w) − I)·r, lengths kept; a small rotation changes nothing to
// first order; the angle is held at π/2.
TEST(ReducedContactTest, TheRotationCorrectionTurnsALinearisedRotationIntoAnExactOne) {
  const Vec3 r(0.01, -0.004, 0.02);
  for (const Vec3& w : {Vec3(0, 0, 0.3), Vec3(0.5, -0.2, 0.9), Vec3(1e-4, 2e-4, -1e-4)}) {
    const Vec3 exact = Eigen::AngleAxisd(w.norm(), w.normalized()) * r - r;
    const Vec3 warped = WarpedDisplacement(w, w.cross(r));
    EXPECT_LT((warped - exact).norm(), 1e-12) << w.transpose();
    EXPECT_NEAR((r + warped).norm(), r.norm(), 1e-12);
    // The linear displacement lengthens r to |r|·√(1 + θ²) when w ⊥ r.
  }
  const Vec3 u(1e-4, 0, -2e-4);
  EXPECT_LT((WarpedDisplacement(Vec3(1e-5, 0, 0), u) - u).norm(), 1e-5 * u.norm());
  EXPECT_EQ(WarpedDisplacement(Vec3::Zero(), u), u);
  const Vec3 held = WarpedDisplacement(Vec3(0, 0, 10.0), Vec3(1, 0, 0));
  const Vec3 quarter = WarpedDisplacement(Vec3(0, 0, std::numbers::pi / 2), Vec3(1, 0, 0));
  EXPECT_LT((held - quarter).norm(), 1e-12);
  const Vec3 nan_free = WarpedDisplacement(Vec3(0, 0, 1e300), Vec3(1, 0, 0));
  EXPECT_TRUE(nan_free.allFinite());
}

// Large local deformation against the corotational FEM (large rotations, same mesh, same point
// load). Dragging the ball's top sideways turns the material around the tool: the linear table
// moves it along straight lines and inflates the ball (+1.9% at 4 N, +7.6% at 8 N where the FEM
// loses 0.3% and 1.0%); corrected, the surface is closer to the FEM and the volume follows it.
// A straight press turns little: there the correction neither helps nor harms (±0.05 points).
// At a small load the two tables agree (the correction is second order).
TEST(ReducedContactTest, TheRotationCorrectionKeepsADraggedSurfaceCloseToTheCorotationalFem) {
  Ball b = MakeBall(6);
  // A point load on the top vertex, so the full FEM gets exactly the table's load.
  ContactResponseParams point_linear = Linear(), point;
  point_linear.footprint_radius = point.footprint_radius = 1e-9;
  auto linear = std::make_unique<ReducedContactModel>(BallModel(b, 100.0, point_linear));
  auto warped = std::make_unique<ReducedContactModel>(BallModel(b, 100.0, point));
  const int top = Top(b), n = b.mesh.VertexCount();
  auto volume_change = [&](const std::vector<Vec3>& x) {
    geometry::TriMesh m = b.surface;
    m.positions = x;
    return geometry::SignedVolume(m) / geometry::SignedVolume(b.surface) - 1;
  };
  // Small: 0.5 mN, a few µm.
  linear->Press(top, Vec3(0, 0, -5e-4));
  warped->Press(top, Vec3(0, 0, -5e-4));
  double diff = 0, disp = 0;
  for (int i = 0; i < n; ++i) {
    diff = std::max(diff, (linear->positions()[i] - warped->positions()[i]).norm());
    disp = std::max(disp, (linear->positions()[i] - b.mesh.positions[i]).norm());
  }
  EXPECT_LT(diff, 1e-3 * disp);
  struct Case {
    Vec3 force;  // N
    bool drag;
  };
  for (const Case& c :
       {Case{Vec3(4, 0, 0), true}, Case{Vec3(8, 0, 0), true}, Case{Vec3(0, 0, -6), false}}) {
    SCOPED_TRACE(c.force.transpose());
    linear->Press(top, c.force);
    warped->Press(top, c.force);
    auto full = FemModel::Create(b.mesh, Tissue(), b.fixed);
    ASSERT_TRUE(full.ok());
    full->SetExternalForce(top, c.force);
    ASSERT_TRUE(full->SolveStatic(60, 1e-8).converged);
    double e_lin = 0, e_warp = 0, scale = 0;
    for (int i = 0; i < n; ++i) {
      const Vec3 ref = full->positions()[i];
      e_lin += (linear->positions()[i] - ref).squaredNorm();
      e_warp += (warped->positions()[i] - ref).squaredNorm();
      scale = std::max(scale, (ref - b.mesh.positions[i]).norm());
    }
    EXPECT_GT(scale, 0.01);  // m: deep, a fifth of the radius or more
    const double rms_lin = std::sqrt(e_lin / n) / scale, rms_warp = std::sqrt(e_warp / n) / scale;
    const double dv_ref = volume_change(full->positions());
    const double dv_lin = volume_change(linear->positions());
    const double dv_warp = volume_change(warped->positions());
    if (c.drag) {
      EXPECT_LT(rms_warp, 0.7 * rms_lin);
      EXPECT_GT(dv_lin - dv_ref, 0.015);  // the linear table inflates
      EXPECT_LT(std::abs(dv_warp - dv_ref), 0.4 * std::abs(dv_lin - dv_ref));
    } else {
      EXPECT_LT(std::abs(rms_warp - rms_lin), 0.1 * rms_lin);
      EXPECT_LT(std::abs(dv_warp - dv_lin), 0.001);
    }
  }
}

// ---- surface twist ----

// A table of grasps on a ball held on its lower part: a grasp's field is the twist field of a
// unit torque on the jaws' disc (the same as PrecomputeTwistField on JawFace), turns the ball
// about the normal at the grasp, and a vertex never precomputed takes its nearest grasp's field,
// flagged. A table read back with a wrong size, a NaN or a bent axis is refused.
TEST(SurfaceTwistTest, EveryGraspIsTheTwistFieldOfItsJawsAndNeighboursStandIn) {
  Ball b = MakeBall(6);
  SurfaceTwistParams p;
  p.jaw_radius = 0.012;
  auto table = PrecomputeSurfaceTwist(b.response, b.surface, b.reachable, p);
  ASSERT_TRUE(table.ok()) << table.error().message;
  ASSERT_TRUE(ValidateSurfaceTwist(*table, b.mesh.positions.size()).ok());
  EXPECT_EQ(table->grasps.size(), b.reachable.size());
  EXPECT_EQ(table->Bytes(),
            static_cast<int64_t>(12 * b.reachable.size() * b.mesh.positions.size()));
  const int top = Top(b);
  bool fallback = true;
  const TwistField f = SurfaceTwistField(*table, top, b.mesh.positions, &fallback);
  EXPECT_FALSE(fallback);
  EXPECT_GT(f.axis.z(), 0.99);  // the outward normal at the top
  std::vector<double> area;
  const std::vector<int> face =
      JawFace(b.mesh, BoundaryAreas(b.mesh), b.mesh.positions[top], p.jaw_radius, &area);
  EXPECT_GE(face.size(), 4u);
  auto direct =
      PrecomputeTwistField(b.response, face, area, b.mesh.positions[top], f.axis, b.mesh.positions);
  ASSERT_TRUE(direct.ok());
  EXPECT_NEAR(f.grasp_compliance, direct->grasp_compliance, 1e-9 * direct->grasp_compliance);
  for (size_t i = 0; i < f.angle.size(); ++i) EXPECT_FLOAT_EQ(f.angle[i], direct->angle[i]) << i;
  EXPECT_NEAR(SurfaceTwistStiffness(*table, top), 1 / f.grasp_compliance, 1e-9);
  // Turned by 30° at the jaws: the grasp's neighbours turn about the normal, the held bottom
  // does not move, nothing leaves its distance to the axis.
  auto model = ReducedTwistModel::Create(f, b.mesh.positions, std::numbers::pi / 2);
  ASSERT_TRUE(model.ok());
  EXPECT_NEAR(SurfaceTwistCapacity(*table, top, std::numbers::pi / 2), model->torque_capacity(),
              1e-6 * model->torque_capacity());
  model->Update(0.5236 / f.grasp_compliance);
  double turned = 0;
  for (int i = 0; i < b.mesh.VertexCount(); ++i) {
    const Vec3& x0 = b.mesh.positions[i];
    const Vec3& x = model->positions()[i];
    if (x0.z() < -0.035) {
      EXPECT_LT((x - x0).norm(), 1e-9) << i;  // held
    }
    const double r0 = (x0 - x0.z() * Vec3::UnitZ()).norm(), r = (x - x.z() * Vec3::UnitZ()).norm();
    if (r0 > 0.005 && x0.z() > 0.04) {
      turned = std::max(turned, std::atan2(Vec3(x0.x(), x0.y(), 0).cross(Vec3(x.x(), x.y(), 0)).z(),
                                           Vec3(x0.x(), x0.y(), 0).dot(Vec3(x.x(), x.y(), 0))));
      EXPECT_NEAR(r, r0, 0.6 * r0);  // radial strain only, no 1/cos θ inflation
    }
  }
  EXPECT_GT(turned, 0.2);  // rad: the top turns with the jaws
  // A vertex on the held bottom was never precomputed: its nearest grasp stands in, flagged.
  int low = -1;
  for (int i = 0; i < b.mesh.VertexCount(); ++i)
    if (b.mesh.positions[i].z() < -0.045) low = i;
  ASSERT_GE(low, 0);
  SurfaceTwistField(*table, low, b.mesh.positions, &fallback);
  EXPECT_TRUE(fallback);
  // Corrupt tables are refused with a reason.
  SurfaceTwistTable bad = *table;
  bad.angle.pop_back();
  EXPECT_FALSE(ValidateSurfaceTwist(bad, b.mesh.positions.size()).ok());
  bad = *table;
  bad.warp[7] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(ValidateSurfaceTwist(bad, b.mesh.positions.size()).ok());
  bad = *table;
  bad.axis[0] *= 2;
  EXPECT_FALSE(ValidateSurfaceTwist(bad, b.mesh.positions.size()).ok());
  bad = *table;
  bad.slot_of_vertex[0] = 1 << 20;
  EXPECT_FALSE(ValidateSurfaceTwist(bad, b.mesh.positions.size()).ok());
  // The memory bound names the size.
  p.max_bytes = 1 << 10;
  auto refused = PrecomputeSurfaceTwist(b.response, b.surface, b.reachable, p);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("MB"), std::string::npos);
}

}  // namespace
}  // namespace vsurg::tissue::reduced_test
