// The haptic channel's messages, between the plain haptics types (common/haptics/types.h) and
// authenticated datagrams. Only this file pair and the endpoints know protobuf; the simulation
// sees StylusSample and ForceCommand.
//
// Threads: a Codec belongs to one thread (it reuses its protobuf messages and buffers, so
// encoding and decoding do not allocate after the first message of each kind).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "common/haptics/types.h"
#include "proto/wire/datagram.h"

namespace vsurg::wire {

struct StylusMessage {
  haptics::StylusSample sample;
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // m/s
};

struct ForceMessage {
  uint64_t echo_sequence = 0;
  double echo_time = 0;    // s
  double server_time = 0;  // s
  haptics::ForceCommand command;
};

class Codec {
 public:
  Codec();
  ~Codec();
  Codec(Codec&&) noexcept;
  Codec& operator=(Codec&&) noexcept;

  // Seal a message into `out` (kMaxDatagram bytes). Return the size, 0 on failure.
  size_t EncodeStylus(const StylusMessage& m, const Header& h, const Authenticator& auth,
                      std::span<uint8_t> out);
  size_t EncodeForce(const ForceMessage& m, const Header& h, const Authenticator& auth,
                     std::span<uint8_t> out);

  // Parse an opened payload. kBadPayload when it does not parse or holds non-finite numbers.
  DropReason DecodeStylus(std::span<const uint8_t> payload, StylusMessage& out);
  DropReason DecodeForce(std::span<const uint8_t> payload, ForceMessage& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::wire
