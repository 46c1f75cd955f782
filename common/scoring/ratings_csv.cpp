#include "common/scoring/ratings_csv.h"

#include <charconv>
#include <map>
#include <set>

#include "common/core/csv.h"

namespace vsurg::scoring {

Expected<std::vector<SubjectRatings>> ParseRatingsCsv(std::string_view text,
                                                      const std::string& source) {
  auto records = csv::Parse(text, source);
  if (!records.ok()) return records.error();
  std::vector<SubjectRatings> subjects;
  std::map<std::string, size_t> subject_index;
  std::set<std::pair<std::string, std::string>> seen;  // (subject, evaluator)
  bool first = true;
  for (const csv::Record& rec : *records) {
    const std::string at = source + ":" + std::to_string(rec.line);
    auto fail = [&](const std::string& column, const std::string& what) {
      return Error{ErrorCode::kParseError, at + ": " + column + ": " + what, column};
    };
    if (first && !rec.fields.empty() && rec.fields[0] == "evaluator_id") {
      first = false;
      continue;  // header
    }
    first = false;
    if (!rec.fields.empty() && !rec.fields[0].empty() && rec.fields[0][0] == '#') continue;
    if (rec.fields.size() != 2 + kIndexCount && rec.fields.size() != 3 + kIndexCount)
      return fail("row", "expected 11 fields (evaluator_id,group,i1..i9) or 12 (…,subject), got " +
                             std::to_string(rec.fields.size()));
    Rating r;
    r.line = rec.line;
    r.evaluator = rec.fields[0];
    if (r.evaluator.empty()) return fail("evaluator_id", "empty");
    auto group = ParseGroup(rec.fields[1]);
    if (!group)
      return fail("group",
                  "unknown group '" + rec.fields[1] + "' (intern, associate_chief or chief)");
    r.group = *group;
    for (int j = 0; j < kIndexCount; ++j) {
      const std::string& f = rec.fields[2 + j];
      const std::string column = "i" + std::to_string(j + 1);
      double v = 0;
      const auto res = std::from_chars(f.data(), f.data() + f.size(), v);
      if (f.empty() || res.ec != std::errc() || res.ptr != f.data() + f.size())
        return fail(column, "not a number: '" + f + "'");
      if (!(v >= kMinScore && v <= kMaxScore))
        return fail(column, "score " + f + " is outside 0..10");
      r.scores[j] = v;
    }
    const std::string subject = rec.fields.size() == 3 + kIndexCount ? rec.fields.back() : "";
    if (!seen.insert({subject, r.evaluator}).second)
      return fail("evaluator_id", "evaluator '" + r.evaluator + "' rated " +
                                      (subject.empty() ? "the subject" : "'" + subject + "'") +
                                      " twice");
    auto [it, added] = subject_index.try_emplace(subject, subjects.size());
    if (added) subjects.push_back(SubjectRatings{subject, {}});
    subjects[it->second].ratings.push_back(std::move(r));
  }
  if (subjects.empty()) return Error{ErrorCode::kParseError, source + ": no ratings", "input"};
  return subjects;
}

}  // namespace vsurg::scoring
