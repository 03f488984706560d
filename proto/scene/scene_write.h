// Writing scene values as JSON: what scene_write.cpp shares with the shape, light and
// material formats (proto/scene/shapes/, lights/, materials/), so that every kind writes its values
// as the rest of a scene does.
#pragma once

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm::scene_write {

nlohmann::json Vec3Json(const Vec3& v);

// An image and how it is sampled, as a material's texture.
nlohmann::json TextureJson(const Texture& texture);

// A constant as a vec3, a polynomial or keyframes as the parser reads them back.
nlohmann::json AnimatedJson(const AnimatedVec3& value);

// The mesh's vertices, triangles and whichever per-vertex attributes it has, added to
// `result` (a mesh shape's fields, or a shared mesh's).
nlohmann::json MeshJson(const TriangleMesh& mesh, nlohmann::json result);

}  // namespace tcfarm::scene_write
