#include "bench/png_plot.h"

#include "common/core/image.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>

namespace vsurg::bench {
namespace {

struct Rgb {
  unsigned char r, g, b;
};

constexpr Rgb kPalette[] = {{31, 119, 180},  {255, 127, 14}, {44, 160, 44},   {214, 39, 40},
                            {148, 103, 189}, {140, 86, 75},  {227, 119, 194}, {127, 127, 127},
                            {188, 189, 34},  {23, 190, 207}};

class Canvas {
 public:
  Canvas(int w, int h) : w_(w), h_(h), px_(static_cast<size_t>(w) * h * 3, 255) {}
  void Set(int x, int y, Rgb c) {
    if (x < 0 || y < 0 || x >= w_ || y >= h_) return;
    unsigned char* p = &px_[(static_cast<size_t>(y) * w_ + x) * 3];
    p[0] = c.r, p[1] = c.g, p[2] = c.b;
  }
  void Rect(int x0, int y0, int x1, int y1, Rgb c) {
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) Set(x, y, c);
  }
  void LineTo(double x0, double y0, double x1, double y1, Rgb c, int thick = 1) {
    const int n = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
    for (int i = 0; i <= n; ++i) {
      const double t = static_cast<double>(i) / n;
      const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
      const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
      Rect(x - thick / 2, y - thick / 2, x + (thick - 1) / 2, y + (thick - 1) / 2, c);
    }
  }
  // Text with its top-left at (x, y); returns the width drawn.
  int Text(int x, int y, const std::string& s, Rgb c, int scale = 1) {
    int cx = x;
    for (char ch : s) {
      for (int row = 0; row < 7; ++row)
        for (int col = 0; col < 5; ++col)
          if (GlyphInk(ch, row, col))
            Rect(cx + col * scale, y + row * scale, cx + col * scale + scale - 1,
                 y + row * scale + scale - 1, c);
      cx += 6 * scale;
    }
    return cx - x;
  }
  static int TextWidth(const std::string& s, int scale = 1) {
    return static_cast<int>(s.size()) * 6 * scale;
  }
  const std::vector<unsigned char>& pixels() const { return px_; }

 private:
  int w_, h_;
  std::vector<unsigned char> px_;
};

std::string TickLabel(double v, bool log) {
  char buf[32];
  if (log) {
    const int e = static_cast<int>(std::floor(std::log10(v) + 1e-9));
    if (e >= -4 && e <= 5) {
      std::snprintf(buf, sizeof buf, "%.*f", e < 0 ? -e : 0, v);
    } else {
      std::snprintf(buf, sizeof buf, "%.0fe%d", v / std::pow(10.0, e), e);
    }
  } else {
    std::snprintf(buf, sizeof buf, "%g", v);
  }
  return buf;
}

// Ticks: decades on a log axis; 1-2-5 steps on a linear one.
std::vector<double> Ticks(double lo, double hi, bool log) {
  std::vector<double> t;
  if (log) {
    const int e0 = static_cast<int>(std::floor(std::log10(lo)));
    const int e1 = static_cast<int>(std::ceil(std::log10(hi)));
    for (int e = e0; e <= e1; ++e) {
      t.push_back(std::pow(10.0, e));
      if (e1 - e0 <= 2 && e < e1)  // few decades: 2 and 5 as well
        t.push_back(2 * std::pow(10.0, e)), t.push_back(5 * std::pow(10.0, e));
    }
    return t;
  }
  const double raw = (hi - lo) / 6;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double step = raw / mag < 1.5   ? mag
                      : raw / mag < 3.5 ? 2 * mag
                      : raw / mag < 7.5 ? 5 * mag
                                        : 10 * mag;
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step)
    t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  return t;
}

}  // namespace

Plot::Plot(std::string title, std::string x_label, std::string y_label, bool log_x, bool log_y)
    : title_(std::move(title)),
      x_label_(std::move(x_label)),
      y_label_(std::move(y_label)),
      log_x_(log_x),
      log_y_(log_y) {}

Plot::Series& Plot::At(int series, const std::string& label) {
  if (series >= static_cast<int>(series_.size())) series_.resize(series + 1);
  Series& s = series_[series];
  if (s.label.empty()) s.label = label;
  return s;
}

void Plot::Point(int series, const std::string& label, double x, double y) {
  Series& s = At(series, label);
  s.x.push_back(x);
  s.y.push_back(y);
}

void Plot::Line(int series, const std::string& label, const std::vector<double>& x,
                const std::vector<double>& y) {
  Series& s = At(series, label);
  s.line = true;
  s.x = x;
  s.y = y;
}

Status Plot::WritePng(const std::string& path, int width, int height) const {
  Canvas c(width, height);
  const int left = 80, right = width - 250, top = 50, bottom = height - 60;
  auto ok = [&](double v, bool log) { return std::isfinite(v) && (!log || v > 0); };
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const Series& s : series_)
    for (size_t i = 0; i < s.x.size(); ++i)
      if (ok(s.x[i], log_x_) && ok(s.y[i], log_y_)) {
        x0 = std::min(x0, s.x[i]), x1 = std::max(x1, s.x[i]);
        y0 = std::min(y0, s.y[i]), y1 = std::max(y1, s.y[i]);
      }
  if (x0 > x1) x0 = 1, x1 = 10, y0 = 1, y1 = 10;
  auto widen = [](double& lo, double& hi, bool log) {
    if (log) {
      lo = std::pow(10.0, std::floor(std::log10(lo)));
      hi = std::pow(10.0, std::ceil(std::log10(hi)));
      if (hi <= lo) hi = lo * 10;
    } else {
      const double pad = hi > lo ? 0.05 * (hi - lo) : 1.0;
      lo = lo >= 0 && lo - pad < 0 ? 0 : lo - pad;
      hi += pad;
    }
  };
  widen(x0, x1, log_x_);
  widen(y0, y1, log_y_);
  auto map = [](double v, double lo, double hi, bool log, double a, double b) {
    const double t = log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo))
                         : (v - lo) / (hi - lo);
    return a + t * (b - a);
  };
  const Rgb black{0, 0, 0}, grid{225, 225, 225};
  for (double t : Ticks(x0, x1, log_x_)) {
    if (t < x0 - 1e-12 || t > x1 * (1 + 1e-12)) continue;
    const double px = map(t, x0, x1, log_x_, left, right);
    c.LineTo(px, top, px, bottom, grid);
    const std::string l = TickLabel(t, log_x_);
    c.Text(static_cast<int>(px) - Canvas::TextWidth(l) / 2, bottom + 8, l, black);
  }
  for (double t : Ticks(y0, y1, log_y_)) {
    if (t < y0 - 1e-12 || t > y1 * (1 + 1e-12)) continue;
    const double py = map(t, y0, y1, log_y_, bottom, top);
    c.LineTo(left, py, right, py, grid);
    const std::string l = TickLabel(t, log_y_);
    c.Text(left - 8 - Canvas::TextWidth(l), static_cast<int>(py) - 3, l, black);
  }
  c.LineTo(left, bottom, right, bottom, black);
  c.LineTo(left, top, left, bottom, black);
  c.Text(left, 8, title_, black, 2);
  c.Text((left + right) / 2 - Canvas::TextWidth(x_label_, 2) / 2, bottom + 28, x_label_, black, 2);
  c.Text(8, top - 14, y_label_, black, 1);
  int legend_y = top;
  for (size_t k = 0; k < series_.size(); ++k) {
    const Series& s = series_[k];
    const Rgb col = kPalette[k % std::size(kPalette)];
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!ok(s.x[i], log_x_) || !ok(s.y[i], log_y_)) continue;
      const double px = map(s.x[i], x0, x1, log_x_, left, right);
      const double py = map(s.y[i], y0, y1, log_y_, bottom, top);
      if (s.line) {
        if (i > 0 && ok(s.x[i - 1], log_x_) && ok(s.y[i - 1], log_y_))
          c.LineTo(map(s.x[i - 1], x0, x1, log_x_, left, right),
                   map(s.y[i - 1], y0, y1, log_y_, bottom, top), px, py, col, 2);
      } else {
        c.Rect(static_cast<int>(px) - 3, static_cast<int>(py) - 3, static_cast<int>(px) + 3,
               static_cast<int>(py) + 3, col);
      }
    }
    if (s.label.empty()) continue;
    c.Rect(right + 15, legend_y + 2, right + 27, legend_y + 10, col);
    c.Text(right + 33, legend_y + 2, s.label.substr(0, 34), black);
    legend_y += 16;
  }
  return WriteRgbPng(path, width, height, c.pixels());
}

}  // namespace vsurg::bench
