// A blocking HTTP/1.1 client for the server's few outbound calls (the identity provider's
// discovery document, its keys and its token endpoint): one request per connection, http:// or
// https:// (TLS with the system's certificate authorities and the host name checked), a deadline
// on the whole exchange and a bound on the answer's size. Boost.Beast does the protocol; this
// file only frames one exchange. Never called on the HTTP server's I/O thread.
#pragma once

#include <string>

#include "common/core/expected.h"

namespace vsurg::server::http {

struct FetchReply {
  int status = 0;
  std::string content_type;
  std::string body;
};

struct FetchRequest {
  std::string method = "GET";  // GET or POST
  std::string url;             // http://host[:port]/path?query or https://...
  std::string body;            // POST only
  std::string content_type;    // of the body
  double timeout_s = 5;
  size_t max_body = 1 << 20;  // bytes; a longer answer is an error
};

// kInvalidArgument for a malformed URL, kUnavailable when the peer cannot be reached or answers
// late, kParseError for a malformed or oversized answer. Any HTTP status is a reply.
Expected<FetchReply> Fetch(const FetchRequest& request);

}  // namespace vsurg::server::http
