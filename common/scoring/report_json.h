// JSON forms of the evaluation reports and weight sets (vsurg-sim score, vsurg-admin, the
// store's recorded reports). Undefined figures (NaN) become null.
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>

#include "common/core/expected.h"
#include "common/scoring/evaluation.h"
#include "common/scoring/trial_metrics.h"

namespace vsurg::scoring {

nlohmann::json WeightSetToJson(const WeightSet& w);
// {"name": "...", "group": {"intern": 0.2, "associate_chief": 0.3, "chief": 0.5},
//  "index": [9 numbers]}; validated. Errors name the JSON path.
Expected<WeightSet> WeightSetFromJson(const nlohmann::json& j);
Expected<WeightSet> WeightSetFromJsonText(const std::string& text);

nlohmann::json ReportToJson(const EvaluationReport& r);
nlohmann::json ComparisonToJson(const ComparisonReport& r,
                                const std::vector<std::string>& subject_names);
nlohmann::json TrainingToJson(const std::vector<TrainingCell>& cells);

// A trial's metrics (s, rad or m, N, m/s³; score 0–10 and the caps that applied), as
// `vsurg-sim run --json`, `vsurg-station --json` and `vsurg-admin sessions --json` print them.
nlohmann::json TrialMetricsToJson(const TrialMetrics& m);

}  // namespace vsurg::scoring
