// The options that say how a file becomes a scene read alike wherever they are given: a
// scene's "import" and "render", and the HTTP submission's "import" (api_server_test).
#include "proto/scene/import/import_options.h"

#include <gtest/gtest.h>

#include "proto/scene/scene.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm {
namespace {

using nlohmann::json;

std::string ErrorAt(const std::function<void()>& read, const std::string& pointer) {
  try {
    read();
  } catch (const SceneError& error) {
    EXPECT_EQ(error.pointer(), pointer);
    return error.what();
  }
  ADD_FAILURE() << "accepted";
  return "";
}

TEST(ImportOptionsTest, ReadsValuesWithinTheSceneLimits) {
  EXPECT_EQ(ReadImageSide(json(scene_limits::kMaxImageSide), "/w"), scene_limits::kMaxImageSide);
  EXPECT_EQ(ReadImageSide(json(2.0), "/w"), 2);
  EXPECT_EQ(ReadSamplesPerPixel(json(scene_limits::kMaxSamplesPerPixel), "/s"), scene_limits::kMaxSamplesPerPixel);
  EXPECT_EQ(ReadFramesPerSecond(json(scene_limits::kMinFramesPerSecond), "/f"), scene_limits::kMinFramesPerSecond);
  EXPECT_EQ(ReadNameOrIndex(json("walk"), "/a"), "walk");
  EXPECT_EQ(ReadNameOrIndex(json(3), "/a"), "3");
}

TEST(ImportOptionsTest, RefusesNamingThePointerAndTheBounds) {
  EXPECT_EQ(ErrorAt([] { ReadImageSide(json(0), "/render/width"); }, "/render/width"),
            "scene/render/width: 0 is out of range; expected a width or height in pixels, an integer in [1, 16384]");
  EXPECT_EQ(ErrorAt([] { ReadSamplesPerPixel(json(1.5), "/import/spp"); }, "/import/spp"),
            "scene/import/spp: 1.5 is not an integer; expected samples per pixel, an integer in [1, 1024]");
  EXPECT_EQ(ErrorAt([] { ReadFramesPerSecond(json(0), "/import/fps"); }, "/import/fps"),
            "scene/import/fps: 0 is out of range; expected frames per second in [0.001, 100000]");
  EXPECT_EQ(ErrorAt([] { ReadFramesPerSecond(json("24"), "/import/fps"); }, "/import/fps"),
            "scene/import/fps: \"24\" is not a number; expected frames per second in [0.001, 100000]");
  EXPECT_EQ(ErrorAt([] { ReadNameOrIndex(json(true), "/import/camera"); }, "/import/camera"),
            "scene/import/camera: true is not a name or an index; expected a name or an index");
}

}  // namespace
}  // namespace tcfarm
