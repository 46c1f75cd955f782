#include "bench/study/study.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <tuple>

#include "common/sim/scene.h"
#include "common/tissue/reduced.h"

namespace vsurg::bench::study {

void Progress::Step(const std::string& what) {
  ++done_;
  const int width = 30, filled = width * done_ / std::max(1, total_);
  std::fprintf(stderr, "\r[%s%s] %3d%%  %-48.48s", std::string(filled, '#').c_str(),
               std::string(width - filled, '.').c_str(), 100 * done_ / std::max(1, total_),
               what.c_str());
  if (done_ >= total_) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

double MedianUs(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int Nearest(const std::vector<Vec3>& points, const Vec3& p) {
  int best = 0;
  double d = kInf;
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    const double e = (points[i] - p).squaredNorm();
    if (e < d) d = e, best = i;
  }
  return best;
}

void Score(Row& row, const std::vector<Vec3>& rest, const std::vector<Vec3>& now,
           const std::vector<int>& marker_vertices, const Reference& ref) {
  double scale = 0;
  std::vector<double> e;
  for (int v : marker_vertices) scale = std::max(scale, ref(rest[v]).norm());
  for (int v : marker_vertices) {
    const Vec3 d = now[v] - rest[v];
    if (!d.allFinite()) {
      row.rms = row.max = kInf;
      row.note = "diverged";
      return;
    }
    e.push_back((d - ref(rest[v])).norm() / std::max(scale, 1e-12));
  }
  double s2 = 0, mx = 0;
  for (double x : e) s2 += x * x, mx = std::max(mx, x);
  row.rms = std::sqrt(s2 / static_cast<double>(e.size()));
  row.max = mx;
}

Reference InterpolatedReference(const geometry::TetMesh& mesh, std::vector<Vec3> displacement) {
  return [mesh, u = std::move(displacement)](const Vec3& x) -> Vec3 {
    auto e = geometry::EmbedPoints(mesh, {x});
    return e.ok() ? geometry::Interpolate((*e)[0], u) : Vec3::Constant(kInf);
  };
}

double Ramp(double t, double ramp_s) {
  return std::clamp(t / ramp_s, 0.0, 1.0);
}

int Substeps(double omega, double limit, double beta) {
  if (!std::isfinite(limit)) return 1;
  const double zeta = 0.5 * beta * omega;
  const double h = limit / std::max(omega, 1e-9) * (std::sqrt(1 + zeta * zeta) - zeta) / 1.2;
  return std::clamp(static_cast<int>(std::ceil(1e-3 / h)), 1, 100);
}

double StabilityLimit(tissue::Integrator integrator) {
  switch (integrator) {
    case tissue::Integrator::kSymplecticEuler:
    case tissue::Integrator::kVerlet:
      return 1.8;
    case tissue::Integrator::kRk4:
      return 2.5;
    case tissue::Integrator::kImplicitEuler:
      return kInf;
    default:
      return 0.5;
  }
}

void ContactTableRow(const Config& cfg, const Expected<tissue::FemStaticResponse>& response,
                     const geometry::TriMesh& display, const std::vector<int>& reachable,
                     double max_force, int top, const std::vector<int>& markers,
                     const Reference& reference, Clock::time_point t0, Row& row) {
  tissue::ContactResponseParams cp;
  cp.footprint_radius = kCapRadius;
  auto table = response.ok() ? tissue::PrecomputeContactResponse(*response, display, reachable, cp)
                             : Expected<tissue::ContactResponse>(response.error());
  const double precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const int64_t bytes = table.ok() ? table->Bytes() : 0;
  auto model = table.ok() ? tissue::ReducedContactModel::Create(
                                std::make_shared<tissue::ContactResponse>(std::move(*table)),
                                display.positions, max_force)
                          : Expected<tissue::ReducedContactModel>(table.error());
  if (!model.ok()) {
    row.note = model.error().message;
    return;
  }
  row.size = model->VertexCount();
  row.time_us = TimeUs(cfg.repeats * 5, [&](int i) {
    model->Press(top, Vec3(0, 0, -kPressForce * ((i % 2) ? 1.0 : 0.97)));
  });
  model->Press(top, Vec3(0, 0, -kPressForce));
  Score(row, display.positions, model->positions(), markers, reference);
  row.note = "precomputed in " + Num(precompute_s, 2) + " s (tetrahedra included); " +
             std::to_string(reachable.size()) + " contacts, " + Num(bytes / 1048576.0, 3) + " MB";
}

SceneOut NewSceneOut(std::string scene, std::string scene_file) {
  SceneOut out;
  out.scene = std::move(scene);
  out.scene_file = std::move(scene_file);
  std::tie(out.budget, out.scene_family) = SceneBudget(out.scene_file);
  return out;
}

std::pair<double, std::string> SceneBudget(const std::string& file) {
  auto scene = sim::LoadSceneByName(file);
  if (!scene.ok()) return {0.1, "?"};
  return {scene->error_budget_rms, sim::ModelKindName(scene->region.kind)};
}

}  // namespace vsurg::bench::study
