#include "server/http/oidc.h"

#include <openssl/bn.h>
#include <openssl/core_names.h>
#include <openssl/evp.h>
#include <openssl/param_build.h>
#include <openssl/rand.h>
#include <openssl/sha.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <vector>

namespace vsurg::server::http {
namespace {

using nlohmann::json;

Error Refused(const std::string& why) {
  return Error{ErrorCode::kUnauthenticated, why, "id_token"};
}

// base64url (RFC 4648 §5) without padding, in both directions, over OpenSSL's base64.
std::string Base64Url(const unsigned char* data, size_t n) {
  std::string out(4 * ((n + 2) / 3) + 1, '\0');
  const int len =
      EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()), data, static_cast<int>(n));
  out.resize(static_cast<size_t>(std::max(len, 0)));
  while (!out.empty() && out.back() == '=') out.pop_back();
  for (char& ch : out) ch = ch == '+' ? '-' : ch == '/' ? '_' : ch;
  return out;
}

std::optional<std::string> FromBase64Url(std::string_view s) {
  if (s.size() % 4 == 1 || s.find_first_of("+/=") != std::string_view::npos) return std::nullopt;
  std::string in(s);
  for (char& ch : in) ch = ch == '-' ? '+' : ch == '_' ? '/' : ch;
  const size_t pad = (4 - in.size() % 4) % 4;
  in.append(pad, '=');
  std::string out(in.size() / 4 * 3, '\0');
  const int len = EVP_DecodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                  reinterpret_cast<const unsigned char*>(in.data()),
                                  static_cast<int>(in.size()));
  if (len < 0) return std::nullopt;
  out.resize(static_cast<size_t>(len) - pad);  // EVP_DecodeBlock counts the padding as zeros
  return out;
}

std::string RandomUrlSafe() {
  unsigned char raw[32];
  if (RAND_bytes(raw, sizeof raw) != 1) return "";
  return Base64Url(raw, sizeof raw);
}

std::string UrlEncode(std::string_view s) {
  static const char* kHex = "0123456789ABCDEF";
  std::string out;
  for (unsigned char ch : s) {
    if (std::isalnum(ch) || ch == '-' || ch == '_' || ch == '.' || ch == '~') {
      out.push_back(static_cast<char>(ch));
    } else {
      out.push_back('%');
      out.push_back(kHex[ch >> 4]);
      out.push_back(kHex[ch & 15]);
    }
  }
  return out;
}

// An RSA public key from a JWK's modulus and exponent (base64url, big-endian).
std::shared_ptr<EVP_PKEY> RsaKey(const std::string& n64, const std::string& e64) {
  const auto n = FromBase64Url(n64), e = FromBase64Url(e64);
  if (!n || !e || n->size() < 256) return nullptr;  // 2048 bits at least
  auto bn = [](const std::string& b) {
    return std::unique_ptr<BIGNUM, decltype(&BN_free)>(
        BN_bin2bn(reinterpret_cast<const unsigned char*>(b.data()), static_cast<int>(b.size()),
                  nullptr),
        BN_free);
  };
  auto bn_n = bn(*n), bn_e = bn(*e);
  std::unique_ptr<OSSL_PARAM_BLD, decltype(&OSSL_PARAM_BLD_free)> build(OSSL_PARAM_BLD_new(),
                                                                        OSSL_PARAM_BLD_free);
  if (!bn_n || !bn_e || !build ||
      !OSSL_PARAM_BLD_push_BN(build.get(), OSSL_PKEY_PARAM_RSA_N, bn_n.get()) ||
      !OSSL_PARAM_BLD_push_BN(build.get(), OSSL_PKEY_PARAM_RSA_E, bn_e.get()))
    return nullptr;
  std::unique_ptr<OSSL_PARAM, decltype(&OSSL_PARAM_free)> params(
      OSSL_PARAM_BLD_to_param(build.get()), OSSL_PARAM_free);
  std::unique_ptr<EVP_PKEY_CTX, decltype(&EVP_PKEY_CTX_free)> ctx(
      EVP_PKEY_CTX_new_from_name(nullptr, "RSA", nullptr), EVP_PKEY_CTX_free);
  EVP_PKEY* key = nullptr;
  if (!params || !ctx || EVP_PKEY_fromdata_init(ctx.get()) <= 0 ||
      EVP_PKEY_fromdata(ctx.get(), &key, EVP_PKEY_PUBLIC_KEY, params.get()) <= 0)
    return nullptr;
  return std::shared_ptr<EVP_PKEY>(key, EVP_PKEY_free);
}

bool VerifyRs256(EVP_PKEY* key, std::string_view signed_part, const std::string& signature) {
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  return ctx && EVP_DigestVerifyInit(ctx.get(), nullptr, EVP_sha256(), nullptr, key) == 1 &&
         EVP_DigestVerify(
             ctx.get(), reinterpret_cast<const unsigned char*>(signature.data()), signature.size(),
             reinterpret_cast<const unsigned char*>(signed_part.data()), signed_part.size()) == 1;
}

// The token's three parts decoded: the header and claims as JSON, the signature as bytes.
struct Jwt {
  json header, claims;
  std::string signature;
  std::string_view signed_part;
};

Expected<Jwt> SplitJwt(std::string_view jwt) {
  if (jwt.size() > 16384) return Refused("the ID token is too long");
  const size_t a = jwt.find('.'), b = a == std::string_view::npos ? a : jwt.find('.', a + 1);
  if (b == std::string_view::npos || jwt.find('.', b + 1) != std::string_view::npos)
    return Refused("the ID token is not a signed JWT (three parts)");
  const auto header = FromBase64Url(jwt.substr(0, a));
  const auto claims = FromBase64Url(jwt.substr(a + 1, b - a - 1));
  const auto signature = FromBase64Url(jwt.substr(b + 1));
  if (!header || !claims || !signature) return Refused("the ID token is not base64url");
  Jwt out{json::parse(*header, nullptr, false), json::parse(*claims, nullptr, false), *signature,
          jwt.substr(0, b)};
  if (!out.header.is_object() || !out.claims.is_object())
    return Refused("the ID token's header or claims are not JSON objects");
  return out;
}

// iss, aud (and azp), exp, iat and nonce, as OpenID Connect Core §3.1.3.7 asks.
Status CheckClaims(const json& c, const OidcOptions& o, const std::string& nonce, double now) {
  if (c.value("iss", "") != o.issuer) return Refused("the ID token is from another issuer");
  const json aud = c.value("aud", json());
  const bool for_us = aud.is_string() ? aud == o.client_id
                                      : aud.is_array() && std::find(aud.begin(), aud.end(),
                                                                    o.client_id) != aud.end();
  if (!for_us) return Refused("the ID token is for another audience");
  if (aud.is_array() && aud.size() > 1 && c.value("azp", "") != o.client_id)
    return Refused("the ID token's authorised party is another client");
  const json exp = c.value("exp", json()), iat = c.value("iat", json());
  if (!exp.is_number() || !iat.is_number()) return Refused("the ID token has no exp or iat");
  if (now > exp.get<double>() + o.clock_skew_s) return Refused("the ID token has expired");
  if (iat.get<double>() > now + o.clock_skew_s) return Refused("the ID token is from the future");
  if (c.value("nonce", "") != nonce || nonce.empty())
    return Refused("the ID token's nonce is not this sign-in's");
  return Status::Ok();
}

}  // namespace

std::string Base64UrlEncode(std::string_view bytes) {
  return Base64Url(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
}

Expected<Jwks> Jwks::Parse(std::string_view text) {
  const json j = json::parse(text, nullptr, false);
  if (!j.is_object() || !j.contains("keys") || !j["keys"].is_array())
    return Error{ErrorCode::kParseError, "the provider's JWKS has no keys", "jwks"};
  Jwks out;
  for (const json& k : j["keys"]) {
    if (!k.is_object() || k.value("kty", "") != "RSA" || k.value("use", "sig") != "sig") continue;
    auto key = RsaKey(k.value("n", ""), k.value("e", ""));
    if (key) out.keys_[k.value("kid", "")] = std::move(key);
  }
  if (out.keys_.empty())
    return Error{ErrorCode::kParseError, "the provider's JWKS has no usable RSA key", "jwks"};
  return out;
}

EVP_PKEY* Jwks::Find(const std::string& kid) const {
  const auto it = keys_.find(kid);
  if (it != keys_.end()) return it->second.get();
  // A JWKS of one key without ids signs every token with it.
  return kid.empty() && keys_.size() == 1 ? keys_.begin()->second.get() : nullptr;
}

Expected<json> VerifyIdToken(std::string_view jwt, const Jwks& keys, const OidcOptions& options,
                             const std::string& nonce, double now_unix_s) {
  auto t = SplitJwt(jwt);
  if (!t.ok()) return t.error();
  if (t->header.value("alg", "") != "RS256")
    return Refused("the ID token is not signed with RS256 (alg '" + t->header.value("alg", "") +
                   "')");
  EVP_PKEY* key = keys.Find(t->header.value("kid", ""));
  if (!key) return Refused("the ID token is signed with a key the provider does not publish");
  if (!VerifyRs256(key, t->signed_part, t->signature))
    return Refused("the ID token's signature does not verify");
  if (Status s = CheckClaims(t->claims, options, nonce, now_unix_s); !s.ok()) return s.error();
  return t->claims;
}

Expected<std::map<std::string, db::Role>> ParseRoleMap(std::string_view text) {
  std::map<std::string, db::Role> out;
  size_t start = 0;
  while (start <= text.size() && !text.empty()) {
    size_t end = text.find(',', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view item = text.substr(start, end - start);
    const size_t eq = item.find('=');
    const auto role =
        eq == std::string_view::npos ? std::nullopt : db::ParseRole(item.substr(eq + 1));
    if (eq == 0 || !role)
      return InvalidArgument("oidc-role-map", "'" + std::string(item) +
                                                  "' is not VALUE=ROLE (a role: trainee, "
                                                  "instructor, evaluator or admin)");
    out[std::string(item.substr(0, eq))] = *role;
    start = end + 1;
  }
  return out;
}

Expected<std::unique_ptr<OidcRelyingParty>> OidcRelyingParty::Create(OidcOptions o, Fetcher f) {
  auto url = [](const std::string& s) {
    return s.rfind("https://", 0) == 0 || s.rfind("http://", 0) == 0;
  };
  if (!url(o.issuer)) return InvalidArgument("oidc-issuer", "an http(s) URL is required");
  if (o.client_id.empty()) return InvalidArgument("oidc-client-id", "is required");
  if (!url(o.redirect_uri)) return InvalidArgument("oidc-redirect-uri", "an http(s) URL");
  if (o.username_claim.empty() || o.role_claim.empty())
    return InvalidArgument("oidc-role-claim", "the username and role claims are named");
  return std::unique_ptr<OidcRelyingParty>(new OidcRelyingParty(std::move(o), std::move(f)));
}

Expected<OidcRelyingParty::Endpoints> OidcRelyingParty::Discover() {
  {
    std::lock_guard lock(mutex_);
    if (endpoints_) return *endpoints_;
  }
  std::string base = options_.issuer;
  while (!base.empty() && base.back() == '/') base.pop_back();
  FetchRequest get;
  get.url = base + "/.well-known/openid-configuration";
  get.timeout_s = options_.fetch_timeout_s;
  auto r = fetch_(get);
  if (!r.ok()) return r.error();
  const json d = json::parse(r->body, nullptr, false);
  if (r->status != 200 || !d.is_object())
    return Error{ErrorCode::kUnavailable, "the identity provider's discovery document is missing",
                 "oidc-issuer"};
  if (d.value("issuer", "") != options_.issuer)
    return Error{ErrorCode::kUnavailable,
                 "the identity provider names itself '" + d.value("issuer", "") + "', not '" +
                     options_.issuer + "'",
                 "oidc-issuer"};
  Endpoints e{d.value("authorization_endpoint", ""), d.value("token_endpoint", ""),
              d.value("jwks_uri", "")};
  if (e.authorization.empty() || e.token.empty() || e.jwks.empty())
    return Error{ErrorCode::kUnavailable, "the identity provider's discovery lacks an endpoint",
                 "oidc-issuer"};
  std::lock_guard lock(mutex_);
  endpoints_ = e;
  return e;
}

// Forgets expired sign-ins, then this address's oldest beyond its share, then the soonest to
// expire beyond the table's bound.
void OidcRelyingParty::MakeRoomLocked(const std::string& address, double now) {
  std::erase_if(pending_, [&](const auto& kv) { return kv.second.expires < now; });
  auto soonest = [&](auto keep) {
    auto best = pending_.end();
    size_t n = 0;
    for (auto it = pending_.begin(); it != pending_.end(); ++it) {
      if (!keep(it->second)) continue;
      ++n;
      if (best == pending_.end() || it->second.expires < best->second.expires) best = it;
    }
    return std::pair{best, n};
  };
  for (;;) {
    auto [oldest, n] = soonest([&](const Pending& p) { return p.address == address; });
    if (n < options_.max_pending_per_address) break;
    pending_.erase(oldest);
  }
  while (pending_.size() >= options_.max_pending)
    pending_.erase(soonest([](const Pending&) { return true; }).first);
}

Expected<OidcRelyingParty::Begun> OidcRelyingParty::Begin(double now, const std::string& address) {
  auto e = Discover();
  if (!e.ok()) return e.error();
  Pending p{RandomUrlSafe(), RandomUrlSafe(), RandomUrlSafe(), address,
            now + options_.pending_ttl_s};
  const std::string state = RandomUrlSafe();
  if (state.empty() || p.nonce.empty() || p.verifier.empty() || p.binding.empty())
    return Error{ErrorCode::kIoError, "the system random generator failed", "oidc"};
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(p.verifier.data()), p.verifier.size(), digest);
  const std::string challenge = Base64Url(digest, sizeof digest);
  Begun out;
  out.binding = p.binding;
  out.redirect_url =
      e->authorization + (e->authorization.find('?') == std::string::npos ? "?" : "&") +
      "response_type=code&client_id=" + UrlEncode(options_.client_id) +
      "&redirect_uri=" + UrlEncode(options_.redirect_uri) + "&scope=openid&state=" + state +
      "&nonce=" + p.nonce + "&code_challenge=" + challenge + "&code_challenge_method=S256";
  std::lock_guard lock(mutex_);
  MakeRoomLocked(address, now);
  pending_[state] = std::move(p);
  return out;
}

Expected<std::string> OidcRelyingParty::ExchangeCode(const Endpoints& e, std::string_view code,
                                                     const std::string& verifier) {
  std::string body = "grant_type=authorization_code&code=" + UrlEncode(code) +
                     "&redirect_uri=" + UrlEncode(options_.redirect_uri) +
                     "&client_id=" + UrlEncode(options_.client_id) +
                     "&code_verifier=" + UrlEncode(verifier);
  if (!options_.client_secret.empty())
    body += "&client_secret=" + UrlEncode(options_.client_secret);
  FetchRequest post;
  post.method = "POST";
  post.url = e.token;
  post.body = body;
  post.content_type = "application/x-www-form-urlencoded";
  post.timeout_s = options_.fetch_timeout_s;
  auto r = fetch_(post);
  if (!r.ok()) return r.error();
  const json j = json::parse(r->body, nullptr, false);
  if (r->status != 200 || !j.is_object() || !j.contains("id_token") || !j["id_token"].is_string())
    return Refused("the identity provider refused the code (HTTP " + std::to_string(r->status) +
                   (j.is_object() ? ", " + j.value("error", std::string("no id_token")) : "") +
                   ")");
  return j["id_token"].get<std::string>();
}

Expected<json> OidcRelyingParty::Verify(const Endpoints& e, const std::string& id_token,
                                        const std::string& nonce, double now) {
  for (int attempt = 0; attempt < 2; ++attempt) {
    std::shared_ptr<const Jwks> keys;
    bool stale = false;
    {
      std::lock_guard lock(mutex_);
      keys = keys_;
      stale = now - keys_fetched_ > 60;  // the keys are fetched again at most once a minute
    }
    if (!keys || (attempt == 1 && stale)) {
      FetchRequest get;
      get.url = e.jwks;
      get.timeout_s = options_.fetch_timeout_s;
      auto r = fetch_(get);
      if (!r.ok()) return r.error();
      auto parsed = Jwks::Parse(r->body);
      if (!parsed.ok()) return parsed.error();
      keys = std::make_shared<const Jwks>(std::move(*parsed));
      std::lock_guard lock(mutex_);
      keys_ = keys;
      keys_fetched_ = now;
    }
    auto claims = VerifyIdToken(id_token, *keys, options_, nonce, now);
    // An unknown key may be a rotation: fetch the keys again once, then judge.
    if (claims.ok() || claims.error().message.find("does not publish") == std::string::npos ||
        attempt == 1)
      return claims;
  }
  return Refused("unreachable");
}

Expected<OidcIdentity> OidcRelyingParty::IdentityOf(const json& claims) const {
  OidcIdentity id;
  id.user = claims.value(options_.username_claim, "");
  if (id.user.empty() || id.user.size() > 128)
    return Refused("the ID token has no usable '" + options_.username_claim + "' claim");
  const json v = claims.value(options_.role_claim, json());
  std::vector<std::string> values;
  if (v.is_string()) values.push_back(v.get<std::string>());
  if (v.is_array())
    for (const json& x : v)
      if (x.is_string()) values.push_back(x.get<std::string>());
  for (const std::string& value : values) {
    if (options_.role_map.empty()) {
      if (auto role = db::ParseRole(value)) return id.role = *role, id;
    } else if (auto it = options_.role_map.find(value); it != options_.role_map.end()) {
      return id.role = it->second, id;
    }
  }
  return Error{ErrorCode::kPermissionDenied,
               "the identity provider gives '" + id.user + "' no vsurg role (claim '" +
                   options_.role_claim + "')",
               "role"};
}

Expected<OidcIdentity> OidcRelyingParty::Finish(std::string_view code, std::string_view state,
                                                std::string_view binding, double now) {
  Pending p;
  {
    std::lock_guard lock(mutex_);
    const auto it = pending_.find(state);
    if (it == pending_.end() || it->second.expires < now)
      return Refused("unknown, expired or already used sign-in (state)");
    p = std::move(it->second);
    pending_.erase(it);  // once, whatever follows
  }
  if (binding.empty() || binding != p.binding)
    return Refused("this sign-in was begun in another browser");
  if (code.empty() || code.size() > 2048) return Refused("the provider sent no code");
  auto e = Discover();
  if (!e.ok()) return e.error();
  auto id_token = ExchangeCode(*e, code, p.verifier);
  if (!id_token.ok()) return id_token.error();
  auto claims = Verify(*e, *id_token, p.nonce, now);
  if (!claims.ok()) return claims.error();
  return IdentityOf(*claims);
}

}  // namespace vsurg::server::http
