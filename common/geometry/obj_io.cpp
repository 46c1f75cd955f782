#include "common/geometry/obj_io.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <istream>
#include <ostream>
#include <string_view>
#include <vector>

namespace vsurg::geometry {
namespace {

// Hard caps so a hostile or corrupt file cannot exhaust memory.
constexpr size_t kMaxLineLength = 1 << 16;
constexpr size_t kMaxVertices = 20'000'000;
constexpr size_t kMaxFaceCorners = 1024;

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

// Splits on spaces and tabs.
std::vector<std::string_view> Tokens(std::string_view s) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

bool ParseDouble(std::string_view s, double& out) {
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  return ec == std::errc() && ptr == end;
}

bool ParseInt(std::string_view s, long& out) {
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  return ec == std::errc() && ptr == end;
}

}  // namespace

Expected<TriMesh> ParseObj(std::istream& in, const std::string& source_name) {
  TriMesh mesh;
  std::string line;
  long line_no = 0;
  auto fail = [&](const std::string& why) {
    return Error{ErrorCode::kParseError, source_name + ":" + std::to_string(line_no) + ": " + why,
                 "obj"};
  };
  std::vector<int> corners;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.size() > kMaxLineLength) return fail("line longer than 65536 characters");
    std::string_view s = Trim(line);
    if (const size_t hash = s.find('#'); hash != std::string_view::npos)
      s = Trim(s.substr(0, hash));
    if (s.empty()) continue;
    const auto tok = Tokens(s);
    const std::string_view key = tok[0];
    if (key == "v") {
      if (tok.size() != 4 && tok.size() != 5) {
        return fail("vertex needs 3 coordinates (optionally w), got " +
                    std::to_string(tok.size() - 1));
      }
      double c[4] = {0, 0, 0, 1};
      for (size_t k = 1; k < tok.size(); ++k) {
        if (!ParseDouble(tok[k], c[k - 1])) {
          return fail("vertex coordinate '" + std::string(tok[k]) + "' is not a number");
        }
        if (!std::isfinite(c[k - 1])) return fail("vertex coordinate is not finite");
      }
      if (c[3] == 0) return fail("vertex weight w is zero");
      if (mesh.positions.size() >= kMaxVertices) return fail("more than 20 million vertices");
      mesh.positions.emplace_back(c[0] / c[3], c[1] / c[3], c[2] / c[3]);
    } else if (key == "f") {
      if (tok.size() < 4) return fail("face needs at least 3 vertices");
      if (tok.size() - 1 > kMaxFaceCorners) return fail("face has more than 1024 vertices");
      corners.clear();
      for (size_t k = 1; k < tok.size(); ++k) {
        const std::string_view ref = tok[k].substr(0, tok[k].find('/'));
        long idx = 0;
        if (ref.empty() || !ParseInt(ref, idx)) {
          return fail("face vertex '" + std::string(tok[k]) + "' is not an index");
        }
        const long n = static_cast<long>(mesh.positions.size());
        if (idx == 0) return fail("face index 0 is invalid (OBJ indices start at 1)");
        const long resolved = idx > 0 ? idx - 1 : n + idx;
        if (resolved < 0 || resolved >= n) {
          return fail("face index " + std::to_string(idx) + " is out of range (" +
                      std::to_string(n) + " vertices so far)");
        }
        corners.push_back(static_cast<int>(resolved));
      }
      for (size_t k = 0; k < corners.size(); ++k) {
        for (size_t q = k + 1; q < corners.size(); ++q) {
          if (corners[k] == corners[q])
            return fail("face repeats vertex " + std::to_string(corners[k] + 1));
        }
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        mesh.triangles.push_back({corners[0], corners[k], corners[k + 1]});
      }
    } else if (key == "vn" || key == "vt" || key == "vp" || key == "o" || key == "g" ||
               key == "s" || key == "usemtl" || key == "mtllib" || key == "l" || key == "p") {
      continue;  // attributes and grouping we do not use
    } else {
      return fail("unknown statement '" + std::string(key) + "'");
    }
  }
  if (in.bad()) return Error{ErrorCode::kIoError, source_name + ": read failed", "obj"};
  if (mesh.triangles.empty()) {
    return Error{ErrorCode::kParseError, source_name + ": no faces in the file", "obj"};
  }
  ComputeVertexNormals(mesh);
  return mesh;
}

Expected<TriMesh> ReadObj(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    return Error{ErrorCode::kIoError, path + ": cannot open: " + std::strerror(errno), "obj"};
  }
  return ParseObj(in, path);
}

void FormatObj(const TriMesh& mesh, std::ostream& out, const std::string& comment) {
  if (!comment.empty()) out << "# " << comment << "\n";
  char buf[128];
  for (const Vec3& p : mesh.positions) {
    std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", p.x(), p.y(), p.z());
    out << buf;
  }
  const bool normals = mesh.normals.size() == mesh.positions.size();
  if (normals) {
    for (const Vec3& n : mesh.normals) {
      std::snprintf(buf, sizeof buf, "vn %.6f %.6f %.6f\n", n.x(), n.y(), n.z());
      out << buf;
    }
  }
  for (const Triangle& t : mesh.triangles) {
    if (normals) {
      std::snprintf(buf, sizeof buf, "f %d//%d %d//%d %d//%d\n", t[0] + 1, t[0] + 1, t[1] + 1,
                    t[1] + 1, t[2] + 1, t[2] + 1);
    } else {
      std::snprintf(buf, sizeof buf, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    out << buf;
  }
}

Status WriteObj(const TriMesh& mesh, const std::string& path, const std::string& comment) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) {
      return Error{ErrorCode::kIoError, path + ": cannot write: " + std::strerror(errno), "out"};
    }
    FormatObj(mesh, out, comment);
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      return Error{ErrorCode::kIoError, path + ": write failed", "out"};
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    return Error{ErrorCode::kIoError, path + ": cannot rename into place: " + why, "out"};
  }
  return Status::Ok();
}

}  // namespace vsurg::geometry
