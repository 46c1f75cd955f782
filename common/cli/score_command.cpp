// vsurg-sim score: the weighted evaluation report of the coil-spring paper (eqs. 9-11) from a
// ratings CSV.
#include "common/cli/commands.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <numbers>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "common/core/file.h"
#include "common/geometry/mesh_generators.h"
#include "common/geometry/obj_io.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "common/sim/limb_scene.h"
#include "common/sim/scene.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "common/tissue/coil_calibration.h"
#include "common/tissue/coil_spring.h"
#include "common/tissue/mass_spring.h"

namespace vsurg::cli::commands {
namespace {

using json = nlohmann::json;
using Kind = ArgParser::Kind;

void PrintReportTable(std::ostream& out, const scoring::EvaluationReport& r) {
  out << std::fixed << std::setprecision(3);
  out << "raters " << r.raters << " (intern " << r.raters_per_group[0] << ", associate_chief "
      << r.raters_per_group[1] << ", chief " << r.raters_per_group[2] << "), weights '"
      << r.weights.name << "'\n";
  if (r.renormalised) {
    out << "absent groups:";
    for (const auto& g : r.absent_groups) out << " " << g;
    out << " (present group weights renormalised)\n";
  }
  out << "index                    weight   M_j (eq.9)   s_j (eq.10)\n";
  for (int j = 0; j < scoring::kIndexCount; ++j)
    out << std::left << std::setw(24) << scoring::IndexName(j) << std::right << std::setw(7)
        << r.weights.index[j] << std::setw(13) << r.index_means[j] << std::setw(14)
        << r.index_variances[j] << "\n";
  out << "comprehensive N (eq.11): " << r.comprehensive << "\n";
  out << "ICC(2,k) over indexes:   " << r.icc2k_indexes << "\n";
  out << "Cronbach alpha:          " << r.cronbach_alpha << "\n";
}

}  // namespace

int Score(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-sim score",
              "Computes the weighted evaluation report of the coil-spring paper section 4.4 "
              "offline: per index\n"
              "the group-weighted mean M_j (eq. 9) and variance s_j (eq. 10), the comprehensive\n"
              "score N (eq. 11), and how far the raters agree (ICC(2,k), Cronbach's alpha).\n"
              "Input rows: evaluator_id,group,i1,...,i9 (group intern, associate_chief or chief;\n"
              "scores 0-10), an optional header row, an optional 12th column naming the subject\n"
              "(several subjects: one report each and ICC(2,k) per index across them).");
  p.Option("input", Kind::kString, "ratings CSV", true)
      .Option("weights", Kind::kString,
              "weight set JSON {name, group{...}, index[9]} (default: the coil-spring paper)")
      .Option("json", Kind::kFlag, "print one JSON object");
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  scoring::WeightSet weights;
  if (p.Has("weights")) {
    auto text = ReadTextFile(p.String("weights"), "--weights");
    if (!text.ok()) return UsageError(err, p.command(), text.error());
    auto w = scoring::WeightSetFromJsonText(*text);
    if (!w.ok())
      return UsageError(err, p.command(),
                        Error{w.error().code, w.error().message, "--weights: " + w.error().field});
    weights = *w;
  }
  auto text = ReadTextFile(p.String("input"), "--input");
  if (!text.ok()) return UsageError(err, p.command(), text.error());
  auto subjects = scoring::ParseRatingsCsv(*text, p.String("input"));
  if (!subjects.ok()) {
    err << p.command() << ": --input: " << subjects.error().message << "\n";
    return kExitUsage;
  }
  if (subjects->size() == 1) {
    auto report = scoring::Evaluate(subjects->front().ratings, weights);
    if (!report.ok()) return UsageError(err, p.command(), report.error());
    if (p.Flag("json")) {
      json j = scoring::ReportToJson(*report);
      if (!subjects->front().subject.empty()) j["subject"] = subjects->front().subject;
      out << j.dump() << "\n";
    } else {
      PrintReportTable(out, *report);
    }
    return 0;
  }
  auto comparison = scoring::Compare(*subjects, weights);
  if (!comparison.ok()) return UsageError(err, p.command(), comparison.error());
  std::vector<std::string> names;
  for (const auto& s : *subjects) names.push_back(s.subject);
  if (p.Flag("json")) {
    out << scoring::ComparisonToJson(*comparison, names).dump() << "\n";
    return 0;
  }
  for (size_t s = 0; s < names.size(); ++s) {
    out << "== subject '" << names[s] << "'\n";
    PrintReportTable(out, comparison->subjects[s]);
  }
  out << "ICC(2,k) per index across subjects (" << comparison->common_raters << " common raters):";
  for (double v : comparison->icc2k_per_index) out << " " << v;
  out << "\n";
  return 0;
}

}  // namespace vsurg::cli::commands
