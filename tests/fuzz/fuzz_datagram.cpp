// libFuzzer target: a datagram as the server's UDP endpoint receives it (framing, sizes, the tag),
// and, behind a valid tag, the payload decoders. The fuzzer cannot forge an HMAC, so an input
// whose first byte is odd is a header and payload that this harness seals with the session key
// first; an even first byte sends the rest as it is, tag and all.
//
// Properties: nothing crashes or reads out of bounds (ASan, UBSan); a datagram this harness
// sealed always opens (Seal and Open agree); a force or scene frame that decodes is finite.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>

#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

using namespace vsurg::wire;

const Authenticator& Auth() {
  static const Authenticator auth([] {
    SessionKey k;
    for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(i * 7 + 3);
    return k;
  }());
  return auth;
}

uint64_t Read64(const uint8_t* p) {
  uint64_t v = 0;
  std::memcpy(&v, p, sizeof v);
  return v;
}

void Decode(Codec& codec, const Opened& o) {
  switch (o.header.type) {
    case PayloadType::kStylusState: {
      // Non-finite stylus values are passed on by design: the simulation's input check refuses
      // them with an event the station sees (tests/common/sim/haptic_property_test.cpp).
      StylusMessage m;
      if (codec.DecodeStylus(o.payload, m) == DropReason::kNone)
        VSURG_FUZZ_CHECK(std::isfinite(m.rtt_us) && m.rtt_us >= 0);
      break;
    }
    case PayloadType::kForceFeedback: {
      ForceMessage m;
      if (codec.DecodeForce(o.payload, m) == DropReason::kNone)
        VSURG_FUZZ_CHECK(m.command.force.allFinite() && m.command.local.jacobian.allFinite());
      break;
    }
    case PayloadType::kSceneFrame: {
      SceneChunk c;
      if (codec.DecodeSceneChunk(o.payload, c) == DropReason::kNone) {
        VSURG_FUZZ_CHECK(c.indices.size() == c.positions.size());
        for (const auto& p : c.positions) VSURG_FUZZ_CHECK(p.allFinite());
      }
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Codec codec;
  if (size < 1) return 0;
  std::span<const uint8_t> datagram(data + 1, size - 1);
  uint8_t sealed[kMaxDatagram];
  if (data[0] & 1) {
    // [type, session 8, sequence 8, time 8] then the payload.
    if (size < 26) return 0;
    Header h;
    h.type = static_cast<PayloadType>(1 + data[1] % 3);
    h.session = Read64(data + 2);
    h.sequence = Read64(data + 10);
    const std::span<const uint8_t> payload(data + 26, size - 26);
    const size_t n = Seal(h, payload, Auth(), sealed);
    if (n == 0) {
      VSURG_FUZZ_CHECK(payload.size() > kMaxPayload);
      return 0;
    }
    Opened o;
    VSURG_FUZZ_CHECK(Open(std::span<const uint8_t>(sealed, n), &Auth(), o) == DropReason::kNone);
    VSURG_FUZZ_CHECK(o.header.session == h.session && o.header.sequence == h.sequence);
    Decode(codec, o);
    return 0;
  }
  Header peeked;
  (void)PeekHeader(datagram, peeked);
  Opened o;
  (void)Open(datagram, nullptr, o);  // an unknown session: never opens
  if (Open(datagram, &Auth(), o) == DropReason::kNone) Decode(codec, o);
  return 0;
}
