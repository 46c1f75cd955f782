// libFuzzer target: the protobuf payload decoders without the datagram around them (what reaches
// them once a tag is valid), with a round trip: what decodes re-encodes and decodes to itself.
// The first byte picks the message type; the rest is the payload.
#include <cmath>
#include <cstdint>
#include <span>

#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"
#include "tests/fuzz/fuzz_check.h"

namespace {
using namespace vsurg::wire;

// Equal, or both NaN (non-finite stylus values are passed on by design).
bool Same(double a, double b) {
  return a == b || (std::isnan(a) && std::isnan(b));
}

const Authenticator& Auth() {
  static const Authenticator auth(SessionKey{});
  return auth;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Codec codec;
  if (size < 1) return 0;
  const std::span<const uint8_t> payload(data + 1, size - 1);
  uint8_t out[kMaxDatagram];
  Opened o;
  switch (data[0] % 3) {
    case 0: {
      StylusMessage m;
      if (codec.DecodeStylus(payload, m) != DropReason::kNone) return 0;
      const size_t n = codec.EncodeStylus(m, {}, Auth(), out);
      VSURG_FUZZ_CHECK(n > 0);
      VSURG_FUZZ_CHECK(Open(std::span<const uint8_t>(out, n), &Auth(), o) == DropReason::kNone);
      StylusMessage back;
      VSURG_FUZZ_CHECK(codec.DecodeStylus(o.payload, back) == DropReason::kNone);
      VSURG_FUZZ_CHECK(Same(back.sample.time, m.sample.time) &&
                       Same(back.sample.position.x(), m.sample.position.x()) &&
                       Same(back.sample.position.z(), m.sample.position.z()) &&
                       back.sample.buttons == m.sample.buttons &&
                       back.twist_shape_key == m.twist_shape_key);
      break;
    }
    case 1: {
      ForceMessage m;
      if (codec.DecodeForce(payload, m) != DropReason::kNone) return 0;
      const size_t n = codec.EncodeForce(m, {.type = PayloadType::kForceFeedback}, Auth(), out);
      VSURG_FUZZ_CHECK(n > 0);
      VSURG_FUZZ_CHECK(Open(std::span<const uint8_t>(out, n), &Auth(), o) == DropReason::kNone);
      ForceMessage back;
      VSURG_FUZZ_CHECK(codec.DecodeForce(o.payload, back) == DropReason::kNone);
      VSURG_FUZZ_CHECK(back.command.force == m.command.force &&
                       back.echo_sequence == m.echo_sequence);
      break;
    }
    default: {
      SceneChunk c;
      if (codec.DecodeSceneChunk(payload, c) != DropReason::kNone) return 0;
      VSURG_FUZZ_CHECK(c.indices.size() == c.positions.size());
      VSURG_FUZZ_CHECK(c.chunk_index < c.chunk_count);
      if (c.twist) {  // a coil limb's twist: whole, finite, and the same after a round trip
        VSURG_FUZZ_CHECK(c.indices.empty() && c.chunk_count == 1);
        VSURG_FUZZ_CHECK(std::isfinite(c.twist->arc) && std::isfinite(c.twist->torque));
        const size_t n = codec.EncodeTwistFrame(c.frame_id, *c.twist,
                                                {.type = PayloadType::kSceneFrame}, Auth(), out);
        VSURG_FUZZ_CHECK(n > 0);
        VSURG_FUZZ_CHECK(Open(std::span<const uint8_t>(out, n), &Auth(), o) == DropReason::kNone);
        SceneChunk back;
        VSURG_FUZZ_CHECK(codec.DecodeSceneChunk(o.payload, back) == DropReason::kNone);
        VSURG_FUZZ_CHECK(back.twist && back.twist->key == c.twist->key &&
                         back.twist->grasp == c.twist->grasp && back.twist->arc == c.twist->arc &&
                         back.twist->torque == c.twist->torque && back.frame_id == c.frame_id);
      }
      break;
    }
  }
  return 0;
}
