// Placement across control replicas (store.h, design note 8): the nodes' load, read and reserved
// one placement at a time site-wide.
#include <openssl/rand.h>

#include "db/store_impl.h"

namespace vsurg::db {

namespace {

Expected<std::string> NewPlacementToken() {
  unsigned char raw[16];
  if (RAND_bytes(raw, sizeof raw) != 1)
    return Error{ErrorCode::kIoError, "the system random generator failed", "placement"};
  static const char* kHex = "0123456789abcdef";
  std::string t;
  for (unsigned char b : raw) {
    t.push_back(kHex[b >> 4]);
    t.push_back(kHex[b & 15]);
  }
  return t;
}

// Live sessions and unexpired reservations per node, in one statement: one snapshot, in which a
// node's commit that turns its reservation into its session's row is seen whole or not at all.
Expected<std::map<std::string, int>> NodeLoad(Connection& c, int64_t now_us) {
  auto st = c.Prepare(
      "SELECT node, count(*) FROM (SELECT node FROM sessions WHERE state IN (?1, ?2, ?3) "
      "UNION ALL SELECT node FROM placements WHERE expires_us >= ?4) AS load GROUP BY node");
  if (!st.ok()) return st.error();
  BindLiveStates(**st, 1);
  (*st)->Bind(4, now_us);
  std::map<std::string, int> load;
  for (;;) {
    auto row = (*st)->Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    load[(*st)->String(0)] = static_cast<int>((*st)->Int(1));
  }
  return load;
}

// Inside the reservation's own transaction: the lock, the expired reservations dropped, the load
// read, the choice, and its reservation written.
Status Reserve(Connection& c, const std::string& token, int64_t expires_us,
               const Store::ChooseNode& choose, std::optional<Store::Placement>& out) {
  if (Status s = c.LockPlacements(); !s.ok()) return s;
  const int64_t now = NowUs();
  if (Status s = RunSql(c, "DELETE FROM placements WHERE expires_us < ?1",
                        [&](Statement& q) { q.Bind(1, now); });
      !s.ok())
    return s;
  auto load = NodeLoad(c, now);
  if (!load.ok()) return load.error();
  out.reset();
  const std::optional<std::string> node = choose(*load);
  if (!node) return Status::Ok();
  if (Status s = RunSql(c, "INSERT INTO placements(token, node, expires_us) VALUES (?1, ?2, ?3)",
                        [&](Statement& q) { q.Bind(1, token).Bind(2, *node).Bind(3, expires_us); });
      !s.ok())
    return s;
  out = Store::Placement{*node, token};
  return Status::Ok();
}

}  // namespace

Status Store::Impl::OnPlacementConnection(const Job& job) {
  if (read_only) return Error{ErrorCode::kFailedPrecondition, "the store is open read-only", ""};
  std::lock_guard lock(placement_mutex);
  if (!placement || placement->Broken()) {
    auto c = Connection::Open(options.path, Connection::Mode::kReadWrite, options.busy_timeout_ms);
    if (!c.ok()) return c.error();
    placement = std::move(c).value();
  }
  return job(*placement);
}

Status EndPlacement(Connection& c, const std::string& token) {
  if (token.empty()) return Status::Ok();
  return RunSql(c, "DELETE FROM placements WHERE token = ?1",
                [&](Statement& q) { q.Bind(1, token); });
}

Expected<std::optional<Store::Placement>> Store::ReservePlacement(int64_t expires_us,
                                                                  const ChooseNode& choose) {
  auto token = NewPlacementToken();
  if (!token.ok()) return token.error();
  std::optional<Placement> out;
  // Its own transaction on its own connection: the lock is held only while one placement reads
  // and reserves, never while other jobs of a batch run, and it never queues behind them.
  Status s = impl_->OnPlacementConnection([&](Connection& c) -> Status {
    Status st = c.BeginWrite();
    if (!st.ok()) return st;
    st = Reserve(c, *token, expires_us, choose, out);
    if (st.ok()) st = c.Exec("COMMIT");
    if (!st.ok()) (void)c.Exec("ROLLBACK");
    return st;
  });
  if (!s.ok()) return s.error();
  return out;
}

Status Store::ReleasePlacement(const std::string& token) {
  return impl_->OnPlacementConnection([&token](Connection& c) { return EndPlacement(c, token); });
}

}  // namespace vsurg::db
