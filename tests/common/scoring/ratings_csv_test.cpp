#include "common/scoring/ratings_csv.h"

#include <gtest/gtest.h>

namespace vsurg::scoring {
namespace {

TEST(RatingsCsvTest, ReadsHeaderRowsAndSubjects) {
  const char* text =
      "evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9\n"
      "e1,intern,1,2,3,4,5,6,7,8,9\n"
      "e2,chief,10,10,10,10,10,10,10,10,0.5\n";
  auto s = ParseRatingsCsv(text, "r.csv");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(s->size(), 1u);
  ASSERT_EQ((*s)[0].ratings.size(), 2u);
  EXPECT_EQ((*s)[0].ratings[1].group, EvaluatorGroup::kChief);
  EXPECT_EQ((*s)[0].ratings[1].scores[8], 0.5);

  auto two = ParseRatingsCsv("e1,intern,1,2,3,4,5,6,7,8,9,coil\ne1,intern,1,2,3,4,5,6,7,8,9,msm\n",
                             "r.csv");
  ASSERT_TRUE(two.ok());
  ASSERT_EQ(two->size(), 2u);
  EXPECT_EQ((*two)[1].subject, "msm");
}

TEST(RatingsCsvTest, ErrorsNameTheLineAndColumn) {
  struct Case {
    const char* text;
    const char* expect;
  } cases[] = {
      {"e1,intern,1,2,3,4,5,6,7,8,11\n", "r.csv:1: i9: score 11 is outside 0..10"},
      {"e1,intern,1,2,3,4,5,6,7,8,9\ne2,resident,1,2,3,4,5,6,7,8,9\n", "r.csv:2: group"},
      {"e1,intern,1,2,x,4,5,6,7,8,9\n", "r.csv:1: i3: not a number"},
      {"e1,intern,1,2,3\n", "r.csv:1: row"},
      {"e1,intern,1,2,3,4,5,6,7,8,9\ne1,chief,1,2,3,4,5,6,7,8,9\n", "r.csv:2: evaluator_id"},
      {"e1,intern,1,2,3,4,5,6,7,8,nan\n", "r.csv:1: i9"},
      {"evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9\n", "no ratings"},
  };
  for (const Case& c : cases) {
    auto s = ParseRatingsCsv(c.text, "r.csv");
    ASSERT_FALSE(s.ok()) << c.text;
    EXPECT_NE(s.error().message.find(c.expect), std::string::npos) << s.error().message;
  }
}

}  // namespace
}  // namespace vsurg::scoring
