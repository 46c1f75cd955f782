// The wire's encodings a node runs for every station: a scene frame split into sealed chunks, a
// twist frame, and the tag every datagram carries against the MACs that could replace it.
#include <benchmark/benchmark.h>

#include <array>
#include <cstring>
#include <numbers>
#include <vector>

#include <openssl/evp.h>
#include <openssl/params.h>

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

// BM_TwistFrameEncode: the same arm's frame as its twist (key, grasp, arc, torque), one chunk.
void BM_TwistFrameEncode(benchmark::State& state) {
  vsurg::wire::SessionKey key{};
  key.fill(7);
  const vsurg::wire::Authenticator auth(key);
  vsurg::wire::Codec codec;
  std::array<uint8_t, vsurg::wire::kMaxDatagram> out{};
  const vsurg::wire::CoilTwist twist{0x9e3779b97f4a7c15ull, 3, 0.2473, 0.0351};
  size_t bytes = 0;
  for (auto _ : state) {
    bytes = codec.EncodeTwistFrame(
        1, twist, {vsurg::wire::kProtocolVersion, vsurg::wire::PayloadType::kSceneFrame, 1, 1},
        auth, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_TwistFrameEncode)->Unit(benchmark::kNanosecond);

// BM_DatagramTag/<mac>: the tag of a stylus datagram's bytes (header and a 70-byte payload, the
// size of a stylus sample's), by each keyed construction with a per-session key made ready once
// (as the Authenticator does), then copied per datagram. 0: HMAC-SHA256 as the wire uses it
// (Authenticator::Tag); 1-3: OpenSSL's EVP_MAC BLAKE2SMAC, SIPHASH (128-bit tag), POLY1305
// (one-time key: a real use must derive a key per datagram, e.g. ChaCha20's block, not counted);
// 4, 5: AES-128-GCM and ChaCha20-Poly1305 over no plaintext with the bytes as associated data
// (GMAC-like; a nonce per datagram, the sequence number, here the iteration).
void BM_DatagramTag(benchmark::State& state) {
  std::array<uint8_t, 102> bytes{};
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(i * 13);
  vsurg::wire::SessionKey key{};
  key.fill(7);
  const int which = static_cast<int>(state.range(0));
  std::array<uint8_t, 64> tag{};
  uint64_t n = 0;
  if (which == 0) {
    const vsurg::wire::Authenticator auth(key);
    for (auto _ : state) {
      bytes[0] = static_cast<uint8_t>(++n);
      benchmark::DoNotOptimize(auth.Tag(bytes));
    }
    state.SetLabel("HMAC-SHA256");
    return;
  }
  if (which <= 3) {
    const char* names[] = {"", "BLAKE2SMAC", "SIPHASH", "POLY1305"};
    EVP_MAC* mac = EVP_MAC_fetch(nullptr, names[which], nullptr);
    if (mac == nullptr) return state.SkipWithError("no such MAC");
    EVP_MAC_CTX* ready = EVP_MAC_CTX_new(mac);
    size_t size = 16;
    OSSL_PARAM params[] = {OSSL_PARAM_construct_size_t("size", &size), OSSL_PARAM_construct_end()};
    const size_t key_size = which == 2 ? 16 : 32;
    if (EVP_MAC_init(ready, key.data(), key_size, which == 3 ? nullptr : params) != 1)
      return state.SkipWithError("init");
    for (auto _ : state) {
      bytes[0] = static_cast<uint8_t>(++n);
      EVP_MAC_CTX* c = EVP_MAC_CTX_dup(ready);
      size_t out = 0;
      EVP_MAC_update(c, bytes.data(), bytes.size());
      EVP_MAC_final(c, tag.data(), &out, tag.size());
      EVP_MAC_CTX_free(c);
      benchmark::DoNotOptimize(tag.data());
    }
    EVP_MAC_CTX_free(ready);
    EVP_MAC_free(mac);
    state.SetLabel(names[which]);
    return;
  }
  const EVP_CIPHER* cipher = which == 4 ? EVP_aes_128_gcm() : EVP_chacha20_poly1305();
  EVP_CIPHER_CTX* c = EVP_CIPHER_CTX_new();
  EVP_EncryptInit_ex(c, cipher, nullptr, key.data(), nullptr);
  std::array<uint8_t, 12> nonce{};
  for (auto _ : state) {
    ++n;
    std::memcpy(nonce.data(), &n, sizeof n);
    int len = 0;
    EVP_EncryptInit_ex(c, nullptr, nullptr, nullptr, nonce.data());
    EVP_EncryptUpdate(c, nullptr, &len, bytes.data(), static_cast<int>(bytes.size()));
    EVP_EncryptFinal_ex(c, tag.data(), &len);
    EVP_CIPHER_CTX_ctrl(c, EVP_CTRL_AEAD_GET_TAG, 16, tag.data());
    benchmark::DoNotOptimize(tag.data());
  }
  EVP_CIPHER_CTX_free(c);
  state.SetLabel(which == 4 ? "AES-128-GMAC" : "ChaCha20-Poly1305");
}
BENCHMARK(BM_DatagramTag)->DenseRange(0, 5)->Unit(benchmark::kNanosecond);

}  // namespace
