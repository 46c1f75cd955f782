#include "common/sim/case_bank.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <random>

#include "common/core/log.h"
#include "common/core/realtime.h"
#include "common/sim/palpation_case.h"
#include "common/sim/simulation.h"
#include "common/tissue/reduced.h"
#include "common/tissue/reduced_cache.h"

namespace vsurg::sim {

CaseBank::CaseBank(Options options) : options_(std::move(options)) {
  thread_ = std::thread([this] {
    NameThisThread("vsurg-cases");
    // Below the haptic and deformation threads: a case built late costs a wait, never a cycle.
    setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
    tissue::SetPrecomputeCancel(&cancel_);  // a stopping bank does not finish a table
    Loop();
  });
}

CaseBank::~CaseBank() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cancel_.store(true);
  changed_.notify_all();
  thread_.join();
}

uint64_t CaseBank::NewSeed() {
  std::random_device device;
  return (static_cast<uint64_t>(device()) << 32) ^ device();
}

std::string CaseBank::CacheDir() const {
  return options_.cache_dir.empty() ? tissue::DefaultCacheDirectory() : options_.cache_dir;
}

void CaseBank::Keep(const Scene& scene) {
  if (!scene.cases) return;
  {
    std::lock_guard lock(mutex_);
    if (kept_.count(scene.name)) return;
    kept_[scene.name] = {scene, Adopt(scene.name)};
  }
  changed_.notify_all();
}

// The cases an earlier process left built in the cache (a restart, or a node's neighbour on one
// machine) are the bank's at once, up to its size; the ones beyond are removed, so the cache holds
// at most the bank's few files per scene however often a server starts. A file whose table no
// longer matches its case (the scene changed since) is found stale when a session loads it and
// rebuilt then. A bank that keeps none leaves the folder alone.
std::deque<uint64_t> CaseBank::Adopt(const std::string& scene_name) const {
  std::deque<uint64_t> out;
  if (options_.ready_per_scene <= 0) return out;
  const std::string prefix = scene_name + ".case-", suffix = "-contact.vrm";
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(CacheDir(), error)) {
    const std::string name = entry.path().filename().string();
    if (name.size() != prefix.size() + 16 + suffix.size() || name.rfind(prefix, 0) != 0 ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    const std::string hex = name.substr(prefix.size(), 16);
    if (hex.find_first_not_of("0123456789abcdef") != std::string::npos) continue;
    const uint64_t seed = std::stoull(hex, nullptr, 16);
    if (static_cast<int>(out.size()) < options_.ready_per_scene) {
      out.push_back(seed);
    } else {
      std::error_code ignored;
      std::filesystem::remove(entry.path(), ignored);
    }
  }
  return out;
}

std::optional<uint64_t> CaseBank::Take(const Scene& scene) {
  if (!scene.cases) return std::nullopt;
  Keep(scene);
  std::optional<uint64_t> seed;
  {
    std::lock_guard lock(mutex_);
    Kept& k = kept_[scene.name];
    if (!k.ready.empty()) {
      seed = k.ready.front();
      k.ready.pop_front();
      ++stats_.taken;
    } else {
      ++stats_.missed;
    }
  }
  changed_.notify_all();
  return seed;
}

void CaseBank::Discard(const std::string& scene_name, uint64_t seed) const {
  std::error_code ignored;  // a file already gone is as good
  std::filesystem::remove(
      std::filesystem::path(CacheDir()) / (CaseName(scene_name, seed) + "-contact.vrm"), ignored);
}

CaseBank::Stats CaseBank::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = stats_;
  s.ready = 0;
  for (const auto& [name, k] : kept_) s.ready += k.ready.size();
  return s;
}

bool CaseBank::WaitReady(double timeout_s) const {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] {
    for (const auto& [name, k] : kept_)
      if (static_cast<int>(k.ready.size()) < options_.ready_per_scene) return false;
    return true;
  });
}

CaseBank::Kept* CaseBank::Short() {
  for (auto& [name, k] : kept_)
    if (static_cast<int>(k.ready.size()) < options_.ready_per_scene) return &k;
  return nullptr;
}

// One case at a time: draw it, build its simulation once (which computes and caches its table),
// and put its seed in the bank. A case that does not build is logged and counted, and another
// seed tried later (a scene that never builds is refused where its sessions are created).
void CaseBank::Loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] { return stop_ || Short() != nullptr; });
    if (stop_) return;
    const Scene scene = Short()->scene;
    lock.unlock();
    const uint64_t seed = NewSeed();
    const auto start = std::chrono::steady_clock::now();
    auto drawn = DrawCase(scene, seed);
    Status built = drawn.ok() ? Status::Ok() : Status(drawn.error());
    if (built.ok()) {
      auto sim = Simulation::Create(*drawn, {.threaded = false, .cache_dir = CacheDir()});
      if (!sim.ok()) built = sim.error();
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    lock.lock();
    if (stop_) return;  // cancelled mid-build, or built as the bank stopped
    if (!built.ok()) {
      ++stats_.failed;
      LogEvent("vsurg-cases", "case_failed",
               {{"scene", scene.name}, {"error", built.error().message}});
      // Not at once again: a scene that cannot build would spin this thread.
      changed_.wait_for(lock, std::chrono::seconds(5), [&] { return stop_; });
      continue;
    }
    auto it = kept_.find(scene.name);
    if (it != kept_.end()) it->second.ready.push_back(seed);
    ++stats_.built;
    stats_.last_build_s = seconds;
    stats_.mean_build_s += (seconds - stats_.mean_build_s) / static_cast<double>(stats_.built);
    changed_.notify_all();
  }
}

}  // namespace vsurg::sim
