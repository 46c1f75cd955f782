// vsurg-server: the simulation server. The SQLite store, the sessions (one Simulation each),
// the UDP haptic endpoint and the gRPC control plane, in one process.
//
//   vsurg-server [serve] --db FILE [options]   serve (the default)
//   vsurg-server init|export|backup --db FILE  work on the store file (server/store_commands.h)
//
// Shutdown: SIGINT or SIGTERM → the control plane stops taking calls (streams are cancelled),
// live sessions are aborted with their trial metrics recorded, the endpoint stops, the store's
// writer drains its queue and closes the file. Exit code 0.
#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "db/store.h"
#include "server/config.h"
#include "server/control/control_plane.h"
#include "server/http/http_server.h"
#include "server/net/udp_endpoint.h"
#include "server/session/session_manager.h"
#include "server/store_commands.h"

namespace {

using vsurg::Status;
using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;

void Log(const std::string& event, const std::string& fields = "") {
  std::cerr << "ts=" << vsurg::db::IsoTimeUtc(vsurg::db::NowUs()) << " component=vsurg-server"
            << " event=" << event << (fields.empty() ? "" : " ") << fields << std::endl;
}

int Main(std::vector<std::string> args) {
  ArgParser p("vsurg-server",
              "The vsurg simulation server: sessions and their tissue physics, the UDP haptic\n"
              "channel, the gRPC control plane (sessions, monitoring, evaluations, admin) and the\n"
              "SQLite store. Stops cleanly on SIGINT/SIGTERM.\n\n"
              "Commands on the store file: vsurg-server init|export|backup --db FILE ...\n"
              "(init creates the first administrator; export and backup open the file read-only).");
  p.Option("db", Kind::kString, "SQLite database file (created when missing)", true)
      .Option("listen", Kind::kString, "gRPC address host:port", false, "127.0.0.1:50051")
      .Option("udp-address", Kind::kString, "UDP haptic endpoint address", false, "127.0.0.1")
      .Option("udp-port", Kind::kInt, "UDP port (0: any free one)", false, "50052")
      .Option("public-host", Kind::kString,
              "host stations are told to send to (default: udp-address)")
      .Option("tls-cert", Kind::kString, "PEM certificate for gRPC TLS")
      .Option("tls-key", Kind::kString, "PEM private key for gRPC TLS")
      .Option("allow-insecure", Kind::kFlag,
              "allow plaintext gRPC and HTTP off loopback (not advised)")
      .Option("http", Kind::kString,
              "web dashboard address host:port (off unless given; port 0: any free one); HTTPS "
              "with the gRPC certificate when TLS is configured")
      .Option("telemetry-hz", Kind::kDouble, "monitor telemetry rate", false, "30")
      .Option("realtime-priority", Kind::kInt,
              "SCHED_FIFO priority of the UDP haptic thread when permitted (0: off)", false, "20")
      .Option("max-sessions", Kind::kInt, "live sessions on this server", false, "256")
      .Option("max-sessions-per-user", Kind::kInt, "live sessions per trainee", false, "2")
      .Option("start-timeout", Kind::kDouble,
              "seconds a created session may wait for Start before it is aborted", false, "60")
      .Option("backup-dir", Kind::kString,
              "the only folder AdminService/Backup writes to (default: backups/ beside --db)")
      .Option("ready-file", Kind::kString,
              "write {grpc_port, udp_port, http_port} here once serving")
      .Option("config", Kind::kString, "JSON file of these options (flags win)");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << "vsurg-server: " << (s.error().field.empty() ? "" : s.error().field + ": ")
              << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) {
    std::cout << p.Help();
    return 0;
  }
  if (p.Has("config")) {
    std::string error;
    if (!vsurg::server::MergeConfig(p.String("config"), args, error)) {
      std::cerr << "vsurg-server: " << error << "\n";
      return 2;
    }
    if (Status s = p.Parse(args); !s.ok()) {
      std::cerr << "vsurg-server: " << s.error().field << ": " << s.error().message << "\n";
      return 2;
    }
  }
  const int udp_port = p.Int("udp-port");
  const double telemetry_hz = p.Double("telemetry-hz");
  if (udp_port < 0 || udp_port > 65535) {
    std::cerr << "vsurg-server: --udp-port: must be within 0..65535\n";
    return 2;
  }
  if (!(telemetry_hz >= 1 && telemetry_hz <= 120)) {
    std::cerr << "vsurg-server: --telemetry-hz: must be within 1..120\n";
    return 2;
  }
  const int max_sessions = p.Int("max-sessions"), per_user = p.Int("max-sessions-per-user");
  const double start_timeout = p.Double("start-timeout");
  if (max_sessions < 1 || max_sessions > 4096) {
    std::cerr << "vsurg-server: --max-sessions: must be within 1..4096\n";
    return 2;
  }
  if (per_user < 1 || per_user > max_sessions) {
    std::cerr << "vsurg-server: --max-sessions-per-user: must be within 1..--max-sessions\n";
    return 2;
  }
  if (!(start_timeout >= 0.1 && start_timeout <= 3600)) {
    std::cerr << "vsurg-server: --start-timeout: must be within 0.1..3600 s\n";
    return 2;
  }

  // Signals go to the main thread only: block them before any thread starts, sigwait below.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto store = vsurg::db::Store::Open({.path = p.String("db")});
  if (!store.ok()) {
    std::cerr << "vsurg-server: --db: " << store.error().message << "\n";
    return 1;
  }
  vsurg::server::EndpointOptions eo;
  eo.address = p.String("udp-address");
  eo.port = static_cast<uint16_t>(udp_port);
  eo.realtime_priority = p.Int("realtime-priority");
  if (eo.realtime_priority < 0 || eo.realtime_priority > 99) {
    std::cerr << "vsurg-server: --realtime-priority: must be within 0..99\n";
    return 2;
  }
  auto endpoint = vsurg::server::UdpEndpoint::Create(eo);
  if (!endpoint.ok()) {
    std::cerr << "vsurg-server: --udp-port: " << endpoint.error().message << "\n";
    return 1;
  }
  vsurg::server::SessionManagerOptions so;
  so.udp_host = p.Has("public-host") ? p.String("public-host") : eo.address;
  so.telemetry_hz = telemetry_hz;
  so.max_live_sessions = max_sessions;
  so.max_sessions_per_user = per_user;
  so.start_timeout_s = start_timeout;
  auto sessions = std::make_unique<vsurg::server::SessionManager>(**store, endpoint->get(), so);
  vsurg::server::ControlPlaneOptions co;
  co.listen = p.String("listen");
  if (p.Has("tls-cert")) co.tls_cert_file = p.String("tls-cert");
  if (p.Has("tls-key")) co.tls_key_file = p.String("tls-key");
  co.allow_insecure = p.Flag("allow-insecure");
  co.backup_dir =
      p.Has("backup-dir")
          ? p.String("backup-dir")
          : (std::filesystem::absolute(p.String("db")).parent_path() / "backups").string();
  auto control = vsurg::server::ControlPlane::Start(**store, *sessions, co);
  if (!control.ok()) {
    std::cerr << "vsurg-server: --"
              << (control.error().field.empty() ? "listen" : control.error().field) << ": "
              << control.error().message << "\n";
    return 1;
  }
  std::unique_ptr<vsurg::server::HttpServer> web;
  if (p.Has("http")) {
    vsurg::server::HttpServerOptions ho;
    ho.listen = p.String("http");
    ho.tls_cert_file = co.tls_cert_file;
    ho.tls_key_file = co.tls_key_file;
    ho.allow_insecure = co.allow_insecure;
    ho.backup_dir = co.backup_dir;
    auto started = vsurg::server::HttpServer::Start(**store, *sessions, ho);
    if (!started.ok()) {
      std::cerr << "vsurg-server: --http: " << started.error().message << "\n";
      return 1;
    }
    web = std::move(started).value();
  }
  const int grpc_port = (*control)->port();
  const int bound_udp = (*endpoint)->port();
  const int http_port = web ? web->port() : 0;
  Log("serving", "grpc_port=" + std::to_string(grpc_port) +
                     " udp_port=" + std::to_string(bound_udp) +
                     (web ? " http_port=" + std::to_string(http_port) : std::string()) +
                     " tls=" + ((*control)->tls() ? "on" : "off") + " db=" + p.String("db"));
  if (p.Has("ready-file")) {
    const std::string path = p.String("ready-file"), tmp = path + ".tmp";
    {
      std::ofstream out(tmp);
      nlohmann::json ready{{"grpc_port", grpc_port}, {"udp_port", bound_udp}, {"pid", getpid()}};
      if (web) ready["http_port"] = http_port;
      out << ready.dump() << "\n";
    }
    std::rename(tmp.c_str(), path.c_str());  // atomically: a reader sees all of it or nothing
  }

  int sig = 0;
  sigwait(&signals, &sig);
  Log("stopping", std::string("signal=") + (sig == SIGINT ? "SIGINT" : "SIGTERM"));
  if (web) web->Shutdown();  // ends the dashboard's streams and exports
  (*control)->Shutdown();
  sessions->Shutdown();
  (*endpoint)->Stop();
  const auto stats = (*store)->stats();
  web.reset();
  control->reset();
  sessions.reset();
  endpoint->reset();
  store->reset();  // drains the writer
  Log("stopped",
      "commits=" + std::to_string(stats.commits) + " jobs=" + std::to_string(stats.jobs));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::vector<std::string> args(argv + 1, argv + argc);
    if (!args.empty() && vsurg::server::IsStoreCommand(args[0]))
      return vsurg::server::RunStoreCommand(
          args[0], std::vector<std::string>(args.begin() + 1, args.end()), std::cout, std::cerr);
    if (!args.empty() && args[0] == "serve") args.erase(args.begin());
    return Main(std::move(args));
  } catch (const std::exception& e) {
    std::cerr << "vsurg-server: fatal: " << e.what() << "\n";
    return 1;
  }
}
