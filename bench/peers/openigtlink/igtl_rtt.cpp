// OpenIGTLink's round trip, paced and measured as `vsurg-bench haptic-rtt` paces and measures
// ours, for the side-by-side table of bench/peers/rtt.sh (our harness; OpenIGTLink itself is
// built from its own checkout, outside this repository).
//
// N clients each send a TRANSFORM message (the stylus pose) every millisecond, spread over the
// millisecond in 8 slots of 125 µs as haptic-rtt spreads its stations. The server, one thread per
// connection as OpenIGTLink's examples serve, receives the header and the body with its CRC
// checked, reads the matrix, and answers with a TRANSFORM (the force) that carries the request's
// time stamp; the client takes the round trip from it. TCP_NODELAY is set by OpenIGTLink on its
// sockets. Statistics as haptic-rtt's: round trips of requests sent after a 0.5 s warm-up, p50,
// p99, p99.9, loss = 1 − received/sent. Prints one JSON object with haptic-rtt's keys.
//
//   igtl_rtt --stations N --seconds S
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "igtlClientSocket.h"
#include "igtlMessageHeader.h"
#include "igtlServerSocket.h"
#include "igtlTimeStamp.h"
#include "igtlTransformMessage.h"

namespace {

using Clock = std::chrono::steady_clock;
Clock::time_point g_start;  // set once every connection is up, before the readers start
constexpr double kWarmupS = 0.5;
constexpr int kSlots = 8;

double NowS() {
  return std::chrono::duration<double>(Clock::now() - g_start).count();
}

// Receives one whole message header from `socket`; false when the peer closed.
bool ReceiveHeader(igtl::Socket* socket, igtl::MessageHeader* header) {
  header->InitPack();
  bool timeout = false;
  const igtlUint64 got = socket->Receive(header->GetPackPointer(), header->GetPackSize(), timeout);
  if (got != header->GetPackSize()) return false;
  header->Unpack();
  return true;
}

// One connection on the server: each TRANSFORM answered with a TRANSFORM stamped as it was.
void Serve(igtl::ClientSocket::Pointer socket) {
  auto header = igtl::MessageHeader::New();
  auto request = igtl::TransformMessage::New();
  auto reply = igtl::TransformMessage::New();
  reply->SetDeviceName("Force");
  auto stamp = igtl::TimeStamp::New();
  while (ReceiveHeader(socket, header)) {
    if (std::strcmp(header->GetDeviceName(), "Stop") == 0) break;  // the client is done
    if (std::strcmp(header->GetDeviceType(), "TRANSFORM") != 0) {
      socket->Skip(header->GetBodySizeToRead(), 0);
      continue;
    }
    request->SetMessageHeader(header);
    request->AllocatePack();
    bool timeout = false;
    if (socket->Receive(request->GetPackBodyPointer(), request->GetPackBodySize(), timeout) !=
        request->GetPackBodySize())
      break;
    if (!(request->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) continue;  // CRC failed
    igtl::Matrix4x4 pose, force;
    request->GetMatrix(pose);
    igtl::IdentityMatrix(force);
    for (int i = 0; i < 3; ++i) force[i][3] = -0.1f * pose[i][3];  // a spring toward the origin
    header->GetTimeStamp(stamp);
    reply->SetMatrix(force);
    reply->SetTimeStamp(stamp);
    reply->Pack();
    if (socket->Send(reply->GetPackPointer(), reply->GetPackSize()) == 0) break;
  }
  socket->CloseSocket();
}

struct Client {
  igtl::ClientSocket::Pointer socket = igtl::ClientSocket::New();
  igtl::TransformMessage::Pointer message = igtl::TransformMessage::New();
  std::vector<double> rtt_us;
  uint64_t sent = 0, received = 0;
  std::thread reader;
};

// A client's answers: the round trip of each, from the time stamp its request carried.
void Read(Client* c) {
  auto header = igtl::MessageHeader::New();
  auto reply = igtl::TransformMessage::New();
  auto stamp = igtl::TimeStamp::New();
  while (ReceiveHeader(c->socket, header)) {
    reply->SetMessageHeader(header);
    reply->AllocatePack();
    bool timeout = false;
    if (c->socket->Receive(reply->GetPackBodyPointer(), reply->GetPackBodySize(), timeout) !=
        reply->GetPackBodySize())
      break;
    if (!(reply->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) continue;
    header->GetTimeStamp(stamp);
    const double sent_s = static_cast<double>(stamp->GetTimeStampInNanoseconds()) * 1e-9;
    if (sent_s >= kWarmupS) {
      ++c->received;
      c->rtt_us.push_back((NowS() - sent_s) * 1e6);
    }
  }
}

// The pacing: as haptic-rtt's, slot k of 8 every 125 µs, each client's pose request in its slot
// until the warm-up and the measured seconds are over.
void Pace(std::vector<std::unique_ptr<Client>>& clients, int n, double seconds) {
  auto stamp = igtl::TimeStamp::New();
  const double total = kWarmupS + seconds;
  Clock::time_point next = Clock::now();
  for (int slot = 0;; slot = (slot + 1) % kSlots) {
    const double t = NowS();
    if (t > total) break;
    for (int k = slot; k < n; k += kSlots) {
      Client& c = *clients[static_cast<size_t>(k)];
      igtl::Matrix4x4 pose;
      igtl::IdentityMatrix(pose);
      pose[0][3] = 0.02f;  // m
      pose[1][3] = 0.0005f;
      pose[2][3] = 0.1f;
      c.message->SetMatrix(pose);
      const double now = NowS();
      stamp->SetTimeInNanoseconds(static_cast<igtlUint64>(now * 1e9));
      c.message->SetTimeStamp(stamp);
      c.message->Pack();
      if (c.socket->Send(c.message->GetPackPointer(), c.message->GetPackSize()) != 0 &&
          now >= kWarmupS)
        ++c.sent;
    }
    next += std::chrono::microseconds(1000 / kSlots);
    std::this_thread::sleep_until(next);
  }
}

// One JSON line: requests sent and answered after the warm-up, the loss, the round trip's
// percentiles over every client.
void Report(const std::vector<std::unique_ptr<Client>>& clients, int n, double seconds) {
  std::vector<double> rtt;
  uint64_t sent = 0, received = 0;
  for (auto& c : clients) {
    sent += c->sent;
    received += c->received;
    rtt.insert(rtt.end(), c->rtt_us.begin(), c->rtt_us.end());
  }
  std::sort(rtt.begin(), rtt.end());
  auto pct = [&](double q) {
    return rtt.empty() ? 0.0 : rtt[std::min(rtt.size() - 1, static_cast<size_t>(q * rtt.size()))];
  };
  const double loss =
      sent ? std::max(0.0, 1.0 - static_cast<double>(received) / static_cast<double>(sent)) : 0.0;
  std::printf(
      "{\"stations\":%d,\"seconds\":%g,\"server\":\"openigtlink\",\"sent\":%llu,\"received\":%llu,"
      "\"loss\":%g,\"rtt_p50_us\":%.3f,\"rtt_p99_us\":%.3f,\"rtt_p999_us\":%.3f}\n",
      n, seconds, static_cast<unsigned long long>(sent), static_cast<unsigned long long>(received),
      loss, pct(0.5), pct(0.99), pct(0.999));
}

int Usage() {
  std::fprintf(stderr, "usage: igtl_rtt --stations N --seconds S\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  int n = 1;
  double seconds = 10;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return Usage();
    if (a == "--stations") {
      n = std::atoi(argv[++i]);
    } else if (a == "--seconds") {
      seconds = std::atof(argv[++i]);
    } else {
      return Usage();
    }
  }
  if (n < 1 || n > 1024 || !(seconds > 0 && seconds <= 3600)) return Usage();

  auto server = igtl::ServerSocket::New();
  if (server->CreateServer(0) < 0 || server->GetServerPort() <= 0) {
    std::fprintf(stderr, "igtl_rtt: cannot create the server socket\n");
    return 1;
  }
  const int port = server->GetServerPort();
  std::vector<std::thread> served;
  std::thread acceptor([&] {
    while (static_cast<int>(served.size()) < n) {
      igtl::ClientSocket::Pointer s = server->WaitForConnection(1000);
      if (s.IsNotNull()) served.emplace_back(Serve, s);
    }
  });
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < n; ++i) {
    auto c = std::make_unique<Client>();
    if (c->socket->ConnectToServer("127.0.0.1", port) != 0) {
      std::fprintf(stderr, "igtl_rtt: client %d cannot connect\n", i);
      return 1;
    }
    c->message->SetDeviceName("Stylus");
    c->rtt_us.reserve(static_cast<size_t>(seconds * 1100));
    clients.push_back(std::move(c));
  }
  acceptor.join();  // (OpenIGTLink accepts slowly: seconds for tens of connections)
  g_start = Clock::now();
  for (auto& c : clients) c->reader = std::thread(Read, c.get());

  Pace(clients, n, seconds);
  // Done: each client says so after its last request; its server thread then closes the
  // connection, which ends the client's reader once the last answers are in.
  for (auto& c : clients) {
    auto stop = igtl::TransformMessage::New();
    stop->SetDeviceName("Stop");
    stop->Pack();
    c->socket->Send(stop->GetPackPointer(), stop->GetPackSize());
  }
  for (auto& c : clients) {
    if (c->reader.joinable()) c->reader.join();
    c->socket->CloseSocket();
  }
  for (auto& t : served) t.join();
  Report(clients, n, seconds);
  return 0;
}
