// The speed-against-error study's report: the cheapest model within each scene's budget, the
// CSV, and the Markdown table kept in docs/BENCHMARKS.md between the study's markers.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "bench/study/study.h"
#include "common/core/csv.h"
#include "common/sim/scene.h"

namespace vsurg::bench::study {
namespace {

// One CSV text field (RFC 4180 quoting), through the project's writer.
std::string CsvField(const std::string& s) {
  std::string out;
  csv::AppendText(out, s);
  return out;
}

}  // namespace

void ChooseCheapest(SceneOut& s) {
  const Row* best = nullptr;
  for (const Row& r : s.rows)
    if (std::isfinite(r.rms) && r.rms <= s.budget && (!best || r.time_us < best->time_us))
      best = &r;
  s.chosen = best ? best->model + " (" + best->setting + ")" : "none within budget";
  const bool same = best && best->model.rfind(s.scene_family, 0) == 0;
  s.chosen += "; `scenes/" + s.scene_file + ".json` uses " + s.scene_family +
              (same ? ": consistent" : ": **not** the cheapest within its budget");
}

std::vector<BudgetVerdict> CheckSceneBudgets(const std::vector<SceneOut>& scenes) {
  std::vector<BudgetVerdict> out;
  std::set<std::string> seen;
  for (const SceneOut& s : scenes)
    for (const SceneModelCheck& c : s.checks) {
      if (seen.count(c.file)) continue;  // a file's first (hardest) study scene decides
      BudgetVerdict v;
      v.file = c.file;
      v.budget = SceneBudget(c.file).first;
      v.in_study = true;
      for (const Row& r : s.rows)
        if (r.model == c.model && r.setting.rfind(c.setting_prefix, 0) == 0) {
          v.model = r.model;
          v.setting = r.setting + " (" + s.scene + ")";
          v.rms = r.rms;
          break;
        }
      v.meets = std::isfinite(v.rms) && v.rms <= v.budget;
      seen.insert(c.file);
      out.push_back(v);
    }
  // The scene files no study row reproduces.
  std::error_code ec;
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(sim::ScenesDirectory(), ec))
    if (e.path().extension() == ".json") files.push_back(e.path().stem().string());
  std::sort(files.begin(), files.end());
  for (const std::string& f : files)
    if (!seen.count(f)) {
      BudgetVerdict v;
      v.file = f;
      v.budget = SceneBudget(f).first;
      out.push_back(v);
    }
  return out;
}

std::string BudgetTable(const std::vector<BudgetVerdict>& verdicts) {
  std::ostringstream md;
  md << "**Scene files against their own budgets** (the study's row that runs the file's own "
        "model with the file's own parameters, under the study's load)\n\n| scene file "
        "| model as the study runs it | RMS error | budget | verdict |\n"
        "| --- | --- | --- | --- | --- |\n";
  for (const BudgetVerdict& v : verdicts) {
    md << "| `scenes/" << v.file << ".json` | "
       << (v.in_study ? (v.model.empty() ? "(row missing)" : v.model + ", " + v.setting)
                      : "not in the study")
       << " | " << (std::isfinite(v.rms) ? Num(100 * v.rms, 3) + "%" : "—") << " | "
       << Num(100 * v.budget, 3) << "% | "
       << (!v.in_study ? "not checked"
           : v.meets   ? "within"
                       : "**over its budget**")
       << " |\n";
  }
  md << "\n";
  return md.str();
}

std::string Num(double v, int digits) {
  if (!std::isfinite(v)) return "";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

Status WriteCsv(const std::string& path, const std::vector<SceneOut>& scenes) {
  std::ofstream out(path);
  if (!out) return Error{ErrorCode::kIoError, "cannot write " + path, "out"};
  out << "model,scene,setting,time_per_update_us,rms_error,max_error,size,budget,meets_budget,"
         "note\n";
  for (const SceneOut& s : scenes)
    for (const Row& r : s.rows)
      out << CsvField(r.model) << "," << s.scene << "," << CsvField(r.setting) << ","
          << Num(r.time_us) << "," << Num(r.rms) << "," << Num(r.max) << "," << r.size << ","
          << s.budget << "," << (std::isfinite(r.rms) && r.rms <= s.budget ? "yes" : "no") << ","
          << CsvField(r.note) << "\n";
  return out ? Status::Ok() : Status(Error{ErrorCode::kIoError, "write failed: " + path, "out"});
}

// One line per scene: its budget, the cheapest model within it, and the most accurate model at
// haptic rate (at most 20 µs per update). Every row of the study is in the CSV beside it.
std::string MarkdownTable(const std::vector<SceneOut>& scenes, const std::string& command) {
  constexpr double kHapticUs = 20;
  std::ostringstream md;
  md << "Command: `" << command << "`. Error: marker displacement error relative to the "
     << "reference's largest marker displacement (RMS over the ten markers); time: median time per "
     << "deformation update on this machine. Every model and setting: "
        "`docs/speed-vs-error.csv`.\n\n"
     << "| study scene | budget | cheapest within it | most accurate at ≤ 20 µs | time | RMS |\n"
     << "| --- | --- | --- | --- | --- | --- |\n";
  for (const SceneOut& s : scenes) {
    const Row* best = nullptr;
    for (const Row& r : s.rows)
      if (r.time_us <= kHapticUs && std::isfinite(r.rms) && (!best || r.rms < best->rms)) best = &r;
    md << "| " << s.scene << " | " << Num(100 * s.budget, 3) << "% | " << s.chosen << " | ";
    if (best) {
      md << best->model << ", " << best->setting << " | " << Num(best->time_us, 3) << " µs | "
         << Num(100 * best->rms, 3) << "% |\n";
    } else {
      md << "none | — | — |\n";
    }
  }
  md << "\n";
  return md.str();
}

Status UpdateBenchmarks(const std::string& path, const std::string& table) {
  const std::string begin = "<!-- speed-vs-error:begin -->", end = "<!-- speed-vs-error:end -->";
  std::ifstream in(path);
  std::stringstream text;
  if (in) text << in.rdbuf();
  std::string s = text.str();
  const std::string block = begin + "\n" + table + end;
  const auto b = s.find(begin), e = s.find(end);
  if (b != std::string::npos && e != std::string::npos && e > b) {
    s.replace(b, e + end.size() - b, block);
  } else {
    s += "\n## Speed against error\n\n" + block + "\n";
  }
  std::ofstream out(path);
  out << s;
  return out ? Status::Ok() : Status(Error{ErrorCode::kIoError, "cannot write " + path, "out"});
}

}  // namespace vsurg::bench::study
