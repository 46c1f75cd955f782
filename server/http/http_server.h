// The dashboard's HTTP(S) listener in vsurg-server (--http HOST:PORT): Boost.Beast over Asio, on
// its own I/O thread, beside the gRPC control plane and over the same domain functions
// (http_api.h decides; this file only moves bytes).
//
// Threads: one I/O thread accepts, parses, calls HttpApi::Handle and writes (a long read, or a
// call that waits on a simulation node, is answered later from the API's workers). Live pages'
// event streams are fed by the sessions' sampler thread, which only posts the latest frame to the
// I/O thread (latest wins, one frame in flight per stream). The store's exports run on a pool of
// max_exports workers (they block on the database), each chunk written by the I/O thread in
// Beast's chunked encoding before the worker reads on, so a million rows stream without
// buffering. None of these threads touches the UDP haptic path.
//
// Exchanges (http_server.cpp): a Connection reads requests and writes plain and deferred replies;
// an EventStream or an ExportStream takes the connection over for a streamed reply.
//
// Limits (one client can never deny service to the others): header and body sizes (431, 413),
// a deadline for a whole request (slowloris: the connection is closed), a write deadline (a
// client that stops reading is dropped), connections in all and per address (503), the
// per-address share falling as the total fills (a few addresses cannot take every connection),
// and when the total is full the oldest idle connection of the address holding the most is
// closed to admit a newcomer from an address holding fewer. Exports: slots in all and per user;
// an export whose client takes no chunk for export_stall_s is ended and its slot freed.
//
// Before a request is handed on (server/http/request_checks.h): its framing must be unambiguous
// (Transfer-Encoding only as a lone `chunked`, never beside Content-Length: else 400 and the
// connection closed, so no request can be smuggled inside another's body) and its Host one the
// server answers for (421 otherwise: DNS rebinding).
//
// No Beast, Asio or OpenSSL type appears in this header.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "common/core/clock.h"
#include "common/core/expected.h"

namespace vsurg::db {
class Store;
}

namespace vsurg::server::ops {
class MetricsRegistry;
}

namespace vsurg::server {
namespace http {
class OidcRelyingParty;
}  // namespace http

class Sessions;

struct HttpServerOptions {
  std::string listen = "127.0.0.1:0";  // host:port; port 0 picks a free one
  // TLS (the same PEM files as gRPC): both or neither. Without TLS the address must be loopback
  // unless allow_insecure is set.
  std::string tls_cert_file;
  std::string tls_key_file;
  bool allow_insecure = false;
  std::string backup_dir;           // as ControlPlaneOptions::backup_dir
  double session_ttl_s = 8 * 3600;  // web sessions (cookies)
  size_t max_header_bytes = 16 * 1024;
  size_t max_body_bytes = 256 * 1024;
  double request_timeout_s = 10;  // to receive a whole request (headers and body)
  double idle_timeout_s = 60;     // keep-alive between requests
  double write_timeout_s = 10;    // for each write
  int max_connections = 512;
  int max_connections_per_address = 64;
  // The per-address share as the total fills: an address may open another connection while it
  // holds fewer than max(min_connections_per_address, free connections / 4) (and the cap above).
  int min_connections_per_address = 4;
  int max_exports = 4;
  int max_exports_per_user = 1;
  double export_stall_s = 3;  // a client that takes no export chunk for this long is dropped
  // Host names the server answers for, besides IP literals and localhost (DNS rebinding).
  std::vector<std::string> hosts;
  const Clock* clock = nullptr;  // web sessions and sign-in limits (null: the steady clock)
  // GET /api/v1/metrics (server/ops/metrics.h), for an administrator's token; null: none. Must
  // outlive the server.
  const ops::MetricsRegistry* metrics = nullptr;
  // Only GET /api/v1/metrics is served (a simulation node: its sessions are the control plane's
  // to show and to create); everything else is 404.
  bool metrics_only = false;
  std::string metrics_token;  // HttpApiOptions::metrics_token
  // The site's identity provider for the dashboard's sign-in (server/http/oidc.h); null: none.
  std::shared_ptr<http::OidcRelyingParty> oidc;
};

struct HttpCounters {
  uint64_t requests = 0;
  uint64_t refused_connections = 0;  // over the limits
  uint64_t bad_requests = 0;         // malformed, too large, too slow, ambiguous, wrong host
  uint64_t evicted_connections = 0;  // idle ones closed to admit a newcomer
  uint64_t events_sent = 0;          // event-stream frames written
  int open_connections = 0;
  int open_streams = 0;  // event streams and exports
};

class HttpServer {
 public:
  static Expected<std::unique_ptr<HttpServer>> Start(db::Store& store, Sessions& sessions,
                                                     const HttpServerOptions& options);
  ~HttpServer();  // Shutdown()
  int port() const;
  bool tls() const;
  HttpCounters counters() const;
  // Closes the listener and every connection, ends the streams and exports, joins the threads.
  void Shutdown();

 private:
  struct Impl;
  explicit HttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::server
