#include "common/core/file.h"

#include <cstdio>
#include <fstream>
#include <sstream>

namespace vsurg {

Expected<std::string> ReadTextFile(const std::string& path, const std::string& field) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{ErrorCode::kIoError, path + ": cannot open", field};
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) return Error{ErrorCode::kIoError, path + ": read failed", field};
  return text.str();
}

AtomicFile::AtomicFile(std::string path, std::string field)
    : path_(std::move(path)), part_(path_ + ".part"), field_(std::move(field)) {}

AtomicFile::AtomicFile(AtomicFile&& o) noexcept
    : path_(std::move(o.path_)),
      part_(std::move(o.part_)),
      field_(std::move(o.field_)),
      out_(std::move(o.out_)),
      bytes_(o.bytes_),
      done_(o.done_) {
  o.done_ = true;  // the moved-from object owns nothing
}

Expected<AtomicFile> AtomicFile::Open(const std::string& path, const std::string& field) {
  AtomicFile f(path, field);
  f.out_.open(f.part_, std::ios::binary | std::ios::trunc);
  if (!f.out_) {
    f.done_ = true;
    return Error{ErrorCode::kIoError, "cannot write " + path, field};
  }
  return f;
}

AtomicFile::~AtomicFile() {
  if (done_) return;
  out_.close();
  std::remove(part_.c_str());
}

bool AtomicFile::Write(std::string_view data) {
  out_.write(data.data(), static_cast<std::streamsize>(data.size()));
  bytes_ += data.size();
  return static_cast<bool>(out_);
}

Status AtomicFile::Commit() {
  out_.flush();
  if (!out_) return Error{ErrorCode::kIoError, "write to " + part_ + " failed", field_};
  out_.close();
  if (std::rename(part_.c_str(), path_.c_str()) != 0)
    return Error{ErrorCode::kIoError, "cannot rename " + part_ + " to " + path_, field_};
  done_ = true;
  return Status::Ok();
}

}  // namespace vsurg
