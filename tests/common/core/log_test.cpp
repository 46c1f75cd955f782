// The event log's two formats: logfmt quotes what would split a field, JSON escapes what would
// break the object and spells numbers as numbers; both keep every field, in order.
#include "common/core/log.h"

#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace vsurg {
namespace {

constexpr int64_t kTs = 1795712588314279;  // 2026-11-26T17:03:08.314279Z

TEST(LogTest, LogfmtQuotesOnlyWhatWouldSplitAField) {
  const std::string line = FormatLogLine(kTs, "vsurg-sessions", "session_ended",
                                         {{"session", "12"},
                                          {"reason", "no stylus data for 5 s"},
                                          {"node", "sim-2"},
                                          {"error", "name 'a' said \"b\"\nthen=c"},
                                          {"empty", ""}},
                                         LogFormat::kLogfmt);
  EXPECT_EQ(line,
            "ts=2026-11-26T17:03:08.314279Z component=vsurg-sessions event=session_ended "
            "session=12 reason=\"no stylus data for 5 s\" node=sim-2 "
            "error=\"name 'a' said \\\"b\\\"\\nthen=c\" empty=\"\"");
}

TEST(LogTest, JsonLinesParseWithEveryFieldAndNumbersByType) {
  const LogFields fields{{"session", int64_t{12}},
                         {"score", 8.5},
                         {"epoch", -3},
                         {"ratio", 1e-3},
                         {"count", uint64_t{18446744073709551615u}},
                         {"nan", std::nan("")},
                         {"node", "sim-2"},
                         {"instance", "1881031612345678"},  // hex that happens to be digits
                         {"version", "01"},
                         {"error", "a \"q\"\\\n\t\x01 é"},
                         {"empty", ""}};
  const std::string line =
      FormatLogLine(kTs, "vsurg-sessions", "session_ended", fields, LogFormat::kJson);
  EXPECT_EQ(line.find('\n'), std::string::npos) << "one line";
  const auto j = nlohmann::json::parse(line);  // throws on anything that is not JSON
  EXPECT_EQ(j["ts"], "2026-11-26T17:03:08.314279Z");
  EXPECT_EQ(j["component"], "vsurg-sessions");
  EXPECT_EQ(j["event"], "session_ended");
  EXPECT_TRUE(j["session"].is_number_integer());
  EXPECT_EQ(j["session"], 12);
  EXPECT_DOUBLE_EQ(j["score"].get<double>(), 8.5);
  EXPECT_EQ(j["epoch"], -3);
  EXPECT_DOUBLE_EQ(j["ratio"].get<double>(), 1e-3);
  EXPECT_EQ(j["count"].get<uint64_t>(), 18446744073709551615u);
  // Text stays text, whatever it looks like; a NaN is not a JSON number.
  for (const char* text : {"nan", "node", "instance", "version", "empty"})
    EXPECT_TRUE(j[text].is_string()) << text;
  EXPECT_EQ(j["instance"], "1881031612345678");
  EXPECT_EQ(j["error"], "a \"q\"\\\n\t\x01 é");
  EXPECT_EQ(j.size(), 3 + fields.size());
}

TEST(LogTest, TheFormatIsNamedOnTheCommandLine) {
  LogFormat f = LogFormat::kLogfmt;
  EXPECT_TRUE(ParseLogFormat("json", &f));
  EXPECT_EQ(f, LogFormat::kJson);
  EXPECT_TRUE(ParseLogFormat("logfmt", &f));
  EXPECT_EQ(f, LogFormat::kLogfmt);
  EXPECT_FALSE(ParseLogFormat("JSON", &f));
  EXPECT_FALSE(ParseLogFormat("", &f));
}

}  // namespace
}  // namespace vsurg
