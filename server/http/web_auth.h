// The dashboard's sign-in: a user's API token (as vsurg-admin issues it) exchanged for a web
// session — an opaque cookie id, HttpOnly, SameSite=Strict, with an expiry — and a CSRF token the
// page sends back in `X-CSRF-Token` on every state-changing request. Failed sign-ins are limited
// per client address.
//
// The web session keeps the user's token in server memory only, and every request authenticates
// it against the store again, so revoking the user's tokens or disabling the account ends their
// web sessions at the next request, exactly as for gRPC. Sign-out forgets the web session.
//
// No HTTP library type appears here (unit-tested without a socket). Thread safety: every member
// function may be called from any thread.
#pragma once

#include <cstddef>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/clock.h"

namespace vsurg::server::http {

struct WebSession {
  std::string id;        // the cookie's value: 32 random bytes, hex
  std::string csrf;      // 32 random bytes, hex; sent back in X-CSRF-Token
  std::string token;     // the user's API token (never leaves the server)
  std::string user;      // whose (the bound on web sessions is per user)
  double expires_s = 0;  // on the sessions' clock
};

// The table is bounded per user, not by sign-ins: a user holds at most `max_per_user` web
// sessions (a new sign-in drops the oldest of *that user's*), so one user signing in again and
// again never signs anyone else out; the table's size is then at most users × max_per_user.
class WebSessions {
 public:
  // `ttl_s`: a web session's lifetime from sign-in (no sliding renewal: a stolen cookie expires).
  WebSessions(const Clock& clock, double ttl_s, size_t max_per_user = 16);
  // A new web session of `user` for an authenticated token.
  WebSession Create(std::string token, std::string user);
  // The live web session with this id; expired ones are forgotten here.
  std::optional<WebSession> Find(std::string_view id);
  // Sign-out. Each removal counts (removals()): the server ends the web session's event
  // streams at their next frame.
  void Remove(std::string_view id);
  size_t size() const;
  size_t size_of(std::string_view user) const;
  double ttl_s() const { return ttl_s_; }
  uint64_t removals() const;

 private:
  const Clock& clock_;
  double ttl_s_;
  size_t max_per_user_;
  mutable std::mutex mutex_;
  std::map<std::string, WebSession, std::less<>> sessions_;
  std::map<std::string, std::vector<std::string>, std::less<>> by_user_;  // ids, oldest first
  uint64_t removals_ = 0;
  void EraseLocked(std::map<std::string, WebSession, std::less<>>::iterator it);
};

// Failed sign-ins per client address: at most `max_failures` in any `window_s`; then refused
// until the oldest failure leaves the window. A success does not erase failures (a guesser with
// one valid token gains nothing). Bounded: at most `max_addresses` addresses are remembered.
class SignInLimiter {
 public:
  SignInLimiter(const Clock& clock, int max_failures = 5, double window_s = 60,
                size_t max_addresses = 10000);
  // 0 when this address may try now, else the seconds until it may.
  double RetryAfter(const std::string& address);
  void Failed(const std::string& address);

 private:
  const Clock& clock_;
  int max_failures_;
  double window_s_;
  size_t max_addresses_;
  std::mutex mutex_;
  std::map<std::string, std::vector<double>> failures_;  // times, oldest first
};

// The value of cookie `name` in a Cookie header ("a=1; b=2"), or nullopt.
std::optional<std::string_view> CookieValue(std::string_view header, std::string_view name);
// Equal, in time independent of where they differ.
bool SameSecret(std::string_view a, std::string_view b);
// 32 bytes from the system's random generator, as 64 hex digits.
std::string RandomHex32();

}  // namespace vsurg::server::http
