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

// A declared range is checked on parsing (both ends inclusive, integers too) and shown in help;
// a default outside it is the declarer's business, never checked against a value not given.
TEST(ArgParserTest, ARangeIsEnforcedAndShown) {
  ArgParser p("tool", "");
  p.Option("rate", Kind::kDouble, "Hz", false, "30")
      .Within({1, 120})
      .Option("threads", Kind::kInt, "count", false, "1")
      .Within({1, 16})
      .Option("name", Kind::kString, "a name");
  EXPECT_TRUE(p.Parse({"--rate", "120", "--threads", "1"}).ok());
  const Status high = p.Parse({"--rate", "120.5"});
  ASSERT_FALSE(high.ok());
  EXPECT_EQ(high.error().field, "--rate");
  EXPECT_EQ(high.error().message, "must be within 1..120");
  EXPECT_EQ(FieldOf(p, {"--threads", "0"}), "--threads");
  EXPECT_EQ(FieldOf(p, {"--threads", "17"}), "--threads");
  EXPECT_EQ(p.RangeOf("rate")->hi, 120);
  EXPECT_FALSE(p.RangeOf("name"));
  EXPECT_NE(p.Help().find("Hz (default 30) (within 1..120)"), std::string::npos) << p.Help();
  // The shortest text that reads back the same number; And and Scaled for derived bounds.
  EXPECT_EQ(NumberText(0.05), "0.05");
  EXPECT_EQ(NumberText(65536), "65536");
  EXPECT_EQ(NumberText(1.0 / 3), "0.3333333333333333");
  EXPECT_EQ(Range({1, 1000}).And({0, 120}).Text(), "1..120");
  EXPECT_EQ(Range({0, 0.1}).Scaled(1e3).Text(), "0..100");
}

TEST(ArgParserTest, ReadsEveryFormAndKeepsDefaults) {
  ArgParser p = Parser();
  ASSERT_TRUE(p.Parse({"--steps", "-3", "--name=a b", "--json"}).ok());
  EXPECT_EQ(p.Int("steps"), -3);  // a value may start with '-'
  ASSERT_TRUE(p.Parse({"--steps", "1", "--dt", "-1e-3"}).ok());
  EXPECT_DOUBLE_EQ(p.Double("dt"), -1e-3);
  ASSERT_TRUE(p.Parse({"--steps", "-3", "--name=a b", "--json"}).ok());
  EXPECT_EQ(p.String("name"), "a b");
  EXPECT_TRUE(p.Flag("json"));
  EXPECT_FALSE(p.Has("dt"));
  EXPECT_DOUBLE_EQ(p.Double("dt"), 0.001);
  // A second parse starts afresh.
  ASSERT_TRUE(p.Parse({"--steps=7", "--dt", "1e-4"}).ok());
  EXPECT_FALSE(p.Flag("json"));
  EXPECT_DOUBLE_EQ(p.Double("dt"), 1e-4);
  // A comma-separated option's items, without the empty ones; none when it is not given.
  EXPECT_TRUE(p.List("name").empty());
  ASSERT_TRUE(p.Parse({"--steps=1", "--name", "lan,,metro,"}).ok());
  EXPECT_EQ(p.List("name"), (std::vector<std::string>{"lan", "metro"}));
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
  EXPECT_EQ(FieldOf(p, {"--steps", "2", "--dt="}), "--dt");       // an empty number
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
