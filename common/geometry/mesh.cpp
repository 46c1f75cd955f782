#include "common/geometry/mesh.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <unordered_map>

#include <Eigen/Geometry>

namespace vsurg::geometry {
namespace {

bool Finite(const Vec3& p) {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(p.z());
}

Status CheckPositions(const std::vector<Vec3>& positions) {
  for (size_t i = 0; i < positions.size(); ++i) {
    if (!Finite(positions[i])) {
      return InvalidArgument("positions", "vertex " + std::to_string(i) + " is not finite");
    }
  }
  return Status::Ok();
}

uint64_t EdgeKey(int a, int b) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
}

}  // namespace

Status Validate(const TriMesh& mesh) {
  if (Status s = CheckPositions(mesh.positions); !s.ok()) return s;
  const int n = mesh.VertexCount();
  for (int t = 0; t < mesh.TriangleCount(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= n) {
        return InvalidArgument("triangles", "triangle " + std::to_string(t) + " refers to vertex " +
                                                std::to_string(tri[k]) + " of " +
                                                std::to_string(n));
      }
    }
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      return InvalidArgument("triangles", "triangle " + std::to_string(t) + " repeats a vertex");
    }
  }
  return Status::Ok();
}

Status Validate(const TetMesh& mesh, double min_volume) {
  if (Status s = CheckPositions(mesh.positions); !s.ok()) return s;
  const int n = mesh.VertexCount();
  for (int t = 0; t < mesh.TetCount(); ++t) {
    for (int k : mesh.tetrahedra[t]) {
      if (k < 0 || k >= n) {
        return InvalidArgument("tetrahedra", "tetrahedron " + std::to_string(t) +
                                                 " refers to vertex " + std::to_string(k) + " of " +
                                                 std::to_string(n));
      }
    }
    const double v = TetVolume(mesh, t);
    if (!(v > min_volume)) {
      return InvalidArgument("tetrahedra", "tetrahedron " + std::to_string(t) +
                                               (v < 0 ? " is inverted" : " is degenerate") +
                                               " (volume " + std::to_string(v) + " m^3)");
    }
  }
  return Status::Ok();
}

Vec3 AnyPerpendicular(const Vec3& a) {
  const Vec3 t = std::abs(a.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return a.cross(t).normalized();
}

Vec3 TriangleNormal(const std::vector<Vec3>& x, const Triangle& t) {
  const Vec3 n = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : Vec3::Zero();
}

Vec3 TriangleNormal(const TriMesh& mesh, int t) {
  return TriangleNormal(mesh.positions, mesh.triangles[t]);
}

double TriangleArea(const TriMesh& mesh, int t) {
  const Triangle& tri = mesh.triangles[t];
  return 0.5 * (mesh.positions[tri[1]] - mesh.positions[tri[0]])
                   .cross(mesh.positions[tri[2]] - mesh.positions[tri[0]])
                   .norm();
}

void ComputeVertexNormals(TriMesh& mesh) {
  mesh.normals.assign(mesh.positions.size(), Vec3::Zero());
  for (const Triangle& tri : mesh.triangles) {
    // The unnormalised cross product weights each face by twice its area.
    const Vec3 n = (mesh.positions[tri[1]] - mesh.positions[tri[0]])
                       .cross(mesh.positions[tri[2]] - mesh.positions[tri[0]]);
    for (int k : tri) mesh.normals[k] += n;
  }
  for (Vec3& n : mesh.normals) {
    const double len = n.norm();
    n = len > 0 ? Vec3(n / len) : Vec3::Zero();
  }
}

VertexAdjacency BuildVertexAdjacency(const TriMesh& mesh) {
  const auto edges = UniqueEdges(mesh);
  VertexAdjacency adj;
  adj.offsets.assign(mesh.positions.size() + 1, 0);
  for (const auto& e : edges) {
    ++adj.offsets[e[0] + 1];
    ++adj.offsets[e[1] + 1];
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) adj.offsets[v + 1] += adj.offsets[v];
  adj.neighbours.resize(adj.offsets.back());
  std::vector<int> fill(adj.offsets.begin(), adj.offsets.end() - 1);
  for (const auto& e : edges) {
    adj.neighbours[fill[e[0]]++] = e[1];
    adj.neighbours[fill[e[1]]++] = e[0];
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    std::sort(adj.neighbours.begin() + adj.offsets[v], adj.neighbours.begin() + adj.offsets[v + 1]);
  }
  return adj;
}

std::vector<std::array<int, 2>> UniqueEdges(const TriMesh& mesh) {
  std::vector<std::array<int, 2>> edges;
  edges.reserve(mesh.triangles.size() * 3);
  for (const Triangle& tri : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int a = tri[k], b = tri[(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

TopologyReport CheckTopology(const TriMesh& mesh) {
  // For each undirected edge count its uses in each direction.
  struct Uses {
    int forward = 0;   // traversed min→max
    int backward = 0;  // traversed max→min
  };
  std::unordered_map<uint64_t, Uses> uses;
  uses.reserve(mesh.triangles.size() * 2);
  for (const Triangle& tri : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int a = tri[k], b = tri[(k + 1) % 3];
      Uses& u = uses[EdgeKey(std::min(a, b), std::max(a, b))];
      (a < b ? u.forward : u.backward) += 1;
    }
  }
  TopologyReport report;
  for (const auto& [key, u] : uses) {
    const int total = u.forward + u.backward;
    if (total == 1) ++report.boundary_edges;
    if (total >= 3) ++report.non_manifold_edges;
    if (u.forward > 1 || u.backward > 1) ++report.misoriented_edges;
  }
  report.euler_characteristic =
      mesh.VertexCount() - static_cast<int>(uses.size()) + mesh.TriangleCount();
  return report;
}

double SignedVolume(const TriMesh& mesh) {
  double six_v = 0;
  for (const Triangle& tri : mesh.triangles) {
    six_v += mesh.positions[tri[0]].dot(mesh.positions[tri[1]].cross(mesh.positions[tri[2]]));
  }
  return six_v / 6.0;
}

double TetVolume(const TetMesh& mesh, int t) {
  const Tetrahedron& k = mesh.tetrahedra[t];
  const Vec3& a = mesh.positions[k[0]];
  return (mesh.positions[k[1]] - a).cross(mesh.positions[k[2]] - a).dot(mesh.positions[k[3]] - a) /
         6.0;
}

TriMesh BoundarySurface(const TetMesh& mesh) {
  // Faces of a positively oriented tet (a,b,c,d), each counter-clockwise seen from outside.
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::pair<Triangle, int>> faces;  // sorted key → (face, count)
  for (const Tetrahedron& tet : mesh.tetrahedra) {
    for (const auto& f : kFaces) {
      const Triangle face = {tet[f[0]], tet[f[1]], tet[f[2]]};
      std::array<int, 3> key = face;
      std::sort(key.begin(), key.end());
      auto [it, inserted] = faces.try_emplace(key, face, 0);
      ++it->second.second;
    }
  }
  TriMesh surface;
  surface.positions = mesh.positions;
  for (const auto& [key, entry] : faces) {
    if (entry.second == 1) surface.triangles.push_back(entry.first);
  }
  return surface;
}

}  // namespace vsurg::geometry
