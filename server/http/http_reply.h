// The dashboard's replies and request parts: JSON and HTML replies, redirects, the page shell,
// query parameters (strict numbers and times), the JSON body and its typed fields, path segments,
// and which role a page is for. Private to server/http.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/expected.h"
#include "server/domain/auth.h"
#include "server/http/http_api.h"

namespace vsurg::server::http {

using nlohmann::json;
inline constexpr std::string_view kCookie = "vsurg_session";

HttpReply Json(int status, const json& j);

HttpReply Ok(const json& j);

HttpReply NoContent();

// The first value of a query parameter, or "".
std::string Param(const std::multimap<std::string, std::string>& q, const std::string& name);

std::optional<uint64_t> ParseId(std::string_view s);

// A query parameter as a non-negative 64-bit number: 0 when absent, nullopt when malformed.
std::optional<int64_t> QueryNumber(const std::multimap<std::string, std::string>& q,
                                   const char* name);

// A time parameter: an ISO time (2026-11-22T10:00:00Z) or microseconds since the epoch; 0 when
// absent, nullopt when neither.
std::optional<int64_t> QueryTime(const std::multimap<std::string, std::string>& q,
                                 const char* name);

// Splits "/a/b/c" into {"a", "b", "c"}.
std::vector<std::string_view> Segments(std::string_view path);

// A JSON object body (POST with Content-Type application/json); an empty body is {}.
Expected<json> Body(const HttpRequest& r);

std::string PageRole(std::string_view page, Method& m);

HttpReply Html(int status, std::string body);

HttpReply Redirect(const std::string& to);

// The page shell with its name filled in (a constant from PageRole, never request text).
HttpReply Shell(const std::string& page);

template <class T>
const Error* Err(const Expected<T>& x) {
  return x.ok() ? nullptr : &x.error();
}

template <class T>
Expected<T> Field(const json& j, const char* name, T fallback) {
  const auto it = j.find(name);
  if (it == j.end() || it->is_null()) return fallback;
  try {
    return it->get<T>();
  } catch (const json::exception&) {
    return InvalidArgument(name, std::string("has the wrong type"));
  }
}

}  // namespace vsurg::server::http
