// EvaluationService over gRPC: durable submissions (finished from the store's writer thread),
// weighted reports and the training effect.
#include "server/control/grpc_common.h"

namespace vsurg::server::grpcapi {
namespace {

using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;

class EvaluationServiceImpl final : public v1::EvaluationService::CallbackService {
 public:
  EvaluationServiceImpl(Domain& d, CallPool& pool) : d_(d), pool_(pool) {}

  ServerUnaryReactor* Submit(CallbackServerContext* ctx, const v1::SubmitEvaluationRequest* req,
                             v1::SubmitEvaluationResponse* resp) override {
    ServerUnaryReactor* r = ctx->DefaultReactor();
    auto p = Authorize(d_, ctx, Method::kEvaluationSubmit);
    if (!p.ok()) {
      r->Finish(ToGrpcStatus(p.error()));
      return r;
    }
    SubmissionRequest in;
    in.idempotency_key = req->idempotency_key();
    in.evaluator = req->evaluator();
    in.evaluator_group = req->evaluator_group();
    in.subject_kind = req->subject_kind();
    in.subject = req->subject();
    if (req->has_moment_min()) in.moment_min = req->moment_min();
    in.comment = req->comment();
    in.scores.assign(req->scores().begin(), req->scores().end());
    auto s = PrepareSubmission(*p, in);
    if (!s.ok()) {
      r->Finish(ToGrpcStatus(s.error()));
      return r;
    }
    // Finishes from the store's writer thread once the group commit is on disk.
    d_.store.SubmitEvaluationAsync(std::move(s).value(), [r, resp](Expected<db::SubmitResult> res) {
      if (!res.ok()) {
        r->Finish(ToGrpcStatus(res.error()));
        return;
      }
      resp->set_submission_id(static_cast<uint64_t>(res->submission_id));
      resp->set_submitted_us(res->submitted_us);
      resp->set_duplicate(res->duplicate);
      r->Finish(grpc::Status::OK);
    });
    return r;
  }

  ServerUnaryReactor* Report(CallbackServerContext* ctx, const v1::ReportRequest* req,
                             v1::ReportResponse* resp) override {
    return Unary(
        d_, pool_, ctx, Method::kEvaluationReport, [=, this](const db::Principal& p) -> Status {
          const std::vector<std::string> subjects(req->subjects().begin(), req->subjects().end());
          auto json = server::Report(d_, p, req->subject_kind(), subjects, req->weight_set());
          if (!json.ok()) return json.error();
          resp->set_report_json(*json);
          return Status::Ok();
        });
  }

  ServerUnaryReactor* TrainingEffect(CallbackServerContext* ctx,
                                     const v1::TrainingEffectRequest* req,
                                     v1::TrainingEffectResponse* resp) override {
    return Unary(d_, pool_, ctx, Method::kEvaluationTrainingEffect,
                 [=, this](const db::Principal& p) -> Status {
                   auto json = server::TrainingEffect(d_, p, req->weight_set());
                   if (!json.ok()) return json.error();
                   resp->set_cells_json(*json);
                   return Status::Ok();
                 });
  }

 private:
  Domain& d_;
  CallPool& pool_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewEvaluationService(Domain& d, CallPool& pool) {
  return std::make_unique<EvaluationServiceImpl>(d, pool);
}

}  // namespace vsurg::server::grpcapi
