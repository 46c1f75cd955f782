// The speed-against-error study (vsurg-bench speed-vs-error; DESIGN.md "Speed against error"):
// what its halves share. bench/study/limb_study.cpp runs the limb scenes, sphere_study.cpp the
// sphere palpation, report.cpp writes the CSV and the Markdown table; bench/speed_vs_error.cpp is
// the command. Scenes, references, markers and the error measure: bench/speed_vs_error.cpp's
// opening comment.
#pragma once

#include <chrono>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/geometry/tet_embedding.h"
#include "common/tissue/fem.h"
#include "common/tissue/mass_spring.h"
#include "common/tissue/torsion_reference.h"

namespace vsurg::bench::study {

using geometry::Vec3;
using Clock = std::chrono::steady_clock;
inline constexpr double kInf = std::numeric_limits<double>::infinity();
// The palpation scenes' press (sphere, kidney): 0.2 N straight down, spread over a 1 cm cap.
inline constexpr double kPressForce = 0.2, kCapRadius = 0.01;  // N, m

struct Row {
  std::string model = "", scene = "", setting = "";
  double time_us = 0, rms = kInf, max = kInf;
  int size = 0;  // particles / vertices / coils
  std::string note = "";
};

struct Trajectory {
  std::string label = "";
  std::vector<double> t = {}, d = {};  // s, m (marker 8's displacement)
};

// A scenes/ file whose own model one of the study's rows reproduces: that row's error against
// the file's own budget.
struct SceneModelCheck {
  std::string file;            // scenes/FILE.json
  std::string model;           // the row's model
  std::string setting_prefix;  // the start of the row's setting
};

struct SceneOut {
  std::string scene;
  std::string scene_file;    // the scenes/ file whose budget applies
  std::string scene_family;  // the model family that file uses
  double budget = 0;
  std::vector<Row> rows;
  std::vector<Trajectory> trajectories;
  std::string chosen;
  std::vector<SceneModelCheck> checks;
};

// A study scene's rows to come, under `scene_file`'s budget and model family.
SceneOut NewSceneOut(std::string scene, std::string scene_file);

// Every scenes/ file against its own budget: one line per file, a failure says so in words.
struct BudgetVerdict {
  std::string file, model, setting;
  double rms = kInf, budget = 0;
  bool in_study = false, meets = false;
};
std::vector<BudgetVerdict> CheckSceneBudgets(const std::vector<SceneOut>& scenes);
std::string BudgetTable(const std::vector<BudgetVerdict>& verdicts);

struct Config {
  bool quick = false;
  int repeats = 9;
};

// A progress bar on stderr.
class Progress {
 public:
  explicit Progress(int total) : total_(total) {}
  void Step(const std::string& what);

 private:
  int total_, done_ = 0;
};

double MedianUs(std::vector<double> v);

template <class F>
double TimeUs(int repeats, F&& f) {
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = Clock::now();
    f(i);
    t.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  }
  return MedianUs(t);
}

// The index of the point nearest to `p`.
int Nearest(const std::vector<Vec3>& points, const Vec3& p);

// Relative marker errors: reference displacement function at a rest point.
using Reference = std::function<Vec3(const Vec3& rest)>;
// A reference FEM's displacement at any rest point, interpolated by the FEM's own shape functions
// (the point embedded in its tetrahedra; outside, the nearest element's nearest point): not the
// nearest node's, whose distance (up to half an element) read as error where the press's
// displacement varies fast.
Reference InterpolatedReference(const geometry::TetMesh& mesh, std::vector<Vec3> displacement);

// Fills row.rms and row.max: marker errors relative to the reference's largest marker
// displacement ("diverged" when a marker is not finite).
void Score(Row& row, const std::vector<Vec3>& rest, const std::vector<Vec3>& now,
           const std::vector<int>& marker_vertices, const Reference& ref);

// 0 → 1 over ramp_s, then 1.
double Ramp(double t, double ramp_s);
// Substeps per 1 ms update that keep an explicit scheme inside its stability limit on the
// stiffest mode ω (rad/s): undamped ω·h < limit; spring damping c = β·k gives that mode a damping
// ratio ζ = β·ω/2, which shrinks the limit to limit·(√(1 + ζ²) − ζ). 1.2× margin; capped at 100
// (a scheme that needs more is run at 100 and reported as it fares).
int Substeps(double omega, double limit, double beta);
// The undamped stability limit on ω·h of an integrator: 2 for symplectic Euler and Verlet, 2√2
// for RK4 (each with a margin: 1.8, 2.5), none for implicit Euler; explicit Euler and the midpoint
// rule grow at any step, and damping holds them at ω·h ≲ 1 (0.5 taken).
double StabilityLimit(tissue::Integrator integrator);

// The error budget and the model family a scenes/ file declares.
std::pair<double, std::string> SceneBudget(const std::string& file);

// A contact table's row (the palpation scenes): the table of `response` over the `reachable`
// vertices of `display` with the press's 1 cm footprint, timed pressing `top` by 0.2 N
// (alternately 0.97 of it), then pressed and scored at `markers` against `reference`; the note
// gives the time since `t0` (what built the response counted) and the table's size. An error
// on the way is the row's note.
void ContactTableRow(const Config& cfg, const Expected<tissue::FemStaticResponse>& response,
                     const geometry::TriMesh& display, const std::vector<int>& reachable,
                     double max_force, int top, const std::vector<int>& markers,
                     const Reference& reference, Clock::time_point t0, Row& row);

// The ten marker vertices on a limb's outer surface `rest` (radius within 2% of the shaft's at
// that z): the nearest to (0, a(z), z) at z = (k − ½)/10 of the length.
std::vector<int> LimbMarkerVertices(const std::vector<Vec3>& rest, const tissue::TaperedShaft& s);

// The sphere scenes' ball (5 cm, G = 12 kPa, ν = 0.45, its bottom cap below z = −0.7·R held):
// its ten markers' vertices among `rest`, the press's nodal forces on its top cap (F straight
// down, spread over the 1 cm cap) and its material.
inline constexpr double kBallRadius = 0.05;  // m
std::vector<int> SphereMarkerVertices(const std::vector<Vec3>& rest);
std::vector<std::pair<int, Vec3>> CapLoad(const geometry::TriMesh& surface, double force);
std::vector<int> BottomCap(const std::vector<Vec3>& rest);
tissue::FemParams BallTissue();

// The halves of the study.
std::vector<SceneOut> RunLimbScenes(const Config& cfg, Progress& progress);  // arm ×2, calf
// The forearm under a hyperelastic law, one scene per law and grasp angle (law_study.cpp).
std::vector<SceneOut> RunArmLaws(const Config& cfg, Progress& progress);
int ArmLawSteps(const Config& cfg);  // the progress steps RunArmLaws takes
// The sphere scenes' ball pressed harder and harder under a hyperelastic law (law_study.cpp).
std::vector<SceneOut> RunBallLaws(const Config& cfg, Progress& progress);
int BallLawSteps(const Config& cfg);
// organ-surface-twist's jaws turned to the task's twist and twice it under each law.
std::vector<SceneOut> RunOrganTwistLaws(const Config& cfg, Progress& progress);
int OrganTwistLawSteps(const Config& cfg);
SceneOut RunSphere(const Config& cfg, Progress& progress);
SceneOut RunOrgan(const Config& cfg, Progress& progress);         // kidney-palpation (imported)
SceneOut RunSurfaceTwist(const Config& cfg, Progress& progress);  // organ-surface-twist
SceneOut RunPad(const Config& cfg, Progress& progress);           // lump-search (a lump)
SceneOut RunPatch(const Config& cfg, Progress& progress);         // pattern-cut (the patch)

// The report.
void ChooseCheapest(SceneOut& s);
std::string Num(double v, int digits = 4);
Status WriteCsv(const std::string& path, const std::vector<SceneOut>& scenes);
std::string MarkdownTable(const std::vector<SceneOut>& scenes, const std::string& command);
// DIR/speed-vs-error.png (time per update against RMS error, log axes, one series per model)
// and DIR/marker8.png (marker 8 during the arm ramp), drawn by gnuplot from data files and
// scripts written beside them (bench/study/figures.cpp).
Status WriteFigures(const std::string& dir, const std::vector<SceneOut>& scenes);
// Replaces the block between the study's markers in a Markdown file (or appends it).
Status UpdateBenchmarks(const std::string& path, const std::string& table);

}  // namespace vsurg::bench::study
