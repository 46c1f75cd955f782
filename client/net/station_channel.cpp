#include "client/net/station_channel.h"

#include <algorithm>
#include <atomic>
#include <bitset>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

#include "client/net/deadband.h"
#include "client/net/passivity.h"
#include "common/core/realtime.h"
#include "common/haptics/tissue_surface.h"
#include "common/haptics/viscoelastic.h"
#include "common/sim/triple_buffer.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"

namespace vsurg::client {

namespace asio = boost::asio;
using asio::ip::udp;
using SteadyTime = std::chrono::steady_clock;  // the device loop's real-time pacing
using Vec3 = Eigen::Vector3d;

Expected<LocalRendering> ParseLocalRendering(const std::string& name) {
  if (name == "server") return LocalRendering::kServerForce;
  if (name == "linear") return LocalRendering::kLinear;
  if (name == "model") return LocalRendering::kModel;
  return InvalidArgument("local-model", "'" + name + "' is not one of server, linear, model");
}

Expected<PassivityMode> ParsePassivityMode(const std::string& name) {
  if (name == "local") return PassivityMode::kLocal;
  if (name == "network") return PassivityMode::kNetwork;
  return InvalidArgument("passivity", "'" + name + "' is not local or network");
}

namespace {

// Which of the last 4096 sequence numbers were seen: tells a reordered datagram from a copy, and
// counts the distinct ones (the rest, up to the newest, were lost).
class SequenceWindow {
 public:
  enum class Kind { kNewest, kReordered, kDuplicate, kTooOld };
  Kind Add(uint64_t seq) {
    if (seq > newest_) {
      if (seq - newest_ >= kSize) {
        seen_.reset();
      } else {
        for (uint64_t s = newest_ + 1; s < seq; ++s) seen_.reset(s % kSize);
      }
      newest_ = seq;
      seen_.set(seq % kSize);
      ++distinct_;
      return Kind::kNewest;
    }
    if (newest_ - seq >= kSize) return Kind::kTooOld;
    if (seen_.test(seq % kSize)) return Kind::kDuplicate;
    seen_.set(seq % kSize);
    ++distinct_;
    return Kind::kReordered;
  }
  uint64_t newest() const { return newest_; }
  uint64_t missing() const { return newest_ - std::min(newest_, distinct_); }

 private:
  static constexpr uint64_t kSize = 4096;
  std::bitset<kSize> seen_;
  uint64_t newest_ = 0, distinct_ = 0;
};

// One servo cycle as the force log writes it (station_channel.h, StationOptions::force_log).
struct LogRow {
  double t, x, y, z, fx, fy, fz;
};

// A contact answer that carries the tissue (LocalModel::tissue_stiffness > 0), rendered as the
// proxy's spring in series with the tissue point (haptics/viscoelastic.h): the station keeps its
// own tip positions of the last second, and at each new answer integrates the tissue's yield from
// the answered sample's time through them, so the force now is what the tissue gives after the
// motion the server has not seen yet. Its time is the servo's: one period per cycle, as the hand
// moves (a loop that ran late beside other work does not let the tissue relax further than the
// hand moved; beside two CPU hogs, wall-time steps left a 0.15 N pull after letting go).
// Device thread only; no allocation after construction.
class TissueContact {
 public:
  explicit TissueContact(double period_s) : ring_(kRing), period_(period_s) {}

  // This cycle's tip (station clock, s; scene frame, m), before Render.
  void Record(double t, const Vec3& x) {
    ring_[head_ % kRing] = {t, x};
    ++head_;
  }

  // The force for this cycle's tip `x` from `answer`; false when the answer carries no tissue
  // (the caller renders the model as it is).
  // `sampled` is the answered sample's time (the echo), `answer_id` its sequence.
  bool Render(const haptics::ForceCommand& answer, uint64_t answer_id, double sampled,
              const Vec3& x, Vec3& force) {
    const haptics::LocalModel& m = answer.local;
    const Vec3& n = m.normal;
    const double kp = -n.dot(m.jacobian * n);
    if (!answer.contact || m.kind != haptics::LocalModel::Kind::kContact ||
        !(m.tissue_stiffness > 0) || !(kp > 0)) {
      active_ = false;
      return false;
    }
    const double f0 = n.dot(m.force0);
    if (!active_ || answer_id != answer_id_) {
      // A new answer: from its sample's time over the tips recorded since (this cycle's last).
      active_ = true, answer_id_ = answer_id;
      contact_.Begin(f0, kp, m.tissue_stiffness, m.tissue_damping, m.tissue_elastic0);
      const double last = sampled;
      const uint64_t have = std::min<uint64_t>(head_, kRing);
      uint64_t k = head_ - have;
      while (k + 1 < head_ && !(ring_[k % kRing].t > last)) ++k;
      for (; k + 1 < head_; ++k) contact_.Step(n.dot(m.position0 - ring_[k % kRing].x), period_);
    }
    const double fn = contact_.Step(n.dot(m.position0 - x), period_);
    // The tissue's force along n; off the surface, nothing.
    force = fn > 0 ? Vec3(m.force0 + n * (fn - f0)) : Vec3::Zero();
    if (!force.allFinite()) force.setZero();
    return true;
  }

 private:
  struct Entry {
    double t = 0;
    Vec3 x = Vec3::Zero();
  };
  static constexpr uint64_t kRing = 1024;  // ~1 s at 1 kHz: beyond that the answer is faded anyway
  std::vector<Entry> ring_;
  uint64_t head_ = 0;
  double period_;
  bool active_ = false;
  uint64_t answer_id_ = 0;
  haptics::ViscoelasticContact contact_;
};

}  // namespace

struct StationChannel::Impl {
  struct Latest {
    wire::ForceMessage message;
    double received_s = -1;  // station clock
  };

  StationOptions options;
  HapticDevice* device = nullptr;
  asio::io_context io;
  udp::socket socket{io};
  udp::endpoint server;
  udp::endpoint from;
  wire::Authenticator auth;
  std::thread net_thread, device_thread;
  std::atomic<bool> stop{false};
  const Clock& clock;  // the station clock: watchdog, fade, round trips, sample times
  double start = 0;
  sim::TripleBuffer<Latest> latest;

  // Network thread.
  std::array<uint8_t, wire::kMaxDatagram + 1> rx{};
  wire::Codec rx_codec;
  wire::ForceMessage rx_message;
  SequenceWindow answers;   // the server's datagram sequence: reordered and duplicated answers
  SequenceWindow answered;  // the echoed stylus sequences: what never came back
  double last_applied_s = -1;
  // RTT ring (network thread writes, stats() reads under the mutex).
  mutable std::mutex stats_mutex;
  std::vector<double> rtt_us;
  size_t rtt_next = 0;
  double jitter_sum = 0, last_rtt = -1;
  std::atomic<double> reported_rtt_us{0};  // receive thread → device thread (telemetry)
  std::atomic<double> reported_jitter_us{0};
  uint64_t jitter_n = 0;
  std::atomic<uint64_t> moved_notices{0};  // answers saying the session moved (not forces)
  std::atomic<uint64_t> marks{0};          // answers saying a palpation's mark was placed
  std::atomic<uint64_t> needle_pops{0}, needle_corrections{0};  // the device thread's needle
  std::atomic<uint64_t> blade_punctures{0};                     // the device thread's blade
  std::atomic<uint64_t> received{0}, dropped{0}, stale{0}, duplicates{0}, lost{0}, late{0},
      newest_answered{0}, scene_chunks{0}, scene_bytes{0}, topology_bytes{0};
  uint64_t last_frame_sequence = 0;
  wire::SceneChunk chunk;
  std::mutex scene_mutex;  // network thread and the render thread, never the device thread
  std::deque<wire::SceneChunk> scene;

  // Device thread.
  std::array<uint8_t, wire::kMaxDatagram> tx{};
  wire::Codec tx_codec;
  std::atomic<uint64_t> sent{0}, fades{0};
  std::atomic<double> dissipated{0}, max_force{0}, to_hand{0}, from_hand{0}, tissue_released{0},
      network_balance_min{0};
  // The force log: the device thread produces rows, the log thread writes them (SPSC ring).
  std::FILE* log_file = nullptr;
  std::vector<LogRow> log_ring;
  std::atomic<uint64_t> log_head{0}, log_tail{0}, log_rows{0}, log_dropped{0};
  std::thread log_thread;
  std::atomic<bool> device_done{false};  // the device loop has returned (after Stop's fade)
  std::atomic<uint64_t> loop_iterations{0};
  std::atomic<double> loop_seconds{0}, loop_hz_min{0}, loop_hz_max{0};
  std::atomic<double> last_fx{0}, last_fy{0}, last_fz{0};
  sim::TripleBuffer<StationView> view;  // device thread → render thread

  // With the deadband answers come at least every heartbeat, not every cycle: the watchdog waits
  // for a heartbeat's answer and a jitter's margin before it fades.
  double watchdog_s;

  explicit Impl(const StationOptions& o)
      : options(o),
        auth(o.key),
        clock(o.clock ? *o.clock : DefaultClock()),
        start(clock.Now()),
        watchdog_s(o.deadband > 0 ? std::max(o.watchdog_s, o.heartbeat_s + 0.035) : o.watchdog_s) {}

  double Now() const { return clock.Now() - start; }

  void Receive() {
    socket.async_receive_from(asio::buffer(rx), from,
                              [this](const boost::system::error_code& ec, size_t n) {
                                if (ec == asio::error::operation_aborted || stop) return;
                                if (!ec) Handle(n);
                                Receive();
                              });
  }

  void Handle(size_t n) {
    wire::Opened o;
    const std::span<const uint8_t> d(rx.data(), n);
    if (wire::Open(d, &auth, o) != wire::DropReason::kNone || o.header.session != options.session) {
      dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (o.header.type == wire::PayloadType::kSceneFrame) {
      if (o.header.sequence <= last_frame_sequence ||
          rx_codec.DecodeSceneChunk(o.payload, chunk) != wire::DropReason::kNone) {
        dropped.fetch_add(1, std::memory_order_relaxed);
        return;
      }
      last_frame_sequence = o.header.sequence;
      scene_chunks.fetch_add(1, std::memory_order_relaxed);
      scene_bytes.fetch_add(n, std::memory_order_relaxed);
      if (chunk.topology != 0) topology_bytes.fetch_add(n, std::memory_order_relaxed);
      std::lock_guard<std::mutex> lock(scene_mutex);
      if (scene.size() >= 4096) scene.pop_front();
      scene.push_back(chunk);
      return;
    }
    if (o.header.type != wire::PayloadType::kForceFeedback) {
      dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (rx_codec.DecodeForce(o.payload, rx_message) != wire::DropReason::kNone) {
      dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (rx_message.command.events & haptics::kEventSessionMoved) {
      // Not a force: the session runs on another node now (live migration). The supervisor asks
      // where; meanwhile the watchdog holds the model, then fades, as for any silence.
      moved_notices.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    const SequenceWindow::Kind kind = answers.Add(o.header.sequence);
    if (kind == SequenceWindow::Kind::kDuplicate) {
      duplicates.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (rx_message.command.events & haptics::kEventMarked)
      marks.fetch_add(1, std::memory_order_relaxed);  // a late answer's mark still counts
    answered.Add(rx_message.echo_sequence);
    lost.store(answered.missing(), std::memory_order_relaxed);
    newest_answered.store(answered.newest(), std::memory_order_relaxed);
    if (kind != SequenceWindow::Kind::kNewest) {  // an older answer after a newer: latest wins
      stale.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    const double now = Now();
    if (last_applied_s >= 0 && now - last_applied_s > watchdog_s)
      late.fetch_add(1, std::memory_order_relaxed);
    last_applied_s = now;
    Latest& back = latest.Back();
    back.message = rx_message;
    if (!options.exact_grasp) back.message.command.local.has_twist_model = false;
    back.received_s = now;
    latest.Publish();
    received.fetch_add(1, std::memory_order_relaxed);
    const double rtt = (now - rx_message.echo_time) * 1e6;
    if (rtt >= 0 && rtt < 10e6) {
      std::lock_guard<std::mutex> lock(stats_mutex);
      rtt_us[rtt_next++ % rtt_us.size()] = rtt;
      if (last_rtt >= 0) {
        jitter_sum += std::abs(rtt - last_rtt), ++jitter_n;
        reported_jitter_us.store(jitter_sum / static_cast<double>(jitter_n),
                                 std::memory_order_relaxed);
      }
      last_rtt = rtt;
      reported_rtt_us.store(rtt, std::memory_order_relaxed);
    }
  }

  // Device thread: one row into the ring, or counted as dropped when the writer is behind.
  void Log(const LogRow& row) {
    const uint64_t head = log_head.load(std::memory_order_relaxed);
    if (head - log_tail.load(std::memory_order_acquire) >= log_ring.size()) {
      log_dropped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    log_ring[head % log_ring.size()] = row;
    log_head.store(head + 1, std::memory_order_release);
  }

  // Log thread: writes what the device thread produced, every 20 ms, until stopped and drained.
  void LogLoop() {
    std::fseek(log_file, 0, SEEK_END);
    if (std::ftell(log_file) == 0) std::fputs("t_s,x_m,y_m,z_m,fx_n,fy_n,fz_n\n", log_file);
    for (;;) {
      const bool stopping = device_done.load();  // Stop's fade is logged too
      const uint64_t head = log_head.load(std::memory_order_acquire);
      uint64_t tail = log_tail.load(std::memory_order_relaxed);
      for (; tail < head; ++tail) {
        const LogRow& r = log_ring[tail % log_ring.size()];
        std::fprintf(log_file, "%.6f,%.7g,%.7g,%.7g,%.6g,%.6g,%.6g\n", r.t, r.x, r.y, r.z, r.fx,
                     r.fy, r.fz);
        log_rows.fetch_add(1, std::memory_order_relaxed);
        log_tail.store(tail + 1, std::memory_order_release);
      }
      if (stopping && tail == log_head.load(std::memory_order_acquire)) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::fflush(log_file);
  }

  // The device loop's own state (device thread only).
  struct Servo {
    explicit Servo(const StationOptions& o, const haptics::DeviceLimits& limits)
        : safety(*haptics::SafetyFilter::Create(limits)),
          deadband({o.deadband, o.deadband_position_m, o.deadband_angle_rad, o.deadband_onset_s,
                    o.heartbeat_s, o.deadband_contact_heartbeat_s}),
          tissue(1.0 / o.rate_hz),
          surface(o.surface, 1.0 / o.rate_hz),
          needle(o.needle, 1.0 / o.rate_hz),
          // Always observing; controlling only when asked.
          passivity(o.passivity ? o.max_damping : 0.0, 1e-4, o.passivity_mode) {
      if (o.blade)
        if (auto b = haptics::BladeModel::Create(*o.blade); b.ok()) blade.emplace(std::move(*b));
    }
    haptics::SafetyFilter safety;
    Deadband deadband;
    TissueContact tissue;
    haptics::SurfaceContact surface;
    haptics::NeedleContact needle;
    std::optional<haptics::BladeModel> blade;  // 2048 segments: made once, with the channel
    PassivityController passivity;
    uint64_t sequence = 0;
    bool fading = false;
    Vec3 last_tip = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // none yet
    double surface_since = -1;  // station clock: when the surface's own contact began (-1: none)
    double rendered_peak = 0, rendered_over_limit = 0;  // this session's, reported uplink
    wire::StylusMessage m;
    SteadyTime::time_point loop_start = SteadyTime::now(), second_start = loop_start;
    uint64_t iterations = 0, second_start_iterations = 0;
  };

  // The loop's own rate, on real time: over the run, and per whole second.
  void CountLoop(Servo& v) {
    const auto t_loop = SteadyTime::now();
    loop_seconds.store(std::chrono::duration<double>(t_loop - v.loop_start).count(),
                       std::memory_order_relaxed);
    loop_iterations.store(v.iterations++, std::memory_order_relaxed);
    if (const double w = std::chrono::duration<double>(t_loop - v.second_start).count(); w >= 1.0) {
      const double hz = static_cast<double>(v.iterations - 1 - v.second_start_iterations) / w;
      if (loop_hz_min.load() == 0 || hz < loop_hz_min.load()) loop_hz_min.store(hz);
      if (hz > loop_hz_max.load()) loop_hz_max.store(hz);
      v.second_start = t_loop;
      v.second_start_iterations = v.iterations - 1;
    }
  }

  // The force of the newest local model at this cycle's sample, independent of network timing;
  // `held` says whether it is a passive field about the tissue's state (held through a silence).
  Vec3 RenderModel(Servo& v, const Latest& l, const haptics::StylusSample& s, const Vec3& velocity,
                   bool& held) {
    using Kind = haptics::LocalModel::Kind;
    const haptics::ForceCommand& answer = l.message.command;
    held = options.rendering == LocalRendering::kModel &&
           (answer.local.kind == Kind::kContact || answer.local.kind == Kind::kGrasp);
    Vec3 f = Vec3::Zero();
    switch (options.rendering) {
      case LocalRendering::kServerForce:
        return answer.force;
      case LocalRendering::kLinear:  // the first linear model: nothing ahead of contact
        if (answer.contact || answer.grasping) f = answer.local.ForceAt(s.position);
        return f;
      case LocalRendering::kModel:
        break;
    }
    // A shared tool's answer (four-handed training): the tool is not at this station's tip, so
    // neither its own surface nor its tissue point applies; the answer's linear model is the
    // coupling and the share of the tissue the server computed for this hand.
    if (answer.shared) {
      held = false;
      v.surface.Yield();
      return answer.local.ForceAt(s.position);
    }
    // A needle: the station's own needle model, the answers correcting its course.
    if (v.needle.active()) {
      held = true;
      v.needle.Answer(answer.local, l.message.echo_sequence);
      const Vec3 axis = -(s.orientation.normalized() * Vec3::UnitZ());
      f = v.needle.Render(s.position, axis, v.sequence + 1);
      needle_pops.store(v.needle.local_pops(), std::memory_order_relaxed);
      needle_corrections.store(v.needle.corrections(), std::memory_order_relaxed);
      return f;
    }
    // A blade: the station's own fracture model from its own tip.
    if (v.blade) {
      held = true;
      const haptics::BladeForce b = v.blade->Step(s.position);
      if (b.punctured) blade_punctures.fetch_add(1, std::memory_order_relaxed);
      return b.force;
    }
    // The server's contact or grasp is the tissue as it is; a free answer is a round trip old,
    // and the station's own surface (when it has one) says where the tissue begins now. Except
    // for an answer about the impact of a contact the station's own surface began, a round trip
    // older than kFreshS (OwnImpact): the station keeps rendering that contact.
    if (answer.contact && OwnImpact(v, l, s.time) && v.surface.Render(s.position, velocity, f)) {
      held = true;
      return f;
    }
    if (answer.contact || answer.grasping) {
      v.surface.Yield();
      v.surface_since = -1;
    } else if (v.surface.Render(s.position, velocity, f)) {
      held = held || v.surface.in_contact();
      if (!v.surface.in_contact())
        v.surface_since = -1;
      else if (v.surface_since < 0)
        v.surface_since = s.time;
      return f;
    }
    if (!v.tissue.Render(answer, l.message.echo_sequence, l.message.echo_time, s.position, f))
      f = answer.local.Render(s.position, s.orientation, s.buttons, velocity);
    return f;
  }

  // A tissue struck by a tap rings for about kImpactS (the spheres' mass-spring transients settle
  // in 120-150 ms). An answer about a sample in that time carries the transient, which no
  // first-order tissue model can carry a round trip forward: one older than kFreshS, about a
  // contact the station's own surface began, is not rendered; the station's contact goes on until
  // an answer about the settled tissue arrives. A fresh answer (a round trip within kFreshS, a
  // lab's or a city's network) is the impact as it is, and takes over at once. Only where the
  // surface carries the tissue's law (the viscoelastic contact); the proxy's rigid spring is no
  // model of an impact either way.
  static constexpr double kImpactS = 0.15, kFreshS = 0.03;
  static bool OwnImpact(const Servo& v, const Latest& l, double now) {
    const double sampled = l.message.echo_time;
    return v.surface.has_tissue() && v.surface.in_contact() && v.surface_since >= 0 &&
           sampled < v.surface_since + kImpactS && now - sampled > kFreshS;
  }

  // The watchdog: a model older than its patience fades out over fade_s.
  void Watchdog(Servo& v, const Latest& l, double now, bool held, bool stopping_now, Vec3& f) {
    const double patience = held ? std::max(watchdog_s, options.model_hold_s) : watchdog_s;
    const double age = now - l.received_s;
    if (age > patience) {
      if (!v.fading) fades.fetch_add(1, std::memory_order_relaxed);
      v.fading = true;
      f *= std::max(0.0, 1.0 - (age - patience) / options.fade_s);
    } else {
      v.fading = false;
    }
    if (stopping_now && !v.fading && age > watchdog_s)
      fades.fetch_add(1, std::memory_order_relaxed);  // stopped while the server was silent
  }

  // Passivity, the station's safety filter and the device: what the hand is given.
  Vec3 Output(Servo& v, const Latest& l, const haptics::StylusSample& s, double dt, Vec3 f) {
    // Passivity observer/controller: the coupling must not put energy into the hand.
    if (l.received_s >= 0)
      v.passivity.TissueReport(l.message.echo_sequence, l.message.command.released_j,
                               l.message.command.absorbed_j);
    // A grasp's twist field may give a yielding hand what it declares (types.h).
    const double allowance = l.received_s >= 0
                                 ? l.message.command.local.TwistFieldEnergy(
                                       l.message.command.proxy, s.orientation, s.buttons)
                                 : 0.0;
    f = v.passivity.Apply(f, s.position, dt, allowance);
    uint32_t events = 0;
    Vec3 out = v.safety.Filter(f, dt, events);
    if (l.received_s < 0) {
      // No answer from this session's server yet: nothing is requested, and the start-up gate
      // must not count these cycles as quiet (else it opens and ramps before the first model
      // arrives, and a session started or re-placed with the tip in tissue kicks).
      v.safety.Disarm();
      out.setZero();
    }
    device->WriteForce(out);
    v.passivity.Held(out);
    v.rendered_peak = std::max(v.rendered_peak, out.norm());
    if (options.force_limit_n > 0 && out.norm() > options.force_limit_n)
      v.rendered_over_limit += dt;
    return out;
  }

  // The stylus to the server: every cycle, or with the deadband only what the hand would notice
  // (and a heartbeat); the server answers each one, so both directions thin alike.
  void SendStylus(Servo& v, double now, const haptics::StylusSample& s, const Vec3& modelled) {
    if (!v.deadband.Due(now, s, modelled)) return;
    v.m.sample = s;
    v.m.rtt_us = reported_rtt_us.load(std::memory_order_relaxed);
    v.m.rendered_peak_n = v.rendered_peak;
    v.m.rendered_over_limit_s = v.rendered_over_limit;
    v.m.jitter_us = reported_jitter_us.load(std::memory_order_relaxed);
    v.m.twist_shape_key = options.twist_shape_key;
    const wire::Header h{wire::kProtocolVersion, wire::PayloadType::kStylusState, options.session,
                         ++v.sequence};
    const size_t size = tx_codec.EncodeStylus(v.m, h, auth, tx);
    boost::system::error_code ec;
    if (size > 0) socket.send_to(asio::buffer(tx.data(), size), server, 0, ec);
    if (!ec) sent.fetch_add(1, std::memory_order_relaxed);
    v.passivity.Sent(v.sequence);
  }

  // The figures other threads read, the force log and the render thread's view.
  void Publish(const Servo& v, const Latest& l, double now, const haptics::StylusSample& s,
               const Vec3& out) {
    dissipated.store(v.passivity.dissipated(), std::memory_order_relaxed);
    to_hand.store(v.passivity.to_hand(), std::memory_order_relaxed);
    from_hand.store(v.passivity.from_hand(), std::memory_order_relaxed);
    tissue_released.store(v.passivity.released(), std::memory_order_relaxed);
    if (const double b = v.passivity.network_balance(); b < network_balance_min.load())
      network_balance_min.store(b, std::memory_order_relaxed);
    if (log_file)
      Log({now, s.position.x(), s.position.y(), s.position.z(), out.x(), out.y(), out.z()});
    last_fx = out.x(), last_fy = out.y(), last_fz = out.z();
    StationView& shown = view.Back();
    shown.sample = s;
    shown.force = out;
    shown.command = l.message.command;
    shown.update_age_s = l.received_s >= 0 ? now - l.received_s : -1;
    view.Publish();
    if (out.norm() > max_force.load()) max_force = out.norm();
  }

  void DeviceLoop() {
    Servo v(options, device->limits());
    const auto period = std::chrono::duration_cast<SteadyTime::duration>(
        std::chrono::duration<double>(1.0 / options.rate_hz));
    auto next = SteadyTime::now();
    const double dt = 1.0 / options.rate_hz;
    // Stop: the force fades out over fade_s (at most 0.5 s) counted in cycles (the station clock
    // may stand still), then the loop returns once the rate limit has reached zero.
    const int stop_cycles = static_cast<int>(std::clamp(
        std::lround(options.fade_s * options.rate_hz), 1L, std::lround(0.5 * options.rate_hz)));
    int stopping = -1;  // cycles since Stop, -1: running
    for (;;) {
      if (stopping < 0 && stop.load(std::memory_order_relaxed)) stopping = 0;
      CountLoop(v);
      const double now = Now();
      haptics::StylusSample s = device->Read();
      s.time = now;  // the station clock: the server echoes it back for the round trip
      if (s.position.allFinite()) v.tissue.Record(now, s.position);
      // The tip's velocity over the last servo period, as the server's proxy measures it between
      // samples (the damping of a contact ahead of the tool, types.h).
      const Vec3 velocity = s.position.allFinite() && v.last_tip.allFinite()
                                ? Vec3((s.position - v.last_tip) * options.rate_hz)
                                : Vec3::Zero();
      v.last_tip = s.position;
      latest.Acquire();
      const Latest& l = latest.Front();
      Vec3 f = Vec3::Zero(), modelled = Vec3::Zero();
      if (l.received_s >= 0 && s.position.allFinite()) {
        bool held = false;
        f = modelled = RenderModel(v, l, s, velocity, held);
        Watchdog(v, l, now, held, stopping == 0, f);
      }
      if (stopping >= 0) f *= std::max(0.0, 1.0 - static_cast<double>(stopping) / stop_cycles);
      const Vec3 out = Output(v, l, s, dt, f);
      SendStylus(v, now, s, modelled);
      Publish(v, l, now, s, out);
      if (stopping >= 0 && ++stopping > stop_cycles && (out.isZero(0.0) || stopping > 1000)) break;
      next += period;
      const auto t = SteadyTime::now();
      if (t - next > std::chrono::milliseconds(20)) next = t;  // fell behind: no burst
      std::this_thread::sleep_until(next);
    }
  }
};

Expected<std::unique_ptr<StationChannel>> StationChannel::Create(const StationOptions& options,
                                                                 HapticDevice* device) {
  if (device == nullptr) return InvalidArgument("device", "a station needs a device");
  if (!(options.rate_hz >= 100 && options.rate_hz <= 20000))
    return InvalidArgument("rate_hz", "must be in 100..20000");
  if (!(options.watchdog_s > 0 && options.fade_s > 0))
    return InvalidArgument("watchdog", "times must be > 0");
  if (!(options.model_hold_s >= 0 && options.model_hold_s <= 10))
    return InvalidArgument("model_hold_s", "must be in 0..10 s");
  if (!(options.deadband >= 0 && options.deadband < 1) || !(options.heartbeat_s > 0.001) ||
      !(options.heartbeat_s <= 0.25) || !(options.deadband_contact_heartbeat_s > 0.001) ||
      !(options.deadband_contact_heartbeat_s <= 0.25) || !(options.deadband_position_m > 0) ||
      !(options.deadband_angle_rad > 0) ||
      !(options.deadband_onset_s >= 0 && options.deadband_onset_s <= 1))
    return InvalidArgument("deadband",
                           "the fraction must be in [0, 1), the heartbeat within 1..250 ms, the "
                           "contact onset within 0..1 s and the thresholds > 0");
  auto impl = std::make_unique<Impl>(options);
  impl->device = device;
  if (!options.force_log.empty()) {
    // Appended: a station's channels (one per session, after a reconnect) share one log.
    impl->log_file = std::fopen(options.force_log.c_str(), "a");
    if (!impl->log_file)
      return InvalidArgument("force_log", "cannot write '" + options.force_log + "'");
    static_assert(sizeof(LogRow) == 56);
    impl->log_ring.resize(1 << 15);  // 33 s of rows at 1 kHz: the writer never falls that far
  }
  impl->rtt_us.assign(1 << 16, 0.0);
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options.server_address, ec);
  if (ec)
    return InvalidArgument("server_address",
                           "'" + options.server_address + "' is not an IP address");
  impl->server = udp::endpoint(address, options.server_port);
  impl->socket.open(address.is_v6() ? udp::v6() : udp::v4(), ec);
  if (!ec) impl->socket.bind(udp::endpoint(address.is_v6() ? udp::v6() : udp::v4(), 0), ec);
  if (ec)
    return Error{ErrorCode::kIoError, "cannot open the station's UDP socket: " + ec.message(),
                 "socket"};
  Impl* p = impl.get();
  p->Receive();
  p->net_thread = std::thread([p] {
    NameThisThread("vsurg-net");
    TrySetRealtimePriority(p->options.realtime_priority);
    p->io.run();
  });
  p->device_thread = std::thread([p] {
    NameThisThread("vsurg-haptic");
    TrySetRealtimePriority(p->options.realtime_priority);
    p->DeviceLoop();
    p->device_done.store(true);
  });
  if (p->log_file)
    p->log_thread = std::thread([p] {
      NameThisThread("vsurg-log");
      p->LogLoop();
    });
  return std::unique_ptr<StationChannel>(new StationChannel(std::move(impl)));
}

StationChannel::StationChannel(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

StationChannel::~StationChannel() {
  Stop();
}

void StationChannel::Stop() {
  if (!impl_ || impl_->stop.exchange(true)) return;
  if (impl_->device_thread.joinable()) impl_->device_thread.join();
  if (impl_->log_thread.joinable()) impl_->log_thread.join();
  if (impl_->log_file) std::fclose(impl_->log_file), impl_->log_file = nullptr;
  impl_->device->WriteForce(Vec3::Zero());  // the hand is not left holding the last force
  impl_->last_fx = 0, impl_->last_fy = 0, impl_->last_fz = 0;
  asio::post(impl_->io, [p = impl_.get()] {
    boost::system::error_code ec;
    p->socket.close(ec);
  });
  if (impl_->net_thread.joinable()) impl_->net_thread.join();
}

StationStats StationChannel::stats() const {
  StationStats s;
  s.sent = impl_->sent.load();
  s.received = impl_->received.load();
  s.dropped = impl_->dropped.load();
  s.stale = impl_->stale.load();
  s.duplicates = impl_->duplicates.load();
  s.lost = impl_->lost.load();
  s.late = impl_->late.load();
  s.energy_to_hand = impl_->to_hand.load();
  s.energy_from_hand = impl_->from_hand.load();
  s.tissue_released = impl_->tissue_released.load();
  s.network_balance_min = impl_->network_balance_min.load();
  s.force_log_rows = impl_->log_rows.load();
  s.force_log_dropped = impl_->log_dropped.load();
  s.watchdog_fades = impl_->fades.load();
  s.scene_chunks = impl_->scene_chunks.load();
  s.scene_bytes = impl_->scene_bytes.load();
  s.topology_bytes = impl_->topology_bytes.load();
  s.marks = impl_->marks.load();
  s.needle_local_pops = impl_->needle_pops.load();
  s.needle_corrections = impl_->needle_corrections.load();
  s.blade_local_punctures = impl_->blade_punctures.load();
  s.passivity_energy_dissipated = impl_->dissipated.load();
  s.max_force = impl_->max_force.load();
  s.loop_iterations = impl_->loop_iterations.load();
  s.loop_seconds = impl_->loop_seconds.load();
  s.loop_hz = s.loop_seconds > 0 ? static_cast<double>(s.loop_iterations) / s.loop_seconds : 0.0;
  s.loop_hz_min = impl_->loop_hz_min.load();
  s.loop_hz_max = impl_->loop_hz_max.load();
  const uint64_t newest = impl_->newest_answered.load();
  s.loss = newest > 0 ? static_cast<double>(s.lost) / static_cast<double>(newest) : 0.0;
  std::vector<double> rtt;
  {
    std::lock_guard<std::mutex> lock(impl_->stats_mutex);
    const size_t n = std::min(impl_->rtt_next, impl_->rtt_us.size());
    rtt.assign(impl_->rtt_us.begin(), impl_->rtt_us.begin() + n);
    s.jitter_us = impl_->jitter_n ? impl_->jitter_sum / impl_->jitter_n : 0.0;
  }
  if (!rtt.empty()) {
    // Selection, not a sort: each nth_element leaves the larger values above its rank, so
    // the next one only searches those.
    const auto at = [&](size_t rank) { return rtt.begin() + static_cast<std::ptrdiff_t>(rank); };
    const size_t p50 = rtt.size() / 2, p99 = rtt.size() * 99 / 100, p999 = rtt.size() * 999 / 1000;
    std::nth_element(rtt.begin(), at(p50), rtt.end());
    std::nth_element(at(p50), at(p99), rtt.end());
    std::nth_element(at(p99), at(p999), rtt.end());
    s.rtt_p50_us = *at(p50);
    s.rtt_p99_us = *at(p99);
    s.rtt_p999_us = *at(p999);
  }
  return s;
}

uint64_t StationChannel::moved_notices() const {
  return impl_->moved_notices.load(std::memory_order_relaxed);
}

uint64_t StationChannel::received() const {
  return impl_->received.load();
}

std::vector<wire::SceneChunk> StationChannel::TakeSceneChunks() {
  std::lock_guard<std::mutex> lock(impl_->scene_mutex);
  std::vector<wire::SceneChunk> out(std::make_move_iterator(impl_->scene.begin()),
                                    std::make_move_iterator(impl_->scene.end()));
  impl_->scene.clear();
  return out;
}

bool StationChannel::TakeView(StationView& out) {
  const bool fresh = impl_->view.Acquire();
  out = impl_->view.Front();
  return fresh;
}

Eigen::Vector3d StationChannel::last_force() const {
  return {impl_->last_fx.load(), impl_->last_fy.load(), impl_->last_fz.load()};
}

}  // namespace vsurg::client
