#include "common/core/csv.h"

#include <cmath>
#include <cstdlib>
#include <limits>

#include <gtest/gtest.h>

namespace vsurg::csv {
namespace {

TEST(CsvTest, ParsesQuotedFieldsWithCommasQuotesAndLineBreaks) {
  auto r = Parse("a,\"b,c\",\"say \"\"hi\"\"\"\r\n\"two\nlines\",,x\n\nlast", "t.csv");
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->size(), 3u);
  EXPECT_EQ((*r)[0].fields, (std::vector<std::string>{"a", "b,c", "say \"hi\""}));
  EXPECT_EQ((*r)[1].fields, (std::vector<std::string>{"two\nlines", "", "x"}));
  EXPECT_EQ((*r)[1].line, 2);
  EXPECT_EQ((*r)[2].line, 5);  // the blank line 4 is skipped
  EXPECT_EQ((*r)[2].fields, (std::vector<std::string>{"last"}));
}

TEST(CsvTest, MalformedQuotingNamesTheLine) {
  auto unterminated = Parse("a,b\nc,\"open\n", "in.csv");
  ASSERT_FALSE(unterminated.ok());
  EXPECT_NE(unterminated.error().message.find("in.csv:"), std::string::npos);
  EXPECT_FALSE(Parse("a\"b\n", "in.csv").ok());
  auto after = Parse("x\n\"q\"z,1\n", "in.csv");
  ASSERT_FALSE(after.ok());
  EXPECT_NE(after.error().message.find("in.csv:2"), std::string::npos);
}

TEST(CsvTest, WriterRoundTripsThroughTheReader) {
  const std::vector<std::string> fields = {"plain",      "with,comma", "with \"quote\"",
                                           "two\nlines", " padded ",   ""};
  std::string line;
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i) line.push_back(',');
    AppendText(line, fields[i]);
  }
  auto r = Parse(line, "w");
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->size(), 1u);
  EXPECT_EQ((*r)[0].fields, fields);
}

TEST(CsvTest, TextThatASpreadsheetWouldRunIsDefused) {
  for (const char* evil : {"=HYPERLINK(\"http://x\")", "+1+1", "-2+3", "@SUM(A1)", "\tx"}) {
    std::string out;
    AppendText(out, evil);
    EXPECT_EQ(out.substr(0, 2), "\"'") << evil;
    auto r = Parse(out, "w");
    ASSERT_TRUE(r.ok());
    EXPECT_EQ((*r)[0].fields[0], std::string("'") + evil);
  }
  std::string number;
  AppendNumber(number, -1.5);
  EXPECT_EQ(number, "-1.5");  // numbers are numbers, never prefixed
}

TEST(CsvTest, NumbersRoundTripExactlyAndNonFiniteIsEmpty) {
  for (double v : {0.1, 1.0 / 3.0, 7.25, 1e-300, -123456789.125}) {
    std::string s;
    AppendNumber(s, v);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), v) << s;
  }
  std::string nan;
  AppendNumber(nan, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(nan.empty());
}

}  // namespace
}  // namespace vsurg::csv
