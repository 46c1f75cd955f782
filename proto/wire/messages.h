// The haptic channel's messages, between the plain haptics types (common/haptics/types.h) and
// authenticated datagrams. Only this file pair and the endpoints know protobuf; the simulation
// sees StylusSample and ForceCommand.
//
// Threads: a Codec belongs to one thread (it reuses its protobuf messages and buffers, so
// encoding and decoding do not allocate after the first message of each kind).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "common/haptics/types.h"
#include "proto/wire/datagram.h"

namespace vsurg::wire {

struct StylusMessage {
  haptics::StylusSample sample;
  double rtt_us = 0;  // the station's last measured round trip (telemetry), 0 if none yet
  // The station's rendering so far (haptic.proto StylusState); 0: not reported. Decoding maps
  // anything non-finite or negative to 0.
  double rendered_peak_n = 0, rendered_over_limit_s = 0, jitter_us = 0;
  uint64_t twist_shape_key = 0;  // the coil limb whose twist frames it remakes; 0: none
};

struct ForceMessage {
  uint64_t echo_sequence = 0;
  double echo_time = 0;    // s
  double server_time = 0;  // s
  haptics::ForceCommand command;
};

// A coil limb's twist, the frame's whole surface (SceneFrame.coil_twist).
struct CoilTwist {
  uint64_t key = 0;  // the limb's CoilLimbKey
  uint64_t grasp = 0;
  double arc = 0;     // m
  double torque = 0;  // N·m
};

// A visual frame's moved vertices, as the simulation produces them.
struct SceneFrameView {
  uint64_t frame_id = 0;
  std::span<const int32_t> indices;
  std::span<const Eigen::Vector3d> positions;  // m, one per index
};

// One received chunk of a frame: positions back in metres (quantised to 1 µm on the wire), or a
// coil limb's twist (no vertices).
struct SceneChunk {
  uint64_t frame_id = 0;
  uint32_t chunk_index = 0, chunk_count = 0;
  std::vector<int32_t> indices;
  std::vector<Eigen::Vector3d> positions;
  std::optional<CoilTwist> twist;
  // A cut's faces (SceneFrame.topology): each face index and its three corners; topology 0: none.
  uint64_t topology = 0;
  std::vector<int32_t> face_indices;
  std::vector<std::array<int32_t, 3>> faces;
};

// A cut's faces that differ from the rest mesh, as the simulation gives them.
struct TopologyView {
  uint64_t frame_id = 0, topology = 0;
  std::span<const int32_t> face_indices;
  std::span<const std::array<int, 3>> faces;
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

  // Split a frame into as few datagrams of at most kMaxDatagram bytes as fit it (greedy, by the
  // exact varint sizes), each sealed, and hand each to `sink`. Returns the chunk count; 0 when
  // there is nothing to send or a position is out of the ±1 km the µm encoding covers. Each
  // chunk is delta-coded within itself (proto/vsurg/v1/haptic.proto, SceneFrame).
  template <class Sink>
  size_t EncodeSceneFrame(const SceneFrameView& frame, const Header& base,
                          const Authenticator& auth, std::span<uint8_t> out, Sink&& sink) {
    const size_t chunks = PlanSceneChunks(frame);
    for (size_t c = 0; c < chunks; ++c) {
      const size_t n = EncodeSceneChunk(frame, c, chunks, base, auth, out);
      if (n == 0) return 0;
      sink(std::span<const uint8_t>(out.data(), n));
    }
    return chunks;
  }
  // A coil limb's twist as one sealed chunk (SceneFrame.coil_twist); 0 when its numbers are not
  // finite.
  size_t EncodeTwistFrame(uint64_t frame_id, const CoilTwist& twist, const Header& h,
                          const Authenticator& auth, std::span<uint8_t> out);
  // A cut's faces in as many chunks as they take (kTopologyChunkFaces each), each sealed and
  // handed to `sink`. Returns the chunk count; 0 when there is nothing to send or an index is
  // negative or past 2²⁴.
  static constexpr size_t kTopologyChunkFaces = 48;  // ≤ 20 bytes each, whatever the deltas
  template <class Sink>
  size_t EncodeTopologyFrame(const TopologyView& t, const Header& base, const Authenticator& auth,
                             std::span<uint8_t> out, Sink&& sink) {
    if (t.face_indices.empty() || t.face_indices.size() != t.faces.size() || t.topology == 0)
      return 0;
    const size_t chunks = (t.faces.size() + kTopologyChunkFaces - 1) / kTopologyChunkFaces;
    for (size_t c = 0; c < chunks; ++c) {
      const size_t n = EncodeTopologyChunk(t, c, chunks, base, auth, out);
      if (n == 0) return 0;
      sink(std::span<const uint8_t>(out.data(), n));
    }
    return chunks;
  }
  // A chunk of vertices or a twist; a twist with vertices, of more than one chunk or with a
  // number that is not finite is kBadPayload.
  DropReason DecodeSceneChunk(std::span<const uint8_t> payload, SceneChunk& out);

  // Parse an opened payload. kBadPayload when it does not parse. A force whose force or local
  // model is non-finite is refused too (a station renders it at 1 kHz); a stylus sample's
  // non-finite values are passed on, for the simulation's input check to refuse with an event
  // the station sees.
  DropReason DecodeStylus(std::span<const uint8_t> payload, StylusMessage& out);
  DropReason DecodeForce(std::span<const uint8_t> payload, ForceMessage& out);

 private:
  size_t PlanSceneChunks(const SceneFrameView& frame);  // fills the chunk boundaries
  size_t EncodeSceneChunk(const SceneFrameView& frame, size_t chunk, size_t chunks,
                          const Header& base, const Authenticator& auth, std::span<uint8_t> out);
  size_t EncodeTopologyChunk(const TopologyView& t, size_t chunk, size_t chunks, const Header& base,
                             const Authenticator& auth, std::span<uint8_t> out);
  std::vector<size_t> chunk_start_;
  std::vector<int32_t> quantized_;  // the planned frame's positions in µm, three per vertex
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::wire
