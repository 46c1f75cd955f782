// The session record (server/session/trace_recorder.h): bounded whatever the session's length,
// spanning all of it, in the telemetry's own names, and a surface frame that decodes to the
// displacement it was given (to the stated 0.01 mm).
#include "server/session/trace_recorder.h"

#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <zlib.h>

#include <cmath>
#include <nlohmann/json.hpp>

namespace vsurg::server {
namespace {

using nlohmann::json;

sim::SessionTelemetry Sample(double t) {
  sim::SessionTelemetry s;
  s.sim.time = t;
  s.sim.samples = static_cast<uint64_t>(t * 1000) + 1;
  s.sim.force = geometry::Vec3(0, 0, 0.5 + t);  // |F| = 0.5 + t N
  s.sim.twist = t * M_PI / 180;                 // t degrees
  s.rtt_us = 400;
  return s;
}

// The record's frames as the page decodes them: base64, inflate, then each frame the sum of the
// differences so far (modulo 2^16).
std::vector<std::vector<int16_t>> Frames(const json& record) {
  const std::string b64 = record["frames"]["deflated"].get<std::string>();
  std::vector<unsigned char> packed(b64.size());
  int n = EVP_DecodeBlock(packed.data(), reinterpret_cast<const unsigned char*>(b64.data()),
                          static_cast<int>(b64.size()));
  EXPECT_GE(n, 0);
  for (size_t k = b64.size(); k > 0 && b64[k - 1] == '='; --k) --n;  // EVP counts the padding
  packed.resize(static_cast<size_t>(n));
  const size_t count = record["frames"]["time_s"].size();
  const size_t values = 3 * record["frames"]["vertices"].get<size_t>();
  std::vector<unsigned char> raw(2 * values * count);
  uLongf size = static_cast<uLongf>(raw.size());
  EXPECT_EQ(uncompress(raw.data(), &size, packed.data(), static_cast<uLong>(packed.size())), Z_OK);
  EXPECT_EQ(size, raw.size());
  std::vector<std::vector<int16_t>> out;
  std::vector<uint16_t> sum(values, 0);
  for (size_t f = 0; f < count; ++f) {
    for (size_t i = 0; i < values; ++i) {
      const size_t at = 2 * (f * values + i);
      sum[i] = static_cast<uint16_t>(sum[i] + (raw[at] | (raw[at + 1] << 8)));
    }
    out.emplace_back(sum.begin(), sum.end());
  }
  return out;
}

geometry::TriMesh Triangle() {
  geometry::TriMesh m;
  m.positions = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}};
  m.triangles = {{0, 1, 2}};
  return m;
}

TEST(TraceRecorderTest, ALongSessionKeepsItsWholeSpanInBoundedMemory) {
  TraceRecorder r;
  r.SetRest(Triangle());
  // Ten minutes at the sampler's 30 Hz: 18,000 ticks, each with a newer station time.
  for (int i = 0; i < 18000; ++i) r.AddSample(Sample(i / 30.0));
  EXPECT_LE(r.samples(), TraceRecorder::kMaxSamples);
  EXPECT_GE(r.samples(), TraceRecorder::kMaxSamples / 2);
  const json j = json::parse(r.Json());
  const auto& t = j["series"]["time_s"];
  ASSERT_EQ(t.size(), r.samples());
  EXPECT_EQ(t.front().get<double>(), 0);
  EXPECT_GT(t.back().get<double>(), 599.0 - 16.0 / 30);  // the end is kept, to one stride
  for (size_t i = 1; i < t.size(); ++i) {
    ASSERT_GT(t[i].get<double>(), t[i - 1].get<double>());
    // One stride everywhere: the halving keeps the points evenly spaced.
    EXPECT_NEAR(t[i].get<double>() - t[i - 1].get<double>(), t[1].get<double>(), 2e-3);
  }
  // Every series beside time_s, in the API's names, one value per time.
  for (const char* name : {"force_n", "twist_deg", "torque_nm", "rtt_us", "score", "contact"})
    ASSERT_EQ(j["series"][name].size(), t.size()) << name;
  const size_t k = t.size() / 2;
  EXPECT_NEAR(j["series"]["force_n"][k].get<double>(), 0.5 + t[k].get<double>(), 0.01);
  EXPECT_NEAR(j["series"]["twist_deg"][k].get<double>(), t[k].get<double>(), 0.05);
}

TEST(TraceRecorderTest, AStalledStationAddsNothingAndAShortSessionKeepsEveryTick) {
  TraceRecorder r;
  r.AddSample(sim::SessionTelemetry{});  // no stylus yet
  for (int i = 0; i < 10; ++i) {
    r.AddSample(Sample(i * 0.033));
    r.AddSample(Sample(i * 0.033));  // the same station time again: stalled
  }
  EXPECT_EQ(r.samples(), 10u);
}

TEST(TraceRecorderTest, AFrameDecodesToItsDisplacementAndUnmovedVerticesStayAtRest) {
  TraceRecorder r;
  r.SetRest(Triangle());
  // Vertex 1 moved by (+1.234 mm, −0.5 mm, +20 mm); vertex 2 far (clamped); vertex 0 at rest;
  // an index past the mesh is ignored.
  r.AddSurface(0.5, {1, 2, 7}, {{0.011234, -0.0005, 0.02}, {0, 0.01, 5.0}, {1, 1, 1}});
  r.AddSurface(0.5, {1}, {{0.02, 0, 0}});  // the same time: nothing new
  r.AddSurface(0.6, {1}, {{0.02, 0, 0}});  // sooner than 5 Hz: not kept
  ASSERT_EQ(r.frames(), 1u);
  const json j = json::parse(r.Json());
  EXPECT_EQ(j["rest"]["positions_mm"].size(), 9u);
  EXPECT_EQ(j["rest"]["positions_mm"][3].get<double>(), 10);
  EXPECT_EQ(j["rest"]["triangles"], json({0, 1, 2}));
  EXPECT_EQ(j["frames"]["unit_mm"].get<double>(), 0.01);
  const auto d = Frames(j).at(0);
  ASSERT_EQ(d.size(), 9u);
  EXPECT_EQ(d[0], 0);
  EXPECT_EQ(d[1], 0);
  EXPECT_EQ(d[2], 0);
  EXPECT_EQ(d[3], 123);  // 1.234 mm → 123 × 0.01 mm
  EXPECT_EQ(d[4], -50);
  EXPECT_EQ(d[5], 2000);
  EXPECT_EQ(d[8], 32767);  // 5 m away: clamped, never wrapped
  // Many frames (vertex 0 rising 1 mm a frame, then falling back past the int16 wrap of the
  // differences): bounded, spanning the session, each restored exactly.
  for (int i = 1; i <= 1000; ++i)
    r.AddSurface(0.5 + 0.2 * i, {0, 2}, {{0, 0, 0.001 * (i % 300)}, {0, 0.01, i % 2 ? 0.3 : -0.3}});
  EXPECT_LE(r.frames(), TraceRecorder::kMaxFrames);
  const json k = json::parse(r.Json());
  const auto frames = Frames(k);
  ASSERT_EQ(frames.size(), r.frames());
  EXPECT_EQ(k["frames"]["time_s"].front().get<double>(), 0.5);
  EXPECT_EQ(frames[0], d);  // the first frame kept whole through every halving
  for (size_t f = 1; f < frames.size(); ++f) {
    const double t = k["frames"]["time_s"][f].get<double>();
    const int i = static_cast<int>(std::lround((t - 0.5) / 0.2));
    EXPECT_EQ(frames[f][2], 100 * (i % 300)) << f;         // 1 mm = 100 units
    EXPECT_EQ(frames[f][8], i % 2 ? 30000 : -30000) << f;  // ±300 mm, 60,000 apart
  }
  EXPECT_GT(k["frames"]["time_s"].back().get<double>(), 200.5 - 3.2);
}

// A palpation's record shows the lumps beside the trainee's marks, in millimetres.
TEST(TraceRecorderTest, APalpationsRecordCarriesTheLumpsAndTheMarks) {
  TraceRecorder r;
  geometry::TriMesh rest;
  rest.positions = {{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}};
  rest.triangles = {{0, 1, 2}};
  r.SetRest(rest);
  r.AddSample(Sample(0.1));
  scoring::PalpableSurface surface{{Eigen::Vector3d(0.003, 0.003, 0)}, {5e-5}};
  scoring::PalpationRecorder palpation(
      {{Eigen::Vector3d(0.004, 0.002, -0.015), 0.005, Eigen::Vector3d(0.004, 0.002, 0)},
       {Eigen::Vector3d(0.04, 0.03, -0.01), 0.004, Eigen::Vector3d(0.04, 0.03, 0)}},
      surface, {});
  palpation.Mark(1.25, Eigen::Vector3d(0.0045, 0.002, 0));
  palpation.Mark(2.5, Eigen::Vector3d(0.02, 0.03, 0));  // 20 mm from the second: false
  r.SetPalpation(palpation);
  const json record = json::parse(r.Json());
  ASSERT_TRUE(record.contains("palpation"));
  const json& p = record["palpation"];
  ASSERT_EQ(p["lumps"].size(), 2u);
  EXPECT_DOUBLE_EQ(p["lumps"][0]["radius_mm"].get<double>(), 5);
  EXPECT_DOUBLE_EQ(p["lumps"][0]["centre_mm"][2].get<double>(), -15);
  EXPECT_DOUBLE_EQ(p["lumps"][0]["surface_mm"][0].get<double>(), 4);
  EXPECT_TRUE(p["lumps"][0]["found"].get<bool>());
  EXPECT_FALSE(p["lumps"][1]["found"].get<bool>());
  ASSERT_EQ(p["marks"].size(), 2u);
  EXPECT_DOUBLE_EQ(p["marks"][0]["time_s"].get<double>(), 1.25);
  EXPECT_DOUBLE_EQ(p["marks"][0]["position_mm"][0].get<double>(), 4.5);
  EXPECT_EQ(p["marks"][0]["lump"].get<int>(), 0);
  EXPECT_EQ(p["marks"][1]["lump"].get<int>(), -1);
  // Read back as the station's summary draws it: in metres, each mark with the lump it found.
  const auto outcome = TraceRecorder::PalpationOf(r.Json());
  ASSERT_TRUE(outcome.has_value());
  ASSERT_EQ(outcome->lumps.size(), 2u);
  EXPECT_NEAR(outcome->lumps[0].centre.z(), -0.015, 1e-9);
  EXPECT_NEAR(outcome->lumps[1].radius, 0.004, 1e-9);
  EXPECT_EQ(outcome->found, (std::vector<bool>{true, false}));
  ASSERT_EQ(outcome->marks.size(), 2u);
  EXPECT_NEAR(outcome->marks[1].position.x(), 0.02, 1e-9);
  EXPECT_DOUBLE_EQ(outcome->marks[1].time, 2.5);
  EXPECT_EQ(outcome->marks[0].lump, 0);
  EXPECT_EQ(outcome->marks[1].lump, -1);
  // A record without the member, or not a record, reads as none; a malformed member too.
  EXPECT_FALSE(TraceRecorder::PalpationOf("{\"samples\": []}").has_value());
  EXPECT_FALSE(TraceRecorder::PalpationOf("not json").has_value());
  EXPECT_FALSE(TraceRecorder::PalpationOf(
                   R"({"palpation": {"lumps": [{"centre_mm": [1, 2]}], "marks": []}})")
                   .has_value());
  const auto odd = TraceRecorder::PalpationOf(
      R"({"palpation": {"lumps": [], "marks": [{"time_s": 1, "position_mm": [1, 2, 3], "lump": 7}]}})");
  ASSERT_TRUE(odd.has_value());
  EXPECT_EQ(odd->marks[0].lump, -1);  // a lump index out of range is no lump
  // Other tasks' records have none.
  TraceRecorder plain;
  plain.SetRest(rest);
  plain.AddSample(Sample(0.1));
  EXPECT_FALSE(json::parse(plain.Json()).contains("palpation"));
}

// A strip of `faces` triangles over faces + 2 vertices, and as many spare ones (a cut's copies).
geometry::TriMesh Strip(int faces) {
  geometry::TriMesh m;
  for (int i = 0; i < 2 * (faces + 2); ++i) m.positions.push_back({1e-3 * i, 1e-3 * (i % 2), 0});
  for (int f = 0; f < faces; ++f) m.triangles.push_back({f, f + 1, f + 2});
  return m;
}

// The faces the record's topology gives at `t`: the rest's with each change up to then applied.
std::vector<geometry::Triangle> FacesAt(const json& record, double t) {
  std::vector<geometry::Triangle> out;
  const auto& tris = record["rest"]["triangles"];
  for (size_t i = 0; i + 2 < tris.size(); i += 3)
    out.push_back({tris[i].get<int>(), tris[i + 1].get<int>(), tris[i + 2].get<int>()});
  const auto& times = record["topology"]["time_s"];
  for (size_t c = 0; c < times.size() && times[c].get<double>() <= t; ++c) {
    const auto& f = record["topology"]["faces"][c];
    for (size_t i = 0; i + 3 < f.size(); i += 4)
      out[f[i].get<size_t>()] = {f[i + 1].get<int>(), f[i + 2].get<int>(), f[i + 3].get<int>()};
  }
  return out;
}

// A cut's topology as it grows: each change kept as the faces it set, so that the record played
// to any time gives the faces shown then; nothing for an unchanged count, a face naming a vertex
// the record has not is left as it was, and a long cut stays bounded with its last state whole.
TEST(TraceRecorderTest, ACutsTopologyReplaysAsItGrewAndStaysBounded) {
  constexpr int kFaces = 1000;
  const geometry::TriMesh rest = Strip(kFaces);
  const int spare = kFaces + 2;
  TraceRecorder r;
  r.SetRest(rest);
  std::vector<geometry::Triangle> shown = rest.triangles;
  const auto cut = [&](double t, uint64_t count, int upto) {
    std::vector<int32_t> indices;
    std::vector<geometry::Triangle> faces;
    for (int f = 0; f < upto; ++f) {
      shown[f] = f % 3 == 0 ? geometry::Triangle{0, 0, 0} : geometry::Triangle{spare + f, f + 1, f};
      indices.push_back(f), faces.push_back(shown[f]);
    }
    r.AddTopology(t, count, indices, faces);
  };
  cut(0.5, 1, 10);
  const std::vector<geometry::Triangle> at_half = shown;
  cut(0.6, 1, 20);  // the same count: nothing new
  cut(1.0, 2, 30);
  {  // the same faces and one naming a vertex out of the record's: that one is ignored
    std::vector<int32_t> indices;
    std::vector<geometry::Triangle> faces;
    for (int f = 0; f < 30; ++f) indices.push_back(f), faces.push_back(shown[f]);
    indices.push_back(40), faces.push_back({0, 1, 99999});
    r.AddTopology(1.5, 3, indices, faces);
  }
  EXPECT_EQ(r.topology_changes(), 2u);
  json record = json::parse(r.Json());
  EXPECT_EQ(FacesAt(record, 0.4), rest.triangles);
  EXPECT_EQ(FacesAt(record, 0.7), at_half);
  EXPECT_EQ(FacesAt(record, 2.0), shown);
  EXPECT_EQ(record["topology"]["faces"][1].size(), 4u * 20) << "only what changed since";

  // A long cut, every change rewriting 100 faces: 2000 changes, 200,000 faces set in all.
  for (uint64_t k = 0; k < 2000; ++k) {
    std::vector<int32_t> indices;
    std::vector<geometry::Triangle> faces;
    for (int i = 0; i < 100; ++i) {
      const int f = static_cast<int>((k * 37 + static_cast<uint64_t>(i) * 7) % kFaces);
      shown[f] = {spare + static_cast<int>((k + static_cast<uint64_t>(i)) % spare), f + 1, f};
    }
    for (int f = 0; f < kFaces; ++f)
      if (shown[f] != rest.triangles[f]) indices.push_back(f), faces.push_back(shown[f]);
    r.AddTopology(2.0 + 0.01 * static_cast<double>(k), 10 + k, indices, faces);
  }
  record = json::parse(r.Json());
  size_t kept = 0;
  for (const auto& f : record["topology"]["faces"]) kept += f.size() / 4;
  EXPECT_LE(kept, TraceRecorder::kMaxTopologyFaces);
  EXPECT_GT(record["topology"]["time_s"].size(), 16u);
  EXPECT_EQ(FacesAt(record, 1e9), shown);
  EXPECT_NEAR(record["topology"]["time_s"].back().get<double>(), 2.0 + 0.01 * 1999, 1e-3);
  EXPECT_FALSE(json::parse(TraceRecorder{}.Json()).contains("topology"));
}

}  // namespace
}  // namespace vsurg::server
