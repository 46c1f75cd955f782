// The case one attempt at a palpation practises (DESIGN.md "Palpation"): a scene whose task
// draws its lumps (Scene::cases) made concrete for one seed, so that no two attempts hide the same
// lumps and a trainee cannot learn the answer. The same seed gives the same case on every machine
// (tissue::DrawInclusions), which is what lets a session move to another node and a trial's
// replay show where its lumps were.
//
// Set-up code: allocates, builds the scene's FEM mesh (milliseconds for a sphere, CGAL's for a
// mesh file).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/sim/scene.h"

namespace vsurg::sim {

// The scene with its lumps drawn for `seed` into `inclusions`, and a name of its own,
// "NAME.case-SEED" (16 hex digits: each case's precomputed table is its own file in the reduced
// models' cache). A scene that draws no cases is returned as it is.
Expected<Scene> DrawCase(const Scene& scene, uint64_t seed);

// The surface a palpation examines: the triangles of `rest` none of whose corners the support
// holds and whose outward normal is within 60° of vertical (a hand presses from above: a pad's
// top, a dome's cap). The lumps are drawn under it, the coverage is its share examined, and the
// scripted searches press it.
std::vector<int> PalpableTriangles(const geometry::TriMesh& rest, const std::vector<int>& held);

// Per vertex of `rest`, its distance (m, straight) to the nearest corner of the palpable
// surface's rim: a corner of both a palpable triangle and another (+inf where there is no rim).
// Near the rim (a pad's edge) the tissue's stiffness falls off steeply and a lump is not told
// from it: cases are drawn away from it, and the scripted searches judge only beyond it.
std::vector<double> RimDistance(const geometry::TriMesh& rest, const std::vector<int>& palpable);

// The name DrawCase gives a scene's case.
std::string CaseName(const std::string& scene_name, uint64_t seed);

}  // namespace vsurg::sim
