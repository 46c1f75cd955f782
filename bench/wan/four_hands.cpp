#include "bench/wan/four_hands.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <thread>

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <random>

#include "bench/relay/relay.h"
#include "common/sim/simulation.h"
#include "proto/wire/messages.h"
#include "server/net/udp_endpoint.h"

namespace vsurg::bench::wan {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr uint64_t kSession = 7;

// The point of segment ab closest to p.
Vec3 ClosestOnSegment(const Vec3& a, const Vec3& b, const Vec3& p) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  return a + (len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0) * ab;
}

// The point of the path's stretch within kPathWindowS of `time` (s, the trainee's clock) closest
// to `tool`: one segment at least, however far `time` is outside the path's (it has two points).
constexpr double kPathWindowS = 1.0;
Vec3 ClosestOnPath(const std::vector<ToolSample>& path, double time, const Vec3& tool) {
  const auto index = [&](double v) {
    return static_cast<size_t>(
        std::lower_bound(path.begin(), path.end(), v,
                         [](const ToolSample& s, double x) { return s.time < x; }) -
        path.begin());
  };
  const size_t hi = std::clamp<size_t>(index(time + kPathWindowS), 1, path.size() - 1);
  const size_t lo = std::min(index(time - kPathWindowS), hi - 1);
  Vec3 best = path[lo].tool;
  for (size_t k = lo; k < hi; ++k) {
    const Vec3 c = ClosestOnSegment(path[k].tool, path[k + 1].tool, tool);
    if ((c - tool).squaredNorm() < (best - tool).squaredNorm()) best = c;
  }
  return best;
}

wire::SessionKey Key(uint64_t seed, uint8_t salt) {
  wire::SessionKey k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(11 * i + salt + seed);
  return k;
}

std::vector<haptics::StylusSample> WithLeadIn(const std::vector<haptics::StylusSample>& plan,
                                              double lead_in_s) {
  std::vector<haptics::StylusSample> out;
  const int lead = static_cast<int>(lead_in_s * 1000);
  out.reserve(plan.size() + lead);
  for (int k = 0; k < lead; ++k) {
    haptics::StylusSample s = plan.front();
    s.time = plan.front().time - lead_in_s + k * 1e-3;
    out.push_back(s);
  }
  out.insert(out.end(), plan.begin(), plan.end());
  return out;
}

// One hand at its station, through its relay to the endpoint.
struct Hand {
  std::unique_ptr<relay::Relay> relay;
  std::unique_ptr<client::VirtualHandDevice> device;
  std::unique_ptr<client::StationChannel> station;

  static Expected<Hand> Start(const FourHandsOptions& o, uint16_t server_port, uint64_t channel,
                              const wire::SessionKey& key, const relay::Profile& profile,
                              const std::vector<haptics::StylusSample>& plan, double lead_in_s,
                              const client::HandImpedance& grip, uint64_t seed) {
    Hand h;
    relay::RelayOptions ro;
    ro.server_port = server_port;
    ro.profile = profile;
    ro.seed = seed;
    auto relay = relay::Relay::Start(ro);
    if (!relay.ok()) return relay.error();
    h.relay = std::move(*relay);
    client::DeviceModel device;
    device.limits = o.scene.haptics.limits;
    auto hand = client::VirtualHandDevice::Create(WithLeadIn(plan, lead_in_s), grip, device);
    if (!hand.ok()) return hand.error();
    h.device = std::move(*hand);
    client::StationOptions co;
    co.server_port = h.relay->port();
    co.session = channel;
    co.key = key;
    co.force_limit_n = o.scene.task.force_limit;
    auto station = client::StationChannel::Create(co, h.device.get());
    if (!station.ok()) return station.error();
    h.station = std::move(*station);
    return h;
  }
  void Stop() {
    station->Stop();
    relay->Stop();
  }
};

// A broken or malicious instructor's station (FourHandsOptions::hostile_instructor), on a thread
// of its own until Stop.
class HostileSender {
 public:
  HostileSender(uint16_t port, uint64_t channel, const wire::SessionKey& key, uint64_t seed)
      : fd_(socket(AF_INET, SOCK_DGRAM, 0)), channel_(channel), auth_(key), rng_(seed) {
    to_.sin_family = AF_INET;
    to_.sin_port = htons(port);
    to_.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    thread_ = std::thread([this] { Run(); });
  }
  ~HostileSender() { Stop(); }
  uint64_t Stop() {
    running_ = false;
    if (thread_.joinable()) thread_.join();
    if (fd_ >= 0) close(fd_), fd_ = -1;
    return sent_;
  }

 private:
  void Run() {
    wire::Codec codec;
    std::vector<uint8_t> buf(wire::kMaxDatagram);
    std::uniform_real_distribution<double> jump(-0.03, 0.03);
    for (uint64_t seq = 1; running_; ++seq) {
      wire::StylusMessage m;
      m.sample.time = seq * 1e-3;
      m.sample.position = Vec3(0, 0, 0.05);
      switch (seq % 5) {
        case 0:
          m.sample.position.x() = std::numeric_limits<double>::quiet_NaN();
          break;
        case 1:
          m.sample.position = Vec3(10, 0, 0);
          break;
        case 2:
          m.sample.position += Vec3(jump(rng_), jump(rng_), jump(rng_));
          break;
        case 3:
          m.sample.time = 1e308;
          break;
        default:
          break;
      }
      size_t n = codec.EncodeStylus(
          m, {wire::kProtocolVersion, wire::PayloadType::kStylusState, channel_, seq}, auth_, buf);
      if (seq % 5 == 4)  // noise: the right channel, no valid seal
        for (size_t i = 20; i < n; ++i) buf[i] = static_cast<uint8_t>(rng_());
      sendto(fd_, buf.data(), n, 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_);
      ++sent_;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  int fd_;
  uint64_t channel_;
  wire::Authenticator auth_;
  std::mt19937_64 rng_;
  sockaddr_in to_{};
  std::atomic<bool> running_{true};
  uint64_t sent_ = 0;
  std::thread thread_;
};

// The correcting instructor's eyes and hand (FourHandsOptions::correct_towards): each tool the
// simulation publishes is seen a down link's delay later, and the hand's intent moves by what
// the controller makes of the shortfalls seen so far. A shortfall is where the tool strays from
// the expert's path (its closest point within kPathWindowS of the same moment), not how far it
// runs behind the plan's clock: pushing a slow approach on to catch up with the plan arrives a
// round trip late, at the surface, and deepens the impact it should have softened.
class Corrector {
 public:
  Corrector(const FourHandsOptions& o, client::VirtualHandDevice* hand)
      : o_(o),
        hand_(hand),
        delay_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double, std::milli>(o.instructor_profile.down.base_ms))) {}
  bool active() const { return hand_ != nullptr && o_.correct_towards.size() > 1; }

  void See(const sim::Telemetry& t) {
    if (!active()) return;
    seen_.push_back({std::chrono::steady_clock::now() + delay_, t.time,
                     ClosestOnPath(o_.correct_towards, t.time, t.tool) - t.tool});
  }
  void Act() {
    if (!active()) return;
    const auto now = std::chrono::steady_clock::now();
    bool moved = false;
    while (!seen_.empty() && seen_.front().at <= now) {
      const Seen e = seen_.front();
      seen_.pop_front();
      if (last_time_ >= 0 && e.time > last_time_)
        integral_ = Clamped(integral_ + o_.correction_ki * (e.time - last_time_) * e.shortfall);
      last_time_ = e.time;
      offset_ = Clamped(o_.correction_kp * e.shortfall + integral_);
      moved = true;
    }
    if (moved) hand_->Correct(offset_);
  }

 private:
  struct Seen {
    std::chrono::steady_clock::time_point at;
    double time;  // s, the trainee's clock
    Vec3 shortfall;
  };
  static Vec3 Clamped(const Vec3& v) {
    const double n = v.norm();
    return n > FourHandsOptions::kMaxCorrection ? v * (FourHandsOptions::kMaxCorrection / n) : v;
  }
  const FourHandsOptions& o_;
  client::VirtualHandDevice* hand_;
  std::chrono::steady_clock::duration delay_;
  std::deque<Seen> seen_;
  double last_time_ = -1;
  Vec3 integral_ = Vec3::Zero(), offset_ = Vec3::Zero();
};

// Reads the simulation's telemetry (the one reader, as the server's sampler is) until the trainee's
// hand has played its plan and settled, applying the mode changes on the way.
void Follow(const FourHandsOptions& o, sim::Simulation& simulation,
            const client::VirtualHandDevice& trainee, Corrector& corrector, FourHandsRun& run) {
  size_t next_change = 0;
  sim::Telemetry t;
  size_t settle_until = std::numeric_limits<size_t>::max();
  for (;;) {
    const size_t cycle = trainee.cycles();
    if (trainee.finished() && settle_until == std::numeric_limits<size_t>::max())
      settle_until = cycle + static_cast<size_t>(o.settle_s * 1000);
    if (cycle >= settle_until) break;
    while (next_change < o.changes.size() && o.changes[next_change].first <= cycle)
      simulation.RequestGuidance(o.changes[next_change++].second);
    if (simulation.TakeTelemetry(t)) {
      run.tool.push_back({t.tool, t.tip, t.tool_force, t.guide_alpha, t.guide_mode, cycle, t.time});
      corrector.See(t);
    }
    corrector.Act();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

}  // namespace

Expected<FourHandsRun> RunFourHands(const FourHandsOptions& o) {
  sim::SimulationOptions so;
  so.cache_dir = o.cache_dir;
  auto simulation = sim::Simulation::Create(o.scene, so);
  if (!simulation.ok()) return simulation.error();
  auto endpoint = server::UdpEndpoint::Create({});
  if (!endpoint.ok()) return endpoint.error();
  server::LinkStats trainee_link;
  (*endpoint)->AddSession(kSession, Key(o.seed, 3), simulation->get(), &trainee_link);
  const uint64_t channel = server::InstructorChannel(kSession);
  if (o.instructor) {
    (*endpoint)->AddInstructorChannel(channel, Key(o.seed, 5), simulation->get());
    (*simulation)->RequestGuidance(o.guide);
  }
  const uint16_t port = (*endpoint)->port();
  Hand instructor;
  std::unique_ptr<HostileSender> hostile;
  if (o.instructor && o.hostile_instructor) {
    hostile = std::make_unique<HostileSender>(port, channel, Key(o.seed, 5), o.seed + 200);
  } else if (o.instructor) {
    auto h = Hand::Start(o, port, channel, Key(o.seed, 5), o.instructor_profile, o.instructor_plan,
                         o.lead_in_s + o.instructor_lag_s, o.instructor_grip, o.seed + 100);
    if (!h.ok()) return h.error();
    instructor = std::move(*h);
  }
  auto trainee = Hand::Start(o, port, kSession, Key(o.seed, 3), o.trainee_profile, o.trainee_plan,
                             o.lead_in_s, o.trainee_grip, o.seed);
  if (!trainee.ok()) return trainee.error();
  FourHandsRun run;
  Corrector corrector(o, instructor.device.get());
  Follow(o, **simulation, *trainee->device, corrector, run);
  trainee->Stop();
  if (hostile) run.hostile_sent = hostile->Stop();
  if (instructor.station) instructor.Stop();
  (*endpoint)->RemoveSession(kSession);
  (*endpoint)->RemoveSession(channel);
  const auto lead = static_cast<std::ptrdiff_t>(o.lead_in_s * 1000);
  const auto cut = [lead](std::vector<client::HandSample> t) {
    t.erase(t.begin(), t.begin() + std::min(lead, std::ssize(t)));
    return t;
  };
  run.trainee = cut(trainee->device->trace());
  run.trainee_station = trainee->station->stats();
  if (instructor.station) {
    run.instructor = cut(instructor.device->trace());
    run.instructor_station = instructor.station->stats();
  }
  run.metrics = (*simulation)->Metrics();
  run.score_but_smoothness = scoring::ScoreButSmoothness(run.metrics, o.scene.task);
  run.trainee_applied = trainee_link.applied.load();
  return run;
}

std::vector<std::pair<size_t, sim::GuideRequest>> EveryModeChange(size_t lead_cycles) {
  return {{lead_cycles + 600, {sim::GuideMode::kGuide, 0.5}},
          {lead_cycles + 1500, {sim::GuideMode::kGuide, 1.0}},
          {lead_cycles + 2500, {sim::GuideMode::kGuide, 0.0}}};
}

double PathError(const FourHandsRun& run, const FourHandsRun& reference, size_t lead_cycles) {
  std::vector<Vec3> path;
  for (const ToolSample& s : reference.tool)
    if (s.cycle >= lead_cycles) path.push_back(s.tool);
  double sum = 0;
  size_t n = 0;
  for (const ToolSample& s : run.tool) {
    if (s.cycle < lead_cycles || path.size() < 2) continue;
    double best = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k + 1 < path.size(); ++k)
      best =
          std::min(best, (s.tool - ClosestOnSegment(path[k], path[k + 1], s.tool)).squaredNorm());
    sum += best;
    ++n;
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

double PeakToolForce(const FourHandsRun& run) {
  double peak = 0;
  for (const ToolSample& s : run.tool) peak = std::max(peak, s.force.norm());
  return peak;
}

double EnergyToHand(const std::vector<client::HandSample>& t) {
  double e = 0;
  for (size_t k = 0; k + 1 < t.size(); ++k) e += t[k].force.dot(t[k + 1].x - t[k].x);
  return e;
}

double PeakForce(const std::vector<client::HandSample>& t) {
  double peak = 0;
  for (const auto& c : t) peak = std::max(peak, c.force.norm());
  return peak;
}

PlaybackError ObserverError(const FourHandsRun& run, double max_lag_s) {
  PlaybackError out;
  const auto& t = run.trainee;
  const auto& i = run.instructor;
  const auto max_lag = static_cast<size_t>(max_lag_s * 1000);
  auto ratio = [&](size_t lag, size_t& cycles) {
    double err = 0, ref = 0;
    cycles = 0;
    for (size_t k = 0; k < t.size() && k + lag < i.size(); ++k) {
      if (t[k].force.norm() <= 0.05) continue;
      err += (i[k + lag].force - t[k].force).squaredNorm();
      ref += t[k].force.squaredNorm();
      ++cycles;
    }
    return ref > 0 ? std::sqrt(err / ref) : std::numeric_limits<double>::infinity();
  };
  out.raw_ratio = ratio(0, out.cycles);
  out.rms_ratio = out.raw_ratio;
  for (size_t lag = 1; lag <= max_lag; ++lag) {
    size_t cycles = 0;
    const double r = ratio(lag, cycles);
    if (r < out.rms_ratio) out.rms_ratio = r, out.lag_s = 1e-3 * lag, out.cycles = cycles;
  }
  return out;
}

}  // namespace vsurg::bench::wan
