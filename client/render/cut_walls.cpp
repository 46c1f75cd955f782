#include "client/render/cut_walls.h"

#include <algorithm>

namespace vsurg::client {
namespace {

using geometry::Triangle;

bool Removed(const Triangle& t) {
  return t[0] == t[1] && t[1] == t[2];
}

uint64_t EdgeKey(int a, int b) {
  const auto lo = static_cast<uint64_t>(std::min(a, b)), hi = static_cast<uint64_t>(std::max(a, b));
  return lo << 32 | hi;
}

// The sorted keys of every edge of the faces drawn, each once per face that has it.
void EdgeKeys(const std::vector<Triangle>& faces, std::vector<uint64_t>& keys) {
  keys.clear();
  for (const Triangle& t : faces)
    if (!Removed(t))
      for (int k = 0; k < 3; ++k) keys.push_back(EdgeKey(t[k], t[(k + 1) % 3]));
  std::sort(keys.begin(), keys.end());
}

// How many faces have the edge.
int FacesOf(const std::vector<uint64_t>& keys, uint64_t key) {
  const auto [lo, hi] = std::equal_range(keys.begin(), keys.end(), key);
  return static_cast<int>(hi - lo);
}

}  // namespace

CutWalls::CutWalls(const std::vector<Triangle>& rest) : rim_(rest.size(), 0) {
  EdgeKeys(rest, keys_);
  for (size_t f = 0; f < rest.size(); ++f)
    for (int k = 0; k < 3; ++k)
      if (!Removed(rest[f]) && FacesOf(keys_, EdgeKey(rest[f][k], rest[f][(k + 1) % 3])) == 1)
        rim_[f] = static_cast<uint8_t>(rim_[f] | (1 << k));
}

void CutWalls::Build(const geometry::TriMesh& now, double thickness, ShapeMesh& out) {
  out.positions.clear();
  out.normals.clear();
  out.indices.clear();
  edges_ = 0;
  const size_t n = now.positions.size();
  if (now.triangles.size() != rim_.size() || now.normals.size() != n || !(thickness > 0)) return;
  EdgeKeys(now.triangles, keys_);
  const float half = static_cast<float>(thickness / 2);
  for (size_t f = 0; f < now.triangles.size(); ++f) {
    const Triangle& t = now.triangles[f];
    if (Removed(t)) continue;
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3], c = t[(k + 2) % 3];
      if ((rim_[f] >> k & 1) || FacesOf(keys_, EdgeKey(a, b)) != 1) continue;
      const Eigen::Vector3f pa = now.positions[a].cast<float>(),
                            pb = now.positions[b].cast<float>();
      const Eigen::Vector3f na = now.normals[a].cast<float>(), nb = now.normals[b].cast<float>();
      // Out of the face: across the edge, in the sheet's plane, away from its third corner.
      const Eigen::Vector3f along = pb - pa, mid = 0.5f * (pa + pb);
      Eigen::Vector3f out_of = along.cross(na + nb);
      if (out_of.dot(mid - now.positions[c].cast<float>()) < 0) out_of = -out_of;
      if (!(out_of.squaredNorm() > 0) || !out_of.allFinite()) continue;
      out_of.normalize();
      const auto base = static_cast<uint32_t>(out.positions.size());
      for (const Eigen::Vector3f& p :
           {Eigen::Vector3f(pa + half * na), Eigen::Vector3f(pa - half * na),
            Eigen::Vector3f(pb - half * nb), Eigen::Vector3f(pb + half * nb)}) {
        out.positions.push_back(p);
        out.normals.push_back(out_of);
      }
      out.indices.insert(out.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
      ++edges_;
    }
  }
}

}  // namespace vsurg::client
