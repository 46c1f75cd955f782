// Datagram framing and authentication for the UDP haptic channel (DESIGN.md "Network").
//
//   offset size  field
//   0      2     magic "VS"
//   2      1     protocol version (kProtocolVersion)
//   3      1     payload type (PayloadType)
//   4      8     session id            (little-endian)
//   12     8     sequence number       (little-endian, per sender, strictly increasing)
//   20     8     reserved: sent as zero, ignored when read (was a sender time no one used;
//                the sample's own time travels in the payload)
//   28     2     payload length        (little-endian)
//   30     2     reserved, zero
//   32     n     payload (protobuf)
//   32+n   16    tag: HMAC-SHA256(session key, bytes 0 .. 32+n), first 16 bytes
//
// At most kMaxDatagram bytes in all. The decoder is pure (no sockets) and checks, in order:
// size bounds, magic, version, type, length, reserved, the session's key, the tag (constant
// time), then the payload; every failure has its own DropReason so endpoints count them.
//
// HMAC-SHA256 is computed from pre-keyed inner and outer SHA-256 states (RFC 2104), copied per
// message: no allocation and no key schedule per datagram.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace vsurg::wire {

inline constexpr uint8_t kProtocolVersion = 1;
inline constexpr size_t kHeaderSize = 32;
inline constexpr size_t kTagSize = 16;
inline constexpr size_t kMaxDatagram = 1200;
inline constexpr size_t kMaxPayload = kMaxDatagram - kHeaderSize - kTagSize;
inline constexpr size_t kKeySize = 32;

enum class PayloadType : uint8_t { kStylusState = 1, kForceFeedback = 2, kSceneFrame = 3 };

enum class DropReason : uint8_t {
  kNone = 0,
  kTooShort,
  kTooLong,
  kBadMagic,
  kBadVersion,
  kBadType,
  kBadLength,
  kUnknownSession,
  kBadTag,
  kBadPayload,
  kStale,  // sequence not newer than the last applied (replayed or reordered)
  kRateLimited,
  kLate,    // waited in the receive queue longer than the bound (a frozen or stalled server)
  kFenced,  // the node's lease has lapsed: it may no longer answer for its sessions
  kCount
};
const char* DropReasonName(DropReason r);

using SessionKey = std::array<uint8_t, kKeySize>;

// A session key made ready for HMAC (inner and outer pads absorbed).
class Authenticator {
 public:
  explicit Authenticator(const SessionKey& key);
  // 16-byte tag of `data`.
  std::array<uint8_t, kTagSize> Tag(std::span<const uint8_t> data) const;

 private:
  alignas(16) unsigned char inner_[128];  // SHA256_CTX after the ipad block (opaque storage)
  alignas(16) unsigned char outer_[128];  // SHA256_CTX after the opad block
};

struct Header {
  uint8_t version = kProtocolVersion;
  PayloadType type = PayloadType::kStylusState;
  uint64_t session = 0;
  uint64_t sequence = 0;
};

// Writes header, payload and tag into `out` (≥ kHeaderSize + payload + kTagSize). Returns the
// datagram size, or 0 if the payload is larger than kMaxPayload.
size_t Seal(const Header& header, std::span<const uint8_t> payload, const Authenticator& auth,
            std::span<uint8_t> out);

// Reads the header without authenticating (to find the session's key). kNone when well formed.
DropReason PeekHeader(std::span<const uint8_t> datagram, Header& header);

struct Opened {
  Header header;
  std::span<const uint8_t> payload;  // points into the datagram
};
// Checks the framing and the tag. `auth` is the session's authenticator (nullptr: unknown).
DropReason Open(std::span<const uint8_t> datagram, const Authenticator* auth, Opened& out);
// The tag only, for a datagram whose header PeekHeader already read and checked (an endpoint
// peeks to find the session's key, then verifies: the header is parsed once).
DropReason Verify(std::span<const uint8_t> datagram, const Authenticator& auth,
                  std::span<const uint8_t>& payload);

}  // namespace vsurg::wire
