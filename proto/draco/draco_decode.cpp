// libtcfarm_draco_decode: draco_codec.h's DecodedMesh over Draco's decoder.
#include <cstring>

#include <draco/compression/decode.h>

#include "proto/draco/draco_codec.h"

namespace tcfarm::draco_codec {
namespace {

template <typename T>
bool ConvertInto(const draco::PointAttribute& attribute, draco::AttributeValueIndex value, unsigned char* out) {
  T converted[16];
  const int components = attribute.num_components();
  if (!attribute.ConvertValue<T>(value, static_cast<int8_t>(components), converted)) return false;
  std::memcpy(out, converted, sizeof(T) * static_cast<size_t>(components));
  return true;
}

bool Convert(const draco::PointAttribute& attribute, draco::AttributeValueIndex value, Component type,
             unsigned char* out) {
  switch (type) {
    case Component::kInt8: return ConvertInto<int8_t>(attribute, value, out);
    case Component::kUint8: return ConvertInto<uint8_t>(attribute, value, out);
    case Component::kInt16: return ConvertInto<int16_t>(attribute, value, out);
    case Component::kUint16: return ConvertInto<uint16_t>(attribute, value, out);
    case Component::kUint32: return ConvertInto<uint32_t>(attribute, value, out);
    case Component::kFloat: return ConvertInto<float>(attribute, value, out);
  }
  return false;
}

size_t ComponentSize(Component type) {
  switch (type) {
    case Component::kInt8:
    case Component::kUint8: return 1;
    case Component::kInt16:
    case Component::kUint16: return 2;
    case Component::kUint32:
    case Component::kFloat: return 4;
  }
  return 0;
}

}  // namespace

struct DecodedMesh::Decoded {
  std::unique_ptr<draco::Mesh> mesh;
};

DecodedMesh::DecodedMesh(const unsigned char* bytes, size_t length) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes), length);
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    error_ = decoded.status().error_msg_string();
    if (error_.empty()) error_ = "Draco's decoder failed";
    return;
  }
  decoded_ = std::make_unique<Decoded>(Decoded{std::move(decoded).value()});
}

DecodedMesh::~DecodedMesh() = default;

size_t DecodedMesh::Points() const { return decoded_ ? decoded_->mesh->num_points() : 0; }

size_t DecodedMesh::Faces() const { return decoded_ ? decoded_->mesh->num_faces() : 0; }

int DecodedMesh::Components(uint32_t id) const {
  const draco::PointAttribute* attribute = decoded_ ? decoded_->mesh->GetAttributeByUniqueId(id) : nullptr;
  return attribute == nullptr ? 0 : attribute->num_components();
}

size_t DecodedMesh::WriteValues(uint32_t id, Component type, unsigned char* out) const {
  const draco::PointAttribute* attribute = decoded_ ? decoded_->mesh->GetAttributeByUniqueId(id) : nullptr;
  if (attribute == nullptr) return 0;
  const size_t elementSize = ComponentSize(type) * static_cast<size_t>(attribute->num_components());
  const size_t points = Points();
  for (size_t p = 0; p < points; ++p) {
    const draco::AttributeValueIndex value = attribute->mapped_index(draco::PointIndex(static_cast<uint32_t>(p)));
    if (value.value() >= attribute->size() || !Convert(*attribute, value, type, out + p * elementSize)) return p;
  }
  return points;
}

void DecodedMesh::WriteFaces(int size, unsigned char* out) const {
  if (!decoded_) return;
  const draco::Mesh& mesh = *decoded_->mesh;
  for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f) {
    for (const draco::PointIndex& point : mesh.face(f)) {
      const uint32_t value = point.value();  // below num_points: Draco's decoder checks its faces
      std::memcpy(out, &value, static_cast<size_t>(size));  // little-endian: the low bytes first
      out += size;
    }
  }
}

}  // namespace tcfarm::draco_codec
