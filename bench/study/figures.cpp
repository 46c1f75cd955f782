// The study's figures, drawn by gnuplot (Debian gnuplot-nox, pngcairo): real axes, log scales,
// legends and fonts. Each figure is a data file (one gnuplot data block per series, its title
// in the block's first line) and a script beside it, kept in the output folder so a figure can
// be restyled or redrawn without rerunning the study.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <vector>

#include "bench/study/study.h"

extern char** environ;

namespace vsurg::bench::study {
namespace {

namespace fs = std::filesystem;

struct Series {
  std::string title;
  std::vector<std::pair<double, double>> points;
};

// Writes NAME.dat and NAME.gp in `dir` and runs gnuplot on the script: NAME.png.
Status Draw(const fs::path& dir, const std::string& name, const std::vector<Series>& series,
            const std::string& settings, const std::string& style) {
  const fs::path dat = dir / (name + ".dat"), gp = dir / (name + ".gp");
  {
    std::ofstream out(dat);
    for (const Series& s : series) {
      out << "\"" << s.title << "\" \"\"\n";  // the block's header: columnheader(1) is its title
      for (const auto& [x, y] : s.points) out << x << " " << y << "\n";
      out << "\n\n";
    }
    if (!out) return Error{ErrorCode::kIoError, "cannot write " + dat.string(), "out"};
  }
  {
    std::ofstream out(gp);
    out << "set terminal pngcairo size 960,600 font 'DejaVu Sans,11'\n"
        << "set output '" << name << ".png'\n"
        << settings << "set key outside right top\nset grid\n"
        << "plot for [i=0:" << series.size() - 1 << "] '" << name
        << ".dat' index i using 1:2 title columnheader(1) " << style << "\n";
    if (!out) return Error{ErrorCode::kIoError, "cannot write " + gp.string(), "out"};
  }
  // gnuplot runs in `dir` so the script's relative paths hold.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  const std::string script = gp.filename().string(), cwd = fs::absolute(dir).string();
  std::string cd_and_run = "cd '" + cwd + "' && exec gnuplot '" + script + "'";
  std::vector<char*> argv = {const_cast<char*>("sh"), const_cast<char*>("-c"), cd_and_run.data(),
                             nullptr};
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, "sh", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  int status = 0;
  if (rc != 0 || waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return Error{ErrorCode::kIoError,
                 "gnuplot failed on " + gp.string() + " (is gnuplot-nox installed?)", "out"};
  return Status::Ok();
}

}  // namespace

Status WriteFigures(const std::string& dir, const std::vector<SceneOut>& scenes) {
  // Pareto: time per update against RMS error, one series per model, all scenes.
  std::vector<Series> models;
  std::map<std::string, size_t> index;
  for (const SceneOut& s : scenes)
    for (const Row& r : s.rows) {
      if (!std::isfinite(r.rms) || !(r.time_us > 0)) continue;
      if (!index.count(r.model)) index[r.model] = models.size(), models.push_back({r.model, {}});
      models[index[r.model]].points.push_back({r.time_us, std::max(r.rms, 1e-4)});
    }
  if (models.empty()) return Error{ErrorCode::kNumerical, "no model produced a finite error", ""};
  if (Status s = Draw(dir, "speed-vs-error", models,
                      "set title 'Time per update against RMS marker error, all scenes'\n"
                      "set logscale xy\nset xlabel 'time per update (µs)'\n"
                      "set ylabel 'RMS marker error (relative)'\n",
                      "with points pointsize 1.3");
      !s.ok())
    return s;
  // Marker 8 during the arm ramp: each dynamic model's trajectory.
  std::vector<Series> lines;
  for (const Trajectory& tr : scenes.at(0).trajectories) {
    Series s{tr.label, {}};
    for (size_t i = 0; i < tr.t.size() && i < tr.d.size(); ++i)
      s.points.push_back({tr.t[i], 1000 * tr.d[i]});
    lines.push_back(std::move(s));
  }
  if (lines.empty()) return Status::Ok();
  return Draw(dir, "marker8", lines,
              "set title 'Marker 8 during the arm ramp to 2.07 N·m (ramp 1 s, hold 2 s)'\n"
              "set xlabel 'time (s)'\nset ylabel 'displacement (mm)'\n",
              "with lines linewidth 2");
}

}  // namespace vsurg::bench::study
