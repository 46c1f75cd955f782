// libFuzzer target: the internal API's messages (proto/vsurg/v1/cluster.proto) as a control
// replica or a node receives them, from anyone who can reach the internal port: the first byte
// chooses the message, the rest is its wire form. A heartbeat or an acquisition goes through to
// the store (a real SQLite file) as ClusterService does; telemetry and session answers through
// the conversions the control plane applies to a node's replies.
// Properties: nothing crashes; a heartbeat is accepted only from the instance that holds the
// name at that epoch; an acquisition the store accepts leaves exactly that instance and epoch in
// the registry, and a refused one changes nothing; a node's reply converts with every list and
// key within its bounds.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "db/store.h"
#include "proto/convert/services.h"
#include "server/cluster/cluster_common.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

using namespace vsurg;
namespace v1 = vsurg::v1;

struct World {
  std::filesystem::path dir;
  std::unique_ptr<db::Store> store;
  World() {
    dir = std::filesystem::temp_directory_path() /
          ("vsurg_fuzz_cluster_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    store = db::Store::Open({.path = (dir / "vsurg.db").string()}).value();
  }
  ~World() {
    store.reset();
    std::filesystem::remove_all(dir);
  }
};

std::optional<db::NodeRecord> Row(db::Store& store, const std::string& name) {
  auto nodes = store.ListNodes();
  if (!nodes.ok()) return std::nullopt;
  for (const db::NodeRecord& n : *nodes)
    if (n.name == name) return n;
  return std::nullopt;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static World world;
  if (size < 1) return 0;
  const uint8_t op = data[0] % 4;
  const void* body = data + 1;
  const int n = static_cast<int>(size - 1);
  constexpr int64_t kTimeoutUs = 2'000'000;
  switch (op) {
    case 0:    // ClusterService.Acquire
    case 1: {  // ClusterService.Heartbeat
      v1::NodeHeartbeat beat;
      if (!beat.ParseFromArray(body, n)) return 0;
      const db::NodeRecord rec = server::cluster::FromProto(beat, db::NowUs());
      const auto before = Row(*world.store, rec.name);
      if (op == 0) {
        auto lease = world.store->AcquireNode(rec, kTimeoutUs, "fuzz");
        const auto after = Row(*world.store, rec.name);
        if (lease.ok()) {
          VSURG_FUZZ_CHECK(after && after->instance == rec.instance && !after->down);
          VSURG_FUZZ_CHECK(after->epoch == lease->epoch);
          VSURG_FUZZ_CHECK(!before || lease->epoch == before->epoch + 1);
        } else if (before) {
          VSURG_FUZZ_CHECK(after && after->epoch == before->epoch &&
                           after->instance == before->instance);
        }
      } else {
        const Status s = world.store->BeatNode(rec);
        if (s.ok())
          VSURG_FUZZ_CHECK(before && before->instance == rec.instance &&
                           before->epoch == rec.epoch && !before->down);
      }
      break;
    }
    case 2: {  // NodeService.Telemetry's reply, as the control plane's poller reads it
      v1::NodeTelemetry t;
      if (!t.ParseFromArray(body, n)) return 0;
      for (const v1::Telemetry& one : t.sessions()) {
        const sim::SessionTelemetry s = convert::FromProto(one);
        VSURG_FUZZ_CHECK(s.surface_positions.size() ==
                         static_cast<size_t>(one.surface().positions_size() / 3));
      }
      break;
    }
    default: {  // NodeService.Create/Join's reply
      v1::NodeSession s;
      if (!s.ParseFromArray(body, n)) return 0;
      const server::CreatedSession c = server::cluster::FromProto(s);
      VSURG_FUZZ_CHECK(c.udp_port == static_cast<uint16_t>(s.udp_port()));
      break;
    }
  }
  return 0;
}
