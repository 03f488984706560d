// The importers SceneImporters() lists (scene_import.h); one factory per format.
#pragma once

#include <memory>

#include "scene/import/scene_import.h"

namespace tcfarm {

std::unique_ptr<SceneImporter> MakeJsonImporter();  // json_importer.cpp
std::unique_ptr<SceneImporter> MakeObjImporter();   // obj_importer.cpp

}  // namespace tcfarm
