// vsurg-server's options against the components' settings: every default and bound the program
// declares (and prints in --help) is the settings struct's own, every bound is enforced when
// parsed, and a command line fills the structs the components are opened with.
#include "server/server_options.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/processes.h"

namespace vsurg::server {
namespace {

using cli::ArgParser;
using cluster::ClusterOptions;
using cluster::NodeOptions;

ArgParser Declared() {
  ArgParser p("vsurg-server", "");
  DeclareServerOptions(p);
  return p;
}

bool Same(std::optional<Range> a, Range b) {
  return a && a->lo == b.lo && a->hi == b.hi;
}

TEST(ServerOptionsTest, EveryBoundAndDefaultIsTheComponentsOwn) {
  const ArgParser p = Declared();
  using S = SessionManagerOptions;
  using E = EndpointOptions;
  const S sessions;
  const E endpoint;
  const ClusterOptions cluster;
  struct Case {
    const char* option;
    Range range;
    double default_value;
  };
  for (const Case& c : std::vector<Case>{
           {"telemetry-hz", S::kTelemetryHz.And(ClusterOptions::kTelemetryHz),
            sessions.telemetry_hz},
           {"max-sessions", S::kMaxLiveSessions, static_cast<double>(sessions.max_live_sessions)},
           {"max-sessions-per-user", S::kMaxLiveSessions,
            static_cast<double>(sessions.max_sessions_per_user)},
           {"start-timeout", S::kStartTimeoutS, sessions.start_timeout_s},
           {"deformation-workers", S::kDeformationWorkers,
            static_cast<double>(sessions.deformation_workers)},
           {"quasi-static-interval-ms", S::kQuasiStaticIntervalS.Scaled(1e3),
            1e3 * sessions.quasi_static_interval_s},
           {"realtime-priority", E::kRealtimePriority,
            static_cast<double>(endpoint.realtime_priority)},
           {"io-threads", E::kIoThreads, static_cast<double>(endpoint.io_threads)},
           {"busy-poll-us", E::kBusyPollUs, static_cast<double>(endpoint.busy_poll_us)},
           {"cluster-tls-refresh", ClusterOptions::kTlsRefreshS, cluster.tls_refresh_s},
           {"cluster-store-lease", ClusterOptions::kStoreLeaseS, cluster.store_lease_s},
           {"cluster-heartbeat-period", ClusterOptions::kHeartbeatPeriodS,
            cluster.heartbeat_period_s},
           {"cluster-heartbeat-timeout", ClusterOptions::kHeartbeatTimeoutS,
            cluster.heartbeat_timeout_s},
           {"capacity", NodeOptions::kCapacityOption, NodeOptions::kDeriveCapacity},
       }) {
    EXPECT_TRUE(Same(p.RangeOf(c.option), c.range)) << c.option;
    EXPECT_EQ(p.DefaultOf(c.option), NumberText(c.default_value)) << c.option;
    // Enforced at both ends, and the message names the bound.
    for (double outside : {c.range.lo - 1, c.range.hi + 1}) {
      ArgParser q = Declared();
      const Status s = q.Parse({"--db", "x.db", std::string("--") + c.option, NumberText(outside)});
      ASSERT_FALSE(s.ok()) << c.option << " " << outside;
      EXPECT_EQ(s.error().field, std::string("--") + c.option);
      EXPECT_EQ(s.error().message, "must be within " + c.range.Text());
    }
    ArgParser q = Declared();
    EXPECT_TRUE(
        q.Parse({"--db", "x.db", std::string("--") + c.option, NumberText(c.range.hi)}).ok())
        << c.option;
  }
  EXPECT_EQ(p.DefaultOf("cluster-control-name"), cluster.control_name);
  EXPECT_EQ(p.DefaultOf("udp-address"), endpoint.address);
}

// The program prints exactly what it declares.
TEST(ServerOptionsTest, TheProgramsHelpIsTheDeclaredOptions) {
  const test::ShellRun r = test::Shell(std::string(VSURG_SERVER_BINARY) + " --help");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string declared = Declared().Help();
  // The program's summary differs; its options (from "options:" on) are the declared ones.
  ASSERT_NE(r.out.find("options:"), std::string::npos);
  EXPECT_EQ(r.out.substr(r.out.find("options:")), declared.substr(declared.find("options:")));
  EXPECT_NE(r.out.find("--telemetry-hz     monitor telemetry rate (default 30) (within 1..120)"),
            std::string::npos)
      << r.out;
}

TEST(ServerOptionsTest, ACommandLineFillsTheComponentsSettings) {
  ArgParser p = Declared();
  ASSERT_TRUE(p.Parse({"--db",
                       "x.db",
                       "--telemetry-hz",
                       "60",
                       "--max-sessions",
                       "10",
                       "--max-sessions-per-user",
                       "3",
                       "--quasi-static-interval-ms",
                       "4",
                       "--udp-port",
                       "0",
                       "--public-host",
                       "sim.example",
                       "--io-threads",
                       "2",
                       "--http",
                       "127.0.0.1:0",
                       "--http-hosts",
                       "a.example,,b.example"})
                  .ok());
  auto s = ReadServerSettings(p);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->role, "all");
  EXPECT_FALSE(s->shared_store);
  EXPECT_EQ(s->sessions.telemetry_hz, 60);
  EXPECT_EQ(s->sessions.max_live_sessions, 10);
  EXPECT_EQ(s->sessions.max_sessions_per_user, 3);
  EXPECT_DOUBLE_EQ(s->sessions.quasi_static_interval_s, 0.004);
  EXPECT_EQ(s->sessions.udp_host, "sim.example");
  EXPECT_EQ(s->endpoint.port, 0);
  EXPECT_EQ(s->endpoint.io_threads, 2);
  EXPECT_EQ(s->control.listen, "127.0.0.1:50051");
  EXPECT_TRUE(s->http);
  EXPECT_EQ(s->web.hosts, (std::vector<std::string>{"a.example", "b.example"}));
  EXPECT_FALSE(s->control.backup_dir.empty()) << "backups/ beside the file";
  // Left alone, every setting is its struct's default.
  ArgParser q = Declared();
  ASSERT_TRUE(q.Parse({"--db", "x.db"}).ok());
  auto d = ReadServerSettings(q);
  ASSERT_TRUE(d.ok());
  const SessionManagerOptions so;
  EXPECT_EQ(d->sessions.telemetry_hz, so.telemetry_hz);
  EXPECT_EQ(d->sessions.max_live_sessions, so.max_live_sessions);
  EXPECT_EQ(d->sessions.start_timeout_s, so.start_timeout_s);
  EXPECT_EQ(d->sessions.quasi_static_interval_s, so.quasi_static_interval_s);
  EXPECT_EQ(d->endpoint.busy_poll_us, EndpointOptions{}.busy_poll_us);
}

}  // namespace
}  // namespace vsurg::server
