#include "common/sim/contact_law.h"

#include <cmath>

#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"

namespace vsurg::sim {
namespace {

constexpr double kRampS = 0.3, kHoldS = 1.5;  // per depth: the move, then the settling
constexpr double kDepthsMm[] = {0.5, 1, 1.5, 2, 3, 4, 5, 6, 8};

// The fit the server's last contact answer carried over the good trainee's press.
Status FitAtThePress(const Scene& scene, const std::vector<haptics::StylusSample>& good,
                     ContactLaw& law) {
  auto simulation = Simulation::Create(scene, {.threaded = false});
  if (!simulation.ok()) return simulation.error();
  (*simulation)->Replay(good, [&](const haptics::StylusSample&, const haptics::ForceCommand& c) {
    if (c.contact && c.local.tissue_stiffness > 0)
      law.stiffness = c.local.tissue_stiffness, law.damping = c.local.tissue_damping;
  });
  if (!(law.stiffness > 0))
    return InvalidArgument("scene",
                           "the contact has no tissue law of its own (a reduced contact "
                           "sends its series stiffness instead)");
  return Status::Ok();
}

// The stylus from 1 cm above down the normal, each depth approached by a minimum-jerk move and
// held; the sample indices where each hold ends.
std::vector<haptics::StylusSample> StaircasePlan(const Touch& a, std::vector<size_t>& ends) {
  std::vector<haptics::StylusSample> plan;
  Vec3 from = a.surface + 0.01 * a.normal;
  double t = 0;
  const auto add = [&](const Vec3& x) {
    haptics::StylusSample s;
    s.time = t, s.position = x;
    plan.push_back(s);
    t += 1e-3;
  };
  for (const double mm : kDepthsMm) {
    const Vec3 to = a.surface - 1e-3 * mm * a.normal;
    for (int k = 0; k < static_cast<int>(kRampS * 1000); ++k)
      add(from + (to - from) * MinJerk(k / (kRampS * 1000)));
    for (int k = 0; k < static_cast<int>(kHoldS * 1000); ++k) add(to);
    ends.push_back(plan.size() - 1);
    from = to;
  }
  return plan;
}

Status StaticCurve(const Scene& scene, const Touch& a, ContactLaw& law) {
  std::vector<size_t> ends;
  const auto plan = StaircasePlan(a, ends);
  auto simulation = Simulation::Create(scene, {.threaded = false});
  if (!simulation.ok()) return simulation.error();
  size_t i = 0, next = 0;
  (*simulation)->Replay(plan, [&](const haptics::StylusSample& s, const haptics::ForceCommand& c) {
    if (next < ends.size() && i++ == ends[next]) {
      ++next;
      if (!c.contact) return;
      law.curve.push_back({(a.surface - s.position).dot(a.normal),
                           (a.surface - c.proxy).dot(a.normal), c.force.dot(a.normal)});
    }
  });
  return Status::Ok();
}

// The static curve as the station renders it: the points that rise strictly from (0, 0), the
// first TissueCurve::kMaxPoints.
void TakeCurve(ContactLaw& law) {
  double x = 0, f = 0;
  for (const auto& p : law.curve) {
    if (law.tissue.count == haptics::TissueCurve::kMaxPoints) break;
    if (!(p.yield > x && p.force > f)) continue;
    law.tissue.yield[law.tissue.count] = x = p.yield;
    law.tissue.force[law.tissue.count++] = f = p.force;
  }
}

}  // namespace

Expected<ContactLaw> MeasureContactLaw(Scene scene) {
  if (scene.task.kind != scoring::TaskKind::kPress)
    return InvalidArgument("scene", "not a press scene");
  scene.haptics.contact_model = HapticsSpec::ContactModel::kViscoelastic;
  auto good = ScriptedTrainee(scene, TraineeStyle::kGood);
  if (!good.ok()) return good.error();
  ContactLaw law;
  if (Status s = FitAtThePress(scene, *good, law); !s.ok()) return s.error();
  auto touch = ScriptedTouch(scene);  // where the good trainee presses
  if (!touch.ok()) return touch.error();
  if (Status s = StaticCurve(scene, *touch, law); !s.ok()) return s.error();
  TakeCurve(law);
  return law;
}

}  // namespace vsurg::sim
