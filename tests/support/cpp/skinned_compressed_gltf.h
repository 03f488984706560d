// compressed_gltf.h's sphere skinned: two joints at its centre, the upper one bending 30
// degrees about z over its one-second animation, each vertex weighted to it by its height
// ((y + 1) / 2), the rest to the root. Written plain and with the skin's JOINTS_0 (unsigned
// bytes) and WEIGHTS_0 (floats) inside the Draco mesh as generic attributes, as Draco-compressed
// characters carry them.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "tests/support/cpp/compressed_gltf.h"

namespace tcfarm::compressed_gltf {

struct Skin {
  std::vector<uint8_t> joints;  // 4 per vertex
  std::vector<float> weights;   // 4 per vertex
};

inline Skin BendSkin(const Sphere& s) {
  Skin skin;
  for (size_t v = 0; v < s.Vertices(); ++v) {
    const float upper = (s.positions[3 * v + 1] + 1) / 2;
    skin.joints.insert(skin.joints.end(), {0, 1, 0, 0});
    skin.weights.insert(skin.weights.end(), {1 - upper, upper, 0, 0});
  }
  return skin;
}

// The joints (nodes 1 and 2), skin and animation, with their keys in a buffer of their own;
// JOINTS_0 and WEIGHTS_0 are accessors 5 and 6, given buffer views there when `skin` is
// set (the plain file), left without (Draco fills them) when it is null.
inline void AddBend(nlohmann::json& gltf, const Sphere& s, const Skin* skin) {
  using nlohmann::json;
  const double half = 15 * 3.14159265358979323846 / 180;
  const std::vector<float> times = {0, 1};
  const std::vector<float> rotations = {0, 0, 0, 1, 0, 0, static_cast<float>(std::sin(half)),
                                        static_cast<float>(std::cos(half))};
  std::string data = BytesOf(times) + BytesOf(rotations);
  const size_t buffer = gltf["buffers"].size(), firstView = gltf["bufferViews"].size();
  gltf["bufferViews"].push_back({{"buffer", buffer}, {"byteOffset", 0}, {"byteLength", 8}});
  gltf["bufferViews"].push_back({{"buffer", buffer}, {"byteOffset", 8}, {"byteLength", 32}});
  const size_t n = s.Vertices();
  gltf["accessors"].push_back({{"componentType", 5121}, {"type", "VEC4"}, {"count", n}});
  gltf["accessors"].push_back({{"componentType", 5126}, {"type", "VEC4"}, {"count", n}});
  gltf["accessors"].push_back(
      {{"bufferView", firstView}, {"componentType", 5126}, {"type", "SCALAR"}, {"count", 2}, {"min", {0}}, {"max", {1}}});
  gltf["accessors"].push_back({{"bufferView", firstView + 1}, {"componentType", 5126}, {"type", "VEC4"}, {"count", 2}});
  if (skin != nullptr) {
    const std::string streams[2] = {BytesOf(skin->joints), BytesOf(skin->weights)};
    for (size_t i = 0; i < 2; ++i) {
      gltf["accessors"][5 + i]["bufferView"] = gltf["bufferViews"].size();
      gltf["bufferViews"].push_back({{"buffer", buffer}, {"byteOffset", data.size()}, {"byteLength", streams[i].size()}});
      data += streams[i];
    }
  }
  gltf["buffers"].push_back({{"byteLength", data.size()}, {"uri", DataUri(data)}});
  gltf["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = 5;
  gltf["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] = 6;
  gltf["nodes"][0]["skin"] = 0;
  gltf["nodes"].push_back({{"name", "root"}, {"children", {2}}});
  gltf["nodes"].push_back({{"name", "bend"}});
  gltf["scenes"][0]["nodes"] = {0, 1};
  gltf["skins"] = {{{"joints", {1, 2}}}};
  const json channel = {{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}};
  const json sampler = {{"input", 7}, {"output", 8}};
  gltf["animations"] = json::array({{{"channels", json::array({channel})}, {"samplers", json::array({sampler})}}});
}

inline nlohmann::json SkinnedPlainGltf(const Sphere& s) {
  nlohmann::json gltf = PlainGltf(s);
  const Skin skin = BendSkin(s);
  AddBend(gltf, s, &skin);
  return gltf;
}

inline nlohmann::json SkinnedDracoGltf(const Sphere& s) {
  using draco_codec::Component;
  using draco_codec::Meaning;
  const Skin skin = BendSkin(s);
  std::vector<int> ids;
  const std::string bytes = draco_codec::EncodeMesh(
      s.Vertices(),
      {{Meaning::kPosition, 3, Component::kFloat, false, s.positions.data()},
       {Meaning::kNormal, 3, Component::kFloat, false, s.normals.data()},
       {Meaning::kTexCoord, 2, Component::kFloat, false, s.uvs.data()},
       {Meaning::kColor, 4, Component::kUint8, true, s.colors.data()},
       {Meaning::kGeneric, 4, Component::kUint8, false, skin.joints.data()},
       {Meaning::kGeneric, 4, Component::kFloat, false, skin.weights.data()}},
      s.indices, {}, &ids);
  nlohmann::json gltf = WithDraco(s, bytes, ids);
  AddBend(gltf, s, nullptr);
  nlohmann::json& attributes = gltf["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"];
  attributes["JOINTS_0"] = ids[4];
  attributes["WEIGHTS_0"] = ids[5];
  return gltf;
}

}  // namespace tcfarm::compressed_gltf
