// Materials and textures: glTF's PBR mapped onto the Whitted model (proto/scene.md).
#include "proto/scene/import/gltf/gltf_reader.h"

#include "proto/scene/import/gltf/file_access.h"
#include "proto/wire/content_hash.h"

namespace tcfarm::gltf {

double GltfReader::NumberIn(const tinygltf::ExtensionMap& extensions, const std::string& extension, const std::string& key,
                       double fallback) {
  auto found = extensions.find(extension);
  if (found == extensions.end() || !found->second.IsObject() || !found->second.Has(key)) return fallback;
  const tinygltf::Value& value = found->second.Get(key);
  return value.IsNumber() ? value.GetNumberAsDouble() : fallback;
}

Material GltfReader::MapMaterial(const tinygltf::Material& source, size_t index) const {
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

Texture::Wrap GltfReader::WrapOf(int code) {
  if (code == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return Texture::Wrap::kClampToEdge;
  if (code == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return Texture::Wrap::kMirroredRepeat;
  return Texture::Wrap::kRepeat;
}

Texture GltfReader::MapTexture(const tinygltf::TextureInfo& info, const std::string& pointer) const {
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

void GltfReader::AddMaterials(Scene& scene) {
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

}  // namespace tcfarm::gltf
