// Accessors: their elements as doubles, every read checked against its buffer view and buffer.
#include "proto/scene/import/gltf/gltf_reader.h"

#include "proto/scene/import/import_budget.h"

namespace tcfarm::gltf {

GltfReader::AccessorData GltfReader::ReadAccessor(int index, const std::string& referencedAt, const std::vector<int>& types,
                          const std::vector<int>& componentTypes, const std::string& expected) const {
  if (index < 0 || static_cast<size_t>(index) >= model_.accessors.size()) {
    Fail(referencedAt,
         "accessor " + std::to_string(index) + " does not exist (the file has " +
             std::to_string(model_.accessors.size()) + ")",
         "the index of an accessor");
  }
  const tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
  const std::string pointer = Pointer("accessors", static_cast<size_t>(index));
  if (std::find(types.begin(), types.end(), accessor.type) == types.end() ||
      std::find(componentTypes.begin(), componentTypes.end(), accessor.componentType) == componentTypes.end()) {
    Fail(pointer,
         TypeName(accessor.type) + " of " + ComponentTypeName(accessor.componentType) + " where " + referencedAt +
             " refers to it",
         expected);
  }
  const int componentSize = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(accessor.componentType));
  const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(accessor.type));
  const size_t elementSize = static_cast<size_t>(componentSize) * static_cast<size_t>(components);
  // Everything the values depend on is checked before they are allocated: a few bytes
  // of JSON must not be able to ask for gigabytes.
  const AccessorLayout layout = CheckedLayout(accessor, pointer, elementSize);
  ChargeValues(accessor.count * static_cast<size_t>(components), pointer);
  AccessorData data;
  data.count = accessor.count;
  data.components = components;
  data.values.assign(accessor.count * static_cast<size_t>(components), 0.0);
  if (layout.elements) {
    for (size_t element = 0; element < accessor.count; ++element) {
      ReadElement(layout.elements->base + element * layout.elements->stride, accessor, componentSize,
                  &data.values[element * static_cast<size_t>(components)]);
    }
  }
  if (layout.sparse) ApplySparse(accessor, pointer, componentSize, *layout.sparse, data);
  return data;
}

void GltfReader::ChargeValues(uint64_t values, const std::string& pointer) const {
  ChargeValueBytes(values * sizeof(double), kValueBytesPerBufferByte, BufferBytes(),
                   "reading it brings the values read from the file's accessors", pointer);
  // What the scene makes of them (vertices, indices, keys: never larger) lives beside them
  // until they are dropped.
  ChargeImportMemory(values * sizeof(double));
}

void GltfReader::ChargeDecodedBytes(uint64_t bytes, const std::string& pointer) const {
  // Against the file's own buffers: what earlier decoding produced must not raise the limit.
  ChargeValueBytes(bytes, kDecodedBytesPerBufferByte, fileBufferBytes_,
                   "decoding it brings the values read and decoded from the file", pointer);
}

void GltfReader::ChargeValueBytes(uint64_t bytes, uint64_t perBufferByte, size_t bufferBytes, const std::string& doing,
                                  const std::string& pointer) const {
  const uint64_t budget = perBufferByte * bufferBytes + kValueBytesAllowance;
  valueBytesRead_ += bytes;
  if (valueBytesRead_ > budget) {
    Fail(pointer, doing + " to " + std::to_string(valueBytesRead_) + " bytes",
         "at most " + std::to_string(perBufferByte) + " bytes of values per byte of the file's buffers (" +
             std::to_string(bufferBytes) + ") + 16 MiB: accessors that are not read over and over");
  }
  // Within this file's own limit; now within what every import running at once shares.
  ChargeImportMemory(bytes);
}

size_t GltfReader::BufferBytes() const {
  size_t bytes = 0;
  for (const tinygltf::Buffer& buffer : model_.buffers) bytes += buffer.data.size();
  return bytes;
}

GltfReader::AccessorLayout GltfReader::CheckedLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                             size_t elementSize) const {
  if (accessor.count > kMaxAccessorCount) {
    Fail(pointer + "/count", std::to_string(accessor.count) + " elements",
         "at most " + std::to_string(kMaxAccessorCount) + " elements in one accessor");
  }
  AccessorLayout layout;
  if (accessor.bufferView >= 0) {
    layout.elements = InView(accessor.bufferView, accessor.byteOffset, accessor.count, elementSize, true, pointer);
  } else if (accessor.count * elementSize > BufferBytes()) {
    Fail(pointer + "/count",
         std::to_string(accessor.count) + " elements without a buffer view (" +
             std::to_string(accessor.count * elementSize) + " bytes of zeros)",
         "an accessor without a buffer view no larger than the file's buffers (" + std::to_string(BufferBytes()) +
             " bytes)");
  }
  if (accessor.sparse.isSparse) layout.sparse = CheckedSparseLayout(accessor, pointer, elementSize);
  return layout;
}

GltfReader::ViewElements GltfReader::InView(int viewIndex, size_t byteOffset, size_t count, size_t elementSize, bool strided,
                    const std::string& pointer) const {
  if (viewIndex < 0 || static_cast<size_t>(viewIndex) >= model_.bufferViews.size()) {
    Fail(pointer + "/bufferView", "buffer view " + std::to_string(viewIndex) + " does not exist",
         "the index of a buffer view");
  }
  const tinygltf::BufferView& view = model_.bufferViews[static_cast<size_t>(viewIndex)];
  const std::string viewPointer = Pointer("bufferViews", static_cast<size_t>(viewIndex));
  if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model_.buffers.size()) {
    Fail(viewPointer + "/buffer", "buffer " + std::to_string(view.buffer) + " does not exist",
         "the index of a buffer");
  }
  const std::vector<unsigned char>& buffer = model_.buffers[static_cast<size_t>(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
    Fail(viewPointer,
         std::to_string(view.byteLength) + " bytes from byte " + std::to_string(view.byteOffset) +
             " of buffer " + std::to_string(view.buffer) + " (" + std::to_string(buffer.size()) + " bytes)",
         "a buffer view inside its buffer");
  }
  const size_t stride = strided && view.byteStride != 0 ? view.byteStride : elementSize;
  if (stride < elementSize) {
    Fail(viewPointer + "/byteStride",
         "a stride of " + std::to_string(stride) + " bytes for elements of " + std::to_string(elementSize),
         "a stride at least the element size");
  }
  // (count - 1) * stride + elementSize <= byteLength - byteOffset, divided so as not to overflow.
  if (count > 0 && (byteOffset > view.byteLength || elementSize > view.byteLength - byteOffset ||
                    (count - 1) > (view.byteLength - byteOffset - elementSize) / stride)) {
    Fail(pointer,
         std::to_string(count) + " elements from byte " + std::to_string(byteOffset) +
             " run past the end of buffer view " + std::to_string(viewIndex) + " (" +
             std::to_string(view.byteLength) + " bytes; elements of " + std::to_string(elementSize) +
             " bytes, " + std::to_string(stride) + " apart)",
         "an accessor inside its buffer view");
  }
  return {buffer.data() + view.byteOffset + byteOffset, stride};
}

void GltfReader::ReadElement(const unsigned char* at, const tinygltf::Accessor& accessor, int componentSize,
                        double* out) {
  const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(accessor.type));
  for (int c = 0; c < components; ++c) {
    out[c] = Component(at + static_cast<size_t>(c) * static_cast<size_t>(componentSize), accessor.componentType,
                       accessor.normalized);
  }
}

GltfReader::SparseLayout GltfReader::CheckedSparseLayout(const tinygltf::Accessor& accessor, const std::string& pointer,
                                 size_t elementSize) const {
  const std::string at = pointer + "/sparse";
  const auto& sparse = accessor.sparse;
  if (sparse.count < 1 || static_cast<size_t>(sparse.count) > accessor.count) {
    Fail(at + "/count", std::to_string(sparse.count) + " substitutions in an accessor of " +
                            std::to_string(accessor.count) + " elements",
         "1 to the accessor's count");
  }
  const int indexType = sparse.indices.componentType;
  if (indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      indexType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    Fail(at + "/indices/componentType", ComponentTypeName(indexType),
         "UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT indices");
  }
  const size_t count = static_cast<size_t>(sparse.count);
  const size_t indexSize = static_cast<size_t>(tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(indexType)));
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
    Fail(at + (sparse.indices.byteOffset < 0 ? "/indices" : "/values") + "/byteOffset", "a negative offset",
         "a byte offset >= 0");
  }
  return {count, indexType, indexSize,
          InView(sparse.indices.bufferView, static_cast<size_t>(sparse.indices.byteOffset), count, indexSize, false,
                 at + "/indices"),
          InView(sparse.values.bufferView, static_cast<size_t>(sparse.values.byteOffset), count, elementSize, false,
                 at + "/values")};
}

void GltfReader::ApplySparse(const tinygltf::Accessor& accessor, const std::string& pointer, int componentSize,
                 const SparseLayout& sparse, AccessorData& data) const {
  const std::string at = pointer + "/sparse";
  const size_t components = static_cast<size_t>(data.components);
  for (size_t k = 0; k < sparse.count; ++k) {
    const double index = Component(sparse.indices.base + k * sparse.indexSize, sparse.indexType, false);
    if (!(index < static_cast<double>(accessor.count))) {
      Fail(at + "/indices",
           "substitution " + std::to_string(k) + " names element " +
               std::to_string(static_cast<uint64_t>(index)) + " of " + std::to_string(accessor.count),
           "indices below the accessor's count");
    }
    if (k > 0 && !(index > Component(sparse.indices.base + (k - 1) * sparse.indexSize, sparse.indexType, false))) {
      Fail(at + "/indices", "substitution " + std::to_string(k) + " names element " +
                                std::to_string(static_cast<uint64_t>(index)) + ", not after the one before it",
           "strictly increasing indices");
    }
    ReadElement(sparse.values.base + k * sparse.values.stride, accessor, componentSize,
                &data.values[static_cast<size_t>(index) * components]);
  }
}

std::string GltfReader::TypeName(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "type " + std::to_string(type);
  }
}

std::string GltfReader::ComponentTypeName(int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "FLOAT";
    default:
      return "component type " + std::to_string(componentType);
  }
}

double GltfReader::Component(const unsigned char* at, int componentType, bool normalized) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return Load<int8_t>(at, normalized);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return Load<uint8_t>(at, normalized);
    case TINYGLTF_COMPONENT_TYPE_SHORT: return Load<int16_t>(at, normalized);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return Load<uint16_t>(at, normalized);
    // glTF never normalizes 32-bit integers or floats.
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return Load<uint32_t>(at, false);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return Load<float>(at, false);
    default: return 0;  // refused by the callers' componentTypes
  }
}

void GltfReader::CheckNormalized(int index, const std::string& what) const {
  const tinygltf::Accessor& accessor = model_.accessors[static_cast<size_t>(index)];
  if (accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !accessor.normalized) {
    Fail(Pointer("accessors", static_cast<size_t>(index)) + "/normalized", "integer " + what + " that are not normalized",
         "normalized: true on integer " + what + " (KHR_mesh_quantization)");
  }
}

void GltfReader::CheckFinite(const AccessorData& data, int index, const std::string& what) const {
  for (size_t i = 0; i < data.values.size(); ++i) {
    double v = data.values[i];
    if (!(std::fabs(v) <= kMaxMagnitude)) {
      Fail(Pointer("accessors", static_cast<size_t>(index)),
           what + " " + std::to_string(i / static_cast<size_t>(data.components)) + " holds " +
               (std::isnan(v)   ? std::string("NaN")
                : std::isinf(v) ? std::string("an infinity")
                                : std::to_string(v)),
           "finite values of magnitude at most 1e30");
    }
  }
}

}  // namespace tcfarm::gltf
