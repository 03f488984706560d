// For tests of the glTF importer: glTF documents built in memory (GltfBuilder), and the
// skinned strip the skin tests bend and spoil (SkinnedStrip).
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"
#include "tests/support/cpp/scene_test_support.h"

namespace tcfarm {

// A glTF document built in memory: one data-URI buffer that accessors are appended to.
class GltfBuilder {
 public:
  using json = nlohmann::json;

  GltfBuilder() {
    doc_ = {{"asset", {{"version", "2.0"}}},
            {"scene", 0},
            {"scenes", json::array({json{{"nodes", json::array()}}})},
            {"nodes", json::array()},
            {"meshes", json::array()},
            {"accessors", json::array()},
            {"bufferViews", json::array()},
            {"buffers", json::array()}};
  }
  json& doc() { return doc_; }

  static size_t Components(const std::string& type) {
    return type == "SCALAR" ? 1 : type == "MAT4" ? 16 : static_cast<size_t>(type[3] - '0');
  }
  // An accessor of floats ("SCALAR", "VEC2", "VEC3", "VEC4", "MAT4"), returning its index.
  int Floats(const std::vector<double>& values, const std::string& type) {
    std::string bytes;
    for (double v : values) {
      float f = static_cast<float>(v);
      bytes.append(reinterpret_cast<const char*>(&f), 4);
    }
    return Add(bytes, 5126, type, values.size() / Components(type));
  }
  // An accessor of integers of a component type (5121 unsigned byte, 5123 unsigned short).
  int Integers(const std::vector<int>& values, int componentType, const std::string& type, bool normalized = false) {
    std::string bytes;
    for (int v : values) {
      if (componentType == 5121) {
        bytes += static_cast<char>(static_cast<uint8_t>(v));
      } else {
        uint16_t u = static_cast<uint16_t>(v);
        bytes.append(reinterpret_cast<const char*>(&u), 2);
      }
    }
    int index = Add(bytes, componentType, type, values.size() / Components(type));
    if (normalized) doc_["accessors"][index]["normalized"] = true;
    return index;
  }
  int Indices(const std::vector<uint16_t>& values) {
    std::string bytes;
    for (uint16_t v : values) bytes.append(reinterpret_cast<const char*>(&v), 2);
    return Add(bytes, 5123, "SCALAR", values.size());
  }
  // A mesh of one primitive over `positions` (VEC3 floats), returning the mesh's index.
  int Mesh(const std::vector<double>& positions, const std::vector<uint16_t>& indices = {}, int mode = 4) {
    json primitive = {{"attributes", {{"POSITION", Floats(positions, "VEC3")}}}, {"mode", mode}};
    if (!indices.empty()) primitive["indices"] = Indices(indices);
    doc_["meshes"].push_back({{"primitives", json::array({primitive})}});
    return static_cast<int>(doc_["meshes"].size()) - 1;
  }
  int Node(json node, bool root) {
    doc_["nodes"].push_back(std::move(node));
    int index = static_cast<int>(doc_["nodes"].size()) - 1;
    if (root) doc_["scenes"][0]["nodes"].push_back(index);
    return index;
  }
  std::string Text() {
    json out = doc_;
    out["buffers"] = json::array(
        {{{"byteLength", buffer_.size()}, {"uri", "data:application/octet-stream;base64," + Base64(buffer_)}}});
    return out.dump();
  }
  // A channel of the first animation, with a sampler of its own.
  void Animate(int node, const std::string& path, int input, int output, const std::string& interpolation = "LINEAR") {
    if (!doc_.contains("animations")) {
      doc_["animations"] = json::array({json{{"channels", json::array()}, {"samplers", json::array()}}});
    }
    json& animation = doc_["animations"][0];
    animation["samplers"].push_back(json{{"input", input}, {"output", output}, {"interpolation", interpolation}});
    animation["channels"].push_back(
        json{{"sampler", animation["samplers"].size() - 1}, {"target", json{{"node", node}, {"path", path}}}});
  }
  Scene Import(const ImportOptions& options = {}) { return ImportSceneBytes(Text(), "gltf", std::nullopt, options); }

 private:
  int Add(const std::string& bytes, int componentType, const std::string& type, size_t count) {
    while (buffer_.size() % 4 != 0) buffer_ += '\0';
    doc_["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", buffer_.size()}, {"byteLength", bytes.size()}});
    buffer_ += bytes;
    doc_["accessors"].push_back({{"bufferView", doc_["bufferViews"].size() - 1},
                                 {"componentType", componentType},
                                 {"type", type},
                                 {"count", count}});
    return static_cast<int>(doc_["accessors"].size()) - 1;
  }

  json doc_;
  std::string buffer_;
};

// A strip of two quads up the y axis (x 0..1, y 0..2) bound to two joints: the bottom row
// to the hip at (0.5, 0, 0), the middle row half and half, the top row to the knee, 1 above
// the hip, which turns 90 degrees about z over one second. The mesh's node is moved by
// 100 along x, which glTF ignores for a skinned mesh.
struct SkinnedStrip {
  using json = nlohmann::json;
  GltfBuilder gltf;
  int joints, weights, inverseBind, meshNode, hip, knee;

  explicit SkinnedStrip(const std::vector<double>& vertexWeights = {1, 0, 0, 0, 1, 0, 0, 0, 0.5, 0.5, 0, 0,
                                                                     0.5, 0.5, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0}) {
    const std::vector<double> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
    int mesh = gltf.Mesh(positions, {0, 1, 2, 1, 3, 2, 2, 3, 4, 3, 5, 4});
    joints = gltf.Integers(std::vector<int>{0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0},
                           5123, "VEC4");
    weights = gltf.Floats(vertexWeights, "VEC4");
    json& attributes = gltf.doc()["meshes"][mesh]["primitives"][0]["attributes"];
    attributes["JOINTS_0"] = joints;
    attributes["WEIGHTS_0"] = weights;
    inverseBind = gltf.Floats({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -0.5, 0, 0, 1,  //
                               1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -0.5, -1, 0, 1},
                              "MAT4");
    meshNode = gltf.Node({{"mesh", mesh}, {"skin", 0}, {"translation", {100, 0, 0}}, {"name", "strip"}}, true);
    knee = gltf.Node({{"translation", {0, 1, 0}}, {"name", "knee"}}, false);
    hip = gltf.Node({{"translation", {0.5, 0, 0}}, {"children", {knee}}, {"name", "hip"}}, true);
    gltf.doc()["skins"] = json::array({json{{"joints", {hip, knee}}, {"inverseBindMatrices", inverseBind}}});
    const double s = std::sqrt(0.5);
    gltf.Animate(knee, "rotation", gltf.Floats({0, 1}, "SCALAR"), gltf.Floats({0, 0, 0, 1, 0, 0, s, s}, "VEC4"));
  }
};

}  // namespace tcfarm
