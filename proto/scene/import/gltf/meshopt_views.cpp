// EXT_meshopt_compression: buffer views whose bytes are decoded, at import, from a compressed
// range of another buffer (meshoptimizer's vertex and index codecs and its filters).
#include <meshoptimizer.h>

#include "proto/scene/import/gltf/gltf_reader.h"

namespace tcfarm::gltf {
namespace {

constexpr const char* kMeshopt = "EXT_meshopt_compression";

bool IsFallbackBuffer(const nlohmann::json& buffer) {
  if (!buffer.is_object() || buffer.contains("uri")) return false;
  const nlohmann::json::json_pointer flag("/extensions/" + std::string(kMeshopt) + "/fallback");
  return buffer.contains(flag) && buffer.at(flag) == true;
}

}  // namespace

void GltfReader::StandInForFallbackBuffers() {
  if (embedded_.json.find("fallback") == std::string::npos) return;  // spares most files a second parse
  nlohmann::json document = nlohmann::json::parse(embedded_.json, nullptr, false);
  if (!document.is_object() || !document.contains("buffers") || !document["buffers"].is_array()) return;
  nlohmann::json& buffers = document["buffers"];
  // In a GLB, buffer 0 without a uri is the BIN chunk, never a placeholder.
  for (size_t i = IsBinary() ? 1 : 0; i < buffers.size(); ++i) {
    if (!IsFallbackBuffer(buffers[i])) continue;
    buffers[i]["uri"] = EmbeddedName(embedded_.bytes.size());
    buffers[i]["byteLength"] = 1;
    embedded_.bytes.push_back({0});
    fallbackBuffers_.insert(i);
  }
  if (!fallbackBuffers_.empty()) embedded_.json = document.dump();
}

void GltfReader::DecodeMeshoptViews() {
  for (size_t i = 0; i < model_.bufferViews.size(); ++i) {
    if (const tinygltf::Value* extension = ExtensionOf(model_.bufferViews[i].extensions, kMeshopt)) {
      DecodeMeshoptView(i, *extension);
    }
  }
  // Decoded views now lie in buffers of their own: what still refers to a placeholder reads nothing.
  for (size_t i = 0; i < model_.bufferViews.size(); ++i) {
    const int buffer = model_.bufferViews[i].buffer;
    if (buffer >= 0 && fallbackBuffers_.count(static_cast<size_t>(buffer))) {
      Fail(Pointer("bufferViews", i) + "/buffer",
           "buffer " + std::to_string(buffer) + " is an EXT_meshopt_compression fallback without data",
           "only buffer views with EXT_meshopt_compression referring to a fallback buffer");
    }
  }
}

void GltfReader::DecodeMeshoptView(size_t index, const tinygltf::Value& extension) {
  const std::string at = Pointer("bufferViews", index) + "/extensions/" + kMeshopt;
  tinygltf::BufferView& view = model_.bufferViews[index];
  const uint64_t source = WholeNumberIn(extension, "buffer", at);
  const uint64_t offset = WholeNumberIn(extension, "byteOffset", at, 0);
  const uint64_t length = WholeNumberIn(extension, "byteLength", at);
  const uint64_t stride = WholeNumberIn(extension, "byteStride", at);
  const uint64_t count = WholeNumberIn(extension, "count", at);
  const std::string mode = StringIn(extension, "mode", at, "");
  const std::string filter = StringIn(extension, "filter", at, "NONE");
  if (source >= model_.buffers.size() || fallbackBuffers_.count(source)) {
    Fail(at + "/buffer", "buffer " + std::to_string(source) + (source < model_.buffers.size() ? " is a fallback" : " does not exist"),
         "the index of a buffer holding the compressed data");
  }
  const std::vector<unsigned char>& data = model_.buffers[source].data;
  if (offset > data.size() || length > data.size() - offset) {
    Fail(at, std::to_string(length) + " bytes from byte " + std::to_string(offset) + " of buffer " +
                 std::to_string(source) + " (" + std::to_string(data.size()) + " bytes)",
         "compressed data inside its buffer");
  }
  const bool attributes = mode == "ATTRIBUTES";
  if (!attributes && mode != "TRIANGLES" && mode != "INDICES") {
    Fail(at + "/mode", "mode " + QuoteInput(mode), "ATTRIBUTES, TRIANGLES or INDICES");
  }
  if (attributes ? (stride == 0 || stride > 256 || stride % 4 != 0) : (stride != 2 && stride != 4)) {
    Fail(at + "/byteStride", "a stride of " + std::to_string(stride) + " for mode " + mode,
         attributes ? "a multiple of 4 up to 256 for ATTRIBUTES" : "2 or 4 for indices");
  }
  if (mode == "TRIANGLES" && count % 3 != 0) {
    Fail(at + "/count", std::to_string(count) + " indices", "whole triangles: a multiple of 3");
  }
  const bool filterFits = filter == "NONE" || (attributes && ((filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) ||
                                                               (filter == "QUATERNION" && stride == 8) ||
                                                               (filter == "EXPONENTIAL" && stride % 4 == 0)));
  if (!filterFits) {
    Fail(at + "/filter", "filter " + QuoteInput(filter) + " on " + mode + " of stride " + std::to_string(stride),
         "NONE; for ATTRIBUTES also OCTAHEDRAL (stride 4 or 8), QUATERNION (8) or EXPONENTIAL (a multiple of 4)");
  }
  if (count > kMaxAccessorCount) {
    Fail(at + "/count", std::to_string(count) + " elements",
         "at most " + std::to_string(kMaxAccessorCount) + " elements in one buffer view");
  }
  if ((view.byteStride != 0 && view.byteStride != stride) || view.byteLength != count * stride) {
    Fail(Pointer("bufferViews", index),
         "a view of " + std::to_string(view.byteLength) + " bytes, stride " + std::to_string(view.byteStride) +
             ", over compressed data of " + std::to_string(count) + " elements of " + std::to_string(stride) + " bytes",
         "byteLength = count * byteStride of its EXT_meshopt_compression, and the same byteStride");
  }
  ChargeDecodedBytes(count * stride, at);
  std::vector<unsigned char> decoded(count * stride);
  const unsigned char* compressed = data.data() + offset;
  const int error = attributes          ? meshopt_decodeVertexBuffer(decoded.data(), count, stride, compressed, length)
                    : mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(decoded.data(), count, stride, compressed, length)
                                          : meshopt_decodeIndexSequence(decoded.data(), count, stride, compressed, length);
  if (error != 0) {
    Fail(at, "its " + std::to_string(length) + " bytes do not decode as meshopt " + mode + " data (error " +
                 std::to_string(error) + ")",
         "data meshoptimizer's encoder wrote for " + std::to_string(count) + " elements of " + std::to_string(stride) +
             " bytes");
  }
  if (filter == "OCTAHEDRAL") meshopt_decodeFilterOct(decoded.data(), count, stride);
  if (filter == "QUATERNION") meshopt_decodeFilterQuat(decoded.data(), count, stride);
  if (filter == "EXPONENTIAL") meshopt_decodeFilterExp(decoded.data(), count, stride);
  view.buffer = AddDecodedBuffer(std::move(decoded));
  view.byteOffset = 0;
}

int GltfReader::AddDecodedBuffer(std::vector<unsigned char> bytes) {
  tinygltf::Buffer buffer;
  buffer.data = std::move(bytes);
  model_.buffers.push_back(std::move(buffer));
  return static_cast<int>(model_.buffers.size() - 1);
}

}  // namespace tcfarm::gltf
