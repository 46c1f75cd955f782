// A bank of palpation cases ready to practise (DESIGN.md "Palpation"): a scene that draws its
// lumps (Scene::cases) needs, for every attempt, a case of its own and that case's contact table,
// precomputed from the case's heterogeneous FEM (seconds: the pad's 19,200 tetrahedra take about
// five). A trainee never waits for one: one background thread keeps a few cases of each kept scene
// built ahead in the reduced models' cache, and a session takes a ready one.
//
// A case is a random 64-bit seed (std::random_device: the operating system's generator), so no
// attempt can be foreseen and the same seed redraws the same case anywhere (DrawCase). Its table
// file is the cache's usual one, named by the case (CaseName); a taken case's file is removed once
// its session has loaded it (Discard), and the cases a bank finds built when it starts keeping a
// scene (an earlier process's) are its own, the ones beyond its size removed: the cache holds only
// the bank's few per scene, never one per attempt or per start.
//
// Threads: Keep, Take, Discard and stats from any control thread; the builder is the bank's own
// thread ("vsurg-cases"), at a lower priority than the node's haptic and deformation threads
// (nice 10), building one case at a time. The destructor stops it within one batch of the table's
// solves (tissue::SetPrecomputeCancel), never after a whole table: a process that is refused at
// start (a second node under a taken name) or shut down exits at once.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "common/sim/scene.h"

namespace vsurg::sim {

class CaseBank {
 public:
  struct Options {
    std::string cache_dir;    // the reduced models' cache ("" the default)
    int ready_per_scene = 2;  // cases kept built ahead for each kept scene
  };
  struct Stats {
    uint64_t built = 0, failed = 0, taken = 0, missed = 0;  // missed: Take found none ready
    double last_build_s = 0, mean_build_s = 0;              // wall time per case built
    size_t ready = 0;                                       // over every kept scene
  };

  explicit CaseBank(Options options);
  ~CaseBank();
  CaseBank(const CaseBank&) = delete;
  CaseBank& operator=(const CaseBank&) = delete;

  // Keeps `scene`'s bank full from now on (a scene without cases is ignored).
  void Keep(const Scene& scene);
  // A ready case of the scene (kept first if it was not): its seed, its table built and cached;
  // nullopt when none is ready yet (the caller draws one itself and builds its table). Either way
  // the bank builds the next.
  std::optional<uint64_t> Take(const Scene& scene);
  // A new seed, from the operating system's generator.
  static uint64_t NewSeed();
  // Removes the cached table of a case whose session has loaded it.
  void Discard(const std::string& scene_name, uint64_t seed) const;
  Stats stats() const;
  // Blocks until every kept scene has its cases ready or `timeout_s` passed (tests, start-up);
  // true when ready.
  bool WaitReady(double timeout_s) const;

 private:
  struct Kept {
    Scene scene;
    std::deque<uint64_t> ready;
  };
  void Loop();
  std::deque<uint64_t> Adopt(const std::string& scene_name) const;
  // The next scene short of cases (under mutex_), or null.
  Kept* Short();
  std::string CacheDir() const;

  Options options_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::map<std::string, Kept> kept_;
  Stats stats_;
  bool stop_ = false;
  std::atomic<bool> cancel_{false};  // the builder's precomputation gives up (stop_, unlocked)
  std::thread thread_;
};

}  // namespace vsurg::sim
