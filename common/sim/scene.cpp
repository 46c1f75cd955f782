#include "common/sim/scene.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/geometry/mesh_import.h"
#include "common/sim/scene_reader.h"

namespace vsurg::sim {
namespace {

using scene_detail::json;
using scene_detail::Reader;
namespace fs = std::filesystem;

constexpr double kDeg = std::numbers::pi / 180.0;

// Per-vertex memory of a session by model (EstimatedSessionBytes), bytes. Measured 2026-11-22:
// resident memory after Simulation::Create and 3 s of a scripted trainee, over the vertex count;
// coil 1,024 B (arm, 6,182 vertices), 773 (65,538-vertex limb), 801 (16,386-vertex organ
// surface); mass-spring 4,623 (1,026), 3,326 (16,386); ring layer 2,052 (1,026), 690 (16,386).
// Small scenes carry fixed costs; the budget is about large ones: the asymptote with margin.
constexpr size_t kCoilBytesPerVertex = 1536;
constexpr size_t kMassSpringBytesPerVertex = 4096;
constexpr size_t kRingLayerBytesPerVertex = 1536;
// Reduced contact: the per-vertex costs of a ring-layer scene plus the table, 72 B per
// (contact, vertex) pair with every vertex a contact at worst (reduced.h: 36 B of displacement
// and 36 B of rotation responses).
constexpr size_t kReducedBytesPerVertex = 1536, kReducedBytesPerVertexPair = 72;

Status ParseMesh(const Reader& r, const std::string& scene_dir, MeshSpec& m) {
  VSURG_TRY(type, r.String("type"));
  if (type == "limb") {
    m.kind = MeshKind::kLimb;
    VSURG_TRY(preset, r.StringOr("preset", "forearm"));
    if (preset == "forearm") {
      m.limb = geometry::ForearmPreset();
    } else if (preset == "calf") {
      m.limb = geometry::CalfPreset();
    } else {
      return r.Bad("preset", "must be forearm or calf");
    }
    VSURG_TRY(length, r.NumberOr("length", m.limb.length, 0.01, 2.0));
    VSURG_TRY(r0, r.NumberOr("radius_proximal", m.limb.radius_proximal, 1e-3, 0.5));
    VSURG_TRY(r1, r.NumberOr("radius_distal", m.limb.radius_distal, 1e-3, 0.5));
    VSURG_TRY(segments, r.IntegerOr("segments", m.limb.segments_around, 3, 4096));
    VSURG_TRY(rings, r.IntegerOr("rings", m.limb.rings_along, 2, 8192));
    m.limb = {length, r0, r1, segments, rings};
  } else if (type == "sphere") {
    m.kind = MeshKind::kSphere;
    VSURG_TRY(radius, r.Number("radius", 1e-3, 1.0));
    VSURG_TRY(particles, r.Integer("particles", 6, 300000));
    m.radius = radius;
    m.particles = particles;
  } else if (type == "file" || type == "obj") {
    // A surface mesh file read by assimp (OBJ, STL, PLY, glTF, ...: geometry/mesh_import.h);
    // "obj" is the older spelling. Its units: the file does not say, the scene does.
    m.kind = MeshKind::kFile;
    VSURG_TRY(path, r.String("path"));
    m.path = fs::path(path).is_absolute() ? path : (fs::path(scene_dir) / path).string();
    VSURG_TRY(units, r.StringOr("units", "m"));
    auto scale = geometry::UnitScale(units);
    if (!scale.ok()) return r.Bad("units", scale.error().message);
    m.metres_per_unit = *scale;
  } else if (type == "block") {
    m.kind = MeshKind::kBlock;
    VSURG_TRY(size, r.NumbersOr("size", 3, 1e-3, 1.0));
    VSURG_TRY(cells, r.NumbersOr("cells", 3, 1, 64));
    if (size.empty()) return r.Missing("size");
    if (cells.empty()) return r.Missing("cells");
    for (int a = 0; a < 3; ++a) {
      if (cells[a] != std::floor(cells[a])) return r.Bad("cells", "must be whole numbers");
      m.block.size[a] = size[a];
      m.block.cells[a] = static_cast<int>(cells[a]);
    }
  } else if (type == "membrane") {
    m.kind = MeshKind::kMembrane;  // the patch is the scene's "cut" (scene_cut.cpp)
  } else {
    return r.Bad("type", "must be limb, sphere, file, block or membrane, got '" + type + "'");
  }
  return Status::Ok();
}

Status ParseCoil(const Reader& r, RegionSpec& g) {
  g.kind = ModelKind::kCoil;
  VSURG_TRY(mode, r.StringOr("mode", "limb"));
  if (mode != "limb" && mode != "surface") return r.Bad("mode", "must be limb or surface");
  g.coil_mode = mode == "limb" ? tissue::TwistMode::kLimb : tissue::TwistMode::kSurface;
  tissue::CoilSpringParams& c = g.coil;
  VSURG_TRY(core, r.Number("core_radius", 1e-6, 10));
  VSURG_TRY(thickness, r.Number("thickness", 1e-6, 10));
  VSURG_TRY(width, r.Number("width", 1e-6, 10));
  VSURG_TRY(coils, r.Integer("coils", 1, tissue::CoilSpringModel::kMaxCoils));
  VSURG_TRY(modulus, r.Number("modulus", 1e-3, 1e13));
  VSURG_TRY(max_force, r.Number("max_force", 1e-9, 1e6));
  VSURG_TRY(friction, r.NumberOr("friction", 1.25, 1e-3, 100));
  // Per-coil flexural rigidities E·I_i (N·m², one per coil; `vsurg-sim calibrate` prints
  // them): the per-ring fit that makes the paper's model a reduced model of Saint-Venant.
  VSURG_TRY(rigidity, r.NumbersOr("coil_rigidity", static_cast<size_t>(coils), 1e-12, 1e12));
  c = {core, thickness, width, coils, modulus, max_force, friction, std::move(rigidity)};
  if (auto m = tissue::CoilSpringModel::Create(c); !m.ok())
    return r.Bad(m.error().field.c_str(), m.error().message);
  return Status::Ok();
}

// How the region is held: none, its bottom, a limb's ends, a plane, or a mesh file's group.
Status ParseSupport(const Reader& r, RegionSpec& g) {
  if (r.Has("support") && r.raw()["support"].is_object()) {
    VSURG_TRY(sr, r.Object("support"));
    if (sr.Has("plane")) {
      VSURG_TRY(plane, sr.Object("plane"));
      VSURG_TRY(point, plane.NumbersOr("point", 3, -100, 100));
      VSURG_TRY(normal, plane.NumbersOr("normal", 3, -1e6, 1e6));
      if (point.size() != 3) return plane.Bad("point", "is required: [x, y, z] in metres");
      if (normal.size() != 3) return plane.Bad("normal", "is required: [x, y, z]");
      const geometry::Vec3 n(normal[0], normal[1], normal[2]);
      if (!(n.norm() > 1e-12)) return plane.Bad("normal", "must not be zero");
      g.support = Support::kPlane;
      g.support_point = geometry::Vec3(point[0], point[1], point[2]);
      g.support_normal = n.normalized();
    } else if (sr.Has("group")) {
      VSURG_TRY(group, sr.String("group"));
      g.support = Support::kGroup;
      g.support_group = group;
    } else {
      return r.Bad("support", "an object must be {\"plane\": {...}} or {\"group\": \"name\"}");
    }
  } else {
    VSURG_TRY(support, r.StringOr("support", "bottom"));
    if (support == "none") {
      g.support = Support::kNone;
    } else if (support == "bottom") {
      g.support = Support::kBottom;
    } else if (support == "ends") {
      g.support = Support::kEnds;
    } else {
      return r.Bad("support", "must be none, bottom, ends, {\"plane\": ...} or {\"group\": ...}");
    }
  }
  return Status::Ok();
}

Status ParseReduced(const Reader& r, RegionSpec& g) {
  g.kind = ModelKind::kReduced;
  VSURG_TRY(mode, r.StringOr("mode", "contact"));
  if (mode != "contact" && mode != "twist" && mode != "surface-twist")
    return r.Bad("mode", "must be contact, twist or surface-twist");
  g.reduced.mode = mode == "twist"           ? ReducedMode::kTwist
                   : mode == "surface-twist" ? ReducedMode::kSurfaceTwist
                                             : ReducedMode::kContact;
  VSURG_TRY(jaw, r.NumberOr("jaw_radius", 0.009, 1e-4, 0.1));
  g.reduced.jaw_radius = jaw;
  VSURG_TRY(cells, r.IntegerOr("fem_cells", 8, 2, 24));
  if (cells % 2 != 0) return r.Bad("fem_cells", "must be even");
  VSURG_TRY(rings, r.IntegerOr("fem_rings", 4, 1, 8));
  VSURG_TRY(fem_size, r.NumberOr("fem_size", 0.0, 0.0, 1.0));
  VSURG_TRY(footprint, r.NumberOr("footprint_radius", 0.005, 1e-4, 0.1));
  VSURG_TRY(max_force, r.NumberOr("max_force", 10.0, 1e-3, 1e3));
  VSURG_TRY(max_twist_deg, r.NumberOr("max_twist_deg", 90.0, 1.0, 180.0));
  VSURG_TRY(levels, r.IntegerOr("levels", 6, 1, 32));
  VSURG_TRY(rotation, r.OptionalBool("rotation"));
  if (rotation && g.reduced.mode != ReducedMode::kContact)
    return r.Bad("rotation", "is the contact table's correction (mode contact)");
  g.reduced.rotation = rotation.value_or(true);
  g.reduced.levels = levels;
  g.reduced.fem_cells = cells;
  g.reduced.fem_rings = rings;
  g.reduced.fem_size = fem_size;
  g.reduced.footprint_radius = footprint;
  g.reduced.max_force = max_force;
  g.reduced.max_twist = max_twist_deg * kDeg;
  return Status::Ok();
}

Status ParseMassSpring(const Reader& r, RegionSpec& g) {
  g.kind = ModelKind::kMassSpring;
  VSURG_TRY(integrator, r.StringOr("integrator", "implicit-euler"));
  auto parsed = tissue::ParseIntegrator(integrator);
  if (!parsed.ok()) return r.Bad("integrator", parsed.error().message);
  g.integrator = *parsed;
  tissue::MassSpringBuildParams& b = g.mass_spring;
  VSURG_TRY(ks, r.Number("structural_stiffness", 1e-9, 1e9));
  VSURG_TRY(kb, r.NumberOr("bending_stiffness", 0.0, 0, 1e9));
  VSURG_TRY(kv, r.NumberOr("volume_stiffness", ks, 1e-9, 1e9));
  VSURG_TRY(damping, r.NumberOr("damping", 0.05, 0, 1e6));
  VSURG_TRY(volume, r.StringOr("volume", "none"));
  if (volume != "none" && volume != "inner-layer")
    return r.Bad("volume", "must be none or inner-layer");
  VSURG_TRY(depth, r.NumberOr("layer_depth", 0.01, 1e-6, 1));
  b.structural_stiffness = ks;
  b.bending_stiffness = kb;
  b.volume_stiffness = kv;
  b.damping = damping;
  b.volume = volume == "inner-layer" ? tissue::VolumeMode::kInnerLayer : tissue::VolumeMode::kNone;
  b.layer_depth = depth;
  return Status::Ok();
}

Status ParseRingLayer(const Reader& r, RegionSpec& g) {
  g.kind = ModelKind::kRingLayer;
  tissue::RingLayerParams& q = g.ring;
  VSURG_TRY(spacing, r.Number("ring_spacing", 1e-5, 1));
  VSURG_TRY(rings, r.Integer("rings", 1, 10000));
  VSURG_TRY(kc, r.Number("chain_stiffness", 1e-9, 1e9));
  VSURG_TRY(cc, r.NumberOr("chain_damping", 0.05, 0, 1e6));
  VSURG_TRY(kt, r.NumberOr("tether_stiffness", 0.0, 0, 1e9));
  q = {spacing, rings, kc, cc, kt};
  return Status::Ok();
}

Status ParseModel(const Reader& r, RegionSpec& g) {
  VSURG_TRY(type, r.String("type"));
  if (type == "coil") return ParseCoil(r, g);
  if (type == "cut-membrane") {  // the patch, its frame and its step are the scene's "cut"
    g.kind = ModelKind::kCutMembrane;
    g.support = Support::kNone;
    return Status::Ok();
  }
  if (type != "mass-spring" && type != "ring-layer" && type != "reduced")
    return r.Bad("type", "must be coil, mass-spring, ring-layer, reduced or cut-membrane, got '" +
                             type + "'");
  VSURG_TRY(dt, r.NumberOr("dt", 1e-3, 1e-6, 0.1));
  g.dt = dt;
  if (Status st = ParseSupport(r, g); !st.ok()) return st;
  if (type == "reduced") return ParseReduced(r, g);
  if (type == "mass-spring") return ParseMassSpring(r, g);
  return ParseRingLayer(r, g);
}

// "tissue_curve": [[yield_m, force_n], ...] (`vsurg-sim contact-law`), strictly rising from (0, 0).
Status ParseTissueCurve(const Reader& r, haptics::TissueCurve& c) {
  if (!r.Has("tissue_curve")) return Status::Ok();
  const json& a = r.raw()["tissue_curve"];
  const auto pair = [](const json& p) {
    return p.is_array() && p.size() == 2 && p[0].is_number() && p[1].is_number();
  };
  if (!a.is_array() || a.empty() || a.size() > haptics::TissueCurve::kMaxPoints ||
      !std::all_of(a.begin(), a.end(), pair))
    return r.Bad("tissue_curve", "must be 1..16 pairs [yield_m, force_n]");
  for (size_t i = 0; i < a.size(); ++i)
    c.yield[i] = a[i][0].get<double>(), c.force[i] = a[i][1].get<double>();
  c.count = static_cast<int>(a.size());
  if (!c.Valid()) return r.Bad("tissue_curve", "must rise strictly in yield and force from (0, 0)");
  return Status::Ok();
}

Status ParseHaptics(const Reader& r, HapticsSpec& h) {
  VSURG_TRY(device, r.StringOr("device", "touch"));
  auto limits = haptics::DeviceLimitsByName(device);
  if (!limits.ok()) return r.Bad("device", limits.error().message);
  h.device = device;
  h.limits = *limits;
  VSURG_TRY(k, r.NumberOr("stiffness", 300.0, 0, 1e5));
  VSURG_TRY(d, r.NumberOr("damping", 1.0, 0, 1e3));
  VSURG_TRY(mu, r.NumberOr("friction", 0.0, 0, 10));
  VSURG_TRY(scale, r.NumberOr("force_scale", 1.0, 1e-6, 1e3));
  VSURG_TRY(hold, r.NumberOr("hold_stiffness", 200.0, 0, 1e5));
  VSURG_TRY(lever, r.NumberOr("min_lever_m", 0.005, 1e-4, 1.0));
  VSURG_TRY(lookahead, r.NumberOr("lookahead_m", 0.03, 0, 0.2));
  VSURG_TRY(contact_model, r.StringOr("contact_model", "viscoelastic"));
  VSURG_TRY(tissue_k, r.NumberOr("tissue_stiffness", 0.0, 0, 1e5));
  VSURG_TRY(tissue_b, r.NumberOr("tissue_damping", 0.0, 0, 1e3));
  VSURG_TRY(station_surface, r.OptionalBool("station_surface"));
  h.station_surface = station_surface;
  h.tissue_stiffness = tissue_k;
  h.tissue_damping = tissue_b;
  if (Status st = ParseTissueCurve(r, h.tissue_curve); !st.ok()) return st;
  if (contact_model == "viscoelastic")
    h.contact_model = HapticsSpec::ContactModel::kViscoelastic;
  else if (contact_model == "fitted")
    h.contact_model = HapticsSpec::ContactModel::kFitted;
  else if (contact_model == "proxy")
    h.contact_model = HapticsSpec::ContactModel::kProxy;
  else
    return r.Bad("contact_model",
                 "must be viscoelastic, fitted or proxy, got '" + contact_model + "'");
  h.min_lever = lever;
  h.lookahead = lookahead;
  h.proxy.stiffness = k;
  h.proxy.damping = d;
  h.proxy.friction = mu;
  h.force_scale = scale;
  h.hold_stiffness = hold;
  return Status::Ok();
}

Status ParseTask(const Reader& r, scoring::TaskSpec& t) {
  VSURG_TRY(type, r.String("type"));
  if (type == "twist") {
    t.kind = scoring::TaskKind::kTwist;
    VSURG_TRY(target, r.Number("target_deg", -720, 720));
    VSURG_TRY(tol, r.Number("tolerance_deg", 1e-3, 180));
    t.target = target * kDeg;
    t.tolerance = tol * kDeg;
  } else if (type == "press") {
    t.kind = scoring::TaskKind::kPress;
    VSURG_TRY(target, r.Number("target_depth_m", 0, 0.5));
    VSURG_TRY(tol, r.Number("tolerance_m", 1e-6, 0.5));
    t.target = target;
    t.tolerance = tol;
  } else if (type == "palpate") {
    t.kind = scoring::TaskKind::kPalpate;  // no target: the marks are scored (palpation.h)
    t.target = 0;
    t.tolerance = scoring::PalpationSpec{}.match_margin;
  } else if (type == "insert") {
    t.kind = scoring::TaskKind::kInsert;  // the target is the scene's (scoring/needle.h)
    VSURG_TRY(tol, r.NumberOr("tolerance_mm", 2, 0.1, 50));
    t.target = 0;
    t.tolerance = tol * 1e-3;
  } else if (type == "cut") {
    t.kind = scoring::TaskKind::kCut;  // the pattern and band are the scene's cut (ParseSceneTask)
  } else {
    return r.Bad("type", "must be twist, press, palpate, insert or cut, got '" + type + "'");
  }
  const bool palpate = t.kind == scoring::TaskKind::kPalpate ||
                       t.kind == scoring::TaskKind::kInsert ||
                       t.kind == scoring::TaskKind::kCut;  // none holds anything
  VSURG_TRY(hold, r.NumberOr("hold_s", palpate ? 0.0 : 2.0, 0, 600));
  VSURG_TRY(limit, r.NumberOr("force_limit_n", 3.0, 0, 1000));
  VSURG_TRY(time_limit, r.NumberOr("time_limit_s", 60.0, 1e-3, 86400));
  if (!(time_limit > hold)) return r.Bad("time_limit_s", "must exceed hold_s");
  VSURG_TRY(expert, r.NumberOr("expert_time_s", hold + 3.0, 1e-3, 86400));
  if (!(expert >= hold)) return r.Bad("expert_time_s", "must be at least hold_s");
  t.expert_time = expert;
  t.hold_s = hold;
  t.force_limit = limit;
  t.time_limit = time_limit;
  return Status::Ok();
}

}  // namespace

const char* ModelKindName(ModelKind kind) {
  switch (kind) {
    case ModelKind::kCoil:
      return "coil";
    case ModelKind::kMassSpring:
      return "mass-spring";
    case ModelKind::kRingLayer:
      return "ring-layer";
    case ModelKind::kReduced:
      return "reduced";
    case ModelKind::kCutMembrane:
      return "cut-membrane";
  }
  return "unknown";
}

// Per-vertex costs (the constants above): positions, the BVH and their triple buffers, visual
// frames, the model's own state (mass-spring: springs, inner layer, CG scratch; coil: centreline
// projections and the deformer).
size_t EstimatedSessionBytes(ModelKind model, size_t surface_vertices, bool reduced_contact) {
  size_t per_vertex = 0;
  switch (model) {
    case ModelKind::kCoil:
      per_vertex = kCoilBytesPerVertex;
      break;
    case ModelKind::kMassSpring:
    case ModelKind::kCutMembrane:
      per_vertex = kMassSpringBytesPerVertex;
      break;
    case ModelKind::kRingLayer:
      per_vertex = kRingLayerBytesPerVertex;
      break;
    case ModelKind::kReduced:
      per_vertex = kReducedBytesPerVertex +
                   (reduced_contact ? kReducedBytesPerVertexPair * surface_vertices : 0);
      break;
  }
  return surface_vertices * per_vertex;
}

Status CheckSessionMemory(ModelKind model, size_t surface_vertices, const std::string& field,
                          bool reduced_contact) {
  const size_t need = EstimatedSessionBytes(model, surface_vertices, reduced_contact);
  if (need <= kSessionMemoryBudgetBytes) return Status::Ok();
  char why[256];
  std::snprintf(why, sizeof why,
                "%s: %zu surface vertices with the %s model need about %.0f MiB per session, over "
                "the budget of %zu MiB: use a coarser mesh",
                field.c_str(), surface_vertices, ModelKindName(model),
                static_cast<double>(need) / (1 << 20), kSessionMemoryBudgetBytes >> 20);
  return Error{ErrorCode::kResourceExhausted, why, field};
}

namespace {
Expected<Scene> ParseSceneObject(const json& root, const std::string& source);
}  // namespace

Expected<Scene> ParseScene(const std::string& text, const std::string& source) {
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for a number beyond a double (1e400): found by fuzz_scene_json.
    return Error{ErrorCode::kParseError, source + ": not valid JSON: " + e.what(), "scene"};
  }
  if (!root.is_object())
    return Error{ErrorCode::kParseError, source + ": the scene must be a JSON object", "scene"};
  // Every field is type-checked by Reader with a message naming it; this catch is the net under
  // that rule, so a field read without a check is a clear error for its file, never a crash.
  try {
    return ParseSceneObject(root, source);
  } catch (const json::exception& e) {
    return Error{ErrorCode::kParseError, source + ": a field has the wrong type: " + e.what(),
                 "scene"};
  }
}

namespace {

// The tissue's material: shear modulus (Pa), Poisson's ratio, density (kg/m³).
Status ParseTissue(const Reader& r, Scene& s) {
  if (!r.Has("tissue")) return Status::Ok();
  VSURG_TRY(t, r.Object("tissue"));
  VSURG_TRY(g, t.NumberOr("shear_modulus", 12e3, 1, 1e10));
  VSURG_TRY(nu, t.NumberOr("poisson_ratio", 0.47, 0, 0.4999));
  VSURG_TRY(rho, t.NumberOr("density", 1050, 1, 1e5));
  s.shear_modulus = g, s.poisson_ratio = nu, s.density = rho;
  return Status::Ok();
}

// Stiff or soft inclusions in the tissue ("tissue.inclusions": [{"centre": [x, y, z] m,
// "radius": m, "contrast": E ratio}]): carried by the FEM a reduced model is built from, so only
// a reduced contact or surface-twist region has them. A sphere's centre must lie in the ball; a
// mesh file's is checked against its tetrahedra when the model is built.
// Where the tissue's volume constraint is integrated ("tissue.volume"): "element" (the default)
// or "vertices" (tissue::FemParams::nodal_volume: linear tetrahedra do not lock as ν → 0.5). Only
// a reduced model's tables are built so (their static responses); the FEM regions keep theirs.
Status ParseVolume(const Reader& r, Scene& s) {
  if (!r.Has("tissue") || !r.raw()["tissue"].contains("volume")) return Status::Ok();
  const Reader t(r.raw()["tissue"], "tissue");
  VSURG_TRY(volume, t.StringOr("volume", "element"));
  if (volume != "element" && volume != "vertices")
    return t.Bad("volume", "must be \"element\" or \"vertices\"");
  s.volume_at_vertices = volume == "vertices";
  if (s.volume_at_vertices && s.region.kind != ModelKind::kReduced)
    return t.Bad("volume", "\"vertices\" is for a reduced model's tables (their static responses)");
  return Status::Ok();
}

Status ParseInclusions(const Reader& r, Scene& s) {
  if (!r.Has("tissue") || !r.raw()["tissue"].contains("inclusions")) return Status::Ok();
  const Reader t(r.raw()["tissue"], "tissue");
  const json& list = t.raw()["inclusions"];
  if (!list.is_array() || list.size() > 16)
    return t.Bad("inclusions", "must be an array of at most 16 inclusions");
  if (!list.empty() &&
      (s.region.kind != ModelKind::kReduced || s.region.reduced.mode == ReducedMode::kTwist))
    return t.Bad("inclusions",
                 "only a reduced contact or surface-twist model carries inclusions (its FEM)");
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = "tissue.inclusions[" + std::to_string(i) + "]";
    if (!list[i].is_object()) return InvalidArgument(path, path + ": must be an object");
    const Reader c(list[i], path);
    VSURG_TRY(centre, c.NumbersOr("centre", 3, -100, 100));
    if (centre.empty()) return c.Missing("centre");
    VSURG_TRY(radius, c.Number("radius", 1e-4, 1.0));
    VSURG_TRY(contrast, c.Number("contrast", 1e-3, tissue::kMaxInclusionContrast));
    tissue::Inclusion inc{{centre[0], centre[1], centre[2]}, radius, contrast};
    if (Status st = tissue::ValidateInclusion(inc, path); !st.ok()) return st;
    if (s.mesh.kind == MeshKind::kSphere && inc.centre.norm() >= s.mesh.radius)
      return c.Bad("centre", "lies outside the tissue (the sphere's radius is " +
                                 std::to_string(s.mesh.radius) + " m)");
    const geometry::Vec3& size = s.mesh.block.size;
    if (s.mesh.kind == MeshKind::kBlock &&
        !(std::abs(inc.centre.x()) < size.x() / 2 && std::abs(inc.centre.y()) < size.y() / 2 &&
          inc.centre.z() > 0 && inc.centre.z() < size.z()))
      return c.Bad("centre", "lies outside the tissue (the block)");
    s.inclusions.push_back(inc);
  }
  return Status::Ok();
}

// A palpation's cases drawn at random, one per attempt ("task.cases": {"count": [min, max],
// "diameter_mm": [min, max], "depth_mm": [min, max], "contrast": [min, max], "gap_mm": g,
// "margin_mm": m (from the palpable surface's rim, sim::RimDistance)},
// every field optional, tissue::InclusionDraw's defaults otherwise). Only a palpation has them,
// and only a reduced contact model (its table is the drawn case's own FEM's).
Status ParseCases(const Reader& task, Scene& s) {
  if (!task.Has("cases")) return Status::Ok();
  if (s.task.kind != scoring::TaskKind::kPalpate)
    return task.Bad("cases", "only a palpation task draws cases");
  if (s.region.kind != ModelKind::kReduced || s.region.reduced.mode != ReducedMode::kContact)
    return task.Bad("cases", "a palpation's cases need a reduced contact model (its FEM)");
  if (!s.inclusions.empty())
    return task.Bad("cases", "a scene either declares its inclusions or draws them, not both");
  VSURG_TRY(c, task.Object("cases"));
  tissue::InclusionDraw d;
  const auto range = [&](const char* key, double scale, double& lo, double& hi) -> Status {
    VSURG_TRY(v, c.NumbersOr(key, 2, -1e6, 1e6));
    if (!v.empty()) lo = v[0] * scale, hi = v[1] * scale;
    return Status::Ok();
  };
  double count_lo = d.min_count, count_hi = d.max_count;
  for (Status st : {range("count", 1, count_lo, count_hi),
                    range("diameter_mm", 1e-3, d.min_diameter, d.max_diameter),
                    range("depth_mm", 1e-3, d.min_depth, d.max_depth),
                    range("contrast", 1, d.min_contrast, d.max_contrast)})
    if (!st.ok()) return st;
  if (count_lo != std::floor(count_lo) || count_hi != std::floor(count_hi) ||
      !(count_lo >= 0 && count_hi <= 16))
    return c.Bad("count", "must be two whole numbers in 0..16");
  d.min_count = static_cast<int>(count_lo);
  d.max_count = static_cast<int>(count_hi);
  VSURG_TRY(gap, c.NumberOr("gap_mm", d.min_gap * 1e3, 0, 1e3));
  d.min_gap = gap * 1e-3;
  VSURG_TRY(margin, c.NumberOr("margin_mm", s.case_margin * 1e3, 0, 1e3));
  s.case_margin = margin * 1e-3;
  if (Status st = tissue::ValidateInclusionDraw(d, "task.cases"); !st.ok()) return st;
  s.cases = d;
  return Status::Ok();
}

// The one deformable region and its model, and what the model asks of the mesh.
Status ParseRegion(const json& root, const Reader& r, Scene& s) {
  if (!root.contains("regions")) return r.Missing("regions");
  if (!root["regions"].is_array() || root["regions"].size() != 1)
    return r.Bad("regions", "must be an array with exactly one deformable region");
  const Reader region(root["regions"][0], "regions[0]");
  VSURG_TRY(region_name, region.StringOr("name", "tissue"));
  s.region.name = region_name;
  VSURG_TRY(model, region.Object("model"));
  if (Status st = ParseModel(model, s.region); !st.ok()) return st;
  if (s.region.kind == ModelKind::kReduced) {
    const bool twist = s.region.reduced.mode == ReducedMode::kTwist;
    if (twist && s.mesh.kind != MeshKind::kLimb)
      return InvalidArgument("regions[0].model.mode",
                             "regions[0].model.mode: a reduced twist model needs a limb mesh");
    if (!twist && s.mesh.kind == MeshKind::kLimb)
      return InvalidArgument("regions[0].model.type",
                             "regions[0].model.type: a reduced contact or surface-twist "
                             "model needs a sphere, a block or a closed mesh file");
  }
  if (s.region.support == Support::kGroup && s.mesh.kind != MeshKind::kFile)
    return InvalidArgument("regions[0].model.support",
                           "regions[0].model.support.group: only a mesh file has named groups");
  if (s.region.kind != ModelKind::kCoil && s.mesh.kind == MeshKind::kLimb &&
      s.region.support == Support::kBottom) {
    s.region.support = Support::kEnds;  // a limb rests on its ends
  }
  // A file's size is known once it is read, a membrane's once its cut is (ParseCut).
  if (s.mesh.kind == MeshKind::kFile || s.mesh.kind == MeshKind::kMembrane) return Status::Ok();
  const auto& c = s.mesh.block.cells;  // a block's boundary: all its grid's nodes less the inside
  const size_t vertices =
      s.mesh.kind == MeshKind::kLimb
          ? static_cast<size_t>(s.mesh.limb.segments_around) * s.mesh.limb.rings_along + 2
      : s.mesh.kind == MeshKind::kBlock
          ? static_cast<size_t>((c[0] + 1) * (c[1] + 1) * (c[2] + 1) -
                                (c[0] - 1) * (c[1] - 1) * (c[2] - 1))
          : static_cast<size_t>(geometry::SphereVertexCount(
                geometry::SphereBase::kOctahedron,
                geometry::SphereLevelsForVertexCount(geometry::SphereBase::kOctahedron,
                                                     s.mesh.particles)));
  return CheckSessionMemory(s.region.kind, vertices, "mesh",
                            s.region.reduced.mode != ReducedMode::kTwist);
}

// The task, which must be one the region's model can do.
Status ParseSceneTask(const Reader& r, Scene& s) {
  VSURG_TRY(task, r.Object("task"));
  if (Status st = ParseTask(task, s.task); !st.ok()) return st;
  const bool twists =
      s.region.kind == ModelKind::kCoil ||
      (s.region.kind == ModelKind::kReduced && s.region.reduced.mode != ReducedMode::kContact);
  const bool insert = s.task.kind == scoring::TaskKind::kInsert;
  if (insert != (s.needle && s.needle->has_target))
    return InvalidArgument("task.type",
                           "task.type: an insert task needs a needle with a target, "
                           "and a needle scene's task is insert");
  const bool cut = s.task.kind == scoring::TaskKind::kCut;
  if (cut != s.cut.has_value())
    return InvalidArgument("task.type",
                           "task.type: a cut task needs the scene's cut, and a cut scene's task is "
                           "cut");
  if (cut) {  // the pattern is the target: its length (m); the band's half width the tolerance
    s.task.target = s.cut->pattern.Length();
    s.task.tolerance = s.cut->pattern.band;
  }
  if ((s.task.kind == scoring::TaskKind::kTwist) != twists)
    return InvalidArgument("task.type",
                           "task.type: a twist task needs a coil or reduced (surface-)twist model, "
                           "a press or palpation task a mass-spring, ring-layer or reduced contact "
                           "model");
  return ParseCases(task, s);
}

// How the station draws it: the material, the drawn surface's size, a finer surface file.
Status ParseVisual(const Reader& r, const std::string& dir, Scene& s) {
  s.visual.material =
      s.mesh.kind == MeshKind::kLimb ? VisualMaterial::kSkin : VisualMaterial::kOrgan;
  if (!r.Has("visual")) return Status::Ok();
  VSURG_TRY(v, r.Object("visual"));
  VSURG_TRY(material, v.StringOr("material", VisualMaterialName(s.visual.material)));
  bool known = false;
  for (VisualMaterial m : {VisualMaterial::kSkin, VisualMaterial::kOrgan, VisualMaterial::kKidney})
    if (material == VisualMaterialName(m)) s.visual.material = m, known = true;
  if (!known)
    return InvalidArgument("visual.material",
                           "visual.material: one of skin, organ, kidney; got '" + material + "'");
  VSURG_TRY(triangles, v.Integer("min_triangles", 1000, 500000, &s.visual.min_triangles));
  s.visual.min_triangles = triangles;
  if (v.Has("mesh")) {
    VSURG_TRY(path, v.String("mesh"));
    s.visual.mesh = fs::path(path).is_absolute() ? path : (fs::path(dir) / path).string();
    VSURG_TRY(units, v.StringOr("units", "m"));
    auto scale = geometry::UnitScale(units);
    if (!scale.ok()) return v.Bad("units", scale.error().message);
    s.visual.metres_per_unit = *scale;
  }
  return Status::Ok();
}

Status ParseBudget(const Reader& r, Scene& s) {
  VSURG_TRY(budget, r.Object("error_budget"));
  VSURG_TRY(rms, budget.Number("rms", 0, 10));
  s.error_budget_rms = rms;
  VSURG_TRY(reference, budget.StringOr("reference", "fem"));
  s.error_reference = reference;
  if (r.Has("cost")) {
    VSURG_TRY(cost, r.Object("cost"));
    VSURG_TRY(core, cost.Number("core_per_station", 1e-4, 64));
    s.core_per_station = core;
  }
  return Status::Ok();
}

Expected<Scene> ParseSceneObject(const json& root, const std::string& source) {
  auto with_source = [&](Error e) {
    e.message = source + ": " + e.message;
    return e;
  };
  const Reader r(root, "");
  Scene s;
  s.source = source;
  const std::string dir = fs::path(source).parent_path().string();
  auto name = r.String("name");
  if (!name.ok()) return with_source(name.error());
  s.name = *name;
  if (r.Has("description")) {
    if (!root["description"].is_string())
      return with_source(r.Bad("description", "must be a string"));
    s.description = root["description"].get<std::string>();
  }
  auto mesh = r.Object("mesh");
  if (!mesh.ok()) return with_source(mesh.error());
  if (Status st = ParseMesh(*mesh, dir, s.mesh); !st.ok()) return with_source(st.error());
  if (Status st = ParseTissue(r, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseRegion(root, r, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseInclusions(r, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseVolume(r, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseLaw(root, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseNeedle(root, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseCut(root, s); !st.ok()) return with_source(st.error());
  if (r.Has("haptics")) {
    auto h = r.Object("haptics");
    if (!h.ok()) return with_source(h.error());
    if (Status st = ParseHaptics(*h, s.haptics); !st.ok()) return with_source(st.error());
  }
  if (Status st = ParseSceneTask(r, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseVisual(r, dir, s); !st.ok()) return with_source(st.error());
  if (Status st = ParseBudget(r, s); !st.ok()) return with_source(st.error());
  return s;
}
}  // namespace

const char* VisualMaterialName(VisualMaterial m) {
  switch (m) {
    case VisualMaterial::kSkin:
      return "skin";
    case VisualMaterial::kOrgan:
      return "organ";
    case VisualMaterial::kKidney:
      return "kidney";
  }
  return "skin";
}

Expected<Scene> LoadScene(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{ErrorCode::kNotFound, path + ": cannot open the scene file", "scene"};
  std::stringstream text;
  text << in.rdbuf();
  return ParseScene(text.str(), path);
}

Expected<SceneMesh> BuildSceneMesh(const MeshSpec& spec) {
  SceneMesh out;
  switch (spec.kind) {
    case MeshKind::kLimb: {
      auto limb = geometry::MakeLimb(spec.limb);
      if (!limb.ok()) return limb.error();
      out.surface = std::move(limb->surface);
      out.centreline = std::move(limb->centreline);
      break;
    }
    case MeshKind::kSphere: {
      const int levels =
          geometry::SphereLevelsForVertexCount(geometry::SphereBase::kOctahedron, spec.particles);
      auto sphere =
          geometry::MakeSubdividedSphere({spec.radius, levels, geometry::SphereBase::kOctahedron});
      if (!sphere.ok()) return sphere.error();
      out.surface = std::move(*sphere);
      break;
    }
    case MeshKind::kBlock: {
      auto box = geometry::MakeTetBox(spec.block);
      if (!box.ok()) return box.error();
      out.surface = geometry::CompactBoundarySurface(*box);
      break;
    }
    case MeshKind::kMembrane: {
      auto patch = MembraneSurface(spec.membrane);
      if (!patch.ok()) return patch.error();
      out.surface = std::move(*patch);
      break;
    }
    case MeshKind::kFile: {
      geometry::ImportReport report;
      auto mesh = geometry::ImportSurfaceMesh(spec.path, spec.metres_per_unit, &report);
      if (!mesh.ok()) return mesh.error();
      out.surface = std::move(*mesh);
      out.groups = std::move(report.groups);
      break;
    }
  }
  return out;
}

std::vector<int> SupportedVertices(const geometry::TriMesh& mesh, Support support) {
  std::vector<int> fixed;
  if (mesh.positions.empty() || support == Support::kNone) return fixed;
  geometry::Vec3 lo = mesh.positions[0], hi = lo;
  for (const geometry::Vec3& p : mesh.positions) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double height = hi.z() - lo.z();
  for (int v = 0; v < mesh.VertexCount(); ++v) {
    const double z = mesh.positions[v].z();
    const bool held = support == Support::kBottom
                          ? z < lo.z() + 0.2 * height
                          : z < lo.z() + 0.01 * height || z > hi.z() - 0.01 * height;
    if (held) fixed.push_back(v);
  }
  return fixed;
}

Expected<std::vector<int>> SupportedVertices(
    const geometry::TriMesh& mesh, const RegionSpec& region,
    const std::map<std::string, std::vector<int>>& groups) {
  switch (region.support) {
    case Support::kPlane: {
      std::vector<int> fixed;
      for (int v = 0; v < mesh.VertexCount(); ++v)
        if ((mesh.positions[v] - region.support_point).dot(region.support_normal) <= 0)
          fixed.push_back(v);
      return fixed;
    }
    case Support::kGroup: {
      const auto it = groups.find(region.support_group);
      if (it == groups.end()) {
        std::string have;
        for (const auto& [name, vertices] : groups) have += (have.empty() ? "" : ", ") + name;
        return InvalidArgument("regions[0].model.support",
                               "regions[0].model.support.group: the mesh has no group '" +
                                   region.support_group +
                                   "' (it has: " + (have.empty() ? "none" : have) + ")");
      }
      for (int v : it->second)
        if (v < 0 || v >= mesh.VertexCount())
          return InvalidArgument("regions[0].model.support", "a group names a vertex off the mesh");
      return it->second;
    }
    default:
      return SupportedVertices(mesh, region.support);
  }
}

std::vector<int> SupportedFemVertices(const geometry::TetMesh& fem,
                                      const geometry::TriMesh& surface,
                                      const std::vector<int>& surface_held,
                                      const RegionSpec& region) {
  geometry::TriMesh points;
  points.positions = fem.positions;
  if (region.support != Support::kGroup) {
    auto held = SupportedVertices(points, region, {});
    return held.ok() ? *held : std::vector<int>{};
  }
  std::vector<uint8_t> is_held(surface.positions.size(), 0);
  for (int v : surface_held) is_held[v] = 1;
  const geometry::TriMesh boundary = geometry::BoundarySurface(fem);
  std::vector<uint8_t> on_boundary(fem.positions.size(), 0);
  for (const auto& t : boundary.triangles)
    for (int v : t) on_boundary[v] = 1;
  std::vector<int> fixed;
  for (int v = 0; v < fem.VertexCount(); ++v) {
    if (!on_boundary[v]) continue;
    int nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    for (int s = 0; s < surface.VertexCount(); ++s) {
      const double d = (surface.positions[s] - fem.positions[v]).squaredNorm();
      if (d < best) best = d, nearest = s;
    }
    if (is_held[nearest]) fixed.push_back(v);
  }
  return fixed;
}

std::string ScenesDirectory() {
  if (const char* env = std::getenv("VSURG_SCENES"); env && *env) return env;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (const fs::path& candidate : {exe.parent_path() / ".." / ".." / "scenes",
                                      exe.parent_path() / ".." / "share" / "vsurg" / "scenes"}) {
      if (fs::is_directory(candidate, ec)) return fs::weakly_canonical(candidate, ec).string();
    }
  }
#ifdef VSURG_SOURCE_SCENES_DIR
  return VSURG_SOURCE_SCENES_DIR;
#else
  return "scenes";
#endif
}

Expected<Scene> LoadSceneByName(const std::string& name) {
  if (name.size() > 5 && name.substr(name.size() - 5) == ".json") return LoadScene(name);
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_')) {
      return InvalidArgument("scene",
                             "scene name '" + name + "' may hold only letters, digits, - and _");
    }
  }
  const std::string path = ScenesDirectory() + "/" + name + ".json";
  if (!fs::exists(path)) {
    return Error{ErrorCode::kNotFound, "no scene '" + name + "' in " + ScenesDirectory(), "scene"};
  }
  return LoadScene(path);
}

}  // namespace vsurg::sim
