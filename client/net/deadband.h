// The station's perceptual deadband: which stylus samples are worth sending (station_channel.h,
// StationOptions::deadband). Header-only: the device loop calls Due once per servo cycle.
// Units: s, m, rad, N.
#pragma once

#include <algorithm>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/haptics/types.h"

namespace vsurg::client {

// The perceptual deadband (Hinterseer et al., IEEE Trans. Signal Process. 56(2), 2008: a change
// below the Weber fraction of what is felt is not perceived, so it need not be sent; with
// passivity, Xu et al., IEEE ToH 2016). A stylus sample is sent when the force the station
// renders has changed since the last sent sample by more than the fraction k of that force
// (plus 0.02 N, about the force a hand holding a stylus just detects; Israr et al. 2006), when
// the tip has moved more than position_m or turned more than angle_rad (free space, where no
// force tells), when the buttons change, at least every heartbeat_s (contact_heartbeat_s while a
// force is rendered: the server's tissue is driven by the samples it gets, and between two it
// holds the tool where the last one left it), and every cycle over the
// first onset_s of a contact (the force rising from below the 0.02 N floor): there the tissue's
// answer changes faster than any local model the station holds, and one bounce held for a
// heartbeat is felt. Loss-robust: a send the deadband triggered is repeated once 5 ms later if
// nothing else was sent, so one lost datagram costs 5 ms, not a heartbeat. k = 0: every cycle
// is sent.
struct DeadbandParams {
  double k = 0;                        // the Weber fraction; 0: every cycle is sent
  double position_m = 0.5e-3;          // m the tip may move unsent
  double angle_rad = 0.0175;           // rad it may turn unsent
  double onset_s = 0.05;               // s of a contact's start sent every cycle
  double heartbeat_s = 0.025;          // s between sends at most
  double contact_heartbeat_s = 0.025;  // s between sends at most while a force is rendered
};

class Deadband {
 public:
  explicit Deadband(const DeadbandParams& p)
      : k_(p.k),
        position_(p.position_m),
        angle_(p.angle_rad),
        onset_(p.onset_s),
        heartbeat_(p.heartbeat_s),
        contact_heartbeat_(std::min(p.heartbeat_s, p.contact_heartbeat_s)) {}
  // Whether the sample s of this cycle (at now, s, on the station's clock), with the force the
  // station renders, is to be sent; if so it becomes the reference the next cycles compare with.
  bool Due(double now, const haptics::StylusSample& s, const Eigen::Vector3d& force) {
    const bool touching = force.allFinite() && force.norm() > kFloorN;
    if (touching && !touching_) onset_until_ = now + onset_;
    touching_ = touching;
    bool due = k_ <= 0 || !sent_ || s.buttons != buttons_ ||
               now - at_ >= (touching ? contact_heartbeat_ : heartbeat_) ||
               (touching && now < onset_until_);
    bool triggered = false;
    if (!due && s.position.allFinite() && force.allFinite()) {
      triggered = (force - force_).norm() > k_ * force_.norm() + kFloorN ||
                  (s.position - position_sent_).norm() > position_ ||
                  s.orientation.angularDistance(orientation_) > angle_;
      due = triggered || (repeat_at_ >= 0 && now >= repeat_at_);
    }
    if (!due) return false;
    repeat_at_ = k_ > 0 && (triggered || s.buttons != buttons_) ? now + 0.005 : -1;
    sent_ = true;
    at_ = now;
    buttons_ = s.buttons;
    if (s.position.allFinite()) position_sent_ = s.position;
    if (s.orientation.coeffs().allFinite()) orientation_ = s.orientation;
    if (force.allFinite()) force_ = force;
    return true;
  }

 private:
  static constexpr double kFloorN = 0.02;  // N, the least force change a hand detects
  double k_, position_, angle_, onset_, heartbeat_, contact_heartbeat_;
  bool sent_ = false, touching_ = false;
  double onset_until_ = -1;
  double at_ = 0, repeat_at_ = -1;
  uint32_t buttons_ = 0;
  Eigen::Vector3d position_sent_ = Eigen::Vector3d::Zero(), force_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_ = Eigen::Quaterniond::Identity();
};

}  // namespace vsurg::client
