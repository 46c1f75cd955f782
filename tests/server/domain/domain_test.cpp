// The control plane's rules without a transport (server/domain/api.h): a real SQLite store and a
// session manager, the same functions the gRPC services and the HTTP API call.
#include "server/domain/api.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/scoring/evaluation.h"
#include "common/sim/scene.h"
#include "server/domain/scene_catalog.h"
#include "server/session/session_manager.h"
#include "tests/support/site.h"
#include "tests/support/temp_dir.h"

namespace vsurg::server {
namespace {

namespace fs = std::filesystem;

class DomainTest : public test::SiteTest {
 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(OpenSite());
    domain_ = std::make_unique<Domain>(Domain{*store_, *sessions_, catalog_, backups()});
    AddUsers({{"tina", db::Role::kTrainee, "novice"},
              {"ian", db::Role::kInstructor, ""},
              {"eve", db::Role::kEvaluator, "chief"},
              {"ed", db::Role::kEvaluator, "intern"}});
  }
  void TearDown() override {
    domain_.reset();
    SiteTest::TearDown();
  }
  SubmissionRequest Scores(const std::string& subject, double base, double moment = -1) {
    SubmissionRequest r;
    r.idempotency_key = subject + std::to_string(base) + std::to_string(moment);
    r.subject_kind = "trainee";
    r.subject = subject;
    if (moment >= 0) r.moment_min = moment;
    for (int j = 0; j < scoring::kIndexCount; ++j) r.scores.push_back(base + 0.1 * j);
    return r;
  }

  SceneCatalog catalog_;
  std::unique_ptr<Domain> domain_;
};

TEST_F(DomainTest, EveryRuleAppliesWhateverTheTransport) {
  // The matrix: a trainee may not report, an instructor may not submit.
  EXPECT_EQ(Report(*domain_, As("tina"), "trainee", {"tina"}, "").error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(PrepareSubmission(As("ian"), Scores("tina", 5)).error().code,
            ErrorCode::kPermissionDenied);
  // Ownership: an evaluator submits as themself, in their own group.
  SubmissionRequest other = Scores("tina", 5);
  other.evaluator = "ed";
  EXPECT_EQ(PrepareSubmission(As("eve"), other).error().code, ErrorCode::kPermissionDenied);
  auto mine = PrepareSubmission(As("eve"), Scores("tina", 5));
  ASSERT_TRUE(mine.ok());
  EXPECT_EQ(mine->evaluator, "eve");
  EXPECT_EQ(mine->evaluator_group, "chief");
  // An admin imports on someone's behalf and must say whose.
  EXPECT_EQ(PrepareSubmission(As("root"), Scores("tina", 5)).error().field, "evaluator");
  // Validation names the field.
  SubmissionRequest eight = Scores("tina", 5);
  eight.scores.pop_back();
  EXPECT_EQ(PrepareSubmission(As("eve"), eight).error().field, "scores");
  SubmissionRequest kind = Scores("tina", 5);
  kind.subject_kind = "planet";
  EXPECT_EQ(PrepareSubmission(As("eve"), kind).error().field, "subject_kind");
  // A trainee creates sessions only for themself, and sees only their own.
  EXPECT_EQ(CreateSession(*domain_, As("tina"), "someone", "arm-torsion").error().code,
            ErrorCode::kPermissionDenied);
  auto created = CreateSession(*domain_, As("ian"), "tina", "arm-torsion");
  ASSERT_TRUE(created.ok()) << created.error().message;
  EXPECT_EQ(ListSessions(*domain_, As("tina"), "", false).value().size(), 1u);
  EXPECT_EQ(ListSessions(*domain_, As("tina"), "ian", false).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(CheckWatch(*domain_, As("tina"), 0, 0).error().code, ErrorCode::kPermissionDenied);
  EXPECT_EQ(CheckWatch(*domain_, As("ian"), 0, 0).value(), 30.0);
  EXPECT_EQ(CheckWatch(*domain_, As("ian"), 0, 61).error().field, "rate_hz");
  // Stopping ends it, with its metrics recorded; a stopped session is not watchable.
  const uint64_t id = static_cast<uint64_t>(created->record.id);
  auto stopped = StopSession(*domain_, As("tina"), id, "done");
  ASSERT_TRUE(stopped.ok()) << stopped.error().message;
  EXPECT_EQ(stopped->record.state, SessionState::kEnded);
  EXPECT_TRUE(stopped->metrics.has_value());
  EXPECT_EQ(CheckWatch(*domain_, As("ian"), id, 0).error().code, ErrorCode::kFailedPrecondition);
  // An administrator cannot lock themself out.
  EXPECT_EQ(SetDisabled(*domain_, As("root"), "root", true).error().field, "name");
}

TEST_F(DomainTest, ReportWeighsTheGroupsAndIsRecorded) {
  for (auto [who, base] : {std::pair{"eve", 8.0}, {"ed", 4.0}}) {
    SubmissionRequest r = Scores("tina", base);
    r.evaluator = who;
    r.evaluator_group = who == std::string("eve") ? "chief" : "intern";
    auto s = PrepareSubmission(As("root"), r);
    ASSERT_TRUE(s.ok()) << s.error().message;
    ASSERT_TRUE(store_->SubmitEvaluation(*s).ok());
  }
  auto text = Report(*domain_, As("ian"), "trainee", {"tina"}, "");
  ASSERT_TRUE(text.ok()) << text.error().message;
  const auto j = nlohmann::json::parse(*text);
  EXPECT_EQ(j["subject"], "tina");
  EXPECT_EQ(j["subject_kind"], "trainee");
  // No associate chief: chief 0.5 and intern 0.2 renormalised to 5/7 and 2/7 (the coil-spring paper
  // eq. 9).
  const double m1 = (0.5 * 8.0 + 0.2 * 4.0) / 0.7;
  EXPECT_NEAR(j["index_means"][0].get<double>(), m1, 1e-9) << j.dump();
  EXPECT_TRUE(j["renormalised"].get<bool>());
  EXPECT_EQ(Report(*domain_, As("ian"), "trainee", {"nobody"}, "").error().code,
            ErrorCode::kNotFound);
  EXPECT_EQ(Report(*domain_, As("ian"), "trainee", {}, "").error().field, "subjects");
  EXPECT_EQ(Report(*domain_, As("ian"), "trainee", {"tina"}, "no-such-set").error().code,
            ErrorCode::kNotFound);
}

TEST_F(DomainTest, TrainingEffectUsesTheComprehensiveScorePerMoment) {
  for (auto [moment, base] : {std::pair{0.0, 3.0}, {20.0, 6.0}}) {
    auto s = PrepareSubmission(As("eve"), Scores("tina", base, moment));
    ASSERT_TRUE(s.ok());
    ASSERT_TRUE(store_->SubmitEvaluation(*s).ok());
  }
  auto text = TrainingEffect(*domain_, As("ian"), "");
  ASSERT_TRUE(text.ok()) << text.error().message;
  const auto cells = nlohmann::json::parse(*text);
  ASSERT_EQ(cells.size(), 2u) << cells.dump();
  // N = Σ w_j x_j with the seed weights (sum 1): base + 0.1·Σ w_j·j.
  const scoring::WeightSet w;
  double shift = 0;
  for (int j = 0; j < scoring::kIndexCount; ++j) shift += w.index[j] * 0.1 * j;
  EXPECT_NEAR(cells[0]["mean"].get<double>(), 3.0 + shift, 1e-9) << cells.dump();
  EXPECT_NEAR(cells[1]["mean"].get<double>(), 6.0 + shift, 1e-9) << cells.dump();
}

TEST(SceneCatalogTest, ListsUsableScenesSaysWhyNotAndReparsesOnlyChangedFiles) {
  const test::TempDir dir("catalog");
  fs::copy_file(fs::path(sim::ScenesDirectory()) / "arm-torsion.json", dir / "arm-torsion.json");
  std::ofstream(dir / "broken.json") << "{\"description\": 42";
  std::ofstream(dir / "notes.txt") << "not a scene";
  SceneCatalog catalog(dir);
  auto first = catalog.List();
  ASSERT_TRUE(first.ok());
  ASSERT_EQ(first->scenes.size(), 1u);
  EXPECT_EQ(first->scenes[0].name, "arm-torsion");
  EXPECT_EQ(first->scenes[0].task, "twist");
  ASSERT_EQ(first->unusable.size(), 1u);
  EXPECT_EQ(first->unusable[0].rfind("broken.json: ", 0), 0u);
  EXPECT_EQ(first->unusable[0].find(dir.string()), std::string::npos);
  EXPECT_EQ(catalog.loads(), 2u);
  // Unchanged: nothing parsed again.
  ASSERT_TRUE(catalog.List().ok());
  EXPECT_EQ(catalog.loads(), 2u);
  // Fixed (another size): parsed again, and now offered; removed: forgotten.
  fs::copy_file(dir / "arm-torsion.json", dir / "broken.json",
                fs::copy_options::overwrite_existing);
  fs::remove(dir / "arm-torsion.json");
  auto again = catalog.List();
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(catalog.loads(), 3u);
  ASSERT_EQ(again->scenes.size(), 1u);
  EXPECT_EQ(again->scenes[0].name, "broken");
  EXPECT_TRUE(again->unusable.empty());
  fs::remove_all(dir);
  EXPECT_EQ(SceneCatalog(dir).List().error().code, ErrorCode::kUnavailable);
}

}  // namespace
}  // namespace vsurg::server
