#include "common/geometry/mesh_import.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unordered_map>

#include "common/geometry/obj_io.h"

namespace vsurg::geometry {
namespace {

// Node transforms are applied by FromScene itself (aiProcess_PreTransformVertices would merge
// the meshes of one material and lose their names, the groups a scene can hold fixed).
constexpr unsigned kSteps = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                            aiProcess_SortByPType | aiProcess_ValidateDataStructure;

struct PositionHash {
  size_t operator()(const Vec3& p) const {
    const std::hash<double> h;
    return h(p.x()) ^ (h(p.y()) * 0x9e3779b97f4a7c15ull) ^ (h(p.z()) * 0xc2b2ae3d27d4eb4full);
  }
};
struct PositionEqual {
  bool operator()(const Vec3& a, const Vec3& b) const { return a == b; }
};

Expected<TriMesh> FromScene(const aiScene* scene, const std::string& source, double scale,
                            ImportReport* report) {
  if (!scene) return Error{ErrorCode::kParseError, source + ": " + aiGetErrorString(), "mesh"};
  ImportReport local;
  ImportReport& r = report ? *report : local;
  r = ImportReport{};
  r.meshes = static_cast<int>(scene->mNumMeshes);
  TriMesh out;
  std::unordered_map<Vec3, int, PositionHash, PositionEqual> index;  // welded positions
  // Every mesh a node references, in the node's world transform (depth first from the root).
  std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack;
  if (scene->mRootNode) stack.emplace_back(scene->mRootNode, scene->mRootNode->mTransformation);
  while (!stack.empty()) {
    const auto [node, world] = stack.back();
    stack.pop_back();
    for (unsigned c = 0; c < node->mNumChildren; ++c)
      stack.emplace_back(node->mChildren[c], world * node->mChildren[c]->mTransformation);
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      if (node->mMeshes[k] >= scene->mNumMeshes) continue;
      const aiMesh* mesh = scene->mMeshes[node->mMeshes[k]];
      const std::string name =
          mesh->mName.length > 0 ? mesh->mName.C_Str() : std::string(node->mName.C_Str());
      std::vector<int> local_index(mesh->mNumVertices);
      std::vector<int>& group = r.groups[name];
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D p = world * mesh->mVertices[v];
        const Vec3 x = scale * Vec3(p.x, p.y, p.z);
        if (!x.allFinite())
          return Error{ErrorCode::kParseError,
                       source + ": vertex " + std::to_string(v) + " of mesh '" + name +
                           "' is not a finite position",
                       "mesh"};
        auto [it, added] = index.emplace(x, out.VertexCount());
        if (added) out.positions.push_back(x);
        local_index[v] = it->second;
        group.push_back(it->second);
      }
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices != 3) {
          ++r.dropped_faces;
          continue;
        }
        const Triangle t = {local_index[face.mIndices[0]], local_index[face.mIndices[1]],
                            local_index[face.mIndices[2]]};
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
          ++r.dropped_faces;
          continue;
        }
        out.triangles.push_back(t);
      }
    }
  }
  for (auto& [name, vertices] : r.groups) {
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  }
  if (out.triangles.empty())
    return Error{ErrorCode::kParseError,
                 source + ": no triangles" +
                     (r.dropped_faces ? " (" + std::to_string(r.dropped_faces) +
                                            " points, lines or repeated-vertex faces dropped)"
                                      : ""),
                 "mesh"};
  if (Status st = Validate(out); !st.ok())
    return Error{ErrorCode::kParseError, source + ": " + st.error().message, "mesh"};
  return out;
}

// assimp's reasons carry no line ("OBJ: vertex index out of range" even for a bad number). When
// it refuses an OBJ file, the project's own strict OBJ reader (obj_io.h) reads the same text for
// a line-numbered reason; both are given. Only after a refusal: that reader refuses some files
// assimp reads (vertex colours), so it never judges a file assimp accepts.
Error WithObjLine(const Error& refused, std::istream& text, const std::string& source) {
  auto strict = ParseObj(text, source);
  if (strict.ok() || strict.error().code != ErrorCode::kParseError) return refused;
  std::string why = refused.message;
  if (why.rfind(source + ": ", 0) == 0) why = why.substr(source.size() + 2);
  return Error{ErrorCode::kParseError, strict.error().message + " (assimp: " + why + ")", "mesh"};
}

bool IsObj(const std::string& name) {
  const std::string ext = std::filesystem::path(name).extension().string();
  return ext == ".obj" || ext == ".OBJ" || name == "obj";
}

}  // namespace

Expected<double> UnitScale(const std::string& units) {
  if (units == "m") return 1.0;
  if (units == "cm") return 0.01;
  if (units == "mm") return 0.001;
  if (units == "um") return 1e-6;
  return InvalidArgument("units", "must be m, cm, mm or um, got '" + units + "'");
}

Expected<TriMesh> ImportSurfaceMesh(const std::string& path, double metres_per_unit,
                                    ImportReport* report) {
  if (!(metres_per_unit > 0) || !std::isfinite(metres_per_unit))
    return InvalidArgument("units", "the scale must be > 0");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return Error{ErrorCode::kNotFound, path + ": no such file", "mesh"};
  const aiScene* scene = aiImportFile(path.c_str(), kSteps);
  auto out = FromScene(scene, path, metres_per_unit, report);
  if (scene) aiReleaseImport(scene);
  if (!scene && IsObj(path)) {
    std::ifstream text(path);
    return WithObjLine(out.error(), text, path);
  }
  return out;
}

Expected<TriMesh> ImportSurfaceMeshFromMemory(const void* data, size_t size,
                                              const std::string& format_hint,
                                              const std::string& source_name,
                                              double metres_per_unit, ImportReport* report) {
  if (!(metres_per_unit > 0) || !std::isfinite(metres_per_unit))
    return InvalidArgument("units", "the scale must be > 0");
  if (size == 0) return Error{ErrorCode::kParseError, source_name + ": empty", "mesh"};
  const aiScene* scene = aiImportFileFromMemory(
      static_cast<const char*>(data), static_cast<unsigned>(size), kSteps, format_hint.c_str());
  auto out = FromScene(scene, source_name, metres_per_unit, report);
  if (scene) aiReleaseImport(scene);
  if (!scene && IsObj(format_hint)) {
    std::istringstream text(std::string(static_cast<const char*>(data), size));
    return WithObjLine(out.error(), text, source_name);
  }
  return out;
}

}  // namespace vsurg::geometry
