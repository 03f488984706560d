// libtcfarm_draco_encode: draco_codec.h's EncodeMesh over Draco's encoder, for test files.
#include <stdexcept>

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include "proto/draco/draco_codec.h"

namespace tcfarm::draco_codec {
namespace {

draco::GeometryAttribute::Type DracoType(Meaning meaning) {
  switch (meaning) {
    case Meaning::kPosition: return draco::GeometryAttribute::POSITION;
    case Meaning::kNormal: return draco::GeometryAttribute::NORMAL;
    case Meaning::kTexCoord: return draco::GeometryAttribute::TEX_COORD;
    case Meaning::kColor: return draco::GeometryAttribute::COLOR;
    case Meaning::kGeneric: return draco::GeometryAttribute::GENERIC;
  }
  return draco::GeometryAttribute::INVALID;
}

draco::DataType DracoDataType(Component type) {
  switch (type) {
    case Component::kInt8: return draco::DT_INT8;
    case Component::kUint8: return draco::DT_UINT8;
    case Component::kInt16: return draco::DT_INT16;
    case Component::kUint16: return draco::DT_UINT16;
    case Component::kUint32: return draco::DT_UINT32;
    case Component::kFloat: return draco::DT_FLOAT32;
  }
  return draco::DT_INVALID;
}

void AddAttribute(draco::Mesh& mesh, size_t points, const Attribute& input, std::vector<int>* ids) {
  draco::GeometryAttribute attribute;
  const draco::DataType dataType = DracoDataType(input.type);
  const size_t elementSize = static_cast<size_t>(input.components) * static_cast<size_t>(draco::DataTypeLength(dataType));
  attribute.Init(DracoType(input.meaning), nullptr, static_cast<uint8_t>(input.components), dataType, input.normalized,
                 static_cast<int64_t>(elementSize), 0);
  const int index = mesh.AddAttribute(attribute, true, static_cast<uint32_t>(points));
  for (size_t v = 0; v < points; ++v) {
    mesh.attribute(index)->SetAttributeValue(draco::AttributeValueIndex(static_cast<uint32_t>(v)),
                                             static_cast<const char*>(input.values) + v * elementSize);
  }
  ids->push_back(static_cast<int>(mesh.attribute(index)->unique_id()));
}

}  // namespace

std::string EncodeMesh(size_t points, const std::vector<Attribute>& attributes, const std::vector<uint32_t>& indices,
                       const Encoding& encoding, std::vector<int>* ids) {
  draco::Mesh mesh;
  mesh.set_num_points(static_cast<uint32_t>(points));
  for (const Attribute& attribute : attributes) AddAttribute(mesh, points, attribute, ids);
  for (size_t i = 0; i + 2 < indices.size(); i += 3) {
    mesh.AddFace({draco::PointIndex(indices[i]), draco::PointIndex(indices[i + 1]), draco::PointIndex(indices[i + 2])});
  }
  draco::Encoder encoder;
  encoder.SetEncodingMethod(encoding.sequential ? draco::MESH_SEQUENTIAL_ENCODING : draco::MESH_EDGEBREAKER_ENCODING);
  if (encoding.positionBits > 0) {
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, encoding.positionBits);
    encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, 12);
    encoder.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD, 14);
  }
  draco::EncoderBuffer out;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &out);
  if (!status.ok()) throw std::runtime_error("draco: " + status.error_msg_string());
  return std::string(out.data(), out.size());
}

}  // namespace tcfarm::draco_codec
