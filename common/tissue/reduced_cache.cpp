#include "common/tissue/reduced_cache.h"

#include <openssl/sha.h>
#include <sys/mman.h>

#include <array>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <type_traits>

#include "common/core/file.h"

namespace vsurg::tissue {
namespace {

using Vec3 = Eigen::Vector3d;
using Digest = std::array<unsigned char, SHA256_DIGEST_LENGTH>;
using Clock = std::chrono::steady_clock;
constexpr char kMagic[8] = {'V', 'S', 'U', 'R', 'G', 'R', 'M', '1'};
constexpr int kHeader = 8 + 32 + 8 + 32;

// A large buffer about to be filled for the first time: huge pages asked for before its first
// touch. On this machine kind every 4 KiB page's first touch is a fault into the hypervisor, and
// the faults were half of loading the sphere's 61 MB contact table (0.3 of 0.6 s); the kernel
// gives huge pages only where asked (transparent_hugepage "madvise", Debian's default).
void AdviseHugePages(const void* data, size_t bytes) {
  constexpr uintptr_t kHuge = uintptr_t{2} << 20;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

Digest Sha256(const std::string& bytes) {
  Digest d;
  SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), d.data());
  return d;
}

// A byte stream in a fixed (little-endian host) order: the key's input and the payload.
class Writer {
 public:
  template <class T>
  void Put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void Put(const Vec3& v) {
    for (int k = 0; k < 3; ++k) Put(v[k]);
  }
  template <class T>
  void PutVector(const std::vector<T>& v) {
    Put(static_cast<uint64_t>(v.size()));
    for (const T& x : v) Put(x);
  }
  void PutString(const std::string& s) {
    Put(static_cast<uint64_t>(s.size()));
    out_ += s;
  }
  const std::string& bytes() const { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& s) : s_(s) {}
  template <class T>
  bool Get(T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (s_.size() - at_ < sizeof v) return false;
    std::memcpy(&v, s_.data() + at_, sizeof v);
    at_ += sizeof v;
    return true;
  }
  bool Get(Vec3& v) { return Get(v[0]) && Get(v[1]) && Get(v[2]); }
  template <class T>
  bool GetVector(std::vector<T>& v, uint64_t expected_size) {
    uint64_t n = 0;
    if (!Get(n) || n != expected_size || n > (s_.size() - at_)) return false;
    if constexpr (std::is_arithmetic_v<T>) {  // one copy: the tables are millions of numbers
      if (n > (s_.size() - at_) / sizeof(T)) return false;
      std::vector<T>().swap(v);
      v.reserve(n);
      AdviseHugePages(v.data(), n * sizeof(T));
      v.resize(n);
      if (n > 0) std::memcpy(v.data(), s_.data() + at_, n * sizeof(T));
      at_ += n * sizeof(T);
      return true;
    }
    v.resize(n);
    for (T& x : v)
      if (!Get(x)) return false;
    return true;
  }
  bool AtEnd() const { return at_ == s_.size(); }

 private:
  const std::string& s_;
  size_t at_ = 0;
};

void PutCommon(Writer& w, const char* kind, const geometry::TetMesh& mesh, const FemParams& p,
               const std::vector<int>& fixed) {
  w.PutString("vsurg reduced model, format 1");
  w.PutString(kind);
  w.PutVector(mesh.positions);
  w.Put(static_cast<uint64_t>(mesh.tetrahedra.size()));
  for (const auto& t : mesh.tetrahedra) w.Put(t);
  // Material and the solver settings that shape a static response (the dynamic ones do not).
  w.Put(p.young);
  w.Put(p.poisson);
  w.Put(p.density);
  w.Put(static_cast<uint8_t>(p.corotational));
  w.PutVector(fixed);
  // A heterogeneous tissue's per-element moduli (a homogeneous one's key as it always was).
  if (!p.element_stiffness_scale.empty()) {
    w.PutString("element stiffness scale");
    w.PutVector(p.element_stiffness_scale);
  }
  if (p.nodal_volume) w.PutString("volume at the vertices");  // other keys as they always were
}

bool ValidName(const std::string& name) {
  if (name.empty() || name.size() > 128 || name[0] == '.') return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
      return false;
  return true;
}

// Reads DIR/NAME.vrm and returns its payload when its key is `key` and it is whole; otherwise
// the report says why (miss, stale, corrupt).
bool ReadPayload(const std::string& path, const Digest& key, std::string& payload, CacheReport& r) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    r.outcome = CacheOutcome::kMiss;
    return false;
  }
  // The header, then the payload in one read of the size the header gives (a byte-wise read of
  // the sphere's 61 MB table through istreambuf_iterator took 0.5 s of its session's creation).
  std::error_code ec;
  const uint64_t file_size = std::filesystem::file_size(path, ec);
  char header[kHeader];
  if (ec || file_size < kHeader || !in.read(header, kHeader) ||
      std::memcmp(header, kMagic, 8) != 0) {
    r.outcome = CacheOutcome::kCorrupt;
    r.message = path + ": not a vsurg reduced-model file (or cut short in its header); rebuilding";
    return false;
  }
  if (std::memcmp(header + 8, key.data(), 32) != 0) {
    r.outcome = CacheOutcome::kStale;
    r.message = path + ": made for another mesh, material or setting; rebuilding";
    return false;
  }
  uint64_t size = 0;
  std::memcpy(&size, header + 40, 8);
  if (size != file_size - kHeader) {
    r.outcome = CacheOutcome::kCorrupt;
    r.message = path + ": truncated (" + std::to_string(file_size - kHeader) + " of " +
                std::to_string(size) + " payload bytes); rebuilding";
    return false;
  }
  payload.clear();
  payload.shrink_to_fit();
  payload.reserve(size);
  AdviseHugePages(payload.data(), size);
  payload.resize(size);
  if (!in.read(payload.data(), static_cast<std::streamsize>(size))) {
    r.outcome = CacheOutcome::kCorrupt;
    r.message = path + ": cut short while read; rebuilding";
    return false;
  }
  const Digest d = Sha256(payload);
  if (std::memcmp(header + 48, d.data(), 32) != 0) {
    r.outcome = CacheOutcome::kCorrupt;
    r.message = path + ": its contents do not match their checksum (damaged or edited); rebuilding";
    return false;
  }
  return true;
}

void WriteFile(const std::string& dir, const std::string& path, const Digest& key,
               const std::string& payload, CacheReport& r) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  auto file = AtomicFile::Open(path, "cache");
  if (!file.ok()) {
    r.outcome = CacheOutcome::kUnwritable;
    r.message += (r.message.empty() ? "" : "; ") + file.error().message + " (not cached)";
    return;
  }
  std::string header(kMagic, 8);
  header.append(reinterpret_cast<const char*>(key.data()), 32);
  const uint64_t size = payload.size();
  header.append(reinterpret_cast<const char*>(&size), 8);
  const Digest d = Sha256(payload);
  header.append(reinterpret_cast<const char*>(d.data()), 32);
  const bool ok = file->Write(header) && file->Write(payload);
  const Status s =
      ok ? file->Commit() : Status(Error{ErrorCode::kIoError, "write failed", "cache"});
  if (!s.ok()) {
    r.outcome = CacheOutcome::kUnwritable;
    r.message +=
        (r.message.empty() ? "" : "; ") + path + ": " + s.error().message + " (not cached)";
  }
}

template <class T, class Decode, class Compute, class Encode>
Expected<T> Cached(const std::string& dir, const std::string& name, const std::string& key_bytes,
                   CacheReport* report, Decode decode, Compute compute, Encode encode) {
  CacheReport local;
  CacheReport& r = report ? *report : local;
  r = CacheReport{};
  if (!ValidName(name))
    return InvalidArgument(
        "name", "a cache name is letters, digits, '-', '_' and '.'; got \"" + name + "\"");
  r.path = (std::filesystem::path(dir) / (name + ".vrm")).string();
  const Digest key = Sha256(key_bytes);
  const auto t0 = Clock::now();
  std::string payload;
  if (ReadPayload(r.path, key, payload, r)) {
    T value;
    if (decode(payload, value)) {
      r.outcome = CacheOutcome::kHit;
      r.load_s = std::chrono::duration<double>(Clock::now() - t0).count();
      return value;
    }
    r.outcome = CacheOutcome::kCorrupt;
    r.message = r.path + ": its contents do not describe this model; rebuilding";
  }
  r.load_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const auto t1 = Clock::now();
  Expected<T> value = compute();
  r.compute_s = std::chrono::duration<double>(Clock::now() - t1).count();
  if (!value.ok()) return value;
  WriteFile(dir, r.path, key, encode(*value), r);
  return value;
}

// The key of a table's inputs, up to its own parameters.
template <class Params>
Writer TableKey(const char* kind, const TableInputs<Params>& in) {
  Writer key;
  PutCommon(key, kind, in.mesh, in.material, in.fixed);
  key.PutVector(in.display.positions);
  key.Put(static_cast<uint64_t>(in.display.triangles.size()));
  for (const auto& t : in.display.triangles) key.Put(t);
  key.PutVector(in.reachable);
  return key;
}

std::string ContactKeyBytes(const ContactInputs& in) {
  Writer key = TableKey("contact table", in);
  key.Put(in.params.footprint_radius);
  key.Put(static_cast<uint8_t>(in.params.rotation));
  return key.bytes();
}

std::string SurfaceTwistKeyBytes(const SurfaceTwistInputs& in) {
  Writer key = TableKey("surface twist table", in);
  key.Put(in.params.jaw_radius);
  return key.bytes();
}

std::string Hex(const std::string& bytes) {
  const Digest d = Sha256(bytes);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (unsigned char c : d) out += kHex[c >> 4], out += kHex[c & 15];
  return out;
}

// The part a contact table and a surface twist table share: the display's vertex count, the
// tool's radius (footprint or jaws), the largest embedding distance and the slots (which display
// vertex each precomputed slot is, each vertex's slot, which vertices have their own).
struct SlotsView {
  int& vertices;
  double& radius;
  double& max_distance;
  std::vector<int>& slots;
  std::vector<int>& slot_of_vertex;
  std::vector<uint8_t>& precomputed;
};

template <class Table>
void PutSlots(Writer& w, const Table& t, double radius, const std::vector<int>& slots) {
  w.Put(static_cast<int32_t>(t.vertices));
  w.Put(radius);
  w.Put(t.max_distance);
  w.Put(static_cast<uint64_t>(slots.size()));
  w.PutVector(slots);
  w.PutVector(t.slot_of_vertex);
  w.PutVector(t.precomputed);
}

// Reads them for a display of `nv` vertices; `count` gets the number of slots.
bool GetSlots(Reader& r, uint64_t nv, const SlotsView& s, uint64_t& count) {
  int32_t vertices = 0;
  if (!r.Get(vertices) || static_cast<uint64_t>(vertices) != nv || !r.Get(s.radius) ||
      !r.Get(s.max_distance) || !r.Get(count) || count > nv)
    return false;
  s.vertices = vertices;
  return r.GetVector(s.slots, count) && r.GetVector(s.slot_of_vertex, nv) &&
         r.GetVector(s.precomputed, nv);
}

SlotsView Slots(ContactResponse& c) {
  return {c.vertices, c.footprint_radius, c.max_distance,
          c.contacts, c.slot_of_vertex,   c.precomputed};
}
SlotsView Slots(SurfaceTwistTable& t) {
  return {t.vertices, t.jaw_radius, t.max_distance, t.grasps, t.slot_of_vertex, t.precomputed};
}

}  // namespace

std::string DefaultCacheDirectory() {
  for (const char* var : {"VSURG_CACHE_DIR", "XDG_CACHE_HOME", "HOME"}) {
    const char* v = std::getenv(var);
    if (!v || !*v) continue;
    const std::string s(v);
    if (std::string(var) == "VSURG_CACHE_DIR") return s;
    if (std::string(var) == "XDG_CACHE_HOME") return (std::filesystem::path(s) / "vsurg").string();
    return (std::filesystem::path(s) / ".cache" / "vsurg").string();
  }
  std::error_code ec;
  return (std::filesystem::temp_directory_path(ec) / "vsurg-cache").string();
}

std::string ContactKey(const ContactInputs& in) {
  return Hex(ContactKeyBytes(in));
}

std::string SurfaceTwistKey(const SurfaceTwistInputs& in) {
  return Hex(SurfaceTwistKeyBytes(in));
}

const char* CacheOutcomeName(CacheOutcome o) {
  switch (o) {
    case CacheOutcome::kHit:
      return "hit";
    case CacheOutcome::kMiss:
      return "miss";
    case CacheOutcome::kStale:
      return "stale";
    case CacheOutcome::kCorrupt:
      return "corrupt";
    case CacheOutcome::kUnwritable:
      return "unwritable";
  }
  return "?";
}

Expected<TwistField> ReducedCache::TwistFieldFor(const std::string& name,
                                                 const TwistFieldInputs& in,
                                                 CacheReport* report) const {
  Writer key;
  PutCommon(key, "twist field", in.mesh, in.material, in.fixed);
  key.PutVector(in.face);
  key.PutVector(in.face_area);
  key.Put(in.origin);
  key.Put(in.axis);
  key.PutVector(in.display);
  const uint64_t n = in.display.size();
  auto decode = [&](const std::string& payload, TwistField& f) {
    Reader r(payload);
    return r.Get(f.origin) && r.Get(f.axis) && r.Get(f.grasp_compliance) && r.Get(f.max_distance) &&
           r.GetVector(f.angle, n) && r.GetVector(f.warp, n) && r.GetVector(f.radial, n) &&
           r.GetVector(f.lateral, n) && r.AtEnd();
  };
  auto compute = [&]() -> Expected<TwistField> {
    auto fem = FemStaticResponse::Create(in.mesh, in.material, in.fixed);
    if (!fem.ok()) return fem.error();
    return PrecomputeTwistField(*fem, in.face, in.face_area, in.origin, in.axis, in.display);
  };
  auto encode = [](const TwistField& f) {
    Writer w;
    w.Put(f.origin);
    w.Put(f.axis);
    w.Put(f.grasp_compliance);
    w.Put(f.max_distance);
    w.PutVector(f.angle);
    w.PutVector(f.warp);
    w.PutVector(f.radial);
    w.PutVector(f.lateral);
    return w.bytes();
  };
  return Cached<TwistField>(dir_, name, key.bytes(), report, decode, compute, encode);
}

Expected<TwistTable> ReducedCache::TwistTableFor(const std::string& name,
                                                 const TwistTableInputs& in,
                                                 CacheReport* report) const {
  Writer key;
  FemParams material;  // the common part's material fields, then the hyperelastic law's own
  material.young = in.material.young;
  material.poisson = in.material.poisson;
  material.nodal_volume = in.material.nodal_volume;
  PutCommon(key, "hyperelastic twist table", in.mesh, material, in.fixed);
  key.Put(in.material.stiffening);
  key.PutVector(in.face);
  key.Put(in.origin);
  key.Put(in.axis);
  key.PutVector(in.display);
  key.Put(in.max_twist);
  key.Put(static_cast<int64_t>(in.levels));
  const uint64_t n = in.display.size();
  auto decode = [&](const std::string& payload, TwistTable& t) {
    Reader r(payload);
    uint64_t levels = 0;
    if (!(r.Get(t.origin) && r.Get(t.axis) && r.Get(t.max_distance) && r.Get(levels) &&
          levels >= 2 && levels <= 65))
      return false;
    t.vertices = static_cast<int>(n);
    return r.GetVector(t.twist, levels) && r.GetVector(t.torque, levels) &&
           r.GetVector(t.axial, levels) && r.GetVector(t.angle, levels * n) &&
           r.GetVector(t.warp, levels * n) && r.GetVector(t.radial, levels * n) &&
           r.GetVector(t.lateral, levels * n) && r.AtEnd() && ValidateTwistTable(t, n).ok();
  };
  auto compute = [&]() { return PrecomputeTwistTable(in); };
  auto encode = [](const TwistTable& t) {
    Writer w;
    w.Put(t.origin);
    w.Put(t.axis);
    w.Put(t.max_distance);
    w.Put(static_cast<uint64_t>(t.twist.size()));
    for (const auto* v : {&t.twist, &t.torque, &t.axial}) w.PutVector(*v);
    for (const auto* v : {&t.angle, &t.warp, &t.radial}) w.PutVector(*v);
    w.PutVector(t.lateral);
    return w.bytes();
  };
  return Cached<TwistTable>(dir_, name, key.bytes(), report, decode, compute, encode);
}

Expected<ContactResponse> ReducedCache::ContactResponseFor(const std::string& name,
                                                           const ContactInputs& in,
                                                           CacheReport* report) const {
  const uint64_t nv = in.display.positions.size();
  auto decode = [&](const std::string& payload, ContactResponse& c) {
    Reader r(payload);
    uint64_t contacts = 0;
    uint8_t rotation = 0;
    return GetSlots(r, nv, Slots(c), contacts) && r.GetVector(c.g, contacts * 9 * nv) &&
           r.Get(rotation) && rotation == static_cast<uint8_t>(in.params.rotation) &&
           r.GetVector(c.w, rotation ? contacts * 9 * nv : 0) && r.AtEnd();
  };
  auto compute = [&]() -> Expected<ContactResponse> {
    auto fem = FemStaticResponse::Create(in.mesh, in.material, in.fixed);
    if (!fem.ok()) return fem.error();
    return PrecomputeContactResponse(*fem, in.display, in.reachable, in.params);
  };
  auto encode = [](const ContactResponse& c) {
    Writer w;
    PutSlots(w, c, c.footprint_radius, c.contacts);
    w.PutVector(c.g);
    w.Put(static_cast<uint8_t>(!c.w.empty()));
    w.PutVector(c.w);
    return w.bytes();
  };
  return Cached<ContactResponse>(dir_, name, ContactKeyBytes(in), report, decode, compute, encode);
}

Expected<SurfaceTwistTable> ReducedCache::SurfaceTwistFor(const std::string& name,
                                                          const SurfaceTwistInputs& in,
                                                          CacheReport* report) const {
  const uint64_t nv = in.display.positions.size();
  auto decode = [&](const std::string& payload, SurfaceTwistTable& t) {
    Reader r(payload);
    uint64_t grasps = 0;
    return GetSlots(r, nv, Slots(t), grasps) && r.GetVector(t.angle, grasps * nv) &&
           r.GetVector(t.warp, grasps * nv) && r.GetVector(t.radial, grasps * nv) &&
           r.GetVector(t.axis, grasps) && r.GetVector(t.grasp_compliance, grasps) && r.AtEnd() &&
           ValidateSurfaceTwist(t, nv).ok();
  };
  auto compute = [&]() -> Expected<SurfaceTwistTable> {
    auto fem = FemStaticResponse::Create(in.mesh, in.material, in.fixed);
    if (!fem.ok()) return fem.error();
    return PrecomputeSurfaceTwist(*fem, in.display, in.reachable, in.params);
  };
  auto encode = [](const SurfaceTwistTable& t) {
    Writer w;
    PutSlots(w, t, t.jaw_radius, t.grasps);
    w.PutVector(t.angle);
    w.PutVector(t.warp);
    w.PutVector(t.radial);
    w.PutVector(t.axis);
    w.PutVector(t.grasp_compliance);
    return w.bytes();
  };
  return Cached<SurfaceTwistTable>(dir_, name, SurfaceTwistKeyBytes(in), report, decode, compute,
                                   encode);
}

}  // namespace vsurg::tissue
