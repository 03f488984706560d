// KHR_draco_mesh_compression: a primitive's attributes and indices decoded, at import, from
// the Draco mesh in its extension's buffer view, into buffers the primitive's accessors then
// read (the accessors keep their count, type and component type, as the extension says).
#include "proto/draco/draco_codec.h"
#include "proto/scene/import/gltf/gltf_reader.h"
#include "proto/scene/import/import_budget.h"

namespace tcfarm::gltf {
namespace {

constexpr const char* kDraco = "KHR_draco_mesh_compression";

// The decoder's name for a glTF component type; false for one Draco cannot fill.
bool DracoComponent(int componentType, draco_codec::Component* component) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: *component = draco_codec::Component::kInt8; return true;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: *component = draco_codec::Component::kUint8; return true;
    case TINYGLTF_COMPONENT_TYPE_SHORT: *component = draco_codec::Component::kInt16; return true;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: *component = draco_codec::Component::kUint16; return true;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: *component = draco_codec::Component::kUint32; return true;
    case TINYGLTF_COMPONENT_TYPE_FLOAT: *component = draco_codec::Component::kFloat; return true;
    default: return false;
  }
}

// What libdraco holds while it decodes, per element the accessors declare: an attribute
// component as its integer prediction and its value (4 bytes each), a triangle corner as
// its point index and the corner table's links (4 ints).
constexpr uint64_t kDracoBytesPerComponent = 8;
constexpr uint64_t kDracoBytesPerCorner = 16;

uint64_t DeclaredElements(const tinygltf::Model& model, int accessor, bool perComponent) {
  if (accessor < 0 || static_cast<size_t>(accessor) >= model.accessors.size()) return 0;  // refused later
  const tinygltf::Accessor& declared = model.accessors[static_cast<size_t>(accessor)];
  const int components = perComponent ? tinygltf::GetNumComponentsInType(static_cast<uint32_t>(declared.type)) : 1;
  return std::min<uint64_t>(declared.count, kMaxAccessorCount) * static_cast<uint64_t>(std::max(components, 1));
}

// The memory decoding a primitive's Draco mesh takes, by the counts its accessors declare;
// the decoded counts are held to them afterwards (DracoAccessor).
uint64_t DeclaredDracoBytes(const tinygltf::Model& model, const tinygltf::Primitive& primitive) {
  uint64_t bytes = kDracoBytesPerCorner * DeclaredElements(model, primitive.indices, false);
  for (const auto& [name, accessor] : primitive.attributes) {
    bytes += kDracoBytesPerComponent * DeclaredElements(model, accessor, true);
  }
  return bytes;
}

}  // namespace

void GltfReader::StandInForDracoIndexViews() {
  if (embedded_.json.find(kDraco) == std::string::npos) return;  // spares most files a second parse
  nlohmann::json document = nlohmann::json::parse(embedded_.json, nullptr, false);
  if (!document.is_object() || !document.contains("meshes") || !document["meshes"].is_array() ||
      !document.contains("accessors") || !document["accessors"].is_array()) {
    return;  // PreCheck and tinygltf say what is wrong
  }
  nlohmann::json& accessors = document["accessors"];
  bool changed = false;
  for (const nlohmann::json& mesh : document["meshes"]) {
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
    for (const nlohmann::json& primitive : mesh["primitives"]) {
      const nlohmann::json::json_pointer view("/extensions/" + std::string(kDraco) + "/bufferView");
      if (!primitive.is_object() || !primitive.contains(view) || !primitive.contains("indices")) continue;
      const nlohmann::json& indices = primitive["indices"];
      if (!indices.is_number_unsigned() || indices.get<uint64_t>() >= accessors.size()) continue;
      nlohmann::json& accessor = accessors[indices.get<size_t>()];
      if (!accessor.is_object() || accessor.contains("bufferView")) continue;
      accessor["bufferView"] = primitive.at(view);
      changed = true;
    }
  }
  if (changed) embedded_.json = document.dump();
}

void GltfReader::DecodeDracoPrimitives() {
  for (size_t m = 0; m < model_.meshes.size(); ++m) {
    for (size_t p = 0; p < model_.meshes[m].primitives.size(); ++p) {
      tinygltf::Primitive& primitive = model_.meshes[m].primitives[p];
      // Points are never rendered (AddShapes skips them): nothing to decode.
      if (primitive.mode == TINYGLTF_MODE_POINTS || !ExtensionOf(primitive.extensions, kDraco)) continue;
      DecodeDracoPrimitive(primitive, Pointer("meshes", m) + "/primitives/" + std::to_string(p));
    }
  }
}

void GltfReader::DecodeDracoPrimitive(tinygltf::Primitive& primitive, const std::string& pointer) {
  const tinygltf::Value& extension = *ExtensionOf(primitive.extensions, kDraco);
  const std::string at = pointer + "/extensions/" + kDraco;
  if (primitive.mode >= 0 && primitive.mode != TINYGLTF_MODE_TRIANGLES) {
    Fail(pointer + "/mode", "mode " + std::to_string(primitive.mode) + " with Draco compression",
         "TRIANGLES (4) or POINTS (0), the modes Draco encodes");
  }
  if (!extension.Has("attributes") || !extension.Get("attributes").IsObject()) {
    Fail(at + "/attributes", "no object of attribute ids", "an object naming each attribute's Draco id");
  }
  const uint64_t viewIndex = WholeNumberIn(extension, "bufferView", at);
  if (viewIndex >= model_.bufferViews.size()) {
    Fail(at + "/bufferView", "buffer view " + std::to_string(viewIndex) + " does not exist",
         "the index of a buffer view");
  }
  const size_t length = model_.bufferViews[viewIndex].byteLength;
  const ViewElements view = InView(static_cast<int>(viewIndex), 0, length, 1, false, at);
  const ImportReservation decoding = ReserveImportMemory(DeclaredDracoBytes(model_, primitive));
  const draco_codec::DecodedMesh mesh(view.base, length);
  if (!mesh.Error().empty()) {
    Fail(at, "its " + std::to_string(length) + " bytes do not decode as a Draco mesh: " + mesh.Error(),
         "a triangle mesh Draco's encoder wrote");
  }
  const size_t points = mesh.Points();
  if (mesh.Faces() > kMaxTriangles || points > kMaxAccessorCount) {
    Fail(at, "a decoded mesh of " + std::to_string(mesh.Faces()) + " triangles and " + std::to_string(points) +
                 " vertices",
         "at most " + std::to_string(kMaxTriangles) + " triangles and " + std::to_string(kMaxAccessorCount) +
             " vertices");
  }
  const tinygltf::Value& ids = extension.Get("attributes");
  for (const std::string& name : ids.Keys()) {
    auto accessor = primitive.attributes.find(name);
    if (accessor == primitive.attributes.end()) continue;  // nothing reads it
    const uint64_t id = WholeNumberIn(ids, name, at + "/attributes");
    const int components = id <= std::numeric_limits<uint32_t>::max() ? mesh.Components(static_cast<uint32_t>(id)) : 0;
    if (components == 0) {
      Fail(at + "/attributes/" + name, "Draco attribute id " + std::to_string(id) + ", which the mesh lacks",
           "the id of an attribute of the decoded mesh");
    }
    WriteDracoAttribute(accessor->second, mesh, static_cast<uint32_t>(id), at + "/attributes/" + name);
  }
  WriteDracoIndices(primitive.indices, mesh, at);
}

tinygltf::Accessor& GltfReader::DracoAccessor(int index, size_t count, const std::string& at) {
  if (index < 0 || static_cast<size_t>(index) >= model_.accessors.size()) {
    Fail(at, "accessor " + std::to_string(index) + " does not exist", "the index of an accessor");
  }
  const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
  if (!dracoAccessors_.insert(index).second) {
    Fail(pointer, "the decoded output of two Draco attributes", "an accessor of its own for each decoded attribute");
  }
  tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
  if (accessor.count != count) {
    Fail(pointer + "/count", std::to_string(accessor.count) + " elements where the Draco mesh decodes to " +
                                 std::to_string(count),
         "the count of the decoded data");
  }
  return accessor;
}

void GltfReader::PointAccessorAt(tinygltf::Accessor& accessor, std::vector<unsigned char> bytes) {
  tinygltf::BufferView view;
  view.byteLength = bytes.size();
  view.buffer = AddDecodedBuffer(std::move(bytes));
  model_.bufferViews.push_back(std::move(view));
  accessor.bufferView = static_cast<int>(model_.bufferViews.size() - 1);
  accessor.byteOffset = 0;
}

void GltfReader::WriteDracoAttribute(int index, const draco_codec::DecodedMesh& mesh, uint32_t id,
                                     const std::string& at) {
  const size_t points = mesh.Points();
  tinygltf::Accessor& accessor = DracoAccessor(index, points, at);
  const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
  const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(accessor.type));
  const int componentSize = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(accessor.componentType));
  draco_codec::Component component{};
  if (components < 1 || componentSize < 1 || components != mesh.Components(id) ||
      !DracoComponent(accessor.componentType, &component)) {
    Fail(pointer, TypeName(accessor.type) + " of " + ComponentTypeName(accessor.componentType) + " for a Draco attribute of " +
                      std::to_string(mesh.Components(id)) + " components",
         "an accessor with as many components as its Draco attribute");
  }
  const size_t elementSize = static_cast<size_t>(components) * static_cast<size_t>(componentSize);
  ChargeDecodedBytes(points * elementSize, at);
  std::vector<unsigned char> bytes(points * elementSize);
  const size_t written = mesh.WriteValues(id, component, bytes.data());
  if (written < points) {
    Fail(at, "the decoded value of vertex " + std::to_string(written) + " does not fit " +
                 ComponentTypeName(accessor.componentType),
         "decoded values the accessor's component type holds");
  }
  PointAccessorAt(accessor, std::move(bytes));
}

void GltfReader::WriteDracoIndices(int index, const draco_codec::DecodedMesh& mesh, const std::string& at) {
  if (index < 0) Fail(at, "a Draco primitive without indices", "indices, which the decoded triangles fill");
  tinygltf::Accessor& accessor = DracoAccessor(index, 3 * mesh.Faces(), at);
  const int size = accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                   : accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                   : accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                        : 0;
  const uint64_t largest = size == 4 ? 0xFFFFFFFFu : (uint64_t{1} << (8 * size)) - 1;
  if (size == 0 || accessor.type != TINYGLTF_TYPE_SCALAR || (mesh.Points() > 0 && mesh.Points() - 1 > largest)) {
    Fail(Pointer("accessors", static_cast<size_t>(index)),
         TypeName(accessor.type) + " of " + ComponentTypeName(accessor.componentType) + " for the indices of " +
             std::to_string(mesh.Points()) + " decoded vertices",
         "a SCALAR accessor of unsigned indices wide enough for every vertex");
  }
  ChargeDecodedBytes(3 * static_cast<uint64_t>(mesh.Faces()) * static_cast<uint64_t>(size), at);
  std::vector<unsigned char> bytes(3 * mesh.Faces() * static_cast<size_t>(size));
  mesh.WriteFaces(size, bytes.data());
  PointAccessorAt(accessor, std::move(bytes));
}

}  // namespace tcfarm::gltf
