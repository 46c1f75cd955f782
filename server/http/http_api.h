// The dashboard's HTTP API and pages, without a socket: a request in, a reply out. The transport
// (server/http/http_server.cpp, Boost.Beast) parses and writes; this file decides. Every route
// calls the domain functions of server/domain/api.h — the same rules as the gRPC services — and
// translates JSON and status codes once (ErrorCode → HTTP status in StatusFor).
//
//   /signin, /live, /session/ID, /evaluate, /reports, /admin, /mine   pages (role-checked; an
//                                                                    anonymous visitor is sent to
//                                                                    /signin, a forbidden one gets
//                                                                    403)
//   /static/…                                                        the page's script and style
//   /api/v1/…                                                        JSON (docs/ARCHITECTURE.md);
//                                                                    401 without a session, 403
//                                                                    when the role may not
//
// Authentication: the web session cookie (web_auth.h) or an `Authorization: Bearer` header (API
// scripts). With the cookie, every POST needs the session's CSRF token in X-CSRF-Token, and a
// JSON body needs Content-Type application/json (a cross-site form cannot send either).
//
// Thread safety: Handle may be called from any thread (the server calls it from its I/O thread).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/core/clock.h"
#include "server/domain/api.h"
#include "server/http/fair_workers.h"
#include "server/http/web_auth.h"

namespace vsurg::server::ops {
class MetricsRegistry;
}

namespace vsurg::server::http {

class OidcRelyingParty;  // server/http/oidc.h

struct HttpRequest {
  std::string method;  // GET, POST, …
  std::string target;  // as sent: path and query
  std::string cookie;  // the Cookie header
  std::string authorization;
  std::string csrf;  // X-CSRF-Token
  std::string content_type;
  std::string body;
  std::string remote;  // the client's address (rate limits)
};

struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // beyond the type and length

  enum class Kind {
    kPlain,     // status, headers, body
    kEvents,    // a server-sent event stream of telemetry (watch below)
    kExport,    // a chunked download (export below)
    kDeferred,  // the reply comes later from `deferred`
  };
  Kind kind = Kind::kPlain;
  struct Watch {
    uint64_t session = 0;  // 0: every live session
    double rate_hz = 4;
    bool surface = false;  // the deformed surface with each frame that has one
  } watch;
  ExportPlan export_plan;
  // kExport of something other than the store's evaluations (the training programme's
  // progress): writes the download through `sink` (false: stop) on an export worker, in bounded
  // memory. Unset: db::Store::Export with `export_plan`.
  std::function<Status(const std::function<bool(std::string_view)>& sink)> produce;
  std::string filename;  // kExport: the download's name
  // kDeferred: starts the work; calls `done` exactly once, from any thread.
  std::function<void(std::function<void(HttpReply)> done)> deferred;
  // kEvents: is the caller still allowed to watch (their token not revoked, their web session
  // not signed out)? Called now and then, and at once after any sign-out (HttpApi::signouts).
  std::function<bool()> still_allowed;
  // kExport: who asked (export slots are shared out per user).
  std::string owner;
};

struct HttpApiOptions {
  // Reads that take long at scale (a cohort's grid over 100,000 trials: ~90 ms) run on these
  // workers, never on the server's I/O thread that answers everyone else; at most
  // `max_queued_reads` wait (then 503). 0 workers: on the calling thread.
  // The workers are shared fairly (server/http/fair_workers.h): one user runs at most all but one
  // of them at once and queues at most `per_user_queued_reads` (then 429, to that user only).
  int read_workers = 2;
  int max_queued_reads = 32;
  int per_user_queued_reads = 4;
  // Calls that wait on a simulation node (creating a session builds its scene there; a live
  // session's surface, record or stop ask its node, which may be frozen for the node-call timeout)
  // run on their own workers, so neither the I/O thread nor the long reads wait behind a node; at
  // most `max_queued_node_calls` wait (then 503). 0 workers: on the calling thread.
  int node_workers = 8;
  int max_queued_node_calls = 64;
  double session_ttl_s = 8 * 3600;  // a web session's lifetime
  bool secure_cookies = false;      // TLS: the cookie gets `Secure`
  int sign_in_failures = 5;         // per address per minute
  int bearer_failures = 20;         // requests with an unknown bearer token, per address a minute
  const Clock* clock = nullptr;     // null: the steady clock
  // GET /api/v1/metrics renders this (Prometheus text format; an administrator's bearer token);
  // null: 404. Must outlive the API.
  const ops::MetricsRegistry* metrics = nullptr;
  bool metrics_only = false;  // HttpServerOptions::metrics_only
  // A token that reads GET /api/v1/metrics and nothing else (Prometheus'; empty: none). It is no
  // user's: a leaked one shows aggregate figures, never a name or a session.
  std::string metrics_token;
  // The site's identity provider (OpenID Connect) for sign-in besides tokens; null: none.
  std::shared_ptr<OidcRelyingParty> oidc;
};

class HttpApi {
 public:
  HttpApi(Domain& domain, const HttpApiOptions& options);
  ~HttpApi();  // answers queued reads with 503 and joins the read workers
  HttpReply Handle(const HttpRequest& request);

  // One telemetry frame as the event streams send it (JSON object; the surface only when asked
  // and present: moved vertex indices and positions in millimetres).
  static std::string TelemetryJson(const SessionTelemetry& t, bool with_surface);
  // An error reply: {"error": message, "field": field} with the status for its code.
  static HttpReply ErrorReply(const Error& e);
  static int StatusFor(ErrorCode code);

  Domain& domain() { return d_; }
  // Web sessions signed out (or dropped) so far: an event stream re-checks its caller when this
  // moves, so signing out ends the web session's streams at their next frame.
  uint64_t signouts() const { return sessions_.removals(); }
  uint64_t bearer_failures() const { return bearer_failures_.load(); }

 private:
  // The API's routes (http_api.cpp): {verb, pattern, method, handler}, one short function each.
  struct Call;
  struct Routes;
  struct Route {
    const char* verb;     // GET (HEAD too) or POST
    const char* pattern;  // below /api/v1/: literals, {id} (a session id), {name} (decoded)
    Method method;        // what the caller must be allowed (Authorize), before the handler
    HttpReply (*handler)(const Call&);
  };
  static const Route kRoutes[];
  static Expected<bool> Match(std::string_view pattern, const std::vector<std::string_view>& seg,
                              Call& call);
  void BearerRefused(const std::string& remote);  // an unknown bearer token: counted, limited
  HttpReply Api(const HttpRequest& r, const std::string& path,
                const std::multimap<std::string, std::string>& query);
  HttpReply Page(const HttpRequest& r, const std::string& path);
  HttpReply MetricsReply() const;
  HttpReply SignIn(const HttpRequest& r);
  // The identity provider's sign-in (server/http/http_signin_oidc.cpp).
  HttpReply OidcBegin(const HttpRequest& r);
  HttpReply OidcCallback(const HttpRequest& r,
                         const std::multimap<std::string, std::string>& query);
  // A deferred reply whose `work` runs on a read worker (the answer of a long read), in the
  // caller's fair share of them (server/http/fair_workers.h).
  HttpReply OffThread(const db::Principal& p, std::function<HttpReply()> work);
  // A deferred reply whose `work` runs on a node-call worker (it may wait on a node).
  HttpReply OnNodeWorker(const db::Principal& p, std::function<HttpReply()> work);
  static HttpReply Deferred(FairWorkers* workers, const db::Principal& p,
                            std::function<HttpReply()> work, const char* busy);

  Domain& d_;
  HttpApiOptions options_;
  const Clock& clock_;
  std::function<bool()> StillAllowed(const std::string& authorization,
                                     const std::optional<WebSession>& web);

  std::unique_ptr<FairWorkers> reads_, node_calls_;
  WebSessions sessions_;
  SignInLimiter limiter_;
  SignInLimiter bearer_limiter_;
  std::atomic<uint64_t> bearer_failures_{0};
};

// Percent-decoding of a query component ('+' is a space); nullopt when malformed.
std::optional<std::string> UrlDecode(std::string_view s);
// The query's parameters in order (a repeated name appears once per value); nullopt when
// malformed.
std::optional<std::multimap<std::string, std::string>> ParseQuery(std::string_view query);

}  // namespace vsurg::server::http
