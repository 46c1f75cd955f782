// A press scene's contact law, measured on the server's own tissue: what a station renders a
// contact's first round trip with, before any answer from the server has arrived
// (haptics/tissue_surface.h).
//
// Two measurements, each a replay of a scripted stylus through the scene's simulation:
//   - the tissue's viscoelastic law as the server fits it (haptics::ViscoelasticFit) at the
//     good scripted trainee's press: k_t (N/m) and b (N·s/m), the tangent about that press;
//   - the tissue's static curve: the tool pressed down the good trainee's normal to depths of
//     0.5 to 8 mm, held at each until the tissue has settled, the yield S under the proxy and the
//     force along the normal at each hold's end (f·n = k_p·(d − S), d the tool's depth), which
//     is the tissue's elastic force e(S) once settled. k_t is its tangent at the press; the
//     curve itself is what a contact from the rest surface follows (haptics::TissueCurve).
//
// Units: m, s, N.
#pragma once

#include <vector>

#include "common/core/expected.h"
#include "common/haptics/viscoelastic.h"
#include "common/sim/scene.h"

namespace vsurg::sim {

struct ContactLawPoint {
  double depth = 0;  // m, the tool below the rest surface along the normal
  double yield = 0;  // m, the surface under the proxy
  double force = 0;  // N, along the normal
};

struct ContactLaw {
  double stiffness = 0, damping = 0;   // the fit at the good trainee's press: N/m, N·s/m
  std::vector<ContactLawPoint> curve;  // the static curve, by depth
  haptics::TissueCurve tissue;         // the curve's strictly rising points
};

// A press scene (measured with the viscoelastic contact model whatever it renders); errors name
// "scene". `tissue` is empty when no depth settled in contact.
Expected<ContactLaw> MeasureContactLaw(Scene scene);

}  // namespace vsurg::sim
