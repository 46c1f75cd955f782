#include "client/device/device_registry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

namespace vsurg::client {
namespace {

TEST(KeyboardMouseDeviceTest, KeysMoveTheTipDragTwistsAndTheWorkspaceHolds) {
  WindowInput input;
  haptics::DeviceLimits limits = haptics::TouchLimits();
  limits.workspace_min = Eigen::Vector3d(-0.1, -0.1, -0.1);
  limits.workspace_max = Eigen::Vector3d(0.1, 0.1, 0.1);
  ManualClock clock;
  KeyboardMouseDevice device([&] { return input; }, Eigen::Vector3d::Zero(),
                             Eigen::Vector3d::UnitZ(), 0.05, limits, &clock);
  EXPECT_EQ(device.info().output_dof, 0) << "it renders no force, only draws it";
  const haptics::StylusSample rest = device.Read();
  EXPECT_EQ(rest.position, Eigen::Vector3d::Zero());
  EXPECT_EQ(rest.buttons, 0u);

  input.right = input.up = true;  // +x and +z at 5 cm/s
  clock.Advance(0.04);
  const haptics::StylusSample moved = device.Read();
  EXPECT_NEAR(moved.position.x(), 0.05 * 0.04, 1e-12);
  EXPECT_NEAR(moved.position.x(), moved.position.z(), 1e-12);
  EXPECT_EQ(moved.position.y(), 0.0);
  clock.Advance(1.0);  // a stalled loop: one read moves at most 50 ms worth
  EXPECT_NEAR(device.Read().position.x(), 0.05 * 0.04 + 0.05 * 0.05, 1e-12);
  input.right = input.up = false;

  input = {};
  input.twist_rad = 0.5;
  input.grasp = true;
  const haptics::StylusSample twisted = device.Read();
  EXPECT_EQ(twisted.buttons, static_cast<uint32_t>(haptics::kButtonGrasp));
  EXPECT_NEAR(Eigen::AngleAxisd(twisted.orientation).angle(), 0.5, 1e-12);
  EXPECT_NEAR(std::abs(Eigen::AngleAxisd(twisted.orientation).axis().z()), 1.0, 1e-12);

  // Held against the workspace (a fast 1 m/s device): the tip stops at its edge.
  input = {};
  input.forward = true;
  KeyboardMouseDevice fast([&] { return input; }, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(),
                           1.0, limits, &clock);
  for (int i = 0; i < 10; ++i) {
    fast.Read();
    clock.Advance(0.03);
  }
  EXPECT_DOUBLE_EQ(fast.Read().position.y(), 0.1);
  device.WriteForce(Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(device.last_force(), Eigen::Vector3d(1, 2, 3));
}

TEST(ReplayDeviceTest, PerReadStepsOneSampleARealTimeFollowsTheClockAndInterpolates) {
  std::vector<haptics::StylusSample> two(2);
  two[1].time = 1.0;
  two[1].position = Eigen::Vector3d(1, 0, 0);
  two[1].orientation = Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()));
  two[1].buttons = 1;
  ReplayDevice per_read(two);
  EXPECT_EQ(per_read.Read().position.x(), 0.0);
  EXPECT_EQ(per_read.Read().position.x(), 1.0);
  EXPECT_TRUE(per_read.finished());

  ManualClock clock(100.0);
  ReplayDevice real_time(two, haptics::TouchLimits(), ReplayDevice::Pace::kRealTime, &clock);
  EXPECT_EQ(real_time.Read().position.x(), 0.0);  // the clock starts at the first Read
  clock.Advance(0.25);
  const haptics::StylusSample mid = real_time.Read();
  EXPECT_NEAR(mid.position.x(), 0.25, 1e-12);  // 250 ms into the 1 m/s segment, exactly
  EXPECT_NEAR(mid.time, 0.25, 1e-12);
  EXPECT_EQ(mid.buttons, 0u) << "the earlier sample's buttons until the next is due";
  // The orientation is interpolated along with the position: angle = x (1 rad per metre).
  EXPECT_NEAR(Eigen::AngleAxisd(mid.orientation).angle(), 0.25, 1e-9);
  EXPECT_FALSE(real_time.finished());
}

TEST(ServoMailboxTest, TheServoThreadGetsTheNewestForceAndTheStationTheNewestPose) {
  ServoMailbox mailbox;
  haptics::StylusSample s;
  s.position = Eigen::Vector3d(0.01, 0.02, 0.03);
  s.buttons = haptics::kButtonGrasp;
  EXPECT_EQ(mailbox.Exchange(s), Eigen::Vector3d::Zero()) << "no force before the station's first";
  EXPECT_EQ(mailbox.sample().position, s.position);
  mailbox.set_force(Eigen::Vector3d(0, 0, 1.5));
  mailbox.set_force(Eigen::Vector3d(0, 0, 2.0));
  EXPECT_EQ(mailbox.Exchange(s), Eigen::Vector3d(0, 0, 2.0));
  std::thread servo([&] {
    for (int i = 0; i < 10000; ++i) {
      s.position.x() = i;
      (void)mailbox.Exchange(s);
    }
  });
  for (int i = 0; i < 10000; ++i) {
    const double x = mailbox.sample().position.x();
    ASSERT_TRUE(x == 0.01 || (x >= 0 && x < 10000 && x == std::floor(x))) << "torn read " << x;
  }
  servo.join();
}

TEST(DeviceRegistryTest, OpensReplaysAndRefusesWhatItCannotOpen) {
  const std::string path = testing::TempDir() + "/device_test.csv";
  std::ofstream(path)
      << "t,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0.1,1,0,0,0,0\n0.001,0,0,0.099,1,0,0,0,1\n";
  DeviceRequest replay;
  replay.trajectory = path;
  auto device = OpenDevice(replay);
  ASSERT_TRUE(device.ok()) << device.error().message;
  EXPECT_EQ((*device)->info().name, "replay");
  EXPECT_DOUBLE_EQ((*device)->Read().position.z(), 0.1);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // past the last sample (1 ms)
  const haptics::StylusSample last = (*device)->Read();
  EXPECT_DOUBLE_EQ(last.position.z(), 0.099);
  EXPECT_EQ(last.buttons, 1u);

  DeviceRequest missing;
  missing.trajectory = testing::TempDir() + "/no-such.csv";
  EXPECT_FALSE(OpenDevice(missing).ok());
  DeviceRequest no_file;
  EXPECT_EQ(OpenDevice(no_file).error().field, "--trajectory");
  DeviceRequest omni = replay;
  omni.limits = "omni";
  EXPECT_DOUBLE_EQ((*OpenDevice(omni))->limits().max_stiffness,
                   haptics::OmniLimits().max_stiffness);
  omni.limits = "phantom-of-the-opera";
  EXPECT_FALSE(OpenDevice(omni).ok());

  DeviceRequest keyboard;
  keyboard.kind = "keyboard-mouse";
  EXPECT_NE(OpenDevice(keyboard).error().message.find("window"), std::string::npos);
  DeviceRequest unknown;
  unknown.kind = "telepathy";
  EXPECT_EQ(OpenDevice(unknown).error().field, "--device");

  // Real devices without their SDK: a clear error that names the reason, not a crash.
  const auto kinds = AvailableDeviceKinds();
  for (const char* real : {"openhaptics", "falcon"}) {
    DeviceRequest r;
    r.kind = real;
    if (std::find(kinds.begin(), kinds.end(), real) == kinds.end()) {
      const auto opened = OpenDevice(r);
      ASSERT_FALSE(opened.ok());
      EXPECT_EQ(opened.error().code, ErrorCode::kUnavailable);
      EXPECT_NE(opened.error().message.find("DEVICES.md"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace vsurg::client
