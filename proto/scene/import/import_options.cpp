#include "proto/scene/import/import_options.h"

#include <cmath>

#include "proto/scene/import/messages.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm {
namespace {

using nlohmann::json;

bool IsWholeNumber(const json& value) {
  if (value.is_number_integer()) return true;
  if (!value.is_number_float()) return false;
  const double number = value.get<double>();
  return std::isfinite(number) && std::floor(number) == number;
}

std::string Shown(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

// A bound as a person writes it: 100000, not 100000.0.
std::string Bound(double bound) {
  return std::floor(bound) == bound ? std::to_string(static_cast<long long>(bound)) : Shown(bound);
}

int ReadInteger(const json& value, const std::string& pointer, int low, int high, const std::string& what) {
  const std::string expected = what + ", an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
  if (!IsWholeNumber(value)) FailInput(pointer, Shown(value) + " is not an integer", expected);
  // The limits are far below 2^53, so comparing as double is exact where it matters.
  const double number = value.get<double>();
  if (number < low || number > high) FailInput(pointer, Shown(value) + " is out of range", expected);
  return static_cast<int>(number);
}

}  // namespace

double ReadFramesPerSecond(const json& value, const std::string& pointer) {
  const std::string expected = "frames per second in [" + Bound(scene_limits::kMinFramesPerSecond) + ", " +
                               Bound(scene_limits::kMaxFramesPerSecond) + "]";
  if (!value.is_number()) FailInput(pointer, Shown(value) + " is not a number", expected);
  const double fps = value.get<double>();
  if (!(fps >= scene_limits::kMinFramesPerSecond && fps <= scene_limits::kMaxFramesPerSecond)) {
    FailInput(pointer, Shown(value) + " is out of range", expected);
  }
  return fps;
}

int ReadImageSide(const json& value, const std::string& pointer) {
  return ReadInteger(value, pointer, 1, scene_limits::kMaxImageSide, "a width or height in pixels");
}

int ReadSamplesPerPixel(const json& value, const std::string& pointer) {
  return ReadInteger(value, pointer, 1, scene_limits::kMaxSamplesPerPixel, "samples per pixel");
}

std::string ReadNameOrIndex(const json& value, const std::string& pointer) {
  if (value.is_string()) return value.get<std::string>();
  if (!IsWholeNumber(value)) FailInput(pointer, Shown(value) + " is not a name or an index", "a name or an index");
  return std::to_string(value.get<long long>());
}

LightUnits ReadLightUnits(const json& value, const std::string& pointer) {
  const std::string expected = "\"photometric\" (glTF's candela and lux at 683 lm/W) or \"radiometric\" (as they are)";
  if (!value.is_string()) FailInput(pointer, Shown(value) + " is not a string", expected);
  const std::optional<LightUnits> units = LightUnitsNamed(value.get<std::string>());
  if (!units) FailInput(pointer, Shown(value) + " names no light units", expected);
  return *units;
}

}  // namespace tcfarm
