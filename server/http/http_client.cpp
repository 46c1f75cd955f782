#include "server/http/http_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/version.hpp>
#include <chrono>
#include <optional>

namespace vsurg::server::http {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = boost::beast::http;

struct Url {
  bool tls = false;
  std::string host, port, target;
};

std::optional<Url> ParseUrl(const std::string& url) {
  Url u;
  std::string rest;
  if (url.rfind("http://", 0) == 0) {
    rest = url.substr(7);
  } else if (url.rfind("https://", 0) == 0) {
    u.tls = true;
    rest = url.substr(8);
  } else {
    return std::nullopt;
  }
  const size_t slash = rest.find('/');
  const std::string authority = rest.substr(0, slash);
  u.target = slash == std::string::npos ? "/" : rest.substr(slash);
  const size_t colon = authority.rfind(':');
  u.host = authority.substr(0, colon);
  u.port = colon == std::string::npos ? (u.tls ? "443" : "80") : authority.substr(colon + 1);
  if (u.host.empty() || u.port.empty() || u.host.find('@') != std::string::npos)
    return std::nullopt;
  for (char ch : u.port)
    if (ch < '0' || ch > '9') return std::nullopt;
  return u;
}

bhttp::request<bhttp::string_body> MakeRequest(const FetchRequest& r, const Url& u) {
  bhttp::request<bhttp::string_body> req{r.method == "POST" ? bhttp::verb::post : bhttp::verb::get,
                                         u.target, 11};
  req.set(bhttp::field::host, u.host + ":" + u.port);
  req.set(bhttp::field::user_agent, "vsurg-server");
  req.set(bhttp::field::accept, "application/json");
  if (r.method == "POST") {
    req.set(bhttp::field::content_type, r.content_type);
    req.body() = r.body;
    req.prepare_payload();
  }
  return req;
}

// One exchange on a connected stream (plain or TLS), within the stream's deadline.
template <typename Stream>
Expected<FetchReply> Exchange(Stream& stream, const FetchRequest& r, const Url& u) {
  beast::error_code ec;
  bhttp::write(stream, MakeRequest(r, u), ec);
  if (ec)
    return Error{ErrorCode::kUnavailable, "cannot send to " + u.host + ": " + ec.message(), "url"};
  beast::flat_buffer buffer;
  bhttp::response_parser<bhttp::string_body> parser;
  parser.body_limit(r.max_body);
  bhttp::read(stream, buffer, parser, ec);
  if (ec == bhttp::error::body_limit)
    return Error{ErrorCode::kParseError, u.host + " answered more than the limit", "url"};
  if (ec)
    return Error{ErrorCode::kUnavailable, "no answer from " + u.host + ": " + ec.message(), "url"};
  FetchReply out;
  out.status = static_cast<int>(parser.get().result_int());
  out.content_type = std::string(parser.get()[bhttp::field::content_type]);
  out.body = std::move(parser.get().body());
  return out;
}

}  // namespace

Expected<FetchReply> Fetch(const FetchRequest& r) {
  const auto u = ParseUrl(r.url);
  if (!u) return InvalidArgument("url", "not an http:// or https:// URL: '" + r.url + "'");
  if (r.method != "GET" && r.method != "POST") return InvalidArgument("method", "GET or POST");
  asio::io_context io;
  beast::error_code ec;
  const auto endpoints = asio::ip::tcp::resolver(io).resolve(u->host, u->port, ec);
  if (ec)
    return Error{ErrorCode::kUnavailable, "cannot resolve " + u->host + ": " + ec.message(), "url"};
  const auto deadline = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(r.timeout_s));
  if (!u->tls) {
    beast::tcp_stream stream(io);
    stream.expires_after(deadline);
    stream.connect(endpoints, ec);
    if (ec)
      return Error{ErrorCode::kUnavailable, "cannot connect to " + u->host + ": " + ec.message(),
                   "url"};
    return Exchange(stream, r, *u);
  }
  asio::ssl::context tls(asio::ssl::context::tls_client);
  tls.set_default_verify_paths();
  tls.set_verify_mode(asio::ssl::verify_peer);
  beast::ssl_stream<beast::tcp_stream> stream(io, tls);
  // SNI: SSL_set_tlsext_host_name is a macro with an old-style cast; its call spelled out.
  if (SSL_ctrl(stream.native_handle(), SSL_CTRL_SET_TLSEXT_HOSTNAME, TLSEXT_NAMETYPE_host_name,
               const_cast<char*>(u->host.c_str())) != 1)
    return Error{ErrorCode::kUnavailable, "cannot name the TLS peer " + u->host, "url"};
  stream.set_verify_callback(asio::ssl::host_name_verification(u->host));
  beast::get_lowest_layer(stream).expires_after(deadline);
  beast::get_lowest_layer(stream).connect(endpoints, ec);
  if (!ec) stream.handshake(asio::ssl::stream_base::client, ec);
  if (ec)
    return Error{ErrorCode::kUnavailable, "no TLS connection to " + u->host + ": " + ec.message(),
                 "url"};
  return Exchange(stream, r, *u);
}

}  // namespace vsurg::server::http
