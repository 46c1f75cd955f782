#include "client/net/station_channel.h"

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <mutex>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include <set>

#include "client/station/coil_twist_view.h"
#include "common/core/clock.h"
#include "common/geometry/mesh_generators.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "server/net/udp_endpoint.h"
#include "tests/net/udp_relay.h"
#include "tests/support/press_and_hold.h"
#include "tests/support/wait.h"

namespace vsurg::client {
namespace {

wire::SessionKey Key() {
  wire::SessionKey k;
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(3 * i + 1);
  return k;
}

using test::PressAndHold;

struct Server {
  std::unique_ptr<sim::Simulation> simulation;
  std::unique_ptr<server::UdpEndpoint> endpoint;
  Server() {
    simulation = *sim::Simulation::Create(*sim::LoadSceneByName("sphere-palpation-256"), {true});
    endpoint = *server::UdpEndpoint::Create({});
    endpoint->AddSession(11, Key(), simulation.get());
  }
};

StationOptions Options(uint16_t port) {
  StationOptions o;
  o.server_port = port;
  o.session = 11;
  o.key = Key();
  return o;
}

void WaitFor(const ReplayDevice& device) {
  test::Eventually(20, [&] { return device.finished(); });
}

TEST(StationChannelTest, RoundTripsOnLoopbackAndRendersTheTissueForce) {
  Server server;
  ReplayDevice device(PressAndHold(1.5));
  auto station = StationChannel::Create(Options(server.endpoint->port()), &device);
  ASSERT_TRUE(station.ok()) << station.error().message;
  WaitFor(device);
  const size_t before_stop = device.forces().size();
  (*station)->Stop();
  const StationStats s = (*station)->stats();
  EXPECT_GT(s.sent, 1000u);
  EXPECT_LT(s.loss, 0.02);  // loopback: none, bar the last datagrams in flight at Stop
  EXPECT_GT(s.rtt_p50_us, 0);
  // The loop's own count: one datagram per iteration (the last may be counted before its send),
  // and a run over a second long has whole seconds that bracket its mean rate.
  EXPECT_LE(s.loop_iterations, s.sent);
  EXPECT_GE(s.loop_iterations + 1, s.sent);
  EXPECT_GT(s.loop_seconds, 1.0);
  EXPECT_GT(s.loop_hz_min, 0.0);
  EXPECT_LE(s.loop_hz_min, s.loop_hz_max);
  EXPECT_NEAR(s.loop_hz, static_cast<double>(s.loop_iterations) / s.loop_seconds, 1e-9);
  const std::vector<Eigen::Vector3d> f = device.forces();
  ASSERT_GT(f.size(), 1000u);
  // Pushed back up out of the sphere (K·3 mm ≈ 0.9 N before it gives) until the end; Stop then
  // fades the device to zero force.
  EXPECT_GT(f[before_stop - 1].z(), 0.1);
  EXPECT_EQ(f.back(), Eigen::Vector3d::Zero());
  for (const auto& x : f) EXPECT_LE(x.norm(), 3.3 + 1e-9);
}

TEST(StationChannelTest, ABadNetworkKeepsForcesBoundedAndContinuous) {
  Server server;
  test::Impairment bad;
  bad.drop = 0.2;
  bad.duplicate = 0.1;
  bad.reorder = 0.1;
  bad.max_delay_ms = 5;
  test::UdpRelay relay(server.endpoint->port(), bad);
  ReplayDevice device(PressAndHold(2.0));
  auto station = StationChannel::Create(Options(relay.port()), &device);
  ASSERT_TRUE(station.ok());
  WaitFor(device);
  const size_t before_stop = device.forces().size();
  (*station)->Stop();
  const StationStats s = (*station)->stats();
  // 20% lost each way, and 0–5 ms jitter at 1 ms spacing reorders many: latest-wins drops those.
  EXPECT_GT(s.received, 0.2 * s.sent);
  EXPECT_GT(s.stale, 0u);  // duplicates and reordering reached the station and were dropped
  const std::vector<Eigen::Vector3d> f = device.forces();
  const double rate_step = device.limits().max_force_rate * 1e-3 * 1.0001;  // per 1 ms cycle
  for (size_t i = 1; i < f.size(); ++i) {
    ASSERT_LE(f[i].norm(), 3.3 + 1e-9);
    ASSERT_LE((f[i] - f[i - 1]).norm(), rate_step) << i;
  }
  EXPECT_GT(f[before_stop - 1].z(), 0.1);
  EXPECT_GT(server.endpoint->counters().Dropped(wire::DropReason::kStale), 0u);
}

// The mocked device (we have no hardware here) misbehaves: NaN and infinite positions and
// orientations, zero quaternions, teleports, leaving the workspace, grasp-button chatter, on top
// of a trainee's real trial. Through the real station channel and the real server endpoint over
// loopback, every force the device is asked to render stays finite, within its limit and its
// rate limit per 1 ms cycle, and the server keeps answering.
class AdversarialDevice : public HapticDevice {
 public:
  AdversarialDevice(std::vector<haptics::StylusSample> base, uint64_t seed, int cycles)
      : base_(std::move(base)), rng_(seed), cycles_(cycles) {}
  haptics::StylusSample Read() override {
    std::lock_guard lock(mutex_);
    haptics::StylusSample s = base_[std::min(i_, base_.size() - 1)];
    ++i_;
    s.position += offset_;
    if (chatter_ > 0) --chatter_, s.buttons = (chatter_ & 1) ? haptics::kButtonGrasp : 0u;
    const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
    // One cycle in 75 misbehaves. Each bad sample closes the server's start-up gate, which
    // opens again after 50 good ones, and while it is closed the local model carries no
    // stiffness either (a station extrapolates nothing the gate held back): a device that
    // misbehaved every 10th cycle would never be given a force at all, and the limits below
    // would be checked on zeros.
    switch (std::uniform_int_distribution<int>(0, 599)(rng_)) {
      case 0:
        s.position.x() = nan;
        break;
      case 1:
        s.position.z() = -inf;
        break;
      case 2:
        s.orientation.coeffs().setZero();
        break;
      case 3:
        s.orientation.coeffs().w() = nan;
        break;
      case 4:
        offset_ = Eigen::Vector3d::Random() * 0.05;  // a teleport that stays
        break;
      case 5:
        offset_.setZero();
        break;
      case 6:
        s.position = Eigen::Vector3d(3, 3, 3);  // far outside the workspace
        break;
      case 7:
        chatter_ = 30;
        break;
      default:
        break;
    }
    return s;
  }
  void WriteForce(const Eigen::Vector3d& f) override {
    std::lock_guard lock(mutex_);
    forces_.push_back(f);
  }
  haptics::DeviceLimits limits() const override { return haptics::TouchLimits(); }
  bool finished() const {
    std::lock_guard lock(mutex_);
    return i_ >= static_cast<size_t>(cycles_);
  }
  std::vector<Eigen::Vector3d> forces() const {
    std::lock_guard lock(mutex_);
    return forces_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<haptics::StylusSample> base_;
  std::mt19937_64 rng_;
  int cycles_;
  size_t i_ = 0;
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();
  int chatter_ = 0;
  std::vector<Eigen::Vector3d> forces_;
};

TEST(StationChannelTest, AMisbehavingDeviceNeverGetsAForceBeyondItsLimits) {
  for (const char* name : {"sphere-palpation-256", "arm-torsion"}) {
    SCOPED_TRACE(name);
    auto scene = sim::LoadSceneByName(name);
    ASSERT_TRUE(scene.ok());
    auto base = sim::ScriptedTrainee(*scene, sim::TraineeStyle::kGood);
    ASSERT_TRUE(base.ok());
    auto simulation = *sim::Simulation::Create(*scene, {true});
    auto endpoint = *server::UdpEndpoint::Create({});
    endpoint->AddSession(11, Key(), simulation.get());
    AdversarialDevice device(*base, 17, 3000);
    auto station = StationChannel::Create(Options(endpoint->port()), &device);
    ASSERT_TRUE(station.ok());
    EXPECT_TRUE(test::Eventually(30, [&] { return device.finished(); }));
    (*station)->Stop();
    const StationStats stats = (*station)->stats();
    endpoint->RemoveSession(11);
    const std::vector<Eigen::Vector3d> f = device.forces();
    ASSERT_GT(f.size(), 2000u);
    const haptics::DeviceLimits limits = device.limits();
    const double rate_step = limits.max_force_rate * 1e-3 * 1.0001;  // per 1 ms cycle
    double strongest = 0;
    for (size_t i = 0; i < f.size(); ++i) {
      ASSERT_TRUE(f[i].allFinite()) << i;
      ASSERT_LE(f[i].norm(), limits.max_force + 1e-9) << i;
      // The last write is Stop's zero: the hand is not left holding a force (by design).
      if (i > 0 && i + 1 < f.size()) {
        ASSERT_LE((f[i] - f[i - 1]).norm(), rate_step) << i;
      }
      strongest = std::max(strongest, f[i].norm());
    }
    EXPECT_GT(strongest, 0.05) << "the trial did reach the tissue";
    EXPECT_GT(stats.received, 0.9 * stats.sent) << "the server kept answering";
    EXPECT_GT(endpoint->counters().answered, 2000u);
  }
}

// Polls until the device has been written `n` more times (the loop's progress, whatever the
// scheduler makes of 1 kHz), or fails after a generous deadline.
void WaitForWrites(const ReplayDevice& device, size_t n) {
  const size_t target = device.forces().size() + n;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (device.forces().size() < target && std::chrono::steady_clock::now() < deadline)
    std::this_thread::yield();
  ASSERT_GE(device.forces().size(), target) << "the device loop stopped";
}

// A contact's model is held through a silence (model_hold_s), then the watchdog fades it; the
// server's force alone (no model) fades 20 ms into the same silence.
TEST(StationChannelTest, TheWatchdogHoldsAContactsModelThenFadesItWhenTheServerGoesQuiet) {
  for (const bool model : {true, false}) {
    SCOPED_TRACE(model ? "the contact's model, held 0.3 s" : "the server's force alone");
    Server server;
    test::UdpRelay relay(server.endpoint->port(), {});
    ReplayDevice device(PressAndHold(3.0));
    ManualClock clock;  // the station's: the watchdog and the fade read it
    StationOptions o = Options(relay.port());
    o.clock = &clock;
    o.model_hold_s = 0.3;
    if (!model) o.rendering = LocalRendering::kServerForce;
    const double patience = model ? 0.3 : 0.020;
    auto station = StationChannel::Create(o, &device);
    ASSERT_TRUE(station.ok());
    WaitForWrites(device, 1200);                    // pressed in, and the start-up ramp done
    ASSERT_GT(device.forces().back().norm(), 0.1);  // steady contact
    relay.SetBlackhole(true);
    WaitForWrites(device, 20);  // answers in flight have landed
    const double steady = device.forces().back().norm();
    ASSERT_GT(steady, 0.1) << "silence alone, with no time passing, is no fade";
    // 45 ms of silence: the server's force is halfway through its fade; the model is still held
    // whole (the replayed hand holds still, so the model gives the force it gave).
    clock.Advance(0.045);
    WaitForWrites(device, 5);
    const double at_45ms = device.forces().back().norm();
    if (model) {
      EXPECT_NEAR(at_45ms, steady, 0.02 * steady);
      EXPECT_EQ((*station)->stats().watchdog_fades, 0u);
      clock.Advance(patience + 0.025 - 0.045);  // halfway through the fade after the hold
      WaitForWrites(device, 5);
    }
    const double half = device.forces().back().norm();
    EXPECT_GT(half, 0.3 * steady);
    EXPECT_LT(half, 0.7 * steady);
    // Past the fade: zero on every cycle, once the safety filter's rate limit (1 N per 1 ms
    // cycle) has brought it down.
    clock.Advance(0.030);
    WaitForWrites(device, 5);
    const size_t from = device.forces().size();
    WaitForWrites(device, 50);
    const std::vector<Eigen::Vector3d> f = device.forces();
    for (size_t i = from; i < f.size(); ++i) EXPECT_EQ(f[i].norm(), 0.0) << i - from;
    EXPECT_EQ((*station)->stats().watchdog_fades, 1u);
    // The server answers again: the station picks up (UDP needs no reconnect handshake); the
    // safety filter's ramp brings the force back over some cycles.
    relay.SetBlackhole(false);
    WaitForWrites(device, 600);
    EXPECT_GT(device.forces().back().norm(), 0.1);
    (*station)->Stop();
  }
}

// Stop fades a held force out over fade_s instead of cutting it; a stop while the server answers
// is no fade for want of answers, one while it is silent (a held model) is.
TEST(StationChannelTest, StopFadesTheForceOutInsteadOfCuttingIt) {
  for (const bool silent : {false, true}) {
    SCOPED_TRACE(silent ? "stopped while the server is silent" : "stopped while it answers");
    Server server;
    test::UdpRelay relay(server.endpoint->port(), {});
    ReplayDevice device(PressAndHold(3.0));
    ManualClock clock;
    StationOptions o = Options(relay.port());
    o.clock = &clock;
    auto station = StationChannel::Create(o, &device);
    ASSERT_TRUE(station.ok());
    WaitForWrites(device, 1200);
    if (silent) {
      relay.SetBlackhole(true);
      WaitForWrites(device, 20);
      clock.Advance(0.1);  // past the watchdog's 20 ms, within the model's hold
      WaitForWrites(device, 5);
    }
    const size_t before = device.forces().size();
    const double held = device.forces().back().norm();
    ASSERT_GT(held, 0.1);
    (*station)->Stop();
    const std::vector<Eigen::Vector3d> f = device.forces();
    // fade_s (50 ms) of the servo's cycles, each step a fiftieth of the force or so.
    ASSERT_GE(f.size(), before + 45);
    for (size_t i = before; i < f.size(); ++i)
      EXPECT_LE((f[i] - f[i - 1]).norm(), 0.05 * held) << i - before;
    EXPECT_EQ(f.back().norm(), 0.0);
    EXPECT_EQ((*station)->stats().watchdog_fades, silent ? 1u : 0u);
  }
}

// The arm twisted to 45° by a scripted trainee, its frames collected by a station that says it
// holds the arm's coil limb (`key`, or 0 for none) until `done` says they show enough or 10 s
// pass (how soon depends on how fast this machine deforms: a liveness bound, not a timing one).
struct TwistedArm {
  std::unique_ptr<sim::Simulation> simulation;
  std::unique_ptr<server::UdpEndpoint> endpoint;
  std::vector<wire::SceneChunk> chunks;
  StationStats stats;

  TwistedArm(uint64_t key,
             const std::function<bool(const wire::SceneChunk&, sim::Simulation&)>& done) {
    auto scene = sim::LoadSceneByName("arm-torsion");
    simulation = *sim::Simulation::Create(*scene, {true});
    endpoint = *server::UdpEndpoint::Create({});
    endpoint->AddSession(11, Key(), simulation.get());
    auto trajectory = *sim::ScriptedTrainee(*scene, sim::TraineeStyle::kGood);
    trajectory.resize(3000);  // approach, grasp and twist to 45°
    ReplayDevice device(trajectory);
    StationOptions o = Options(endpoint->port());
    o.twist_shape_key = key;
    auto station = StationChannel::Create(o, &device);
    EXPECT_TRUE(station.ok());
    if (!station.ok()) return;
    WaitFor(device);
    bool finished = false;
    for (auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
         !finished && std::chrono::steady_clock::now() < until;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      for (auto& c : (*station)->TakeSceneChunks()) {
        finished = finished || done(c, *simulation);
        chunks.push_back(std::move(c));
      }
    }
    (*station)->Stop();
    stats = (*station)->stats();
  }
  std::string Why() const {
    return "frames sent " + std::to_string(endpoint->counters().frames) + ", chunks " +
           std::to_string(chunks.size()) + ", dropped " + std::to_string(stats.dropped) +
           ", deformation updates " + std::to_string(simulation->deformation_updates());
  }
};

// A station holding the same arm is sent each frame as the twist that made it, one small chunk,
// and remakes from it the surface the server shows, to the last bit; a twist about the limb's
// axis, every vertex at its own height and distance from the axis.
TEST(StationChannelTest, AStationWithTheArmRemakesItsTwistFromThreeNumbers) {
  auto scene = sim::LoadSceneByName("arm-torsion");
  auto mesh = sim::BuildSceneMesh(scene->mesh);
  ASSERT_TRUE(mesh.ok());
  auto view = CoilTwistView::For(*scene, *mesh);
  ASSERT_TRUE(view.has_value());
  std::vector<int32_t> indices, shown_indices;
  std::vector<Eigen::Vector3d> remade, shown;
  TwistedArm arm(view->key(), [&](const wire::SceneChunk& c, sim::Simulation& server) {
    // Done when the station has the frame the server shows now (the hand holds still).
    return c.twist && c.frame_id == server.ShownSurface(shown_indices, shown);
  });
  ASSERT_FALSE(arm.chunks.empty()) << arm.Why();
  for (const auto& c : arm.chunks) {
    ASSERT_TRUE(c.twist.has_value()) << "a vertex chunk for a station holding the arm";
    EXPECT_EQ(c.chunk_count, 1u);
  }
  EXPECT_EQ(arm.endpoint->counters().frame_chunks, arm.endpoint->counters().frames);
  // The last frame remade, beside the surface the server shows.
  const wire::CoilTwist& last = *arm.chunks.back().twist;
  EXPECT_GT(std::abs(last.torque), 0.0);
  ASSERT_TRUE(view->Shape(last, indices, remade));
  arm.simulation->ShownSurface(shown_indices, shown);
  const auto& rest = mesh->surface.positions;
  ASSERT_EQ(remade.size(), rest.size());
  std::vector<Eigen::Vector3d> server_surface = rest;
  for (size_t i = 0; i < shown_indices.size(); ++i) server_surface[shown_indices[i]] = shown[i];
  size_t moved = 0;
  for (size_t i = 0; i < rest.size(); ++i) {
    ASSERT_LE((remade[i] - server_surface[i]).norm(), 1e-6) << i;  // ShownSurface's own µm
    EXPECT_NEAR(remade[i].z(), rest[i].z(), 1e-9);
    EXPECT_NEAR(std::hypot(remade[i].x(), remade[i].y()), std::hypot(rest[i].x(), rest[i].y()),
                1e-9);
    if ((remade[i] - rest[i]).norm() > 1e-6) ++moved;
  }
  EXPECT_GT(moved, 1000u) << arm.Why();
  EXPECT_LT(moved, rest.size());  // the elbow end never moves
  // A twist of another limb (another key) shapes nothing.
  wire::CoilTwist other = last;
  other.key ^= 1;
  EXPECT_FALSE(view->Shape(other, indices, remade));
}

// A station that holds no coil limb (or says so with no key) is sent the moved vertices.
TEST(StationChannelTest, SceneFramesCarryTheTwistedVerticesToAStationWithoutTheArm) {
  std::set<int> seen;
  TwistedArm arm(0, [&](const wire::SceneChunk& c, sim::Simulation&) {
    seen.insert(c.indices.begin(), c.indices.end());
    return seen.size() > 1000;
  });
  ASSERT_FALSE(arm.chunks.empty()) << arm.Why();
  // What the frames carry is the test; the frame rate is a benchmark's.
  EXPECT_GE(arm.endpoint->counters().frames, 1u);
  const auto rest = geometry::MakeLimb(geometry::ForearmPreset())->surface.positions;
  std::set<int> moved;
  for (const auto& c : arm.chunks) {
    EXPECT_FALSE(c.twist.has_value());
    for (size_t i = 0; i < c.indices.size(); ++i) {
      ASSERT_LT(c.indices[i], static_cast<int>(rest.size()));
      const auto& p0 = rest[c.indices[i]];
      // A twist about the limb axis: same height and distance from the axis, to the µm.
      EXPECT_NEAR(c.positions[i].z(), p0.z(), 1e-6);
      EXPECT_NEAR(std::hypot(c.positions[i].x(), c.positions[i].y()), std::hypot(p0.x(), p0.y()),
                  2e-6);
      moved.insert(c.indices[i]);
    }
  }
  EXPECT_GT(moved.size(), 1000u) << arm.Why();
  EXPECT_LT(moved.size(), rest.size());  // the elbow end never moves
}

}  // namespace
}  // namespace vsurg::client
