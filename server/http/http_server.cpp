#include "server/http/http_server.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>

#include "common/core/realtime.h"
#include "server/domain/auth.h"
#include "server/domain/scene_catalog.h"
#include "server/http/http_api.h"
#include "server/http/request_checks.h"
#include "server/session/sessions.h"

namespace vsurg::server {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;
using tcp = asio::ip::tcp;
using http::HttpApi;
using http::HttpReply;
using http::HttpRequest;

// Sent with every response, plain or streamed: scripts, styles and connections from this server
// only, never framed, never sniffed, no referrer.
constexpr std::pair<const char*, const char*> kSecurityHeaders[] = {
    {"Content-Security-Policy",
     "default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'; "
     "connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'self'"},
    {"X-Content-Type-Options", "nosniff"},
    {"X-Frame-Options", "DENY"},
    {"Referrer-Policy", "no-referrer"},
};

// One event-stream frame in two forms: with the session's surface (`full`) and without it
// (`light`). A stream writes `full` only when the surface changed since it last wrote one (the
// surface is a whole state, vertices away from rest, so a watcher keeps the last one it got): a
// trainee holding a twist costs each page ~400 bytes a frame instead of ~125 KB.
struct Frame {
  std::shared_ptr<const std::string> full, light;
  uint64_t surface_frame = 0;
  bool has_surface = false;
};

// The event streams' frames, formatted once per sampler tick for every stream that watches the
// same thing (20 instructors on one session cost one JSON encoding, not 20). Sampler thread only.
class FrameCache {
 public:
  Frame Get(uint64_t session, bool surface, const std::vector<SessionTelemetry>& list) {
    const int64_t stamp = list.empty() ? 0 : list.front().server_time_us;
    std::lock_guard<std::mutex> lock(mutex_);
    Entry& e = entries_[{session, surface}];
    if (e.frame.full && e.stamp == stamp && e.count == list.size() && stamp != 0) return e.frame;
    auto encode = [&](bool with_surface) {
      std::string text = "data: ";
      if (session == 0) text += "[";
      for (size_t i = 0; i < list.size(); ++i) {
        if (i) text += ",";
        text += HttpApi::TelemetryJson(list[i], with_surface);
      }
      if (session == 0) text += "]";
      return std::make_shared<const std::string>(text + "\n\n");
    };
    Frame f;
    f.light = encode(false);
    f.has_surface = surface && list.size() == 1 && list.front().has_surface;
    f.full = f.has_surface ? encode(true) : f.light;
    f.surface_frame = f.has_surface ? list.front().surface_frame : 0;
    e = {stamp, list.size(), f};
    if (entries_.size() > 4096) entries_.clear();  // ended sessions' entries, now and then
    return f;
  }

 private:
  struct Entry {
    int64_t stamp = 0;
    size_t count = 0;
    Frame frame;
  };
  std::mutex mutex_;
  std::map<std::pair<uint64_t, bool>, Entry> entries_;
};

// What outlives the server object while handlers are still queued: the I/O context (last, so it
// is destroyed first and the connections its handlers hold find the counters still there).
struct Shared {
  HttpServerOptions options;
  std::mutex mutex;  // per_address, open, exports_by_user
  std::map<std::string, int> per_address;
  std::map<std::string, int> exports_by_user;
  std::atomic<uint64_t> requests{0}, refused{0}, bad{0}, events{0}, evicted{0};
  std::atomic<int> open{0}, streams{0}, exports{0};
  FrameCache frames;
  asio::io_context io;
};

class ConnectionBase {
 public:
  virtual ~ConnectionBase() = default;
  virtual void Close() = 0;  // I/O thread
  // Waiting for a request (none yet, or between keep-alive requests, or a half-sent one): not
  // streaming, exporting or waiting for the store. Such a connection may be closed to admit
  // another client when every connection is taken. I/O thread.
  virtual bool Idle() const = 0;
  virtual const std::string& remote() const = 0;
  std::chrono::steady_clock::time_point idle_since{};  // when it last started waiting
};

// A long exchange a connection hands its stream to after the request (an event stream, an
// export). The connection holds it until it closes, and it holds the connection.
class Exchange {
 public:
  virtual ~Exchange() = default;
  virtual void Stop() = 0;  // I/O thread, from the connection's Close; idempotent
};

struct Context {  // what a connection needs from the server
  Shared* shared;
  std::weak_ptr<Shared> owner;  // for callbacks that may outlive the server (a store commit)
  HttpApi* api;
  db::Store* store;
  Sessions* sessions;
  asio::thread_pool* export_pool;                         // the store's exports run here
  std::list<std::weak_ptr<ConnectionBase>>* connections;  // I/O thread only
};

std::chrono::steady_clock::duration Seconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(s));
}

// The header of a streamed reply (an event stream, an export): never cached, the connection
// closed at its end.
std::shared_ptr<bhttp::response<bhttp::empty_body>> StreamHeader(const std::string& type) {
  auto res = std::make_shared<bhttp::response<bhttp::empty_body>>(bhttp::status::ok, 11);
  res->set(bhttp::field::server, "vsurg");
  res->set(bhttp::field::content_type, type);
  res->set(bhttp::field::cache_control, "no-store");
  for (const auto& [name, value] : kSecurityHeaders) res->set(name, value);
  res->keep_alive(false);
  return res;
}

// The request/reply exchange: reads a request (its framing and host checked first), hands it to
// HttpApi, and writes the plain or deferred reply, keeping the connection alive between
// requests; an event stream or an export takes the connection over (EventStream, ExportStream).
template <class Stream>
class Connection final : public ConnectionBase,
                         public std::enable_shared_from_this<Connection<Stream>> {
 public:
  template <class... Args>
  Connection(Context ctx, std::string remote, Args&&... args)
      : ctx_(ctx), remote_(std::move(remote)), stream_(std::forward<Args>(args)...) {}

  ~Connection() override {
    std::lock_guard<std::mutex> lock(ctx_.shared->mutex);
    if (--ctx_.shared->per_address[remote_] <= 0) ctx_.shared->per_address.erase(remote_);
    ctx_.shared->open.fetch_sub(1);
  }

  void Begin() {
    if constexpr (std::is_same_v<Stream, beast::ssl_stream<beast::tcp_stream>>) {
      Lowest().expires_after(Seconds(ctx_.shared->options.request_timeout_s));
      stream_.async_handshake(asio::ssl::stream_base::server,
                              [self = this->shared_from_this()](beast::error_code ec) {
                                if (ec) return self->Close();
                                self->Read();
                              });
    } else {
      Read();
    }
  }

  void Close() override {
    if (closed_) return;
    closed_ = true;
    beast::error_code ec;
    Lowest().socket().shutdown(tcp::socket::shutdown_both, ec);
    Lowest().close();
    // Either may hold the last reference to this connection: released as the function returns.
    const auto waiting = std::move(waiting_);
    const auto exchange = std::move(exchange_);
    if (exchange) exchange->Stop();
  }

  // A plain reply, then the next request (or the end, without keep-alive).
  void Write(HttpReply reply) {
    if (closed_) return;
    auto res = std::make_shared<bhttp::response<bhttp::string_body>>(
        static_cast<bhttp::status>(reply.status), 11);
    res->set(bhttp::field::server, "vsurg");
    if (!reply.content_type.empty()) res->set(bhttp::field::content_type, reply.content_type);
    for (auto& [name, value] : reply.headers) res->insert(name, value);
    for (const auto& [name, value] : kSecurityHeaders) res->set(name, value);
    if (reply.status == 401 || reply.status == 403 || reply.status >= 500 ||
        reply.content_type.rfind("application/json", 0) == 0)
      res->set(bhttp::field::cache_control, "no-store");
    res->body() = std::move(reply.body);
    res->keep_alive(keep_alive_);
    res->prepare_payload();
    Lowest().expires_after(Seconds(ctx_.shared->options.write_timeout_s));
    bhttp::async_write(stream_, *res,
                       [self = this->shared_from_this(), res](beast::error_code ec, size_t) {
                         if (ec || !self->keep_alive_) return self->Close();
                         self->Read();
                       });
  }

  // For the exchanges that take the connection over.
  Stream& stream() { return stream_; }
  beast::tcp_stream& Lowest() { return beast::get_lowest_layer(stream_); }
  const Context& ctx() const { return ctx_; }
  bool closed() const { return closed_; }

 private:
  bool Idle() const override { return reading_ && !closed_; }
  const std::string& remote() const override { return remote_; }

  void Read() {
    if (closed_) return;
    reading_ = true;
    idle_since = std::chrono::steady_clock::now();
    parser_.emplace();
    parser_->header_limit(static_cast<uint32_t>(ctx_.shared->options.max_header_bytes));
    parser_->body_limit(ctx_.shared->options.max_body_bytes);
    // The whole request must arrive within the deadline, however slowly it trickles.
    Lowest().expires_after(Seconds(served_ == 0 ? ctx_.shared->options.request_timeout_s
                                                : ctx_.shared->options.idle_timeout_s));
    // The header first: its framing is checked before any body byte is read.
    bhttp::async_read_header(
        stream_, buffer_, *parser_,
        [self = this->shared_from_this()](beast::error_code ec, size_t) { self->OnHeader(ec); });
  }

  void OnHeader(beast::error_code ec) {
    if (closed_) return;
    if (ec) return OnRead(ec);
    const auto& req = parser_->get();
    std::vector<std::string_view> te;
    for (auto it = req.find(bhttp::field::transfer_encoding);
         it != req.end() && it->name() == bhttp::field::transfer_encoding; ++it)
      te.emplace_back(it->value().data(), it->value().size());
    const int lengths = static_cast<int>(req.count(bhttp::field::content_length));
    if (const std::string why = http::FramingProblem(te, lengths); !why.empty()) {
      ctx_.shared->bad.fetch_add(1);
      return Refuse(400, why);
    }
    if (parser_->is_done()) return OnRead({});
    bhttp::async_read(
        stream_, buffer_, *parser_,
        [self = this->shared_from_this()](beast::error_code ec2, size_t) { self->OnRead(ec2); });
  }

  void OnRead(beast::error_code ec) {
    if (closed_) return;
    if (ec == bhttp::error::end_of_stream || ec == asio::error::operation_aborted) return Close();
    if (ec == beast::error::timeout) {
      // Idle keep-alive connections close quietly; a request that never finished is counted.
      if (parser_->got_some()) ctx_.shared->bad.fetch_add(1);
      return Close();
    }
    if (ec) {
      ctx_.shared->bad.fetch_add(1);
      if (ec == bhttp::error::header_limit) return Refuse(431, "the request's header is too large");
      if (ec == bhttp::error::body_limit) return Refuse(413, "the request's body is too large");
      if (Lowest().socket().is_open() && parser_->got_some())
        return Refuse(400, "a malformed HTTP request");
      return Close();
    }
    reading_ = false;
    ++served_;
    ctx_.shared->requests.fetch_add(1);
    auto& req = parser_->get();
    keep_alive_ = req.keep_alive();
    if (req.method() != bhttp::verb::get && req.method() != bhttp::verb::post)
      return Refuse(405, "only GET and POST");
    const auto host = req[bhttp::field::host];
    if (!http::HostAllowed(std::string_view(host.data(), host.size()),
                           ctx_.shared->options.hosts)) {
      ctx_.shared->bad.fetch_add(1);
      return Refuse(421, "this server does not answer for the host name '" +
                             std::string(host).substr(0, 100) + "'");
    }
    HttpRequest r;
    r.method = std::string(req.method_string());
    r.target = std::string(req.target());
    r.cookie = std::string(req[bhttp::field::cookie]);
    r.authorization = std::string(req[bhttp::field::authorization]);
    r.csrf = std::string(req["X-CSRF-Token"]);
    r.content_type = std::string(req[bhttp::field::content_type]);
    r.body = std::move(req.body());
    r.remote = remote_;
    HttpReply reply = ctx_.api->Handle(r);
    switch (reply.kind) {
      case HttpReply::Kind::kPlain:
        return Write(std::move(reply));
      case HttpReply::Kind::kDeferred:
        return Defer(std::move(reply));
      case HttpReply::Kind::kEvents:
      case HttpReply::Kind::kExport:
        keep_alive_ = false;
        exchange_ = StartExchange(std::move(reply));
        return;
    }
  }

  std::shared_ptr<Exchange> StartExchange(HttpReply reply);  // below the exchanges

  // The connection waits for the answer (kept alive by itself until then, or until the server
  // closes it); the callback holds only weak references.
  void Defer(HttpReply reply) {
    waiting_ = this->shared_from_this();
    std::weak_ptr<Connection> weak = waiting_;
    reply.deferred([weak, owner = ctx_.owner](HttpReply done) {
      const auto shared = owner.lock();  // the server may have stopped meanwhile
      if (!shared) return;
      asio::post(shared->io, [weak, done = std::move(done)]() mutable {
        if (auto self = weak.lock()) {
          self->waiting_.reset();
          self->Write(std::move(done));
        }
      });
    });
  }

  // A status with a one-line JSON error, then the connection closes (the request was unusable).
  void Refuse(int status, const std::string& why) {
    keep_alive_ = false;
    HttpReply r = HttpApi::ErrorReply(Error{ErrorCode::kInvalidArgument, why, "request"});
    r.status = status;
    Write(std::move(r));
  }

  Context ctx_;
  std::string remote_;
  Stream stream_;
  beast::flat_buffer buffer_;
  std::optional<bhttp::request_parser<bhttp::string_body>> parser_;
  bool keep_alive_ = true;
  bool closed_ = false;
  bool reading_ = false;  // waiting for a request (Idle)
  uint64_t served_ = 0;
  std::shared_ptr<Connection> waiting_;  // a deferred reply's connection, until the reply
  std::shared_ptr<Exchange> exchange_;   // the event stream or export, until Close
};

// Server-sent events: the sessions' sampler thread formats a frame (FrameCache) and posts it; the
// I/O thread writes the latest, one write in flight, so a slow reader gets the newest frame and
// never a backlog. The stream ends when the client hangs up, a write fails, the session ends, the
// caller loses the right to watch, or the server stops.
template <class Stream>
class EventStream final : public Exchange,
                          public std::enable_shared_from_this<EventStream<Stream>> {
 public:
  EventStream(std::shared_ptr<Connection<Stream>> conn, HttpReply reply)
      : conn_(std::move(conn)),
        shared_(conn_->ctx().shared),
        watch_(reply.watch),
        still_allowed_(std::move(reply.still_allowed)) {}
  ~EventStream() override { Unsubscribe(); }

  void Start() {
    last_check_ = std::chrono::steady_clock::now();
    signouts_ = conn_->ctx().api->signouts();
    shared_->streams.fetch_add(1);
    counted_ = true;
    // A read that can only end in an error tells when the client hangs up between frames (a
    // client sends nothing on an event stream; data is ignored).
    conn_->Lowest().socket().async_read_some(
        asio::buffer(hangup_), [self = this->shared_from_this()](beast::error_code ec, size_t) {
          if (ec) self->conn_->Close();
        });
    std::weak_ptr<EventStream> weak = this->shared_from_this();
    Shared* shared = shared_;
    const HttpReply::Watch watch = watch_;
    auto last = std::make_shared<std::chrono::steady_clock::time_point>();
    subscription_ = conn_->ctx().sessions->Subscribe(
        watch.session,
        [weak, shared, watch, last](const std::vector<SessionTelemetry>& list, bool ended) {
          // The sessions' sampler thread: format (once per frame for all who watch the same
          // thing), hand over, never wait.
          Frame frame;
          if (ended) {
            frame.full = frame.light =
                std::make_shared<const std::string>("event: ended\ndata: {}\n\n");
          } else {
            if (watch.session != 0 && list.empty()) return;
            const auto now = std::chrono::steady_clock::now();
            if (watch.surface) {
              // The surface comes with every third sample: send those, whatever the phase.
              if (!list.front().has_surface) return;
            } else if (std::chrono::duration<double>(now - *last).count() < 0.9 / watch.rate_hz) {
              return;
            }
            *last = now;
            frame = shared->frames.Get(watch.session, watch.surface, list);
          }
          asio::post(shared->io, [weak, frame = std::move(frame), ended] {
            if (auto self = weak.lock()) self->Push(frame, ended);
          });
        });
    auto header = StreamHeader("text/event-stream");
    header->set("X-Accel-Buffering", "no");
    auto serializer = std::make_shared<bhttp::response_serializer<bhttp::empty_body>>(*header);
    writing_ = true;
    conn_->Lowest().expires_after(Seconds(shared_->options.write_timeout_s));
    bhttp::async_write_header(
        conn_->stream(), *serializer,
        [self = this->shared_from_this(), header, serializer](beast::error_code ec, size_t) {
          if (ec || self->conn_->closed()) return self->conn_->Close();
          self->WriteRaw(std::make_shared<const std::string>("retry: 2000\n\n"));
        });
  }

  void Stop() override { Unsubscribe(); }

 private:
  void Unsubscribe() {
    if (subscription_) {  // never the sampler thread: it holds only a weak reference
      conn_->ctx().sessions->Unsubscribe(subscription_);
      subscription_ = 0;
    }
    if (counted_) shared_->streams.fetch_sub(1), counted_ = false;
  }

  void Push(Frame frame, bool ended) {
    if (conn_->closed()) return;
    if (ended) ending_ = true;
    if (writing_) {
      pending_ = std::move(frame);
      return;
    }
    WriteFrame(std::move(frame));
  }

  // Chosen when written, not when queued: a frame that replaced a pending one still carries the
  // newest surface to a stream that has not written it.
  void WriteFrame(Frame frame) {
    if (frame.has_surface && frame.surface_frame != surface_written_) {
      surface_written_ = frame.surface_frame;
      return WriteRaw(std::move(frame.full));
    }
    WriteRaw(std::move(frame.light));
  }

  void WriteRaw(std::shared_ptr<const std::string> text) {
    writing_ = true;
    conn_->Lowest().expires_after(Seconds(shared_->options.write_timeout_s));
    asio::async_write(conn_->stream(), asio::buffer(*text),
                      [self = this->shared_from_this(), text](beast::error_code ec, size_t) {
                        self->OnWritten(ec);
                      });
  }

  void OnWritten(beast::error_code ec) {
    writing_ = false;
    if (ec || conn_->closed()) return conn_->Close();
    shared_->events.fetch_add(1);
    const auto now = std::chrono::steady_clock::now();
    const uint64_t signouts = conn_->ctx().api->signouts();
    if (std::chrono::duration<double>(now - last_check_).count() > 5 || signouts != signouts_) {
      // A revoked token or a disabled account ends the stream within 5 s; a sign-out (of this
      // web session) at its next frame.
      last_check_ = now;
      signouts_ = signouts;
      if (still_allowed_ && !still_allowed_()) return conn_->Close();
    }
    if (pending_) {
      Frame next = std::move(*pending_);
      pending_.reset();
      return WriteFrame(std::move(next));
    }
    if (ending_) return conn_->Close();
    conn_->Lowest().expires_never();  // waiting for the next frame is not the client's fault
  }

  std::shared_ptr<Connection<Stream>> conn_;
  Shared* shared_;
  HttpReply::Watch watch_;
  std::function<bool()> still_allowed_;
  uint64_t subscription_ = 0;
  bool counted_ = false;  // in shared_->streams
  bool writing_ = false, ending_ = false;
  std::optional<Frame> pending_;
  uint64_t surface_written_ = UINT64_MAX;  // the surface frame this stream last wrote
  uint64_t signouts_ = 0;  // HttpApi::signouts when this stream last checked its caller
  std::chrono::steady_clock::time_point last_check_{};
  char hangup_[64];
};

// An export: the store's export runs on the export pool (it blocks on the database, so never on
// the I/O thread; the pool has max_exports workers, not a thread per export) and hands each chunk
// to the I/O thread, which writes it in Beast's chunked encoding; the worker waits until the chunk
// is on the wire before it reads on (one chunk in flight: a million rows stream in bounded
// memory). A client that takes no chunk for export_stall_s is dropped and its slot freed.
template <class Stream>
class ExportStream final : public Exchange,
                           public std::enable_shared_from_this<ExportStream<Stream>> {
 public:
  ExportStream(std::shared_ptr<Connection<Stream>> conn, HttpReply reply)
      : conn_(std::move(conn)), shared_(conn_->ctx().shared), reply_(std::move(reply)) {}

  // False when every export slot (in all or of this user) is taken.
  bool Start() {
    if (!TakeSlot()) return false;
    shared_->streams.fetch_add(1);
    auto header = StreamHeader(reply_.content_type);
    header->set(bhttp::field::content_disposition,
                "attachment; filename=\"" + reply_.filename + "\"");
    header->chunked(true);
    auto serializer = std::make_shared<bhttp::response_serializer<bhttp::empty_body>>(*header);
    conn_->Lowest().expires_after(Seconds(shared_->options.write_timeout_s));
    bhttp::async_write_header(
        conn_->stream(), *serializer,
        [self = this->shared_from_this(), header, serializer](beast::error_code ec, size_t) {
          if (ec || self->conn_->closed()) {
            self->Finish();
            return self->conn_->Close();
          }
          asio::post(*self->conn_->ctx().export_pool, [self] { self->Run(); });
        });
    return true;
  }

  // The connection closed (client gone, stalled, server stopping): a waiting worker goes on.
  void Stop() override {
    std::lock_guard<std::mutex> lock(gate_mutex_);
    stopped_ = true;
    gate_.notify_all();
  }

 private:
  enum class Chunk { kNone, kPending, kWritten, kFailed };

  // Export pool.
  void Run() {
    const ExportPlan& plan = reply_.export_plan;
    const auto sink = [&](std::string_view chunk) {
      return chunk.empty() || Send(std::make_shared<const std::string>(chunk));
    };
    const Status s = reply_.produce ? reply_.produce(sink)
                                    : conn_->ctx().store->Export(plan.filter, plan.format, sink);
    // The slot back before the end goes on the wire, so that a client that received a whole
    // export may start the next at once (under load the worker ran Finish after the client had
    // asked again, and got 503); the worker does not wait for the last chunk either. The last
    // chunk only after a complete export: a failed one ends without it, so the client sees an
    // incomplete download.
    Finish();
    asio::post(shared_->io, [self = this->shared_from_this(), complete = s.ok()] {
      if (!complete || self->conn_->closed()) return self->conn_->Close();
      self->conn_->Lowest().expires_after(Seconds(self->shared_->options.export_stall_s));
      asio::async_write(self->conn_->stream(), bhttp::make_chunk_last(),
                        [self](beast::error_code, size_t) { self->conn_->Close(); });
    });
  }

  // Export pool: a chunk through the I/O thread; returns once it is on the wire (true) or cannot
  // be (false).
  bool Send(std::shared_ptr<const std::string> text) {
    {
      std::lock_guard<std::mutex> lock(gate_mutex_);
      if (stopped_) return false;
      chunk_ = Chunk::kPending;
    }
    asio::post(shared_->io, [self = this->shared_from_this(), text] {
      if (self->conn_->closed()) return self->Settle(false);
      // A client that stops reading frees its slot after export_stall_s, not write_timeout_s.
      self->conn_->Lowest().expires_after(Seconds(self->shared_->options.export_stall_s));
      asio::async_write(self->conn_->stream(), bhttp::make_chunk(asio::buffer(*text)),
                        [self, text](beast::error_code ec, size_t) { self->Settle(!ec); });
    });
    std::unique_lock<std::mutex> lock(gate_mutex_);
    gate_.wait(lock, [&] { return chunk_ != Chunk::kPending || stopped_; });
    return chunk_ == Chunk::kWritten && !stopped_;
  }

  void Settle(bool written) {  // I/O thread
    std::lock_guard<std::mutex> lock(gate_mutex_);
    chunk_ = written ? Chunk::kWritten : Chunk::kFailed;
    gate_.notify_all();
  }

  // An export slot: in all and per user (a user's stalled downloads hold only their own).
  bool TakeSlot() {
    std::lock_guard<std::mutex> lock(shared_->mutex);
    int& mine = shared_->exports_by_user[reply_.owner];
    if (shared_->exports.load() >= shared_->options.max_exports ||
        mine >= shared_->options.max_exports_per_user) {
      if (mine == 0) shared_->exports_by_user.erase(reply_.owner);
      return false;
    }
    ++mine;
    shared_->exports.fetch_add(1);
    return true;
  }
  void Finish() {  // the slot back, once
    if (finished_.exchange(true)) return;
    {
      std::lock_guard<std::mutex> lock(shared_->mutex);
      if (--shared_->exports_by_user[reply_.owner] <= 0)
        shared_->exports_by_user.erase(reply_.owner);
      shared_->exports.fetch_sub(1);
    }
    shared_->streams.fetch_sub(1);
  }

  std::shared_ptr<Connection<Stream>> conn_;
  Shared* shared_;
  HttpReply reply_;
  std::atomic<bool> finished_{false};
  std::mutex gate_mutex_;
  std::condition_variable gate_;
  Chunk chunk_ = Chunk::kNone;
  bool stopped_ = false;
};

template <class Stream>
std::shared_ptr<Exchange> Connection<Stream>::StartExchange(HttpReply reply) {
  auto self = this->shared_from_this();
  if (reply.kind == HttpReply::Kind::kEvents) {
    auto events = std::make_shared<EventStream<Stream>>(self, std::move(reply));
    events->Start();
    return events;
  }
  auto exporting = std::make_shared<ExportStream<Stream>>(self, std::move(reply));
  if (exporting->Start()) return exporting;
  HttpReply busy = HttpApi::ErrorReply(
      Error{ErrorCode::kUnavailable,
            "too many exports at once (yours or the server's); try again shortly", ""});
  busy.headers.emplace_back("Retry-After", "5");
  Write(std::move(busy));
  return nullptr;
}

}  // namespace

struct HttpServer::Impl {
  HttpServerOptions options;
  db::Store& store;
  Sessions& sessions;
  SceneCatalog scenes;
  Domain domain;
  std::unique_ptr<HttpApi> api;
  std::shared_ptr<Shared> shared = std::make_shared<Shared>();
  std::optional<asio::ssl::context> ssl;
  std::optional<tcp::acceptor> acceptor;
  std::list<std::weak_ptr<ConnectionBase>> connections;  // I/O thread only
  std::optional<asio::thread_pool> export_pool;          // max_exports workers
  std::thread thread;
  int port = 0;
  std::once_flag shutdown_once;

  Impl(db::Store& s, Sessions& m, const HttpServerOptions& o)
      : options(o), store(s), sessions(m), domain{s, m, scenes, o.backup_dir} {}

  Context MakeContext() {
    return Context{shared.get(), shared, api.get(), &store, &sessions, &*export_pool, &connections};
  }

  void Accept() {
    acceptor->async_accept(shared->io, [this](beast::error_code ec, tcp::socket socket) {
      if (ec == asio::error::operation_aborted || !acceptor->is_open()) return;
      if (!ec) Admit(std::move(socket));
      Accept();
    });
  }

  // Every connection is taken: closes the oldest idle connection of the address holding the
  // most connections, when that address holds more than `held` (the newcomer's). shared->mutex
  // held; I/O thread. Its counts fall when it is destroyed, moments later.
  bool EvictIdleFor(int held) {
    std::shared_ptr<ConnectionBase> victim;
    int victim_held = held;
    for (auto& w : connections) {
      auto c = w.lock();
      if (!c || !c->Idle()) continue;
      const auto it = shared->per_address.find(c->remote());
      const int n = it == shared->per_address.end() ? 0 : it->second;
      if (n > victim_held || (victim && n == victim_held && c->idle_since < victim->idle_since)) {
        victim = c;
        victim_held = n;
      }
    }
    if (!victim) return false;
    shared->evicted.fetch_add(1);
    victim->Close();
    return true;
  }

  void Admit(tcp::socket socket) {
    beast::error_code ec;
    const auto remote = socket.remote_endpoint(ec);
    if (ec) return;
    const std::string address = remote.address().to_string();
    {
      std::lock_guard<std::mutex> lock(shared->mutex);
      const int open = shared->open.load();
      const int held = shared->per_address[address];
      // The share an address may hold falls as the total fills (see the header).
      const int share = std::min(
          options.max_connections_per_address,
          std::max(options.min_connections_per_address, (options.max_connections - open) / 4));
      bool admit = held < share && open < options.max_connections;
      if (!admit && held < share && EvictIdleFor(held)) admit = true;
      if (!admit) {
        shared->refused.fetch_add(1);
        // Best effort, never blocking the I/O thread: a 503 if the socket takes it now.
        static constexpr char kBusy[] =
            "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
            "Retry-After: 5\r\nConnection: close\r\nContent-Length: 51\r\n\r\n"
            "{\"error\":\"too many connections; try again shortly\"}";
        socket.non_blocking(true, ec);
        socket.write_some(asio::buffer(kBusy, sizeof kBusy - 1), ec);
        socket.close(ec);
        if (shared->per_address[address] == 0) shared->per_address.erase(address);
        return;
      }
      ++shared->per_address[address];
      shared->open.fetch_add(1);
    }
    socket.set_option(tcp::no_delay(true), ec);
    std::shared_ptr<ConnectionBase> c;
    if (ssl) {
      auto conn = std::make_shared<Connection<beast::ssl_stream<beast::tcp_stream>>>(
          MakeContext(), address, std::move(socket), *ssl);
      conn->Begin();
      c = conn;
    } else {
      auto conn = std::make_shared<Connection<beast::tcp_stream>>(MakeContext(), address,
                                                                  std::move(socket));
      conn->Begin();
      c = conn;
    }
    connections.remove_if([](const std::weak_ptr<ConnectionBase>& w) { return w.expired(); });
    connections.push_back(c);
  }
};

HttpServer::HttpServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
HttpServer::~HttpServer() {
  Shutdown();
}
int HttpServer::port() const {
  return impl_->port;
}
bool HttpServer::tls() const {
  return impl_->ssl.has_value();
}

HttpCounters HttpServer::counters() const {
  const Shared& s = *impl_->shared;
  HttpCounters c;
  c.requests = s.requests.load();
  c.refused_connections = s.refused.load();
  c.bad_requests = s.bad.load();
  c.events_sent = s.events.load();
  c.evicted_connections = s.evicted.load();
  c.open_connections = s.open.load();
  c.open_streams = s.streams.load();
  return c;
}

Expected<std::unique_ptr<HttpServer>> HttpServer::Start(db::Store& store, Sessions& sessions,
                                                        const HttpServerOptions& options) {
  auto impl = std::make_unique<Impl>(store, sessions, options);
  impl->shared->options = options;
  if (options.tls_cert_file.empty() != options.tls_key_file.empty())
    return InvalidArgument("tls", "a certificate and its key are both required");
  if (!options.tls_cert_file.empty()) {
    impl->ssl.emplace(asio::ssl::context::tls_server);
    beast::error_code ec;
    impl->ssl->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 |
                               asio::ssl::context::no_sslv3 | asio::ssl::context::no_tlsv1 |
                               asio::ssl::context::no_tlsv1_1,
                           ec);
    impl->ssl->use_certificate_chain_file(options.tls_cert_file, ec);
    if (ec)
      return InvalidArgument("tls_cert",
                             "cannot use " + options.tls_cert_file + ": " + ec.message());
    impl->ssl->use_private_key_file(options.tls_key_file, asio::ssl::context::pem, ec);
    if (ec)
      return InvalidArgument("tls_key", "cannot use " + options.tls_key_file + ": " + ec.message());
  } else if (!IsLoopbackHost(options.listen) && !options.allow_insecure) {
    return InvalidArgument("http",
                           "plaintext HTTP only on loopback; configure a TLS certificate "
                           "(or allow insecure explicitly)");
  }
  // host:port, [v6]:port
  const std::string& listen = options.listen;
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == listen.size())
    return InvalidArgument("http", "'" + listen + "' is not HOST:PORT");
  std::string host = listen.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  int port = -1;
  try {
    size_t used = 0;
    port = std::stoi(listen.substr(colon + 1), &used);
    if (used != listen.size() - colon - 1) port = -1;
  } catch (const std::exception&) {
    port = -1;
  }
  if (port < 0 || port > 65535) return InvalidArgument("http", "'" + listen + "': bad port");
  beast::error_code ec;
  asio::ip::address address;
  if (host == "localhost") {
    address = asio::ip::make_address("127.0.0.1");
  } else {
    address = asio::ip::make_address(host, ec);
    if (ec) return InvalidArgument("http", "'" + host + "' is not an IP address");
  }
  http::HttpApiOptions ao;
  ao.session_ttl_s = options.session_ttl_s;
  ao.secure_cookies = impl->ssl.has_value();
  ao.clock = options.clock;
  ao.metrics = options.metrics;
  ao.metrics_only = options.metrics_only;
  ao.metrics_token = options.metrics_token;
  ao.oidc = options.oidc;
  impl->api = std::make_unique<HttpApi>(impl->domain, ao);
  impl->acceptor.emplace(impl->shared->io);
  const tcp::endpoint endpoint(address, static_cast<uint16_t>(port));
  impl->acceptor->open(endpoint.protocol(), ec);
  if (!ec) impl->acceptor->set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) impl->acceptor->bind(endpoint, ec);
  if (!ec) impl->acceptor->listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    return Error{ErrorCode::kIoError, "cannot listen on " + listen + ": " + ec.message(), "http"};
  impl->port = impl->acceptor->local_endpoint().port();
  Impl* p = impl.get();
  p->export_pool.emplace(static_cast<size_t>(std::max(1, options.max_exports)));
  p->Accept();
  p->thread = std::thread([p] {
    NameThisThread("vsurg-http");
    p->shared->io.run();
  });
  return std::unique_ptr<HttpServer>(new HttpServer(std::move(impl)));
}

void HttpServer::Shutdown() {
  std::call_once(impl_->shutdown_once, [this] {
    Impl* p = impl_.get();
    if (p->thread.joinable()) {
      asio::post(p->shared->io, [p] {
        beast::error_code ec;
        p->acceptor->close(ec);
        for (auto& w : p->connections)
          if (auto c = w.lock()) c->Close();  // ends the event streams' subscriptions
        p->connections.clear();
        p->shared->io.stop();
      });
      p->thread.join();
    }
    // Every export's connection was closed above, so a worker waiting on a chunk goes on.
    if (p->export_pool) p->export_pool->join();
  });
}

}  // namespace vsurg::server
