// The wire's encodings a node runs for every station: a scene frame split into sealed chunks.
#include <benchmark/benchmark.h>

#include <array>
#include <numbers>
#include <vector>

#include "common/sim/simulation.h"
#include "proto/wire/datagram.h"
#include "proto/wire/messages.h"

namespace {

// BM_SceneFrameEncode: one twisted arm's frame (arm-torsion's surface turned 20° about the limb's
// axis, so every vertex moved, as in a twist; the visual sender's case at 60 Hz per twisting
// station), planned, encoded and sealed into chunks of at most a datagram each.
void BM_SceneFrameEncode(benchmark::State& state) {
  auto scene = vsurg::sim::LoadSceneByName("arm-torsion");
  if (!scene.ok()) return state.SkipWithError("scene");
  auto mesh = vsurg::sim::BuildSceneMesh(scene->mesh);
  if (!mesh.ok()) return state.SkipWithError("mesh");
  const Eigen::AngleAxisd turn(20 * std::numbers::pi / 180, Eigen::Vector3d::UnitZ());
  std::vector<int32_t> indices;
  std::vector<Eigen::Vector3d> positions;
  for (size_t i = 0; i < mesh->surface.positions.size(); ++i) {
    indices.push_back(static_cast<int32_t>(i));
    positions.push_back(turn * mesh->surface.positions[i]);
  }
  vsurg::wire::SessionKey key{};
  key.fill(7);
  const vsurg::wire::Authenticator auth(key);
  vsurg::wire::Codec codec;
  std::array<uint8_t, vsurg::wire::kMaxDatagram> out{};
  const vsurg::wire::SceneFrameView view{1, indices, positions};
  size_t chunks = 0, bytes = 0;
  for (auto _ : state) {
    bytes = 0;
    chunks = codec.EncodeSceneFrame(
        view, {vsurg::wire::kProtocolVersion, vsurg::wire::PayloadType::kSceneFrame, 1, 1}, auth,
        out, [&](std::span<const uint8_t> d) { bytes += d.size(); });
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["vertices"] = static_cast<double>(indices.size());
  state.counters["chunks"] = static_cast<double>(chunks);
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_SceneFrameEncode)->Unit(benchmark::kMicrosecond);

}  // namespace
