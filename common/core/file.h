// Reading a whole text file (configs, CSV inputs, certificates) into memory, and writing an
// output file so that a reader never sees a partial one.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>

#include "common/core/expected.h"

namespace vsurg {

// kIoError "PATH: cannot open" / "PATH: read failed", `field` naming the input that gave PATH.
Expected<std::string> ReadTextFile(const std::string& path, const std::string& field);

// Writes PATH.part and renames it to PATH on Commit; destroyed uncommitted, it removes the part
// file (an interrupted export leaves no half file behind under the final name).
class AtomicFile {
 public:
  static Expected<AtomicFile> Open(const std::string& path, const std::string& field);
  AtomicFile(AtomicFile&& o) noexcept;
  AtomicFile& operator=(AtomicFile&&) = delete;
  ~AtomicFile();
  bool Write(std::string_view data);  // false once a write failed
  Status Commit();
  uint64_t bytes() const { return bytes_; }

 private:
  AtomicFile(std::string path, std::string field);
  std::string path_, part_, field_;
  std::ofstream out_;
  uint64_t bytes_ = 0;
  bool done_ = false;
};

}  // namespace vsurg
