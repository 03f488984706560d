#include "proto/scene/import/obj_reader.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <tuple>
#include <utility>

#include <tiny_obj_loader.h>

#include "proto/scene/import/import_budget.h"
#include "proto/scene/import/messages.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm {
namespace {

using scene_limits::kMaxMagnitude;
// Ear clipping costs O(n^3) in the corners of a concave polygon; beyond this a concave
// face is fanned instead (it may then cover area outside its outline). Real models'
// concave faces have a handful of corners.
constexpr size_t kMaxEarClippedCorners = 256;

// What reading an OBJ holds at most per byte of its text (ImportBudget): the text twice more
// (the line check's copy, tinyobjloader's stream) and, for "v 0 0 0\n" (8 bytes), three
// doubles in tinyobjloader, three read exactly and the mesh's vertex, each in a vector that
// may have grown to twice its size (144 bytes); a face line costs less.
constexpr uint64_t kObjBytesPerTextByte = 20;
// The name under which the line check hands tinyobjloader every material library at once
// (see ObjLineCheck::Run).
const char* const kAllLibraries = "all-material-libraries";

[[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected) {
  FailInput(pointer, problem, expected);
}

std::string Quote(const std::string& text) { return QuoteInput(text); }

std::vector<std::string> Tokens(const std::string& line) {
  std::vector<std::string> tokens;
  const std::string spaces = " \t\r\v\f";
  size_t position = 0;
  while (true) {
    size_t begin = line.find_first_not_of(spaces, position);
    if (begin == std::string::npos) break;
    size_t end = line.find_first_of(spaces, begin);
    tokens.push_back(line.substr(begin, end == std::string::npos ? std::string::npos : end - begin));
    if (end == std::string::npos) break;
    position = end;
  }
  return tokens;
}

// --- the strict line check -------------------------------------------------------------

// Checks every statement the reader uses, keeps the exact values of v/vn/vt (tinyobjloader's
// number parser is not correctly rounded: its 0.123 is not strtod's), and writes the text
// tinyobjloader then reads: the same lines with comments and unused statements removed, so
// it sees only what was checked. tinyobjloader gives the structure (faces and their index
// triples, objects, groups, materials); v/vn/vt reach it as placeholders that only count
// elements for negative indices, as the values it would read are not used.
class ObjLineCheck {
  static constexpr const char* kPlaceholder[] = {"v 0 0 0", "vn 0 0 1", "vt 0 0"};

 public:
  explicit ObjLineCheck(const ObjReadOptions& options) : options_(options) {}

  std::string Run(const std::string& text) {
    std::string cleaned;
    cleaned.reserve(text.size());
    // One synthetic mtllib before line 1: tinyobjloader then knows every library's
    // materials at every usemtl, wherever the file's mtllib lines stand.
    if (options_.readMaterialLibrary) cleaned += std::string("mtllib ") + kAllLibraries + "\n";
    // Some Windows exporters start the file with a UTF-8 byte order mark.
    size_t begin = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
    while (begin < text.size()) {
      size_t end = text.find('\n', begin);
      if (end == std::string::npos) end = text.size();
      ++lineNumber_;
      cleaned += CheckLine(text.substr(begin, end - begin));
      cleaned += '\n';
      begin = end + 1;
    }
    return cleaned;
  }

  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  std::vector<std::array<double, 2>> uvs;
  std::vector<std::pair<std::string, size_t>> libraries;  // mtllib names with their lines
  std::vector<std::pair<std::string, size_t>> usedMaterials;  // usemtl names with their lines
  size_t faceCount = 0;
  bool everyCornerHasNormal = true;
  bool everyCornerHasUv = true;

 private:
  [[noreturn]] void FailAtLine(const std::string& problem, const std::string& expected) const {
    Fail(options_.pointer, options_.displayName + " line " + std::to_string(lineNumber_) + ": " + problem, expected);
  }

  std::string CheckLine(std::string line) {
    line = line.substr(0, line.find('#'));
    std::vector<std::string> tokens = Tokens(line);
    if (tokens.empty()) return "";
    const std::string& keyword = tokens[0];
    if (keyword == "v") return CheckVertex(tokens);
    if (keyword == "vn") return CheckNormal(tokens);
    if (keyword == "vt") return CheckUv(tokens);
    if (keyword == "f") return CheckFace(tokens);
    if (keyword == "g" || keyword == "o" || keyword == "s") return Join(tokens);
    if (keyword == "mtllib" || keyword == "usemtl") return CheckMaterialStatement(tokens);
    // Lines, points, parameter-space vertices, curves and surfaces do not make triangles.
    return "";
  }

  static std::string Join(const std::vector<std::string>& tokens) {
    std::string joined;
    for (const auto& token : tokens) joined += (joined.empty() ? "" : " ") + token;
    return joined;
  }

  double ParseNumber(const std::string& token) const {
    const char* begin = token.data();
    const char* end = token.data() + token.size();
    if (begin != end && *begin == '+') ++begin;
    double value = 0;
    auto [rest, error] = std::from_chars(begin, end, value);
    if (error != std::errc() || rest != end || !std::isfinite(value) || std::fabs(value) > kMaxMagnitude) {
      FailAtLine("bad coordinate " + Quote(token), "finite numbers of magnitude at most 1e30");
    }
    return value;
  }

  std::vector<double> ParseNumbers(const std::vector<std::string>& tokens) const {
    std::vector<double> numbers;
    for (size_t i = 1; i < tokens.size(); ++i) numbers.push_back(ParseNumber(tokens[i]));
    return numbers;
  }

  std::string CheckVertex(const std::vector<std::string>& tokens) {
    if (tokens.size() < 4) FailAtLine("a vertex with fewer than 3 coordinates", "\"v x y z\"");
    // Extra numbers (w, or the vertex colours some exporters add) do not move the vertex.
    std::vector<double> numbers = ParseNumbers(tokens);
    positions.push_back(Vec3{numbers[0], numbers[1], numbers[2]});
    if (positions.size() > static_cast<size_t>(std::numeric_limits<int>::max())) {
      FailAtLine("too many vertices", "at most 2^31 - 1 vertices");
    }
    return kPlaceholder[0];
  }

  std::string CheckNormal(const std::vector<std::string>& tokens) {
    if (tokens.size() != 4) FailAtLine("a normal without exactly 3 coordinates", "\"vn x y z\"");
    std::vector<double> numbers = ParseNumbers(tokens);
    normals.push_back(Vec3{numbers[0], numbers[1], numbers[2]});
    if (normals.size() > static_cast<size_t>(std::numeric_limits<int>::max())) {
      FailAtLine("too many normals", "at most 2^31 - 1 normals");
    }
    return kPlaceholder[1];
  }

  std::string CheckUv(const std::vector<std::string>& tokens) {
    if (tokens.size() < 2 || tokens.size() > 4) {
      FailAtLine("a texture coordinate with " + std::to_string(tokens.size() - 1) + " numbers", "\"vt u [v [w]]\"");
    }
    std::vector<double> numbers = ParseNumbers(tokens);
    numbers.resize(2, 0.0);  // v defaults to 0; w has no use without 3D textures
    uvs.push_back({numbers[0], numbers[1]});
    if (uvs.size() > static_cast<size_t>(std::numeric_limits<int>::max())) {
      FailAtLine("too many texture coordinates", "at most 2^31 - 1 texture coordinates");
    }
    return kPlaceholder[2];
  }

  // A 1-based index, or a negative one counting back from the latest element defined.
  bool ResolveIndex(const std::string& text, size_t count, long long& resolved) const {
    long long value = 0;
    auto [rest, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (text.empty() || error != std::errc() || rest != text.data() + text.size() || value == 0) return false;
    long long total = static_cast<long long>(count);
    resolved = value > 0 ? value - 1 : total + value;
    return resolved >= 0 && resolved < total;
  }

  // "i", "i/t", "i//n" or "i/t/n".
  void CheckReference(const std::string& token) {
    const std::string expected = "a vertex reference i, i/t, i//n or i/t/n with i a defined vertex";
    std::vector<std::string> parts;
    size_t begin = 0;
    while (true) {
      size_t slash = token.find('/', begin);
      parts.push_back(token.substr(begin, slash == std::string::npos ? std::string::npos : slash - begin));
      if (slash == std::string::npos) break;
      begin = slash + 1;
    }
    bool wellFormed = parts.size() <= 3 && !parts[0].empty() && !(parts.size() == 2 && parts[1].empty()) &&
                      !(parts.size() == 3 && parts[2].empty());
    if (!wellFormed) FailAtLine("bad vertex reference " + Quote(token), expected);
    long long resolved = 0;
    if (!ResolveIndex(parts[0], positions.size(), resolved)) {
      long long value = 0;
      auto [rest, error] = std::from_chars(parts[0].data(), parts[0].data() + parts[0].size(), value);
      if (error != std::errc() || rest != parts[0].data() + parts[0].size() || value == 0) {
        FailAtLine("bad vertex reference " + Quote(token), expected);
      }
      FailAtLine("vertex reference " + parts[0] + " does not name one of the " + std::to_string(positions.size()) +
                     " vertices defined so far",
                 expected);
    }
    bool hasUv = parts.size() >= 2 && !parts[1].empty();
    bool hasNormal = parts.size() == 3;
    if (hasUv && !ResolveIndex(parts[1], uvs.size(), resolved)) {
      FailAtLine("texture coordinate reference " + Quote(parts[1]) + " does not name one of the " +
                     std::to_string(uvs.size()) + " texture coordinates defined so far",
                 "a reference i/t or i/t/n with t a defined texture coordinate");
    }
    if (hasNormal && !ResolveIndex(parts[2], normals.size(), resolved)) {
      FailAtLine("normal reference " + Quote(parts[2]) + " does not name one of the " +
                     std::to_string(normals.size()) + " normals defined so far",
                 "a reference i//n or i/t/n with n a defined normal");
    }
    everyCornerHasUv = everyCornerHasUv && hasUv;
    everyCornerHasNormal = everyCornerHasNormal && hasNormal;
  }

  std::string CheckFace(const std::vector<std::string>& tokens) {
    if (tokens.size() < 4) {
      FailAtLine("a face with " + std::to_string(tokens.size() - 1) + " vertices", "a face of at least 3 vertices");
    }
    for (size_t i = 1; i < tokens.size(); ++i) CheckReference(tokens[i]);
    size_t triangles = tokens.size() - 3;
    if (triangles > options_.triangleBudget - triangleCount_) {
      FailAtLine("the scene exceeds " + std::to_string(options_.triangleLimit) + " triangles",
                 "at most " + std::to_string(options_.triangleLimit) + " triangles in the whole scene");
    }
    triangleCount_ += triangles;
    ++faceCount;
    return Join(tokens);
  }

  std::string CheckMaterialStatement(const std::vector<std::string>& tokens) {
    // Without a way to read libraries, materials are not this reader's business.
    if (!options_.readMaterialLibrary) return "";
    if (tokens.size() < 2) FailAtLine(tokens[0] + " without a name", "\"" + tokens[0] + " name\"");
    if (tokens[0] == "usemtl") {
      if (tokens.size() > 2) FailAtLine("usemtl with more than one name", "\"usemtl name\"");
      usedMaterials.emplace_back(tokens[1], lineNumber_);
      return Join(tokens);
    }
    for (size_t i = 1; i < tokens.size(); ++i) libraries.emplace_back(tokens[i], lineNumber_);
    return "";  // handed over through the synthetic first line
  }

  const ObjReadOptions& options_;
  size_t lineNumber_ = 0;
  size_t triangleCount_ = 0;
};

// --- materials -------------------------------------------------------------------------

// Hands tinyobjloader the materials of every library, read and checked beforehand.
class PreloadedMaterials : public tinyobj::MaterialReader {
 public:
  PreloadedMaterials(std::vector<tinyobj::material_t> materials, std::map<std::string, int> names)
      : materials_(std::move(materials)), names_(std::move(names)) {}

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* names, std::string* /*warn*/, std::string* /*err*/) override {
    if (name != kAllLibraries) return false;
    *materials = materials_;
    *names = names_;
    return true;
  }

 private:
  std::vector<tinyobj::material_t> materials_;
  std::map<std::string, int> names_;
};

Material ConvertMaterial(const tinyobj::material_t& source, const std::string& library,
                         const ObjReadOptions& options) {
  auto fail = [&](const std::string& problem, const std::string& expected) {
    Fail(options.pointer, options.displayName + ": material " + Quote(source.name) + " of " + library + ": " + problem,
         expected);
  };
  auto colour = [&](const double* rgb, const char* statement) {
    Vec3 value{rgb[0], rgb[1], rgb[2]};
    for (int axis = 0; axis < 3; ++axis) {
      if (!std::isfinite(value[axis]) || value[axis] < 0 || value[axis] > kMaxMagnitude) {
        fail(std::string(statement) + " is not a non-negative finite colour",
             std::string(statement) + " r g b with each component in [0, 1e30]");
      }
    }
    return value;
  };
  Phong phong;
  phong.diffuse = colour(source.diffuse, "Kd");
  phong.specular = colour(source.specular, "Ks");
  if (!std::isfinite(source.shininess) || source.shininess < 0 || source.shininess > kMaxMagnitude) {
    fail("Ns is not a non-negative finite exponent", "Ns in [0, 1e30]");
  }
  phong.shininess = source.shininess;
  if (!std::isfinite(source.dissolve)) fail("d (or Tr) is not finite", "d in [0, 1]");
  if (!std::isfinite(source.ior)) fail("Ni is not finite", "Ni in [1, 10]");
  // Exporters write d slightly outside [0, 1] and Ni 0 for "unset"; clamping keeps their
  // files usable, and the mapping is documented in proto/scene.md.
  phong.transparency = std::clamp(1.0 - source.dissolve, 0.0, 1.0);
  phong.indexOfRefraction = std::clamp(source.ior, scene_limits::kMinIndexOfRefraction, scene_limits::kMaxIndexOfRefraction);
  // illum 3 is "reflection on, ray traced": the mirror weight is the specular colour.
  if (source.illum == 3) {
    double strongest = std::max({phong.specular.x, phong.specular.y, phong.specular.z});
    phong.reflectivity = std::min(strongest, 1.0 - phong.transparency);
  }
  Material material;
  material.name = source.name;
  material.model = phong;
  return material;
}

struct Libraries {
  std::vector<tinyobj::material_t> raw;
  std::map<std::string, int> names;
  std::vector<Material> converted;
};

Libraries LoadLibraries(const ObjLineCheck& check, const ObjReadOptions& options) {
  Libraries libraries;
  std::set<std::string> loaded;
  for (const auto& [name, line] : check.libraries) {
    if (!loaded.insert(name).second) continue;
    std::istringstream text(options.readMaterialLibrary(name, line));
    size_t before = libraries.raw.size();
    std::string warnings, errors;
    // The first library to define a name wins, as in tinyobjloader's own mtllib handling.
    tinyobj::LoadMtl(&libraries.names, &libraries.raw, &text, &warnings, &errors);
    for (size_t i = before; i < libraries.raw.size(); ++i) {
      libraries.converted.push_back(ConvertMaterial(libraries.raw[i], name, options));
    }
  }
  for (const auto& [name, line] : check.usedMaterials) {
    if (libraries.names.count(name) == 0) {
      Fail(options.pointer,
           options.displayName + " line " + std::to_string(line) + ": usemtl " + Quote(name) +
               " names no material of the material libraries",
           "a material defined by newmtl in a library named by mtllib");
    }
  }
  return libraries;
}

// --- geometry ----------------------------------------------------------------------------

// Polygon corners projected onto the plane of their largest normal component, oriented so
// that the polygon winds counter-clockwise.
std::vector<std::array<double, 2>> ProjectPolygon(const std::vector<Vec3>& corners, const Vec3& normal) {
  int drop = 0;
  for (int axis = 1; axis < 3; ++axis) {
    if (std::fabs(normal[axis]) > std::fabs(normal[drop])) drop = axis;
  }
  int u = (drop + 1) % 3;
  int v = (drop + 2) % 3;
  double flip = normal[drop] < 0 ? -1.0 : 1.0;
  std::vector<std::array<double, 2>> points;
  for (const Vec3& corner : corners) points.push_back({corner[u], flip * corner[v]});
  return points;
}

double Cross2(const std::array<double, 2>& a, const std::array<double, 2>& b, const std::array<double, 2>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

std::vector<std::array<size_t, 3>> Fan(size_t count) {
  std::vector<std::array<size_t, 3>> triangles;
  for (size_t i = 1; i + 1 < count; ++i) triangles.push_back({0, i, i + 1});
  return triangles;
}

}  // namespace

std::vector<std::array<size_t, 3>> TriangulatePolygon(const std::vector<Vec3>& corners) {
  const size_t count = corners.size();
  if (count <= 3) return Fan(count);
  // Newell's normal: the polygon's orientation even when it is concave.
  Vec3 normal;
  for (size_t i = 0; i < count; ++i) {
    const Vec3& a = corners[i];
    const Vec3& b = corners[(i + 1) % count];
    normal.x += (a.y - b.y) * (a.z + b.z);
    normal.y += (a.z - b.z) * (a.x + b.x);
    normal.z += (a.x - b.x) * (a.y + b.y);
  }
  if (normal == Vec3{}) return Fan(count);
  std::vector<std::array<double, 2>> points = ProjectPolygon(corners, normal);
  bool convex = true;
  for (size_t i = 0; i < count && convex; ++i) {
    convex = Cross2(points[i], points[(i + 1) % count], points[(i + 2) % count]) >= 0;
  }
  if (convex || count > kMaxEarClippedCorners) return Fan(count);

  std::vector<size_t> remaining(count);
  for (size_t i = 0; i < count; ++i) remaining[i] = i;
  std::vector<std::array<size_t, 3>> triangles;
  while (remaining.size() > 3) {
    bool clipped = false;
    // Trying corner 1 first makes the result a fan wherever the polygon allows one.
    for (size_t k = 1; k <= remaining.size() && !clipped; ++k) {
      size_t j = k % remaining.size();
      size_t previous = remaining[(j + remaining.size() - 1) % remaining.size()];
      size_t current = remaining[j];
      size_t next = remaining[(j + 1) % remaining.size()];
      const auto& a = points[previous];
      const auto& b = points[current];
      const auto& c = points[next];
      if (Cross2(a, b, c) <= 0) continue;  // reflex or flat: not an ear
      bool empty = true;
      for (size_t other : remaining) {
        if (other == previous || other == current || other == next) continue;
        const auto& p = points[other];
        if (Cross2(a, b, p) >= 0 && Cross2(b, c, p) >= 0 && Cross2(c, a, p) >= 0) {
          empty = false;
          break;
        }
      }
      if (!empty) continue;
      triangles.push_back({previous, current, next});
      remaining.erase(remaining.begin() + static_cast<std::ptrdiff_t>(j));
      clipped = true;
    }
    if (!clipped) break;  // self-intersecting: fan what is left
  }
  for (size_t i = 1; i + 1 < remaining.size(); ++i) {
    triangles.push_back({remaining[0], remaining[i], remaining[i + 1]});
  }
  return triangles;
}

ObjModel ReadObj(const std::string& text, const ObjReadOptions& options) {
  ChargeImportMemory(kObjBytesPerTextByte * text.size());
  ObjLineCheck check(options);
  std::string cleaned = check.Run(text);
  Libraries libraries;
  if (options.readMaterialLibrary) libraries = LoadLibraries(check, options);

  tinyobj::attrib_t attributes;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warnings, errors;
  std::istringstream stream(cleaned);
  PreloadedMaterials reader(libraries.raw, libraries.names);
  bool ok = tinyobj::LoadObj(&attributes, &shapes, &materials, &warnings, &errors, &stream,
                             options.readMaterialLibrary ? &reader : nullptr, /*triangulate=*/false,
                             /*default_vcols_fallback=*/false);
  // The line check has refused whatever tinyobjloader would; a disagreement is a bug here.
  if (!ok || !errors.empty() || attributes.vertices.size() != 3 * check.positions.size()) {
    throw std::logic_error("tinyobjloader refused " + options.displayName + " after the line check passed: " + errors);
  }

  ObjModel model;
  model.materials = std::move(libraries.converted);
  TriangleMesh& mesh = model.mesh;
  mesh.vertices = std::move(check.positions);
  const bool keepNormals = check.faceCount > 0 && check.everyCornerHasNormal;
  const bool keepUvs = check.faceCount > 0 && check.everyCornerHasUv;
  if (keepNormals) mesh.normals.assign(mesh.vertices.size(), Vec3{});
  if (keepUvs) mesh.uvs.assign(mesh.vertices.size(), {0.0, 0.0});

  // A position takes the normal/UV of its first use; a later use with others gets a copy.
  constexpr int kUnassigned = -2;
  std::vector<std::pair<int, int>> assigned(mesh.vertices.size(), {kUnassigned, kUnassigned});
  std::map<std::tuple<int, int, int>, uint32_t> copies;
  auto vertexOf = [&](const tinyobj::index_t& index) -> uint32_t {
    int v = index.vertex_index;
    int n = keepNormals ? index.normal_index : -1;
    int t = keepUvs ? index.texcoord_index : -1;
    if (v < 0 || static_cast<size_t>(v) >= assigned.size() ||
        (keepNormals && (n < 0 || static_cast<size_t>(n) >= check.normals.size())) ||
        (keepUvs && (t < 0 || static_cast<size_t>(t) >= check.uvs.size()))) {
      throw std::logic_error("tinyobjloader gave an index the line check did not see in " + options.displayName);
    }
    auto slot = static_cast<size_t>(v);
    if (assigned[slot].first == kUnassigned) {
      assigned[slot] = {n, t};
      if (keepNormals) mesh.normals[slot] = check.normals[static_cast<size_t>(n)];
      if (keepUvs) mesh.uvs[slot] = check.uvs[static_cast<size_t>(t)];
    }
    if (assigned[slot] == std::make_pair(n, t)) return static_cast<uint32_t>(slot);
    auto [found, inserted] = copies.try_emplace({v, n, t}, static_cast<uint32_t>(mesh.vertices.size()));
    if (inserted) {
      if (mesh.vertices.size() >= std::numeric_limits<uint32_t>::max()) {
        Fail(options.pointer, options.displayName + ": too many distinct vertex/normal/UV combinations",
             "at most 2^32 - 1 vertices");
      }
      mesh.vertices.push_back(mesh.vertices[slot]);
      if (keepNormals) mesh.normals.push_back(check.normals[static_cast<size_t>(n)]);
      if (keepUvs) mesh.uvs.push_back(check.uvs[static_cast<size_t>(t)]);
    }
    return found->second;
  };

  std::vector<uint32_t> faceVertices;
  std::vector<Vec3> facePositions;
  for (const tinyobj::shape_t& shape : shapes) {
    const tinyobj::mesh_t& source = shape.mesh;
    size_t offset = 0;
    for (size_t face = 0; face < source.num_face_vertices.size(); ++face) {
      size_t count = source.num_face_vertices[face];
      int material = face < source.material_ids.size() ? source.material_ids[face] : -1;
      if (material >= static_cast<int>(model.materials.size())) material = -1;
      // A part ends where the OBJ object/group or the material changes.
      bool newPart = face == 0 || model.parts.back().material != material;
      if (newPart) model.parts.push_back(ObjModel::Part{shape.name, material, mesh.triangles.size(), 0});
      faceVertices.clear();
      facePositions.clear();
      for (size_t corner = 0; corner < count; ++corner) {
        faceVertices.push_back(vertexOf(source.indices[offset + corner]));
        facePositions.push_back(mesh.vertices[faceVertices.back()]);
      }
      offset += count;
      for (const auto& triangle : TriangulatePolygon(facePositions)) {
        mesh.triangles.push_back({faceVertices[triangle[0]], faceVertices[triangle[1]], faceVertices[triangle[2]]});
        ++model.parts.back().triangleCount;
      }
    }
  }
  return model;
}

}  // namespace tcfarm
