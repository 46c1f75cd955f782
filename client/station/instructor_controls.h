// An instructor's station's switches of four-handed training's mode (common/sim/guidance.h):
// scripted by seconds live (vsurg-station --guide-plan, for demonstrations and tests) and from the
// station window's keys:
//   O observe    G guide at the dominance α    T take over (α = 1)    H hand back (α = 0)
//   [ and ]  α down and up by 0.1 (sent at once while guiding)
// Plain data and a small state machine: no OpenGL, no network (Station::RequestGuide sends).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "client/device/window_input.h"
#include "common/core/expected.h"
#include "common/sim/guidance.h"

namespace vsurg::client {

struct GuideStep {
  double at_s = 0;  // seconds live
  sim::GuideRequest request;
};
// "SECONDS:MODE[:ALPHA],…" with MODE observe, guide or none (leave), α only with guide, the
// times rising: "2:guide:0.5,5:guide:1,8:guide:0". kInvalidArgument naming the step otherwise.
Expected<std::vector<GuideStep>> ParseGuidePlan(std::string_view text);

class InstructorControls {
 public:
  InstructorControls(std::vector<GuideStep> plan, double alpha);
  // Once per frame: what to ask for now, if anything (a scripted step now due, else a key
  // pressed since the frame before).
  std::optional<sim::GuideRequest> Next(double live_s, const WindowInput& in);
  double alpha() const { return alpha_; }  // what G asks for
  // The keys, for the station's HUD.
  static constexpr std::string_view kHelp =
      "keys: O observe  G guide  T take over  H hand back  [ ] alpha";

 private:
  std::optional<sim::GuideRequest> OnKey(char key);

  std::vector<GuideStep> plan_;
  size_t next_step_ = 0;
  double alpha_ = 0.5;
  bool guiding_ = false;
  uint32_t presses_seen_ = 0;
};

}  // namespace vsurg::client
