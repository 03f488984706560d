// Materials and textures: glTF's metallic-roughness model kept as it is (MetallicRoughness,
// proto/scene/material.h), with the KHR_materials extensions tcfarm implements.
#include "proto/scene/import/gltf/gltf_reader.h"

#include "proto/scene/import/gltf/file_access.h"
#include "proto/wire/content_hash.h"

namespace tcfarm::gltf {
double GltfReader::NumberIn(const tinygltf::ExtensionMap& extensions, const std::string& extension, const std::string& key,
                       double fallback) {
  const tinygltf::Value* object = ExtensionOf(extensions, extension);
  return object ? FactorIn(*object, key, fallback) : fallback;
}

double GltfReader::FactorIn(const tinygltf::Value& object, const std::string& key, double fallback) {
  if (!object.Has(key)) return fallback;
  const tinygltf::Value& value = object.Get(key);
  return value.IsNumber() ? value.GetNumberAsDouble() : fallback;
}

Material GltfReader::MapMaterial(const tinygltf::Material& source, size_t index) const {
  const std::string pointer = Pointer("materials", index);
  const auto& pbr = source.pbrMetallicRoughness;
  std::vector<double> base = pbr.baseColorFactor;
  if (base.size() != 4) base = {1, 1, 1, 1};
  for (double v : {base[0], base[1], base[2], base[3], pbr.metallicFactor, pbr.roughnessFactor}) {
    if (!(v >= 0 && v <= 1)) {
      Fail(pointer + "/pbrMetallicRoughness", "a factor of " + std::to_string(v), "factors in [0, 1]");
    }
  }
  MetallicRoughness m;
  m.baseColor = {base[0], base[1], base[2]};
  m.alpha = base[3];
  m.metallic = pbr.metallicFactor;
  m.roughness = pbr.roughnessFactor;
  const std::string pbrPointer = pointer + "/pbrMetallicRoughness";
  if (pbr.baseColorTexture.index >= 0) {
    m.baseColorTexture = MapSlot(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord,
                                 pbr.baseColorTexture.extensions, pbrPointer + "/baseColorTexture");
  }
  if (pbr.metallicRoughnessTexture.index >= 0) {
    m.metallicRoughnessTexture =
        MapSlot(pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord,
                pbr.metallicRoughnessTexture.extensions, pbrPointer + "/metallicRoughnessTexture");
  }
  if (source.normalTexture.index >= 0) {
    m.normalTexture = MapSlot(source.normalTexture.index, source.normalTexture.texCoord,
                              source.normalTexture.extensions, pointer + "/normalTexture");
    if (m.normalTexture) m.normalTexture->amount = std::clamp(source.normalTexture.scale, -scene_limits::kMaxNormalScale,
                                         scene_limits::kMaxNormalScale);
  }
  if (source.occlusionTexture.index >= 0) {
    m.occlusionTexture = MapSlot(source.occlusionTexture.index, source.occlusionTexture.texCoord,
                                 source.occlusionTexture.extensions, pointer + "/occlusionTexture");
    if (m.occlusionTexture) m.occlusionTexture->amount = std::clamp(source.occlusionTexture.strength, 0.0, 1.0);
  }
  if (source.emissiveTexture.index >= 0) {
    m.emissiveTexture = MapSlot(source.emissiveTexture.index, source.emissiveTexture.texCoord,
                                source.emissiveTexture.extensions, pointer + "/emissiveTexture");
  }
  if (source.emissiveFactor.size() == 3) {
    for (size_t c = 0; c < 3; ++c) {
      const double emitted = source.emissiveFactor[c];
      if (!(emitted >= 0 && emitted <= 1)) {
        Fail(pointer + "/emissiveFactor/" + std::to_string(c), std::to_string(emitted), "a factor in [0, 1]");
      }
    }
    m.emissive = {source.emissiveFactor[0], source.emissiveFactor[1], source.emissiveFactor[2]};
  }
  if (source.alphaMode == "MASK") m.alphaMode = MetallicRoughness::Alpha::kMask;
  if (source.alphaMode == "BLEND") m.alphaMode = MetallicRoughness::Alpha::kBlend;
  if (!(source.alphaCutoff >= 0 && source.alphaCutoff <= 1)) {
    Fail(pointer + "/alphaCutoff", std::to_string(source.alphaCutoff), "a cutoff in [0, 1]");
  }
  m.alphaCutoff = source.alphaCutoff;
  m.doubleSided = source.doubleSided;
  MapExtensions(source, pointer, m);
  Material material;
  material.model = m;
  return material;
}

void GltfReader::MapExtensions(const tinygltf::Material& source, const std::string& pointer,
                               MetallicRoughness& m) const {
  const std::string extensions = pointer + "/extensions/";
  auto checked = [&](const std::string& extension, const std::string& key, double value, double low, double high,
                     const std::string& expected) {
    if (!(value >= low && value <= high)) Fail(extensions + extension + "/" + key, std::to_string(value), expected);
    return value;
  };
  m.transmission = checked("KHR_materials_transmission", "transmissionFactor",
                           NumberIn(source.extensions, "KHR_materials_transmission", "transmissionFactor", 0), 0, 1,
                           "a factor in [0, 1]");
  // glTF allows ior 0 (a perfect mirror's f0 of 1); tcfarm's refraction needs [1, 10].
  const double ior = NumberIn(source.extensions, "KHR_materials_ior", "ior", 1.5);
  checked("KHR_materials_ior", "ior", ior, 0, 1e9, "an ior >= 1, or 0");
  m.ior = std::clamp(ior, scene_limits::kMinIndexOfRefraction, scene_limits::kMaxIndexOfRefraction);
  m.emissiveStrength = checked(
      "KHR_materials_emissive_strength", "emissiveStrength",
      NumberIn(source.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1), 0,
      scene_limits::kMaxEmissiveStrength, "a finite non-negative strength");
  m.unlit = ExtensionOf(source.extensions, "KHR_materials_unlit") != nullptr;
  if (const tinygltf::Value* specular = ExtensionOf(source.extensions, "KHR_materials_specular")) {
    m.specular = checked("KHR_materials_specular", "specularFactor", FactorIn(*specular, "specularFactor", 1), 0, 1,
                         "a factor in [0, 1]");
    if (specular->Has("specularColorFactor") && specular->Get("specularColorFactor").IsArray() &&
        specular->Get("specularColorFactor").ArrayLen() == 3) {
      double rgb[3];
      for (int c = 0; c < 3; ++c) {
        const tinygltf::Value& v = specular->Get("specularColorFactor").Get(c);
        rgb[c] = checked("KHR_materials_specular", "specularColorFactor/" + std::to_string(c),
                         v.IsNumber() ? v.GetNumberAsDouble() : -1, 0, scene_limits::kMaxMagnitude,
                         "a finite non-negative factor");
      }
      m.specularColor = {rgb[0], rgb[1], rgb[2]};
    }
    for (const char* textureKey : {"specularTexture", "specularColorTexture"}) {
      if (specular->Has(textureKey)) Warn("texture_left_out", extensions + "KHR_materials_specular/" + textureKey, "the texture is left out; its factor is used");
    }
  }
  if (const tinygltf::Value* clearcoat = ExtensionOf(source.extensions, "KHR_materials_clearcoat")) {
    MapClearcoat(*clearcoat, extensions + "KHR_materials_clearcoat", m);
  }
}

void GltfReader::MapClearcoat(const tinygltf::Value& extension, const std::string& pointer,
                              MetallicRoughness& m) const {
  auto factor = [&](const char* key) {
    const double value = FactorIn(extension, key, 0);
    if (!(value >= 0 && value <= 1)) Fail(pointer + "/" + key, std::to_string(value), "a factor in [0, 1]");
    return value;
  };
  m.clearcoat = factor("clearcoatFactor");
  m.clearcoatRoughness = factor("clearcoatRoughnessFactor");
  m.clearcoatTexture = MapExtensionSlot(extension, "clearcoatTexture", pointer);
  m.clearcoatRoughnessTexture = MapExtensionSlot(extension, "clearcoatRoughnessTexture", pointer);
  m.clearcoatNormalTexture = MapExtensionSlot(extension, "clearcoatNormalTexture", pointer);
  if (m.clearcoatNormalTexture) {
    const double scale = FactorIn(extension.Get("clearcoatNormalTexture"), "scale", 1);
    m.clearcoatNormalTexture->amount = std::clamp(scale, -scene_limits::kMaxNormalScale, scene_limits::kMaxNormalScale);
  }
}

std::optional<TextureSlot> GltfReader::MapExtensionSlot(const tinygltf::Value& extension, const std::string& key,
                                                        const std::string& pointer) const {
  if (!extension.Has(key)) return std::nullopt;
  const tinygltf::Value& info = extension.Get(key);
  const std::string at = pointer + "/" + key;
  if (!info.IsObject() || !info.Has("index") || !info.Get("index").IsInt()) {
    Fail(at, "not a texture reference", "an object with a texture's \"index\"");
  }
  const int texCoord = info.Has("texCoord") && info.Get("texCoord").IsInt() ? info.Get("texCoord").GetNumberAsInt() : 0;
  // The reference's own extensions (KHR_texture_transform), as tinygltf gives a TextureInfo's.
  tinygltf::ExtensionMap nested;
  if (info.Has("extensions") && info.Get("extensions").IsObject()) {
    const tinygltf::Value& extensions = info.Get("extensions");
    for (const std::string& name : extensions.Keys()) nested[name] = extensions.Get(name);
  }
  return MapSlot(info.Get("index").GetNumberAsInt(), texCoord, nested, at);
}

Texture::Wrap GltfReader::WrapOf(int code) {
  if (code == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return Texture::Wrap::kClampToEdge;
  if (code == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return Texture::Wrap::kMirroredRepeat;
  return Texture::Wrap::kRepeat;
}

std::optional<TextureSlot> GltfReader::MapSlot(int index, int texCoord, const tinygltf::ExtensionMap& extensions,
                                               const std::string& pointer) const {
  std::optional<Texture> texture = MapTexture(index, pointer);
  if (!texture) return std::nullopt;
  TextureSlot slot;
  slot.texture = std::move(*texture);
  slot.texCoord = texCoord;
  if (const tinygltf::Value* transform = ExtensionOf(extensions, "KHR_texture_transform")) {
    const std::string at = pointer + "/extensions/KHR_texture_transform";
    auto pair = [&](const char* key, std::array<double, 2> fallback) {
      if (!transform->Has(key)) return fallback;
      const tinygltf::Value& v = transform->Get(key);
      if (!v.IsArray() || v.ArrayLen() != 2 || !v.Get(0).IsNumber() || !v.Get(1).IsNumber()) {
        Fail(at + "/" + key, "not a pair of numbers", "an array of 2 finite numbers");
      }
      std::array<double, 2> result{v.Get(0).GetNumberAsDouble(), v.Get(1).GetNumberAsDouble()};
      if (!std::isfinite(result[0]) || !std::isfinite(result[1])) Fail(at + "/" + key, "a number that is not finite", "finite numbers");
      return result;
    };
    slot.offset = pair("offset", {0, 0});
    slot.scale = pair("scale", {1, 1});
    slot.rotation = FactorIn(*transform, "rotation", 0);
    if (!std::isfinite(slot.rotation)) Fail(at + "/rotation", "a number that is not finite", "a rotation in radians");
    if (transform->Has("texCoord") && transform->Get("texCoord").IsInt()) slot.texCoord = transform->Get("texCoord").GetNumberAsInt();
  }
  if (slot.texCoord != 0 && slot.texCoord != 1) {
    Warn("texcoord_set_missing", pointer + "/texCoord", "TEXCOORD_" + std::to_string(slot.texCoord) + " is not kept; the texture is sampled with TEXCOORD_0");
    slot.texCoord = 0;
  }
  return slot;
}

std::optional<GltfReader::ImageSource> GltfReader::ImageSourceOf(const tinygltf::Texture& texture,
                                                                 const std::string& texturePointer) const {
  if (const tinygltf::Value* webp = ExtensionOf(texture.extensions, "EXT_texture_webp")) {
    const std::string at = texturePointer + "/extensions/EXT_texture_webp";
    if (webp->Has("source")) return ImageSource{static_cast<int64_t>(WholeNumberIn(*webp, "source", at)), at + "/source"};
  }
  if (ExtensionOf(texture.extensions, "KHR_texture_basisu") != nullptr) {
    const std::string at = texturePointer + "/extensions/KHR_texture_basisu";
    if (texture.source < 0) {
      Warn("texture_left_out", at, "KTX2 (Basis Universal) images are not decoded and the texture has no other source; it is left out");
      return std::nullopt;
    }
    Warn("extension_not_implemented", at, "KTX2 (Basis Universal) images are not decoded; the texture's own source is used");
  }
  return ImageSource{texture.source, texturePointer + "/source"};
}

std::optional<Texture> GltfReader::MapTexture(int index, const std::string& pointer) const {
  if (static_cast<size_t>(index) >= model_.textures.size()) {
    Fail(pointer + "/index", "texture " + std::to_string(index) + " does not exist",
         "an index below the file's " + std::to_string(model_.textures.size()) + " textures");
  }
  const tinygltf::Texture& source = model_.textures[static_cast<size_t>(index)];
  const std::string texturePointer = Pointer("textures", static_cast<size_t>(index));
  const std::optional<ImageSource> found = ImageSourceOf(source, texturePointer);
  if (!found) return std::nullopt;
  const ImageSource& imageSource = *found;
  if (imageSource.index < 0 || static_cast<size_t>(imageSource.index) >= model_.images.size()) {
    Fail(imageSource.pointer, "image " + std::to_string(imageSource.index) + " does not exist",
         "an index below the file's " + std::to_string(model_.images.size()) + " images");
  }
  const int imageIndex = static_cast<int>(imageSource.index);
  const tinygltf::Image& image = model_.images[static_cast<size_t>(imageIndex)];
  if (image.image.empty()) {
    Fail(Pointer("images", static_cast<size_t>(imageIndex)), "the image holds no bytes",
         "a PNG, JPEG or WebP image in a file, a data URI or a buffer view");
  }
  Texture texture;
  // One copy of an image however many materials use it: a short JSON must not multiply a large image.
  auto& shared = imageBytes_[imageIndex];
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
                           : input_.displayName + " at " + Pointer("images", static_cast<size_t>(imageIndex));
  if (source.sampler >= 0) {
    if (static_cast<size_t>(source.sampler) >= model_.samplers.size()) {
      Fail(texturePointer + "/sampler", "sampler " + std::to_string(source.sampler) + " does not exist",
           "an index below the file's " + std::to_string(model_.samplers.size()) + " samplers");
    }
    const tinygltf::Sampler& sampler = model_.samplers[static_cast<size_t>(source.sampler)];
    texture.wrapS = WrapOf(sampler.wrapS);
    texture.wrapT = WrapOf(sampler.wrapT);
    if (sampler.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST) texture.filter = Texture::Filter::kNearest;
    // A minification filter without mip levels: the full image, aliasing as the file asks.
    if (sampler.minFilter == TINYGLTF_TEXTURE_FILTER_NEAREST || sampler.minFilter == TINYGLTF_TEXTURE_FILTER_LINEAR) {
      texture.mipmaps = false;
    } else if (sampler.minFilter >= 0 && sampler.minFilter != TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR) {
      // Mip levels are always blended linearly, and texels filtered as magFilter says.
      Warn("sampler_filter_approximated", Pointer("samplers", static_cast<size_t>(source.sampler)) + "/minFilter",
           "minification filter " + std::to_string(sampler.minFilter) +
               " is approximated: mip levels are blended linearly and texels filtered as magFilter says");
    }
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
  // A primitive without a material gets glTF's default: white, metallic and rough.
  scene.materials.assign(1, Material{});
  scene.materials[0].name = "default";
  scene.materials[0].model = MetallicRoughness{};
  materialIndex_.assign(model_.materials.size(), 0);
  for (const auto& [name, index] : byName) {
    Material material = MapMaterial(model_.materials[index], index);
    material.name = name;
    materialIndex_[index] = static_cast<int>(scene.materials.size());
    scene.materials.push_back(material);
  }
}

}  // namespace tcfarm::gltf
