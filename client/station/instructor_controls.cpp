#include "client/station/instructor_controls.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace vsurg::client {
namespace {

std::vector<std::string_view> Split(std::string_view text, char by) {
  std::vector<std::string_view> out;
  for (size_t start = 0;;) {
    const size_t end = text.find(by, start);
    out.push_back(text.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

std::optional<double> Number(std::string_view text) {
  const std::string s(text);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace

Expected<std::vector<GuideStep>> ParseGuidePlan(std::string_view text) {
  std::vector<GuideStep> plan;
  if (text.empty()) return plan;
  for (std::string_view step : Split(text, ',')) {
    const std::string field = "guide-plan step " + std::to_string(plan.size() + 1);
    const auto parts = Split(step, ':');
    if (parts.size() < 2 || parts.size() > 3)
      return InvalidArgument(
          field, "SECONDS:MODE or SECONDS:guide:ALPHA, not '" + std::string(step) + "'");
    const auto at = Number(parts[0]);
    if (!at || *at < 0 || *at > 86400) return InvalidArgument(field, "seconds live, 0 to 86400");
    if (!plan.empty() && *at < plan.back().at_s)
      return InvalidArgument(field, "the steps' times rise");
    auto mode = sim::ParseGuideMode(parts[1]);
    if (!mode.ok()) return InvalidArgument(field, mode.error().message);
    GuideStep s{*at, {*mode, 0}};
    if (parts.size() == 3) {
      const auto alpha = Number(parts[2]);
      if (!alpha) return InvalidArgument(field, "alpha is a number in [0, 1]");
      s.request.alpha = *alpha;
    }
    if (Status ok = sim::CheckGuideRequest(s.request); !ok.ok())
      return InvalidArgument(field, ok.error().message);
    plan.push_back(s);
  }
  return plan;
}

InstructorControls::InstructorControls(std::vector<GuideStep> plan, double alpha)
    : plan_(std::move(plan)), alpha_(std::clamp(alpha, 0.0, 1.0)) {}

std::optional<sim::GuideRequest> InstructorControls::Next(double live_s, const WindowInput& in) {
  std::optional<sim::GuideRequest> due;
  while (next_step_ < plan_.size() && plan_[next_step_].at_s <= live_s)
    due = plan_[next_step_++].request;  // steps passed together: the last one counts
  const bool pressed = in.command_presses != presses_seen_;
  presses_seen_ = in.command_presses;
  if (due) {
    guiding_ = due->mode == sim::GuideMode::kGuide;
    return due;
  }
  return pressed ? OnKey(in.command) : std::nullopt;
}

std::optional<sim::GuideRequest> InstructorControls::OnKey(char key) {
  using sim::GuideMode;
  switch (key) {
    case 'O':
      guiding_ = false;
      return sim::GuideRequest{GuideMode::kObserve, 0};
    case 'G':
      guiding_ = true;
      return sim::GuideRequest{GuideMode::kGuide, alpha_};
    case 'T':
      guiding_ = true;
      return sim::GuideRequest{GuideMode::kGuide, 1.0};
    case 'H':
      guiding_ = true;
      return sim::GuideRequest{GuideMode::kGuide, 0.0};
    case '[':
    case ']':
      // Tenths, so that repeated presses land on 0 and 1 exactly.
      alpha_ = std::clamp(std::round(10 * alpha_ + (key == ']' ? 1 : -1)) / 10, 0.0, 1.0);
      if (guiding_) return sim::GuideRequest{GuideMode::kGuide, alpha_};
      return std::nullopt;
    default:
      return std::nullopt;
  }
}

}  // namespace vsurg::client
