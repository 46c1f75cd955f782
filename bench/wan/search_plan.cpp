// The palpation's rows of the network grid: a stretch of a scripted examiner's search, played
// open loop by the grid's virtual hand (bench/wan/wan.h, SearchPlan).
#include <algorithm>
#include <limits>

#include "bench/wan/wan.h"
#include "common/sim/palpation_search.h"
#include "common/sim/simulation.h"

namespace vsurg::bench::wan {

namespace {

sim::SearchStyle StyleOf(sim::TraineeStyle style) {
  switch (style) {
    case sim::TraineeStyle::kHesitant:
      return sim::HesitantSearch();
    case sim::TraineeStyle::kRough:
      return sim::RoughSearch();
    case sim::TraineeStyle::kGood:
    case sim::TraineeStyle::kSteady:
      break;
  }
  return sim::ExpertSearch();
}

}  // namespace

// The goal's lump (tests/common/sim/palpation_test.cpp): 10 mm across, five times as stiff, its
// centre 15 mm under the pad's top.
const tissue::Inclusion kGridLump{{0.013, -0.009, 0.025}, 0.005, 5};

Expected<std::vector<haptics::StylusSample>> SearchPlan(const sim::Scene& scene,
                                                        sim::TraineeStyle style, double window_s) {
  if (scene.task.kind != scoring::TaskKind::kPalpate)
    return InvalidArgument("scene", "a search needs a palpation scene");
  auto simulation = sim::Simulation::Create(scene, {.threaded = false});
  if (!simulation.ok()) return simulation.error();
  auto search = sim::PalpationSearch::Create((*simulation)->rest_mesh(),
                                             (*simulation)->held_vertices(), StyleOf(style));
  if (!search.ok()) return search.error();
  // The whole search, closed on the tissue's answers without a network.
  std::vector<haptics::StylusSample> samples;
  sim::SearchThrough(**simulation, *search,
                     [&samples](const haptics::StylusSample& s, const haptics::ForceCommand&) {
                       samples.push_back(s);
                     });
  // The stretch centred on the deepest press nearest the lump's top (what the examiner came to
  // find), the mark buttons cleared: the grid measures touch, not marking.
  const Vec3 above = scene.inclusions.empty() ? Vec3::Zero() : scene.inclusions.front().centre;
  size_t centre = 0;
  double best = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < samples.size(); ++k) {
    const double d = (samples[k].position - above).head<2>().norm() + samples[k].position.z();
    if (d < best) best = d, centre = k;
  }
  // It starts with the hand at its highest of the half second before (lifted between two
  // presses): a plan that began in contact would be felt only from the first answer on.
  const size_t half = static_cast<size_t>(500 * window_s);
  size_t from = centre > half ? centre - half : 0;
  for (size_t k = from > 500 ? from - 500 : 0, top = from; k <= top; ++k)
    if (samples[k].position.z() > samples[from].position.z()) from = k;
  const size_t to = std::min(samples.size(), from + 2 * half);
  std::vector<haptics::StylusSample> plan(samples.begin() + from, samples.begin() + to);
  for (size_t k = 0; k < plan.size(); ++k) plan[k].time = k * 1e-3, plan[k].buttons = 0;
  return plan;
}

}  // namespace vsurg::bench::wan
