// Simulation's palpation (scoring/palpation.h): the surface a trainee examines, the lumps as
// scoring sees them, and the haptic path's stage that records presses and marks.
#include <cmath>

#include "common/geometry/bvh.h"
#include "common/sim/palpation_case.h"
#include "common/sim/simulation.h"

namespace vsurg::sim {

using geometry::Vec3;

// Set-up: the palpable surface (PalpableTriangles); each lump's surface point is the nearest
// point of that surface to its centre.
Status Simulation::BuildPalpation() {
  if (scene_.task.kind != scoring::TaskKind::kPalpate) return Status::Ok();
  scoring::PalpableSurface surface;
  const std::vector<int> palpable = PalpableTriangles(rest_, held_);
  for (int t : palpable) {
    const geometry::Triangle& tri = rest_.triangles[t];
    const Vec3 &a = rest_.positions[tri[0]], &b = rest_.positions[tri[1]],
               &c = rest_.positions[tri[2]];
    surface.centroids.push_back((a + b + c) / 3.0);
    surface.areas.push_back(0.5 * (b - a).cross(c - a).norm());
  }
  if (palpable.empty())
    return Error{ErrorCode::kInvalidArgument,
                 "a palpation needs a surface facing up that the support leaves free",
                 "regions[0].model.support"};
  std::vector<scoring::Lump> lumps;
  for (const tissue::Inclusion& inc : scene_.inclusions) {
    if (inc.contrast == 1) continue;  // not a lump: the tissue itself
    scoring::Lump lump{inc.centre, inc.radius, inc.centre};
    double best = std::numeric_limits<double>::infinity();
    for (int t : palpable) {
      const geometry::Triangle& tri = rest_.triangles[t];
      const Vec3 &a = rest_.positions[tri[0]], &b = rest_.positions[tri[1]],
                 &c = rest_.positions[tri[2]];
      const Vec3 w = geometry::ClosestPointOnTriangle(inc.centre, a, b, c);  // barycentric
      const Vec3 p = w.x() * a + w.y() * b + w.z() * c;
      if (const double d = (p - inc.centre).squaredNorm(); d < best) best = d, lump.surface = p;
    }
    lumps.push_back(lump);
  }
  palpation_ = scoring::PalpationRecorder(std::move(lumps), std::move(surface), {});
  return Status::Ok();
}

// Haptic thread: the press under the trainee's hand counts towards the coverage; the mark button
// pressed (its rising edge) while the tool is on the surface marks the proxy's point.
void Simulation::PalpationStep(const haptics::StylusSample& trainee, StylusStep& step) {
  if (scene_.task.kind != scoring::TaskKind::kPalpate) return;
  const bool mark = (trainee.buttons & haptics::kButtonMark) != 0;
  const bool contact = step.cmd.contact && !step.cmd.grasping;
  palpation_.Add(contact, step.cmd.proxy, step.force.norm());
  if (mark && !mark_button_ && contact && palpation_.Mark(trial_time_, step.cmd.proxy))
    step.events |= haptics::kEventMarked;
  mark_button_ = mark;
}

scoring::TrialMetrics Simulation::Metrics() const {
  scoring::TrialMetrics m = recorder_.Finish();
  if (scene_.task.kind == scoring::TaskKind::kPalpate) palpation_.Complete(m, scene_.task);
  if (scene_.task.kind == scoring::TaskKind::kCut && cut_.record) {
    const scoring::TaskSpec& t = scene_.task;
    scoring::CompleteCutTrial(
        cut_.record->Complete({scene_.cut->pattern, t.force_limit, t.time_limit, t.expert_time}), t,
        m);
  }
  if (scene_.task.kind == scoring::TaskKind::kInsert && needle_.model)
    needle_.record.Complete(m, scene_.task, static_cast<int>(needle_.model->punctures()),
                            static_cast<int>(needle_.breaches));
  return m;
}

}  // namespace vsurg::sim
