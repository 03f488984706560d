// A glTF 2.0 file (.gltf with external or data-URI buffers, or .glb) as a scene: its node
// hierarchy as shared parent motions, one mesh shape per (node, primitive), PBR materials
// mapped onto the Whitted model, its cameras and KHR_lights_punctual lights, and one
// animation's channels as keyframes. proto/scene.md documents the mapping.
//
// The file is read by tinygltf (Debian's libtinygltf: maintained, a header plus a library,
// it reads .gltf with external and data-URI buffers and .glb). It parses; everything the
// scene model relies on (ranges, finiteness, key order, the graph being a forest) is
// checked here, so that bad input is refused with the glTF pointer of the bad value.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <type_traits>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "wire/content_hash.h"
#include "scene/import/gltf_data_uris.h"
#include "scene/import/mesh_geometry.h"
#include "scene/import/importers.h"
#include "scene/import/messages.h"
#include "scene/import/scene_files.h"
#include "scene/scene_limits.h"

namespace tcfarm {
namespace {

using import::CrossProduct;
using import::HasArea;
using import::Norm;
using import::Sub;
// The scene format's limits, checked here so that a glTF file is refused with its own
// pointer rather than the pointer of the JSON it would become.
using scene_limits::kMaxFrameCount;
using scene_limits::kMaxJoints;
using scene_limits::kMaxMagnitude;
using scene_limits::kMaxMotionDepth;
using scene_limits::kMaxScale;
using scene_limits::kMaxTriangles;
using scene_limits::kMinScale;

constexpr double kPi = 3.14159265358979323846;
// The most elements one accessor may hold: the indices of the most triangles a scene may
// hold. Far below 2^31, so that no count can ask for more than a few GiB of values.
constexpr size_t kMaxAccessorCount = 3 * kMaxTriangles;
// The values all accessor reads together may produce (8 bytes each), per byte of the
// file's buffers, plus a fixed allowance: an accessor of bytes read once gives 8 per byte,
// and a short JSON naming one large accessor over and over must not multiply it.
constexpr uint64_t kValueBytesPerBufferByte = 16;
constexpr uint64_t kValueBytesAllowance = uint64_t{16} << 20;
// glTF's defaults for what a file leaves out.
constexpr int kDefaultWidth = 640, kDefaultHeight = 480;
// A matrix whose columns, once divided by their lengths, are further than this from
// orthonormal has shear (or a projective row) that translation, rotation and scale cannot
// express. Exporters write rotations to float precision, hence not tighter.
constexpr double kOrthonormalTolerance = 1e-5;
// A column shorter than this (relative to the longest) makes the matrix singular.
constexpr double kSingularRatio = 1e-12;
// Phong exponents the roughness mapping may give: 1 (broad) to 10000 (a mirror-like glint).
constexpr double kMinShininess = 1, kMaxShininess = 10000;
// The camera a file without one gets: as the OBJ importer's, from the front and above.
const Vec3 kViewFrom{0, 0.35, 1};
constexpr double kDefaultFovDegrees = 45;
constexpr double kFramingMargin = 1.1;
// With no light in the file, one white directional light over the camera's shoulder, as OBJ.
const Vec3 kDefaultLightDirection{-0.4, -1, -0.7};

// What this importer implements, for extensionsRequired; optional others are ignored.
const std::set<std::string> kSupportedExtensions = {"KHR_lights_punctual", "KHR_materials_transmission",
                                                    "KHR_materials_ior", "KHR_mesh_quantization"};

std::string Pointer(const std::string& collection, size_t index) {
  return "/" + collection + "/" + std::to_string(index);
}


std::string UrlDecode(const std::string& text) {
  std::string decoded;
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%' && i + 2 < text.size() && std::isxdigit(static_cast<unsigned char>(text[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(text[i + 2]))) {
      decoded += static_cast<char>(std::stoi(text.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      decoded += text[i];
    }
  }
  return decoded;
}

// tinygltf reads external files only through these, so that a file never reaches outside
// the scene's folder and data without a folder never reads any. They also hand over the
// file's data URIs, decoded beforehand (gltf_data_uris.h), under the names that replaced them.
struct FileAccess {
  std::optional<std::filesystem::path> folder;
  std::string prefix;  // folder as tinygltf joins it, with a trailing '/'
  std::vector<std::vector<unsigned char>>* embedded;
};

// tinygltf joins a uri to the folder, or to "." (or to nothing, without a folder).
std::optional<size_t> EmbeddedIndexOf(const FileAccess& access, std::string_view path) {
  for (std::string_view base : {std::string_view(access.prefix), std::string_view("./")}) {
    if (!base.empty() && path.substr(0, base.size()) == base) path.remove_prefix(base.size());
  }
  const std::optional<size_t> index = gltf::EmbeddedIndex(path);
  if (!index || *index >= access.embedded->size()) return std::nullopt;
  return index;
}

bool Inside(const FileAccess& access, const std::string& path, std::filesystem::path* resolved) {
  if (!access.folder || path.compare(0, access.prefix.size(), access.prefix) != 0) return false;
  try {
    *resolved = ResolveInsideFolder(*access.folder, path.substr(access.prefix.size()), "", "file");
  } catch (const SceneError&) {
    return false;
  }
  std::error_code error;
  return std::filesystem::is_regular_file(*resolved, error);
}

bool FileExistsInside(const std::string& path, void* user) {
  const FileAccess& access = *static_cast<FileAccess*>(user);
  std::filesystem::path resolved;
  return EmbeddedIndexOf(access, path) || Inside(access, path, &resolved);
}

std::string ExpandNothing(const std::string& path, void*) { return path; }

bool ReadFileInside(std::vector<unsigned char>* out, std::string* error, const std::string& path, void* user) {
  const FileAccess& access = *static_cast<FileAccess*>(user);
  if (const std::optional<size_t> index = EmbeddedIndexOf(access, path)) {
    out->swap((*access.embedded)[*index]);  // tinygltf swaps it on into the buffer or image: no copy
    return true;
  }
  std::filesystem::path resolved;
  if (!Inside(access, path, &resolved)) {
    if (error) *error = "not a readable file inside the scene folder";
    return false;
  }
  std::ifstream in(resolved, std::ios::binary);
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) {
    if (error) *error = "read error";
    return false;
  }
  return true;
}

bool WriteNothing(std::string* error, const std::string&, const std::vector<unsigned char>&, void*) {
  if (error) *error = "the importer writes no files";
  return false;
}

// tinygltf 2.7 hands an image stored in a bufferView to the image loader without checking
// that the view lies inside its buffer: a GLB whose view runs past the binary chunk would
// be read out of bounds. The model being loaded already holds its views and buffers.
std::string ImageViewOutsideBuffer(const tinygltf::Model& model, const tinygltf::Image& image, int imageIndex) {
  if (image.bufferView < 0) return "";  // a data: URI or a file, decoded into memory tinygltf owns
  const tinygltf::BufferView& view = model.bufferViews.at(static_cast<size_t>(image.bufferView));
  const tinygltf::Buffer& buffer = model.buffers.at(static_cast<size_t>(view.buffer));
  const size_t size = buffer.data.size();
  if (view.byteOffset <= size && view.byteLength <= size - view.byteOffset &&
      view.byteLength <= static_cast<size_t>(std::numeric_limits<int>::max())) {
    return "";
  }
  return "image " + std::to_string(imageIndex) + "'s bufferView " + std::to_string(image.bufferView) +
         " (bytes " + std::to_string(view.byteOffset) + " + " + std::to_string(view.byteLength) +
         ") runs past the end of buffer " + std::to_string(view.buffer) + " (" + std::to_string(size) + " bytes)";
}

// Images are kept as their file's bytes (PNG, JPEG): workers decode them when a scene is
// built, and the bytes' hash names the image wherever the scene travels.
bool KeepImageEncoded(tinygltf::Image* image, const int imageIndex, std::string* error, std::string*, int, int,
                      const unsigned char* bytes, int size, void* loadingModel) {
  const std::string outside =
      ImageViewOutsideBuffer(*static_cast<const tinygltf::Model*>(loadingModel), *image, imageIndex);
  if (!outside.empty() || size < 0) {
    if (error) *error += outside.empty() ? "image " + std::to_string(imageIndex) + " is too large" : outside;
    return false;
  }
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

// ---- the JSON's types ---------------------------------------------------------------------
// tinygltf passes over a property of the wrong type as if it were absent; a scene built
// from such a file would silently differ from the one its author meant. So the properties
// of glTF 2.0's schema are checked for their JSON type first, with their pointer.

enum class JsonKind { kAny, kObject, kArray, kString, kNumber, kIndex, kBool };

struct Field {
  const char* key;
  JsonKind kind;
  const char* schema = "";         // for objects, and arrays of objects: the object's schema
  JsonKind item = JsonKind::kAny;  // for arrays: the elements' kind
};

const std::map<std::string, std::vector<Field>>& Schemas() {
  using K = JsonKind;
  static const std::map<std::string, std::vector<Field>> schemas = {
      {"root",
       {{"asset", K::kObject, "asset"},
        {"scene", K::kIndex},
        {"scenes", K::kArray, "scene", K::kObject},
        {"nodes", K::kArray, "node", K::kObject},
        {"meshes", K::kArray, "mesh", K::kObject},
        {"accessors", K::kArray, "accessor", K::kObject},
        {"bufferViews", K::kArray, "bufferView", K::kObject},
        {"buffers", K::kArray, "buffer", K::kObject},
        {"materials", K::kArray, "material", K::kObject},
        {"textures", K::kArray, "texture", K::kObject},
        {"images", K::kArray, "image", K::kObject},
        {"samplers", K::kArray, "sampler", K::kObject},
        {"cameras", K::kArray, "camera", K::kObject},
        {"animations", K::kArray, "animation", K::kObject},
        {"skins", K::kArray, "skin", K::kObject},
        {"extensionsUsed", K::kArray, "", K::kString},
        {"extensionsRequired", K::kArray, "", K::kString}}},
      {"asset",
       {{"version", K::kString}, {"minVersion", K::kString}, {"generator", K::kString}, {"copyright", K::kString}}},
      {"scene", {{"nodes", K::kArray, "", K::kIndex}}},
      {"node",
       {{"camera", K::kIndex},
        {"children", K::kArray, "", K::kIndex},
        {"skin", K::kIndex},
        {"matrix", K::kArray, "", K::kNumber},
        {"mesh", K::kIndex},
        {"rotation", K::kArray, "", K::kNumber},
        {"scale", K::kArray, "", K::kNumber},
        {"translation", K::kArray, "", K::kNumber},
        {"weights", K::kArray, "", K::kNumber}}},
      {"mesh", {{"primitives", K::kArray, "primitive", K::kObject}, {"weights", K::kArray, "", K::kNumber}}},
      {"primitive",
       {{"attributes", K::kObject, "indices"},
        {"indices", K::kIndex},
        {"material", K::kIndex},
        {"mode", K::kIndex},
        {"targets", K::kArray, "indices", K::kObject}}},
      {"accessor",
       {{"bufferView", K::kIndex},
        {"byteOffset", K::kIndex},
        {"componentType", K::kIndex},
        {"normalized", K::kBool},
        {"count", K::kIndex},
        {"type", K::kString},
        {"max", K::kArray, "", K::kNumber},
        {"min", K::kArray, "", K::kNumber},
        {"sparse", K::kObject, "sparse"}}},
      {"sparse",
       {{"count", K::kIndex}, {"indices", K::kObject, "sparseIndices"}, {"values", K::kObject, "sparseValues"}}},
      {"sparseIndices", {{"bufferView", K::kIndex}, {"byteOffset", K::kIndex}, {"componentType", K::kIndex}}},
      {"sparseValues", {{"bufferView", K::kIndex}, {"byteOffset", K::kIndex}}},
      {"bufferView",
       {{"buffer", K::kIndex},
        {"byteOffset", K::kIndex},
        {"byteLength", K::kIndex},
        {"byteStride", K::kIndex},
        {"target", K::kIndex}}},
      {"buffer", {{"uri", K::kString}, {"byteLength", K::kIndex}}},
      {"material",
       {{"pbrMetallicRoughness", K::kObject, "pbr"},
        {"normalTexture", K::kObject, "textureInfo"},
        {"occlusionTexture", K::kObject, "textureInfo"},
        {"emissiveTexture", K::kObject, "textureInfo"},
        {"emissiveFactor", K::kArray, "", K::kNumber},
        {"alphaMode", K::kString},
        {"alphaCutoff", K::kNumber},
        {"doubleSided", K::kBool}}},
      {"pbr",
       {{"baseColorFactor", K::kArray, "", K::kNumber},
        {"baseColorTexture", K::kObject, "textureInfo"},
        {"metallicFactor", K::kNumber},
        {"roughnessFactor", K::kNumber},
        {"metallicRoughnessTexture", K::kObject, "textureInfo"}}},
      {"textureInfo", {{"index", K::kIndex}, {"texCoord", K::kIndex}, {"scale", K::kNumber}, {"strength", K::kNumber}}},
      {"texture", {{"sampler", K::kIndex}, {"source", K::kIndex}}},
      {"image", {{"uri", K::kString}, {"mimeType", K::kString}, {"bufferView", K::kIndex}}},
      {"sampler", {{"magFilter", K::kIndex}, {"minFilter", K::kIndex}, {"wrapS", K::kIndex}, {"wrapT", K::kIndex}}},
      {"camera",
       {{"type", K::kString},
        {"perspective", K::kObject, "perspective"},
        {"orthographic", K::kObject, "orthographic"}}},
      {"perspective", {{"aspectRatio", K::kNumber}, {"yfov", K::kNumber}, {"zfar", K::kNumber}, {"znear", K::kNumber}}},
      {"orthographic", {{"xmag", K::kNumber}, {"ymag", K::kNumber}, {"zfar", K::kNumber}, {"znear", K::kNumber}}},
      {"animation",
       {{"channels", K::kArray, "channel", K::kObject}, {"samplers", K::kArray, "animationSampler", K::kObject}}},
      {"channel", {{"sampler", K::kIndex}, {"target", K::kObject, "target"}}},
      {"target", {{"node", K::kIndex}, {"path", K::kString}}},
      {"animationSampler", {{"input", K::kIndex}, {"output", K::kIndex}, {"interpolation", K::kString}}},
      {"skin", {{"inverseBindMatrices", K::kIndex}, {"skeleton", K::kIndex}, {"joints", K::kArray, "", K::kIndex}}},
  };
  return schemas;
}

const char* KindName(JsonKind kind) {
  switch (kind) {
    case JsonKind::kObject:
      return "an object";
    case JsonKind::kArray:
      return "an array";
    case JsonKind::kString:
      return "a string";
    case JsonKind::kNumber:
      return "a number";
    case JsonKind::kIndex:
      return "a non-negative integer";
    case JsonKind::kBool:
      return "a boolean";
    case JsonKind::kAny:
      break;
  }
  return "any value";
}

bool IsKind(const nlohmann::json& value, JsonKind kind) {
  switch (kind) {
    case JsonKind::kObject:
      return value.is_object();
    case JsonKind::kArray:
      return value.is_array();
    case JsonKind::kString:
      return value.is_string();
    case JsonKind::kNumber:
      return value.is_number();
    case JsonKind::kIndex:
      return value.is_number_unsigned() || (value.is_number_integer() && value.get<int64_t>() >= 0) ||
             (value.is_number_float() && value.get<double>() >= 0 &&
              value.get<double>() == std::floor(value.get<double>()));
    case JsonKind::kBool:
      return value.is_boolean();
    case JsonKind::kAny:
      return true;
  }
  return true;
}

std::string EscapePointer(const std::string& key) {
  std::string escaped;
  for (char c : key) escaped += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
  return escaped;
}

// The first property of the wrong JSON type under `value` (an object of `schema`), as
// {pointer, expected}; empty when all are right.
std::pair<std::string, std::string> WrongType(const nlohmann::json& value, const std::string& schema,
                                              const std::string& pointer) {
  // Every object's extensions are objects of objects; extras may be anything.
  if (value.contains("extensions")) {
    const auto& extensions = value["extensions"];
    if (!extensions.is_object()) return {pointer + "/extensions", "an object"};
    for (const auto& [name, extension] : extensions.items()) {
      if (!extension.is_object()) return {pointer + "/extensions/" + EscapePointer(name), "an object"};
    }
  }
  if (value.contains("name") && !value["name"].is_string()) return {pointer + "/name", "a string"};
  if (schema == "indices") {  // attributes and morph targets: names of accessor indices
    for (const auto& [name, index] : value.items()) {
      if (!IsKind(index, JsonKind::kIndex)) return {pointer + "/" + EscapePointer(name), KindName(JsonKind::kIndex)};
    }
    return {};
  }
  auto fields = Schemas().find(schema);
  if (fields == Schemas().end()) return {};
  for (const Field& field : fields->second) {
    if (!value.contains(field.key)) continue;
    const auto& member = value[field.key];
    const std::string at = pointer + "/" + field.key;
    if (!IsKind(member, field.kind)) return {at, KindName(field.kind)};
    if (field.kind == JsonKind::kObject && *field.schema) {
      auto wrong = WrongType(member, field.schema, at);
      if (!wrong.first.empty()) return wrong;
    }
    if (field.kind == JsonKind::kArray) {
      for (size_t i = 0; i < member.size(); ++i) {
        const std::string itemAt = at + "/" + std::to_string(i);
        if (!IsKind(member[i], field.item)) return {itemAt, KindName(field.item)};
        if (field.item == JsonKind::kObject) {
          auto wrong = WrongType(member[i], field.schema, itemAt);
          if (!wrong.first.empty()) return wrong;
        }
      }
    }
  }
  return {};
}

class GltfReader {
 public:
  GltfReader(const ImportInput& input) : input_(input), options_(input.options) {}

  Scene Read() {
    embedded_ = gltf::ExtractDataUris(CheckContainer(), input_.displayName);
    PreCheck(embedded_.json);
    Load();
    embedded_ = {};
    CheckExtensions();
    Scene scene;
    AddMaterials(scene);
    BuildGraph();
    ChooseAnimation();
    BuildMotions();
    AddShapes(scene);
    AddLights(scene);
    AddCamera(scene);
    scene.render.width = kDefaultWidth;
    scene.render.height = kDefaultHeight;
    scene.render.firstFrame = 0;
    scene.render.frameCount = frameCount_;
    return scene;
  }

 private:
  [[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected) const {
    FailInput(pointer, input_.displayName + ": " + problem, expected);
  }
  void Warn(const std::string& pointer, const std::string& text) const {
    std::fprintf(stderr, "warning: %s%s%s: %s\n", input_.displayName.c_str(), pointer.empty() ? "" : " at ",
                 pointer.c_str(), text.c_str());
  }

  bool IsBinary() const { return input_.bytes.compare(0, 4, "glTF") == 0; }

  // The GLB container (header, JSON chunk, optional BIN chunk), checked before tinygltf
  // reads it so that a truncated file is refused with the byte offset where it falls short.
  // Returns the JSON text.
  std::string_view CheckContainer() const {
    const std::string& bytes = input_.bytes;
    if (bytes.size() > std::numeric_limits<unsigned int>::max()) {
      Fail("", "the file holds " + std::to_string(bytes.size()) + " bytes", "a glTF file under 4 GiB");
    }
    if (!IsBinary()) return bytes;
    auto word = [&](size_t offset) {
      uint32_t value = 0;
      for (int i = 3; i >= 0; --i) value = value << 8 | static_cast<unsigned char>(bytes[offset + i]);
      return value;
    };
    const std::string glb = "a GLB file: a 12-byte header, a JSON chunk, an optional BIN chunk";
    if (bytes.size() < 20)
      Fail("", "GLB byte " + std::to_string(bytes.size()) + ": the file ends inside its header", glb);
    if (word(4) != 2) Fail("", "GLB byte 4: version " + std::to_string(word(4)), "GLB version 2");
    if (word(8) != bytes.size()) {
      Fail("",
           "GLB byte 8: the header gives a length of " + std::to_string(word(8)) + " bytes but the file holds " +
               std::to_string(bytes.size()) + (word(8) > bytes.size() ? " (truncated)" : ""),
           glb);
    }
    uint32_t jsonLength = word(12);
    if (word(16) != 0x4E4F534Au) Fail("", "GLB byte 16: the first chunk is not JSON", glb);
    if (20 + static_cast<uint64_t>(jsonLength) > bytes.size()) {
      Fail("", "GLB byte 12: a JSON chunk of " + std::to_string(jsonLength) + " bytes runs past the end of the file",
           glb);
    }
    size_t next = 20 + jsonLength;
    if (next + 8 <= bytes.size()) {
      uint32_t binLength = word(next);
      if (next + 8 + static_cast<uint64_t>(binLength) > bytes.size()) {
        Fail("",
             "GLB byte " + std::to_string(next) + ": a chunk of " + std::to_string(binLength) +
                 " bytes runs past the end of the file",
             glb);
      }
    } else if (next != bytes.size()) {
      Fail("", "GLB byte " + std::to_string(next) + ": the file ends inside a chunk header", glb);
    }
    return std::string_view(bytes).substr(20, jsonLength);
  }

  // What tinygltf reports without saying where: extensions this importer lacks, and
  // files that are missing. Syntax and type errors are left to tinygltf.
  void PreCheck(const std::string& jsonText) const {
    nlohmann::json document = nlohmann::json::parse(jsonText, nullptr, false);
    if (!document.is_object()) return;  // tinygltf says what is wrong with the syntax
    auto [pointer, expected] = WrongType(document, "root", "");
    if (!pointer.empty()) {
      Fail(pointer,
           std::string("a value of JSON type ") + document.at(nlohmann::json::json_pointer(pointer)).type_name(),
           expected);
    }
    if (document.contains("extensionsRequired") && document["extensionsRequired"].is_array()) {
      const auto& required = document["extensionsRequired"];
      for (size_t i = 0; i < required.size(); ++i) {
        if (required[i].is_string() && !kSupportedExtensions.count(required[i].get<std::string>())) {
          Fail("/extensionsRequired/" + std::to_string(i),
               "the file requires extension " + QuoteInput(required[i].get<std::string>()) +
                   ", which this importer does not implement",
               "only required extensions among KHR_lights_punctual, KHR_materials_transmission, "
               "KHR_materials_ior, KHR_mesh_quantization");
        }
      }
    }
    for (const char* collection : {"buffers", "images"}) {
      if (!document.contains(collection) || !document[collection].is_array()) continue;
      const auto& items = document[collection];
      for (size_t i = 0; i < items.size(); ++i) {
        if (!items[i].is_object() || !items[i].contains("uri") || !items[i]["uri"].is_string()) continue;
        std::string uri = items[i]["uri"].get<std::string>();
        std::string pointer = Pointer(collection, i) + "/uri";
        if (const std::optional<size_t> embedded = gltf::EmbeddedIndex(uri)) {
          CheckEmbeddedLength(items[i], embedded_.bytes[*embedded].size(), Pointer(collection, i));
          continue;
        }
        if (uri.compare(0, 5, "data:") == 0) continue;  // one the scan did not take out (gltf_data_uris.h): tinygltf decodes it
        std::string what = std::string(collection) == "buffers" ? "buffer file" : "image file";
        if (!input_.baseDirectory) {
          Fail(pointer, what + " " + QuoteInput(uri) + " cannot be read: the file was submitted without a folder",
               "a self-contained glTF (data URIs or GLB), or one imported from a folder holding its files");
        }
        std::filesystem::path path;
        try {
          path = ResolveInsideFolder(*input_.baseDirectory, UrlDecode(uri), pointer, what);
        } catch (const SceneError& error) {
          Fail(pointer, std::string(error.what()).substr(("scene" + pointer + ": ").size()),
               "a file inside the scene folder");
        }
        std::error_code error;
        if (!std::filesystem::is_regular_file(path, error)) {
          Fail(pointer, what + " " + QuoteInput(uri) + " is missing", "a readable file inside the scene folder");
        }
      }
    }
  }

  // tinygltf would report a buffer whose data URI decodes to another length than its
  // byteLength under the name that replaced the URI.
  void CheckEmbeddedLength(const nlohmann::json& item, size_t decoded, const std::string& pointer) const {
    if (!item.contains("byteLength") || !item["byteLength"].is_number()) return;  // not a buffer
    const nlohmann::json& length = item["byteLength"];
    if (!length.is_number_unsigned() || length.get<uint64_t>() != decoded) {
      Fail(pointer + "/byteLength", "a byteLength of " + length.dump() + " for a data URI of " +
                                        std::to_string(decoded) + " bytes",
           "the byteLength its data URI decodes to");
    }
  }

  // What tinygltf reads: the file with its data URIs replaced by their names. A GLB's
  // JSON chunk is rebuilt only when it held data URIs.
  std::string GlbWithJson(const std::string& json) const {
    const std::string& bytes = input_.bytes;
    uint32_t oldLength = 0;
    for (int i = 3; i >= 0; --i) oldLength = oldLength << 8 | static_cast<unsigned char>(bytes[12 + i]);
    std::string padded = json + std::string((4 - json.size() % 4) % 4, ' ');
    const std::string_view rest = std::string_view(bytes).substr(20 + oldLength);
    auto word = [](uint64_t value) {
      std::string out(4, '\0');
      for (int i = 0; i < 4; ++i) out[i] = static_cast<char>(value >> (8 * i));
      return out;
    };
    std::string glb = bytes.substr(0, 8) + word(20 + padded.size() + rest.size()) + word(padded.size()) + "JSON";
    glb.reserve(glb.size() + padded.size() + rest.size());
    glb += padded;
    glb.append(rest);
    return glb;
  }

  void Load() {
    tinygltf::TinyGLTF loader;
    FileAccess access{input_.baseDirectory, "", &embedded_.bytes};
    std::string base;
    if (input_.baseDirectory) {
      base = input_.baseDirectory->string();
      access.prefix = base + "/";
    }
    loader.SetFsCallbacks({&FileExistsInside, &ExpandNothing, &ReadFileInside, &WriteNothing, &access});
    loader.SetImageLoader(&KeepImageEncoded, &model_);
    std::string error, warning;
    bool loaded = false;
    if (IsBinary()) {
      const std::string rebuilt = embedded_.bytes.empty() ? "" : GlbWithJson(embedded_.json);
      const std::string& glb = embedded_.bytes.empty() ? input_.bytes : rebuilt;
      loaded = loader.LoadBinaryFromMemory(&model_, &error, &warning,
                                           reinterpret_cast<const unsigned char*>(glb.data()),
                                           static_cast<unsigned int>(glb.size()), base, tinygltf::REQUIRE_VERSION);
    } else {
      loaded = loader.LoadASCIIFromString(&model_, &error, &warning, embedded_.json.data(),
                                          static_cast<unsigned int>(embedded_.json.size()), base,
                                          tinygltf::REQUIRE_VERSION);
    }
    auto oneLine = [](std::string text) {
      while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
      std::replace(text.begin(), text.end(), '\n', ' ');
      return text;
    };
    if (!loaded) Fail("", "tinygltf cannot read it: " + oneLine(error), "a valid glTF 2.0 file");
    if (!warning.empty()) Warn("", "tinygltf: " + oneLine(warning));
  }

  void CheckExtensions() const {
    for (size_t i = 0; i < model_.extensionsRequired.size(); ++i) {
      if (!kSupportedExtensions.count(model_.extensionsRequired[i])) {
        Fail("/extensionsRequired/" + std::to_string(i),
             "the file requires extension " + QuoteInput(model_.extensionsRequired[i]) +
                 ", which this importer does not implement",
             "only required extensions this importer implements");
      }
    }
  }

  // ---- accessors ------------------------------------------------------------------------

  struct AccessorData {
    size_t count = 0;
    int components = 0;
    std::vector<double> values;  // count * components
    double At(size_t element, int component) const { return values[element * components + component]; }
  };

  // Where `count` elements of `elementSize` bytes start in a buffer, and how far apart.
  struct ViewElements {
    const unsigned char* base;
    size_t stride;
  };
  // A sparse accessor's substitutions: `count` indices of `indexType`, and as many values.
  struct SparseLayout {
    size_t count;
    int indexType;
    size_t indexSize;
    ViewElements indices, values;
  };
  // Where an accessor's elements lie: `elements` none when it has no buffer view (all zeros).
  struct AccessorLayout {
    std::optional<ViewElements> elements;
    std::optional<SparseLayout> sparse;
  };

  // An accessor's elements as doubles. `types` are the allowed TINYGLTF_TYPE_*; integer
  // components of a normalized accessor become [0, 1] (or [-1, 1]) as the spec says. A
  // sparse accessor's substitutions are applied over its buffer view's elements (or zeros).
  AccessorData ReadAccessor(int index, const std::string& referencedAt, const std::vector<int>& types,
                            const std::vector<int>& componentTypes, const std::string& expected) const {
    if (index < 0 || static_cast<size_t>(index) >= model_.accessors.size()) {
      Fail(referencedAt,
           "accessor " + std::to_string(index) + " does not exist (the file has " +
               std::to_string(model_.accessors.size()) + ")",
           "the index of an accessor");
    }
    const tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
    const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
    if (std::find(types.begin(), types.end(), accessor.type) == types.end() ||
        std::find(componentTypes.begin(), componentTypes.end(), accessor.componentType) == componentTypes.end()) {
      Fail(pointer,
           TypeName(accessor.type) + " of " + ComponentTypeName(accessor.componentType) + " where " + referencedAt +
               " refers to it",
           expected);
    }
    const int componentSize = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(accessor.componentType));
    const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(accessor.type));
    const size_t elementSize = static_cast<size_t>(componentSize) * static_cast<size_t>(components);
    // Everything the values depend on is checked before they are allocated: a few bytes
    // of JSON must not be able to ask for gigabytes.
    const AccessorLayout layout = CheckedLayout(accessor, pointer, elementSize);
    ChargeValues(accessor.count * static_cast<size_t>(components), pointer);
    AccessorData data;
    data.count = accessor.count;
    data.components = components;
    data.values.assign(accessor.count * static_cast<size_t>(components), 0.0);
    if (layout.elements) {
      for (size_t element = 0; element < accessor.count; ++element) {
        ReadElement(layout.elements->base + element * layout.elements->stride, accessor, componentSize,
                    &data.values[element * static_cast<size_t>(components)]);
      }
    }
    if (layout.sparse) ApplySparse(accessor, pointer, componentSize, *layout.sparse, data);
    return data;
  }

  void ChargeValues(uint64_t values, const std::string& pointer) const {
    const uint64_t budget = kValueBytesPerBufferByte * BufferBytes() + kValueBytesAllowance;
    valueBytesRead_ += values * sizeof(double);
    if (valueBytesRead_ > budget) {
      Fail(pointer, "reading it brings the values read from the file's accessors to " +
                        std::to_string(valueBytesRead_) + " bytes",
           "at most " + std::to_string(kValueBytesPerBufferByte) + " bytes of values per byte of the file's buffers (" +
               std::to_string(BufferBytes()) + ") + 16 MiB: accessors that are not read over and over");
    }
  }

  size_t BufferBytes() const {
    size_t bytes = 0;
    for (const tinygltf::Buffer& buffer : model_.buffers) bytes += buffer.data.size();
    return bytes;
  }

  // The one gate every read of an accessor passes before anything is allocated per
  // element: its count below the limit, its elements inside its buffer view and the view
  // inside its buffer (or, without a view, no more zeros than the file has buffer bytes),
  // and its sparse substitutions' views likewise. 64-bit arithmetic that cannot overflow.
  AccessorLayout CheckedLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                               size_t elementSize) const {
    if (accessor.count > kMaxAccessorCount) {
      Fail(pointer + "/count", std::to_string(accessor.count) + " elements",
           "at most " + std::to_string(kMaxAccessorCount) + " elements in one accessor");
    }
    AccessorLayout layout;
    if (accessor.bufferView >= 0) {
      layout.elements = InView(accessor.bufferView, accessor.byteOffset, accessor.count, elementSize, true, pointer);
    } else if (accessor.count * elementSize > BufferBytes()) {
      Fail(pointer + "/count",
           std::to_string(accessor.count) + " elements without a buffer view (" +
               std::to_string(accessor.count * elementSize) + " bytes of zeros)",
           "an accessor without a buffer view no larger than the file's buffers (" + std::to_string(BufferBytes()) +
               " bytes)");
    }
    if (accessor.sparse.isSparse) layout.sparse = CheckedSparseLayout(accessor, pointer, elementSize);
    return layout;
  }

  // Where `count` elements of `elementSize` bytes start in buffer view `viewIndex`, from
  // byteOffset, and how far apart they lie (the view's byteStride, when `strided`, else
  // packed): checked to lie inside the view and the view inside its buffer. `pointer` is
  // the object referring to the view (an accessor, or a sparse accessor's indices or values).
  ViewElements InView(int viewIndex, size_t byteOffset, size_t count, size_t elementSize, bool strided,
                      const std::string& pointer) const {
    if (viewIndex < 0 || static_cast<size_t>(viewIndex) >= model_.bufferViews.size()) {
      Fail(pointer + "/bufferView", "buffer view " + std::to_string(viewIndex) + " does not exist",
           "the index of a buffer view");
    }
    const tinygltf::BufferView& view = model_.bufferViews[static_cast<size_t>(viewIndex)];
    const std::string viewPointer = Pointer("bufferViews", static_cast<size_t>(viewIndex));
    if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model_.buffers.size()) {
      Fail(viewPointer + "/buffer", "buffer " + std::to_string(view.buffer) + " does not exist",
           "the index of a buffer");
    }
    const std::vector<unsigned char>& buffer = model_.buffers[static_cast<size_t>(view.buffer)].data;
    if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
      Fail(viewPointer,
           std::to_string(view.byteLength) + " bytes from byte " + std::to_string(view.byteOffset) +
               " of buffer " + std::to_string(view.buffer) + " (" + std::to_string(buffer.size()) + " bytes)",
           "a buffer view inside its buffer");
    }
    const size_t stride = strided && view.byteStride != 0 ? view.byteStride : elementSize;
    if (stride < elementSize) {
      Fail(viewPointer + "/byteStride",
           "a stride of " + std::to_string(stride) + " bytes for elements of " + std::to_string(elementSize),
           "a stride at least the element size");
    }
    // (count - 1) * stride + elementSize <= byteLength - byteOffset, divided so as not to overflow.
    if (count > 0 && (byteOffset > view.byteLength || elementSize > view.byteLength - byteOffset ||
                      (count - 1) > (view.byteLength - byteOffset - elementSize) / stride)) {
      Fail(pointer,
           std::to_string(count) + " elements from byte " + std::to_string(byteOffset) +
               " run past the end of buffer view " + std::to_string(viewIndex) + " (" +
               std::to_string(view.byteLength) + " bytes; elements of " + std::to_string(elementSize) +
               " bytes, " + std::to_string(stride) + " apart)",
           "an accessor inside its buffer view");
    }
    return {buffer.data() + view.byteOffset + byteOffset, stride};
  }

  static void ReadElement(const unsigned char* at, const tinygltf::Accessor& accessor, int componentSize,
                          double* out) {
    const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(accessor.type));
    for (int c = 0; c < components; ++c) {
      out[c] = Component(at + static_cast<size_t>(c) * static_cast<size_t>(componentSize), accessor.componentType,
                         accessor.normalized);
    }
  }

  // A sparse accessor's substitutions: `count` strictly increasing element indices, and as
  // many packed elements of the accessor's own type that replace those elements.
  SparseLayout CheckedSparseLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                                   size_t elementSize) const {
    const std::string at = pointer + "/sparse";
    const auto& sparse = accessor.sparse;
    if (sparse.count < 1 || static_cast<size_t>(sparse.count) > accessor.count) {
      Fail(at + "/count", std::to_string(sparse.count) + " substitutions in an accessor of " +
                              std::to_string(accessor.count) + " elements",
           "1 to the accessor's count");
    }
    const int indexType = sparse.indices.componentType;
    if (indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      Fail(at + "/indices/componentType", ComponentTypeName(indexType),
           "UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT indices");
    }
    const size_t count = static_cast<size_t>(sparse.count);
    const size_t indexSize = static_cast<size_t>(tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(indexType)));
    if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
      Fail(at + (sparse.indices.byteOffset < 0 ? "/indices" : "/values") + "/byteOffset", "a negative offset",
           "a byte offset >= 0");
    }
    return {count, indexType, indexSize,
            InView(sparse.indices.bufferView, static_cast<size_t>(sparse.indices.byteOffset), count, indexSize, false,
                   at + "/indices"),
            InView(sparse.values.bufferView, static_cast<size_t>(sparse.values.byteOffset), count, elementSize, false,
                   at + "/values")};
  }

  void ApplySparse(const tinygltf::Accessor& accessor, const std::string& pointer, int componentSize,
                   const SparseLayout& sparse, AccessorData& data) const {
    const std::string at = pointer + "/sparse";
    const size_t components = static_cast<size_t>(data.components);
    for (size_t k = 0; k < sparse.count; ++k) {
      const double index = Component(sparse.indices.base + k * sparse.indexSize, sparse.indexType, false);
      if (!(index < static_cast<double>(accessor.count))) {
        Fail(at + "/indices",
             "substitution " + std::to_string(k) + " names element " +
                 std::to_string(static_cast<uint64_t>(index)) + " of " + std::to_string(accessor.count),
             "indices below the accessor's count");
      }
      if (k > 0 && !(index > Component(sparse.indices.base + (k - 1) * sparse.indexSize, sparse.indexType, false))) {
        Fail(at + "/indices", "substitution " + std::to_string(k) + " names element " +
                                  std::to_string(static_cast<uint64_t>(index)) + ", not after the one before it",
             "strictly increasing indices");
      }
      ReadElement(sparse.values.base + k * sparse.values.stride, accessor, componentSize,
                  &data.values[static_cast<size_t>(index) * components]);
    }
  }

  static std::string TypeName(int type) {
    switch (type) {
      case TINYGLTF_TYPE_SCALAR:
        return "SCALAR";
      case TINYGLTF_TYPE_VEC2:
        return "VEC2";
      case TINYGLTF_TYPE_VEC3:
        return "VEC3";
      case TINYGLTF_TYPE_VEC4:
        return "VEC4";
      case TINYGLTF_TYPE_MAT2:
        return "MAT2";
      case TINYGLTF_TYPE_MAT3:
        return "MAT3";
      case TINYGLTF_TYPE_MAT4:
        return "MAT4";
      default:
        return "type " + std::to_string(type);
    }
  }

  static std::string ComponentTypeName(int componentType) {
    switch (componentType) {
      case TINYGLTF_COMPONENT_TYPE_BYTE:
        return "BYTE";
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return "UNSIGNED_BYTE";
      case TINYGLTF_COMPONENT_TYPE_SHORT:
        return "SHORT";
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        return "UNSIGNED_SHORT";
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        return "UNSIGNED_INT";
      case TINYGLTF_COMPONENT_TYPE_FLOAT:
        return "FLOAT";
      default:
        return "component type " + std::to_string(componentType);
    }
  }

  // One component of type T at `at` (glTF is little-endian, as every host this builds on),
  // as its value or, normalized, as glTF maps integers into [-1, 1] or [0, 1].
  template <typename T>
  static double Load(const unsigned char* at, bool normalized) {
    T v;
    std::memcpy(&v, at, sizeof v);
    if (!normalized || !std::is_integral_v<T>) return v;
    const double scaled = v / static_cast<double>(std::numeric_limits<T>::max());
    return std::is_signed_v<T> ? std::max(scaled, -1.0) : scaled;
  }

  static double Component(const unsigned char* at, int componentType, bool normalized) {
    switch (componentType) {
      case TINYGLTF_COMPONENT_TYPE_BYTE: return Load<int8_t>(at, normalized);
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return Load<uint8_t>(at, normalized);
      case TINYGLTF_COMPONENT_TYPE_SHORT: return Load<int16_t>(at, normalized);
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return Load<uint16_t>(at, normalized);
      // glTF never normalizes 32-bit integers or floats.
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return Load<uint32_t>(at, false);
      case TINYGLTF_COMPONENT_TYPE_FLOAT: return Load<float>(at, false);
      default: return 0;  // refused by the callers' componentTypes
    }
  }

  void CheckFinite(const AccessorData& data, int index, const std::string& what) const {
    for (size_t i = 0; i < data.values.size(); ++i) {
      double v = data.values[i];
      if (!(std::fabs(v) <= kMaxMagnitude)) {
        Fail(Pointer("accessors", static_cast<size_t>(index)),
             what + " " + std::to_string(i / static_cast<size_t>(data.components)) + " holds " +
                 (std::isnan(v)   ? std::string("NaN")
                  : std::isinf(v) ? std::string("an infinity")
                                  : std::to_string(v)),
             "finite values of magnitude at most 1e30");
      }
    }
  }

  // ---- materials ------------------------------------------------------------------------

  static double NumberIn(const tinygltf::ExtensionMap& extensions, const std::string& extension, const std::string& key,
                         double fallback) {
    auto found = extensions.find(extension);
    if (found == extensions.end() || !found->second.IsObject() || !found->second.Has(key)) return fallback;
    const tinygltf::Value& value = found->second.Get(key);
    return value.IsNumber() ? value.GetNumberAsDouble() : fallback;
  }

  // proto/scene.md, "glTF materials", gives the rule and its reasons.
  Material MapMaterial(const tinygltf::Material& source, size_t index) const {
    const std::string pointer = Pointer("materials", index);
    const auto& pbr = source.pbrMetallicRoughness;
    std::vector<double> base = pbr.baseColorFactor;
    if (base.size() != 4) base = {1, 1, 1, 1};
    double metallic = pbr.metallicFactor, roughness = pbr.roughnessFactor;
    for (double v : {base[0], base[1], base[2], base[3], metallic, roughness}) {
      if (!(v >= 0 && v <= 1)) {
        Fail(pointer + "/pbrMetallicRoughness", "a factor of " + std::to_string(v), "factors in [0, 1]");
      }
    }
    double transmission = NumberIn(source.extensions, "KHR_materials_transmission", "transmissionFactor", 0);
    double ior = NumberIn(source.extensions, "KHR_materials_ior", "ior", 1.5);
    if (!(transmission >= 0 && transmission <= 1)) {
      Fail(pointer + "/extensions/KHR_materials_transmission/transmissionFactor", std::to_string(transmission),
           "a factor in [0, 1]");
    }
    if (!std::isfinite(ior) || ior < 0)
      Fail(pointer + "/extensions/KHR_materials_ior/ior", std::to_string(ior), "an ior >= 1");
    Material material;
    material.reflectivity = metallic * (1 - roughness) * (1 - roughness);
    // Metals transmit nothing; what reflects is not also transmitted.
    material.transparency = std::min(transmission * (1 - metallic), 1 - material.reflectivity);
    for (int c = 0; c < 3; ++c) {
      double diffuse = base[static_cast<size_t>(c)] * (1 - metallic) * (1 - material.transparency);
      double specular = 0.04 + (base[static_cast<size_t>(c)] - 0.04) * metallic;
      (c == 0 ? material.diffuse.x : c == 1 ? material.diffuse.y : material.diffuse.z) = diffuse;
      (c == 0 ? material.specular.x : c == 1 ? material.specular.y : material.specular.z) = specular;
    }
    double r4 = roughness * roughness * roughness * roughness;
    material.shininess = r4 > 0 ? std::clamp(2 / r4 - 2, kMinShininess, kMaxShininess) : kMaxShininess;
    material.indexOfRefraction = std::clamp(ior, scene_limits::kMinIndexOfRefraction, scene_limits::kMaxIndexOfRefraction);
    if (pbr.baseColorTexture.index >= 0) {
      material.diffuseTexture = MapTexture(pbr.baseColorTexture, pointer + "/pbrMetallicRoughness/baseColorTexture");
    }
    if (source.emissiveFactor.size() == 3) {
      for (int c = 0; c < 3; ++c) {
        const double emitted = source.emissiveFactor[static_cast<size_t>(c)];
        if (!(emitted >= 0 && emitted <= kMaxMagnitude)) {
          Fail(pointer + "/emissiveFactor/" + std::to_string(c), std::to_string(emitted), "a finite non-negative factor");
        }
        (c == 0 ? material.emission.x : c == 1 ? material.emission.y : material.emission.z) = emitted;
      }
    }
    return material;
  }

  // glTF's sampler codes (WebGL's enums); a sampler that leaves one out means repeat and
  // the renderer's choice of filter, here bilinear.
  static Texture::Wrap WrapOf(int code) {
    if (code == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return Texture::Wrap::kClampToEdge;
    if (code == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return Texture::Wrap::kMirroredRepeat;
    return Texture::Wrap::kRepeat;
  }

  Texture MapTexture(const tinygltf::TextureInfo& info, const std::string& pointer) const {
    if (static_cast<size_t>(info.index) >= model_.textures.size()) {
      Fail(pointer + "/index", "texture " + std::to_string(info.index) + " does not exist",
           "an index below the file's " + std::to_string(model_.textures.size()) + " textures");
    }
    if (info.texCoord != 0) Warn(pointer + "/texCoord", "only TEXCOORD_0 is kept; the texture is sampled with it");
    const tinygltf::Texture& source = model_.textures[static_cast<size_t>(info.index)];
    const std::string texturePointer = Pointer("textures", static_cast<size_t>(info.index));
    if (source.source < 0 || static_cast<size_t>(source.source) >= model_.images.size()) {
      Fail(texturePointer + "/source", "image " + std::to_string(source.source) + " does not exist",
           "an index below the file's " + std::to_string(model_.images.size()) + " images");
    }
    const tinygltf::Image& image = model_.images[static_cast<size_t>(source.source)];
    if (image.image.empty()) {
      Fail(Pointer("images", static_cast<size_t>(source.source)), "the image holds no bytes",
           "a PNG or JPEG image in a file, a data URI or a buffer view");
    }
    Texture texture;
    // One copy of an image however many materials use it: a short JSON must not multiply a large image.
    auto& shared = imageBytes_[source.source];
    if (!shared.first) {
      shared.first = std::make_shared<const std::string>(image.image.begin(), image.image.end());
      shared.second = wire::Sha256Hex(*shared.first);
    }
    texture.bytes = shared.first;
    texture.asset = shared.second;
    // For messages: the file beside the glTF, or where in it an embedded image lies.
    const bool external =
        !image.uri.empty() && image.uri.compare(0, 5, "data:") != 0 && !gltf::EmbeddedIndex(image.uri);
    texture.image = external ? UrlDecode(image.uri)
                             : input_.displayName + " at " + Pointer("images", static_cast<size_t>(source.source));
    if (source.sampler >= 0) {
      if (static_cast<size_t>(source.sampler) >= model_.samplers.size()) {
        Fail(texturePointer + "/sampler", "sampler " + std::to_string(source.sampler) + " does not exist",
             "an index below the file's " + std::to_string(model_.samplers.size()) + " samplers");
      }
      const tinygltf::Sampler& sampler = model_.samplers[static_cast<size_t>(source.sampler)];
      texture.wrapS = WrapOf(sampler.wrapS);
      texture.wrapT = WrapOf(sampler.wrapT);
      if (sampler.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST) texture.filter = Texture::Filter::kNearest;
    }
    return texture;
  }

  // Materials as the scene parser orders them ("default" first, then by name), so the
  // scene reads back with the same indices. Primitives without a material get the
  // built-in default, not glTF's (a black metal).
  void AddMaterials(Scene& scene) {
    std::map<std::string, size_t> byName;
    std::vector<std::string> names(model_.materials.size());
    for (size_t i = 0; i < model_.materials.size(); ++i) {
      std::string name = model_.materials[i].name.empty() ? "material" + std::to_string(i) : model_.materials[i].name;
      if (name == "default" || byName.count(name)) name += "#" + std::to_string(i);
      while (byName.count(name)) name += "'";
      byName.emplace(name, i);
      names[i] = name;
    }
    scene.materials.assign(1, Material{});
    scene.materials[0].name = "default";
    materialIndex_.assign(model_.materials.size(), 0);
    for (const auto& [name, index] : byName) {
      Material material = MapMaterial(model_.materials[index], index);
      material.name = name;
      materialIndex_[index] = static_cast<int>(scene.materials.size());
      scene.materials.push_back(material);
    }
  }

  // ---- node graph -----------------------------------------------------------------------

  // Parents of every node, and the roots of the scene to render; a node with two parents
  // or on a cycle is refused.
  void BuildGraph() {
    const size_t count = model_.nodes.size();
    parent_.assign(count, -1);
    for (size_t i = 0; i < count; ++i) {
      const auto& children = model_.nodes[i].children;
      for (size_t k = 0; k < children.size(); ++k) {
        int child = children[k];
        std::string pointer = Pointer("nodes", i) + "/children/" + std::to_string(k);
        if (child < 0 || static_cast<size_t>(child) >= count) {
          Fail(pointer,
               "node " + std::to_string(child) + " does not exist (the file has " + std::to_string(count) + ")",
               "the index of a node");
        }
        if (static_cast<size_t>(child) == i)
          Fail(pointer, "node " + std::to_string(i) + " is its own child", "a tree of nodes");
        if (parent_[static_cast<size_t>(child)] >= 0) {
          Fail(pointer,
               "node " + std::to_string(child) + " already has parent " +
                   std::to_string(parent_[static_cast<size_t>(child)]),
               "a tree of nodes: each node the child of at most one");
        }
        parent_[static_cast<size_t>(child)] = static_cast<int>(i);
      }
    }
    // With one parent each, a cycle is a walk up that comes back.
    for (size_t i = 0; i < count; ++i) {
      size_t steps = 0;
      for (int up = parent_[i]; up >= 0; up = parent_[static_cast<size_t>(up)]) {
        if (static_cast<size_t>(up) == i || ++steps > count) {
          Fail(Pointer("nodes", i), "node " + std::to_string(i) + " is its own ancestor (a recursive node graph)",
               "a tree of nodes");
        }
      }
    }
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      size_t chosen = model_.defaultScene >= 0 ? static_cast<size_t>(model_.defaultScene) : 0;
      if (chosen >= model_.scenes.size()) {
        Fail("/scene", "scene " + std::to_string(chosen) + " does not exist", "the index of a scene");
      }
      const auto& nodes = model_.scenes[chosen].nodes;
      for (size_t k = 0; k < nodes.size(); ++k) {
        std::string pointer = Pointer("scenes", chosen) + "/nodes/" + std::to_string(k);
        if (nodes[k] < 0 || static_cast<size_t>(nodes[k]) >= count) {
          Fail(pointer, "node " + std::to_string(nodes[k]) + " does not exist", "the index of a node");
        }
        if (parent_[static_cast<size_t>(nodes[k])] >= 0)
          Fail(pointer, "node " + std::to_string(nodes[k]) + " has a parent", "a root node");
        roots.push_back(nodes[k]);
      }
    } else {
      // No scene: every root node, as viewers do.
      for (size_t i = 0; i < count; ++i) {
        if (parent_[i] < 0) roots.push_back(static_cast<int>(i));
      }
    }
    // Depth-first, so parents come before their children.
    std::vector<int> stack(roots.rbegin(), roots.rend());
    inScene_.assign(count, false);
    while (!stack.empty()) {
      int node = stack.back();
      stack.pop_back();
      if (inScene_[static_cast<size_t>(node)]) continue;
      inScene_[static_cast<size_t>(node)] = true;
      order_.push_back(node);
      const auto& children = model_.nodes[static_cast<size_t>(node)].children;
      for (auto it = children.rbegin(); it != children.rend(); ++it) stack.push_back(*it);
    }
  }

  // ---- transforms and animation ---------------------------------------------------------

  // A column-major matrix as translation, rotation and scale, or refused.
  void Decompose(const std::vector<double>& m, const std::string& pointer, Vec3* translation, Quaternion* rotation,
                 Vec3* scale) const {
    for (double v : m) {
      if (!(std::fabs(v) <= kMaxMagnitude)) Fail(pointer, "a matrix element of " + std::to_string(v), "finite numbers");
    }
    if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1) {
      Fail(pointer, "a projective bottom row", "an affine matrix (bottom row 0, 0, 0, 1)");
    }
    Vec3 column[3] = {{m[0], m[1], m[2]}, {m[4], m[5], m[6]}, {m[8], m[9], m[10]}};
    double length[3] = {Norm(column[0]), Norm(column[1]), Norm(column[2])};
    double longest = std::max({length[0], length[1], length[2]});
    if (!(longest > 0) || std::min({length[0], length[1], length[2]}) <= kSingularRatio * longest) {
      Fail(pointer, "a singular matrix", "a matrix of translation, rotation and non-zero scale");
    }
    Vec3 cross = CrossProduct(column[0], column[1]);
    double determinant = cross.x * column[2].x + cross.y * column[2].y + cross.z * column[2].z;
    // A mirror is a negative scale on x.
    if (determinant < 0) length[0] = -length[0];
    double r[3][3];
    for (int c = 0; c < 3; ++c) {
      for (int row = 0; row < 3; ++row) r[row][c] = column[c][row] / length[c];
    }
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        double dot = r[0][a] * r[0][b] + r[1][a] * r[1][b] + r[2][a] * r[2][b];
        if (std::fabs(dot - (a == b ? 1 : 0)) > kOrthonormalTolerance) {
          Fail(pointer, "a matrix with shear", "a matrix of translation, rotation and scale only");
        }
      }
    }
    *translation = {m[12], m[13], m[14]};
    *scale = {length[0], length[1], length[2]};
    // Shepperd's method: divide by the largest of the four candidates.
    double trace = r[0][0] + r[1][1] + r[2][2];
    Quaternion q;
    if (trace > 0) {
      double s = std::sqrt(trace + 1) * 2;
      q = {s / 4, (r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s};
    } else if (r[0][0] > r[1][1] && r[0][0] > r[2][2]) {
      double s = std::sqrt(1 + r[0][0] - r[1][1] - r[2][2]) * 2;
      q = {(r[2][1] - r[1][2]) / s, s / 4, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s};
    } else if (r[1][1] > r[2][2]) {
      double s = std::sqrt(1 + r[1][1] - r[0][0] - r[2][2]) * 2;
      q = {(r[0][2] - r[2][0]) / s, (r[0][1] + r[1][0]) / s, s / 4, (r[1][2] + r[2][1]) / s};
    } else {
      double s = std::sqrt(1 + r[2][2] - r[0][0] - r[1][1]) * 2;
      q = {(r[1][0] - r[0][1]) / s, (r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, s / 4};
    }
    *rotation = q;
  }

  // The animation to play: by name or index, the first by default; none when the file
  // has none.
  void ChooseAnimation() {
    animation_ = -1;
    frameCount_ = 1;
    if (!(options_.framesPerSecond > 0) || !std::isfinite(options_.framesPerSecond)) {
      Fail("", "a frame rate of " + std::to_string(options_.framesPerSecond), "a positive frames per second");
    }
    const std::string& wanted = options_.animation;
    if (wanted.empty()) {
      if (!model_.animations.empty()) animation_ = 0;
    } else {
      for (size_t i = 0; i < model_.animations.size(); ++i) {
        if (model_.animations[i].name == wanted) {
          animation_ = static_cast<int>(i);
          break;
        }
      }
      if (animation_ < 0 && wanted.find_first_not_of("0123456789") == std::string::npos && wanted.size() < 9 &&
          std::stoul(wanted) < model_.animations.size()) {
        animation_ = std::stoi(wanted);
      }
      if (animation_ < 0) {
        Fail("/animations",
             "no animation named or numbered " + QuoteInput(wanted) + " (the file has " +
                 std::to_string(model_.animations.size()) + ")",
             "an animation's name or index");
      }
    }
  }

  struct Channel {
    bool present = false;
    std::vector<double> times;
    AccessorData values;
    Interpolation interpolation = Interpolation::kLinear;
  };

  // Keyframe frames from a sampler's input: finite, non-negative, strictly increasing.
  std::vector<double> ReadTimes(int accessor, const std::string& referencedAt) const {
    AccessorData data = ReadAccessor(accessor, referencedAt, {TINYGLTF_TYPE_SCALAR}, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                                     "a SCALAR FLOAT accessor of key times in seconds");
    const std::string pointer = Pointer("accessors", static_cast<size_t>(accessor));
    if (data.count == 0) Fail(pointer + "/count", "no key times", "at least one key");
    std::vector<double> frames;
    for (size_t k = 0; k < data.count; ++k) {
      double time = data.values[k];
      if (!std::isfinite(time) || time < 0) {
        Fail(pointer, "key time " + std::to_string(k) + " is " + std::to_string(time), "finite non-negative times");
      }
      double frame = time * options_.framesPerSecond;
      if (!frames.empty() && !(frame > frames.back())) {
        Fail(pointer,
             "key time " + std::to_string(k) + " (" + std::to_string(time) + " s) does not follow key " +
                 std::to_string(k - 1),
             "strictly increasing key times");
      }
      frames.push_back(frame);
    }
    return frames;
  }

  // A sampler's keys: their frames, interpolation and values, `perKey` elements per key
  // (per in-tangent, value and out-tangent for CUBICSPLINE), checked to be as many as that.
  Channel ReadChannel(const tinygltf::AnimationSampler& sampler, const std::string& samplerPointer, int type,
                      const std::vector<int>& componentTypes, const std::string& expected, size_t perKey) const {
    Channel channel;
    channel.present = true;
    channel.times = ReadTimes(sampler.input, samplerPointer + "/input");
    if (sampler.interpolation == "STEP") {
      channel.interpolation = Interpolation::kStep;
    } else if (sampler.interpolation == "CUBICSPLINE") {
      channel.interpolation = Interpolation::kCubicSpline;
    } else if (sampler.interpolation == "LINEAR" || sampler.interpolation.empty()) {
      channel.interpolation = Interpolation::kLinear;
    } else {
      Fail(samplerPointer + "/interpolation", QuoteInput(sampler.interpolation), "LINEAR, STEP or CUBICSPLINE");
    }
    channel.values = ReadAccessor(sampler.output, samplerPointer + "/output", {type}, componentTypes, expected);
    CheckFinite(channel.values, sampler.output, "key value");
    const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
    const size_t wanted = channel.times.size() * perKey * (cubic ? 3 : 1);
    if (channel.values.count != wanted) {
      const std::string what = perKey > 1 ? std::to_string(perKey) + " weights (one per morph target) " : "one value ";
      Fail(Pointer("accessors", static_cast<size_t>(sampler.output)) + "/count",
           std::to_string(channel.values.count) + " values for " + std::to_string(channel.times.size()) + " key times",
           std::to_string(wanted) + " values (" + what +
               (cubic ? "per in-tangent, value and out-tangent of each key)" : "per key)"));
    }
    return channel;
  }

  // Node i's local translation, rotation and scale over frames, from the node and the
  // chosen animation's channels; the channels of morph target weights are kept for the
  // shapes.
  void BuildMotions() {
    const size_t count = model_.nodes.size();
    channels_.assign(count, {});
    double lastFrame = 0;
    if (animation_ >= 0) {
      const auto& animation = model_.animations[static_cast<size_t>(animation_)];
      const std::string animationPointer = Pointer("animations", static_cast<size_t>(animation_));
      for (size_t c = 0; c < animation.channels.size(); ++c) {
        const auto& channel = animation.channels[c];
        const std::string pointer = animationPointer + "/channels/" + std::to_string(c);
        if (channel.target_node < 0) continue;  // a target for an extension
        if (static_cast<size_t>(channel.target_node) >= count) {
          Fail(pointer + "/target/node", "node " + std::to_string(channel.target_node) + " does not exist",
               "the index of a node");
        }
        const std::string& path = channel.target_path;
        if (path != "translation" && path != "rotation" && path != "scale" && path != "weights") {
          Fail(pointer + "/target/path", "path " + QuoteInput(path), "translation, rotation, scale or weights");
        }
        if (channel.sampler < 0 || static_cast<size_t>(channel.sampler) >= animation.samplers.size()) {
          Fail(pointer + "/sampler", "sampler " + std::to_string(channel.sampler) + " does not exist",
               "the index of a sampler");
        }
        const auto& node = model_.nodes[static_cast<size_t>(channel.target_node)];
        if (!node.matrix.empty()) {
          Fail(pointer + "/target/node", "node " + std::to_string(channel.target_node) + " has a matrix",
               "animated nodes with translation, rotation and scale (the glTF rule)");
        }
        Channel& target = channels_[static_cast<size_t>(channel.target_node)][path];
        if (target.present)
          Fail(pointer, "a second channel for " + path + " of the same node", "one channel per node and path");
        const std::string samplerPointer = animationPointer + "/samplers/" + std::to_string(channel.sampler);
        const auto& sampler = animation.samplers[static_cast<size_t>(channel.sampler)];
        // Rotations and weights may be floats or normalized integers.
        const std::vector<int> floatsOrIntegers = {
            TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
            TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
        if (path == "weights") {
          const size_t targets = MorphTargetCount(static_cast<size_t>(channel.target_node));
          if (targets == 0) {
            Fail(pointer + "/target/node",
                 "node " + std::to_string(channel.target_node) + " has no mesh with morph targets",
                 "a weights channel on a node whose mesh has morph targets");
          }
          target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_SCALAR, floatsOrIntegers,
                               "a SCALAR accessor of morph target weights", targets);
        } else if (path == "rotation") {
          target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_VEC4, floatsOrIntegers,
                               "a VEC4 accessor of quaternions", 1);
        } else {
          target = ReadChannel(sampler, samplerPointer, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                               "a VEC3 FLOAT accessor", 1);
        }
        lastFrame = std::max(lastFrame, target.times.back());
      }
    }
    double frames = std::ceil(lastFrame);
    if (frames + 1 > kMaxFrameCount) {
      Fail(Pointer("animations", static_cast<size_t>(animation_)),
           "the animation lasts " + std::to_string(lastFrame / options_.framesPerSecond) + " s, " +
               std::to_string(frames + 1) + " frames at " + std::to_string(options_.framesPerSecond) + " per second",
           "at most " + std::to_string(kMaxFrameCount) + " frames");
    }
    frameCount_ = static_cast<int>(frames) + 1;

    motions_.assign(count, nullptr);
    for (int node : order_) {
      auto motion =
          std::make_shared<Motion>(LocalMotion(static_cast<size_t>(node), channels_[static_cast<size_t>(node)]));
      int parent = parent_[static_cast<size_t>(node)];
      if (parent >= 0 && !motions_[static_cast<size_t>(parent)]->IsNone()) {
        motion->parent = motions_[static_cast<size_t>(parent)];
      }
      int depth = 0;
      for (const Motion* up = motion.get(); up->parent; up = up->parent.get()) ++depth;
      if (depth >= kMaxMotionDepth) {
        Fail(Pointer("nodes", static_cast<size_t>(node)), "a node " + std::to_string(depth) + " levels deep",
             "a hierarchy at most " + std::to_string(kMaxMotionDepth) + " levels deep");
      }
      motions_[static_cast<size_t>(node)] = motion;
    }
  }

  Motion LocalMotion(size_t index, const std::map<std::string, Channel>& channels) const {
    const tinygltf::Node& node = model_.nodes[index];
    const std::string pointer = Pointer("nodes", index);
    Vec3 translation, scale{1, 1, 1};
    Quaternion rotation;
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16)
        Fail(pointer + "/matrix", std::to_string(node.matrix.size()) + " numbers", "16 numbers");
      Decompose(node.matrix, pointer + "/matrix", &translation, &rotation, &scale);
    } else {
      auto check = [&](const std::vector<double>& values, size_t size, const char* key) {
        if (!values.empty() && values.size() != size) {
          Fail(pointer + "/" + key, std::to_string(values.size()) + " numbers", std::to_string(size) + " numbers");
        }
        for (double v : values) {
          if (!(std::fabs(v) <= kMaxMagnitude))
            Fail(pointer + "/" + key, "a value of " + std::to_string(v), "finite numbers");
        }
      };
      check(node.translation, 3, "translation");
      check(node.rotation, 4, "rotation");
      check(node.scale, 3, "scale");
      if (!node.translation.empty()) translation = {node.translation[0], node.translation[1], node.translation[2]};
      if (!node.rotation.empty()) rotation = {node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]};
      if (!node.scale.empty()) scale = {node.scale[0], node.scale[1], node.scale[2]};
    }
    if (rotation.w == 0 && rotation.x == 0 && rotation.y == 0 && rotation.z == 0) {
      Fail(pointer + "/rotation", "a zero quaternion", "a unit quaternion");
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!(std::fabs(scale[axis]) >= kMinScale && std::fabs(scale[axis]) <= kMaxScale)) {
        Fail(pointer, "a scale of " + std::to_string(scale[axis]), "scale components of magnitude in [1e-6, 1e6]");
      }
    }
    Motion motion;
    motion.translation = AnimatedVec3::Constant(translation);
    motion.rotation = AnimatedRotation::Constant(rotation);
    motion.scale = AnimatedVec3::Constant(scale);
    const double fps = options_.framesPerSecond;
    auto vectorKeys = [&](const Channel& channel) {
      std::vector<AnimatedVec3::Keyframe> keys;
      bool cubic = channel.interpolation == Interpolation::kCubicSpline;
      for (size_t k = 0; k < channel.times.size(); ++k) {
        size_t at = cubic ? 3 * k + 1 : k;
        AnimatedVec3::Keyframe key{channel.times[k],
                                   {channel.values.At(at, 0), channel.values.At(at, 1), channel.values.At(at, 2)}};
        if (cubic) {
          // glTF's tangents are per second; the scene's per frame.
          key.inTangent = {channel.values.At(at - 1, 0) / fps, channel.values.At(at - 1, 1) / fps,
                           channel.values.At(at - 1, 2) / fps};
          key.outTangent = {channel.values.At(at + 1, 0) / fps, channel.values.At(at + 1, 1) / fps,
                            channel.values.At(at + 1, 2) / fps};
        }
        keys.push_back(key);
      }
      return AnimatedVec3::Keyframes(std::move(keys), channel.interpolation);
    };
    if (auto found = channels.find("translation"); found != channels.end())
      motion.translation = vectorKeys(found->second);
    if (auto found = channels.find("scale"); found != channels.end()) {
      const Channel& channel = found->second;
      for (size_t i = 0; i < channel.values.values.size(); ++i) {
        // Only key values bound the scale (tangents may overshoot: the parser checks frames).
        bool value = channel.interpolation != Interpolation::kCubicSpline || (i / 3) % 3 == 1;
        double v = std::fabs(channel.values.values[i]);
        if (value && !(v >= kMinScale && v <= kMaxScale)) {
          Fail(pointer, "an animated scale of " + std::to_string(channel.values.values[i]),
               "scale components of magnitude in [1e-6, 1e6] (a node cannot be scaled to nothing)");
        }
      }
      motion.scale = vectorKeys(channel);
    }
    if (auto found = channels.find("rotation"); found != channels.end()) {
      const Channel& channel = found->second;
      bool cubic = channel.interpolation == Interpolation::kCubicSpline;
      std::vector<AnimatedRotation::Keyframe> keys;
      auto quaternion = [&](size_t at, double divide) {
        return Quaternion{channel.values.At(at, 3) / divide, channel.values.At(at, 0) / divide,
                          channel.values.At(at, 1) / divide, channel.values.At(at, 2) / divide};
      };
      for (size_t k = 0; k < channel.times.size(); ++k) {
        size_t at = cubic ? 3 * k + 1 : k;
        AnimatedRotation::Keyframe key{channel.times[k], quaternion(at, 1)};
        if (key.value.w == 0 && key.value.x == 0 && key.value.y == 0 && key.value.z == 0) {
          Fail(pointer, "a zero quaternion at key " + std::to_string(k) + " of its rotation channel",
               "unit quaternions");
        }
        if (cubic) {
          key.inTangent = quaternion(at - 1, fps);
          key.outTangent = quaternion(at + 1, fps);
        }
        keys.push_back(key);
      }
      motion.rotation = AnimatedRotation::Keyframes(std::move(keys), channel.interpolation);
    }
    return motion;
  }

  // ---- meshes ---------------------------------------------------------------------------

  TriangleMesh PrimitiveMesh(const tinygltf::Primitive& primitive, const std::string& pointer) const {
    auto position = primitive.attributes.find("POSITION");
    if (position == primitive.attributes.end()) {
      Fail(pointer + "/attributes", "no POSITION attribute", "a primitive with POSITION");
    }
    const std::vector<int> anyComponent = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
    AccessorData positions = ReadAccessor(position->second, pointer + "/attributes/POSITION", {TINYGLTF_TYPE_VEC3},
                                          anyComponent, "a VEC3 accessor of positions");
    CheckFinite(positions, position->second, "position");
    TriangleMesh mesh;
    for (size_t v = 0; v < positions.count; ++v)
      mesh.vertices.push_back({positions.At(v, 0), positions.At(v, 1), positions.At(v, 2)});
    if (auto normal = primitive.attributes.find("NORMAL"); normal != primitive.attributes.end()) {
      AccessorData normals =
          ReadAccessor(normal->second, pointer + "/attributes/NORMAL", {TINYGLTF_TYPE_VEC3},
                       {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT},
                       "a VEC3 accessor of normals");
      CheckFinite(normals, normal->second, "normal");
      if (normals.count != positions.count) {
        Fail(Pointer("accessors", static_cast<size_t>(normal->second)) + "/count",
             std::to_string(normals.count) + " normals for " + std::to_string(positions.count) + " positions",
             "one normal per position");
      }
      for (size_t v = 0; v < normals.count; ++v)
        mesh.normals.push_back({normals.At(v, 0), normals.At(v, 1), normals.At(v, 2)});
    }
    if (auto uv = primitive.attributes.find("TEXCOORD_0"); uv != primitive.attributes.end()) {
      AccessorData uvs = ReadAccessor(uv->second, pointer + "/attributes/TEXCOORD_0", {TINYGLTF_TYPE_VEC2},
                                      anyComponent, "a VEC2 accessor of texture coordinates");
      CheckFinite(uvs, uv->second, "texture coordinate");
      if (uvs.count != positions.count) {
        Fail(Pointer("accessors", static_cast<size_t>(uv->second)) + "/count",
             std::to_string(uvs.count) + " texture coordinates for " + std::to_string(positions.count) + " positions",
             "one per position");
      }
      for (size_t v = 0; v < uvs.count; ++v) mesh.uvs.push_back({uvs.At(v, 0), uvs.At(v, 1)});
    }
    if (auto color = primitive.attributes.find("COLOR_0"); color != primitive.attributes.end()) {
      mesh.colors = ReadVertexColors(color->second, pointer + "/attributes/COLOR_0", positions.count);
    }
    std::vector<uint32_t> indices;
    if (primitive.indices >= 0) {
      AccessorData data = ReadAccessor(primitive.indices, pointer + "/indices", {TINYGLTF_TYPE_SCALAR},
                                       {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                        TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                                       "a SCALAR accessor of unsigned indices");
      for (size_t i = 0; i < data.count; ++i) {
        double index = data.values[i];
        if (!(index < static_cast<double>(positions.count))) {
          Fail(Pointer("accessors", static_cast<size_t>(primitive.indices)),
               "index " + std::to_string(i) + " is " + std::to_string(static_cast<uint64_t>(index)) +
                   ", out of range for " + std::to_string(positions.count) + " vertices",
               "indices below the vertex count");
        }
        indices.push_back(static_cast<uint32_t>(index));
      }
    } else {
      for (size_t v = 0; v < positions.count; ++v) indices.push_back(static_cast<uint32_t>(v));
    }
    int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
    mesh.triangles = Triangles(indices, mode);
    return mesh;
  }

 public:
  // The triangles of a TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN list, as the glTF spec
  // numbers them (a strip alternates its winding so every triangle faces the same way).
  static std::vector<std::array<uint32_t, 3>> Triangles(const std::vector<uint32_t>& indices, int mode) {
    std::vector<std::array<uint32_t, 3>> triangles;
    const size_t n = indices.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      for (size_t i = 0; i + 2 < n; i += 3) triangles.push_back({indices[i], indices[i + 1], indices[i + 2]});
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (size_t i = 0; i + 2 < n; ++i) {
        triangles.push_back({indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]});
      }
    } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
      for (size_t i = 0; i + 2 < n; ++i) triangles.push_back({indices[i + 1], indices[i + 2], indices[0]});
    }
    return triangles;
  }

 private:
  // How many of the scene's nodes place each mesh.
  std::vector<int> NodesPerMesh() const {
    std::vector<int> count(model_.meshes.size(), 0);
    for (int node : order_) {
      const int mesh = model_.nodes[static_cast<size_t>(node)].mesh;
      if (mesh >= 0 && static_cast<size_t>(mesh) < count.size()) ++count[static_cast<size_t>(mesh)];
    }
    return count;
  }

  // The name a shared primitive takes in Scene::meshes: its glTF mesh's name (else
  // `mesh<i>`), `/p` after it when the mesh has several primitives, `#<i>` after a name
  // another mesh has taken already.
  static std::string SharedMeshName(const tinygltf::Mesh& mesh, size_t meshIndex, size_t primitive,
                                    const Scene& scene) {
    std::string name = mesh.name.empty() ? "mesh" + std::to_string(meshIndex) : mesh.name;
    if (mesh.primitives.size() > 1) name += "/" + std::to_string(primitive);
    if (scene.meshes.count(name)) name += "#" + std::to_string(meshIndex);
    return name;
  }

  // Gives the shape the primitive's triangles: its own when one node places the mesh,
  // else the scene's shared copy (read once, in the mesh's space; each node's Motion
  // places it).
  void SetPrimitiveMesh(Shape& shape, size_t meshIndex, size_t p, bool shared, const std::string& pointer,
                        Scene& scene) {
    if (!shared) {
      shape.mesh = PrimitiveMesh(model_.meshes[meshIndex].primitives[p], pointer);
      return;
    }
    auto [entry, isNew] = sharedPrimitives_.try_emplace({meshIndex, p});
    if (isNew) {
      auto mesh = std::make_shared<const TriangleMesh>(PrimitiveMesh(model_.meshes[meshIndex].primitives[p], pointer));
      // A primitive without area is skipped at every node: it never enters the table.
      entry->second.name = HasArea(*mesh) ? SharedMeshName(model_.meshes[meshIndex], meshIndex, p, scene) : "";
      if (!entry->second.name.empty()) scene.meshes[entry->second.name] = mesh;
      entry->second.mesh = std::move(mesh);
    }
    shape.sharedMesh = entry->second.mesh;
    shape.meshRef = entry->second.name;
  }

  void AddShapes(Scene& scene) {
    size_t triangles = 0;
    const std::vector<int> nodesPerMesh = NodesPerMesh();
    for (int node : order_) {
      const auto& source = model_.nodes[static_cast<size_t>(node)];
      if (source.mesh < 0) continue;
      const std::string nodePointer = Pointer("nodes", static_cast<size_t>(node));
      if (static_cast<size_t>(source.mesh) >= model_.meshes.size()) {
        Fail(nodePointer + "/mesh", "mesh " + std::to_string(source.mesh) + " does not exist", "the index of a mesh");
      }
      // A skinned mesh is placed by its joints alone: glTF ignores its node's transform.
      const SkinJoints* skin = source.skin >= 0 ? &ReadSkin(static_cast<size_t>(node)) : nullptr;
      MorphTargetCount(static_cast<size_t>(node));  // refuses primitives with different target counts
      const auto& mesh = model_.meshes[static_cast<size_t>(source.mesh)];
      for (size_t p = 0; p < mesh.primitives.size(); ++p) {
        const auto& primitive = mesh.primitives[p];
        const std::string pointer =
            Pointer("meshes", static_cast<size_t>(source.mesh)) + "/primitives/" + std::to_string(p);
        int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
            mode != TINYGLTF_MODE_TRIANGLE_FAN) {
          if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
            Fail(pointer + "/mode", "mode " + std::to_string(mode), "a primitive mode from 0 to 6");
          }
          Warn(pointer, "points and lines are not rendered; the primitive is skipped");
          continue;
        }
        Shape shape;
        shape.type = Shape::Type::kMesh;
        shape.name = (source.name.empty() ? "node" + std::to_string(node) : source.name) +
                     (mesh.primitives.size() > 1 ? "/" + std::to_string(p) : "");
        if (primitive.material >= 0) {
          if (static_cast<size_t>(primitive.material) >= model_.materials.size()) {
            Fail(pointer + "/material", "material " + std::to_string(primitive.material) + " does not exist",
                 "the index of a material");
          }
          shape.material = materialIndex_[static_cast<size_t>(primitive.material)];
        }
        SetPrimitiveMesh(shape, static_cast<size_t>(source.mesh), p, nodesPerMesh[static_cast<size_t>(source.mesh)] > 1,
                         pointer, scene);
        if (!HasArea(shape.Mesh())) {
          Warn(pointer, "no triangle with area; the primitive is skipped");
          continue;
        }
        triangles += shape.Mesh().triangles.size();
        if (triangles > kMaxTriangles) {
          Fail(pointer, "more than " + std::to_string(kMaxTriangles) + " triangles in all", "a smaller scene");
        }
        shape.deformation =
            PrimitiveDeformation(static_cast<size_t>(node), skin, primitive, pointer, shape.Mesh());
        if (skin == nullptr) shape.motion = *motions_[static_cast<size_t>(node)];
        scene.shapes.push_back(std::move(shape));
      }
    }
  }

  // ---- skins and morph targets ----------------------------------------------------------

  // How many morph targets node i's mesh has (0 without a mesh): the same in every
  // primitive and as many as the mesh's default weights, or refused.
  size_t MorphTargetCount(size_t node) const {
    const int meshIndex = model_.nodes[node].mesh;
    if (meshIndex < 0) return 0;
    if (static_cast<size_t>(meshIndex) >= model_.meshes.size()) {
      Fail(Pointer("nodes", node) + "/mesh", "mesh " + std::to_string(meshIndex) + " does not exist",
           "the index of a mesh");
    }
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(meshIndex)];
    const std::string pointer = Pointer("meshes", static_cast<size_t>(meshIndex));
    const size_t targets = mesh.primitives.empty() ? 0 : mesh.primitives[0].targets.size();
    for (size_t p = 1; p < mesh.primitives.size(); ++p) {
      if (mesh.primitives[p].targets.size() != targets) {
        Fail(pointer + "/primitives/" + std::to_string(p) + "/targets",
             std::to_string(mesh.primitives[p].targets.size()) + " morph targets where primitive 0 has " +
                 std::to_string(targets),
             "the same number of morph targets in every primitive of a mesh");
      }
    }
    CheckWeights(mesh.weights, targets, pointer + "/weights");
    return targets;
  }

  // Default weights (a mesh's or a node's): none, or one finite weight per morph target.
  void CheckWeights(const std::vector<double>& weights, size_t targets, const std::string& pointer) const {
    if (weights.empty()) return;
    if (weights.size() != targets) {
      Fail(pointer, std::to_string(weights.size()) + " weights for " + std::to_string(targets) + " morph targets",
           "one weight per morph target");
    }
    for (size_t i = 0; i < weights.size(); ++i) {
      if (!(std::fabs(weights[i]) <= kMaxMagnitude)) {
        Fail(pointer + "/" + std::to_string(i), std::to_string(weights[i]), "finite weights");
      }
    }
  }

  // Node i's morph target weights over frame time: its animation's weights channel, else
  // the node's `weights`, else its mesh's, else zeros.
  AnimatedWeights MorphWeights(size_t node, size_t targets) const {
    const tinygltf::Node& source = model_.nodes[node];
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(source.mesh)];
    CheckWeights(source.weights, targets, Pointer("nodes", node) + "/weights");
    if (auto found = channels_[node].find("weights"); found != channels_[node].end()) {
      const Channel& channel = found->second;
      const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
      const double fps = options_.framesPerSecond;
      auto values = [&](size_t element) {
        auto first = channel.values.values.begin() + static_cast<std::ptrdiff_t>(element * targets);
        return std::vector<double>(first, first + static_cast<std::ptrdiff_t>(targets));
      };
      std::vector<AnimatedWeights::Keyframe> keys;
      for (size_t k = 0; k < channel.times.size(); ++k) {
        AnimatedWeights::Keyframe key{channel.times[k], values(cubic ? 3 * k + 1 : k)};
        if (cubic) {
          // glTF's tangents are per second; the scene's per frame.
          key.inTangent = values(3 * k);
          key.outTangent = values(3 * k + 2);
          for (double& tangent : key.inTangent) tangent /= fps;
          for (double& tangent : key.outTangent) tangent /= fps;
        }
        keys.push_back(std::move(key));
      }
      return AnimatedWeights::Keyframes(std::move(keys), channel.interpolation);
    }
    const std::vector<double>& weights = source.weights.empty() ? mesh.weights : source.weights;
    return AnimatedWeights::Constant(weights.empty() ? std::vector<double>(targets, 0.0) : weights);
  }

  // A primitive's morph targets: POSITION and NORMAL deltas, one per vertex (a target
  // without POSITION moves nothing; NORMAL deltas are kept only for a mesh with normals).
  MorphTargets ReadMorphTargets(const tinygltf::Primitive& primitive, const std::string& pointer,
                                const TriangleMesh& mesh) const {
    MorphTargets morph;
    const size_t vertices = mesh.vertices.size();
    auto deltas = [&](int accessor, const std::string& at, const std::vector<int>& componentTypes,
                      const std::string& what) {
      AccessorData data = ReadAccessor(accessor, at, {TINYGLTF_TYPE_VEC3}, componentTypes,
                                       "a VEC3 accessor of " + what);
      CheckFinite(data, accessor, what);
      if (data.count != vertices) {
        Fail(Pointer("accessors", static_cast<size_t>(accessor)) + "/count",
             std::to_string(data.count) + " " + what + " for a primitive of " + std::to_string(vertices) + " vertices",
             "one per vertex of the primitive");
      }
      std::vector<Vec3> out(vertices);
      for (size_t v = 0; v < vertices; ++v) out[v] = {data.At(v, 0), data.At(v, 1), data.At(v, 2)};
      return out;
    };
    // Floats, or KHR_mesh_quantization's signed integers.
    const std::vector<int> deltaTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                         TINYGLTF_COMPONENT_TYPE_SHORT};
    for (size_t t = 0; t < primitive.targets.size(); ++t) {
      const auto& target = primitive.targets[t];
      const std::string at = pointer + "/targets/" + std::to_string(t);
      auto position = target.find("POSITION");
      morph.positionDeltas.push_back(position == target.end()
                                         ? std::vector<Vec3>(vertices)
                                         : deltas(position->second, at + "/POSITION", deltaTypes, "position deltas"));
      auto normal = target.find("NORMAL");
      morph.normalDeltas.push_back(normal == target.end() || mesh.normals.empty()
                                       ? std::vector<Vec3>{}
                                       : deltas(normal->second, at + "/NORMAL", deltaTypes, "normal deltas"));
    }
    return morph;
  }

  // What a skin gives every primitive it binds: its joints' world motions and inverse
  // bind matrices, read and checked once.
  struct SkinJoints {
    std::vector<Motion> joints;
    std::vector<Affine> inverseBind;
  };

  const SkinJoints& ReadSkin(size_t node) {
    const int index = model_.nodes[node].skin;
    if (static_cast<size_t>(index) >= model_.skins.size()) {
      Fail(Pointer("nodes", node) + "/skin",
           "skin " + std::to_string(index) + " does not exist (the file has " + std::to_string(model_.skins.size()) +
               ")",
           "the index of a skin");
    }
    auto [entry, isNew] = skins_.try_emplace(static_cast<size_t>(index));
    if (!isNew) return entry->second;
    const tinygltf::Skin& skin = model_.skins[static_cast<size_t>(index)];
    const std::string pointer = Pointer("skins", static_cast<size_t>(index));
    if (skin.joints.empty() || skin.joints.size() > kMaxJoints) {
      Fail(pointer + "/joints", std::to_string(skin.joints.size()) + " joints",
           "1 to " + std::to_string(kMaxJoints) + " joints");
    }
    auto inScene = [&](int node, const std::string& at, const std::string& what) {
      if (node < 0 || static_cast<size_t>(node) >= model_.nodes.size()) {
        Fail(at, what + " names node " + std::to_string(node) + ", which does not exist (the file has " +
                     std::to_string(model_.nodes.size()) + ")",
             "the index of a node of the rendered scene");
      }
      if (!inScene_[static_cast<size_t>(node)]) {
        Fail(at, what + " names node " + std::to_string(node) + ", which is not in the rendered scene",
             "a node of the rendered scene");
      }
    };
    if (skin.skeleton >= 0) inScene(skin.skeleton, pointer + "/skeleton", "the skeleton");
    SkinJoints& out = entry->second;
    for (size_t j = 0; j < skin.joints.size(); ++j) {
      const int joint = skin.joints[j];
      const std::string at = pointer + "/joints/" + std::to_string(j);
      inScene(joint, at, "joint " + std::to_string(j));
      if (skin.skeleton >= 0) {
        int up = joint;
        while (up >= 0 && up != skin.skeleton) up = parent_[static_cast<size_t>(up)];
        if (up != skin.skeleton) {
          Fail(at, "joint " + std::to_string(j) + " (node " + std::to_string(joint) +
                       ") is not the skeleton node " + std::to_string(skin.skeleton) + " or below it",
               "joints in the hierarchy under the skin's skeleton");
        }
      }
      out.joints.push_back(*motions_[static_cast<size_t>(joint)]);
    }
    out.inverseBind.assign(skin.joints.size(), Affine{});  // none given: identities
    if (skin.inverseBindMatrices >= 0) {
      AccessorData matrices = ReadAccessor(skin.inverseBindMatrices, pointer + "/inverseBindMatrices",
                                           {TINYGLTF_TYPE_MAT4}, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                                           "a MAT4 FLOAT accessor of inverse bind matrices");
      const std::string at = Pointer("accessors", static_cast<size_t>(skin.inverseBindMatrices));
      CheckFinite(matrices, skin.inverseBindMatrices, "matrix");
      if (matrices.count != skin.joints.size()) {
        Fail(at + "/count",
             std::to_string(matrices.count) + " inverse bind matrices for " + std::to_string(skin.joints.size()) +
                 " joints",
             "one per joint");
      }
      for (size_t j = 0; j < matrices.count; ++j) {
        // Column-major: element (row, column) is at 4 * column + row.
        auto m = [&](int row, int column) { return matrices.At(j, 4 * column + row); };
        if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1) {
          Fail(at, "matrix " + std::to_string(j) + " has the last row " + Row(m(3, 0), m(3, 1), m(3, 2), m(3, 3)),
               "affine matrices (last row 0, 0, 0, 1)");
        }
        Affine& affine = out.inverseBind[j];
        for (int row = 0; row < 3; ++row) {
          for (int column = 0; column < 3; ++column) affine.linear[row][column] = m(row, column);
          affine.offset[row] = m(row, 3);
        }
      }
    }
    return out;
  }

  static std::string Row(double a, double b, double c, double d) {
    std::string text;
    for (double v : {a, b, c, d}) text += (text.empty() ? "" : ", ") + nlohmann::json(v).dump();
    return text;
  }

  // COLOR_0: linear RGB (an alpha is not used), FLOAT or normalized UNSIGNED_BYTE or
  // UNSIGNED_SHORT, one per position.
  std::vector<Vec3> ReadVertexColors(int index, const std::string& referencedAt, size_t positions) const {
    AccessorData colors = ReadAccessor(
        index, referencedAt, {TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4},
        {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
        "a VEC3 or VEC4 accessor of colours (FLOAT, or normalized UNSIGNED_BYTE or UNSIGNED_SHORT)");
    const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
    const tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
    if (accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !accessor.normalized) {
      Fail(pointer + "/normalized", "integer colours that are not normalized", "normalized: true on integer colours");
    }
    CheckFinite(colors, index, "colour");
    if (colors.count != positions) {
      Fail(pointer + "/count", std::to_string(colors.count) + " colours for " + std::to_string(positions) + " positions",
           "one colour per position");
    }
    std::vector<Vec3> result;
    result.reserve(colors.count);
    for (size_t v = 0; v < colors.count; ++v) {
      Vec3 rgb{colors.At(v, 0), colors.At(v, 1), colors.At(v, 2)};
      for (int c = 0; c < 3; ++c) {
        if (!(rgb[c] >= 0)) {
          Fail(pointer, "colour " + std::to_string(v) + " has a negative component " + std::to_string(rgb[c]),
               "colours in [0, 1]");
        }
      }
      result.push_back(rgb);
    }
    return result;
  }

  // A primitive's skin: JOINTS_0/WEIGHTS_0 (and _1 for 8 influences), each vertex's weights
  // divided by their sum (refused when it is further than kWeightSumTolerance from 1), and
  // only the joints that move some vertex of the primitive, renumbered in the skin's order.
  Skin BindPrimitive(const SkinJoints& joints, size_t node, const tinygltf::Primitive& primitive,
                     const std::string& pointer, size_t vertices) const {
    struct Set {
      AccessorData joints, weights;
      int jointsAccessor, weightsAccessor;
    };
    std::vector<Set> sets;
    for (int set = 0; set < 2; ++set) {
      const std::string suffix = "_" + std::to_string(set);
      auto jointAttribute = primitive.attributes.find("JOINTS" + suffix);
      auto weightAttribute = primitive.attributes.find("WEIGHTS" + suffix);
      const bool hasJoints = jointAttribute != primitive.attributes.end();
      const bool hasWeights = weightAttribute != primitive.attributes.end();
      if (!hasJoints && !hasWeights && set == 1) break;
      if (!hasJoints || !hasWeights) {
        Fail(pointer + "/attributes",
             std::string(hasJoints ? "JOINTS" : hasWeights ? "WEIGHTS" : "neither JOINTS nor WEIGHTS") +
                 (hasJoints || hasWeights ? suffix + " alone" : suffix) + ", though node " + std::to_string(node) +
                 " binds the mesh to skin " + std::to_string(model_.nodes[node].skin),
             "JOINTS_0 and WEIGHTS_0 (and JOINTS_1 with WEIGHTS_1, or neither) on each primitive of a skinned mesh");
      }
      Set read{ReadAccessor(jointAttribute->second, pointer + "/attributes/JOINTS" + suffix, {TINYGLTF_TYPE_VEC4},
                            {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                            "a VEC4 accessor of UNSIGNED_BYTE or UNSIGNED_SHORT joint indices"),
               ReadAccessor(weightAttribute->second, pointer + "/attributes/WEIGHTS" + suffix, {TINYGLTF_TYPE_VEC4},
                            {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                             TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                            "a VEC4 accessor of FLOAT or normalized UNSIGNED_BYTE or UNSIGNED_SHORT weights"),
               jointAttribute->second, weightAttribute->second};
      for (const auto& [accessor, count] :
           {std::pair{read.jointsAccessor, read.joints.count}, std::pair{read.weightsAccessor, read.weights.count}}) {
        if (count != vertices) {
          Fail(Pointer("accessors", static_cast<size_t>(accessor)) + "/count",
               std::to_string(count) + " elements for a primitive of " + std::to_string(vertices) + " vertices",
               "one per vertex of the primitive");
        }
      }
      const tinygltf::Accessor& weightAccessor = model_.accessors[static_cast<size_t>(read.weightsAccessor)];
      if (weightAccessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !weightAccessor.normalized) {
        Fail(Pointer("accessors", static_cast<size_t>(read.weightsAccessor)) + "/normalized",
             "integer weights that are not normalized", "normalized: true on integer weights");
      }
      CheckFinite(read.weights, read.weightsAccessor, "vertex");
      sets.push_back(std::move(read));
    }
    Skin skin;
    skin.influencesPerVertex = static_cast<int>(4 * sets.size());
    const size_t k = static_cast<size_t>(skin.influencesPerVertex);
    skin.vertexJoints.resize(vertices * k);
    skin.vertexWeights.resize(vertices * k);
    std::vector<bool> used(joints.joints.size(), false);
    for (size_t v = 0; v < vertices; ++v) {
      double sum = 0;
      for (size_t i = 0; i < k; ++i) {
        const Set& set = sets[i / 4];
        const double joint = set.joints.At(v, static_cast<int>(i % 4));
        const double weight = set.weights.At(v, static_cast<int>(i % 4));
        if (!(joint < static_cast<double>(joints.joints.size()))) {
          Fail(Pointer("accessors", static_cast<size_t>(set.jointsAccessor)),
               "vertex " + std::to_string(v) + " names joint " + std::to_string(static_cast<uint64_t>(joint)) +
                   " (weight " + nlohmann::json(weight).dump() + ") of skin " +
                   std::to_string(model_.nodes[node].skin) + ", which has " + std::to_string(joints.joints.size()),
               "joint indices below the skin's joint count");
        }
        if (!(weight >= 0)) {
          Fail(Pointer("accessors", static_cast<size_t>(set.weightsAccessor)),
               "vertex " + std::to_string(v) + " has the weight " + nlohmann::json(weight).dump(), "weights >= 0");
        }
        skin.vertexWeights[v * k + i] = weight;
        sum += weight;
        if (weight == 0) continue;  // its joint does not move the vertex: index 0 will do
        used[static_cast<size_t>(joint)] = true;
        skin.vertexJoints[v * k + i] = static_cast<uint32_t>(joint);
      }
      if (!(std::fabs(sum - 1) <= kWeightSumTolerance)) {
        Fail(Pointer("accessors", static_cast<size_t>(sets[0].weightsAccessor)),
             "vertex " + std::to_string(v) + "'s weights sum to " + nlohmann::json(sum).dump() +
                 (sets.size() > 1 ? " (with WEIGHTS_1)" : ""),
             "weights summing to 1 within " + nlohmann::json(kWeightSumTolerance).dump() +
                 " (closer sums are divided by their sum)");
      }
      if (sum != 1) {
        for (size_t i = 0; i < k; ++i) skin.vertexWeights[v * k + i] /= sum;
      }
    }
    std::vector<uint32_t> renumbered(used.size(), 0);  // per joint of the skin, its index here
    for (size_t j = 0; j < used.size(); ++j) {
      if (!used[j]) continue;
      renumbered[j] = static_cast<uint32_t>(skin.joints.size());
      skin.joints.push_back(joints.joints[j]);
      skin.inverseBind.push_back(joints.inverseBind[j]);
    }
    for (size_t i = 0; i < skin.vertexJoints.size(); ++i) {
      skin.vertexJoints[i] = renumbered[skin.vertexJoints[i]];
    }
    return skin;
  }

  // The morph targets and skin of node i's primitive p, or none when it has neither.
  std::shared_ptr<const Deformation> PrimitiveDeformation(size_t node, const SkinJoints* skin,
                                                          const tinygltf::Primitive& primitive,
                                                          const std::string& pointer, const TriangleMesh& mesh) const {
    if (primitive.targets.empty() && skin == nullptr) return nullptr;
    auto deformation = std::make_shared<Deformation>();
    if (!primitive.targets.empty()) {
      deformation->hasMorph = true;
      deformation->morph = ReadMorphTargets(primitive, pointer, mesh);
      deformation->morph.weights = MorphWeights(node, primitive.targets.size());
    }
    if (skin != nullptr) {
      deformation->hasSkin = true;
      deformation->skin = BindPrimitive(*skin, node, primitive, pointer, mesh.vertices.size());
    }
    return deformation;
  }

  // ---- lights and camera ----------------------------------------------------------------

  void AddLights(Scene& scene) const {
    bool any = false;
    for (int node : order_) {
      const auto& source = model_.nodes[static_cast<size_t>(node)];
      auto extension = source.extensions.find("KHR_lights_punctual");
      if (extension == source.extensions.end() || !extension->second.Has("light")) continue;
      const std::string pointer = Pointer("nodes", static_cast<size_t>(node)) + "/extensions/KHR_lights_punctual/light";
      const tinygltf::Value& index = extension->second.Get("light");
      if (!index.IsInt() || index.GetNumberAsInt() < 0 ||
          static_cast<size_t>(index.GetNumberAsInt()) >= model_.lights.size()) {
        Fail(pointer, "no such light", "the index of a KHR_lights_punctual light");
      }
      const size_t lightIndex = static_cast<size_t>(index.GetNumberAsInt());
      const tinygltf::Light& light = model_.lights[lightIndex];
      const std::string lightPointer = "/extensions/KHR_lights_punctual/lights/" + std::to_string(lightIndex);
      std::vector<double> color = light.color.size() == 3 ? light.color : std::vector<double>{1, 1, 1};
      for (double v : {color[0], color[1], color[2], light.intensity}) {
        if (!(v >= 0 && v <= kMaxMagnitude))
          Fail(lightPointer, "a colour or intensity of " + std::to_string(v), "finite non-negative values");
      }
      Light out;
      if (light.type == "directional") {
        out.type = Light::Type::kDirectional;
        out.direction = AnimatedVec3::Constant({0, 0, -1});
      } else if (light.type == "point") {
        out.type = Light::Type::kPoint;
        out.position = AnimatedVec3::Constant({0, 0, 0});
      } else if (light.type == "spot") {
        // A spot shines down its node's -z; glTF's cone angles are radians from the axis.
        out.type = Light::Type::kSpot;
        out.position = AnimatedVec3::Constant({0, 0, 0});
        out.direction = AnimatedVec3::Constant({0, 0, -1});
        const double outer = light.spot.outerConeAngle * 180 / kPi, inner = light.spot.innerConeAngle * 180 / kPi;
        if (!(outer > 0 && outer <= 90)) {
          Fail(lightPointer + "/spot/outerConeAngle", std::to_string(light.spot.outerConeAngle), "an angle in (0, pi/2]");
        }
        if (!(inner >= 0 && inner < outer)) {
          Fail(lightPointer + "/spot/innerConeAngle", std::to_string(light.spot.innerConeAngle),
               "an angle in [0, outerConeAngle)");
        }
        out.outerConeDegrees = outer;
        out.innerConeDegrees = inner;
      } else {
        Fail(lightPointer + "/type", "type " + QuoteInput(light.type), "point, spot or directional");
      }
      // Photometric units taken one for one as the scene's radiometric ones (scene.md).
      out.intensity =
          AnimatedVec3::Constant({color[0] * light.intensity, color[1] * light.intensity, color[2] * light.intensity});
      out.motion = *motions_[static_cast<size_t>(node)];
      scene.lights.push_back(out);
      any = true;
    }
    if (!any) {
      Light light;
      light.type = Light::Type::kDirectional;
      light.direction = AnimatedVec3::Constant(kDefaultLightDirection);
      light.intensity = AnimatedVec3::Constant(Vec3{1, 1, 1});
      scene.lights.push_back(light);
    }
  }

  void AddCamera(Scene& scene) const {
    int chosenNode = -1;
    const std::string& wanted = options_.camera;
    for (int node : order_) {
      int camera = model_.nodes[static_cast<size_t>(node)].camera;
      if (camera < 0) continue;
      if (static_cast<size_t>(camera) >= model_.cameras.size()) {
        Fail(Pointer("nodes", static_cast<size_t>(node)) + "/camera",
             "camera " + std::to_string(camera) + " does not exist", "the index of a camera");
      }
      bool match = wanted.empty() || model_.nodes[static_cast<size_t>(node)].name == wanted ||
                   model_.cameras[static_cast<size_t>(camera)].name == wanted || std::to_string(camera) == wanted;
      // The first in node order, whatever order the depth-first walk met them.
      if (match && (chosenNode < 0 || node < chosenNode)) chosenNode = node;
    }
    if (chosenNode < 0 && !wanted.empty()) {
      Fail("/cameras", "no camera node named or numbered " + QuoteInput(wanted),
           "a camera's (or its node's) name, or its index");
    }
    if (chosenNode < 0) {
      FrameBounds(scene);
      return;
    }
    const size_t cameraIndex = static_cast<size_t>(model_.nodes[static_cast<size_t>(chosenNode)].camera);
    const tinygltf::Camera& camera = model_.cameras[cameraIndex];
    const std::string pointer = Pointer("cameras", cameraIndex);
    double degrees = 45;
    if (camera.type == "orthographic") {
      // ymag is half the view's height; the render size sets the width, as for yfov.
      const double ymag = camera.orthographic.ymag;
      if (!(ymag > 0 && ymag <= 5e8)) {
        Fail(pointer + "/orthographic/ymag", std::to_string(ymag), "a positive half height of the view");
      }
      scene.camera.orthographic = true;
      scene.camera.orthographicHeight = 2 * ymag;
    } else if (camera.type == "perspective") {
      degrees = camera.perspective.yfov * 180 / kPi;
      if (!(degrees > 0 && degrees < 180)) {
        Fail(pointer + "/perspective/yfov", std::to_string(camera.perspective.yfov) + " radians",
             "a field of view in (0, pi)");
      }
    } else {
      Fail(pointer + "/type", "type " + QuoteInput(camera.type), "perspective or orthographic");
    }
    // glTF cameras look down their node's -z with +y up; the node's motion carries them.
    scene.camera.position = AnimatedVec3::Constant({0, 0, 0});
    scene.camera.lookAt = AnimatedVec3::Constant({0, 0, -1});
    scene.camera.up = {0, 1, 0};
    scene.camera.verticalFovDegrees = degrees;
    scene.camera.rig = *motions_[static_cast<size_t>(chosenNode)];
  }

  // No camera in the file: one framing the shapes' bounds at frame 0, as for OBJ.
  void FrameBounds(Scene& scene) const {
    Vec3 low{kMaxMagnitude, kMaxMagnitude, kMaxMagnitude};
    Vec3 high{-kMaxMagnitude, -kMaxMagnitude, -kMaxMagnitude};
    for (const Shape& shape : scene.shapes) {
      Affine worldFromObject = shape.motion.WorldFromObject(0);  // the identity for a skinned mesh
      const std::vector<Vec3> vertices =
          shape.deformation ? Deform(shape.Mesh(), *shape.deformation, 0).positions : shape.Mesh().vertices;
      for (const Vec3& vertex : vertices) {
        Vec3 v = worldFromObject.Apply(vertex);
        for (int axis = 0; axis < 3; ++axis) {
          low[axis] = std::min(low[axis], v[axis]);
          high[axis] = std::max(high[axis], v[axis]);
        }
      }
    }
    if (scene.shapes.empty()) low = high = Vec3{};
    Vec3 center{(low.x + high.x) / 2, (low.y + high.y) / 2, (low.z + high.z) / 2};
    double radius = std::max(Norm(Sub(high, low)) / 2, 1e-3);
    double distance = kFramingMargin * radius / std::sin(kDefaultFovDegrees / 2 * kPi / 180);
    double length = Norm(kViewFrom);
    Vec3 position{center.x + kViewFrom.x / length * distance, center.y + kViewFrom.y / length * distance,
                  center.z + kViewFrom.z / length * distance};
    for (int axis = 0; axis < 3; ++axis) {
      if (!(std::fabs(position[axis]) <= kMaxMagnitude)) {
        Fail("", "the model spans " + std::to_string(radius * 2) + " units, too far to frame",
             "a model whose camera stays within 1e30 of the origin");
      }
    }
    scene.camera.position = AnimatedVec3::Constant(position);
    scene.camera.lookAt = AnimatedVec3::Constant(center);
    scene.camera.verticalFovDegrees = kDefaultFovDegrees;
  }

  const ImportInput& input_;
  const ImportOptions& options_;
  tinygltf::Model model_;
  gltf::EmbeddedData embedded_;  // while loading: the data URIs, decoded
  mutable uint64_t valueBytesRead_ = 0;  // by ReadAccessor, against kValueBytesPerBufferByte
  // Per glTF image that a material uses: its bytes and their hash (Texture::asset).
  mutable std::map<int, std::pair<std::shared_ptr<const std::string>, std::string>> imageBytes_;
  std::vector<int> materialIndex_;  // per glTF material, its index in the scene
  struct SharedPrimitive {
    std::string name;  // in Scene::meshes; empty for a primitive without area
    std::shared_ptr<const TriangleMesh> mesh;
  };
  std::map<std::pair<size_t, size_t>, SharedPrimitive> sharedPrimitives_;  // by (mesh, primitive)
  std::vector<int> parent_;         // per node, its parent or -1
  std::vector<bool> inScene_;
  std::vector<int> order_;  // the chosen scene's nodes, parents before children
  int animation_ = -1;
  int frameCount_ = 1;
  std::vector<std::shared_ptr<const Motion>> motions_;  // per node, its world motion
  std::vector<std::map<std::string, Channel>> channels_;  // per node, its channels by path
  std::map<size_t, SkinJoints> skins_;                    // by skin, once a node binds it
};

class GltfImporter : public SceneImporter {
 public:
  std::string Type() const override { return "gltf"; }
  std::vector<std::string> Extensions() const override { return {".gltf", ".glb"}; }

  // GLB's magic, or a JSON object naming "asset" (required in glTF, unknown to tcfarm JSON).
  // The key must be the top object's own: tcfarm JSON may use "asset" as a material's name.
  bool Sniff(std::string_view head) const override {
    if (head.substr(0, 4) == "glTF") return true;
    if (head.substr(0, 3) == "\xEF\xBB\xBF") head.remove_prefix(3);
    size_t first = head.find_first_not_of(" \t\r\n");
    if (first == std::string_view::npos || head[first] != '{') return false;
    int depth = 0;
    for (size_t i = first; i < head.size(); ++i) {
      char c = head[i];
      if (c == '{' || c == '[') {
        ++depth;
      } else if (c == '}' || c == ']') {
        if (--depth == 0) return false;
      } else if (c == '"') {
        size_t end = i + 1;
        while (end < head.size() && head[end] != '"') end += head[end] == '\\' ? 2 : 1;
        if (end >= head.size()) return false;
        std::string_view text = head.substr(i + 1, end - i - 1);
        size_t next = head.find_first_not_of(" \t\r\n", end + 1);
        if (depth == 1 && text == "asset" && next != std::string_view::npos && head[next] == ':') return true;
        i = end;
      }
    }
    return false;
  }

  Scene Import(const ImportInput& input) const override {
    Scene scene = GltfReader(input).Read();
    // Workers receive the scene as tcfarm JSON: what the parser would refuse (a camera's up
    // along its view at some frame, an animated scale through zero) is refused now.
    // The scene itself is returned, not the one read back, so that nodes keep sharing
    // their parents' motions.
    try {
      ParseScene(SerializeScene(scene));
    } catch (const SceneError& error) {
      FailInput("", input.displayName + ": the imported scene breaks a rule of the scene format: " + error.what(),
                "a glTF file whose scene the format can hold");
    }
    return scene;
  }
};

}  // namespace

std::unique_ptr<SceneImporter> MakeGltfImporter() { return std::make_unique<GltfImporter>(); }

// For tests: a strip or fan as triangles.
std::vector<std::array<uint32_t, 3>> GltfTriangles(const std::vector<uint32_t>& indices, int mode) {
  return GltfReader::Triangles(indices, mode);
}

}  // namespace tcfarm
