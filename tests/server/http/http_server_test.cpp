// The dashboard's listener on loopback (server/http/http_server.h): real sockets, a real SQLite
// file, the session manager; a Beast client for well-formed requests and raw sockets for the
// bad ones. What one client does never stops the server from answering the others.
#include "server/http/http_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <vector>

#include "db/store.h"
#include "server/session/session_manager.h"
#include "tests/support/self_signed.h"
#include "tests/support/site.h"
#include "tests/support/temp_dir.h"
#include "tests/support/wait.h"

namespace vsurg::server {
namespace {

namespace fs = std::filesystem;
namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;
using nlohmann::json;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;

struct Response {
  int status = 0;
  std::map<std::string, std::string> headers;
  std::string body;
  std::string Header(const std::string& name) const {
    const auto it = headers.find(name);
    return it == headers.end() ? std::string() : it->second;
  }
};

template <class Stream>
Response Exchange(Stream& stream, const std::string& method, const std::string& target,
                  const std::map<std::string, std::string>& headers, const std::string& body) {
  bhttp::request<bhttp::string_body> req(bhttp::string_to_verb(method), target, 11);
  req.set(bhttp::field::host, "127.0.0.1");
  for (const auto& [k, v] : headers) req.set(k, v);
  if (!body.empty()) req.set(bhttp::field::content_type, "application/json");
  req.body() = body;
  req.prepare_payload();
  bhttp::write(stream, req);
  beast::flat_buffer buffer;
  bhttp::response_parser<bhttp::string_body> parser;
  parser.body_limit(64 << 20);
  bhttp::read(stream, buffer, parser);
  Response r;
  r.status = static_cast<int>(parser.get().result_int());
  for (const auto& f : parser.get())
    r.headers[std::string(f.name_string())] = std::string(f.value());
  r.body = parser.get().body();
  return r;
}

Response Request(int port, const std::string& method, const std::string& target,
                 const std::map<std::string, std::string>& headers = {},
                 const std::string& body = "") {
  asio::io_context io;
  tcp::socket socket(io);
  socket.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)));
  return Exchange(socket, method, target, headers, body);
}

// A raw TCP client: sends bytes, reads whatever comes until the server closes or `timeout_s`.
class Raw {
 public:
  // `from`: the loopback source address (127.0.0.0/8: every one of them is this machine's), so
  // one test can be several clients; `rcvbuf`: a small receive buffer for a client that will
  // not read (0: the kernel's).
  explicit Raw(int port, const char* from = nullptr, int rcvbuf = 0) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (rcvbuf > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    if (from) {
      sockaddr_in src{};
      src.sin_family = AF_INET;
      ::inet_pton(AF_INET, from, &src.sin_addr);
      if (::bind(fd_, reinterpret_cast<sockaddr*>(&src), sizeof src) != 0) return;
    }
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~Raw() { ::close(fd_); }
  bool connected() const { return connected_; }
  bool Send(const std::string& s) {
    return ::send(fd_, s.data(), s.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(s.size());
  }
  // Reads until the peer closes (true) or the time runs out (false); `out` gets the bytes.
  bool ReadUntilClosed(double timeout_s, std::string& out) {
    timeval tv{0, 100000};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    const auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
    char buf[4096];
    while (Clock::now() < end) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n == 0) return true;
      if (n > 0)
        out.append(buf, static_cast<size_t>(n));
      else if (errno != EAGAIN && errno != EWOULDBLOCK)
        return true;  // reset: closed too
    }
    return false;
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

class HttpServerTest : public test::SiteTest {
 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(OpenSite());
    AddUsers({{"tina", db::Role::kTrainee, "novice"}, {"eve", db::Role::kEvaluator, "chief"}});
  }
  void Start(HttpServerOptions o = {}) {
    o.backup_dir = backups();
    auto s = HttpServer::Start(*store_, *sessions_, o);
    ASSERT_TRUE(s.ok()) << s.error().message;
    server_ = std::move(s).value();
    port_ = server_->port();
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
    server_.reset();
    SiteTest::TearDown();
  }
  std::map<std::string, std::string> Bearer() { return {{"Authorization", "Bearer " + admin_}}; }

  std::unique_ptr<HttpServer> server_;
  int port_ = 0;
};

TEST_F(HttpServerTest, SignsInServesPagesAndStreamsTheLiveSessions) {
  Start();
  const Response page = Request(port_, "GET", "/signin");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.Header("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
  EXPECT_EQ(page.Header("X-Frame-Options"), "DENY");
  EXPECT_EQ(Request(port_, "GET", "/static/app.js").status, 200);
  EXPECT_EQ(Request(port_, "GET", "/api/v1/users").status, 401);

  const Response in = Request(port_, "POST", "/api/v1/signin", {}, json{{"token", admin_}}.dump());
  ASSERT_EQ(in.status, 200) << in.body;
  const std::string cookie = in.Header("Set-Cookie").substr(0, in.Header("Set-Cookie").find(';'));
  EXPECT_EQ(Request(port_, "GET", "/live", {{"Cookie", cookie}}).status, 200);

  // A session prepared for tina shows in the live stream with her name and its state.
  const Response created = Request(
      port_, "POST", "/api/v1/sessions",
      {{"Cookie", cookie}, {"X-CSRF-Token", json::parse(in.body)["csrf"].get<std::string>()}},
      json{{"trainee", "tina"}, {"scene", "arm-torsion"}}.dump());
  ASSERT_EQ(created.status, 201) << created.body;
  EXPECT_FALSE(json::parse(created.body).contains("session_key")) << "the key goes to the station";
  asio::io_context io;
  tcp::socket socket(io);
  socket.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_)));
  const std::string req =
      "GET /api/v1/live/events HTTP/1.1\r\nHost: 127.0.0.1\r\nCookie: " + cookie + "\r\n\r\n";
  asio::write(socket, asio::buffer(req));
  std::string got;
  const auto end = Clock::now() + std::chrono::seconds(10);
  int frames = 0;
  while (Clock::now() < end && frames < 3) {
    char buf[4096];
    const size_t n = socket.read_some(asio::buffer(buf));
    got.append(buf, n);
    frames = 0;
    for (size_t at = got.find("data: [{"); at != std::string::npos;
         at = got.find("data: [{", at + 1))
      ++frames;
  }
  EXPECT_NE(got.find("Content-Type: text/event-stream"), std::string::npos);
  EXPECT_GE(frames, 3) << got;
  EXPECT_NE(got.find("\"trainee\":\"tina\""), std::string::npos);
  EXPECT_NE(got.find("\"state\":\"created\""), std::string::npos);
  EXPECT_EQ(server_->counters().open_streams, 1);
  socket.close();
  EXPECT_TRUE(test::Eventually(5, [&] { return server_->counters().open_streams == 0; }))
      << "a client that hangs up ends its stream";
}

// A session page's stream carries the deformed surface (~125 KB for a twisted arm) only when it
// changed since that stream last carried it; a watcher keeps the last one. A prepared session's
// surface stays at rest, so each stream gets it once, first, and then frames without it.
TEST_F(HttpServerTest, ASessionStreamSendsTheSurfaceOnlyWhenItChanged) {
  Start();
  const Response created = Request(port_, "POST", "/api/v1/sessions", Bearer(),
                                   json{{"trainee", "tina"}, {"scene", "arm-torsion"}}.dump());
  ASSERT_EQ(created.status, 201) << created.body;
  const std::string id = std::to_string(json::parse(created.body)["session"]["id"].get<uint64_t>());
  auto frames_of_one_stream = [&] {
    asio::io_context io;
    tcp::socket socket(io);
    socket.connect(
        tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_)));
    const std::string req = "GET /api/v1/sessions/" + id +
                            "/events HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer " +
                            admin_ + "\r\n\r\n";
    asio::write(socket, asio::buffer(req));
    std::string got;
    std::vector<std::string> frames;
    const auto end = Clock::now() + std::chrono::seconds(10);
    while (Clock::now() < end && frames.size() < 5) {
      char buf[4096];
      got.append(buf, socket.read_some(asio::buffer(buf)));
      frames.clear();
      for (size_t at = got.find("data: {"); at != std::string::npos;) {
        const size_t stop = got.find("\n\n", at);
        if (stop == std::string::npos) break;
        frames.push_back(got.substr(at, stop - at));
        at = got.find("data: {", stop);
      }
    }
    return frames;
  };
  for (int stream = 0; stream < 2; ++stream) {
    const std::vector<std::string> frames = frames_of_one_stream();
    ASSERT_GE(frames.size(), 5u) << "stream " << stream;
    EXPECT_NE(frames[0].find("\"surface\""), std::string::npos) << "the first frame: " << frames[0];
    for (size_t k = 1; k < frames.size(); ++k)
      EXPECT_EQ(frames[k].find("\"surface\""), std::string::npos)
          << "stream " << stream << " frame " << k << " repeats an unchanged surface";
    EXPECT_NE(frames.back().find("\"state\":\"created\""), std::string::npos) << frames.back();
  }
}

TEST_F(HttpServerTest, SlowOversizedAndMalformedRequestsAreCutOffWhileOthersAreServed) {
  HttpServerOptions o;
  o.request_timeout_s = 1;
  o.max_header_bytes = 8192;
  o.max_body_bytes = 4096;
  Start(o);
  // Slowloris: a header that never ends, one byte at a time.
  Raw slow(port_);
  ASSERT_TRUE(slow.Send("GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\n"));
  const auto t0 = Clock::now();
  bool closed = false;
  std::string ignored;
  for (int i = 0; i < 40 && !closed; ++i) {
    slow.Send("X");
    closed = slow.ReadUntilClosed(0.1, ignored);
  }
  const double held = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_TRUE(closed) << "the server closes a request that takes longer than its deadline";
  EXPECT_LT(held, 3.5);

  Raw big_header(port_);
  big_header.Send("GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Pad: " + std::string(20000, 'a') +
                  "\r\n\r\n");
  std::string answer;
  big_header.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 431", 0), 0u) << answer.substr(0, 80);

  Raw big_body(port_);
  big_body.Send(
      "POST /api/v1/signin HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
      "Content-Length: 10000000\r\n\r\n{");
  answer.clear();
  big_body.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 413", 0), 0u) << answer.substr(0, 80);

  Raw garbage(port_);
  garbage.Send("HELLO THERE\r\n\r\n");
  answer.clear();
  garbage.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 400", 0), 0u) << answer.substr(0, 80);

  Raw verb(port_);
  verb.Send("DELETE /api/v1/users HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  answer.clear();
  verb.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 405", 0), 0u) << answer.substr(0, 80);

  EXPECT_GE(server_->counters().bad_requests, 4u);
  EXPECT_EQ(Request(port_, "GET", "/signin").status, 200);
  EXPECT_EQ(store_->ListUsers().value().size(), 3u) << "nothing was written";
}

TEST_F(HttpServerTest, ConnectionsAreLimitedPerAddressAndFreedWhenClosed) {
  HttpServerOptions o;
  o.max_connections_per_address = 4;
  o.request_timeout_s = 30;
  Start(o);
  std::vector<std::unique_ptr<Raw>> idle;
  for (int i = 0; i < 4; ++i) idle.push_back(std::make_unique<Raw>(port_));
  ASSERT_TRUE(test::Eventually(5, [&] { return server_->counters().open_connections >= 4; }));
  Raw fifth(port_);
  std::string answer;
  EXPECT_TRUE(fifth.ReadUntilClosed(5, answer));
  EXPECT_EQ(answer.rfind("HTTP/1.1 503", 0), 0u) << answer;
  EXPECT_GE(server_->counters().refused_connections, 1u);
  idle.pop_back();  // one hangs up: there is room again
  ASSERT_TRUE(test::Eventually(5, [&] { return server_->counters().open_connections <= 3; }));
  EXPECT_EQ(Request(port_, "GET", "/signin").status, 200);
}

TEST_F(HttpServerTest, AnExportStreamsEveryRowAsTheStoreHasIt) {
  Start();
  for (int k = 0; k < 300; ++k) {
    db::Submission s;
    s.idempotency_key = "k" + std::to_string(k);
    s.evaluator = "eve";
    s.evaluator_group = "chief";
    s.subject_kind = db::SubjectKind::kModel;
    s.subject = "model-" + std::to_string(k);
    s.submitted_by = "eve";
    for (int j = 0; j < 9; ++j) s.scores[j] = (k + j) % 11;
    ASSERT_TRUE(store_->SubmitEvaluation(s).ok());
  }
  for (const char* format : {"csv", "jsonl", "xapi"}) {
    std::string expected;
    ASSERT_TRUE(store_
                    ->Export({}, db::ParseExportFormat(format).value(),
                             [&](std::string_view c) {
                               expected.append(c);
                               return true;
                             })
                    .ok());
    const Response r =
        Request(port_, "GET", std::string("/api/v1/export?format=") + format, Bearer());
    ASSERT_EQ(r.status, 200);
    EXPECT_EQ(r.Header("Transfer-Encoding"), "chunked");
    EXPECT_NE(r.Header("Content-Disposition").find("attachment"), std::string::npos);
    EXPECT_EQ(r.body, expected) << format;
    EXPECT_GT(r.body.size(), 10000u);
  }
  // Filtered, and a refused filter.
  EXPECT_EQ(Request(port_, "GET", "/api/v1/export?format=csv&session=abc", Bearer()).status, 400);
}

// RFC 9112 §6.3: a request whose body length is ambiguous is refused with 400 and its connection
// closed, so a request hidden in its body (smuggled past a proxy that framed it otherwise) is
// never served. A lone `Transfer-Encoding: chunked` still works.
TEST_F(HttpServerTest, AmbiguouslyFramedRequestsAreRefusedAndNothingHiddenInThemIsServed) {
  Start();
  const std::string hidden =
      "GET /api/v1/users HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer " + admin_ +
      "\r\n\r\n";
  for (const std::string framing :
       {"Transfer-Encoding: chunked, identity\r\nContent-Length: 0\r\n",
        "Transfer-Encoding: identity\r\nContent-Length: 0\r\n",
        "Transfer-Encoding: xchunked\r\nContent-Length: 0\r\n",
        "Transfer-Encoding: chunked\r\nContent-Length: 0\r\n",
        "Transfer-Encoding: chunked\r\nTransfer-Encoding: chunked\r\n",
        "Transfer-Encoding: gzip, chunked\r\n", "Transfer-Encoding: identity\r\n"}) {
    SCOPED_TRACE(framing);
    Raw raw(port_);
    ASSERT_TRUE(raw.Send("POST /api/v1/signin HTTP/1.1\r\nHost: 127.0.0.1\r\n" + framing + "\r\n" +
                         hidden));
    std::string answer;
    EXPECT_TRUE(raw.ReadUntilClosed(5, answer)) << "the connection is closed";
    EXPECT_EQ(answer.rfind("HTTP/1.1 400", 0), 0u) << answer.substr(0, 120);
    size_t responses = 0;
    for (size_t at = answer.find("HTTP/1.1 "); at != std::string::npos;
         at = answer.find("HTTP/1.1 ", at + 1))
      ++responses;
    EXPECT_EQ(responses, 1u) << "the hidden request was served: " << answer;
    EXPECT_EQ(answer.find("\"users\""), std::string::npos);
  }
  // Chunked alone is fine: a sign-in in two chunks.
  const std::string body = json{{"token", admin_}}.dump();
  Raw chunked(port_);
  std::ostringstream hex;
  hex << std::hex << 5 << "\r\n"
      << body.substr(0, 5) << "\r\n"
      << (body.size() - 5) << "\r\n"
      << body.substr(5) << "\r\n0\r\n\r\n";
  ASSERT_TRUE(chunked.Send(
      "POST /api/v1/signin HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
      "Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n" +
      hex.str()));
  std::string answer;
  chunked.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << answer.substr(0, 200);
}

// DNS rebinding: a page on evil.example that resolves to this server gets nothing; IP literals,
// localhost and the configured names are served.
TEST_F(HttpServerTest, OnlyConfiguredHostNamesAreServed) {
  HttpServerOptions o;
  o.hosts = {"dashboard.example.org"};
  Start(o);
  for (const char* host : {"evil.example", "evil.example:8080", "dashboard.example.org.evil"}) {
    EXPECT_EQ(Request(port_, "GET", "/api/v1/users",
                      {{"Host", host}, {"Authorization", "Bearer " + admin_}})
                  .status,
              421)
        << host;
  }
  for (const char* host : {"127.0.0.1", "localhost:1234", "Dashboard.Example.org"})
    EXPECT_EQ(Request(port_, "GET", "/signin", {{"Host", host}}).status, 200) << host;
  Raw none(port_);
  none.Send("GET /signin HTTP/1.0\r\n\r\n");
  std::string answer;
  none.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.rfind("HTTP/1.1 421", 0), 0u) << answer.substr(0, 80);
}

// A few addresses cannot take every connection: their share falls as the total fills, and when
// it is full an idle connection of the address holding the most is closed for a newcomer. A
// legitimate user still signs in, from an address of their own.
TEST_F(HttpServerTest, AFewAddressesCannotTakeEveryConnection) {
  HttpServerOptions o;
  o.max_connections = 128;
  o.max_connections_per_address = 64;
  o.request_timeout_s = 60;
  Start(o);
  std::vector<std::unique_ptr<Raw>> held;
  auto settle = [&] {
    int last = -1;
    for (int i = 0; i < 100 && server_->counters().open_connections != last; ++i) {
      last = server_->counters().open_connections;
      std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
  };
  // 8 addresses × 64 half-sent requests (the attack that took all 512 before).
  for (int a = 2; a <= 9; ++a)
    for (int i = 0; i < 64; ++i) {
      const std::string from = "127.0.0." + std::to_string(a);
      held.push_back(std::make_unique<Raw>(port_, from.c_str()));
      held.back()->Send("GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\n");
    }
  settle();
  const HttpCounters c = server_->counters();
  EXPECT_LT(c.open_connections, o.max_connections) << "8 addresses took every connection";
  EXPECT_GT(c.refused_connections, 0u);
  auto sign_in = [&](const char* from) {
    Raw user(port_, from);
    user.Send(
        "POST /api/v1/signin HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: "
        "application/json\r\nConnection: close\r\nContent-Length: " +
        std::to_string(json{{"token", admin_}}.dump().size()) + "\r\n\r\n" +
        json{{"token", admin_}}.dump());
    std::string answer;
    user.ReadUntilClosed(10, answer);
    return answer.substr(0, 12);
  };
  EXPECT_EQ(sign_in("127.0.0.100"), "HTTP/1.1 200");
  // Many addresses, each within its share, fill the rest: a newcomer gets in by closing an idle
  // connection of the address holding the most.
  for (int a = 10; a <= 60; ++a)
    for (int i = 0; i < 4; ++i) {
      const std::string from = "127.0.0." + std::to_string(a);
      held.push_back(std::make_unique<Raw>(port_, from.c_str()));
    }
  settle();
  EXPECT_EQ(sign_in("127.0.0.101"), "HTTP/1.1 200");
  EXPECT_GT(server_->counters().evicted_connections, 0u);
}

// An export whose client stops reading holds one slot of its user's only, and only until
// export_stall_s: another user's export goes through meanwhile, and the same user's next one
// after it.
TEST_F(HttpServerTest, AStalledExportHoldsOnlyItsOwnersSlotAndOnlyBriefly) {
  HttpServerOptions o;
  o.export_stall_s = 1;
  o.write_timeout_s = 30;
  Start(o);
  ASSERT_TRUE(store_->CreateUser("root2", db::Role::kAdmin, "").ok());
  const std::string other = store_->IssueToken("root2", "test").value();
  db::Submission first;
  first.idempotency_key = "k0";
  first.evaluator = "eve";
  first.evaluator_group = "chief";
  first.subject_kind = db::SubjectKind::kModel;
  first.subject = "model-0";
  first.submitted_by = "eve";
  ASSERT_TRUE(store_->SubmitEvaluation(first).ok());
  // 20,000 submissions (180,000 rows, ~15 MB of CSV): more than every socket buffer holds.
  ASSERT_TRUE(store_
                  ->Write([](db::Connection& c) {
                    return c.Exec(
                        "WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < "
                        "20000) INSERT INTO submissions(idempotency_key, evaluator_id, "
                        "evaluator_group, subject_kind, subject, moment_min, submitted_us, "
                        "submitted_by) SELECT 'bulk-' || i, evaluator_id, evaluator_group, "
                        "subject_kind, 'model-bulk-' || i, moment_min, submitted_us + i, "
                        "submitted_by FROM n, submissions WHERE idempotency_key = 'k0'; "
                        "INSERT INTO evaluations(submission_id, index_no, score) SELECT s.id, "
                        "e.index_no, e.score FROM submissions s, evaluations e, submissions f "
                        "WHERE s.idempotency_key LIKE 'bulk-%' AND f.idempotency_key = 'k0' AND "
                        "e.submission_id = f.id");
                  })
                  .ok());
  const std::string ask =
      "GET /api/v1/export?format=csv HTTP/1.1\r\nHost: 127.0.0.1\r\n"
      "Authorization: Bearer " +
      admin_ + "\r\n\r\n";
  // The exports run on the server's pool: none starts a thread of its own.
  const auto threads = [] {
    size_t n = 0;
    for ([[maybe_unused]] const auto& t : std::filesystem::directory_iterator("/proc/self/task"))
      ++n;
    return n;
  };
  const size_t threads_before = threads();
  Raw stalled(port_, nullptr, 4096);
  ASSERT_TRUE(stalled.Send(ask));  // and never reads
  ASSERT_TRUE(test::Eventually(10, [&] { return server_->counters().open_streams >= 1; }));
  ASSERT_EQ(server_->counters().open_streams, 1);
  EXPECT_EQ(threads(), threads_before) << "an export started a thread of its own";
  // The same user again: refused at once (their one slot is taken).
  EXPECT_EQ(Request(port_, "GET", "/api/v1/export?format=csv", Bearer()).status, 503);
  // Another user: served in full meanwhile.
  const Response theirs =
      Request(port_, "GET", "/api/v1/export?format=csv", {{"Authorization", "Bearer " + other}});
  EXPECT_EQ(theirs.status, 200);
  EXPECT_GT(theirs.body.size(), 10'000'000u);
  // The stalled one is dropped after export_stall_s, and the slot is its user's again.
  EXPECT_TRUE(test::Eventually(20, [&] { return server_->counters().open_streams == 0; }))
      << "a reader that stopped kept its slot";
  EXPECT_EQ(Request(port_, "GET", "/api/v1/export?format=jsonl&session=1", Bearer()).status, 200);
}

// Signing out ends the web session's event streams at their next frame (the token itself stays
// valid: another web session of the same user keeps streaming).
TEST_F(HttpServerTest, SigningOutEndsThatWebSessionsEventStreams) {
  Start();
  auto sign_in = [&] {
    const Response in =
        Request(port_, "POST", "/api/v1/signin", {}, json{{"token", admin_}}.dump());
    EXPECT_EQ(in.status, 200);
    return std::pair{in.Header("Set-Cookie").substr(0, in.Header("Set-Cookie").find(';')),
                     json::parse(in.body)["csrf"].get<std::string>()};
  };
  const auto [cookie, csrf] = sign_in();
  const auto [other_cookie, other_csrf] = sign_in();
  Raw mine(port_), theirs(port_);
  ASSERT_TRUE(mine.Send("GET /api/v1/live/events HTTP/1.1\r\nHost: 127.0.0.1\r\nCookie: " + cookie +
                        "\r\n\r\n"));
  ASSERT_TRUE(theirs.Send("GET /api/v1/live/events HTTP/1.1\r\nHost: 127.0.0.1\r\nCookie: " +
                          other_cookie + "\r\n\r\n"));
  ASSERT_TRUE(test::Eventually(10, [&] { return server_->counters().open_streams >= 2; }));
  ASSERT_EQ(server_->counters().open_streams, 2);
  EXPECT_EQ(Request(port_, "POST", "/api/v1/signout", {{"Cookie", cookie}, {"X-CSRF-Token", csrf}})
                .status,
            204);
  std::string got;
  EXPECT_TRUE(mine.ReadUntilClosed(3, got)) << "the signed-out stream went on";
  EXPECT_TRUE(test::Eventually(5, [&] { return server_->counters().open_streams <= 1; }));
  EXPECT_EQ(server_->counters().open_streams, 1) << "the other web session's stream ended too";
}

TEST_F(HttpServerTest, HttpsWithTheGrpcCertificateAndNoPlaintextOffLoopback) {
  const auto [cert, key] = test::SelfSigned();
  std::ofstream(dir_ / "cert.pem") << cert;
  std::ofstream(dir_ / "key.pem") << key;
  HttpServerOptions plain;
  plain.listen = "0.0.0.0:0";
  EXPECT_EQ(HttpServer::Start(*store_, *sessions_, plain).error().code,
            ErrorCode::kInvalidArgument);
  HttpServerOptions half;
  half.tls_cert_file = (dir_ / "cert.pem").string();
  EXPECT_FALSE(HttpServer::Start(*store_, *sessions_, half).ok());

  HttpServerOptions o;
  o.tls_cert_file = (dir_ / "cert.pem").string();
  o.tls_key_file = (dir_ / "key.pem").string();
  Start(o);
  EXPECT_TRUE(server_->tls());
  asio::io_context io;
  asio::ssl::context ctx(asio::ssl::context::tls_client);
  ctx.add_certificate_authority(asio::buffer(cert));
  ctx.set_verify_mode(asio::ssl::verify_peer);
  beast::ssl_stream<tcp::socket> stream(io, ctx);
  stream.next_layer().connect(
      tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port_)));
  stream.handshake(asio::ssl::stream_base::client);
  const Response in =
      Exchange(stream, "POST", "/api/v1/signin", {}, json{{"token", admin_}}.dump());
  EXPECT_EQ(in.status, 200);
  EXPECT_NE(in.Header("Set-Cookie").find("; Secure"), std::string::npos);
  // Plaintext on the TLS port gets no page.
  Raw raw(port_);
  raw.Send("GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  std::string answer;
  raw.ReadUntilClosed(5, answer);
  EXPECT_EQ(answer.find("HTTP/1.1 200"), std::string::npos);
}

}  // namespace
}  // namespace vsurg::server
