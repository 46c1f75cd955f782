#include "bench/relay/relay.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <thread>

#include <gtest/gtest.h>

namespace vsurg::relay {
namespace {

TEST(ImpairmentTest, TheSameSeedGivesTheSameFates) {
  const Profile p = *ProfileByName("bad-wifi");
  Impairment a(p.up, 7), b(p.up, 7), c(p.up, 8);
  int differ = 0;
  for (int i = 0; i < 5000; ++i) {
    const double t = i * 1e-3;
    const Fate fa = a.Decide(t), fb = b.Decide(t), fc = c.Decide(t);
    ASSERT_EQ(fa.lost, fb.lost);
    ASSERT_EQ(fa.release_s, fb.release_s);
    ASSERT_EQ(fa.copy_release_s.has_value(), fb.copy_release_s.has_value());
    differ += fa.lost != fc.lost || fa.release_s != fc.release_s;
  }
  EXPECT_GT(differ, 1000);  // another seed is another run
}

TEST(ImpairmentTest, GilbertElliottGivesTheMeanRateInBurstsOfTheMeanLength) {
  DirectionParams d;
  BurstLoss(d, 0.02, 4);
  EXPECT_NEAR(d.MeanLoss(), 0.02, 1e-12);
  Impairment imp(d, 3);
  int lost = 0, bursts = 0;
  bool in_burst = false;
  const int n = 400000;
  for (int i = 0; i < n; ++i) {
    const bool l = imp.Decide(i * 1e-3).lost;
    lost += l;
    if (l && !in_burst) ++bursts;
    in_burst = l;
  }
  EXPECT_NEAR(static_cast<double>(lost) / n, 0.02, 0.003);
  EXPECT_NEAR(static_cast<double>(lost) / bursts, 4.0, 0.4);
}

TEST(ImpairmentTest, BurstsLastInTimeNotInDatagramsForASparseFlow) {
  // A station behind the deadband sends every 25 ms: a 4 ms burst must not take four of its
  // datagrams (100 ms) in a row, and the mean rate stays the profile's.
  DirectionParams d;
  BurstLoss(d, 0.02, 4);
  Impairment imp(d, 5);
  int lost = 0, pairs = 0;
  bool previous = false;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const bool l = imp.Decide(i * 0.025).lost;
    lost += l;
    pairs += l && previous;
    previous = l;
  }
  EXPECT_NEAR(static_cast<double>(lost) / n, 0.02, 0.003);
  EXPECT_LT(pairs, lost / 5);  // about independent at 25 ms apart (0.02 of them would be)
}

TEST(ImpairmentTest, JitterWithoutReorderingKeepsTheOrderAndWithItOvertakes) {
  DirectionParams d;
  d.base_ms = 25;
  d.jitter_ms = 3;
  Impairment fifo(d, 1);
  d.reorder = true;
  Impairment loose(d, 1);
  double last_fifo = 0, last_free = 0, sum = 0;
  int overtaken = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double t = i * 1e-3;
    const Fate a = fifo.Decide(t), b = loose.Decide(t);
    ASSERT_GE(a.release_s, last_fifo);
    ASSERT_GE(a.release_s - t, 0.025 - 0.006 - 1e-12);  // ±2σ at most
    overtaken += b.release_s < last_free;
    last_fifo = a.release_s;
    last_free = std::max(last_free, b.release_s);
    sum += b.release_s - t;
  }
  EXPECT_GT(overtaken, n / 4);  // 3 ms σ at 1 ms spacing reorders many
  EXPECT_NEAR(sum / n, 0.025, 0.0003);
}

TEST(ImpairmentTest, AnOutageLosesEverythingInItsWindowOnly) {
  DirectionParams d;
  d.outage_at_s = 1.0;
  d.outage_s = 0.5;
  Impairment imp(d, 1);
  for (int i = 0; i < 3000; ++i) {
    const double t = i * 1e-3;
    const Fate f = imp.Decide(t);
    EXPECT_EQ(f.lost, t >= 1.0 && t < 1.5) << t;
    if (f.lost) {
      EXPECT_EQ(f.why, Fate::Why::kOutage);
    }
  }
}

TEST(ImpairmentTest, UnknownProfilesAreRefusedWithTheKnownOnes) {
  auto p = ProfileByName("moon");
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error().message.find("continental"), std::string::npos);
  for (const char* name :
       {"none", "lan", "metro", "regional", "continental", "intercontinental", "bad-wifi"})
    EXPECT_TRUE(ProfileByName(name).ok()) << name;
}

// A UDP echo server on loopback (the "server" behind the relay).
class Echo {
 public:
  Echo() {
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t n = sizeof a;
    getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
    timeval tv{0, 100000};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    thread_ = std::thread([this] {
      char buf[2048];
      while (!stop_) {
        sockaddr_in from{};
        socklen_t len = sizeof from;
        const ssize_t r =
            recvfrom(fd_, buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &len);
        if (r > 0)
          sendto(fd_, buf, static_cast<size_t>(r), 0, reinterpret_cast<sockaddr*>(&from), len);
      }
    });
  }
  ~Echo() {
    stop_ = true;
    thread_.join();
    close(fd_);
  }
  uint16_t port() const { return port_; }

 private:
  int fd_ = -1;
  uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// A station's socket: sends to the relay on loopback, waits up to `timeout` for an answer.
struct StationSocket {
  StationSocket(uint16_t relay_port, timeval timeout) : fd(socket(AF_INET, SOCK_DGRAM, 0)) {
    to.sin_family = AF_INET;
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    to.sin_port = htons(relay_port);
    Timeout(timeout);
  }
  ~StationSocket() { close(fd); }
  void Timeout(timeval t) { setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof t); }
  ssize_t Send(int v) {
    return sendto(fd, &v, sizeof v, 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
  }
  ssize_t Receive(int& v) { return recv(fd, &v, sizeof v, 0); }
  int fd;
  sockaddr_in to{};
};

TEST(RelayTest, DelaysBothWaysOnLoopbackAndCountsWhatItDid) {
  Echo echo;
  RelayOptions o;
  o.server_port = echo.port();
  o.profile = *ProfileByName("metro");  // 10 ± 1 ms each way
  auto relay = Relay::Start(o);
  ASSERT_TRUE(relay.ok()) << relay.error().message;
  StationSocket station((*relay)->port(), {2, 0});
  int answered = 0;
  double min_rtt = 1e9;
  for (int i = 0; i < 20; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(station.Send(i), static_cast<ssize_t>(sizeof i));
    int back = -1;
    if (station.Receive(back) == static_cast<ssize_t>(sizeof back) && back == i) {
      ++answered;
      min_rtt = std::min(
          min_rtt, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
  }
  EXPECT_EQ(answered, 20);
  EXPECT_GE(min_rtt, 0.016);  // two one-way delays of at least 8 ms (10 − 2σ)
  (*relay)->Stop();
  const RelayStats s = (*relay)->stats();
  EXPECT_EQ(s.up.received, 20u);
  EXPECT_EQ(s.up.forwarded, 20u);
  EXPECT_EQ(s.down.forwarded, 20u);
  EXPECT_NEAR(s.up.mean_delay_ms, 10, 1.5);
  EXPECT_EQ(s.flows, 1u);
}

TEST(RelayTest, ABlackholeLosesEverythingUntilLifted) {
  Echo echo;
  RelayOptions o;
  o.server_port = echo.port();
  o.profile = *ProfileByName("none");
  auto relay = Relay::Start(o);
  ASSERT_TRUE(relay.ok());
  (*relay)->SetBlackhole(true);
  StationSocket station((*relay)->port(), {0, 200000});
  int back = 0;
  station.Send(1);
  EXPECT_LT(station.Receive(back), 0);
  (*relay)->SetBlackhole(false);
  station.Timeout({2, 0});
  station.Send(1);
  EXPECT_EQ(station.Receive(back), static_cast<ssize_t>(sizeof back));
  EXPECT_EQ((*relay)->stats().up.lost_outage, 1u);
}

TEST(RelayTest, BadAddressesAreRefusedWithTheField) {
  RelayOptions o;
  o.server_host = "not-an-address";
  o.server_port = 9;
  auto r = Relay::Start(o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().field, "server");
  o.server_host = "127.0.0.1";
  o.server_port = 0;
  EXPECT_FALSE(Relay::Start(o).ok());
}

}  // namespace
}  // namespace vsurg::relay
