// Reading a scene's materials and their textures.
#include "proto/scene/parse/scene_reader.h"

#include "proto/scene/materials/material_format.h"
#include "proto/wire/content_hash.h"

namespace tcfarm::scene_parse {

std::vector<Material> SceneReader::ReadMaterials(const Node& root, std::vector<Material> base) {
  std::vector<Material> materials = std::move(base);
  if (materials.empty()) {
    materials.push_back(Material{});
    materials[0].name = kDefaultMaterial;
  }
  for (size_t i = 0; i < materials.size(); ++i) materialIndex_[materials[i].name] = static_cast<int>(i);
  if (!root.Has("materials")) return materials;
  Node node = root.Member("materials");
  if (!node.value.is_object()) FailType(node, "an object mapping material names to materials");
  for (const auto& entry : node.value.items()) {
    Material material = ReadMaterial(node.Member(entry.key()));
    material.name = entry.key();
    // A user "default" replaces the built-in one, so a written scene reads back the same;
    // a material named like an imported one replaces it.
    if (auto known = materialIndex_.find(material.name); known != materialIndex_.end()) {
      materials[static_cast<size_t>(known->second)] = material;
    } else {
      materialIndex_[material.name] = static_cast<int>(materials.size());
      materials.push_back(material);
    }
  }
  return materials;
}

// The model whose keys the material names (the list's first, Phong, when it names none);
// naming two models' keys is an error.
Material SceneReader::ReadMaterial(const Node& node) {
  std::vector<std::string> keys;
  for (const MaterialFormat* format : MaterialFormats()) keys.insert(keys.end(), format->Keys().begin(), format->Keys().end());
  ExpectObject(node, keys, "a material");
  const MaterialFormat* chosen = nullptr;
  std::string chosenKey;
  for (const MaterialFormat* format : MaterialFormats()) {
    for (const std::string& key : format->Keys()) {
      if (!node.Has(key)) continue;
      if (chosen && chosen != format) {
        Fail(node.MemberPointer(chosenKey), std::string(chosen->OneKey()) + " beside " + format->OneKey(),
             std::string("either ") + chosen->AllKeys() + " or " + format->AllKeys() + ", not both");
      }
      if (!chosen) chosen = format, chosenKey = key;
    }
  }
  Material material;
  (chosen ? chosen : MaterialFormats().front())->Read(*this, node, material);
  return material;
}

Texture SceneReader::ReadTexture(const Node& node, const std::vector<std::string>& moreKeys) {
  const std::string expected =
      "a texture {\"image\": file or \"asset\": SHA-256, \"wrap_s\", \"wrap_t\", \"filter\", \"mipmaps\"}";
  std::vector<std::string> keys{"image", "asset", "wrap_s", "wrap_t", "filter", "mipmaps"};
  keys.insert(keys.end(), moreKeys.begin(), moreKeys.end());
  ExpectObject(node, keys, expected);
  if (node.Has("image") == node.Has("asset")) {
    Fail(node.pointer, node.Has("image") ? "both an image and an asset" : "neither an image nor an asset",
         "exactly one of \"image\" (a file inside the scene folder) and \"asset\" (the SHA-256 of an image the farm holds)");
  }
  Texture texture;
  if (node.Has("asset")) {
    Node asset = node.Member("asset");
    texture.asset = ReadString(asset, "the SHA-256 of an image file, 64 lowercase hex characters");
    if (!wire::IsSha256Hex(texture.asset)) {
      Fail(asset.pointer, Quote(texture.asset) + " is not a SHA-256", "64 lowercase hex characters");
    }
  } else {
    ReadTextureFile(node.Member("image"), texture);
  }
  const std::string wrapExpected = "\"repeat\", \"clamp_to_edge\" or \"mirrored_repeat\"";
  for (const char* key : {"wrap_s", "wrap_t"}) {
    if (!node.Has(key)) continue;
    Node wrap = node.Member(key);
    const std::string name = ReadString(wrap, wrapExpected);
    Texture::Wrap mode = name == "repeat"          ? Texture::Wrap::kRepeat
                         : name == "clamp_to_edge" ? Texture::Wrap::kClampToEdge
                         : name == "mirrored_repeat" ? Texture::Wrap::kMirroredRepeat
                                                   : (Fail(wrap.pointer, "unknown wrap mode " + Quote(name), wrapExpected),
                                                      Texture::Wrap::kRepeat);
    (std::string(key) == "wrap_s" ? texture.wrapS : texture.wrapT) = mode;
  }
  if (node.Has("filter")) {
    Node filter = node.Member("filter");
    const std::string name = ReadString(filter, "\"linear\" or \"nearest\"");
    if (name != "linear" && name != "nearest") Fail(filter.pointer, "unknown filter " + Quote(name), "\"linear\" or \"nearest\"");
    texture.filter = name == "nearest" ? Texture::Filter::kNearest : Texture::Filter::kLinear;
  }
  if (node.Has("mipmaps")) {
    Node mipmaps = node.Member("mipmaps");
    if (!mipmaps.value.is_boolean()) FailType(mipmaps, "true or false");
    texture.mipmaps = mipmaps.value.get<bool>();
  }
  return texture;
}

void SceneReader::ReadTextureFile(const Node& image, Texture& texture) {
  texture.image = ReadString(image, "a PNG or JPEG file inside the scene folder");
  if (!baseDirectory_) {
    Fail(image.pointer, "texture image " + Quote(texture.image) + " cannot be resolved: the scene was submitted without a folder",
         "an image uploaded with the scene (tcfarm submit uploads the files a scene names), or {\"asset\": its SHA-256}");
  }
  texture.file = ResolveInsideFolder(*baseDirectory_, texture.image, image.pointer, "texture image");
  std::error_code error;
  if (!std::filesystem::is_regular_file(texture.file, error)) {
    Fail(image.pointer, "cannot read texture image " + Quote(texture.image), "a readable image file inside the scene folder");
  }
}

}  // namespace tcfarm::scene_parse
