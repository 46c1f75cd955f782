// vsurg-admin import, report, weights-put: evaluations and their weights.
#include "client/admin/commands.h"

#include <openssl/evp.h>

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/file.h"
#include "common/core/time.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "db/vocabulary.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::admin {

namespace v1 = vsurg::v1;

std::string ImportKey(const std::string& kind, const std::string& subject,
                      const std::string& evaluator, const std::string& moment) {
  std::string tuple = kind + '\0' + subject + '\0' + evaluator;
  if (!moment.empty()) tuple += '\0' + moment;
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  EVP_Digest(tuple.data(), tuple.size(), digest, &n, EVP_sha256(), nullptr);
  static const char* kHex = "0123456789abcdef";
  std::string key = "import:";
  for (unsigned int i = 0; i < n; ++i) key += kHex[digest[i] >> 4], key += kHex[digest[i] & 15];
  return key;
}

int Import(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin import",
              "Submits evaluations from a ratings CSV (evaluator_id,group,i1..i9[,subject]).\n"
              "Idempotent: each row's key is derived from its subject and evaluator, so running\n"
              "an import twice stores nothing twice. Stored evaluations are records and are never\n"
              "changed: a row whose scores differ from the stored ones (a correction) is refused\n"
              "and reported, and the other rows still go in. Prints one line per row: stored,\n"
              "unchanged (already stored) or refused, with the reason; exit 1 if any was refused.");
  p.Option("input", Kind::kString, "ratings CSV", true)
      .Option("subject-kind", Kind::kString, "session, trainee or model", true)
      .Option("subject", Kind::kString, "the subject, for rows without a subject column")
      .Option("moment", Kind::kDouble, "training moment, minutes (trainee subjects)")
      .Option("quiet", Kind::kFlag, "print only refused rows and the summary");
  client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const bool quiet = p.Flag("quiet");
  auto text = ReadTextFile(p.String("input"), "--input");
  if (!text.ok()) return Usage(err, p.command(), "--input", text.error().message);
  auto subjects = scoring::ParseRatingsCsv(*text, p.String("input"));
  if (!subjects.ok()) return Usage(err, p.command(), "--input", subjects.error().message);
  for (const auto& subject : *subjects)
    if (subject.subject.empty() && !p.Has("subject"))
      return Usage(err, p.command(), "--subject", "rows without a subject need --subject");
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return Usage(err, p.command(), remote.error().field, remote.error().message);
  auto stub = v1::EvaluationService::NewStub(remote->channel);
  // (An std::optional<double> here trips GCC 12's -Wmaybe-uninitialized in the generated setter.)
  const bool has_moment = p.Has("moment");
  const double moment = has_moment ? p.Double("moment") : 0.0;
  int stored = 0, repeated = 0, refused = 0;
  for (const auto& subject : *subjects) {
    const std::string name = subject.subject.empty() ? p.String("subject") : subject.subject;
    for (const auto& r : subject.ratings) {
      v1::SubmitEvaluationRequest req;
      req.set_idempotency_key(ImportKey(p.String("subject-kind"), name, r.evaluator,
                                        has_moment ? std::to_string(moment) : ""));
      req.set_evaluator(r.evaluator);
      req.set_evaluator_group(scoring::GroupName(r.group));
      req.set_subject_kind(p.String("subject-kind"));
      req.set_subject(name);
      if (has_moment) req.set_moment_min(moment);
      for (double s : r.scores) req.add_scores(s);
      v1::SubmitEvaluationResponse resp;
      grpc::ClientContext ctx;
      remote->Prepare(ctx);
      const std::string row =
          "line " + std::to_string(r.line) + " (" + r.evaluator + " on " + name + ")";
      const grpc::Status s = stub->Submit(&ctx, req, &resp);
      if (s.ok()) {
        if (!quiet)
          out << row << ": " << (resp.duplicate() ? "unchanged (already stored)" : "stored")
              << "\n";
        (resp.duplicate() ? repeated : stored)++;
        continue;
      }
      // The server is gone or refuses us altogether: stop, the rest would fail the same way.
      const grpc::StatusCode code = s.error_code();
      if (code == grpc::StatusCode::UNAVAILABLE || code == grpc::StatusCode::UNAUTHENTICATED ||
          code == grpc::StatusCode::PERMISSION_DENIED ||
          code == grpc::StatusCode::DEADLINE_EXCEEDED) {
        out << "imported " << stored << " evaluations (" << repeated << " unchanged, " << refused
            << " refused) before the error\n";
        err << p.command() << ": " << row << ": ";
        return RpcError(err, p.command(), s);
      }
      out << row << ": refused: " << s.error_message() << "\n";
      ++refused;
    }
  }
  out << "imported " << stored << " evaluations (" << repeated << " unchanged, " << refused
      << " refused)\n";
  return refused > 0 ? 1 : 0;
}

void PrintReport(std::ostream& out, const nlohmann::json& r) {
  out << "subject " << r.value("subject", std::string("?")) << ": " << r["raters"] << " raters ("
      << "intern " << r["raters_per_group"]["intern"] << ", associate_chief "
      << r["raters_per_group"]["associate_chief"] << ", chief " << r["raters_per_group"]["chief"]
      << "), weights '" << r["weights"]["name"].get<std::string>() << "'"
      << (r["renormalised"].get<bool>() ? " (absent groups renormalised)" : "") << "\n";
  for (size_t j = 0; j < r["index_names"].size(); ++j) {
    char line[160];
    std::snprintf(line, sizeof line, "  %-24s M %6s  s %6s\n",
                  r["index_names"][j].get<std::string>().c_str(),
                  Fixed(r["index_means"][j]).c_str(), Fixed(r["index_variances"][j]).c_str());
    out << line;
  }
  out << "  comprehensive N " << Fixed(r["comprehensive"]) << ", ICC(2,k) over indexes "
      << Fixed(r["icc2k"]) << ", Cronbach alpha " << Fixed(r["cronbach_alpha"]) << "\n";
}

int Report(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-admin report",
      "The weighted evaluation report of the coil-spring paper (eq. 9-11) for one subject, or a\n"
      "comparison of several (comma-separated) with the raters' agreement per index.");
  p.Option("subject-kind", Kind::kString, "session, trainee or model", true)
      .Option("subjects", Kind::kString, "subject, or subjects separated by commas", true)
      .Option("weights", Kind::kString, "a stored weight set (default: the coil-spring paper)",
              false, "")
      .Option("training", Kind::kFlag, "print the training effect table instead")
      .Option("json", Kind::kFlag, "print the report as JSON");
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::EvaluationService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  if (p.Flag("training")) {
    v1::TrainingEffectRequest req;
    req.set_weight_set(p.String("weights"));
    v1::TrainingEffectResponse resp;
    if (grpc::Status s = stub->TrainingEffect(&ctx, req, &resp); !s.ok())
      return RpcError(err, p.command(), s);
    out << resp.cells_json() << "\n";
    return 0;
  }
  v1::ReportRequest req;
  req.set_subject_kind(p.String("subject-kind"));
  std::stringstream list(p.String("subjects"));
  for (std::string s; std::getline(list, s, ',');)
    if (!s.empty()) req.add_subjects(s);
  req.set_weight_set(p.String("weights"));
  v1::ReportResponse resp;
  if (grpc::Status s = stub->Report(&ctx, req, &resp); !s.ok())
    return RpcError(err, p.command(), s);
  if (p.Flag("json")) {
    out << resp.report_json() << "\n";
    return 0;
  }
  const auto j = nlohmann::json::parse(resp.report_json(), nullptr, false);
  if (j.is_discarded()) return out << resp.report_json() << "\n", 0;
  if (!j.contains("subjects")) {
    PrintReport(out, j);
    return 0;
  }
  for (const auto& one : j["subjects"]) PrintReport(out, one);
  out << "ICC(2,k) per index across subjects (" << j["common_raters"] << " common raters):";
  for (const auto& v : j["icc2k_per_index"]) out << " " << Fixed(v);
  out << "\n";
  return 0;
}

int WeightsPut(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin weights-put",
              "Stores a weight set (JSON {name, group{...}, index[9]}).");
  p.Option("file", Kind::kString, "weight set JSON", true);
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto json = ReadTextFile(p.String("file"), "--file");
  if (!json.ok()) return Usage(err, p.command(), "--file", json.error().message);
  auto stub = v1::AdminService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  v1::WeightSet w;
  w.set_json(*json);
  v1::Empty empty;
  const grpc::Status s = stub->PutWeightSet(&ctx, w, &empty);
  if (!s.ok()) return RpcError(err, p.command(), s);
  out << "stored\n";
  return 0;
}

}  // namespace vsurg::admin
