// A session's record for the dashboard: its telemetry traces over the whole session and its
// tissue surface at a few frames per second, so that an ended session can be read and replayed
// (the session page's traces and timeline; an evaluator scores beside them).
//
// Bounded memory whatever the length: each series keeps at most a fixed number of points; when
// it is full every other point is dropped and the stride doubles, so a long session keeps its
// whole span at a coarser rate (a 1-minute trial keeps every sampler tick at 30 Hz, 1800 points,
// and of its surface taken at 5 Hz every 4th state, 75 frames 0.8 s apart, which the replay
// interpolates).
//
// The series carry the telemetry's own names with units (sim::TelemetryFields: time_s, force_n,
// twist_deg, …), the same as the live API. A surface frame is every vertex's displacement from
// rest in units of 0.01 mm as little-endian int16 (±327 mm), kept as they are: taking one costs
// the quantisation only, since deflating each on the sampler thread was timed at 0.7–0.8 ms for
// a frame of the forearm's 6,182 vertices (synthetic displacements); memory is at most kMaxFrames ×
// 6 bytes × vertices (3.6 MB for the forearm, 0.6 MB for an organ of 1,026). The record sends the
// frames as one deflate stream of each frame's difference from the one before (modulo 2¹⁶, so the
// running sum restores each exactly): a held twist costs almost nothing. A 7 s arm trial's 35
// frames (bench/record_size.py, docs/BENCHMARKS.md): 1.73 MB as plain base64, 0.65 MB deflated one
// by one, 0.22 MB sent. A synthetic minute of a twisting forearm (75 frames kept of 300): a frame
// taken in at most 0.27 ms (the halving included), the record serialised in 29 ms, 0.47 MB.
//
// Threads: one writer (the session manager's sampler, under its lock). Json() reads only: a copy
// taken under that lock is serialised outside it (deflating is the slow part).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/geometry/mesh.h"
#include "common/scoring/palpation.h"
#include "common/sim/telemetry.h"

namespace vsurg::server {

class TraceRecorder {
 public:
  static constexpr size_t kMaxSamples = 2048;
  static constexpr size_t kMaxFrames = 96;
  static constexpr double kFrameUnitM = 1e-5;   // 0.01 mm
  static constexpr double kFramePeriodS = 0.2;  // of the station's clock: 5 Hz

  // The rest surface the frames displace (kept in the record: a replay needs no scene file).
  void SetRest(const geometry::TriMesh& rest);
  // Every sampler tick: kept when the station's clock advanced since the last kept sample.
  void AddSample(const sim::SessionTelemetry& t);
  // A surface state (sim::Simulation::ShownSurface: the vertices away from rest, the others at
  // rest) at the station's time `time_s`.
  void AddSurface(double time_s, const std::vector<int32_t>& indices,
                  const std::vector<geometry::Vec3>& positions);
  // A cut scene's topology as the frames last showed it (sim::Simulation::ShownTopology: every
  // face that differs from the rest mesh's, a removed one {0, 0, 0}), `topology` the count of
  // changes so far: kept as the faces that differ from the topology kept before, at `time_s`, so
  // the replay shows the cut growing. Bounded: past kMaxTopologyChanges faces in all, each two
  // neighbouring changes merge into one (the later), so a long cut keeps its whole span at a
  // coarser step; all merged into one, the changes are at most the mesh's faces.
  void AddTopology(double time_s, uint64_t topology, const std::vector<int32_t>& face_indices,
                   const std::vector<geometry::Triangle>& faces);
  size_t topology_changes() const { return topology_.size(); }
  static constexpr size_t kMaxTopologyFaces = 65536;
  // A palpation's lumps and the trainee's marks, shown with the record once the search is over
  // (the station never shows the lumps during it): "palpation": {"lumps": [{"centre_mm",
  // "radius_mm", "surface_mm", "found"}], "marks": [{"time_s", "position_mm", "lump"}]} in the
  // record (a mark's lump: the index of the lump it found, -1 for a false mark). Set at the
  // session's end; not part of the moved state (the receiver's own simulation has it).
  void SetPalpation(const scoring::PalpationRecorder& palpation);
  // That member read back from a record's JSON (the station's summary draws it); nullopt when the
  // record has none or it is malformed.
  static std::optional<scoring::PalpationOutcome> PalpationOf(const std::string& record_json);
  // A needle insertion's target and the tracts the needle left (the record's "needle" member):
  // the replay draws them beside the tool's path.
  void SetNeedle(const haptics::NeedleModel& needle);
  size_t samples() const { return samples_.size(); }
  size_t frames() const { return frames_.size(); }
  // {"series": {"time_s": [...], "force_n": [...], ...}, "rest": {"positions_mm": [...],
  //  "triangles": [...]}, "frames": {"time_s": [...], "unit_mm": 0.01, "vertices": V,
  //  "deflated": "b64 of deflate(frame 0, frame 1 − frame 0, …)"}}, and for a cut
  //  "topology": {"time_s": [...], "faces": [[face, a, b, c, face, a, b, c, ...], ...]}: each
  //  change the faces it set, applied in turn to the rest triangles.
  std::string Json() const;
  // The record so far (common/core/state_archive.h; live migration), not the rest surface: the
  // receiver sets that from its own simulation first. Loaded series are checked against it.
  template <class A>
  void Persist(A& a) {
    a(samples_, samples_seen_, sample_stride_, last_time_, frames_, last_frame_time_, frames_seen_,
      frame_stride_);
  }
  // After a Persist read: the series within their bounds and each frame of this rest's size.
  bool Consistent() const;

 private:
  struct Sample {
    double time_s;
    float values[sim::kTelemetryFieldCount];
    template <class A>
    void Persist(A& a) {
      a(time_s, values);
    }
  };
  struct Frame {
    double time_s;
    std::vector<int16_t> displacement;  // 3 per vertex, units of kFrameUnitM
    template <class A>
    void Persist(A& a) {
      a(time_s, displacement);
    }
  };
  struct TopologyChange {
    double time_s;
    std::vector<int32_t> faces;  // face, a, b, c for each face the change set
  };
  void MergeTopologyChanges();
  // Appends `x` (the `seen`-th offered) when it falls on the stride; halves a full series.
  template <typename T>
  static void Offer(std::vector<T>& v, uint64_t& seen, uint64_t& stride, size_t max, T&& x);

  std::vector<geometry::Vec3> rest_;
  std::vector<int32_t> triangles_;
  std::vector<Sample> samples_;
  uint64_t samples_seen_ = 0, sample_stride_ = 1;
  double last_time_ = -1;
  std::vector<Frame> frames_;
  // A cut's changes (not part of the moved state: a cut session is never moved), the faces as
  // the last change left them, the topology count kept last and the face entries in all.
  std::vector<TopologyChange> topology_;
  std::vector<geometry::Triangle> faces_now_;
  uint64_t topology_seen_ = 0;
  size_t topology_faces_ = 0;
  std::string palpation_;  // the "palpation" member's JSON, or empty
  std::string needle_;     // the "needle" member's JSON, or empty
  double last_frame_time_ = -1;
  uint64_t frames_seen_ = 0, frame_stride_ = 1;
};

}  // namespace vsurg::server
