// What the dashboard's listener checks on a request's header before it reads a body or hands
// the request on (http_server.cpp), as pure functions: unit-tested and fuzzed without a socket.
//
//  1. Framing (RFC 9112 §6.1, §6.3): a request whose body length is ambiguous is refused with
//     400 and the connection closed, never guessed at. Accepted: no Transfer-Encoding (the body
//     is Content-Length bytes, or none), or exactly one Transfer-Encoding field whose value is
//     `chunked` and no Content-Length. Refused: any other coding or list (`chunked, identity`,
//     `identity`, `xchunked`, `gzip, chunked`: we decode none of them), several fields, and
//     Transfer-Encoding beside Content-Length (the classic smuggling pair).
//  2. Host (DNS rebinding): the server answers only for names it was configured with, for IP
//     literals (a rebinding attack needs a name) and for `localhost`; a request without a Host
//     is refused (HTTP/1.1 requires one).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace vsurg::server::http {

// Empty when the framing is unambiguous; else why not. `te_fields`: the Transfer-Encoding
// fields' values, one per field as received; `content_length_fields`: how many there were.
std::string FramingProblem(const std::vector<std::string_view>& te_fields,
                           int content_length_fields);

// Whether `host` (a Host header: name or literal, with an optional port) is one the server
// answers for. `names`: the configured host names, matched case-insensitively.
bool HostAllowed(std::string_view host, const std::vector<std::string>& names);

}  // namespace vsurg::server::http
