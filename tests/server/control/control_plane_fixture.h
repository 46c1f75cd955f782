// The control plane suites' fixture: a gRPC server on a loopback port over a real SQLite file,
// the UDP endpoint, and stubs for each role (tests/server/control/control_plane_*_test.cpp).
#pragma once

#include "server/control/control_plane.h"
#include "server/domain/api.h"

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "client/device/device.h"
#include "client/net/station_channel.h"
#include "common/scoring/evaluation.h"
#include "db/store.h"
#include "proto/convert/services.h"
#include "server/domain/auth.h"
#include "server/net/udp_endpoint.h"
#include "server/session/session_manager.h"
#include "tests/support/press_and_hold.h"
#include "tests/support/self_signed.h"
#include "tests/support/site.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::server::test_control {

namespace fs = std::filesystem;
using grpc::StatusCode;

// A station's channel options: the endpoint's port, the id its datagrams carry, the key.
inline client::StationOptions StationFor(uint16_t port, uint64_t wire_id, const std::string& key) {
  client::StationOptions so;
  so.server_port = port;
  so.session = wire_id;
  std::copy(key.begin(), key.end(), so.key.begin());
  return so;
}

class ControlPlaneTest : public test::SiteTest {
 protected:
  void SetUp() override {
    endpoint_ = std::move(UdpEndpoint::Create({})).value();
    ASSERT_NO_FATAL_FAILURE(OpenSite(endpoint_.get()));
    ControlPlaneOptions co;
    co.backup_dir = backups();
    auto cp = ControlPlane::Start(*store_, *sessions_, co);
    ASSERT_TRUE(cp.ok()) << cp.error().message;
    control_ = std::move(cp).value();
    channel_ = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_->port()),
                                   grpc::InsecureChannelCredentials());
    AddUsers({{"tina", db::Role::kTrainee, "virtual-40"},
              {"tom", db::Role::kTrainee, "real-40"},
              {"ida", db::Role::kInstructor, ""},
              {"eve", db::Role::kEvaluator, "chief"}});
    role_tokens_ = {{db::Role::kAdmin, admin_},
                    {db::Role::kTrainee, tokens_["tina"]},
                    {db::Role::kInstructor, tokens_["ida"]},
                    {db::Role::kEvaluator, tokens_["eve"]}};
    tom_ = tokens_["tom"];
  }
  void TearDown() override {
    control_.reset();
    SiteTest::TearDown();  // the sessions before the endpoint they send through
  }

  // Every client call carries a deadline.
  std::unique_ptr<grpc::ClientContext> Ctx(const std::string& token, double seconds = 10) {
    auto ctx = std::make_unique<grpc::ClientContext>();
    if (!token.empty()) ctx->AddMetadata("authorization", "Bearer " + token);
    ctx->set_deadline(std::chrono::system_clock::now() +
                      std::chrono::milliseconds(static_cast<int>(seconds * 1000)));
    return ctx;
  }
  std::unique_ptr<grpc::ClientContext> Ctx(db::Role role) { return Ctx(role_tokens_[role]); }

  v1::SubmitEvaluationRequest Submission(const std::string& key, const std::string& subject) {
    v1::SubmitEvaluationRequest r;
    r.set_idempotency_key(key);
    r.set_subject_kind("model");
    r.set_subject(subject);
    for (double s : {8.0, 7.0, 9.0, 8.0, 7.0, 8.0, 9.0, 6.0, 7.0}) r.add_scores(s);
    return r;
  }

  // EvaluationService/Report on model subjects, as an instructor sees it.
  nlohmann::json ModelReport(const std::string& subject, const std::string& weight_set = "") {
    auto ev = v1::EvaluationService::NewStub(channel_);
    v1::ReportRequest rq;
    rq.set_subject_kind("model");
    rq.add_subjects(subject);
    if (!weight_set.empty()) rq.set_weight_set(weight_set);
    v1::ReportResponse rep;
    const grpc::Status s = ev->Report(Ctx(db::Role::kInstructor).get(), rq, &rep);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return s.ok() ? nlohmann::json::parse(rep.report_json()) : nlohmann::json();
  }

  std::unique_ptr<UdpEndpoint> endpoint_;
  std::unique_ptr<ControlPlane> control_;
  std::shared_ptr<grpc::Channel> channel_;
  std::map<db::Role, std::string> role_tokens_;
  std::string tom_;
};

}  // namespace vsurg::server::test_control
