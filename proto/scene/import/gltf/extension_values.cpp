// Extension objects: tinygltf keeps them as Values, unchecked; their properties are read here
// with the pointer of a bad one.
#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {

const tinygltf::Value* GltfReader::ExtensionOf(const tinygltf::ExtensionMap& extensions, const std::string& name) {
  auto found = extensions.find(name);
  return found != extensions.end() && found->second.IsObject() ? &found->second : nullptr;
}

uint64_t GltfReader::WholeNumberIn(const tinygltf::Value& object, const std::string& key, const std::string& pointer,
                                   std::optional<uint64_t> fallback) const {
  // Doubles hold every whole number up to 2^53 exactly; no count or offset comes near it.
  constexpr double kLargest = 9007199254740992.0;
  if (!object.Has(key)) {
    if (fallback) return *fallback;
    Fail(pointer, "no " + key, "a " + key);
  }
  const tinygltf::Value& value = object.Get(key);
  const double number = value.IsNumber() ? value.GetNumberAsDouble() : -1;
  if (!(number >= 0 && number <= kLargest && number == std::floor(number))) {
    Fail(pointer + "/" + key, value.IsNumber() ? std::to_string(number) : "a value that is not a number",
         "a whole number >= 0");
  }
  return static_cast<uint64_t>(number);
}

std::string GltfReader::StringIn(const tinygltf::Value& object, const std::string& key, const std::string& pointer,
                                 const std::string& fallback) const {
  if (!object.Has(key)) return fallback;
  const tinygltf::Value& value = object.Get(key);
  if (!value.IsString()) Fail(pointer + "/" + key, "a value that is not a string", "a string");
  return value.Get<std::string>();
}

}  // namespace tcfarm::gltf
