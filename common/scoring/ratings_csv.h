// Ratings from a CSV file: `evaluator_id,group,i1,…,i9[,subject]` (the contract of
// `vsurg-sim score` and of `vsurg-admin` imports).
//
// An optional header row starts with `evaluator_id`. `group` is intern, associate_chief or
// chief; each score 0–10. The optional 12th column names the subject (a session, a trainee or a
// simulator model); rows without it belong to the subject "" — one subject in all is the usual
// case. Every error names the line and the column.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"
#include "common/scoring/evaluation.h"

namespace vsurg::scoring {

// Subjects in the order they first appear.
Expected<std::vector<SubjectRatings>> ParseRatingsCsv(std::string_view text,
                                                      const std::string& source);

}  // namespace vsurg::scoring
