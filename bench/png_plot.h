// A small PNG plotter for the study's figures: scatter and line series on linear or log axes,
// a title, axis labels, tick labels and a legend, drawn with a built-in 5×7 bitmap font and
// written as an RGB PNG (zlib deflate). No plotting library needed at run time.
#pragma once

#include <string>
#include <vector>

#include "common/core/expected.h"

namespace vsurg::bench {

class Plot {
 public:
  Plot(std::string title, std::string x_label, std::string y_label, bool log_x, bool log_y);
  // `series` picks the colour (a fixed palette); the first label given for a series is the
  // legend entry. Non-finite or (on log axes) non-positive values are skipped.
  void Point(int series, const std::string& label, double x, double y);
  void Line(int series, const std::string& label, const std::vector<double>& x,
            const std::vector<double>& y);
  Status WritePng(const std::string& path, int width = 960, int height = 600) const;

 private:
  struct Series {
    std::string label;
    std::vector<double> x, y;
    bool line = false;
  };
  std::string title_, x_label_, y_label_;
  bool log_x_, log_y_;
  std::vector<Series> series_;
  Series& At(int series, const std::string& label);
};

}  // namespace vsurg::bench
