// AdminService over gRPC: users, tokens, weight sets, the streamed export, backups.
#include <condition_variable>
#include <mutex>
#include <thread>

#include "common/core/realtime.h"
#include "server/control/grpc_common.h"

namespace vsurg::server::grpcapi {
namespace {

using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;

// Streams an export: a producer thread formats chunks and waits for each write to complete
// (flow control); the reactor callbacks only flip flags under the mutex.
class ExportReactor final : public grpc::ServerWriteReactor<v1::ExportChunk> {
 public:
  ExportReactor(db::Store& store, db::ExportFilter filter, db::ExportFormat format) {
    thread_ = std::thread([this, &store, filter, format] {
      NameThisThread("vsurg-export");
      Status s = store.Export(filter, format, [this](std::string_view chunk) {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [this] { return !writing_ || broken_; });
        if (broken_) return false;
        chunk_.set_data(chunk.data(), chunk.size());
        writing_ = true;
        lock.unlock();
        StartWrite(&chunk_);
        return true;
      });
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return !writing_ || broken_; });
      const bool broken = broken_;
      lock.unlock();
      Finish(broken ? grpc::Status::CANCELLED : ToGrpcStatus(s));
    });
  }
  void OnWriteDone(bool ok) override {
    {
      std::lock_guard lock(mutex_);
      writing_ = false;
      if (!ok) broken_ = true;
    }
    cv_.notify_all();
  }
  void OnCancel() override {
    {
      std::lock_guard lock(mutex_);
      broken_ = true;
    }
    cv_.notify_all();
  }
  void OnDone() override {
    thread_.join();  // its last act was Finish
    delete this;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool writing_ = false, broken_ = false;
  v1::ExportChunk chunk_;
  std::thread thread_;
};

class AdminServiceImpl final : public v1::AdminService::CallbackService {
 public:
  AdminServiceImpl(Domain& d, CallPool& pool) : d_(d), pool_(pool) {}

  ServerUnaryReactor* CreateUser(CallbackServerContext* ctx, const v1::CreateUserRequest* req,
                                 v1::User* resp) override {
    return Unary(
        d_, pool_, ctx, Method::kAdminCreateUser, [=, this](const db::Principal& p) -> Status {
          auto u = server::CreateUser(d_, p, req->name(), RoleFromProto(req->role()), req->group());
          if (!u.ok()) return u.error();
          ToProto(*u, resp);
          return Status::Ok();
        });
  }

  ServerUnaryReactor* IssueToken(CallbackServerContext* ctx, const v1::IssueTokenRequest* req,
                                 v1::IssueTokenResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kAdminIssueToken,
                 [=, this](const db::Principal& p) -> Status {
                   auto t = server::IssueToken(d_, p, req->user(), req->label());
                   if (!t.ok()) return t.error();
                   resp->set_token(*t);
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* RevokeTokens(CallbackServerContext* ctx, const v1::UserRef* req,
                                   v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kAdminRevokeTokens, [=, this](const db::Principal& p) {
      return server::RevokeTokens(d_, p, req->name());
    });
  }

  ServerUnaryReactor* SetDisabled(CallbackServerContext* ctx, const v1::SetDisabledRequest* req,
                                  v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kAdminSetDisabled, [=, this](const db::Principal& p) {
      return server::SetDisabled(d_, p, req->name(), req->disabled());
    });
  }

  ServerUnaryReactor* ListUsers(CallbackServerContext* ctx, const v1::ListUsersRequest*,
                                v1::ListUsersResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kAdminListUsers,
                 [=, this](const db::Principal& p) -> Status {
                   auto users = server::ListUsers(d_, p);
                   if (!users.ok()) return users.error();
                   for (const db::UserRecord& u : *users) ToProto(u, resp->add_users());
                   return Status::Ok();
                 });
  }

  ServerUnaryReactor* PutWeightSet(CallbackServerContext* ctx, const v1::WeightSet* req,
                                   v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kAdminPutWeightSet, [=, this](const db::Principal& p) {
      return server::PutWeightSet(d_, p, req->json());
    });
  }

  ServerUnaryReactor* ListWeightSets(CallbackServerContext* ctx, const v1::ListWeightSetsRequest*,
                                     v1::ListWeightSetsResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kAdminListWeightSets,
                 [=, this](const db::Principal& p) -> Status {
                   auto names = server::ListWeightSets(d_, p);
                   if (!names.ok()) return names.error();
                   for (const std::string& n : *names) resp->add_names(n);
                   return Status::Ok();
                 });
  }

  grpc::ServerWriteReactor<v1::ExportChunk>* Export(CallbackServerContext* ctx,
                                                    const v1::ExportRequest* req) override {
    auto p = Authorize(d_, ctx, Method::kAdminExport);
    if (!p.ok()) return new Refuse<v1::ExportChunk>(ToGrpcStatus(p.error()));
    auto plan =
        PlanExport(*p, req->format(), req->from_us(), req->to_us(), req->trainee(), req->session());
    if (!plan.ok()) return new Refuse<v1::ExportChunk>(ToGrpcStatus(plan.error()));
    return new ExportReactor(d_.store, plan->filter, plan->format);
  }

  ServerUnaryReactor* Backup(CallbackServerContext* ctx, const v1::BackupRequest* req,
                             v1::Empty*) override {
    return Unary(d_, pool_, ctx, Method::kAdminBackup,
                 [=, this](const db::Principal& p) { return server::Backup(d_, p, req->path()); });
  }

 private:
  Domain& d_;
  CallPool& pool_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewAdminService(Domain& d, CallPool& pool) {
  return std::make_unique<AdminServiceImpl>(d, pool);
}

}  // namespace vsurg::server::grpcapi
