// A power cut for SQLite, the way SQLite's own crash tests model one: an SQLite VFS over the
// system's that keeps, for every database and WAL file, what is on the platter (the bytes as of
// the file's last sync) apart from what is only in the page cache (every write and truncation
// since). At a chosen I/O call the power goes: the disk image is what was synced plus some of
// what was not (none, all, a random subset of the writes, or of their 512-byte sectors: a torn
// write), and from then on every write and sync fails, as a process with no power would not get
// to make them. The image can then be written out and opened as the machine would find it.
//
// The real files are only the page cache's stand-in: a sync does not reach the disk (there is no
// need; the image is kept here), so a test of many crash points stays fast.
//
// Test-only. One PowerCut at a time in a process: it registers itself as SQLite's default VFS
// while it lives (every connection opened meanwhile goes through it) and gives the system's back
// when it goes.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <vector>

struct sqlite3_vfs;

namespace vsurg::test {

class PowerCut {
 public:
  enum class Loss {
    kAllUnsynced,   // nothing written since the last sync survives
    kNoneLost,      // everything written survives (a killed process: the page cache is kept)
    kRandomWrites,  // each unsynced write survives or not, in order
    kTornSectors,   // each 512-byte sector of each unsynced write survives or not
  };

  // The power goes at the `cut_at`-th write, sync or truncation (1-based; 0: never).
  PowerCut(uint64_t cut_at, Loss loss, uint32_t seed);
  ~PowerCut();
  PowerCut(const PowerCut&) = delete;
  PowerCut& operator=(const PowerCut&) = delete;

  bool cut() const;
  uint64_t io_calls() const;  // writes, syncs and truncations seen so far
  // Writes the disk image of every file the store had under `from_dir` into `to_dir`, under the
  // same names (the power cut's if there was one, else the files as synced and written now).
  void WriteImage(const std::string& from_dir, const std::string& to_dir) const;

  // What the VFS's files report to it (public for its C callbacks).
  struct Op {
    bool truncate = false;
    int64_t offset = 0;  // a write's offset, a truncation's size
    std::string data;
  };
  struct File {
    std::string synced;        // what a sync has made durable
    std::vector<Op> unsynced;  // since, in order
  };
  int OnWrite(const std::string& path, int64_t offset, const void* data, int size);
  int OnTruncate(const std::string& path, int64_t size);
  int OnSync(const std::string& path);
  void OnDelete(const std::string& path);
  sqlite3_vfs* base() const { return base_; }

 private:
  // Counts one I/O call; true when the power is (now) out.
  bool Tick();
  void TakeImage();
  static void Apply(std::string& image, const Op& op);

  const uint64_t cut_at_;
  const Loss loss_;
  std::mt19937 random_;
  sqlite3_vfs* base_ = nullptr;
  mutable std::mutex mutex_;
  uint64_t calls_ = 0;
  bool cut_ = false;
  std::map<std::string, File> files_;         // by full path
  std::map<std::string, std::string> image_;  // at the cut
};

}  // namespace vsurg::test
