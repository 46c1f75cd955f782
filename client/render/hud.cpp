#include "client/render/hud.h"

#include <imgui.h>
#include <imgui_freetype.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

namespace vsurg::client {
namespace {

std::string Printf(const char* format, double a, double b = 0, double c = 0) {
  char text[160];
  std::snprintf(text, sizeof text, format, a, b, c);
  return text;
}

const ImU32 kGood = IM_COL32(70, 190, 110, 255), kWarn = IM_COL32(235, 170, 40, 255),
            kBad = IM_COL32(225, 70, 60, 255), kTrack = IM_COL32(255, 255, 255, 38),
            kText = IM_COL32(235, 238, 242, 255);

// A horizontal gauge over [0, full]: a green band [band_lo, band_hi], red beyond `red_from`,
// the value as a bar and a tick, and a caption above it.
void Gauge(const char* caption, const std::string& value_text, double value, double full,
           double band_lo, double band_hi, double red_from, ImU32 bar, float width) {
  ImGui::TextUnformatted(caption);
  ImGui::SameLine();
  const float right = ImGui::GetCursorPosX();
  ImGui::SetCursorPosX(std::max(right, width - ImGui::CalcTextSize(value_text.c_str()).x + 8));
  ImGui::TextUnformatted(value_text.c_str());
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 at = ImGui::GetCursorScreenPos();
  const float h = ImGui::GetFontSize() * 0.75f;
  const auto x = [&](double v) {
    return at.x + width * static_cast<float>(std::clamp(full > 0 ? v / full : 0.0, 0.0, 1.0));
  };
  draw->AddRectFilled(at, ImVec2(at.x + width, at.y + h), kTrack, 3);
  if (band_hi > band_lo)
    draw->AddRectFilled(ImVec2(x(band_lo), at.y), ImVec2(x(band_hi), at.y + h),
                        IM_COL32(70, 190, 110, 70), 2);
  if (red_from < full)
    draw->AddRectFilled(ImVec2(x(red_from), at.y), ImVec2(at.x + width, at.y + h),
                        IM_COL32(225, 70, 60, 70), 2);
  draw->AddRectFilled(ImVec2(at.x, at.y + h * 0.25f), ImVec2(x(value), at.y + h * 0.75f), bar, 2);
  draw->AddLine(ImVec2(x(value), at.y - 2), ImVec2(x(value), at.y + h + 2), kText, 2);
  ImGui::Dummy(ImVec2(width, h + 4));
}

constexpr ImGuiWindowFlags kPanel =
    ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoInputs |
    ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav;

// The status lines, top left: the first as a title, a lost link's line in red.
void StatusPanel(const std::vector<std::string>& lines) {
  // Sized from its text now: an auto-resized window takes its new size a frame late, and a
  // screenshot of the first frame would cut the lines off.
  const ImGuiStyle& style = ImGui::GetStyle();
  float text_w = 0;
  for (const std::string& line : lines)
    text_w = std::max(text_w, ImGui::CalcTextSize(line.c_str()).x);
  const float text_h = static_cast<float>(lines.size()) * ImGui::GetTextLineHeightWithSpacing() +
                       (lines.size() > 1 ? style.ItemSpacing.y : 0);
  ImGui::SetNextWindowPos(ImVec2(10, 10));
  ImGui::SetNextWindowSize(
      ImVec2(text_w + 2 * style.WindowPadding.x, text_h + 2 * style.WindowPadding.y));
  ImGui::SetNextWindowBgAlpha(0.55f);
  ImGui::Begin("status", nullptr, kPanel & ~ImGuiWindowFlags_AlwaysAutoResize);
  for (size_t k = 0; k < lines.size(); ++k) {
    if (k == 0) {
      ImGui::TextColored(ImVec4(0.55f, 0.85f, 1.0f, 1.0f), "%s", lines[k].c_str());
      if (lines.size() > 1) ImGui::Separator();
    } else if (lines[k].rfind("LINK", 0) == 0) {
      ImGui::TextColored(ImVec4(1.0f, 0.45f, 0.35f, 1.0f), "%s", lines[k].c_str());
    } else {
      ImGui::TextUnformatted(lines[k].c_str());
    }
  }
  ImGui::End();
}

// The task's gauges: force against its safe band, the task's quantity against its target, the
// hold.
void TrialGauges(const Guidance& g, float gauge_w) {
  // Force: the safe band up to the task's limit, red beyond, full scale the device's limit.
  const double full_force = std::max({g.device_limit_n, g.force_limit_n * 1.2, 0.5});
  const ImU32 force_colour = g.force_n > g.force_limit_n         ? kBad
                             : g.force_n > 0.8 * g.force_limit_n ? kWarn
                                                                 : kGood;
  Gauge("Force", Printf("%.2f N  (safe below %.1f N)", g.force_n, g.force_limit_n), g.force_n,
        full_force, 0, g.force_limit_n, g.force_limit_n, force_colour, gauge_w);
  if (g.needle) {  // how deep the tip is on its tract; where the target lies is the question
    Gauge("Needle depth", Printf("%.1f mm along the needle", g.current * 1e3), g.current, 0.06, 0,
          0, 0.06, kGood, gauge_w);
    ImGui::Text("Layers punctured: %d", g.passed);
    ImGui::TextUnformatted(g.marks > 0 ? "Confirmed in the target"
                                       : "M or button 2: confirm the tip is in the target");
    ImGui::TextUnformatted("Enter: done");
    return;
  }
  if (g.cut) {  // how far the blade is from the marked line, against the band
    const bool within = g.current <= g.tolerance;
    Gauge("Off the line", Printf("%.1f mm  (band ± %.0f mm)", g.current * 1e3, g.tolerance * 1e3),
          g.current, 3 * g.tolerance, 0, g.tolerance, 3 * g.tolerance, within ? kGood : kWarn,
          gauge_w);
    ImGui::TextUnformatted(g.through ? "Blade: through, cutting" : "Blade: press it through");
    if (g.grasp >= 0)
      ImGui::TextUnformatted(g.grasp ? "Grasper: holding" : "Grasper: open (button 1 grasps)");
    return;
  }
  if (g.palpate) {  // where the lumps are is the question: nothing here gives it away
    ImGui::Text("Lumps marked: %d", g.marks);
    ImGui::TextUnformatted("M or button 2: mark a lump");
    ImGui::TextUnformatted("Enter: the search is done");
    return;
  }
  // The task's quantity against its target band.
  const double scale = g.twist ? 180 / M_PI : 1e3;
  const char* unit = g.twist ? "°" : " mm";
  const double full = std::max(g.target + 3 * g.tolerance, 1.3 * g.target);
  const bool within = std::abs(g.current - g.target) <= g.tolerance;
  const std::string value = Printf("%.1f", g.current * scale) + unit + "  (target " +
                            Printf("%.0f", g.target * scale) + unit + " ± " +
                            Printf("%.0f", g.tolerance * scale) + unit + ")";
  Gauge(g.twist ? "Twist" : "Depth", value, std::abs(g.current), full, g.target - g.tolerance,
        g.target + g.tolerance, full, within ? kGood : kWarn, gauge_w);
  const double hold = g.hold_s > 0 ? std::clamp(g.held_s / g.hold_s, 0.0, 1.0) : 0;
  Gauge("Hold", Printf("%.1f / %.1f s", std::min(g.held_s, g.hold_s), g.hold_s), hold, 1, 0, 0, 1,
        kGood, gauge_w);
}

// The trial's clock and, when there is one, the link's state as a coloured dot.
void TrialClockAndLink(const Guidance& g) {
  const int elapsed = static_cast<int>(g.elapsed_s), limit = static_cast<int>(g.time_limit_s);
  char clock[64];
  std::snprintf(clock, sizeof clock, "Time %d:%02d / %d:%02d", elapsed / 60, elapsed % 60,
                limit / 60, limit % 60);
  ImGui::TextUnformatted(clock);
  if (g.link.empty()) return;
  const ImU32 colour = g.link_level == 0 ? kGood : g.link_level == 1 ? kWarn : kBad;
  const ImVec2 at = ImGui::GetCursorScreenPos();
  const float r = ImGui::GetFontSize() * 0.3f;
  ImGui::GetWindowDrawList()->AddCircleFilled(ImVec2(at.x + r, at.y + ImGui::GetFontSize() * 0.55f),
                                              r, colour);
  ImGui::Dummy(ImVec2(2.5f * r, 1));
  ImGui::SameLine();
  ImGui::Text("Link %s", g.link.c_str());
}

// The trial panel, bottom right, sized from its rows now (three gauges, the time, the link), not
// a frame late.
void TrialPanel(const Guidance& g, int width, int height) {
  const float gauge_w = std::clamp(static_cast<float>(width) * 0.22f, 170.0f, 420.0f);
  ImGui::SetNextWindowPos(ImVec2(static_cast<float>(width) - 10, static_cast<float>(height) - 10),
                          ImGuiCond_Always, ImVec2(1.0f, 1.0f));
  const ImGuiStyle& style = ImGui::GetStyle();
  const float line = ImGui::GetTextLineHeight(), gap = style.ItemSpacing.y;
  const float gauge = line + gap + ImGui::GetFontSize() * 0.75f + 4 + gap;
  const float rows = 3 * gauge + (line + gap) + (g.link.empty() ? 0 : line + gap);
  ImGui::SetNextWindowSize(
      ImVec2(gauge_w + 8 + 2 * style.WindowPadding.x, rows - gap + 2 * style.WindowPadding.y));
  ImGui::SetNextWindowBgAlpha(0.55f);
  ImGui::Begin("trial", nullptr, kPanel & ~ImGuiWindowFlags_AlwaysAutoResize);
  TrialGauges(g, gauge_w);
  TrialClockAndLink(g);
  ImGui::End();
}

// The end-of-trial summary, centred: the score coloured by its band, then the summary's lines.
void SummaryPanel(const TrialSummary& summary, int width, int height) {
  const float w = static_cast<float>(width), h = static_cast<float>(height);
  ImGui::SetNextWindowPos(summary.low ? ImVec2(w * 0.5f, h - 10.0f) : ImVec2(w * 0.5f, h * 0.4f),
                          ImGuiCond_Always, summary.low ? ImVec2(0.5f, 1.0f) : ImVec2(0.5f, 0.5f));
  ImGui::SetNextWindowBgAlpha(0.85f);
  ImGui::Begin("summary", nullptr, kPanel);
  ImGui::TextColored(ImVec4(0.55f, 0.85f, 1.0f, 1.0f), "Trial complete");
  ImGui::Separator();
  const ImVec4 colour = summary.score >= 7   ? ImVec4(0.45f, 0.85f, 0.55f, 1)
                        : summary.score >= 4 ? ImVec4(0.95f, 0.7f, 0.2f, 1)
                                             : ImVec4(0.95f, 0.4f, 0.35f, 1);
  ImGui::SetWindowFontScale(1.8f);
  ImGui::TextColored(colour, "Score %.1f / 10", summary.score);
  ImGui::SetWindowFontScale(1.0f);
  for (const std::string& line : summary.lines) ImGui::BulletText("%s", line.c_str());
  ImGui::End();
}

}  // namespace

struct Hud::Impl {
  ImGuiContext* context = nullptr;
  bool font = false;
  float font_px = 0;
  std::string font_path;
};

std::string Hud::DefaultFontPath() {
  for (const char* p : {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                        "/usr/share/fonts/dejavu/DejaVuSans.ttf"})
    if (std::filesystem::exists(p)) return p;
  return "";
}

Hud::Hud(const std::string& font_path) : impl_(std::make_unique<Impl>()) {
  impl_->font_path = font_path;
  impl_->context = ImGui::CreateContext();
  ImGui::SetCurrentContext(impl_->context);
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini written beside the binary
  io.LogFilename = nullptr;
  ImGui::StyleColorsDark();
  ImGuiStyle& style = ImGui::GetStyle();
  style.WindowRounding = 6;
  style.WindowBorderSize = 0;
  style.WindowPadding = ImVec2(12, 10);
  ImGui_ImplOpenGL3_Init("#version 330 core");
}

Hud::~Hud() {
  ImGui::SetCurrentContext(impl_->context);
  ImGui_ImplOpenGL3_Shutdown();
  ImGui::DestroyContext(impl_->context);
}

bool Hud::font_loaded() const {
  return impl_->font;
}

// The type size follows the window: 17 px at 720 rows; the atlas is built again when it changes.
void Hud::FitFont(int height) {
  ImGuiIO& io = ImGui::GetIO();
  const float px =
      std::round(std::clamp(17.0f * static_cast<float>(height) / 720.0f, 12.0f, 40.0f));
  if (px == impl_->font_px) return;
  impl_->font_px = px;
  io.Fonts->Clear();
  io.Fonts->FontBuilderIO = ImGuiFreeType::GetBuilderForFreeType();
  io.Fonts->FontBuilderFlags = ImGuiFreeTypeBuilderFlags_LightHinting;
  impl_->font = !impl_->font_path.empty() &&
                io.Fonts->AddFontFromFileTTF(impl_->font_path.c_str(), px) != nullptr;
  if (!impl_->font) {
    ImFontConfig config;
    config.SizePixels = px;
    io.Fonts->AddFontDefault(&config);
  }
  ImGui_ImplOpenGL3_DestroyFontsTexture();
  ImGui_ImplOpenGL3_CreateFontsTexture();
}

void Hud::Draw(int width, int height, const std::vector<std::string>& lines, const Guidance& g,
               const TrialSummary& summary) {
  ImGui::SetCurrentContext(impl_->context);
  FitFont(height);
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(static_cast<float>(width), static_cast<float>(height));
  io.DeltaTime = 1.0f / 60.0f;
  ImGui_ImplOpenGL3_NewFrame();
  ImGui::NewFrame();
  if (!lines.empty()) StatusPanel(lines);
  if (g.show) TrialPanel(g, width, height);
  if (summary.show) SummaryPanel(summary, width, height);
  ImGui::Render();
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

}  // namespace vsurg::client
