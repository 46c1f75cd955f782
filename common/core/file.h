// Reading a whole text file (configs, CSV inputs, certificates) into memory.
#pragma once

#include <string>

#include "common/core/expected.h"

namespace vsurg {

// kIoError "PATH: cannot open" / "PATH: read failed", `field` naming the input that gave PATH.
Expected<std::string> ReadTextFile(const std::string& path, const std::string& field);

}  // namespace vsurg
