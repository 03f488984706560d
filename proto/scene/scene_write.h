// Writing scene values as JSON: what scene_write.cpp shares with the shape formats
// (proto/scene/shapes/), so that every kind writes its values as the rest of a scene does.
#pragma once

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm::scene_write {

nlohmann::json Vec3Json(const Vec3& v);

// The mesh's vertices, triangles and whichever per-vertex attributes it has, added to
// `result` (a mesh shape's fields, or a shared mesh's).
nlohmann::json MeshJson(const TriangleMesh& mesh, nlohmann::json result);

}  // namespace tcfarm::scene_write
