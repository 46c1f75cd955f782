#include "server/session/trace_recorder.h"

#include <openssl/evp.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace vsurg::server {
namespace {

// Rounded to what the figure means (3 significant decimals are plenty for a plot), so the stored
// text stays short: 0.1234567 → 0.123.
double Round(double v, int decimals) {
  if (!std::isfinite(v)) return 0;
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

std::string Base64(const std::vector<uint8_t>& bytes) {
  std::string out(4 * ((bytes.size() + 2) / 3) + 1, '\0');
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()), bytes.data(),
                                static_cast<int>(bytes.size()));
  out.resize(static_cast<size_t>(std::max(n, 0)));
  return out;
}

std::vector<uint8_t> Deflate(const std::vector<uint8_t>& in, int level) {
  uLongf size = compressBound(static_cast<uLong>(in.size()));
  std::vector<uint8_t> out(size);
  if (compress2(out.data(), &size, in.data(), static_cast<uLong>(in.size()), level) != Z_OK)
    return {};
  out.resize(size);
  return out;
}

}  // namespace

template <typename T>
void TraceRecorder::Offer(std::vector<T>& v, uint64_t& seen, uint64_t& stride, size_t max, T&& x) {
  const uint64_t index = seen++;
  if (index % stride != 0) return;
  if (v.size() == max) {  // keep the points on the doubled stride: every other one
    size_t kept = 0;
    for (size_t i = 0; i < v.size(); i += 2, ++kept)
      if (kept != i) v[kept] = std::move(v[i]);  // (a self-move would empty the first)
    v.resize(kept);
    stride *= 2;
    if (index % stride != 0) return;
  }
  v.push_back(std::move(x));
}

void TraceRecorder::SetRest(const geometry::TriMesh& rest) {
  rest_ = rest.positions;
  triangles_.clear();
  triangles_.reserve(3 * rest.triangles.size());
  for (const auto& t : rest.triangles)
    for (int k = 0; k < 3; ++k) triangles_.push_back(static_cast<int32_t>(t[k]));
}

void TraceRecorder::AddSample(const sim::SessionTelemetry& t) {
  if (t.sim.samples == 0 || !(t.sim.time > last_time_)) return;  // nothing new from the station
  last_time_ = t.sim.time;
  Sample s{t.sim.time, {}};
  const auto fields = sim::TelemetryFields(t);
  for (size_t i = 0; i < fields.size(); ++i) s.values[i] = static_cast<float>(fields[i].value);
  Offer(samples_, samples_seen_, sample_stride_, kMaxSamples, std::move(s));
}

void TraceRecorder::AddSurface(double time_s, const std::vector<int32_t>& indices,
                               const std::vector<geometry::Vec3>& positions) {
  // A stalled station gives no new state; more often than kFramePeriodS is not kept.
  if (rest_.empty() || !(time_s >= last_frame_time_ + kFramePeriodS * 0.99)) return;
  last_frame_time_ = time_s;
  Frame f{time_s, std::vector<int16_t>(3 * rest_.size(), 0)};
  const size_t n = std::min(indices.size(), positions.size());
  for (size_t k = 0; k < n; ++k) {
    const auto v = static_cast<size_t>(indices[k]);
    if (v >= rest_.size()) continue;
    for (int c = 0; c < 3; ++c) {
      const double u = std::round((positions[k][c] - rest_[v][c]) / kFrameUnitM);
      f.displacement[3 * v + static_cast<size_t>(c)] =
          static_cast<int16_t>(std::clamp(std::isfinite(u) ? u : 0.0, -32767.0, 32767.0));
    }
  }
  Offer(frames_, frames_seen_, frame_stride_, kMaxFrames, std::move(f));
}

void TraceRecorder::AddTopology(double time_s, uint64_t topology,
                                const std::vector<int32_t>& face_indices,
                                const std::vector<geometry::Triangle>& faces) {
  const size_t n = triangles_.size() / 3;
  if (topology == 0 || topology == topology_seen_ || n == 0 || !std::isfinite(time_s)) return;
  topology_seen_ = topology;
  std::vector<geometry::Triangle> shown(n);
  for (size_t f = 0; f < n; ++f)
    for (int k = 0; k < 3; ++k) shown[f][k] = triangles_[3 * f + static_cast<size_t>(k)];
  const size_t given = std::min(face_indices.size(), faces.size());
  for (size_t k = 0; k < given; ++k) {
    const auto f = static_cast<size_t>(face_indices[k]);
    if (f >= n) continue;
    bool inside = true;  // a face naming a vertex the record has not is left as it was
    for (int c = 0; c < 3; ++c)
      inside = inside && faces[k][c] >= 0 && static_cast<size_t>(faces[k][c]) < rest_.size();
    if (inside) shown[f] = faces[k];
  }
  if (faces_now_.size() != n) {  // the first change: from the rest triangles
    faces_now_.resize(n);
    for (size_t f = 0; f < n; ++f)
      for (int k = 0; k < 3; ++k) faces_now_[f][k] = triangles_[3 * f + static_cast<size_t>(k)];
  }
  TopologyChange change{time_s, {}};
  for (size_t f = 0; f < n; ++f) {
    if (shown[f] == faces_now_[f]) continue;
    change.faces.insert(change.faces.end(),
                        {static_cast<int32_t>(f), shown[f][0], shown[f][1], shown[f][2]});
    faces_now_[f] = shown[f];
  }
  if (change.faces.empty()) return;
  topology_faces_ += change.faces.size() / 4;
  topology_.push_back(std::move(change));
  while (topology_faces_ > kMaxTopologyFaces && topology_.size() > 1) MergeTopologyChanges();
}

// Each two neighbouring changes into one at the later's time, a face set by both kept once with
// the later's value.
void TraceRecorder::MergeTopologyChanges() {
  std::vector<TopologyChange> merged;
  std::vector<bool> by_later(triangles_.size() / 3, false);
  topology_faces_ = 0;
  for (size_t i = 0; i < topology_.size(); i += 2) {
    if (i + 1 == topology_.size()) {
      merged.push_back(std::move(topology_[i]));
    } else {
      TopologyChange both{topology_[i + 1].time_s, std::move(topology_[i + 1].faces)};
      const std::vector<int32_t>& earlier = topology_[i].faces;
      const size_t later_end = both.faces.size();
      for (size_t j = 0; j < later_end; j += 4) by_later[static_cast<size_t>(both.faces[j])] = true;
      for (size_t k = 0; k < earlier.size(); k += 4)
        if (!by_later[static_cast<size_t>(earlier[k])])
          both.faces.insert(both.faces.end(), earlier.begin() + static_cast<long>(k),
                            earlier.begin() + static_cast<long>(k) + 4);
      for (size_t j = 0; j < later_end; j += 4)
        by_later[static_cast<size_t>(both.faces[j])] = false;
      merged.push_back(std::move(both));
    }
    topology_faces_ += merged.back().faces.size() / 4;
  }
  topology_ = std::move(merged);
}

void TraceRecorder::SetPalpation(const scoring::PalpationRecorder& palpation) {
  const auto mm = [](const Eigen::Vector3d& p) {
    return nlohmann::json::array(
        {Round(p.x() * 1e3, 2), Round(p.y() * 1e3, 2), Round(p.z() * 1e3, 2)});
  };
  const scoring::PalpationOutcome outcome = palpation.Outcome();
  nlohmann::json lumps = nlohmann::json::array(), marks = nlohmann::json::array();
  for (size_t i = 0; i < outcome.lumps.size(); ++i) {
    const scoring::Lump& l = outcome.lumps[i];
    lumps.push_back({{"centre_mm", mm(l.centre)},
                     {"radius_mm", Round(l.radius * 1e3, 2)},
                     {"surface_mm", mm(l.surface)},
                     {"found", static_cast<bool>(outcome.found[i])}});
  }
  for (const scoring::PalpationOutcome::Placed& m : outcome.marks)
    marks.push_back(
        {{"time_s", Round(m.time, 3)}, {"position_mm", mm(m.position)}, {"lump", m.lump}});
  palpation_ = nlohmann::json{{"lumps", std::move(lumps)}, {"marks", std::move(marks)}}.dump();
}

std::optional<scoring::PalpationOutcome> TraceRecorder::PalpationOf(
    const std::string& record_json) {
  // Only the palpation member is kept as the record is parsed (a record is mostly its frames).
  const auto keep = [](int depth, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    return depth != 1 || event != nlohmann::json::parse_event_t::key || parsed == "palpation";
  };
  const nlohmann::json record = nlohmann::json::parse(record_json, keep, false);
  if (record.is_discarded() || !record.is_object() || !record.contains("palpation"))
    return std::nullopt;
  const auto metres = [](const nlohmann::json& v) -> Eigen::Vector3d {
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
        !v[2].is_number())
      throw nlohmann::json::type_error::create(302, "not a point", nullptr);
    return Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>()) * 1e-3;
  };
  try {
    const nlohmann::json& p = record.at("palpation");
    scoring::PalpationOutcome out;
    for (const nlohmann::json& l : p.at("lumps")) {
      out.lumps.push_back({metres(l.at("centre_mm")), l.at("radius_mm").get<double>() * 1e-3,
                           metres(l.at("surface_mm"))});
      out.found.push_back(l.value("found", false));
    }
    for (const nlohmann::json& m : p.at("marks")) {
      const int lump = m.value("lump", -1);
      out.marks.push_back({metres(m.at("position_mm")), m.at("time_s").get<double>(),
                           lump >= 0 && lump < static_cast<int>(out.lumps.size()) ? lump : -1});
    }
    return out;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

void TraceRecorder::SetNeedle(const haptics::NeedleModel& needle) {
  const auto mm = [](const Eigen::Vector3d& p) {
    return nlohmann::json::array(
        {Round(p.x() * 1e3, 2), Round(p.y() * 1e3, 2), Round(p.z() * 1e3, 2)});
  };
  const haptics::NeedleTissueSpec& spec = needle.spec();
  nlohmann::json n{{"skin_z_mm", Round(spec.surface_z * 1e3, 2)}};
  if (spec.has_target)
    n["target"] = {
        {"kind", spec.target.kind == haptics::NeedleTarget::Kind::kVessel ? "vessel" : "cyst"},
        {"name", spec.target.name},
        {"centre_mm", mm(spec.target.centre)},
        {"radius_mm", Round(spec.target.radius * 1e3, 2)}};
  nlohmann::json tracts = nlohmann::json::array();
  for (const haptics::NeedleState& t : needle.Tracts())  // entry, and the deepest point cut
    tracts.push_back({{"entry_mm", mm(t.entry)},
                      {"deepest_mm", mm(t.entry + t.cut * t.direction)},
                      {"punctured", t.passed}});
  n["tracts"] = std::move(tracts);
  needle_ = n.dump();
}

std::string TraceRecorder::Json() const {
  nlohmann::json series = nlohmann::json::object();
  const auto names = sim::TelemetryFields(sim::SessionTelemetry{});
  for (size_t i = 0; i < names.size(); ++i) {
    nlohmann::json column = nlohmann::json::array();
    const int decimals = names[i].decimals + (names[i].name == "time_s" ? 0 : 1);
    for (const Sample& s : samples_) column.push_back(Round(s.values[i], decimals));
    series[std::string(names[i].name)] = std::move(column);
  }
  // The time from the double (the float copy loses milliseconds after a few hours).
  nlohmann::json times = nlohmann::json::array();
  for (const Sample& s : samples_) times.push_back(Round(s.time_s, 3));
  series["time_s"] = std::move(times);
  nlohmann::json positions = nlohmann::json::array();
  for (const auto& p : rest_)
    for (int c = 0; c < 3; ++c) positions.push_back(Round(p[c] * 1e3, 3));
  // The frames as one stream of differences from the frame before (modulo 2^16), deflated.
  nlohmann::json frame_times = nlohmann::json::array();
  std::vector<uint8_t> all;
  all.reserve(6 * rest_.size() * frames_.size());
  const std::vector<int16_t> rest_state(3 * rest_.size(), 0);
  const std::vector<int16_t>* previous = &rest_state;
  for (const Frame& f : frames_) {
    frame_times.push_back(Round(f.time_s, 3));
    for (size_t i = 0; i < f.displacement.size(); ++i) {
      const auto d = static_cast<uint16_t>(static_cast<uint16_t>(f.displacement[i]) -
                                           static_cast<uint16_t>((*previous)[i]));
      all.push_back(static_cast<uint8_t>(d & 0xff));
      all.push_back(static_cast<uint8_t>(d >> 8));
    }
    previous = &f.displacement;
  }
  nlohmann::json record{
      {"series", std::move(series)},
      {"rest", {{"positions_mm", std::move(positions)}, {"triangles", triangles_}}},
      {"frames",
       {{"time_s", std::move(frame_times)},
        {"unit_mm", kFrameUnitM * 1e3},
        {"vertices", rest_.size()},
        {"deflated", Base64(Deflate(all, 6))}}}};
  if (!topology_.empty()) {
    nlohmann::json change_times = nlohmann::json::array(), changes = nlohmann::json::array();
    for (const TopologyChange& c : topology_) {
      change_times.push_back(Round(c.time_s, 3));
      changes.push_back(c.faces);
    }
    record["topology"] = {{"time_s", std::move(change_times)}, {"faces", std::move(changes)}};
  }
  if (!palpation_.empty()) record["palpation"] = nlohmann::json::parse(palpation_);
  if (!needle_.empty()) record["needle"] = nlohmann::json::parse(needle_);
  return record.dump();
}

bool TraceRecorder::Consistent() const {
  if (samples_.size() > kMaxSamples || frames_.size() > kMaxFrames || sample_stride_ == 0 ||
      frame_stride_ == 0)
    return false;
  for (const Frame& f : frames_)
    if (f.displacement.size() != 3 * rest_.size()) return false;
  return true;
}

}  // namespace vsurg::server
