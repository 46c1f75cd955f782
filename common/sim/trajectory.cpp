#include "common/sim/trajectory.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>

#include "common/geometry/bvh.h"
#include "common/geometry/mesh_generators.h"
#include "common/sim/cut_trainee.h"
#include "common/sim/needle_trainee.h"

namespace vsurg::sim {

using haptics::StylusSample;
using Vec3 = Eigen::Vector3d;

namespace {

constexpr const char* kHeader = "t,x,y,z,qw,qx,qy,qz,buttons";
constexpr size_t kMaxSamples = 50'000'000;

// A piecewise plan: each phase moves a scalar from `from` to `to` over `duration` seconds.
struct Phase {
  double duration, from, to;
  bool smooth;  // minimum-jerk or linear
};

double PlanValue(const std::vector<Phase>& plan, double t) {
  double t0 = 0;
  for (const Phase& p : plan) {
    if (t <= t0 + p.duration) {
      const double u = p.duration > 0 ? (t - t0) / p.duration : 1.0;
      return p.from + (p.to - p.from) * (p.smooth ? MinJerk(u) : std::clamp(u, 0.0, 1.0));
    }
    t0 += p.duration;
  }
  return plan.empty() ? 0.0 : plan.back().to;
}

double PlanDuration(const std::vector<Phase>& plan) {
  double d = 0;
  for (const Phase& p : plan) d += p.duration;
  return d;
}

}  // namespace

Expected<std::vector<StylusSample>> ParseTrajectoryCsv(const std::string& text,
                                                       const std::string& source) {
  std::istringstream in(text);
  std::string line;
  long line_no = 0;
  auto fail = [&](const std::string& why) {
    return Error{ErrorCode::kParseError, source + ":" + std::to_string(line_no) + ": " + why,
                 "trajectory"};
  };
  std::vector<StylusSample> out;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line_no == 1) {
      if (line != kHeader) return fail(std::string("the header must be '") + kHeader + "'");
      continue;
    }
    if (line.empty()) continue;
    double v[9];
    size_t pos = 0;
    for (int c = 0; c < 9; ++c) {
      const size_t end = c < 8 ? line.find(',', pos) : line.size();
      if (end == std::string::npos)
        return fail("expected 9 columns, found " + std::to_string(c + 1));
      const char* b = line.data() + pos;
      const char* e = line.data() + end;
      auto [ptr, ec] = std::from_chars(b, e, v[c]);
      if (ec != std::errc() || ptr != e) {
        static const char* kNames[] = {"t", "x", "y", "z", "qw", "qx", "qy", "qz", "buttons"};
        return fail(std::string("column ") + kNames[c] + ": '" + std::string(b, e) +
                    "' is not a number");
      }
      pos = end + 1;
    }
    if (pos <= line.size()) return fail("expected 9 columns, found more");
    if (out.size() >= kMaxSamples) return fail("more than 50 million samples");
    StylusSample s;
    s.time = v[0];
    s.position = Vec3(v[1], v[2], v[3]);
    s.orientation = Eigen::Quaterniond(v[4], v[5], v[6], v[7]);
    const double qn = s.orientation.norm();
    if (std::isfinite(qn) && qn > 0) s.orientation.normalize();
    if (!(v[8] >= 0 && v[8] < 4294967296.0 && v[8] == std::floor(v[8]))) {
      return fail("column buttons: must be a non-negative integer");
    }
    s.buttons = static_cast<uint32_t>(v[8]);
    out.push_back(s);  // NaN and infinities are kept: the simulation's safety deals with them
  }
  if (line_no == 0)
    return Error{ErrorCode::kParseError, source + ": empty file, no header", "trajectory"};
  return out;
}

Expected<std::vector<StylusSample>> ReadTrajectoryCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{ErrorCode::kIoError, path + ": cannot open", "trajectory"};
  std::stringstream text;
  text << in.rdbuf();
  return ParseTrajectoryCsv(text.str(), path);
}

Status WriteTrajectoryCsv(const std::vector<StylusSample>& samples, const std::string& path) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) return Error{ErrorCode::kIoError, path + ": cannot write", "out"};
    out << kHeader << "\n";
    char buf[256];
    for (const StylusSample& s : samples) {
      const auto& q = s.orientation;
      std::snprintf(buf, sizeof buf, "%.6f,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u\n", s.time,
                    s.position.x(), s.position.y(), s.position.z(), q.w(), q.x(), q.y(), q.z(),
                    s.buttons);
      out << buf;
    }
    out.flush();
    if (!out) return Error{ErrorCode::kIoError, path + ": write failed", "out"};
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return Error{ErrorCode::kIoError, path + ": cannot rename", "out"};
  return Status::Ok();
}

Expected<TraineeStyle> ParseTraineeStyle(const std::string& name) {
  if (name == "good") return TraineeStyle::kGood;
  if (name == "hesitant") return TraineeStyle::kHesitant;
  if (name == "rough") return TraineeStyle::kRough;
  if (name == "steady") return TraineeStyle::kSteady;
  return InvalidArgument("style",
                         "unknown trainee style '" + name + "' (good, hesitant, rough, steady)");
}

// The task quantity over time by style: twist (rad) or press depth below the rest surface (m).
static std::vector<Phase> StylePhases(TraineeStyle style, double target, double hold) {
  std::vector<Phase> plan;
  switch (style) {
    case TraineeStyle::kGood:
      plan = {{0.5, 0, 0, true},
              {2.0, 0, target, true},
              {hold + 1.0, target, target, true},
              {0.8, target, 0, true}};
      break;
    case TraineeStyle::kHesitant:
      plan = {{1.0, 0, 0, true},
              {3.0, 0, 0.7 * target, true},
              {1.0, 0.7 * target, 0.7 * target, true},
              {1.5, 0.7 * target, 0.88 * target, true},
              {1.0, 0.88 * target, 0.93 * target, true},
              {0.8, 0.93 * target, 0.93 * target, true},
              {1.0, 0.93 * target, target, true},
              {hold + 0.5, target, target, true},
              {1.5, target, 0, true}};
      break;
    case TraineeStyle::kRough:
      plan = {{0.2, 0, 0, false},
              {0.4, 0, 1.5 * target, false},
              {0.8, 1.5 * target, 1.5 * target, false},
              {0.3, 1.5 * target, 0.8 * target, false},
              {0.4, 0.8 * target, 1.15 * target, false},
              {hold * 0.6, 1.15 * target, 1.05 * target, false},
              {0.3, 1.05 * target, 0, false}};
      break;
    case TraineeStyle::kSteady:
      plan = {{0.2, 0, 0, false},           {0.4, 0, target, false},
              {0.8, target, target, false}, {0.3, target, target, false},
              {0.4, target, target, false}, {hold * 0.6, target, target, false},
              {0.3, target, 0, false}};
      break;
  }
  return plan;
}

double MinJerk(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10 - 15 * u + 6 * u * u);
}

// A limb's side 3 cm from the distal end, a sphere's top, or a mesh's surface above its middle.
Expected<Touch> ScriptedTouch(const Scene& scene) {
  Touch t;
  Vec3 &surface_point = t.surface, &normal = t.normal, &axis_point = t.axis_point, &axis = t.axis;
  if (scene.mesh.kind == MeshKind::kLimb) {
    const double z = scene.mesh.limb.length - 0.03;
    const double a = scene.mesh.limb.radius_proximal +
                     (scene.mesh.limb.radius_distal - scene.mesh.limb.radius_proximal) * z /
                         scene.mesh.limb.length;
    // Between two vertices of the ring so the contact is on a face; the faceted surface sits
    // inside the circle by a·(1 − cos(π/n)).
    const double half = std::numbers::pi / scene.mesh.limb.segments_around;
    surface_point =
        Vec3(a * std::cos(half) * std::cos(half), a * std::cos(half) * std::sin(half), z);
    normal = Vec3(std::cos(half), std::sin(half), 0);
    axis_point = Vec3(0, 0, z);
    axis = Vec3::UnitZ();
  } else if (scene.mesh.kind == MeshKind::kSphere) {
    // Slightly off the pole, inside one face.
    const Vec3 dir = Vec3(0.02, 0.03, 1.0).normalized();
    const double inset = scene.mesh.particles < 100 ? 0.9 : 0.995;  // faceting
    surface_point = scene.mesh.radius * inset * dir;
    normal = dir;
    axis_point = surface_point;
    axis = normal;
  } else {
    // A mesh file (an organ): the surface straight above its middle, where a tool comes down
    // from above, inside the face the vertical line meets.
    auto mesh = BuildSceneMesh(scene.mesh);
    if (!mesh.ok()) return mesh.error();
    const geometry::TriMesh& surface = mesh->surface;
    Vec3 lo = Vec3::Constant(1e30), hi = -lo;
    for (const Vec3& p : surface.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const Vec3 middle = 0.5 * (lo + hi);
    const geometry::Bvh bvh(surface);
    const auto hit = bvh.FirstHit(surface.positions, Vec3(middle.x(), middle.y(), hi.z() + 0.05),
                                  Vec3(middle.x(), middle.y(), lo.z() - 0.05));
    if (hit.triangle < 0)
      return InvalidArgument("scene", "scripted trainees need a surface above the mesh's middle");
    normal = geometry::TriangleNormal(surface, hit.triangle);
    if (normal.z() < 0) normal = -normal;
    surface_point = hit.point;
    axis_point = surface_point;
    axis = normal;
  }
  return t;
}

// The trainee approaches the surface along its normal, sinks 2 mm in, then either twists about
// the task's axis with the grasp held (twist tasks) or presses along the normal (press tasks),
// holds, and leaves.
Expected<std::vector<StylusSample>> ScriptedTrainee(const Scene& scene, TraineeStyle style,
                                                    double rate_hz, unsigned seed) {
  if (!(rate_hz >= 10 && rate_hz <= 100000))
    return InvalidArgument("rate", "rate must be in 10..100000 Hz");
  if (scene.task.kind == scoring::TaskKind::kInsert) return NeedleTrainee(scene, style, rate_hz);
  if (scene.task.kind == scoring::TaskKind::kCut) return CutTrainee(scene, style, rate_hz, seed);
  if (scene.task.kind == scoring::TaskKind::kPalpate)
    return Error{ErrorCode::kFailedPrecondition,
                 "a palpation's scripted trainees search closed on the forces they feel "
                 "(sim::PalpationSearch; vsurg-sim search): no trajectory is written ahead",
                 "scene"};
  auto touch = ScriptedTouch(scene);
  if (!touch.ok()) return touch.error();
  const Vec3 &surface_point = touch->surface, &normal = touch->normal;
  const Vec3 &axis_point = touch->axis_point, &axis = touch->axis;
  const bool twist = scene.task.kind == scoring::TaskKind::kTwist;
  const double target = scene.task.target, hold = scene.task.hold_s;
  const double sink = 0.002;  // m below the surface while grasping
  const std::vector<Phase> plan = StylePhases(style, target, hold);
  const double approach = 0.4, leave = 0.3;  // s
  const double body = PlanDuration(plan);
  const double total = approach + body + leave;
  std::mt19937 rng(seed);
  std::normal_distribution<double> tremor(0.0, style == TraineeStyle::kRough ? 4e-4 : 0.0);
  const Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity();
  std::vector<StylusSample> out;
  const int n = static_cast<int>(std::ceil(total * rate_hz)) + 1;
  out.reserve(n);
  const Vec3 start = surface_point + 0.02 * normal;
  const Vec3 inside = surface_point - sink * normal;
  for (int k = 0; k < n; ++k) {
    const double t = k / rate_hz;
    StylusSample s;
    s.time = t;
    s.orientation = q0;
    if (t < approach) {
      s.position = start + (inside - start) * MinJerk(t / approach);
    } else if (t < approach + body) {
      const double value = PlanValue(plan, t - approach);
      if (twist) {
        const Eigen::AngleAxisd turn(value, axis);
        s.position = axis_point + turn * (inside - axis_point);
        s.orientation = Eigen::Quaterniond(turn) * q0;
        s.buttons =
            t - approach > 0.1 ? uint32_t{haptics::kButtonGrasp} : 0u;  // grasp once in contact
      } else {
        s.position = surface_point - std::max(sink, value) * normal;
      }
    } else {
      const double u = (t - approach - body) / leave;
      s.position = inside + (start - inside) * MinJerk(u);
    }
    if (style == TraineeStyle::kRough) s.position += Vec3(tremor(rng), tremor(rng), tremor(rng));
    out.push_back(s);
  }
  return out;
}

}  // namespace vsurg::sim
