#include "server/control/grpc_common.h"

#include "proto/convert/services.h"

namespace vsurg::server::grpcapi {

// The one place where our errors become gRPC statuses.
grpc::Status ToGrpcStatus(const Error& e) {
  grpc::StatusCode code = grpc::StatusCode::INTERNAL;
  switch (e.code) {
    case ErrorCode::kInvalidArgument:
    case ErrorCode::kParseError:
      code = grpc::StatusCode::INVALID_ARGUMENT;
      break;
    case ErrorCode::kNotFound:
      code = grpc::StatusCode::NOT_FOUND;
      break;
    case ErrorCode::kAlreadyExists:
      code = grpc::StatusCode::ALREADY_EXISTS;
      break;
    case ErrorCode::kFailedPrecondition:
      code = grpc::StatusCode::FAILED_PRECONDITION;
      break;
    case ErrorCode::kUnavailable:
      code = grpc::StatusCode::UNAVAILABLE;
      break;
    case ErrorCode::kResourceExhausted:
      code = grpc::StatusCode::RESOURCE_EXHAUSTED;
      break;
    case ErrorCode::kUnauthenticated:
      code = grpc::StatusCode::UNAUTHENTICATED;
      break;
    case ErrorCode::kPermissionDenied:
      code = grpc::StatusCode::PERMISSION_DENIED;
      break;
    case ErrorCode::kIoError:
    case ErrorCode::kNumerical:
      code = grpc::StatusCode::INTERNAL;
      break;
  }
  return grpc::Status(code, e.field.empty() ? e.message : e.field + ": " + e.message);
}

grpc::Status ToGrpcStatus(const Status& s) {
  return s.ok() ? grpc::Status::OK : ToGrpcStatus(s.error());
}

Expected<db::Principal> Authorize(Domain& d, grpc::CallbackServerContext* ctx, Method m) {
  const auto& md = ctx->client_metadata();
  const auto it = md.find("authorization");
  std::optional<std::string_view> header;
  if (it != md.end()) header = std::string_view(it->second.data(), it->second.size());
  return server::Authorize(d.store, header, m);
}

void ToProto(const db::SessionRecord& r, v1::Session* out) {
  out->set_id(static_cast<uint64_t>(r.id));
  out->set_trainee(r.trainee);
  out->set_scene(r.scene);
  out->set_state(convert::ToProto(r.state));
  out->set_created_us(r.created_us);
  out->set_started_us(r.started_us);
  out->set_ended_us(r.ended_us);
  out->set_end_reason(r.end_reason);
}

void ToProto(const SessionView& v, v1::Session* out) {
  ToProto(v.record, out);
  if (v.metrics) convert::ToProto(*v.metrics, out->mutable_metrics());
}

std::optional<db::Role> RoleFromProto(v1::Role r) {
  switch (r) {
    case v1::ROLE_TRAINEE:
      return db::Role::kTrainee;
    case v1::ROLE_INSTRUCTOR:
      return db::Role::kInstructor;
    case v1::ROLE_EVALUATOR:
      return db::Role::kEvaluator;
    case v1::ROLE_ADMIN:
      return db::Role::kAdmin;
    default:
      return std::nullopt;
  }
}

v1::Role RoleToProto(db::Role r) {
  switch (r) {
    case db::Role::kTrainee:
      return v1::ROLE_TRAINEE;
    case db::Role::kInstructor:
      return v1::ROLE_INSTRUCTOR;
    case db::Role::kEvaluator:
      return v1::ROLE_EVALUATOR;
    case db::Role::kAdmin:
      return v1::ROLE_ADMIN;
  }
  return v1::ROLE_UNSPECIFIED;
}

void ToProto(const db::UserRecord& u, v1::User* out) {
  out->set_name(u.name);
  out->set_role(RoleToProto(u.role));
  out->set_group(u.group);
  out->set_created_us(u.created_us);
  out->set_disabled(u.disabled);
}

sim::GuideMode GuideModeFromProto(v1::GuideMode m) {
  switch (m) {
    case v1::GUIDE_MODE_OBSERVE:
      return sim::GuideMode::kObserve;
    case v1::GUIDE_MODE_GUIDE:
      return sim::GuideMode::kGuide;
    default:
      return sim::GuideMode::kNone;
  }
}

v1::GuideMode GuideModeToProto(sim::GuideMode m) {
  return static_cast<v1::GuideMode>(static_cast<int>(m));
}

void ToProto(const SessionGuidance& g, v1::Guidance* out) {
  out->set_trainee(g.trainee);
  out->set_instructor(g.instructor);
  out->set_mode(GuideModeToProto(g.requested.mode));
  out->set_alpha(g.requested.alpha);
  out->set_alpha_now(g.alpha);
}

SessionGuidance FromProto(const v1::Guidance& g) {
  SessionGuidance out;
  out.trainee = g.trainee();
  out.instructor = g.instructor();
  out.requested = {GuideModeFromProto(g.mode()), g.alpha()};
  out.alpha = g.alpha_now();
  return out;
}

}  // namespace vsurg::server::grpcapi
