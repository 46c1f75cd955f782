#include "proto/wire/datagram.h"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "proto/wire/messages.h"

namespace vsurg::wire {
namespace {

SessionKey Key(uint8_t seed) {
  SessionKey k;
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(seed * 31 + i * 7);
  return k;
}

// A force answer sealed, opened and decoded again: at most 400 bytes, always authentic; the
// decoder's verdict on what it carried.
DropReason ForceRoundTrip(Codec& codec, const Authenticator& auth, const ForceMessage& m,
                          ForceMessage& back) {
  std::array<uint8_t, kMaxDatagram> buf;
  const size_t n =
      codec.EncodeForce(m, {kProtocolVersion, PayloadType::kForceFeedback, 5, 1}, auth, buf);
  EXPECT_GT(n, 0u);
  EXPECT_LE(n, 400u);
  Opened o;
  EXPECT_EQ(Open(std::span<const uint8_t>(buf.data(), n), &auth, o), DropReason::kNone);
  return codec.DecodeForce(o.payload, back);
}

StylusMessage Stylus() {
  StylusMessage m;
  m.sample.time = 12.345;
  m.sample.position = Eigen::Vector3d(0.01, -0.02, 0.2);
  m.sample.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  m.sample.buttons = 1;
  return m;
}

TEST(DatagramTest, HmacMatchesRfc4231TestCase2) {
  // RFC 4231 §4.3 uses key "Jefe"; ours are 32 bytes, zero-padded the same way HMAC pads.
  SessionKey key{};
  std::memcpy(key.data(), "Jefe", 4);
  const std::string data = "what do ya want for nothing?";
  const auto tag = Authenticator(key).Tag(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(data.data()), data.size()));
  const uint8_t expected[16] = {0x5b, 0xdc, 0xc1, 0x46, 0xbf, 0x60, 0x75, 0x4e,
                                0x6a, 0x04, 0x24, 0x26, 0x08, 0x95, 0x75, 0xc7};
  EXPECT_EQ(0, std::memcmp(tag.data(), expected, 16));
}

TEST(DatagramTest, StylusRoundTripIsSmallAndExact) {
  const Authenticator auth(Key(1));
  Codec codec;
  std::array<uint8_t, kMaxDatagram> buf;
  const size_t n =
      codec.EncodeStylus(Stylus(), {kProtocolVersion, PayloadType::kStylusState, 42, 7}, auth, buf);
  ASSERT_GT(n, 64u);
  EXPECT_LE(n, 200u);  // DESIGN.md: typically 64–200 bytes
  Opened opened;
  ASSERT_EQ(Open(std::span<const uint8_t>(buf.data(), n), &auth, opened), DropReason::kNone);
  EXPECT_EQ(opened.header.session, 42u);
  EXPECT_EQ(opened.header.sequence, 7u);
  // Bytes 20..27 are reserved: zero on the wire.
  for (size_t i = 20; i < 28; ++i) EXPECT_EQ(buf[i], 0) << i;
  // The endpoint's path: the header peeked once, then only the tag verified.
  Header peeked;
  std::span<const uint8_t> payload;
  ASSERT_EQ(PeekHeader(std::span<const uint8_t>(buf.data(), n), peeked), DropReason::kNone);
  ASSERT_EQ(Verify(std::span<const uint8_t>(buf.data(), n), auth, payload), DropReason::kNone);
  EXPECT_EQ(payload.data(), opened.payload.data());
  EXPECT_EQ(Verify(std::span<const uint8_t>(buf.data(), n), Authenticator(Key(2)), payload),
            DropReason::kBadTag);
  StylusMessage back;
  ASSERT_EQ(codec.DecodeStylus(opened.payload, back), DropReason::kNone);
  EXPECT_EQ(back.sample.position, Stylus().sample.position);
  EXPECT_EQ(back.sample.buttons, 1u);
  EXPECT_NEAR(back.sample.orientation.angularDistance(Stylus().sample.orientation), 0, 1e-15);
}

// Found by fuzz_messages: the codec's message object is shared by decode and encode, and a
// decoded payload's unknown fields (kept by the protobuf parser) rode along in the next encode:
// a peer could make us send its bytes, and oversized ones made the encode fail (no answer).
TEST(DatagramTest, AnEncodeCarriesNothingADecodedPayloadLeftBehind) {
  const Authenticator auth(Key(1));
  Codec fresh, shared;
  std::array<uint8_t, kMaxDatagram> a, b;
  const size_t clean = fresh.EncodeStylus(Stylus(), {}, auth, a);
  ASSERT_GT(clean, 0u);
  Opened o;
  ASSERT_EQ(Open(std::span<const uint8_t>(a.data(), clean), &auth, o), DropReason::kNone);
  // The same payload with an unknown field 99 (a 600-byte string) appended.
  std::vector<uint8_t> payload(o.payload.begin(), o.payload.end());
  payload.insert(payload.end(), {0x9a, 0x06, 0xd8, 0x04});  // field 99, length-delimited, 600
  payload.insert(payload.end(), 600, 'x');
  StylusMessage decoded;
  ASSERT_EQ(shared.DecodeStylus(payload, decoded), DropReason::kNone);
  const size_t n = shared.EncodeStylus(Stylus(), {}, auth, b);
  EXPECT_EQ(n, clean);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), clean), 0);
}

TEST(DatagramTest, ForceRoundTripCarriesTheLocalModel) {
  const Authenticator auth(Key(2));
  Codec codec;
  ForceMessage m;
  m.echo_sequence = 99;
  m.echo_time = 1.5;
  m.command.force = Eigen::Vector3d(0, 0, 1.25);
  m.command.local.force0 = m.command.force;
  m.command.local.position0 = Eigen::Vector3d(0.01, 0, 0.04);
  m.command.local.jacobian = -300.0 * Eigen::Matrix3d::Identity();
  m.command.local.jacobian(0, 2) = 5;
  m.command.contact = true;
  m.command.events = 0x12;
  std::array<uint8_t, kMaxDatagram> buf;
  const size_t n =
      codec.EncodeForce(m, {kProtocolVersion, PayloadType::kForceFeedback, 5, 1}, auth, buf);
  ASSERT_GT(n, 0u);
  EXPECT_LE(n, 300u);
  Opened o;
  ASSERT_EQ(Open(std::span<const uint8_t>(buf.data(), n), &auth, o), DropReason::kNone);
  ForceMessage back;
  ASSERT_EQ(codec.DecodeForce(o.payload, back), DropReason::kNone);
  EXPECT_EQ(back.echo_sequence, 99u);
  EXPECT_EQ(back.command.local.jacobian, m.command.local.jacobian);
  EXPECT_EQ(back.command.force, m.command.force);
  EXPECT_TRUE(back.command.contact);
  EXPECT_EQ(back.command.events, 0x12u);
  EXPECT_EQ(back.command.local.kind, haptics::LocalModel::Kind::kLinear);
}

TEST(DatagramTest, ContactAndGraspModelsCrossWithTheirKindAndBadDirectionsAreRefused) {
  const Authenticator auth(Key(2));
  Codec codec;
  const auto round_trip = [&](const ForceMessage& m, ForceMessage& back) {
    return ForceRoundTrip(codec, auth, m, back);
  };
  ForceMessage contact;
  contact.command.local.kind = haptics::LocalModel::Kind::kContact;
  contact.command.local.normal = Eigen::Vector3d(0, 0.6, 0.8);
  ForceMessage back;
  ASSERT_EQ(round_trip(contact, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.kind, haptics::LocalModel::Kind::kContact);
  EXPECT_TRUE(back.command.local.normal.isApprox(contact.command.local.normal));
  EXPECT_EQ(back.command.local.tissue_stiffness, 0.0);  // none fitted: none sent
  // The tissue under the proxy crosses with a contact; a tissue the station cannot integrate
  // (negative, non-finite) is refused.
  contact.command.local.tissue_stiffness = 176.5;
  contact.command.local.tissue_damping = 13.25;
  contact.command.local.tissue_elastic0 = 0.625;
  ASSERT_EQ(round_trip(contact, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.tissue_stiffness, 176.5);
  EXPECT_EQ(back.command.local.tissue_damping, 13.25);
  EXPECT_EQ(back.command.local.tissue_elastic0, 0.625);
  for (const auto& bad :
       {std::array<double, 3>{-1.0, 13.0, 0.5}, std::array<double, 3>{176.0, -0.1, 0.5},
        std::array<double, 3>{NAN, 13.0, 0.5}, std::array<double, 3>{176.0, 13.0, INFINITY}}) {
    ForceMessage b = contact;
    b.command.local.tissue_stiffness = bad[0];
    b.command.local.tissue_damping = bad[1];
    b.command.local.tissue_elastic0 = bad[2];
    EXPECT_EQ(round_trip(b, back), DropReason::kBadPayload) << bad[0] << " " << bad[1];
  }
  // The proxy's damping ahead of contact crosses too; negative or non-finite is refused.
  contact.command.local.contact_damping = 1.5;
  ASSERT_EQ(round_trip(contact, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.contact_damping, 1.5);
  for (double bad : {-0.5, double(NAN), double(INFINITY)}) {
    ForceMessage b = contact;
    b.command.local.contact_damping = bad;
    EXPECT_EQ(round_trip(b, back), DropReason::kBadPayload) << bad;
  }
  contact.command.local.contact_damping = 0;
  ForceMessage grasp;
  grasp.command.local.kind = haptics::LocalModel::Kind::kGrasp;
  grasp.command.local.axis = Eigen::Vector3d(0, 0, 2);  // normalised on arrival
  grasp.command.local.orientation0 =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()));
  grasp.command.local.dforce_dtwist = Eigen::Vector3d(0.1, -8, 0);
  ASSERT_EQ(round_trip(grasp, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.kind, haptics::LocalModel::Kind::kGrasp);
  EXPECT_TRUE(back.command.local.axis.isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(back.command.local.orientation0.isApprox(grasp.command.local.orientation0));
  EXPECT_EQ(back.command.local.dforce_dtwist, grasp.command.local.dforce_dtwist);
  EXPECT_FALSE(back.command.local.has_twist_model);  // an older server's grasp: the tangent alone
  // The exact grasp model crosses whole (its torque steps as floats) and is refused when partial
  // or not finite.
  ForceMessage exact = grasp;
  haptics::LocalModel& m = exact.command.local;
  m.has_twist_model = true;
  for (int i = 0; i < haptics::LocalModel::kTwistSamples; ++i)
    m.torque_steps[i] = 0.25 * haptics::LocalModel::kTwistOffsets[i];
  m.force_per_torque = Eigen::Vector3d(0, -200, 0);
  m.arm = Eigen::Vector3d(0.03, 0, 0);
  m.torque0 = 1.5;
  ASSERT_EQ(round_trip(exact, back), DropReason::kNone);
  EXPECT_TRUE(back.command.local.has_twist_model);
  for (int i = 0; i < haptics::LocalModel::kTwistSamples; ++i)
    EXPECT_NEAR(back.command.local.torque_steps[i], m.torque_steps[i], 1e-7) << i;
  EXPECT_EQ(back.command.local.force_per_torque, m.force_per_torque);
  EXPECT_EQ(back.command.local.arm, m.arm);
  EXPECT_EQ(back.command.local.torque0, 1.5);
  for (int bad = 0; bad < 3; ++bad) {
    ForceMessage b = exact;
    if (bad == 0) b.command.local.torque_steps[3] = NAN;
    if (bad == 1) b.command.local.arm.z() = INFINITY;
    if (bad == 2) b.command.local.torque0 = NAN;
    EXPECT_EQ(round_trip(b, back), DropReason::kBadPayload) << bad;
  }
  // A contact without a usable normal, a grasp without an axis or orientation: never rendered.
  contact.command.local.normal = Eigen::Vector3d::Zero();
  EXPECT_EQ(round_trip(contact, back), DropReason::kBadPayload);
  grasp.command.local.orientation0.coeffs().setZero();
  EXPECT_EQ(round_trip(grasp, back), DropReason::kBadPayload);
  grasp.command.local.orientation0 = Eigen::Quaterniond::Identity();
  grasp.command.local.dforce_dtwist.x() = NAN;
  EXPECT_EQ(round_trip(grasp, back), DropReason::kBadPayload);
}

TEST(DatagramTest, ANeedlesStateCrossesWholeAndIsRefusedWhenAStationCouldNotRenderIt) {
  const Authenticator auth(Key(4));
  Codec codec;
  ForceMessage m, back;
  haptics::NeedleState& n = m.command.local.needle;
  m.command.local.kind = haptics::LocalModel::Kind::kNeedle;
  n.phase = haptics::NeedleState::Phase::kInserted;
  n.tract = 2, n.begun = 3, n.passed = 4;
  n.entry = Eigen::Vector3d(0.001, -0.002, 0.05);
  n.direction = Eigen::Vector3d(0, 0.6, -1.6);  // normalised on arrival
  n.cut = 0.019, n.anchor = 0.0185, n.last_depth = 0.0191, n.velocity = 0.008;
  ASSERT_EQ(ForceRoundTrip(codec, auth, m, back), DropReason::kNone);
  const haptics::NeedleState& b = back.command.local.needle;
  EXPECT_EQ(back.command.local.kind, haptics::LocalModel::Kind::kNeedle);
  EXPECT_EQ(b.phase, n.phase);
  EXPECT_EQ(b.tract, 2u);
  EXPECT_EQ(b.begun, 3u);
  EXPECT_EQ(b.passed, 4u);
  EXPECT_EQ(b.entry, n.entry);
  EXPECT_TRUE(b.direction.isApprox(n.direction.normalized()));
  EXPECT_EQ(b.cut, 0.019);
  EXPECT_EQ(b.anchor, 0.0185);
  // Another kind carries no needle: what a previous answer left is not kept.
  ForceMessage linear;
  ASSERT_EQ(ForceRoundTrip(codec, auth, linear, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.needle, haptics::NeedleState{});
  for (int bad = 0; bad < 3; ++bad) {
    ForceMessage x = m;
    if (bad == 0) x.command.local.needle.direction.setZero();
    if (bad == 1) x.command.local.needle.cut = NAN;
    if (bad == 2) x.command.local.needle.entry.y() = INFINITY;
    EXPECT_EQ(ForceRoundTrip(codec, auth, x, back), DropReason::kBadPayload) << bad;
  }
}

TEST(DatagramTest, TheServersPortEnergiesCrossAndAreRefusedWhenNotEnergies) {
  // The network passivity control gives the hand no more than released_j: a value that is not
  // an energy (negative, NaN, infinite) must never reach it.
  const Authenticator auth(Key(3));
  Codec codec;
  const auto round_trip = [&](const ForceMessage& m, ForceMessage& back) {
    return ForceRoundTrip(codec, auth, m, back);
  };
  ForceMessage m, back;
  m.command.released_j = 0.0123;
  m.command.absorbed_j = 0.0456;
  ASSERT_EQ(round_trip(m, back), DropReason::kNone);
  EXPECT_EQ(back.command.released_j, 0.0123);
  EXPECT_EQ(back.command.absorbed_j, 0.0456);
  for (const double bad : {-1e-6, double(NAN), double(INFINITY)}) {
    m.command.released_j = bad;
    EXPECT_EQ(round_trip(m, back), DropReason::kBadPayload) << bad;
    m.command.released_j = 0;
    m.command.absorbed_j = bad;
    EXPECT_EQ(round_trip(m, back), DropReason::kBadPayload) << bad;
    m.command.absorbed_j = 0;
  }
}

// A shared tool's coupling (four-handed training) crosses as the station must evaluate it, and
// an answer that stops carrying it leaves nothing of it behind; a gain outside [0, 1] or a
// target that is not finite is refused.
TEST(DatagramTest, ASharedToolsCouplingCrossesAndIsRefusedWhenNotOne) {
  const Authenticator auth(Key(4));
  Codec codec;
  ForceMessage m, back;
  m.command.shared = true;
  m.command.local.pull_target = Eigen::Vector3d(0.01, -0.02, 0.03);
  m.command.local.pull_gain = 0.75;
  ASSERT_EQ(ForceRoundTrip(codec, auth, m, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.pull_target, m.command.local.pull_target);
  EXPECT_EQ(back.command.local.pull_gain, 0.75);
  ForceMessage plain;
  ASSERT_EQ(ForceRoundTrip(codec, auth, plain, back), DropReason::kNone);
  EXPECT_EQ(back.command.local.pull_gain, 0);
  EXPECT_TRUE(back.command.local.pull_target.isZero(0));
  // (The encoder sends a gain only when it is > 0: a negative or NaN one crosses as none.)
  for (const double bad : {1.5, double(INFINITY)}) {
    ForceMessage b = m;
    b.command.local.pull_gain = bad;
    EXPECT_EQ(ForceRoundTrip(codec, auth, b, back), DropReason::kBadPayload) << bad;
  }
  ForceMessage far = m;
  far.command.local.pull_target.x() = INFINITY;
  EXPECT_EQ(ForceRoundTrip(codec, auth, far, back), DropReason::kBadPayload);
}

TEST(DatagramTest, WrongKeyEveryFlippedByteTruncationAndOversizeAreRejected) {
  const Authenticator auth(Key(3)), other(Key(4));
  Codec codec;
  std::array<uint8_t, kMaxDatagram> buf;
  const size_t n =
      codec.EncodeStylus(Stylus(), {kProtocolVersion, PayloadType::kStylusState, 1, 1}, auth, buf);
  Opened o;
  EXPECT_EQ(Open(std::span<const uint8_t>(buf.data(), n), &other, o), DropReason::kBadTag);
  EXPECT_EQ(Open(std::span<const uint8_t>(buf.data(), n), nullptr, o), DropReason::kUnknownSession);
  for (size_t i = 0; i < n; ++i) {
    for (uint8_t bit : {0x01, 0x80}) {
      std::array<uint8_t, kMaxDatagram> bad = buf;
      bad[i] ^= bit;
      EXPECT_NE(Open(std::span<const uint8_t>(bad.data(), n), &auth, o), DropReason::kNone)
          << "byte " << i;
    }
  }
  for (size_t cut = 0; cut < n; ++cut) {
    EXPECT_NE(Open(std::span<const uint8_t>(buf.data(), cut), &auth, o), DropReason::kNone) << cut;
  }
  std::vector<uint8_t> big(kMaxDatagram + 1, 0);
  EXPECT_EQ(Open(big, &auth, o), DropReason::kTooLong);
  std::array<uint8_t, kMaxPayload + 1> huge{};
  EXPECT_EQ(Seal({}, huge, auth, buf), 0u);
}

TEST(DatagramTest, RandomGarbageNeverOpensAndNeverCrashes) {
  const Authenticator auth(Key(5));
  std::mt19937_64 rng(17);
  std::uniform_int_distribution<int> len(0, 1300), byte(0, 255);
  Opened o;
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> d(len(rng));
    for (auto& b : d) b = static_cast<uint8_t>(byte(rng));
    if (i % 3 == 0 && d.size() >= 4) d[0] = 'V', d[1] = 'S', d[2] = kProtocolVersion, d[3] = 1;
    ASSERT_NE(Open(d, &auth, o), DropReason::kNone);
  }
}

TEST(DatagramTest, AuthenticGarbagePayloadAndNonFiniteForcesAreBadPayload) {
  const Authenticator auth(Key(6));
  Codec codec;
  std::array<uint8_t, kMaxDatagram> buf;
  const uint8_t junk[] = {0xff, 0xff, 0xff, 0xff, 0xff};
  const size_t n = Seal({kProtocolVersion, PayloadType::kForceFeedback, 1, 1}, junk, auth, buf);
  Opened o;
  ASSERT_EQ(Open(std::span<const uint8_t>(buf.data(), n), &auth, o), DropReason::kNone);
  ForceMessage f;
  EXPECT_EQ(codec.DecodeForce(o.payload, f), DropReason::kBadPayload);
  ForceMessage nan_force;
  nan_force.command.force.x() = NAN;
  const size_t m = codec.EncodeForce(
      nan_force, {kProtocolVersion, PayloadType::kForceFeedback, 1, 2}, auth, buf);
  ASSERT_EQ(Open(std::span<const uint8_t>(buf.data(), m), &auth, o), DropReason::kNone);
  EXPECT_EQ(codec.DecodeForce(o.payload, f), DropReason::kBadPayload);  // never rendered
}

TEST(DatagramTest, SceneFramesAreChunkedToFitAndRoundTripToTheMicrometre) {
  const Authenticator auth(Key(7));
  Codec codec;
  std::vector<int32_t> indices;
  std::vector<Eigen::Vector3d> positions;
  for (int i = 0; i < 4921; ++i) {  // the arm's moved vertices at 2.07 N·m
    indices.push_back(i * 1 + 3);
    positions.emplace_back(0.03 * std::cos(i * 0.1), 0.03 * std::sin(i * 0.1), 0.25 * i / 4921.0);
  }
  std::array<uint8_t, kMaxDatagram> buf;
  std::vector<SceneChunk> chunks;
  const size_t count = codec.EncodeSceneFrame(
      {42, indices, positions}, {kProtocolVersion, PayloadType::kSceneFrame, 3, 100}, auth, buf,
      [&](std::span<const uint8_t> d) {
        ASSERT_LE(d.size(), kMaxDatagram);
        Opened o;
        ASSERT_EQ(Open(d, &auth, o), DropReason::kNone);
        EXPECT_EQ(o.header.type, PayloadType::kSceneFrame);
        SceneChunk c;
        ASSERT_EQ(codec.DecodeSceneChunk(o.payload, c), DropReason::kNone);
        chunks.push_back(c);
      });
  ASSERT_GT(count, 1u);
  ASSERT_EQ(chunks.size(), count);
  // Tightly packed and delta-coded: neighbours 3 mm apart take 2 bytes a coordinate and an index
  // a byte, so more than 150 vertices a datagram (absolute coordinates, 3 bytes each, fit ~100).
  EXPECT_LT(count, 4921u / 150);
  size_t k = 0;
  for (const SceneChunk& c : chunks) {
    EXPECT_EQ(c.frame_id, 42u);
    EXPECT_EQ(c.chunk_count, count);
    for (size_t i = 0; i < c.indices.size(); ++i, ++k) {
      EXPECT_EQ(c.indices[i], indices[k]);
      EXPECT_LE((c.positions[i] - positions[k]).cwiseAbs().maxCoeff(), 0.5e-6);
    }
  }
  EXPECT_EQ(k, indices.size());
  std::vector<Eigen::Vector3d> bad = {Eigen::Vector3d(NAN, 0, 0)};
  std::vector<int32_t> one = {0};
  EXPECT_EQ(codec.EncodeSceneFrame({1, one, bad}, {}, auth, buf, [](auto) {}), 0u);
  // The ±1 km the deltas' sint32 allows: the far ends of it round-trip, beyond it is refused.
  std::vector<int32_t> two = {0, 0x7fffffff};
  std::vector<Eigen::Vector3d> far = {Eigen::Vector3d(-1000, 1000, -1000),
                                      Eigen::Vector3d(1000, -1000, 1000)};
  std::vector<SceneChunk> got;
  ASSERT_EQ(codec.EncodeSceneFrame(
                {2, two, far}, {kProtocolVersion, PayloadType::kSceneFrame, 3, 1}, auth, buf,
                [&](std::span<const uint8_t> d) {
                  Opened o;
                  ASSERT_EQ(Open(d, &auth, o), DropReason::kNone);
                  SceneChunk c;
                  ASSERT_EQ(codec.DecodeSceneChunk(o.payload, c), DropReason::kNone);
                  got.push_back(c);
                }),
            1u);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].indices, two);
  EXPECT_EQ(got[0].positions[0], far[0]);
  EXPECT_EQ(got[0].positions[1], far[1]);
  far[1].x() = 1000.001;
  EXPECT_EQ(codec.EncodeSceneFrame({2, two, far}, {}, auth, buf, [](auto) {}), 0u);
}

TEST(DatagramTest, ACutsFacesRoundTripInChunksThatStandAlone) {
  const Authenticator auth(Key(7));
  Codec codec;
  std::vector<int32_t> faces;
  std::vector<std::array<int, 3>> corners;
  for (int f = 0; f < 300; ++f) {  // a freed piece's removed faces and the cut's re-pointed ones
    faces.push_back(40 + 3 * f);
    corners.push_back(f % 2 ? std::array<int, 3>{0, 0, 0}
                            : std::array<int, 3>{700 + f, 20 + f, (1 << 24) - f});
  }
  std::array<uint8_t, kMaxDatagram> buf;
  std::vector<SceneChunk> chunks;
  const size_t count = codec.EncodeTopologyFrame(
      {9, 17, faces, corners}, {kProtocolVersion, PayloadType::kSceneFrame, 3, 1}, auth, buf,
      [&](std::span<const uint8_t> d) {
        ASSERT_LE(d.size(), kMaxDatagram);
        Opened o;
        ASSERT_EQ(Open(d, &auth, o), DropReason::kNone);
        SceneChunk c;
        ASSERT_EQ(codec.DecodeSceneChunk(o.payload, c), DropReason::kNone);
        chunks.push_back(c);
      });
  ASSERT_EQ(count, (300 + Codec::kTopologyChunkFaces - 1) / Codec::kTopologyChunkFaces);
  size_t k = 0;
  for (const SceneChunk& c : chunks) {
    EXPECT_EQ(c.topology, 17u);
    EXPECT_TRUE(c.indices.empty());
    EXPECT_FALSE(c.twist.has_value());
    for (size_t i = 0; i < c.face_indices.size(); ++i, ++k) {
      EXPECT_EQ(c.face_indices[i], faces[k]);
      EXPECT_EQ(c.faces[i][0], corners[k][0]);
      EXPECT_EQ(c.faces[i][2], corners[k][2]);
    }
  }
  EXPECT_EQ(k, faces.size());
  // Out of range either way: refused, never sent.
  std::vector<int32_t> one = {1};
  std::vector<std::array<int, 3>> negative = {{0, -1, 2}}, past = {{0, 1, (1 << 24) + 1}};
  EXPECT_EQ(codec.EncodeTopologyFrame({1, 1, one, negative}, {}, auth, buf, [](auto) {}), 0u);
  EXPECT_EQ(codec.EncodeTopologyFrame({1, 1, one, past}, {}, auth, buf, [](auto) {}), 0u);
  EXPECT_EQ(codec.EncodeTopologyFrame({1, 0, one, corners}, {}, auth, buf, [](auto) {}), 0u);
}

// A SceneFrame payload written by hand (protobuf's wire format): varint fields, packed fields of
// unsigned or zigzag varints, 64-bit fields and embedded messages.
struct FrameBytes {
  std::vector<uint8_t> bytes;
  FrameBytes& Fixed64(int number, uint64_t v) {
    Varint(bytes, (static_cast<uint64_t>(number) << 3) | 1);
    for (int k = 0; k < 8; ++k) bytes.push_back(static_cast<uint8_t>(v >> (8 * k)));
    return *this;
  }
  FrameBytes& Double(int number, double v) { return Fixed64(number, std::bit_cast<uint64_t>(v)); }
  FrameBytes& Bytes(int number, const std::vector<uint8_t>& body) {
    Varint(bytes, (static_cast<uint64_t>(number) << 3) | 2);
    Varint(bytes, body.size());
    bytes.insert(bytes.end(), body.begin(), body.end());
    return *this;
  }
  static void Varint(std::vector<uint8_t>& out, uint64_t v) {
    for (; v >= 0x80; v >>= 7) out.push_back(static_cast<uint8_t>(v | 0x80));
    out.push_back(static_cast<uint8_t>(v));
  }
  FrameBytes& Field(int number, uint64_t v) {
    Varint(bytes, static_cast<uint64_t>(number) << 3);
    Varint(bytes, v);
    return *this;
  }
  FrameBytes& Packed(int number, const std::vector<int64_t>& values, bool zigzag) {
    std::vector<uint8_t> body;
    for (int64_t v : values)
      Varint(body, zigzag ? (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63)
                          : static_cast<uint64_t>(v));
    Varint(bytes, (static_cast<uint64_t>(number) << 3) | 2);
    Varint(bytes, body.size());
    bytes.insert(bytes.end(), body.begin(), body.end());
    return *this;
  }
};

// A chunk in the absolute coding (what servers before the deltas sent) still decodes; a chunk
// that mixes the codings, whose deltas lead an index below zero or a coordinate past ±1 km, or
// whose counts disagree is refused, never turned into a vertex.
TEST(DatagramTest, SceneChunksDecodeEitherCodingAndRefuseWhatNoEncoderWrites) {
  Codec codec;
  SceneChunk c;
  const auto header = [] { return FrameBytes().Field(1, 9).Field(2, 0).Field(3, 1); };
  FrameBytes absolute = header();
  absolute.Packed(4, {5, 7}, false).Packed(5, {1, -2, 3, 40, 50, -60}, true);
  ASSERT_EQ(codec.DecodeSceneChunk(absolute.bytes, c), DropReason::kNone);
  EXPECT_EQ(c.indices, (std::vector<int32_t>{5, 7}));
  EXPECT_EQ(c.positions[1], Eigen::Vector3d(40e-6, 50e-6, -60e-6));
  FrameBytes delta = header();
  delta.Packed(6, {5, 2}, true).Packed(7, {1, -2, 3, 39, 52, -63}, true);
  ASSERT_EQ(codec.DecodeSceneChunk(delta.bytes, c), DropReason::kNone);
  EXPECT_EQ(c.indices, (std::vector<int32_t>{5, 7}));
  EXPECT_EQ(c.positions[1], Eigen::Vector3d(40e-6, 50e-6, -60e-6));
  FrameBytes mixed = header();
  mixed.Packed(4, {5}, false).Packed(5, {1, 2, 3}, true);
  mixed.Packed(6, {5}, true).Packed(7, {1, 2, 3}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(mixed.bytes, c), DropReason::kBadPayload);
  FrameBytes below = header();
  below.Packed(6, {5, -6}, true).Packed(7, {0, 0, 0, 0, 0, 0}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(below.bytes, c), DropReason::kBadPayload);
  FrameBytes beyond = header();
  const int64_t max = 2'147'483'647;
  beyond.Packed(6, {0, 1}, true).Packed(7, {max, 0, 0, max, 0, 0}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(beyond.bytes, c), DropReason::kBadPayload);
  FrameBytes short_positions = header();
  short_positions.Packed(6, {1, 1}, true).Packed(7, {0, 0, 0, 0, 0}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(short_positions.bytes, c), DropReason::kBadPayload);
  // A cut's faces: a face index or corner led below zero, a corner short, faces beside vertices,
  // or faces without a topology: refused.
  FrameBytes faces = header();
  faces.Field(9, 3).Packed(10, {4, 1}, true).Packed(11, {7, 1, 1, 0, 0, 0}, true);
  ASSERT_EQ(codec.DecodeSceneChunk(faces.bytes, c), DropReason::kNone);
  EXPECT_EQ(c.face_indices, (std::vector<int32_t>{4, 5}));
  EXPECT_EQ(c.faces[1], (std::array<int32_t, 3>{9, 9, 9}));
  FrameBytes face_below = header();
  face_below.Field(9, 3).Packed(10, {4, -5}, true).Packed(11, {7, 1, 1, 0, 0, 0}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(face_below.bytes, c), DropReason::kBadPayload);
  FrameBytes corner_below = header();
  corner_below.Field(9, 3).Packed(10, {4}, true).Packed(11, {7, -8, 1}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(corner_below.bytes, c), DropReason::kBadPayload);
  FrameBytes corner_short = header();
  corner_short.Field(9, 3).Packed(10, {4}, true).Packed(11, {7, 1}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(corner_short.bytes, c), DropReason::kBadPayload);
  FrameBytes with_vertices = header();
  with_vertices.Field(9, 3).Packed(10, {4}, true).Packed(11, {7, 1, 1}, true);
  with_vertices.Packed(6, {5}, true).Packed(7, {1, 2, 3}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(with_vertices.bytes, c), DropReason::kBadPayload);
  FrameBytes no_topology = header();
  no_topology.Packed(10, {4}, true).Packed(11, {7, 1, 1}, true);
  EXPECT_EQ(codec.DecodeSceneChunk(no_topology.bytes, c), DropReason::kBadPayload);
}

// A coil limb's twist is one sealed chunk of its four numbers, read back exactly; a vertex chunk
// read after it has no twist. A twist that is not finite is not sent, and one that comes with
// vertices, or as one chunk of several, is refused.
TEST(DatagramTest, ACoilTwistFrameIsOneChunkOfItsNumbersAndNothingElse) {
  Codec codec;
  const Authenticator auth(Key(4));
  std::array<uint8_t, kMaxDatagram> out{};
  const CoilTwist twist{0x1234567890abcdefull, 7, 0.1234567890123, -0.0123456789};
  const Header h{kProtocolVersion, PayloadType::kSceneFrame, 9, 41};
  const size_t n = codec.EncodeTwistFrame(12, twist, h, auth, out);
  ASSERT_GT(n, 0u);
  EXPECT_LT(n, 100u) << "a limb's whole frame in a small datagram";
  Opened o;
  ASSERT_EQ(Open(std::span<const uint8_t>(out.data(), n), &auth, o), DropReason::kNone);
  EXPECT_EQ(o.header.type, PayloadType::kSceneFrame);
  EXPECT_EQ(o.header.sequence, 41u);
  SceneChunk c;
  ASSERT_EQ(codec.DecodeSceneChunk(o.payload, c), DropReason::kNone);
  ASSERT_TRUE(c.twist.has_value());
  EXPECT_EQ(c.frame_id, 12u);
  EXPECT_EQ(c.chunk_count, 1u);
  EXPECT_TRUE(c.indices.empty());
  EXPECT_EQ(c.twist->key, twist.key);
  EXPECT_EQ(c.twist->grasp, twist.grasp);
  EXPECT_EQ(c.twist->arc, twist.arc);
  EXPECT_EQ(c.twist->torque, twist.torque);

  FrameBytes vertices = FrameBytes().Field(1, 9).Field(2, 0).Field(3, 1);
  vertices.Packed(6, {5}, true).Packed(7, {1, 2, 3}, true);
  ASSERT_EQ(codec.DecodeSceneChunk(vertices.bytes, c), DropReason::kNone);
  EXPECT_FALSE(c.twist.has_value());

  for (const double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(codec.EncodeTwistFrame(12, {1, 7, bad, 0.01}, h, auth, out), 0u);
    EXPECT_EQ(codec.EncodeTwistFrame(12, {1, 7, 0.1, bad}, h, auth, out), 0u);
  }
  // Hand-made: the twist beside vertices, as chunk 0 of 2, with a NaN torque.
  const auto twist_field = [](double torque) {
    FrameBytes t;
    t.Field(1, 7).Fixed64(4, 1);
    t.Double(2, 0.1).Double(3, torque);
    return t.bytes;
  };
  FrameBytes with_vertices = FrameBytes().Field(1, 9).Field(2, 0).Field(3, 1);
  with_vertices.Packed(6, {5}, true).Packed(7, {1, 2, 3}, true).Bytes(8, twist_field(0.01));
  EXPECT_EQ(codec.DecodeSceneChunk(with_vertices.bytes, c), DropReason::kBadPayload);
  FrameBytes of_two = FrameBytes().Field(1, 9).Field(2, 0).Field(3, 2);
  of_two.Bytes(8, twist_field(0.01));
  EXPECT_EQ(codec.DecodeSceneChunk(of_two.bytes, c), DropReason::kBadPayload);
  FrameBytes nan_torque = FrameBytes().Field(1, 9).Field(2, 0).Field(3, 1);
  nan_torque.Bytes(8, twist_field(std::nan("")));
  EXPECT_EQ(codec.DecodeSceneChunk(nan_torque.bytes, c), DropReason::kBadPayload);
  FrameBytes whole = FrameBytes().Field(1, 9).Field(2, 0).Field(3, 1);
  whole.Bytes(8, twist_field(0.01));
  ASSERT_EQ(codec.DecodeSceneChunk(whole.bytes, c), DropReason::kNone);
  EXPECT_EQ(c.twist->torque, 0.01);
  EXPECT_EQ(c.twist->key, 1u);
}

}  // namespace
}  // namespace vsurg::wire
