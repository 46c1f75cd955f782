#include "bench/wan/wan.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "bench/relay/relay.h"
#include "common/sim/simulation.h"
#include "common/sim/trajectory.h"
#include "server/net/udp_endpoint.h"

namespace vsurg::bench::wan {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kContactN = 0.1;  // a force this large is contact

wire::SessionKey Key(uint64_t seed) {
  wire::SessionKey k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(7 * i + 3 + seed);
  return k;
}

// The first cycle whose force reaches contact; −1: none.
long Onset(const std::vector<client::HandSample>& t) {
  for (size_t k = 0; k < t.size(); ++k)
    if (t[k].force.norm() >= kContactN) return static_cast<long>(k);
  return -1;
}

// RMS of what a critically damped second-order low-pass at 30 Hz leaves out: the force's content
// above 30 Hz (buzz, oscillation), per component, summed.
double AboveThirtyHz(const std::vector<client::HandSample>& t, double dt) {
  const double a = 1.0 - std::exp(-2 * M_PI * 30 * dt);
  Vec3 s1 = Vec3::Zero(), s2 = Vec3::Zero();
  double sum = 0;
  for (const auto& c : t) {
    s1 += a * (c.force - s1);
    s2 += a * (s1 - s2);
    sum += (c.force - s2).squaredNorm();
  }
  return t.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(t.size()));
}

}  // namespace

Expected<sim::Scene> GridScene(const std::string& name) {
  const bool stiff = name == "sphere-palpation-256@700";
  auto scene = sim::LoadSceneByName(stiff ? "sphere-palpation-256" : name);
  if (!scene.ok()) return scene.error();
  if (stiff) {
    // An Omni-class device at its stiffness limit: the hard case for delay and passivity.
    scene->name = name;
    scene->haptics.device = "omni";
    scene->haptics.limits = haptics::OmniLimits();
    scene->haptics.proxy.stiffness = 700;
  }
  if (scene->task.kind == scoring::TaskKind::kPalpate) {  // one known case, the same every run
    scene->cases.reset();
    scene->inclusions = {kGridLump};
  }
  return scene;
}

Expected<std::vector<haptics::StylusSample>> TapPlan(const sim::Scene& scene) {
  if (scene.task.kind != scoring::TaskKind::kPress)
    return InvalidArgument("scene", "a palpation needs a press scene");
  // Where the good trainee presses (common/sim/trajectory.h).
  auto touch = sim::ScriptedTouch(scene);
  if (!touch.ok()) return touch.error();
  const Vec3 &surface = touch->surface, &normal = touch->normal;
  const Vec3 above = surface + 0.06 * normal, deep = surface - 0.005 * normal;
  std::vector<haptics::StylusSample> plan;
  const double down = 0.35, hold = 1.0, up = 0.4;
  for (int k = 0; k <= static_cast<int>((down + hold + up) * 1000); ++k) {
    const double t = k * 1e-3;
    haptics::StylusSample s;
    s.time = t;
    if (t < down) {
      s.position = above + (deep - above) * sim::MinJerk(t / down);
    } else if (t < down + hold) {
      s.position = deep;
    } else {
      s.position = deep + (above - deep) * sim::MinJerk((t - down - hold) / up);
    }
    plan.push_back(s);
  }
  return plan;
}

Expected<Run> RunOnce(const RunOptions& o) {
  sim::SimulationOptions so;
  so.cache_dir = o.cache_dir;
  auto simulation = sim::Simulation::Create(o.scene, so);
  if (!simulation.ok()) return simulation.error();
  auto endpoint = server::UdpEndpoint::Create({});
  if (!endpoint.ok()) return endpoint.error();
  const uint64_t id = 1;
  (*endpoint)->AddSession(id, Key(o.seed), simulation->get());
  relay::RelayOptions ro;
  ro.server_port = (*endpoint)->port();
  ro.profile = o.profile;
  ro.seed = o.seed;
  auto relay = relay::Relay::Start(ro);
  if (!relay.ok()) return relay.error();
  client::DeviceModel device;
  device.limits = o.scene.haptics.limits;
  std::vector<haptics::StylusSample> plan;
  const int lead = static_cast<int>(o.lead_in_s * 1000);
  plan.reserve(o.plan.size() + lead);
  for (int k = 0; k < lead; ++k) {
    haptics::StylusSample s = o.plan.front();
    s.time = o.plan.front().time - o.lead_in_s + k * 1e-3;
    plan.push_back(s);
  }
  plan.insert(plan.end(), o.plan.begin(), o.plan.end());
  auto hand = client::VirtualHandDevice::Create(std::move(plan), o.grip, device);
  if (!hand.ok()) return hand.error();
  client::StationOptions co;
  co.server_port = (*relay)->port();
  co.session = id;
  co.key = Key(o.seed);
  co.rendering = o.rendering;
  co.passivity = o.passivity;
  co.passivity_mode = o.passivity_mode;
  co.deadband = o.deadband;
  co.deadband_contact_heartbeat_s = o.contact_heartbeat_s;
  co.exact_grasp = o.exact_grasp;
  co.model_hold_s = o.model_hold_s;
  co.force_limit_n = o.scene.task.force_limit;
  if (o.station_surface) {  // the tissue the station holds from its join
    co.surface = (*simulation)->station_surface();
    co.needle = (*simulation)->station_needle();
    co.blade = (*simulation)->station_blade();
  }
  const auto start = std::chrono::steady_clock::now();
  auto station = client::StationChannel::Create(co, hand->get());
  if (!station.ok()) return station.error();
  // Wait on the hand's own progress (its device time), not on the wall clock: a loaded machine
  // slows the run, it does not cut it short.
  while (!(*hand)->finished()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const auto settle_until = (*hand)->cycles() + static_cast<size_t>(o.settle_s * 1000);
  while ((*hand)->cycles() < settle_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  (*station)->Stop();
  Run run;
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  (*relay)->Stop();
  const relay::RelayStats rs = (*relay)->stats();
  run.up_datagrams = rs.up.received;
  run.down_datagrams = rs.down.received;
  run.station = (*station)->stats();
  (*endpoint)->RemoveSession(id);
  run.trace = (*hand)->trace();
  run.trace.erase(run.trace.begin(),
                  run.trace.begin() + std::min<std::ptrdiff_t>(lead, std::ssize(run.trace)));
  const scoring::TrialMetrics m = (*simulation)->Metrics();
  run.score = m.score;
  run.score_but_smoothness = scoring::ScoreButSmoothness(m, o.scene.task);
  run.server_peak_force = m.peak_force;
  return run;
}

std::vector<size_t> Pops(const std::vector<client::HandSample>& t) {
  std::vector<size_t> out;
  for (size_t k = 3; k < t.size(); ++k) {
    const double before = t[k - 3].force.norm();
    const double after = t[k].force.norm();
    if (before >= 0.3 && before - after >= std::max(0.2, 0.3 * before) &&
        (out.empty() || k > out.back() + 10))
      out.push_back(k);
  }
  return out;
}

Figures Compare(const Run& run, const Run& ref, bool press_scene) {
  Figures f;
  {
    const std::vector<size_t> pa = Pops(run.trace), pb = Pops(ref.trace);
    f.pops = static_cast<int>(pa.size()), f.reference_pops = static_cast<int>(pb.size());
    for (size_t i = 0; i < std::min(pa.size(), pb.size()); ++i)
      f.pop_delay_cycles = std::max(
          f.pop_delay_cycles, std::abs(static_cast<double>(pa[i]) - static_cast<double>(pb[i])));
  }
  const auto& a = run.trace;
  const auto& b = ref.trace;
  const size_t n = std::min(a.size(), b.size());
  const double dt = 1e-3;
  double peak_ref = 0, err2 = 0;
  for (size_t k = 0; k < n; ++k) {
    peak_ref = std::max(peak_ref, b[k].force.norm());
    err2 += (a[k].force - b[k].force).squaredNorm();
  }
  for (const auto& c : a) f.peak_force_n = std::max(f.peak_force_n, c.force.norm());
  f.rms_error_pct =
      n && peak_ref > 0 ? 100 * std::sqrt(err2 / static_cast<double>(n)) / peak_ref : 0;
  const long ka = Onset(a), kb = Onset(b);
  if (ka >= 0 && kb >= 0) {
    f.onset_delay_cycles = static_cast<double>(ka - kb);
    const Vec3 normal = b[kb].force.normalized();  // the reference's push at its onset
    f.onset_extra_mm = 1e3 * (b[kb].x - a[ka].x).dot(normal);
  }
  // Energy the held force gave the hand over the run: Σ F_k·(x_{k+1} − x_k).
  const auto energy = [](const std::vector<client::HandSample>& t) {
    double e = 0;
    for (size_t k = 0; k + 1 < t.size(); ++k) e += t[k].force.dot(t[k + 1].x - t[k].x);
    return e;
  };
  f.energy_to_hand_mj = 1e3 * energy(a);
  f.energy_excess_mj = f.energy_to_hand_mj - 1e3 * energy(b);
  f.oscillation_n = AboveThirtyHz(a, dt);
  // The pull after the tool has let go: from 20 ms after the grasp button's release (a few
  // cycles' grace for the tissue's own timing) for 300 ms, the force beyond the reference's; in a
  // scene without a grasp, the largest force from 20 ms after the reference last felt anything.
  // On 20 ms means of |F|: a contact that chatters after release (both runs do on the arm) is
  // not read as a pull because its phases differ by a few cycles. Each mean lies wholly after
  // the grace (one ending 20 ms after it would reach back into it and read a release a few
  // cycles later than the reference's as a pull).
  const auto mean20 = [n](const std::vector<client::HandSample>& t) {
    std::vector<double> m(n, 0.0);
    double sum = 0;
    for (size_t k = 0; k < n; ++k) {
      sum += t[k].force.norm();
      if (k >= 20) sum -= t[k - 20].force.norm();
      m[k] = sum / static_cast<double>(std::min<size_t>(k + 1, 20));
    }
    return m;
  };
  const std::vector<double> ma = mean20(a), mb = mean20(b);
  size_t release = 0;
  for (size_t k = 1; k < n; ++k)
    if ((b[k - 1].buttons & haptics::kButtonGrasp) && !(b[k].buttons & haptics::kButtonGrasp))
      release = k;
  constexpr size_t kGrace = 20, kMean = 20;
  const auto keep = [&f](double pull, size_t k) {
    if (pull > f.phantom_n) f.phantom_n = pull, f.phantom_cycle = k;
  };
  if (release > 0) {
    for (size_t k = release + kGrace + kMean - 1; k < std::min(n, release + 300); ++k)
      keep(ma[k] - mb[k], k);
  } else if (kb >= 0) {
    size_t last_felt = 0;
    for (size_t k = 0; k < n; ++k)
      if (b[k].force.norm() >= 0.01) last_felt = k;
    for (size_t k = last_felt + kGrace + kMean - 1; k < n; ++k) keep(ma[k], k);
  }
  // Displayed stiffness: the least-squares slope of the force along the contact normal over the
  // depth along it, over the cycles in contact.
  if (press_scene && kb >= 0) {
    const Vec3 normal = b[kb].force.normalized();
    const auto slope = [&](const std::vector<client::HandSample>& t) {
      double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
      for (const auto& c : t) {
        const double fn = c.force.dot(normal);
        if (fn < kContactN) continue;
        const double depth = -c.x.dot(normal);
        sx += depth, sy += fn, sxx += depth * depth, sxy += depth * fn, m += 1;
      }
      const double den = m * sxx - sx * sx;
      return m > 10 && den > 0 ? (m * sxy - sx * sy) / den : 0.0;
    };
    const double ks = slope(a), kr = slope(b);
    f.stiffness_pct = kr > 0 ? 100 * ks / kr : 0;
  }
  f.up_hz = run.seconds > 0 ? static_cast<double>(run.up_datagrams) / run.seconds : 0;
  f.down_hz = run.seconds > 0 ? static_cast<double>(run.down_datagrams) / run.seconds : 0;
  f.score = run.score;
  f.score_but_smoothness = run.score_but_smoothness;
  return f;
}

}  // namespace vsurg::bench::wan
