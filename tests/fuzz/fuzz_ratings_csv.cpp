// libFuzzer target: the ratings CSV of `vsurg-sim score` and `vsurg-admin import`. What parses is
// valid (ValidateRating) and its weighted report (the coil-spring paper eq. 9-11) is finite.
#include <cmath>
#include <cstdint>
#include <string_view>

#include "common/scoring/evaluation.h"
#include "common/scoring/ratings_csv.h"
#include "tests/fuzz/fuzz_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace vsurg::scoring;
  auto subjects =
      ParseRatingsCsv(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.csv");
  if (!subjects.ok()) return 0;
  for (const SubjectRatings& s : *subjects) {
    for (const Rating& r : s.ratings) VSURG_FUZZ_CHECK(ValidateRating(r).ok());
    auto report = Evaluate(s.ratings, WeightSet{});
    if (report.ok()) VSURG_FUZZ_CHECK(std::isfinite(report->comprehensive));
  }
  return 0;
}
