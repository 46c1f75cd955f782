// The reduced models' precomputation cached on disk (common/tissue/reduced.h): a scene's twist
// field or contact table is computed once and read back in milliseconds at the next start.
//
// Key: SHA-256 (OpenSSL) over everything the result depends on, in a fixed byte order: the
// format version, the model kind, the FEM mesh (positions and elements), the material, the
// fixed vertices, the load's definition (loaded face and axis, or footprint and reachable
// vertices) and the display surface. One file per scene model, DIR/NAME.vrm:
//   "VSURGRM1" | key (32 B) | payload size (u64) | SHA-256 of the payload (32 B) | payload
// Reading checks each in turn. A missing file is a miss; a file whose key differs (the mesh,
// material or solver settings changed since) is stale; a short file or one whose payload does
// not hash to its stored digest (truncated, or edited by hand) is corrupt. Each of these is
// recomputed and rewritten (through AtomicFile: a reader never sees half a file), and the
// report says which, with a message naming the file. A stale or corrupt file is never used.
//
// Threads: none shared; the files are the only shared state (AtomicFile's rename is atomic).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/core/expected.h"
#include "common/geometry/mesh.h"
#include "common/tissue/fem.h"
#include "common/tissue/reduced.h"
#include "common/tissue/twist_table.h"

namespace vsurg::tissue {

enum class CacheOutcome { kHit, kMiss, kStale, kCorrupt, kUnwritable };
const char* CacheOutcomeName(CacheOutcome o);

struct CacheReport {
  CacheOutcome outcome = CacheOutcome::kMiss;
  std::string path;
  std::string message;   // why a file was not used (stale, corrupt) or not written
  double compute_s = 0;  // the precomputation's time on a miss (s), 0 on a hit
  double load_s = 0;     // reading and checking the file (s)
};

struct TwistFieldInputs {
  geometry::TetMesh mesh;
  FemParams material;
  std::vector<int> fixed;
  std::vector<int> face;
  std::vector<double> face_area;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::vector<Eigen::Vector3d> display;
};

// What a table of responses over a display surface is computed from (contact tables and
// surface twist tables alike): the FEM, its support, the display and the vertices a tool reaches.
template <class Params>
struct TableInputs {
  geometry::TetMesh mesh;
  FemParams material;
  std::vector<int> fixed;
  geometry::TriMesh display;
  std::vector<int> reachable;
  Params params;
};
using ContactInputs = TableInputs<ContactResponseParams>;
using SurfaceTwistInputs = TableInputs<SurfaceTwistParams>;

// Where the files go by default: $VSURG_CACHE_DIR, else $XDG_CACHE_HOME/vsurg, else
// $HOME/.cache/vsurg, else <temp>/vsurg-cache.
std::string DefaultCacheDirectory();

// The key (SHA-256, hex) of a contact table's inputs: what its file carries, and what lets the
// sessions of one scene share one table in memory.
std::string ContactKey(const ContactInputs& in);
std::string SurfaceTwistKey(const SurfaceTwistInputs& in);

class ReducedCache {
 public:
  explicit ReducedCache(std::string dir) : dir_(std::move(dir)) {}
  // `name`: the scene model's file name stem (letters, digits, '-', '_', '.'; else refused).
  Expected<TwistField> TwistFieldFor(const std::string& name, const TwistFieldInputs& in,
                                     CacheReport* report = nullptr) const;
  // The hyperelastic twist's load levels (twist_table.h).
  Expected<TwistTable> TwistTableFor(const std::string& name, const TwistTableInputs& in,
                                     CacheReport* report = nullptr) const;
  Expected<ContactResponse> ContactResponseFor(const std::string& name, const ContactInputs& in,
                                               CacheReport* report = nullptr) const;
  Expected<SurfaceTwistTable> SurfaceTwistFor(const std::string& name, const SurfaceTwistInputs& in,
                                              CacheReport* report = nullptr) const;
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

}  // namespace vsurg::tissue
