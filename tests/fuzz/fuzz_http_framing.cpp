// libFuzzer target: the dashboard's request header handling (server/http/request_checks.h) as
// the listener applies it, on Beast's own parser: any bytes a client sends.
// Properties: whenever the framing check accepts a header, Beast's idea of the body agrees with
// it (chunked exactly when a lone `Transfer-Encoding: chunked` came, and then no Content-Length;
// otherwise not chunked), so no request can hide inside another's body; a body is then parsed
// to its end or refused, never both; the Host check accepts a name only when it is localhost or
// configured (an IP literal otherwise), and never crashes on any Host.
#include <cctype>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "server/http/request_checks.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

namespace beast = boost::beast;
namespace bhttp = beast::http;

bool HasLetterOutsideBrackets(std::string_view host) {
  if (!host.empty() && host.front() == '[') return false;
  const size_t colon = host.rfind(':');
  const std::string_view name = host.substr(0, colon);
  for (char c : name)
    if (std::isalpha(static_cast<unsigned char>(c))) return true;
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<std::string> names = {"dashboard.example.org"};
  bhttp::request_parser<bhttp::string_body> parser;
  parser.header_limit(16 * 1024);
  parser.body_limit(64 * 1024);
  parser.eager(false);
  beast::error_code ec;
  std::string_view in(reinterpret_cast<const char*>(data), size);
  size_t used = parser.put(boost::asio::buffer(in.data(), in.size()), ec);
  if (ec || !parser.is_header_done()) return 0;
  const auto& req = parser.get();
  std::vector<std::string_view> te;
  for (auto it = req.find(bhttp::field::transfer_encoding);
       it != req.end() && it->name() == bhttp::field::transfer_encoding; ++it)
    te.emplace_back(it->value().data(), it->value().size());
  const int lengths = static_cast<int>(req.count(bhttp::field::content_length));
  const std::string problem = vsurg::server::http::FramingProblem(te, lengths);
  if (problem.empty()) {
    VSURG_FUZZ_CHECK(parser.chunked() == !te.empty());
    if (parser.chunked()) VSURG_FUZZ_CHECK(lengths == 0 && !parser.content_length());
    if (!te.empty()) VSURG_FUZZ_CHECK(te.size() == 1);
    // The body: parsed to its end, or refused; what follows is the next request's, never ours.
    while (!ec && !parser.is_done() && used < in.size()) {
      in.remove_prefix(used);
      used = parser.put(boost::asio::buffer(in.data(), in.size()), ec);
      if (used == 0) break;
    }
    if (parser.is_done() && parser.content_length())
      VSURG_FUZZ_CHECK(req.body().size() == *parser.content_length());
  } else {
    VSURG_FUZZ_CHECK(!te.empty());  // refused only for a Transfer-Encoding
  }
  const auto host_field = req[bhttp::field::host];
  const std::string_view host(host_field.data(), host_field.size());
  if (vsurg::server::http::HostAllowed(host, names) && HasLetterOutsideBrackets(host)) {
    std::string lower;
    for (char c : host.substr(0, host.rfind(':')))
      lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    VSURG_FUZZ_CHECK(lower == "localhost" || lower == "dashboard.example.org");
  }
  return 0;
}
