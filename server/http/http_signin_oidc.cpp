// The dashboard's sign-in through the site's identity provider (server/http/oidc.h): the
// browser's way there and back. Both routes may block on the provider (its discovery at the
// first sign-in, the code's exchange), so they run on node-call workers in the caller's
// address's fair share, never on the I/O thread; the callback's answer is a page that
// goes on to the dashboard by a same-site navigation (a cookie set on a cross-site redirect's
// answer with SameSite=Strict would not be sent on that redirect's next hop).
#include <chrono>

#include "server/http/http_api.h"
#include "server/http/http_reply.h"
#include "server/http/oidc.h"
#include "server/http/web_auth.h"

namespace vsurg::server::http {
namespace {

constexpr std::string_view kBindingCookie = "vsurg_oidc";

double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string EscapeHtml(std::string_view s) {
  std::string out;
  for (char ch : s) {
    switch (ch) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out.push_back(ch);
    }
  }
  return out;
}

// A sign-in that did not happen: why, and the way back to the sign-in page.
HttpReply Refusal(const Error& e) {
  HttpReply reply =
      Html(HttpApi::StatusFor(e.code),
           "<!doctype html><html lang=en><meta charset=utf-8><title>Sign-in refused</title>"
           "<link rel=stylesheet href=\"/static/style.css\"><main><div class=\"panel signin\">"
           "<h1>Sign-in refused</h1>"
           "<p id=refused>The sign-in through your organisation was refused: " +
               EscapeHtml(e.message) +
               ".</p><p><a class=button href=\"/signin\">Back to sign-in</a></p></div></main>");
  reply.headers.emplace_back("Cache-Control", "no-store");
  return reply;
}

}  // namespace

HttpReply HttpApi::OidcBegin(const HttpRequest& r) {
  if (!options_.oidc)
    return ErrorReply(Error{ErrorCode::kNotFound, "this site has no identity provider", "oidc"});
  if (const double wait = limiter_.RetryAfter(r.remote); wait > 0)
    return Refusal(Error{ErrorCode::kResourceExhausted,
                         "too many failed sign-ins from this address; try later", ""});
  db::Principal caller;
  caller.name = "oidc@" + r.remote;  // the fair share: per address, before anyone is known
  // On a worker: the first sign-in asks the provider for its discovery document.
  return OnNodeWorker(caller, [this, remote = r.remote]() -> HttpReply {
    auto begun = options_.oidc->Begin(UnixNow(), remote);
    if (!begun.ok()) return Refusal(begun.error());
    HttpReply reply = Redirect(begun->redirect_url);
    // Lax: the provider's redirect back is a top-level cross-site GET, which Lax cookies go with.
    reply.headers.emplace_back(
        "Set-Cookie",
        std::string(kBindingCookie) + "=" + begun->binding +
            "; Path=/api/v1/signin/oidc; HttpOnly; SameSite=Lax; Max-Age=" +
            std::to_string(static_cast<int64_t>(options_.oidc->options().pending_ttl_s)) +
            (options_.secure_cookies ? "; Secure" : ""));
    reply.headers.emplace_back("Cache-Control", "no-store");
    return reply;
  });
}

HttpReply HttpApi::OidcCallback(const HttpRequest& r,
                                const std::multimap<std::string, std::string>& query) {
  if (!options_.oidc)
    return ErrorReply(Error{ErrorCode::kNotFound, "this site has no identity provider", "oidc"});
  auto param = [&](const char* name) {
    const auto it = query.find(name);
    return it == query.end() ? std::string() : it->second;
  };
  if (const std::string error = param("error"); !error.empty())
    return Refusal(Error{ErrorCode::kUnauthenticated,
                         "the identity provider answered '" + error.substr(0, 64) + "'", "oidc"});
  const std::string binding(CookieValue(r.cookie, kBindingCookie).value_or(""));
  db::Principal caller;
  caller.name = "oidc@" + r.remote;
  return OnNodeWorker(
      caller,
      [this, code = param("code"), state = param("state"), binding,
       remote = r.remote]() -> HttpReply {
        // A failed exchange (an unknown or replayed state, another browser's, a token that does
        // not verify) counts against the address as a failed sign-in does; a user the provider
        // vouched for and vsurg refuses (no role, disabled, another role here) is no guess.
        auto id = options_.oidc->Finish(code, state, binding, UnixNow());
        if (!id.ok()) {
          if (id.error().code == ErrorCode::kUnauthenticated) limiter_.Failed(remote);
          return Refusal(id.error());
        }
        auto token = d_.store.SignInFederated(id->user, id->role, sessions_.ttl_s());
        if (!token.ok()) return Refusal(token.error());
        const WebSession web = sessions_.Create(*token, id->user);
        HttpReply reply =
            Html(200,
                 "<!doctype html><meta charset=utf-8><meta http-equiv=refresh "
                 "content=\"0;url=/\"><title>Signed in</title><p>Signed in as " +
                     EscapeHtml(id->user) + "; <a href=\"/\">on to the dashboard</a>.</p>");
        reply.headers.emplace_back("Set-Cookie",
                                   std::string(kCookie) + "=" + web.id +
                                       "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" +
                                       std::to_string(static_cast<int64_t>(sessions_.ttl_s())) +
                                       (options_.secure_cookies ? "; Secure" : ""));
        reply.headers.emplace_back(
            "Set-Cookie",
            std::string(kBindingCookie) + "=; Path=/api/v1/signin/oidc; HttpOnly; Max-Age=0");
        reply.headers.emplace_back("Cache-Control", "no-store");
        return reply;
      });
}

}  // namespace vsurg::server::http
