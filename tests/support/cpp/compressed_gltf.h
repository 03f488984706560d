// glTF files of one UV sphere (positions, normals, texture coordinates, vertex colours,
// 32-bit indices), written plain and compressed by Draco's and meshoptimizer's own encoders,
// for the importer's tests, tests/gltf's render comparison and tests/bench's import figures.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include "proto/draco/draco_codec.h"
#include "tests/support/cpp/scene_test_support.h"

namespace tcfarm::compressed_gltf {

struct Sphere {
  std::vector<float> positions, normals, uvs;  // 3, 3 and 2 per vertex
  std::vector<uint8_t> colors;                  // RGBA per vertex
  std::vector<uint32_t> indices;                // 3 per triangle
  size_t Vertices() const { return positions.size() / 3; }
};

// 2 * rings * segments triangles (those at the poles without area), a seam of doubled vertices.
inline Sphere MakeSphere(int rings, int segments) {
  constexpr double kPi = 3.14159265358979323846;
  Sphere s;
  for (int r = 0; r <= rings; ++r) {
    for (int g = 0; g <= segments; ++g) {
      const double theta = kPi * r / rings, phi = 2 * kPi * g / segments;
      const float n[3] = {static_cast<float>(std::sin(theta) * std::cos(phi)), static_cast<float>(std::cos(theta)),
                          static_cast<float>(std::sin(theta) * std::sin(phi))};
      s.positions.insert(s.positions.end(), {n[0], n[1], n[2]});
      s.normals.insert(s.normals.end(), {n[0], n[1], n[2]});
      s.uvs.insert(s.uvs.end(), {static_cast<float>(g) / segments, static_cast<float>(r) / rings});
      s.colors.insert(s.colors.end(), {static_cast<uint8_t>(255 * r / rings), static_cast<uint8_t>(255 * g / segments),
                                       128, 255});
    }
  }
  const auto at = [&](int r, int g) { return static_cast<uint32_t>(r * (segments + 1) + g); };
  for (int r = 0; r < rings; ++r) {
    for (int g = 0; g < segments; ++g) {
      s.indices.insert(s.indices.end(), {at(r, g), at(r, g + 1), at(r + 1, g)});
      s.indices.insert(s.indices.end(), {at(r, g + 1), at(r + 1, g + 1), at(r + 1, g)});
    }
  }
  return s;
}

template <typename T>
std::string BytesOf(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

// The parts every variant shares: one node placing mesh 0, one material, accessors 0..4
// (POSITION, NORMAL, TEXCOORD_0, COLOR_0, indices) without their buffer views.
inline nlohmann::json Skeleton(const Sphere& s) {
  using nlohmann::json;
  const size_t n = s.Vertices();
  const auto accessor = [](int componentType, const char* type, size_t count) {
    return json{{"componentType", componentType}, {"type", type}, {"count", count}};
  };
  json gltf = {{"asset", {{"version", "2.0"}}},
               {"scene", 0},
               {"scenes", {{{"nodes", {0}}}}},
               {"nodes", {{{"name", "sphere"}, {"mesh", 0}}}},
               {"materials", {{{"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.6, 0.4, 1}}}}}}},
               {"meshes",
                {{{"primitives",
                   {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}, {"COLOR_0", 3}}},
                     {"indices", 4},
                     {"material", 0}}}}}}},
               {"accessors",
                {accessor(5126, "VEC3", n), accessor(5126, "VEC3", n), accessor(5126, "VEC2", n),
                 accessor(5121, "VEC4", n), accessor(5125, "SCALAR", s.indices.size())}}};
  gltf["accessors"][0]["min"] = {-1, -1, -1};
  gltf["accessors"][0]["max"] = {1, 1, 1};
  gltf["accessors"][3]["normalized"] = true;
  return gltf;
}

inline std::string DataUri(const std::string& bytes) {
  return "data:application/octet-stream;base64," + Base64(bytes);
}

// The attribute streams in accessor order, then the indices.
inline std::vector<std::string> Streams(const Sphere& s) {
  return {BytesOf(s.positions), BytesOf(s.normals), BytesOf(s.uvs), BytesOf(s.colors), BytesOf(s.indices)};
}

inline nlohmann::json PlainGltf(const Sphere& s) {
  nlohmann::json gltf = Skeleton(s);
  std::string buffer;
  const std::vector<std::string> streams = Streams(s);
  for (size_t i = 0; i < streams.size(); ++i) {
    gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", buffer.size()}, {"byteLength", streams[i].size()}});
    gltf["accessors"][i]["bufferView"] = i;
    buffer += streams[i];
  }
  gltf["buffers"] = {{{"byteLength", buffer.size()}, {"uri", DataUri(buffer)}}};
  return gltf;
}

using DracoOptions = draco_codec::Encoding;

inline std::string DracoBytes(const Sphere& s, const DracoOptions& options, std::vector<int>* ids) {
  using draco_codec::Component;
  using draco_codec::Meaning;
  return draco_codec::EncodeMesh(s.Vertices(),
                                 {{Meaning::kPosition, 3, Component::kFloat, false, s.positions.data()},
                                  {Meaning::kNormal, 3, Component::kFloat, false, s.normals.data()},
                                  {Meaning::kTexCoord, 2, Component::kFloat, false, s.uvs.data()},
                                  {Meaning::kColor, 4, Component::kUint8, true, s.colors.data()}},
                                 s.indices, options, ids);
}

// The sphere's file around Draco bytes whose attributes have unique ids `ids` (in accessor order).
inline nlohmann::json WithDraco(const Sphere& s, const std::string& bytes, const std::vector<int>& ids) {
  nlohmann::json gltf = Skeleton(s);
  gltf["buffers"] = {{{"byteLength", bytes.size()}, {"uri", DataUri(bytes)}}};
  gltf["bufferViews"] = {{{"buffer", 0}, {"byteLength", bytes.size()}}};
  gltf["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"] = {
      {"bufferView", 0},
      {"attributes", {{"POSITION", ids[0]}, {"NORMAL", ids[1]}, {"TEXCOORD_0", ids[2]}, {"COLOR_0", ids[3]}}}};
  gltf["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  gltf["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  return gltf;
}

inline nlohmann::json DracoGltf(const Sphere& s, const DracoOptions& options = {}) {
  std::vector<int> ids;
  const std::string bytes = DracoBytes(s, options, &ids);
  return WithDraco(s, bytes, ids);
}

// EXT_meshopt_compression over every stream, with a fallback buffer that has no data. With
// `filters`, normals are octahedral (4 bytes: KHR_mesh_quantization's normalized BYTE) and
// texture coordinates exponential (15-bit mantissas): lossy, as those filters are.
inline nlohmann::json MeshoptGltf(const Sphere& s, bool filters = false) {
  nlohmann::json gltf = Skeleton(s);
  std::vector<std::string> streams = Streams(s);
  std::vector<size_t> strides = {12, 12, 8, 4, 4};
  std::vector<std::string> filterNames(5, "NONE");
  const size_t n = s.Vertices();
  if (filters) {
    std::vector<float> normals4;
    for (size_t v = 0; v < n; ++v) {
      normals4.insert(normals4.end(), {s.normals[3 * v], s.normals[3 * v + 1], s.normals[3 * v + 2], 1.0f});
    }
    streams[1].assign(4 * n, '\0');
    meshopt_encodeFilterOct(streams[1].data(), n, 4, 8, normals4.data());
    strides[1] = 4;
    filterNames[1] = "OCTAHEDRAL";
    gltf["accessors"][1]["componentType"] = 5120;
    gltf["accessors"][1]["normalized"] = true;
    meshopt_encodeFilterExp(streams[2].data(), n, 8, 15, s.uvs.data());
    filterNames[2] = "EXPONENTIAL";
    gltf["extensionsUsed"].push_back("KHR_mesh_quantization");
    gltf["extensionsRequired"].push_back("KHR_mesh_quantization");
  }
  std::string compressed;
  size_t fallbackBytes = 0;
  for (size_t i = 0; i < streams.size(); ++i) {
    const bool indices = i == 4;
    const size_t count = indices ? s.indices.size() : n;
    std::vector<unsigned char> out(indices ? meshopt_encodeIndexBufferBound(count, n)
                                           : meshopt_encodeVertexBufferBound(count, strides[i]));
    const size_t size = indices ? meshopt_encodeIndexBuffer(out.data(), out.size(), s.indices.data(), count)
                                : meshopt_encodeVertexBuffer(out.data(), out.size(), streams[i].data(), count, strides[i]);
    nlohmann::json view = {{"buffer", 1}, {"byteOffset", fallbackBytes}, {"byteLength", count * strides[i]}};
    if (!indices) view["byteStride"] = strides[i];
    view["extensions"]["EXT_meshopt_compression"] = {
        {"buffer", 0},      {"byteOffset", compressed.size()}, {"byteLength", size},
        {"byteStride", strides[i]}, {"count", count}, {"mode", indices ? "TRIANGLES" : "ATTRIBUTES"},
        {"filter", filterNames[i]}};
    gltf["bufferViews"].push_back(view);
    gltf["accessors"][i]["bufferView"] = i;
    compressed.append(reinterpret_cast<const char*>(out.data()), size);
    compressed.append((4 - compressed.size() % 4) % 4, '\0');
    fallbackBytes += count * strides[i];
  }
  gltf["buffers"] = {{{"byteLength", compressed.size()}, {"uri", DataUri(compressed)}},
                     {{"byteLength", fallbackBytes}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}};
  gltf["extensionsUsed"].push_back("EXT_meshopt_compression");
  gltf["extensionsRequired"].push_back("EXT_meshopt_compression");
  return gltf;
}

// The sphere with its triangles' corners in the order meshopt's index codec gives them back
// (it may rotate a triangle, abc as bca): the plain twin a meshopt file decodes to exactly.
inline Sphere WithMeshoptIndexOrder(Sphere s) {
  std::vector<unsigned char> encoded(meshopt_encodeIndexBufferBound(s.indices.size(), s.Vertices()));
  encoded.resize(meshopt_encodeIndexBuffer(encoded.data(), encoded.size(), s.indices.data(), s.indices.size()));
  if (meshopt_decodeIndexBuffer(s.indices.data(), s.indices.size(), encoded.data(), encoded.size()) != 0) {
    throw std::runtime_error("meshopt: the indices do not decode");
  }
  return s;
}

// RFC 4648 Base64 decoded (what Base64 writes; anything else is not checked).
inline std::string FromBase64(const std::string& text) {
  static const std::string kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  uint32_t bits = 0;
  int count = 0;
  for (const char c : text) {
    const size_t value = kAlphabet.find(c);
    if (value == std::string::npos) continue;  // padding
    bits = bits << 6 | static_cast<uint32_t>(value);
    if ((count += 6) >= 8) out += static_cast<char>((bits >> (count -= 8)) & 0xFF);
  }
  return out;
}

// `gltf` as a GLB: buffer 0's data URI becomes the BIN chunk (other buffers stay as they are).
inline std::string Glb(nlohmann::json gltf) {
  nlohmann::json& buffer = gltf["buffers"][0];
  std::string binary = FromBase64(buffer["uri"].get<std::string>().substr(buffer["uri"].get<std::string>().find(',') + 1));
  buffer.erase("uri");
  std::string text = gltf.dump();
  text.append((4 - text.size() % 4) % 4, ' ');
  binary.append((4 - binary.size() % 4) % 4, '\0');
  const auto word = [](size_t value) {
    const uint32_t v = static_cast<uint32_t>(value);
    return std::string{static_cast<char>(v & 0xFF), static_cast<char>(v >> 8 & 0xFF), static_cast<char>(v >> 16 & 0xFF),
                       static_cast<char>(v >> 24)};
  };
  return "glTF" + word(2) + word(12 + 8 + text.size() + 8 + binary.size()) + word(text.size()) + "JSON" + text +
         word(binary.size()) + std::string("BIN\0", 4) + binary;
}

}  // namespace tcfarm::compressed_gltf
