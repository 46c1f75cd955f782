// The export formats as pure writers: rows in, text out, no database (unit-tested alone in
// tests/db/export_formats_test.cpp).
//
//   csv    one line per stored score, RFC 4180, a header line, CRLF; times ISO-8601 UTC
//   jsonl  one JSON object per stored score and line
//   xapi   one xAPI statement per submission (actor: the evaluator's account on urn:vsurg; verb:
//          ADL "scored"; object: the rated subject; result: mean score 0–10 and the nine index
//          scores as an extension), one per line, by the platform's one xAPI writer
//          (common/scoring/xapi.h)
//
// CSV and JSON lines are escaped by hand here, not by nlohmann::json: the export is a measured hot
// path (docs/BENCHMARKS.md, 10⁶ rows) and a json object per row would allocate for every field;
// an xAPI statement is one json object per submission (nine rows). The tests parse every line back
// with nlohmann::json.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/core/json_escape.h"
#include "db/store.h"

namespace vsurg::db {

struct ExportRow {  // one stored score with its submission
  int64_t submission_id = 0;
  int64_t submitted_us = 0;
  std::string_view evaluator, evaluator_group, subject_kind, subject, trainee;
  std::optional<double> moment_min;
  int64_t index_no = 0;  // 1..9
  double score = 0;
};

class ExportFormatter {
 public:
  explicit ExportFormatter(ExportFormat format) : format_(format) {}
  void Begin(std::string& out);                      // the CSV header
  void Add(const ExportRow& row, std::string& out);  // rows in submission, index order
  void End(std::string& out);                        // the last xAPI statement

 private:
  void AddCsv(const ExportRow& row, std::string& out);
  void AddJsonLine(const ExportRow& row, std::string& out);
  void AddXapi(const ExportRow& row, std::string& out);
  void FlushXapi(std::string& out);

  ExportFormat format_;
  // xAPI: one statement per submission, gathered over its rows.
  int64_t xapi_id_ = -1;
  struct XapiHead {  // the submission's first row, copied (a row's views last one row)
    int64_t submitted_us = 0;
    std::string evaluator, evaluator_group, subject_kind, subject;
  } xapi_head_;
  std::vector<std::pair<int64_t, double>> xapi_scores_;  // index number, score
};

// `s` as the inside of a JSON string: common/core/json_escape.h.
using vsurg::AppendJsonEscaped;

}  // namespace vsurg::db
