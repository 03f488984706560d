#include "proto/scene/import/gltf/json_types.h"

#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

namespace tcfarm::gltf {

std::string Pointer(const std::string& collection, size_t index) {
  return "/" + collection + "/" + std::to_string(index);
}

namespace {

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

}  // namespace

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

}  // namespace tcfarm::gltf
