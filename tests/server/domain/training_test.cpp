// The training programme's rules (server/domain/training.h) on a real SQLite store: courses from
// expert trials, cohorts and their grid, proficiency by streak, locking, the daily limit, the
// station's next exercise, the rights of each role, and the progress exports.
#include "server/domain/training.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "common/core/csv.h"
#include "server/domain/scene_catalog.h"
#include "tests/support/site.h"

namespace vsurg::server {
namespace {

constexpr const char* kScene = "sphere-palpation-256";
constexpr const char* kScene2 = "arm-torsion";

class TrainingTest : public test::SiteTest {
 protected:
  // A cohort of one, tina, enrolled in `course` (instructor ian).
  void EnrolTinaAlone(const std::string& name, int64_t course, int64_t& cohort) {
    auto h = CreateCohort(*domain_, As("ian"), name, "", {"tina"});
    ASSERT_TRUE(h.ok());
    db::EnrolmentRecord e;
    e.course_id = course;
    e.cohort_id = h->id;
    ASSERT_TRUE(Enrol(*domain_, As("ian"), e).ok());
    cohort = h->id;
  }
  // That trainee's state on the course's first exercise, from the cohort's grid.
  CellState FirstExerciseState(int64_t cohort, int64_t course) {
    auto grid = CohortProgress(*domain_, As("ian"), cohort, course);
    EXPECT_TRUE(grid.ok());
    return grid.ok() && grid->trainees.size() == 1 ? grid->trainees[0].exercises[0].state
                                                   : CellState::kLocked;
  }
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(OpenSite());
    domain_ = std::make_unique<Domain>(Domain{*store_, *sessions_, catalog_, backups()});
    AddUsers({{"ian", db::Role::kInstructor, ""},
              {"ivy", db::Role::kInstructor, ""},
              {"tina", db::Role::kTrainee, "novice"},
              {"tom", db::Role::kTrainee, "novice"},
              {"exa", db::Role::kTrainee, "staff"},
              {"exb", db::Role::kTrainee, "staff"},
              {"exc", db::Role::kTrainee, "staff"}});
  }
  void TearDown() override {
    domain_.reset();
    SiteTest::TearDown();
  }
  // A recorded trial: a session of `trainee` on `scene` (an attempt at `exercise` when not 0)
  // that ended with these figures.
  int64_t Trial(const std::string& trainee, const std::string& scene, int64_t exercise,
                double time_s, double peak_n) {
    auto s = store_->CreateSession(trainee, scene);
    EXPECT_TRUE(s.ok());
    if (exercise) {
      EXPECT_TRUE(store_->SetSessionExercise(s->id, exercise).ok());
    }
    scoring::TrialMetrics m;
    m.completed = true;
    m.completion_time = time_s;
    m.peak_force = peak_n;
    m.score = 8;
    EXPECT_TRUE(store_->EndSession(s->id, SessionState::kEnded, NowUs(), "done", m).ok());
    return s->id;
  }
  ExerciseSpec Spec(std::vector<TargetSpec> targets, int consecutive = 2) {
    ExerciseSpec s;
    s.targets = std::move(targets);
    s.rule.consecutive = consecutive;
    return s;
  }
  // A two-exercise course from the experts' trials, and a cohort of tina and tom enrolled in it.
  void Programme() {
    for (const char* e : {"exa", "exb", "exc"}) ASSERT_TRUE(store_->SetExpert(e, true).ok());
    Trial("exa", kScene, 0, 20, 1.0);
    Trial("exb", kScene, 0, 24, 1.2);
    Trial("exc", kScene, 0, 28, 1.4);
    Trial("exa", kScene2, 0, 30, 2.0);
    Trial("exb", kScene2, 0, 34, 2.2);
    auto c = CreateCourse(
        *domain_, As("ian"), "Basics", "press, then twist",
        {{"Press", kScene, Spec({{"completion_time_s", std::nullopt}, {"peak_force_n", 1.5}})},
         {"Twist", kScene2, Spec({{"completion_time_s", std::nullopt}})}});
    ASSERT_TRUE(c.ok()) << c.error().message;
    course_ = *c;
    auto h = CreateCohort(*domain_, As("ian"), "Residents 2026", "", {"tina", "tom"});
    ASSERT_TRUE(h.ok()) << h.error().message;
    cohort_ = *h;
    db::EnrolmentRecord e;
    e.course_id = course_.record.id;
    e.cohort_id = cohort_.id;
    ASSERT_TRUE(Enrol(*domain_, As("ian"), e).ok());
  }
  int64_t Ex(int i) const { return course_.exercises[static_cast<size_t>(i)].record.id; }

  SceneCatalog catalog_;
  std::unique_ptr<Domain> domain_;
  CourseView course_;
  db::CohortRecord cohort_;
};

TEST_F(TrainingTest, ExpertTargetsAreTheirMeanPlusOneSdAndFollowThemAsTheyTrain) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  const ExerciseView& press = course_.exercises[0];
  ASSERT_EQ(press.targets.size(), 2u);
  // 20, 24, 28 s: mean 24, sample SD 4 → 28 s.
  EXPECT_TRUE(press.targets[0].from_experts);
  EXPECT_EQ(press.targets[0].expert_trials, 3);
  EXPECT_NEAR(*press.targets[0].value, 28.0, 1e-9);
  EXPECT_NEAR(*press.targets[1].value, 1.5, 1e-12);  // fixed
  EXPECT_TRUE(press.ready);
  // A fourth expert trial moves the benchmark: 20, 24, 28, 16 → mean 22, SD 5.164.
  Trial("exa", kScene, 0, 16, 1.0);
  auto again = GetCourse(*domain_, As("ian"), course_.record.id);
  ASSERT_TRUE(again.ok());
  EXPECT_NEAR(*again->exercises[0].targets[0].value, 22 + std::sqrt(80.0 / 3), 1e-9);
  // One expert trial is no benchmark: the target waits and nothing can pass.
  ASSERT_TRUE(store_->SetExpert("exb", false).ok());
  ASSERT_TRUE(store_->SetExpert("exa", false).ok());
  auto waiting = GetCourse(*domain_, As("ian"), course_.record.id);
  EXPECT_FALSE(waiting->exercises[1].ready);
  EXPECT_FALSE(waiting->exercises[1].targets[0].value.has_value());
}

TEST_F(TrainingTest, TheGridFollowsEachTraineeToProficiencyAndOpensTheNextExercise) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  // tina: fail (too much force), pass, pass → proficient at attempt 3; the twist opens.
  Trial("tina", kScene, Ex(0), 25, 1.8);
  Trial("tina", kScene, Ex(0), 26, 1.2);
  Trial("tina", kScene, Ex(0), 27.5, 1.4);
  // tom: five failures in a row → stalled.
  for (int i = 0; i < 5; ++i) Trial("tom", kScene, Ex(0), 40, 1.0);
  auto grid = CohortProgress(*domain_, As("ian"), cohort_.id, course_.record.id);
  ASSERT_TRUE(grid.ok()) << grid.error().message;
  ASSERT_EQ(grid->trainees.size(), 2u);
  const TraineeProgress& tina = grid->trainees[0];
  EXPECT_EQ(tina.trainee, "tina");
  EXPECT_EQ(tina.exercises[0].state, CellState::kProficient);
  EXPECT_EQ(*tina.exercises[0].progress.proficient_at, 3);
  EXPECT_EQ(tina.exercises[1].state, CellState::kNotStarted);
  EXPECT_EQ(*tina.next_exercise, Ex(1));
  EXPECT_FALSE(tina.stalled);
  const TraineeProgress& tom = grid->trainees[1];
  EXPECT_EQ(tom.exercises[0].state, CellState::kStalled);
  EXPECT_EQ(tom.exercises[0].to_improve, std::vector<std::string>{"completion_time_s"});
  EXPECT_EQ(tom.exercises[1].state, CellState::kLocked);
  EXPECT_TRUE(tom.stalled);
  // The learning curve's CUSUM has one value per attempt, and the station's next exercise.
  auto curve = TraineeCurve(*domain_, As("tina"), "tina", Ex(0));
  ASSERT_TRUE(curve.ok());
  EXPECT_EQ(curve->cusum.values.size(), 3u);
  EXPECT_NEAR(curve->cusum.values[0], 1 - curve->cusum.limits.s, 1e-12);  // a failure first
  auto next = NextExerciseOf(*domain_, As("tina"), "");
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(*next->exercise_id, Ex(1));
  EXPECT_EQ(next->open, std::vector<int64_t>{Ex(1)});
  // The cohort curve: attempt 1 of both, attempts 2–5 of fewer; the experts beside it.
  auto cc = CohortCurveOf(*domain_, As("ian"), cohort_.id, Ex(0));
  ASSERT_TRUE(cc.ok());
  const MetricCurve& time = cc->metrics[0];
  EXPECT_EQ(time.points[0].trainees, 2);
  EXPECT_NEAR(time.points[0].mean, 32.5, 1e-9);
  EXPECT_EQ(time.points[3].trainees, 1);
  EXPECT_EQ(time.expert_trials, 3);
  EXPECT_NEAR(time.expert_mean, 24, 1e-9);
}

TEST_F(TrainingTest, ALockedExerciseAndTheDailyLimitRefuseAnAttempt) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  auto locked = CreateExerciseSession(*domain_, As("tina"), "", Ex(1));
  EXPECT_EQ(locked.error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ(CreateExerciseSession(*domain_, As("tina"), "tom", Ex(0)).error().code,
            ErrorCode::kPermissionDenied);
  auto ok = CreateExerciseSession(*domain_, As("tina"), "", Ex(0));
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_EQ(store_->SessionExercise(ok->record.id).value(), Ex(0));
  ASSERT_TRUE(sessions_->Stop(static_cast<uint64_t>(ok->record.id), "test").ok());
  // A trainee not enrolled gets a clear refusal.
  AddUsers({{"una", db::Role::kTrainee, ""}});
  EXPECT_EQ(CreateExerciseSession(*domain_, As("una"), "", Ex(0)).error().code,
            ErrorCode::kFailedPrecondition);
  // One attempt a day: the second is refused until tomorrow.
  ExerciseSpec one = Spec({{"peak_force_n", 1.5}});
  one.rule.max_attempts_per_day = 1;
  ASSERT_TRUE(SetExerciseSpec(*domain_, As("ian"), Ex(0), one).ok());
  EXPECT_EQ(SetExerciseSpec(*domain_, As("ivy"), Ex(0), one).error().code,
            ErrorCode::kPermissionDenied);  // not her course
  Trial("tina", kScene, Ex(0), 25, 1.0);
  EXPECT_EQ(CreateExerciseSession(*domain_, As("tina"), "", Ex(0)).error().code,
            ErrorCode::kResourceExhausted);
}

TEST_F(TrainingTest, EachRoleSeesWhatIsTheirs) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  EXPECT_EQ(TraineeCourses(*domain_, As("tina"), "tom").error().code, ErrorCode::kPermissionDenied);
  EXPECT_EQ(CohortProgress(*domain_, As("tina"), cohort_.id, course_.record.id).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(CohortProgress(*domain_, As("ivy"), cohort_.id, course_.record.id).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_TRUE(CohortProgress(*domain_, As("root"), cohort_.id, course_.record.id).ok());
  EXPECT_TRUE(ListCohorts(*domain_, As("ivy"))->empty());
  EXPECT_EQ(ListCohorts(*domain_, As("ian"))->size(), 1u);
  EXPECT_EQ(ListCourses(*domain_, As("tina"))->size(), 1u);
  AddUsers({{"una", db::Role::kTrainee, ""}});
  EXPECT_TRUE(ListCourses(*domain_, As("una"))->empty());
  EXPECT_EQ(GetCourse(*domain_, As("una"), course_.record.id).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(CreateCohort(*domain_, As("ivy"), "Hers", "ian", {}).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(CreateCohort(*domain_, As("ian"), "Residents 2026", "", {}).error().code,
            ErrorCode::kAlreadyExists);
  EXPECT_EQ(SetExpert(*domain_, As("tina"), "tina", true).error().code,
            ErrorCode::kPermissionDenied);
}

TEST_F(TrainingTest, ASpecIsCheckedFieldByField) {
  EXPECT_EQ(ParseExerciseSpec("[]").error().field, "spec");
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[]})").error().field, "targets");
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[{"metric":"speed","value":1}]})").error().field,
            "targets[0]");
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[{"metric":"score"}]})").error().field, "targets[0]");
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[{"metric":"score","value":8}],"consecutive":0})")
                .error()
                .field,
            "consecutive");
  EXPECT_EQ(
      ParseExerciseSpec(R"({"targets":[{"metric":"score","value":8}],"cusum":{"p0":0.3,"p1":0.1}})")
          .error()
          .field,
      "cusum.p1");
  auto ok = ParseExerciseSpec(
      R"({"targets":[{"metric":"score","value":8},{"metric":"peak_force_n","from_experts":true}],
          "consecutive":3,"benchmark":"best_quartile"})");
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  auto back = ParseExerciseSpec(ExerciseSpecJson(*ok));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->rule.consecutive, 3);
  EXPECT_EQ(back->benchmark, scoring::BenchmarkMode::kBestQuartile);
  EXPECT_FALSE(back->targets[1].value.has_value());
}

// An exercise sets its own task (the arm twisted to 60° within 4°, under 2 N, in 45 s): checked
// against its scene's task, shown resolved, and its expert benchmark taken from expert trials
// at this exercise only (the scene's other trials were another task); an expert runs it
// without an enrolment.
TEST_F(TrainingTest, AnExerciseSetsItsOwnTaskAndItsExpertsTrialsAtIt) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  auto spec = ParseExerciseSpec(
      R"({"targets":[{"metric":"completion_time_s","from_experts":true}],
          "task":{"target_deg":60,"tolerance_deg":4,"force_limit_n":2,"time_limit_s":45}})");
  ASSERT_TRUE(spec.ok()) << spec.error().message;
  EXPECT_EQ(spec->task.kind, scoring::TaskKind::kTwist);
  EXPECT_NEAR(*spec->task.target, 60 * M_PI / 180, 1e-12);
  EXPECT_FALSE(spec->task.hold_s.has_value());  // the scene's
  auto back = ParseExerciseSpec(ExerciseSpecJson(*spec));
  ASSERT_TRUE(back.ok());
  EXPECT_NEAR(*back->task.tolerance, 4 * M_PI / 180, 1e-12);
  EXPECT_NEAR(*back->task.time_limit, 45, 1e-12);
  // Refused by name: a press's depth on the arm, a target out of range, an unknown setting.
  auto press = ParseExerciseSpec(
      R"({"targets":[{"metric":"score","value":7}],"task":{"target_depth_m":0.004}})");
  ASSERT_TRUE(press.ok());
  Status wrong_kind = SetExerciseSpec(*domain_, As("ian"), Ex(1), *press);
  EXPECT_EQ(wrong_kind.error().field, "exercise.spec.task.target_deg");
  auto far =
      ParseExerciseSpec(R"({"targets":[{"metric":"score","value":7}],"task":{"target_deg":400}})");
  EXPECT_EQ(SetExerciseSpec(*domain_, As("ian"), Ex(1), *far).error().field,
            "exercise.spec.task.target_deg");
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[{"metric":"score","value":7}],"task":{"speed":1}})")
                .error()
                .field,
            "task.speed");
  EXPECT_EQ(
      ParseExerciseSpec(R"({"targets":[{"metric":"score","value":7}],"task":{"hold_s":"long"}})")
          .error()
          .field,
      "task.hold_s");

  ASSERT_TRUE(SetExerciseSpec(*domain_, As("ian"), Ex(1), *spec).ok());
  auto course = GetCourse(*domain_, As("tina"), course_.record.id);
  ASSERT_TRUE(course.ok()) << course.error().message;
  const ExerciseView& twist = course->exercises[1];
  ASSERT_TRUE(twist.task.has_value());
  EXPECT_NEAR(twist.task->target, 60 * M_PI / 180, 1e-12);
  EXPECT_NEAR(twist.task->force_limit, 2, 1e-12);
  EXPECT_GT(twist.task->hold_s, 0);  // the scene's hold, kept
  // The two expert trials on the arm were the scene's own task: they do not set this one.
  EXPECT_EQ(twist.targets[0].expert_trials, 0);
  EXPECT_FALSE(twist.ready);
  // An expert (not enrolled) runs the exercise itself; two such trials make the benchmark.
  auto run = CreateExerciseSession(*domain_, As("exa"), "", Ex(1));
  ASSERT_TRUE(run.ok()) << run.error().message;
  EXPECT_EQ(store_->SessionExercise(run->record.id).value(), Ex(1));
  ASSERT_TRUE(sessions_->Stop(static_cast<uint64_t>(run->record.id), "test").ok());
  Trial("exa", kScene2, Ex(1), 12, 1.0);
  Trial("exb", kScene2, Ex(1), 16, 1.0);
  auto ready = GetCourse(*domain_, As("ian"), course_.record.id);
  EXPECT_EQ(ready->exercises[1].targets[0].expert_trials, 2);
  EXPECT_NEAR(*ready->exercises[1].targets[0].value, 14 + std::sqrt(8.0), 1e-9);
  EXPECT_TRUE(ready->exercises[1].ready);
  // The press exercise, without settings, still takes every expert trial on its scene.
  EXPECT_EQ(ready->exercises[0].targets[0].expert_trials, 3);
}

// A palpation exercise (the lump search): its targets on the search's own metrics (no lump
// missed, no false mark, the coverage from the experts' searches), a course's task settings that
// give it a target refused by name (a search has none), and a trainee's attempt judged on them.
TEST_F(TrainingTest, APalpationExerciseIsJudgedOnLumpsFoundFalseMarksAndCoverage) {
  for (const char* e : {"exa", "exb"}) ASSERT_TRUE(store_->SetExpert(e, true).ok());
  const auto search = [&](const std::string& trainee, int64_t exercise, int found, int false_marks,
                          double coverage) {
    auto s = store_->CreateSession(trainee, "lump-search");
    EXPECT_TRUE(s.ok());
    if (exercise) {
      EXPECT_TRUE(store_->SetSessionExercise(s->id, exercise).ok());
    }
    scoring::TrialMetrics m;
    m.completed = true;
    m.completion_time = m.duration = 140;
    m.lumps = 1;
    m.lumps_found = found;
    m.false_marks = false_marks;
    m.localisation_error = found ? 0.003 : 0;
    m.coverage = coverage;
    m.score = 8;
    EXPECT_TRUE(store_->EndSession(s->id, SessionState::kEnded, NowUs(), "done", m).ok());
  };
  search("exa", 0, 1, 0, 1.0);
  search("exb", 0, 1, 0, 0.9);
  auto c = CreateCourse(
      *domain_, As("ian"), "Breast examination", "find the lump",
      {{"Find the lump", "lump-search",
        Spec({{"lumps_missed", 0.0}, {"false_marks", 0.0}, {"coverage", std::nullopt}}, 1)}});
  ASSERT_TRUE(c.ok()) << c.error().message;
  const ExerciseView& ex = c->exercises[0];
  ASSERT_EQ(ex.targets.size(), 3u);
  EXPECT_EQ(ex.targets[2].expert_trials, 2);
  EXPECT_LT(*ex.targets[2].value, 0.95);  // mean − SD of 1.0 and 0.9: more is better
  EXPECT_TRUE(ex.ready);
  auto target = ParseExerciseSpec(
      R"({"targets":[{"metric":"score","value":7}],"task":{"target_depth_m":0.004}})");
  ASSERT_TRUE(target.ok());
  EXPECT_EQ(SetExerciseSpec(*domain_, As("ian"), ex.record.id, *target).error().field,
            "exercise.spec.task.target");
  // A trainee enrolled: a search that missed the lump fails, one that found it passes.
  int64_t cohort = 0;
  ASSERT_NO_FATAL_FAILURE(EnrolTinaAlone("Breast 2026", c->record.id, cohort));
  const auto state = [&] { return FirstExerciseState(cohort, c->record.id); };
  search("tina", ex.record.id, 0, 1, 1.0);
  EXPECT_EQ(state(), CellState::kTraining);
  search("tina", ex.record.id, 1, 0, 1.0);
  EXPECT_EQ(state(), CellState::kProficient);
}

TEST_F(TrainingTest, ANeedleExerciseIsJudgedOnItsPlacementAndItsBackWall) {
  for (const char* e : {"exa", "exb"}) ASSERT_TRUE(store_->SetExpert(e, true).ok());
  // Every needle figure through the store: what a trial wrote is what the targets read.
  const auto insert = [&](const std::string& trainee, int64_t exercise, double depth_error,
                          int breaches) {
    auto s = store_->CreateSession(trainee, "needle-vessel");
    EXPECT_TRUE(s.ok());
    if (exercise) {
      EXPECT_TRUE(store_->SetSessionExercise(s->id, exercise).ok());
    }
    scoring::TrialMetrics m;
    m.completed = true;
    m.completion_time = m.duration = 12;
    m.punctures = 4 + breaches;
    m.extra_punctures = breaches;
    m.back_wall_breaches = breaches;
    m.depth_error = depth_error;
    m.path_deviation = 0.0005;
    m.lateral_strain = 0.02;
    m.score = breaches ? 3 : 9;
    EXPECT_TRUE(store_->EndSession(s->id, SessionState::kEnded, NowUs(), "done", m).ok());
  };
  insert("exa", 0, 0.0005, 0);
  insert("exb", 0, 0.0015, 0);
  auto c = CreateCourse(*domain_, As("ian"), "Vascular access", "reach the vein",
                        {{"Cannulate the vein", "needle-vessel",
                          Spec({{"back_wall_breaches", 0.0},
                                {"depth_error_m", std::nullopt},
                                {"lateral_strain", 0.05}},
                               1)}});
  ASSERT_TRUE(c.ok()) << c.error().message;
  const ExerciseView& ex = c->exercises[0];
  ASSERT_EQ(ex.targets.size(), 3u);
  EXPECT_EQ(ex.targets[1].expert_trials, 2);
  EXPECT_GT(*ex.targets[1].value, 0.001);  // mean + SD of 0.5 and 1.5 mm: less is better
  int64_t cohort = 0;
  ASSERT_NO_FATAL_FAILURE(EnrolTinaAlone("Access 2026", c->record.id, cohort));
  const auto state = [&] { return FirstExerciseState(cohort, c->record.id); };
  insert("tina", ex.record.id, 0.0005, 1);  // in the vein, but through its back wall first
  EXPECT_EQ(state(), CellState::kTraining);
  insert("tina", ex.record.id, 0.0008, 0);
  EXPECT_EQ(state(), CellState::kProficient);
}

TEST_F(TrainingTest, ACutExerciseIsJudgedOnItsLineAndTheSkinItTore) {
  for (const char* e : {"exa", "exb"}) ASSERT_TRUE(store_->SetExpert(e, true).ok());
  // Every cut figure through the store: what a trial wrote is what the targets read.
  const auto cut = [&](const std::string& trainee, int64_t exercise, double deviation_max,
                       double torn, int lifts) {
    auto s = store_->CreateSession(trainee, "pattern-cut");
    EXPECT_TRUE(s.ok());
    if (exercise) {
      EXPECT_TRUE(store_->SetSessionExercise(s->id, exercise).ok());
    }
    scoring::TrialMetrics m;
    m.completed = true;
    m.completion_time = m.duration = 18;
    m.task_error = 0.3 * deviation_max;
    m.coverage = 0.99;
    m.cut_deviation_max = deviation_max;
    m.cut_outside = 0;
    m.torn_length = torn;
    m.cut_lifts = lifts;
    m.score = torn > 0 ? 5 : 9;
    EXPECT_TRUE(store_->EndSession(s->id, SessionState::kEnded, NowUs(), "done", m).ok());
  };
  cut("exa", 0, 0.0008, 0, 0);
  cut("exb", 0, 0.0012, 0, 0);
  auto c = CreateCourse(
      *domain_, As("ian"), "Basic skills", "pattern cutting",
      {{"Cut the circle out", "pattern-cut",
        Spec({{"cut_deviation_max_m", std::nullopt}, {"torn_length_m", 0.0}, {"cut_lifts", 1.0}},
             1)}});
  ASSERT_TRUE(c.ok()) << c.error().message;
  const ExerciseView& ex = c->exercises[0];
  ASSERT_EQ(ex.targets.size(), 3u);
  EXPECT_EQ(ex.targets[0].expert_trials, 2);
  EXPECT_GT(*ex.targets[0].value, 0.001);  // the experts' mean + SD of 0.8 and 1.2 mm
  int64_t cohort = 0;
  ASSERT_NO_FATAL_FAILURE(EnrolTinaAlone("Skills 2026", c->record.id, cohort));
  const auto state = [&] { return FirstExerciseState(cohort, c->record.id); };
  cut("tina", ex.record.id, 0.0009, 0.0033, 0);  // on the line, but the grasp tore the skin
  EXPECT_EQ(state(), CellState::kTraining);
  cut("tina", ex.record.id, 0.0009, 0, 1);
  EXPECT_EQ(state(), CellState::kProficient);
}

TEST_F(TrainingTest, ProgressExportsAsCsvJsonLinesAndXapi) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  Trial("tina", kScene, Ex(0), 25, 1.2);
  Trial("tina", kScene, Ex(0), 26, 1.2);
  Trial("tina", kScene2, Ex(1), 30, 1.0);
  Trial("tina", kScene2, Ex(1), 31, 1.0);
  auto run = [&](db::ExportFormat f, const std::string& who, int64_t cohort) -> std::string {
    std::string out;
    Status s = ExportProgress(*domain_, As(who), course_.record.id, cohort, f,
                              [&](std::string_view chunk) {
                                out += chunk;
                                return true;
                              });
    EXPECT_TRUE(s.ok()) << s.error().message;
    return out;
  };
  const std::string csv = run(db::ExportFormat::kCsv, "ian", cohort_.id);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);  // header + 2 trainees × 2
  EXPECT_NE(csv.find("Basics,1,Press,sphere-palpation-256,tina,proficient,2,2,2,2,"),
            std::string::npos)
      << csv;
  std::istringstream jl(run(db::ExportFormat::kJsonLines, "ian", cohort_.id));
  int rows = 0;
  for (std::string line; std::getline(jl, line); ++rows)
    EXPECT_TRUE(nlohmann::json::parse(line).contains("proficient_at_attempt"));
  EXPECT_EQ(rows, 4);
  // xAPI: four attempts, two passes, one completed course; ids are UUIDs (version 5).
  std::istringstream xs(run(db::ExportFormat::kXapi, "tina", 0));
  std::map<std::string, int> verbs;
  const std::regex uuid("[0-9a-f]{8}-[0-9a-f]{4}-5[0-9a-f]{3}-[89ab][0-9a-f]{3}-[0-9a-f]{12}");
  for (std::string line; std::getline(xs, line);) {
    const auto j = nlohmann::json::parse(line);
    ++verbs[j["verb"]["display"]["en-US"].get<std::string>()];
    EXPECT_TRUE(std::regex_match(j["id"].get<std::string>(), uuid)) << j["id"];
    EXPECT_EQ(j["actor"]["account"]["name"], "tina");
  }
  EXPECT_EQ(verbs["attempted"], 4);
  EXPECT_EQ(verbs["passed"], 2);
  EXPECT_EQ(verbs["completed"], 1);
  // A download stopped by its reader stops the export (one trainee's lines at a time).
  int calls = 0;
  EXPECT_EQ(
      ExportProgress(*domain_, As("ian"), course_.record.id, cohort_.id, db::ExportFormat::kXapi,
                     [&](std::string_view) {
                       ++calls;
                       return false;
                     })
          .error()
          .code,
      ErrorCode::kUnavailable);
  EXPECT_EQ(calls, 1);
  // A trainee exports only their own; an instructor names the cohort.
  std::string ignored;
  EXPECT_EQ(
      ExportProgress(*domain_, As("tina"), course_.record.id, cohort_.id, db::ExportFormat::kCsv,
                     [&](std::string_view c) {
                       ignored += c;
                       return true;
                     })
          .error()
          .code,
      ErrorCode::kPermissionDenied);
}

// OWASP's CSV-injection rule for every CSV the programme writes: a cell a spreadsheet would run
// as a formula (one that begins with = + - @ TAB or CR) is written as text, whoever typed it (an
// instructor's course, exercise and cohort names, a trainee's name) and whoever exports it (an
// instructor's cohort, a trainee's own).
bool Defused(const std::string& cell) {
  if (cell.empty() || std::string_view("=+-@\t\r").find(cell[0]) == std::string_view::npos)
    return true;
  char* end = nullptr;
  (void)std::strtod(cell.c_str(), &end);
  return end == cell.c_str() + cell.size();  // a number written as one, like -1.5
}
void ExpectEveryCellDefused(const std::string& text, const std::string& what) {
  auto records = csv::Parse(text, what);
  ASSERT_TRUE(records.ok()) << records.error().message;
  ASSERT_GT(records->size(), 1u) << what;
  for (const csv::Record& r : *records)
    for (const std::string& cell : r.fields) EXPECT_TRUE(Defused(cell)) << what << ": " << cell;
}

TEST_F(TrainingTest, EveryCsvCellThatCouldRunAsAFormulaIsWrittenAsText) {
  AddUsers({{"=HYPERLINK(\"http://evil\")", db::Role::kTrainee, "novice"},
            {"@SUM(A1)", db::Role::kTrainee, "novice"}});
  auto c = CreateCourse(
      *domain_, As("ian"), "+cmd|' /C calc'!A0", "",
      {{"-2+3", kScene, Spec({{"score", 8.0}}, 1)}, {"\tTab", kScene2, Spec({{"score", 8.0}}, 1)}});
  ASSERT_TRUE(c.ok()) << c.error().message;
  auto h = CreateCohort(*domain_, As("ian"), "=1+1", "",
                        {"=HYPERLINK(\"http://evil\")", "@SUM(A1)", "\rcr", "tina"});
  ASSERT_TRUE(h.ok()) << h.error().message;
  db::EnrolmentRecord e;
  e.course_id = c->record.id;
  e.cohort_id = h->id;
  ASSERT_TRUE(Enrol(*domain_, As("ian"), e).ok());
  Trial("@SUM(A1)", kScene, c->exercises[0].record.id, 20, 1.0);
  auto exported = [&](const std::string& who, int64_t cohort) {
    std::string out;
    Status s = ExportProgress(*domain_, As(who), c->record.id, cohort, db::ExportFormat::kCsv,
                              [&](std::string_view chunk) {
                                out += chunk;
                                return true;
                              });
    EXPECT_TRUE(s.ok()) << s.error().message;
    return out;
  };
  ExpectEveryCellDefused(exported("ian", h->id), "the cohort's progress");
  ExpectEveryCellDefused(exported("@SUM(A1)", 0), "a trainee's own progress");
  EXPECT_NE(exported("@SUM(A1)", 0).find("'@SUM(A1)"), std::string::npos);
  // The evaluation export, the other CSV with names in it.
  db::Submission sub;
  sub.idempotency_key = "k";
  sub.evaluator = "=evil()";
  sub.evaluator_group = "chief";
  sub.subject_kind = db::SubjectKind::kTrainee;
  sub.subject = "@SUM(A1)";
  sub.moment_min = 20;
  sub.scores = {8, 7, 9, 8, 7, 8, 9, 6, 7};
  sub.submitted_by = "ian";
  ASSERT_TRUE(store_->SubmitEvaluation(sub).ok());
  std::string evaluations;
  ASSERT_TRUE(store_
                  ->Export({}, db::ExportFormat::kCsv,
                           [&](std::string_view chunk) {
                             evaluations += chunk;
                             return true;
                           })
                  .ok());
  ExpectEveryCellDefused(evaluations, "the evaluations");
}

// One request's cost is bounded: a cohort's grid comes a page of trainees at a time, each page
// the same rows the whole grid has for those trainees.
TEST_F(TrainingTest, TheGridComesAPageOfTraineesAtATime) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  Trial("tina", kScene, Ex(0), 25, 1.2);
  Trial("tom", kScene, Ex(0), 40, 1.2);
  auto whole = CohortProgress(*domain_, As("ian"), cohort_.id, course_.record.id);
  ASSERT_TRUE(whole.ok()) << whole.error().message;
  ASSERT_EQ(whole->trainees.size(), 2u);
  EXPECT_EQ(whole->total_trainees, 2);
  for (int64_t offset = 0; offset < 3; ++offset) {
    auto page = CohortProgress(*domain_, As("ian"), cohort_.id, course_.record.id,
                               {.offset = offset, .limit = 1});
    ASSERT_TRUE(page.ok()) << page.error().message;
    EXPECT_EQ(page->total_trainees, 2);
    EXPECT_EQ(page->offset, std::min<int64_t>(offset, 2));
    ASSERT_EQ(page->trainees.size(), offset < 2 ? 1u : 0u);
    if (offset == 2) continue;
    const TraineeProgress& t = page->trainees[0];
    const TraineeProgress& w = whole->trainees[static_cast<size_t>(offset)];
    EXPECT_EQ(t.trainee, w.trainee);
    ASSERT_EQ(t.exercises.size(), w.exercises.size());
    for (size_t i = 0; i < t.exercises.size(); ++i) {
      EXPECT_EQ(t.exercises[i].state, w.exercises[i].state) << t.trainee << " " << i;
      EXPECT_EQ(t.exercises[i].progress.attempts, w.exercises[i].progress.attempts);
    }
  }
  for (const GridPage bad :
       {GridPage{.offset = 0, .limit = 0}, GridPage{.offset = 0, .limit = kMaxGridTrainees + 1},
        GridPage{.offset = -1, .limit = 1}})
    EXPECT_EQ(CohortProgress(*domain_, As("ian"), cohort_.id, course_.record.id, bad).error().code,
              ErrorCode::kInvalidArgument);
}

// A trainee reads an exercise only of a course they are enrolled in, by every route (the course
// page, the learning curve); a numeric benchmark is not taken for a mode.
TEST_F(TrainingTest, ATraineeReadsOnlyTheExercisesOfTheirOwnCourses) {
  ASSERT_NO_FATAL_FAILURE(Programme());
  auto other = CreateCourse(*domain_, As("ivy"), "Advanced", "",
                            {{"Hidden", kScene, Spec({{"score", 8.0}}, 1)}});
  ASSERT_TRUE(other.ok()) << other.error().message;
  const int64_t hidden = other->exercises[0].record.id;
  EXPECT_EQ(GetCourse(*domain_, As("tina"), other->record.id).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_EQ(TraineeCurve(*domain_, As("tina"), "tina", hidden).error().code,
            ErrorCode::kPermissionDenied);
  EXPECT_TRUE(TraineeCurve(*domain_, As("tina"), "tina", Ex(0)).ok());
  EXPECT_TRUE(TraineeCurve(*domain_, As("ivy"), "tina", hidden).ok());  // an instructor may
  EXPECT_EQ(ParseExerciseSpec(R"({"targets":[{"metric":"score","value":8}],"benchmark":3})")
                .error()
                .field,
            "benchmark");
}

}  // namespace
}  // namespace vsurg::server
