#include "server/config.h"

#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

namespace vsurg::server {

bool MergeConfig(const std::string& path, std::vector<std::string>& args, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = "--config: cannot read " + path;
    return false;
  }
  std::stringstream text;
  text << in.rdbuf();
  const auto j = nlohmann::json::parse(text.str(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    error = "--config: " + path + " is not a JSON object";
    return false;
  }
  std::set<std::string> given;
  for (const std::string& a : args)
    if (a.rfind("--", 0) == 0) given.insert(a.substr(2, a.find('=') - 2));
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (given.count(it.key()) || it.key() == "config") continue;
    if (it->is_boolean()) {
      if (it->get<bool>()) args.push_back("--" + it.key());
    } else if (it->is_string()) {
      args.push_back("--" + it.key());
      args.push_back(it->get<std::string>());
    } else if (it->is_number()) {
      args.push_back("--" + it.key());
      args.push_back(it->dump());
    } else {
      error = "--config: " + it.key() + ": a string, number or boolean is expected";
      return false;
    }
  }
  return true;
}

}  // namespace vsurg::server
