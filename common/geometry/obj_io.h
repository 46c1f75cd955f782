// Wavefront OBJ import and export for triangle meshes. Scenes and tools read mesh files through
// assimp (mesh_import.h); this strict reader reads back our own exports and, when assimp refuses
// an OBJ file, finds the line and the reason (assimp gives neither).
//
// Import reads `v` (x y z [w]) and `f` (v, v/vt, v//vn, v/vt/vn; negative indices count back
// from the latest vertex); polygons are fan-triangulated; `vn`, `vt`, groups, materials and
// smoothing groups are accepted and ignored. Anything malformed is an error of code kParseError
// whose message starts with "<path>:<line>: " and says why. Export writes through a temporary
// file renamed into place, so a failed write never leaves a truncated mesh behind.
#pragma once

#include <iosfwd>
#include <string>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

Expected<TriMesh> ReadObj(const std::string& path);
// Parses OBJ text; `source_name` prefixes error messages (a path or "<memory>").
Expected<TriMesh> ParseObj(std::istream& in, const std::string& source_name);

// Writes positions, per-vertex normals when the mesh has them, and faces. `comment` becomes a
// leading "# ..." line (may be empty).
Status WriteObj(const TriMesh& mesh, const std::string& path, const std::string& comment = "");
void FormatObj(const TriMesh& mesh, std::ostream& out, const std::string& comment = "");

}  // namespace vsurg::geometry
