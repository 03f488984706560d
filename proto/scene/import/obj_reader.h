// Wavefront OBJ (+ MTL) -> triangles, per-vertex normals and UVs, and materials.
//
// Both ways an OBJ file enters a scene use this reader: a JSON mesh's "file" reference
// (geometry only; the JSON shape names its material) and an OBJ file imported as a whole
// scene (geometry, parts and materials). tinyobjloader reads the structure (faces and
// their index triples, objects, groups, usemtl) and the MTL libraries. A strict line check
// runs first, because tinyobjloader accepts silently what a farm must refuse (a bad number
// reads as 0, an out-of-range index is only a warning) and reports no line numbers; it
// also supplies the v/vn/vt values, read exactly (tinyobjloader's are not correctly rounded).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "proto/scene/scene.h"

namespace tcfarm {

struct ObjModel {
  // A run of consecutive triangles of one OBJ object/group with one material.
  struct Part {
    std::string name;   // the OBJ object or group name; may be empty
    int material = -1;  // index into materials; -1 when no usemtl applies
    size_t firstTriangle = 0;
    size_t triangleCount = 0;
  };

  // Vertices are the file's positions in file order (so indices read like the file's),
  // then a copy of a position for each further normal/UV combination it is used with.
  // normals/uvs are kept only when every face corner of the file names one.
  TriangleMesh mesh;
  std::vector<Part> parts;             // in file order; together they cover mesh.triangles
  std::vector<Material> materials;     // from the material libraries, in library order
};

struct ObjReadOptions {
  std::string pointer;      // JSON pointer that errors name ("" for a whole-file import)
  std::string displayName;  // how messages name the file
  size_t triangleBudget = 0;  // triangles the rest of the scene leaves to this file
  size_t triangleLimit = 0;   // the whole scene's limit, for messages
  // Returns the text of the material library `name` (an mtllib argument); `line` is
  // where the OBJ names it, for messages. Throws SceneError when it cannot. Without it,
  // mtllib and usemtl are ignored.
  std::function<std::string(const std::string& name, size_t line)> readMaterialLibrary;
};

// Throws SceneError (at options.pointer, naming the file and line where known) for
// malformed statements, non-finite or huge numbers, references to undefined vertices,
// normals or UVs, faces of fewer than 3 vertices, usemtl names no library defines, bad
// material values, and more triangles than the budget.
ObjModel ReadObj(const std::string& text, const ObjReadOptions& options);

// The triangles of one polygon (a face's corner positions, in order) as index triples
// into `corners`. Convex polygons are fanned from the first corner; concave ones are ear
// clipped in their plane. Always corners.size() - 2 triangles.
std::vector<std::array<size_t, 3>> TriangulatePolygon(const std::vector<Vec3>& corners);

}  // namespace tcfarm
