#include "db/export_formats.h"

#include <cstdio>

#include "common/core/csv.h"
#include "common/scoring/vocabulary.h"

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
    xapi_sum_ = 0;
    xapi_n_ = 0;
    xapi_scores_.clear();
    // actor: the evaluator (an account on this platform); verb: ADL "scored"; object: the rated
    // subject as an activity.
    std::string& h = xapi_head_;
    h = "{\"id\":\"urn:vsurg:submission:";
    AppendInt(h, r.submission_id);
    h += "\",\"timestamp\":\"" + IsoTimeUtc(r.submitted_us) +
         "\",\"actor\":{\"objectType\":\"Agent\",\"account\":{\"homePage\":\"urn:vsurg\",\"name\":"
         "\"";
    AppendJsonEscaped(h, r.evaluator);
    h += "\"}},\"verb\":{\"id\":\"http://adlnet.gov/expapi/verbs/scored\",\"display\":{\"en-US\":"
         "\"scored\"}},\"object\":{\"objectType\":\"Activity\",\"id\":\"urn:vsurg:";
    AppendJsonEscaped(h, r.subject_kind);
    h.push_back(':');
    AppendJsonEscaped(h, r.subject);
    h += "\"},\"context\":{\"extensions\":{\"urn:vsurg:evaluator-group\":\"";
    AppendJsonEscaped(h, r.evaluator_group);
    h += "\"}}";
  }
  if (!xapi_scores_.empty()) xapi_scores_.push_back(',');
  xapi_scores_ += "\"";
  xapi_scores_ += IndexNameOf(r.index_no);
  xapi_scores_ += "\":";
  csv::AppendNumber(xapi_scores_, r.score);
  xapi_sum_ += r.score;
  ++xapi_n_;
}

void ExportFormatter::FlushXapi(std::string& out) {
  if (xapi_id_ < 0) return;
  out += xapi_head_;
  out += ",\"result\":{\"score\":{\"raw\":";
  csv::AppendNumber(out, xapi_n_ ? xapi_sum_ / xapi_n_ : 0.0);
  out += ",\"min\":0,\"max\":10},\"extensions\":{\"urn:vsurg:index-scores\":{";
  out += xapi_scores_;
  out += "}}}}\n";
  xapi_id_ = -1;
}

}  // namespace vsurg::db
