// The one reader of the options that say how a file becomes a scene (ImportOptions): a
// scene's own "import" block and "render" settings (scene_parse) and the HTTP submission's
// "import" block (coordinator/http/submit_request.cpp) name them differently ("size" is
// [width, height], "spp" is samples_per_pixel) but read each value here, so bounds
// (scene_limits.h) and messages are the same wherever they are given.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "proto/scene/import/scene_import.h"

namespace tcfarm {

// Each reads the value found at the JSON pointer `pointer`, or throws SceneError there
// ("<problem>; expected <what>").
double ReadFramesPerSecond(const nlohmann::json& value, const std::string& pointer);
int ReadImageSide(const nlohmann::json& value, const std::string& pointer);  // a width or a height
int ReadSamplesPerPixel(const nlohmann::json& value, const std::string& pointer);
// "photometric" (candela and lux at 683 lm/W, as the tools that write glTF mean them) or
// "radiometric" (the numbers as they are).
LightUnits ReadLightUnits(const nlohmann::json& value, const std::string& pointer);
// An animation or a camera: its name, or its index (written as its decimal digits).
std::string ReadNameOrIndex(const nlohmann::json& value, const std::string& pointer);

}  // namespace tcfarm
