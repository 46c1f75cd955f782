#include "db/export_formats.h"

#include <cstdio>

#include <nlohmann/json.hpp>

#include "common/core/csv.h"
#include "common/scoring/vocabulary.h"
#include "common/scoring/xapi.h"

namespace vsurg::db {
namespace {

const char* IndexNameOf(int64_t index_no) {
  return index_no >= 1 && index_no <= scoring::kIndexCount
             ? scoring::IndexName(static_cast<int>(index_no - 1))
             : "";
}

void AppendInt(std::string& out, int64_t v) {
  char num[24];
  std::snprintf(num, sizeof num, "%lld", static_cast<long long>(v));
  out += num;
}

// "name":"escaped value"
void AppendJsonField(std::string& out, const char* name, std::string_view value) {
  out.push_back('"');
  out += name;
  out += "\":\"";
  AppendJsonEscaped(out, value);
  out.push_back('"');
}

}  // namespace

void ExportFormatter::Begin(std::string& out) {
  if (format_ == ExportFormat::kCsv)
    out +=
        "submission_id,submitted_at,evaluator,evaluator_group,subject_kind,subject,trainee,"
        "moment_min,index_no,index_name,score\r\n";
}

void ExportFormatter::Add(const ExportRow& row, std::string& out) {
  switch (format_) {
    case ExportFormat::kCsv:
      AddCsv(row, out);
      break;
    case ExportFormat::kJsonLines:
      AddJsonLine(row, out);
      break;
    case ExportFormat::kXapi:
      AddXapi(row, out);
      break;
  }
}

void ExportFormatter::End(std::string& out) {
  if (format_ == ExportFormat::kXapi) FlushXapi(out);
}

void ExportFormatter::AddCsv(const ExportRow& r, std::string& out) {
  AppendInt(out, r.submission_id);
  out.push_back(',');
  out += IsoTimeUtc(r.submitted_us);
  out.push_back(',');
  csv::AppendText(out, r.evaluator);
  out.push_back(',');
  out += r.evaluator_group;
  out.push_back(',');
  out += r.subject_kind;
  out.push_back(',');
  csv::AppendText(out, r.subject);
  out.push_back(',');
  csv::AppendText(out, r.trainee);
  out.push_back(',');
  if (r.moment_min) csv::AppendNumber(out, *r.moment_min);
  out.push_back(',');
  AppendInt(out, r.index_no);
  out.push_back(',');
  out += IndexNameOf(r.index_no);
  out.push_back(',');
  csv::AppendNumber(out, r.score);
  out += "\r\n";
}

void ExportFormatter::AddJsonLine(const ExportRow& r, std::string& out) {
  out += "{\"submission_id\":";
  AppendInt(out, r.submission_id);
  out += ",\"submitted_at\":\"" + IsoTimeUtc(r.submitted_us) + "\",";
  AppendJsonField(out, "evaluator", r.evaluator);
  out.push_back(',');
  AppendJsonField(out, "evaluator_group", r.evaluator_group);
  out.push_back(',');
  AppendJsonField(out, "subject_kind", r.subject_kind);
  out.push_back(',');
  AppendJsonField(out, "subject", r.subject);
  out.push_back(',');
  AppendJsonField(out, "trainee", r.trainee);
  out += ",\"moment_min\":";
  if (r.moment_min) {
    csv::AppendNumber(out, *r.moment_min);
  } else {
    out += "null";
  }
  out += ",\"index_no\":";
  AppendInt(out, r.index_no);
  out += ",\"index_name\":\"";
  out += IndexNameOf(r.index_no);
  out += "\",\"score\":";
  csv::AppendNumber(out, r.score);
  out += "}\n";
}

void ExportFormatter::AddXapi(const ExportRow& r, std::string& out) {
  if (r.submission_id != xapi_id_) {
    FlushXapi(out);
    xapi_id_ = r.submission_id;
    xapi_head_ = {r.submitted_us, std::string(r.evaluator), std::string(r.evaluator_group),
                  std::string(r.subject_kind), std::string(r.subject)};
    xapi_scores_.clear();
  }
  xapi_scores_.emplace_back(r.index_no, r.score);
}

// The submission's statement: the evaluator scored the subject, the mean of the index scores as
// the result (0–10), each index's score as an extension.
void ExportFormatter::FlushXapi(std::string& out) {
  if (xapi_id_ < 0) return;
  const XapiHead& r = xapi_head_;
  nlohmann::json st = xapi::Statement(
      "urn:vsurg:submission:" + std::to_string(xapi_id_), r.submitted_us, r.evaluator, "scored",
      xapi::Activity("urn:vsurg:" + r.subject_kind + ":" + r.subject));
  st["context"] = {{"extensions", {{"urn:vsurg:evaluator-group", r.evaluator_group}}}};
  nlohmann::json scores = nlohmann::json::object();
  double sum = 0;
  for (const auto& [index_no, score] : xapi_scores_) {
    scores[IndexNameOf(index_no)] = score;
    sum += score;
  }
  const double mean = xapi_scores_.empty() ? 0.0 : sum / static_cast<double>(xapi_scores_.size());
  st["result"] = {{"score", {{"raw", mean}, {"min", 0}, {"max", 10}}},
                  {"extensions", {{"urn:vsurg:index-scores", scores}}}};
  xapi::AppendLine(out, st);
  xapi_id_ = -1;
}

}  // namespace vsurg::db
