// vsurg-bench wan: the closed-loop network grid (bench/wan/wan.h) over profiles × scenes ×
// methods, each cell against the same scene and method through the relay with no impairment.
// Writes DIR/wan.csv (one row per cell and run), DIR/traces/*.csv (the force per servo cycle of
// the first run of each cell) and gnuplot figures (force over time per profile; error and
// datagram rate against the round trip). docs/BENCHMARKS.md "Haptics across networks".
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "bench/wan/wan.h"
#include "common/core/args.h"
#include "common/sim/trajectory.h"

namespace vsurg::bench {

namespace {

namespace fs = std::filesystem;

constexpr double kSearchWindowS = 6;  // s of a palpation's search the grid plays

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

void Plot(const fs::path& dir, const std::string& name, const std::string& settings,
          const std::string& plot) {
  std::ofstream(dir / (name + ".gp"))
      << "set terminal pngcairo noenhanced size 1100,640 font 'DejaVu Sans,10'\n"
      << "set output '" << name << ".png'\n"
      << settings << "set grid\nset key outside right top\n"
      << plot << "\n";
  const std::string cmd =
      "cd '" + fs::absolute(dir).string() + "' && gnuplot '" + name + ".gp' > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0)
    std::cerr << "vsurg-bench wan: gnuplot failed on " << name << "\n";
}

// What the hand lived, per servo cycle, in the station's --force-log columns.
void WriteTrace(const fs::path& file, const wan::Run& run) {
  std::ofstream t(file);
  t << "t_s,x_m,y_m,z_m,fx_n,fy_n,fz_n\n";
  for (const auto& c : run.trace)
    t << c.t << "," << c.x.x() << "," << c.x.y() << "," << c.x.z() << "," << c.force.x() << ","
      << c.force.y() << "," << c.force.z() << "\n";
}

struct Method {
  std::string name;  // "model", "model+tdpa", "model+fitk", or "model+db0.1" with a deadband
  client::LocalRendering rendering;
  client::PassivityMode passivity;
  double deadband;
  sim::HapticsSpec::ContactModel contact;  // the contact's local model
  bool exact_grasp;
  bool hold;                   // StationOptions::model_hold_s at its default; false: 0 (+fade)
  bool surface;                // the tissue's surface at the station; false: +nosurf
  double contact_heartbeat_s;  // StationOptions::deadband_contact_heartbeat_s (+chbN, N ms)
};

// The methods by name, each at every deadband (wan --methods, --deadbands).
Expected<std::vector<Method>> ParseMethods(const std::string& names, const std::string& deadbands) {
  std::vector<Method> methods;
  for (const auto& name : Split(names)) {
    std::string base = name;
    const auto strip = [&base](const std::string& suffix) {
      const bool has = base.size() > suffix.size() && base.ends_with(suffix);
      if (has) base.resize(base.size() - suffix.size());
      return has;
    };
    const bool no_surface = strip("+nosurf");  // the very last suffix
    const bool fade = strip("+fade");
    double contact_heartbeat_s = client::StationOptions{}.deadband_contact_heartbeat_s;
    if (const size_t at = base.rfind("+chb"); at != std::string::npos) {
      contact_heartbeat_s = std::strtod(base.c_str() + at + 4, nullptr) / 1e3;
      if (!(contact_heartbeat_s > 0.001 && contact_heartbeat_s <= 0.25))
        return InvalidArgument("methods", "+chbN: N ms in (1, 250]");
      base.resize(at);
    }
    const bool fit_k = strip("+fitk"), proxy_k = strip("+proxyk");
    const bool tdpa = strip("+tdpa");
    const bool tangent = strip("+tangent");
    using ContactModel = sim::HapticsSpec::ContactModel;
    const ContactModel contact = fit_k     ? ContactModel::kFitted
                                 : proxy_k ? ContactModel::kProxy
                                           : ContactModel::kViscoelastic;
    auto m = client::ParseLocalRendering(base);
    if (!m.ok()) return m.error();
    const auto mode = tdpa ? client::PassivityMode::kNetwork : client::PassivityMode::kLocal;
    for (const auto& db : Split(deadbands)) {
      const double k = std::strtod(db.c_str(), nullptr);
      if (!(k >= 0 && k < 1)) return InvalidArgument("deadbands", "0 ≤ k < 1");
      methods.push_back({k > 0 ? name + "+db" + db : name, *m, mode, k, contact, !tangent, !fade,
                         !no_surface, contact_heartbeat_s});
    }
  }
  return methods;
}

wan::RunOptions CellOptions(const sim::Scene& scene, const std::vector<haptics::StylusSample>& plan,
                            const Method& method_entry, const client::HandImpedance& grip, int r) {
  const relay::Profile none = *relay::ProfileByName("none");
  wan::RunOptions o;
  o.scene = scene;
  o.scene.haptics.contact_model = method_entry.contact;
  o.plan = plan;
  o.profile = none;
  o.seed = static_cast<uint64_t>(r);
  o.rendering = method_entry.rendering;
  o.deadband = method_entry.deadband;
  o.passivity_mode = method_entry.passivity;
  o.exact_grasp = method_entry.exact_grasp;
  if (!method_entry.hold) o.model_hold_s = 0;
  o.station_surface = method_entry.surface;
  o.contact_heartbeat_s = method_entry.contact_heartbeat_s;
  o.grip = grip;
  return o;
}

std::string CsvRow(const std::string& scene_name, const std::string& profile,
                   const std::string& method_name, int r, const wan::Run& run,
                   const wan::Figures& f) {
  const double rtt_ms = run.station.rtt_p50_us / 1e3;
  char line[512];
  std::snprintf(line, sizeof line,
                "%s,%s,%s,%d,%.2f,%.2f,%.0f,%.2f,%.1f,%.2f,%.2f,%.4f,%.3f,%.3f,%.0f,%.0f,"
                "%.2f,%.3f,%llu,%llu,%llu,%llu,%d,%d,%.0f",
                scene_name.c_str(), profile.c_str(), method_name.c_str(), r, rtt_ms,
                f.rms_error_pct, f.onset_delay_cycles, f.onset_extra_mm, f.stiffness_pct,
                f.energy_to_hand_mj, f.energy_excess_mj, f.oscillation_n, f.peak_force_n,
                f.phantom_n, f.up_hz, f.down_hz, f.score, run.server_peak_force,
                static_cast<unsigned long long>(run.station.lost),
                static_cast<unsigned long long>(run.station.stale),
                static_cast<unsigned long long>(run.station.late),
                static_cast<unsigned long long>(run.station.watchdog_fades), f.pops,
                f.reference_pops, f.pop_delay_cycles);
  return line;
}

// The force magnitude over time per profile, one figure per scene and method; error and datagram
// rate against the round trip, per method.
void PlotFigures(const fs::path& out,
                 const std::map<std::string, std::vector<std::string>>& trace_files,
                 const std::vector<Method>& methods) {
  // Figures: the force magnitude over time per profile, one per scene and method.
  for (const auto& [key, files] : trace_files) {
    std::string plot = "plot ";
    for (size_t i = 0; i < files.size(); ++i) {
      const size_t bar = files[i].find('|');
      plot += (i ? ", " : "") + std::string("'") + files[i].substr(0, bar) +
              "' every ::1 using 1:(sqrt($5**2+$6**2+$7**2)) with lines title '" +
              files[i].substr(bar + 1) + "'";
    }
    Plot(out, "force_" + key,
         "set datafile separator ','\nset xlabel 'device time (s)'\nset ylabel '|F| at the hand "
         "(N)'\nset title '" +
             key + ": force the hand felt, per network profile'\n",
         plot);
  }
  // Error and datagram rate against the round trip, per method (every scene).
  std::string err_plot = "plot ", rate_plot = "plot ";
  for (size_t i = 0; i < methods.size(); ++i) {
    const std::string& m = methods[i].name;
    const std::string sel = "(strcol(3) eq '" + m + "' ? $5 : 1/0)";
    err_plot += (i ? ", " : "") + std::string("'wan.csv' every ::1 using ") + sel +
                ":6 with points pt 7 title '" + m + "'";
    rate_plot += (i ? ", " : "") + std::string("'wan.csv' every ::1 using ") + sel +
                 ":16 with points pt 7 title '" + m + " (down)'";
  }
  Plot(out, "error_vs_rtt",
       "set datafile separator ','\nset logscale x\nset xlabel 'round trip p50 (ms)'\nset "
       "ylabel 'force RMS error (% of the no-delay peak)'\n",
       err_plot);
  Plot(out, "rate_vs_rtt",
       "set datafile separator ','\nset logscale x\nset xlabel 'round trip p50 (ms)'\nset "
       "ylabel 'datagrams per second, server to station'\n",
       rate_plot);
}

// What the hand plays on `scene`: the tap (press scenes, --trainee tap), a stretch of a
// palpation's search, or the scripted trainee.
Expected<std::vector<haptics::StylusSample>> GridPlan(const sim::Scene& scene, bool tap,
                                                      sim::TraineeStyle style) {
  if (tap) return wan::TapPlan(scene);
  if (scene.task.kind == scoring::TaskKind::kPalpate)
    return wan::SearchPlan(scene, style, kSearchWindowS);
  return sim::ScriptedTrainee(scene, style, 1000.0, 1);
}

}  // namespace

int Wan(const std::vector<std::string>& args) {
  cli::ArgParser p("vsurg-bench wan",
                   "haptics across networks: a simulated hand through the impairment relay");
  p.Option("profiles", cli::ArgParser::Kind::kString, "comma-separated relay profiles", false,
           "lan,metro,regional,continental,intercontinental,bad-wifi")
      .Option("scenes", cli::ArgParser::Kind::kString, "comma-separated", false,
              "sphere-palpation-256,sphere-palpation-256@700,arm-torsion,organ-surface-twist; "
              "also needle-vessel (pop_delay_ms), lump-search (6 s of a search at its lump)")
      .Option("methods", cli::ArgParser::Kind::kString,
              "server, linear, model; +tdpa: with the network (two-port) passivity control; the "
              "contact's local model, instead of the tissue's (viscoelastic, the default): +proxyk "
              "the proxy's spring, +fitk one slope fitted to the force over the depth; +tangent: a "
              "grasp rendered to first order in the twist (the exact grasp model off); +fade "
              "(after the others but +nosurf): every model faded 20 ms into a silence, none held "
              "(model_hold_s 0); "
              "+chbN (before +fade): with a deadband, a heartbeat of N ms while a force is "
              "rendered; +nosurf (last): without the tissue's surface at the station (the "
              "surface ahead from the answers alone)",
              false, "server,linear,model")
      .Option("grip", cli::ArgParser::Kind::kString, "relaxed or tensed", false, "tensed")
      .Option("trainee", cli::ArgParser::Kind::kString,
              "good, hesitant or rough; tap: a quick palpation from 6 cm above (press scenes)",
              false, "good")
      .Option("deadbands", cli::ArgParser::Kind::kString,
              "comma-separated Weber fractions to run each method at (0: every cycle)", false, "0")
      .Option("runs", cli::ArgParser::Kind::kInt, "runs per cell (seeds 1..N)", false, "1")
      .Option("out", cli::ArgParser::Kind::kString, "output folder", false, "wan-out");
  if (auto rc = cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  const auto grip = client::GripByName(p.String("grip"));
  if (!grip.ok()) return cli::UsageError(std::cerr, p.command(), grip.error());
  const bool tap = p.String("trainee") == "tap";
  const auto style = sim::ParseTraineeStyle(tap ? "good" : p.String("trainee"));
  if (!style.ok()) return cli::UsageError(std::cerr, p.command(), style.error());
  std::vector<relay::Profile> profiles;
  for (const auto& name : p.List("profiles")) {
    auto pr = relay::ProfileByName(name);
    if (!pr.ok()) return cli::UsageError(std::cerr, p.command(), pr.error());
    profiles.push_back(*pr);
  }
  const auto parsed = ParseMethods(p.String("methods"), p.String("deadbands"));
  if (!parsed.ok()) return cli::UsageError(std::cerr, p.command(), parsed.error());
  const std::vector<Method>& methods = *parsed;
  const int runs = p.Int("runs");
  if (runs < 1 || runs > 20) return std::cerr << "vsurg-bench wan: --runs: 1..20\n", 2;
  const fs::path out = p.String("out");
  fs::create_directories(out / "traces");
  std::ofstream csv(out / "wan.csv");
  csv << "scene,profile,method,run,rtt_ms,rms_error_pct,onset_delay_ms,onset_extra_mm,"
         "stiffness_pct,energy_to_hand_mj,energy_excess_mj,oscillation_n,peak_force_n,phantom_n,"
         "up_hz,down_hz,score,server_peak_n,lost,stale,late,watchdog_fades,pops,reference_pops,"
         "pop_delay_ms\n";
  const relay::Profile none = *relay::ProfileByName("none");
  std::map<std::string, std::vector<std::string>> trace_files;  // scene/method → files
  for (const auto& scene_name : p.List("scenes")) {
    auto scene = wan::GridScene(scene_name);
    if (!scene.ok()) return cli::UsageError(std::cerr, p.command(), scene.error());
    const bool palpate = scene->task.kind == scoring::TaskKind::kPalpate;
    auto plan = GridPlan(*scene, tap, *style);
    if (!plan.ok()) return cli::UsageError(std::cerr, p.command(), plan.error());
    const bool press = scene->task.kind == scoring::TaskKind::kPress || palpate;
    for (const Method& method_entry : methods) {
      const std::string& method_name = method_entry.name;
      for (int r = 1; r <= runs; ++r) {
        wan::RunOptions o = CellOptions(*scene, *plan, method_entry, *grip, r);
        // The reference: the same rendering at full rate through the relay, unimpaired, with the
        // one-port passivity control (so what the network control costs shows as error).
        wan::RunOptions ref_options = o;
        ref_options.profile = none;
        ref_options.deadband = 0;
        ref_options.passivity_mode = client::PassivityMode::kLocal;
        auto ref = wan::RunOnce(ref_options);
        if (!ref.ok()) return std::cerr << "vsurg-bench wan: " << ref.error().message << "\n", 1;
        for (const relay::Profile& profile : profiles) {
          o.profile = profile;
          auto run = wan::RunOnce(o);
          if (!run.ok()) return std::cerr << "vsurg-bench wan: " << run.error().message << "\n", 1;
          const wan::Figures f = wan::Compare(*run, *ref, press);
          const std::string line = CsvRow(scene_name, profile.name, method_name, r, *run, f);
          csv << line << "\n" << std::flush;
          std::cout << line << "\n" << std::flush;
          if (r == 1) {
            const std::string file =
                "traces/" + scene_name + "_" + profile.name + "_" + method_name + ".csv";
            WriteTrace(out / file, *run);
            trace_files[scene_name + "_" + method_name].push_back(file + "|" + profile.name);
          }
        }
        if (r == 1) {
          const std::string file = "traces/" + scene_name + "_none_" + method_name + ".csv";
          WriteTrace(out / file, *ref);
          trace_files[scene_name + "_" + method_name].insert(
              trace_files[scene_name + "_" + method_name].begin(), file + "|no delay");
        }
      }
    }
  }
  PlotFigures(out, trace_files, methods);
  std::cerr << "vsurg-bench wan: " << (out / "wan.csv").string() << "\n";
  return 0;
}

}  // namespace vsurg::bench
