// The gRPC control plane: SessionService, MonitorService, EvaluationService, AdminService, the
// standard health service and server reflection (proto/vsurg/v1/services.proto).
//
// Callback API, thin reactors over the domain functions of server/domain/api.h (the rules, shared
// with the HTTP API): a service translates the request, calls one function, translates the result.
// A unary call's body runs on the control plane's call pool (server/control/call_pool.h), never on
// gRPC's own few callback threads, which a call waiting on a node would otherwise hold.
// Every call: the bearer token is authenticated against the store (UNAUTHENTICATED), then the
// permission matrix decides (PERMISSION_DENIED), then ownership, then validation
// (INVALID_ARGUMENT naming the field). Errors are mapped to gRPC codes in one place
// (grpcapi::ToGrpcStatus). No lock is held across a reactor callback: evaluation submissions finish
// from the store's writer thread after the group commit; monitor streams are fed by the sessions'
// sampler thread through a one-slot mailbox per stream.
//
// No gRPC or protobuf type appears in this header.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "common/core/expected.h"
#include "server/domain/auth.h"  // IsLoopbackHost

namespace vsurg::db {
class Store;
}

namespace vsurg::server {

class Sessions;

struct ControlPlaneOptions {
  std::string listen = "127.0.0.1:0";  // host:port; port 0 picks a free one
  // TLS: both files (PEM) or neither. Without TLS the address must be loopback unless
  // allow_insecure is set (DESIGN.md: plaintext only on loopback by default).
  std::string tls_cert_file;
  std::string tls_key_file;
  bool allow_insecure = false;
  int max_export_chunk = 1 << 16;  // bytes per ExportChunk
  // AdminService/Backup writes only here (created when missing); empty: backups refused.
  std::string backup_dir;
};

class ControlPlane {
 public:
  static Expected<std::unique_ptr<ControlPlane>> Start(db::Store& store, Sessions& sessions,
                                                       const ControlPlaneOptions& options);
  ~ControlPlane();  // Shutdown()
  int port() const;
  bool tls() const;
  // Ends the streams, waits (up to a deadline) for calls in flight, stops the server.
  void Shutdown();

 private:
  struct Impl;
  explicit ControlPlane(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::server
