// An instructor's station's mode switches (client/station/instructor_controls.h): the scripted
// plan's grammar and refusals, steps taken when due, and the keys as an instructor uses them.
#include "client/station/instructor_controls.h"

#include <gtest/gtest.h>

namespace vsurg::client {
namespace {

using sim::GuideMode;

TEST(InstructorControlsTest, APlanReadsItsStepsAndRefusesWhatCannotBeAsked) {
  auto plan = ParseGuidePlan("2:guide:0.5,5:guide:1,8:observe,9:none");
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  ASSERT_EQ(plan->size(), 4u);
  EXPECT_DOUBLE_EQ((*plan)[0].at_s, 2);
  EXPECT_EQ((*plan)[0].request.mode, GuideMode::kGuide);
  EXPECT_DOUBLE_EQ((*plan)[1].request.alpha, 1);
  EXPECT_EQ((*plan)[2].request.mode, GuideMode::kObserve);
  EXPECT_EQ((*plan)[3].request.mode, GuideMode::kNone);
  EXPECT_TRUE(ParseGuidePlan("")->empty());
  for (const char* bad : {"2:guide:1.5", "2:guide:nan", "2:observe:0.5", "x:guide:0.5",
                          "5:guide:0.5,2:guide:1", "2:steer", "2", "2:guide:0.5:1", "-1:observe"}) {
    auto refused = ParseGuidePlan(bad);
    ASSERT_FALSE(refused.ok()) << bad;
    EXPECT_NE(refused.error().field.find("guide-plan step"), std::string::npos) << bad;
  }
}

TEST(InstructorControlsTest, StepsAreTakenWhenDueAndKeysSwitchAsTheyAreNamed) {
  InstructorControls c(*ParseGuidePlan("1:guide:0.5,1.5:guide:0.8,3:observe"), 0.5);
  WindowInput in;
  EXPECT_FALSE(c.Next(0.5, in).has_value());  // nothing due, no key
  auto due = c.Next(2.0, in);                 // two steps passed in one frame: the last counts
  ASSERT_TRUE(due.has_value());
  EXPECT_DOUBLE_EQ(due->alpha, 0.8);
  EXPECT_FALSE(c.Next(2.1, in).has_value());
  auto press = [&](char key) {
    in.command = key;
    ++in.command_presses;
    return c.Next(2.2, in);
  };
  EXPECT_DOUBLE_EQ(press('T')->alpha, 1.0);  // take over
  EXPECT_DOUBLE_EQ(press('H')->alpha, 0.0);  // hand back
  EXPECT_DOUBLE_EQ(press(']')->alpha, 0.6);  // while guiding, α is sent at once
  EXPECT_DOUBLE_EQ(press(']')->alpha, 0.7);
  for (int i = 0; i < 10; ++i) press(']');
  EXPECT_DOUBLE_EQ(c.alpha(), 1.0);  // held within [0, 1]
  EXPECT_EQ(press('O')->mode, GuideMode::kObserve);
  EXPECT_FALSE(press('[').has_value());  // observing: α changes for the next G, nothing is sent
  EXPECT_DOUBLE_EQ(c.alpha(), 0.9);
  auto guide = press('G');
  EXPECT_EQ(guide->mode, GuideMode::kGuide);
  EXPECT_DOUBLE_EQ(guide->alpha, 0.9);
  EXPECT_FALSE(press('x').has_value());                   // not a command
  EXPECT_FALSE(c.Next(2.3, in).has_value());              // a press counts once
  EXPECT_EQ(c.Next(3.0, in)->mode, GuideMode::kObserve);  // the plan goes on
}

}  // namespace
}  // namespace vsurg::client
