#include "proto/wire/datagram.h"

#include <cstring>

// OpenSSL 3 marks the low-level SHA-256 calls deprecated in favour of EVP, whose contexts are
// heap objects; copying a pre-keyed SHA256_CTX is what keeps the per-datagram path allocation-free.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <openssl/crypto.h>
#include <openssl/sha.h>

namespace vsurg::wire {
namespace {

static_assert(sizeof(SHA256_CTX) <= 128, "Authenticator storage too small for SHA256_CTX");

void PutLe(uint8_t* p, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

uint64_t GetLe(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

}  // namespace

const char* DropReasonName(DropReason r) {
  switch (r) {
    case DropReason::kNone:
      return "none";
    case DropReason::kTooShort:
      return "too_short";
    case DropReason::kTooLong:
      return "too_long";
    case DropReason::kBadMagic:
      return "bad_magic";
    case DropReason::kBadVersion:
      return "bad_version";
    case DropReason::kBadType:
      return "bad_type";
    case DropReason::kBadLength:
      return "bad_length";
    case DropReason::kUnknownSession:
      return "unknown_session";
    case DropReason::kBadTag:
      return "bad_tag";
    case DropReason::kBadPayload:
      return "bad_payload";
    case DropReason::kStale:
      return "stale";
    case DropReason::kRateLimited:
      return "rate_limited";
    case DropReason::kLate:
      return "late";
    case DropReason::kFenced:
      return "fenced";
    case DropReason::kCount:
      break;
  }
  return "?";
}

// RFC 2104: HMAC(K, m) = H((K ⊕ opad) ‖ H((K ⊕ ipad) ‖ m)), 64-byte blocks; a 32-byte key is
// used as is (zero-padded).
Authenticator::Authenticator(const SessionKey& key) {
  unsigned char ipad[64], opad[64];
  std::memset(ipad, 0x36, sizeof ipad);
  std::memset(opad, 0x5c, sizeof opad);
  for (size_t i = 0; i < kKeySize; ++i) ipad[i] ^= key[i], opad[i] ^= key[i];
  auto* inner = reinterpret_cast<SHA256_CTX*>(inner_);
  auto* outer = reinterpret_cast<SHA256_CTX*>(outer_);
  SHA256_Init(inner);
  SHA256_Update(inner, ipad, sizeof ipad);
  SHA256_Init(outer);
  SHA256_Update(outer, opad, sizeof opad);
  OPENSSL_cleanse(ipad, sizeof ipad);
  OPENSSL_cleanse(opad, sizeof opad);
}

std::array<uint8_t, kTagSize> Authenticator::Tag(std::span<const uint8_t> data) const {
  SHA256_CTX ctx;
  unsigned char inner_hash[SHA256_DIGEST_LENGTH], full[SHA256_DIGEST_LENGTH];
  std::memcpy(&ctx, inner_, sizeof ctx);
  SHA256_Update(&ctx, data.data(), data.size());
  SHA256_Final(inner_hash, &ctx);
  std::memcpy(&ctx, outer_, sizeof ctx);
  SHA256_Update(&ctx, inner_hash, sizeof inner_hash);
  SHA256_Final(full, &ctx);
  std::array<uint8_t, kTagSize> tag;
  std::memcpy(tag.data(), full, kTagSize);
  return tag;
}

size_t Seal(const Header& h, std::span<const uint8_t> payload, const Authenticator& auth,
            std::span<uint8_t> out) {
  const size_t total = kHeaderSize + payload.size() + kTagSize;
  if (payload.size() > kMaxPayload || out.size() < total) return 0;
  uint8_t* p = out.data();
  p[0] = 'V';
  p[1] = 'S';
  p[2] = h.version;
  p[3] = static_cast<uint8_t>(h.type);
  PutLe(p + 4, h.session, 8);
  PutLe(p + 12, h.sequence, 8);
  PutLe(p + 20, 0, 8);  // reserved
  PutLe(p + 28, payload.size(), 2);
  PutLe(p + 30, 0, 2);
  if (!payload.empty()) std::memcpy(p + kHeaderSize, payload.data(), payload.size());
  const auto tag = auth.Tag(std::span<const uint8_t>(p, kHeaderSize + payload.size()));
  std::memcpy(p + kHeaderSize + payload.size(), tag.data(), kTagSize);
  return total;
}

DropReason PeekHeader(std::span<const uint8_t> d, Header& h) {
  if (d.size() < kHeaderSize + kTagSize) return DropReason::kTooShort;
  if (d.size() > kMaxDatagram) return DropReason::kTooLong;
  if (d[0] != 'V' || d[1] != 'S') return DropReason::kBadMagic;
  if (d[2] != kProtocolVersion) return DropReason::kBadVersion;
  if (d[3] < 1 || d[3] > 3) return DropReason::kBadType;
  const size_t length = GetLe(d.data() + 28, 2);
  if (kHeaderSize + length + kTagSize != d.size() || GetLe(d.data() + 30, 2) != 0)
    return DropReason::kBadLength;
  h.version = d[2];
  h.type = static_cast<PayloadType>(d[3]);
  h.session = GetLe(d.data() + 4, 8);
  h.sequence = GetLe(d.data() + 12, 8);
  return DropReason::kNone;
}

DropReason Open(std::span<const uint8_t> d, const Authenticator* auth, Opened& out) {
  if (DropReason r = PeekHeader(d, out.header); r != DropReason::kNone) return r;
  if (auth == nullptr) return DropReason::kUnknownSession;
  return Verify(d, *auth, out.payload);
}

DropReason Verify(std::span<const uint8_t> d, const Authenticator& auth,
                  std::span<const uint8_t>& payload) {
  const size_t body = d.size() - kTagSize;  // PeekHeader checked the size
  const auto tag = auth.Tag(d.first(body));
  if (CRYPTO_memcmp(tag.data(), d.data() + body, kTagSize) != 0) return DropReason::kBadTag;
  payload = d.subspan(kHeaderSize, body - kHeaderSize);
  return DropReason::kNone;
}

}  // namespace vsurg::wire
#pragma GCC diagnostic pop
