// Sign-in through the site's identity provider: OpenID Connect's authorization code flow with
// PKCE (RFC 7636, S256), this server the relying party. Hospitals keep their surgeons' accounts in
// one place; vsurg takes the user's name and role from the provider's ID token and signs them in
// with the same web session as a token sign-in (server/http/web_auth.h). Local accounts stay.
//
//   Begin   a state (the request's id), a nonce (the ID token's) and a code verifier, each 32
//           random bytes; the browser is sent to the provider's authorization endpoint and given a
//           binding cookie, so that only the browser that began a sign-in can finish it.
//   Finish  the state is taken (once: a replayed state is refused), the binding compared, the code
//           exchanged at the token endpoint with the verifier, and the ID token checked: RS256
//           over a key of the provider's JWKS (by `kid`; the keys fetched again once when a `kid`
//           is unknown), `iss` the issuer, `aud` holding the client id (`azp` the client id when
//           there are several), `exp` not passed and `iat` not ahead (within the skew), `nonce`
//           the state's. Any other algorithm (`none`, HS256 with the public key as secret) is
//           refused. The user's name is the username claim; the role the role claim, a role's name
//           or a value the role map names.
//
// Discovery (issuer + /.well-known/openid-configuration) happens at the first sign-in and again
// after a failure, so the server starts while the provider is down. Thread safety: every member
// function may be called from any thread; Finish blocks on the provider (never on the HTTP
// server's I/O thread).
#pragma once

#include <openssl/types.h>

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "common/core/expected.h"
#include "db/vocabulary.h"
#include "server/http/http_client.h"

namespace vsurg::server::http {

struct OidcOptions {
  std::string issuer;         // the provider's issuer URL, exactly as its ID tokens say it
  std::string client_id;      // this server's client at the provider
  std::string client_secret;  // empty: a public client (PKCE alone)
  std::string redirect_uri;   // this server's callback, .../api/v1/signin/oidc/callback
  std::string username_claim = "preferred_username";
  std::string role_claim = "vsurg_role";  // a string, or an array of strings (the first known)
  // The provider's values (a group's name) to vsurg's roles; empty: the value is a role's name.
  std::map<std::string, db::Role> role_map;
  double pending_ttl_s = 600;  // a sign-in begun and not finished is forgotten after this
  size_t max_pending = 4096;   // sign-ins in flight (the soonest to expire forgotten beyond)
  size_t max_pending_per_address = 16;  // one address's (its own oldest forgotten beyond)
  double clock_skew_s = 60;             // allowed between the provider's clock and ours
  double fetch_timeout_s = 5;           // each call to the provider
};

// The provider's signing keys (a JWKS's RSA keys by `kid`).
class Jwks {
 public:
  static Expected<Jwks> Parse(std::string_view json);
  EVP_PKEY* Find(const std::string& kid) const;  // null when unknown
  size_t size() const { return keys_.size(); }

 private:
  std::map<std::string, std::shared_ptr<EVP_PKEY>> keys_;
};

// The ID token's claims once every check above holds; kUnauthenticated naming what failed.
Expected<nlohmann::json> VerifyIdToken(std::string_view jwt, const Jwks& keys,
                                       const OidcOptions& options, const std::string& nonce,
                                       double now_unix_s);

struct OidcIdentity {
  std::string user;
  db::Role role = db::Role::kTrainee;
};

class OidcRelyingParty {
 public:
  using Fetcher = std::function<Expected<FetchReply>(const FetchRequest&)>;
  // kInvalidArgument naming the option when one is missing or malformed.
  static Expected<std::unique_ptr<OidcRelyingParty>> Create(OidcOptions options,
                                                            Fetcher fetch = Fetch);

  struct Begun {
    std::string redirect_url;  // the provider's authorization endpoint with the request
    std::string binding;       // the binding cookie's value
  };
  // `address`: the client's, so that one address beginning sign-ins in a loop only ever
  // forgets its own. Blocks on the provider at the first sign-in (discovery).
  Expected<Begun> Begin(double now_unix_s, const std::string& address);
  Expected<OidcIdentity> Finish(std::string_view code, std::string_view state,
                                std::string_view binding, double now_unix_s);
  const OidcOptions& options() const { return options_; }

 private:
  struct Endpoints {
    std::string authorization, token, jwks;
  };
  struct Pending {
    std::string nonce, verifier, binding, address;
    double expires = 0;
  };
  void MakeRoomLocked(const std::string& address, double now);
  OidcRelyingParty(OidcOptions options, Fetcher fetch)
      : options_(std::move(options)), fetch_(std::move(fetch)) {}
  Expected<Endpoints> Discover();
  Expected<std::string> ExchangeCode(const Endpoints& e, std::string_view code,
                                     const std::string& verifier);
  Expected<nlohmann::json> Verify(const Endpoints& e, const std::string& id_token,
                                  const std::string& nonce, double now_unix_s);
  Expected<OidcIdentity> IdentityOf(const nlohmann::json& claims) const;

  const OidcOptions options_;
  const Fetcher fetch_;
  std::mutex mutex_;
  std::optional<Endpoints> endpoints_;
  std::shared_ptr<const Jwks> keys_;
  double keys_fetched_ = -1e18;
  std::map<std::string, Pending, std::less<>> pending_;  // by state
};

// base64url without padding (RFC 4648 §5), as JOSE writes it.
std::string Base64UrlEncode(std::string_view bytes);

// "group=role,group=role" for --oidc-role-map; kInvalidArgument naming the bad item.
Expected<std::map<std::string, db::Role>> ParseRoleMap(std::string_view text);

}  // namespace vsurg::server::http
