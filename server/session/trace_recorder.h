// A session's record for the dashboard: its telemetry traces over the whole session and its
// tissue surface at a few frames per second, so that an ended session can be read and replayed
// (the session page's traces and timeline; an evaluator scores beside them).
//
// Bounded memory whatever the length: each series keeps at most a fixed number of points; when
// it is full every other point is dropped and the stride doubles, so a long session keeps its
// whole span at a coarser rate (a 1-minute trial keeps every sampler tick at 30 Hz, 1800 points,
// and every 8th surface state of the 10 Hz monitors' ones, 75 frames 0.8 s apart, which the
// replay interpolates).
//
// The series carry the telemetry's own names with units (sim::TelemetryFields: time_s, force_n,
// twist_deg, …), the same as the live API. A surface frame is every vertex's displacement from
// rest in units of 0.01 mm as little-endian int16 (±327 mm), base64: 6 bytes per vertex before
// the encoding, against ~26 in decimal JSON.
//
// Threads: one writer (the session manager's sampler, under its lock); Json() under that lock.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/geometry/mesh.h"
#include "common/sim/telemetry.h"

namespace vsurg::server {

class TraceRecorder {
 public:
  static constexpr size_t kMaxSamples = 2048;
  static constexpr size_t kMaxFrames = 96;
  static constexpr double kFrameUnitM = 1e-5;  // 0.01 mm

  // The rest surface the frames displace (kept in the record: a replay needs no scene file).
  void SetRest(const geometry::TriMesh& rest);
  // Every sampler tick: kept when the station's clock advanced since the last kept sample.
  void AddSample(const sim::SessionTelemetry& t);
  // A surface state (sim::Simulation::ShownSurface: the vertices away from rest, the others at
  // rest) at the station's time `time_s`.
  void AddSurface(double time_s, const std::vector<int32_t>& indices,
                  const std::vector<geometry::Vec3>& positions);
  size_t samples() const { return samples_.size(); }
  size_t frames() const { return frames_.size(); }
  // {"series": {"time_s": [...], "force_n": [...], ...}, "rest": {"positions_mm": [...],
  //  "triangles": [...]}, "frames": {"time_s": [...], "unit_mm": 0.01, "displacement": ["b64"]}}
  std::string Json() const;

 private:
  struct Sample {
    double time_s;
    float values[sim::kTelemetryFieldCount];
  };
  struct Frame {
    double time_s;
    std::vector<int16_t> displacement;  // 3 per vertex
  };
  // Appends `x` (the `seen`-th offered) when it falls on the stride; halves a full series.
  template <typename T>
  static void Offer(std::vector<T>& v, uint64_t& seen, uint64_t& stride, size_t max, T&& x);

  std::vector<geometry::Vec3> rest_;
  std::vector<int32_t> triangles_;
  std::vector<Sample> samples_;
  uint64_t samples_seen_ = 0, sample_stride_ = 1;
  double last_time_ = -1;
  std::vector<Frame> frames_;
  double last_frame_time_ = -1;
  uint64_t frames_seen_ = 0, frame_stride_ = 1;
};

}  // namespace vsurg::server
