// vsurg-bench haptic-rtt and udp-floor (see vsurg_bench_main.cpp's usage): simulated stations
// at 1 kHz against a real UDP endpoint on loopback, and the same stations against a plain echo.
#include "bench/rtt_commands.h"
#include "bench/rtt_server_stack.h"
#include "bench/udp_echo.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/args.h"
#include "common/core/realtime.h"
#include "common/sim/simulation.h"
#include "db/store.h"
#include "proto/wire/asio.h"
#include "proto/wire/messages.h"
#include "server/http/http_server.h"
#include "server/net/udp_endpoint.h"
#include "server/session/session_manager.h"

namespace vsurg::bench {
namespace {

namespace asio = boost::asio;
using asio::ip::udp;
using vsurg::cli::ArgParser;
using Clock = std::chrono::steady_clock;

struct Station {
  vsurg::wire::Authenticator auth;
  uint64_t session;
  uint64_t sequence = 0;
  uint64_t twist_shape_key = 0;          // the coil limb it says it remakes twists of (0: vertices)
  uint64_t first_measured = UINT64_MAX;  // the first sequence number sent in the measured window
  Station(uint64_t id, const vsurg::wire::SessionKey& key) : auth(key), session(id) {}
};

// --period-ms of haptic-rtt and udp-floor (the same stations in both).
constexpr const char* kPeriodHelp =
    "each station sends every this many milliseconds (1: a 1 kHz station; 20: about what the "
    "perceptual deadband sends)";

// --stations-per-socket of haptic-rtt and udp-floor.
constexpr const char* kPerSocketHelp =
    "stations that share one of the driver's sockets and go out as one batch (1: a socket per "
    "station, as separate machines; more: a driver that spends less of the two cores)";

// The options haptic-rtt and udp-floor share (the load both put on loopback), declared once.
void DeclareStationLoad(ArgParser& p, const std::string& priority_help) {
  using vsurg::server::EndpointOptions;
  p.Option("stations", ArgParser::Kind::kInt, "simulated stations", false, "1")
      .Within({1, 1024})
      .Option("seconds", ArgParser::Kind::kDouble, "measurement time, s", false, "10")
      .Within({0.001, 3600})
      .Option("realtime-priority", ArgParser::Kind::kInt, priority_help, false, "0")
      .Within(EndpointOptions::kRealtimePriority)
      .Option("period-ms", ArgParser::Kind::kInt, kPeriodHelp, false, "1")
      .Within({1, 100})
      .Option("stations-per-socket", ArgParser::Kind::kInt, kPerSocketHelp, false, "1")
      .Within({1, 64});
}

// Station i's session key, the same in haptic-rtt and udp-floor (sessions 1000 + i).
vsurg::wire::SessionKey BenchKey(int i) {
  vsurg::wire::SessionKey key;
  for (size_t k = 0; k < key.size(); ++k) key[k] = static_cast<uint8_t>(i * 7 + k);
  return key;
}

// How long stations run before measuring: the sessions' start-up gates and caches.
constexpr double kWarmupS = 0.5;
// haptic-rtt --twist-deg: when each station grasps (in the warm-up, after its approach).
constexpr double kTwistGraspS = 0.3;

// What a station's answers are: the server's force datagrams, or its own stylus datagrams
// echoed back unchanged (the bare-UDP floor).
enum class Answer { kForce, kEcho };

struct RttRun {
  uint64_t sent = 0, received = 0;
  std::vector<double> rtt_us;  // sorted: from the stylus datagram's send to its answer read
  // Sorted: from the send to the answer's arrival at the station's socket (its kernel stamp), so
  // without the driver's own time: answers that waited for one thread to read and decode the
  // other stations' answers, or for that thread to be scheduled. A station on a machine of its
  // own reads only its own answers.
  std::vector<double> arrival_rtt_us;
  // The driver's own load over the measured window: its thread's CPU over the wall time (1 is a
  // whole core), and the pacer's slots that went out more than a slot late (the driver could not
  // keep its stations' schedule: they then catch up together, a burst no lab's stations on their
  // own machines would send) and the latest of them.
  double driver_cpu_s = 0, driver_wall_s = 0;
  uint64_t slots = 0, late_slots = 0;
  double max_late_us = 0;

  static double Percentile(const std::vector<double>& sorted, double q) {
    return sorted.empty()
               ? 0.0
               : sorted[std::min(sorted.size() - 1, static_cast<size_t>(q * sorted.size()))];
  }
  double Percentile(double q) const { return Percentile(rtt_us, q); }
  nlohmann::json Summary(int stations, double seconds) const {
    nlohmann::json j;
    j["stations"] = stations;
    j["seconds"] = seconds;
    j["sent"] = sent;
    j["received"] = received;
    j["loss"] =
        sent ? std::max(0.0, 1.0 - static_cast<double>(received) / static_cast<double>(sent)) : 0.0;
    j["rtt_p50_us"] = Percentile(0.5);
    j["rtt_p99_us"] = Percentile(0.99);
    j["rtt_p999_us"] = Percentile(0.999);
    j["arrival_rtt_p50_us"] = Percentile(arrival_rtt_us, 0.5);
    j["arrival_rtt_p99_us"] = Percentile(arrival_rtt_us, 0.99);
    j["arrival_rtt_p999_us"] = Percentile(arrival_rtt_us, 0.999);
    j["driver_busy_cores"] = driver_wall_s > 0 ? driver_cpu_s / driver_wall_s : 0.0;
    j["driver_late_slots"] =
        slots ? static_cast<double>(late_slots) / static_cast<double>(slots) : 0.0;
    j["driver_max_late_us"] = max_late_us;
    return j;
  }
};

// The pacer's slots per millisecond: a station sends in one of 8 slots of 125 µs (DriveStations).
constexpr int kSlotsPerMs = 8;

// The stations' sockets: station k sends and receives on socket k mod S, each socket read and
// written a batch at a time (recvmmsg, sendmmsg). With `per_socket` 1 every station has its own
// socket (S = the stations), as separate machines would; with more, S is a multiple of the
// pacer's slots, so a socket's stations all fall in one slot and go out as one batch. The server
// sees the same datagrams either way; only their source ports are fewer. This is the driver's
// cost, not the server's: on two cores a driver that spends a core on per-datagram system calls
// leaves the server (and the floor's echo) less than the stations in a lab would.
int StationSockets(int n, int per_socket, int slots) {
  if (per_socket <= 1) return n;
  const int groups = (n + per_socket * slots - 1) / (per_socket * slots);
  return std::min(n, groups * slots);
}

// The stylus of station `k` of `n` at time t (s) of the drive: resting 3 mm inside the tissue,
// approaching from outside during the first 0.2 s; with a stroke, circling its rest once a
// second; with a twist, grasped once in contact and turned about the limb's axis (z through the
// origin), there and back every 2 s, the hand on the arc. The stations' phases differ, so each
// grasps with its stylus already turned by its own phase (the grasp's zero) and turns from
// there: their updates do not all fall due at once.
struct StylusMotion {
  Eigen::Vector3d rest, outward;
  double stroke = 0, twist = 0;  // m, rad
  vsurg::haptics::StylusSample At(double t, int k, int n) const {
    vsurg::haptics::StylusSample s;
    s.position = rest + (1.0 - std::min(1.0, t / 0.2)) * 0.02 * outward;
    if (stroke > 0) {
      const double a = 2 * std::numbers::pi * (t + static_cast<double>(k) / n);
      const Eigen::Vector3d e1 = outward.unitOrthogonal(), e2 = outward.cross(e1);
      s.position += stroke * (std::cos(a) * e1 + std::sin(a) * e2);
    }
    if (twist > 0 && t >= kTwistGraspS) {
      const double a = twist * std::sin(std::numbers::pi * (t - kTwistGraspS) +
                                        2 * std::numbers::pi * static_cast<double>(k) / n);
      const Eigen::AngleAxisd turn(a, Eigen::Vector3d::UnitZ());
      s.buttons = vsurg::haptics::kButtonGrasp;
      s.position = turn * s.position;
      s.orientation = Eigen::Quaterniond(turn);
    }
    return s;
  }
};

// The stations' answers, read in batches with their kernel arrival stamps: each answer to a
// measured datagram adds its round trip, and its round trip less the time it sat at the station.
struct AnswerReader {
  AnswerReader(Answer kind, const std::unordered_map<uint64_t, Station*>& stations, RttRun& into,
               std::function<double()> clock)
      : answer(kind), by_session(stations), run(into), now_s(std::move(clock)) {}
  Answer answer;
  const std::unordered_map<uint64_t, Station*>& by_session;
  RttRun& run;
  std::function<double()> now_s;
  vsurg::wire::Codec codec;
  vsurg::wire::ForceMessage reply;
  vsurg::wire::StylusMessage echoed;
  static constexpr int kBatch = 16;
  std::vector<std::array<uint8_t, 2048>> rx = std::vector<std::array<uint8_t, 2048>>(kBatch);
  std::array<iovec, kBatch> rx_iov{};
  std::array<mmsghdr, kBatch> rx_msgs{};
  std::array<std::array<char, CMSG_SPACE(sizeof(timespec))>, kBatch> rx_control{};

  static int64_t WallNs(const timespec& ts) {
    return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  }
  // A received datagram's arrival stamp (CLOCK_REALTIME, ns); -1 without one.
  static int64_t ArrivalNs(const msghdr& h) {
    for (cmsghdr* c = CMSG_FIRSTHDR(&h); c != nullptr; c = CMSG_NXTHDR(const_cast<msghdr*>(&h), c))
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        return WallNs(ts);
      }
    return -1;
  }
  void Take(std::span<const uint8_t> datagram, int64_t arrived_ns) {
    vsurg::wire::Header h;
    if (vsurg::wire::PeekHeader(datagram, h) != vsurg::wire::DropReason::kNone) return;
    // An answer is a force (or the echoed stylus datagram); a scene frame's chunk is read and
    // authenticated as a station would, but is not an answer.
    const bool answer_type =
        h.type == (answer == Answer::kForce ? vsurg::wire::PayloadType::kForceFeedback
                                            : vsurg::wire::PayloadType::kStylusState);
    const auto it = by_session.find(h.session);
    if (it == by_session.end()) return;
    Station& st = *it->second;
    vsurg::wire::Opened o;
    double echo_time = -1;
    uint64_t echo_sequence = 0;
    if (vsurg::wire::Open(datagram, &st.auth, o) == vsurg::wire::DropReason::kNone && answer_type) {
      if (answer == Answer::kForce &&
          codec.DecodeForce(o.payload, reply) == vsurg::wire::DropReason::kNone)
        echo_time = reply.echo_time, echo_sequence = reply.echo_sequence;
      if (answer == Answer::kEcho &&
          codec.DecodeStylus(o.payload, echoed) == vsurg::wire::DropReason::kNone)
        echo_time = echoed.sample.time, echo_sequence = o.header.sequence;
    }
    if (echo_time < 0 || echo_sequence < st.first_measured) return;
    ++run.received;
    const double rtt_us = (now_s() - echo_time) * 1e6;
    run.rtt_us.push_back(rtt_us);
    // Less the time the answer sat at the station, on the stamp's own clock (read now): the
    // send's clock and the stamp's are never compared, so the wall clock's slewing adds nothing;
    // a stepped wall clock counts as no wait.
    timespec wall{};
    clock_gettime(CLOCK_REALTIME, &wall);
    const double waited_us =
        arrived_ns >= 0
            ? 1e-3 * static_cast<double>(std::max<int64_t>(0, WallNs(wall) - arrived_ns))
            : 0.0;
    run.arrival_rtt_us.push_back(rtt_us - waited_us);
  }
  // Reads `socket` whenever it is readable, for as long as the loop runs.
  void Receive(udp::socket& socket) {
    socket.async_wait(udp::socket::wait_read, [this, sp = &socket](auto ec) {
      if (ec) return;
      for (;;) {
        for (int i = 0; i < kBatch; ++i) {
          rx_iov[i] = {rx[i].data(), rx[i].size()};
          rx_msgs[i] = {};
          rx_msgs[i].msg_hdr.msg_iov = &rx_iov[i];
          rx_msgs[i].msg_hdr.msg_iovlen = 1;
          rx_msgs[i].msg_hdr.msg_control = rx_control[i].data();
          rx_msgs[i].msg_hdr.msg_controllen = rx_control[i].size();
        }
        const int got =
            ::recvmmsg(sp->native_handle(), rx_msgs.data(), kBatch, MSG_DONTWAIT, nullptr);
        if (got <= 0) break;
        for (int i = 0; i < got; ++i)
          Take({rx[i].data(), rx_msgs[i].msg_len}, ArrivalNs(rx_msgs[i].msg_hdr));
        if (got < kBatch) break;
      }
      Receive(*sp);
    });
  }
};

// The driver's sockets on loopback, non-blocking, each stamping its datagrams' arrival (for
// arrival_rtt_us).
std::vector<std::unique_ptr<udp::socket>> StationSocketsOn(asio::io_context& io, int count) {
  std::vector<std::unique_ptr<udp::socket>> sockets;
  for (int i = 0; i < count; ++i) {
    sockets.push_back(
        std::make_unique<udp::socket>(io, udp::endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    sockets.back()->non_blocking(true);
    const int on = 1;
    ::setsockopt(sockets.back()->native_handle(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  }
  return sockets;
}

// The stations' side of haptic-rtt and udp-floor, the same for both: each station sends an
// authenticated stylus datagram every millisecond (stamped with the send time, which the answer
// echoes), spread over the millisecond in 8 slots of 125 µs as independent stations would be
// rather than sent as one burst the server must queue; with `period_ms` > 1 (a station behind
// the perceptual deadband, which sends about one sample in 20) every period_ms milliseconds,
// the stations spread over the period's 8·period_ms slots alike; the stylus approaches from
// `outward` of `rest` during the warm-up. With `stroke` > 0 (m) each station's stylus then circles
// `rest` at that radius once a second, across `outward` (a hand palpating; the stations' phases
// spread), instead of resting. Answers are opened and decoded; the round trip of each is kept.
// `per_socket`: stations sharing a socket (StationSockets).
RttRun DriveStations(asio::io_context& io, std::vector<std::unique_ptr<Station>>& stations,
                     const udp::endpoint& server, const Eigen::Vector3d& rest,
                     const Eigen::Vector3d& outward, double seconds, Answer answer,
                     int period_ms = 1, double stroke = 0, double twist = 0, int per_socket = 1) {
  const int n = static_cast<int>(stations.size());
  const int slots = kSlotsPerMs * period_ms;
  const int socket_count = StationSockets(n, per_socket, slots);
  std::vector<std::unique_ptr<udp::socket>> sockets = StationSocketsOn(io, socket_count);
  std::unordered_map<uint64_t, Station*> by_session;
  for (auto& st : stations) by_session[st->session] = st.get();
  const Clock::time_point start = Clock::now();
  auto now_s = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  RttRun run;
  run.rtt_us.reserve(static_cast<size_t>(n * seconds * 1000 * 1.1 / period_ms));
  run.arrival_rtt_us.reserve(run.rtt_us.capacity());
  vsurg::wire::Codec codec;
  AnswerReader reader{answer, by_session, run, now_s};
  for (auto& socket : sockets) reader.Receive(*socket);
  const StylusMotion motion{rest, outward, stroke, twist};
  const int max_batch = (n + socket_count - 1) / socket_count;
  std::vector<std::array<uint8_t, vsurg::wire::kMaxDatagram>> tx(static_cast<size_t>(max_batch));
  std::vector<iovec> tx_iov(static_cast<size_t>(max_batch));
  std::vector<mmsghdr> tx_msgs(static_cast<size_t>(max_batch));
  const auto to = server.data();
  const auto to_len = static_cast<socklen_t>(server.size());
  asio::steady_timer timer(io);
  Clock::time_point next = Clock::now();
  const double total = kWarmupS + seconds;
  int slot = 0;
  double cpu_from = -1, wall_from = -1;
  // The measured window holds the datagrams *scheduled* in [warm-up, end): a pacer running late
  // on a loaded machine catches up (at most 20 ms, as a station does) without adding any, and
  // an answer counts when its echoed sequence is one of them.
  std::function<void()> tick = [&] {
    const double t = now_s();
    if (t > total + 0.05) return io.stop();
    const double scheduled = std::chrono::duration<double>(next - start).count();
    if (scheduled >= kWarmupS && cpu_from < 0) cpu_from = ThreadCpuSeconds(), wall_from = t;
    if (scheduled >= total && cpu_from >= 0 && run.driver_wall_s == 0)
      run.driver_cpu_s = ThreadCpuSeconds() - cpu_from, run.driver_wall_s = t - wall_from;
    if (scheduled >= kWarmupS && scheduled < total) {
      const double late_us = (t - scheduled) * 1e6;
      ++run.slots;
      if (late_us > 1000.0 / kSlotsPerMs) ++run.late_slots;
      run.max_late_us = std::max(run.max_late_us, late_us);
    }
    if (scheduled < total) {
      // This slot's stations, socket by socket (a socket's stations share a slot).
      for (int s = slot % socket_count; s < socket_count && s < n; s += slots) {
        int batch = 0;
        for (int k = s; k < n; k += socket_count) {
          if (k % slots != slot) continue;
          Station& st = *stations[k];
          vsurg::wire::StylusMessage msg;
          msg.sample = motion.At(t, k, n);
          msg.sample.time = now_s();
          msg.twist_shape_key = st.twist_shape_key;
          const auto b = static_cast<size_t>(batch);
          const size_t size = codec.EncodeStylus(
              msg,
              {vsurg::wire::kProtocolVersion, vsurg::wire::PayloadType::kStylusState, st.session,
               ++st.sequence},
              st.auth, tx[b]);
          tx_iov[b] = {tx[b].data(), size};
          tx_msgs[b] = {};
          tx_msgs[b].msg_hdr.msg_name = const_cast<sockaddr*>(to);
          tx_msgs[b].msg_hdr.msg_namelen = to_len;
          tx_msgs[b].msg_hdr.msg_iov = &tx_iov[b];
          tx_msgs[b].msg_hdr.msg_iovlen = 1;
          ++batch;
          if (scheduled >= kWarmupS) {
            if (st.first_measured == UINT64_MAX) st.first_measured = st.sequence;
            ++run.sent;  // counted as sent even if the socket refuses it: a loss
          }
        }
        if (batch > 0)
          ::sendmmsg(sockets[static_cast<size_t>(s)]->native_handle(), tx_msgs.data(),
                     static_cast<unsigned>(batch), MSG_DONTWAIT);
      }
    }
    slot = (slot + 1) % slots;
    constexpr auto kSlot = std::chrono::microseconds(1000 / kSlotsPerMs);
    next += kSlot;
    if (const auto late = Clock::now() - next; late > std::chrono::milliseconds(20))
      next += late / kSlot * kSlot;  // fell behind: skip whole slots, no burst
    timer.expires_at(next);
    timer.async_wait([&](auto ec) {
      if (!ec) tick();
    });
  };
  tick();
  io.run();
  std::sort(run.rtt_us.begin(), run.rtt_us.end());
  std::sort(run.arrival_rtt_us.begin(), run.arrival_rtt_us.end());
  return run;
}

}  // namespace

namespace {

void DeclareHapticRtt(ArgParser& p) {
  DeclareStationLoad(
      p,
      "SCHED_FIFO priority of the endpoint's I/O thread and of the stations' thread, when "
      "permitted (vsurg-server's --realtime-priority, default " +
          std::to_string(vsurg::server::EndpointOptions{}.realtime_priority) +
          "; vsurg-station's, default 20)");
  p.Option("scene", ArgParser::Kind::kString, "scene each session runs", false, "arm-torsion")
      .Option("idle", ArgParser::Kind::kInt,
              "sessions that exist but nobody drives (never-started ones)", false, "0")
      .Within({0, 1024})
      .Option("idle-scene", ArgParser::Kind::kString, "their scene", false, "sphere-palpation-256")
      .Option("idle-threads", ArgParser::Kind::kFlag,
              "give idle sessions a running deformation thread, as before the server started "
              "one only for a driven session (for comparison)")
      .Option("dashboard-clients", ArgParser::Kind::kInt,
              "run the server's own stack (store, session manager, web dashboard) and have this "
              "many dashboard clients follow every session live (-1: the bare endpoint)",
              false, "-1")
      .Within({-1, 256})
      .Option("pool-workers", ArgParser::Kind::kInt,
              "driven sessions deform on a pool of this many workers (0: one per core); -1: a "
              "deformation thread per session (vsurg-server's default)",
              false, "-1")
      .Within({-1, 64})
      .Option("io-threads", ArgParser::Kind::kInt,
              "the endpoint's I/O threads, each with a socket on the port (SO_REUSEPORT), "
              "sessions spread over them by id",
              false, "1")
      .Within(vsurg::server::EndpointOptions::kIoThreads)
      .Option("busy-poll-us", ArgParser::Kind::kInt,
              "microseconds the endpoint's I/O threads poll before they sleep, while datagrams "
              "come at least once per window (vsurg-server's --busy-poll-us; 0: never)",
              false, "0")
      .Within(vsurg::server::EndpointOptions::kBusyPollUs)
      .Option("stroke-mm", ArgParser::Kind::kDouble,
              "after the warm-up each stylus circles its resting point at this radius once a "
              "second (0: it rests)",
              false, "0")
      .Within({0, 20})
      .Option("twist-deg", ArgParser::Kind::kDouble,
              "each station grasps the limb in the warm-up and then turns it about its axis by "
              "up to this many degrees, there and back every 2 s (twist scenes; 0: no grasp)",
              false, "0")
      .Within({0, 90})
      .Option("quasi-static-interval-ms", ArgParser::Kind::kDouble,
              "while grasped, a quasi-static model updates at most once per this many milliseconds "
              "(vsurg-server's --quasi-static-interval-ms; 0: every request)",
              false, "8")
      .Within(vsurg::server::SessionManagerOptions::kQuasiStaticIntervalS.Scaled(1e3))
      .Option("visual-hz", ArgParser::Kind::kDouble,
              "the sessions' scene frames per second, sent to the stations (0: none)", false, "60")
      .Option("vertex-frames", ArgParser::Kind::kFlag,
              "the stations say they hold no coil limb, so a twisted limb's frames come as its "
              "moved vertices (as before twist frames; for comparison)")
      .Option("tree-queries", ArgParser::Kind::kFlag,
              "the haptic path's closest-face queries walk the tree every time instead of "
              "answering from kept lists (for comparison)")
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
}

// The server's whole CPU (its I/O, deformation and visual threads) is the process's less the
// driving thread's.
double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  const auto s_of = [](const timeval& tv) {
    return static_cast<double>(tv.tv_sec) + 1e-6 * static_cast<double>(tv.tv_usec);
  };
  return s_of(u.ru_utime) + s_of(u.ru_stime);
}

// One haptic-rtt run: the sessions (bare on the endpoint, or through the server's own stack),
// idle ones beside them, the stations that drive them, and the figures read around the drive.
struct HapticRttRun {
  const ArgParser& p;
  int n = 0, dashboard_clients = -1;
  std::unique_ptr<vsurg::sim::DeformationPool> pool;
  std::vector<std::unique_ptr<vsurg::sim::Simulation>> idle_sims, sims;
  std::unique_ptr<vsurg::server::UdpEndpoint> endpoint;
  std::unique_ptr<ServerStack> stack;
  asio::io_context io;
  std::vector<std::unique_ptr<Station>> stations;

  explicit HapticRttRun(const ArgParser& parsed) : p(parsed) {}

  // Sessions that exist and nobody drives.
  vsurg::Status StartIdle() {
    auto idle_scene = vsurg::sim::LoadSceneByName(p.String("idle-scene"));
    if (!idle_scene.ok()) return vsurg::InvalidArgument("--idle-scene", idle_scene.error().message);
    for (int i = 0; i < p.Int("idle"); ++i) {
      auto sim = vsurg::sim::Simulation::Create(
          *idle_scene,
          {.threaded = true, .start_deformation = p.Flag("idle-threads"), .cache_dir = {}});
      if (!sim.ok()) return sim.error();
      idle_sims.push_back(std::move(*sim));
    }
    return vsurg::Status::Ok();
  }

  // What a vsurg-station with this scene declares (CoilTwistView): the coil limb's key, unless
  // --vertex-frames.
  uint64_t TwistShapeKey(const vsurg::sim::Scene& scene) const {
    if (p.Flag("vertex-frames")) return 0;
    auto mesh = vsurg::sim::BuildSceneMesh(scene.mesh);
    return mesh.ok() ? vsurg::sim::CoilLimbKeyOf(scene, *mesh) : 0;
  }

  // The endpoint and the driven sessions with a station each: through the session manager (its
  // sampler feeding telemetry) and the dashboard, as vsurg-server runs them, or bare.
  vsurg::Status StartDriven(const vsurg::sim::Scene& scene) {
    n = p.Int("stations");
    dashboard_clients = p.Int("dashboard-clients");
    const int pool_workers = p.Int("pool-workers");
    if (pool_workers >= 0) pool = std::make_unique<vsurg::sim::DeformationPool>(pool_workers);
    const double interval_s = 1e-3 * p.Double("quasi-static-interval-ms");
    auto created =
        vsurg::server::UdpEndpoint::Create({.visual_hz = p.Double("visual-hz"),
                                            .realtime_priority = p.Int("realtime-priority"),
                                            .io_threads = p.Int("io-threads"),
                                            .busy_poll_us = p.Int("busy-poll-us")});
    if (!created.ok()) return created.error();
    endpoint = std::move(created).value();
    if (dashboard_clients >= 0) {
      auto made = ServerStack::Start(*endpoint, scene.name, n, pool_workers, interval_s);
      if (!made.ok()) return made.error();
      stack = std::move(made).value();
      for (int i = 0; i < n; ++i)
        stations.push_back(std::make_unique<Station>(stack->ids[i], stack->keys[i]));
      stack->Follow(dashboard_clients);
      const uint64_t shape_key = TwistShapeKey(scene);
      for (auto& st : stations) st->twist_shape_key = shape_key;
      return vsurg::Status::Ok();
    }
    for (int i = 0; i < n; ++i) {
      const vsurg::wire::SessionKey key = BenchKey(i);
      auto sim = vsurg::sim::Simulation::Create(scene, {.threaded = true,
                                                        .start_deformation = true,
                                                        .cache_dir = {},
                                                        .pool = pool.get(),
                                                        .kept_face_lists = !p.Flag("tree-queries"),
                                                        .quasi_static_interval_s = interval_s});
      if (!sim.ok()) return sim.error();
      sims.push_back(std::move(*sim));
      endpoint->AddSession(1000 + i, key, sims.back().get());
      stations.push_back(std::make_unique<Station>(1000 + i, key));
    }
    const uint64_t shape_key = TwistShapeKey(scene);
    for (auto& st : stations) st->twist_shape_key = shape_key;
    return vsurg::Status::Ok();
  }

  uint64_t Deformations() const {
    uint64_t d = 0;
    for (const auto& sim : sims) d += sim->deformation_updates();
    return d;
  }

  // The top of any other scene's surface: of its vertices within a millimetre of the highest, the
  // one nearest the middle of its extent across (a sphere's pole, a block's or a patch's middle).
  static Eigen::Vector3d TopOf(const vsurg::sim::Scene& scene) {
    auto mesh = vsurg::sim::BuildSceneMesh(scene.mesh);
    if (!mesh.ok() || mesh->surface.positions.empty()) return Eigen::Vector3d::Zero();
    const auto& v = mesh->surface.positions;
    Eigen::Vector3d lo = v[0], hi = v[0];
    for (const auto& p : v) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const Eigen::Vector2d middle = 0.5 * (lo + hi).head<2>();
    Eigen::Vector3d best = v[0];
    double best_d = 1e300;
    for (const auto& p : v) {
      const double d = (p.head<2>() - middle).squaredNorm();
      if (p.z() > hi.z() - 1e-3 && d < best_d) best = p, best_d = d;
    }
    return best;
  }

  // The drive, with the server's CPU, deformations and residence read around it. The stylus
  // rests 4 mm inside the limb's side (or the top of another surface): every answer runs the full
  // contact path. It approaches from outside during the warm-up so the proxy enters through the
  // surface.
  nlohmann::json Drive(const vsurg::sim::Scene& scene) {
    const bool limb = scene.mesh.kind == vsurg::sim::MeshKind::kLimb;
    const Eigen::Vector3d rest = limb ? Eigen::Vector3d(scene.mesh.limb.radius_distal - 0.004,
                                                        0.0005, scene.mesh.limb.length - 0.03)
                                      : TopOf(scene) + Eigen::Vector3d(0.0005, 0.0005, -0.004);
    const Eigen::Vector3d outward = limb ? Eigen::Vector3d(1, 0, 0) : Eigen::Vector3d(0, 0, 1);
    const udp::endpoint server(asio::ip::make_address("127.0.0.1"), endpoint->port());
    const double seconds = p.Double("seconds"), cpu0 = endpoint->io_cpu_seconds();
    const vsurg::server::EndpointCounters counters0 = endpoint->counters();
    const double process0 = ProcessCpuSeconds(), own0 = ThreadCpuSeconds();
    const uint64_t deformations0 = Deformations();
    const int priority = p.Int("realtime-priority");
    const bool realtime = priority > 0 && vsurg::TrySetRealtimePriority(priority);  // stations
    RttRun run =
        DriveStations(io, stations, server, rest, outward, seconds, Answer::kForce,
                      p.Int("period-ms"), p.Double("stroke-mm") * 1e-3,
                      p.Double("twist-deg") * std::numbers::pi / 180, p.Int("stations-per-socket"));
    const double cpu = endpoint->io_cpu_seconds() - cpu0;
    const double server_cpu = (ProcessCpuSeconds() - process0) - (ThreadCpuSeconds() - own0);
    const uint64_t deformed = Deformations() - deformations0;
    // The answers' time on the node over the run (warm-up included), from the endpoint's
    // histogram: its quantiles are bucket bounds (EndpointCounters::kResidenceBounds).
    vsurg::server::EndpointCounters residence = endpoint->counters();
    uint64_t timed = 0;
    for (size_t b = 0; b < residence.residence_buckets.size(); ++b) {
      residence.residence_buckets[b] -= counters0.residence_buckets[b];
      timed += residence.residence_buckets[b];
    }
    residence.residence_seconds -= counters0.residence_seconds;
    nlohmann::json j = run.Summary(n, seconds);
    const double span = (kWarmupS + seconds) * n;
    j["server_cpu_per_station"] = cpu / span;
    j["server_process_cpu_per_station"] = server_cpu / span;
    // Per answered datagram, µs: the I/O threads' CPU and the whole node's (every thread but the
    // driver's), over the datagrams the endpoint answered in the same span.
    const double answered = static_cast<double>(residence.answered - counters0.answered);
    j["server_io_cpu_per_datagram_us"] = answered > 0 ? 1e6 * cpu / answered : 0.0;
    j["server_process_cpu_per_datagram_us"] = answered > 0 ? 1e6 * server_cpu / answered : 0.0;
    // Bare sessions only (with --dashboard-clients the session manager holds them): -1 there.
    j["deformations_per_station_s"] = sims.empty() ? -1.0 : static_cast<double>(deformed) / span;
    // The scene frames' traffic to each station, per second of the run.
    j["frame_chunks_per_station_s"] =
        static_cast<double>(residence.frame_chunks - counters0.frame_chunks) / span;
    j["frame_bytes_per_station_s"] =
        static_cast<double>(residence.frame_bytes - counters0.frame_bytes) / span;
    j["server_residence_mean_us"] =
        timed ? 1e6 * residence.residence_seconds / static_cast<double>(timed) : 0.0;
    j["server_residence_p50_le_us"] = 1e6 * residence.ResidenceQuantile(0.5);
    j["server_residence_p99_le_us"] = 1e6 * residence.ResidenceQuantile(0.99);
    j["realtime_priority"] = realtime ? priority : 0;
    return j;
  }

  // The dashboard's figures, then everything stopped.
  void Stop(nlohmann::json& j) {
    uint64_t dashboard_bytes = 0, dashboard_events = 0;
    if (stack) {
      dashboard_bytes = stack->bytes.load();
      dashboard_events = stack->server->counters().events_sent;
      stack->Stop();
    }
    endpoint->Stop();
    j["dashboard_bytes"] = dashboard_bytes;
    j["dashboard_events"] = dashboard_events;
  }

  // What the run was asked for, beside its figures.
  void Settings(nlohmann::json& j, const vsurg::sim::Scene& scene) const {
    const int per_socket = p.Int("stations-per-socket"), period_ms = p.Int("period-ms");
    j["scene"] = scene.name;
    j["twist_deg"] = p.Double("twist-deg");
    j["visual_hz"] = p.Double("visual-hz");
    j["quasi_static_interval_ms"] = p.Double("quasi-static-interval-ms");
    j["idle_sessions"] = p.Int("idle");
    j["idle_threads"] = p.Flag("idle-threads");
    j["dashboard_clients"] = dashboard_clients;
    j["pool_workers"] = pool ? pool->workers() : p.Int("pool-workers");
    j["io_threads"] = endpoint->io_threads();
    j["busy_poll_us"] = p.Int("busy-poll-us");
    j["busy_polled_receives"] = endpoint->counters().busy_polled;
    j["period_ms"] = period_ms;
    j["stations_per_socket"] = per_socket;
    j["station_sockets"] = StationSockets(n, per_socket, kSlotsPerMs * period_ms);
    j["stroke_mm"] = p.Double("stroke-mm");
    j["kept_face_lists"] = !p.Flag("tree-queries");
  }
};

}  // namespace

int HapticRtt(const std::vector<std::string>& args) {
  ArgParser p(
      "vsurg-bench haptic-rtt",
      "Round trip of stylus datagram -> force datagram for N stations at 1 kHz on loopback.");
  DeclareHapticRtt(p);
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  auto scene = vsurg::sim::LoadSceneByName(p.String("scene"));
  if (!scene.ok())
    return std::cerr << p.command() << ": --scene: " << scene.error().message << "\n", 2;
  HapticRttRun r(p);
  if (vsurg::Status s = r.StartIdle(); !s.ok())
    return vsurg::cli::UsageError(std::cerr, p.command(), s.error());
  if (vsurg::Status s = r.StartDriven(*scene); !s.ok())
    return std::cerr << s.error().message << "\n", 1;
  nlohmann::json j = r.Drive(*scene);
  r.Stop(j);
  r.Settings(j, *scene);
  if (p.Flag("json")) {
    std::cout << j.dump() << "\n";
    return 0;
  }
  std::printf(
      "%d stations, %.1f s: rtt p50 %.1f us, p99 %.1f us, p99.9 %.1f us, loss %.4f, server "
      "cpu/station %.4f, idle sessions %d%s, dashboard clients %d (%.1f MB of events)\n",
      r.n, p.Double("seconds"), j["rtt_p50_us"].get<double>(), j["rtt_p99_us"].get<double>(),
      j["rtt_p999_us"].get<double>(), j["loss"].get<double>(),
      j["server_cpu_per_station"].get<double>(), p.Int("idle"),
      p.Flag("idle-threads") ? " (with deformation threads)" : "", r.dashboard_clients,
      static_cast<double>(j["dashboard_bytes"].get<uint64_t>()) / 1e6);
  return 0;
}

int UdpFloor(const std::vector<std::string>& args) {
  ArgParser p("vsurg-bench udp-floor",
              "The bare-UDP floor under haptic-rtt: the same stations, pacing and statistics "
              "against a plain echo on loopback.");
  DeclareStationLoad(p,
                     "SCHED_FIFO priority of the echo thread and of the stations' thread, when "
                     "permitted (as haptic-rtt's)");
  p.Option("busy-poll-us", ArgParser::Kind::kInt,
           "the echo polls this long before it blocks, by haptic-rtt's rule (0: the plain "
           "blocking echo, the floor)",
           false, "0")
      .Within(vsurg::server::EndpointOptions::kBusyPollUs)
      .Option("batch", ArgParser::Kind::kInt,
              "datagrams the echo takes in one recvmmsg and answers in one sendmmsg, as the "
              "server's I/O thread does (1: one recvfrom and one sendto each, the plain echo)",
              false, "1")
      .Within({1, static_cast<double>(UdpEcho::kMaxBatch)})
      .Option("json", ArgParser::Kind::kFlag, "print one JSON object");
  if (auto rc = vsurg::cli::ParseOrExit(p, args, std::cout, std::cerr)) return *rc;
  if (p.Int("batch") > 1 && p.Int("busy-poll-us") > 0)
    return std::cerr << p.command() << ": --busy-poll-us is the plain echo's (--batch 1)\n", 2;
  const int n = p.Int("stations");
  const double seconds = p.Double("seconds");
  const int period_ms = p.Int("period-ms");
  const int per_socket = p.Int("stations-per-socket");
  const int priority = p.Int("realtime-priority");
  const int batch = p.Int("batch");
  auto echo = UdpEcho::Start({.priority = priority,
                              .busy_poll_us = static_cast<int>(p.Int("busy-poll-us")),
                              .batch = batch});
  if (!echo.ok()) return std::cerr << p.command() << ": " << echo.error().message << "\n", 1;
  asio::io_context io;
  std::vector<std::unique_ptr<Station>> stations;
  for (int i = 0; i < n; ++i) stations.push_back(std::make_unique<Station>(1000 + i, BenchKey(i)));
  const bool realtime = priority > 0 && vsurg::TrySetRealtimePriority(priority);  // the stations
  const RttRun run = DriveStations(
      io, stations, udp::endpoint(asio::ip::make_address("127.0.0.1"), (*echo)->port()),
      Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), seconds, Answer::kEcho, period_ms, 0, 0,
      per_socket);
  (*echo)->Stop();
  nlohmann::json j = run.Summary(n, seconds);
  j["server"] = batch > 1 ? "udp-echo-batched" : "udp-echo";
  j["batch"] = batch;
  const double answered = static_cast<double>((*echo)->answered());
  j["server_cpu_per_datagram_us"] = answered > 0 ? 1e6 * (*echo)->cpu_seconds() / answered : 0.0;
  j["datagrams_per_receive"] =
      (*echo)->calls() ? answered / static_cast<double>((*echo)->calls()) : 0.0;
  if (std::vector<double> r = (*echo)->residences_us(); !r.empty()) {
    std::sort(r.begin(), r.end());
    j["echo_residence_p50_us"] = RttRun::Percentile(r, 0.5);
    j["echo_residence_p99_us"] = RttRun::Percentile(r, 0.99);
    // In the node's histogram's terms (haptic-rtt's server_residence_p99_le_us): the bound of the
    // bucket the p99 falls in.
    const auto& bounds = vsurg::server::EndpointCounters::kResidenceBounds;
    const double p99 = 1e-6 * RttRun::Percentile(r, 0.99);
    const auto b = std::lower_bound(bounds.begin(), bounds.end(), p99);
    j["echo_residence_p99_le_us"] = b == bounds.end() ? -1.0 : 1e6 * *b;  // -1: above all
  }
  j["busy_poll_us"] = p.Int("busy-poll-us");
  j["period_ms"] = period_ms;
  j["stations_per_socket"] = per_socket;
  j["station_sockets"] = StationSockets(n, per_socket, kSlotsPerMs * period_ms);
  j["server_cpu_per_station"] = (*echo)->cpu_seconds() / (kWarmupS + seconds) / n;
  j["realtime_priority"] = realtime ? priority : 0;
  if (p.Flag("json")) {
    std::cout << j.dump() << "\n";
  } else {
    std::printf(
        "%d stations, %.1f s, bare UDP echo: rtt p50 %.1f us, p99 %.1f us, p99.9 %.1f us, "
        "loss %.4f\n",
        n, seconds, run.Percentile(0.5), run.Percentile(0.99), run.Percentile(0.999),
        j["loss"].get<double>());
  }
  return 0;
}

}  // namespace vsurg::bench
