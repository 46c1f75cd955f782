#include "server/http/web_auth.h"

#include <openssl/rand.h>

#include <algorithm>
#include <stdexcept>
#include <vector>

namespace vsurg::server::http {

std::string RandomHex32() {
  unsigned char bytes[32];
  if (RAND_bytes(bytes, sizeof bytes) != 1)
    throw std::runtime_error("the system random generator failed");
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out(64, '0');
  for (size_t i = 0; i < sizeof bytes; ++i) {
    out[2 * i] = kHex[bytes[i] >> 4];
    out[2 * i + 1] = kHex[bytes[i] & 15];
  }
  return out;
}

bool SameSecret(std::string_view a, std::string_view b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  const size_t n = std::min(a.size(), b.size());
  for (size_t i = 0; i < n; ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

std::optional<std::string_view> CookieValue(std::string_view header, std::string_view name) {
  while (!header.empty()) {
    const size_t semi = header.find(';');
    std::string_view pair = header.substr(0, semi);
    header = semi == std::string_view::npos ? std::string_view() : header.substr(semi + 1);
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    while (!pair.empty() && pair.back() == ' ') pair.remove_suffix(1);
    const size_t eq = pair.find('=');
    if (eq == std::string_view::npos) continue;
    if (pair.substr(0, eq) == name) return pair.substr(eq + 1);
  }
  return std::nullopt;
}

WebSessions::WebSessions(const Clock& clock, double ttl_s, size_t max_per_user)
    : clock_(clock), ttl_s_(ttl_s), max_per_user_(std::max<size_t>(1, max_per_user)) {}

void WebSessions::EraseLocked(std::map<std::string, WebSession, std::less<>>::iterator it) {
  if (auto u = by_user_.find(it->second.user); u != by_user_.end()) {
    std::erase(u->second, it->first);
    if (u->second.empty()) by_user_.erase(u);
  }
  sessions_.erase(it);
}

WebSession WebSessions::Create(std::string token, std::string user) {
  WebSession s{RandomHex32(), RandomHex32(), std::move(token), std::move(user),
               clock_.Now() + ttl_s_};
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_.Now();
  for (auto it = sessions_.begin(); it != sessions_.end();) {
    const auto next = std::next(it);
    if (it->second.expires_s <= now) EraseLocked(it);
    it = next;
  }
  std::vector<std::string>& mine = by_user_[s.user];
  while (mine.size() >= max_per_user_) {  // this user's oldest goes, nobody else's
    const std::string oldest = mine.front();
    mine.erase(mine.begin());
    sessions_.erase(oldest);
    ++removals_;
  }
  mine.push_back(s.id);
  sessions_.emplace(s.id, s);
  return s;
}

std::optional<WebSession> WebSessions::Find(std::string_view id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = sessions_.find(id);
  if (it == sessions_.end()) return std::nullopt;
  if (it->second.expires_s <= clock_.Now()) {
    EraseLocked(it);
    return std::nullopt;
  }
  return it->second;
}

void WebSessions::Remove(std::string_view id) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto it = sessions_.find(id); it != sessions_.end()) {
    EraseLocked(it);
    ++removals_;
  }
}

size_t WebSessions::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return sessions_.size();
}

size_t WebSessions::size_of(std::string_view user) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = by_user_.find(user);
  return it == by_user_.end() ? 0 : it->second.size();
}

uint64_t WebSessions::removals() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return removals_;
}

SignInLimiter::SignInLimiter(const Clock& clock, int max_failures, double window_s,
                             size_t max_addresses)
    : clock_(clock),
      max_failures_(std::max(1, max_failures)),
      window_s_(window_s),
      max_addresses_(std::max<size_t>(1, max_addresses)) {}

double SignInLimiter::RetryAfter(const std::string& address) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = failures_.find(address);
  if (it == failures_.end()) return 0;
  const double now = clock_.Now();
  std::vector<double>& times = it->second;
  std::erase_if(times, [&](double t) { return t <= now - window_s_; });
  if (times.empty()) {
    failures_.erase(it);
    return 0;
  }
  if (static_cast<int>(times.size()) < max_failures_) return 0;
  return std::max(0.001, times.front() + window_s_ - now);
}

void SignInLimiter::Failed(const std::string& address) {
  std::lock_guard<std::mutex> lock(mutex_);
  const double now = clock_.Now();
  if (failures_.size() >= max_addresses_ && !failures_.count(address)) {
    // Forget addresses whose failures all left the window; if none did, the oldest one.
    std::erase_if(failures_, [&](const auto& kv) { return kv.second.back() <= now - window_s_; });
    if (failures_.size() >= max_addresses_) {
      auto oldest = std::min_element(failures_.begin(), failures_.end(), [](auto& a, auto& b) {
        return a.second.back() < b.second.back();
      });
      failures_.erase(oldest);
    }
  }
  std::vector<double>& times = failures_[address];
  times.push_back(now);
  if (static_cast<int>(times.size()) > max_failures_) times.erase(times.begin());
}

}  // namespace vsurg::server::http
