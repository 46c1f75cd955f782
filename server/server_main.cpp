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
#include <set>
#include <sstream>
#include <string>
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
#include "server/session/session_manager.h"
#include "server/store_commands.h"

namespace {

using vsurg::Status;
using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;

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

int Main(std::vector<std::string> args) {
  ArgParser p("vsurg-server",
              "The vsurg simulation server: sessions and their tissue physics, the UDP haptic\n"
              "channel, the gRPC control plane (sessions, monitoring, evaluations, admin) and the\n"
              "store. Stops cleanly on SIGINT/SIGTERM. --role control|sim: one site over several\n"
              "machines on a shared PostgreSQL store (docs/SCALING.md).\n\n"
              "Commands on the store file: vsurg-server init|export|backup --db FILE ...\n"
              "(init creates the first administrator; export and backup open the file read-only).");
  p.Option("db", Kind::kString,
           "SQLite database file (created when missing), or a postgresql:// URI (the shared "
           "store of control and sim roles)",
           true)
      .Option("role", Kind::kString,
              "all (one process), control (control plane of a site) or sim (simulation node)",
              false, "all")
      .Option("cluster-listen", Kind::kString,
              "control, sim: the internal API's host:port (port 0: any free one)", false,
              "127.0.0.1:0")
      .Option("cluster-token-file", Kind::kString,
              "control, sim: file holding the site's shared secret (>= 16 characters)")
      .Option("cluster-tls-cert", Kind::kString,
              "control, sim: this process's PEM certificate for mutual TLS on the internal API "
              "(a node's names the node, a control replica's names --cluster-control-name)")
      .Option("cluster-tls-key", Kind::kString, "control, sim: its PEM private key")
      .Option("cluster-tls-ca", Kind::kString,
              "control, sim: the site's PEM CA bundle; peers' certificates must chain to it")
      .Option("cluster-tls-refresh", Kind::kDouble,
              "control, sim: seconds between reads of the TLS files (renewal without restart)",
              false, "60")
      .Option("cluster-store-lease", Kind::kDouble,
              "control: seconds of lease a node's row in the store carries; the replica a node "
              "beats to keeps its heartbeats in memory and rewrites the row when half of it is "
              "gone (<= 2.5: every heartbeat is written); the same on every replica",
              false, "10")
      .Option("cluster-heartbeat-period", Kind::kDouble,
              "control, sim: seconds between a node's heartbeats; the same on every process", false,
              "0.5")
      .Option("cluster-heartbeat-timeout", Kind::kDouble,
              "control, sim: seconds a node may be silent before the site declares it down and "
              "re-places its sessions (its lease); longer rides out a control plane starved of "
              "CPU, at the cost of a lost node's stations waiting longer; the same on every "
              "process",
              false, "2")
      .Option("cluster-control-name", Kind::kString,
              "control, sim: the name control replicas' certificates carry", false, "vsurg-control")
      .Option("cluster-health-listen", Kind::kString,
              "control, sim: host:port of a plaintext gRPC health check (liveness only, for "
              "probes when the internal API wants a client certificate)")
      .Option("control", Kind::kString,
              "sim: the control plane's internal API, host:port[,host:port...]")
      .Option("node-name", Kind::kString, "sim: this node's name, unique in the site")
      .Option("advertise", Kind::kString,
              "sim: host:port the control plane reaches this node's internal API at "
              "(default: --cluster-listen's host with its bound port)")
      .Option("capacity", Kind::kInt, "sim: live sessions this node takes", false, "24")
      .Option("drain-timeout", Kind::kDouble,
              "sim: on SIGTERM, seconds the live sessions may take to finish", false, "600")
      .Option("drain-wait", Kind::kFlag,
              "sim: on SIGTERM, let the live sessions finish here instead of moving them to "
              "other nodes (live migration, the default)")
      .Option("listen", Kind::kString, "gRPC address host:port", false, "127.0.0.1:50051")
      .Option("udp-address", Kind::kString, "UDP haptic endpoint address", false, "127.0.0.1")
      .Option("udp-port", Kind::kInt, "UDP port (0: any free one)", false, "50052")
      .Option("public-host", Kind::kString,
              "host stations are told to send to (default: udp-address)")
      .Option("public-port", Kind::kInt,
              "UDP port stations are told to send to (default: the endpoint's; a relay or NAT in "
              "front of it listens on another)")
      .Option("tls-cert", Kind::kString, "PEM certificate for gRPC TLS")
      .Option("tls-key", Kind::kString, "PEM private key for gRPC TLS")
      .Option("allow-insecure", Kind::kFlag,
              "allow plaintext gRPC and HTTP off loopback (not advised)")
      .Option("http", Kind::kString,
              "web dashboard address host:port (off unless given; port 0: any free one); HTTPS "
              "with the gRPC certificate when TLS is configured. On a sim node: only the "
              "Prometheus metrics (GET /api/v1/metrics)")
      .Option("http-hosts", Kind::kString,
              "host names the dashboard answers for, comma-separated, besides IP literals and "
              "localhost (any other Host header gets 421: DNS rebinding)")
      .Option("metrics-token-file", Kind::kString,
              "file holding a token (>= 16 characters) that reads GET /api/v1/metrics and "
              "nothing else: Prometheus' (without it, an administrator's token)")
      .Option("log-format", Kind::kString,
              "the event log on stderr: logfmt (key=value lines) or json (one object a line; "
              "every line about a session carries its id as `session`)",
              false, "logfmt")
      .Option("telemetry-hz", Kind::kDouble, "monitor telemetry rate", false, "30")
      .Option("deformation-workers", Kind::kInt,
              "driven sessions deform on a pool of this many threads (0: one per core) instead "
              "of a thread each (-1)",
              false, "-1")
      .Option("quasi-static-interval-ms", Kind::kDouble,
              "a quasi-static model (coil, reduced) updates at most once per this many "
              "milliseconds while a hand grasps it, from the newest request (0: every request; "
              "0..100)",
              false, "8")
      .Option("realtime-priority", Kind::kInt,
              "SCHED_FIFO priority of the UDP haptic thread when permitted (0: off, the normal "
              "priority a container gives)",
              false, "0")
      .Option("io-threads", Kind::kInt,
              "UDP haptic threads, each with a socket on the UDP port (SO_REUSEPORT), sessions "
              "spread over them by id (1..16)",
              false, "1")
      .Option("busy-poll-us", Kind::kInt,
              "microseconds an I/O thread polls its socket before it sleeps, only while its "
              "datagrams come at least once per window (0: never; 0..10000)",
              false, "0")
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
  if (vsurg::LogFormat format; vsurg::ParseLogFormat(p.String("log-format"), &format)) {
    vsurg::SetLogFormat(format);
  } else {
    std::cerr << "vsurg-server: --log-format: must be logfmt or json\n";
    return 2;
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
  if (const double ms = p.Double("quasi-static-interval-ms"); !(ms >= 0 && ms <= 100)) {
    std::cerr << "vsurg-server: --quasi-static-interval-ms: must be within 0..100\n";
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

  const std::string role = p.String("role");
  if (role != "all" && role != "control" && role != "sim") {
    std::cerr << "vsurg-server: --role: must be all, control or sim\n";
    return 2;
  }
  vsurg::server::cluster::ClusterOptions cluster;
  if (role != "all") {
    if (vsurg::db::BackendOf(p.String("db")) != vsurg::db::Backend::kPostgres) {
      std::cerr << "vsurg-server: --db: the " << role
                << " role shares its store with the site: a postgresql:// URI is required\n";
      return 2;
    }
    if (!p.Has("cluster-token-file")) {
      std::cerr << "vsurg-server: --cluster-token-file: required by the " << role << " role\n";
      return 2;
    }
    std::ifstream in(p.String("cluster-token-file"));
    if (!in || !std::getline(in, cluster.token)) {
      std::cerr << "vsurg-server: --cluster-token-file: cannot read "
                << p.String("cluster-token-file") << "\n";
      return 2;
    }
    cluster.listen = p.String("cluster-listen");
    cluster.allow_insecure = p.Flag("allow-insecure");
    if (p.Has("cluster-tls-cert")) cluster.tls_cert = p.String("cluster-tls-cert");
    if (p.Has("cluster-tls-key")) cluster.tls_key = p.String("cluster-tls-key");
    if (p.Has("cluster-tls-ca")) cluster.tls_ca = p.String("cluster-tls-ca");
    cluster.tls_refresh_s = p.Double("cluster-tls-refresh");
    cluster.store_lease_s = p.Double("cluster-store-lease");
    if (!(cluster.store_lease_s >= 2 && cluster.store_lease_s <= 300)) {
      std::cerr << "vsurg-server: --cluster-store-lease: must be within 2..300 s\n";
      return 2;
    }
    cluster.heartbeat_period_s = p.Double("cluster-heartbeat-period");
    cluster.heartbeat_timeout_s = p.Double("cluster-heartbeat-timeout");
    if (!(cluster.heartbeat_period_s >= 0.05 && cluster.heartbeat_period_s <= 10)) {
      std::cerr << "vsurg-server: --cluster-heartbeat-period: must be within 0.05..10 s\n";
      return 2;
    }
    if (!(cluster.heartbeat_timeout_s <= 120 &&
          cluster.heartbeat_timeout_s - cluster.lease_margin_s >= 2 * cluster.heartbeat_period_s)) {
      std::cerr << "vsurg-server: --cluster-heartbeat-timeout: must be at most 120 s and, less "
                << cluster.lease_margin_s << " s of margin, at least two heartbeat periods\n";
      return 2;
    }
    cluster.control_name = p.String("cluster-control-name");
    if (p.Has("cluster-health-listen")) cluster.health_listen = p.String("cluster-health-listen");
    cluster.telemetry_hz = telemetry_hz;
    cluster.max_sessions_per_user = per_user;
  }
  if (role == "sim" && !p.Has("control")) {
    std::cerr << "vsurg-server: --control: required by the sim role\n";
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
  const bool shared_store = vsurg::db::BackendOf(p.String("db")) == vsurg::db::Backend::kPostgres;
  // First: the collectors read the objects below; only the dashboard renders them, and it is
  // shut down before any of them.
  vsurg::server::ops::MetricsRegistry metrics;
  std::unique_ptr<vsurg::server::UdpEndpoint> endpoint;
  std::unique_ptr<vsurg::server::SessionManager> manager;
  std::unique_ptr<vsurg::server::cluster::ClusterSessions> placed;
  std::unique_ptr<vsurg::server::cluster::NodeAgent> agent;
  vsurg::server::Sessions* sessions = nullptr;
  vsurg::server::Lease lease;  // a node's (its agent renews it); unused by the all-in-one server
  if (role != "control") {     // this process runs sessions: the UDP endpoint and the manager
    vsurg::server::EndpointOptions eo;
    eo.address = p.String("udp-address");
    eo.port = static_cast<uint16_t>(udp_port);
    eo.realtime_priority = p.Int("realtime-priority");
    if (eo.realtime_priority < 0 || eo.realtime_priority > 99) {
      std::cerr << "vsurg-server: --realtime-priority: must be within 0..99\n";
      return 2;
    }
    eo.io_threads = static_cast<int>(p.Int("io-threads"));
    if (p.Int("busy-poll-us") < 0 ||
        p.Int("busy-poll-us") > vsurg::server::UdpEndpoint::kMaxBusyPollUs) {
      std::cerr << "vsurg-server: --busy-poll-us: must be within 0.."
                << vsurg::server::UdpEndpoint::kMaxBusyPollUs << "\n";
      return 2;
    }
    eo.busy_poll_us = static_cast<int>(p.Int("busy-poll-us"));
    if (role == "sim") eo.lease = &lease;
    auto created = vsurg::server::UdpEndpoint::Create(eo);
    if (!created.ok()) {
      std::cerr << "vsurg-server: --udp-port: " << created.error().message << "\n";
      return 1;
    }
    endpoint = std::move(created).value();
    vsurg::server::SessionManagerOptions so;
    so.udp_host = p.Has("public-host") ? p.String("public-host") : eo.address;
    if (p.Has("public-port")) {
      const int public_port = p.Int("public-port");
      if (public_port < 1 || public_port > 65535) {
        std::cerr << "vsurg-server: --public-port: must be within 1..65535\n";
        return 2;
      }
      so.udp_port = static_cast<uint16_t>(public_port);
    }
    so.telemetry_hz = telemetry_hz;
    so.max_live_sessions = max_sessions;
    so.max_sessions_per_user = per_user;
    so.start_timeout_s = start_timeout;
    so.deformation_workers = static_cast<int>(p.Int("deformation-workers"));
    so.quasi_static_interval_s = 1e-3 * p.Double("quasi-static-interval-ms");
    if (role == "sim") {
      char host[256] = {};
      gethostname(host, sizeof host - 1);
      so.node = p.Has("node-name") ? p.String("node-name") : std::string(host);
      so.lease = &lease;
    }
    auto opened = vsurg::server::SessionManager::Open(**store, endpoint.get(), so);
    if (!opened.ok()) {
      std::string flag = opened.error().field;  // the option's name, as typed
      std::replace(flag.begin(), flag.end(), '_', '-');
      std::cerr << "vsurg-server: --" << flag << ": " << opened.error().message << "\n";
      return opened.error().code == vsurg::ErrorCode::kInvalidArgument ? 2 : 1;
    }
    manager = std::move(opened).value();
    sessions = manager.get();
    if (role == "sim") {
      vsurg::server::cluster::NodeOptions no;
      no.name = so.node;
      no.advertise = p.Has("advertise") ? p.String("advertise") : "";
      no.control = p.String("control");
      no.udp_host = so.udp_host;
      no.udp_port = so.udp_port ? so.udp_port : endpoint->port();
      no.capacity = p.Int("capacity");
      no.migrate_on_drain = !p.Flag("drain-wait");
      no.cluster = cluster;
      no.lease = &lease;
      auto started = vsurg::server::cluster::NodeAgent::Start(*manager, no);
      if (!started.ok()) {
        std::cerr << "vsurg-server: --" << started.error().field << ": " << started.error().message
                  << "\n";
        return 1;
      }
      agent = std::move(started).value();
    }
  } else {  // control: the sessions are the site's nodes'
    auto started = vsurg::server::cluster::ClusterSessions::Start(**store, cluster);
    if (!started.ok()) {
      std::cerr << "vsurg-server: --" << started.error().field << ": " << started.error().message
                << "\n";
      return 1;
    }
    placed = std::move(started).value();
    sessions = placed.get();
  }
  std::unique_ptr<vsurg::server::ControlPlane> control;
  std::unique_ptr<vsurg::server::HttpServer> web;
  std::unique_ptr<vsurg::server::ops::SessionMetrics> session_metrics;
  vsurg::server::ControlPlaneOptions co;
  co.listen = p.String("listen");
  if (p.Has("tls-cert")) co.tls_cert_file = p.String("tls-cert");
  if (p.Has("tls-key")) co.tls_key_file = p.String("tls-key");
  co.allow_insecure = p.Flag("allow-insecure");
  // A shared store is backed up by PostgreSQL's own tools: no backup folder, backups refused.
  co.backup_dir =
      p.Has("backup-dir") ? p.String("backup-dir")
      : shared_store
          ? std::string()
          : (std::filesystem::absolute(p.String("db")).parent_path() / "backups").string();
  if (role != "sim") {  // a simulation node serves the internal API (and --http: its metrics)
    auto started = vsurg::server::ControlPlane::Start(**store, *sessions, co);
    if (!started.ok()) {
      std::cerr << "vsurg-server: --"
                << (started.error().field.empty() ? "listen" : started.error().field) << ": "
                << started.error().message << "\n";
      return 1;
    }
    control = std::move(started).value();
  }
  if (p.Has("http")) {  // the dashboard; on a simulation node only its metrics
    vsurg::server::HttpServerOptions ho;
    ho.listen = p.String("http");
    ho.tls_cert_file = co.tls_cert_file;
    ho.tls_key_file = co.tls_key_file;
    ho.allow_insecure = co.allow_insecure;
    ho.backup_dir = co.backup_dir;
    ho.metrics_only = role == "sim";
    if (p.Has("metrics-token-file")) {
      std::ifstream in(p.String("metrics-token-file"));
      if (!in || !std::getline(in, ho.metrics_token) || ho.metrics_token.size() < 16) {
        std::cerr << "vsurg-server: --metrics-token-file: cannot read a token of at least 16 "
                     "characters from "
                  << p.String("metrics-token-file") << "\n";
        return 2;
      }
    }
    if (p.Has("http-hosts")) {
      const std::string list = p.String("http-hosts");
      for (size_t at = 0; at <= list.size();) {
        const size_t comma = std::min(list.find(',', at), list.size());
        if (comma > at) ho.hosts.push_back(list.substr(at, comma - at));
        at = comma + 1;
      }
    }
    // The Prometheus scrape (GET /api/v1/metrics, an administrator's token), on every role.
    namespace ops = vsurg::server::ops;
    session_metrics = std::make_unique<ops::SessionMetrics>(*sessions);
    metrics.Add([&](ops::MetricsText& m) { session_metrics->Collect(m); });
    if (endpoint)
      metrics.Add([&](ops::MetricsText& m) { ops::CollectEndpoint(endpoint->counters(), m); });
    metrics.Add([&](ops::MetricsText& m) { ops::CollectStore((*store)->stats(), m); });
    if (placed) metrics.Add([&](ops::MetricsText& m) { placed->Collect(m); });
    if (agent) metrics.Add([&](ops::MetricsText& m) { agent->Collect(m); });
    metrics.Add([&](ops::MetricsText& m) {
      if (web) CollectHttp(web->counters(), m);
    });
    ho.metrics = &metrics;
    auto web_started = vsurg::server::HttpServer::Start(**store, *sessions, ho);
    if (!web_started.ok()) {
      std::cerr << "vsurg-server: --http: " << web_started.error().message << "\n";
      return 1;
    }
    web = std::move(web_started).value();
  }
  const int grpc_port = control ? control->port() : 0;
  const int bound_udp = endpoint ? endpoint->port() : 0;
  const int http_port = web ? web->port() : 0;
  const int cluster_port = placed ? placed->port() : agent ? agent->port() : 0;
  vsurg::LogFields serving{{"role", role}, {"grpc_port", grpc_port}, {"udp_port", bound_udp}};
  if (web) serving.emplace_back("http_port", http_port);
  if (cluster_port) {
    serving.emplace_back("cluster_port", cluster_port);
    serving.emplace_back("cluster_tls", cluster.tls() ? "mutual" : "off");
  }
  serving.emplace_back("tls", control && control->tls() ? "on" : "off");
  serving.emplace_back("db", vsurg::db::BackendName(vsurg::db::BackendOf(p.String("db"))));
  Log("serving", serving);
  if (p.Has("ready-file")) {
    const std::string path = p.String("ready-file"), tmp = path + ".tmp";
    {
      std::ofstream out(tmp);
      nlohmann::json ready{
          {"grpc_port", grpc_port}, {"udp_port", bound_udp}, {"pid", getpid()}, {"role", role}};
      if (web) ready["http_port"] = http_port;
      if (cluster_port) ready["cluster_port"] = cluster_port;
      out << ready.dump() << "\n";
    }
    std::rename(tmp.c_str(), path.c_str());  // atomically: a reader sees all of it or nothing
  }

  int sig = 0;
  sigwait(&signals, &sig);
  Log("stopping", {{"signal", sig == SIGINT ? "SIGINT" : "SIGTERM"}});
  // A node's rolling upgrade: SIGTERM lets its live sessions finish (Kubernetes sends it and
  // waits terminationGracePeriodSeconds); SIGINT (an operator's ^C) does not wait.
  if (agent && sig == SIGTERM) agent->Drain(p.Double("drain-timeout"));
  if (web) web->Shutdown();  // ends the dashboard's streams and exports
  if (control) control->Shutdown();
  if (agent) agent->Shutdown();
  sessions->Shutdown();
  if (endpoint) endpoint->Stop();
  const auto stats = (*store)->stats();
  web.reset();
  session_metrics.reset();  // unsubscribes: before the sessions go
  control.reset();
  agent.reset();
  manager.reset();
  placed.reset();
  endpoint.reset();
  store->reset();  // drains the writer
  Log("stopped", {{"commits", stats.commits}, {"jobs", stats.jobs}});
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
