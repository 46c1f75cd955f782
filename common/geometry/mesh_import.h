// Surface meshes from files, read by assimp (Debian libassimp-dev): Wavefront OBJ (vertex
// colours, signed numbers, concave polygons), STL as 3D Slicer exports it (ASCII or binary), PLY
// (ASCII or binary), glTF 2 (.gltf with its buffers, .glb) and the other formats assimp reads.
// A well-kept library instead of our own parsers: mesh formats are not our core, and a surgeon's
// segmentation arrives in whichever of them the tool wrote.
//
// Every mesh in the file is taken, with its nodes' transforms applied; polygons are triangulated
// (concave ones by ear clipping), vertices at the same position are joined, within a mesh and
// across meshes (STL repeats them per facet; an OBJ's groups share their seams), points, lines
// and faces that repeat a vertex are dropped and counted. Each named mesh (an OBJ group or
// object, an STL solid, a glTF mesh) is a named group of vertices: a scene can hold one fixed.
// Positions are scaled by the file's unit (the file does not say: the caller does, "units" in a
// scene). Errors are kParseError (or
// kNotFound / kIoError for a missing or unreadable file) with a message that starts with the
// path and says what is wrong: assimp's own reason for a broken file, "no triangles", a
// position that is not finite.
//
// Output is not re-oriented or closed: models that need a closed, consistently oriented surface
// check geometry::Topology themselves and say so.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"

namespace vsurg::geometry {

struct ImportReport {
  int meshes = 0;         // meshes in the file
  int dropped_faces = 0;  // points, lines and faces with a repeated vertex
  // Named groups: the vertices of the file's meshes by name (a vertex on a seam is in both).
  std::map<std::string, std::vector<int>> groups;
};

// Metres per file unit for "m", "cm", "mm" or "um"; kInvalidArgument otherwise.
Expected<double> UnitScale(const std::string& units);

Expected<TriMesh> ImportSurfaceMesh(const std::string& path, double metres_per_unit = 1.0,
                                    ImportReport* report = nullptr);
// The same from memory; `format_hint` is the file extension ("obj", "stl", "ply", "glb").
Expected<TriMesh> ImportSurfaceMeshFromMemory(const void* data, size_t size,
                                              const std::string& format_hint,
                                              const std::string& source_name,
                                              double metres_per_unit = 1.0,
                                              ImportReport* report = nullptr);

}  // namespace vsurg::geometry
