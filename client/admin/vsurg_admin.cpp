// vsurg-admin: the administrators' tool, a pure gRPC client: every command goes through the
// server's AdminService / EvaluationService / SessionService with a bearer token (--token,
// --token-file or $VSURG_TOKEN), and every call has a deadline. It never opens the store file:
// the operations that need the file (init, offline export, backup to a path) are vsurg-server's
// subcommands.
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

#include "client/net/remote.h"
#include "common/core/args.h"
#include "common/core/file.h"
#include "common/core/time.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "db/vocabulary.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace {

namespace v1 = vsurg::v1;
using vsurg::Error;
using vsurg::Expected;
using vsurg::ReadTextFile;
using vsurg::Status;
using vsurg::cli::ArgParser;
using Kind = ArgParser::Kind;

using vsurg::cli::kExitRuntime;
using vsurg::cli::kExitUsage;
using vsurg::cli::ParseOrExit;

int Usage(std::ostream& err, const std::string& cmd, const std::string& field,
          const std::string& msg) {
  return vsurg::cli::UsageError(err, cmd,
                                vsurg::Error{vsurg::ErrorCode::kInvalidArgument, msg, field});
}

using vsurg::client::Remote;

// Adds the remote options, parses and connects. Returns the exit code to stop with (help
// printed, or a usage error), or nothing when the command should go on with `remote`.
std::optional<int> Begin(ArgParser& p, const std::vector<std::string>& args, std::ostream& out,
                         std::ostream& err, Remote& remote) {
  vsurg::client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return rc;
  auto r = vsurg::client::ConnectRemote(p);
  if (!r.ok()) return Usage(err, p.command(), r.error().field, r.error().message);
  remote = std::move(r).value();
  return std::nullopt;
}

int RpcError(std::ostream& err, const std::string& cmd, const grpc::Status& s) {
  return vsurg::client::ReportRpcError(err, cmd, s);
}

int UserAdd(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin user-add", "Creates a user (trainee, instructor, evaluator, admin).");
  p.Option("name", Kind::kString, "user name", true)
      .Option("role", Kind::kString, "trainee, instructor, evaluator or admin", true)
      .Option("group", Kind::kString,
              "trainee group, or evaluator group (intern, "
              "associate_chief, chief)",
              false, "")
      .Option("issue-token", Kind::kFlag, "also issue a token and print it");
  vsurg::client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const auto role = vsurg::db::ParseRole(p.String("role"));
  if (!role) return Usage(err, p.command(), "--role", "trainee, instructor, evaluator or admin");
  auto remote = vsurg::client::ConnectRemote(p);
  if (!remote.ok()) return Usage(err, p.command(), remote.error().field, remote.error().message);
  auto stub = v1::AdminService::NewStub(remote->channel);
  v1::CreateUserRequest req;
  req.set_name(p.String("name"));
  req.set_role(static_cast<v1::Role>(static_cast<int>(*role) + 1));
  req.set_group(p.String("group"));
  v1::User user;
  grpc::ClientContext ctx;
  remote->Prepare(ctx);
  if (grpc::Status s = stub->CreateUser(&ctx, req, &user); !s.ok())
    return RpcError(err, p.command(), s);
  if (p.Flag("issue-token")) {
    v1::IssueTokenRequest t;
    t.set_user(user.name());
    v1::IssueTokenResponse tr;
    grpc::ClientContext c2;
    remote->Prepare(c2);
    if (grpc::Status s = stub->IssueToken(&c2, t, &tr); !s.ok())
      return RpcError(err, p.command(), s);
    out << tr.token() << "\n";
  } else {
    out << "created " << user.name() << "\n";
  }
  return 0;
}

int Token(const std::vector<std::string>& args, std::ostream& out, std::ostream& err, bool revoke) {
  ArgParser p(revoke ? "vsurg-admin token-revoke" : "vsurg-admin token-issue",
              revoke ? "Revokes every token of a user."
                     : "Issues a new token for a user and "
                       "prints it once.");
  p.Option("user", Kind::kString, "user name", true)
      .Option("label", Kind::kString, "note", false, "");
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::AdminService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  if (revoke) {
    v1::UserRef ref;
    ref.set_name(p.String("user"));
    v1::Empty e;
    if (grpc::Status s = stub->RevokeTokens(&ctx, ref, &e); !s.ok())
      return RpcError(err, p.command(), s);
    out << "revoked\n";
    return 0;
  }
  v1::IssueTokenRequest req;
  req.set_user(p.String("user"));
  req.set_label(p.String("label"));
  v1::IssueTokenResponse resp;
  if (grpc::Status s = stub->IssueToken(&ctx, req, &resp); !s.ok())
    return RpcError(err, p.command(), s);
  out << resp.token() << "\n";
  return 0;
}

// An import row's idempotency key: a SHA-256 of the whole (kind, subject, evaluator, moment)
// tuple, so keys never collide however long the subject (they were cut at 128 characters).
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

int Import(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
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
  vsurg::client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const bool quiet = p.Flag("quiet");
  auto text = ReadTextFile(p.String("input"), "--input");
  if (!text.ok()) return Usage(err, p.command(), "--input", text.error().message);
  auto subjects = vsurg::scoring::ParseRatingsCsv(*text, p.String("input"));
  if (!subjects.ok()) return Usage(err, p.command(), "--input", subjects.error().message);
  for (const auto& subject : *subjects)
    if (subject.subject.empty() && !p.Has("subject"))
      return Usage(err, p.command(), "--subject", "rows without a subject need --subject");
  auto remote = vsurg::client::ConnectRemote(p);
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
      req.set_evaluator_group(vsurg::scoring::GroupName(r.group));
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

std::string Fixed(const nlohmann::json& v, int digits = 3) {
  if (!v.is_number()) return "n/a";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v.get<double>());
  return buf;
}

// The seed 000 table of one subject's report (Fig. 12-14: M_j, s_j, N) with the agreement.
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

int Report(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin report",
              "The weighted evaluation report of seed 000 (eq. 9-11) for one subject, or a\n"
              "comparison of several (comma-separated) with the raters' agreement per index.");
  p.Option("subject-kind", Kind::kString, "session, trainee or model", true)
      .Option("subjects", Kind::kString, "subject, or subjects separated by commas", true)
      .Option("weights", Kind::kString, "a stored weight set (default: seed 000)", false, "")
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

int Export(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ArgParser p(
      "vsurg-admin export",
      "Exports the stored evaluations through the server, streamed: one row per evaluator,\n"
      "subject and index (CSV per RFC 4180 with ISO-8601 UTC times, or JSON lines), or one\n"
      "xAPI statement per submission. Written to a temporary file and renamed when\n"
      "complete. (Offline, from the store file: vsurg-server export --db FILE.)");
  p.Option("format", Kind::kString, "csv, jsonl or xapi", false, "csv")
      .Option("out", Kind::kString, "output file", true)
      .Option("from", Kind::kString, "submitted at or after (2026-11-21 or ...T10:00:00Z)")
      .Option("to", Kind::kString, "submitted before")
      .Option("trainee", Kind::kString, "only this trainee (trainee subjects and their sessions)")
      .Option("session", Kind::kInt, "only this session");
  vsurg::client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  v1::ExportRequest req;
  req.set_format(p.String("format"));
  if (!vsurg::db::ParseExportFormat(req.format()))
    return Usage(err, p.command(), "--format", "csv, jsonl or xapi");
  for (const char* opt : {"from", "to"}) {
    if (!p.Has(opt)) continue;
    auto t = vsurg::ParseIsoUtc(p.String(opt), std::string("--") + opt);
    if (!t.ok()) return Usage(err, p.command(), t.error().field, t.error().message);
    std::string(opt) == "from" ? req.set_from_us(*t) : req.set_to_us(*t);
  }
  if (p.Has("trainee")) req.set_trainee(p.String("trainee"));
  if (p.Has("session")) {
    if (p.Int("session") <= 0) return Usage(err, p.command(), "--session", "a session id > 0");
    req.set_session(static_cast<uint64_t>(p.Int("session")));
  }
  auto remote = vsurg::client::ConnectRemote(p);
  if (!remote.ok()) return Usage(err, p.command(), remote.error().field, remote.error().message);
  auto file = vsurg::AtomicFile::Open(p.String("out"), "--out");
  if (!file.ok()) return Usage(err, p.command(), "--out", file.error().message);
  auto stub = v1::AdminService::NewStub(remote->channel);
  grpc::ClientContext ctx;
  remote->Prepare(ctx, std::max(600.0, remote->timeout_s));
  auto reader = stub->Export(&ctx, req);
  v1::ExportChunk chunk;
  while (reader->Read(&chunk)) {
    if (!file->Write(chunk.data())) {
      ctx.TryCancel();
      break;
    }
  }
  if (grpc::Status s = reader->Finish(); !s.ok()) return RpcError(err, p.command(), s);
  if (Status s = file->Commit(); !s.ok()) {
    err << p.command() << ": " << s.error().message << "\n";
    return kExitRuntime;
  }
  err << "vsurg-admin: wrote " << file->bytes() << " bytes to " << p.String("out") << "\n";
  return 0;
}

int Simple(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
           const std::string& cmd) {
  ArgParser p("vsurg-admin " + cmd,
              cmd == "users"    ? "Lists the users."
              : cmd == "backup" ? "Online backup of the server's store to a new file on the server."
                                : "Stores a weight set (JSON {name, group{...}, index[9]}).");
  if (cmd == "backup")
    p.Option("out", Kind::kString,
             "file name in the server's backup directory (vsurg-server --backup-dir)", true);
  if (cmd == "weights-put") p.Option("file", Kind::kString, "weight set JSON", true);
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::AdminService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  v1::Empty empty;
  grpc::Status s;
  if (cmd == "users") {
    v1::ListUsersResponse resp;
    s = stub->ListUsers(&ctx, v1::ListUsersRequest(), &resp);
    if (s.ok())
      for (const v1::User& u : resp.users())
        out << u.name() << "\t" << v1::Role_Name(u.role()) << "\t" << u.group()
            << (u.disabled() ? "\tdisabled" : "") << "\n";
  } else if (cmd == "backup") {
    v1::BackupRequest req;
    req.set_path(p.String("out"));
    s = stub->Backup(&ctx, req, &empty);
    if (s.ok()) out << "backed up to " << p.String("out") << " in the server's backup directory\n";
  } else {
    auto json = ReadTextFile(p.String("file"), "--file");
    if (!json.ok()) return Usage(err, p.command(), "--file", json.error().message);
    v1::WeightSet w;
    w.set_json(*json);
    s = stub->PutWeightSet(&ctx, w, &empty);
    if (s.ok()) out << "stored\n";
  }
  return s.ok() ? 0 : RpcError(err, p.command(), s);
}

// The scenes the server runs, and the sessions with the scoring loop's trial metrics.
int Scenes(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
           const std::string& cmd) {
  ArgParser p("vsurg-admin " + cmd, cmd == "scenes"
                                        ? "Lists the scenes the server can run."
                                        : "Lists sessions with their trial metrics (ended ones).");
  if (cmd == "sessions") {
    p.Option("trainee", Kind::kString, "only this trainee's")
        .Option("json", Kind::kFlag, "one JSON object per line");
  }
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::SessionService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  if (cmd == "scenes") {
    v1::ListScenesResponse resp;
    const grpc::Status s = stub->ListScenes(&ctx, v1::ListScenesRequest(), &resp);
    if (!s.ok()) return RpcError(err, p.command(), s);
    out << "scene\tmodel\ttask\terror budget (RMS)\n";
    for (const v1::SceneInfo& i : resp.scenes())
      out << i.name() << "\t" << i.model() << "\t" << i.task() << "\t"
          << Fixed(i.error_budget_rms(), 2) << "\n";
    for (const std::string& why : resp.unusable()) err << "unusable scene file " << why << "\n";
    return 0;
  }
  v1::ListSessionsRequest req;
  if (p.Has("trainee")) req.set_trainee(p.String("trainee"));
  v1::ListSessionsResponse resp;
  const grpc::Status s = stub->List(&ctx, req, &resp);
  if (!s.ok()) return RpcError(err, p.command(), s);
  if (!p.Flag("json"))
    out << "id\ttrainee\tscene\tstate\tscore\tcompleted\ttime_s\ttask_error\tpeak_force_n\t"
           "over_limit_s\tpath_m\trms_jerk\toverloads\n";
  for (const v1::Session& x : resp.sessions()) {
    const v1::TrialMetrics& m = x.metrics();
    const std::string state = vsurg::convert::StateName(x.state());
    if (p.Flag("json")) {
      nlohmann::json j = {{"id", x.id()},
                          {"trainee", x.trainee()},
                          {"scene", x.scene()},
                          {"state", state},
                          {"end_reason", x.end_reason()}};
      if (x.has_metrics())
        j["metrics"] = vsurg::scoring::TrialMetricsToJson(vsurg::convert::FromProto(m));
      out << j.dump() << "\n";
      continue;
    }
    out << x.id() << "\t" << x.trainee() << "\t" << x.scene() << "\t" << state;
    if (x.has_metrics())
      out << "\t" << Fixed(m.score(), 1) << "\t" << (m.completed() ? "yes" : "no") << "\t"
          << Fixed(m.completion_time_s(), 2) << "\t" << Fixed(m.task_error(), 4) << "\t"
          << Fixed(m.peak_force_n(), 2) << "\t" << Fixed(m.time_over_force_limit_s(), 2) << "\t"
          << Fixed(m.path_length_m(), 3) << "\t" << Fixed(m.rms_jerk(), 0) << "\t"
          << m.overload_events();
    out << "\n";
  }
  return 0;
}

const char* kHelp =
    "usage: vsurg-admin <command> [options]\n\n"
    "commands:\n"
    "  user-add      create a user (trainee, instructor, evaluator, admin)\n"
    "  users         list users\n"
    "  token-issue   issue a token for a user (printed once)\n"
    "  token-revoke  revoke a user's tokens\n"
    "  weights-put   store a weight set\n"
    "  scenes        the scenes the server runs\n"
    "  sessions      sessions with the scoring loop's trial metrics\n"
    "  import        submit evaluations from a ratings CSV\n"
    "  report        weighted evaluation report (seed 000 eq. 9-11), or --training\n"
    "  export        export evaluations: --format csv|jsonl|xapi --out FILE\n"
    "  backup        online backup of the server's store\n\n"
    "Remote commands take --server HOST:PORT and a token (--token, --token-file, $VSURG_TOKEN).\n";

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::vector<std::string> all(argv + 1, argv + argc);
    if (all.empty()) {
      std::cerr << "vsurg-admin: a command is required (see --help)\n";
      return kExitUsage;
    }
    const std::string& cmd = all[0];
    const std::vector<std::string> rest(all.begin() + 1, all.end());
    auto& out = std::cout;
    auto& err = std::cerr;
    if (cmd == "--help" || cmd == "-h" || cmd == "help") return out << kHelp, 0;
    if (cmd == "init") {
      // Moved: vsurg-admin is a pure gRPC client and never opens the store file.
      err << "vsurg-admin: 'init' works on the store file and moved to the server: "
             "vsurg-server init --db FILE [--name admin]\n";
      return kExitUsage;
    }
    if (cmd == "user-add") return UserAdd(rest, out, err);
    if (cmd == "token-issue") return Token(rest, out, err, false);
    if (cmd == "token-revoke") return Token(rest, out, err, true);
    if (cmd == "import") return Import(rest, out, err);
    if (cmd == "report") return Report(rest, out, err);
    if (cmd == "export") return Export(rest, out, err);
    if (cmd == "scenes" || cmd == "sessions") return Scenes(rest, out, err, cmd);
    if (cmd == "users" || cmd == "backup" || cmd == "weights-put")
      return Simple(rest, out, err, cmd);
    std::cerr << "vsurg-admin: unknown command '" << cmd << "' (see --help)\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "vsurg-admin: fatal: " << e.what() << "\n";
    return kExitRuntime;
  }
}
