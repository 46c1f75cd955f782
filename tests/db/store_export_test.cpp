// What leaves the store: the evaluation exports (CSV per RFC 4180 and formula-safe, JSON lines,
// xAPI), online backups, weight sets and reports, and the read-only open of a file beside a live
// server.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/core/csv.h"
#include "db/store.h"
#include "tests/db/store_fixture.h"

namespace vsurg::db {
namespace {

namespace fs = std::filesystem;

class StoreExportTest : public test_store::StoreTest {};

INSTANTIATE_TEST_SUITE_P(Backends, StoreExportTest,
                         ::testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const auto& p) { return std::string(BackendName(p.param)); });

TEST_P(StoreExportTest, CsvExportIsRfc4180UtcAndFormulaSafe) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  auto session = store_->CreateSession("trainee-1", "arm-torsion");
  ASSERT_TRUE(store_->SetSessionState(session->id, SessionState::kRunning, 100).ok());
  Submission s = Valid("e1", "=HYPERLINK(\"http://evil\")");
  s.subject_kind = SubjectKind::kSession;
  s.subject = std::to_string(session->id);
  ASSERT_TRUE(store_->SubmitEvaluation(s).ok());
  ASSERT_TRUE(store_->SubmitEvaluation(Valid("e2", "dr, comma", "msm")).ok());
  std::string out;
  ASSERT_TRUE(store_
                  ->Export({}, ExportFormat::kCsv,
                           [&](std::string_view chunk) {
                             out.append(chunk);
                             return true;
                           })
                  .ok());
  auto rows = csv::Parse(out, "export");
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  ASSERT_EQ(rows->size(), 1u + 18u);
  EXPECT_EQ((*rows)[0].fields[0], "submission_id");
  const auto& first = (*rows)[1].fields;
  ASSERT_EQ(first.size(), 11u);
  EXPECT_EQ(first[2], "'=HYPERLINK(\"http://evil\")");
  EXPECT_EQ(first[6], "trainee-1");  // the session's trainee
  EXPECT_EQ(first[9], "effectiveness");
  EXPECT_EQ(first[10], "8");
  EXPECT_EQ(first[1].size(), 27u);  // 2026-11-21T23:59:01.123456Z
  EXPECT_EQ(first[1].back(), 'Z');
  EXPECT_EQ((*rows)[10].fields[2], "dr, comma");

  // Filters: by session, by trainee, by time.
  auto count = [&](const ExportFilter& f) {
    int lines = 0;
    EXPECT_TRUE(store_
                    ->Export(f, ExportFormat::kJsonLines,
                             [&](std::string_view chunk) {
                               for (char c : chunk) lines += c == '\n';
                               return true;
                             })
                    .ok());
    return lines;
  };
  EXPECT_EQ(count({}), 18);
  EXPECT_EQ(count({.session = session->id}), 9);
  EXPECT_EQ(count({.trainee = std::string("trainee-1")}), 9);
  EXPECT_EQ(count({.trainee = std::string("nobody")}), 0);
  EXPECT_EQ(count({.from_us = NowUs() + 1000000}), 0);
  EXPECT_EQ(count({.to_us = NowUs() + 1000000}), 18);
}

TEST_P(StoreExportTest, JsonLinesAndXapiParse) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  ASSERT_TRUE(store_->SubmitEvaluation(Valid("e1", "dr \"quoted\"\n")).ok());
  for (ExportFormat f : {ExportFormat::kJsonLines, ExportFormat::kXapi}) {
    std::string out;
    ASSERT_TRUE(store_
                    ->Export({}, f,
                             [&](std::string_view c) {
                               out.append(c);
                               return true;
                             })
                    .ok());
    std::istringstream lines(out);
    std::string line;
    int n = 0;
    while (std::getline(lines, line)) {
      const auto j = nlohmann::json::parse(line);
      if (f == ExportFormat::kXapi) {
        EXPECT_EQ(j["verb"]["id"], "http://adlnet.gov/expapi/verbs/scored");
        EXPECT_EQ(j["actor"]["account"]["name"], "dr \"quoted\"\n");
        EXPECT_NEAR(j["result"]["score"]["raw"].get<double>(), 69.0 / 9, 1e-12);
        EXPECT_EQ(j["result"]["extensions"]["urn:vsurg:index-scores"].size(), 9u);
      } else {
        EXPECT_EQ(j["evaluator"], "dr \"quoted\"\n");
      }
      ++n;
    }
    EXPECT_EQ(n, f == ExportFormat::kXapi ? 1 : 9);
  }
}

TEST_P(StoreExportTest, OnlineBackupIsACompleteSoundCopy) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  for (int i = 0; i < 50; ++i)
    ASSERT_TRUE(
        store_->SubmitEvaluation(Valid("b" + std::to_string(i), "dr-" + std::to_string(i))).ok());
  const std::string copy = (dir_ / "backup.db").string();
  if (!sqlite()) {  // PostgreSQL's own tools back it up; the store says so and writes nothing
    const Status refused = store_->Backup(copy);
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().code, ErrorCode::kFailedPrecondition);
    EXPECT_NE(refused.error().message.find("pg_dump"), std::string::npos);
    EXPECT_FALSE(fs::exists(copy));
    return;
  }
  ASSERT_TRUE(store_->Backup(copy).ok());
  auto b = Store::Open({.path = copy});
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ((*b)->CountEvaluationRows().value(), 450);
  EXPECT_EQ((*b)->IntegrityCheck().value(), "ok");
  EXPECT_FALSE(store_->Backup((dir_ / "no/such/dir/x.db").string()).ok());
}

TEST_P(StoreExportTest, WeightSetsAndReportsAreKept) {
  const std::string w =
      R"({"name":"equal","group":{"intern":0.34,"associate_chief":0.33,"chief":0.33},"index":[0.2,0.1,0.1,0.1,0.1,0.1,0.1,0.1,0.1]})";
  ASSERT_TRUE(store_->PutWeightSet("equal", w).ok());
  EXPECT_EQ(store_->GetWeightSet("equal").value(), w);
  EXPECT_EQ(store_->GetWeightSet("nope").error().code, ErrorCode::kNotFound);
  EXPECT_FALSE(store_->PutWeightSet("broken", "{not json").ok());
  EXPECT_EQ(store_->ListWeightSets().value(), std::vector<std::string>{"equal"});
  EXPECT_TRUE(store_->RecordReport("model", "coil", w, R"({"comprehensive":8})").ok());
}

TEST_P(StoreExportTest, ReadOnlyOpenNeverCreatesMigratesOrWrites) {
  ASSERT_TRUE(store_->InitAdmin("root").ok());
  ASSERT_TRUE(store_->SubmitEvaluation(Valid("k1")).ok());
  // A mistyped path is an error, and no file (no database) appears.
  if (sqlite()) {
    const fs::path typo = dir_ / "vsurg-typo.db";
    auto missing = Store::OpenReadOnly(typo.string());
    ASSERT_FALSE(missing.ok());
    EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
    EXPECT_FALSE(fs::exists(typo));
  } else {
    const std::string typo = path_ + "_typo";
    auto missing = Store::OpenReadOnly(typo);
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.error().message.find("does not exist"), std::string::npos)
        << missing.error().message;
    EXPECT_FALSE(Store::OpenReadOnly(typo).ok()) << "still not there";
  }
  // Beside the live writer: reads see what it committed; writes are refused, the file unchanged.
  auto ro = Store::OpenReadOnly(path_);
  ASSERT_TRUE(ro.ok()) << ro.error().message;
  EXPECT_TRUE((*ro)->read_only());
  EXPECT_EQ((*ro)->CountEvaluationRows().value(), 9);
  std::string csv;
  ASSERT_TRUE((*ro)
                  ->Export({}, ExportFormat::kCsv,
                           [&](std::string_view c) {
                             csv.append(c);
                             return true;
                           })
                  .ok());
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 10);
  auto w = (*ro)->CreateUser("mallory", Role::kAdmin, "");
  ASSERT_FALSE(w.ok());
  EXPECT_EQ(w.error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ((*ro)->SubmitEvaluation(Valid("k2", "dr-b")).error().code,
            ErrorCode::kFailedPrecondition);
  EXPECT_EQ(store_->ListUsers().value().size(), 1u);
  EXPECT_EQ(Rows(), 9);
  // A writer's commit after the read-only open is seen by its next read.
  ASSERT_TRUE(store_->SubmitEvaluation(Valid("k3", "dr-c")).ok());
  EXPECT_EQ((*ro)->CountEvaluationRows().value(), 18);
}

TEST_P(StoreExportTest, ReadOnlyOpenRefusesAFileAtAnotherSchemaVersion) {
  store_.reset();
  for (const int v : {0, Store::SchemaVersion() + 1}) {
    SetVersion(v);
    auto other = Store::OpenReadOnly(path_);
    ASSERT_FALSE(other.ok()) << v;
    EXPECT_EQ(other.error().code, ErrorCode::kFailedPrecondition);
    EXPECT_NE(other.error().message.find("schema version " + std::to_string(v)), std::string::npos)
        << other.error().message;
    EXPECT_EQ(Version(), v) << "no migration ran";
  }
  if (!sqlite()) return;
  // An empty file that is not a database yet (a path created by mistake) is refused too.
  std::ofstream(dir_ / "empty.db").close();
  EXPECT_FALSE(Store::OpenReadOnly((dir_ / "empty.db").string()).ok());
}

}  // namespace
}  // namespace vsurg::db
