// The nodes' telemetry: one stream per node, only what someone on this replica watches, and the
// subscribers it feeds.
#include "common/core/realtime.h"
#include "server/cluster/cluster_impl.h"

namespace vsurg::server::cluster {

void ClusterSessions::Impl::OpenStream(const std::string& node, const db::NodeRecord& n,
                                       WatchSpec spec) {
  auto st = std::make_unique<NodeStream>();
  st->address = n.grpc_address;
  st->spec = std::move(spec);
  st->ctx = CallContext(options.token, 0);
  st->last_message = std::chrono::steady_clock::now();
  v1::NodeWatchRequest req;
  req.set_all(st->spec.all);
  for (uint64_t id : st->spec.sessions) req.add_sessions(id);
  for (uint64_t id : st->spec.surfaces) req.add_surfaces(id);
  req.set_rate_hz(options.telemetry_hz);
  NodeStream* p = st.get();
  std::shared_ptr<grpc::ClientReader<v1::NodeTelemetry>> reader =
      StubFor(n).Watch(p->ctx.get(), req);
  watch_opened.fetch_add(1, std::memory_order_relaxed);
  p->reader = std::thread([this, p, reader] {
    NameThisThread("vsurg-watch");
    v1::NodeTelemetry msg;
    while (reader->Read(&msg)) {
      watch_bytes.fetch_add(msg.ByteSizeLong(), std::memory_order_relaxed);
      std::map<uint64_t, SessionTelemetry> next;
      for (const v1::Telemetry& t : msg.sessions()) next[t.session_id()] = convert::FromProto(t);
      std::lock_guard lock(p->mutex);
      for (auto& [id, t] : next) {
        const auto old = p->latest.find(id);
        if (!t.has_surface && old != p->latest.end() && old->second.has_surface) {
          t.has_surface = true;
          t.surface_frame = old->second.surface_frame;
          t.surface_indices = std::move(old->second.surface_indices);
          t.surface_positions = std::move(old->second.surface_positions);
        }
      }
      p->latest = std::move(next);
      p->last_message = std::chrono::steady_clock::now();
    }
    reader->Finish();
    std::lock_guard lock(p->mutex);
    p->done = true;
    p->latest.clear();
  });
  streams[node] = std::move(st);
  streams_open.store(static_cast<int>(streams.size()), std::memory_order_relaxed);
}

void ClusterSessions::Impl::CloseStream(
    std::map<std::string, std::unique_ptr<NodeStream>>::iterator it) {
  it->second->ctx->TryCancel();
  if (it->second->reader.joinable()) it->second->reader.join();
  streams.erase(it);
  streams_open.store(static_cast<int>(streams.size()), std::memory_order_relaxed);
}

void ClusterSessions::Impl::Reconcile(bool all, const std::set<uint64_t>& watched) {
  std::map<std::string, WatchSpec> want;
  std::map<std::string, db::NodeRecord> up;
  auto nodes = store.ListNodes();
  if (!nodes.ok()) return;  // keep what runs
  const int64_t now = db::NowUs();
  for (const db::NodeRecord& n : *nodes)
    if (Healthy(n, now)) {
      up[n.name] = n;
      if (all) want[n.name].all = true;
    }
  for (uint64_t id : watched) {
    auto row = store.GetSession(static_cast<int64_t>(id));
    if (!row.ok() || !vsurg::IsLive(row->state) || !up.count(row->node)) continue;
    WatchSpec& w = want[row->node];
    if (!w.all) w.sessions.insert(id);
    w.surfaces.insert(id);
  }
  for (auto it = streams.begin(); it != streams.end();) {
    auto next = std::next(it);
    const auto w = want.find(it->first);
    bool done;
    {
      std::lock_guard lock(it->second->mutex);
      done = it->second->done;
    }
    if (w == want.end() || !(w->second == it->second->spec) || done ||
        up[it->first].grpc_address != it->second->address)
      CloseStream(it);
    it = next;
  }
  for (auto& [node, w] : want)
    if (!streams.count(node)) OpenStream(node, up[node], std::move(w));
}

void ClusterSessions::Impl::PollerLoop() {
  const double period = 1.0 / options.telemetry_hz;
  // A stream silent this long is a node frozen or cut off: its sessions are left out (their
  // watchers get nothing from it) until it speaks again or the watchdog declares it down.
  const auto silent =
      std::chrono::microseconds(static_cast<int64_t>(std::max(0.5, 3 * period) * 1e6));
  const int reconcile_every = std::max(1, static_cast<int>(0.2 / period));  // 5 times a second
  int tick = 0;
  std::optional<std::pair<bool, std::set<uint64_t>>> last;
  while (WaitFor(period)) {
    std::pair<bool, std::set<uint64_t>> watch;
    {
      std::lock_guard lock(subscribers_mutex);
      for (const auto& [token, sub] : subscribers) {
        if (sub.ended) continue;
        if (sub.session == 0)
          watch.first = true;
        else
          watch.second.insert(sub.session);
      }
    }
    if (!watch.first && watch.second.empty()) {
      while (!streams.empty()) CloseStream(streams.begin());
      last.reset();
      continue;
    }
    if (!last || *last != watch || ++tick % reconcile_every == 0) {
      Reconcile(watch.first, watch.second);
      last = watch;
    }
    std::vector<SessionTelemetry> all;
    const auto now = std::chrono::steady_clock::now();
    for (auto& [node, st] : streams) {
      std::lock_guard lock(st->mutex);
      if (now - st->last_message > silent) continue;
      for (const auto& [id, t] : st->latest) all.push_back(t);
    }
    std::lock_guard lock(subscribers_mutex);
    for (auto& [token, sub] : subscribers) {
      if (sub.ended) continue;
      if (sub.session == 0) {
        sub.fn(all, false);
        continue;
      }
      std::vector<SessionTelemetry> one;
      for (const SessionTelemetry& t : all)
        if (t.id == sub.session) one.push_back(t);
      if (!one.empty()) {
        sub.fn(one, false);
        continue;
      }
      // Not on any node's stream now: ended (or its node is gone), unless the store still
      // says live (a stream just opened, or a node that missed a beat).
      auto row = store.GetSession(static_cast<int64_t>(sub.session));
      if (row.ok() && vsurg::IsLive(row->state)) continue;
      sub.ended = true;
      sub.fn({}, true);
    }
  }
  while (!streams.empty()) CloseStream(streams.begin());
}

uint64_t ClusterSessions::Subscribe(uint64_t session, Subscriber fn) {
  std::lock_guard lock(impl_->subscribers_mutex);
  const uint64_t token = impl_->next_token++;
  impl_->subscribers[token] = {session, std::move(fn), false};
  return token;
}

void ClusterSessions::Unsubscribe(uint64_t token) {
  std::lock_guard lock(impl_->subscribers_mutex);  // waits for a delivery in progress
  impl_->subscribers.erase(token);
}

}  // namespace vsurg::server::cluster
