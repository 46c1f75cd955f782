// The station's heads-up display: Dear ImGui drawn by its OpenGL 3 backend over the scene, text
// in a real typeface (DejaVu Sans rasterised by FreeType through ImGui's FreeType builder).
//
// Panels: the status lines (top left); the trial's gauges (bottom): the force against its safe
// band and the device's limit, the twist or press depth against the target and its tolerance,
// the hold, the time, the link's quality; and at the end a summary with the score and what
// lowered it. Threads: the render thread that owns the GL context (one Hud per context).
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace vsurg::client {

struct Guidance {
  bool show = false;
  bool twist = true;     // a twist task (angles in rad) or a press task (depths in m)
  bool palpate = false;  // a palpation: no target, the marks placed so far instead
  // A needle insertion: `current` is the tip's depth along its tract (m), `passed` the
  // boundaries its tract has punctured; `marks` the confirmations the server took.
  bool needle = false;
  int passed = 0;
  // A cut: `current` is the blade's distance from the marked line (m), `tolerance` the band's
  // half width; `through` the blade is through the tissue; `grasp` the second hand's jaws
  // (-1: no second hand, 0 open, 1 holding).
  bool cut = false, through = false;
  int grasp = -1;
  int marks = 0;
  double target = 0, tolerance = 0, current = 0;
  double held_s = 0, hold_s = 0;  // within tolerance so far, and as long as the task asks
  double force_n = 0, force_limit_n = 0, device_limit_n = 0;  // N
  double elapsed_s = 0, time_limit_s = 0;                     // s
  std::string link;    // the link's figures, e.g. "RTT 2.1 ms, 0.0% lost"
  int link_level = 0;  // 0 good, 1 fair (felt late), 2 too poor for faithful touch
};

struct TrialSummary {
  bool show = false;
  double score = 0;                // 0–10
  std::vector<std::string> lines;  // what lowered the score (or that nothing did)
  bool low = false;  // at the bottom of the view, leaving the tissue clear (findings drawn on it)
};

class Hud {
 public:
  // `font_path`: a TTF; empty or unreadable: ImGui's built-in bitmap font (and font_loaded()
  // says so).
  explicit Hud(const std::string& font_path = DefaultFontPath());
  ~Hud();
  Hud(const Hud&) = delete;
  Hud& operator=(const Hud&) = delete;

  void Draw(int width, int height, const std::vector<std::string>& lines, const Guidance& g,
            const TrialSummary& summary);
  bool font_loaded() const;
  static std::string DefaultFontPath();

 private:
  void FitFont(int height);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vsurg::client
