// Control-plane measurements for vsurg-bench (see vsurg_bench_main.cpp for the commands).
#include "bench/control_bench.h"

#include <arpa/inet.h>
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "db/postgres.h"
#include "db/sqlite.h"
#include "db/store.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"
#include "server/cluster/cluster.h"
#include "server/control/control_plane.h"
#include "server/net/lease.h"
#include "server/net/udp_endpoint.h"
#include "server/ops/metrics.h"
#include "server/session/session_manager.h"
#include "vsurg/v1/cluster.grpc.pb.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::bench {
namespace {

namespace fs = std::filesystem;
using cli::ArgParser;
using Clock = std::chrono::steady_clock;
using json = nlohmann::json;

fs::path TempDir(const std::string& tag) {
  const fs::path d =
      fs::temp_directory_path() / ("vsurg_bench_" + tag + "_" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

struct SubmitResult {
  std::string store;  // sqlite or postgresql
  int max_batch = 0;
  double per_s = 0, p50_ms = 0, p99_ms = 0, jobs_per_commit = 0;
  uint64_t ok = 0, failed = 0;
};

// In-flight calls ("lanes") on the callback client API: each lane issues its next submission
// from the previous one's completion, so `clients` calls are always outstanding.
// One statement on a PostgreSQL server's maintenance database (CREATE/DROP DATABASE).
bool PostgresAdmin(const std::string& uri, const std::string& sql) {
  const Status s = db::RunPostgresStatement(uri, sql);
  if (!s.ok()) std::cerr << sql << ": " << s.error().message << "\n";
  return s.ok();
}

// `clients` evaluators submitting back to back through the control plane's gRPC, each one
// request in flight: a lane starts its next submission from the previous one's completion.
class SubmitLoad {
 public:
  SubmitLoad(v1::EvaluationService::Stub& stub, std::string token, int clients)
      : stub_(stub), token_(std::move(token)), lanes_(clients), running_(clients) {
    latency_ms_.reserve(1 << 20);
    for (Lane& lane : lanes_) {
      lane.req.set_evaluator_group("chief");
      lane.req.set_subject_kind("model");
      lane.req.set_subject("bench-model");
      for (int j = 0; j < 9; ++j) lane.req.add_scores(7);
    }
  }
  void Start() {
    for (Lane& lane : lanes_) Send(lane);
  }
  // Forgets the latencies so far (the warm-up's).
  void ClearLatencies() {
    std::lock_guard lock(m_);
    latency_ms_.clear();
  }
  uint64_t ok() const { return ok_.load(); }
  uint64_t failed() const { return failed_.load(); }
  // Stops every lane after its request in flight; then the latencies since the last clear.
  std::vector<double> StopAndTake() {
    stop_ = true;
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return running_ == 0; });
    return latency_ms_;
  }

 private:
  struct Lane {
    std::unique_ptr<grpc::ClientContext> ctx;
    v1::SubmitEvaluationRequest req;
    v1::SubmitEvaluationResponse resp;
    Clock::time_point sent;
  };
  void Send(Lane& lane) {
    const uint64_t n = next_.fetch_add(1);
    lane.ctx = std::make_unique<grpc::ClientContext>();
    lane.ctx->AddMetadata("authorization", "Bearer " + token_);
    lane.ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    lane.req.set_idempotency_key("bench-" + std::to_string(n));
    lane.req.set_evaluator("rater-" + std::to_string(n));
    lane.sent = Clock::now();
    stub_.async()->Submit(lane.ctx.get(), &lane.req, &lane.resp,
                          [this, &lane](grpc::Status s) { Done(lane, s); });
  }
  void Done(Lane& lane, const grpc::Status& s) {
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - lane.sent).count();
    if (s.ok()) {
      ok_.fetch_add(1);
      std::lock_guard lock(m_);
      latency_ms_.push_back(ms);
    } else {
      failed_.fetch_add(1);
    }
    if (!stop_.load()) return Send(lane);
    std::lock_guard lock(m_);
    if (--running_ == 0) cv_.notify_all();
  }

  v1::EvaluationService::Stub& stub_;
  const std::string token_;
  std::vector<Lane> lanes_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> next_{0}, ok_{0}, failed_{0};
  std::mutex m_;
  std::condition_variable cv_;
  int running_;
  std::vector<double> latency_ms_;
};

// The submissions through a control plane on `location`'s store: half a second's warm-up, then
// `seconds` measured (rate, latency percentiles, jobs per group commit).
void MeasureSubmissions(const std::string& location, int max_batch, int clients, double seconds,
                        SubmitResult& out) {
  auto store = std::move(db::Store::Open({.path = location, .max_batch = max_batch})).value();
  const std::string token = store->InitAdmin("root").value();
  auto sessions = server::SessionManager::Open(*store, nullptr, {}).value();
  auto cp = std::move(server::ControlPlane::Start(*store, *sessions, {})).value();
  auto stub = v1::EvaluationService::NewStub(grpc::CreateChannel(
      "127.0.0.1:" + std::to_string(cp->port()), grpc::InsecureChannelCredentials()));
  SubmitLoad load(*stub, token, clients);
  load.Start();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const uint64_t ok0 = load.ok();
  load.ClearLatencies();
  const db::StoreStats s0 = store->stats();
  const auto t0 = Clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  const uint64_t ok1 = load.ok();
  const db::StoreStats s1 = store->stats();
  const std::vector<double> latency_ms = load.StopAndTake();
  out.p50_ms = Percentile(latency_ms, 0.5);
  out.p99_ms = Percentile(latency_ms, 0.99);
  out.ok = ok1 - ok0;
  out.failed = load.failed();
  out.per_s = static_cast<double>(out.ok) / elapsed;
  out.jobs_per_commit = s1.commits > s0.commits
                            ? static_cast<double>(s1.jobs - s0.jobs) / (s1.commits - s0.commits)
                            : 0;
  cp->Shutdown();
}

// `postgres` empty: a new SQLite file; else a new database on that server (dropped after).
SubmitResult RunSubmit(const std::string& postgres, int max_batch, int clients, double seconds) {
  const fs::path dir = TempDir("submit_" + std::to_string(max_batch));
  SubmitResult out;
  out.store = postgres.empty() ? "sqlite" : "postgresql";
  out.max_batch = max_batch;
  std::string location = (dir / "vsurg.db").string();
  const std::string pg_name =
      "vsurg_bench_" + std::to_string(getpid()) + "_" + std::to_string(max_batch);
  if (!postgres.empty()) {
    if (!PostgresAdmin(postgres, "CREATE DATABASE " + pg_name)) return out;
    location = postgres.substr(0, postgres.rfind('/') + 1) + pg_name;
  }
  MeasureSubmissions(location, max_batch, clients, seconds, out);
  fs::remove_all(dir);
  if (!postgres.empty()) PostgresAdmin(postgres, "DROP DATABASE " + pg_name + " WITH (FORCE)");
  return out;
}

// Fills a store with `rows` evaluation rows (rows / 9 submissions) in one transaction.
Status Fill(db::Store& store, int64_t rows) {
  return store.Write([rows](db::Connection& c) -> Status {
    const int64_t now = db::NowUs();
    if (Status s = c.Exec("INSERT INTO users(name, role, created_us) VALUES ('bench', 'admin', 0)");
        !s.ok())
      return s;
    auto ev = c.Prepare("INSERT INTO evaluators(name, evaluator_group) VALUES (?1, ?2)");
    auto sub = c.Prepare(
        "INSERT INTO submissions(idempotency_key, evaluator_id, evaluator_group, subject_kind, "
        "subject, submitted_us, submitted_by) VALUES (?1, ?2, ?3, 'model', ?4, ?5, 1)");
    auto val =
        c.Prepare("INSERT INTO evaluations(submission_id, index_no, score) VALUES (?1, ?2, ?3)");
    if (!ev.ok() || !sub.ok() || !val.ok()) return Error{ErrorCode::kIoError, "prepare", ""};
    const char* groups[] = {"intern", "associate_chief", "chief"};
    const int evaluators = 1000;
    for (int e = 0; e < evaluators; ++e) {
      (*ev)->Bind(1, "rater-" + std::to_string(e)).Bind(2, groups[e % 3]);
      if (Status s = (*ev)->Run(); !s.ok()) return s;
    }
    const int64_t submissions = (rows + 8) / 9;
    for (int64_t i = 0; i < submissions; ++i) {
      const int64_t e = i % evaluators;
      (*sub)->Bind(1, "k" + std::to_string(i)).Bind(2, e + 1).Bind(3, groups[e % 3]);
      (*sub)->Bind(4, "model-" + std::to_string(i / evaluators)).Bind(5, now - (submissions - i));
      if (Status s = (*sub)->Run(); !s.ok()) return s;
      auto id_or = c.LastInsertId();
      if (!id_or.ok()) return id_or.error();
      const int64_t id = *id_or;
      for (int j = 1; j <= 9; ++j) {
        (*val)->Bind(1, id).Bind(2, int64_t{j}).Bind(3, 0.5 * static_cast<double>((i + j) % 21));
        if (Status s = (*val)->Run(); !s.ok()) return s;
      }
    }
    return Status::Ok();
  });
}

}  // namespace

int GrpcSubmit(const std::vector<std::string>& args) {
  ArgParser p(
      "vsurg-bench grpc-submit",
      "Durable evaluation submissions per second through gRPC on loopback (in-process\n"
      "server, real SQLite file with synchronous=FULL, and with --postgres a real PostgreSQL\n"
      "database, synchronous_commit on), for each writer batch limit side by side: 1 = one\n"
      "commit (fsync) per submission, larger = group commit.");
  p.Option("clients", ArgParser::Kind::kInt, "calls in flight", false, "32")
      .Option("seconds", ArgParser::Kind::kDouble, "measured time per setting, s", false, "5")
      .Option("batches", ArgParser::Kind::kString, "writer batch limits, comma-separated", false,
              "1,1024")
      .Option("postgres", ArgParser::Kind::kString,
              "also a PostgreSQL server (its maintenance database's URI, e.g. from "
              "deploy/postgres.sh): each setting runs on SQLite and PostgreSQL alternately")
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  const int clients = p.Int("clients");
  const double seconds = p.Double("seconds");
  if (clients < 1 || clients > 1024 || !(seconds > 0 && seconds <= 600)) {
    std::cerr << p.command() << ": --clients 1..1024, --seconds (0, 600]\n";
    return 2;
  }
  std::vector<int> batches;
  std::stringstream list(p.String("batches"));
  for (std::string b; std::getline(list, b, ',');) batches.push_back(std::stoi(b));
  json results = json::array();
  std::vector<std::string> stores = {""};
  if (p.Has("postgres")) stores.push_back(p.String("postgres"));
  for (int b : batches)
    for (const std::string& pg : stores) {
      const SubmitResult r = RunSubmit(pg, b, clients, seconds);
      results.push_back({{"store", r.store},
                         {"max_batch", r.max_batch},
                         {"submissions_per_s", r.per_s},
                         {"p50_ms", r.p50_ms},
                         {"p99_ms", r.p99_ms},
                         {"jobs_per_commit", r.jobs_per_commit},
                         {"ok", r.ok},
                         {"failed", r.failed}});
      if (!p.Flag("json"))
        std::printf(
            "%-10s max_batch %5d: %8.0f submissions/s  p50 %.2f ms  p99 %.2f ms  %.1f per commit\n",
            r.store.c_str(), r.max_batch, r.per_s, r.p50_ms, r.p99_ms, r.jobs_per_commit);
    }
  if (p.Flag("json")) std::cout << json{{"clients", clients}, {"results", results}}.dump() << "\n";
  return 0;
}

int ExportBench(const std::vector<std::string>& args) {
  ArgParser p(
      "vsurg-bench export",
      "Exports N evaluation rows (one per evaluator, subject and index) from a real SQLite\n"
      "file: directly from the store, and streamed through gRPC AdminService/Export.");
  p.Option("rows", ArgParser::Kind::kInt, "evaluation rows", false, "1000000")
      .Option("format", ArgParser::Kind::kString, "csv, jsonl or xapi", false, "csv")
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  const auto format = db::ParseExportFormat(p.String("format"));
  if (!format || p.Int("rows") < 9) {
    std::cerr << p.command() << ": --format csv|jsonl|xapi, --rows >= 9\n";
    return 2;
  }
  const fs::path dir = TempDir("export");
  json out;
  {
    auto store = std::move(db::Store::Open({.path = (dir / "vsurg.db").string()})).value();
    auto t0 = Clock::now();
    if (Status s = Fill(*store, p.Int("rows")); !s.ok()) {
      std::cerr << p.command() << ": fill: " << s.error().message << "\n";
      return 1;
    }
    const double fill_s = std::chrono::duration<double>(Clock::now() - t0).count();
    const int64_t rows = store->CountEvaluationRows().value();

    std::ofstream file(dir / "local.out", std::ios::binary);
    uint64_t local_bytes = 0;
    t0 = Clock::now();
    (void)store->Export({}, *format, [&](std::string_view c) {
      file.write(c.data(), static_cast<std::streamsize>(c.size()));
      local_bytes += c.size();
      return true;
    });
    file.close();
    const double local_s = std::chrono::duration<double>(Clock::now() - t0).count();

    const std::string token = store->IssueToken("bench", "").value();
    auto sessions_owned = server::SessionManager::Open(*store, nullptr, {}).value();
    server::SessionManager& sessions = *sessions_owned;
    auto cp = std::move(server::ControlPlane::Start(*store, sessions, {})).value();
    auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(cp->port()),
                                       grpc::InsecureChannelCredentials());
    auto stub = v1::AdminService::NewStub(channel);
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer " + token);
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(10));
    v1::ExportRequest req;
    req.set_format(p.String("format"));
    std::ofstream remote_file(dir / "remote.out", std::ios::binary);
    uint64_t remote_bytes = 0;
    t0 = Clock::now();
    auto reader = stub->Export(&ctx, req);
    v1::ExportChunk chunk;
    while (reader->Read(&chunk)) {
      remote_file.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
      remote_bytes += chunk.data().size();
    }
    const grpc::Status st = reader->Finish();
    const double remote_s = std::chrono::duration<double>(Clock::now() - t0).count();
    cp->Shutdown();
    out = {{"rows", rows},
           {"format", p.String("format")},
           {"fill_s", fill_s},
           {"store_export_s", local_s},
           {"store_export_bytes", local_bytes},
           {"grpc_export_s", remote_s},
           {"grpc_export_bytes", remote_bytes},
           {"grpc_ok", st.ok()},
           {"rows_per_s_grpc", static_cast<double>(rows) / remote_s}};
  }
  fs::remove_all(dir);
  if (p.Flag("json")) {
    std::cout << out.dump() << "\n";
  } else {
    std::printf("%lld rows (%s): store export %.2f s (%.1f MB), gRPC export %.2f s (%.1f MB)%s\n",
                static_cast<long long>(out["rows"].get<int64_t>()), p.String("format").c_str(),
                out["store_export_s"].get<double>(), out["store_export_bytes"].get<double>() / 1e6,
                out["grpc_export_s"].get<double>(), out["grpc_export_bytes"].get<double>() / 1e6,
                out["grpc_ok"].get<bool>() ? "" : " (gRPC FAILED)");
  }
  return out["grpc_ok"].get<bool>() ? 0 : 1;
}

}  // namespace vsurg::bench

namespace vsurg::bench {

namespace {

// A site in one process for a measurement: a control replica and `nodes` simulation nodes on
// the database at `uri`, each role with a store of its own, as separate processes would have;
// each node with a UDP endpoint on loopback when `udp` (else none: sessions are only created).
struct BenchSite {
  std::unique_ptr<db::Store> control_store;
  std::unique_ptr<server::cluster::ClusterSessions> control;
  // Each node's lease (its agent renews it; declared first, so it outlives the agents).
  std::vector<std::unique_ptr<server::Lease>> leases;
  std::vector<std::unique_ptr<db::Store>> node_stores;
  std::vector<std::unique_ptr<server::UdpEndpoint>> endpoints;
  std::vector<std::unique_ptr<server::SessionManager>> managers;
  std::vector<std::unique_ptr<server::cluster::NodeAgent>> agents;

  BenchSite(const std::string& uri, const server::cluster::ClusterOptions& co, int nodes,
            bool udp) {
    control_store = std::move(db::Store::Open({.path = uri})).value();
    control = std::move(server::cluster::ClusterSessions::Start(*control_store, co)).value();
    for (int i = 0; i < nodes; ++i) {
      node_stores.push_back(std::move(db::Store::Open({.path = uri})).value());
      leases.push_back(std::make_unique<server::Lease>());
      if (udp) {
        server::EndpointOptions eo;
        eo.address = "127.0.0.1";
        eo.port = 0;
        eo.realtime_priority = 0;
        eo.lease = leases.back().get();
        endpoints.push_back(std::move(server::UdpEndpoint::Create(eo)).value());
      }
      server::SessionManagerOptions so;
      so.node = "sim-" + std::to_string(i);
      so.lease = leases.back().get();
      so.max_live_sessions = 4096;
      so.max_sessions_per_user = 4096;
      managers.push_back(server::SessionManager::Open(*node_stores.back(),
                                                      udp ? endpoints.back().get() : nullptr, so)
                             .value());
      server::cluster::NodeOptions no;
      no.name = so.node;
      no.control = "127.0.0.1:" + std::to_string(control->port());
      no.udp_host = "127.0.0.1";
      no.udp_port = udp ? endpoints.back()->port() : 1;
      no.capacity = 4096;
      no.cluster = co;
      no.lease = leases.back().get();
      agents.push_back(std::move(server::cluster::NodeAgent::Start(*managers.back(), no)).value());
    }
  }
  // The nodes' sessions end, then the agents, the managers and the endpoints they use, then the
  // control replica.
  void Stop() {
    for (auto& m : managers) m->Shutdown();
    agents.clear();
    managers.clear();
    endpoints.clear();
    if (control) control->Shutdown();
  }
};

}  // namespace

int Placement(const std::vector<std::string>& args) {
  ArgParser p("vsurg-bench placement",
              "Session creation through the control role's placement (ClusterSessions over a real\n"
              "PostgreSQL, sim nodes' NodeService on loopback gRPC) against the all-in-one path\n"
              "(SessionManager::Create on an SQLite store), alternately in one run.");
  p.Option("postgres", ArgParser::Kind::kString,
           "a PostgreSQL server's maintenance database URI (deploy/postgres.sh)", true)
      .Option("nodes", ArgParser::Kind::kInt, "simulation nodes", false, "3")
      .Option("sessions", ArgParser::Kind::kInt, "sessions created on each path", false, "60")
      .Option("scene", ArgParser::Kind::kString, "scene", false, "arm-torsion")
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
  if (Status s = p.Parse(args); !s.ok()) {
    std::cerr << p.command() << ": " << s.error().field << ": " << s.error().message << "\n";
    return 2;
  }
  if (p.HelpRequested()) return std::cout << p.Help(), 0;
  const int nodes = p.Int("nodes"), sessions = p.Int("sessions");
  if (nodes < 1 || nodes > 16 || sessions < 1 || sessions > 1000) {
    std::cerr << p.command() << ": --nodes 1..16, --sessions 1..1000\n";
    return 2;
  }
  const std::string admin = p.String("postgres");
  const std::string name = "vsurg_placement_" + std::to_string(getpid());
  if (!PostgresAdmin(admin, "CREATE DATABASE " + name)) return 1;
  const std::string uri = admin.substr(0, admin.rfind('/') + 1) + name;
  const fs::path dir = TempDir("placement");
  const std::string token = "bench-cluster-token-0123456789";
  std::vector<double> placed_ms, local_ms;
  {
    server::cluster::ClusterOptions co;
    co.token = token;
    co.listen = "127.0.0.1:0";
    co.max_sessions_per_user = 1 << 20;
    BenchSite site(uri, co, nodes, false);
    auto& control = site.control;
    auto& control_store = site.control_store;
    for (int i = 0;
         i < 100 && control_store->ListNodes().value().size() < static_cast<size_t>(nodes); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    auto local_store = std::move(db::Store::Open({.path = (dir / "vsurg.db").string()})).value();
    server::SessionManagerOptions lo;
    lo.max_live_sessions = 4096;
    lo.max_sessions_per_user = 4096;
    auto local_owned = server::SessionManager::Open(*local_store, nullptr, lo).value();
    server::SessionManager& local = *local_owned;
    for (int k = 0; k < sessions; ++k) {
      const std::string trainee = "trainee-" + std::to_string(k);
      auto t0 = Clock::now();
      auto a = control->Create(trainee, p.String("scene"));
      placed_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      t0 = Clock::now();
      auto b = local.Create(trainee, p.String("scene"));
      local_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      if (!a.ok() || !b.ok()) {
        std::cerr << p.command() << ": " << (a.ok() ? b.error().message : a.error().message)
                  << "\n";
        return 1;
      }
    }
    local.Shutdown();
    site.Stop();
  }
  fs::remove_all(dir);
  PostgresAdmin(admin, "DROP DATABASE " + name + " WITH (FORCE)");
  const json out = {{"nodes", nodes},
                    {"sessions", sessions},
                    {"scene", p.String("scene")},
                    {"placed_p50_ms", Percentile(placed_ms, 0.5)},
                    {"placed_p99_ms", Percentile(placed_ms, 0.99)},
                    {"local_p50_ms", Percentile(local_ms, 0.5)},
                    {"local_p99_ms", Percentile(local_ms, 0.99)}};
  if (p.Flag("json")) {
    std::cout << out.dump() << "\n";
  } else {
    std::printf("create through placement (%d nodes, PostgreSQL): p50 %.2f ms  p99 %.2f ms\n",
                nodes, Percentile(placed_ms, 0.5), Percentile(placed_ms, 0.99));
    std::printf("create in one process (SQLite):                   p50 %.2f ms  p99 %.2f ms\n",
                Percentile(local_ms, 0.5), Percentile(local_ms, 0.99));
  }
  return 0;
}

}  // namespace vsurg::bench

namespace vsurg::bench {

// Simulated nodes: the heartbeats of `count` nodes (Acquire, then one Heartbeat per period each,
// spread evenly over the period) from `threads` client threads to one control replica.
struct HeartbeatLoad {
  std::atomic<uint64_t> sent{0}, failed{0};
  std::vector<double> latency_ms;  // merged after the run
  std::mutex mutex;
};

static void BeatNodes(int first, int count, int total, int port, int node_port,
                      const std::string& token, double period_s, Clock::time_point until,
                      HeartbeatLoad& load) {
  auto stub = v1::ClusterService::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));
  auto context = [&] {
    auto ctx = std::make_unique<grpc::ClientContext>();
    ctx->AddMetadata("authorization", "Bearer " + token);
    ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    return ctx;
  };
  std::vector<v1::NodeHeartbeat> beats(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    v1::NodeHeartbeat& b = beats[static_cast<size_t>(i)];
    b.set_name("sim-" + std::to_string(first + i));
    // Never called (no one watches, nothing is placed); a port that takes connections, so a
    // late node's probe decides nothing, as for a live node.
    b.set_grpc_address("127.0.0.1:" + std::to_string(node_port));
    b.set_udp_host("127.0.0.1");
    b.set_udp_port(1);
    b.set_capacity(24);
    b.set_instance("bench-" + std::to_string(first + i));
    v1::NodeLeaseReply reply;
    auto ctx = context();
    if (stub->Acquire(ctx.get(), b, &reply).ok()) b.set_epoch(reply.epoch());
  }
  std::vector<double> mine;
  const auto period = std::chrono::duration<double>(period_s);
  const auto start = Clock::now();
  for (int round = 0; Clock::now() < until; ++round)
    for (int i = 0; i < count && Clock::now() < until; ++i) {
      // Node first+i beats at its own phase of the period.
      const auto due = start + std::chrono::duration_cast<Clock::duration>(
                                   period * (round + static_cast<double>(first + i) / total));
      std::this_thread::sleep_until(due);
      v1::HeartbeatReply reply;
      auto ctx = context();
      const auto t0 = Clock::now();
      const bool ok = stub->Heartbeat(ctx.get(), beats[static_cast<size_t>(i)], &reply).ok();
      mine.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      load.sent.fetch_add(1);
      if (!ok) load.failed.fetch_add(1);
    }
  std::lock_guard lock(load.mutex);
  load.latency_ms.insert(load.latency_ms.end(), mine.begin(), mine.end());
}

// A loopback port listening and never accepting: the simulated nodes' internal port (the kernel
// completes the probes' handshakes). -1 when none can be had; `fd` is the socket to close.
int SilentListener(int& fd) {
  fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), len) != 0 ||
      ::listen(fd, 4096) != 0 || ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0)
    return -1;
  return ntohs(addr.sin_port);
}

struct HeartbeatRun {
  std::string uri, token;
  int nodes = 0, node_port = 0;
  double seconds = 0, store_lease_s = 0;
  bool in_memory = false;
};

// One configuration on its own database: the nodes acquire, then beat through the measured
// window from four threads; the store's writes and commits counted over it.
json HeartbeatRound(const HeartbeatRun& run) {
  auto store = std::move(db::Store::Open({.path = run.uri})).value();
  server::cluster::ClusterOptions co;
  co.token = run.token;
  co.listen = "127.0.0.1:0";
  // Every heartbeat written: a store lease no longer than the timeout and two periods.
  co.store_lease_s = run.in_memory ? run.store_lease_s : co.heartbeat_timeout_s;
  auto control = std::move(server::cluster::ClusterSessions::Start(*store, co)).value();
  const int threads = 4;
  HeartbeatLoad load;
  // Acquisitions first (one transaction each), then the measured window.
  const double settle = 2 + run.nodes / 500.0;
  const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(settle + run.seconds));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    const int first = run.nodes * t / threads, last = run.nodes * (t + 1) / threads;
    pool.emplace_back(BeatNodes, first, last - first, run.nodes, control->port(), run.node_port,
                      run.token, co.heartbeat_period_s, until, std::ref(load));
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(settle));
  const db::StoreStats a = store->stats();
  const uint64_t sent0 = load.sent.load();
  std::this_thread::sleep_for(std::chrono::duration<double>(run.seconds));
  const db::StoreStats b = store->stats();
  const uint64_t sent1 = load.sent.load();
  for (auto& t : pool) t.join();
  const auto listed = store->ListNodes().value();
  size_t down = 0;
  for (const auto& n : listed) down += n.down;
  control->Shutdown();
  return {{"mode", run.in_memory ? "in_memory" : "every_beat"},
          {"store_lease_s", co.store_lease_s},
          {"nodes", run.nodes},
          {"heartbeats_per_s", static_cast<double>(sent1 - sent0) / run.seconds},
          {"store_writes_per_s", static_cast<double>(b.jobs - a.jobs) / run.seconds},
          {"store_commits_per_s", static_cast<double>(b.commits - a.commits) / run.seconds},
          {"failed", load.failed.load()},
          {"nodes_down", down},
          {"beat_p50_ms", Percentile(load.latency_ms, 0.5)},
          {"beat_p99_ms", Percentile(load.latency_ms, 0.99)}};
}

void PrintHeartbeatRound(const json& r) {
  std::printf(
      "%-10s store lease %4.1f s, %d nodes: %7.0f heartbeats/s  %7.1f store writes/s "
      "(%6.1f commits/s)  heartbeat p50 %.2f ms p99 %.2f ms  failed %llu  down %zu\n",
      r["mode"].get<std::string>().c_str(), r["store_lease_s"].get<double>(), r["nodes"].get<int>(),
      r["heartbeats_per_s"].get<double>(), r["store_writes_per_s"].get<double>(),
      r["store_commits_per_s"].get<double>(), r["beat_p50_ms"].get<double>(),
      r["beat_p99_ms"].get<double>(), static_cast<unsigned long long>(r["failed"].get<uint64_t>()),
      r["nodes_down"].get<size_t>());
}

int Heartbeats(const std::vector<std::string>& args) {
  ArgParser p("vsurg-bench heartbeats",
              "The control plane's store writes per second for many simulated nodes' heartbeats:\n"
              "every heartbeat written (the store lease equal to the heartbeat timeout) against\n"
              "heartbeats kept in memory with a store lease (--store-lease), alternately in one\n"
              "run, each on a fresh PostgreSQL database.");
  p.Option("postgres", ArgParser::Kind::kString,
           "a PostgreSQL server's maintenance database URI (deploy/postgres.sh)", true)
      .Option("nodes", ArgParser::Kind::kInt, "simulated nodes", false, "1000")
      .Within({1, 5000})
      .Option("seconds", ArgParser::Kind::kDouble, "measured seconds per configuration", false,
              "15")
      .Within({2, 600})
      .Option("store-lease", ArgParser::Kind::kDouble, "the in-memory configuration's, s", false,
              "10")
      .Option("rounds", ArgParser::Kind::kInt, "alternations of the two configurations", false, "2")
      .Within({1, 10})
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  const std::string admin = p.String("postgres");
  int listener = -1;
  const int node_port = SilentListener(listener);
  if (node_port < 0) return std::cerr << p.command() << ": cannot listen on loopback\n", 1;
  json runs = json::array();
  for (int round = 0; round < p.Int("rounds"); ++round)
    for (const bool in_memory : {false, true}) {
      const std::string name = "vsurg_beats_" + std::to_string(getpid()) + "_" +
                               std::to_string(round) + (in_memory ? "m" : "w");
      if (!PostgresAdmin(admin, "CREATE DATABASE " + name)) return 1;
      const json r = HeartbeatRound({admin.substr(0, admin.rfind('/') + 1) + name,
                                     "bench-cluster-token-0123456789", p.Int("nodes"), node_port,
                                     p.Double("seconds"), p.Double("store-lease"), in_memory});
      PostgresAdmin(admin, "DROP DATABASE " + name + " WITH (FORCE)");
      runs.push_back(r);
      if (!p.Flag("json")) PrintHeartbeatRound(r);
    }
  ::close(listener);
  if (p.Flag("json")) std::cout << json{{"runs", runs}}.dump() << "\n";
  return 0;
}

}  // namespace vsurg::bench

namespace vsurg::bench {

namespace {
// The control replica's counter of telemetry bytes received (server/ops metrics text).
double ReceivedBytes(const server::cluster::ClusterSessions& c) {
  server::ops::MetricsText m;
  c.Collect(m);
  const std::string key = "\nvsurg_telemetry_received_bytes_total ";
  const size_t at = m.str().find(key);
  return at == std::string::npos ? 0 : std::stod(m.str().substr(at + key.size()));
}

// Every session's station: the stylus pressing 2–6 mm into the sphere's top and back once a
// second, 500 Hz, so each surface is deformed and moving (a surface state holds the vertices away
// from rest; a stream sends one per new frame). Until `driving` falls.
void PressEverySession(const std::vector<server::CreatedSession>& created,
                       const std::atomic<bool>& driving) {
  boost::asio::io_context io;
  boost::asio::ip::udp::socket sock(io, boost::asio::ip::udp::v4());
  wire::Codec codec;
  std::vector<uint8_t> buf(wire::kMaxDatagram);
  const auto t0 = Clock::now();
  for (uint64_t seq = 1; driving; ++seq) {
    for (const server::CreatedSession& c : created) {
      wire::StylusMessage m;
      m.sample.time = std::chrono::duration<double>(Clock::now() - t0).count();
      m.sample.position = Eigen::Vector3d(0, 0, 0.046 + 0.002 * std::sin(6.2832 * m.sample.time));
      const size_t n = codec.EncodeStylus(m,
                                          {wire::kProtocolVersion, wire::PayloadType::kStylusState,
                                           static_cast<uint64_t>(c.record.id), seq},
                                          wire::Authenticator(c.key), buf);
      boost::system::error_code ec;
      sock.send_to(boost::asio::buffer(buf.data(), n),
                   {boost::asio::ip::make_address(c.udp_host), c.udp_port}, 0, ec);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

// The former way, bytes per second: every node's whole telemetry at the telemetry rate.
Expected<double> PolledBytesPerSecond(db::Store& control_store, const std::string& token,
                                      double telemetry_hz, double seconds) {
  std::vector<std::unique_ptr<v1::NodeService::Stub>> stubs;
  const auto listed = control_store.ListNodes();
  if (!listed.ok()) return listed.error();
  for (const auto& n : *listed)
    stubs.push_back(v1::NodeService::NewStub(
        grpc::CreateChannel(n.grpc_address, grpc::InsecureChannelCredentials())));
  double bytes = 0;
  const auto window = std::chrono::duration<double>(seconds);
  const auto t0 = Clock::now();
  for (auto next = t0; Clock::now() - t0 < window;) {
    for (auto& stub : stubs) {
      grpc::ClientContext ctx;
      ctx.AddMetadata("authorization", "Bearer " + token);
      v1::NodeTelemetry reply;
      if (stub->Telemetry(&ctx, {}, &reply).ok()) bytes += reply.ByteSizeLong();
    }
    next += std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / telemetry_hz));
    std::this_thread::sleep_until(next);
  }
  return bytes / seconds;
}

// The streams, bytes per second received while `watched` (0: the overview) are subscribed.
double StreamedBytesPerSecond(server::cluster::ClusterSessions& control,
                              const std::vector<uint64_t>& watched, double seconds) {
  std::vector<uint64_t> tokens;
  for (uint64_t id : watched)
    tokens.push_back(control.Subscribe(id, [](const std::vector<sim::SessionTelemetry>&, bool) {}));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the streams open
  const double b0 = ReceivedBytes(control);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const double b1 = ReceivedBytes(control);
  for (uint64_t t : tokens) control.Unsubscribe(t);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // and close
  return (b1 - b0) / seconds;
}

}  // namespace

int TelemetryBench(const std::vector<std::string>& args) {
  ArgParser p("vsurg-bench telemetry",
              "What a control replica receives from the nodes for its watchers, per second: the\n"
              "former poll (NodeService.Telemetry on every node at the telemetry rate, every\n"
              "session with its surface) against the streams (NodeService.Watch: an overview\n"
              "watcher, then one session viewed besides), in one run on a real PostgreSQL.");
  p.Option("postgres", ArgParser::Kind::kString,
           "a PostgreSQL server's maintenance database URI (deploy/postgres.sh)", true)
      .Option("nodes", ArgParser::Kind::kInt, "simulation nodes", false, "3")
      .Within({1, 16})
      .Option("sessions", ArgParser::Kind::kInt, "live sessions per node", false, "8")
      .Within({1, 64})
      .Option("seconds", ArgParser::Kind::kDouble, "seconds per way", false, "5")
      .Within({1, 3600})
      .Option("scene", ArgParser::Kind::kString, "scene (a sphere, pressed 2-6 mm at its top)",
              false, "sphere-palpation-1024");
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  const int nodes = p.Int("nodes"), per_node = p.Int("sessions");
  const double seconds = p.Double("seconds");
  const std::string admin = p.String("postgres");
  const std::string name = "vsurg_telemetry_" + std::to_string(getpid());
  if (!PostgresAdmin(admin, "CREATE DATABASE " + name)) return 1;
  const std::string uri = admin.substr(0, admin.rfind('/') + 1) + name;
  const std::string token = "bench-cluster-token-0123456789";
  double poll_bps = 0, overview_bps = 0, viewed_bps = 0;
  {
    server::cluster::ClusterOptions co;
    co.token = token;
    co.listen = "127.0.0.1:0";
    co.max_sessions_per_user = 1 << 20;
    BenchSite site(uri, co, nodes, true);
    std::vector<uint64_t> ids;
    std::vector<server::CreatedSession> created;
    for (int k = 0; k < nodes * per_node; ++k) {
      auto c = site.control->Create("trainee-" + std::to_string(k), p.String("scene"));
      if (!c.ok()) return std::cerr << p.command() << ": " << c.error().message << "\n", 1;
      if (auto st = site.control->Start(c->record.id); !st.ok())
        return std::cerr << p.command() << ": " << st.error().message << "\n", 1;
      ids.push_back(static_cast<uint64_t>(c->record.id));
      created.push_back(*c);
    }
    std::atomic<bool> driving{true};
    std::thread stations(PressEverySession, std::cref(created), std::cref(driving));
    std::this_thread::sleep_for(std::chrono::seconds(1));  // pressed in
    auto polled = PolledBytesPerSecond(*site.control_store, token, co.telemetry_hz, seconds);
    if (polled.ok()) {
      poll_bps = *polled;
      overview_bps = StreamedBytesPerSecond(*site.control, {0}, seconds);
      viewed_bps = StreamedBytesPerSecond(*site.control, {0, ids.front()}, seconds);
    }
    driving = false;
    stations.join();
    site.Stop();
    if (!polled.ok()) return std::cerr << p.command() << ": " << polled.error().message << "\n", 1;
  }
  PostgresAdmin(admin, "DROP DATABASE " + name + " WITH (FORCE)");
  std::printf(
      "%d nodes x %d sessions (%s), %.0f Hz: poll of every node %.1f kB/s; streams, overview "
      "%.1f kB/s; overview + one session viewed %.1f kB/s\n",
      nodes, per_node, p.String("scene").c_str(), server::cluster::ClusterOptions{}.telemetry_hz,
      poll_bps / 1e3, overview_bps / 1e3, viewed_bps / 1e3);
  return 0;
}

}  // namespace vsurg::bench
