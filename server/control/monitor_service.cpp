// MonitorService over gRPC: one stream per watcher, fed by the sessions' sampler thread.
#include <chrono>
#include <map>
#include <mutex>

#include "server/control/grpc_common.h"

namespace vsurg::server::grpcapi {
namespace {

using grpc::CallbackServerContext;

// One monitor stream. The sessions' sampler thread delivers the latest telemetry into a mailbox
// (one message per session, latest wins); a write starts only when none is in flight. Reactor
// callbacks take the mailbox mutex only to swap messages and never call into gRPC with it held.
class WatchReactor final : public grpc::ServerWriteReactor<v1::Telemetry> {
 public:
  WatchReactor(Sessions& sessions, uint64_t session, double rate_hz)
      : sessions_(sessions), interval_s_(1.0 / rate_hz) {
    token_ = sessions_.Subscribe(session, [this](const std::vector<SessionTelemetry>& list,
                                                 bool ended) { Deliver(list, ended); });
  }

  void OnWriteDone(bool ok) override {
    std::unique_lock lock(mutex_);
    writing_ = false;
    if (!ok) {
      FinishLocked(lock, grpc::Status(grpc::StatusCode::UNAVAILABLE, "the monitor went away"));
      return;
    }
    Pump(lock);
  }

  void OnCancel() override {
    std::unique_lock lock(mutex_);
    FinishLocked(lock, grpc::Status::CANCELLED);
  }

  void OnDone() override {
    sessions_.Unsubscribe(token_);  // waits for a delivery in progress
    delete this;
  }

 private:
  void Deliver(const std::vector<SessionTelemetry>& list, bool ended) {
    std::unique_lock lock(mutex_);
    if (finished_) return;
    if (ended) {
      end_ = true;
    } else {
      const auto now = std::chrono::steady_clock::now();
      if (std::chrono::duration<double>(now - last_).count() < interval_s_ * 0.9) return;
      last_ = now;
      for (const SessionTelemetry& t : list) convert::ToProto(t, &pending_[t.id]);
    }
    Pump(lock);
  }

  void Pump(std::unique_lock<std::mutex>& lock) {
    if (writing_ || finished_) return;
    if (!pending_.empty()) {
      inflight_.Swap(&pending_.begin()->second);
      pending_.erase(pending_.begin());
      writing_ = true;
      lock.unlock();
      StartWrite(&inflight_);
      return;
    }
    if (end_) FinishLocked(lock, grpc::Status::OK);  // the session ended: the stream ends
  }

  void FinishLocked(std::unique_lock<std::mutex>& lock, const grpc::Status& s) {
    if (finished_) return;
    finished_ = true;
    lock.unlock();
    Finish(s);
  }

  Sessions& sessions_;
  double interval_s_;
  uint64_t token_ = 0;
  std::mutex mutex_;
  std::map<uint64_t, v1::Telemetry> pending_;
  v1::Telemetry inflight_;
  bool writing_ = false, finished_ = false, end_ = false;
  std::chrono::steady_clock::time_point last_{};
};

class MonitorServiceImpl final : public v1::MonitorService::CallbackService {
 public:
  explicit MonitorServiceImpl(Domain& d) : d_(d) {}

  grpc::ServerWriteReactor<v1::Telemetry>* Watch(CallbackServerContext* ctx,
                                                 const v1::WatchRequest* req) override {
    auto p = Authorize(d_, ctx, Method::kMonitorWatch);
    if (!p.ok()) return new Refuse<v1::Telemetry>(ToGrpcStatus(p.error()));
    auto hz = CheckWatch(d_, *p, req->session_id(), req->rate_hz());
    if (!hz.ok()) return new Refuse<v1::Telemetry>(ToGrpcStatus(hz.error()));
    return new WatchReactor(d_.sessions, req->session_id(), *hz);
  }

 private:
  Domain& d_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewMonitorService(Domain& d) {
  return std::make_unique<MonitorServiceImpl>(d);
}

}  // namespace vsurg::server::grpcapi
