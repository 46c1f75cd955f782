// CutMembrane (common/tissue/cut_membrane.h): a cut in a taut patch gapes, follows the blade's
// line to a fraction of an edge, closes a loop into a free piece, ignores a blade back in its own
// cut, runs to and along the rim; and over a thousand random cuts the patch keeps every invariant
// (no NaN, no inverted or sliver triangle, no crack the cut did not make).
#include "common/tissue/cut_membrane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <vector>

namespace vsurg::tissue {
namespace {

CutMembrane Patch(int cells = 24) {
  CutMembraneParams p;
  p.cells = cells;
  auto m = CutMembrane::Create(p);
  EXPECT_TRUE(m.ok()) << m.error().message;
  return std::move(*m);
}

// A blade's path in steps of `step` m from `a` to `b`, as the haptic loop hands it on.
int Draw(CutMembrane& m, const Vec2& a, const Vec2& b, double step) {
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step)));
  int cut = 0;
  for (int i = 0; i < n; ++i)
    cut += m.Cut(a + (b - a) * (i / double(n)), a + (b - a) * ((i + 1) / double(n)));
  return cut;
}

double Cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Every invariant of a patch, however cut: finite positions; every triangle kept counter-
// clockwise and no angle below the snapping bound (or the grid's own 45°); across an uncut edge
// two triangles share both particles (no crack), across a cut one they share none of an interior
// node's (the cut is open).
void ExpectSound(const CutMembrane& m) {
  for (const Vec3& x : m.positions()) ASSERT_TRUE(x.allFinite());
  std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> sides;  // nodes → particles
  for (int f = 0; f < m.FaceCount(); ++f) {
    if (m.Removed(f)) continue;
    const auto v = m.face(f).v;
    const Vec2 a = m.Rest(v[0]), b = m.Rest(v[1]), c = m.Rest(v[2]);
    ASSERT_GT(Cross(b - a, c - a), 0) << "face " << f << " inverted at rest";
    for (int k = 0; k < 3; ++k) {
      const Vec2 u = m.Rest(v[(k + 1) % 3]) - m.Rest(v[k]),
                 w = m.Rest(v[(k + 2) % 3]) - m.Rest(v[k]);
      ASSERT_GT(std::atan2(std::abs(Cross(u, w)), u.dot(w)), (20 - 1e-9) * std::numbers::pi / 180);
      const int p = v[k], q = v[(k + 1) % 3], a_node = m.NodeOf(p), b_node = m.NodeOf(q);
      const auto key = std::minmax(a_node, b_node);
      sides[{key.first, key.second}].push_back(a_node < b_node ? std::pair{p, q} : std::pair{q, p});
    }
  }
  // A node opens along a cut where the cut passes through it: on the rim, or with two cut edges.
  std::map<int, int> cut_at;
  for (const auto& e : m.cut_edges()) ++cut_at[e[0]], ++cut_at[e[1]];
  const auto opens = [&](int node, int particle) {
    const Vec2 r = m.Rest(particle);
    const bool rim = std::abs(r.x()) > 0.5 * m.params().size_x - 1e-9 ||
                     std::abs(r.y()) > 0.5 * m.params().size_y - 1e-9;
    return rim || cut_at[node] >= 2;
  };
  for (const auto& [edge, list] : sides) {
    if (list.size() != 2) continue;
    if (m.EdgeCut(edge.first, edge.second)) {
      if (opens(edge.first, list[0].first)) {
        EXPECT_NE(list[0].first, list[1].first) << "a cut still joined at " << edge.first;
      }
      if (opens(edge.second, list[0].second)) {
        EXPECT_NE(list[0].second, list[1].second) << "a cut still joined at " << edge.second;
      }
    } else {
      EXPECT_EQ(list[0], list[1]) << "a crack the cut did not make: " << edge.first << "-"
                                  << edge.second;
    }
  }
}

struct Deviation {
  double worst = 0, rms = 0;
};
// The cut's nodes' distances from the line through a and b (m).
Deviation FromLine(const CutMembrane& m, const Vec2& a, const Vec2& b) {
  const Vec2 dir = (b - a).normalized();
  Deviation d;
  int n = 0;
  for (const auto& e : m.cut_edges()) {
    for (int node : e) {
      const double off = std::abs(Cross(dir, m.Rest(node) - a));
      d.worst = std::max(d.worst, off), d.rms += off * off, ++n;
    }
  }
  d.rms = std::sqrt(d.rms / std::max(n, 1));
  return d;
}

TEST(CutMembraneTest, AStraightCutFollowsTheLineAndTheTautPatchGapesAlongIt) {
  CutMembrane m = Patch();
  const Vec2 a(-0.025, 0.004), b(0.025, 0.0075);  // across the grid at a slant
  EXPECT_GT(Draw(m, a, b, 0.2e-3), 10);
  ExpectSound(m);
  const Deviation d = FromLine(m, a, b);
  // Node snapping's bound: where the line runs midway between two rows of nodes neither may move
  // onto it, and the cut is half an edge off; elsewhere it lies on the line.
  EXPECT_LT(d.worst, 0.55 * m.EdgeLength()) << "the cut strays from the blade's line";
  EXPECT_LT(d.rms, 0.25 * m.EdgeLength());
  const size_t particles = m.positions().size();
  EXPECT_GT(particles, static_cast<size_t>(m.node_count()));
  for (int i = 0; i < 400; ++i) ASSERT_TRUE(m.Step(1e-3));
  // The lips of the cut pull apart: the copies of the middle node are no longer together.
  double gap = 0;
  for (size_t p = m.node_count(); p < particles; ++p) {
    const int node = m.NodeOf(static_cast<int>(p));
    gap = std::max(gap, (m.positions()[p] - m.positions()[node]).norm());
  }
  EXPECT_GT(gap, 0.5 * m.params().pretension * m.EdgeLength());
  ExpectSound(m);
}

// The equilateral lattice under a uniform pre-strain is in equilibrium; only the half triangles
// that close the rows at the frame differ, and move their neighbours by micrometres.
TEST(CutMembraneTest, AnUncutPatchStaysAtRestUnderItsOwnTension) {
  CutMembrane m = Patch();
  for (int i = 0; i < 400; ++i) ASSERT_TRUE(m.Step(1e-3));
  EXPECT_LT(m.model().MaxDisplacement(), 0.002 * m.EdgeLength());
  EXPECT_LT(m.model().KineticEnergy(), 1e-12);
}

// The stiffnesses a blade meets, from their closed forms, against the patch itself: a point force
// at its middle, in the plane and across it, stepped to rest (27% more and 15% less than the
// closed forms at 16 cells: the load's spread of half an edge is an estimate).
TEST(CutMembraneTest, APointForceMovesThePatchAsItsClosedFormsSay) {
  for (const bool across : {false, true}) {
    CutMembraneParams p;
    p.cells = 16;
    auto m = CutMembrane::Create(p);
    ASSERT_TRUE(m.ok());
    const double f = 0.05;
    m->Load(Vec2(0, 0), across ? Vec3(0, 0, -f) : Vec3(f, 0, 0));
    for (int i = 0; i < 3000; ++i) ASSERT_TRUE(m->Step(1e-3));
    const double moved = m->model().MaxDisplacement();
    const double k = across ? m->NormalStiffness() : m->InPlaneStiffness();
    EXPECT_NEAR(moved, f / k, 0.35 * f / k) << (across ? "across" : "in the plane");
  }
}

// A grasper pulling the patch in its plane: a small pull holds (the jaws feel the patch pull
// back), a large one stretches the springs at the jaws past the failure strain and the patch
// tears there, its topology sound and its state finite.
TEST(CutMembraneTest, AGraspPulledTooFarTearsThePatch) {
  for (const double pull : {0.002, 0.03}) {
    CutMembraneParams p;
    p.cells = 16;
    auto m = CutMembrane::Create(p);
    ASSERT_TRUE(m.ok());
    for (int i = 1; i <= 1500; ++i) {
      const double x = pull * std::min(1.0, i / 1000.0);
      m->Hold(Vec2(0, 0), Vec3(x, 0, 0), 2000);
      ASSERT_TRUE(m->Step(1e-3));
      m->Tear();
    }
    ExpectSound(*m);
    if (pull < 0.01) {
      EXPECT_EQ(m->torn_edges(), 0);
      EXPECT_LT(m->HoldForce().x(), -0.1) << "the patch pulls the jaws back";
    } else {
      EXPECT_GT(m->torn_edges(), 0);
      EXPECT_EQ(m->cut_edges().size(), static_cast<size_t>(m->torn_edges()));
    }
    m->Release();
    EXPECT_EQ(m->HoldForce().norm(), 0.0);
  }
}

TEST(CutMembraneTest, ACutClosingALoopFreesThePieceInside) {
  CutMembrane m = Patch();
  const double r = 0.012;
  Vec2 last(r, 0);
  for (int i = 1; i <= 720; ++i) {  // a circle in 0.5° steps, and a little past its start
    const double t = i * std::numbers::pi / 360 * 1.1;
    const Vec2 next(r * std::cos(t), r * std::sin(t));
    m.Cut(last, next);
    last = next;
  }
  EXPECT_EQ(m.freed_pieces(), 1);
  int removed = 0;
  for (int f = 0; f < m.FaceCount(); ++f) removed += m.Removed(f);
  const double face_area = 0.5 * m.EdgeLength() * m.EdgeLength();
  EXPECT_NEAR(removed * face_area, std::numbers::pi * r * r, 0.25 * std::numbers::pi * r * r);
  ExpectSound(m);
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(m.Step(1e-3));
  ExpectSound(m);
}

TEST(CutMembraneTest, ABladeBackInItsOwnCutCutsNothing) {
  CutMembrane m = Patch();
  Draw(m, {-0.02, 0.001}, {0.02, 0.001}, 0.2e-3);
  const size_t edges = m.cut_edges().size();
  EXPECT_EQ(Draw(m, {0.02, 0.001}, {-0.015, 0.001}, 0.2e-3), 0);
  EXPECT_EQ(m.cut_edges().size(), edges);
  ExpectSound(m);
}

TEST(CutMembraneTest, ACutRunsToTheRimAndAlongItWithoutFreeingTheRim) {
  CutMembrane m = Patch();
  Draw(m, {0.0, 0.0}, {0.0, 0.04}, 0.2e-3);     // to the rim
  Draw(m, {0.0, 0.04}, {0.039, 0.04}, 0.2e-3);  // along it
  ExpectSound(m);
  EXPECT_EQ(m.freed_pieces(), 0);
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(m.Step(1e-3));
  for (int p = 0; p < static_cast<int>(m.positions().size()); ++p) {
    const Vec2 r = m.Rest(p);
    if (std::abs(r.x()) > 0.0399 || std::abs(r.y()) > 0.0399) {
      EXPECT_EQ(m.positions()[p].z(), 0.0) << "the rim moved";
    }
  }
}

TEST(CutMembraneTest, ABladeFasterThanTheMeshCutsWhatSmallStepsCut) {
  CutMembrane slow = Patch(), fast = Patch();
  const Vec2 a(-0.03, -0.011), b(0.03, 0.013);
  Draw(slow, a, b, 0.1e-3);
  fast.Cut(a, b);  // one step across the whole patch
  const double h = fast.EdgeLength();
  for (const CutMembrane* m : {&slow, &fast}) {
    const Deviation d = FromLine(*m, a, b);
    EXPECT_LT(d.worst, 0.55 * h);
    EXPECT_LT(d.rms, 0.25 * h);
    EXPECT_GT(m->cut_edges().size(), 0.9 * 0.06 / h);  // the whole way across
    ExpectSound(*m);
  }
  EXPECT_NEAR(static_cast<double>(fast.cut_edges().size()), slow.cut_edges().size(),
              0.25 * slow.cut_edges().size());
}

TEST(CutMembraneTest, AThousandRandomCutsKeepEveryInvariant) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-0.045, 0.045), turn(-0.8, 0.8);
  std::uniform_real_distribution<double> len(0.2e-3, 6e-3);
  int cuts = 0;
  for (int patch = 0; patch < 10; ++patch) {
    CutMembraneParams p;
    p.cells = 16;
    auto m = CutMembrane::Create(p);
    ASSERT_TRUE(m.ok());
    Vec2 at(pos(rng), pos(rng));
    double heading = turn(rng) * 4;
    for (int i = 0; i < 100; ++i, ++cuts) {
      if (i % 25 == 0) at = Vec2(pos(rng), pos(rng));  // a new cut somewhere
      heading += turn(rng);
      const Vec2 next = at + len(rng) * Vec2(std::cos(heading), std::sin(heading));
      m->Cut(at, next);
      at = next;
      if (i % 5 == 0) m->Load(at, Vec3(0, 0, -0.2));
      ASSERT_TRUE(m->Step(1e-3)) << "diverged at cut " << cuts;
      ASSERT_NO_FATAL_FAILURE(ExpectSound(*m)) << "cut " << cuts;
    }
  }
  EXPECT_EQ(cuts, 1000);
}

TEST(CutMembraneTest, BadParametersAreRefusedByName) {
  const auto field = [](auto change) {
    CutMembraneParams p;
    change(p);
    auto m = CutMembrane::Create(p);
    return m.ok() ? std::string("ok") : m.error().field;
  };
  EXPECT_EQ(field([](CutMembraneParams& p) { p.thickness = 0; }), "thickness");
  EXPECT_EQ(field([](CutMembraneParams& p) { p.youngs_modulus = -1; }), "youngs_modulus");
  EXPECT_EQ(field([](CutMembraneParams& p) { p.cells = 1; }), "cells");
  EXPECT_EQ(field([](CutMembraneParams& p) { p.pretension = 0.7; }), "pretension");
  EXPECT_EQ(field([](CutMembraneParams& p) { p.density = NAN; }), "density");
  EXPECT_EQ(field([](CutMembraneParams& p) { p.failure_strain = 0; }), "failure_strain");
  EXPECT_EQ(field([](CutMembraneParams&) {}), "ok");
}

}  // namespace
}  // namespace vsurg::tissue
