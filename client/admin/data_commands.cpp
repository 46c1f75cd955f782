// vsurg-admin export and backup: the stored evaluations out of the server.
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

int Export(const Args& args, std::ostream& out, std::ostream& err) {
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
  client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  v1::ExportRequest req;
  req.set_format(p.String("format"));
  if (!db::ParseExportFormat(req.format()))
    return Usage(err, p.command(), "--format", "csv, jsonl or xapi");
  for (const char* opt : {"from", "to"}) {
    if (!p.Has(opt)) continue;
    auto t = ParseIsoUtc(p.String(opt), std::string("--") + opt);
    if (!t.ok()) return Usage(err, p.command(), t.error().field, t.error().message);
    std::string(opt) == "from" ? req.set_from_us(*t) : req.set_to_us(*t);
  }
  if (p.Has("trainee")) req.set_trainee(p.String("trainee"));
  if (p.Has("session")) {
    if (p.Int("session") <= 0) return Usage(err, p.command(), "--session", "a session id > 0");
    req.set_session(static_cast<uint64_t>(p.Int("session")));
  }
  auto remote = client::ConnectRemote(p);
  if (!remote.ok()) return Usage(err, p.command(), remote.error().field, remote.error().message);
  auto file = AtomicFile::Open(p.String("out"), "--out");
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

int Backup(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin backup",
              "Online backup of the server's store to a new file on the server.");
  p.Option("out", Kind::kString,
           "file name in the server's backup directory (vsurg-server --backup-dir)", true);
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::AdminService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  v1::BackupRequest req;
  req.set_path(p.String("out"));
  v1::Empty empty;
  const grpc::Status s = stub->Backup(&ctx, req, &empty);
  if (!s.ok()) return RpcError(err, p.command(), s);
  out << "backed up to " << p.String("out") << " in the server's backup directory\n";
  return 0;
}

}  // namespace vsurg::admin
