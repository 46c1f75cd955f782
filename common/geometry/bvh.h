// Bounding-volume hierarchy (axis-aligned boxes) over the triangles of a deforming surface.
//
// Built once over a mesh's topology (median split on the longest axis, ≤ 4 triangles a leaf);
// as the surface deforms, Refit() recomputes the boxes bottom-up over new positions (same
// topology, O(n), no allocation): each leaf's box from its distinct vertices, listed at build
// time (a leaf's four triangles share about half of their twelve corners). Queries take the
// positions they run against, so one tree can serve any snapshot of the same mesh; they use a fixed
// stack and never allocate.
//
// Threads: queries are const and may run on any thread against positions nobody is writing;
// Refit writes the boxes (the deformation thread refits its own copy, see sim/simulation.h).
// Units: metres.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/geometry/mesh.h"

namespace vsurg::geometry {

struct ClosestHit {
  int triangle = -1;  // −1: nothing within range
  Vec3 barycentric = Vec3::Zero();
  Vec3 point = Vec3::Zero();
  double distance = std::numeric_limits<double>::infinity();
};

struct RayHit {
  int triangle = -1;  // −1: no hit
  double t = 0;       // along the segment, 0..1 (or the ray, in its length units)
  Vec3 barycentric = Vec3::Zero();
  Vec3 point = Vec3::Zero();
  bool front_face = false;  // the segment enters through the outward side
};

class Bvh {
 public:
  Bvh() = default;
  explicit Bvh(const TriMesh& mesh);

  void Refit(const std::vector<Vec3>& positions);

  // The closest surface point within max_distance. Triangles whose unit normal n has
  // n·normal_hint < min_normal_dot are skipped (with the default hint none is).
  // start_triangle (a caller's previous answer, −1 for none) is measured first: its distance
  // bounds the search from the start, so no box farther than it is opened (for a point under a
  // smooth surface most boxes around it are about as near, so this saves little: 4% in
  // docs/BENCHMARKS.md). The answer's distance is the same either way; of faces equally near
  // (a shared edge or corner), the start wins.
  ClosestHit Closest(const std::vector<Vec3>& positions, const Vec3& p,
                     double max_distance = std::numeric_limits<double>::infinity(),
                     const Vec3& normal_hint = Vec3::Zero(), double min_normal_dot = -2.0,
                     int start_triangle = -1) const;

  // As Closest, and one walk of the tree also lists in `near` (cleared first) every face, whatever
  // its normal, whose closest point lies within R = the answer's distance + slack of p (with no
  // answer, R = max_distance + slack), with its squared distance. At most `capacity` are listed;
  // returns R, or −1 when more faces than that are within it (the list is then cut short).
  struct NearFace {
    int32_t triangle;
    double distance2;
  };
  double ClosestAndNear(const std::vector<Vec3>& positions, const Vec3& p, double max_distance,
                        const Vec3& normal_hint, double min_normal_dot, int start_triangle,
                        double slack, size_t capacity, std::vector<NearFace>& near,
                        ClosestHit& hit) const;

  // The first triangle the segment a→b crosses (t ∈ [0, 1]).
  RayHit FirstHit(const std::vector<Vec3>& positions, const Vec3& a, const Vec3& b) const;

  int node_count() const { return static_cast<int>(nodes_.size()); }
  const std::vector<Triangle>& triangles() const { return triangles_; }

 private:
  struct Node {
    Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
    int32_t left = -1;  // child index, −1 for a leaf
    int32_t right = -1;
    int32_t first = 0;  // leaf: first entry in order_
    int32_t count = 0;  // leaf: number of triangles
  };
  // The topology only (children, leaves' triangles); the constructor's Refit makes the boxes.
  int Build(int first, int count, const std::vector<Vec3>& centroid);
  // Closest's walk; with near, also ClosestAndNear's list (boxes opened up to the answer + slack).
  ClosestHit Search(const std::vector<Vec3>& positions, const Vec3& p, double max_distance,
                    const Vec3& normal_hint, double min_normal_dot, int start_triangle,
                    double slack, size_t capacity, std::vector<NearFace>* near) const;

  std::vector<Triangle> triangles_;
  std::vector<int32_t> order_;  // triangle indices grouped by leaf
  std::vector<Node> nodes_;     // children after their parent: refit runs backwards
  // Node i's distinct vertices (leaves only; empty for inner nodes):
  // leaf_vertices_[vertex_start_[i] .. vertex_start_[i + 1]). Apart from Node, which stays 64
  // bytes for the queries.
  std::vector<int32_t> vertex_start_;
  std::vector<int32_t> leaf_vertices_;
};

// The closest-face query of a point that moves little between calls over a surface that moves
// little (the proxy's tip at 1 kHz), answered from a short list instead of the tree. A call the
// list cannot answer walks the tree (Bvh::ClosestAndNear) and lists every face whose closest point
// lay within R = d + 2·margin of that call's point c, d being its answer's distance (or the range,
// with no answer). Later, at a point p over a surface no vertex of which has moved more than m
// since, a face off the list is farther than R − |p − c| − m: the list's own best answer stands
// when it is nearer than that (with no answer, when the range is), and otherwise the tree answers
// and the list is made again. The answer's distance is therefore always the tree's (tested); of
// faces equally near (a shared edge or corner), which one is returned may differ. A tip 3–4 mm
// deep has 6–13 faces on a 0.5 mm margin's list, where the walk opens some 45 boxes and 25 faces:
// a third of the time or less at a node's load (docs/BENCHMARKS.md, "the proxy's query from a
// kept list"). The list is kept nearest first, each face with its distance from c; a face's
// distance from p is at least that less |p − c| + m, so a call stops at the first face that
// cannot be nearer than its best so far: a resting tip measures the face it rests on and its
// equals, not the whole list.
//
// surface_motion is a bound on how far the surface has moved in all, non-decreasing over its
// life: the sum, over the surfaces published so far, of each one's largest vertex move from the
// one before (Simulation's Snapshot::motion). Unknown (+inf): no list is kept and each call is
// the tree's query. Not thread-safe: one per querying thread (a session's haptic path).
class ClosestCache {
 public:
  static constexpr size_t kCapacity = 256;  // faces; a nearer crowd is not listed
  explicit ClosestCache(double margin = 5e-4);
  // A copy holds its lists in storage of its own reserved to kCapacity, so no call allocates.
  ClosestCache(const ClosestCache& other);
  ClosestCache& operator=(const ClosestCache& other);

  ClosestHit Closest(const Bvh& bvh, const std::vector<Vec3>& positions, double surface_motion,
                     const Vec3& p, double max_distance, const Vec3& normal_hint = Vec3::Zero(),
                     double min_normal_dot = -2.0, int start_triangle = -1);
  void Clear();
  uint64_t hits() const { return hits_; }          // calls the list answered
  uint64_t misses() const { return misses_; }      // calls the tree answered
  size_t listed() const { return faces_.size(); }  // faces on the list now
  uint64_t examined() const { return examined_; }  // faces the list's answers measured

 private:
  struct Face {
    int32_t triangle, a, b, c;  // the corners inline: a listed face reads no triangle table
    double distance;            // from the list's centre when listed; the list is nearest first
  };
  double margin_;
  std::vector<Face> faces_;
  std::vector<Bvh::NearFace> scratch_;
  Vec3 centre_ = Vec3::Zero();
  double radius_ = -1;  // R; < 0: no list
  double motion_ = 0;   // surface_motion when the list was made
  size_t triangle_count_ = 0;
  uint64_t hits_ = 0, misses_ = 0, examined_ = 0;
};

// Closest point on triangle abc to p, as barycentric weights (Ericson §5.1.5).
Vec3 ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace vsurg::geometry
