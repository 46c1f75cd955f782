// vsurg-relay: the user-space network impairment relay (bench/relay/relay.h) as a command.
//
//   vsurg-relay --server 127.0.0.1:50052 --listen 127.0.0.1:50062 --profile regional --seed 7
//
// Stations send to --listen; start the server with --public-host/--public-port naming it so
// that the server hands its stations the relay's address. Runs until SIGINT/SIGTERM or
// --duration, then prints what it did per direction (JSON, also to --stats-file).
// Exit codes: 0 done, 1 runtime error, 2 usage.
#include <signal.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <iostream>
#include <thread>

#include <nlohmann/json.hpp>

#include "bench/relay/relay.h"
#include "common/core/args.h"

namespace {

using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;

std::atomic<bool> g_stop{false};
void OnSignal(int) {
  g_stop = true;
}

bool SplitHostPort(const std::string& text, std::string& host, uint16_t& port) {
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0) return false;
  host = text.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  try {
    size_t used = 0;
    const int p = std::stoi(text.substr(colon + 1), &used);
    if (used != text.size() - colon - 1 || p < 0 || p > 65535) return false;
    port = static_cast<uint16_t>(p);
  } catch (...) {
    return false;
  }
  return true;
}

nlohmann::json Json(const vsurg::relay::DirectionStats& d) {
  return {{"received", d.received},     {"forwarded", d.forwarded},
          {"duplicated", d.duplicated}, {"lost_random", d.lost_random},
          {"lost_burst", d.lost_burst}, {"lost_outage", d.lost_outage},
          {"reordered", d.reordered},   {"mean_delay_ms", d.mean_delay_ms}};
}

}  // namespace

int main(int argc, char** argv) {
  ArgParser p("vsurg-relay", "a UDP relay that delays, jitters, reorders and loses datagrams");
  std::string profiles;
  for (const auto& pr : vsurg::relay::Profiles())
    profiles += "\n      " + pr.name + ": " + pr.summary;
  p.Option("server", Kind::kString, "the server's UDP endpoint host:port", true)
      .Option("listen", Kind::kString, "where stations send, host:port (port 0: any)", false,
              "127.0.0.1:0")
      .Option("profile", Kind::kString, "a named profile:" + profiles, false, "none")
      .Option("seed", Kind::kInt, "the impairments' seed (same seed, same fates)", false, "1")
      .Option("delay-ms", Kind::kDouble, "override: one-way delay, both directions")
      .Option("jitter-ms", Kind::kDouble, "override: σ of the delay, both directions")
      .Option("loss", Kind::kDouble, "override: mean loss rate 0..1, both directions")
      .Option("burst", Kind::kDouble, "with --loss: mean burst length, ms (datagrams at 1 kHz)",
              false, "1")
      .Option("reorder", Kind::kFlag, "override: jitter may reorder datagrams")
      .Option("duplicate", Kind::kDouble, "override: duplication probability")
      .Option("outage-at", Kind::kDouble, "override: an outage this many s after traffic starts")
      .Option("outage-ms", Kind::kDouble, "with --outage-at: its length", false, "500")
      .Option("duration", Kind::kDouble, "stop after this many seconds (0: at a signal)", false,
              "0")
      .Option("ready-file", Kind::kString, "write {\"port\": P} here once listening")
      .Option("stats-file", Kind::kString, "write the final statistics (JSON) here");
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (auto code = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *code;

  vsurg::relay::RelayOptions o;
  if (!SplitHostPort(p.String("server"), o.server_host, o.server_port) ||
      !SplitHostPort(p.String("listen"), o.listen_host, o.listen_port)) {
    std::cerr << "vsurg-relay: --server/--listen: expected host:port\n";
    return vsurg::cli::kExitUsage;
  }
  auto profile = vsurg::relay::ProfileByName(p.String("profile"));
  if (!profile.ok()) return vsurg::cli::UsageError(std::cerr, "vsurg-relay", profile.error());
  o.profile = *profile;
  o.seed = static_cast<uint64_t>(p.Int("seed"));
  for (auto* d : {&o.profile.up, &o.profile.down}) {
    if (p.Has("delay-ms")) d->base_ms = p.Double("delay-ms");
    if (p.Has("jitter-ms")) d->jitter_ms = p.Double("jitter-ms");
    if (p.Has("loss")) vsurg::relay::BurstLoss(*d, p.Double("loss"), p.Double("burst"));
    if (p.Has("reorder")) d->reorder = true;
    if (p.Has("duplicate")) d->duplicate = p.Double("duplicate");
    if (p.Has("outage-at"))
      d->outage_at_s = p.Double("outage-at"), d->outage_s = p.Double("outage-ms") * 1e-3;
    if (d->base_ms < 0 || d->jitter_ms < 0 || d->duplicate < 0 || d->duplicate > 1 ||
        d->outage_s < 0) {
      std::cerr << "vsurg-relay: delays, jitter, outage and probabilities must be ≥ 0 "
                   "(probabilities ≤ 1)\n";
      return vsurg::cli::kExitUsage;
    }
  }
  auto relay = vsurg::relay::Relay::Start(o);
  if (!relay.ok()) {
    std::cerr << "vsurg-relay: " << relay.error().field << ": " << relay.error().message << "\n";
    return relay.error().code == vsurg::ErrorCode::kInvalidArgument ? vsurg::cli::kExitUsage
                                                                    : vsurg::cli::kExitRuntime;
  }
  signal(SIGINT, OnSignal);
  signal(SIGTERM, OnSignal);
  const uint16_t port = (*relay)->port();
  std::cerr << "vsurg-relay: " << o.listen_host << ":" << port << " -> " << o.server_host << ":"
            << o.server_port << " profile=" << o.profile.name << " (" << o.profile.summary
            << ") seed=" << o.seed << "\n";
  if (p.Has("ready-file")) {
    const std::string path = p.String("ready-file"), tmp = path + ".tmp";
    std::ofstream(tmp) << nlohmann::json{{"port", port}}.dump() << "\n";
    std::rename(tmp.c_str(), path.c_str());
  }
  const double duration = p.Double("duration");
  const auto start = std::chrono::steady_clock::now();
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (duration > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > duration)
      break;
  }
  (*relay)->Stop();
  const auto s = (*relay)->stats();
  const nlohmann::json out = {{"profile", o.profile.name}, {"seed", o.seed},
                              {"flows", s.flows},          {"refused_flows", s.refused_flows},
                              {"up", Json(s.up)},          {"down", Json(s.down)}};
  std::cout << out.dump() << "\n";
  if (p.Has("stats-file")) std::ofstream(p.String("stats-file")) << out.dump(2) << "\n";
  return 0;
}
