// One trainee's simulation: stylus samples in, force commands out (DESIGN.md "Haptic
// interaction"; STYLE.md: the handler never sees a socket).
//
// Two loops share a session's scene:
//
//   haptic path, OnStylus()            deformation, its own thread (or StepDeformation())
//   ---------------------------------  ---------------------------------------------------
//   latest surface snapshot ───────────  deforms: coil deformer / mass-spring / ring layer
//   proxy contact, grasp-and-twist       refits a BVH over the new surface, publishes it
//   coil inverse (twist → torque)        reads the latest DeformInput: torque, grasp, contact
//   safety filter, local model           force on the tissue
//   trial metrics
//   publishes a DeformInput ──────────
//
// Hand-offs are TripleBuffers (lock-free, latest-wins); all buffers are sized at Create, so the
// haptic path never allocates and never waits. Visual frames (TakeVisualFrame, at ~60 Hz from a
// third thread) carry only the vertices that moved since the previous frame.
//
// Grasp-and-twist (coil scenes): in contact, pressing the grasp button grasps the surface point
// under the proxy. The twist axis is the limb centreline there (limb mode) or the surface normal
// (surface mode). The stylus's rotation about that axis since the grasp is the imposed twist Φ;
// the coil model's closed-form inverse gives the torque M; the device feels −M/lever along the
// tangent (lever = the grasp point's distance from the axis, at least min_lever), scaled by the
// scene's force_scale, plus a holding spring to the grasped point turned by Φ. Releasing lets go
// and the tissue relaxes.
//
// Palpation (mass-spring, ring-layer): the proxy's force pushes the stylus back; its opposite
// acts on the tissue at the contact point. For the mass-spring model it enters as zero-length
// spring-dampers from the contact triangle's vertices towards the tip (barycentric shares of the
// coupling's K and D), inside the implicit solve: a coupling stiffer than the tissue applied as
// an explicit force made the 1026-particle sphere chatter at the device's rate limit.
//
// Threads: OnStylus and Metrics from one haptic thread; TakeVisualFrame from one other thread;
// the deformation thread is owned. Create/destroy from anywhere (the destructor joins).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/bvh.h"
#include "common/haptics/blade.h"
#include "common/haptics/needle.h"
#include "common/haptics/proxy.h"
#include "common/haptics/safety.h"
#include "common/haptics/stiffness_fit.h"
#include "common/haptics/tissue_surface.h"
#include "common/haptics/types.h"
#include "common/haptics/viscoelastic.h"
#include "common/scoring/needle.h"
#include "common/scoring/palpation.h"
#include "common/scoring/trial_metrics.h"
#include "common/sim/deformation_pool.h"
#include "common/sim/guidance.h"
#include "common/sim/scene.h"
#include "common/sim/telemetry.h"
#include "common/sim/tissue_room.h"
#include "common/sim/triple_buffer.h"

namespace vsurg::sim {

// The largest step of a session's trial clock, s. A station's clock may jump (a bad device, a
// faulty sync, or an attacker with a valid key): the trial clock follows the station's time
// steps up to this bound and no further, so the work one sample can cause (the trial recorder's
// grid, a replay's deformation steps) is bounded, and a jump costs no other session anything.
// It is above the endpoint's stall time (0.5 s), so a real pause still counts in full.
inline constexpr double kMaxClockStepS = 1.0;

// SimulationOptions::quasi_static_interval_s's default, s: two surfaces per 60 Hz frame.
inline constexpr double kQuasiStaticIntervalS = 0.008;

struct SimulationOptions {
  bool threaded = true;  // false: the caller drives StepDeformation() (replays, tests)
  // Threaded only: start the deformation thread at Create. The server leaves it off and turns it
  // on only while a station drives the session (SetDeformationRunning), so a session nobody
  // drives costs no thread and no CPU.
  bool start_deformation = true;
  // Reduced models: where their precomputation is cached (tissue::ReducedCache); empty: the
  // default (tissue::DefaultCacheDirectory()).
  std::string cache_dir = "";
  // Threaded only: the deformation runs as a member of this pool (common/sim/deformation_pool.h)
  // instead of on a thread of its own. It must outlive the simulation. Null: its own thread.
  DeformationPool* pool = nullptr;
  // The haptic path's closest-face queries answer from kept lists while the tip and the surface
  // move less than their margin (geometry::ClosestCache: the same answers, fewer memory reads);
  // false: each walks the tree (the comparison in docs/BENCHMARKS.md).
  bool kept_face_lists = true;
  // Threaded only: while the hand grasps, a quasi-static model (coil, reduced; not paced) updates
  // on a new request at most once per this many seconds, then from the newest request. A hand
  // twisting at a 1 kHz station asks for an update every millisecond, while the surface is shown
  // at 60 Hz and the grasp's force never reads it. A touch, whose proxy does read the surface, is
  // served at every request. 0: every request at once. Within [0, 0.1].
  double quasi_static_interval_s = kQuasiStaticIntervalS;
};

struct VisualFrame {
  uint64_t frame_id = 0;                  // counts published deformations
  std::vector<int32_t> indices;           // vertices that moved since the previous frame taken
  std::vector<geometry::Vec3> positions;  // their positions, m
  // The whole surface of this frame as a coil limb's twist (a viewer with the scene remakes it
  // from these three numbers), when the room made it so; the moved vertices are given as well,
  // unless the frame was taken for a viewer that remakes it (TakeVisualFrame's twist_key).
  std::optional<CoilTwistShape> twist;
  // A cut scene's topology (rooms/cut_room.h), when it changed since the previous frame taken or
  // in the kTopologyRepeats frames after: every face that differs from the rest mesh's, as it is
  // now (a removed face is {0, 0, 0}), and the count of changes so far. Whole, not a change from
  // the last frame, so a frame lost on the way is made good by any later one, and a face never
  // shows a cut the tissue has not made. Empty for the other scenes.
  uint64_t topology = 0;
  std::vector<int32_t> face_indices;
  std::vector<geometry::Triangle> faces;
};

class Simulation final : private DeformationPool::Member {
 public:
  static Expected<std::unique_ptr<Simulation>> Create(const Scene& scene,
                                                      const SimulationOptions& options = {});
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // Haptic thread, ≥ 1 kHz. Never allocates, never blocks.
  haptics::ForceCommand OnStylus(const haptics::StylusSample& sample);
  // Four-handed training (guidance.h): an instructor's station's sample, on the same haptic
  // thread as the trainee's (the endpoint steers both channels to the session's lane), between
  // them. The answer is the instructor's share of the tool; the trial advances only with the
  // trainee's samples. Never allocates, never blocks.
  haptics::ForceCommand OnInstructorStylus(const haptics::StylusSample& sample);
  // Two hands: the station's second device, a cut scene's grasper (Scene::CutSpec::grasper), on
  // the same haptic thread as the first hand's (the endpoint steers its channel to the session's
  // lane). Its jaws close (kButtonGrasp) on the patch within reach and hold the particle under
  // them toward themselves; the answer is the patch's pull on them, through their own safety
  // filter. Silent for kSecondHandSilenceS of trial time (its device or link lost), its hold
  // fades out over kSecondHandFadeS while the first hand goes on. Never allocates or blocks.
  haptics::ForceCommand OnSecondHandStylus(const haptics::StylusSample& sample);
  static constexpr double kSecondHandSilenceS = 0.1, kSecondHandFadeS = 0.5;
  // The second hand's grasps so far and its peak pull (N); haptic thread, or after it stopped.
  int second_hand_grasps() const { return second_.grasps; }
  double second_hand_peak_force() const { return second_.peak_force; }
  // Any thread: the instructor's mode and dominance, checked first (CheckGuideRequest); the
  // haptic thread ramps to it. {kNone}: the instructor left.
  void RequestGuidance(const GuideRequest& r) { guidance_.Request(r); }
  GuideRequest requested_guidance() const { return guidance_.requested(); }
  // Threaded mode, from one control thread (never the haptic thread): starts or stops (joins)
  // the deformation thread. The tissue keeps its state while the thread is off; the haptic path
  // keeps answering from the last published surface.
  void SetDeformationRunning(bool running);
  bool deformation_running() const { return thread_.joinable() || pooled_; }
  // Non-threaded mode: one deformation update from the latest input (the caller's thread).
  void StepDeformation();
  // Non-threaded mode: plays samples through OnStylus in their own time. The deformation steps
  // at the scene's dt (mass-spring, ring layer: as many steps as the samples' clock advanced) or
  // once after each sample (coil: it updates on a new torque). `on_command` sees every answer.
  void Replay(const std::vector<haptics::StylusSample>& samples,
              const std::function<void(const haptics::StylusSample&, const haptics::ForceCommand&)>&
                  on_command);
  // Visual thread: fills `out` with the vertices that moved since the previous call; false when
  // nothing new was published. Reuses out's capacity. A coil limb's twist whose CoilTwistShape
  // key is `twist_key` (a station that remakes the twist from its numbers) comes as that shape
  // alone, its vertices not made: a later frame that needs vertices sends them against it.
  bool TakeVisualFrame(VisualFrame& out, uint64_t twist_key = 0);
  // Every vertex as the last TakeVisualFrame that made them read them (what its frame was made
  // from); only from the thread that takes the frames, until its next call.
  const std::vector<geometry::Vec3>& LastFramePositions() const {
    return visual_.Front().positions;
  }

  // Any thread (the control plane's sampler, for monitors): the surface as the visual thread
  // last sent it, as the vertices more than 1 µm from rest. Returns that frame's id (0: none
  // yet). Copies under a lock the visual thread takes only when a frame moved something.
  uint64_t ShownSurface(std::vector<int32_t>& indices,
                        std::vector<geometry::Vec3>& positions) const;
  // Any thread, as ShownSurface: a cut scene's topology as the visual thread last sent it (the
  // faces that differ from the rest mesh's, as VisualFrame has them). Returns its count of
  // changes (0: uncut, or not a cut scene).
  uint64_t ShownTopology(std::vector<int32_t>& face_indices,
                         std::vector<geometry::Triangle>& faces) const;
  // The haptic thread's own view, or after it stopped (not concurrently with OnStylus).
  scoring::TrialMetrics Metrics() const;
  // A palpation's marks and lumps (the haptic thread's, or after it stopped): what the trial's
  // summary shows beside each other once the search is over.
  const scoring::PalpationRecorder& palpation() const { return palpation_; }
  // A needle scene's model as the haptic thread left it (its tract, punctures), or null.
  const haptics::NeedleModel* needle() const { return needle_.model ? &*needle_.model : nullptr; }
  // One reader thread (the control plane's sampler): the latest telemetry, published by the
  // haptic thread every few samples. False when nothing new since the previous call.
  bool TakeTelemetry(Telemetry& out);
  const Scene& scene() const { return scene_; }
  const geometry::TriMesh& rest_mesh() const { return rest_; }
  // The rest surface's vertices the scene's support holds.
  const std::vector<int>& held_vertices() const { return held_; }
  // Any thread: the surface at rest and its contact law, as a station renders the surface ahead
  // of the tool before the server's answers say it (haptics/tissue_surface.h); a station gets it
  // with its join. Null when the scene has no surface ahead (lookahead 0).
  std::shared_ptr<const haptics::TissueSurface> station_surface() const { return station_surface_; }
  // Any thread: a needle scene's tissue, as a station renders the needle with its own model
  // (haptics/needle.h); null for other scenes. A station gets it with its join.
  std::shared_ptr<const haptics::NeedleTissueSpec> station_needle() const {
    return station_needle_;
  }
  // Any thread: a cut scene's blade with the patch's stiffnesses (haptics/blade.h), as a station
  // renders the blade with its own fracture model; null for other scenes. With the join.
  std::shared_ptr<const haptics::BladeParams> station_blade() const { return station_blade_; }
  // The haptic thread's trial clock (s since the first sample; see kMaxClockStepS) and how many
  // samples jumped. Not concurrently with OnStylus.
  double trial_time() const { return trial_time_; }
  uint64_t clock_jumps() const { return clock_jumps_; }
  // Deformation updates published so far (any thread).
  uint64_t deformation_updates() const { return updates_.load(std::memory_order_relaxed); }
  // Of those, the ones published to the haptic path as its surface (all but a grasp's: Deform).
  uint64_t surface_updates() const { return surface_updates_.load(std::memory_order_relaxed); }
  // Requests handed to the deformation so far: each wakes it (any thread).
  uint64_t deformation_requests() const { return input_version_.load(std::memory_order_relaxed); }

  // Live migration (server/cluster/: a draining node hands its sessions to other nodes). The
  // whole state a trainee's trial goes on from, as bytes: the trial clock and recorder, the
  // proxy, the safety filter's arming and ramp, the grasp, the port energies, the surface the
  // haptic path answers from, and the tissue model's own state where it has one beyond its input
  // (the mass-spring's particles, the ring layer's rings; the quasi-static models' surface is a
  // function of the input, which is carried). Neither concurrently with OnStylus nor with a
  // deformation: the caller has stopped both (the session is out of the endpoint and its
  // deformation is off).
  std::string SaveState();
  // A new simulation of the same scene (built by Create, not yet driven) set to a SaveState's
  // bytes; before the deformation runs. Refused, and the simulation left as it was built, when
  // the bytes are of another format version, scene, mesh or model, or do not read back whole.
  Status RestoreState(std::string_view bytes);

 private:
  // RestoreState's first stage: the format and what must have been built alike; "" when they
  // match, else why not.
  std::string ReadStateHeader(StateReader& r) const;
  struct Snapshot {
    std::vector<geometry::Vec3> positions;
    geometry::Bvh bvh;
    uint64_t id = 0;
    bool overload = false;
    bool outside_model = false;  // the reduced contact used a neighbour's precomputed response
    // m: how far the surface has moved in all, a bound non-decreasing from one snapshot to the
    // next (each publish adds its largest vertex move): the haptic path's kept closest-face
    // lists (geometry::ClosestCache) stand while it says the surface moved less than their margin.
    double motion = 0;
  };
  struct VisualPositions {
    std::vector<geometry::Vec3> positions;
    uint64_t id = 0;
    std::optional<CoilTwistShape> twist;
    // A cut's faces (Deformed::faces), copied when its topology changed; empty for the others.
    std::vector<geometry::Triangle> faces;
    uint64_t topology = 0;
    std::optional<geometry::Vec3> focus;  // Deformed::focus
    // A coil twist whose vertices are not made yet (Deformed::turn): `positions` are older until
    // MakeVertices turns them.
    std::shared_ptr<const tissue::CoilTurnTable> turn;
    tissue::CoilState turn_state;
  };
  static void MakeVertices(VisualPositions& v);

  static Expected<std::unique_ptr<Simulation>> CreateChecked(const Scene& scene,
                                                             const SimulationOptions& options);
  Simulation(const Scene& scene, geometry::TriMesh rest, const SimulationOptions& options);
  Status Build();
  std::string CacheDirectory() const;  // the reduced models' cache (options or the default)
  bool Paced() const;  // dynamic models step on the clock; quasi-static ones follow requests
  void DeformationLoop();
  // As a pool's member: one deformation when due (paced: every dt; quasi-static: a new request).
  DeformationPool::Clock::time_point StepDue(DeformationPool::Clock::time_point now) override;
  void Deform(const DeformInput& in);
  // A deformation published to the view and (unless `surface` is false) to the haptic path.
  void Publish(const Deformed& d, bool surface = true);
  // Visual thread: a cut's faces into a frame (VisualFrame::faces).
  void TakeTopology(const VisualPositions& v, VisualFrame& out);
  static constexpr int kTopologyRepeats = 3;
  void PublishSurface(const std::vector<geometry::Vec3>& positions, bool overload,
                      bool outside_model);
  void PublishInput();
  haptics::ForceCommand Zero(const haptics::StylusSample& s, uint32_t events);
  // The haptic path's stages (simulation_stylus.cpp), one sample's work in progress in `step`.
  struct StylusStep {
    uint32_t events = 0;
    double dt = 1e-3;  // s, what the proxy integrates over
    geometry::Vec3 force = geometry::Vec3::Zero();
    Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();
    double quantity = 0;  // the task's: twist (rad) or press depth (m)
    bool overload = false;
    haptics::ForceCommand cmd;
  };
  haptics::ForceCommand RejectInput(const haptics::StylusSample& s, uint32_t events);
  void CountPortEnergy(const haptics::StylusSample& s);
  double AdvanceClock(const haptics::StylusSample& s, uint32_t& events);
  void EndGrasp(uint32_t& events);
  TwistAnswer TwistAt(double phi);
  enum class TwistPhase { kBegin, kEnd, kRelease };
  void RoomTwistStep(TwistPhase phase, double dt, double twist = 0);
  void GraspStep(const haptics::StylusSample& s, StylusStep& step);
  void GraspModel(const haptics::StylusSample& s, double twist, const TwistAnswer& answer,
                  const geometry::Vec3& tangent, const geometry::Vec3& radial,
                  haptics::LocalModel& local);
  void ContactStep(const Snapshot& snap, const haptics::StylusSample& s, bool button,
                   StylusStep& step);
  void TryGrasp(const haptics::ProxyState& ps, const haptics::StylusSample& s, uint32_t& events);
  void Regrasp(const GraspQuery& q);
  void ContactModel(const haptics::ProxyState& ps, double depth, StylusStep& step);
  geometry::Vec3 Answer(const Snapshot& snap, const haptics::StylusSample& s, StylusStep& step);
  void PublishTelemetry(const haptics::StylusSample& s, const haptics::ForceCommand& cmd,
                        const geometry::Vec3& out, double quantity);
  // Four-handed training's stages (simulation_guidance.cpp).
  void ShareTool(const haptics::StylusSample& trainee, StylusStep& step);
  void RecordSample(const haptics::StylusSample& trainee, const StylusStep& step,
                    const geometry::Vec3& out);
  void CountInstructorEnergy(const haptics::StylusSample& s);
  // A palpation's stage (simulation_palpation.cpp): the press's coverage, and a mark.
  void PalpationStep(const haptics::StylusSample& trainee, StylusStep& step);
  Status BuildPalpation();
  // A needle scene's stages (simulation_needle.cpp): the needle in its tissue instead of the
  // proxy's contact; the skin's dimple for the deformation; the trial's needle record.
  void NeedleStep(const Snapshot& snap, const haptics::StylusSample& s, StylusStep& step);
  void NeedleDeform(const Snapshot& snap, const haptics::NeedleForce& f);
  void NeedleRecord(const haptics::NeedleForce& f, const haptics::StylusSample& trainee,
                    StylusStep& step);
  Status BuildNeedle();
  // A cut scene's stages (simulation_cut.cpp): the blade instead of the proxy's contact, its
  // crack handed to the patch's room, the blade's load for the deformation, the trial's cut.
  Status BuildCut();
  void CutStep(const haptics::StylusSample& s, StylusStep& step);
  void CutRecord(const haptics::BladeForce& f, const haptics::StylusSample& s);
  // The second hand's stages (simulation_second_hand.cpp): its jaws on the patch, and (on the
  // first hand's samples, which keep the trial's clock) the fade of a hold whose hand fell silent.
  void SecondHandJaws(const haptics::StylusSample& s, uint32_t& events);
  void SecondHandStep(double dt);
  void CountSecondHandEnergy(const haptics::StylusSample& s);
  // The second hand's state (haptic thread): its filter and clock, its jaws (`at` the rest-plane
  // point they took, `target` where they are), the hold's weight (1 held, fading to 0 once its
  // hand is silent), when its hand was last heard (trial time; < 0 never), its port energies.
  struct SecondHand {
    haptics::SafetyFilter safety;
    bool closed = false, fading = false;
    geometry::Vec3 at = geometry::Vec3::Zero(), target = geometry::Vec3::Zero();
    double weight = 0, last_seen = -1, time = 0;
    bool has_time = false;
    geometry::Vec3 force = geometry::Vec3::Zero(), x = geometry::Vec3::Zero();
    bool has_x = false;
    double released_j = 0, absorbed_j = 0, peak_force = 0;
    int grasps = 0;
  };
  // Haptic thread: a free tip's local model, the surface ahead of it (see simulation.cpp).
  double ContactStiffness(const ContactQuery& q) const;
  std::shared_ptr<const haptics::TissueSurface> MakeStationSurface() const;
  // The motion the kept face lists are given: the snapshot's, or +inf (none kept) when disabled.
  double KeptListMotion(const Snapshot& snap) const {
    return options_.kept_face_lists ? snap.motion : std::numeric_limits<double>::infinity();
  }
  void SurfaceAhead(const Snapshot& snap, const geometry::Vec3& tip, haptics::LocalModel& local,
                    Eigen::Matrix3d& jacobian);

  Scene scene_;
  geometry::TriMesh rest_;
  SimulationOptions options_;

  // Haptic side.
  haptics::ProxyContact proxy_;
  std::shared_ptr<const haptics::TissueSurface> station_surface_;    // set by Build
  std::shared_ptr<const haptics::NeedleTissueSpec> station_needle_;  // set by Build (needle scenes)
  std::shared_ptr<const haptics::BladeParams> station_blade_;        // set by Build (cut scenes)
  haptics::SafetyFilter safety_;
  scoring::TrialRecorder recorder_;
  scoring::PalpationRecorder palpation_;  // a palpation task's marks and coverage
  bool mark_button_ = false;              // the mark button as the last sample held it
  // A needle scene's (haptic thread): the model, the trial's needle record, back-wall breaches,
  // and the skin's face under the tract's entry (found once per tract, for the dimple).
  struct NeedleSide {
    std::optional<haptics::NeedleModel> model;
    scoring::NeedleRecorder record;
    uint32_t breaches = 0;
    uint32_t face_tract = 0;  // the tract the face was found for (0: none)
    int face = -1;
    geometry::Vec3 face_barycentric = geometry::Vec3::Zero();
    template <class A>
    void Persist(A& a) {  // the face is found again from the restored tract
      if (model) a(*model);
      a(record, breaches);
    }
  };
  NeedleSide needle_;
  // A cut scene's (haptic thread): the blade, the feed of its crack to the room (CutRoom), the
  // trial's cut record, the room's tears and freed pieces as last recorded.
  struct CutSide {
    std::optional<haptics::BladeModel> blade;
    haptics::CrackFeed feed;
    std::optional<scoring::CutRecorder> record;
    double torn = 0;  // m
    int freed = 0;
  };
  CutSide cut_;
  SecondHand second_;
  uint64_t samples_ = 0;
  // The server's port energies (haptics::ForceCommand::released_j): the force answered last, held
  // until the next sample, against the motion to it.
  geometry::Vec3 port_force_ = geometry::Vec3::Zero(), port_x_ = geometry::Vec3::Zero();
  bool port_has_x_ = false;
  double released_j_ = 0, absorbed_j_ = 0;
  bool telemetry_grasping_ = false;
  double live_score_ = 0;  // the trial's score as of the last telemetry
  TripleBuffer<Telemetry> telemetry_;
  std::vector<geometry::Vec3> centreline_points_;  // limb meshes: the axis polyline
  std::vector<int> held_;                          // the surface vertices the scene's support holds
  DeformInput input_;
  double last_time_ = 0;   // s, the station's time of the last accepted sample
  double trial_time_ = 0;  // s, the trial clock: bounded steps of the station's time
  uint64_t clock_jumps_ = 0;
  bool has_time_ = false;
  bool grasping_ = false;
  Eigen::Quaterniond grasp_q0_ = Eigen::Quaterniond::Identity();
  geometry::Vec3 axis_ = geometry::Vec3::UnitZ(), axis_point_ = geometry::Vec3::Zero();
  double lever_ = 0.03;
  geometry::Vec3 rest_contact_ = geometry::Vec3::Zero(), rest_normal_ = geometry::Vec3::UnitZ();
  bool last_contact_ = false;
  int ahead_triangle_ = -1;  // haptic thread: the last surface-ahead face, the next search's start
  // Haptic thread: the surface-ahead query's kept face list.
  geometry::ClosestCache ahead_cache_{haptics::ProxyContact::kKeptListMargin};
  haptics::StiffnessFit stiffness_fit_;        // the contact's slope for the local model
  haptics::ViscoelasticFit viscoelastic_fit_;  // the tissue under the proxy, for the local model
  bool room_has_contact_stiffness_ = false;    // the room answers ContactStiffness itself
  GraspQuery grasp_query_;  // the current grasp's (a restored grasp asks its room again)

  // Four-handed training (guidance.h), haptic thread but the request: the shared tool's weights,
  // the tissue's force on the tool and its slope as the trainee's last sample left them, the
  // trainee's hand there; the instructor's own safety filter, clock and port energies.
  Guidance guidance_;
  geometry::Vec3 tool_force_ = geometry::Vec3::Zero();
  Eigen::Matrix3d tool_slope_ = Eigen::Matrix3d::Zero();
  geometry::Vec3 trainee_x_ = geometry::Vec3::Zero();
  bool tool_contact_ = false;
  geometry::Vec3 tool_proxy_ = geometry::Vec3::Zero();
  haptics::SafetyFilter instructor_safety_;
  double instructor_time_ = 0;
  bool instructor_has_time_ = false;
  geometry::Vec3 instructor_force_ = geometry::Vec3::Zero(), instructor_x_ = geometry::Vec3::Zero();
  bool instructor_has_x_ = false;
  double instructor_released_j_ = 0, instructor_absorbed_j_ = 0;

  // The tissue model (common/sim/tissue_room.h): its haptic-side queries run on the haptic
  // thread, its Deform on the deformation side; each room keeps the two sides' state apart.
  TissueRoom room_;

  TripleBuffer<Snapshot> surface_;
  TripleBuffer<DeformInput> inputs_;
  TripleBuffer<VisualPositions> visual_;
  std::vector<geometry::Vec3> last_sent_;  // visual thread
  // Visual thread: the twist last sent as its shape alone, while last_sent_ is older than it.
  std::shared_ptr<const tissue::CoilTurnTable> sent_turn_;
  tissue::CoilState sent_turn_state_;
  uint64_t sent_topology_ = 0;       // visual thread: the topology last sent
  int topology_repeats_ = 0;         // visual thread: frames still owed it
  uint64_t published_topology_ = 0;  // deformation side: the last copied to the view
  mutable std::mutex shown_mutex_;   // guards shown_
  // What the visual thread last sent (a twist sent as its shape made into vertices on demand).
  mutable VisualPositions shown_;
  uint64_t publish_id_ = 0;
  // Deformation side: the surface last published and Snapshot::motion so far.
  std::vector<geometry::Vec3> last_published_;
  std::vector<geometry::Vec3> made_;  // a deferred update's vertices, when the surface needs them
  double surface_motion_ = 0;
  std::atomic<uint64_t> updates_{0}, surface_updates_{0};
  // A grasp's latest update's flags (it reaches the view only, not the surface's snapshot): what
  // the haptic path reports while grasping, as a snapshot's flags otherwise.
  std::atomic<bool> grasp_overload_{false}, grasp_outside_model_{false};
  // Coil scenes: the deformation thread sleeps on this until the haptic path asks for something
  // new (C++20 atomic wait: no lock; the haptic side's notify is a no-op without a waiter).
  std::atomic<uint64_t> input_version_{0};
  DeformInput published_;  // haptic thread: what was last handed over
  std::atomic<bool> stop_{false};
  std::thread thread_;
  // In a pool (options_.pool): whether it is a member now (control thread), and its schedule
  // (the pool's worker, one at a time).
  bool pooled_ = false;
  DeformationPool::Clock::time_point pool_next_{};
  uint64_t pool_seen_ = 0;
  DeformationPool::Clock::time_point pool_last_{};  // its last quasi-static update
  // options_.quasi_static_interval_s in the clock's units (the thread's loop and the pool's step).
  DeformationPool::Clock::duration quasi_static_interval_{};
};

}  // namespace vsurg::sim
