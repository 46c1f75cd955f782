#include <openssl/rand.h>
#include <openssl/sha.h>

#include "common/scoring/vocabulary.h"
#include "db/store_impl.h"

// Users, their roles and groups, and bearer tokens (only their SHA-256 is stored).
namespace vsurg::db {
namespace {

std::array<unsigned char, SHA256_DIGEST_LENGTH> TokenHash(std::string_view token) {
  std::array<unsigned char, SHA256_DIGEST_LENGTH> h{};
  SHA256(reinterpret_cast<const unsigned char*>(token.data()), token.size(), h.data());
  return h;
}

Expected<std::string> NewToken() {
  unsigned char raw[32];
  if (RAND_bytes(raw, sizeof raw) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "token"};
  static const char* kHex = "0123456789abcdef";
  std::string t = "vst_";
  for (unsigned char b : raw) {
    t.push_back(kHex[b >> 4]);
    t.push_back(kHex[b & 15]);
  }
  return t;
}

Status InsertUser(Connection& c, const std::string& name, Role role, const std::string& group,
                  int64_t& id_out) {
  if (name.empty() || name.size() > 128)
    return InvalidArgument("name", "a user name of 1 to 128 characters is required");
  if (role == Role::kEvaluator && !scoring::ParseGroup(group))
    return InvalidArgument("group", "an evaluator's group is intern, associate_chief or chief");
  const int64_t now = NowUs();
  Status s = RunSql(c, "INSERT INTO users(name, role, created_us) VALUES (?1, ?2, ?3)",
                    [&](Statement& st) { st.Bind(1, name).Bind(2, RoleName(role)).Bind(3, now); });
  if (!s.ok()) {
    if (s.error().code == ErrorCode::kAlreadyExists)
      return Error{ErrorCode::kAlreadyExists, "user '" + name + "' exists", "name"};
    return s;
  }
  auto id = c.LastInsertId();
  if (!id.ok()) return id.error();
  id_out = *id;
  if (role == Role::kTrainee) {
    // A trainee known from earlier sessions or imports gets linked to the new login.
    s = RunSql(c,
               "INSERT INTO trainees(name, trainee_group, user_id) VALUES (?1, ?2, ?3) "
               "ON CONFLICT(name) DO UPDATE SET user_id = excluded.user_id, "
               "trainee_group = excluded.trainee_group",
               [&](Statement& st) { st.Bind(1, name).Bind(2, group).Bind(3, id_out); });
  } else if (role == Role::kEvaluator) {
    s = RunSql(c,
               "INSERT INTO evaluators(name, evaluator_group, user_id) VALUES (?1, ?2, ?3) "
               "ON CONFLICT(name) DO UPDATE SET user_id = excluded.user_id",
               [&](Statement& st) { st.Bind(1, name).Bind(2, group).Bind(3, id_out); });
  }
  return s;
}

Status InsertToken(Connection& c, int64_t user_id, const std::string& token,
                   const std::string& label) {
  const auto h = TokenHash(token);
  return RunSql(c, "INSERT INTO tokens(user_id, hash, label, created_us) VALUES (?1, ?2, ?3, ?4)",
                [&](Statement& st) {
                  st.Bind(1, user_id).BindBlob(2, h.data(), static_cast<int>(h.size()));
                  st.Bind(3, label).Bind(4, NowUs());
                });
}

}  // namespace

Expected<UserRecord> Store::CreateUser(const std::string& name, Role role,
                                       const std::string& group) {
  UserRecord u;
  Status s = Write([&](Connection& c) { return InsertUser(c, name, role, group, u.id); });
  if (!s.ok()) return s.error();
  u.name = name;
  u.role = role;
  u.group = group;
  u.created_us = NowUs();
  return u;
}

Status Store::SetUserDisabled(const std::string& name, bool disabled) {
  return Write([&](Connection& c) -> Status {
    Status s = RunSql(c, "UPDATE users SET disabled = ?2 WHERE name = ?1",
                      [&](Statement& st) { st.Bind(1, name).Bind(2, int64_t{disabled ? 1 : 0}); });
    if (s.ok() && c.Changes() == 0)
      return Error{ErrorCode::kNotFound, "no user '" + name + "'", "name"};
    return s;
  });
}

Expected<std::string> Store::IssueToken(const std::string& user, const std::string& label) {
  auto token = NewToken();
  if (!token.ok()) return token.error();
  Status s = Write([&](Connection& c) -> Status {
    auto id = LookupId(c, "SELECT id FROM users WHERE name = ?1", user);
    if (!id.ok()) return id.error();
    if (!*id) return Error{ErrorCode::kNotFound, "no user '" + user + "'", "user"};
    return InsertToken(c, **id, *token, label);
  });
  if (!s.ok()) return s.error();
  return token;
}

Status Store::RevokeTokens(const std::string& user) {
  return Write([&](Connection& c) -> Status {
    auto id = LookupId(c, "SELECT id FROM users WHERE name = ?1", user);
    if (!id.ok()) return id.error();
    if (!*id) return Error{ErrorCode::kNotFound, "no user '" + user + "'", "user"};
    return RunSql(c, "UPDATE tokens SET revoked = 1 WHERE user_id = ?1",
                  [&](Statement& st) { st.Bind(1, **id); });
  });
}

Expected<std::string> Store::SignInFederated(const std::string& user, Role role,
                                             double session_ttl_s) {
  auto token = NewToken();
  if (!token.ok()) return token.error();
  Status s = Write([&](Connection& c) -> Status {
    int64_t id = 0;
    {
      auto st = c.Prepare("SELECT id, role, disabled FROM users WHERE name = ?1");
      if (!st.ok()) return st.error();
      (*st)->Bind(1, user);
      auto row = (*st)->Step();
      if (!row.ok()) return row.error();
      if (*row) {
        id = (*st)->Int(0);
        if ((*st)->Int(2) != 0)
          return Error{ErrorCode::kPermissionDenied, "the account '" + user + "' is disabled",
                       "user"};
        if (ParseRole((*st)->Text(1)) != role)
          return Error{ErrorCode::kPermissionDenied,
                       "the account '" + user + "' has the role " + std::string((*st)->Text(1)) +
                           " here, and the identity provider says " + RoleName(role) +
                           "; an administrator reconciles the two",
                       "role"};
      }
    }
    if (id == 0) {
      if (Status st = InsertUser(c, user, role, "", id); !st.ok()) return st;
    }
    // The web sessions' tokens of this user that outlived their sessions: revoked.
    Status old = RunSql(c,
                        "UPDATE tokens SET revoked = 1 WHERE user_id = ?1 AND label = ?2 "
                        "AND created_us < ?3",
                        [&](Statement& st) {
                          st.Bind(1, id).Bind(2, kFederatedLabel);
                          st.Bind(3, NowUs() - static_cast<int64_t>(session_ttl_s * 1e6));
                        });
    if (!old.ok()) return old;
    return InsertToken(c, id, *token, kFederatedLabel);
  });
  if (!s.ok()) return s.error();
  return token;
}

Expected<std::string> Store::InitAdmin(const std::string& name) {
  auto token = NewToken();
  if (!token.ok()) return token.error();
  Status s = Write([&](Connection& c) -> Status {
    auto any = LookupId(c, "SELECT id FROM users WHERE role = ?1 LIMIT 1", "admin");
    if (!any.ok()) return any.error();
    if (*any)
      return Error{ErrorCode::kAlreadyExists,
                   "an administrator exists already; ask them for a token", "init"};
    int64_t id = 0;
    if (Status st = InsertUser(c, name, Role::kAdmin, "", id); !st.ok()) return st;
    return InsertToken(c, id, *token, "init");
  });
  if (!s.ok()) return s.error();
  return token;
}

Expected<Principal> Store::Authenticate(std::string_view token) {
  if (token.size() < 8 || token.size() > 256)
    return Error{ErrorCode::kUnauthenticated, "malformed token", "authorization"};
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  const auto h = TokenHash(token);
  auto st = (**r).Prepare(
      "SELECT u.id, u.name, u.role, u.disabled, t.revoked, "
      "coalesce(tr.trainee_group, ev.evaluator_group, '') FROM tokens t "
      "JOIN users u ON u.id = t.user_id LEFT JOIN trainees tr ON tr.user_id = u.id "
      "LEFT JOIN evaluators ev ON ev.user_id = u.id WHERE t.hash = ?1");
  if (!st.ok()) return st.error();
  (*st)->BindBlob(1, h.data(), static_cast<int>(h.size()));
  auto row = (*st)->Step();
  if (!row.ok()) return row.error();
  if (!*row) {
    (*st)->Reset();
    return Error{ErrorCode::kUnauthenticated, "unknown token", "authorization"};
  }
  Principal p;
  p.user_id = (*st)->Int(0);
  p.name = (*st)->String(1);
  p.role = ParseRole((*st)->Text(2)).value_or(Role::kTrainee);
  const bool disabled = (*st)->Int(3) != 0, revoked = (*st)->Int(4) != 0;
  p.group = (*st)->String(5);
  (*st)->Reset();
  if (revoked) return Error{ErrorCode::kUnauthenticated, "the token was revoked", "authorization"};
  if (disabled) return Error{ErrorCode::kUnauthenticated, "the user is disabled", "authorization"};
  return p;
}

Expected<std::vector<UserRecord>> Store::ListUsers() {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  auto st = (**r).Prepare(
      "SELECT u.id, u.name, u.role, coalesce(tr.trainee_group, ev.evaluator_group, ''), "
      "u.created_us, u.disabled FROM users u LEFT JOIN trainees tr ON tr.user_id = u.id "
      "LEFT JOIN evaluators ev ON ev.user_id = u.id ORDER BY u.id");
  if (!st.ok()) return st.error();
  std::vector<UserRecord> out;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    UserRecord u;
    u.id = (*st)->Int(0);
    u.name = (*st)->String(1);
    u.role = ParseRole((*st)->Text(2)).value_or(Role::kTrainee);
    u.group = (*st)->String(3);
    u.created_us = (*st)->Int(4);
    u.disabled = (*st)->Int(5) != 0;
    out.push_back(std::move(u));
  }
  (*st)->Reset();
  return out;
}

}  // namespace vsurg::db
