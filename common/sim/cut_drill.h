// The pattern-cutting drill, run whole on one thread (DESIGN.md "Cutting"): a blade driven by a
// scripted trainee through a cuttable patch at the haptic rate, the blade's fracture-mechanics
// force (haptics/blade.h), the patch cut and deformed at the same rate (tissue/cut_membrane.h),
// and the cut scored (scoring/cut.h). What the drill measures: the cost of each stage per step,
// the force against the fracture model's prediction, and the trainee's metrics.
//
// Drill files (scenes/drills/*.json, mm and N as people read them):
//   { "name": "pattern-cut", "description": "…",
//     "tissue":  { "size_mm": [80, 80], "cells": 32, "thickness_mm": 1.2,
//                  "youngs_modulus": 1.18e6, "density": 1100, "pretension": 0.02,
//                  "failure_strain": 0.54 },
//     "blade":   { "toughness": 1700, "angle_deg": 0, "width_mm": 0.3 },
//     "pattern": { "type": "circle", "centre_mm": [0, 0], "radius_mm": 15, "band_mm": 2 }
//              | { "type": "line", "from_mm": [x, y], "to_mm": [x, y], "band_mm": 2 },
//     "task":    { "force_limit_n": 3, "time_limit_s": 120, "expert_time_s": 25 } }
// Every value is checked by name ("blade.toughness: must be in […]"); the blade's and the
// patch's own checks follow (haptics::CheckBlade, tissue::CheckCutMembrane).
//
// Set-up allocates; the loop does not but for what the recorder's report keeps.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/haptics/blade.h"
#include "common/scoring/cut.h"
#include "common/tissue/cut_membrane.h"

namespace vsurg::sim {

struct CutDrillSpec {
  std::string name, description, source;
  tissue::CutMembraneParams tissue;
  haptics::BladeParams blade;  // its stiffnesses are the patch's, set by RunCutDrill
  scoring::CutTask task;
};

// The blade as `patch` meets it: `blade` with the patch's own in-plane and out-of-plane
// stiffnesses (CutMembrane::InPlaneStiffness, NormalStiffness).
Expected<haptics::BladeModel> BladeOnPatch(haptics::BladeParams blade,
                                           const tissue::CutMembrane& patch);

Expected<CutDrillSpec> ParseCutDrill(const std::string& json_text, const std::string& source);
Expected<CutDrillSpec> LoadCutDrill(const std::string& path);

// A scripted trainee's two hands. The right draws the blade along the pattern at `speed` with a
// lateral wobble of `wobble` m (two sines of random phase), lifting the blade out `lifts` times on
// the way. The left holds the patch with a grasper beside the cut (a circle's piece at its middle,
// a line 6 mm to its left at its middle) before the blade goes in, lifting it by `grasp_lift` m
// for counter-traction and pulling it `grasp_pull` m away from the cut, over a second.
struct CutHand {
  double speed = 0.005;  // m/s
  double wobble = 0.0003;
  int lifts = 0;
  uint32_t seed = 1;
  double grasp_lift = 0.003, grasp_pull = 0;
  static CutHand Expert(uint32_t seed);
  static CutHand Novice(uint32_t seed);
};

struct StageTimes {
  double p50_us = 0, p99_us = 0, max_us = 0;
};

struct CutDrillResult {
  scoring::CutMetrics metrics;
  double cutting_force = 0;    // N, J_c t: the fracture model's prediction
  double force_rms_error = 0;  // relative to it, over the steps the cut advanced
  int cutting_steps = 0;
  double puncture_force = 0;  // N, the model's f_p, and the largest press before it
  double peak_press = 0;
  StageTimes blade, tissue;     // per 1 ms step: the blade's force; the cut and the step
  double max_cut_us = 0;        // the dearest single topology update
  double peak_grasp_force = 0;  // N, on the left hand's jaws
  double torn_length = 0;       // m, torn by pulling (edges past the failure strain)
  int cut_edges = 0, particles = 0, freed = 0, steps = 0;
  bool diverged = false;
};

// What a figure of the drill needs: per step the time (s), the tip (m), the force on the hand
// (N) and whether the blade was through; at the end, the patch's triangles as they lie (m, the
// freed piece left out) and the blade's cut (segments, m).
struct CutDrillTrace {
  struct Sample {
    double t, x, y, z, force;
    bool through, cutting;
  };
  std::vector<Sample> samples;
  std::vector<std::array<geometry::Vec3, 3>> faces;
  std::vector<haptics::BladeModel::Segment> cut;
};

// Runs the drill at 1 kHz until the hand's path ends (or the time limit). Deterministic but for
// the times. `trace`, when given, is filled for a figure.
Expected<CutDrillResult> RunCutDrill(const CutDrillSpec& spec, const CutHand& hand,
                                     CutDrillTrace* trace = nullptr);

}  // namespace vsurg::sim
