// vsurg-sim cut: the pattern-cutting drill (common/sim/cut_drill.h) run by a scripted hand, with
// its metrics, the force against the fracture model's prediction, and the cost of each stage.
#include <ostream>

#include <nlohmann/json.hpp>

#include "common/cli/commands.h"
#include "common/cli/cut_figure.h"
#include "common/core/args.h"
#include "common/sim/cut_drill.h"

namespace vsurg::cli::commands {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

json Times(const sim::StageTimes& t) {
  return {{"p50_us", t.p50_us}, {"p99_us", t.p99_us}, {"max_us", t.max_us}};
}

json ToJson(const sim::CutDrillSpec& spec, const sim::CutDrillResult& r, const std::string& hand) {
  const scoring::CutMetrics& m = r.metrics;
  json why = json::array();
  for (const auto& line : scoring::ExplainCut(m, spec.task)) why.push_back(line);
  return {{"drill", spec.name},
          {"hand", hand},
          {"score", m.score},
          {"completed", m.completed},
          {"completion_time_s", m.completion_time},
          {"duration_s", m.duration},
          {"deviation_rms_mm", m.deviation_rms * 1e3},
          {"deviation_max_mm", m.deviation_max * 1e3},
          {"cut_length_mm", m.cut_length * 1e3},
          {"outside_length_mm", m.outside_length * 1e3},
          {"coverage", m.coverage},
          {"through_share", m.through_share},
          {"lifts", m.lifts},
          {"piece_freed", m.piece_freed},
          {"peak_force_n", m.peak_force},
          {"time_over_limit_s", m.time_over_limit},
          {"torn_length_mm", m.torn_length * 1e3},
          {"peak_grasp_force_n", r.peak_grasp_force},
          {"why", why},
          {"cutting_force_n", r.cutting_force},
          {"force_rms_error", r.force_rms_error},
          {"cutting_steps", r.cutting_steps},
          {"puncture_force_n", r.puncture_force},
          {"peak_press_n", r.peak_press},
          {"blade_step", Times(r.blade)},
          {"tissue_step", Times(r.tissue)},
          {"max_cut_us", r.max_cut_us},
          {"cut_edges", r.cut_edges},
          {"particles", r.particles},
          {"freed_pieces", r.freed},
          {"steps", r.steps},
          {"diverged", r.diverged}};
}

// Targets from `n` expert runs of the drill (seeds 1..n), and `m` checked against them.
Expected<json> CheckAgainstExperts(const sim::CutDrillSpec& spec, int n,
                                   const scoring::CutMetrics& m) {
  if (n < 2 || n > 20) return InvalidArgument("--experts", "--experts: 2 to 20 runs");
  std::vector<scoring::CutMetrics> experts;
  for (int seed = 1; seed <= n; ++seed) {
    auto e = sim::RunCutDrill(spec, sim::CutHand::Expert(static_cast<uint32_t>(seed)));
    if (!e.ok()) return e.error();
    experts.push_back(e->metrics);
  }
  auto targets = scoring::CutTargetsFromExperts(experts);
  if (!targets.ok()) return targets.error();
  json checks = json::array();
  bool passed = true;
  for (const scoring::CutCheck& c : scoring::CheckCut(m, *targets)) {
    checks.push_back(
        {{"metric", c.metric}, {"value", c.value}, {"target", c.target}, {"met", c.met}});
    passed = passed && c.met;
  }
  return json{{"experts", n}, {"checks", checks}, {"passed", passed}};
}

}  // namespace

int Cut(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-sim cut",
      "Runs the pattern-cutting drill: a scripted trainee's grasper holds a taut patch\n"
      "while the other hand presses a blade through it and draws it along the marked line\n"
      "or circle at 1 kHz; the blade's force is the fracture-mechanics model, the patch\n"
      "is cut, held, torn and deformed at the same rate.\n"
      "Prints the cut's metrics and score, the force against J_c t, and each stage's cost.");
  p.Option("drill", Kind::kString, "drill file (scenes/drills/*.json)", true)
      .Option("hand", Kind::kString, "expert or novice (default expert)")
      .Option("seed", Kind::kInt, "the hand's wobble (default 1)")
      .Option("figure", Kind::kString, "write DIR/cut.png: the patch as cut, the force (gnuplot)")
      .Option("grasp-pull", Kind::kDouble,
              "the left hand pulls the patch this far from the cut (mm)")
      .Option("experts", Kind::kInt,
              "targets from this many expert runs (seeds 1..N), the run checked against them");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto spec = sim::LoadCutDrill(p.String("drill"));
  if (!spec.ok()) return UsageError(err, p.command(), spec.error());
  const std::string hand = p.Has("hand") ? p.String("hand") : "expert";
  if (hand != "expert" && hand != "novice")
    return UsageError(err, p.command(),
                      InvalidArgument("--hand", "--hand: expert or novice, got '" + hand + "'"));
  const auto seed = static_cast<uint32_t>(p.Has("seed") ? p.Int("seed") : 1);
  sim::CutHand cut_hand =
      hand == "expert" ? sim::CutHand::Expert(seed) : sim::CutHand::Novice(seed);
  if (p.Has("grasp-pull")) {
    const double pull = p.Double("grasp-pull");
    if (!(pull >= 0 && pull <= 30))
      return UsageError(err, p.command(),
                        InvalidArgument("--grasp-pull", "--grasp-pull: 0 to 30 mm"));
    cut_hand.grasp_pull = pull * 1e-3;
  }
  sim::CutDrillTrace trace;
  auto r = sim::RunCutDrill(*spec, cut_hand, p.Has("figure") ? &trace : nullptr);
  if (!r.ok()) return UsageError(err, p.command(), r.error());
  if (p.Has("figure")) {
    const std::string who =
        hand + " hand" +
        (p.Has("grasp-pull") ? ", grasp pulled " + p.String("grasp-pull") + " mm" : "");
    if (Status st = WriteCutFigure(p.String("figure"), *spec, *r, trace, who); !st.ok())
      return UsageError(err, p.command(), st.error());
  }
  json j = ToJson(*spec, *r, hand);
  if (p.Has("experts")) {
    auto checked = CheckAgainstExperts(*spec, p.Int("experts"), r->metrics);
    if (!checked.ok()) return UsageError(err, p.command(), checked.error());
    j["proficiency"] = *checked;
  }
  out << j.dump() << "\n";
  return r->diverged ? 1 : 0;
}

}  // namespace vsurg::cli::commands
