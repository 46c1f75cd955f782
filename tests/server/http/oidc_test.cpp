// The ID token's check (server/http/oidc.h) on tokens signed here with a real RSA key: what a
// provider signs is accepted; forged, re-signed, unsigned, HMAC-signed, expired, early, foreign
// (issuer, audience, authorised party), replayed (nonce) and malformed tokens are refused, each
// naming why. The flow around it runs against a real provider in tests/e2e/oidc_test.py.
#include "server/http/oidc.h"

#include <openssl/core_names.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rsa.h>

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

namespace vsurg::server::http {
namespace {

using nlohmann::json;

std::string Url64(std::string_view bytes) {
  return Base64UrlEncode(bytes);
}

// A provider's key pair: signs tokens and publishes its public half as a JWKS.
class TestKey {
 public:
  TestKey(std::string kid, unsigned bits = 2048)
      : kid_(std::move(kid)), key_(EVP_RSA_gen(bits), EVP_PKEY_free) {}

  std::string Jwk() const {
    auto part = [&](const char* name) {
      BIGNUM* bn = nullptr;
      EVP_PKEY_get_bn_param(key_.get(), name, &bn);
      std::string bytes(static_cast<size_t>(BN_num_bytes(bn)), '\0');
      BN_bn2bin(bn, reinterpret_cast<unsigned char*>(bytes.data()));
      BN_free(bn);
      return Url64(bytes);
    };
    return json{{"kty", "RSA"},
                {"use", "sig"},
                {"kid", kid_},
                {"alg", "RS256"},
                {"n", part(OSSL_PKEY_PARAM_RSA_N)},
                {"e", part(OSSL_PKEY_PARAM_RSA_E)}}
        .dump();
  }

  std::string Sign(const json& header, const json& claims) const {
    const std::string signed_part = Url64(header.dump()) + "." + Url64(claims.dump());
    std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
    size_t n = 0;
    EVP_DigestSignInit(ctx.get(), nullptr, EVP_sha256(), nullptr, key_.get());
    EVP_DigestSign(ctx.get(), nullptr, &n,
                   reinterpret_cast<const unsigned char*>(signed_part.data()), signed_part.size());
    std::string sig(n, '\0');
    EVP_DigestSign(ctx.get(), reinterpret_cast<unsigned char*>(sig.data()), &n,
                   reinterpret_cast<const unsigned char*>(signed_part.data()), signed_part.size());
    sig.resize(n);
    return signed_part + "." + Url64(sig);
  }
  const std::string& kid() const { return kid_; }

 private:
  std::string kid_;
  std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key_;
};

constexpr double kNow = 1.8e9;  // s since the epoch

class OidcTokenTest : public ::testing::Test {
 protected:
  OidcTokenTest() : key_("k1"), other_("k1") {
    options_.issuer = "https://idp.hospital.example/realms/staff";
    options_.client_id = "vsurg-dashboard";
    auto jwks = Jwks::Parse("{\"keys\":[" + key_.Jwk() + "]}");
    EXPECT_TRUE(jwks.ok());
    jwks_ = std::move(*jwks);
  }
  json Claims() const {
    return {{"iss", options_.issuer},
            {"aud", options_.client_id},
            {"sub", "x1"},
            {"preferred_username", "dr-lee"},
            {"vsurg_role", "instructor"},
            {"exp", kNow + 300},
            {"iat", kNow - 5},
            {"nonce", "n-123"}};
  }
  json Header() const { return {{"alg", "RS256"}, {"typ", "JWT"}, {"kid", key_.kid()}}; }
  // Why `jwt` is refused ("" when it is accepted).
  std::string Why(const std::string& jwt, const std::string& nonce = "n-123",
                  double now = kNow) const {
    auto r = VerifyIdToken(jwt, jwks_, options_, nonce, now);
    if (r.ok()) return "";
    EXPECT_EQ(r.error().code, ErrorCode::kUnauthenticated);
    return r.error().message;
  }

  TestKey key_, other_;
  OidcOptions options_;
  Jwks jwks_;
};

TEST_F(OidcTokenTest, WhatTheProviderSignsIsAccepted) {
  auto r = VerifyIdToken(key_.Sign(Header(), Claims()), jwks_, options_, "n-123", kNow);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ((*r)["preferred_username"], "dr-lee");
  // An audience list holding us, with us as the authorised party; the clock skew both ways.
  json c = Claims();
  c["aud"] = {"vsurg-dashboard", "other-app"};
  c["azp"] = "vsurg-dashboard";
  EXPECT_EQ(Why(key_.Sign(Header(), c)), "");
  EXPECT_EQ(Why(key_.Sign(Header(), Claims()), "n-123", kNow + 300 + 59), "");
  c = Claims();
  c["iat"] = kNow + 59;
  EXPECT_EQ(Why(key_.Sign(Header(), c)), "");
}

TEST_F(OidcTokenTest, ForgedOrResignedTokensAreRefused) {
  const std::string good = key_.Sign(Header(), Claims());
  // The claims changed after signing (an instructor made an administrator).
  json c = Claims();
  c["vsurg_role"] = "admin";
  const size_t dot = good.find('.'), last = good.rfind('.');
  const std::string tampered = good.substr(0, dot + 1) + Url64(c.dump()) + good.substr(last);
  EXPECT_NE(Why(tampered).find("signature"), std::string::npos);
  // Signed by another key under the provider's key id.
  EXPECT_NE(Why(other_.Sign(Header(), Claims())).find("signature"), std::string::npos);
  // A key the provider does not publish.
  json h = Header();
  h["kid"] = "k9";
  EXPECT_NE(Why(key_.Sign(h, Claims())).find("does not publish"), std::string::npos);
}

TEST_F(OidcTokenTest, UnsignedAndHmacSignedTokensAreRefused) {
  // alg none, no signature.
  const json none = {{"alg", "none"}, {"typ", "JWT"}};
  EXPECT_NE(Why(Url64(none.dump()) + "." + Url64(Claims().dump()) + ".").find("RS256"),
            std::string::npos);
  // HS256 keyed with the public key's JWK (the algorithm-confusion attack).
  const json hs = {{"alg", "HS256"}, {"typ", "JWT"}, {"kid", key_.kid()}};
  const std::string part = Url64(hs.dump()) + "." + Url64(Claims().dump());
  const std::string secret = key_.Jwk();
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  HMAC(EVP_sha256(), secret.data(), static_cast<int>(secret.size()),
       reinterpret_cast<const unsigned char*>(part.data()), part.size(), mac, &n);
  EXPECT_NE(Why(part + "." + Url64(std::string(reinterpret_cast<char*>(mac), n))).find("RS256"),
            std::string::npos);
}

TEST_F(OidcTokenTest, ExpiredEarlyForeignAndReplayedTokensAreRefused) {
  const auto refused = [&](const char* field, json value, const char* why) {
    json c = Claims();
    if (value.is_null())
      c.erase(field);
    else
      c[field] = value;
    EXPECT_NE(Why(key_.Sign(Header(), c)).find(why), std::string::npos) << field << " " << value;
  };
  refused("exp", kNow - 61, "expired");
  refused("exp", nullptr, "no exp");
  refused("iat", kNow + 120, "future");
  refused("iss", "https://evil.example", "issuer");
  refused("aud", "other-app", "audience");
  refused("aud", json::array({"other-app"}), "audience");
  refused("aud", json::array({"vsurg-dashboard", "other-app"}), "authorised party");
  refused("nonce", "n-456", "nonce");
  refused("nonce", nullptr, "nonce");
  EXPECT_NE(Why(key_.Sign(Header(), Claims()), "").find("nonce"), std::string::npos);
}

TEST_F(OidcTokenTest, MalformedTokensAndKeySetsAreRefused) {
  for (const std::string& bad :
       std::vector<std::string>{"", "abc", "a.b", "a.b.c.d", "!!.??.**", std::string(20000, 'a')})
    EXPECT_NE(Why(bad), "") << bad.substr(0, 20);
  EXPECT_FALSE(Jwks::Parse("").ok());
  EXPECT_FALSE(Jwks::Parse("{\"keys\":[]}").ok());
  EXPECT_FALSE(Jwks::Parse("{\"keys\":[{\"kty\":\"EC\",\"crv\":\"P-256\"}]}").ok());
  const TestKey weak("w", 1024);  // under 2048 bits: not trusted
  EXPECT_FALSE(Jwks::Parse("{\"keys\":[" + weak.Jwk() + "]}").ok());
}

TEST(OidcRoleMapTest, ValuesMapToRolesAndBadItemsAreNamed) {
  auto m = ParseRoleMap("surgeons=trainee,faculty=instructor");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->at("faculty"), db::Role::kInstructor);
  EXPECT_EQ(ParseRoleMap("faculty=dean").error().field, "oidc-role-map");
  EXPECT_FALSE(ParseRoleMap("=trainee").ok());
  EXPECT_FALSE(ParseRoleMap("faculty").ok());
}

}  // namespace
}  // namespace vsurg::server::http
