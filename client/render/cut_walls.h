// The walls a cut opens in a sheet of tissue (a cut scene's patch, drawn as its physics surface):
// along each edge that a cut or a tear left with a face on one side only, a strip as tall as the
// sheet is thick, from −t/2 to +t/2 along the sheet's normals at the edge's ends, facing out of
// the face it bounds. The view shades them in the tissue's interior colour (MeshView), so the cut
// shows the dermis it exposed instead of a paper edge.
//
// An edge is a wall when it borders one face now and bordered two at rest: a face keeps its index
// and its corners' order when a cut gives a corner a copy of its particle (tissue/cut_membrane.h),
// so edge k of face f now is edge k of face f at rest. The frame's rim is no wall; a freed piece's
// faces are gone ({0, 0, 0}), so its hole's rim is.
//
// Units: m. Threads: any (no OpenGL here; the view uploads the result).
#pragma once

#include <cstdint>
#include <vector>

#include "client/render/shapes.h"
#include "common/geometry/mesh.h"

namespace vsurg::client {

class CutWalls {
 public:
  // `rest`: the sheet's faces at rest (their rim found once).
  explicit CutWalls(const std::vector<geometry::Triangle>& rest);
  // The walls of `now` (positions, its faces as they are, their vertex normals), `thickness` m
  // tall; a quad (four vertices, flat-shaded) per wall edge. Reuses out's capacity.
  void Build(const geometry::TriMesh& now, double thickness, ShapeMesh& out);
  // The wall edges of the last Build.
  int edges() const { return edges_; }

 private:
  std::vector<uint8_t> rim_;  // per face, bit k: edge k bordered one face at rest
  std::vector<uint64_t> keys_;
  int edges_ = 0;
};

}  // namespace vsurg::client
