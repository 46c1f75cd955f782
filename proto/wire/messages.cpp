#include "proto/wire/messages.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdlib>

#include "vsurg/v1/haptic.pb.h"

namespace vsurg::wire {
namespace {

void Put(const Eigen::Vector3d& v, v1::Vec3* m) {
  m->set_x(v.x());
  m->set_y(v.y());
  m->set_z(v.z());
}
Eigen::Vector3d Get(const v1::Vec3& m) {
  return {m.x(), m.y(), m.z()};
}

}  // namespace

// Each encode or decode builds its message afresh on an arena whose only block is this struct's
// own buffer: Reset() returns the whole block, so no call reaches the heap once the codec exists
// (a reused message would not do: proto3 Clear() and Parse() delete and re-create every
// submessage, eight heap allocations per stylus-and-force exchange), and nothing a previous
// message left (unknown fields, repeated values) can ride along.
struct Codec::Impl {
  static constexpr size_t kArenaBytes = 64 * 1024;  // a SceneFrame chunk needs ~10 KiB at most
  alignas(16) std::array<char, kArenaBytes> block;
  google::protobuf::Arena arena{ArenaOptionsFor(block)};
  std::array<uint8_t, kMaxPayload> payload;

  static google::protobuf::ArenaOptions ArenaOptionsFor(std::array<char, kArenaBytes>& b) {
    google::protobuf::ArenaOptions o;
    o.initial_block = b.data();
    o.initial_block_size = b.size();
    return o;
  }
  template <class Message>
  Message& Fresh() {
    arena.Reset();
    return *google::protobuf::Arena::CreateMessage<Message>(&arena);
  }
  // `m` serialized into `payload`, sized once: ByteSizeLong caches the packed fields' sizes and
  // SerializeWithCachedSizesToArray uses them (SerializeToArray would size it all again). False
  // when it does not fit.
  bool Serialize(const google::protobuf::MessageLite& m, size_t& n) {
    n = m.ByteSizeLong();
    if (n > kMaxPayload) return false;
    return static_cast<size_t>(m.SerializeWithCachedSizesToArray(payload.data()) -
                               payload.data()) == n;
  }
  // `m` serialized and sealed as a datagram of `type` with `h`'s other fields; 0 when it does
  // not fit.
  size_t Sealed(const google::protobuf::MessageLite& m, Header h, PayloadType type,
                const Authenticator& auth, std::span<uint8_t> out) {
    size_t n = 0;
    if (!Serialize(m, n)) return 0;
    h.type = type;
    return Seal(h, std::span<const uint8_t>(payload.data(), n), auth, out);
  }
};

Codec::Codec() : impl_(std::make_unique<Impl>()) {}
Codec::~Codec() = default;
Codec::Codec(Codec&&) noexcept = default;
Codec& Codec::operator=(Codec&&) noexcept = default;

size_t Codec::EncodeStylus(const StylusMessage& m, const Header& h, const Authenticator& auth,
                           std::span<uint8_t> out) {
  v1::StylusState& s = impl_->Fresh<v1::StylusState>();
  s.set_time(m.sample.time);
  Put(m.sample.position, s.mutable_position());
  const Eigen::Quaterniond& q = m.sample.orientation;
  s.mutable_orientation()->set_w(q.w());
  s.mutable_orientation()->set_x(q.x());
  s.mutable_orientation()->set_y(q.y());
  s.mutable_orientation()->set_z(q.z());
  s.set_buttons(m.sample.buttons);
  s.set_rtt_us(static_cast<float>(m.rtt_us));
  s.set_rendered_peak_n(static_cast<float>(m.rendered_peak_n));
  s.set_rendered_over_limit_s(static_cast<float>(m.rendered_over_limit_s));
  s.set_jitter_us(static_cast<float>(m.jitter_us));
  s.set_twist_shape_key(m.twist_shape_key);
  return impl_->Sealed(s, h, PayloadType::kStylusState, auth, out);
}

size_t Codec::EncodeForce(const ForceMessage& m, const Header& h, const Authenticator& auth,
                          std::span<uint8_t> out) {
  v1::ForceFeedback& f = impl_->Fresh<v1::ForceFeedback>();
  const haptics::ForceCommand& c = m.command;
  f.set_echo_sequence(m.echo_sequence);
  f.set_echo_time(m.echo_time);
  f.set_server_time(m.server_time);
  Put(c.force, f.mutable_force());
  f.set_contact(c.contact);
  f.set_grasping(c.grasping);
  Put(c.proxy, f.mutable_proxy());
  v1::LocalModel* local = f.mutable_local();
  Put(c.local.force0, local->mutable_force0());
  Put(c.local.position0, local->mutable_position0());
  local->mutable_jacobian()->Resize(9, 0.0);  // keeps its capacity: no allocation after the first
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) local->set_jacobian(3 * r + k, c.local.jacobian(r, k));
  }
  // Only what the kind uses crosses the wire (a grasp answer grows by ~90 bytes and ~100 more with
  // its exact model, a contact by 27, and by 27 more once it carries the tissue, or 9 ahead of
  // contact with the proxy's damping).
  local->set_kind(static_cast<v1::LocalModel::Kind>(c.local.kind));
  if (c.local.kind == haptics::LocalModel::Kind::kContact) {
    Put(c.local.normal, local->mutable_normal());
    local->set_tissue_stiffness(c.local.tissue_stiffness);
    local->set_tissue_damping(c.local.tissue_damping);
    local->set_tissue_elastic0(c.local.tissue_elastic0);
    local->set_contact_damping(c.local.contact_damping);
  } else {
    local->clear_tissue_stiffness(), local->clear_tissue_damping(), local->clear_tissue_elastic0();
    local->clear_contact_damping();
  }
  if (c.local.pull_gain > 0) {
    Put(c.local.pull_target, local->mutable_pull_target());
    local->set_pull_gain(c.local.pull_gain);
  } else {  // Clear keeps the submessage's allocation (2 bytes on the wire once it was used)
    if (local->has_pull_target()) local->mutable_pull_target()->Clear();
    local->clear_pull_gain();
  }
  if (c.local.kind == haptics::LocalModel::Kind::kGrasp) {
    Put(c.local.axis, local->mutable_axis());
    Put(c.local.dforce_dtwist, local->mutable_dforce_dtwist());
    if (c.local.has_twist_model) {
      for (const double t : c.local.torque_steps) local->add_torque_steps(static_cast<float>(t));
      Put(c.local.force_per_torque, local->mutable_force_per_torque());
      local->set_torque0(c.local.torque0);
      Put(c.local.arm, local->mutable_arm());
    }
    const Eigen::Quaterniond& q0 = c.local.orientation0;
    v1::Quat* q = local->mutable_orientation0();
    q->set_w(q0.w()), q->set_x(q0.x()), q->set_y(q0.y()), q->set_z(q0.z());
  }
  if (c.local.kind == haptics::LocalModel::Kind::kNeedle) {
    const haptics::NeedleState& n = c.local.needle;
    v1::NeedleState* w = local->mutable_needle();
    w->set_phase(static_cast<uint32_t>(n.phase)), w->set_tract(n.tract), w->set_begun(n.begun);
    Put(n.entry, w->mutable_entry()), Put(n.direction, w->mutable_direction());
    w->set_passed(n.passed), w->set_cut(n.cut), w->set_anchor(n.anchor);
    w->set_last_depth(n.last_depth), w->set_velocity(n.velocity);
  } else {
    local->clear_needle();
  }
  f.set_events(c.events);
  f.set_twist(c.twist);
  f.set_score(static_cast<float>(c.score));
  f.set_released_j(c.released_j);
  f.set_absorbed_j(c.absorbed_j);
  f.set_guide_mode(c.guide_mode);
  f.set_guide_alpha(static_cast<float>(c.guide_alpha));
  f.set_shared(c.shared);
  return impl_->Sealed(f, h, PayloadType::kForceFeedback, auth, out);
}

namespace {

size_t VarintSize(uint64_t v) {  // 7 bits a byte: (significant bits + 6) / 7, at least 1
  return static_cast<size_t>((64 - std::countl_zero(v | 1)) + 6) / 7;
}
uint64_t ZigZag(int64_t v) {
  return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63);
}
constexpr double kMicro = 1e6;
// A coordinate within ±1 km, so that a delta between two (±2·10⁹ µm) fits a sint32.
constexpr double kMaxMetres = 1000.0;
constexpr int64_t kMaxMicro = 1'000'000'000;
constexpr size_t kFrameOverhead = 48;           // frame id, chunk fields, two packed-field headers
constexpr int64_t kMaxTopologyIndex = 1 << 24;  // faces and vertices of a cut's patch

}  // namespace

size_t Codec::PlanSceneChunks(const SceneFrameView& f) {
  chunk_start_.clear();
  quantized_.clear();
  if (f.indices.empty() || f.indices.size() != f.positions.size()) return 0;
  quantized_.reserve(3 * f.positions.size());
  const size_t budget = kMaxPayload - kFrameOverhead;
  size_t used = budget + 1;
  int64_t previous_index = 0;
  std::array<int64_t, 3> previous{};
  for (size_t i = 0; i < f.indices.size(); ++i) {
    const Eigen::Vector3d& p = f.positions[i];
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > kMaxMetres || f.indices[i] < 0) return 0;
    std::array<int64_t, 3> um{};
    for (int k = 0; k < 3; ++k) {
      // To the nearest µm (ties to even: lrint is one instruction where llround is a call);
      // each position quantised once, here, for the chunks' encoding too.
      um[k] = std::lrint(p[k] * kMicro);
      quantized_.push_back(static_cast<int32_t>(um[k]));
    }
    // The vertex's size as a delta from the one before it in the chunk (from zero as a chunk's
    // first).
    const auto size_after = [&](int64_t index, const std::array<int64_t, 3>& at) {
      size_t n = VarintSize(ZigZag(f.indices[i] - index));
      for (int k = 0; k < 3; ++k) n += VarintSize(ZigZag(um[k] - at[k]));
      return n;
    };
    size_t size = size_after(previous_index, previous);
    if (used + size > budget) {
      chunk_start_.push_back(i);
      used = 0;
      size = size_after(0, {});
    }
    used += size;
    previous_index = f.indices[i];
    previous = um;
  }
  chunk_start_.push_back(f.indices.size());
  return chunk_start_.size() - 1;
}

size_t Codec::EncodeSceneChunk(const SceneFrameView& f, size_t chunk, size_t chunks,
                               const Header& base, const Authenticator& auth,
                               std::span<uint8_t> out) {
  v1::SceneFrame& m = impl_->Fresh<v1::SceneFrame>();
  m.set_frame_id(f.frame_id);
  m.set_chunk_index(static_cast<uint32_t>(chunk));
  m.set_chunk_count(static_cast<uint32_t>(chunks));
  const size_t first = chunk_start_[chunk], last = chunk_start_[chunk + 1];
  auto& index_deltas = *m.mutable_index_deltas();
  auto& position_deltas = *m.mutable_position_deltas_um();
  index_deltas.Reserve(static_cast<int>(last - first));
  position_deltas.Reserve(static_cast<int>(3 * (last - first)));
  int32_t previous_index = 0;
  std::array<int32_t, 3> previous{};
  for (size_t i = first; i < last; ++i) {
    index_deltas.AddAlreadyReserved(f.indices[i] - previous_index);
    previous_index = f.indices[i];
    for (size_t k = 0; k < 3; ++k) {
      const int32_t um = quantized_[3 * i + k];  // |um| ≤ 10⁹: the delta fits
      position_deltas.AddAlreadyReserved(um - previous[k]);
      previous[k] = um;
    }
  }
  Header h = base;
  h.sequence = base.sequence + chunk;
  return impl_->Sealed(m, h, PayloadType::kSceneFrame, auth, out);
}

size_t Codec::EncodeTwistFrame(uint64_t frame_id, const CoilTwist& twist, const Header& base,
                               const Authenticator& auth, std::span<uint8_t> out) {
  if (!std::isfinite(twist.arc) || !std::isfinite(twist.torque)) return 0;
  v1::SceneFrame& m = impl_->Fresh<v1::SceneFrame>();
  m.set_frame_id(frame_id);
  m.set_chunk_index(0);
  m.set_chunk_count(1);
  v1::SceneFrame::CoilTwist& t = *m.mutable_coil_twist();
  t.set_grasp(twist.grasp);
  t.set_arc_m(twist.arc);
  t.set_torque_nm(twist.torque);
  t.set_key(twist.key);
  return impl_->Sealed(m, base, PayloadType::kSceneFrame, auth, out);
}

size_t Codec::EncodeTopologyChunk(const TopologyView& t, size_t chunk, size_t chunks,
                                  const Header& base, const Authenticator& auth,
                                  std::span<uint8_t> out) {
  v1::SceneFrame& m = impl_->Fresh<v1::SceneFrame>();
  m.set_frame_id(t.frame_id);
  m.set_chunk_index(static_cast<uint32_t>(chunk));
  m.set_chunk_count(static_cast<uint32_t>(chunks));
  m.set_topology(t.topology);
  const size_t first = chunk * kTopologyChunkFaces;
  const size_t last = std::min(t.faces.size(), first + kTopologyChunkFaces);
  int32_t previous_face = 0, previous_vertex = 0;
  for (size_t i = first; i < last; ++i) {
    if (t.face_indices[i] < 0 || t.face_indices[i] > kMaxTopologyIndex) return 0;
    m.add_face_index_deltas(t.face_indices[i] - previous_face);
    previous_face = t.face_indices[i];
    for (int v : t.faces[i]) {
      if (v < 0 || v > kMaxTopologyIndex) return 0;
      m.add_face_vertex_deltas(v - previous_vertex);
      previous_vertex = v;
    }
  }
  Header h = base;
  h.sequence = base.sequence + chunk;
  return impl_->Sealed(m, h, PayloadType::kSceneFrame, auth, out);
}

namespace {

// A chunk of a cut's faces: nothing else in it, every index within [0, 2²⁴].
DropReason DecodeTopologyChunk(const v1::SceneFrame& m, SceneChunk& out) {
  if (m.indices_size() > 0 || m.index_deltas_size() > 0 || m.has_coil_twist() ||
      m.face_vertex_deltas_size() != 3 * m.face_index_deltas_size() || m.chunk_count() == 0 ||
      m.chunk_index() >= m.chunk_count())
    return DropReason::kBadPayload;
  out.frame_id = m.frame_id();
  out.chunk_index = m.chunk_index();
  out.chunk_count = m.chunk_count();
  out.topology = m.topology();
  out.indices.clear();
  out.positions.clear();
  const int count = m.face_index_deltas_size();
  out.face_indices.resize(count);
  out.faces.resize(count);
  int64_t face = 0, vertex = 0;  // sums of at most 2²⁰ deltas of at most 2³¹: no overflow
  for (int i = 0; i < count; ++i) {
    face += m.face_index_deltas(i);
    if (face < 0 || face > kMaxTopologyIndex) return DropReason::kBadPayload;
    out.face_indices[i] = static_cast<int32_t>(face);
    for (int k = 0; k < 3; ++k) {
      vertex += m.face_vertex_deltas(3 * i + k);
      if (vertex < 0 || vertex > kMaxTopologyIndex) return DropReason::kBadPayload;
      out.faces[i][k] = static_cast<int32_t>(vertex);
    }
  }
  return DropReason::kNone;
}

}  // namespace

DropReason Codec::DecodeSceneChunk(std::span<const uint8_t> payload, SceneChunk& out) {
  v1::SceneFrame& m = impl_->Fresh<v1::SceneFrame>();
  if (!m.ParseFromArray(payload.data(), static_cast<int>(payload.size())))
    return DropReason::kBadPayload;
  out.twist.reset();
  out.topology = 0;
  out.face_indices.clear();
  out.faces.clear();
  if (m.topology() != 0) return DecodeTopologyChunk(m, out);
  if (m.face_index_deltas_size() > 0 || m.face_vertex_deltas_size() > 0)
    return DropReason::kBadPayload;
  if (m.has_coil_twist()) {
    const v1::SceneFrame::CoilTwist& t = m.coil_twist();
    if (m.indices_size() > 0 || m.index_deltas_size() > 0 || m.positions_um_size() > 0 ||
        m.position_deltas_um_size() > 0 || m.chunk_count() != 1 || m.chunk_index() != 0 ||
        !std::isfinite(t.arc_m()) || !std::isfinite(t.torque_nm()))
      return DropReason::kBadPayload;
    out.frame_id = m.frame_id();
    out.chunk_index = 0;
    out.chunk_count = 1;
    out.indices.clear();
    out.positions.clear();
    out.twist = CoilTwist{t.key(), t.grasp(), t.arc_m(), t.torque_nm()};
    return DropReason::kNone;
  }
  const bool deltas = m.index_deltas_size() > 0 || m.position_deltas_um_size() > 0;
  if (m.positions_um_size() != 3 * m.indices_size() ||
      m.position_deltas_um_size() != 3 * m.index_deltas_size() ||
      (deltas && m.indices_size() > 0) || m.chunk_count() == 0 ||
      m.chunk_index() >= m.chunk_count()) {
    return DropReason::kBadPayload;  // one coding or the other, whole
  }
  out.frame_id = m.frame_id();
  out.chunk_index = m.chunk_index();
  out.chunk_count = m.chunk_count();
  const int count = deltas ? m.index_deltas_size() : m.indices_size();
  out.indices.resize(count);
  out.positions.resize(count);
  int64_t index = 0;
  std::array<int64_t, 3> um{};
  for (int i = 0; i < count; ++i) {
    if (deltas) {
      // Sums of at most 2²⁰ deltas of at most 2³¹ each: no int64 overflow, each checked.
      index += m.index_deltas(i);
      for (int k = 0; k < 3; ++k) um[k] += m.position_deltas_um(3 * i + k);
      if (std::max({std::abs(um[0]), std::abs(um[1]), std::abs(um[2])}) > kMaxMicro)
        return DropReason::kBadPayload;
    } else {
      index = m.indices(i);
      for (int k = 0; k < 3; ++k) um[k] = m.positions_um(3 * i + k);
    }
    if (index < 0 || index > 0x7fffffff) return DropReason::kBadPayload;
    out.indices[i] = static_cast<int32_t>(index);
    out.positions[i] = Eigen::Vector3d(static_cast<double>(um[0]), static_cast<double>(um[1]),
                                       static_cast<double>(um[2])) /
                       kMicro;
  }
  return DropReason::kNone;
}

DropReason Codec::DecodeStylus(std::span<const uint8_t> payload, StylusMessage& out) {
  v1::StylusState& s = impl_->Fresh<v1::StylusState>();
  if (!s.ParseFromArray(payload.data(), static_cast<int>(payload.size())))
    return DropReason::kBadPayload;
  out.sample.time = s.time();
  out.sample.position = Get(s.position());
  out.sample.orientation = Eigen::Quaterniond(s.orientation().w(), s.orientation().x(),
                                              s.orientation().y(), s.orientation().z());
  out.sample.buttons = s.buttons();
  out.rtt_us = std::isfinite(s.rtt_us()) && s.rtt_us() > 0 ? s.rtt_us() : 0.0;
  const auto figure = [](float v) { return std::isfinite(v) && v > 0 ? double{v} : 0.0; };
  out.rendered_peak_n = figure(s.rendered_peak_n());
  out.rendered_over_limit_s = figure(s.rendered_over_limit_s());
  out.jitter_us = figure(s.jitter_us());
  out.twist_shape_key = s.twist_shape_key();
  // Non-finite values are passed on: the simulation's safety turns them into zero force and an
  // event, which the station then sees.
  return DropReason::kNone;
}

namespace {

// Four-handed training's fields of an answer: a mode the station knows, α within [0, 1].
void ReadGuidance(const v1::ForceFeedback& f, haptics::ForceCommand& c) {
  c.guide_mode = f.guide_mode() <= 2 ? f.guide_mode() : 0;
  c.guide_alpha = std::isfinite(f.guide_alpha())
                      ? std::clamp(static_cast<double>(f.guide_alpha()), 0.0, 1.0)
                      : 0.0;
  c.shared = f.shared();
}

// A needle's state as a station can render it: a phase it knows, a unit direction into the
// tissue, finite lengths; else refused.
bool ReadNeedle(const v1::NeedleState& w, haptics::NeedleState& n) {
  if (w.phase() > 2) return false;
  n.phase = static_cast<haptics::NeedleState::Phase>(w.phase());
  n.tract = w.tract(), n.begun = w.begun(), n.passed = w.passed();
  n.entry = Get(w.entry()), n.direction = Get(w.direction());
  n.cut = w.cut(), n.anchor = w.anchor(), n.last_depth = w.last_depth(), n.velocity = w.velocity();
  const double d = n.direction.norm();
  if (!(d > 0.5 && d < 2) || !n.entry.allFinite() || !std::isfinite(n.cut) ||
      !std::isfinite(n.anchor) || !std::isfinite(n.last_depth) || !std::isfinite(n.velocity))
    return false;
  n.direction /= d;
  return true;
}

// The local model's kind-specific parts, normalised; an unknown kind (a newer server) renders as
// LINEAR, the oldest contract; a contact or grasp whose directions cannot be normalised, or a
// needle's state a station cannot render, is refused.
DropReason ReadLocalKind(const v1::LocalModel& w, haptics::LocalModel& l) {
  l.kind = haptics::LocalModel::Kind::kLinear;
  l.normal = Eigen::Vector3d::UnitZ();
  l.axis = Eigen::Vector3d::UnitZ();
  l.orientation0 = Eigen::Quaterniond::Identity();
  l.dforce_dtwist.setZero();
  l.has_twist_model = false;
  l.torque_steps.fill(0);
  l.force_per_torque.setZero();
  l.arm.setZero();
  l.torque0 = 0;
  l.tissue_stiffness = l.tissue_damping = l.tissue_elastic0 = 0;
  l.contact_damping = 0;
  l.needle = {};
  // The coupling: a gain outside [0, 1] or a target that is not finite is refused, not guessed.
  l.pull_target = Get(w.pull_target());
  l.pull_gain = w.pull_gain();
  if (!(l.pull_gain >= 0 && l.pull_gain <= 1) || !l.pull_target.allFinite())
    return DropReason::kBadPayload;
  const auto unit = [](const Eigen::Vector3d& v, Eigen::Vector3d& unit_out) {
    const double n = v.norm();
    if (!(n > 1e-9) || !std::isfinite(n)) return false;
    unit_out = v / n;
    return true;
  };
  switch (w.kind()) {
    case v1::LocalModel::CONTACT:
      if (!unit(Get(w.normal()), l.normal)) return DropReason::kBadPayload;
      l.kind = haptics::LocalModel::Kind::kContact;
      // A tissue the station cannot integrate (negative, non-finite) is refused, not guessed.
      l.tissue_stiffness = w.tissue_stiffness();
      l.tissue_damping = w.tissue_damping();
      l.tissue_elastic0 = w.tissue_elastic0();
      l.contact_damping = w.contact_damping();
      if (!(l.tissue_stiffness >= 0) || !(l.tissue_damping >= 0) ||
          !std::isfinite(l.tissue_stiffness) || !std::isfinite(l.tissue_damping) ||
          !std::isfinite(l.tissue_elastic0) || !(l.contact_damping >= 0) ||
          !std::isfinite(l.contact_damping))
        return DropReason::kBadPayload;
      break;
    case v1::LocalModel::GRASP: {
      const v1::Quat& q = w.orientation0();
      Eigen::Quaterniond q0(q.w(), q.x(), q.y(), q.z());
      const double qn = q0.norm();
      if (!unit(Get(w.axis()), l.axis) || !(qn > 1e-9) || !std::isfinite(qn))
        return DropReason::kBadPayload;
      l.orientation0 = Eigen::Quaterniond(q0.coeffs() / qn);
      l.dforce_dtwist = Get(w.dforce_dtwist());
      if (!l.dforce_dtwist.allFinite()) return DropReason::kBadPayload;
      // The exact model: whole (8 finite steps and finite parts) or refused; none at all is an
      // older server's answer, rendered along its tangent.
      if (const int n = w.torque_steps_size(); n != 0) {
        if (n != haptics::LocalModel::kTwistSamples) return DropReason::kBadPayload;
        for (int i = 0; i < n; ++i) l.torque_steps[i] = w.torque_steps(i);
        l.force_per_torque = Get(w.force_per_torque());
        l.torque0 = w.torque0();
        l.arm = Get(w.arm());
        if (!std::all_of(l.torque_steps.begin(), l.torque_steps.end(),
                         [](double t) { return std::isfinite(t); }) ||
            !l.force_per_torque.allFinite() || !std::isfinite(l.torque0) || !l.arm.allFinite())
          return DropReason::kBadPayload;
        l.has_twist_model = true;
      }
      l.kind = haptics::LocalModel::Kind::kGrasp;
      break;
    }
    case v1::LocalModel::NEEDLE:
      if (!ReadNeedle(w.needle(), l.needle)) return DropReason::kBadPayload;
      l.kind = haptics::LocalModel::Kind::kNeedle;
      break;
    default:
      break;
  }
  return DropReason::kNone;
}

}  // namespace

DropReason Codec::DecodeForce(std::span<const uint8_t> payload, ForceMessage& out) {
  v1::ForceFeedback& f = impl_->Fresh<v1::ForceFeedback>();
  if (!f.ParseFromArray(payload.data(), static_cast<int>(payload.size())))
    return DropReason::kBadPayload;
  haptics::ForceCommand& c = out.command;
  out.echo_sequence = f.echo_sequence();
  out.echo_time = f.echo_time();
  out.server_time = f.server_time();
  c.force = Get(f.force());
  c.contact = f.contact();
  c.grasping = f.grasping();
  c.proxy = Get(f.proxy());
  c.local.force0 = Get(f.local().force0());
  c.local.position0 = Get(f.local().position0());
  if (f.local().jacobian_size() == 9) {
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) c.local.jacobian(r, k) = f.local().jacobian(3 * r + k);
    }
  } else {
    c.local.jacobian.setZero();
  }
  if (const DropReason why = ReadLocalKind(f.local(), c.local); why != DropReason::kNone)
    return why;
  c.events = f.events();
  c.twist = f.twist();
  c.score = std::isfinite(f.score()) ? std::clamp(static_cast<double>(f.score()), 0.0, 10.0) : 0.0;
  c.released_j = f.released_j();
  c.absorbed_j = f.absorbed_j();
  ReadGuidance(f, c);
  // A station renders these at 1 kHz: anything non-finite is refused here, and so are port
  // energies that are not energies (negative), which the network passivity control would trust.
  if (!c.force.allFinite() || !c.local.force0.allFinite() || !c.local.position0.allFinite() ||
      !c.local.jacobian.allFinite() || !(c.released_j >= 0) || !(c.absorbed_j >= 0) ||
      !std::isfinite(c.released_j) || !std::isfinite(c.absorbed_j)) {
    return DropReason::kBadPayload;
  }
  return DropReason::kNone;
}

}  // namespace vsurg::wire
