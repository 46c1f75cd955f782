#include "tests/support/power_cut_vfs.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace vsurg::test {
namespace {

PowerCut* g_cut = nullptr;  // the one alive (header: one at a time)
sqlite3_vfs g_vfs;          // the system's VFS with our xOpen and xDelete

// Our file: the system's file after our header. `path` empty: not tracked (temporary files).
struct CutFile {
  sqlite3_file base;
  std::string* path;
  sqlite3_file* real() { return reinterpret_cast<sqlite3_file*>(this + 1); }
};
CutFile* CutOf(sqlite3_file* f) {
  return reinterpret_cast<CutFile*>(f);
}

int CutClose(sqlite3_file* f) {
  CutFile* c = CutOf(f);
  const int rc = c->real()->pMethods->xClose(c->real());
  delete c->path;
  return rc;
}
int CutRead(sqlite3_file* f, void* out, int n, sqlite3_int64 at) {
  return CutOf(f)->real()->pMethods->xRead(CutOf(f)->real(), out, n, at);
}
int CutWrite(sqlite3_file* f, const void* data, int n, sqlite3_int64 at) {
  CutFile* c = CutOf(f);
  if (c->path) {
    if (const int rc = g_cut->OnWrite(*c->path, at, data, n); rc != SQLITE_OK) return rc;
  }
  return c->real()->pMethods->xWrite(c->real(), data, n, at);
}
int CutTruncate(sqlite3_file* f, sqlite3_int64 size) {
  CutFile* c = CutOf(f);
  if (c->path) {
    if (const int rc = g_cut->OnTruncate(*c->path, size); rc != SQLITE_OK) return rc;
  }
  return c->real()->pMethods->xTruncate(c->real(), size);
}
int CutSync(sqlite3_file* f, int /*flags*/) {
  CutFile* c = CutOf(f);
  return c->path ? g_cut->OnSync(*c->path) : SQLITE_OK;  // the image is the disk (header)
}
int CutFileSize(sqlite3_file* f, sqlite3_int64* size) {
  return CutOf(f)->real()->pMethods->xFileSize(CutOf(f)->real(), size);
}
int CutLock(sqlite3_file* f, int level) {
  return CutOf(f)->real()->pMethods->xLock(CutOf(f)->real(), level);
}
int CutUnlock(sqlite3_file* f, int level) {
  return CutOf(f)->real()->pMethods->xUnlock(CutOf(f)->real(), level);
}
int CutCheckReservedLock(sqlite3_file* f, int* out) {
  return CutOf(f)->real()->pMethods->xCheckReservedLock(CutOf(f)->real(), out);
}
int CutFileControl(sqlite3_file* f, int op, void* arg) {
  return CutOf(f)->real()->pMethods->xFileControl(CutOf(f)->real(), op, arg);
}
int CutSectorSize(sqlite3_file* f) {
  return CutOf(f)->real()->pMethods->xSectorSize(CutOf(f)->real());
}
int CutDeviceCharacteristics(sqlite3_file* f) {
  return CutOf(f)->real()->pMethods->xDeviceCharacteristics(CutOf(f)->real());
}
int CutShmMap(sqlite3_file* f, int region, int size, int extend, void volatile** out) {
  return CutOf(f)->real()->pMethods->xShmMap(CutOf(f)->real(), region, size, extend, out);
}
int CutShmLock(sqlite3_file* f, int offset, int n, int flags) {
  return CutOf(f)->real()->pMethods->xShmLock(CutOf(f)->real(), offset, n, flags);
}
void CutShmBarrier(sqlite3_file* f) {
  CutOf(f)->real()->pMethods->xShmBarrier(CutOf(f)->real());
}
int CutShmUnmap(sqlite3_file* f, int remove) {
  return CutOf(f)->real()->pMethods->xShmUnmap(CutOf(f)->real(), remove);
}

// Version 2: shared memory for WAL, and no memory-mapped I/O (every page goes through xRead).
const sqlite3_io_methods kMethods = {2,
                                     CutClose,
                                     CutRead,
                                     CutWrite,
                                     CutTruncate,
                                     CutSync,
                                     CutFileSize,
                                     CutLock,
                                     CutUnlock,
                                     CutCheckReservedLock,
                                     CutFileControl,
                                     CutSectorSize,
                                     CutDeviceCharacteristics,
                                     CutShmMap,
                                     CutShmLock,
                                     CutShmBarrier,
                                     CutShmUnmap,
                                     nullptr,
                                     nullptr};

int CutOpen(sqlite3_vfs*, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  CutFile* c = CutOf(f);
  c->base.pMethods = nullptr;
  c->path = nullptr;
  sqlite3_vfs* base = g_cut->base();
  const int rc = base->xOpen(base, name, c->real(), flags, out_flags);
  if (rc != SQLITE_OK) return rc;
  if (name && (flags & (SQLITE_OPEN_MAIN_DB | SQLITE_OPEN_WAL | SQLITE_OPEN_MAIN_JOURNAL)))
    c->path = new std::string(name);
  c->base.pMethods = &kMethods;
  return SQLITE_OK;
}

int CutDelete(sqlite3_vfs*, const char* name, int sync_dir) {
  g_cut->OnDelete(name);
  return g_cut->base()->xDelete(g_cut->base(), name, sync_dir);
}

}  // namespace

PowerCut::PowerCut(uint64_t cut_at, Loss loss, uint32_t seed)
    : cut_at_(cut_at), loss_(loss), random_(seed) {
  if (g_cut) throw std::logic_error("one PowerCut at a time");
  base_ = sqlite3_vfs_find(nullptr);
  g_vfs = *base_;
  g_vfs.zName = "vsurg-power-cut";
  g_vfs.szOsFile = static_cast<int>(sizeof(CutFile)) + base_->szOsFile;
  g_vfs.xOpen = CutOpen;
  g_vfs.xDelete = CutDelete;
  g_vfs.pNext = nullptr;
  g_cut = this;
  sqlite3_vfs_register(&g_vfs, /*makeDflt=*/1);
}

PowerCut::~PowerCut() {
  sqlite3_vfs_register(base_, 1);
  sqlite3_vfs_unregister(&g_vfs);
  g_cut = nullptr;
}

bool PowerCut::cut() const {
  std::lock_guard lock(mutex_);
  return cut_;
}
uint64_t PowerCut::io_calls() const {
  std::lock_guard lock(mutex_);
  return calls_;
}

bool PowerCut::Tick() {
  if (cut_) return true;
  if (++calls_ == cut_at_) {
    TakeImage();
    cut_ = true;
  }
  return cut_;
}

int PowerCut::OnWrite(const std::string& path, int64_t offset, const void* data, int size) {
  std::lock_guard lock(mutex_);
  if (Tick()) return SQLITE_IOERR_WRITE;
  files_[path].unsynced.push_back(
      {false, offset, std::string(static_cast<const char*>(data), static_cast<size_t>(size))});
  return SQLITE_OK;
}

int PowerCut::OnTruncate(const std::string& path, int64_t size) {
  std::lock_guard lock(mutex_);
  if (Tick()) return SQLITE_IOERR_TRUNCATE;
  files_[path].unsynced.push_back({true, size, {}});
  return SQLITE_OK;
}

int PowerCut::OnSync(const std::string& path) {
  std::lock_guard lock(mutex_);
  if (Tick()) return SQLITE_IOERR_FSYNC;
  File& f = files_[path];
  for (const Op& op : f.unsynced) Apply(f.synced, op);
  f.unsynced.clear();
  return SQLITE_OK;
}

void PowerCut::OnDelete(const std::string& path) {
  std::lock_guard lock(mutex_);
  if (!cut_) files_.erase(path);  // an unlink is taken as durable at once
}

void PowerCut::Apply(std::string& image, const Op& op) {
  const auto at = static_cast<size_t>(op.offset);
  if (op.truncate) {
    image.resize(at);
    return;
  }
  if (image.size() < at + op.data.size()) image.resize(at + op.data.size(), '\0');
  std::memcpy(image.data() + at, op.data.data(), op.data.size());
}

void PowerCut::TakeImage() {
  std::bernoulli_distribution keep(0.5);
  constexpr int64_t kSector = 512;
  for (const auto& [path, f] : files_) {
    std::string image = f.synced;
    for (const Op& op : f.unsynced) {
      switch (loss_) {
        case Loss::kAllUnsynced:
          break;
        case Loss::kNoneLost:
          Apply(image, op);
          break;
        case Loss::kRandomWrites:
          if (keep(random_)) Apply(image, op);
          break;
        case Loss::kTornSectors: {
          if (op.truncate) {
            if (keep(random_)) Apply(image, op);
            break;
          }
          // The write's pieces, cut at the disk's sector boundaries, each kept or not.
          int64_t from = op.offset;
          const int64_t end = op.offset + static_cast<int64_t>(op.data.size());
          while (from < end) {
            const int64_t to = std::min(end, (from / kSector + 1) * kSector);
            if (keep(random_))
              Apply(image, {false, from,
                            op.data.substr(static_cast<size_t>(from - op.offset),
                                           static_cast<size_t>(to - from))});
            from = to;
          }
          break;
        }
      }
    }
    image_[path] = std::move(image);
  }
}

void PowerCut::WriteImage(const std::string& from_dir, const std::string& to_dir) const {
  namespace fs = std::filesystem;
  std::lock_guard lock(mutex_);
  std::map<std::string, std::string> now;
  if (!cut_)
    for (const auto& [path, f] : files_) {
      std::string image = f.synced;
      for (const Op& op : f.unsynced) Apply(image, op);
      now[path] = std::move(image);
    }
  fs::create_directories(to_dir);
  for (const auto& [path, image] : cut_ ? image_ : now) {
    const fs::path p(path);
    if (fs::path(p).parent_path() != fs::path(from_dir)) continue;
    std::ofstream out(fs::path(to_dir) / p.filename(), std::ios::binary | std::ios::trunc);
    out.write(image.data(), static_cast<std::streamsize>(image.size()));
  }
}

}  // namespace vsurg::test
