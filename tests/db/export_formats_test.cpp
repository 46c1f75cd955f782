// The export formats as pure writers: rows in, text out, every JSON line parsed back.
#include "db/export_formats.h"
#include "common/scoring/xapi.h"

#include <gtest/gtest.h>

#include <regex>

#include <nlohmann/json.hpp>
#include <sstream>

namespace vsurg::db {
namespace {

std::vector<ExportRow> TwoSubmissions() {
  std::vector<ExportRow> rows;
  for (int64_t id : {7, 8})
    for (int64_t j = 1; j <= 9; ++j) {
      ExportRow r;
      r.submission_id = id;
      r.submitted_us = 1'700'000'000'123'456;
      r.evaluator = id == 7 ? "dr \"quote\"\n\\ back" : "=cmd()";
      r.evaluator_group = "chief";
      r.subject_kind = "trainee";
      r.subject = "trainee, one";
      r.trainee = "trainee, one";
      if (id == 8) r.moment_min = 20;
      r.index_no = j;
      r.score = static_cast<double>(j) + (id == 8 ? 0.5 : 0.0);
      rows.push_back(r);
    }
  return rows;
}

std::string Write(ExportFormat f, const std::vector<ExportRow>& rows) {
  ExportFormatter w(f);
  std::string out;
  w.Begin(out);
  for (const ExportRow& r : rows) w.Add(r, out);
  w.End(out);
  return out;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

TEST(ExportFormatsTest, CsvHasAHeaderOneCrlfLinePerScoreAndQuotesWhatNeedsIt) {
  const std::string csv = Write(ExportFormat::kCsv, TwoSubmissions());
  std::vector<std::string> lines;  // records end in CRLF; a quoted field may hold a bare LF
  for (size_t at = 0, end; (end = csv.find("\r\n", at)) != std::string::npos; at = end + 2)
    lines.push_back(csv.substr(at, end - at));
  ASSERT_EQ(lines.size(), 1u + 18u);
  EXPECT_EQ(csv.substr(csv.size() - 2), "\r\n");
  EXPECT_EQ(lines[0].rfind("submission_id,submitted_at,evaluator,", 0), 0u);
  EXPECT_NE(lines[1].find("\"dr \"\"quote\"\"\n\\ back\""), std::string::npos) << lines[1];
  EXPECT_NE(csv.find("2023-11-14T22:13:20.123456Z"), std::string::npos);
  EXPECT_NE(csv.find("\"trainee, one\""), std::string::npos) << "a comma is quoted";
  EXPECT_NE(csv.find("\"'=cmd()\""), std::string::npos) << "a formula is neutralised";
  EXPECT_NE(lines.back().find(",9,texture,9.5"), std::string::npos) << lines.back();
}

TEST(ExportFormatsTest, JsonLinesParseBackToTheSameValues) {
  const auto rows = TwoSubmissions();
  const auto lines = Lines(Write(ExportFormat::kJsonLines, rows));
  ASSERT_EQ(lines.size(), rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const auto j = nlohmann::json::parse(lines[i]);
    EXPECT_EQ(j["submission_id"], rows[i].submission_id);
    EXPECT_EQ(j["evaluator"], std::string(rows[i].evaluator));
    EXPECT_EQ(j["index_no"], rows[i].index_no);
    EXPECT_EQ(j["index_name"], scoring::IndexName(static_cast<int>(rows[i].index_no - 1)));
    EXPECT_DOUBLE_EQ(j["score"].get<double>(), rows[i].score);
    if (rows[i].moment_min)
      EXPECT_EQ(j["moment_min"], *rows[i].moment_min);
    else
      EXPECT_TRUE(j["moment_min"].is_null());
  }
}

TEST(ExportFormatsTest, XapiIsOneStatementPerSubmissionWithTheMeanAndTheNineScores) {
  const auto lines = Lines(Write(ExportFormat::kXapi, TwoSubmissions()));
  ASSERT_EQ(lines.size(), 2u);
  const auto first = nlohmann::json::parse(lines[0]);
  // A UUID, as xAPI asks, named by the submission: the same id in every export of it.
  EXPECT_EQ(first["id"], xapi::StatementId("urn:vsurg:submission:7"));
  EXPECT_TRUE(std::regex_match(first["id"].get<std::string>(),
                               std::regex("[0-9a-f]{8}-[0-9a-f]{4}-5[0-9a-f]{3}-[89ab][0-9a-f]{3}-"
                                          "[0-9a-f]{12}")));
  EXPECT_EQ(first["timestamp"].get<std::string>().back(), 'Z');
  EXPECT_EQ(first["actor"]["account"]["name"], "dr \"quote\"\n\\ back");
  EXPECT_EQ(first["verb"]["id"], "http://adlnet.gov/expapi/verbs/scored");
  EXPECT_EQ(first["object"]["id"], "urn:vsurg:trainee:trainee, one");
  EXPECT_DOUBLE_EQ(first["result"]["score"]["raw"].get<double>(), 5.0);  // mean of 1..9
  const auto scores = first["result"]["extensions"]["urn:vsurg:index-scores"];
  EXPECT_EQ(scores.size(), 9u);
  EXPECT_EQ(scores["texture"], 9);
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(lines[1])["result"]["score"]["raw"].get<double>(), 5.5);
}

TEST(ExportFormatsTest, EveryControlCharacterIsEscaped) {
  std::string all;
  for (int c = 0; c < 0x20; ++c) all.push_back(static_cast<char>(c));
  all += "\"\\/é";
  std::string out = "\"";
  AppendJsonEscaped(out, all);
  out += "\"";
  EXPECT_EQ(nlohmann::json::parse(out).get<std::string>(), all);
}

TEST(ExportFormatsTest, NoRowsIsAHeaderOrNothing) {
  EXPECT_EQ(Lines(Write(ExportFormat::kCsv, {})).size(), 1u);  // the header
  EXPECT_EQ(Write(ExportFormat::kJsonLines, {}), "");
  EXPECT_EQ(Write(ExportFormat::kXapi, {}), "");
}

}  // namespace
}  // namespace vsurg::db
