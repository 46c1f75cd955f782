// vsurg-sim cut --figure DIR: the drill drawn by gnuplot (DIR/cut.png): the patch from above as
// the cut left it (its triangles, the freed piece gone), the marked pattern and its band, the
// blade's cut; beside it the force on the hand over time against the fracture model's f_c and
// f_p. The data files stay in DIR beside the script.
#include "common/cli/cut_figure.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>

namespace vsurg::cli {

namespace fs = std::filesystem;

namespace {

void WriteData(const fs::path& dir, const sim::CutDrillSpec& spec, const sim::CutDrillTrace& t) {
  std::ofstream patch(dir / "patch.dat");
  for (const auto& f : t.faces) {  // closed polygons, mm
    for (int k = 0; k <= 3; ++k) patch << f[k % 3].x() * 1e3 << " " << f[k % 3].y() * 1e3 << "\n";
    patch << "\n";
  }
  std::ofstream cut(dir / "cut.dat");
  for (const auto& s : t.cut)
    cut << s.ax * 1e3 << " " << s.ay * 1e3 << "\n" << s.bx * 1e3 << " " << s.by * 1e3 << "\n\n";
  // The pattern, then the band's two edges (the pattern moved by the band along its normal).
  std::ofstream pattern(dir / "pattern.dat");
  const scoring::CutPattern& p = spec.task.pattern;
  for (double side : {0.0, 1.0, -1.0}) {
    for (int i = 0; i <= 360; ++i) {
      const double u = i / 360.0, e = 1e-4;
      double x = 0, y = 0, xa = 0, ya = 0, xb = 0, yb = 0;
      p.At(u, x, y), p.At(std::max(0.0, u - e), xa, ya), p.At(std::min(1.0, u + e), xb, yb);
      const double tx = xb - xa, ty = yb - ya, tl = std::hypot(tx, ty);
      const double off = side * p.band / tl;
      pattern << (x - off * ty) * 1e3 << " " << (y + off * tx) * 1e3 << "\n";
    }
    pattern << "\n\n";
  }
  std::ofstream force(dir / "force.dat");
  for (const auto& s : t.samples) force << s.t << " " << s.force << " " << s.through << "\n";
}

std::string Script(const sim::CutDrillSpec& spec, const sim::CutDrillResult& r,
                   const std::string& hand) {
  const double band = spec.task.pattern.band * 1e3;
  const double hx = 0.5e3 * spec.tissue.size_x, hy = 0.5e3 * spec.tissue.size_y;
  std::string s =
      "set terminal pngcairo noenhanced size 1200,560 font 'DejaVu Sans,10'\n"
      "set output 'cut.png'\nset multiplot layout 1,2 title '" +
      spec.name + ", " + hand + ": score " + std::to_string(r.metrics.score).substr(0, 4) +
      ", deviation " + std::to_string(r.metrics.deviation_rms * 1e3).substr(0, 4) + " mm RMS, " +
      (r.metrics.completed ? "completed" : "not completed") + "'\n";
  s += "set size ratio -1\nset xrange [" + std::to_string(-hx) + ":" + std::to_string(hx) +
       "]\nset yrange [" + std::to_string(-hy) + ":" + std::to_string(hy) + "]\n";
  s += "set xlabel 'x (mm)'\nset ylabel 'y (mm)'\nset key bottom right opaque\n";
  s += "plot 'patch.dat' with lines lc rgb '#c8a08c' lw 0.6 title 'the patch as cut',"
       " 'pattern.dat' index 0 with lines lc rgb '#3060c0' lw 1.5 dt 2 title 'the marked line',"
       " '' index 1:2 with lines lc rgb '#3060c0' lw 1 title 'its band (±" +
       std::to_string(band).substr(0, 3) +
       " mm)',"
       " 'cut.dat' with lines lc rgb '#b00000' lw 2 title \"the blade's cut\"\n";
  s +=
      "set size noratio\nset autoscale\nset xlabel 'time (s)'\nset ylabel 'force on the hand (N)'\n"
      "set key top right\n";
  s += "plot 'force.dat' using 1:2 with lines lc rgb '#404040' title 'force',"
       " " +
       std::to_string(r.cutting_force) +
       " with lines lc rgb '#b00000' dt 2 title 'f_c = J_c t',"
       " " +
       std::to_string(r.puncture_force) + " with lines lc rgb '#3060c0' dt 3 title 'f_p'\n";
  s += "unset multiplot\n";
  return s;
}

}  // namespace

Status WriteCutFigure(const std::string& dir, const sim::CutDrillSpec& spec,
                      const sim::CutDrillResult& r, const sim::CutDrillTrace& trace,
                      const std::string& hand) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{ErrorCode::kIoError, dir + ": " + ec.message(), "--figure"};
  WriteData(dir, spec, trace);
  std::ofstream(fs::path(dir) / "cut.gp") << Script(spec, r, hand);
  const std::string cmd =
      "cd '" + fs::absolute(dir).string() + "' && gnuplot cut.gp > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0)
    return Error{ErrorCode::kIoError, "gnuplot failed on " + dir + "/cut.gp", "--figure"};
  return Status::Ok();
}

}  // namespace vsurg::cli
