// vsurg-admin user-add, users, token-issue, token-revoke.
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

int UserAdd(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin user-add", "Creates a user (trainee, instructor, evaluator, admin).");
  p.Option("name", Kind::kString, "user name", true)
      .Option("role", Kind::kString, "trainee, instructor, evaluator or admin", true)
      .Option("group", Kind::kString,
              "trainee group, or evaluator group (intern, "
              "associate_chief, chief)",
              false, "")
      .Option("issue-token", Kind::kFlag, "also issue a token and print it");
  client::AddRemoteOptions(p);
  if (auto rc = ParseOrExit(p, args, out, err)) return *rc;
  const auto role = db::ParseRole(p.String("role"));
  if (!role) return Usage(err, p.command(), "--role", "trainee, instructor, evaluator or admin");
  auto remote = client::ConnectRemote(p);
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

int Token(const Args& args, std::ostream& out, std::ostream& err, bool revoke) {
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

int Users(const Args& args, std::ostream& out, std::ostream& err) {
  ArgParser p("vsurg-admin users", "Lists the users.");
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::AdminService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  v1::ListUsersResponse resp;
  const grpc::Status s = stub->ListUsers(&ctx, v1::ListUsersRequest(), &resp);
  if (!s.ok()) return RpcError(err, p.command(), s);
  for (const v1::User& u : resp.users())
    out << u.name() << "\t" << v1::Role_Name(u.role()) << "\t" << u.group()
        << (u.disabled() ? "\tdisabled" : "") << "\n";
  return 0;
}

}  // namespace vsurg::admin
