// vsurg-server's --config: a JSON object whose keys are the long option names (a string, a
// number, or true for a flag); options given on the command line win over the file.
#pragma once

#include <string>
#include <vector>

namespace vsurg::server {

// Appends the file's options to `args` (those not already given). False, with `error` set, when
// the file cannot be read or is not such an object.
bool MergeConfig(const std::string& path, std::vector<std::string>& args, std::string& error);

}  // namespace vsurg::server
