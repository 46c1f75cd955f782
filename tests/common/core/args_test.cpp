// ArgParser and ParseOrExit, directly: every rule of the tools' command lines.
#include "common/core/args.h"

#include <gtest/gtest.h>

#include <sstream>

namespace vsurg::cli {
namespace {

using Kind = ArgParser::Kind;

ArgParser Parser() {
  ArgParser p("tool cmd", "Does a thing.");
  p.Option("dt", Kind::kDouble, "step, s", false, "0.001")
      .Option("steps", Kind::kInt, "count", true)
      .Option("name", Kind::kString, "a name")
      .Option("json", Kind::kFlag, "JSON out");
  return p;
}

std::string FieldOf(ArgParser& p, const std::vector<std::string>& args) {
  const Status s = p.Parse(args);
  return s.ok() ? "ok" : s.error().field;
}

TEST(ArgParserTest, ReadsEveryFormAndKeepsDefaults) {
  ArgParser p = Parser();
  ASSERT_TRUE(p.Parse({"--steps", "-3", "--name=a b", "--json"}).ok());
  EXPECT_EQ(p.Int("steps"), -3);  // a value may start with '-'
  EXPECT_EQ(p.String("name"), "a b");
  EXPECT_TRUE(p.Flag("json"));
  EXPECT_FALSE(p.Has("dt"));
  EXPECT_DOUBLE_EQ(p.Double("dt"), 0.001);
  // A second parse starts afresh.
  ASSERT_TRUE(p.Parse({"--steps=7", "--dt", "1e-4"}).ok());
  EXPECT_FALSE(p.Flag("json"));
  EXPECT_DOUBLE_EQ(p.Double("dt"), 1e-4);
}

TEST(ArgParserTest, EveryErrorNamesTheOption) {
  ArgParser p = Parser();
  EXPECT_EQ(FieldOf(p, {}), "--steps");                                // required
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--bogus", "1"}), "--bogus");  // unknown
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--steps", "3"}), "--steps");  // repeated
  EXPECT_EQ(FieldOf(p, {"--steps", "2.5"}), "--steps");                // not an integer
  EXPECT_EQ(FieldOf(p, {"--steps", "99999999999"}), "--steps");        // out of range
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--dt", "nan"}), "--dt");      // not finite
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--dt", "inf"}), "--dt");
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--dt", "1x"}), "--dt");  // the whole token
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--dt"}), "--dt");        // needs a value
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--name="}), "--name");   // empty string
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--json=1"}), "--json");  // a flag takes none
  EXPECT_EQ(FieldOf(p, {"stray", "--steps", "2"}), "stray");      // positional
  EXPECT_EQ(FieldOf(p, {"--"}), "--");
}

TEST(ArgParserTest, ParseOrExitPrintsHelpOrOneErrorLine) {
  ArgParser p = Parser();
  std::ostringstream out, err;
  EXPECT_EQ(ParseOrExit(p, {"--steps", "1"}, out, err), std::nullopt);
  EXPECT_EQ(ParseOrExit(p, {"--steps", "x"}, out, err), kExitUsage);
  EXPECT_EQ(err.str(), "tool cmd: --steps: 'x' is not an integer\n");
  EXPECT_TRUE(out.str().empty());
  // --help ends the parse: a missing required option or what follows is not an error.
  EXPECT_EQ(ParseOrExit(p, {"--help", "--bogus"}, out, err), 0);
  EXPECT_EQ(ParseOrExit(p, {"--help"}, out, err), 0);
  EXPECT_NE(out.str().find("usage: tool cmd [--dt X] --steps X [--name X] [--json]"),
            std::string::npos)
      << out.str();
  EXPECT_NE(out.str().find("(default 0.001)"), std::string::npos);
  EXPECT_NE(out.str().find("(required)"), std::string::npos);
}

}  // namespace
}  // namespace vsurg::cli
