// Start-up of the gRPC control plane: credentials (TLS or loopback plaintext), the four services
// (server/control/*_service.cpp), health and reflection, and an orderly shutdown.
#include "server/control/control_plane.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include <chrono>
#include <mutex>

#include "common/core/file.h"
#include "server/control/grpc_common.h"
#include "server/domain/scene_catalog.h"

namespace vsurg::server {

struct ControlPlane::Impl {
  SceneCatalog scenes;  // follows sim::ScenesDirectory()
  Domain domain;
  // Declared before the services and the server, so it ends after them: the server's shutdown
  // waits for the calls in it to finish.
  CallPool calls;
  std::unique_ptr<grpc::Service> session_service = grpcapi::NewSessionService(domain, calls);
  std::unique_ptr<grpc::Service> monitor_service = grpcapi::NewMonitorService(domain);
  std::unique_ptr<grpc::Service> evaluation_service = grpcapi::NewEvaluationService(domain, calls);
  std::unique_ptr<grpc::Service> admin_service = grpcapi::NewAdminService(domain, calls);
  std::unique_ptr<grpc::Service> training_service = grpcapi::NewTrainingService(domain, calls);
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  bool tls = false;
  std::once_flag shutdown_once;
  Impl(db::Store& store, Sessions& sessions, const ControlPlaneOptions& o)
      : domain{store, sessions, scenes, o.backup_dir} {}
};

ControlPlane::ControlPlane(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ControlPlane::~ControlPlane() {
  Shutdown();
}
int ControlPlane::port() const {
  return impl_->port;
}
bool ControlPlane::tls() const {
  return impl_->tls;
}

Expected<std::unique_ptr<ControlPlane>> ControlPlane::Start(db::Store& store, Sessions& sessions,
                                                            const ControlPlaneOptions& options) {
  auto impl = std::make_unique<Impl>(store, sessions, options);
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (options.tls_cert_file.empty() != options.tls_key_file.empty())
    return InvalidArgument("tls", "a certificate and its key are both required");
  if (!options.tls_cert_file.empty()) {
    auto cert = ReadTextFile(options.tls_cert_file, "tls_cert");
    if (!cert.ok()) return cert.error();
    auto key = ReadTextFile(options.tls_key_file, "tls_key");
    if (!key.ok()) return key.error();
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({*key, *cert});
    creds = grpc::SslServerCredentials(ssl);
    impl->tls = true;
  } else {
    if (!IsLoopbackHost(options.listen) && !options.allow_insecure)
      return InvalidArgument("listen",
                             "plaintext gRPC only on loopback; configure a TLS "
                             "certificate (or allow insecure explicitly)");
    creds = grpc::InsecureServerCredentials();
  }
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, creds, &impl->port);
  builder.RegisterService(impl->session_service.get());
  builder.RegisterService(impl->monitor_service.get());
  builder.RegisterService(impl->evaluation_service.get());
  builder.RegisterService(impl->admin_service.get());
  builder.RegisterService(impl->training_service.get());
  impl->server = builder.BuildAndStart();
  if (!impl->server || impl->port == 0)
    return Error{ErrorCode::kUnavailable, "cannot listen on " + options.listen, "listen"};
  return std::unique_ptr<ControlPlane>(new ControlPlane(std::move(impl)));
}

void ControlPlane::Shutdown() {
  std::call_once(impl_->shutdown_once, [this] {
    if (impl_->server) {
      // Streams (monitors, exports) are cancelled at the deadline; unary calls finish first.
      impl_->server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
      impl_->server->Wait();
    }
  });
}

}  // namespace vsurg::server
