#include "db/store.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <future>

#include "common/core/realtime.h"
#include "db/migrations.h"
#include "db/store_impl.h"

namespace vsurg::db {

Expected<std::optional<int64_t>> LookupId(Connection& c, const std::string& sql,
                                          std::string_view key) {
  auto st = c.Prepare(sql);
  if (!st.ok()) return st.error();
  (*st)->Bind(1, key);
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  std::optional<int64_t> id;
  if (*row) id = (*st)->Int(0);
  (*st)->Reset();
  return id;
}

void Store::Impl::WriterLoop() {
  std::vector<Pending> batch;
  for (;;) {
    {
      std::unique_lock lock(queue_mutex);
      queue_cv.wait(lock, [&] { return stopping || !queue.empty(); });
      if (queue.empty()) return;  // stopping and drained
      while (!queue.empty() && static_cast<int>(batch.size()) < options.max_batch) {
        batch.push_back(std::move(queue.front()));
        queue.pop_front();
      }
    }
    RunBatch(batch);
    batch.clear();
  }
}

void Store::Impl::RunBatch(std::vector<Pending>& batch) {
  // A shared store's server may have restarted since the last batch: reconnect first (the jobs
  // of a batch that met the loss failed with kUnavailable and were never acknowledged).
  if (writer->Broken()) {
    auto again =
        Connection::Open(options.path, Connection::Mode::kReadWrite, options.busy_timeout_ms);
    if (again.ok()) writer = std::move(again).value();
  }
  // The jobs that are a transaction each go first, then the rest in one group commit.
  for (Pending& p : batch)
    if (p.alone) RunAlone(p);
  std::erase_if(batch, [](const Pending& p) { return p.alone; });
  if (batch.empty()) return;
  std::vector<Status> results(batch.size());
  const auto t0 = std::chrono::steady_clock::now();
  Status begin = writer->BeginWrite();
  uint64_t failed = 0;
  bool commit_failed = false;
  if (!begin.ok()) {
    for (auto& r : results) r = begin;
    failed = batch.size();
    commit_failed = true;
  } else {
    for (size_t i = 0; i < batch.size(); ++i) {
      Status s = writer->Exec("SAVEPOINT job");
      if (s.ok()) {
        s = batch[i].job(*writer);
        if (!s.ok()) {
          (void)writer->Exec("ROLLBACK TO job");
          ++failed;
        }
        (void)writer->Exec("RELEASE job");
      }
      results[i] = std::move(s);
    }
    if (Status commit = writer->Exec("COMMIT"); !commit.ok()) {
      (void)writer->Exec("ROLLBACK");
      commit_failed = true;
      for (auto& r : results)
        if (r.ok()) r = commit, ++failed;
    }
  }
  CountCommit(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
              batch.size(), failed, commit_failed);
  // Only now, after the COMMIT (fsync), is anything acknowledged.
  for (size_t i = 0; i < batch.size(); ++i)
    if (batch[i].done) batch[i].done(std::move(results[i]));
}

void Store::Impl::RunAlone(Pending& p) {
  const auto t0 = std::chrono::steady_clock::now();
  Status s = p.job(*writer);  // autocommit: durable when the statement returns
  CountCommit(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1,
              s.ok() ? 0 : 1, false);
  if (p.done) p.done(std::move(s));
}

Status Store::Impl::WriteAlone(Job job) {
  std::promise<Status> written;
  auto done = written.get_future();
  Pending p;
  p.alone = true;
  p.job = std::move(job);
  p.done = [&written](Status s) { written.set_value(std::move(s)); };
  Post(std::move(p));
  return done.get();
}

void Store::Impl::CountCommit(double took, size_t jobs, uint64_t failed, bool commit_failed) {
  std::lock_guard lock(stats_mutex);
  ++stats.commits;
  stats.jobs += jobs;
  stats.failed_jobs += failed;
  stats.failed_commits += commit_failed;
  const auto& bounds = StoreStats::kCommitBounds;
  stats.commit_buckets[static_cast<size_t>(std::lower_bound(bounds.begin(), bounds.end(), took) -
                                           bounds.begin())]++;
  stats.commit_seconds += took;
  stats.writer_round_trips = writer->RoundTrips();
}

Store::Store(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Store::~Store() {
  {
    std::lock_guard lock(impl_->queue_mutex);
    impl_->stopping = true;
  }
  impl_->queue_cv.notify_all();
  if (impl_->thread.joinable()) impl_->thread.join();
}

int Store::SchemaVersion() {
  return static_cast<int>(Migrations().size());
}

Expected<std::unique_ptr<Store>> Store::Open(const StoreOptions& options) {
  if (options.path.empty())
    return InvalidArgument("path", "a database file or a postgresql:// URI is required");
  if (options.max_batch < 1 || options.read_connections < 1)
    return InvalidArgument("max_batch", "batch and pool sizes must be >= 1");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  auto writer =
      Connection::Open(options.path, Connection::Mode::kReadWrite, options.busy_timeout_ms);
  if (!writer.ok()) return writer.error();
  impl->writer = std::move(writer).value();
  if (Status s = Migrate(*impl->writer); !s.ok()) return s.error();
  std::unique_ptr<Store> store(new Store(std::move(impl)));
  store->impl_->thread = std::thread([s = store->impl_.get()] {
    NameThisThread("vsurg-store");
    s->WriterLoop();
  });
  return store;
}

Expected<std::unique_ptr<Store>> Store::OpenReadOnly(const std::string& path) {
  if (path.empty())
    return InvalidArgument("path", "a database file or a postgresql:// URI is required");
  std::error_code ec;
  if (BackendOf(path) == Backend::kSqlite && !std::filesystem::is_regular_file(path, ec))
    return Error{ErrorCode::kNotFound, "no database file " + path, "db"};
  auto impl = std::make_unique<Impl>();
  impl->options.path = path;
  impl->read_only = true;
  auto c = Connection::Open(path, Connection::Mode::kReadOnly, impl->options.busy_timeout_ms);
  if (!c.ok()) return c.error();
  auto version = c.value()->SchemaVersion();
  if (!version.ok())
    return Error{version.error().code, path + ": " + version.error().message, "db"};
  const int v = *version;
  if (v != SchemaVersion())
    return Error{ErrorCode::kFailedPrecondition,
                 path + " is at schema version " + std::to_string(v) + ", this binary reads " +
                     std::to_string(SchemaVersion()) +
                     (v < SchemaVersion() ? " (a vsurg-server of this version migrates it when it "
                                            "opens the file)"
                                          : " (use a newer vsurg)"),
                 "db"};
  impl->pool.push_back(std::move(c).value());
  return std::unique_ptr<Store>(new Store(std::move(impl)));
}

bool Store::read_only() const {
  return impl_->read_only;
}

void Store::Impl::Post(Pending job) {
  {
    std::lock_guard lock(queue_mutex);
    if (read_only) {
      if (job.done)
        job.done(Error{ErrorCode::kFailedPrecondition, "the store was opened read-only", ""});
      return;
    }
    if (stopping) {
      if (job.done) job.done(Error{ErrorCode::kUnavailable, "the store is shutting down", ""});
      return;
    }
    queue.push_back(std::move(job));
  }
  queue_cv.notify_one();
}

void Store::WriteAsync(Job job, std::function<void(Status)> done) {
  impl_->Post({std::move(job), std::move(done)});
}

Status Store::Write(Job job) {
  std::promise<Status> p;
  auto f = p.get_future();
  WriteAsync(std::move(job), [&p](Status s) { p.set_value(std::move(s)); });
  return f.get();
}

StoreStats Store::stats() const {
  StoreStats out;
  {
    std::lock_guard lock(impl_->stats_mutex);
    out = impl_->stats;
  }
  std::lock_guard lock(impl_->queue_mutex);
  out.queued = impl_->queue.size();
  return out;
}

Status Store::Backup(const std::string& destination) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  return (**r).Backup(destination);
}

Expected<std::string> Store::IntegrityCheck() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  return (**r).IntegrityCheck();
}

Backend Store::backend() const {
  return BackendOf(impl_->options.path);
}

}  // namespace vsurg::db
