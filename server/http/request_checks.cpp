#include "server/http/request_checks.h"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>

namespace vsurg::server::http {
namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool EqualsNoCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

}  // namespace

std::string FramingProblem(const std::vector<std::string_view>& te_fields,
                           int content_length_fields) {
  if (te_fields.empty()) return {};
  if (content_length_fields > 0)
    return "Transfer-Encoding and Content-Length together: the body's length is ambiguous";
  if (te_fields.size() > 1) return "more than one Transfer-Encoding field";
  if (!EqualsNoCase(Trim(te_fields.front()), "chunked"))
    return "only 'Transfer-Encoding: chunked' is accepted";
  return {};
}

bool HostAllowed(std::string_view host, const std::vector<std::string>& names) {
  host = Trim(host);
  if (host.empty()) return false;
  std::string_view name = host;
  if (name.front() == '[') {  // [v6]:port
    const size_t close = name.find(']');
    if (close == std::string_view::npos) return false;
    const std::string literal(name.substr(1, close - 1));
    const std::string_view rest = name.substr(close + 1);
    if (!rest.empty() &&
        (rest.front() != ':' || rest.size() == 1 ||
         !std::all_of(rest.begin() + 1, rest.end(), [](char c) { return c >= '0' && c <= '9'; })))
      return false;
    in6_addr a6{};
    return inet_pton(AF_INET6, literal.c_str(), &a6) == 1;
  }
  if (const size_t colon = name.rfind(':'); colon != std::string_view::npos) {
    const std::string_view port = name.substr(colon + 1);
    if (port.empty() ||
        !std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return false;
    name = name.substr(0, colon);
  }
  if (name.empty()) return false;
  const std::string text(name);
  in_addr a4{};
  if (inet_pton(AF_INET, text.c_str(), &a4) == 1) return true;
  if (EqualsNoCase(name, "localhost")) return true;
  return std::any_of(names.begin(), names.end(),
                     [&](const std::string& n) { return EqualsNoCase(name, n); });
}

}  // namespace vsurg::server::http
