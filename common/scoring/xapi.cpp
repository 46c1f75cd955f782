#include "common/scoring/xapi.h"

#include <openssl/sha.h>

#include "common/core/time.h"

namespace vsurg::xapi {

using nlohmann::json;

std::string StatementId(const std::string& name) {
  static constexpr unsigned char kUrlNamespace[16] = {0x6b, 0xa7, 0xb8, 0x11, 0x9d, 0xad,
                                                      0x11, 0xd1, 0x80, 0xb4, 0x00, 0xc0,
                                                      0x4f, 0xd4, 0x30, 0xc8};
  std::string input(reinterpret_cast<const char*>(kUrlNamespace), 16);
  input += name;
  unsigned char h[SHA_DIGEST_LENGTH];
  SHA1(reinterpret_cast<const unsigned char*>(input.data()), input.size(), h);
  h[6] = static_cast<unsigned char>((h[6] & 0x0f) | 0x50);
  h[8] = static_cast<unsigned char>((h[8] & 0x3f) | 0x80);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (int i = 0; i < 16; ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out.push_back('-');
    out.push_back(kHex[h[i] >> 4]);
    out.push_back(kHex[h[i] & 15]);
  }
  return out;
}

json Actor(const std::string& account) {
  return {{"objectType", "Agent"}, {"account", {{"homePage", "urn:vsurg"}, {"name", account}}}};
}

json Verb(const std::string& adl_verb) {
  return {{"id", "http://adlnet.gov/expapi/verbs/" + adl_verb}, {"display", {{"en-US", adl_verb}}}};
}

json Activity(const std::string& id, const std::string& name, const std::string& type) {
  json a = {{"objectType", "Activity"}, {"id", id}};
  if (!name.empty()) a["definition"]["name"] = {{"en-US", name}};
  if (!type.empty()) a["definition"]["type"] = "http://adlnet.gov/expapi/activities/" + type;
  return a;
}

json Statement(const std::string& id_name, int64_t time_us, const std::string& actor,
               const std::string& verb, json object) {
  return {{"id", StatementId(id_name)},
          {"timestamp", IsoTimeUtc(time_us)},
          {"actor", Actor(actor)},
          {"verb", Verb(verb)},
          {"object", std::move(object)}};
}

void AppendLine(std::string& out, const json& statement) {
  out += statement.dump(-1, ' ', false, json::error_handler_t::replace);
  out.push_back('\n');
}

}  // namespace vsurg::xapi
