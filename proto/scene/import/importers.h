// The importers SceneImporters() lists (scene_import.h); one factory per format.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "proto/scene/import/scene_import.h"

namespace tcfarm {

std::unique_ptr<SceneImporter> MakeJsonImporter();  // json_importer.cpp
std::unique_ptr<SceneImporter> MakeObjImporter();   // obj_importer.cpp
std::unique_ptr<SceneImporter> MakeGltfImporter();  // gltf_importer.cpp

// A glTF primitive's index list as triangles, by its mode (4 TRIANGLES, 5 TRIANGLE_STRIP,
// 6 TRIANGLE_FAN), as the glTF importer converts them (gltf/meshes.cpp).
std::vector<std::array<uint32_t, 3>> GltfTriangles(const std::vector<uint32_t>& indices, int mode);

}  // namespace tcfarm
