// libFuzzer target: the identity provider's answers as the dashboard's sign-in reads them
// (server/http/oidc.h). Input: a first byte choosing what the rest is, a key set (JWKS) as the
// provider's jwks_uri might serve it, or an ID token checked against a real RSA key generated at
// start-up.
// Properties: nothing crashes or hangs; a key set either parses or is refused naming the JWKS; no
// input ever passes as an ID token (an RS256 signature cannot be forged by mutation), and every
// refusal is kUnauthenticated.
#include <openssl/core_names.h>
#include <openssl/evp.h>
#include <openssl/rsa.h>

#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "server/http/oidc.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

using namespace vsurg;
using namespace vsurg::server::http;

// The provider's key set: one real 2048-bit key under kid "k1".
const Jwks& ProviderKeys() {
  static const Jwks keys = [] {
    std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(EVP_RSA_gen(2048), EVP_PKEY_free);
    auto part = [&](const char* name) {
      BIGNUM* bn = nullptr;
      EVP_PKEY_get_bn_param(key.get(), name, &bn);
      std::string bytes(static_cast<size_t>(BN_num_bytes(bn)), '\0');
      BN_bn2bin(bn, reinterpret_cast<unsigned char*>(bytes.data()));
      BN_free(bn);
      return Base64UrlEncode(bytes);
    };
    const nlohmann::json jwks = {{"keys",
                                  {{{"kty", "RSA"},
                                    {"kid", "k1"},
                                    {"n", part(OSSL_PKEY_PARAM_RSA_N)},
                                    {"e", part(OSSL_PKEY_PARAM_RSA_E)}}}}};
    return Jwks::Parse(jwks.dump()).value();
  }();
  return keys;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string rest(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] % 2 == 0) {
    auto keys = Jwks::Parse(rest);
    VSURG_FUZZ_CHECK(keys.ok() ? keys->size() > 0 : keys.error().field == "jwks");
    return 0;
  }
  OidcOptions o;
  o.issuer = "https://idp.example";
  o.client_id = "vsurg-dashboard";
  auto claims = VerifyIdToken(rest, ProviderKeys(), o, "n-123", 1.8e9);
  VSURG_FUZZ_CHECK(!claims.ok());
  VSURG_FUZZ_CHECK(claims.error().code == ErrorCode::kUnauthenticated);
  return 0;
}
