// vsurg-server: the simulation server. By default (--role all) the store, the sessions (one
// Simulation each), the UDP haptic endpoint and the gRPC control plane, in one process. A site of
// several machines runs the same binary in two more roles over a shared PostgreSQL store
// (DESIGN.md "Beyond one machine", server/cluster/cluster.h, docs/SCALING.md):
//   --role control   the gRPC and HTTP control plane, placement, the nodes' registry; stateless
//   --role sim       a simulation node: sessions and the UDP endpoint, heartbeats to control
//
//   vsurg-server [serve] --db FILE|URI [options]   serve (the default)
//   vsurg-server init|export|backup --db FILE|URI  work on the store (server/store_commands.h)
//
// Shutdown: SIGINT or SIGTERM → the control plane stops taking calls (streams are cancelled),
// live sessions are aborted with their trial metrics recorded, the endpoint stops, the store's
// writer drains its queue and closes the file. Exit code 0. A sim node drains first on SIGTERM:
// no new sessions, the live ones move to other nodes (live migration; those no node takes, and
// all with --drain-wait, finish here, up to --drain-timeout), then the same.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "common/core/log.h"
#include "db/store.h"
#include "server/cluster/cluster.h"
#include "server/config.h"
#include "server/control/control_plane.h"
#include "server/http/http_server.h"
#include "server/net/udp_endpoint.h"
#include "server/ops/collectors.h"
#include "server/ops/metrics.h"
#include "server/ops/session_metrics.h"
#include "server/server_options.h"
#include "server/session/session_manager.h"
#include "server/store_commands.h"

namespace {

using vsurg::Status;
using vsurg::cli::ArgParser;
using vsurg::server::ServerSettings;

void Log(const std::string& event, const vsurg::LogFields& fields = {}) {
  vsurg::LogEvent("vsurg-server", event, fields);
}

// The dashboard's counters as Prometheus families.
void CollectHttp(const vsurg::server::HttpCounters& c, vsurg::server::ops::MetricsText& m) {
  m.Family("vsurg_http_requests_total", "counter", "Requests the dashboard answered.");
  m.Sample("vsurg_http_requests_total", {}, static_cast<double>(c.requests));
  m.Family("vsurg_http_bad_requests_total", "counter",
           "Requests refused as malformed, too large, too slow, ambiguous or for another host.");
  m.Sample("vsurg_http_bad_requests_total", {}, static_cast<double>(c.bad_requests));
  m.Family("vsurg_http_refused_connections_total", "counter", "Connections over the limits.");
  m.Sample("vsurg_http_refused_connections_total", {}, static_cast<double>(c.refused_connections));
  m.Family("vsurg_http_open_connections", "gauge", "Open dashboard connections.");
  m.Sample("vsurg_http_open_connections", {}, c.open_connections);
  m.Family("vsurg_http_open_streams", "gauge", "Open event streams and exports.");
  m.Sample("vsurg_http_open_streams", {}, c.open_streams);
}

// Exit codes: 2 for what the command line asked wrong, 1 for what failed at run time.
int Fail(const std::string& option, const std::string& message, int code) {
  std::cerr << "vsurg-server: " << (option.empty() ? "" : "--" + option + ": ") << message << "\n";
  return code;
}
int Fail(const vsurg::Error& e, const std::string& option_if_none, int code) {
  std::string flag = e.field.empty() ? option_if_none : e.field;  // the option, as typed
  if (flag.starts_with("--")) flag.erase(0, 2);  // the parser's own fields say it already
  std::replace(flag.begin(), flag.end(), '_', '-');
  return Fail(flag, e.message, code);
}

// The command line (and --config) as settings, or the exit code to stop with (after --help, or
// one line naming the option that is wrong).
std::variant<ServerSettings, int> ReadCommandLine(std::vector<std::string> args) {
  ArgParser p("vsurg-server",
              "The vsurg simulation server: sessions and their tissue physics, the UDP haptic\n"
              "channel, the gRPC control plane (sessions, monitoring, evaluations, admin) and the\n"
              "store. Stops cleanly on SIGINT/SIGTERM. --role control|sim: one site over several\n"
              "machines on a shared PostgreSQL store (docs/SCALING.md).\n\n"
              "Commands on the store file: vsurg-server init|export|backup --db FILE ...\n"
              "(init creates the first administrator; export and backup open the file read-only).");
  vsurg::server::DeclareServerOptions(p);
  if (Status s = p.Parse(args); !s.ok()) return Fail(s.error(), "", 2);
  if (p.HelpRequested()) {
    std::cout << p.Help();
    return 0;
  }
  if (p.Has("config")) {
    std::string error;
    if (!vsurg::server::MergeConfig(p.String("config"), args, error)) return Fail("", error, 2);
    if (Status s = p.Parse(args); !s.ok()) return Fail(s.error(), "", 2);
  }
  if (vsurg::LogFormat format; vsurg::ParseLogFormat(p.String("log-format"), &format))
    vsurg::SetLogFormat(format);
  else
    return Fail("log-format", "must be logfmt or json", 2);
  auto settings = vsurg::server::ReadServerSettings(p);
  if (!settings.ok()) return Fail(settings.error(), "", 2);
  return std::move(settings).value();
}

// The process's parts, made in order by the stages below and stopped in reverse by Stop.
struct Server {
  ServerSettings s;
  std::unique_ptr<vsurg::db::Store> store;
  // Before the parts: the collectors read them; only the dashboard renders them, and it is shut
  // down before any of them.
  vsurg::server::ops::MetricsRegistry metrics;
  std::unique_ptr<vsurg::server::UdpEndpoint> endpoint;
  std::unique_ptr<vsurg::server::SessionManager> manager;
  std::unique_ptr<vsurg::server::cluster::ClusterSessions> placed;
  std::unique_ptr<vsurg::server::cluster::NodeAgent> agent;
  vsurg::server::Sessions* sessions = nullptr;
  vsurg::server::Lease lease;  // a node's (its agent renews it); unused by the all-in-one server
  std::unique_ptr<vsurg::server::ControlPlane> control;
  std::unique_ptr<vsurg::server::HttpServer> web;
  std::unique_ptr<vsurg::server::ops::SessionMetrics> session_metrics;

  bool sim() const { return s.role == "sim"; }

  // This process runs sessions: the UDP endpoint, the manager, and on a node its agent.
  std::optional<int> StartSessions() {
    if (sim()) s.endpoint.lease = &lease;
    auto created = vsurg::server::UdpEndpoint::Create(s.endpoint);
    if (!created.ok()) return Fail("udp-port", created.error().message, 1);
    endpoint = std::move(created).value();
    if (sim()) s.sessions.lease = &lease;
    auto opened = vsurg::server::SessionManager::Open(*store, endpoint.get(), s.sessions);
    if (!opened.ok())
      return Fail(opened.error(), "",
                  opened.error().code == vsurg::ErrorCode::kInvalidArgument ? 2 : 1);
    manager = std::move(opened).value();
    sessions = manager.get();
    if (!sim()) return std::nullopt;
    s.node.cluster = s.cluster;
    s.node.lease = &lease;
    if (s.node.udp_port == 0) s.node.udp_port = endpoint->port();
    auto started = vsurg::server::cluster::NodeAgent::Start(*manager, s.node);
    if (!started.ok()) return Fail(started.error(), "", 1);
    agent = std::move(started).value();
    return std::nullopt;
  }

  // The control role: the sessions are the site's nodes'.
  std::optional<int> StartPlacement() {
    auto started = vsurg::server::cluster::ClusterSessions::Start(*store, s.cluster);
    if (!started.ok()) return Fail(started.error(), "", 1);
    placed = std::move(started).value();
    sessions = placed.get();
    return std::nullopt;
  }

  // gRPC for stations, monitors and tools (not on a node: it serves only the internal API).
  std::optional<int> StartControl() {
    if (sim()) return std::nullopt;
    auto started = vsurg::server::ControlPlane::Start(*store, *sessions, s.control);
    if (!started.ok()) return Fail(started.error(), "listen", 1);
    control = std::move(started).value();
    return std::nullopt;
  }

  // The dashboard with the Prometheus scrape (on a node only the scrape), on every role.
  std::optional<int> StartDashboard() {
    if (!s.http) return std::nullopt;
    namespace ops = vsurg::server::ops;
    session_metrics = std::make_unique<ops::SessionMetrics>(*sessions);
    metrics.Add([this](ops::MetricsText& m) { session_metrics->Collect(m); });
    if (endpoint)
      metrics.Add([this](ops::MetricsText& m) { ops::CollectEndpoint(endpoint->counters(), m); });
    metrics.Add([this](ops::MetricsText& m) { ops::CollectStore(store->stats(), m); });
    if (placed) metrics.Add([this](ops::MetricsText& m) { placed->Collect(m); });
    if (agent) metrics.Add([this](ops::MetricsText& m) { agent->Collect(m); });
    metrics.Add([this](ops::MetricsText& m) {
      if (web) CollectHttp(web->counters(), m);
    });
    s.web.metrics = &metrics;
    auto started = vsurg::server::HttpServer::Start(*store, *sessions, s.web);
    if (!started.ok()) return Fail("http", started.error().message, 1);
    web = std::move(started).value();
    return std::nullopt;
  }

  // The "serving" log line, and the ready file (written whole or not at all).
  void Announce() const {
    const int grpc_port = control ? control->port() : 0;
    const int udp_port = endpoint ? endpoint->port() : 0;
    const int http_port = web ? web->port() : 0;
    const int cluster_port = placed ? placed->port() : agent ? agent->port() : 0;
    vsurg::LogFields serving{{"role", s.role}, {"grpc_port", grpc_port}, {"udp_port", udp_port}};
    if (web) serving.emplace_back("http_port", http_port);
    if (cluster_port) {
      serving.emplace_back("cluster_port", cluster_port);
      serving.emplace_back("cluster_tls", s.cluster.tls() ? "mutual" : "off");
    }
    serving.emplace_back("tls", control && control->tls() ? "on" : "off");
    serving.emplace_back("db", vsurg::db::BackendName(vsurg::db::BackendOf(s.db)));
    Log("serving", serving);
    if (s.ready_file.empty()) return;
    const std::string tmp = s.ready_file + ".tmp";
    {
      std::ofstream out(tmp);
      nlohmann::json ready{
          {"grpc_port", grpc_port}, {"udp_port", udp_port}, {"pid", getpid()}, {"role", s.role}};
      if (web) ready["http_port"] = http_port;
      if (cluster_port) ready["cluster_port"] = cluster_port;
      out << ready.dump() << "\n";
    }
    std::rename(tmp.c_str(), s.ready_file.c_str());
  }

  // After SIGINT or SIGTERM. A node's rolling upgrade: SIGTERM lets its live sessions move or
  // finish (Kubernetes sends it and waits terminationGracePeriodSeconds); SIGINT (an
  // operator's ^C) does not wait.
  void Stop(int sig) {
    if (agent && sig == SIGTERM) agent->Drain(s.drain_timeout_s);
    if (web) web->Shutdown();  // ends the dashboard's streams and exports
    if (control) control->Shutdown();
    if (agent) agent->Shutdown();
    sessions->Shutdown();
    if (endpoint) endpoint->Stop();
    const auto stats = store->stats();
    web.reset();
    session_metrics.reset();  // unsubscribes: before the sessions go
    control.reset();
    agent.reset();
    manager.reset();
    placed.reset();
    endpoint.reset();
    store.reset();  // drains the writer
    Log("stopped", {{"commits", stats.commits}, {"jobs", stats.jobs}});
  }
};

int Main(std::vector<std::string> args) {
  auto read = ReadCommandLine(std::move(args));
  if (const int* code = std::get_if<int>(&read)) return *code;
  // Signals go to the main thread only: block them before any thread starts, sigwait below.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  Server server;
  server.s = std::move(std::get<ServerSettings>(read));
  auto store = vsurg::db::Store::Open({.path = server.s.db});
  if (!store.ok()) return Fail("db", store.error().message, 1);
  server.store = std::move(store).value();
  std::optional<int> failed =
      server.s.role == "control" ? server.StartPlacement() : server.StartSessions();
  if (!failed) failed = server.StartControl();
  if (!failed) failed = server.StartDashboard();
  if (failed) return *failed;
  server.Announce();
  int sig = 0;
  sigwait(&signals, &sig);
  Log("stopping", {{"signal", sig == SIGINT ? "SIGINT" : "SIGTERM"}});
  server.Stop(sig);
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
