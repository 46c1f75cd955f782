// vsurg-sim search: a palpation's case drawn and searched by a scripted examiner, headless.
#include <chrono>
#include <cstdio>
#include <ostream>

#include <nlohmann/json.hpp>

#include "common/cli/commands.h"
#include "common/core/args.h"
#include "common/scoring/report_json.h"
#include "common/sim/case_bank.h"
#include "common/sim/palpation_case.h"
#include "common/sim/palpation_search.h"
#include "common/sim/simulation.h"

namespace vsurg::cli::commands {
namespace {

using Kind = ArgParser::Kind;

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int Search(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-sim search",
              "Draws a palpation scene's case (its hidden lumps) and searches it with a scripted\n"
              "examiner closed on the forces it feels; prints the case's build time, the lumps\n"
              "and the trial's palpation metrics.");
  p.Option("scene", Kind::kString, "a palpation scene in scenes/ or a .json path", true)
      .Option("case", Kind::kInt, "the case's seed (default: a new random one)")
      .Option("style", Kind::kString, sim::kSearchStyleNames, false, "expert")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  auto scene = sim::LoadSceneByName(p.String("scene"));
  if (!scene.ok()) return UsageError(err, p.command(), scene.error());
  if (scene->task.kind != scoring::TaskKind::kPalpate)
    return UsageError(err, p.command(), InvalidArgument("--scene", "not a palpation scene"));
  const std::string style = p.String("style");
  auto search_style = sim::SearchStyleByName(style, "--style");
  if (!search_style.ok()) return UsageError(err, p.command(), search_style.error());
  const uint64_t seed =
      p.Has("case") ? static_cast<uint64_t>(p.Int("case")) : sim::CaseBank::NewSeed();
  const auto t0 = std::chrono::steady_clock::now();
  auto drawn = sim::DrawCase(*scene, seed);
  if (!drawn.ok()) return UsageError(err, p.command(), drawn.error());
  auto simulation = sim::Simulation::Create(*drawn, {.threaded = false});
  if (!simulation.ok()) {
    err << p.command() << ": the case does not build: " << simulation.error().message << "\n";
    return kExitRuntime;
  }
  const double build_s = SecondsSince(t0);
  auto search = sim::PalpationSearch::Create((*simulation)->rest_mesh(),
                                             (*simulation)->held_vertices(), *search_style);
  if (!search.ok()) return UsageError(err, p.command(), search.error());
  const auto t1 = std::chrono::steady_clock::now();
  sim::SearchThrough(**simulation, *search);
  const scoring::TrialMetrics m = (*simulation)->Metrics();
  const double search_s = SecondsSince(t1);
  if (p.Flag("json")) {
    nlohmann::json lumps = nlohmann::json::array();
    for (const tissue::Inclusion& l : drawn->inclusions)
      lumps.push_back({{"centre_m", {l.centre.x(), l.centre.y(), l.centre.z()}},
                       {"radius_m", l.radius},
                       {"contrast", l.contrast}});
    out << nlohmann::json{{"case", seed},
                          {"style", style},
                          {"build_s", build_s},
                          {"search_cpu_s", search_s},
                          {"lumps", lumps},
                          {"spots", search->spots().size()},
                          {"metrics", scoring::TrialMetricsToJson(m)}}
               .dump()
        << "\n";
    return 0;
  }
  char line[320];
  std::snprintf(line, sizeof line,
                "case %llu: %zu lump(s), built in %.2f s; the %s pressed %zu spots in %.0f s "
                "(%.1f s of CPU): found %d, %d false mark(s), %.1f mm off, %.0f%% examined, "
                "score %.1f\n",
                static_cast<unsigned long long>(seed), drawn->inclusions.size(), build_s,
                style.c_str(), search->spots().size(), m.duration, search_s, m.lumps_found,
                m.false_marks, 1e3 * m.localisation_error, 100 * m.coverage, m.score);
  out << line;
  return 0;
}

}  // namespace vsurg::cli::commands
