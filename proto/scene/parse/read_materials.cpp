// Reading a scene's materials and their textures.
#include "proto/scene/parse/scene_reader.h"

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

Material SceneReader::ReadMaterial(const Node& node) {
  ExpectObject(node, {"diffuse", "specular", "shininess", "reflectivity", "transparency", "ior", "diffuse_texture",
                      "emission", "pbr"},
               "a material");
  Material material;
  if (node.Has("pbr")) {
    for (const char* phong : {"diffuse", "specular", "shininess", "reflectivity", "transparency", "ior",
                              "diffuse_texture", "emission"}) {
      if (node.Has(phong)) {
        Fail(node.MemberPointer(phong), "a Phong parameter beside a \"pbr\" block",
             "either Phong's parameters or one \"pbr\" block (glTF's metallic-roughness model), not both");
      }
    }
    material.pbr = ReadPbr(node.Member("pbr"));
    return material;
  }
  if (node.Has("diffuse_texture")) material.diffuseTexture = ReadTexture(node.Member("diffuse_texture"));
  if (node.Has("diffuse")) material.diffuse = ReadColour(node.Member("diffuse"));
  if (node.Has("emission")) material.emission = ReadColour(node.Member("emission"));
  if (node.Has("specular")) material.specular = ReadColour(node.Member("specular"));
  if (node.Has("shininess")) {
    material.shininess = ReadNonNegative(node.Member("shininess"), "a non-negative Phong exponent");
  }
  if (node.Has("reflectivity")) {
    material.reflectivity = ReadInRange(node.Member("reflectivity"), 0, 1, "a number in [0, 1]");
  }
  if (node.Has("transparency")) {
    material.transparency = ReadInRange(node.Member("transparency"), 0, 1, "a number in [0, 1]");
  }
  if (node.Has("ior")) {
    material.indexOfRefraction = ReadInRange(node.Member("ior"), 1, 10, "an index of refraction in [1, 10]");
  }
  if (material.reflectivity + material.transparency > 1) {
    Fail(node.MemberPointer(node.Has("transparency") ? "transparency" : "reflectivity"),
         "reflectivity " + FormatNumber(material.reflectivity) + " + transparency " +
             FormatNumber(material.transparency) + " exceeds 1",
         "reflectivity + transparency <= 1 (they share the light that is not absorbed)");
  }
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
