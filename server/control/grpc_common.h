// What the gRPC services share: the one mapping of our errors to gRPC statuses, the bearer
// token from call metadata, the unary-call shape, and the session messages. Private to
// server/control/ (generated types appear here, never in a header outside this folder).
#pragma once

#include <grpcpp/grpcpp.h>

#include "server/control/call_pool.h"
#include "server/domain/api.h"
#include "server/session/caller_deadline.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::server::grpcapi {

namespace v1 = vsurg::v1;

grpc::Status ToGrpcStatus(const Error& e);
grpc::Status ToGrpcStatus(const Status& s);

// The caller of this call (its `authorization` metadata), when their role may call `m`.
Expected<db::Principal> Authorize(Domain& d, grpc::CallbackServerContext* ctx, Method m);

// A unary call: authenticated and checked against the matrix, then its body (a domain call and
// the response's translation), both on the control plane's CallPool (server/control/call_pool.h:
// never on gRPC's own few callback threads, which a call waiting on a node would hold), with the
// caller's deadline bounding what it asks of a node. The body runs after the handler has
// returned: it captures by value (`[=, this]`: the request and response pointers, which gRPC
// keeps until the call is finished), never by reference.
template <class Body>
grpc::ServerUnaryReactor* Unary(Domain& d, CallPool& pool, grpc::CallbackServerContext* ctx,
                                Method m, Body body) {
  grpc::ServerUnaryReactor* r = ctx->DefaultReactor();
  pool.Post([&d, ctx, m, r, body = std::move(body)]() mutable {
    const CallerDeadline deadline(ctx->deadline());
    auto p = Authorize(d, ctx, m);
    r->Finish(p.ok() ? ToGrpcStatus(body(*p)) : ToGrpcStatus(p.error()));
  });
  return r;
}

// A server-streaming call refused before it starts: it only reports the status.
template <class Message>
class Refuse final : public grpc::ServerWriteReactor<Message> {
 public:
  explicit Refuse(const grpc::Status& status) { this->Finish(status); }
  void OnDone() override { delete this; }
};

void ToProto(const db::SessionRecord& r, v1::Session* out);
void ToProto(const SessionView& v, v1::Session* out);
std::optional<db::Role> RoleFromProto(v1::Role r);
v1::Role RoleToProto(db::Role r);
void ToProto(const db::UserRecord& u, v1::User* out);
// Four-handed training: the mode (GUIDE_MODE_NONE and values this build does not know: kNone)
// and who is in a session with what they asked for, both ways (the public API and the nodes').
sim::GuideMode GuideModeFromProto(v1::GuideMode m);
v1::GuideMode GuideModeToProto(sim::GuideMode m);  // the same wire values
void ToProto(const SessionGuidance& g, v1::Guidance* out);
SessionGuidance FromProto(const v1::Guidance& g);

// The services, registered by ControlPlane::Start; each lives as long as `d`.
// Their unary calls run on `pool`, which outlives them.
std::unique_ptr<grpc::Service> NewSessionService(Domain& d, CallPool& pool);
std::unique_ptr<grpc::Service> NewMonitorService(Domain& d);
std::unique_ptr<grpc::Service> NewEvaluationService(Domain& d, CallPool& pool);
std::unique_ptr<grpc::Service> NewAdminService(Domain& d, CallPool& pool);
std::unique_ptr<grpc::Service> NewTrainingService(Domain& d, CallPool& pool);

}  // namespace vsurg::server::grpcapi
