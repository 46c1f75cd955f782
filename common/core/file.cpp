#include "common/core/file.h"

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

}  // namespace vsurg
