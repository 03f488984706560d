// Draco behind a narrow wall: the importer's decoder (libtcfarm_draco_decode) and the test
// files' encoder (libtcfarm_draco_encode) are shared libraries of our own that link Debian's
// static libdraco.a with every one of its symbols hidden, exporting only what this header
// declares. Debian's libdraco.so exports its own copy of another tinygltf version and of
// stb, which would take the place of the importer's wherever the dynamic linker met it
// first; through these libraries no Draco symbol is visible to the process at all.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#define TCFARM_DRACO_API __attribute__((visibility("default")))

namespace tcfarm::draco_codec {

// Component types of decoded or encoded values: glTF's accessor component types.
enum class Component { kInt8, kUint8, kInt16, kUint16, kUint32, kFloat };

// One Draco mesh, decoded from bytes at construction; Error() says why when they are not one.
class TCFARM_DRACO_API DecodedMesh {
 public:
  DecodedMesh(const unsigned char* bytes, size_t length);
  ~DecodedMesh();
  DecodedMesh(const DecodedMesh&) = delete;
  DecodedMesh& operator=(const DecodedMesh&) = delete;

  const std::string& Error() const { return error_; }  // empty once decoded
  size_t Points() const;
  size_t Faces() const;
  // The components of the attribute whose unique id is `id`; 0 when the mesh has none.
  int Components(uint32_t id) const;
  // Attribute `id`'s value at every point, converted with Draco's range checks to `type`,
  // written little-endian from `out` (Points() * Components(id) values). Returns the first
  // point whose value does not fit `type`, or Points() when all do.
  size_t WriteValues(uint32_t id, Component type, unsigned char* out) const;
  // Every face's three point indices, `size` bytes each (1, 2 or 4), little-endian.
  void WriteFaces(int size, unsigned char* out) const;

 private:
  struct Decoded;
  std::unique_ptr<Decoded> decoded_;
  std::string error_;
};

// What the test files' encoder takes: an attribute's meaning and values, one element per point.
enum class Meaning { kPosition, kNormal, kTexCoord, kColor, kGeneric };
struct Attribute {
  Meaning meaning;
  int components;
  Component type;
  bool normalized;
  const void* values;
};
struct Encoding {
  bool sequential = true;  // keeps vertex and triangle order; edgebreaker reorders both
  int positionBits = 0;    // 0: no quantization (lossless); else normals 12 bits, texture coordinates 14
};

// The Draco bytes of a mesh of `points` points and the triangles `indices`; each attribute's
// unique id goes to `ids`, in order. Throws std::runtime_error when Draco cannot encode it.
TCFARM_DRACO_API std::string EncodeMesh(size_t points, const std::vector<Attribute>& attributes,
                                        const std::vector<uint32_t>& indices, const Encoding& encoding,
                                        std::vector<int>* ids);

}  // namespace tcfarm::draco_codec
