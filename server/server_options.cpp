#include "server/server_options.h"

#include "server/http/oidc.h"

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "common/sim/scene.h"
#include "db/store.h"
#include "server/cluster/node_cost.h"

namespace vsurg::server {
namespace {

using cli::ArgParser;
using Kind = ArgParser::Kind;
using cluster::ClusterOptions;
using cluster::NodeOptions;

// The program's own defaults where they differ from a component's (which binds to a free port).
ServerSettings Defaults() {
  ServerSettings s;
  s.control.listen = "127.0.0.1:50051";
  s.endpoint.port = 50052;
  s.cluster.listen = "127.0.0.1:0";
  s.sessions.cases_ready = 2;  // a palpation's sessions start without building their case
  return s;
}

std::string Num(double v) {
  return NumberText(v);
}

void DeclareStoreAndRole(ArgParser& p) {
  p.Option("db", Kind::kString,
           "SQLite database file (created when missing), or a postgresql:// URI (the shared "
           "store of control and sim roles)",
           true)
      .Option("role", Kind::kString,
              "all (one process), control (control plane of a site) or sim (simulation node)",
              false, Defaults().role);
}

void DeclareCluster(ArgParser& p) {
  const ServerSettings d = Defaults();
  const ClusterOptions& c = d.cluster;
  p.Option("cluster-listen", Kind::kString,
           "control, sim: the internal API's host:port (port 0: any free one)", false, c.listen)
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
              false, Num(c.tls_refresh_s))
      .Within(ClusterOptions::kTlsRefreshS)
      .Option("cluster-store-lease", Kind::kDouble,
              "control: seconds of lease a node's row in the store carries; the replica a node "
              "beats to keeps its heartbeats in memory and rewrites the row when half of it is "
              "gone (<= 2.5: every heartbeat is written); the same on every replica",
              false, Num(c.store_lease_s))
      .Within(ClusterOptions::kStoreLeaseS)
      .Option("cluster-heartbeat-period", Kind::kDouble,
              "control, sim: seconds between a node's heartbeats; the same on every process", false,
              Num(c.heartbeat_period_s))
      .Within(ClusterOptions::kHeartbeatPeriodS)
      .Option("cluster-heartbeat-timeout", Kind::kDouble,
              "control, sim: seconds a node may be silent before the site declares it down and "
              "re-places its sessions (its lease; at least two heartbeat periods past the lease "
              "margin); longer rides out a control plane starved of CPU, at the cost of a lost "
              "node's stations waiting longer; the same on every process",
              false, Num(c.heartbeat_timeout_s))
      .Within(ClusterOptions::kHeartbeatTimeoutS)
      .Option("cluster-control-name", Kind::kString,
              "control, sim: the name control replicas' certificates carry", false, c.control_name)
      .Option("cluster-health-listen", Kind::kString,
              "control, sim: host:port of a plaintext gRPC health check (liveness only, for "
              "probes when the internal API wants a client certificate)")
      .Option("control", Kind::kString,
              "sim: the control plane's internal API, host:port[,host:port...]")
      .Option("node-name", Kind::kString, "sim: this node's name, unique in the site")
      .Option("advertise", Kind::kString,
              "sim: host:port the control plane reaches this node's internal API at "
              "(default: --cluster-listen's host with its bound port)")
      .Option("capacity", Kind::kInt,
              "sim: live sessions this node takes (0: what 70% of its cores hold at the dearest "
              "cost per station its scenes state, else 24)",
              false, Num(NodeOptions::kDeriveCapacity))
      .Within(NodeOptions::kCapacityOption)
      .Option("drain-timeout", Kind::kDouble,
              "sim: on SIGTERM, seconds the live sessions may take to finish", false,
              Num(d.drain_timeout_s))
      .Within({0, 86400})
      .Option("drain-wait", Kind::kFlag,
              "sim: on SIGTERM, let the live sessions finish here instead of moving them to "
              "other nodes (live migration, the default)");
}

void DeclareNetwork(ArgParser& p) {
  const ServerSettings d = Defaults();
  p.Option("listen", Kind::kString, "gRPC address host:port", false, d.control.listen)
      .Option("udp-address", Kind::kString, "UDP haptic endpoint address", false,
              d.endpoint.address)
      .Option("udp-port", Kind::kInt, "UDP port (0: any free one)", false, Num(d.endpoint.port))
      .Within(EndpointOptions::kPort)
      .Option("public-host", Kind::kString,
              "host stations are told to send to (default: udp-address)")
      .Option("public-port", Kind::kInt,
              "UDP port stations are told to send to (default: the endpoint's; a relay or NAT in "
              "front of it listens on another)")
      .Within({1, EndpointOptions::kPort.hi})
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
      .Option("oidc-issuer", Kind::kString,
              "the dashboard's sign-in through an OpenID Connect identity provider: its issuer "
              "URL (discovery at ISSUER/.well-known/openid-configuration); tokens still work")
      .Option("oidc-client-id", Kind::kString, "this server's client id at the provider")
      .Option("oidc-client-secret-file", Kind::kString,
              "file holding the client's secret (none: a public client, PKCE alone)")
      .Option("oidc-redirect-uri", Kind::kString,
              "the callback as registered at the provider: "
              "https://HOST/api/v1/signin/oidc/callback")
      .Option("oidc-username-claim", Kind::kString, "the ID token's claim naming the user", false,
              "preferred_username")
      .Option("oidc-role-claim", Kind::kString,
              "the ID token's claim giving the role (a string or a list, e.g. groups)", false,
              "vsurg_role")
      .Option("oidc-role-map", Kind::kString,
              "the claim's values to roles, VALUE=ROLE,... (none: the value is the role's name)")
      .Option("log-format", Kind::kString,
              "the event log on stderr: logfmt (key=value lines) or json (one object a line; "
              "every line about a session carries its id as `session`)",
              false, "logfmt");
}

void DeclareSessions(ArgParser& p) {
  const ServerSettings d = Defaults();
  using S = SessionManagerOptions;
  using E = EndpointOptions;
  p.Option("telemetry-hz", Kind::kDouble, "monitor telemetry rate", false,
           Num(d.sessions.telemetry_hz))
      .Within(S::kTelemetryHz.And(ClusterOptions::kTelemetryHz))
      .Option("deformation-workers", Kind::kInt,
              "driven sessions deform on a pool of this many threads (0: one per core) instead "
              "of a thread each (-1)",
              false, Num(d.sessions.deformation_workers))
      .Within(S::kDeformationWorkers)
      .Option("quasi-static-interval-ms", Kind::kDouble,
              "a quasi-static model (coil, reduced) updates at most once per this many "
              "milliseconds while a hand grasps it, from the newest request (0: every request)",
              false, Num(1e3 * d.sessions.quasi_static_interval_s))
      .Within(S::kQuasiStaticIntervalS.Scaled(1e3))
      .Option("cases-ready", Kind::kInt,
              "palpation cases kept built ahead for each scene that draws them, in the reduced "
              "models' cache (0: each session builds its own when it is created)",
              false, Num(d.sessions.cases_ready))
      .Within(S::kCasesReady)
      .Option("realtime-priority", Kind::kInt,
              "SCHED_FIFO priority of the UDP haptic thread when permitted (0: off, the normal "
              "priority a container gives)",
              false, Num(d.endpoint.realtime_priority))
      .Within(E::kRealtimePriority)
      .Option("io-threads", Kind::kInt,
              "UDP haptic threads, each with a socket on the UDP port (SO_REUSEPORT), sessions "
              "spread over them by id",
              false, Num(d.endpoint.io_threads))
      .Within(E::kIoThreads)
      .Option("busy-poll-us", Kind::kInt,
              "microseconds an I/O thread polls its socket before it sleeps, only while its "
              "datagrams come at least once per window (0: never)",
              false, Num(d.endpoint.busy_poll_us))
      .Within(E::kBusyPollUs)
      .Option("max-sessions", Kind::kInt, "live sessions on this server", false,
              Num(d.sessions.max_live_sessions))
      .Within(S::kMaxLiveSessions)
      .Option("max-sessions-per-user", Kind::kInt,
              "live sessions per trainee (at most --max-sessions)", false,
              Num(d.sessions.max_sessions_per_user))
      .Within(S::kMaxLiveSessions)
      .Option("start-timeout", Kind::kDouble,
              "seconds a created session may wait for Start before it is aborted", false,
              Num(d.sessions.start_timeout_s))
      .Within(S::kStartTimeoutS)
      .Option("backup-dir", Kind::kString,
              "the only folder AdminService/Backup writes to (default: backups/ beside --db)")
      .Option("ready-file", Kind::kString,
              "write {grpc_port, udp_port, http_port} here once serving")
      .Option("config", Kind::kString, "JSON file of these options (flags win)");
}

Error Bad(const std::string& option, const std::string& message) {
  return Error{ErrorCode::kInvalidArgument, message, option};
}

// The first line of `path` as a secret of at least `min` characters.
Expected<std::string> ReadSecret(const cli::ArgParser& p, const std::string& option, size_t min) {
  std::string secret;
  std::ifstream in(p.String(option));
  if (!in || !std::getline(in, secret) || secret.size() < min)
    return Bad(option, "cannot read a secret of at least " + std::to_string(min) +
                           " characters from " + p.String(option));
  return secret;
}

Status ReadCluster(const cli::ArgParser& p, ServerSettings& s) {
  ClusterOptions& c = s.cluster;
  if (!s.shared_store)
    return Bad("db", "the " + s.role +
                         " role shares its store with the site: a postgresql:// URI is required");
  if (!p.Has("cluster-token-file"))
    return Bad("cluster-token-file", "required by the " + s.role + " role");
  auto token = ReadSecret(p, "cluster-token-file", 1);
  if (!token.ok()) return token.error();
  c.token = *token;
  c.listen = p.String("cluster-listen");
  c.allow_insecure = p.Flag("allow-insecure");
  if (p.Has("cluster-tls-cert")) c.tls_cert = p.String("cluster-tls-cert");
  if (p.Has("cluster-tls-key")) c.tls_key = p.String("cluster-tls-key");
  if (p.Has("cluster-tls-ca")) c.tls_ca = p.String("cluster-tls-ca");
  c.tls_refresh_s = p.Double("cluster-tls-refresh");
  c.store_lease_s = p.Double("cluster-store-lease");
  c.heartbeat_period_s = p.Double("cluster-heartbeat-period");
  c.heartbeat_timeout_s = p.Double("cluster-heartbeat-timeout");
  if (c.heartbeat_timeout_s - c.lease_margin_s < 2 * c.heartbeat_period_s)
    return Bad("cluster-heartbeat-timeout", "less " + NumberText(c.lease_margin_s) +
                                                " s of margin, must last two heartbeat periods");
  c.control_name = p.String("cluster-control-name");
  if (p.Has("cluster-health-listen")) c.health_listen = p.String("cluster-health-listen");
  c.telemetry_hz = s.sessions.telemetry_hz;
  c.max_sessions_per_user = s.sessions.max_sessions_per_user;
  if (s.role == "sim" && !p.Has("control")) return Bad("control", "required by the sim role");
  return Status::Ok();
}

// --capacity 0: what 70% of the node's cores hold at the dearest cost per station its scenes
// state (docs/SCALING.md), else the pressing stations' measured 24.
void DeriveCapacity(NodeOptions& n) {
  const double cores = NodeCores();
  const DearestScene dearest = FindDearestScene(sim::ScenesDirectory());
  n.capacity = CapacityAtCost(cores, dearest.core_per_station);
  if (n.capacity == 0) {
    n.capacity = NodeOptions{}.capacity;
    n.capacity_from = "no scene states its cost: the pressing stations' " + Num(n.capacity);
    return;
  }
  n.capacity_from = "70% of " + Num(cores) + " cores at " + dearest.name + "'s " +
                    Num(dearest.core_per_station) + " core per station";
}

void ReadSessions(const cli::ArgParser& p, ServerSettings& s) {
  EndpointOptions& e = s.endpoint;
  e.address = p.String("udp-address");
  e.port = static_cast<uint16_t>(p.Int("udp-port"));
  e.realtime_priority = p.Int("realtime-priority");
  e.io_threads = p.Int("io-threads");
  e.busy_poll_us = p.Int("busy-poll-us");
  SessionManagerOptions& so = s.sessions;
  so.udp_host = p.Has("public-host") ? p.String("public-host") : e.address;
  if (p.Has("public-port")) so.udp_port = static_cast<uint16_t>(p.Int("public-port"));
  so.telemetry_hz = p.Double("telemetry-hz");
  so.max_live_sessions = p.Int("max-sessions");
  so.max_sessions_per_user = p.Int("max-sessions-per-user");
  so.start_timeout_s = p.Double("start-timeout");
  so.deformation_workers = p.Int("deformation-workers");
  so.quasi_static_interval_s = 1e-3 * p.Double("quasi-static-interval-ms");
  so.cases_ready = p.Int("cases-ready");
  if (s.role != "sim") return;
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  so.node = p.Has("node-name") ? p.String("node-name") : std::string(host);
  NodeOptions& n = s.node;
  n.name = so.node;
  n.advertise = p.Has("advertise") ? p.String("advertise") : "";
  n.control = p.String("control");
  n.udp_host = so.udp_host;
  n.udp_port = so.udp_port;  // 0: the endpoint's, once bound
  n.capacity = p.Int("capacity");
  if (n.capacity == NodeOptions::kDeriveCapacity) DeriveCapacity(n);
  n.migrate_on_drain = !p.Flag("drain-wait");
}

// The identity provider's relying party, from the --oidc-* options (it asks the provider nothing
// yet: discovery happens at the first sign-in).
Expected<std::shared_ptr<http::OidcRelyingParty>> ReadOidc(const cli::ArgParser& p) {
  http::OidcOptions o;
  o.issuer = p.String("oidc-issuer");
  o.client_id = p.String("oidc-client-id");
  o.redirect_uri = p.String("oidc-redirect-uri");
  o.username_claim = p.String("oidc-username-claim");
  o.role_claim = p.String("oidc-role-claim");
  if (p.Has("oidc-client-secret-file")) {
    auto secret = ReadSecret(p, "oidc-client-secret-file", 1);
    if (!secret.ok()) return secret.error();
    o.client_secret = *secret;
  }
  if (p.Has("oidc-role-map")) {
    auto map = http::ParseRoleMap(p.String("oidc-role-map"));
    if (!map.ok()) return map.error();
    o.role_map = std::move(*map);
  }
  auto rp = http::OidcRelyingParty::Create(std::move(o));
  if (!rp.ok()) return Bad(rp.error().field, rp.error().message);
  return std::shared_ptr<http::OidcRelyingParty>(std::move(*rp));
}

Status ReadFrontDoors(const cli::ArgParser& p, ServerSettings& s) {
  ControlPlaneOptions& co = s.control;
  co.listen = p.String("listen");
  if (p.Has("tls-cert")) co.tls_cert_file = p.String("tls-cert");
  if (p.Has("tls-key")) co.tls_key_file = p.String("tls-key");
  co.allow_insecure = p.Flag("allow-insecure");
  // A shared store is backed up by PostgreSQL's own tools: no backup folder, backups refused.
  co.backup_dir =
      p.Has("backup-dir") ? p.String("backup-dir")
      : s.shared_store
          ? std::string()
          : (std::filesystem::absolute(p.String("db")).parent_path() / "backups").string();
  s.http = p.Has("http");
  HttpServerOptions& ho = s.web;
  ho.listen = p.String("http");
  ho.tls_cert_file = co.tls_cert_file;
  ho.tls_key_file = co.tls_key_file;
  ho.allow_insecure = co.allow_insecure;
  ho.backup_dir = co.backup_dir;
  ho.metrics_only = s.role == "sim";
  if (p.Has("metrics-token-file")) {
    auto token = ReadSecret(p, "metrics-token-file", 16);
    if (!token.ok()) return token.error();
    ho.metrics_token = *token;
  }
  if (p.Has("oidc-issuer")) {
    auto oidc = ReadOidc(p);
    if (!oidc.ok()) return oidc.error();
    ho.oidc = std::move(*oidc);
  }
  const std::string list = p.String("http-hosts");
  for (size_t at = 0; at < list.size();) {
    const size_t comma = std::min(list.find(',', at), list.size());
    if (comma > at) ho.hosts.push_back(list.substr(at, comma - at));
    at = comma + 1;
  }
  return Status::Ok();
}

}  // namespace

void DeclareServerOptions(cli::ArgParser& p) {
  DeclareStoreAndRole(p);
  DeclareCluster(p);
  DeclareNetwork(p);
  DeclareSessions(p);
}

Expected<ServerSettings> ReadServerSettings(const cli::ArgParser& p) {
  ServerSettings s = Defaults();
  s.role = p.String("role");
  if (s.role != "all" && s.role != "control" && s.role != "sim")
    return Bad("role", "must be all, control or sim");
  s.db = p.String("db");
  s.shared_store = db::BackendOf(s.db) == db::Backend::kPostgres;
  s.drain_timeout_s = p.Double("drain-timeout");
  s.ready_file = p.String("ready-file");
  ReadSessions(p, s);
  if (s.sessions.max_sessions_per_user > s.sessions.max_live_sessions)
    return Bad("max-sessions-per-user", "must be at most --max-sessions");
  if (s.role != "all")
    if (Status st = ReadCluster(p, s); !st.ok()) return st.error();
  if (Status st = ReadFrontDoors(p, s); !st.ok()) return st.error();
  return s;
}

}  // namespace vsurg::server
