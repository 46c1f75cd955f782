// Test-only UDP relay between a station and a server on loopback, with a bad network's habits:
// drop, duplicate, reorder and delay with jitter, independently per direction. Stations send to
// relay.port(); the relay forwards to the server and the answers back to the last station seen.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "proto/wire/asio.h"

namespace vsurg::test {

struct Impairment {
  double drop = 0;          // probability
  double duplicate = 0;     // probability
  double reorder = 0;       // probability a datagram is held until the next one passes
  double max_delay_ms = 0;  // uniform extra delay 0..max
  bool blackhole = false;   // drop everything (toggle at run time)
};

class UdpRelay {
 public:
  UdpRelay(uint16_t server_port, Impairment impairment)
      : front_(io_, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)),
        back_(io_, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)),
        server_(boost::asio::ip::make_address("127.0.0.1"), server_port),
        impairment_(impairment) {
    ReceiveFront();
    ReceiveBack();
    thread_ = std::thread([this] { io_.run(); });
  }
  ~UdpRelay() {
    boost::asio::post(io_, [this] {
      boost::system::error_code ec;
      front_.close(ec);
      back_.close(ec);
      io_.stop();
    });
    thread_.join();
  }
  uint16_t port() const { return front_.local_endpoint().port(); }
  void SetBlackhole(bool on) { blackhole_ = on; }
  uint64_t dropped() const { return dropped_; }
  uint64_t forwarded() const { return forwarded_; }

 private:
  using Buffer = std::shared_ptr<std::vector<uint8_t>>;
  void ReceiveFront() {
    front_.async_receive_from(boost::asio::buffer(front_rx_), station_, [this](auto ec, size_t n) {
      if (ec) return;
      station_known_ = true;
      Forward(std::make_shared<std::vector<uint8_t>>(front_rx_.begin(), front_rx_.begin() + n),
              back_, server_, held_up_);
      ReceiveFront();
    });
  }
  void ReceiveBack() {
    back_.async_receive_from(
        boost::asio::buffer(back_rx_), from_server_, [this](auto ec, size_t n) {
          if (ec) return;
          if (station_known_) {
            Forward(std::make_shared<std::vector<uint8_t>>(back_rx_.begin(), back_rx_.begin() + n),
                    front_, station_, held_down_);
          }
          ReceiveBack();
        });
  }
  void Forward(Buffer b, boost::asio::ip::udp::socket& via, boost::asio::ip::udp::endpoint to,
               Buffer& held) {
    std::uniform_real_distribution<double> u(0, 1);
    if (blackhole_ || u(rng_) < impairment_.drop) {
      ++dropped_;
      return;
    }
    if (!held && u(rng_) < impairment_.reorder) {
      held = b;  // released after the next one: a swap
      return;
    }
    const int copies = u(rng_) < impairment_.duplicate ? 2 : 1;
    for (int c = 0; c < copies; ++c) Send(b, via, to);
    if (held) {
      Send(held, via, to);
      held.reset();
    }
  }
  void Send(Buffer b, boost::asio::ip::udp::socket& via, boost::asio::ip::udp::endpoint to) {
    std::uniform_real_distribution<double> u(0, impairment_.max_delay_ms);
    const double delay = impairment_.max_delay_ms > 0 ? u(rng_) : 0.0;
    ++forwarded_;
    if (delay <= 0) {
      boost::system::error_code ec;
      via.send_to(boost::asio::buffer(*b), to, 0, ec);
      return;
    }
    auto timer = std::make_shared<boost::asio::steady_timer>(io_);
    timer->expires_after(std::chrono::microseconds(static_cast<int64_t>(delay * 1000)));
    timer->async_wait([timer, b, &via, to](auto ec) {
      if (ec) return;
      boost::system::error_code e;
      via.send_to(boost::asio::buffer(*b), to, 0, e);
    });
  }

  boost::asio::io_context io_;
  boost::asio::ip::udp::socket front_, back_;
  boost::asio::ip::udp::endpoint server_, station_, from_server_;
  std::array<uint8_t, 2048> front_rx_{}, back_rx_{};
  Impairment impairment_;
  std::atomic<bool> blackhole_{false}, station_known_{false};
  std::atomic<uint64_t> dropped_{0}, forwarded_{0};
  Buffer held_up_, held_down_;
  std::mt19937_64 rng_{42};
  std::thread thread_;
};

}  // namespace vsurg::test
