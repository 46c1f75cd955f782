// The store's private parts, shared by its source files (db/store.cpp: opening, the writer
// thread, backup; store_users.cpp, store_sessions.cpp, store_evaluations.cpp, store_export.cpp:
// one concept each). Not installed, not included outside db/.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "db/connection.h"
#include "db/store.h"

namespace vsurg::db {

struct Store::Impl {
  struct Pending {
    Job job;
    std::function<void(Status)> done;
    // One statement that is a transaction by itself (a lease renewal): run in autocommit, outside
    // the batch's transaction, so it costs its server one round trip instead of five (BEGIN,
    // SAVEPOINT, the statement, RELEASE, COMMIT).
    bool alone = false;
  };

  StoreOptions options;
  bool read_only = false;              // OpenReadOnly: no writer, no writes
  std::unique_ptr<Connection> writer;  // writer thread only (after Open)
  std::mutex queue_mutex;
  std::condition_variable queue_cv;
  std::deque<Pending> queue;
  bool stopping = false;
  std::thread thread;

  // Placement's own read-write connection (store_placement.cpp): a reservation never waits in
  // the writer's queue behind a batch and its commit. Opened on first use, renewed when lost.
  std::mutex placement_mutex;
  std::unique_ptr<Connection> placement;
  // `job` on that connection, under its mutex.
  Status OnPlacementConnection(const Job& job);

  std::mutex pool_mutex;
  std::vector<std::unique_ptr<Connection>> pool;

  mutable std::mutex stats_mutex;
  StoreStats stats;

  void WriterLoop();
  void RunBatch(std::vector<Pending>& batch);
  void RunAlone(Pending& job);  // Pending::alone
  // A job run alone (Pending::alone), waited for: one statement in autocommit, or a job that
  // makes its own transaction.
  Status WriteAlone(Job job);
  void Post(Pending job);  // queues a job, or fails it at once (read-only, stopping)
  void CountCommit(double seconds, size_t jobs, uint64_t failed, bool commit_failed);

  // A pooled read connection, returned on scope exit.
  struct Reader {
    Impl* impl;
    std::unique_ptr<Connection> c;
    Reader(Impl* i, std::unique_ptr<Connection> conn) : impl(i), c(std::move(conn)) {}
    Reader(Reader&& o) noexcept : impl(o.impl), c(std::move(o.c)) {}
    Reader& operator=(Reader&&) = delete;
    ~Reader() {
      if (c && !c->Broken()) {  // a lost connection is dropped; the next read opens another
        std::lock_guard lock(impl->pool_mutex);
        impl->pool.push_back(std::move(c));
      }
    }
    Connection& operator*() { return *c; }
  };
  Expected<Reader> Read() {
    {
      std::lock_guard lock(pool_mutex);
      if (!pool.empty()) {
        Reader r{this, std::move(pool.back())};
        pool.pop_back();
        return r;
      }
    }
    auto c = Connection::Open(options.path, Connection::Mode::kReadOnly, options.busy_timeout_ms);
    if (!c.ok()) return c.error();
    return Reader{this, std::move(c).value()};
  }
};

// Runs a prepared statement with binds; convenience for the many one-shot writes.
template <class Bind>
Status RunSql(Connection& c, const std::string& sql, Bind&& bind) {
  auto st = c.Prepare(sql);
  if (!st.ok()) return st.error();
  bind(**st);
  return (*st)->Run();
}

// The trial_metrics columns ReadTrialMetrics reads, in its order.
inline constexpr const char* kTrialMetricColumns =
    "completed, completion_time_s, task_error, peak_force_n, time_over_force_limit_s, "
    "path_length_m, rms_jerk, overload_events, duration_s, score, raw_score, caps, "
    "station_peak_force_n, station_time_over_limit_s, link_rtt_ms, link_jitter_ms, "
    "link_loss_ratio, link_rate_hz, guided_share, guided_alpha, lumps, lumps_found, false_marks, "
    "localisation_error_m, coverage, mean_force_n, depth_error_m, path_deviation_m, punctures, "
    "extra_punctures, back_wall_breaches, lateral_strain, cut_deviation_max_m, cut_outside_m, "
    "torn_length_m, cut_lifts";
// A row's trial metrics from column `first` on (kTrialMetricColumns).
scoring::TrialMetrics ReadTrialMetrics(const Statement& q, int first);

// The id in column 0 of the first row of `sql` bound to `key`, if any.
Expected<std::optional<int64_t>> LookupId(Connection& c, const std::string& sql,
                                          std::string_view key);

// Binds the three live states' names at ?first, ?first+1, ?first+2.
void BindLiveStates(Statement& q, int first);

// Inside a write job: the reservation `token` (Store::ReservePlacement) ends, replaced by the
// session row the same job writes ("" for none).
Status EndPlacement(Connection& c, const std::string& token);

}  // namespace vsurg::db
