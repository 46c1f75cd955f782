// A simulated operator and device: the replay device with the loop closed. A trainee's plan (a
// scripted trajectory) is what the hand *intends*; the hand reaches for it through its own
// impedance, and the force the station renders pushes it back, so delay, loss and poor local
// models show up as what a person would feel and do: sinking into tissue, buzz, a kick.
//
// Per axis, the hand (mass m_h) and the device's moving parts (apparent mass m_d) move together:
//   (m_h + m_d)·ẍ = K_h·(x_plan − x) + B_h·(ẋ_plan − ẋ) + F_device − F_friction(ẋ)
// K_h, B_h: the grip's stiffness and damping about the intended path (an equilibrium-point
// controller: the muscles pull toward the plan like a spring and damper, Feldman 1986; Hogan
// 1985). F_device is the force the station wrote, held over the servo interval (zero-order
// hold, the device's own saturation applied). F_friction: Coulomb, smoothed over 2 mm/s.
// Integrated with semi-implicit Euler in `substeps` steps per servo period (the hand and device
// modes are ≤ 60 rad/s: 10 steps of 0.1 ms are far inside stability). The stylus reading is
// quantised to the encoder's resolution; orientation and buttons follow the plan (a 3-DoF
// output device renders no torque).
//
// Values, SI:
//   relaxed grip: m_h 0.55 kg, B_h 6.5 N·s/m, K_h 135 N/m — one participant's fit of the arm
//     holding a haptic device's end effector (van Beek et al., Sci Rep 5:18004, 2015, Fig. 3:
//     M 0.554 kg, B 6.45 N·s/m, K 135 N/m);
//   tensed grip: K_h 540 N/m, B_h 13 N·s/m, the same mass — stiffness and damping rise with grip
//     force and co-contraction (Hasser & Cutkosky 2002; Fu & Çavuşoğlu, IEEE TSMC-B 42(5), 2012,
//     over 1–3 N grips); the factors 4 and 2 are our choice of a firm grip, not a measurement;
//   Touch-class device: apparent mass at the tip 45 g, backdrive friction 0.26 N, encoder
//     resolution 0.055 mm (> 450 dpi), force limits haptics::TouchLimits() (3D Systems Touch
//     specification).
// Time is the device's own: each Read advances it by one servo period (1/rate_hz), so a run is
// the same whatever the machine's load (the network, in real time, is not).
//
// Threads: Read and WriteForce from the station's device thread; trace() from any thread.
#pragma once

#include <mutex>
#include <vector>

#include "client/device/device.h"
#include "common/core/expected.h"

namespace vsurg::client {

struct HandImpedance {
  double mass = 0.55;      // kg
  double damping = 6.5;    // N·s/m
  double stiffness = 135;  // N/m
};
HandImpedance RelaxedGrip();
HandImpedance TensedGrip();
Expected<HandImpedance> GripByName(const std::string& name);  // "relaxed" or "tensed"

struct DeviceModel {
  double mass = 0.045;           // kg, apparent at the tip
  double friction = 0.26;        // N, Coulomb
  double resolution = 0.055e-3;  // m per encoder count (0: exact)
  haptics::DeviceLimits limits = haptics::TouchLimits();
};

// One servo cycle as the hand lived it.
struct HandSample {
  double t = 0;                                     // s, device time at the Read
  Eigen::Vector3d x = Eigen::Vector3d::Zero();      // m, the true position
  Eigen::Vector3d plan = Eigen::Vector3d::Zero();   // m, where the hand meant to be
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N, held over the interval after t
  uint32_t buttons = 0;
};

class VirtualHandDevice : public HapticDevice {
 public:
  // `plan` at a fixed rate (ScriptedTrainee's, or a recording); past its end the hand holds the
  // last pose. Fails on an empty plan or non-positive parameters.
  static Expected<std::unique_ptr<VirtualHandDevice>> Create(
      std::vector<haptics::StylusSample> plan, HandImpedance hand = RelaxedGrip(),
      DeviceModel device = {}, double rate_hz = 1000, int substeps = 10);

  haptics::StylusSample Read() override;
  void WriteForce(const Eigen::Vector3d& force) override;
  haptics::DeviceLimits limits() const override { return device_.limits; }
  DeviceInfo info() const override { return {"virtual-hand", 6, 3, device_.limits, rate_hz_}; }

  // The hand's intent moved by `offset` (m) from its plan from now on: a hand correcting what it
  // sees (an instructor putting a shared tool back on the path). Any thread.
  void Correct(const Eigen::Vector3d& offset);

  bool finished() const;                  // the plan has been played out
  std::vector<HandSample> trace() const;  // every cycle so far
  size_t cycles() const;                  // how many: trace().size() without the copy
  double plan_duration() const;

 private:
  VirtualHandDevice(std::vector<haptics::StylusSample> plan, HandImpedance hand, DeviceModel device,
                    double rate_hz, int substeps);
  haptics::StylusSample PlanAt(double t) const;  // interpolated

  std::vector<haptics::StylusSample> plan_;
  HandImpedance hand_;
  DeviceModel device_;
  double rate_hz_;
  int substeps_;
  mutable std::mutex mutex_;  // guards the trace and the cursor for readers
  double t_ = 0;
  bool started_ = false;
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero(), v_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d held_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();  // Correct's
  std::vector<HandSample> trace_;
};

}  // namespace vsurg::client
