// The scenes a server offers: the scene folder's *.json files that load, with their summary, and
// the ones that do not with why. Re-reads a file only when its size or modification time changed,
// so listing costs a directory scan, not a parse of every scene per call.
//
// Thread safety: List may be called from any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/trial_metrics.h"

namespace vsurg::server {

struct SceneInfo {
  std::string name;  // the file's stem: what Create and the stations resolve
  std::string description;
  std::string model;  // coil, mass-spring, …
  std::string task;   // twist or press
  double error_budget_rms = 0;
  std::string material;  // how stations draw it: skin, organ, kidney (sim::VisualMaterial)
  bool limb = false;     // a limb along z, lying with +y up (else resting on −z)
  // The task's figures, in the units a trainee reads: the target and its tolerance (degrees of
  // twist, or millimetres of press depth), the force a trainee should stay under (N), the
  // largest force the device renders (N), and the time allowed (s). Plots draw them as lines.
  double target = 0, tolerance = 0;
  double force_limit_n = 0, device_max_force_n = 0, time_limit_s = 0;
  scoring::TaskSpec spec;  // the task as the scene file sets it (SI units)
};

struct SceneListing {
  std::vector<SceneInfo> scenes;      // by name
  std::vector<std::string> unusable;  // "file.json: why", by file name
};

class SceneCatalog {
 public:
  SceneCatalog() = default;  // the server's scene folder, sim::ScenesDirectory(), at each List
  explicit SceneCatalog(std::filesystem::path dir);
  Expected<SceneListing> List();
  uint64_t loads() const;  // scene files parsed so far (tests: unchanged files are not)

 private:
  struct Entry {
    std::filesystem::file_time_type mtime;
    uintmax_t size = 0;
    bool usable = false;
    SceneInfo info;
    std::string why;
  };
  std::filesystem::path dir_;  // empty: sim::ScenesDirectory()
  mutable std::mutex mutex_;
  std::map<std::string, Entry> cache_;  // by full path
  uint64_t loads_ = 0;
};

}  // namespace vsurg::server
