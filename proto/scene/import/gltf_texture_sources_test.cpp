// Which image a glTF texture shows: its own source (PNG or JPEG), EXT_texture_webp's WebP
// source before it, and KHR_texture_basisu, whose KTX2 images are not decoded: refused when
// required, else the texture's own source with a warning, or no texture with a warning.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"
#include "tests/support/cpp/scene_test_support.h"

namespace tcfarm {
namespace {

using nlohmann::json;

// Not decoded at import: only their first bytes (the signature workers read) matter here.
const std::string kPng = "\x89PNG\r\n\x1a\n a PNG";
const std::string kJpeg = "\xff\xd8\xff\xe0 a JPEG";
const std::string kWebp("RIFF\x10\0\0\0WEBPVP8L a WebP", 21);
const std::string kKtx2 = "\xabKTX 20\xbb\r\n\x1a\n a KTX2";

// One textured triangle; its images are `images` (MIME type, bytes) and texture 0 is `texture`.
json TexturedTriangle(const std::vector<std::pair<std::string, std::string>>& images, const json& texture) {
  json document = json::parse(R"({
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": 3,
                   "min": [0, 0, 0], "max": [1, 1, 0]},
                  {"bufferView": 0, "componentType": 5126, "type": "VEC2", "count": 3}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "buffers": [{"byteLength": 36,
                 "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
    "materials": [{"name": "printed", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]})");
  for (const auto& [mime, bytes] : images) {
    document["images"].push_back({{"uri", "data:" + mime + ";base64," + Base64(bytes)}});
  }
  document["textures"] = json::array({texture});
  return document;
}

Scene Import(const json& document) { return ImportSceneBytes(document.dump(), "gltf"); }

const MetallicRoughness& Printed(const Scene& scene) {
  for (const Material& material : scene.materials) {
    if (material.name == "printed") return material.As<MetallicRoughness>();
  }
  throw std::runtime_error("no material \"printed\"");
}

std::string BaseColorBytes(const Scene& scene) {
  const auto& slot = Printed(scene).baseColorTexture;
  return slot && slot->texture.bytes ? *slot->texture.bytes : "";
}

std::vector<std::string> WarningsWithCode(const Scene& scene, const std::string& code) {
  std::vector<std::string> lines;
  for (const ImportWarning& warning : scene.importWarnings) {
    if (warning.code == code) lines.push_back(warning.pointer + ": " + warning.message);
  }
  return lines;
}

TEST(GltfTextureSourcesTest, PngAndJpegImagesReachTheTextureAsTheirBytes) {
  EXPECT_EQ(BaseColorBytes(Import(TexturedTriangle({{"image/png", kPng}}, {{"source", 0}}))), kPng);
  EXPECT_EQ(BaseColorBytes(Import(TexturedTriangle({{"image/jpeg", kJpeg}}, {{"source", 0}}))), kJpeg);
}

TEST(GltfTextureSourcesTest, WebpSourceIsPreferredToTheFallback) {
  json document = TexturedTriangle({{"image/png", kPng}, {"image/webp", kWebp}},
                                   {{"source", 0}, {"extensions", {{"EXT_texture_webp", {{"source", 1}}}}}});
  document["extensionsUsed"] = {"EXT_texture_webp"};
  EXPECT_EQ(BaseColorBytes(Import(document)), kWebp);
  // Required, with no fallback: the WebP is all there is, and it is enough.
  document["textures"][0].erase("source");
  document["extensionsRequired"] = {"EXT_texture_webp"};
  const Scene scene = Import(document);
  EXPECT_EQ(BaseColorBytes(scene), kWebp);
  EXPECT_TRUE(WarningsWithCode(scene, "extension_not_implemented").empty());
}

TEST(GltfTextureSourcesTest, AMissingWebpSourceIsRefusedAtItsIndex) {
  json document = TexturedTriangle({{"image/webp", kWebp}}, {{"extensions", {{"EXT_texture_webp", {{"source", 3}}}}}});
  const std::string what = ErrorOf([&] { Import(document); });
  EXPECT_NE(what.find("/textures/0/extensions/EXT_texture_webp/source: the gltf scene: image 3 does not exist"),
            std::string::npos)
      << what;
}

TEST(GltfTextureSourcesTest, RequiredBasisuIsRefused) {
  json document = TexturedTriangle({{"image/ktx2", kKtx2}}, {{"extensions", {{"KHR_texture_basisu", {{"source", 0}}}}}});
  document["extensionsUsed"] = {"KHR_texture_basisu"};
  document["extensionsRequired"] = {"KHR_texture_basisu"};
  const std::string what = ErrorOf([&] { Import(document); });
  EXPECT_NE(what.find("/extensionsRequired/0"), std::string::npos) << what;
  EXPECT_NE(what.find("requires extension \"KHR_texture_basisu\", which this importer does not implement"),
            std::string::npos)
      << what;
}

TEST(GltfTextureSourcesTest, OptionalBasisuFallsBackToTheTexturesOwnSourceSaid) {
  json document = TexturedTriangle({{"image/ktx2", kKtx2}, {"image/png", kPng}},
                                   {{"source", 1}, {"extensions", {{"KHR_texture_basisu", {{"source", 0}}}}}});
  document["extensionsUsed"] = {"KHR_texture_basisu"};
  const Scene scene = Import(document);
  EXPECT_EQ(BaseColorBytes(scene), kPng);
  const std::vector<std::string> said = WarningsWithCode(scene, "extension_not_implemented");
  ASSERT_EQ(said.size(), 2u);  // the extension, and the texture it concerns
  EXPECT_EQ(said[1],
            "/textures/0/extensions/KHR_texture_basisu: KTX2 (Basis Universal) images are not decoded; the "
            "texture's own source is used");
}

TEST(GltfTextureSourcesTest, OptionalBasisuWithoutFallbackLeavesTheTextureOutSaid) {
  json document = TexturedTriangle({{"image/ktx2", kKtx2}}, {{"extensions", {{"KHR_texture_basisu", {{"source", 0}}}}}});
  document["extensionsUsed"] = {"KHR_texture_basisu"};
  const Scene scene = Import(document);
  EXPECT_FALSE(Printed(scene).baseColorTexture.has_value());
  const std::vector<std::string> said = WarningsWithCode(scene, "texture_left_out");
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find("/textures/0/extensions/KHR_texture_basisu: KTX2"), std::string::npos) << said[0];
}

}  // namespace
}  // namespace tcfarm
