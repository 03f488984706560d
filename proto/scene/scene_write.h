// Writing scene values as JSON: what scene_write.cpp shares with the shape and light
// formats (proto/scene/shapes/, proto/scene/lights/), so that every kind writes its values
// as the rest of a scene does.
#pragma once

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm::scene_write {

nlohmann::json Vec3Json(const Vec3& v);

// A constant as a vec3, a polynomial or keyframes as the parser reads them back.
nlohmann::json AnimatedJson(const AnimatedVec3& value);

// The mesh's vertices, triangles and whichever per-vertex attributes it has, added to
// `result` (a mesh shape's fields, or a shared mesh's).
nlohmann::json MeshJson(const TriangleMesh& mesh, nlohmann::json result);

}  // namespace tcfarm::scene_write
