// A station's needle (haptics/needle.h), servo cycle by servo cycle: the station runs the same
// needle model as the server, from its own tip, so the skin dimples and each layer pops on the
// cycle the hand's force crosses its puncture force, whatever the round trip (the needle's
// model-mediated teleoperation: the tissue's laws at the operator's side, Mitra & Niemeyer 2008).
//
// The server stays the authority on what happened: its answers carry its NeedleState. The
// station keeps its own where they agree on the tract, its phase and the punctures (the same
// samples through the same model), and where they disagree it takes the server's word once the
// answer is about a sample sent at or after the station's own latest change of them (an older
// answer is a round trip behind the station's pop, not a contradiction of it). On the same tract
// it keeps its own friction anchor, velocity and depth (continuous, a round trip newer).
//
// Threads: the device thread's (Render, Answer); no allocation per cycle.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include "common/haptics/needle.h"

namespace vsurg::haptics {

class NeedleContact {
 public:
  // `spec` null: no needle (Render answers nothing).
  NeedleContact(std::shared_ptr<const NeedleTissueSpec> spec, double period_s = 1e-3);

  bool active() const { return model_.has_value(); }
  // This cycle's force on the needle at `tip`, advancing along `axis` (unit, hub to tip);
  // `next_sequence` is the number the stylus datagram of this cycle's sample goes out with.
  Vec3 Render(const Vec3& tip, const Vec3& axis, uint64_t next_sequence);
  // The server's answer about the station's datagram `echo_sequence`.
  void Answer(const LocalModel& local, uint64_t echo_sequence);

  const NeedleModel* model() const { return model_ ? &*model_ : nullptr; }
  uint64_t local_pops() const { return local_pops_; }    // pops rendered before any answer said so
  uint64_t corrections() const { return corrections_; }  // times the server's word was taken

 private:
  std::optional<NeedleModel> model_;
  double period_ = 1e-3;
  uint64_t changed_at_ = 0;  // the datagram of the station's latest change of tract or punctures
  uint64_t local_pops_ = 0, corrections_ = 0;
};

}  // namespace vsurg::haptics
