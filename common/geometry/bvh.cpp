#include "common/geometry/bvh.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace vsurg::geometry {
namespace {

constexpr int kLeafSize = 4;
constexpr int kStackSize = 128;  // depth of a median-split tree over < 2^60 triangles

double BoxDistance2(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  const Vec3 d = (lo - p).cwiseMax(Vec3::Zero()).cwiseMax(p - hi);
  return d.squaredNorm();
}

// Slab test of segment a + t·d, t ∈ [0, t_max], against a box.
bool SegmentHitsBox(const Vec3& a, const Vec3& inv_d, double t_max, const Vec3& lo,
                    const Vec3& hi) {
  double t0 = 0, t1 = t_max;
  for (int k = 0; k < 3; ++k) {
    double ta = (lo[k] - a[k]) * inv_d[k], tb = (hi[k] - a[k]) * inv_d[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

// The normal filter of a closest query: faces whose unit normal n has n·hint < min_dot are refused
// (with a zero hint, or min_dot ≤ −1, none is).
struct FaceFilter {
  FaceFilter(const Vec3& normal_hint, double min_normal_dot)
      : on(min_normal_dot > -1.0 && normal_hint.squaredNorm() > 0),
        hint(normal_hint),
        min_dot(min_normal_dot),
        hint_norm(normal_hint.norm()) {}
  bool Accepts(const Vec3& a, const Vec3& b, const Vec3& c) const {
    if (!on) return true;
    const Vec3 n = (b - a).cross(c - a);
    const double len = n.norm();
    return len > 0 && !(n.dot(hint) < min_dot * len * hint_norm);
  }
  bool on;
  Vec3 hint;
  double min_dot, hint_norm;
};

}  // namespace

Vec3 ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return Vec3(1, 0, 0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return Vec3(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return Vec3(1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return Vec3(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return Vec3(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return Vec3(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return Vec3(1, 0, 0);  // degenerate: its first corner
  const double v = vb / denom, w = vc / denom;
  return Vec3(1 - v - w, v, w);
}

Bvh::Bvh(const TriMesh& mesh) : triangles_(mesh.triangles) {
  const int n = mesh.TriangleCount();
  order_.resize(n);
  std::vector<Vec3> centroid(n);
  for (int t = 0; t < n; ++t) {
    order_[t] = t;
    const Triangle& tri = triangles_[t];
    centroid[t] = (mesh.positions[tri[0]] + mesh.positions[tri[1]] + mesh.positions[tri[2]]) / 3.0;
  }
  nodes_.reserve(n > 0 ? 2 * ((n + kLeafSize - 1) / kLeafSize) : 0);
  if (n > 0) Build(0, n, centroid);
  vertex_start_.reserve(nodes_.size() + 1);
  leaf_vertices_.reserve(static_cast<size_t>(n) * 2);
  for (const Node& node : nodes_) {
    vertex_start_.push_back(static_cast<int32_t>(leaf_vertices_.size()));
    if (node.left >= 0) continue;
    const auto begin = leaf_vertices_.end() - leaf_vertices_.begin();
    for (int k = node.first; k < node.first + node.count; ++k)
      for (int v : triangles_[order_[k]]) leaf_vertices_.push_back(v);
    std::sort(leaf_vertices_.begin() + begin, leaf_vertices_.end());
    leaf_vertices_.erase(std::unique(leaf_vertices_.begin() + begin, leaf_vertices_.end()),
                         leaf_vertices_.end());
  }
  vertex_start_.push_back(static_cast<int32_t>(leaf_vertices_.size()));
  Refit(mesh.positions);  // the boxes: one computation for the build and every refit
}

int Bvh::Build(int first, int count, const std::vector<Vec3>& centroid) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{});
  if (count <= kLeafSize) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  Vec3 lo = centroid[order_[first]], hi = lo;
  for (int k = first; k < first + count; ++k)
    lo = lo.cwiseMin(centroid[order_[k]]), hi = hi.cwiseMax(centroid[order_[k]]);
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + first + half,
                   order_.begin() + first + count,
                   [&](int a, int b) { return centroid[a][axis] < centroid[b][axis]; });
  const int left = Build(first, half, centroid);
  const int right = Build(first + half, count - half, centroid);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

void Bvh::Refit(const std::vector<Vec3>& positions) {
  for (int i = static_cast<int>(nodes_.size()) - 1; i >= 0; --i) {
    Node& node = nodes_[i];
    if (node.left < 0) {
      // Each corner once (a leaf's triangles share about half of theirs).
      Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (int32_t k = vertex_start_[i]; k < vertex_start_[i + 1]; ++k) {
        const Vec3& p = positions[leaf_vertices_[k]];
        lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
      }
      node.lo = lo, node.hi = hi;
    } else {
      node.lo = nodes_[node.left].lo.cwiseMin(nodes_[node.right].lo);
      node.hi = nodes_[node.left].hi.cwiseMax(nodes_[node.right].hi);
    }
  }
}

namespace {

// Face abc's closest point to p (barycentric w, point q, squared distance d2).
struct FacePoint {
  Vec3 w, q;
  double d2;
};
FacePoint OnFace(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 w = ClosestPointOnTriangle(p, a, b, c);
  const Vec3 q = w[0] * a + w[1] * b + w[2] * c;
  return {w, q, (q - p).squaredNorm()};
}

// Face t is kept as the best when it is nearer than the best so far or, the first time, as near
// as the range allows (best_d2 starts at the range squared).
bool Keep(int t, const FacePoint& f, ClosestHit& best, double& best_d2) {
  if (!(f.d2 < best_d2 || (best.triangle < 0 && f.d2 <= best_d2))) return false;
  best_d2 = f.d2;
  best = ClosestHit{t, f.w, f.q, std::sqrt(f.d2)};
  return true;
}

}  // namespace

ClosestHit Bvh::Closest(const std::vector<Vec3>& positions, const Vec3& p, double max_distance,
                        const Vec3& normal_hint, double min_normal_dot, int start_triangle) const {
  return Search(positions, p, max_distance, normal_hint, min_normal_dot, start_triangle, 0, 0,
                nullptr);
}

double Bvh::ClosestAndNear(const std::vector<Vec3>& positions, const Vec3& p, double max_distance,
                           const Vec3& normal_hint, double min_normal_dot, int start_triangle,
                           double slack, size_t capacity, std::vector<NearFace>& near,
                           ClosestHit& hit) const {
  near.clear();
  hit = Search(positions, p, max_distance, normal_hint, min_normal_dot, start_triangle, slack,
               capacity, &near);
  const double radius = (hit.triangle >= 0 ? hit.distance : max_distance) + slack;
  if (!(radius < std::numeric_limits<double>::infinity())) return -1;
  // The walk kept what was within reach when it was met; the reach only shrank since.
  std::erase_if(near, [&](const NearFace& f) { return f.distance2 > radius * radius; });
  if (near.size() >= capacity) return -1;  // full: a face within R may have been left out
  return radius;
}

ClosestHit Bvh::Search(const std::vector<Vec3>& positions, const Vec3& p, double max_distance,
                       const Vec3& normal_hint, double min_normal_dot, int start_triangle,
                       double slack, size_t capacity, std::vector<NearFace>* near) const {
  ClosestHit best;
  if (nodes_.empty() || !p.allFinite()) return best;
  double best_d2 = max_distance * max_distance;
  // Boxes farther than this are not opened: the best so far, or with a list, it plus the slack.
  double open2 = best_d2;
  const auto reopen = [&] {
    if (!near) {
      open2 = best_d2;
      return;
    }
    const double r = (best.triangle >= 0 ? best.distance : max_distance) + slack;
    open2 = r * r;
  };
  reopen();
  const FaceFilter filter(normal_hint, min_normal_dot);
  // The triangle t's closest point, kept when it is nearer than the best so far (or, the first
  // time, as near as the range allows); with a list, every face within reach is listed.
  auto consider = [&](int t) {
    const Vec3& a = positions[triangles_[t][0]];
    const Vec3& b = positions[triangles_[t][1]];
    const Vec3& c = positions[triangles_[t][2]];
    const bool accepted = filter.Accepts(a, b, c);
    if (!accepted && !near) return;
    const FacePoint f = OnFace(p, a, b, c);
    if (near && f.d2 <= open2) {
      if (near->size() >= capacity)  // full: drop what the reach has since left behind
        std::erase_if(*near, [&](const NearFace& n) { return n.distance2 > open2; });
      if (near->size() < capacity) near->push_back({t, f.d2});
    }
    if (accepted && Keep(t, f, best, best_d2)) reopen();
  };
  if (start_triangle >= 0 && start_triangle < static_cast<int>(triangles_.size()))
    consider(start_triangle);
  // Each entry carries its box's distance, measured when its parent was opened, so no box is
  // measured twice; an entry whose box the best so far has moved out of range is dropped.
  struct Entry {
    int node;
    double d2;
  };
  Entry stack[kStackSize];
  int top = 0;
  stack[top++] = {0, BoxDistance2(p, nodes_[0].lo, nodes_[0].hi)};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.d2 > open2) continue;
    const Node& node = nodes_[e.node];
    if (node.left >= 0) {
      // Nearer child last, so it is popped first; a child out of range is not pushed.
      const double dl = BoxDistance2(p, nodes_[node.left].lo, nodes_[node.left].hi);
      const double dr = BoxDistance2(p, nodes_[node.right].lo, nodes_[node.right].hi);
      if (top + 2 > kStackSize) continue;  // unreachable for any real mesh; never overflow
      const Entry near_child{dl < dr ? node.left : node.right, std::min(dl, dr)};
      const Entry far_child{dl < dr ? node.right : node.left, std::max(dl, dr)};
      if (far_child.d2 <= open2) stack[top++] = far_child;
      if (near_child.d2 <= open2) stack[top++] = near_child;
      continue;
    }
    for (int k = node.first; k < node.first + node.count; ++k)
      if (order_[k] != start_triangle) consider(order_[k]);
  }
  return best;
}

ClosestCache::ClosestCache(double margin) : margin_(margin) {
  faces_.reserve(kCapacity);
  scratch_.reserve(kCapacity);
}

ClosestCache::ClosestCache(const ClosestCache& other) : ClosestCache(other.margin_) {
  *this = other;
}

ClosestCache& ClosestCache::operator=(const ClosestCache& other) {
  if (this == &other) return *this;
  margin_ = other.margin_;
  faces_.assign(other.faces_.begin(), other.faces_.end());  // within the reserved storage
  centre_ = other.centre_;
  radius_ = other.radius_;
  motion_ = other.motion_;
  triangle_count_ = other.triangle_count_;
  hits_ = other.hits_;
  misses_ = other.misses_;
  examined_ = other.examined_;
  return *this;
}

void ClosestCache::Clear() {
  faces_.clear();
  radius_ = -1;
}

ClosestHit ClosestCache::Closest(const Bvh& bvh, const std::vector<Vec3>& positions,
                                 double surface_motion, const Vec3& p, double max_distance,
                                 const Vec3& normal_hint, double min_normal_dot,
                                 int start_triangle) {
  const std::vector<Triangle>& triangles = bvh.triangles();
  if (!(surface_motion < std::numeric_limits<double>::infinity()) || !p.allFinite()) {
    ++misses_;
    return bvh.Closest(positions, p, max_distance, normal_hint, min_normal_dot, start_triangle);
  }
  // How far a face off the list may have come nearer: the point's move and the surface's.
  const double moved = (p - centre_).norm() + (surface_motion - motion_);
  if (radius_ >= 0 && triangle_count_ == triangles.size() && surface_motion >= motion_ &&
      moved < radius_) {
    // 1 nm below the bound: the rounding of the distances it compares, many times over.
    const double bound = radius_ - moved - 1e-9;
    ClosestHit best;
    double best_d2 = max_distance * max_distance;
    const FaceFilter filter(normal_hint, min_normal_dot);
    const auto consider = [&](int t, int32_t ia, int32_t ib, int32_t ic) {
      const Vec3 &a = positions[ia], &b = positions[ib], &c = positions[ic];
      if (filter.Accepts(a, b, c)) Keep(t, OnFace(p, a, b, c), best, best_d2);
    };
    if (start_triangle >= 0 && start_triangle < static_cast<int>(triangles.size())) {
      const Triangle& s = triangles[start_triangle];
      consider(start_triangle, s[0], s[1], s[2]);
    }
    // Nearest first (as listed): a face whose distance from the list's centre, less the move,
    // exceeds the best so far (or the range) cannot be nearer, nor can any after it.
    size_t k = 0;
    for (; k < faces_.size(); ++k) {
      const Face& f = faces_[k];
      if (f.distance - moved - 1e-9 > (best.triangle >= 0 ? best.distance : max_distance)) break;
      if (f.triangle != start_triangle) consider(f.triangle, f.a, f.b, f.c);
    }
    if (best.triangle >= 0 ? best.distance < bound : max_distance < bound) {
      ++hits_;
      examined_ += k;
      return best;
    }
  }
  ++misses_;
  ClosestHit hit;
  const double radius = bvh.ClosestAndNear(positions, p, max_distance, normal_hint, min_normal_dot,
                                           start_triangle, 2 * margin_, kCapacity, scratch_, hit);
  faces_.clear();
  radius_ = radius;
  if (radius >= 0) {
    std::sort(scratch_.begin(), scratch_.end(), [](const Bvh::NearFace& x, const Bvh::NearFace& y) {
      return x.distance2 < y.distance2;
    });
    for (const Bvh::NearFace& f : scratch_) {
      const Triangle& t = triangles[f.triangle];
      faces_.push_back({f.triangle, t[0], t[1], t[2], std::sqrt(f.distance2)});
    }
    centre_ = p;
    motion_ = surface_motion;
    triangle_count_ = triangles.size();
  }
  return hit;
}

// Möller–Trumbore against each triangle in the boxes the segment crosses.
RayHit Bvh::FirstHit(const std::vector<Vec3>& positions, const Vec3& a, const Vec3& b) const {
  RayHit best;
  if (nodes_.empty() || !a.allFinite() || !b.allFinite()) return best;
  const Vec3 d = b - a;
  const Vec3 inv_d(1.0 / d.x(), 1.0 / d.y(),
                   1.0 / d.z());  // ±inf where d is 0: the slab test copes
  double t_best = 1.0;
  int stack[kStackSize];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (!SegmentHitsBox(a, inv_d, t_best, node.lo, node.hi)) continue;
    if (node.left >= 0) {
      if (top + 2 > kStackSize) continue;
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    for (int k = node.first; k < node.first + node.count; ++k) {
      const int t = order_[k];
      const Vec3& p0 = positions[triangles_[t][0]];
      const Vec3 e1 = positions[triangles_[t][1]] - p0, e2 = positions[triangles_[t][2]] - p0;
      const Vec3 pv = d.cross(e2);
      const double det = e1.dot(pv);
      if (std::abs(det) < 1e-300) continue;  // parallel or degenerate
      const double inv = 1.0 / det;
      const Vec3 tv = a - p0;
      const double u = tv.dot(pv) * inv;
      if (u < 0 || u > 1) continue;
      const Vec3 qv = tv.cross(e1);
      const double v = d.dot(qv) * inv;
      if (v < 0 || u + v > 1) continue;
      const double s = e2.dot(qv) * inv;
      if (s < 0 || s > t_best) continue;
      t_best = s;
      best = RayHit{t, s, Vec3(1 - u - v, u, v), a + s * d, det > 0};  // det = −d·n: entering
    }
  }
  return best;
}

}  // namespace vsurg::geometry
