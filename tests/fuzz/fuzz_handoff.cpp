// libFuzzer target: a live session's handoff (live migration: NodeService.Adopt and
// ClusterService.Migrate carry it; server/session/session_manager.h SessionHandoff), as a node
// adopting a session reads it from anyone who can reach the internal port. The first byte chooses
// what the rest is:
//   0  the handoff's bytes as sent (a length, then deflated): SessionHandoff::FromBytes;
//   1  the handoff's bytes before deflation, deflated here the way Bytes() does, so the fuzzer
//      reaches the reader itself rather than zlib's checksum;
//   2  a simulation's state (Simulation::RestoreState) for one of three scenes (the second byte
//      picks it): a mass-spring, a ring layer and a coil model;
//   3  a trial record's state (TraceRecorder, read as SessionManager::Adopt reads it).
// Properties: nothing crashes; a handoff that reads back is live, keyed and named, and reads back
// the same after Bytes(); a refused simulation state leaves the simulation as it was built (its
// own state unchanged), and a taken one answers the next stylus samples with finite forces within
// the device's limit and is itself taken by a fresh simulation; a record that reads back whole is
// consistent.
#include <zlib.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>

#include "common/core/state_archive.h"
#include "common/sim/simulation.h"
#include "server/session/session_manager.h"
#include "server/session/trace_recorder.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

using namespace vsurg;

constexpr std::array<const char*, 3> kScenes = {"sphere-palpation-256", "sphere-palpation-rings",
                                                "arm-torsion"};

struct World {
  std::array<sim::Scene, kScenes.size()> scenes;
  std::array<std::string, kScenes.size()> built;  // each scene's state as Create leaves it
  std::array<geometry::TriMesh, kScenes.size()> rest;
  World() {
    for (size_t i = 0; i < kScenes.size(); ++i) {
      auto scene = sim::LoadSceneByName(kScenes[i]);
      VSURG_FUZZ_CHECK(scene.ok());
      scenes[i] = std::move(scene).value();
      auto sim = Make(i);
      built[i] = sim->SaveState();
      rest[i] = sim->rest_mesh();
    }
  }
  std::unique_ptr<sim::Simulation> Make(size_t i) const {
    sim::SimulationOptions o;
    o.threaded = false;
    auto s = sim::Simulation::Create(scenes[i], o);
    VSURG_FUZZ_CHECK(s.ok());
    return std::move(s).value();
  }
};

World& TheWorld() {
  static World world;
  return world;
}

bool Same(const server::SessionHandoff& a, const server::SessionHandoff& b) {
  return a.id == b.id && a.trainee == b.trainee && a.scene == b.scene && a.state == b.state &&
         a.created_us == b.created_us && a.started_us == b.started_us && a.key == b.key &&
         a.simulation == b.simulation && a.trace == b.trace && a.applied == b.applied &&
         a.lost == b.lost && a.span_s == b.span_s && a.rtt_us == b.rtt_us &&
         a.jitter_us == b.jitter_us && a.rendered_peak_n == b.rendered_peak_n &&
         a.rendered_over_limit_s == b.rendered_over_limit_s && a.from_node == b.from_node &&
         a.from_epoch == b.from_epoch && a.task.kind == b.task.kind &&
         a.task.target == b.task.target;
}

void CheckHandoff(std::string_view bytes) {
  auto h = server::SessionHandoff::FromBytes(bytes);
  if (!h.ok()) {
    VSURG_FUZZ_CHECK(h.error().field == "handoff");
    return;
  }
  VSURG_FUZZ_CHECK(h->key.size() == 32 && IsLive(h->state) && h->id > 0 && !h->from_node.empty());
  auto again = server::SessionHandoff::FromBytes(h->Bytes());
  VSURG_FUZZ_CHECK(again.ok() && Same(*h, *again));
}

// Twenty stylus samples after the restored trial's time, the tip rising through the scene's centre
// with the grasp pressed for the last ten: enough for the restored state to act.
void CheckSimulation(size_t which, std::string_view bytes) {
  const World& w = TheWorld();
  auto sim = w.Make(which);
  const Status s = sim->RestoreState(bytes);
  if (!s.ok()) {
    VSURG_FUZZ_CHECK(sim->SaveState() == w.built[which]);
    return;
  }
  const std::string taken = sim->SaveState();
  auto fresh = w.Make(which);
  VSURG_FUZZ_CHECK(fresh->RestoreState(taken).ok());
  const double limit = w.scenes[which].haptics.limits.max_force;
  const double t0 = sim->trial_time();
  for (int k = 0; k < 20; ++k) {
    haptics::StylusSample in;
    in.time = t0 + 1e-3 * (k + 1);
    in.position = geometry::Vec3(0, 0, 0.002 * k);
    in.buttons = k >= 10 ? haptics::kButtonGrasp : 0u;
    const haptics::ForceCommand out = sim->OnStylus(in);
    VSURG_FUZZ_CHECK(std::isfinite(out.force.x()) && std::isfinite(out.force.y()) &&
                     std::isfinite(out.force.z()));
    VSURG_FUZZ_CHECK(out.force.norm() <= limit);
  }
}

void CheckRecord(size_t which, std::string_view bytes) {
  const World& w = TheWorld();
  server::TraceRecorder trace;
  trace.SetRest(w.rest[which]);
  StateReader r(bytes);
  r(trace);
  if (r.done() && trace.Consistent()) {
    // What Adopt takes writes back the same way it was read, and its record renders.
    StateWriter out;
    out(trace);
    VSURG_FUZZ_CHECK(out.bytes() == bytes);
    VSURG_FUZZ_CHECK(!trace.Json().empty());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const uint8_t op = data[0] % 4;
  const std::string_view rest(reinterpret_cast<const char*>(data + 1), size - 1);
  switch (op) {
    case 0:
      CheckHandoff(rest);
      break;
    case 1: {
      // The framing Bytes() writes: the inflated size (8 bytes, host order), then zlib.
      const uint64_t n = rest.size();
      uLongf room = compressBound(static_cast<uLong>(n));
      std::string sent(8 + room, '\0');
      std::memcpy(sent.data(), &n, 8);
      VSURG_FUZZ_CHECK(compress2(reinterpret_cast<Bytef*>(sent.data() + 8), &room,
                                 reinterpret_cast<const Bytef*>(rest.data()), static_cast<uLong>(n),
                                 1) == Z_OK);
      sent.resize(8 + room);
      CheckHandoff(sent);
      break;
    }
    case 2:
      CheckSimulation(static_cast<uint8_t>(rest[0]) % kScenes.size(), rest.substr(1));
      break;
    default:
      CheckRecord(static_cast<uint8_t>(rest[0]) % kScenes.size(), rest.substr(1));
      break;
  }
  return 0;
}
