#include "server/domain/scene_catalog.h"

#include <algorithm>
#include <cmath>

#include "common/sim/scene.h"

namespace vsurg::server {

namespace fs = std::filesystem;

SceneCatalog::SceneCatalog(fs::path dir) : dir_(std::move(dir)) {}

uint64_t SceneCatalog::loads() const {
  std::lock_guard lock(mutex_);
  return loads_;
}

Expected<SceneListing> SceneCatalog::List() {
  std::error_code ec;
  std::vector<fs::path> files;
  const fs::path dir = dir_.empty() ? fs::path(sim::ScenesDirectory()) : dir_;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.path().extension() == ".json") files.push_back(entry.path());
  if (ec) return Error{ErrorCode::kUnavailable, "cannot read the scenes folder", "scenes"};
  std::sort(files.begin(), files.end());
  SceneListing out;
  std::lock_guard lock(mutex_);
  std::map<std::string, Entry> next;
  for (const fs::path& file : files) {
    const std::string key = file.string();
    const auto mtime = fs::last_write_time(file, ec);
    const uintmax_t size = ec ? 0 : fs::file_size(file, ec);
    Entry e;
    if (auto it = cache_.find(key);
        !ec && it != cache_.end() && it->second.mtime == mtime && it->second.size == size) {
      e = it->second;
    } else {
      ++loads_;
      e.mtime = mtime;
      e.size = size;
      auto scene = sim::LoadScene(file.string());
      if (scene.ok()) {
        e.usable = true;
        e.info.name = file.stem().string();
        e.info.description = scene->description;
        e.info.model = sim::ModelKindName(scene->region.kind);
        e.info.task = scoring::TaskKindName(scene->task.kind);
        e.info.error_budget_rms = scene->error_budget_rms;
        e.info.material = sim::VisualMaterialName(scene->visual.material);
        e.info.limb = scene->mesh.kind == sim::MeshKind::kLimb;
        const double unit = scoring::DisplayUnitOf(scene->task.kind).per_si;  // rad → °, m → mm
        e.info.target = scene->task.target * unit;
        e.info.tolerance = scene->task.tolerance * unit;
        e.info.force_limit_n = scene->task.force_limit;
        e.info.device_max_force_n = scene->haptics.limits.max_force;
        e.info.time_limit_s = scene->task.time_limit;
        e.info.spec = scene->task;
      } else {
        // Named by its file name: the message's own prefix is the server's full path.
        e.why = scene.error().message;
        if (e.why.rfind(file.string() + ": ", 0) == 0) e.why.erase(0, file.string().size() + 2);
      }
    }
    if (e.usable)
      out.scenes.push_back(e.info);
    else
      out.unusable.push_back(file.filename().string() + ": " + e.why);
    next.emplace(key, std::move(e));
  }
  cache_ = std::move(next);  // files removed from the folder are forgotten
  return out;
}

}  // namespace vsurg::server
